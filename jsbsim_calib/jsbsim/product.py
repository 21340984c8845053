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

The product's files change together: :func:`write_calibrated` (and ``generate``) replace
them as one unit through :mod:`jsbsim_calib.core.commit` (temporary files, a journal, renames; the
replaced files backed up to ``aircraft/<name>/backup/``, the last :data:`BACKUPS_KEPT`), and
every reader calls :func:`recover_product` first, so a killed write leaves the old set or
the new one. :func:`check_consistent` refuses a set whose aircraft file was written from
other calibration values than ``calibration.json`` holds (files of different commits).
A calibrated aircraft is written without re-indenting it: hand-added comments, functions and
formatting stay; only the factor values change.
"""
from __future__ import annotations

import json
import shutil
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Mapping

import numpy as np

from .. import __version__
from ..core.commit import commit, recover
from ..core.errors import AircraftFileError, ModelError, Problem
from ..factors import REGISTRY, FactorError, FactorSet, propeller_factor_values
from ..physics.airfoil import AIRFOIL_DIR
from ..physics.geometry import AircraftGeometry, load_geometry
from ..physics.propeller import PropellerTables, apply_factors
from .aircraft import (KEEP, calibration_digest, declared_factors, generator_record, hand_edited, propulsion_files,
                       set_effect_values, set_factor_values, stamp)
from .propulsion import propeller_tree
from .xml import FACTOR_DIGITS, Tree, fmt, indent, read, tostring, write_bytes

BACKUPS_KEPT = 3                 # backups of replaced product files kept in aircraft/<name>/backup/
JOURNAL = ".commit-journal.json"

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

    @property
    def journal(self) -> Path:
        return self.folder / JOURNAL

    @property
    def backups(self) -> Path:
        return self.folder / "backup"

    @property
    def product_files(self) -> list[Path]:
        """Every file the workbench writes for the aircraft (what a commit may replace)."""
        return [self.aircraft_xml, self.propeller_xml, self.calibration, self.engine_xml, self.propeller_bem,
                self.init_xml, self.script]


def recover_product(paths: AircraftPaths) -> str | None:
    """Finish or roll back an interrupted write of the aircraft's files (:func:`jsbsim_calib.core.commit.recover`)."""
    if not paths.folder.is_dir():
        return None
    done = recover(paths.journal, paths.product_files)
    if done == "finished":
        warnings.warn(f"{paths.folder}: an interrupted write of the aircraft's files was finished from its journal")
    return done


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
    """Factor values of the calibration record (neutral when there is none); refused
    (:class:`AircraftFileError`) when the record is not readable JSON or holds bad values."""
    recover_product(paths)
    if not paths.calibration.is_file():
        return FactorSet()
    try:
        data = json.loads(paths.calibration.read_text())
        factors = data.get("factors", {}) if isinstance(data, dict) else None
        if not isinstance(factors, dict):
            raise ValueError("no 'factors' object")
        return FactorSet(factors)
    except (ValueError, TypeError, UnicodeDecodeError, FactorError) as exc:
        raise AircraftFileError(paths.calibration, Problem("factors", f"not a calibration record: {exc}")) from None


def read_calibration_record(paths: AircraftPaths) -> dict:
    """The whole calibration record (``{}`` when there is none); refused like :func:`read_calibration`."""
    read_calibration(paths)                       # recovers, and checks the factors
    if not paths.calibration.is_file():
        return {}
    return json.loads(paths.calibration.read_text())


def rounded(factors: FactorSet) -> FactorSet:
    """The values the record stores (:data:`CALIBRATION_DIGITS` decimals): an aircraft written
    with them is what ``generate`` writes again from the record."""
    return FactorSet({k: round(v, CALIBRATION_DIGITS) for k, v in factors.items()})


