"""The aircraft's flight envelope, checked on reference data before anything is flown.

A data row outside the envelope of the aircraft it is evaluated on would still trim (a climb
at 25,000 ft gives a negative rate of climb, a 3,200 lb C172 climbs) and give numbers that
mean nothing. The limits are the aircraft's own, from its geometry file: maximum weight
(``[mass] max_weight``), service ceiling, Vne and the landing-flap stall speed Vso
(``[operations]``, optional; the POH figures, cited there). Every problem is listed with its
file, line (row) and column; the margins are stated here:

* weight above the maximum weight: a warning naming the row; above
  :data:`WEIGHT_REFUSE_FACTOR` x the maximum weight: refused (the G1000 loading uses the same
  factor, :data:`jsbsim_calib.data.logs.MAX_WEIGHT_MARGIN`);
* pressure altitude above the service ceiling (the best climb there is 100 ft/min): a warning;
  more than :data:`CEILING_MARGIN_FT` above it: refused (at the POH's decrease of the best climb
  with altitude, 40-50 ft/min per 1,000 ft for both aircraft, the absolute ceiling lies about
  2,000-2,500 ft above the service ceiling);
* calibrated airspeed above Vne, or below :data:`STALL_MARGIN` x Vso (the stall speed falls as
  the square root of the weight: 0.85 x Vso is the stall speed at 72 % of the maximum weight,
  below any loading of these aircraft): refused.

Temperatures against ISA are checked without the aircraft, by the schemas
(:data:`jsbsim_calib.data.schemas.ISA_DEVIATION_LIMIT_C`).
"""
from __future__ import annotations

import math
import warnings
from dataclasses import dataclass
from typing import Callable

import numpy as np

from ..core.errors import DataError, Problem
from ..core.units import FT, KT, LBM
from ..physics.atmosphere import C_TO_K, isa_pressure, isa_temperature_c, kcas_from_kias, tas_to_cas
from ..physics.geometry import AircraftGeometry

WEIGHT_REFUSE_FACTOR = 1.25      # rows heavier than this x the maximum weight are refused
CEILING_MARGIN_FT = 3000.0       # rows more than this above the service ceiling are refused
STALL_MARGIN = 0.85              # rows slower than this x Vso are refused


class EnvelopeWarning(UserWarning):
    """A data row outside the aircraft's normal envelope but within the stated margins."""


@dataclass(frozen=True)
class Envelope:
    """An aircraft's limits (NaN: not stated, not checked); speeds calibrated [kt]."""

    aircraft: str
    max_weight_lb: float
    service_ceiling_ft: float = math.nan
    vne_kcas: float = math.nan
    vso_kcas: float = math.nan

    @classmethod
    def of(cls, geom: AircraftGeometry) -> "Envelope":
        ops = geom.operations
        table = ops.airspeed_calibration if len(ops.asi_kias_kt) else None

        def kcas(kias: float) -> float:
            return float(kcas_from_kias(kias, table)) if math.isfinite(kias) else math.nan

        stated = getattr(geom, "stated_max_weight_lb", None)     # a foreign aircraft's: NaN when unknown
        max_weight = geom.mass.max_mass_kg / LBM if stated is None else stated
        return cls(geom.title, max_weight, getattr(ops, "service_ceiling_m", math.nan) / FT,
                   kcas(getattr(ops, "never_exceed_kias_kt", math.nan)),
                   kcas(getattr(ops, "stall_landing_kias_kt", math.nan)))


def _column(frame, name: str) -> np.ndarray:
    return frame[name].to_numpy(float) if name in frame else np.full(len(frame), np.nan)


