"""Benchmark of the held-out validation (`jsbsim-calib validate`) and the physics checks.

    python benchmarks/validation.py [AIRCRAFT ...]      (default: c172 sr20)

Prints per aircraft and stage the wall time, refits, trims and trims per second of the fold
refits (nothing written), and the wall time of the physics checks. Not part of the main job
(its time budget): the validation is its own command.
"""
import resource
import sys
import time
import warnings
from pathlib import Path

from jsbsim_calib.calibration.validation import STAGE_DATA_KEYS, stage_data, validate_steady, validate_trims
from jsbsim_calib.calibration.validation_dynamic import validate_dynamic
from jsbsim_calib.evaluation.physics_checks import run_physics_checks
from jsbsim_calib.jsbsim.product import load_aircraft_geometry


def main(names: list[str]) -> None:
    root = Path(__file__).resolve().parents[1]
    warnings.simplefilter("ignore")
    t0 = time.perf_counter()
    for name in names:
        geom = load_aircraft_geometry(root, name)
        runs = [validate_steady]
        if all(k in geom.data_files for k in STAGE_DATA_KEYS["trims"]):
            runs.append(validate_trims)
        if all(k in geom.data_files for k in STAGE_DATA_KEYS["dynamic"]):
            runs.append(validate_dynamic)
        for run in runs:
            v = run(root, name)
            refits = len(v.folds) + (v.control is not None)
            print(f"{name:<5} {v.stage:<7} {v.wall_time_s:6.1f} s  {refits:2d} refits  {v.trims:7d} trims "
                  f"({v.trims / v.wall_time_s:5.0f} trims/s)  {len(v.flagged())}/{len(v.rows())} fold-metrics flagged")
        t1 = time.perf_counter()
        pc = run_physics_checks(root, name, stage_data(root, name, ("poh_climb", "poh_cruise")))
        print(f"{name:<5} physics {time.perf_counter() - t1:6.1f} s  ({sum(c.ok for c in pc.checks())}/"
              f"{len(pc.checks())} checks hold)")
    print(f"total {time.perf_counter() - t0:.1f} s; peak memory (RSS) "
          f"{resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0:.0f} MB")


if __name__ == "__main__":
    main(sys.argv[1:] or ["c172", "sr20"])
