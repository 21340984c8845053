"""Evaluate a model against reference data: trim at every point, compare, summarize.

Every data kind maps its rows to trim conditions (``KINDS``); the comparison, statistics
and JSON schema are shared:

    {"aircraft", "model": "calibrated"|"baseline",
     "points": [{<input columns>, "model": {metric: value}, "error": {...}, "within": {...},
                 "trimmed": bool, "reason": str}],
     "summary": {metric: {"n", "rmse", "mape", "nmbe", "within_pct", "failed"}}}

(:meth:`Evaluation.to_json`; the summary is typed, :class:`MetricSummary`, and
:func:`summary_dict` gives its JSON). Text and Markdown tables are :mod:`jsbsim_calib.report`.

Errors are model - data. ``mape``/``nmbe`` are percent of the data value (method eq.
3.25-3.26); ``within_pct`` counts a failed trim as outside tolerance.
"""
from __future__ import annotations

import json
import math
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Mapping, Sequence

import numpy as np
import pandas as pd

from ..data import flighttest, logs
from ..data.poh import poh_climb_conditions, poh_cruise_conditions, poh_value
from ..data.schemas import METRICS, Dataset
from ..flight.condition import Condition, TrimResult
from ..jsbsim.simulator import Simulator
from ..physics.geometry import AircraftGeometry


@dataclass(frozen=True)
class Kind:
    conditions: Callable[[Dataset, AircraftGeometry], list[Condition]]
    value: Callable[[str, TrimResult], float]
    shown: tuple[str, ...] | None = None          # input columns of the printed table (None: all)


KINDS: dict[str, Kind] = {
    "poh_climb": Kind(poh_climb_conditions, poh_value),
    "poh_cruise": Kind(poh_cruise_conditions, poh_value),
    "snapshot": Kind(flighttest.snapshot_conditions, flighttest.snapshot_value,
                     ("table", "flaps_deg", "pressure_alt_ft", "ktas", "vs_fpm", "roll_deg")),
    "flap_climb": Kind(flighttest.flap_climb_conditions, flighttest.flap_climb_value,
                       ("weight_lb", "flaps_deg", "pressure_alt_ft", "ktas")),
    "g1000": Kind(logs.log_conditions, logs.log_value,
                  ("segment", "kind", "duration_s", "pressure_alt_ft", "oat_c", "ktas", "vs_fpm", "weight_lb")),
}


@dataclass
class PointResult:
    index: int
    inputs: dict
    model: dict[str, float]
    error: dict[str, float]
    within: dict[str, bool]
    trimmed: bool
    reason: str = ""
    trim: TrimResult | None = None


@dataclass(frozen=True)
class MetricSummary:
    """Accuracy of one metric over a dataset (method eq. 3.24-3.26); errors are model - data.
    A statistic that cannot be computed (no trimmed point, no nonzero data value) is None."""

    n: int                        # points with a data value for the metric
    rmse: float | None            # root-mean-square error [the metric's unit]
    mape: float | None            # mean absolute error [% of the data value]
    nmbe: float | None            # mean bias error [% of the data value]
    within_pct: float | None      # points within tolerance [%] (a failed trim counts as outside)
    failed: int                   # points whose trim failed

    def as_dict(self) -> dict:
        """The JSON schema's keys: n, rmse, mape, nmbe, within_pct, failed."""
        return {"n": self.n, "rmse": self.rmse, "mape": self.mape, "nmbe": self.nmbe, "within_pct": self.within_pct,
                "failed": self.failed}


Summary = dict[str, MetricSummary]          # by metric


def summary_dict(summary: Mapping[str, MetricSummary]) -> dict[str, dict]:
    """A summary in the JSON schema ``{metric: {"n", "rmse", "mape", "nmbe", "within_pct", "failed"}}``."""
    return {m: s.as_dict() for m, s in summary.items()}


def summarize(points: Sequence[PointResult], metrics: Sequence[str]) -> Summary:
    """RMSE, MAPE, nMBE, share within tolerance and failures per metric (method eq. 3.24-3.26)."""
    out = {}
    for m in metrics:
        rows = [p for p in points if m in p.inputs and np.isfinite(p.inputs[m])]
        ok = [p for p in rows if p.trimmed and np.isfinite(p.error.get(m, np.nan))]
        err = np.array([p.error[m] for p in ok])
        ref = np.array([p.inputs[m] for p in ok])
        nz = ref != 0
        out[m] = MetricSummary(
            n=len(rows),
            rmse=float(np.sqrt(np.mean(err**2))) if len(ok) else None,
            mape=float(100 * np.mean(np.abs(err[nz] / ref[nz]))) if nz.any() else None,
            nmbe=float(100 * np.mean(err[nz] / ref[nz])) if nz.any() else None,
            within_pct=float(100.0 * sum(p.within.get(m, False) for p in rows) / len(rows)) if rows else None,
            failed=len(rows) - len(ok),
        )
    return out


