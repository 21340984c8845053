"""Tests of the Garmin G1000 log import, air-data reduction and segment extraction."""
from __future__ import annotations

import io
import math
import warnings
from datetime import datetime, timedelta
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from jsbsim_calib.core.errors import DataError
from jsbsim_calib.data.g1000.parse import REQUIRED_CHANNELS, G1000DataWarning, G1000Log, read_g1000
from jsbsim_calib.data.g1000.segments import (
    Segment,
    SegmentCriteria,
    WeightAssumption,
    extract_segments,
    segments_dataframe,
)
from jsbsim_calib.physics.atmosphere import isa_temperature_c, kcas_from_kias, ktas_from_kcas, pressure_altitude_ft
from jsbsim_calib.report.plots import PLOT_PANELS, plot_log

REAL_LOG = Path(__file__).resolve().parents[1] / "data" / "g1000" / "log_110812_095915_KCKN.csv"

AIRFRAME = ('#airframe_info, log_version="1.00", airframe_name="Cessna 172S", '
            'unit_software_part_number="006-B0319-81", system_id="TEST123", mode=NORMAL, ')

# (column, unit) of the synthetic logs: the required channels plus a few others
COLUMNS = [
    ("Lcl Date", "yyy-mm-dd"), ("Lcl Time", "hh:mm:ss"), ("UTCOfst", "hh:mm"),
    ("AtvWpt", "ident"), ("AltB", "ft Baro"), ("BaroA", "inch"), ("OAT", "deg C"),
    ("IAS", "kt"), ("GndSpd", "kt"), ("VSpd", "fpm"), ("Pitch", "deg"), ("Roll", "deg"),
    ("HDG", "deg"), ("FQtyL", "gals"), ("FQtyR", "gals"), ("E1 FFlow", "gph"),
    ("E1 RPM", "rpm"), ("TAS", "kt"), ("HSIS", "enum"), ("GPSfix", "enum"),
]
NAMES = [c for c, _ in COLUMNS]


def g1000_text(rows: list[list[object]], *, columns=COLUMNS, units: bool = True,
               airframe: bool = True, pad: bool = True) -> str:
    """A G1000-style CSV: airframe line, units line, padded header, padded rows."""
    def fmt(cells: list[object]) -> str:
        return ", ".join((f"{c:>8}" if pad else str(c)) for c in cells)

    lines = []
    if airframe:
        lines.append(AIRFRAME)
    if units:
        lines.append("#" + fmt([u for _, u in columns]))
    lines.append(fmt([c for c, _ in columns]))
    lines += [fmt(r) for r in rows]
    return "\n".join(lines) + "\n"


def row(second: int, **over: object) -> list[object]:
    """One plausible cruise row at 09:00:00 + second; keyword names use _ for blanks."""
    t = datetime(2020, 5, 1, 9, 0, 0) + timedelta(seconds=second)
    values = {
        "Lcl Date": t.strftime("%Y-%m-%d"), "Lcl Time": t.strftime("%H:%M:%S"),
        "UTCOfst": "-05:00", "AtvWpt": "KXYZ", "AltB": 4500.0, "BaroA": 29.92, "OAT": 10.0,
        "IAS": 105.0, "GndSpd": 110.0, "VSpd": 0.0, "Pitch": 1.5, "Roll": 0.5, "HDG": 90.0,
        "FQtyL": 20.0, "FQtyR": 19.0, "E1 FFlow": 9.5, "E1 RPM": 2450.0, "TAS": 113,
        "HSIS": "GPS", "GPSfix": "3D",
    }
    for k, v in over.items():
        values[k.replace("_", " ")] = v
    return [values[c] for c in NAMES]


def write(tmp_path: Path, text: str, name: str = "log.csv") -> Path:
    p = tmp_path / name
    p.write_text(text)
    return p


def g1000_warnings(record) -> list[str]:
    return [str(w.message) for w in record if issubclass(w.category, G1000DataWarning)]


