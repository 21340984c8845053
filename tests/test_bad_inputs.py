"""Bad inputs (README, "Bad inputs"): every case below, given to the command line, ends with
exit code 2 and a message naming the file and row/column (or the argument), never a
traceback; the loaders of POH and snapshot CSV files, G1000 logs, time histories and geometry
files, fed random garbage, truncations, NaN/inf/empty cells and wrong units, give a clean
result or the project's DataError/InputError/GeometryError, never another exception and never
a NaN that passes (hypothesis). Real JSBSim on generated aircraft, no mocks.

    python tests/test_bad_inputs.py ROOT     # prints the README table from real runs (ROOT: a
                                             # JSBSim root with generated aircraft)
"""
from __future__ import annotations

import json
import math
import os
import re
import shutil
import sys
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings, strategies as st

from jsbsim_calib.cli import main
from jsbsim_calib.data.load import load_dataset
from jsbsim_calib.data.timehistory import load_time_history
from jsbsim_calib.core.errors import DataError, GeometryError, InputError
from jsbsim_calib.physics.geometry import load_geometry

REPO = Path(__file__).resolve().parents[1]
DATA = REPO / "data"
LOG = DATA / "g1000" / "log_110812_095915_KCKN.csv"
N_EXAMPLES = int(os.environ.get("BAD_INPUT_EXAMPLES", "25"))        # more: a longer hunt
EXAMPLES = settings(max_examples=N_EXAMPLES, deadline=None,
                    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])


# --------------------------------------------------------------------------- making bad files
def lines_of(name: str) -> list[str]:
    return (DATA / name).read_text().splitlines()


def set_cell(lines: list[str], row: int, column: str, text: str) -> list[str]:
    """``lines`` (header first) with one cell (data row from 1) replaced."""
    j = lines[0].split(",").index(column)
    out = list(lines)
    cells = out[row].split(",")
    cells[j] = text
    out[row] = ",".join(cells)
    return out


def write(tmp: Path, name: str, lines: list[str] | str | bytes) -> Path:
    p = tmp / name
    if isinstance(lines, bytes):
        p.write_bytes(lines)
    else:
        p.write_text(lines if isinstance(lines, str) else "\n".join(lines) + "\n")
    return p


def poh(tmp: Path, edit: Callable[[list[str]], list[str]], name: str = "c172_poh_climb.csv") -> Path:
    return write(tmp, f"bad_{name}", edit(lines_of(name)))


def climb_cell(column: str, text: str, row: int = 1):
    return lambda tmp: poh(tmp, lambda ls: set_cell(ls, row, column, text))


def snapshots(tmp: Path, edit: Callable[[list[str]], list[str]]) -> Path:
    return poh(tmp, edit, "c172_flight_test_snapshots.csv")


def log_cut(n_bytes: int | None = None, n_lines: int | None = None):
    def make(tmp):
        data = LOG.read_bytes()
        if n_bytes is not None:
            data = data[:n_bytes]
        else:
            data = b"\n".join(data.split(b"\n")[:n_lines]) + b"\n"
        return write(tmp, "log_cut.csv", data)
    return make


# --------------------------------------------------------------------------- the cases
@dataclass(frozen=True)
class Case:
    id: str
    what: str                                    # the bad input (README table)
    argv: Callable[[Path, Path], list[str]]      # (root, tmp) -> command line after the global options
    expect: tuple[str, ...]                      # fragments the message must hold (place, reason)
    edit_root: Callable[[Path], None] | None = None   # the case breaks the aircraft: run on a copy
    exit: int = 2                                # 0: read correctly (a spreadsheet export, a declared unit)


def evaluate(make_data: Callable[[Path], Path], aircraft: str = "c172", *extra: str):
    return lambda root, tmp: ["evaluate", aircraft, "--data", str(make_data(tmp)), "--report-dir", str(tmp / "r"),
                              *extra]


def good_climb(tmp: Path) -> Path:
    return DATA / "c172_poh_climb.csv"


def breaking(fn: Callable[[Path], None]):
    """A case that breaks the aircraft (on its own copy) and evaluates the POH climbs."""
    return dict(argv=evaluate(good_climb), edit_root=fn)


def _xml(root: Path, name: str = "c172") -> Path:
    return root / "aircraft" / name / f"{name}.xml"


def _set_factor(root: Path, prop: str, value: str) -> None:
    p = _xml(root)
    text, n = re.subn(rf'<property value="[^"]*" persistent="true"> {re.escape(prop)} </property>',
                      f'<property value="{value}" persistent="true"> {prop} </property>', p.read_text())
    assert n == 1, prop
    p.write_text(text)


def _edit_calibration(root: Path, factor: str, value: float) -> None:
    p = root / "aircraft" / "c172" / "calibration.json"
    rec = json.loads(p.read_text()) if p.is_file() else {"factors": {}}
    rec["factors"][factor] = value
    p.write_text(json.dumps(rec, indent=2) + "\n")


def _time_history_nan(tmp: Path) -> Path:
    d = tmp / "th"
    d.mkdir()
    rows = [f"{i / 10:.1f},5500.0,110.0,0.0,0.5,0.0,{1.0 + 0.1 * i:.2f}" for i in range(6)]
    rows[3] = rows[3].replace("110.0", "nan")
    (d / "T_1_pitch_pulse.csv").write_text("time_s,pressure_alt_ft,ktas,vs_fpm,pitch_deg,roll_deg,elevator_deg\n"
                                           + "\n".join(rows) + "\n")
    meta = {"test_id": "T.1", "title": "pitch pulse", "part60": "2.b.1", "kind": "pitch_pulse", "aircraft": "c172",
            "configuration": {"weight_lb": 2400.0, "cg_in": 42.0, "flaps_deg": 0.0, "mixture": "cruise"},
            "sample_rate_hz": 10.0, "inputs": ["elevator_deg"], "sources": {}}
    (d / "T_1_pitch_pulse.json").write_text(json.dumps(meta))
    return d


