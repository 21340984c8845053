"""Term synthesis with real JSBSim: truth aircraft with effects outside the library, the null
cases, the written aircraft in JSBSim's runner, and the real trims and G1000 log.

A truth is a copy of the committed C172 with an undeclared term written into an axis of its XML
(:func:`jsbsim_calib.synthetic.truth.truth_copy`); its data are a synthetic campaign flown by it
(:func:`jsbsim_calib.synthetic.snapshots.synthesize`, with measurement noise); the clean C172 then closes the
loop on them. Measured on this machine (the values the comments give) with the committed C172.
"""
from __future__ import annotations

import json
import re
import shutil
import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest

from jsbsim_calib.calibration import synthesis
from jsbsim_calib.calibration.closeloop import close_loop
from jsbsim_calib.calibration.terms import AXES, INTERPRETATIONS, LONGITUDINAL, REGRESSORS, axes_for
from jsbsim_calib.data.flighttest import QuirkWarning
from jsbsim_calib.data.load import load_dataset
from jsbsim_calib.core.errors import ModelError
from jsbsim_calib.flight.condition import Condition
from jsbsim_calib.jsbsim.simulator import Simulator
from jsbsim_calib.jsbsim.xml import read
from jsbsim_calib.report.markdown import write_close_loop_report
from jsbsim_calib.synthetic.truth import (UndeclaredTerm, add_undeclared_term, root_copy, synthetic_rows, truth_copy,
                                  write_climbs, write_snapshots)

REPO = Path(__file__).resolve().parents[1]
TRAVEL = REPO / "data" / "c172_control_travel.csv"


@pytest.fixture(scope="module")
def clean():
    sim = Simulator(REPO, "c172")
    yield sim
    sim.close()


def truth_data(tmp_path: Path, terms=(), effects=None, *, kind: str = "snapshots", n: int = 36, seed: int = 0):
    """A synthetic campaign flown by a truth copy: snapshots, or its full-throttle climbs."""
    truth = truth_copy(REPO / "aircraft" / "c172", tmp_path / "truth" / "c172", terms, effects, root=REPO)
    rows = synthetic_rows(truth, REPO, n=n, seed=seed)
    path = (write_climbs(rows, tmp_path / "climbs.csv") if kind == "climbs"
            else write_snapshots(rows, tmp_path / "snapshots.csv"))
    with warnings.catch_warnings():
        warnings.simplefilter("error", QuirkWarning)         # synthetic data have no quirks
        return load_dataset(path, control_travel=TRAVEL)


# --------------------------------------------------------------------------- the pieces, without JSBSim
def test_dictionary_respects_symmetry_and_every_test_term_has_a_meaning():
    odd = {"beta", "p b/2V", "r b/2V", "aileron", "rudder", "alpha x beta", "beta x flaps", "beta x Tc"}
    for a in LONGITUDINAL:
        regs = {t.regressor for t in synthesis.dictionary([a])}
        assert regs and not regs & odd, (a, regs & odd)
    assert {"p b/2V", "r b/2V", "beta", "flaps", "1", "flaps x Tc"} <= {t.regressor for t in synthesis.dictionary(["YAW"])}
    assert axes_for(["aileron_deg", "rudder_deg"]) == ("ROLL", "YAW") and axes_for(["roc_fpm", "rpm"]) == ("DRAG",)
    for key in (("ROLL", "flaps"), ("PITCH", "flaps x Tc"), ("DRAG", "alpha^2"), ("YAW", "p b/2V")):
        assert key in INTERPRETATIONS and key[1] in REGRESSORS and key[0] in AXES
    with pytest.raises(ModelError):
        synthesis.dictionary(["TORQUE"])


