"""Synthetic flight-test time histories: a plan of maneuvers flown by a truth aircraft, written
as format 1 (:mod:`jsbsim_calib.data.timehistory`).

A plan is a TOML file (``jsbsim_calib/synthetic/plans/level5.toml`` is the default, ``--plan level5``)::

    [plan]
    name = "level5"
    sample_rate_hz = 10.0                  # the data rate (the C172 flight test: 10 Hz)
    [variation]                            # the pilot's scatter (seeded), independent of --noise
    timing_s = 0.1                         # input start and length: +- uniform
    amplitude_frac = 0.08                  # surface amplitudes: x (1 +- uniform)
    [noise.pitch_deg]                      # per channel, at --noise 1 (defaults: NOISE)
    sigma = 0.05                           # Gaussian noise per sample
    bias = 0.1                             # standard deviation of the constant offset (drawn once per run)

    [[maneuver]]
    id = "S.06"                            # test id (file stem: S_06_pitch_pulse)
    kind = "pitch_pulse"
    part60 = "2.b.1"
    title = "Pitch control pulse (cruise)"
    duration_s = 10.0
    start = { pressure_alt_ft = 5500, kcas = 100, weight_lb = 2400, cg_in = 41.5 }
    inputs = [{ shape = "pulse", channel = "elevator_deg", amplitude = 6.0, start_s = 1.0, length_s = 1.0 }]
    pilot = { roll = "bank" }              # or { pitch = { loop = "pitch", offset = 2.0, start_s = 0, end_s = 12 } }

Start: ``pressure_alt_ft``, ``kcas`` or ``ktas``, ``weight_lb``, ``cg_in``, optional
``flaps_deg``, ``vs_fpm``, ``bank_deg`` (a steady coordinated turn), ``throttle`` (given: the
throttle is fixed and the flight path free, e.g. a full-throttle climb or an idle glide),
``mixture`` (cruise | climb; default climb at full throttle) and ``isa_dev_c``. Inputs are
ramped shapes (``pulse``, ``step``, ``doublet``, ``3211``, ``multisine``; ``ramp_s`` default
0.15 s) of a surface (data signs, degrees), the throttle (change) or the flaps (change,
degrees); ``length_s`` is the hold (each half of a doublet; the unit of a 3-2-1-1, whose
steps last 3, 2, 1 and 1 units; the whole of a multisine; a step without it is held to the
end). A multisine sums the harmonics of 1/``length_s`` within ``band_hz`` (default
:data:`MULTISINE_BAND_HZ`) with Schroeder's phases, scaled so that its peak is ``amplitude``
and tapered over ``ramp_s`` at both ends. Pilot loops (axis pitch, roll,
yaw or speed; one loop per axis, several windows allowed) hold the trimmed value, a ``target``
or the trimmed value plus an ``offset``.

Every plan is validated before anything flies: an unknown key, a missing key or a bad value
is an :class:`~jsbsim_calib.core.errors.InputError` naming the plan file, the maneuver and the key.
"""
from __future__ import annotations

import math
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Mapping, Sequence

import numpy as np

try:
    import tomllib
except ModuleNotFoundError:      # Python < 3.11
    import tomli as tomllib

from ..data.flighttest import load_control_travel, to_jsbsim_sign
from ..data.timehistory import (AXIS_CHANNELS, CHANNELS, MIXTURES, PILOT_AXES, Configuration, SensorError, pilot_windows,
                               TimeHistory, TimeHistoryMeta, load_time_history,
                               trajectory_to_time_history, write_time_history)
from ..core.errors import InputError, Problem
from ..flight.condition import Condition
from ..jsbsim.pilot import AXIS_OF_LOOP
from ..jsbsim.trajectory import RECORD, Hold, Input, Maneuver, fly

PLANS_DIR = Path(__file__).resolve().parent / "plans"
DEFAULT_RATE_HZ = 10.0
DEFAULT_RAMP_S = 0.15
MAX_NOISE = 10.0          # largest --noise scale

