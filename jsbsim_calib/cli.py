"""Command line: a thin layer over the library (parse, call, write through the product and the
reports, print).

    jsbsim-calib generate AIRCRAFT [--baseline]
    jsbsim-calib calibrate AIRCRAFT [--stage steady|trims|dynamic|all] [--no-write] [--start current] [--skip STEP]
                                    [--json OUT] [--exit-zero]
    jsbsim-calib evaluate AIRCRAFT --data FILE|DIR [--baseline] [--json OUT] [--report-dir DIR]
    jsbsim-calib synth --truth AIRCRAFT|DIR --out FILE.csv [--seed N] [--points N] [--noise X]
    jsbsim-calib synth --truth AIRCRAFT|DIR --plan PLAN --out DIR [--seed N] [--noise X]
    jsbsim-calib close-loop AIRCRAFT --data FILE [--json OUT] [--skip STEP] [--out NAME]
    jsbsim-calib close-loop AIRCRAFT --flight-test DIR_OR_FILE... [--json OUT] [--out NAME]
    jsbsim-calib check AIRCRAFT [--json OUT]
    jsbsim-calib evaluate|check AIRCRAFT --foreign-root DIR|jsbsim [--foreign-aircraft NAME] ...   any JSBSim aircraft
    jsbsim-calib export flightgear AIRCRAFT --out DIR
    jsbsim-calib regress AIRCRAFT --baseline REF.json [--data FILE...] [--share X] | --write-baseline REF.json
    jsbsim-calib validate AIRCRAFT [--stage steady|trims|dynamic|all] [--fold NAME] [--report-dir reports]
    jsbsim-calib slipstream AIRCRAFT [--stage steady|all] [--variant off|swirl|theory|fitted] [--max-nfev N] [--json OUT]
    jsbsim-calib airfoil NAME
    jsbsim-calib part60 AIRCRAFT --flight-test DIR_OR_FILE... [--json OUT] [--exit-zero]
    jsbsim-calib plan AIRCRAFT [--flight-test DIR_OR_FILE...] [--count N] [--factor NAME...] [--out DIR]

The global options (--root, --quiet, --verbose, --log-file, --executor, --workers, --scheduler) go
before or after the command. Exit codes: 0 done; 1 regress: something moved; 2 an error (bad input, nothing written
half); 3 calibrate / part60: done, but a target was missed (--exit-zero: 0).
"""
from __future__ import annotations

import argparse
import contextlib
import json
import multiprocessing
import signal
import sys
import threading
import time
import warnings
from pathlib import Path
from typing import Sequence


def _interrupted_loading(signum, frame):
    print("interrupted; nothing written", file=sys.stderr)
    raise SystemExit(130)


# Ctrl-C while the command loads (seconds on a busy machine): one line, exit 130 (main() then
# turns it into KeyboardInterrupt). A worker process (a pool's, a local dask cluster's) that loads
# this module ignores it: a terminal's Ctrl-C reaches every process of the command, and the
# command alone answers it. (A spawned worker has the command's sys.argv and runs its script
# as its own main module, named __mp_main__, before its parent_process() is set: a dask worker of
# `jsbsim-calib` took itself for the command and printed the line too.)
WORKER = getattr(sys.modules.get("__mp_main__"), "__name__", None) == "__mp_main__" \
    or multiprocessing.parent_process() is not None
ENTRY = not WORKER and (__name__ == "__main__" or Path(sys.argv[0]).name == "jsbsim-calib")   # the command
if ENTRY:
    signal.signal(signal.SIGINT, _interrupted_loading)
elif WORKER:
    signal.signal(signal.SIGINT, signal.SIG_IGN)

from . import __version__  # noqa: E402  (after the SIGINT handler: imports take seconds)
from .calibration.loop import write_aircraft  # noqa: E402
from .calibration.steady import steady_factors
from .calibration.trims import TRIM_STEPS
from .core.commit import new_run
from .core.errors import CalibError, InputError, Problem
from .core.executor import make_executor
from .evaluation.fleet import evaluate_fleet, format_fleet, log_files
from .evaluation.evaluate import evaluate_dataset
from .generate import generate
from .core.guard import command_guard, interrupted_message
from .jsbsim.aircraft import read_factors
from .jsbsim.probes import report
from .jsbsim.product import AircraftPaths, load_aircraft_geometry, read_calibration, recover_product, write_calibrated
from .jsbsim.simulator import Simulator
from .physics.airfoil import regenerate
from .core.preflight import command_problems
from .report.markdown import (write_close_loop_report, write_dynamic_report, write_evaluation_report, write_log_report,
                              write_steady_report, write_trims_report)
from .report.progress import PlanStep, Progress, Tee
from .report.text import evaluation_table, format_stability, format_summary
from .report.verdicts import format_verdicts, lost_targets, verdicts
from .synthetic.snapshots import synthesize, write_csv
from .synthetic.maneuvers import check_settings, load_plan, synthesize_maneuvers
from .calibration.variants import SLIPSTREAM, compare_variants
from .calibration.workflow import (STAGE_DATA, STAGE_NAMES, load_data_for, run_close_loop, run_dynamic, run_steady, run_trims,
                       stage_plan, stage_start)


EXIT_TARGETS_MISSED = 3        # calibrate, part60: the run is done, a target was missed (--exit-zero: 0)


def _verdict_exit(a, missed: int) -> int:
    """The exit code of a command that judges targets."""
    if missed and not a.exit_zero:
        print(f"exit code {EXIT_TARGETS_MISSED}: {missed} target(s) missed (--exit-zero to exit 0)", file=sys.stderr)
        return EXIT_TARGETS_MISSED
    return 0


def _write_json(path, obj) -> None:
    Path(path).write_text(json.dumps(obj, indent=2, default=float) + "\n")
    print(f"json: {path}")


def _progress(a, plan: Sequence[PlanStep] = ()) -> Progress:
    """The command's progress display (report.progress): a status line on stderr when stdout and
    stderr are a terminal (not with --quiet), every line with --verbose, and every line to
    --log-file; closed by _run."""
    console = getattr(a, "console", sys.stderr)
    p = Progress(plan, live=not a.quiet and console.isatty() and sys.stdout.isatty(),
                 verbose=a.verbose and not a.quiet, log=getattr(a, "log", None), stream=console, hold_stdout=True)
    a.displays = getattr(a, "displays", []) + [p]
    return p


