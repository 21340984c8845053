"""Stage 2b held out: each dynamic test with an amplitude-free, toleranced metric left out in
turn, stage 2b's own axis fits rerun on the rest, and the left-out test flown.

A fold refits only the dynamic steps that fly the test it leaves out (and the coupled lateral
refit after them), from the stage-2a factors, as stage 2b does; the kept tests give the fit
error, the left-out one the held-out error, the product (after stage 2b) the in-sample one,
per metric, in the types of :mod:`jsbsim_calib.calibration.validation`. Not judged: metrics
without a tolerance (the phugoid's "representative" damping), and the peak rates after the
pulses, which depend on the unrecorded input amplitude: stage 2b fits them with the amplitude
free within its plausible range, where every pulse is explained, so leaving one out tests
nothing.
"""
from __future__ import annotations

import math
import time
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Sequence

import numpy as np

from ..data.dynamic_tests import DynamicTest, aircraft_dynamic_tests
from ..data.flighttest import QuirkWarning
from ..evaluation.evaluate_dynamic import MetricResult, evaluate_dynamic
from ..factors import FactorSet
from ..jsbsim.product import AircraftPaths, load_aircraft_geometry, read_calibration
from ..jsbsim.simulator import Simulator
from .dynamic import DYNAMIC_STEPS, MAX_NFEV, dynamic_stage
from .validation import (STEADY_KINDS, TRIMS_KINDS, ErrorStat, Fold, FoldMetric, FoldResult, Validation,
                         select_folds, stage_data, stage_factors)

KIND = "dynamic"             # the fold's rows: positions in the aircraft's list of dynamic tests


@dataclass(frozen=True)
class Judged:
    """One judged metric of one flown test: its error and tolerance in the metric's unit."""

    test: str
    name: str
    unit: str
    error: float              # NaN: not flown
    tolerance: float


def judged(results: Sequence[MetricResult]) -> list[Judged]:
    """The metrics a fold judges: those with a tolerance that do not depend on an input amplitude."""
    return [Judged(m.test, m.metric.name, m.metric.unit, m.error, m.metric.tol()) for m in results
            if m.metric.tolerance is not None and not m.metric.amplitude_dependent]


def error_stat(rows: Sequence[Judged]) -> ErrorStat:
    """RMSE over the flown tests, share within tolerance (a test not flown counts as outside)."""
    ok = [r.error for r in rows if math.isfinite(r.error)]
    within = sum(1 for r in rows if abs(r.error) <= r.tolerance)        # NaN compares False
    return ErrorStat(len(rows), float(np.sqrt(np.mean(np.square(ok)))) if ok else math.nan,
                     100.0 * within / len(rows) if rows else math.nan, len(rows) - len(ok))


def dynamic_folds(tests: Sequence[DynamicTest]) -> list[Fold]:
    """A fold per test with a metric :func:`judged` judges."""
    return [Fold(f"{t.id} {t.kind.replace('_', ' ')}", "dynamic test", {KIND: (i,)}) for i, t in enumerate(tests)
            if any(m.tolerance is not None and not m.amplitude_dependent for m in t.metrics)]


def fold_metrics(fold: Fold, tests: Sequence[DynamicTest], refit: dict[str, list[Judged]],
                 product: dict[str, list[Judged]]) -> list[FoldMetric]:
    """Per metric of the fold's tests: the refit on the kept tests of the same metric (fit),
    on the fold's (held out), the product on the fold's (in sample)."""
    left = {tests[i].id for i in fold.rows.get(KIND, ())}
    mine = [j for t in left for j in refit[t]]
    out = []
    for name in dict.fromkeys(j.name for j in mine):
        held = [j for j in mine if j.name == name]
        fit = [j for t, js in refit.items() if t not in left for j in js if j.name == name]
        ins = [j for t in left for j in product[t] if j.name == name]
        out.append(FoldMetric(fold.name, fold.grouping, KIND, name, held[0].unit, error_stat(fit), error_stat(held),
                              error_stat(ins), float(np.mean([j.tolerance for j in held]))))
    return out


def control_metrics(refit: dict[str, list[Judged]], product: dict[str, list[Judged]]) -> list[FoldMetric]:
    """The control (nothing left out): the refit on every test against the product, per metric."""
    mine = _by_name(product)
    return [FoldMetric("none (control)", "control", KIND, name, rows[0].unit, error_stat(rows), error_stat(rows),
                       error_stat(mine.get(name, [])), float(np.mean([j.tolerance for j in rows])))
            for name, rows in _by_name(refit).items()]


