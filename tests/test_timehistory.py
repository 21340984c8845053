"""Format 1 (flight-test time histories): validation, byte-stable writing, and the replay of
a real flight of the committed C172 through the format (real JSBSim, no mocks)."""
import json
import math
import shutil
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from jsbsim_calib.core.errors import DataError, InputError
from jsbsim_calib.data.flighttest import load_control_travel
from jsbsim_calib.data.timehistory import (CHANNELS, Configuration, TimeHistory, TimeHistoryMeta,
                                           load_time_histories, load_time_history, maneuver_from_time_history,
                                           trajectory_to_time_history, write_time_history)
from jsbsim_calib.flight.condition import Condition
from jsbsim_calib.jsbsim.simulator import Simulator
from jsbsim_calib.jsbsim.trajectory import Input, Maneuver, fly

REPO = Path(__file__).resolve().parents[1]
RATE_HZ = 10.0

HEADER = "time_s,pressure_alt_ft,ktas,vs_fpm,pitch_deg,roll_deg,q_deg_s,elevator_deg,column_in,throttle_norm"
ROWS = [f"{i / 10:.1f},5500.0,{110 - 0.1 * i:.2f},0.0,{0.5 + 0.05 * i:.3f},0.0,0.5,{1.0 + 0.1 * i:.2f},3.1,0.8"
        for i in range(6)]
META = {"test_id": "T.1", "title": "pitch pulse", "part60": "2.b.1", "kind": "pitch_pulse", "aircraft": "c172",
        "configuration": {"weight_lb": 2400.0, "cg_in": 42.0, "flaps_deg": 0.0, "mixture": "cruise"},
        "sample_rate_hz": RATE_HZ, "inputs": ["elevator_deg"], "sources": {"pitch_deg": "AHRS"},
        "pilot": {"roll": "bank"}, "notes": "hand-made"}


def _write(d: Path, header=HEADER, rows=ROWS, meta=META, stem="T_1_pitch_pulse") -> Path:
    d.mkdir(parents=True, exist_ok=True)
    csv = d / f"{stem}.csv"
    csv.write_text("\n".join([header, *rows]) + "\n")
    if meta is not None:
        (d / f"{stem}.json").write_text(meta if isinstance(meta, str) else json.dumps(meta, indent=2))
    return csv


def _cell(row: int, column: str, text: str, rows=ROWS) -> list[str]:
    """ROWS with one cell (0-based data row, column name) replaced."""
    j = HEADER.split(",").index(column)
    out = [r.split(",") for r in rows]
    out[row][j] = text
    return [",".join(r) for r in out]


def _meta(**changes) -> dict:
    m = json.loads(json.dumps(META))
    for k, v in changes.items():
        if v is None:
            m.pop(k, None)
        else:
            m[k] = v
    return m


# --------------------------------------------------------------------------- reading and validation
def test_valid_file_loads(tmp_path):
    th = load_time_history(_write(tmp_path))
    assert th.channels == tuple(HEADER.split(","))
    assert th.meta.configuration == Configuration(2400.0, 42.0, 0.0, "cruise", 0.0)
    assert th.meta.inputs == ("elevator_deg",) and th.meta.pilot == {"roll": "bank"}
    np.testing.assert_allclose(th.time_s, np.arange(6) / 10)
    assert th.channel("pitch_deg")[2] == pytest.approx(0.6)
    assert np.isfinite(th.frame.to_numpy()).all()
    with pytest.raises(KeyError, match="no channel 'rpm'"):
        th.channel("rpm")


# a steady start of three samples (noisy speed and climb, 20 deg bank), then the elevator steps 2 deg
STEADY = [f"{i / 10:.1f},5500.0,{(110.3, 109.9, 109.8)[i] if i < 3 else 105.0},{(15.0, -3.0, 0.0)[i] if i < 3 else 300.0},"
          f"0.5,{20.0 if i < 3 else 25.0},0.5,{1.0 if i < 3 else 3.0},3.1,0.8" for i in range(8)]