def cmd_generate(a) -> int:
    g = generate(a.aircraft, Path(a.root), baseline=a.baseline, progress=_progress(a), force=a.force)
    for p in g.files:
        print(p)
    if g.dropped:
        print(f"dropped {len(g.dropped)} hand-edited line(s) (--force):", file=sys.stderr)
        for line in g.dropped:
            print(f"  {line}", file=sys.stderr)
    if g.backup is not None:
        print(f"backup of the replaced files: {g.backup}")
    return 0


def _calibrate_steady(a, root: Path, say, start, run: str):
    res = run_steady(root, a.aircraft, start=start, progress=say, executor=a.pool)
    print(res.fit.report())
    print(res.fuel_flow.report())
    for kind in res.calibrated:
        print(f"\n{kind}: baseline")
        print(format_summary(res.baseline[kind].summary()))
        print(f"{kind}: calibrated")
        print(format_summary(res.calibrated[kind].summary()))
        if res.thesis.get(kind):
            print(f"{kind}: thesis model (same points)")
            print(format_summary(res.thesis[kind]))
    print(f"\nwall time {res.wall_time_s:.1f} s, {res.trims} trims")
    if not a.no_write:
        print(write_calibrated(root, a.aircraft, res.factors, "steady", res.summary(), run=run).report())
    print(f"report: {write_steady_report(res, Path(a.report_dir) / a.aircraft)}")
    return res.factors, {k: e.summary() for k, e in res.calibrated.items()}


def _calibrate_trims(a, root: Path, say, start, run: str):
    res = run_trims(root, a.aircraft, skip=tuple(a.skip or ()), progress=say, start=start, executor=a.pool)
    for r in res.steps:
        print(r.report())
    last = list(res.evaluations)[-1]
    for kind in res.evaluations["steady"]:
        for label in ("steady", last):
            print(f"\n{kind}: {'stage 1 model' if label == 'steady' else 'after ' + label}")
            print(format_summary(res.evaluations[label][kind].summary()))
    for kind in res.poh_after:
        print(f"\n{kind}: POH accuracy, stage 1 model")
        print(format_summary(res.poh_before[kind].summary()))
        print(f"{kind}: POH accuracy after stage 2a")
        print(format_summary(res.poh_after[kind].summary()))
    print(f"\nwall time {res.wall_time_s:.1f} s, {res.trims} trims")
    if not a.no_write:
        print(write_calibrated(root, a.aircraft, res.factors, "trims", res.summary(), run=run).report())
    print(f"report: {write_trims_report(res, Path(a.report_dir) / a.aircraft)}")
    return res.factors, {**{k: e.summary() for k, e in res.poh_after.items()},
                         **{k: e.summary() for k, e in res.evaluations[last].items()}}


def _calibrate_dynamic(a, root: Path, say, start, run: str):
    res = run_dynamic(root, a.aircraft, start=start, progress=say, executor=a.pool)
    for r in res.steps:
        print(r.report())
    print("\ndynamic tests (before -> after stage 2b):")
    for rb, ra in zip(res.dynamic_before.results, res.dynamic_after.results):
        for mb, ma in zip(rb.metrics, ra.metrics):
            print(f"  {ra.test.id:<6} {ma.metric.name:<22} flight test {ma.metric.measured:8.3g}   model "
                  f"{mb.model:8.3g} -> {ma.model:8.3g}   {ma.metric.tolerance_text():>16}  {ma.verdict}")
    for kind, ev in res.trims_after.items():
        print(f"\n{kind}: after stage 2b")
        print(format_summary(ev.summary()))
    print(f"\nwall time {res.wall_time_s:.1f} s, {res.trims} trims, "
          f"{res.dynamic_after.frames} frames per dynamic evaluation")
    if not a.no_write:
        print(write_calibrated(root, a.aircraft, res.factors, "dynamic", res.summary(), run=run).report())
    print(f"report: {write_dynamic_report(res, Path(a.report_dir) / a.aircraft)}")
    return res.factors, res.summaries()


CALIBRATE_STAGES = {"steady": ("steady",), "trims": ("trims",), "dynamic": ("dynamic",),
                    "all": ("steady", "trims", "dynamic")}
FINAL_MODEL = {"steady": "stage 1 (POH climb and cruise)", "trims": "stage 2a (flight-test trims, after stage 1)",
               "dynamic": "stage 2b (dynamic tests, after stages 1 and 2a)"}
STAGE_RUNS = {"steady": _calibrate_steady, "trims": _calibrate_trims, "dynamic": _calibrate_dynamic}


def _first_start(a, root: Path, stage: str):
    """Where the command's first stage starts (printed): the stated, reproducible point
    (workflow.recorded_start; stage 1: neutral), or (--start current) the current calibration
    (stage 1: calibration.json; stages 2a and 2b: the aircraft file's values, stage 2a with the
    later stages' factors neutral)."""
    if a.start == "current":
        print(f"start: {STAGE_NAMES[stage]} starts from the current calibration (--start current: a rerun starts "
              "from this run's result)")
        paths = AircraftPaths(root, a.aircraft)
        if stage == "steady":
            return read_calibration(paths)
        declared = read_factors(paths.aircraft_xml)
        return steady_factors(declared) if stage == "trims" else declared
    start, text = stage_start(root, a.aircraft, stage)
    print(f"start: {text}")
    return None if stage == "steady" else start


def cmd_calibrate(a) -> int:
    root = Path(a.root)
    plan = stage_plan(root, a.aircraft, CALIBRATE_STAGES[a.stage])
    say = _progress(a, [PlanStep(fit, f"{STAGE_NAMES[stage]} {fit}", trims) for stage, fit, trims in plan])
    run = new_run()                      # one backup per run: the product as it stood before it
    factors, summaries, final, history = None, {}, "", []
    for stage in CALIBRATE_STAGES[a.stage]:
        if stage not in {s for s, _, _ in plan}:
            if a.stage == stage:
                raise CalibError(f"aircraft/{a.aircraft}/geometry.toml names no {STAGE_DATA[stage]} data ([data] "
                                 "table)" + (": no dynamic tests" if stage == "dynamic" else ""))
            print(f"\n{a.aircraft}: no {'dynamic ' if stage == 'dynamic' else ''}flight-test data, "
                  f"{STAGE_NAMES[stage]} skipped")
            continue
        if factors is None:
            factors = _first_start(a, root, stage)
        else:
            print()
            factors = steady_factors(factors) if stage == "trims" else factors
        factors, summaries = STAGE_RUNS[stage](a, root, say, factors, run)
        final = FINAL_MODEL[stage]
        history.append((STAGE_NAMES[stage], verdicts(summaries)))
    where = "not written (--no-write)" if a.no_write else f"written to {root / 'aircraft' / a.aircraft}"
    print(f"\nfinal model: {final}, {where}")
    vs = verdicts(summaries)
    print(format_verdicts(vs, f"{a.aircraft} model from {final}", history[:-1]))
    if a.json:
        _write_json(a.json, {"aircraft": a.aircraft, "stage": a.stage, "final_model": final,
                             "written": not a.no_write, "targets_met": sum(v.passed for v in vs),
                             "verdicts": [v.to_json() for v in vs],
                             "lost": [{**v.to_json(), "met_after": stage} for v, stage in lost_targets(history)]})
    return _verdict_exit(a, sum(not v.passed for v in vs))


