"""Fault recovery on time histories, set against jsbsim-deviations' published recalls.

A fault is injected into a truth copy of the committed C172; the truth flies the packaged
Level 5 plan (``synth --plan level5``, sensor noise on, one campaign per seed); the loop
(:func:`jsbsim_calib.calibration.closeloop_dynamic.close_loop_dynamic`) runs on the committed
model with those records. A run *names* the fault when the change it adds first is the faulty
factor or moment of inertia; it *restores* it when the fitted change is within 10 % of the
injected one. Faults (the model's own derivatives at cruise, by
:func:`jsbsim_calib.jsbsim.probes.trim_derivatives`):

* ``Cm_alpha x0.7``: K_Cm_alpha moved so that the total Cm_alpha is 0.7 of the model's;
* ``Cmq x0.5``: K_Cmq moved so that the total Cm_q is half the model's;
* ``inertia x1.6``: the pitch moment of inertia (``mass_balance/iyy``) 1.6 times the model's.

jsbsim-deviations (a tool that detects FDM changes) reports recalls of 0.59, 0.45 and 0.27 on
these faults; the issue's bar is >= 95 % named and restored.

    python benchmarks/fault_recovery.py [--seeds 5] [--faults cm_alpha,cmq,iyy] [--jobs N] [--plan PLAN]

``--plan``: the campaign the truth flies (default the Level 5 plan; e.g. the identification plan
that ``jsbsim-calib plan c172`` designs, ``reports/c172/plan/plan.toml``).

Prints one row per run and the table; takes minutes per run on 2 cores.
"""
from __future__ import annotations

import argparse
import json
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor, as_completed
from pathlib import Path

from jsbsim_calib.calibration.closeloop_dynamic import close_loop_dynamic
from jsbsim_calib.data.flighttest import load_control_travel
from jsbsim_calib.evaluation.evaluate_dynamic import load_recorded_tests
from jsbsim_calib.flight.condition import Condition
from jsbsim_calib.jsbsim.aircraft import moment_of_inertia, set_factor_values, set_moment_of_inertia
from jsbsim_calib.jsbsim.probes import trim_derivatives
from jsbsim_calib.jsbsim.simulator import Simulator
from jsbsim_calib.jsbsim.xml import read, write
from jsbsim_calib.synthetic.maneuvers import load_plan, synthesize_maneuvers
from jsbsim_calib.synthetic.truth import root_copy, truth_copy

REPO = Path(__file__).resolve().parents[1]
CRUISE = Condition(pressure_alt_ft=5500, weight_lb=2400, ktas=110, cg_in=42.0)
PUBLISHED = {"cm_alpha": 0.59, "cmq": 0.45, "iyy": 0.27}
FACTOR_OF = {"cm_alpha": "K_Cm_alpha", "cmq": "K_Cmq"}
TITLES = {"cm_alpha": "Cm_alpha x0.7", "cmq": "Cmq x0.5", "iyy": "inertia x1.6"}


def fault_values(sim: Simulator) -> dict[str, tuple[str, float, float]]:
    """fault -> (what the loop must name, the model's value, the truth's value)."""
    d = trim_derivatives(sim, CRUISE)
    k_a, k_q = sim.factors["K_Cm_alpha"], sim.factors["K_Cmq"]
    cm_a, cm_q = d.Cm_alpha, d.Cm_q
    return {"cm_alpha": ("factor K_Cm_alpha", k_a, k_a - 0.3 * cm_a),      # Cm_alpha total x 0.7
            "cmq": ("factor K_Cmq", k_q, k_q + 0.5 * cm_q),               # -K_Cmq qhat: total x 0.5
            "iyy": ("inertia iyy", 1.0, 1.6)}


def truth_for(fault: str, values, tmp: Path) -> tuple[Path, Path]:
    root = root_copy(REPO, tmp / "root", folders=("aircraft", "engine", "airfoils", "data"))
    truth = truth_copy(REPO / "aircraft" / "c172", tmp / "truth" / "c172", root=root)
    t = read(truth / "c172.xml")
    _, _, value = values[fault]
    if fault == "iyy":
        set_moment_of_inertia(t, "iyy", value * moment_of_inertia(t, "iyy"))
    else:
        set_factor_values(t, {FACTOR_OF[fault]: value})
    write(t, truth / "c172.xml")
    return truth, root


