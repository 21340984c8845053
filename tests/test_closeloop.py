"""Closing the loop with real JSBSim: synthetic truths with undeclared effects, the null
case, an effect outside the library, and the real C172 flight-test trims.

A truth aircraft is the committed calibrated C172 with an effect written into its XML (the
effect files' own XML, or a hand-written function for the outside-library case); its
snapshots come from ``synth`` with measurement noise; the clean C172 is then diagnosed.
"""
from __future__ import annotations

import json
import shutil
import subprocess
import sys
import warnings
from pathlib import Path

import jsbsim
import numpy as np
import pytest
from lxml import etree

from jsbsim_calib.jsbsim import xml
from jsbsim_calib.calibration.closeloop import close_loop
from jsbsim_calib.calibration.loop import write_aircraft
from jsbsim_calib.data.load import load_dataset
from jsbsim_calib.calibration.effects import library
from jsbsim_calib.flight.condition import Condition
from jsbsim_calib.core.errors import ModelError
from jsbsim_calib.factors import REGISTRY
from jsbsim_calib.jsbsim.aircraft import add_effect, added_xml, effect_constants, moment_of_inertia, set_moment_of_inertia
from jsbsim_calib.jsbsim.simulator import Simulator
from jsbsim_calib.data.flighttest import QuirkWarning
from jsbsim_calib.synthetic.snapshots import synthesize, write_csv

REPO = Path(__file__).resolve().parents[1]
TRAVEL = REPO / "data" / "c172_control_travel.csv"
SNAPSHOT_METRICS = ("pitch_deg", "elevator_deg", "aileron_deg", "rudder_deg")


def make_truth(tmp_path: Path, effects: dict[str, dict[str, float]], extra_roll_xml: str | None = None) -> Path:
    """aircraft folder: the committed C172 with effects (name -> {factor: value}) in its XML."""
    d = tmp_path / "truth" / "c172"
    shutil.copytree(REPO / "aircraft" / "c172", d)
    lib = library()
    with Simulator(REPO, "c172") as s:
        for name, vals in effects.items():
            e = lib[name]
            s.add_effect(e, {f.property: vals[f.name] for f in e.factors if f.name in vals})
        tree = s.aircraft_tree()
    if extra_roll_xml:
        tree.getroot().find("aerodynamics/axis[@name='ROLL']").append(etree.fromstring(extra_roll_xml))
    xml.write(tree, d / "c172.xml")
    return d


def snapshots(tmp_path: Path, truth_dir: Path, seed: int, n: int = 48):
    with Simulator.from_dir(truth_dir, REPO) as truth:
        rows, _ = synthesize(truth, n=n, seed=seed)
    path = tmp_path / "synth.csv"
    write_csv(rows, path)
    with warnings.catch_warnings():
        warnings.simplefilter("error", QuirkWarning)         # synthetic data has no quirks
        return load_dataset(path, control_travel=TRAVEL)


@pytest.fixture(scope="module")
def clean():
    sim = Simulator(REPO, "c172")
    yield sim
    sim.close()


def _first(res, rnd: int = 1):
    return min((c for c in res.candidates if c.round == rnd), key=lambda c: c.delta_bic)


def _within(res) -> dict[str, float]:
    return {m: s.within_pct for m, s in res.summaries("all").after.items()}


# --------------------------------------------------------------------------- library and synth
def test_every_library_effect_loads_flies_and_moves_what_it_says(clean):
    cond = Condition(4000.0, 2400.0, ktas=85.0, mode="level", vs_fpm=500.0, flaps_deg=10.0, mixture="climb")
    base = clean.trim(cond)
    moved = {}
    for name, e in library().items():
        assert e.factors and all(f.property.startswith("calibration/effects/") for f in e.factors), name
        trial = clean.clone()
        vals = {f.property: f.lower + 0.75 * (f.upper - f.lower) for f in e.factors}
        trial.add_effect(e, vals)
        t = trial.trim(cond)
        assert t.trimmed, (name, t.reason)
        moved[name] = {m: abs(getattr(t, a) - getattr(base, a)) for m, a in
                       (("pitch_deg", "theta_deg"), ("elevator_deg", "elevator_deg"), ("aileron_deg", "aileron_deg"),
                        ("rudder_deg", "rudder_deg"))}
        trial.close()
    for name, e in library().items():
        if name == "ground_effect":                    # nothing at altitude: by design
            assert max(moved[name].values()) < 1e-6
            continue
        assert max(moved[name][m] for m in e.affects) > 0.05, (name, moved[name])


