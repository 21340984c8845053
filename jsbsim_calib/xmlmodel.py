"""The one module that knows JSBSim's XML: aircraft, engine and propeller files.

It writes what the preprocessors computed (SI inside Python) in JSBSim units with explicit
``unit=`` attributes, declares every calibration factor as a persistent property with its
bounds and doc beside it, and reads/edits factor values in an existing file.
"""
from __future__ import annotations

import math
from decimal import Decimal
from pathlib import Path
from typing import Mapping

import numpy as np
from lxml import etree

from .physics.aero.model import AeroModel, Table
from .physics.engine import PistonParams
from .errors import ModelError
from .factors import FACTORS, REGISTRY, Factor, FactorSet
from .physics.geometry import AircraftGeometry
from .physics.propeller import PropellerTables
from .units import FT, IN, LB_PER_GAL_AVGAS, LBF, LBM, SLUG, US_GAL

E = etree.Element
M2_TO_FT2 = 1.0 / FT**2
# Parasite drag grows with lift as CDp (1 + 0.38 CL^2) (I. Kroo, Aircraft Design: Synthesis and
# Analysis, "drag due to lift": the viscous part of lift-dependent drag). The wing strips
# carry theirs in the section polars; this adds it to the fuselage, fin and drag items.
KROO_K = 0.38


# Numbers in generated files have a fixed precision (README, "Reproducible bytes"): scalars
# NUMBER_DIGITS significant digits; every table TABLE_DIGITS significant digits of its
# largest entry, the same decimals for all its entries (an absolute precision, so that
# entries near zero, which carry the round-off of the larger terms they are sums of, are
# not written to more digits than their neighbours). Never an exponent.
NUMBER_DIGITS = 6
TABLE_DIGITS = 6
FACTOR_DIGITS = 10          # factor values: what calibration.json records


def fmt(x: float, digits: int = NUMBER_DIGITS) -> str:
    """``x`` to ``digits`` significant digits in plain notation (same bytes on every run)."""
    x = float(x)
    if not math.isfinite(x):
        raise ValueError(f"cannot write {x} into a JSBSim file")
    if x == 0.0:
        return "0"
    return _plain(f"{x:.{digits}g}")


def fmt_fixed(x: float, decimals: int) -> str:
    """``x`` rounded to ``decimals`` decimal places (negative: tens, hundreds ...), plain notation."""
    x = float(x)
    if not math.isfinite(x):
        raise ValueError(f"cannot write {x} into a JSBSim file")
    if decimals < 0:
        return _plain(f"{round(x, decimals):.0f}")
    return _plain(f"{x:.{decimals}f}")


def decimals_for(values, digits: int = TABLE_DIGITS) -> int:
    """Decimal places that give ``digits`` significant digits to the largest of ``values``."""
    top = float(np.max(np.abs(np.asarray(values, float)))) if np.size(values) else 0.0
    if top == 0.0 or not math.isfinite(top):
        return digits
    return digits - 1 - math.floor(math.log10(top))


def _plain(s: str) -> str:
    """A number string without exponent or trailing zeros; '-0' -> '0'."""
    if "e" in s or "E" in s:
        s = format(Decimal(s), "f")
    if "." in s:
        s = s.rstrip("0").rstrip(".")
    return "0" if s in ("-0", "", "-") else s


def sub(parent, tag: str, text: str | None = None, **attrib) -> etree._Element:
    el = etree.SubElement(parent, tag, {k: str(v) for k, v in attrib.items()})
    if text is not None:
        el.text = f" {text} "
    return el


def comment(parent, text: str) -> None:
    parent.append(etree.Comment(f" {text} "))


def location(parent, name: str | None, xyz_m, tag: str = "location") -> etree._Element:
    el = sub(parent, tag, unit="IN", **({"name": name} if name else {}))
    for axis, v in zip("xyz", np.asarray(xyz_m) / IN):
        sub(el, axis, fmt(v, 5))
    return el


# --------------------------------------------------------------------------- function DSL
def P(name: str):
    el = E("property")
    el.text = f" {name} "
    return el


def V(x: float):
    el = E("value")
    el.text = f" {fmt(x)} "
    return el


def op(tag: str, *args):
    el = E(tag)
    for a in args:
        el.append(a)
    return el


def product(*a):
    return op("product", *a)


def sum_(*a):
    return op("sum", *a)


def diff(*a):
    return op("difference", *a)


def quot(a, b):
    return op("quotient", a, b)


def cos_(a):
    return op("cos", a)


def sin_(a):
    return op("sin", a)


def sqrt_(a):
    return op("sqrt", a)


def table(t: Table, row_prop: str, col_prop: str | None = None):
    el = E("table")
    sub(el, "independentVar", row_prop, lookup="row")
    if t.col is not None:
        sub(el, "independentVar", col_prop, lookup="column")
    lines = []
    d = decimals_for(t.data)
    if t.col is not None:
        lines.append("          " + " ".join(f"{fmt(c, 5):>10}" for c in t.col))
        for r, row in zip(t.row, t.data):
            lines.append(f"{fmt(r, 5):>9} " + " ".join(f"{fmt_fixed(v, d):>10}" for v in row))
    else:
        for r, v in zip(t.row, t.data):
            lines.append(f"{fmt(r, 5):>9} {fmt_fixed(v, d):>12}")
    td = sub(el, "tableData")
    td.text = "\n" + "\n".join(lines) + "\n        "
    return el


def function(parent, name: str, description: str, expr) -> etree._Element:
    f = sub(parent, "function", name=name)
    sub(f, "description", description)
    f.append(expr)
    return f


# --------------------------------------------------------------------------- names
ALPHA = "aero/alpha-deg"
SHIFT = "aero/calibration/alpha-shift-deg"
FLAP = "fcs/flap-pos-deg"
ELEV = "fcs/elevator-pos-deg"
AIL = "fcs/aileron-pos-deg"
RUD = "fcs/rudder-pos-deg"
ALPHA_H = "aero/ht/alpha-deg"
LOOKUP = {"alpha": ALPHA, "shift": SHIFT, "flap": FLAP, "elevator": ELEV, "aileron": AIL, "rudder": RUD,
          "alpha_h": ALPHA_H}


