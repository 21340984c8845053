"""Dynamic tests: fly each maneuver, measure what the flight test measured, compare.

The measurements are pure functions of a flown trace (:func:`peak_rate`,
:func:`steady_roll_rate`, :func:`phugoid`); :func:`evaluate_dynamic` flies every test of a
list on a simulator and returns a :class:`DynamicEvaluation` (typed results: value, error,
tolerance, within; a NaN is never within).
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Mapping, Sequence

import numpy as np

from ..data.dynamic_tests import (ENGINE_STEP_S, PHUGOID_HOLD_S, PULSE_START_S, ROLL_STEP_START_S, ROLL_WINDOW_S, DynamicMetric,
                                 DynamicTest)
from ..data.flighttest import ControlAxis, to_jsbsim_sign
from ..data.timehistory import SURFACE_OF, TimeHistory, load_time_histories, maneuver_from_time_history
from ..core.errors import CalibError
from .evaluate import MetricSummary, Summary
from ..core.executor import SERIAL, Executor
from ..jsbsim.simulator import Simulator
from ..jsbsim.trajectory import RATE_HZ, Trajectory, fly


# --------------------------------------------------------------------------- measurements
def _mean(x) -> float:
    """Correctly rounded mean (numpy's SIMD reductions may sum in a CPU's order: the fits
    read these numbers, and must give the same bits on every CPU)."""
    return math.fsum(np.asarray(x, float).tolist()) / len(x)


def peak_rate(t: np.ndarray, rate: np.ndarray, start_s: float, sign: float) -> float:
    """Largest change of a body rate from its value at ``start_s``, in the direction ``sign``
    (the signed peak: a response the wrong way is negative)."""
    i0 = int(np.searchsorted(t, start_s))
    d = sign * (rate[i0:] - rate[i0])
    return float(sign * np.max(d)) if d.size else math.nan


def steady_roll_rate(t: np.ndarray, p: np.ndarray, step_s: float, window=ROLL_WINDOW_S) -> float:
    """Mean roll rate between ``window`` seconds after the step."""
    m = (t >= step_s + window[0]) & (t <= step_s + window[1])
    return _mean(p[m]) if m.any() else math.nan


def phugoid(t: np.ndarray, speed: np.ndarray, release_s: float) -> tuple[float, float]:
    """Period [s] and damping ratio of the oscillation of ``speed`` after ``release_s``: the
    period from successive up-crossings of the mean, the damping from the logarithmic
    decrement of successive peaks (first two cycles). NaN where fewer than two cycles show."""
    m = t >= release_s + 2.0
    ts, v = t[m], speed[m]
    if ts.size < 10:
        return math.nan, math.nan
    dv = v - _mean(v)
    up = np.flatnonzero((dv[:-1] < 0) & (dv[1:] >= 0))
    if up.size < 3:
        return math.nan, math.nan
    # crossing times by linear interpolation between frames
    tc = ts[up] + (ts[up + 1] - ts[up]) * (-dv[up]) / (dv[up + 1] - dv[up])
    period = _mean(np.diff(tc[:3]))
    peaks = [float(np.max(np.abs(dv[a:b]))) for a, b in zip(up[:-1], up[1:])]
    if len(peaks) < 2 or peaks[1] <= 0:
        return period, math.nan
    delta = math.log(peaks[0] / peaks[1])
    return period, delta / math.sqrt(4 * math.pi ** 2 + delta ** 2)


def _crossing(t: np.ndarray, x: np.ndarray, level: float, rising: bool, i0: int) -> float:
    """First time from index ``i0`` at which x reaches ``level`` (linear between samples)."""
    d = (x[i0:] - level) * (1.0 if rising else -1.0)
    k = np.flatnonzero(d >= 0)
    if not k.size:
        return math.nan
    j = i0 + int(k[0])
    if j == i0 or x[j] == x[j - 1]:
        return float(t[j])
    return float(t[j - 1] + (t[j] - t[j - 1]) * (level - x[j - 1]) / (x[j] - x[j - 1]))


def response_times(t: np.ndarray, x: np.ndarray, start_s: float) -> tuple[float, float]:
    """(T_i, T_t): from ``start_s`` to 10 % and to 90 % of the total response, the change from
    the value at ``start_s`` to the extreme reached afterwards (its direction: the larger)."""
    if not math.isfinite(start_s):
        return math.nan, math.nan
    i0 = int(np.searchsorted(t, start_s))
    seg = x[i0:]
    if seg.size < 2 or not np.isfinite(seg).all():
        return math.nan, math.nan
    x0 = seg[0]
    hi, lo = np.max(seg) - x0, x0 - np.min(seg)
    total = hi if hi >= lo else -lo
    if total == 0:
        return math.nan, math.nan
    rising = total > 0
    ti = _crossing(t, x, x0 + 0.1 * total, rising, i0)
    tt = _crossing(t, x, x0 + 0.9 * total, rising, i0)
    return ti - start_s, tt - start_s


def measure(test: DynamicTest, tr: Trajectory) -> dict[str, float]:
    """The test's metrics on a flown trace."""
    t, x = tr.time_s, tr[test.channel]
    if test.kind == "phugoid":
        period, zeta = phugoid(t, x, PHUGOID_HOLD_S + 0.6)
        return {"phugoid_period_s": period, "phugoid_damping": zeta}
    m = test.metrics[0]
    if test.kind == "engine_acceleration":
        ti, tt = response_times(t, x, ENGINE_STEP_S)
        return {m.name: tt - ti}
    if test.kind == "roll_step":
        return {m.name: steady_roll_rate(t, x, ROLL_STEP_START_S)}
    return {m.name: peak_rate(t, x, PULSE_START_S, math.copysign(1.0, m.measured))}