# --------------------------------------------------------------------------------------------
# import: the real example log
# --------------------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def real_log() -> G1000Log:
    with warnings.catch_warnings(record=True) as rec:
        warnings.simplefilter("always")
        log = read_g1000(REAL_LOG)
    msgs = g1000_warnings(rec)
    # the example file ends in a cut-off line (59 of 64 fields, no newline)
    assert len(msgs) == 1 and "line 3970" in msgs[0] and "truncated" in msgs[0]
    return log


def test_real_log_imports(real_log: G1000Log) -> None:
    d = real_log.data
    assert len(d) == 3966                       # 3967 data lines, the truncated last one dropped
    assert real_log.airframe["airframe_name"] == "Cessna 172S"
    assert real_log.airframe["system_id"] == "24B6FD7AC"
    assert real_log.airframe["unit_software_version"] == "10.01"
    assert real_log.units["AltB"] == "ft Baro"
    assert real_log.units["E1 FFlow"] == "gph"
    assert real_log.start_time == datetime(2011, 8, 12, 9, 59, 7)
    # 09:59:07 to 11:06:25 local
    assert 65.0 <= real_log.duration_s / 60.0 <= 68.0
    assert d["time_s"].iloc[0] == 0.0
    assert np.all(np.diff(d["time_s"].to_numpy()) > 0)
    for col in REQUIRED_CHANNELS + ("TAS", "GndSpd", "AltMSL", "LatAc", "NormAc", "HDG",
                                    "WndSpd", "WndDr", "E1 CHT1"):
        assert d[col].dtype == np.float64, col
    for col in ("AtvWpt", "HSIS", "GPSfix"):
        assert d[col].dtype == object, col
    assert d["AtvWpt"].isna().iloc[0]           # blank at the start of the log
    assert d["AtvWpt"].iloc[-1] == "KGFK"
    assert d["HSIS"].iloc[0] == "GPS"
    assert d["AltB"].iloc[0] == pytest.approx(861.5)
    assert d["E1 RPM"].max() == pytest.approx(2623.7)


def test_text_stream_equals_file(tmp_path: Path) -> None:
    text = g1000_text([row(0), row(1), row(2)])
    from_file = read_g1000(write(tmp_path, text))
    from_stream = read_g1000(io.StringIO(text))
    assert from_stream.path == "<stream>"
    pd.testing.assert_frame_equal(from_file.data, from_stream.data)
    assert from_file.airframe == from_stream.airframe
    assert from_file.airframe["system_id"] == "TEST123"
    assert from_file.airframe["mode"] == "NORMAL"


# --------------------------------------------------------------------------------------------
# import: edge cases
# --------------------------------------------------------------------------------------------

def test_blank_cells_whitespace_and_blank_lines(tmp_path: Path) -> None:
    rows = [row(0), row(1, AltB="", AtvWpt=""), row(2, E1_FFlow="   ")]
    text = g1000_text(rows).replace("\n", "\n\n   \n", 2) + "\n\n"
    log = read_g1000(write(tmp_path, text))
    d = log.data
    assert len(d) == 3
    assert math.isnan(d["AltB"].iloc[1]) and d["AltB"].iloc[0] == 4500.0
    assert math.isnan(d["E1 FFlow"].iloc[2])
    assert d["AtvWpt"].isna().iloc[1] and d["AtvWpt"].iloc[0] == "KXYZ"
    assert "E1 RPM" in d.columns and " E1 RPM" not in d.columns
    assert d["E1 RPM"].dtype == np.float64


def test_repeated_timestamps_are_spread_inside_their_second(tmp_path: Path) -> None:
    seconds = [0, 1, 1, 1, 2, 2, 4, 5]
    rows = [row(s, E1_RPM=2400 + k) for k, s in enumerate(seconds)]
    log = read_g1000(write(tmp_path, g1000_text(rows)))
    t = log.data["time_s"].to_numpy()
    assert len(t) == len(seconds)                 # every sample kept
    np.testing.assert_allclose(t, [0, 1, 1 + 1 / 3, 1 + 2 / 3, 2, 2.5, 4, 5])
    np.testing.assert_allclose(log.data["E1 RPM"], 2400 + np.arange(8))   # order preserved


