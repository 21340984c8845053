"""The close-the-loop engine: one loop for every kind of evidence.

diagnose -> candidates -> fit -> evidence -> add -> refit, round after round, until nothing
passes (after an add, the evidence refits its own nuisance parameters, and the change is fitted
again on them: :meth:`Evidence.rebase`, :func:`fit_again`); the same rules judge every
candidate on every kind of data. What differs per kind of evidence is an adapter
(:class:`Evidence`): what a residual row is and its scale, how the residual is diagnosed, how
the points or maneuvers form folds, which candidates a round tries and how a candidate is
flown. :mod:`.closeloop` adapts trims (POH tables, flight-test
snapshots, flap climbs, G1000 segments), :mod:`.closeloop_dynamic` time histories.

A candidate is a :class:`Change`: a library effect or a synthesized term (XML added, its own
factors fitted), an existing calibration factor refitted alone, or a moment of inertia scaled.
Named candidates (effects, factors, inertias) are tried first; synthesized terms only when
none passes. Each is fitted alone on the evidence's fitted part and scored against the
round's start (:func:`score`): the change of the Bayesian information criterion with each
metric's residuals scaled by its noise and counted by its independent samples, the share of
the structured residual it explains in the metrics it moves (net of what it spoils), and
how far it moves a prediction. Those that pass are cross-validated (folds of the evidence:
points, or whole maneuvers) in the order of the share they explain (a synthesized term
:data:`TERM_MARGIN` less), and the first that pays off out of sample is added
(:func:`best_out_of_sample`). The test a candidate failed is its reason. Every test is written
as what passing requires, so a NaN fails it.
"""
from __future__ import annotations

import math
import time
from contextlib import ExitStack
from dataclasses import dataclass, field, replace
from functools import partial
from pathlib import Path
from typing import Callable, Mapping, Protocol, Sequence

import numpy as np
from scipy.optimize import minimize_scalar

from ..core.errors import CalibError
from ..core.executor import Executor
from ..factors import Factor, FactorSet
from ..jsbsim.product import AircraftPaths, write_derived
from ..jsbsim.simulator import Simulator
from .effects import Effect
from .fit import LEGS, FitResult, fit, unfitted

MIN_EVIDENCE = 10.0      # BIC decrease for "very strong" evidence (Kass & Raftery)
MIN_HELD_GAIN = 0.10     # cross-validated residual sum of squares must fall by 10 %
MATERIAL = 0.25          # the effect must move a prediction by a quarter of a tolerance (scale)
BREAKS = "breaks the model"   # the reason of a candidate that fails where the model did not
MIN_EXPLAINED = 0.6      # share of the structured residual (beyond noise) the effect must explain
TERM_MARGIN = 0.1        # a synthesized term is preferred to a named candidate when it explains this much more
NOISE_FLOOR = 0.02       # smallest noise the likelihood assumes, in tolerances (scales)
MAX_EFFECTS = 4
INERTIA_SCALES = (0.4, 2.5)  # the range a moment of inertia may be scaled over
INERTIA_BRACKET = 0.25       # the search about a start estimate (+-)
START_HALVINGS = 3           # a term's start halved toward neutral at most this often where the model breaks
# The loop's fits, on every kind of evidence. They stop when an iteration lowers the cost by less
# than FIT_TOLERANCE of it: on the Level 5 campaign (46,640 rows) a refit reached 1e-4 of its
# final cost in 7 iterations and spent 28 more (150 s) on the last 0.02 %, which moved no
# explained share by 0.1 point. A candidate starts close (its estimate, or the factor's value):
# one leg, no path of priors; on the trims that cut a round's candidate fits from 24 to 10 s
# with the same decisions (docs/benchmarks.md). A refit polishes (the last two legs of LEGS).
FIT_TOLERANCE = 1e-4
CANDIDATE_LEGS = ((1.0, 0.002),)
REFIT_LEGS = LEGS[-2:]
RULES = {"min_evidence_bic_decrease": MIN_EVIDENCE, "min_explained_share": MIN_EXPLAINED,
         "material_share_of_scale": MATERIAL, "min_cross_validated_gain": MIN_HELD_GAIN,
         "term_margin_share": TERM_MARGIN}


# --------------------------------------------------------------------------- the rules
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


