"""What a long command shows while it runs (issue 26): on a terminal a step counter with the
elapsed time and an estimate of the time left, one line per step finished and none per
iteration; --verbose every line; --log-file everything; nothing on a pipe. Where a stage
starts when it runs alone (the same command, the same product), and its plan."""
from __future__ import annotations

import io
import sys
from pathlib import Path

from jsbsim_calib.calibration.fit import WorkLine
from jsbsim_calib.calibration.workflow import recorded_start, stage_plan
from jsbsim_calib.cli import main
from jsbsim_calib.factors import REGISTRY, FactorSet, set_in, switches
from jsbsim_calib.jsbsim.aircraft import read_factors
from jsbsim_calib.jsbsim.product import AircraftPaths, read_calibration, read_calibration_record, rounded
from jsbsim_calib.report.progress import PlanStep, Progress

REPO = Path(__file__).resolve().parents[1]
POH_CLIMB = REPO / "data" / "c172_poh_climb.csv"


class Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def _fit_lines(task: str, n: int, trims_each: int) -> list[WorkLine]:
    return [WorkLine(f"{task}: iteration {i:3d}  cost {2.731:10.4g}  trims {i * trims_each:6d}", task, i * trims_each)
            for i in range(1, n + 1)]


def test_a_terminal_gets_a_counter_an_estimate_and_a_line_per_step_not_per_iteration():
    term = Terminal()
    plan = [PlanStep("steady", "stage 1 steady", 100), PlanStep("steady refit", "stage 2a steady refit", 300)]
    with Progress(plan, live=True, stream=term) as p:
        p("baseline: trimming 60 POH points")
        for line in _fit_lines("steady", 5, 20):
            p(line)
        assert p.bar.n == 100
        for line in _fit_lines("steady refit", 30, 5):          # 30 identical costs: one status line
            p(line)
        assert p.bar.n == 100 + 150 and p.bar.total == 400
        p("stage 2a model: trimming 60 POH points")               # another task: the step is done
        assert p.bar.n == 400 and "steady refit: done in" in term.getvalue()
    out = term.getvalue()
    lines = out.split("\n")
    assert not [ln for ln in lines if "iteration" in ln.split("\r")[-1]], "a line per iteration"
    assert "[1/2] stage 1 steady: done in" in out and out.count("[2/2] stage 2a steady refit: done in") == 1
    assert "elapsed" in out and "left" in out and "[2/2] stage 2a steady refit" in out


def test_without_a_record_the_counter_counts_steps():
    term = Terminal()
    with Progress([PlanStep("pitch"), PlanStep("control")], live=True, stream=term) as p:
        p("pitch: start cost 47 with 12 residuals, 3 factors")
        p("control: start cost 79 with 30 residuals, 6 factors")
        assert (p.bar.n, p.bar.total) == (1, 2)


def test_a_command_without_a_plan_shows_the_time_and_its_activity():
    term = Terminal()
    with Progress((), live=True, stream=term) as p:
        p("flying 10 dynamic tests")
    assert "elapsed, flying 10 dynamic tests" in term.getvalue() and "%" not in term.getvalue()


def test_what_the_command_prints_goes_above_the_status_line(monkeypatch):
    term = Terminal()
    monkeypatch.setattr(sys, "stdout", term)
    monkeypatch.setattr(sys, "stderr", term)
    with Progress([PlanStep("steady")], live=True, stream=term, hold_stdout=True) as p:
        p("steady: iteration 1")
        print("[[Fit: steady]]")
        print("a line", end="")
        print(" continued")
    assert sys.stdout is term and sys.stderr is term
    out = term.getvalue()
    assert "\r[[Fit: steady]]\n" in out and "\ra line continued\n" in out          # on a cleared line each