def test_missing_units_line(tmp_path: Path) -> None:
    log = read_g1000(write(tmp_path, g1000_text([row(0), row(1)], units=False)))
    assert log.units == {}
    assert len(log.data) == 2
    assert log.data["IAS"].iloc[1] == 105.0
    assert log.airframe["airframe_name"] == "Cessna 172S"


def test_header_only_file_without_airframe_line(tmp_path: Path) -> None:
    log = read_g1000(write(tmp_path, g1000_text([row(0), row(1)], airframe=False)))
    assert log.airframe == {}
    assert log.units["BaroA"] == "inch"
    assert len(log.data) == 2


def test_truncated_last_line_dropped_with_warning(tmp_path: Path) -> None:
    text = g1000_text([row(0), row(1), row(2)])
    text = text[: text.rstrip("\n").rfind(",", 0, len(text) - 40)]   # cut inside the last row
    with pytest.warns(G1000DataWarning, match=r"line 6: last line is truncated") as rec:
        log = read_g1000(write(tmp_path, text))
    assert len(g1000_warnings(rec)) == 1
    assert len(log.data) == 2


def test_wrong_field_count_row_dropped_naming_the_line(tmp_path: Path) -> None:
    rows = [row(s) for s in range(6)]
    text = g1000_text(rows).split("\n")
    text[5] = text[5] + ", 12.0, 13.0"             # line 6: two fields too many
    text[6] = ",".join(text[6].split(",")[:10])    # line 7: too few, not the last line
    with warnings.catch_warnings(record=True) as rec:
        warnings.simplefilter("always")
        log = read_g1000(write(tmp_path, "\n".join(text)))
    msgs = g1000_warnings(rec)
    assert len(msgs) == 2
    assert "line 6" in msgs[0] and "22 fields, expected 20" in msgs[0]
    assert "line 7" in msgs[1] and "10 fields, expected 20" in msgs[1]
    assert len(log.data) == 4
    assert list(log.data["Lcl Time"]) == ["09:00:00", "09:00:01", "09:00:04", "09:00:05"]


def test_trailing_comma_is_accepted(tmp_path: Path) -> None:
    text = "\n".join(line + ", " for line in g1000_text([row(0), row(1)]).split("\n")[:-1])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        log = read_g1000(write(tmp_path, text))
    assert len(log.data) == 2 and log.units["E1 RPM"] == "rpm"


def test_bad_timestamp_row_dropped(tmp_path: Path) -> None:
    rows = [row(0), row(1, Lcl_Time="9:xx"), row(2)]
    with pytest.warns(G1000DataWarning, match=r"line 5: unreadable date/time"):
        log = read_g1000(write(tmp_path, g1000_text(rows)))
    np.testing.assert_allclose(log.data["time_s"], [0.0, 2.0])


def test_not_a_g1000_file(tmp_path: Path) -> None:
    with pytest.raises(DataError, match="not a Garmin G1000 log") as exc:
        read_g1000(write(tmp_path, "time,alt,speed\n0,100,50\n1,110,52\n"))
    assert len(exc.value.problems) == 1
    assert str(tmp_path / "log.csv") in str(exc.value)


def test_airframe_line_without_header(tmp_path: Path) -> None:
    with pytest.raises(DataError, match="no column header"):
        read_g1000(write(tmp_path, AIRFRAME + "\n#units, more\n1, 2, 3\n"))


