"""The product: an aircraft's files in a JSBSim root, and writing them.

``aircraft/<name>/geometry.toml`` (the source), ``aircraft/<name>/<name>.xml`` (the aircraft
with its calibration factors declared), ``aircraft/<name>/calibration.json`` (factor values and
the fit record), ``aircraft/<name>/propeller_bem.csv`` (the neutral BEM tables), and
``engine/<name>_engine.xml`` / ``engine/<name>_propeller.xml`` (the propeller with its factors
baked in).

:func:`write_aircraft` is the one place that writes an aircraft with its factors: the factor
(and effect) values into the aircraft file and the propeller factors into the propeller
tables, each file written atomically. The product, the calibration sandbox, a calibrated
aircraft and a close-loop aircraft are all written through it.
"""
from __future__ import annotations

import json
import shutil
from dataclasses import dataclass
from pathlib import Path
from typing import Mapping

import numpy as np

from .. import __version__
from ..errors import ModelError
from ..factors import FactorSet
from ..physics.airfoil import AIRFOIL_DIR
from ..physics.geometry import AircraftGeometry, load_geometry
from ..physics.propeller import PropellerTables, apply_factors
from .aircraft import propulsion_files, set_effect_values, set_factor_values
from .propulsion import propeller_tree
from .xml import Tree, read, write, write_bytes

CALIBRATION_DIGITS = 10          # decimals of the factor values in calibration.json (and the aircraft file)


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
            return propulsion_files(self.aircraft_xml).get(which)
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


# --------------------------------------------------------------------------- calibration record
def read_calibration(paths: AircraftPaths) -> FactorSet:
    """Factor values of the calibration record (neutral when there is none)."""
    if not paths.calibration.is_file():
        return FactorSet()
    data = json.loads(paths.calibration.read_text())
    return FactorSet(data.get("factors", {}))


def rounded(factors: FactorSet) -> FactorSet:
    """The values the record stores (:data:`CALIBRATION_DIGITS` decimals): an aircraft written
    with them is what ``generate`` writes again from the record."""
    return FactorSet({k: round(v, CALIBRATION_DIGITS) for k, v in factors.items()})


def write_calibration_record(paths: AircraftPaths, factors: FactorSet, stage: str, record: dict) -> Path:
    """Store the factors and the record of the stage that produced them beside the aircraft.
    A stage-1 record starts a new history (the flight-test stage builds on it)."""
    rec = json.loads(paths.calibration.read_text()) if paths.calibration.is_file() else {}
    rec["aircraft"] = paths.name
    rec["jsbsim_calib"] = __version__
    rec["factors"] = {k: round(v, CALIBRATION_DIGITS) for k, v in factors.items()}
    if stage == "steady":
        rec["stages"] = {}
    rec.setdefault("stages", {})[stage] = record
    write_bytes(paths.calibration, (json.dumps(rec, indent=2) + "\n").encode())
    return paths.calibration


# --------------------------------------------------------------------------- BEM tables
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
    rows = [line.split(",") for line in text.splitlines() if line and not line.startswith("#")][1:]
    J = np.array(sorted({float(r[0]) for r in rows}))
    if rows[0][1] == "":
        CT = np.array([float(r[2]) for r in rows])
        CP = np.array([float(r[3]) for r in rows])
        return PropellerTables(J, None, CT, CP, {"source": source})
    B = np.array(sorted({float(r[1]) for r in rows}))
    CT = np.array([float(r[2]) for r in rows]).reshape(len(J), len(B))
    CP = np.array([float(r[3]) for r in rows]).reshape(len(J), len(B))
    return PropellerTables(J, B, CT, CP, {"source": source})


def propeller_tables(paths: AircraftPaths, factors: FactorSet) -> PropellerTables:
    """The aircraft's propeller tables with the propeller factors of ``factors`` (BEM breakpoints)."""
    return apply_factors(read_bem_csv(paths.propeller_bem), factors.propeller())


# --------------------------------------------------------------------------- writing an aircraft
@dataclass(frozen=True)
class Propeller:
    """What the propeller file is baked from: the aircraft's geometry and neutral BEM tables,
    and the name of the aircraft whose geometry file the file cites."""

    geometry: AircraftGeometry
    bem: PropellerTables
    aircraft: str


def write_aircraft(paths: AircraftPaths, factors: FactorSet, *, aircraft: Tree | None = None,
                   propeller: Propeller | None = None, effect_values: Mapping[str, float] | None = None) -> list[Path]:
    """Write an aircraft with its factors; returns the files written.

    ``aircraft``: the parsed aircraft file; the values of ``factors`` (and ``effect_values``, by
    property) are declared in it and it is written to ``paths.aircraft_xml``. ``propeller``: the
    propeller tables are baked with the propeller factors of ``factors`` and written to
    ``paths.propeller_xml``. Either may be left out (a derived aircraft flies on its parent's
    propeller file; the sandbox re-bakes its propeller alone when only propeller factors
    change). Each file is written atomically."""
    out = []
    if aircraft is not None:
        set_factor_values(aircraft, factors)
        if effect_values:
            set_effect_values(aircraft, effect_values)
        write(aircraft, paths.aircraft_xml)
        out.append(paths.aircraft_xml)
    if propeller is not None:
        write(propeller_tree(propeller.geometry, propeller.bem, factors, aircraft=propeller.aircraft,
                             file_name=paths.propeller_file), paths.propeller_xml)
        out.append(paths.propeller_xml)
    return out


def write_calibrated(root: Path | str, name: str, factors: FactorSet, stage: str, record: dict) -> list[Path]:
    """Write calibrated factors into an aircraft of ``root`` (aircraft file, baked propeller,
    calibration record). Returns the files written. A steady-stage result starts a new
    record (the flight-test stage builds on it and must be rerun)."""
    paths = AircraftPaths(Path(root), name)
    factors = rounded(factors)
    propeller = Propeller(load_aircraft_geometry(paths.root, name), read_bem_csv(paths.propeller_bem), name)
    files = write_aircraft(paths, factors, aircraft=read(paths.aircraft_xml), propeller=propeller)
    return files + [write_calibration_record(paths, factors, stage, record)]


def write_derived(source: AircraftPaths, aircraft: Tree, factors: FactorSet, destination: AircraftPaths) -> Path:
    """Write ``aircraft`` (a variant of ``source``, e.g. with effects added) as ``destination``:
    the source's folder copied (its geometry and BEM tables; not its XML or calibration
    record), the aircraft file written with ``factors``. It flies on the source's engine and
    propeller files, which its XML names."""
    if destination.folder.resolve() != source.folder.resolve():
        destination.folder.mkdir(parents=True, exist_ok=True)
        for f in source.folder.iterdir():
            if f.is_file() and f.suffix != ".xml" and f.name != "calibration.json":
                shutil.copy(f, destination.folder / f.name)
    write_aircraft(destination, factors, aircraft=aircraft,
                   effect_values={f.property: factors[n] for n, f in factors.extra.items()})
    return destination.aircraft_xml