@dataclass
class Evaluation:
    aircraft: str
    model_kind: str                 # calibrated | baseline
    dataset: Dataset
    points: list[PointResult]
    wall_time_s: float = 0.0

    @property
    def metrics(self) -> tuple[str, ...]:
        return self.dataset.metrics

    def summary(self) -> Summary:
        return summarize(self.points, self.metrics)

    def to_json(self) -> dict:
        def clean(x):
            if isinstance(x, float) and not math.isfinite(x):
                return None
            if isinstance(x, (np.floating,)):
                return clean(float(x))
            if isinstance(x, (np.bool_,)):
                return bool(x)
            return x

        pts = []
        for p in self.points:
            d = {k: clean(v) for k, v in p.inputs.items()}
            d.update({"model": {k: clean(v) for k, v in p.model.items()},
                      "error": {k: clean(v) for k, v in p.error.items()},
                      "within": {k: bool(v) for k, v in p.within.items()},
                      "trimmed": bool(p.trimmed)})
            if p.reason:
                d["reason"] = p.reason
            pts.append(d)
        out = {"aircraft": self.aircraft, "model": self.model_kind, "data": str(self.dataset.path),
               "kind": self.dataset.kind, "points": pts, "summary": summary_dict(self.summary())}
        if "table" in self.dataset.extra:
            out["segments"] = [{k: clean(v) for k, v in r.items()}
                               for r in self.dataset.extra["table"].to_dict("records")]
            out["weight_assumption"] = self.dataset.extra.get("weight_note")
        quirks = self.dataset.extra.get("quirks")
        if quirks:
            out["excluded"] = [{"row": q.row, "line": q.line, "reason": q.reason} for q in quirks]
        return out

    def write_json(self, path: Path) -> None:
        Path(path).write_text(json.dumps(self.to_json(), indent=2) + "\n")

    def frame(self) -> pd.DataFrame:
        rows = []
        for p in self.points:
            r = dict(p.inputs)
            for m in self.metrics:
                r[f"model_{m}"] = p.model.get(m, np.nan)
                r[f"error_{m}"] = p.error.get(m, np.nan)
            r["trimmed"] = p.trimmed
            rows.append(r)
        return pd.DataFrame(rows)


def compare_model(index: int, inputs: dict, model: Mapping[str, float], trimmed: bool, reason: str = "",
                  trim: TrimResult | None = None) -> PointResult:
    """A point's model values against its data: errors (model - data) and tolerance checks."""
    error, within = {}, {}
    for m, v in model.items():
        ref = inputs[m]
        error[m] = v - ref if np.isfinite(v) else np.nan
        within[m] = bool(np.isfinite(v) and abs(v - ref) <= METRICS[m].tol_for(ref) + 1e-9)
    return PointResult(index, inputs, dict(model), error, within, trimmed, reason, trim)


def compare(index: int, inputs: dict, metrics: Sequence[str], t: TrimResult, value) -> PointResult:
    model = {}
    for m in metrics:
        ref = inputs.get(m, np.nan)
        if not np.isfinite(ref):
            continue
        model[m] = value(m, t) if t.trimmed else np.nan
    return compare_model(index, inputs, model, t.trimmed, t.reason, t)


def thesis_summary(ds: Dataset) -> Summary:
    """Accuracy of the thesis's calibrated model on the same points (columns thesis_model_*)."""
    pts = []
    ref = ds.reference
    for i, row in enumerate(ds.frame.to_dict("records")):
        model = {}
        for m in ds.metrics:
            col = f"thesis_model_{m}"
            if col not in ref.columns:
                continue
            try:
                model[m] = float(ref[col].iloc[i])
            except ValueError:
                continue
        pts.append(compare_model(i, row, model, bool(model)))
    metrics = [m for m in ds.metrics if f"thesis_model_{m}" in ref.columns]
    return summarize(pts, metrics) if metrics else {}


def evaluate_dataset(sim: Simulator, ds: Dataset, *, model_kind: str = "calibrated",
                     progress: Callable[[int, int], None] | None = None) -> Evaluation:
    """Trim the model at every point of a dataset and compare."""
    if ds.kind not in KINDS:
        raise ValueError(f"no evaluation for data of kind '{ds.kind}'")
    kind = KINDS[ds.kind]
    t0 = time.perf_counter()
    conds = kind.conditions(ds, sim.geometry)
    points = []
    rows = ds.frame.to_dict("records")
    for i, (row, cond) in enumerate(zip(rows, conds)):
        key = (str(ds.path), i)
        t = sim.trim_level(cond, key) if cond.mode == "level" else sim.trim(cond, key)
        points.append(compare(i, row, ds.metrics, t, kind.value))
        if progress:
            progress(i + 1, len(rows))
    return Evaluation(sim.name, model_kind, ds, points, time.perf_counter() - t0)
