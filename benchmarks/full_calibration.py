"""Benchmark of the calibration chain, the executors, the time-domain runner and a log fleet.

    python benchmarks/full_calibration.py [--quick]

Prints, on this machine:
* the three C172 stages in a row from neutral factors (as the main job, nothing written), on
  one process and on a process pool of 2 workers (the same factors, checked), with the
  speed-up, against the targets (<= 120 s) and the thesis (stage 1 10.5 min on 20 cores; its
  two stages about 77 min);
* the SR20's stage 1 (thesis: 20 min);
* trims per second, the runner's speed (x real time at 60 and 120 Hz), and G1000 logs per
  minute over a synthetic fleet of 100 logs, on 1 and 2 workers.
``--quick`` skips the 2-worker chain.
"""
from __future__ import annotations

import resource
import sys
import tempfile
import time
from pathlib import Path

from jsbsim_calib.calibration.steady import steady_factors
from jsbsim_calib.calibration.workflow import run_dynamic, run_steady, run_trims
from jsbsim_calib.core.executor import SERIAL, ProcessExecutor
from jsbsim_calib.evaluation.fleet import evaluate_fleet
from jsbsim_calib.flight.condition import Condition
from jsbsim_calib.jsbsim.script import SETTLE_S
from jsbsim_calib.jsbsim.simulator import Simulator
from jsbsim_calib.jsbsim.trajectory import Input, Maneuver, fly
from jsbsim_calib.synthetic.truth import synthetic_fleet

ROOT = Path(__file__).resolve().parents[1]
THESIS_MIN = {"c172 steady": 10.5, "sr20 steady": 20.0, "c172 two stages": 77.0}


def chain(executor) -> tuple[dict[str, float], dict, int]:
    t0 = time.perf_counter()
    steady = run_steady(ROOT, "c172", executor=executor)
    t1 = time.perf_counter()
    trims = run_trims(ROOT, "c172", start=steady_factors(steady.factors), executor=executor)
    t2 = time.perf_counter()
    dyn = run_dynamic(ROOT, "c172", start=trims.factors, executor=executor)
    t3 = time.perf_counter()
    times = {"stage 1": t1 - t0, "stage 2a": t2 - t1, "stage 2b": t3 - t2, "all": t3 - t0}
    return times, dyn.factors.as_dict(), steady.trims + trims.trims + dyn.trims


def report_chain(label: str, times: dict[str, float], trims: int) -> None:
    print(f"C172 stages 1 + 2a + 2b, {label}:")
    for k in ("stage 1", "stage 2a", "stage 2b"):
        print(f"  {k:<10} {times[k]:7.1f} s")
    print(f"  all        {times['all']:7.1f} s   (target <= 120 s; thesis {THESIS_MIN['c172 two stages']:g} min for "
          f"two stages: {THESIS_MIN['c172 two stages'] * 60 / times['all']:.0f}x faster; stage 1 vs the thesis's "
          f"{THESIS_MIN['c172 steady']:g} min: {THESIS_MIN['c172 steady'] * 60 / times['stage 1']:.0f}x)")
    print(f"  trims      {trims}   ({trims / times['all']:.0f} trims/s)")


def time_domain() -> None:
    cond = Condition(pressure_alt_ft=5500, weight_lb=2400, ktas=110, cg_in=42.0)
    m = Maneuver("bench", cond, 120.0, (Input("elevator_deg", (0, 1, 1.1, 3, 3.1), (0, 0, -2, -2, 0)),))
    with Simulator(ROOT, "c172") as sim:
        for rate in (60.0, 120.0):
            fly(sim, m, rate_hz=rate)
            t0 = time.perf_counter()
            tr = fly(sim, m, rate_hz=rate)
            wall = time.perf_counter() - t0
            frames = len(tr.time_s) + int(SETTLE_S * rate)
            print(f"time domain at {rate:5.0f} Hz    {m.duration_s / wall:7.0f} x real time (a 120 s maneuver, trim, "
                  f"load and {SETTLE_S:g} s settling included; {frames / wall:.0f} frames/s; target >= 1,000x at 60 Hz)")


def fleet(n: int = 100) -> None:
    with tempfile.TemporaryDirectory() as d:
        synthetic_fleet(ROOT / "data/g1000/log_110812_095915_KCKN.csv", Path(d), n)
        with Simulator(ROOT, "c172") as sim:
            for label, ex in (("1 worker", SERIAL), ("2 workers", None)):
                pool = ProcessExecutor(2) if ex is None else ex
                try:
                    t0 = time.perf_counter()
                    res = evaluate_fleet(sim, Path(d), executor=pool)
                    wall = time.perf_counter() - t0
                finally:
                    pool.close()
                print(f"G1000 fleet, {label:<9}   {60 * n / wall:7.0f} logs/min ({n} synthetic logs, "
                      f"{len(res.failed)} without a steady segment)")


def main(argv: list[str]) -> None:
    quick = "--quick" in argv
    times, factors, trims = chain(SERIAL)
    report_chain("one process", times, trims)
    if not quick:
        with ProcessExecutor(2) as pool:
            t2, f2, n2 = chain(pool)
        report_chain("process pool of 2 workers", t2, n2)
        print(f"  speed-up with 2 workers: {times['all'] / t2['all']:.2f}x; factors "
              f"{'identical' if f2 == factors else 'DIFFERENT'} to the one-process run")
    t0 = time.perf_counter()
    sr = run_steady(ROOT, "sr20")
    wall = time.perf_counter() - t0
    print(f"SR20 stage 1               {wall:7.1f} s   (thesis {THESIS_MIN['sr20 steady']:g} min: "
          f"{THESIS_MIN['sr20 steady'] * 60 / wall:.0f}x faster; {sr.trims / wall:.0f} trims/s)")
    time_domain()
    fleet()
    print(f"peak memory (RSS)          {resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0:.0f} MB")


if __name__ == "__main__":
    main(sys.argv[1:])
