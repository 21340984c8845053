"""POH performance tables as reference data: maximum rate of climb and cruise.

A climb row is trimmed at full throttle, POH mixture procedure (full rich below the POH's
leaning altitude, best power above), at its KIAS converted to KCAS by the aircraft's airspeed
calibration, flight path free; a cruise row in level flight at its KTAS, best-power mixture,
the throttle trimming (a constant-speed propeller governs at the row's RPM). Temperature:
``oat_c``, or ISA + ``temp_dev_c``.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from ..flight.condition import Condition, TrimResult
from ..physics.atmosphere import kcas_from_kias
from ..physics.geometry import AircraftGeometry
from .schemas import Column, Dataset, Schema, reference_columns, validate_frame

POH_SCHEMAS: dict[str, Schema] = {
    "poh_climb": Schema(
        "poh_climb", "POH maximum rate of climb: full throttle at the given pressure altitude, temperature, KIAS",
        (Column("pressure_alt_ft", -2000, 30000, "ft"), Column("kias", 30, 250, "kt"),
         Column("weight_lb", 300, 20000, "lb"), Column("roc_fpm", -3000, 5000, "ft/min"),
         Column("oat_c", -70, 60, "deg C", required=False), Column("temp_dev_c", -60, 60, "deg C", required=False),
         Column("flaps_deg", 0, 50, "deg", required=False)),
        ("roc_fpm",), one_of=(("oat_c", "temp_dev_c"),)),
    "poh_cruise": Schema(
        "poh_cruise", "POH cruise: level flight at pressure altitude, temperature and KTAS",
        (Column("pressure_alt_ft", -2000, 30000, "ft"), Column("ktas", 30, 300, "kt"),
         Column("weight_lb", 300, 20000, "lb"), Column("rpm", 500, 4000, "rpm", required=False),
         Column("pct_power", 0, 130, "%", required=False), Column("gph", 0, 60, "US gal/h", required=False),
         Column("oat_c", -70, 60, "deg C", required=False), Column("temp_dev_c", -60, 60, "deg C", required=False),
         Column("flaps_deg", 0, 50, "deg", required=False)),
        ("rpm", "pct_power", "gph"), one_of=(("oat_c", "temp_dev_c"), ("rpm", "pct_power", "gph"))),
}

# the trim outputs the POH metrics compare
POH_VALUES = {"roc_fpm": "roc_fpm", "rpm": "rpm", "pct_power": "pct_power", "gph": "gph"}


def load_poh(path: Path, raw: pd.DataFrame, kind: str) -> Dataset:
    schema = POH_SCHEMAS[kind]
    frame = validate_frame(raw, schema, path)
    metrics = tuple(m for m in schema.metrics if m in frame.columns)
    return Dataset(kind, path, frame, reference_columns(raw), metrics)


def _temperature(row) -> dict:
    if "oat_c" in row and np.isfinite(row.get("oat_c", np.nan)):
        return {"oat_c": float(row["oat_c"])}
    return {"isa_dev_c": float(row.get("temp_dev_c", 0.0) or 0.0)}


def poh_climb_conditions(ds: Dataset, geom: AircraftGeometry) -> list[Condition]:
    """Full throttle, POH mixture procedure, KIAS -> KCAS by the aircraft's calibration, flight path free."""
    return [Condition(pressure_alt_ft=r.pressure_alt_ft, weight_lb=r.weight_lb,
                      kcas=kcas_from_kias(r.kias, geom.operations.airspeed_calibration),
                      mode="full_throttle", mixture="climb", flaps_deg=r.flaps_deg, **_temperature(r))
            for _, r in ds.frame.iterrows()]


def poh_cruise_conditions(ds: Dataset, geom: AircraftGeometry) -> list[Condition]:
    """Level flight at KTAS, throttle trims, best-power mixture."""
    return [Condition(pressure_alt_ft=r.pressure_alt_ft, weight_lb=r.weight_lb, ktas=r.ktas, mode="level",
                      flaps_deg=r.flaps_deg, rpm=r.get("rpm") if np.isfinite(r.get("rpm", np.nan)) else None,
                      **_temperature(r))
            for _, r in ds.frame.iterrows()]


def poh_value(metric: str, t: TrimResult) -> float:
    return getattr(t, POH_VALUES[metric])
