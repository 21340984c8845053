"""Close the loop on trims: the engine of :mod:`.loop` with trim data as its evidence.

:func:`close_loop` works on any aircraft and any trim data (flight-test snapshots, flap
climbs, POH climb/cruise, G1000 segments); :class:`TrimEvidence` is what trims bring to the
one loop (rows, diagnosis, folds, candidates, the synthesis of terms); the steps:

1. evaluate the model; diagnose the residuals (:mod:`jsbsim_calib.calibration.diagnose`);
2. split the points: every :data:`HOLDOUT`-th is held out, the rest are fitted;
3. for every library effect the model lacks (and that moves a metric of the data): add it
   to a copy of the aircraft, fit its factor(s) alone on the fitted points (residuals /
   tolerance with the stages' penalties), and score it by the change of the Bayesian
   information criterion ``-(chi2_0 - chi2_1) + k ln(n)``, each metric's residuals scaled by
   its noise as the diagnosis estimates it (n residuals, k the effect's factors). An effect
   of the same form as a calibration factor (``same_as``, e.g. p_factor and K_PF) adds to
   it; that factor is then not refitted with it;
4. accept the best candidate only if the evidence is strong (:data:`MIN_EVIDENCE`), it
   pays for itself out of sample (4-fold cross-validation: every point predicted by a fit
   that did not see it; the residuals must fall by :data:`MIN_HELD_GAIN`), it changes some
   prediction by a material share of a tolerance (:data:`MATERIAL`), and it explains most
   of the structure (:data:`MIN_EXPLAINED` of the residual sum of squares beyond the noise
   the diagnosis estimates, in the structured metrics it moves; what it makes worse
   elsewhere counts against it): a library effect that only grazes an unknown effect is not
   attributed; then refit the added effects' factors together with the stage-2a factors
   acting on the same metrics (:func:`companion_factors`: fitted without the effect, they may
   have stood in for it);
5. when no library effect passes and structure remains, synthesize the missing term
   (:mod:`.synthesis`, section "synthesis" below): candidate terms of the structured
   metrics' axes, linearized by JSBSim, the sparsest set selected, written as an effect, fitted
   with the fit engine and judged by the same rules, plus a null test of the selection
   (shuffled residuals) and a cross-validation that repeats the selection in every fold; a
   library effect that explains the data always wins (it is tried first, every round); an
   added term holds the levers of its metrics (:func:`_synthesized_effect`);
6. repeat until no candidate passes; diagnose again: what is still structured is reported
   as unexplained, with the states it correlates with, not attributed.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np

from ..core.executor import SERIAL
from ..data.schemas import METRICS, Dataset
from ..evaluation.evaluate import KINDS, Evaluation, Summary, evaluate_dataset, summarize, summary_dict
from ..factors import FactorSet, levers
from ..jsbsim.simulator import Simulator
from ..jsbsim.xml import Tree
from .diagnose import ALPHA, MetricDiagnosis, diagnose
from .effects import Effect, library
from .fit import FitResult
from .loop import (MAX_EFFECTS, LoopResult, NOISE_FLOOR, Candidate, Change,
                   LoopRun, Round, Rows, cross_validate, fit_change, run_loop)
from .points import FAIL_PENALTY
from .synthesis import Linearization, Selection, Synthesis, dictionary_for, linearize, null_test, select, term_effect
from .terms import axes_for

HOLDOUT = 4              # every 4th point is held out


@dataclass(frozen=True)
class BeforeAfter:
    """Summaries of the same points before and after closing the loop."""

    before: Summary
    after: Summary

    def as_dict(self) -> dict:
        return {"before": summary_dict(self.before), "after": summary_dict(self.after)}


@dataclass
class CloseLoopResult(LoopResult):
    """What the loop found and the aircraft it ends with (as a parsed file, its factors
    including the added effects' own: no live simulator; :meth:`simulator` flies it)."""

    aircraft: str
    root: Path                          # the JSBSim root the aircraft was loaded from
    dataset: Dataset
    fit_points: list[int]
    held_points: list[int]
    before: Evaluation
    after: Evaluation
    diagnosis_before: dict[str, MetricDiagnosis]
    diagnosis_after: dict[str, MetricDiagnosis]
    candidates: list[Candidate]
    added: list[str]
    refits: list[FitResult]
    factors: FactorSet
    aircraft_tree: Tree
    wall_time_s: float
    notes: list[str] = field(default_factory=list)
    synthesized: list[Synthesis] = field(default_factory=list)   # every synthesis attempt (accepted or not)

    def summaries(self, which: str) -> BeforeAfter:
        """Summaries (schema of ``evaluate``) of 'all', 'fit' or 'held' points, before and after."""
        idx = {"all": None, "fit": set(self.fit_points), "held": set(self.held_points)}[which]
        out = {}
        for label, ev in (("before", self.before), ("after", self.after)):
            pts = [p for p in ev.points if idx is None or p.index in idx]
            out[label] = summarize(pts, ev.metrics)
        return BeforeAfter(**out)

    def to_json(self) -> dict:
        s = self.summaries("all").as_dict()
        return {"aircraft": self.aircraft, "data": str(self.dataset.path), "kind": self.dataset.kind,
                "before": s["before"], "candidates": [c.as_dict() for c in self.candidates], "added": self.added,
                "after": s["after"], "unexplained": [u.as_dict() for u in self.unexplained()],
                "fitted_points": self.summaries("fit").as_dict(), "held_out_points": self.summaries("held").as_dict(),
                "diagnosis_before": {m: d.as_dict() for m, d in self.diagnosis_before.items()},
                "diagnosis_after": {m: d.as_dict() for m, d in self.diagnosis_after.items()},
                "factors": {n: self.factors[n] for n in self.factors.extra},
                "notes": self.notes, "synthesized": [s.as_dict() for s in self.synthesized]}


# --------------------------------------------------------------------------- the trim adapter
# After an effect is added it is refitted with the levers of the metrics it moves (the factors
# of these stage-2a steps that move one metric alone): they were fitted without it and may have
# compensated for it. A factor that moves two metrics (the wing moment moves elevator and
# pitch) stays: refitting it for one would spoil the other.
COMPANION_STEPS = ("pitch", "control")


def companion_factors(effect: Effect) -> list[str]:
    """Stage-2a calibration factors acting on the metrics this effect moves (not those the
    effect duplicates, see the effect file's ``same_as``)."""
    out = []
    for m in effect.affects:
        out += [f for f in levers(m, COMPANION_STEPS) if f not in out and f not in effect.same_as]
    return out


def noise_in_tolerances(d: MetricDiagnosis) -> float:
    """A metric's noise in tolerance units for the likelihood: the diagnosis's estimate,
    at least :data:`NOISE_FLOOR`; the tolerance itself where the diagnosis had too few
    points to estimate it (a conservative scale: it asks for more evidence, never less)."""
    s = d.noise / d.tolerance
    return max(s, NOISE_FLOOR) if math.isfinite(s) else 1.0


class TrimEvidence:
    """Trims of one dataset as evidence for the loop (:mod:`.loop`): a row per point and
    metric, (model - data)/tolerance, and one row of failed-trim penalties; every
    :data:`HOLDOUT`-th point held out of the fits, cross-validation over :data:`HOLDOUT` folds
    of points; the candidates: every library effect the model lacks that moves a metric of the
    data, then (none passing) a term synthesized by JSBSim's linearization of the structured
    metrics' axes (section "synthesis")."""

    kind = "trims"
    executor = SERIAL          # its candidates run here: their synthesis keeps state between rounds

    def __init__(self, ds: Dataset, conds, lib: dict[str, Effect], *, refit_companions: bool = True,
                 synthesize: bool = True, say=lambda s: None):
        self.ds, self.conds, self.lib = ds, conds, lib
        self.refit_companions, self.synthesize, self.say = refit_companions, synthesize, say
        n = len(ds)
        self.held = [i for i in range(n) if i % HOLDOUT == HOLDOUT - 1]
        self.fitp = [i for i in range(n) if i % HOLDOUT != HOLDOUT - 1]
        self.syntheses: list[Synthesis] = []
        self._pending: dict[str, tuple[Synthesis, Linearization, Change]] = {}

    def rows(self, sim: Simulator, part) -> Rows:
        """(model - data)/tolerance at the given points, a penalty per failed trim, and the
        model values in units of each metric's absolute tolerance (materiality)."""
        ds, value = self.ds, KINDS[self.ds.kind].value
        r, metric, vals, lab, failed = [], [], [], [], 0
        for i in part:
            c = self.conds[i]
            t = sim.trim_level(c, key=("loop", i)) if c.mode == "level" else sim.trim(c, key=("loop", i))
            row = ds.frame.iloc[i]
            failed += not t.trimmed
            for m in ds.metrics:
                ref = float(row[m]) if m in row else math.nan
                if not math.isfinite(ref):
                    continue
                v = value(m, t) if t.trimmed else math.nan
                r.append((v - ref) / METRICS[m].tol_for(ref) if math.isfinite(v) else 0.0)
                vals.append(v / METRICS[m].tol_for(1.0))
                metric.append(m)
                lab.append(f"{i}.{m}")
        r.append(FAIL_PENALTY * failed)
        vals.append(math.nan)
        metric.append("")
        lab.append("trim failures")
        return Rows(np.array(r), np.array(metric, dtype=object), np.array(vals), lab)

    def diagnose(self, sim: Simulator) -> dict[str, MetricDiagnosis]:
        return diagnose(evaluate_dataset(sim, self.ds))

    def noise(self, d: MetricDiagnosis) -> float:
        return noise_in_tolerances(d)

    def independent_share(self, d: MetricDiagnosis) -> float:
        return 1.0                      # the points are independent

    def parts(self) -> tuple[list[int], list[int]]:
        return self.fitp, self.held

    def folds(self) -> list[tuple[list[int], list[int]]]:
        n = len(self.ds)
        return [([i for i in range(n) if i % HOLDOUT != f], [i for i in range(n) if i % HOLDOUT == f])
                for f in range(HOLDOUT)]

    def moves(self, ch: Change) -> tuple[str, ...]:
        return tuple(ch.effect.affects) if ch.effect is not None else ()

    def fitted_on(self, ch: Change) -> tuple[str, ...]:
        return ()                       # every metric: a trim answers every change at once

    def rebase(self, sim: Simulator) -> bool:
        """Nothing: a trim has no nuisance parameter of its own."""
        return False

    def named(self, rnd: int, current: Simulator, diag, factors: FactorSet) -> list[Change]:
        return [Change.of_effect(e) for name, e in self.lib.items()
                if name not in current.effects and set(e.affects) & set(self.ds.metrics)]

    def companions(self, ch: Change) -> list[str]:
        return companion_factors(ch.effect) if self.refit_companions and ch.effect is not None else []

    def focused(self, sim: Simulator, part, names) -> "TrimEvidence":
        return self                  # a trim is cheap: every point is evaluated in every fit

    def fit_options(self, what: str) -> dict:
        return {"max_nfev": 20 if what == "candidate" else 30}

    def judge(self, ch: Change, cand: Candidate, current: Simulator, factors: FactorSet) -> list[str]:
        """A synthesized term must also beat its null test (section "synthesis")."""
        if ch.kind != "term":
            return []
        rec = self._pending[ch.name][0]
        return [] if rec.p_null <= ALPHA else [
            f"the dictionary explains as much of shuffled residuals (null test p = {rec.p_null:.3f}, "
            f"needs <= {ALPHA:g})"]

    def cross_validate(self, current: Simulator, ch: Change, factors: FactorSet, focus=None) -> float:
        if ch.kind == "term":
            return cross_validate_synthesis(self, current, self._pending[ch.name][1], factors)
        return cross_validate(self, current, ch, factors, self)       # a trim evidence is its own focus

    def synthesized(self, rnd: int, current: Simulator, diag, factors: FactorSet, start: Round) -> list[Change]:
        if not self.synthesize:
            return []
        rec, ch, lin = synthesize_term(self, start, current)
        self.syntheses.append(rec)
        if ch is None:
            return []
        self._pending[ch.name] = (rec, lin, ch)
        return [ch]

    def unscreened(self, rnd: int, diag) -> bool:
        return False                 # named() offers the whole library at once


def close_loop(sim: Simulator, ds: Dataset, *, effects: dict[str, Effect] | None = None,
               max_effects: int = MAX_EFFECTS, refit_companions: bool = True, synthesize: bool = True,
               progress: Callable[[str], None] | None = None) -> CloseLoopResult:
    """Close the loop on one dataset (see the module doc). ``sim`` is left unchanged; the
    result holds the aircraft with the added effects (its file and factors). ``synthesize``:
    synthesize a term when no library effect passes (step 5)."""
    t0 = time.perf_counter()
    say = progress or (lambda s: None)
    lib = dict(library() if effects is None else effects)
    ev = TrimEvidence(ds, KINDS[ds.kind].conditions(ds, sim.geometry), lib, refit_companions=refit_companions,
                      synthesize=synthesize, say=say)
    before = evaluate_dataset(sim, ds)
    diag0 = diagnose(before)
    for m, d in diag0.items():
        say(f"diagnosis {m}: {'STRUCTURED' if d.structured else 'noise'}: {d.reason}")
    run = run_loop(ev, sim, max_effects=max_effects, diagnosis=diag0, final=lambda s: evaluate_dataset(s, ds),
                   progress=say)
    _record_syntheses(ev, run)
    return CloseLoopResult(sim.name, sim.root, ds, ev.fitp, ev.held, before, run.final, diag0, diagnose(run.final),
                           run.candidates, run.added_names, run.refits, run.factors, run.tree,
                           time.perf_counter() - t0, synthesized=ev.syntheses)


# --------------------------------------------------------------------------- synthesis (beyond the library)
# When no library effect passes and structure remains, the missing term is synthesized
# (jsbsim_calib.calibration.synthesis) and judged by the loop's rules, plus a null test of the
# selection and a cross-validation that repeats the selection in every fold.
def _linearized(ev: TrimEvidence, start: Round, current: Simulator) -> tuple[tuple[str, ...], Linearization | None]:
    """The structured metrics of the round and the linearized residual of all points to the
    terms of their axes (None: no candidate term)."""
    metrics = tuple(m for m, v in start.structure.items() if v > 0)
    terms = dictionary_for(metrics, exclude=current.effect_values)
    if not terms:
        return metrics, None
    weight = {m: 1.0 / noise_in_tolerances(d) for m, d in start.diagnosis.items()}
    everything = list(range(len(ev.ds)))

    def residuals(s: Simulator):
        rows = ev.rows(s, everything)
        return rows.residual, rows.labels

    return metrics, linearize(current, terms, residuals, weight)


def _synthesized_effect(sel: Selection, lin: Linearization, ds: Dataset) -> Effect:
    """The selection as an effect. The levers of the metrics it moves are held with it (its
    ``same_as``), not refitted: the dictionary has their forms (a constant, the surface), so
    whatever a lever could still take was a candidate of the selection already."""
    moved = lin.moved(sel.terms, sel.coefficients)
    held = [f for m in moved for f in levers(m, COMPANION_STEPS)]
    return term_effect(sel.terms, sel.coefficients, source=f"{ds.path.name} ({len(lin.groups)} fitted points)",
                       affects=moved, held=held)


def cross_validate_synthesis(ev: TrimEvidence, current: Simulator, lin: Linearization, factors: FactorSet) -> float:
    """K-fold cross-validation of the whole synthesis: in every fold the terms are selected
    and fitted on the other points, and the fold's points predicted (residual sum of squares)."""
    total = 0.0
    for train, test in ev.folds():
        part = lin.subset(train)
        sel = select(part)
        if not sel.terms:
            total += ev.rows(current, test).rss()
            continue
        trial, _ = fit_change(ev, current, Change.of_effect(_synthesized_effect(sel, part, ev.ds), "term"), factors,
                              train)
        with trial:
            total += ev.rows(trial, test).rss()
    return total


def synthesize_term(ev: TrimEvidence, start: Round, current: Simulator
                    ) -> tuple[Synthesis, Change | None, Linearization | None]:
    """One synthesis (module doc, step 5): the record, the term as a change to try (None: no
    term selected) and the linearization it came from."""
    metrics, lin = _linearized(ev, start, current)
    rec = Synthesis(start.number, metrics, axes_for(metrics), len(lin.terms) if lin else 0)
    if lin is None:
        rec.reason = "no candidate term for the structured metrics " + ", ".join(metrics)
        return rec, None, None
    rec.notes += list(lin.notes)
    part = lin.subset(ev.fitp)
    rec.selection = sel = select(part)
    ev.say(f"round {start.number}: synthesis on {', '.join(metrics)}: {rec.candidates} terms of "
           f"{', '.join(rec.axes)}; selected {', '.join(t.label for t in sel.terms) or 'nothing'}")
    if not sel.terms:
        rec.reason = "no set of terms lowers the extended BIC of the linearized residual"
        return rec, None, None
    eff = _synthesized_effect(sel, part, ev.ds)
    rec.effect = eff.name
    rec.p_null = null_test(part, sel)
    return rec, Change.of_effect(eff, "term"), lin


def _record_syntheses(ev: TrimEvidence, run: LoopRun) -> None:
    """Each synthesis record completed from its candidate: fitted and final values, the verdict."""
    by_name = {c.effect: c for c in run.candidates}
    for rec in ev.syntheses:
        cand = by_name.get(rec.effect)
        if cand is None:
            rec.reason = rec.reason or "fit failed"
            continue
        rec.cv = cand.cv
        rec.accepted = cand.accepted
        rec.reason = ("passes the evidence rules, the null test and cross-validation" if cand.accepted
                      else cand.reason)
        rec.terms = _term_records(rec, ev._pending[rec.effect][2].effect, cand, run.factors)


def _term_records(rec: Synthesis, eff: Effect, cand: Candidate, factors: FactorSet) -> list[dict]:
    """Per term: its interpretation, linearized estimate, fitted value, standard error, bounds
    and value after the last refit (None where not added)."""
    out = []
    for t, k, f in zip(rec.selection.terms, rec.selection.coefficients, eff.factors):
        label = eff.label(f)
        out.append({**t.as_dict(), "estimate": k, "fitted": cand.factors.get(label), "stderr": cand.stderr.get(label),
                    "bounds": [f.lower, f.upper],
                    "final": factors[label] if rec.accepted and label in factors.extra else None})
    return out
