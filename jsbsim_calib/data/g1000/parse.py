"""Garmin G1000 flight-log import.

A G1000 log (one CSV file per power-on, written to the SD card of the MFD) looks like::

    #airframe_info, log_version="1.00", airframe_name="Cessna 172S", ..., system_id="24B6FD7AC", ...
    #yyy-mm-dd, hh:mm:ss,   hh:mm,  ident,      degrees,      degrees, ft Baro,  inch, ...
      Lcl Date, Lcl Time, UTCOfst, AtvWpt,     Latitude,    Longitude,    AltB, BaroA, ...
    2011-08-12, 09:59:07,  -05:00,       ,   47.8413467,  -96.6191635,   861.5, 29.83, ...

``read_g1000`` turns it into a :class:`G1000Log` (airframe record, units, and a DataFrame with a
``time_s`` column); :mod:`.segments` finds the quasi-steady stretches in it, and
:func:`jsbsim_calib.report.plots.plot_log` draws it.

Repeated timestamps
-------------------
The recorder writes about one row per second (3966 rows in 4038 s in the example log) but
stamps each row with the whole second of its clock, so rows drift against the clock: 728 rows
(18 %) repeat the second of the row before, and about 800 seconds have no row (steps of 0,
1 and 2 s alternate). The rows sharing a second are distinct samples (attitude, RPM and
vertical speed differ), so all rows are kept, and ``time_s`` spaces the ``n`` rows that share
a second evenly inside it (``s, s + 1/n, ...``). Averaging them instead would throw away 18 %
of the samples, understate the noise estimates used for weighting, and leave a 2 s hole
next to each repeat; spacing keeps time strictly increasing with an error below one second,
which is small against the 30 s or more of a segment.
"""
from __future__ import annotations

import re
import warnings
from dataclasses import dataclass
from datetime import datetime
from pathlib import Path
from typing import IO, Any

import numpy as np
import pandas as pd

from ...core.errors import DataError, Problem
from ..spreadsheet import decode

__all__ = [
    "G1000Log",
    "G1000DataWarning",
    "REQUIRED_CHANNELS",
    "read_g1000",
]


class G1000DataWarning(UserWarning):
    """A recoverable problem in a G1000 log (a dropped line, an unreadable cell)."""


# --------------------------------------------------------------------------------------------
# Import
# --------------------------------------------------------------------------------------------

#: Channels a log must have for the calibration. TAS is not required: it is computed from
#: AltB, BaroA, OAT and IAS (all required) by :func:`ktas_from_kcas`.
REQUIRED_CHANNELS: tuple[str, ...] = (
    "AltB", "BaroA", "OAT", "IAS", "VSpd", "Pitch", "Roll",
    "E1 RPM", "E1 FFlow", "FQtyL", "FQtyR",
)

_TIME_COLUMNS = ("Lcl Date", "Lcl Time")
_STRING_COLUMNS = frozenset({"Lcl Date", "Lcl Time", "UTCOfst"})

#: Units accepted for channels the calibration reads (lower case, single spaces). A units
#: line naming anything else for these channels is an error: the numbers would be misread.
_ACCEPTED_UNITS: dict[str, frozenset[str]] = {
    "AltB": frozenset({"ft baro", "ft"}),
    "BaroA": frozenset({"inch", "inhg", "in hg", "in"}),
    "OAT": frozenset({"deg c", "degc", "c"}),
    "IAS": frozenset({"kt", "kts", "knots"}),
    "TAS": frozenset({"kt", "kts", "knots"}),
    "GndSpd": frozenset({"kt", "kts", "knots"}),
    "VSpd": frozenset({"fpm", "ft/min"}),
    "Pitch": frozenset({"deg"}),
    "Roll": frozenset({"deg"}),
    "E1 RPM": frozenset({"rpm"}),
    "E1 FFlow": frozenset({"gph"}),
    "FQtyL": frozenset({"gals", "gal"}),
    "FQtyR": frozenset({"gals", "gal"}),
}

_MAX_LINE_WARNINGS = 20
_HEADER_SEARCH_LINES = 50


