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
from typing import Mapping

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


def format_verdicts(vs: list[Verdict], model: str) -> str:
    """The verdict table the console shows at the end of a calibration."""
    lines = [f"Verdicts of the {model}:",
             f"{'data':<11} {'metric':<17} {'tolerance':>14} {'target':>15} {'measured':>9}  verdict"]
    for v in vs:
        m = METRICS[v.target.metric]
        tol = f"+-{m.tolerance * 100:g} %" if m.relative else f"+-{m.tolerance:g} {m.unit}"
        meas = "n/a" if v.measured is None or not math.isfinite(v.measured) else (
            f"{v.measured:.1f} %" if v.target.statistic in ("within_pct", "mape") else f"{v.measured:.2f}")
        lines.append(f"{v.target.kind:<11} {v.target.metric:<17} {tol:>14} {v.target.describe():>15} {meas:>9}  "
                     f"{v.word}")
    n = sum(v.passed for v in vs)
    lines.append(f"{n} of {len(vs)} targets met")
    return "\n".join(lines)