def test_missing_channels_are_all_listed(tmp_path: Path) -> None:
    drop = {"VSpd", "E1 RPM", "FQtyR", "OAT"}
    cols = [(c, u) for c, u in COLUMNS if c not in drop]
    rows = [[v for (c, _), v in zip(COLUMNS, row(0)) if c not in drop]]
    with pytest.raises(DataError) as exc:
        read_g1000(write(tmp_path, g1000_text(rows, columns=cols)))
    msg = str(exc.value)
    for c in drop:
        assert c in msg
    assert "missing required channel(s): OAT, VSpd, E1 RPM, FQtyR" in msg


def test_wrong_units_are_errors(tmp_path: Path) -> None:
    cols = [(c, {"AltB": "m", "IAS": "km/h"}.get(c, u)) for c, u in COLUMNS]
    with pytest.raises(DataError) as exc:
        read_g1000(write(tmp_path, g1000_text([row(0)], columns=cols)))
    assert len(exc.value.problems) == 2
    assert "column AltB" in str(exc.value) and "column IAS" in str(exc.value)


@pytest.mark.parametrize("text", ["", "   \n\n  \n"])
def test_empty_file(tmp_path: Path, text: str) -> None:
    with pytest.raises(DataError, match="empty"):
        read_g1000(write(tmp_path, text))


def test_no_valid_rows(tmp_path: Path) -> None:
    text = g1000_text([]) + "2020-05-01, 09:00:00, 1, 2\n"
    with pytest.warns(G1000DataWarning), pytest.raises(DataError, match="no valid data rows"):
        read_g1000(write(tmp_path, text))


def test_missing_file(tmp_path: Path) -> None:
    with pytest.raises(DataError, match="cannot read"):
        read_g1000(tmp_path / "nope.csv")


# --------------------------------------------------------------------------------------------
# air data
# --------------------------------------------------------------------------------------------

def isa_pressure_altitude(alt_b: float, baro: float) -> float:
    """The ISA relations written out independently, with the textbook constants."""
    p = baro * (1.0 - 6.8756e-6 * alt_b) ** 5.2559
    return (1.0 - (p / 29.92) ** (1.0 / 5.2559)) / 6.8756e-6


def test_pressure_altitude() -> None:
    assert pressure_altitude_ft(5000.0, 29.92) == pytest.approx(5000.0, abs=0.5)
    hp = pressure_altitude_ft(5000.0, 30.42)
    assert hp == pytest.approx(isa_pressure_altitude(5000.0, 30.42), abs=5.0)
    assert 4500.0 < hp < 4600.0                  # high pressure: pressure altitude below AltB
    # low setting raises it; arrays work element-wise
    arr = pressure_altitude_ft(np.array([0.0, 2500.0, 8000.0]), np.array([29.42, 29.92, 30.12]))
    expected = [isa_pressure_altitude(a, b) for a, b in [(0, 29.42), (2500, 29.92), (8000, 30.12)]]
    np.testing.assert_allclose(arr, expected, atol=5.0)
    assert arr[0] > 400.0
    # not the 1000 ft/inHg rule of thumb
    assert abs(hp - 4500.0) > 30.0


def test_isa_temperature() -> None:
    assert isa_temperature_c(0.0) == pytest.approx(15.0)
    assert isa_temperature_c(10000.0) == pytest.approx(-4.81, abs=0.01)


def test_kcas_from_kias() -> None:
    assert kcas_from_kias(100.0) == 100.0
    np.testing.assert_array_equal(kcas_from_kias(np.array([60.0, 90.0])), [60.0, 90.0])
    table = ([50.0, 80.0, 120.0], [56.0, 80.0, 118.0])
    np.testing.assert_allclose(kcas_from_kias(np.array([40.0, 50.0, 65.0, 100.0, 140.0]), table),
                               [46.0, 56.0, 68.0, 99.0, 138.0])
    with pytest.raises(ValueError):
        kcas_from_kias(80.0, ([80.0, 50.0], [80.0, 56.0]))


