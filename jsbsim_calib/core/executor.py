"""One interface for independent work: in this process, in a process pool, or on a Dask cluster.

Independent work is a list of calls of one function (a fit's Jacobian columns, maneuvers,
logs, close-loop candidates). :meth:`Executor.map` runs ``fn(item)`` for every item and
returns the results in order. The function may be a closure over a
:class:`~jsbsim_calib.jsbsim.simulator.Simulator` and data: it is serialized once with
cloudpickle (a Simulator pickles as its aircraft, factors and effect values and rebuilds its
own sandbox where it lands), and every worker keeps what it unpickled for the next call of the
same function, so a worker loads an aircraft once per fit, not once per task.

The results are the same bits whatever the executor and the number of workers, provided each
call is a pure function of its item: the fits make it so (every evaluation starts from a
JSBSim in a fresh load's state and the trim warm starts of the last accepted point:
:mod:`jsbsim_calib.calibration.fit`).
"""
from __future__ import annotations

import atexit
import contextlib
import hashlib
import importlib
import logging
import math
import multiprocessing
import os
import pickle
import shutil
import signal
import threading
import time
from concurrent.futures import ProcessPoolExecutor
from typing import Any, Callable, Sequence

import cloudpickle

from .errors import CalibError
from .tempdirs import make_dir

_CACHE: dict[str, Callable] = {}          # in a worker: unpickled functions by key
_CACHE_LIMIT = 4
_RUNNING: dict[str, int] = {}             # keys of the functions running now (nested work), by depth
_MEETING = None                           # in a pool's worker: the barrier of ProcessExecutor.ready
READY_TIMEOUT_S = 300
CONNECT_TIMEOUT_S = 5            # an unreachable dask scheduler fails after this, naming its address
# a dask worker samples its task's stack every 10 ms for its dashboard's profile: a fit's task is a
# deep stack of short Python calls into JSBSim, and the sampling cost it a quarter of its CPU (the
# steady stage on 2 workers: 23.1 CPU-s against the pool's 18.5). A remote cluster: docs/cluster.md
DASK_WORKER_CONFIG = {"distributed.worker.profile.enabled": False}
LOOK_EVERY_S = 10.0              # how often a dask executor looks for workers that joined or left


def _call(key: str, payload, item):
    """A task in a worker: the function ``key`` (unpickled once) applied to ``item``.
    ``payload``: the serialized function, or the path of a file holding it. A function still
    running (a task whose own work goes to the executor in this process: a validation fold's
    fits) is never evicted."""
    fn = _CACHE.get(key)
    if fn is None:
        idle = [k for k in _CACHE if k not in _RUNNING]
        if len(_CACHE) >= _CACHE_LIMIT and idle:
            _close(_CACHE.pop(idle[0]))
        if isinstance(payload, str):
            with open(payload, "rb") as fh:
                payload = fh.read()
        fn = _CACHE[key] = cloudpickle.loads(payload)
    _RUNNING[key] = _RUNNING.get(key, 0) + 1
    try:
        return fn(item)
    finally:
        _RUNNING[key] -= 1
        if not _RUNNING[key]:
            del _RUNNING[key]


def _call_block(key: str, payload, items) -> list:
    """A block of tasks in one worker (:meth:`DaskExecutor.map`, where a worker has no runner)."""
    return [_call(key, payload, item) for item in items]


class _Runner:
    """A dask actor, one per worker: it runs blocks of tasks sent straight from the client,
    without the scheduler in between, each block and its results pickled whole. (A batch of 16
    items of 25 ms, each with a fit's 7 KB of warm starts, on 2 workers: 5-7 ms over its work,
    as on the pool; 48 ms as actor calls of the items themselves, whose every small array dask
    sends as a frame of its own, and 14-16 ms as pickled blocks in scheduled tasks.) A block of
    a function its worker no longer holds (it keeps the last few: :func:`_call`) returns None,
    and the client sends it again with the function."""

    def block(self, key: str, items: bytes, payload: bytes | None = None) -> bytes | None:
        if payload is None and key not in _CACHE:
            return None
        return pickle.dumps(_call_block(key, payload, pickle.loads(items)))


