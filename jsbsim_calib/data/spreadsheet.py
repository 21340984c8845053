"""Spreadsheet exports: the one place a data file's bytes become comma-separated text.

Every CSV loader (POH tables, flight-test snapshots and climbs, time histories, G1000 logs)
reads its file through :func:`decode` (UTF-8 with or without a byte-order mark, UTF-16 with a
byte-order mark or plainly little-endian; anything else refused naming the line and byte) and,
for tables, :func:`read_sheet`: the separator is the one of ``,`` ``;`` TAB that the header
line uses most; in a ``;`` or TAB file a decimal comma (``1,5``, German Excel) is read as a
decimal point, and a dotted number there (``1.234``: a thousands separator or a decimal point?)
is refused naming its line and column; header names are stripped and lower-cased; a header
named twice is refused naming both columns. A plain comma-separated UTF-8 file comes back as
its own text, so its reading does not change.
"""
from __future__ import annotations

import codecs
import csv
import io
import re
from dataclasses import dataclass
from pathlib import Path

from ..core.errors import DataError, Problem

SEPARATORS = {",": "comma", ";": "semicolon", "\t": "tab"}
_DECIMAL_COMMA = re.compile(r"[+-]?\d*,\d+(?:[eE][+-]?\d+)?")
_THOUSANDS_DOT = re.compile(r"[+-]?\d{1,3}(?:\.\d{3})+")
_THOUSANDS_DOT_DECIMAL_COMMA = re.compile(r"[+-]?\d{1,3}(?:\.\d{3})+,\d+")


@dataclass(frozen=True)
class Sheet:
    """A table as comma-separated text with decimal points and normalised header names."""

    text: str
    separator: str            # what the file used: ',', ';' or '\t'
    decimal_comma: bool       # the file wrote decimal commas (read as points)


def decode(path: Path, data: bytes) -> str:
    """The file's text: UTF-8 (a byte-order mark dropped) or UTF-16; else a DataError naming
    the line and the byte that is not UTF-8."""
    try:
        if data.startswith((codecs.BOM_UTF16_LE, codecs.BOM_UTF16_BE)):
            return data.decode("utf-16")
        if len(data) >= 8 and data[1:64:2].count(0) == len(data[1:64:2]) and data[0:64:2].count(0) == 0:
            return data.decode("utf-16-le")          # UTF-16 without its mark (every second byte 0)
    except UnicodeDecodeError as exc:
        raise DataError(path, f"UTF-16 text that cannot be decoded ({exc.reason}); save it as 'CSV UTF-8'") from None
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        line = data[:exc.start].count(b"\n") + 1
        col = exc.start - (data.rfind(b"\n", 0, exc.start) + 1) + 1
        raise DataError(path, Problem(f"line {line}, column {col}", f"byte 0x{data[exc.start]:02x} is not UTF-8 text "
                                      "(a Latin-1/Windows-1252 export?); save the file as 'CSV UTF-8'")) from None


def read_text(path: Path) -> str:
    """:func:`decode` of a file; a missing or unreadable file is a DataError naming it."""
    try:
        return decode(path, Path(path).read_bytes())
    except FileNotFoundError:
        raise DataError(path, "file not found") from None
    except IsADirectoryError:
        raise DataError(path, "is a folder; give a data file") from None
    except OSError as exc:
        raise DataError(path, f"cannot read: {exc.strerror or exc}") from None


def separator_of(header: str) -> str:
    """The separator the header line uses most (comma when it uses none)."""
    counts = {s: header.count(s) for s in SEPARATORS}
    best = max(counts, key=lambda s: (counts[s], s == ","))
    return best if counts[best] else ","


def read_sheet(path: Path, text: str | None = None) -> Sheet:
    """The file as comma-separated text with decimal points and lower-case header names
    (see the module docstring); DataError listing every cell or header it cannot read."""
    text = read_text(path) if text is None else text
    first = next((ln for ln in text.splitlines() if ln.strip()), "")
    sep = separator_of(first)
    rows = list(csv.reader(io.StringIO(text), delimiter=sep))
    if not rows:
        return Sheet(text, sep, False)
    header = [h.strip().lower() for h in rows[0]]
    problems = duplicate_header_problems(header)
    body, decimal_comma = rows[1:], False
    if sep != ",":
        body, decimal_comma, bad = _decimal_points(body, header, SEPARATORS[sep])
        problems += bad
    if problems:
        raise DataError(path, problems)
    if sep == "," and header == rows[0]:
        return Sheet(text, sep, False)             # a plain CSV: read as it stands
    out = io.StringIO()
    csv.writer(out, lineterminator="\n").writerows([header, *body])
    return Sheet(out.getvalue(), sep, decimal_comma)


def duplicate_header_problems(header: list[str]) -> list[Problem]:
    """Every header name given twice (after stripping and lower-casing), naming both columns."""
    seen: dict[str, int] = {}
    out = []
    for j, h in enumerate(header):
        k = seen.setdefault(h, j)
        if k != j and h:
            out.append(Problem(f"line 1, column '{h}'", f"appears more than once (columns {k + 1} and {j + 1}): a "
                                                        "duplicated column; remove one or rename it"))
    return out


def _decimal_points(body: list[list[str]], header: list[str], sep_name: str):
    """Rows with decimal commas made points; dotted numbers that may be thousands separators refused."""
    out, problems, seen_comma = [], [], False
    for i, row in enumerate(body):
        cells = []
        for j, cell in enumerate(row):
            t = cell.strip()
            if _THOUSANDS_DOT_DECIMAL_COMMA.fullmatch(t):
                t, seen_comma = t.replace(".", "").replace(",", "."), True
            elif _DECIMAL_COMMA.fullmatch(t):
                t, seen_comma = t.replace(",", "."), True
            cells.append(t)
        out.append(cells)
    if seen_comma:
        for i, row in enumerate(out):
            for j, t in enumerate(row):
                if _THOUSANDS_DOT.fullmatch(body[i][j].strip()):
                    name = header[j] if j < len(header) else f"#{j + 1}"
                    problems.append(Problem(f"line {i + 2} (row {i + 1}), column '{name}'",
                                            f"'{t}' in a {sep_name}-separated file with decimal commas: a thousands "
                                            "separator or a decimal point? write it without thousands separators"))
    return out, seen_comma, problems[:10]
