"""The Part 60 objective tests of a model: every Level 5 test (and the supplemental ones the
flight-test package holds), flown and judged, as a typed result; nothing is written here
(:mod:`jsbsim_calib.report.part60_report` writes the report).

Sources, any or all: the flight-test summary file (results + snapshots: climbs and trims are
trimmed, the engine acceleration and the dynamic tests are flown, :mod:`..data.part60_tests`,
:mod:`..data.dynamic_tests`) and flight-test time histories (each flown from its recorded
initial condition with its recorded inputs, :mod:`.timehistory_compare`). Every catalogue test
(:data:`..data.part60_tests.CATALOGUE`) gets a verdict: PASS, FAIL, or n/a with the reason (the model
cannot do the test, no data for it, a tolerance the evaluator judges). A NaN never passes.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Sequence

import numpy as np

from ..data.dynamic_tests import (ENGINE_STEP_S, PHUGOID_HOLD_S, PULSE_START_S, ROLL_STEP_START_S, ROLL_WINDOW_S,
                                 DynamicTest, engine_maneuver, load_dynamic_tests)
from ..data.flighttest import load_control_travel, to_data_sign
from ..data.part60_tests import (CATALOGUE, CATALOGUE_BY_ID, FAIL, NA, PASS, MetricVerdict, Part60Test,
                          StaticCase, catalogue_test, classify_files, combine, judge,
                          load_static_cases, snapshot_values)
from ..data.timehistory import load_time_histories
from .evaluate_dynamic import fly_test, response_times
from ..core.errors import CalibError, DataError, Problem
from ..flight.condition import Condition, TrimResult
from ..jsbsim.simulator import Simulator
from ..jsbsim.trajectory import Trajectory, fly
from .timehistory_compare import ChannelError, TimeHistoryComparison, band_metric, compare_time_history, unit_of

IC_UNITS = {"weight_lb": "lb", "cg_in": "in", "flaps_deg": "deg", "pressure_alt_ft": "ft", "ktas": "kt",
            "kcas": "kt", "vs_fpm": "ft/min", "pitch_deg": "deg", "roll_deg": "deg", "elevator_deg": "deg",
            "aileron_deg": "deg", "rudder_deg": "deg", "throttle_norm": "-", "rpm": "rpm"}
TRIM_VALUES: dict[str, Callable[[TrimResult], float]] = {
    "ktas": lambda t: t.ktas, "kcas": lambda t: t.kcas, "vs_fpm": lambda t: t.roc_fpm,
    "pitch_deg": lambda t: t.theta_deg, "roll_deg": lambda t: t.phi_deg,
    "elevator_deg": lambda t: to_data_sign("elevator", t.elevator_deg),
    "aileron_deg": lambda t: to_data_sign("aileron", t.aileron_deg),
    "rudder_deg": lambda t: to_data_sign("rudder", t.rudder_deg), "throttle_norm": lambda t: t.throttle,
    "rpm": lambda t: t.rpm, "pct_power": lambda t: t.pct_power,
}
CONDITION_VALUES = {"weight_lb": "weight_lb", "cg_in": "cg_in", "flaps_deg": "flaps_deg",
                    "pressure_alt_ft": "pressure_alt_ft"}
INPUT_MOVED = {"elevator_deg": 0.5, "aileron_deg": 0.5, "rudder_deg": 0.5, "flaps_deg": 1.0, "throttle_norm": 0.05}
TH_IC_CHANNELS = ("pressure_alt_ft", "kcas", "ktas", "vs_fpm", "pitch_deg", "roll_deg", "elevator_deg",
                  "aileron_deg", "rudder_deg", "flaps_deg", "throttle_norm", "rpm")


# --------------------------------------------------------------------------- results
@dataclass(frozen=True)
class InitialRow:
    """An initial-condition quantity: the flight test's value and the model's trimmed one."""

    quantity: str
    unit: str
    flight_test: float
    model: float


@dataclass
class TracePlot:
    """A time-history plot: the model's trace, the flight test's where one exists, and the
    tolerance: a band of half-width ``band`` around the flight-test trace, or a box
    ``target`` (t0, t1, lo, hi) where only a summary value exists; ``marks``: (time, label)."""

    title: str
    channel: str
    unit: str
    time_s: np.ndarray
    model: np.ndarray | None
    flight_test: np.ndarray | None = None
    band: float | None = None
    target: tuple[float, float, float, float] | None = None
    marks: tuple[tuple[float, str], ...] = ()


@dataclass
class CaseResult:
    """One flown case of a test (a result row of the summary file, or one time history)."""

    test_id: str
    case: str
    source: str                          # "summary data" | "time history"
    title: str
    initial: list[InitialRow] = field(default_factory=list)
    metrics: list[MetricVerdict] = field(default_factory=list)
    plots: list[TracePlot] = field(default_factory=list)
    errors: list[ChannelError] = field(default_factory=list)
    assumptions: list[str] = field(default_factory=list)
    failure: str = ""

    @property
    def verdict(self) -> str:
        return FAIL if self.failure else combine([m.verdict for m in self.metrics])


@dataclass
class ObjectiveTest:
    """A catalogue test, its cases and its verdict (PASS / FAIL / n/a) with the reason."""

    test: Part60Test
    cases: list[CaseResult]
    verdict: str
    reason: str


@dataclass
class Part60Evaluation:
    aircraft: str
    tests: list[ObjectiveTest]
    sources: list[str]
    ignored: list[str] = field(default_factory=list)

    def counts(self) -> dict[str, int]:
        out = {PASS: 0, FAIL: 0, NA: 0}
        for t in self.tests:
            out[t.verdict] += 1
        return out

    def test(self, test_id: str) -> ObjectiveTest:
        return next(t for t in self.tests if t.test.id == test_id)

    def to_json(self) -> dict:
        """Every test's verdict and reason, and each case's metrics (a NaN is written as null)."""
        num = lambda x: float(x) if isinstance(x, (int, float, np.number)) and math.isfinite(float(x)) else None
        case = lambda c: {"case": c.case, "source": c.source, "verdict": c.verdict, "failure": c.failure,
                          "metrics": [{"name": m.name, "unit": m.unit, "flight_test": num(m.flight_test),
                                       "model": num(m.model), "error": num(m.error), "tolerance": m.tolerance,
                                       "verdict": m.verdict, "reason": m.reason} for m in c.metrics]}
        return {"aircraft": self.aircraft, "counts": self.counts(), "sources": list(self.sources),
                "ignored": list(self.ignored),
                "tests": [{"id": t.test.id, "title": t.test.title, "verdict": t.verdict, "reason": t.reason,
                           "cases": [case(c) for c in t.cases]} for t in self.tests]}


# --------------------------------------------------------------------------- verdicts
def _fmt(x: float) -> str:
    return "NaN" if not math.isfinite(x) else f"{x:.3g}"


def _fail_reason(c: CaseResult) -> str:
    if c.failure:
        return f"{c.case}: not flown ({c.failure})"
    bad = [m for m in c.metrics if m.verdict == FAIL]
    return f"{c.case}: " + "; ".join(f"{m.name} model {_fmt(m.model)} vs flight test "
                                     f"{m.flight_test_text or _fmt(m.flight_test)} ({m.reason})" for m in bad)


def objective_verdict(test: Part60Test, cases: Sequence[CaseResult]) -> tuple[str, str]:
    """(verdict, reason) of a test from its cases; a test the model cannot do, or without
    data, is n/a with the reason."""
    if test.not_possible:
        return NA, test.not_possible
    if not cases:
        return NA, "no flight-test data for this test in the given files"
    v = combine([c.verdict for c in cases])
    if v == FAIL:
        return FAIL, " | ".join(_fail_reason(c) for c in cases if c.verdict == FAIL)
    if v == NA:
        reasons = sorted({f"{m.name}: {m.reason}" for c in cases for m in c.metrics if m.reason})
        return NA, "; ".join(reasons) or "nothing judged"
    n = sum(c.verdict == PASS for c in cases)
    return PASS, f"{n} of {len(cases)} cases pass" + ("" if n == len(cases) else " (others n/a)")


# --------------------------------------------------------------------------- summary data: static cases
def _initial_from_trim(ic: dict[str, float], cond: Condition | None, trim: TrimResult | None) -> list[InitialRow]:
    rows = []
    for q, attr in CONDITION_VALUES.items():
        model = getattr(cond, attr) if cond is not None else None
        rows.append(InitialRow(q, IC_UNITS[q], ic.get(q, math.nan), math.nan if model is None else float(model)))
    for q in ("ktas", "vs_fpm", "pitch_deg", "roll_deg", "elevator_deg", "aileron_deg", "rudder_deg",
              "throttle_norm", "rpm"):
        model = TRIM_VALUES[q](trim) if trim is not None and trim.trimmed else math.nan
        rows.append(InitialRow(q, IC_UNITS[q], ic.get(q, math.nan), model))
    return rows


def _trim(sim: Simulator, cond: Condition) -> TrimResult:
    return sim.trim_level(cond) if cond.mode == "level" else sim.trim(cond)


def _trim_case(sim: Simulator, case: StaticCase, test: Part60Test) -> CaseResult:
    out = CaseResult(test.id, f"{case.id} (initial condition {case.initial})", "summary data", case.title,
                     assumptions=list(case.assumptions))
    t = _trim(sim, case.condition)
    out.initial = _initial_from_trim(case.initial_values, case.condition, t)
    if not t.trimmed:
        out.failure = f"no trim: {t.reason}"
    for ref in case.references:
        spec = test.metric(ref.metric)
        model = TRIM_VALUES[ref.metric](t) if t.trimmed and ref.metric in TRIM_VALUES else math.nan
        out.metrics.append(judge(spec, ref.value, model, ref.text))
    return out


def _engine_case(sim: Simulator, case: StaticCase, test: Part60Test) -> CaseResult:
    out = CaseResult(test.id, f"{case.id} (no flight-test initial condition)", "summary data", case.title,
                     assumptions=list(case.assumptions))
    try:
        tr = fly(sim, engine_maneuver(case.condition))
    except (CalibError, ValueError) as exc:
        out.failure = str(exc)
        tr = None
    out.initial = _initial_from_trim({}, case.condition, tr.trim if tr else None)
    ti, tt = response_times(tr.time_s, tr["rpm"], ENGINE_STEP_S) if tr else (math.nan, math.nan)
    model = {"t_i_s": ti, "t_t_s": tt, "response_time_s": tt - ti}
    out.metrics = [judge(test.metric(r.metric), r.value, model[r.metric], r.text) for r in case.references]
    if tr is not None:
        marks = ((ENGINE_STEP_S, "throttle"), (ENGINE_STEP_S + ti, "T_i"), (ENGINE_STEP_S + tt, "T_t"))
        out.plots.append(TracePlot("engine RPM after the throttle step (model)", "rpm", "rpm", tr.time_s,
                                   tr["rpm"], marks=tuple(m for m in marks if math.isfinite(m[0]))))
    return out


def static_case_result(sim: Simulator, case: StaticCase) -> CaseResult:
    """Trim (climb, trim) or fly (engine) one static case and judge its metrics."""
    test = CATALOGUE_BY_ID[case.test_id]
    if case.problem or case.condition is None:
        return CaseResult(test.id, case.id, "summary data", case.title, failure=case.problem or "no condition")
    return _engine_case(sim, case, test) if case.kind == "engine" else _trim_case(sim, case, test)


# --------------------------------------------------------------------------- summary data: dynamic tests
def _dynamic_plot(dt: DynamicTest, tr: Trajectory, metrics: list[MetricVerdict], test: Part60Test) -> TracePlot:
    x = tr[dt.channel]
    if dt.channel in ("elevator_deg", "aileron_deg", "rudder_deg"):
        x = to_data_sign(dt.channel[:-4], x)
    m = metrics[0]
    spec = test.metric(m.name)
    band = spec.tolerance.band(m.flight_test) if spec and not spec.tolerance.judged else math.nan
    box, marks = None, ()
    if dt.kind == "roll_step" and math.isfinite(band):
        box = (ROLL_STEP_START_S + ROLL_WINDOW_S[0], ROLL_STEP_START_S + ROLL_WINDOW_S[1],
               m.flight_test - band, m.flight_test + band)
        marks = ((ROLL_STEP_START_S, "wheel step"),)
    elif dt.kind.endswith("pulse") and math.isfinite(band):
        box = (PULSE_START_S, float(tr.time_s[-1]), m.flight_test - band, m.flight_test + band)
        marks = ((PULSE_START_S, "pulse"),)
    elif dt.kind == "phugoid":
        marks = ((0.5 + PHUGOID_HOLD_S, "release"),)
    return TracePlot(f"{dt.channel} (model; band: flight-test {m.name} +- tolerance)", dt.channel,
                     unit_of(dt.channel), tr.time_s, x, target=box, marks=marks)


def dynamic_case_result(sim: Simulator, dt: DynamicTest, ic: dict[str, float]) -> CaseResult:
    """Fly one dynamic test of the summary data and judge it with the catalogue's tolerances."""
    test = catalogue_test(dt.part60) or catalogue_test(dt.title)
    r = fly_test(sim, dt)
    out = CaseResult(test.id, f"{dt.id} (initial condition {dt.initial})", "summary data", dt.title,
                     assumptions=list(dt.assumptions), failure=r.failure)
    for mr in r.metrics:
        spec = test.metric(mr.metric.name)
        out.metrics.append(judge(spec, mr.metric.measured, mr.model))
    out.initial = _initial_from_trim(ic, dt.maneuver.start, r.trajectory.trim if r.trajectory else None)
    if r.trajectory is not None:
        out.plots.append(_dynamic_plot(dt, r.trajectory, out.metrics, test))
    if any(m.amplitude_dependent for m in dt.metrics):
        out.assumptions.append("the peak rate depends on the assumed pulse amplitude (not recorded)")
    return out


