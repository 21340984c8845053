"""Tests of jsbsim_calib.physics.airfoil on the stored polars in airfoils/ (real data, physics facts)."""
from __future__ import annotations

import sys

import numpy as np
import pytest

from jsbsim_calib.physics.airfoil import (
    AIRFOIL_DIR,
    DEFAULT_REYNOLDS,
    STORED_AIRFOILS,
    Airfoil,
    MissingDependencyError,
    Polar,
    available_airfoils,
    compute_airfoil,
    load_airfoil,
    naca4_coordinates,
    read_airfoil_csv,
    viterna_extend,
    write_airfoil_csv,
)
from jsbsim_calib.core.errors import DataError, GeometryError

STORED = sorted(STORED_AIRFOILS)


@pytest.fixture(scope="module")
def airfoils() -> dict[str, Airfoil]:
    return {name: load_airfoil(name, [AIRFOIL_DIR]) for name in STORED}


# --- the stored files ------------------------------------------------------------------------


def test_every_registered_airfoil_is_stored_with_provenance(airfoils):
    assert set(STORED) <= set(available_airfoils([AIRFOIL_DIR]))
    for name, af in airfoils.items():
        assert af.name == name
        np.testing.assert_allclose(af.reynolds, DEFAULT_REYNOLDS)
        prov = af.provenance
        assert prov["airfoil"] == name
        assert prov["tool"] == "NeuralFoil 0.3.3"
        assert prov["regenerate"] == f"jsbsim-calib airfoil {name}"
        for key in ("coordinates", "model_size", "n_crit", "mach", "post_stall", "cd_max"):
            assert prov[key], key
        assert (AIRFOIL_DIR / f"{name}.csv").stat().st_size < 150_000
    assert "STAND-IN" in airfoils["nlf0115"].provenance["usage"]
    assert "SR20" in airfoils["nlf0115"].provenance["usage"]


def test_naca2412_at_re_3e6_matches_wind_tunnel_and_theory(airfoils):
    p = airfoils["naca2412"].polar(3e6)
    assert p.reynolds == 3e6
    # Thin-airfoil theory: about -2.1 deg for 2 % camber at 40 % chord.
    assert -2.6 < p.alpha_zero_lift_deg < -1.6
    assert 5.6 < p.lift_slope_per_rad < 6.7
    # Abbott & von Doenhoff: cl_max about 1.6 at Re 3.1e6 (smooth).
    assert 1.4 < p.cl_max < 1.85
    assert 12.0 < p.alpha_cl_max_deg < 22.0
    assert 0.004 < p.cd_min < 0.009
    assert -0.07 < p.cm0 < -0.03


@pytest.mark.parametrize("name", ["naca0009", "naca0012"])
def test_symmetric_sections_are_symmetric(airfoils, name):
    af = airfoils[name]
    alpha = np.arange(-180.0, 180.01, 2.5)
    for re in (*DEFAULT_REYNOLDS, 2.5e6):
        cl, cd, cm = af.coefficients(alpha, re)
        cl0, cd0, cm0 = af.coefficients(0.0, re)
        assert abs(cl0) < 1e-3 and abs(cm0) < 1e-3
        np.testing.assert_allclose(cl, -cl[::-1], atol=1e-4)   # odd
        np.testing.assert_allclose(cd, cd[::-1], atol=1e-4)    # even
        np.testing.assert_allclose(cm, -cm[::-1], atol=1e-4)   # odd
        assert abs(af.polar(re).alpha_zero_lift_deg) < 0.05


