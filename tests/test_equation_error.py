"""Equation error on recorded maneuvers (jsbsim_calib.calibration.equation_error), real JSBSim:
the model's own maneuvers leave almost no error, and a truth whose pitch inertia is 1.6 times
the model's is ranked first as that inertia, with its size, on the pitch axis; the close-loop
screen names it a finalist. Noise-free synthetic records of the packaged Level 5 plan's pitch
maneuvers (a pulse and a phugoid), cheap enough for the fast tier."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from jsbsim_calib.calibration.equation_error import EE_AXES, equation_error, inertia_columns, rank
from jsbsim_calib.evaluation.evaluate_dynamic import load_recorded_tests
from jsbsim_calib.jsbsim.aircraft import moment_of_inertia, set_moment_of_inertia
from jsbsim_calib.jsbsim.simulator import Simulator
from jsbsim_calib.jsbsim.xml import read, write
from jsbsim_calib.synthetic.maneuvers import Plan, load_plan, synthesize_maneuvers
from jsbsim_calib.synthetic.truth import root_copy, truth_copy

REPO = Path(__file__).resolve().parents[1]
PITCH_TESTS = ("S.06", "S.07")           # phugoid, pitch pulse


def _records(truth_dir: Path, root: Path, out: Path) -> list:
    plan = load_plan("level5")
    plan = Plan(**{**plan.__dict__, "maneuvers": tuple(m for m in plan.maneuvers if m.id in PITCH_TESTS)})
    with Simulator.from_dir(truth_dir, root) as truth:
        synthesize_maneuvers(truth, plan, out, seed=1, noise=0.0)
    return load_recorded_tests(out)


@pytest.fixture(scope="module")
def heavy_pitch(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("ee")
    root = root_copy(REPO, tmp / "root", folders=("aircraft", "engine", "airfoils", "data"))
    truth = truth_copy(REPO / "aircraft" / "c172", tmp / "truth" / "c172", root=root)
    t = read(truth / "c172.xml")
    set_moment_of_inertia(t, "iyy", 1.6 * moment_of_inertia(t, "iyy"))
    write(t, truth / "c172.xml")
    return _records(truth, root, tmp / "data"), _records(REPO / "aircraft" / "c172", REPO, tmp / "own")


def test_the_models_own_maneuvers_leave_little_error_and_a_heavier_pitch_inertia_ranks_first(heavy_pitch):
    heavy, own = heavy_pitch
    with Simulator(REPO, "c172") as sim:
        clean = equation_error(sim, own, inertia_columns())
        lin = equation_error(sim, heavy, inertia_columns())
    pitch = np.array(lin.metric) == "PITCH"
    rms_own = float(np.sqrt(np.mean(clean.residual[np.array(clean.metric) == "PITCH"] ** 2)))
    rms_heavy = float(np.sqrt(np.mean(lin.residual[pitch] ** 2)))
    assert np.isfinite(rms_own) and rms_own < 0.5 * rms_heavy, (rms_own, rms_heavy)
    assert set(lin.metric) <= set(EE_AXES)
    top = rank(lin)[0]
    assert (top.kind, top.target) == ("inertia", "iyy"), rank(lin)[:3]
    assert top.estimate[0] == pytest.approx(0.6, rel=0.15)