# --------------------------------------------------------------------------- time histories
def _th_plots(c: TimeHistoryComparison) -> list[TracePlot]:
    """The test's channel (with its tolerance band) and every input the record moves."""
    test = c.test
    channels = [test.channel] if test and test.channel in c.data else []
    channels += [ch for ch, moved in INPUT_MOVED.items()
                 if ch in c.data and ch not in channels and np.ptp(c.data[ch]) > moved]
    band = band_metric(test, c.metrics) if test else None
    marks = ((c.input_start_s, "input"),) if math.isfinite(c.input_start_s) else ()
    out = []
    for ch in channels:
        half = band[1] if band and band[0] == ch else None
        out.append(TracePlot(f"{ch}: flight test and model" + (" (band: tolerance)" if half else ""), ch,
                             unit_of(ch), c.time_s, c.model.get(ch), c.data[ch], band=half, marks=marks))
    return out


def timehistory_case_result(sim: Simulator, th) -> tuple[Part60Test | None, CaseResult]:
    """Fly one time history and judge it (the test from its ``part60`` field or title)."""
    c = compare_time_history(sim, th)
    test_id = c.test.id if c.test else "?"
    out = CaseResult(test_id, Path(c.path).name, "time history", c.title, metrics=list(c.metrics),
                     errors=list(c.errors), failure=c.failure, plots=_th_plots(c))
    out.initial = [InitialRow(ch, IC_UNITS.get(ch, unit_of(ch)), float(c.data[ch][0]), _trimmed(c, ch))
                   for ch in TH_IC_CHANNELS if ch in c.data]
    out.assumptions = _flown_how(c)
    return c.test, out