def _flown(sim: Simulator, tests: Sequence[DynamicTest]) -> dict[str, list[Judged]]:
    ev = evaluate_dynamic(sim, tests)
    return {r.test.id: judged(r.metrics) for r in ev.results}


def refit_dynamic(sim: Simulator, tests: Sequence[DynamicTest], data, start: FactorSet, fold: Fold,
                  max_nfev: int) -> tuple[FactorSet, float, tuple[str, ...]]:
    """The dynamic steps that fly a left-out test (all for the control), on the kept tests."""
    left = set(fold.rows.get(KIND, ()))
    kinds = {tests[i].kind for i in left} if left else {t.kind for t in tests}
    steps = tuple(s for s in DYNAMIC_STEPS if set(s.kinds) & kinds)
    kept = [t for i, t in enumerate(tests) if i not in left]
    results = dynamic_stage(sim, kept, data, start=start, steps=steps, max_nfev=max_nfev)
    final = results[-1].final if results else start
    return final, (results[-1].cost_final if results else math.nan), tuple(r.stage for r in results)


def dynamic_inputs(root: Path, name: str) -> tuple[list[DynamicTest], dict]:
    """The aircraft's dynamic tests and the trim data the dynamic steps fit or hold."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", QuirkWarning)
        tests = aircraft_dynamic_tests(load_aircraft_geometry(root, name), name)
        data = stage_data(root, name, TRIMS_KINDS + STEADY_KINDS)
    return tests, data


def dynamic_fold_names(root: Path | str, name: str) -> list[str]:
    return [f.name for f in dynamic_folds(dynamic_inputs(Path(root), name)[0])]


def validate_dynamic(root: Path | str, name: str, *, folds: Sequence[str] | None = None,
                     max_nfev: int = MAX_NFEV, control: bool = True,
                     progress: Callable[[str], None] | None = None) -> Validation:
    """Stage 2b held out (module doc). ``folds``: names to run (default all, :func:`dynamic_folds`)."""
    say = progress or (lambda s: None)
    root = Path(root)
    t0 = time.perf_counter()
    tests, data = dynamic_inputs(root, name)
    start = stage_factors(root, name, "trims")
    product = read_calibration(AircraftPaths(root, name))
    chosen = select_folds(dynamic_folds(tests), folds)
    with Simulator(root, name, factors=product) as sim:
        trims0 = sim.trims
        say("dynamic: flying the tests on the product")
        in_product = _flown(sim, tests)
        runs = ([Fold("none (control)", "control", {})] if control else []) + chosen
        results = []
        for fold in runs:
            k = chosen.index(fold) + 1 if fold.rows else 0
            say(f"dynamic: {'control refit' if not fold.rows else f'fold {k}/{len(chosen)} {fold.name}'}")
            f0, n0 = time.perf_counter(), sim.trims
            factors, cost, ran = refit_dynamic(sim, tests, data, start, fold, max_nfev)
            sim.set_factors(factors)
            flown = _flown(sim, tests)
            if fold.rows:
                metrics = fold_metrics(fold, tests, flown, in_product)
            else:
                metrics = control_metrics(flown, in_product)
            failures = [f"{tests[i].id}: not flown" for i in fold.rows.get(KIND, ())
                        if any(not math.isfinite(j.error) for j in flown[tests[i].id])]
            moved = {k: (start[k], factors[k]) for k in factors if factors[k] != start[k]}
            results.append(FoldResult(fold, ran, factors, metrics, cost, time.perf_counter() - f0, sim.trims - n0,
                                      failures, moved))
        sim.set_factors(product)
        trims = sim.trims - trims0
    ctrl = results[0] if control else None
    val = Validation(name, "dynamic", results[1:] if control else results, ctrl,
                     {KIND: {name: error_stat(rows) for name, rows in _by_name(in_product).items()}},
                     max_nfev, time.perf_counter() - t0, trims)
    val.notes.append(f"model: stage 2a factors of aircraft/{name}/calibration.json refitted by the stage-2b steps "
                     "that fly a left-out test (and the lateral refit after them), on the kept tests; in-sample: the "
                     "product (after stage 2b)")
    val.notes.append("not folded: the pulses (their peak rates depend on the unrecorded input amplitude, free in the "
                     "fit within its plausible range, where every pulse is explained) and the phugoid's damping (no "
                     "tolerance); the refits still fly the pulses they keep")
    return val


def _by_name(flown: dict[str, list[Judged]]) -> dict[str, list[Judged]]:
    """The judged metrics of all tests, grouped by metric name (in the order they first appear)."""
    out: dict[str, list[Judged]] = {}
    for js in flown.values():
        for j in js:
            out.setdefault(j.name, []).append(j)
    return out