def T(model: AeroModel, name: str):
    t = model.tables[name]
    return table(t, LOOKUP[t.row_name], LOOKUP.get(t.col_name) if t.col_name else None)


def fp(f: Factor) -> etree._Element:
    return P(f.property)


def K(name: str):
    return P(REGISTRY[name].property)


# --------------------------------------------------------------------------- aircraft
def aircraft_xml(geom: AircraftGeometry, aero: AeroModel, *, engine_file: str, propeller_file: str,
                 piston: PistonParams, factors: FactorSet, inertia_empty: np.ndarray,
                 travel_comment: str = "") -> etree._ElementTree:
    root = E("fdm_config", name=geom.title, version="2.0", release="ALPHA")
    root.text = "\n"
    hdr = sub(root, "fileheader")
    sub(hdr, "author", "jsbsim-calib (generated)")
    sub(hdr, "filecreationdate", "2026-11-21")
    sub(hdr, "version", "1")
    sub(hdr, "description", f"{geom.title}: strip-theory aerodynamics, BEM propeller, FGPiston engine")
    sub(hdr, "note", f"Generated from {geom.path.parent.name}/{geom.path.name} by 'jsbsim-calib generate "
                     f"{geom.name}'. Edit the geometry file and regenerate, or edit the calibration "
                     "properties below by hand. Public sources are cited in the geometry file.")

    met = sub(root, "metrics")
    sub(met, "wingarea", fmt(aero.S_m2 * M2_TO_FT2), unit="FT2")
    sub(met, "wingspan", fmt(aero.b_m / FT), unit="FT")
    sub(met, "chord", fmt(aero.cbar_m / FT), unit="FT")
    sub(met, "htailarea", fmt(geom.horizontal_tail.area_m2 * M2_TO_FT2), unit="FT2")
    sub(met, "htailarm", fmt(aero.const("ht_arm_x") / FT), unit="FT")
    sub(met, "vtailarea", fmt(geom.vertical_tail.area_m2 * M2_TO_FT2), unit="FT2")
    sub(met, "vtailarm", fmt(aero.const("vt_arm_x") / FT), unit="FT")
    comment(met, "AERORP: the wing's mean quarter chord; aerodynamic moments below are about it")
    location(met, "AERORP", aero.aerorp_m)
    location(met, "EYEPOINT", geom.mass.stations[0].location_m + np.array([0.0, -0.35, 0.75]) if geom.mass.stations
             else aero.aerorp_m)
    location(met, "VRP", np.zeros(3))

    mb = sub(root, "mass_balance")
    comment(mb, "Inertia: radii of gyration (geometry [mass]) applied at max weight, minus the default loading "
                "and full fuel, so the loaded aircraft at max weight has Ixx = b^2 W Rx^2/(4g) etc.")
    for tag, v in zip(("ixx", "iyy", "izz"), inertia_empty):
        sub(mb, tag, fmt(v / (SLUG * FT**2)), unit="SLUG*FT2")
    sub(mb, "ixz", "0", unit="SLUG*FT2")
    sub(mb, "emptywt", fmt(geom.mass.empty_mass_kg / LBM), unit="LBS")
    location(mb, "CG", geom.mass.empty_cg_m)
    comment(mb, "pointmass 0 is the payload jsbsim-calib sets (weight and station) to reach a test's weight and CG")
    pm = sub(mb, "pointmass", name="calibration payload")
    sub(pm, "weight", "0", unit="LBS")
    location(pm, None, np.array([geom.operations.poh_cg_m, 0.0, 0.0]))
    for st in geom.mass.stations:
        pm = sub(mb, "pointmass", name=st.name)
        sub(pm, "weight", fmt(st.mass_kg / LBM), unit="LBS")
        location(pm, None, st.location_m)

    gr = sub(root, "ground_reactions")
    for c in geom.gear:
        ct = sub(gr, "contact", type=c.type, name=c.name)
        location(ct, None, c.location_m)
        static, dynamic = (0.8, 0.5) if c.type == "BOGEY" else (1.0, 1.0)
        sub(ct, "static_friction", fmt(static))
        sub(ct, "dynamic_friction", fmt(dynamic))
        sub(ct, "rolling_friction", "0.02")
        sub(ct, "spring_coeff", fmt(c.spring_n_per_m / (LBF / FT)), unit="LBS/FT")
        sub(ct, "damping_coeff", fmt(c.damping_n_s_per_m / (LBF / FT)), unit="LBS/FT/SEC")
        if c.damping_rebound_n_s_per_m is not None:
            sub(ct, "damping_coeff_rebound", fmt(c.damping_rebound_n_s_per_m / (LBF / FT)), unit="LBS/FT/SEC")
        sub(ct, "max_steer", fmt(math.degrees(c.max_steer_rad)), unit="DEG")
        sub(ct, "brake_group", c.brake_group)
        sub(ct, "retractable", "0")

    pr = sub(root, "propulsion")
    en = sub(pr, "engine", file=engine_file)
    for i in range(len(geom.tanks)):
        sub(en, "feed", str(i))
    th = sub(en, "thruster", file=propeller_file)
    sub(th, "sense", str(geom.propeller.sense))
    location(th, None, geom.propeller.location_m)
    orient = sub(th, "orient", unit="DEG")
    for a in ("roll", "pitch", "yaw"):
        sub(orient, a, "0")
    for i, t in enumerate(geom.tanks):
        tk = sub(pr, "tank", type="FUEL", number=str(i))
        comment(tk, f"{t.name} tank, {fmt(t.capacity_m3 / US_GAL)} US gal AVGAS")
        location(tk, None, t.location_m)
        cap_lb = t.capacity_m3 / US_GAL * LB_PER_GAL_AVGAS
        sub(tk, "capacity", fmt(cap_lb), unit="LBS")
        sub(tk, "contents", fmt(cap_lb), unit="LBS")
        sub(tk, "unusable", fmt(t.unusable_m3 / US_GAL * LB_PER_GAL_AVGAS), unit="LBS")
        sub(tk, "type", geom.fuel_type)

    _calibration_system(root, factors, piston)
    _fcs(root, geom, travel_comment)
    _aerodynamics(root, geom, aero)
    return etree.ElementTree(root)


