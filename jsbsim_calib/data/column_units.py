"""Units of a table's columns: declared in the header and converted, or judged by what the
numbers are.

Declared: a header may name its unit in brackets (``roc [m/s]``, ``oat (degF)``) or as a
suffix (``alt_m``, ``roc_mps``, ``weight_kg``); the column becomes the schema's column
(``roc_fpm``) in the schema's unit. A unit the quantity cannot have is refused.

Undeclared: a column whose values fit another unit far better than its own is refused,
naming the likely unit -- a POH climb rate of a few units (m/s, not the hundreds of ft/min
excess power gives a light single), a climb table whose climb rate would vanish far below the
service ceiling (altitudes in metres), percent power below 1.5 (a fraction), a fuel flow
three to four times what the engine burns per rated horsepower (litres per hour), a weight
below the aircraft's empty weight (kilograms).
"""
from __future__ import annotations

import re

import numpy as np
import pandas as pd

from ..core.errors import Problem

M_FT = 3.280839895
# dimension -> unit as written (lower case) -> (scale, offset) to the schema's unit
UNITS: dict[str, dict[str, tuple[float, float]]] = {
    "altitude": {"ft": (1, 0), "feet": (1, 0), "m": (M_FT, 0), "metres": (M_FT, 0), "meters": (M_FT, 0)},
    "climb": {"fpm": (1, 0), "ft/min": (1, 0), "mps": (60 * M_FT, 0), "m/s": (60 * M_FT, 0), "fps": (60, 0),
              "ft/s": (60, 0)},
    "speed": {"kt": (1, 0), "kts": (1, 0), "knots": (1, 0), "kn": (1, 0), "kmh": (1 / 1.852, 0),
              "km/h": (1 / 1.852, 0), "mph": (0.868976, 0), "mps": (1.943844, 0), "m/s": (1.943844, 0)},
    "weight": {"lb": (1, 0), "lbs": (1, 0), "kg": (2.20462262, 0)},
    "temperature": {"c": (1, 0), "degc": (1, 0), "deg c": (1, 0), "°c": (1, 0), "f": (5 / 9, -160 / 9),
                    "degf": (5 / 9, -160 / 9), "deg f": (5 / 9, -160 / 9), "°f": (5 / 9, -160 / 9),
                    "k": (1, -273.15)},
    "temperature difference": {"c": (1, 0), "degc": (1, 0), "k": (1, 0), "f": (5 / 9, 0), "degf": (5 / 9, 0)},
    "fuel flow": {"gph": (1, 0), "gal/h": (1, 0), "usgph": (1, 0), "lph": (0.264172052, 0), "l/h": (0.264172052, 0)},
    "power": {"%": (1, 0), "pct": (1, 0), "percent": (1, 0), "fraction": (100, 0)},
    "engine speed": {"rpm": (1, 0), "1/min": (1, 0)},
    "angle": {"deg": (1, 0), "degrees": (1, 0), "°": (1, 0), "rad": (57.2957795, 0)},
    "arm": {"in": (1, 0), "inch": (1, 0), "m": (39.3700787, 0), "cm": (0.393700787, 0), "mm": (0.0393700787, 0)},
}
# schema column -> (names it may be given, dimension)
QUANTITIES: dict[str, tuple[tuple[str, ...], str]] = {
    "pressure_alt_ft": (("pressure_alt", "alt", "altitude", "pressure_altitude", "hp"), "altitude"),
    "roc_fpm": (("roc", "rate_of_climb", "climb_rate"), "climb"),
    "vs_fpm": (("vs", "vertical_speed"), "climb"),
    "kias": (("kias", "ias"), "speed"),
    "ktas": (("ktas", "tas"), "speed"),
    "weight_lb": (("weight", "gross_weight", "mass"), "weight"),
    "oat_c": (("oat",), "temperature"),
    "temp_dev_c": (("temp_dev", "isa_dev"), "temperature difference"),
    "gph": (("gph", "fuel_flow", "ff"), "fuel flow"),
    "pct_power": (("pct_power", "power"), "power"),
    "rpm": (("rpm",), "engine speed"),
    "cg_in": (("cg",), "arm"),
    "flaps_deg": (("flaps",), "angle"),
    "pitch_deg": (("pitch",), "angle"),
}
_BRACKETED = re.compile(r"^(.*?)\s*[\[(]\s*([^\])]*?)\s*[\])]$")


