"""Generate an aircraft: geometry -> aerodynamics, propeller, engine -> JSBSim files.

``generate(name)`` runs the chain for ``aircraft/<name>/geometry.toml`` in a JSBSim root
and writes ``aircraft/<name>/<name>.xml``, ``engine/<name>_engine.xml``,
``engine/<name>_propeller.xml``, the neutral BEM tables beside the aircraft
(``aircraft/<name>/propeller_bem.csv``, so calibration can re-bake the propeller without
rerunning BEM), an initial-conditions file and a cruise script. Factor values come from
``aircraft/<name>/calibration.json`` when it exists (the calibrated product) and are
neutral otherwise or with ``baseline=True``. Everything is computed and checked before
the first file is written; the files are replaced as one unit (a journal, backups of the
replaced files: :func:`jsbsim_calib.jsbsim.product.commit_product`); a rerun writes identical
bytes.

The aircraft file's header records the tool version, a digest of the input files (geometry,
airfoil polars, control-travel table) and one of its own body without the calibration
values. An aircraft whose body no longer matches its digest was edited by hand: ``generate``
refuses to overwrite it (listing the lines it would drop) unless ``force=True``.
"""
from __future__ import annotations

import hashlib
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np

from .core.errors import ModelError
from .factors import FactorSet
from .jsbsim.aircraft import aircraft_xml, calibration_digest, declared_factors, dropped_lines, hand_edited
from .jsbsim.product import (AircraftPaths, Propeller, aircraft_bytes, airfoil_dirs, bem_csv_text, commit_product,
                             hand_set_factors, load_aircraft_geometry, parse_bem_csv, propeller_bytes,
                             read_calibration, recover_product, warn_hand_set)
from .jsbsim.propulsion import BEM_RPM, engine_xml
from .jsbsim.templates import init_xml, script_xml
from .jsbsim.xml import Tree, copy, parse, read, tostring, tree
from .physics.aero.model import AeroModel, build_aero
from .physics.airfoil import airfoil_path, load_airfoil
from .physics.engine import PistonParams, design_piston
from .physics.geometry import AircraftGeometry
from .physics.mass import empty_inertia
from .physics.propeller import Blade, PropellerTables, bem_point, helical_blade, propeller_tables
from .physics.slipstream import torque_shape

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


SWIRL_J = 0.5                 # the climb: the advance ratio the swirl's radial shape is taken at
SWIRL_ALPHA_DEG = 4.5         # a constant-speed blade's angle of attack at 0.75 R there (the governor's climb pitch)


def swirl_torque_shape(geom: AircraftGeometry, root: Path):
    """The propeller's torque shape in the climb (blade-element solution at J = 0.5; a
    constant-speed blade at the helix angle + 4.5 deg): what the swirl at the fin follows."""
    blade = blade_for(geom, root)
    if geom.propeller.constant_speed:
        blade = blade.with_beta75(math.degrees(math.atan(SWIRL_J / (0.75 * math.pi))) + SWIRL_ALPHA_DEG)
    n = BEM_RPM / 60.0
    pt = bem_point(blade, V_ms=SWIRL_J * n * geom.propeller.diameter_m, rpm=BEM_RPM)
    return torque_shape(pt.r_over_R, pt.dQ_dr, 0.5 * geom.propeller.diameter_m)


def propeller_base_tables(geom: AircraftGeometry, root: Path) -> PropellerTables:
    blade = blade_for(geom, root)
    beta = BETA_GRID if geom.propeller.constant_speed else None
    return propeller_tables(blade, J_GRID, rpm=BEM_RPM, beta75_deg=beta)


def input_files(geom: AircraftGeometry, root: Path) -> list[Path]:
    """The files an aircraft is generated from: its geometry, the airfoil polars it names, its
    control-travel table."""
    names = sorted({s.airfoil for s in geom.surfaces} | {geom.propeller.airfoil})
    files = [geom.path] + [airfoil_path(n, airfoil_dirs(root)) for n in names]
    return files + ([geom.control_travel_file] if geom.control_travel_file else [])


def inputs_digest(files) -> str:
    """A digest of files by name and content (the same on any machine and checkout path)."""
    h = hashlib.sha256()
    for f in files:
        h.update(Path(f).name.encode() + b"\0" + hashlib.sha256(Path(f).read_bytes()).digest())
    return "sha256:" + h.hexdigest()


@dataclass
class Generated:
    """What the chain computed for one aircraft, and its files (path -> bytes, in the order:
    aircraft, engine, propeller, BEM tables, initial conditions, script). ``calibration``: the
    digest of the calibration record the factor values came from (None: neutral or given
    values); after ``generate``: ``dropped``, the hand-edited lines it dropped (``force``),
    and ``backup``, the folder of the replaced files."""

    paths: AircraftPaths
    geometry: AircraftGeometry
    aero: AeroModel
    piston: PistonParams
    bem: PropellerTables
    factors: FactorSet
    aircraft: Tree
    files: dict[str, bytes] = field(default_factory=dict)
    calibration: str | None = None
    dropped: list[str] = field(default_factory=list)
    backup: Path | None = None


