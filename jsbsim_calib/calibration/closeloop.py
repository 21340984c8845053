"""Close the loop: find structured residuals, trace them to a missing effect, add it, refit.

:func:`close_loop` works on any aircraft and any trim data (flight-test snapshots, flap
climbs, POH climb/cruise):

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
from contextlib import ExitStack
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np

from ..data.schemas import METRICS, Dataset
from ..evaluate import KINDS, Evaluation, Summary, evaluate_dataset, summarize, summary_dict
from ..factors import FactorSet, levers
from ..jsbsim.product import AircraftPaths, write_derived
from ..jsbsim.simulator import Simulator
from ..jsbsim.xml import Tree
from .diagnose import ALPHA, Correlate, MetricDiagnosis, diagnose
from .effects import Effect, library
from .fit import FitResult, fit
from .points import FAIL_PENALTY
from .synthesis import Linearization, Selection, Synthesis, dictionary_for, linearize, null_test, select, term_effect
from .terms import axes_for

HOLDOUT = 4              # every 4th point is held out
MIN_EVIDENCE = 10.0      # BIC decrease for "very strong" evidence (Kass & Raftery)
MIN_HELD_GAIN = 0.10     # cross-validated residual sum of squares must fall by 10 %
MATERIAL = 0.25          # the effect must move a prediction by a quarter of a tolerance
MIN_EXPLAINED = 0.6      # share of the structured residual (beyond noise) the effect must explain
MAX_EFFECTS = 4


@dataclass
class Candidate:
    effect: str
    round: int
    factors: dict[str, float]
    stderr: dict[str, float | None]
    rss_fit: tuple[float, float]           # before, after (fitted points)
    rss_held: tuple[float, float]          # before, after (held-out points)
    n_fit: int
    delta_bic: float
    material: float                        # largest prediction change / tolerance
    explained: dict[str, float] = field(default_factory=dict)   # share of each structured metric explained
    share: float = 0.0                     # share of all the structure explained (net of damage elsewhere)
    cv: tuple[float, float] | None = None  # cross-validated residual sum of squares, without and with
    accepted: bool = False
    reason: str = ""
    affects: tuple[str, ...] = ()          # the metrics the effect moves

    @property
    def score(self) -> float:
        return -self.delta_bic

    def as_dict(self) -> dict:
        return {"effect": self.effect, "round": self.round, "score": round(self.score, 3),
                "factor": {k: v for k, v in self.factors.items()}, "stderr": self.stderr,
                "delta_bic": round(self.delta_bic, 3), "rss_fit": list(self.rss_fit), "rss_held": list(self.rss_held),
                "material": round(self.material, 3), "explained": {k: round(v, 3) for k, v in self.explained.items()},
                "explained_share": round(self.share, 3), "cross_validated": list(self.cv) if self.cv else None,
                "accepted": self.accepted, "reason": self.reason}


@dataclass(frozen=True)
class BeforeAfter:
    """Summaries of the same points before and after closing the loop."""

    before: Summary
    after: Summary

    def as_dict(self) -> dict:
        return {"before": summary_dict(self.before), "after": summary_dict(self.after)}


@dataclass(frozen=True)
class Unexplained:
    """A metric whose residual is still structured after the loop, with the states it follows."""

    metric: str
    correlates_with: list[str]          # regressors, most significant first
    reason: str
    correlations: list[Correlate]

    def as_dict(self) -> dict:
        return {"metric": self.metric, "correlates_with": list(self.correlates_with), "reason": self.reason,
                "correlations": [c.as_dict() for c in self.correlations]}


@dataclass
class CloseLoopResult:
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

    def unexplained(self) -> list[Unexplained]:
        return [Unexplained(m, [c.regressor for c in d.correlates], d.reason, list(d.correlates))
                for m, d in self.diagnosis_after.items() if d.structured]

    def simulator(self) -> Simulator:
        """A simulator of the aircraft the loop ends with (use it in a ``with`` block)."""
        return Simulator.with_aircraft(self.root, self.aircraft, self.aircraft_tree, self.factors)

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


# --------------------------------------------------------------------------- residuals
def _residuals(sim: Simulator, ds: Dataset, conds, indices) -> tuple[np.ndarray, list[str], dict]:
    """(model - data)/tolerance at the given points, a penalty per failed trim, and the
    model values (for the materiality test)."""
    value = KINDS[ds.kind].value
    r, lab, vals, failed = [], [], {}, 0
    for i in indices:
        c = conds[i]
        t = sim.trim_level(c, key=("loop", i)) if c.mode == "level" else sim.trim(c, key=("loop", i))
        row = ds.frame.iloc[i]
        if not t.trimmed:
            failed += 1
        for m in ds.metrics:
            ref = float(row[m]) if m in row else math.nan
            if not math.isfinite(ref):
                continue
            v = value(m, t) if t.trimmed else math.nan
            vals[(i, m)] = v
            r.append((v - ref) / METRICS[m].tol_for(ref) if math.isfinite(v) else 0.0)
            lab.append(f"{i}.{m}")
    r.append(FAIL_PENALTY * failed)
    lab.append("trim failures")
    return np.array(r), lab, vals


def _rss(r: np.ndarray) -> float:
    return float(r @ r)


def _by_metric(r: np.ndarray, labels: list[str]) -> dict[str, float]:
    out: dict[str, float] = {}
    for v, lab in zip(r, labels):
        if "." in lab:
            m = lab.split(".", 1)[1]
            out[m] = out.get(m, 0.0) + float(v) ** 2
    return out


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


# --------------------------------------------------------------------------- evidence
# Every test is written as what passing requires, so that a NaN (a quantity that could not
# be computed) fails it.
NOISE_FLOOR = 0.02       # smallest noise the likelihood assumes, in tolerances


def noise_in_tolerances(d: MetricDiagnosis) -> float:
    """A metric's noise in tolerance units for the likelihood: the diagnosis's estimate,
    at least :data:`NOISE_FLOOR`; the tolerance itself where the diagnosis had too few
    points to estimate it (a conservative scale: it asks for more evidence, never less)."""
    s = d.noise / d.tolerance
    return max(s, NOISE_FLOOR) if math.isfinite(s) else 1.0


def evidence_failures(delta_bic: float, material: float, structure: float, share: float) -> list[str]:
    """Why a candidate fails the in-sample tests; empty if it passes them all."""
    why = []
    if not delta_bic <= -MIN_EVIDENCE:
        why.append(f"evidence too weak (BIC change {delta_bic:+.1f}, needs <= -{MIN_EVIDENCE:g})")
    if not material >= MATERIAL:
        why.append(f"moves predictions by {material:.2f} tolerance at most (needs {MATERIAL:g})")
    if not structure > 0:
        why.append("no structured residual in the metrics it moves")
    elif not share >= MIN_EXPLAINED:
        why.append(f"explains {100 * share:.0f} % of the structured residual (needs {100 * MIN_EXPLAINED:.0f} %)")
    return why


def pays_off_out_of_sample(cv_without: float, cv_with: float) -> bool:
    """The cross-validated residual sum of squares falls by at least :data:`MIN_HELD_GAIN`."""
    return bool(cv_with <= (1.0 - MIN_HELD_GAIN) * cv_without)


# --------------------------------------------------------------------------- the loop
def _fit(current: Simulator, eff: Effect, factors: FactorSet, ds: Dataset, conds, points,
         max_nfev: int = 20) -> tuple[Simulator, FitResult]:
    """A copy of ``current`` with ``eff`` added and its factor(s) fitted alone on ``points``
    (the caller closes the copy: ``with``)."""
    trial = current.clone()
    try:
        trial.add_effect(eff)
        extra = eff.as_factors()
        start = factors.with_extra(extra)
        trial.set_factors(start)

        def res(fs):
            trial.set_factors(fs)
            r, lab, _ = _residuals(trial, ds, conds, points)
            return r, lab

        fr = fit(f"candidate {eff.name}", list(extra), start, res, sim=trial, max_nfev=max_nfev)
    except BaseException:
        trial.close()
        raise
    trial.set_factors(fr.final)
    return trial, fr


def cross_validate(current: Simulator, eff: Effect, factors: FactorSet, ds: Dataset, conds,
                   folds: int = HOLDOUT) -> float:
    """K-fold cross-validation: residual sum of squares of every point predicted by a fit
    of ``eff`` that did not see it."""
    n = len(ds)
    total = 0.0
    for f in range(folds):
        test = [i for i in range(n) if i % folds == f]
        train = [i for i in range(n) if i % folds != f]
        trial, _ = _fit(current, eff, factors, ds, conds, train)
        with trial:
            total += _rss(_residuals(trial, ds, conds, test)[0])
    return total


@dataclass
class _Round:
    """The model's residuals at the start of a round, against which candidates are scored."""

    number: int
    diagnosis: dict[str, MetricDiagnosis]
    fitted: np.ndarray                 # residuals of the fitted points (last: failed-trim penalty)
    labels: list[str]
    values: dict                       # model values of the fitted points
    held_rss: float
    per_metric: dict[str, float]       # residual sum of squares of each metric
    structure: dict[str, float]        # each structured metric's sum of squares beyond its noise


