"""Quasi-steady segments of a Garmin G1000 log: stretches of level cruise and full-throttle climb
in which the aircraft is close enough to steady flight to be compared with a trimmed model.

``extract_segments`` finds them (criteria in :class:`SegmentCriteria`), ``segments_dataframe``
tabulates them. Air data (pressure altitude, KCAS, KTAS) come from
:mod:`jsbsim_calib.physics.atmosphere`.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Sequence

import numpy as np
import pandas as pd

from ...physics.atmosphere import isa_temperature_c, kcas_from_kias, ktas_from_kcas, pressure_altitude_ft
from .parse import G1000Log


@dataclass(frozen=True)
class SegmentCriteria:
    """Criteria for quasi-steady segments. Every window must meet all criteria of its kind.

    All segments (pointwise, every sample):
      * airborne: ``IAS >= min_airborne_ias_kt`` (40 kt), ``GndSpd >= min_airborne_gnd_speed_kt``
        (30 kt, when logged), and ``AltB`` at least ``min_height_above_field_ft`` (300 ft) above
        the field: the median baro altitude of the ground runs (``IAS`` below the airborne
        limit) before and after the sample, the higher of the two. This leaves out the take-off
        and landing rolls, ground effect and the first part of the climb-out, in which the
        take-off flaps may still be down (the log has no flap channel);
      * wings level: ``|Roll| < max_abs_roll_deg`` (10 deg);
      * AltB, BaroA, OAT, IAS, VSpd, Pitch, Roll and E1 RPM logged;
      * no time gap between samples longer than ``max_gap_s`` (5 s).
    Level cruise (window):
      * duration ``>= min_cruise_duration_s`` (30 s);
      * ``|mean VSpd| < max_cruise_abs_mean_vs_fpm`` (100 ft/min);
      * altitude drift ``< max_cruise_alt_drift_ft`` (100 ft): slope of a straight line fitted
        to AltB over time, times the duration;
      * std of IAS ``< max_cruise_ias_std_kt`` (2 kt), std of E1 RPM ``< max_cruise_rpm_std`` (25);
      * fuel flow logged and positive at every sample.
    Full-throttle climb (window):
      * duration ``>= min_climb_duration_s`` (30 s);
      * mean VSpd ``> min_climb_mean_vs_fpm`` (300 ft/min);
      * E1 RPM ``>= min_climb_rpm`` (2250, a fixed-pitch C172 at full throttle in a Vy climb
        turns about 2300-2450) at every sample, std of E1 RPM ``< max_climb_rpm_std`` (25);
      * std of IAS ``< max_climb_ias_std_kt`` (3 kt);
      * ``Pitch > min_climb_pitch_deg`` (0 deg) at every sample;
      * ``IAS >= min_climb_ias_kt`` (65 kt) at every sample: leaves out Vx and flaps-down
        climbs (C172S: Vx 62 KIAS, Vy 74 KIAS at sea level), which the POH climb data are not
        for.
    Transients (both kinds): over the first and the last ``edge_s`` (5 s) of a window the
    mean IAS, E1 RPM, VSpd and Pitch may differ from the window mean by at most
    ``edge_max_ias_dev_kt`` (1.5 kt), ``edge_max_rpm_dev`` (30), ``edge_max_vs_dev_fpm``
    (250 ft/min) and ``edge_max_pitch_dev_deg`` (1.5 deg), so that a window does not reach into
    a level-off, a power change or an acceleration.

    Search: the samples meeting the pointwise criteria form runs; in each run the longest window
    meeting the window criteria is taken, and the parts of the run before and after it are
    searched again, so segments are maximal (cannot be extended) and do not overlap. Cruise
    windows are searched first; climb windows cannot overlap them (the VSpd criteria exclude
    each other anyway).
    """

    min_cruise_duration_s: float = 30.0       # [s]
    min_climb_duration_s: float = 30.0        # [s]
    max_gap_s: float = 5.0                    # [s] longest time step inside a segment
    min_airborne_ias_kt: float = 40.0         # [kt]
    min_airborne_gnd_speed_kt: float = 30.0   # [kt] used only where GndSpd is logged
    min_height_above_field_ft: float = 300.0  # [ft] above the AltB of the neighbouring ground runs
    max_abs_roll_deg: float = 10.0            # [deg]
    max_cruise_abs_mean_vs_fpm: float = 100.0  # [ft/min]
    max_cruise_alt_drift_ft: float = 100.0    # [ft]
    max_cruise_ias_std_kt: float = 2.0        # [kt]
    max_cruise_rpm_std: float = 25.0          # [rpm]
    min_climb_mean_vs_fpm: float = 300.0      # [ft/min]
    min_climb_rpm: float = 2250.0             # [rpm]
    max_climb_rpm_std: float = 25.0           # [rpm]
    max_climb_ias_std_kt: float = 3.0         # [kt]
    min_climb_pitch_deg: float = 0.0          # [deg]
    min_climb_ias_kt: float = 65.0            # [kt]
    edge_s: float = 5.0                       # [s]
    edge_max_ias_dev_kt: float = 1.5          # [kt]
    edge_max_rpm_dev: float = 30.0            # [rpm]
    edge_max_vs_dev_fpm: float = 250.0        # [ft/min]
    edge_max_pitch_dev_deg: float = 1.5       # [deg]


@dataclass(frozen=True)
class WeightAssumption:
    """Assumed loading for the weight estimate; the G1000 logs fuel but not weight.

    ``weight = empty_weight_lb + occupants_lb + baggage_lb + fuel_gal * fuel_density_lb_per_gal``.
    The defaults are ASSUMPTIONS, not records: the C172S standard empty weight of the POH
    (1663 lb; the actual aircraft's weight-and-balance record differs), two occupants
    (instructor and student) at the FAA standard adult weight of 170 lb each, no baggage, and
    avgas at 6.0 lb/US gal. Change them when the actual loading is known.
    """

    empty_weight_lb: float = 1663.0          # [lb] C172S standard empty weight (POH)
    occupants_lb: float = 340.0              # [lb] assumed: 2 x 170 lb (FAA standard adult)
    baggage_lb: float = 0.0                  # [lb] assumed
    fuel_density_lb_per_gal: float = 6.0     # [lb/US gal] avgas

    def weight_lb(self, fuel_gal: float) -> float:
        """Gross weight [lb] with ``fuel_gal`` [US gal] on board."""
        return (self.empty_weight_lb + self.occupants_lb + self.baggage_lb
                + fuel_gal * self.fuel_density_lb_per_gal)


@dataclass(frozen=True)
class Segment:
    """A quasi-steady stretch of flight. Values are means over the window."""

    kind: str                 # 'cruise' | 'climb'
    t_start_s: float          # [s] time_s of the first sample
    t_end_s: float            # [s] time_s of the last sample
    duration_s: float         # [s] t_end_s - t_start_s
    n_samples: int            # [-]
    pressure_alt_ft: float    # [ft] pressure altitude (AltB referred to 29.92 inHg)
    oat_c: float              # [deg C]
    isa_dev_c: float          # [deg C] OAT - ISA temperature at the pressure altitude
    kias: float               # [kt]
    kcas: float               # [kt]
    ktas: float               # [kt] from pressure altitude, OAT and CAS
    vs_fpm: float             # [ft/min] mean VSpd
    rpm: float                # [rpm]
    fuel_flow_gph: float      # [US gal/h]
    pitch_deg: float          # [deg]
    roll_deg: float           # [deg]
    fuel_gal: float           # [US gal] FQtyL + FQtyR
    weight_lb: float          # [lb] from WeightAssumption and fuel_gal
    ktas_logged: float = math.nan   # [kt] mean of the logged TAS (NaN if not logged)
    std: dict[str, float] = field(default_factory=dict)  # sample std devs, keys as the fields


_STD_KEYS = {  # Segment.std key -> column of the work frame
    "alt_ft": "AltB", "pressure_alt_ft": "hp", "oat_c": "OAT", "kias": "IAS", "ktas": "ktas",
    "vs_fpm": "VSpd", "rpm": "E1 RPM", "fuel_flow_gph": "E1 FFlow", "pitch_deg": "Pitch",
    "roll_deg": "Roll",
}


class _Sums:
    """Prefix sums for O(1) window means and variances over index ranges [i, j]."""

    def __init__(self, x: np.ndarray):
        self.off = float(np.mean(x)) if x.size else 0.0
        xc = x - self.off
        self.s1 = np.concatenate([[0.0], np.cumsum(xc)])
        self.s2 = np.concatenate([[0.0], np.cumsum(xc * xc)])

    def mean(self, i: Any, j: Any) -> Any:
        return (self.s1[j + 1] - self.s1[i]) / (j - i + 1) + self.off

    def std(self, i: Any, j: Any) -> Any:
        n = j - i + 1
        m = (self.s1[j + 1] - self.s1[i]) / n
        return np.sqrt(np.maximum((self.s2[j + 1] - self.s2[i]) / n - m * m, 0.0))


def _runs(mask: np.ndarray, t: np.ndarray, max_gap_s: float) -> list[tuple[int, int]]:
    """Index ranges [a, b] of consecutive True samples without time gaps above max_gap_s."""
    out: list[tuple[int, int]] = []
    start: int | None = None
    for k in range(len(mask)):
        if mask[k] and start is not None and t[k] - t[k - 1] > max_gap_s:
            out.append((start, k - 1))
            start = k
        elif mask[k] and start is None:
            start = k
        elif not mask[k] and start is not None:
            out.append((start, k - 1))
            start = None
    if start is not None:
        out.append((start, len(mask) - 1))
    return out


def _elevation(alt: np.ndarray, a: int, b: int) -> float:
    seg = alt[a:b + 1]
    return float(np.nanmedian(seg)) if np.isfinite(seg).any() else math.nan


def _field_elevation(alt: np.ndarray, ground: np.ndarray) -> np.ndarray:
    """Per sample: the higher of the median AltB of the ground runs before and after it
    (NaN where there is none)."""
    n = len(alt)
    before = np.full(n, np.nan)
    after = np.full(n, np.nan)
    runs = _runs(ground, np.arange(n, dtype=float), math.inf)
    for a, b in runs:            # later runs overwrite: the last run starting before
        before[a:] = _elevation(alt, a, b)
    for a, b in reversed(runs):  # earlier runs overwrite: the first run ending after
        after[: b + 1] = _elevation(alt, a, b)
    return np.fmax(before, after)


class _Window:
    """Window criteria of one segment kind over one run of samples."""

    def __init__(self, kind: str, w: pd.DataFrame, c: SegmentCriteria):
        self.kind = kind
        self.c = c
        self.t = w["time_s"].to_numpy(float)
        self.ias = _Sums(w["IAS"].to_numpy(float))
        self.rpm = _Sums(w["E1 RPM"].to_numpy(float))
        self.vs = _Sums(w["VSpd"].to_numpy(float))
        self.pitch = _Sums(w["Pitch"].to_numpy(float))
        # prefix sums for the straight-line fit of AltB over time (shifted for accuracy)
        tc = self.t - (self.t[0] if self.t.size else 0.0)
        alt = w["AltB"].to_numpy(float)
        hc = alt - (float(np.mean(alt)) if alt.size else 0.0)
        self.st = np.concatenate([[0.0], np.cumsum(tc)])
        self.stt = np.concatenate([[0.0], np.cumsum(tc * tc)])
        self.sh = np.concatenate([[0.0], np.cumsum(hc)])
        self.sth = np.concatenate([[0.0], np.cumsum(tc * hc)])
        if kind == "cruise":
            self.min_dur = c.min_cruise_duration_s
        else:
            self.min_dur = c.min_climb_duration_s

    def _edge_ok(self, x: _Sums, a: Any, b: Any, whole: Any, tol: float) -> Any:
        return np.abs(x.mean(a, b) - whole) <= tol

    def valid(self, i: int, j: np.ndarray) -> np.ndarray:
        """Which windows [i, j] (j an array of end indices) meet the window criteria."""
        c, t = self.c, self.t
        n = j - i + 1
        ok = (t[j] - t[i]) >= self.min_dur
        ias_std, rpm_std = self.ias.std(i, j), self.rpm.std(i, j)
        vs_mean = self.vs.mean(i, j)
        if self.kind == "cruise":
            ok &= np.abs(vs_mean) < c.max_cruise_abs_mean_vs_fpm
            ok &= ias_std < c.max_cruise_ias_std_kt
            ok &= rpm_std < c.max_cruise_rpm_std
            st = self.st[j + 1] - self.st[i]
            stt = self.stt[j + 1] - self.stt[i]
            sh = self.sh[j + 1] - self.sh[i]
            sth = self.sth[j + 1] - self.sth[i]
            den = n * stt - st * st
            slope = np.where(den > 0, (n * sth - st * sh) / np.where(den > 0, den, 1.0), 0.0)
            ok &= np.abs(slope) * (t[j] - t[i]) < c.max_cruise_alt_drift_ft
        else:
            ok &= vs_mean > c.min_climb_mean_vs_fpm
            ok &= ias_std < c.max_climb_ias_std_kt
            ok &= rpm_std < c.max_climb_rpm_std
        # transients at both ends
        i_edge = int(np.searchsorted(t, t[i] + c.edge_s, side="right") - 1)
        j_edge = np.maximum(np.searchsorted(t, t[j] - c.edge_s, side="left"), i)
        i_edge_arr = np.minimum(i_edge, j)
        for x, tol in ((self.ias, c.edge_max_ias_dev_kt), (self.rpm, c.edge_max_rpm_dev),
                       (self.vs, c.edge_max_vs_dev_fpm), (self.pitch, c.edge_max_pitch_dev_deg)):
            whole = x.mean(i, j)
            ok &= self._edge_ok(x, i, i_edge_arr, whole, tol)
            ok &= self._edge_ok(x, j_edge, j, whole, tol)
        return ok

    def longest(self, lo: int, hi: int) -> tuple[int, int] | None:
        """Longest valid window inside [lo, hi] (indices into the run)."""
        t = self.t
        best: tuple[int, int] | None = None
        best_dur = -1.0
        for i in range(lo, hi + 1):
            if t[hi] - t[i] <= best_dur or t[hi] - t[i] < self.min_dur:
                break
            j0 = int(np.searchsorted(t, t[i] + max(self.min_dur, best_dur), side="left"))
            j0 = max(j0, i)
            if j0 > hi:
                continue
            j = np.arange(j0, hi + 1)
            ok = self.valid(i, j)
            if ok.any():
                jb = int(j[np.flatnonzero(ok)[-1]])
                dur = t[jb] - t[i]
                if dur > best_dur:
                    best, best_dur = (i, jb), dur
        return best

    def all_windows(self) -> list[tuple[int, int]]:
        out: list[tuple[int, int]] = []
        stack = [(0, len(self.t) - 1)]
        while stack:
            lo, hi = stack.pop()
            if hi <= lo:
                continue
            found = self.longest(lo, hi)
            if found is None:
                continue
            out.append(found)
            stack.append((lo, found[0] - 1))
            stack.append((found[1] + 1, hi))
        return sorted(out)


def _work_frame(log: G1000Log, kcas_table: tuple[Sequence[float], Sequence[float]] | None
                ) -> pd.DataFrame:
    d = log.data
    w = pd.DataFrame({"time_s": d["time_s"].to_numpy(float)})
    for col in ("AltB", "BaroA", "OAT", "IAS", "VSpd", "Pitch", "Roll", "E1 RPM", "E1 FFlow",
                "FQtyL", "FQtyR", "TAS", "GndSpd"):
        w[col] = pd.to_numeric(d[col], errors="coerce").to_numpy(float) if col in d else np.nan
    w["hp"] = pressure_altitude_ft(w["AltB"].to_numpy(), w["BaroA"].to_numpy())
    w["kcas"] = kcas_from_kias(w["IAS"].to_numpy(), kcas_table)
    w["ktas"] = ktas_from_kcas(w["kcas"].to_numpy(), w["hp"].to_numpy(), w["OAT"].to_numpy())
    w["fuel"] = w["FQtyL"] + w["FQtyR"]
    return w


def _segment(kind: str, w: pd.DataFrame, weight: WeightAssumption) -> Segment:
    def m(col: str) -> float:
        x = w[col].to_numpy(float)
        return float(np.nanmean(x)) if np.isfinite(x).any() else math.nan

    t0, t1 = float(w["time_s"].iloc[0]), float(w["time_s"].iloc[-1])
    hp, oat, fuel = m("hp"), m("OAT"), m("fuel")
    std = {key: float(np.nanstd(w[col].to_numpy(float), ddof=1))
           if np.isfinite(w[col]).sum() > 1 else math.nan for key, col in _STD_KEYS.items()}
    return Segment(
        kind=kind, t_start_s=t0, t_end_s=t1, duration_s=t1 - t0, n_samples=len(w),
        pressure_alt_ft=hp, oat_c=oat, isa_dev_c=oat - isa_temperature_c(hp),
        kias=m("IAS"), kcas=m("kcas"), ktas=m("ktas"), vs_fpm=m("VSpd"), rpm=m("E1 RPM"),
        fuel_flow_gph=m("E1 FFlow"), pitch_deg=m("Pitch"), roll_deg=m("Roll"), fuel_gal=fuel,
        weight_lb=weight.weight_lb(fuel) if math.isfinite(fuel) else math.nan,
        ktas_logged=m("TAS"), std=std,
    )


def extract_segments(log: G1000Log, criteria: SegmentCriteria = SegmentCriteria(), *,
                     weight: WeightAssumption = WeightAssumption(),
                     kcas_table: tuple[Sequence[float], Sequence[float]] | None = None,
                     ) -> list[Segment]:
    """Quasi-steady level-cruise and full-throttle-climb segments of a log, sorted by time.

    The criteria and the search are described in :class:`SegmentCriteria`; ``weight`` gives the
    loading assumed for ``Segment.weight_lb`` and ``kcas_table`` the airspeed calibration passed
    to :func:`kcas_from_kias`.
    """
    c = criteria
    w = _work_frame(log, kcas_table)
    t = w["time_s"].to_numpy(float)
    ias, gs, alt = w["IAS"].to_numpy(), w["GndSpd"].to_numpy(), w["AltB"].to_numpy()

    with np.errstate(invalid="ignore"):
        on_ground = ~(ias >= c.min_airborne_ias_kt)
        field_alt = _field_elevation(alt, on_ground & np.isfinite(ias))
        airborne = ~on_ground
        airborne &= ~(gs < c.min_airborne_gnd_speed_kt)  # NaN GndSpd does not exclude
        airborne &= ~(alt < field_alt + c.min_height_above_field_ft)
        base = airborne & (np.abs(w["Roll"].to_numpy()) < c.max_abs_roll_deg)
        for col in ("AltB", "BaroA", "OAT", "IAS", "VSpd", "Pitch", "Roll", "E1 RPM"):
            base &= np.isfinite(w[col].to_numpy())
        ff = w["E1 FFlow"].to_numpy()
        cruise_mask = base & np.isfinite(ff) & (ff > 0)
        climb_mask = (base & (w["E1 RPM"].to_numpy() >= c.min_climb_rpm)
                      & (w["Pitch"].to_numpy() > c.min_climb_pitch_deg)
                      & (ias >= c.min_climb_ias_kt))

    found: list[tuple[str, int, int]] = []
    taken = np.zeros(len(w), dtype=bool)
    for kind, mask in (("cruise", cruise_mask), ("climb", climb_mask)):
        for a, b in _runs(mask & ~taken, t, c.max_gap_s):
            sub = w.iloc[a:b + 1]
            for i, j in _Window(kind, sub, c).all_windows():
                found.append((kind, a + i, a + j))
                taken[a + i:a + j + 1] = True

    found.sort(key=lambda s: s[1])
    return [_segment(kind, w.iloc[i:j + 1], weight) for kind, i, j in found]


_TABLE_COLUMNS = ["kind", "t_start_s", "t_end_s", "duration_s", "n_samples", "pressure_alt_ft",
                  "oat_c", "isa_dev_c", "kias", "kcas", "ktas", "ktas_logged", "vs_fpm", "rpm",
                  "gph", "pitch_deg", "roll_deg", "fuel_gal", "weight_lb"]


def segments_dataframe(segments: Sequence[Segment]) -> pd.DataFrame:
    """One row per segment, in time order.

    Columns: ``kind, t_start_s, t_end_s, duration_s, n_samples, pressure_alt_ft, oat_c,
    isa_dev_c, kias, kcas, ktas, ktas_logged, vs_fpm, rpm, gph`` (fuel flow)``, pitch_deg,
    roll_deg, fuel_gal, weight_lb``, then the standard deviations ``alt_ft_std,
    pressure_alt_ft_std, oat_c_std, kias_std, ktas_std, vs_fpm_std, rpm_std,
    fuel_flow_gph_std, pitch_deg_std, roll_deg_std``. No segments give an empty frame with
    these columns.
    """
    rows = []
    for s in segments:
        row = {col: getattr(s, "fuel_flow_gph" if col == "gph" else col) for col in _TABLE_COLUMNS}
        row.update({f"{k}_std": v for k, v in s.std.items()})
        rows.append(row)
    std_cols = [f"{k}_std" for k in _STD_KEYS]
    return pd.DataFrame(rows, columns=_TABLE_COLUMNS + std_cols)
