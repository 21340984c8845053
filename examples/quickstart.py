"""Quickstart: generate the SR20, calibrate it to its POH (a short stage 1), evaluate and plot,
all in a temporary copy of the repository's JSBSim root (the repository is not written).

    python examples/quickstart.py [OUT_DIR]        # OUT_DIR: where the plot goes (default: the temp root)
"""
import shutil, sys, tempfile
from pathlib import Path

from jsbsim_calib.evaluation.evaluate import evaluate_dataset
from jsbsim_calib.generate import generate
from jsbsim_calib.jsbsim.product import write_calibrated
from jsbsim_calib.jsbsim.simulator import Simulator
from jsbsim_calib.report.plots import climb_vs_altitude, save
from jsbsim_calib.report.text import evaluation_table
from jsbsim_calib.calibration.workflow import load_data_for, run_steady

REPO = Path(__file__).resolve().parents[1]
root = Path(tempfile.mkdtemp(prefix="jsbsim-calib-quickstart-"))
for d in ("aircraft/sr20", "engine", "airfoils", "data"):               # a JSBSim root of our own
    shutil.copytree(REPO / d, root / d, ignore=shutil.ignore_patterns("backup"))

generate("sr20", root, baseline=True)                                    # geometry.toml -> JSBSim XML, neutral factors
stage1 = run_steady(root, "sr20", max_nfev=5)                            # stage 1 on the POH, 5 evaluations: a quick look
write_calibrated(root, "sr20", stage1.factors, "steady", stage1.summary())
with Simulator(root, "sr20") as sim:                                     # the calibrated aircraft, as JSBSim flies it
    climb = evaluate_dataset(sim, load_data_for(sim, root / "data" / "sr20_poh_climb.csv"))
print(evaluation_table(climb))
out = Path(sys.argv[1]) if len(sys.argv) > 1 else root
save(climb_vs_altitude({"baseline": stage1.baseline["poh_climb"], "calibrated": climb}), out / "sr20_climb.png")
print(f"plot: {out / 'sr20_climb.png'}")