def _evaluate_fleet(a) -> int:
    """``evaluate AIRCRAFT --data DIR``: every G1000 log of the folder (jsbsim_calib.evaluation.fleet)."""
    with _simulator(a) as sim:
        res = evaluate_fleet(sim, Path(a.data), executor=a.pool, progress=_progress(a))
    print(format_fleet(res))
    if a.json:
        Path(a.json).write_text(json.dumps(res.to_json(), indent=2) + "\n")
        print(f"json: {a.json}")
    return 0


def cmd_evaluate(a) -> int:
    if Path(a.data).is_dir():
        return _evaluate_fleet(a)
    with _simulator(a) as sim:
        ds = load_data_for(sim, a.data)
        ds, estimate = _log_loading(a, sim, ds)        # G1000 logs: the loading given, the weight estimated
        ev = evaluate_dataset(sim, ds, model_kind="baseline" if a.baseline else "calibrated",
                              progress=None)
    print(evaluation_table(ev))
    vs = verdicts({ds.kind: ev.summary()})
    if vs:
        print(format_verdicts(vs, f"{sim.name} model ({'baseline' if a.baseline else 'as it stands'}) on {Path(a.data).name}"))
    if ds.kind == "g1000":
        print(ds.extra["weight_note"])
        if estimate is not None:
            print(estimate.describe() + (" (used)" if a.estimate_weight else " (not used: --estimate-weight)"))
    if a.report_dir is None:
        print("report: not written (--report-dir DIR writes it to DIR/AIRCRAFT/)")
    elif ds.kind == "g1000":
        png, md = write_log_report(ev, Path(a.report_dir) / sim.name, weight_estimate=estimate)
        print(f"plot: {png}\nreport: {md}")
    else:
        print(f"report: {write_evaluation_report(ev, Path(a.report_dir) / sim.name)}")
    if a.json:
        ev.write_json(Path(a.json))
        print(f"json: {a.json}")
    return 0


MAX_POINTS = 10000          # synth --points


def truth_folder(a) -> Path | None:
    """synth --truth: an aircraft named as every command names one (a plain name: the folder
    aircraft/NAME under --root), or an aircraft folder anywhere (a path; also a plain name that
    is a folder here and no aircraft of --root). None when it is neither."""
    named = Path(a.root) / "aircraft" / a.truth
    plain = Path(a.truth).name == a.truth and a.truth not in (".", "..")
    if plain and (named / f"{a.truth}.xml").is_file():
        return named
    return Path(a.truth) if Path(a.truth).is_dir() else None


def cmd_synth(a) -> int:
    check_settings(a.seed, a.noise)
    if a.plan:
        return _synth_plan(a)
    if not 1 <= a.points <= MAX_POINTS:
        raise InputError("synth", Problem("--points", f"{a.points}: give a number of trims in [1, {MAX_POINTS}]"))
    with Simulator.from_dir(truth_folder(a), Path(a.root)) as truth:
        rows, skipped = synthesize(truth, n=a.points, seed=a.seed, noise=a.noise, progress=_progress(a))
    if not rows:
        raise CalibError(f"synth: none of the {a.points} points trimmed on {Path(a.truth).name}; nothing written "
                         f"({'; '.join(skipped[:3])})")
    write_csv(rows, Path(a.out))
    for s in skipped:
        print(f"left out (the truth does not trim): {s}", file=sys.stderr)
    print(f"{len(rows)} snapshots of {Path(a.truth).name} (seed {a.seed}, noise x{a.noise:g}) written to {a.out}")
    return 0


def _synth_plan(a) -> int:
    plan = load_plan(a.plan)
    with Simulator.from_dir(truth_folder(a), Path(a.root)) as truth:
        files = synthesize_maneuvers(truth, plan, Path(a.out), seed=a.seed, noise=a.noise,
                                     progress=_progress(a))
    for f in files:
        print(f)
    print(f"{len(files)} time histories of {Path(a.truth).name} (plan {plan.name}, {plan.sample_rate_hz:g} Hz, "
          f"seed {a.seed}, noise x{a.noise:g}) written to {a.out}")
    return 0


def _close_loop_dynamic(a) -> int:
    from .calibration.closeloop_dynamic import run_close_loop_dynamic
    from .report.closeloop_dynamic_report import format_result, write_close_loop_dynamic_report
    if a.skip:
        raise CalibError("close-loop --flight-test: --skip reruns stage 2a for trim data, not for time histories")
    root = Path(a.root)
    res = run_close_loop_dynamic(root, a.aircraft, a.flight_test, progress=_progress(a), executor=a.pool)
    print(format_result(res))
    written = None
    if not a.no_write:
        written = write_aircraft(res, root, a.aircraft if a.in_place else (a.out or f"{a.aircraft}_loop"))
        print(f"aircraft: {written}")
    command = f"jsbsim-calib close-loop {a.aircraft} --flight-test {' '.join(Path(f).name for f in a.flight_test)}"
    print(f"report: {write_close_loop_dynamic_report(res, Path(a.report_dir) / a.aircraft, written, command)}")
    if a.json:
        Path(a.json).write_text(json.dumps(res.to_json(), indent=2, default=float) + "\n")
        print(f"json: {a.json}")
    return 0