# --------------------------------------------------------------------------- what an evidence kind provides
@dataclass(frozen=True)
class Rows:
    """Residual rows (model - data)/tolerance of some points, with each row's metric (""
    for a penalty row: a failed trim or flight, unit variance) and the model's value in
    tolerance units (NaN where none: materiality)."""

    residual: np.ndarray
    metric: np.ndarray
    values: np.ndarray
    labels: list[str]

    def rss(self) -> float:
        return float(self.residual @ self.residual)

    def per_metric(self) -> dict[str, float]:
        return {m: float(np.sum(self.residual[self.metric == m] ** 2)) for m in dict.fromkeys(self.metric) if m}

    def penalty(self) -> float:
        return float(np.sum(self.residual[self.metric == ""] ** 2))


class Diagnosis(Protocol):
    structured: bool
    reason: str


class Evidence(Protocol):
    """An adapter of one kind of evidence (module doc)."""

    kind: str
    executor: Executor                                               # where candidates and folds run

    def rows(self, sim: Simulator, part: Sequence[int]) -> Rows: ...
    def focused(self, sim: Simulator, part: Sequence[int], names: Sequence[str]) -> "Evidence": ...  # for a fit of names
    def diagnose(self, sim: Simulator) -> Mapping[str, Diagnosis]: ...
    def noise(self, d: Diagnosis) -> float: ...                      # in tolerance units
    def independent_share(self, d: Diagnosis) -> float: ...
    def parts(self) -> tuple[list[int], list[int]]: ...              # fitted, held out
    def folds(self) -> list[tuple[list[int], list[int]]]: ...        # (train, test) of cross-validation
    def moves(self, ch: "Change") -> tuple[str, ...]: ...            # the metrics a change acts on
    def fitted_on(self, ch: "Change") -> tuple[str, ...]: ...        # the metrics its fit minimizes (() every row)
    def rebase(self, sim: Simulator) -> bool: ...                    # its nuisance parameters refitted on sim (any?)
    def named(self, rnd: int, current: Simulator, diag, factors: FactorSet) -> list["Change"]: ...
    def synthesized(self, rnd: int, current: Simulator, diag, factors: FactorSet, start: "Round") -> list["Change"]: ...
    def unscreened(self, rnd: int, diag) -> bool: ...                # named() has candidates of this round left
    def companions(self, ch: "Change") -> list[str]: ...
    def fit_options(self, what: str) -> dict: ...                    # 'candidate' or 'refit': max_nfev, prior
    def judge(self, ch: "Change", cand: "Candidate", current: Simulator, factors: FactorSet) -> list[str]: ...
    # a named change's must be cross_validate()'s sum: try_changes may run its folds ahead
    def cross_validate(self, current: Simulator, ch: "Change", factors: FactorSet,
                       focus: "Evidence | None" = None) -> float: ...


def fit_options(ev: Evidence, what: str) -> dict:
    """The options of the loop's fits (``what``: 'candidate' or 'refit'): the loop's stopping
    rule and legs, with the evidence's own evaluation budget and prior."""
    legs = CANDIDATE_LEGS if what == "candidate" else REFIT_LEGS
    return {"ftol": FIT_TOLERANCE, "legs": legs, **ev.fit_options(what)}


# --------------------------------------------------------------------------- candidates
@dataclass(frozen=True)
class Change:
    """A candidate change of the model: a library effect or a synthesized term (its XML added,
    its own factors fitted), an existing calibration factor refitted alone, or a moment of
    inertia scaled (the aircraft file's ``mass_balance``)."""

    name: str
    kind: str                            # effect | term | factor | inertia
    axis: str = ""                       # roll | pitch | yaw (time histories; "" where unknown)
    effect: Effect | None = None
    target: str = ""                     # factor: its name; inertia: ixx, iyy or izz
    start: tuple[tuple[str, float], ...] = ()   # where its fit starts (an estimate), by factor label

    @classmethod
    def of_effect(cls, eff: Effect, kind: str = "effect", axis: str = "") -> "Change":
        return cls(eff.name, kind, axis, eff)

    @property
    def k(self) -> int:
        """Its number of fitted coefficients."""
        return len(self.effect.factors) if self.effect is not None else 1

    def labels(self) -> list[str]:
        """The factors its fit moves (an inertia: none of the factor set)."""
        if self.effect is not None:
            return list(self.effect.as_factors())
        return [self.target] if self.kind == "factor" else []


