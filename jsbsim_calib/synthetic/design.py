"""Experiment design: the maneuvers that would most shrink the uncertainty of the factors the
data in hand leave loose (``jsbsim-calib plan``).

Information. A record of a maneuver is its response channels (:data:`CHANNELS`) sampled at
:data:`SAMPLE_HZ`, each with the sensor noise of the synthesis (``NOISE``: the sigma per
sample). Its Fisher information about the stage-2b factors (:data:`DESIGN_FACTORS`,
normalized units) is ``J^T J``, where ``J`` is the sensitivity of the samples, divided by
their sigma, to each factor: forward differences of flights of the current model
(:data:`STEP`). The data in hand count the same way: recorded time histories as records; a
flight-test results table as the stage-2b fit sees it, its summary metrics over their
tolerances and the snapshot trims over theirs (the rows that depend on an assumed input
amplitude carry no information), scaled by the reduced chi-square at the current model as a
fit's standard errors are. The bounds of a factor stand for one standard deviation of what is
known before any data (:data:`PRIOR_SD`): a factor no data move keeps that.

Design. The candidates are the Part 60 catalogue's dynamic tests of a base plan (the packaged
Level 5 one) at new conditions (speeds and flaps around the plan's) and designed inputs on
each surface: a doublet, a 3-2-1-1 and a multisine of bounded amplitude
(:data:`DESIGNED`). A candidate whose predicted flight leaves :data:`ENVELOPE` is dropped
with the limit it broke, and so is one whose noise-free record the replay cannot follow to
within :data:`REPLAY_LIMIT` sensor sigmas (:func:`replay_error`); the replay error of the
others counts as noise (:func:`usable_information`). The plan is built greedily: each pick is the candidate that most
lowers the sum of the log variances of the target factors (the loosest ones in hand, D-
optimal on their block), given the data in hand and the picks before it.

The predicted standard errors assume the new records are explained to their sensor noise; a
refit's own chi-square widens them by whatever the model still misses. :func:`refit` and
:func:`combined_errors` are that check on a truth aircraft (``benchmarks/plan_design.py``);
:func:`run_plan` is the command: the design, its plan file and its JSBSim scripts.
"""
from __future__ import annotations

import math
import time
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from ..calibration.dynamic import metric_residuals
from ..calibration.fit import LEGS, FitResult, data_rows, fit, sensitivity
from ..calibration.points import FAIL_PENALTY, Residual, point_residuals, point_sets
from ..calibration.workflow import FLIGHT_TEST_KINDS, aircraft_data, dynamic_tests
from ..core import numerics
from ..core.errors import CalibError, InputError
from ..data.dynamic_tests import DynamicTest
from ..data.flighttest import QuirkWarning
from ..data.schemas import Dataset
from ..evaluation.evaluate_dynamic import CHANNEL_SCALES, RecordedTest, fly_test, load_recorded_tests, recorded_test
from ..factors import DYNAMIC_STEPS, FactorSet, set_in
from ..jsbsim.product import load_aircraft_geometry
from ..jsbsim.simulator import Simulator
from ..jsbsim.trajectory import Maneuver, Trajectory, export, fly
from .maneuvers import (INPUT_CHANNELS, NOISE, InputSpec, ManeuverSpec, Plan, build_maneuver, control_travel,
                        fly_plan, load_plan, plan_text, record_flight, sensor_errors)

DESIGN_FACTORS = set_in(DYNAMIC_STEPS)      # what time histories fit: damping, control power, stiffness
CHANNELS = tuple(CHANNEL_SCALES)            # a record's response channels
SAMPLE_HZ = 10.0                            # the flight test's rate
STEP = 0.02                                 # forward-difference step, normalized factor units
PRIOR_SD = 1.0                              # what the bounds tell: one standard deviation (normalized units)
COUNT = 4                                   # maneuvers a plan proposes
TARGETS = 2                                 # the loosest factors it aims at
SPEEDS = (0.8, 1.0, 1.2)                    # candidate speeds: shares of the catalogue test's
FLAPS_SPEED = (0.75, 20.0)                  # and a flaps-down condition: share of the speed, flaps [deg]
CATALOGUE_KINDS = ("pitch_pulse", "pitch_doublet", "phugoid", "roll_pulse", "roll_step", "roll_doublet", "yaw_pulse",
                   "rudder_response", "dutch_roll", "yaw_doublet", "spiral", "maneuvering_stability")
