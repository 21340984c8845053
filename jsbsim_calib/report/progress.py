"""What a long command shows while it runs (issue 26).

On a terminal: one status line (tqdm) with the step counter (``[4/10] pitch``), the elapsed
time, an estimate of the time left and the latest activity, and one line per step finished,
instead of a line per fit iteration. ``verbose``: every progress line, time-stamped, as
before. ``log``: every progress line to that file as well. Nothing when the console is not a
terminal (a pipe, a CI log) unless ``verbose``.

The estimate: a :class:`PlanStep` may carry the trims the step took the last time
(calibration.json records them); then the work done is counted in trims (a fit's progress
line carries its trims so far: a str with ``task`` and ``work`` attributes,
:class:`jsbsim_calib.calibration.fit.WorkLine`) and the time left is the elapsed time scaled
by the work left at this run's average rate. Without a record the counter counts steps and the
estimate is per step. The progress lines are only shown: no product or report byte depends on
them.
"""
from __future__ import annotations

import shutil
import sys
import time
from dataclasses import dataclass
from typing import Sequence, TextIO

from tqdm import tqdm

BAR_FORMAT = "{desc} {percentage:3.0f}% |{bar:16}| {elapsed} elapsed, ~{remaining} left{postfix}"
NO_PLAN_FORMAT = "{elapsed} elapsed{postfix}"          # a command without a plan: time and activity
ACTIVITY_CHARS = 60          # of the latest progress line, on the status line
DEFAULT_COLUMNS = 110        # the status line's width on a terminal that reports none


@dataclass(frozen=True)
class PlanStep:
    """A step of a command's plan: its name (the task its progress lines start with, ``name:
    ...``), its label on the counter, and the work it took the last time (None: unknown)."""

    name: str
    label: str = ""
    expected: int | None = None