CASES = [
    # --- POH data (C172: max weight 2,550 lb, service ceiling 14,000 ft, Vne 163 KIAS, Vso 40 KIAS)
    Case("weight-3200", "POH climb at 3,200 lb (C172 max gross 2,550)", evaluate(climb_cell("weight_lb", "3200")),
         ("line 2 (row 1), column 'weight_lb'", "1.25 x", "maximum weight 2550 lb")),
    Case("weight-negative", "negative weight (-100 lb)", evaluate(climb_cell("weight_lb", "-100")),
         ("line 2 (row 1), column 'weight_lb'", "plausible range")),
    Case("speed-0", "0 KIAS", evaluate(climb_cell("kias", "0")), ("line 2 (row 1), column 'kias'", "plausible range")),
    Case("speed-400", "400 KIAS", evaluate(climb_cell("kias", "400")), ("column 'kias'", "plausible range")),
    Case("speed-vne", "200 KIAS (C172 Vne 163)", evaluate(climb_cell("kias", "200")),
         ("line 2 (row 1), column 'kias'", "above the Cessna 172S Skyhawk SP's Vne 163")),
    Case("speed-stall", "30 KIAS (below 0.85 x Vso 40)", evaluate(climb_cell("kias", "30")),
         ("column 'kias'", "stall speed 40")),
    Case("alt-25000", "climb at 25,000 ft (ceiling 14,000)", evaluate(climb_cell("pressure_alt_ft", "25000")),
         ("line 2 (row 1), column 'pressure_alt_ft'", "service ceiling 14000 ft", "outside its envelope")),
    Case("alt-40000", "40,000 ft", evaluate(climb_cell("pressure_alt_ft", "40000")),
         ("column 'pressure_alt_ft'", "plausible range")),
    Case("oat-kelvin", "OAT in Kelvin (253 for -20 C)", evaluate(climb_cell("oat_c", "253")),
         ("line 2 (row 1), column 'oat_c'", "plausible range")),
    Case("oat-fahrenheit", "OAT 55 (Fahrenheit) at 12,000 ft: ISA +64", evaluate(climb_cell("oat_c", "55", row=7)),
         ("line 8 (row 7), column 'oat_c'", "ISA +64", "Kelvin or Fahrenheit")),
    Case("isa-dev-55", "ISA deviation +55 C in a cruise table",
         evaluate(lambda tmp: poh(tmp, lambda ls: set_cell(ls, 2, "temp_dev_c", "55"), "c172_poh_cruise.csv")),
         ("line 3 (row 2), column 'temp_dev_c'", "more than 50")),
    Case("duplicate-rows", "every row duplicated", evaluate(lambda tmp: poh(tmp, lambda ls: [ls[0]] + [
        r for r in ls[1:] for _ in (0, 1)])), ("line 3 (row 2)", "duplicates line 2 (row 1)")),
    Case("poh-header-only", "POH file with its header only", evaluate(lambda tmp: poh(tmp, lambda ls: ls[:1])),
         ("no data rows",)),
    Case("empty-cell", "an empty cell", evaluate(climb_cell("roc_fpm", "")),
         ("line 2 (row 1), column 'roc_fpm'", "empty")),
    Case("nan-cell", "'nan' in a cell", evaluate(climb_cell("roc_fpm", "nan", row=3)),
         ("line 4 (row 3), column 'roc_fpm'", "not finite")),
    Case("inf-cell", "'inf' in a cell", evaluate(climb_cell("kias", "inf")), ("column 'kias'", "not finite")),
    Case("text-cell", "text in a number column ('74 kt')", evaluate(climb_cell("kias", "74 kt")),
         ("column 'kias'", "'74 kt' is not a number")),
    Case("missing-column", "POH climb without its kias column",
         evaluate(lambda tmp: write(tmp, "c.csv", [",".join(c for c in l.split(",")[:2] + l.split(",")[3:])
                                                   for l in lines_of("c172_poh_climb.csv")])),
         ("column 'kias'", "missing")),
    Case("unknown-columns", "a CSV of unknown columns", evaluate(lambda tmp: write(tmp, "x.csv", ["a,b", "1,2"])),
         ("columns", "cannot tell the kind")),
    Case("empty-file", "an empty (0-byte) data file", evaluate(lambda tmp: write(tmp, "e.csv", b"")),
         ("e.csv", "not a readable CSV")),
    Case("binary-garbage", "random bytes as a data file",
         evaluate(lambda tmp: write(tmp, "g.csv", bytes(range(256)) * 4)), ("g.csv",)),
    Case("truncated-poh", "POH file cut in the middle of a row",
         evaluate(lambda tmp: write(tmp, "t.csv", (DATA / "c172_poh_climb.csv").read_bytes()[:290])),
         ("t.csv", "fields, the header has 7")),
    # --- flight-test snapshots
    Case("snap-header-only", "snapshot file with its header only", evaluate(lambda tmp: snapshots(tmp, lambda ls: ls[:1])),
         ("no data rows",)),
    Case("snap-no-usable", "snapshot file whose every row is a quirk (no flight data)",
         evaluate(lambda tmp: snapshots(tmp, lambda ls: [ls[0]] + [",".join(l.split(",")[:2] + [""] * (
             len(l.split(",")) - 2)) for l in ls[1:4]])), ("no usable row", "no flight data")),
    Case("snap-weight", "snapshot at 3,200 lb", evaluate(lambda tmp: snapshots(tmp, lambda ls: set_cell(
        ls, 1, "weight_lb", "3200"))), ("line 2 (C.1), column 'weight_lb'", "maximum weight")),
    Case("snap-duplicate", "a duplicated snapshot row", evaluate(lambda tmp: snapshots(tmp, lambda ls: ls + ls[1:2])),
         ("(C.1)", "duplicates line 2 (C.1)")),
    # --- G1000 logs
    Case("log-2.5kB", "G1000 log cut at 2.5 kB", evaluate(log_cut(n_bytes=2500)), ("log_cut.csv",)),
    Case("log-no-segment", "G1000 log of the ground run only (no steady segment)", evaluate(log_cut(n_lines=300)),
         ("log_cut.csv", "no quasi-steady segment")),
    Case("log-fahrenheit", "G1000 log whose OAT unit is deg F",
         evaluate(lambda tmp: write(tmp, "log_f.csv", LOG.read_text().replace(",  ft msl, deg C,", ",  ft msl, deg F,", 1))),
         ("column OAT", "'deg F'")),
    Case("log-no-channel", "G1000 log without its E1 RPM channel",
         evaluate(lambda tmp: write(tmp, "log_r.csv", LOG.read_text().replace(" E1 RPM,", " E1 RPMX,", 1))),
         ("missing required channel", "E1 RPM")),
    # --- arguments
    Case("json-missing-folder", "--json into a folder that does not exist",
         lambda root, tmp: ["evaluate", "c172", "--data", str(DATA / "c172_poh_climb.csv"), "--json",
                            str(tmp / "nope" / "x.json")], ("--json", "does not exist")),
    Case("json-folder", "--json naming a folder", lambda root, tmp: ["evaluate", "c172", "--data",
                                                                   str(DATA / "c172_poh_climb.csv"), "--json", str(tmp)],
         ("--json", "is a folder")),
    Case("close-loop-json-folder", "close-loop --json naming a folder",
         lambda root, tmp: ["close-loop", "c172", "--data", str(DATA / "c172_flight_test_snapshots.csv"), "--json",
                            str(tmp)], ("--json", "is a folder")),
    Case("data-folder", "--data naming a folder", lambda root, tmp: ["evaluate", "c172", "--data", str(DATA)],
         ("--data", "is a folder")),
    Case("data-missing", "--data naming no file", lambda root, tmp: ["evaluate", "c172", "--data", str(tmp / "n.csv")],
         ("--data", "no such file")),
    Case("synth-points-0", "synth --points 0", lambda root, tmp: [
        "synth", "--truth", str(root / "aircraft" / "c172"), "--out", str(tmp / "s.csv"), "--points", "0"],
         ("--points", "[1, 10000]")),
    Case("synth-noise-negative", "synth --noise -1", lambda root, tmp: [
        "synth", "--truth", str(root / "aircraft" / "c172"), "--out", str(tmp / "s.csv"), "--noise", "-1"],
         ("--noise",)),
    Case("workers-0", "--workers 0", lambda root, tmp: ["--workers", "0", "check", "c172"], ("--workers",)),
    Case("part60-missing", "part60 --flight-test naming nothing",
         lambda root, tmp: ["part60", "c172", "--flight-test", str(tmp / "none")], ("--flight-test", "no such file")),
    Case("time-history-nan", "a time history with a 'nan' cell (close-loop --flight-test)",
         lambda root, tmp: ["close-loop", "c172", "--flight-test", str(_time_history_nan(tmp)), "--no-write",
                            "--report-dir", str(tmp / "r")],
         ("T_1_pitch_pulse.csv, line 5 (row 4), column 'ktas'", "not a finite number")),
    # --- the aircraft's own files
    Case("propeller-empty", "an empty propeller XML",
         **breaking(lambda r: (r / "engine" / "c172_propeller.xml").write_bytes(b"")),
         expect=("c172_propeller.xml", "cannot read")),
    Case("engine-empty", "an empty engine XML", **breaking(lambda r: (r / "engine" / "c172_engine.xml").write_bytes(b"")),
         expect=("c172_engine.xml", "cannot read")),
    Case("aircraft-cut", "the aircraft XML cut at 131,072 bytes",
         **breaking(lambda r: _xml(r).write_bytes(_xml(r).read_bytes()[:131072])), expect=("c172.xml", "cannot read")),
    Case("factor-nan", "a factor set to NaN by hand in the aircraft XML",
         **breaking(lambda r: _set_factor(r, "calibration/K_cl_slope", "nan")),
         expect=("c172.xml", "factor K_cl_slope (calibration/K_cl_slope)", "'nan' is not a finite number")),
    Case("factor-bounds", "a factor set past its bounds by hand (K_cl_slope 5)",
         **breaking(lambda r: _set_factor(r, "calibration/K_cl_slope", "5")),
         expect=("c172.xml", "factor K_cl_slope", "value 5 is outside its bounds [0.7, 1.3]")),
    Case("factor-text", "a factor value that is not a number",
         **breaking(lambda r: _set_factor(r, "calibration/K_cdi", "one")),
         expect=("factor K_cdi", "'one' is not a number")),
    Case("propeller-factor-by-hand", "a baked propeller factor edited in the aircraft XML only",
         **breaking(lambda r: _set_factor(r, "calibration/K_CT_scale", "1.01")),
         expect=("declares propeller factors that differ", "K_CT_scale")),
    Case("calibration-garbage", "calibration.json that is not JSON",
         **breaking(lambda r: (r / "aircraft" / "c172" / "calibration.json").write_text("{factors: ")),
         expect=("calibration.json", "not a calibration record")),
    Case("mixed-set", "calibration.json of another write than the aircraft XML",
         **breaking(lambda r: _edit_calibration(r, "K_cdi", 1.2345)),
         expect=("other calibration values than", "K_cdi", "backup")),
    Case("bem-empty", "an empty propeller_bem.csv",
         **breaking(lambda r: (r / "aircraft" / "c172" / "propeller_bem.csv").write_text("")),
         expect=("propeller_bem.csv", "generate")),
    Case("geometry-not-toml", "geometry.toml that is not TOML",
         **breaking(lambda r: (r / "aircraft" / "c172" / "geometry.toml").write_text("[mass\nmax_weight = ")),
         expect=("geometry.toml", "not valid TOML")),
    Case("geometry-inf", "geometry.toml with max_weight = '1e999 lb' (not finite)",
         **breaking(lambda r: (r / "aircraft" / "c172" / "geometry.toml").write_text(
             (r / "aircraft" / "c172" / "geometry.toml").read_text().replace('max_weight = "2550 lb"',
                                                                            'max_weight = "1e999 lb"'))),
         expect=("mass.max_weight", "not a finite number")),
]


