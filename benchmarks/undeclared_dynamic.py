"""Undeclared time-domain effects outside the dynamic library, found from time histories.

Each case writes one effect the model lacks into a truth copy of the committed C172 (a
``<function>`` in its aerodynamic axis, :class:`jsbsim_calib.synthetic.truth.UndeclaredTerm`, or
a moment of inertia scaled); the truth flies the packaged Level 5 plan (``synth --plan level5``:
sensor noise and biases on, inputs included); the loop
(:func:`jsbsim_calib.calibration.closeloop_dynamic.close_loop_dynamic`) runs on the committed
model with those records. Cases (different axes and state products, one a moment of inertia):

* ``roll_aileron_qbar``: Cl += -4e-5 x aileron [deg] x qbar [psf] (aileron power falls with
  dynamic pressure: 40 % less at 40 psf);
* ``yaw_aileron_alpha``: Cn += -0.03 x aileron [deg] x alpha [rad] (adverse aileron yaw grows
  with angle of attack);
* ``pitch_elevator_qbar``: Cm += -4e-4 x elevator [deg] x qbar [psf];
* ``pitch_elevator_flaps``: Cm += 2e-4 x elevator [deg] x flaps [deg] (elevator power 25 % less
  at flaps 20: the downwash at the tail);
* ``ixx``: the roll moment of inertia x 2;
* ``library_yaw_roll_rate``: not undeclared: the dynamic library's ``yaw_due_to_roll_rate`` at
  K = -0.05 (Cn += K p b/2V), which the loop must add as that library effect.

A case is *found* when the loop adds a term on the truth's axis whose regressor is the truth's
(a synthesized effect may hold other terms: their fitted values are listed), or the right
inertia, with the coefficient within 25 %. The worst channel of the truth's axis is judged by its
RMS beyond its bias and noise (the loop's diagnosis), before and after.

    python benchmarks/undeclared_dynamic.py [--cases roll_aileron_qbar,...] [--seed 1] [--jobs N]

Prints one JSON row per run and the table; minutes per run on one core.
"""
from __future__ import annotations

import argparse
import json
import tempfile
from concurrent.futures import ProcessPoolExecutor, as_completed
from pathlib import Path

from fault_recovery import REPO, campaign_close_loop       # this folder: a sibling benchmark's run
from jsbsim_calib.calibration.closeloop_dynamic import CHANNEL_AXIS, dynamic_library
from jsbsim_calib.jsbsim.aircraft import moment_of_inertia, set_moment_of_inertia
from jsbsim_calib.jsbsim.simulator import Simulator
from jsbsim_calib.jsbsim.xml import read, write
from jsbsim_calib.synthetic.truth import UndeclaredTerm, root_copy, truth_copy

# case -> (moment axis, regressor or inertia, coefficient or scale, the loop's axis)
CASES = {"roll_aileron_qbar": ("ROLL", "aileron x qbar", -4e-5, "roll"),
         "yaw_aileron_alpha": ("YAW", "aileron x alpha", -0.03, "yaw"),
         "pitch_elevator_qbar": ("PITCH", "elevator x qbar", -4e-4, "pitch"),
         "pitch_elevator_flaps": ("PITCH", "elevator x flaps", 2e-4, "pitch"),
         "ixx": ("inertia", "ixx", 2.0, "roll"),
         "library_yaw_roll_rate": ("library", "yaw_due_to_roll_rate", -0.05, "yaw")}
COEFFICIENT = {"ROLL": "Cl", "YAW": "Cn", "PITCH": "Cm"}


def truth_for(case: str, tmp: Path) -> tuple[Path, Path]:
    axis, what, value, _ = CASES[case]
    root = root_copy(REPO, tmp / "root", folders=("aircraft", "engine", "airfoils", "data"))
    if axis == "library":
        truth = truth_copy(REPO / "aircraft" / "c172", tmp / "truth" / "c172", root=root)
        with Simulator.from_dir(truth, root) as s:
            eff = dynamic_library()[what]
            s.add_effect(eff, {f.property: value for f in eff.factors})
            write(s.aircraft_tree(), truth / "c172.xml")
        return truth, root
    if axis != "inertia":
        return truth_copy(REPO / "aircraft" / "c172", tmp / "truth" / "c172",
                          [UndeclaredTerm(axis, value, what)], root=root), root
    truth = truth_copy(REPO / "aircraft" / "c172", tmp / "truth" / "c172", root=root)
    t = read(truth / "c172.xml")
    set_moment_of_inertia(t, what, value * moment_of_inertia(t, what))
    write(t, truth / "c172.xml")
    return truth, root


