"""Model variants side by side: the same calibration chain run on the same data with a model
switch set differently (the propeller slipstream: off, the swirl alone, the theory, fitted), so that a user
sees what a piece of physics buys before it goes into the product.

A :class:`Variant` is data: the switch values the chain starts from and keeps, and the factors
it adds to a stage-2a step (fitted there like the step's own). Nothing is written: the chain
runs on the committed aircraft's files (:mod:`jsbsim_calib.calibration.workflow`), each variant from
neutral factors, as the main job does.
"""
from __future__ import annotations

import time
import warnings
from dataclasses import dataclass, field, replace
from functools import partial
from pathlib import Path
from typing import Callable, Mapping

import numpy as np

from ..core.errors import ModelError
from ..core.executor import SERIAL, Executor
from ..evaluation.evaluate import Evaluation, summary_dict
from ..factors import SWITCHES, FactorSet
from ..jsbsim.product import load_aircraft_geometry
from .fit import MAX_NFEV
from .steady import steady_factors
from .trims import TRIM_STEPS
from .workflow import run_dynamic, run_steady, run_trims

FULL_POWER = 0.95            # throttle at or above this: a full-power (slipstream-heavy) row


@dataclass(frozen=True)
class Variant:
    name: str
    doc: str
    switches: Mapping[str, float]                    # model switch values (factors.SWITCHES)
    fitted: Mapping[str, tuple[str, ...]] = field(default_factory=dict)   # stage-2a step -> factors added

    def __post_init__(self):
        unknown = [k for k in self.switches if k not in SWITCHES]
        steps = {s.name for s in TRIM_STEPS}
        unknown += [f"step {s}" for s in self.fitted if s not in steps]
        if unknown:
            raise ModelError(f"variant {self.name}: unknown {', '.join(unknown)}; switches: {', '.join(SWITCHES)}")


SLIPSTREAM = (
    Variant("off", "no slipstream (K_slip = K_swirl = 0): the method's model", {"K_slip": 0.0, "K_swirl": 0.0}),
    Variant("swirl", "the swirl at the fin only, as the theory gives it (K_swirl = 1, K_slip = 0)",
            {"K_slip": 0.0, "K_swirl": 1.0}),
    Variant("theory", "momentum theory as computed (K_slip = K_swirl = 1, not fitted)",
            {"K_slip": 1.0, "K_swirl": 1.0}),
    Variant("fitted", "stage 1 without it; stage 2a fits K_slip in the control step (the trim elevator from "
                      "full-power climbs to cruise) and K_swirl in the P-factor step (the climb rudder), from 0: the "
                      "steps' prior pulls both toward 0, the data must earn them",
            {"K_slip": 0.0, "K_swirl": 0.0}, {"control": ("K_slip",), "pfactor": ("K_swirl",)}),
)


@dataclass
class VariantResult:
    """One variant's chain: the factors it ends with and what it predicts after each stage."""

    variant: Variant
    factors: FactorSet
    poh: dict[str, Evaluation]                        # after the last stage run
    trims: dict[str, Evaluation]                      # flight-test trims after the last stage ({} without data)
    dynamic: dict[str, dict]                          # dynamic metric -> {"model", "measured", "verdict"}
    wall_time_s: float

    def to_json(self) -> dict:
        return {"variant": self.variant.name, "switches": dict(self.variant.switches),
                "fitted": {k: list(v) for k, v in self.variant.fitted.items()},
                "factors": self.factors.as_dict(), "figures": self.rows(), "wall_time_s": self.wall_time_s}

    def rows(self) -> dict[str, float | None]:
        """The figures the comparison reports, by label (None: not measured)."""
        out: dict[str, float | None] = {}
        for kind, metrics in (("poh_climb", ("roc_fpm",)), ("poh_cruise", ("rpm", "pct_power", "gph"))):
            s = summary_dict(self.poh[kind].summary()) if kind in self.poh else {}
            for m in metrics:
                if m in s:
                    out[f"{kind} {m} RMSE"] = s[m]["rmse"]
        snap = summary_dict(self.trims["snapshot"].summary()) if "snapshot" in self.trims else {}
        for m in ("pitch_deg", "elevator_deg", "aileron_deg", "rudder_deg"):
            if m in snap:
                out[f"trims {m} within %"] = snap[m]["within_pct"]
                out[f"trims {m} RMSE"] = snap[m]["rmse"]
        for m, rmse in full_power_rmse(self.trims).items():
            out[f"full-power {m} RMSE"] = rmse
        if self.dynamic:
            judged = [d["verdict"] for d in self.dynamic.values() if d["verdict"] != "n/a"]
            out[f"dynamic tests passed (of {len(judged)})"] = judged.count("PASS")
        competing = ("K_PF", "K_dr_slope", "K_de_slope") if self.trims else ()     # what the switches compete with
        for k in ("K_slip", "K_swirl") + competing:
            out[k] = self.factors[k]
        return out


