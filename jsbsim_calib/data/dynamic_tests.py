"""The flight test's dynamic tests, from their published summaries: what was flown, what was
measured, and what we have to assume.

Only summaries of the dynamic tests survive (``c172_flight_test_results.csv``): a peak body
rate after a control pulse, the phugoid's period and damping, the steady roll rate after a
wheel step. Each result row ``C.n`` belongs to the snapshot row ``C.(n-1)`` that holds the
test's initial condition (weight, CG, flaps, pressure altitude, KTAS, vertical speed, bank).
A :class:`DynamicTest` pairs them with a :class:`~jsbsim_calib.jsbsim.trajectory.Maneuver`
built from the Part 60 procedure and stated assumptions:

* pulses (2.b.1-2.b.6): a 1 s pulse (0.1 s ramps) of :data:`PULSE_FRACTION` of the control
  travel from neutral toward the stop in the direction the result's sign gives. The pulse
  amplitude was not recorded: the peak rate depends on it, so these metrics are marked
  ``amplitude_dependent`` and never decide a factor alone (:mod:`jsbsim_calib.calibration.dynamic`).
* roll response (2.d.2): a wheel step of :data:`ROLL_STEP_FRACTION` of the travel toward the
  roll the result's sign gives ("about one-third of maximum roll controller travel", taken
  from neutral to the stop), held; the steady roll rate is the mean roll rate 1 to 3 s after
  the step.
* engine acceleration (1.f.1): no flight-test initial condition and no recorded response, only
  the FAA's alternative data, a range ("2 - 4" s, 10 % to 90 % of the RPM response); flown at
  :data:`ENGINE_CONDITION`, the range's middle is the value and its half-width the tolerance.
* phugoid (2.c.9.b): column aft (elevator :data:`PHUGOID_ELEVATOR_DEG` trailing edge up)
  for :data:`PHUGOID_HOLD_S`, which slows the aircraft by about 10 kt, then released (stick
  fixed: the simulator has no reversible controls, as the method notes); period and damping
  ratio from the airspeed oscillation that follows.

Surface angles here are in JSBSim's signs (the maneuver's); the data's signs are mapped by
:mod:`.flighttest`.
"""
from __future__ import annotations

import math
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from ..core.errors import DataError, ModelError, Problem
from ..flight.condition import Condition
from ..jsbsim.trajectory import Input, Maneuver
from ..physics.geometry import AircraftGeometry
from .flighttest import SNAPSHOT_INPUTS, ControlAxis, load_control_travel, to_jsbsim_sign
from .schemas import Column, read_csv_checked

PULSE_FRACTION = 1.0 / 3.0        # assumed pulse amplitude, share of the travel from neutral to the stop
ROLL_STEP_FRACTION = 1.0 / 3.0    # the roll-response step (data README: about 1/3 of full travel)
PULSE_START_S, PULSE_LENGTH_S, RAMP_S = 0.5, 1.0, 0.1
PULSE_WINDOW_S = 6.0
ROLL_STEP_START_S = 0.5
ROLL_WINDOW_S = (1.0, 3.0)        # after the step: where the steady roll rate is averaged
PHUGOID_ELEVATOR_DEG = -1.0       # JSBSim sign (trailing edge up): with the hold, about 10 kt slower (C172)
PHUGOID_HOLD_S = 4.0
PHUGOID_DURATION_S = 130.0       # three up-crossings after the release at periods up to 40 s

RESULT_COLUMNS = ("table", "title", "metric", "tolerance", "flight_test")
KINDS = {   # result metric text -> (kind, metric name, unit, channel, surface)
    "Maximum Pitch Rate": ("pitch_pulse", "max_pitch_rate_deg_s", "deg/s", "q_deg_s", "elevator"),
    "Maximum Roll Rate": ("roll_pulse", "max_roll_rate_deg_s", "deg/s", "p_deg_s", "aileron"),
    "Maximum Yaw Rate": ("yaw_pulse", "max_yaw_rate_deg_s", "deg/s", "r_deg_s", "rudder"),
    "Steady-state Roll Rate": ("roll_step", "roll_rate_deg_s", "deg/s", "p_deg_s", "aileron"),
    "Period": ("phugoid", "phugoid_period_s", "s", "kcas", "elevator"),
    "Damping Ratio": ("phugoid", "phugoid_damping", "-", "kcas", "elevator"),
    "ΔT": ("engine_acceleration", "response_time_s", "s", "rpm", "throttle"),
}
# engine acceleration: no flight data; flown at a stated approach condition (the method's note)
ENGINE_CONDITION = Condition(pressure_alt_ft=3000.0, weight_lb=2400.0, kcas=70.0, flaps_deg=20.0,
                             mode="full_throttle", throttle=0.0, mixture="climb")
