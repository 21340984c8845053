"""The propeller slipstream by momentum theory: what the tail and the wing root fly in.

An actuator disc of area A giving thrust T at airspeed V accelerates the air through it by
``a V`` and far behind it by ``2 a V``, with ``T = 2 rho A V^2 a (1 + a)``; with the disc thrust
coefficient ``Tc = T / (q A)`` (q the free-stream dynamic pressure), ``Tc = 4 a (1 + a)``:

* far-wake dynamic pressure ratio ``q_s / q = (1 + 2a)^2 = 1 + Tc``;
* contraction: the slipstream radius ``R_s = R sqrt((1 + a) / (1 + 2a))`` (continuity), from R
  at Tc = 0 to R / sqrt(2) for a static disc;
* swirl: the torque Q leaves angular momentum in the slipstream. An annulus at radius r of the
  disc carries ``dQ = dm w_t r`` (``dm = rho 2 pi r V (1 + a) dr``), and keeps its ``w_t r`` as
  it contracts to ``r_w``; its swirl angle far behind the disc is ``w_t r / (r_w V (1 + 2a))``.
  With ``Qc = Q / (q A R)`` and the torque's radial shape ``s(r/R) = R (dQ/dr) / Q`` (from the
  blade-element solution, :func:`torque_shape`), that is
  ``Qc s / (4 (r/R)(r_w/R)) / ((1 + a)(1 + 2a))``. A free vortex (``w_t r`` the same everywhere,
  ``s = 2 r/R``) gives ``Qc R / (2 r_w (1 + a)(1 + 2a))``: the default when no blade is given,
  and an upper bound near the hub, where a real blade loads little.

The share of a surface inside the slipstream cylinder is geometry: the horizontal tail's span
within ``sqrt(R_s^2 - dz^2)`` of the thrust line (dz its height above it), the fin's height
within ``R_s``, the wing's area on the same chord at its height, outside the fuselage. The
tables of :func:`immersion_tables` (against Tc) are what the aircraft's functions read.
SI units; Tc and Qc dimensionless.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

TC_GRID = np.array([0.0, 0.05, 0.1, 0.2, 0.3, 0.5, 0.75, 1.0, 1.5, 2.0, 3.0, 5.0, 8.0, 12.0, 20.0])


def axial_induction(tc: float | np.ndarray) -> np.ndarray:
    """``a`` from ``Tc = 4 a (1 + a)`` (Tc >= 0)."""
    tc = np.maximum(np.asarray(tc, float), 0.0)
    return 0.5 * (np.sqrt(1.0 + tc) - 1.0)


def dynamic_pressure_ratio(tc):
    """Far-wake dynamic pressure over the free stream's: ``1 + Tc``."""
    return (1.0 + 2.0 * axial_induction(tc)) ** 2


def contraction_ratio(tc):
    """Far-wake slipstream radius over the disc radius."""
    a = axial_induction(tc)
    return np.sqrt((1.0 + a) / (1.0 + 2.0 * a))


def swirl_angle_rad(qc, tc, r_over_R):
    """Swirl angle far behind the disc at ``r / R`` from the axis (free vortex)."""
    a = axial_induction(tc)
    return np.asarray(qc, float) / (2.0 * np.asarray(r_over_R, float) * (1.0 + a) * (1.0 + 2.0 * a))


FREE_VORTEX = (np.array([0.0, 1.0]), np.array([0.0, 2.0]))     # s(r/R) = 2 r/R
FIN_POINTS = 41              # heights over the fin's immersed part the swirl is averaged on


def torque_shape(r_over_R, dQ_dr, radius_m: float) -> tuple[np.ndarray, np.ndarray]:
    """The torque's radial shape ``s(r/R) = R (dQ/dr) / Q`` of a blade-element solution
    (stations ``r_over_R``, torque per unit radius ``dQ_dr`` [N m/m]): it integrates to 1 over
    r/R from 0 to 1."""
    x = np.asarray(r_over_R, float)
    q = np.nan_to_num(np.asarray(dQ_dr, float)) * radius_m
    total = float(np.trapezoid(q, x))
    if not total > 0.0:
        raise ValueError("torque_shape: the blade absorbs no torque at this point")
    return x, q / total


