"""Do the 95 % prediction bands cover the truth? Issue 28 asks for 90-98 % over 50 campaigns.

The truth is the committed C172 with the elevator gearing and offset moved (K_de_slope 1.25,
K_de_offset -1.0; the product has 1.07 and -0.45); each campaign is a synthetic snapshot
campaign of it, refitted by the committed C172 and its bands drawn
(:mod:`jsbsim_calib.synthetic.coverage`). Prints, per campaign, the share of rows whose truth
lies within the band and whether each factor's interval holds its true value; then the totals,
and per block of the campaigns the truth's own error against its noisy data (a block whose mean
is not zero would be a bias no band accounts for).

    python benchmarks/band_coverage.py [--campaigns 50] [--points 16] [--prior 0.1] [--bootstrap 40]

About 1.5 s a campaign on one core. ``--bootstrap N`` then checks the linearization on the
first campaign: N refits to its fitted values plus its residuals drawn with replacement; the
spread of their estimates against the fit's standard errors (issue 28's check of the bands).
"""
from __future__ import annotations

import argparse
import collections
import math
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np

from jsbsim_calib.calibration.trims import STEP_PRIOR
from jsbsim_calib.jsbsim.simulator import Simulator
from jsbsim_calib.synthetic.coverage import bootstrap, campaigns

ROOT = Path(__file__).resolve().parents[1]
TRUTH = {"K_de_slope": 1.25, "K_de_offset": -1.0}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--campaigns", type=int, default=50)
    ap.add_argument("--points", type=int, default=16)
    ap.add_argument("--prior", type=float, default=STEP_PRIOR)
    ap.add_argument("--bootstrap", type=int, default=0, help="resamples of the residual bootstrap (0: none)")
    a = ap.parse_args()
    warnings.simplefilter("ignore")
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        runs = campaigns(ROOT, "c172", TRUTH, range(a.campaigns), Path(tmp), points=a.points, prior=a.prior)
    blocks = collections.defaultdict(list)
    for seed, c in enumerate(runs):
        for b, e in c.truth_errors:
            blocks[b].append(e)
        print(f"campaign {seed:2d}: rows covered {c.covered.mean():5.0%}, "
              + ", ".join(f"{n} {'in' if ok else 'OUT'}" for n, ok in c.inside.items()))
    every = np.concatenate([c.covered for c in runs])
    print(f"\n{len(runs)} campaigns, {every.size} rows, {time.perf_counter() - t0:.0f} s")
    print(f"rows covered: {every.mean():.1%}; campaigns with every row covered: "
          f"{sum(bool(c.covered.all()) for c in runs)} of {len(runs)}")
    for n in TRUTH:
        print(f"{n}: its 95 % interval holds the truth in {sum(c.inside[n] for c in runs)} of {len(runs)}")
    print("\nthe truth's own error against its noisy data, per block (deg):")
    for b, e in sorted(blocks.items()):
        e = np.array([x for x in e if math.isfinite(x)])
        print(f"  {b:<28} n {e.size:4d}  mean {e.mean():+.3f}  sd {e.std():.3f}  "
              f"mean/SE {e.mean() / (e.std() / math.sqrt(e.size)):+.1f}")
    if a.bootstrap:
        t1 = time.perf_counter()
        with tempfile.TemporaryDirectory() as tmp, Simulator(ROOT, "c172") as model, Simulator(ROOT, "c172") as truth:
            start = model.factors
            truth.set_factors(start.with_vector(list(TRUTH), list(TRUTH.values()), normalized=False))
            se, spread = bootstrap(model, truth, start, TRUTH, 0, Path(tmp), resamples=a.bootstrap, points=a.points,
                                   prior=a.prior)
        print(f"\nresidual bootstrap of campaign 0, {a.bootstrap} refits ({time.perf_counter() - t1:.0f} s):")
        for n in TRUTH:
            print(f"  {n}: linearized standard error {se[n]:.4g}, bootstrap {spread[n]:.4g} "
                  f"(ratio {spread[n] / se[n]:.2f})")


if __name__ == "__main__":
    main()