def test_initial_condition_from_the_steady_start(tmp_path):
    th = load_time_history(_write(tmp_path, rows=STEADY))
    assert th.steady_lead() == 3                                 # until the elevator departs by > 0.5 deg
    c = th.initial_condition()                                   # the mean of the steady samples, not the first
    assert (c.ktas, c.pressure_alt_ft, c.vs_fpm, c.bank_deg, c.turn) == pytest.approx(
        (110.0, 5500.0, 4.0, 20.0, "coordinated"))
    assert (c.weight_lb, c.cg_in, c.flaps_deg, c.mixture, c.mode) == (2400.0, 42.0, 0.0, "cruise", "level")
    m = maneuver_from_time_history(th)                           # the elevator: a change from the steady value
    assert m.inputs[0].value[0] == pytest.approx(0.0) and max(map(abs, m.inputs[0].value)) == pytest.approx(2.0)
    held = _meta(pilot={"pitch": [{"loop": "pitch", "target": 3.0, "start_s": 0.2}]})
    assert load_time_history(_write(tmp_path / "w", rows=STEADY, meta=held)).steady_lead() == 2   # a window moves it
    straight = load_time_history(_write(tmp_path / "b")).initial_condition()
    assert straight.turn == "straight" and straight.bank_deg == 0.0
    assert straight.ktas == pytest.approx(np.mean([110 - 0.1 * i for i in range(6)]))   # 0.5 s, nothing departs


# each case: (files to write, what the message must name)
CSV = "T_1_pitch_pulse.csv"
JSON = "T_1_pitch_pulse.json"
CASES = {
    "unknown column": (dict(header=HEADER.replace("q_deg_s", "q_rad_s")),
                       [CSV, "line 1", "column 'q_rad_s'", "unknown channel", "known: time_s, pressure_alt_ft"]),
    "duplicate column": (dict(header=HEADER.replace("roll_deg", "pitch_deg")),
                         [CSV, "line 1", "column 'pitch_deg'", "appears more than once"]),
    "missing time column": (dict(header=HEADER.replace("time_s", "t"), meta=_meta(sample_rate_hz=10.0)),
                            [CSV, "line 1", "column 'time_s'", "missing"]),
    "no response channel": (dict(header="time_s,elevator_deg", rows=["0.0,1.0", "0.1,1.0"]),
                            [CSV, "line 1", "no response channel"]),
    "non-numeric cell": (dict(rows=_cell(3, "pitch_deg", "abc")),
                         [CSV, "line 5 (row 4)", "column 'pitch_deg'", "'abc' is not a number"]),
    "NaN cell": (dict(rows=_cell(2, "ktas", "NaN")), [CSV, "line 4 (row 3)", "column 'ktas'", "not a finite number"]),
    "inf cell": (dict(rows=_cell(1, "q_deg_s", "-inf")), [CSV, "line 3 (row 2)", "column 'q_deg_s'", "not a finite"]),
    "blank cell": (dict(rows=_cell(4, "elevator_deg", "")), [CSV, "line 6 (row 5)", "column 'elevator_deg'", "empty"]),
    "time not increasing": (dict(rows=_cell(3, "time_s", "0.2")),
                            [CSV, "line 5 (row 4)", "column 'time_s'", "time must increase strictly"]),
    "sample rate inconsistent": (dict(meta=_meta(sample_rate_hz=20.0)),
                                 [CSV, "line 3 (row 2)", "column 'time_s'", "1/sample_rate_hz = 0.05 s"]),
    "value out of range": (dict(rows=_cell(2, "pitch_deg", "95.0")),
                           [CSV, "line 4 (row 3)", "column 'pitch_deg'", "outside the plausible range [-90, 90]"]),
    "wrong number of fields": (dict(rows=[*ROWS[:2], ROWS[2] + ",1.0", *ROWS[3:]]),
                               [CSV, "line 4 (row 3)", "11 fields, the header has 10"]),
    "missing metadata key": (dict(meta=_meta(part60=None)), [JSON, "key 'part60'", "missing"]),
    "unknown metadata key": (dict(meta=_meta(pilots={"roll": "bank"})), [JSON, "key 'pilots'", "unknown key"]),
    "invalid configuration": (dict(meta=_meta(configuration={"weight_lb": "heavy", "cg_in": 42.0, "flaps_deg": 0.0,
                                                             "mixture": "lean"})),
                              [JSON, "key 'configuration.weight_lb'", "key 'configuration.mixture'"]),
    "invalid sample rate": (dict(meta=_meta(sample_rate_hz=-10)), [JSON, "key 'sample_rate_hz'", "not a rate"]),
    "pilot loop on the wrong axis": (dict(meta=_meta(pilot={"roll": "altitude"})),
                                     [JSON, "key 'pilot.roll'", "not a loop of the roll axis"]),
    "input not a column": (dict(meta=_meta(inputs=["rudder_deg"])), [JSON, "key 'inputs[0]'", "'rudder_deg' is not a "
                                                                                           "column of the CSV"]),
    "input not an input channel": (dict(meta=_meta(inputs=["pitch_deg"])),
                                   [JSON, "key 'inputs[0]'", "not an input channel"]),
    "control and surface both inputs": (dict(meta=_meta(inputs=["elevator_deg", "column_in"])),
                                        [JSON, "key 'inputs'", "drive the same surface"]),
    "source not a column": (dict(meta=_meta(sources={"rpm": "magneto"})), [JSON, "key 'sources.rpm'", "not a column"]),
    "missing sidecar": (dict(meta=None), [JSON, "metadata sidecar missing"]),
    "sidecar not JSON": (dict(meta='{"test_id": "T.1",\n "title": }'), [JSON, "line 2", "not valid JSON"]),
}


