"""The chains an aircraft goes through; each runs its stages and returns its results.

``run_steady`` evaluates the baseline on all POH points, runs stage 1 (16 factors, then
K_FF), evaluates the result on all points, and returns a :class:`SteadyCalibration`;
``run_trims`` runs stage 2a on the flight-test trims (:class:`TrimsCalibration`);
``run_close_loop`` closes the loop on one data file
(:class:`~jsbsim_calib.calibration.closeloop.CloseLoopResult`). Nothing here writes a file:
the calibrated product is written by :func:`jsbsim_calib.jsbsim.product.write_calibrated`
(after which ``load_model(name)`` is the calibrated aircraft and ``jsbsim-calib generate
<name>`` reproduces the same bytes), the reports by :mod:`jsbsim_calib.report`.
"""
from __future__ import annotations

import time
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np

from .bands import Bands, prediction_bands, response_bands
from .closeloop import CloseLoopResult, close_loop
from .dynamic import DYNAMIC_STEPS, DynamicStep, dynamic_stage
from .fit import MAX_NFEV, FitResult
from .points import stage1_subset
from .steady import STAGE1_STEPS, steady_stage
from .trims import TRIM_STEPS, TrimStep, trims_stage
from ..data.dynamic_tests import DynamicTest, aircraft_dynamic_tests
from ..data.flighttest import QuirkWarning
from ..data.load import load_dataset
from ..data.schemas import Dataset
from ..evaluation.evaluate_dynamic import DynamicEvaluation, evaluate_dynamic
from ..core.errors import InputError, ModelError, Problem
from ..core.executor import SERIAL, Executor
from ..evaluation.evaluate import Evaluation, Summary, evaluate_dataset, summary_dict, thesis_summary
from ..factors import FactorSet, switches
from ..jsbsim.probes import AeroCurves, aero_curves
from ..jsbsim.product import AircraftPaths, load_aircraft_geometry, propeller_tables, read_calibration_record
from ..jsbsim.simulator import Simulator
from ..physics.propeller import PropellerTables


@dataclass
class SteadyCalibration:
    """Stage 1: the fits, the evaluations of the baseline and the calibrated model on every POH
    point, and the lift curves, drag polars and propeller tables of both models."""

    aircraft: str
    fit: FitResult
    fuel_flow: FitResult
    baseline: dict[str, Evaluation]
    calibrated: dict[str, Evaluation]
    thesis: dict[str, Summary]
    factors: FactorSet
    wall_time_s: float
    trims: int
    climb_points: list[int]
    cruise_points: list[int]
    aero_curves: dict[str, AeroCurves]           # baseline, calibrated
    propeller_tables: dict[str, PropellerTables]  # baseline, calibrated (BEM breakpoints)
    bands: Bands | None = None                    # the calibrated model's 95 % prediction bands (None: not computed)

    def summary(self) -> dict:
        """The stage's record (calibration.json), JSON-safe."""
        return {
            "aircraft": self.aircraft,
            "fit": self.fit.summary(), "fuel_flow": self.fuel_flow.summary(),
            "baseline": {k: summary_dict(e.summary()) for k, e in self.baseline.items()},
            "calibrated": {k: summary_dict(e.summary()) for k, e in self.calibrated.items()},
            "thesis": {k: summary_dict(s) for k, s in self.thesis.items()},
            "fitted_points": {"poh_climb": self.climb_points, "poh_cruise": self.cruise_points},
        }


def aircraft_data(root: Path, name: str, kinds=("poh_climb", "poh_cruise")) -> dict[str, Dataset]:
    """The aircraft's reference data named in its geometry file ([data] table), by kind."""
    geom = load_aircraft_geometry(root, name)
    missing = [k for k in kinds if k not in geom.data_files]
    if missing:
        raise ModelError(f"aircraft/{name}/geometry.toml names no data for {', '.join(missing)} ([data] table)")
    return {k: load_dataset(geom.data_files[k], control_travel=geom.control_travel_file, geometry=geom) for k in kinds}


