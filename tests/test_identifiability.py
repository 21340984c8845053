"""Issue 28, item 2: the identifiability table of the calibration reports, on a real fit."""
import math

import numpy as np
import pytest

from jsbsim_calib.calibration.fit import FitResult, fit, residual_group
from jsbsim_calib.calibration.points import PointSet, point_residuals
from jsbsim_calib.data.load import load_dataset
from jsbsim_calib.evaluation.evaluate import evaluate_dataset
from jsbsim_calib.factors import FactorSet
from jsbsim_calib.jsbsim.simulator import Simulator
from jsbsim_calib.report.identifiability import identifiability_section
from jsbsim_calib.report.verdicts import TARGETS


def test_residual_groups_drop_the_row_and_keep_the_quantity():
    assert residual_group("poh_cruise[12].gph") == "poh_cruise.gph"
    assert residual_group("snapshot[3].throttle>1") == "snapshot.throttle>1"
    assert residual_group("C.19 q_peak") == "C.19 q_peak"
    assert residual_group("prior K_FF") == "prior"


@pytest.fixture(scope="module")
def fuel_and_pitch_damping(repo):
    """K_FF (fuel flow sets it) and K_Cmq (no steady cruise point feels pitch damping) fitted
    together on five POH cruise points, with the fit's prior."""
    with Simulator(repo, "c172") as sim:
        cruise = load_dataset(repo / "data" / "c172_poh_cruise.csv")
        ps = PointSet.from_dataset(cruise, sim, [0, 8, 18, 29, 36], metrics=("gph",))

        def residuals(fs):
            sim.set_factors(fs)
            r, lab, _ = point_residuals(sim, ps, ("gph",))
            return np.array(r), lab

        yield fit("fuel", ["K_FF", "K_Cmq"], sim.factors, residuals, sim=sim, max_nfev=40, legs=((1.0, 0.02),))


def test_the_data_carry_a_determined_factor_and_the_prior_an_untouched_one(fuel_and_pitch_damping):
    res = fuel_and_pitch_damping
    ff, cmq = dict(res.information["K_FF"]), dict(res.information["K_Cmq"])
    assert ff["poh_cruise.gph"] > 0.9 and math.isclose(sum(ff.values()), 1.0, rel_tol=1e-12)
    assert cmq.get("poh_cruise.gph", 0.0) < 1e-6 and cmq["prior"] > 0.999
    assert res.determination("K_FF") == "determined"
    assert res.determination("K_Cmq").startswith(("held by the prior", "not identified"))
    table = identifiability_section([res])
    row = next(line for line in table if line.startswith("| fuel | K_FF |"))
    assert "poh_cruise.gph" in row and row.endswith("| determined |")
    assert any("K_Cmq (fuel: " in line for line in table if line.startswith("Not determined"))


def test_a_nan_standard_error_is_never_determined(fuel_and_pitch_damping):
    res = fuel_and_pitch_damping
    bad = FitResult(**{**res.__dict__, "stderr": {**res.stderr, "K_FF": float("nan")}})
    assert bad.determination("K_FF") == "not identified"
    row = next(line for line in identifiability_section([bad]) if "| K_FF |" in line)
    assert "nan" not in row.lower() and row.endswith("| not identified |")


# --------------------------------------------------------------------------- prediction bands (item 1)
def test_a_band_is_the_factors_interval_carried_through_the_model(repo, fuel_and_pitch_damping):
    """Each fuel-flow band must be Z95 * SE(K_FF) * |d gph / d K_FF| (the sensitivity taken here
    with a step four times the bands' own, in physical units); neither factor moves the RPM of a
    steady point (its band: zero, to the trims' precision)."""
    from jsbsim_calib.calibration.bands import prediction_bands
    from jsbsim_calib.calibration.fit import Z95
    res = fuel_and_pitch_damping
    cruise = load_dataset(repo / "data" / "c172_poh_cruise.csv")
    with Simulator(repo, "c172") as sim:
        sim.set_factors(res.final)
        bands = prediction_bands(sim, res.final, [res], {"poh_cruise": evaluate_dataset(sim, cruise)})
        conds = PointSet.from_dataset(cruise, sim).conditions
        f = res.final.factor("K_FF")
        d = 4 * 0.002 * 0.5 * (f.upper - f.lower)
        gph = []
        for k_ff in (res.final["K_FF"], res.final["K_FF"] + d):
            sim.set_factors(res.final.with_vector(["K_FF"], [k_ff], normalized=False))
            gph.append(np.array([sim.trim_level(c).gph for c in conds]))
    expected = Z95 * res.stderr["K_FF"] * np.abs(gph[1] - gph[0]) / d
    band = bands.rows["poh_cruise"]["gph"]
    assert np.all(np.isfinite(band)) and band == pytest.approx(expected, rel=1e-3)
    assert np.all(bands.rows["poh_cruise"]["rpm"] < 0.01) and bands.rmse["poh_cruise"]["rpm"] < 0.01   # rpm
    assert math.isfinite(bands.rmse["poh_cruise"]["gph"]) and bands.rmse["poh_cruise"]["gph"] > 0


