"""Flight-test time histories ("format 1"): one CSV per maneuver and a JSON metadata sidecar.

A maneuver is two files with the same stem, e.g. ``C_56_phugoid.csv`` and ``C_56_phugoid.json``.

CSV: a header line of channel names (units in the names, :data:`CHANNELS`), then one row
per sample. Only ``time_s`` is required, plus at least one response channel. Every cell is a
finite number: a blank, ``nan`` or ``inf`` cell is an error, never a gap. Surfaces and
cockpit controls are in the data's signs (:mod:`.flighttest`: elevator + trailing edge up,
aileron + right trailing edge up, rudder + trailing edge right; column aft, wheel right,
right pedal forward positive). ``vs_fpm`` is geometric (dh/dt), as the trims take it.

JSON: ``test_id``, ``title``, ``part60`` (e.g. "2.c.9.b"), ``kind`` (free text: phugoid,
pitch_pulse, ...), ``aircraft``, ``configuration`` {``weight_lb``, ``cg_in``, ``flaps_deg``,
``mixture`` ("cruise" | "climb"), optional ``isa_dev_c``} at the start of the maneuver,
``sample_rate_hz``, ``inputs`` (the channels the pilot moved: surfaces, cockpit controls,
``throttle_norm``, ``flaps_deg``), ``sources`` {channel: sensor or source}, optional ``pilot``
{axis: loop} (the loops a synthetic pilot flew: axes pitch, roll, yaw, speed; loops of
:mod:`jsbsim_calib.jsbsim.pilot`) and optional ``notes``. Unknown keys are errors.

:func:`load_time_history` validates both files up front and raises one
:class:`~jsbsim_calib.core.errors.DataError` listing every problem with its file, CSV line (row)
and column, or JSON key. :func:`write_time_history` writes fixed precision per channel
(:attr:`Channel.decimals`): the same data give the same bytes. :func:`maneuver_from_time_history`
turns a record into a :class:`~jsbsim_calib.jsbsim.trajectory.Maneuver` that replays its inputs
open loop; :func:`trajectory_to_time_history` turns a flown trajectory into format 1.
"""
from __future__ import annotations

import csv
import io
import json
import math
import re
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Iterable, Mapping, Sequence

import numpy as np
import pandas as pd
from scipy.linalg import solveh_banded

from ..core.errors import DataError, InputError, Problem
from ..flight.condition import Condition
from ..jsbsim.pilot import AXIS_OF_LOOP
from ..jsbsim.trajectory import Hold, Input, Maneuver, Trajectory
from .spreadsheet import read_sheet
from .flighttest import SURFACE_METRICS, ControlAxis, load_control_travel, to_data_sign, to_jsbsim_sign


# --------------------------------------------------------------------------- channels
@dataclass(frozen=True)
class Channel:
    """A channel of format 1: unit, plausible range, written decimals and role."""

    name: str
    unit: str
    lo: float
    hi: float
    decimals: int
    role: str          # time | state | surface | control | engine
    doc: str


CHANNELS: dict[str, Channel] = {c.name: c for c in (
    Channel("time_s", "s", 0.0, 86400.0, 6, "time", "time since the start of the record"),
    Channel("pressure_alt_ft", "ft", -2000.0, 30000.0, 2, "state", "pressure altitude"),
    Channel("kcas", "kt", 0.0, 300.0, 3, "state", "calibrated airspeed"),
    Channel("ktas", "kt", 0.0, 300.0, 3, "state", "true airspeed"),
    Channel("vs_fpm", "ft/min", -10000.0, 10000.0, 2, "state", "vertical speed, geometric (dh/dt)"),
    Channel("pitch_deg", "deg", -90.0, 90.0, 4, "state", "pitch attitude"),
    Channel("roll_deg", "deg", -180.0, 180.0, 4, "state", "bank angle, + right wing down"),
    Channel("heading_deg", "deg", -360.0, 720.0, 4, "state", "heading"),
    Channel("p_deg_s", "deg/s", -400.0, 400.0, 4, "state", "body roll rate, + right wing down"),
    Channel("q_deg_s", "deg/s", -400.0, 400.0, 4, "state", "body pitch rate, + nose up"),
    Channel("r_deg_s", "deg/s", -400.0, 400.0, 4, "state", "body yaw rate, + nose right"),
    Channel("alpha_deg", "deg", -45.0, 45.0, 4, "state", "angle of attack"),
    Channel("beta_deg", "deg", -45.0, 45.0, 4, "state", "sideslip angle, + wind from the right"),
    Channel("nz_g", "g", -4.0, 7.0, 5, "state", "normal load factor, + up (1 in level flight)"),
    Channel("elevator_deg", "deg", -60.0, 60.0, 4, "surface", "elevator, + trailing edge up"),
    Channel("aileron_deg", "deg", -60.0, 60.0, 4, "surface", "aileron, + right trailing edge up (roll right)"),
    Channel("rudder_deg", "deg", -60.0, 60.0, 4, "surface", "rudder, + trailing edge right (yaw right)"),
    Channel("flaps_deg", "deg", -5.0, 45.0, 4, "surface", "flap position, + down"),
    Channel("column_in", "in", -20.0, 20.0, 5, "control", "control column, + aft"),
    Channel("wheel_deg", "deg", -180.0, 180.0, 4, "control", "control wheel, + right"),
    Channel("pedal_in", "in", -50.0, 50.0, 5, "control", "rudder pedals, + right pedal forward"),
    Channel("throttle_norm", "-", -0.1, 1.1, 5, "control", "throttle lever, 0 idle to 1 full"),
    Channel("rpm", "rpm", 0.0, 4000.0, 2, "engine", "engine speed"),
)}
RESPONSES = tuple(n for n, c in CHANNELS.items() if c.role in ("state", "engine"))
COCKPIT = {"column_in": "elevator", "wheel_deg": "aileron", "pedal_in": "rudder"}     # control -> surface
SURFACE_OF = {m: s for s, m in SURFACE_METRICS.items()}                                # elevator_deg -> elevator
INPUTS = (*SURFACE_OF, *COCKPIT, "throttle_norm", "flaps_deg")
MIXTURES = ("cruise", "climb")
PILOT_AXES = ("pitch", "roll", "yaw", "speed")
AXIS_CHANNELS = {"pitch": ("elevator_deg", "column_in"), "roll": ("aileron_deg", "wheel_deg"),
                 "yaw": ("rudder_deg", "pedal_in"), "speed": ("throttle_norm",)}