def test_ktas_from_kcas() -> None:
    assert ktas_from_kcas(100.0, 0.0, 15.0) == pytest.approx(100.0, abs=1e-9)
    # 10000 ft ISA: density ratio 0.7385 -> EAS/sqrt(sigma) = 116.4 kt, compressibility a bit less
    v = ktas_from_kcas(100.0, 10000.0, isa_temperature_c(10000.0))
    assert 115.5 < v < 116.4
    # warmer air: faster
    assert ktas_from_kcas(100.0, 5000.0, 30.0) > ktas_from_kcas(100.0, 5000.0, 0.0)


def test_ktas_matches_logged_tas(real_log: G1000Log) -> None:
    d = real_log.data[real_log.data["IAS"] > 50.0]
    hp = pressure_altitude_ft(d["AltB"].to_numpy(), d["BaroA"].to_numpy())
    ktas = ktas_from_kcas(kcas_from_kias(d["IAS"].to_numpy()), hp, d["OAT"].to_numpy())
    diff = ktas - d["TAS"].to_numpy()             # the G1000 logs TAS in whole knots
    assert len(d) > 2000
    assert np.max(np.abs(diff)) < 1.0
    assert abs(np.mean(diff)) < 0.1


# --------------------------------------------------------------------------------------------
# segments on a synthetic flight with known segments
# --------------------------------------------------------------------------------------------

FIELD_ALT_FT = 2800.0   # [ft] AltB on the ground; the level legs are at about 5500 ft
BARO_INHG = 30.12
# (kind, start, end) [s] of the quasi-steady segments of synthetic_flight()
KNOWN = [("climb", 150.0, 350.0), ("cruise", 390.0, 710.0), ("cruise", 795.0, 1100.0)]


def _ar1(rng: np.random.Generator, n: int, std: float, rho: float) -> np.ndarray:
    e = rng.normal(0.0, std * math.sqrt(1 - rho * rho), n)
    x = np.empty(n)
    x[0] = rng.normal(0.0, std)
    for k in range(1, n):
        x[k] = rho * x[k - 1] + e[k]
    return x