ENGINE_STEP_S, ENGINE_RAMP_S, ENGINE_WINDOW_S = 1.0, 0.1, 10.0
ENGINE_ASSUMPTIONS = (
    "no flight-test initial condition: trimmed at 3,000 ft, 2,400 lb, POH CG, flaps 20, 70 KCAS with the "
    "throttle at idle (a descent), ISA, full rich",
    f"throttle idle -> full in {ENGINE_RAMP_S:g} s at {ENGINE_STEP_S:g} s, stick fixed",
    "response: engine RPM from its idle value to the highest value within "
    f"{ENGINE_WINDOW_S:g} s; T_i, T_t from the start of the throttle movement",
)
# the surface a positive body rate asks for, data sign (pitch up: trailing edge up; roll right:
# right aileron up; yaw right: rudder trailing edge right)
POSITIVE_RATE_SURFACE = {"elevator": +1.0, "aileron": +1.0, "rudder": +1.0}


@dataclass(frozen=True)
class DynamicMetric:
    """A measured summary value and its Part 60 tolerance (None: "representative", judged by
    an evaluator, no pass/fail)."""

    name: str
    measured: float
    tolerance: float | None
    relative: bool
    unit: str
    amplitude_dependent: bool
    thesis_model: float = math.nan

    def tol(self) -> float:
        if self.tolerance is None:
            return math.nan
        return self.tolerance * abs(self.measured) if self.relative else self.tolerance

    def tolerance_text(self) -> str:
        if self.tolerance is None:
            return "representative"
        return f"+-{self.tolerance * 100:g} %" if self.relative else f"+-{self.tolerance:g} {self.unit}"


@dataclass(frozen=True)
class DynamicTest:
    id: str                     # result table id (C.19)
    initial: str                # snapshot row with the initial condition (C.18)
    part60: str                 # Part 60 test id (2.b.1)
    title: str
    kind: str                   # pitch_pulse | roll_pulse | yaw_pulse | roll_step | phugoid
    maneuver: Maneuver
    metrics: tuple[DynamicMetric, ...]
    channel: str                # the trajectory channel the metrics read
    assumptions: tuple[str, ...]


def parse_tolerance(text: str) -> tuple[float | None, bool]:
    """'$\\pm 20\\%$ (...)' -> (0.2, relative); '$\\pm 2^\\circ/s$' -> (2.0, absolute); '' -> (None, False)."""
    t = str(text) if text is not None else ""
    if not t.strip() or t.strip().lower() == "nan":
        return None, False
    m = re.search(r"(\d+(?:\.\d+)?)\s*\\?%", t)
    if m:
        return float(m.group(1)) / 100.0, True
    m = re.search(r"(\d+(?:\.\d+)?)", t)
    return (float(m.group(1)), False) if m else (None, False)


def _number(text) -> float:
    try:
        return float(str(text).split("±")[0].replace("%", "").strip())
    except ValueError:
        return math.nan


def _initial_id(result_id: str) -> str:
    prefix, _, n = result_id.rpartition(".")
    return f"{prefix}.{int(n) - 1}"


def _condition(row: pd.Series, where: str, problems: list) -> Condition | None:
    vals = {}
    for c in SNAPSHOT_INPUTS + (Column("roll_deg", -90, 90, "deg"),):
        v = pd.to_numeric(row.get(c.name), errors="coerce")
        if not (np.isfinite(v) and c.lo <= v <= c.hi):
            problems.append(Problem(f"{where}, column '{c.name}'", f"initial condition missing or impossible: "
                                                                    f"{row.get(c.name)!r}"))
            return None
        vals[c.name] = float(v)
    bank = vals["roll_deg"]
    return Condition(pressure_alt_ft=vals["pressure_alt_ft"], weight_lb=vals["weight_lb"], ktas=vals["ktas"],
                     cg_in=vals["cg_in"], flaps_deg=vals["flaps_deg"], vs_fpm=vals["vs_fpm"], bank_deg=bank,
                     turn="coordinated" if bank != 0.0 else "straight", mixture="cruise")