def build(name: str, root: Path = Path("."), *, factors: FactorSet | None = None, baseline: bool = False,
          progress: Callable[[str], None] | None = None) -> Generated:
    """Compute every file of an aircraft (nothing is written)."""
    root = Path(root)
    paths = AircraftPaths(root, name)
    recover_product(paths)
    say = progress or (lambda s: None)
    say(f"reading {paths.geometry}")
    geom = load_aircraft_geometry(root, name)
    airfoils = {n: load_airfoil(n, airfoil_dirs(root)) for n in {s.airfoil for s in geom.surfaces}}
    calibration = None
    if factors is None:
        factors = FactorSet() if baseline else read_calibration(paths)
        if not baseline and paths.calibration.is_file():
            calibration = calibration_digest(factors)
    aero = build_aero(geom, airfoils, progress=lambda s: say(f"aerodynamics: {s}"),
                      torque_shape=swirl_torque_shape(geom, root))
    say("propeller: blade-element momentum")
    # the tables are baked from their stored (rounded) form, as calibration re-bakes them
    bem = parse_bem_csv(bem_csv_text(propeller_base_tables(geom, root)))
    say("engine: FGPiston design")
    piston = design_piston(geom.engine, paths.engine_file)
    travel = f"Control travel from {geom.control_travel_file.name}." if geom.control_travel_file else ""
    aircraft = aircraft_xml(geom, aero, engine_file=paths.engine_file, propeller_file=paths.propeller_file,
                            piston=piston, factors=factors, inertia_empty=empty_inertia(geom), travel_comment=travel,
                            inputs_sha256=inputs_digest(input_files(geom, root)))
    e = geom.engine
    files = {
        str(paths.aircraft_xml): aircraft_bytes(copy(aircraft), factors, stamp_body=True, calibration=calibration),
        str(paths.engine_xml): tostring(engine_xml(
            piston, f"{e.model}: {e.max_power_w / 745.69987:g} hp at {e.rated_rpm:g} rpm (from aircraft/{name}/geometry.toml)")),
        str(paths.propeller_xml): propeller_bytes(paths.propeller_file, Propeller(geom, bem, name), factors),
        str(paths.propeller_bem): bem_csv_text(bem).encode(),
        str(paths.init_xml): init_xml(geom).encode(),
        str(paths.script): script_xml(geom, bem).encode(),
    }
    return Generated(paths, geom, aero, piston, bem, factors, aircraft, files, calibration)


MAX_LISTED_LINES = 40


def _hand_edits(g: Generated, force: bool) -> list[str]:
    """The lines of a hand-edited aircraft file that the new one drops; refused (ModelError,
    listing them) without ``force``. Factor values set by hand are named in warnings."""
    if not g.paths.aircraft_xml.is_file():
        return []
    try:
        old = read(g.paths.aircraft_xml)
    except ModelError:
        return []                                  # unreadable: nothing to keep (it is backed up)
    if g.calibration is not None:
        try:
            warn_hand_set(g.paths, hand_set_factors(declared_factors(old, g.paths.aircraft_xml), g.factors),
                          "generate (from calibration.json)")
        except ModelError:
            pass                                   # bad values by hand: the new file replaces them
    if not hand_edited(old):
        return []
    new = tree(parse(g.files[str(g.paths.aircraft_xml)].decode(), str(g.paths.aircraft_xml)))
    dropped = dropped_lines(old, new)
    if force:
        return dropped
    shown = dropped[:MAX_LISTED_LINES]
    more = [f"... and {len(dropped) - len(shown)} more lines"] if len(dropped) > len(shown) else []
    what = ("it would drop these lines:\n" + "\n".join("  " + d for d in shown + more)) if dropped else \
        "it drops no line, but restores what the edit removed"
    raise ModelError(f"{g.paths.aircraft_xml} was edited by hand since the workbench wrote it (its body differs from "
                     f"the digest in its header); 'generate' rewrites it from {g.paths.geometry.name}: {what}\n"
                     f"Move the additions into an effect or the geometry file, or run 'jsbsim-calib generate "
                     f"{g.paths.name} --force' (the old file goes to {g.paths.backups}/)")


def generate(name: str, root: Path = Path("."), *, baseline: bool = False, factors: FactorSet | None = None,
             progress: Callable[[str], None] | None = None, force: bool = False) -> Generated:
    """Build and write all files of an aircraft as one unit. Returns what was generated,
    ``files`` with every file (aircraft, engine, propeller, BEM tables, initial conditions,
    script). An aircraft file edited by hand is refused (ModelError listing the lines it
    would drop) unless ``force``; then ``dropped`` lists them."""
    g = build(name, root, factors=factors, baseline=baseline, progress=progress)
    g.dropped = _hand_edits(g, force)
    g.backup = commit_product(g.paths, {Path(p): d for p, d in g.files.items()}).backup
    return g
