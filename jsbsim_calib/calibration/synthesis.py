"""Term synthesis: when structured residual remains that no library effect explains, build the
missing term from a dictionary of physically meaningful regressors, select the sparsest set
that explains the residual, and write it as an effect the close-loop can test and add.

The pieces, each usable alone (the trim loop, :mod:`.closeloop`, chains them; a loop on time
histories can reuse all of them with its own residual function):

1. :func:`dictionary`: candidate terms ``Delta C = K x`` of the axes the structured metrics
   reveal (:mod:`.terms`: regressors, axes, interpretations, as data);
2. :func:`linearize`: the sensitivities of every residual to every candidate coefficient,
   by JSBSim: all candidates are added to a copy of the aircraft at zero (one reload), then
   each coefficient in turn is set to a small step and every point re-trimmed (re-flown);
3. :func:`select`: sparse regression on the linearized problem, sequential thresholded least
   squares (STLSQ, as SINDy) on noise-weighted, unit-norm columns with a small ridge, its
   threshold raised step by step from the last support (each step drops the weakest term),
   and the supports of forward stepwise selection (:func:`forward_path`: with correlated
   columns the threshold can drop a whole block of terms at once and pass over every small
   support); of the supports these paths visit (at most :data:`MAX_TERMS` terms) the one with the
   lowest extended Bayesian information criterion (BIC plus the log of the number of
   supports of its size, :func:`ebic_penalty`: with a dictionary of 15 terms plain BIC
   buys noise with extra terms);
4. :func:`null_test`: the same selection on residuals without structure (each metric's
   residuals shuffled among the points, with random signs; or, for groups of correlated rows
   such as the samples of a maneuver, whole groups' signs flipped): a dictionary always
   explains some noise; the observed explained chi-square must beat the null draws
   (p <= :data:`jsbsim_calib.calibration.diagnose.ALPHA`);
5. :func:`term_effect`: the selected terms as an :class:`~.effects.Effect` (XML text, one
   JSBSim ``<function>`` per term in its axis, each with its own persistent factor property
   and a description naming its regressor and the data it came from): the close-loop fits it
   with the project's fit engine and judges it by the library's evidence rules.

**The generic interface** (:class:`Linearization`): rows of residuals (model - data, in
tolerance units) with a weight each (1/noise, the likelihood's scale), the group each row
belongs to (a point of a trim campaign, a maneuver of a time history: the unit of
cross-validation folds and of the null test), the metric (channel) of each row, and
the sensitivity of each row to each term's coefficient. :func:`linearize` builds one from any
``residuals(sim) -> (r, labels)`` and a ``split(label) -> (group, metric) | None`` (default
``"<group>.<metric>"``; rows it returns None for, e.g. a failure penalty, are left out);
:func:`select` and :func:`null_test` work on it alone (``null_test(..., mode="flip")`` where the
rows of a group are correlated, as the samples of a maneuver are).

Why STLSQ in numpy (with :mod:`jsbsim_calib.core.numerics`) rather than scikit-learn or pysindy:
the problem is tiny (tens of candidates, a few hundred rows), and the selection is a
discontinuous function of its inputs; scikit-learn's solvers call OpenBLAS, whose kernels
differ by CPU in their last bits, so a threshold could fall differently on another machine.
Here every sum is correctly rounded: the same data select the same terms on every CPU.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Iterable, Mapping, Sequence

import numpy as np

from ..core import numerics
from ..core.errors import ModelError
from ..factors import Factor
from ..jsbsim.simulator import Simulator
from ..jsbsim.xml import comment, element, fmt, parse, sub, tostring, tree
from .effects import Effect
from .terms import AXES, REGRESSORS, SAME_FORM, axes_for, interpretation

STEP_COEFFICIENT = 1e-3      # linearization step: the coefficient change at the regressor's typical magnitude
MAX_TERMS = 3                # largest support the selection considers
EBIC_GAMMA = 1.0             # the extended BIC's weight of the number of supports of a size
RIDGE = 0.05                 # ridge of the thresholded least squares (unit-norm columns; SINDy's STLSQ alpha)
NULL_DRAWS = 199             # draws of the null test
NULL_SEED = 20260            # their seed (the same draws every run)
BOUND_MULTIPLE = 4.0         # a synthesized factor's bounds: this multiple of its linearized estimate
AFFECTS_TOL = 0.1            # a term "moves" a metric that it changes by this share of a tolerance somewhere
EFFECT_PREFIX = "synth_"


# --------------------------------------------------------------------------- terms
@dataclass(frozen=True)
class Term:
    """One candidate: ``Delta <coefficient of axis> = K x <regressor>``."""

    axis: str
    regressor: str

    @property
    def name(self) -> str:
        """``Cl_flaps``, ``Cm_flaps_x_tc``: the coefficient and the regressor's key."""
        return f"{AXES[self.axis].coefficient}_{REGRESSORS[self.regressor].key}"

    @property
    def label(self) -> str:
        return f"{AXES[self.axis].coefficient} ~ {self.regressor}"

    @property
    def factor_property(self) -> str:
        """The JSBSim property of the term's factor K."""
        return f"calibration/effects/{EFFECT_PREFIX}{self.name}"

    @property
    def unit(self) -> str:
        """Unit of the coefficient K (per unit of the regressor)."""
        u = REGRESSORS[self.regressor].unit
        return "-" if u == "-" else f"1/{u}"

    @property
    def step(self) -> float:
        """The linearization step of K (:data:`STEP_COEFFICIENT` at the regressor's typical magnitude)."""
        return STEP_COEFFICIENT / REGRESSORS[self.regressor].scale

    def interpretation(self) -> str:
        return interpretation(self.axis, self.regressor)

    def expression(self) -> str:
        """The force or moment in JSBSim's function language: K x qbar S [l]."""
        a = AXES[self.axis]
        length = f"<property>{a.length}</property>" if a.length else ""
        return (f"<product><property>aero/qbar-psf</property><property>metrics/Sw-sqft</property>{length}"
                f"<property>{self.factor_property}</property>{REGRESSORS[self.regressor].xml}</product>")

    def as_dict(self) -> dict:
        return {"term": self.name, "axis": self.axis, "coefficient": AXES[self.axis].coefficient,
                "regressor": self.regressor, "unit": self.unit, "interpretation": self.interpretation()}