def model_curves(root: Path, name: str, factors: FactorSet) -> tuple[dict[str, AeroCurves], dict[str, PropellerTables]]:
    """Lift curve, drag polar and propeller tables of the baseline and of the model at ``factors``."""
    with Simulator(root, name, baseline=True) as sb, Simulator(root, name, factors=factors) as sc:
        curves = {"baseline": aero_curves(sb), "calibrated": aero_curves(sc)}
    paths = AircraftPaths(root, name)
    return curves, {"baseline": propeller_tables(paths, FactorSet()), "calibrated": propeller_tables(paths, factors)}


def run_steady(root: Path | str, name: str, *, start: FactorSet | None = None,
               progress: Callable[[str], None] | None = None, executor: Executor = SERIAL,
               max_nfev: int | None = MAX_NFEV, bands: bool = True) -> SteadyCalibration:
    """Stage 1 on the aircraft's POH data, with baseline and calibrated evaluations
    (``executor``: where the fits' independent evaluations run; the same results anywhere).
    ``start``: default neutral, with the model switches the aircraft file sets (the slipstream).
    ``bands``: also the calibrated model's prediction bands (one evaluation per factor)."""
    root = Path(root)
    t0 = time.perf_counter()
    say = progress or (lambda s: None)
    data = aircraft_data(root, name)
    climb, cruise = data["poh_climb"], data["poh_cruise"]
    with Simulator(root, name, baseline=True) as sim:
        start = switches(sim.declared) if start is None else start
        say(f"baseline: trimming {len(climb) + len(cruise)} POH points")
        baseline = {k: evaluate_dataset(sim, ds, model_kind="baseline") for k, ds in data.items()}
        ci, ki = stage1_subset(climb), stage1_subset(cruise)
        fit, ff = steady_stage(sim, climb, cruise, start=start, climb_points=ci, cruise_points=ki, progress=say,
                               executor=executor, max_nfev=max_nfev)
        sim.set_factors(ff.final)
        say(f"calibrated: trimming {len(climb) + len(cruise)} POH points")
        calibrated = {k: evaluate_dataset(sim, ds) for k, ds in data.items()}
        trims = sim.trims                       # the calibration's trims, not the bands'
        drawn = None
        if bands:
            say("prediction bands: one evaluation of the POH points per fitted factor")
            drawn = prediction_bands(sim, ff.final, (fit, ff), calibrated)
    curves, tables = model_curves(root, name, ff.final)
    return SteadyCalibration(name, fit, ff, baseline, calibrated,
                             {k: thesis_summary(ds) for k, ds in data.items()}, ff.final,
                             time.perf_counter() - t0, trims, ci, ki, curves, tables, drawn)


# --------------------------------------------------------------------------- where a stage starts, what it runs
STAGES = ("steady", "trims", "dynamic")
STAGE_NAMES = {"steady": "stage 1", "trims": "stage 2a", "dynamic": "stage 2b"}
STAGE_DATA = {"steady": "poh_climb", "trims": "flight_test", "dynamic": "flight_test_results"}   # [data] key


def _recorded_fits(record: dict, stage: str) -> list[dict]:
    """The fit records of one stage in calibration.json, in the order they ran."""
    st = record.get("stages", {}).get(stage)
    if not isinstance(st, dict):
        return []
    return [st["fit"], st["fuel_flow"]] if stage == "steady" else list(st.get("steps", []))


def recorded_start(record: dict, declared: FactorSet, stage: str) -> tuple[FactorSet, str]:
    """Where ``stage`` starts when it runs alone (issue 26: the same command gives the same
    product): the model switches the aircraft file declares, every earlier stage's factors as
    that stage wrote them (the fits' final values in the calibration record, each fit over the
    ones before it) and every other factor neutral, so that a rerun does not start from its own
    last result. An earlier stage the record lacks leaves its factors neutral. Returns the
    factors and a sentence that states them."""
    values = dict(switches(declared).items())
    used, missing = [], []
    for earlier in STAGES[:STAGES.index(stage)]:
        fits = _recorded_fits(record, earlier)
        (used if fits else missing).append(STAGE_NAMES[earlier])
        for f in fits:
            values.update({n: d["final"] for n, d in f.get("factors", {}).items()})
    text = (f"{STAGE_NAMES[stage]} starts from "
            + (f"the factors {' and '.join(used)} wrote (calibration.json), every other factor neutral"
               if used else "neutral factors")
            + (f" ({' and '.join(missing)}: not recorded, its factors neutral)" if missing and used else "")
            + ", model switches as the aircraft file sets them")
    return FactorSet(values), text


