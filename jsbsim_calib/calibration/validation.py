"""Held-out validation of the calibration stages: refit with a group of data left out, judge the
left-out group (REPORTING: the stages' fits and the committed products are not changed).

A fold leaves out the rows a user would vary: POH climbs by temperature and by altitude band,
POH cruise by altitude (stage 1); flight-test snapshots and flaps-down climbs by flap setting
and by test type from the title: climb, cruise, turn, pulse initial conditions (stage 2a).
Each fold refits with the stage's own fit functions and real trims, from the stage's own
factors (``calibration.json``):

* stage 1 (:func:`~jsbsim_calib.calibration.steady.steady_stage`): the 16 factors and K_FF on
  the stage-1 subset that the stage's own rule picks from the fold's complement, a few
  iterations (``max_nfev``, default 60);
* stage 2a (:func:`~jsbsim_calib.calibration.trims.trims_stage`): only the steps whose
  residuals use rows the fold removes, in order, on the complement.

Then every point is trimmed again: the *fit* error is the refit's error on the points it kept
(the complement), the *held-out* error its error on the fold, the *in-sample* error the stage's
model's on the fold (it saw them). A fold-metric is flagged when held-out RMSE exceeds
:data:`FLAG_RATIO` times the fit RMSE (unless below :data:`RESOLUTION` of its tolerance), when a
held-out trim fails, or when a number is missing (a NaN never passes).
A control refit with nothing left out measures what the shortened refit alone changes.
"""
from __future__ import annotations

import json
import math
import time
import uuid
import warnings
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Callable, Mapping, Sequence

import numpy as np
import pandas as pd

from ..data.flighttest import QuirkWarning
from ..data.load import load_dataset
from ..data.schemas import METRICS, Dataset
from ..core.errors import InputError, ModelError
from ..core.executor import SERIAL, Executor
from ..evaluation.evaluate import MetricSummary, PointResult, evaluate_dataset, summarize
from ..factors import FactorSet
from ..jsbsim.aircraft import read_factors
from ..jsbsim.product import AircraftPaths, load_aircraft_geometry
from ..jsbsim.simulator import Simulator
from .points import point_sets, stage1_subset
from .steady import steady_stage
from .trims import TRIM_STEPS, TrimStep, trims_stage
from .workflow import recorded_start

FLAG_RATIO = 1.5             # held-out RMSE above this many times the fit RMSE is flagged ...
RESOLUTION = 0.1             # ... unless it is below this share of the metric's tolerance (the data's resolution)
STEADY_MAX_NFEV = 60         # a fold's stage-1 refit: a few iterations from the calibrated factors
TRIMS_MAX_NFEV = 60          # a fold's stage-2a step refits
ALTITUDE_BANDS = 3           # POH climbs: the distinct altitudes split into this many bands
TURN_BANK_DEG = 15.0         # a snapshot banked more than this is a turn, whatever its title
STEADY_KINDS = ("poh_climb", "poh_cruise")
TRIMS_KINDS = ("snapshot", "flap_climb")
DATA_KEYS = {"poh_climb": "poh_climb", "poh_cruise": "poh_cruise", "snapshot": "flight_test",
             "flap_climb": "flap_climb"}      # data kind -> key of the geometry file's [data] table
STAGE_DATA_KEYS = {"steady": ("poh_climb", "poh_cruise"), "trims": ("flight_test",),
                   "dynamic": ("flight_test", "flight_test_results")}   # [data] keys a stage needs

Say = Callable[[str], None]


# --------------------------------------------------------------------------- results
@dataclass(frozen=True)
class Fold:
    """A group of data left out: row positions (in the stage's datasets) per data kind."""

    name: str                              # e.g. "climb OAT -20 C"
    grouping: str                          # what a user varies: "climb temperature", "flap setting", ...
    rows: Mapping[str, tuple[int, ...]]    # data kind -> row positions left out

    @property
    def size(self) -> int:
        return sum(len(r) for r in self.rows.values())


