"""Flight-test trims: snapshots and flaps-down climbs, their sign conventions and their quirks.

Sign conventions. The flight-test data (see ``data/README``) and JSBSim disagree:

=========  ===========================================  ======================================  =====
surface    data: positive means                         JSBSim (generated FCS): positive means  map
=========  ===========================================  ======================================  =====
elevator   trailing edge up (nose up), column aft       trailing edge down (nose down)          x -1
aileron    right aileron trailing edge up (roll right)  roll right                              x +1
rudder     trailing edge right (yaw right), right pedal trailing edge left (yaw left)           x -1
=========  ===========================================  ======================================  =====

Metrics keep the data's signs (``elevator_deg`` positive = trailing edge up); the model's
surfaces are converted with :data:`DATA_SIGN` in one place (:func:`to_data_sign`).

Cockpit controls map to surfaces through the control-travel table (end stops of each
control and surface), piecewise linearly through the control's neutral position (zero
surface): one slope to each stop. The table gives no neutral positions; each is estimated
from the snapshots themselves (median over rows of the neutral that makes the row's control
and surface agree), which for the C172 data gives column 2.71 in (the end-to-end linear
map), wheel 0.05 deg and pedals 20.77 in.

Quirks are detected, never fitted. A row is left out, with a :class:`QuirkWarning` naming
the row and the reason, when it has no flight data (ground and alternative-data tests),
misses a trim input, has an impossible value (outside the plausible range or a control
outside its travel), or a surface position that disagrees with its cockpit control by more
than :data:`CONSISTENCY_TOL_DEG` (Part 60's surface-position calibration tolerance, tests
2.a.1-2.a.3). Throttle and RPM are not used as targets (the data README: unreliable).

A snapshot is trimmed at its weight, CG, flaps, pressure altitude, true airspeed and
vertical speed, ISA (temperature was not recorded), with its bank angle as a steady
coordinated turn; mixture full rich (the POH climb procedure) where the data note full
throttle, best power otherwise. The throttle is a trim unknown (above the stop it pays the
penalty of the fit). A flaps-down climb is trimmed at full throttle and its speed; the rate
of climb is compared.
"""
from __future__ import annotations

import math
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np
import pandas as pd

from ..core.errors import DataError, Problem
from ..flight.condition import Condition, TrimResult
from .schemas import Column, Dataset, Schema, duplicate_rows, read_csv_checked, reference_columns, validate_frame

# data sign = DATA_SIGN * JSBSim sign (and back: the map is its own inverse)
DATA_SIGN = {"elevator": -1.0, "aileron": 1.0, "rudder": -1.0}
SURFACE_METRICS = {"elevator": "elevator_deg", "aileron": "aileron_deg", "rudder": "rudder_deg"}
CONTROL_COLUMNS = {"column": "column_in", "wheel": "wheel_deg", "pedals": "pedal_in"}
CONSISTENCY_TOL_DEG = 2.0          # [deg] surface vs cockpit control (Part 60 2.a.1-2.a.3)
TRAVEL_MARGIN = 0.02               # share of a control's travel allowed past its stops (reading error)
FULL_THROTTLE = 0.99               # recorded throttle at or above: full throttle noted (climb procedure)

SNAPSHOT_INPUTS = (
    Column("weight_lb", 500, 20000, "lb"), Column("cg_in", -100, 400, "in"), Column("flaps_deg", 0, 45, "deg"),
    Column("pressure_alt_ft", -2000, 30000, "ft"), Column("ktas", 20, 300, "kt"),
    Column("vs_fpm", -5000, 5000, "ft/min"),
)
SNAPSHOT_VALUES = (
    Column("pitch_deg", -45, 45, "deg"), Column("roll_deg", -90, 90, "deg"),
    Column("elevator_deg", -60, 60, "deg"), Column("aileron_deg", -60, 60, "deg"),
    Column("rudder_deg", -60, 60, "deg"),
)
SNAPSHOT_OPTIONAL = (
    Column("heading_deg", -360, 720, "deg", required=False), Column("column_in", -1e3, 1e3, "in", required=False),
    Column("wheel_deg", -1e3, 1e3, "deg", required=False), Column("pedal_in", -1e3, 1e3, "in", required=False),
    Column("throttle_norm", -10, 10, "-", required=False),
)
SNAPSHOT_METRICS = ("pitch_deg", "elevator_deg", "aileron_deg", "rudder_deg")