@dataclass
class Candidate:
    """A change fitted alone and scored against its round's start."""

    effect: str
    round: int
    factors: dict[str, float]
    stderr: dict[str, float | None]
    rss_fit: tuple[float, float]            # before, after (fitted part)
    rss_held: tuple[float, float] | None    # before, after (held-out part; None: none held out)
    n: int                                  # residual rows of the fitted part
    delta_bic: float
    material: float                         # largest prediction change / tolerance (scale)
    explained: dict[str, float] = field(default_factory=dict)   # share of each structured metric explained
    share: float = 0.0                      # share of the structure of the metrics it moves (net of damage)
    cv: tuple[float, float] | None = None   # cross-validated residual sum of squares, without and with
    accepted: bool = False
    reason: str = ""
    affects: tuple[str, ...] = ()           # the metrics it moves
    kind: str = "effect"
    axis: str = ""

    @property
    def score(self) -> float:
        return -self.delta_bic

    @property
    def breaks(self) -> bool:
        """It fails where the model flew or trimmed: its BIC change and share count failures."""
        return self.reason.startswith(BREAKS)

    def evidence_cells(self) -> tuple[str, str]:
        """Its BIC change and explained share as a report shows them ("-" where it breaks the model)."""
        return ("-", "-") if self.breaks else (f"{self.delta_bic:+.1f}", f"{100 * self.share:.0f} %")

    def as_dict(self) -> dict:
        js = _js
        return {"effect": self.effect, "kind": self.kind, "round": self.round, "axis": self.axis or None,
                "score": js(self.score), "factor": dict(self.factors),
                "stderr": {k: js(v) for k, v in self.stderr.items()}, "delta_bic": js(round(self.delta_bic, 3)),
                "rss_fit": [js(x) for x in self.rss_fit],
                "rss_held": [js(x) for x in self.rss_held] if self.rss_held else None, "n": self.n,
                "material": js(round(self.material, 3)),
                "explained": {k: js(round(v, 3)) for k, v in self.explained.items()},
                "explained_share": js(round(self.share, 3)),
                "cross_validated": [js(x) for x in self.cv] if self.cv else None,
                "accepted": self.accepted, "reason": self.reason}


def _js(x):
    return None if x is None or not math.isfinite(x) else float(x)


# --------------------------------------------------------------------------- fitting a change
@dataclass
class Fitted:
    """A change fitted alone: its values (factors by label; an inertia as ``<axis>_scale``),
    their standard errors, and the factor set the trial flies."""

    values: dict[str, float]
    stderr: dict[str, float | None]
    factors: FactorSet
    focus: Evidence | None = None    # the evidence focused on its factors at its start (:func:`focus_of`)


def _inside(f: Factor, value: float) -> float:
    """A start value inside a factor's bounds (a twentieth of its range from either)."""
    margin = 0.05 * (f.upper - f.lower)
    return min(f.upper - margin, max(f.lower + margin, value))


def _residuals(ev: Evidence, sim: Simulator, part: Sequence[int]):
    def res(fs: FactorSet):
        sim.set_factors(fs)
        rows = ev.rows(sim, part)
        return rows.residual, rows.labels
    return res


def _effect_start(ev: Evidence, current: Simulator, ch: Change, factors: FactorSet,
                  part: Sequence[int]) -> tuple[Simulator, FactorSet, Evidence]:
    """A copy of ``current`` with the effect (or term) at its fit's start (its estimate where it
    has one), that start, and the evidence focused on its factors there (the caller closes the copy)."""
    trial = current.clone()
    try:
        trial.add_effect(ch.effect)
        extra = ch.effect.as_factors()
        neutral = factors.with_extra(extra)
        start = neutral.updated({k: _inside(extra[k], v) for k, v in ch.start if k in extra})
        start = _flying_start(ev, trial, neutral, start, list(extra), part) if ch.kind == "term" else start
        trial.set_factors(start)
        return trial, start, ev.focused(trial, part, list(extra))
    except BaseException:
        trial.close()
        raise


def _flying_start(ev: Evidence, trial: Simulator, neutral: FactorSet, start: FactorSet, names: Sequence[str],
                  part: Sequence[int]) -> FactorSet:
    """A term's linearized start, halved toward neutral (at most :data:`START_HALVINGS` times)
    while the model cannot fly or trim there where it could at neutral: from a start where every
    evaluation fails the fit has no gradient to follow (an elevator power that falls with the
    flaps, estimated at 1.8 times the truth's, left the flaps-30 trim without elevator)."""
    base = None
    for _ in range(START_HALVINGS):
        trial.set_factors(start)
        broken = ev.rows(trial, part).penalty()
        if base is None and broken > 0.0:
            trial.set_factors(neutral)
            base = ev.rows(trial, part).penalty()
        if broken <= (base or 0.0):
            return start
        start = start.updated({k: neutral[k] + 0.5 * (start[k] - neutral[k]) for k in names})
    return start


