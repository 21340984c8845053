"""Garmin G1000 logs as reference data: segments -> trim conditions -> evaluation.

A log is read and cut into quasi-steady segments by :mod:`jsbsim_calib.data.g1000` (criteria in
:class:`~jsbsim_calib.data.g1000.segments.SegmentCriteria`). Each segment becomes one data point:

* level cruise: level flight (the segment's mean vertical speed) at its pressure altitude,
  OAT and true airspeed, best-power mixture (the pilot leaned) -> RPM and pitch attitude;
* full-throttle climb: full throttle at its calibrated airspeed, mixture per the POH climb
  procedure -> rate of climb (pressure-altitude rate, as the G1000's VSpd) and pitch.

Weight: the log has fuel but no weight record. ``weight = empty + occupants + baggage +
fuel``, with the aircraft's empty weight from its geometry file and the occupants and baggage
of :class:`LogLoading` -- a stated assumption (two 170 lb adults, no baggage), to be changed
when the loading is known. The CG is the aircraft's default (its POH CG) unless ``LogLoading.cg_in``
gives it; loading values outside their plausible ranges are refused (:func:`loading_problems`).
"""
from __future__ import annotations

import math
import numbers
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from ..core.errors import DataError, InputError, Problem, raise_if
from ..core.units import IN, LBM
from ..flight.condition import Condition, TrimResult
from ..physics.geometry import AircraftGeometry
from .g1000.parse import read_g1000
from .g1000.segments import SegmentCriteria, WeightAssumption, extract_segments, segments_dataframe
from .schemas import Dataset, temperature_problems

METRICS = ("rpm", "roc_fpm", "pitch_deg")


@dataclass(frozen=True)
class LogLoading:
    """Assumed payload of a logged flight (the log records fuel only)."""

    occupants_lb: float = 340.0       # [lb] assumed: two adults at the FAA standard 170 lb
    baggage_lb: float = 0.0           # [lb] assumed
    fuel_density_lb_per_gal: float = 6.0   # [lb/US gal] avgas
    cg_in: float | None = None        # [in] CG station; None: the aircraft's POH CG

    def __post_init__(self):
        raise_if(loading_problems(self), "G1000 loading", InputError)


# plausible inputs of a logged flight's loading (anything outside is refused, never clipped)
LOADING_RANGES = {"occupants_lb": (0.0, 1500.0), "baggage_lb": (0.0, 1000.0),
                  "fuel_density_lb_per_gal": (5.0, 7.5), "cg_in": (0.0, 400.0)}
MAX_WEIGHT_MARGIN = 1.25     # a log's weight may exceed the aircraft's maximum weight by at most this factor


def loading_problems(loading: LogLoading) -> list[Problem]:
    """Every loading value that is not a number or outside its plausible range (LOADING_RANGES)."""
    out = []
    for name, (lo, hi) in LOADING_RANGES.items():
        v = getattr(loading, name)
        if v is None and name == "cg_in":
            continue
        if not isinstance(v, numbers.Real) or isinstance(v, bool) or not math.isfinite(v):
            out.append(Problem(name, f"{v!r} is not a finite number"))
        elif not lo <= v <= hi:
            out.append(Problem(name, f"{v:g} is outside the plausible range [{lo:g}, {hi:g}]"))
    return out


def check_loading_for(geometry: AircraftGeometry, loading: LogLoading, weights_lb) -> None:
    """The loading against the aircraft: the CG within its envelope's stations, the weights
    within :data:`MAX_WEIGHT_MARGIN` of its maximum weight."""
    problems = []
    m = geometry.mass
    if loading.cg_in is not None:
        fwd, aft = float(np.min(m.cg_envelope_fwd_m)) / IN, float(np.max(m.cg_envelope_aft_m)) / IN
        if not fwd <= loading.cg_in <= aft:
            problems.append(Problem("cg_in", f"{loading.cg_in:g} in is outside the aircraft's CG envelope "
                                              f"[{fwd:.1f}, {aft:.1f}] in"))
    w_max = m.max_mass_kg / LBM
    heaviest = float(np.max(weights_lb)) if len(weights_lb) else 0.0
    if heaviest > MAX_WEIGHT_MARGIN * w_max:
        problems.append(Problem("weight", f"the loading gives {heaviest:.0f} lb, more than {MAX_WEIGHT_MARGIN:g} x "
                                          f"the maximum weight {w_max:.0f} lb"))
    raise_if(problems, "G1000 loading", InputError)


MIN_RUNNING_RPM = 500.0      # below this through a segment in flight, the engine speed is not recorded
# log channels a segment's comparison needs (its metrics), by the segment's name for them
NEEDED_CHANNELS = {"rpm": "E1 RPM", "pitch_deg": "Pitch"}


def channel_problems(segs) -> list[Problem]:
    """Segments through which a channel they need is zero (the engine speed) or does not move
    at all (a stuck or unrecorded channel: no sensor reads the same to the last digit for 30 s
    of flight)."""
    out = []
    for k, s in enumerate(segs, 1):
        where = f"segment {k} ({s.kind}, t {s.t_start_s:.0f}-{s.t_end_s:.0f} s)"
        if not s.rpm >= MIN_RUNNING_RPM:
            out.append(Problem(f"{where}, column '{NEEDED_CHANNELS['rpm']}'",
                               f"{s.rpm:g} rpm through the segment: the engine speed is not recorded (or the engine "
                               "is stopped); a segment needs it"))
            continue
        for name, channel in NEEDED_CHANNELS.items():
            if s.n_samples >= 10 and s.std.get(name, 1.0) == 0.0:
                out.append(Problem(f"{where}, column '{channel}'", f"constant at {getattr(s, name):g} for "
                                   f"{s.n_samples} samples: a stuck or unrecorded channel"))
    return out