def campaign_close_loop(truth: Path, root: Path, seed: int, tmp: Path, plan: str = "level5"):
    """The truth flies the plan (a packaged name or a file; sensor noise on); the loop runs on
    the committed model with its records: the result and the loop's wall time."""
    with Simulator.from_dir(truth, root) as t:
        synthesize_maneuvers(t, load_plan(plan), tmp / "data", seed=seed)
    with Simulator(REPO, "c172") as sim:
        f = sim.geometry.control_travel_file
        tests = load_recorded_tests(tmp / "data", load_control_travel(f) if f else None)
        t0 = time.perf_counter()
        res = close_loop_dynamic(sim, tests)
        return res, time.perf_counter() - t0


def one_run(fault: str, seed: int, values, plan: str = "level5") -> dict:
    name, model_value, truth_value = values[fault]
    with tempfile.TemporaryDirectory() as d:
        res, wall = campaign_close_loop(*truth_for(fault, values, Path(d)), seed, Path(d), plan)
    first = res.added[0] if res.added else ""
    accepted = next((c for c in res.candidates if c.accepted and c.effect == first), None)
    if fault == "iyy":
        got = accepted.factors.get("iyy_scale") if accepted else None
    else:
        got = res.factors[name.split()[1]] if first == name else None
    change = truth_value - model_value
    err = abs((got - model_value) / change - 1.0) if got is not None and change else None
    return {"fault": fault, "seed": seed, "added": res.added, "named": first == name, "fitted": got,
            "truth": truth_value, "model": model_value, "error_of_change": err,
            "restored": bool(first == name and err is not None and err <= 0.10), "wall_s": round(wall, 1),
            "structured": [c for c, d in res.diagnosis_before.items() if d.structured],
            "candidate_alone": accepted.factors if accepted else None,
            "refit": {n: res.factors[n] for fr in res.refits for n in fr.names if n in res.factors},
            "tried": [f"{c.effect}: {c.reason}" for c in res.candidates]}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", type=int, default=5)
    ap.add_argument("--faults", default="cm_alpha,cmq,iyy")
    ap.add_argument("--jobs", type=int, default=1, help="runs at once (processes; default 1)")
    ap.add_argument("--plan", default="level5", help="the plan the truth flies: a packaged name or a plan file "
                    "(e.g. reports/c172/plan/plan.toml, designed by `jsbsim-calib plan c172`)")
    ap.add_argument("--json", help="write the runs as JSON")
    a = ap.parse_args(argv)
    with Simulator(REPO, "c172") as sim:
        values = fault_values(sim)
    jobs = [(fault, seed) for fault in a.faults.split(",") for seed in range(1, a.seeds + 1)]
    runs = []
    with ProcessPoolExecutor(a.jobs) as pool:          # each run is independent: one process per run
        for done in as_completed([pool.submit(one_run, fault, seed, values, a.plan) for fault, seed in jobs]):
            runs.append(done.result())
            print(json.dumps(runs[-1]), flush=True)
    runs.sort(key=lambda r: (r["fault"], r["seed"]))
    print("\n| fault | runs | named | named and within 10 % | jsbsim-deviations recall | median wall [s] |")
    print("|---|---:|---:|---:|---:|---:|")
    for fault in a.faults.split(","):
        rs = [r for r in runs if r["fault"] == fault]
        walls = sorted(r["wall_s"] for r in rs)
        print(f"| {TITLES[fault]} | {len(rs)} | {sum(r['named'] for r in rs) / len(rs):.0%} | "
              f"{sum(r['restored'] for r in rs) / len(rs):.0%} | {PUBLISHED[fault]:.2f} | {walls[len(walls) // 2]} |")
    if a.json:
        Path(a.json).write_text(json.dumps(runs, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
