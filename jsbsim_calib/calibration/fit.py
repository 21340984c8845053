"""The fit engine every calibration stage and step shares.

Factors normalized to [-1, 1] over their bounds (method 3.1.2), residuals divided by their
tolerances, a bounded Levenberg-Marquardt (:func:`jsbsim_calib.core.numerics.least_squares`,
which gives the same bits on every CPU) with a deliberate finite-difference step, a progress
line per iteration, and a result in the lmfit manner (initial -> final, bounds, "at
boundary" flags, standard errors where the Jacobian allows, cost, evaluations, wall time).
"""
from __future__ import annotations

import math
import re
import time
import uuid
from dataclasses import dataclass, field
from typing import Callable, Sequence

import numpy as np

from ..core import numerics
from ..core.executor import SERIAL, Executor
from ..factors import FactorSet
from ..jsbsim.simulator import Simulator

# The fit (see fit; docs/model.md, "Reproducible fits", for the measurements behind each value)
PRIOR_WEIGHT = 0.5           # pull of normalized factors toward the prior centre
LEGS = ((6.0, 0.02), (2.0, 0.02), (1.0, 0.02), (1.0, 0.002))   # (prior multiple, finite-difference step)
FIT_TOL = 1e-6               # ftol = xtol = gtol of the least-squares solver (1e-9 before: the same costs, 15 % more time)
MAX_RESTARTS = 2             # restarts of the optimizer within a leg
RESTART_GAIN = 1e-6          # a restart must lower the cost by this share, or the leg ends
MAX_NFEV = 600               # function evaluations of a whole fit

# How well the data determine a factor (FitResult.determination; the identifiability tables)
PRIOR_GROUP = "prior"        # the residual group of the prior's rows
Z95 = 1.96                   # a 95 % interval is +/- Z95 standard errors
LOOSE_SHARE = 0.25           # loose: the 95 % interval spans more than this share of the factor's range
HELD_BY_PRIOR = 0.5          # held by the prior: the prior carries at least this share of its information


class WorkLine(str):
    """A progress line that counts its task's work (a fit: the trims it took so far), for a
    display's estimate of the time left (:mod:`jsbsim_calib.report.progress`); a plain str to
    any other reader."""

    task: str
    work: int

    def __new__(cls, text: str, task: str, work: int):
        line = super().__new__(cls, text)
        line.task, line.work = task, int(work)
        return line


