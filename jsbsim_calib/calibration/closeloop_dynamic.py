"""Close the loop on time histories: the trim loop's method (:mod:`.closeloop`) on recorded maneuvers.

:func:`close_loop_dynamic` works on recorded tests (:class:`jsbsim_calib.dynamics.RecordedTest`:
flight-test or synthetic time histories, format 1 through :func:`jsbsim_calib.dynamics.recorded_test`):

1. fly every test on the model (a trim at its start, its inputs replayed) and diagnose the
   residual time history of each response channel (:func:`diagnose_channel`): bias, trend,
   the states and inputs it follows, against a noise estimate from its second differences (a
   smooth model error nearly cancels there, sensor noise does not). A channel is structured
   when its residual beyond that noise is material (a quarter of its scale,
   :data:`jsbsim_calib.dynamics.CHANNEL_SCALES`) and more than the noise could give (a
   chi-square test); an axis (:data:`jsbsim_calib.dynamics.AXIS_CHANNELS`) when one of its
   channels is;
2. for every library effect that acts on a structured axis (:func:`effect_axis`: the axis of
   the force or moment it adds; roll and yaw are coupled, so a lateral effect acts on both):
   add it to a copy of the aircraft, fit its factor(s) alone on all the tests (residuals
   (model - data)/scale at every recorded sample of every response channel) and score it with
   the trim loop's rules (:func:`.closeloop.evidence_failures`,
   :func:`.closeloop.pays_off_out_of_sample`): BIC change <= -10 with each channel's residuals
   scaled by its noise, at least 60 % of the structured residual of the channels it moves
   explained (net of what it spoils elsewhere), a material change of some sample, and a 10 %
   gain in cross-validation whose folds are whole maneuvers (:data:`CV_FOLDS`);
3. add the best, refit its factors with the stage-2b factors of its axis
   (``step_factors("yaw dynamics")`` ...; those it duplicates, ``same_as``, excepted; the
   prior of the stage-2b steps about where they stand), repeat until nothing passes;
4. fly again: before and after per axis and channel; what is still structured is reported
   with the states it follows, not attributed.

The library: the trim library's effects that add a force or moment (``effects/*.xml``; those
that change only what an instrument shows act on nothing the time histories compare: the
flown states are compared) and the dynamic effects (``effects/dynamic/*.xml``: yaw due to roll
rate, roll due to yaw rate, aileron adverse yaw). These are zero in a steady straight trim,
so the trim loop does not try them. Pitch damping is the calibration factor K_Cmq of stage 2b,
not an effect.

The samples of a time history are correlated: the likelihood behind the BIC change assumes
white noise of the estimated level, which overstates the evidence wherever the residual stays
structured (the trim loop's likelihood has the same blind spot). The explained share and the
cross-validation over whole maneuvers are the tests that decide between effects.
"""
from __future__ import annotations

import math
import time
from contextlib import ExitStack
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Mapping, Sequence

import numpy as np
from scipy import stats

from ..data.flighttest import load_control_travel
from ..data.timehistory import CHANNELS
from ..dynamics import AXIS_CHANNELS, CHANNEL_SCALES, FAIL_RESIDUAL, RecordedTest, load_recorded_tests
from ..errors import CalibError, InputError, Problem
from ..factors import FactorSet, step_factors
from ..jsbsim.product import AircraftPaths, write_derived
from ..jsbsim.simulator import Simulator
from ..jsbsim.trajectory import fly
from ..jsbsim.xml import Tree, parse
from .closeloop import (MATERIAL, MIN_EVIDENCE, MIN_EXPLAINED, MIN_HELD_GAIN, NOISE_FLOOR, Unexplained,
                        evidence_failures, pays_off_out_of_sample)
from .diagnose import ALPHA, Correlate
from .effects import LIBRARY_DIR, Effect, library
from .fit import LEGS, FitResult, fit
from .trims import STEP_PRIOR

