"""The test pilot: PID loops a maneuver can hand an axis to, as a JSBSim system in the aircraft.

The method's pilot model holds altitude or pitch with the column, bank with the wheel,
sideslip or heading with the pedals and airspeed with the throttle. It lives in the aircraft
file (``<system name="test pilot">``), so JSBSim's own runner flies a maneuver script exactly
as the workbench does. Every loop is off until a script switches it on (``pilot/<axis>-mode``);
off, its output is exactly zero and the aircraft trims and flies as without it.

Each loop adds an increment to the cockpit command of its axis (``fcs/pilot-<axis>-cmd-norm``,
summed into the flight-control channels with the recorded or scripted command): open-loop
inputs and the pilot mix per axis. The derivative acts on the measured body rate (no kick
when a target steps); integrators are clipped (no wind-up) and do not move at zero time
step (trims). Gains are properties, in command units per degree (per knot, per foot), with
defaults for a light single; a script can set them.
"""
from __future__ import annotations

from dataclasses import dataclass

from .xml import comment, operation, prop, sub, value

PILOT_SYSTEM = "test pilot"

# modes of each axis (pilot/<axis>-mode)
PITCH_MODES = {"off": 0, "pitch": 1, "altitude": 2}
ROLL_MODES = {"off": 0, "bank": 1}
YAW_MODES = {"off": 0, "sideslip": 1, "heading": 2}
SPEED_MODES = {"off": 0, "airspeed": 1}
AXIS_OF_LOOP = {"pitch": "pitch", "altitude": "pitch", "bank": "roll", "sideslip": "yaw", "heading": "yaw",
                "airspeed": "speed"}
MODE_OF_LOOP = {**PITCH_MODES, **ROLL_MODES, **YAW_MODES, **SPEED_MODES}
TARGETS = {"pitch": "pilot/pitch-target-deg", "altitude": "pilot/altitude-target-ft",
           "bank": "pilot/roll-target-deg", "sideslip": "pilot/beta-target-deg",
           "heading": "pilot/heading-target-deg", "airspeed": "pilot/kcas-target"}
MEASURED = {"pitch": "attitude/theta-deg", "altitude": "position/h-sl-ft", "bank": "attitude/phi-deg",
            "sideslip": "aero/beta-deg", "heading": "attitude/psi-deg", "airspeed": "velocities/vc-kts"}
OUTPUTS = {"pitch": "fcs/pilot-elevator-cmd-norm", "roll": "fcs/pilot-aileron-cmd-norm",
           "yaw": "fcs/pilot-rudder-cmd-norm", "speed": "fcs/pilot-throttle-cmd-norm"}


@dataclass(frozen=True)
class Gains:
    """Default gains (command units per degree, degree per second, knot or foot)."""

    pitch_kp: float = 0.06        # elevator per deg of pitch error
    pitch_ki: float = 0.02        # per deg s
    pitch_kd: float = 0.03        # per deg/s of pitch-attitude rate
    altitude_kp: float = 0.05     # deg of pitch per ft of altitude error
    altitude_kd: float = 0.15     # deg of pitch per ft/s of vertical speed
    altitude_max_deg: float = 8.0  # largest pitch change the altitude loop asks for
    roll_kp: float = 0.04
    roll_ki: float = 0.005
    roll_kd: float = 0.01
    sideslip_kp: float = 0.15     # rudder per deg of sideslip
    sideslip_ki: float = 0.05
    heading_kp: float = 0.05      # rudder per deg of heading error
    yaw_kd: float = 0.03          # rudder per deg/s of sideslip rate (any yaw mode)
    speed_kp: float = 0.05        # throttle per knot
    speed_ki: float = 0.01


GAINS = Gains()


def gain_property(name: str) -> str:
    return f"pilot/gain/{name.replace('_', '-')}"


def _mode_is(axis: str, mode: int):
    return operation("eq", prop(f"pilot/{axis}-mode"), value(mode))


def _mode_on(axis: str):
    return operation("gt", prop(f"pilot/{axis}-mode"), value(0))


def _g(name: str):
    return prop(gain_property(name))


def _fcs_function(channel, name: str, expression, clip: tuple[float, float] | None = None, output: str | None = None):
    fn = sub(channel, "fcs_function", name=name)
    sub(fn, "function").append(expression)
    if clip:
        c = sub(fn, "clipto")
        sub(c, "min", f"{clip[0]:g}")
        sub(c, "max", f"{clip[1]:g}")
    if output:
        sub(fn, "output", output)


def _integrator(channel, name: str, error: str, limit: float) -> None:
    it = sub(channel, "integrator", name=name)
    sub(it, "input", error)
    sub(it, "c1", "1")
    c = sub(it, "clipto")
    sub(c, "min", f"{-limit:g}")
    sub(c, "max", f"{limit:g}")


def _difference_if(on, target: str, measured: str):
    return operation("product", operation("difference", prop(target), prop(measured)), on)