@pytest.mark.parametrize("case", CASES, ids=list(CASES))
def test_validation_error_names_file_line_and_column(tmp_path, case):
    files, expected = CASES[case]
    path = _write(tmp_path, **files)
    with pytest.raises(DataError) as exc:
        load_time_history(path)
    text = str(exc.value)
    for part in expected:
        assert part in text, f"{part!r} not in:\n{text}"
    assert str(path) in text.splitlines()[0]


def test_every_problem_is_listed_at_once(tmp_path):
    rows = _cell(1, "pitch_deg", "x", rows=_cell(3, "ktas", "nan", rows=_cell(4, "roll_deg", "200")))
    path = _write(tmp_path, rows=rows, meta=_meta(title=None, inputs=["rudder_deg"]))
    with pytest.raises(DataError) as exc:
        load_time_history(path)
    wheres = " | ".join(p.where for p in exc.value.problems)
    for part in ("line 3 (row 2), column 'pitch_deg'", "line 5 (row 4), column 'ktas'",
                 "line 6 (row 5), column 'roll_deg'", "key 'title'", "key 'inputs[0]'"):
        assert part in wheres


@pytest.mark.parametrize("text", ["nan", "NaN", "-nan", "inf", "", " "])
def test_a_nan_never_passes(tmp_path, text):
    with pytest.raises(DataError, match="column 'vs_fpm'"):
        load_time_history(_write(tmp_path, rows=_cell(5, "vs_fpm", text)))


def test_directory_of_records(tmp_path):
    _write(tmp_path, stem="b_second")
    _write(tmp_path, stem="a_first")
    (tmp_path / "stray.csv").write_text("x,y\n1,2\n")          # no sidecar: not a record
    got = load_time_histories(tmp_path)
    assert [t.path.name for t in got] == ["a_first.csv", "b_second.csv"]
    empty = tmp_path / "empty"
    empty.mkdir()
    with pytest.raises(DataError, match="no time histories here"):
        load_time_histories(empty)
    bad = _write(tmp_path / "bad", rows=_cell(1, "ktas", "?"))
    with pytest.raises(DataError, match="line 3"):
        load_time_histories([tmp_path / "a_first.csv", bad])


