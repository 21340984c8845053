"""Piston engine: JSBSim FGPiston parameters designed from the engine's published data,
and the POH mixture procedure.

JSBSim's FGPiston computes, at steady state (JSBSim 1.3 source, FGPiston.cpp):

* manifold pressure  MAP = p_ram * Ze / (Ze + Z_airbox + Z_throttle (1 - throttle)^2),
  Ze = peak piston speed / mean piston speed, Z_airbox from the maximum MAP at rated RPM;
* air mass flow      m_air = VE * ve(p/MAP) * displacement * RPM/120 * MAP / (R T_amb);
* fuel flow          m_fuel = m_air * (1.3 * mixture * 101325 / p_amb) / 14.7;
* indicated power    IHP = fuel_pph / ISFC * ME(fuel/air) - static friction;
* brake power        HP = IHP + (PMEP + FMEP) * displacement * RPM / (cycles * 22371),
  PMEP = (MAP - p_amb) VE, FMEP = -(FMEP_dyn * piston speed + FMEP_static).

``piston_steady_state`` reproduces this so the engine can be designed in Python (and the
replica is checked against JSBSim in the tests). ``design_piston`` picks the free
parameters so that the engine delivers its rated power at rated RPM at sea level with
the best-power mixture, with mechanical losses at rated of 1/8.55 of indicated power, the
friction that makes full-throttle power follow the Gagg-Farrar altitude law
P/P0 = sigma - (1 - sigma)/7.55.

Power varies with temperature at a given pressure altitude as sqrt(T_std/T) (Lycoming
operator's manuals, and method eq. 2.15): the aircraft file schedules the volumetric
efficiency with sqrt(T/T_std) because FGPiston's air flow alone scales with 1/T.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from scipy.optimize import brentq

from ..core.units import FT, HP, IN, INHG, P0, T0
from .atmosphere import isa_pressure, isa_temperature, pressure_altitude
from .geometry import EngineSpec

R_AIR_JSB = 287.3              # [J/(kg K)] FGPiston's gas constant
FAR_STOICH_INV = 14.7
LB_PER_KG = 2.2046             # FGPiston's conversion
# Mixture. Brake power at constant air flow versus fuel/air ratio f relative to best power
# follows the classical spark-ignition curve (C. F. Taylor, The Internal-Combustion Engine in
# Theory and Practice, vol. 1, ch. 12): flat within 1-2 % from 0.85 to 1.2 times the
# best-power ratio, 2 % down at 1.15-1.2 times (a full-rich setting), misfire when much
# leaner. FGPiston multiplies fuel flow by its mixture-efficiency table, so the engine file
# carries ME(f) = P(f) f_bp / f: richer than best power burns more fuel for the same power,
# as real engines do (FGPiston's built-in table lets power grow with fuel flow up to f =
# 0.10, so a full-rich engine made 10 % more power).
# Full rich is FGPiston's mixture lever at 1.0 at sea level (equivalence ratio 1.3, f =
# 0.0884); a fuel-injection servo holds that ratio at altitude (FGPiston's lever would
# enrich as 1/pressure), so full rich is f = 0.0884 at every altitude, 15 % rich of best
# power: 2 % less power and about 15 gph at takeoff for a 180 hp engine.
FAR_FULL_RICH = 1.3 / 14.7
FAR_BEST_POWER = FAR_FULL_RICH / 1.15
_PHI = np.array([0.60, 0.67, 0.73, 0.79, 0.85, 0.91, 0.97, 1.03, 1.09, 1.15, 1.21, 1.33, 1.45, 1.58, 1.70, 1.94, 2.18])
MIXTURE_POWER = np.array([0.0, 0.80, 0.87, 0.93, 0.97, 0.99, 1.00, 1.00, 0.99, 0.98, 0.96, 0.92, 0.86, 0.78,
                          0.68, 0.45, 0.0])
MIXTURE_FAR = _PHI * FAR_BEST_POWER
_ME_FAR = MIXTURE_FAR
_ME_VAL = MIXTURE_POWER * FAR_BEST_POWER / MIXTURE_FAR
ISFC_DESIGN = 0.39                              # [lb/(hp h)] indicated SFC at best power
GAGG_FARRAR_LOSS = 1.0 / 8.55                   # mechanical-loss fraction of IHP at rated power


@dataclass(frozen=True)
class PistonParams:
    """FGPiston inputs (JSBSim units) as written to the engine file."""

    name: str
    max_hp: float
    max_rpm: float
    idle_rpm: float
    displacement_in3: float
    bore_in: float
    stroke_in: float
    cylinders: int
    compression_ratio: float
    max_map_inhg: float
    min_map_inhg: float
    volumetric_efficiency: float
    isfc_lb_hphr: float
    fmep_static_pa: float
    fmep_dynamic_pa_per_mps: float
    static_friction_hp: float = 1.5
    peak_piston_speed_fps: float = 100.0
    ram_air_factor: float = 1.0
    cycles: int = 4
    man_press_lag_s: float = 0.1
    temperature_exponent: float = 0.5   # full-throttle power ~ (T_std/T)^n at a pressure altitude


def mixture_efficiency(far):
    return np.interp(far, _ME_FAR, _ME_VAL, left=0.0, right=0.0)


def mixture_for_far(far: float, p_amb_pa: float) -> float:
    """FGPiston mixture command that gives a fuel/air ratio at an ambient pressure."""
    return far * FAR_STOICH_INV * p_amb_pa / (1.3 * 101325.0)


def poh_mixture(p_amb_pa: float, *, climb: bool = False, full_rich_below_m: float = 0.0) -> float:
    """Mixture command of the POH procedure.

    Climb: full rich below ``full_rich_below_m`` pressure altitude, leaned for maximum RPM
    (best power) above. Cruise: best power. Capped at 1.0 (FGPiston's full-rich lever).
    """
    rich = climb and float(pressure_altitude(p_amb_pa)) < full_rich_below_m
    return min(1.0, mixture_for_far(FAR_FULL_RICH if rich else FAR_BEST_POWER, p_amb_pa))


def _impedances(p: PistonParams):
    rated_mps = p.max_rpm * p.stroke_in / 360.0
    ze_rated = p.peak_piston_speed_fps / rated_mps
    max_map = p.max_map_inhg * INHG
    min_map = p.min_map_inhg * INHG
    z_airbox = (P0 * ze_rated / max_map) - ze_rated
    z_throttle = (p.peak_piston_speed_fps / ((p.idle_rpm * p.stroke_in) / 360.0)) * (P0 / min_map - 1.0) - z_airbox
    return z_airbox, z_throttle


def piston_steady_state(p: PistonParams, *, p_amb_pa: float, t_amb_k: float, rpm: float, throttle: float = 1.0,
                        mixture: float = 1.0, p_total_pa: float | None = None, ve: float | None = None,
                        isfc: float | None = None) -> dict[str, float]:
    """FGPiston's steady-state output (see module doc). Returns hp, fuel_pph, map_pa, far."""
    ve = p.volumetric_efficiency if ve is None else ve
    isfc = p.isfc_lb_hphr if isfc is None else isfc
    z_airbox, z_throttle = _impedances(p)
    p_ram = p_amb_pa if p_total_pa is None else (p_total_pa - p_amb_pa) * p.ram_air_factor + p_amb_pa
    mps = rpm * p.stroke_in / 360.0
    ze = p.peak_piston_speed_fps / mps if mps > 0 else 999999.0
    zt = (1.0 - throttle) ** 2 * z_throttle
    map_pa = p_ram * ze / (ze + z_airbox + zt)
    gamma = 1.3
    cr = p.compression_ratio
    mratio = min(p_amb_pa / map_pa, cr)
    ve_factor = (gamma - 1) / gamma + (cr - mratio) / (gamma * (cr - 1))
    disp = p.displacement_in3 * IN**3
    v_dot = disp * rpm / 60.0 / 2.0 * ve * ve_factor
    m_air = v_dot * map_pa / (R_AIR_JSB * t_amb_k)
    er = 1.3 * mixture * 101325.0 / p_amb_pa
    m_fuel = m_air * er / FAR_STOICH_INV
    fuel_pph = m_fuel * LB_PER_KG * 3600.0
    far = m_fuel / m_air
    ihp = fuel_pph / isfc * float(mixture_efficiency(far)) - p.static_friction_hp
    pmep = (map_pa - p_amb_pa) * ve
    fmep = -(p.fmep_dynamic_pa_per_mps * mps * FT + p.fmep_static_pa)
    pumping_hp = (pmep + fmep) * disp * rpm / (p.cycles * 22371.0)
    return {"hp": ihp + pumping_hp, "ihp": ihp, "fuel_pph": fuel_pph, "map_pa": map_pa, "far": far,
            "loss_hp": -pumping_hp + p.static_friction_hp}


def design_piston(spec: EngineSpec, name: str) -> PistonParams:
    """FGPiston parameters that meet the rated point and the Gagg-Farrar loss fraction."""
    base = PistonParams(
        name=name, max_hp=spec.max_power_w / HP, max_rpm=spec.rated_rpm, idle_rpm=spec.idle_rpm,
        displacement_in3=spec.displacement_m3 / IN**3, bore_in=spec.bore_m / IN, stroke_in=spec.stroke_m / IN,
        cylinders=spec.cylinders, compression_ratio=spec.compression_ratio,
        max_map_inhg=spec.max_map_pa / INHG, min_map_inhg=spec.min_map_pa / INHG,
        volumetric_efficiency=0.8, isfc_lb_hphr=ISFC_DESIGN, fmep_static_pa=46500.0,
        fmep_dynamic_pa_per_mps=18400.0)
    mix = mixture_for_far(FAR_BEST_POWER, P0)
    rated_hp = spec.max_power_w / HP

    def with_scale(s, ve):
        return replace(base, fmep_static_pa=46500.0 * s, fmep_dynamic_pa_per_mps=18400.0 * s,
                       volumetric_efficiency=ve)

    def ve_for(s):
        return brentq(lambda ve: piston_steady_state(with_scale(s, ve), p_amb_pa=P0, t_amb_k=T0, rpm=spec.rated_rpm,
                                                     mixture=mix)["hp"] - rated_hp, 0.2, 1.5)

    def loss_err(s):
        out = piston_steady_state(with_scale(s, ve_for(s)), p_amb_pa=P0, t_amb_k=T0, rpm=spec.rated_rpm, mixture=mix)
        return out["loss_hp"] / (out["hp"] + out["loss_hp"]) - GAGG_FARRAR_LOSS

    s = brentq(loss_err, 0.05, 3.0)
    return with_scale(s, ve_for(s))


def rated_check(p: PistonParams, altitude_m: float = 0.0) -> float:
    """Full-throttle power [hp] at rated RPM, ISA, best-power mixture (design check)."""
    pa = float(isa_pressure(altitude_m))
    return piston_steady_state(p, p_amb_pa=pa, t_amb_k=float(isa_temperature(altitude_m)), rpm=p.max_rpm,
                               mixture=min(1.0, mixture_for_far(FAR_BEST_POWER, pa)))["hp"]
