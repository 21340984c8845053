"""The dictionary of candidate terms the close-loop synthesizes from, as data.

A term is one coefficient of one aerodynamic axis times one regressor: ``Delta C = K x``,
added to the aircraft as the force ``K x qbar S`` (LIFT, DRAG, SIDE) or the moment
``K x qbar S l`` (ROLL and YAW with the span, PITCH with the mean chord), in JSBSim's axes
and signs (lift up, drag aft, side force right, roll right wing down, pitch nose up, yaw
nose right). :mod:`.synthesis` builds, linearizes, selects and writes terms; this module only
says which terms make physical sense and what each would mean:

* :data:`REGRESSORS`: the states a coefficient may follow, each as JSBSim's function language,
  with the axes it may act on. Symmetric axes (lift, drag, pitch) take only states that keep
  their sign in a mirror image (alpha, flaps, thrust coefficient ...); the lateral axes take
  the antisymmetric ones (sideslip, roll and yaw rate, aileron, rudder) and, as asymmetries of
  the airframe or the propeller, the symmetric ones. Products of two states: those of alpha,
  sideslip, flaps and the thrust coefficient;
* :data:`METRIC_AXES`: the axes a measured metric reveals in trimmed flight (the synthesis
  restricts its dictionary to the axes of the structured metrics);
* :data:`INTERPRETATIONS`: what a term means physically, per (axis, regressor), in words for
  the report;
* :data:`SAME_FORM`: calibration factors a term duplicates (held, not refitted, with it).

A leaf of the calibration floor: no JSBSim, no XML parsing.
"""
from __future__ import annotations

from dataclasses import dataclass

from ..core.errors import ModelError


@dataclass(frozen=True)
class Axis:
    name: str                   # JSBSim's <axis name=...>
    coefficient: str            # CL, CD, CY, Cl, Cm, Cn
    length: str | None          # reference length property of a moment (None: a force)
    noun: str                   # what a positive coefficient adds, in words
    symmetric: bool             # a longitudinal axis (lift, drag, pitch)

    @property
    def unit(self) -> str:
        """Unit suffix of the function name: lbs (force) or lbsft (moment)."""
        return "lbsft" if self.length else "lbs"


AXES: dict[str, Axis] = {a.name: a for a in (
    Axis("LIFT", "CL", None, "lift (+ up)", True),
    Axis("DRAG", "CD", None, "drag (+ more drag)", True),
    Axis("SIDE", "CY", None, "side force (+ to the right)", False),
    Axis("ROLL", "Cl", "metrics/bw-ft", "rolling moment (+ right wing down)", False),
    Axis("PITCH", "Cm", "metrics/cbarw-ft", "pitching moment (+ nose up)", True),
    Axis("YAW", "Cn", "metrics/bw-ft", "yawing moment (+ nose right)", False),
)}
LONGITUDINAL = ("LIFT", "DRAG", "PITCH")
LATERAL = ("SIDE", "ROLL", "YAW")


@dataclass(frozen=True)
class Regressor:
    name: str                   # as the report writes it
    key: str                    # identifier in property and factor names
    unit: str                   # unit of the regressor (the coefficient's is 1/unit)
    scale: float                # typical magnitude in flight (sets the linearization step)
    xml: str                    # JSBSim function language
    axes: tuple[str, ...]       # the axes it may act on
    doc: str                    # what it is, in words
    dynamic: bool = False       # seen only in maneuvers (zero or constant in a steady straight trim)


def _p(path: str) -> str:
    return f"<property>{path}</property>"


TC_XML = ("<quotient>" + _p("propulsion/engine/thrust-lbs") + "<product>" + _p("aero/qbar-psf")
          + _p("metrics/Sw-sqft") + "</product></quotient>")
ALL = LONGITUDINAL + LATERAL