FLAP_CLIMB_SCHEMA = Schema(
    "flap_climb", "flight-test flaps-down climb: full throttle at weight, pressure altitude, KTAS, flaps",
    (Column("weight_lb", 500, 20000, "lb"), Column("pressure_alt_ft", -2000, 30000, "ft"),
     Column("ktas", 20, 300, "kt"), Column("flaps_deg", 0, 45, "deg"), Column("roc_fpm", -3000, 5000, "ft/min"),
     Column("cg_in", -100, 400, "in", required=False), Column("temp_dev_c", -60, 60, "deg C", required=False)),
    ("roc_fpm",))


class QuirkWarning(UserWarning):
    """A data row left out of fits and comparisons, with the reason."""


@dataclass(frozen=True)
class Quirk:
    row: str                # the row's label (table id, or 'row N')
    line: int               # CSV line (header = 1)
    reason: str

    def __str__(self) -> str:
        return f"{self.row} (line {self.line}): {self.reason}"


# --------------------------------------------------------------------------- signs
def to_data_sign(surface: str, jsbsim_deg: float) -> float:
    """A surface angle in JSBSim's sign convention expressed in the data's."""
    return DATA_SIGN[surface] * jsbsim_deg


def to_jsbsim_sign(surface: str, data_deg: float) -> float:
    """A surface angle in the data's sign convention expressed in JSBSim's."""
    return DATA_SIGN[surface] * data_deg


# --------------------------------------------------------------------------- control travel
@dataclass(frozen=True)
class ControlAxis:
    """A cockpit control and its surface (data signs): end stops and the neutral position."""

    control: str             # column | wheel | pedals
    unit: str
    control_min: float
    control_max: float
    surface: str             # elevator | aileron | rudder
    surface_min_deg: float
    surface_max_deg: float
    neutral: float           # control position at zero surface deflection

    @property
    def linear_neutral(self) -> float:
        """Neutral of the end-to-end linear map."""
        span = self.surface_max_deg - self.surface_min_deg
        return self.control_min - self.surface_min_deg / span * (self.control_max - self.control_min)

    def surface_deg(self, control: float) -> float:
        """Surface angle (data sign) for a control position: piecewise linear through neutral."""
        c0 = self.neutral
        if control >= c0:
            return self.surface_max_deg * (control - c0) / (self.control_max - c0)
        return self.surface_min_deg * (control - c0) / (self.control_min - c0)

    def control_position(self, surface_deg: float) -> float:
        """Control position for a surface angle (data sign): the inverse of :meth:`surface_deg`."""
        c0 = self.neutral
        if surface_deg >= 0:
            return c0 + surface_deg / self.surface_max_deg * (self.control_max - c0)
        return c0 + surface_deg / self.surface_min_deg * (self.control_min - c0)

    def implied_neutral(self, control: float, surface_deg: float) -> float:
        """The neutral position that makes one (control, surface) reading agree."""
        if surface_deg >= 0:
            return (self.surface_max_deg * control - surface_deg * self.control_max) / (self.surface_max_deg - surface_deg)
        a = -self.surface_min_deg
        return (a * control + surface_deg * self.control_min) / (surface_deg + a)

    def within_travel(self, control: float) -> bool:
        m = TRAVEL_MARGIN * (self.control_max - self.control_min)
        return self.control_min - m <= control <= self.control_max + m


