"""Regression check of an aircraft after a hand edit: what moved, point by point.

:func:`write_baseline` evaluates an aircraft on all its data files (the ``[data]`` table of its
geometry file that an evaluation understands: POH climb and cruise, flight-test snapshots and
flap climbs, a G1000 log) and records the evaluations as JSON::

    {"aircraft", "jsbsim_calib", "share": <default share>,
     "evaluations": {"<data file, relative to the root>": <the evaluation JSON of `evaluate --json`>}}

:func:`regress` evaluates the aircraft as it stands now on the same files and lists every
metric of every data point whose model value moved by more than ``share`` of its tolerance
(default 0.1: 10 ft/min of climb, 5 rpm, 0.5 % power, 0.5 % of fuel flow, 0.1 deg of attitude
or surface), and every point that trims now and did not, or the other way round. Trims converge
to 1e-10 g, so an edit that changes nothing (a comment, formatting) moves nothing at all.
"""
from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Mapping, Sequence

from .. import __version__
from ..core.errors import DataError, InputError, Problem
from ..data.load import load_dataset
from ..data.schemas import METRICS
from ..jsbsim.simulator import Simulator
from .evaluate import KINDS, evaluate_dataset

DEFAULT_SHARE = 0.1
EVALUATED_KINDS = ("poh_climb", "poh_cruise", "flight_test", "flap_climb", "g1000")


@dataclass(frozen=True)
class Move:
    """One metric of one data point that moved (or whose trim changed)."""

    data: str                   # data file key
    row: int                    # point index in the file
    metric: str
    baseline: float | None      # model value in the baseline (None: the trim failed)
    now: float | None           # model value now (None: the trim fails)
    tolerance: float            # the metric's tolerance at this point

    @property
    def share(self) -> float:
        """|now - baseline| / tolerance (inf when a trim started or stopped failing)."""
        if self.baseline is None or self.now is None:
            return math.inf
        return abs(self.now - self.baseline) / self.tolerance

    def describe(self) -> str:
        unit = METRICS[self.metric].unit if self.metric in METRICS else ""
        if self.baseline is None or self.now is None:
            state = "now trims" if self.baseline is None else "no longer trims"
            return f"{self.data} row {self.row} {self.metric}: {state}"
        return (f"{self.data} row {self.row} {self.metric}: {self.baseline:.6g} -> {self.now:.6g} {unit} "
                f"({self.now - self.baseline:+.4g}, {self.share:.2f} of the +-{self.tolerance:.4g} tolerance)")


@dataclass
class Regression:
    """The outcome of :func:`regress`."""

    aircraft: str
    share: float
    files: list[str]
    compared: int                                  # metric values compared
    moves: list[Move] = field(default_factory=list)

    @property
    def moved(self) -> bool:
        return bool(self.moves)

    def report(self) -> str:
        head = (f"{self.aircraft}: {self.compared} metric values on {len(self.files)} data files compared with the "
                f"baseline; threshold {self.share:g} of each tolerance")
        if not self.moves:
            return head + "\nnothing moved"
        lines = [head, f"{len(self.moves)} moved:"]
        return "\n".join(lines + ["  " + m.describe() for m in sorted(self.moves, key=lambda m: -m.share)])

    def to_json(self) -> dict:
        return {"aircraft": self.aircraft, "share": self.share, "files": self.files, "compared": self.compared,
                "moved": [{"data": m.data, "row": m.row, "metric": m.metric, "baseline": m.baseline, "now": m.now,
                           "tolerance": m.tolerance,
                           "share": None if math.isinf(m.share) else m.share} for m in self.moves]}


# --------------------------------------------------------------------------- evaluating
def data_files(sim: Simulator) -> list[Path]:
    """The aircraft's data files an evaluation understands, in the order of :data:`EVALUATED_KINDS`."""
    files = sim.geometry.data_files
    return [files[k] for k in EVALUATED_KINDS if k in files]


def file_key(root: Path, path: Path | str) -> str:
    """A data file's key: its path relative to the root when inside it (POSIX), else absolute."""
    p = Path(path).resolve()
    try:
        return p.relative_to(Path(root).resolve()).as_posix()
    except ValueError:
        return p.as_posix()