SEGMENT_QUANTITIES = {"pressure_alt_ft": "AltB and BaroA", "oat_c": "OAT", "kcas": "IAS", "ktas": "TAS",
                      "weight_lb": "FQtyL and FQtyR", "pitch_deg": "Pitch"}    # what a segment needs, from


def nonfinite_problems(frame: pd.DataFrame) -> list[Problem]:
    """Segments whose mean of a quantity the trims need is not a number (a damaged channel that
    the segment criteria did not see): named with the segment and the log's columns."""
    out = []
    for i in range(len(frame)):
        where = f"segment {i + 1} (t {frame['t_start_s'].iloc[i]:.0f}-{frame['t_end_s'].iloc[i]:.0f} s)"
        for q, columns in SEGMENT_QUANTITIES.items():
            v = frame[q].iloc[i]
            if not (isinstance(v, numbers.Real) and math.isfinite(v)):
                out.append(Problem(f"{where}, column(s) {columns}", f"{q} is {v!r} over the segment: not a number"))
    return out


def log_dataset(path: str | Path, geometry: AircraftGeometry, loading: LogLoading = LogLoading(),
                criteria: SegmentCriteria = SegmentCriteria(), *, require_segments: bool = True) -> Dataset:
    """The quasi-steady segments of a log as a dataset of kind ``g1000``. A log without a
    segment is refused (DataError) unless ``require_segments=False`` (a fleet lists it); a
    segment whose OAT is implausible at its pressure altitude is refused."""
    path = Path(path)
    log = read_g1000(path)
    weight = WeightAssumption(empty_weight_lb=geometry.mass.empty_mass_kg / LBM,
                              occupants_lb=loading.occupants_lb, baggage_lb=loading.baggage_lb,
                              fuel_density_lb_per_gal=loading.fuel_density_lb_per_gal)
    segs = extract_segments(log, criteria, weight=weight)
    if not segs and require_segments:
        raise DataError(path, Problem("", f"no quasi-steady segment in {log.duration_s:.0f} s of log ({len(log.data)} "
                                          "rows): nothing to compare (criteria: level cruise or full-throttle climb "
                                          "of 30 s or more, jsbsim_calib.data.g1000.segments.SegmentCriteria)"))
    raise_if(channel_problems(segs), path, DataError)
    table = segments_dataframe(segs)
    frame = table.copy()
    frame.insert(0, "segment", np.arange(1, len(frame) + 1))
    frame["flaps_deg"] = 0.0
    cruise = frame["kind"] == "cruise"
    frame["rpm"] = np.where(cruise, table["rpm"], np.nan)
    frame["roc_fpm"] = np.where(cruise, np.nan, table["vs_fpm"])
    frame["pitch_deg"] = table["pitch_deg"]
    raise_if(nonfinite_problems(frame), path, DataError)
    raise_if(temperature_problems(frame, lambda i, c: f"segment {i + 1} (t {frame['t_start_s'].iloc[i]:.0f}-"
                                                      f"{frame['t_end_s'].iloc[i]:.0f} s), column 'OAT'"),
             path, DataError)
    note = (f"weight = empty {weight.empty_weight_lb:.0f} lb + occupants {loading.occupants_lb:.0f} lb + baggage "
            f"{loading.baggage_lb:.0f} lb (assumed) + logged fuel x {loading.fuel_density_lb_per_gal:g} lb/gal")
    check_loading_for(geometry, loading, frame["weight_lb"].to_numpy(float) if len(frame) else [])
    if (loading.occupants_lb, loading.baggage_lb) != (LogLoading.occupants_lb, LogLoading.baggage_lb):
        note = note.replace("(assumed)", "(given)")
    if loading.cg_in is not None:
        note += f"; CG {loading.cg_in:g} in (given)"
    return Dataset("g1000", path, frame, pd.DataFrame(), METRICS,
                   extra={"log": log, "segments": segs, "table": table, "weight_note": note, "quirks": [],
                          "cg_in": loading.cg_in})


def log_conditions(ds: Dataset, geom: AircraftGeometry) -> list[Condition]:
    out = []
    for _, r in ds.frame.iterrows():
        if r["kind"] == "cruise":
            out.append(Condition(pressure_alt_ft=float(r["pressure_alt_ft"]), weight_lb=float(r["weight_lb"]),
                                 ktas=float(r["ktas"]), oat_c=float(r["oat_c"]), mode="level",
                                 vs_fpm=float(r["vs_fpm"]), mixture="cruise", cg_in=ds.extra.get("cg_in")))
        else:
            out.append(Condition(pressure_alt_ft=float(r["pressure_alt_ft"]), weight_lb=float(r["weight_lb"]),
                                 kcas=float(r["kcas"]), oat_c=float(r["oat_c"]), mode="full_throttle",
                                 mixture="climb", cg_in=ds.extra.get("cg_in")))
    return out


# the trim outputs a log's metrics compare (the G1000's VSpd is the pressure-altitude rate)
LOG_VALUES = {"rpm": "rpm", "roc_fpm": "roc_pressure_fpm", "pitch_deg": "theta_deg"}


def log_value(metric: str, t: TrimResult) -> float:
    return getattr(t, LOG_VALUES[metric])