_BASE = (
    Regressor("1", "0", "-", 1.0, "<value>1</value>", ALL, "a constant"),
    Regressor("alpha", "alpha", "rad", 0.1, _p("aero/alpha-rad"), ALL, "angle of attack"),
    Regressor("alpha^2", "alpha2", "rad2", 0.01, "<product>" + _p("aero/alpha-rad") * 2 + "</product>",
              LONGITUDINAL, "angle of attack squared (grows at high alpha)"),
    Regressor("beta", "beta", "rad", 0.02, _p("aero/beta-rad"), LATERAL, "sideslip"),
    Regressor("beta^2", "beta2", "rad2", 4e-4, "<product>" + _p("aero/beta-rad") * 2 + "</product>", ("DRAG",),
              "sideslip squared"),
    Regressor("flaps", "flaps", "deg", 20.0, _p("fcs/flap-pos-deg"), ALL, "flap deflection"),
    Regressor("elevator", "elevator", "deg", 5.0, _p("fcs/elevator-pos-deg"), LONGITUDINAL,
              "elevator deflection (+ trailing edge down)"),
    Regressor("aileron", "aileron", "deg", 2.0, _p("fcs/aileron-pos-deg"), LATERAL,
              "aileron deflection (+ roll right)"),
    Regressor("rudder", "rudder", "deg", 3.0, _p("fcs/rudder-pos-deg"), LATERAL,
              "rudder deflection (+ trailing edge left)"),
    Regressor("Tc", "tc", "-", 0.1, TC_XML, ALL, "thrust coefficient T/(qbar S)"),
    Regressor("p b/2V", "phat", "-", 0.01, "<product>" + _p("velocities/p-aero-rad_sec") + _p("aero/bi2vel")
              + "</product>", LATERAL, "non-dimensional roll rate p b/2V"),
    Regressor("q c/2V", "qhat", "-", 0.005, "<product>" + _p("velocities/q-aero-rad_sec") + _p("aero/ci2vel")
              + "</product>", ("LIFT", "PITCH"), "non-dimensional pitch rate q c/2V"),
    Regressor("r b/2V", "rhat", "-", 0.01, "<product>" + _p("velocities/r-aero-rad_sec") + _p("aero/bi2vel")
              + "</product>", LATERAL, "non-dimensional yaw rate r b/2V"),
    Regressor("Mach", "mach", "-", 0.15, _p("velocities/mach"), ("DRAG",), "Mach number"),
)
_BY_NAME = {r.name: r for r in _BASE}
# products of two states: their axes are those both allow, or, for a symmetric state times an
# antisymmetric one (an odd product), the lateral axes
PRODUCTS = (("alpha", "beta"), ("alpha", "flaps"), ("alpha", "Tc"), ("beta", "flaps"), ("beta", "Tc"),
            ("flaps", "Tc"))


def _product(a: Regressor, b: Regressor) -> Regressor:
    odd = (a.axes == LATERAL) != (b.axes == LATERAL)
    axes = LATERAL if odd else tuple(x for x in ALL if x in a.axes and x in b.axes)
    units = " ".join(u for u in (a.unit, b.unit) if u != "-") or "-"
    return Regressor(f"{a.name} x {b.name}", f"{a.key}_x_{b.key}", units, a.scale * b.scale,
                     f"<product>{a.xml}{b.xml}</product>", axes, f"{a.doc} times {b.doc}")


# What time histories reveal beyond trims: the rate of change of alpha, and a damping or a
# control power that varies with the state (rates and deflections times alpha, flaps, the
# thrust coefficient or the dynamic pressure: cable stretch and hinge moments grow with it)
_DYNAMIC = (
    Regressor("alphadot c/2V", "adhat", "-", 0.005, "<product>" + _p("aero/alphadot-rad_sec") + _p("aero/ci2vel")
              + "</product>", ("LIFT", "PITCH"), "non-dimensional rate of change of angle of attack", True),
)
_QBAR = Regressor("qbar", "qbar", "psf", 30.0, _p("aero/qbar-psf"), ALL, "dynamic pressure")
_BY_NAME.update({r.name: r for r in _DYNAMIC})
DYNAMIC_PRODUCTS = (("p b/2V", "alpha"), ("r b/2V", "alpha"), ("q c/2V", "alpha"), ("p b/2V", "flaps"),
                    ("r b/2V", "flaps"), ("q c/2V", "flaps"), ("p b/2V", "Tc"), ("r b/2V", "Tc"), ("q c/2V", "Tc"),
                    ("aileron", "alpha"), ("elevator", "alpha"), ("rudder", "alpha"), ("aileron", "flaps"),
                    ("elevator", "flaps"), ("aileron", "qbar"), ("elevator", "qbar"), ("rudder", "qbar"))
_OPERANDS = {**_BY_NAME, "qbar": _QBAR}


def _dynamic_product(a: str, b: str) -> Regressor:
    r = _product(_OPERANDS[a], _OPERANDS[b])
    return Regressor(r.name, r.key, r.unit, r.scale, r.xml, r.axes, r.doc, True)