def _close(fn) -> None:
    """Close the simulators a cached function holds (their sandboxes)."""
    for cell in getattr(fn, "__closure__", None) or ():
        obj = cell.cell_contents
        if hasattr(obj, "close") and type(obj).__name__ == "Simulator":
            obj.close()


_HELD = {signal.SIGINT, signal.SIGTERM}


@contextlib.contextmanager
def _signals_held():
    """Ctrl-C and SIGTERM held back while the pool starts its workers. A worker spawned by a
    parent that is interrupted before sending the worker its start-up data dies reading it, with
    a traceback on the user's terminal (EOFError: seen once on CI). Held back, the signal lands
    when the block ends, in the parent, as KeyboardInterrupt or exit. (The workers inherit the
    mask; :func:`_worker_init` lifts it.)"""
    if not hasattr(signal, "pthread_sigmask") or threading.current_thread() is not threading.main_thread():
        yield
        return
    before = signal.pthread_sigmask(signal.SIG_BLOCK, _HELD)
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, before)


def _worker_init(meeting=None) -> None:
    global _MEETING
    _MEETING = meeting
    signal.signal(signal.SIGINT, signal.SIG_IGN)     # Ctrl-C is the parent's to handle: no worker tracebacks
    if hasattr(signal, "pthread_sigmask"):
        signal.pthread_sigmask(signal.SIG_UNBLOCK, _HELD)     # held by the parent while it spawned this worker
    atexit.register(lambda: [_close(f) for f in _CACHE.values()])


def _import(modules: Sequence[str]) -> None:
    for m in modules:
        importlib.import_module(m)


def _meet(modules: Sequence[str]) -> int:
    """A worker imports ``modules`` and waits here until every worker of its pool has come
    (:meth:`ProcessExecutor.ready`)."""
    _import(modules)
    _MEETING.wait(READY_TIMEOUT_S)
    return os.getpid()


class _Payloads:
    """Serialized functions by key (the last few)."""

    def __init__(self):
        self._by_key: dict[str, tuple[str, bytes]] = {}

    def get(self, fn: Callable, key: str | None) -> tuple[str, bytes]:
        if key is not None and key in self._by_key:
            return self._by_key[key]
        payload = cloudpickle.dumps(fn)
        out = (hashlib.sha1(payload).hexdigest(), payload)
        if key is not None:
            if len(self._by_key) >= _CACHE_LIMIT:
                self._by_key.pop(next(iter(self._by_key)))
            self._by_key[key] = out
        return out


class Executor:
    """Runs ``fn(item)`` for every item; results in order. ``key``: a name that stays with the
    same function across calls (a fit's problem): it is serialized once and every worker
    unpickles it once."""

    name = "serial"
    workers = 1

    def __init__(self):
        self._payloads = _Payloads()

    def __getstate__(self) -> dict:
        """An executor pickles without its serialized functions: a task that holds it (a close-loop
        evidence does) would carry every earlier payload, and each fit's payload would double the
        last (2.4 MB to 75 MB in six fits of one close-loop run, 19 GB when the system killed it)."""
        return {k: v for k, v in self.__dict__.items() if k != "_payloads"}

    def __setstate__(self, state: dict) -> None:
        self.__dict__.update(state)
        self._payloads = _Payloads()

    def map(self, fn: Callable[[Any], Any], items: Sequence, key: str | None = None) -> list:
        """In this process, as a worker would: a keyed function runs on its own unpickled copy
        (made once per key, as a worker makes it), so the caller's simulator keeps its state
        (its warm starts, its loaded JSBSim) and the results are the pool's bits."""
        if key is None:
            return [fn(i) for i in items]
        digest, payload = self._payloads.get(fn, key)
        return [_call(digest, payload, i) for i in items]

    def ready(self, modules: Sequence[str] = ()) -> None:
        """Every worker started and ``modules`` imported there (otherwise a pool's workers start with
        its first batch, and a task imports what its function needs)."""
        _import(modules)

    def close(self) -> None:
        pass

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def describe(self) -> str:
        return f"{self.name} ({self.workers} worker{'s' if self.workers != 1 else ''})"