# --------------------------------------------------------------------------- issue 27: nothing silent, nothing lost
CLIMB3 = lines_of("c172_poh_climb.csv")[:4]            # three rows: a cheap evaluation
CRUISE3 = lines_of("c172_poh_cruise.csv")[:4]


def climb3(tmp: Path, name: str, text: str | bytes) -> Path:
    return write(tmp, name, text)


def sheet(lines: list[str], sep: str = ",", decimal: str = ".") -> str:
    return "\n".join(ln.replace(",", sep).replace(".", decimal) for ln in lines) + "\n"


def column(lines: list[str], name: str, fn: Callable[[str], str], header: str | None = None) -> list[str]:
    """``lines`` with every cell of one column mapped by ``fn`` (and the header renamed)."""
    j = lines[0].split(",").index(name)
    out = [",".join(header if k == j and header else c for k, c in enumerate(lines[0].split(",")))]
    for ln in lines[1:]:
        cells = ln.split(",")
        cells[j] = fn(cells[j])
        out.append(",".join(cells))
    return out


def scaled(factor: float, digits: int = 2) -> Callable[[str], str]:
    return lambda v: f"{float(v) * factor:.{digits}f}"


def data_case(id, what, make, expect, exit=2):
    """A case evaluating the data file ``make(tmp)`` on the C172."""
    return Case(id, what, evaluate(make), expect, exit=exit)


def _log_lines() -> list[str]:
    return LOG.read_text().splitlines()


def _log_with(channel: str, value: str) -> str:
    lines = _log_lines()
    j = [h.strip() for h in lines[2].split(",")].index(channel)
    out = lines[:3]
    for ln in lines[3:]:
        cells = ln.split(",")
        if len(cells) > j:
            cells[j] = value
        out.append(",".join(cells))
    return "\n".join(out) + "\n"


def _edit_geometry(old: str, new: str, count: int = 1):
    def edit(root: Path) -> None:
        p = root / "aircraft" / "c172" / "geometry.toml"
        text = p.read_text()
        assert old in text, old
        p.write_text(text.replace(old, new, count))
    return edit


