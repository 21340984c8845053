"""Sectional aerodynamics of a strip: stored airfoil polar plus control-surface increments.

A deflected trailing-edge surface of chord fraction E changes the section as a flap does
in thin-airfoil theory (Glauert): the zero-lift angle moves by ``tau(E) * eta(delta) *
delta`` and the quarter-chord moment changes by ``dcm/ddelta(E) * eta * delta``. The
factor ``eta`` (lift effectiveness at large deflection, below 1 once the flow separates
from the deflected surface) and the profile-drag increment follow the trends of USAF
DATCOM 6.1.1.1 and Hoerner's *Fluid-Dynamic Lift* for plain and single-slotted flaps;
the simple curves used here are engineering fits, stated below.

Deflection sign: positive ``delta`` increases the lift of the strip (trailing edge
towards the pressure side).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


def flap_theta(E: np.ndarray | float) -> np.ndarray:
    """Glauert angle of the hinge line for chord fraction E: cos(theta) = 2E - 1."""
    return np.arccos(np.clip(2.0 * np.asarray(E, float) - 1.0, -1.0, 1.0))


def tau(E: np.ndarray | float) -> np.ndarray:
    """Thin-airfoil flap effectiveness d(alpha0)/d(delta) [-] (0 for E = 0, 1 for E = 1)."""
    th = flap_theta(E)
    return 1.0 - (th - np.sin(th)) / math.pi


def dcm_ddelta(E: np.ndarray | float) -> np.ndarray:
    """Thin-airfoil quarter-chord moment per radian of flap deflection [1/rad] (negative)."""
    th = flap_theta(E)
    return -0.5 * np.sin(th) * (1.0 - np.cos(th))


def eta_deflection(delta_rad: np.ndarray, kind: np.ndarray | str) -> np.ndarray:
    """Lift effectiveness at large deflection, fraction of the linear value [-].

    plain:        1 up to 10 deg, then -1.75 %/deg (0.65 at 30 deg), floor 0.35
    slotted_flap: 1 up to 15 deg, then -1.2 %/deg (0.82 at 30 deg), floor 0.5
    """
    d = np.degrees(np.abs(np.asarray(delta_rad, float)))
    slotted = np.asarray(kind) == "slotted_flap"
    plain = np.clip(1.0 - 0.0175 * np.maximum(d - 10.0, 0.0), 0.35, 1.0)
    slot = np.clip(1.0 - 0.012 * np.maximum(d - 15.0, 0.0), 0.5, 1.0)
    return np.where(slotted, slot, plain)


def profile_drag_increment(delta_rad: np.ndarray, E: np.ndarray, kind: np.ndarray | str) -> np.ndarray:
    """Section profile-drag increment of a deflected surface [-]: A * E * sin^2(delta).

    A = 0.85 for plain surfaces (about 0.025 at E = 0.25, 20 deg; DATCOM/Hoerner trend) and
    0.5 for single-slotted flaps (about 0.038 at E = 0.3, 30 deg).
    """
    a = np.where(np.asarray(kind) == "slotted_flap", 0.5, 0.85)
    return a * np.asarray(E, float) * np.sin(np.asarray(delta_rad, float)) ** 2


# Fraction of the zero-lift shift carried by shifting the polar along alpha. The rest is
# added as a constant lift increment, so the section's maximum lift rises by
# (1 - kappa) * a0 * dalpha0 while the stall angle falls by kappa * dalpha0.
KAPPA = {"plain": 1.0, "slotted_flap": 0.5}


@dataclass(frozen=True)
class Deflection:
    """The control-surface increments of strips at fixed deflections: what
    :func:`section_coefficients` adds to the clean polar, worked out once for a state
    whose deflections do not change while its circulation is solved."""

    kappa: np.ndarray     # share of the zero-lift shift carried along alpha
    dalpha: np.ndarray    # [rad] the zero-lift shift
    dcl: np.ndarray       # constant lift increment
    dcd: np.ndarray       # profile-drag increment
    dcm: np.ndarray       # quarter-chord moment increment


def deflection(delta_rad: np.ndarray, E: np.ndarray, kind: np.ndarray, lift_slope: np.ndarray) -> Deflection:
    """The increments of strips deflected by ``delta_rad`` (chord fractions ``E``, surface kinds
    ``kind``, linear lift slopes ``lift_slope`` [1/rad] for the constant part of the lift)."""
    delta_rad = np.asarray(delta_rad, float)
    E = np.asarray(E, float)
    kind = np.asarray(kind)
    has = (E > 0) & (delta_rad != 0.0)
    eta = eta_deflection(delta_rad, kind)
    dalpha = np.where(has, tau(E) * eta * delta_rad, 0.0)
    kappa = np.where(kind == "slotted_flap", KAPPA["slotted_flap"], KAPPA["plain"])
    return Deflection(kappa, dalpha, (1.0 - kappa) * lift_slope * dalpha,
                      np.where(has, profile_drag_increment(delta_rad, E, kind), 0.0),
                      np.where(has, dcm_ddelta(E) * eta * delta_rad, 0.0))


def section_lift(polar_cl, alpha_eff_rad: np.ndarray, d: Deflection) -> np.ndarray:
    """cl of strips at effective angles [rad] with the increments ``d``; ``polar_cl(alpha_deg)``
    gives the clean sections' cl (the same bits as :func:`section_coefficients`'s cl)."""
    return polar_cl(np.degrees(np.asarray(alpha_eff_rad, float) + d.kappa * d.dalpha)) + d.dcl


def section_coefficients(polar, alpha_eff_rad: np.ndarray, delta_rad: np.ndarray,
                         E: np.ndarray, kind: np.ndarray, lift_slope: np.ndarray) -> tuple[np.ndarray, ...]:
    """cl, cd, cm (quarter chord) of strips at effective angle alpha_eff with deflection delta.

    ``polar(alpha_deg) -> (cl, cd, cm)`` gives the clean sections of these strips (at their
    Reynolds numbers); ``lift_slope`` is the section's linear lift slope [1/rad] used for
    the constant part of the flap increment.
    """
    d = deflection(delta_rad, E, kind, lift_slope)
    alpha_eff_rad = np.asarray(alpha_eff_rad, float)
    cl = section_lift(lambda a: polar(a)[0], alpha_eff_rad, d)
    _, cd, cm = polar(np.degrees(alpha_eff_rad))
    return cl, cd + d.dcd, cm + d.dcm
