"""Generate an aircraft: geometry -> aerodynamics, propeller, engine -> JSBSim files.

``generate(name)`` runs the chain for ``aircraft/<name>/geometry.toml`` in a JSBSim root
and writes ``aircraft/<name>/<name>.xml``, ``engine/<name>_engine.xml``,
``engine/<name>_propeller.xml``, the neutral BEM tables beside the aircraft
(``aircraft/<name>/propeller_bem.csv``, so calibration can re-bake the propeller without
rerunning BEM), an initial-conditions file and a cruise script. Factor values come from
``aircraft/<name>/calibration.json`` when it exists (the calibrated product) and are
neutral otherwise or with ``baseline=True``. Everything is computed and checked before
the first file is written; a rerun writes identical bytes.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np

from .factors import FactorSet
from .jsbsim.aircraft import aircraft_xml
from .jsbsim.product import (AircraftPaths, Propeller, airfoil_dirs, bem_csv_text, load_aircraft_geometry,
                             parse_bem_csv, read_calibration, write_aircraft)
from .jsbsim.propulsion import BEM_RPM, engine_xml
from .jsbsim.templates import init_xml, script_xml
from .jsbsim.xml import Tree, tostring, write_bytes
from .physics.aero.model import AeroModel, build_aero
from .physics.airfoil import load_airfoil
from .physics.engine import PistonParams, design_piston
from .physics.geometry import AircraftGeometry
from .physics.mass import empty_inertia
from .physics.propeller import Blade, PropellerTables, helical_blade, propeller_tables

J_GRID = np.round(np.concatenate([np.arange(0.0, 1.0, 0.05), np.arange(1.0, 1.61, 0.1)]), 4)
BETA_GRID = np.arange(8.0, 44.1, 4.0)


def blade_for(geom: AircraftGeometry, root: Path) -> Blade:
    """The propeller blade of the geometry file, with its stored section polar."""
    p = geom.propeller
    section = load_airfoil(p.airfoil, airfoil_dirs(root))
    R = 0.5 * p.diameter_m
    cmax, ctip = p.chord_max_m / R, p.chord_tip_m / R
    # blade planform shape (fraction of max chord): fuller in the middle, rounded tip [EST]
    chord_table = np.array([[p.hub_radius_m / R, 0.65 * cmax], [0.35, 0.9 * cmax], [0.6, cmax], [0.85, 0.85 * cmax],
                            [0.95, 0.7 * cmax], [1.0, ctip]])
    chord_table = chord_table[np.argsort(chord_table[:, 0])]
    pitch = p.pitch_m if p.pitch_m is not None else 2 * math.pi * 0.75 * R * math.tan(math.radians(p.reference_pitch_deg))
    return helical_blade(p.diameter_m, p.blades, pitch, hub_radius_m=p.hub_radius_m, chord_over_R=chord_table,
                         section=section)


def propeller_base_tables(geom: AircraftGeometry, root: Path) -> PropellerTables:
    blade = blade_for(geom, root)
    beta = BETA_GRID if geom.propeller.constant_speed else None
    return propeller_tables(blade, J_GRID, rpm=BEM_RPM, beta75_deg=beta)


@dataclass
class Generated:
    """What the chain computed for one aircraft, and its files (path -> bytes; the aircraft
    and propeller files are written by :func:`jsbsim_calib.jsbsim.product.write_aircraft`)."""

    paths: AircraftPaths
    geometry: AircraftGeometry
    aero: AeroModel
    piston: PistonParams
    bem: PropellerTables
    factors: FactorSet
    aircraft: Tree
    files: dict[str, bytes] = field(default_factory=dict)


def build(name: str, root: Path = Path("."), *, factors: FactorSet | None = None, baseline: bool = False,
          progress: Callable[[str], None] | None = None) -> Generated:
    """Compute every file of an aircraft (nothing is written)."""
    root = Path(root)
    paths = AircraftPaths(root, name)
    say = progress or (lambda s: None)
    say(f"reading {paths.geometry}")
    geom = load_aircraft_geometry(root, name)
    airfoils = {n: load_airfoil(n, airfoil_dirs(root)) for n in {s.airfoil for s in geom.surfaces}}
    if factors is None:
        factors = FactorSet() if baseline else read_calibration(paths)
    aero = build_aero(geom, airfoils, progress=lambda s: say(f"aerodynamics: {s}"))
    say("propeller: blade-element momentum")
    # the tables are baked from their stored (rounded) form, as calibration re-bakes them
    bem = parse_bem_csv(bem_csv_text(propeller_base_tables(geom, root)))
    say("engine: FGPiston design")
    piston = design_piston(geom.engine, paths.engine_file)
    travel = f"Control travel from {geom.control_travel_file.name}." if geom.control_travel_file else ""
    aircraft = aircraft_xml(geom, aero, engine_file=paths.engine_file, propeller_file=paths.propeller_file,
                            piston=piston, factors=factors, inertia_empty=empty_inertia(geom), travel_comment=travel)
    e = geom.engine
    files = {
        str(paths.engine_xml): tostring(engine_xml(
            piston, f"{e.model}: {e.max_power_w / 745.69987:g} hp at {e.rated_rpm:g} rpm (from aircraft/{name}/geometry.toml)")),
        str(paths.propeller_bem): bem_csv_text(bem).encode(),
        str(paths.init_xml): init_xml(geom).encode(),
        str(paths.script): script_xml(geom, bem).encode(),
    }
    return Generated(paths, geom, aero, piston, bem, factors, aircraft, files)


def generate(name: str, root: Path = Path("."), *, baseline: bool = False, factors: FactorSet | None = None,
             progress: Callable[[str], None] | None = None) -> Generated:
    """Build and write all files of an aircraft. Returns what was generated, ``files`` with
    every file (aircraft, engine, propeller, BEM tables, initial conditions, script)."""
    g = build(name, root, factors=factors, baseline=baseline, progress=progress)
    aircraft_file, propeller_file = write_aircraft(g.paths, g.factors, aircraft=g.aircraft,
                                                   propeller=Propeller(g.geometry, g.bem, name))
    for path, data in g.files.items():
        write_bytes(Path(path), data)
    engine_file, *others = g.files
    g.files = {str(aircraft_file): aircraft_file.read_bytes(), engine_file: g.files[engine_file],
               str(propeller_file): propeller_file.read_bytes(), **{k: g.files[k] for k in others}}
    return g