def _trimmed(c: TimeHistoryComparison, ch: str) -> float:
    """The model's trimmed value of a channel (the first sample where the trim has none)."""
    if c.trajectory is None:
        return math.nan
    trim = c.trajectory.trim
    if ch in TRIM_VALUES and trim.trimmed:
        return float(TRIM_VALUES[ch](trim))
    return float(c.model[ch][0]) if ch in c.model else math.nan


def _flown_how(c: TimeHistoryComparison) -> list[str]:
    if c.maneuver is None:
        return []
    m = c.maneuver
    out = [f"trimmed at the recorded initial condition ({m.start.mode.replace('_', ' ')} trim), then "
           f"{m.duration_s:g} s of the recorded inputs, open loop: "
           + (", ".join(sorted({i.channel for i in m.inputs})) or "none")]
    if m.holds:
        out.append("the model's test pilot flies " + ", ".join(
            f"{h.loop} ({'the trimmed value' if h.target is None else f'{h.target:.4g}, the flight test final value'})"
            for h in m.holds) + "; the recorded surfaces of those axes are model outputs")
    out.append("the model is sampled at the flight test's times; the metrics of both traces count from the "
               "flight test's input start")
    return out


# --------------------------------------------------------------------------- the chain
@dataclass
class SummaryData:
    """The flight-test summary files (results, snapshots with the initial conditions, control
    travel)."""

    results: Path
    snapshots: Path
    travel: Path


