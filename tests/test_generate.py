"""Generation: the committed files are what 'generate' writes; bad geometry stops with a clear error."""
import re
import shutil
import subprocess
import sys
from pathlib import Path

import jsbsim
import numpy as np
import pytest

from jsbsim_calib.generate import generate
from jsbsim_calib.jsbsim.product import AircraftPaths
from jsbsim_calib.core.errors import GeometryError

AIRCRAFT = ("c172", "sr20")


@pytest.mark.parametrize("name", AIRCRAFT)
def test_committed_files_equal_a_fresh_generate(generated_root, repo, name):
    """generate is deterministic and the repository holds its output (calibrated factors included)."""
    paths = AircraftPaths(repo, name)
    fresh = AircraftPaths(generated_root, name)
    for a, b in ((paths.aircraft_xml, fresh.aircraft_xml), (paths.engine_xml, fresh.engine_xml),
                 (paths.propeller_xml, fresh.propeller_xml), (paths.propeller_bem, fresh.propeller_bem),
                 (paths.script, fresh.script), (paths.init_xml, fresh.init_xml)):
        assert a.read_bytes() == b.read_bytes(), f"{a} differs from a fresh 'jsbsim-calib generate {name}'"


@pytest.mark.slow
def test_generate_twice_gives_identical_bytes(generated_root):
    before = {p: p.read_bytes() for p in generated_root.rglob("*.xml")}
    generate("c172", generated_root)
    after = {p: p.read_bytes() for p in generated_root.rglob("*.xml")}
    assert before == after


@pytest.mark.parametrize("name", AIRCRAFT)
def test_loads_from_the_repository_root(repo, name):
    fdm = jsbsim.FGFDMExec(str(repo))
    fdm.set_debug_level(0)
    assert fdm.load_model(name)


@pytest.mark.parametrize("name", AIRCRAFT)
def test_jsbsim_runner_trims_and_flies_60s_of_cruise(repo, tmp_path, name):
    """JSBSim's own runner (pip wheel 'jsbsim' command) flies the generated script."""
    runner = shutil.which("jsbsim") or str(Path(sys.executable).with_name("jsbsim"))
    out = subprocess.run([runner, "--root", str(repo), "--nohighlight", str(repo / "scripts" / f"{name}_cruise.xml")],
                         capture_output=True, text=True, timeout=300, cwd=tmp_path)
    text = out.stdout.replace("\0", "") + out.stderr.replace("\0", "")
    assert out.returncode == 0, text[-2000:]
    assert "Trim successful" in text
    assert "nan" not in text.lower().replace("nan ", "x") or not re.search(r"\bnan\b", text.lower())
    alts = [float(v) for v in re.findall(r"altitude \[ft\] = ([-0-9.eE+]+)", text)]
    times = [float(v) for v in re.findall(r"executed at time: ([-0-9.eE+]+)", text)]
    assert len(alts) >= 6 and max(times) >= 50.0
    assert all(np.isfinite(alts)) and min(alts) > 5000.0 and max(alts) < 6000.0


def _copy_c172(tmp_path: Path) -> Path:
    root = tmp_path / "root"
    (root / "aircraft").mkdir(parents=True)
    shutil.copytree(Path(__file__).resolve().parents[1] / "aircraft" / "c172", root / "aircraft" / "c172")
    shutil.copytree(Path(__file__).resolve().parents[1] / "data", root / "data")
    return root


@pytest.mark.parametrize("edit, field", [
    (lambda s: re.sub(r'\nspan = "433 in".*\n', "\n", s), "reference.span"),
    (lambda s: s.replace('y = { values = [0.0, 78.0, 216.5], unit = "in" }',
                         'y = { values = [0.0, -78.0, -216.5], unit = "in" }'), "wing.y"),
    (lambda s: s.replace('airfoil = "naca2412-tr05"', 'airfoil = "naca9999"'), "wing.airfoil"),
    (lambda s: s.replace('wing_area = "174 ft2"', 'wing_area = "174 deg"'), "reference.wing_area"),
    (lambda s: s.replace('diameter = "76 in"', 'diameter = "76"'), "propeller.diameter"),
])
def test_bad_geometry_names_file_and_field_and_writes_nothing(tmp_path, edit, field):
    root = _copy_c172(tmp_path)
    g = root / "aircraft" / "c172" / "geometry.toml"
    g.write_text(edit(g.read_text()))
    before = sorted(p for p in root.rglob("*") if p.is_file())
    with pytest.raises(GeometryError) as exc:
        generate("c172", root)
    msg = str(exc.value)
    assert "geometry.toml" in msg and field in msg, msg
    assert sorted(p for p in root.rglob("*") if p.is_file()) == before
