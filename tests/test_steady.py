"""Stage 1: data validation, the evaluate JSON schema, factor recovery on synthetic POH data."""
import json
import subprocess
import sys

import numpy as np
import pytest

from jsbsim_calib.calibration.fit import fit
from jsbsim_calib.calibration.points import PointSet, point_residuals
from jsbsim_calib.core.errors import DataError
from jsbsim_calib.data.load import load_dataset
from jsbsim_calib.factors import FactorSet
from jsbsim_calib.jsbsim.simulator import Simulator


# --------------------------------------------------------------------------- data validation
def _write(tmp_path, text, name="poh.csv"):
    p = tmp_path / name
    p.write_text(text)
    return p


CLIMB = "oat_c,pressure_alt_ft,kias,weight_lb,flaps_deg,roc_fpm\n0,0,74,2550,0,785\n0,2000,73,2550,0,695\n"


def test_climb_loads_and_extra_columns_are_ignored(tmp_path):
    ds = load_dataset(_write(tmp_path, CLIMB.replace("roc_fpm\n", "roc_fpm,comment\n")
                             .replace("785\n", "785,x\n").replace("695\n", "695,y\n")))
    assert ds.kind == "poh_climb" and ds.metrics == ("roc_fpm",) and len(ds) == 2
    assert "comment" not in ds.frame


@pytest.mark.parametrize("text, where, what", [
    (CLIMB.replace(",kias", ",speed"), "column 'kias'", "missing"),
    (CLIMB.replace("0,2000,73,", "0,2000,,"), "line 3 (row 2), column 'kias'", "empty"),
    (CLIMB.replace("785", "fast"), "line 2 (row 1), column 'roc_fpm'", "not a number"),
    (CLIMB.replace("2550,0,695", "-2550,0,695"), "line 3 (row 2), column 'weight_lb'", "outside"),
])
def test_bad_data_names_file_row_and_column(tmp_path, text, where, what):
    p = _write(tmp_path, text)
    with pytest.raises(DataError) as exc:
        load_dataset(p)
    msg = str(exc.value)
    assert str(p) in msg and where in msg and what in msg, msg


def test_every_problem_is_reported_at_once(tmp_path):
    p = _write(tmp_path, CLIMB.replace("785", "x").replace("2000,73", "2000,999"))
    with pytest.raises(DataError) as exc:
        load_dataset(p)
    assert len(exc.value.problems) == 2


def test_isa_marker_means_standard_temperature(repo):
    ds = load_dataset(repo / "data" / "sr20_poh_climb.csv")
    assert "oat_c" not in ds.frame and (ds.frame["temp_dev_c"] == 0).all()


# --------------------------------------------------------------------------- evaluate JSON
def test_evaluate_cli_writes_the_documented_json(repo, tmp_path):
    out = tmp_path / "ev.json"
    r = subprocess.run([sys.executable, "-m", "jsbsim_calib.cli", "--root", str(repo), "evaluate", "c172",
                        "--data", str(repo / "data" / "c172_poh_cruise.csv"), "--json", str(out), "--report-dir", str(tmp_path)],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    d = json.loads(out.read_text())
    assert d["aircraft"] == "c172" and d["model"] == "calibrated"
    assert len(d["points"]) == 37
    p = d["points"][0]
    for col in ("pressure_alt_ft", "ktas", "weight_lb", "rpm", "pct_power", "gph"):
        assert col in p
    assert set(p["model"]) == set(p["error"]) == set(p["within"]) == {"rpm", "pct_power", "gph"}
    assert isinstance(p["trimmed"], bool)
    assert set(d["summary"]) == {"rpm", "pct_power", "gph"}
    for s in d["summary"].values():
        assert set(s) == {"n", "rmse", "mape", "nmbe", "within_pct", "failed"}
    assert p["error"]["rpm"] == pytest.approx(p["model"]["rpm"] - p["rpm"])
    assert "RMSE" in r.stdout


def test_baseline_flag_evaluates_the_uncalibrated_model(repo, tmp_path):
    out = tmp_path / "ev.json"
    r = subprocess.run([sys.executable, "-m", "jsbsim_calib.cli", "--root", str(repo), "evaluate", "c172",
                        "--data", str(repo / "data" / "c172_poh_climb.csv"), "--baseline", "--json", str(out), "--report-dir", str(tmp_path)],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    d = json.loads(out.read_text())
    assert d["model"] == "baseline" and d["summary"]["roc_fpm"]["rmse"] > 100.0


# --------------------------------------------------------------------------- factor recovery
TRUTH = {"K_cd0_slope": 1.12, "K_cdi": 1.08, "K_CT_scale": 0.95, "K_CQ_scale": 1.06, "K_HP": 1.03, "K_FF": 1.07}


@pytest.mark.slow
def test_steady_fit_recovers_known_factors_from_synthetic_poh(repo, tmp_path, synthetic_poh):
    """POH-like targets made by the model with known factors are fitted back from neutral."""
    sim = Simulator(repo, "c172", baseline=True)
    climb = load_dataset(repo / "data" / "c172_poh_climb.csv")
    cruise = load_dataset(repo / "data" / "c172_poh_cruise.csv")
    truth = FactorSet(TRUTH)
    sim.set_factors(truth)
    synth = {}
    for ds, idx in ((climb, [0, 3, 6, 9, 14, 17, 20, 22, 26]), (cruise, [0, 5, 8, 13, 18, 21, 24, 29, 34, 36])):
        synth[ds.kind] = synthetic_poh(sim, ds, idx, tmp_path / f"{ds.kind}.csv")
    sim.set_factors(FactorSet())
    cps = PointSet.from_dataset(synth["poh_climb"], sim)
    kps = PointSet.from_dataset(synth["poh_cruise"], sim)
    names = [n for n in TRUTH if n != "K_FF"]

    def residuals(fs):
        sim.set_factors(fs)
        r1, l1, _ = point_residuals(sim, cps, ("roc_fpm",))
        r2, l2, _ = point_residuals(sim, kps, ("pct_power", "rpm"))
        return np.array(r1 + r2), l1 + l2

    res = fit("recovery", names, FactorSet(), residuals, sim=sim, prior=0.0, ftol=1e-10)
    for n in names:
        assert res.final[n] == pytest.approx(TRUTH[n], abs=0.01), (n, res.final[n])
    assert res.cost_final < 1e-3

    def ff(fs):
        sim.set_factors(fs)
        r, l, _ = point_residuals(sim, kps, ("gph",))
        return np.array(r), l

    res2 = fit("fuel flow", ["K_FF"], res.final, ff, sim=sim, prior=0.0)
    assert res2.final["K_FF"] == pytest.approx(TRUTH["K_FF"], abs=0.002)
    sim.close()