def test_synth_cli_is_deterministic_and_writes_the_snapshot_schema(tmp_path):
    outs = []
    for k in range(2):
        out = tmp_path / f"s{k}.csv"
        r = subprocess.run([sys.executable, "-m", "jsbsim_calib.cli", "--root", str(REPO), "synth", "--truth",
                            str(REPO / "aircraft" / "c172"), "--out", str(out), "--seed", "5", "--points", "24"],
                           capture_output=True, text=True, timeout=300)
        assert r.returncode == 0, r.stderr
        outs.append(out.read_bytes())
    assert outs[0] == outs[1]
    ds = load_dataset(tmp_path / "s0.csv", control_travel=TRAVEL)
    assert ds.kind == "snapshot" and len(ds) >= 22 and not ds.extra["quirks"]
    assert {"climb", "cruise", "flaps", "turn"} <= {t.split()[0].replace("full-power", "climb").replace("level", "cruise")
                                                   .replace("steady", "turn") for t in
                                                   __import__("pandas").read_csv(tmp_path / "s0.csv")["title"]}


# --------------------------------------------------------------------------- undeclared effects
@pytest.mark.parametrize("effect, values, seed", [
    ("thrust_line_offset", {"K": 1.5}, 12),
    ("control_rigging_offset_aileron", {"K": 1.2}, 13),
    ("engine_torque_roll", {"K": 1.5}, 11),
])
@pytest.mark.slow
def test_an_undeclared_library_effect_is_found_first_and_closes_the_residual(tmp_path, clean, effect, values, seed):
    ds = snapshots(tmp_path, make_truth(tmp_path, {effect: values}), seed)
    res = close_loop(clean, ds)
    assert _first(res).effect == effect
    assert res.added[0] == effect and len(res.added) == 1, res.added
    affected = library()[effect].affects
    before = res.summaries("all").before
    assert any(before[m].within_pct < 100.0 or before[m].rmse > 0.3 for m in affected if m in before)
    assert all(v == 100.0 for v in _within(res).values()), _within(res)
    assert not res.unexplained()


def test_the_report_quotes_the_xml_each_change_wrote(clean):
    """A loop's report shows what each change wrote into the aircraft: an effect's system and
    the functions it joined to an aerodynamic axis (named), a refitted factor's declaration, a
    scaled inertia with its note; every quoted element is XML, and a change the aircraft does
    not hold is an error, not an empty block."""
    tree = clean.aircraft_tree()
    effect = library()["p_factor"]
    add_effect(tree, effect, effect_constants(clean.geometry), {effect.factors[0].property: 2.5})
    set_moment_of_inertia(tree, "iyy", 1.5 * moment_of_inertia(tree, "iyy"), "close-loop: iyy x 1.5 (fitted to the data)")
    text = added_xml(tree, "p_factor")
    assert 'name="effect: p_factor"' in text and 'value="2.5"' in text
    assert '<axis name="YAW">' in text and 'name="aero/effects/p_factor-lbsft"' in text
    factor = added_xml(tree, "factor K_Cmq")
    assert factor.startswith("<property") and REGISTRY["K_Cmq"].property in factor
    inertia = added_xml(tree, "inertia iyy")
    assert "close-loop: iyy x 1.5" in inertia and "<iyy unit=" in inertia
    for quoted in (text, factor, inertia):
        etree.fromstring(f"<quoted>{quoted}</quoted>")
    with pytest.raises(ModelError, match="slipstream_tail"):
        added_xml(tree, "slipstream_tail")


