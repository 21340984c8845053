"""Stage 2b and the time-domain machinery: real JSBSim flights of the committed C172.

- maneuvers start in equilibrium and JSBSim's own runner replays an exported maneuver script
  to the same trace, frame for frame;
- the pilot loops hold what they are asked to hold;
- the dynamic tests load from the real summary data with their stated assumptions;
- the measurements recover known periods, damping and rates;
- damping factors perturbed in a truth aircraft are recovered from its time histories;
- on the real data, a factor only amplitude-dependent metrics move is not fitted; a NaN never passes.
"""
from __future__ import annotations

import math
from dataclasses import replace
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from jsbsim_calib.calibration.dynamic import (DYNAMIC_STEPS, amplitude_scale, dynamic_stage, dynamic_step,
                                              identified_by, metric_residuals)
from jsbsim_calib.data.dynamic_tests import DynamicMetric, load_dynamic_tests, parse_tolerance
from jsbsim_calib.data.flighttest import load_control_travel
from jsbsim_calib.evaluation.evaluate_dynamic import MetricResult, TestResult, evaluate_dynamic, fly_test, peak_rate, phugoid, recorded, \
    steady_roll_rate
from jsbsim_calib.core.errors import DataError
from jsbsim_calib.jsbsim.aircraft import set_factor_values
from jsbsim_calib.flight.condition import Condition
from jsbsim_calib.jsbsim.script import SETTLE_S
from jsbsim_calib.jsbsim.simulator import Simulator
from jsbsim_calib.jsbsim.trajectory import RECORD, Hold, Input, Maneuver, export, fly
from jsbsim_calib.jsbsim.xml import read, write

REPO = Path(__file__).resolve().parents[1]
CRUISE = Condition(pressure_alt_ft=5500, weight_lb=2400, ktas=110, cg_in=42.0)


def _root_copy(tmp: Path) -> Path:
    for d in ("aircraft", "engine", "airfoils", "data"):
        shutil.copytree(REPO / d, tmp / d)
    return tmp


def _doublet(channel: str, a: float) -> Input:
    return Input(channel, (0, .5, .6, 1.5, 1.6, 2.5, 2.6), (0, 0, a, a, -a, -a, 0))


@pytest.fixture(scope="module")
def sim():
    with Simulator(REPO, "c172") as s:
        yield s


@pytest.fixture(scope="module")
def tests_real():
    travel = load_control_travel(REPO / "data/c172_control_travel.csv")
    return load_dynamic_tests(REPO / "data/c172_flight_test_results.csv",
                              REPO / "data/c172_flight_test_snapshots.csv", travel)


# --------------------------------------------------------------------------- the runner
def test_maneuver_starts_in_equilibrium(sim):
    tr = fly(sim, Maneuver("hands_off", CRUISE, 3.0))
    assert np.ptp(tr["pitch_deg"]) < 5e-3 and np.ptp(tr["ktas"]) < 5e-3 and np.ptp(tr["roll_deg"]) < 5e-3
    assert np.all(np.isfinite(tr["rpm"])) and abs(tr["rpm"][0] - tr.trim.rpm) < 0.1


def test_exported_script_replays_in_jsbsims_runner_frame_for_frame(tmp_path):
    root = _root_copy(tmp_path / "root")
    m = Maneuver("pulse_replay", CRUISE, 6.0, (_doublet("elevator_deg", -3.0), _doublet("aileron_deg", 4.0)))
    with Simulator(root, "c172") as s:
        flown = fly(s, m)
        paths = export(s, m, root / "scripts", flown=flown)
    # the pip wheel's runner flies 120 Hz unless told the script's rate (the C++ runner takes the script's)
    runner = shutil.which("jsbsim", path=str(Path(sys.executable).parent)) or shutil.which("jsbsim")
    run = subprocess.run([runner, "--root", str(root), "--script", str(paths["script"]),
                          "--simulation-rate", f"{1 / flown.dt_s:g}"],
                         capture_output=True, text=True, cwd=paths["script"].parent)
    assert run.returncode == 0, run.stderr[-2000:]
    csv = pd.read_csv(paths["csv"])
    t = csv["Time"].to_numpy()
    start = int(np.argmin(np.abs(t - SETTLE_S)))            # maneuver time 0
    n = len(flown.time_s)
    for name, (prop, scale) in RECORD.items():
        col = next(c for c in csv.columns if c.endswith(prop))
        replay = csv[col].to_numpy()[start:start + n] * scale
        assert np.allclose(replay, flown[name][:len(replay)], rtol=1e-9, atol=1e-9), name
    assert len(csv) - start >= n - 1


