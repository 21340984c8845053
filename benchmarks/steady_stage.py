"""Benchmark of the steady-state stage: wall time, trims per second, evaluations, memory.

    python benchmarks/steady_stage.py [AIRCRAFT]

Runs stage 1 from neutral factors on the aircraft's POH data without writing anything.
Target (issue 3): <= 30 s on a 2-core machine (the thesis: 10.5 min on 20 cores).
"""
import resource
import sys
import time
from pathlib import Path

from jsbsim_calib.jsbsim.simulator import Simulator
from jsbsim_calib.calibration.steady import steady_stage
from jsbsim_calib.calibration.workflow import aircraft_data


def main(name: str = "c172") -> None:
    root = Path(__file__).resolve().parents[1]
    data = aircraft_data(root, name)
    climb, cruise = data["poh_climb"], data["poh_cruise"]
    t0 = time.perf_counter()
    sim = Simulator(root, name, baseline=True)
    t_load = time.perf_counter() - t0
    t1 = time.perf_counter()
    fit, ff = steady_stage(sim, climb, cruise)
    wall = time.perf_counter() - t1
    rss_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
    print(f"aircraft                 {name}")
    print(f"model load (sandbox)     {t_load * 1e3:.0f} ms")
    print(f"steady stage wall time   {wall:.2f} s   (target <= 30 s)")
    print(f"  main fit               {fit.wall_time_s:.2f} s, {fit.nfev} evaluations, {fit.njev} Jacobians")
    print(f"  fuel-flow fit          {ff.wall_time_s:.2f} s, {ff.nfev} evaluations")
    print(f"trims                    {sim.trims}   ({sim.trims / wall:.0f} trims/s)")
    print(f"JSBSim state evaluations {sim.evals}   ({sim.evals / wall:.0f} /s)")
    print(f"model reloads            {sim.loads}")
    print(f"final cost               {fit.cost_final:.4g} (from {fit.cost_initial:.4g})")
    print(f"peak memory (RSS)        {rss_mb:.0f} MB")


if __name__ == "__main__":
    main(*sys.argv[1:])