def stage_start(root: Path | str, name: str, stage: str) -> tuple[FactorSet, str]:
    """:func:`recorded_start` for an aircraft of ``root``."""
    with Simulator(Path(root), name) as sim:
        declared = sim.declared
    return recorded_start(read_calibration_record(AircraftPaths(Path(root), name)), declared, stage)


def stage_plan(root: Path | str, name: str, stages: tuple[str, ...]) -> list[tuple[str, str, int | None]]:
    """The fits ``stages`` will run on the aircraft, those its data allow, in order: (stage,
    fit name, trims it took the last time or None). The fits are the ones the calibration
    record lists for the stage (those the last run did), else the stage's definition."""
    root = Path(root)
    geom = load_aircraft_geometry(root, name)
    record = read_calibration_record(AircraftPaths(root, name))
    defined = {"steady": STAGE1_STEPS, "trims": tuple(st.name for st in TRIM_STEPS),
               "dynamic": tuple(st.name for st in DYNAMIC_STEPS)}
    out = []
    for stage in (s for s in STAGES if s in stages and STAGE_DATA[s] in geom.data_files):
        fits = _recorded_fits(record, stage)
        out += ([(stage, f["stage"], f.get("trims")) for f in fits] if fits else
                [(stage, fit_name, None) for fit_name in defined[stage]])
    return out


# --------------------------------------------------------------------------- stage 2a
FLIGHT_TEST_KINDS = {"snapshot": "flight_test", "flap_climb": "flap_climb"}   # dataset kind -> [data] key


@dataclass
class TrimsCalibration:
    """The flight-test trim stage: fits per step and the evaluations between them.

    ``evaluations[label][kind]``: labels ``baseline`` (all factors neutral), ``steady``
    (stage 1 only, where stage 2a starts), then one per step; kinds ``snapshot`` and
    ``flap_climb``. ``poh_before``/``poh_after``: the POH evaluations before and after."""

    aircraft: str
    steps: list[FitResult]
    evaluations: dict[str, dict[str, Evaluation]]
    poh_before: dict[str, Evaluation]
    poh_after: dict[str, Evaluation]
    thesis: dict[str, Summary]
    factors: FactorSet
    skipped: list[str]
    wall_time_s: float
    trims: int
    bands: Bands | None = None                    # the final model's 95 % prediction bands (None: not computed)

    @property
    def data(self) -> dict[str, Dataset]:
        return {k: e.dataset for k, e in self.evaluations["steady"].items()}

    def summary(self) -> dict:
        """The stage's record (calibration.json), JSON-safe."""
        return {
            "aircraft": self.aircraft,
            "steps": [r.summary() for r in self.steps], "skipped_steps": self.skipped,
            "flight_test": {label: {k: summary_dict(e.summary()) for k, e in ev.items()}
                            for label, ev in self.evaluations.items()},
            "thesis": {k: summary_dict(s) for k, s in self.thesis.items()},
            "poh_before": {k: summary_dict(e.summary()) for k, e in self.poh_before.items()},
            "poh_after": {k: summary_dict(e.summary()) for k, e in self.poh_after.items()},
            "left_out": [str(q) for ds in self.data.values() for q in ds.extra.get("quirks", [])],
        }


