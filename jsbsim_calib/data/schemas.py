"""Reference data: columns, metrics with their tolerances, datasets, and up-front validation.

Every problem is reported at once with the file, the CSV line, the data row and the
column. Extra columns are ignored; ``thesis_model_*`` columns are kept aside as
comparison values, never as targets.
"""
from __future__ import annotations

import csv
import io
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from ..core.errors import DataError, Problem
from ..physics.atmosphere import isa_temperature_c
from .spreadsheet import read_sheet

# A temperature further than this from ISA at the row's pressure altitude is refused: the
# records are about +-40 deg C (the C172 POH's own climb table reaches ISA +45 at 10,000 ft);
# a Kelvin value (288) or a Fahrenheit one of a warm day (80 F at 8,000 ft: ISA +58) is not.
ISA_DEVIATION_LIMIT_C = 50.0


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
    # dynamic tests (Part 60; their data files state the same tolerances)
    "phugoid_period_s": Metric("phugoid_period_s", 0.10, relative=True, unit="s", doc="phugoid period"),
    "roll_rate_deg_s": Metric("roll_rate_deg_s", 2.0, unit="deg/s", doc="steady roll rate after a wheel step"),
    "max_pitch_rate_deg_s": Metric("max_pitch_rate_deg_s", 0.20, relative=True, unit="deg/s",
                                   doc="peak pitch rate after a column pulse"),
    "max_roll_rate_deg_s": Metric("max_roll_rate_deg_s", 0.20, relative=True, unit="deg/s",
                                  doc="peak roll rate after a wheel pulse"),
    "max_yaw_rate_deg_s": Metric("max_yaw_rate_deg_s", 0.20, relative=True, unit="deg/s",
                                 doc="peak yaw rate after a pedal pulse"),
    "response_time_s": Metric("response_time_s", 1.0, unit="s",
                              doc="engine acceleration: RPM from 10 % to 90 % of its response to the throttle"),
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


def field_count_problems(path: Path, text: str | None = None) -> list[Problem]:
    """Lines whose number of fields differs from the header's (a row cut short, or shifted)."""
    if text is None:
        try:
            text = Path(path).read_text()
        except (OSError, UnicodeDecodeError):
            return []                           # read_csv says what is wrong with the file
    rows = [r for r in csv.reader(io.StringIO(text))]
    if not rows:
        return []
    if text and not text.endswith(("\n", "\r")):
        warnings.warn(f"{path}: the last line has no line end: the file may be cut short (line {len(rows)})",
                      stacklevel=3)
    n = len(rows[0])
    out = [Problem(f"line {i + 2} (row {i + 1})", f"{len(r)} fields, the header has {n} (a row cut short or shifted"
                   + ("; decimal commas in a comma-separated file?)" if len(r) > n else ")"))
           for i, r in enumerate(rows[1:]) if r and len(r) != n]
    return out[:10] + ([Problem("", f"and {len(out) - 10} more such rows")] if len(out) > 10 else [])


def read_csv_checked(path: Path) -> pd.DataFrame:
    """A data table as text cells (:func:`.spreadsheet.read_sheet`: any separator, decimal
    commas, a BOM, UTF-16, header case); DataError naming every line it cannot read."""
    if Path(path).is_dir():
        raise DataError(path, "is a folder; give a data file")
    sheet = read_sheet(Path(path))
    problems = field_count_problems(path, sheet.text)
    if problems:
        raise DataError(path, problems)
    try:
        return pd.read_csv(io.StringIO(sheet.text), dtype=str, keep_default_na=False, skipinitialspace=True)
    except (pd.errors.ParserError, pd.errors.EmptyDataError) as exc:
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
    problems += temperature_problems(out) + duplicate_rows(raw)
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


def temperature_problems(frame: pd.DataFrame, place=None) -> list[Problem]:
    """Temperatures more than :data:`ISA_DEVIATION_LIMIT_C` from ISA at the row's pressure
    altitude (``oat_c``), or ISA deviations beyond it (``temp_dev_c``); ``place(i, column)``
    names a row (default: CSV line and row)."""
    place = place or (lambda i, c: f"line {i + 2} (row {i + 1}), column '{c}'")
    out = []
    hp = frame["pressure_alt_ft"].to_numpy(float) if "pressure_alt_ft" in frame else np.full(len(frame), np.nan)
    if "oat_c" in frame:
        oat = frame["oat_c"].to_numpy(float)
        dev = oat - np.asarray(isa_temperature_c(np.nan_to_num(hp)), float)
        for i in np.flatnonzero(np.isfinite(oat) & np.isfinite(hp) & (np.abs(dev) > ISA_DEVIATION_LIMIT_C)):
            out.append(Problem(place(i, "oat_c"), f"{oat[i]:g} deg C is ISA {dev[i]:+.0f} deg C at {hp[i]:g} ft: more "
                               f"than {ISA_DEVIATION_LIMIT_C:g} deg C from standard (Kelvin or Fahrenheit?)"))
    if "temp_dev_c" in frame:
        dev = frame["temp_dev_c"].to_numpy(float)
        for i in np.flatnonzero(np.isfinite(dev) & (np.abs(dev) > ISA_DEVIATION_LIMIT_C)):
            out.append(Problem(place(i, "temp_dev_c"), f"ISA {dev[i]:+g} deg C is more than {ISA_DEVIATION_LIMIT_C:g} "
                                                       "deg C from standard"))
    return out


def duplicate_rows(raw: pd.DataFrame, labels=None) -> list[Problem]:
    """Rows identical to an earlier row in every column (a duplicate counts twice in fits and
    summaries); ``labels``: the rows' names (default 'row N')."""
    seen: dict[tuple, int] = {}
    out = []
    cells = raw.astype(str).apply(lambda c: c.str.strip())
    for i, row in enumerate(cells.itertuples(index=False, name=None)):
        if all(v == "" for v in row):
            continue
        j = seen.setdefault(row, i)
        if j != i:
            name = (lambda k: f"row {k + 1}") if labels is None else (lambda k: labels[k])
            out.append(Problem(f"line {i + 2} ({name(i)})", f"duplicates line {j + 2} ({name(j)}): a duplicated row "
                                                             "counts twice in fits and summaries; remove one"))
    return out


def reference_columns(raw: pd.DataFrame, rows=None) -> pd.DataFrame:
    """The ``thesis_model_*`` columns of a raw file (comparison values, never targets), of
    ``rows`` (a boolean mask) or all rows."""
    cols = [c for c in raw.columns if c.strip().startswith("thesis_model_")]
    if rows is None:
        return raw[cols].copy()
    return raw.loc[rows, cols].reset_index(drop=True)