class Progress:
    """The ``progress`` callable a command hands the library (module doc). Use it in a ``with``
    block (or call :meth:`close`): the status line is removed at the end. ``hold_stdout``: while
    the status line shows, what the command prints (stdout and stderr: the same terminal) is
    written above it, line by line, instead of running into it."""

    def __init__(self, plan: Sequence[PlanStep] = (), *, live: bool, verbose: bool = False,
                 log: TextIO | None = None, stream: TextIO | None = None, hold_stdout: bool = False):
        self.plan = list(plan)
        self.stream = stream if stream is not None else sys.stderr
        self.verbose, self.log = verbose, log
        self.t0 = time.perf_counter()
        self.index = -1                      # the plan step running or last run (-1: none yet)
        self.running = False
        self.step_t0 = self.step_last = self.t0
        self.done = 0                        # work of the finished steps (expected units)
        by_work = bool(self.plan) and all(s.expected for s in self.plan)
        self.by_work = by_work
        total = sum(s.expected for s in self.plan) if by_work else (len(self.plan) or None)
        sized = shutil.get_terminal_size((0, 0)).columns > 0     # a terminal that reports no width: a fixed one
        self.bar = tqdm(total=total, file=self.stream, bar_format=BAR_FORMAT if self.plan else NO_PLAN_FORMAT,
                        smoothing=0, leave=False, dynamic_ncols=sized, ncols=None if sized else DEFAULT_COLUMNS,
                        nrows=None if sized else 24,
                        desc=self._desc()) if live else None
        self._held = None
        if self.bar is not None and hold_stdout:      # what the command prints goes above the status line
            self._held = (sys.stdout, sys.stderr)
            sys.stdout, sys.stderr = (LinesAboveTheBar(f, self.stream) for f in self._held)

    def _desc(self) -> str:
        if not self.plan:
            return ""
        i = max(self.index, 0)
        return f"[{i + 1}/{len(self.plan)}] {self.plan[i].label or self.plan[i].name}"

    def _stamp(self, msg: str) -> str:
        return f"[{time.perf_counter() - self.t0:7.1f} s] {msg}"

    def __call__(self, msg: str) -> None:
        line = self._stamp(msg)
        if self.log is not None:
            print(line, file=self.log, flush=True)
        if self.verbose:
            if self.bar is not None:
                self.bar.write(line, file=self.stream)
            else:
                print(line, file=self.stream, flush=True)
        if self.bar is not None:
            self._show(msg)

    def _step_of(self, task: str) -> int | None:
        """The plan step of ``task`` from the one running on (a step's name ends it once)."""
        first = self.index if self.running else self.index + 1
        for i in range(max(first, 0), len(self.plan)):
            if self.plan[i].name == task:
                return i
        return None

    def _show(self, msg: str) -> None:
        task = getattr(msg, "task", None) or msg.split(":", 1)[0]
        if self.running and task != self.plan[self.index].name:
            self._finish_step(time.perf_counter())          # another task's line: the step is done
        i = self._step_of(task)
        if i is not None and not self.running:
            self.index, self.step_t0, self.running = i, time.perf_counter(), True
        if self.running:
            self.step_last = time.perf_counter()
            self.done = sum(s.expected for s in self.plan[:i]) if self.by_work else i
            self.bar.set_description_str(self._desc(), refresh=False)
        n = self.done
        work = getattr(msg, "work", None)
        if self.by_work and self.running and work is not None and task == self.plan[self.index].name:
            n += min(work, self.plan[self.index].expected)
        elif self.index >= 0 and not self.running:
            n = self.done + (self.plan[self.index].expected if self.by_work else 1)
        self.bar.n = n
        text = msg.split(": ", 1)[1] if ": " in msg else msg
        self.bar.set_postfix_str(text[:ACTIVITY_CHARS], refresh=False)
        self.bar.refresh()

    def _finish_step(self, at: float | None = None) -> None:
        """A line for the step running: it ended ``at`` (None: at its last progress line)."""
        if self.running:
            self.running = False
            end = self.step_last if at is None else at
            self.bar.write(f"{self._desc()}: done in {end - self.step_t0:.0f} s", file=self.stream)

    def close(self, finished: bool = True) -> None:
        """Remove the status line (``finished``: after a line for the last step)."""
        if self._held is not None:
            sys.stdout.flush()
            sys.stderr.flush()
            (sys.stdout, sys.stderr), self._held = self._held, None
        if self.bar is not None:
            if finished:
                self._finish_step()
            self.bar.close()
            self.bar = None

    def __enter__(self) -> "Progress":
        return self

    def __exit__(self, kind, value, tb) -> None:
        self.close(finished=kind is None)


class LinesAboveTheBar:
    """stdout while a status line shows on the same terminal: each complete line is written with
    the status line cleared and then redrawn (tqdm.external_write_mode); a partial line waits for
    its end (or a flush)."""

    def __init__(self, stream: TextIO, bar_stream: TextIO):
        self.stream, self.bar_stream, self.pending = stream, bar_stream, ""

    def write(self, text: str) -> int:
        self.pending += text
        if "\n" in self.pending:
            lines, self.pending = self.pending.rsplit("\n", 1)
            self._emit(lines + "\n")
        return len(text)

    def _emit(self, text: str) -> None:
        with tqdm.external_write_mode(file=self.bar_stream):
            self.stream.write(text)
            self.stream.flush()

    def flush(self) -> None:
        if self.pending:
            self._emit(self.pending)
            self.pending = ""
        self.stream.flush()

    def __getattr__(self, name):
        return getattr(self.stream, name)


class Tee:
    """A text stream that writes to ``stream`` and to ``log`` (``--log-file``: the file gets
    everything the command prints); anything else is the stream's."""

    def __init__(self, stream: TextIO, log: TextIO):
        self.stream, self.log = stream, log

    def write(self, text: str) -> int:
        self.log.write(text)
        return self.stream.write(text)

    def flush(self) -> None:
        self.log.flush()
        self.stream.flush()

    def __getattr__(self, name):
        return getattr(self.stream, name)