def calibrated_airspeed(frame, geom: AircraftGeometry) -> tuple[np.ndarray, str]:
    """The rows' calibrated airspeed [kt] and the column it comes from (kcas, kias through the
    aircraft's airspeed calibration, or ktas at the row's pressure altitude and temperature)."""
    if "kcas" in frame:
        return _column(frame, "kcas"), "kcas"
    if "kias" in frame:
        ops = geom.operations
        return np.asarray(kcas_from_kias(_column(frame, "kias"), ops.airspeed_calibration if len(ops.asi_kias_kt)
                                         else None), float), "kias"
    if "ktas" not in frame:
        return np.full(len(frame), np.nan), ""
    hp = _column(frame, "pressure_alt_ft")
    isa = np.asarray(isa_temperature_c(np.nan_to_num(hp)), float)
    oat = _column(frame, "oat_c")
    dev = np.nan_to_num(_column(frame, "temp_dev_c"))
    t_c = np.where(np.isfinite(oat), oat, isa + dev)
    with np.errstate(invalid="ignore"):
        cas = tas_to_cas(_column(frame, "ktas") * KT, isa_pressure(np.nan_to_num(hp) * FT), t_c + C_TO_K) / KT
    return np.asarray(cas, float), "ktas"


def envelope_problems(frame, geom: AircraftGeometry, where: Callable[[int, str], str]
                      ) -> tuple[list[Problem], list[Problem]]:
    """(refusals, warnings) of the rows of ``frame`` against the aircraft's envelope;
    ``where(i, column)`` names a row's place."""
    env = Envelope.of(geom)
    refused, warned = [], []
    w, hp = _column(frame, "weight_lb"), _column(frame, "pressure_alt_ft")
    cas, speed_col = calibrated_airspeed(frame, geom)
    for i in range(len(frame)):
        if w[i] > WEIGHT_REFUSE_FACTOR * env.max_weight_lb:
            refused.append(Problem(where(i, "weight_lb"), f"{w[i]:g} lb is more than {WEIGHT_REFUSE_FACTOR:g} x the "
                                   f"{env.aircraft}'s maximum weight {env.max_weight_lb:.0f} lb: outside its envelope"))
        elif w[i] > env.max_weight_lb * (1 + 1e-9):
            warned.append(Problem(where(i, "weight_lb"), f"{w[i]:g} lb is above the {env.aircraft}'s maximum weight "
                                  f"{env.max_weight_lb:.0f} lb"))
        ceiling = env.service_ceiling_ft
        if hp[i] > ceiling + CEILING_MARGIN_FT:
            refused.append(Problem(where(i, "pressure_alt_ft"), f"{hp[i]:g} ft is more than {CEILING_MARGIN_FT:.0f} ft "
                                   f"above the {env.aircraft}'s service ceiling {ceiling:.0f} ft: outside its envelope"))
        elif hp[i] > ceiling:
            warned.append(Problem(where(i, "pressure_alt_ft"), f"{hp[i]:g} ft is above the {env.aircraft}'s service "
                                  f"ceiling {ceiling:.0f} ft"))
        if cas[i] > env.vne_kcas:
            refused.append(Problem(where(i, speed_col), f"{cas[i]:.0f} KCAS is above the {env.aircraft}'s Vne "
                                   f"{env.vne_kcas:.0f} KCAS: outside its envelope"))
        elif cas[i] < STALL_MARGIN * env.vso_kcas:
            refused.append(Problem(where(i, speed_col), f"{cas[i]:.0f} KCAS is below {STALL_MARGIN:g} x the "
                                   f"{env.aircraft}'s landing-flap stall speed {env.vso_kcas:.0f} KCAS: outside its "
                                   "envelope"))
    return refused, warned


def check_envelope(frame, geom: AircraftGeometry, source, where: Callable[[int, str], str]) -> None:
    """Refuse (DataError, every row listed) rows outside the envelope; warn about rows within
    the margins (:class:`EnvelopeWarning`, one per row and column)."""
    refused, warned = envelope_problems(frame, geom, where)
    if refused:
        raise DataError(source, refused)
    for p in warned:
        warnings.warn(f"{getattr(source, 'name', source)}: {p}", EnvelopeWarning, stacklevel=3)
