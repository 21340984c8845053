"""Flying a maneuver: trim at its start, then a JSBSim run script with inputs and pilot loops.

A :class:`Maneuver` is a start condition, a duration, open-loop inputs (surface angles or
throttle as breakpoints in time, as changes from the trim or absolute) and pilot loops
(:mod:`.pilot`: hold pitch, altitude, bank, sideslip, heading or airspeed over a time
window), mixed per axis. :func:`fly` trims the simulator's aircraft at the start, writes the
maneuver as a JSBSim script into the simulator's sandbox (:mod:`.script`), runs it in a fresh
FGFDMExec of that sandbox (the inputs' breakpoints played from Python, as the script's events
would play them) and records a :class:`Trajectory` every frame. :func:`export`
writes the same script for the aircraft as it stands in a JSBSim root, with an output
directive, so that ``jsbsim --root ROOT --script S`` replays the trace frame for frame.

Surfaces here are in JSBSim's signs (elevator + trailing edge down, aileron + roll right,
rudder + trailing edge left), as the trims give them; :mod:`jsbsim_calib.data` maps data
signs.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Mapping, Sequence

import numpy as np

from ..core.errors import ModelError, TrimError
from ..flight.condition import Condition, TrimResult
from .pilot import AXIS_OF_LOOP, MEASURED, MODE_OF_LOOP, TARGETS
from .script import INTEGRATORS, SETTLE_S, Ramp, RampPlayer, ScriptSpec, Setting, init_tree, output_tree, script_tree
from .xml import tostring, write

RATE_HZ = 60.0               # frames per second of maneuvers (the method's 60 Hz; 120 Hz moves peak rates by ~2 %)

# what a trajectory records: name -> (property, scale)
RECORD = {
    "pressure_alt_ft": ("atmosphere/pressure-altitude", 1.0), "h_ft": ("position/h-sl-ft", 1.0),
    "kcas": ("velocities/vc-kts", 1.0), "ktas": ("velocities/vtrue-kts", 1.0),
    "vs_fpm": ("velocities/h-dot-fps", 60.0),
    "pitch_deg": ("attitude/theta-deg", 1.0), "roll_deg": ("attitude/phi-deg", 1.0),
    "heading_deg": ("attitude/psi-deg", 1.0),
    "p_deg_s": ("velocities/p-rad_sec", 180.0 / math.pi), "q_deg_s": ("velocities/q-rad_sec", 180.0 / math.pi),
    "r_deg_s": ("velocities/r-rad_sec", 180.0 / math.pi),
    "alpha_deg": ("aero/alpha-deg", 1.0), "beta_deg": ("aero/beta-deg", 1.0), "nz_g": ("accelerations/Nz", 1.0),
    "elevator_deg": ("fcs/elevator-pos-deg", 1.0), "aileron_deg": ("fcs/aileron-pos-deg", 1.0),
    "rudder_deg": ("fcs/rudder-pos-deg", 1.0), "flaps_deg": ("fcs/flap-pos-deg", 1.0),
    "throttle_norm": ("fcs/throttle-pos-norm", 1.0), "rpm": ("propulsion/engine/engine-rpm", 1.0),
    "thrust_lbf": ("propulsion/engine/thrust-lbs", 1.0),
}
SURFACES = {"elevator_deg": ("fcs/elevator-cmd-norm", "horizontal_tail", "elevator"),
            "aileron_deg": ("fcs/aileron-cmd-norm", "wing", "aileron"),
            "rudder_deg": ("fcs/rudder-cmd-norm", "vertical_tail", "rudder")}
COMMANDS = {"throttle_norm": "fcs/throttle-cmd-norm", "flaps_deg": "fcs/flap-cmd-norm"}
START_STATE = ("ic/terrain-elevation-ft", "ic/h-sl-ft", "ic/phi-rad", "ic/theta-rad", "ic/psi-true-rad", "ic/u-fps",
               "ic/v-fps", "ic/w-fps", "ic/p-rad_sec", "ic/q-rad_sec", "ic/r-rad_sec", "atmosphere/delta-T",
               "fcs/elevator-cmd-norm", "fcs/aileron-cmd-norm", "fcs/rudder-cmd-norm", "fcs/throttle-cmd-norm",
               "fcs/mixture-cmd-norm", "fcs/flap-cmd-norm", "fcs/flap-pos-deg")
GOVERNOR = ("propulsion/engine/constant-speed-mode", "propulsion/engine/blade-angle", "fcs/advance-cmd-norm")


@dataclass(frozen=True)
class Input:
    """An open-loop input: a surface angle [deg, JSBSim sign] (``elevator_deg``, ``aileron_deg``,
    ``rudder_deg``), the throttle (``throttle_norm``) or the flaps (``flaps_deg``), straight
    lines between breakpoints. ``relative``: values are changes from the trimmed value."""

    channel: str
    time_s: tuple[float, ...]
    value: tuple[float, ...]
    relative: bool = True

    def __post_init__(self):
        if self.channel not in SURFACES and self.channel not in COMMANDS:
            raise ValueError(f"unknown input channel '{self.channel}'; channels: "
                             f"{', '.join([*SURFACES, *COMMANDS])}")
        if len(self.time_s) != len(self.value) or not self.time_s:
            raise ValueError(f"input {self.channel}: give as many times as values (at least one)")
        if not all(math.isfinite(v) for v in (*self.time_s, *self.value)):
            raise ValueError(f"input {self.channel}: times and values must be finite numbers")


@dataclass(frozen=True)
class Hold:
    """A pilot loop (``pitch``, ``altitude``, ``bank``, ``sideslip``, ``heading``, ``airspeed``)
    from ``start_s`` to ``end_s``; ``target`` None holds the trimmed value."""

    loop: str
    target: float | None = None
    start_s: float = 0.0
    end_s: float = math.inf

    def __post_init__(self):
        if self.loop not in MODE_OF_LOOP or self.loop == "off":
            raise ValueError(f"unknown pilot loop '{self.loop}'; loops: {', '.join(TARGETS)}")


@dataclass(frozen=True)
class Maneuver:
    """What to fly: from a trim at ``start``, ``duration_s`` seconds of inputs and pilot loops."""

    name: str
    start: Condition
    duration_s: float
    inputs: tuple[Input, ...] = ()
    holds: tuple[Hold, ...] = ()
    title: str = ""

    def __post_init__(self):
        if not (math.isfinite(self.duration_s) and 0 < self.duration_s <= 3600):
            raise ValueError(f"maneuver {self.name}: duration {self.duration_s} s is not in (0, 3600]")
        axes = [AXIS_OF_LOOP[h.loop] for h in self.holds]
        for a in set(axes):
            spans = sorted((h.start_s, h.end_s) for h in self.holds if AXIS_OF_LOOP[h.loop] == a)
            if any(s2 < e1 for (_, e1), (s2, _) in zip(spans, spans[1:])):
                raise ValueError(f"maneuver {self.name}: two pilot loops hold the {a} axis at once")


@dataclass
class Trajectory:
    """A flown maneuver: every frame from maneuver time 0 (channels of :data:`RECORD`, JSBSim
    signs), the trim it started from and the script that flew it."""

    maneuver: Maneuver
    trim: TrimResult
    time_s: np.ndarray
    channels: dict[str, np.ndarray]
    dt_s: float = 1.0 / RATE_HZ
    spec: ScriptSpec | None = None

    @property
    def script(self) -> str:
        """The run script that flies it in JSBSim's runner (its inputs as events)."""
        return tostring(script_tree(self.spec)).decode() if self.spec is not None else ""

    def __getitem__(self, name: str) -> np.ndarray:
        return self.channels[name]

    def at(self, times_s: Sequence[float]) -> dict[str, np.ndarray]:
        """Every channel at the given maneuver times (linear between frames)."""
        t = np.asarray(times_s, float)
        return {k: np.interp(t, self.time_s, v) for k, v in self.channels.items()}