def _calibration_system(root, factors: FactorSet, piston: PistonParams) -> None:
    sy = sub(root, "system", name="calibration")
    comment(sy, "Calibration factors of the method (persistent: a reset keeps them). Edit a value by hand to "
                "change the model; bounds and the equation of the method are given beside each. Factors marked "
                "'baked' act through the propeller tables: change them with 'jsbsim-calib generate'.")
    for f in FACTORS:
        bounds = f"[{fmt(f.lower)}, {fmt(f.upper)}] {f.unit}".rstrip()
        tag = " baked into the propeller tables;" if f.baked else ""
        comment(sy, f"{f.name}: {f.doc}. Acts on {f.applies_to}. Bounds {bounds}, neutral {fmt(f.neutral)};{tag}")
        sub(sy, "property", f.property, value=fmt(factors[f.name], FACTOR_DIGITS), persistent="true")
    ch = sub(sy, "channel", name="engine calibration")
    comment(ch, "Volumetric efficiency: base value x K_HP x K_FF x (T/T_std(pressure altitude))^(1-n), so that "
                f"power follows (T_std/T)^n, n = {fmt(piston.temperature_exponent)}, at a given pressure altitude "
                "(FGPiston's air flow alone gives n = 1); indicated SFC x K_FF so that K_FF changes fuel flow, "
                "not power")
    fn = sub(ch, "fcs_function", name="propulsion/calibration/volumetric-efficiency")
    sub(fn, "description", "FGPiston volumetric efficiency with power and temperature calibration")
    fun = sub(fn, "function")
    t_std = diff(V(518.67), product(V(0.00356616), P("atmosphere/pressure-altitude")))
    fun.append(product(V(piston.volumetric_efficiency), K("K_HP"), K("K_FF"),
                       op("pow", quot(P("atmosphere/T-R"), t_std), V(1.0 - piston.temperature_exponent))))
    sub(fn, "output", "propulsion/engine/volumetric-efficiency")
    fn = sub(ch, "fcs_function", name="propulsion/calibration/isfc")
    sub(fn, "description", "FGPiston fuel consumption per indicated power with fuel-flow calibration")
    fun = sub(fn, "function")
    fun.append(product(V(piston.isfc_lb_hphr), K("K_FF")))
    sub(fn, "output", "propulsion/engine/bsfc-lbs_hphr")


def _surface_channel(fcs, name: str, inputs: list[str], lo_deg: float, hi_deg: float, out_deg: str, out_norm: str,
                     note: str) -> None:
    ch = sub(fcs, "channel", name=name)
    comment(ch, note)
    sm = sub(ch, "summer", name=f"fcs/{name.lower()}-sum")
    for i in inputs:
        sub(sm, "input", i)
    clip = sub(sm, "clipto")
    sub(clip, "min", "-1")
    sub(clip, "max", "1")
    sc = sub(ch, "aerosurface_scale", name=f"fcs/{name.lower()}-scale")
    sub(sc, "input", f"fcs/{name.lower()}-sum")
    sub(sc, "zero_centered", "true")
    rng = sub(sc, "range")
    sub(rng, "min", fmt(lo_deg))
    sub(rng, "max", fmt(hi_deg))
    sub(sc, "output", out_deg)
    nm = sub(ch, "pure_gain", name=f"fcs/{name.lower()}-norm")
    sub(nm, "input", out_deg)
    sub(nm, "gain", fmt(1.0 / max(abs(lo_deg), abs(hi_deg))))
    sub(nm, "output", out_norm)


def _fcs(root, geom: AircraftGeometry, travel_comment: str) -> None:
    fcs = sub(root, "flight_control", name="FCS")
    comment(fcs, "Normalized commands (-1..1) map zero-centred onto the surface travel "
                 f"(JSBSim signs: elevator + trailing edge down, aileron + roll right, rudder + trailing edge left). "
                 f"{travel_comment}")
    el = geom.horizontal_tail.control("elevator")
    _surface_channel(fcs, "Pitch", ["fcs/elevator-cmd-norm", "fcs/pitch-trim-cmd-norm"],
                     math.degrees(el.deflection_min_rad), math.degrees(el.deflection_max_rad), ELEV,
                     "fcs/elevator-pos-norm", "elevator [deg], + trailing edge down")
    ai = geom.wing.control("aileron")
    _surface_channel(fcs, "Roll", ["fcs/aileron-cmd-norm", "fcs/roll-trim-cmd-norm"],
                     math.degrees(ai.deflection_min_rad), math.degrees(ai.deflection_max_rad), AIL,
                     "fcs/left-aileron-pos-norm", "effective aileron [deg], + right trailing edge up (roll right)")
    ch = fcs.findall("channel")[-1]
    g = sub(ch, "pure_gain", name="fcs/right-aileron-norm")
    sub(g, "input", "fcs/left-aileron-pos-norm")
    sub(g, "gain", "-1")
    sub(g, "output", "fcs/right-aileron-pos-norm")
    ru = geom.vertical_tail.control("rudder")
    _surface_channel(fcs, "Yaw", ["fcs/rudder-cmd-norm", "fcs/yaw-trim-cmd-norm"],
                     math.degrees(ru.deflection_min_rad), math.degrees(ru.deflection_max_rad), RUD,
                     "fcs/rudder-pos-norm", "rudder [deg], + trailing edge left (nose-left yaw)")
    fl = geom.wing.control("flap")
    if fl is not None:
        ch = sub(fcs, "channel", name="Flaps")
        k = sub(ch, "kinematic", name="fcs/flaps-control")
        sub(k, "input", "fcs/flap-cmd-norm")
        tr = sub(k, "traverse")
        dets = [math.degrees(d) for d in fl.detents_rad] or [0.0, math.degrees(fl.deflection_max_rad)]
        span = max(dets) - min(dets)
        prev = dets[0]
        for d in dets:
            s = sub(tr, "setting")
            sub(s, "position", fmt(d))
            sub(s, "time", fmt(fl.transit_time_s * (d - prev) / span if span else 0.0))
            prev = d
        sub(k, "output", FLAP)
        nm = sub(ch, "pure_gain", name="fcs/flap-norm")
        sub(nm, "input", FLAP)
        sub(nm, "gain", fmt(1.0 / max(dets)))
        sub(nm, "output", "fcs/flap-pos-norm")