# designed inputs per surface: (axis, amplitude [deg, data sign], 3-2-1-1 unit [s], the catalogue kind whose
# pilot loops it keeps). Amplitudes: about a third of the Level 5 pulses' travel, in the linear range.
DESIGNED = {"elevator_deg": ("pitch", 2.0, 0.4, "pitch_pulse"), "aileron_deg": ("roll", 5.0, 0.8, "roll_pulse"),
            "rudder_deg": ("yaw", 3.0, 0.8, "yaw_pulse")}
DESIGNED_RAMP_S = 0.3                       # ramps of the designed steps: three samples of a 10 Hz record
MULTISINE_S = 20.0                          # a multisine's length
ENVELOPE = {"roll_deg": (-60.0, 60.0), "nz_g": (0.3, 2.0), "alpha_deg": (-5.0, 12.0), "beta_deg": (-12.0, 12.0)}
COCKPIT_CHANNELS = ("column_in", "wheel_deg", "pedal_in")
MIN_SPEED_SHARE = 0.75                      # the predicted airspeed stays above this share of the start's
REPLAY_LIMIT = 1.0                          # a noise-free record must replay within this RMS [sensor sigmas]


@dataclass(frozen=True)
class Candidate:
    spec: ManeuverSpec
    source: str                   # "catalogue 2.b.1 at new conditions" or "designed 3-2-1-1"


@dataclass
class Scored:
    """A candidate flown on the model: its information and predicted excursions."""

    candidate: Candidate
    information: np.ndarray
    trajectory: Trajectory


@dataclass
class Pick:
    scored: Scored
    se_after: dict[str, float]    # every design factor's predicted standard error with this pick and those before


@dataclass
class Proposal:
    aircraft: str
    names: tuple[str, ...]
    factors: FactorSet            # the model's factors the design linearized at
    targets: tuple[str, ...]
    se_in_hand: dict[str, float]
    evidence: str                 # what the data in hand were
    picks: list[Pick]
    tried: int
    dropped: list[tuple[str, str]] = field(default_factory=list)    # (candidate id, why)


# --------------------------------------------------------------------------- information
def _weights() -> dict[str, float]:
    return {c: 1.0 / NOISE[c][0] for c in CHANNELS}


def _samples(traj: Trajectory, duration_s: float) -> np.ndarray:
    t = np.arange(0.0, duration_s + 1e-9, 1.0 / SAMPLE_HZ)
    at, w = traj.at(t), _weights()
    return np.concatenate([at[c] * w[c] for c in CHANNELS])


def record_sensitivity(sim: Simulator, maneuver: Maneuver, factors: FactorSet,
                       names: Sequence[str]) -> tuple[np.ndarray, Trajectory]:
    """The weighted samples' sensitivity to each factor (columns, normalized units) of a
    maneuver flown by the model, and its flight at ``factors``. Leaves the model at ``factors``."""
    flown = []

    def samples(fs: FactorSet):
        sim.set_factors(fs)
        flown.append(fly(sim, maneuver))
        return _samples(flown[-1], maneuver.duration_s), []

    jac = sensitivity(samples, factors, names, STEP)
    sim.set_factors(factors)
    return jac, flown[0]


def records_information(sim: Simulator, tests: Sequence[RecordedTest], factors: FactorSet,
                        names: Sequence[str] = DESIGN_FACTORS) -> np.ndarray:
    """The information of recorded time histories (their maneuvers flown by the model)."""
    out = np.zeros((len(names), len(names)))
    for t in tests:
        jac, _ = record_sensitivity(sim, t.maneuver, factors, names)
        out += numerics.gram(jac)
    return out


SNAPSHOT_TRIMS = tuple(Residual("snapshot", "all", m) for m in ("pitch_deg", "elevator_deg", "aileron_deg",
                                                                  "rudder_deg"))


