"""A fleet of Garmin G1000 logs: every log of a folder evaluated against one aircraft.

Logs are independent work (:mod:`jsbsim_calib.core.executor`): each is read, cut into its
quasi-steady segments and trimmed from a freshly loaded aircraft, so a log's result does not
depend on the logs before it, nor on the executor. The batch streams: logs go out in chunks,
only one summary row per log comes back (memory flat in the number of logs), a log that fails
(unreadable, no steady segment, no trim) is listed with its reason and the batch goes on.
"""
from __future__ import annotations

import math
import time
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Iterable, Sequence

from ..core.errors import CalibError, DataError
from ..core.executor import SERIAL, Executor
from ..data.logs import METRICS, log_dataset
from ..jsbsim.simulator import Simulator
from .evaluate import evaluate_dataset

CHUNK_PER_WORKER = 4


@dataclass(frozen=True)
class LogRow:
    """One log's result: its segments and the model's error per metric (None where the log
    has no segment of that kind)."""

    log: str
    segments: int
    rmse: dict[str, float | None]
    within_pct: dict[str, float | None]
    failure: str = ""


@dataclass
class FleetResult:
    aircraft: str
    rows: list[LogRow]
    wall_time_s: float = 0.0
    notes: list[str] = field(default_factory=list)

    @property
    def failed(self) -> list[LogRow]:
        return [r for r in self.rows if r.failure]

    def pooled(self) -> dict[str, dict[str, float | None]]:
        """Fleet statistics per metric: RMSE over all segments (from the per-log RMSEs weighted
        by their segments) and the mean share within tolerance."""
        out = {}
        for m in METRICS:
            rows = [r for r in self.rows if not r.failure and r.rmse.get(m) is not None]
            n = sum(r.segments for r in rows)
            out[m] = {"logs": len(rows),
                      "rmse": math.sqrt(math.fsum(r.rmse[m] ** 2 * r.segments for r in rows) / n) if n else None,
                      "within_pct": (math.fsum(r.within_pct[m] for r in rows) / len(rows)) if rows else None}
        return out

    def to_json(self) -> dict:
        return {"aircraft": self.aircraft, "logs": len(self.rows), "failed": len(self.failed),
                "pooled": self.pooled(),
                "rows": [{"log": r.log, "segments": r.segments, "rmse": r.rmse, "within_pct": r.within_pct,
                          "failure": r.failure} for r in self.rows]}


def log_files(folder: Path) -> list[Path]:
    """The G1000 logs of a folder (CSV files whose first line is ``#airframe_info``), by name."""
    out = []
    for p in sorted(Path(folder).glob("*.csv")):
        with open(p, "rb") as fh:
            if fh.read(64).lstrip().startswith(b"#airframe_info"):
                out.append(p)
    return out


class _EvaluateLog:
    """One log from a freshly loaded aircraft (the same bits in any worker)."""

    def __init__(self, sim: Simulator):
        self.sim = sim

    def __call__(self, path: Path) -> LogRow:
        sim = self.sim
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                ds = log_dataset(path, sim.geometry, require_segments=False)
            if len(ds) == 0:
                return LogRow(path.name, 0, {}, {}, "no quasi-steady segment")
            sim.fresh()
            sim.trim_cache = {}
            s = evaluate_dataset(sim, ds).summary()
        except (CalibError, OSError, ValueError) as exc:
            return LogRow(path.name, 0, {}, {}, f"{type(exc).__name__}: {str(exc).splitlines()[0]}")
        rmse = {m: (s[m].rmse if m in s else None) for m in METRICS}
        within = {m: (s[m].within_pct if m in s else None) for m in METRICS}
        return LogRow(path.name, len(ds), rmse, within)


def _chunks(items: Sequence, size: int) -> Iterable[Sequence]:
    for i in range(0, len(items), size):
        yield items[i:i + size]


def evaluate_fleet(sim: Simulator, folder: Path, *, executor: Executor = SERIAL,
                   progress: Callable[[str], None] | None = None) -> FleetResult:
    """Every log of ``folder`` against ``sim``'s aircraft."""
    logs = log_files(folder)
    if not logs:
        raise DataError(folder, "no G1000 log in this folder (CSV files whose first line is '#airframe_info')")
    t0, rows = time.perf_counter(), []
    task = _EvaluateLog(sim)
    key = f"fleet {id(sim)} {sim.factors!r}"
    for chunk in _chunks(logs, CHUNK_PER_WORKER * executor.workers):
        rows += executor.map(task, list(chunk), key=key)
        if progress:
            done, el = len(rows), time.perf_counter() - t0
            progress(f"logs {done}/{len(logs)}  failed {sum(1 for r in rows if r.failure)}  "
                     f"{60 * done / max(el, 1e-9):.0f} logs/min")
    return FleetResult(sim.name, rows, time.perf_counter() - t0)


def format_fleet(res: FleetResult) -> str:
    """The fleet table: one row per log, then the pooled figures and the failures."""
    head = f"{'log':<36} {'segments':>8} " + " ".join(f"{m + ' RMSE':>14} {'within %':>9}" for m in METRICS)
    lines = [head]
    for r in res.rows:
        if r.failure:
            lines.append(f"{r.log:<36} {'-':>8}  failed: {r.failure}")
            continue
        cells = " ".join(f"{_num(r.rmse.get(m)):>14} {_num(r.within_pct.get(m), '.0f'):>9}" for m in METRICS)
        lines.append(f"{r.log:<36} {r.segments:>8} {cells}")
    pooled = res.pooled()
    lines.append(f"{'fleet (' + str(len(res.rows) - len(res.failed)) + ' logs)':<36} "
                 f"{sum(r.segments for r in res.rows):>8} " +
                 " ".join(f"{_num(pooled[m]['rmse']):>14} {_num(pooled[m]['within_pct'], '.0f'):>9}" for m in METRICS))
    lines.append(f"{len(res.failed)} of {len(res.rows)} logs failed")
    return "\n".join(lines)


def _num(x, spec: str = ".1f") -> str:
    return "-" if x is None or not math.isfinite(x) else format(x, spec)
