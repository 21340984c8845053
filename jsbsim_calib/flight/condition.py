"""A flight condition to trim to, and the trimmed state: plain data (speeds in knots,
altitudes in feet, angles in degrees, as the data files give them)."""
from __future__ import annotations

import functools
from dataclasses import dataclass, field

from ..core.units import KT
from ..physics.atmosphere import cas_to_tas, isa_at_ft

MODES = {
    "level": "flight path given (vs_fpm), speed given, throttle trims",
    "full_throttle": "throttle given (throttle), speed given, flight path free (a climb)",
    "level_full_throttle": "throttle given, flight path given, speed free (maximum level speed)",
}


@dataclass(frozen=True)
class Condition:
    """A flight condition to trim to. Speeds in knots, altitudes in feet, angles in degrees."""

    pressure_alt_ft: float
    weight_lb: float
    kcas: float | None = None
    ktas: float | None = None
    oat_c: float | None = None            # absolute temperature; else ISA + isa_dev_c
    isa_dev_c: float = 0.0
    cg_in: float | None = None            # None: the aircraft's POH CG
    flaps_deg: float = 0.0
    mode: str = "level"                   # see MODES
    vs_fpm: float = 0.0                   # vertical speed (geometric) for mode 'level'
    throttle: float = 1.0                 # for mode 'full_throttle'
    bank_deg: float = 0.0
    turn: str = "straight"                # straight (heading fixed) | coordinated
    mixture: str | float = "cruise"       # POH procedure: cruise | climb | explicit mixture command
    fuel_fraction: float | None = None    # None: the aircraft's default for POH points
    rpm: float | None = None              # governor setting of a constant-speed propeller (None: maximum)

    def __post_init__(self):
        if (self.kcas is None) == (self.ktas is None):
            raise ValueError("give exactly one of kcas and ktas")
        if self.mode not in MODES:
            raise ValueError(f"mode must be one of {', '.join(MODES)}, not {self.mode!r}")
        if self.turn not in ("straight", "coordinated"):
            raise ValueError(f"turn must be 'straight' or 'coordinated', not {self.turn!r}")

    def temperature_k(self) -> float:
        if self.oat_c is not None:
            return self.oat_c + 273.15
        return isa_at_ft(self.pressure_alt_ft)[0] + self.isa_dev_c

    def true_airspeed_kt(self) -> float:
        """True airspeed [kt]: given, or from KCAS at the condition's pressure altitude and temperature."""
        if self.ktas is not None:
            return self.ktas
        return _ktas(self.kcas, self.pressure_alt_ft, self.temperature_k())


@functools.lru_cache(maxsize=4096)
def _ktas(kcas: float, pressure_alt_ft: float, temperature_k: float) -> float:
    """True airspeed [kt] of a calibrated airspeed, kept (a fit trims the same points thousands of times)."""
    return float(cas_to_tas(kcas * KT, isa_at_ft(pressure_alt_ft)[1], temperature_k) / KT)


@dataclass
class TrimResult:
    """Trimmed state. Surface angles in JSBSim's signs (elevator + trailing edge down,
    aileron + roll right, rudder + trailing edge left)."""

    condition: Condition
    trimmed: bool
    reason: str = ""
    residual: float = float("nan")
    evals: int = 0
    alpha_deg: float = float("nan")
    beta_deg: float = float("nan")
    theta_deg: float = float("nan")
    phi_deg: float = float("nan")
    gamma_deg: float = float("nan")
    roc_fpm: float = float("nan")           # rate of climb, geometric (tapeline) dh/dt
    roc_pressure_fpm: float = float("nan")  # rate of change of pressure altitude (VSI)
    ktas: float = float("nan")
    kcas: float = float("nan")
    throttle: float = float("nan")
    mixture: float = float("nan")
    rpm: float = float("nan")
    power_hp: float = float("nan")
    pct_power: float = float("nan")
    gph: float = float("nan")
    thrust_lbf: float = float("nan")
    torque_lbft: float = float("nan")
    map_inhg: float = float("nan")
    elevator_deg: float = float("nan")
    aileron_deg: float = float("nan")
    rudder_deg: float = float("nan")
    qbar_psf: float = float("nan")
    extra: dict = field(default_factory=dict)

    def as_dict(self) -> dict:
        d = {k: getattr(self, k) for k in self.__dataclass_fields__ if k not in ("condition", "extra")}
        d.update(self.extra)
        return d