@dataclass(frozen=True, eq=False)
class G1000Log:
    """One imported G1000 log.

    ``data`` holds one row per logged sample with a float ``time_s`` column [s] (seconds since
    the first valid row, rows sharing a clock second spaced evenly inside it), the numeric
    channels as float columns named as in the log without surrounding blanks (``AltB`` [ft],
    ``BaroA`` [inHg], ``OAT`` [deg C], ``IAS``/``TAS``/``GndSpd`` [kt], ``VSpd`` [ft/min],
    ``Pitch``/``Roll`` [deg], ``E1 RPM`` [rpm], ``E1 FFlow`` [US gal/h], ``FQtyL``/``FQtyR``
    [US gal], ...) and the text channels (``Lcl Date``, ``Lcl Time``, ``AtvWpt``, ``HSIS``,
    ``GPSfix``, ...) as strings. Blank cells are NaN.
    """

    path: str                   # file name, or "<stream>" for an unnamed text stream
    airframe: dict[str, str]    # the #airframe_info record: airframe_name, system_id, ...
    units: dict[str, str]       # column -> unit from the units line ({} when it is missing)
    data: pd.DataFrame          # samples; time_s [s] since the first valid row
    start_time: datetime | None = None  # local date and time of the first valid row

    @property
    def duration_s(self) -> float:
        """Time from the first to the last row [s]."""
        if self.data.empty:
            return 0.0
        return float(self.data["time_s"].iloc[-1] - self.data["time_s"].iloc[0])


def _split(line: str) -> list[str]:
    return [f.strip() for f in line.split(",")]


def _parse_airframe(line: str) -> dict[str, str]:
    body = line.split(",", 1)[1] if "," in line else ""
    out: dict[str, str] = {}
    for m in re.finditer(r'([A-Za-z_][\w.]*)\s*=\s*(?:"([^"]*)"|([^,]*))', body):
        value = m.group(2) if m.group(2) is not None else m.group(3)
        out[m.group(1)] = value.strip()
    return out


def _read_text(source: str | Path | IO[str]) -> tuple[str, str]:
    if hasattr(source, "read"):
        text = source.read()  # type: ignore[union-attr]
        if isinstance(text, bytes):
            text = text.decode("utf-8-sig", errors="replace")
        name = str(getattr(source, "name", "<stream>"))
        return name, text.lstrip("\ufeff")
    path = Path(source)  # type: ignore[arg-type]
    try:
        raw = path.read_bytes()
    except OSError as exc:
        raise DataError(path, [Problem("", f"cannot read file: {exc.strerror or exc}")]) from exc
    try:
        return str(path), decode(path, raw)     # UTF-8, a byte-order mark, UTF-16
    except DataError as exc:                    # a stray byte: kept readable, as before, and said
        warnings.warn(f"{path}: {exc.problems[0]}; read with the byte replaced", G1000DataWarning, stacklevel=3)
        return str(path), raw.decode("utf-8-sig", errors="replace")


def _warn_lines(source: str, messages: list[str]) -> None:
    for msg in messages[:_MAX_LINE_WARNINGS]:
        warnings.warn(f"{source}: {msg}", G1000DataWarning, stacklevel=3)
    if len(messages) > _MAX_LINE_WARNINGS:
        warnings.warn(f"{source}: ... and {len(messages) - _MAX_LINE_WARNINGS} more such problems",
                      G1000DataWarning, stacklevel=3)


def _lines(text: str) -> list[str]:
    lines = text.split("\n")
    ends_with_newline = text.endswith("\n")
    lines = [ln[:-1] if ln.endswith("\r") else ln for ln in lines]
    return lines[:-1] if ends_with_newline else lines


@dataclass
class _Preamble:
    """What precedes the data rows: the airframe record, the '#' lines, the column header."""

    airframe: dict[str, str]
    comment_lines: list[tuple[int, str]]       # (index, text) of '#' lines before the header
    header_idx: int
    header: list[str]


def _preamble(name: str, lines: list[str]) -> _Preamble:
    airframe: dict[str, str] = {}
    airframe_seen = False
    comment_lines: list[tuple[int, str]] = []
    for idx, line in enumerate(lines[:_HEADER_SEARCH_LINES]):
        stripped = line.strip()
        if not stripped:
            continue
        if stripped.startswith("#"):
            if stripped.lower().startswith("#airframe_info"):
                airframe_seen = True
                airframe = _parse_airframe(stripped)
            else:
                comment_lines.append((idx, stripped))
            continue
        fields = _split(stripped)
        if "Lcl Date" in fields and "Lcl Time" in fields:
            header = fields[:-1] if len(fields) > 1 and fields[-1] == "" else fields    # a trailing comma
            return _Preamble(airframe, comment_lines, idx, header)
        if not airframe_seen:
            break  # the first real line of a G1000 log is the airframe, units or header line
    if airframe_seen:
        msg = "no column header line with 'Lcl Date' and 'Lcl Time' after '#airframe_info'"
    else:
        msg = ("not a Garmin G1000 log: no '#airframe_info' line and no column header "
               "with 'Lcl Date' and 'Lcl Time'")
    raise DataError(name, [Problem("", msg)])