DYNAMIC_LIBRARY_DIR = LIBRARY_DIR / "dynamic"
CV_FOLDS = 4                 # cross-validation folds (whole maneuvers; fewer with fewer tests)
MAX_EFFECTS = 4
CANDIDATE_NFEV = 40          # function evaluations of a candidate's fit (one factor, a smooth response)
REFIT_NFEV = 80
MIN_SAMPLES = 10             # samples a channel needs to be diagnosed
MIN_CORRELATION = 0.3        # |r| of a state or input listed as a correlate
CHANNEL_AXIS = {c: a for a, chans in AXIS_CHANNELS.items() for c in chans}
MOMENT_AXIS = {"ROLL": "roll", "YAW": "yaw", "SIDE": "yaw", "PITCH": "pitch", "LIFT": "pitch", "DRAG": "pitch"}
COUPLED = {"roll": ("roll", "yaw"), "yaw": ("roll", "yaw"), "pitch": ("pitch",)}
# the trim loop's evidence rules (recorded in the JSON; evidence_failures and
# pays_off_out_of_sample apply them)
RULES = {"min_evidence_bic_decrease": MIN_EVIDENCE, "min_explained_share": MIN_EXPLAINED,
         "material_share_of_scale": MATERIAL, "min_cross_validated_gain": MIN_HELD_GAIN, "cv_folds": CV_FOLDS}


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
    axis = effect_axis(eff)
    return [f for f in step_factors(f"{axis} dynamics") if f not in eff.same_as] if axis else []


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


def fly_response(sim: Simulator, test: RecordedTest) -> Response:
    chans = response_channels(test)
    try:
        tr = fly(sim, test.maneuver)
    except CalibError as exc:
        return Response(test, chans, np.full(len(test.time_s) * len(chans), FAIL_RESIDUAL), None, str(exc))
    r, _ = test.residuals(tr, chans)
    return Response(test, chans, r, tr.at(test.time_s))


def fly_all(sim: Simulator, tests: Sequence[RecordedTest]) -> list[Response]:
    return [fly_response(sim, t) for t in tests]


