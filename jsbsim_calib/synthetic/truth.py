"""Helpers for tests and experiments with truth aircraft: copies of an aircraft with effects
the model does not declare, synthetic data flown by them, and a JSBSim root to write into.

:func:`truth_copy` copies an aircraft folder and writes undeclared effects into its XML: library
effects (their own XML, at given factor values) and hand-made terms
(:class:`UndeclaredTerm`: a ``<function>`` in an axis, ``coefficient x regressor x qbar S [l]``,
the regressor a name of :data:`jsbsim_calib.calibration.terms.REGRESSORS` or raw JSBSim
function XML). The copy flies as JSBSim flies it; nothing in it says the term is there.
"""
from __future__ import annotations

import csv
import shutil
from dataclasses import dataclass
from pathlib import Path
from typing import Mapping, Sequence

from ..calibration.effects import library
from ..calibration.terms import AXES, REGRESSORS, axis as axis_record
from ..core.errors import ModelError
from ..jsbsim.simulator import Simulator
from ..jsbsim.xml import Tree, comment, fmt, function, parse, read, write
from .snapshots import synthesize, write_csv

ROOT_FOLDERS = ("aircraft", "engine", "airfoils", "data")


@dataclass(frozen=True)
class UndeclaredTerm:
    """``Delta C = coefficient x regressor`` on ``axis`` (LIFT, DRAG, SIDE, ROLL, PITCH, YAW)."""

    axis: str
    coefficient: float
    regressor: str                   # a REGRESSORS name ("flaps", "flaps x Tc", ...) or raw XML
    name: str = ""

    def expression(self) -> str:
        a = axis_record(self.axis)
        reg = self.regressor if self.regressor.lstrip().startswith("<") else _regressor_xml(self.regressor)
        length = f"<property>{a.length}</property>" if a.length else ""
        return (f"<product><value>{fmt(self.coefficient, 10)}</value><property>aero/qbar-psf</property>"
                f"<property>metrics/Sw-sqft</property>{length}{reg}</product>")


def _regressor_xml(name: str) -> str:
    if name not in REGRESSORS:
        raise ModelError(f"unknown regressor '{name}'; known: {', '.join(REGRESSORS)}")
    return REGRESSORS[name].xml


def add_undeclared_term(aircraft: Tree, term: UndeclaredTerm, index: int = 0) -> None:
    """Append the term as a ``<function>`` to its axis of a parsed aircraft file."""
    axes = aircraft.getroot().find("aerodynamics")
    target = axes.find(f"axis[@name='{term.axis}']") if axes is not None else None
    if target is None:
        raise ModelError(f"the aircraft has no <axis name='{term.axis}'>")
    name = term.name or f"term{index}"
    unit = AXES[term.axis].unit
    comment(target, f"undeclared test term: {AXES[term.axis].coefficient} += {term.coefficient:g} x {term.regressor}")
    function(target, f"aero/undeclared/{name}-{unit}", f"undeclared {term.axis} term",
             parse(term.expression(), f"term {name}"))


def truth_copy(source_dir: Path, dest_dir: Path, terms: Sequence[UndeclaredTerm] = (),
               effects: Mapping[str, Mapping[str, float]] | None = None, root: Path | None = None) -> Path:
    """A copy of an aircraft folder (``dest_dir``, named as the source) with library effects
    (name -> {factor: value}) and undeclared terms written into its XML; ``root`` supplies
    engines and airfoils when the source is not inside a JSBSim root."""
    source_dir, dest_dir = Path(source_dir), Path(dest_dir)
    if dest_dir.name != source_dir.name:
        raise ModelError(f"the copy must keep the aircraft's name ({source_dir.name}), not {dest_dir.name}")
    shutil.copytree(source_dir, dest_dir)
    xml_path = dest_dir / f"{dest_dir.name}.xml"
    tree = read(xml_path)
    if effects:
        lib = library()
        with Simulator.from_dir(dest_dir, root or source_dir.parent.parent) as s:
            for name, vals in effects.items():
                e = lib[name]
                s.add_effect(e, {f.property: vals[f.name] for f in e.factors if f.name in vals})
            tree = s.aircraft_tree()
    for k, t in enumerate(terms):
        add_undeclared_term(tree, t, k)
    write(tree, xml_path)
    return dest_dir


def synthetic_rows(truth_dir: Path, root: Path, *, n: int, seed: int, noise: float = 1.0) -> list[dict]:
    """Snapshot rows of a synthetic campaign flown by the truth (:func:`jsbsim_calib.synthetic.snapshots.synthesize`)."""
    with Simulator.from_dir(truth_dir, root) as truth:
        rows, _ = synthesize(truth, n=n, seed=seed, noise=noise)
    return rows


def write_snapshots(rows: list[dict], path: Path) -> Path:
    write_csv(rows, path)
    return Path(path)


CLIMB_COLUMNS = ("weight_lb", "cg_in", "flaps_deg", "pressure_alt_ft", "ktas", "roc_fpm")


def write_climbs(rows: list[dict], path: Path) -> Path:
    """The full-throttle climbs of a synthetic campaign (``throttle_norm`` 1) in the flight-test
    climb format (``roc_fpm``: the truth's climb rate with its noise): climbs at full throttle,
    the rate of climb compared."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(CLIMB_COLUMNS)
        for r in rows:
            if r.get("throttle_norm") == 1.0:
                w.writerow([r["weight_lb"], r["cg_in"], r["flaps_deg"], r["pressure_alt_ft"], r["ktas"], r["vs_fpm"]])
    return path


def root_copy(repo: Path, dest: Path, folders: Sequence[str] = ROOT_FOLDERS) -> Path:
    """A JSBSim root to write into: copies of the repository's aircraft, engines, airfoils and data."""
    dest = Path(dest)
    for d in folders:
        shutil.copytree(Path(repo) / d, dest / d)
    return dest


def synthetic_fleet(real_log: Path, out_dir: Path, n: int, *, rows: int = 300, seed: int = 0) -> list[Path]:
    """``n`` G1000 logs cut from a real one (its three header lines, then ``rows`` consecutive
    rows from a seeded start): a fleet of short flights, some with a quasi-steady segment, some
    without (those fail as real short logs do)."""
    import random
    lines = Path(real_log).read_text().splitlines(keepends=True)
    head, body = lines[:3], [ln for ln in lines[3:] if ln.strip()][:-1]     # the real log's last line is cut
    rnd = random.Random(seed)
    out_dir.mkdir(parents=True, exist_ok=True)
    paths = []
    for i in range(n):
        start = rnd.randrange(0, len(body) - rows)
        p = out_dir / f"log_{i:04d}.csv"
        p.write_text("".join(head + body[start:start + rows]))
        paths.append(p)
    return paths
