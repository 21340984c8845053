"""Held-out validation, physics checks and the G1000 loading and weight estimate (issue 14, items
1, 4 and 5), on real JSBSim and the project's data; the folds are a reduced set (the full run
is `jsbsim-calib validate AIRCRAFT`, minutes)."""
from __future__ import annotations

import math
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from jsbsim_calib.calibration.validation import (FLAG_RATIO, ErrorStat, FoldMetric, climb_folds, cruise_folds,
                                                 snapshot_test_type, stage_data, stage_factors, trims_folds,
                                                 validate_steady, validate_trims)
from jsbsim_calib.data.logs import LogLoading, log_conditions, log_dataset, log_value
from jsbsim_calib.data.schemas import Dataset
from jsbsim_calib.core.errors import DataError, InputError
from jsbsim_calib.evaluation.evaluate import PointResult, evaluate_dataset, summarize
from jsbsim_calib.core.executor import ProcessExecutor
from jsbsim_calib.factors import FactorSet
from jsbsim_calib.flight.condition import Condition
from jsbsim_calib.jsbsim.product import load_aircraft_geometry
from jsbsim_calib.jsbsim.simulator import Simulator
from jsbsim_calib.evaluation.physics_checks import OSWALD_RANGE, PROPELLER_PEAK_RANGE, run_physics_checks
from jsbsim_calib.evaluation.weight_estimate import estimate_weight, with_weight_offset

REPO = Path(__file__).resolve().parents[1]
LOG = REPO / "data" / "g1000" / "log_110812_095915_KCKN.csv"
FAST_NFEV = 20               # the tests' refits: a few iterations (the command's default is 60)


# --------------------------------------------------------------------------- folds (data only)
def test_folds_group_what_a_user_varies():
    c172 = stage_data(REPO, "c172", ("poh_climb", "poh_cruise"))
    names = [f.name for f in climb_folds(c172["poh_climb"])]
    assert names[:4] == ["climb OAT -20 C", "climb OAT 0 C", "climb OAT 20 C", "climb OAT 40 C"]
    bands = [f for f in climb_folds(c172["poh_climb"]) if f.grouping == "climb altitude band"]
    assert len(bands) == 3 and sorted(i for f in bands for i in f.rows["poh_climb"]) == list(range(27))
    assert [f.name for f in cruise_folds(c172["poh_cruise"])] == [f"cruise {a:,} ft" for a in range(2000, 12001, 2000)]
    sr20 = stage_data(REPO, "sr20", ("poh_climb", "poh_cruise"))
    assert all(f.grouping == "climb altitude band" for f in climb_folds(sr20["poh_climb"]))   # ISA only
    folds = {f.name: f for f in trims_folds(stage_data(REPO, "c172", ("snapshot", "flap_climb")))}
    assert set(folds) == {"flaps 0", "flaps 10", "flaps 20", "flaps 30", "climbs", "cruise trims", "turns", "pulse ICs"}
    assert folds["flaps 10"].rows["flap_climb"] == (0, 1, 2) and folds["climbs"].rows["flap_climb"] == (0, 1, 2)
    assert len(folds["turns"].rows["snapshot"]) == 1                      # C.59, 45 deg bank
    assert snapshot_test_type("2.b.2/2.b.5 Roll Control / Small Control Inputs - Roll (Cruise Case)") == "pulse"
    assert snapshot_test_type("2.c.5 Longitudinal Trim (Clean Configuration Case)") == "cruise"
    assert snapshot_test_type("anything", bank_deg=30.0) == "turn"