def _aerodynamics(root, geom: AircraftGeometry, m: AeroModel) -> None:
    ae = sub(root, "aerodynamics")
    S_ft2 = m.S_m2 * M2_TO_FT2
    b_ft = m.b_m / FT
    def force(*coef):
        return product(P("aero/qbar-psf"), P("metrics/Sw-sqft"), *coef)

    def moment(length: str, *coef):
        return product(P("aero/qbar-psf"), P("metrics/Sw-sqft"), P(length), *coef)

    comment(ae, "Strip-theory tables (jsbsim_calib.aero): coefficients on the wing area; moments about the "
                "AERORP. Angles in degrees. Calibration factors (system 'calibration') act where the method puts "
                "them: see each description.")
    function(ae, SHIFT, "alpha_shift + alpha_shift_addl: added to the wing section angle (eq. 3.1, 3.27)",
             sum_(K("alpha_shift"), K("alpha_shift_addl")))
    # Reynolds number: tables are built at one Reynolds number per angle of attack; skin
    # friction of a turbulent boundary layer scales as Re^-0.2 away from it.
    mu = product(V(3.737e-7), op("pow", quot(P("atmosphere/T-R"), V(518.67)), V(1.5)),
                 quot(V(518.67 + 198.72), sum_(P("atmosphere/T-R"), V(198.72))))
    function(ae, "aero/reynolds-per-ft", "free-stream Reynolds number per foot (Sutherland viscosity)",
             quot(product(P("atmosphere/rho-slugs_ft3"), P("velocities/vt-fps")), mu))

    def re_factor(ref):
        ratio = quot(P("aero/reynolds-per-ft"), ref)
        return op("max", V(0.7), op("min", V(1.5), op("pow", op("max", ratio, V(0.01)), V(-0.2))))

    function(ae, "aero/wing/re-factor", "profile-drag scale (Re/Re_table)^-0.2 of the wing strips",
             re_factor(T(m, "wing_Re")))
    function(ae, "aero/body/re-factor", "profile-drag scale (Re/Re_cruise)^-0.2 of tails and fuselage",
             re_factor(V(m.const("cruise_Re_per_ft"))))
    # ---- wing
    function(ae, "aero/wing/CL", "wing lift: K_cl_slope (CL_w(alpha, shift) + K_dcl_flaps flaps) + K_cl_offset S_w/S "
                                 "(eq. 3.6)",
             sum_(product(K("K_cl_slope"), sum_(T(m, "wing_CL"), product(K("K_dcl_flaps"), T(m, "flap_dCL")))),
                  product(K("K_cl_offset"), V(m.const("wing_area_ratio")))))
    function(ae, "aero/wing/CD0", "wing profile drag: K_cd0_slope CD0_w Re-factor + K_cd0_offset S_profile/S + flap "
                                  "increment + K_dcd0_flaps (dCD0/dflap) flap (eq. 3.7, 3.42)",
             sum_(product(K("K_cd0_slope"), T(m, "wing_CD0"), P("aero/wing/re-factor")),
                  product(K("K_cd0_offset"), V(m.const("wing_profile_ratio"))),
                  T(m, "flap_dCD0"),
                  product(K("K_dcd0_flaps"), V(m.const("flap_dcd0_per_deg")), P(FLAP))))
    function(ae, "aero/wing/CDi", "wing induced drag: K_cdi (CDi_w + flap increment) (eq. 3.9)",
             product(K("K_cdi"), sum_(T(m, "wing_CDi"), T(m, "flap_dCDi"))))
    function(ae, "aero/wing/CD", "wing drag", sum_(P("aero/wing/CD0"), P("aero/wing/CDi")))
    function(ae, "aero/wing/Cm", "wing section moment K_cm_slope Cm_w + K_cm_offset sum(c dS)/(S c) + flap "
                                 "increment + K_dcm_flaps (dcm/dflap) flap, plus the wing normal force about the "
                                 "AERORP (eq. 3.30, 3.44)",
             sum_(product(K("K_cm_slope"), T(m, "wing_Cm")),
                  product(K("K_cm_offset"), V(m.const("wing_cm_ratio"))),
                  T(m, "flap_dCm"),
                  product(K("K_dcm_flaps"), V(m.const("flap_dcm_per_deg")), P(FLAP)),
                  product(V(-m.const("wing_arm_x") / m.cbar_m),
                          sum_(product(P("aero/wing/CL"), cos_(P("aero/alpha-rad"))),
                               product(P("aero/wing/CD"), sin_(P("aero/alpha-rad")))))))
    # ---- horizontal tail
    arm_h = m.const("ht_arm_x")
    function(ae, "aero/ht/alpha-lag-deg", "wing angle when the tail's air left the wing: alpha - alphadot l_h/V",
             diff(P(ALPHA), product(V(math.degrees(1.0) * arm_h / FT), P("aero/alphadot-rad_sec"),
                                    quot(V(1.0), P("velocities/vt-fps")))))
    function(ae, "aero/ht/alpha-deg", "local angle of the horizontal tail: alpha - downwash (lagged by the tail "
                                      "arm) + pitch rate x arm / V",
             sum_(P(ALPHA),
                  product(V(-1.0), table(m.tables["downwash"], "aero/ht/alpha-lag-deg", FLAP)),
                  product(V(math.degrees(1.0) * arm_h / FT), P("velocities/q-aero-rad_sec"),
                          quot(V(1.0), P("velocities/vt-fps")))))
    function(ae, "aero/ht/eps-rad", "rotation of the local flow at the tail [rad]",
             product(V(math.radians(1.0)), diff(P(ALPHA), P(ALPHA_H))))
    eta = m.const("ht_eta")
    b_e_ft = m.const("elevator_span") / FT
    function(ae, "aero/ht/CL-local", "tail lift in its local flow: eta (CL_h + K_de_slope dCL_e) + elevator "
                                     "circulation offset 2 K_de_offset b_e sqrt(eta)/(V S) (eq. 3.36)",
             sum_(product(V(eta), sum_(T(m, "ht_CL"), product(K("K_de_slope"), T(m, "elev_dCL")))),
                  product(V(2.0 * b_e_ft * math.sqrt(eta) / S_ft2 / FT**2), K("K_de_offset"),
                          quot(V(1.0), P("velocities/vt-fps")))))
    function(ae, "aero/ht/CD-local", "tail drag in its local flow: eta (K_cd0_slope CD0_h + K_cd0_offset "
                                     "S_h/S + K_cdi CDi_h + elevator drag)",
             product(V(eta), sum_(product(K("K_cd0_slope"), T(m, "ht_CD0"), P("aero/body/re-factor")),
                                  product(K("K_cd0_offset"), V(m.const("ht_profile_ratio"))),
                                  product(K("K_cdi"), T(m, "ht_CDi")),
                                  T(m, "elev_dCD"))))
    function(ae, "aero/ht/CL", "tail lift, free-stream axes",
             diff(product(P("aero/ht/CL-local"), cos_(P("aero/ht/eps-rad"))),
                  product(P("aero/ht/CD-local"), sin_(P("aero/ht/eps-rad")))))
    function(ae, "aero/ht/CD", "tail drag, free-stream axes",
             sum_(product(P("aero/ht/CD-local"), cos_(P("aero/ht/eps-rad"))),
                  product(P("aero/ht/CL-local"), sin_(P("aero/ht/eps-rad")))))
    function(ae, "aero/ht/Cm", "tail forces about the AERORP and the tail section moment",
             sum_(product(V(-arm_h / m.cbar_m),
                          sum_(product(P("aero/ht/CL"), cos_(P("aero/alpha-rad"))),
                               product(P("aero/ht/CD"), sin_(P("aero/alpha-rad"))))),
                  product(V(m.const("ht_arm_z") / m.cbar_m),
                          diff(product(P("aero/ht/CD"), cos_(P("aero/alpha-rad"))),
                               product(P("aero/ht/CL"), sin_(P("aero/alpha-rad"))))),
                  product(V(eta), sum_(T(m, "ht_Cm"), product(K("K_de_slope"), T(m, "elev_dCm"))))))
    # ---- fuselage group and vertical tail
    function(ae, "aero/body/CD", "fuselage, fin and drag items: K_cd0_slope (CD_fus + CD_fin + CD_items) "
                                 "(1 + 0.38 CL^2) + K_cd0_offset (1 + S_v/S) (eq. 3.8). The (1 + 0.38 CL^2) is "
                                 "the lift-dependent parasite drag of parts outside the wing strips (Kroo)",
             sum_(product(K("K_cd0_slope"),
                          sum_(product(sum_(T(m, "body_CD"), V(m.const("vt_CD0"))), P("aero/body/re-factor")),
                               V(m.const("items_CD0"))),
                          sum_(V(1.0), product(V(KROO_K), P("aero/wing/CL"), P("aero/wing/CL")))),
                  product(K("K_cd0_offset"), V(1.0 + m.const("vt_profile_ratio")))))
    # ---- rates and lateral controls
    def p_hat():
        return product(P("aero/bi2vel"), P("velocities/p-aero-rad_sec"))

    def r_hat():
        return product(P("aero/bi2vel"), P("velocities/r-aero-rad_sec"))

    def q_hat():
        return product(P("aero/ci2vel"), P("velocities/q-aero-rad_sec"))

    b_r_ft = m.const("rudder_span") / FT
    function(ae, "aero/rudder/CY-offset", "rudder circulation offset: side force 2 K_dr_offset b_r/(V S) (eq. 3.36)",
             product(V(2.0 * b_r_ft / S_ft2 / FT**2), K("K_dr_offset"), quot(V(1.0), P("velocities/vt-fps"))))
    a2_ft2 = m.const("aileron_moment_arm2") / FT**2
    function(ae, "aero/aileron/Cl-offset", "aileron circulation offset: roll 2 K_da_offset sum(b y)/(V S b) (eq. 3.36)",
             product(V(2.0 * a2_ft2 / (S_ft2 * b_ft) / FT**2), K("K_da_offset"), quot(V(1.0), P("velocities/vt-fps"))))
    function(ae, "aero/elevator/CL-offset", "(reported) elevator circulation offset lift", product(
        V(2.0 * b_e_ft * math.sqrt(eta) / S_ft2 / FT**2), K("K_de_offset"), quot(V(1.0), P("velocities/vt-fps"))))

    ax = sub(ae, "axis", name="LIFT")
    function(ax, "aero/force/L_wing", "wing lift", force(P("aero/wing/CL")))
    function(ax, "aero/force/L_ht", "horizontal-tail lift", force(P("aero/ht/CL")))
    function(ax, "aero/force/L_body", "fuselage lift", force(T(m, "body_CL")))
    function(ax, "aero/force/L_q", "wing lift due to pitch rate", force(T(m, "CL_q"), q_hat()))

    ax = sub(ae, "axis", name="DRAG")
    function(ax, "aero/force/D_wing", "wing drag", force(P("aero/wing/CD")))
    function(ax, "aero/force/D_ht", "horizontal-tail drag", force(P("aero/ht/CD")))
    function(ax, "aero/force/D_body", "fuselage, fin and drag items", force(P("aero/body/CD")))
    function(ax, "aero/force/D_controls", "aileron and rudder drag",
             force(sum_(T(m, "ail_dCD"), T(m, "rud_dCD"))))

    ax = sub(ae, "axis", name="SIDE")
    function(ax, "aero/force/Y_beta", "side force due to sideslip", force(T(m, "CY_beta"), P("aero/beta-rad")))
    function(ax, "aero/force/Y_rates", "side force due to roll and yaw rate",
             force(sum_(product(T(m, "CY_p"), p_hat()), product(T(m, "CY_r"), r_hat()))))
    function(ax, "aero/force/Y_controls", "side force due to aileron and rudder (K_da/K_dr slope, eq. 3.36)",
             force(sum_(product(K("K_da_slope"), T(m, "ail_dCY")), product(K("K_dr_slope"), T(m, "rud_dCY")),
                        P("aero/rudder/CY-offset"))))

    ax = sub(ae, "axis", name="ROLL")
    function(ax, "aero/moment/l_beta", "dihedral effect", moment("metrics/bw-ft", T(m, "Cl_beta"), P("aero/beta-rad")))
    function(ax, "aero/moment/l_rates", "roll damping and roll due to yaw rate",
             moment("metrics/bw-ft", sum_(product(T(m, "Cl_p"), p_hat()), product(T(m, "Cl_r"), r_hat()))))
    function(ax, "aero/moment/l_controls", "aileron (K_da slope/offset) and rudder (K_dr) roll",
             moment("metrics/bw-ft", sum_(product(K("K_da_slope"), T(m, "ail_dCl")), P("aero/aileron/Cl-offset"),
                                          product(K("K_dr_slope"), T(m, "rud_dCl")),
                                          product(V(m.const("rudder_arm_z") / m.b_m), P("aero/rudder/CY-offset")))))
    function(ax, "aero/moment/l_damping", "extra roll damping -K_Clp p b/(2V) (eq. 3.48)",
             moment("metrics/bw-ft", V(-1.0), K("K_Clp"), p_hat()))

    ax = sub(ae, "axis", name="PITCH")
    function(ax, "aero/moment/m_wing", "wing", moment("metrics/cbarw-ft", P("aero/wing/Cm")))
    function(ax, "aero/moment/m_ht", "horizontal tail", moment("metrics/cbarw-ft", P("aero/ht/Cm")))
    function(ax, "aero/moment/m_body", "fuselage (Munk) and drag items below/above the AERORP",
             moment("metrics/cbarw-ft", sum_(T(m, "body_Cm"),
                                             product(K("K_cd0_slope"), V(m.const("items_CD0") * m.const("items_arm_z")
                                                                         / m.cbar_m)),
                                             product(K("K_cd0_slope"), T(m, "body_CD"),
                                                     V(m.const("fus_arm_z") / m.cbar_m)))))
    function(ax, "aero/moment/m_q", "wing pitch damping", moment("metrics/cbarw-ft", T(m, "Cm_q"), q_hat()))
    function(ax, "aero/moment/m_damping", "extra pitch damping -K_Cmq q c/(2V) (eq. 3.51)",
             moment("metrics/cbarw-ft", V(-1.0), K("K_Cmq"), q_hat()))

    ax = sub(ae, "axis", name="YAW")
    function(ax, "aero/moment/n_beta", "weathercock stability", moment("metrics/bw-ft", T(m, "Cn_beta"),
                                                                        P("aero/beta-rad")))
    function(ax, "aero/moment/n_rates", "yaw damping and yaw due to roll rate",
             moment("metrics/bw-ft", sum_(product(T(m, "Cn_p"), p_hat()), product(T(m, "Cn_r"), r_hat()))))
    function(ax, "aero/moment/n_controls", "aileron adverse yaw and rudder (K_da/K_dr, eq. 3.36)",
             moment("metrics/bw-ft", sum_(product(K("K_da_slope"), T(m, "ail_dCn")),
                                          product(K("K_dr_slope"), T(m, "rud_dCn")),
                                          product(V(-m.const("vt_arm_x") / m.b_m), P("aero/rudder/CY-offset")))))
    function(ax, "aero/moment/n_damping", "extra yaw damping -K_Cnr r b/(2V) (eq. 3.54)",
             moment("metrics/bw-ft", V(-1.0), K("K_Cnr"), r_hat()))
    function(ax, "aero/moment/n_pfactor", "P-factor N = -K_PF T (D/2) sin(alpha) [lbf ft] (eq. 3.38)",
             product(V(-0.5 * geom.propeller.diameter_m / FT), K("K_PF"), P("propulsion/engine/thrust-lbs"),
                     sin_(P("aero/alpha-rad"))))


