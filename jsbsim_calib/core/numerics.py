"""Small dense linear algebra and a bounded least-squares solver that give the same bits on
every x86-64 CPU.

Why not numpy.linalg and scipy.optimize.least_squares: they call OpenBLAS, which picks its
kernels by CPU at load time (Haswell, SkylakeX, Zen ...), and the kernels sum in different
orders. A fit amplifies those last-bit differences along its path (measured: the C172's
stage 1 + 2a landed 0.7 standard errors apart on an AMD and an Intel machine, and bit for
bit on the Intel result when this machine was told to use the SkylakeX kernels). Here every
product is an exactly rounded element-wise numpy operation and every sum is ``math.fsum``
(correctly rounded), so the result depends on the inputs only. The sizes are small (tens of
factors, hundreds of residuals): pure Python loops cost milliseconds against the seconds of
the trims that produce the numbers.

A leaf module (numpy only).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable

import numpy as np


class SingularMatrixError(ArithmeticError):
    """The matrix has no inverse (a zero pivot)."""


class ProblemError(ValueError):
    """A least-squares problem that cannot be solved as posed (bounds, start, residuals at the start)."""


def dot(a, b) -> float:
    """Sum of element-wise products, correctly rounded."""
    return math.fsum(np.multiply(np.asarray(a, float), np.asarray(b, float)).tolist())


def sum_sq(a) -> float:
    """Sum of squares, correctly rounded."""
    a = np.asarray(a, float)
    return math.fsum((a * a).tolist())


def norm(a) -> float:
    return math.sqrt(sum_sq(a))


def matvec(A, x) -> np.ndarray:
    A = np.asarray(A, float)
    return np.array([dot(row, x) for row in A])


def gram(J) -> np.ndarray:
    """J^T J."""
    J = np.asarray(J, float)
    n = J.shape[1]
    G = np.empty((n, n))
    for i in range(n):
        for j in range(i, n):
            G[i, j] = G[j, i] = dot(J[:, i], J[:, j])
    return G


def solve(A, b) -> np.ndarray:
    """x with A x = b: Gaussian elimination with partial pivoting. ``b`` a vector or a matrix
    (one right-hand side per column)."""
    A = np.array(A, float)
    x = np.array(b, float)
    n = len(A)
    if A.shape != (n, n) or x.shape[0] != n:
        raise ValueError(f"solve needs a square matrix and a right-hand side of its size, got {A.shape}, {x.shape}")
    if x.ndim == 1:
        return lu_solve(lu_factor(A), x)
    for k in range(n):                  # a matrix of right-hand sides (inverse): the same elimination in numpy
        p = k + int(np.argmax(np.abs(A[k:, k])))
        if not A[p, k] != 0.0 or not math.isfinite(A[p, k]):
            raise SingularMatrixError(f"zero or non-finite pivot in column {k}")
        if p != k:
            A[[k, p]] = A[[p, k]]
            x[[k, p]] = x[[p, k]]
        f = A[k + 1:, k] / A[k, k]
        A[k + 1:, k:] -= np.multiply.outer(f, A[k, k:])
        x[k + 1:] -= np.multiply.outer(f, x[k])
    for k in range(n - 1, -1, -1):
        x[k] = (x[k] - np.array([dot(A[k, k + 1:], x[k + 1:, j]) for j in range(x.shape[1])])) / A[k, k]
    return x


def lu_factor(A) -> tuple:
    """Gaussian elimination with partial pivoting of A, recorded for many right-hand sides (a
    trim's Newton steps share their Jacobian): (row swaps, multipliers, upper triangle) on Python
    floats, each operation rounded as numpy rounds it (a 6 x 6 system: about 15 us here against
    125 us in numpy calls on such small rows). :func:`lu_solve` then makes on ``b`` the
    operations :func:`solve` makes on a matrix of right-hand sides, in its order: the same bits."""
    A = [[float(v) for v in row] for row in A]
    n = len(A)
    swaps, mults = [], []
    for k in range(n):
        col = [abs(A[i][k]) for i in range(k, n)]
        if not all(math.isfinite(c) for c in col):            # numpy's argmax picks a NaN or an inf
            raise SingularMatrixError(f"zero or non-finite pivot in column {k}")
        p = k + col.index(max(col))                            # the first of the largest, as argmax
        if not A[p][k] != 0.0:
            raise SingularMatrixError(f"zero or non-finite pivot in column {k}")
        if p != k:
            A[k], A[p] = A[p], A[k]
        row, fs = A[k], []
        for i in range(k + 1, n):
            f = A[i][k] / row[k]
            Ai = A[i]
            for j in range(k, n):
                Ai[j] = Ai[j] - f * row[j]
            fs.append(f)
        swaps.append(p)
        mults.append(fs)
    return tuple(swaps), tuple(tuple(f) for f in mults), tuple(tuple(row) for row in A)


def lu_solve(lu: tuple, b) -> np.ndarray:
    """x with A x = b, ``lu`` = :func:`lu_factor` (A): the same bits as ``solve(A, b)``."""
    swaps, mults, U = lu
    x = [float(v) for v in b]
    n = len(x)
    for k in range(n):
        p = swaps[k]
        if p != k:
            x[k], x[p] = x[p], x[k]
        xk = x[k]
        for i, f in zip(range(k + 1, n), mults[k]):
            x[i] = x[i] - f * xk
    for k in range(n - 1, -1, -1):
        x[k] = (x[k] - math.fsum([U[k][j] * x[j] for j in range(k + 1, n)])) / U[k][k]
    return np.array(x)


def inverse(A) -> np.ndarray:
    return solve(A, np.eye(len(A)))


# --------------------------------------------------------------------------- least squares
@dataclass
class LSQResult:
    """Outcome of :func:`least_squares` (named as scipy names them)."""

    x: np.ndarray
    cost: float                 # 1/2 sum r^2 at x
    fun: np.ndarray             # residuals at x
    jac: np.ndarray             # the last Jacobian computed (at x, or one step before it)
    nfev: int                   # residual evaluations (Jacobian evaluations not counted)
    njev: int
    status: int                 # 0 evaluations exhausted, 1 gtol, 2 xtol, 3 ftol
    message: str


MESSAGES = {0: "the maximum number of function evaluations is exceeded",
            1: "`gtol` termination condition is satisfied",
            2: "`xtol` termination condition is satisfied",
            3: "`ftol` termination condition is satisfied"}


def _checked_box(x0, lower, upper) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The start and the bounds as float arrays of one shape; :class:`ProblemError` for a start
    outside the box or not finite, or a bound pair with lower >= upper (nothing is clipped)."""
    x = np.asarray(x0, float)
    try:
        lower, upper = (np.broadcast_to(np.asarray(b, float), x.shape).copy() for b in (lower, upper))
    except ValueError:
        raise ProblemError(f"least_squares: bounds of shape {np.shape(lower)} and {np.shape(upper)} do not fit "
                           f"x0 of shape {x.shape}") from None
    where = lambda mask: ", ".join(str(i) for i in np.flatnonzero(mask)[:5])
    if not np.all(lower < upper):
        raise ProblemError(f"least_squares: lower >= upper (or not a number) at index {where(~(lower < upper))}")
    if not np.all(np.isfinite(x)):
        raise ProblemError(f"least_squares: x0 is not finite at index {where(~np.isfinite(x))}")
    outside = (x < lower) | (x > upper)
    if outside.any():
        i = int(np.flatnonzero(outside)[0])
        raise ProblemError(f"least_squares: x0 outside the bounds at index {where(outside)} (first: {x[i]!r} not in "
                           f"[{lower[i]!r}, {upper[i]!r}]); start inside the box (nothing is clipped)")
    return x, lower, upper


def _damped_steps(A, g, d, free, x, lower, upper, lam: float, nu: float, xtol: float, count: int):
    """The next ``count`` trial steps of the damping sequence from (lam, nu), as a rejection of
    each would make them: [(x_new, step, lam, nu)], the status that ends the sequence before
    ``count`` steps (0: no evaluations left, 2: step below xtol) or None, and (lam, nu) after
    the last step's rejection. A singular damped system raises the damping and is no step."""
    out = []
    while True:
        if len(out) >= count:
            return out, (0 if count == 0 else None), (lam, nu)
        step = np.zeros_like(x)
        try:
            step[free] = solve(A[np.ix_(free, free)] + lam * np.diag(d[free]), -g[free])
        except SingularMatrixError:
            lam, nu = lam * nu, 2.0 * nu
            continue
        x_new = np.clip(x + step, lower, upper)
        s = x_new - x
        if norm(s) <= xtol * (1.0 + norm(x)):
            return out, 2, (lam, nu)
        out.append((x_new, s, lam, nu))
        lam, nu = lam * nu, 2.0 * nu


def least_squares(fun: Callable[[np.ndarray], np.ndarray], jac: Callable[[np.ndarray, np.ndarray], np.ndarray], x0,
                  lower, upper, *, ftol: float = 1e-9, xtol: float = 1e-9, gtol: float = 1e-9,
                  max_nfev: int | None = None, lam0: float = 1e-3,
                  callback: Callable[[float], None] | None = None,
                  on_trial: Callable[[np.ndarray], None] | None = None,
                  trials: Callable[[list[np.ndarray]], list[np.ndarray]] | None = None,
                  batch: int = 1) -> LSQResult:
    """Minimize 1/2 |fun(x)|^2 on the box [lower, upper]: Levenberg-Marquardt with
    Marquardt's diagonal scaling and Nielsen's damping update, steps projected onto the box,
    factors on a bound that the gradient pushes outward held there (an active set).

    Stops when an accepted step lowers the cost by less than ``ftol`` of it, when a step is
    shorter than ``xtol`` (1 + |x|), when the projected gradient is below ``gtol`` (1 + cost),
    or after ``max_nfev`` residual evaluations. ``jac(x, fun(x))`` gives the Jacobian;
    ``on_trial(x)`` runs for each trial point taken into account (in order), ``callback(cost)``
    after each accepted step. A start outside the box (or not finite),
    a lower bound not below its upper bound, or a residual at the start that is not finite is a
    :class:`ProblemError` (the start is never clipped).

    ``trials`` (a list of points -> their residuals) with ``batch`` > 1 evaluates the next
    ``batch`` trial points of the damping sequence at once (the steps a rejection would try
    next, each more damped): on a parallel executor the rejections cost no extra round. The
    first trial that lowers the cost is taken, as one at a time would: the same iterates, the
    same counts, the same bits, whatever the batch.
    Deterministic: the same inputs give the same bits on any CPU (module doc).
    """
    x, lower, upper = _checked_box(x0, lower, upper)
    r = np.asarray(fun(x), float)
    bad = np.flatnonzero(~np.isfinite(r))
    if bad.size:
        raise ProblemError(f"least_squares: {bad.size} of {r.size} residuals are not finite at the start x0 "
                           f"(first at index {int(bad[0])}: {r[bad[0]]}); the cost is not defined there")
    evaluate = trials if trials is not None else (lambda xs: [fun(xi) for xi in xs])
    batch = max(1, int(batch)) if trials is not None else 1
    cost, nfev, njev = 0.5 * sum_sq(r), 1, 0
    lam, nu, status, J = None, 2.0, None, None
    while status is None:
        J = np.asarray(jac(x, r), float)
        njev += 1
        g, A = matvec(J.T, r), gram(J)
        held = ((x <= lower) & (g > 0)) | ((x >= upper) & (g < 0))
        free = np.flatnonzero(~held)
        if free.size == 0 or max(abs(g[free])) <= gtol * (1.0 + cost):
            status = 1
            break
        d = np.maximum(np.diag(A), 1e-12 * max(1.0, float(np.max(np.diag(A)))))
        lam = lam0 if lam is None else lam
        while status is None:
            room = None if max_nfev is None else max_nfev - nfev
            steps, stop, (lam_next, nu_next) = _damped_steps(A, g, d, free, x, lower, upper, lam, nu, xtol,
                                                             batch if room is None else min(batch, max(room, 0)))
            accepted = False
            for (x_new, s, lam_at, nu_at), r_new in zip(steps, evaluate([st[0] for st in steps]) if steps else []):
                r_new = np.asarray(r_new, float)
                nfev += 1
                if on_trial:
                    on_trial(x_new)
                cost_new = 0.5 * sum_sq(r_new) if np.all(np.isfinite(r_new)) else math.inf
                if cost_new < cost:
                    predicted = -(dot(g, s) + 0.5 * dot(s, matvec(A, s)))
                    rho = (cost - cost_new) / predicted if predicted > 0 else 0.0
                    lam, nu = lam_at * max(1.0 / 3.0, 1.0 - (2.0 * rho - 1.0) ** 3), 2.0
                    gain = cost - cost_new
                    x, r, cost = x_new, r_new, cost_new
                    if callback:
                        callback(cost)
                    if gain <= ftol * cost:
                        status = 3
                    accepted = True
                    break
                lam, nu = lam_at * nu_at, 2.0 * nu_at
            if accepted:
                break
            if stop is not None:
                status = stop
            else:
                lam, nu = lam_next, nu_next
    return LSQResult(x, cost, r, J, nfev, njev, status, MESSAGES[status])
