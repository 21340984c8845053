"""A fleet of G1000 logs: every log of a folder evaluated, failures listed without stopping the
batch, memory flat in the number of logs, the same rows on a process pool."""
from __future__ import annotations

import tracemalloc
from pathlib import Path

import pytest

from jsbsim_calib.core.errors import DataError
from jsbsim_calib.core.executor import ProcessExecutor
from jsbsim_calib.evaluation.fleet import evaluate_fleet, format_fleet
from jsbsim_calib.jsbsim.simulator import Simulator
from jsbsim_calib.synthetic.truth import synthetic_fleet

REPO = Path(__file__).resolve().parents[1]
REAL = REPO / "data/g1000/log_110812_095915_KCKN.csv"


@pytest.fixture(scope="module")
def sim():
    with Simulator(REPO, "c172") as s:
        yield s


def _peak_mb(sim, folder: Path) -> tuple[float, object]:
    tracemalloc.start()
    res = evaluate_fleet(sim, folder)
    peak = tracemalloc.get_traced_memory()[1] / 1e6
    tracemalloc.stop()
    return peak, res


@pytest.mark.slow
def test_a_200_log_fleet_streams_with_flat_memory(sim, tmp_path):
    small, large = tmp_path / "small", tmp_path / "large"
    synthetic_fleet(REAL, small, 20, seed=1)
    synthetic_fleet(REAL, large, 200, seed=1)
    peak_small, _ = _peak_mb(sim, small)
    peak_large, res = _peak_mb(sim, large)
    assert len(res.rows) == 200
    assert peak_large < peak_small + 10.0, (peak_small, peak_large)   # ten times the logs, not ten times the memory
    ok = [r for r in res.rows if not r.failure]
    assert ok and all(r.segments > 0 for r in ok)
    assert all(r.failure == "no quasi-steady segment" for r in res.failed)
    pooled = res.pooled()
    assert pooled["rpm"]["rmse"] is not None and 0 < pooled["rpm"]["rmse"] < 80


def test_failures_are_listed_and_the_batch_goes_on(sim, tmp_path):
    synthetic_fleet(REAL, tmp_path, 6, seed=3)
    cut = tmp_path / "log_cut.csv"
    cut.write_bytes(REAL.read_bytes()[:2500])                   # a log cut at 2.5 kB
    res = evaluate_fleet(sim, tmp_path)
    assert len(res.rows) == 7
    bad = {r.log: r.failure for r in res.failed}
    assert "log_cut.csv" in bad and bad["log_cut.csv"]
    table = format_fleet(res)
    assert "log_cut.csv" in table and "failed:" in table and f"{len(res.failed)} of 7 logs failed" in table


def test_the_pool_gives_the_same_rows(sim, tmp_path):
    synthetic_fleet(REAL, tmp_path, 10, seed=5)
    one = evaluate_fleet(sim, tmp_path)
    with ProcessExecutor(2) as pool:
        two = evaluate_fleet(sim, tmp_path, executor=pool)
    assert one.rows == two.rows


def test_a_folder_without_logs_is_an_error(sim, tmp_path):
    (tmp_path / "notes.csv").write_text("a,b\n1,2\n")
    with pytest.raises(DataError, match="no G1000 log"):
        evaluate_fleet(sim, tmp_path)