def _edit_xml(pattern: str, repl: str):
    def edit(root: Path) -> None:
        text, n = re.subn(pattern, repl, _xml(root).read_text(), flags=re.S)
        assert n == 1, pattern
        _xml(root).write_text(text)
    return edit


def _locked(root: Path) -> None:
    (root / "aircraft" / "c172" / ".lock").write_text(json.dumps(
        {"pid": 1, "command": "jsbsim-calib calibrate c172 --stage all", "started": "2026-11-25 23:00:00 +0000"}))


def _th_without_sidecar(tmp: Path) -> Path:
    d = _time_history_nan(tmp)
    (d / "T_1_pitch_pulse.json").unlink()
    return d


def _th_semicolon(tmp: Path) -> Path:
    d = _time_history_nan(tmp)
    p = d / "T_1_pitch_pulse.csv"
    p.write_text(p.read_text().replace(",", ";").replace(".", ","))
    return d


def _file(tmp: Path) -> Path:
    return write(tmp, "f", "not a folder\n")


NEW_CASES = [
    # --- spreadsheet exports: read, or refused naming the line and column
    data_case("csv-semicolon", "POH climb exported with ';' separators (read)",
              lambda tmp: climb3(tmp, "s.csv", sheet(CLIMB3, ";")), ("report:",), exit=0),
    data_case("csv-tab", "POH climb exported with tabs (read)",
              lambda tmp: climb3(tmp, "t.csv", sheet(CLIMB3, "\t")), ("report:",), exit=0),
    data_case("csv-decimal-comma", "German Excel: ';' separators and decimal commas (read)",
              lambda tmp: climb3(tmp, "d.csv", sheet(CLIMB3, ";", ",")), ("report:",), exit=0),
    data_case("csv-cruise-decimal-comma", "a cruise table with ';' and decimal commas (read)",
              lambda tmp: climb3(tmp, "dc.csv", sheet(CRUISE3, ";", ",")), ("report:",), exit=0),
    data_case("csv-uppercase", "UPPERCASE headers (read)",
              lambda tmp: climb3(tmp, "u.csv", "\n".join([CLIMB3[0].upper(), *CLIMB3[1:]]) + "\n"), ("report:",), exit=0),
    data_case("csv-bom", "a UTF-8 byte-order mark (read)",
              lambda tmp: climb3(tmp, "b.csv", b"\xef\xbb\xbf" + sheet(CLIMB3).encode()), ("report:",), exit=0),
    data_case("csv-utf16", "UTF-16 with its byte-order mark (read)",
              lambda tmp: climb3(tmp, "w.csv", sheet(CLIMB3).encode("utf-16")), ("report:",), exit=0),
    data_case("csv-utf16-no-bom", "UTF-16 little-endian without a byte-order mark (read)",
              lambda tmp: climb3(tmp, "w.csv", sheet(CLIMB3).encode("utf-16-le")), ("report:",), exit=0),
    data_case("csv-latin1", "a Windows-1252 export ('oat_\u00b0c' header)",
              lambda tmp: climb3(tmp, "l.csv", sheet(CLIMB3).replace("oat_c", "oat_\u00b0c").encode("cp1252")),
              ("l.csv: line 1, column 5", "not UTF-8")),
    data_case("csv-decimal-comma-in-comma-file", "a decimal comma in a comma-separated file",
              lambda tmp: climb3(tmp, "c.csv", sheet(CLIMB3).replace("855.0", "855,0")),
              ("line 2 (row 1)", "8 fields, the header has 7", "decimal commas")),
    data_case("csv-thousands-dot", "';' and decimal commas with a thousands dot ('2.550')",
              lambda tmp: climb3(tmp, "k.csv", sheet(CLIMB3, ";", ",").replace(";2550;", ";2.550;", 1)),
              ("line 2 (row 1), column 'weight_lb'", "thousands separator")),
    data_case("csv-duplicate-column", "a duplicated header column (kias twice)",
              lambda tmp: climb3(tmp, "dup.csv", sheet(CLIMB3).replace("flaps_deg", "kias")),
              ("line 1, column 'kias'", "appears more than once (columns 3 and 5)")),
    data_case("csv-duplicate-column-case", "the same column twice in other case (ROC_FPM, roc_fpm)",
              lambda tmp: climb3(tmp, "dup.csv", sheet(CLIMB3).replace("thesis_model_roc_fpm", "ROC_FPM")),
              ("line 1, column 'roc_fpm'", "columns 6 and 7")),
    data_case("snap-duplicate-id", "two different snapshots with one id (C.1)",
              lambda tmp: snapshots(tmp, lambda ls: [ls[0], ls[1], ls[2].replace("C.3,", "C.1,", 1), *ls[3:]]),
              ("line 3 (C.1), column 'table'", "also line 2's")),
    # --- G1000 logs
    data_case("log-bom", "a G1000 log with a byte-order mark (read as a log)",
              lambda tmp: write(tmp, "log_bom.csv", b"\xef\xbb\xbf" + log_cut(n_lines=300)(tmp).read_bytes()),
              ("log_bom.csv", "no quasi-steady segment in 296 s")),
    data_case("log-no-airframe", "a G1000 log without its #airframe_info line (read as a log)",
              lambda tmp: write(tmp, "log_na.csv", "\n".join(_log_lines()[1:300]) + "\n"),
              ("log_na.csv", "no quasi-steady segment")),
    data_case("log-utf16", "a G1000 log saved as UTF-16 (read as a log)",
              lambda tmp: write(tmp, "log_16.csv", ("\n".join(_log_lines()[:300]) + "\n").encode("utf-16")),
              ("log_16.csv", "no quasi-steady segment")),
    data_case("log-rpm-zero", "a G1000 log whose E1 RPM is 0 all flight",
              lambda tmp: write(tmp, "log_rpm.csv", _log_with("E1 RPM", " 0")),
              ("segment 1 (cruise", "column 'E1 RPM'", "0 rpm through the segment")),
    data_case("log-pitch-stuck", "a G1000 log whose pitch never moves (2.5 deg all flight)",
              lambda tmp: write(tmp, "log_p.csv", _log_with("Pitch", " 2.5")),
              ("column 'Pitch'", "constant at 2.5", "stuck")),
    # --- units: declared ones converted, undeclared ones judged by what the numbers are
    data_case("roc-mps", "climb rate in m/s under roc_fpm",
              lambda tmp: climb3(tmp, "r.csv", sheet(column(CLIMB3, "roc_fpm", scaled(1 / 196.85)))),
              ("column 'roc_fpm'", "fit m/s")),
    data_case("roc-mps-declared", "climb rate in m/s declared 'roc [m/s]' (converted)",
              lambda tmp: climb3(tmp, "r.csv", sheet(column(CLIMB3, "roc_fpm", scaled(1 / 196.85, 3), "roc [m/s]"))),
              ("report:",), exit=0),
    data_case("alt-metres", "POH climb altitudes in metres under pressure_alt_ft",
              lambda tmp: poh(tmp, lambda ls: column(ls, "pressure_alt_ft", scaled(1 / 3.28084, 0))),
              ("column 'pressure_alt_ft'", "in metres")),
    data_case("alt-metres-declared", "altitudes in metres declared 'alt_m' (converted)",
              lambda tmp: climb3(tmp, "a.csv", sheet(column(CLIMB3, "pressure_alt_ft", scaled(1 / 3.28084, 1), "alt_m"))),
              ("report:",), exit=0),
    data_case("pct-power-fraction", "% power given as a fraction (0.77)",
              lambda tmp: poh(tmp, lambda ls: column(ls, "pct_power", scaled(0.01)), "c172_poh_cruise.csv"),
              ("column 'pct_power'", "a fraction of rated power")),
    data_case("gph-litres", "fuel flow in L/h under gph",
              lambda tmp: poh(tmp, lambda ls: column(ls, "gph", scaled(3.785, 1)), "c172_poh_cruise.csv"),
              ("column 'gph'", "litres per hour")),
    data_case("gph-litres-declared", "fuel flow declared 'fuel_flow [l/h]' (converted)",
              lambda tmp: climb3(tmp, "g.csv", sheet(column(CRUISE3, "gph", scaled(3.785, 2), "fuel_flow [l/h]"))),
              ("report:",), exit=0),
    data_case("weight-kg", "weights in kg under weight_lb (1157 for 2550 lb)",
              lambda tmp: climb3(tmp, "w.csv", sheet(column(CLIMB3, "weight_lb", scaled(1 / 2.20462, 0)))),
              ("line 2 (row 1), column 'weight_lb'", "below the aircraft's empty weight", "kilograms?")),
    data_case("weight-kg-declared", "weights declared 'weight [kg]' (converted)",
              lambda tmp: climb3(tmp, "w.csv", sheet(column(CLIMB3, "weight_lb", scaled(1 / 2.20462, 3), "weight [kg]"))),
              ("report:",), exit=0),
    data_case("oat-fahrenheit-declared", "OAT declared 'oat [degF]' (converted)",
              lambda tmp: climb3(tmp, "o.csv", sheet(column(CLIMB3, "oat_c", lambda v: f"{float(v) * 1.8 + 32:.1f}",
                                                            "oat [degF]"))), ("report:",), exit=0),
    data_case("unit-unknown", "a unit the quantity cannot have ('roc [furlong/h]')",
              lambda tmp: climb3(tmp, "x.csv", sheet(column(CLIMB3, "roc_fpm", str, "roc [furlong/h]"))),
              ("line 1, column 'roc [furlong/h]'", "no climb unit")),
    data_case("unit-twice", "one quantity in two columns (roc_fpm and 'roc [m/s]')",
              lambda tmp: climb3(tmp, "x.csv", sheet(column(CLIMB3, "thesis_model_roc_fpm", str, "roc [m/s]"))),
              ("column 'roc [m/s]'", "gives roc_fpm a second time")),
    # --- time histories
    Case("th-no-sidecar", "a time history without its JSON sidecar",
         lambda root, tmp: ["close-loop", "c172", "--flight-test", str(_th_without_sidecar(tmp)), "--no-write",
                            "--report-dir", str(tmp / "r")], ("T_1_pitch_pulse.csv", "sidecar missing")),
    Case("th-semicolon", "a time history with ';' and decimal commas, a 'nan' cell (read, cell named)",
         lambda root, tmp: ["close-loop", "c172", "--flight-test", str(_th_semicolon(tmp)), "--no-write",
                            "--report-dir", str(tmp / "r")], ("line 5 (row 4), column 'ktas'", "not a finite number")),
    # --- geometry.toml: unknown keys and contradictions
    Case("geometry-unknown-key", "an unknown geometry key (wing.sweep)",
         **breaking(_edit_geometry("[wing]\n", '[wing]\nsweep = "3 deg"\n')),
         expect=("geometry.toml", "wing.sweep: unknown key", "known keys here")),
    Case("geometry-unknown-table", "an unknown geometry table ([winglets])",
         **breaking(_edit_geometry("[aircraft]\n", '[winglets]\nheight = "1 ft"\n\n[aircraft]\n')),
         expect=("winglets: unknown key",)),
    Case("geometry-station-typo", "a misspelt key in a list of tables (mass.stations[0].wieght)",
         **breaking(_edit_geometry('weight = "340 lb"', 'wieght = "340 lb"')),
         expect=("mass.stations[0].wieght: unknown key", "mass.stations[0].weight: missing")),
    Case("geometry-max-below-empty", "max_weight (1500 lb) below the empty weight (1663 lb)",
         **breaking(_edit_geometry('max_weight = "2550 lb"', 'max_weight = "1500 lb"')),
         expect=("mass.max_weight: 1500 lb is below mass.empty_weight 1663 lb",)),
    Case("geometry-envelope-above-max", "a CG envelope reaching 2,700 lb (max_weight 2,550)",
         **breaking(_edit_geometry("values = [1500, 1950, 2550]", "values = [1500, 1950, 2700]")),
         expect=("mass.cg_envelope_weight", "above mass.max_weight")),
    Case("geometry-envelope-inverted", "a forward CG limit aft of the aft limit",
         **breaking(_edit_geometry("values = [35.0, 35.0, 41.0]", "values = [35.0, 35.0, 48.0]")),
         expect=("mass.cg_envelope_forward", "aft of its aft limit")),
    # --- an aircraft XML that would abort JSBSim (C++ exception, exit 134)
    Case("xml-no-propulsion", "the aircraft XML without <propulsion>",
         **breaking(_edit_xml(r"<propulsion>.*?</propulsion>", "")), expect=("c172.xml", "no <propulsion> section")),
    Case("xml-no-aerodynamics", "the aircraft XML without <aerodynamics>",
         **breaking(_edit_xml(r"<aerodynamics>.*?</aerodynamics>", "")), expect=("c172.xml", "no <aerodynamics>")),
    Case("xml-thruster-missing", "a thruster file that is not in engine/",
         **breaking(_edit_xml(r'thruster file="c172_propeller"', 'thruster file="c172_prop"')),
         expect=("c172.xml: line", "no c172_prop.xml in")),
    # --- command lines: contradictions, step names, folders that cannot be written, a held aircraft
    Case("regress-baseline-and-write", "regress --baseline A --write-baseline B (A ignored)",
         lambda root, tmp: ["regress", "c172", "--baseline", str(write(tmp, "a.json", "{}")), "--write-baseline",
                            str(tmp / "b.json")], ("--baseline and --write-baseline", "give one of them")),
    Case("regress-write-baseline-json", "regress --write-baseline B --json J (nothing to compare)",
         lambda root, tmp: ["regress", "c172", "--write-baseline", str(tmp / "b.json"), "--json", str(tmp / "j.json")],
         ("--write-baseline and --json",)),
    Case("calibrate-skip-bogus", "calibrate --skip bogus",
         lambda root, tmp: ["calibrate", "c172", "--stage", "trims", "--skip", "bogus", "--no-write"],
         ("--skip", "'bogus' is no step", "pitch, control, pfactor, flaps")),
    Case("close-loop-skip-bogus", "close-loop --skip bogus",
         lambda root, tmp: ["close-loop", "c172", "--data", str(DATA / "c172_flight_test_snapshots.csv"), "--skip",
                            "bogus", "--no-write"], ("--skip", "'bogus' is no step")),
    Case("close-loop-in-place-out", "close-loop --in-place --out NAME",
         lambda root, tmp: ["close-loop", "c172", "--data", str(DATA / "c172_flight_test_snapshots.csv"), "--in-place",
                            "--out", "x"], ("--in-place and --out",)),
    Case("close-loop-no-write-in-place", "close-loop --no-write --in-place",
         lambda root, tmp: ["close-loop", "c172", "--data", str(DATA / "c172_flight_test_snapshots.csv"), "--no-write",
                            "--in-place"], ("--no-write and --in-place",)),
    Case("report-dir-unwritable", "calibrate --report-dir in a folder that cannot be written",
         lambda root, tmp: ["calibrate", "c172", "--stage", "steady", "--no-write", "--report-dir", "/proc/jsbsim-calib"],
         ("--report-dir", "cannot write in /proc")),
    Case("report-dir-under-file", "--report-dir below a file",
         lambda root, tmp: ["evaluate", "c172", "--data", str(DATA / "c172_poh_climb.csv"), "--report-dir",
                            str(_file(tmp) / "r")], ("--report-dir", "is a file, not a folder")),
    Case("close-loop-out-is-file", "close-loop --out naming a file in aircraft/",
         lambda root, tmp: ["close-loop", "c172", "--data", str(DATA / "c172_flight_test_snapshots.csv"), "--out",
                            "c172_file", "--report-dir", str(tmp / "r")],
         ("aircraft folder", "c172_file", "is a file, not a folder"),
         edit_root=lambda r: (r / "aircraft" / "c172_file").write_text("")),
    Case("aircraft-locked", "generate while another run writes the aircraft",
         lambda root, tmp: ["generate", "c172"], ("being written by another run", "pid 1",
                                                   "'jsbsim-calib calibrate c172 --stage all'", "started 2026-11-25"),
         edit_root=_locked),
    Case("scheduler-unreachable", "--executor dask --scheduler at an address where none answers",
         lambda root, tmp: ["--executor", "dask", "--scheduler", "tcp://127.0.0.1:9", "check", "c172"],
         ("--scheduler tcp://127.0.0.1:9", "within 5 s")),
]
CASES += NEW_CASES


