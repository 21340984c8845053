"""Point sets and residuals of the fits: which trims a step uses, and how far each is from
its target, in tolerances.

A point set is a dataset's rows with their trim conditions and the metrics compared.
Residuals are (model - data) / tolerance, with a throttle penalty for a level point that needs
more than full throttle (method eq. 3.32) and a penalty per failed trim (eq. 3.33). A held
point set compares the model with its own predictions at a step's start, so that a step
cannot buy its fit with what earlier steps matched.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Mapping, Sequence

import numpy as np

from ..data.schemas import METRICS, Dataset
from ..evaluation.evaluate import KINDS
from ..flight.condition import Condition, TrimResult
from ..jsbsim.simulator import Simulator

FAIL_PENALTY = 20.0          # per failed trim (method eq. 3.33)
THROTTLE_TOL = 0.05          # throttle above 1 per 0.05 (eq. 3.32)
HOLD_TOL_SCALE = 0.25        # held predictions: a quarter of the tolerances


# Subset of the C172 POH used in the fit (9 climb, 7 cruise, as the method): chosen to span
# temperature, altitude and power. Points are matched by their values, so the same
# selection rule applies to any aircraft: extreme and middle temperatures and altitudes.
def default_subset(ds: Dataset, n: int) -> list[int]:
    """Indices of ``n`` points spread over the data: farthest-point sampling in normalized
    (altitude, temperature or speed) space, starting from the first point. Deterministic."""
    f = ds.frame
    cols = ["pressure_alt_ft"] + (["oat_c"] if "oat_c" in f else []) + (["ktas"] if "ktas" in f else []) \
        + (["temp_dev_c"] if "temp_dev_c" in f and f["temp_dev_c"].nunique() > 1 else [])
    X = f[cols].to_numpy(float)
    span = np.ptp(X, axis=0)
    X = (X - X.min(0)) / np.where(span > 0, span, 1.0)
    n = min(n, len(X))
    chosen = [int(np.argmin(X[:, 0] + X[:, -1]))]
    d = np.linalg.norm(X - X[chosen[0]], axis=1)
    while len(chosen) < n:
        k = int(np.argmax(d))
        chosen.append(k)
        d = np.minimum(d, np.linalg.norm(X - X[k], axis=1))
    return sorted(chosen)


SUBSET_SIZE = {"poh_climb": 9, "poh_cruise": 7}      # the stage-1 subset (the method's 9 climb, 7 cruise)


def stage1_subset(ds: Dataset) -> list[int]:
    """The POH points stage 1 fits (and stage 2a holds)."""
    return default_subset(ds, SUBSET_SIZE.get(ds.kind, 8))


@dataclass
class PointSet:
    """Trim conditions and targets of the points a fit uses."""

    name: str
    dataset: Dataset
    indices: list[int]
    conditions: list[Condition]
    metrics: tuple[str, ...]
    scales: Mapping[str, float] = field(default_factory=dict)   # metric -> share of its tolerance (default 1)
    _targets: dict = field(default_factory=dict, init=False, repr=False, compare=False)   # read once (target)

    @classmethod
    def from_dataset(cls, ds: Dataset, sim: Simulator, indices: Sequence[int] | None = None, metrics=None,
                     scales: Mapping[str, float] | None = None):
        conds = KINDS[ds.kind].conditions(ds, sim.geometry)
        idx = list(range(len(ds))) if indices is None else list(indices)
        return cls(ds.kind, ds, idx, [conds[i] for i in idx], tuple(metrics or ds.metrics), dict(scales or {}))

    def target(self, i: int, m: str) -> float:
        if (i, m) not in self._targets:         # read once: a fit asks for each thousands of times
            self._targets[i, m] = float(self.dataset.frame[m].iat[self.indices[i]])
        return self._targets[i, m]


def trim_points(sim: Simulator, ps: PointSet) -> list[TrimResult]:
    return [sim.trim(c, key=(str(ps.dataset.path), ps.indices[k])) for k, c in enumerate(ps.conditions)]


def point_residuals(sim: Simulator, ps: PointSet, metrics: Sequence[str],
                    results: list[TrimResult] | None = None,
                    tol_scale: float = 1.0) -> tuple[list[float], list[str], int]:
    """Residuals (model - data)/(tolerance x ``tol_scale`` x the set's scale of the metric) of a
    point set, with the throttle penalty for level points that need more than full throttle.
    Returns residuals, labels, number failed."""
    value = KINDS[ps.dataset.kind].value
    res, lab, failed = [], [], 0
    results = results if results is not None else trim_points(sim, ps)
    for k, t in enumerate(results):
        cond = ps.conditions[k]
        # a level point past the throttle stop keeps its (continuous) values and pays the
        # throttle penalty (eq. 3.32); other failures pay the failure penalty (eq. 3.33)
        past_stop = (not t.trimmed and cond.mode == "level" and t.reason.startswith("needs more than full")
                     and ";" not in t.reason)
        thr = t.extra.get("throttle_required", 1.0)
        if past_stop:
            # compare what the aircraft does at full throttle (speed falls short), as the
            # evaluation does: continuous with the level trim at the stop
            ft = sim.trim_at_stop(cond, key=(str(ps.dataset.path), ps.indices[k]))
            if ft.trimmed:
                t = ft
        ok = t.trimmed or past_stop
        if not ok:
            failed += 1
        for m in metrics:
            ref = ps.target(k, m)
            if not np.isfinite(ref):
                continue
            v = value(m, t) if ok else np.nan
            tol = METRICS[m].tol_for(ref) * tol_scale * ps.scales.get(m, 1.0)
            res.append((v - ref) / tol if np.isfinite(v) else 0.0)
            lab.append(f"{ps.name}[{ps.indices[k]}].{m}")
        if cond.mode == "level":
            res.append(max(0.0, (thr - 1.0) / THROTTLE_TOL) if ok else 0.0)
            lab.append(f"{ps.name}[{ps.indices[k]}].throttle>1")
    return res, lab, failed


@dataclass(frozen=True)
class Residual:
    """Residuals of one step: a data kind, which of its points, which metric, and the share of
    the metric's tolerance a residual is divided by (1: the tolerance; 0.2 of the POH climb's
    100 fpm: its 20 fpm RMSE target)."""

    kind: str            # snapshot | flap_climb | poh_climb | poh_cruise
    points: str          # all | clean (flaps up) | flaps (flaps down) | subset (the stage-1 subset)
    metric: str
    scale: float = 1.0


def _select(ds: Dataset, which: str) -> list[int]:
    if which == "subset":
        return stage1_subset(ds)
    flaps = ds.frame["flaps_deg"].to_numpy(float) if "flaps_deg" in ds.frame else np.zeros(len(ds))
    if which == "clean":
        return [i for i, f in enumerate(flaps) if f == 0.0]
    if which == "flaps":
        return [i for i, f in enumerate(flaps) if f > 0.0]
    return list(range(len(ds)))


def point_sets(sim: Simulator, data: dict[str, Dataset], residuals: Sequence[Residual]):
    groups: dict[tuple[str, str], dict[str, float]] = {}
    for r in residuals:
        groups.setdefault((r.kind, r.points), {})[r.metric] = r.scale
    sets = []
    for (kind, which), scales in groups.items():
        ds = data.get(kind)
        idx = _select(ds, which) if ds is not None else []
        if idx:
            sets.append(PointSet.from_dataset(ds, sim, idx, tuple(scales), scales))
    return sets


def held_sets(sim: Simulator, data: dict[str, Dataset], hold: Sequence[Residual]) -> list[PointSet]:
    """Point sets whose targets are the current model's own predictions."""
    out = []
    for ps in point_sets(sim, data, hold):
        kind = ps.dataset.kind
        frame = ps.dataset.frame.copy()
        for m in ps.metrics:
            frame[m] = np.nan
        for i, cond in zip(ps.indices, ps.conditions):
            t = sim.trim_level(cond) if cond.mode == "level" else sim.trim(cond)
            if t.trimmed:
                for m in ps.metrics:
                    frame.loc[frame.index[i], m] = KINDS[kind].value(m, t)
        out.append(replace(ps, name=f"{ps.name} (held)", dataset=replace(ps.dataset, frame=frame)))
    return out