@dataclass
class FitResult:
    """Outcome of one least-squares fit (one stage or step)."""

    stage: str
    names: list[str]
    initial: FactorSet
    final: FactorSet
    cost_initial: float
    cost_final: float
    nfev: int
    njev: int
    status: int
    message: str
    wall_time_s: float
    trims: int
    stderr: dict[str, float | None] = field(default_factory=dict)
    correl: dict[tuple[str, str], float] = field(default_factory=dict)
    history: list[dict] = field(default_factory=list)
    residual_names: list[str] = field(default_factory=list)
    residuals: np.ndarray | None = None
    notes: list[str] = field(default_factory=list)
    information: dict[str, list[tuple[str, float]]] = field(default_factory=dict)
    covariance: np.ndarray | None = None   # of the normalized factors (names' order), None where rank-deficient

    def at_boundary(self, name: str, tol: float = 1e-3) -> str:
        f = self.final.factor(name)
        v = self.final[name]
        span = f.upper - f.lower
        if v <= f.lower + tol * span:
            return "at lower bound"
        if v >= f.upper - tol * span:
            return "at upper bound"
        return ""

    def determination(self, name: str) -> str:
        """How well the data determine a factor: "not identified" (no standard error, or one
        over half the factor's range), "held by the prior" (the prior carries most of its
        information), "loose" (its 95 % interval spans over a quarter of its range), else
        "determined"; a factor on a bound says so too."""
        f, se = self.final.factor(name), self.stderr.get(name)
        span = f.upper - f.lower
        prior = dict(self.information.get(name, [])).get(PRIOR_GROUP, 0.0)
        if se is None or not math.isfinite(se) or se > 0.5 * span:
            word = "not identified"
        elif prior >= HELD_BY_PRIOR:
            word = "held by the prior"
        elif 2.0 * Z95 * se > LOOSE_SHARE * span:
            word = "loose"
        else:
            word = "determined"
        bound = self.at_boundary(name)
        return f"{word}, {bound}" if bound else word

    def strongest_correlation(self, name: str) -> tuple[str, float] | None:
        """The factor this one's estimate is most correlated with, and the coefficient."""
        pairs = [(b if a == name else a, r) for (a, b), r in self.correl.items() if name in (a, b)]
        return min(pairs, key=lambda p: (-abs(p[1]), p[0])) if pairs else None

    def report(self) -> str:
        """Text report in the lmfit manner."""
        lines = [f"[[Fit: {self.stage}]]",
                 "    method             = Levenberg-Marquardt (bounded, normalized factors)",
                 f"    status             = {self.status}: {self.message}",
                 f"    function evals     = {self.nfev} ({self.njev} Jacobians, {self.trims} trims)",
                 f"    residuals          = {len(self.residual_names)}",
                 f"    cost (1/2 sum r^2) = {self.cost_initial:.4g} -> {self.cost_final:.4g}",
                 "[[Factors]]"]
        for n in self.names:
            f = self.final.factor(n)
            se = self.stderr.get(n)
            se_s = f" +/- {se:.3g}" if se is not None and math.isfinite(se) else " +/- (n/a)"
            flag = self.at_boundary(n)
            if not flag and se is not None and math.isfinite(se) and se > 0.5 * (f.upper - f.lower):
                flag = "not identified by these data"
            unit = "" if f.unit == "-" else f" {f.unit}"
            lines.append(f"    {n:<17} {self.initial[n]:>9.4g} -> {self.final[n]:>9.5g}{se_s:<14}{unit:<6} "
                         f"bounds [{f.lower:g}, {f.upper:g}]{'  ' + flag.upper() if flag else ''}")
        strong = [(k, v) for k, v in self.correl.items() if abs(v) > 0.9]
        if strong:
            lines.append("[[Correlations]] (|r| > 0.9)")
            for (a, b), v in sorted(strong, key=lambda kv: -abs(kv[1])):
                lines.append(f"    C({a}, {b}) = {v:+.3f}")
        for n in self.notes:
            lines.append(f"    note: {n}")
        return "\n".join(lines)

    def summary(self) -> dict:
        return {
            "stage": self.stage, "status": self.status, "message": self.message, "nfev": self.nfev,
            "njev": self.njev, "trims": self.trims, "cost_initial": self.cost_initial, "cost_final": self.cost_final,
            "factors": {n: {"initial": self.initial[n], "final": self.final[n], "stderr": self.stderr.get(n),
                            "lower": self.final.factor(n).lower, "upper": self.final.factor(n).upper,
                            "at_boundary": self.at_boundary(n) or None} for n in self.names},
            "notes": self.notes,
        }


def data_rows(jac: np.ndarray, labels: Sequence[str]) -> np.ndarray:
    """The residual rows that are measurements: not the prior's, and moved by some factor. A
    row no factor moves (a throttle penalty that does not bind, a failed trim's constant
    penalty) is no observation: counted, it would shrink the reduced chi-square and with it
    every standard error (16 such rows among 32 made them 1.5x too small)."""
    moved = np.any(jac != 0.0, axis=1) if jac.ndim == 2 and len(jac) else np.zeros(0, bool)
    prior = np.array([lab.startswith("prior ") for lab in labels], bool) if len(labels) == len(moved) \
        else np.zeros(len(moved), bool)
    return moved & ~prior


