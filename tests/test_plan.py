"""``jsbsim-calib plan``: designed inputs, the proposal on the committed C172 and the flight card
(real JSBSim; the proposal is flown through the packaged synthesis and JSBSim's own runner)."""
import fcntl
import json
import math
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from jsbsim_calib.synthetic import design as D
from jsbsim_calib.synthetic.design import in_hand_information
from jsbsim_calib.cli import main
from jsbsim_calib.core.errors import CalibError, InputError
from jsbsim_calib.jsbsim.simulator import Simulator
from jsbsim_calib.synthetic.maneuvers import (
    InputSpec,
    input_shape,
    load_plan,
    multisine,
    plan_text,
)

REPO = Path(__file__).resolve().parents[1]


# --------------------------------------------------------------------------- designed inputs and the plan format
def test_3211_steps_last_3_2_1_1_units_and_alternate():
    spec = InputSpec("3211", "elevator_deg", 2.0, 1.0, 0.5, ramp_s=0.1)
    t, v = input_shape(spec, 1.0, 0.5, 2.0)
    assert v[0] == v[1] == v[-1] == 0.0
    holds = [(t[k + 1] - t[k], v[k]) for k in range(2, len(t) - 1, 2)]
    assert [h[0] for h in holds] == pytest.approx([1.5, 1.0, 0.5, 0.5])
    assert [h[1] for h in holds] == [2.0, -2.0, 2.0, -2.0]


def test_multisine_peaks_at_its_amplitude_starts_and_ends_at_zero():
    t = np.arange(0.0, 20.0 + 1e-9, 0.05)
    x = multisine(t, 20.0, (0.1, 1.5), 1.0)
    assert np.max(np.abs(x)) == pytest.approx(1.0)
    assert x[0] == pytest.approx(0.0, abs=1e-12) and x[-1] == pytest.approx(0.0, abs=1e-12)
    spectrum = np.abs(np.fft.rfft(x))
    freqs = np.fft.rfftfreq(len(x), 0.05)
    assert freqs[np.argmax(spectrum)] <= 1.5 and spectrum[freqs > 3.0].max() < 0.05 * spectrum.max()


@pytest.mark.parametrize("inputs, key", [
    ('{ shape = "pulse", channel = "elevator_deg", amplitude = 2, start_s = 1, length_s = 1, band_hz = [0.1, 1] }',
     "band_hz"),
    ('{ shape = "multisine", channel = "elevator_deg", amplitude = 2, start_s = 1, length_s = 5, band_hz = [0.05, 0.1] }',
     "band_hz"),
    ('{ shape = "multisine", channel = "elevator_deg", amplitude = 2, start_s = 1, length_s = 5, band_hz = [1, 0.5] }',
     "band_hz"),
    ('{ shape = "3211", channel = "elevator_deg", amplitude = 2, start_s = 1 }', "length_s"),
])
def test_bad_designed_inputs_name_the_key(tmp_path, inputs, key):
    f = tmp_path / "p.toml"
    f.write_text('[[maneuver]]\nid = "X.1"\nkind = "pitch_3211"\ntitle = "t"\npart60 = "designed input"\n'
                 'duration_s = 10.0\nstart = { pressure_alt_ft = 3000, kcas = 90, weight_lb = 2300, cg_in = 41 }\n'
                 f"inputs = [{inputs}]\n")
    with pytest.raises(InputError) as e:
        load_plan(f)
    assert f"key '{key}'" in str(e.value) and "X.1" in str(e.value)


def test_a_written_plan_reads_back_to_the_same_maneuvers(tmp_path):
    level5 = load_plan("level5")
    f = tmp_path / "again.toml"
    f.write_text(plan_text("again", "the same maneuvers", level5.maneuvers, timing_s=0.1, header="two\nlines"))
    again = load_plan(f)
    assert again.maneuvers == level5.maneuvers and again.timing_s == 0.1


