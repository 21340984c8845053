"""Load any reference data file: its kind is recognised from its columns (or, for a Garmin
G1000 log, its first line) and it is validated before anything runs."""
from __future__ import annotations

from pathlib import Path

from ..core.errors import DataError, Problem, raise_if
from .column_units import declared_units, unit_problems
from .envelope import check_envelope
from .flighttest import load_flight_test
from .logs import log_dataset
from .poh import load_poh
from .schemas import Dataset, read_csv_checked


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


def load_dataset(path: str | Path, kind: str | None = None, *, control_travel: str | Path | None = None,
                 geometry=None) -> Dataset:
    """Load and validate a data file of any kind.

    ``control_travel``: the aircraft's control-travel table; with it, flight-test snapshots
    are also checked for surfaces that disagree with their cockpit controls. ``geometry``:
    the aircraft, needed for a G1000 log (its empty weight enters the weight estimate); with
    it, every row is checked against the aircraft's envelope (:mod:`.envelope`).
    """
    path = Path(path)
    if path.is_dir():
        raise DataError(path, "is a folder; give a data file")
    ds = _load(path, kind, control_travel, geometry)
    if ds.kind != "g1000":
        raise_if(unit_problems(ds.frame, ds.kind, geometry), path, DataError)
    if geometry is not None:
        check_envelope(ds.frame, geometry, path, _places(ds))
    return ds


def _places(ds: Dataset):
    """Names of a row's place in its file, by the kind of data."""
    f = ds.frame
    if ds.kind == "g1000":
        return lambda i, c: (f"segment {f['segment'].iloc[i]} ({f['kind'].iloc[i]}, t {f['t_start_s'].iloc[i]:.0f}-"
                             f"{f['t_end_s'].iloc[i]:.0f} s), column '{c}'")
    if "line" in f:
        return lambda i, c: f"line {f['line'].iloc[i]} ({f['table'].iloc[i]}), column '{c}'"
    return lambda i, c: f"line {i + 2} (row {i + 1}), column '{c}'"


def _is_g1000_log(path: Path) -> bool:
    """A Garmin G1000 log: its first line is '#airframe_info', or (the line lost) its header
    names 'Lcl Date' and 'Lcl Time'; a byte-order mark or UTF-16 as any CSV."""
    with open(path, "rb") as fh:
        head = fh.read(4096)
    utf16 = head.startswith((b"\xff\xfe", b"\xfe\xff"))
    text = head.decode("utf-16" if utf16 else "utf-8-sig", errors="ignore").lstrip()
    first = text.splitlines()[:3]
    return text.startswith("#airframe_info") or any("Lcl Date" in ln and "Lcl Time" in ln for ln in first)


def _load(path: Path, kind: str | None, control_travel, geometry) -> Dataset:
    if path.is_file() and _is_g1000_log(path):
            if geometry is None:
                raise DataError(path, "a G1000 log is evaluated for an aircraft: its empty weight enters the "
                                      "weight estimate (pass geometry=...)")
            return log_dataset(path, geometry)
    raw, problems = declared_units(read_csv_checked(path))
    raise_if(problems, path, DataError)
    cols = {c.strip() for c in raw.columns}
    kind = kind or _kind_of(cols)
    if kind is None:
        raise DataError(path, [Problem("columns", "cannot tell the kind of data from the columns "
                                       f"{sorted(cols)}; expected a POH climb (kias, roc_fpm, ...), POH cruise "
                                       "(ktas, rpm/pct_power/gph, ...), flight-test snapshot or flap-climb file")])
    if kind in ("snapshot", "flap_climb"):
        return load_flight_test(path, raw, kind, control_travel)
    return load_poh(path, raw, kind)