# --------------------------------------------------------------------------- commands
def _surface_range(sim, channel: str) -> tuple[float, float]:
    _, surface, control = SURFACES[channel]
    c = getattr(sim.geometry, surface).control(control)
    return math.degrees(c.deflection_min_rad), math.degrees(c.deflection_max_rad)


def _to_command(deg: float, lo: float, hi: float) -> float:
    """Surface angle -> normalized command of a zero-centred aerosurface_scale."""
    return deg / hi if deg >= 0 else deg / -lo


def _from_command(cmd: float, lo: float, hi: float) -> float:
    return cmd * hi if cmd >= 0 else cmd * -lo


def surface_command(sim, channel: str, deg: float) -> float:
    """A surface angle (JSBSim's sign, degrees) as the normalized command of its channel."""
    return _to_command(deg, *_surface_range(sim, channel))


def surface_deg(sim, channel: str, command: float) -> float:
    """A surface channel's normalized command as its angle (JSBSim's sign, degrees)."""
    return _from_command(command, *_surface_range(sim, channel))


def flap_command_per_deg(sim) -> float:
    """The change of the flap command per degree of flap."""
    fmax = sim.geometry.wing.control("flap")
    return 1.0 / math.degrees(fmax.deflection_max_rad) if fmax else 1.0