def swirl_arm(z_over_R, tc, shape=FREE_VORTEX) -> np.ndarray:
    """``s / (4 (r/R)(r_w/R))`` at far-wake heights ``z_over_R`` from the axis: the swirl angle
    there is ``Qc`` times this over ``(1 + a)(1 + 2a)``. Zero outside the slipstream."""
    z = np.abs(np.asarray(z_over_R, float))
    r = z / contraction_ratio(tc)                         # the disc radius of that streamline
    s = np.interp(r, shape[0], shape[1], left=0.0, right=0.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where((r > 0) & (r <= 1.0), s / (4.0 * r * np.maximum(z, 1e-9)), 0.0)


@dataclass(frozen=True)
class TailGeometry:
    """Where the surfaces are relative to the thrust line [m]."""

    radius_m: float                 # propeller radius
    ht_semispan_m: float            # horizontal tail semispan
    ht_height_m: float              # horizontal tail height above the thrust line
    fin_root_m: float               # fin root height above the thrust line
    fin_tip_m: float                # fin tip height above the thrust line
    wing_height_m: float            # wing root chord line height above the thrust line
    wing_area_m2: float             # reference wing area
    wing_root_chord_m: float        # wing chord inside the slipstream
    fuselage_half_width_m: float    # the part of the span the fuselage covers (no wing strips)
    torque_shape: tuple = FREE_VORTEX   # (r/R, s(r/R)): the blade's torque shape (torque_shape)


def ht_fraction(g: TailGeometry, tc) -> np.ndarray:
    """Share of the horizontal tail's span inside the slipstream."""
    rs = g.radius_m * contraction_ratio(tc)
    half_chord = np.sqrt(np.maximum(rs ** 2 - g.ht_height_m ** 2, 0.0))
    return np.minimum(1.0, half_chord / g.ht_semispan_m)


def fin_fraction(g: TailGeometry, tc) -> np.ndarray:
    """Share of the fin's height inside the slipstream."""
    rs = g.radius_m * contraction_ratio(tc)
    lo, hi = g.fin_root_m, g.fin_tip_m
    inside = np.clip(np.minimum(hi, rs) - np.maximum(lo, -rs), 0.0, None)
    return inside / (hi - lo)


def fin_swirl_arm(g: TailGeometry, tc) -> np.ndarray:
    """The swirl geometry of :func:`swirl_arm` averaged over the fin's whole height (zero on the
    part outside the slipstream): the fin's mean sideslip from the swirl is ``Qc`` times this
    over ``(1 + a)(1 + 2a)``."""
    out = []
    for t in np.atleast_1d(np.asarray(tc, float)):
        rs = g.radius_m * float(contraction_ratio(t))
        lo, top = max(g.fin_root_m, 0.05 * g.radius_m), min(g.fin_tip_m, rs)   # not on the axis itself
        if top <= lo:
            out.append(0.0)
            continue
        z = np.linspace(lo, top, FIN_POINTS) / g.radius_m
        arm = swirl_arm(z, t, g.torque_shape)
        height = (g.fin_tip_m - g.fin_root_m) / g.radius_m
        out.append(float(np.trapezoid(arm, z)) / height)
    return np.array(out) if np.ndim(tc) else np.array(out[0])


def wing_fraction(g: TailGeometry, tc) -> np.ndarray:
    """Share of the reference wing area inside the slipstream: the root strips either side of
    the fuselage, on the chord of the slipstream circle at the wing's height (a high wing far
    above the thrust line has none)."""
    rs = g.radius_m * contraction_ratio(tc)
    half_chord = np.sqrt(np.maximum(rs ** 2 - g.wing_height_m ** 2, 0.0))
    span_inside = 2.0 * np.clip(half_chord - g.fuselage_half_width_m, 0.0, None)
    return span_inside * g.wing_root_chord_m / g.wing_area_m2


def immersion_tables(g: TailGeometry) -> dict[str, np.ndarray]:
    """The shares and the swirl geometry against :data:`TC_GRID`."""
    return {"ht_fraction": ht_fraction(g, TC_GRID), "fin_fraction": fin_fraction(g, TC_GRID),
            "fin_swirl_arm": fin_swirl_arm(g, TC_GRID), "wing_fraction": wing_fraction(g, TC_GRID)}


def disc_area_m2(radius_m: float) -> float:
    return math.pi * radius_m ** 2
