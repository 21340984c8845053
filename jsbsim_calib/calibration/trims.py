"""Stage 2a (method 3.2): the flight-test trim steps in order, each fitting its factors to its
residuals and freezing them. A step is data: its name (the registry's factors of that step are
what it fits), the residuals it fits them to and the ones it holds."""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Sequence

import numpy as np

from ..data.schemas import Dataset
from ..core.executor import SERIAL, Executor
from ..factors import FactorSet, step_factors
from ..jsbsim.simulator import Simulator
from .fit import MAX_NFEV, PRIOR_WEIGHT, FitResult, fit
from .points import FAIL_PENALTY, HOLD_TOL_SCALE, Residual, point_sets, held_sets, point_residuals

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
    for step in steps:
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
                  prior_center=current if step.prior_at_start else None, executor=executor)
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
