"""The report figures (issue 26): a tolerance band on every parity plot, a line at 1 on "RMSE /
tolerance", strips of more than four panels wrapped to rows, a unit on every axis."""
from __future__ import annotations

from types import SimpleNamespace as NS

import numpy as np

from jsbsim_calib.report import plots
from jsbsim_calib.report.validation_report import fold_figure


def _evaluation(metric: str, shift: float):
    x = np.linspace(200.0, 900.0, 8)
    return NS(points=[NS(inputs={metric: v}, model={metric: v + shift}) for v in x])


def _labels(fig) -> list[str]:
    return [t for ax in fig.axes for t in (ax.get_xlabel(), ax.get_ylabel()) if t]


def _has_band(ax) -> bool:
    return any(c.get_label() == "tolerance" for c in ax.collections)


def test_parity_plots_carry_the_tolerance_band_and_units():
    fig = plots.parity({"baseline": _evaluation("roc_fpm", 150.0), "calibrated": _evaluation("roc_fpm", 10.0)},
                       "roc_fpm")
    assert _has_band(fig.axes[0]) and _labels(fig) == ["data roc_fpm [ft/min]", "model roc_fpm [ft/min]"]


def test_a_strip_of_more_than_four_panels_wraps_to_rows():
    evals = {f"state {k}": _evaluation("pitch_deg", 0.1 * k) for k in range(7)}
    fig = plots.parity_panels(evals, "pitch_deg")
    grids = {ax.get_subplotspec().get_geometry()[:2] for ax in fig.axes}
    assert len(fig.axes) == 7 and grids == {(2, 4)} and all(_has_band(ax) for ax in fig.axes)
    assert all("[deg]" in t for t in _labels(fig))
    few = plots.parity_panels({k: evals[k] for k in list(evals)[:3]}, "pitch_deg")
    assert {ax.get_subplotspec().get_geometry()[:2] for ax in few.axes} == {(1, 3)}


def test_rmse_over_tolerance_has_a_line_at_one():
    m = NS(fit=NS(rmse=50.0), held_out=NS(rmse=150.0), tolerance=100.0, flagged=True, fold="flaps 10",
           metric="roc_fpm")
    fig = fold_figure([NS(aircraft="c172", stage="steady", rows=lambda: [m])])
    ax = fig.axes[0]
    assert any(list(line.get_ydata()) == [1.0, 1.0] for line in ax.get_lines())
    assert ax.get_ylabel() == "RMSE / tolerance [-]"
