"""The identifiability table of a calibration report: for every factor a stage fitted, how well
its data determine it (standard error, 95 % interval against the factor's range, the factor its
estimate moves with, and which data carry its information), and a flag on the ones they do not."""
from __future__ import annotations

from typing import Sequence

from ..calibration.fit import LOOSE_SHARE, PRIOR_GROUP, Z95, FitResult

MIN_SHARE = 0.05          # information sources listed: those carrying at least this share ...
MAX_SOURCES = 3           # ... at most this many


def _pct(share: float) -> str:
    return f"{100.0 * share:.0f} %"


def _sources(fit: FitResult, name: str) -> str:
    shown = [(g, s) for g, s in fit.information.get(name, []) if s >= MIN_SHARE][:MAX_SOURCES]
    return ", ".join(f"{g} {_pct(s)}" for g, s in shown) or "-"


def _row(fit: FitResult, name: str) -> str:
    f, se = fit.final.factor(name), fit.stderr.get(name)
    unit = "" if f.unit == "-" else f" {f.unit}"
    has_se = se is not None and se == se
    width = _pct(2.0 * Z95 * se / (f.upper - f.lower)) if has_se else "-"
    corr = fit.strongest_correlation(name)
    corr = corr if corr and abs(corr[1]) >= 0.005 else None       # no "+0.00" (nor "-0.00")
    return (f"| {fit.stage} | {name} | {fit.final[name]:.5g}{unit} | {f'{se:.3g}' if has_se else '-'} | {width} "
            f"| {f'{corr[0]} {corr[1]:+.2f}' if corr else '-'} | {_sources(fit, name)} | {fit.determination(name)} |")


def identifiability_section(fits: Sequence[FitResult]) -> list[str]:
    """Markdown lines: the table over the fits that fitted something, and the factors flagged."""
    fits = [f for f in fits if f.njev > 0]
    L = ["## Identifiability", "",
         f"How well the data determine each factor, at the fit's solution. The 95 % interval is +/- {Z95} "
         "standard errors, shown as a share of the factor's range (its bounds); the correlation is the "
         "strongest with another factor of the same fit; the information is the squared sensitivity of the "
         "weighted residuals to the factor, split by the data it comes from (a data set and quantity, a "
         f"maneuver's metric, or the `{PRIOR_GROUP}` that pulls the factor toward its start). A factor is "
         f"*loose* when its interval spans over {_pct(LOOSE_SHARE)} of its range, *held by the prior* when the "
         "prior carries half its information or more, *not identified* without a standard error or with one "
         "over half its range.", "",
         "| fit | factor | value | standard error | 95 % interval / range | strongest correlation "
         "| information from | verdict |", "|---|---|---:|---:|---:|---|---|---|"]
    flagged = []
    for fit in fits:
        for n in fit.names:
            L.append(_row(fit, n))
            if not fit.determination(n).startswith("determined"):
                flagged.append(f"{n} ({fit.stage}: {fit.determination(n)})")
    L += ["", ("Not determined by these data: " + "; ".join(flagged) + ".") if flagged
          else "Every fitted factor is determined by these data.", ""]
    return L
