"""Close the loop on time histories: the trim loop's method (:mod:`.closeloop`) on recorded maneuvers.

:func:`close_loop_dynamic` works on recorded tests (:class:`jsbsim_calib.evaluation.evaluate_dynamic.RecordedTest`:
flight-test or synthetic time histories, format 1 through :func:`jsbsim_calib.evaluation.evaluate_dynamic.recorded_test`):

1. fit a constant offset on each replayed surface input of every test (:func:`fit_input_offsets`:
   nuisance parameters for the error of the replay's reference, the input's first sample);
   fly every test on the model (a trim at its start, its inputs replayed) and diagnose the
   residual time history of each response channel (:func:`diagnose_channel`): its constant
   over every test (a sensor's bias, a nuisance set aside), trend, the states and inputs it
   follows, against a noise estimate from its second differences (a smooth model error nearly
   cancels there, sensor noise does not). A channel is structured when its residual beyond
   that bias and noise is material (a quarter of its scale,
   :data:`jsbsim_calib.evaluation.evaluate_dynamic.CHANNEL_SCALES`) and more than the noise could give (a
   chi-square test), over every test or, for a body rate, over the tests that move its axis's
   surface (:func:`excites`: the steady tests dilute a moment the maneuvers show); an axis
   (:data:`jsbsim_calib.evaluation.evaluate_dynamic.AXIS_CHANNELS`) when one of its channels is;
2. screen the candidates of the most structured axis by equation error (:func:`screen`,
   :mod:`.equation_error`: the model's moment at every recorded state against the moment
   the recorded motion needs; no flight): the library effects acting on it, the stage-2b
   factors of the axis, its moment of inertia and the dictionary's terms (rates times states,
   alpha-dot, deflections times states). The :data:`FINALISTS` strongest named candidates are
   flown with the strongest single term not of a factor's form (a control power or a damping
   that varies with a state, an effect in no library); the sparse selection of terms (one
   synthesized effect; a single term of a factor's form is that factor) is flown only when none
   of those passes. When nothing of the axis passes, the round screens the next structured
   axis (:func:`screen_order`): a yaw effect also rolls the aircraft, and may leave roll a
   little more structured than yaw. Each finalist
   (:class:`Change`: an effect or term added, a factor refitted alone, an inertia scaled)
   is fitted alone on all the tests (residuals
   (model - data)/scale at every recorded sample of every response channel; the fit flies the
   tests its factors move and predicts the others to first order, :meth:`TimeHistoryEvidence.focused`)
   and scored on all of them, flown, with
   the trim loop's rules (:func:`.closeloop.evidence_failures`,
   :func:`.closeloop.pays_off_out_of_sample`): BIC change <= -10 with each channel's residuals
   scaled by its noise, at least 60 % of the structured residual of the channels it moves
   explained (net of what it spoils elsewhere), a material change of some sample, and a 10 %
   gain in cross-validation whose folds are whole maneuvers (:data:`CV_FOLDS`);
3. add the best, fit the inputs' offsets again on the model with it
   (:meth:`TimeHistoryEvidence.rebase`) and the change again alone with them
   (:func:`.loop.fit_again`), refit an added effect's or term's factors with the stage-2b factors of its
   axis (``step_factors("yaw dynamics")`` ...; those it duplicates, ``same_as``, excepted; the
   prior of the stage-2b steps about where they stand; a refitted factor or a scaled inertia
   keeps the value of its own fit), repeat until nothing passes;
4. fly again: before and after per axis and channel, each test with the offsets of the last
   rebase, re-fitted (linearized, as the candidates are judged: :func:`projected`); what is
   still structured is reported with the states it follows, not attributed.

The library: the trim library's effects that add a force or moment (``effects/*.xml``; those
that change only what an instrument shows act on nothing the time histories compare: the
flown states are compared) and the dynamic effects (``effects/dynamic/*.xml``: yaw due to roll
rate, roll due to yaw rate, aileron adverse yaw). These are zero in a steady straight trim,
so the trim loop does not try them. Pitch damping is the calibration factor K_Cmq of stage 2b,
not an effect.

The samples of a time history are correlated: the likelihood behind the BIC change counts
each channel's effective samples (:func:`independent_share`, from the lag-1 autocorrelation of
its residual), not every sample, so the evidence it prints is of the size the explained share
and the cross-validation over whole maneuvers (the tests that decide between effects) imply.
"""
from __future__ import annotations

import copy
import math
import time
from dataclasses import dataclass, field, replace
from functools import partial
from pathlib import Path
from typing import Callable, Mapping, Sequence

import numpy as np
from scipy import stats

from ..data.flighttest import load_control_travel
from ..data.timehistory import CHANNELS, fitted_polyline, noise_sigma
from ..evaluation.evaluate_dynamic import AXIS_CHANNELS, CHANNEL_SCALES, FAIL_RESIDUAL, RecordedTest, load_recorded_tests
from ..evaluation.part60 import INPUT_MOVED
from ..core.errors import CalibError, InputError, Problem
from ..core.executor import SERIAL, Executor
from ..factors import FactorSet, step_factors
from ..jsbsim.simulator import Simulator
from ..jsbsim.trajectory import fly
from ..jsbsim.xml import Tree, parse
from .diagnose import ALPHA, Correlate
from .effects import LIBRARY_DIR, Effect, library
from .equation_error import Column, Ranked, effect_columns, equation_error, explained_rows, factor_columns, \
    inertia_columns, rank, term_columns
from .fit import FitResult
from .loop import (CANDIDATE_LEGS, MATERIAL, MAX_EFFECTS, LoopResult, NOISE_FLOOR, RULES as LOOP_RULES, Candidate, Change, Round, Rows,
                   cross_validate as loop_cross_validate, run_loop)
from .synthesis import EFFECT_PREFIX, Linearization, Selection, dictionary, select, term_effect
from .terms import SAME_FORM
from .trims import STEP_PRIOR

DYNAMIC_LIBRARY_DIR = LIBRARY_DIR / "dynamic"
CV_FOLDS = 4                 # cross-validation folds (whole maneuvers; fewer with fewer tests)
CANDIDATE_NFEV = 12          # function evaluations of a candidate's fit (from the equation error's estimate)
REFIT_NFEV = 80
MIN_SAMPLES = 10             # samples a channel needs to be diagnosed
MIN_CORRELATION = 0.3        # |r| of a state or input listed as a correlate
# A body rate is also judged over the tests that move its axis: the rates answer a moment within the
# maneuver that excites it, and the steady tests of a campaign dilute that (Cl += K aileron x qbar on
# the Level 5 plan: p 0.235 of its scale over every test, 1.14 over the roll pulse and step). The
# attitudes and the airspeed integrate the rates and carry the replay's drift: the committed model's
# own campaigns (seeds 1-5) reach 0.27 of the pitch scale over the elevator tests, the rates 0.13.
AXIS_RATE = {"roll": "p_deg_s", "pitch": "q_deg_s", "yaw": "r_deg_s"}
RATE_CHANNELS = tuple(AXIS_RATE.values())
AXIS_SURFACE = {"roll": "aileron_deg", "pitch": "elevator_deg", "yaw": "rudder_deg"}
FINALISTS = 3                # named candidates flown per round (the strongest by equation error)
SCREEN_LISTED = 12           # ranked candidates a report lists per round
EE_AXES_OF = {"roll": ("ROLL",), "yaw": ("YAW",), "pitch": ("PITCH",)}   # LIFT: alpha's noise dominates it
AXIS_OF_EE = {"ROLL": "roll", "YAW": "yaw", "PITCH": "pitch", "LIFT": "pitch"}
INERTIA_OF = {"roll": "ixx", "pitch": "iyy", "yaw": "izz"}
# A moment of inertia is fitted on the body rate of its axis: it scales the angular acceleration a
# moment gives and changes no steady state, while the attitudes and the airspeed integrate the
# replay's input errors over the long maneuvers. Iyy x1.6 on the Level 5 campaign (seed 2): fitted on
# every channel 1.525, on the pitch rate 1.582 (docs/benchmarks.md).
INERTIA_RATE = {INERTIA_OF[a]: rate for a, rate in AXIS_RATE.items()}
CHANNEL_AXIS = {c: a for a, chans in AXIS_CHANNELS.items() for c in chans}
MOMENT_AXIS = {"ROLL": "roll", "YAW": "yaw", "SIDE": "yaw", "PITCH": "pitch", "LIFT": "pitch", "DRAG": "pitch"}
COUPLED = {"roll": ("roll", "yaw"), "yaw": ("roll", "yaw"), "pitch": ("pitch",)}
# the trim loop's evidence rules (recorded in the JSON; evidence_failures and
# pays_off_out_of_sample apply them)
RULES = {**LOOP_RULES, "cv_folds": CV_FOLDS}