# sensor error at --noise 1: channel -> (sigma per sample, standard deviation of the constant bias)
NOISE: dict[str, tuple[float, float]] = {
    "pressure_alt_ft": (2.0, 10.0), "kcas": (0.3, 0.5), "ktas": (0.3, 0.5), "vs_fpm": (15.0, 5.0),
    "pitch_deg": (0.05, 0.1), "roll_deg": (0.05, 0.1), "heading_deg": (0.2, 0.5),
    "p_deg_s": (0.1, 0.05), "q_deg_s": (0.1, 0.05), "r_deg_s": (0.1, 0.05),
    "alpha_deg": (0.2, 0.3), "beta_deg": (0.2, 0.3), "nz_g": (0.005, 0.002),
    "elevator_deg": (0.1, 0.1), "aileron_deg": (0.1, 0.1), "rudder_deg": (0.1, 0.1), "flaps_deg": (0.1, 0.0),
    "column_in": (0.01, 0.01), "wheel_deg": (0.3, 0.3), "pedal_in": (0.01, 0.01),
    "throttle_norm": (0.002, 0.0), "rpm": (10.0, 5.0),
}
SHAPES = ("pulse", "step", "doublet", "3211", "multisine")
MULTISINE_BAND_HZ = (0.1, 1.5)   # a multisine's default band: the phugoid is slower, the short period inside
MULTISINE_DT_S = 0.05            # breakpoint spacing of a multisine
INPUT_CHANNELS = ("elevator_deg", "aileron_deg", "rudder_deg", "throttle_norm", "flaps_deg")
SURFACE_OF = {"elevator_deg": "elevator", "aileron_deg": "aileron", "rudder_deg": "rudder"}
OFFSET_LOOPS = ("pitch", "bank", "sideslip", "airspeed")    # loops whose target may be the trim plus an offset


# --------------------------------------------------------------------------- the plan as data
@dataclass(frozen=True)
class InputSpec:
    """A ramped pilot input (surfaces in the data's signs, degrees; throttle and flaps as changes)."""

    shape: str
    channel: str
    amplitude: float
    start_s: float
    length_s: float | None = None
    ramp_s: float = DEFAULT_RAMP_S
    band_hz: tuple[float, float] = MULTISINE_BAND_HZ      # a multisine's band


@dataclass(frozen=True)
class HoldSpec:
    """A pilot loop on an axis: the trimmed value, a ``target`` or the trimmed value + ``offset``."""

    axis: str
    loop: str
    target: float | None = None
    offset: float | None = None
    start_s: float = 0.0
    end_s: float = math.inf


@dataclass(frozen=True)
class ManeuverSpec:
    id: str
    kind: str
    title: str
    part60: str
    duration_s: float
    start: Condition
    inputs: tuple[InputSpec, ...] = ()
    holds: tuple[HoldSpec, ...] = ()
    notes: str = ""

    @property
    def pilot(self) -> dict[str, str]:
        return {h.axis: h.loop for h in self.holds}


@dataclass(frozen=True)
class Plan:
    path: Path
    name: str
    description: str
    sample_rate_hz: float
    timing_s: float
    amplitude_frac: float
    noise: Mapping[str, tuple[float, float]]
    maneuvers: tuple[ManeuverSpec, ...]


# --------------------------------------------------------------------------- reading and validating
class _Reader:
    """Typed fields of a TOML table, collecting every problem with its place."""

    def __init__(self, problems: list[Problem], where: str, doc: Any):
        self.problems, self.where, self.doc = problems, where, doc if isinstance(doc, dict) else {}
        if not isinstance(doc, dict):
            self.bad("", "must be a table")

    def bad(self, key: str, message: str) -> None:
        self.problems.append(Problem(f"{self.where}, key '{key}'" if key else self.where, message))

    def keys(self, known: Sequence[str]) -> None:
        for k in self.doc:
            if k not in known:
                self.bad(k, f"unknown key; known keys: {', '.join(known)}")

    def number(self, key: str, lo: float, hi: float, default: float | None = None, required: bool = True):
        if key not in self.doc:
            if required and default is None:
                self.bad(key, "missing")
            return default
        v = self.doc[key]
        if not (isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) and lo <= v <= hi):
            self.bad(key, f"{v!r} is not a number in [{lo:g}, {hi:g}]")
            return default
        return float(v)

    def text(self, key: str, choices: Sequence[str] | None = None, default: str | None = None,
             pattern: str | None = None) -> str | None:
        if key not in self.doc:
            if default is None:
                self.bad(key, "missing")
            return default
        v = self.doc[key]
        if not (isinstance(v, str) and v.strip()):
            self.bad(key, f"{v!r} is not a non-empty text")
        elif choices is not None and v not in choices:
            self.bad(key, f"{v!r}: use one of {', '.join(choices)}")
        elif pattern is not None and not re.fullmatch(pattern, v):
            self.bad(key, f"{v!r} must match {pattern}")
        else:
            return v
        return default