def dictionary(axes: Iterable[str], exclude: Iterable[str] = (), *, dynamic: bool = False) -> tuple[Term, ...]:
    """The candidate terms of ``axes`` (every regressor that may act on each), without those
    whose factor property is in ``exclude`` (terms the aircraft has already); ``dynamic``: with
    the regressors only maneuvers reveal (rates times states, alpha-dot, deflections times states)."""
    skip = set(exclude)
    out = []
    for a in axes:
        if a not in AXES:
            raise ModelError(f"unknown axis '{a}'; axes: {', '.join(AXES)}")
        out += [Term(a, r.name) for r in REGRESSORS.values() if a in r.axes and (dynamic or not r.dynamic)]
    return tuple(t for t in out if t.factor_property not in skip)


def dictionary_for(metrics: Iterable[str], exclude: Iterable[str] = ()) -> tuple[Term, ...]:
    """The candidate terms of the axes the metrics reveal (:data:`.terms.METRIC_AXES`)."""
    return dictionary(axes_for(metrics), exclude)


# --------------------------------------------------------------------------- effects
def _bound(estimate: float, step: float) -> float:
    """A round bound (1, 2 or 5 x 10^k) at least :data:`BOUND_MULTIPLE` times the estimate."""
    want = max(BOUND_MULTIPLE * abs(estimate), 10.0 * step)
    k = math.floor(math.log10(want))
    return next(m * 10.0**k for m in (1.0, 2.0, 5.0, 10.0) if m * 10.0**k >= want)


def _effect_xml(name: str, terms: Sequence[Term], factors: Sequence[Factor], description: str, note: str,
                affects: Sequence[str], source: str) -> str:
    root = element("effect", name=name, affects=" ".join(affects))
    sub(root, "description", description)
    sub(root, "regressor", ", ".join(t.regressor for t in terms))
    for f in factors:
        sub(root, "factor", f.doc, name=f.name, property=f.property, neutral="0", lower=fmt(f.lower),
            upper=fmt(f.upper), unit=f.unit)
    aero = sub(root, "aerodynamics")
    for t in terms:
        ax = aero.find(f"axis[@name='{t.axis}']")
        if ax is None:
            ax = sub(aero, "axis", name=t.axis)
        fn = sub(ax, "function", name=f"aero/effects/{EFFECT_PREFIX}{t.name}-{AXES[t.axis].unit}")
        sub(fn, "description", f"{t.label} [{t.unit}]: {t.interpretation()}; {source}")
        fn.append(parse(t.expression(), t.name))
    doc = tree(root)
    comment(root, note)
    return tostring(doc).decode()


