"""JSBSim engine and propeller files: the FGPiston design and the propeller tables with the
propeller factors baked in (JSBSim reads its tables at load time); the baked values are
recorded in the propeller file, where :func:`read_baked_factors` finds them."""
from __future__ import annotations

import math
from pathlib import Path
from typing import Mapping

import numpy as np

from ..core.errors import AircraftFileError, Problem
from ..factors import FactorSet, propeller_factor_values
from ..physics.engine import MIXTURE_FAR, PistonParams, mixture_efficiency
from ..physics.geometry import AircraftGeometry, PropellerSpec
from ..physics.propeller import PropellerTables, apply_factors
from ..core.units import FT, IN, SLUG
from .xml import FACTOR_DIGITS, Tree, comment, comments, data_table, decimals_for, element, fmt, fmt_fixed, read, sub, tree

# breakpoints of the baked JSBSim tables: finer than the BEM grid, so that JSBSim's linear
# interpolation follows the (spline) curve closely and the calibration's cost stays smooth
J_TABLE = np.round(np.arange(0.0, 1.6001, 0.02), 4)
BEM_RPM = 2400.0              # [rpm] the BEM tables are computed at this speed
BAKED_NOTE = "calibration (baked):"


def engine_xml(p: PistonParams, spec_note: str) -> Tree:
    root = element("piston_engine", name=p.name)
    root.text = "\n"
    comment(root, spec_note)
    comment(root, "FGPiston parameters designed by jsbsim_calib.engine.design_piston: rated power at rated RPM, "
                  "sea level, best-power mixture; friction so that full-throttle power follows Gagg-Farrar. "
                  "The aircraft's 'calibration' system overrides volumetric-efficiency and bsfc each frame.")
    parameters = (
        ("minmp", fmt(p.min_map_inhg), "INHG"), ("maxmp", fmt(p.max_map_inhg), "INHG"),
        ("displacement", fmt(p.displacement_in3), "IN3"), ("bore", fmt(p.bore_in), "IN"),
        ("stroke", fmt(p.stroke_in), "IN"), ("cylinders", str(p.cylinders), None),
        ("compression-ratio", fmt(p.compression_ratio), None), ("maxhp", fmt(p.max_hp), "HP"),
        ("cycles", str(p.cycles), None), ("idlerpm", fmt(p.idle_rpm), None), ("maxrpm", fmt(p.max_rpm), None),
        ("sparkfaildrop", "0.1", None), ("volumetric-efficiency", fmt(p.volumetric_efficiency), None),
        ("bsfc", fmt(p.isfc_lb_hphr), "LBS/HP*HR"), ("static-fmep", fmt(p.fmep_static_pa), "PA"),
        ("dynamic-fmep", fmt(p.fmep_dynamic_pa_per_mps), "PA"), ("static-friction", fmt(p.static_friction_hp), "HP"),
        ("peak-piston-speed", fmt(p.peak_piston_speed_fps), None), ("ram-air-factor", fmt(p.ram_air_factor), None),
        ("man-press-lag", fmt(p.man_press_lag_s), None), ("starter-torque", fmt(0.4 * p.max_hp), None),
        ("starter-rpm", fmt(2 * p.idle_rpm), None),
    )
    for tag, text, unit in parameters:
        sub(root, tag, text, **({"unit": unit} if unit else {}))
    comment(root, "Mixture efficiency ME(fuel/air) = P(f) f_bp / f, P = brake power at constant air flow relative "
                  "to best power (classical spark-ignition mixture curve, jsbsim_calib.engine)")
    t = sub(root, "table", name="MIXTURE", type="internal")
    data_table(t, [f"      {fmt(f, 4):>7} {fmt(float(mixture_efficiency(f)), 5):>8}" for f in MIXTURE_FAR], "    ")
    return tree(root)


def propeller_xml(name: str, tables: PropellerTables, spec: PropellerSpec, factors: Mapping[str, float],
                  note: str = "") -> Tree:
    """A propeller file: its tables (1-D in J for a fixed pitch, J x blade angle for a
    constant-speed propeller, with its pitch and governor limits) and the baked factors
    (``K_Ip`` scales the rotating inertia ``<ixx>`` of the geometry's propeller)."""
    root = element("propeller", name=name)
    root.text = "\n"
    comment(root, note)
    comment(root, f"{BAKED_NOTE} " + ", ".join(f"{k}={fmt(v, FACTOR_DIGITS)}" for k, v in factors.items()))
    sub(root, "ixx", fmt(spec.ixx_kgm2 / (SLUG * FT**2) * factors.get("K_Ip", 1.0)), unit="SLUG*FT2")
    sub(root, "diameter", fmt(spec.diameter_m / IN), unit="IN")
    sub(root, "numblades", str(spec.blades))
    sub(root, "gearratio", "1")
    if tables.beta75_deg is not None:
        for tag, v in (("minpitch", spec.min_pitch_deg), ("maxpitch", spec.max_pitch_deg),
                       ("minrpm", spec.min_rpm), ("maxrpm", spec.max_rpm)):
            sub(root, tag, fmt(v))
    for tname, data in (("C_THRUST", tables.CT), ("C_POWER", tables.CP)):
        t = sub(root, "table", name=tname, type="internal")
        d = decimals_for(data)
        if tables.beta75_deg is None:
            rows = [f"{fmt(j, 5):>8} {fmt_fixed(v, d):>12}" for j, v in zip(tables.J, data)]
        else:
            rows = ["         " + " ".join(f"{fmt(b, 5):>10}" for b in tables.beta75_deg)]
            rows += [f"{fmt(j, 5):>8} " + " ".join(f"{fmt_fixed(v, d):>10}" for v in row)
                     for j, row in zip(tables.J, data)]
        data_table(t, rows, "    ")
    return tree(root)


def propeller_tree(geom: AircraftGeometry, base: PropellerTables, factors: FactorSet, *, aircraft: str,
                   file_name: str) -> Tree:
    """The propeller file of ``aircraft``: the neutral BEM tables ``base`` with the propeller
    factors of ``factors`` baked in, on the :data:`J_TABLE` breakpoints."""
    pf = factors.propeller()
    tables = apply_factors(base, propeller_factor_values(pf), J_out=J_TABLE)
    p = geom.propeller
    note = (f"{p.model}: {p.diameter_m / IN:g} in diameter, {p.blades} blades; blade-element momentum tables "
            f"(Prandtl tip/hub loss, {p.airfoil} sections, {BEM_RPM:g} rpm) from aircraft/{aircraft}/geometry.toml")
    return propeller_xml(file_name, tables, p, pf, note)


def read_baked_factors(propeller_xml_path: Path) -> dict[str, float]:
    """Propeller factors recorded in a propeller file's 'calibration (baked)' comment;
    :class:`AircraftFileError` naming the file and line when a value is not a finite number."""
    for c in comments(read(propeller_xml_path).getroot()):
        text = (c.text or "").strip()
        if text.startswith(BAKED_NOTE):
            out, problems = {}, []
            for part in text.split(":", 1)[1].split(","):
                k, _, v = part.partition("=")
                if not _:
                    continue
                try:
                    out[k.strip()] = float(v)
                except ValueError:
                    out[k.strip()] = math.nan
                if not math.isfinite(out[k.strip()]):
                    problems.append(Problem(f"line {c.sourceline}, {BAKED_NOTE} {k.strip()}",
                                            f"{v.strip()!r} is not a finite number"))
            if problems:
                raise AircraftFileError(propeller_xml_path, problems)
            return out
    return {}
