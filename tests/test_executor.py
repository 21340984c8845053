"""Independent work on other executors gives the same bits: a fit whose Jacobian columns and
trial points run in a process pool or on a dask.distributed LocalCluster lands on exactly the
factors of the same fit in this process; a Simulator pickles and rebuilds; a fresh load is
history-free, and so is a reset after trims; propeller tables kept per factor set fly as
freshly baked ones."""
from __future__ import annotations

import contextlib
import os
import pickle
import sys
import time
import warnings
from dataclasses import replace
from pathlib import Path

import cloudpickle
import numpy as np
import pytest

from jsbsim_calib.calibration.fit import fit
from jsbsim_calib.calibration.points import KINDS, PointSet, point_residuals
from jsbsim_calib.evaluation.evaluate_dynamic import evaluate_dynamic
from jsbsim_calib.core.executor import SERIAL, DaskExecutor, ProcessExecutor, make_executor
from jsbsim_calib.core.errors import CalibError
from jsbsim_calib.flight.condition import Condition
from jsbsim_calib.jsbsim.simulator import Simulator
from jsbsim_calib.calibration.workflow import aircraft_data, dynamic_tests

REPO = Path(__file__).resolve().parents[1]
A = Condition(pressure_alt_ft=5500, weight_lb=2400, ktas=110, cg_in=42.0)
B = Condition(pressure_alt_ft=1000, weight_lb=2550, kcas=74, cg_in=41.0, mode="full_throttle", mixture="climb")


def _small_fit(executor):
    """K_HP and K_CQ_scale (a baked propeller factor: the workers re-bake their tables) on six
    POH points of the C172, from neutral."""
    data = aircraft_data(REPO, "c172")
    with Simulator(REPO, "c172", baseline=True) as sim:
        climb = PointSet.from_dataset(data["poh_climb"], sim, [0, 10, 20])
        cruise = PointSet.from_dataset(data["poh_cruise"], sim, [3, 17, 32])

        def residuals(fs):
            sim.set_factors(fs)
            r1, l1, _ = point_residuals(sim, climb, ("roc_fpm",))
            r2, l2, _ = point_residuals(sim, cruise, ("rpm",))
            return np.array(r1 + r2), l1 + l2

        out = fit("executor test", ["K_HP", "K_CQ_scale"], sim.factors, residuals, sim=sim, max_nfev=40,
                  executor=executor)
        return out.final.as_dict(), out.cost_final, out.nfev, out.trims, sim.trims     # counts too: any executor


def test_a_fresh_load_is_history_free():
    results = []
    for history in ([], [B], [B, A, B]):
        with Simulator(REPO, "c172") as sim:
            for c in history:
                sim.trim(c)
            sim.fresh()
            t = sim.trim(A)
            results.append((t.alpha_deg, t.elevator_deg, t.throttle, t.rpm))
    assert results[0] == results[1] == results[2]


def _properties(fdm) -> dict[str, float]:
    """Every property of a JSBSim but the gear's side friction, which JSBSim leaves uninitialized
    until a wheel touches the ground (two fresh loads differ there too)."""
    names = [line.split()[0] for line in fdm.query_property_catalog("").splitlines() if line.strip()]
    return {n: fdm[n] for n in names if not n.endswith("side_friction_coeff")}


def _differences(a: dict, b: dict) -> list[str]:
    same = lambda x, y: x == y or (x != x and y != y)          # NaN where both are NaN
    return [f"{n}: {a[n]!r} vs {b.get(n)!r}" for n in a if not same(a[n], b.get(n))] + \
        [f"{n} missing" for n in b if n not in a]


PILOT = ("accelerations/a-pilot-", "accelerations/n-pilot-")   # outputs of the last frame, fed back nowhere


@pytest.mark.parametrize("name, kinds", [("c172", ("poh_climb", "poh_cruise", "flight_test", "flap_climb")),
                                         ("sr20", ("poh_climb", "poh_cruise"))])
