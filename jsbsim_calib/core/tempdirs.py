"""Temporary directories of a run (simulator sandboxes, staged roots, task files).

Every temporary directory the workbench makes lives under one parent per process,
``<tmp>/jsbsim-calib-run-<pid>-XXXX``, removed when the process exits (``atexit``, and
multiprocessing's finalizers in pool workers), whatever the run did: a failed or interrupted
run leaves nothing behind even where a sandbox's owner never closed it. A parent left by a
process that was killed (SIGKILL: no exit handler runs) is removed by the next run that
makes a directory (its process no longer exists).

A leaf module: the standard library only.
"""
from __future__ import annotations

import atexit
import os
import shutil
import tempfile
from pathlib import Path

PREFIX = "jsbsim-calib-run-"
_parent: tuple[int, Path] | None = None        # (pid, directory) of this process


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:          # someone else's process
        return True
    return True


def _remove(path: Path) -> None:
    shutil.rmtree(path, ignore_errors=True)


def sweep_stale(base: Path | None = None) -> list[Path]:
    """Remove the run directories of processes that no longer exist (this user's only)."""
    base = Path(base or tempfile.gettempdir())
    removed = []
    for d in base.glob(f"{PREFIX}*"):
        try:
            pid = int(d.name[len(PREFIX):].split("-")[0])
            mine = d.stat().st_uid == os.getuid()
        except (ValueError, OSError):
            continue
        if mine and pid != os.getpid() and not _alive(pid):
            _remove(d)
            removed.append(d)
    return removed


def run_dir() -> Path:
    """This process's parent of temporary directories (made on first use, removed at exit)."""
    global _parent
    pid = os.getpid()
    if _parent is None or _parent[0] != pid or not _parent[1].is_dir():
        sweep_stale()
        path = Path(tempfile.mkdtemp(prefix=f"{PREFIX}{pid}-"))
        _parent = (pid, path)
        atexit.register(_remove, path)
        try:                      # pool workers end through multiprocessing's exit function
            from multiprocessing import util
            util.Finalize(None, _remove, args=(path,), exitpriority=0)
        except Exception:         # pragma: no cover - multiprocessing always importable
            pass
    return _parent[1]


def make_dir(prefix: str) -> Path:
    """A new temporary directory of this run (``prefix`` names what it holds)."""
    return Path(tempfile.mkdtemp(prefix=prefix, dir=run_dir()))