# --------------------------------------------------------------------------- running a case
def copy_root(src: Path, dst: Path) -> Path:
    """A JSBSim root to break: aircraft and engine copied, the rest linked."""
    dst.mkdir(parents=True, exist_ok=True)
    for d in ("aircraft", "engine"):
        shutil.copytree(src / d, dst / d, ignore=shutil.ignore_patterns("backup"))
    for d in ("airfoils", "data", "scripts"):
        (dst / d).symlink_to(src / d, target_is_directory=True)
    return dst


def run_case(case: Case, root: Path, tmp: Path, capsys) -> tuple[int, str]:
    if case.edit_root is not None:
        root = copy_root(root, tmp / "root")
        case.edit_root(root)
    argv = ["--root", str(root), "--executor", "serial", "--quiet", *case.argv(root, tmp)]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        rc = main(argv)
    out = capsys.readouterr()
    return rc, out.out + out.err


@pytest.mark.parametrize("case", CASES, ids=[c.id for c in CASES])
def test_bad_input_is_refused_by_name(case, generated_root, tmp_path, capsys):
    rc, text = run_case(case, generated_root, tmp_path, capsys)
    assert rc == case.exit, text[-2000:]
    assert "Traceback" not in text
    missing = [e for e in case.expect if e not in text]
    assert not missing, f"{missing} not in:\n{text[-2000:]}"