def test_a_reset_after_trims_of_every_kind_is_a_fresh_load(name, kinds):
    """fresh() after trims resets the loaded JSBSim instead of loading it again: every property
    is then a fresh load's (the pilot's accelerations aside, which the first frame recomputes:
    checked after a trim), and a trim from there gives a fresh load's bits. The history: a spread
    of every data kind (flaps, weights, altitudes, the SR20's governor), a turn and a trim with
    no equilibrium."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        data = aircraft_data(REPO, name, kinds)
    with Simulator(REPO, name) as sim, Simulator(REPO, name) as loaded:
        conds = []
        for ds in data.values():
            cs = KINDS[ds.kind].conditions(ds, sim.geometry)
            conds += cs[::max(1, len(cs) // 5)]
        conds += [replace(conds[0], kcas=25.0), replace(conds[-1], bank_deg=30.0, turn="coordinated")]
        results = [sim.trim(c, key=i) for i, c in enumerate(conds)]
        assert not results[-2].trimmed and sum(r.trimmed for r in results) >= 15
        loads = sim.loads
        sim.fresh()
        assert (sim.loads, sim.resets) == (loads, 1)               # reset, not loaded
        got, want = _properties(sim.fdm), _properties(loaded.fdm)
        assert not [d for d in _differences(got, want) if not d.startswith(PILOT)]
        probe = conds[len(conds) // 2]
        a, b = sim.trim(probe), loaded.trim(probe)
        assert a.trimmed and (a.alpha_deg, a.elevator_deg, a.throttle, a.rpm) == \
            (b.alpha_deg, b.elevator_deg, b.throttle, b.rpm)
        assert not _differences(_properties(sim.fdm), _properties(loaded.fdm))


def test_a_jsbsim_handed_out_is_loaded_anew():
    """What a caller did with ``sim.fdm`` is not known: the next fresh() loads the aircraft."""
    with Simulator(REPO, "c172") as sim:
        sim.trim(A)
        sim.fresh()
        assert (sim.loads, sim.resets) == (1, 1)
        sim.fdm.run()
        sim.fresh()
        assert (sim.loads, sim.resets) == (2, 1)


def test_propeller_tables_kept_per_factor_set_fly_as_freshly_baked_ones():
    """A propeller factor set met again flies on the tables kept for it (no re-bake) exactly as
    a simulator that baked them afresh; a propeller change reloads (set_factors says so), any
    other factor does not."""
    with Simulator(REPO, "c172") as sim:
        start = sim.factors
        assert sim.set_factors(start.replace(K_CT_scale=start["K_CT_scale"] * 1.02)) is True
        assert sim.set_factors(start) is True                     # the kept tables of the start
        assert sim.set_factors(start.replace(K_Clp=0.05)) is False
        sim.set_factors(start)
        sim.fresh()
        kept = sim.trim(A)
    with Simulator(REPO, "c172") as fresh:
        baked = fresh.trim(A)
    assert (kept.rpm, kept.alpha_deg, kept.throttle) == (baked.rpm, baked.alpha_deg, baked.throttle)


def test_a_simulator_pickles_as_what_it_flies():
    with Simulator(REPO, "c172") as sim:
        sim.set_factors(sim.factors.replace(K_Clp=0.1, K_CT_scale=0.95))
        other = cloudpickle.loads(cloudpickle.dumps(sim))
        try:
            assert other.sandbox != sim.sandbox and other.factors == sim.factors
            sim.fresh()
            other.fresh()
            assert sim.trim(A).alpha_deg == other.trim(A).alpha_deg
        finally:
            other.close()
    assert not other.sandbox.exists()


@pytest.mark.slow
def test_process_pool_and_dask_give_the_same_bits_as_this_process():
    serial = _small_fit(SERIAL)
    with ProcessExecutor(2) as pool:
        assert _small_fit(pool) == serial
    with DaskExecutor(workers=2) as dask:
        assert dask.workers == 2
        assert _small_fit(dask) == serial
        fleet = "jsbsim_calib.evaluation.fleet"                                   # nothing above imports it
        assert not any(dask._client.run(lambda: fleet in sys.modules).values())
        dask.ready([fleet])
        assert all(dask._client.run(lambda: fleet in sys.modules).values())
        assert dask.map(abs, list(range(-9, 0)), key="abs") == list(range(9, 0, -1))   # 9 items in 2 strided blocks: in order


def test_dask_runners_resend_a_dropped_function_and_outlive_a_lost_worker():
    """A batch goes to each worker's runner (an actor) as one pickled block: a runner that has
    let a function go gets it again, and a batch whose worker was lost runs elsewhere, in
    order, and then without that runner. A task's own error still reaches the caller."""
    with DaskExecutor(workers=2) as dask:
        items = list(range(-9, 0))
        fns = [lambda x, k=k: x * k for k in range(6)]
        for k, fn in enumerate(fns):                # more functions than a runner keeps: the first dropped
            assert dask.map(fn, items, key=f"f{k}") == [x * k for x in items]
        assert dask.map(fns[1], items, key="f1") == items        # the runner asks for it again
        lost = dask._addresses[0]
        with contextlib.suppress(Exception):     # the worker exits while answering
            dask._client.run(os._exit, 1, workers=[lost])
        for _ in range(20):                      # the scheduler hears of it within a second or so
            if lost not in dask._client.scheduler_info().get("workers", {}):
                break
            time.sleep(0.2)
        assert dask.map(abs, items, key="abs") == list(range(9, 0, -1))
        assert lost not in dask._runners
        with pytest.raises(ZeroDivisionError):
            dask.map(lambda x: 1 / x, [1, 0, 2], key="inverse")


