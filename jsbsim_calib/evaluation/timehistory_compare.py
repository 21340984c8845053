"""A flight-test time history against the model: fly its inputs, sample, measure both, compare.

:func:`compare_time_history` replays a record on a simulator (:func:`replay_maneuver`: the
open-loop replay of :func:`~jsbsim_calib.data.timehistory.maneuver_from_time_history` with
the replay policy below), samples the model at the data's times (surfaces in the data's
signs), computes the Part 60 test's metrics (:data:`jsbsim_calib.data.part60_tests.CATALOGUE`) on
both traces with the same functions, judges them (:func:`~jsbsim_calib.data.part60_tests.judge`)
and adds every channel's error (model - data). The result is a :class:`TimeHistoryComparison`.

Replay policy (:data:`EXAMINED_AXES`): the axes a test examines follow the recorded inputs,
open loop, as changes from the model's own trim; an axis the record says the pilot flew
closed loop (``pilot`` in its metadata, or the caller's) is flown by the model's test pilot
holding the flight test's final value (altitude and heading: the trimmed value), and its
recorded surface is then a model output, not an input (replaying it too would count the
pilot's correction twice). A metric on a channel the pilot holds is matched by construction
and is not judged. A record that starts at a throttle stop (an idle glide, a full-throttle
climb) is trimmed at that throttle with the flight path free
(:meth:`~jsbsim_calib.data.timehistory.TimeHistory.initial_condition`, for every replay).

The measurements are pure functions of a trace (:class:`Trace`: times, channels, the time the
test's input starts and ends): response times 10-90 % (engine), signed peaks (pulses, rudder
response), steady means (roll rate, sideslip), an oscillation's period and damping from its
turning points (phugoid, dutch roll), the spiral trend. Both traces use the *data's* input
start, so the model is measured at the same instants as the flight test.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Callable, Mapping

import numpy as np

from ..core.errors import CalibError
from ..data.dynamic_tests import ROLL_WINDOW_S
from ..data.flighttest import to_data_sign
from ..data.part60_tests import (FAIL, INPUT_CHANNEL, METRIC_CHANNEL, NA, PASS, MetricVerdict, Part60Test,
                                 catalogue_test, judge)
from ..data.timehistory import (AXIS_OF_CHANNEL, DEPARTURE, INPUT_NOISE_SIGMAS, TimeHistory, input_times,
                               maneuver_from_time_history, noise_sigma, reference_errors)
from ..jsbsim.trajectory import RATE_HZ, Hold, Maneuver, Trajectory, fly
from .evaluate_dynamic import peak_rate, response_times, steady_roll_rate

CHANNELS = ("pressure_alt_ft", "kcas", "ktas", "vs_fpm", "pitch_deg", "roll_deg", "heading_deg", "p_deg_s",
            "q_deg_s", "r_deg_s", "alpha_deg", "beta_deg", "nz_g", "elevator_deg", "aileron_deg", "rudder_deg",
            "flaps_deg", "throttle_norm", "rpm")
UNITS = {"pressure_alt_ft": "ft", "kcas": "kt", "ktas": "kt", "vs_fpm": "ft/min", "nz_g": "g", "rpm": "rpm",
         "throttle_norm": "-", "p_deg_s": "deg/s", "q_deg_s": "deg/s", "r_deg_s": "deg/s"}
SURFACE_OF = {"elevator_deg": "elevator", "aileron_deg": "aileron", "rudder_deg": "rudder"}
STEADY_S = 3.0           # steady values: mean over the last seconds of a record
END_S = 2.0              # "after" values of a change: mean over the last seconds
RELEASE_S = 1.0          # a released control: the state held before it, mean over this second
OSCILLATION_THRESHOLD = 0.05   # turning points stand out by this share of the oscillation's range
NOISE_SIGMAS = 8.0             # ... and by this many standard deviations of the sample noise

# Replay policy. The axes a test examines are driven by the recorded inputs (open loop); an
# axis the record (or the caller) names a pilot loop for is flown by the model's own test
# pilot, holding the flight test's final value (its recorded surface is then a model output).
EXAMINED_AXES = {
    "1.f.1": ("speed",), "2.b.1/2.b.4": ("pitch",), "2.b.2/2.b.5": ("roll",), "2.b.3/2.b.6": ("yaw",),
    "2.c.1.b": ("speed",), "2.c.9.b": ("pitch",), "2.d.2": ("roll",),
    "2.d.6.a/b": ("yaw",), "2.d.7": ("yaw",), "2.d.8": ("yaw",),
}
LOOP_CHANNEL = {"pitch": "pitch_deg", "bank": "roll_deg", "sideslip": "beta_deg", "airspeed": "kcas",
                "altitude": "pressure_alt_ft", "heading": "heading_deg"}
TRIMMED_TARGET = ("altitude", "heading")     # loops that hold the trimmed value (no data target)
# metrics whose model value is the flight test's rescaled by a ratio of two metrics (a gradient):
# 2.c.7, the elevator change the model needs for the flight test's speed change
RESCALED = {"2.c.7": ("elevator_change_deg", "speed_change_kt")}


def unit_of(channel: str) -> str:
    return UNITS.get(channel, "deg/s" if channel.endswith("_deg_s") else "deg")


# --------------------------------------------------------------------------- traces and events
@dataclass(frozen=True)
class Trace:
    """Times [s from the record's start], channels (data signs), and the test input's start
    and end (NaN: no input, or it never ends)."""

    time_s: np.ndarray
    channels: Mapping[str, np.ndarray]
    start_s: float = 0.0
    end_s: float = math.nan

    def __getitem__(self, name: str) -> np.ndarray:
        x = self.channels.get(name)
        return np.full(self.time_s.shape, np.nan) if x is None else x


# --------------------------------------------------------------------------- measurements
def signed_peak(t: np.ndarray, x: np.ndarray, start_s: float, sign: float | None = None) -> float:
    """The largest change from the value at ``start_s``, signed; ``sign`` fixes the direction
    (a response the other way is then negative): :func:`jsbsim_calib.evaluation.evaluate_dynamic.peak_rate`."""
    if not math.isfinite(start_s):
        return math.nan
    if sign is None:
        i0 = int(np.searchsorted(t, start_s))
        d = x[i0:] - x[i0]
        sign = math.copysign(1.0, d[np.argmax(np.abs(d))]) if d.size else 1.0
    return peak_rate(t, x, start_s, sign)


def mean_between(t: np.ndarray, x: np.ndarray, t0: float, t1: float) -> float:
    m = (t >= t0) & (t <= t1)
    return float(np.mean(x[m])) if m.any() and np.isfinite(x[m]).all() else math.nan


def end_mean(t: np.ndarray, x: np.ndarray, span_s: float = END_S) -> float:
    return mean_between(t, x, t[-1] - span_s, t[-1])


def value_at(t: np.ndarray, x: np.ndarray, time_s: float) -> float:
    return float(np.interp(time_s, t, x)) if math.isfinite(time_s) else math.nan


def turning_points(x: np.ndarray, h: float) -> list[int]:
    """Indices of the alternating extrema of ``x`` that stand out by more than ``h`` (a zigzag:
    an extremum counts once the signal has come back from it by more than ``h``), so noise
    and a slow drift make no extra cycles."""
    pts, ext, direction = [], 0, 0
    for i in range(1, x.size):
        if direction == 0:
            if abs(x[i] - x[0]) > h:
                direction, ext = (1 if x[i] > x[0] else -1), i
            continue
        if (x[i] - x[ext]) * direction > 0:
            ext = i
        elif (x[ext] - x[i]) * direction > h:
            pts.append(ext)
            direction, ext = -direction, i
    return pts


def oscillation(t: np.ndarray, x: np.ndarray, after_s: float, threshold: float = OSCILLATION_THRESHOLD
                ) -> tuple[float, float]:
    """Period [s] and damping ratio of the oscillation of ``x`` after ``after_s``, from its
    turning points (:func:`turning_points`: standing out by ``threshold`` of the signal's range
    and by :data:`NOISE_SIGMAS` times its sample noise, :func:`noise_sigma`): the period
    from every second turning point (first two cycles), the damping from the logarithmic
    decrement over one cycle of the peak-to-peak swings (a slow offset cancels). NaN where
    fewer than one cycle (or, for the damping, one and a half) shows."""
    m = t >= after_s
    ts, v = t[m], x[m]
    if ts.size < 10 or not np.isfinite(v).all() or np.ptp(v) == 0:
        return math.nan, math.nan
    k = turning_points(v, max(threshold * float(np.ptp(v)), NOISE_SIGMAS * noise_sigma(v)))
    if len(k) < 3:
        return math.nan, math.nan
    tk, vk = ts[k], v[k]
    period = float(np.mean((tk[2:] - tk[:-2])[:2]))
    swings = np.abs(np.diff(vk))
    if swings.size < 3 or swings[2] <= 0:
        return period, math.nan
    delta = math.log(swings[0] / swings[2])
    return period, delta / math.sqrt(4 * math.pi ** 2 + delta ** 2)


def spiral_trend(t: np.ndarray, roll: np.ndarray, release_s: float) -> float:
    """Change of the bank magnitude from the release to the end (+ diverging, - recovering):
    means over the :data:`RELEASE_S` before the release and the :data:`END_S` at the end, so a
    sample's noise does not decide a trend judged within +-1 deg."""
    if not math.isfinite(release_s):
        return math.nan
    return abs(end_mean(t, roll)) - abs(mean_between(t, roll, release_s - RELEASE_S, release_s))


def _release(tr: Trace) -> float:
    """Where a held input is released (its end), else its start (a release from a trim), else
    the record's start (no input seen: the controls were released before it)."""
    for t in (tr.end_s, tr.start_s):
        if math.isfinite(t):
            return t
    return float(tr.time_s[0])


def _change(ch: str) -> Callable[[Trace], float]:
    return lambda tr: end_mean(tr.time_s, tr[ch]) - value_at(tr.time_s, tr[ch], tr.start_s)


def _steady(ch: str) -> Callable[[Trace], float]:
    return lambda tr: end_mean(tr.time_s, tr[ch], STEADY_S)


def _peak(ch: str) -> Callable[[Trace], float]:
    return lambda tr: signed_peak(tr.time_s, tr[ch], tr.start_s)


def _engine(k: int) -> Callable[[Trace], float]:
    def f(tr: Trace) -> float:
        ti, tt = response_times(tr.time_s, tr["rpm"], tr.start_s)
        return (ti, tt, tt - ti)[k]
    return f


def _oscillation(ch: str, k: int, skip_s: float) -> Callable[[Trace], float]:
    return lambda tr: oscillation(tr.time_s, tr[ch], _release(tr) + skip_s)[k]


METRIC_FUNCTIONS: dict[str, Callable[[Trace], float]] = {
    "ktas": lambda tr: float(np.nanmean(tr["ktas"])), "vs_fpm": lambda tr: float(np.nanmean(tr["vs_fpm"])),
    "t_i_s": _engine(0), "t_t_s": _engine(1), "response_time_s": _engine(2),
    "max_pitch_rate_deg_s": _peak("q_deg_s"), "max_roll_rate_deg_s": _peak("p_deg_s"),
    "max_yaw_rate_deg_s": _peak("r_deg_s"),
    "elevator_change_deg": _change("elevator_deg"), "pitch_change_deg": _change("pitch_deg"),
    "speed_change_kt": _change("kcas"), "bank_change_deg": _change("roll_deg"),
    "elevator_deg": _steady("elevator_deg"), "pitch_deg": _steady("pitch_deg"), "rpm": _steady("rpm"),
    "nz_g": _steady("nz_g"),
    "phugoid_period_s": _oscillation("kcas", 0, 2.0), "phugoid_damping": _oscillation("kcas", 1, 2.0),
    "dutch_roll_period_s": _oscillation("r_deg_s", 0, 0.5), "dutch_roll_damping": _oscillation("r_deg_s", 1, 0.5),
    "roll_rate_deg_s": lambda tr: steady_roll_rate(tr.time_s, tr["p_deg_s"], tr.start_s, ROLL_WINDOW_S),
    "spiral_roll_change_deg": lambda tr: spiral_trend(tr.time_s, tr["roll_deg"], _release(tr)),
    "turn_aileron_deg": lambda tr: mean_between(tr.time_s, tr["aileron_deg"], _release(tr) - STEADY_S, _release(tr)),
    "sideslip_deg": _steady("beta_deg"), "roll_deg": _steady("roll_deg"), "aileron_deg": _steady("aileron_deg"),
}


def measure_trace(test: Part60Test, tr: Trace) -> dict[str, float]:
    """The test's metrics on one trace (NaN where a metric cannot be measured)."""
    out = {}
    for spec in test.metrics:
        f = METRIC_FUNCTIONS.get(spec.name)
        try:
            out[spec.name] = float(f(tr)) if f else math.nan
        except (ValueError, IndexError, ZeroDivisionError):
            out[spec.name] = math.nan
    return out


# --------------------------------------------------------------------------- channels
@dataclass(frozen=True)
class ChannelError:
    """Model - data over a record, for one channel (heading wrapped to +-180 deg)."""

    channel: str
    unit: str
    n: int
    rmse: float
    max_abs: float
    bias: float


def data_channels(th: TimeHistory) -> dict[str, np.ndarray]:
    """The record's channels that hold numbers (data signs)."""
    out = {}
    for name in CHANNELS:
        try:
            x = np.asarray(th.channel(name), float)
        except (KeyError, ValueError, CalibError):
            continue
        if x.shape == np.shape(th.time_s) and np.isfinite(x).any():
            out[name] = x
    return out


def model_channels(tr: Trajectory, times_s: np.ndarray) -> dict[str, np.ndarray]:
    """The flown trajectory at the given times, surfaces in the data's signs."""
    at = tr.at(times_s)
    out = {k: at[k] for k in CHANNELS if k in at}
    for ch, surface in SURFACE_OF.items():
        out[ch] = to_data_sign(surface, out[ch])
    return out


def channel_errors(data: Mapping[str, np.ndarray], model: Mapping[str, np.ndarray]) -> list[ChannelError]:
    out = []
    for ch in CHANNELS:
        if ch not in data or ch not in model:
            continue
        e = model[ch] - data[ch]
        if ch == "heading_deg":
            e = (e + 180.0) % 360.0 - 180.0
        e = e[np.isfinite(e)]
        if not e.size:
            continue
        out.append(ChannelError(ch, unit_of(ch), int(e.size), float(np.sqrt(np.mean(e ** 2))),
                                float(np.max(np.abs(e))), float(np.mean(e))))
    return out


# --------------------------------------------------------------------------- the comparison
@dataclass
class TimeHistoryComparison:
    """One record against the model: the traces at the data's times, the judged metrics, the
    channel errors; ``failure`` says why the model could not fly it."""

    path: Path
    title: str
    test: Part60Test | None
    time_s: np.ndarray
    data: dict[str, np.ndarray]
    model: dict[str, np.ndarray]
    input_start_s: float
    input_end_s: float
    metrics: list[MetricVerdict] = field(default_factory=list)
    errors: list[ChannelError] = field(default_factory=list)
    maneuver: Maneuver | None = None
    trajectory: Trajectory | None = None
    loops: dict[str, str] = field(default_factory=dict)     # axis -> loop the model's pilot flew
    failure: str = ""


def _test_of(th: TimeHistory) -> Part60Test | None:
    meta = th.meta
    for key in (getattr(meta, "part60", ""), getattr(meta, "title", ""), getattr(meta, "test_id", "")):
        t = catalogue_test(key) if key else None
        if t is not None:
            return t
    return None


def _input_window(test: Part60Test | None, t: np.ndarray, data: Mapping[str, np.ndarray],
                  pilot: Mapping[str, object], lead: int) -> tuple[float, float]:
    """When the test's input starts and ends in the data. A pilot loop on the input's axis that
    ends (a turn held, then the wheel released) ends the input where the record says it ends:
    a held surface moves too little to be seen returning."""
    ch = INPUT_CHANNEL.get(test.id) if test else None
    if ch is None:
        return 0.0, math.nan
    start, end = input_times(t, data.get(ch), DEPARTURE.get(ch, 0.5), lead)
    loop = pilot.get(AXIS_OF_CHANNEL.get(ch, ""))
    released = loop[-1].get("end_s") if isinstance(loop, list) and loop else None
    return start, float(released) if released is not None else end


# --------------------------------------------------------------------------- the replay
def replay_pilot(test: Part60Test | None, pilot: Mapping[str, str]) -> dict[str, str]:
    """Axis -> loop the model's pilot flies: the record's loops on the axes the test does not
    examine."""
    examined = EXAMINED_AXES.get(test.id, ()) if test else ()
    return {a: loop for a, loop in pilot.items() if a not in examined}


def _windows(windows: list) -> list[Hold]:
    """Loops the record keeps with their targets and windows: flown as the pilot flew them."""
    return [Hold(w["loop"], w.get("target"), float(w.get("start_s", 0.0)), float(w.get("end_s", math.inf)))
            for w in windows]


def _held_to_the_end(loop) -> str | None:
    """The loop an axis is held by at the record's end (a name, or the last window without an
    end), else None."""
    if isinstance(loop, list):
        last = loop[-1] if loop else {}
        return last.get("loop") if "end_s" not in last and "target" in last else None
    return loop


def _holds(loops: Mapping[str, object], t: np.ndarray, data: Mapping[str, np.ndarray]) -> tuple[Hold, ...]:
    out = []
    for axis, loop in loops.items():
        if isinstance(loop, list):
            out += _windows(loop)
            continue
        ch = LOOP_CHANNEL[loop]
        target = None if loop in TRIMMED_TARGET or ch not in data else end_mean(t, data[ch], STEADY_S)
        out.append(Hold(loop, target if target is None or math.isfinite(target) else None))
    return tuple(out)


def replay_maneuver(sim, th: TimeHistory, test: Part60Test | None, pilot: Mapping[str, str] | None,
                    t: np.ndarray, data: Mapping[str, np.ndarray]) -> tuple[Maneuver, dict[str, str]]:
    """The record's replay (:func:`maneuver_from_time_history`: an axis's recorded input is
    not replayed while a loop flies it) with Part 60's holds: a loop named alone holds the
    record's end value, not the trim's. Returns the maneuver and the loops (axis -> loop)."""
    loops = replay_pilot(test, dict(th.meta.pilot) if pilot is None else dict(pilot))
    m = maneuver_from_time_history(th, sim.geometry, loops)
    return replace(m, holds=_holds(loops, t, data)), loops


def _fly(sim, th: TimeHistory, test, pilot, t, data) -> tuple[Maneuver | None, Trajectory | None, dict, str]:
    try:
        m, loops = replay_maneuver(sim, th, test, pilot, t, data)
        return m, fly(sim, m, rate_hz=RATE_HZ), loops, ""
    except (CalibError, ValueError) as exc:
        return None, None, {}, f"{type(exc).__name__}: {exc}"


def _held(verdicts: list[MetricVerdict], loops: Mapping[str, str]) -> list[MetricVerdict]:
    """Metrics on a channel the model's pilot held at the flight test's value: n/a (matched by
    construction)."""
    ends = [_held_to_the_end(lp) for lp in loops.values()]
    held = {LOOP_CHANNEL[lp] for lp in ends if lp is not None and lp not in TRIMMED_TARGET}
    return [replace(v, verdict=NA, reason=f"held by the model's test pilot at the flight test's value "
                                          f"({METRIC_CHANNEL[v.name]}): matched by construction")
            if METRIC_CHANNEL.get(v.name) in held and v.verdict != NA else v for v in verdicts]


def _rescale(test: Part60Test, got_data: dict[str, float], got_model: dict[str, float]) -> dict[str, float]:
    if test.id not in RESCALED:
        return got_model
    value, by = RESCALED[test.id]
    out = dict(got_model)
    out[value] = got_data[value] * got_data[by] / got_model[by] if got_model[by] else math.nan
    return out


def compare_time_history(sim, th: TimeHistory, *, test: Part60Test | None = None,
                         pilot: Mapping[str, str] | None = None) -> TimeHistoryComparison:
    """Fly one record on ``sim`` and compare (see the module doc). ``test``: the catalogue entry
    (default: from the record's ``part60`` or title); ``pilot``: axis -> loop for closed-loop
    axes (default: the record's)."""
    test = test or _test_of(th)
    t = np.asarray(th.time_s, float) - float(th.time_s[0])
    data = data_channels(th)
    start, end = _input_window(test, t, data, dict(th.meta.pilot) if pilot is None else dict(pilot),
                               th.steady_lead())
    title = getattr(th.meta, "title", "") or Path(th.path).stem
    out = TimeHistoryComparison(Path(th.path), title, test, t, data, {}, start, end)
    out.maneuver, out.trajectory, out.loops, out.failure = _fly(sim, th, test, pilot, t, data)
    if out.trajectory is not None:
        out.model = model_channels(out.trajectory, t)
        out.errors = channel_errors(data, out.model)
    if test is None:
        return out
    got_data = measure_trace(test, Trace(t, data, start, end))
    got_model = (_rescale(test, got_data, _measured_model(out, out.model)) if out.model
                 else {m.name: math.nan for m in test.metrics})
    out.metrics = _held([judge(spec, got_data[spec.name], got_model[spec.name]) for spec in test.metrics],
                        out.loops)
    trend = {m.name for m in test.metrics if m.tolerance.judged == "trend"}
    out.metrics = [_within_spread(sim, th, out, v) if v.verdict == FAIL and v.name in trend else v for v in out.metrics]
    return out


def replay_spread(sim, th: TimeHistory, c: TimeHistoryComparison, name: str) -> float:
    """How far a metric of the replay moves with the levels its inputs are flown from: each
    input moved by the standard error of its steady lead's mean (:func:`reference_errors`) and
    flown again, the changes added in quadrature. A near-neutral spiral integrates a level
    error into its trend: on the C172 with the swirl on, 0.029 deg of aileron moved the bank
    change 30 s after the release by 2.65 deg."""
    t, base = c.time_s, _measured_model(c, c.model)[name]
    errors, sq = reference_errors(th, sim.geometry), 0.0
    for k, inp in enumerate(c.maneuver.inputs):
        u = errors.get(inp.channel, 0.0)
        if not u:
            continue
        moved = replace(inp, value=tuple(v + u for v in inp.value))
        tr = fly(sim, replace(c.maneuver, inputs=c.maneuver.inputs[:k] + (moved,) + c.maneuver.inputs[k + 1:]),
                 rate_hz=RATE_HZ)
        sq += (_measured_model(c, model_channels(tr, t))[name] - base) ** 2
    return math.sqrt(sq)


def _measured_model(c: TimeHistoryComparison, model: Mapping[str, np.ndarray]) -> dict[str, float]:
    return measure_trace(c.test, Trace(c.time_s, dict(model), c.input_start_s, c.input_end_s))


def _within_spread(sim, th: TimeHistory, c: TimeHistoryComparison, v: MetricVerdict) -> MetricVerdict:
    """A trend judged wrong is not, where the flight test lies within :data:`INPUT_NOISE_SIGMAS`
    of the replay's spread (:func:`replay_spread`): the record cannot tell the model's trend
    from its own there (the replay follows its inputs within as many standard deviations)."""
    if c.maneuver is None or not math.isfinite(v.error):      # no replay, or a NaN: nothing to weigh
        return v
    try:
        spread = replay_spread(sim, th, c, v.name)
    except (CalibError, ValueError):         # a moved replay that does not fly judges nothing
        return v
    if not abs(v.error) <= INPUT_NOISE_SIGMAS * spread:
        return v
    return replace(v, verdict=PASS, reason=f"{v.reason}, but within {INPUT_NOISE_SIGMAS:g} x the replay's spread "
                                           f"+-{spread:.2g} {v.unit} (its inputs' levels, each moved by the "
                                           "standard error of its steady lead's mean)")


def band_metric(test: Part60Test, metrics: list[MetricVerdict]) -> tuple[str, float] | None:
    """(channel, half-width) of the tolerance band on the test's plot channel: the tolerance of
    the first numerically judged metric measured on that channel, at its flight-test value."""
    for spec in test.metrics:
        if METRIC_CHANNEL.get(spec.name) != test.channel or spec.tolerance.judged:
            continue
        mv = next((m for m in metrics if m.name == spec.name), None)
        ref = mv.flight_test if mv is not None else math.nan
        if math.isfinite(ref):
            return test.channel, spec.tolerance.band(ref)
    return None