def cmd_close_loop(a) -> int:
    if a.flight_test:
        return _close_loop_dynamic(a)
    root = Path(a.root)
    res = run_close_loop(root, a.aircraft, Path(a.data), skip_steps=tuple(a.skip or ()),
                         progress=_progress(a))
    s = res.summaries("all")
    print("before:")
    print(format_summary(s.before))
    print("after:")
    print(format_summary(s.after))
    print(f"added: {', '.join(res.added) or 'nothing'}")
    for rec in res.synthesized:                # terms synthesized beyond the library (calibration.synthesis)
        terms = "; ".join(f"{t['coefficient']} ~ {t['regressor']} = {t['final' if rec.accepted else 'fitted']:.4g} "
                          f"({t['interpretation']})" for t in rec.terms) or "no term selected"
        print(f"synthesized, round {rec.round}: {terms}: {'added' if rec.accepted else 'rejected: ' + rec.reason}")
    for u in res.unexplained():
        print(f"unexplained: {u.metric} correlates with {', '.join(u.correlates_with[:3]) or 'no single state'}")
    written = None
    if not a.no_write:
        written = write_aircraft(res, root, a.aircraft if a.in_place else (a.out or f"{a.aircraft}_loop"))
        print(f"aircraft: {written}")
    print(f"report: {write_close_loop_report(res, Path(a.report_dir) / a.aircraft, written)}")
    if a.json:
        Path(a.json).write_text(json.dumps(res.to_json(), indent=2, default=float) + "\n")
        print(f"json: {a.json}")
    return 0


def cmd_check(a) -> int:
    with _simulator(a) as sim:
        rep = report(sim, **_check_inputs(sim))
    print(format_stability(rep))
    if a.json:
        Path(a.json).write_text(json.dumps(rep.as_dict(), indent=2) + "\n")
        print(f"json: {a.json}")
    return 0


def cmd_airfoil(a) -> int:
    print(regenerate(a.name, Path(a.out)))
    return 0


def cmd_part60(a) -> int:
    from .data.part60_tests import FAIL
    from .evaluation.part60 import evaluate_part60, load_part60_inputs
    from .report.part60_report import format_part60_table, write_part60_report
    with Simulator(Path(a.root), a.aircraft) as sim:
        inputs = load_part60_inputs(a.flight_test, sim.geometry.control_travel_file)
        ev = evaluate_part60(sim, summary=inputs.summary, time_histories=inputs.time_histories,
                             ignored=inputs.ignored, progress=_progress(a))
    command = f"jsbsim-calib part60 {a.aircraft} --flight-test {' '.join(map(str, a.flight_test))}"
    files = write_part60_report(ev, Path(a.report_dir) / a.aircraft / "part60", command)
    print(format_part60_table(ev))
    for note in ev.ignored:
        print(f"not used: {note}")
    print(f"report: {files.markdown}\nhtml: {files.html} (self-contained)")
    if a.json:
        _write_json(a.json, ev.to_json())
    return _verdict_exit(a, ev.counts()[FAIL])


# --------------------------------------------------------------------------- G1000 loading, validate
LOADING_OPTIONS = ("occupants_lb", "baggage_lb", "fuel_density_lb_per_gal", "cg_in")


def _log_loading(a, sim, ds):
    """A G1000 log with the loading given on the command line and the weight estimated from the
    log (used instead of the assumption with --estimate-weight); other data unchanged."""
    from .data.logs import LogLoading, log_dataset
    from .evaluation.weight_estimate import estimate_weight, with_weight_offset
    given = {k: getattr(a, k) for k in LOADING_OPTIONS if getattr(a, k, None) is not None}
    if ds.kind != "g1000":
        if given or getattr(a, "estimate_weight", False):
            raise CalibError("--occupants-lb, --baggage-lb, --fuel-density, --cg-in and --estimate-weight apply to a "
                             f"G1000 log, not to data of kind '{ds.kind}'")
        return ds, None
    if given:
        ds = log_dataset(ds.path, sim.geometry, LogLoading(**given))
    try:
        estimate = estimate_weight(sim, ds)
    except CalibError as exc:
        if a.estimate_weight:
            raise
        print(f"warning: weight not estimated: {exc}", file=sys.stderr)
        return ds, None
    return (with_weight_offset(ds, estimate) if a.estimate_weight else ds), estimate


STAGE_NUMBERS = {"steady": "1", "trims": "2a", "dynamic": "2b"}


def cmd_validate(a) -> int:
    from .calibration.validation import STAGE_DATA_KEYS, fold_names, stage_data, validate_steady, validate_trims
    from .calibration.validation_dynamic import dynamic_fold_names, validate_dynamic
    from .evaluation.physics_checks import run_physics_checks
    from .report.validation_report import format_physics, format_validation, write_validation_report
    root, say, t0 = Path(a.root), _progress(a), time.perf_counter()
    geom = load_aircraft_geometry(root, a.aircraft)
    stages = (a.stage,)
    if a.stage == "all":
        has = {st: all(k in geom.data_files for k in STAGE_DATA_KEYS[st]) for st in ("trims", "dynamic")}
        for st in [st for st, ok in has.items() if not ok]:
            print(f"{a.aircraft}: no {' / '.join(STAGE_DATA_KEYS[st])} data, stage {STAGE_NUMBERS[st]} not validated")
        stages = ("steady",) + tuple(st for st, ok in has.items() if ok)
    folds = {st: None for st in stages}
    if a.fold:                               # each stage runs the named folds it has
        names = {st: dynamic_fold_names(root, a.aircraft) if st == "dynamic" else fold_names(root, a.aircraft, st)
                 for st in stages}
        unknown = [f for f in a.fold if not any(f in n for n in names.values())]
        if unknown:
            raise CalibError(f"unknown fold(s) {', '.join(unknown)}; folds: "
                             + "; ".join(f"{st}: {', '.join(n)}" for st, n in names.items()))
        folds = {st: [f for f in a.fold if f in names[st]] for st in stages if set(a.fold) & set(names[st])}
    run = {"steady": validate_steady, "trims": validate_trims, "dynamic": validate_dynamic}
    kw = {} if a.max_nfev is None else {"max_nfev": a.max_nfev}
    pool = {"steady": {"executor": a.pool}, "trims": {"executor": a.pool}, "dynamic": {}}   # folds as independent tasks
    vals = [run[st](root, a.aircraft, folds=f, progress=say, **kw, **pool[st]) for st, f in folds.items()]
    for v in vals:
        print(format_validation(v) + "\n")
    physics = None
    if not a.no_physics:
        physics = run_physics_checks(root, a.aircraft, stage_data(root, a.aircraft, ("poh_climb", "poh_cruise")), say)
        print(format_physics(physics))
    command = f"jsbsim-calib validate {a.aircraft}" + ("" if a.stage == "all" else f" --stage {a.stage}")
    md = write_validation_report(a.aircraft, vals, physics, Path(a.report_dir) / a.aircraft, command)
    print(f"report: {md}")
    if a.json:
        Path(a.json).write_text(json.dumps({"validations": [v.to_json() for v in vals]}, indent=2) + "\n")
        print(f"json: {a.json}")
    times = ", ".join(f"{v.stage} {v.wall_time_s:.0f} s ({len(v.folds) + (v.control is not None)} refits, "
                      f"{v.trims} trims)" for v in vals)
    extra = "" if physics is None else f", physics checks {physics.wall_time_s:.1f} s"
    print(f"validation wall time {time.perf_counter() - t0:.0f} s: {times}{extra}")
    return 0


