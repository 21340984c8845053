"""One error hierarchy for the workbench.

Every error that comes from bad input lists *all* problems found, each with the
place it was found (file, row, column or field), so one run tells the user
everything that needs fixing.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Iterable, Sequence


class CalibError(Exception):
    """Base class of every error raised by jsbsim_calib."""


@dataclass(frozen=True)
class Problem:
    """One thing wrong with an input: where it is and what is wrong."""

    where: str
    message: str

    def __str__(self) -> str:
        return f"{self.where}: {self.message}" if self.where else self.message


class InputError(CalibError, ValueError):
    """Bad input file or argument. ``problems`` lists every problem found; one problem is
    said on one line (``<file>: <place>: <what>``), several on one line each below the file."""

    def __init__(self, source: str | Path, problems: Sequence[Problem] | Problem | str):
        if isinstance(problems, str):
            problems = [Problem("", problems)]
        elif isinstance(problems, Problem):
            problems = [problems]
        self.source = str(source)
        self.problems = list(problems)
        if len(self.problems) == 1:          # one line: "<file>: line N, column C: what is wrong"
            super().__init__(f"{self.source}: {self.problems[0]}")
            return
        lines = [f"{self.source}: {len(self.problems)} problem(s)"]
        lines += [f"  - {p}" for p in self.problems]
        super().__init__("\n".join(lines))


class GeometryError(InputError):
    """The aircraft geometry file is missing a field, has a bad value or unit."""


class DataError(InputError):
    """A data file (POH, flight test, flight log) is malformed."""


class ModelError(CalibError):
    """A generated or hand-edited JSBSim model is inconsistent or does not load."""


class AircraftFileError(InputError, ModelError):
    """An aircraft, engine or propeller file with bad values (e.g. a factor edited by hand to
    NaN or past its bounds); ``problems`` lists each with its line."""


class TrimError(CalibError):
    """A trim did not converge. ``reason`` says why."""

    def __init__(self, reason: str, residual: float | None = None):
        self.reason = reason
        self.residual = residual
        super().__init__(reason if residual is None else f"{reason} (residual {residual:.3g})")


def raise_if(problems: Iterable[Problem], source: str | Path, cls: type[InputError] = InputError) -> None:
    """Raise ``cls`` listing ``problems`` if there are any."""
    problems = list(problems)
    if problems:
        raise cls(source, problems)