REGRESSORS: dict[str, Regressor] = {**_BY_NAME, **{f"{a} x {b}": _product(_BY_NAME[a], _BY_NAME[b])
                                                   for a, b in PRODUCTS},
                                    **{f"{a} x {b}": _dynamic_product(a, b) for a, b in DYNAMIC_PRODUCTS}}

# The axes a metric of trimmed flight reveals. A side force shows in a steady trim only
# through the sideslip it takes, which the roll and yaw terms of the same regressor reproduce
# (their columns are nearly collinear), so SIDE serves data that measure sideslip.
METRIC_AXES: dict[str, tuple[str, ...]] = {
    "aileron_deg": ("ROLL",), "rudder_deg": ("YAW",), "elevator_deg": ("PITCH",), "pitch_deg": ("LIFT",),
    "roc_fpm": ("DRAG",), "rpm": ("DRAG",), "pct_power": ("DRAG",), "gph": ("DRAG",), "beta_deg": ("SIDE",),
}

# What a term means, per (axis, regressor): the report's words. A pair not listed reads
# "<axis noun> proportional to <regressor doc>".
INTERPRETATIONS: dict[tuple[str, str], str] = {
    ("ROLL", "1"): "constant rolling moment: wing rigging asymmetry (wash-in/wash-out difference), a lateral "
                   "fuel or load imbalance",
    ("ROLL", "flaps"): "rolling moment proportional to flap deflection: flap rigging asymmetry or a flap-track "
                       "difference",
    ("ROLL", "Tc"): "rolling moment growing with the thrust coefficient: slipstream swirl over the wing roots "
                    "beyond the model",
    ("ROLL", "alpha"): "rolling moment growing with angle of attack: asymmetric wing twist or stall strips",
    ("ROLL", "beta"): "dihedral effect (Cl_beta) differs from the model: wing dihedral, wing-body position",
    ("ROLL", "aileron"): "aileron power differs from the model (Cl_da)",
    ("ROLL", "rudder"): "roll due to rudder differs from the model (Cl_dr): fin height",
    ("ROLL", "p b/2V"): "roll damping differs from the model (Cl_p)",
    ("ROLL", "r b/2V"): "roll due to yaw rate differs from the model (Cl_r, grows with lift)",
    ("ROLL", "flaps x Tc"): "rolling moment from the slipstream over the deflected flaps: swirl acting "
                            "unequally on the two flaps",
    ("YAW", "1"): "constant yawing moment: fin offset or rudder rigging",
    ("YAW", "Tc"): "yawing moment growing with the thrust coefficient: slipstream swirl on the fin, P-factor",
    ("YAW", "alpha x Tc"): "yawing moment in thrust x angle of attack: P-factor (asymmetric blade loading)",
    ("YAW", "beta"): "directional stability (Cn_beta) differs from the model: fin size or effectiveness",
    ("YAW", "rudder"): "rudder power differs from the model (Cn_dr)",
    ("YAW", "aileron"): "adverse aileron yaw differs from the model (Cn_da)",
    ("YAW", "p b/2V"): "yawing moment in roll rate (Cn_p): the wing's adverse yaw in rolling flight differs "
                       "from the model",
    ("YAW", "r b/2V"): "yaw damping differs from the model (Cn_r)",
    ("YAW", "flaps"): "yawing moment proportional to flap deflection: asymmetric flap drag (rigging)",
    ("PITCH", "1"): "constant pitching moment (Cm0): wing incidence, tail incidence or camber",
    ("PITCH", "alpha"): "static stability differs from the model (Cm_alpha): neutral point position",
    ("PITCH", "flaps"): "pitching moment proportional to flap deflection: flap moment or downwash at the tail",
    ("PITCH", "Tc"): "pitching moment growing with the thrust coefficient: thrust line or slipstream on the tail",
    ("PITCH", "flaps x Tc"): "pitching moment in thrust x flaps: slipstream over the deflected flaps changes the "
                             "downwash at the tail",
    ("PITCH", "elevator"): "elevator power differs from the model (Cm_de)",
    ("PITCH", "q c/2V"): "pitch damping differs from the model (Cm_q)",
    ("PITCH", "alpha x flaps"): "flaps change the static stability: downwash at the tail with flaps",
    ("DRAG", "1"): "parasite drag differs from the model (CD0)",
    ("DRAG", "alpha"): "drag growing linearly with angle of attack: polar shape, camber",
    ("DRAG", "alpha^2"): "drag growing with alpha^2 at high angle of attack: induced drag or separation beyond "
                         "the model (a lower Oswald factor)",
    ("DRAG", "flaps"): "flap drag differs from the model",
    ("DRAG", "Tc"): "drag proportional to the thrust coefficient: slipstream scrubbing drag or a propeller "
                    "efficiency loss",
    ("DRAG", "beta^2"): "sideslip drag",
    ("DRAG", "Mach"): "drag growing with Mach number: compressibility or a Reynolds-number effect of speed",
    ("LIFT", "1"): "zero-lift angle differs from the model (CL0): incidence or camber",
    ("LIFT", "alpha"): "lift-curve slope differs from the model (CL_alpha)",
    ("LIFT", "flaps"): "flap lift differs from the model",
    ("LIFT", "Tc"): "power-induced lift: slipstream over the wing",
    ("LIFT", "flaps x Tc"): "power-induced lift of the deflected flaps in the slipstream",
    ("SIDE", "beta"): "side force due to sideslip differs from the model (CY_beta)",
    ("PITCH", "alphadot c/2V"): "Cm_alphadot differs from the model: the downwash lag at the tail",
    ("LIFT", "alphadot c/2V"): "CL_alphadot differs from the model: the downwash lag at the tail",
    ("ROLL", "p b/2V x alpha"): "roll damping varies with angle of attack (Cl_p falls toward the stall)",
    ("ROLL", "p b/2V x flaps"): "roll damping varies with the flaps",
    ("PITCH", "q c/2V x flaps"): "pitch damping varies with the flaps",
    ("PITCH", "q c/2V x alpha"): "pitch damping varies with angle of attack",
    ("YAW", "r b/2V x alpha"): "yaw damping varies with angle of attack",
    ("YAW", "p b/2V x alpha"): "yaw due to roll rate grows with angle of attack (Cn_p ~ -CL/8): the wing's "
                               "adverse yaw in rolling flight",
    ("ROLL", "r b/2V x alpha"): "roll due to yaw rate grows with angle of attack (Cl_r ~ CL/4)",
    ("ROLL", "aileron x alpha"): "aileron power varies with angle of attack",
    ("ROLL", "aileron x qbar"): "aileron power falls with dynamic pressure: cable stretch or hinge moment",
    ("PITCH", "elevator x qbar"): "elevator power falls with dynamic pressure: cable stretch or hinge moment",
    ("YAW", "rudder x qbar"): "rudder power falls with dynamic pressure: cable stretch or hinge moment",
    ("YAW", "aileron x alpha"): "adverse aileron yaw grows with angle of attack (Cn_da ~ CL)",
    ("PITCH", "elevator x alpha"): "elevator power varies with angle of attack",
    ("PITCH", "elevator x flaps"): "elevator power varies with the flaps (downwash at the tail)",
}

