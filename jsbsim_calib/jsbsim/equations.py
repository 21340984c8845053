"""The aircraft's functions as data: which calibration factor multiplies which quantity.

The strip model (:mod:`jsbsim_calib.physics.aero`) computes named tables and constants; this
module states how JSBSim combines them at run time (lift, drag, side force and the three
moments, with the calibration factors where the method puts them, eq. 3.1-3.56) and how the
engine calibration acts on FGPiston. An equation is a tree of a few node kinds (a JSBSim
property, a number, a calibration factor, an aerodynamic table looked up by properties, an
operation); :mod:`jsbsim_calib.jsbsim.aircraft` walks the trees and writes them as JSBSim
functions. Nothing here knows XML, and no equation is written anywhere else.

Units are JSBSim's (ft, lbf, slug, Rankine) where a property carries them.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Union

from ..core.units import FT
from ..physics.aero.model import AeroModel, Table
from ..physics.engine import PistonParams
from ..physics.geometry import AircraftGeometry

HP_FTLBF_S = 550.0            # [ft lbf/s per hp]

# Parasite drag grows with lift as CDp (1 + 0.38 CL^2) (I. Kroo, Aircraft Design: Synthesis and
# Analysis, "drag due to lift": the viscous part of lift-dependent drag). The wing strips
# carry theirs in the section polars; this adds it to the fuselage, fin and drag items.
KROO_K = 0.38
M2_TO_FT2 = 1.0 / FT**2


# --------------------------------------------------------------------------- nodes
@dataclass(frozen=True)
class Property:
    """A JSBSim property."""

    path: str


@dataclass(frozen=True)
class Number:
    value: float


@dataclass(frozen=True)
class FactorValue:
    """A calibration factor (its declared property in the aircraft's ``calibration`` system)."""

    name: str


@dataclass(frozen=True)
class Lookup:
    """An aerodynamic table of the strip model, looked up by one or two properties."""

    table: Table
    row: str
    column: str | None = None


@dataclass(frozen=True)
class Operation:
    """product, sum, difference, quotient, pow, sin, cos, max or min of the arguments."""

    name: str
    args: tuple


Node = Union[Property, Number, FactorValue, Lookup, Operation]


@dataclass(frozen=True)
class Function:
    name: str               # the JSBSim property it defines (an FCS function: its name)
    description: str
    expression: Node
    output: str | None = None   # an FCS function: the property it drives


@dataclass(frozen=True)
class Axis:
    name: str               # LIFT, DRAG, SIDE, ROLL, PITCH, YAW
    functions: tuple[Function, ...]


@dataclass(frozen=True)
class Aerodynamics:
    functions: tuple[Function, ...]     # intermediate quantities, in the order JSBSim evaluates them
    axes: tuple[Axis, ...]


def product(*terms: Node) -> Operation:
    return Operation("product", terms)


def total(*terms: Node) -> Operation:
    return Operation("sum", terms)


def difference(minuend: Node, subtrahend: Node) -> Operation:
    return Operation("difference", (minuend, subtrahend))


def ratio(numerator: Node, denominator: Node) -> Operation:
    return Operation("quotient", (numerator, denominator))


def power(base: Node, exponent: Node) -> Operation:
    return Operation("pow", (base, exponent))


def sine(angle: Node) -> Operation:
    return Operation("sin", (angle,))


def cosine(angle: Node) -> Operation:
    return Operation("cos", (angle,))


def largest(*terms: Node) -> Operation:
    return Operation("max", terms)


def smallest(*terms: Node) -> Operation:
    return Operation("min", terms)


def prop(path: str) -> Property:
    return Property(path)


def number(x: float) -> Number:
    return Number(x)


def factor(name: str) -> FactorValue:
    return FactorValue(name)


# --------------------------------------------------------------------------- names
ALPHA = "aero/alpha-deg"
ALPHA_RAD = "aero/alpha-rad"
SHIFT = "aero/calibration/alpha-shift-deg"
FLAP = "fcs/flap-pos-deg"
ELEVATOR = "fcs/elevator-pos-deg"
AILERON = "fcs/aileron-pos-deg"
RUDDER = "fcs/rudder-pos-deg"
ALPHA_TAIL = "aero/ht/alpha-deg"
INVERSE_SPEED = ratio(number(1.0), prop("velocities/vt-fps"))
# the breakpoint axes of the strip model's tables, as JSBSim properties
TC = "aero/slipstream/tc"
TABLE_AXES = {"alpha": ALPHA, "shift": SHIFT, "flap": FLAP, "elevator": ELEVATOR, "aileron": AILERON,
              "rudder": RUDDER, "alpha_h": ALPHA_TAIL, "tc": TC}


class _Terms:
    """The building blocks of the aerodynamic functions of one aircraft."""

    def __init__(self, model: AeroModel):
        self.model = model

    def table(self, name: str) -> Lookup:
        t = self.model.tables[name]
        return Lookup(t, TABLE_AXES[t.row_name], TABLE_AXES.get(t.col_name) if t.col_name else None)

    def const(self, name: str) -> float:
        return self.model.const(name)

    @staticmethod
    def force(*coefficients: Node) -> Operation:
        return product(prop("aero/qbar-psf"), prop("metrics/Sw-sqft"), *coefficients)

    @staticmethod
    def moment(length: str, *coefficients: Node) -> Operation:
        return product(prop("aero/qbar-psf"), prop("metrics/Sw-sqft"), prop(length), *coefficients)

    @staticmethod
    def roll_rate() -> Operation:
        return product(prop("aero/bi2vel"), prop("velocities/p-aero-rad_sec"))

    @staticmethod
    def yaw_rate() -> Operation:
        return product(prop("aero/bi2vel"), prop("velocities/r-aero-rad_sec"))

    @staticmethod
    def pitch_rate() -> Operation:
        return product(prop("aero/ci2vel"), prop("velocities/q-aero-rad_sec"))

    @staticmethod
    def reynolds_scale(reference: Node) -> Operation:
        """Profile-drag scale (Re/Re_reference)^-0.2, held within [0.7, 1.5]."""
        ratio_re = ratio(prop("aero/reynolds-per-ft"), reference)
        return largest(number(0.7), smallest(number(1.5), power(largest(ratio_re, number(0.01)), number(-0.2))))

    @staticmethod
    def to_wind_normal(lift: str, drag: str) -> Operation:
        """Lift cos(alpha) + drag sin(alpha): the body-normal force of a surface."""
        return total(product(prop(lift), cosine(prop(ALPHA_RAD))), product(prop(drag), sine(prop(ALPHA_RAD))))


# --------------------------------------------------------------------------- aerodynamics
def _air(terms: _Terms) -> list[Function]:
    """Section-angle shift and Reynolds-number scales."""
    temperature = prop("atmosphere/T-R")
    viscosity = product(number(3.737e-7), power(ratio(temperature, number(518.67)), number(1.5)),
                        ratio(number(518.67 + 198.72), total(temperature, number(198.72))))
    return [
        Function(SHIFT, "alpha_shift + alpha_shift_addl: added to the wing section angle (eq. 3.1, 3.27)",
                 total(factor("alpha_shift"), factor("alpha_shift_addl"))),
        # Reynolds number: tables are built at one Reynolds number per angle of attack; skin
        # friction of a turbulent boundary layer scales as Re^-0.2 away from it.
        Function("aero/reynolds-per-ft", "free-stream Reynolds number per foot (Sutherland viscosity)",
                 ratio(product(prop("atmosphere/rho-slugs_ft3"), prop("velocities/vt-fps")), viscosity)),
        Function("aero/wing/re-factor", "profile-drag scale (Re/Re_table)^-0.2 of the wing strips",
                 terms.reynolds_scale(terms.table("wing_Re"))),
        Function("aero/body/re-factor", "profile-drag scale (Re/Re_cruise)^-0.2 of tails and fuselage",
                 terms.reynolds_scale(number(terms.const("cruise_Re_per_ft")))),
    ]


def _slipstream(terms: _Terms) -> list[Function]:
    """Momentum-theory slipstream (jsbsim_calib.physics.slipstream): disc thrust and torque
    coefficients, the dynamic-pressure gains of the surfaces inside it, the swirl at the fin."""
    t, c = terms.table, terms.const
    area_ft2 = c("disc_area") * M2_TO_FT2
    radius_ft = c("disc_radius") / FT
    qa = product(largest(prop("aero/qbar-psf"), number(1.0)), number(area_ft2))
    a = product(number(0.5), difference(power(total(number(1.0), prop(TC)), number(0.5)), number(1.0)))
    return [
        Function(TC, "disc thrust coefficient Tc = T / (qbar A_disc), within [0, 20]",
                 smallest(number(20.0), largest(number(0.0), ratio(prop("propulsion/engine/thrust-lbs"), qa)))),
        Function("aero/slipstream/qc", "disc torque coefficient Qc = Q / (qbar A_disc R), within [0, 5]; Q = the "
                                       "engine's power / the propeller's angular speed (the properties every JSBSim "
                                       "version has: FlightGear 2020.3's has no propeller-torque-ftlb)",
                 smallest(number(5.0), largest(number(0.0), ratio(
                     ratio(product(number(HP_FTLBF_S * 60.0 / (2.0 * math.pi)), prop("propulsion/engine/power-hp")),
                           largest(prop("propulsion/engine/propeller-rpm"), number(1.0))),
                     product(qa, number(radius_ft)))))),
        Function("aero/slipstream/a", "axial induction a: Tc = 4 a (1 + a)", a),
        Function("aero/slipstream/ht-gain", "dynamic-pressure gain of the horizontal tail: 1 + K_slip f_h(Tc) Tc",
                 total(number(1.0), product(factor("K_slip"), t("slip_ht_fraction"), prop(TC)))),
        Function("aero/slipstream/fin-gain", "dynamic-pressure gain of the fin: 1 + K_slip f_v(Tc) Tc",
                 total(number(1.0), product(factor("K_slip"), t("slip_fin_fraction"), prop(TC)))),
        Function("aero/slipstream/wing-gain", "dynamic-pressure increment of the wing (root strips): K_slip f_w(Tc) Tc",
                 product(factor("K_slip"), t("slip_wing_fraction"), prop(TC))),
        Function("aero/slipstream/fin-sideslip-rad", "sideslip the swirl makes at the fin: -sense K_swirl Qc "
                                                     "R/(2r) / ((1 + a)(1 + 2a))",
                 product(number(-c("prop_sense")), factor("K_swirl"), prop("aero/slipstream/qc"), t("slip_fin_swirl_arm"),
                         ratio(number(1.0), product(total(number(1.0), prop("aero/slipstream/a")),
                                                    total(number(1.0), product(number(2.0),
                                                                               prop("aero/slipstream/a"))))))),
    ]


def _fin_slipstream(terms: _Terms, coefficient: str) -> Operation:
    """The fin in the slipstream: its sideslip effect grown by the dynamic-pressure gain, and the
    swirl's sideslip at the fin: fin_X_beta ((gain - 1) beta + gain beta_swirl)."""
    gain = prop("aero/slipstream/fin-gain")
    return product(terms.table(f"vt_{coefficient}_beta"),
                   total(product(difference(gain, number(1.0)), prop("aero/beta-rad")),
                         product(gain, prop("aero/slipstream/fin-sideslip-rad"))))


def _wing(terms: _Terms) -> list[Function]:
    t, c, m = terms.table, terms.const, terms.model
    return [
        Function("aero/wing/CL", "wing lift: (K_cl_slope (CL_w(alpha, shift) + K_dcl_flaps flaps) + K_cl_offset "
                                 "S_w/S) (1 + slipstream increment of the root strips) (eq. 3.6)",
                 product(total(product(factor("K_cl_slope"),
                                       total(t("wing_CL"), product(factor("K_dcl_flaps"), t("flap_dCL")))),
                               product(factor("K_cl_offset"), number(c("wing_area_ratio")))),
                         total(number(1.0), prop("aero/slipstream/wing-gain")))),
        Function("aero/wing/CD0", "wing profile drag: (K_cd0_slope CD0_w Re-factor + K_cd0_offset S_profile/S + flap "
                                  "increment + K_dcd0_flaps (dCD0/dflap) flap) (1 + slipstream increment) (eq. 3.7, "
                                  "3.42)",
                 product(total(product(factor("K_cd0_slope"), t("wing_CD0"), prop("aero/wing/re-factor")),
                               product(factor("K_cd0_offset"), number(c("wing_profile_ratio"))),
                               t("flap_dCD0"),
                               product(factor("K_dcd0_flaps"), number(c("flap_dcd0_per_deg")), prop(FLAP))),
                         total(number(1.0), prop("aero/slipstream/wing-gain")))),
        Function("aero/wing/CDi", "wing induced drag: K_cdi (CDi_w + flap increment) (eq. 3.9)",
                 product(factor("K_cdi"), total(t("wing_CDi"), t("flap_dCDi")))),
        Function("aero/wing/CD", "wing drag", total(prop("aero/wing/CD0"), prop("aero/wing/CDi"))),
        Function("aero/wing/Cm", "wing section moment K_cm_slope Cm_w + K_cm_offset sum(c dS)/(S c) + flap "
                                 "increment + K_dcm_flaps (dcm/dflap) flap, plus the wing normal force about the "
                                 "AERORP (eq. 3.30, 3.44)",
                 total(product(factor("K_cm_slope"), t("wing_Cm")),
                       product(factor("K_cm_offset"), number(c("wing_cm_ratio"))),
                       t("flap_dCm"),
                       product(factor("K_dcm_flaps"), number(c("flap_dcm_per_deg")), prop(FLAP)),
                       product(number(-c("wing_arm_x") / m.cbar_m), terms.to_wind_normal("aero/wing/CL", "aero/wing/CD")))),
    ]


def _elevator_offset_lift(terms: _Terms) -> Operation:
    """Lift of the elevator circulation offset 2 K_de_offset b_e sqrt(eta) / (V S) (eq. 3.36)."""
    span_ft = terms.const("elevator_span") / FT
    area_ft2 = terms.model.S_m2 * M2_TO_FT2
    return product(number(2.0 * span_ft * math.sqrt(terms.const("ht_eta")) / area_ft2 / FT**2), factor("K_de_offset"),
                   INVERSE_SPEED)


def _tail_flow(terms: _Terms) -> list[Function]:
    """The horizontal tail's local flow: lagged downwash and pitch rate."""
    arm = terms.const("ht_arm_x")
    downwash = terms.model.tables["downwash"]
    return [
        Function("aero/ht/alpha-lag-deg", "wing angle when the tail's air left the wing: alpha - alphadot l_h/V",
                 difference(prop(ALPHA), product(number(math.degrees(1.0) * arm / FT), prop("aero/alphadot-rad_sec"),
                                                 INVERSE_SPEED))),
        Function("aero/ht/alpha-deg", "local angle of the horizontal tail: alpha - downwash (lagged by the tail "
                                      "arm) + pitch rate x arm / V",
                 total(prop(ALPHA),
                       product(number(-1.0), Lookup(downwash, "aero/ht/alpha-lag-deg", FLAP)),
                       product(number(math.degrees(1.0) * arm / FT), prop("velocities/q-aero-rad_sec"),
                               INVERSE_SPEED))),
        Function("aero/ht/eps-rad", "rotation of the local flow at the tail [rad]",
                 product(number(math.radians(1.0)), difference(prop(ALPHA), prop(ALPHA_TAIL)))),
    ]


def _tail(terms: _Terms) -> list[Function]:
    t, c, m = terms.table, terms.const, terms.model
    eta = c("ht_eta")
    eps = prop("aero/ht/eps-rad")
    return _tail_flow(terms) + [
        Function("aero/ht/CL-local", "tail lift in its local flow: eta gain (CL_h + K_de_slope dCL_e) + elevator "
                                     "circulation offset 2 K_de_offset b_e sqrt(eta)/(V S) (eq. 3.36); gain: the "
                                     "slipstream's dynamic pressure",
                 total(product(number(eta), prop("aero/slipstream/ht-gain"),
                               total(t("ht_CL"), product(factor("K_de_slope"), t("elev_dCL")))),
                       _elevator_offset_lift(terms))),
        Function("aero/ht/CD-local", "tail drag in its local flow: eta gain (K_cd0_slope CD0_h + K_cd0_offset "
                                     "S_h/S + K_cdi CDi_h + elevator drag)",
                 product(number(eta), prop("aero/slipstream/ht-gain"),
                         total(product(factor("K_cd0_slope"), t("ht_CD0"), prop("aero/body/re-factor")),
                               product(factor("K_cd0_offset"), number(c("ht_profile_ratio"))),
                               product(factor("K_cdi"), t("ht_CDi")),
                               t("elev_dCD")))),
        Function("aero/ht/CL", "tail lift, free-stream axes",
                 difference(product(prop("aero/ht/CL-local"), cosine(eps)),
                            product(prop("aero/ht/CD-local"), sine(eps)))),
        Function("aero/ht/CD", "tail drag, free-stream axes",
                 total(product(prop("aero/ht/CD-local"), cosine(eps)),
                       product(prop("aero/ht/CL-local"), sine(eps)))),
        Function("aero/ht/Cm", "tail forces about the AERORP and the tail section moment",
                 total(product(number(-c("ht_arm_x") / m.cbar_m), terms.to_wind_normal("aero/ht/CL", "aero/ht/CD")),
                       product(number(c("ht_arm_z") / m.cbar_m),
                               difference(product(prop("aero/ht/CD"), cosine(prop(ALPHA_RAD))),
                                          product(prop("aero/ht/CL"), sine(prop(ALPHA_RAD))))),
                       product(number(eta), prop("aero/slipstream/ht-gain"),
                               total(t("ht_Cm"), product(factor("K_de_slope"), t("elev_dCm")))))),
    ]


def _body_and_offsets(terms: _Terms) -> list[Function]:
    """Fuselage group drag and the circulation offsets of the lateral controls."""
    t, c, m = terms.table, terms.const, terms.model
    area_ft2 = m.S_m2 * M2_TO_FT2
    span_ft = m.b_m / FT
    rudder_span_ft = c("rudder_span") / FT
    aileron_arm2_ft2 = c("aileron_moment_arm2") / FT**2
    return [
        Function("aero/body/CD", "fuselage, fin and drag items: K_cd0_slope (CD_fus + CD_fin + CD_items) "
                                 "(1 + 0.38 CL^2) + K_cd0_offset (1 + S_v/S) (eq. 3.8). The (1 + 0.38 CL^2) is "
                                 "the lift-dependent parasite drag of parts outside the wing strips (Kroo)",
                 total(product(factor("K_cd0_slope"),
                               total(product(total(t("body_CD"), number(c("vt_CD0"))), prop("aero/body/re-factor")),
                                     number(c("items_CD0"))),
                               total(number(1.0), product(number(KROO_K), prop("aero/wing/CL"), prop("aero/wing/CL")))),
                       product(factor("K_cd0_offset"), number(1.0 + c("vt_profile_ratio"))))),
        Function("aero/rudder/CY-offset", "rudder circulation offset: side force 2 K_dr_offset b_r/(V S) (eq. 3.36)",
                 product(number(2.0 * rudder_span_ft / area_ft2 / FT**2), factor("K_dr_offset"), INVERSE_SPEED)),
        Function("aero/aileron/Cl-offset", "aileron circulation offset: roll 2 K_da_offset sum(b y)/(V S b) (eq. 3.36)",
                 product(number(2.0 * aileron_arm2_ft2 / (area_ft2 * span_ft) / FT**2), factor("K_da_offset"),
                         INVERSE_SPEED)),
        Function("aero/elevator/CL-offset", "(reported) elevator circulation offset lift", _elevator_offset_lift(terms)),
    ]


def _forces(terms: _Terms) -> list[Axis]:
    t, force = terms.table, terms.force
    return [
        Axis("LIFT", (
            Function("aero/force/L_wing", "wing lift", force(prop("aero/wing/CL"))),
            Function("aero/force/L_ht", "horizontal-tail lift", force(prop("aero/ht/CL"))),
            Function("aero/force/L_body", "fuselage lift", force(t("body_CL"))),
            Function("aero/force/L_q", "wing lift due to pitch rate", force(t("CL_q"), terms.pitch_rate())))),
        Axis("DRAG", (
            Function("aero/force/D_wing", "wing drag", force(prop("aero/wing/CD"))),
            Function("aero/force/D_ht", "horizontal-tail drag", force(prop("aero/ht/CD"))),
            Function("aero/force/D_body", "fuselage, fin and drag items", force(prop("aero/body/CD"))),
            Function("aero/force/D_controls", "aileron and rudder drag", force(total(t("ail_dCD"), t("rud_dCD")))))),
        Axis("SIDE", (
            Function("aero/force/Y_beta", "side force due to sideslip", force(t("CY_beta"), prop("aero/beta-rad"))),
            Function("aero/force/Y_rates", "side force due to roll and yaw rate",
                     force(total(product(t("CY_p"), terms.roll_rate()), product(t("CY_r"), terms.yaw_rate())))),
            Function("aero/force/Y_controls", "side force due to aileron and rudder (K_da/K_dr slope, eq. 3.36; the "
                                              "rudder in the slipstream's dynamic pressure)",
                     force(total(product(factor("K_da_slope"), t("ail_dCY")),
                                 product(factor("K_dr_slope"), t("rud_dCY"), prop("aero/slipstream/fin-gain")),
                                 prop("aero/rudder/CY-offset")))),
            Function("aero/force/Y_slipstream", "the fin in the slipstream: dynamic pressure and swirl",
                     force(_fin_slipstream(terms, "CY")))))]


def _roll_and_pitch(terms: _Terms) -> list[Axis]:
    t, c, m, moment = terms.table, terms.const, terms.model, terms.moment
    return [
        Axis("ROLL", (
            Function("aero/moment/l_beta", "dihedral effect", moment("metrics/bw-ft", t("Cl_beta"), prop("aero/beta-rad"))),
            Function("aero/moment/l_rates", "roll damping and roll due to yaw rate",
                     moment("metrics/bw-ft", total(product(t("Cl_p"), terms.roll_rate()),
                                                   product(t("Cl_r"), terms.yaw_rate())))),
            Function("aero/moment/l_slipstream", "the fin in the slipstream: dynamic pressure and swirl",
                     moment("metrics/bw-ft", _fin_slipstream(terms, "Cl"))),
            Function("aero/moment/l_controls", "aileron (K_da slope/offset) and rudder (K_dr, in the slipstream) roll",
                     moment("metrics/bw-ft", total(product(factor("K_da_slope"), t("ail_dCl")),
                                                   prop("aero/aileron/Cl-offset"),
                                                   product(factor("K_dr_slope"), t("rud_dCl"),
                                                           prop("aero/slipstream/fin-gain")),
                                                   product(number(c("rudder_arm_z") / m.b_m),
                                                           prop("aero/rudder/CY-offset"))))),
            Function("aero/moment/l_damping", "extra roll damping -K_Clp p b/(2V) (eq. 3.48)",
                     moment("metrics/bw-ft", number(-1.0), factor("K_Clp"), terms.roll_rate())))),
        Axis("PITCH", (
            Function("aero/moment/m_wing", "wing", moment("metrics/cbarw-ft", prop("aero/wing/Cm"))),
            Function("aero/moment/m_ht", "horizontal tail", moment("metrics/cbarw-ft", prop("aero/ht/Cm"))),
            Function("aero/moment/m_body", "fuselage (Munk) and drag items below/above the AERORP",
                     moment("metrics/cbarw-ft",
                            total(t("body_Cm"),
                                  product(factor("K_cd0_slope"), number(c("items_CD0") * c("items_arm_z") / m.cbar_m)),
                                  product(factor("K_cd0_slope"), t("body_CD"), number(c("fus_arm_z") / m.cbar_m))))),
            Function("aero/moment/m_q", "wing pitch damping", moment("metrics/cbarw-ft", t("Cm_q"), terms.pitch_rate())),
            Function("aero/moment/m_damping", "extra pitch damping -K_Cmq q c/(2V) (eq. 3.51)",
                     moment("metrics/cbarw-ft", number(-1.0), factor("K_Cmq"), terms.pitch_rate())),
            Function("aero/moment/m_alpha", "extra pitch stiffness K_Cm_alpha alpha (stage 2b)",
                     moment("metrics/cbarw-ft", factor("K_Cm_alpha"), prop(ALPHA_RAD)))))]


def _yaw(terms: _Terms, geom: AircraftGeometry) -> Axis:
    t, c, m, moment = terms.table, terms.const, terms.model, terms.moment
    return Axis("YAW", (
        Function("aero/moment/n_beta", "weathercock stability", moment("metrics/bw-ft", t("Cn_beta"),
                                                                        prop("aero/beta-rad"))),
        Function("aero/moment/n_rates", "yaw damping and yaw due to roll rate",
                 moment("metrics/bw-ft", total(product(t("Cn_p"), terms.roll_rate()),
                                               product(t("Cn_r"), terms.yaw_rate())))),
        Function("aero/moment/n_slipstream", "the fin in the slipstream: dynamic pressure and swirl",
                 moment("metrics/bw-ft", _fin_slipstream(terms, "Cn"))),
        Function("aero/moment/n_controls", "aileron adverse yaw and rudder (K_da/K_dr, eq. 3.36; the rudder in the "
                                           "slipstream)",
                 moment("metrics/bw-ft", total(product(factor("K_da_slope"), t("ail_dCn")),
                                               product(factor("K_dr_slope"), t("rud_dCn"),
                                                       prop("aero/slipstream/fin-gain")),
                                               product(number(-c("vt_arm_x") / m.b_m), prop("aero/rudder/CY-offset"))))),
        Function("aero/moment/n_damping", "extra yaw damping -K_Cnr r b/(2V) (eq. 3.54)",
                 moment("metrics/bw-ft", number(-1.0), factor("K_Cnr"), terms.yaw_rate())),
        Function("aero/moment/n_pfactor", "P-factor N = -K_PF T (D/2) sin(alpha) [lbf ft] (eq. 3.38)",
                 product(number(-0.5 * geom.propeller.diameter_m / FT), factor("K_PF"), prop("propulsion/engine/thrust-lbs"),
                         sine(prop(ALPHA_RAD))))))


def aerodynamics(geom: AircraftGeometry, model: AeroModel) -> Aerodynamics:
    """The aerodynamic functions of an aircraft: coefficients on the wing area, moments about
    the AERORP, angles in degrees; calibration factors where the method puts them."""
    terms = _Terms(model)
    functions = _air(terms) + _slipstream(terms) + _wing(terms) + _tail(terms) + _body_and_offsets(terms)
    return Aerodynamics(tuple(functions), tuple(_forces(terms) + _roll_and_pitch(terms) + [_yaw(terms, geom)]))


# --------------------------------------------------------------------------- engine calibration
def engine_calibration(piston: PistonParams) -> tuple[Function, ...]:
    """FGPiston's volumetric efficiency and indicated fuel consumption with the engine factors:
    VE x K_HP x K_FF x (T/T_std(pressure altitude))^(1-n) (power follows (T_std/T)^n at a
    pressure altitude; FGPiston's air flow alone gives n = 1), ISFC x K_FF (K_FF changes fuel
    flow, not power)."""
    standard_temperature = difference(number(518.67), product(number(0.00356616), prop("atmosphere/pressure-altitude")))
    return (
        Function("propulsion/calibration/volumetric-efficiency",
                 "FGPiston volumetric efficiency with power and temperature calibration",
                 product(number(piston.volumetric_efficiency), factor("K_HP"), factor("K_FF"),
                         power(ratio(prop("atmosphere/T-R"), standard_temperature),
                               number(1.0 - piston.temperature_exponent))),
                 output="propulsion/engine/volumetric-efficiency"),
        Function("propulsion/calibration/isfc",
                 "FGPiston fuel consumption per indicated power with fuel-flow calibration",
                 product(number(piston.isfc_lb_hphr), factor("K_FF")), output="propulsion/engine/bsfc-lbs_hphr"),
    )