@dataclass(frozen=True)
class ErrorStat:
    """Accuracy of one metric over a set of points. NaN when nothing could be computed."""

    n: int                    # points with a data value
    rmse: float               # [the metric's unit] over the trimmed points; NaN if none trimmed
    within_pct: float         # [%] within tolerance; a failed trim counts as outside; NaN if n == 0
    failed: int               # points whose trim failed

    @classmethod
    def of(cls, s: MetricSummary) -> "ErrorStat":
        nan = lambda v: math.nan if v is None else float(v)
        return cls(s.n, nan(s.rmse), nan(s.within_pct) if s.n else math.nan, s.failed)

    @property
    def all_within(self) -> bool:
        """Every point within tolerance (False for NaN or no point)."""
        return bool(self.n > 0 and self.within_pct >= 100.0 - 1e-9)


@dataclass(frozen=True)
class FoldMetric:
    """Fit, held-out and in-sample error of one metric for one fold."""

    fold: str
    grouping: str
    kind: str                 # data kind of the metric (poh_climb, snapshot, ...)
    metric: str
    unit: str
    fit: ErrorStat            # refit on the points it kept (the fold's complement)
    held_out: ErrorStat       # refit on the left-out points
    in_sample: ErrorStat      # the stage's own model on the left-out points
    tolerance: float          # [the metric's unit] its tolerance, mean over the left-out points

    @property
    def ratio(self) -> float:
        """Held-out RMSE / fit RMSE (NaN when either is NaN; inf when only the fit is exact)."""
        h, f = self.held_out.rmse, self.fit.rmse
        if not (math.isfinite(h) and math.isfinite(f)):
            return math.nan
        if f == 0.0:
            return 1.0 if h == 0.0 else math.inf
        return h / f

    @property
    def below_resolution(self) -> bool:
        """Held-out RMSE below RESOLUTION of the tolerance: no ratio makes it material."""
        return bool(math.isfinite(self.held_out.rmse) and self.held_out.rmse <= RESOLUTION * self.tolerance)

    @property
    def flagged(self) -> bool:
        """A failed held-out trim, a held-out error that is not a number, or held-out much worse
        than fit (ratio > FLAG_RATIO; a NaN ratio never passes) unless below the resolution."""
        if self.held_out.failed > 0 or not math.isfinite(self.held_out.rmse) or math.isnan(self.ratio):
            return True
        return not (self.below_resolution or self.ratio <= FLAG_RATIO)

    @property
    def flag_reason(self) -> str:
        if self.held_out.failed:
            return f"{self.held_out.failed} held-out trim(s) failed"
        if not self.flagged:
            return ""
        if self.fit.n == 0:
            return "no point of this kind left in the fit"
        r = self.ratio
        if not math.isfinite(r):
            return "no number (a NaN never passes)" if math.isnan(r) else "fit exact, held-out not"
        return f"held-out/fit {r:.2f} > {FLAG_RATIO:g}"


@dataclass
class FoldResult:
    """One refit with a fold left out (or, for the control, nothing)."""

    fold: Fold
    refitted: tuple[str, ...]          # the fit steps run
    factors: FactorSet                 # after the refit
    metrics: list[FoldMetric]
    cost_final: float                  # 1/2 sum r^2 of the last step's residuals
    wall_time_s: float
    trims: int
    failures: list[str] = field(default_factory=list)   # held-out points whose trim failed, with the reason
    moved: dict[str, tuple[float, float]] = field(default_factory=dict)   # factor -> (stage value, refit value)

    def largest_moves(self, n: int = 3) -> list[tuple[str, float, float]]:
        """The factors the refit moved most, in normalized units (share of their range)."""
        span = lambda k: self.factors.factor(k).upper - self.factors.factor(k).lower
        order = sorted(self.moved, key=lambda k: -abs(self.moved[k][1] - self.moved[k][0]) / span(k))
        return [(k, *self.moved[k]) for k in order[:n]]