def test_write_read_round_trip_is_byte_stable(tmp_path):
    th = load_time_history(_write(tmp_path / "src"))
    c1, j1 = write_time_history(th, tmp_path / "one")
    th2 = load_time_history(c1)
    c2, j2 = write_time_history(th2, tmp_path / "two")
    assert c1.read_bytes() == c2.read_bytes() and j1.read_bytes() == j2.read_bytes()
    assert c1.read_text().splitlines()[1] == "0.000000,5500.00,110.000,0.00,0.5000,0.0000,0.5000,1.0000,3.10000,0.80000"
    np.testing.assert_array_equal(th2.frame.to_numpy(), th.frame.to_numpy())
    assert th2.meta == th.meta


def test_writer_refuses_a_record_that_would_not_load(tmp_path):
    th = load_time_history(_write(tmp_path))
    th.frame.loc[2, "pitch_deg"] = math.nan
    with pytest.raises(DataError, match="column 'pitch_deg'"):
        write_time_history(th, tmp_path / "out")


def test_cockpit_input_needs_the_travel_table(tmp_path):
    th = load_time_history(_write(tmp_path, meta=_meta(inputs=["column_in"])))
    with pytest.raises(InputError, match="control-travel table"):
        maneuver_from_time_history(th)
    m = maneuver_from_time_history(th, travel=load_control_travel(REPO / "data" / "c172_control_travel.csv"),
                                   pilot={"roll": "bank"})
    assert [i.channel for i in m.inputs] == ["elevator_deg"] and m.inputs[0].relative
    assert [h.loop for h in m.holds] == ["bank"] and m.duration_s == pytest.approx(0.5)
    with pytest.raises(InputError, match="not a loop of the roll axis"):
        maneuver_from_time_history(th, travel=load_control_travel(REPO / "data" / "c172_control_travel.csv"),
                                   pilot={"roll": "heading"})


# --------------------------------------------------------------------------- a real flight through the format
@pytest.fixture(scope="module")
def c172(tmp_path_factory):
    folder = tmp_path_factory.mktemp("truth") / "c172"
    shutil.copytree(REPO / "aircraft" / "c172", folder)
    with Simulator.from_dir(folder, REPO) as sim:
        yield sim


def _pulse(channel: str, t0: float, amplitude: float) -> Input:
    return Input(channel, (0.0, t0, t0 + 0.2, t0 + 1.0, t0 + 1.2), (0.0, 0.0, amplitude, amplitude, 0.0))


def _flight(sim) -> Maneuver:
    """Pulses on the data's 10 Hz grid, each toward the side of its trimmed surface (the
    surface never crosses zero, where the script inserts a breakpoint between frames)."""
    start = Condition(5000.0, 2400.0, kcas=100.0, cg_in=42.0, mixture="cruise")
    t = sim.trim(start)
    side = {c: math.copysign(1.0, getattr(t, c)) for c in ("elevator_deg", "aileron_deg", "rudder_deg")}
    inputs = (_pulse("elevator_deg", 1.0, 1.5 * side["elevator_deg"]),
              _pulse("aileron_deg", 4.0, 4.0 * side["aileron_deg"]),
              _pulse("rudder_deg", 7.0, 3.0 * side["rudder_deg"]),
              Input("throttle_norm", (0.0, 10.0, 10.5), (0.0, 0.0, 0.1)))
    return Maneuver("replay_truth", start, 14.0, inputs, title="pulses of every surface and a throttle step")


META_FLIGHT = TimeHistoryMeta("R.1", "pulses of every surface", "2.b.1", "pulses", "c172",
                              Configuration(2400.0, 42.0, 0.0, "cruise"), RATE_HZ,
                              ("elevator_deg", "aileron_deg", "rudder_deg", "throttle_norm"), {"pitch_deg": "truth"})
COMPARED = {"pitch_deg": 0.002, "roll_deg": 0.002, "p_deg_s": 0.002, "q_deg_s": 0.002, "r_deg_s": 0.002,
            "heading_deg": 0.002, "kcas": 0.005}


@pytest.mark.parametrize("inputs", [("elevator_deg", "aileron_deg", "rudder_deg", "throttle_norm"),
                                    ("column_in", "wheel_deg", "pedal_in", "throttle_norm")],
                         ids=["surfaces", "cockpit"])