def _factor_start(ev: Evidence, current: Simulator, ch: Change, factors: FactorSet,
                  part: Sequence[int]) -> tuple[Simulator, FactorSet, Evidence]:
    """A copy of ``current`` with an existing factor at its fit's start, that start, and the
    evidence focused on the factor there (the caller closes the copy)."""
    trial = current.clone()
    try:
        f = factors.factor(ch.target)
        start = factors.updated({ch.target: _inside(f, factors[ch.target] + dict(ch.start).get(ch.target, 0.0))})
        trial.set_factors(start)
        return trial, start, ev.focused(trial, part, [ch.target])
    except BaseException:
        trial.close()
        raise


STARTS = {"effect": _effect_start, "term": _effect_start, "factor": _factor_start}


def _fit_factors(ev: Evidence, current: Simulator, ch: Change, factors: FactorSet,
                 part: Sequence[int]) -> tuple[Simulator, Fitted]:
    """An effect's (or term's) factors fitted alone from its start (:data:`STARTS`), with the
    evidence's prior about neutral; an existing factor without a prior: the data say where it
    stands."""
    trial, start, focus = STARTS[ch.kind](ev, current, ch, factors, part)
    try:
        names, opts = ch.labels(), fit_options(ev, "candidate")
        if ch.kind == "factor":
            opts = {**{k: v for k, v in opts.items() if k != "prior_center"}, "prior": 0.0}
        elif "prior_center" in opts:
            opts = {**opts, "prior_center": factors.with_extra(ch.effect.as_factors())}
        fr = fit(f"candidate {ch.name}", names, start, _residuals(focus, trial, part), sim=trial, **opts)
        trial.set_factors(fr.final)
    except BaseException:
        trial.close()
        raise
    return trial, Fitted({k: fr.final[k] for k in names}, dict(fr.stderr), fr.final, focus)


def _inertia_note(axis: str, scale: float) -> str:
    return f"close-loop: {axis} x {scale:.4g} (fitted to the data)"


def _fit_inertia(ev: Evidence, current: Simulator, ch: Change, factors: FactorSet,
                 part: Sequence[int]) -> tuple[Simulator, Fitted]:
    """A moment of inertia scaled by the factor that minimizes the residuals the evidence fits
    it on (:meth:`Evidence.fitted_on`): a bounded Brent search about its start estimate (one
    reload and one evaluation of the part per step)."""
    trial = current.clone()
    try:
        base, on = trial.moment_of_inertia(ch.target), ev.fitted_on(ch)

        def cost(s: float) -> float:
            trial.set_moment_of_inertia(ch.target, base * s)
            rows = ev.rows(trial, part)
            r = rows.residual[np.isin(rows.metric, on)] if on else rows.residual
            return float(r @ r)

        s0 = 1.0 + dict(ch.start).get(ch.target, 0.0)
        lo = max(INERTIA_SCALES[0], min(s0, INERTIA_SCALES[1]) - INERTIA_BRACKET)
        hi = min(INERTIA_SCALES[1], lo + 2 * INERTIA_BRACKET)
        best = minimize_scalar(cost, bounds=(lo, hi), method="bounded",
                               options={"xatol": 2e-3, "maxiter": ev.fit_options("candidate").get("max_nfev", 20)})
        s = float(best.x)
        trial.set_moment_of_inertia(ch.target, base * s, _inertia_note(ch.target, s))
    except BaseException:
        trial.close()
        raise
    return trial, Fitted({f"{ch.target}_scale": s}, {}, factors)


FITS = {"effect": _fit_factors, "term": _fit_factors, "factor": _fit_factors, "inertia": _fit_inertia}


def focus_of(ev: Evidence, current: Simulator, ch: Change, factors: FactorSet) -> Evidence:
    """The evidence as the change's fit on the fitted part runs on it (:meth:`Evidence.focused`
    at the change's start; an inertia's search: the evidence itself). Its folds are fitted on it,
    so that they fly only the tests the change moves, as its fit did."""
    if ch.kind not in STARTS:
        return ev
    trial, _, focus = STARTS[ch.kind](ev, current, ch, factors, ev.parts()[0])
    trial.close()
    return focus


def fit_change(ev: Evidence, current: Simulator, ch: Change, factors: FactorSet,
               part: Sequence[int]) -> tuple[Simulator, Fitted]:
    """A copy of ``current`` with the change fitted alone on ``part`` (the caller closes it)."""
    return FITS[ch.kind](ev, current, ch, factors, part)


# --------------------------------------------------------------------------- a round
@dataclass
class Round:
    """The model's residuals at the start of a round, against which candidates are scored."""

    number: int
    diagnosis: Mapping[str, Diagnosis]
    fitted: Rows
    held_rss: float | None
    structure: dict[str, float]        # each structured metric's sum of squares beyond its noise