def synthetic_flight(seed: int = 7) -> tuple[str, pd.DataFrame]:
    """A 1280 s flight: 100 s taxi, take-off roll, 25 s initial climb at 63 kt (flaps, below
    300 ft: not a segment), 200 s climb at 75 kt, 700 ft/min and 2400 rpm, level-off and
    acceleration, level at about 5500 ft and 2450 rpm until 710 s, a 25 deg turn, power
    reduction to 2200 rpm and deceleration, level until 1100 s, then a 500 ft/min descent at
    1900 rpm. Samples every 1.017 s +-0.35 s stamped with the whole second (so some seconds
    repeat and some are missing), with turbulence-like noise. Returns the CSV text and the
    true (noise-free) time histories."""
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, 1280.0, 1.017)
    t[1:] += rng.uniform(-0.35, 0.35, len(t) - 1)          # write jitter of the recorder
    n = len(t)

    def sched(knots: list[tuple[float, float]]) -> np.ndarray:
        x, y = zip(*knots)
        return np.interp(t, x, y)

    vs = sched([(0, 0), (118, 0), (122, 600), (145, 600), (150, 700), (350, 700), (360, 0),
                (1100, 0), (1110, -500), (1280, -500)])
    ias = sched([(0, 0), (100, 0), (118, 55), (122, 63), (145, 63), (152, 75), (350, 75),
                 (390, 105), (710, 105), (720, 103), (775, 103), (795, 95), (1100, 95),
                 (1110, 100), (1280, 100)])
    rpm = sched([(0, 1000), (99, 1000), (103, 2300), (118, 2330), (145, 2350), (152, 2400),
                 (350, 2400), (375, 2600), (380, 2600), (385, 2450), (770, 2450), (775, 2200),
                 (1100, 2200), (1105, 1900), (1280, 1900)])
    roll = sched([(0, 0), (710, 0), (714, 25), (766, 25), (770, 0), (1280, 0)])
    pitch = sched([(0, 2.5), (115, 2.5), (122, 9), (145, 9), (152, 8), (350, 8), (360, 2),
                   (390, 1.5), (775, 1.5), (795, 3), (1100, 3), (1110, -1), (1280, -1)])
    ff = sched([(0, 2.5), (100, 2.5), (103, 15.5), (360, 15.5), (380, 15.8), (385, 10.5),
                (770, 10.5), (775, 8.2), (1100, 8.2), (1105, 5.0), (1280, 5.0)])
    gs = np.where(t < 100, np.clip(t / 10.0, 0, 8), ias + 5.0)
    alt = FIELD_ALT_FT + np.concatenate([[0.0], np.cumsum(np.diff(t) * (vs[1:] + vs[:-1]) / 120)])
    hp_true = pressure_altitude_ft(alt, BARO_INHG)
    oat = 15.0 - 1.98 * hp_true / 1000.0 + 4.0     # ISA + 4
    fuel = 40.0 - np.cumsum(ff * np.gradient(t)) / 3600.0
    truth = pd.DataFrame({"t": t, "vs": vs, "ias": ias, "rpm": rpm, "roll": roll, "pitch": pitch,
                          "ff": ff, "alt": alt, "oat": oat, "fuel": fuel})

    air = t >= 118
    ias_m = ias + air * (rng.normal(0, 0.5, n) + _ar1(rng, n, 0.5, 0.9))
    vs_m = vs + _ar1(rng, n, 90.0, 0.7) * np.where(air, 1.0, 0.15)
    alt_m = alt + _ar1(rng, n, 12.0, 0.9) * np.where(air, 1.0, 0.1)
    roll_m = roll + _ar1(rng, n, 2.0, 0.9) * np.where(air, 1.0, 0.05)
    pitch_m = pitch + _ar1(rng, n, 0.4, 0.8)
    rpm_m = rpm + rng.normal(0, 6.0, n)
    ff_m = ff + rng.normal(0, 0.08, n)
    oat_m = oat + rng.normal(0, 0.1, n)
    tas = ktas_from_kcas(ias, hp_true, oat)

    t0 = datetime(2020, 5, 1, 10, 0, 0)
    rows = []
    for k in range(n):
        stamp = t0 + timedelta(seconds=int(t[k]))
        rows.append([stamp.strftime("%Y-%m-%d"), stamp.strftime("%H:%M:%S"), "-05:00", "",
                     f"{alt_m[k]:.1f}", f"{BARO_INHG:.2f}", f"{oat_m[k]:.1f}", f"{ias_m[k]:.2f}",
                     f"{gs[k]:.2f}", f"{vs_m[k]:.2f}", f"{pitch_m[k]:.2f}", f"{roll_m[k]:.2f}",
                     "90.0", f"{fuel[k] / 2:.2f}", f"{fuel[k] / 2:.2f}", f"{ff_m[k]:.2f}",
                     f"{rpm_m[k]:.1f}", f"{max(tas[k], 0):.0f}", "GPS", "3D"])
    return g1000_text(rows), truth


@pytest.fixture(scope="module")
def synthetic() -> tuple[G1000Log, pd.DataFrame, list[Segment]]:
    text, truth = synthetic_flight()
    log = read_g1000(io.StringIO(text))
    return log, truth, extract_segments(log)


def test_synthetic_log_has_repeated_seconds(synthetic) -> None:
    log, truth, _ = synthetic
    stamps = log.data["Lcl Time"]
    assert stamps.duplicated().sum() > 5               # the 1.017 s sampling repeats seconds
    assert len(log.data) == len(truth)
    assert np.max(np.abs(log.data["time_s"] - truth["t"])) < 1.0


