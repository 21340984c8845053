"""Benchmark of stage 2a and of closing the loop on the real C172 trims.

    python benchmarks/trims_and_loop.py

Prints the wall time, trims and trims per second of stage 2a (from the committed stage-1
factors, nothing written; the thesis: about 9 minutes for its pitch, control and flap
steps), of the close-loop on the flight-test snapshots with stage 2a rerun without its
P-factor step, and of a G1000 log evaluation, with peak memory.
"""
import resource
import time
import warnings
from pathlib import Path

from jsbsim_calib.calibration.workflow import load_data_for, run_close_loop, run_trims
from jsbsim_calib.evaluation.evaluate import evaluate_dataset
from jsbsim_calib.jsbsim.simulator import Simulator


def main() -> None:
    root = Path(__file__).resolve().parents[1]
    warnings.simplefilter("ignore")
    t0 = time.perf_counter()
    res = run_trims(root, "c172")
    print(f"stage 2a wall time          {res.wall_time_s:.1f} s, {res.trims} trims "
          f"({res.trims / res.wall_time_s:.0f} trims/s), {len(res.steps)} steps")
    for r in res.steps:
        print(f"  {r.stage:<14} {r.wall_time_s:5.1f} s  {r.nfev:3d} evaluations  {r.trims:6d} trims")
    t1 = time.perf_counter()
    loop = run_close_loop(root, "c172", root / "data" / "c172_flight_test_snapshots.csv", skip_steps=("pfactor",))
    print(f"close-loop (with stage 2a)  {time.perf_counter() - t1:.1f} s, loop alone {loop.wall_time_s:.1f} s, "
          f"{len(loop.candidates)} candidate fits, added {loop.added}")
    with Simulator(root, "c172") as sim:
        t2 = time.perf_counter()
        ev = evaluate_dataset(sim, load_data_for(sim, root / "data" / "g1000" / "log_110812_095915_KCKN.csv"))
        print(f"G1000 log read + evaluate   {time.perf_counter() - t2:.2f} s, {len(ev.points)} segments")
    print(f"total                       {time.perf_counter() - t0:.1f} s")
    print(f"peak memory (RSS)           {resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0:.0f} MB")


if __name__ == "__main__":
    main()
