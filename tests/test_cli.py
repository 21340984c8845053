"""The command line's grammar (issue 26): global options before or after the command, --version,
a default stage, --max-nfev checked by the parser, one set of verdict words, the fleet folder,
no report written into the repository unasked, and any JSBSim aircraft by name. Real JSBSim where
something flies; the parser alone where nothing does."""
from __future__ import annotations

import json
import math
from pathlib import Path

import jsbsim
import pytest

from jsbsim_calib import __version__
from jsbsim_calib.cli import EXIT_TARGETS_MISSED, _verdict_exit, build_parser, main, path_problems
from jsbsim_calib.report.verdicts import TARGETS, Verdict, format_verdicts, lost_targets

REPO = Path(__file__).resolve().parents[1]
POH_CLIMB = REPO / "data" / "c172_poh_climb.csv"


def parse(*argv):
    return build_parser().parse_args(list(argv))


def test_global_options_after_the_command():
    a = parse("evaluate", "c172", "--data", "d.csv", "--workers", "1", "--root", "R", "--quiet", "--executor", "serial")
    assert (a.workers, a.root, a.quiet, a.executor) == (1, "R", True, "serial")


def test_global_options_before_the_command_are_not_clobbered_by_defaults():
    a = parse("--root", "R", "--workers", "3", "--scheduler", "tcp://h:1", "calibrate", "c172")
    assert (a.root, a.workers, a.scheduler, a.executor, a.quiet) == ("R", 3, "tcp://h:1", "process", False)
    b = parse("--root", "R", "check", "c172", "--root", "S")        # after the command wins
    assert b.root == "S"


def test_version(capsys):
    with pytest.raises(SystemExit) as e:
        main(["--version"])
    assert e.value.code == 0 and capsys.readouterr().out.strip() == f"jsbsim-calib {__version__}"


def test_calibrate_defaults_to_the_main_job_and_takes_json_and_exit_zero():
    a = parse("calibrate", "c172")
    assert (a.stage, a.json, a.exit_zero) == ("all", None, False)
    assert parse("part60", "c172", "--flight-test", "data", "--json", "x.json", "--exit-zero").exit_zero


@pytest.mark.parametrize("command", [["validate", "c172"], ["slipstream", "c172"]])
@pytest.mark.parametrize("value", ["0", "-3", "many"])
def test_max_nfev_below_one_is_a_clear_error(command, value, capsys):
    with pytest.raises(SystemExit) as e:
        main(command + ["--max-nfev", value])
    err = capsys.readouterr().err
    assert e.value.code == 2 and "argument --max-nfev" in err and "Traceback" not in err


def test_one_set_of_verdict_words_and_a_nan_fails():
    target = next(t for t in TARGETS if t.statistic == "rmse")
    text = format_verdicts([Verdict(target, 1e9), Verdict(target, math.nan), Verdict(target, 0.0)], "test model")
    assert text.count("FAIL") == 2 and text.count("PASS") == 1 and "MISS" not in text
    assert Verdict(target, math.nan).to_json()["measured"] is None


def test_the_guard_names_a_target_an_earlier_stage_met_and_the_chain_lost():
    """Issue 24's guard: the console table shows each metric after every stage, and a target met
    after an earlier stage and missed at the end (a NaN at the end included) is named with that
    stage; one no stage met, or one the last stage does not judge, is not."""
    climb, rpm, power, pitch = (next(t for t in TARGETS if (t.kind, t.metric, t.statistic) == k) for k in (
        ("poh_climb", "roc_fpm", "rmse"), ("poh_cruise", "rpm", "rmse"), ("poh_cruise", "pct_power", "rmse"),
        ("snapshot", "pitch_deg", "within_pct")))
    s1 = [Verdict(climb, 16.8), Verdict(rpm, 9.5), Verdict(power, 1.3)]
    s2a = [Verdict(climb, 17.5), Verdict(rpm, 11.0), Verdict(power, 1.2), Verdict(pitch, 96.0)]
    end = [Verdict(climb, math.nan), Verdict(rpm, 10.9), Verdict(power, 0.99)]
    lost = lost_targets([("stage 1", s1), ("stage 2a", s2a), ("stage 2b", end)])
    assert [(v.target, stage) for v, stage in lost] == [(climb, "stage 2a"), (rpm, "stage 1")]
    text = format_verdicts(end, "test model", [("stage 1", s1), ("stage 2a", s2a)])
    assert "after stage 1" in text and "after stage 2a" in text and "16.80" in text and "17.50" in text
    assert "guard: poh_climb roc_fpm RMSE <= 20 was met after stage 2a and is missed at the end" in text
    assert "poh_cruise rpm RMSE <= 10 was met after stage 1" in text and "pct_power" not in text.split("guard:")[1]
    assert lost_targets([("stage 1", s1)]) == [] and lost_targets([]) == []


