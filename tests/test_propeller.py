"""Physics tests of the BEM propeller model (jsbsim_calib.physics.propeller).

The propeller is C172-like: McCauley 1A170E/JHA7660, 76 in diameter, 60 in
geometric pitch, 2 blades.  Chord distribution (documented choice): chord/R
rises from 0.09 at the hub (r/R = 0.15) to a maximum 0.13 at 0.6 R and tapers
to 0.06 at the tip; c/R = 0.13 is c/D = 0.065, about 4.9 in, typical of this
blade (activity factor about 81).  The section is an analytic Clark-Y-like
polar defined below.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from jsbsim_calib.core.errors import GeometryError, InputError
from jsbsim_calib.factors import PROPELLER_FACTORS, propeller_factor_values
from jsbsim_calib.physics.propeller import (
    Blade,
    BEMPoint,
    PropellerTables,
    TABLE_FACTORS,
    SectionPolar,
    apply_factors,
    bem_point,
    helical_blade,
    propeller_tables,
)
from jsbsim_calib.core.units import IN

REPO = Path(__file__).resolve().parents[1]

D_IN, PITCH_IN = 76.0, 60.0
D = D_IN * IN                     # [m]
R = 0.5 * D                       # [m]
PITCH = PITCH_IN * IN             # [m]
HUB = 0.15 * R                    # [m]
RPM = 2400.0
N = RPM / 60.0                    # [rev/s]
ALPHA_L0_DEG = -3.5               # [deg] zero-lift angle of the analytic section

# (r/R, c/R): max chord 0.13 R (0.065 D) near 0.6 R
CHORD_OVER_R = np.array([(0.15, 0.09), (0.35, 0.12), (0.60, 0.13), (0.85, 0.11), (0.95, 0.085), (1.00, 0.06)])


class AnalyticPolar:
    """Cambered thin-airfoil section with stall and flat-plate post-stall, valid -180..180 deg.

    Attached flow: cl = 2 pi sin(alpha - alpha_L0), cd = cd0(Re) + k cl^2 with
    cd0 = 0.009 (Re / 1e6)^-0.15 (turbulent skin-friction trend).
    Post-stall: flat plate with normal-force coefficient 2 (lift) and 1.9
    (drag): cl = 2 sin(alpha) cos(alpha), cd = cd0 + 1.9 sin^2(alpha).
    A logistic blend in |alpha - alpha_L0| centred on the stall angle (14 deg
    past zero lift, cl_max about 1.5) joins the two.
    """

    def __init__(self, alpha_L0_deg: float = ALPHA_L0_DEG, stall_deg: float = 14.0, width_deg: float = 1.5,
                 cd0: float = 0.009, k: float = 0.008):
        self.alpha_L0 = math.radians(alpha_L0_deg)
        self.stall = math.radians(stall_deg)
        self.width = math.radians(width_deg)
        self.cd0 = cd0
        self.k = k

    def coefficients(self, alpha_deg, reynolds):
        a = np.radians(np.asarray(alpha_deg, dtype=float))
        re = np.asarray(reynolds, dtype=float)
        cd0 = self.cd0 * (np.maximum(re, 1e4) / 1e6) ** -0.15
        da = np.angle(np.exp(1j * (a - self.alpha_L0)))       # wrapped to (-pi, pi]
        attached = 1.0 / (1.0 + np.exp((np.abs(da) - self.stall) / self.width))
        cl_att = 2.0 * np.pi * np.sin(da)
        cl_fp = 2.0 * np.sin(a) * np.cos(a)
        cd_fp = cd0 + 1.9 * np.sin(a) ** 2
        cl = attached * cl_att + (1.0 - attached) * cl_fp
        cd = attached * (cd0 + self.k * cl_att**2) + (1.0 - attached) * cd_fp
        return cl, cd, np.zeros_like(cl)


def c172_blade(n_blades: int = 2, section: SectionPolar | None = None) -> Blade:
    return helical_blade(D, n_blades, PITCH, hub_radius_m=HUB, chord_over_R=CHORD_OVER_R,
                         section=section if section is not None else AnalyticPolar())


J_GRID = np.round(np.arange(0.0, 1.40001, 0.05), 10)


@pytest.fixture(scope="module")
def blade() -> Blade:
    return c172_blade()


@pytest.fixture(scope="module")
def tables(blade: Blade) -> PropellerTables:
    return propeller_tables(blade, J_GRID, rpm=RPM)


@pytest.fixture(scope="module")
def cs_tables(blade: Blade) -> PropellerTables:
    return propeller_tables(blade, J_GRID, rpm=RPM, beta75_deg=np.arange(10.0, 40.01, 5.0))


def zero_crossing(J: np.ndarray, C: np.ndarray) -> float:
    i = int(np.flatnonzero((C[:-1] > 0) & (C[1:] <= 0))[0])
    return float(J[i] + C[i] * (J[i + 1] - J[i]) / (C[i] - C[i + 1]))


# ----------------------------------------------------------------------------- geometry


def test_helical_blade_beta75_matches_pitch(blade: Blade) -> None:
    expected = math.degrees(math.atan(PITCH_IN / (math.pi * 0.75 * D_IN)))
    assert abs(expected - 18.52) < 0.01
    assert abs(blade.beta75_deg - expected) < 0.05
    # constant geometric pitch at every station: 2 pi r tan(beta) = pitch
    r = blade.r_over_R * R
    np.testing.assert_allclose(2 * np.pi * r * np.tan(np.radians(blade.beta_deg)), PITCH, rtol=1e-12)
    assert blade.r_over_R[0] == pytest.approx(0.15) and blade.r_over_R[-1] == 1.0
    assert blade.chord_m.max() == pytest.approx(0.13 * R, rel=0.02)


def test_with_beta75_rotates_whole_blade(blade: Blade) -> None:
    b30 = blade.with_beta75(30.0)
    assert b30.beta75_deg == pytest.approx(30.0, abs=1e-12)
    np.testing.assert_allclose(b30.beta_deg - blade.beta_deg, 30.0 - blade.beta75_deg, rtol=1e-12)
    np.testing.assert_array_equal(b30.chord_m, blade.chord_m)


def test_blade_validation_lists_every_problem() -> None:
    with pytest.raises(GeometryError) as err:
        Blade(diameter_m=D, n_blades=2, hub_radius_m=HUB, r_over_R=np.array([0.15, 0.5, 0.9]),
              chord_m=np.array([0.1, -0.1, 0.1]), beta_deg=np.array([30.0, 20.0, 15.0]), section=AnalyticPolar())
    wheres = [p.where for p in err.value.problems]
    assert wheres == ["r_over_R", "chord_m"]


def test_bem_point_rejects_bad_conditions(blade: Blade) -> None:
    with pytest.raises(InputError) as err:
        bem_point(blade, V_ms=-1.0, rpm=0.0)
    assert {p.where for p in err.value.problems} == {"V_ms", "rpm"}


# ----------------------------------------------------------------------------- physics


def test_zero_thrust_advance_ratio(tables: PropellerTables, blade: Blade) -> None:
    J0 = zero_crossing(tables.J, tables.CT)
    J0_est = math.pi * 0.75 * math.tan(math.radians(blade.beta75_deg - ALPHA_L0_DEG))
    assert abs(J0 - J0_est) < 0.10 * J0_est
    # cambered section: zero lift below the geometric pitch angle -> J0 above P/D
    assert J0 > PITCH_IN / D_IN


def test_efficiency_below_actuator_disk_ideal(blade: Blade) -> None:
    for J in (0.2, 0.4, 0.6, 0.75, 0.85):
        p = bem_point(blade, V_ms=J * N * D, rpm=RPM)
        assert p.converged and p.CT > 0
        ideal = 2.0 / (1.0 + math.sqrt(1.0 + 8.0 * p.CT / (math.pi * J**2)))
        assert 0.5 * ideal < p.efficiency < ideal, (J, p.efficiency, ideal)


def test_static_figure_of_merit_below_one(blade: Blade) -> None:
    """Static momentum bound: P >= T^1.5 / sqrt(2 rho A), i.e. CT^1.5 / (sqrt(pi/2) CP) < 1."""
    p = bem_point(blade, V_ms=0.0, rpm=RPM)
    assert isinstance(p, BEMPoint)
    assert p.converged and p.J == 0.0 and p.CT > 0
    fm = p.CT**1.5 / (math.sqrt(math.pi / 2) * p.CP)
    assert 0.2 < fm < 1.0
    assert np.all(np.isnan(p.a[p.F > 0]))        # axial induction factor undefined at V = 0


def test_static_reverse_pitch_gives_reverse_thrust(blade: Blade) -> None:
    p = bem_point(blade.with_beta75(-10.0), V_ms=0.0, rpm=RPM)
    assert p.converged and p.CT < 0 and p.CP > 0
    assert np.min(p.phi_deg) < 0                  # flow reversed through the outer disk


def test_compressibility_option_raises_lift_and_thrust(blade: Blade) -> None:
    plain = bem_point(blade, V_ms=0.5 * 45 * D, rpm=2700.0)
    pg = bem_point(blade, V_ms=0.5 * 45 * D, rpm=2700.0, compressibility=True)
    assert pg.converged and 1.02 * plain.CT < pg.CT < 1.4 * plain.CT


def test_tip_loss_reduces_thrust(blade: Blade) -> None:
    # working range (at J = 0 the analytic blade is partly stalled, where lower tip
    # angle of attack from the tip loss can even raise the thrust)
    for J in (0.3, 0.5, 0.7):
        with_loss = bem_point(blade, V_ms=J * N * D, rpm=RPM, tip_loss=True)
        without = bem_point(blade, V_ms=J * N * D, rpm=RPM, tip_loss=False)
        assert with_loss.converged and without.converged
        assert with_loss.CT < 0.97 * without.CT
        assert with_loss.F[-1] == 0.0 and with_loss.dT_dr[-1] == 0.0
        assert without.F[-1] > 0.999 and without.dT_dr[-1] > 0.0   # only the (inboard) hub loss remains
        tip = without.r_over_R > 0.9
        assert np.all(with_loss.F[tip] < without.F[tip])


def test_fixed_pitch_performance_curve(tables: PropellerTables) -> None:
    J, CT, CP = tables.J, tables.CT, tables.CP
    J0 = zero_crossing(J, CT)
    working = (J >= 0.45) & (J <= J0)
    eff = np.where(CP > 0, J * CT / CP, np.nan)
    i = int(np.nanargmax(np.where(J < J0, eff, np.nan)))
    assert 0.70 <= eff[i] <= 0.90
    assert 0.55 <= J[i] <= 0.85
    assert np.all(np.diff(CT[working]) < 0)
    assert np.all(CP[J < J0] > 0)
    assert CT[0] > 0.04 and CP[0] > 0.02          # static thrust and power are substantial
    assert tables.provenance["unconverged_points"] == "none"


def test_more_blades_more_thrust() -> None:
    two, three = c172_blade(2), c172_blade(3)
    for J in (0.3, 0.5, 0.7):
        ct2 = bem_point(two, V_ms=J * N * D, rpm=RPM).CT
        ct3 = bem_point(three, V_ms=J * N * D, rpm=RPM).CT
        assert ct3 > 1.1 * ct2, (J, ct2, ct3)


def test_station_solution_satisfies_momentum_balance(blade: Blade) -> None:
    """Blade-element loads equal the annulus momentum loads at every converged station."""
    rho = 1.225
    V = 0.6 * N * D
    omega = 2 * math.pi * N
    p = bem_point(blade, V_ms=V, rpm=RPM, rho=rho)
    r = p.r_over_R * R
    live = (p.F > 0) & (np.abs(p.a) < 0.4)
    assert live.sum() >= len(r) - 2
    dT_mom = 4 * math.pi * r * rho * V**2 * (1 + p.a) * p.a * p.F
    dQ_mom = 4 * math.pi * r**3 * rho * V * (1 + p.a) * omega * p.a_prime * p.F
    np.testing.assert_allclose(p.dT_dr[live], dT_mom[live], rtol=1e-6)
    np.testing.assert_allclose(p.dQ_dr[live], dQ_mom[live], rtol=1e-6)
    # and the solved inflow angle closes the velocity triangle
    phi = np.radians(p.phi_deg[live])
    np.testing.assert_allclose(np.tan(phi), V * (1 + p.a[live]) / (omega * r[live] * (1 - p.a_prime[live])), rtol=1e-6)


def test_windmill_and_deep_stall_are_solved(blade: Blade) -> None:
    # low pitch, high speed: windmilling (negative thrust and power), Buhl region at some stations
    rho, V = 1.225, 1.0 * N * D
    wm = bem_point(blade.with_beta75(5.0), V_ms=V, rpm=RPM, rho=rho)
    assert wm.converged and wm.CT < 0 and wm.CP < 0
    buhl = (wm.a < -0.4) & (wm.F > 0)
    assert buhl.any()
    # there the blade-element thrust equals Buhl's empirical turbulent-wake thrust
    aw, F, r = -wm.a[buhl], wm.F[buhl], wm.r_over_R[buhl] * R
    ct_buhl = 8 / 9 + (4 * F - 40 / 9) * aw + (50 / 9 - 4 * F) * aw**2
    np.testing.assert_allclose(-wm.dT_dr[buhl] / (math.pi * rho * V**2 * r), ct_buhl, rtol=1e-6)
    # coarse pitch, static: the blade is stalled but still pushes
    st = bem_point(blade.with_beta75(40.0), V_ms=0.0, rpm=RPM)
    assert st.converged and st.CT > 0 and st.CP > 0
    assert np.max(st.alpha_deg) > 14.0 + ALPHA_L0_DEG


def test_constant_speed_tables_increase_with_blade_angle(cs_tables: PropellerTables, blade: Blade) -> None:
    betas = cs_tables.beta75_deg
    assert cs_tables.CT.shape == (J_GRID.size, betas.size)
    checked = 0
    for i, J in enumerate(cs_tables.J):
        if J < 0.3:
            continue
        # working range at this J: 0.75R geometric angle of attack between 0 and 9 deg (attached flow)
        alpha_geo = betas - math.degrees(math.atan(J / (0.75 * math.pi)))
        cols = np.flatnonzero((alpha_geo >= 0.0) & (alpha_geo <= 9.0))
        if cols.size < 2:
            continue
        checked += 1
        assert np.all(np.diff(cs_tables.CT[i, cols]) > 0), J
        assert np.all(np.diff(cs_tables.CP[i, cols]) > 0), J
    assert checked >= 10
    # the reference-angle column reproduces the fixed-pitch evaluation of the rotated blade
    p = bem_point(blade.with_beta75(20.0), V_ms=0.7 * N * D, rpm=RPM)
    j = int(np.argmin(np.abs(cs_tables.J - 0.7)))
    k = int(np.flatnonzero(betas == 20.0)[0])
    assert cs_tables.CT[j, k] == pytest.approx(p.CT, rel=1e-12)
    assert cs_tables.CP[j, k] == pytest.approx(p.CP, rel=1e-12)


# ----------------------------------------------------------------------------- calibration factors


def test_the_tables_take_the_registrys_propeller_factors(tables: PropellerTables) -> None:
    """physics.propeller names the factors its tables take without reading the factor registry:
    they are the registry's propeller factors but the rotating inertia (K_Ip, the file's <ixx>),
    in order, and a missing value is refused."""
    assert TABLE_FACTORS + ("K_Ip",) == PROPELLER_FACTORS
    with pytest.raises(ValueError, match="K_CQ_quad"):
        apply_factors(tables, {n: 0.0 for n in TABLE_FACTORS[:-1]})


def test_neutral_factors_are_bitwise_identity(tables: PropellerTables, cs_tables: PropellerTables) -> None:
    for base in (tables, cs_tables):
        out = apply_factors(base, propeller_factor_values(dict()))
        assert out.CT.tobytes() == base.CT.tobytes()
        assert out.CP.tobytes() == base.CP.tobytes()
        assert out.J.tobytes() == base.J.tobytes()
        assert out.provenance["factor.K_CT_scale"] == "1.0"
        assert out.provenance["rpm"] == base.provenance["rpm"]


def test_scale_doubles_exactly(tables: PropellerTables) -> None:
    out = apply_factors(tables, propeller_factor_values(dict(K_CT_scale=2.0, K_CQ_scale=0.5)))
    np.testing.assert_array_equal(out.CT, 2.0 * tables.CT)
    np.testing.assert_array_equal(out.CP, 0.5 * tables.CP)
    assert out.provenance["factor.K_CT_scale"] == "2.0"


def test_shift_moves_curve(tables: PropellerTables) -> None:
    shift = 0.1                                    # two table steps
    out = apply_factors(tables, propeller_factor_values(dict(K_CT_shift=shift, K_CQ_shift=-shift)))
    np.testing.assert_allclose(out.CT[:-2], tables.CT[2:], atol=1e-12)
    np.testing.assert_allclose(out.CP[2:], tables.CP[:-2], atol=1e-12)
    # beyond the table: linear extrapolation by the end slope
    slope = (tables.CT[-1] - tables.CT[-2]) / (tables.J[-1] - tables.J[-2])
    assert out.CT[-1] == pytest.approx(tables.CT[-1] + slope * shift, rel=1e-9)


def test_tilt_and_quad_by_hand(tables: PropellerTables) -> None:
    f = dict(J_anchor=0.6, K_CT_scale=1.1, K_CT_tilt=0.5, K_CT_quad=-2.0,
                         K_CQ_shift=0.0, K_CQ_tilt=-0.3, K_CQ_quad=1.0)
    out = apply_factors(tables, propeller_factor_values(f))
    J = tables.J
    for Jx in (0.2, 1.0):
        i = int(np.argmin(np.abs(J - Jx)))
        d = Jx - 0.6
        assert out.CT[i] == pytest.approx(1.1 * tables.CT[i] * (1 + 0.5 * d - 2.0 * d * d), rel=1e-12)
        assert out.CP[i] == pytest.approx(tables.CP[i] * (1 - 0.3 * d + 1.0 * d * d), rel=1e-12)
    # at the anchor tilt and quad do nothing
    i = int(np.argmin(np.abs(J - 0.6)))
    assert out.CT[i] == pytest.approx(1.1 * tables.CT[i], rel=1e-12)


def test_factors_on_constant_speed_tables_per_column(cs_tables: PropellerTables) -> None:
    f = dict(K_CT_shift=0.05, K_CT_scale=0.9, K_CT_tilt=0.2, K_CQ_scale=1.2, K_CQ_quad=0.4)
    out = apply_factors(cs_tables, propeller_factor_values(f))
    assert out.CT.shape == cs_tables.CT.shape and out.beta75_deg is not None
    np.testing.assert_array_equal(out.beta75_deg, cs_tables.beta75_deg)
    for k in range(cs_tables.beta75_deg.size):
        fixed = PropellerTables(J=cs_tables.J, beta75_deg=None, CT=cs_tables.CT[:, k], CP=cs_tables.CP[:, k],
                                provenance={})
        col = apply_factors(fixed, propeller_factor_values(f))
        np.testing.assert_allclose(out.CT[:, k], col.CT, rtol=0, atol=1e-15)
        np.testing.assert_allclose(out.CP[:, k], col.CP, rtol=0, atol=1e-15)
    # a different output grid is allowed
    Jo = np.linspace(0.0, 1.2, 7)
    out2 = apply_factors(cs_tables, propeller_factor_values(dict()), J_out=Jo)
    np.testing.assert_array_equal(out2.J, Jo)
    assert out2.CT.shape == (7, cs_tables.beta75_deg.size)


# ----------------------------------------------------------------------------- stored polar


def _clarky_available() -> bool:
    if not (REPO / "airfoils" / "clarky.csv").exists():
        return False
    try:
        import jsbsim_calib.physics.airfoil as af  # noqa: F401
    except Exception:
        return False
    return hasattr(af, "load_airfoil")


@pytest.mark.skipif(not _clarky_available(), reason="jsbsim_calib.physics.airfoil or airfoils/clarky.csv not available")
def test_c172_prop_with_stored_clarky_polar() -> None:
    from jsbsim_calib.physics.airfoil import load_airfoil

    section = load_airfoil("clarky", [REPO / "airfoils"])
    blade = c172_blade(section=section)
    tab = propeller_tables(blade, J_GRID, rpm=RPM)
    J0 = zero_crossing(tab.J, tab.CT)
    assert PITCH_IN / D_IN < J0 < 1.15
    eff = np.where((tab.CP > 0) & (tab.J < J0), tab.J * tab.CT / tab.CP, np.nan)
    i = int(np.nanargmax(eff))
    assert 0.65 <= eff[i] <= 0.92 and 0.5 <= tab.J[i] <= 0.9     # BEM runs a few % above test data
    assert np.all(tab.CP[tab.J < J0] > 0)
    working = (tab.J >= 0.45) & (tab.J <= J0)
    assert np.all(np.diff(tab.CT[working]) < 0)
    assert tab.provenance["unconverged_points"] == "none"
