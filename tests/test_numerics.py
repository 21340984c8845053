"""The bounded least-squares solver (jsbsim_calib.numerics): it solves a small problem, holds a
bound, and refuses what it cannot solve as posed with a clear error (issue 26): a start outside
the bounds (never clipped), lower >= upper, residuals at the start that are not finite."""
from __future__ import annotations

import math

import numpy as np
import pytest

from jsbsim_calib.numerics import ProblemError, least_squares

T = np.linspace(0.0, 1.0, 7)
Y = 0.3 + 0.5 * T


def fun(x):
    return x[0] + x[1] * T - Y


def jac(x, r):
    return np.column_stack([np.ones_like(T), T])


def test_solves_a_line_and_holds_a_bound():
    res = least_squares(fun, jac, [0.0, 0.0], -1.0, 1.0)
    assert res.x == pytest.approx([0.3, 0.5], abs=1e-8) and res.cost < 1e-16
    held = least_squares(fun, jac, [0.0, 0.0], [-1.0, -1.0], [1.0, 0.2])
    assert held.x[1] == 0.2 and math.isfinite(held.cost)


@pytest.mark.parametrize("x0, match", [([1.5, 0.0], "x0 outside the bounds at index 0"),
                                       ([0.0, -1.0000001], "x0 outside the bounds at index 1"),
                                       ([math.nan, 0.0], "x0 is not finite")])
def test_a_start_outside_the_box_is_refused_not_clipped(x0, match):
    with pytest.raises(ProblemError, match=match):
        least_squares(fun, jac, x0, -1.0, 1.0)


@pytest.mark.parametrize("lower, upper", [([-1.0, 1.0], [1.0, 1.0]), ([-1.0, 2.0], [1.0, 1.0]),
                                          ([-1.0, math.nan], [1.0, 1.0])])
def test_lower_not_below_upper_is_refused(lower, upper):
    with pytest.raises(ProblemError, match="lower >= upper"):
        least_squares(fun, jac, [0.0, 0.0], lower, upper)


def test_bounds_that_do_not_fit_x0_are_refused():
    with pytest.raises(ProblemError, match="do not fit"):
        least_squares(fun, jac, [0.0, 0.0], [-1.0, -1.0, -1.0], 1.0)


@pytest.mark.parametrize("bad", [math.nan, math.inf])
def test_residuals_not_finite_at_the_start_are_refused(bad):
    def broken(x):
        r = fun(x)
        r[3] = bad
        return r
    with pytest.raises(ProblemError, match="not finite at the start"):
        least_squares(broken, jac, [0.0, 0.0], -1.0, 1.0)


def test_a_start_on_the_bound_is_inside():
    res = least_squares(fun, jac, [1.0, -1.0], -1.0, 1.0)
    assert res.x == pytest.approx([0.3, 0.5], abs=1e-8)