# --------------------------------------------------------------------------- the proposal on the committed C172
@pytest.fixture(scope="module")
def planned(tmp_path_factory, worker_id):
    """``plan c172`` on the committed aircraft (the data in hand: its flight-test results table),
    made once for all the suite's workers (35-45 s each): the first to ask writes it into their
    shared temporary folder under a lock, the others read it there."""
    base = tmp_path_factory.getbasetemp()
    shared = base.parent if worker_id != "master" else base
    out, record = shared / "plan-c172", shared / "plan-c172.json"
    with open(shared / "plan-c172.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        if not record.is_file():
            out.mkdir(exist_ok=True)
            (out / "flight_card_P_99_phugoid.png").write_bytes(b"an earlier card's figure")
            before = sorted(p.name for p in (REPO / "aircraft" / "c172").iterdir())
            code = main(["--root", str(REPO), "--quiet", "plan", "c172", "--out", str(out)])
            after = sorted(p.name for p in (REPO / "aircraft" / "c172").iterdir())
            record.write_text(json.dumps([code, before, after]))
        code, before, after = json.loads(record.read_text())
    return code, out, before, after


@pytest.mark.slow
def test_plan_writes_a_card_a_plan_and_scripts_and_leaves_the_aircraft_alone(planned):
    code, out, before, after = planned
    assert code == 0 and before == after
    plan = load_plan(out / "plan.toml")
    assert len(plan.maneuvers) == D.COUNT
    md = (out / "flight_card.md").read_text()
    page = (out / "flight_card.html").read_text()
    for m in plan.maneuvers:
        assert m.id in md and m.id in page
        assert (out / "scripts" / f"{re.sub('[.]', '_', m.id)}_{m.kind}.xml").is_file()
    assert md.count("![") == page.count("<img ") == len(plan.maneuvers)
    assert sorted(p.name for p in out.glob("flight_card_*.png")) == sorted(re.findall(r"\((flight_card_\S+\.png)\)", md))
    srcs = re.findall(r'src="([^"]*)"', page)
    assert srcs and all(s.startswith("data:image/png;base64,") for s in srcs)    # self-contained
    assert "K_Cmq" in md and "Stop the maneuver" in md


@pytest.mark.slow
def test_a_proposed_script_runs_in_jsbsims_runner(planned, tmp_path):
    _, out, _, _ = planned
    script = next(s for s in sorted((out / "scripts").glob("P_*.xml")) if not s.stem.endswith(("_init", "_output")))
    runner = Path(sys.executable).with_name("jsbsim")
    if not runner.is_file():
        pytest.skip("no jsbsim runner beside this Python")
    res = subprocess.run([str(runner), f"--root={REPO}", f"--script={script}"], check=False, capture_output=True,
                         text=True, timeout=120, cwd=tmp_path)
    assert res.returncode == 0, res.stderr[-2000:]
    rows = (out / "scripts" / f"{script.stem}.csv").read_text().splitlines()
    assert len(rows) > 100 and "p-rad_sec" in rows[0]


@pytest.mark.slow
def test_the_plan_aims_at_the_loosest_factors_and_beats_random_level5_maneuvers(planned):
    """Predicted by the information (a record's replay error counted as noise, for the plan
    and the draws alike): the plan's picks shrink the two loosest factors' standard errors at
    least 3x more than the median of 40 random draws of as many Level 5 maneuvers; and the
    synthesis flies the plan on a truth whose refit agrees with the prediction."""
    _, out, _, _ = planned
    plan, level5 = load_plan(out / "plan.toml"), load_plan("level5")
    names = D.DESIGN_FACTORS
    with Simulator(REPO, "c172") as sim:
        fs = sim.factors
        info, _ = in_hand_information(sim, REPO, "c172")
        se0 = D.standard_errors(info, names, fs)
        targets = D.loosest(se0, fs)
        assert targets == ("K_Cmq", "K_Cnr")
        per = {}
        for m in (*plan.maneuvers, *level5.maneuvers):
            try:
                per[m.id] = D.usable_information(sim, m, level5, fs, names)[0]
            except CalibError:                 # a Level 5 maneuver the model cannot fly carries nothing
                per[m.id] = np.zeros((len(names), len(names)))
        planned_se = D.standard_errors(info + sum(per[m.id] for m in plan.maneuvers), names, fs)
        rng = np.random.default_rng(3)
        draws = [rng.choice(len(level5.maneuvers), len(plan.maneuvers), replace=False) for _ in range(40)]
        random_se = [D.standard_errors(info + sum(per[level5.maneuvers[i].id] for i in d), names, fs) for d in draws]
        for n in targets:
            median = float(np.median([s[n] for s in random_se]))
            assert median / planned_se[n] >= 3.0, (n, median, planned_se[n])
        # flown on a truth with K_Cmq, K_Cnr moved, then refitted: the standard errors as predicted
        with Simulator(REPO, "c172") as truth:
            true = fs.with_vector(["K_Cmq", "K_Cnr"], [2.0 / 6.0, 0.02 / 0.07])
            truth.set_factors(true)
            records = D.synthetic_records(truth, plan.maneuvers, plan, seed=1)
        fit = D.refit(sim, records, fs)
        se = D.combined_errors(info, fit, true)
    for n in targets:
        assert math.isfinite(se[n]) and se[n] < se0[n] / 10.0
        assert 0.3 < se[n] / planned_se[n] < 5.0, (n, se[n], planned_se[n])
