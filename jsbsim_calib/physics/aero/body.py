"""Non-lifting parts: fuselage and parasite-drag items, by classical empirical methods.

One function per physical model; all return coefficients on the wing reference area (and
the wing chord or span for moments), about the aerodynamic reference point.
"""
from __future__ import annotations

import math

import numpy as np

from ..geometry import AircraftGeometry


def turbulent_skin_friction(reynolds: float) -> float:
    """Flat-plate turbulent skin-friction coefficient, Prandtl-Schlichting: 0.455/(log10 Re)^2.58."""
    return 0.455 / math.log10(reynolds) ** 2.58


def body_form_factor(fineness: float) -> float:
    """Form factor of a streamlined body (Raymer, Aircraft Design, eq. 12.31): 1 + 60/f^3 + f/400."""
    return 1.0 + 60.0 / fineness**3 + fineness / 400.0


def fuselage_equivalent_diameter_m(geom: AircraftGeometry) -> float:
    f = geom.fuselage
    return math.sqrt(f.max_width_m * f.max_height_m)


def fuselage_zero_lift_drag(geom: AircraftGeometry, reynolds_per_m: float) -> float:
    """Fuselage skin-friction and form drag, CD0 on S_ref."""
    f = geom.fuselage
    fin = f.length_m / fuselage_equivalent_diameter_m(geom)
    cf = turbulent_skin_friction(reynolds_per_m * f.length_m)
    return cf * body_form_factor(fin) * f.wetted_area_m2 / geom.reference.wing_area_m2


def fuselage_crossflow_normal_force(geom: AircraftGeometry, alpha_rad: np.ndarray) -> np.ndarray:
    """Viscous crossflow normal force (Allen & Perkins, NACA TR 1048): eta * cdc * Sp/S * sin^2(a) * sign(a).

    eta = 0.65 (finite-length factor for fineness about 7), cdc = 1.2 (circular-cylinder
    crossflow drag), planform area Sp = 0.8 * L * W (rounded-box fuselage).
    """
    f = geom.fuselage
    sp = 0.8 * f.length_m * f.max_width_m
    return 0.65 * 1.2 * sp / geom.reference.wing_area_m2 * np.sin(alpha_rad) * np.abs(np.sin(alpha_rad))


def fuselage_pitch_slope_per_rad(geom: AircraftGeometry) -> float:
    """Fuselage (destabilizing) dCm/dalpha [1/rad], Gilruth & White (NACA TR 711) as in Raymer eq. 16.25.

    Cm_alpha = K_f W_f^2 L_f / (S c) per degree, with K_f from the position of the wing root
    quarter chord along the fuselage; K_f(p) = 0.0011 exp(0.06 p), p in percent of length,
    is a fit to Raymer Fig. 16.14.
    """
    f = geom.fuselage
    w = geom.wing
    x_root_qc = w.x_le_m[0] + 0.25 * w.chord_m[0]
    pct = 100.0 * (x_root_qc - f.x_nose_m) / f.length_m
    kf = 0.0011 * math.exp(0.06 * pct)
    per_deg = kf * f.max_width_m**2 * f.length_m / (geom.reference.wing_area_m2 * geom.cbar_m)
    return per_deg * 180.0 / math.pi


def fuselage_sideforce_slope_per_rad(geom: AircraftGeometry) -> float:
    """Body side force CY_beta [1/rad] = -2 K_i S0/S (DATCOM 5.2.1.1), K_i = 1.4 for a high wing,
    S0 = cross-section area at 0.38 L taken as 0.8 * pi/4 * W * H."""
    f = geom.fuselage
    s0 = 0.8 * math.pi / 4.0 * f.max_width_m * f.max_height_m
    return -2.0 * 1.4 * s0 / geom.reference.wing_area_m2


def fuselage_volume_m3(geom: AircraftGeometry) -> float:
    f = geom.fuselage
    return 0.55 * f.length_m * f.max_width_m * f.max_height_m


def fuselage_yaw_slope_per_rad(geom: AircraftGeometry) -> float:
    """Body Cn_beta [1/rad] (destabilizing) = -1.3 Vol/(S b) * (H/W) (Raymer eq. 16.47)."""
    f = geom.fuselage
    return -1.3 * fuselage_volume_m3(geom) / (geom.reference.wing_area_m2 * geom.reference.span_m) * (
        f.max_height_m / f.max_width_m)


def wing_body_dihedral_effect_per_rad(geom: AircraftGeometry) -> float:
    """Wing-body interference Cl_beta [1/rad] (DATCOM 5.1.2.1): -1.2 sqrt(A) z_w D / b^2,
    z_w = height of the wing root chord above the fuselage axis (high wing: stabilizing)."""
    w = geom.wing
    b = geom.reference.span_m
    aspect = b * b / geom.reference.wing_area_m2
    z_w = w.z_m[0] - geom.fuselage.z_axis_m
    return -1.2 * math.sqrt(aspect) * z_w * fuselage_equivalent_diameter_m(geom) / b**2


def drag_items(geom: AircraftGeometry) -> tuple[float, float]:
    """Sum of the drag-item coefficients (on S_ref) and the drag-weighted height offset
    from the reference point [m] (structural z, up positive)."""
    s = geom.reference.wing_area_m2
    zref = geom.aero_reference_point_m[2]
    cd = sum(d.area_m2 for d in geom.drag) / s
    if cd == 0:
        return 0.0, 0.0
    z = sum(d.area_m2 * (d.z_m - zref) for d in geom.drag) / (cd * s)
    return cd, z
