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

import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np

from .physics.aero.model import AeroModel, build_aero
from .physics.airfoil import AIRFOIL_DIR, load_airfoil
from .physics.atmosphere import density, isa_pressure, isa_temperature
from .physics.engine import PistonParams, design_piston
from .errors import ModelError
from .factors import FactorSet
from .physics.geometry import AircraftGeometry, load_geometry
from .physics.mass import empty_inertia
from .physics.propeller import PropellerTables, apply_factors, helical_blade, propeller_tables
from .units import FT, IN, KT, LB_PER_GAL_AVGAS, LBM, US_GAL
from . import xmlmodel

J_GRID = np.round(np.concatenate([np.arange(0.0, 1.0, 0.05), np.arange(1.0, 1.61, 0.1)]), 4)
BETA_GRID = np.arange(8.0, 44.1, 4.0)
# breakpoints of the baked JSBSim tables: finer than the BEM grid, so that JSBSim's linear
# interpolation follows the (spline) curve closely and the calibration's cost stays smooth
J_TABLE = np.round(np.arange(0.0, 1.6001, 0.02), 4)
BEM_RPM = 2400.0


@dataclass(frozen=True)
class AircraftPaths:
    root: Path
    name: str

    @property
    def folder(self) -> Path:
        return self.root / "aircraft" / self.name

    @property
    def geometry(self) -> Path:
        return self.folder / "geometry.toml"

    @property
    def aircraft_xml(self) -> Path:
        return self.folder / f"{self.name}.xml"

    @property
    def calibration(self) -> Path:
        return self.folder / "calibration.json"

    @property
    def propeller_bem(self) -> Path:
        return self.folder / "propeller_bem.csv"

    def _referenced(self, which: str) -> str | None:
        """Engine/propeller file named in an existing aircraft file (a derived aircraft such
        as a close-loop result shares its parent's engine files)."""
        if self.aircraft_xml.is_file():
            return xmlmodel.propulsion_files(self.aircraft_xml).get(which)
        return None

    @property
    def engine_file(self) -> str:
        return self._referenced("engine") or f"{self.name}_engine"

    @property
    def propeller_file(self) -> str:
        return self._referenced("thruster") or f"{self.name}_propeller"

    @property
    def engine_xml(self) -> Path:
        return self.root / "engine" / f"{self.engine_file}.xml"

    @property
    def propeller_xml(self) -> Path:
        return self.root / "engine" / f"{self.propeller_file}.xml"

    @property
    def init_xml(self) -> Path:
        return self.folder / "cruise_init.xml"

    @property
    def script(self) -> Path:
        return self.root / "scripts" / f"{self.name}_cruise.xml"


def airfoil_dirs(root: Path) -> list[Path]:
    return [root / "airfoils", AIRFOIL_DIR]


def load_aircraft_geometry(root: Path, name: str) -> AircraftGeometry:
    paths = AircraftPaths(root, name)
    if not paths.geometry.is_file():
        known = sorted(p.parent.name for p in (root / "aircraft").glob("*/geometry.toml"))
        raise ModelError(f"no aircraft '{name}': {paths.geometry} not found (known: {', '.join(known) or 'none'})")
    return load_geometry(paths.geometry, airfoil_dirs(root))


def read_calibration(paths: AircraftPaths) -> FactorSet:
    """Factor values of the calibration record (neutral when there is none)."""
    if not paths.calibration.is_file():
        return FactorSet()
    data = json.loads(paths.calibration.read_text())
    return FactorSet(data.get("factors", {}))


def write_calibration(paths: AircraftPaths, factors: FactorSet, record: dict) -> None:
    """Store the calibrated factors (and what produced them) beside the aircraft."""
    out = {"aircraft": paths.name, "factors": {k: round(v, 10) for k, v in factors.items()}}
    out.update(record)
    paths.calibration.write_text(json.dumps(out, indent=2, sort_keys=False) + "\n")


def blade_for(geom: AircraftGeometry, root: Path):
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


def bem_csv_text(tables: PropellerTables) -> str:
    lines = ["# Neutral BEM propeller tables (jsbsim_calib.propeller), re-baked with calibration factors",
             "# columns: J, beta75_deg (blank for fixed pitch), CT, CP"]
    lines.append("J,beta75_deg,CT,CP")
    if tables.beta75_deg is None:
        for j, ct, cp in zip(tables.J, tables.CT, tables.CP):
            lines.append(f"{j:.4f},,{ct:.8f},{cp:.8f}")
    else:
        for i, j in enumerate(tables.J):
            for k, b in enumerate(tables.beta75_deg):
                lines.append(f"{j:.4f},{b:.3f},{tables.CT[i, k]:.8f},{tables.CP[i, k]:.8f}")
    return "\n".join(lines) + "\n"