def test_a_ready_pool_has_every_worker_started():
    with ProcessExecutor(2) as pool:
        assert not pool._pool._processes                  # a pool starts with its first batch
        pool.ready(["jsbsim_calib.calibration.fit"])
        assert len(pool._pool._processes) == 2
        pool.ready()                                      # again: the same two
        assert len(pool._pool._processes) == 2 and pool.map(abs, [-1, -2]) == [1, 2]


def test_dynamic_tests_fly_the_same_on_a_pool():
    tests = dynamic_tests(REPO, "c172")[:4]
    with Simulator(REPO, "c172") as sim:
        a = evaluate_dynamic(sim, tests)
        with ProcessExecutor(2) as pool:
            b = evaluate_dynamic(sim, tests, executor=pool)
    assert [m.model for m in a.metric_results()] == [m.model for m in b.metric_results()]


def test_flying_the_dynamic_tests_here_keeps_the_callers_warm_starts():
    """Evaluating the dynamic tests in this process (SERIAL) leaves the simulator's trim warm
    starts as they were, as on a pool (whose workers fly copies): a fit that follows starts
    from the same warm starts on every executor (it did not, and stage 2b landed 1e-10 apart)."""
    tests = dynamic_tests(REPO, "c172")[:1]
    with Simulator(REPO, "c172") as sim:
        sim.trim(A, key="A")
        before = {k: (x.tobytes(), pickle.dumps(lu)) for k, (x, lu) in sim.trim_cache.items()}   # lu: J factored
        evaluate_dynamic(sim, tests)
        assert before and {k: (x.tobytes(), pickle.dumps(lu)) for k, (x, lu) in sim.trim_cache.items()} == before


def test_unknown_executor_is_refused():
    with pytest.raises(CalibError, match="unknown executor"):
        make_executor("threads")


class _HoldsItsExecutor:
    """A task that holds the executor it runs on, as a close-loop evidence does, with some data."""

    def __init__(self, executor):
        self.executor, self.data = executor, np.arange(20000.0)

    def __call__(self, item):
        return item


def test_a_task_holding_its_executor_pickles_to_the_same_size_call_after_call():
    """The executor pickles without its serialized functions: a task holding it carried every
    earlier payload, so each keyed call's payload doubled (a close-loop run reached 19 GB)."""
    ex = make_executor("serial")
    task = _HoldsItsExecutor(ex)
    sizes = []
    for k in range(5):
        assert ex.map(task, [k], key=f"call {k}") == [k]
        sizes.append(len(cloudpickle.dumps(task)))
    assert max(sizes) - min(sizes) < 1000, sizes
    assert pickle.loads(pickle.dumps(ex)).map(task, [7], key="again") == [7]