START_KEYS = ("pressure_alt_ft", "kcas", "ktas", "weight_lb", "cg_in", "flaps_deg", "vs_fpm", "bank_deg", "throttle",
              "mixture", "isa_dev_c")


def _start(r: _Reader) -> Condition | None:
    r.keys(START_KEYS)
    n = len(r.problems)
    speeds = [k for k in ("kcas", "ktas") if k in r.doc]
    if len(speeds) != 1:
        r.bad("kcas", "give exactly one of kcas and ktas")
    speed = {k: r.number(k, 30, 250) for k in speeds}
    throttle = r.number("throttle", 0, 1, required=False)
    bank = r.number("bank_deg", -60, 60, 0.0)
    mixture = r.text("mixture", MIXTURES, "climb" if throttle is not None and throttle >= 0.99 else "cruise")
    vals = dict(pressure_alt_ft=r.number("pressure_alt_ft", -1000, 20000), weight_lb=r.number("weight_lb", 500, 20000),
                cg_in=r.number("cg_in", -100, 400), flaps_deg=r.number("flaps_deg", 0, 45, 0.0),
                vs_fpm=r.number("vs_fpm", -3000, 3000, 0.0), isa_dev_c=r.number("isa_dev_c", -60, 60, 0.0))
    if len(r.problems) > n:
        return None
    mode = {"mode": "full_throttle", "throttle": throttle} if throttle is not None else {"mode": "level"}
    return Condition(**vals, **speed, **mode, bank_deg=bank, turn="coordinated" if bank else "straight",
                     mixture=mixture)


def _input(r: _Reader, duration_s: float | None) -> InputSpec | None:
    r.keys(("shape", "channel", "amplitude", "start_s", "length_s", "ramp_s", "band_hz"))
    n = len(r.problems)
    shape, channel = r.text("shape", SHAPES), r.text("channel", INPUT_CHANNELS)
    amp = r.number("amplitude", -60, 60)
    start = r.number("start_s", 0, duration_s if duration_s else 3600)
    length = r.number("length_s", 0.05, 3600, required=shape != "step")
    ramp = r.number("ramp_s", 0.01, 10, DEFAULT_RAMP_S)
    band = _band(r, shape, length)
    if channel == "throttle_norm" and amp is not None and abs(amp) > 1:
        r.bad("amplitude", f"{amp:g}: a throttle change is within [-1, 1]")
    if len(r.problems) > n:
        return None
    return InputSpec(shape, channel, amp, start, length, ramp, band)


def _band(r: _Reader, shape: str | None, length_s: float | None) -> tuple[float, float]:
    """A multisine's band [Hz]: two numbers, low < high, holding at least one harmonic of 1/length_s."""
    if "band_hz" not in r.doc:
        return MULTISINE_BAND_HZ
    v = r.doc["band_hz"]
    ok = (isinstance(v, list) and len(v) == 2 and all(isinstance(x, (int, float)) and not isinstance(x, bool)
                                                    and math.isfinite(x) and 0 < x <= 50 for x in v) and v[0] < v[1])
    if shape != "multisine":
        r.bad("band_hz", "applies to a multisine only")
    elif not ok:
        r.bad("band_hz", f"{v!r}: give [low, high] in Hz, 0 < low < high <= 50")
    elif length_s is not None and not _harmonics(length_s, (float(v[0]), float(v[1]))):
        r.bad("band_hz", f"{v!r}: no harmonic of 1/length_s = {1 / length_s:.3g} Hz within the band")
    else:
        return float(v[0]), float(v[1])
    return MULTISINE_BAND_HZ