# --------------------------------------------------------------------------- engine / propeller
def engine_xml(p: PistonParams, spec_note: str) -> etree._ElementTree:
    root = E("piston_engine", name=p.name)
    root.text = "\n"
    comment(root, spec_note)
    comment(root, "FGPiston parameters designed by jsbsim_calib.engine.design_piston: rated power at rated RPM, "
                  "sea level, best-power mixture; friction so that full-throttle power follows Gagg-Farrar. "
                  "The aircraft's 'calibration' system overrides volumetric-efficiency and bsfc each frame.")
    sub(root, "minmp", fmt(p.min_map_inhg), unit="INHG")
    sub(root, "maxmp", fmt(p.max_map_inhg), unit="INHG")
    sub(root, "displacement", fmt(p.displacement_in3), unit="IN3")
    sub(root, "bore", fmt(p.bore_in), unit="IN")
    sub(root, "stroke", fmt(p.stroke_in), unit="IN")
    sub(root, "cylinders", str(p.cylinders))
    sub(root, "compression-ratio", fmt(p.compression_ratio))
    sub(root, "maxhp", fmt(p.max_hp), unit="HP")
    sub(root, "cycles", str(p.cycles))
    sub(root, "idlerpm", fmt(p.idle_rpm))
    sub(root, "maxrpm", fmt(p.max_rpm))
    sub(root, "sparkfaildrop", "0.1")
    sub(root, "volumetric-efficiency", fmt(p.volumetric_efficiency))
    sub(root, "bsfc", fmt(p.isfc_lb_hphr), unit="LBS/HP*HR")
    sub(root, "static-fmep", fmt(p.fmep_static_pa), unit="PA")
    sub(root, "dynamic-fmep", fmt(p.fmep_dynamic_pa_per_mps), unit="PA")
    sub(root, "static-friction", fmt(p.static_friction_hp), unit="HP")
    sub(root, "peak-piston-speed", fmt(p.peak_piston_speed_fps))
    sub(root, "ram-air-factor", fmt(p.ram_air_factor))
    sub(root, "man-press-lag", fmt(p.man_press_lag_s))
    sub(root, "starter-torque", fmt(0.4 * p.max_hp))
    sub(root, "starter-rpm", fmt(2 * p.idle_rpm))
    from .physics.engine import MIXTURE_FAR, mixture_efficiency
    comment(root, "Mixture efficiency ME(fuel/air) = P(f) f_bp / f, P = brake power at constant air flow relative "
                  "to best power (classical spark-ignition mixture curve, jsbsim_calib.engine)")
    t = sub(root, "table", name="MIXTURE", type="internal")
    td = sub(t, "tableData")
    td.text = "\n" + "\n".join(f"      {fmt(f, 4):>7} {fmt(float(mixture_efficiency(f)), 5):>8}"
                                 for f in MIXTURE_FAR) + "\n    "
    return etree.ElementTree(root)