# --------------------------------------------------------------------------- recorded time histories
# residual scale of each response channel of a recorded maneuver (Part 60-sized: rates 2 deg/s,
# attitudes and aerodynamic angles 1-2 deg, airspeed 3 kt)
CHANNEL_SCALES = {"p_deg_s": 2.0, "q_deg_s": 2.0, "r_deg_s": 2.0, "roll_deg": 2.0, "pitch_deg": 1.0,
                  "beta_deg": 1.0, "alpha_deg": 1.0, "kcas": 3.0}
AXIS_CHANNELS = {"roll": ("p_deg_s", "roll_deg"), "pitch": ("q_deg_s", "pitch_deg", "alpha_deg", "kcas"),
                 "yaw": ("r_deg_s", "beta_deg")}


@dataclass(frozen=True)
class RecordedTest:
    """A maneuver with its recorded response (a flight-test or synthetic time history): the
    inputs replayed open loop (or with the pilot loops of the maneuver), the response
    channels compared at the recorded times (signs of :data:`jsbsim_calib.jsbsim.trajectory.RECORD`)."""

    id: str
    kind: str
    maneuver: object
    time_s: np.ndarray
    channels: dict
    record: dict = field(default_factory=dict)     # every recorded channel (surfaces in JSBSim's signs)
    weights: dict = field(default_factory=dict)    # channel -> weight of its residuals (default 1)

    def residuals(self, tr: Trajectory, channels: Sequence[str]) -> tuple[np.ndarray, list[str]]:
        """(model - recorded) / scale at every recorded time."""
        out, labels = [], []
        model = tr.at(self.time_s)
        for c in channels:
            if c not in self.channels or c not in model:
                continue
            d = self.channels[c]
            r = (model[c] - d) * self.weights.get(c, 1.0) / CHANNEL_SCALES.get(c, 1.0)
            out.append(np.where(np.isfinite(r), r, FAIL_RESIDUAL))
            labels += [f"{self.id} {c} t={t:.2f}" for t in self.time_s]
        return (np.concatenate(out) if out else np.zeros(0)), labels


FAIL_RESIDUAL = 20.0


def recorded(test_id: str, kind: str, tr: Trajectory, rate_hz: float = 10.0,
             channels: Sequence[str] = tuple(CHANNEL_SCALES)) -> RecordedTest:
    """A flown trajectory as a recorded test (sampled at ``rate_hz``): what a synthetic flight
    test of a truth aircraft records."""
    t = np.arange(0.0, tr.time_s[-1] + 1e-9, 1.0 / rate_hz)
    at = tr.at(t)
    return RecordedTest(test_id, kind, tr.maneuver, t, {c: at[c] for c in channels}, dict(at))


def recorded_test(th: TimeHistory, travel: Mapping[str, ControlAxis] | None = None) -> RecordedTest:
    """A format-1 time history as a recorded test: its inputs replayed from the trim at its
    first sample (with the pilot loops its sidecar names; cockpit controls through ``travel``),
    its response channels (those of :data:`CHANNEL_SCALES` it has) compared at its sample times
    from 0. The data's signs of these channels are JSBSim's (:data:`~jsbsim_calib.jsbsim.trajectory.RECORD`)."""
    maneuver = maneuver_from_time_history(th, pilot=th.meta.pilot, travel=travel)
    t = th.time_s - th.time_s[0]
    channels = {c: th.channel(c) for c in CHANNEL_SCALES if c in th.channels}
    record = {c: th.channel(c) for c in th.channels if c != "time_s"}
    for c, surface in SURFACE_OF.items():
        if c in record:
            record[c] = to_jsbsim_sign(surface, record[c])
    return RecordedTest(th.meta.test_id, th.meta.kind, maneuver, t, channels, record)


def load_recorded_tests(dir_or_files, travel: Mapping[str, ControlAxis] | None = None) -> list[RecordedTest]:
    """Every time history of directories and/or CSV files (:func:`load_time_histories`: each
    directory's records by name, then the files given) as a recorded test."""
    items = [dir_or_files] if isinstance(dir_or_files, (str, Path)) else list(dir_or_files)
    records = [th for d in items if Path(d).is_dir() for th in load_time_histories(Path(d))]
    files = [Path(f) for f in items if not Path(f).is_dir()]
    records += load_time_histories(files) if files else []
    return [recorded_test(th, travel) for th in records]