def _stderr(jac: np.ndarray, names: list[str], residuals: np.ndarray, space: FactorSet,
            rows: np.ndarray | None = None) -> tuple[dict, dict, np.ndarray | None]:
    """Standard errors and correlations of the factors from the Jacobian at the solution, with
    the covariance (of the normalized factors; None where rank-deficient) scaled by the reduced
    chi-square of the measurements (``rows``: :func:`data_rows`; default every row)."""
    out: dict[str, float | None] = {n: None for n in names}
    corr = {}
    jtj = numerics.gram(jac)
    try:
        cov = numerics.inverse(jtj)
    except numerics.SingularMatrixError:
        return out, corr, None
    if not np.all(np.isfinite(cov)) or np.any(np.diag(cov) <= 0) or np.max(np.abs(cov)) > 1e12:
        return out, corr, None                  # rank-deficient: no standard errors
    rows = np.ones(len(residuals), bool) if rows is None else rows
    dof = max(1, int(np.count_nonzero(rows)) - len(names))
    cov = cov * numerics.sum_sq(np.asarray(residuals)[rows]) / dof
    d = np.sqrt(np.clip(np.diag(cov), 0, None))
    for i, n in enumerate(names):
        f = space.factor(n)
        out[n] = float(d[i] * 0.5 * (f.upper - f.lower))        # back from normalized units
    for i in range(len(names)):
        for j in range(i + 1, len(names)):
            if d[i] > 0 and d[j] > 0:
                corr[(names[i], names[j])] = float(cov[i, j] / (d[i] * d[j]))
    return out, corr, cov


def sensitivity(residuals, start: FactorSet, names: Sequence[str], step: float = 0.05) -> np.ndarray:
    """Forward-difference Jacobian in normalized factor units at ``start`` (inwards at a bound)
    of ``residuals``: factors -> (residuals, labels)."""
    r0, _ = residuals(start)
    x0 = start.vector(names)
    cols = []
    for i in range(len(names)):
        x = np.array(x0)
        x[i] += step if x[i] + step <= 1 else -step
        r1, _ = residuals(start.with_vector(names, x))
        cols.append((r1 - r0) / (x[i] - x0[i]))
    return np.column_stack(cols)


def residual_group(label: str) -> str:
    """The data a residual belongs to: its label without the row ("poh_climb[3].roc_fpm" ->
    "poh_climb.roc_fpm"; a maneuver's metric stays as it is; the prior's rows: "prior")."""
    return PRIOR_GROUP if label.startswith("prior ") else re.sub(r"\[[^\]]*\]", "", label)


def _information(jac: np.ndarray | None, labels: list[str], names: list[str]) -> dict[str, list[tuple[str, float]]]:
    """Per factor, the share of its Fisher information (the sum of its squared Jacobian column:
    the weighted residuals' sensitivity) that each group of residuals carries, largest first:
    which data determine it."""
    if jac is None or jac.shape != (len(labels), len(names)):
        return {}
    rows: dict[str, list[int]] = {}
    for k, lab in enumerate(labels):                  # one pass: a time history has a group per sample
        rows.setdefault(residual_group(lab), []).append(k)
    out = {}
    for i, n in enumerate(names):
        total = numerics.sum_sq(jac[:, i])
        if not (math.isfinite(total) and total > 0.0):
            out[n] = []
            continue
        shares = {g: numerics.sum_sq(jac[r, i]) / total for g, r in rows.items()}
        out[n] = sorted(shares.items(), key=lambda kv: (-kv[1], kv[0]))
    return out


class FitProblem:
    """A fit's residuals as a pure function of (normalized factors, trim warm starts, prior
    multiple): every evaluation starts from a JSBSim in a fresh load's state and the given warm starts,
    so that it gives the same bits in this process or in any executor's worker, whatever ran
    before. Called with an item ``(x, warm_starts, prior_multiple)`` it returns the residuals
    (the executors' form); with ``(x, warm_starts, prior_multiple, True)``, the whole
    :class:`Evaluation` (a trial point, whose warm starts the next steps need)."""

    def __init__(self, sim: Simulator, residuals, start: FactorSet, names: Sequence[str], x_center: np.ndarray,
                 prior: float):
        self.sim, self.residuals, self.start, self.names = sim, residuals, start, list(names)
        self.x_center, self.prior = x_center, prior
        self.key = uuid.uuid4().hex        # one serialization per fit (executors)

    def evaluate(self, x: np.ndarray, warm: dict, weight: float) -> "Evaluation":
        fs = self.start.with_vector(self.names, np.clip(x, -1, 1))
        sim = self.sim
        trims0 = sim.trims
        sim.trim_cache = dict(warm)
        if not sim.set_factors(fs):          # new propeller tables there: already a fresh JSBSim
            sim.fresh()
        r, lab = self.residuals(fs)
        if self.prior:
            r = np.concatenate([r, weight * self.prior * (fs.vector(self.names) - self.x_center)])
            lab = list(lab) + [f"prior {n}" for n in self.names]
        return Evaluation(r, list(lab), sim.trim_cache, sim.trims - trims0)

    def __call__(self, item):
        out = self.evaluate(*item[:3])
        return out if len(item) > 3 and item[3] else out.residuals