def results_information(sim: Simulator, tests: Sequence[DynamicTest], data: dict[str, Dataset], factors: FactorSet,
                        names: Sequence[str] = DESIGN_FACTORS) -> np.ndarray:
    """The information of a flight-test results table as stage 2b fits it: the metrics that do
    not depend on an assumed input amplitude and the snapshot trims, over their tolerances,
    scaled by the reduced chi-square of the measurements at ``factors`` (as a fit's standard
    errors are: :func:`~jsbsim_calib.calibration.fit.data_rows`)."""
    sim.set_factors(factors)
    sets = point_sets(sim, data, SNAPSHOT_TRIMS)

    evaluated = []                              # the first: at ``factors``

    def residuals(fs: FactorSet):
        sim.set_factors(fs)
        out = []
        for test in tests:
            r, _, amp = metric_residuals(fly_test(sim, test))
            out += [x for x, a in zip(r, amp) if not a]
        for ps in sets:
            out += point_residuals(sim, ps, ps.metrics)[0]
        evaluated.append(np.array(out, float))
        return evaluated[-1], []

    jac = sensitivity(residuals, factors, names, STEP)
    sim.set_factors(factors)
    r0 = evaluated[0]
    rows = data_rows(jac, [""] * len(r0))
    chi2 = numerics.sum_sq(r0[rows]) / max(1, int(np.count_nonzero(rows)) - len(names))
    return numerics.gram(jac) / max(chi2, 1e-12)


def standard_errors(information: np.ndarray, names: Sequence[str], factors: FactorSet) -> dict[str, float]:
    """Each factor's standard error (its units) with the prior of the bounds (:data:`PRIOR_SD`)."""
    cov = numerics.inverse(information + np.eye(len(names)) / PRIOR_SD ** 2)
    return {n: float(math.sqrt(max(cov[i, i], 0.0)) * 0.5 * (factors.factor(n).upper - factors.factor(n).lower))
            for i, n in enumerate(names)}


def loosest(se: dict[str, float], factors: FactorSet, count: int = TARGETS) -> tuple[str, ...]:
    """The factors with the largest standard error as a share of their range."""
    share = {n: s / (factors.factor(n).upper - factors.factor(n).lower) for n, s in se.items()}
    return tuple(sorted(share, key=lambda n: (-share[n], n))[:count])


# --------------------------------------------------------------------------- candidates
def _at(spec: ManeuverSpec, ident: str, share: float, flaps_deg: float, title: str) -> ManeuverSpec:
    c = spec.start
    speed = {"kcas": round(c.kcas * share, 1), "ktas": None} if c.kcas is not None else \
        {"ktas": round(c.ktas * share, 1), "kcas": None}
    start = replace(c, **speed, flaps_deg=flaps_deg)
    return replace(spec, id=ident, title=title, start=start)


def _conditions(spec: ManeuverSpec) -> list[tuple[float, float, str]]:
    """(speed share, flaps, words) of the candidate conditions about a catalogue test's."""
    out = [(s, spec.start.flaps_deg, f"{s:.0%} of its speed") for s in SPEEDS]
    if spec.start.flaps_deg == 0.0:
        out.append((FLAPS_SPEED[0], FLAPS_SPEED[1], f"flaps {FLAPS_SPEED[1]:g}, {FLAPS_SPEED[0]:.0%} of its speed"))
    return out


def _designed(template: ManeuverSpec, channel: str, shape: str) -> ManeuverSpec:
    axis, amp, unit, _ = DESIGNED[channel]
    if shape == "doublet":
        spec, length = InputSpec("doublet", channel, amp, 1.0, 1.5 * unit, DESIGNED_RAMP_S), 1.0 + 3.0 * unit + 8.0
    elif shape == "3211":
        spec, length = InputSpec("3211", channel, amp, 1.0, unit, DESIGNED_RAMP_S), 1.0 + 7.0 * unit + 8.0
    else:
        spec, length = InputSpec("multisine", channel, amp, 1.0, MULTISINE_S, ramp_s=1.0), MULTISINE_S + 3.0
    words = {"doublet": "doublet", "3211": "3-2-1-1", "multisine": "multisine"}[shape]
    return replace(template, kind=f"{axis}_{shape}", part60="designed input", duration_s=round(length, 2),
                   inputs=(spec,), title=f"{words.capitalize()} on the {channel.split('_')[0]}", notes="")