AXIS_NAMES = {"longitudinal": ("column", "elevator"), "lateral": ("wheel", "aileron"),
              "directional": ("pedals", "rudder")}


def load_control_travel(path: str | Path) -> dict[str, ControlAxis]:
    """The control-travel table (one row per axis), keyed by surface; neutral = linear map's."""
    path = Path(path)
    raw = read_csv_checked(path)
    need = ["axis", "cockpit_control", "control_min", "control_max", "control_unit", "surface",
            "surface_min_deg", "surface_max_deg"]
    problems = [Problem(f"column '{c}'", "missing") for c in need if c not in raw.columns]
    if problems:
        raise DataError(path, problems)
    out: dict[str, ControlAxis] = {}
    for i, r in raw.iterrows():
        where = f"line {i + 2}"
        try:
            vals = [float(r[c]) for c in ("control_min", "control_max", "surface_min_deg", "surface_max_deg")]
        except ValueError:
            problems.append(Problem(where, "stops must be numbers"))
            continue
        surface = str(r["surface"]).strip()
        if surface not in DATA_SIGN:
            problems.append(Problem(where + ", column 'surface'", f"unknown surface '{surface}'"))
            continue
        if not (vals[0] < vals[1] and vals[2] < 0 < vals[3]):
            problems.append(Problem(where, "need control_min < control_max and surface_min < 0 < surface_max"))
            continue
        ax = ControlAxis(str(r["cockpit_control"]).strip(), str(r["control_unit"]).strip(), vals[0], vals[1],
                         surface, vals[2], vals[3], 0.0)
        out[surface] = ControlAxis(**{**ax.__dict__, "neutral": ax.linear_neutral})
    if problems:
        raise DataError(path, problems)
    return out


def control_column(axis: ControlAxis) -> str:
    return CONTROL_COLUMNS.get(axis.control, axis.control)


def estimate_neutrals(frame: pd.DataFrame, travel: dict[str, ControlAxis]) -> dict[str, ControlAxis]:
    """Neutral positions estimated from the rows (median of each row's implied neutral over
    rows whose control is inside its travel); the table's linear neutral where no row helps."""
    out = {}
    for surface, ax in travel.items():
        col, met = control_column(ax), SURFACE_METRICS[surface]
        guesses = []
        if col in frame and met in frame:
            for c, s in zip(frame[col], frame[met]):
                if np.isfinite(c) and np.isfinite(s) and ax.control_min < c < ax.control_max \
                        and ax.surface_min_deg < s < ax.surface_max_deg:
                    n = ax.implied_neutral(c, s)
                    if ax.control_min < n < ax.control_max:
                        guesses.append(n)
        n0 = float(np.median(guesses)) if guesses else ax.linear_neutral
        out[surface] = ControlAxis(**{**ax.__dict__, "neutral": n0})
    return out


# --------------------------------------------------------------------------- loading
def _numeric(raw: pd.DataFrame, name: str) -> np.ndarray:
    if name not in raw:
        return np.full(len(raw), np.nan)
    return pd.to_numeric(raw[name].astype(str).str.strip().replace("", np.nan), errors="coerce").to_numpy(float)


def _labels(raw: pd.DataFrame) -> list[str]:
    if "table" in raw:
        return [str(t).strip() or f"row {i + 1}" for i, t in enumerate(raw["table"])]
    return [f"row {i + 1}" for i in range(len(raw))]


def duplicate_ids(raw: pd.DataFrame) -> list[Problem]:
    """Snapshot ids ('table') given to two different rows (an identical row is
    :func:`.schemas.duplicate_rows`' to report)."""
    if "table" not in raw:
        return []
    cells = raw.astype(str).apply(lambda c: c.str.strip())
    first: dict[str, int] = {}
    out = []
    for i, t in enumerate(cells["table"]):
        j = first.setdefault(t, i) if t else i
        if j != i and not cells.iloc[i].equals(cells.iloc[j]):
            out.append(Problem(f"line {i + 2} ({t}), column 'table'", f"the id {t} is also line {j + 2}'s, with other "
                                                                     "values: give each snapshot its own id"))
    return out


