"""International Standard Atmosphere (troposphere and lower stratosphere) and airspeeds.

SI in, SI out. Pressure altitude is geopotential altitude in the standard atmosphere
that has the given static pressure.
"""
from __future__ import annotations

import math

import numpy as np

from .units import GAMMA, LAPSE, P0, R_AIR, T0, G0, KT

_H_TROP = 11000.0                       # [m] tropopause (geopotential)
_T_TROP = T0 - LAPSE * _H_TROP          # [K]
_P_TROP = P0 * (_T_TROP / T0) ** (G0 / (R_AIR * LAPSE))
A0 = math.sqrt(GAMMA * R_AIR * T0)      # [m/s] sea-level speed of sound


def isa_temperature(h_m):
    """Standard temperature [K] at geopotential altitude h [m]."""
    h = np.asarray(h_m, float)
    return np.where(h < _H_TROP, T0 - LAPSE * h, _T_TROP)


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


def kcas_to_ktas(kcas, pressure_alt_m, oat_k):
    return cas_to_tas(np.asarray(kcas) * KT, isa_pressure(pressure_alt_m), oat_k) / KT


def ktas_to_kcas(ktas, pressure_alt_m, oat_k):
    return tas_to_cas(np.asarray(ktas) * KT, isa_pressure(pressure_alt_m), oat_k) / KT