@dataclass
class Validation:
    """Held-out validation of one stage of one aircraft."""

    aircraft: str
    stage: str                         # steady | trims
    folds: list[FoldResult]
    control: FoldResult | None         # the same refit with nothing left out
    in_sample: dict[str, dict[str, ErrorStat]]   # the stage's model on all points: kind -> metric -> error
    max_nfev: int
    wall_time_s: float
    trims: int
    notes: list[str] = field(default_factory=list)

    def rows(self) -> list[FoldMetric]:
        return [m for f in self.folds for m in f.metrics]

    def flagged(self) -> list[FoldMetric]:
        return [m for m in self.rows() if m.flagged]

    def to_json(self) -> dict:
        def stat(s: ErrorStat) -> dict:
            fin = lambda v: v if math.isfinite(v) else None
            return {"n": s.n, "rmse": fin(s.rmse), "within_pct": fin(s.within_pct), "failed": s.failed}

        def fold(fr: FoldResult) -> dict:
            return {"fold": fr.fold.name, "grouping": fr.fold.grouping,
                    "left_out": {k: list(v) for k, v in fr.fold.rows.items()}, "refitted": list(fr.refitted),
                    "wall_time_s": fr.wall_time_s, "trims": fr.trims, "failures": fr.failures,
                    "moved": {k: {"stage": a, "refit": b} for k, a, b in fr.largest_moves(len(fr.moved))},
                    "metrics": [{"kind": m.kind, "metric": m.metric, "unit": m.unit, "tolerance": m.tolerance,
                                 "fit": stat(m.fit),
                                 "held_out": stat(m.held_out), "in_sample": stat(m.in_sample),
                                 "ratio": m.ratio if math.isfinite(m.ratio) else None, "flagged": m.flagged,
                                 "flag_reason": m.flag_reason} for m in fr.metrics]}

        return {"aircraft": self.aircraft, "stage": self.stage, "flag_ratio": FLAG_RATIO, "resolution": RESOLUTION,
                "max_nfev": self.max_nfev,
                "in_sample": {k: {m: stat(s) for m, s in v.items()} for k, v in self.in_sample.items()},
                "control": fold(self.control) if self.control else None,
                "folds": [fold(f) for f in self.folds], "notes": self.notes}

    def write_json(self, path: Path) -> None:
        Path(path).write_text(json.dumps(self.to_json(), indent=2) + "\n")


# --------------------------------------------------------------------------- folds
def _groups(values: Sequence[float]) -> dict[float, tuple[int, ...]]:
    out: dict[float, list[int]] = {}
    for i, v in enumerate(values):
        out.setdefault(float(v), []).append(i)
    return {k: tuple(v) for k, v in sorted(out.items())}


def _temperature_column(frame: pd.DataFrame) -> tuple[str, str] | None:
    """The column a POH climb varies its temperature by, and its label (None: one temperature)."""
    for col, label in (("oat_c", "OAT"), ("temp_dev_c", "ISA")):
        if col in frame and frame[col].nunique(dropna=True) > 1 and frame[col].notna().all():
            return col, label
    return None


def climb_folds(climb: Dataset) -> list[Fold]:
    """POH climbs by temperature (one fold per value) and by altitude band (low, middle, high)."""
    f, folds = climb.frame, []
    temp = _temperature_column(f)
    if temp:
        col, label = temp
        for v, rows in _groups(f[col].to_numpy(float)).items():
            sign = "+" if label == "ISA" and v > 0 else ""
            folds.append(Fold(f"climb {label} {sign}{v:g} C", "climb temperature", {"poh_climb": rows}))
    alts = sorted(set(f["pressure_alt_ft"].astype(float)))
    for band in np.array_split(np.array(alts), min(ALTITUDE_BANDS, len(alts))):
        rows = tuple(i for i, a in enumerate(f["pressure_alt_ft"].astype(float)) if a in set(band))
        folds.append(Fold(f"climb {band[0]:,.0f}-{band[-1]:,.0f} ft", "climb altitude band", {"poh_climb": rows}))
    return folds


def cruise_folds(cruise: Dataset) -> list[Fold]:
    """POH cruise by pressure altitude (one fold per altitude)."""
    return [Fold(f"cruise {a:,.0f} ft", "cruise altitude", {"poh_cruise": rows})
            for a, rows in _groups(cruise.frame["pressure_alt_ft"].to_numpy(float)).items()]


def snapshot_test_type(title: str, bank_deg: float = 0.0) -> str:
    """The kind of flight-test snapshot from its title: climb, turn, pulse (the initial condition
    of a control-input test) or cruise (trims, power change, phugoid)."""
    t = title.lower()
    if "roll response" in t or abs(bank_deg) > TURN_BANK_DEG:
        return "turn"
    if "climb" in t:
        return "climb"
    if "small control inputs" in t or "control /" in t:
        return "pulse"
    return "cruise"