def start_round(ev: Evidence, number: int, current: Simulator, diag: Mapping[str, Diagnosis]) -> Round:
    fitp, held = ev.parts()
    rows = ev.rows(current, fitp)
    per = rows.per_metric()
    counts = {m: int(np.sum(rows.metric == m)) for m in per}
    structure = {m: max(0.0, per[m] - counts[m] * ev.noise(diag[m]) ** 2)
                 for m in per if m in diag and diag[m].structured}
    return Round(number, diag, rows, ev.rows(current, held).rss() if held else None, structure)


def score(ev: Evidence, start: Round, ch: Change, fitted: Fitted, trial: Simulator) -> Candidate:
    """A fitted change scored against the round's start: evidence, materiality, explained share.
    The likelihood is Gaussian with each metric's noise, its rows counted by their independent
    share (penalty rows: unit variance, independent)."""
    fitp, held = ev.parts()
    r0, r1 = start.fitted, ev.rows(trial, fitp)
    per0, per1 = r0.per_metric(), r1.per_metric()
    diag = start.diagnosis
    explained = {m: (per0[m] - per1.get(m, 0.0)) / s for m, s in start.structure.items() if s > 0}
    moves = ev.moves(ch)
    own = sum(v for m, v in start.structure.items() if m in moves)
    share = (r0.rss() - r1.rss()) / own if own > 0 else 0.0
    chi = sum(ev.independent_share(diag[m]) * (per0[m] - per1.get(m, 0.0)) / ev.noise(diag[m]) ** 2
              for m in per0 if m in diag)
    chi += r0.penalty() - r1.penalty()
    n = sum(ev.independent_share(diag[m]) if m in diag else 1.0 for m in r0.metric)
    dbic = -chi + ch.k * math.log(max(2.0, n))
    both = np.isfinite(r0.values) & np.isfinite(r1.values) if len(r0.values) == len(r1.values) else None
    material = float(np.max(np.abs(r1.values[both] - r0.values[both]))) if both is not None and np.any(both) else 0.0
    held_rss = (start.held_rss, ev.rows(trial, held).rss()) if held else None
    c = Candidate(ch.name, start.number, dict(fitted.values), dict(fitted.stderr), (r0.rss(), r1.rss()), held_rss,
                  len(r0.residual), dbic, material, explained, share, affects=tuple(moves), kind=ch.kind, axis=ch.axis)
    c.reason = breaks_reason(r0, r1) or "; ".join(evidence_failures(dbic, material, own, share))
    return c


def breaks_reason(before: Rows, after: Rows) -> str:
    """Why a change is rejected outright: it fails (penalty rows) where the model flew or
    trimmed, so its BIC change and share would count failures, not a fit ("" if it does not)."""
    if after.penalty() <= before.penalty():
        return ""
    return f"{BREAKS}: it cannot fly or trim where the model did (failure rows {before.penalty():.3g} -> " \
           f"{after.penalty():.3g})"


def _try(ev: Evidence, start: Round, current: Simulator, factors: FactorSet,
         ch: Change) -> tuple[Candidate, Evidence | None] | str:
    """A change fitted alone on the fitted part and scored, with the evidence its fit ran on
    where that is not the evidence itself (its folds' :func:`focus_of`); the error where it
    breaks the model. A task: it reads the evidence and the model, and changes neither."""
    try:
        trial, fitted = fit_change(ev, current, ch, factors, ev.parts()[0])
    except CalibError as exc:
        return f"fit failed ({exc})"
    with trial:
        c = score(ev, start, ch, fitted, trial)
    c.reason = "; ".join([c.reason] * bool(c.reason) + ev.judge(ch, c, current, factors))
    return c, (fitted.focus if fitted.focus is not ev else None)


def _task(ev: Evidence, start: Round, current: Simulator, factors: FactorSet, item):
    """A candidate's fit (``("fit", change)``: :func:`_try`) or one of its folds (``("fold",
    change, fold)``, on the evidence its fit runs on: :func:`focus_of`; None where that fails:
    the fold is left to :func:`cross_validate`, as if not run ahead)."""
    if item[0] == "fit":
        return _try(ev, start, current, factors, item[1])
    try:
        return _fold(ev, current, item[1], factors, focus_of(ev, current, item[1], factors), item[2])
    except CalibError:
        return None


