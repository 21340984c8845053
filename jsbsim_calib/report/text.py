"""Text tables for the console: an evaluation point by point, a summary, the stability check."""
from __future__ import annotations

import math
from typing import Mapping

import numpy as np

from ..evaluation.evaluate import KINDS, Evaluation, MetricSummary
from ..jsbsim.probes import StabilityReport


def evaluation_table(ev: Evaluation) -> str:
    """Plain-text table of every point and the summary."""
    lines = []
    shown = KINDS[ev.dataset.kind].shown if ev.dataset.kind in KINDS else None
    inputs = list(shown) if shown else [c for c in ev.dataset.frame.columns
                                        if c not in ev.metrics and c != "flaps_deg"]
    head = " ".join(f"{c:>14}" for c in inputs) + "".join(f" {m + ' data':>14} {'model':>9} {'error':>8}"
                                                          for m in ev.metrics) + "  trim"
    lines.append(head)
    for p in ev.points:
        s = " ".join(_cell(p.inputs.get(c), 14, ".1f") for c in inputs)
        for m in ev.metrics:
            if not _finite(p.inputs.get(m)):           # the metric does not apply to this point
                s += f" {'-':>14} {'-':>9} {'-':>8} "
                continue
            mark = "" if p.within.get(m, False) else "*"
            s += (f" {_cell(p.inputs.get(m), 14, '.2f')} {_cell(p.model.get(m), 9, '.2f')} "
                  f"{_cell(p.error.get(m), 8, '+.2f')}{mark or ' '}")
        s += "  ok" if p.trimmed else f"  FAILED: {p.reason}"
        lines.append(s)
    lines.append("")
    lines.append(format_summary(ev.summary()))
    lines.append("(* outside tolerance)")
    for q in ev.dataset.extra.get("quirks", []):
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


def _optional(v: float | None, spec: str) -> str:
    return (spec % v) if v is not None else "-"


def format_summary(summary: Mapping[str, MetricSummary]) -> str:
    """A summary (:meth:`Evaluation.summary`) as a text table."""
    lines = [f"{'metric':>12} {'n':>4} {'RMSE':>9} {'MAPE %':>8} {'nMBE %':>8} {'within %':>9} {'failed':>7}"]
    for m, s in summary.items():
        lines.append(f"{m:>12} {s.n:4d} {_optional(s.rmse, '%9.2f'):>9} {_optional(s.mape, '%8.2f'):>8} "
                     f"{_optional(s.nmbe, '%8.2f'):>8} {_optional(s.within_pct, '%9.1f'):>9} {s.failed:7d}")
    return "\n".join(lines)


CHECK_COLUMNS = (("kcas", "KCAS", ".1f"), ("alpha_deg", "alpha", ".2f"), ("elevator_deg", "elev", ".2f"),
                 ("CL_alpha", "CL_a", ".2f"), ("Cm_alpha", "Cm_a", ".3f"), ("static_margin", "SM", ".3f"),
                 ("Cn_beta", "Cn_b", ".4f"), ("Cl_beta", "Cl_b", ".4f"), ("Cl_p", "Cl_p", ".3f"),
                 ("Cm_q", "Cm_q", ".2f"), ("Cn_r", "Cn_r", ".4f"))


def format_stability(report: StabilityReport) -> str:
    """The plausibility report (:func:`report`) as text tables, as ``check`` prints it."""
    rep = report.as_dict()
    lines = [f"{rep['aircraft']}: stability and control derivatives ({rep['axes']})",
             f"{'condition':<16}" + "".join(f"{h:>9}" for _, h, _ in CHECK_COLUMNS)]
    for name, d in rep["derivatives"].items():
        if "error" in d:
            lines.append(f"{name:<16} does not trim: {d['error']}")
            continue
        lines.append(f"{name:<16}" + "".join(f"{d[k]:>9{f}}" if isinstance(d.get(k), (int, float)) else f"{'-':>9}"
                                             for k, _, f in CHECK_COLUMNS))
    lines += ["", "Stall (power off: the lowest speed of a steady glide, elevator within its stops):",
              f"{'weight lb':>10} {'CG in':>7} {'flaps':>6} {'KCAS':>7} {'KIAS':>7} {'CLmax':>7}  note"]
    for s in rep["stall"]:
        num = lambda v, f: f"{v:{f}}" if isinstance(v, (int, float)) else "-"
        lines.append(f"{num(s.get('weight_lb'), '10.0f')} {num(s.get('cg_in'), '7.1f')} {num(s.get('flaps_deg'), '6.0f')} "
                     f"{num(s.get('kcas'), '7.1f')} {num(s.get('kias'), '7.1f')} {num(s.get('cl_max'), '7.3f')}  "
                     f"{s.get('reason', '')}")
    changed = rep.get("factors_changed") or {}
    lines.append("")
    lines.append(f"factors away from neutral: {len(changed)}" + (" (" + ", ".join(f"{k} {v:.4g}" for k, v in changed.items())
                                                                  + ")" if changed else ""))
    return "\n".join(lines)
