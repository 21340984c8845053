"""Reference data: schemas, loading and up-front validation.

A data file is recognised by its columns (or, for a Garmin G1000 log, its first line).
Every problem is reported at once with the file, the CSV line, the data row and the
column. Extra columns are ignored; ``thesis_model_*`` columns are kept aside as
comparison values, never as targets.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from .errors import DataError, Problem


@dataclass(frozen=True)
class Column:
    name: str
    lo: float
    hi: float
    unit: str
    required: bool = True


@dataclass(frozen=True)
class Metric:
    """A compared quantity: CSV column name, tolerance, and whether it is relative."""

    name: str
    tolerance: float
    relative: bool = False
    unit: str = ""
    doc: str = ""

    def tol_for(self, reference: float) -> float:
        return self.tolerance * abs(reference) if self.relative else self.tolerance


METRICS: dict[str, Metric] = {
    "roc_fpm": Metric("roc_fpm", 100.0, unit="ft/min", doc="rate of climb (geometric dh/dt)"),
    "rpm": Metric("rpm", 50.0, unit="rpm", doc="engine speed"),
    "pct_power": Metric("pct_power", 5.0, unit="% rated", doc="power, percent of rated"),
    "gph": Metric("gph", 0.05, relative=True, unit="US gal/h", doc="fuel flow (+-5 %)"),
    "pitch_deg": Metric("pitch_deg", 1.0, unit="deg", doc="pitch attitude"),
    "elevator_deg": Metric("elevator_deg", 1.0, unit="deg", doc="elevator, data sign (+ trailing edge up)"),
    "aileron_deg": Metric("aileron_deg", 1.0, unit="deg", doc="aileron, data sign (+ right trailing edge up)"),
    "rudder_deg": Metric("rudder_deg", 1.0, unit="deg", doc="rudder, data sign (+ trailing edge right)"),
}


@dataclass(frozen=True)
class Schema:
    kind: str
    description: str
    columns: tuple[Column, ...]
    metrics: tuple[str, ...]
    one_of: tuple[tuple[str, ...], ...] = ()      # at least one of these columns must be present

    def column(self, name: str) -> Column | None:
        for c in self.columns:
            if c.name == name:
                return c
        return None


SCHEMAS: dict[str, Schema] = {
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


def _kind_of(columns: set[str]) -> str | None:
    if {"vs_fpm", "pitch_deg"} <= columns:
        return "snapshot"
    if "roc_fpm" in columns and "ktas" in columns:
        return "flap_climb"
    if "roc_fpm" in columns:
        return "poh_climb"
    if "ktas" in columns or ({"rpm", "pct_power", "gph"} & columns):
        return "poh_cruise"
    return None


@dataclass
class Dataset:
    """Validated reference data of one kind."""

    kind: str
    path: Path
    frame: pd.DataFrame                      # schema columns, numeric, ISA marker resolved
    reference: pd.DataFrame                  # thesis_model_* columns (comparison only)
    metrics: tuple[str, ...]
    extra: dict = field(default_factory=dict)

    def __len__(self) -> int:
        return len(self.frame)


def read_csv_checked(path: Path) -> pd.DataFrame:
    try:
        return pd.read_csv(path, dtype=str, keep_default_na=False, skipinitialspace=True)
    except FileNotFoundError:
        raise DataError(path, "file not found") from None
    except (pd.errors.ParserError, UnicodeDecodeError, pd.errors.EmptyDataError) as exc:
        raise DataError(path, f"not a readable CSV file: {exc}") from None


def validate_frame(raw: pd.DataFrame, schema: Schema, path: Path) -> pd.DataFrame:
    """Check columns and values; return the schema columns as floats. Raises DataError listing all problems."""
    problems: list[Problem] = []
    cols = {c.strip() for c in raw.columns}
    raw = raw.rename(columns=lambda c: c.strip())
    for c in schema.columns:
        if c.required and c.name not in cols:
            problems.append(Problem(f"column '{c.name}'", f"missing (needed: {c.unit})"))
    for group in schema.one_of:
        if not (set(group) & cols):
            problems.append(Problem("columns", f"need at least one of {', '.join(group)}"))
    out = pd.DataFrame(index=raw.index)
    for c in schema.columns:
        if c.name not in cols:
            continue
        values = []
        for i, text in enumerate(raw[c.name].astype(str)):
            where = f"line {i + 2} (row {i + 1}), column '{c.name}'"
            t = text.strip()
            if t == "":
                problems.append(Problem(where, "empty (NaN)"))
                values.append(np.nan)
                continue
            if t.upper() == "ISA" and c.name in ("oat_c", "temp_dev_c"):
                values.append(np.nan)        # resolved below: standard temperature
                continue
            try:
                v = float(t)
            except ValueError:
                problems.append(Problem(where, f"'{t}' is not a number"))
                values.append(np.nan)
                continue
            if not np.isfinite(v):
                problems.append(Problem(where, f"'{t}' is not finite"))
            elif not c.lo <= v <= c.hi:
                problems.append(Problem(where, f"{v:g} {c.unit} is outside the plausible range [{c.lo:g}, {c.hi:g}]"))
            values.append(v)
        out[c.name] = values
    if not len(raw):
        problems.append(Problem("", "no data rows"))
    if problems:
        raise DataError(path, problems)
    # 'ISA' in an OAT column means standard temperature: ISA deviation 0
    if "oat_c" in out and raw["oat_c"].astype(str).str.strip().str.upper().eq("ISA").any():
        isa = raw["oat_c"].astype(str).str.strip().str.upper().eq("ISA").to_numpy()
        if isa.all():
            out = out.drop(columns="oat_c")
            out["temp_dev_c"] = 0.0
        else:
            out.loc[isa, "oat_c"] = np.nan
            out["temp_dev_c"] = np.where(isa, 0.0, np.nan)
    if "flaps_deg" not in out:
        out["flaps_deg"] = 0.0
    return out


def load_dataset(path: str | Path, kind: str | None = None, *, control_travel: str | Path | None = None,
                 geometry=None) -> Dataset:
    """Load and validate a data file of any kind.

    ``control_travel``: the aircraft's control-travel table; with it, flight-test snapshots
    are also checked for surfaces that disagree with their cockpit controls. ``geometry``:
    the aircraft, needed for a G1000 log (its empty weight enters the weight estimate).
    """
    path = Path(path)
    if path.is_file():
        with open(path, "rb") as fh:
            head = fh.read(64)
        if head.lstrip().startswith(b"#airframe_info"):
            if geometry is None:
                raise DataError(path, "a G1000 log is evaluated for an aircraft: its empty weight enters the "
                                      "weight estimate (pass geometry=...)")
            from .logs import log_dataset
            return log_dataset(path, geometry)
    raw = read_csv_checked(path)
    cols = {c.strip() for c in raw.columns}
    kind = kind or _kind_of(cols)
    if kind is None:
        raise DataError(path, [Problem("columns", "cannot tell the kind of data from the columns "
                                       f"{sorted(cols)}; expected a POH climb (kias, roc_fpm, ...), POH cruise "
                                       "(ktas, rpm/pct_power/gph, ...), flight-test snapshot or flap-climb file")])
    if kind in ("snapshot", "flap_climb"):
        from .flighttest import load_flight_test
        return load_flight_test(path, raw, kind, control_travel)
    schema = SCHEMAS[kind]
    frame = validate_frame(raw, schema, path)
    ref = raw[[c for c in raw.columns if c.strip().startswith("thesis_model_")]].copy()
    metrics = tuple(m for m in schema.metrics if m in frame.columns)
    return Dataset(kind, path, frame, ref, metrics)