def test_inputs_played_from_python_fly_the_bits_of_the_scripts_events(sim):
    """fly() plays a maneuver's input breakpoints from Python (JSBSim would test hundreds of
    event conditions every frame); the script it exports holds them as events. A recorded
    input (a breakpoint every 0.1 s, noise on it) and a step (two breakpoints at one time),
    flown both ways, give the same bits in every frame, the last included."""
    rng = np.random.default_rng(7)
    t = tuple(float(x) for x in np.round(np.arange(0.0, 4.01, 0.1), 1))
    aileron = Input("aileron_deg", t, tuple(3.0 * np.sin(np.array(t) * 2.0) + rng.normal(0, 0.2, len(t))))
    rudder = Input("rudder_deg", (0.0, 1.0, 1.0, 4.0), (0.0, 0.0, 2.0, 2.0))
    flown = fly(sim, Maneuver("recorded_inputs", CRUISE, 4.0, (aileron, rudder)))
    script = sim.sandbox / "scripts" / "recorded_inputs_events.xml"
    script.write_text(flown.script)
    assert flown.script.count("FG_RAMP") >= len(t) + 1       # (and a breakpoint where the aileron crosses 0)
    fdm = sim.new_exec()
    assert fdm.load_script(str(script))
    fdm.run_ic()
    n_settle = int(round(SETTLE_S / flown.dt_s))
    frames = []
    for i in range(n_settle + len(flown.time_s)):
        if i >= n_settle:
            frames.append([fdm[p] * k for p, k in RECORD.values()])
        fdm.run()
    events = np.array(frames)
    for j, name in enumerate(RECORD):
        assert np.array_equal(events[:, j], flown[name]), name


def test_pilot_holds_bank_and_altitude(sim):
    tr = fly(sim, Maneuver("turn", CRUISE, 25.0, holds=(Hold("bank", 30.0), Hold("altitude"), Hold("sideslip", 0.0))))
    last = tr.time_s > 20
    assert abs(np.mean(tr["roll_deg"][last]) - 30.0) < 1.5
    assert abs(tr["h_ft"][-1] - tr["h_ft"][0]) < 60.0
    assert np.max(np.abs(tr["beta_deg"][last])) < 1.0


def test_bad_maneuvers_are_refused():
    with pytest.raises(ValueError, match="unknown input channel"):
        Input("stick", (0.0,), (1.0,))
    with pytest.raises(ValueError, match="finite"):
        Input("elevator_deg", (0.0, 1.0), (0.0, float("nan")))
    with pytest.raises(ValueError, match="two pilot loops hold the pitch axis"):
        Maneuver("m", CRUISE, 10.0, holds=(Hold("pitch"), Hold("altitude")))
    with pytest.raises(ValueError, match="duration"):
        Maneuver("m", CRUISE, float("nan"))


# --------------------------------------------------------------------------- measurements
def test_phugoid_measures_a_known_damped_oscillation():
    t = np.arange(0, 200, 1 / 60)
    zeta, T = 0.05, 35.0
    wn = 2 * math.pi / (T * math.sqrt(1 - zeta**2))
    v = 100 + 8 * np.exp(-zeta * wn * t) * np.sin(2 * math.pi / T * t)
    period, damping = phugoid(t, v, 0.0)
    assert period == pytest.approx(T, rel=0.01)
    assert damping == pytest.approx(zeta, abs=0.006)
    assert all(math.isnan(x) for x in phugoid(t[:100], v[:100], 0.0))     # too short: NaN, not a number