def _stack(responses: Sequence[Response]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Scaled residuals, scaled model values (NaN where not flown) and each row's channel."""
    r, v, ch = [], [], []
    for x in responses:
        n = len(x.test.time_s)
        r.append(x.scaled)
        v += [x.model[c] / CHANNEL_SCALES[c] if x.model is not None else np.full(n, np.nan) for c in x.channels]
        ch.append(np.repeat(np.array(x.channels, dtype=object), n))
    cat = lambda parts: np.concatenate(parts) if parts else np.zeros(0)
    return cat(r), cat(v), cat(ch)


def _per_channel(r: np.ndarray, ch: np.ndarray) -> dict[str, float]:
    return {c: float(np.sum(r[ch == c] ** 2)) for c in dict.fromkeys(ch)}


def _residual_function(sim: Simulator, tests: Sequence[RecordedTest]):
    """factors -> (scaled residuals of every test, labels), flying ``sim``."""
    labels = [f"{t.id} {c} t={s:.2f}" for t in tests for c in response_channels(t) for s in t.time_s]

    def residuals(fs: FactorSet):
        sim.set_factors(fs)
        return _stack(fly_all(sim, tests))[0], labels

    return residuals


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
    bias: float
    trend_per_s: float                 # slope against maneuver time (within each maneuver) [units/s]
    noise: float                       # estimated sensor noise, standard deviation [channel units]
    structured: bool
    reason: str
    correlates: list[Correlate] = field(default_factory=list)

    @property
    def metric(self) -> str:
        return self.channel

    def as_dict(self) -> dict:
        return {"channel": self.channel, "axis": self.axis, "n": self.n, "n_effective": _js(self.n_effective),
                "scale": self.scale, "rms": _js(self.rms), "bias": _js(self.bias), "trend_per_s": _js(self.trend_per_s),
                "noise": _js(self.noise), "structured": self.structured, "reason": self.reason,
                "correlates_with": [c.as_dict() for c in self.correlates]}


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
        return False, (f"residual beyond noise {beyond:.3g} {unit} is below {MATERIAL:g} of the scale "
                       f"{d.scale:g} {unit}")
    if not p_noise < ALPHA:
        return False, f"no more than the noise ({d.noise:.3g} {unit}) gives (p = {p_noise:.2g})"
    parts = [f"{beyond:.3g} {unit} beyond noise ({beyond / d.scale:.2f} of the scale)",
             f"mean {d.bias:+.3g}", f"trend {d.trend_per_s:+.3g}/s"]
    if d.correlates:
        c = d.correlates[0]
        parts.append(f"follows {c.regressor} (r = {c.r:+.2f})")
    return True, "; ".join(parts)


def diagnose_channel(channel: str, responses: Sequence[Response]) -> ChannelDiagnosis:
    """The diagnosis of one response channel over the tests that recorded it and flew."""
    flown = [x for x in responses if x.model is not None and channel in x.channels]
    scale, axis, unit = CHANNEL_SCALES[channel], CHANNEL_AXIS[channel], CHANNELS[channel].unit
    errs = [x.error(channel) for x in flown]
    n = int(sum(e.size for e in errs))
    if n < MIN_SAMPLES:
        return ChannelDiagnosis(channel, axis, n, math.nan, scale, math.nan, math.nan, math.nan, math.nan, False,
                                "too few samples")
    e = np.concatenate(errs)
    n_eff = effective_samples(errs)
    d = ChannelDiagnosis(channel, axis, n, n_eff, scale, float(np.sqrt(np.mean(e ** 2))), float(np.mean(e)),
                         trend(errs, [x.test.time_s for x in flown]), noise_estimate(errs, resolution(channel)),
                         False, "", correlates(e, _regressors(flown), n_eff)[:4])
    beyond = math.sqrt(max(0.0, d.rms ** 2 - d.noise ** 2)) if math.isfinite(d.noise) else math.nan
    p_noise = float(stats.chi2.sf(float(np.sum(e ** 2)) / d.noise ** 2, n)) if d.noise > 0 else 0.0
    d.structured, d.reason = _verdict(d, beyond, p_noise, unit)
    return d


def diagnose_responses(responses: Sequence[Response]) -> dict[str, ChannelDiagnosis]:
    """Every response channel any test recorded."""
    chans = [c for c in CHANNEL_SCALES if any(c in x.channels for x in responses)]
    return {c: diagnose_channel(c, responses) for c in chans}


def structured_axes(diag: Mapping[str, ChannelDiagnosis]) -> tuple[str, ...]:
    return tuple(dict.fromkeys(d.axis for d in diag.values() if d.structured))


def noise_in_scales(d: ChannelDiagnosis) -> float:
    """A channel's noise in units of its scale for the likelihood: the estimate, at least
    :data:`~.closeloop.NOISE_FLOOR`; the scale itself where no estimate exists (asks for more
    evidence, never less)."""
    s = d.noise / d.scale
    return max(s, NOISE_FLOOR) if math.isfinite(s) else 1.0


# --------------------------------------------------------------------------- candidates
@dataclass
class DynamicCandidate:
    effect: str
    round: int
    axis: str                              # the axis of its force or moment
    factors: dict[str, float]
    stderr: dict[str, float | None]
    rss: tuple[float, float]               # all samples (/scale), before and after its fit
    n_samples: int
    delta_bic: float
    material: float                        # largest change of a sample / its scale
    explained: dict[str, float] = field(default_factory=dict)   # share of each structured channel explained
    share: float = 0.0                     # share of the structure of the channels it moves (net of damage)
    cv: tuple[float, float] | None = None  # cross-validated residual sum of squares, without and with
    accepted: bool = False
    reason: str = ""

    @property
    def score(self) -> float:
        return -self.delta_bic

    def as_dict(self) -> dict:
        return {"effect": self.effect, "round": self.round, "axis": self.axis, "score": _js(self.score),
                "factor": dict(self.factors), "stderr": {k: _js(v) for k, v in self.stderr.items()},
                "delta_bic": _js(round(self.delta_bic, 3)), "rss": [_js(x) for x in self.rss],
                "n_samples": self.n_samples, "material": _js(round(self.material, 3)),
                "explained": {k: _js(round(v, 3)) for k, v in self.explained.items()},
                "explained_share": _js(round(self.share, 3)),
                "cross_validated": [_js(x) for x in self.cv] if self.cv else None,
                "accepted": self.accepted, "reason": self.reason}


@dataclass
class _Round:
    """The model's residuals at the start of a round, against which candidates are scored."""

    number: int
    diagnosis: dict[str, ChannelDiagnosis]
    residuals: np.ndarray
    values: np.ndarray
    per_channel: dict[str, float]
    structure: dict[str, float]         # each structured channel's sum of squares beyond its noise (/scale^2)


def _start_round(number: int, responses: Sequence[Response], diag: dict[str, ChannelDiagnosis]) -> _Round:
    r, v, ch = _stack(responses)
    per = _per_channel(r, ch)
    counts = {c: int(np.sum(ch == c)) for c in per}
    structure = {c: max(0.0, per[c] - counts[c] * (diag[c].noise / diag[c].scale) ** 2)
                 for c in per if c in diag and diag[c].structured}
    return _Round(number, diag, r, v, per, structure)


def _fit_candidate(current: Simulator, eff: Effect, factors: FactorSet, tests: Sequence[RecordedTest]
                   ) -> tuple[Simulator, FitResult]:
    """A copy of ``current`` with ``eff`` added and its factor(s) fitted alone on ``tests``
    (the caller closes the copy)."""
    trial = current.clone()
    try:
        trial.add_effect(eff)
        extra = eff.as_factors()
        start = factors.with_extra(extra)
        trial.set_factors(start)
        fr = fit(f"candidate {eff.name}", list(extra), start, _residual_function(trial, tests), sim=trial,
                 prior=STEP_PRIOR, prior_center=start, legs=LEGS[-2:], max_nfev=CANDIDATE_NFEV)
    except BaseException:
        trial.close()
        raise
    trial.set_factors(fr.final)
    return trial, fr


def _score(start: _Round, eff: Effect, fr: FitResult, responses: Sequence[Response]) -> DynamicCandidate:
    """A fitted candidate scored against the round's start: evidence, materiality, explained share."""
    r1, v1, ch = _stack(responses)
    per1 = _per_channel(r1, ch)
    explained = {c: (start.per_channel[c] - per1.get(c, 0.0)) / s for c, s in start.structure.items() if s > 0}
    own = sum(s for c, s in start.structure.items() if CHANNEL_AXIS[c] in acts_on(eff))
    rss0, rss1 = float(start.residuals @ start.residuals), float(r1 @ r1)
    share = (rss0 - rss1) / own if own > 0 else 0.0
    chi = sum((start.per_channel[c] - per1.get(c, 0.0)) / noise_in_scales(start.diagnosis[c]) ** 2
              for c in start.per_channel if c in start.diagnosis)
    dbic = -chi + len(eff.factors) * math.log(max(2, r1.size))
    dv = np.abs(v1 - start.values)
    material = float(np.nanmax(dv)) if np.any(np.isfinite(dv)) else math.nan
    c = DynamicCandidate(eff.name, start.number, effect_axis(eff) or "", {k: fr.final[k] for k in eff.as_factors()},
                         dict(fr.stderr), (rss0, rss1), int(r1.size), dbic, material, explained, share)
    c.reason = "; ".join(evidence_failures(dbic, material, own, share))
    return c


def _candidates(start: _Round, current: Simulator, lib: Mapping[str, Effect], factors: FactorSet,
                tests: Sequence[RecordedTest], say) -> list[DynamicCandidate]:
    """Every library effect the model lacks that acts on a structured axis, fitted and scored."""
    axes = set(structured_axes(start.diagnosis))
    tried = []
    for name, eff in lib.items():
        if name in current.effects or not set(acts_on(eff)) & axes:
            continue
        try:
            trial, fr = _fit_candidate(current, eff, factors, tests)
        except CalibError as exc:                    # a candidate that breaks the model is rejected
            say(f"round {start.number}: {name}: fit failed ({exc})")
            continue
        with trial:
            c = _score(start, eff, fr, fly_all(trial, tests))
        tried.append(c)
        say(f"round {start.number}: {name:26s} BIC {c.delta_bic:+11.1f}  explains {100 * c.share:5.0f} %  "
            f"{'passes the fit tests' if not c.reason else 'rejected'}")
    return tried


def maneuver_folds(n_tests: int, folds: int = CV_FOLDS) -> list[list[int]]:
    """Cross-validation folds of whole maneuvers: test i in fold i mod k (k = min(folds, tests))."""
    k = min(folds, n_tests)
    return [[i for i in range(n_tests) if i % k == f] for f in range(k)]


def cross_validate(current: Simulator, eff: Effect, factors: FactorSet, tests: Sequence[RecordedTest]) -> float:
    """Residual sum of squares of every maneuver predicted by a fit of ``eff`` that did not see
    it; NaN with fewer than two maneuvers (nothing to predict from)."""
    folds = maneuver_folds(len(tests))
    if len(folds) < 2:
        return math.nan
    total = 0.0
    for held in folds:
        trial, _ = _fit_candidate(current, eff, factors, [t for i, t in enumerate(tests) if i not in held])
        with trial:
            r = _stack(fly_all(trial, [tests[i] for i in held]))[0]
        total += float(r @ r)
    return total


def _best_out_of_sample(tried: list[DynamicCandidate], start: _Round, current: Simulator, lib: Mapping[str, Effect],
                        factors: FactorSet, tests: Sequence[RecordedTest], say) -> DynamicCandidate | None:
    """The strongest candidate that passed the fit tests and pays off in cross-validation."""
    cv0 = float(start.residuals @ start.residuals)
    for c in sorted((c for c in tried if not c.reason), key=lambda c: c.delta_bic):
        cv1 = cross_validate(current, lib[c.effect], factors, tests)
        c.cv = (cv0, cv1)
        if pays_off_out_of_sample(cv0, cv1):
            return c
        c.reason = (f"does not pay off out of sample: cross-validated residuals {cv0:.3g} -> {cv1:.3g} "
                    f"(needs -{100 * MIN_HELD_GAIN:.0f} %, folds of whole maneuvers)")
        say(f"round {c.round}: {c.effect}: {c.reason}")
    return None


def _add(current: Simulator, eff: Effect, factors: FactorSet,
         values: Mapping[str, float]) -> tuple[Simulator, FactorSet]:
    """A copy of ``current`` with ``eff`` added at its fitted values."""
    trial = current.clone()
    try:
        trial.add_effect(eff)
        fs = factors.with_extra(eff.as_factors(), values)
        trial.set_factors(fs)
    except BaseException:
        trial.close()
        raise
    return trial, fs


def _refit(rnd: int, current: Simulator, lib: Mapping[str, Effect], added: list[str], factors: FactorSet,
           tests: Sequence[RecordedTest], say) -> FitResult:
    """Every added effect refitted with the stage-2b factors of its axis."""
    names = list(factors.extra)
    for e in added:
        names += [f for f in companion_factors(lib[e]) if f not in names]
    say(f"round {rnd}: added {added[-1]}; refit of {', '.join(names)}")
    return fit(f"refit after {added[-1]}", names, factors, _residual_function(current, tests), sim=current,
               prior=STEP_PRIOR, prior_center=factors, legs=LEGS[-2:], max_nfev=REFIT_NFEV)


# --------------------------------------------------------------------------- the result and the loop
@dataclass
class CloseLoopDynamicResult:
    """What the loop found on the time histories and the aircraft it ends with (as a parsed
    file and its factors, the added effects' own included; :meth:`simulator` flies it)."""

    aircraft: str
    root: Path
    tests: list[RecordedTest]
    before: list[Response]
    after: list[Response]
    diagnosis_before: dict[str, ChannelDiagnosis]
    diagnosis_after: dict[str, ChannelDiagnosis]
    candidates: list[DynamicCandidate]
    added: list[str]
    refits: list[FitResult]
    factors: FactorSet
    aircraft_tree: Tree
    wall_time_s: float
    notes: list[str] = field(default_factory=list)

    def errors(self, which: str) -> dict[str, dict[str, ChannelError]]:
        """'before' or 'after': axis -> channel -> error over all tests."""
        return error_summary({"before": self.before, "after": self.after}[which])

    def unexplained(self) -> list[Unexplained]:
        return [Unexplained(c, [x.regressor for x in d.correlates], d.reason, list(d.correlates))
                for c, d in self.diagnosis_after.items() if d.structured]

    def simulator(self) -> Simulator:
        """A simulator of the aircraft the loop ends with (use it in a ``with`` block)."""
        return Simulator.with_aircraft(self.root, self.aircraft, self.aircraft_tree, self.factors)

    def to_json(self) -> dict:
        errs = {w: {a: {c: e.as_dict() for c, e in chans.items()} for a, chans in self.errors(w).items()}
                for w in ("before", "after")}
        return {"aircraft": self.aircraft, "tests": [_test_dict(r) for r in self.before],
                "before": errs["before"], "candidates": [c.as_dict() for c in self.candidates], "added": self.added,
                "after": errs["after"], "unexplained": [u.as_dict() for u in self.unexplained()],
                "diagnosis_before": {c: d.as_dict() for c, d in self.diagnosis_before.items()},
                "diagnosis_after": {c: d.as_dict() for c, d in self.diagnosis_after.items()},
                "factors": {n: self.factors[n] for n in self.factors.extra},
                "refits": [r.summary() for r in self.refits], "rules": RULES, "notes": self.notes}


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


def _round(rnd: int, current: Simulator, factors: FactorSet, lib: Mapping[str, Effect], tests, diag, responses,
           say) -> tuple[list[DynamicCandidate], DynamicCandidate | None]:
    start = _start_round(rnd, responses, diag)
    tried = _candidates(start, current, lib, factors, tests, say)
    best = _best_out_of_sample(tried, start, current, lib, factors, tests, say)
    if best is not None:
        best.accepted = True
        best.reason = (f"accepted: strongest evidence; out of sample {best.cv[0]:.3g} -> {best.cv[1]:.3g} "
                       f"({len(maneuver_folds(len(tests)))}-fold cross-validation over whole maneuvers)")
        for c in tried:
            if not c.reason:
                c.reason = f"passes the fit tests; weaker evidence than {best.effect}"
    return tried, best


def close_loop_dynamic(sim: Simulator, tests: Sequence[RecordedTest], *, effects: Mapping[str, Effect] | None = None,
                       max_effects: int = MAX_EFFECTS,
                       progress: Callable[[str], None] | None = None) -> CloseLoopDynamicResult:
    """Close the loop on recorded maneuvers (see the module doc). ``sim`` is left unchanged; the
    result holds the aircraft with the added effects (its file and factors)."""
    t0 = time.perf_counter()
    say = progress or (lambda s: None)
    tests = list(tests)
    check_tests(tests)
    lib = default_effects() if effects is None else dict(effects)
    before = fly_all(sim, tests)
    diag0 = diagnose_responses(before)
    for c, d in diag0.items():
        say(f"diagnosis {c}: {'STRUCTURED' if d.structured else 'noise'}: {d.reason}")
    candidates, added, refits = [], [], []
    with ExitStack() as boxes:
        current = boxes.enter_context(sim.clone())
        factors, responses, diag = current.factors, before, diag0
        for rnd in range(1, max_effects + 1):
            if not structured_axes(diag):
                say(f"round {rnd}: no structured residual: nothing to add")
                break
            tried, best = _round(rnd, current, factors, lib, tests, diag, responses, say)
            candidates += tried
            if best is None:
                break
            trial, factors = _add(current, lib[best.effect], factors, best.factors)
            boxes.enter_context(trial)
            current.close()
            current = trial
            added.append(best.effect)
            refits.append(_refit(rnd, current, lib, added, factors, tests, say))
            factors = refits[-1].final
            current.set_factors(factors)
            responses = fly_all(current, tests)
            diag = diagnose_responses(responses)
        after = fly_all(current, tests)
        tree = current.aircraft_tree()
    notes = [f"{r.test.id}: not flown ({r.failure}); its samples count as failures" for r in before if r.failure]
    return CloseLoopDynamicResult(sim.name, sim.root, tests, before, after, diag0, diagnose_responses(after),
                                  candidates, added, refits, factors, tree, time.perf_counter() - t0, notes)


# --------------------------------------------------------------------------- files
def run_close_loop_dynamic(root: Path | str, name: str, flight_test, *,
                           progress: Callable[[str], None] | None = None) -> CloseLoopDynamicResult:
    """Close the loop on an aircraft with time histories (directories and/or CSV files of
    format 1; cockpit controls through the aircraft's control-travel table)."""
    with Simulator(Path(root), name) as sim:
        f = sim.geometry.control_travel_file
        tests = load_recorded_tests(flight_test, load_control_travel(f) if f else None)
        res = close_loop_dynamic(sim, tests, progress=progress)
    res.notes.append(f"model: {name}; {len(tests)} time histories: " + ", ".join(f"{t.id} ({t.kind})" for t in tests))
    return res


def write_aircraft(result: CloseLoopDynamicResult, root: Path, out_name: str) -> Path:
    """Write the aircraft with its added effects as ``aircraft/<out_name>/`` of ``root``."""
    return write_derived(AircraftPaths(result.root, result.aircraft), result.aircraft_tree, result.factors,
                         AircraftPaths(Path(root), out_name))