@dataclass
class Evaluation:
    """One evaluation of a fit's residuals: with its labels, the trim warm starts it leaves and
    the trims it took."""

    residuals: np.ndarray
    labels: list[str]
    warm: dict
    trims: int


def _jacobian(problem: FitProblem, executor: Executor, x: np.ndarray, f0: np.ndarray, step: float, warm: dict,
              weight: float) -> np.ndarray:
    """Forward differences with an absolute step in normalized units (larger than the trim
    noise; relative steps would vanish at x = 0), inwards at a bound; the columns are
    independent work (``executor``)."""
    hs = [step if xi + step <= 1.0 else -step for xi in x]
    items = []
    for i, h in enumerate(hs):
        xi = np.array(x, float)
        xi[i] += h
        items.append((xi, warm, weight))
    cols = executor.map(problem, items, key=problem.key)
    return np.column_stack([(c - f0) / h for c, h in zip(cols, hs)])


def fit(stage: str, names: Sequence[str], start: FactorSet, residuals: Callable[[FactorSet], tuple[np.ndarray, list[str]]],
        *, sim: Simulator, max_nfev: int | None = MAX_NFEV, progress: Callable[[str], None] | None = None,
        ftol: float = FIT_TOL, prior: float = PRIOR_WEIGHT, prior_center: FactorSet | None = None,
        legs: Sequence[tuple[float, float]] | None = None, restarts: int = MAX_RESTARTS,
        executor: Executor = SERIAL) -> FitResult:
    """Least-squares fit of ``names`` (others held at ``start``).

    ``prior`` adds the residuals ``prior * (x - x_center)`` (x = normalized factor, centre
    neutral or ``prior_center``): among factor sets the data cannot tell apart it picks the
    one closest to the physics-based model. A factor moved across half its range costs as
    much as a quarter of a tolerance on one point (prior 0.5): the data's weakly identified
    directions are pinned by the prior, not by round-off (README, "Reproducible fits").

    The fit is a sequence of legs (:data:`LEGS`), each from the last one's result: first a
    path of decreasing priors, then a polish with a small finite-difference step. A leg
    restarts the optimizer from its result (a fresh damping: it can stop on a kink of the
    trims, whose tables interpolate linearly) until a restart gains less than
    :data:`RESTART_GAIN` of the cost or takes no step (a restart of it would repeat it: the
    refit of a Level 5 campaign of Cm += K elevator x qbar spent 11 of its 25 s so), at most
    ``restarts`` times. ``legs`` replaces :data:`LEGS` (a fit of a few
    well-identified factors needs no path of priors). Every evaluation is a pure function of
    its point and of the warm starts of the last accepted point (:class:`FitProblem`): the
    Jacobian's columns run on ``executor`` and give the same bits there.
    """
    names = list(names)
    t0 = time.perf_counter()
    x0 = start.vector(names)
    bad = [n for n, x in zip(names, x0) if not -1.0 <= x <= 1.0]
    if bad:
        raise ValueError(f"start values outside the bounds of {', '.join(bad)}")
    problem = FitProblem(sim, residuals, start, names,
                         (prior_center or FactorSet(extra=start.extra)).vector(names), prior)
    labels: list[str] = []
    history: list[dict] = []
    state = {"weight": 1.0, "step": LEGS[0][1], "warm": dict(sim.trim_cache), "last": {}, "njev": 0, "trims": 0,
             "trials": {}}

    def counted(ev: Evaluation) -> Evaluation:         # an evaluation the serial algorithm makes
        labels[:] = ev.labels
        state["last"] = ev.warm
        state["trims"] += ev.trims
        return ev

    def fun(x):
        return counted(problem.evaluate(x, state["warm"], state["weight"])).residuals

    def trials(xs):
        """Trial points: in this process one at a time, or as one batch on the executor (each
        counted when the least-squares walk takes it into account: :func:`on_trial`)."""
        if len(xs) == 1:
            evs, here = [problem.evaluate(xs[0], state["warm"], state["weight"])], True
        else:
            evs = executor.map(problem, [(xi, state["warm"], state["weight"], True) for xi in xs], key=problem.key)
            here = False
        state["trials"] = {xi.tobytes(): (e, here) for xi, e in zip(xs, evs)}
        return [e.residuals for e in evs]

    def on_trial(x):
        ev, here = state["trials"][x.tobytes()]
        counted(ev)
        if not here:                  # the simulator's count: as if it had run here (the same on any executor)
            sim.trims += ev.trims

    def callback(c: float):           # a step was accepted: its warm starts are the next evaluations'
        state["warm"] = state["last"]
        history.append({"iteration": len(history) + 1, "cost": c, "prior_multiple": state["weight"],
                        "trims": state["trims"]})
        if progress:
            progress(WorkLine(f"{stage}: iteration {len(history):3d}  cost {c:10.4g}  trims {state['trims']:6d}  "
                              f"{time.perf_counter() - t0:6.1f} s", stage, state["trims"]))

    def jac(x, f0):
        state["njev"] += 1
        return _jacobian(problem, executor, x, f0, state["step"], state["warm"], state["weight"])

    r0 = fun(x0)
    state["warm"] = state["last"]
    cost0 = 0.5 * numerics.sum_sq(r0)
    if progress:
        progress(WorkLine(f"{stage}: start cost {cost0:.4g} with {len(r0)} residuals, {len(names)} factors", stage,
                          state["trims"]))
    x, nfev, res = x0, 0, None
    for weight, step in (legs if legs is not None else LEGS if prior else LEGS[-2:]):   # no prior: no path
        state.update(weight=weight, step=step)
        cost = math.inf
        for _ in range(1 + restarts):
            left = None if max_nfev is None else max_nfev - nfev
            if left is not None and left <= 0:
                break
            res = numerics.least_squares(fun, jac, x, -1.0, 1.0, ftol=ftol, xtol=ftol, gtol=ftol,
                                         max_nfev=left, callback=callback, on_trial=on_trial, trials=trials,
                                         batch=executor.workers)
            nfev += res.nfev
            gained = res.cost < (1.0 - RESTART_GAIN) * cost and not np.array_equal(res.x, x)
            x, cost = res.x, min(cost, float(res.cost))
            if not gained:             # a run that took no step would be repeated bit for bit
                break
    final = start.with_vector(names, x)
    r_final = counted(problem.evaluate(x, state["warm"], 1.0)).residuals    # leaves the simulator at the final factors
    se, corr, cov = _stderr(res.jac, names, r_final, final, data_rows(res.jac, labels))
    return FitResult(stage, names, start, final, cost0, 0.5 * numerics.sum_sq(r_final), nfev,
                     state["njev"], int(res.status), str(res.message), time.perf_counter() - t0,
                     state["trims"], se, corr, history, list(labels), r_final,
                     information=_information(res.jac, labels, names), covariance=cov)


def unfitted(stage: str, names: Sequence[str], start: FactorSet,
             residuals: Callable[[FactorSet], tuple[np.ndarray, list[str]]], sim: Simulator) -> FitResult:
    """The record of a step that fits nothing: its residuals at ``start``, factors unchanged."""
    t0, trims0 = time.perf_counter(), sim.trims
    r, labels = residuals(start)
    cost = 0.5 * numerics.sum_sq(r)
    return FitResult(stage, list(names), start, start, cost, cost, 1, 0, 0, "nothing fitted",
                     time.perf_counter() - t0, sim.trims - trims0, {n: None for n in names}, {}, [], list(labels), r)