def run_trims(root: Path | str, name: str, *, skip: tuple[str, ...] = (), steps: tuple[TrimStep, ...] = TRIM_STEPS,
              start: FactorSet | None = None, progress: Callable[[str], None] | None = None,
              executor: Executor = SERIAL, max_nfev: int | None = MAX_NFEV, bands: bool = True) -> TrimsCalibration:
    """Stage 2a on the aircraft's flight-test trims, from its stage-1 factors.

    ``skip``: names of steps left out (e.g. ``("pfactor",)``); ``start``: factors to start
    from (default :func:`recorded_start`: stage 1's factors as it recorded them, later ones
    neutral); ``bands``: also the final model's prediction bands (one evaluation of the
    flight-test and POH points per factor the steps set)."""
    root = Path(root)
    t0 = time.perf_counter()
    say = progress or (lambda s: None)
    geom = load_aircraft_geometry(root, name)
    keys = [k for k in FLIGHT_TEST_KINDS.values() if k in geom.data_files]
    if "flight_test" not in keys:
        raise ModelError(f"aircraft/{name}/geometry.toml names no flight_test data ([data] table)")
    data = aircraft_data(root, name, tuple(keys))
    ft = {ds.kind: ds for ds in data.values()}
    poh = aircraft_data(root, name)
    unknown = [s for s in skip if s not in {st.name for st in steps}]
    if unknown:
        raise InputError("command line", Problem("--skip", f"unknown step(s) {', '.join(unknown)}; steps: "
                                                           f"{', '.join(st.name for st in steps)}"))
    with Simulator(root, name) as sim:
        if start is None:
            start = recorded_start(read_calibration_record(AircraftPaths(root, name)), sim.declared, "trims")[0]
        evaluations: dict[str, dict[str, Evaluation]] = {}

        def evaluate(label: str, model_kind: str = "calibrated") -> None:
            evaluations[label] = {k: evaluate_dataset(sim, ds, model_kind=model_kind) for k, ds in ft.items()}

        sim.set_factors(FactorSet())
        evaluate("baseline", "baseline")
        sim.set_factors(start)
        evaluate("steady")
        say(f"stage 1 model: trimming {sum(len(d) for d in poh.values())} POH points")
        poh_before = {k: evaluate_dataset(sim, ds) for k, ds in poh.items()}
        run = tuple(st for st in steps if st.name not in skip)
        results = trims_stage(sim, {**ft, **poh}, start=start, steps=run, progress=say,
                              after_step=lambda st, res: evaluate(st.name), executor=executor, max_nfev=max_nfev)
        final = results[-1].final if results else start
        sim.set_factors(final)
        say(f"stage 2a model: trimming {sum(len(d) for d in poh.values())} POH points")
        poh_after = {k: evaluate_dataset(sim, ds) for k, ds in poh.items()}
        trims = sim.trims                       # the calibration's trims, not the bands'
        drawn = None
        if bands and results:
            say("prediction bands: one evaluation of the flight-test and POH points per factor")
            drawn = prediction_bands(sim, final, results, {**evaluations[results[-1].stage], **poh_after})
    return TrimsCalibration(name, results, evaluations, poh_before, poh_after,
                            {k: thesis_summary(ds) for k, ds in ft.items()}, final, list(skip),
                            time.perf_counter() - t0, trims, drawn)


# --------------------------------------------------------------------------- stage 2b
@dataclass
class DynamicCalibration:
    """Stage 2b: the fits per axis, the dynamic tests and the trims and POH before and after."""

    aircraft: str
    steps: list[FitResult]
    tests: list[DynamicTest]
    dynamic_before: DynamicEvaluation
    dynamic_after: DynamicEvaluation
    trims_before: dict[str, Evaluation]
    trims_after: dict[str, Evaluation]
    poh_after: dict[str, Evaluation]
    factors: FactorSet
    wall_time_s: float
    trims: int
    bands: dict[str, np.ndarray] | None = None    # per test: the 95 % band of its plotted response (None: not drawn)

    def summaries(self) -> dict[str, Summary]:
        """What the verdicts judge: the POH, the trims and the dynamic tests after the stage."""
        return {**{k: e.summary() for k, e in self.poh_after.items()},
                **{k: e.summary() for k, e in self.trims_after.items()}, "dynamic": self.dynamic_after.by_metric()}

    def summary(self) -> dict:
        """The stage's record (calibration.json), JSON-safe."""
        return {
            "aircraft": self.aircraft, "steps": [r.summary() for r in self.steps],
            "dynamic_before": self.dynamic_before.to_json(), "dynamic_after": self.dynamic_after.to_json(),
            "flight_test_after": {k: summary_dict(e.summary()) for k, e in self.trims_after.items()},
            "poh_after": {k: summary_dict(e.summary()) for k, e in self.poh_after.items()},
        }