def cmd_slipstream(a) -> int:
    from .factors import SWITCHES
    from .report.variants_report import format_comparison, write_comparison_report
    root = Path(a.root)
    load_aircraft_geometry(root, a.aircraft)
    chosen = [v for v in SLIPSTREAM if not a.variant or v.name in a.variant]
    kw = {} if a.max_nfev is None else {"max_nfev": a.max_nfev}
    results = compare_variants(root, a.aircraft, chosen, stages=a.stage, progress=_progress(a),
                               executor=a.pool, **kw)
    print(format_comparison(a.aircraft, results))
    product = read_calibration(AircraftPaths(root, a.aircraft))
    command = (f"jsbsim-calib slipstream {a.aircraft}" + ("" if a.stage == "all" else f" --stage {a.stage}")
               + ("" if a.max_nfev is None else f" --max-nfev {a.max_nfev}"))
    md = write_comparison_report(a.aircraft, results, {k: product[k] for k in SWITCHES},
                                 Path(a.report_dir) / a.aircraft, command)
    print(f"report: {md}")
    if a.json:
        Path(a.json).write_text(json.dumps({"aircraft": a.aircraft, "variants": [r.to_json() for r in results]},
                                           indent=2) + "\n")
        print(f"json: {a.json}")
    return 0


# --------------------------------------------------------------------------- foreign aircraft, export, regress
def _is_foreign(root: Path, name: str) -> bool:
    """An aircraft of the JSBSim root without a geometry file: one the workbench did not generate."""
    paths = AircraftPaths(root, name)
    return not paths.geometry.is_file() and (root / "aircraft" / name / f"{name}.xml").is_file()


def _simulator(a) -> Simulator:
    """The command's aircraft: a workbench aircraft, or any JSBSim aircraft (--foreign-root, or an
    aircraft of --root without geometry.toml, e.g. the jsbsim package's c172p)."""
    foreign_root = getattr(a, "foreign_root", None)
    if not foreign_root and _is_foreign(Path(a.root), a.aircraft):
        foreign_root = a.root
    if not foreign_root:
        return Simulator(Path(a.root), a.aircraft, baseline=a.baseline)
    from .jsbsim.foreign import foreign_simulator
    if a.baseline:
        raise CalibError("--baseline: a foreign aircraft has no calibration factors")
    return foreign_simulator(Path(a.root), a.aircraft, foreign_root, a.foreign_aircraft)


def _check_inputs(sim) -> dict:
    from .jsbsim.foreign import ForeignSimulator, check_conditions, stall_cases
    return {"conditions": check_conditions(sim), "stall_cases": stall_cases(sim)} if isinstance(sim, ForeignSimulator) else {}


ANY_AIRCRAFT = ("aircraft name: folder aircraft/AIRCRAFT under --root; one without geometry.toml (e.g. c172p under "
                "the jsbsim package's root) is any JSBSim aircraft, flown as its file stands")


def _foreign_options(parser) -> None:
    parser.add_argument("--foreign-root", metavar="DIR",
                        help="fly a JSBSim aircraft the workbench did not generate, from this JSBSim root "
                             "('jsbsim': the jsbsim package's own aircraft, e.g. c172p, c172x)")
    parser.add_argument("--foreign-aircraft", metavar="NAME",
                        help="with --foreign-root: the aircraft there (default AIRCRAFT); a workbench AIRCRAFT lends "
                             "its POH conventions (leaning altitude, fuel share, rated power, weights, airspeed "
                             "calibration)")


def cmd_export(a) -> int:
    from .export.flightgear import export_flightgear
    ex = export_flightgear(Path(a.root), a.aircraft, Path(a.out))
    for f in ex.files:
        print(f)
    print(f"fly it: fgfs --fg-aircraft={ex.folder.parent} --aircraft={ex.name}")
    return 0


def cmd_regress(a) -> int:
    from .evaluation.regress import regress, write_baseline
    say = _progress(a)
    if a.write_baseline:
        print(f"baseline: {write_baseline(Path(a.root), a.aircraft, Path(a.write_baseline), a.data, say)}")
        return 0
    if not a.baseline:
        raise CalibError("regress: give --baseline REF.json (or --write-baseline REF.json)")
    res = regress(Path(a.root), a.aircraft, a.baseline, a.data, a.share, say)
    print(res.report())
    if a.json:
        Path(a.json).write_text(json.dumps(res.to_json(), indent=2) + "\n")
        print(f"json: {a.json}")
    return 1 if res.moved else 0


def cmd_plan(a) -> int:
    from .synthetic.design import run_plan
    from .report.flight_card import write_flight_card
    out = Path(a.out or Path(a.report_dir) / a.aircraft / "plan")
    res = run_plan(Path(a.root), a.aircraft, out, flight_test=a.flight_test, base_plan=a.plan, count=a.count,
                   targets=tuple(a.factor or ()), progress=_progress(a))
    prop = res.proposal
    card = write_flight_card(prop, out)
    print(f"{a.aircraft}: data in hand: {prop.evidence}")
    print("standard errors now: " + ", ".join(f"{n} {prop.se_in_hand[n]:.3g}" for n in prop.names))
    print(f"aimed at: {', '.join(prop.targets)}; {prop.tried} candidates flown, {len(prop.dropped)} left out")
    for k, p in enumerate(prop.picks, 1):
        m = p.scored.candidate.spec
        after = ", ".join(f"{n} {p.se_after[n]:.3g}" for n in prop.targets)
        print(f"{k}. {m.id} {m.title}: {after}")
    print(f"flight card: {card['markdown']} and {card['html']}")
    print(f"plan: {res.plan_file} (fly it on a truth: jsbsim-calib synth --truth AIRCRAFT --plan {res.plan_file} "
          f"--out DIR); JSBSim scripts: {res.plan_file.parent / 'scripts'}  ({res.wall_time_s:.0f} s)")
    return 0