def calibration_record_bytes(paths: AircraftPaths, factors: FactorSet, stage: str, record: dict) -> bytes:
    """The calibration record with the factors and the record of the stage that produced
    them. A stage-1 record starts a new history (the flight-test stage builds on it)."""
    rec = json.loads(paths.calibration.read_text()) if paths.calibration.is_file() else {}
    rec["aircraft"] = paths.name
    rec["jsbsim_calib"] = __version__
    rec["factors"] = {k: round(v, CALIBRATION_DIGITS) for k, v in factors.items()}
    if stage == "steady":
        rec["stages"] = {}
    rec.setdefault("stages", {})[stage] = record
    return (json.dumps(rec, indent=2) + "\n").encode()


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
    """The neutral BEM tables beside an aircraft; :class:`AircraftFileError` naming the file when
    it is missing, cut or not numbers (``generate`` rewrites it)."""
    try:
        tables = parse_bem_csv(path.read_text(), str(path))
    except (OSError, UnicodeDecodeError, ValueError, IndexError) as exc:
        raise AircraftFileError(path, Problem("", f"not the BEM tables 'generate' writes ({exc}); run 'jsbsim-calib "
                                                  f"generate' to rewrite them")) from None
    if not all(np.all(np.isfinite(a)) for a in (tables.J, tables.CT, tables.CP)):
        raise AircraftFileError(path, Problem("", "holds values that are not finite numbers; run 'jsbsim-calib "
                                                  "generate' to rewrite it"))
    return tables


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
    return apply_factors(read_bem_csv(paths.propeller_bem), propeller_factor_values(factors.propeller()))


# --------------------------------------------------------------------------- writing an aircraft
@dataclass(frozen=True)
class Propeller:
    """What the propeller file is baked from: the aircraft's geometry and neutral BEM tables,
    and the name of the aircraft whose geometry file the file cites."""

    geometry: AircraftGeometry
    bem: PropellerTables
    aircraft: str


def aircraft_bytes(aircraft: Tree, factors: FactorSet, *, effect_values: Mapping[str, float] | None = None,
                   indent_file: bool = True, stamp_body: bool = False, calibration=KEEP) -> bytes:
    """The bytes of an aircraft file with the values of ``factors`` (and ``effect_values``, by
    property) declared in it. ``indent_file=False`` keeps the tree's formatting (a calibrated
    aircraft: hand edits stay as they are); ``stamp_body`` records the body's digest (the
    workbench's own edits are not hand edits); ``calibration``: the digest of the calibration
    record the values come from (None: not from one; KEEP: unchanged) (:func:`.aircraft.stamp`)."""
    set_factor_values(aircraft, factors)
    if effect_values:
        set_effect_values(aircraft, effect_values)
    if indent_file:
        indent(aircraft)
    stamp(aircraft, body=stamp_body, calibration=calibration)
    return tostring(aircraft, indent_file)


def propeller_bytes(file_name: str, propeller: Propeller, factors: FactorSet) -> bytes:
    """The propeller file ``file_name`` (``AircraftPaths.propeller_file``) baked at ``factors``."""
    return tostring(propeller_tree(propeller.geometry, propeller.bem, factors, aircraft=propeller.aircraft,
                                   file_name=file_name))


def write_aircraft(paths: AircraftPaths, factors: FactorSet, *, aircraft: Tree | None = None,
                   propeller: Propeller | None = None, effect_values: Mapping[str, float] | None = None,
                   stamp_body: bool = False) -> list[Path]:
    """Write an aircraft with its factors; returns the files written.

    ``aircraft``: the parsed aircraft file; the values of ``factors`` (and ``effect_values``, by
    property) are declared in it and it is written to ``paths.aircraft_xml`` (``stamp_body``:
    its record's body digest recomputed). ``propeller``: the propeller tables are baked with the
    propeller factors of ``factors`` and written to ``paths.propeller_xml``. Either may be left
    out (a derived aircraft flies on its parent's propeller file; the sandbox re-bakes its
    propeller alone when only propeller factors change). Each file is written atomically; the
    product's files are written together by :func:`write_calibrated` and ``generate``."""
    out = []
    if aircraft is not None:
        write_bytes(paths.aircraft_xml, aircraft_bytes(aircraft, factors, effect_values=effect_values,
                                                       stamp_body=stamp_body))
        out.append(paths.aircraft_xml)
    if propeller is not None:
        write_bytes(paths.propeller_xml, propeller_bytes(paths.propeller_file, propeller, factors))
        out.append(paths.propeller_xml)
    return out