def term_effect(terms: Sequence[Term], estimates: Sequence[float], *, source: str, affects: Sequence[str],
                held: Sequence[str] = ()) -> Effect:
    """The terms as an effect: one factor per term (property ``calibration/effects/synth_<term>``,
    neutral 0, bounds :data:`BOUND_MULTIPLE` times its estimate, rounded), one ``<function>`` per
    term in its axis; ``source`` names the data the terms came from (descriptions, comments);
    ``held``: calibration factors not to refit with it (its ``same_as``, with those of
    :data:`.terms.SAME_FORM` for each term and for each state of a product: Cl ~ aileron x qbar
    is the aileron power K_da_slope made to vary with the dynamic pressure, and refitted with
    it, the two nearly collinear where the state varies little, the split between them followed
    the sensors' errors: on the Level 5 plan 0.70 of the truth's coefficient, held 1.000)."""
    if not terms:
        raise ModelError("an effect needs at least one term")
    name = EFFECT_PREFIX + "_".join(t.name for t in terms)
    factors = []
    for t, k in zip(terms, estimates):
        b = _bound(k, t.step)
        doc = f"{t.label} [{t.unit}]: {t.interpretation()}"
        factors.append(Factor(t.name, t.factor_property, 0.0, -b, b, t.unit, ("effect",), tuple(affects),
                              f"{AXES[t.axis].noun.split(' (')[0]} term", doc))
    description = "; ".join(f"Delta {t.label.replace(' ~ ', ' = K x ')} [K in {t.unit}]" for t in terms)
    note = f"Synthesized from {source}: " + "; ".join(f"{t.label}: {t.interpretation()}" for t in terms)
    forms = [(t.axis, r) for t in terms for r in dict.fromkeys([t.regressor, *t.regressor.split(" x ")])]
    same = tuple(dict.fromkeys([f for form in forms for f in SAME_FORM.get(form, ())] + list(held)))
    text = _effect_xml(name, terms, factors, description, note, affects, f"synthesized by jsbsim-calib close-loop "
                       f"from {source}")
    return Effect(name, description, tuple(affects), same, ", ".join(t.regressor for t in terms), note,
                  tuple(factors), Path(source), text)


def probe_effect(terms: Sequence[Term]) -> Effect:
    """All candidate terms at once (factors at zero): the copy :func:`linearize` perturbs."""
    return term_effect(terms, [0.0] * len(terms), source="the linearization", affects=())


# --------------------------------------------------------------------------- the generic interface
@dataclass(frozen=True)
class Linearization:
    """A residual and its sensitivities to candidate coefficients (module doc): row i has the
    residual ``residual[i]`` (model - data, tolerance units), the weight ``weight[i]`` (1/noise
    in the same units), belongs to ``group[i]`` and measures ``metric[i]``; ``sensitivity[i, j]``
    is the change of residual i per unit coefficient of ``terms[j]``."""

    terms: tuple[Term, ...]
    residual: np.ndarray
    sensitivity: np.ndarray
    weight: np.ndarray
    group: tuple[str, ...]
    metric: tuple[str, ...]
    notes: tuple[str, ...] = ()

    def subset(self, groups: Iterable) -> "Linearization":
        """The rows of the given groups."""
        keep = {str(g) for g in groups}
        idx = [i for i, g in enumerate(self.group) if g in keep]
        return Linearization(self.terms, self.residual[idx], self.sensitivity[idx], self.weight[idx],
                             tuple(self.group[i] for i in idx), tuple(self.metric[i] for i in idx), self.notes)

    @property
    def groups(self) -> tuple[str, ...]:
        return tuple(dict.fromkeys(self.group))

    def change(self, terms: Sequence[Term], coefficients: Sequence[float]) -> np.ndarray:
        """The linearized change of every residual when ``terms`` take ``coefficients``."""
        cols = [self.terms.index(t) for t in terms]
        return np.array([numerics.dot(self.sensitivity[i, cols], coefficients) for i in range(len(self.residual))])

    def moved(self, terms: Sequence[Term], coefficients: Sequence[float], tol: float = AFFECTS_TOL) -> tuple[str, ...]:
        """The metrics the terms change by ``tol`` (tolerance units) somewhere."""
        d = np.abs(self.change(terms, coefficients))
        return tuple(m for m in dict.fromkeys(self.metric)
                     if max((d[i] for i, x in enumerate(self.metric) if x == m), default=0.0) >= tol)