def test_at_least_a_hundred_cases():
    assert len({c.id for c in CASES}) == len(CASES) >= 100
    assert len(NEW_CASES) >= 48


TABLE_ROW = re.compile(r"^\| (\d+) \| `([^`]+)` \| (.+?) \| (\d+) \| .+ \|$", re.M)


def test_readme_table_is_these_cases():
    """docs/bad-inputs.md (the README's former section, continued with the cases of issue 27):
    one row per case, in order, each with its id, description and exit code."""
    rows = TABLE_ROW.findall((REPO / "docs" / "bad-inputs.md").read_text())
    assert [(int(k), i, w, int(rc)) for k, i, w, rc in rows] == [(k, c.id, c.what, c.exit)
                                                                 for k, c in enumerate(CASES, 1)]


# warnings, not refusals: within the margins, the run goes on and says so
def test_weight_above_max_gross_warns(generated_root, tmp_path, capsys):
    data = climb_cell("weight_lb", "2700")(tmp_path)       # 2,700 lb: above 2,550, below 1.25 x
    rc = main(["--root", str(generated_root), "--executor", "serial", "--quiet", "evaluate", "c172", "--data",
               str(data), "--report-dir", str(tmp_path / "r")])
    err = capsys.readouterr().err
    assert rc == 0 and "line 2 (row 1), column 'weight_lb': 2700 lb is above the" in err


def test_altitude_above_the_ceiling_warns(generated_root, tmp_path, capsys):
    data = climb_cell("pressure_alt_ft", "15000")(tmp_path)
    rc = main(["--root", str(generated_root), "--executor", "serial", "--quiet", "evaluate", "c172", "--data",
               str(data), "--report-dir", str(tmp_path / "r")])
    err = capsys.readouterr().err
    assert rc == 0 and "15000 ft is above the Cessna 172S Skyhawk SP's service ceiling 14000 ft" in err


# --------------------------------------------------------------------------- loaders under random damage
JUNK = st.sampled_from(["", " ", "nan", "NaN", "inf", "-inf", "1e400", "-1e400", "abc", "ISA", "0", "-0", "1e-300",
                        "3.2e4", "--5", "1,5", "\u00b0C", "\x00", "288.15", "-273.15", "99999999999999999999"])