def _plan_parser(sub) -> None:
    from .factors import DYNAMIC_STEPS, set_in
    n = sub.add_parser("plan", help="what to fly next: the maneuvers that most shrink the standard errors of the "
                                    "loosest stage-2b factors, as a flight card (Markdown + HTML), a plan file and "
                                    "JSBSim scripts")
    n.add_argument("aircraft", help="aircraft name: folder aircraft/AIRCRAFT under --root")
    n.add_argument("--flight-test", nargs="+", metavar="DIR_OR_FILE",
                   help="the data in hand as time histories (default: the aircraft's flight-test results table)")
    n.add_argument("--count", type=int, default=None, help="maneuvers to propose (default 4)")
    n.add_argument("--factor", nargs="+", choices=set_in(DYNAMIC_STEPS), metavar="NAME",
                   help="aim at these factors (default: the two loosest)")
    n.add_argument("--plan", default="level5", help="the catalogue plan whose tests are moved to new conditions "
                                                    "(default the packaged level5)")
    n.add_argument("--out", help="folder to write to (default REPORT_DIR/AIRCRAFT/plan)")
    n.add_argument("--report-dir", default="reports", help="reports folder (default reports/)")
    n.set_defaults(func=cmd_plan)


def _export_regress_parsers(sub) -> None:
    x = sub.add_parser("export", help="write a calibrated aircraft for a simulator: flightgear (an aircraft folder)")
    x.add_argument("target", choices=("flightgear",), help="flightgear: NAME-set.xml, the FDM, Engines/, README")
    x.add_argument("aircraft", help="aircraft name: folder aircraft/AIRCRAFT under --root")
    x.add_argument("--out", required=True, help="the aircraft folder to write (fgfs --fg-aircraft=ITS_PARENT)")
    x.set_defaults(func=cmd_export)
    r = sub.add_parser("regress", help="re-evaluate after a hand edit and list every metric per data point that moved "
                                       "(exit 1 when something moved)")
    r.add_argument("aircraft", help="aircraft name: folder aircraft/AIRCRAFT under --root")
    r.add_argument("--baseline", metavar="REF.json", help="compare with this baseline")
    r.add_argument("--write-baseline", metavar="REF.json", help="evaluate and record the baseline instead")
    r.add_argument("--data", nargs="+", metavar="FILE", help="only these data files (default: all the aircraft's)")
    r.add_argument("--share", type=float, default=0.1, help="a move counts above this share of its tolerance (0.1)")
    r.add_argument("--json", help="also write the moves as JSON to this file")
    r.set_defaults(func=cmd_regress)


def _analysis_parsers(sub) -> None:
    """evaluate, validate, synth and close-loop: the commands that compare the model with data."""
    e = sub.add_parser("evaluate", help="compare the model with a data file (POH, flight test, G1000 log)")
    e.add_argument("aircraft", help=ANY_AIRCRAFT)
    e.add_argument("--data", required=True,
                   help="data file: POH climb/cruise CSV, flight-test snapshots or flap climbs, G1000 log; or a "
                        "folder of G1000 logs (a fleet: one row per log)")
    e.add_argument("--baseline", action="store_true", help="evaluate the uncalibrated model")
    e.add_argument("--json", help="write the results as JSON to this file")
    e.add_argument("--report-dir", help="write the report (and a G1000 log's plot) to REPORT_DIR/AIRCRAFT/; default: "
                                        "none written (the console and --json give the figures)")
    e.add_argument("--occupants-lb", dest="occupants_lb", type=float, help="G1000 log: occupants [lb] (default 340)")
    e.add_argument("--baggage-lb", dest="baggage_lb", type=float, help="G1000 log: baggage [lb] (default 0)")
    e.add_argument("--fuel-density", dest="fuel_density_lb_per_gal", type=float,
                   help="G1000 log: fuel density [lb/US gal] (default 6.0, avgas)")
    e.add_argument("--cg-in", dest="cg_in", type=float, help="G1000 log: CG station [in] (default the POH CG)")
    e.add_argument("--estimate-weight", action="store_true",
                   help="G1000 log: use the weight estimated from the level segments' RPM instead of the loading")
    _foreign_options(e)
    e.set_defaults(func=cmd_evaluate)

    v = sub.add_parser("validate", help="held-out validation of the calibration stages (refits with data left out) "
                                        "and physics checks; writes REPORT_DIR/AIRCRAFT/validation.md")
    v.add_argument("aircraft", help="aircraft name: folder aircraft/AIRCRAFT under --root")
    v.add_argument("--stage", choices=("steady", "trims", "dynamic", "all"), default="all",
                   help="steady: stage 1 folds; trims: stage 2a folds; dynamic: stage 2b folds; all (default): those "
                        "the data allow")
    v.add_argument("--fold", action="append", metavar="NAME", help="run only this fold (repeatable; e.g. 'flaps 10')")
    v.add_argument("--max-nfev", dest="max_nfev", type=_positive_int, help="evaluations per refit (default 60)")
    v.add_argument("--no-physics", action="store_true", help="skip the physics checks")
    v.add_argument("--json", help="also write the validation results as JSON to this file")
    v.add_argument("--report-dir", default="reports", help="where the report goes (REPORT_DIR/AIRCRAFT/)")
    v.set_defaults(func=cmd_validate)

    s = sub.add_parser("slipstream", help="the propeller slipstream off, its swirl alone, as the theory gives it, and "
                                          "fitted: each variant calibrated from neutral on the same data; writes "
                                          "REPORT_DIR/AIRCRAFT/slipstream.md (nothing else)")
    s.add_argument("aircraft", help="aircraft name: folder aircraft/AIRCRAFT under --root")
    s.add_argument("--stage", choices=("steady", "all"), default="all",
                   help="steady: stage 1 only; all (default): every stage the aircraft's data allow")
    s.add_argument("--json", help="also write each variant's factors and figures as JSON to this file")
    s.add_argument("--max-nfev", dest="max_nfev", type=_positive_int, metavar="N",
                   help="evaluations per fit (default: the calibration's); fewer for a quick look")
    s.add_argument("--variant", action="append", choices=tuple(v.name for v in SLIPSTREAM),
                   help="run only this variant (repeatable; default all of them)")
    s.add_argument("--report-dir", default="reports", help="where the report goes (REPORT_DIR/AIRCRAFT/)")
    s.set_defaults(func=cmd_slipstream)

    y = sub.add_parser("synth", help="synthetic flight-test snapshots (or, with --plan, time histories) flown by a "
                                     "truth aircraft folder")
    y.add_argument("--truth", required=True, metavar="AIRCRAFT",
                   help="the truth aircraft, flown as its XML stands: an aircraft name (folder aircraft/AIRCRAFT under "
                        "--root), or a path to an aircraft folder anywhere")
    y.add_argument("--out", required=True, help="snapshot CSV to write; with --plan: the directory of the time histories")
    y.add_argument("--plan", help="fly a maneuver plan (TOML file, or 'level5' for the packaged Level 5 plan) and "
                                  "write one CSV + JSON per maneuver (format 1)")
    y.add_argument("--seed", type=int, default=0, help="seed of the campaign's random draws (default 0)")
    y.add_argument("--points", type=int, default=48, help="number of trims of the campaign (default 48; not with --plan)")
    y.add_argument("--noise", type=float, default=1.0, help="scale of the measurement noise (0: none)")
    y.set_defaults(func=cmd_synth)

    o = sub.add_parser("close-loop", help="find structured residuals, add the missing effect, refit, report")
    o.add_argument("aircraft", help="aircraft name: folder aircraft/AIRCRAFT under --root")
    source = o.add_mutually_exclusive_group(required=True)
    source.add_argument("--data", help="flight-test snapshots, flap climbs or POH data")
    source.add_argument("--flight-test", nargs="+", metavar="DIR_OR_FILE",
                        help="time histories (format 1: folders and/or CSV files with JSON sidecars): close the loop "
                             "on recorded maneuvers")
    o.add_argument("--json", help="write the result as JSON to this file")
    o.add_argument("--skip", action="append", metavar="STEP",
                   help="first rerun stage 2a without this step (e.g. pfactor); repeatable")
    o.add_argument("--out", help="name of the aircraft folder written (default AIRCRAFT_loop)")
    o.add_argument("--in-place", action="store_true", help="write the effects into the aircraft itself")
    o.add_argument("--no-write", action="store_true", help="write no aircraft")
    o.add_argument("--report-dir", default="reports", help="where the report goes (REPORT_DIR/AIRCRAFT/)")
    o.set_defaults(func=cmd_close_loop)