def try_changes(ev: Evidence, start: Round, current: Simulator, changes: Sequence[Change], factors: FactorSet,
                say, ahead: dict[str, float] | None = None, focus: dict[str, Evidence] | None = None) -> list[Candidate]:
    """Each change fitted alone on the fitted part and scored, as independent tasks on the
    evidence's executor (each fit starts from a fresh copy of the model: the same bits on
    any executor); one that breaks the model is rejected with the error named.

    ``ahead``: where the fits leave workers idle (fewer changes than workers), the folds of the
    first change (the likeliest: the evidence lists its candidates strongest first) run in the
    same batch, and its cross-validated sum is stored here by name (the sum
    :func:`cross_validate` gives: the same tasks, added in the same order). With as many
    changes as workers they would only lengthen the batch, and they are lost where another
    change is taken (a Level 5 campaign of Cl += K aileron x qbar, pool of 2: the four folds of
    K_da_slope, listed first, ran beside the four fits; the term was taken).

    ``focus``: the evidence each change's fit ran on, where it is not the evidence itself, is
    stored here by name (its folds run on it: :func:`cross_validate`)."""
    run_ahead = (ahead is not None and ev.executor.workers > len(changes) and bool(changes)
                 and changes[0].kind != "term")
    folds = ev.folds() if run_ahead else []
    folds = folds if len(folds) >= 2 else []
    items = [("fit", ch) for ch in changes] + [("fold", changes[0], f) for f in folds]
    done = ev.executor.map(partial(_task, ev, start, current, factors), items)
    if folds and all(x is not None for x in done[len(changes):]):
        ahead[changes[0].name] = sum(done[len(changes):], 0.0)
    tried = []
    for ch, c in zip(changes, done[:len(changes)]):
        if isinstance(c, str):
            say(f"round {start.number}: {ch.name}: {c}")
            continue
        c, on = c
        if on is not None and focus is not None:
            focus[ch.name] = on
        tried.append(c)
        numbers = "" if c.breaks else f"BIC {c.delta_bic:+10.1f}  explains {100 * c.share:5.0f} %  "
        say(f"round {start.number}: {ch.name:34s} {numbers}{'passes the fit tests' if not c.reason else 'rejected: ' + c.reason}")
    return tried


def _fold(ev: Evidence, current: Simulator, ch: Change, factors: FactorSet, on: Evidence, fold) -> float:
    """A fold's held-out residual sum of squares (flown: ``ev``), the change fitted on the rest
    (on ``on``: :func:`focus_of`). A task."""
    train, test = fold
    trial, _ = fit_change(on, current, ch, factors, train)
    with trial:
        return ev.rows(trial, test).rss()


def cross_validate(ev: Evidence, current: Simulator, ch: Change, factors: FactorSet,
                   focus: Evidence | None = None) -> float:
    """Residual sum of squares of every fold predicted by a fit of the change that did not see
    it (the evidence's folds, independent tasks on its executor); NaN with fewer than two folds.
    The folds' fits run on the evidence as the change's own fit did (``focus``, where the
    caller has it from that fit: :func:`focus_of` gives the same): on a Level 5 campaign of
    Cl += K aileron x qbar each fold flew 48 of its 105 flights to choose its own tests."""
    folds = ev.folds()
    if len(folds) < 2:
        return math.nan
    on = focus if focus is not None else focus_of(ev, current, ch, factors)
    return sum(ev.executor.map(partial(_fold, ev, current, ch, factors, on), folds), 0.0)


def best_out_of_sample(ev: Evidence, tried: list[Candidate], current: Simulator, changes: Mapping[str, Change],
                       factors: FactorSet, say, ahead: Mapping[str, float] | None = None,
                       focus: Mapping[str, Evidence] | None = None) -> Candidate | None:
    """Of the candidates that passed the fit tests, the one that explains the most of the
    structured residual and pays off in cross-validation; a synthesized term counts
    :data:`TERM_MARGIN` less, and ties keep the order of the BIC change (``ahead``: sums already
    computed, by name, and the evidence each fit ran on: :func:`try_changes`).

    The BIC change weighs each channel by its noise, and a stand-in that moves many quiet rows a
    little can carry more of it than the change that removes the structure: a library effect at
    its bound against the truth's term, BIC -13,926 explaining 70 % against -3,957 explaining
    89 % (cross-validated 1.46e4 against 1.08e4, the model 1.80e4). The margin: the best of a
    dictionary of terms fits a campaign's noise a little better than any one physical effect
    (pitch damping x Tc against K_Cmq on a Cmq x0.5 campaign, both 100 % to the printed digit)."""
    def explains(c: Candidate) -> float:
        return c.share - (TERM_MARGIN if c.kind == "term" else 0.0)

    everything = sorted({i for _, test in ev.folds() for i in test})
    cv0 = None
    for c in sorted((c for c in tried if not c.reason), key=lambda c: (-explains(c), c.delta_bic)):
        cv0 = ev.rows(current, everything).rss() if cv0 is None else cv0     # the model's: the same for each
        cv1 = (ahead or {}).get(c.effect)
        cv1 = ev.cross_validate(current, changes[c.effect], factors, (focus or {}).get(c.effect)) if cv1 is None else cv1
        c.cv = (cv0, cv1)
        if pays_off_out_of_sample(cv0, cv1):
            return c
        c.reason = (f"does not pay off out of sample: cross-validated residuals {cv0:.3g} -> {cv1:.3g} "
                    f"(needs -{100 * MIN_HELD_GAIN:.0f} %)")
        say(f"round {c.round}: {c.effect}: {c.reason}")
    return None