def _column_of(name: str) -> str | None:
    for col, (names, _) in QUANTITIES.items():
        if name == col or name in names:
            return col
    return None


def _parse(header: str) -> tuple[str, str, str | None] | None:
    """(schema column, unit, None) of a header that declares a unit, (column, unit, problem) for
    a unit the quantity cannot have; None for a header without a unit of a known quantity."""
    m = _BRACKETED.match(header)
    if m:
        col = _column_of(m.group(1).strip())
        if col is None:
            return None
        dim = QUANTITIES[col][1]
        unit = m.group(2).strip()
        known = UNITS[dim]
        return col, unit, None if unit in known else f"unit '{unit}' is no {dim} unit; known: {', '.join(known)}"
    if _column_of(header) == header or "_" not in header:
        return None
    stem, suffix = header.rsplit("_", 1)
    col = _column_of(stem)
    if col is None or suffix not in UNITS[QUANTITIES[col][1]]:
        return None
    return col, suffix, None


def _convert(cells: pd.Series, scale: float, offset: float) -> pd.Series:
    """Text cells converted where they are numbers (the others left for the schema to name)."""
    def one(t: str) -> str:
        try:
            v = float(t)
        except ValueError:
            return t
        return f"{v * scale + offset:.10g}" if np.isfinite(v) else t
    return cells if (scale, offset) == (1, 0) else cells.astype(str).map(one)


def declared_units(raw: pd.DataFrame) -> tuple[pd.DataFrame, list[Problem]]:
    """``raw`` with every column whose header declares a unit renamed to its schema column and
    converted to the schema's unit; problems for unknown units and for a quantity given twice."""
    out, problems, renamed = raw.copy(), [], {}
    for j, h in enumerate(raw.columns):
        parsed = _parse(str(h).strip())
        if parsed is None:
            continue
        col, unit, why = parsed
        if why:
            problems.append(Problem(f"line 1, column '{h}'", why))
            continue
        if col in raw.columns or col in renamed.values():
            problems.append(Problem(f"line 1, column '{h}'", f"gives {col} a second time"))
            continue
        scale, offset = UNITS[QUANTITIES[col][1]][unit]
        out[h] = _convert(raw[h], scale, offset)
        renamed[h] = col
    return out.rename(columns=renamed), problems


# --------------------------------------------------------------------------- undeclared units
def _values(frame: pd.DataFrame, col: str) -> np.ndarray:
    v = frame[col].to_numpy(float) if col in frame else np.array([])
    return v[np.isfinite(v)]


def climb_rate_problems(frame: pd.DataFrame, geometry) -> list[Problem]:
    """A full-throttle climb rate of a few units: m/s, not ft/min. Excess power gives a light
    single hundreds of ft/min (at most ``33,000 x hp / weight``)."""
    roc = _values(frame, "roc_fpm")
    if not len(roc):
        return []
    med = float(np.median(np.abs(roc)))
    bound = 3000.0
    if geometry is not None and len(_values(frame, "weight_lb")):
        bound = 33000.0 * geometry.engine.max_power_w / 745.7 / float(np.median(_values(frame, "weight_lb")))
    factor = UNITS["climb"]["m/s"][0]
    if med < 40.0 and 100.0 <= med * factor <= 1.5 * bound:
        return [Problem("column 'roc_fpm'", f"median {med:g} ft/min: far below the hundreds of ft/min a full-throttle "
                                            f"climb gives (excess power: up to {bound:.0f} ft/min); the values fit "
                                            f"m/s ({med:g} m/s = {med * factor:.0f} ft/min): convert them or name "
                                            "the unit in the header ('roc [m/s]')")]
    return []


