"""Physics tests of the aerodynamic preprocessor (jsbsim_calib.physics.aero), without JSBSim.

* lifting line: an elliptic wing has Prandtl's lift slope and induced drag;
* strip model: a symmetric configuration has no lateral forces at zero sideslip, dihedral
  gives a stable rolling moment with sideslip, a fin a stable yawing moment behind the
  reference point;
* sections: a plain flap adds lift and a nose-down moment with the thin-airfoil
  effectiveness (checked against Glauert's integrals evaluated numerically).

The propeller is tested in tests/test_propeller.py.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from scipy.integrate import quad

from jsbsim_calib.physics.aero.lifting_line import (LiftingLine, freestream_dir, kutta_joukowski, onset_velocity,
                                            surface_strips)
from jsbsim_calib.physics.aero.sections import dcm_ddelta, section_coefficients, tau
from jsbsim_calib.physics.aero.strips import StripModel, wind_to_coeffs
from jsbsim_calib.physics.airfoil import AIRFOIL_DIR, load_airfoil
from jsbsim_calib.jsbsim.product import airfoil_dirs
from jsbsim_calib.physics.geometry import LiftingSurface, load_geometry

REPO = Path(__file__).resolve().parents[1]
RHO, MU, SPEED = 1.1, 1.8e-5, 50.0          # [kg/m^3], [Pa s], [m/s] for the strip Reynolds numbers


@pytest.fixture(scope="module")
def geom():
    """A real aircraft geometry: StripModel takes its reference span for the vortex core."""
    return load_geometry(REPO / "aircraft" / "c172" / "geometry.toml", airfoil_dirs(REPO))


@pytest.fixture(scope="module")
def naca0012():
    return {"naca0012": load_airfoil("naca0012", [AIRFOIL_DIR])}


# --------------------------------------------------------------------------- lifting line
def elliptic_wing(aspect: float, span_m: float = 10.0, n: int = 81) -> LiftingSurface:
    """Elliptic chord, straight quarter-chord line, no twist, no dihedral."""
    s = 0.5 * span_m
    area = span_m**2 / aspect
    c0 = 4.0 * area / (math.pi * span_m)
    y = s * np.sin(np.linspace(0.0, 0.5 * math.pi, n))          # stations clustered at the tip
    c = c0 * np.sqrt(np.clip(1.0 - (y / s) ** 2, 0.0, None))
    return LiftingSurface("wing", "naca0012", y, c, -0.25 * c, np.zeros(n), np.zeros(n), 0.0, 0.0, False)


@pytest.mark.parametrize("aspect", [6.0, 8.0])
def test_elliptic_wing_lift_slope_and_induced_drag(aspect):
    wing = elliptic_wing(aspect)
    st = surface_strips(wing, np.zeros(3), 40)
    S = float(np.sum(st.area))
    A = wing.span_m**2 / S
    a0 = 2.0 * math.pi
    alpha = math.radians(4.0)
    ll = LiftingLine(st, freestream_dir(alpha, 0.0), 1e-6 * wing.span_m)
    U = onset_velocity(st.point, alpha, 0.0)
    gamma = ll.solve(U, np.full(st.n, a0), np.zeros(st.n))
    F = kutta_joukowski(st, gamma, U + ll.induced_velocity(gamma)).sum(axis=0)
    e_drag = freestream_dir(alpha, 0.0)                        # downstream
    e_lift = np.array([math.sin(alpha), 0.0, -math.cos(alpha)])  # up, normal to the free stream
    CL = F @ e_lift / (0.5 * S)
    CDi = F @ e_drag / (0.5 * S)
    assert CL / alpha == pytest.approx(a0 * A / (A + 2.0), rel=0.02)
    assert CDi == pytest.approx(CL**2 / (math.pi * A), rel=0.03)
    # the circulation is elliptic: Gamma/Gamma_root = sqrt(1 - (2y/b)^2)
    y = np.abs(st.point[:, 1])
    g_ell = gamma.max() * np.sqrt(1.0 - (2.0 * y / wing.span_m) ** 2)
    assert np.max(np.abs(gamma - g_ell)) < 0.03 * gamma.max()


# --------------------------------------------------------------------------- strip model
def wing(dihedral_deg: float = 3.0) -> LiftingSurface:
    """Tapered, washed-out, symmetric-section wing (span 10 m)."""
    return LiftingSurface("wing", "naca0012", np.array([0.0, 2.0, 5.0]), np.array([1.6, 1.6, 1.1]),
                          np.array([0.0, 0.0, 0.2]), np.zeros(3), np.radians([2.0, 2.0, 0.0]),
                          math.radians(dihedral_deg), 0.0, False)


def fin(x_le_m: float = 5.0) -> LiftingSurface:
    """Vertical fin in the plane of symmetry, leading edge at station x_le_m (aft +)."""
    return LiftingSurface("vertical_tail", "naca0012", np.array([0.0, 1.5]), np.array([1.2, 0.7]),
                          np.array([x_le_m, x_le_m + 0.6]), np.array([0.3, 1.8]), np.zeros(2), 0.0, 0.0, True)


REF = np.array([0.4, 0.0, 0.0])            # reference point (structural frame) near the wing quarter chord
S_REF, B_REF, C_REF = 14.0, 10.0, 1.45


def coefficients(sm: StripModel, alpha_deg: float, beta_deg: float = 0.0, omega=(0.0, 0.0, 0.0)) -> dict:
    sm.set_reynolds(SPEED, RHO, MU)
    sol = sm.solve(math.radians(alpha_deg), math.radians(beta_deg), omega)
    assert sol.converged
    F, M = sm.loads(sol)
    return wind_to_coeffs(F, M, sol.alpha, sol.beta, S_REF, B_REF, C_REF)


def beta_derivatives(sm: StripModel, alpha_deg: float) -> dict:
    p, m = coefficients(sm, alpha_deg, 1.0), coefficients(sm, alpha_deg, -1.0)
    return {k: (p[k] - m[k]) / math.radians(2.0) for k in ("CY", "Cl", "Cn")}


@pytest.mark.parametrize("surfaces", ["wing", "wing+fin"])
@pytest.mark.parametrize("alpha_deg", [0.0, 6.0])
def test_symmetric_configuration_has_no_lateral_loads_at_zero_sideslip(geom, naca0012, surfaces, alpha_deg):
    parts = (wing(),) if surfaces == "wing" else (wing(), fin())
    sm = StripModel(geom, naca0012, parts, REF, 24)
    # symmetric flight: angle of attack and a pitch rate, no sideslip, no roll or yaw rate
    c = coefficients(sm, alpha_deg, 0.0, omega=(0.0, 0.01, 0.0))
    for k in ("CY", "Cl", "Cn"):
        assert abs(c[k]) < 1e-9, f"{k} = {c[k]:.3g}"
    if alpha_deg > 0:
        assert c["CL"] > 0.3


def test_dihedral_gives_stable_rolling_moment_growing_with_dihedral(geom, naca0012):
    cl_beta = {}
    for dih in (0.0, 3.0, 6.0):
        sm = StripModel(geom, naca0012, (wing(dih),), REF, 24)
        cl_beta[dih] = beta_derivatives(sm, 5.0)["Cl"]
    assert cl_beta[3.0] < 0 and cl_beta[6.0] < 0
    assert abs(cl_beta[0.0]) < abs(cl_beta[3.0]) < abs(cl_beta[6.0])
    # small angles: the dihedral part is about proportional to the dihedral
    ratio = (cl_beta[6.0] - cl_beta[0.0]) / (cl_beta[3.0] - cl_beta[0.0])
    assert ratio == pytest.approx(2.0, rel=0.1)


def test_fin_gives_side_force_and_weathercock_stability_behind_the_reference(geom, naca0012):
    behind = beta_derivatives(StripModel(geom, naca0012, (fin(5.0),), REF, 24), 2.0)
    assert behind["CY"] < 0
    assert behind["Cn"] > 0
    # the same fin ahead of the reference point destabilizes
    ahead = beta_derivatives(StripModel(geom, naca0012, (fin(-3.0),), REF, 24), 2.0)
    assert ahead["CY"] == pytest.approx(behind["CY"], rel=1e-6)
    assert ahead["Cn"] < 0


# --------------------------------------------------------------------------- sections
def glauert_flap(E: float) -> tuple[float, float]:
    """Thin-airfoil zero-lift angle change and quarter-chord moment per radian of a flap of
    chord fraction E, from Glauert's integrals over the camber slope dz/dx = -delta aft of
    the hinge (x = (1 - cos theta)/2): returns (-d alpha0/d delta, d cm/d delta)."""
    th_h = math.acos(2.0 * E - 1.0)                  # hinge at x = 1 - E
    slope = lambda th: -1.0 if th > th_h else 0.0    # dz/dx per unit delta
    a_l0 = -quad(lambda th: slope(th) * (math.cos(th) - 1.0), 0.0, math.pi, points=[th_h])[0] / math.pi
    A1 = 2.0 / math.pi * quad(lambda th: slope(th) * math.cos(th), 0.0, math.pi, points=[th_h])[0]
    A2 = 2.0 / math.pi * quad(lambda th: slope(th) * math.cos(2 * th), 0.0, math.pi, points=[th_h])[0]
    return -a_l0, math.pi / 4.0 * (A2 - A1)


def test_thin_airfoil_flap_effectiveness():
    th = math.acos(2.0 * 0.25 - 1.0)
    closed = 1.0 - (th - math.sin(th)) / math.pi
    eff, dcm = glauert_flap(0.25)
    assert float(tau(0.25)) == pytest.approx(closed, rel=0.01)
    assert float(tau(0.25)) == pytest.approx(eff, rel=0.01)
    assert float(dcm_ddelta(0.25)) == pytest.approx(dcm, rel=0.01)
    assert 0.60 < float(tau(0.25)) < 0.62                      # the textbook value, 0.61
    for E in (0.1, 0.3, 0.45):
        e, m = glauert_flap(E)
        assert float(tau(E)) == pytest.approx(e, rel=0.01)
        assert float(dcm_ddelta(E)) == pytest.approx(m, rel=0.01)


def test_plain_flap_adds_lift_and_nose_down_moment():
    polar = load_airfoil("naca0012", [AIRFOIL_DIR]).polar(3e6)
    slope = polar.lift_slope_per_rad
    E, kind = np.array([0.25]), np.array(["plain"])
    alpha = np.radians([2.0])

    def sec(delta_deg):
        return section_coefficients(polar.coefficients, alpha, np.radians([delta_deg]), E, kind, np.array([slope]))

    cl0, cd0, cm0 = sec(0.0)
    cl1, cd1, cm1 = sec(8.0)
    assert cl1[0] > cl0[0] and cm1[0] < cm0[0] and cd1[0] > cd0[0]
    # linear range: the lift increment is a0 tau delta, the moment increment the thin-airfoil one
    d = math.radians(8.0)
    assert cl1[0] - cl0[0] == pytest.approx(slope * float(tau(0.25)) * d, rel=0.1)
    assert cm1[0] - cm0[0] == pytest.approx(float(dcm_ddelta(0.25)) * d, rel=0.01)
    # an upward deflection does the opposite
    clm, _, cmm = sec(-8.0)
    assert clm[0] < cl0[0] and cmm[0] > cm0[0]