def add(current: Simulator, ch: Change, factors: FactorSet, cand: Candidate) -> tuple[Simulator, FactorSet]:
    """A copy of ``current`` with the change at its fitted values."""
    trial = current.clone()
    try:
        if ch.effect is not None:
            trial.add_effect(ch.effect)
            fs = factors.with_extra(ch.effect.as_factors(), cand.factors)
        elif ch.kind == "factor":
            fs = factors.updated(cand.factors)
        else:
            s = cand.factors[f"{ch.target}_scale"]
            trial.set_moment_of_inertia(ch.target, trial.moment_of_inertia(ch.target) * s, _inertia_note(ch.target, s))
            fs = factors
        trial.set_factors(fs)
    except BaseException:
        trial.close()
        raise
    return trial, fs


def fit_again(ev: Evidence, current: Simulator, ch: Change, factors: FactorSet, cand: Candidate) -> None:
    """The accepted change fitted alone once more, from its values, on the evidence as
    :meth:`Evidence.rebase` left it (its nuisance parameters fitted on the model with the
    change): what they took up of the change while fitted without it is the change's again.
    The candidate keeps its scores; its values and standard errors are the new fit's, and its
    reason says so. Traced on Iyy x1.6 (Level 5, seed 3): its pitch-rate rows had their
    minimum at 1.53 with the offsets of the model without it, at 1.56-1.57 with them refitted."""
    if ch.kind == "inertia":
        start = ((ch.target, cand.factors[f"{ch.target}_scale"] - 1.0),)
    elif ch.kind == "factor":
        start = ((ch.target, cand.factors[ch.target] - factors[ch.target]),)
    else:
        start = tuple(cand.factors.items())
    trial, fitted = fit_change(ev, current, replace(ch, start=start), factors, ev.parts()[0])
    trial.close()
    text = lambda values: ", ".join(f"{k} {v:.6g}" for k, v in values.items())
    cand.reason += (f"; fitted again with the evidence's nuisance parameters refitted with it: {text(cand.factors)} -> "
                    f"{text(fitted.values)}")
    cand.factors, cand.stderr = dict(fitted.values), dict(fitted.stderr)


def refit(ev: Evidence, rnd: int, current: Simulator, added: list[Change], factors: FactorSet, say) -> FitResult:
    """Every added effect refitted with the calibration factors the evidence names for each
    added change (fitted without it, they may have stood in for it); with none of either (a
    factor refitted or an inertia scaled, alone), the record of the model as it stands."""
    names = list(factors.extra)
    for ch in added:
        names += [f for f in ev.companions(ch) if f not in names]
    say(f"round {rnd}: added {added[-1].name}; refit of {', '.join(names) or 'nothing'}")
    fitp, _ = ev.parts()
    if not names:
        return unfitted(f"refit after {added[-1].name}", names, factors, _residuals(ev, current, fitp), current)
    opts = fit_options(ev, "refit")
    if "prior_center" in opts:
        opts = {**opts, "prior_center": factors}
    focus = ev.focused(current, fitp, names)
    return fit(f"refit after {added[-1].name}", names, factors, _residuals(focus, current, fitp), sim=current,
               executor=ev.executor, **opts)


# --------------------------------------------------------------------------- the loop
@dataclass
class LoopRun:
    """What the loop did: every candidate, the changes added, the refits, the aircraft it ends
    with (a parsed file and its factors) and what the evidence's ``final`` made of it."""

    candidates: list[Candidate]
    added: list[Change]
    refits: list[FitResult]
    factors: FactorSet
    tree: object
    final: object
    diagnoses: list                     # each round's diagnosis
    wall_time_s: float

    @property
    def added_names(self) -> list[str]:
        return [c.name for c in self.added]