def _pulse(name: str, start: Condition, surface: str, amplitude_deg: float, title: str) -> Maneuver:
    channel = f"{surface}_deg"
    t0, L, r = PULSE_START_S, PULSE_LENGTH_S, RAMP_S
    inp = Input(channel, (0.0, t0, t0 + r, t0 + L, t0 + L + r), (0.0, 0.0, amplitude_deg, amplitude_deg, 0.0))
    return Maneuver(name, start, PULSE_WINDOW_S, (inp,), title=title)


def _travel_deg(travel: dict[str, ControlAxis], surface: str, data_sign: float) -> float:
    ax = travel[surface]
    return ax.surface_max_deg if data_sign > 0 else -ax.surface_min_deg


def engine_maneuver(start: Condition = ENGINE_CONDITION) -> Maneuver:
    """1.f.1: from the trim at idle, the throttle idle -> full (absolute), stick fixed."""
    t0, r = ENGINE_STEP_S, ENGINE_RAMP_S
    inp = Input("throttle_norm", (0.0, t0, t0 + r), (start.throttle, start.throttle, 1.0), relative=False)
    return Maneuver("part60_1f1_engine_acceleration", start, t0 + ENGINE_WINDOW_S, (inp,),
                    title="1.f.1 Engine acceleration")


def range_value(text) -> tuple[float, float]:
    """A range '2 - 4' -> (3.0, 1.0): its middle and half-width; anything else (NaN, NaN)."""
    m = re.fullmatch(r"\s*(\d+(?:\.\d+)?)\s*-\s*(\d+(?:\.\d+)?)\s*", str(text))
    if not m:
        return math.nan, math.nan
    lo, hi = float(m.group(1)), float(m.group(2))
    return (0.5 * (lo + hi), 0.5 * (hi - lo)) if hi > lo else (math.nan, math.nan)


def _engine_test(tid: str, i: int, row: pd.Series, file: str, problems: list) -> DynamicTest | None:
    """The engine acceleration row: its range as the value and tolerance (module doc). The
    deceleration (1.f.2) is a ground test with the brakes set: not flown (Part 60's report says so)."""
    title = str(row["title"]).strip()
    if not title.startswith("1.f.1"):
        return None
    value, half = range_value(row["flight_test"])
    if not math.isfinite(value):
        problems.append(Problem(f"{file}: line {i + 2} ({tid}), column 'flight_test'",
                                f"'{row['flight_test']}' is not a range such as '2 - 4'"))
        return None
    metric = DynamicMetric("response_time_s", value, half, False, "s", False, _number(row.get("thesis_model")))
    return DynamicTest(tid, "", title.split(" ")[0], title, "engine_acceleration", engine_maneuver(), (metric,),
                       "rpm", ENGINE_ASSUMPTIONS + (f"flight test '{row['flight_test']}': its middle, "
                                                    f"{value:g} +- {half:g} s",))


def _maneuver(kind: str, test_id: str, start: Condition, surface: str, measured: float,
              travel: dict[str, ControlAxis], title: str) -> tuple[Maneuver, tuple[str, ...]]:
    name = f"{test_id.replace('.', '_')}_{kind}"
    if kind == "phugoid":
        inp = Input("elevator_deg", (0.0, 0.5, 0.5 + RAMP_S, 0.5 + PHUGOID_HOLD_S, 0.5 + PHUGOID_HOLD_S + RAMP_S),
                    (0.0, 0.0, PHUGOID_ELEVATOR_DEG, PHUGOID_ELEVATOR_DEG, 0.0))
        return Maneuver(name, start, PHUGOID_DURATION_S, (inp,), title=title), (
            f"elevator {abs(PHUGOID_ELEVATOR_DEG):g} deg trailing edge up for {PHUGOID_HOLD_S:g} s, then released "
            "(stick fixed)",)
    sign = math.copysign(1.0, measured) * POSITIVE_RATE_SURFACE[surface]     # data sign of the input
    frac = ROLL_STEP_FRACTION if kind == "roll_step" else PULSE_FRACTION
    amp_data = sign * frac * _travel_deg(travel, surface, sign)
    amp = to_jsbsim_sign(surface, amp_data)
    what = f"{surface} {abs(amp_data):.1f} deg ({frac:.2g} of its travel toward the stop)"
    if kind == "roll_step":
        inp = Input("aileron_deg", (0.0, ROLL_STEP_START_S, ROLL_STEP_START_S + RAMP_S), (0.0, 0.0, amp))
        return Maneuver(name, start, ROLL_STEP_START_S + ROLL_WINDOW_S[1] + 0.5, (inp,), title=title), (
            f"wheel step: {what}, held",)
    return _pulse(name, start, surface, amp, title), (
        f"1 s pulse of {what}: the amplitude was not recorded (assumed)",)