def _linear_problem(structure: float, seed: int = 3):
    rng = np.random.default_rng(seed)
    terms = synthesis.dictionary(["ROLL"])
    n = 40
    J = rng.standard_normal((2 * n, len(terms)))
    r = structure * J[:, 4] + 0.1 * rng.standard_normal(2 * n)
    return synthesis.Linearization(terms, r, -J, np.full(2 * n, 10.0), tuple(str(i // 2) for i in range(2 * n)),
                                   tuple("ab"[i % 2] for i in range(2 * n)))


def test_stlsq_finds_the_sparse_term_and_the_null_test_refuses_noise():
    lin = _linear_problem(0.3)
    sel = synthesis.select(lin)
    assert sel.terms == (lin.terms[4],) and sel.coefficients[0] == pytest.approx(0.3, rel=0.05)
    assert synthesis.null_test(lin, sel) <= 0.01
    noise = _linear_problem(0.0)
    sel0 = synthesis.select(noise)
    assert not sel0.terms or synthesis.null_test(noise, sel0) > 0.01
    assert synthesis.select(lin.subset(range(20))).rows == 40


def test_the_small_supports_are_scored_where_stlsq_jumps_over_them():
    """Correlated columns (a common part): STLSQ's threshold drops from 6 terms to 1 here, so
    the supports of 2 and 3 terms are the forward path's; each size up to MAX_TERMS is scored
    and the sparse truth is kept (the dynamic screen's dictionaries are this correlated:
    on a roll record STLSQ visited no support of 3 terms or fewer and selected nothing)."""
    rng = np.random.default_rng(19)
    terms = synthesis.dictionary(["ROLL"])
    common = rng.standard_normal(200)
    J = 0.9 * common[:, None] + 0.45 * rng.standard_normal((200, len(terms)))
    lin = synthesis.Linearization(terms, 0.3 * J[:, 4] + 0.1 * rng.standard_normal(200), -J, np.full(200, 10.0),
                                  tuple(str(i // 2) for i in range(200)), tuple("ab"[i % 2] for i in range(200)))
    nq, _, _ = synthesis._normal(lin)
    assert not {2, 3} & {len(S) for S in synthesis.stlsq_path(nq, nq.b)}
    sel = synthesis.select(lin)
    assert {1, 2, 3} <= {len(s) for s, _ in sel.path}
    assert sel.terms == (terms[4],) and sel.coefficients[0] == pytest.approx(0.3, rel=0.05)


# --------------------------------------------------------------------------- effects outside the library
# (term, data, points, seed, metric); measured (committed C172, this machine): regressor found,
# metric within tolerance before -> after, fitted coefficient vs truth
CASES = {
    # Cl ~ flaps: aileron 72 % -> 100 %, Cl_flaps 4.115e-4 /deg (truth 4e-4, +3 %)
    "rolling moment in flaps": (UndeclaredTerm("ROLL", 4e-4, "flaps"), "snapshots", 36, 14, "aileron_deg"),
    # Cm ~ flaps x Tc: elevator 83 % -> 100 %, -0.0192 /deg (truth -0.02, -4 %)
    "pitching moment in thrust x flaps": (UndeclaredTerm("PITCH", -0.02, "flaps x Tc"), "snapshots", 36, 15,
                                          "elevator_deg"),
    # CD ~ alpha^2 (climbs at full throttle, roc): roc 84 % -> 100 %, 2.55 /rad2 (truth 2.5, +2 %)
    "drag in alpha^2": (UndeclaredTerm("DRAG", 2.5, "alpha^2"), "climbs", 150, 16, "roc_fpm"),
    # Cn ~ p b/2V (banked turns): rudder 86.7 % -> 100 %, 7.96 (truth 8, -0.4 %), BIC change -76.6; 60 points:
    # with 40 (BIC change -39.8 on the product before the joint refit fitted every POH point) the residual of
    # the fitted 30 fell within the noise estimate on today's product, and nothing was tried
    "yawing moment in roll rate": (UndeclaredTerm("YAW", 8.0, "p b/2V"), "snapshots", 60, 17, "rudder_deg"),
}


@pytest.mark.slow
@pytest.mark.parametrize("case", list(CASES))
def test_an_effect_outside_the_library_is_synthesized_named_and_closes_the_residual(tmp_path, clean, case):
    term, kind, n, seed, metric = CASES[case]
    ds = truth_data(tmp_path, [term], kind=kind, n=n, seed=seed)
    res = close_loop(clean, ds)
    before, after = res.summaries("all").before, res.summaries("all").after
    assert before[metric].within_pct < 95.0, before[metric]
    accepted = [r for r in res.synthesized if r.accepted]
    assert len(accepted) == 1 and res.added == [accepted[0].effect], (res.added, [r.reason for r in res.synthesized])
    [t] = accepted[0].terms
    assert (t["axis"], t["regressor"]) == (term.axis, term.regressor), t
    assert abs(t["final"] - term.coefficient) <= 0.25 * abs(term.coefficient), (t["final"], term.coefficient)
    assert after[metric].within_pct >= 95.0 and all(s.within_pct >= 95.0 for s in after.values()), after
    assert accepted[0].p_null <= 0.01 and accepted[0].cv[1] < accepted[0].cv[0]


# --------------------------------------------------------------------------- null cases
@pytest.mark.slow
def test_a_clean_truth_adds_nothing(tmp_path, clean):
    res = close_loop(clean, truth_data(tmp_path, n=36, seed=21))
    assert res.added == [] and not any(r.accepted for r in res.synthesized)
    assert "synthesized" in res.to_json() and not res.unexplained()


@pytest.mark.slow
def test_a_library_effect_wins_over_a_synthesized_term(tmp_path, clean):
    """Engine torque roll (L = K Q): the dictionary has look-alikes (Cl ~ Tc); the library,
    tried first, explains it, and nothing is synthesized."""
    res = close_loop(clean, truth_data(tmp_path, effects={"engine_torque_roll": {"K": 1.5}}, n=36, seed=11))
    assert res.added == ["engine_torque_roll"], [(c.effect, c.reason) for c in res.candidates]
    assert not any(r.accepted for r in res.synthesized)


# --------------------------------------------------------------------------- the written aircraft, CLI, report
@pytest.mark.slow
def test_cli_writes_the_term_into_an_aircraft_that_jsbsims_runner_flies(tmp_path):
    """close-loop through the command line on the flap-roll truth, written in place into a copy
    of the repository's root: JSON and report name the term; JSBSim's runner flies the repository's
    script with it; the term acts (aileron with flaps 20)."""
    ds = truth_data(tmp_path, [CASES["rolling moment in flaps"][0]], n=36, seed=14)
    root = root_copy(REPO, tmp_path / "root", ("aircraft", "engine", "airfoils", "data", "scripts"))
    out = tmp_path / "loop.json"
    r = subprocess.run([sys.executable, "-m", "jsbsim_calib.cli", "--root", str(root), "--quiet", "close-loop", "c172",
                        "--data", str(ds.path), "--in-place", "--json", str(out), "--report-dir",
                        str(tmp_path / "reports")], capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr[-3000:]
    assert "synthesized, round 1: Cl ~ flaps" in r.stdout and "flap rigging asymmetry" in r.stdout
    d = json.loads(out.read_text())
    assert d["added"] == ["synth_Cl_flaps"]
    [rec] = d["synthesized"]
    assert rec["accepted"] and rec["terms"][0]["regressor"] == "flaps" and rec["selection"]["terms"] == ["Cl_flaps"]
    report = (tmp_path / "reports" / "c172" / "close-loop.md").read_text()
    assert "## Synthesized terms" in report and "flap rigging asymmetry" in report
    text = (root / "aircraft" / "c172" / "c172.xml").read_text()
    assert 'name="aero/effects/synth_Cl_flaps-lbsft"' in text and "synthesized by jsbsim-calib close-loop" in text
    runner = shutil.which("jsbsim", path=str(Path(sys.executable).parent)) or shutil.which("jsbsim")
    fly = subprocess.run([runner, "--root", str(root), "--nohighlight", str(root / "scripts" / "c172_cruise.xml")],
                         capture_output=True, text=True, timeout=300, cwd=tmp_path)
    log = fly.stdout.replace("\0", "") + fly.stderr.replace("\0", "")
    assert fly.returncode == 0 and "Trim successful" in log, log[-2000:]
    alts = [float(v) for v in re.findall(r"altitude \[ft\] = ([-0-9.eE+]+)", log)]
    assert len(alts) >= 6 and all(5000.0 < a < 6000.0 for a in alts)
    cond = Condition(3000.0, 2300.0, ktas=75.0, flaps_deg=20.0, mode="level")
    with Simulator(root, "c172") as sim:
        assert sim.effects == ["synth_Cl_flaps"]
        with_term = sim.trim(cond)
        sim.set_effect_values({"calibration/effects/synth_Cl_flaps": 0.0})
        without = sim.trim(cond)
    assert abs(with_term.aileron_deg - without.aileron_deg) > 0.5


# --------------------------------------------------------------------------- real data
@pytest.mark.slow
@pytest.mark.parametrize("data", ["c172_flight_test_snapshots.csv", "g1000/log_110812_095915_KCKN.csv"])
def test_the_loop_on_real_data_runs_and_says_what_it_synthesized(tmp_path, data):
    """Measured with the committed C172: real trims: the library adds nothing; synthesis on
    aileron and rudder selects Cn ~ r b/2V, beta x Tc, flaps x Tc, which fails cross-validation
    (38 -> 425): nothing added. G1000 log: attitude_reference_offset added; synthesis on the
    remaining pitch selects CL ~ 1, alpha x Tc, rejected (BIC +100, null test p 0.46)."""
    from jsbsim_calib.calibration.workflow import run_close_loop
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", QuirkWarning)
        res = run_close_loop(REPO, "c172", REPO / "data" / data)
    d = res.to_json()
    assert {"added", "synthesized", "unexplained"} <= set(d)
    for rec in res.synthesized:
        assert rec.accepted or rec.reason, rec.as_dict()
    if not res.synthesized:
        assert not any(m.structured for m in res.diagnosis_after.values()) or res.added
    report = write_close_loop_report(res, tmp_path / "c172").read_text()
    assert "## Synthesized terms" in report
    added_terms = [t["term"] for r in res.synthesized if r.accepted for t in r.terms]
    print(f"{data}: added {res.added}; synthesized {added_terms}; "
          f"attempts {[(r.round, [t['term'] for t in r.terms], r.reason) for r in res.synthesized]}")


def test_testing_helper_writes_an_undeclared_term_into_an_axis(tmp_path):
    d = truth_copy(REPO / "aircraft" / "c172", tmp_path / "t" / "c172", [UndeclaredTerm("YAW", 0.5, "r b/2V", "t")])
    tree = read(d / "c172.xml")
    fn = tree.getroot().find("aerodynamics/axis[@name='YAW']/function[@name='aero/undeclared/t-lbsft']")
    assert fn is not None and "velocities/r-aero-rad_sec" in "".join(fn.itertext())
    with pytest.raises(ModelError):
        add_undeclared_term(tree, UndeclaredTerm("TORQUE", 1.0, "1"))
    with pytest.raises(ModelError):
        UndeclaredTerm("ROLL", 1.0, "no such state").expression()