def _round(ev: Evidence, rnd: int, current: Simulator, factors: FactorSet, diag,
           say) -> tuple[list[Candidate], Candidate | None, dict[str, Change]]:
    start = start_round(ev, rnd, current, diag)
    named = ev.named(rnd, current, diag, factors)
    by_name = {c.name: c for c in named}
    ahead: dict[str, float] = {}
    focus: dict[str, Evidence] = {}
    tried = try_changes(ev, start, current, named, factors, say, ahead, focus)
    best = best_out_of_sample(ev, tried, current, by_name, factors, say, ahead, focus)
    if best is None:
        terms = ev.synthesized(rnd, current, diag, factors, start)
        by_name.update({c.name: c for c in terms})
        more = try_changes(ev, start, current, terms, factors, say, focus=focus)
        tried += more
        best = best_out_of_sample(ev, more, current, by_name, factors, say, focus=focus)
    if best is not None:
        best.accepted = True
        best.reason = (f"accepted: explains the most of those that pass; out of sample {best.cv[0]:.3g} -> "
                       f"{best.cv[1]:.3g} ({len(ev.folds())}-fold cross-validation)")
        for c in tried:
            if not c.reason:
                c.reason = f"passes the fit tests; explains less than {best.effect} ({100 * best.share:.0f} %)"
    return tried, best, by_name


def run_loop(ev: Evidence, sim: Simulator, *, max_effects: int = MAX_EFFECTS, diagnosis=None,
             final: Callable[[Simulator], object] = lambda s: None,
             progress: Callable[[str], None] | None = None) -> LoopRun:
    """Close the loop on one kind of evidence (module doc). ``sim`` is left unchanged;
    ``diagnosis``: the first round's, where the caller has it; ``final(sim)`` runs on the
    aircraft the loop ends with before it closes (the evaluation a result reports)."""
    t0 = time.perf_counter()
    say = progress or (lambda s: None)
    candidates, added, refits, diagnoses = [], [], [], []
    with ExitStack() as boxes:
        current = boxes.enter_context(sim.clone())
        factors = current.factors
        for rnd in range(1, max_effects + 1):
            diag = diagnosis if rnd == 1 and diagnosis is not None else ev.diagnose(current)
            diagnoses.append(diag)
            if not any(d.structured for d in diag.values()):
                say(f"round {rnd}: no structured residual: nothing to add")
                break
            tried, best, changes = _round(ev, rnd, current, factors, diag, say)
            while best is None and ev.unscreened(rnd, diag):
                say(f"round {rnd}: nothing passes; screening the next structured part")
                more, best, changes = _round(ev, rnd, current, factors, diag, say)
                tried += more
            candidates += tried
            if best is None:
                break
            ch = changes[best.effect]
            trial, now = add(current, ch, factors, best)
            if ev.rebase(trial):
                trial.close()
                fit_again(ev, current, ch, factors, best)
                trial, now = add(current, ch, factors, best)
            boxes.enter_context(trial)
            current.close()
            current, factors = trial, now
            added.append(ch)
            refits.append(refit(ev, rnd, current, added, factors, say))
            factors = refits[-1].final
            current.set_factors(factors)
        out = final(current)
        tree = current.aircraft_tree()
    return LoopRun(candidates, added, refits, factors, tree, out, diagnoses, time.perf_counter() - t0)


# --------------------------------------------------------------------------- results
@dataclass(frozen=True)
class Unexplained:
    """A metric whose residual is still structured after the loop, with the states it follows."""

    metric: str
    correlates_with: list[str]          # regressors, most significant first
    reason: str
    correlations: list

    def as_dict(self) -> dict:
        return {"metric": self.metric, "correlates_with": list(self.correlates_with), "reason": self.reason,
                "correlations": [c.as_dict() for c in self.correlations]}


class LoopResult:
    """What every loop result shares (a dataclass with ``root``, ``aircraft``,
    ``aircraft_tree``, ``factors`` and ``diagnosis_after``)."""

    def unexplained(self) -> list[Unexplained]:
        """The metrics (channels) still structured after the loop, with the states they follow:
        reported, not attributed."""
        return [Unexplained(m, [c.regressor for c in d.correlates], d.reason, list(d.correlates))
                for m, d in self.diagnosis_after.items() if d.structured]

    def simulator(self) -> Simulator:
        """A simulator of the aircraft the loop ends with (use it in a ``with`` block)."""
        return Simulator.with_aircraft(self.root, self.aircraft, self.aircraft_tree, self.factors)


def write_aircraft(result, root: Path, out_name: str) -> Path:
    """Write the aircraft a loop ended with (a result with ``root``, ``aircraft``,
    ``aircraft_tree`` and ``factors``) as ``aircraft/<out_name>/`` of ``root`` (the parent's
    folder copied, its XML replaced), loadable by JSBSim and by this workbench."""
    return write_derived(AircraftPaths(result.root, result.aircraft), result.aircraft_tree, result.factors,
                         AircraftPaths(Path(root), out_name))