def snapshot_titles(ds: Dataset) -> list[str]:
    """Titles of a snapshot dataset's rows (from its file, by the ``table`` column)."""
    raw = pd.read_csv(ds.path, dtype=str, keep_default_na=False, skipinitialspace=True)
    by_table = dict(zip(raw["table"].str.strip(), raw.get("title", pd.Series([""] * len(raw))).str.strip()))
    return [by_table.get(str(t).strip(), "") for t in ds.frame["table"]]


def _by_value(data: Mapping[str, Dataset], values: Mapping[str, Sequence]) -> dict[object, dict[str, tuple[int, ...]]]:
    out: dict[object, dict[str, list[int]]] = {}
    for kind in data:
        for i, v in enumerate(values[kind]):
            out.setdefault(v, {}).setdefault(kind, []).append(i)
    return {v: {k: tuple(r) for k, r in rows.items()} for v, rows in out.items()}


def trims_folds(data: Mapping[str, Dataset]) -> list[Fold]:
    """Snapshots and flaps-down climbs by flap setting and by test type."""
    data = {k: data[k] for k in TRIMS_KINDS if k in data}
    flaps = {k: [float(x) for x in ds.frame["flaps_deg"]] for k, ds in data.items()}
    types = {k: (["climb"] * len(ds) if k == "flap_climb" else
                 [snapshot_test_type(t, b) for t, b in zip(snapshot_titles(ds), ds.frame["roll_deg"].astype(float))])
             for k, ds in data.items()}
    folds = [Fold(f"flaps {v:g}", "flap setting", rows) for v, rows in sorted(_by_value(data, flaps).items())]
    labels = {"climb": "climbs", "cruise": "cruise trims", "turn": "turns", "pulse": "pulse ICs"}
    by_type = _by_value(data, types)
    folds += [Fold(label, "test type", by_type[t]) for t, label in labels.items() if t in by_type]
    return folds


def select_folds(folds: Sequence[Fold], names: Sequence[str] | None) -> list[Fold]:
    """The folds named (all when ``names`` is None); an unknown name is an error."""
    if names is None:
        return list(folds)
    known = {f.name: f for f in folds}
    unknown = [n for n in names if n not in known]
    if unknown:
        raise InputError("folds", f"unknown fold(s) {', '.join(unknown)}; folds: {', '.join(known)}")
    return [known[n] for n in names]


# --------------------------------------------------------------------------- data and factors
def stage_data(root: Path, name: str, kinds: Sequence[str]) -> dict[str, Dataset]:
    """The aircraft's datasets of these kinds (those its geometry file names), by kind."""
    geom = load_aircraft_geometry(Path(root), name)
    out = {}
    for kind in kinds:
        path = geom.data_files.get(DATA_KEYS[kind])
        if path is not None:
            ds = load_dataset(path, control_travel=geom.control_travel_file)
            out[ds.kind] = ds
    return out


def _record(root: Path, name: str) -> dict:
    path = AircraftPaths(root, name).calibration
    if not path.is_file():
        raise ModelError(f"aircraft/{name} has no calibration.json: calibrate it first")
    return json.loads(path.read_text())


def stage_factors(root: Path, name: str, stage: str) -> FactorSet:
    """The factors a stage produced, from its record in calibration.json: stage 1's fits
    (``steady``), or those and every stage-2a step after them (``trims``); the model switches
    as the aircraft file sets them (the stage fitted around them), later factors neutral."""
    record = _record(root, name)
    needed = ("steady",) if stage == "steady" else ("steady", "trims")
    missing = [s for s in needed if s not in record.get("stages", {})]
    if missing:
        raise ModelError(f"aircraft/{name}/calibration.json has no record of stage(s) {', '.join(missing)}")
    declared = read_factors(AircraftPaths(root, name).aircraft_xml)
    return recorded_start(record, declared, "trims" if stage == "steady" else "dynamic")[0]


def without_rows(ds: Dataset, rows: Sequence[int], tag: str) -> Dataset:
    """A dataset without some rows, under its own name (the trims' warm starts are keyed by file)."""
    keep = [i for i in range(len(ds)) if i not in set(rows)]
    ref = ds.reference.iloc[keep].reset_index(drop=True) if len(ds.reference) == len(ds) else ds.reference
    slug = "".join(c if c.isalnum() else "-" for c in tag)
    return replace(ds, frame=ds.frame.iloc[keep].reset_index(drop=True), reference=ref,
                   path=ds.path.with_name(f"{ds.path.stem}~without-{slug}{ds.path.suffix}"))