SERIAL = Executor()


class ProcessExecutor(Executor):
    """A pool of worker processes on this machine (spawned: no state inherited by accident)."""

    name = "process"

    def __init__(self, workers: int | None = None):
        super().__init__()
        self.workers = max(1, int(workers or os.cpu_count() or 1))
        spawn = multiprocessing.get_context("spawn")
        self._pool = ProcessPoolExecutor(self.workers, mp_context=spawn, initializer=_worker_init,
                                         initargs=(spawn.Barrier(self.workers),))
        self._dir = make_dir("jsbsim-calib-tasks-")

    def ready(self, modules: Sequence[str] = ()) -> None:
        """Start every worker now, import ``modules`` there, and wait until all have. A command's
        workers start with its first batch instead (about 1 s on 2 cores: spawn and imports): a
        benchmark's clock starts after this, as after a cluster's start. Each worker takes one
        task that waits for the others, so the pool starts one process per task."""
        if self.workers == 1:
            return super().ready(modules)
        with _signals_held():
            meetings = [self._pool.submit(_meet, tuple(modules)) for _ in range(self.workers)]
        for f in meetings:
            f.result()

    def map(self, fn, items, key=None):
        if self.workers == 1 or len(items) <= 1:
            return super().map(fn, items, key)
        digest, payload = self._payloads.get(fn, key)
        path = self._dir / f"{digest}.pkl"          # the workers read it once; the tasks carry its path
        if not path.exists():
            path.write_bytes(payload)
        with _signals_held():           # the submits start the workers
            results = self._pool.map(_call, [digest] * len(items), [str(path)] * len(items), items)
        return list(results)

    def close(self) -> None:
        self._pool.shutdown(wait=True, cancel_futures=True)     # interrupted: the tasks not started dropped
        shutil.rmtree(self._dir, ignore_errors=True)