def test_stage_factors_are_the_stages_own():
    """Stage 2a's factors from the record reproduce stage 2a's own accuracy (before stage 2b)."""
    import json
    rec = json.loads((REPO / "aircraft" / "c172" / "calibration.json").read_text())["stages"]
    f1, f2 = stage_factors(REPO, "c172", "steady"), stage_factors(REPO, "c172", "trims")
    neutral = FactorSet()
    assert f1["K_HP"] == rec["steady"]["fit"]["factors"]["K_HP"]["final"] and f1["K_PF"] == neutral["K_PF"]
    assert f2["K_PF"] == rec["trims"]["steps"][-1]["factors"]["K_PF"]["final"] and f2["K_Clp"] == neutral["K_Clp"]
    snap = stage_data(REPO, "c172", ("snapshot",))["snapshot"]
    with Simulator(REPO, "c172", factors=f2) as sim:
        s = evaluate_dataset(sim, snap).summary()
    for m, want in rec["trims"]["flight_test"]["steady refit"]["snapshot"].items():
        assert s[m].rmse == pytest.approx(want["rmse"], abs=1e-6)


def test_stage_factors_keep_the_model_switches_the_aircraft_file_sets(tmp_path):
    """A fold refits around the switches the stage was fitted with: a slipstream switched on by
    hand in the aircraft file stays on in every fold (it was dropped, and the folds then judged
    another model than the stage's)."""
    import shutil
    root = tmp_path / "root"
    for d in ("aircraft", "engine", "airfoils", "data"):
        shutil.copytree(REPO / d, root / d, ignore=shutil.ignore_patterns("backup"))
    xml = root / "aircraft" / "c172" / "c172.xml"
    off = '<property value="0" persistent="true"> calibration/K_slip </property>'
    assert off in xml.read_text()
    xml.write_text(xml.read_text().replace(off, off.replace('value="0"', 'value="1"')))
    assert stage_factors(root, "c172", "steady")["K_slip"] == stage_factors(root, "c172", "trims")["K_slip"] == 1.0
    assert stage_factors(REPO, "c172", "steady")["K_slip"] == 0.0
    assert stage_factors(REPO, "c172", "trims")["K_swirl"] == 1.0          # the product's own switch


# --------------------------------------------------------------------------- NaN never passes
def _metric(fit: float, held: float, failed: int = 0, n: int = 3) -> FoldMetric:
    return FoldMetric("f", "g", "poh_climb", "roc_fpm", "ft/min", ErrorStat(n, fit, 100.0, 0),
                      ErrorStat(n, held, math.nan if math.isnan(held) else 100.0, failed), ErrorStat(n, 1.0, 100.0, 0),
                      100.0)


def test_nan_never_passes_a_within_check():
    assert not _metric(20.0, 29.9).flagged and _metric(20.0, 30.1).flagged
    assert _metric(20.0, 29.9).ratio == pytest.approx(1.495)
    for m in (_metric(10.0, math.nan), _metric(math.nan, 5.0), _metric(math.nan, math.nan)):
        assert math.isnan(m.ratio) and m.flagged and m.flag_reason
    assert _metric(10.0, 5.0, failed=1).flagged                      # a failed held-out trim is flagged
    assert _metric(0.0, 20.0).flagged and not _metric(0.0, 0.0).flagged
    # below a tenth of the tolerance (10 fpm) no ratio is material: a governed RPM off by 0.01 vs 0.001
    assert _metric(1.0, 9.0).ratio == 9.0 and not _metric(1.0, 9.0).flagged
    assert not ErrorStat(0, math.nan, math.nan, 0).all_within and not ErrorStat(3, 1.0, math.nan, 0).all_within
    # a failed trim counts as outside tolerance; its NaN never enters the RMSE
    pts = [PointResult(0, {"roc_fpm": 500.0}, {"roc_fpm": 510.0}, {"roc_fpm": 10.0}, {"roc_fpm": True}, True),
           PointResult(1, {"roc_fpm": 500.0}, {"roc_fpm": math.nan}, {"roc_fpm": math.nan}, {"roc_fpm": False}, False)]
    s = ErrorStat.of(summarize(pts, ["roc_fpm"])["roc_fpm"])
    assert s.within_pct == 50.0 and s.rmse == 10.0 and s.failed == 1 and not s.all_within