def _ramp(sim, inp: Input, start: Mapping[str, float]) -> Ramp:
    """An input as a command ramp (a breakpoint added where a surface crosses zero, where the
    command's slope changes)."""
    if inp.channel in SURFACES:
        prop = SURFACES[inp.channel][0]
        lo, hi = _surface_range(sim, inp.channel)
        base = _from_command(start[prop], lo, hi) if inp.relative else 0.0
        t, v = [], []
        for k, (tk, vk) in enumerate(zip(inp.time_s, inp.value)):
            deg = base + vk
            if k and (v[-1] < 0) != (deg < 0) and deg != v[-1]:
                t0 = t[-1] + (tk - t[-1]) * (0.0 - v[-1]) / (deg - v[-1])
                t.append(t0)
                v.append(0.0)
            t.append(tk)
            v.append(deg)
        return Ramp(prop, tuple(t), tuple(_to_command(d, lo, hi) for d in v))
    prop = COMMANDS[inp.channel]
    if inp.channel == "flaps_deg":
        scale = flap_command_per_deg(sim)
        base = start[prop] if inp.relative else 0.0
        return Ramp(prop, inp.time_s, tuple(base + v * scale for v in inp.value))
    base = start[prop] if inp.relative else 0.0
    return Ramp(prop, inp.time_s, tuple(min(1.0, max(0.0, base + v)) for v in inp.value))


def _settings(hold: Hold, trim: TrimResult, fdm) -> list[Setting]:
    axis = AXIS_OF_LOOP[hold.loop]
    trimmed = {"pitch": trim.theta_deg, "altitude": fdm["position/h-sl-ft"], "bank": trim.phi_deg,
               "sideslip": trim.beta_deg, "heading": fdm[MEASURED["heading"]], "airspeed": trim.kcas}
    target = trimmed[hold.loop] if hold.target is None else hold.target
    out = [Setting(hold.start_s, TARGETS[hold.loop], target),
           Setting(hold.start_s, f"pilot/{axis}-mode", MODE_OF_LOOP[hold.loop])]
    if hold.loop == "altitude":         # the altitude loop moves the pitch target about the trimmed attitude
        out.insert(0, Setting(hold.start_s, TARGETS["pitch"], trim.theta_deg))
    if math.isfinite(hold.end_s):
        out.append(Setting(hold.end_s, f"pilot/{axis}-mode", 0))
    return out


# --------------------------------------------------------------------------- the script of a maneuver
def _start_state(sim) -> dict[str, float]:
    """The properties a trim set, in the order the script must set them."""
    fdm = sim.fdm
    keys = list(START_STATE)
    keys += [f"propulsion/tank[{i}]/contents-lbs" for i in range(len(sim.geometry.tanks))]
    keys += [f"inertia/pointmass-weight-lbs[{i}]" for i in range(len(sim.geometry.mass.stations) + 1)]
    keys += ["inertia/pointmass-location-X-inches[0]"]
    if sim.geometry.propeller.constant_speed:
        keys += list(GOVERNOR)
    out = {k: float(fdm[k]) for k in keys}
    bad = [k for k, v in out.items() if not math.isfinite(v)]
    if bad:
        raise ModelError(f"the trimmed state has non-finite values ({', '.join(bad)}): cannot fly from it")
    return out


def _spec(sim, m: Maneuver, trim: TrimResult, rate_hz: float, with_values: bool) -> ScriptSpec:
    start = _start_state(sim)
    if with_values:        # the factor and effect values the simulator flies (the sandbox file declares others)
        start.update(sim.property_values())
    ramps = [_ramp(sim, i, start) for i in m.inputs]
    settings = [s for h in m.holds for s in _settings(h, trim, sim.fdm)]
    integ = {k: float(sim.fdm[k]) for k in INTEGRATORS}
    return ScriptSpec(m.name, sim.name, f"{m.name}_init", m.duration_s, 1.0 / rate_hz, start, integ, ramps,
                      settings, description=m.title or m.name)


def _trim(sim, m: Maneuver) -> TrimResult:
    t = sim.trim(m.start)
    if not t.trimmed:
        raise TrimError(f"maneuver {m.name}: no trim at its start ({t.reason})", t.residual)
    return t


def _frames_about(times_s, n_settle: int, n: int, dt: float) -> np.ndarray:
    """Which of a flight's ``n`` frames :meth:`Trajectory.at` needs at ``times_s`` (maneuver
    times): the two about each time (and a third where the time falls on a frame, for the
    clock's round-off), and the first and last of the maneuver."""
    keep = np.zeros(n, bool)
    f = np.asarray(times_s, float) / dt
    k, r = np.floor(f).astype(int), np.round(f)
    on = r[np.abs(f - r) < 1e-6].astype(int)
    for idx in (k, k + 1, on - 1, on + 1):
        keep[np.clip(n_settle + idx, n_settle, n - 1)] = True
    keep[[n_settle, n - 1]] = True
    return keep


