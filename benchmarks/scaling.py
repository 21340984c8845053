"""Scaling of the calibration with workers: the process pool and a Dask LocalCluster.

    python benchmarks/scaling.py [--workers 1,2,4] [--executors process,dask] [--chain [--no-steady]] [--profile]

For each executor and worker count it runs the C172 steady stage (stage 1 from neutral
factors, as the main job, nothing written) and, with ``--chain``, the chain of stages 1, 2a
and 2b. It prints:

* wall time, speed-up over one worker and parallel efficiency, and whether the factors are
  the serial run's bits (they must be: the executors and the batches change only where an
  evaluation runs, never what it computes);
* the serial fraction, measured two ways: from the one-worker run (the time outside batches
  of independent evaluations, over the wall time), and from each measured speed-up S on p
  workers (Karp-Flatt: e = (1/S - 1/p) / (1 - 1/p)); with Amdahl's law each predicts the
  speed-up at 16 and 64 workers (a fit of n factors has at most n independent Jacobian
  columns: more workers than that wait); under the table, the speed-up measured at 16 and 64
  workers, where the run has them, beside the ones predicted;
* where a run's time goes: in batches, split into the least the tasks' own times allow (each
  batch's slowest task, or its tasks' sum over the workers where longer) and the rest
  (sending, results, uneven shares), and outside batches; the tasks' count and mean own time
  (the same evaluations take longer where the workers share a machine's memory and clocks);
* with ``--profile``, where the one-worker steady stage (and, with ``--chain``, the chain)
  spends its time: JSBSim trims, loads, resets, sandbox files, pickling, flights (their script
  loads, frames and reads; their trims count as trims), the least-squares algebra, and the rest.

Compare figures only within one run on one machine. Issue 25's targets: the steady stage on 2
workers >= 1.8x faster than on 1; a serial fraction that predicts >= 8x at 16 workers; Dask
within 15 % of the pool at the same worker count.
"""
from __future__ import annotations

import argparse
import cProfile
import pstats
import time
from pathlib import Path

import numpy as np

from jsbsim_calib.calibration.steady import steady_factors, steady_stage
from jsbsim_calib.calibration.workflow import aircraft_data, run_dynamic, run_steady, run_trims
from jsbsim_calib.core.executor import make_executor
from jsbsim_calib.jsbsim.simulator import Simulator

ROOT = Path(__file__).resolve().parents[1]
PREDICT_AT = (16, 64)
READY_MODULES = ("jsbsim_calib.calibration.workflow",)     # what a stage's tasks import


class Clocked:
    """``fn`` with the seconds each call took where it ran (a worker: the task's own time)."""

    def __init__(self, fn):
        self.fn = fn

    def __call__(self, item):
        t0 = time.perf_counter()
        out = self.fn(item)
        return out, time.perf_counter() - t0


class Timed:
    """An executor that times its batches: the time spent in batches of more than one
    evaluation is the part more workers can share. Inside the batches it splits the wall time
    into what the tasks' own times allow at best (each batch's slowest task, or its tasks'
    sum over the workers where that is longer) and the rest (sending, results, tasks unevenly
    shared), and counts the tasks and their own time."""

    def __init__(self, executor):
        self.executor, self.parallel_s, self.batches = executor, 0.0, 0
        self.bound_s, self.task_s, self.tasks = 0.0, 0.0, 0

    def __getattr__(self, name):
        return getattr(self.executor, name)

    def map(self, fn, items, key=None):
        t0 = time.perf_counter()
        out = self.executor.map(Clocked(fn), items, key)
        if len(items) > 1:
            self.parallel_s += time.perf_counter() - t0
            self.batches += 1
            own = [s for _, s in out]
            self.bound_s += max(max(own), sum(own) / self.executor.workers)
            self.task_s += sum(own)
            self.tasks += len(out)
        return [r for r, _ in out]


def steady(executor) -> np.ndarray:
    """Stage 1 from neutral factors: the factors found and the costs, as one vector of bits."""
    data = aircraft_data(ROOT, "c172")
    with Simulator(ROOT, "c172", baseline=True) as sim:
        main, ff = steady_stage(sim, data["poh_climb"], data["poh_cruise"], executor=executor)
    return np.array(list(ff.final.vector(main.names + ff.names)) + [main.cost_final, ff.cost_final])