def _hold(r: _Reader, axis: str, duration_s: float | None) -> HoldSpec | None:
    r.keys(("loop", "target", "offset", "start_s", "end_s"))
    n = len(r.problems)
    loops = [k for k, a in AXIS_OF_LOOP.items() if a == axis]
    loop = r.text("loop", loops)
    target = r.number("target", -20000, 40000, required=False)
    offset = r.number("offset", -90, 90, required=False)
    if target is not None and offset is not None:
        r.bad("offset", "give a target or an offset, not both")
    if offset is not None and loop not in OFFSET_LOOPS:
        r.bad("offset", f"an offset applies to the loops {', '.join(OFFSET_LOOPS)}")
    start = r.number("start_s", 0, 3600, 0.0)
    end = r.number("end_s", 0, 3600, required=False)
    if start is not None and end is not None and end <= start:
        r.bad("end_s", f"{end:g} s is not after start_s {start:g} s")
    if len(r.problems) > n:
        return None
    return HoldSpec(axis, loop, target, offset, start, math.inf if end is None else end)


def _pilot(doc: Any, problems: list[Problem], where: str, duration_s: float | None) -> tuple[HoldSpec, ...]:
    r = _Reader(problems, where, doc)
    r.keys(PILOT_AXES)
    out = []
    for axis in PILOT_AXES:
        if axis not in r.doc:
            continue
        entries = r.doc[axis]
        entries = [{"loop": entries}] if isinstance(entries, str) else entries
        entries = [entries] if isinstance(entries, dict) else entries
        if not isinstance(entries, list):
            r.bad(axis, "a loop name, a table {loop, target|offset, start_s, end_s} or a list of tables")
            continue
        holds = [_hold(_Reader(problems, f"{where}.{axis}[{i}]", e), axis, duration_s) for i, e in enumerate(entries)]
        holds = [h for h in holds if h is not None]
        if len({h.loop for h in holds}) > 1:
            r.bad(axis, "one loop per axis (several time windows of it are allowed)")
        out += holds
    return tuple(out)


MANEUVER_KEYS = ("id", "kind", "title", "part60", "duration_s", "start", "inputs", "pilot", "notes")


def _maneuver(doc: Any, i: int, problems: list[Problem], name: str) -> ManeuverSpec | None:
    ident = doc.get("id") if isinstance(doc, dict) else None
    where = f"{name}: maneuver[{i}]" + (f" ({ident})" if isinstance(ident, str) else "")
    r = _Reader(problems, where, doc)
    n = len(problems)
    r.keys(MANEUVER_KEYS)
    ident, kind = r.text("id", pattern=r"[A-Za-z0-9_.-]+"), r.text("kind", pattern=r"[a-z0-9_]+")
    title, part60 = r.text("title"), r.text("part60")
    duration = r.number("duration_s", 0.5, 3600)
    notes = r.text("notes", default="")
    start = None
    if "start" in r.doc:
        start = _start(_Reader(problems, f"{where}.start", r.doc["start"]))
    else:
        r.bad("start", "missing")
    raw_inputs = r.doc.get("inputs", [])
    if not isinstance(raw_inputs, list):
        r.bad("inputs", "must be a list of tables")
        raw_inputs = []
    inputs = [_input(_Reader(problems, f"{where}.inputs[{k}]", e), duration) for k, e in enumerate(raw_inputs)]
    holds = _pilot(r.doc.get("pilot", {}), problems, f"{where}.pilot", duration)
    if len(problems) > n:
        return None
    return ManeuverSpec(ident, kind, title, part60, duration, start, tuple(inputs), holds, notes)