def split_label(label: str) -> tuple[str, str] | None:
    """(group, metric) of a residual label ``"<group>.<metric>"``; None for a row without a dot
    (a penalty: not a residual of a metric)."""
    if "." not in label:
        return None
    g, m = label.split(".", 1)
    return g, m


Split = Callable[[str], "tuple[str, str] | None"]


def _perturbed(sim: Simulator, terms, residuals, r0, lab0, split: Split) -> tuple[np.ndarray, list[str]]:
    """Columns of sensitivities: each term at its step, every residual again."""
    cols, notes = [], []
    for t in terms:
        sim.set_effect_values({t.factor_property: t.step})
        r, lab = residuals(sim)
        sim.set_effect_values({t.factor_property: 0.0})
        penalties_equal = all(a == b for a, b, x in zip(r, r0, lab) if split(x) is None)
        if lab != lab0 or not penalties_equal or not np.all(np.isfinite(r)):
            notes.append(f"{t.label}: a trim failed at the linearization step; left out")
            cols.append(np.zeros(len(r0)))
            continue
        cols.append((np.asarray(r) - r0) / t.step)
    return np.column_stack(cols) if cols else np.zeros((len(r0), 0)), notes


def linearize(sim: Simulator, terms: Sequence[Term], residuals: Callable[[Simulator], tuple[np.ndarray, list[str]]],
              weight: Mapping[str, float], split: Split = split_label) -> Linearization:
    """Sensitivities of ``residuals`` to every term's coefficient by JSBSim (module doc, step 2):
    ``sim`` is left unchanged (a copy is perturbed); ``weight``: 1/noise per metric (a metric
    not given: 1); ``split``: a row label's (group, metric), None for rows to leave out
    (default: ``"<group>.<metric>"``, :func:`split_label`)."""
    with sim.clone() as probe:
        probe.add_effect(probe_effect(terms))
        r0, lab0 = residuals(probe)
        r0 = np.asarray(r0, float)
        J, notes = _perturbed(probe, terms, residuals, r0, list(lab0), split)
    rows = [(i, split(x)) for i, x in enumerate(lab0) if split(x) is not None]
    idx = [i for i, _ in rows]
    return Linearization(tuple(terms), r0[idx], J[idx], np.array([float(weight.get(gm[1], 1.0)) for _, gm in rows]),
                         tuple(gm[0] for _, gm in rows), tuple(gm[1] for _, gm in rows), tuple(notes))


# --------------------------------------------------------------------------- sparse selection
@dataclass(frozen=True)
class Selection:
    """The sparsest set of terms the linearized residual asks for (:func:`select`)."""

    terms: tuple[Term, ...]
    coefficients: tuple[float, ...]          # per unit regressor, linearized estimate
    chi2_before: float                       # weighted residual sum of squares without terms
    chi2_after: float                        # with the selected terms (linearized)
    rows: int
    path: tuple[tuple[tuple[str, ...], float], ...] = ()   # supports visited and their extended-BIC change

    @property
    def delta_bic(self) -> float:
        return self.chi2_after - self.chi2_before + len(self.terms) * math.log(max(self.rows, 1))

    @property
    def explained(self) -> float:
        """Linearized chi-square explained."""
        return self.chi2_before - self.chi2_after

    def as_dict(self) -> dict:
        return {"terms": [t.name for t in self.terms], "estimates": list(self.coefficients),
                "chi2_before": self.chi2_before, "chi2_after": self.chi2_after, "rows": self.rows,
                "delta_bic": self.delta_bic,
                "path": [{"terms": list(s), "delta_bic": b} for s, b in self.path]}


@dataclass(frozen=True)
class _Normal:
    """The weighted problem on unit-norm columns as normal equations: G = A'A, b = A'y."""

    G: np.ndarray
    b: np.ndarray
    yy: float
    scale: np.ndarray                         # column norms (physical coefficient = w / scale)
    usable: tuple[int, ...]                   # columns with a sensitivity