# Terms of the same form as a calibration factor (those factors are not refitted with them).
SAME_FORM: dict[tuple[str, str], tuple[str, ...]] = {
    ("ROLL", "aileron"): ("K_da_slope",), ("YAW", "rudder"): ("K_dr_slope",), ("PITCH", "elevator"): ("K_de_slope",),
    ("ROLL", "p b/2V"): ("K_Clp",), ("YAW", "r b/2V"): ("K_Cnr",), ("PITCH", "q c/2V"): ("K_Cmq",),
    ("PITCH", "alpha"): ("K_Cm_alpha",), ("YAW", "alpha x Tc"): ("K_PF",), ("PITCH", "1"): ("K_cm_offset",),
}


def regressor(name: str) -> Regressor:
    try:
        return REGRESSORS[name]
    except KeyError:
        raise ModelError(f"unknown regressor '{name}'; known: {', '.join(REGRESSORS)}") from None


def axis(name: str) -> Axis:
    try:
        return AXES[name]
    except KeyError:
        raise ModelError(f"unknown axis '{name}'; axes: {', '.join(AXES)}") from None


def axes_for(metrics) -> tuple[str, ...]:
    """The axes the given metrics reveal (:data:`METRIC_AXES`), in :data:`AXES` order."""
    wanted = {a for m in metrics for a in METRIC_AXES.get(m, ())}
    return tuple(a for a in AXES if a in wanted)


def interpretation(axis_name: str, regressor_name: str) -> str:
    """What a term means physically (:data:`INTERPRETATIONS`, else a plain description)."""
    got = INTERPRETATIONS.get((axis_name, regressor_name))
    if got:
        return got
    a, r = axis(axis_name), regressor(regressor_name)
    noun = a.noun.split(" (")[0]
    return f"{noun} proportional to the {r.doc}" if r.name != "1" else f"constant {noun}"