def _noise(doc: Any, problems: list[Problem], name: str) -> dict[str, tuple[float, float]]:
    r = _Reader(problems, f"{name}: noise", doc)
    r.keys(tuple(c for c in CHANNELS if c != "time_s"))
    out = dict(NOISE)
    for ch, spec in r.doc.items():
        if ch not in CHANNELS or ch == "time_s":
            continue
        s = _Reader(problems, f"{name}: noise.{ch}", spec)
        s.keys(("sigma", "bias"))
        base = NOISE.get(ch, (0.0, 0.0))
        out[ch] = (s.number("sigma", 0, 1e4, base[0]), s.number("bias", 0, 1e4, base[1]))
    return out


def plan_path(plan: str | Path) -> Path:
    """A plan file, or the name of a packaged plan (``level5``)."""
    p = Path(plan)
    if p.is_file():
        return p
    packaged = PLANS_DIR / f"{plan}.toml"
    if re.fullmatch(r"[A-Za-z0-9_-]+", str(plan)) and packaged.is_file():
        return packaged
    names = sorted(f.stem for f in PLANS_DIR.glob("*.toml"))
    raise InputError(plan, f"no such plan file, nor a packaged plan (packaged: {', '.join(names)})")


def load_plan(plan: str | Path) -> Plan:
    """Read and validate a plan (a file or a packaged name). Raises InputError listing every problem."""
    path = plan_path(plan)
    try:
        doc = tomllib.loads(path.read_text())
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise InputError(path, f"not valid TOML: {exc}") from None
    name, problems = path.name, []
    r = _Reader(problems, name, doc)
    r.keys(("plan", "variation", "noise", "maneuver"))
    head = _Reader(problems, f"{name}: plan", doc.get("plan", {}))
    head.keys(("name", "description", "sample_rate_hz"))
    var = _Reader(problems, f"{name}: variation", doc.get("variation", {}))
    var.keys(("timing_s", "amplitude_frac"))
    raw = doc.get("maneuver", [])
    if not isinstance(raw, list) or not raw:
        r.bad("maneuver", "the plan needs at least one [[maneuver]]")
        raw = []
    maneuvers = [_maneuver(m, i, problems, name) for i, m in enumerate(raw)]
    ids = [m.id for m in maneuvers if m is not None]
    for dup in sorted({x for x in ids if ids.count(x) > 1}):
        r.bad("maneuver", f"id {dup!r} appears more than once")
    out = Plan(path, head.text("name", default=path.stem), head.text("description", default=""),
               head.number("sample_rate_hz", 0.1, 1000, DEFAULT_RATE_HZ), var.number("timing_s", 0, 5, 0.0),
               var.number("amplitude_frac", 0, 0.5, 0.0), _noise(doc.get("noise", {}), problems, name),
               tuple(m for m in maneuvers if m is not None))
    if problems:
        raise InputError(path, problems)
    return out


def check_settings(seed: int, noise: float) -> None:
    """Sane ``--seed`` and ``--noise``: InputError otherwise."""
    problems = []
    if not isinstance(seed, int) or isinstance(seed, bool) or seed < 0:
        problems.append(Problem("--seed", f"{seed!r}: give a whole number >= 0"))
    if not (isinstance(noise, (int, float)) and math.isfinite(noise) and 0 <= noise <= MAX_NOISE):
        problems.append(Problem("--noise", f"{noise!r}: give a scale in [0, {MAX_NOISE:g}] (0: exact)"))
    if problems:
        raise InputError("synth", problems)


# --------------------------------------------------------------------------- pilot inputs
def input_shape(spec: InputSpec, start_s: float, length_s: float, amplitude: float):
    """Breakpoints of a ramped shape (times, values)."""
    s, r, a = start_s, spec.ramp_s, amplitude
    if spec.shape == "pulse":
        return (0.0, s, s + r, s + r + length_s, s + 2 * r + length_s), (0.0, 0.0, a, a, 0.0)
    if spec.shape == "doublet":
        t1 = s + r + length_s
        return (0.0, s, s + r, t1, t1 + 2 * r, t1 + 2 * r + length_s, t1 + 3 * r + length_s), \
            (0.0, 0.0, a, a, -a, -a, 0.0)
    if spec.shape == "3211":
        times, values, t = [0.0, s], [0.0, 0.0], s
        for units, sign in ((3, 1.0), (2, -1.0), (1, 1.0), (1, -1.0)):
            times += [t + r, t + r + units * length_s]
            values += [sign * a, sign * a]
            t += r + units * length_s
        return tuple(times + [t + r]), tuple(values + [0.0])
    if spec.shape == "multisine":
        t = np.arange(0.0, length_s + 1e-9, MULTISINE_DT_S)
        return tuple([0.0, *(s + t).tolist()]), tuple([0.0, *(a * multisine(t, length_s, spec.band_hz, r)).tolist()])
    if spec.length_s is None:
        return (0.0, s, s + r), (0.0, 0.0, a)
    return (0.0, s, s + r, s + r + length_s, s + 2 * r + length_s), (0.0, 0.0, a, a, 0.0)


