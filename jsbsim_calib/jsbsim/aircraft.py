"""A JSBSim aircraft file: written from what the physics computed, and the edits calibration
makes to it.

It writes the geometry, mass properties, engine and propeller references, the flight-control
channels and the aircraft's functions (:mod:`jsbsim_calib.jsbsim.equations`) in JSBSim units
with explicit ``unit=`` attributes, declares every calibration factor as a persistent property
with its bounds and doc beside it, and reads and edits factor values and effects in an
existing file. Writing an aircraft with its factors to disk is
:func:`jsbsim_calib.jsbsim.product.write_aircraft`.
"""
from __future__ import annotations

import hashlib
import json
import math
from pathlib import Path
from typing import Mapping

import numpy as np

from .. import __version__
from ..core.errors import AircraftFileError, ModelError, Problem
from ..factors import FACTORS, REGISTRY, FactorSet
from ..physics.aero.model import AeroModel
from ..physics.engine import PistonParams
from ..physics.geometry import AircraftGeometry
from ..core.units import FT, LB_PER_GAL_AVGAS, LBF, LBM, SLUG, US_GAL
from . import equations
from .equations import AILERON, ELEVATOR, FLAP, M2_TO_FT2, RUDDER
from .pilot import OUTPUTS as PILOT_OUTPUTS, pilot_system, throttle_channel
from .xml import (FACTOR_DIGITS, Tree, comment, copy, element, element_text, fmt, function, is_comment, location,
                  operation, parse, prop, read, sub, table, tostring, tree, value)


# --------------------------------------------------------------------------- writing
def aircraft_xml(geom: AircraftGeometry, aero: AeroModel, *, engine_file: str, propeller_file: str,
                 piston: PistonParams, factors: FactorSet, inertia_empty: np.ndarray,
                 travel_comment: str = "", inputs_sha256: str = "") -> Tree:
    """The aircraft file: what the strip model, the engine design and the mass properties
    computed, in JSBSim units, with every calibration factor declared at its value.
    ``inputs_sha256``: the digest of the files it was generated from (its header's record)."""
    root = element("fdm_config", name=geom.title, version="2.0", release="ALPHA")
    root.text = "\n"
    _header(root, geom, inputs_sha256)
    _metrics(root, geom, aero)
    _mass_balance(root, geom, inertia_empty)
    _ground_reactions(root, geom)
    _propulsion(root, geom, engine_file, propeller_file)
    _calibration_system(root, factors, piston)
    pilot_system(root)
    _fcs(root, geom, travel_comment)
    _aerodynamics(root, geom, aero)
    return tree(root)


def _header(root, geom: AircraftGeometry, inputs_sha256: str) -> None:
    hdr = sub(root, "fileheader")
    sub(hdr, "author", "jsbsim-calib (generated)")
    sub(hdr, "filecreationdate", "2026-11-21")
    sub(hdr, "version", "1")
    sub(hdr, "description", f"{geom.title}: strip-theory aerodynamics, BEM propeller, FGPiston engine")
    sub(hdr, "note", f"Generated from {geom.path.parent.name}/{geom.path.name} by 'jsbsim-calib generate "
                     f"{geom.name}'. Edit the geometry file and regenerate, or edit the calibration "
                     "properties below by hand. Public sources are cited in the geometry file.")
    comment(hdr, "the workbench's record: its version, the digest of the input files, of this file's body (without "
                 "the calibration values and this record: a different body means hand edits) and of the "
                 "calibration record the values came from")
    sub(hdr, GENERATOR, program="jsbsim-calib", version=__version__, inputs=inputs_sha256, body="")


def _metrics(root, geom: AircraftGeometry, aero: AeroModel) -> None:
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


def _mass_balance(root, geom: AircraftGeometry, inertia_empty: np.ndarray) -> None:
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


def _ground_reactions(root, geom: AircraftGeometry) -> None:
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