class DaskExecutor(Executor):
    """A dask.distributed cluster: ``scheduler`` its address, or None for a local cluster of
    ``workers`` processes (one thread each: JSBSim is not shared between threads). A batch
    goes as one block per worker to that worker's :class:`_Runner`; where a worker is lost, its
    block runs as a task the scheduler places."""

    name = "dask"

    def __init__(self, scheduler: str | None = None, workers: int | None = None):
        try:
            from distributed import Client, LocalCluster
        except ImportError as exc:      # pragma: no cover - the extra is part of the test install
            raise CalibError("the dask executor needs dask.distributed: pip install 'jsbsim-calib[cluster]'") from exc
        super().__init__()
        self._cluster = None
        if scheduler:
            try:
                self._client = Client(scheduler, timeout=f"{CONNECT_TIMEOUT_S}s")
            except (OSError, TimeoutError) as exc:
                raise CalibError(f"--scheduler {scheduler}: no dask scheduler answers there within "
                                 f"{CONNECT_TIMEOUT_S} s ({type(exc).__name__}: {exc})") from None
        else:
            import dask
            with dask.config.set(DASK_WORKER_CONFIG):     # the workers take it at their start
                self._cluster = LocalCluster(n_workers=max(1, int(workers or os.cpu_count() or 1)),
                                             threads_per_worker=1, processes=True, dashboard_address=None)
            self._client = Client(self._cluster)
        self._scattered: dict = {}
        self._runners: dict = {}     # a runner (actor) per worker, by its address, with the keys sent to it
        self._looked = -math.inf
        self._look()

    def _look(self) -> None:
        """The cluster's workers as they are now, each with its runner (a worker that joined
        since gets one; one gone loses its own). At most every :data:`LOOK_EVERY_S`."""
        if time.monotonic() - self._looked < LOOK_EVERY_S:
            return
        self._looked = time.monotonic()
        self._addresses = sorted(self._client.scheduler_info().get("workers", {}))
        self.workers = max(1, len(self._addresses))
        for a in [a for a in self._runners if a not in self._addresses]:
            del self._runners[a]
        for a in self._addresses:       # free to start elsewhere where its worker has just left
            if a not in self._runners:
                runner = self._client.submit(_Runner, actor=True, workers=[a], allow_other_workers=True, pure=False)
                self._runners[a] = (runner.result(), set())

    def map(self, fn, items, key=None):
        if len(items) <= 1:
            return super().map(fn, items, key)
        self._look()
        digest, payload = self._payloads.get(fn, key)
        # a block of items per worker, not a task per item, each to its worker's runner: a
        # scheduled task costs the cluster about 2 ms of its scheduler's and workers' time,
        # and a fit's batch is a few items of 10-40 ms. Strided, so that the costly items (a
        # propeller factor's column loads JSBSim anew) spread over the blocks
        runners = list(self._runners.items())
        n = min(len(items), len(runners) or self.workers)
        blocks = [list(items[i::n]) for i in range(n)]
        if not runners:
            results = self._scheduled(digest, payload, blocks)
        else:
            calls = [self._send(address, digest, payload, block) for (address, _), block in zip(runners, blocks)]
            results = [self._result(call, address, digest, payload, block)
                       for call, (address, _), block in zip(calls, runners, blocks)]
        out: list = [None] * len(items)
        for i, result in enumerate(results):
            out[i::n] = result
        return out

    def _send(self, address: str, digest: str, payload: bytes, block: list):
        """A block to a runner (the function with it, unless sent before); None where its
        worker is gone."""
        runner, sent = self._runners[address]
        try:
            return runner.block(digest, pickle.dumps(block), None if digest in sent else payload)
        except Exception:
            return None

    def _result(self, call, address: str, digest: str, payload: bytes, block: list) -> list:
        """A runner's block: sent again with the function where the runner no longer holds it;
        where its worker is gone, the runner dropped and the block scheduled anywhere (a task's
        own error is raised again from there)."""
        runner, sent = self._runners[address]
        try:
            if call is None:
                raise RuntimeError(f"the runner on {address} is gone")
            result = call.result()
            if result is None:
                result = runner.block(digest, pickle.dumps(block), payload).result()
            sent.add(digest)
            return pickle.loads(result)
        except Exception:
            if address not in self._client.scheduler_info().get("workers", {}):
                del self._runners[address]
            return self._scheduled(digest, payload, [block])[0]

    def _scheduled(self, digest: str, payload: bytes, blocks: list[list]) -> list[list]:
        """Blocks as tasks the scheduler places."""
        if digest not in self._scattered:
            self._scattered = {digest: self._client.scatter(payload, broadcast=True)}
        return self._client.gather([self._client.submit(_call_block, digest, self._scattered[digest], block,
                                                        pure=False) for block in blocks])

    def ready(self, modules: Sequence[str] = ()) -> None:
        """``modules`` imported on every worker (the cluster's workers have started with it)."""
        self._client.run(_import, tuple(modules))

    def close(self) -> None:
        self._client.close()
        if self._cluster is not None:
            self._cluster.close()

    def __exit__(self, kind, *exc):
        if kind is None:
            return self.close()
        # interrupted (or failed) with runners' calls in flight: the local scheduler's close would
        # log an error for each worker whose connection those calls left closed, after the
        # command's own one line
        log = logging.getLogger("distributed")
        level = log.level
        log.setLevel(logging.CRITICAL)
        try:
            self.close()
        finally:
            log.setLevel(level)


def make_executor(kind: str = "serial", workers: int | None = None, scheduler: str | None = None) -> Executor:
    """``serial``, ``process`` (``workers``, default: one per core) or ``dask`` (``scheduler``
    address, or a local cluster of ``workers``)."""
    if kind == "serial":
        return SERIAL
    if kind == "process":
        return ProcessExecutor(workers)
    if kind == "dask":
        return DaskExecutor(scheduler, workers)
    raise CalibError(f"unknown executor '{kind}': serial, process or dask")