# --------------------------------------------------------------------------- refits (real JSBSim)
def _finite(s: ErrorStat) -> bool:
    return s.n > 0 and math.isfinite(s.rmse) and math.isfinite(s.within_pct)


@pytest.mark.slow
def test_stage1_folds_refit_and_report_finite_numbers():
    v = validate_steady(REPO, "c172", folds=["climb OAT 40 C", "cruise 12,000 ft"], max_nfev=FAST_NFEV,
                        control=False)
    assert [f.fold.name for f in v.folds] == ["climb OAT 40 C", "cruise 12,000 ft"] and v.stage == "steady"
    start = stage_factors(REPO, "c172", "steady")
    for fr in v.folds:
        assert fr.refitted == ("steady", "fuel flow") and fr.trims > 0
        assert any(fr.factors[k] != start[k] for k in ("K_cd0_offset", "K_HP", "K_CT_scale", "K_cdi"))
        for m in fr.metrics:
            assert _finite(m.fit) and _finite(m.held_out) and _finite(m.in_sample) and math.isfinite(m.ratio)
            assert m.flagged == (m.ratio > FLAG_RATIO or m.held_out.failed > 0)
    climb = v.folds[0].metrics
    assert [(m.kind, m.metric, m.held_out.n, m.fit.n) for m in climb] == [("poh_climb", "roc_fpm", 6, 21)]
    assert {m.metric for m in v.folds[1].metrics} == {"rpm", "pct_power", "gph"}
    assert v.to_json()["folds"][0]["metrics"][0]["held_out"]["n"] == 6


@pytest.mark.slow
def test_folds_are_independent_tasks_with_the_same_bits_on_a_pool():
    """The folds run as independent tasks (each from the stage model's warm starts): on a pool of
    two workers they give this process's factors and errors bit for bit, in the folds' order."""
    folds = ["climb OAT 40 C", "cruise 12,000 ft"]
    here = validate_steady(REPO, "c172", folds=folds, max_nfev=5)
    with ProcessExecutor(2) as pool:
        there = validate_steady(REPO, "c172", folds=folds, max_nfev=5, executor=pool)
    assert [f.fold.name for f in there.folds] == folds and there.control is not None
    for a, b in zip([here.control] + here.folds, [there.control] + there.folds):
        assert a.factors == b.factors and a.trims == b.trims
        assert [(m.fit.rmse, m.held_out.rmse) for m in a.metrics] == [(m.fit.rmse, m.held_out.rmse) for m in b.metrics]
    assert here.trims == there.trims


@pytest.mark.slow
def test_stage2a_flap_folds_refit_only_the_steps_that_use_them():
    v = validate_trims(REPO, "c172", folds=["flaps 20", "flaps 30"], max_nfev=FAST_NFEV, control=False)
    for fr in v.folds:
        # the flaps-down snapshots enter the control, P-factor and flap steps and the joint refit
        # (every snapshot), not the pitch step (flaps-up pitch)
        assert fr.refitted == ("control", "pfactor", "flaps", "steady refit")
        assert {(m.kind, m.metric) for m in fr.metrics} == {("snapshot", x) for x in
                                                           ("pitch_deg", "elevator_deg", "aileron_deg", "rudder_deg")}
        for m in fr.metrics:
            assert _finite(m.fit) and m.held_out.n == fr.fold.size and _finite(m.in_sample)
            assert m.held_out.failed == len(fr.failures)
            if m.held_out.failed:                       # a failed held-out trim never passes
                assert m.flagged and not m.held_out.all_within
            else:
                assert math.isfinite(m.held_out.rmse)