# --------------------------------------------------------------------------- the product written as one unit
@dataclass(frozen=True)
class FactorChange:
    name: str
    old: float            # in the aircraft file before the write
    new: float


@dataclass(frozen=True)
class ProductWrite:
    """What a write of the product did: the files, the factor values it changed, the factors
    it found set by hand (file value != calibration.json) and overwrote, and the backup."""

    files: list[Path]
    changes: list[FactorChange] = field(default_factory=list)
    hand_set: list[str] = field(default_factory=list)
    backup: Path | None = None

    def __iter__(self):
        return iter(self.files)

    def report(self) -> str:
        lines = ["written: " + ", ".join(str(f) for f in self.files)]
        if self.changes:
            lines.append(f"factor values changed ({len(self.changes)}):")
            lines += [f"  {c.name:<18} {c.old:.10g} -> {c.new:.10g}" for c in self.changes]
        else:
            lines.append("factor values unchanged")
        if self.backup is not None:
            lines.append(f"backup of the replaced files: {self.backup}")
        return "\n".join(lines)


def _same(a: float, b: float) -> bool:
    """Equal as the aircraft file writes them (:data:`FACTOR_DIGITS` significant digits)."""
    return fmt(a, FACTOR_DIGITS) == fmt(b, FACTOR_DIGITS)


def factor_changes(old: Mapping[str, float], new: Mapping[str, float]) -> list[FactorChange]:
    """The registry factors whose value goes from ``old`` (missing: neutral) to another in ``new``."""
    return [FactorChange(k, float(old.get(k, f.neutral)), float(new[k])) for k, f in REGISTRY.items()
            if k in new and not _same(old.get(k, f.neutral), new[k])]


def hand_set_factors(declared: Mapping[str, float], recorded: Mapping[str, float]) -> list[FactorChange]:
    """Factors whose value in the aircraft file differs from calibration.json (set by hand):
    ``old`` the record's value, ``new`` the file's."""
    return [FactorChange(k, float(recorded[k]), float(v)) for k, v in declared.items()
            if k in recorded and not _same(v, recorded[k])]


def warn_hand_set(paths: AircraftPaths, hand: list[FactorChange], what: str, kept: bool = False) -> None:
    """Name each factor set by hand: ``what`` overwrites it, or (``kept``) keeps it and records it."""
    done = (f"{what} keeps it and records it in calibration.json" if kept else
            f"{what} overwrites it (the old file goes to {paths.backups}/)")
    for h in hand:
        warnings.warn(f"{paths.aircraft_xml}: {h.name} = {h.new:.10g} differs from calibration.json ({h.old:.10g}): "
                      f"set by hand (or by close-loop --in-place); {done}")


def commit_product(paths: AircraftPaths, files: Mapping[Path, bytes], run: str | None = None):
    """Replace the product's ``files`` as one unit, backing up the replaced ones (``run``: one
    backup for all the commits of a run, :func:`jsbsim_calib.core.commit.commit`)."""
    return commit(files, paths.journal, backup=paths.backups, keep=BACKUPS_KEPT, run=run)