def test_peak_and_steady_rates():
    t = np.linspace(0, 6, 361)
    p = np.where(t > 1, -20 * (1 - np.exp(-(t - 1) / 0.3)), 0.0)
    assert steady_roll_rate(t, p, 0.5) == pytest.approx(-20.0 * 0.985, rel=0.02)
    assert peak_rate(t, -p, 0.5, +1.0) == pytest.approx(20.0, rel=0.01)
    assert peak_rate(t, p, 0.5, +1.0) <= 0.0          # a response the wrong way is no positive peak


def test_a_nan_never_passes():
    m = DynamicMetric("roll_rate_deg_s", -18.3, 2.0, False, "deg/s", False)
    assert MetricResult("C.58", m, float("nan")).within is False
    assert MetricResult("C.58", m, float("nan")).verdict == "FAIL"
    assert MetricResult("C.58", m, -18.0).within is True
    assert amplitude_scale(float("nan"), 10.0) == 1.0
    res, _, _ = metric_residuals(TestResult(None, None, [MetricResult("C.58", m, float("nan"))]))
    assert all(math.isfinite(r) and abs(r) >= 10 for r in res)       # the failure penalty, never NaN


# --------------------------------------------------------------------------- the real summary data
def test_dynamic_tests_load_with_their_assumptions(tests_real):
    ids = {t.id: t for t in tests_real}
    assert set(ids) == {"C.12", "C.19", "C.21", "C.23", "C.25", "C.27", "C.31", "C.33", "C.56", "C.58", "C.60"}
    # 1.f.1: the alternative data's range "2 - 4" s is 3 +- 1 s; 1.f.2 (a ground test) is not flown
    assert ids["C.12"].kind == "engine_acceleration" and ids["C.12"].initial == ""
    assert (ids["C.12"].metrics[0].measured, ids["C.12"].metrics[0].tol()) == (3.0, 1.0)
    assert ids["C.56"].initial == "C.55" and {m.name for m in ids["C.56"].metrics} == {"phugoid_period_s",
                                                                                       "phugoid_damping"}
    assert ids["C.56"].metrics[0].tol() == pytest.approx(3.5)
    assert ids["C.58"].maneuver.start.bank_deg == pytest.approx(40.6)
    assert all(m.amplitude_dependent for t in tests_real if t.kind.endswith("pulse") for m in t.metrics)
    assert all("not recorded" in t.assumptions[0] for t in tests_real if t.kind.endswith("pulse"))
    # the roll step goes toward the roll the result's sign gives: left (JSBSim aileron negative)
    assert ids["C.58"].maneuver.inputs[0].value[-1] < 0
    assert parse_tolerance(r"$\pm 20\%$ ($2.2^\circ/\text{s}$)") == (0.2, True)
    assert parse_tolerance(r"$\pm 2^\circ/\text{s}$") == (2.0, False)


def test_a_results_row_without_initial_condition_is_named(tmp_path):
    res = tmp_path / "results.csv"
    res.write_text("table,title,metric,tolerance,flight_test\nC.99,2.c.9.b - Phugoid,Period,10 %,35.0\n")
    with pytest.raises(DataError, match="C.99.*no snapshot row C.98"):
        load_dynamic_tests(res, REPO / "data/c172_flight_test_snapshots.csv",
                           load_control_travel(REPO / "data/c172_control_travel.csv"))


def test_an_engine_range_that_is_not_a_range_is_named(tmp_path):
    res = tmp_path / "results.csv"
    res.write_text("table,title,metric,tolerance,flight_test\nC.12,1.f.1 Engine Acceleration,ΔT,± 1 sec,fast\n")
    with pytest.raises(DataError, match=r"line 2 \(C.12\), column 'flight_test'.*'fast' is not a range"):
        load_dynamic_tests(res, REPO / "data/c172_flight_test_snapshots.csv",
                           load_control_travel(REPO / "data/c172_control_travel.csv"))