def test_a_verdict_says_whether_its_band_crosses_the_target_and_a_nan_has_no_band():
    from jsbsim_calib.calibration.bands import Bands
    b = Bands({}, {"poh_climb": {"roc_fpm": 3.0}, "poh_cruise": {"rpm": float("nan")}})
    assert b.confidence("poh_climb", "roc_fpm", 16.0, 20.0) == "band inside"     # 13-19: a sure PASS
    assert b.confidence("poh_climb", "roc_fpm", 18.5, 20.0) == "band across"     # 15.5-21.5
    assert b.confidence("poh_climb", "roc_fpm", 24.0, 20.0) == "band inside"     # a sure FAIL
    assert b.confidence("poh_climb", "roc_fpm", float("nan"), 20.0) == "no band"
    assert b.confidence("poh_cruise", "rpm", 9.0, 10.0) == "no band"


def test_no_band_without_a_covariance(repo, fuel_and_pitch_damping):
    from jsbsim_calib.calibration.bands import prediction_bands
    blind = FitResult(**{**fuel_and_pitch_damping.__dict__, "covariance": None})
    with Simulator(repo, "c172") as sim:
        assert prediction_bands(sim, blind.final, [blind], {}) is None


def test_each_factor_takes_its_covariance_from_the_last_fit_that_set_it():
    """A chain's steps refit some factors: the band uses the last fit's block for each (the
    marginal covariance of a later fit replaces the earlier one); a step that fitted nothing
    sets nothing."""
    from types import SimpleNamespace

    from jsbsim_calib.calibration.bands import covariance
    first = SimpleNamespace(names=["a", "b"], covariance=np.array([[1.0, 0.5], [0.5, 2.0]]), njev=3)
    last = SimpleNamespace(names=["b", "c"], covariance=np.array([[3.0, 0.1], [0.1, 4.0]]), njev=2)
    idle = SimpleNamespace(names=["c"], covariance=None, njev=0)
    names, C = covariance([first, last, idle])
    assert names == ["b", "c", "a"]
    assert np.array_equal(C, np.array([[3.0, 0.1, 0.0], [0.1, 4.0, 0.0], [0.0, 0.0, 1.0]]))
    assert covariance([SimpleNamespace(names=["a"], covariance=None, njev=5)]) is None


def test_a_share_within_tolerance_gets_the_range_its_bands_allow():
    from jsbsim_calib.calibration.bands import Bands
    b = Bands({"snapshot": {"rudder_deg": np.array([0.2, 0.2, 0.6, 0.1])}}, {})
    err, tol = np.array([0.5, -0.9, 1.5, np.nan]), np.ones(4)
    assert b.within_range("snapshot", "rudder_deg", err, tol) == (25.0, 75.0)   # a NaN: outside at both ends
    assert all(math.isnan(v) for v in b.within_range("snapshot", "pitch_deg", err, tol))
    from jsbsim_calib.calibration.bands import holds
    within_95 = next(t for t in TARGETS if t.statistic == "within_pct" and t.limit == 95.0)
    assert holds(90.0, 100.0, within_95.met_by) == "band across" and holds(96.0, 100.0, within_95.met_by) == "band inside"
    assert holds(25.0, 75.0, within_95.met_by) == "band inside"           # a sure FAIL
    assert holds(float("nan"), 100.0, within_95.met_by) == "no band"    # a share without a band is never confident


@pytest.mark.slow
def test_the_95_percent_bands_cover_the_truth_in_12_campaigns(repo, tmp_path):
    """Issue 28: synthetic snapshot campaigns of a truth C172 (elevator gearing and offset
    moved), each refitted by the committed model and its bands drawn. The sweep over 50
    campaigns is a benchmark (``benchmarks/band_coverage.py``: 97.1 % of 795 rows, 47 of 50
    campaigns with every row covered, the intervals 48 and 49 of 50); here 12 of them. Measured:
    91.7 % of 192 rows, 10 of 12 campaigns whole, each interval 11 of 12. Bands too narrow
    lose rows (below 85 %); bands far too wide cover every row of every campaign."""
    import warnings

    from jsbsim_calib.synthetic.coverage import campaigns
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        runs = campaigns(repo, "c172", {"K_de_slope": 1.25, "K_de_offset": -1.0}, range(12), tmp_path)
    whole = sum(bool(c.covered.all()) for c in runs)
    assert 9 <= whole <= 11, whole
    for n in ("K_de_slope", "K_de_offset"):
        assert sum(c.inside[n] for c in runs) >= 10, n
    rows = np.concatenate([c.covered for c in runs])
    assert 0.85 <= rows.mean() <= 0.99 and rows.size == 192, (rows.mean(), rows.size)