def test_synthetic_segments_found(synthetic) -> None:
    log, truth, segs = synthetic
    assert [s.kind for s in segs] == [k for k, _, _ in KNOWN]
    for s, (kind, a, b) in zip(segs, KNOWN):
        assert s.t_start_s == pytest.approx(a, abs=10.0), (kind, s.t_start_s)
        assert s.t_end_s == pytest.approx(b, abs=10.0), (kind, s.t_end_s)
        assert s.duration_s == pytest.approx(s.t_end_s - s.t_start_s)
        assert s.n_samples == pytest.approx(s.duration_s, rel=0.05)
        sel = truth[(truth.t >= s.t_start_s) & (truth.t <= s.t_end_s)]
        hp = pressure_altitude_ft(sel.alt.to_numpy(), BARO_INHG).mean()
        assert s.pressure_alt_ft == pytest.approx(hp, abs=25.0)
        assert s.oat_c == pytest.approx(sel.oat.mean(), abs=0.2)
        assert s.isa_dev_c == pytest.approx(4.0, abs=0.3)
        assert s.kias == pytest.approx(sel.ias.mean(), abs=1.0)
        assert s.kcas == s.kias
        tas = ktas_from_kcas(sel.ias.to_numpy(), hp, sel.oat.mean()).mean()
        assert s.ktas == pytest.approx(tas, abs=1.5)
        assert s.ktas_logged == pytest.approx(s.ktas, abs=1.5)
        assert s.rpm == pytest.approx(sel.rpm.mean(), abs=8.0)
        assert s.fuel_flow_gph == pytest.approx(sel.ff.mean(), abs=0.2)
        assert s.pitch_deg == pytest.approx(sel.pitch.mean(), abs=0.5)
        assert abs(s.roll_deg) < 3.0
        assert s.fuel_gal == pytest.approx(sel.fuel.mean(), abs=0.05)
        assert s.weight_lb == pytest.approx(1663 + 340 + 6.0 * sel.fuel.mean(), abs=0.5)
        assert 0.2 < s.std["kias"] < 2.0 and 2.0 < s.std["rpm"] < 15.0
        assert 40.0 < s.std["vs_fpm"] < 150.0
    climb, cruise1, cruise2 = segs
    assert climb.vs_fpm == pytest.approx(700.0, abs=40.0)
    assert climb.rpm == pytest.approx(2400.0, abs=8.0)
    assert cruise1.rpm == pytest.approx(2450.0, abs=8.0) and abs(cruise1.vs_fpm) < 30.0
    assert cruise1.pressure_alt_ft == pytest.approx(
        pressure_altitude_ft(truth.alt.max(), BARO_INHG), abs=25.0)
    assert cruise1.pressure_alt_ft < truth.alt.max() - 150.0   # 30.12 inHg: Hp below AltB
    assert cruise2.rpm == pytest.approx(2200.0, abs=8.0)
    assert cruise2.kias == pytest.approx(95.0, abs=1.0)


def test_turn_ground_and_descent_not_reported(synthetic) -> None:
    _, _, segs = synthetic
    for s in segs:
        assert s.t_end_s < 720.0 or s.t_start_s > 760.0      # the turn
        assert s.t_start_s > 140.0          # taxi, take-off roll, slow initial climb
        assert s.t_end_s < 1115.0                             # the descent
        assert s.kias > 70.0


def test_stricter_criteria_find_fewer(synthetic) -> None:
    log, _, segs = synthetic
    assert extract_segments(log, SegmentCriteria(max_cruise_ias_std_kt=0.1)) == [segs[0]]
    assert [s.kind for s in extract_segments(log, SegmentCriteria(min_climb_rpm=2500))] == \
        ["cruise", "cruise"]
    long_only = extract_segments(log, SegmentCriteria(min_cruise_duration_s=400.0))
    assert long_only == [segs[0]]


def test_weight_assumption_is_a_parameter(synthetic) -> None:
    log, _, segs = synthetic
    heavy = extract_segments(log, weight=WeightAssumption(empty_weight_lb=1700.0, occupants_lb=400,
                                                          baggage_lb=20.0))
    for a, b in zip(segs, heavy):
        assert b.weight_lb - a.weight_lb == pytest.approx(37 + 60 + 20)
    assert WeightAssumption().weight_lb(10.0) == 1663 + 340 + 60