def _propulsion(root, geom: AircraftGeometry, engine_file: str, propeller_file: str) -> None:
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
    for f in equations.engine_calibration(piston):
        fn = sub(ch, "fcs_function", name=f.name)
        sub(fn, "description", f.description)
        sub(fn, "function").append(_expression(f.expression))
        sub(fn, "output", f.output)


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
    _surface_channel(fcs, "Pitch", ["fcs/elevator-cmd-norm", "fcs/pitch-trim-cmd-norm", PILOT_OUTPUTS["pitch"]],
                     math.degrees(el.deflection_min_rad), math.degrees(el.deflection_max_rad), ELEVATOR,
                     "fcs/elevator-pos-norm", "elevator [deg], + trailing edge down")
    ai = geom.wing.control("aileron")
    _surface_channel(fcs, "Roll", ["fcs/aileron-cmd-norm", "fcs/roll-trim-cmd-norm", PILOT_OUTPUTS["roll"]],
                     math.degrees(ai.deflection_min_rad), math.degrees(ai.deflection_max_rad), AILERON,
                     "fcs/left-aileron-pos-norm", "effective aileron [deg], + right trailing edge up (roll right)")
    ch = fcs.findall("channel")[-1]
    g = sub(ch, "pure_gain", name="fcs/right-aileron-norm")
    sub(g, "input", "fcs/left-aileron-pos-norm")
    sub(g, "gain", "-1")
    sub(g, "output", "fcs/right-aileron-pos-norm")
    ru = geom.vertical_tail.control("rudder")
    _surface_channel(fcs, "Yaw", ["fcs/rudder-cmd-norm", "fcs/yaw-trim-cmd-norm", PILOT_OUTPUTS["yaw"]],
                     math.degrees(ru.deflection_min_rad), math.degrees(ru.deflection_max_rad), RUDDER,
                     "fcs/rudder-pos-norm", "rudder [deg], + trailing edge left (nose-left yaw)")
    throttle_channel(fcs)
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


def _expression(node: equations.Node):
    """An equation node as JSBSim's function language."""
    if isinstance(node, equations.Property):
        return prop(node.path)
    if isinstance(node, equations.Number):
        return value(node.value)
    if isinstance(node, equations.FactorValue):
        return prop(REGISTRY[node.name].property)
    if isinstance(node, equations.Lookup):
        t = node.table
        return table(t.row, t.data, node.row, t.col, node.column)
    return operation(node.name, *(_expression(a) for a in node.args))


def _aerodynamics(root, geom: AircraftGeometry, model: AeroModel) -> None:
    ae = sub(root, "aerodynamics")
    comment(ae, "Strip-theory tables (jsbsim_calib.aero): coefficients on the wing area; moments about the "
                "AERORP. Angles in degrees. Calibration factors (system 'calibration') act where the method puts "
                "them: see each description.")
    aero = equations.aerodynamics(geom, model)
    for f in aero.functions:
        function(ae, f.name, f.description, _expression(f.expression))
    for axis in aero.axes:
        ax = sub(ae, "axis", name=axis.name)
        for f in axis.functions:
            function(ax, f.name, f.description, _expression(f.expression))


def add_trim_aid(aircraft: Tree, location_m) -> None:
    """Add (once) a thrust-line force driven by ``external_reactions/trim-aid/magnitude`` [lbf].

    Only the calibration sandbox uses it: a level point that needs more than full throttle
    is trimmed at full throttle plus this force, which keeps the fit's residuals continuous
    across the throttle stop and measures how far past it the point is.
    """
    root = aircraft.getroot()
    er = root.find("external_reactions")
    if er is not None and er.find("force[@name='trim-aid']") is not None:
        return
    if er is None:
        er = element("external_reactions")
        root.find("ground_reactions").addnext(er)
    f = sub(er, "force", name="trim-aid", frame="BODY")
    location(f, None, location_m)
    d = sub(f, "direction")
    for axis, v in zip("xyz", (1, 0, 0)):
        sub(d, axis, str(v))