# --------------------------------------------------------------------------- results
@dataclass
class MetricResult:
    test: str
    metric: DynamicMetric
    model: float

    @property
    def error(self) -> float:
        return self.model - self.metric.measured

    @property
    def within(self) -> bool | None:
        """True/False against the tolerance; None where the tolerance is 'representative'. A
        NaN is never within."""
        if self.metric.tolerance is None:
            return None
        return bool(abs(self.error) <= self.metric.tol())         # NaN compares False

    @property
    def verdict(self) -> str:
        w = self.within
        return "n/a" if w is None else ("PASS" if w else "FAIL")


@dataclass
class TestResult:
    __test__ = False            # not a pytest test class
    test: DynamicTest
    trajectory: Trajectory | None
    metrics: list[MetricResult]
    failure: str = ""            # why the test could not be flown (no trim, ...)


@dataclass
class DynamicEvaluation:
    aircraft: str
    results: list[TestResult]
    wall_time_s: float = 0.0
    frames: int = 0

    def metric_results(self) -> list[MetricResult]:
        return [m for r in self.results for m in r.metrics]

    def by_metric(self) -> Summary:
        """Accuracy per metric over the tests that measure it (the statistics of
        :class:`~jsbsim_calib.evaluation.evaluate.MetricSummary`; a test not flown counts as outside)."""
        out = {}
        for name in dict.fromkeys(m.metric.name for m in self.metric_results()):
            rows = [m for m in self.metric_results() if m.metric.name == name]
            ok = [m for m in rows if math.isfinite(m.error)]
            err = np.array([m.error for m in ok])
            ref = np.array([m.metric.measured for m in ok])
            nz = ref != 0
            judged = [m for m in rows if m.within is not None]
            out[name] = MetricSummary(
                n=len(rows), rmse=float(np.sqrt(np.mean(err ** 2))) if ok else None,
                mape=float(100 * np.mean(np.abs(err[nz] / ref[nz]))) if nz.any() else None,
                nmbe=float(100 * np.mean(err[nz] / ref[nz])) if nz.any() else None,
                within_pct=float(100.0 * sum(bool(m.within) for m in judged) / len(judged)) if judged else None,
                failed=len(rows) - len(ok))
        return out

    def summary(self) -> dict:
        rows = self.metric_results()
        judged = [m for m in rows if m.within is not None]
        return {"aircraft": self.aircraft, "n": len(rows), "judged": len(judged),
                "passed": sum(1 for m in judged if m.within),
                "failed_to_fly": [r.test.id for r in self.results if r.failure]}

    def to_json(self) -> dict:
        return {"aircraft": self.aircraft, "summary": self.summary(), "tests": [
            {"id": r.test.id, "initial": r.test.initial, "part60": r.test.part60, "title": r.test.title,
             "kind": r.test.kind, "assumptions": list(r.test.assumptions), "failure": r.failure,
             "metrics": [{"name": m.metric.name, "flight_test": m.metric.measured, "model": _js(m.model),
                          "error": _js(m.error), "tolerance": m.metric.tolerance_text(),
                          "amplitude_dependent": m.metric.amplitude_dependent, "verdict": m.verdict,
                          "thesis_model": _js(m.metric.thesis_model)} for m in r.metrics]}
            for r in self.results]}


def _js(x: float):
    return None if x is None or not math.isfinite(x) else float(x)


def fly_test(sim: Simulator, test: DynamicTest, *, rate_hz: float = RATE_HZ) -> TestResult:
    try:
        tr = fly(sim, test.maneuver, rate_hz=rate_hz)
    except CalibError as exc:
        return TestResult(test, None, [MetricResult(test.id, m, math.nan) for m in test.metrics], str(exc))
    got = measure(test, tr)
    return TestResult(test, tr, [MetricResult(test.id, m, got.get(m.name, math.nan)) for m in test.metrics])


class _FlyFresh:
    """One test flown from a freshly loaded aircraft (no warm starts): the same bits in this
    process or in an executor's worker."""

    def __init__(self, sim: Simulator, rate_hz: float):
        self.sim, self.rate_hz = sim, rate_hz

    def __call__(self, test: DynamicTest) -> TestResult:
        self.sim.fresh()
        self.sim.trim_cache = {}
        return fly_test(self.sim, test, rate_hz=self.rate_hz)


def evaluate_dynamic(sim: Simulator, tests: Sequence[DynamicTest], *, rate_hz: float = RATE_HZ,
                     progress: Callable[[str], None] | None = None, executor: Executor = SERIAL) -> DynamicEvaluation:
    """Fly every test on ``sim`` (at its current factors) and compare; the tests are
    independent work (``executor``)."""
    t0 = time.perf_counter()
    if progress:
        progress(f"flying {len(tests)} dynamic tests ({executor.describe()})")
    out = executor.map(_FlyFresh(sim, rate_hz), list(tests), key=f"fly {id(sim)} {sim.factors!r}")
    frames = sum(0 if r.trajectory is None else len(r.trajectory.time_s) for r in out)
    return DynamicEvaluation(sim.name, out, time.perf_counter() - t0, frames)