def _header_problems(pre: _Preamble) -> list[Problem]:
    problems: list[Problem] = []
    seen: set[str] = set()
    for col in pre.header:
        if col == "":
            problems.append(Problem(f"line {pre.header_idx + 1}", "empty column name in the header"))
        elif col in seen:
            problems.append(Problem(f"line {pre.header_idx + 1}", f"column {col!r} appears twice"))
        seen.add(col)
    missing = [c for c in REQUIRED_CHANNELS if c not in seen]
    if missing:
        problems.append(Problem(f"line {pre.header_idx + 1}",
                                "missing required channel(s): " + ", ".join(missing)))
    return problems


def _units(pre: _Preamble, problems: list[Problem], line_warnings: list[str]) -> dict[str, str]:
    """Units of the columns from the '#' line before the header (the last one), checked for the
    channels the calibration reads."""
    if not pre.comment_lines:
        return {}
    n_fields = len(pre.header)
    u_idx, u_line = pre.comment_lines[-1]
    u_fields = _split(u_line[1:])
    if len(u_fields) == n_fields + 1 and u_fields[-1] == "":
        u_fields = u_fields[:-1]
    if len(u_fields) != n_fields:
        line_warnings.append(f"line {u_idx + 1}: units line has {len(u_fields)} fields, header "
                             f"has {n_fields}; units matched by position where possible")
    units = {col: u for col, u in zip(pre.header, u_fields) if col}
    for col, accepted in _ACCEPTED_UNITS.items():
        unit = " ".join(units.get(col, "").lower().split())
        if unit and unit not in accepted:
            problems.append(Problem(f"line {u_idx + 1}, column {col}",
                                    f"unit {units[col]!r}, expected one of {sorted(accepted)}"))
    return units


def _data_rows(lines: list[str], pre: _Preamble, line_warnings: list[str]) -> tuple[list[list[str]], list[int]]:
    """The rows with the header's number of fields, and their line numbers."""
    n_fields = len(pre.header)
    last_nonblank = max((i for i, ln in enumerate(lines) if ln.strip()), default=-1)
    rows: list[list[str]] = []
    row_lines: list[int] = []
    for idx in range(pre.header_idx + 1, len(lines)):
        line = lines[idx]
        stripped = line.strip()
        if not stripped or stripped.startswith("#"):
            continue
        fields = _split(line)
        if len(fields) == n_fields + 1 and fields[-1] == "":
            fields = fields[:-1]
        if len(fields) != n_fields:
            if idx == last_nonblank and len(fields) < n_fields:
                line_warnings.append(f"line {idx + 1}: last line is truncated ({len(fields)} of "
                                     f"{n_fields} fields); row dropped")
            else:
                line_warnings.append(f"line {idx + 1}: {len(fields)} fields, expected {n_fields}; "
                                     "row dropped")
            continue
        rows.append(fields)
        row_lines.append(idx + 1)
    return rows, row_lines


def _clock(frame: pd.DataFrame, line_no: np.ndarray, line_warnings: list[str]):
    """Timestamps of the rows: (the timestamps, seconds since the first, rows to keep), dropping
    rows whose date/time is unreadable or whose clock steps backwards."""
    stamp = (frame["Lcl Date"].fillna("").astype(str) + " "
             + frame["Lcl Time"].fillna("").astype(str))
    ts = pd.to_datetime(stamp, format="ISO8601", errors="coerce")
    bad = ts.isna().to_numpy()
    for k in np.flatnonzero(bad):
        line_warnings.append(f"line {line_no[k]}: unreadable date/time {stamp.iloc[k].strip()!r}; "
                             "row dropped")
    keep = ~bad
    # clock stepping backwards: drop rows until it passes the last good time again
    secs = np.full(len(ts), np.nan)
    secs[keep] = (ts[keep] - ts[keep].iloc[0]).dt.total_seconds().to_numpy() if keep.any() else []
    running = -np.inf
    for k in range(len(secs)):
        if not keep[k]:
            continue
        if secs[k] < running:
            keep[k] = False
            line_warnings.append(f"line {line_no[k]}: time {stamp.iloc[k].strip()} is earlier than "
                                 "the row before; row dropped")
        else:
            running = secs[k]
    return ts, secs, keep


