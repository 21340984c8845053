"""The two roll responses (C.58 cruise, C.60 approach; Part 60 2.d.2) against the candidate
effects issue 24 names: can one physical term, fitted with the roll damping, meet both?

    python benchmarks/roll_trace.py

First the wheel step at which the product itself meets each steady rate (the step's size was
not recorded; the thesis flew the recorded wheel).

For each candidate term of the close-loop's dictionary (``Delta Cl = K x regressor``, the
same XML the loop would add), K and K_Clp are solved so that both steady roll rates meet the
flight test (two rates, two unknowns); the script prints K, K_Clp, both rates, what the term
does to the aileron or damping at each test's condition (the physical check), and what it does
to the roll pulses C.25 / C.27 and to the 20 flight-test trims' aileron. Real JSBSim, the
committed C172; about 15 s.
"""
from __future__ import annotations

import math
import warnings
from dataclasses import replace
from pathlib import Path

import numpy as np
from scipy.optimize import least_squares

from jsbsim_calib.calibration.dynamic import AMPLITUDE_RANGE
from jsbsim_calib.calibration.synthesis import Term, term_effect
from jsbsim_calib.calibration.workflow import dynamic_tests, load_data_for
from jsbsim_calib.data.dynamic_tests import ROLL_STEP_FRACTION
from jsbsim_calib.evaluation.evaluate import evaluate_dataset
from jsbsim_calib.evaluation.evaluate_dynamic import fly_test
from jsbsim_calib.jsbsim.probes import trim_derivatives
from jsbsim_calib.jsbsim.simulator import Simulator

REPO = Path(__file__).resolve().parents[1]
STEPS, PULSES = ("C.58", "C.60"), ("C.25", "C.27")
TRIMS_WITHIN = 95.0              # the trims' target: within +-1 deg on 95 % of the rows
CANDIDATES = (                   # regressor of the roll axis, what a fitted K would mean
    ("aileron x qbar", "aileron deflection lost with dynamic pressure (cable stretch, hinge moment)"),
    ("aileron x alpha", "aileron power varying with angle of attack"),
    ("aileron x flaps", "aileron power varying with the flaps"),
    ("p b/2V x flaps", "roll damping varying with the flaps"),
    ("p b/2V x alpha", "roll damping varying with angle of attack"),
)


def rates(sim: Simulator, tests) -> dict[str, float]:
    out = {}
    for t in tests:
        sim.fresh()
        sim.trim_cache = {}
        r = fly_test(sim, t)
        out[t.id] = r.metrics[0].model
    return out


def aileron_within(sim: Simulator, ds) -> tuple[float, float]:
    s = evaluate_dataset(sim, ds).summary()["aileron_deg"]
    return s.rmse, s.within_pct


def main() -> None:
    warnings.simplefilter("ignore")
    tests = {t.id: t for t in dynamic_tests(REPO, "c172") if t.id in STEPS + PULSES}
    target = {i: tests[i].metrics[0].measured for i in STEPS + PULSES}
    with Simulator(REPO, "c172") as base:
        ds = load_data_for(base, REPO / "data" / "c172_flight_test_snapshots.csv")
        r0, a0 = rates(base, tests.values()), aileron_within(base, ds)
        print(f"flight test: {', '.join(f'{k} {v:+.1f}' for k, v in target.items())} deg/s")
        print(f"product (K_Clp {base.factors['K_Clp']:.4g}): {', '.join(f'{k} {v:+.1f}' for k, v in r0.items())} "
              f"deg/s; trims' aileron RMSE {a0[0]:.2f} deg, {a0[1]:.0f} % within +-1 deg")
        for i in STEPS:
            frac = step_meeting(base, tests[i], target[i])
            print(f"{i}: the product meets {target[i]:+.1f} deg/s with a wheel step of {frac:.3f} of the travel "
                  f"(assumed {ROLL_STEP_FRACTION:.3f}: 'about one-third'); the thesis flew the recorded wheel")
        for t in tests.values():
            d, c = trim_derivatives(base, t.maneuver.start), t.maneuver.start
            print(f"{t.id}: {d.ktas:.0f} KTAS, flaps {c.flaps_deg:g}, alpha {d.alpha_deg:.1f} deg, "
                  f"qbar {d.qbar_psf:.1f} psf, the product's Cl_p {d.Cl_p:+.4f} (K_Clp included)")
        print(f"\n{'candidate':<18} {'K':>11} {'K_Clp':>8}  {'C.58':>6} {'C.60':>6}  {'C.25':>6} {'C.27':>6}  "
              f"{'aileron trims':>15}  what K means at C.58 / C.60")
        for regressor, meaning in CANDIDATES:
            print(trace(base, regressor, meaning, tests, target, ds))