@pytest.mark.parametrize("name", STORED)
def test_full_range_continuous_and_flat_plate_like(airfoils, name):
    for p in airfoils[name].polars:
        assert p.alpha_deg[0] == -180.0 and p.alpha_deg[-1] == 180.0
        assert np.all(np.diff(p.alpha_deg) > 0)
        assert np.max(np.abs(np.diff(p.cl))) <= 0.3, f"cl jump at Re {p.reynolds:g}"
        assert np.max(np.abs(np.diff(p.cm))) <= 0.3, f"cm jump at Re {p.reynolds:g}"
        assert np.all(p.cd > 0)
        cl, cd, cm = p.coefficients(np.array([-180.0, -90.0, 90.0, 180.0]))
        assert cl[0] == 0.0 and cl[3] == 0.0
        assert cd[0] == cd[3] and cm[0] == cm[3]
        assert 1.8 <= cd[1] <= 2.1 and 1.8 <= cd[2] <= 2.1
        # centre of pressure near mid chord at 90 deg: cm about c/4 = -cn/4, nose down.
        assert -0.6 < cm[2] < -0.4 and 0.4 < cm[1] < 0.6
        # attached flow uses NeuralFoil, deep stall the post-stall model
        src = dict(zip(p.alpha_deg, p.source))
        assert src[0.0] == "neuralfoil" and src[5.0] == "neuralfoil"
        assert src[45.0] == "viterna" and src[-45.0] == "viterna"
        # drag grows from the attached minimum to the flat-plate maximum; a fixed-transition
        # (fully turbulent) section has about twice the laminar minimum drag
        from jsbsim_calib.physics.airfoil import split_transition
        limit = 0.012 if split_transition(p.name)[1] is None else 0.016
        assert p.cd_min < limit and p.cd_min < p.coefficients(30.0)[1] < cd[2]


def test_angles_outside_the_table_wrap_around(airfoils):
    p = airfoils["naca2412"].polars[0]
    for a, b in ((190.0, -170.0), (-200.0, 160.0), (370.0, 10.0)):
        np.testing.assert_allclose(p.coefficients(a), p.coefficients(b), atol=1e-12)


# --- Reynolds interpolation --------------------------------------------------------------------


def test_polar_at_stored_reynolds_is_the_stored_polar(airfoils):
    af = airfoils["naca2412"]
    for stored in af.polars:
        assert af.polar(stored.reynolds) is stored
        cl, cd, cm = af.coefficients(stored.alpha_deg, stored.reynolds)
        np.testing.assert_array_equal(cl, stored.cl)
        np.testing.assert_array_equal(cd, stored.cd)
        np.testing.assert_array_equal(cm, stored.cm)


def test_polar_between_two_reynolds_lies_between_them(airfoils):
    af = airfoils["naca2412"]
    lo, hi = af.polar(2e6), af.polar(3e6)
    mid = af.polar(2.5e6)
    assert mid.reynolds == 2.5e6
    a = mid.alpha_deg
    for k in range(3):
        ya, yb, ym = lo.coefficients(a)[k], hi.coefficients(a)[k], mid.coefficients(a)[k]
        assert np.all(ym >= np.minimum(ya, yb) - 1e-12) and np.all(ym <= np.maximum(ya, yb) + 1e-12)
    # linear in log(Re): sqrt(2e6 * 3e6) is exactly half way
    geo = af.polar(np.sqrt(2e6 * 3e6))
    np.testing.assert_allclose(geo.coefficients(a)[0], 0.5 * (lo.coefficients(a)[0] + hi.coefficients(a)[0]),
                               atol=1e-12)
    assert lo.cl_max < mid.cl_max < hi.cl_max


def test_reynolds_outside_the_stored_range_is_clamped(airfoils):
    af = airfoils["naca2412"]
    assert af.polar(1e4) is af.polars[0]
    assert af.polar(1e9) is af.polars[-1]
    a = np.linspace(-30, 30, 7)
    np.testing.assert_array_equal(af.coefficients(a, 1e9)[0], af.polars[-1].coefficients(a)[0])