# --------------------------------------------------------------------------- factor values
def _declaration_value(el, what: str) -> tuple[float, Problem | None]:
    """The number a declaration's ``value`` holds, or the problem with it."""
    text = el.get("value", "")
    where = f"line {el.sourceline}, {what}"
    try:
        v = float(text)
    except ValueError:
        return math.nan, Problem(where, f"value {text!r} is not a number")
    if not math.isfinite(v):
        return v, Problem(where, f"value {text!r} is not a finite number")
    return v, None


def declared_factors(aircraft: Tree, source: str | Path = "aircraft file") -> dict[str, float]:
    """Factor values declared in a parsed aircraft file. Raises :class:`AircraftFileError`
    listing every declaration whose value is not a finite number or is outside the factor's
    bounds (a hand edit the calibration would never write), each with its line."""
    by_prop = {f.property: f.name for f in FACTORS}
    vals, problems = {}, []
    for el in aircraft.iter("property"):
        name = (el.text or "").strip()
        if name in by_prop and el.get("value") is not None:
            f = REGISTRY[by_prop[name]]
            v, bad = _declaration_value(el, f"factor {f.name} ({f.property})")
            if bad is None and not f.lower - 1e-12 <= v <= f.upper + 1e-12:
                bad = Problem(f"line {el.sourceline}, factor {f.name} ({f.property})",
                              f"value {v:g} is outside its bounds [{f.lower:g}, {f.upper:g}] {f.unit.strip('-')}".rstrip())
            if bad is not None:
                problems.append(bad)
            else:
                vals[f.name] = v
    if problems:
        raise AircraftFileError(source, problems)
    return vals


def read_factors(aircraft_xml_path: Path) -> FactorSet:
    """Factor values declared in an aircraft file (missing ones stay neutral); refused
    (:class:`AircraftFileError`) when a value is not a number or outside its bounds."""
    return FactorSet(declared_factors(read(aircraft_xml_path), aircraft_xml_path))


def set_factor_values(aircraft: Tree, factors: Mapping[str, float]) -> None:
    """Write factor values into the property declarations of a parsed aircraft file."""
    by_prop = {f.property: f.name for f in FACTORS}
    found = set()
    for el in aircraft.iter("property"):
        name = (el.text or "").strip()
        # declarations carry a value attribute; references inside functions do not
        if el.get("value") is not None and name in by_prop and by_prop[name] in factors:
            el.set("value", fmt(factors[by_prop[name]], FACTOR_DIGITS))
            found.add(by_prop[name])
    missing = {k for k in factors if k in REGISTRY} - found      # effect factors are declared by their effect
    if missing:
        raise ModelError(f"aircraft file lacks declarations for factors: {', '.join(sorted(missing))}")


def propulsion_files(aircraft_xml_path: Path) -> dict[str, str]:
    """The engine and thruster file names an aircraft file uses ({'engine': ..., 'thruster': ...})."""
    try:
        root = read(aircraft_xml_path).getroot()
    except ModelError:
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


INERTIA_TAGS = ("ixx", "iyy", "izz")


def moment_of_inertia(aircraft: Tree, axis: str) -> float:
    """An empty-aircraft moment of inertia of the file (``ixx``, ``iyy``, ``izz``) [slug ft2]."""
    el = aircraft.getroot().find(f"mass_balance/{axis}")
    if axis not in INERTIA_TAGS or el is None:
        raise ModelError(f"the aircraft file has no <mass_balance><{axis}>")
    return float(el.text)


def set_moment_of_inertia(aircraft: Tree, axis: str, value: float, note: str = "") -> None:
    """Write a moment of inertia into the file (slug ft2), with a comment saying why."""
    moment_of_inertia(aircraft, axis)
    el = aircraft.getroot().find(f"mass_balance/{axis}")
    el.text = f" {value:.6g} "
    if note:
        comment(el.getparent(), note)


def effect_constants(geometry: AircraftGeometry) -> dict[str, float]:
    """The aircraft constants an effect file may use as placeholders ({prop_radius_ft} ...)."""
    d_ft = geometry.propeller.diameter_m / 0.3048
    return {"prop_radius_ft": d_ft / 2.0, "prop_diameter_ft": d_ft, "prop_disk_area_ft2": math.pi * d_ft**2 / 4.0,
            "wing_span_ft": geometry.reference.span_m / 0.3048}


