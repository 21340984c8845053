"""Any JSBSim aircraft through the adapter: the stock c172p of the jsbsim package on the C172 POH,
and the adapter against the workbench's own simulator on a generated aircraft."""
import hashlib
import math
import pickle
from pathlib import Path

import jsbsim
import pytest

from jsbsim_calib.cli import main
from jsbsim_calib.data.load import load_dataset
from jsbsim_calib.evaluation.evaluate import evaluate_dataset
from jsbsim_calib.flight.condition import Condition
from jsbsim_calib.jsbsim.foreign import ForeignSimulator, conventions_like, foreign_simulator, read_foreign
from jsbsim_calib.jsbsim.product import load_aircraft_geometry
from jsbsim_calib.jsbsim.simulator import Simulator

REPO = Path(__file__).resolve().parents[1]
STOCK = Path(jsbsim.get_default_root_dir())


def digest(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def test_reads_what_the_trims_need_from_the_stock_c172p():
    ac = read_foreign(STOCK, "c172p")
    assert ac.empty_weight_lb == 1500 and ac.empty_cg_in == (41.0, 0.0, 36.5)
    assert [p.weight_lb for p in ac.point_masses] == [180, 0, 0, 0, 0]
    assert [t.capacity_lb for t in ac.tanks] == [185, 185] and ac.fuel_share == pytest.approx(200 / 370)
    assert ac.engine.max_hp == 160 and not ac.propeller.constant_speed and ac.propeller.diameter_in == 75
    assert ac.flap_max_deg == 30 and ac.surface_ranges_deg["elevator"] == (-28, 23)
    assert ac.wing_area_ft2 == 174


def test_stock_c172p_on_the_c172_poh_in_a_sandbox(capsys):
    before = digest(STOCK / "aircraft" / "c172p" / "c172p.xml")
    with foreign_simulator(REPO, "c172", STOCK, "c172p") as sim:
        box = sim.sandbox
        summaries = {d: evaluate_dataset(sim, load_dataset(REPO / "data" / f"c172_poh_{d}.csv")).summary()
                     for d in ("climb", "cruise")}
        # a snapshot's CG is reached with point mass 0, in the file's stations
        t = sim.trim(Condition(pressure_alt_ft=4000, weight_lb=2300, ktas=100, cg_in=44.0, flaps_deg=10))
        assert t.trimmed and sim.fdm["inertia/cg-x-in"] == pytest.approx(44.0, abs=1e-6)
        assert sim.fdm["inertia/weight-lbs"] == pytest.approx(2300, abs=1e-6) and sim.fdm["fcs/flap-pos-deg"] == pytest.approx(10)
    assert not box.exists() and digest(STOCK / "aircraft" / "c172p" / "c172p.xml") == before
    climb, cruise = summaries["climb"]["roc_fpm"], summaries["cruise"]
    assert climb.failed == 0 and climb.rmse == pytest.approx(178.5, abs=0.5)       # README's table
    assert cruise["rpm"].rmse == pytest.approx(67.2, abs=0.5) and cruise["gph"].within_pct == pytest.approx(8.1, abs=0.1)
    # the command line: check on the stock aircraft (one CG: the file's)
    assert main(["--root", str(REPO), "check", "c172", "--foreign-root", "jsbsim", "--foreign-aircraft", "c172p"]) == 0
    out = capsys.readouterr().out
    assert "c172p" in out and out.count("  2550 ") == 2 and "cruise " in out


def test_adapter_flies_a_generated_constant_speed_aircraft_as_the_workbench_does():
    """The SR20 (governed propeller) read through its XML alone trims to the workbench's own values."""
    geom = load_aircraft_geometry(REPO, "sr20")
    conv = conventions_like(geom, poh_cg_in=geom.operations.poh_cg_m / 0.0254)
    ds = load_dataset(REPO / "data" / "sr20_poh_cruise.csv")
    with Simulator(REPO, "sr20") as own, ForeignSimulator(REPO, "sr20", conv) as foreign:
        assert foreign.geometry.propeller.constant_speed and foreign.aircraft.propeller.max_rpm == 2700
        a, b = evaluate_dataset(own, ds), evaluate_dataset(foreign, ds)
    for p, q in zip(a.points, b.points):
        assert p.trimmed == q.trimmed
        for m, v in p.model.items():
            assert math.isclose(v, q.model[m], rel_tol=1e-6, abs_tol=1e-6), (p.index, m, v, q.model[m])


def test_foreign_aircraft_pickles_refuses_factors_and_unknown_engines(tmp_path):
    cond = Condition(pressure_alt_ft=3000, weight_lb=2300, ktas=100)
    with ForeignSimulator(STOCK, "c172x") as sim:
        with pytest.raises(Exception, match="no calibration factors"):
            sim.set_factors(sim.factors.updated({"K_cd0_slope": 1.1}))
        copy = pickle.loads(pickle.dumps(sim))          # as an executor sends it
        try:
            assert copy.sandbox != sim.sandbox and copy.trim(cond).rpm == sim.trim(cond).rpm
        finally:
            copy.close()
    with pytest.raises(Exception, match="piston engines with a propeller only|engines"):
        read_foreign(STOCK, "737")