def _start_round(number: int, current: Simulator, ds: Dataset, conds, fitp, held,
                 diag: dict[str, MetricDiagnosis]) -> _Round:
    r0, lab0, v0 = _residuals(current, ds, conds, fitp)
    h0 = _residuals(current, ds, conds, held)[0]
    per0 = _by_metric(r0, lab0)
    counts = {m: sum(1 for x in lab0 if x.endswith("." + m)) for m in per0}
    # structure: each structured metric's sum of squares beyond its estimated noise
    structure = {m: max(0.0, per0[m] - counts[m] * (diag[m].noise / diag[m].tolerance) ** 2)
                 for m in per0 if m in diag and diag[m].structured}
    return _Round(number, diag, r0, lab0, v0, _rss(h0), per0, structure)


def _score(start: _Round, name: str, eff: Effect, fr: FitResult, trial: Simulator, ds: Dataset, conds, fitp,
           held) -> Candidate:
    """A fitted candidate scored against the round's start: evidence, materiality, explained share."""
    r0, per0, v0, structure, diag = start.fitted, start.per_metric, start.values, start.structure, start.diagnosis
    r1, lab1, v1 = _residuals(trial, ds, conds, fitp)
    h1 = _residuals(trial, ds, conds, held)[0]
    per1 = _by_metric(r1, lab1)
    explained = {m: (per0[m] - per1.get(m, 0.0)) / structure[m] for m in structure if structure[m] > 0}
    rss0, rss1, hold1, n_fit = _rss(r0), _rss(r1), _rss(h1), len(r0)
    # share of the structure of the metrics it moves, net of what it spoils elsewhere
    own = sum(v for m, v in structure.items() if m in eff.affects)
    share = (rss0 - rss1) / own if own > 0 else 0.0
    k = len(eff.factors)
    # Gaussian log-likelihood with each metric's noise (estimated by the diagnosis,
    # in tolerance units): BIC change = -(chi2 before - chi2 after) + k ln n
    chi = sum((per0[m] - per1.get(m, 0.0)) / noise_in_tolerances(diag[m]) ** 2
              for m in per0 if m in diag)
    chi += (float(r0[-1]) ** 2 - float(r1[-1]) ** 2)          # failed-trim penalty, unit variance
    dbic = -chi + k * math.log(n_fit)
    material = max((abs(v1[key] - v0[key]) / METRICS[key[1]].tol_for(1.0)
                    for key in v1 if key in v0 and math.isfinite(v1[key]) and math.isfinite(v0[key])),
                   default=0.0)
    c = Candidate(name, start.number, {lab: fr.final[lab] for lab in eff.as_factors()}, dict(fr.stderr),
                  (rss0, rss1), (start.held_rss, hold1), n_fit, dbic, material, explained, share,
                  affects=tuple(eff.affects))
    c.reason = "; ".join(evidence_failures(dbic, material, own, share))
    return c