@pytest.mark.slow
def test_validate_cli_writes_the_report_and_its_figure(tmp_path):
    r = subprocess.run([sys.executable, "-m", "jsbsim_calib.cli", "--root", str(REPO), "--quiet", "validate", "c172",
                        "--stage", "trims", "--fold", "turns", "--max-nfev", "5", "--no-physics", "--report-dir",
                        str(tmp_path)], capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr
    assert "turns" in r.stdout and "held-out" in r.stdout and "validation wall time" in r.stdout
    md = (tmp_path / "c172" / "validation.md").read_text()
    assert "| turns | test type |" in md and "none (control)" in md
    assert (tmp_path / "c172" / "validation.png").stat().st_size > 10_000
    bad = subprocess.run([sys.executable, "-m", "jsbsim_calib.cli", "--root", str(REPO), "validate", "c172",
                          "--fold", "no such fold"], capture_output=True, text=True, timeout=120)
    assert bad.returncode == 2 and "unknown fold" in bad.stderr


# --------------------------------------------------------------------------- stage 2b
def test_stage2b_folds_are_the_tests_with_an_amplitude_free_tolerance():
    from jsbsim_calib.calibration.validation_dynamic import dynamic_fold_names
    assert dynamic_fold_names(REPO, "c172") == ["C.12 engine acceleration", "C.56 phugoid", "C.58 roll step",
                                                 "C.60 roll step"]


def test_a_dynamic_error_that_is_not_a_number_never_passes():
    from jsbsim_calib.calibration.validation_dynamic import Judged, error_stat
    s = error_stat([Judged("C.58", "roll_rate_deg_s", "deg/s", math.nan, 2.0),
                    Judged("C.60", "roll_rate_deg_s", "deg/s", 1.0, 2.0)])
    assert s.failed == 1 and s.within_pct == 50.0 and s.rmse == 1.0
    assert math.isnan(error_stat([Judged("C.58", "roll_rate_deg_s", "deg/s", math.nan, 2.0)]).rmse)


@pytest.mark.slow
def test_stage2b_left_out_roll_step_is_flown_on_a_refit_without_it():
    """C.58 left out: the roll axis refitted on C.60 and the pulses (real fits, a few
    evaluations), then C.58 flown. The two roll steps disagree (pb/2V 0.030 vs 0.041, README):
    a fit to one misses the other by far more than the tolerance: the report flags it."""
    from jsbsim_calib.calibration.validation_dynamic import validate_dynamic
    val = validate_dynamic(REPO, "c172", folds=["C.58 roll step"], max_nfev=4, control=False)
    (fold,) = val.folds
    assert "roll dynamics" in fold.refitted and "pitch dynamics" not in fold.refitted
    (m,) = fold.metrics
    assert m.metric == "roll_rate_deg_s" and m.fit.n == 1 and m.held_out.n == 1 and m.tolerance == 2.0
    assert all(math.isfinite(x) for x in (m.fit.rmse, m.held_out.rmse, m.in_sample.rmse))
    assert m.held_out.rmse > 2 * m.tolerance and m.fit.rmse < m.tolerance and m.flagged
    assert val.in_sample["dynamic"]["phugoid_period_s"].within_pct == 100.0


# --------------------------------------------------------------------------- physics checks
@pytest.fixture(scope="module")
def physics():
    return {n: run_physics_checks(REPO, n, stage_data(REPO, n, ("poh_climb", "poh_cruise"))) for n in ("c172", "sr20")}


def test_the_physics_checks_are_printed_and_written(physics, tmp_path):
    """The validation report's physics section (fast: no refit; the command's own test flies folds)."""
    from jsbsim_calib.report.validation_report import format_physics, write_validation_report
    text = format_physics(physics["c172"])
    assert text.startswith("c172: physics checks") and len(text.splitlines()) == 1 + len(physics["c172"].checks()) + len(physics["c172"].notes)
    md = write_validation_report("c172", [], physics["c172"], tmp_path, "jsbsim-calib validate c172").read_text()
    assert "jsbsim-calib validate c172" in md and "## Physics checks" in md


@pytest.mark.parametrize("name", ["c172", "sr20"])
def test_lighter_climbs_better_as_the_classic_estimate_says(physics, name):
    ws = physics[name].weight
    assert len(ws) == 3
    for w in ws:
        assert w.model_droc_dw_fpm_per_lb < 0 and w.classic_droc_dw_fpm_per_lb < 0
        # measured 1.04-1.06: the model's trend is the classic -ROC/W - 2 D_i V/W^2
        assert 0.8 < w.ratio < 1.25
        assert -1.0 < w.model_droc_dw_fpm_per_lb < -0.2          # fpm per lb: a few hundred fpm per 500 lb
    assert math.isnan(physics[name].poh_droc_dw_fpm_per_lb)      # the POH data give one weight


@pytest.mark.parametrize("name", ["c172", "sr20"])
def test_span_efficiency_of_the_drag_polar(physics, name):
    po = physics[name].polar
    assert len(po.points) >= 6 and po.cd0 > 0
    assert OSWALD_RANGE[0] <= po.oswald_efficiency <= OSWALD_RANGE[1]


@pytest.mark.parametrize("name", [
    pytest.param("c172", marks=pytest.mark.xfail(strict=True, reason=(
        "measured: the calibrated C172 propeller peaks at 0.664 (J 0.60, below the cruise J 0.66-0.74); "
        "the uncalibrated BEM table peaks at 0.84 at J 0.75. Stage 1 lowered the propeller efficiency and the "
        "drag together (the POH fixes their balance, not each): README, Held-out validation"))),
    "sr20"])
def test_propeller_efficiency_peaks_in_the_cruise_range(physics, name):
    pr = physics[name].propeller
    assert PROPELLER_PEAK_RANGE[0] <= pr.peak_efficiency <= PROPELLER_PEAK_RANGE[1]
    assert pr.peak_in_cruise_range


def test_the_uncalibrated_propellers_pass_the_propeller_check(physics):
    for name in ("c172", "sr20"):
        pr = physics[name].propeller
        assert PROPELLER_PEAK_RANGE[0] <= pr.neutral_peak_efficiency <= PROPELLER_PEAK_RANGE[1]
        assert all(0.4 < p.efficiency < 0.9 and 0.3 < p.advance_ratio < 1.2 for p in pr.points)


# --------------------------------------------------------------------------- G1000 loading
@pytest.fixture(scope="module")
def c172_geometry():
    return load_aircraft_geometry(REPO, "c172")


def test_log_loading_changes_the_weight_as_documented(c172_geometry):
    base = log_dataset(LOG, c172_geometry)
    assert base.frame.equals(log_dataset(LOG, c172_geometry, LogLoading()).frame)     # defaults as before
    heavy = log_dataset(LOG, c172_geometry, LogLoading(occupants_lb=440.0, baggage_lb=50.0,
                                                       fuel_density_lb_per_gal=6.5, cg_in=44.0))
    fuel = base.extra["table"]["fuel_gal"].to_numpy(float)
    expected = base.frame["weight_lb"].to_numpy(float) + 100.0 + 50.0 + 0.5 * fuel
    assert np.allclose(heavy.frame["weight_lb"].to_numpy(float), expected)
    assert {c.cg_in for c in log_conditions(heavy, c172_geometry)} == {44.0}
    assert {c.cg_in for c in log_conditions(base, c172_geometry)} == {None}
    assert "(given)" in heavy.extra["weight_note"] and "CG 44 in" in heavy.extra["weight_note"]


@pytest.mark.parametrize("field,value", [("occupants_lb", -10.0), ("occupants_lb", math.nan), ("occupants_lb", 1e6),
                                         ("baggage_lb", -1.0), ("fuel_density_lb_per_gal", math.inf),
                                         ("fuel_density_lb_per_gal", 0.0), ("cg_in", math.nan), ("cg_in", -40.0)])
def test_an_invalid_loading_is_refused(field, value):
    with pytest.raises(InputError, match=field):
        LogLoading(**{field: value})


def test_a_loading_the_aircraft_cannot_have_is_refused(c172_geometry):
    with pytest.raises(InputError, match="CG envelope"):
        log_dataset(LOG, c172_geometry, LogLoading(cg_in=30.0))
    with pytest.raises(InputError, match="maximum weight"):
        log_dataset(LOG, c172_geometry, LogLoading(occupants_lb=1400.0, baggage_lb=900.0))


def test_evaluate_cli_refuses_a_bad_loading_with_a_clear_error():
    r = subprocess.run([sys.executable, "-m", "jsbsim_calib.cli", "--root", str(REPO), "evaluate", "c172", "--data",
                        str(LOG), "--occupants-lb", "-5"], capture_output=True, text=True, timeout=120)
    assert r.returncode == 2 and "occupants_lb: -5 is outside the plausible range" in r.stderr


# --------------------------------------------------------------------------- weight estimate
def test_weight_estimate_on_the_real_log(c172_geometry):
    with Simulator(REPO, "c172") as sim:
        ds = log_dataset(LOG, sim.geometry)
        est = estimate_weight(sim, ds)
        used = with_weight_offset(ds, est)
    # measured: 2414 +/- 56 lb (assumed 2210): the slow level segments need more power than the assumed
    # loading gives; with it the logged climbs (not used by the estimate) fall from 156 to 47 fpm RMSE
    assert est.method == "rpm" and len(est.segments) == 6
    assert math.isfinite(est.weight_lb) and 1900.0 <= est.weight_lb <= 2550.0
    assert math.isfinite(est.stderr_lb) and 0.0 < est.stderr_lb < 200.0
    assert np.allclose(used.frame["weight_lb"] - ds.frame["weight_lb"], est.offset_lb)


def _synthetic_log(sim: Simulator, offset_lb: float, tmp: Path, noise_rpm: float = 3.0) -> Dataset:
    """A small 'log' of level segments whose RPM and pitch are the model's own trims at the segments'
    weight + ``offset_lb`` (plus a little seeded RPM noise); weight_lb holds the assumption."""
    rng = np.random.default_rng(0)
    rows = [(3000.0, 10.0, 85.0, 2150.0), (3000.0, 10.0, 100.0, 2140.0), (5500.0, 5.0, 92.0, 2130.0),
            (5500.0, 5.0, 110.0, 2120.0), (3000.0, 10.0, 118.0, 2110.0)]
    recs = []
    for k, (hp, oat, ktas, w) in enumerate(rows, 1):
        t = sim.trim_level(Condition(pressure_alt_ft=hp, weight_lb=w + offset_lb, ktas=ktas, oat_c=oat))
        assert t.trimmed, t.reason
        recs.append({"segment": k, "kind": "cruise", "pressure_alt_ft": hp, "oat_c": oat, "ktas": ktas, "kcas": np.nan,
                     "vs_fpm": 0.0, "weight_lb": w, "flaps_deg": 0.0,
                     "rpm": log_value("rpm", t) + noise_rpm * rng.standard_normal(),
                     "roc_fpm": np.nan, "pitch_deg": log_value("pitch_deg", t)})
    return Dataset("g1000", tmp / "synthetic_log.csv", pd.DataFrame(recs), pd.DataFrame(),
                   ("rpm", "roc_fpm", "pitch_deg"), extra={"cg_in": None})


def test_weight_estimate_recovers_a_known_weight(tmp_path):
    with Simulator(REPO, "c172") as sim:
        syn = _synthetic_log(sim, -180.0, tmp_path)
        est = estimate_weight(sim, syn)
        exact = estimate_weight(sim, replace(syn, frame=_synthetic_log(sim, -180.0, tmp_path, 0.0).frame))
    truth = float(np.mean(syn.frame["weight_lb"])) - 180.0
    assert abs(est.weight_lb - truth) <= 50.0 and est.stderr_lb < 50.0
    assert abs(exact.weight_lb - truth) <= 1.0
    with pytest.raises(DataError, match="G1000 log"):
        with Simulator(REPO, "c172") as sim:
            estimate_weight(sim, stage_data(REPO, "c172", ("poh_climb",))["poh_climb"])