def test_replay_of_the_model_own_record_reproduces_it(c172, tmp_path, inputs):
    """Flight -> format 1 (noise 0, written and read back) -> maneuver -> flight: the replay
    gives back the recorded attitudes and rates to the written digits."""
    travel = load_control_travel(c172.geometry.control_travel_file)
    traj = fly(c172, _flight(c172))
    th = trajectory_to_time_history(traj, replace(META_FLIGHT, inputs=inputs), RATE_HZ, travel=travel)
    record = load_time_history(write_time_history(th, tmp_path)[0])
    assert len(record.frame) == 141 and set(record.channels) == set(CHANNELS)
    m = maneuver_from_time_history(record, c172.geometry)
    assert m.duration_s == pytest.approx(14.0) and m.start.ktas == record.channel("ktas")[0]
    assert all(len(i.time_s) <= 7 for i in m.inputs)          # the written ramps' corners, found again
    replay = trajectory_to_time_history(fly(c172, m), META_FLIGHT, RATE_HZ, travel=travel)
    for ch, tol in COMPARED.items():
        err = np.max(np.abs(replay.channel(ch) - record.channel(ch)))
        assert err <= tol, f"{ch}: replay differs by {err:.4g} (tolerance {tol})"
    assert np.ptp(record.channel("q_deg_s")) > 5 and np.ptp(record.channel("p_deg_s")) > 5


def test_noise_is_seeded_and_stays_valid(c172, tmp_path):
    from jsbsim_calib.data.timehistory import SensorError
    traj = fly(c172, _flight(c172))
    noise = {c: SensorError(0.1, 0.05) for c in ("pitch_deg", "roll_deg", "q_deg_s", "elevator_deg", "heading_deg")}
    a = trajectory_to_time_history(traj, META_FLIGHT, RATE_HZ, noise=noise, rng=np.random.default_rng(4))
    b = trajectory_to_time_history(traj, META_FLIGHT, RATE_HZ, noise=noise, rng=np.random.default_rng(4))
    exact = trajectory_to_time_history(traj, META_FLIGHT, RATE_HZ)
    pa, pb = write_time_history(a, tmp_path / "a")[0], write_time_history(b, tmp_path / "b")[0]
    assert pa.read_bytes() == pb.read_bytes()
    d = a.channel("pitch_deg") - exact.channel("pitch_deg")
    assert 0.02 < np.std(d) < 0.2 and abs(np.mean(d) - 0.05) < 0.03
    assert isinstance(load_time_history(pa), TimeHistory)


def test_a_noisy_input_is_replayed_as_the_surface_moved_not_as_its_sensor_noise(c172):
    """The pulses recorded with 0.1 deg of sensor noise on every surface: the replay's inputs
    follow the noise-free record's within 0.04 deg RMS (a constant left aside: the mean of
    the steady start, which the loop's offsets fit), on at most 20 breakpoints. Flying every
    sample, as the replay did before INPUT_NOISE_SIGMAS, they were 0.08-0.09 deg off."""
    from jsbsim_calib.data.timehistory import SensorError
    traj = fly(c172, _flight(c172))
    noise = {c: SensorError(0.1, 0.0) for c in ("elevator_deg", "aileron_deg", "rudder_deg")}
    noisy = trajectory_to_time_history(traj, META_FLIGHT, RATE_HZ, noise=noise, rng=np.random.default_rng(0))
    clean = maneuver_from_time_history(trajectory_to_time_history(traj, META_FLIGHT, RATE_HZ), c172.geometry)
    t = np.arange(0.0, 14.0, 0.05)
    for got, want in zip(maneuver_from_time_history(noisy, c172.geometry).inputs[:3], clean.inputs):
        err = np.interp(t, got.time_s, got.value) - np.interp(t, want.time_s, want.value)
        assert np.std(err) < 0.04 and len(got.time_s) <= 20, got.channel        # of 141 samples