def _candidates(start: _Round, current: Simulator, lib: dict[str, Effect], factors: FactorSet, ds: Dataset, conds,
                fitp, held, say) -> list[Candidate]:
    """Every library effect the model lacks (and that moves a metric of the data), fitted and scored."""
    tried = []
    for name, eff in lib.items():
        if name in current.effects or not set(eff.affects) & set(ds.metrics):
            continue
        try:
            trial, fr = _fit(current, eff, factors, ds, conds, fitp)
        except Exception as exc:                           # a candidate that breaks the trims is rejected
            say(f"round {start.number}: {name}: fit failed ({exc})")
            continue
        with trial:
            c = _score(start, name, eff, fr, trial, ds, conds, fitp, held)
        tried.append(c)
        say(f"round {start.number}: {name:34s} BIC {c.delta_bic:+9.1f}  explains {100 * c.share:5.0f} %  "
            f"{'passes the fit tests' if not c.reason else 'rejected'}")
    return tried


def _best_out_of_sample(tried: list[Candidate], current: Simulator, lib: dict[str, Effect], factors: FactorSet,
                        ds: Dataset, conds, say) -> Candidate | None:
    """The strongest candidate that passed the fit tests and pays off in cross-validation."""
    for c in sorted((c for c in tried if not c.reason), key=lambda c: c.delta_bic):
        cv0 = _rss(_residuals(current, ds, conds, list(range(len(ds))))[0])
        cv1 = cross_validate(current, lib[c.effect], factors, ds, conds)
        c.cv = (cv0, cv1)
        if pays_off_out_of_sample(cv0, cv1):
            return c
        c.reason = (f"does not pay off out of sample: cross-validated residuals {cv0:.3g} -> {cv1:.3g} "
                    f"(needs -{100 * MIN_HELD_GAIN:.0f} %)")
        say(f"round {c.round}: {c.effect}: {c.reason}")
    return None