def chain(executor) -> np.ndarray:
    """Stages 1, 2a and 2b in a row (nothing written): the final factors as a vector."""
    s1 = run_steady(ROOT, "c172", executor=executor, bands=False)
    s2a = run_trims(ROOT, "c172", start=steady_factors(s1.factors), executor=executor, bands=False)
    s2b = run_dynamic(ROOT, "c172", start=s2a.factors, executor=executor, bands=False)
    return np.array(list(s2b.factors.as_dict().values()))


def run(job, kind: str, workers: int) -> tuple[float, Timed, np.ndarray]:
    """Wall time, the timed executor (time in batches, their count) and the result of ``job``
    on ``kind`` with ``workers`` (one worker: this process). The executor starts before the
    clock (a cluster's start-up is not the job's, nor a pool's: about 1 s on 2 cores, which the
    pool spends at its first batch unless :meth:`ready` starts it)."""
    with make_executor("serial" if workers == 1 else kind, workers) as ex:
        ex.ready(READY_MODULES)         # the workers started and the fits' modules imported there, on both
        timed = Timed(ex)
        t0 = time.perf_counter()
        out = job(timed)
        return time.perf_counter() - t0, timed, out


def amdahl(e: float, p: int) -> float:
    return 1.0 / (e + (1.0 - e) / p)


def karp_flatt(speedup: float, p: int) -> float:
    return (1.0 / speedup - 1.0 / p) / (1.0 - 1.0 / p)


def split(timed: Timed, wall: float) -> str:
    """Where a run's wall time went: in batches (how many) = the least their tasks allow + the
    rest, and outside batches; the tasks' count and mean own time."""
    rest = timed.parallel_s - timed.bound_s
    mean = 1e3 * timed.task_s / max(1, timed.tasks)
    return (f"{timed.parallel_s:.2f} ({timed.batches}) = {timed.bound_s:.2f} + {rest:.2f} / "
            f"{wall - timed.parallel_s:.2f}   {timed.tasks} tasks, {mean:.1f} ms")


def table(title: str, job, kinds: list[str], workers: list[int], serial: bool = True) -> None:
    """One row per executor and worker count; ``serial=False`` leaves out the one-worker run
    (no speed-ups: the bits are compared with the table's first run). Under the table, the
    speed-up measured at 16 and 64 workers (where run) beside the ones predicted."""
    print(f"\n{title}")
    wall1, ref, e1, measured = None, None, None, {}
    if serial:
        wall1, timed1, ref = run(job, "serial", 1)
        e1 = max(0.0, 1.0 - timed1.parallel_s / wall1)
        print(f"  1 worker (this process): {wall1:7.2f} s; serial fraction from this run {e1:.3f} (time outside "
              f"batches) -> predicts " + ", ".join(f"{amdahl(e1, p):.1f}x at {p}" for p in PREDICT_AT))
        print(f"  in batches (n) = the least their tasks allow + the rest / outside [s]: {split(timed1, wall1)}")
    print(f"  {'executor':<9}{'workers':>8}{'wall s':>9}{'speed-up':>10}{'efficiency':>11}{'Karp-Flatt e':>14}"
          f"{'predicts':>22}  same bits  in batches (n) = least + rest / outside [s]   tasks, mean own time")
    for kind in kinds:
        for p in [w for w in workers if w > 1]:
            wall, timed, out = run(job, kind, p)
            ref = out if ref is None else ref
            same = "yes" if out.shape == ref.shape and np.array_equal(out, ref) else "NO"
            if wall1 is None:
                print(f"  {kind:<9}{p:>8}{wall:>9.2f}{'':>10}{'':>11}{'':>14}{'':>22}  {same:<9}  {split(timed, wall)}")
                continue
            s, e = wall1 / wall, karp_flatt(wall1 / wall, p)
            measured[kind, p] = (s, e)
            pred = ", ".join(f"{amdahl(max(e, 1e-9), q):.1f}x@{q}" for q in PREDICT_AT)
            print(f"  {kind:<9}{p:>8}{wall:>9.2f}{s:>9.2f}x{s / p:>10.0%}{e:>14.3f}{pred:>22}  {same:<9}  "
                  f"{split(timed, wall)}")
    for kind in kinds:
        for q in PREDICT_AT:
            if (kind, q) in measured:
                print(f"  {kind} at {q} workers: measured {measured[kind, q][0]:.2f}x; predicted "
                      + "; ".join(predictions(e1, measured, kind, q)))