def _normal(lin: Linearization) -> tuple[_Normal, np.ndarray, np.ndarray]:
    A = lin.sensitivity * lin.weight[:, None]
    y = -lin.residual * lin.weight
    s = np.array([numerics.norm(A[:, j]) for j in range(A.shape[1])])
    top = float(np.max(s)) if len(s) else 0.0
    usable = tuple(j for j in range(len(s)) if s[j] > 1e-12 * max(top, 1e-300) and top > 0)
    An = A[:, list(usable)] / s[list(usable)] if usable else np.zeros((len(y), 0))
    return _Normal(numerics.gram(An), numerics.matvec(An.T, y), numerics.sum_sq(y), s, usable), An, y


def _solve(nq: _Normal, S: Sequence[int], b: np.ndarray, ridge: float) -> np.ndarray:
    G = nq.G[np.ix_(S, S)] + ridge * np.eye(len(S))
    try:
        return numerics.solve(G, b[list(S)])
    except numerics.SingularMatrixError:
        return np.zeros(len(S))


def _chi2(nq: _Normal, S: Sequence[int], b: np.ndarray) -> tuple[float, np.ndarray]:
    """Weighted residual sum of squares of the least-squares fit on S (no ridge), and its weights."""
    if not S:
        return nq.yy, np.zeros(0)
    w = _solve(nq, S, b, 1e-12)
    return max(0.0, nq.yy - numerics.dot(w, b[list(S)])), w


def stlsq_path(nq: _Normal, b: np.ndarray, ridge: float = RIDGE) -> list[tuple[int, ...]]:
    """Supports of sequential thresholded least squares as its threshold rises: from the full
    ridge fit, the threshold is set just above the weakest |weight|, STLSQ iterates (threshold,
    refit) to a fixed support, and so on until no term is left."""
    S = list(range(len(nq.usable)))
    path = []
    while S:
        w = _solve(nq, S, b, ridge)
        path.append(tuple(S))
        lam = float(np.min(np.abs(w))) * (1.0 + 1e-9)
        while S:
            keep = [j for j, wj in zip(S, w) if abs(wj) >= lam]
            if len(keep) == len(S):
                break
            S = keep
            w = _solve(nq, S, b, ridge) if S else w
    return path


def forward_path(nq: _Normal, b: np.ndarray, max_terms: int) -> list[tuple[int, ...]]:
    """Supports of forward stepwise selection: from none, the term that lowers the chi-square
    most is added, up to ``max_terms`` (ties: the first column). STLSQ's threshold can drop a
    whole block of correlated terms at once and pass over the small supports; these are the
    small supports a greedy search visits."""
    S: list[int] = []
    path = []
    for _ in range(min(max_terms, len(nq.usable))):
        best, best_chi2 = None, math.inf
        for j in range(len(nq.usable)):
            if j in S:
                continue
            chi2, _ = _chi2(nq, S + [j], b)
            if chi2 < best_chi2:
                best, best_chi2 = j, chi2
        if best is None:
            break
        S.append(best)
        path.append(tuple(sorted(S)))
    return path


def ebic_penalty(k: int, n_rows: int, n_candidates: int, gamma: float = EBIC_GAMMA) -> float:
    """Penalty of a support of k terms out of ``n_candidates`` on ``n_rows`` residuals: BIC's
    k ln n plus 2 gamma ln C(p, k) (extended BIC, Chen & Chen 2008), the price of having
    looked at every support of that size."""
    return k * math.log(max(n_rows, 1)) + 2.0 * gamma * math.log(math.comb(max(n_candidates, k), k))


def _best(nq: _Normal, b: np.ndarray, n_rows: int, max_terms: int) -> tuple[tuple[int, ...], float, np.ndarray,
                                                                               list[tuple[tuple[int, ...], float]]]:
    """The support of the forward and the STLSQ paths (at most ``max_terms`` terms) with the
    lowest extended BIC (ties: the smaller, then the first visited): support, chi2,
    least-squares weights, and every support scored (change from none)."""
    p = len(nq.usable)
    best, best_score = ((), nq.yy, np.zeros(0)), 0.0
    scored: list[tuple[tuple[int, ...], float]] = [((), 0.0)]
    for S in forward_path(nq, b, max_terms) + stlsq_path(nq, b):
        if len(S) > max_terms or any(S == s for s, _ in scored):
            continue
        chi2, w = _chi2(nq, S, b)
        score = chi2 - nq.yy + ebic_penalty(len(S), n_rows, p)
        scored.append((S, score))
        if score < best_score or (score == best_score and len(S) < len(best[0])):
            best, best_score = (S, chi2, w), score
    return best[0], best[1], best[2], scored