AXIS_OF_CHANNEL = {c: axis for axis, names in AXIS_CHANNELS.items() for c in names}
STEADY_LEAD_S = 1.0      # the steady start a record begins from: at most its first second
THROTTLE_STOP = 0.02     # a record starting this close to a throttle stop is trimmed at it (flight path free)
INPUT_NOISE_SIGMAS = 4.0  # a replayed input follows the record within this many standard deviations of its sample noise
MIN_LEAD_SAMPLES = 5     # a steady lead this long measures an input's noise (shorter: the input is flown as recorded)
DEPARTURE = {"throttle_norm": 0.05, "flaps_deg": 1.0, "column_in": 0.05, "pedal_in": 0.05, "wheel_deg": 2.0}
#   ... ended where an input departs from its first sample by this much (else 0.5 deg of a surface)
MAX_LISTED = 10          # problems of one kind listed per column before a count of the rest
RATE_TOLERANCE = 0.01    # sample interval vs 1 / sample_rate_hz


@dataclass(frozen=True)
class SensorError:
    """A channel's measurement error: a constant offset and Gaussian noise per sample."""

    sigma: float = 0.0
    bias: float = 0.0


# --------------------------------------------------------------------------- metadata
@dataclass(frozen=True)
class Configuration:
    """Loading and configuration at the start of the maneuver."""

    weight_lb: float
    cg_in: float
    flaps_deg: float
    mixture: str = "cruise"
    isa_dev_c: float = 0.0


@dataclass(frozen=True)
class TimeHistoryMeta:
    """The JSON sidecar of a time history."""

    test_id: str
    title: str
    part60: str
    kind: str
    aircraft: str
    configuration: Configuration
    sample_rate_hz: float
    inputs: tuple[str, ...]
    sources: Mapping[str, str]
    pilot: Mapping[str, object] = field(default_factory=dict)   # axis -> loop, or its windows (below)
    notes: str = ""

    def to_json(self) -> dict:
        c = self.configuration
        out = {"test_id": self.test_id, "title": self.title, "part60": self.part60, "kind": self.kind,
               "aircraft": self.aircraft,
               "configuration": {"weight_lb": c.weight_lb, "cg_in": c.cg_in, "flaps_deg": c.flaps_deg,
                                 "mixture": c.mixture, "isa_dev_c": c.isa_dev_c},
               "sample_rate_hz": self.sample_rate_hz, "inputs": list(self.inputs),
               "sources": {k: self.sources[k] for k in _ordered(self.sources)}}
        if self.pilot:
            out["pilot"] = {a: self.pilot[a] for a in PILOT_AXES if a in self.pilot}
        if self.notes:
            out["notes"] = self.notes
        return out


def _ordered(names: Iterable[str]) -> list[str]:
    """Channel names in the registry's order."""
    names = set(names)
    return [n for n in CHANNELS if n in names]


META_TEXT = ("test_id", "title", "part60", "kind", "aircraft")
META_KEYS = (*META_TEXT, "configuration", "sample_rate_hz", "inputs", "sources", "pilot", "notes")
META_OPTIONAL = ("pilot", "notes")
CONFIG_NUMBERS = {"weight_lb": (500.0, 20000.0), "cg_in": (-100.0, 400.0), "flaps_deg": (0.0, 45.0),
                  "isa_dev_c": (-60.0, 60.0)}
CONFIG_KEYS = (*CONFIG_NUMBERS, "mixture")


