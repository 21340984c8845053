"""Stage 1 (method 3.1): the 16 coupled aerodynamic, propeller and engine factors on a
documented subset of POH climb and cruise points (climb error / 100 fpm, power / 5 points,
RPM / 50 rpm; a penalty per point for more than full throttle, 20 per failed trim), then the
fuel-flow factor alone against fuel flow (error / 5 %). The factors come from the registry
(their steps ``steady`` and ``fuel flow``)."""
from __future__ import annotations

from typing import Callable, Sequence

import numpy as np

from ..core.executor import SERIAL, Executor
from ..data.schemas import Dataset
from ..factors import SWITCHES, FactorSet, set_in, step_factors
from ..jsbsim.simulator import Simulator
from .fit import MAX_NFEV, FitResult, fit
from .points import FAIL_PENALTY, PointSet, point_residuals, stage1_subset

STAGE1_STEPS = ("steady", "fuel flow")
STEADY_NAMES = list(step_factors("steady"))


def steady_stage(sim: Simulator, climb: Dataset, cruise: Dataset, *, start: FactorSet | None = None,
                 climb_points: Sequence[int] | None = None, cruise_points: Sequence[int] | None = None,
                 progress: Callable[[str], None] | None = None,
                 max_nfev: int | None = MAX_NFEV, executor: Executor = SERIAL) -> tuple[FitResult, FitResult]:
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

    main = fit("steady", STEADY_NAMES, start, residuals, sim=sim, progress=progress, max_nfev=max_nfev,
               executor=executor)
    main.notes.append(f"fitted points: climb {ci}, cruise {ki} (row indices of {climb.path.name}, {cruise.path.name})")

    def ff_residuals(fs: FactorSet):
        sim.set_factors(fs)
        r, l, f = point_residuals(sim, kps, ("gph",))
        return np.array(r + [FAIL_PENALTY * f]), l + ["trim failures"]

    ff = fit("fuel flow", list(step_factors("fuel flow")), main.final, ff_residuals, sim=sim, progress=progress,
             executor=executor)
    return main, ff


def steady_factors(factors: FactorSet) -> FactorSet:
    """Stage-1 factors and the model switches kept, every later factor neutral: where stage 2a
    starts."""
    stage1 = set(set_in(STAGE1_STEPS)) | set(SWITCHES)
    return FactorSet({k: v for k, v in factors.items() if k in stage1})