@pytest.mark.slow
def test_a_pair_of_undeclared_effects_is_found(tmp_path, clean):
    ds = snapshots(tmp_path, make_truth(tmp_path, {"control_rigging_offset_rudder": {"K": -1.0},
                                                   "cg_offset": {"K": 0.15}}), 16)
    res = close_loop(clean, ds)
    assert _first(res).effect in ("control_rigging_offset_rudder", "cg_offset")
    assert set(res.added) == {"control_rigging_offset_rudder", "cg_offset"}, \
        [(c.effect, c.round, c.reason) for c in res.candidates]
    assert all(v == 100.0 for v in _within(res).values())


@pytest.mark.slow
def test_null_truth_adds_nothing_and_the_cli_writes_json_and_a_loadable_aircraft(tmp_path):
    ds_path = tmp_path / "null.csv"
    with Simulator.from_dir(REPO / "aircraft" / "c172", REPO) as truth:
        rows, _ = synthesize(truth, n=48, seed=21)
    write_csv(rows, ds_path)
    root = tmp_path / "root"
    for d in ("aircraft", "engine", "data", "airfoils"):
        shutil.copytree(REPO / d, root / d)
    out = tmp_path / "null.json"
    r = subprocess.run([sys.executable, "-m", "jsbsim_calib.cli", "--root", str(root), "close-loop", "c172",
                        "--data", str(ds_path), "--json", str(out), "--out", "c172_null",
                        "--report-dir", str(tmp_path / "reports")], capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr
    d = json.loads(out.read_text())
    assert set(d) >= {"before", "candidates", "added", "after", "unexplained"}
    assert d["added"] == [] and d["unexplained"] == []
    assert set(d["before"]) == set(SNAPSHOT_METRICS)
    assert set(d["before"]["pitch_deg"]) == {"n", "rmse", "mape", "nmbe", "within_pct", "failed"}
    assert (tmp_path / "reports" / "c172" / "close-loop.md").is_file()
    fdm = jsbsim.FGFDMExec(str(root))
    fdm.set_debug_level(0)
    assert fdm.load_model("c172_null")


@pytest.mark.slow
def test_an_effect_outside_the_library_is_reported_not_attributed(tmp_path, clean):
    """A rolling moment growing with flap deflection (an asymmetric flap rigging): no library
    effect is attributed (the library alone, ``synthesize=False``; with synthesis the loop builds
    the term: tests/test_synthesis.py)."""
    roll = ("<function name='aero/outside/flap-roll'><product><value>0.0004</value><property>aero/qbar-psf</property>"
            "<property>metrics/Sw-sqft</property><property>metrics/bw-ft</property><property>fcs/flap-pos-deg</property>"
            "</product></function>")
    ds = snapshots(tmp_path, make_truth(tmp_path, {}, roll), 14)
    res = close_loop(clean, ds, synthesize=False)
    assert res.added == [], [(c.effect, c.share, c.reason) for c in res.candidates if c.round == 1]
    un = {u.metric: u.correlates_with for u in res.unexplained()}
    assert "aileron_deg" in un and "flaps" in un["aileron_deg"][:3], un


@pytest.mark.slow
def test_written_aircraft_flies_like_the_closed_loop_model(tmp_path, clean):
    ds = snapshots(tmp_path, make_truth(tmp_path, {"control_rigging_offset_rudder": {"K": -1.0}}), 15, n=24)
    res = close_loop(clean, ds, max_effects=1)
    assert res.added == ["control_rigging_offset_rudder"]
    root = tmp_path / "root"
    for d in ("aircraft", "engine", "data", "airfoils"):
        shutil.copytree(REPO / d, root / d)
    path = write_aircraft(res, root, "c172_rig")
    assert "effect: control_rigging_offset_rudder" in path.read_text()
    cond = Condition(5000.0, 2400.0, ktas=105.0, mode="level")
    with Simulator(root, "c172_rig") as again, res.simulator() as loop:
        assert again.effects == ["control_rigging_offset_rudder"]
        a, b = again.trim(cond), loop.trim(cond)
        assert a.rudder_deg == pytest.approx(b.rudder_deg, abs=1e-6)


# --------------------------------------------------------------------------- real data
@pytest.mark.slow
def test_real_c172_trims_without_pfactor_step_find_the_yaw_effect(tmp_path):
    from jsbsim_calib.calibration.workflow import run_close_loop
    res = run_close_loop(REPO, "c172", REPO / "data" / "c172_flight_test_snapshots.csv", skip_steps=("pfactor",))
    s = res.summaries("all")
    assert res.added[:1] == ["p_factor"], [(c.effect, c.round, c.reason) for c in res.candidates]
    # measured with the swirl on and the joint refit on every POH point: rudder RMSE 0.94 -> 0.45 deg,
    # within +-1 deg 75 -> 100 % (0.86 -> 0.44, 75 -> 95 % when it fitted stage 1's 16 POH points)
    # (with it off: 1.42 -> 0.65 deg, 35 -> 85 %)
    assert s.before["rudder_deg"].rmse > 0.75 and s.after["rudder_deg"].rmse < 0.55
    assert s.after["rudder_deg"].within_pct >= 90.0
    assert s.after["aileron_deg"].within_pct == 100.0


# --------------------------------------------------------------------------- NaN never passes
def test_no_evidence_test_accepts_a_nan():
    """Each evidence test of the close-loop, fed a NaN in any of its quantities, refuses; a
    metric whose noise could not be estimated weighs with its tolerance, not with NaN."""
    from jsbsim_calib.calibration.closeloop import noise_in_tolerances
    from jsbsim_calib.calibration.loop import MIN_EVIDENCE, evidence_failures, pays_off_out_of_sample
    from jsbsim_calib.calibration.diagnose import MetricDiagnosis
    nan = float("nan")
    passing = dict(delta_bic=-2 * MIN_EVIDENCE, material=1.0, structure=1.0, share=0.9)
    assert evidence_failures(**passing) == []
    for k in passing:
        assert evidence_failures(**{**passing, k: nan}), f"a NaN {k} passed the evidence tests"
    assert pays_off_out_of_sample(1.0, 0.5)
    assert not pays_off_out_of_sample(nan, 0.5) and not pays_off_out_of_sample(1.0, nan)
    d = MetricDiagnosis("roc_fpm", 2, 10.0, 5.0, nan, 100.0, False, "noise: too few points")
    assert noise_in_tolerances(d) == 1.0
    assert noise_in_tolerances(MetricDiagnosis("roc_fpm", 9, 10.0, 5.0, 20.0, 100.0, True, "")) == 0.2


def test_a_change_that_breaks_the_model_shows_no_evidence_numbers():
    """A change the model cannot fly or trim with (more failure rows than before) is rejected
    for that, and its report cells show no BIC change or share (they would count failures:
    +4e5 next to "explains -300 %" before); a NaN penalty does not pass as "no break"."""
    from jsbsim_calib.calibration.loop import BREAKS, Candidate, Rows, breaks_reason
    rows = lambda res, met: Rows(np.array(res, float), np.array(met), np.full(len(res), np.nan), [""] * len(res))
    flown = rows([0.5, -0.2], ["roll_deg", "roll_deg"])
    broken = rows([0.5, 30.0], ["roll_deg", ""])
    assert breaks_reason(flown, flown) == "" and breaks_reason(broken, flown) == ""
    assert breaks_reason(flown, broken).startswith(BREAKS) and "0 -> 900" in breaks_reason(flown, broken)
    assert breaks_reason(flown, rows([0.5, float("nan")], ["roll_deg", ""])).startswith(BREAKS)   # NaN: a break
    c = Candidate("Cl_beta_x", 1, {}, {}, (1.0, 2.0), None, 2, 4e5, 0.0, share=-3.0,
                  reason=breaks_reason(flown, broken))
    assert c.breaks and c.evidence_cells() == ("-", "-")
    fair = Candidate("Cl_beta_x", 1, {}, {}, (1.0, 0.5), None, 2, -12.34, 0.0, share=0.8)
    assert not fair.breaks and fair.evidence_cells() == ("-12.3", "80 %")