def _harmonics(length_s: float, band_hz: tuple[float, float]) -> list[int]:
    return [k for k in range(1, int(band_hz[1] * length_s) + 1) if band_hz[0] <= k / length_s <= band_hz[1]]


def multisine(t: np.ndarray, length_s: float, band_hz: tuple[float, float], taper_s: float) -> np.ndarray:
    """A unit-peak multisine at times ``t`` in [0, length_s]: the harmonics of 1/length_s within
    the band, Schroeder's phases (a low peak for the power it carries), tapered linearly over
    ``taper_s`` at both ends (it starts and ends at zero)."""
    ks = _harmonics(length_s, band_hz)
    n = len(ks)
    x = sum(np.sin(2.0 * np.pi * k * t / length_s - np.pi * i * (i + 1) / n) for i, k in enumerate(ks))
    taper = np.clip(np.minimum(t, length_s - t) / max(taper_s, 1e-9), 0.0, 1.0)
    x = x * taper
    peak = float(np.max(np.abs(x))) if len(x) else 0.0
    return x / peak if peak > 0 else x


def pilot_input(spec: InputSpec, duration_s: float, timing_s: float, amplitude_frac: float, rng) -> Input:
    """A pilot's rendition of an input: start, hold and (surface) amplitude scattered by the
    plan's variation; surfaces in JSBSim's signs."""
    start = max(0.0, spec.start_s + float(rng.uniform(-timing_s, timing_s)))
    length = spec.length_s if spec.length_s is not None else duration_s
    length = max(spec.ramp_s, length + float(rng.uniform(-timing_s, timing_s)))
    amp = spec.amplitude
    if spec.channel in SURFACE_OF:
        amp = to_jsbsim_sign(SURFACE_OF[spec.channel], amp * (1.0 + float(rng.uniform(-amplitude_frac,
                                                                                      amplitude_frac))))
    times, values = input_shape(spec, start, length, amp)
    return Input(spec.channel, times, values, relative=True)


def _trimmed_values(sim, start: Condition) -> dict[str, float]:
    t = sim.trim(start)
    return {"pitch": t.theta_deg, "bank": t.phi_deg, "sideslip": t.beta_deg, "airspeed": t.kcas}


def pilot_holds(sim, spec: ManeuverSpec) -> tuple[Hold, ...]:
    """The plan's loops as holds (an offset is added to the trimmed value)."""
    trimmed = _trimmed_values(sim, spec.start) if any(h.offset is not None for h in spec.holds) else {}
    out = []
    for h in spec.holds:
        target = trimmed[h.loop] + h.offset if h.offset is not None else h.target
        out.append(Hold(h.loop, target, h.start_s, h.end_s))
    return tuple(out)


def build_maneuver(sim, spec: ManeuverSpec, timing_s: float, amplitude_frac: float, rng) -> Maneuver:
    inputs = tuple(pilot_input(i, spec.duration_s, timing_s, amplitude_frac, rng) for i in spec.inputs)
    return Maneuver(file_stem_of(spec), spec.start, spec.duration_s, inputs, pilot_holds(sim, spec), title=spec.title)


def file_stem_of(spec: ManeuverSpec) -> str:
    return re.sub(r"[^A-Za-z0-9_-]+", "_", f"{spec.id}_{spec.kind}").strip("_")