def predictions(e1: float | None, measured: dict, kind: str, q: int) -> list[str]:
    """The speed-ups at ``q`` workers that the table's other figures predict: from the
    one-worker run's serial fraction, and from Karp-Flatt at each smaller worker count."""
    out = [f"{amdahl(e1, q):.2f}x from the one-worker run's serial fraction"] if e1 is not None else []
    out += [f"{amdahl(max(e, 1e-9), q):.2f}x from Karp-Flatt at {p}" for (k, p), (_, e) in sorted(measured.items())
            if k == kind and p < q]
    return out


PROFILE_GROUPS = (   # (what, functions whose cumulative time it is), in the order printed
    ("JSBSim trims", ("_trim_once",)),
    ("JSBSim loads", ("_load",)),
    ("JSBSim resets", ("_reset",)),
    ("sandbox files", ("_write_sandbox",)),
    ("pickling", ("dumps", "loads")),
)
FLIGHTS = ("trajectory.py", "fly")   # its own time: a flight's script load, frames and reads (its trim: above)
FIT_CALLBACKS = ("fun", "jac", "trials", "on_trial", "callback")    # fit.py's functions the solver calls


def profile(job, what: str) -> None:
    """Where ``job`` spends its time on one worker (cProfile: its overhead included)."""
    pr = cProfile.Profile()
    t0 = time.perf_counter()
    pr.enable()
    job(make_executor("serial"))
    pr.disable()
    wall = time.perf_counter() - t0
    st = pstats.Stats(pr).stats
    total = max(v[3] for v in st.values())          # the outermost call's cumulative time
    cum: dict[str, float] = {}
    for (_, _, func), (_, _, _, ct, _) in st.items():
        cum[func] = cum.get(func, 0.0) + ct
    # the solver's own algebra: its time less that of its calls back into the fit
    inner = sum(ct for (file, _, func), v in st.items() if file.endswith("fit.py") and func in FIT_CALLBACKS
                for (_, _, caller), (_, _, _, ct) in v[4].items() if caller == "least_squares")
    lm = cum.get("least_squares", 0.0) - inner
    flights = sum(v[2] for (file, _, func), v in st.items() if file.endswith(FLIGHTS[0]) and func == FLIGHTS[1])
    print(f"\nprofile of the {what} on 1 worker ({wall:.1f} s under the profiler):")
    shown = 0.0
    for name, funcs in PROFILE_GROUPS + (("JSBSim flights (trims aside)", ()),):
        t = sum(cum.get(f, 0.0) for f in funcs) if funcs else flights
        shown += t
        print(f"  {name:<30}{t:7.2f} s  {t / total:5.1%}")
    rest = total - shown - lm
    print(f"  {'least-squares algebra':<30}{lm:7.2f} s  {lm / total:5.1%}")
    print(f"  {'the rest':<30}{rest:7.2f} s  {rest / total:5.1%}   (data, residuals, reports' evaluations, bookkeeping)")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--workers", default="1,2", help="worker counts, comma-separated (default 1,2)")
    ap.add_argument("--executors", default="process,dask", help="process and/or dask (default both)")
    ap.add_argument("--chain", action="store_true", help="also the chain of stages 1, 2a and 2b")
    ap.add_argument("--profile", action="store_true", help="a profile of the one-worker steady stage (and chain, "
                    "with --chain)")
    ap.add_argument("--no-serial", action="store_true", help="leave out the one-worker runs (no speed-ups)")
    ap.add_argument("--no-steady", action="store_true", help="leave out the steady stage's table (with --chain)")
    a = ap.parse_args()
    workers = sorted({int(w) for w in a.workers.split(",")})
    kinds = [k for k in a.executors.split(",") if k]
    if a.profile:
        profile(steady, "steady stage")
        if a.chain:
            profile(chain, "chain (stages 1, 2a, 2b)")
    if not a.no_steady:
        table("C172 steady stage (stage 1 from neutral factors)", steady, kinds, workers, not a.no_serial)
    if a.chain:
        table("C172 chain (stages 1, 2a, 2b)", chain, kinds, workers, not a.no_serial)


if __name__ == "__main__":
    main()
