"""One writer per aircraft folder, and what an interrupted command leaves.

A command that writes an aircraft (``generate``, ``calibrate`` without ``--no-write``,
``close-loop`` writing an aircraft) holds ``aircraft/NAME/.lock`` while it runs: a file made
atomically (``O_EXCL``) holding the holder's pid, command line and start time. A second
writer of the same folder is refused at once, naming them (it would otherwise overwrite a
result the first was told was written); a lock whose process is gone is taken over.

Interrupted (Ctrl-C), a command says in one line what the aircraft holds: unchanged (a write
half done rolled back by :func:`jsbsim_calib.core.commit.recover`), or the new product (its write
had been decided); :func:`interrupted_message`.

The guard knows no aircraft file: the command line gives it the aircraft's files
(``files(root, name)``, an object with ``folder`` and ``product_files``:
:class:`jsbsim_calib.jsbsim.product.AircraftPaths`) and how a half-done write of them is finished
or rolled back (``recover(files)``: :func:`jsbsim_calib.jsbsim.product.recover_product`).
"""
from __future__ import annotations

import hashlib
import json
import os
import sys
import time
import warnings
from collections.abc import Callable
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from .commit import alive
from .errors import CalibError

LOCK = ".lock"


class LockedError(CalibError):
    """Another process writes the aircraft folder."""



def _holder(lock: Path) -> dict | None:
    try:
        return json.loads(lock.read_text())
    except (OSError, ValueError):
        return None


@contextmanager
def aircraft_lock(folder: Path, command: str):
    """Hold ``folder/.lock`` while the block runs; :class:`LockedError` naming the holder when
    a live process holds it."""
    folder = Path(folder)
    made = not folder.exists()
    folder.mkdir(parents=True, exist_ok=True)
    lock = folder / LOCK
    doc = {"pid": os.getpid(), "command": command, "started": time.strftime("%Y-%m-%d %H:%M:%S %z")}
    for _ in range(2):
        try:
            fd = os.open(lock, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o644)
        except FileExistsError:
            held = _holder(lock)
            if held and isinstance(held.get("pid"), int) and alive(held["pid"]) and held["pid"] != os.getpid():
                raise LockedError(f"{folder} is being written by another run: pid {held['pid']}, "
                                  f"'{held.get('command', '?')}', started {held.get('started', '?')}; wait for it "
                                  f"to end (or remove {lock} if that process is gone)") from None
            lock.unlink(missing_ok=True)          # its process is gone (or the file is unreadable): take it over
            continue
        with os.fdopen(fd, "w") as fh:
            fh.write(json.dumps(doc) + "\n")
        break
    else:
        raise LockedError(f"{lock}: cannot take the lock")
    try:
        yield lock
    finally:
        if (_holder(lock) or {}).get("pid") == os.getpid():
            lock.unlink(missing_ok=True)
        if made and not any(folder.iterdir()):
            folder.rmdir()                        # made for the lock only: nothing was written


def written_aircraft(a) -> str | None:
    """The aircraft folder name a command line writes, or None."""
    name = getattr(a, "aircraft", None)
    if a.command == "generate" or (a.command == "calibrate" and not a.no_write):
        return name
    if a.command == "close-loop" and not a.no_write:
        return name if a.in_place else (a.out or f"{name}_loop")
    return None


def fingerprint(paths) -> str:
    """A digest of the aircraft's product files as they stand."""
    h = hashlib.sha256()
    for p in paths.product_files:
        h.update(str(p).encode() + (p.read_bytes() if p.is_file() else b"<none>"))
    return h.hexdigest()


@contextmanager
def command_guard(a, files: Callable[[Path, str], Any], recover: Callable[[Any], str | None]):
    """The lock of the aircraft folder the command writes (if any), and its fingerprint before
    the run (``a.before``) for :func:`interrupted_message`. ``files``, ``recover``: the
    aircraft's files and their recovery (see the module's text)."""
    name = written_aircraft(a)
    a.before = None
    if name is None:
        yield
        return
    paths = files(Path(a.root), name)
    with aircraft_lock(paths.folder, " ".join(["jsbsim-calib", *sys.argv[1:]]) if sys.argv else a.command):
        recover(paths)
        a.before = fingerprint(paths)
        yield


def interrupted_message(a, files: Callable[[Path, str], Any], recover: Callable[[Any], str | None]) -> str:
    """One line: what the interrupted command left of the aircraft it writes (``files``,
    ``recover`` as for :func:`command_guard`)."""
    name = written_aircraft(a) if hasattr(a, "command") else None
    if name is None or getattr(a, "before", None) is None:
        return "interrupted; nothing written"
    paths = files(Path(a.root), name)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")            # the one line below says it
        done = recover(paths)
    where = f"aircraft/{name}"
    if fingerprint(paths) == a.before:
        return f"interrupted; {where} unchanged" + (" (a half-done write rolled back)" if done == "rolled back" else "")
    return f"interrupted; {where} holds the new product (its write had completed)"