def complement(ds: Dataset, rows: Sequence[int]) -> list[int]:
    left = set(rows)
    return [i for i in range(len(ds)) if i not in left]


# --------------------------------------------------------------------------- errors of a refit
Points = dict[str, list[PointResult]]        # data kind -> evaluated points (every row, in order)


def evaluate_all(sim: Simulator, data: Mapping[str, Dataset]) -> Points:
    return {k: evaluate_dataset(sim, ds).points for k, ds in data.items()}


def _stat(points: list[PointResult], rows: Sequence[int], metric: str) -> ErrorStat:
    return ErrorStat.of(summarize([points[i] for i in rows], [metric])[metric])


def mean_tolerance(ds: Dataset, rows: Sequence[int], metric: str) -> float:
    """The metric's tolerance [its unit] averaged over the rows with a data value (relative ones vary)."""
    refs = [float(ds.frame[metric].iloc[i]) for i in rows]
    tols = [METRICS[metric].tol_for(r) for r in refs if math.isfinite(r)]
    return float(np.mean(tols)) if tols else math.nan


def fold_metrics(fold: Fold, data: Mapping[str, Dataset], refit: Points, stage_model: Points) -> list[FoldMetric]:
    """Fit (complement), held-out (fold) and in-sample errors of every metric the fold leaves out."""
    out = []
    for kind, rows in fold.rows.items():
        if not rows:
            continue
        kept = complement(data[kind], rows)
        for m in data[kind].metrics:
            out.append(FoldMetric(fold.name, fold.grouping, kind, m, METRICS[m].unit, _stat(refit[kind], kept, m),
                                  _stat(refit[kind], rows, m), _stat(stage_model[kind], rows, m),
                                  mean_tolerance(data[kind], rows, m)))
    return out


def control_metrics(data: Mapping[str, Dataset], refit: Points, stage_model: Points) -> list[FoldMetric]:
    """The control (nothing left out): the refit's error on all points against the stage model's."""
    out = []
    for kind, ds in data.items():
        rows = list(range(len(ds)))
        for m in ds.metrics:
            out.append(FoldMetric("none (control)", "control", kind, m, METRICS[m].unit, _stat(refit[kind], rows, m),
                                  _stat(refit[kind], rows, m), _stat(stage_model[kind], rows, m),
                                  mean_tolerance(ds, rows, m)))
    return out


def in_sample_table(data: Mapping[str, Dataset], stage_model: Points) -> dict[str, dict[str, ErrorStat]]:
    return {k: {m: _stat(stage_model[k], range(len(ds)), m) for m in ds.metrics} for k, ds in data.items()}


# --------------------------------------------------------------------------- stage 1
def steady_fit_points(data: Mapping[str, Dataset], fold: Fold) -> dict[str, list[int]]:
    """The stage-1 subset the stage's own rule picks from the fold's complement, as row positions."""
    out = {}
    for kind in STEADY_KINDS:
        kept = complement(data[kind], fold.rows.get(kind, ()))
        sub = replace(data[kind], frame=data[kind].frame.iloc[kept].reset_index(drop=True))
        out[kind] = [kept[i] for i in stage1_subset(sub)]
    return out


def refit_steady(sim: Simulator, data: Mapping[str, Dataset], start: FactorSet, fold: Fold,
                 max_nfev: int) -> tuple[FactorSet, float, tuple[str, ...]]:
    """Stage 1 on the fold's complement from ``start``: its factors, last cost, the fits run."""
    pts = steady_fit_points(data, fold)
    fit, ff = steady_stage(sim, data["poh_climb"], data["poh_cruise"], start=start,
                           climb_points=pts["poh_climb"], cruise_points=pts["poh_cruise"], max_nfev=max_nfev)
    return ff.final, fit.cost_final, (fit.stage, ff.stage)