CELL = st.one_of(JUNK, st.floats(allow_nan=True, allow_infinity=True).map(repr),
                 st.text(alphabet=st.characters(blacklist_categories=("Cs",), blacklist_characters=",\n\r"),
                         max_size=8))


@st.composite
def damaged(draw, text: str) -> bytes:
    """``text`` after one random kind of damage: cells replaced, truncated, lines dropped or
    repeated, a column rescaled (wrong units), or random bytes."""
    kind = draw(st.sampled_from(["cells", "truncate", "lines", "units", "garbage"]))
    lines = text.splitlines()
    if kind == "garbage":
        return draw(st.binary(max_size=400))
    if kind == "truncate":
        data = text.encode()
        return data[:draw(st.integers(0, len(data)))]
    if kind == "lines":
        keep = draw(st.lists(st.integers(0, len(lines) - 1), max_size=len(lines) + 3))
        return ("\n".join(lines[i] for i in keep) + "\n").encode()
    cells = [ln.split(",") for ln in lines]
    if kind == "units":
        j = draw(st.integers(0, len(cells[0]) - 1))
        scale, shift = draw(st.sampled_from([(1.8, 32.0), (1.0, 273.15), (3.28084, 0.0), (0.3048, 0.0),
                                             (0.4536, 0.0), (1.852, 0.0), (-1.0, 0.0)]))
        for r in cells[1:]:
            try:
                r[j] = repr(float(r[j]) * scale + shift)
            except (ValueError, IndexError):
                pass
    else:
        for _ in range(draw(st.integers(1, 6))):
            i, j = draw(st.integers(0, len(cells) - 1)), draw(st.integers(0, len(cells[0]) - 1))
            if j < len(cells[i]):
                cells[i][j] = draw(CELL)
    return ("\n".join(",".join(r) for r in cells) + "\n").encode()


def assert_no_nan(ds, columns) -> None:
    """Every schema column of a loaded dataset finite (a NaN never passes)."""
    for c in columns:
        if c in ds.frame:
            v = ds.frame[c].to_numpy(float)
            assert np.all(np.isfinite(v)), f"{c} passes non-finite values: {v}"


def load_or_refuse(fn, *args, **kw):
    """The loader's result, or None when it refused with the project's error."""
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            return fn(*args, **kw)
    except (DataError, InputError, GeometryError):
        return None


@pytest.fixture(scope="module")
def c172_geometry():
    from jsbsim_calib.jsbsim.product import load_aircraft_geometry
    return load_aircraft_geometry(REPO, "c172")


@EXAMPLES
@given(data=st.data())
def test_poh_loader_under_damage(data, tmp_path, c172_geometry):
    name = data.draw(st.sampled_from(["c172_poh_climb.csv", "c172_poh_cruise.csv", "sr20_poh_climb.csv",
                                      "c172_flight_test_flap_climb.csv"]))
    p = tmp_path / name
    p.write_bytes(data.draw(damaged((DATA / name).read_text())))
    ds = load_or_refuse(load_dataset, p, geometry=c172_geometry)
    if ds is not None:
        assert len(ds) > 0
        assert_no_nan(ds, ["pressure_alt_ft", "weight_lb", "kias", "ktas", "flaps_deg", *ds.metrics])
        if ds.kind.startswith("poh"):
            nan = np.full(len(ds), np.nan)
            oat = ds.frame["oat_c"].to_numpy(float) if "oat_c" in ds.frame else nan
            dev = ds.frame["temp_dev_c"].to_numpy(float) if "temp_dev_c" in ds.frame else nan
            assert np.all(np.isfinite(oat) | np.isfinite(dev)), "a row without a temperature passed"


@EXAMPLES
@given(data=st.data())
def test_snapshot_loader_under_damage(data, tmp_path, c172_geometry):
    p = tmp_path / "snap.csv"
    p.write_bytes(data.draw(damaged((DATA / "c172_flight_test_snapshots.csv").read_text())))
    ds = load_or_refuse(load_dataset, p, control_travel=DATA / "c172_control_travel.csv", geometry=c172_geometry)
    if ds is not None and ds.kind == "snapshot":
        assert len(ds) > 0
        assert_no_nan(ds, ["weight_lb", "cg_in", "flaps_deg", "pressure_alt_ft", "ktas", "vs_fpm", "pitch_deg",
                           "roll_deg", "elevator_deg", "aileron_deg", "rudder_deg"])


LOG_HEAD = "\n".join(LOG.read_text().splitlines()[:1400]) + "\n"      # taxi, take-off, climb and cruise