def candidates(plan: Plan) -> list[Candidate]:
    """The catalogue's dynamic tests of ``plan`` at new conditions, and the designed inputs at
    the conditions of each axis's catalogue test."""
    out, n = [], 0
    for spec in plan.maneuvers:
        if spec.kind not in CATALOGUE_KINDS:
            continue
        for share, flaps, words in _conditions(spec):
            n += 1
            out.append(Candidate(_at(spec, f"P.{n:02d}", share, flaps, f"{spec.title} ({words})"),
                                 f"catalogue {spec.part60} ({spec.id}) at {words}"))
    for channel, (axis, _, _, kind) in DESIGNED.items():
        template = next((s for s in plan.maneuvers if s.kind == kind), None)
        if template is None:
            continue
        for shape in ("doublet", "3211", "multisine"):
            base = _designed(template, channel, shape)
            for share, flaps, words in _conditions(template):
                n += 1
                spec = _at(base, f"P.{n:02d}", share, flaps, f"{base.title} ({words})")
                out.append(Candidate(spec, f"designed {shape} at the conditions of {template.id}, {words}"))
    return out


def outside_envelope(traj: Trajectory) -> str:
    """The first limit of :data:`ENVELOPE` the flight breaks ('' if none)."""
    for c, (lo, hi) in ENVELOPE.items():
        v = traj[c]
        if v.min() < lo or v.max() > hi:
            return f"{c} reaches {v.min():.3g}..{v.max():.3g} (limits {lo:g}..{hi:g})"
    v0 = traj["kcas"][0]
    if traj["kcas"].min() < MIN_SPEED_SHARE * v0:
        return f"kcas falls to {traj['kcas'].min():.1f} from {v0:.1f}"
    return ""


def replay_error(sim: Simulator, spec: ManeuverSpec, base: Plan, flown: Trajectory) -> float:
    """How far the replay of a noise-free record of the maneuver as ``flown`` departs from it
    (RMS, in sensor sigmas): a record a fit cannot replay faithfully carries no usable information."""
    travel = control_travel(sim)
    th = record_flight(sim.name, spec, base, flown, travel, 0.0, sensor_errors(base, 0.0, 0), np.random.default_rng(0))
    rec = replace(recorded_test(th, travel), weights=record_weights())
    r, _ = rec.residuals(fly(sim, rec.maneuver), CHANNELS)
    return math.sqrt(numerics.sum_sq(r) / max(1, len(r)))


def usable_information(sim: Simulator, spec: ManeuverSpec, base: Plan, factors: FactorSet,
                       names: Sequence[str]) -> tuple[np.ndarray, Trajectory, float]:
    """A maneuver's information as a fit could use it, its flight and its replay error ``e``
    (:func:`replay_error`): the record's systematic replay error counts as noise, dividing
    the information by ``1 + e^2``."""
    m = build_maneuver(sim, spec, 0.0, 0.0, np.random.default_rng(0))     # no pilot scatter in a design flight
    jac, traj = record_sensitivity(sim, m, factors, names)
    e = replay_error(sim, spec, base, traj)
    return numerics.gram(jac) / (1.0 + e * e), traj, e


def score(sim: Simulator, cands: Sequence[Candidate], factors: FactorSet, names: Sequence[str], base: Plan,
          progress: Callable[[str], None] | None = None) -> tuple[list[Scored], list[tuple[str, str]]]:
    """Fly every candidate (and its factor perturbations) on the model; the dropped ones with why."""
    scored, dropped = [], []
    for k, c in enumerate(cands):
        try:
            info, traj, replay = usable_information(sim, c.spec, base, factors, names)
        except (CalibError, ValueError) as exc:
            dropped.append((c.spec.id, f"not flown: {exc}"))
            continue
        why = outside_envelope(traj) or (f"its record replays {replay:.2g} sensor sigmas off (limit {REPLAY_LIMIT:g})"
                                         if not replay <= REPLAY_LIMIT else "")
        if why:
            dropped.append((c.spec.id, why))
        else:
            scored.append(Scored(c, info, traj))
        if progress:
            progress(f"plan: {k + 1}/{len(cands)} candidates flown")
    return scored, dropped


