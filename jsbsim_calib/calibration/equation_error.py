"""Equation error on recorded maneuvers: rank candidate changes of the model without flying them.

Output error (fly the model, compare the responses) is how a candidate is judged; it costs a
flight of every maneuver per evaluation. Equation error is how candidates are *ranked*: at
every recorded sample, the model's forces and moments at the recorded state are set against
what the recorded motion needs, and each candidate change is a column of the same rows.

* **The state** of sample k is the model's trim at the maneuver's start plus the recorded
  change since the first sample (airspeed, alpha, beta, attitude, rates, surfaces, flaps,
  throttle), as the replay flies it: a sensor's constant bias cancels, and at the first
  sample the model is trimmed. JSBSim evaluates it (``run_ic``: every model once, no time
  step); mass, fuel, CG and the engine's speed are the trim's.
* **What the motion needs**: Euler's equations with the model's inertia J, ``J w' + w x J w``,
  over each sample interval (the change of the recorded rates divided by its length, the
  rates at its middle), and for lift the recorded normal load factor (``nz W``). The model's
  side is the mean of its two ends (the trapezoidal rule: a 10 Hz record of a 0.15 s input
  ramp keeps its derivative unbiased, a smoothing filter's would not). The residual row is
  (model - needed) in coefficient units (divided by ``qbar S b``, ``qbar S c`` or ``qbar S``),
  on the axes ROLL, PITCH, YAW and LIFT (LIFT where nz is recorded).
* **A column** is the change of every row per unit of a candidate's coefficient: a term of
  the dictionary (:mod:`.terms`, ``dynamic=True``: rates times states, alpha-dot, deflections
  times states) read from its JSBSim function at a tiny coefficient in the same evaluation; an
  existing calibration factor or a library effect's factor by a step of its property; a moment
  of inertia by the equations (a relative change of Ixx, Iyy or Izz changes what the motion
  needs, not what the model gives).

* **Sensor noise** would bias the ranking (errors in variables): the noise of a state enters
  both the model's moment at it (the residual) and every column evaluated there, so the
  columns of the noisiest states (alpha and beta vanes, airspeed) gain a share they do not
  have, and the noise of the rates' change enters both the needed moment and an inertia's
  column. The model is evaluated at vane and airspeed states smoothed by :func:`smoothed`,
  and the inertia columns use smoothed rates; the needed moments keep the recorded rates (their
  noise is the residual's, unbiased). On the packaged Level 5 campaign of a Cmq x0.5 truth
  with its sensor noise, the unsmoothed screen ranked K_Cm_alpha above K_Cmq (share 0.156
  against 0.121) and left K_Cmq sixth; smoothed, K_Cmq is the first factor, at -9.48 against
  the truth's -9.23.

The rows and columns form a :class:`~.synthesis.Linearization` (groups: maneuvers; metrics:
axes), so :func:`~.synthesis.select` and :func:`~.synthesis.null_test` apply as they are, and
:func:`rank` scores every candidate alone by the chi-square it explains. Samples where the
engine's speed leaves its trimmed value (throttle changes: the evaluation holds the trimmed
propeller speed) are left out.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Mapping, Sequence

import numpy as np
from scipy.signal import savgol_filter

from ..core import numerics
from ..factors import FactorSet
from ..jsbsim.simulator import Simulator
from ..jsbsim.trajectory import SURFACES, flap_command_per_deg, surface_command, surface_deg
from .effects import Effect
from .synthesis import Linearization, Term, probe_effect
from .terms import AXES

KT = 1.6878098571011957          # ft/s per knot
D2R = math.pi / 180.0
EE_AXES = ("ROLL", "PITCH", "YAW", "LIFT")
RPM_BAND = 40.0                  # samples whose engine speed left the first sample's by more are left out
TERM_PROBE = 1e-6                # term coefficients during the evaluation (their functions read, their force negligible)
FACTOR_STEP = 0.01               # a factor's step, share of its range
TOTALS = ("moments/l-total-lbsft", "moments/m-total-lbsft", "moments/n-total-lbsft", "forces/fbz-total-lbs")
INERTIA_AXES = {"ixx": ("ROLL", 0), "iyy": ("PITCH", 1), "izz": ("YAW", 2)}
SMOOTH_SAMPLES = 11              # the smoothing window (1.1 s at 10 Hz; :func:`smoothed`)
VANES = ("ktas", "kcas", "alpha_deg", "beta_deg", "pressure_alt_ft")   # the states smoothed (module doc)
RATES = ("p_deg_s", "q_deg_s", "r_deg_s")


@dataclass(frozen=True)
class Column:
    """A candidate's coefficient: a dictionary term, an existing factor, an effect's factor, or
    a relative change of a moment of inertia."""

    kind: str                    # term | factor | effect | inertia
    target: str                  # the term's name, the factor's, the effect's, ixx/iyy/izz
    name: str                    # unique: kind:target[.factor]
    label: str                   # for the report
    term: Term | None = None
    property: str = ""           # the JSBSim property stepped (factor, effect)
    step: float = 0.0


def term_columns(terms: Sequence[Term]) -> list[Column]:
    return [Column("term", t.name, f"term:{t.name}", t.label, term=t) for t in terms]


def factor_columns(factors: FactorSet, names: Sequence[str]) -> list[Column]:
    out = []
    for n in names:
        f = factors.factor(n)
        out.append(Column("factor", n, f"factor:{n}", f"{n} ({f.doc.split(';')[0]})", property=f.property,
                          step=FACTOR_STEP * (f.upper - f.lower)))
    return out


def effect_columns(effects: Mapping[str, Effect]) -> list[Column]:
    return [Column("effect", name, f"effect:{e.label(f)}", f"{name} ({f.name})", property=f.property,
                   step=FACTOR_STEP * (f.upper - f.lower))
            for name, e in effects.items() for f in e.factors]


def inertia_columns() -> list[Column]:
    return [Column("inertia", k, f"inertia:{k}", f"{k.upper()} x (1 + s)") for k in INERTIA_AXES]


# --------------------------------------------------------------------------- one maneuver
@dataclass
class _Start:
    """The model's trim at a maneuver's start: what the recorded changes are added to."""

    values: dict[str, float]     # ic and fcs properties
    vt_over_vc: float
    rpm: float
    weight: float
    inertia: np.ndarray          # J (slug ft2), body axes


def _start(fdm) -> _Start:
    keys = ("ic/h-sl-ft", "ic/phi-rad", "ic/theta-rad", "ic/psi-true-rad", "ic/p-rad_sec", "ic/q-rad_sec",
            "ic/r-rad_sec", "fcs/throttle-cmd-norm", "fcs/flap-cmd-norm", "fcs/flap-pos-deg")
    vals = {k: float(fdm[k]) for k in keys}
    vals.update({c: float(fdm[p]) for c, (p, _, _) in SURFACES.items()})
    u, v, w = fdm["ic/u-fps"], fdm["ic/v-fps"], fdm["ic/w-fps"]
    vals["V"] = math.sqrt(u * u + v * v + w * w)
    vals["alpha"], vals["beta"] = math.atan2(w, u), math.asin(v / vals["V"])
    ixz = fdm["inertia/ixz-slugs_ft2"]
    J = np.array([[fdm["inertia/ixx-slugs_ft2"], 0.0, -ixz], [0.0, fdm["inertia/iyy-slugs_ft2"], 0.0],
                  [-ixz, 0.0, fdm["inertia/izz-slugs_ft2"]]])
    return _Start(vals, fdm["velocities/vtrue-kts"] / fdm["velocities/vc-kts"],
                  fdm["propulsion/engine/engine-rpm"], fdm["inertia/weight-lbs"], J)


def _change(rec: Mapping[str, np.ndarray], c: str, k: int, default: float = 0.0) -> float:
    return float(rec[c][k] - rec[c][0]) if c in rec else default


def _set_sample(sim: Simulator, s: _Start, rec: Mapping[str, np.ndarray], k: int) -> None:
    """The model's trimmed state plus the recorded change at sample k, evaluated by JSBSim."""
    fdm, v = sim.fdm, s.values
    if "ktas" in rec:
        V = v["V"] + _change(rec, "ktas", k) * KT
    else:
        V = v["V"] + _change(rec, "kcas", k) * KT * s.vt_over_vc
    a = v["alpha"] + _change(rec, "alpha_deg", k) * D2R
    b = v["beta"] + _change(rec, "beta_deg", k) * D2R
    fdm["ic/u-fps"], fdm["ic/v-fps"], fdm["ic/w-fps"] = V * math.cos(a) * math.cos(b), V * math.sin(b), \
        V * math.sin(a) * math.cos(b)
    fdm["ic/h-sl-ft"] = v["ic/h-sl-ft"] + _change(rec, "pressure_alt_ft", k)
    fdm["ic/phi-rad"] = v["ic/phi-rad"] + _change(rec, "roll_deg", k) * D2R
    fdm["ic/theta-rad"] = v["ic/theta-rad"] + _change(rec, "pitch_deg", k) * D2R
    for c, ic in (("p_deg_s", "ic/p-rad_sec"), ("q_deg_s", "ic/q-rad_sec"), ("r_deg_s", "ic/r-rad_sec")):
        fdm[ic] = v[ic] + _change(rec, c, k) * D2R
    for c, (prop, _, _) in SURFACES.items():
        fdm[prop] = surface_command(sim, c, surface_deg(sim, c, v[c]) + _change(rec, c, k))
    fdm["fcs/throttle-cmd-norm"] = min(1.0, max(0.0, v["fcs/throttle-cmd-norm"] + _change(rec, "throttle_norm", k)))
    fdm["fcs/flap-cmd-norm"] = v["fcs/flap-cmd-norm"] + _change(rec, "flaps_deg", k) * flap_command_per_deg(sim)
    fdm.run_ic()
    fdm.run_ic()      # alpha-dot from this state's accelerations (the first evaluation's), not the last sample's


