"""Load any reference data file: its kind is recognised from its columns (or, for a Garmin
G1000 log, its first line) and it is validated before anything runs."""
from __future__ import annotations

from pathlib import Path

from ..errors import DataError, Problem
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
            return log_dataset(path, geometry)
    raw = read_csv_checked(path)
    cols = {c.strip() for c in raw.columns}
    kind = kind or _kind_of(cols)
    if kind is None:
        raise DataError(path, [Problem("columns", "cannot tell the kind of data from the columns "
                                       f"{sorted(cols)}; expected a POH climb (kias, roc_fpm, ...), POH cruise "
                                       "(ktas, rpm/pct_power/gph, ...), flight-test snapshot or flap-climb file")])
    if kind in ("snapshot", "flap_climb"):
        return load_flight_test(path, raw, kind, control_travel)
    return load_poh(path, raw, kind)
