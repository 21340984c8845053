"""Calibration factors of the method, as data.

Each factor is a named JSBSim property declared (persistent) in the generated aircraft
XML with its neutral value, bounds and units beside it. The aircraft functions multiply
or add it where the method puts it. Propeller factors (``baked=True``) are applied to the
propeller tables when they are written, and recorded in the propeller file.

Each factor also declares the fit steps that set it (``steps``) and the measured metrics it
moves (``moves``): the stages, the close-loop and the reports derive every set of factors
they need from these (:func:`step_factors`, :func:`set_in`, :func:`levers`, ``baked``), so
adding a factor is adding its record here (and its term where it acts, in the aircraft's
functions, :mod:`jsbsim_calib.jsbsim.equations`). The factors of the effect library are
:class:`Factor` records too (step ``effect``).

``FactorSet`` holds values; it converts to and from the optimizer's vector in one place,
normalizing each factor to [-1, 1] over its bounds, and refuses out-of-bounds values.

A leaf module (numpy and the errors only): every floor of the package may use it.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Iterable, Mapping, Sequence

import numpy as np

from .core.errors import CalibError


@dataclass(frozen=True)
class Factor:
    name: str
    property: str          # JSBSim property path
    neutral: float         # value that leaves the baseline model unchanged
    lower: float
    upper: float
    unit: str              # '-' for dimensionless
    steps: tuple[str, ...]  # the fit steps that set it, in the order they run (see STEPS)
    moves: tuple[str, ...]  # the measured metrics it moves (names of jsbsim_calib.data.schemas.METRICS)
    applies_to: str        # where the method puts it
    doc: str               # one line: what it does and which way it moves the result
    baked: bool = False    # True: applied to the propeller tables at generation

    def to_unit(self, value: float) -> float:
        """Value mapped to [-1, 1] over the bounds."""
        return 2.0 * (value - self.lower) / (self.upper - self.lower) - 1.0

    def from_unit(self, u: float) -> float:
        return self.lower + 0.5 * (u + 1.0) * (self.upper - self.lower)


def _f(name, neutral, lower, upper, unit, steps, moves, applies_to, doc, baked=False):
    suffix = {"deg": "-deg", "m2/s": "-m2_sec"}.get(unit, "")
    return Factor(name, f"calibration/{name}{suffix}", neutral, lower, upper, unit, steps, moves, applies_to, doc,
                  baked)


# The fit steps, in the order the calibration runs them: stage 1 (POH) fits the aerodynamic,
# propeller and engine factors, then fuel flow; stage 2a (flight-test trims) runs the method's
# steps, then refits stage 1's factors with the control, P-factor and flap steps' jointly to all
# the steady data ("steady refit"; jsbsim_calib.calibration.steady and .trims declare what each
# step fits them to). A factor lists the steps that set it; "effect" marks the factors of the
# effect library (jsbsim_calib.calibration.effects). Stage 2b (jsbsim_calib.calibration.dynamic) runs the
# dynamic steps, each axis its own fit against flown maneuvers.
STEPS = ("steady", "fuel flow", "pitch", "control", "pfactor", "flaps", "steady refit", "roll dynamics",
         "pitch dynamics", "yaw dynamics", "engine dynamics", "effect")
DYNAMIC_STEPS = ("roll dynamics", "pitch dynamics", "yaw dynamics")   # stage 2b (time domain)
STAGE1 = ("steady", "steady refit")          # steps of the 16 coupled stage-1 factors (the refit: more)
POH = ("roc_fpm", "pct_power", "rpm")        # what the stage-1 factors move


FACTORS: tuple[Factor, ...] = (
    # --- steady stage (method Table 3.1, eq. 3.1-3.19)
    _f("alpha_shift", 0.0, -4.0, 4.0, "deg", STAGE1, POH,
       "wing strips: section angle (eq. 3.1-3.2)",
       "adds to the wing section angle before the polar lookup: + gives more lift at the same alpha"),
    _f("K_cl_slope", 1.0, 0.7, 1.3, "-", STAGE1, POH,
       "wing strips: lift in wind axes (eq. 3.6)",
       "scales the wing lift: > 1 steeper lift curve, lower trim alpha"),
    _f("K_cl_offset", 0.0, -0.3, 0.3, "-", STAGE1, POH,
       "wing strips: lift in wind axes (eq. 3.6)",
       "adds to the section lift of every wing strip: + shifts zero lift to lower alpha"),
    _f("K_cd0_slope", 1.0, 0.7, 1.3, "-", STAGE1, POH,
       "profile drag of all lifting surfaces and the fuselage group (eq. 3.7-3.8)",
       "scales parasitic drag: > 1 more drag, higher cruise power and RPM, less climb"),
    _f("K_cd0_offset", 0.0, -0.05, 0.05, "-", STAGE1, POH,
       "profile drag of all lifting surfaces and the fuselage group (eq. 3.7-3.8)",
       "adds to every strip's profile drag and to the fuselage drag: + more drag"),
    _f("K_cdi", 1.0, 0.7, 1.3, "-", STAGE1, POH,
       "induced drag of all strips (eq. 3.9)",
       "scales induced drag (1/Oswald factor): > 1 more drag at high lift, less climb"),
    _f("J_anchor", 0.6, 0.45, 0.75, "-", STAGE1, POH,
       "propeller tables: anchor of the tilt and quadratic terms (eq. 3.16-3.17)",
       "advance ratio about which the CT/CQ tilt and curvature act", baked=True),
    _f("K_CT_shift", 0.0, -0.1, 0.1, "-", STAGE1, POH,
       "propeller C_THRUST: advance-ratio shift (eq. 3.13)",
       "reads the thrust curve at J + shift: + less thrust (curve falls with J)", baked=True),
    _f("K_CT_scale", 1.0, 0.8, 1.2, "-", STAGE1, POH,
       "propeller C_THRUST (eq. 3.16)",
       "scales thrust coefficient: > 1 more thrust, better climb, lower cruise RPM", baked=True),
    _f("K_CT_tilt", 0.0, -0.1, 0.1, "-", STAGE1, POH,
       "propeller C_THRUST (eq. 3.16)",
       "linear change of thrust with J about J_anchor: + more thrust at high J", baked=True),
    _f("K_CT_quad", 0.0, -0.2, 0.2, "-", STAGE1, POH,
       "propeller C_THRUST (eq. 3.16)",
       "quadratic change of thrust about J_anchor: + more thrust away from the anchor", baked=True),
    _f("K_CQ_shift", 0.0, -0.1, 0.1, "-", STAGE1, POH,
       "propeller C_POWER (= 2 pi C_Q): advance-ratio shift (eq. 3.13)",
       "reads the torque curve at J + shift: + less torque, higher RPM", baked=True),
    _f("K_CQ_scale", 1.0, 0.8, 1.2, "-", STAGE1, POH,
       "propeller C_POWER (eq. 3.17)",
       "scales torque/power coefficient: > 1 more power absorbed, lower RPM", baked=True),
    _f("K_CQ_tilt", 0.0, -0.1, 0.1, "-", STAGE1, POH,
       "propeller C_POWER (eq. 3.17)",
       "linear change of torque with J about J_anchor", baked=True),
    _f("K_CQ_quad", 0.0, -0.2, 0.2, "-", STAGE1, POH,
       "propeller C_POWER (eq. 3.17)",
       "quadratic change of torque about J_anchor", baked=True),
    _f("K_HP", 1.0, 0.8, 1.2, "-", STAGE1, POH,
       "engine power (eq. 3.18): volumetric efficiency",
       "scales engine air flow and so power: > 1 more full-throttle power, better climb"),
    _f("K_FF", 1.0, 0.8, 1.2, "-", ("fuel flow", "steady refit"), ("gph",),
       "engine fuel flow at constant power (eq. 3.19)",
       "scales fuel flow: > 1 more fuel burnt for the same power"),
    # --- flight-test stage: pitching moment (Table 3.4, eq. 3.27-3.30)
    _f("alpha_shift_addl", 0.0, -4.0, 4.0, "deg", ("pitch",), ("pitch_deg",),
       "wing strips: section angle, added to alpha_shift (eq. 3.27)",
       "additional wing section-angle shift: + lowers trim pitch attitude"),
    _f("K_cm_slope", 1.0, 0.2, 3.0, "-", ("pitch",), ("elevator_deg", "pitch_deg"),
       "wing strips: section pitching moment (eq. 3.30)",
       "scales the wing section pitching moment (nose-down camber moment)"),
    _f("K_cm_offset", 0.0, -0.5, 0.5, "-", ("pitch",), ("elevator_deg", "pitch_deg"),
       "wing strips: section pitching moment (eq. 3.30)",
       "adds to every wing strip's section moment: + nose-up, elevator trims further down"),
    # --- control effectiveness (Table 3.5, eq. 3.35-3.38)
    _f("K_de_slope", 1.0, 0.5, 3.0, "-", ("control", "pitch dynamics"), ("elevator_deg",),
       "elevator circulation (eq. 3.36)",
       "scales elevator effectiveness: > 1 smaller trim elevator"),
    _f("K_de_offset", 0.0, -5.0, 5.0, "m2/s", ("control", "steady refit"), ("elevator_deg",),
       "elevator circulation (eq. 3.36)",
       "adds circulation on the elevator span: + tail lift up (nose down), falls with speed"),
    _f("K_da_slope", 1.0, 0.5, 3.0, "-", ("control", "roll dynamics"), ("aileron_deg",),
       "aileron circulation (eq. 3.36)",
       "scales aileron effectiveness: > 1 smaller trim aileron"),
    _f("K_da_offset", 0.0, -5.0, 5.0, "m2/s", ("control", "steady refit"), ("aileron_deg",),
       "aileron circulation (eq. 3.36)",
       "adds antisymmetric aileron circulation: + right-roll moment"),
    _f("K_dr_slope", 1.0, 0.5, 3.0, "-", ("control", "pfactor", "steady refit"), ("rudder_deg",),
       "rudder circulation (eq. 3.36)",
       "scales rudder effectiveness: > 1 smaller trim rudder"),
    _f("K_dr_offset", 0.0, -5.0, 5.0, "m2/s", ("control", "pfactor", "steady refit"), ("rudder_deg",),
       "rudder circulation (eq. 3.36)",
       "adds fin circulation as a positive (trailing edge left) rudder does: nose-left moment"),
    # The method bounds K_PF to [0, 0.5] for its form applied on every strip; applied once as
    # eq. 3.38 the C172 flight-test climbs need about 5 (it trades with K_dr_slope; with the
    # slipstream's swirl off it also stood for the swirl on the fin): bound widened to 5. With
    # the swirl on the C172's chain still puts it at 5; bounded to 3 it cuts K_dr_slope
    # instead and the slow end is no better (docs/results.md, the slow end).
    _f("K_PF", 0.0, 0.0, 5.0, "-", ("pfactor", "steady refit"), ("rudder_deg", "aileron_deg"),
       "yawing moment N = -K_PF T (D/2) sin(alpha) (eq. 3.38)",
       "P-factor: + nose-left yaw growing with thrust and alpha (right rudder in climbs)"),
    # not in the method (it names the slipstream as a missing model): the momentum-theory slipstream
    # of jsbsim_calib.physics.slipstream. Model switches, not fitted by any step (no steps): every
    # stage keeps the value it starts from. 0 (neutral) leaves it out, 1 is the theory; the
    # product's choice and why: reports/<aircraft>/slipstream.md (jsbsim-calib slipstream)
    _f("K_slip", 0.0, 0.0, 2.0, "-", (), ("elevator_deg", "rudder_deg", "pitch_deg"),
       "slipstream dynamic pressure on the tails and wing root (momentum theory)",
       "scales the slipstream's extra dynamic pressure: 1 the theory, > 1 more tail and rudder power with thrust"),
    _f("K_swirl", 0.0, 0.0, 2.0, "-", (), ("rudder_deg", "aileron_deg"),
       "slipstream swirl at the fin (momentum theory, free vortex)",
       "scales the swirl's sideslip at the fin: 1 the theory, > 1 more nose-left yaw with power (right rudder)"),
    # --- flaps (Table 3.6, eq. 3.42-3.45)
    _f("K_dcd0_flaps", 0.0, -2.0, 2.0, "-", ("flaps", "steady refit"), ("roc_fpm",),
       "flap strips: profile drag per flap degree (eq. 3.42)",
       "adds K times the per-degree flap profile-drag estimate: + more flaps-down drag"),
    _f("K_dcm_flaps", 0.0, -3.0, 3.0, "-", ("flaps", "steady refit"), ("elevator_deg",),
       "flap strips: section moment per flap degree (eq. 3.44)",
       "adds K times the per-degree flap moment estimate: + more nose-down with flaps"),
    # not in the method: its flap step cannot move the flaps-down trim attitude, which is set
    # by the flap lift increment (see the README)
    _f("K_dcl_flaps", 1.0, 0.5, 1.5, "-", ("flaps", "steady refit"), ("pitch_deg", "roc_fpm"),
       "flap strips: lift increment of the flap (strip theory)",
       "scales the flap lift increment: < 1 less lift from the flaps, higher flaps-down pitch attitude"),
    # --- damping (Table 3.7, eq. 3.48-3.56): stage 2b, each axis its own fit. The method's bounds
    # (+-0.02, +-0.1) are for its own model's derivatives; here they are about half of the strip
    # model's (Cl_p -0.58, Cm_q -12.6, Cn_r -0.13), so that the factor can move the response it
    # is fitted to (measured: the method's bounds move a roll rate by 1 deg/s, a pitch rate by 0.1).
    _f("K_Clp", 0.0, -0.3, 0.3, "-", ("roll dynamics",), ("roll_rate_deg_s", "max_roll_rate_deg_s"),
       "rolling moment -K p b/(2V) qbar S b (eq. 3.48)",
       "extra roll damping: + more damping, slower steady roll rate"),
    _f("K_Cmq", 0.0, -6.0, 6.0, "-", ("pitch dynamics",), ("max_pitch_rate_deg_s", "phugoid_damping"),
       "pitching moment -K q c/(2V) qbar S c (eq. 3.51)",
       "extra pitch damping: + more damping, lower peak pitch rate"),
    _f("K_Cnr", 0.0, -0.07, 0.07, "-", ("yaw dynamics",), ("max_yaw_rate_deg_s",),
       "yawing moment -K r b/(2V) qbar S b (eq. 3.54)",
       "extra yaw damping: + more damping, lower peak yaw rate"),
    # not in the method: its pitch factors cannot separate elevator power from pitch stiffness (the
    # 1-g trims see only their ratio); the turns, the phugoid and the pulses can (README)
    _f("K_Cm_alpha", 0.0, -0.8, 0.8, "1/rad", ("pitch dynamics",),
       ("elevator_deg", "pitch_deg", "phugoid_period_s", "max_pitch_rate_deg_s"),
       "pitching moment K alpha qbar S c (stiffness)",
       "adds K alpha to the pitching moment: + less stable (neutral point forward), less trim elevator per CL"),
    # not in the method: the rotating inertia of engine and propeller, which sets how fast the RPM
    # follows the throttle (Part 60 1.f.1); JSBSim reads it from the propeller file (<ixx>) at load
    # and spins the whole drive with it, while the geometry gives the propeller's alone (JSBSim's
    # c172 value): the crankshaft, flywheel and accessories are what the factor adds
    _f("K_Ip", 1.0, 0.5, 3.0, "-", ("engine dynamics",), ("response_time_s",),
       "propeller file: rotating inertia of propeller, crankshaft and accessories (<ixx>)",
       "scales the rotating inertia: > 1 slower RPM response to the throttle", baked=True),
)

REGISTRY: dict[str, Factor] = {f.name: f for f in FACTORS}
PROPELLER_FACTORS = tuple(f.name for f in FACTORS if f.baked)
# model switches: factors no step fits (the slipstream's); a calibration keeps the aircraft's values
SWITCHES = tuple(f.name for f in FACTORS if not f.steps)


class FactorError(CalibError, ValueError):
    """A factor name is unknown or a value is outside its bounds."""


def propeller_factor_values(factors: Mapping[str, float]) -> dict[str, float]:
    """The propeller factors (the registry's baked factors, in its order), neutral unless
    ``factors`` gives them: what :func:`jsbsim_calib.physics.propeller.apply_factors` bakes into
    the tables. Values are not bounded here: the tables take any."""
    names = [n for n, f in REGISTRY.items() if f.baked]
    unknown = sorted(set(factors) - set(names))
    if unknown:
        raise FactorError(f"not propeller factors: {', '.join(unknown)}; propeller factors: {', '.join(names)}")
    return {n: float(factors.get(n, REGISTRY[n].neutral)) for n in names}


def factor(name: str) -> Factor:
    try:
        return REGISTRY[name]
    except KeyError:
        raise FactorError(f"unknown factor '{name}'; known factors: {', '.join(REGISTRY)}") from None


def neutral_values() -> dict[str, float]:
    return {f.name: f.neutral for f in FACTORS}


def step_factors(step: str) -> tuple[str, ...]:
    """The factors a fit step sets, in the order it fits them: first those it sets for the
    first time, then the ones it refits (each group in registry order)."""
    if step not in STEPS:
        raise FactorError(f"unknown step '{step}'; steps: {', '.join(STEPS)}")
    mine = [f for f in FACTORS if step in f.steps]
    return tuple(f.name for f in sorted(mine, key=lambda f: f.steps.index(step) > 0))


def switches(factors: Mapping[str, float]) -> "FactorSet":
    """Only the model switches of ``factors`` (:data:`SWITCHES`), every other factor neutral:
    where a calibration from neutral starts on an aircraft whose switches were set by hand."""
    return FactorSet({k: factors[k] for k in SWITCHES if k in factors})


def set_in(steps: Sequence[str]) -> tuple[str, ...]:
    """The factors that any of ``steps`` sets, in registry order."""
    return tuple(f.name for f in FACTORS if set(f.steps) & set(steps))


def levers(metric: str, steps: Sequence[str]) -> tuple[str, ...]:
    """The factors of ``steps`` that move ``metric`` and nothing else the data measure (the
    metric's own levers), in registry order."""
    return tuple(f.name for f in FACTORS if set(f.steps) & set(steps) and f.moves == (metric,))


class FactorSet(Mapping[str, float]):
    """Values of all factors (neutral unless given). Out-of-bounds values raise, never clamp.

    ``extra``: more factors beyond the registry (the factors of effects added to an
    aircraft, :mod:`jsbsim_calib.calibration.effects`), with their own bounds and properties."""

    def __init__(self, values: Mapping[str, float] | None = None, extra: Mapping[str, Factor] | None = None):
        self._extra = dict(extra or {})
        self._reg = {**REGISTRY, **self._extra} if self._extra else REGISTRY
        self._v = {**neutral_values(), **{k: f.neutral for k, f in self._extra.items()}}
        bad = []
        for k, v in (values or {}).items():
            f = self._reg.get(k)
            if f is None:
                bad.append(f"unknown factor '{k}'")
                continue
            v = float(v)
            if not (f.lower - 1e-12 <= v <= f.upper + 1e-12) or not np.isfinite(v):
                bad.append(f"{k} = {v:g} is outside [{f.lower:g}, {f.upper:g}] {f.unit}")
                continue
            self._v[k] = v
        if bad:
            raise FactorError("; ".join(bad))

    @property
    def extra(self) -> dict[str, Factor]:
        return dict(self._extra)

    def factor(self, name: str) -> Factor:
        try:
            return self._reg[name]
        except KeyError:
            raise FactorError(f"unknown factor '{name}'") from None

    def __getitem__(self, k: str) -> float:
        return self._v[k]

    def __iter__(self):
        return iter(self._v)

    def __len__(self) -> int:
        return len(self._v)

    def replace(self, **changes: float) -> "FactorSet":
        return self.updated(changes)

    def updated(self, changes: Mapping[str, float]) -> "FactorSet":
        v = dict(self._v)
        v.update(changes)
        return FactorSet(v, self._extra)

    def with_extra(self, extra: Mapping[str, Factor], values: Mapping[str, float] | None = None) -> "FactorSet":
        """The same values with more (effect) factors."""
        return FactorSet({**self._v, **(values or {})}, {**self._extra, **extra})

    def vector(self, names: Sequence[str], normalized: bool = True) -> np.ndarray:
        x = np.array([self._reg[n].to_unit(self._v[n]) if normalized else self._v[n] for n in names])
        # snap round-off to 0: scipy's trust region starts at |x0|_inf, which must not be 1e-16
        return np.where(np.abs(x) < 1e-12, 0.0, x)

    def with_vector(self, names: Sequence[str], x: Iterable[float], normalized: bool = True) -> "FactorSet":
        v = dict(self._v)
        for n, xi in zip(names, x):
            v[n] = self._reg[n].from_unit(float(xi)) if normalized else float(xi)
        return FactorSet(v, self._extra)

    def changed(self) -> dict[str, float]:
        """Factors that differ from neutral."""
        return {k: v for k, v in self._v.items() if v != self._reg[k].neutral}

    def propeller(self) -> dict[str, float]:
        return {k: self._v[k] for k in PROPELLER_FACTORS}

    def as_dict(self) -> dict[str, float]:
        return dict(self._v)

    def __repr__(self) -> str:
        ch = self.changed()
        return f"FactorSet({ch if ch else 'neutral'})"
