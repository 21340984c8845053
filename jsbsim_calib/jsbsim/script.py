"""A maneuver as a JSBSim run script: initial state, engine settling, inputs and pilot loops.

The workbench flies every maneuver by running this script in JSBSim (:mod:`.trajectory`), so
JSBSim's own runner replays an exported script to the same trace, frame for frame.

How a script starts from a trimmed state. JSBSim's initialization puts a running piston
engine at its full-throttle steady state (``FGPropulsion::InitRunning``), whatever the
throttle. So the script holds the aircraft: for :data:`SETTLE_S` seconds the four state
integrators are off (the aircraft stays exactly at its trimmed state while time runs) and the
fuel is frozen, the engine and propeller settle at the trimmed throttle and mixture, and the
flaps reach their position. Then the integrators come back and the maneuver's time 0 begins.
Every property the trim set (initial state, atmosphere, controls, loading, governor, factor
values that differ from the file) is written with full precision (``repr``).

Inputs are piecewise linear in time between breakpoints (``FG_RAMP`` events, each from one
breakpoint to the next), triggered half a frame early so that a breakpoint time that the
frame clock reaches with round-off still starts on its frame. The workbench's own flights play
those events from Python (:class:`RampPlayer`, the same bits): JSBSim tests every event's
condition at every frame, and a recorded input has a breakpoint per sample.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Mapping, Sequence

from .xml import Tree, comment, element, sub, tree

# [s] engine settling: the RPM decays from full throttle's with a time constant proportional to the
# rotating inertia; with the C172's fitted inertia (K_Ip 2.12) it is 0.08 rpm from its trim at 6 s in
# cruise (1.5 rpm at 3 s), 11 rpm at idle (measured)
SETTLE_S = 6.0
INTEGRATORS = ("simulation/integrator/rate/rotational", "simulation/integrator/rate/translational",
               "simulation/integrator/position/rotational", "simulation/integrator/position/translational")
FUEL_FREEZE = "propulsion/fuel_freeze"
ENGINE_START_COMMANDS = ("fcs/throttle-cmd-norm", "fcs/mixture-cmd-norm")   # what InitRunning overwrites


@dataclass(frozen=True)
class Ramp:
    """A property that follows straight lines between breakpoints (maneuver time, value)."""

    property: str
    time_s: tuple[float, ...]
    value: tuple[float, ...]

    def __post_init__(self):
        if len(self.time_s) != len(self.value) or not self.time_s:
            raise ValueError(f"{self.property}: breakpoints need as many times as values (and at least one)")
        if any(b < a for a, b in zip(self.time_s, self.time_s[1:])):
            raise ValueError(f"{self.property}: breakpoint times must not decrease")


@dataclass(frozen=True)
class Setting:
    """A property set at a maneuver time (a pilot mode, a target, a flap lever)."""

    time_s: float
    property: str
    value: float


@dataclass
class ScriptSpec:
    """Everything a maneuver script holds (maneuver times from the end of the settling)."""

    name: str
    aircraft: str
    init_name: str
    duration_s: float
    dt_s: float
    start: dict[str, float]            # property -> value before initialization, in the order given
    integrators: dict[str, float]      # the state integrators to restore at time 0
    ramps: Sequence[Ramp] = ()
    settings: Sequence[Setting] = ()
    description: str = ""
    outputs: Sequence[str] = field(default_factory=tuple)   # properties of an optional CSV output directive


def _num(x: float) -> str:
    return repr(float(x))


@dataclass(frozen=True)
class RampEvent:
    """One event of a ramp: from the first frame at or after ``threshold`` (simulation time),
    go to ``value`` in ``tc`` seconds (0: at once)."""

    threshold: float
    value: float
    tc: float


def ramp_events(r: Ramp, dt: float) -> list[RampEvent]:
    """The events of a ramp, in the script's order: a step to its first value, then a ramp
    to each next breakpoint (a step where two breakpoints share a time), each half a frame
    early."""
    first = RampEvent(SETTLE_S + r.time_s[0] - dt / 2, r.value[0], 0.0)
    return [first] + [RampEvent(SETTLE_S + a - dt / 2, v, max(0.0, b - a))
                      for a, b, v in zip(r.time_s, r.time_s[1:], r.value[1:])]


class RampPlayer:
    """The ramps of a script played from Python, frame by frame, as JSBSim's script plays
    their events (``FGScript::RunScript``: the same order, the same arithmetic, so the same
    bits). JSBSim tests every event's condition at every frame: a recorded input with a
    breakpoint per sample is hundreds of events and costs the flight several times over;
    played here, a frame touches only the events in progress. Call it with the simulation
    time each ``FGFDMExec.run()`` will reach (it advances the clock before its script);
    ``node_of(property)`` gives JSBSim's property node."""

    def __init__(self, ramps: Sequence[Ramp], dt: float, end_s: float, node_of):
        self._ramps = [(node_of(r.property), ramp_events(r, dt)) for r in ramps]
        self._next = [0] * len(self._ramps)
        self._active: list[list[tuple]] = [[] for _ in self._ramps]    # (event, start, original, span)
        self._end = end_s

    def __call__(self, t: float) -> None:
        if t > self._end:                       # the script has ended: JSBSim runs no event
            return
        for j, (node, events) in enumerate(self._ramps):
            k, active = self._next[j], self._active[j]
            if not active and (k >= len(events) or t < events[k].threshold):
                continue
            still = [a for a in active if _play(node, a, t)]
            while k < len(events) and t >= events[k].threshold:      # triggered now: starts from the value set so far
                e, original = events[k], node.get_double_value()
                k += 1
                a = (e, t, original, e.value - original)
                if _play(node, a, t):
                    still.append(a)
            self._next[j], self._active[j] = k, still