def write_calibrated(root: Path | str, name: str, factors: FactorSet, stage: str, record: dict, *,
                     run: str | None = None) -> ProductWrite:
    """Write calibrated factors into an aircraft of ``root`` as one unit: the aircraft file
    (values only: its comments, added functions and formatting stay), the baked propeller and
    the calibration record. A factor whose value in the file differs from calibration.json
    (set by hand) is named in a warning, as overwritten or (a model switch, a factor the stage
    does not fit) as kept and recorded; the replaced files are
    backed up (``run``, :func:`jsbsim_calib.core.commit.new_run`: the writes of one run keep one
    backup, the product as it stood before the run). A steady-stage result starts a new
    record (the flight-test stage builds on it and must be rerun)."""
    paths = AircraftPaths(Path(root), name)
    recover_product(paths)
    factors = rounded(factors)
    tree = read(paths.aircraft_xml)
    declared = declared_factors(tree, paths.aircraft_xml)
    found = hand_set_factors(declared, read_calibration(paths)) if paths.calibration.is_file() else []
    hand = [h for h in found if not _same(factors[h.name], h.new)]     # overwritten by the stage
    warn_hand_set(paths, hand, f"the '{stage}' stage")
    warn_hand_set(paths, [h for h in found if h not in hand], f"the '{stage}' stage", kept=True)   # e.g. a switch
    changes = factor_changes(declared, factors)
    propeller = Propeller(load_aircraft_geometry(paths.root, name), read_bem_csv(paths.propeller_bem), name)
    files = {paths.aircraft_xml: aircraft_bytes(tree, factors, indent_file=False,
                                                calibration=calibration_digest(factors)),
             paths.propeller_xml: propeller_bytes(paths.propeller_file, propeller, factors),
             paths.calibration: calibration_record_bytes(paths, factors, stage, record)}
    done = commit_product(paths, files, run)
    return ProductWrite(list(files), changes, [h.name for h in hand], done.backup)


def check_consistent(paths: AircraftPaths, aircraft: Tree) -> None:
    """Refuse an aircraft file written from other calibration values than calibration.json
    holds: files of different writes (e.g. one restored or copied by hand, or a write
    interrupted before writes were journaled). Values set by hand in the file are allowed."""
    written_from = generator_record(aircraft).get("calibration")
    if not written_from or not paths.calibration.is_file():
        return
    recorded = read_calibration(paths)
    if calibration_digest(recorded) == written_from:
        return
    declared = declared_factors(aircraft, paths.aircraft_xml)
    differ = hand_set_factors(declared, recorded)
    listed = "; ".join(f"{d.name}: aircraft file {d.new:.10g}, calibration.json {d.old:.10g}" for d in differ[:8])
    raise ModelError(f"{paths.aircraft_xml} was written with other calibration values than {paths.calibration} "
                     f"holds: the files are from different writes ({listed or 'values restored by hand'}). "
                     f"Restore a consistent set from {paths.backups}/ or rewrite the aircraft from calibration.json "
                     f"with 'jsbsim-calib generate {paths.name}'")


def write_derived(source: AircraftPaths, aircraft: Tree, factors: FactorSet, destination: AircraftPaths) -> Path:
    """Write ``aircraft`` (a variant of ``source``, e.g. with effects added) as ``destination``:
    the source's folder copied (its geometry and BEM tables; not its XML, calibration record or
    backups), the aircraft file written with ``factors``. It flies on the source's engine and
    propeller files, which its XML names. The record's body digest is recomputed unless the
    source file carries hand edits (they stay visible as such)."""
    clean = source.aircraft_xml.is_file() and hand_edited(read(source.aircraft_xml)) is False
    if destination.folder.resolve() != source.folder.resolve():
        destination.folder.mkdir(parents=True, exist_ok=True)
        for f in source.folder.iterdir():
            if f.is_file() and f.suffix != ".xml" and f.name not in ("calibration.json", JOURNAL, ".lock"):
                shutil.copy(f, destination.folder / f.name)
    write_aircraft(destination, factors, aircraft=aircraft, stamp_body=clean,
                   effect_values={f.property: factors[n] for n, f in factors.extra.items()})
    return destination.aircraft_xml
