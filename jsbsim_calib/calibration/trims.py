"""Stage 2a (method 3.2): the flight-test trim steps in order, each fitting its factors to its
residuals and freezing them. A step is data: its name (the registry's factors of that step are
what it fits), the residuals it fits them to and the ones it holds."""
from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Callable, Sequence

import numpy as np

from ..data.schemas import Dataset
from ..core.executor import SERIAL, Executor
from ..factors import REGISTRY, FactorSet, step_factors
from ..jsbsim.simulator import Simulator
from .fit import FIT_TOL, MAX_NFEV, PRIOR_WEIGHT, FitResult, fit
from .points import FAIL_PENALTY, HOLD_TOL_SCALE, Residual, point_sets, held_sets, point_residuals

TARGET_SCALE = 0.2           # the POH's RMSE targets (20 fpm, 10 rpm, 1 point) in shares of their tolerances
REFIT_LEGS = ((1.0, 0.02), (1.0, 0.002))   # the refit starts where the steps stopped: no path of priors
REFIT_TOL = 1e-3            # its legs stop at a step gaining < 0.1 %, or a step or gradient that small (at fit.FIT_TOL,
                            # 1e-6: 26 iterations to cost 61.81 on every POH point, 15 of them gaining < 0.1 % each;
                            # at 1e-3: 11 to 61.80, stopped by the step's length)
STEP_PRIOR = 0.1             # stage 2a's steps fit a few factors the trims identify: a weaker pull


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
    legs: tuple[tuple[float, float], ...] | None = None   # the fit's legs (None: fit.LEGS)
    ftol: float = FIT_TOL            # the fit's ftol = xtol = gtol: a leg stops when a step gains less (see fit)


POH_HOLD = (Residual("poh_climb", "subset", "roc_fpm"), Residual("poh_cruise", "subset", "pct_power"),
            Residual("poh_cruise", "subset", "rpm"))       # stage 2b's steps hold the POH predictions
FLIGHT_TEST = tuple(Residual("snapshot", "all", m) for m in ("pitch_deg", "elevator_deg", "aileron_deg",
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
             "snapshots waits for the flap step (the flap moment is not fitted yet)"),
    TrimStep("pfactor", step_factors("pfactor"), (Residual("snapshot", "all", "rudder_deg"),),
             "P-factor (method 3.2.2, eq. 3.41): rudder of all snapshots / 1 deg; the rudder factors are "
             "refitted with K_PF (the control step could not see the thrust-dependent yaw and set them for it)"),
    TrimStep("flaps", step_factors("flaps"),
             (Residual("flap_climb", "all", "roc_fpm"), Residual("snapshot", "flaps", "pitch_deg"),
              Residual("snapshot", "flaps", "elevator_deg")),
             "flap aerodynamics (method 3.2.3): flaps-down climb rate / 100 fpm and pitch / 1 deg, plus the "
             "flaps-down trim elevator / 1 deg (where the flap moment shows most) and a flap-lift factor "
             "(the flaps-down attitude is set by the flap lift, which the method's two factors cannot move)"),
    TrimStep("steady refit", step_factors("steady refit"),
             (Residual("poh_climb", "all", "roc_fpm", TARGET_SCALE),
              Residual("poh_cruise", "all", "pct_power", TARGET_SCALE),
              Residual("poh_cruise", "all", "rpm", TARGET_SCALE), Residual("poh_cruise", "all", "gph"))
             + FLIGHT_TEST,
             "stage 1's factors and those of the control, P-factor and flap steps refitted jointly to every kind "
             "of steady data from where the steps left them, on every POH point (the targets judge all 64; fitted on stage "
             "1's 16, the cruise RPM ended 11.0 rpm RMS against its 10): the trims bring drag the POH fit did not see (a 5 deg "
             "climb rudder, the trimmed tail load) and the steps moved the POH predictions (POH climb RMSE 16.8 -> "
             "41 fpm with stage 1 refitted alone, the flight-test trims held); POH climb, cruise power and RPM / "
             "their RMSE targets (20 fpm, 1 point, 10 rpm), fuel flow, snapshots and flap climbs / their "
             "tolerances; the factors are pulled toward their values at the step's start. The pitch step's "
             "factors (static margin, wing angle) stay as it fitted them, and so do the elevator and aileron "
             "power stage 2b refits: refitted here they moved the phugoid period from 1 % to 8.7 % off",
             prior_at_start=True, prior=PRIOR_WEIGHT, legs=REFIT_LEGS, ftol=REFIT_TOL),
)


def fitted_after(step: TrimStep, skipped: set[str]) -> tuple[str, ...]:
    """The step's factors less those that only skipped steps set before it: a step left out
    (``--skip pfactor``) leaves its factors where they were, and the joint refit does not fit
    them in its place."""
    def set_before(name: str) -> tuple[str, ...]:
        steps = REGISTRY[name].steps if name in REGISTRY else ()
        return steps[:steps.index(step.name)] if step.name in steps else ()
    return tuple(n for n in step.factors if not set_before(n) or not set(set_before(n)) <= skipped)


def trims_stage(sim: Simulator, data: dict[str, Dataset], *, start: FactorSet,
                steps: Sequence[TrimStep] = TRIM_STEPS, progress: Callable[[str], None] | None = None,
                max_nfev: int | None = MAX_NFEV, prior: float | None = None,
                after_step: Callable[[TrimStep, FitResult], None] | None = None,
                executor: Executor = SERIAL) -> list[FitResult]:
    """Method stage 2a: the trim steps in order, each from the factors of the last.

    ``data`` maps a kind (``snapshot``, ``flap_climb``, ``poh_climb``, ``poh_cruise``) to
    its dataset; a step whose own residuals have no data is skipped with a note.
    ``after_step`` is called after each fit (for evaluations between steps).
    """
    results = []
    current = start
    skipped = {st.name for st in TRIM_STEPS} - {st.name for st in steps}
    for step in steps:
        step = replace(step, factors=fitted_after(step, skipped))
        sets = point_sets(sim, data, step.residuals)
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
                  prior_center=current if step.prior_at_start else None, legs=step.legs, ftol=step.ftol,
                  executor=executor)
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