# --------------------------------------------------------------------------- sensors and metadata
def sensor_errors(plan: Plan, noise: float, seed: int) -> dict[str, SensorError]:
    """Each channel's sensor error for this run: the plan's sigma and a bias drawn once (seeded),
    both scaled by ``noise``."""
    rng = np.random.default_rng([seed, 1])
    out = {}
    for ch in CHANNELS:
        if ch == "time_s":
            continue
        sigma, bias_sd = plan.noise.get(ch, (0.0, 0.0))
        bias = float(rng.standard_normal()) * bias_sd
        out[ch] = SensorError(noise * sigma, noise * bias)
    return out


def _sources(truth: str, channels: Sequence[str], plan: Plan, noise: float) -> dict[str, str]:
    out = {}
    for ch in channels:
        if ch == "time_s":
            continue
        sigma, bias_sd = plan.noise.get(ch, (0.0, 0.0))
        what = f"JSBSim {RECORD[ch][0]}" if ch in RECORD else "the surface through the control-travel table"
        unit = "" if CHANNELS[ch].unit == "-" else f" {CHANNELS[ch].unit}"
        out[ch] = (f"synthetic: {what} of the truth aircraft '{truth}'; noise sigma {noise * sigma:g}{unit}, "
                   f"constant bias drawn with sd {noise * bias_sd:g}{unit}")
    return out


def _inputs_of(spec: ManeuverSpec) -> tuple[str, ...]:
    """The channels the pilot moved: the inputs' channels and the surfaces of the loops' axes."""
    moved = {i.channel for i in spec.inputs} | {AXIS_CHANNELS[h.axis][0] for h in spec.holds}
    return tuple(c for c in CHANNELS if c in moved)


def meta_of(spec: ManeuverSpec, plan: Plan, truth: str, channels: Sequence[str], noise: float,
            holds: Sequence[Hold] = ()) -> TimeHistoryMeta:
    """The sidecar of a flown maneuver; ``holds``: the pilot loops as flown (targets resolved
    from the truth's trim), kept with their windows so that a replay flies them again."""
    c = spec.start
    notes = " ".join(x for x in (spec.notes, f"Synthetic: plan '{plan.name}', truth '{truth}'.") if x)
    return TimeHistoryMeta(spec.id, spec.title, spec.part60, spec.kind, truth,
                           Configuration(c.weight_lb, c.cg_in, c.flaps_deg, c.mixture, c.isa_dev_c),
                           plan.sample_rate_hz, _inputs_of(spec), _sources(truth, channels, plan, noise),
                           pilot_windows(holds) if holds else spec.pilot, notes)


# --------------------------------------------------------------------------- flying the plan
def control_travel(sim):
    """The aircraft's control-travel table (cockpit controls to surfaces), None without one."""
    path = sim.geometry.control_travel_file
    return load_control_travel(path) if path else None


def record_flight(sim_name: str, spec: ManeuverSpec, plan: Plan, traj, travel, noise: float,
                  errors: Mapping[str, SensorError], rng) -> TimeHistory:
    """A maneuver of the plan as flown (``traj``) recorded as format 1: every recorded channel
    (cockpit controls too, with ``travel``) at the plan's rate, with the sensor ``errors``."""
    channels = [c for c in CHANNELS if c in RECORD or c == "time_s"]
    channels += [c for c in ("column_in", "wheel_deg", "pedal_in") if travel]
    meta = meta_of(spec, plan, sim_name, channels, noise, traj.maneuver.holds)
    return trajectory_to_time_history(traj, meta, plan.sample_rate_hz, travel, errors, rng)


def fly_plan(sim, plan: Plan, *, seed: int = 0, noise: float = 1.0,
             progress: Callable[[str], None] | None = None) -> list[TimeHistory]:
    """Fly every maneuver of the plan on the truth and record it as format 1."""
    check_settings(seed, noise)
    travel = control_travel(sim)
    errors = sensor_errors(plan, noise, seed)
    out = []
    for k, spec in enumerate(plan.maneuvers):
        m = build_maneuver(sim, spec, plan.timing_s, plan.amplitude_frac, np.random.default_rng([seed, 2, k]))
        out.append(record_flight(sim.name, spec, plan, fly(sim, m), travel, noise, errors,
                                 np.random.default_rng([seed, 3, k])))
        if progress:
            progress(f"synth: {k + 1}/{len(plan.maneuvers)} {spec.id} {spec.kind}")
    return out