def read_bem_csv(path: Path) -> PropellerTables:
    return parse_bem_csv(path.read_text(), str(path))


def parse_bem_csv(text: str, source: str = "propeller_bem.csv") -> PropellerTables:
    rows = [l.split(",") for l in text.splitlines() if l and not l.startswith("#")][1:]
    J = np.array(sorted({float(r[0]) for r in rows}))
    if rows[0][1] == "":
        CT = np.array([float(r[2]) for r in rows])
        CP = np.array([float(r[3]) for r in rows])
        return PropellerTables(J, None, CT, CP, {"source": source})
    B = np.array(sorted({float(r[1]) for r in rows}))
    CT = np.array([float(r[2]) for r in rows]).reshape(len(J), len(B))
    CP = np.array([float(r[3]) for r in rows]).reshape(len(J), len(B))
    return PropellerTables(J, B, CT, CP, {"source": source})


def propeller_tree(geom: AircraftGeometry, base: PropellerTables, factors: FactorSet, paths: AircraftPaths):
    pf = factors.propeller()
    tables = apply_factors(base, pf, J_out=J_TABLE)
    p = geom.propeller
    note = (f"{p.model}: {fmt_len(p.diameter_m)} diameter, {p.blades} blades; blade-element momentum tables "
            f"(Prandtl tip/hub loss, {p.airfoil} sections, {BEM_RPM:g} rpm) from aircraft/{paths.name}/geometry.toml")
    if p.constant_speed:
        return xmlmodel.propeller_xml(paths.propeller_file, tables, diameter_m=p.diameter_m, blades=p.blades,
                                      ixx_kgm2=p.ixx_kgm2, factors=pf, min_pitch=p.min_pitch_deg,
                                      max_pitch=p.max_pitch_deg, min_rpm=p.min_rpm, max_rpm=p.max_rpm, note=note)
    return xmlmodel.propeller_xml(paths.propeller_file, tables, diameter_m=p.diameter_m, blades=p.blades,
                                  ixx_kgm2=p.ixx_kgm2, factors=pf, note=note)


def fmt_len(x_m: float) -> str:
    return f"{x_m / IN:g} in"


def init_xml(geom: AircraftGeometry) -> str:
    return f"""<?xml version="1.0" encoding="UTF-8"?>
<initialize name="cruise_init">
  <!-- Cruise start for scripts/{geom.name}_cruise.xml (generated by jsbsim-calib) -->
  <ubody unit="KTS"> 110.0 </ubody>
  <vbody unit="KTS"> 0.0 </vbody>
  <wbody unit="KTS"> 0.0 </wbody>
  <latitude unit="DEG"> 40.0 </latitude>
  <longitude unit="DEG"> -88.0 </longitude>
  <phi unit="DEG"> 0.0 </phi>
  <theta unit="DEG"> 0.0 </theta>
  <psi unit="DEG"> 90.0 </psi>
  <altitude unit="FT"> 5500.0 </altitude>
  <running> 0 </running>
</initialize>
"""


CRUISE_SCRIPT_RPM_BELOW_MAX = 200.0     # [rpm] governor setting of the cruise script: maximum less this
CRUISE_SCRIPT_POWER = 0.65               # [-] share of rated power the script's starting blade angle absorbs


def script_start_blade_deg(geom: AircraftGeometry, bem: PropellerTables, rpm: float) -> float:
    """Blade angle that absorbs about 65 % of rated power at the script's cruise (5500 ft, 110 KTAS)
    and ``rpm``: the start of the runner's trim, so the governor has little left to do."""
    h = 5500 * FT
    rho = float(density(isa_pressure(h), isa_temperature(h)))
    n = rpm / 60.0
    D = geom.propeller.diameter_m
    J = 110 * KT / (n * D)
    cp_needed = CRUISE_SCRIPT_POWER * geom.engine.max_power_w / (rho * n**3 * D**5)
    cp = np.array([np.interp(J, bem.J, bem.CP[:, k]) for k in range(len(bem.beta75_deg))])
    beta = float(np.interp(cp_needed, cp, bem.beta75_deg)) if np.all(np.diff(cp) > 0) else geom.propeller.min_pitch_deg
    return round(min(max(beta, geom.propeller.min_pitch_deg), geom.propeller.max_pitch_deg), 1)