def _refs(fdm) -> np.ndarray:
    """qbar S times b, c, b, 1: what turns a moment (force) into a coefficient, per axis."""
    qs = fdm["aero/qbar-psf"] * fdm["metrics/Sw-sqft"]
    return np.array([qs * fdm["metrics/bw-ft"], qs * fdm["metrics/cbarw-ft"], qs * fdm["metrics/bw-ft"], qs])


def _needed(J: np.ndarray, w: np.ndarray, wdot: np.ndarray) -> np.ndarray:
    """Moments the motion needs, rows of samples: J w' + w x J w."""
    Jw = w @ J.T
    return wdot @ J.T + np.cross(w, Jw)


def _intervals(rec: Mapping[str, np.ndarray], t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Body rates (rad/s) at the middle of each sample interval and their change over it
    divided by its length: the derivative of the interval, unbiased by a fast input (a
    smoothing filter's derivative at 10 Hz is not)."""
    w = np.column_stack([np.asarray(rec[c], float) * D2R for c in ("p_deg_s", "q_deg_s", "r_deg_s")])
    return 0.5 * (w[1:] + w[:-1]), np.diff(w, axis=0) / np.diff(t)[:, None]


def smoothed(rec: Mapping[str, np.ndarray], channels: Sequence[str]) -> dict[str, np.ndarray]:
    """The record with ``channels`` smoothed (a quintic Savitzky-Golay fit over
    :data:`SMOOTH_SAMPLES` samples: the noise of a 10 Hz record falls to about half, a pitch
    pulse's response keeps its shape)."""
    out = dict(rec)
    for c in channels:
        if c in rec and len(rec[c]) >= SMOOTH_SAMPLES:
            out[c] = savgol_filter(np.asarray(rec[c], float), SMOOTH_SAMPLES, 5, mode="interp")
    return out


def _usable(test, n: int) -> list[int]:
    """Samples to evaluate (those whose engine speed stays at the first sample's)."""
    rec = test.record
    if "rpm" not in rec:
        return list(range(n))
    return [k for k in range(n) if abs(rec["rpm"][k] - rec["rpm"][0]) <= RPM_BAND]


@dataclass
class _Rows:
    """The rows of every maneuver so far: residual, columns, axis and maneuver of each."""

    residual: list = field(default_factory=list)
    columns: list = field(default_factory=list)
    axis: list = field(default_factory=list)
    group: list = field(default_factory=list)


def _evaluate(sim: Simulator, s: _Start, rec, k: int,
              cols: Sequence[Column]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Sample k: the model's moments and lift (-Fz) divided by their references, and the
    columns (the same units), four rows each."""
    _set_sample(sim, s, rec, k)
    fdm = sim.fdm
    base = np.array([fdm[p] for p in TOTALS])
    ref = _refs(fdm)
    col = np.zeros((4, len(cols)))
    for j, c in enumerate(cols):
        col[:, j] = _column(sim, s, c, base, ref)
    return np.array([base[0], base[1], base[2], -base[3]]), ref, col


def _maneuver(sim: Simulator, test, cols: Sequence[Column], rows: _Rows, notes: list[str]) -> None:
    """The rows of one maneuver: one per axis and sample interval whose two ends are usable,
    the model's value and columns averaged over the ends (trapezoidal rule)."""
    t = sim.trim(test.maneuver.start)
    if not t.trimmed:
        notes.append(f"{test.id}: no trim at its start ({t.reason}); left out")
        return
    s, rec = _start(sim.fdm), smoothed(test.record, VANES)
    w, wdot = _intervals(test.record, test.time_s)
    ws, wdots = _intervals(smoothed(test.record, RATES), test.time_s)    # the inertia columns' (module doc)
    usable = set(_usable(test, len(test.time_s)))
    at = {k: _evaluate(sim, s, rec, k, cols) for k in sorted(usable)}
    inert = [c for c in cols if c.kind == "inertia"]
    for k in range(len(test.time_s) - 1):
        if k not in usable or k + 1 not in usable:
            continue
        (m0, ref0, c0), (m1, ref1, c1) = at[k], at[k + 1]
        ref = 0.5 * (ref0 + ref1)
        model = 0.5 * (m0 / ref0 + m1 / ref1)
        col = 0.5 * (c0 + c1)
        need = _needed(s.inertia, w[k:k + 1], wdot[k:k + 1])[0]
        nz = 0.5 * (rec["nz_g"][k] + rec["nz_g"][k + 1]) * s.weight if "nz_g" in rec else math.nan
        need = np.array([*need, nz]) / ref
        for c in inert:
            col[:, cols.index(c)] = _inertia_column(s, c, ws[k], wdots[k]) / ref
        for a in range(4 if "nz_g" in rec else 3):
            rows.residual.append(model[a] - need[a])
            rows.columns.append(col[a])
            rows.axis.append(EE_AXES[a])
            rows.group.append(test.id)


def _inertia_column(s: _Start, c: Column, w: np.ndarray, wdot: np.ndarray) -> np.ndarray:
    """The change of the needed moments per relative change of one moment of inertia (minus:
    the residual is model - needed)."""
    _, i = INERTIA_AXES[c.target]
    dJ = np.zeros((3, 3))
    dJ[i, i] = s.inertia[i, i]
    d = _needed(dJ, w[None, :], wdot[None, :])[0]
    return -np.array([d[0], d[1], d[2], 0.0])


def _column(sim, s: _Start, c: Column, base: np.ndarray, ref: np.ndarray) -> np.ndarray:
    """The change of the four rows per unit of the candidate's coefficient at the state JSBSim
    holds (divided by the references; inertia: filled by the caller)."""
    fdm = sim.fdm
    if c.kind == "inertia":
        return np.zeros(4)
    if c.kind == "term":
        out = np.zeros(4)
        if c.term.axis in EE_AXES:
            out[EE_AXES.index(c.term.axis)] = fdm[f"aero/effects/synth_{c.term.name}-{AXES[c.term.axis].unit}"] / TERM_PROBE
        return out / ref
    x0 = fdm[c.property]
    fdm[c.property] = x0 + c.step
    fdm.run_ic()
    moved = np.array([fdm[p] for p in TOTALS])
    fdm[c.property] = x0
    d = (moved - base) / c.step
    return np.array([d[0], d[1], d[2], -d[3]]) / ref


def _probe(sim: Simulator, cols: Sequence[Column], effects: Mapping[str, Effect]) -> Simulator:
    """A copy with every candidate term (at :data:`TERM_PROBE`) and library effect (neutral) added."""
    probe = sim.clone()
    try:
        terms = [c.term for c in cols if c.kind == "term"]
        if terms:
            probe.add_effect(probe_effect(terms), {t.factor_property: TERM_PROBE for t in terms})
        for name in dict.fromkeys(c.target for c in cols if c.kind == "effect"):
            probe.add_effect(effects[name])
    except BaseException:
        probe.close()
        raise
    return probe


def axis_noise(residual: np.ndarray, axis: np.ndarray, group: np.ndarray) -> dict[str, float]:
    """Each axis's noise from the second differences of its rows within each maneuver (median
    absolute value: the corners of the inputs stay out), at least 1e-6."""
    out = {}
    for a in dict.fromkeys(axis):
        d2 = np.concatenate([np.diff(residual[(axis == a) & (group == g)], 2) for g in dict.fromkeys(group)]
                            or [np.zeros(0)])
        out[a] = max(1e-6, 1.4826 * float(np.median(np.abs(d2))) / math.sqrt(6.0)) if d2.size else 1.0
    return out


def _demeaned(r: np.ndarray, S: np.ndarray, axis: np.ndarray, group: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rows and columns less their mean over each maneuver and axis: the replay trims the model
    at the start, so a constant moment is the trim's, not a candidate's (and the first sample
    of a maneuver whose pilot acted before it is not the trim: its offset goes too)."""
    r, S = r.copy(), S.copy()
    for g in dict.fromkeys(group):
        for a in dict.fromkeys(axis):
            m = (group == g) & (axis == a)
            if np.any(m):
                n = int(np.sum(m))
                r[m] -= math.fsum(r[m]) / n          # correctly rounded: the same bits on every CPU
                S[m] -= np.array([math.fsum(c) for c in S[m].T]) / n
    return r, S


def equation_error(sim: Simulator, tests: Sequence, cols: Sequence[Column],
                   effects: Mapping[str, Effect] | None = None) -> Linearization:
    """The equation error of every usable sample of ``tests`` (module doc) and its columns."""
    rows, notes = _Rows(), []
    with _probe(sim, cols, effects or {}) as probe:
        for test in tests:
            _maneuver(probe, test, cols, rows, notes)
    r = np.array(rows.residual)
    axis, group = np.array(rows.axis, dtype=object), np.array(rows.group, dtype=object)
    S = np.array(rows.columns) if rows.columns else np.zeros((0, len(cols)))
    r, S = _demeaned(r, S, axis, group)
    noise = axis_noise(r, axis, group) if r.size else {}
    return Linearization(tuple(cols), r, S, np.array([1.0 / noise[a] for a in axis]), tuple(group), tuple(axis),
                         tuple(notes))


# --------------------------------------------------------------------------- ranking
@dataclass(frozen=True)
class Ranked:
    """One candidate (the columns of one target) scored alone on the equation error."""

    kind: str
    target: str
    columns: tuple[str, ...]
    estimate: tuple[float, ...]      # least-squares coefficients
    explained: float                 # weighted chi-square explained
    share: float                     # of the chi-square of the axes it acts on
    axes: tuple[str, ...]            # the axes its columns move

    def as_dict(self) -> dict:
        return {"kind": self.kind, "target": self.target, "estimate": list(self.estimate),
                "explained_chi2": self.explained, "share": self.share, "axes": list(self.axes)}


def _weighted(lin: Linearization) -> tuple[np.ndarray, np.ndarray]:
    return lin.sensitivity * lin.weight[:, None], -lin.residual * lin.weight


def explained_rows(lin: Linearization, columns: Sequence[str], coefficients: Sequence[float]) -> tuple[np.ndarray, np.ndarray]:
    """The rows some columns move (by their term names): what the columns at these
    coefficients predict of the weighted residual (x) and the weighted residual, data less
    model (y). Columns that explain the residual put the points on y = x."""
    names = [t.name for t in lin.terms]
    A, y = _weighted(lin)
    X = A[:, [names.index(c) for c in columns]]
    rows = np.any(np.abs(X) > 0, axis=1)
    return numerics.matvec(X[rows], np.asarray(coefficients, float)), y[rows]


def rank(lin: Linearization) -> list[Ranked]:
    """Every target's columns fitted alone (least squares on the weighted rows): the chi-square
    each explains, strongest first (ties: the order of the columns)."""
    A, y = _weighted(lin)
    metric = np.array(lin.metric, dtype=object)
    targets: dict[tuple[str, str], list[int]] = {}
    for j, c in enumerate(lin.terms):
        targets.setdefault((c.kind, c.target), []).append(j)
    out = []
    for (kind, target), idx in targets.items():
        X = A[:, idx]
        moved = tuple(a for a in EE_AXES if np.any(np.abs(X[metric == a]) > 0))
        if not moved:
            continue
        G = numerics.gram(X)
        b = numerics.matvec(X.T, y)
        try:
            coef = numerics.solve(G + 1e-12 * np.trace(G) * np.eye(len(idx)), b)
        except numerics.SingularMatrixError:
            continue
        explained = float(numerics.dot(coef, b))
        own = sum(numerics.sum_sq(y[metric == a]) for a in moved)
        out.append(Ranked(kind, target, tuple(lin.terms[j].name for j in idx), tuple(float(x) for x in coef),
                          explained, explained / own if own > 0 else 0.0, moved))
    return sorted(out, key=lambda r: -r.explained)
