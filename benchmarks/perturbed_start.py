"""How far a round-off change of the start moves the C172's whole chain (stages 1, 2a, 2b).

    python benchmarks/perturbed_start.py

Starts stage 1 1e-8 (normalized) away from where the main job starts (neutral factors, the
model switches as the aircraft file sets them), runs stages 2a and 2b from
there (as the main job does, nothing written) and prints, against the committed product
(``aircraft/c172/calibration.json``): each fitted factor's move in standard errors of the fit
that set it last, and each POH and flight-test prediction's move as a share of its tolerance,
with the stated tolerances (docs/model.md, "Reproducible fits": 4 standard errors, 0.2 of a
tolerance). About 2-4 min on one core. The SR20's stage 1 is checked the same way, at one
standard error and a tenth of a tolerance, by ``tests/test_reproducible.py``.
"""
from __future__ import annotations

import json
import math
import time
import warnings
from pathlib import Path

import numpy as np

from jsbsim_calib.calibration.steady import STEADY_NAMES, steady_factors
from jsbsim_calib.calibration.workflow import aircraft_data, run_dynamic, run_steady, run_trims
from jsbsim_calib.data.flighttest import QuirkWarning
from jsbsim_calib.data.schemas import METRICS
from jsbsim_calib.evaluation.evaluate import evaluate_dataset
from jsbsim_calib.factors import FactorSet, switches
from jsbsim_calib.jsbsim.aircraft import read_factors
from jsbsim_calib.jsbsim.product import AircraftPaths
from jsbsim_calib.jsbsim.simulator import Simulator

ROOT = Path(__file__).resolve().parents[1]
PERTURBATION = 1e-8
FACTOR_TOL_SE, PREDICTION_TOL = 4.0, 0.2        # the stated tolerances of the chain
KINDS = ("poh_climb", "poh_cruise", "flight_test", "flap_climb")


def stderr_of_last_fit(record: dict) -> dict[str, float]:
    """Each factor's standard error from the fit that set it last (stages in order)."""
    out = {}
    for stage in ("steady", "trims", "dynamic"):
        st = record["stages"][stage]
        for fit in ([st["fit"], st["fuel_flow"]] if stage == "steady" else st["steps"]):
            out.update({n: d["stderr"] for n, d in fit["factors"].items() if d.get("stderr") is not None})
    return out


def prediction_moves(factors: FactorSet) -> list[tuple[float, str]]:
    """(share of the tolerance, where) for every prediction, committed product against ``factors``."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", QuirkWarning)
        data = aircraft_data(ROOT, "c172", KINDS)
    out = []
    with Simulator(ROOT, "c172") as committed, Simulator(ROOT, "c172", factors=factors) as fresh:
        for ds in data.values():
            for pa, pb in zip(evaluate_dataset(committed, ds).points, evaluate_dataset(fresh, ds).points):
                for m in (m for m in ds.metrics if m in pa.model):
                    share = abs(pa.model[m] - pb.model.get(m, math.nan)) / METRICS[m].tol_for(pa.inputs[m])
                    out.append((share if math.isfinite(share) else math.inf, f"{ds.path.name} row {pa.index} {m}"))
    return out


def main() -> None:
    fs = switches(read_factors(AircraftPaths(ROOT, "c172").aircraft_xml))   # where the main job starts
    x = fs.vector(STEADY_NAMES)
    start = fs.with_vector(STEADY_NAMES, x + PERTURBATION * np.where(np.arange(len(x)) % 2, -1.0, 1.0))
    t0 = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", QuirkWarning)
        steady = run_steady(ROOT, "c172", start=start, bands=False)
        trims = run_trims(ROOT, "c172", start=steady_factors(steady.factors), bands=False)
        final = run_dynamic(ROOT, "c172", start=trims.factors, bands=False).factors
    wall = time.perf_counter() - t0
    record = json.loads(AircraftPaths(ROOT, "c172").calibration.read_text())
    se = stderr_of_last_fit(record)
    moves = sorted(((abs(final[n] - record["factors"][n]) / se[n], n) for n in se), reverse=True)
    shares = sorted(prediction_moves(final), reverse=True)
    print(f"C172 chain from a start {PERTURBATION:g} away: {wall:.0f} s")
    print("largest factor moves (standard errors of the fit that set each last):")
    for k, n in moves[:5]:
        print(f"  {n:<18} {k:9.2e}")
    print("largest prediction moves (share of the tolerance):")
    for s, where in shares[:5]:
        print(f"  {where:<45} {s:9.2e}")
    ok = moves[0][0] <= FACTOR_TOL_SE and shares[0][0] <= PREDICTION_TOL
    print(f"stated: factors <= {FACTOR_TOL_SE:g} standard errors, predictions <= {PREDICTION_TOL:g} of a "
          f"tolerance: {'MET' if ok else 'NOT MET'}")


if __name__ == "__main__":
    main()