def script_xml(geom: AircraftGeometry, bem: PropellerTables) -> str:
    cs = geom.propeller
    governor_start = governor_on = governor_note = ""
    if cs.constant_speed:
        rpm = max(cs.min_rpm, cs.max_rpm - CRUISE_SCRIPT_RPM_BELOW_MAX)
        advance = (rpm - cs.min_rpm) / max(1.0, cs.max_rpm - cs.min_rpm)
        governor_note = f"""
       Constant-speed propeller: JSBSim's governor cannot bring the engine up from the
       start (it drives the blade to the coarse stop), so the trim runs with the blade held at
       {script_start_blade_deg(geom, bem, rpm):g} deg and the governor, set to {rpm:g} rpm, takes over after it."""
        governor_start = f"""
      <set name="propulsion/engine/constant-speed-mode" value="0"/>
      <set name="propulsion/engine/blade-angle" value="{script_start_blade_deg(geom, bem, rpm):g}"/>
      <set name="fcs/advance-cmd-norm" value="{advance:.6g}"/>"""
        governor_on = """
    <event name="governor on">
      <condition> simulation/sim-time-sec ge 0.1 </condition>
      <set name="propulsion/engine/constant-speed-mode" value="1"/>
    </event>"""
    return f"""<?xml version="1.0" encoding="UTF-8"?>
<runscript name="{geom.name} cruise">
  <!-- Generated by jsbsim-calib. Trims {geom.title} in level cruise at 5500 ft and
       110 kt and flies 60 s hands off. Run from the repository root with JSBSim's runner,
       option root set to the repository: jsbsim (root .) scripts/{geom.name}_cruise.xml{governor_note} -->
  <use aircraft="{geom.name}" initialize="cruise_init"/>
  <run start="0.0" end="60.0" dt="0.0166666667">
    <property value="0"> simulation/notify-time-trigger </property>
    <event name="engine start and trim">
      <condition> simulation/sim-time-sec ge 0.0 </condition>
      <set name="fcs/mixture-cmd-norm" value="0.87"/>
      <set name="fcs/throttle-cmd-norm" value="0.75"/>{governor_start}
      <set name="propulsion/set-running" value="-1"/>
      <set name="simulation/do_simple_trim" value="1"/>
      <notify>
        <property caption="trimmed alpha [deg]"> aero/alpha-deg </property>
        <property caption="throttle"> fcs/throttle-cmd-norm </property>
        <property caption="engine rpm"> propulsion/engine/engine-rpm </property>
      </notify>
    </event>{governor_on}
    <event name="report" persistent="true">
      <condition> simulation/sim-time-sec ge simulation/notify-time-trigger </condition>
      <set name="simulation/notify-time-trigger" value="10" type="FG_DELTA"/>
      <notify>
        <property caption="altitude [ft]"> position/h-sl-ft </property>
        <property caption="true airspeed [kt]"> velocities/vtrue-kts </property>
        <property caption="pitch [deg]"> attitude/theta-deg </property>
        <property caption="vertical speed [ft/s]"> velocities/h-dot-fps </property>
      </notify>
    </event>
  </run>
</runscript>
"""


@dataclass
class Generated:
    paths: AircraftPaths
    geometry: AircraftGeometry
    aero: AeroModel
    piston: PistonParams
    bem: PropellerTables
    factors: FactorSet
    files: dict[str, bytes]


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
    files: dict[str, bytes] = {}

    def xml_bytes(tree) -> bytes:
        from lxml import etree
        etree.indent(tree, space="  ")
        return etree.tostring(tree, pretty_print=True, xml_declaration=True, encoding="UTF-8")

    files[str(paths.aircraft_xml)] = xml_bytes(xmlmodel.aircraft_xml(
        geom, aero, engine_file=paths.engine_file, propeller_file=paths.propeller_file, piston=piston,
        factors=factors, inertia_empty=empty_inertia(geom), travel_comment=travel))
    e = geom.engine
    files[str(paths.engine_xml)] = xml_bytes(xmlmodel.engine_xml(
        piston, f"{e.model}: {e.max_power_w / 745.69987:g} hp at {e.rated_rpm:g} rpm (from aircraft/{name}/geometry.toml)"))
    files[str(paths.propeller_xml)] = xml_bytes(propeller_tree(geom, bem, factors, paths))
    files[str(paths.propeller_bem)] = bem_csv_text(bem).encode()
    files[str(paths.init_xml)] = init_xml(geom).encode()
    files[str(paths.script)] = script_xml(geom, bem).encode()
    return Generated(paths, geom, aero, piston, bem, factors, files)


def generate(name: str, root: Path = Path("."), *, baseline: bool = False, factors: FactorSet | None = None,
             progress: Callable[[str], None] | None = None) -> Generated:
    """Build and write all files of an aircraft. Returns what was generated."""
    g = build(name, root, factors=factors, baseline=baseline, progress=progress)
    for path, data in g.files.items():
        p = Path(path)
        p.parent.mkdir(parents=True, exist_ok=True)
        if not p.exists() or p.read_bytes() != data:
            p.write_bytes(data)
    return g