# --------------------------------------------------------------------------- stage 2a
def steps_using(sim: Simulator, data: Mapping[str, Dataset], fold: Fold,
                steps: Sequence[TrimStep] = TRIM_STEPS) -> tuple[TrimStep, ...]:
    """The stage-2a steps whose own residuals use rows the fold removes (all flight-test steps
    for the control fold, which removes nothing)."""
    def uses(ps) -> bool:
        if not fold.rows:
            return ps.dataset.kind in TRIMS_KINDS
        return bool(set(ps.indices) & set(fold.rows.get(ps.dataset.kind, ())))

    return tuple(st for st in steps if any(uses(ps) for ps in point_sets(sim, data, st.residuals)))


def refit_trims(sim: Simulator, data: Mapping[str, Dataset], start: FactorSet, fold: Fold,
                max_nfev: int) -> tuple[FactorSet, float, tuple[str, ...]]:
    """The stage-2a steps that use the fold's rows, in order, on the complement, from ``start``."""
    steps = steps_using(sim, data, fold)
    kept = {}
    for kind, ds in data.items():
        rows = fold.rows.get(kind, ())
        if len(rows) < len(ds):
            kept[kind] = without_rows(ds, rows, fold.name) if rows else ds
    results = trims_stage(sim, kept, start=start, steps=steps, max_nfev=max_nfev)
    final = results[-1].final if results else start
    return final, (results[-1].cost_final if results else math.nan), tuple(r.stage for r in results)


# --------------------------------------------------------------------------- the loop
Refit = Callable[[Simulator, Mapping[str, Dataset], FactorSet, Fold, int], tuple[FactorSet, float, tuple[str, ...]]]


def run_fold(sim: Simulator, data: Mapping[str, Dataset], judged: Sequence[str], start: FactorSet, fold: Fold,
             refit: Refit, stage_model: Points, max_nfev: int) -> FoldResult:
    """Refit with the fold left out, trim every judged point again, and compare."""
    t0, trims0 = time.perf_counter(), sim.trims
    factors, cost, ran = refit(sim, data, start, fold, max_nfev)
    sim.set_factors(factors)
    shown = {k: data[k] for k in judged}
    points = evaluate_all(sim, shown)
    metrics = fold_metrics(fold, shown, points, stage_model) if fold.rows else control_metrics(shown, points, stage_model)
    sim.set_factors(start)
    moved = {k: (start[k], factors[k]) for k in factors if factors[k] != start[k]}
    return FoldResult(fold, ran, factors, metrics, cost, time.perf_counter() - t0, sim.trims - trims0,
                      failed_points(shown, points, fold), moved)


def failed_points(data: Mapping[str, Dataset], points: Points, fold: Fold) -> list[str]:
    """The fold's points (all points for the control) whose trim failed: row label and reason."""
    out = []
    for kind, ds in data.items():
        rows = fold.rows.get(kind, ()) if fold.rows else range(len(ds))
        for i in rows:
            p = points[kind][i]
            if not p.trimmed:
                label = ds.frame["table"].iloc[i] if "table" in ds.frame else f"row {i}"
                out.append(f"{kind} {label}: {p.reason}")
    return out


def run_validation(sim: Simulator, stage: str, data: Mapping[str, Dataset], judged: Sequence[str], start: FactorSet,
                   folds: Sequence[Fold], refit: Refit, *, max_nfev: int, control: bool = True,
                   progress: Say | None = None, executor: Executor = SERIAL) -> Validation:
    """Every fold (and the control) refitted and judged, each an independent task on
    ``executor``: it starts from ``start`` and the trim warm starts of the stage's own model,
    whatever ran before it, so that the results are the same bits on any executor and worker
    count. The simulator is left at ``start``."""
    say = progress or (lambda s: None)
    t0, trims0 = time.perf_counter(), sim.trims
    sim.set_factors(start)
    stage_model = evaluate_all(sim, {k: data[k] for k in judged})
    warm = dict(sim.trim_cache)
    runs = ([Fold("none (control)", "control", {})] if control else []) + list(folds)

    def one(fold: Fold) -> FoldResult:
        sim.trim_cache = dict(warm)
        return run_fold(sim, data, judged, start, fold, refit, stage_model, max_nfev)

    say(f"{stage}: {len(runs)} refits ({'the control and ' if control else ''}{len(folds)} folds) on "
        f"{executor.describe()}")
    results = executor.map(one, runs, key=uuid.uuid4().hex)
    ctrl = results.pop(0) if control else None
    trims = sim.trims - trims0 + sum(r.trims for r in results) + (ctrl.trims if ctrl else 0)
    return Validation(sim.name, stage, results, ctrl, in_sample_table({k: data[k] for k in judged}, stage_model),
                      max_nfev, time.perf_counter() - t0, trims)