def pilot_system(root) -> None:
    """Append the test-pilot system to an aircraft's root element (before its flight control)."""
    sy = sub(root, "system", name=PILOT_SYSTEM)
    comment(sy, "Test pilot of jsbsim-calib (jsbsim_calib.jsbsim.pilot): PID loops a maneuver script switches on. "
                "pilot/pitch-mode 0 off, 1 hold pilot/pitch-target-deg, 2 hold pilot/altitude-target-ft; "
                "pilot/roll-mode 1 holds pilot/roll-target-deg; pilot/yaw-mode 1 holds pilot/beta-target-deg, "
                "2 holds pilot/heading-target-deg; pilot/speed-mode 1 holds pilot/kcas-target with the throttle. "
                "Each adds fcs/pilot-<axis>-cmd-norm to its channel's command; off it adds exactly 0.")
    for axis in ("pitch", "roll", "yaw", "speed"):
        sub(sy, "property", f"pilot/{axis}-mode", value="0")
    for t in TARGETS.values():
        sub(sy, "property", t, value="0")
    for name, v in GAINS.__dict__.items():
        sub(sy, "property", gain_property(name), value=f"{v:g}")

    ch = sub(sy, "channel", name="pilot pitch")
    # altitude mode: the pitch target moves with the altitude error, damped by the vertical speed
    _fcs_function(ch, "pilot/altitude-pitch-deg", operation("product", _mode_is("pitch", 2), operation(
        "difference", operation("product", _g("altitude_kp"),
                                operation("difference", prop(TARGETS["altitude"]), prop(MEASURED["altitude"]))),
        operation("product", _g("altitude_kd"), prop("velocities/h-dot-fps")))),
        clip=(-GAINS.altitude_max_deg, GAINS.altitude_max_deg))
    _fcs_function(ch, "pilot/pitch-error-deg", operation("product", _mode_on("pitch"), operation(
        "difference", operation("sum", prop(TARGETS["pitch"]), prop("pilot/altitude-pitch-deg")),
        prop(MEASURED["pitch"]))))
    _integrator(ch, "pilot/pitch-integral", "pilot/pitch-error-deg", 1.0 / GAINS.pitch_ki)
    _fcs_function(ch, "pilot/elevator", operation("product", _mode_on("pitch"), operation(
        "difference", operation("product", _g("pitch_kd"), prop("velocities/thetadot-rad_sec"), value(57.29577951308232)),
        operation("sum", operation("product", _g("pitch_kp"), prop("pilot/pitch-error-deg")),
                  operation("product", _g("pitch_ki"), prop("pilot/pitch-integral"))))),
        clip=(-1, 1), output=OUTPUTS["pitch"])

    ch = sub(sy, "channel", name="pilot roll")
    _fcs_function(ch, "pilot/roll-error-deg", _difference_if(_mode_on("roll"), TARGETS["bank"], MEASURED["bank"]))
    _integrator(ch, "pilot/roll-integral", "pilot/roll-error-deg", 1.0 / GAINS.roll_ki)
    _fcs_function(ch, "pilot/aileron", operation("product", _mode_on("roll"), operation(
        "difference", operation("sum", operation("product", _g("roll_kp"), prop("pilot/roll-error-deg")),
                                operation("product", _g("roll_ki"), prop("pilot/roll-integral"))),
        operation("product", _g("roll_kd"), prop("velocities/phidot-rad_sec"), value(57.29577951308232)))),
        clip=(-1, 1), output=OUTPUTS["roll"])

    ch = sub(sy, "channel", name="pilot yaw")
    # sideslip error positive: the wind comes from further right than wanted: nose right (rudder -)
    _fcs_function(ch, "pilot/beta-error-deg", _difference_if(_mode_is("yaw", 1), MEASURED["sideslip"],
                                                            TARGETS["sideslip"]))
    _integrator(ch, "pilot/beta-integral", "pilot/beta-error-deg", 1.0 / GAINS.sideslip_ki)
    # heading error in (-180, 180], positive: the nose must go right
    _fcs_function(ch, "pilot/heading-error-deg", operation("product", _mode_is("yaw", 2), operation(
        "difference", operation("mod", operation("sum", operation(
            "difference", prop(TARGETS["heading"]), prop(MEASURED["heading"])), value(540)), value(360)),
        value(180))))
    _fcs_function(ch, "pilot/rudder", operation("product", _mode_on("yaw"), operation(
        "difference", operation("product", _g("yaw_kd"), prop("aero/betadot-deg_sec"), value(-1.0)),
        operation("sum", operation("product", _g("sideslip_kp"), prop("pilot/beta-error-deg")),
                  operation("product", _g("sideslip_ki"), prop("pilot/beta-integral")),
                  operation("product", _g("heading_kp"), prop("pilot/heading-error-deg"))))),
        clip=(-1, 1), output=OUTPUTS["yaw"])

    ch = sub(sy, "channel", name="pilot speed")
    _fcs_function(ch, "pilot/speed-error-kt", _difference_if(_mode_on("speed"), TARGETS["airspeed"],
                                                            MEASURED["airspeed"]))
    _integrator(ch, "pilot/speed-integral", "pilot/speed-error-kt", 1.0 / GAINS.speed_ki)
    _fcs_function(ch, "pilot/throttle", operation("product", _mode_on("speed"), operation(
        "sum", operation("product", _g("speed_kp"), prop("pilot/speed-error-kt")),
        operation("product", _g("speed_ki"), prop("pilot/speed-integral")))),
        clip=(-1, 1), output=OUTPUTS["speed"])


def throttle_channel(fcs) -> None:
    """The throttle channel: command plus the pilot's increment, within the stops."""
    ch = sub(fcs, "channel", name="Throttle")
    sm = sub(ch, "summer", name="fcs/throttle-sum")
    sub(sm, "input", "fcs/throttle-cmd-norm")
    sub(sm, "input", OUTPUTS["speed"])
    c = sub(sm, "clipto")
    sub(c, "min", "0")
    sub(c, "max", "1")
    sub(sm, "output", "fcs/throttle-pos-norm")