def test_a_record_starting_at_full_throttle_is_trimmed_there(c172):
    """The Level 5 normal climb at seed 2 records 693.7 ft/min, a little more than the model
    climbs at full throttle there: a level trim at that climb rate has no solution ("needs
    more than full throttle"), so the replay trims at full throttle with the flight path free."""
    from jsbsim_calib.synthetic.maneuvers import fly_plan, load_plan
    plan = load_plan("level5")
    th = fly_plan(c172, replace(plan, maneuvers=plan.maneuvers[:1]), seed=2)[0]
    start = th.initial_condition()
    assert (start.mode, start.throttle) == ("full_throttle", 1.0)
    level = c172.trim(replace(start, mode="level"))
    assert not level.trimmed and "more than full throttle" in level.reason
    assert fly(c172, maneuver_from_time_history(th, c172.geometry)).time_s[-1] == pytest.approx(th.time_s[-1])


def test_a_busy_input_takes_its_noise_from_its_steady_lead():
    """A 1.5 Hz, 2 deg input sampled at 10 Hz moves its second differences far more than 0.1 deg
    of noise does: their spread reads 0.64-0.68 deg over seeds (on the identification plan's
    elevator multisine 0.17, and a replay within 4 of that was 0.25 deg RMS off the input, 0.13
    now). The ten samples of the steady lead before it read 0.07-0.17."""
    from jsbsim_calib.data.timehistory import input_noise, noise_sigma
    rng = np.random.default_rng(4)
    t = np.arange(300) / 10.0
    x = np.where(t >= 1.0, 2.0 * np.sin(2 * np.pi * 1.5 * (t - 1.0)), 0.0) + rng.normal(0.0, 0.1, t.size)
    assert noise_sigma(x) > 0.5 and 0.05 < input_noise(x, 10) < 0.2
    assert input_noise(x, 3) == 0.0                 # too short a lead to tell: flown as recorded


@pytest.mark.parametrize("stem", ["S.13", "S.18"])
def test_a_model_replaying_its_own_record_with_pilot_loops_flies_it_again(c172, stem):
    """The Level 5 spiral (bank held 1-15 s, then released; altitude held until then) and flap
    change (altitude held), noise-free: replayed with the record's loops, the committed C172
    flies its record again. While a loop flies an axis its recorded surface is the pilot's
    output; when the replay fed it under the loop too (the correction twice), the flap
    change's pitch was 1.8 deg off and the spiral's 0.6."""
    from jsbsim_calib.synthetic.maneuvers import fly_plan, load_plan
    plan = load_plan("level5")
    th = fly_plan(c172, replace(plan, maneuvers=tuple(m for m in plan.maneuvers if m.id == stem)), noise=0.0)[0]
    m = maneuver_from_time_history(th, c172.geometry, th.meta.pilot)
    flown = fly(c172, m).at(th.time_s - th.time_s[0])
    for ch in ("pitch_deg", "roll_deg"):
        err = np.max(np.abs(flown[ch] - th.channel(ch)))
        assert err < 0.02, f"{stem} {ch}: {err:.3f} deg"


def test_pilot_windows_round_trip_into_the_replays_holds_and_bad_windows_are_named():
    """A sidecar keeps the pilot's targets and windows; the replay flies them; a bad window is
    refused by its key."""
    from jsbsim_calib.data.timehistory import _holds, pilot_windows
    from jsbsim_calib.core.errors import InputError
    from jsbsim_calib.jsbsim.trajectory import Hold
    holds = (Hold("altitude"), Hold("bank", 30.0, 1.0, 15.0))
    doc = pilot_windows(holds)
    assert doc == {"pitch": "altitude", "roll": [{"loop": "bank", "target": 30.0, "start_s": 1.0, "end_s": 15.0}]}
    assert _holds(doc, "x") == holds
    with pytest.raises(InputError, match=r"pilot.roll\[0\].*start_s < end_s"):
        _holds({"roll": [{"loop": "bank", "start_s": 5.0, "end_s": 2.0}]}, "x")
    with pytest.raises(InputError, match="not a loop of the roll axis"):
        _holds({"roll": [{"loop": "pitch"}]}, "x")
