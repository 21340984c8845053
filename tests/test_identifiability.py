"""Issue 28, item 2: the identifiability table of the calibration reports, on a real fit."""
import math

import numpy as np
import pytest

from jsbsim_calib.calibration.fit import FitResult, fit, residual_group
from jsbsim_calib.calibration.points import PointSet, point_residuals
from jsbsim_calib.data.load import load_dataset
from jsbsim_calib.factors import FactorSet
from jsbsim_calib.jsbsim.simulator import Simulator
from jsbsim_calib.report.identifiability import identifiability_section


def test_residual_groups_drop_the_row_and_keep_the_quantity():
    assert residual_group("poh_cruise[12].gph") == "poh_cruise.gph"
    assert residual_group("snapshot[3].throttle>1") == "snapshot.throttle>1"
    assert residual_group("C.19 q_peak") == "C.19 q_peak"
    assert residual_group("prior K_FF") == "prior"


@pytest.fixture(scope="module")
def fuel_and_pitch_damping(repo):
    """K_FF (fuel flow sets it) and K_Cmq (no steady cruise point feels pitch damping) fitted
    together on five POH cruise points, with the fit's prior."""
    with Simulator(repo, "c172") as sim:
        cruise = load_dataset(repo / "data" / "c172_poh_cruise.csv")
        ps = PointSet.from_dataset(cruise, sim, [0, 8, 18, 29, 36], metrics=("gph",))

        def residuals(fs):
            sim.set_factors(fs)
            r, lab, _ = point_residuals(sim, ps, ("gph",))
            return np.array(r), lab

        yield fit("fuel", ["K_FF", "K_Cmq"], sim.factors, residuals, sim=sim, max_nfev=40, legs=((1.0, 0.02),))


def test_the_data_carry_a_determined_factor_and_the_prior_an_untouched_one(fuel_and_pitch_damping):
    res = fuel_and_pitch_damping
    ff, cmq = dict(res.information["K_FF"]), dict(res.information["K_Cmq"])
    assert ff["poh_cruise.gph"] > 0.9 and math.isclose(sum(ff.values()), 1.0, rel_tol=1e-12)
    assert cmq.get("poh_cruise.gph", 0.0) < 1e-6 and cmq["prior"] > 0.999
    assert res.determination("K_FF") == "determined"
    assert res.determination("K_Cmq").startswith(("held by the prior", "not identified"))
    table = identifiability_section([res])
    row = next(line for line in table if line.startswith("| fuel | K_FF |"))
    assert "poh_cruise.gph" in row and row.endswith("| determined |")
    assert any("K_Cmq (fuel: " in line for line in table if line.startswith("Not determined"))


def test_a_nan_standard_error_is_never_determined(fuel_and_pitch_damping):
    res = fuel_and_pitch_damping
    bad = FitResult(**{**res.__dict__, "stderr": {**res.stderr, "K_FF": float("nan")}})
    assert bad.determination("K_FF") == "not identified"
    row = next(line for line in identifiability_section([bad]) if "| K_FF |" in line)
    assert "nan" not in row.lower() and row.endswith("| not identified |")