def test_coefficients_broadcast_and_agree_with_polar(airfoils):
    af = airfoils["clarky"]
    alpha = np.linspace(-40.0, 40.0, 9)[:, None]
    re = np.array([3e5, 1.5e6, 4e6, 2e7])
    cl, cd, cm = af.coefficients(alpha, re)
    assert cl.shape == cd.shape == cm.shape == (9, 4)
    for j, r in enumerate(re):
        ref = af.polar(r).coefficients(alpha[:, 0])
        for k, got in enumerate((cl, cd, cm)):
            np.testing.assert_allclose(got[:, j], ref[k], atol=1e-12)
    scalar = af.coefficients(4.0, 3e6)
    assert np.ndim(scalar[0]) == 0


# --- file format ---------------------------------------------------------------------------------


@pytest.mark.parametrize("name", STORED)
def test_write_read_roundtrip_gives_identical_bytes(airfoils, name, tmp_path):
    out = tmp_path / f"{name}.csv"
    write_airfoil_csv(airfoils[name], out)
    assert out.read_bytes() == (AIRFOIL_DIR / f"{name}.csv").read_bytes()
    again = read_airfoil_csv(out)
    assert again.provenance == airfoils[name].provenance


def test_unknown_airfoil_names_the_name_and_the_available_ones(tmp_path):
    with pytest.raises(GeometryError) as info:
        load_airfoil("naca9999x", [tmp_path, AIRFOIL_DIR])
    msg = str(info.value)
    assert "naca9999x" in msg
    for name in STORED:
        assert name in msg


def test_first_search_dir_wins_and_names_are_normalised(airfoils, tmp_path):
    src = airfoils["naca0012"]
    only_one = Airfoil(src.name, src.polars[:1], {"airfoil": "naca0012", "mach": "0"})
    write_airfoil_csv(only_one, tmp_path / "naca0012.csv")
    assert len(load_airfoil("NACA 0012", [tmp_path, AIRFOIL_DIR]).polars) == 1
    assert len(load_airfoil("NACA 0012", [AIRFOIL_DIR, tmp_path]).polars) == len(DEFAULT_REYNOLDS)


def test_malformed_file_lists_every_problem(tmp_path):
    bad = tmp_path / "bad.csv"
    bad.write_text("# airfoil: bad\nreynolds,alpha_deg,cl,cd,cm,source\n"
                   "1e6,-180,0,0.02,0,viterna\n1e6,0,abc,0.01,0,neuralfoil\n"
                   "1e6,170,0,0.02,0,guess\n")
    with pytest.raises(DataError) as info:
        read_airfoil_csv(bad)
    problems = info.value.problems
    assert any("line 4" in p.where for p in problems)
    assert any("line 5" in p.where and "guess" in p.message for p in problems)


# --- building blocks ---------------------------------------------------------------------------


