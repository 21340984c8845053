"""Accuracy targets as data, and the verdict of an evaluation against them.

A target names a data kind, a metric, a statistic of the evaluation summary (``rmse`` or
``within_pct``) and its limit. The tolerances themselves belong to the metrics
(:data:`jsbsim_calib.data.schemas.METRICS`, FAA Part 60 Level 5 derived); the targets say how much
of the data must meet them. A statistic that is missing or not a number is a FAIL, never a
PASS (the verdict words are those of the dynamic and Part 60 tables: PASS / FAIL).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Mapping, Sequence

from ..data.schemas import METRICS


@dataclass(frozen=True)
class Target:
    kind: str              # data kind: poh_climb, poh_cruise, snapshot, flap_climb, dynamic
    metric: str
    statistic: str         # rmse, mape (at most) | within_pct (at least)
    limit: float

    def describe(self) -> str:
        return {"rmse": f"RMSE <= {self.limit:g}", "mape": f"error <= {self.limit:g} %"}.get(
            self.statistic, f"within >= {self.limit:g} %")

    def met_by(self, value: float | None) -> bool:
        if value is None or not math.isfinite(value):
            return False
        return value >= self.limit if self.statistic == "within_pct" else value <= self.limit


TARGETS: tuple[Target, ...] = (
    Target("poh_climb", "roc_fpm", "rmse", 20.0),
    Target("poh_climb", "roc_fpm", "within_pct", 100.0),
    Target("poh_cruise", "rpm", "rmse", 10.0),
    Target("poh_cruise", "rpm", "within_pct", 100.0),
    Target("poh_cruise", "pct_power", "rmse", 1.0),
    Target("poh_cruise", "pct_power", "within_pct", 100.0),
    Target("poh_cruise", "gph", "within_pct", 100.0),
    Target("snapshot", "pitch_deg", "within_pct", 95.0),
    Target("snapshot", "elevator_deg", "within_pct", 95.0),
    Target("snapshot", "aileron_deg", "within_pct", 95.0),
    Target("snapshot", "rudder_deg", "within_pct", 95.0),
    Target("flap_climb", "roc_fpm", "within_pct", 100.0),
    Target("dynamic", "phugoid_period_s", "mape", 5.0),          # stage 2b (issue): within 5 % of the flight test
    Target("dynamic", "roll_rate_deg_s", "within_pct", 100.0),
    Target("dynamic", "response_time_s", "within_pct", 100.0),   # 1.f.1 engine acceleration: 2-4 s
)


@dataclass(frozen=True)
class Verdict:
    target: Target
    measured: float | None

    @property
    def passed(self) -> bool:
        return self.target.met_by(self.measured)

    @property
    def word(self) -> str:
        return "PASS" if self.passed else "FAIL"

    def to_json(self) -> dict:
        finite = self.measured is not None and math.isfinite(self.measured)
        return {"data": self.target.kind, "metric": self.target.metric, "statistic": self.target.statistic,
                "target": self.target.describe(), "measured": self.measured if finite else None,
                "verdict": self.word}


def verdicts(summaries: Mapping[str, Mapping[str, Mapping]], targets=TARGETS) -> list[Verdict]:
    """Verdicts of the targets whose kind and metric the summaries hold
    (``summaries[kind][metric]``: :class:`jsbsim_calib.evaluation.evaluate.MetricSummary`)."""
    out = []
    for t in targets:
        s = summaries.get(t.kind, {}).get(t.metric)
        if s is not None:
            out.append(Verdict(t, getattr(s, t.statistic)))
    return out


def _measured(v: Verdict | None) -> str:
    if v is None:
        return ""
    if v.measured is None or not math.isfinite(v.measured):
        return "n/a"
    return f"{v.measured:.1f} %" if v.target.statistic in ("within_pct", "mape") else f"{v.measured:.2f}"


def lost_targets(history: Sequence[tuple[str, list[Verdict]]]) -> list[tuple[Verdict, str]]:
    """The chain's guard: the targets an earlier stage met that the last stage misses, each with
    the last earlier stage that met it (``history``: (stage, its verdicts), in the chain's order)."""
    if not history:
        return []
    out = []
    for v in history[-1][1]:
        if v.passed:
            continue
        met = [stage for stage, vs in history[:-1] for w in vs if w.target == v.target and w.passed]
        if met:
            out.append((v, met[-1]))
    return out


def format_verdicts(vs: list[Verdict], model: str, earlier: Sequence[tuple[str, list[Verdict]]] = ()) -> str:
    """The verdict table the console shows at the end of a calibration; ``earlier``: the
    verdicts after each earlier stage of the chain, shown beside the final ones, and the guard's
    line (a target an earlier stage met and the chain lost)."""
    stages = [stage for stage, _ in earlier]
    lines = [f"Verdicts of the {model}:",
             f"{'data':<11} {'metric':<17} {'tolerance':>14} {'target':>15}"
             + "".join(f" {'after ' + s:>15}" for s in stages) + f" {'measured':>9}  verdict"]
    for v in vs:
        m = METRICS[v.target.metric]
        tol = f"+-{m.tolerance * 100:g} %" if m.relative else f"+-{m.tolerance:g} {m.unit}"
        before = "".join(f" {_measured(next((w for w in ws if w.target == v.target), None)):>15}" for _, ws in earlier)
        lines.append(f"{v.target.kind:<11} {v.target.metric:<17} {tol:>14} {v.target.describe():>15}{before} "
                     f"{_measured(v):>9}  {v.word}")
    n = sum(v.passed for v in vs)
    lines.append(f"{n} of {len(vs)} targets met")
    if earlier:
        lost = lost_targets([*earlier, ("end", vs)])
        lines.append("guard: " + ("; ".join(f"{v.target.kind} {v.target.metric} {v.target.describe()} was met after "
                                            f"{stage} and is missed at the end" for v, stage in lost)
                                  if lost else "every target an earlier stage met is still met"))
    return "\n".join(lines)