def test_evaluate_takes_a_folder_of_logs():
    assert path_problems(parse("--root", str(REPO), "evaluate", "c172", "--data", str(REPO / "data" / "g1000"))) == []


def test_fleet_folder_evaluates(tmp_path, capsys):
    out = tmp_path / "fleet.json"
    assert main(["--root", str(REPO), "evaluate", "c172", "--data", str(REPO / "data" / "g1000"), "--quiet",
                 "--executor", "serial", "--json", str(out)]) == 0
    assert "fleet (1 logs)" in capsys.readouterr().out and out.is_file()


def test_evaluate_writes_no_report_unless_asked(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    assert main(["--root", str(REPO), "evaluate", "c172", "--data", str(POH_CLIMB), "--executor", "serial"]) == 0
    out = capsys.readouterr().out
    assert "report: not written" in out and "Verdicts of the c172 model" in out and "PASS" in out
    assert list(tmp_path.iterdir()) == []
    assert main(["--root", str(REPO), "evaluate", "c172", "--data", str(POH_CLIMB), "--executor", "serial",
                 "--report-dir", str(tmp_path)]) == 0
    assert (tmp_path / "c172").is_dir()


def test_any_jsbsim_aircraft_by_name(capsys):
    """`jsbsim-calib --root JSBSIM_ROOT evaluate c172p --data POH`: no geometry.toml, the adapter
    flies the stock file and says what it cannot know; the figures as with --foreign-root."""
    root = jsbsim.get_default_root_dir()
    assert main(["--root", str(root), "evaluate", "c172p", "--data", str(POH_CLIMB), "--executor", "serial"]) == 0
    out, err = capsys.readouterr()
    assert "does not state a maximum weight" in err
    assert "Verdicts of the c172p model" in out and "FAIL" in out          # the stock c172p: 178 fpm RMSE
    assert main(["--root", str(root), "check", "c172p", "--executor", "serial"]) == 0
    assert "stall: no steady glide below" in capsys.readouterr().out


def test_check_words_the_stall_as_the_end_of_the_envelope(tmp_path, capsys):
    out = tmp_path / "check.json"
    assert main(["--root", str(REPO), "--executor", "serial", "check", "c172", "--json", str(out)]) == 0
    text = capsys.readouterr().out
    stall = text[text.index("Stall"):]
    assert "trim failed" not in stall and "no equilibrium" not in stall and "expected end of the envelope" in stall
    assert json.loads(out.read_text())


def test_exit_code_for_missed_targets_is_documented():
    assert EXIT_TARGETS_MISSED == 3 and "3" in build_parser().epilog


def test_exit_zero_turns_missed_targets_into_success():
    """`--exit-zero`: a run with missed targets exits 0 (the main job's test checks the JSON and
    exit code 3 of a real run: tests/test_reproducible.py)."""
    argv = ["calibrate", "c172", "--json", "x.json"]
    assert _verdict_exit(parse(*argv), 2) == EXIT_TARGETS_MISSED and _verdict_exit(parse(*argv), 0) == 0
    assert _verdict_exit(parse(*argv, "--exit-zero"), 2) == 0


def test_synth_takes_an_aircraft_name_as_every_command_does_and_still_a_folder(tmp_path, capsys):
    """`synth --truth c172` (an aircraft of --root) flies the same truth as `--truth aircraft/c172`
    (a folder): the same snapshots; a name that is neither is a clear error."""
    by_name, by_folder = tmp_path / "name.csv", tmp_path / "folder.csv"
    common = ["--root", str(REPO), "--quiet", "--executor", "serial", "synth", "--points", "2", "--seed", "3"]
    assert main(common + ["--truth", "c172", "--out", str(by_name)]) == 0
    assert main(common + ["--truth", str(REPO / "aircraft" / "c172"), "--out", str(by_folder)]) == 0
    assert by_name.read_bytes() == by_folder.read_bytes() and len(by_name.read_text().splitlines()) > 1
    capsys.readouterr()
    assert main(common + ["--truth", "nosuch", "--out", str(tmp_path / "x.csv")]) == 2
    assert "--truth" in capsys.readouterr().err