def full_power_rmse(trims: Mapping[str, Evaluation]) -> dict[str, float]:
    """Elevator and rudder RMSE over the trimmed full-throttle rows (snapshots and flaps-down
    climbs): where the slipstream is strongest."""
    out = {}
    for m in ("elevator_deg", "rudder_deg"):
        err = [p.error[m] for ev in trims.values() for p in ev.points
               if p.trimmed and p.inputs.get("throttle_norm", 0.0) >= FULL_POWER and np.isfinite(p.error.get(m, np.nan))]
        if err:
            out[m] = float(np.sqrt(np.mean(np.square(err))))
    return out


def _steps_with(fitted: Mapping[str, tuple[str, ...]]):
    return tuple(replace(s, factors=s.factors + tuple(fitted.get(s.name, ()))) for s in TRIM_STEPS)


def run_variant(root: Path | str, name: str, variant: Variant, *, stages: str = "all",
                progress: Callable[[str], None] | None = None, executor: Executor = SERIAL,
                max_nfev: int | None = MAX_NFEV) -> VariantResult:
    """The chain (stage 1, then 2a and 2b where the aircraft has flight-test data and ``stages``
    is ``all``) from neutral factors with the variant's switches (``max_nfev``: evaluations per
    fit, the calibration's by default; fewer for a quick look)."""
    t0 = time.perf_counter()
    say = progress or (lambda s: None)
    start = FactorSet(dict(variant.switches))
    kw = {"progress": say, "executor": executor, "max_nfev": max_nfev}
    steady = run_steady(root, name, start=start, bands=False, **kw)
    factors, poh, trims, dynamic = steady.factors, steady.calibrated, {}, {}
    geom = load_aircraft_geometry(Path(root), name)
    if stages == "all" and "flight_test" in geom.data_files:
        tr = run_trims(root, name, start=steady_factors(factors), steps=_steps_with(variant.fitted), bands=False, **kw)
        factors, poh = tr.factors, tr.poh_after
        if "flight_test_results" in geom.data_files:
            dyn = run_dynamic(root, name, start=factors, bands=False, **kw)
            factors, poh, trims = dyn.factors, dyn.poh_after, dyn.trims_after
            dynamic = {f"{r.test.id} {m.metric.name}": {"model": m.model, "measured": m.metric.measured,
                                                       "verdict": m.verdict}
                       for r in dyn.dynamic_after.results for m in r.metrics}
        else:
            trims = {k: ev for k, ev in tr.evaluations[list(tr.evaluations)[-1]].items()}
    return VariantResult(variant, factors, poh, trims, dynamic, time.perf_counter() - t0)


def compare_variants(root: Path | str, name: str, variants=SLIPSTREAM, *, stages: str = "all",
                     progress: Callable[[str], None] | None = None,
                     executor: Executor = SERIAL, max_nfev: int | None = MAX_NFEV) -> list[VariantResult]:
    """Each variant's chain, in order. Without stage 2a (``stages="steady"`` or no flight-test
    data) a variant that only adds fitted factors to its steps is the same as its switches
    alone and is left out (a warning: the user asked for it). On an executor of several workers
    the variants are independent tasks (each chain's fits in its worker: the same bits, no
    progress lines from inside them); on one, they run here in turn with their progress."""
    say = progress or (lambda s: None)
    trims = stages == "all" and "flight_test" in load_aircraft_geometry(Path(root), name).data_files
    chosen = []
    for v in variants:
        if v.fitted and not trims:
            warnings.warn(f"variant {v.name}: left out (no stage 2a here, so nothing fits its factors)")
            continue
        chosen.append(v)
    if executor.workers > 1 and len(chosen) > 1:
        say(f"variants {', '.join(v.name for v in chosen)}: independent chains on {executor.describe()}")
        return executor.map(partial(run_variant, root, name, stages=stages, max_nfev=max_nfev), chosen)
    out = []
    for v in chosen:
        say(f"variant {v.name}: {v.doc}")
        out.append(run_variant(root, name, v, stages=stages, progress=say, executor=executor, max_nfev=max_nfev))
    return out
