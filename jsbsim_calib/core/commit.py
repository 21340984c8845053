"""Several files replaced as one unit: temporary files, a journal, then renames.

:func:`commit` writes every new file to a temporary file beside its target (flushed to
disk), copies the files it replaces to a backup folder (the last few kept; the commits of one
run share one backup, which holds each file as it stood before the run), then writes a
journal naming each temporary file and its target (atomically: the commit is decided when
the journal exists), renames the temporary files over their targets, and removes the
journal. A process killed at any point leaves either

* no journal: the targets are untouched (the old set); stray temporary files are removed by
  :func:`recover` (rolled back), or
* a journal: every temporary file it names is complete; :func:`recover` renames the ones
  left (rolled forward: the new set).

So a reader that calls :func:`recover` first always sees the old set or the new one, never a
truncated file or a mix. A leaf module: the standard library only.
"""
from __future__ import annotations

import json
import os
import shutil
import uuid
from dataclasses import dataclass
from pathlib import Path
from typing import Mapping, Sequence

TMP_MARK = ".commit-"
RUN_MARK = ".run"                  # in a backup folder: the run whose commits it backs up
_ACTIVE: set[str] = set()          # tokens of commits running in this process


@dataclass(frozen=True)
class Committed:
    """What a commit did: the files it replaced or created, and the backup of the old ones
    (None when nothing was replaced)."""

    written: tuple[Path, ...]
    backup: Path | None


def _tmp_name(target: Path, token: str) -> Path:
    return target.with_name(f".{target.name}{TMP_MARK}{token}.tmp")


def _fsync_dir(path: Path) -> None:
    try:
        fd = os.open(path, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


def _write_synced(path: Path, data: bytes) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "xb") as fh:
        fh.write(data)
        fh.flush()
        os.fsync(fh.fileno())


def new_run() -> str:
    """A token naming a run: its commits share one backup (:func:`commit`'s ``run``)."""
    return uuid.uuid4().hex


def _numbered(folder: Path) -> list[int]:
    return sorted(int(d.name) for d in folder.iterdir() if d.is_dir() and d.name.isdigit()) if folder.is_dir() else []


def _run_backup(folder: Path, run: str | None) -> Path | None:
    """The newest backup of ``folder`` when it belongs to ``run``."""
    numbers = _numbered(folder)
    if run is None or not numbers:
        return None
    last = folder / str(numbers[-1])
    mark = last / RUN_MARK
    return last if mark.is_file() and mark.read_text().strip() == run else None


def _backup(targets: Sequence[Path], folder: Path, keep: int, run: str | None = None) -> Path | None:
    """Copy the existing ``targets`` to ``folder/<n>/`` (n one more than the last); keep the
    newest ``keep`` backups. ``run``: a later commit of the same run adds to the run's backup
    only the files it does not hold yet (the backup keeps the files as they stood before the
    run)."""
    old = [t for t in targets if t.is_file()]
    if not old or keep <= 0:
        return None
    same = _run_backup(folder, run)
    if same is not None:
        for t in old:
            if not (same / t.name).exists():
                shutil.copy2(t, same / t.name)
        return same
    folder.mkdir(parents=True, exist_ok=True)
    numbers = _numbered(folder)
    dest = folder / str((numbers[-1] if numbers else 0) + 1)
    dest.mkdir()
    for t in old:
        shutil.copy2(t, dest / t.name)
    if run is not None:
        (dest / RUN_MARK).write_text(run + "\n")
    for n in (numbers + [int(dest.name)])[:-keep]:
        shutil.rmtree(folder / str(n), ignore_errors=True)
    return dest


def commit(files: Mapping[Path, bytes], journal: Path, *, backup: Path | None = None, keep: int = 3,
           run: str | None = None) -> Committed:
    """Replace ``files`` (target -> bytes) as one unit (module doc); a target that holds its
    bytes already is left alone. ``journal``: the journal's path (one per set of files);
    ``backup``: the folder of backups of the replaced files (``keep`` newest kept); ``run``
    (:func:`new_run`): the commits of one run share one backup, of the files as they stood
    before the run (issue 26: a run of three stages kept three backups and rotated that one
    out)."""
    recover(journal, list(files))
    changed = {Path(p): d for p, d in files.items() if not (Path(p).is_file() and Path(p).read_bytes() == d)}
    if not changed:
        return Committed((), None)
    token = f"{os.getpid()}-{uuid.uuid4().hex[:12]}"
    _ACTIVE.add(token)
    try:
        pairs = [(_tmp_name(p, token), p) for p in changed]
        try:
            for tmp, target in pairs:
                _write_synced(tmp, changed[target])
            saved = _backup([t for _, t in pairs], backup, keep, run) if backup is not None else None
            doc = {"token": token, "pid": os.getpid(), "files": [[str(tmp), str(t)] for tmp, t in pairs]}
            jtmp = _tmp_name(journal, token)
            _write_synced(jtmp, (json.dumps(doc, indent=1) + "\n").encode())
            os.replace(jtmp, journal)               # the commit is decided here
        except BaseException:
            _discard(token, [t for _, t in pairs] + [journal])
            raise
        _fsync_dir(journal.parent)
        for tmp, target in pairs:
            os.replace(tmp, target)
        for d in {t.parent for _, t in pairs}:
            _fsync_dir(d)
        journal.unlink()
        return Committed(tuple(t for _, t in pairs), saved)
    finally:
        _ACTIVE.discard(token)


def _discard(token: str, targets: Sequence[Path]) -> None:
    for t in targets:
        Path(_tmp_name(t, token)).unlink(missing_ok=True)


def alive(pid: int) -> bool:
    """Whether a process of that id runs (one of another user counts as running)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def _owner(tmp: Path) -> tuple[int, str] | None:
    """(pid, token) of a temporary file's commit."""
    try:
        token = tmp.name.rsplit(TMP_MARK, 1)[1].rsplit(".tmp", 1)[0]
        return int(token.split("-")[0]), token
    except (IndexError, ValueError):
        return None


def _abandoned(pid: int, token: str) -> bool:
    return not alive(pid) if pid != os.getpid() else token not in _ACTIVE


def recover(journal: Path, targets: Sequence[Path]) -> str | None:
    """Finish or roll back an interrupted commit of ``targets``: 'finished' (a journal's
    renames done), 'rolled back' (stray temporary files of a commit that never decided
    removed) or None (nothing to do). A journal of a commit still running in another
    process is left to it."""
    journal = Path(journal)
    done = None
    if journal.is_file():
        try:
            doc = json.loads(journal.read_text())
            pairs, pid, token = doc["files"], int(doc["pid"]), str(doc["token"])
        except (ValueError, KeyError, TypeError):
            pairs, pid, token = [], -1, ""          # unreadable: it was never renamed into place
        if pid > 0 and not _abandoned(pid, token):
            return None
        for tmp, target in pairs:
            try:
                os.replace(tmp, target)
            except FileNotFoundError:
                pass                                 # renamed before the interruption
        journal.unlink(missing_ok=True)
        done = "finished"
    for target in [*map(Path, targets), journal]:
        if not target.parent.is_dir():
            continue
        for tmp in target.parent.glob(f".{target.name}{TMP_MARK}*.tmp"):
            owner = _owner(tmp)
            if owner is not None and _abandoned(*owner):
                tmp.unlink(missing_ok=True)
                done = done or "rolled back"
    return done