def load_snapshots(path: Path, raw: pd.DataFrame, control_travel: str | Path | None = None) -> Dataset:
    """Validate a snapshot file; rows with quirks are left out, with a warning each."""
    cols = {c.strip() for c in raw.columns}
    raw = raw.rename(columns=lambda c: c.strip())
    missing = [c.name for c in SNAPSHOT_INPUTS + SNAPSHOT_VALUES if c.name not in cols]
    if missing:
        raise DataError(path, [Problem(f"column '{m}'", "missing") for m in missing])
    if not len(raw):
        raise DataError(path, Problem("", "no data rows"))
    labels = _labels(raw)
    frame = pd.DataFrame({c.name: _numeric(raw, c.name) for c in SNAPSHOT_INPUTS + SNAPSHOT_VALUES + SNAPSHOT_OPTIONAL})
    quirks: list[Quirk] = []
    bad = np.zeros(len(frame), bool)

    def flag(i: int, reason: str) -> None:
        if not bad[i]:
            quirks.append(Quirk(labels[i], i + 2, reason))
        bad[i] = True

    # unparseable text is an error of the file, not a quirk
    problems = []
    for c in SNAPSHOT_INPUTS + SNAPSHOT_VALUES + SNAPSHOT_OPTIONAL:
        if c.name not in raw:
            continue
        for i, t in enumerate(raw[c.name].astype(str)):
            t = t.strip()
            if t and not np.isfinite(frame[c.name].iloc[i]) and t.lower() != "nan":
                problems.append(Problem(f"line {i + 2} ({labels[i]}), column '{c.name}'", f"'{t}' is not a number"))
    problems += duplicate_rows(raw, labels) + duplicate_ids(raw)
    if problems:
        raise DataError(path, problems)
    core = [c.name for c in SNAPSHOT_INPUTS + SNAPSHOT_VALUES]
    for i in range(len(frame)):
        row = frame.iloc[i]
        if row[core].isna().all():
            flag(i, "no flight data (ground test or alternative data)")
            continue
        gaps = [c for c in core if not np.isfinite(row[c])]
        if gaps:
            flag(i, f"missing {', '.join(gaps)}")
            continue
        for c in SNAPSHOT_INPUTS + SNAPSHOT_VALUES:
            if not c.lo <= row[c.name] <= c.hi:
                flag(i, f"impossible {c.name} {row[c.name]:g} {c.unit} (plausible {c.lo:g} to {c.hi:g})")
    travel = None
    if control_travel is not None:
        travel = estimate_neutrals(frame[~bad], load_control_travel(control_travel))
        for i in range(len(frame)):
            if bad[i]:
                continue
            row = frame.iloc[i]
            for surface, ax in travel.items():
                col, met = control_column(ax), SURFACE_METRICS[surface]
                c, s = row.get(col, np.nan), row[met]
                if not ax.surface_min_deg - 0.5 <= s <= ax.surface_max_deg + 0.5:
                    flag(i, f"impossible {met} {s:g} deg: outside the {surface} travel "
                            f"[{ax.surface_min_deg:g}, {ax.surface_max_deg:g}]")
                    continue
                if not np.isfinite(c):
                    continue
                if not ax.within_travel(c):
                    flag(i, f"impossible {col} {c:g} {ax.unit}: outside the {ax.control} travel "
                            f"[{ax.control_min:g}, {ax.control_max:g}]")
                    continue
                expect = ax.surface_deg(c)
                if abs(s - expect) > CONSISTENCY_TOL_DEG:
                    flag(i, f"{met} {s:g} deg disagrees with {col} {c:g} {ax.unit} "
                            f"(the control-travel table gives {expect:.1f} deg)")
    for q in quirks:
        warnings.warn(f"{path.name}: {q}; left out", QuirkWarning, stacklevel=3)
    if bad.all():
        raise DataError(path, [Problem("", f"no usable row: all {len(frame)} rows are left out")] +
                        [Problem(f"line {q.line} ({q.row})", q.reason) for q in quirks[:10]])
    frame.insert(0, "table", labels)
    frame["line"] = np.arange(2, len(frame) + 2)
    usable = frame[~bad].reset_index(drop=True)
    ref = reference_columns(raw, ~bad)
    return Dataset("snapshot", path, usable, ref, SNAPSHOT_METRICS,
                   extra={"quirks": quirks, "travel": travel, "rows": len(frame)})