def _refit(rnd: int, current: Simulator, lib: dict[str, Effect], added: list[str], factors: FactorSet, ds: Dataset,
           conds, fitp, refit_companions: bool, say) -> FitResult:
    """Every added effect refitted with the calibration factors of their metrics."""
    names = [n for n in factors.extra]
    if refit_companions:
        for e in added:
            names += [f for f in companion_factors(lib[e]) if f not in names]

    def res(fs):
        current.set_factors(fs)
        r, lab, _ = _residuals(current, ds, conds, fitp)
        return r, lab

    say(f"round {rnd}: added {added[-1]}; refit of {', '.join(names)}")
    return fit(f"refit after {added[-1]}", names, factors, res, sim=current, max_nfev=30)


def close_loop(sim: Simulator, ds: Dataset, *, effects: dict[str, Effect] | None = None,
               max_effects: int = MAX_EFFECTS, refit_companions: bool = True, synthesize: bool = True,
               progress: Callable[[str], None] | None = None) -> CloseLoopResult:
    """Close the loop on one dataset (see the module doc). ``sim`` is left unchanged; the
    result holds the aircraft with the added effects (its file and factors). ``synthesize``:
    synthesize a term when no library effect passes (step 5)."""
    t0 = time.perf_counter()
    say = progress or (lambda s: None)
    lib = dict(library() if effects is None else effects)      # synthesized effects join it when added
    syntheses: list[Synthesis] = []
    conds = KINDS[ds.kind].conditions(ds, sim.geometry)
    n = len(ds)
    held = [i for i in range(n) if i % HOLDOUT == HOLDOUT - 1]
    fitp = [i for i in range(n) if i % HOLDOUT != HOLDOUT - 1]
    before = evaluate_dataset(sim, ds)
    diag0 = diagnose(before)
    for m, d in diag0.items():
        say(f"diagnosis {m}: {'STRUCTURED' if d.structured else 'noise'}: {d.reason}")
    candidates: list[Candidate] = []
    added: list[str] = []
    refits: list[FitResult] = []
    with ExitStack() as sandboxes:
        current = sandboxes.enter_context(sim.clone())
        factors = current.factors
        for rnd in range(1, max_effects + 1):
            diag = diag0 if rnd == 1 else diagnose(evaluate_dataset(current, ds))
            if not any(d.structured for d in diag.values()):
                say(f"round {rnd}: no structured residual: nothing to add")
                break
            start = _start_round(rnd, current, ds, conds, fitp, held, diag)
            tried = _candidates(start, current, lib, factors, ds, conds, fitp, held, say)
            candidates += tried
            best = _best_out_of_sample(tried, current, lib, factors, ds, conds, say)
            if best is None and synthesize:
                best = _synthesis_round(start, current, lib, factors, ds, conds, fitp, held, syntheses, candidates,
                                        say)
            if best is None:
                break
            best.accepted = True
            best.reason = (f"accepted: strongest evidence; out of sample {best.cv[0]:.3g} -> {best.cv[1]:.3g} "
                           f"({HOLDOUT}-fold cross-validation)")
            trial, fr = _fit(current, lib[best.effect], factors, ds, conds, fitp)
            sandboxes.enter_context(trial)
            current.close()
            current = trial
            factors = fr.final
            added.append(best.effect)
            rf = _refit(rnd, current, lib, added, factors, ds, conds, fitp, refit_companions, say)
            refits.append(rf)
            factors = rf.final
            current.set_factors(factors)
        after = evaluate_dataset(current, ds)
        tree = current.aircraft_tree()
    diag1 = diagnose(after)
    _final_values(syntheses, factors)
    return CloseLoopResult(sim.name, sim.root, ds, fitp, held, before, after, diag0, diag1, candidates, added,
                           refits, factors, tree, time.perf_counter() - t0, synthesized=syntheses)


