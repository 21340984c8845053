"""Garmin G1000 logs as reference data: segments -> trim conditions -> evaluation.

A log is read and cut into quasi-steady segments by :mod:`jsbsim_calib.g1000` (criteria in
:class:`~jsbsim_calib.g1000.SegmentCriteria`). Each segment becomes one data point:

* level cruise: level flight (the segment's mean vertical speed) at its pressure altitude,
  OAT and true airspeed, best-power mixture (the pilot leaned) -> RPM and pitch attitude;
* full-throttle climb: full throttle at its calibrated airspeed, mixture per the POH climb
  procedure -> rate of climb (pressure-altitude rate, as the G1000's VSpd) and pitch.

Weight: the log has fuel but no weight record. ``weight = empty + occupants + baggage +
fuel``, with the aircraft's empty weight from its geometry file and the occupants and baggage
of :class:`LogLoading` -- a stated assumption (two 170 lb adults, no baggage), to be changed
when the loading is known. The CG is the aircraft's default (its POH CG).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from .data import Dataset
from .jsbsim.condition import Condition, TrimResult
from .g1000 import SegmentCriteria, WeightAssumption, extract_segments, plot_log, read_g1000, segments_dataframe
from .physics.geometry import AircraftGeometry

METRICS = ("rpm", "roc_fpm", "pitch_deg")


@dataclass(frozen=True)
class LogLoading:
    """Assumed payload of a logged flight (the log records fuel only)."""

    occupants_lb: float = 340.0       # [lb] assumed: two adults at the FAA standard 170 lb
    baggage_lb: float = 0.0           # [lb] assumed
    fuel_density_lb_per_gal: float = 6.0   # [lb/US gal] avgas


def log_dataset(path: str | Path, geometry: AircraftGeometry, loading: LogLoading = LogLoading(),
                criteria: SegmentCriteria = SegmentCriteria()) -> Dataset:
    """The quasi-steady segments of a log as a dataset of kind ``g1000``."""
    path = Path(path)
    log = read_g1000(path)
    weight = WeightAssumption(empty_weight_lb=geometry.mass.empty_mass_kg / 0.45359237,
                              occupants_lb=loading.occupants_lb, baggage_lb=loading.baggage_lb,
                              fuel_density_lb_per_gal=loading.fuel_density_lb_per_gal)
    segs = extract_segments(log, criteria, weight=weight)
    table = segments_dataframe(segs)
    frame = table.copy()
    frame.insert(0, "segment", np.arange(1, len(frame) + 1))
    frame["flaps_deg"] = 0.0
    cruise = frame["kind"] == "cruise"
    frame["rpm"] = np.where(cruise, table["rpm"], np.nan)
    frame["roc_fpm"] = np.where(cruise, np.nan, table["vs_fpm"])
    frame["pitch_deg"] = table["pitch_deg"]
    note = (f"weight = empty {weight.empty_weight_lb:.0f} lb + occupants {loading.occupants_lb:.0f} lb + baggage "
            f"{loading.baggage_lb:.0f} lb (assumed) + logged fuel x {loading.fuel_density_lb_per_gal:g} lb/gal")
    return Dataset("g1000", path, frame, pd.DataFrame(), METRICS,
                   extra={"log": log, "segments": segs, "table": table, "weight_note": note, "quirks": []})


def log_conditions(ds: Dataset, geom: AircraftGeometry) -> list[Condition]:
    out = []
    for _, r in ds.frame.iterrows():
        if r["kind"] == "cruise":
            out.append(Condition(pressure_alt_ft=float(r["pressure_alt_ft"]), weight_lb=float(r["weight_lb"]),
                                 ktas=float(r["ktas"]), oat_c=float(r["oat_c"]), mode="level",
                                 vs_fpm=float(r["vs_fpm"]), mixture="cruise"))
        else:
            out.append(Condition(pressure_alt_ft=float(r["pressure_alt_ft"]), weight_lb=float(r["weight_lb"]),
                                 kcas=float(r["kcas"]), oat_c=float(r["oat_c"]), mode="full_throttle",
                                 mixture="climb"))
    return out


def log_value(metric: str, t: TrimResult) -> float:
    if metric == "rpm":
        return t.rpm
    if metric == "roc_fpm":
        return t.roc_pressure_fpm
    if metric == "pitch_deg":
        return t.theta_deg
    raise KeyError(metric)


def model_table(evaluation) -> pd.DataFrame:
    """Model values per segment (for :func:`jsbsim_calib.g1000.plot_log`)."""
    rows = []
    for p in evaluation.points:
        rows.append({"t_start_s": p.inputs["t_start_s"], "rpm": p.model.get("rpm", math.nan),
                     "roc_fpm": p.model.get("roc_fpm", math.nan), "pitch_deg": p.model.get("pitch_deg", math.nan)})
    return pd.DataFrame(rows)


def write_log_report(evaluation, out_dir: Path) -> tuple[Path, Path]:
    """A figure of the log with its segments and the model, and a Markdown table."""
    from .evaluate import format_summary
    ds = evaluation.dataset
    out_dir.mkdir(parents=True, exist_ok=True)
    stem = ds.path.stem if ds.path.stem.startswith("log") else f"log_{ds.path.stem}"
    fig = plot_log(ds.extra["log"], ds.extra["segments"], model=model_table(evaluation))
    png = out_dir / f"{stem}.png"
    fig.savefig(png, dpi=90)
    L = [f"# {evaluation.aircraft}: G1000 log {ds.path.name}", "",
         f"{len(ds)} quasi-steady segments ({int((ds.frame['kind'] == 'cruise').sum())} level cruise, "
         f"{int((ds.frame['kind'] == 'climb').sum())} full-throttle climbs); {ds.extra['weight_note']}.", "",
         "Cruise: level flight at the logged true airspeed, best-power mixture -> RPM. Climbs: full throttle at "
         "the logged calibrated airspeed, mixture per the POH -> rate of climb. Pitch for both.", "",
         "```", format_summary(evaluation.summary()), "```", "",
         "| # | kind | start min | s | Hp ft | OAT C | KTAS | VS fpm | weight lb | RPM log | model | pitch log | "
         "model | ROC log | model |", "|---:|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for p in evaluation.points:
        r = p.inputs
        f = lambda v, d=0: "-" if v is None or not np.isfinite(v) else f"{v:.{d}f}"
        L.append(f"| {r['segment']} | {r['kind']} | {r['t_start_s'] / 60:.1f} | {r['duration_s']:.0f} | "
                 f"{r['pressure_alt_ft']:.0f} | {r['oat_c']:.1f} | {r['ktas']:.1f} | {r['vs_fpm']:+.0f} | "
                 f"{r['weight_lb']:.0f} | {f(r['rpm'])} | {f(p.model.get('rpm'))} | {r['pitch_deg']:.1f} | "
                 f"{f(p.model.get('pitch_deg'), 1)} | {f(r['roc_fpm'])} | {f(p.model.get('roc_fpm'))} |")
    L += ["", f"![log]({png.name})", ""]
    md = out_dir / f"{stem}.md"
    md.write_text("\n".join(L) + "\n")
    return png, md
