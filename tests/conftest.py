import shutil
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="session")
def repo() -> Path:
    return REPO


@pytest.fixture(scope="session")
def generated_root(tmp_path_factory) -> Path:
    """A copy of the repository's JSBSim root with every aircraft regenerated from its geometry."""
    from jsbsim_calib.build import generate
    root = tmp_path_factory.mktemp("root")
    for d in ("aircraft", "engine", "airfoils", "data", "scripts"):
        shutil.copytree(REPO / d, root / d)
    names = sorted(p.parent.name for p in (REPO / "aircraft").glob("*/geometry.toml"))
    for n in names:
        generate(n, root)
    return root