def _steady_inputs(root: Path, name: str) -> tuple[dict[str, Dataset], list[Fold]]:
    data = stage_data(root, name, STEADY_KINDS)
    missing = [k for k in STEADY_KINDS if k not in data]
    if missing:
        raise ModelError(f"aircraft/{name}/geometry.toml names no {', '.join(missing)} data ([data] table)")
    return data, climb_folds(data["poh_climb"]) + cruise_folds(data["poh_cruise"])


def _trims_inputs(root: Path, name: str) -> tuple[dict[str, Dataset], list[Fold]]:
    with warnings.catch_warnings():          # the rows left out are listed in the notes
        warnings.simplefilter("ignore", QuirkWarning)
        data = stage_data(root, name, TRIMS_KINDS + STEADY_KINDS)
    if "snapshot" not in data:
        raise ModelError(f"aircraft/{name}/geometry.toml names no flight_test data ([data] table): "
                         "stage 2a cannot be validated")
    return data, trims_folds(data)


def fold_names(root: Path | str, name: str, stage: str) -> list[str]:
    """The names of a stage's folds for an aircraft (``steady`` or ``trims``)."""
    inputs = _steady_inputs if stage == "steady" else _trims_inputs
    return [f.name for f in inputs(Path(root), name)[1]]


def validate_steady(root: Path | str, name: str, *, folds: Sequence[str] | None = None,
                    max_nfev: int = STEADY_MAX_NFEV, control: bool = True,
                    progress: Say | None = None, executor: Executor = SERIAL) -> Validation:
    """Stage 1 held out: POH climbs by temperature and altitude band, cruise by altitude.

    ``folds``: names of the folds to run (default all, :func:`climb_folds`, :func:`cruise_folds`)."""
    root = Path(root)
    data, all_folds = _steady_inputs(root, name)
    start = stage_factors(root, name, "steady")
    chosen = select_folds(all_folds, folds)
    with Simulator(root, name, factors=start) as sim:
        val = run_validation(sim, "steady", data, STEADY_KINDS, start, chosen, refit_steady, max_nfev=max_nfev,
                             control=control, progress=progress, executor=executor)
    if _temperature_column(data["poh_climb"].frame) is None:
        val.notes.append("the POH climbs are at one temperature: no temperature folds")
    val.notes.append(f"model: stage 1 factors of aircraft/{name}/calibration.json; each fold refits the 16 "
                     f"factors (at most {max_nfev} evaluations) and K_FF on the stage-1 subset of its complement")
    return val


def validate_trims(root: Path | str, name: str, *, folds: Sequence[str] | None = None,
                   max_nfev: int = TRIMS_MAX_NFEV, control: bool = True,
                   progress: Say | None = None, executor: Executor = SERIAL) -> Validation:
    """Stage 2a held out: snapshots and flaps-down climbs by flap setting and by test type.

    ``folds``: names of the folds to run (default all, :func:`trims_folds`)."""
    root = Path(root)
    data, all_folds = _trims_inputs(root, name)
    start = stage_factors(root, name, "trims")
    judged = tuple(k for k in TRIMS_KINDS if k in data)
    chosen = select_folds(all_folds, folds)
    with Simulator(root, name, factors=start) as sim:
        val = run_validation(sim, "trims", data, judged, start, chosen, refit_trims, max_nfev=max_nfev,
                             control=control, progress=progress, executor=executor)
    left = [str(q) for k in judged for q in data[k].extra.get("quirks", [])]
    val.notes.append(f"model: stage 1 and stage 2a factors of aircraft/{name}/calibration.json (before stage 2b); "
                     f"each fold refits only the stage-2a steps whose residuals use its rows (at most {max_nfev} "
                     "evaluations each); the POH points the steps hold are kept")
    val.notes += [f"left out of every fold (data quirks): {q}" for q in left]
    return val