def write_aircraft(result: CloseLoopResult, root: Path, out_name: str) -> Path:
    """Write the aircraft with its added effects as ``aircraft/<out_name>/`` of ``root`` (the
    parent's folder copied, its XML replaced), loadable by JSBSim and by this workbench."""
    return write_derived(AircraftPaths(result.root, result.aircraft), result.aircraft_tree, result.factors,
                         AircraftPaths(Path(root), out_name))


# --------------------------------------------------------------------------- synthesis (beyond the library)
# When no library effect passes and structure remains, the missing term is synthesized
# (jsbsim_calib.calibration.synthesis) and judged by the rules above, plus a null test of the
# selection and a cross-validation that repeats the selection in every fold.
def _linearized(start: _Round, current: Simulator, ds: Dataset, conds) -> tuple[tuple[str, ...], Linearization | None]:
    """The structured metrics of the round and the linearized residual of all points to the
    terms of their axes (None: no candidate term)."""
    metrics = tuple(m for m, v in start.structure.items() if v > 0)
    terms = dictionary_for(metrics, exclude=current.effect_values)
    if not terms:
        return metrics, None
    weight = {m: 1.0 / noise_in_tolerances(d) for m, d in start.diagnosis.items()}
    everything = list(range(len(ds)))
    return metrics, linearize(current, terms, lambda s: _residuals(s, ds, conds, everything)[:2], weight)


def _synthesized_effect(sel: Selection, lin: Linearization, ds: Dataset) -> Effect:
    """The selection as an effect. The levers of the metrics it moves are held with it (its
    ``same_as``), not refitted: the dictionary has their forms (a constant, the surface), so
    whatever a lever could still take was a candidate of the selection already."""
    moved = lin.moved(sel.terms, sel.coefficients)
    held = [f for m in moved for f in levers(m, COMPANION_STEPS)]
    return term_effect(sel.terms, sel.coefficients, source=f"{ds.path.name} ({len(lin.groups)} fitted points)",
                       affects=moved, held=held)


def cross_validate_synthesis(current: Simulator, lin: Linearization, factors: FactorSet, ds: Dataset, conds,
                             folds: int = HOLDOUT) -> float:
    """K-fold cross-validation of the whole synthesis: in every fold the terms are selected
    and fitted on the other points, and the fold's points predicted (residual sum of squares)."""
    n, total = len(ds), 0.0
    for f in range(folds):
        test = [i for i in range(n) if i % folds == f]
        train = [i for i in range(n) if i % folds != f]
        part = lin.subset(train)
        sel = select(part)
        if not sel.terms:
            total += _rss(_residuals(current, ds, conds, test)[0])
            continue
        trial, _ = _fit(current, _synthesized_effect(sel, part, ds), factors, ds, conds, train)
        with trial:
            total += _rss(_residuals(trial, ds, conds, test)[0])
    return total