def read_results(results: str | Path, snapshots: str | Path) -> tuple[pd.DataFrame, dict[str, pd.Series]]:
    """A results file (its columns checked) and the snapshot rows by table id (C.1, ...)."""
    res = read_csv_checked(Path(results)).rename(columns=lambda c: c.strip())
    missing = [c for c in RESULT_COLUMNS if c not in res]
    if missing:
        raise DataError(results, [Problem(f"column '{c}'", "missing") for c in missing])
    snap = read_csv_checked(Path(snapshots)).rename(columns=lambda c: c.strip())
    if "table" not in snap:
        raise DataError(snapshots, [Problem("column 'table'", "missing")])
    return res, {str(r["table"]).strip(): r for _, r in snap.iterrows()}


def load_dynamic_tests(results: str | Path, snapshots: str | Path, travel: dict[str, ControlAxis]) -> list[DynamicTest]:
    """The dynamic tests of a flight-test results file whose initial conditions the snapshot
    file holds. Rows of other kinds (climbs, trims, engine) are not dynamic tests here."""
    results, snapshots = Path(results), Path(snapshots)
    res, snap_rows = read_results(results, snapshots)
    problems: list[Problem] = []
    grouped: dict[str, list] = {}
    for i, r in res.iterrows():
        kind = KINDS.get(str(r["metric"]).strip())
        if kind is None:
            continue
        grouped.setdefault(str(r["table"]).strip(), []).append((i, r, kind))
    tests = []
    for tid, rows in grouped.items():
        if rows[0][2][0] == "engine_acceleration":
            test = _engine_test(tid, rows[0][0], rows[0][1], results.name, problems)
            tests += [test] if test else []
            continue
        init = _initial_id(tid)
        where = f"{snapshots.name}: row {init} (initial condition of {tid})"
        if init not in snap_rows:
            problems.append(Problem(f"{results.name}: {tid}", f"no snapshot row {init} holds its initial condition"))
            continue
        start = _condition(snap_rows[init], where, problems)
        if start is None:
            continue
        metrics = []
        for i, r, (kind, mname, unit, channel, surface) in rows:
            value = _number(r["flight_test"])
            if not math.isfinite(value):
                problems.append(Problem(f"{results.name}: line {i + 2} ({tid}), column 'flight_test'",
                                        f"'{r['flight_test']}' is not a number"))
                continue
            tol, rel = parse_tolerance(r["tolerance"])
            metrics.append(DynamicMetric(mname, value, tol, rel, unit, kind.endswith("pulse"),
                                         _number(r.get("thesis_model"))))
        if not metrics:
            continue
        kind, _, _, channel, surface = rows[0][2]
        title = str(rows[0][1]["title"]).strip()
        part60 = title.split(" ")[0]
        maneuver, assumptions = _maneuver(kind, tid, start, surface, metrics[0].measured, travel, title)
        tests.append(DynamicTest(tid, init, part60, title, kind, maneuver, tuple(metrics), channel, assumptions))
    if problems:
        raise DataError(results, problems)
    return tests


def aircraft_dynamic_tests(geom: AircraftGeometry, name: str) -> list[DynamicTest]:
    """The dynamic tests of aircraft ``name`` (its geometry ``geom``): its flight-test results file
    with the snapshots' initial conditions."""
    missing = [k for k in ("flight_test", "flight_test_results") if k not in geom.data_files]
    if missing or geom.control_travel_file is None:
        raise ModelError(f"aircraft/{name}/geometry.toml names no {', '.join(missing) or 'control travel'} "
                         "([data] table): no dynamic tests")
    return load_dynamic_tests(geom.data_files["flight_test_results"], geom.data_files["flight_test"],
                              load_control_travel(geom.control_travel_file))