def _positive_int(text: str) -> int:
    """An argparse type: a whole number of at least 1 (e.g. --max-nfev)."""
    try:
        n = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a whole number") from None
    if n < 1:
        raise argparse.ArgumentTypeError(f"{n}: give at least 1")
    return n


GLOBAL_DEFAULTS = {"root": ".", "quiet": False, "verbose": False, "log_file": None, "executor": "process",
                   "workers": None, "scheduler": None}


def _global_options(p, suppress: bool) -> None:
    """The options every command takes, before the command (``suppress`` False: with their
    defaults) or after it (``suppress`` True: set only when given, so a value given before the
    command is not clobbered by a default)."""
    d = (lambda key: argparse.SUPPRESS) if suppress else GLOBAL_DEFAULTS.get
    p.add_argument("--root", default=d("root"), help="JSBSim root (holds aircraft/, engine/, data/); default: current dir")
    p.add_argument("--quiet", action="store_true", default=d("quiet"),
                   help="no progress display (it shows only on a terminal: a step counter, the time elapsed and an "
                        "estimate of the time left)")
    p.add_argument("--verbose", action="store_true", default=d("verbose"),
                   help="every progress line (each fit iteration), time-stamped, on stderr")
    p.add_argument("--log-file", metavar="FILE", default=d("log_file"),
                   help="also write everything the command prints, and every progress line, to FILE")
    p.add_argument("--executor", choices=("serial", "process", "dask"), default=d("executor"),
                   help="where independent work runs (a fit's Jacobian columns ...): process pool (default), this "
                        "process, or a dask.distributed cluster; the results are the same bits on each")
    p.add_argument("--workers", type=int, metavar="N", default=d("workers"),
                   help="worker processes (process pool, local dask cluster); default: one per core")
    p.add_argument("--scheduler", metavar="ADDRESS", default=d("scheduler"),
                   help="dask scheduler address (tcp://host:8786) for --executor dask; default: a local cluster")


def _verdict_options(p, what: str) -> None:
    p.add_argument("--json", help=f"also write {what} as JSON to this file")
    p.add_argument("--exit-zero", action="store_true",
                   help=f"exit 0 when targets are missed (default: exit {EXIT_TARGETS_MISSED})")


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="jsbsim-calib", description="Build and calibrate general-aviation JSBSim aircraft.",
                                epilog="Global options go before or after the command. Exit codes: 0 done; 1 regress: "
                                       "something moved; 2 error; 3 calibrate/part60: a target missed (--exit-zero: 0).")
    p.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    _global_options(p, suppress=False)
    sub = p.add_subparsers(dest="command", required=True)

    g = sub.add_parser("generate", help="regenerate an aircraft's JSBSim files from aircraft/NAME/geometry.toml")
    g.add_argument("aircraft", help="aircraft name: folder aircraft/AIRCRAFT under --root")
    g.add_argument("--baseline", action="store_true", help="write neutral factors (ignore calibration.json)")
    g.add_argument("--force", action="store_true",
                   help="overwrite an aircraft file edited by hand (the lines dropped are listed; a backup is kept)")
    g.set_defaults(func=cmd_generate)

    c = sub.add_parser("calibrate", help="run a calibration stage and write the calibrated aircraft")
    c.add_argument("aircraft", help="aircraft name: folder aircraft/AIRCRAFT under --root")
    c.add_argument("--stage", default="all", choices=("steady", "trims", "dynamic", "all"),
                   help="steady: POH climb/cruise (stage 1, resets later stages); trims: flight-test trims "
                        "(stage 2a); dynamic: damping and pitch axis on the dynamic tests (stage 2b); all (default, "
                        "the main job): the three in order, those the aircraft's data allow")
    c.add_argument("--start", choices=("neutral", "current"), default="neutral",
                   help="where the first stage starts (printed): neutral (default, reproducible: its own and later "
                        "stages' factors neutral, earlier stages' as they recorded them in calibration.json, so the "
                        "same command gives the same product) or the current calibration")
    c.add_argument("--skip", action="append", metavar="STEP",
                   help="trims stage: leave out a step (pitch, control, pfactor, flaps); repeatable")
    c.add_argument("--no-write", action="store_true", help="do not write the aircraft files")
    c.add_argument("--report-dir", default="reports", help="where reports go (default reports/)")
    _verdict_options(c, "the verdicts of the targets")
    c.set_defaults(func=cmd_calibrate)

    _analysis_parsers(sub)

    k = sub.add_parser("check", help="plausibility: lift slope, stall speed, stability and damping derivatives")
    k.add_argument("aircraft", help=ANY_AIRCRAFT)
    k.add_argument("--baseline", action="store_true", help="check the uncalibrated model (all factors neutral)")
    k.add_argument("--json", help="also write the full report as JSON to this file")
    _foreign_options(k)
    k.set_defaults(func=cmd_check)

    f = sub.add_parser("airfoil", help="recompute a stored airfoil polar with NeuralFoil")
    f.add_argument("name", help="stored polar name, e.g. naca2412-tr05 (airfoils/NAME.csv)")
    f.add_argument("--out", default="airfoils", help="folder to write the polar to (default airfoils/)")
    f.set_defaults(func=cmd_airfoil)

    q = sub.add_parser("part60", help="FAA Part 60 Level 5 objective tests against flight-test summaries and/or "
                                      "time histories: report (Markdown + self-contained HTML) and verdicts")
    q.add_argument("aircraft", help="aircraft name: folder aircraft/AIRCRAFT under --root")
    q.add_argument("--flight-test", required=True, nargs="+", metavar="DIR_OR_FILE",
                   help="flight-test files or folders: results + snapshots (+ control travel) CSV files and/or "
                        "time histories (CSV + JSON sidecar)")
    q.add_argument("--report-dir", default="reports", help="where the report goes (REPORT_DIR/AIRCRAFT/part60/)")
    _verdict_options(q, "every test's verdict and its cases' metrics")
    q.set_defaults(func=cmd_part60)
    _plan_parser(sub)
    _export_regress_parsers(sub)
    for command in sub.choices.values():
        _global_options(command, suppress=True)
    return p