# --------------------------------------------------------------------------- the greedy design
def _objective(information: np.ndarray, idx: Sequence[int]) -> float:
    cov = numerics.inverse(information + np.eye(len(information)) / PRIOR_SD ** 2)
    return math.fsum(math.log(max(cov[i, i], 1e-300)) for i in idx)


def choose(in_hand: np.ndarray, scored: Sequence[Scored], names: Sequence[str], targets: Sequence[str],
           factors: FactorSet, count: int = COUNT) -> list[Pick]:
    """Greedy D-optimal picks on the targets' variances: each the candidate that lowers them most."""
    idx = [list(names).index(t) for t in targets]
    info, left, picks = np.array(in_hand, float), list(scored), []
    for _ in range(min(count, len(left))):
        best = min(range(len(left)), key=lambda k: (_objective(info + left[k].information, idx), k))
        s = left.pop(best)
        info = info + s.information
        picks.append(Pick(s, standard_errors(info, names, factors)))
    return picks


def design(sim: Simulator, plan: Plan, in_hand: np.ndarray, evidence: str, *, count: int = COUNT,
           targets: Sequence[str] | None = None, names: Sequence[str] = DESIGN_FACTORS,
           progress: Callable[[str], None] | None = None) -> Proposal:
    """The proposal: ``count`` maneuvers for the target factors (default the :data:`TARGETS`
    loosest given ``in_hand``, the information of the data in hand)."""
    factors = sim.factors
    se = standard_errors(in_hand, names, factors)
    targets = tuple(targets) if targets else loosest(se, factors)
    cands = candidates(plan)
    scored, dropped = score(sim, cands, factors, names, plan, progress)
    picks = choose(in_hand, scored, names, targets, factors, count)
    return Proposal(sim.name, tuple(names), factors, targets, se, evidence, picks, len(cands), dropped)


# --------------------------------------------------------------------------- a refit, then with the data in hand
REFIT_PRIOR = 1e-3            # the refit's pull to its start: only keeps an unidentified direction finite


def record_weights() -> dict[str, float]:
    """A recorded test's channel weights in the ratio of the sensors' sigmas (the design's)."""
    return {c: CHANNEL_SCALES[c] / NOISE[c][0] for c in CHANNELS}


def refit(sim: Simulator, tests: Sequence[RecordedTest], start: FactorSet, names: Sequence[str] = DESIGN_FACTORS,
          progress: Callable[[str], None] | None = None) -> FitResult:
    """Fit ``names`` to new records alone (the fit's standard errors scale with how well the
    model explains them: replay and model errors count, not only the sensors')."""
    weighted = [replace(t, weights=record_weights()) for t in tests]

    def residuals(fs: FactorSet):
        sim.set_factors(fs)
        out, labels = [], []
        for t in weighted:
            try:
                r, lab = t.residuals(fly(sim, t.maneuver), CHANNELS)
            except CalibError:
                r, lab = np.full(1, FAIL_PENALTY), [f"{t.id}: not flown"]
            out.append(r)
            labels += lab
        return np.concatenate(out), labels

    return fit("design refit", names, start, residuals, sim=sim, prior=REFIT_PRIOR, prior_center=start,
               legs=LEGS[-2:], progress=progress)


def combined_errors(in_hand: np.ndarray, result: FitResult, factors: FactorSet) -> dict[str, float]:
    """Standard errors with the data in hand and a refit's records (independent data: their
    informations add; a refit without a covariance adds none)."""
    names = result.names
    learnt = np.zeros((len(names), len(names))) if result.covariance is None else numerics.inverse(result.covariance)
    return standard_errors(in_hand + learnt, names, factors)