def test_naca4_coordinates_geometry():
    xy = naca4_coordinates("0012")
    assert xy.shape == (161, 2)
    np.testing.assert_allclose(xy[0], [1.0, 0.0], atol=1e-12)    # closed trailing edge
    np.testing.assert_allclose(xy[-1], [1.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(xy[80], [0.0, 0.0], atol=1e-12)   # leading edge
    upper, lower = xy[:81][::-1], xy[80:]
    thickness = upper[:, 1] - lower[:, 1]
    assert abs(thickness.max() - 0.12) < 1e-3
    assert 0.28 < upper[np.argmax(thickness), 0] < 0.32
    xy = naca4_coordinates("naca2412", n_points=201)
    upper, lower = xy[:101][::-1], xy[100:]
    camber = 0.5 * (upper[:, 1] + lower[:, 1])
    assert abs(camber.max() - 0.02) < 2e-4
    assert 0.37 < upper[np.argmax(camber), 0] < 0.43
    with pytest.raises(GeometryError):
        naca4_coordinates("24a2")
    with pytest.raises(GeometryError):
        naca4_coordinates("2412", n_points=160)


def test_viterna_extend_is_continuous_and_flat_plate_like():
    a = np.arange(-15.0, 16.0, 1.0)
    cl = 0.1 * a
    cd = 0.006 + 0.0004 * a**2
    cm = -0.05 + 0.001 * a
    af, clf, cdf, cmf = viterna_extend(a, cl, cd, cm, cd_max=1.9, alpha_match_hi_deg=14.0,
                                       alpha_match_lo_deg=-12.0)
    assert af[0] == -180.0 and af[-1] == 180.0 and np.all(np.diff(af) > 0)
    inner = (af >= -12.0) & (af <= 14.0)
    np.testing.assert_array_equal(af[inner], a[(a >= -12) & (a <= 14)])
    np.testing.assert_array_equal(clf[inner], cl[(a >= -12) & (a <= 14)])
    # continuity: just beyond the matching angles the model stays close to the matched values
    fine = np.array([-12.001, 14.001])
    for full, base in ((clf, cl), (cdf, cd), (cmf, cm)):
        model = np.interp(fine, af, full)
        assert np.all(np.abs(model - np.interp([-12.0, 14.0], a, base)) < 0.01)
    assert clf[0] == 0.0 and clf[-1] == 0.0
    np.testing.assert_allclose(np.interp([-90.0, 90.0], af, cdf), 1.9)
    np.testing.assert_allclose(np.interp(90.0, af, cmf), -1.9 / 4, atol=1e-9)
    with pytest.raises(GeometryError):
        viterna_extend(a, cl, cd, cm, cd_max=1.9, alpha_match_hi_deg=20.0, alpha_match_lo_deg=-12.0)


def test_polar_rejects_bad_tables():
    with pytest.raises(DataError):
        Polar("x", 1e6, 0.0, np.array([-170.0, 180.0]), np.zeros(2), np.ones(2), np.zeros(2))
    with pytest.raises(DataError):
        Polar("x", 1e6, 0.0, np.array([-180.0, 0.0, 0.0, 180.0]), np.zeros(4), np.ones(4), np.zeros(4))


# --- NeuralFoil ------------------------------------------------------------------------------------


def test_stored_naca2412_matches_a_fresh_neuralfoil_run(airfoils):
    try:
        import aerosandbox as asb
        import neuralfoil as nf
    except ImportError:  # pragma: no cover - CI installs it
        pytest.fail("neuralfoil is not installed: pip install jsbsim-calib[airfoils]")
    af = airfoils["naca2412"]
    p = af.polar(3e6)
    alphas = np.array([-8.0, -2.0, 0.0, 4.0, 10.0, 15.5])
    assert all(dict(zip(p.alpha_deg, p.source))[a] == "neuralfoil" for a in alphas)
    out = nf.get_aero_from_airfoil(
        airfoil=asb.Airfoil(name="naca2412", coordinates=naca4_coordinates("2412")),
        alpha=alphas, Re=3e6, n_crit=float(af.provenance["n_crit"]),
        model_size=af.provenance["model_size"])
    cl, cd, cm = p.coefficients(alphas)
    np.testing.assert_allclose(cl, out["CL"], atol=1e-5)
    np.testing.assert_allclose(cd, out["CD"], atol=1e-5)
    np.testing.assert_allclose(cm, out["CM"], atol=1e-5)


def test_recomputing_is_byte_identical_and_matches_the_stored_rows(tmp_path):
    first = compute_airfoil("naca2412", [3e6])
    second = compute_airfoil("naca2412", [3e6])
    write_airfoil_csv(first, tmp_path / "a.csv")
    write_airfoil_csv(second, tmp_path / "b.csv")
    assert (tmp_path / "a.csv").read_bytes() == (tmp_path / "b.csv").read_bytes()
    rows = [r for r in (tmp_path / "a.csv").read_text().splitlines() if r.startswith("3000000,")]
    stored = [r for r in (AIRFOIL_DIR / "naca2412.csv").read_text().splitlines() if r.startswith("3000000,")]
    assert rows == stored


def test_missing_neuralfoil_gives_install_hint(monkeypatch):
    monkeypatch.setitem(sys.modules, "neuralfoil", None)
    with pytest.raises(MissingDependencyError, match=r"pip install jsbsim-calib\[airfoils\]"):
        compute_airfoil("naca0012", [1e6])
