"""Prediction bands: the factors' covariance from the fits, carried to every prediction.

Linearization: the sensitivities G of the model's predictions to the fitted factors
(normalized, forward differences from the calibrated point) and the covariance C of those
factors give each prediction the variance ``g C g^T``; the band is +/- ``Z95`` standard
deviations. The fits are taken as independent (their covariances form the blocks of C). A
metric's RMSE gets its band the same way, through its gradient ``sum_j e_j g_j / (n RMSE)``.
A verdict then carries its confidence: a met RMSE target whose band stays below the limit is
met *with the band inside*; one whose band crosses the limit is met *with the band across*.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable, Mapping, Sequence

import numpy as np

from ..core import numerics
from ..data.schemas import Dataset
from ..evaluation.evaluate import Evaluation, evaluate_dataset
from ..evaluation.evaluate_dynamic import TestResult, fly_test
from ..factors import FactorSet
from ..jsbsim.simulator import Simulator
from .fit import Z95, FitResult

STEP = 0.002          # forward-difference step in normalized factor units (the fits' polish step)


def holds(low: float, high: float, met_by: Callable[[float], bool]) -> str:
    """How a verdict stands over its band, from the statistic at the band's two ends: "band
    inside" (the same verdict at both), "band across" (not), or "no band" (an end is not a
    number: a NaN never reads as a confident verdict)."""
    if not (math.isfinite(low) and math.isfinite(high)):
        return "no band"
    return "band inside" if met_by(low) == met_by(high) else "band across"


@dataclass
class Bands:
    """95 % half-widths of the model's predictions (``rows[kind][metric]``, one per data row,
    NaN where the model did not trim) and of each metric's RMSE (``rmse[kind][metric]``)."""

    rows: dict[str, dict[str, np.ndarray]]
    rmse: dict[str, dict[str, float]]

    def confidence(self, kind: str, metric: str, rmse: float | None, limit: float) -> str:
        """How an RMSE verdict stands against its band: inside, across the limit, or unknown."""
        band = self.rmse.get(kind, {}).get(metric, math.nan)
        value = math.nan if rmse is None else rmse
        return holds(value - band, value + band, lambda v: v <= limit)

    def within_range(self, kind: str, metric: str, errors: np.ndarray, tolerances: np.ndarray) -> tuple[float, float]:
        """The share [%] of the rows within their tolerance at the two ends of the bands (each
        error moved by its band away from, then toward zero); a row with no error or no band
        counts as outside at both ends, as the verdicts count a point the model cannot trim."""
        band = self.rows.get(kind, {}).get(metric)
        if band is None or not len(errors):
            return math.nan, math.nan
        e, ok = np.abs(errors), np.isfinite(errors) & np.isfinite(band)
        low = np.sum(ok & (e + np.where(ok, band, 0.0) <= tolerances + 1e-9))
        high = np.sum(ok & (e - np.where(ok, band, 0.0) <= tolerances + 1e-9))
        return 100.0 * low / len(e), 100.0 * high / len(e)


def covariance(fits: Sequence[FitResult]) -> tuple[list[str], np.ndarray] | None:
    """The factors of the fits and their covariance (normalized units), each factor's from the
    last fit that set it (its block of that fit's covariance), the fits taken as independent;
    None when such a fit has no covariance (rank-deficient: no band can be drawn)."""
    names: list[str] = []
    blocks = []
    for f in reversed(fits):
        if f.njev == 0:                         # a step that fitted nothing sets nothing
            continue
        new = [i for i, n in enumerate(f.names) if n not in names]
        if not new:
            continue
        if f.covariance is None:
            return None
        names += [f.names[i] for i in new]
        blocks.append(f.covariance[np.ix_(new, new)])
    C = np.zeros((len(names), len(names)))
    at = 0
    for b in blocks:
        C[at:at + len(b), at:at + len(b)] = b
        at += len(b)
    return names, C


def _values(evaluations: Mapping[str, Evaluation]) -> dict[str, dict[str, np.ndarray]]:
    """The model's value at every row, per data kind and metric (NaN where it did not trim)."""
    return {kind: {m: np.array([p.model.get(m, np.nan) for p in ev.points]) for m in ev.metrics}
            for kind, ev in evaluations.items()}


