"""The weight of a logged flight estimated from the log itself.

A G1000 log records fuel but not the loading, so the evaluation assumes one
(:class:`~jsbsim_calib.data.logs.LogLoading`). In level flight at a given true airspeed and
altitude the power required grows with weight (induced drag ~ W^2), and with a fixed-pitch
propeller the RPM with it: the weight at which the model's trimmed level-flight RPM matches the
logged RPM over the level segments estimates the weight (method ``rpm``). The same with the
logged pitch attitude (method ``pitch``) is confounded with any attitude-reference offset of
the AHRS (on the C172 log about 1.4 deg, ``close-loop``): reported for comparison only.

The unknown is one offset common to all segments (the payload); each segment keeps its logged
fuel. Gauss-Newton on the offset with finite-difference sensitivities (real trims), the
standard error from the scatter of the segments about the fit.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Sequence

import numpy as np

from ..core.errors import DataError
from ..data.logs import log_conditions, log_value
from ..data.schemas import Dataset
from ..flight.condition import Condition
from ..jsbsim.simulator import Simulator

METHODS = {"rpm": "level-flight RPM (power required against weight)",
           "pitch": "level-flight pitch attitude (confounded with an attitude-reference offset)"}
METRIC = {"rpm": "rpm", "pitch": "pitch_deg"}       # method -> the log's metric it matches
STEP_LB = 100.0              # finite-difference step of the sensitivities
TOL_LB = 0.5                 # Gauss-Newton stops when a step is smaller
MAX_ITER = 8
OFFSET_BOUND_LB = 1500.0     # the offset is kept within +- this (a plausibility bound, reported if reached)


@dataclass(frozen=True)
class WeightEstimate:
    """Weight of a logged flight from its level segments."""

    weight_lb: float                 # [lb] mean weight over the segments used (estimated)
    stderr_lb: float                 # [lb] standard error (NaN with fewer than 2 segments)
    method: str                      # rpm | pitch
    offset_lb: float                 # [lb] estimated - assumed, the same for every segment
    assumed_weight_lb: float         # [lb] mean assumed weight over the same segments
    segments: tuple[int, ...]        # segment numbers used
    residual_rms: float              # [rpm or deg] model - log at the estimate
    sensitivity_per_lb: float        # [rpm or deg per lb] mean d(model)/dW
    notes: tuple[str, ...] = field(default_factory=tuple)

    def describe(self) -> str:
        """One line for the report and the console."""
        unit = "rpm" if self.method == "rpm" else "deg"
        return (f"weight estimated from the log ({METHODS[self.method]}): {self.weight_lb:.0f} +/- "
                f"{self.stderr_lb:.0f} lb over segments {', '.join(map(str, self.segments))} (assumed "
                f"{self.assumed_weight_lb:.0f} lb, offset {self.offset_lb:+.0f} lb; residual RMS "
                f"{self.residual_rms:.2g} {unit}, sensitivity {self.sensitivity_per_lb:.3g} {unit}/lb)")


def _level_rows(ds: Dataset, metric: str) -> list[int]:
    f = ds.frame
    return [i for i in range(len(f)) if f["kind"].iloc[i] == "cruise" and np.isfinite(f[metric].iloc[i])]


def _values(sim: Simulator, conds: Sequence[Condition], rows: Sequence[int], metric: str, offset_lb: float,
            key: str) -> np.ndarray:
    """The model's metric at each row's condition with ``offset_lb`` added to its weight (NaN: no trim)."""
    out = []
    for i in rows:
        c = replace(conds[i], weight_lb=conds[i].weight_lb + offset_lb)
        t = sim.trim_level(c, (key, i, "weight estimate"))
        out.append(log_value(metric, t) if t.trimmed else math.nan)
    return np.array(out)


def _gauss_newton(sim, conds, rows, y, metric, key) -> tuple[float, np.ndarray, np.ndarray, list[str]]:
    """Offset minimizing sum (model - log)^2; returns offset, residuals, sensitivities, notes."""
    offset, notes = 0.0, []
    for _ in range(MAX_ITER):
        v0 = _values(sim, conds, rows, metric, offset, key)
        s = (_values(sim, conds, rows, metric, offset + STEP_LB, key) - v0) / STEP_LB
        if not (np.all(np.isfinite(v0)) and np.all(np.isfinite(s))) or float(np.sum(s * s)) == 0.0:
            raise DataError(key, f"the model does not trim at every level segment near offset {offset:+.0f} lb")
        step = -float(np.sum(s * (v0 - y)) / np.sum(s * s))
        new = float(np.clip(offset + step, -OFFSET_BOUND_LB, OFFSET_BOUND_LB))
        done = abs(new - offset) < TOL_LB
        offset = new
        if done:
            break
    if abs(offset) >= OFFSET_BOUND_LB:
        notes.append(f"offset at its plausibility bound +-{OFFSET_BOUND_LB:.0f} lb: the estimate is not trustworthy")
    v = _values(sim, conds, rows, metric, offset, key)
    return offset, v - y, s, notes


def estimate_weight(sim: Simulator, log_dataset: Dataset, method: str = "rpm") -> WeightEstimate:
    """The weight at which the model's level-flight ``method`` (``rpm`` or ``pitch``) matches the
    log on average over its level segments (least squares on one payload offset)."""
    if method not in METHODS:
        raise ValueError(f"method must be one of {', '.join(METHODS)}, not {method!r}")
    if log_dataset.kind != "g1000":
        raise DataError(log_dataset.path, f"a weight is estimated from a G1000 log, not from data of kind "
                                          f"'{log_dataset.kind}'")
    metric = METRIC[method]
    rows = _level_rows(log_dataset, metric)
    if not rows:
        raise DataError(log_dataset.path, "no level-flight segment: the weight cannot be estimated from this log")
    conds = log_conditions(log_dataset, sim.geometry)
    y = log_dataset.frame[metric].to_numpy(float)[rows]
    offset, res, s, notes = _gauss_newton(sim, conds, rows, y, metric, str(log_dataset.path))
    n = len(rows)
    sigma = math.sqrt(float(np.sum(res ** 2)) / (n - 1)) if n > 1 else math.nan
    stderr = sigma / math.sqrt(float(np.sum(s * s)))
    assumed = float(np.mean([conds[i].weight_lb for i in rows]))
    segs = tuple(int(log_dataset.frame["segment"].iloc[i]) for i in rows)
    return WeightEstimate(assumed + offset, stderr, method, offset, assumed, segs,
                          math.sqrt(float(np.mean(res ** 2))), float(np.mean(s)), tuple(notes))


def with_weight_offset(ds: Dataset, estimate: WeightEstimate) -> Dataset:
    """The log's dataset with every segment's weight moved by the estimate's offset (the
    estimate used instead of the assumed loading)."""
    frame = ds.frame.copy()
    frame["weight_lb"] = frame["weight_lb"] + estimate.offset_lb
    extra = dict(ds.extra)
    if "table" in extra:
        table = extra["table"].copy()
        table["weight_lb"] = table["weight_lb"] + estimate.offset_lb
        extra["table"] = table
    extra["weight_note"] = (f"weight estimated from the log's level-flight {estimate.method}: the assumed loading "
                            f"({ds.extra.get('weight_note', 'assumed')}) {estimate.offset_lb:+.0f} lb "
                            f"(+/- {estimate.stderr_lb:.0f} lb)")
    extra["weight_estimate"] = estimate
    return replace(ds, frame=frame, extra=extra)
