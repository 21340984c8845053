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
    from jsbsim_calib.generate import generate
    root = tmp_path_factory.mktemp("root")
    for d in ("aircraft", "engine", "airfoils", "data", "scripts"):
        shutil.copytree(REPO / d, root / d)
    names = sorted(p.parent.name for p in (REPO / "aircraft").glob("*/geometry.toml"))
    for n in names:
        generate(n, root)
    return root


def _synthetic_poh(sim, ds, indices, path: Path):
    """Rows ``indices`` of a POH dataset with their metrics replaced by what ``sim`` (at its
    current factors) trims to there, written to ``path`` and loaded back."""
    from jsbsim_calib.data.load import load_dataset
    from jsbsim_calib.evaluate import KINDS
    conds = KINDS[ds.kind].conditions(ds, sim.geometry)
    f = ds.frame.iloc[indices].copy()
    for j, i in enumerate(indices):
        t = sim.trim_level(conds[i]) if conds[i].mode == "level" else sim.trim(conds[i])
        assert t.trimmed, t.reason
        for m in ds.metrics:
            f.loc[f.index[j], m] = KINDS[ds.kind].value(m, t)
    f.to_csv(path, index=False)
    return load_dataset(path)


@pytest.fixture
def synthetic_poh():
    return _synthetic_poh