@dataclass
class Part60Inputs:
    """What the chain reads: the summary files (or None), the time histories, files left out."""

    summary: SummaryData | None
    time_histories: list
    ignored: list[str]


def load_part60_inputs(paths: Sequence[str | Path], travel: str | Path | None = None) -> Part60Inputs:
    """The flight-test files and folders of ``paths`` (:func:`~..data.part60_tests.classify_files`):
    the results file with its snapshot file (control travel: the one given among the files,
    else ``travel``, the aircraft's table) and every time history. DataError when there is
    nothing to evaluate, or a results file without its snapshots or control travel."""
    files = classify_files(list(paths))
    problems = []
    if files.results and not files.snapshots:
        problems.append(Problem(str(files.results), "a results file needs the snapshot file with its initial "
                                                    "conditions among the flight-test files"))
    travel_file = files.travel or (Path(travel) if travel else None)
    if files.results and files.snapshots and travel_file is None:
        problems.append(Problem(str(files.results), "the dynamic tests need the control-travel table"))
    if not files.results and not files.time_histories:
        problems.append(Problem(", ".join(map(str, paths)), "no flight-test results file and no time history"))
    if problems:
        raise DataError("--flight-test", problems)
    summary = SummaryData(files.results, files.snapshots, travel_file) if files.results else None
    ths = load_time_histories(files.time_histories) if files.time_histories else []
    return Part60Inputs(summary, ths, files.ignored)


