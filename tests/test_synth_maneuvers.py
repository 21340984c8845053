"""Synthetic time histories: the packaged Level 5 plan flown by a copy of the committed C172
(real JSBSim), written as format 1; seeds, noise and plan validation."""
import shutil
from pathlib import Path

import numpy as np
import pytest

from jsbsim_calib.cli import main
from jsbsim_calib.core.errors import InputError
from jsbsim_calib.data.timehistory import load_time_histories
from jsbsim_calib.jsbsim.simulator import Simulator
from jsbsim_calib.synthetic.maneuvers import check_settings, load_plan, synthesize_maneuvers

REPO = Path(__file__).resolve().parents[1]
LEVEL5_KINDS = {"climb", "longitudinal_trim", "phugoid", "pitch_pulse", "roll_pulse", "yaw_pulse", "roll_step",
                "rudder_response", "dutch_roll", "spiral", "sideslip", "static_stability", "maneuvering_stability",
                "flap_change", "power_change", "engine_acceleration"}


@pytest.fixture(scope="module")
def truth(tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp("truth") / "c172"
    shutil.copytree(REPO / "aircraft" / "c172", folder)
    return folder


@pytest.fixture(scope="module")
def flown(truth, tmp_path_factory):
    """The default plan written for a few (seed, noise) settings: directory per setting."""
    out = {}
    plan = load_plan("level5")
    with Simulator.from_dir(truth, REPO) as sim:
        for seed, noise in ((5, 1.0), (5, 0.0), (6, 1.0)):
            d = tmp_path_factory.mktemp(f"seed{seed}_noise{noise:g}")
            synthesize_maneuvers(sim, plan, d, seed=seed, noise=noise)
            out[seed, noise] = d
    return out


def _bytes(d: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted(d.iterdir())}


def test_default_plan_covers_level5_and_writes_valid_files(flown):
    plan = load_plan("level5")
    assert plan.sample_rate_hz == 10.0 and {m.kind for m in plan.maneuvers} == LEVEL5_KINDS
    assert all(m.duration_s <= (150 if m.kind == "phugoid" else 60) for m in plan.maneuvers)
    records = load_time_histories(flown[5, 1.0])
    assert len(records) == len(plan.maneuvers) == 22
    # three pitch pulses, at the flight test's three conditions (C.19, C.21, C.23)
    assert [m.id for m in plan.maneuvers if m.kind == "pitch_pulse"] == ["S.07", "S.21", "S.22"]
    for spec, th in zip(plan.maneuvers, records):
        assert th.meta.test_id == spec.id and th.meta.kind == spec.kind and th.meta.part60 == spec.part60
        assert th.time_s[-1] == pytest.approx(spec.duration_s) and np.all(np.diff(th.time_s) == pytest.approx(0.1))
        assert np.isfinite(th.frame.to_numpy()).all()
        assert th.meta.aircraft == "c172" and set(th.meta.sources) == set(th.channels) - {"time_s"}
    by_kind = {th.meta.kind: th for th in records}
    # the loops as flown: held at the trim by name, with a target or a window as windows (a replay flies them again)
    assert by_kind["sideslip"].meta.pilot == {"pitch": "altitude",
                                               "roll": [{"loop": "bank", "target": 3.0, "start_s": 2.0}],
                                               "yaw": [{"loop": "sideslip", "target": 5.0, "start_s": 2.0}]}
    assert by_kind["spiral"].meta.pilot["roll"] == [{"loop": "bank", "target": 30.0, "start_s": 1.0, "end_s": 15.0}]
    assert by_kind["engine_acceleration"].meta.inputs == ("elevator_deg", "aileron_deg", "throttle_norm")


def test_noise_zero_records_the_truth(flown):
    records = {th.meta.test_id: th for th in load_time_histories(flown[5, 0.0])}
    trim = records["S.03"]                                    # flaps 10 at 90 KCAS, level
    assert trim.channel("kcas")[0] == pytest.approx(90.0, abs=2e-3)
    assert trim.channel("flaps_deg")[0] == 10.0 and trim.channel("vs_fpm")[0] == pytest.approx(0.0, abs=0.02)
    sideslip = records["S.14"]
    assert sideslip.channel("beta_deg")[-1] == pytest.approx(5.0, abs=0.3)     # the sideslip loop
    steps = records["S.20"]
    assert steps.channel("throttle_norm")[0] == 0.0 and steps.channel("throttle_norm")[-1] == 1.0
    assert steps.channel("rpm")[-1] - steps.channel("rpm")[0] > 800
    turn = records["S.17"]
    assert turn.channel("roll_deg")[-1] == pytest.approx(45.0, abs=1.0) and turn.channel("nz_g")[-1] > 1.3


def test_same_seed_same_bytes_and_noise_matters(flown, truth, tmp_path):
    plan = load_plan("level5")
    with Simulator.from_dir(truth, REPO) as sim:
        synthesize_maneuvers(sim, plan, tmp_path, seed=5, noise=1.0)
    assert _bytes(tmp_path) == _bytes(flown[5, 1.0])
    a, exact, other = (_bytes(flown[k]) for k in ((5, 1.0), (5, 0.0), (6, 1.0)))
    csvs = [n for n in a if n.endswith(".csv")]
    assert all(a[n] != exact[n] and a[n] != other[n] for n in csvs)
    noisy, clean = (load_time_histories(flown[k]) for k in ((5, 1.0), (5, 0.0)))
    d = noisy[1].channel("pitch_deg") - clean[1].channel("pitch_deg")
    assert 0.02 < np.std(d) < 0.1                            # sigma 0.05 deg


def test_cli_synth_plan_and_settings(truth, tmp_path, capsys):
    out = tmp_path / "th"
    assert main(["--quiet", "synth", "--truth", str(truth), "--plan", "level5", "--out", str(out), "--seed", "2",
                 "--noise", "0.5"]) == 0
    assert len(list(out.glob("*.csv"))) == 22 and "22 time histories" in capsys.readouterr().out
    assert main(["--quiet", "synth", "--truth", str(truth), "--plan", "level5", "--out", str(out),
                 "--noise", "-1"]) == 2
    assert "--noise" in capsys.readouterr().err
    assert main(["--quiet", "synth", "--truth", str(truth), "--plan", "nowhere", "--out", str(out)]) == 2
    assert "packaged: level5" in capsys.readouterr().err
    snap = tmp_path / "snap.csv"                               # without --plan: snapshots as before
    assert main(["--quiet", "synth", "--truth", str(truth), "--out", str(snap), "--points", "4"]) == 0
    assert snap.read_text().startswith("table,title,weight_lb")


@pytest.mark.parametrize("seed, noise, part", [(-1, 1.0, "--seed"), (0, -0.5, "--noise"), (0, float("nan"), "--noise"),
                                                (0, 11.0, "--noise")])
def test_settings_must_be_sane(seed, noise, part):
    with pytest.raises(InputError, match=part):
        check_settings(seed, noise)


GOOD = """
[plan]
name = "tiny"
sample_rate_hz = 20.0

[[maneuver]]
id = "M.1"
kind = "pitch_pulse"
part60 = "2.b.1"
title = "pulse"
duration_s = 5.0
start = { pressure_alt_ft = 5000, kcas = 100, weight_lb = 2400, cg_in = 42.0 }
inputs = [{ shape = "pulse", channel = "elevator_deg", amplitude = 3.0, start_s = 1.0, length_s = 1.0 }]
pilot = { roll = "bank" }
"""
PLAN_CASES = {
    "unknown maneuver key": (('duration_s = 5.0', 'duration_s = 5.0\nspeed = 3'), ["maneuver[0] (M.1)", "key 'speed'",
                                                                                "unknown key"]),
    "unknown start key": (("cg_in = 42.0 }", "cg_in = 42.0, oat = 3 }"), ["maneuver[0] (M.1).start", "key 'oat'"]),
    "missing duration": (('duration_s = 5.0\n', ''), ["maneuver[0] (M.1)", "key 'duration_s'", "missing"]),
    "both speeds": (("kcas = 100,", "kcas = 100, ktas = 105,"), ["M.1).start", "key 'kcas'", "exactly one"]),
    "bad shape": (('shape = "pulse"', 'shape = "sine"'), ["M.1).inputs[0]", "key 'shape'", "pulse, step, doublet"]),
    "bad channel": (('channel = "elevator_deg"', 'channel = "pitch_deg"'), ["M.1).inputs[0]", "key 'channel'"]),
    "pulse without length": ((", length_s = 1.0 }", " }"), ["M.1).inputs[0]", "key 'length_s'", "missing"]),
    "loop on the wrong axis": (('roll = "bank"', 'roll = "altitude"'), ["M.1).pilot.roll[0]", "key 'loop'"]),
    "unknown axis": (('roll = "bank"', 'wheel = "bank"'), ["M.1).pilot", "key 'wheel'", "unknown key"]),
    "offset on altitude": (('roll = "bank"', 'pitch = { loop = "altitude", offset = 100 }'),
                           ["M.1).pilot.pitch[0]", "key 'offset'"]),
    "bad sample rate": (("sample_rate_hz = 20.0", "sample_rate_hz = 0"), ["tiny.toml: plan", "key 'sample_rate_hz'"]),
    "unknown noise channel": (("[[maneuver]]", "[noise.pitch_rad]\nsigma = 1\n\n[[maneuver]]"),
                              ["tiny.toml: noise", "key 'pitch_rad'"]),
    "negative noise": (("[[maneuver]]", "[noise.pitch_deg]\nsigma = -1\n\n[[maneuver]]"),
                       ["noise.pitch_deg", "key 'sigma'"]),
    "not TOML": (("[plan]", "[plan"), ["not valid TOML"]),
}


@pytest.mark.parametrize("case", PLAN_CASES, ids=list(PLAN_CASES))
def test_plan_validation_names_file_maneuver_and_key(tmp_path, case):
    (old, new), expected = PLAN_CASES[case]
    assert old in GOOD
    path = tmp_path / "tiny.toml"
    path.write_text(GOOD.replace(old, new, 1))
    with pytest.raises(InputError) as exc:
        load_plan(path)
    text = str(exc.value)
    assert str(path) in text.splitlines()[0]
    for part in expected:
        assert part in text, f"{part!r} not in:\n{text}"


def test_custom_plan_flies_at_its_rate(truth, tmp_path):
    path = tmp_path / "tiny.toml"
    path.write_text(GOOD)
    plan = load_plan(path)
    with Simulator.from_dir(truth, REPO) as sim:
        files = synthesize_maneuvers(sim, plan, tmp_path / "out", seed=1, noise=0.0)
    assert [f.name for f in files] == ["M_1_pitch_pulse.csv"]
    (th,) = load_time_histories(tmp_path / "out")
    assert th.meta.sample_rate_hz == 20.0 and len(th.frame) == 101
    assert th.meta.inputs == ("elevator_deg", "aileron_deg") and th.meta.pilot == {"roll": "bank"}
    q = th.channel("q_deg_s")
    assert q.max() > 3.0                                      # 3 deg trailing edge up: nose up
