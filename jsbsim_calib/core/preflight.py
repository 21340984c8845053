"""Checks of a command line before any work: flags that contradict each other, step names,
and the folders a command will write (a fit must not end, after minutes, on a folder it
cannot write, nor write the aircraft and then fail on its report).

Each check returns :class:`~jsbsim_calib.core.errors.Problem` s naming the option; the command
line reports them all at once (``cli._run``), and gives what the checks cannot know from here:
the names of the steps of stage 2a (:data:`jsbsim_calib.calibration.trims.TRIM_STEPS`).
"""
from __future__ import annotations

import uuid
from collections.abc import Sequence
from pathlib import Path

from .errors import Problem

# (command, option given, option given): the second silently overrides or ignores the first
CONTRADICTIONS = (
    ("regress", "baseline", "write_baseline", "--baseline compares with a baseline, --write-baseline records one: "
                                              "give one of them"),
    ("regress", "write_baseline", "json", "--json writes a comparison's moves; --write-baseline compares nothing"),
    ("close-loop", "in_place", "out", "--in-place writes into the aircraft itself, --out into another folder: "
                                      "give one of them"),
    ("close-loop", "no_write", "in_place", "--no-write writes no aircraft; --in-place would write one"),
    ("close-loop", "no_write", "out", "--no-write writes no aircraft; --out names one"),
)


def flag_problems(a) -> list[Problem]:
    """Options given together that contradict each other (one would be ignored)."""
    return [Problem(f"--{x.replace('_', '-')} and --{y.replace('_', '-')}", why)
            for cmd, x, y, why in CONTRADICTIONS if a.command == cmd and getattr(a, x, None) and getattr(a, y, None)]


def skip_problems(a, names: Sequence[str]) -> list[Problem]:
    """``--skip`` names that are no step of stage 2a (``names``: its steps)."""
    return [Problem("--skip", f"'{s}' is no step of stage 2a; steps: {', '.join(names)}")
            for s in (getattr(a, "skip", None) or ()) if s not in names]


def _probe(folder: Path) -> str | None:
    """Why files cannot be written in ``folder`` (or, not there yet, in the nearest folder above
    it that is, where it would be made); None when they can. A real file is made and removed:
    permission bits say nothing to the superuser or of a read-only file system."""
    p = folder
    while not p.exists():
        if p.parent == p:
            return "no folder above it exists"
        p = p.parent
    if not p.is_dir():
        return f"{p} is a file, not a folder"
    probe = p / f".jsbsim-calib-probe-{uuid.uuid4().hex}"
    try:
        probe.write_bytes(b"")
        probe.unlink()
    except OSError as exc:
        return f"cannot write in {p}: {exc.strerror or exc}"
    return None


def output_folders(a) -> list[tuple[str, Path]]:
    """(option, folder) for each folder the command will write into."""
    root, out = Path(a.root), []
    name = getattr(a, "aircraft", None)
    if getattr(a, "report_dir", None) and name:
        out.append(("--report-dir", Path(a.report_dir) / name))
    if a.command == "generate" or (a.command == "calibrate" and not a.no_write):
        out.append(("aircraft folder", root / "aircraft" / name))
    if a.command == "generate":
        out.append(("engine folder", root / "engine"))
    if a.command == "close-loop" and not a.no_write:
        out.append(("aircraft folder", root / "aircraft" / (name if a.in_place else (a.out or f"{name}_loop"))))
    return out


def writable_problems(a) -> list[Problem]:
    """Every folder the command will write that it cannot."""
    out = []
    for option, folder in output_folders(a):
        why = _probe(folder)
        if why:
            out.append(Problem(option, f"{folder}: {why}"))
    return out


def command_problems(a, trim_steps: Sequence[str]) -> list[Problem]:
    """Every problem of a command line that can be found before any work (``trim_steps``: the
    names of the steps of stage 2a)."""
    return flag_problems(a) + skip_problems(a, trim_steps) + writable_problems(a)

