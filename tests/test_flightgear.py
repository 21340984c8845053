"""The exported aircraft flown in FlightGear against the same 60 s in JSBSim's runner.

Marked ``flightgear`` and skipped ("fgfs not installed") where FlightGear is not installed
(CI does not install it): ``apt-get install -y flightgear xvfb``. Both flights hold the
trimmed cruise of ``scripts/c172_cruise.xml`` (5,500 ft, 110 KTAS) with the controls fixed;
FlightGear starts at the runner's trimmed state and trims with its own copy of JSBSim.

Tolerances: altitude +-100 ft and airspeed +-3 kt (FAA Part 60 trim tolerances), RPM +-50
(the POH comparison's tolerance).
"""
import pytest

from jsbsim_calib.export.fgfs import compare, find_fgfs, fly_flightgear, runner_cruise
from jsbsim_calib.export.flightgear import export_flightgear

ALTITUDE_TOL_FT = 100.0
KTAS_TOL = 3.0
RPM_TOL = 50.0



def test_export_is_a_flightgear_aircraft_folder_with_the_product_byte_for_byte(repo, tmp_path):
    from lxml import etree
    from jsbsim_calib.cli import main
    out = tmp_path / "aircraft" / "c172"
    assert main(["--root", str(repo), "export", "flightgear", "c172", "--out", str(out)]) == 0
    assert (out / "c172.xml").read_bytes() == (repo / "aircraft" / "c172" / "c172.xml").read_bytes()
    for f in ("c172_engine.xml", "c172_propeller.xml"):
        assert (out / "Engines" / f).read_bytes() == (repo / "engine" / f).read_bytes()
    sim = etree.parse(str(out / "c172-set.xml")).getroot().find("sim")
    assert sim.findtext("flight-model") == "jsb" and sim.findtext("aero") == "c172"
    assert (out / sim.findtext("model/path")).is_file() and "--fg-aircraft" in (out / "README.md").read_text()


@pytest.mark.flightgear
@pytest.mark.skipif(find_fgfs() is None, reason="fgfs not installed")
def test_flightgear_flies_the_runners_cruise(repo, tmp_path):
    export = export_flightgear(repo, "c172", tmp_path / "aircraft" / "c172")
    runner, start = runner_cruise(repo, "c172", tmp_path)
    flight = fly_flightgear(export.folder, "c172", start, 60.0, log_path=tmp_path / "fgfs.log")
    agreement = compare(flight.samples, runner, 60.0)
    print(f"\nFlightGear vs JSBSim's runner, 60 s of cruise at 5500 ft, 110 KTAS: largest differences "
          f"altitude {agreement.altitude_ft:.1f} ft, airspeed {agreement.ktas:.2f} kt, RPM {agreement.rpm:.1f} "
          f"({agreement.samples} samples); trimmed throttle FlightGear {flight.throttle:.4f} (mixture "
          f"{flight.mixture:.2f}), runner {start.throttle:.4f} (mixture {start.mixture:.2f}); FlightGear wall time {flight.wall_time_s:.0f} s")
    assert flight.samples[-1].time_s >= 60.0
    assert agreement.within(ALTITUDE_TOL_FT, KTAS_TOL, RPM_TOL), agreement
