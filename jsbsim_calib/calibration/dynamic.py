"""Stage 2b (method 3.3): the damping step, and the pitch axis revisited with the dynamic data.

Each axis is its own fit (a :class:`DynamicStep`: its factors from the registry, the dynamic
tests it flies, the trims it fits or holds). A dynamic metric's residual is (model - flight
test) / tolerance; a "representative" metric (the phugoid's damping) uses
:data:`REPRESENTATIVE_TOL`. A metric that depends on an unrecorded input amplitude (the peak
rate after a pulse) is compared with the amplitude left free within :data:`AMPLITUDE_RANGE`
of the assumed one (the peak rate of a small pulse is proportional to it): it counts only
where no plausible amplitude explains the flight test, and a factor that only such metrics
move is not fitted at all (:func:`identified_by`): the assumption would decide it alone.

The pitch step fits the trims (pitch and elevator of every snapshot, turns included) in the
same least squares as the phugoid and the pulses, with elevator power, a pitch-stiffness
factor and pitch damping: the 1-g trims see only the ratio of elevator power to stiffness,
the turns (elevator per g), the phugoid and the pulses see them apart.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable, Sequence

import numpy as np

from ..data.dynamic_tests import DynamicTest
from ..data.schemas import Dataset
from ..core.errors import CalibError
from ..core.executor import SERIAL, Executor
from ..evaluation.evaluate_dynamic import AXIS_CHANNELS, RecordedTest, fly_test
from ..jsbsim.trajectory import fly
from ..factors import FactorSet, step_factors
from ..jsbsim.simulator import Simulator
from .fit import LEGS, MAX_NFEV, FitResult, fit, sensitivity, unfitted
from .points import FAIL_PENALTY, HOLD_TOL_SCALE, Residual, held_sets, point_residuals, point_sets
from .trims import POH_HOLD, STEP_PRIOR

AMPLITUDE_RANGE = (0.3, 1.5)  # unrecorded amplitude: from 0.3 to 1.5 times the assumed one (10 % to 50 % of travel)
REPRESENTATIVE_TOL = {"phugoid_damping": 0.05}     # "representative damping": a tolerance to weigh it by
IDENTIFIED_SHARE = 0.1        # a factor needs this share of its sensitivity from amplitude-free residuals


@dataclass(frozen=True)
class DynamicStep:
    name: str
    kinds: tuple[str, ...]                 # dynamic test kinds it flies and fits (summaries and recordings)
    trims: tuple[Residual, ...] = ()       # trim residuals it fits (with the dynamic ones)
    hold: tuple[Residual, ...] = ()        # predictions held at the step's start
    doc: str = ""
    names: tuple[str, ...] = ()            # factors, when not the registry's of the step (the joint refit)
    recorded: bool = True                  # flies recorded time histories of its kinds (their channels)

    @property
    def factors(self) -> tuple[str, ...]:
        return self.names or step_factors(self.name)


SNAPSHOT = ("pitch_deg", "elevator_deg", "aileron_deg", "rudder_deg")
DYNAMIC_STEPS: tuple[DynamicStep, ...] = (
    DynamicStep("roll dynamics", ("roll_step", "roll_pulse", "roll_doublet"),
                hold=(Residual("snapshot", "all", "aileron_deg"),),
                doc="roll damping and aileron power: steady roll rate after the wheel steps / 2 deg/s, peak roll "
                    "rate after the pulses (amplitude free within its plausible range); the trim ailerons are held"),
    DynamicStep("pitch dynamics", ("phugoid", "pitch_pulse", "pitch_doublet"),
                trims=(Residual("snapshot", "all", "pitch_deg"), Residual("snapshot", "all", "elevator_deg")),
                hold=POH_HOLD,
                doc="pitch damping, stiffness and elevator power in one least squares: phugoid period / 10 %, "
                    "its damping / 0.05, the pitch attitude and trim elevator of every snapshot (turns included) "
                    "/ 1 deg, peak pitch rate after the pulses (amplitude free within its plausible range); the POH is held"),
    DynamicStep("yaw dynamics", ("yaw_pulse", "rudder_response", "dutch_roll", "yaw_doublet"),
                hold=(Residual("snapshot", "all", "rudder_deg"),),
                doc="yaw damping: peak yaw rate after the pedal pulses (amplitude free within its plausible "
                    "range); the trim rudders are held"),
    DynamicStep("engine dynamics", ("engine_acceleration",), recorded=False,
                doc="rotating inertia of engine and propeller: the RPM's 10-90 % response time after the throttle "
                    "step (1.f.1) / 1 s, from the middle of the FAA's alternative data (2-4 s); recorded time "
                    "histories hold no RPM channel, so only the summary test is flown"),
)


def amplitude_scale(model: float, measured: float) -> float:
    """The share of the assumed amplitude that best explains the flight test, within
    :data:`AMPLITUDE_RANGE` (a response proportional to the amplitude)."""
    if not (math.isfinite(model) and model != 0.0 and math.isfinite(measured)):
        return 1.0
    return min(AMPLITUDE_RANGE[1], max(AMPLITUDE_RANGE[0], measured / model))


def metric_residuals(result) -> tuple[list[float], list[str], list[bool]]:
    """Residuals of one flown test: (model - flight test) / tolerance, an amplitude-dependent
    model value at its best plausible amplitude; labels; whether each depends on an assumed
    amplitude. A test that could not be flown gives the failure penalty (never NaN)."""
    res, lab, amp = [], [], []
    for m in result.metrics:
        tol = m.metric.tol() if m.metric.tolerance is not None else REPRESENTATIVE_TOL.get(m.metric.name, math.nan)
        if not (math.isfinite(tol) and tol > 0):
            continue
        model = m.model * (amplitude_scale(m.model, m.metric.measured) if m.metric.amplitude_dependent else 1.0)
        r = (model - m.metric.measured) / tol
        res.append(r if math.isfinite(r) else FAIL_PENALTY)
        lab.append(f"{m.test} {m.metric.name}")
        amp.append(m.metric.amplitude_dependent)
    return res, lab, amp


def identified_by(jac: np.ndarray, kind_of_row: np.ndarray, names: Sequence[str]) -> tuple[list[str], list[str]]:
    """Factors whose sensitivity (sum of squared Jacobian entries over the fitted residuals)
    comes at least :data:`IDENTIFIED_SHARE` from amplitude-free ones, and those that do not.
    ``kind_of_row``: 'free', 'amplitude' or 'held' (held predictions are constraints, not
    information)."""
    keep, drop = [], []
    for j, n in enumerate(names):
        col = jac[:, j] ** 2
        total = math.fsum(col[kind_of_row != "held"].tolist())
        free = math.fsum(col[kind_of_row == "free"].tolist())
        (keep if total > 0 and free >= IDENTIFIED_SHARE * total else drop).append(n)
    return keep, drop


def step_axis(step_name: str) -> str:
    return step_name.split()[0]


COUPLED_AXES = ("roll", "yaw")       # the lateral-directional axes: refitted together


def refit_step(steps: Sequence[DynamicStep], fitted: Sequence[FitResult]) -> DynamicStep | None:
    """The coupled axes together, their fitted factors from where the axis fits left them: a
    yaw-damping error shows in the roll response and a roll-damping error in the yaw
    response, so the axis fits, run one after the other, leave each other's errors in their
    factors. None when fewer than two of them fitted anything (the pitch axis is decoupled)."""
    steps = [s for s in steps if step_axis(s.name) in COUPLED_AXES]
    done = [r for r in fitted if step_axis(r.stage) in COUPLED_AXES and r.message != "nothing fitted"]
    if len(done) < 2:
        return None
    names = tuple(dict.fromkeys(n for r in done for n in r.names))
    return DynamicStep("lateral refit", tuple(k for s in steps for k in s.kinds),
                       tuple(dict.fromkeys(t for s in steps for t in s.trims)),
                       tuple(dict.fromkeys(h for s in steps for h in s.hold if h not in
                                           {t for s2 in steps for t in s2.trims})),
                       "the roll and yaw factors together on all their tests (the two axes are coupled)", names)


def _residual_function(sim: Simulator, tests: Sequence, sets, held, step_name: str):
    """(factors -> residuals, labels) of a step, and a mask of its amplitude-dependent rows."""
    amp_mask: list[bool] = []

    def residuals(fs: FactorSet):
        sim.set_factors(fs)
        res, lab, amp, failed = [], [], [], 0
        for test in tests:
            if isinstance(test, RecordedTest):
                axis = step_axis(step_name)
                channels = AXIS_CHANNELS.get(axis) or tuple(c for a in AXIS_CHANNELS.values() for c in a)
                try:
                    r, l = test.residuals(fly(sim, test.maneuver), channels)
                    r = list(r)
                except CalibError:
                    r, l = [FAIL_PENALTY], [f"{test.id}: not flown"]
                a = [False] * len(r)
            else:
                r, l, a = metric_residuals(fly_test(sim, test))
            res += r
            lab += l
            amp += ["amplitude" if x else "free" for x in a]
        for ps, scale in [(p, 1.0) for p in sets] + [(p, HOLD_TOL_SCALE) for p in held]:
            r, l, f = point_residuals(sim, ps, ps.metrics, tol_scale=scale)
            res += r
            lab += l
            amp += ["free" if scale == 1.0 else "held"] * len(r)
            failed += f
        amp_mask[:] = amp + ["free"]
        return np.array(res + [FAIL_PENALTY * failed]), lab + ["trim failures"]

    return residuals, amp_mask


def dynamic_step(sim: Simulator, step: DynamicStep, tests: Sequence[DynamicTest | RecordedTest],
                 data: dict[str, Dataset],
                 start: FactorSet, *, progress: Callable[[str], None] | None = None,
                 max_nfev: int | None = MAX_NFEV, executor: Executor = SERIAL) -> FitResult | None:
    """One axis: fit the step's identified factors; None when it has no test to fly."""
    mine = [t for t in tests if t.kind in step.kinds and (step.recorded or not isinstance(t, RecordedTest))]
    if not mine:
        return None
    sim.set_factors(start)
    sets = point_sets(sim, data, step.trims)
    held = held_sets(sim, data, step.hold)
    residuals, amp_mask = _residual_function(sim, mine, sets, held, step.name)
    names = list(step.factors)
    jac = sensitivity(residuals, start, names)
    keep, drop = identified_by(jac, np.array(amp_mask), names)
    if keep:
        out = fit(step.name, keep, start, residuals, sim=sim, progress=progress, max_nfev=max_nfev,
                  prior=STEP_PRIOR, prior_center=start, legs=LEGS[-2:], executor=executor)
    else:                                      # nothing identified: the factors stay where they were
        out = unfitted(step.name, names, start, residuals, sim)
        out.notes.append("no factor identified without the assumed input amplitudes: nothing fitted")
    out.notes.append(step.doc)
    out.notes.append("flown: " + ", ".join(f"{t.id} ({t.kind})" for t in mine))
    for n in drop:
        out.notes.append(f"{n} not fitted: only metrics that depend on an assumed input amplitude move it "
                         f"(less than {IDENTIFIED_SHARE:.0%} of its sensitivity from the others)")
    return out


def dynamic_stage(sim: Simulator, tests: Sequence[DynamicTest | RecordedTest], data: dict[str, Dataset], *,
                  start: FactorSet,
                  steps: Sequence[DynamicStep] = DYNAMIC_STEPS, progress: Callable[[str], None] | None = None,
                  after_step: Callable[[DynamicStep, FitResult], None] | None = None,
                  executor: Executor = SERIAL, max_nfev: int | None = MAX_NFEV) -> list[FitResult]:
    """Stage 2b: the dynamic steps in order, each from the factors of the last."""
    results, current = [], start
    for step in steps:
        out = dynamic_step(sim, step, tests, data, current, progress=progress, executor=executor, max_nfev=max_nfev)
        if out is None:
            if progress:
                progress(f"{step.name}: no dynamic test of kinds {', '.join(step.kinds)}, skipped")
            continue
        results.append(out)
        current = out.final
        sim.set_factors(current)
        if after_step:
            after_step(step, out)
    joint = refit_step(steps, results)
    if joint is not None:
        out = dynamic_step(sim, joint, tests, data, current, progress=progress, executor=executor, max_nfev=max_nfev)
        if out is not None:
            results.append(out)
            sim.set_factors(out.final)
            if after_step:
                after_step(joint, out)
    return results