def synthetic_records(truth: Simulator, specs: Sequence[ManeuverSpec], base: Plan, seed: int) -> list[RecordedTest]:
    """``specs`` flown by a truth aircraft with the base plan's pilot scatter and sensor noise,
    as records. The noise is the sensors' sigma on the response channels only: the refit
    replays the recorded inputs as known (output error), and noise on them would bias it
    toward weaker controls (errors in variables), a constant bias is a nuisance it does not
    estimate; neither is what a design is judged by."""
    noise = {c: (0.0 if c in INPUT_CHANNELS or c in COCKPIT_CHANNELS else s, 0.0) for c, (s, _) in base.noise.items()}
    plan = replace(base, maneuvers=tuple(specs), noise=noise)
    travel = control_travel(truth)
    return [recorded_test(th, travel) for th in fly_plan(truth, plan, seed=seed, noise=1.0)]


# --------------------------------------------------------------------------- the command
@dataclass
class PlanResult:
    """``jsbsim-calib plan``: the proposal and the files written for it."""

    proposal: Proposal
    plan_file: Path
    scripts: list[Path]
    wall_time_s: float


def in_hand_information(sim: Simulator, root: Path, name: str, flight_test=None) -> tuple[np.ndarray, str]:
    """The information of the data in hand at the model's factors, and the words for them:
    recorded time histories (``flight_test``: folders or files), else the aircraft's
    flight-test results table and snapshots."""
    if flight_test:
        records = load_recorded_tests(flight_test, control_travel(sim))
        return records_information(sim, records, sim.factors), f"{len(records)} recorded time histories"
    tests = dynamic_tests(root, name)
    geom = load_aircraft_geometry(root, name)
    keys = tuple(k for k in FLIGHT_TEST_KINDS.values() if k in geom.data_files)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", QuirkWarning)
        ft = {ds.kind: ds for ds in aircraft_data(root, name, keys).values()}
    if not tests and not ft:
        raise InputError(name, "no flight-test data in hand: give --flight-test with time histories")
    words = f"{len(tests)} dynamic tests of the flight-test results and {sum(len(d.frame) for d in ft.values())} trims"
    return results_information(sim, tests, ft, sim.factors), words


def run_plan(root: Path | str, name: str, out_dir: Path | str, *, flight_test=None, base_plan: str = "level5",
             count: int | None = None, targets: tuple[str, ...] = (),
             progress: Callable[[str], None] | None = None) -> PlanResult:
    """Design the next flights for the aircraft as it stands (:mod:`.design`) and write the plan
    file (``plan.toml``, flown by ``synth --plan``) and a JSBSim script per maneuver
    (``scripts/``, with their initialization files) into ``out_dir``."""
    root, out_dir, t0 = Path(root), Path(out_dir), time.perf_counter()
    say = progress or (lambda s: None)
    base = load_plan(base_plan)
    with Simulator(root, name) as sim:
        say("plan: the information of the data in hand")
        info, words = in_hand_information(sim, root, name, flight_test)
        proposal = design(sim, base, info, words, count=count or COUNT, targets=targets, progress=say)
        scripts_dir = out_dir / "scripts"
        scripts_dir.mkdir(parents=True, exist_ok=True)
        scripts = []
        for p in proposal.picks:
            m = build_maneuver(sim, p.scored.candidate.spec, 0.0, 0.0, np.random.default_rng(0))
            scripts.append(export(sim, m, scripts_dir, flown=p.scored.trajectory, init_dir=scripts_dir)["script"])
    specs = [p.scored.candidate.spec for p in proposal.picks]
    header = (f"Proposed by jsbsim-calib plan {name}: the flights that most shrink the standard errors of "
              f"{', '.join(proposal.targets)}.\nFly it on a truth aircraft: jsbsim-calib synth --truth AIRCRAFT "
              f"--plan THIS_FILE --out DIR")
    plan_file = out_dir / "plan.toml"
    plan_file.write_text(plan_text(f"{name}_plan", f"designed for {', '.join(proposal.targets)}", specs,
                                   sample_rate_hz=base.sample_rate_hz, timing_s=base.timing_s,
                                   amplitude_frac=base.amplitude_frac, header=header))
    return PlanResult(proposal, plan_file, scripts, time.perf_counter() - t0)