def step_meeting(sim: Simulator, test, measured: float) -> float:
    """The wheel step, as a share of the travel, at which the model's steady roll rate is the
    flight test's (secant iterations on the step's size; the rate is nearly proportional)."""
    inp = test.maneuver.inputs[0]

    def rate(scale: float) -> float:
        m = replace(test.maneuver, inputs=(replace(inp, value=tuple(v * scale for v in inp.value)),))
        return rates(sim, [replace(test, maneuver=m)])[test.id] - measured

    a, fa = 1.0, rate(1.0)
    b = measured / (fa + measured)
    for _ in range(6):
        fb = rate(b)
        if abs(fb) < 0.01 or fb == fa:
            break
        a, b, fa = b, b - fb * (b - a) / (fb - fa), fb
    return b * ROLL_STEP_FRACTION


def trace(base: Simulator, regressor: str, meaning: str, tests, target, ds) -> str:
    """The term added to a copy of the product, K and K_Clp solved so that both steps meet the
    flight test; the row: the fit, the pulses, the trims and what the term breaks."""
    f, k_clp = base.factors.factor("K_Clp"), base.factors["K_Clp"]
    eff = term_effect([Term("ROLL", regressor)], [1e4], source="roll_trace", affects=("roll_rate_deg_s",))
    extra = eff.as_factors()
    steps = [tests[i] for i in STEPS]
    with base.clone() as sim:
        sim.add_effect(eff)
        start = base.factors.with_extra(extra)

        def flown(x) -> dict[str, float]:
            sim.set_factors(start.updated({"K_Clp": float(x[1]), next(iter(extra)): float(x[0])}))
            return rates(sim, steps)

        def residual(x):
            got = flown(x)
            r = np.array([(got[i] - target[i]) / 2.0 for i in STEPS])
            return np.where(np.isfinite(r), r, 50.0)         # a step the model cannot fly: the solver's penalty

        slope = float(np.max(np.abs(residual([1e-3, k_clp]) - residual([0.0, k_clp])))) / 1e-3
        fit = least_squares(residual, [0.0, k_clp], bounds=([-np.inf, f.lower], [np.inf, f.upper]),
                            x_scale=[1.0 / slope if slope > 0 else 1.0, 0.1], diff_step=1e-3)
        k, clp = fit.x
        power = _power(flown(np.array([k, k_clp])), flown(np.array([0.0, k_clp])))
        residual(fit.x)
        got, trims = rates(sim, tests.values()), aileron_within(sim, ds)
    both = all(abs(got[i] - target[i]) <= 2.0 for i in STEPS)
    return (f"{regressor:<18} {k:>11.4g} {clp:>8.4g}  {_rate(got['C.58'])} {_rate(got['C.60'])}  "
            f"{_rate(got['C.25'])} {_rate(got['C.27'])}  {trims[0]:>5.2f} / {trims[1]:3.0f} %  "
            f"{'both steps met' if both else 'steps NOT met'}; {meaning}: {power}; "
            f"{'; '.join(_conflicts(got, target, trims, clp, f)) or 'no conflict'}")


def _rate(v: float) -> str:
    """A steady or peak roll rate for the table; "n/f" where the maneuver could not be flown."""
    return f"{v:>+6.1f}" if np.isfinite(v) else f"{'n/f':>6}"


def _conflicts(got, target, trims, clp, f) -> list[str]:
    """What the fitted term breaks: a roll pulse no amplitude in the stated range explains (its
    peak rate is proportional to the unrecorded amplitude), the trims' aileron below its
    target, K_Clp on a bound."""
    out = []
    for i in PULSES:
        need = target[i] / got[i] if np.isfinite(got[i]) and got[i] else math.nan
        if not AMPLITUDE_RANGE[0] <= need <= AMPLITUDE_RANGE[1]:
            out.append(f"{i} needs the pulse x{need:.2f} (range x{AMPLITUDE_RANGE[0]:g}-x{AMPLITUDE_RANGE[1]:g})"
                       if np.isfinite(need) else f"{i} not flown")
    if not trims[1] >= TRIMS_WITHIN:
        out.append(f"trims' aileron {trims[1]:.0f} % within +-1 deg (target {TRIMS_WITHIN:.0f} %)")
    if min(clp - f.lower, f.upper - clp) <= 1e-6 * (f.upper - f.lower):
        out.append(f"K_Clp on its bound ({clp:g})")
    return out


def _power(with_k: dict[str, float], without: dict[str, float]) -> str:
    """What the term alone does at each step: the steady roll rate with it over the rate
    without it, both at the product's K_Clp (for an aileron term the aileron power's ratio,
    for a damping term the inverse of the damping's); NaN where a step is not flown."""
    return "roll rate x" + " / x".join(f"{with_k[i] / without[i]:.2f}" for i in STEPS)


if __name__ == "__main__":
    main()
