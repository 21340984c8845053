"""Evaluate a model against reference data: trim at every point, compare, summarize.

Every data kind maps its rows to trim conditions (``KINDS``); the comparison, statistics
and JSON schema are shared:

    {"aircraft", "model": "calibrated"|"baseline",
     "points": [{<input columns>, "model": {metric: value}, "error": {...}, "within": {...},
                 "trimmed": bool, "reason": str}],
     "summary": {metric: {"n", "rmse", "mape", "nmbe", "within_pct", "failed"}}}

Errors are model - data. ``mape``/``nmbe`` are percent of the data value (method eq.
3.25-3.26); ``within_pct`` counts a failed trim as outside tolerance.
"""
from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Sequence

import numpy as np
import pandas as pd

from .data import flighttest, logs
from .data.poh import poh_climb_conditions, poh_cruise_conditions, poh_value
from .data.schemas import METRICS, Dataset
from .jsbsim.condition import Condition, TrimResult
from .jsbsim.simulator import Simulator
from .physics.geometry import AircraftGeometry


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


def summarize(points: Sequence[PointResult], metrics: Sequence[str]) -> dict:
    """RMSE, MAPE, nMBE, share within tolerance and failures per metric (method eq. 3.24-3.26)."""
    out = {}
    for m in metrics:
        rows = [p for p in points if m in p.inputs and np.isfinite(p.inputs[m])]
        ok = [p for p in rows if p.trimmed and np.isfinite(p.error.get(m, np.nan))]
        err = np.array([p.error[m] for p in ok])
        ref = np.array([p.inputs[m] for p in ok])
        nz = ref != 0
        out[m] = {
            "n": len(rows),
            "rmse": float(np.sqrt(np.mean(err**2))) if len(ok) else None,
            "mape": float(100 * np.mean(np.abs(err[nz] / ref[nz]))) if nz.any() else None,
            "nmbe": float(100 * np.mean(err[nz] / ref[nz])) if nz.any() else None,
            "within_pct": float(100.0 * sum(p.within.get(m, False) for p in rows) / len(rows)) if rows else None,
            "failed": len(rows) - len(ok),
        }
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

    def summary(self) -> dict:
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
               "kind": self.dataset.kind, "points": pts, "summary": self.summary()}
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

    def table(self) -> str:
        """Plain-text table of every point and the summary."""
        lines = []
        shown = KINDS[self.dataset.kind].shown if self.dataset.kind in KINDS else None
        inputs = list(shown) if shown else [c for c in self.dataset.frame.columns
                                            if c not in self.metrics and c != "flaps_deg"]
        head = " ".join(f"{c:>14}" for c in inputs) + "".join(f" {m + ' data':>14} {'model':>9} {'error':>8}"
                                                              for m in self.metrics) + "  trim"
        lines.append(head)
        for p in self.points:
            s = " ".join(_cell(p.inputs.get(c), 14, ".1f") for c in inputs)
            for m in self.metrics:
                if not _finite(p.inputs.get(m)):           # the metric does not apply to this point
                    s += f" {'-':>14} {'-':>9} {'-':>8} "
                    continue
                mark = "" if p.within.get(m, False) else "*"
                s += (f" {_cell(p.inputs.get(m), 14, '.2f')} {_cell(p.model.get(m), 9, '.2f')} "
                      f"{_cell(p.error.get(m), 8, '+.2f')}{mark or ' '}")
            s += "  ok" if p.trimmed else f"  FAILED: {p.reason}"
            lines.append(s)
        lines.append("")
        lines.append(format_summary(self.summary()))
        lines.append("(* outside tolerance)")
        for q in self.dataset.extra.get("quirks", []):
            lines.append(f"left out: {q}")
        return "\n".join(lines)


def _finite(v) -> bool:
    return isinstance(v, (int, float, np.number)) and not isinstance(v, bool) and math.isfinite(float(v))


def _cell(v, width: int, spec: str) -> str:
    """A table cell: text as it is, whole numbers without decimals, '-' for a missing value."""
    if isinstance(v, str):
        return f"{v:>{width}}"
    if not _finite(v):
        return f"{'-':>{width}}"
    if float(v).is_integer() and "+" not in spec:
        return f"{int(v):>{width}d}"
    return f"{format(float(v), spec):>{width}}"


def format_summary(summary: dict) -> str:
    lines = [f"{'metric':>12} {'n':>4} {'RMSE':>9} {'MAPE %':>8} {'nMBE %':>8} {'within %':>9} {'failed':>7}"]
    for m, s in summary.items():
        f = lambda v, fmt: (fmt % v) if v is not None else "-"
        lines.append(f"{m:>12} {s['n']:4d} {f(s['rmse'], '%9.2f'):>9} {f(s['mape'], '%8.2f'):>8} "
                     f"{f(s['nmbe'], '%8.2f'):>8} {f(s['within_pct'], '%9.1f'):>9} {s['failed']:7d}")
    return "\n".join(lines)


def compare(index: int, inputs: dict, metrics: Sequence[str], t: TrimResult, value) -> PointResult:
    model, error, within = {}, {}, {}
    for m in metrics:
        ref = inputs.get(m, np.nan)
        if not np.isfinite(ref):
            continue
        v = value(m, t) if t.trimmed else np.nan
        model[m] = v
        error[m] = v - ref if np.isfinite(v) else np.nan
        within[m] = bool(np.isfinite(v) and abs(v - ref) <= METRICS[m].tol_for(ref) + 1e-9)
    return PointResult(index, inputs, model, error, within, t.trimmed, t.reason, t)


def evaluate_dataset(sim: Simulator, ds: Dataset, *, model_kind: str = "calibrated",
                     progress: Callable[[int, int], None] | None = None) -> Evaluation:
    """Trim the model at every point of a dataset and compare."""
    import time
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