def altitude_problems(frame: pd.DataFrame, geometry) -> list[Problem]:
    """A climb table whose climb rate, fitted against altitude, would vanish far below the
    aircraft's service ceiling, and near it were the altitudes metres."""
    ceiling = geometry.operations.service_ceiling_m * M_FT if geometry is not None else float("nan")
    if "roc_fpm" not in frame or not np.isfinite(ceiling):
        return []
    h, roc = frame["pressure_alt_ft"].to_numpy(float), frame["roc_fpm"].to_numpy(float)
    ok = np.isfinite(h) & np.isfinite(roc)
    if ok.sum() < 3 or np.ptp(h[ok]) <= 0:
        return []
    slope, icpt = np.polyfit(h[ok], roc[ok], 1)
    if slope >= 0 or icpt <= 0:
        return []
    h0 = -icpt / slope                    # where the fitted climb rate reaches zero
    if h0 < 0.55 * ceiling and 0.8 * ceiling <= h0 * M_FT <= 3.0 * ceiling:
        return [Problem("column 'pressure_alt_ft'", f"the climb rate falls {-slope * 1000:.0f} ft/min per 1000 of "
                        f"altitude, to zero at {h0:.0f}, far below the service ceiling {ceiling:.0f} ft; in metres "
                        f"that is {h0 * M_FT:.0f} ft: convert the altitudes or name the unit ('alt [m]')")]
    return []


def power_problems(frame: pd.DataFrame, geometry) -> list[Problem]:
    """Percent power given as a fraction (0.77), fuel flow in litres per hour."""
    out = []
    pct = _values(frame, "pct_power")
    if len(pct) and pct.max() <= 1.5 and pct.max() > 0:
        out.append(Problem("column 'pct_power'", f"values {pct.min():g} to {pct.max():g}: a fraction of rated power, "
                                                 f"not percent ({pct.max():g} = {100 * pct.max():g} %); write percent "
                                                 "or name the unit ('power [fraction]')"))
    if geometry is None or "gph" not in frame:
        return out
    gph = frame["gph"].to_numpy(float)
    share = frame["pct_power"].to_numpy(float) / 100 if "pct_power" in frame and not out else np.full(len(gph), 0.7)
    ok = np.isfinite(gph) & np.isfinite(share) & (share > 0.2)
    if not ok.any():
        return out
    hp = geometry.engine.max_power_w / 745.7
    per_hp = float(np.median(gph[ok] / share[ok])) / hp       # gal/h per rated hp at full power: about 0.08
    litres = UNITS["fuel flow"]["l/h"][0]
    if per_hp > 0.16 and 0.035 <= per_hp * litres <= 0.14:
        out.append(Problem("column 'gph'", f"{per_hp:.2f} gal/h per rated hp at full power, about four times what a "
                                           f"piston engine burns (0.07-0.10); the values fit litres per hour "
                                           f"({per_hp * litres:.3f} gal/h per hp): convert them or name the unit "
                                           "('fuel_flow [l/h]')"))
    return out


def weight_problems(frame: pd.DataFrame, geometry) -> list[Problem]:
    """Weights below the aircraft's empty weight (kilograms?), each row named."""
    if geometry is None or "weight_lb" not in frame:
        return []
    empty = geometry.mass.empty_mass_kg * 2.20462262
    w = frame["weight_lb"].to_numpy(float)
    out = []
    for i in np.flatnonzero(np.isfinite(w) & (w < empty)):
        hint = f" (kilograms? {w[i]:g} kg = {w[i] * 2.20462262:.0f} lb)" if w[i] * 2.20462262 >= empty else ""
        out.append(Problem(f"line {i + 2} (row {i + 1}), column 'weight_lb'",
                           f"{w[i]:g} lb is below the aircraft's empty weight {empty:.0f} lb{hint}"))
    return out[:10]


def unit_problems(frame: pd.DataFrame, kind: str, geometry=None) -> list[Problem]:
    """Columns whose values fit another unit far better than their own (see the module docstring)."""
    out = power_problems(frame, geometry)
    if kind in ("poh_climb", "flap_climb"):
        out += climb_rate_problems(frame, geometry)
    if kind == "poh_climb":
        out += altitude_problems(frame, geometry)
    if kind.startswith("poh") or kind == "flap_climb":
        out += weight_problems(frame, geometry)
    return out