def _play(node, active: tuple, t: float) -> bool:
    """Set an event's value at time ``t``; True while it is still ramping (FG_RAMP: the
    fraction of its time gone times its span from the value it started at)."""
    e, start, original, span = active
    gone = t - start
    if e.tc > 0 and gone <= e.tc:
        node.set_double_value(gone / e.tc * span + original)
        return True
    node.set_double_value(e.value)
    return False


def init_tree(spec: ScriptSpec) -> Tree:
    """The initialization file: a placeholder start the script's properties overwrite (JSBSim
    needs one), with the engine running."""
    root = element("initialize", name=spec.init_name)
    comment(root, f"Initial conditions of the maneuver script '{spec.name}' (jsbsim-calib): the script sets "
                  "the trimmed state itself (ic/ properties), with full precision.")
    sub(root, "ubody", _num(spec.start.get("ic/u-fps", 150.0)), unit="FT/SEC")
    sub(root, "altitude", "5000", unit="FT")
    sub(root, "running", "-1")
    return tree(root)


def _event(run, name: str, time_s: float, dt: float, sets: Sequence[tuple[str, float, dict]]):
    return _event_at(run, name, time_s - dt / 2, sets)


def _event_at(run, name: str, threshold: float, sets: Sequence[tuple[str, float, dict]]):
    ev = sub(run, "event", name=name)
    sub(ev, "condition", f"simulation/sim-time-sec ge {_num(threshold)}")
    for prop, v, extra in sets:
        sub(ev, "set", name=prop, value=_num(v), **extra)
    return ev


def script_tree(spec: ScriptSpec, output_file: str | None = None) -> Tree:
    """The run script (``output_file``: the name of an output directive file to reference)."""
    root = element("runscript", name=spec.name)
    if spec.description:
        comment(root, spec.description)
    comment(root, f"Generated by jsbsim-calib. The first {SETTLE_S:g} s hold the aircraft at its trimmed state "
                  "(state integrators off, fuel frozen) while the engine settles at the trimmed throttle; "
                  f"maneuver time 0 is simulation time {SETTLE_S:g} s. Replay with JSBSim's runner (root ROOT, script "
                  f"THIS) at the script's rate: {1 / spec.dt_s:g} Hz; the pip wheel's runner flies 120 Hz unless its "
                  "option simulation-rate says otherwise, the C++ runner takes the script's rate")
    sub(root, "use", aircraft=spec.aircraft, initialize=spec.init_name)
    if output_file:
        sub(root, "output", file=output_file)
    run = sub(root, "run", start="0.0", end=_num(SETTLE_S + spec.duration_s), dt=_num(spec.dt_s))
    for k, v in spec.start.items():
        sub(run, "property", k, value=_num(v))
    for k in INTEGRATORS:
        sub(run, "property", k, value="0")
    sub(run, "property", FUEL_FREEZE, value="1")
    dt = spec.dt_s
    _event(run, "controls after the engine start", 0.0, 0.0,
           [(k, spec.start[k], {}) for k in ENGINE_START_COMMANDS if k in spec.start])
    _event(run, "release: maneuver time 0", SETTLE_S, dt,
           [(k, v, {}) for k, v in spec.integrators.items()] + [(FUEL_FREEZE, 0.0, {})])
    for s in sorted(spec.settings, key=lambda s: s.time_s):
        _event(run, f"{s.property} at {s.time_s:g} s", SETTLE_S + s.time_s, dt, [(s.property, s.value, {})])
    for r in spec.ramps:
        for k, e in enumerate(ramp_events(r, dt)):
            extra = {"action": "FG_RAMP", "tc": _num(e.tc)} if e.tc > 0 else {}
            _event_at(run, f"{r.property} {'start' if k == 0 else k - 1}", e.threshold, [(r.property, e.value, extra)])
    return tree(root)


def output_tree(path: str, properties: Sequence[str], rate_hz: float) -> Tree:
    """A CSV output directive (JSBSim's runner writes the trace with it)."""
    root = element("output", name=path, type="CSV", rate=f"{rate_hz:g}")
    for p in properties:
        sub(root, "property", p)
    return tree(root)


def overrides(declared: Mapping[str, float], current: Mapping[str, float]) -> dict[str, float]:
    """Property values that differ from what the aircraft file declares."""
    return {k: v for k, v in current.items() if declared.get(k) != v}