def _is_number(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


def _keys_check(doc: dict, known: Sequence[str], optional: Sequence[str], where) -> list[Problem]:
    out = [Problem(where(k), "missing") for k in known if k not in optional and k not in doc]
    out += [Problem(where(k), f"unknown key; known keys: {', '.join(known)}") for k in doc if k not in known]
    return out


def _parse_configuration(doc, where) -> tuple[Configuration | None, list[Problem]]:
    if not isinstance(doc, dict):
        return None, [Problem(where("configuration"), "must be an object {weight_lb, cg_in, flaps_deg, mixture}")]
    w = lambda k: where(f"configuration.{k}")
    problems = _keys_check(doc, CONFIG_KEYS, ("isa_dev_c",), w)
    for k, (lo, hi) in CONFIG_NUMBERS.items():
        v = doc.get(k)
        if k in doc and not (_is_number(v) and lo <= v <= hi):
            problems.append(Problem(w(k), f"{v!r} is not a number in [{lo:g}, {hi:g}]"))
    if "mixture" in doc and doc["mixture"] not in MIXTURES:
        problems.append(Problem(w("mixture"), f"{doc['mixture']!r}: use one of {', '.join(MIXTURES)}"))
    if problems:
        return None, problems
    return Configuration(float(doc["weight_lb"]), float(doc["cg_in"]), float(doc["flaps_deg"]), doc["mixture"],
                         float(doc.get("isa_dev_c", 0.0))), []


WINDOW_KEYS = ("loop", "target", "start_s", "end_s")


def _parse_window(win, axis: str, w: str) -> list[Problem]:
    """One window of a pilot loop: {"loop", optional absolute "target", "start_s", "end_s"}."""
    if not isinstance(win, dict):
        return [Problem(w, "a window must be an object {loop, target, start_s, end_s}")]
    out = [Problem(w, f"unknown key '{k}'; keys: {', '.join(WINDOW_KEYS)}") for k in win if k not in WINDOW_KEYS]
    out += _parse_loop(win.get("loop"), axis, w)
    for k in ("target", "start_s", "end_s"):
        if k in win and not _is_number(win[k]):
            out.append(Problem(f"{w}.{k}", f"{win[k]!r} is not a number"))
    if _is_number(win.get("start_s", 0.0)) and _is_number(win.get("end_s", math.inf)) \
            and not 0.0 <= win.get("start_s", 0.0) < win.get("end_s", math.inf):
        out.append(Problem(w, "needs 0 <= start_s < end_s"))
    return out


def _parse_loop(loop, axis: str, w: str) -> list[Problem]:
    if AXIS_OF_LOOP.get(loop) != axis:
        loops = [k for k, a in AXIS_OF_LOOP.items() if a == axis]
        return [Problem(w, f"{loop!r} is not a loop of the {axis} axis; loops: {', '.join(loops)}")]
    return []


def _parse_pilot(doc, where) -> list[Problem]:
    """{axis: loop} (held at the trimmed value over the whole record) or {axis: [window, ...]}
    (each window a loop, its absolute target and its times: what the pilot flew)."""
    if not isinstance(doc, dict):
        return [Problem(where("pilot"), "must be an object {axis: loop or [windows]}")]
    out = []
    for axis, loop in doc.items():
        w = where(f"pilot.{axis}")
        if axis not in PILOT_AXES:
            out.append(Problem(w, f"unknown axis; axes: {', '.join(PILOT_AXES)}"))
        elif isinstance(loop, list):
            out += [p for i, win in enumerate(loop) for p in _parse_window(win, axis, f"{w}[{i}]")]
        else:
            out += _parse_loop(loop, axis, w)
    return out


def _parse_lists(doc: dict, where) -> list[Problem]:
    out = []
    inputs = doc.get("inputs")
    if "inputs" in doc and not (isinstance(inputs, list) and all(isinstance(i, str) for i in inputs)):
        out.append(Problem(where("inputs"), "must be a list of channel names"))
    elif isinstance(inputs, list):
        for i, name in enumerate(inputs):
            if name not in INPUTS:
                out.append(Problem(where(f"inputs[{i}]"), f"'{name}' is not an input channel; inputs: "
                                                          f"{', '.join(INPUTS)}"))
        for axis, names in AXIS_CHANNELS.items():
            both = [n for n in names if n in inputs]
            if len(both) > 1:
                out.append(Problem(where("inputs"), f"{' and '.join(both)} drive the same surface: give one"))
    sources = doc.get("sources")
    if "sources" in doc and not (isinstance(sources, dict) and all(isinstance(v, str) for v in sources.values())):
        out.append(Problem(where("sources"), "must be an object {channel: text}"))
    return out


def parse_meta(doc, name: str) -> tuple[TimeHistoryMeta | None, list[Problem]]:
    """Validate a sidecar document; the metadata or None, and every problem (``name``: the
    JSON file's name, for the places)."""
    where = lambda k: f"{name}, key '{k}'"
    if not isinstance(doc, dict):
        return None, [Problem(name, "the metadata must be a JSON object")]
    problems = _keys_check(doc, META_KEYS, META_OPTIONAL, where)
    for k in META_TEXT:
        if k in doc and not (isinstance(doc[k], str) and doc[k].strip()):
            problems.append(Problem(where(k), "must be a non-empty text"))
    if "notes" in doc and not isinstance(doc["notes"], str):
        problems.append(Problem(where("notes"), "must be a text"))
    rate = doc.get("sample_rate_hz")
    if "sample_rate_hz" in doc and not (_is_number(rate) and 0 < rate <= 10000):
        problems.append(Problem(where("sample_rate_hz"), f"{rate!r} is not a rate in (0, 10000] Hz"))
    config, p = _parse_configuration(doc.get("configuration", {}), where) if "configuration" in doc else (None, [])
    problems += p + _parse_lists(doc, where)
    if "pilot" in doc:
        problems += _parse_pilot(doc["pilot"], where)
    if problems:
        return None, problems
    return TimeHistoryMeta(doc["test_id"], doc["title"], doc["part60"], doc["kind"], doc["aircraft"], config,
                           float(rate), tuple(doc["inputs"]), dict(doc["sources"]), dict(doc.get("pilot", {})),
                           doc.get("notes", "")), []


def input_times(t: np.ndarray, u: np.ndarray | None, threshold: float, lead: int = 1) -> tuple[float, float]:
    """When an input first departs from its initial value (the mean of its first ``lead``
    samples: the record's steady start) by more than ``threshold``, and from when on it stays
    back within it (a pulse's or a doublet's end; NaN: held to the end)."""
    if u is None or not np.isfinite(u[:lead]).all():
        return math.nan, math.nan
    away = np.abs(u - np.mean(u[:lead])) > threshold
    if not away.any():
        return math.nan, math.nan
    i0, i1 = int(np.argmax(away)), int(np.flatnonzero(away)[-1])
    return float(t[i0]), float(t[i1 + 1]) if i1 + 1 < t.size else math.nan


# --------------------------------------------------------------------------- the time history
@dataclass
class TimeHistory:
    """A maneuver's record: where it was read from (None: not written yet), its metadata and
    its samples (one column per channel, numeric, in the file's order)."""

    path: Path | None
    meta: TimeHistoryMeta
    frame: pd.DataFrame

    @property
    def time_s(self) -> np.ndarray:
        return self.frame["time_s"].to_numpy(float)

    @property
    def channels(self) -> tuple[str, ...]:
        return tuple(self.frame.columns)

    @property
    def stem(self) -> str:
        return self.path.stem if self.path is not None else file_stem(self.meta)

    def channel(self, name: str) -> np.ndarray:
        if name not in self.frame:
            raise KeyError(f"{self.stem}: no channel '{name}'; channels: {', '.join(self.frame.columns)}")
        return self.frame[name].to_numpy(float)

    def steady_lead(self) -> int:
        """How many leading samples hold the steady start the record begins from (at least one):
        those of its first :data:`STEADY_LEAD_S` before an input departs from its first sample
        (:data:`DEPARTURE`) or a pilot window with a target begins. Their mean, not one noisy
        sample, is the replay's trim and the reference of its inputs."""
        t = self.time_s - self.time_s[0]
        end = STEADY_LEAD_S
        for name in self.meta.inputs:
            departs = input_times(t, self.channel(name), DEPARTURE.get(name, 0.5))[0]
            end = min(end, departs) if math.isfinite(departs) else end
        for loop in self.meta.pilot.values():
            starts = [float(w.get("start_s", 0.0)) for w in loop if "target" in w] if isinstance(loop, list) else []
            end = min([end, *starts])
        return max(1, int(np.count_nonzero(t < end)))

    def initial_condition(self) -> Condition:
        """The trim condition of the steady start (the mean of :meth:`steady_lead`'s samples):
        pressure altitude, KTAS (else KCAS), vertical speed, bank (a steady coordinated turn if
        not 0), and the configuration. A record whose first sample is within
        :data:`THROTTLE_STOP` of a throttle stop (an idle glide, a full-throttle climb) is
        trimmed at that throttle with the flight path free: a level trim there is
        over-determined, and a noisy vertical speed a few feet per minute beyond the model's
        best has no trim at all."""
        missing = [c for c in ("pressure_alt_ft",) if c not in self.frame]
        if "ktas" not in self.frame and "kcas" not in self.frame:
            missing.append("ktas or kcas")
        if missing:
            raise DataError(self.path or self.stem, Problem("columns", f"the initial condition needs "
                                                                       f"{', '.join(missing)}"))
        first = self.frame.iloc[:self.steady_lead()].mean()
        speed = {"ktas": float(first["ktas"])} if "ktas" in self.frame else {"kcas": float(first["kcas"])}
        bank = float(first["roll_deg"]) if "roll_deg" in self.frame else 0.0
        c = self.meta.configuration
        thr = float(self.frame["throttle_norm"].iloc[0]) if "throttle_norm" in self.frame else 0.5
        at_stop = math.isfinite(thr) and min(thr, abs(1.0 - thr)) <= THROTTLE_STOP
        stop = {"mode": "full_throttle", "throttle": float(round(thr))} if at_stop else {"mode": "level"}
        return Condition(pressure_alt_ft=float(first["pressure_alt_ft"]), weight_lb=c.weight_lb, cg_in=c.cg_in,
                         flaps_deg=c.flaps_deg, **stop,
                         vs_fpm=float(first["vs_fpm"]) if "vs_fpm" in self.frame else 0.0,
                         bank_deg=bank, turn="coordinated" if bank != 0.0 else "straight", mixture=c.mixture,
                         isa_dev_c=c.isa_dev_c, **speed)


def file_stem(meta: TimeHistoryMeta) -> str:
    """The default file stem of a record: test id and kind (``C.56`` phugoid -> ``C_56_phugoid``)."""
    return re.sub(r"[^A-Za-z0-9_-]+", "_", f"{meta.test_id}_{meta.kind}").strip("_")


# --------------------------------------------------------------------------- checks
def _capped(problems: list[Problem], what: str) -> list[Problem]:
    """At most MAX_LISTED problems of one kind, then a count of the rest."""
    if len(problems) <= MAX_LISTED:
        return problems
    return problems[:MAX_LISTED] + [Problem(problems[MAX_LISTED].where, f"and {len(problems) - MAX_LISTED} more "
                                                                         f"rows: {what}")]


def _cell(name: str, row: int, column: str) -> str:
    return f"{name}, line {row + 2} (row {row + 1}), column '{column}'"


def _check_columns(columns: Sequence[str], name: str) -> list[Problem]:
    out = []
    for c in sorted({c for c in columns if list(columns).count(c) > 1}):
        out.append(Problem(f"{name}, line 1, column '{c}'", "appears more than once"))
    for c in columns:
        if c not in CHANNELS:
            out.append(Problem(f"{name}, line 1, column '{c}'", f"unknown channel; known: {', '.join(CHANNELS)}"))
    if "time_s" not in columns:
        out.append(Problem(f"{name}, line 1, column 'time_s'", "missing (required)"))
    if not any(c in RESPONSES for c in columns):
        out.append(Problem(f"{name}, line 1", f"no response channel: give at least one of {', '.join(RESPONSES)}"))
    return out


def _check_time(t: np.ndarray, rate_hz: float | None, name: str) -> list[Problem]:
    if t.size < 2:
        return [Problem(name, f"{t.size} sample(s): a time history needs at least two")]
    dt = np.diff(t)
    bad = [Problem(_cell(name, i + 1, "time_s"), f"{t[i + 1]:g} s does not follow {t[i]:g} s (time must increase "
                                                 "strictly)") for i in np.flatnonzero(~(dt > 0))]
    out = _capped(bad, "time not increasing")
    if rate_hz and not bad:
        step = 1.0 / rate_hz
        off = np.flatnonzero(np.abs(dt - step) > RATE_TOLERANCE * step)
        out += _capped([Problem(_cell(name, i + 1, "time_s"),
                                f"interval {dt[i]:.6g} s differs from 1/sample_rate_hz = {step:.6g} s by more than "
                                f"{RATE_TOLERANCE:.0%}") for i in off], "sample interval off the sample rate")
    return out


def _check_ranges(frame: pd.DataFrame, name: str) -> list[Problem]:
    out = []
    for col in frame.columns:
        ch = CHANNELS.get(col)
        if ch is None:
            continue
        v = frame[col].to_numpy(float)
        rows = np.flatnonzero(np.isfinite(v) & ((v < ch.lo) | (v > ch.hi)))
        unit = "" if ch.unit == "-" else f" {ch.unit}"
        out += _capped([Problem(_cell(name, i, col), f"{v[i]:g}{unit} is outside the plausible range "
                                                     f"[{ch.lo:g}, {ch.hi:g}]") for i in rows], "outside range")
    return out


def _check_against_columns(doc: Mapping, columns: Sequence[str], json_name: str) -> list[Problem]:
    """Inputs and sources of a sidecar (checked or not) that name no column of the CSV."""
    out = []
    inputs = doc.get("inputs")
    for i, c in enumerate(inputs if isinstance(inputs, (list, tuple)) else ()):
        if isinstance(c, str) and c not in columns:
            out.append(Problem(f"{json_name}, key 'inputs[{i}]'", f"'{c}' is not a column of the CSV"))
    sources = doc.get("sources")
    for c in sources if isinstance(sources, Mapping) else ():
        if c not in columns:
            out.append(Problem(f"{json_name}, key 'sources.{c}'", f"'{c}' is not a column of the CSV"))
    return out


def check_time_history(th: TimeHistory, name: str | None = None) -> list[Problem]:
    """Every problem of a time history in memory (columns, non-finite values, time, ranges,
    metadata against columns)."""
    name = name or f"{th.stem}.csv"
    _, meta_problems = parse_meta(th.meta.to_json(), f"{th.stem}.json")
    cols = list(th.frame.columns)
    out = _check_columns(cols, name)
    if out or meta_problems:
        return out + meta_problems
    data = th.frame.to_numpy(float)
    for i, j in zip(*np.nonzero(~np.isfinite(data))):
        out.append(Problem(_cell(name, int(i), cols[j]), f"{data[i, j]} is not a finite number"))
    out = _capped(out, "non-finite values")
    if not out:
        out += _check_time(th.time_s, th.meta.sample_rate_hz, name) + _check_ranges(th.frame, name)
    return out + _check_against_columns(th.meta.to_json(), cols, f"{th.stem}.json")


# --------------------------------------------------------------------------- reading
def _read_rows(path: Path) -> tuple[list[str], list[list[str]], list[Problem]]:
    if not path.is_file():
        return [], [], [Problem(path.name, "file not found")]
    try:
        text = read_sheet(path).text        # any separator, decimal commas, BOM, UTF-16, header case
    except DataError as exc:
        return [], [], [Problem(path.name + (f", {p.where}" if p.where else ""), p.message) for p in exc.problems]
    rows = list(csv.reader(io.StringIO(text)))
    if not rows:
        return [], [], [Problem(path.name, "empty file (no header line)")]
    header = [h.strip() for h in rows[0]]
    body = rows[1:]
    problems = [Problem(f"{path.name}, line {i + 2} (row {i + 1})", f"{len(r)} fields, the header has {len(header)}")
                for i, r in enumerate(body) if len(r) != len(header)]
    return header, body, _capped(problems, "wrong number of fields")


def _parse_cells(header: list[str], body: list[list[str]], name: str) -> tuple[pd.DataFrame, list[Problem]]:
    """The cells as numbers; every blank, non-numeric or non-finite cell is a problem."""
    problems = []
    cols = {}
    for j, col in enumerate(header):
        text = [r[j].strip() if j < len(r) else "" for r in body]
        values = pd.to_numeric(pd.Series(text, dtype=object), errors="coerce").to_numpy(float)
        bad = []
        for i in np.flatnonzero(~np.isfinite(values)):
            t = text[i]
            why = "empty cell (a gap is not allowed)" if t == "" else \
                f"'{t}' is not a finite number" if t.lower().lstrip("+-") in ("nan", "inf", "infinity") else \
                f"'{t}' is not a number"
            bad.append(Problem(_cell(name, int(i), col), why))
        problems += _capped(bad, f"cells that are not numbers in column '{col}'")
        cols[col] = values
    return pd.DataFrame(cols, columns=header), problems


def _read_meta(path: Path) -> tuple[TimeHistoryMeta | None, dict, list[Problem]]:
    """The sidecar: the metadata (None if invalid), the raw document and every problem."""
    if not path.is_file():
        return None, {}, [Problem(path.name, f"metadata sidecar missing: expected {path.name} next to the CSV")]
    try:
        doc = json.loads(path.read_text())
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        line = f", line {exc.lineno}" if isinstance(exc, json.JSONDecodeError) else ""
        return None, {}, [Problem(f"{path.name}{line}", f"not valid JSON: {exc}")]
    meta, problems = parse_meta(doc, path.name)
    return meta, doc if isinstance(doc, dict) else {}, problems


def load_time_history(path: str | Path) -> TimeHistory:
    """Read and validate a record (the CSV; its sidecar has the same stem). Raises
    :class:`DataError` listing every problem of both files."""
    path = Path(path)
    if path.suffix.lower() == ".json":
        path = path.with_suffix(".csv")
    json_path = path.with_suffix(".json")
    meta, doc, problems = _read_meta(json_path)
    header, body, p = _read_rows(path)
    problems += p
    if not header:
        raise DataError(path, problems)
    problems += _check_columns(header, path.name)
    frame, p = _parse_cells(header, body, path.name)
    problems += p
    if "time_s" in frame and np.all(np.isfinite(frame["time_s"].to_numpy(float))):
        problems += _check_time(frame["time_s"].to_numpy(float), meta.sample_rate_hz if meta else None, path.name)
    problems += _check_ranges(frame, path.name)
    problems += _check_against_columns(doc, header, json_path.name)
    if problems:
        raise DataError(path, problems)
    return TimeHistory(path, meta, frame)


def load_time_histories(dir_or_files: str | Path | Sequence[str | Path]) -> list[TimeHistory]:
    """Every record of a directory (each ``*.csv`` with a sidecar, sorted by name) or of a
    list of CSV files. Raises one :class:`DataError` listing the problems of every file."""
    if isinstance(dir_or_files, (str, Path)) and Path(dir_or_files).is_dir():
        d = Path(dir_or_files)
        files = sorted(p for p in d.glob("*.csv") if p.with_suffix(".json").is_file())
        if not files:
            lone = sorted(d.glob("*.csv"))[:10]
            raise DataError(d, [Problem(p.name, f"metadata sidecar missing: expected {p.with_suffix('.json').name} "
                                                "next to it") for p in lone]
                            or "no time histories here (a CSV file with a JSON sidecar of the same stem)")
        source = d
    else:
        items = [dir_or_files] if isinstance(dir_or_files, (str, Path)) else list(dir_or_files)
        files = [Path(f) for f in items]
        if not files:
            raise DataError("time histories", "no files given")
        source = files[0] if len(files) == 1 else files[0].parent
    out, problems = [], []
    for f in files:
        try:
            out.append(load_time_history(f))
        except DataError as exc:
            problems += exc.problems
    if problems:
        raise DataError(source, problems)
    return out


# --------------------------------------------------------------------------- writing
def _format(value: float, decimals: int) -> str:
    s = f"{value:.{decimals}f}"
    return s[1:] if s.startswith("-") and float(s) == 0.0 else s


def csv_text(th: TimeHistory) -> str:
    """The CSV of a record: registry order of the channels, fixed decimals per channel."""
    cols = _ordered(th.frame.columns)
    data = th.frame[cols].to_numpy(float)
    dec = [CHANNELS[c].decimals for c in cols]
    lines = [",".join(cols)]
    lines += [",".join(_format(v, d) for v, d in zip(row, dec)) for row in data]
    return "\n".join(lines) + "\n"


def write_time_history(th: TimeHistory, directory: str | Path) -> tuple[Path, Path]:
    """Write ``<stem>.csv`` and ``<stem>.json`` into ``directory`` (created); the paths.
    Refuses (DataError) a record that would not load back."""
    problems = check_time_history(th)
    if problems:
        raise DataError(th.stem, problems)
    d = Path(directory)
    d.mkdir(parents=True, exist_ok=True)
    csv_path, json_path = d / f"{th.stem}.csv", d / f"{th.stem}.json"
    csv_path.write_bytes(csv_text(th).encode())
    json_path.write_bytes((json.dumps(th.meta.to_json(), indent=2) + "\n").encode())
    return csv_path, json_path


# --------------------------------------------------------------------------- replay
def _breakpoints(t: np.ndarray, v: np.ndarray, tol: float) -> tuple[tuple[float, ...], tuple[float, ...]]:
    """The fewest samples whose polyline passes within ``tol`` of every sample (greedy: a
    segment grows while the samples it spans stay within ``tol`` of its chord). With ``tol``
    the written resolution, the corners of a recorded ramp are found again."""
    keep, a, j = [0], 0, 2
    while j < t.size:
        span = slice(a + 1, j)
        chord = v[a] + (v[j] - v[a]) * (t[span] - t[a]) / (t[j] - t[a])
        if np.any(np.abs(v[span] - chord) > tol):
            a = j - 1
            keep.append(a)
        j += 1
    if t.size > 1:
        keep.append(t.size - 1)
    return tuple(float(t[k]) for k in keep), tuple(float(v[k]) for k in keep)


def fitted_polyline(t: np.ndarray, v: np.ndarray, knots: np.ndarray) -> np.ndarray:
    """The values at ``knots`` (sample times, increasing, the first and last of ``t`` among
    them) of the polyline closest to the samples ``v`` in least squares: a flat stretch of a
    noisy input is held at its mean, not at one sample."""
    j = np.clip(np.searchsorted(knots, t, side="right") - 1, 0, knots.size - 2)
    w = (t - knots[j]) / (knots[j + 1] - knots[j])
    a, n = 1.0 - w, knots.size
    diag = np.bincount(j, a * a, n) + np.bincount(j + 1, w * w, n)
    upper = np.concatenate(([0.0], np.bincount(j, a * w, n)[:-1]))
    rhs = np.bincount(j, a * v, n) + np.bincount(j + 1, w * v, n)
    return solveh_banded(np.vstack((upper, diag)), rhs)


def noise_sigma(x: np.ndarray) -> float:
    """The sample noise of a smooth signal: the robust spread of its second differences."""
    if x.size < 3:
        return 0.0
    return float(np.median(np.abs(np.diff(x, 2)))) / 0.6745 / math.sqrt(6.0)


def _resolution(name: str, travel: Mapping[str, ControlAxis] | None) -> float:
    """The written resolution of an input channel, in the units of its maneuver channel
    (a cockpit control's through the steepest slope of its surface map)."""
    lsb = 1.01 * 10.0 ** -CHANNELS[name].decimals
    if name in COCKPIT and travel and COCKPIT[name] in travel:
        ax = travel[COCKPIT[name]]
        slope = max(abs(ax.surface_max_deg / (ax.control_max - ax.neutral)),
                    abs(ax.surface_min_deg / (ax.control_min - ax.neutral)))
        return lsb * slope
    return lsb


def _input_series(th: TimeHistory, name: str, travel: Mapping[str, ControlAxis] | None) -> tuple[str, np.ndarray]:
    """An input channel as a maneuver channel and its values (surfaces in JSBSim's signs)."""
    x = th.channel(name)
    if name in SURFACE_OF:
        surface = SURFACE_OF[name]
        return name, to_jsbsim_sign(surface, x)
    if name in COCKPIT:
        surface = COCKPIT[name]
        if not travel or surface not in travel:
            raise InputError(th.path or th.stem, Problem(f"inputs: {name}", "a cockpit control needs the aircraft's "
                                                                            "control-travel table to move its surface"))
        ax = travel[surface]
        deg = np.array([ax.surface_deg(float(c)) for c in x])
        return SURFACE_METRICS[surface], to_jsbsim_sign(surface, deg)
    return name, x


def _holds(pilot: Mapping[str, object] | None, source) -> tuple[Hold, ...]:
    problems = _parse_pilot(dict(pilot or {}), lambda k: k)
    if problems:
        raise InputError(source, problems)
    out = []
    for axis, loop in (pilot or {}).items():
        if isinstance(loop, list):
            out += [Hold(w["loop"], w.get("target"), float(w.get("start_s", 0.0)), float(w.get("end_s", math.inf)))
                    for w in loop]
        else:
            out.append(Hold(loop))
    return tuple(out)


def pilot_windows(holds: Sequence[Hold]) -> dict[str, object]:
    """Pilot loops as the sidecar keeps them: a loop held at the trim over the whole record as
    its name, any other as its windows (absolute targets: what the pilot flew)."""
    out: dict[str, object] = {}
    for h in holds:
        axis = AXIS_OF_LOOP[h.loop]
        if h.target is None and h.start_s == 0.0 and not math.isfinite(h.end_s) and axis not in out:
            out[axis] = h.loop
            continue
        win = {"loop": h.loop, **({"target": round(float(h.target), 6)} if h.target is not None else {}),
               "start_s": float(h.start_s), **({"end_s": float(h.end_s)} if math.isfinite(h.end_s) else {})}
        prev = out.get(axis)
        out[axis] = (prev if isinstance(prev, list) else ([{"loop": prev}] if prev else [])) + [win]
    return out


def input_noise(x: np.ndarray, lead: int) -> float:
    """A recorded input's sample noise: the spread of its steady lead's samples, or of its
    second differences (:func:`noise_sigma`) where that is smaller (a busy input, a multisine,
    moves its differences too). 0 where the lead is shorter than :data:`MIN_LEAD_SAMPLES`:
    the differences alone cannot tell a busy input from noise, so it is flown as recorded."""
    return min(noise_sigma(x), float(np.std(x[:lead], ddof=1))) if lead >= MIN_LEAD_SAMPLES else 0.0


def _polyline(t: np.ndarray, x: np.ndarray, resolution: float, sigma: float) -> tuple[tuple[float, ...], tuple[float, ...]]:
    """A recorded input as breakpoints (:func:`_breakpoints`): within its written resolution,
    or, where the samples are noisier, within :data:`INPUT_NOISE_SIGMAS` of their noise
    ``sigma`` with the values fitted to the samples (:func:`fitted_polyline`), so that sensor
    noise on a surface is not flown as surface motion."""
    noise = INPUT_NOISE_SIGMAS * sigma
    times, values = _breakpoints(t, x, max(resolution, noise))
    if noise > resolution and len(times) > 1:
        values = tuple(float(v) for v in fitted_polyline(t, x, np.array(times)))
    return times, values


def _loop_spans(pilot: Mapping[str, object] | None) -> dict[str, list[tuple[float, float]]]:
    """Axis -> the (start, end) times its loops fly (a loop named alone: the whole record)."""
    out = {}
    for axis, loop in (pilot or {}).items():
        windows = loop if isinstance(loop, list) else [{}]
        out[axis] = [(float(w.get("start_s", 0.0)), float(w.get("end_s", math.inf))) for w in windows]
    return out


def _outside(inp: Input, spans: Sequence[tuple[float, float]], t: np.ndarray) -> Input:
    """``inp`` with no change from the trim inside ``spans`` (edges included), where the model's
    own pilot flies the axis: a recorded surface is there the record's pilot's output, and
    replaying it under the loop would count the correction twice. The recorded input ends one
    sample (of ``t``) before a loop takes over and resumes one sample after it lets go."""
    kt, kv = np.asarray(inp.time_s, float), np.asarray(inp.value, float)
    times = set(kt.tolist())
    for a, b in spans:
        times |= {x for x in (a, b) if kt[0] < x < kt[-1]}
        times |= set(t[t < a][-1:].tolist()) | set(t[t > b][:1].tolist())
    times = sorted(times)
    values = [0.0 if any(a <= x <= b for a, b in spans) else float(np.interp(x, kt, kv)) for x in times]
    return replace(inp, time_s=tuple(times), value=tuple(values))


def _travel(geometry, travel: Mapping[str, ControlAxis] | None) -> Mapping[str, ControlAxis] | None:
    if travel is None and geometry is not None and getattr(geometry, "control_travel_file", None):
        return load_control_travel(geometry.control_travel_file)
    return travel


def reference_errors(th: TimeHistory, geometry=None, *,
                     travel: Mapping[str, ControlAxis] | None = None) -> dict[str, float]:
    """Per replayed input (its maneuver channel), the standard error of the level a replay
    flies it from: the mean of the steady lead's samples (:meth:`TimeHistory.steady_lead`),
    so its sample noise (:func:`input_noise`) over the square root of the lead's length; 0
    where the lead is too short to measure the noise."""
    travel, lead = _travel(geometry, travel), th.steady_lead()
    return {channel: input_noise(x, lead) / math.sqrt(lead)
            for channel, x in (_input_series(th, name, travel) for name in th.meta.inputs)}


def maneuver_from_time_history(th: TimeHistory, geometry=None, pilot: Mapping[str, str] | None = None, *,
                               travel: Mapping[str, ControlAxis] | None = None) -> Maneuver:
    """A maneuver that replays the record: from the trim at its steady start
    (:meth:`TimeHistory.initial_condition`), every input channel as an open-loop change from
    its value there (the mean of :meth:`TimeHistory.steady_lead`'s samples; straight
    lines between samples; cockpit controls through the control-travel table: ``travel``,
    else the table of ``geometry``, with the table's linear neutrals). ``pilot`` {axis: loop}
    adds pilot loops holding the trimmed value on those axes, {axis: [windows]} the loops
    with the targets and times the record keeps; while a loop flies its axis, the axis's
    recorded input is not replayed (:func:`_outside`: it is the record's pilot's output), so a
    model replaying its own record flies it again."""
    travel = _travel(geometry, travel)
    holds, flown = _holds(pilot, th.path or th.stem), _loop_spans(pilot)
    t = th.time_s - th.time_s[0]
    lead = th.steady_lead()
    inputs = []
    for name in th.meta.inputs:
        channel, x = _input_series(th, name, travel)
        inp = Input(channel, *_polyline(t, x - np.mean(x[:lead]), _resolution(name, travel), input_noise(x, lead)),
                    relative=True)
        spans = flown.get(AXIS_OF_CHANNEL.get(name, ""))
        if spans:
            inp = _outside(inp, spans, t)
            if not any(inp.value):
                continue
        inputs.append(inp)
    name = re.sub(r"[^A-Za-z0-9_-]+", "_", th.stem)
    return Maneuver(name, th.initial_condition(), float(t[-1]), tuple(inputs), holds,
                    title=th.meta.title)


# --------------------------------------------------------------------------- from a flown trajectory
def sample_times(duration_s: float, rate_hz: float) -> np.ndarray:
    """Data times 0, 1/rate, ... up to the duration (included when it falls on a sample)."""
    n = int(math.floor(duration_s * rate_hz + 1e-6)) + 1
    return np.arange(n) / rate_hz


def _true_channels(traj: Trajectory, times: np.ndarray, travel: Mapping[str, ControlAxis] | None,
                   channels: Sequence[str] | None) -> dict[str, np.ndarray]:
    at = traj.at(times)
    out = {"time_s": times}
    for name in CHANNELS:
        if name in SURFACE_OF:
            out[name] = to_data_sign(SURFACE_OF[name], at[name])
        elif name in at:
            out[name] = at[name]
    for name, surface in COCKPIT.items():
        if travel and surface in travel:
            out[name] = np.array([travel[surface].control_position(float(s)) for s in out[SURFACE_METRICS[surface]]])
    if channels is not None:
        unknown = [c for c in channels if c not in out]
        if unknown:
            raise InputError("channels", f"not available from the trajectory: {', '.join(unknown)}")
        out = {k: v for k, v in out.items() if k == "time_s" or k in channels}
    return out


def _measured(values: dict[str, np.ndarray], noise: Mapping[str, SensorError] | None, rng) -> dict[str, np.ndarray]:
    out = {}
    for name, v in values.items():
        e = (noise or {}).get(name)
        if name != "time_s" and e is not None and (e.sigma or e.bias):
            v = v + e.bias + (e.sigma * rng.standard_normal(v.size) if e.sigma else 0.0)
        v = np.round(v, CHANNELS[name].decimals)
        out[name] = np.mod(v, 360.0) if name == "heading_deg" else v
    return out


def trajectory_to_time_history(traj: Trajectory, meta: TimeHistoryMeta, sample_rate_hz: float,
                               travel: Mapping[str, ControlAxis] | None = None,
                               noise: Mapping[str, SensorError] | None = None, rng=None, *,
                               channels: Sequence[str] | None = None) -> TimeHistory:
    """A flown trajectory (JSBSim's signs, every frame) as format 1: the frames at the data
    times (linear between frames), surfaces in the data's signs, cockpit controls from the
    surfaces through ``travel`` (when given), each channel with its sensor error (``noise``:
    channel -> :class:`SensorError`, drawn from ``rng``), rounded to the written decimals.
    ``channels``: the channels to keep (default: every one available). The metadata's
    sample rate is set to ``sample_rate_hz``."""
    if not (math.isfinite(sample_rate_hz) and sample_rate_hz > 0):
        raise InputError("sample_rate_hz", f"{sample_rate_hz!r} is not a positive rate")
    times = sample_times(traj.maneuver.duration_s, sample_rate_hz)
    rng = rng if rng is not None else np.random.default_rng(0)
    values = _measured(_true_channels(traj, times, travel, channels), noise, rng)
    frame = pd.DataFrame({k: values[k] for k in _ordered(values)})
    th = TimeHistory(None, replace(meta, sample_rate_hz=float(sample_rate_hz)), frame)
    problems = check_time_history(th)
    if problems:
        raise DataError(th.stem, problems)
    return th