def _spread_seconds(secs: np.ndarray) -> np.ndarray:
    """Seconds since the first row, the rows that share a second spread evenly inside it."""
    group = np.concatenate([[0], np.cumsum(np.diff(secs) != 0)])
    pos = pd.Series(np.arange(len(secs))).groupby(group).cumcount().to_numpy()
    size = np.bincount(group)[group]
    return secs + pos / size


def _channels(frame: pd.DataFrame, header: list[str], line_no: np.ndarray, time_s: np.ndarray,
              line_warnings: list[str]) -> dict[str, Any]:
    """The columns as floats where they are numbers (a few unreadable cells become NaN), as
    text otherwise."""
    out: dict[str, Any] = {"time_s": time_s.astype(float)}
    for col in header:
        cells = frame[col]
        if col in _STRING_COLUMNS:
            out[col] = cells.astype(object)
            continue
        num = pd.to_numeric(cells, errors="coerce")
        unreadable = (cells.notna() & num.isna()).to_numpy()
        if not unreadable.any():
            out[col] = num.astype(float).to_numpy()
        elif col in _ACCEPTED_UNITS or unreadable.sum() <= 0.01 * cells.notna().sum():
            for k in np.flatnonzero(unreadable):
                line_warnings.append(f"line {line_no[k]}, column {col}: unreadable number "
                                     f"{cells.iloc[k]!r}; set to NaN")
            out[col] = num.astype(float).to_numpy()
        else:
            out[col] = cells.astype(object)
    return out


def read_g1000(source: str | Path | IO[str]) -> G1000Log:
    """Read a Garmin G1000 CSV flight log from a file path or a text stream.

    Tolerated, with a :class:`G1000DataWarning` naming the line where something is dropped:
    blank cells (NaN), blanks around cells, blank lines, a missing units line, a trailing comma,
    rows sharing a timestamp (see the module docstring), a truncated last line (dropped), rows
    with the wrong number of fields or an unreadable date/time (dropped), rows whose clock steps
    backwards (dropped), unreadable numbers in a numeric channel (NaN).

    Raises :class:`DataError` listing every problem when the input is empty, is not a G1000 log
    (no ``#airframe_info`` line and no column header with ``Lcl Date`` and ``Lcl Time``), lacks
    required channels (all listed, see :data:`REQUIRED_CHANNELS`), states units other than the
    expected ones for a required channel, or has no valid data row.
    """
    name, text = _read_text(source)
    if not text.strip():
        raise DataError(name, [Problem("", "file is empty")])
    lines = _lines(text)
    pre = _preamble(name, lines)
    problems = _header_problems(pre)
    line_warnings: list[str] = []
    units = _units(pre, problems, line_warnings)
    if problems:
        raise DataError(name, problems)

    rows, row_lines = _data_rows(lines, pre, line_warnings)
    frame = pd.DataFrame(rows, columns=pre.header, dtype=object)
    frame = frame.replace("", np.nan)
    line_no = np.asarray(row_lines, dtype=int)
    ts, secs, keep = _clock(frame, line_no, line_warnings)
    _warn_lines(name, line_warnings)

    frame = frame.loc[keep].reset_index(drop=True)
    secs = secs[keep]
    line_no = line_no[keep]
    if frame.empty:
        raise DataError(name, [Problem("", "no valid data rows")])
    ts = ts[keep].reset_index(drop=True)
    start_time = ts.iloc[0].to_pydatetime()
    time_s = _spread_seconds(secs - secs[0])

    line_warnings = []
    data = pd.DataFrame(_channels(frame, pre.header, line_no, time_s, line_warnings))
    _warn_lines(name, line_warnings)
    for col in REQUIRED_CHANNELS:
        if data[col].isna().all():
            warnings.warn(f"{name}: required channel {col!r} has no values", G1000DataWarning,
                          stacklevel=2)
    return G1000Log(path=name, airframe=pre.airframe, units=units, data=data, start_time=start_time)
