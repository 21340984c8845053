"""Residual diagnosis: is what is left after a fit structure or noise, and what does it follow?

For each metric of an evaluation, the residuals (model - data) of the trimmed points are
compared with

* the tolerance of the metric (a structure smaller than :data:`MATERIAL` of a tolerance is
  not worth a model change), and
* an estimate of the data noise: half the mean squared difference between each point's
  residual and that of its nearest neighbour in the space of the flight condition (a
  smooth structure cancels in the difference, noise does not), floored at the resolution
  of the data.

Residuals are *structured* when their part beyond the noise is material and either their
mean differs from zero (t-test) or one candidate regressor explains them (F-test of
``r = a + b x`` against ``r = a``), at significance :data:`ALPHA`.

The regressors are states of the model's own trims (:data:`REGRESSORS`): thrust, torque,
angle of attack, flaps, CG, weight, dynamic pressure and its inverse, thrust x sin(alpha),
thrust and torque over dynamic pressure, bank, sideslip, speed, lift coefficient, vertical
speed.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Callable

import numpy as np
from scipy import stats

from ..data.schemas import METRICS

ALPHA = 0.01            # significance of the tests
MATERIAL = 0.25         # share of the tolerance a structure must reach
RESOLUTION = {"pitch_deg": 0.05, "elevator_deg": 0.05, "aileron_deg": 0.05, "rudder_deg": 0.05, "roc_fpm": 5.0,
              "rpm": 5.0, "pct_power": 0.25, "gph": 0.05}


def _tr(attr: str) -> Callable:
    return lambda t: float(getattr(t, attr))


REGRESSORS: dict[str, tuple[str, Callable]] = {
    "thrust": ("lbf", _tr("thrust_lbf")),
    "torque": ("lbf ft", lambda t: abs(float(t.torque_lbft))),
    "alpha": ("deg", _tr("alpha_deg")),
    "flaps": ("deg", lambda t: float(t.condition.flaps_deg)),
    "cg": ("in", lambda t: float(t.condition.cg_in) if t.condition.cg_in is not None else math.nan),
    "weight": ("lb", lambda t: float(t.condition.weight_lb)),
    "qbar": ("psf", _tr("qbar_psf")),
    "1/qbar": ("1/psf", lambda t: 1.0 / max(float(t.qbar_psf), 1e-6)),
    "thrust x sin(alpha)": ("lbf", lambda t: float(t.thrust_lbf) * math.sin(math.radians(t.alpha_deg))),
    "thrust/qbar": ("ft2", lambda t: float(t.thrust_lbf) / max(float(t.qbar_psf), 1e-6)),
    "torque/qbar": ("ft3", lambda t: abs(float(t.torque_lbft)) / max(float(t.qbar_psf), 1e-6)),
    "bank": ("deg", _tr("phi_deg")),
    "sideslip": ("deg", _tr("beta_deg")),
    "ktas": ("kt", _tr("ktas")),
    "CL": ("-", lambda t: float(t.condition.weight_lb) / max(float(t.qbar_psf), 1e-6)),
    "vs": ("ft/min", _tr("roc_fpm")),
}
NEIGHBOUR_SPACE = ("alpha", "flaps", "thrust", "qbar", "bank", "weight", "cg")


@dataclass
class Correlate:
    regressor: str
    r: float               # correlation coefficient
    slope: float           # residual per unit regressor
    p: float               # F-test p-value

    def as_dict(self) -> dict:
        return {"regressor": self.regressor, "r": round(self.r, 3), "slope": self.slope, "p": self.p}


@dataclass
class MetricDiagnosis:
    metric: str
    n: int
    rms: float
    bias: float
    noise: float                       # estimated data noise (standard deviation)
    tolerance: float
    structured: bool
    reason: str
    correlates: list[Correlate] = field(default_factory=list)

    def as_dict(self) -> dict:
        return {"metric": self.metric, "n": self.n, "rms": self.rms, "bias": self.bias, "noise": self.noise,
                "tolerance": self.tolerance, "structured": self.structured, "reason": self.reason,
                "correlates_with": [c.as_dict() for c in self.correlates]}


def regressor_matrix(trims) -> tuple[list[str], np.ndarray]:
    """Regressor values of a list of trim results (rows) in :data:`REGRESSORS` order."""
    names = list(REGRESSORS)
    X = np.array([[REGRESSORS[k][1](t) for k in names] for t in trims], float).reshape(len(trims), len(names))
    return names, X


def noise_estimate(r: np.ndarray, X: np.ndarray, names: list[str], floor: float) -> float:
    """Estimate of the noise standard deviation: the smaller of the nearest-neighbour
    difference estimate and, with enough points (more than twice the regressors), the
    residual scatter of a regression on all regressors; never below ``floor``."""
    cols = [names.index(k) for k in NEIGHBOUR_SPACE if k in names]
    Z = X[:, cols]
    ok = np.all(np.isfinite(Z), axis=1)
    Z, rz = Z[ok], r[ok]
    if len(rz) < 4:
        return floor
    span = np.ptp(Z, axis=0)
    Z = (Z - Z.min(0)) / np.where(span > 0, span, 1.0)
    d = np.linalg.norm(Z[:, None, :] - Z[None, :, :], axis=2)
    np.fill_diagonal(d, np.inf)
    nn = np.argmin(d, axis=1)
    est = float(np.sqrt(0.5 * np.mean((rz - rz[nn]) ** 2)))
    good = np.all(np.isfinite(X), axis=0) & (np.ptp(np.where(np.isfinite(X), X, 0.0), axis=0) > 1e-12)
    A = np.column_stack([np.ones(len(r)), X[:, good]])
    if len(r) > 2 * A.shape[1]:
        coef, *_ = np.linalg.lstsq(A, r, rcond=None)
        est = min(est, float(np.sqrt(np.sum((r - A @ coef) ** 2) / (len(r) - A.shape[1]))))
    return max(floor, est)


def correlates(r: np.ndarray, X: np.ndarray, names: list[str]) -> list[Correlate]:
    """Single-regressor fits r = a + b x, most significant first (p < ALPHA only)."""
    out = []
    n = len(r)
    rss0 = float(np.sum((r - r.mean()) ** 2))
    for j, name in enumerate(names):
        x = X[:, j]
        if not np.all(np.isfinite(x)) or np.ptp(x) <= 1e-12 or n < 4 or rss0 <= 0:
            continue
        A = np.column_stack([np.ones(n), x])
        coef, *_ = np.linalg.lstsq(A, r, rcond=None)
        rss1 = float(np.sum((r - A @ coef) ** 2))
        F = (rss0 - rss1) / max(rss1 / (n - 2), 1e-300)
        p = float(stats.f.sf(F, 1, n - 2))
        if p < ALPHA:
            out.append(Correlate(name, float(np.corrcoef(x, r)[0, 1]), float(coef[1]), p))
    return sorted(out, key=lambda c: c.p)


def diagnose(evaluation) -> dict[str, MetricDiagnosis]:
    """Diagnosis of every metric of an :class:`~jsbsim_calib.evaluation.evaluate.Evaluation`."""
    out = {}
    for m in evaluation.metrics:
        pts = [p for p in evaluation.points if p.trimmed and p.trim is not None and np.isfinite(p.error.get(m, np.nan))]
        tol = METRICS[m].tol_for(1.0) if not METRICS[m].relative else METRICS[m].tolerance
        if len(pts) < 4:
            out[m] = MetricDiagnosis(m, len(pts), math.nan, math.nan, math.nan, tol, False, "too few points")
            continue
        r = np.array([p.error[m] for p in pts])
        if METRICS[m].relative:
            r = r / np.array([abs(p.inputs[m]) for p in pts])
        names, X = regressor_matrix([p.trim for p in pts])
        noise = noise_estimate(r, X, names, RESOLUTION.get(m, 0.0) / (1.0 if not METRICS[m].relative else 100.0))
        rms, bias = float(np.sqrt(np.mean(r**2))), float(np.mean(r))
        beyond = math.sqrt(max(0.0, rms**2 - noise**2))
        cors = correlates(r, X, names)
        n = len(r)
        t_p = float(stats.ttest_1samp(r, 0.0).pvalue) if np.std(r) > 0 else (0.0 if abs(bias) > 0 else 1.0)
        if beyond < MATERIAL * tol:
            structured, why = False, (f"residual beyond noise {beyond:.3g} is below {MATERIAL:g} of the tolerance "
                                      f"{tol:g}")
        elif t_p < ALPHA or cors:
            parts = []
            if t_p < ALPHA:
                parts.append(f"mean {bias:+.3g} (p = {t_p:.2g})")
            if cors:
                parts.append(f"follows {cors[0].regressor} (r = {cors[0].r:+.2f}, p = {cors[0].p:.2g})")
            structured, why = True, "; ".join(parts)
        else:
            structured, why = False, f"no significant mean or trend (noise {noise:.3g})"
        out[m] = MetricDiagnosis(m, n, rms, bias, noise, tol, structured, why, cors[:4])
    return out