def _show_warning(message, category, filename, lineno, file=None, line=None):
    print(f"warning: {message}", file=sys.stderr)


# --------------------------------------------------------------------------- paths given on the command line
def _output_file(option: str, value) -> list[Problem]:
    """A file to write: not a folder, in a folder that exists."""
    p = Path(value)
    if p.is_dir():
        return [Problem(option, f"{value}: is a folder; give a file name")]
    if not p.parent.is_dir():
        return [Problem(option, f"{value}: the folder {p.parent} does not exist")]
    return []


def _input_file(option: str, value) -> list[Problem]:
    """A file to read: exists and is not a folder."""
    p = Path(value)
    if p.is_dir():
        return [Problem(option, f"{value}: is a folder; give a file")]
    if not p.exists():
        return [Problem(option, f"{value}: no such file")]
    return []


def _output_folder(option: str, value) -> list[Problem]:
    p = Path(value)
    return [Problem(option, f"{value}: is a file; give a folder")] if p.exists() and not p.is_dir() else []


def path_problems(a) -> list[Problem]:
    """Every path argument that cannot work, before anything runs (a calibration must not fail
    after minutes on a JSON file it cannot write)."""
    out = [] if Path(a.root).is_dir() else [Problem("--root", f"{a.root}: not a folder")]
    if getattr(a, "json", None):
        out += _output_file("--json", a.json)
    if getattr(a, "report_dir", None):
        out += _output_folder("--report-dir", a.report_dir)
    if a.command == "evaluate" and Path(a.data).is_dir():          # a folder of G1000 logs: the fleet
        out += [] if log_files(Path(a.data)) else [Problem("--data", f"{a.data}: is a folder without G1000 logs; give "
                                                           "a data file, or a folder of G1000 logs (a fleet)")]
    elif a.command == "evaluate" or (a.command == "close-loop" and a.data):
        out += _input_file("--data", a.data)
    if a.command == "synth":
        out += _output_folder("--out", a.out) if a.plan else _output_file("--out", a.out)
        if truth_folder(a) is None:
            out.append(Problem("--truth", f"{a.truth}: neither an aircraft of --root ({Path(a.root) / 'aircraft'}) "
                                          "nor an aircraft folder"))
    if a.command == "plan":
        out += _output_folder("--out", a.out) if a.out else []
        out += [] if a.count is None or 1 <= a.count <= 20 else [Problem("--count", f"{a.count}: give 1 to 20")]
    if a.command in ("close-loop", "part60", "plan"):
        out += [Problem("--flight-test", f"{f}: no such file or folder") for f in (a.flight_test or ())
                if not Path(f).exists()]
    if a.command == "regress":
        out += _input_file("--baseline", a.baseline) if a.baseline else []
        out += _output_file("--write-baseline", a.write_baseline) if a.write_baseline else []
        out += [q for f in (a.data or ()) for q in _input_file("--data", f)]
    if a.command == "export":
        out += _output_folder("--out", a.out)
    return out


def _run(args) -> int:
    if args.workers is not None and args.workers < 1:
        raise InputError("command line", Problem("--workers", f"{args.workers}: give at least 1"))
    problems = path_problems(args) + command_problems(args, [st.name for st in TRIM_STEPS])
    if problems:
        raise InputError("command line", problems)
    finished = False
    try:
        with command_guard(args, AircraftPaths, recover_product), \
                make_executor(args.executor, args.workers, args.scheduler) as args.pool:
            code = args.func(args)
        finished = True
        return code
    finally:
        for display in reversed(getattr(args, "displays", ())):      # each restores the streams it held
            display.close(finished)


def _terminate(signum, frame):
    raise SystemExit(128 + signum)         # exit handlers run: sandboxes removed, nothing half written


def main(argv=None) -> int:
    code = _main_logged(argv)
    if ENTRY and threading.current_thread() is threading.main_thread():
        # the command is over (written, or nothing written): a Ctrl-C while the interpreter shuts
        # down would only turn its exit code into a death by signal, or print a traceback
        signal.signal(signal.SIGINT, signal.SIG_IGN)
    return code


def _main_logged(argv) -> int:
    warnings.showwarning = _show_warning
    args = build_parser().parse_args(argv)
    args.console = sys.stderr            # the progress display's stream (not the --log-file copy)
    if not args.log_file:
        return _main(args)
    problems = _output_file("--log-file", args.log_file)
    if problems:
        print(f"error: {InputError('command line', problems)}", file=sys.stderr)
        return 2
    with open(args.log_file, "w") as log:
        args.log = log
        with contextlib.redirect_stdout(Tee(sys.stdout, log)), contextlib.redirect_stderr(Tee(sys.stderr, log)):
            return _main(args)


def _main(args) -> int:
    previous = None
    if threading.current_thread() is threading.main_thread():
        if signal.getsignal(signal.SIGINT) is _interrupted_loading:
            signal.signal(signal.SIGINT, signal.default_int_handler)
        previous = signal.signal(signal.SIGTERM, _terminate)
    try:
        return _run(args)
    except CalibError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(interrupted_message(args, AircraftPaths, recover_product), file=sys.stderr)
        return 130
    except OSError as exc:
        if exc.filename is None:           # not a file the user named or the workbench writes: a bug
            raise
        print(f"error: {exc.filename}: {exc.strerror or exc}", file=sys.stderr)
        return 2
    finally:
        if previous is not None:
            signal.signal(signal.SIGTERM, previous)


if __name__ == "__main__":
    sys.exit(main())
