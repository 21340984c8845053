"""Do the prediction bands cover the truth? Synthetic snapshot campaigns of a truth aircraft
whose factors are known, each refitted by the model, its bands drawn, the truth held against
them (``benchmarks/band_coverage.py``; issue 28 asks for 90-98 % over 50 campaigns).

A campaign (:func:`campaign`) is ``synth --points N`` of the truth at one seed, with the
package's measurement noise; the model refits ``names`` to one trim quantity of its rows from
``start`` (the prior of stage 2a's steps toward it) and draws its bands
(:func:`~jsbsim_calib.calibration.bands.prediction_bands`). A row is covered when the truth's own
value there lies within the band of the refitted model; a factor when its 95 % interval holds
the true value.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Mapping, Sequence

import numpy as np

from ..calibration.bands import prediction_bands
from ..calibration.fit import Z95, fit
from ..calibration.points import PointSet, point_residuals
from ..calibration.trims import STEP_PRIOR
from ..data.load import load_dataset
from ..data.schemas import Dataset
from ..evaluation.evaluate import evaluate_dataset
from ..factors import FactorSet
from ..jsbsim.simulator import Simulator
from .snapshots import synthesize, write_csv

LEGS = ((1.0, 0.02), (1.0, 0.002))        # a fit of a few well-identified factors: no path of priors


@dataclass
class Campaign:
    covered: np.ndarray                    # per row: the truth within the refitted model's band
    inside: dict[str, bool]                # per factor: its 95 % interval holds the truth
    truth_errors: list[tuple[str, float]]  # per row: (block, the truth's own value - its noisy datum)


def _values(evaluation, metric: str) -> np.ndarray:
    return np.array([p.model.get(metric, math.nan) for p in evaluation.points])


def _synthesized(truth: Simulator, seed: int, folder: Path, points: int):
    rows, _ = synthesize(truth, n=points, seed=seed, noise=1.0)
    path = Path(folder) / f"campaign_{seed}.csv"
    write_csv(rows, path)
    return rows, load_dataset(path)


def _refit(model: Simulator, ds: Dataset, start: FactorSet, names: Sequence[str], metric: str, prior: float):
    model.set_factors(start)
    ps = PointSet.from_dataset(ds, model, metrics=(metric,))

    def residuals(fs: FactorSet):
        model.set_factors(fs)
        r, lab, _ = point_residuals(model, ps, (metric,))
        return np.array(r), lab

    return fit("coverage", list(names), start, residuals, sim=model, prior=prior, legs=LEGS)


def campaign(model: Simulator, truth: Simulator, start: FactorSet, true: Mapping[str, float], seed: int,
             folder: Path, *, metric: str = "elevator_deg", points: int = 16, prior: float = STEP_PRIOR) -> Campaign:
    """One campaign: ``truth`` (flying the ``true`` factor values) synthesizes it, ``model``
    refits ``true``'s factors to ``metric`` from ``start`` and draws the bands."""
    rows, ds = _synthesized(truth, seed, folder, points)
    res = _refit(model, ds, start, list(true), metric, prior)
    model.set_factors(res.final)
    fitted = evaluate_dataset(model, ds)
    bands = prediction_bands(model, res.final, [res], {ds.kind: fitted})
    pred, truth_values = _values(fitted, metric), _values(evaluate_dataset(truth, ds), metric)
    band = bands.rows[ds.kind][metric] if bands is not None else np.full(len(pred), math.nan)
    covered = np.abs(pred - truth_values) <= band             # NaN: not covered
    se = {n: res.stderr.get(n) for n in true}
    inside = {n: se[n] is not None and abs(res.final[n] - v) <= Z95 * se[n] for n, v in true.items()}
    blocks = [r["title"].split(",")[0].split(" at ")[0] for r in rows]
    return Campaign(covered, inside, list(zip(blocks, (truth_values - ds.frame[metric].to_numpy(float)).tolist())))


def campaigns(root: Path, name: str, true: Mapping[str, float], seeds: Sequence[int], folder: Path,
              **kw) -> list[Campaign]:
    """:func:`campaign` at every seed, the truth the aircraft with ``true`` set, the model the
    aircraft as it stands."""
    with Simulator(root, name) as model, Simulator(root, name) as truth:
        start = model.factors
        truth.set_factors(start.with_vector(list(true), list(true.values()), normalized=False))
        return [campaign(model, truth, start, true, s, folder, **kw) for s in seeds]


def bootstrap(model: Simulator, truth: Simulator, start: FactorSet, true: Mapping[str, float], seed: int,
              folder: Path, *, resamples: int = 40, metric: str = "elevator_deg", points: int = 16,
              prior: float = STEP_PRIOR) -> tuple[dict[str, float], dict[str, float]]:
    """The check of the linearized standard errors by a bootstrap of the fit's residuals: one
    campaign refitted, then ``resamples`` times again on its fitted values plus its residuals
    drawn with replacement (centred, scaled by sqrt(n / (n - p))). Returns the fit's standard
    errors and the bootstrap's standard deviations of the estimates."""
    _, ds = _synthesized(truth, seed, folder, points)
    names = list(true)
    res = _refit(model, ds, start, names, metric, prior)
    model.set_factors(res.final)
    fitted = _values(evaluate_dataset(model, ds), metric)
    data = ds.frame[metric].to_numpy(float)
    ok = np.isfinite(fitted) & np.isfinite(data)
    e = (data - fitted)[ok]
    e = (e - e.mean()) * math.sqrt(e.size / max(1, e.size - len(names)))
    rng = np.random.default_rng([seed, 11])
    estimates = []
    for _ in range(resamples):
        frame = ds.frame.copy()
        values = np.array(fitted)
        values[ok] = fitted[ok] + rng.choice(e, e.size, replace=True)
        frame.loc[ok, metric] = values[ok]
        estimates.append(_refit(model, replace(ds, frame=frame), res.final, names, metric, prior).final.vector(names, normalized=False))
    spread = np.std(np.array(estimates), axis=0, ddof=1)
    return {n: res.stderr.get(n) for n in names}, dict(zip(names, spread.tolist()))