def synthesize_maneuvers(sim, plan: Plan, out_dir: str | Path, *, seed: int = 0, noise: float = 1.0,
                         progress: Callable[[str], None] | None = None) -> list[Path]:
    """Fly the plan and write one CSV + JSON per maneuver into ``out_dir``; every file is read
    back through the format's validation. The CSV paths."""
    written = []
    for th in fly_plan(sim, plan, seed=seed, noise=noise, progress=progress):
        csv_path, _ = write_time_history(th, out_dir)
        load_time_history(csv_path)
        written.append(csv_path)
    return written


# --------------------------------------------------------------------------- writing a plan
def _toml(v) -> str:
    if isinstance(v, str):
        return '"' + v.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(v, (tuple, list)):
        return "[" + ", ".join(_toml(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{ " + ", ".join(f"{k} = {_toml(x)}" for k, x in v.items()) + " }"
    return repr(float(v)) if isinstance(v, float) else repr(v)


def _start_table(c: Condition) -> dict:
    out: dict = {"pressure_alt_ft": c.pressure_alt_ft}
    out.update({"kcas": c.kcas} if c.kcas is not None else {"ktas": c.ktas})
    out.update(weight_lb=c.weight_lb, cg_in=c.cg_in)
    extra = {"flaps_deg": c.flaps_deg, "vs_fpm": c.vs_fpm, "bank_deg": c.bank_deg, "isa_dev_c": c.isa_dev_c}
    out.update({k: v for k, v in extra.items() if v})
    if c.mode == "full_throttle":
        out["throttle"] = c.throttle
    out["mixture"] = c.mixture
    return out


def _input_table(i: InputSpec) -> dict:
    out = {"shape": i.shape, "channel": i.channel, "amplitude": i.amplitude, "start_s": i.start_s}
    if i.length_s is not None:
        out["length_s"] = i.length_s
    out["ramp_s"] = i.ramp_s
    if i.shape == "multisine":
        out["band_hz"] = list(i.band_hz)
    return out


def _pilot_table(holds: Sequence[HoldSpec]) -> dict:
    out: dict = {}
    for h in holds:
        entry = {"loop": h.loop, "start_s": h.start_s}
        entry.update({"target": h.target} if h.target is not None else {})
        entry.update({"offset": h.offset} if h.offset is not None else {})
        entry.update({"end_s": h.end_s} if math.isfinite(h.end_s) else {})
        out.setdefault(h.axis, []).append(entry)
    return out


def plan_text(name: str, description: str, maneuvers: Sequence[ManeuverSpec], *, sample_rate_hz: float = DEFAULT_RATE_HZ,
              timing_s: float = 0.0, amplitude_frac: float = 0.0, header: str = "") -> str:
    """A plan file (this module's format) that :func:`load_plan` reads back to the same maneuvers."""
    lines = [f"# {x}" if x else "#" for x in header.splitlines()]
    lines += ["[plan]", f"name = {_toml(name)}", f"description = {_toml(description)}",
              f"sample_rate_hz = {_toml(float(sample_rate_hz))}", "", "[variation]",
              f"timing_s = {_toml(float(timing_s))}", f"amplitude_frac = {_toml(float(amplitude_frac))}"]
    for m in maneuvers:
        lines += ["", "[[maneuver]]", f"id = {_toml(m.id)}", f"kind = {_toml(m.kind)}", f"part60 = {_toml(m.part60)}",
                  f"title = {_toml(m.title)}", f"duration_s = {_toml(float(m.duration_s))}",
                  f"start = {_toml(_start_table(m.start))}"]
        if m.inputs:
            lines.append(f"inputs = {_toml([_input_table(i) for i in m.inputs])}")
        if m.holds:
            lines.append(f"pilot = {_toml(_pilot_table(m.holds))}")
        if m.notes:
            lines.append(f"notes = {_toml(m.notes)}")
    return "\n".join(lines) + "\n"