def select(lin: Linearization, max_terms: int = MAX_TERMS) -> Selection:
    """The sparsest set of terms that explains the linearized residual (module doc, step 3)."""
    nq, _, _ = _normal(lin)
    S, chi2, w, path = _best(nq, nq.b, len(lin.residual), max_terms)
    cols = [nq.usable[j] for j in S]
    terms = tuple(lin.terms[c] for c in cols)
    coef = tuple(float(wj / nq.scale[c]) for wj, c in zip(w, cols))
    named = tuple((tuple(lin.terms[nq.usable[j]].name for j in s), float(d)) for s, d in path)
    return Selection(terms, coef, nq.yy, chi2, len(lin.residual), named)


def _null_draw(y: np.ndarray, lin: Linearization, rng: np.random.Generator, mode: str) -> np.ndarray:
    """Residuals without structure: each metric's rows shuffled among the groups with random
    signs (``permute``), or each group's rows with one random sign (``flip``)."""
    if mode == "flip":
        groups = lin.groups
        signs = dict(zip(groups, rng.choice((-1.0, 1.0), size=len(groups))))
        return y * np.array([signs[g] for g in lin.group])
    out = np.empty_like(y)
    for m in dict.fromkeys(lin.metric):
        idx = np.array([i for i, x in enumerate(lin.metric) if x == m])
        out[idx] = y[idx][rng.permutation(len(idx))] * rng.choice((-1.0, 1.0), size=len(idx))
    return out


def null_test(lin: Linearization, selection: Selection, draws: int = NULL_DRAWS, seed: int = NULL_SEED,
              max_terms: int = MAX_TERMS, mode: str = "permute") -> float:
    """p-value of the selection's explained chi-square against the same selection on residuals
    without structure (module doc, step 4): ``permute`` shuffles each metric's residuals among
    the points and flips their signs at random (independent points: trims, snapshots, log
    segments); ``flip`` only flips the sign of whole groups (groups whose rows are correlated,
    e.g. the samples of a maneuver)."""
    if mode not in ("permute", "flip"):
        raise ModelError(f"null test mode must be 'permute' or 'flip', not {mode!r}")
    nq, An, y = _normal(lin)
    rng = np.random.default_rng(seed)
    beaten = 0
    for _ in range(draws):
        b = numerics.matvec(An.T, _null_draw(y, lin, rng, mode))
        _, chi2, _, _ = _best(nq, b, len(lin.residual), max_terms)      # a draw keeps the sum of squares
        beaten += (nq.yy - chi2) >= selection.explained
    return (1.0 + beaten) / (1.0 + draws)


# --------------------------------------------------------------------------- the record
@dataclass
class Synthesis:
    """One synthesis attempt of the close-loop: what it worked on, what it selected, how the
    selected terms fared (JSON and report)."""

    round: int
    metrics: tuple[str, ...]                 # the structured metrics it set out to explain
    axes: tuple[str, ...]
    candidates: int                          # terms in the dictionary
    selection: Selection | None = None
    effect: str = ""
    terms: list[dict] = field(default_factory=list)   # per term: interpretation, estimate, fitted value, stderr
    p_null: float = math.nan
    cv: tuple[float, float] | None = None
    accepted: bool = False
    reason: str = ""
    notes: list[str] = field(default_factory=list)

    def as_dict(self) -> dict:
        return {"round": self.round, "metrics": list(self.metrics), "axes": list(self.axes),
                "candidates": self.candidates, "selection": self.selection.as_dict() if self.selection else None,
                "effect": self.effect, "terms": self.terms,
                "p_null": self.p_null if math.isfinite(self.p_null) else None,
                "cross_validated": list(self.cv) if self.cv else None, "accepted": self.accepted,
                "reason": self.reason, "notes": self.notes}