def add_effect(aircraft: Tree, effect, constants: Mapping[str, float],
               values: Mapping[str, float] | None = None) -> None:
    """Insert an effect of the library (:class:`jsbsim_calib.calibration.effects.Effect`: its
    ``name``, ``description``, ``note``, ``factors`` and XML ``text``) into a parsed aircraft: its
    factor properties (persistent, with their values) and functions in a
    <system name="effect: NAME">, its moments in <aerodynamics>."""
    root = aircraft.getroot()
    name = effect.name
    if any(s.get("name") == EFFECT_SYSTEM_PREFIX + name for s in root.findall("system")):
        raise ModelError(f"the aircraft already has the effect '{name}'")
    try:
        el = parse(effect.text.format_map({k: fmt(v) for k, v in constants.items()}), f"effect '{name}'")
    except KeyError as exc:
        raise ModelError(f"effect '{name}' needs the constant {exc}") from None
    values = dict(values or {})
    system = element("system", name=EFFECT_SYSTEM_PREFIX + name)
    comment(system, f"Effect '{name}' (added by jsbsim-calib close-loop): {effect.description}. {effect.note}")
    for f in effect.factors:
        comment(system, f"{f.name}: {f.doc}. Bounds [{f.lower:g}, {f.upper:g}] {f.unit}, neutral {f.neutral:g}")
        sub(system, "property", f" {f.property} ", value=fmt(values.get(f.property, f.neutral), FACTOR_DIGITS),
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


def added_xml(aircraft: Tree, change: str) -> str:
    """What a close-the-loop change wrote into a parsed aircraft, as XML text: an effect's
    ``<system name="effect: NAME">`` and the functions it joined to ``<aerodynamics>`` ("NAME");
    a calibration factor's declaration ("factor K_X"); a moment of inertia with its note
    ("inertia iyy")."""
    root = aircraft.getroot()
    kind, _, what = change.partition(" ")
    if kind == "factor" and what in REGISTRY:
        out = [p for s in root.findall("system") for p in s.findall("property")
               if (p.text or "").strip() == REGISTRY[what].property]
    elif kind == "inertia" and what in INERTIA_TAGS:
        el = root.find(f"mass_balance/{what}")
        out = [n for n in el.getparent() if is_comment(n) and "close-loop" in (n.text or "")][-1:] + [el]
    else:
        out = [s for s in root.findall("system") if s.get("name") == EFFECT_SYSTEM_PREFIX + change]
        for axis in root.findall("aerodynamics/axis"):
            mine, joined = False, []
            for node in axis:
                if is_comment(node):
                    mine = (node.text or "").strip() == f"effect '{change}'"
                elif mine:
                    joined.append(node)
            if joined:
                out.append(f'<!-- in <aerodynamics><axis name="{axis.get("name")}"> -->')
                out += joined
    if not out:
        raise ModelError(f"the aircraft has no change '{change}' of the loop")
    return "\n".join(n if isinstance(n, str) else element_text(n) for n in out)


def effect_values(aircraft: Tree) -> dict[str, dict[str, float]]:
    """Effects present in a parsed aircraft: name -> {factor property: value}."""
    out = {}
    for s in aircraft.getroot().findall("system"):
        n = s.get("name", "")
        if n.startswith(EFFECT_SYSTEM_PREFIX):
            values, problems = {}, []
            for p in s.findall("property"):
                if p.get("value") is not None:
                    v, bad = _declaration_value(p, f"effect factor {(p.text or '').strip()}")
                    problems += [bad] if bad else []
                    values[(p.text or "").strip()] = v
            if problems:
                raise AircraftFileError(f"effect '{n[len(EFFECT_SYSTEM_PREFIX):]}'", problems)
            out[n[len(EFFECT_SYSTEM_PREFIX):]] = values
    return out


def effect_property_values(aircraft: Tree) -> dict[str, float]:
    """The factor values of every effect in a parsed aircraft, by property."""
    return {p: v for vals in effect_values(aircraft).values() for p, v in vals.items()}


def set_effect_values(aircraft: Tree, values: Mapping[str, float]) -> None:
    """Write effect factor values into their declarations."""
    for s in aircraft.getroot().findall("system"):
        if s.get("name", "").startswith(EFFECT_SYSTEM_PREFIX):
            for p in s.findall("property"):
                k = (p.text or "").strip()
                if k in values and p.get("value") is not None:
                    p.set("value", fmt(values[k], FACTOR_DIGITS))


# --------------------------------------------------------------------------- the workbench's record
GENERATOR = "generator"        # <fileheader><generator program version inputs body [calibration]/>


def generator_record(aircraft: Tree) -> dict[str, str]:
    """The workbench's record in an aircraft's header ({} when the file has none)."""
    el = aircraft.getroot().find(f"fileheader/{GENERATOR}")
    return dict(el.attrib) if el is not None else {}


def _value_declarations(root):
    """The declarations whose values calibration sets: factors and effect factors."""
    factors = {f.property for f in FACTORS}
    for s in root.findall("system"):
        effect = s.get("name", "").startswith(EFFECT_SYSTEM_PREFIX)
        for p in s.findall("property"):
            if p.get("value") is not None and (effect or (p.text or "").strip() in factors):
                yield p


def canonical_body(aircraft: Tree) -> bytes:
    """The file as written without the calibration values and the record: what
    :func:`body_digest` hashes and what a hand edit changes."""
    box = copy(aircraft)
    root = box.getroot()
    el = root.find(f"fileheader/{GENERATOR}")
    if el is not None:
        el.getparent().remove(el)
    for p in _value_declarations(root):
        p.set("value", "")
    return tostring(box, indent=False)


def body_digest(aircraft: Tree) -> str:
    return "sha256:" + hashlib.sha256(canonical_body(aircraft)).hexdigest()


def hand_edited(aircraft: Tree) -> bool | None:
    """True when the body differs from the one the workbench last wrote (hand edits); None
    when the file has no record (written by hand or before the record existed)."""
    body = generator_record(aircraft).get("body")
    return None if not body else body != body_digest(aircraft)


def calibration_digest(factors) -> str:
    """A digest of calibration values: the factors away from neutral, as the aircraft file
    writes them (a factor added to the registry later, at neutral, does not change it)."""
    vals = {f.name: fmt(factors[f.name], FACTOR_DIGITS) for f in FACTORS
            if f.name in factors and fmt(factors[f.name], FACTOR_DIGITS) != fmt(f.neutral, FACTOR_DIGITS)}
    return "sha256:" + hashlib.sha256(json.dumps(vals, sort_keys=True).encode()).hexdigest()


KEEP = object()


def stamp(aircraft: Tree, *, body: bool, calibration=KEEP) -> None:
    """Update the record of a tree about to be written: ``body`` recomputes the body digest
    (the workbench's own edits are not hand edits; a tree the workbench found hand-edited is
    stamped with ``body=False`` so the edits stay visible); ``calibration``: the digest of
    the calibration record the values come from, None for values that do not (a baseline,
    given factors), :data:`KEEP` to leave it. A file without a header record is left alone."""
    el = aircraft.getroot().find(f"fileheader/{GENERATOR}")
    if el is None:
        return
    if calibration is not KEEP:
        if calibration is None:
            el.attrib.pop("calibration", None)
        else:
            el.set("calibration", calibration)
    if body:
        el.set("version", __version__)
        el.set("body", body_digest(aircraft))


def dropped_lines(old: Tree, new: Tree) -> list[str]:
    """Lines of ``old`` (calibration values left out) that ``new`` does not have, in order."""
    import difflib
    a = canonical_body(old).decode().splitlines()
    b = canonical_body(new).decode().splitlines()
    out = []
    for tag, i1, i2, _, _ in difflib.SequenceMatcher(None, a, b, autojunk=False).get_opcodes():
        if tag in ("delete", "replace"):
            out += [f"line {i + 1}: {a[i].strip()}" for i in range(i1, i2)]
    return out
