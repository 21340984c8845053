"""Does ``jsbsim-calib plan`` pay? Its proposal against the same number of Level 5 maneuvers
drawn at random, on a truth aircraft with known factors.

The truth is the committed C172 with two damping factors moved inside their bounds (K_Cmq 2,
K_Cnr 0.02; the product has K_Cmq on its bound and K_Cnr unfitted). The data in hand are the
C172's flight-test results table (10 dynamic tests, 23 trims): their information about the
stage-2b factors at the model (:func:`jsbsim_calib.synthetic.design.results_information`),
and an estimate drawn about the truth with the covariance they leave (per seed). Each arm
flies its maneuvers on the truth (pilot scatter and sensor noise of the Level 5 plan, per
seed), refits the six stage-2b factors to the records
(:func:`~jsbsim_calib.synthetic.design.refit`, from the in-hand estimate) and combines the
refit's covariance with the data in hand
(:func:`~jsbsim_calib.synthetic.design.combined_errors`).

The issue's bar: the standard error of the two loosest factors falls at least 3x more with the
plan than with random maneuvers, i.e. ``(SE in hand / SE plan) >= 3 (SE in hand / SE random)``,
which is ``SE random / SE plan >= 3``.

    python benchmarks/plan_design.py [--seeds 3] [--draws 3] [--count 4] [--jobs 2]

Prints a row per refit and the table; about a minute per refit on one core.
"""
from __future__ import annotations

import argparse
import statistics
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

from jsbsim_calib.synthetic import design as D
from jsbsim_calib.synthetic.design import in_hand_information
from jsbsim_calib.jsbsim.simulator import Simulator
from jsbsim_calib.synthetic.maneuvers import load_plan

ROOT = Path(__file__).resolve().parents[1]
TRUTH = {"K_Cmq": 2.0, "K_Cnr": 0.02}


def truth_factors(model):
    return model.with_vector(list(TRUTH), [model.factor(n).to_unit(v) for n, v in TRUTH.items()])


def in_hand_estimate(truth, info, seed: int):
    """An estimate the data in hand could have given: the truth plus a draw of their covariance."""
    names = D.DESIGN_FACTORS
    cov = np.linalg.inv(info + np.eye(len(names)) / D.PRIOR_SD ** 2)
    x = truth.vector(names) + np.random.default_rng([seed, 9]).multivariate_normal(np.zeros(len(names)), cov)
    return truth.with_vector(names, np.clip(x, -1.0, 1.0))


def arm(task):
    """One refit: (label, seed, specs) -> (label, seed, ids, standard errors, estimates, wall)."""
    label, seed, specs, info = task
    t0 = time.perf_counter()
    base = load_plan("level5")
    with Simulator(ROOT, "c172") as model, Simulator(ROOT, "c172") as truth_sim:
        truth = truth_factors(model.factors)
        truth_sim.set_factors(truth)
        records = D.synthetic_records(truth_sim, specs, base, seed)
        center = in_hand_estimate(truth, info, seed)
        fit = D.refit(model, records, center)
        se = D.combined_errors(info, fit, center)
    return label, seed, [s.id for s in specs], se, {n: fit.final[n] for n in TRUTH}, time.perf_counter() - t0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--draws", type=int, default=3, help="random draws of maneuvers per seed")
    ap.add_argument("--count", type=int, default=D.COUNT)
    ap.add_argument("--jobs", type=int, default=2)
    a = ap.parse_args()
    t0 = time.perf_counter()
    base = load_plan("level5")
    with Simulator(ROOT, "c172") as sim:
        info, words = in_hand_information(sim, ROOT, "c172")
        proposal = D.design(sim, base, info, words, count=a.count)
    print(f"design: {time.perf_counter() - t0:.1f} s; targets {', '.join(proposal.targets)}; "
          f"picks {', '.join(p.scored.candidate.spec.id for p in proposal.picks)}")
    for p in proposal.picks:
        print(f"  {p.scored.candidate.spec.id}: {p.scored.candidate.spec.title}  predicted "
              + ", ".join(f"{n} {p.se_after[n]:.3g}" for n in proposal.targets))
    plan_specs = [p.scored.candidate.spec for p in proposal.picks]
    tasks = []
    for seed in range(1, a.seeds + 1):
        tasks.append(("plan", seed, plan_specs, info))
        for d in range(a.draws):
            idx = sorted(np.random.default_rng([seed, 7, d]).choice(len(base.maneuvers), a.count, replace=False))
            tasks.append((f"random {d}", seed, [base.maneuvers[i] for i in idx], info))
    rows = []
    with ProcessPoolExecutor(a.jobs) as pool:
        for label, seed, ids, se, est, wall in pool.map(arm, tasks):
            rows.append((label, se))
            print(f"seed {seed} {label:<9} {' '.join(ids):<24} "
                  + "  ".join(f"{n} {est[n]:+.4g} +/- {se[n]:.3g}" for n in proposal.targets) + f"  ({wall:.0f} s)")
    print()
    print("| factor | truth | SE in hand | SE after the plan (median) | SE after random (median) | random / plan |")
    print("|---|---|---|---|---|---|")
    for n in proposal.targets:
        plan = statistics.median(se[n] for lab, se in rows if lab == "plan")
        rand = statistics.median(se[n] for lab, se in rows if lab != "plan")
        print(f"| {n} | {TRUTH.get(n, float('nan')):g} | {proposal.se_in_hand[n]:.3g} | {plan:.3g} | {rand:.3g} | "
              f"{rand / plan:.1f}x |")
    print(f"\n{len(rows)} refits, {a.jobs} jobs: {time.perf_counter() - t0:.0f} s")


if __name__ == "__main__":
    main()