@settings(max_examples=max(1, N_EXAMPLES * 3 // 5), deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])
@given(data=st.data())
def test_g1000_loader_under_damage(data, tmp_path, c172_geometry):
    p = tmp_path / "log.csv"
    p.write_bytes(data.draw(damaged(LOG_HEAD)))
    ds = load_or_refuse(load_dataset, p, geometry=c172_geometry)
    if ds is not None:
        assert len(ds) > 0
        assert_no_nan(ds, ["pressure_alt_ft", "oat_c", "kcas", "ktas", "weight_lb", "pitch_deg"])
        cruise = ds.frame["kind"] == "cruise"
        assert np.all(np.isfinite(ds.frame.loc[cruise, "rpm"])) and np.all(np.isfinite(ds.frame.loc[~cruise, "roc_fpm"]))


@EXAMPLES
@given(data=st.data())
def test_a_spreadsheet_export_reads_as_the_csv(data, tmp_path, c172_geometry):
    """A POH or snapshot file exported another way (separator, decimal comma, header case, a
    byte-order mark, UTF-16, CRLF) loads to the same frame as the file itself."""
    name = data.draw(st.sampled_from(["c172_poh_climb.csv", "c172_poh_cruise.csv", "sr20_poh_climb.csv",
                                      "c172_flight_test_flap_climb.csv"]))
    lines = lines_of(name)
    sep = data.draw(st.sampled_from([",", ";", "\t"]))
    decimal = data.draw(st.sampled_from([".", ","])) if sep != "," else "."
    header = data.draw(st.sampled_from([str.lower, str.upper, str.title]))(lines[0])
    text = sheet([header, *lines[1:]], sep, decimal)
    if data.draw(st.booleans()):
        text = text.replace("\n", "\r\n")
    encoding = data.draw(st.sampled_from(["utf-8", "utf-8-sig", "utf-16", "utf-16-le"]))
    p = write(tmp_path, name, text.encode(encoding))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        got, want = load_dataset(p, geometry=c172_geometry), load_dataset(DATA / name, geometry=c172_geometry)
    assert got.kind == want.kind
    assert got.frame.equals(want.frame)


TH_HEADER = "time_s,pressure_alt_ft,ktas,vs_fpm,pitch_deg,roll_deg,q_deg_s,elevator_deg,throttle_norm"
TH_ROWS = [f"{i / 10:.1f},5500.0,{110 - 0.1 * i:.2f},0.0,{0.5 + 0.05 * i:.3f},0.0,0.5,{1.0 + 0.1 * i:.2f},0.8"
           for i in range(8)]
TH_META = {"test_id": "T.1", "title": "pitch pulse", "part60": "2.b.1", "kind": "pitch_pulse", "aircraft": "c172",
           "configuration": {"weight_lb": 2400.0, "cg_in": 42.0, "flaps_deg": 0.0, "mixture": "cruise"},
           "sample_rate_hz": 10.0, "inputs": ["elevator_deg"], "sources": {"pitch_deg": "AHRS"}}


@st.composite
def damaged_meta(draw) -> bytes:
    kind = draw(st.sampled_from(["keep", "value", "drop", "garbage", "truncate"]))
    doc = json.loads(json.dumps(TH_META))
    text = json.dumps(doc)
    if kind == "value":
        key = draw(st.sampled_from(["sample_rate_hz", "weight_lb", "cg_in", "flaps_deg", "mixture", "inputs", "title"]))
        value = draw(st.one_of(st.none(), st.booleans(), st.floats(), st.text(max_size=5), st.lists(st.integers(),
                                                                                                   max_size=2)))
        (doc["configuration"] if key in doc["configuration"] else doc)[key] = value
        text = json.dumps(doc)
    elif kind == "drop":
        doc.pop(draw(st.sampled_from(sorted(doc))))
        text = json.dumps(doc)
    elif kind == "garbage":
        return draw(st.binary(max_size=100))
    elif kind == "truncate":
        text = text[:draw(st.integers(0, len(text)))]
    return text.encode()


@EXAMPLES
@given(csv=damaged("\n".join([TH_HEADER, *TH_ROWS])), meta=damaged_meta())
def test_time_history_loader_under_damage(csv, meta, tmp_path):
    (tmp_path / "T_1.csv").write_bytes(csv)
    (tmp_path / "T_1.json").write_bytes(meta)
    th = load_or_refuse(load_time_history, tmp_path / "T_1.csv")
    if th is not None:
        assert np.all(np.isfinite(th.frame.to_numpy(float)))
        c = th.meta.configuration
        assert all(math.isfinite(v) for v in (c.weight_lb, c.cg_in, c.flaps_deg, c.isa_dev_c, th.meta.sample_rate_hz))


GEOMETRY = (REPO / "aircraft" / "c172" / "geometry.toml").read_text()
QUANTITY = re.compile(r'"(-?[0-9.]+) ([a-zA-Z0-9*/]+)"')


@st.composite
def damaged_geometry(draw) -> str:
    """The C172 geometry with a quantity's number or unit replaced, a line dropped, or cut."""
    kind = draw(st.sampled_from(["number", "unit", "drop", "truncate", "bare"]))
    lines = GEOMETRY.splitlines()
    if kind == "truncate":
        return GEOMETRY[:draw(st.integers(0, len(GEOMETRY)))]
    if kind == "drop":
        i = draw(st.integers(0, len(lines) - 1))
        return "\n".join(lines[:i] + lines[i + 1:])
    spots = [(i, m) for i, ln in enumerate(lines) for m in QUANTITY.finditer(ln)]
    i, m = draw(st.sampled_from(spots))
    if kind == "number":
        new = f'"{draw(st.sampled_from(["nan", "inf", "1e999", "-1", "0", "", "1e-320", "abc"]))} {m.group(2)}"'
    elif kind == "unit":
        new = f'"{m.group(1)} {draw(st.sampled_from(["m", "kg", "deg", "kt", "furlong", "", "ft2", "rpm"]))}"'
    else:
        new = draw(st.sampled_from(["nan", "inf", "-inf", "1e999", "true", "[]", '""']))
    lines[i] = lines[i][:m.start()] + new + lines[i][m.end():]
    return "\n".join(lines)


@EXAMPLES
@given(text=damaged_geometry())
def test_geometry_loader_under_damage(text, tmp_path):
    folder = tmp_path / "aircraft" / "c172"
    folder.mkdir(parents=True, exist_ok=True)
    for d in ("data", "airfoils"):
        if not (tmp_path / d).exists():
            (tmp_path / d).symlink_to(REPO / d, target_is_directory=True)
    (folder / "geometry.toml").write_text(text)
    g = load_or_refuse(load_geometry, folder / "geometry.toml", [REPO / "airfoils"])
    if g is not None:
        scalars = [g.reference.wing_area_m2, g.reference.span_m, g.mass.max_mass_kg, g.mass.empty_mass_kg,
                   g.propeller.diameter_m, g.engine.max_power_w, g.operations.poh_cg_m, g.fuselage.length_m]
        assert all(math.isfinite(v) for v in scalars), scalars
        for s in g.surfaces:
            assert np.all(np.isfinite(s.y_m)) and np.all(np.isfinite(s.chord_m))


# --------------------------------------------------------------------------- the README table
def readme_table(root: Path, first: int = 1) -> str:
    """The README's table (from case ``first``): each case with the first problem its run
    reports, or, read correctly, its last line."""
    import contextlib
    import io
    import tempfile

    rows = ["| # | test id | bad input: what is wrong | exit | what the user sees (first problem) |",
            "|---|---|---|---|---|"]
    for k, case in list(enumerate(CASES, 1))[first - 1:]:
        with tempfile.TemporaryDirectory() as d:
            buf = io.StringIO()
            out = io.StringIO()
            with contextlib.redirect_stderr(buf), contextlib.redirect_stdout(out):
                tmp = Path(d)
                r = copy_root(root, tmp / "root") if case.edit_root else root
                if case.edit_root:
                    case.edit_root(r)
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")
                    rc = main(["--root", str(r), "--executor", "serial", "--quiet", *case.argv(r, tmp)])
            text = (buf.getvalue() if rc else out.getvalue().strip().splitlines()[-1]).replace(d, "TMP").replace(
                str(root), "ROOT")
            lines = [ln.strip() for ln in text.splitlines() if ln.strip()]
            listed = [ln[2:] for ln in lines if ln.startswith("- ")]       # several problems: file, then the first
            first = f"{lines[0].rsplit(': ', 1)[0]}: {listed[0]}" if listed else (lines[0] if lines else "")
            first = first.replace("error: ", "").replace("|", "\\|")
            rows.append(f"| {k} | `{case.id}` | {case.what} | {rc} | {first[:200]} |")
    return "\n".join(rows)


if __name__ == "__main__":
    print(readme_table(Path(sys.argv[1]).resolve(), int(sys.argv[2]) if len(sys.argv) > 2 else 1))