def propeller_xml(name: str, tables: PropellerTables, *, diameter_m: float, blades: int, ixx_kgm2: float,
                  factors: Mapping[str, float], min_pitch: float | None = None, max_pitch: float | None = None,
                  min_rpm: float | None = None, max_rpm: float | None = None, note: str = "") -> etree._ElementTree:
    root = E("propeller", name=name)
    root.text = "\n"
    comment(root, note)
    comment(root, "calibration (baked): " + ", ".join(f"{k}={fmt(v, FACTOR_DIGITS)}" for k, v in factors.items()))
    sub(root, "ixx", fmt(ixx_kgm2 / (SLUG * FT**2)), unit="SLUG*FT2")
    sub(root, "diameter", fmt(diameter_m / IN), unit="IN")
    sub(root, "numblades", str(blades))
    sub(root, "gearratio", "1")
    if tables.beta75_deg is not None:
        sub(root, "minpitch", fmt(min_pitch))
        sub(root, "maxpitch", fmt(max_pitch))
        if min_rpm is not None:
            sub(root, "minrpm", fmt(min_rpm))
            sub(root, "maxrpm", fmt(max_rpm))
    for tname, data in (("C_THRUST", tables.CT), ("C_POWER", tables.CP)):
        t = sub(root, "table", name=tname, type="internal")
        td = sub(t, "tableData")
        d = decimals_for(data)
        if tables.beta75_deg is None:
            rows = [f"{fmt(j, 5):>8} {fmt_fixed(v, d):>12}" for j, v in zip(tables.J, data)]
        else:
            rows = ["         " + " ".join(f"{fmt(b, 5):>10}" for b in tables.beta75_deg)]
            rows += [f"{fmt(j, 5):>8} " + " ".join(f"{fmt_fixed(v, d):>10}" for v in row)
                     for j, row in zip(tables.J, data)]
        td.text = "\n" + "\n".join(rows) + "\n    "
    return etree.ElementTree(root)