def _change(m: Mapping[str, np.ndarray], c: str) -> np.ndarray:
    return m[c] - m[c][0]


# the states and inputs a residual is correlated with: changes from the start of each maneuver
# (the trim absorbs constants), model values at the recorded times, JSBSim signs
REGRESSORS: dict[str, tuple[str, Callable]] = {
    "p": ("deg/s", lambda m: _change(m, "p_deg_s")), "q": ("deg/s", lambda m: _change(m, "q_deg_s")),
    "r": ("deg/s", lambda m: _change(m, "r_deg_s")), "alpha": ("deg", lambda m: _change(m, "alpha_deg")),
    "beta": ("deg", lambda m: _change(m, "beta_deg")), "roll": ("deg", lambda m: _change(m, "roll_deg")),
    "aileron": ("deg", lambda m: _change(m, "aileron_deg")), "elevator": ("deg", lambda m: _change(m, "elevator_deg")),
    "rudder": ("deg", lambda m: _change(m, "rudder_deg")), "thrust": ("lbf", lambda m: _change(m, "thrust_lbf")),
    "p x alpha": ("deg2/s", lambda m: _change(m, "p_deg_s") * m["alpha_deg"]),
    "r x alpha": ("deg2/s", lambda m: _change(m, "r_deg_s") * m["alpha_deg"]),
    "aileron x alpha": ("deg2", lambda m: _change(m, "aileron_deg") * m["alpha_deg"]),
}


# --------------------------------------------------------------------------- the library
def dynamic_library() -> dict[str, Effect]:
    """The dynamic effects (``effects/dynamic/*.xml``), by name."""
    return library(DYNAMIC_LIBRARY_DIR)


def default_effects() -> dict[str, Effect]:
    """The candidates of the loop: the trim library and the dynamic effects."""
    return {**library(), **dynamic_library()}


def effect_axis(eff: Effect) -> str | None:
    """The axis (roll, pitch, yaw) of the first force or moment an effect adds; None when it
    adds none (it changes only what an instrument shows)."""
    axes = [MOMENT_AXIS.get(a.get("name", "")) for a in parse(eff.text, str(eff.path)).findall("aerodynamics/axis")]
    return next((a for a in axes if a), None)


def acts_on(eff: Effect) -> tuple[str, ...]:
    """The axes whose channels an effect moves (roll and yaw together: they are coupled)."""
    axis = effect_axis(eff)
    return COUPLED[axis] if axis else ()


def companion_factors(eff: Effect) -> list[str]:
    """The stage-2b factors of the effect's axis (not those it duplicates, ``same_as``)."""
    return TimeHistoryEvidence((), {}).companions(Change.of_effect(eff, axis=effect_axis(eff) or ""))


# --------------------------------------------------------------------------- flying the tests
def response_channels(test: RecordedTest) -> tuple[str, ...]:
    """The response channels a test recorded, in :data:`CHANNEL_SCALES` order."""
    return tuple(c for c in CHANNEL_SCALES if c in test.channels)


@dataclass
class Response:
    """A recorded test flown on a model: the scaled residuals (model - data)/scale, channel
    after channel, and every recorded channel of the model at the test's times (None: the
    test could not be flown; its residuals are then the failure penalty)."""

    test: RecordedTest
    channels: tuple[str, ...]
    scaled: np.ndarray
    model: dict[str, np.ndarray] | None
    failure: str = ""

    def error(self, channel: str) -> np.ndarray:
        """model - data in the channel's units (NaN where not flown)."""
        if self.model is None:
            return np.full(len(self.test.time_s), np.nan)
        return self.model[channel] - self.test.channels[channel]

    def weighted_error(self, channel: str) -> np.ndarray:
        """The error times the test's weight of the channel (:func:`replay_weights`)."""
        return self.error(channel) * self.test.weights.get(channel, 1.0)


def fly_response(sim: Simulator, test: RecordedTest) -> Response:
    chans = response_channels(test)
    try:
        tr = fly(sim, test.maneuver, at=test.time_s)
    except CalibError as exc:
        return Response(test, chans, np.full(len(test.time_s) * len(chans), FAIL_RESIDUAL), None, str(exc))
    r, _ = test.residuals(tr, chans)
    return Response(test, chans, r, tr.at(test.time_s))


def fly_all(sim: Simulator, tests: Sequence[RecordedTest]) -> list[Response]:
    return [fly_response(sim, t) for t in tests]


CHUNK_TESTS = 3              # the loop's flights: tasks of this many tests each


def _fly_fresh(sim: Simulator, warm: dict, tests: Sequence[RecordedTest]) -> tuple[list[Response], dict]:
    """Tests flown in turn from a JSBSim with no history and the trim warm starts ``warm`` (a
    task): their responses and the warm starts they leave."""
    sim.trim_cache = dict(warm)
    sim.fresh()
    return fly_all(sim, tests), sim.trim_cache


def fly_spread(sim: Simulator, tests: Sequence[RecordedTest], executor: Executor = SERIAL) -> list[Response]:
    """Every test flown on the model as ``sim`` stands, in contiguous chunks of
    :data:`CHUNK_TESTS`, each from a JSBSim with no history and the trim warm starts ``sim``
    holds, as independent tasks on ``executor`` (a pool flies one evaluation of the evidence
    on every worker). A flight's last bits depend on the flights the model made before it (the
    trim starts from the state the last one left in JSBSim: 8e-14 in the scaled residuals), so
    the chunks, not the executor, fix that history: the same bits on any executor and any
    number of workers. ``sim`` is left with no history and with the warm starts the chunks
    left, merged in their order."""
    tests = list(tests)
    if not tests:
        return []
    warm = dict(sim.trim_cache)
    chunks = [tests[a:a + CHUNK_TESTS] for a in range(0, len(tests), CHUNK_TESTS)]
    if executor.workers > 1 and len(chunks) > 1:
        done = executor.map(partial(_fly_fresh, sim, warm), chunks)
    else:
        done = [_fly_fresh(sim, warm, c) for c in chunks]
    sim.trim_cache = warm
    for _, left in done:
        sim.trim_cache.update(left)
    sim.fresh()
    return [x for flown, _ in done for x in flown]