def test_segments_dataframe(synthetic) -> None:
    _, _, segs = synthetic
    df = segments_dataframe(segs)
    assert len(df) == len(segs)
    for col in ("pressure_alt_ft", "oat_c", "isa_dev_c", "kias", "kcas", "ktas", "vs_fpm", "rpm",
                "gph", "pitch_deg", "weight_lb", "kind", "t_start_s", "duration_s", "rpm_std"):
        assert col in df.columns, col
    assert list(df["kind"]) == ["climb", "cruise", "cruise"]
    assert df["gph"].iloc[1] == segs[1].fuel_flow_gph
    assert df["rpm_std"].iloc[2] == segs[2].std["rpm"]
    empty = segments_dataframe([])
    assert empty.empty and "ktas" in empty.columns


# --------------------------------------------------------------------------------------------
# segments on the real log
# --------------------------------------------------------------------------------------------

def test_real_log_segments(real_log: G1000Log) -> None:
    segs = extract_segments(real_log)
    kinds = [s.kind for s in segs]
    assert kinds.count("cruise") >= 1
    assert kinds.count("climb") >= 1
    starts = [s.t_start_s for s in segs]
    assert starts == sorted(starts)
    for a, b in zip(segs, segs[1:]):
        assert a.t_end_s < b.t_start_s                     # no overlap
    for s in segs:
        assert 1800.0 <= s.rpm <= 2750.0
        assert 70.0 <= s.ktas <= 140.0
        assert s.duration_s >= 30.0
        assert abs(s.ktas - s.ktas_logged) < 1.0
        assert 2150.0 < s.weight_lb < 2250.0
        if s.kind == "cruise":
            assert abs(s.vs_fpm) < 100.0 and s.fuel_flow_gph > 5.0
        else:
            assert s.vs_fpm > 300.0 and s.rpm >= 2250.0 and s.pitch_deg > 0.0
    # the long cruise at about 2500 ft, 2480 rpm and 11.5 gal/h, from 45 to 52 minutes
    longest = max((s for s in segs if s.kind == "cruise"), key=lambda s: s.duration_s)
    assert longest.duration_s > 300.0
    assert longest.pressure_alt_ft == pytest.approx(2560.0, abs=60.0)
    assert longest.rpm == pytest.approx(2480.0, abs=20.0)
    assert longest.fuel_flow_gph == pytest.approx(11.5, abs=0.3)


# --------------------------------------------------------------------------------------------
# plot
# --------------------------------------------------------------------------------------------

def test_plot_log(synthetic, tmp_path: Path) -> None:
    from matplotlib.figure import Figure

    log, _, segs = synthetic
    model = pd.DataFrame({"t_start_s": [s.t_start_s for s in segs],
                          "rpm": [s.rpm + 20.0 for s in segs],
                          "roc_fpm": [s.vs_fpm if s.kind == "climb" else np.nan for s in segs],
                          "pitch_deg": [s.pitch_deg - 0.5 for s in segs]})
    fig = plot_log(log, segs, model=model)
    assert isinstance(fig, Figure)
    axes = fig.get_axes()
    assert len(axes) == len(PLOT_PANELS) == 6
    rpm_ax = axes[PLOT_PANELS.index("rpm")]
    assert "model" in rpm_ax.get_legend_handles_labels()[1]
    # 3 segments x 6 panels shaded
    assert sum(len(a.patches) for a in axes) == 3 * 6
    out = tmp_path / "log.png"
    fig.savefig(out, dpi=60)
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert out.stat().st_size > 10_000

    fig2 = plot_log(log, [])
    assert len(fig2.get_axes()) == 6
    with pytest.raises(ValueError, match="roc_fpm"):
        plot_log(log, segs, model=model.drop(columns="roc_fpm"))