def found(case: str, res) -> tuple[str, float | None]:
    """The added change that names the truth's states and axis, and its fitted value."""
    axis, what, _, _ = CASES[case]
    if axis == "library":
        label = f"{what}.{dynamic_library()[what].factors[0].name}"
        return (what, res.factors[label]) if what in res.added else ("", None)
    if axis == "inertia":
        c = next((c for c in res.candidates if c.accepted and c.effect == f"inertia {what}"), None)
        return (c.effect, c.factors.get(f"{what}_scale")) if c else ("", None)
    key = f"{COEFFICIENT[axis]}_{what.replace(' x ', '_x_')}"
    for name in res.added:
        label = f"{name}.{key}"
        if name.startswith("synth_") and label in res.factors.extra:
            return name, res.factors[label]
    return "", None


def one_run(case: str, seed: int) -> dict:
    axis, what, value, loop_axis = CASES[case]
    with tempfile.TemporaryDirectory() as d:
        res, wall = campaign_close_loop(*truth_for(case, Path(d)), seed, Path(d))
    name, got = found(case, res)
    err = abs(got / value - 1.0) if got is not None else None
    chans = [c for c in res.diagnosis_before if CHANNEL_AXIS.get(c) == loop_axis]
    worst = max(chans, key=lambda c: res.diagnosis_before[c].beyond / res.diagnosis_before[c].scale)
    b, a = res.diagnosis_before[worst].beyond, res.diagnosis_after[worst].beyond
    return {"case": case, "seed": seed, "added": res.added, "found": name, "fitted": got, "truth": value,
            "error": err, "within_25pct": bool(err is not None and err <= 0.25), "worst_channel": worst,
            "beyond_before": b, "beyond_after": a, "after_over_before": a / b if b > 0 else None,
            "rms_before": res.errors("before")[loop_axis][worst].rms,
            "rms_after": res.errors("after")[loop_axis][worst].rms, "wall_s": round(wall, 1),
            "added_factors": {n: res.factors[n] for n in res.factors.extra},
            "tried": [f"{c.effect}: {c.reason}" for c in res.candidates]}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--cases", default=",".join(CASES))
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--jobs", type=int, default=1, help="runs at once (processes; default 1)")
    ap.add_argument("--json", help="write the runs as JSON")
    a = ap.parse_args(argv)
    runs = []
    with ProcessPoolExecutor(a.jobs) as pool:          # each run is independent: one process per run
        for done in as_completed([pool.submit(one_run, c, a.seed) for c in a.cases.split(",")]):
            runs.append(done.result())
            print(json.dumps(runs[-1]), flush=True)
    runs.sort(key=lambda r: list(CASES).index(r["case"]))
    print("\n| case | added | truth | fitted | error | worst channel | beyond noise before -> after | "
          "RMS before -> after | wall [s] |")
    print("|---|---|---:|---:|---:|---|---:|---:|---:|")
    for r in runs:
        fitted = f"{r['fitted']:.4g}" if r["fitted"] is not None else "-"
        err = f"{100 * r['error']:.0f} %" if r["error"] is not None else "-"
        print(f"| {r['case']} | {', '.join(r['added']) or 'nothing'} | {r['truth']:.4g} | {fitted} | {err} | "
              f"{r['worst_channel']} | {r['beyond_before']:.3g} -> {r['beyond_after']:.3g} | "
              f"{r['rms_before']:.3g} -> {r['rms_after']:.3g} | {r['wall_s']} |")
    if a.json:
        Path(a.json).write_text(json.dumps(runs, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