def test_the_engine_step_refits_the_rotating_inertia_from_the_rpm_response(sim, tests_real):
    """A truth with K_Ip = 1.3 sets the response time the engine step fits; from K_Ip = 1 it
    finds the truth again (the step prior pulls a little toward its start). Recorded time
    histories hold no RPM channel: the step does not fly them."""
    eng = next(t for t in tests_real if t.kind == "engine_acceleration")
    step = next(s for s in DYNAMIC_STEPS if s.name == "engine dynamics")
    start = sim.factors
    try:
        sim.set_factors(start.replace(K_Ip=1.3))
        truth = fly_test(sim, eng).metrics[0].model
        assert 2.0 < truth < 3.0
        measured = replace(eng, metrics=(replace(eng.metrics[0], measured=truth),))
        out = dynamic_step(sim, step, [measured], {}, start.replace(K_Ip=1.0))
        assert out.final["K_Ip"] == pytest.approx(1.3, rel=0.03)
        assert dynamic_step(sim, step, [recorded("e", "engine_acceleration", fly(sim, eng.maneuver))], {}, start) is None
    finally:
        sim.set_factors(start)


def test_real_dynamic_tests_fly_and_yaw_damping_is_not_decided_by_assumed_amplitudes(sim, tests_real):
    ev = evaluate_dynamic(sim, tests_real)
    assert not ev.summary()["failed_to_fly"]
    assert all(math.isfinite(m.model) for m in ev.metric_results())
    yaw = next(s for s in DYNAMIC_STEPS if s.name == "yaw dynamics")
    out = dynamic_step(sim, yaw, tests_real, {}, sim.factors)
    assert out.message == "nothing fitted" and out.final["K_Cnr"] == sim.factors["K_Cnr"]
    assert any("K_Cnr not fitted" in n for n in out.notes)


def test_identified_by_ignores_held_rows():
    jac = np.array([[1.0, 5.0], [0.0, 5.0], [0.5, 0.01]])
    keep, drop = identified_by(jac, np.array(["amplitude", "held", "free"]), ["a", "b"])
    assert keep == ["a"] and drop == ["b"]      # b: its only large sensitivities are an amplitude and a held row


# --------------------------------------------------------------------------- recovery
@pytest.mark.slow
def test_damping_factors_of_a_truth_aircraft_are_recovered_from_its_time_histories(tmp_path):
    """A copy of the C172 with roll, pitch and yaw damping changed flies doublets and a roll step
    (10 Hz records); stage 2b from the committed model recovers the three factors within 10 %."""
    root = _root_copy(tmp_path / "truth")
    truth_values = {"K_Clp": 0.10, "K_Cmq": 2.0, "K_Cnr": 0.03}
    with Simulator(REPO, "c172") as s:
        base = s.factors
    xml = root / "aircraft/c172/c172.xml"
    tree = read(xml)
    set_factor_values(tree, base.updated(truth_values))
    write(tree, xml)
    plan = [("roll", "roll_pulse", _doublet("aileron_deg", 5.0)),
            ("rollstep", "roll_step", Input("aileron_deg", (0, .5, .6, 3.5, 3.6), (0, 0, -5, -5, 0))),
            ("pitch", "pitch_pulse", _doublet("elevator_deg", 3.0)), ("yaw", "yaw_pulse", _doublet("rudder_deg", 5.0))]
    with Simulator(root, "c172") as truth:
        recs = [recorded(n, k, fly(truth, Maneuver(n, CRUISE, 8.0, (i,)))) for n, k, i in plan]
    with Simulator(REPO, "c172") as s:
        results = dynamic_stage(s, recs, {}, start=s.factors)
    final = results[-1].final
    for name, v in truth_values.items():
        assert final[name] == pytest.approx(v, rel=0.10), (name, final[name])
