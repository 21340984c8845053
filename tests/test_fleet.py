"""A fleet of G1000 logs: every log of a folder evaluated, failures listed without stopping the
batch, memory flat in the number of logs, the same rows on a process pool."""
from __future__ import annotations

import json
import subprocess
import sys
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


# A fleet evaluated in a fresh process: its peak resident memory over what the process held
# before the fleet (JSBSim loaded), C allocations included; tracemalloc would slow the
# evaluation fivefold and see Python's allocations only.
FLEET_RUN = """
import json, resource, sys
from pathlib import Path
from jsbsim_calib.evaluation.fleet import evaluate_fleet
from jsbsim_calib.jsbsim.simulator import Simulator
with Simulator(Path(sys.argv[1]), "c172") as sim:
    before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    res = evaluate_fleet(sim, Path(sys.argv[2]))
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
print(json.dumps({"growth_kb": peak - before, "rows": len(res.rows),
                  "segments": [r.segments for r in res.rows if not r.failure],
                  "failed": [r.failure for r in res.failed], "rpm_rmse": res.pooled()["rpm"]["rmse"]}))
"""


def _fleet_in_a_process(folder: Path) -> dict:
    r = subprocess.run([sys.executable, "-c", FLEET_RUN, str(REPO), str(folder)], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr[-3000:]
    return json.loads(r.stdout.splitlines()[-1])


@pytest.mark.slow
def test_a_200_log_fleet_streams_with_flat_memory(tmp_path):
    small, large = tmp_path / "small", tmp_path / "large"
    synthetic_fleet(REAL, small, 20, seed=1)
    synthetic_fleet(REAL, large, 200, seed=1)
    few, many = _fleet_in_a_process(small), _fleet_in_a_process(large)
    assert many["rows"] == 200
    # ten times the logs, not ten times the memory (measured: 6.8 MB over the start for 20, 7.7 for 200;
    # a log read whole is 2 MB)
    assert many["growth_kb"] < few["growth_kb"] + 10 * 1024, (few["growth_kb"], many["growth_kb"])
    assert many["segments"] and all(n > 0 for n in many["segments"])
    assert all(f == "no quasi-steady segment" for f in many["failed"])
    assert many["rpm_rmse"] is not None and 0 < many["rpm_rmse"] < 80


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