def load_flap_climbs(path: Path, raw: pd.DataFrame) -> Dataset:
    frame = validate_frame(raw, FLAP_CLIMB_SCHEMA, path)
    frame.insert(0, "table", _labels(raw))
    ref = reference_columns(raw)
    return Dataset("flap_climb", path, frame, ref, ("roc_fpm",), extra={"quirks": [], "rows": len(frame)})


def load_flight_test(path: Path, raw: pd.DataFrame, kind: str, control_travel: str | Path | None = None) -> Dataset:
    if kind == "snapshot":
        return load_snapshots(path, raw, control_travel)
    return load_flap_climbs(path, raw)


# --------------------------------------------------------------------------- trim conditions
def snapshot_conditions(ds: Dataset, geom) -> list[Condition]:
    out = []
    for _, r in ds.frame.iterrows():
        thr = r.get("throttle_norm", np.nan)
        climb = bool(np.isfinite(thr) and thr >= FULL_THROTTLE)
        bank = float(r["roll_deg"])
        out.append(Condition(pressure_alt_ft=float(r["pressure_alt_ft"]), weight_lb=float(r["weight_lb"]),
                             ktas=float(r["ktas"]), cg_in=float(r["cg_in"]), flaps_deg=float(r["flaps_deg"]),
                             mode="level", vs_fpm=float(r["vs_fpm"]), bank_deg=bank,
                             turn="coordinated" if bank != 0.0 else "straight",
                             mixture="climb" if climb else "cruise", isa_dev_c=0.0))
    return out


def _surface_value(surface: str) -> Callable[[TrimResult], float]:
    return lambda t: to_data_sign(surface, getattr(t, SURFACE_METRICS[surface]))


# what a snapshot's and a flaps-down climb's metrics compare: trim outputs, surfaces in the data's signs
SNAPSHOT_OUTPUTS: dict[str, Callable[[TrimResult], float]] = {
    "pitch_deg": lambda t: t.theta_deg, "roll_deg": lambda t: t.phi_deg,
    **{m: _surface_value(s) for s, m in SURFACE_METRICS.items()}, "roc_fpm": lambda t: t.roc_fpm}
FLAP_CLIMB_OUTPUTS = {m: SNAPSHOT_OUTPUTS[m] for m in ("roc_fpm", "pitch_deg")}


def snapshot_value(metric: str, t: TrimResult) -> float:
    return SNAPSHOT_OUTPUTS[metric](t)


def flap_climb_conditions(ds: Dataset, geom) -> list[Condition]:
    f = ds.frame
    return [Condition(pressure_alt_ft=float(r["pressure_alt_ft"]), weight_lb=float(r["weight_lb"]),
                      ktas=float(r["ktas"]), flaps_deg=float(r["flaps_deg"]), mode="full_throttle",
                      mixture="climb", isa_dev_c=float(r["temp_dev_c"]) if "temp_dev_c" in f else 0.0,
                      cg_in=float(r["cg_in"]) if "cg_in" in f and math.isfinite(r["cg_in"]) else None)
            for _, r in f.iterrows()]


def flap_climb_value(metric: str, t: TrimResult) -> float:
    return FLAP_CLIMB_OUTPUTS[metric](t)