def _predictions(sim: Simulator, factors: FactorSet, data: Mapping[str, Dataset]) -> dict[str, dict[str, np.ndarray]]:
    sim.set_factors(factors)
    return _values({kind: evaluate_dataset(sim, ds) for kind, ds in data.items()})


def _quadratic(g: np.ndarray, C: np.ndarray) -> float:
    return numerics.dot(g, numerics.matvec(C, g))


def prediction_bands(sim: Simulator, factors: FactorSet, fits: Sequence[FitResult],
                     evaluations: Mapping[str, Evaluation]) -> Bands | None:
    """The bands of the model at ``factors`` (``evaluations``: its evaluations there, by data
    kind) from the covariance of ``fits`` (None when a fit has no covariance). Costs one
    evaluation of the data per factor."""
    cov = covariance(fits)
    if cov is None:
        return None
    names, C = cov
    data = {kind: ev.dataset for kind, ev in evaluations.items()}
    base = _values(evaluations)
    x0 = factors.vector(names)
    sens = []                                   # per factor: predictions' change per unit step
    for i in range(len(names)):
        h = STEP if x0[i] + STEP <= 1.0 else -STEP
        x = np.array(x0, float)
        x[i] += h
        moved = _predictions(sim, factors.with_vector(names, x), data)
        sens.append({k: {m: (v - base[k][m]) / h for m, v in ms.items()} for k, ms in moved.items()})
    sim.set_factors(factors)
    rows: dict[str, dict[str, np.ndarray]] = {}
    rmse: dict[str, dict[str, float]] = {}
    for kind, ds in data.items():
        rows[kind], rmse[kind] = {}, {}
        for m in ds.metrics:
            G = np.column_stack([s[kind][m] for s in sens])            # rows x factors
            pred = base[kind][m]
            rows[kind][m] = np.array([Z95 * math.sqrt(max(_quadratic(g, C), 0.0)) if np.all(np.isfinite(g))
                                      else math.nan for g in G])
            err = pred - ds.frame[m].to_numpy(float)
            ok = np.isfinite(err) & np.all(np.isfinite(G), axis=1)
            r = math.sqrt(numerics.sum_sq(err[ok]) / ok.sum()) if ok.any() else math.nan
            if not (ok.any() and r > 0):
                rmse[kind][m] = math.nan
                continue
            grad = numerics.matvec(G[ok].T, err[ok]) / (ok.sum() * r)
            rmse[kind][m] = Z95 * math.sqrt(max(_quadratic(grad, C), 0.0))
    return Bands(rows, rmse)


def _channel(r: TestResult) -> np.ndarray | None:
    return None if r.trajectory is None else r.trajectory[r.test.channel]


def response_bands(sim: Simulator, factors: FactorSet, fits: Sequence[FitResult],
                   results: Sequence[TestResult]) -> dict[str, np.ndarray] | None:
    """The 95 % band of each dynamic test's plotted response (its metric's channel over
    maneuver time, ``results``: the model flown at ``factors``) from the covariance of ``fits``
    (None when a fit has no covariance). Costs one flight of every test per factor; a test
    the model could not fly, at its factors or moved, has a band of NaN."""
    cov = covariance(fits)
    if cov is None:
        return None
    names, C = cov
    x0 = factors.vector(names)
    moved = []                                  # per factor: (step, every test flown)
    for i in range(len(names)):
        h = STEP if x0[i] + STEP <= 1.0 else -STEP
        x = np.array(x0, float)
        x[i] += h
        sim.set_factors(factors.with_vector(names, x))
        moved.append((h, [fly_test(sim, r.test) for r in results]))
    sim.set_factors(factors)
    out = {}
    for k, r in enumerate(results):
        y0 = _channel(r)
        cols = [_channel(m[k]) for _, m in moved]
        if y0 is None or any(c is None or c.shape != y0.shape for c in cols):
            out[r.test.id] = np.full(0 if y0 is None else y0.shape, math.nan)
            continue
        G = np.column_stack([(c - y0) / h for c, (h, _) in zip(cols, moved)])      # samples x factors
        out[r.test.id] = np.array([Z95 * math.sqrt(max(_quadratic(g, C), 0.0)) for g in G])
    return out
