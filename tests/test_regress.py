"""regress: a hand edit that changes the model is listed point by point; one that does not is silent."""
import re
import shutil
from pathlib import Path

import pytest

from jsbsim_calib.cli import main
from jsbsim_calib.evaluation.regress import regress, write_baseline

REPO = Path(__file__).resolve().parents[1]
FACTOR = "calibration/K_cd0_slope"


@pytest.fixture
def root(tmp_path) -> Path:
    """A JSBSim root with a copy of the C172 (aircraft folder, its engine files, the data)."""
    (tmp_path / "engine").mkdir()
    shutil.copytree(REPO / "aircraft" / "c172", tmp_path / "aircraft" / "c172")
    for f in ("c172_engine.xml", "c172_propeller.xml"):
        shutil.copy(REPO / "engine" / f, tmp_path / "engine" / f)
    shutil.copytree(REPO / "data", tmp_path / "data")
    (tmp_path / "airfoils").symlink_to(REPO / "airfoils", target_is_directory=True)
    return tmp_path


def edit(root: Path, change) -> None:
    path = root / "aircraft" / "c172" / "c172.xml"
    path.write_text(change(path.read_text()))


def scale_factor(text: str, k: float) -> str:
    pattern = re.compile(r'(<property value=")([-0-9.]+)("[^>]*>\s*' + re.escape(FACTOR) + r"\s*</property>)")
    assert len(pattern.findall(text)) == 1
    return pattern.sub(lambda m: f"{m.group(1)}{float(m.group(2)) * k:.10f}{m.group(3)}", text)


def test_baseline_holds_every_data_file_and_a_comment_edit_moves_nothing(root, tmp_path):
    base = tmp_path / "ref.json"
    assert main(["--root", str(root), "--quiet", "regress", "c172", "--write-baseline", str(base)]) == 0
    doc = __import__("json").loads(base.read_text())
    assert set(doc["evaluations"]) == {"data/c172_poh_climb.csv", "data/c172_poh_cruise.csv",
                                       "data/c172_flight_test_snapshots.csv", "data/c172_flight_test_flap_climb.csv",
                                       "data/g1000/log_110812_095915_KCKN.csv"}
    edit(root, lambda t: t.replace("<metrics>", "<!-- hand edit: a note, nothing else -->\n  <metrics>", 1))
    res = regress(root, "c172", base)
    assert not res.moved and res.compared > 200, res.report()
    assert main(["--root", str(root), "--quiet", "regress", "c172", "--baseline", str(base)]) == 0


def test_drag_factor_plus_5_percent_is_flagged_point_by_point(root, tmp_path, capsys):
    base = write_baseline(root, "c172", tmp_path / "ref.json",
                          [root / "data" / "c172_poh_climb.csv", root / "data" / "c172_poh_cruise.csv"])
    edit(root, lambda t: scale_factor(t, 1.05))
    res = regress(root, "c172", base)
    moved = {(m.data, m.metric) for m in res.moves}
    assert ("data/c172_poh_climb.csv", "roc_fpm") in moved
    assert {("data/c172_poh_cruise.csv", m) for m in ("rpm", "pct_power", "gph")} <= moved
    climbs = [m for m in res.moves if m.metric == "roc_fpm"]
    assert len(climbs) == 27 and all(m.now < m.baseline for m in climbs)       # more drag, less climb
    assert all(m.share > 0.1 for m in res.moves)
    # the command line: exit 1 and one line per moved metric; only the files asked for
    assert main(["--root", str(root), "--quiet", "regress", "c172", "--baseline", str(base),
                 "--data", str(root / "data" / "c172_poh_climb.csv")]) == 1
    out = capsys.readouterr().out
    assert "27 moved" in out and out.count("roc_fpm") == 27


def test_data_not_in_the_baseline_is_an_error(root, tmp_path, capsys):
    base = write_baseline(root, "c172", tmp_path / "ref.json", [root / "data" / "c172_poh_climb.csv"])
    assert main(["--root", str(root), "regress", "c172", "--baseline", str(base),
                 "--data", str(root / "data" / "c172_poh_cruise.csv")]) == 2
    assert "not in the baseline" in capsys.readouterr().err