def write(tree: etree._ElementTree, path: Path) -> None:
    etree.indent(tree, space="  ")
    data = etree.tostring(tree, pretty_print=True, xml_declaration=True, encoding="UTF-8")
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(data)


def add_trim_aid(tree: etree._ElementTree, location_m) -> None:
    """Add (once) a thrust-line force driven by ``external_reactions/trim-aid/magnitude`` [lbf].

    Only the calibration sandbox uses it: a level point that needs more than full throttle
    is trimmed at full throttle plus this force, which keeps the fit's residuals continuous
    across the throttle stop and measures how far past it the point is.
    """
    root = tree.getroot()
    er = root.find("external_reactions")
    if er is not None and er.find("force[@name='trim-aid']") is not None:
        return
    if er is None:
        er = E("external_reactions")
        root.find("ground_reactions").addnext(er)
    f = sub(er, "force", name="trim-aid", frame="BODY")
    location(f, None, location_m)
    d = sub(f, "direction")
    for axis, v in zip("xyz", (1, 0, 0)):
        sub(d, axis, str(v))


# --------------------------------------------------------------------------- reading / editing factors
def read_factors(aircraft_xml_path: Path) -> FactorSet:
    """Factor values declared in an aircraft file (missing ones stay neutral)."""
    try:
        tree = etree.parse(str(aircraft_xml_path))
    except (OSError, etree.XMLSyntaxError) as exc:
        raise ModelError(f"{aircraft_xml_path}: cannot read: {exc}") from None
    by_prop = {f.property: f.name for f in FACTORS}
    vals = {}
    for el in tree.iter("property"):
        name = (el.text or "").strip()
        if name in by_prop and el.get("value") is not None:
            vals[by_prop[name]] = float(el.get("value"))
    return FactorSet(vals)


def set_factor_values(tree: etree._ElementTree, factors: Mapping[str, float]) -> None:
    """Write factor values into the property declarations of a parsed aircraft file."""
    by_prop = {f.property: f.name for f in FACTORS}
    found = set()
    for el in tree.iter("property"):
        name = (el.text or "").strip()
        # declarations carry a value attribute; references inside functions do not
        if el.get("value") is not None and name in by_prop and by_prop[name] in factors:
            el.set("value", fmt(factors[by_prop[name]], FACTOR_DIGITS))
            found.add(by_prop[name])
    missing = {k for k in factors if k in REGISTRY} - found      # effect factors are declared by their effect
    if missing:
        raise ModelError(f"aircraft file lacks declarations for factors: {', '.join(sorted(missing))}")