def test_a_pipe_gets_nothing_verbose_every_line_and_the_log_everything():
    pipe, log = io.StringIO(), io.StringIO()
    lines = _fit_lines("steady", 3, 10)
    with Progress([PlanStep("steady")], live=False, stream=pipe, log=log) as p:
        for line in lines:
            p(line)
    assert pipe.getvalue() == "" and log.getvalue().count("steady: iteration") == 3
    verbose = io.StringIO()
    with Progress((), live=False, verbose=True, stream=verbose) as p:
        for line in lines:
            p(line)
    assert [ln.split("] ", 1)[1] for ln in verbose.getvalue().splitlines()] == lines
    assert all(ln.startswith("[") and " s] " in ln for ln in verbose.getvalue().splitlines())


def test_log_file_holds_what_the_command_prints(tmp_path, capsys):
    log = tmp_path / "run.log"
    assert main(["--root", str(REPO), "--executor", "serial", "evaluate", "c172", "--data", str(POH_CLIMB),
                 "--log-file", str(log)]) == 0
    out, err = capsys.readouterr()
    assert "Verdicts of the c172 model" in out and "Verdicts of the c172 model" in log.read_text()
    assert err == ""                        # not a terminal: no progress display
    assert main(["--root", str(REPO), "evaluate", "c172", "--data", str(POH_CLIMB),
                 "--log-file", str(tmp_path / "no" / "run.log")]) == 2
    assert "--log-file" in capsys.readouterr().err


def test_a_stage_alone_starts_from_what_the_earlier_stages_recorded():
    """calibrate --stage trims / dynamic: stage 1's (and 2a's) factors as calibration.json
    records their fits, the model switches as the aircraft file sets them, the stage's own
    factors neutral; the committed c172 (the main job's
    product) is that start plus stage 2b's fitted factors, so the start is the main job's."""
    paths = AircraftPaths(REPO, "c172")
    record, declared = read_calibration_record(paths), read_factors(paths.aircraft_xml)
    committed = read_calibration(paths)
    trims, text = recorded_start(record, declared, "trims")
    assert "the factors stage 1 wrote (calibration.json), every other factor neutral" in text
    for n in REGISTRY:
        fitted = n in set_in(("steady", "fuel flow"))
        want = (record["stages"]["steady"]["fit"]["factors"].get(n) or record["stages"]["steady"]["fuel_flow"]
                ["factors"].get(n) or {}).get("final") if fitted else switches(declared)[n]
        assert trims[n] == want, n
    dynamic, text = recorded_start(record, declared, "dynamic")
    assert "stage 1 and stage 2a wrote" in text
    set_by_2b = {n for s in record["stages"]["dynamic"]["steps"] for n in s["factors"]}
    before_2b = {n for s in record["stages"]["trims"]["steps"] for n in s["factors"]}
    before_2b |= set(set_in(("steady", "fuel flow")))
    first_in_2b = set_by_2b - before_2b                       # K_Clp, K_Cmq, K_Cnr (2b refits K_da_slope ...)
    assert first_in_2b and all(dynamic[n] == FactorSet()[n] for n in first_in_2b)
    assert {n: v for n, v in rounded(dynamic).items() if n not in set_by_2b} == \
        {n: v for n, v in committed.items() if n not in set_by_2b}
    again, _ = recorded_start(record, declared, "dynamic")
    assert again.as_dict() == dynamic.as_dict()
    neutral, text = recorded_start({}, declared, "dynamic")
    assert neutral.as_dict() == switches(declared).as_dict() and "neutral factors" in text


def test_the_plan_of_the_main_job_lists_the_fits_with_their_last_trims():
    plan = stage_plan(REPO, "c172", ("steady", "trims", "dynamic"))
    fits = [f for _, f, _ in plan]
    assert fits[:7] == ["steady", "fuel flow", "pitch", "control", "pfactor", "flaps", "steady refit"]
    assert all(isinstance(t, int) and t > 0 for _, _, t in plan)
    assert [s for s, _, _ in stage_plan(REPO, "sr20", ("steady", "trims", "dynamic"))] == ["steady", "steady"]