def _judge(rec: Synthesis, cand: Candidate, current: Simulator, lin: Linearization, factors: FactorSet,
           ds: Dataset, conds) -> None:
    """The library's evidence rules, the null test of the selection, cross-validation."""
    why = [cand.reason] if cand.reason else []
    if not rec.p_null <= ALPHA:
        why.append(f"the dictionary explains as much of shuffled residuals (null test p = {rec.p_null:.3f}, "
                   f"needs <= {ALPHA:g})")
    if not why:
        cv0 = _rss(_residuals(current, ds, conds, list(range(len(ds))))[0])
        cv1 = cross_validate_synthesis(current, lin, factors, ds, conds)
        rec.cv = cand.cv = (cv0, cv1)
        if not pays_off_out_of_sample(cv0, cv1):
            why.append(f"does not pay off out of sample: cross-validated residuals {cv0:.3g} -> {cv1:.3g} "
                       f"(needs -{100 * MIN_HELD_GAIN:.0f} %)")
    rec.accepted = not why
    cand.reason = "; ".join(why)
    rec.reason = cand.reason or "passes the evidence rules, the null test and cross-validation"


def _term_records(sel: Selection, eff: Effect, fr: FitResult) -> list[dict]:
    out = []
    for t, k, f in zip(sel.terms, sel.coefficients, eff.factors):
        label = eff.label(f)
        out.append({**t.as_dict(), "estimate": k, "fitted": fr.final[label], "stderr": fr.stderr.get(label),
                    "bounds": [f.lower, f.upper], "final": None})
    return out


def synthesize_term(start: _Round, current: Simulator, factors: FactorSet, ds: Dataset, conds, fitp, held,
                    say) -> tuple[Synthesis, Candidate | None, Effect | None]:
    """One synthesis (module doc, step 5): the record, the fitted candidate and its effect."""
    metrics, lin = _linearized(start, current, ds, conds)
    rec = Synthesis(start.number, metrics, axes_for(metrics), len(lin.terms) if lin else 0)
    if lin is None:
        rec.reason = "no candidate term for the structured metrics " + ", ".join(metrics)
        return rec, None, None
    rec.notes += list(lin.notes)
    part = lin.subset(fitp)
    rec.selection = sel = select(part)
    say(f"round {start.number}: synthesis on {', '.join(metrics)}: {rec.candidates} terms of "
        f"{', '.join(rec.axes)}; selected {', '.join(t.label for t in sel.terms) or 'nothing'}")
    if not sel.terms:
        rec.reason = "no set of terms lowers the extended BIC of the linearized residual"
        return rec, None, None
    eff = _synthesized_effect(sel, part, ds)
    rec.effect = eff.name
    try:
        trial, fr = _fit(current, eff, factors, ds, conds, fitp)
    except Exception as exc:                           # a term that breaks the trims is rejected
        rec.reason = f"fit failed ({exc})"
        return rec, None, None
    with trial:
        cand = _score(start, eff.name, eff, fr, trial, ds, conds, fitp, held)
    rec.terms = _term_records(sel, eff, fr)
    rec.p_null = null_test(part, sel)
    _judge(rec, cand, current, lin, factors, ds, conds)
    say(f"round {start.number}: {eff.name:34s} BIC {cand.delta_bic:+9.1f}  explains {100 * cand.share:5.0f} %  "
        f"null p {rec.p_null:.3f}  {'passes' if rec.accepted else 'rejected: ' + rec.reason}")
    return rec, cand, eff


def _synthesis_round(start: _Round, current: Simulator, lib: dict[str, Effect], factors: FactorSet, ds: Dataset,
                     conds, fitp, held, syntheses: list[Synthesis], candidates: list[Candidate],
                     say) -> Candidate | None:
    """Synthesize a term for what the library left structured; when it passes, its effect joins
    ``lib`` and its candidate is returned (added like a library effect)."""
    rec, cand, eff = synthesize_term(start, current, factors, ds, conds, fitp, held, say)
    syntheses.append(rec)
    if cand is not None:
        candidates.append(cand)
    if not rec.accepted:
        return None
    lib[eff.name] = eff
    return cand


def _final_values(syntheses: list[Synthesis], factors: FactorSet) -> None:
    """Each added term's value after the last refit."""
    for rec in syntheses:
        for t in rec.terms if rec.accepted else ():
            label = f"{rec.effect}.{t['term']}"
            t["final"] = factors[label] if label in factors.extra else None
