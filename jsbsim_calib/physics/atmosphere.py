"""International Standard Atmosphere (troposphere and lower stratosphere) and air data: the
one place that converts altitudes, temperatures and airspeeds.

The standard atmosphere is SI in, SI out. Pressure altitude is geopotential altitude in the
standard atmosphere that has the given static pressure.

Air data (the units of cockpits and data files: knots, feet, inches of mercury, degrees
Celsius) are built on it:

* :func:`pressure_altitude_ft` from the altimeter's indicated altitude and setting;
* :func:`isa_temperature_c` at a pressure altitude;
* :func:`kcas_from_kias` and its inverse :func:`kias_from_kcas` through an aircraft's
  airspeed-calibration table (the position error of its airspeed indicator). Between the
  table's points the correction KCAS - KIAS is interpolated linearly; beyond its ends the
  correction of the end point is held, in both directions, so the two functions are exact
  inverses everywhere;
* :func:`ktas_from_kcas` at a pressure altitude and outside air temperature (compressible,
  subsonic).
"""
from __future__ import annotations

import functools
import math
from typing import Any, Sequence

import numpy as np

from ..core.units import FT, GAMMA, LAPSE, P0, R_AIR, T0, G0, KT

_H_TROP = 11000.0                       # [m] tropopause (geopotential)
_T_TROP = T0 - LAPSE * _H_TROP          # [K]
_P_TROP = P0 * (_T_TROP / T0) ** (G0 / (R_AIR * LAPSE))
A0 = math.sqrt(GAMMA * R_AIR * T0)      # [m/s] sea-level speed of sound


def isa_temperature(h_m):
    """Standard temperature [K] at geopotential altitude h [m]."""
    h = np.asarray(h_m, float)
    return np.where(h < _H_TROP, T0 - LAPSE * h, _T_TROP)


@functools.lru_cache(maxsize=4096)
def isa_at_ft(pressure_alt_ft: float) -> tuple[float, float]:
    """ISA temperature [K] and pressure [Pa] at a pressure altitude [ft], as floats: the values of
    :func:`isa_temperature` and :func:`isa_pressure`, kept (a fit trims the same few altitudes
    tens of thousands of times)."""
    h = pressure_alt_ft * FT
    return float(isa_temperature(h)), float(isa_pressure(h))


def isa_pressure(h_m):
    """Standard static pressure [Pa] at geopotential altitude h [m]."""
    h = np.asarray(h_m, float)
    tro = P0 * (1.0 - LAPSE * h / T0) ** (G0 / (R_AIR * LAPSE))
    strat = _P_TROP * np.exp(-G0 * (h - _H_TROP) / (R_AIR * _T_TROP))
    return np.where(h < _H_TROP, tro, strat)


def pressure_altitude(p_pa):
    """Pressure altitude [m] for a static pressure [Pa]."""
    p = np.asarray(p_pa, float)
    tro = T0 / LAPSE * (1.0 - (p / P0) ** (R_AIR * LAPSE / G0))
    strat = _H_TROP - R_AIR * _T_TROP / G0 * np.log(p / _P_TROP)
    return np.where(p > _P_TROP, tro, strat)


def density(p_pa, t_k):
    return np.asarray(p_pa, float) / (R_AIR * np.asarray(t_k, float))


def viscosity(t_k):
    """Dynamic viscosity of air [Pa s], Sutherland's law."""
    t = np.asarray(t_k, float)
    return 1.458e-6 * t**1.5 / (t + 110.4)


def speed_of_sound(t_k):
    return np.sqrt(GAMMA * R_AIR * np.asarray(t_k, float))


def cas_to_tas(cas_ms, p_pa, t_k):
    """True airspeed [m/s] from calibrated airspeed (subsonic compressible flow)."""
    cas = np.asarray(cas_ms, float)
    qc = P0 * ((1.0 + 0.2 * (cas / A0) ** 2) ** 3.5 - 1.0)          # impact pressure
    mach = np.sqrt(5.0 * ((qc / np.asarray(p_pa, float) + 1.0) ** (2.0 / 7.0) - 1.0))
    return mach * speed_of_sound(t_k)


def tas_to_cas(tas_ms, p_pa, t_k):
    """Calibrated airspeed [m/s] from true airspeed."""
    mach = np.asarray(tas_ms, float) / speed_of_sound(t_k)
    qc = np.asarray(p_pa, float) * ((1.0 + 0.2 * mach**2) ** 3.5 - 1.0)
    return A0 * np.sqrt(5.0 * ((qc / P0 + 1.0) ** (2.0 / 7.0) - 1.0))


