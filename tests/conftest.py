import fcntl
import os
import shutil
from contextlib import contextmanager
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="session")
def repo() -> Path:
    return REPO


# close-loop's aircraft (aircraft/NAME_loop, ignored by git) share their engine files with NAME's:
# a checkout where close-loop ran must not hand them to the tests
LOOP_OUTPUT = "*_loop"
AIRCRAFT_NAMES = sorted(p.parent.name for p in (REPO / "aircraft").glob("*/geometry.toml")
                        if not p.parent.match(LOOP_OUTPUT))


def _copy_root(root: Path) -> Path:
    for d in ("aircraft", "engine", "airfoils", "data", "scripts"):
        shutil.copytree(REPO / d, root / d, ignore=shutil.ignore_patterns(LOOP_OUTPUT) if d == "aircraft" else None)
    return root


@contextmanager
def _locked(path: Path):
    with open(path, "w") as fh:
        fcntl.flock(fh, fcntl.LOCK_EX)
        yield


@pytest.fixture(scope="session")
def generated_root(tmp_path_factory) -> Path:
    """A copy of the repository's JSBSim root with every aircraft regenerated from its geometry,
    made once per test run: pytest-xdist's workers share it, each generating the aircraft the
    others are not generating (worker N starts with aircraft N, one lock per aircraft), so the
    two aircraft are generated side by side, once."""
    from jsbsim_calib.generate import generate
    worker = os.environ.get("PYTEST_XDIST_WORKER")
    if worker is None:
        root = _copy_root(tmp_path_factory.mktemp("root"))
        for n in AIRCRAFT_NAMES:
            generate(n, root)
        return root
    root = tmp_path_factory.getbasetemp().parent / "generated_root"
    with _locked(root.with_suffix(".lock")):
        if not (root / ".copied").is_file():
            shutil.rmtree(root, ignore_errors=True)             # a worker that died half way
            _copy_root(root)
            (root / ".copied").touch()
    k = int(worker.removeprefix("gw")) % len(AIRCRAFT_NAMES)
    for n in AIRCRAFT_NAMES[k:] + AIRCRAFT_NAMES[:k]:
        with _locked(root.parent / f"generated_root.{n}.lock"):
            if not (root / f".generated-{n}").is_file():
                generate(n, root)
                (root / f".generated-{n}").touch()
    return root


def _synthetic_poh(sim, ds, indices, path: Path):
    """Rows ``indices`` of a POH dataset with their metrics replaced by what ``sim`` (at its
    current factors) trims to there, written to ``path`` and loaded back."""
    from jsbsim_calib.data.load import load_dataset
    from jsbsim_calib.evaluation.evaluate import KINDS
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


# The longest tests (30-130 s each on 2 cores, longest first, measured on a fresh clone on
# 2026-11-28) start first: a long test that starts last leaves the other worker idle at the end
# (longest-first scheduling; the order is the same on every worker, as pytest-xdist requires).
LONGEST_FIRST = ("test_an_undeclared_effect_is_found_on_the_level5_campaign",       # four of 93-126 s
                 "test_main_job_rewrites_the_committed_c172_byte_for_byte",
                 "test_real_c172_trims_without_pfactor_step_find_the_yaw_effect",
                 "test_stage2a_flap_folds_refit_only_the_steps_that_use_them",
                 "test_candidates_folds_and_refit_on_a_pool_give_the_serial_bits",
                 "test_the_plan_aims_at_the_loosest_factors_and_beats_random_level5_maneuvers",
                 "test_sr20_steady_fit_from_a_perturbed_start_lands_on_the_committed_factors",
                 "test_stage_2b_alone_starts_where_the_main_job_did_and_rewrites_its_bytes",
                 "test_hand_edits_survive_calibrate_and_generate",
                 "test_the_model_passes_its_own_level5_flight_test_at_every_seed",
                 "test_a_pair_of_undeclared_effects_is_found")


def pytest_collection_modifyitems(session, config, items):
    rank = {name: i for i, name in enumerate(LONGEST_FIRST)}
    items.sort(key=lambda item: rank.get(item.originalname, len(rank)))
