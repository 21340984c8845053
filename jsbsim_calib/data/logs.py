"""Garmin G1000 logs as reference data: segments -> trim conditions -> evaluation.

A log is read and cut into quasi-steady segments by :mod:`jsbsim_calib.data.g1000` (criteria in
:class:`~jsbsim_calib.data.g1000.segments.SegmentCriteria`). Each segment becomes one data point:

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

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from ..jsbsim.condition import Condition, TrimResult
from ..physics.geometry import AircraftGeometry
from ..units import LBM
from .g1000.parse import read_g1000
from .g1000.segments import SegmentCriteria, WeightAssumption, extract_segments, segments_dataframe
from .schemas import Dataset

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
    weight = WeightAssumption(empty_weight_lb=geometry.mass.empty_mass_kg / LBM,
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


# the trim outputs a log's metrics compare (the G1000's VSpd is the pressure-altitude rate)
LOG_VALUES = {"rpm": "rpm", "roc_fpm": "roc_pressure_fpm", "pitch_deg": "theta_deg"}


def log_value(metric: str, t: TrimResult) -> float:
    return getattr(t, LOG_VALUES[metric])
