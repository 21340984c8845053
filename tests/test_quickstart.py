"""The README's Python quickstart (examples/quickstart.py) runs as written: generate, a short
stage 1, evaluate and plot, in a temporary root; the repository is not written."""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]


@pytest.mark.slow
def test_quickstart_runs_and_leaves_the_repository_alone(tmp_path):
    before = subprocess.run(["git", "status", "--porcelain", "--", "aircraft", "engine", "reports"], cwd=REPO,
                            capture_output=True, text=True).stdout
    r = subprocess.run([sys.executable, str(REPO / "examples" / "quickstart.py"), str(tmp_path)],
                       capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr[-3000:]
    assert "roc_fpm" in r.stdout and (tmp_path / "sr20_climb.png").stat().st_size > 10_000
    after = subprocess.run(["git", "status", "--porcelain", "--", "aircraft", "engine", "reports"], cwd=REPO,
                           capture_output=True, text=True).stdout
    assert after == before