def summary_cases(sim: Simulator, data: SummaryData, say, notes: list[str]) -> list[CaseResult]:
    """Every flyable case of the summary files; the rows of tests the model cannot do go to
    ``notes``."""
    static = load_static_cases(data.results, data.snapshots)
    dynamic = [t for t in load_dynamic_tests(data.results, data.snapshots, load_control_travel(data.travel))
               if t.kind != "engine_acceleration"]      # 1.f.1: a static case here, with T_i and T_t
    ics = snapshot_values(data.snapshots)
    out = []
    for case in static:
        if CATALOGUE_BY_ID[case.test_id].not_possible:
            notes.append(f"{Path(data.results).name}: {case.id} ({case.title}) not flown: "
                         f"{CATALOGUE_BY_ID[case.test_id].not_possible}")
            continue
        say(f"{case.id} {case.title}")
        out.append(static_case_result(sim, case))
    for dt in dynamic:
        say(f"{dt.id} {dt.title}")
        out.append(dynamic_case_result(sim, dt, ics.get(dt.initial, {})))
    return out


def evaluate_part60(sim: Simulator, *, summary: SummaryData | None = None, time_histories: Sequence = (),
                    ignored: Sequence[str] = (), progress: Callable[[str], None] | None = None) -> Part60Evaluation:
    """Every catalogue test against the summary data and/or time histories, on ``sim``."""
    say = progress or (lambda msg: None)
    notes = list(ignored)
    cases = summary_cases(sim, summary, say, notes) if summary is not None else []
    unmatched = []
    for th in time_histories:
        say(f"time history {Path(th.path).name}")
        test, case = timehistory_case_result(sim, th)
        (cases if test is not None else unmatched).append(case)
    tests = []
    for test in CATALOGUE:
        mine = [c for c in cases if c.test_id == test.id]
        tests.append(ObjectiveTest(test, mine, *objective_verdict(test, mine)))
    sources = ([str(summary.results), str(summary.snapshots)] if summary else []) + [str(th.path) for th in
                                                                                      time_histories]
    notes += [f"{c.case}: no Part 60 test of the catalogue matches '{c.title}'" for c in unmatched]
    return Part60Evaluation(sim.name, tests, sources, notes)
