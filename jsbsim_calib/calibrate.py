"""Calibration stages: least-squares fits of factors to reference data.

``fit`` is the engine shared by every stage: factors normalized to [-1, 1] over their
bounds (method 3.1.2), residuals divided by their tolerances, ``scipy.optimize.
least_squares`` (trust-region reflective, bounded) with a deliberate finite-difference
step, a progress line per iteration, and a result in the lmfit manner (initial -> final,
bounds, "at boundary" flags, standard errors where the Jacobian allows, cost, evaluations,
wall time).

Stage 1 (``steady_stage``): 16 coupled aero/propeller/engine factors on a documented
subset of POH climb and cruise points (climb error / 100 fpm, power / 5 points, RPM /
50 rpm; a penalty per point for more than full throttle, 20 per failed trim), then K_FF
alone against fuel flow (error / 5 %).
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field, replace
from typing import Callable, Sequence

import numpy as np
from scipy.optimize import least_squares

from .data.schemas import METRICS, Dataset
from .evaluate import KINDS
from .factors import FactorSet, step_factors
from .jsbsim.condition import Condition, TrimResult
from .jsbsim.simulator import Simulator

FAIL_PENALTY = 20.0          # per failed trim (method eq. 3.33)
THROTTLE_TOL = 0.05          # throttle above 1 per 0.05 (eq. 3.32)
# The fit (see fit; README, "Reproducible fits", for the measurements behind each value)
PRIOR_WEIGHT = 0.5           # pull of normalized factors toward the prior centre
LEGS = ((6.0, 0.02), (2.0, 0.02), (1.0, 0.02), (1.0, 0.002))   # (prior multiple, finite-difference step)
TRUST_RADIUS0 = 1.0          # first trust region of every leg, normalized units (the box is [-1, 1])
FIT_TOL = 1e-9               # ftol = xtol = gtol of scipy's least_squares
MAX_RESTARTS = 2             # restarts of the optimizer within a leg
RESTART_GAIN = 1e-6          # a restart must lower the cost by this share, or the leg ends
MAX_NFEV = 600               # function evaluations of a whole fit
STEP_PRIOR = 0.1             # stage 2a's steps fit a few factors the trims identify: a weaker pull


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

    def at_boundary(self, name: str, tol: float = 1e-3) -> str:
        f = self.final.factor(name)
        v = self.final[name]
        span = f.upper - f.lower
        if v <= f.lower + tol * span:
            return "at lower bound"
        if v >= f.upper - tol * span:
            return "at upper bound"
        return ""

    def report(self) -> str:
        """Text report in the lmfit manner."""
        lines = [f"[[Fit: {self.stage}]]",
                 "    method             = least_squares (trf, bounded, normalized factors)",
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


def _stderr(jac: np.ndarray, names: list[str], residuals: np.ndarray, space: FactorSet) -> tuple[dict, dict]:
    """Standard errors of the factors from the Jacobian at the solution, with the
    covariance scaled by the reduced chi-square of the residuals (as lmfit does)."""
    out: dict[str, float | None] = {n: None for n in names}
    corr = {}
    try:
        jtj = jac.T @ jac
        if np.linalg.matrix_rank(jtj) < len(names):
            return out, corr
        cov = np.linalg.inv(jtj)
    except np.linalg.LinAlgError:
        return out, corr
    dof = max(1, len(residuals) - len(names))
    cov = cov * float(residuals @ residuals) / dof
    d = np.sqrt(np.clip(np.diag(cov), 0, None))
    for i, n in enumerate(names):
        f = space.factor(n)
        out[n] = float(d[i] * 0.5 * (f.upper - f.lower))        # back from normalized units
    for i in range(len(names)):
        for j in range(i + 1, len(names)):
            if d[i] > 0 and d[j] > 0:
                corr[(names[i], names[j])] = float(cov[i, j] / (d[i] * d[j]))
    return out, corr


def _trf_leg(fun, jac, x0: np.ndarray, ftol: float, max_nfev: int | None, callback):
    """One run of scipy's trust-region-reflective least squares on [-1, 1] from ``x0``.

    The optimizer moves ``u = x - x0 + c`` with ``|c| = TRUST_RADIUS0``: scipy's trf starts
    with a trust region of ``|u0|``, which would otherwise be the norm of the start itself
    (a start a round-off away from zero would get a round-off trust region and stop)."""
    c = np.full(len(x0), TRUST_RADIUS0 / math.sqrt(len(x0)))
    res = least_squares(lambda u: fun(u - c + x0), c, jac=lambda u: jac(u - c + x0),
                        bounds=(-1.0 - x0 + c, 1.0 - x0 + c), method="trf", x_scale=1.0,
                        ftol=ftol, xtol=ftol, gtol=ftol, max_nfev=max_nfev, callback=callback)
    res.x = np.clip(res.x - c + x0, -1.0, 1.0)
    return res


def fit(stage: str, names: Sequence[str], start: FactorSet, residuals: Callable[[FactorSet], tuple[np.ndarray, list[str]]],
        *, sim: Simulator, max_nfev: int | None = MAX_NFEV, progress: Callable[[str], None] | None = None,
        ftol: float = FIT_TOL, prior: float = PRIOR_WEIGHT, prior_center: FactorSet | None = None) -> FitResult:
    """Least-squares fit of ``names`` (others held at ``start``).

    ``prior`` adds the residuals ``prior * (x - x_center)`` (x = normalized factor, centre
    neutral or ``prior_center``): among factor sets the data cannot tell apart it picks the
    one closest to the physics-based model. A factor moved across half its range costs as
    much as a quarter of a tolerance on one point (prior 0.5): the data's weakly identified
    directions are pinned by the prior, not by round-off (README, "Reproducible fits").

    The fit is a sequence of legs (:data:`LEGS`), each from the last one's result: first a
    path of decreasing priors (the minimum with a strong prior is unique and every start
    reaches it; a Gauss-Newton step amplifies a perturbation by about |r|/sigma_min^2, which
    the strong prior keeps small while the residuals are large), then a polish with a small
    finite-difference step. A leg restarts the optimizer from its result (a fresh trust
    region: trf can stop on a kink of the trims) until a restart gains less than
    :data:`RESTART_GAIN` of the cost.
    """
    names = list(names)
    t0 = time.perf_counter()
    trims0 = sim.trims
    x0 = start.vector(names)
    bad = [n for n, x in zip(names, x0) if not -1.0 <= x <= 1.0]
    if bad:
        raise ValueError(f"start values outside the bounds of {', '.join(bad)}")
    x_center = (prior_center or FactorSet(extra=start.extra)).vector(names)
    labels: list[str] = []
    history: list[dict] = []
    leg = {"weight": 1.0, "step": LEGS[0][1]}
    njev = [0]

    def fun(x):
        fs = start.with_vector(names, np.clip(x, -1, 1))
        r, lab = residuals(fs)
        if prior:
            r = np.concatenate([r, leg["weight"] * prior * (fs.vector(names) - x_center)])
            lab = list(lab) + [f"prior {n}" for n in names]
        labels[:] = lab
        return r

    def callback(intermediate_result):
        it = len(history) + 1
        c = float(intermediate_result.cost)
        history.append({"iteration": it, "cost": c, "prior_multiple": leg["weight"], "trims": sim.trims - trims0})
        if progress:
            progress(f"{stage}: iteration {it:3d}  cost {c:10.4g}  trims {sim.trims - trims0:6d}  "
                     f"{time.perf_counter() - t0:6.1f} s")

    def jac(x):
        """Forward differences with an absolute step in normalized units (the leg's: larger
        than the trim noise; scipy's relative steps vanish at x = 0), inwards at a bound."""
        njev[0] += 1
        f0 = fun(x)
        J = np.empty((len(f0), len(x)))
        for i in range(len(x)):
            h = leg["step"] if x[i] + leg["step"] <= 1.0 else -leg["step"]
            xi = np.array(x, float)
            xi[i] += h
            J[:, i] = (fun(xi) - f0) / h
        return J

    r0 = fun(x0)
    cost0 = 0.5 * float(r0 @ r0)
    if progress:
        progress(f"{stage}: start cost {cost0:.4g} with {len(r0)} residuals, {len(names)} factors")
    x, nfev, res = x0, 0, None
    for weight, step in (LEGS if prior else LEGS[-2:]):        # no prior: no path of priors
        leg.update(weight=weight, step=step)
        cost = math.inf
        for _ in range(1 + MAX_RESTARTS):
            left = None if max_nfev is None else max_nfev - nfev
            if left is not None and left <= 0:
                break
            res = _trf_leg(fun, jac, x, ftol, left, callback)
            nfev += res.nfev
            gained = res.cost < (1.0 - RESTART_GAIN) * cost
            x, cost = res.x, min(cost, float(res.cost))
            if not gained:
                break
    final = start.with_vector(names, x)
    r_final, _ = residuals(final)             # leaves the simulator at the final factors
    if prior:
        r_final = np.concatenate([r_final, prior * (final.vector(names) - x_center)])
    se, corr = _stderr(res.jac, names, r_final, final)
    return FitResult(stage, names, start, final, cost0, 0.5 * float(r_final @ r_final), nfev,
                     njev[0], int(res.status), str(res.message), time.perf_counter() - t0,
                     sim.trims - trims0, se, corr, history, list(labels), r_final)


# --------------------------------------------------------------------------- stage 1
# Subset of the C172 POH used in the fit (9 climb, 7 cruise, as the method): chosen to span
# temperature, altitude and power. Points are matched by their values, so the same
# selection rule applies to any aircraft: extreme and middle temperatures and altitudes.
def default_subset(ds: Dataset, n: int) -> list[int]:
    """Indices of ``n`` points spread over the data: farthest-point sampling in normalized
    (altitude, temperature or speed) space, starting from the first point. Deterministic."""
    f = ds.frame
    cols = ["pressure_alt_ft"] + (["oat_c"] if "oat_c" in f else []) + (["ktas"] if "ktas" in f else []) \
        + (["temp_dev_c"] if "temp_dev_c" in f and f["temp_dev_c"].nunique() > 1 else [])
    X = f[cols].to_numpy(float)
    span = np.ptp(X, axis=0)
    X = (X - X.min(0)) / np.where(span > 0, span, 1.0)
    n = min(n, len(X))
    chosen = [int(np.argmin(X[:, 0] + X[:, -1]))]
    d = np.linalg.norm(X - X[chosen[0]], axis=1)
    while len(chosen) < n:
        k = int(np.argmax(d))
        chosen.append(k)
        d = np.minimum(d, np.linalg.norm(X - X[k], axis=1))
    return sorted(chosen)


SUBSET_SIZE = {"poh_climb": 9, "poh_cruise": 7}      # the stage-1 subset (the method's 9 climb, 7 cruise)


def stage1_subset(ds: Dataset) -> list[int]:
    """The POH points stage 1 fits (and stage 2a holds)."""
    return default_subset(ds, SUBSET_SIZE.get(ds.kind, 8))


@dataclass
class PointSet:
    """Trim conditions and targets of the points a fit uses."""

    name: str
    dataset: Dataset
    indices: list[int]
    conditions: list[Condition]
    metrics: tuple[str, ...]

    @classmethod
    def from_dataset(cls, ds: Dataset, sim: Simulator, indices: Sequence[int] | None = None, metrics=None):
        conds = KINDS[ds.kind].conditions(ds, sim.geometry)
        idx = list(range(len(ds))) if indices is None else list(indices)
        return cls(ds.kind, ds, idx, [conds[i] for i in idx], tuple(metrics or ds.metrics))

    def target(self, i: int, m: str) -> float:
        return float(self.dataset.frame.iloc[self.indices[i]][m])


def trim_points(sim: Simulator, ps: PointSet) -> list[TrimResult]:
    return [sim.trim(c, key=(str(ps.dataset.path), ps.indices[k])) for k, c in enumerate(ps.conditions)]


def point_residuals(sim: Simulator, ps: PointSet, metrics: Sequence[str],
                    results: list[TrimResult] | None = None,
                    tol_scale: float = 1.0) -> tuple[list[float], list[str], int]:
    """Residuals (model - data)/(tolerance x ``tol_scale``) of a point set, with the throttle
    penalty for level points that need more than full throttle. Returns residuals, labels,
    number failed."""
    value = KINDS[ps.dataset.kind].value
    res, lab, failed = [], [], 0
    results = results if results is not None else trim_points(sim, ps)
    for k, t in enumerate(results):
        cond = ps.conditions[k]
        # a level point past the throttle stop keeps its (continuous) values and pays the
        # throttle penalty (eq. 3.32); other failures pay the failure penalty (eq. 3.33)
        past_stop = (not t.trimmed and cond.mode == "level" and t.reason.startswith("needs more than full")
                     and ";" not in t.reason)
        thr = t.extra.get("throttle_required", 1.0)
        if past_stop:
            # compare what the aircraft does at full throttle (speed falls short), as the
            # evaluation does: continuous with the level trim at the stop
            ft = sim.trim_at_stop(cond, key=(str(ps.dataset.path), ps.indices[k]))
            if ft.trimmed:
                t = ft
        ok = t.trimmed or past_stop
        if not ok:
            failed += 1
        for m in metrics:
            ref = ps.target(k, m)
            if not np.isfinite(ref):
                continue
            v = value(m, t) if ok else np.nan
            tol = METRICS[m].tol_for(ref) * tol_scale
            res.append((v - ref) / tol if np.isfinite(v) else 0.0)
            lab.append(f"{ps.name}[{ps.indices[k]}].{m}")
        if cond.mode == "level":
            res.append(max(0.0, (thr - 1.0) / THROTTLE_TOL) if ok else 0.0)
            lab.append(f"{ps.name}[{ps.indices[k]}].throttle>1")
    return res, lab, failed


STEADY_NAMES = list(step_factors("steady"))


def steady_stage(sim: Simulator, climb: Dataset, cruise: Dataset, *, start: FactorSet | None = None,
                 climb_points: Sequence[int] | None = None, cruise_points: Sequence[int] | None = None,
                 progress: Callable[[str], None] | None = None,
                 max_nfev: int | None = MAX_NFEV) -> tuple[FitResult, FitResult]:
    """Method stage 1: the 16 coupled factors on the subset, then K_FF alone on fuel flow."""
    start = start or FactorSet()
    ci = stage1_subset(climb) if climb_points is None else list(climb_points)
    ki = stage1_subset(cruise) if cruise_points is None else list(cruise_points)
    cps = PointSet.from_dataset(climb, sim, ci)
    kps = PointSet.from_dataset(cruise, sim, ki)

    def residuals(fs: FactorSet):
        sim.set_factors(fs)
        r1, l1, f1 = point_residuals(sim, cps, ("roc_fpm",))
        r2, l2, f2 = point_residuals(sim, kps, ("pct_power", "rpm"))
        return np.array(r1 + r2 + [FAIL_PENALTY * (f1 + f2)]), l1 + l2 + ["trim failures"]

    main = fit("steady", STEADY_NAMES, start, residuals, sim=sim, progress=progress, max_nfev=max_nfev)
    main.notes.append(f"fitted points: climb {ci}, cruise {ki} (row indices of {climb.path.name}, {cruise.path.name})")

    def ff_residuals(fs: FactorSet):
        sim.set_factors(fs)
        r, l, f = point_residuals(sim, kps, ("gph",))
        return np.array(r + [FAIL_PENALTY * f]), l + ["trim failures"]

    ff = fit("fuel flow", list(step_factors("fuel flow")), main.final, ff_residuals, sim=sim, progress=progress)
    return main, ff


# --------------------------------------------------------------------------- stage 2a
@dataclass(frozen=True)
class Residual:
    """Residuals of one step: a data kind, which of its points, which metric."""

    kind: str            # snapshot | flap_climb | poh_climb | poh_cruise
    points: str          # all | clean (flaps up) | flaps (flaps down) | subset (the stage-1 subset)
    metric: str


@dataclass(frozen=True)
class TrimStep:
    """One step of the flight-test stage: the factors it fits, the residuals it fits them
    to, and the residuals it holds: the model's own predictions at the step's start, with
    :data:`HOLD_TOL_SCALE` of the tolerances, so that the step cannot buy its fit with
    what earlier steps (or stage 1) already matched. Each step starts from the factors of
    the steps before it and freezes them."""

    name: str
    factors: tuple[str, ...]
    residuals: tuple[Residual, ...]
    doc: str
    hold: tuple[Residual, ...] = ()
    prior_at_start: bool = False     # pull factors toward their values at the step's start, not neutral
    prior: float = STEP_PRIOR        # weight of that pull (see fit)


HOLD_TOL_SCALE = 0.25
POH_HOLD = (Residual("poh_climb", "subset", "roc_fpm"), Residual("poh_cruise", "subset", "pct_power"),
            Residual("poh_cruise", "subset", "rpm"))
FLIGHT_TEST_HOLD = tuple(Residual("snapshot", "all", m) for m in ("pitch_deg", "elevator_deg", "aileron_deg",
                                                                    "rudder_deg")) \
    + (Residual("flap_climb", "all", "roc_fpm"),)

TRIM_STEPS: tuple[TrimStep, ...] = (
    TrimStep("pitch", step_factors("pitch"),
             (Residual("snapshot", "clean", "pitch_deg"),),
             "pitching moment (method 3.2.1): pitch attitude of the flaps-up snapshots / 1 deg; the trim "
             "elevator of all snapshots is held (the control step fits it), the POH is not: the lift curve sets "
             "the attitude, and moving it moves the drag tables under the POH points, which the final steady "
             "refit rebalances", (Residual("snapshot", "all", "elevator_deg"),)),
    TrimStep("control", step_factors("control"),
             (Residual("snapshot", "clean", "elevator_deg"), Residual("snapshot", "all", "aileron_deg"),
              Residual("snapshot", "all", "rudder_deg")),
             "control effectiveness (method 3.2.2): trim surfaces / 1 deg; the elevator of flaps-down "
             "snapshots waits for the flap step (the flap moment is not fitted yet)", POH_HOLD),
    TrimStep("pfactor", step_factors("pfactor"), (Residual("snapshot", "all", "rudder_deg"),),
             "P-factor (method 3.2.2, eq. 3.41): rudder of all snapshots / 1 deg; the rudder factors are "
             "refitted with K_PF (the control step could not see the thrust-dependent yaw and set them for it)",
             POH_HOLD),
    TrimStep("flaps", step_factors("flaps"),
             (Residual("flap_climb", "all", "roc_fpm"), Residual("snapshot", "flaps", "pitch_deg"),
              Residual("snapshot", "flaps", "elevator_deg")),
             "flap aerodynamics (method 3.2.3): flaps-down climb rate / 100 fpm and pitch / 1 deg, plus the "
             "flaps-down trim elevator / 1 deg (where the flap moment shows most) and a flap-lift factor "
             "(the flaps-down attitude is set by the flap lift, which the method's two factors cannot move)",
             POH_HOLD),
    TrimStep("steady refit", step_factors("steady refit"),
             (Residual("poh_climb", "subset", "roc_fpm"), Residual("poh_cruise", "subset", "pct_power"),
              Residual("poh_cruise", "subset", "rpm"), Residual("poh_cruise", "subset", "gph")),
             "stage 1 again from its values, the flight-test factors frozen: the trims bring drag the POH fit "
             "did not see (a 5 deg climb rudder, the trimmed tail load); the flight-test predictions are held "
             "and the factors are pulled toward their stage-1 values",
             FLIGHT_TEST_HOLD, prior_at_start=True, prior=PRIOR_WEIGHT),
)


def _select(ds: Dataset, which: str) -> list[int]:
    if which == "subset":
        return stage1_subset(ds)
    flaps = ds.frame["flaps_deg"].to_numpy(float) if "flaps_deg" in ds.frame else np.zeros(len(ds))
    if which == "clean":
        return [i for i, f in enumerate(flaps) if f == 0.0]
    if which == "flaps":
        return [i for i, f in enumerate(flaps) if f > 0.0]
    return list(range(len(ds)))


def _point_sets(sim: Simulator, data: dict[str, Dataset], residuals: Sequence[Residual]):
    groups: dict[tuple[str, str], list[str]] = {}
    for r in residuals:
        groups.setdefault((r.kind, r.points), []).append(r.metric)
    sets = []
    for (kind, which), metrics in groups.items():
        ds = data.get(kind)
        idx = _select(ds, which) if ds is not None else []
        if idx:
            sets.append(PointSet.from_dataset(ds, sim, idx, metrics))
    return sets


def held_sets(sim: Simulator, data: dict[str, Dataset], hold: Sequence[Residual]) -> list[PointSet]:
    """Point sets whose targets are the current model's own predictions."""
    out = []
    for ps in _point_sets(sim, data, hold):
        kind = ps.dataset.kind
        frame = ps.dataset.frame.copy()
        for m in ps.metrics:
            frame[m] = np.nan
        for i, cond in zip(ps.indices, ps.conditions):
            t = sim.trim_level(cond) if cond.mode == "level" else sim.trim(cond)
            if t.trimmed:
                for m in ps.metrics:
                    frame.loc[frame.index[i], m] = KINDS[kind].value(m, t)
        out.append(replace(ps, name=f"{ps.name} (held)", dataset=replace(ps.dataset, frame=frame)))
    return out


def trims_stage(sim: Simulator, data: dict[str, Dataset], *, start: FactorSet,
                steps: Sequence[TrimStep] = TRIM_STEPS, progress: Callable[[str], None] | None = None,
                max_nfev: int | None = MAX_NFEV, prior: float | None = None,
                after_step: Callable[[TrimStep, FitResult], None] | None = None) -> list[FitResult]:
    """Method stage 2a: the trim steps in order, each from the factors of the last.

    ``data`` maps a kind (``snapshot``, ``flap_climb``, ``poh_climb``, ``poh_cruise``) to
    its dataset; a step whose own residuals have no data is skipped with a note.
    ``after_step`` is called after each fit (for evaluations between steps).
    """
    results = []
    current = start
    for step in steps:
        sets = _point_sets(sim, data, step.residuals)
        if not sets:
            if progress:
                progress(f"{step.name}: no data for this step, skipped")
            continue
        sim.set_factors(current)
        held = held_sets(sim, data, step.hold)

        def residuals(fs: FactorSet, sets=sets, held=held):
            sim.set_factors(fs)
            res, lab, failed = [], [], 0
            for ps, scale in [(p, 1.0) for p in sets] + [(p, HOLD_TOL_SCALE) for p in held]:
                r, l, f = point_residuals(sim, ps, ps.metrics, tol_scale=scale)
                res += r
                lab += l
                failed += f
            return np.array(res + [FAIL_PENALTY * failed]), lab + ["trim failures"]

        out = fit(step.name, list(step.factors), current, residuals, sim=sim,
                  progress=progress, max_nfev=max_nfev, prior=step.prior if prior is None else prior,
                  prior_center=current if step.prior_at_start else None)
        out.notes.append(step.doc)
        for ps, what in [(p, "fitted") for p in sets] + [(p, "held at the step's start") for p in held]:
            rows = [str(ps.dataset.frame["table"].iloc[i]) if "table" in ps.dataset.frame else str(i)
                    for i in ps.indices]
            out.notes.append(f"{what}: {', '.join(ps.metrics)} of {ps.dataset.path.name} rows {', '.join(rows)}")
        results.append(out)
        current = out.final
        sim.set_factors(current)
        if after_step:
            after_step(step, out)
    return results