def read_baked_factors(propeller_xml_path: Path) -> dict[str, float]:
    """Propeller factors recorded in a propeller file's 'calibration (baked)' comment."""
    tree = etree.parse(str(propeller_xml_path))
    for c in tree.getroot().iter(etree.Comment):
        text = (c.text or "").strip()
        if text.startswith("calibration (baked):"):
            out = {}
            for part in text.split(":", 1)[1].split(","):
                if "=" in part:
                    k, v = part.split("=")
                    out[k.strip()] = float(v)
            return out
    return {}


def propulsion_files(aircraft_xml_path: Path) -> dict[str, str]:
    """The engine and thruster file names an aircraft file uses ({'engine': ..., 'thruster': ...})."""
    try:
        root = etree.parse(str(aircraft_xml_path)).getroot()
    except (OSError, etree.XMLSyntaxError):
        return {}
    out = {}
    eng = root.find("propulsion/engine")
    if eng is not None and eng.get("file"):
        out["engine"] = eng.get("file")
        thr = eng.find("thruster")
        if thr is not None and thr.get("file"):
            out["thruster"] = thr.get("file")
    return out


# --------------------------------------------------------------------------- effects
EFFECT_SYSTEM_PREFIX = "effect: "


def read_effect(path: Path) -> dict:
    """Parse an effect file (jsbsim_calib/effects/*.xml): its name, what it affects, its
    factors and its XML parts (placeholders such as {prop_radius_ft} left in place)."""
    try:
        text = Path(path).read_text()
        root = etree.fromstring(text.encode())
    except (OSError, etree.XMLSyntaxError) as exc:
        raise ModelError(f"{path}: cannot read effect: {exc}") from None
    if root.tag != "effect" or not root.get("name"):
        raise ModelError(f"{path}: the root element must be <effect name=...>")
    note = ""
    prev = root.getprevious()
    while prev is not None:
        if isinstance(prev, etree._Comment):
            note = " ".join((prev.text or "").split())
        prev = prev.getprevious()
    factors = []
    for f in root.findall("factor"):
        try:
            factors.append({"name": f.get("name"), "property": f.get("property"), "neutral": float(f.get("neutral")),
                            "lower": float(f.get("lower")), "upper": float(f.get("upper")),
                            "unit": f.get("unit", "-"), "doc": " ".join((f.text or "").split())})
        except (TypeError, ValueError):
            raise ModelError(f"{path}: factor needs name, property, neutral, lower, upper") from None
    if not factors:
        raise ModelError(f"{path}: an effect needs at least one <factor>")
    return {"name": root.get("name"), "affects": tuple((root.get("affects") or "").split()),
            "same_as": tuple((root.get("same_as") or "").split()),
            "description": " ".join((root.findtext("description") or "").split()),
            "regressor": " ".join((root.findtext("regressor") or "").split()), "note": note,
            "factors": factors, "text": text}


def add_effect(tree: etree._ElementTree, effect: dict, constants: Mapping[str, float],
               values: Mapping[str, float] | None = None) -> None:
    """Insert an effect into a parsed aircraft: its factor properties (persistent, with their
    values) and functions in a <system name="effect: NAME">, its moments in <aerodynamics>."""
    root = tree.getroot()
    name = effect["name"]
    if any(s.get("name") == EFFECT_SYSTEM_PREFIX + name for s in root.findall("system")):
        raise ModelError(f"the aircraft already has the effect '{name}'")
    try:
        el = etree.fromstring(effect["text"].format_map({k: fmt(v) for k, v in constants.items()}).encode())
    except KeyError as exc:
        raise ModelError(f"effect '{name}' needs the constant {exc}") from None
    values = dict(values or {})
    system = E("system", name=EFFECT_SYSTEM_PREFIX + name)
    comment(system, f"Effect '{name}' (added by jsbsim-calib close-loop): {effect['description']}. "
                    f"{effect['note']}")
    for f in effect["factors"]:
        comment(system, f"{f['name']}: {f['doc']}. Bounds [{f['lower']:g}, {f['upper']:g}] {f['unit']}, "
                        f"neutral {f['neutral']:g}")
        sub(system, "property", f" {f['property']} ", value=fmt(values.get(f["property"], f["neutral"]), FACTOR_DIGITS),
            persistent="true")
    part = el.find("system")
    if part is not None:
        for child in part:
            system.append(child)
    systems = root.findall("system")
    (systems[-1] if systems else root.find("flight_control")).addnext(system)
    part = el.find("aerodynamics")
    if part is not None:
        aero = root.find("aerodynamics")
        for axis in part.findall("axis"):
            # JSBSim keeps only the last <axis> of a name: the functions join the existing one
            target = aero.find(f"axis[@name='{axis.get('name')}']")
            if target is None:
                target = sub(aero, "axis", name=axis.get("name"))
            comment(target, f"effect '{name}'")
            for fn in axis:
                target.append(fn)


def effect_values(tree: etree._ElementTree) -> dict[str, dict[str, float]]:
    """Effects present in a parsed aircraft: name -> {factor property: value}."""
    out = {}
    for s in tree.getroot().findall("system"):
        n = s.get("name", "")
        if n.startswith(EFFECT_SYSTEM_PREFIX):
            out[n[len(EFFECT_SYSTEM_PREFIX):]] = {(p.text or "").strip(): float(p.get("value"))
                                                  for p in s.findall("property") if p.get("value") is not None}
    return out


def set_effect_values(tree: etree._ElementTree, values: Mapping[str, float]) -> None:
    """Write effect factor values into their declarations."""
    for s in tree.getroot().findall("system"):
        if s.get("name", "").startswith(EFFECT_SYSTEM_PREFIX):
            for p in s.findall("property"):
                k = (p.text or "").strip()
                if k in values and p.get("value") is not None:
                    p.set("value", fmt(values[k], FACTOR_DIGITS))