def dynamic_tests(root: Path, name: str) -> list[DynamicTest]:
    """The aircraft's dynamic tests: its flight-test results file with the snapshots' initial conditions."""
    return aircraft_dynamic_tests(load_aircraft_geometry(root, name), name)


def run_dynamic(root: Path | str, name: str, *, start: FactorSet | None = None,
                steps: tuple[DynamicStep, ...] = DYNAMIC_STEPS,
                progress: Callable[[str], None] | None = None, executor: Executor = SERIAL,
                max_nfev: int | None = MAX_NFEV, bands: bool = True) -> DynamicCalibration:
    """Stage 2b on the aircraft's dynamic tests, from ``start`` (default :func:`recorded_start`:
    the factors stages 1 and 2a recorded, stage 2b's neutral); ``bands``: also the 95 % band
    of every test's response (one flight of the tests per fitted factor)."""
    root = Path(root)
    t0 = time.perf_counter()
    say = progress or (lambda s: None)
    tests = dynamic_tests(root, name)
    geom = load_aircraft_geometry(root, name)
    keys = tuple(k for k in FLIGHT_TEST_KINDS.values() if k in geom.data_files)
    ft = {ds.kind: ds for ds in aircraft_data(root, name, keys).values()}
    poh = aircraft_data(root, name)
    with Simulator(root, name) as sim:
        if start is None:
            start = recorded_start(read_calibration_record(AircraftPaths(root, name)), sim.declared, "dynamic")[0]
        sim.set_factors(start)
        say(f"flying {len(tests)} dynamic tests")
        before = evaluate_dynamic(sim, tests, executor=executor)
        trims_before = {k: evaluate_dataset(sim, ds) for k, ds in ft.items()}
        results = dynamic_stage(sim, tests, {**ft, **poh}, start=start, steps=steps, progress=say,
                                executor=executor, max_nfev=max_nfev)
        final = results[-1].final if results else start
        sim.set_factors(final)
        after = evaluate_dynamic(sim, tests, executor=executor)
        trims_after = {k: evaluate_dataset(sim, ds) for k, ds in ft.items()}
        poh_after = {k: evaluate_dataset(sim, ds) for k, ds in poh.items()}
        trims = sim.trims                       # the calibration's trims, not the bands'
        drawn = None
        if bands and results:
            say("prediction bands: one flight of the dynamic tests per fitted factor")
            drawn = response_bands(sim, final, results, after.results)
    return DynamicCalibration(name, results, tests, before, after, trims_before, trims_after, poh_after, final,
                              time.perf_counter() - t0, trims, drawn)


# --------------------------------------------------------------------------- close the loop
def run_close_loop(root: Path | str, name: str, data: Path | str, *, skip_steps: tuple[str, ...] = (),
                   progress: Callable[[str], None] | None = None) -> CloseLoopResult:
    """Close the loop on an aircraft with one data file (:func:`jsbsim_calib.calibration.closeloop.close_loop`).

    ``skip_steps``: first rerun stage 2a from the aircraft's stage-1 factors without these
    steps (e.g. ``("pfactor",)``: let the loop find what the step would have fitted)."""
    root = Path(root)
    say = progress or (lambda s: None)
    with Simulator(root, name) as sim:
        start = sim.factors
        if skip_steps:
            say(f"stage 2a without {', '.join(skip_steps)}")
            with warnings.catch_warnings():       # its rows left out are reported when the loop's data load
                warnings.simplefilter("ignore", QuirkWarning)
                start = run_trims(root, name, skip=tuple(skip_steps), progress=say, bands=False).factors
            sim.set_factors(start)
        ds = load_data_for(sim, data)
        res = close_loop(sim, ds, progress=say)
    res.notes.append(f"model: {name}" + (f", stage 2a rerun without {', '.join(skip_steps)}" if skip_steps else ""))
    return res


def load_data_for(sim: Simulator, data: Path | str) -> Dataset:
    """A data file checked against the aircraft (its control-travel table for snapshots)."""
    return load_dataset(data, control_travel=sim.geometry.control_travel_file, geometry=sim.geometry)