# --------------------------------------------------------------------------- air data
STD_BARO_INHG = 29.92                 # [inHg] standard altimeter setting
C_TO_K = 273.15                       # [K] at 0 deg C


def _plain(x: np.ndarray) -> Any:
    """A float for a scalar input, the array otherwise."""
    return float(x) if x.ndim == 0 else x


_LAPSE_PER_FT = LAPSE * FT / T0        # [1/ft] troposphere lapse over T0 = 6.8756e-6
_PRESSURE_EXPONENT = G0 / (R_AIR * LAPSE)    # [-] troposphere pressure exponent = 5.2559


def pressure_altitude_ft(alt_baro_ft: Any, baro_setting_inhg: Any) -> Any:
    """Pressure altitude [ft] from indicated altitude ``AltB`` [ft] at altimeter setting [inHg].

    The altimeter shows the standard-atmosphere altitude of the static pressure referred to
    the set pressure: ``p = p_set * (1 - 6.8756e-6 * AltB) ** 5.2559`` (troposphere, as
    :func:`isa_pressure`); pressure altitude is the same relation solved for ``p`` with
    29.92 inHg set. Works on scalars and arrays.
    """
    h = np.asarray(alt_baro_ft, dtype=float)
    p = np.asarray(baro_setting_inhg, dtype=float) * (1.0 - _LAPSE_PER_FT * h) ** _PRESSURE_EXPONENT
    return _plain((1.0 - (p / STD_BARO_INHG) ** (1.0 / _PRESSURE_EXPONENT)) / _LAPSE_PER_FT)


def isa_temperature_c(pressure_alt_ft: Any) -> Any:
    """Standard temperature [deg C] at a pressure altitude [ft]."""
    return _plain(np.asarray(isa_temperature(np.asarray(pressure_alt_ft, float) * FT)) - C_TO_K)


def _asi_table(table: tuple[Sequence[float], Sequence[float]]) -> tuple[np.ndarray, np.ndarray]:
    kias, kcas = np.asarray(table[0], dtype=float), np.asarray(table[1], dtype=float)
    if kias.ndim != 1 or kias.shape != kcas.shape or kias.size < 1 or np.any(np.diff(kias) <= 0):
        raise ValueError("airspeed calibration table needs two equally long sequences with "
                         "strictly increasing KIAS")
    return kias, kcas


def kcas_from_kias(kias: Any, table: tuple[Sequence[float], Sequence[float]] | None = None) -> Any:
    """Calibrated airspeed [kt] from indicated airspeed [kt].

    ``table = (kias_points, kcas_points)``: the aircraft's airspeed calibration (see the
    module doc for the behaviour past its ends); without it the identity (an air-data
    computer's output taken as calibrated).
    """
    v = np.asarray(kias, dtype=float)
    if table is not None:
        xi, yi = _asi_table(table)
        v = v + np.interp(v, xi, yi - xi)
    return _plain(v)


def kias_from_kcas(kcas: Any, table: tuple[Sequence[float], Sequence[float]] | None = None) -> Any:
    """Indicated airspeed [kt] from calibrated airspeed [kt]: the inverse of :func:`kcas_from_kias`."""
    v = np.asarray(kcas, dtype=float)
    if table is not None:
        xi, yi = _asi_table(table)
        if np.any(np.diff(yi) <= 0):
            raise ValueError("an airspeed calibration table is inverted only where KCAS increases with KIAS")
        v = v - np.interp(v, yi, yi - xi)
    return _plain(v)


def ktas_from_kcas(kcas: Any, pressure_alt_ft: Any, oat_c: Any) -> Any:
    """True airspeed [kt] from calibrated airspeed [kt], pressure altitude [ft] and outside air
    temperature [deg C] (:func:`cas_to_tas`; a negative speed keeps its sign)."""
    vc = np.asarray(kcas, dtype=float)
    p = isa_pressure(np.asarray(pressure_alt_ft, dtype=float) * FT)
    v = np.sign(vc) * cas_to_tas(np.abs(vc) * KT, p, np.asarray(oat_c, dtype=float) + C_TO_K) / KT
    return _plain(np.asarray(v))
