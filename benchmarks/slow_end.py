"""The slow end of the envelope (issue 24): full-throttle climbs of the committed C172 at sea
level, 2,550 lb, wings level, from 60 to 85 KIAS, against the POH's best-angle (62 KIAS) and
best-rate (74 KIAS) speeds.

    python benchmarks/slow_end.py [--root .] [--aircraft c172]

For each indicated speed (KCAS from the aircraft's airspeed calibration): whether JSBSim trims
it, the rate of climb, the rudder (JSBSim's sign: - trailing edge right) and the flight-path
angle; then the lowest speed that trims, the best-rate speed and the steepest climb among the
trimmed ones. Real JSBSim; a few seconds.
"""
from __future__ import annotations

import argparse
from pathlib import Path

from jsbsim_calib.flight.condition import Condition
from jsbsim_calib.jsbsim.product import load_aircraft_geometry
from jsbsim_calib.jsbsim.simulator import Simulator
from jsbsim_calib.physics.atmosphere import kcas_from_kias

SPEEDS_KIAS = range(60, 86)
WEIGHT_LB, PRESSURE_ALT_FT = 2550.0, 0.0
POH_BEST_ANGLE, POH_BEST_RATE = 62, 74


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--root", type=Path, default=Path(__file__).resolve().parents[1])
    ap.add_argument("--aircraft", default="c172")
    a = ap.parse_args()
    table = load_aircraft_geometry(a.root, a.aircraft).operations.airspeed_calibration
    rows = []
    with Simulator(a.root, a.aircraft) as sim:
        for kias in SPEEDS_KIAS:
            sim.fresh()
            sim.trim_cache = {}
            r = sim.trim(Condition(pressure_alt_ft=PRESSURE_ALT_FT, weight_lb=WEIGHT_LB,
                                   kcas=float(kcas_from_kias(float(kias), table)), mode="full_throttle",
                                   mixture="climb"))
            rows.append((kias, r))
            print(f"{kias:3d} KIAS  {'trimmed' if r.trimmed else 'NO TRIM'}  rate of climb {r.roc_fpm:6.0f} fpm  "
                  f"rudder {r.rudder_deg:6.2f} deg  flight path {r.gamma_deg:5.2f} deg"
                  + ("" if r.trimmed else f"  ({r.reason})"))
    ok = [(k, r) for k, r in rows if r.trimmed]
    if not ok:
        print("no speed trims")
        return
    rate = max(ok, key=lambda kr: kr[1].roc_fpm)
    angle = max(ok, key=lambda kr: kr[1].gamma_deg)
    print(f"lowest trimmed speed {ok[0][0]} KIAS; best rate {rate[0]} KIAS ({rate[1].roc_fpm:.0f} fpm; POH "
          f"{POH_BEST_RATE}); steepest {angle[0]} KIAS ({angle[1].gamma_deg:.2f} deg; POH best angle {POH_BEST_ANGLE})")


if __name__ == "__main__":
    main()
