"""The bounded least-squares solver (jsbsim_calib.core.numerics): it solves a small problem, holds a
bound, and refuses what it cannot solve as posed with a clear error (issue 26): a start outside
the bounds (never clipped), lower >= upper, residuals at the start that are not finite."""
from __future__ import annotations

import math

import numpy as np
import pytest

from jsbsim_calib.core.numerics import ProblemError, least_squares

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


def rosenbrock(x):
    return np.array([10.0 * (x[1] - x[0] ** 2), 1.0 - x[0], 0.3 * np.sin(3.0 * x[0] * x[1])])


def rosenbrock_jac(x, r):
    h = 1e-7
    return np.column_stack([(rosenbrock(x + h * e) - r) / h for e in np.eye(2)])


@pytest.mark.parametrize("max_nfev", [None, 7, 12])
@pytest.mark.parametrize("batch", [2, 3, 8])
def test_a_batch_of_trial_points_takes_the_steps_one_at_a_time_takes(batch, max_nfev):
    """Trial points evaluated ``batch`` at a time (a parallel executor's round) give the same
    iterates, counts and bits as one at a time, also when the evaluation budget ends inside a
    batch; the trials taken into account are reported in order, and more are evaluated than
    counted only where rejections were possible."""
    seen, taken = {"one": [], "batch": []}, []

    def trials(xs):
        seen["batch"].extend(x.copy() for x in xs)
        return [rosenbrock(x) for x in xs]

    one = least_squares(rosenbrock, rosenbrock_jac, [-0.9, 0.8], -2.0, 2.0, max_nfev=max_nfev,
                        on_trial=lambda x: seen["one"].append(x.copy()))
    many = least_squares(rosenbrock, rosenbrock_jac, [-0.9, 0.8], -2.0, 2.0, max_nfev=max_nfev, trials=trials,
                         batch=batch, on_trial=lambda x: taken.append(x.copy()))
    assert one.x.tobytes() == many.x.tobytes() and one.cost == many.cost
    assert (one.nfev, one.njev, one.status) == (many.nfev, many.njev, many.status)
    assert len(taken) == len(seen["one"]) == one.nfev - 1 > 3
    assert all(a.tobytes() == b.tobytes() for a, b in zip(taken, seen["one"]))
    assert len(seen["batch"]) >= len(taken)
    assert max_nfev is None or many.nfev <= max_nfev


def test_a_factored_matrix_solves_to_the_bits_of_the_matrix_elimination():
    """A trim's Newton steps solve with its Jacobian factored once (lu_factor, lu_solve, on Python
    floats): the bits of solve's elimination in numpy on a matrix of right-hand sides, on random
    systems over ten decades, and the same refusal of a singular matrix."""
    from jsbsim_calib.core.numerics import SingularMatrixError, lu_factor, lu_solve, solve
    rng = np.random.default_rng(7)
    for n in (1, 2, 6, 7):
        for _ in range(300):
            A = rng.normal(size=(n, n)) * 10.0 ** rng.uniform(-5, 5, size=(n, n))
            b = rng.normal(size=n)
            assert np.array_equal(lu_solve(lu_factor(A), b), solve(A, b[:, None])[:, 0])
    singular = np.array([[1.0, 2.0], [2.0, 4.0]])
    with pytest.raises(SingularMatrixError):
        lu_factor(singular)
    with pytest.raises(SingularMatrixError):
        solve(singular, np.ones(2))