def evaluate_files(sim: Simulator, files: Sequence[Path | str],
                   progress: Callable[[str], None] | None = None) -> dict[str, dict]:
    """The evaluation JSON of each file, by key."""
    out = {}
    for f in files:
        if progress:
            progress(f"evaluating {Path(f).name}")
        ds = load_dataset(f, control_travel=sim.geometry.control_travel_file, geometry=sim.geometry)
        if ds.kind not in KINDS:
            raise DataError(f, f"data of kind '{ds.kind}' cannot be evaluated")
        out[file_key(sim.root, f)] = evaluate_dataset(sim, ds).to_json()
    return out


def write_baseline(root: Path | str, name: str, out: Path | str, files: Sequence[Path | str] | None = None,
                   progress: Callable[[str], None] | None = None) -> Path:
    """Evaluate aircraft ``name`` on ``files`` (default: all its data files) and write the baseline JSON."""
    with Simulator(Path(root), name) as sim:
        evaluations = evaluate_files(sim, list(files) if files else data_files(sim), progress)
    doc = {"aircraft": name, "jsbsim_calib": __version__, "share": DEFAULT_SHARE, "evaluations": evaluations}
    Path(out).write_text(json.dumps(doc, indent=2) + "\n")
    return Path(out)


# --------------------------------------------------------------------------- comparing
def _value(point: Mapping, metric: str) -> float | None:
    v = point.get("model", {}).get(metric)
    return None if v is None or not point.get("trimmed", False) else float(v)


def point_moves(key: str, row: int, base: Mapping, now: Mapping, share: float) -> list[Move]:
    """The metrics of one point that moved by more than ``share`` of their tolerance."""
    out = []
    for metric in sorted(set(base.get("model", {})) | set(now.get("model", {}))):
        b, n = _value(base, metric), _value(now, metric)
        if b is None and n is None:
            continue
        ref = now.get(metric, base.get(metric))
        tol = METRICS[metric].tol_for(float(ref)) if metric in METRICS and ref is not None else 1.0
        move = Move(key, row, metric, b, n, tol)
        if move.share > share:
            out.append(move)
    return out


def compare_evaluations(key: str, base: Mapping, now: Mapping, share: float) -> tuple[list[Move], int]:
    """Moves between two evaluation JSONs of the same data file, and the number of values compared."""
    if len(base["points"]) != len(now["points"]):
        raise DataError(key, f"the baseline has {len(base['points'])} points, the data file now "
                             f"{len(now['points'])}: the data changed, write a new baseline")
    moves, compared = [], 0
    for row, (b, n) in enumerate(zip(base["points"], now["points"])):
        moves += point_moves(key, row, b, n, share)
        compared += len(set(b.get("model", {})) | set(n.get("model", {})))
    return moves, compared


def _read_baseline(path: Path | str) -> dict:
    try:
        doc = json.loads(Path(path).read_text())
    except (OSError, ValueError) as exc:
        raise InputError(path, f"cannot read the baseline: {exc}") from None
    if not isinstance(doc, dict) or "evaluations" not in doc:
        raise InputError(path, "not a regress baseline (no 'evaluations'; write one with --write-baseline)")
    return doc


def _files_to_check(root: Path, doc: dict, baseline: Path | str, files: Sequence[Path | str] | None) -> list[str]:
    if not files:
        return list(doc["evaluations"])
    keys = [file_key(root, f) for f in files]
    missing = [Problem(k, "not in the baseline") for k in keys if k not in doc["evaluations"]]
    if missing:
        raise InputError(baseline, missing)
    return keys


def regress(root: Path | str, name: str, baseline: Path | str, files: Sequence[Path | str] | None = None,
            share: float = DEFAULT_SHARE, progress: Callable[[str], None] | None = None) -> Regression:
    """Evaluate aircraft ``name`` as it stands on the baseline's data files (or ``files``, which
    the baseline must hold) and list what moved by more than ``share`` of its tolerance."""
    root = Path(root)
    doc = _read_baseline(baseline)
    if doc.get("aircraft") != name:
        raise InputError(baseline, f"a baseline of '{doc.get('aircraft')}', not of '{name}'")
    keys = _files_to_check(root, doc, baseline, files)
    with Simulator(root, name) as sim:
        now = evaluate_files(sim, [Path(k) if Path(k).is_absolute() else root / k for k in keys], progress)
    result = Regression(name, share, keys, 0)
    for key in keys:
        moves, compared = compare_evaluations(key, doc["evaluations"][key], now[key], share)
        result.moves += moves
        result.compared += compared
    return result