def _stack(responses: Sequence[Response]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Scaled residuals, scaled model values (NaN where not flown) and each row's channel ("":
    a test the model could not fly, its failure penalty: no channel's structure)."""
    r, v, ch = [], [], []
    for x in responses:
        n = len(x.test.time_s)
        r.append(x.scaled)
        v += [x.model[c] / CHANNEL_SCALES[c] if x.model is not None else np.full(n, np.nan) for c in x.channels]
        ch.append(np.repeat(np.array(x.channels if x.model is not None else [""] * len(x.channels), dtype=object), n))
    cat = lambda parts: np.concatenate(parts) if parts else np.zeros(0)
    return cat(r), cat(v), cat(ch)


def _per_channel(r: np.ndarray, ch: np.ndarray) -> dict[str, float]:
    return {c: float(np.sum(r[ch == c] ** 2)) for c in dict.fromkeys(ch)}


# --------------------------------------------------------------------------- errors and diagnosis
@dataclass(frozen=True)
class ChannelError:
    """A channel's error over every recorded sample (channel units; NaN samples left out)."""

    channel: str
    axis: str
    n: int
    rms: float
    max_abs: float
    scale: float

    @property
    def rms_in_scales(self) -> float:
        return self.rms / self.scale

    def as_dict(self) -> dict:
        return {"n": self.n, "rms": _js(self.rms), "max_abs": _js(self.max_abs), "scale": self.scale,
                "rms_in_scales": _js(self.rms_in_scales)}


def error_summary(responses: Sequence[Response]) -> dict[str, dict[str, ChannelError]]:
    """axis -> channel -> error over all tests; a test not flown counts as NaN (n counts it,
    rms does not: see ``failed`` in the diagnosis)."""
    out: dict[str, dict[str, ChannelError]] = {}
    for c in CHANNEL_SCALES:
        errs = [x.error(c) for x in responses if c in x.channels]
        if not errs:
            continue
        e = np.concatenate(errs)
        ok = e[np.isfinite(e)]
        rms = float(np.sqrt(np.mean(ok ** 2))) if ok.size else math.nan
        mx = float(np.max(np.abs(ok))) if ok.size else math.nan
        out.setdefault(CHANNEL_AXIS[c], {})[c] = ChannelError(c, CHANNEL_AXIS[c], int(e.size), rms, mx,
                                                              CHANNEL_SCALES[c])
    return out


@dataclass
class ChannelDiagnosis:
    """A channel's residual time history over all tests: is it structure or noise, what does it follow?"""

    channel: str
    axis: str
    n: int
    n_effective: float                 # independent samples (lag-1 autocorrelation), for the p-values of correlates
    scale: float                       # the channel's residual scale [channel units]
    rms: float
    bias: float                        # the constant fitted over every test (a sensor's bias) [channel units]
    trend_per_s: float                 # slope against maneuver time (within each maneuver) [units/s]
    noise: float                       # estimated sensor noise, standard deviation [channel units]
    structured: bool
    reason: str
    correlates: list[Correlate] = field(default_factory=list)
    beyond: float = math.nan           # RMS beyond the bias and the noise [channel units]

    @property
    def metric(self) -> str:
        return self.channel

    def as_dict(self) -> dict:
        return {"channel": self.channel, "axis": self.axis, "n": self.n, "n_effective": _js(self.n_effective),
                "scale": self.scale, "rms": _js(self.rms), "bias": _js(self.bias), "trend_per_s": _js(self.trend_per_s),
                "noise": _js(self.noise), "beyond_bias_and_noise": _js(self.beyond), "structured": self.structured,
                "reason": self.reason, "correlates_with": [c.as_dict() for c in self.correlates]}


def resolution(channel: str) -> float:
    """The standard deviation of the rounding to the written decimals of format 1."""
    return 10.0 ** -CHANNELS[channel].decimals / math.sqrt(12.0) if channel in CHANNELS else 0.0


def noise_estimate(errors: Sequence[np.ndarray], floor: float) -> float:
    """Sensor noise from the second differences of the residuals (within each maneuver):
    white noise of deviation s gives second differences of deviation s sqrt(6); a smooth model
    error nearly cancels (a 0.5 Hz oscillation sampled at 10 Hz keeps a tenth of its
    amplitude). The median absolute value keeps the corners of the inputs out. Never below
    ``floor``; NaN with too few samples."""
    d2 = np.concatenate([np.diff(e, 2) for e in errors if e.size >= 3] or [np.zeros(0)])
    d2 = d2[np.isfinite(d2)]
    if d2.size < MIN_SAMPLES:
        return math.nan
    return max(floor, 1.4826 * float(np.median(np.abs(d2))) / math.sqrt(6.0))


def effective_samples(errors: Sequence[np.ndarray]) -> float:
    """n (1 - rho)/(1 + rho), rho the lag-1 autocorrelation of the residuals (pooled over the
    maneuvers), at least 3."""
    e = np.concatenate(errors)
    m = float(np.mean(e))
    den = float(np.sum((e - m) ** 2))
    num = sum(float(np.sum((x[1:] - m) * (x[:-1] - m))) for x in errors)
    rho = min(0.99, max(0.0, num / den)) if den > 0 else 0.0
    return max(3.0, e.size * (1.0 - rho) / (1.0 + rho))


def trend(errors: Sequence[np.ndarray], times: Sequence[np.ndarray]) -> float:
    """Slope of the residual against time within each maneuver (pooled)."""
    num = sum(float(np.sum((t - t.mean()) * (e - e.mean()))) for e, t in zip(errors, times))
    den = sum(float(np.sum((t - t.mean()) ** 2)) for t in times)
    return num / den if den > 0 else math.nan


def correlates(e: np.ndarray, X: Mapping[str, np.ndarray], n_effective: float) -> list[Correlate]:
    """The states and inputs the residual follows (|r| >= :data:`MIN_CORRELATION`), strongest
    first; p-values of the F-test on the effective number of samples."""
    out = []
    for name, x in X.items():
        if x.size != e.size or not np.all(np.isfinite(x)) or np.ptp(x) <= 1e-12 or np.ptp(e) <= 0:
            continue
        r = float(np.corrcoef(x, e)[0, 1])
        if abs(r) < MIN_CORRELATION:
            continue
        slope = float(np.polyfit(x, e, 1)[0])
        dof = max(1.0, n_effective - 2.0)
        p = float(stats.f.sf(r * r * dof / max(1.0 - r * r, 1e-12), 1, dof))
        out.append(Correlate(name, r, slope, p))
    return sorted(out, key=lambda c: -abs(c.r))


def _regressors(flown: Sequence[Response]) -> dict[str, np.ndarray]:
    return {k: np.concatenate([f(x.model) for x in flown]) for k, (_, f) in REGRESSORS.items()}


def _verdict(d: ChannelDiagnosis, beyond: float, p_noise: float, unit: str) -> tuple[bool, str]:
    if not math.isfinite(d.noise):
        return False, "noise could not be estimated"
    if not beyond >= MATERIAL * d.scale:
        return False, (f"residual beyond bias and noise {beyond:.3g} {unit} is below {MATERIAL:g} of the scale "
                       f"{d.scale:g} {unit}")
    if not p_noise < ALPHA:
        return False, f"no more than the noise ({d.noise:.3g} {unit}) gives (p = {p_noise:.2g})"
    parts = [f"{beyond:.3g} {unit} beyond bias and noise ({beyond / d.scale:.2f} of the scale)",
             f"bias {d.bias:+.3g}", f"trend {d.trend_per_s:+.3g}/s"]
    if d.correlates:
        c = d.correlates[0]
        parts.append(f"follows {c.regressor} (r = {c.r:+.2f})")
    return True, "; ".join(parts)


def diagnose_channel(channel: str, responses: Sequence[Response]) -> ChannelDiagnosis:
    """The diagnosis of one response channel over the tests that recorded it and flew."""
    flown = [x for x in responses if x.model is not None and channel in x.channels]
    scale, axis, unit = CHANNEL_SCALES[channel], CHANNEL_AXIS[channel], CHANNELS[channel].unit
    errs = [x.weighted_error(channel) for x in flown]
    n = int(sum(e.size for e in errs))
    if n < MIN_SAMPLES:
        return ChannelDiagnosis(channel, axis, n, math.nan, scale, math.nan, math.nan, math.nan, math.nan, False,
                                "too few samples")
    e = np.concatenate(errs)
    w = np.concatenate([np.full(len(x.test.time_s), x.test.weights.get(channel, 1.0)) for x in flown])
    bias = sensor_bias(e, w)
    rest = e - bias * w
    n_eff = effective_samples(errs)
    d = ChannelDiagnosis(channel, axis, n, n_eff, scale, float(np.sqrt(np.mean(e ** 2))), bias,
                         trend(errs, [x.test.time_s for x in flown]), noise_estimate(errs, resolution(channel)),
                         False, "", correlates(e, _regressors(flown), n_eff)[:4])
    d.beyond, p_noise = _beyond_noise(rest, d.noise)
    d.structured, d.reason = _verdict(d, d.beyond, p_noise, unit)
    own = [k for k, x in enumerate(flown) if excites(x.test, axis)] if channel in RATE_CHANNELS else []
    if not d.structured and 0 < len(own) < len(flown):
        ends = np.cumsum([0] + [len(x) for x in errs])
        beyond, p_own = _beyond_noise(np.concatenate([rest[ends[k]:ends[k + 1]] for k in own]), d.noise)
        structured, why = _verdict(d, beyond, p_own, unit)
        if structured:
            ids = ", ".join(flown[k].test.id for k in own)
            d.structured, d.reason = True, f"{why}; over the tests that move its axis ({ids})"
    return d


def _beyond_noise(rest: np.ndarray, noise: float) -> tuple[float, float]:
    """The RMS of a residual beyond the noise, and the chance that the noise alone gives as much
    (chi-square)."""
    if not math.isfinite(noise):
        return math.nan, math.nan
    beyond = math.sqrt(max(0.0, float(np.mean(rest ** 2)) - noise ** 2))
    return beyond, float(stats.chi2.sf(float(np.sum(rest ** 2)) / noise ** 2, rest.size - 1)) if noise > 0 else 0.0


def excites(test: RecordedTest, axis: str) -> bool:
    """The test moves its axis's surface on purpose: an input whose range is over what the Part 60
    report calls moved (:data:`jsbsim_calib.evaluation.part60.INPUT_MOVED`, 0.5 deg; the pilot loops
    of the Level 5 plan move a surface by 0.16 deg at most)."""
    surface = AXIS_SURFACE[axis]
    return any(i.channel == surface and float(np.ptp(np.asarray(i.value, float))) > INPUT_MOVED[surface]
               for i in test.maneuver.inputs)


def sensor_bias(e: np.ndarray, w: np.ndarray) -> float:
    """The constant b whose weighted error ``b w`` fits ``e`` best (a sensor's bias: one
    constant in the channel's units, each test's weight applied); 0 where nothing is weighted."""
    ww = float(w @ w)
    return float(w @ e) / ww if ww > 0 else 0.0


def diagnose_responses(responses: Sequence[Response]) -> dict[str, ChannelDiagnosis]:
    """Every response channel any test recorded."""
    chans = [c for c in CHANNEL_SCALES if any(c in x.channels for x in responses)]
    return {c: diagnose_channel(c, responses) for c in chans}


def structured_axes(diag: Mapping[str, ChannelDiagnosis]) -> tuple[str, ...]:
    return tuple(dict.fromkeys(d.axis for d in diag.values() if d.structured))


def independent_share(d: ChannelDiagnosis) -> float:
    """The share of a channel's samples that are independent (its effective samples, from the
    lag-1 autocorrelation of its residual, over its samples): the samples of a time history are
    correlated, and a likelihood that counts each as independent overstates the evidence by
    the inverse of this share (a BIC change of -45,000 beside 0 % explained)."""
    s = d.n_effective / d.n if d.n else math.nan
    return min(1.0, s) if math.isfinite(s) else 1.0


def noise_in_scales(d: ChannelDiagnosis) -> float:
    """A channel's noise in units of its scale for the likelihood: the estimate, at least
    :data:`~.closeloop.NOISE_FLOOR`; the scale itself where no estimate exists (asks for more
    evidence, never less)."""
    s = d.noise / d.scale
    return max(s, NOISE_FLOOR) if math.isfinite(s) else 1.0


# --------------------------------------------------------------------------- the screen (equation error)
def _columns(current: Simulator, lib: Mapping[str, Effect], axes: Sequence[str]) -> tuple[list[Column], dict]:
    """The candidates of the structured axes as equation-error columns: library effects acting
    on them, the stage-2b factors of those axes, their moments of inertia, and the dictionary's
    terms of their aerodynamic axes (those the aircraft has excepted)."""
    effects = {n: e for n, e in lib.items() if n not in current.effects and set(acts_on(e)) & set(axes)
               and not n.startswith(EFFECT_PREFIX)}
    factors = list(dict.fromkeys(f for a in axes for f in step_factors(f"{a} dynamics")))
    ee_axes = [x for a in axes for x in EE_AXES_OF[a]]
    terms = dictionary(dict.fromkeys(ee_axes), exclude=current.effect_values, dynamic=True)
    inertia = [c for c in inertia_columns() if c.target in {INERTIA_OF[a] for a in axes}]
    return term_columns(terms) + factor_columns(current.factors, factors) + effect_columns(effects) + inertia, effects


def screen_order(diag: Mapping[str, ChannelDiagnosis]) -> tuple[str, ...]:
    """The structured axes, most structured first (RMS beyond noise, in scales, of the axis's
    most structured channel): a missing effect shows most on its own axis, and a screen works
    on one axis. A round screens the next axis when the one before yields nothing: a yaw
    effect that also rolls the aircraft may leave roll a little more structured than yaw."""
    def beyond(d: ChannelDiagnosis) -> float:
        b = d.beyond / d.scale
        return b if math.isfinite(b) else 0.0
    ranked = sorted((d for d in diag.values() if d.structured), key=beyond, reverse=True)
    return tuple(dict.fromkeys(d.axis for d in ranked))


def _on_axes(lin: Linearization, ee_axes: Sequence[str]) -> Linearization:
    keep = [i for i, m in enumerate(lin.metric) if m in ee_axes]
    return Linearization(lin.terms, lin.residual[keep], lin.sensitivity[keep], lin.weight[keep],
                         tuple(lin.group[i] for i in keep), tuple(lin.metric[i] for i in keep), lin.notes)


def _terms_only(lin: Linearization) -> Linearization:
    idx = [j for j, c in enumerate(lin.terms) if c.kind == "term"]
    return Linearization(tuple(lin.terms[j].term for j in idx), lin.residual, lin.sensitivity[:, idx], lin.weight,
                         lin.group, lin.metric, lin.notes)


@dataclass
class Screen:
    """A round's equation-error screen: every candidate ranked, the finalists flown."""

    round: int
    axes: tuple[str, ...]
    rows: int
    ranked: list[Ranked]
    selection: Selection | None
    finalists: list[str]
    wall_time_s: float
    top_term: str = ""           # the strongest single term (not of a factor's form), flown with the named
    explains: dict[str, tuple[np.ndarray, np.ndarray]] = field(default_factory=dict, repr=False)
    # per finalist: what its linearized columns predict of the axis's weighted equation error, and
    # that error (equation_error.explained_rows); the report's residual-against-regressor plot

    def as_dict(self) -> dict:
        return {"round": self.round, "axes": list(self.axes), "rows": self.rows,
                "ranked": [r.as_dict() for r in self.ranked[:SCREEN_LISTED]],
                "selection": self.selection.as_dict() if self.selection else None,
                "finalists": self.finalists, "top_term": self.top_term, "wall_time_s": self.wall_time_s}


def screen(rnd: int, current: Simulator, lib: Mapping[str, Effect], tests,
           axis: str) -> tuple[Screen, list[Change], list[Change]]:
    """Rank every candidate of a structured axis by equation error (module
    :mod:`.equation_error`), then keep the finalists to fly: first the :data:`FINALISTS`
    strongest named candidates (effects, factors, inertias), with the strongest single term
    (:func:`_top_term`); then, if none of those passes, the sparse selection of dictionary terms
    as one synthesized effect (a term of the same form as a factor is that factor)."""
    t0 = time.perf_counter()
    axes = (axis,)
    cols, effects = _columns(current, lib, axes)
    ee_axes = tuple(dict.fromkeys(x for a in axes for x in EE_AXES_OF[a]))
    lin = _on_axes(equation_error(current, tests, cols, effects), ee_axes)
    ranked = rank(lin)
    named = [r for r in ranked if r.kind != "term"][:FINALISTS]
    changes = [_named_change(r, effects) for r in named]
    explains = {c.name: explained_rows(lin, r.columns, r.estimate) for c, r in zip(changes, named)}
    top = _top_term(ranked, lin)
    top_change = _synthesized_change(top, lin, tests, changes) if top is not None else None
    changes += [top_change] if top_change is not None else []
    first, then = list({c.name: c for c in changes}.values()), []
    sel = select(_terms_only(lin)) if lin.residual.size else None
    chosen = _synthesized_change(sel, lin, tests, first) if sel is not None and sel.terms else None
    if chosen is not None and chosen.name not in {c.name for c in first}:
        (then if chosen.kind == "term" else first).append(chosen)     # a selected factor's form: that factor, named
    for pick, c in ((top, top_change), (sel, chosen)):
        if pick is not None and c is not None and c.name not in explains:
            explains[c.name] = explained_rows(_terms_only(lin), [t.name for t in pick.terms], pick.coefficients)
    return Screen(rnd, tuple(axes), int(lin.residual.size), ranked, sel, [c.name for c in first + then],
                  time.perf_counter() - t0, top_change.name if top_change is not None else "", explains), first, then


def _top_term(ranked: Sequence[Ranked], lin: Linearization) -> Selection | None:
    """The term that explains most alone, of a form no factor has (a single term of a factor's
    form is that factor, a named candidate already): one coefficient, flown with the named
    candidates on equal terms. It may rank below them by equation error and still fit the
    flights better (elevator x qbar ranked 0.42 of the pitch axis against K_Cm_alpha's 0.48,
    and its flight explained 89 % against 70 % for the library's best): the flights judge."""
    terms = {c.name: c.term for c in lin.terms}
    best = next((r for r in ranked if r.kind == "term"
                 and (terms[r.columns[0]].axis, terms[r.columns[0]].regressor) not in SAME_FORM), None)
    if best is None:
        return None
    return Selection((terms[best.columns[0]],), best.estimate, math.nan, math.nan, int(lin.residual.size))



def _named_change(r: Ranked, effects: Mapping[str, Effect]) -> Change:
    start = tuple((c.split(":", 1)[1], float(x)) for c, x in zip(r.columns, r.estimate))
    if r.kind == "effect":
        return replace(Change.of_effect(effects[r.target], axis=effect_axis(effects[r.target]) or ""), start=start)
    axis = AXIS_OF_EE[r.axes[0]] if r.kind == "factor" else next(a for a, i in INERTIA_OF.items() if i == r.target)
    if r.kind == "factor":
        axis = next((a for a in ("roll", "pitch", "yaw") if r.target in step_factors(f"{a} dynamics")), axis)
    return Change(f"{r.kind} {r.target}", r.kind, axis, target=r.target, start=start)


def _synthesized_change(sel: Selection, lin: Linearization, tests, named: list[Change]) -> Change | None:
    """The selected terms as an effect; a single term of the same form as a factor is that
    factor (already a finalist, or added as one)."""
    if len(sel.terms) == 1 and SAME_FORM.get((sel.terms[0].axis, sel.terms[0].regressor)):
        f = SAME_FORM[(sel.terms[0].axis, sel.terms[0].regressor)][0]
        axis = next((a for a in ("roll", "pitch", "yaw") if f in step_factors(f"{a} dynamics")), None)
        if axis is None:
            return None
        return Change(f"factor {f}", "factor", axis, target=f, start=((f, _factor_units(f, sel)),))
    moved = tuple(dict.fromkeys(AXIS_OF_EE[t.axis] for t in sel.terms))
    eff = term_effect(sel.terms, sel.coefficients, source=f"{len(tests)} time histories (equation error)",
                      affects=[c for a in moved for c in AXIS_CHANNELS[a]])
    return Change(eff.name, "term", moved[0], eff,
                  start=tuple((eff.label(f), k) for f, k in zip(eff.factors, sel.coefficients)))


def _factor_units(name: str, sel: Selection) -> float:
    """A single selected term's coefficient in its factor's units: the factors of
    :data:`~.terms.SAME_FORM` add ``K x`` (K_Cm_alpha) or subtract it (the damping factors,
    ``-K x``; K_cm_offset and the slopes: no estimate, 0)."""
    k = sel.coefficients[0]
    return {"K_Cm_alpha": k, "K_Cmq": -k, "K_Clp": -k, "K_Cnr": -k}.get(name, 0.0)


def maneuver_folds(n_tests: int, folds: int = CV_FOLDS) -> list[list[int]]:
    """Cross-validation folds of whole maneuvers: test i in fold i mod k (k = min(folds, tests))."""
    k = min(folds, n_tests)
    return [[i for i in range(n_tests) if i % k == f] for f in range(k)]


def cross_validate(current: Simulator, ch: Change | Effect, factors: FactorSet, tests: Sequence[RecordedTest]) -> float:
    """Residual sum of squares of every maneuver predicted by a fit of the change that did not
    see it; NaN with fewer than two maneuvers (nothing to predict from)."""
    ch = Change.of_effect(ch, axis=effect_axis(ch) or "") if isinstance(ch, Effect) else ch
    return loop_cross_validate(TimeHistoryEvidence(tests, {}), current, ch, factors)


# --------------------------------------------------------------------------- the result and the loop
@dataclass
class CloseLoopDynamicResult(LoopResult):
    """What the loop found on the time histories and the aircraft it ends with (as a parsed
    file and its factors, the added effects' own included; :meth:`simulator` flies it)."""

    aircraft: str
    root: Path
    tests: list[RecordedTest]
    before: list[Response]
    after: list[Response]
    diagnosis_before: dict[str, ChannelDiagnosis]
    diagnosis_after: dict[str, ChannelDiagnosis]
    candidates: list[Candidate]
    added: list[str]
    refits: list[FitResult]
    factors: FactorSet
    aircraft_tree: Tree
    wall_time_s: float
    notes: list[str] = field(default_factory=list)
    screens: list[Screen] = field(default_factory=list)
    input_offsets: dict[str, dict[str, float]] = field(default_factory=dict)   # test -> surface -> deg (nuisance)

    def errors(self, which: str) -> dict[str, dict[str, ChannelError]]:
        """'before' or 'after': axis -> channel -> error over all tests."""
        return error_summary({"before": self.before, "after": self.after}[which])

    def to_json(self) -> dict:
        errs = {w: {a: {c: e.as_dict() for c, e in chans.items()} for a, chans in self.errors(w).items()}
                for w in ("before", "after")}
        return {"aircraft": self.aircraft, "tests": [_test_dict(r) for r in self.before],
                "before": errs["before"], "candidates": [c.as_dict() for c in self.candidates], "added": self.added,
                "after": errs["after"], "unexplained": [u.as_dict() for u in self.unexplained()],
                "diagnosis_before": {c: d.as_dict() for c, d in self.diagnosis_before.items()},
                "diagnosis_after": {c: d.as_dict() for c, d in self.diagnosis_after.items()},
                "factors": {n: self.factors[n] for n in self.factors.extra},
                "refits": [r.summary() for r in self.refits], "rules": RULES, "notes": self.notes,
                "screens": [x.as_dict() for x in self.screens], "input_offsets_deg": self.input_offsets,
                "wall_time_s": self.wall_time_s}


def _test_dict(r: Response) -> dict:
    t = r.test
    return {"id": t.id, "kind": t.kind, "samples": int(len(t.time_s)), "duration_s": float(t.time_s[-1]),
            "channels": list(r.channels), "failure": r.failure or None}


def _js(x):
    return None if x is None or not math.isfinite(x) else float(x)


def check_tests(tests: Sequence[RecordedTest]) -> None:
    """At least one test, unique ids, each with samples and a response channel."""
    problems = [Problem(t.id, "no response channel (" + ", ".join(CHANNEL_SCALES) + ")")
                for t in tests if not response_channels(t)]
    problems += [Problem(t.id, f"{len(t.time_s)} samples (needs at least 3)") for t in tests if len(t.time_s) < 3]
    ids = [t.id for t in tests]
    problems += [Problem(i, "test id given more than once") for i in dict.fromkeys(ids) if ids.count(i) > 1]
    if not tests:
        problems.append(Problem("", "no recorded test given"))
    if problems:
        raise InputError("recorded tests", problems)


# --------------------------------------------------------------------------- the inputs' offsets (nuisance)
OFFSET_CHANNELS = ("elevator_deg", "aileron_deg", "rudder_deg")
OFFSET_BOUND_DEG = 1.0       # an offset is the reference's error, not a control input
OFFSET_SIGMAS = 3.0          # ... within this many of the input's own noise (a noiseless input gets none)
OFFSET_STEP_DEG = 0.05       # finite-difference step of the offsets' Jacobian
OFFSET_ITERATIONS = 3


def with_offsets(test: RecordedTest, offsets: Mapping[str, float]) -> RecordedTest:
    """The test with a constant added to each of its replayed surface inputs [deg]."""
    inputs = tuple(replace(i, value=tuple(v + offsets[i.channel] for v in i.value)) if i.channel in offsets else i
                   for i in test.maneuver.inputs)
    return replace(test, maneuver=replace(test.maneuver, inputs=inputs))


def offset_bounds(tests: Sequence[RecordedTest]) -> list[dict[str, float]]:
    """Per test, how far each replayed surface input's offset may go: :data:`OFFSET_SIGMAS` of
    the input's noise (:func:`~jsbsim_calib.data.timehistory.noise_sigma` of its recorded samples), at most
    :data:`OFFSET_BOUND_DEG`; an input without noise has no offset."""
    out = []
    for t in tests:
        b = {i.channel: min(OFFSET_BOUND_DEG, OFFSET_SIGMAS * noise_sigma(np.asarray(t.record.get(i.channel, ()), float)))
             for i in t.maneuver.inputs if i.channel in OFFSET_CHANNELS}
        out.append({c: v for c, v in b.items() if v > 0})
    return out


def _offset_jacobians(sim: Simulator, tests: Sequence[RecordedTest], offsets: Sequence[Mapping[str, float]],
                      executor: Executor = SERIAL):
    """Each test flown at its offsets, and the change of its scaled residuals per degree of each
    of its offsets (None: no offset). A test's offsets move only its own residuals, so one
    flight of each test per surface it has an offset on gives every Jacobian."""
    steps = [(k, c) for k, o in enumerate(offsets) for c in OFFSET_CHANNELS if c in o]
    flown = fly_spread(sim, [with_offsets(t, o) for t, o in zip(tests, offsets)] + [
        with_offsets(tests[k], {**offsets[k], c: offsets[k][c] + OFFSET_STEP_DEG}) for k, c in steps], executor)
    base, flown = flown[:len(tests)], flown[len(tests):]
    moved = {step: (x.scaled - base[step[0]].scaled) / OFFSET_STEP_DEG for step, x in zip(steps, flown)}
    return base, [np.column_stack([moved[k, c] for c in o]) if o else None for k, o in enumerate(offsets)]


def fit_input_offsets(sim: Simulator, tests: Sequence[RecordedTest], executor: Executor = SERIAL,
                      start: Sequence[Mapping[str, float]] | None = None) -> list[dict[str, float]]:
    """Per test, a constant offset on each replayed surface input, fitted to its response by
    Gauss-Newton (nuisance parameters, as output-error identification fits biases). A replay
    takes each input as a change from its first sample, so that sample's noise offsets the
    whole input, and the start's noise (airspeed, attitude) leaves the trimmed surfaces a
    little off what the pilot held. Open loop, such an offset drifts the response over a long
    maneuver by more than a missing effect moves it: the model flying its own Level 5 campaign
    showed roll, pitch and airspeed structured before, none after. Each offset stays within
    :func:`offset_bounds`, so that it cannot stand in for a missing effect; each test keeps
    the offsets of its lowest cost. The candidates then see the offsets' directions projected
    out (:func:`offset_bases`), and the loop fits them again on the model with each change it
    adds (:meth:`TimeHistoryEvidence.rebase`, from ``start``: the offsets fitted before):
    fitted once, on the model before any change, they would keep what they took up of a
    missing effect."""
    bounds = offset_bounds(tests)
    which = [k for k, b in enumerate(bounds) if b]          # a test without offsets is not flown here
    first = [{c: (start[k] if start else {}).get(c, 0.0) for c in bounds[k]} for k in which]
    fitted = dict(zip(which, _fitted_offsets(sim, [tests[k] for k in which], [bounds[k] for k in which],
                                             first, executor)))
    return [fitted.get(k, {}) for k in range(len(tests))]


def _fitted_offsets(sim: Simulator, tests: Sequence[RecordedTest], bounds: Sequence[Mapping[str, float]],
                    first: Sequence[Mapping[str, float]], executor: Executor):
    offsets = [dict(o) for o in first]
    best = [(math.inf, dict(o)) for o in offsets]

    def keep_best(flown):         # per test, the offsets of the lowest cost so far
        return [(c, dict(o)) if (c := float(x.scaled @ x.scaled)) < b[0] else b for x, o, b in zip(flown, offsets, best)]

    for it in range(OFFSET_ITERATIONS):
        base, jac = _offset_jacobians(sim, tests, offsets, executor)
        best = keep_best(base)
        for k, (o, J) in enumerate(zip(offsets, jac)):
            if J is not None and base[k].model is not None:
                step = np.linalg.lstsq(J, -base[k].scaled, rcond=None)[0]
                offsets[k] = {c: float(np.clip(o[c] + dx, -bounds[k][c], bounds[k][c])) for c, dx in zip(o, step)}
    best = keep_best(fly_spread(sim, [with_offsets(t, o) for t, o in zip(tests, offsets)], executor))
    return [b[1] for b in best]


def offset_bases(sim: Simulator, tests: Sequence[RecordedTest], executor: Executor = SERIAL) -> list[np.ndarray | None]:
    """Per test (offsets applied, weights set), an orthonormal basis of the directions its
    offsets move its scaled residuals in (None: no offset, or not flown). Projecting them out
    of a test's residuals re-fits its offsets, linearized, with every candidate: a candidate
    is judged on what no offset explains (variable projection of nuisance parameters)."""
    zero = [dict.fromkeys(b, 0.0) for b in offset_bounds(tests)]
    which = [k for k, o in enumerate(zero) if o]
    base, jac = _offset_jacobians(sim, [tests[k] for k in which], [zero[k] for k in which], executor)
    bases = {k: np.linalg.qr(J)[0] for k, x, J in zip(which, base, jac)
             if x.model is not None and np.all(np.isfinite(J))}
    return [bases.get(k) for k in range(len(tests))]


# --------------------------------------------------------------------------- what the inputs' noise gives
REPLAY_DRAWS = 2             # replays of every test with its inputs' noise redrawn
REPLAY_SEED = 20261


def _on_samples(knots: np.ndarray, t: np.ndarray) -> bool:
    """Breakpoints at the record's sample times, increasing, from its first to its last."""
    return knots.size > 1 and knots[0] == t[0] and knots[-1] == t[-1] and bool(np.all(np.diff(knots) > 0)) \
        and bool(np.isin(knots, t).all())


def _noisy(test: RecordedTest, rng: np.random.Generator) -> RecordedTest:
    """The test with each input's sensor noise drawn again: the recorded samples' noise
    (:func:`~jsbsim_calib.data.timehistory.noise_sigma`, the same level) through the replay's
    least-squares polyline on the input's breakpoints (a constant part is left to the offsets).
    An input whose breakpoints are not the record's sample times (a step where a pilot loop
    takes the axis over), or whose samples the record does not hold, is replayed as it is."""
    t, inputs = np.asarray(test.time_s, float), []
    for i in test.maneuver.inputs:
        x, knots = test.record.get(i.channel), np.asarray(i.time_s, float)
        sigma = noise_sigma(np.asarray(x, float)) if x is not None and len(x) == t.size else 0.0
        if sigma > 0 and _on_samples(knots, t):
            i = replace(i, value=tuple(np.asarray(i.value) + fitted_polyline(t, rng.normal(0.0, sigma, t.size), knots)))
        inputs.append(i)
    return replace(test, maneuver=replace(test.maneuver, inputs=tuple(inputs)))


def replay_weights(sim: Simulator, tests: Sequence[RecordedTest], executor: Executor = SERIAL) -> list[RecordedTest]:
    """Each test with a weight per channel: 1 / sqrt(1 + (spread / scale)^2), the spread the
    RMS change of the model's response when the inputs' own noise is drawn again
    (:data:`REPLAY_DRAWS` replays). A replay feeds the model the recorded inputs as fitted to
    their samples, with what the fit leaves of their noise: where a mode diverges (a spiral
    left to itself) that alone can move the response by more than any model error, and such a
    test must not read as structure; a test whose inputs carry no noise keeps weight 1."""
    rng = np.random.default_rng(REPLAY_SEED)
    noisy = [_noisy(t, rng) for _ in range(REPLAY_DRAWS) for t in tests]
    flown = fly_spread(sim, list(tests) + noisy, executor)
    base = flown[:len(tests)]
    spread = [{c: 0.0 for c in x.channels} for x in base]
    for draw in range(REPLAY_DRAWS):
        for k, x in enumerate(flown[(draw + 1) * len(tests):(draw + 2) * len(tests)]):
            for c in x.channels:
                d = (x.model[c] - base[k].model[c]) if x.model is not None and base[k].model is not None else np.inf
                spread[k][c] += float(np.mean(np.square(d))) / REPLAY_DRAWS
    return [replace(t, weights={c: 1.0 / math.sqrt(1.0 + v / CHANNEL_SCALES[c] ** 2) for c, v in s.items()})
            for t, s in zip(tests, spread)]


def projected(x: Response, Q: np.ndarray | None) -> Response:
    """A flown test less what its input offsets explain (``Q``: :func:`offset_bases`; None:
    none): its scaled residuals projected, and its response channels moved with them (the
    model as it flies with its offsets re-fitted, linearized). The offsets are fitted once, on
    the model before any change; a changed model flown with them would show as structure the
    offsets it needs now would remove. A sample the model did not give (NaN) stays NaN: its
    scaled residual is the failure penalty, not a value of the model."""
    if Q is None or x.model is None:
        return x
    r = x.scaled - Q @ (Q.T @ x.scaled)
    n, model = len(x.test.time_s), dict(x.model)
    for k, c in enumerate(x.channels):
        moved = x.test.channels[c] + r[k * n:(k + 1) * n] * CHANNEL_SCALES[c] / x.test.weights.get(c, 1.0)
        model[c] = np.where(np.isfinite(x.model[c]), moved, np.nan)
    return replace(x, scaled=r, model=model)


FOCUS_SHARE = 1e-2           # a fit flies the tests that carry all but this share of a factor's sensitivity
FOCUS_STEP = 0.02            # the step (normalized factor) of the sensitivities that choose them


def sensitive(slopes: Sequence[Sequence[np.ndarray | None]]) -> set[int]:
    """The tests to fly (indices into ``slopes``: per test, a slope per factor, None where a
    flight failed): those that failed, and for each factor the fewest that carry all but
    :data:`FOCUS_SHARE` of its squared slopes, largest first."""
    keep = {j for j, s in enumerate(slopes) if any(c is None for c in s)}
    for k in range(len(slopes[0]) if slopes else 0):
        energy = np.array([0.0 if j in keep else float(s[k] @ s[k]) for j, s in enumerate(slopes)])
        order = np.argsort(-energy, kind="stable")
        covered = np.cumsum(energy[order]) < (1.0 - FOCUS_SHARE) * energy.sum()
        keep |= {int(order[j]) for j in range(len(order)) if j == 0 or covered[j - 1]}
    return keep


@dataclass(frozen=True)
class Linearized:
    """A test's projected response about a fit's start, to first order in the fit's factors."""

    at: Response
    names: tuple[str, ...]
    start: np.ndarray            # the factors' values at the start
    slopes: np.ndarray           # d scaled residual / d value, a column per factor

    def response(self, factors: FactorSet) -> Response:
        dx = np.array([factors[n] for n in self.names]) - self.start
        return replace(self.at, scaled=self.at.scaled + self.slopes @ dx)


class TimeHistoryEvidence:
    """Recorded maneuvers as evidence for the loop (:mod:`.loop`): a row per response channel
    and recorded sample, (model - data)/scale; every maneuver fitted, cross-validation over
    folds of whole maneuvers; the candidates: the finalists of the equation-error screen of the
    most structured axis (:func:`screen`), its synthesized terms when no named one passes; then,
    if none passes, those of the next structured axis (:func:`screen_order`)."""

    kind = "time histories"

    def __init__(self, tests: Sequence[RecordedTest], lib: dict[str, Effect], executor: Executor = SERIAL,
                 bases: Sequence[np.ndarray | None] | None = None,
                 offsets: Sequence[Mapping[str, float]] | None = None):
        self.raw, self.lib, self.executor = list(tests), lib, executor        # as recorded, weights set
        self.offsets = [dict(o) for o in offsets] if offsets is not None else [{} for _ in self.raw]
        self.tests = [with_offsets(t, o) for t, o in zip(self.raw, self.offsets)]       # as flown
        self.bases = list(bases) if bases is not None else [None] * len(self.tests)   # offset_bases()
        self.screens: list[Screen] = []
        self._terms: list[Change] = []
        self.linear: dict[int, Linearized] = {}         # tests predicted, not flown (focused())
        self.focus: tuple = ()                          # focused(): (factors, their values, the part)

    def __getstate__(self) -> dict:
        """Pickled (a task's copy): the evidence without its executor (a task runs its own work here)
        and without the screens' records (the report's, not a task's)."""
        return {**self.__dict__, "executor": SERIAL, "screens": []}

    def rows(self, sim: Simulator, part) -> Rows:
        flown = self._flown(sim, part)
        r, v, ch = _stack(flown)
        B = self._bias_columns(part, flown)
        r = r - B @ np.linalg.lstsq(B, r, rcond=None)[0] if B.size else r
        labels = [f"{self.tests[i].id} {c} t={s:.2f}" for i in part for c in response_channels(self.tests[i])
                  for s in self.tests[i].time_s]
        return Rows(r, ch, v, labels)

    def _projected(self, i: int, x: Response) -> Response:
        return projected(x, self.bases[i])

    def _flown(self, sim: Simulator, part) -> list[Response]:
        """The tests of ``part`` on the model as ``sim`` stands, projected: flown, or predicted
        to first order where :meth:`focused` linearized them."""
        flights = iter(fly_spread(sim, [self.tests[i] for i in part if i not in self.linear], self.executor))
        return [self.linear[i].response(sim.factors) if i in self.linear else self._projected(i, next(flights))
                for i in part]

    def focused(self, sim: Simulator, part, names: Sequence[str]) -> "TimeHistoryEvidence":
        """A copy for a fit of ``names`` from the factors ``sim`` holds: it flies only the tests
        of ``part`` that carry all but :data:`FOCUS_SHARE` of some factor's sensitivity (its
        squared residual slopes) and predicts the others to first order about the start, from
        their flights there and one step away (k + 1 flights of the part). A pitch factor
        leaves the lateral maneuvers and the trims in a line: a fit of K_Cmq on the Level 5
        campaign flew 4 of its 20 tests (before its two more pitch pulses). The caller's trim
        warm starts and factors are kept. A copy focused on the same factors at the same values
        over a part that holds ``part`` is its own focus (a fold's fit: :func:`.loop.focus_of`)."""
        names = list(names)
        if not names or len(part) < 2:
            return self
        start, warm = sim.factors, dict(sim.trim_cache)
        x0 = start.vector(names)
        key = (tuple(names), x0.tobytes())
        if self.focus[:2] == key and set(part) <= self.focus[2]:
            return self

        def flown_at(x: np.ndarray) -> list[Response]:
            sim.trim_cache = dict(warm)
            if not sim.set_factors(start.with_vector(names, x)):
                sim.fresh()
            return self._flown(sim, part)

        at = flown_at(x0)
        slopes = [[] for _ in part]
        for k in range(len(names)):
            x = np.array(x0, float)
            x[k] += FOCUS_STEP if x0[k] + FOCUS_STEP <= 1.0 else -FOCUS_STEP
            moved = flown_at(x)
            dv = start.with_vector(names, x)[names[k]] - start[names[k]]
            for j, (a, b) in enumerate(zip(at, moved)):
                slopes[j].append(None if a.model is None or b.model is None else (b.scaled - a.scaled) / dv)
        sim.trim_cache = warm                                  # the caller's model and warm starts again
        if not sim.set_factors(start):
            sim.fresh()
        keep = sensitive(slopes)
        out = copy.copy(self)
        out.focus = (*key, frozenset(part))
        out.linear = {**self.linear, **{i: Linearized(at[j], tuple(names), start.vector(names, normalized=False),
                                                       np.column_stack(slopes[j]))
                                        for j, i in enumerate(part) if j not in keep}}
        return out

    def _bias_columns(self, part, flown: Sequence[Response]) -> np.ndarray:
        """A column per response channel: what a constant sensor bias of one scale does to the
        stacked residuals of the flown tests (the same constant in every test, each test's
        weight applied; a failed test: none), less what the offsets explain. Projected out of
        the rows with the offsets' directions (a joint projection, Frisch-Waugh), the biases
        are nuisance parameters refitted with every candidate, as the offsets are."""
        chans = [c for c in CHANNEL_SCALES if any(c in x.channels for x in flown if x.model is not None)]
        blocks = []
        for i, x in zip(part, flown):
            n = len(x.test.time_s)
            block = np.zeros((n * len(x.channels), len(chans)))
            if x.model is not None:
                for k, c in enumerate(x.channels):
                    block[k * n:(k + 1) * n, chans.index(c)] = x.test.weights.get(c, 1.0)
                Q = self.bases[i]
                block = block if Q is None else block - Q @ (Q.T @ block)
            blocks.append(block)
        return np.concatenate(blocks) if blocks else np.zeros((0, 0))

    def diagnose(self, sim: Simulator) -> dict[str, ChannelDiagnosis]:
        return diagnose_responses([self._projected(i, x) for i, x in enumerate(fly_spread(sim, self.tests, self.executor))])

    def noise(self, d: ChannelDiagnosis) -> float:
        return noise_in_scales(d)

    def independent_share(self, d: ChannelDiagnosis) -> float:
        return independent_share(d)

    def parts(self) -> tuple[list[int], list[int]]:
        return list(range(len(self.tests))), []

    def folds(self) -> list[tuple[list[int], list[int]]]:
        every = range(len(self.tests))
        return [([i for i in every if i not in held], held) for held in maneuver_folds(len(self.tests))]

    def moves(self, ch: Change) -> tuple[str, ...]:
        return tuple(c for c in CHANNEL_SCALES if CHANNEL_AXIS[c] in COUPLED.get(ch.axis, ()))

    def fitted_on(self, ch: Change) -> tuple[str, ...]:
        """An inertia on the body rate of its axis (:data:`INERTIA_RATE`); every other change
        on every channel."""
        return (INERTIA_RATE[ch.target],) if ch.kind == "inertia" else ()

    def rebase(self, sim: Simulator) -> bool:
        """The inputs' offsets fitted again on the model as it stands (a change just added), from
        where they stood (:func:`fit_input_offsets`), and their directions with them
        (:func:`offset_bases`). Traced on an undeclared Cm += K elevator x qbar (Level 5, seed 1):
        fitted on the model without the term, the pulses' elevator offsets stood at -0.29 to
        -0.32 deg, and kept, they held pitch at 35 % of before. True where a test has offsets
        (the loop then fits the change again: :func:`.loop.fit_again`)."""
        self.offsets = fit_input_offsets(sim, self.raw, self.executor, start=self.offsets)
        self.tests = [with_offsets(t, o) for t, o in zip(self.raw, self.offsets)]
        self.bases = offset_bases(sim, self.tests, self.executor)
        return any(self.offsets)

    def named(self, rnd: int, current: Simulator, diag, factors: FactorSet) -> list[Change]:
        axis = next(a for a in screen_order(diag) if a not in self._screened(rnd))
        scr, first, self._terms = screen(rnd, current, self.lib, self.tests, axis)
        self.screens.append(scr)
        return first

    def _screened(self, rnd: int) -> set[str]:
        return {a for s in self.screens if s.round == rnd for a in s.axes}

    def unscreened(self, rnd: int, diag) -> bool:
        """A structured axis of the round's diagnosis not screened yet (:func:`screen_order`)."""
        return any(a not in self._screened(rnd) for a in screen_order(diag))

    def synthesized(self, rnd: int, current: Simulator, diag, factors: FactorSet, start: Round) -> list[Change]:
        return self._terms

    def companions(self, ch: Change) -> list[str]:
        """The stage-2b factors of an added effect's (or term's) axis, as the trims have them: a
        refitted factor or a scaled inertia adds nothing they could have stood in for."""
        if ch.effect is None or not ch.axis:
            return []
        return [f for f in step_factors(f"{ch.axis} dynamics") if f not in ch.effect.same_as]

    def fit_options(self, what: str) -> dict:
        return {"prior": STEP_PRIOR, "prior_center": None, "legs": CANDIDATE_LEGS, "restarts": 0,
                "max_nfev": CANDIDATE_NFEV if what == "candidate" else REFIT_NFEV}

    def judge(self, ch: Change, cand: Candidate, current: Simulator, factors: FactorSet) -> list[str]:
        return []

    def cross_validate(self, current: Simulator, ch: Change, factors: FactorSet, focus=None) -> float:
        return loop_cross_validate(self, current, ch, factors, focus)


def close_loop_dynamic(sim: Simulator, tests: Sequence[RecordedTest], *, effects: Mapping[str, Effect] | None = None,
                       max_effects: int = MAX_EFFECTS, progress: Callable[[str], None] | None = None,
                       executor: Executor = SERIAL) -> CloseLoopDynamicResult:
    """Close the loop on recorded maneuvers (see the module doc). ``sim`` is left unchanged; the
    result holds the aircraft with the added effects (its file and factors). ``executor``: where
    the candidates' fits, the cross-validation folds, the refits' Jacobians and, in chunks of
    maneuvers, every evaluation made in this process run (the same bits on any: :func:`fly_spread`)."""
    t0 = time.perf_counter()
    say = progress or (lambda s: None)
    tests = list(tests)
    check_tests(tests)
    offsets = fit_input_offsets(sim, tests, executor)
    weighted = replay_weights(sim, [with_offsets(t, o) for t, o in zip(tests, offsets)], executor)
    tests = [replace(t, weights=w.weights) for t, w in zip(tests, weighted)]       # as recorded, weights set
    bases = offset_bases(sim, weighted, executor)
    before = [projected(x, Q) for x, Q in zip(fly_spread(sim, weighted, executor), bases)]
    flying = [k for k, r in enumerate(before) if not r.failure]      # the others carry no structure (notes)
    say("input offsets (per maneuver, deg): " + "; ".join(
        f"{t.id} " + ", ".join(f"{c.split('_')[0]} {v:+.3f}" for c, v in o.items()) for t, o in zip(tests, offsets) if o))
    ev = TimeHistoryEvidence([tests[k] for k in flying], default_effects() if effects is None else dict(effects),
                             executor, [bases[k] for k in flying], [offsets[k] for k in flying])

    def as_left(every: list, loop: list) -> list:      # the loop's value for each test it flew
        out = list(every)
        for j, k in enumerate(flying):
            out[k] = loop[j]
        return out

    def flown(s: Simulator) -> list[Response]:   # every test, its offsets as the loop left them, re-fitted (linearized)
        return [projected(x, Q) for x, Q in zip(fly_spread(s, as_left(weighted, ev.tests), executor),
                                                 as_left(bases, ev.bases))]

    diag0 = diagnose_responses(before)
    for c, d in diag0.items():
        say(f"diagnosis {c}: {'STRUCTURED' if d.structured else 'noise'}: {d.reason}")
    run = run_loop(ev, sim, max_effects=max_effects, diagnosis=diag0, final=flown, progress=say)
    notes = [f"{r.test.id}: not flown ({r.failure}); set aside: the candidates are fitted and cross-validated on the "
             "maneuvers the model flies" for r in before if r.failure]
    return CloseLoopDynamicResult(sim.name, sim.root, as_left(weighted, ev.tests), before, run.final, diag0,
                                  diagnose_responses(run.final), run.candidates, run.added_names, run.refits,
                                  run.factors, run.tree, time.perf_counter() - t0, notes, ev.screens,
                                  {t.id: o for t, o in zip(tests, as_left(offsets, ev.offsets)) if o})


# --------------------------------------------------------------------------- files
def run_close_loop_dynamic(root: Path | str, name: str, flight_test, *,
                           progress: Callable[[str], None] | None = None,
                           executor: Executor = SERIAL) -> CloseLoopDynamicResult:
    """Close the loop on an aircraft with time histories (directories and/or CSV files of
    format 1; cockpit controls through the aircraft's control-travel table)."""
    with Simulator(Path(root), name) as sim:
        f = sim.geometry.control_travel_file
        tests = load_recorded_tests(flight_test, load_control_travel(f) if f else None)
        res = close_loop_dynamic(sim, tests, progress=progress, executor=executor)
    res.notes.append(f"model: {name}; {len(tests)} time histories: " + ", ".join(f"{t.id} ({t.kind})" for t in tests))
    return res