def fly(sim, m: Maneuver, *, rate_hz: float = RATE_HZ, at=None) -> Trajectory:
    """Trim at the maneuver's start and fly it in JSBSim; every frame from maneuver time 0, or
    with ``at`` (maneuver times) only those :meth:`Trajectory.at` needs there (the same values
    there, bit for bit; a recorded test sampled at 10 Hz on 60 Hz frames reads half of them)."""
    trim = _trim(sim, m)
    spec = _spec(sim, m, trim, rate_hz, with_values=True)
    box = sim.sandbox
    init_path = box / "aircraft" / sim.name / f"{spec.init_name}.xml"
    script_path = box / "scripts" / f"{m.name}.xml"
    write(init_tree(spec), init_path)
    write(script_tree(replace(spec, ramps=())), script_path)     # the inputs are played from here
    fdm = sim.new_exec()
    if not fdm.load_script(str(script_path)):
        raise ModelError(f"JSBSim could not load the maneuver script {script_path}")
    fdm.run_ic()
    pm = fdm.get_property_manager()
    nodes = [(pm.get_node(p), k) for k, (p, k) in RECORD.items()]
    n_settle = int(round(SETTLE_S * rate_hz))
    n = n_settle + int(round(m.duration_s * rate_hz)) + 1
    data = np.empty((n, len(nodes)))
    time = np.empty(n)
    tnode = pm.get_node("simulation/sim-time-sec")
    dt = fdm.get_delta_t()
    end = SETTLE_S + spec.duration_s + 0.99 * dt       # FGScript's end: the script's plus 0.99 frame
    inputs = RampPlayer(spec.ramps, spec.dt_s, end, lambda p: _node(pm, p, m))
    keep = np.ones(n, bool) if at is None else _frames_about(at, n_settle, n, dt)
    keep[:n_settle] = False
    for i in range(n):
        time[i] = tnode.get_double_value()
        if keep[i]:
            data[i] = [node.get_double_value() * k for node, k in nodes]
        if i < n - 1:
            inputs(time[i] + dt)        # FGFDMExec::Run advances the clock, then plays the script
            fdm.run()
    data, time = data[keep], time[keep] - time[n_settle]
    if not np.all(np.isfinite(data)):
        raise ModelError(f"maneuver {m.name}: the flight produced non-finite values")
    channels = {k: data[:, j] for j, k in enumerate(RECORD)}
    return Trajectory(m, trim, time, channels, 1.0 / rate_hz, spec)


def _node(pm, prop: str, m: Maneuver):
    node = pm.get_node(prop)
    if node is None:
        raise ModelError(f"maneuver {m.name}: the aircraft has no property {prop} to drive")
    return node


def export(sim, m: Maneuver, script_dir: Path, *, rate_hz: float = RATE_HZ,
           output_rate_hz: float | None = None, flown: Trajectory | None = None,
           init_dir: Path | None = None) -> dict[str, Path]:
    """Write the maneuver as a script for the aircraft as its JSBSim root holds it: the script
    (``script_dir/<name>.xml``), its initialization file (in the aircraft's folder) and a CSV
    output directive (``script_dir/<name>_output.xml``, written to ``<name>.csv``).

    ``flown``: a trajectory :func:`fly` returned for this maneuver: the script starts from
    its trim (a second trim of the same point agrees only to its convergence tolerance, and
    JSBSim's runner would then replay a neighbouring trace, not this one). The factor values
    come from the aircraft file either way. ``init_dir``: write the initialization file there
    instead, the script naming it by its absolute path (JSBSim reads it from there), so that
    the aircraft's folder is left as it is."""
    if flown is not None and flown.spec is not None:
        values = sim.property_values()
        spec = replace(flown.spec, start={k: v for k, v in flown.spec.start.items() if k not in values})
        rate_hz = 1.0 / spec.dt_s
    else:
        spec = _spec(sim, m, _trim(sim, m), rate_hz, with_values=False)
    props = [p for p, _ in RECORD.values()]
    script_dir = Path(script_dir)
    if init_dir is not None:
        spec = replace(spec, init_name=str(Path(init_dir).resolve() / spec.init_name))
    paths = {"script": script_dir / f"{m.name}.xml", "output": script_dir / f"{m.name}_output.xml",
             "init": sim.paths.folder / f"{spec.init_name}.xml", "csv": script_dir / f"{m.name}.csv"}
    write(init_tree(spec), paths["init"])
    write(output_tree(str(paths["csv"].resolve()), props, output_rate_hz or rate_hz), paths["output"])
    write(script_tree(spec, output_file=paths["output"].name), paths["script"])
    return paths

