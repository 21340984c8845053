"""FAA 14 CFR Part 60 Level 5 FTD objective tests as data, and the flight-test summaries of them.

The catalogue (:data:`CATALOGUE`) follows the method's Appendix A (Level 5 tests, with the
adaptions the method states for a simulator without control loading) plus the tests the
flight-test package adds beyond Level 5 (flaps-down climbs; the Level 6/7 control-input
checks 2.b.1-2.b.6 with the method's +-20 % of peak rate). Each entry names its Part 60 id,
title, metrics with tolerances, the channel its time-history plot shows and, for tests this
model cannot do, the reason.

Tolerances (:class:`Tolerance`): absolute (in the metric's unit) and/or relative (share of the
flight-test value); where Part 60 gives two values joined by "or", the less restrictive one
applies. An acceptance range (FAA alternative data, engine response 2-4 s) applies where there
is no flight-test value. Non-numeric tolerances: ``trend`` (correct trend: not opposite signs
with either value beyond the tolerance's neutral band; a neutral value on the same side as a
signed one is the same trend), ``ctm`` (correct trend and magnitude: a wrong trend
fails, the magnitude is the evaluator's), ``representative`` (the evaluator's), ``info``
(shown, not judged). :func:`judge` turns a flight-test and a model value into a
:class:`MetricVerdict`: no flight-test value is n/a, a model value that is not a number (NaN:
no trim, no oscillation found) is a FAIL, never a PASS.

The summary file (``c172_flight_test_results.csv``) holds static tests too: climbs (1.c.1,
flaps-down), longitudinal trims (2.c.5) and the engine (1.f.1/1.f.2). :func:`load_static_cases`
pairs each result row ``C.n`` with the snapshot row ``C.(n-1)`` that holds its initial
condition and states how the model is trimmed there (:class:`StaticCase`); the dynamic rows
are :mod:`.dynamic_tests`'.
"""
from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from ..core.errors import DataError, Problem
from ..flight.condition import Condition
from .dynamic_tests import ENGINE_ASSUMPTIONS, ENGINE_CONDITION, RESULT_COLUMNS, range_value, read_results
from .schemas import read_csv_checked

PASS, FAIL, NA = "PASS", "FAIL", "n/a"
JUDGED = ("", "range", "trend", "ctm", "representative", "info")


# --------------------------------------------------------------------------- tolerances
@dataclass(frozen=True)
class Tolerance:
    """A Part 60 tolerance (see the module doc). ``judged`` "" is numeric (absolute and/or
    relative; with ``lo_hi``, the acceptance range that applies without a flight-test value),
    "range" an acceptance range ``lo_hi`` only."""

    absolute: float | None = None
    relative: float | None = None          # share of the flight-test value
    unit: str = ""
    judged: str = ""
    lo_hi: tuple[float, float] | None = None

    def __post_init__(self):
        if self.judged not in JUDGED:
            raise ValueError(f"tolerance kind {self.judged!r} is not one of {JUDGED}")
        if self.judged == "" and self.absolute is None and self.relative is None:
            raise ValueError("a numeric tolerance needs an absolute or a relative value")
        if self.judged == "range" and self.lo_hi is None:
            raise ValueError("a range tolerance needs lo_hi")

    def band(self, reference: float) -> float:
        """Half-width of the band around ``reference`` (the less restrictive of the two)."""
        parts = [self.absolute or 0.0, (self.relative or 0.0) * abs(reference)]
        return max(parts) if self.judged == "" else math.nan

    def text(self) -> str:
        if self.judged == "range":
            return f"{self.lo_hi[0]:g} to {self.lo_hi[1]:g} {self.unit} (alternative data)"
        if self.lo_hi is not None:
            return (f"+-{self.absolute:g} {self.unit} (no flight data: {self.lo_hi[0]:g} to {self.lo_hi[1]:g} "
                    f"{self.unit}, alternative data)")
        if self.judged == "trend" and self.absolute:
            return f"correct trend (neutral within +-{self.absolute:g} {self.unit})"
        if self.judged:
            return {"trend": "correct trend", "ctm": "correct trend and magnitude",
                    "representative": "representative", "info": "none (information)"}[self.judged]
        parts = []
        if self.absolute is not None:
            parts.append(f"+-{self.absolute:g} {self.unit}".rstrip())
        if self.relative is not None:
            parts.append(f"+-{self.relative * 100:g} %")
        return " or ".join(parts)


def tol(absolute=None, relative=None, unit="") -> Tolerance:
    return Tolerance(absolute, relative, unit)


TREND, CTM, REPRESENTATIVE, INFO = (Tolerance(judged=k) for k in ("trend", "ctm", "representative", "info"))


@dataclass(frozen=True)
class MetricSpec:
    """A compared quantity of a test: key, label, unit, tolerance."""

    name: str
    label: str
    unit: str
    tolerance: Tolerance


@dataclass(frozen=True)
class Part60Test:
    """One objective test: Part 60 id, title, level, flight conditions, metrics, the channel of
    its time-history plot, and ``not_possible``: why this model cannot do it ("" = it can)."""

    id: str
    title: str
    level: str                       # "5" | "6/7 (supplemental)" | "supplemental"
    conditions: str
    metrics: tuple[MetricSpec, ...]
    channel: str | None = None
    not_possible: str = ""
    note: str = ""                   # the adaption the method states
    match: tuple[str, ...] = ()      # title prefixes of result rows and time histories that belong here

    def metric(self, name: str) -> MetricSpec | None:
        return next((m for m in self.metrics if m.name == name), None)


NO_LOADING = "no control loading: the model has no cockpit controls, forces or reversible controls"
GROUND = "a ground test: the workbench trims and flies the aircraft airborne only (terrain far below)"

_M = MetricSpec
CLIMB_METRICS = (_M("ktas", "airspeed", "kt", tol(3.0, unit="kt")),
                 _M("vs_fpm", "vertical speed", "ft/min", tol(100.0, 0.05, "ft/min")))
ENGINE_METRICS = (_M("t_i_s", "T_i: throttle movement to 10 % of the response", "s", tol(1.0, unit="s")),
                  _M("t_t_s", "T_t: throttle movement to 90 % of the response", "s", tol(1.0, unit="s")),
                  _M("response_time_s", "response time, 10 % to 90 % (T_t - T_i)", "s",
                     Tolerance(1.0, unit="s", lo_hi=(2.0, 4.0))))
SURFACE_CAL = "surface position calibration (Level 6/7 part, used in lieu of forces)"

CATALOGUE: tuple[Part60Test, ...] = (
    Part60Test("1.c.1", "Normal climb, all engines operating", "5", "clean, nominal climb speed", CLIMB_METRICS,
               "vs_fpm", note="snapshot results are acceptable for Level 5", match=("1.c.1",)),
    Part60Test("supp. flaps climb", "Flaps-down climb (supplemental)", "supplemental", "flaps 10, full throttle",
               CLIMB_METRICS, "vs_fpm", note="not a Part 60 test; the flight-test package's supplemental climbs",
               match=("Flaps Down Climb",)),
    Part60Test("1.f.1", "Engine acceleration", "5", "approach or landing", ENGINE_METRICS, "rpm",
               note="FAA alternative data for a small single-engine reciprocating airplane: response time 2-4 s",
               match=("1.f.1",)),
    Part60Test("1.f.2", "Engine deceleration", "5", "on ground", ENGINE_METRICS, "rpm",
               not_possible=GROUND + "; a ground run at take-off power with the brakes set is not modelled",
               match=("1.f.2",)),
    Part60Test("2.a.1", "Pitch controller position vs force and surface position calibration", "5", "on ground",
               (_M("elevator_deg", SURFACE_CAL, "deg", tol(2.0, unit="deg")),), None,
               not_possible=f"{NO_LOADING}; the control-to-surface map is the data's own control-travel table "
                            "(checked as data consistency, +-2 deg, when snapshots are loaded)",
               match=("2.a.1",)),
    Part60Test("2.a.2", "Roll controller position vs force and surface position calibration", "5", "on ground",
               (_M("aileron_deg", SURFACE_CAL, "deg", tol(2.0, unit="deg")),), None,
               not_possible=f"{NO_LOADING}; see 2.a.1", match=("2.a.2",)),
    Part60Test("2.a.3", "Rudder pedal position vs force and surface position calibration", "5", "on ground",
               (_M("rudder_deg", SURFACE_CAL, "deg", tol(2.0, unit="deg")),), None,
               not_possible=f"{NO_LOADING}; see 2.a.1", match=("2.a.3",)),
    Part60Test("2.b.1/2.b.4", "Pitch control / small control inputs - pitch", "6/7 (supplemental)",
               "cruise, take-off", (_M("max_pitch_rate_deg_s", "peak pitch rate after the pulse", "deg/s",
                                      tol(relative=0.20, unit="deg/s")),), "q_deg_s",
               note="free response is not possible without reversible controls; +-20 % of the peak body rate "
                    "(the method's tolerance)", match=("2.b.1", "2.b.4")),
    Part60Test("2.b.2/2.b.5", "Roll control / small control inputs - roll", "6/7 (supplemental)", "cruise, take-off",
               (_M("max_roll_rate_deg_s", "peak roll rate after the pulse", "deg/s",
                   tol(relative=0.20, unit="deg/s")),), "p_deg_s", note="see 2.b.1/2.b.4",
               match=("2.b.2", "2.b.5")),
    Part60Test("2.b.3/2.b.6", "Yaw control / small control inputs - yaw", "6/7 (supplemental)", "cruise, take-off",
               (_M("max_yaw_rate_deg_s", "peak yaw rate after the pulse", "deg/s",
                   tol(relative=0.20, unit="deg/s")),), "r_deg_s", note="see 2.b.1/2.b.4",
               match=("2.b.3", "2.b.6")),
    Part60Test("2.c.1.b", "Power change force", "5", "approach",
               (_M("elevator_change_deg", "elevator change holding altitude after the power change", "deg", CTM),
                _M("pitch_change_deg", "pitch change after the power change", "deg", CTM)), "elevator_deg",
               note=f"{NO_LOADING}: correct trend and magnitude of the elevator needed to hold altitude",
               match=("2.c.1",)),
    Part60Test("2.c.2.b", "Flap change force", "5", "take-off through initial flap retraction; approach",
               (_M("elevator_change_deg", "elevator change after the flap change", "deg", CTM),
                _M("pitch_change_deg", "pitch change after the flap change", "deg", CTM)), "pitch_deg",
               note=f"{NO_LOADING}: correct trend and magnitude of the pitch response", match=("2.c.2",)),
    Part60Test("2.c.4.b", "Gear change force", "5", "take-off, approach", (), None,
               not_possible="fixed landing gear: there is no gear change", match=("2.c.4",)),
    Part60Test("2.c.5", "Longitudinal trim", "5", "cruise, approach, landing",
               (_M("elevator_deg", "elevator (data sign, + trailing edge up)", "deg", tol(1.0, unit="deg")),
                _M("pitch_deg", "pitch attitude", "deg", tol(1.0, unit="deg")),
                _M("pct_power", "power (percent of rated)", "% rated", tol(5.0, unit="points")),
                _M("rpm", "engine speed (the data call it unreliable)", "rpm", INFO)), "elevator_deg",
               note="the +-0.5 deg trim-surface tolerance does not apply: the trim tab is not modelled",
               match=("2.c.5",)),
    Part60Test("2.c.6", "Longitudinal maneuvering stability (stick force/g)", "6/7 (supplemental)", "cruise",
               (_M("elevator_deg", "steady elevator in the banked turn (data sign)", "deg", tol(1.0, 0.10, "deg")),
                _M("nz_g", "steady load factor", "g", INFO)), "elevator_deg",
               note=f"not a Level 5 test; {NO_LOADING}: the alternative method on the elevator angle",
               match=("2.c.6",)),
    Part60Test("2.c.7", "Longitudinal static stability", "5", "approach",
               (_M("elevator_change_deg", "elevator change between the speeds", "deg", tol(1.0, 0.10, "deg")),
                _M("speed_change_kt", "speed change reached", "kt", INFO)), "kcas",
               note=f"{NO_LOADING}: the alternative method (+-1 deg or +-10 % of the change of elevator angle)",
               match=("2.c.7",)),
    Part60Test("2.c.8.b", "Stall warning (actuation of stall warning device)", "5",
               "second-segment climb, approach or landing", (), None,
               not_possible="no stall warning system is modelled", match=("2.c.8",)),
    Part60Test("2.c.9.b", "Phugoid dynamics", "5", "cruise",
               (_M("phugoid_period_s", "period", "s", tol(relative=0.10, unit="s")),
                _M("phugoid_damping", "damping ratio", "-", REPRESENTATIVE)), "kcas",
               note="stick fixed after the release: true free response needs reversible controls",
               match=("2.c.9",)),
    Part60Test("2.d.2", "Roll response (rate)", "5", "cruise, approach or landing",
               (_M("roll_rate_deg_s", "steady roll rate after the wheel step", "deg/s", tol(2.0, 0.10, "deg/s")),),
               "p_deg_s", match=("2.d.2",)),
    Part60Test("2.d.4", "Spiral stability", "5", "cruise",
               (_M("spiral_roll_change_deg", "change of the bank magnitude after the release", "deg",
                   Tolerance(1.0, unit="deg", judged="trend")),
                _M("turn_aileron_deg", "aileron held in the steady turn (alternate method)", "deg",
                   tol(2.0, unit="deg"))), "roll_deg",
               note="correct trend, and the alternate method's +-2 deg aileron (Level 7 tolerance)",
               match=("2.d.4",)),
    Part60Test("2.d.6.a/b", "Rudder response", "5", "approach or landing",
               (_M("max_yaw_rate_deg_s", "peak yaw rate change", "deg/s", tol(2.0, 0.10, "deg/s")),
                _M("max_roll_rate_deg_s", "peak roll rate change", "deg/s", tol(2.0, unit="deg/s")),
                _M("bank_change_deg", "bank change at the end", "deg", tol(3.0, unit="deg"))), "r_deg_s",
               note="Level 6/7 roll-rate and bank tolerances adopted", match=("2.d.6",)),
    Part60Test("2.d.7", "Dutch roll (yaw damper off)", "6/7 (supplemental)", "cruise, approach or landing",
               (_M("dutch_roll_period_s", "period", "s", tol(0.5, 0.10, "s")),
                _M("dutch_roll_damping", "damping ratio", "-", tol(0.02, unit=""))), "r_deg_s",
               note="not a Level 5 test; Level 6/7 tolerances (period +-0.5 s or +-10 %, damping ratio +-0.02)",
               match=("2.d.7",)),
    Part60Test("2.d.8", "Steady state sideslip", "5", "approach or landing",
               (_M("sideslip_deg", "steady sideslip", "deg", tol(1.0, unit="deg")),
                _M("roll_deg", "steady bank", "deg", tol(2.0, unit="deg")),
                _M("aileron_deg", "steady aileron (data sign)", "deg", tol(2.0, 0.10, "deg"))), "beta_deg",
               note="roll controller position or force: not applicable (no cockpit controls)", match=("2.d.8",)),
)
CATALOGUE_BY_ID = {t.id: t for t in CATALOGUE}

# the time-history channel each metric is measured on (its plot's tolerance band)
METRIC_CHANNEL = {
    "ktas": "ktas", "vs_fpm": "vs_fpm", "t_i_s": "rpm", "t_t_s": "rpm", "response_time_s": "rpm",
    "max_pitch_rate_deg_s": "q_deg_s", "max_roll_rate_deg_s": "p_deg_s", "max_yaw_rate_deg_s": "r_deg_s",
    "elevator_change_deg": "elevator_deg", "pitch_change_deg": "pitch_deg", "elevator_deg": "elevator_deg",
    "pitch_deg": "pitch_deg", "rpm": "rpm", "speed_change_kt": "kcas", "phugoid_period_s": "kcas",
    "phugoid_damping": "kcas", "roll_rate_deg_s": "p_deg_s", "spiral_roll_change_deg": "roll_deg",
    "turn_aileron_deg": "aileron_deg", "bank_change_deg": "roll_deg", "sideslip_deg": "beta_deg",
    "roll_deg": "roll_deg", "aileron_deg": "aileron_deg", "dutch_roll_period_s": "r_deg_s",
    "dutch_roll_damping": "r_deg_s", "nz_g": "nz_g",
}
# the control each test's procedure moves (its start is the time the metrics count from)
INPUT_CHANNEL = {
    "1.c.1": None, "supp. flaps climb": None, "1.f.1": "throttle_norm", "1.f.2": "throttle_norm",
    "2.b.1/2.b.4": "elevator_deg", "2.b.2/2.b.5": "aileron_deg", "2.b.3/2.b.6": "rudder_deg",
    "2.c.1.b": "throttle_norm", "2.c.2.b": "flaps_deg", "2.c.5": None, "2.c.6": None, "2.c.7": "elevator_deg",
    "2.c.9.b": "elevator_deg", "2.d.2": "aileron_deg", "2.d.4": "aileron_deg", "2.d.6.a/b": "rudder_deg",
    "2.d.7": "rudder_deg", "2.d.8": "rudder_deg",
}
_PART60_ID = re.compile(r"^\s*(\d\.[a-z]\.\d+)")


def catalogue_test(title_or_id: str) -> Part60Test | None:
    """The catalogue entry a result row's title, a time history's ``part60`` field or a test
    id belongs to (by id, else by the leading Part 60 id, else by title prefix)."""
    text = str(title_or_id).strip()
    if text in CATALOGUE_BY_ID:
        return CATALOGUE_BY_ID[text]
    m = _PART60_ID.match(text)
    key = m.group(1) if m else None
    for t in CATALOGUE:
        if any((key and key == p) or text.lower().startswith(p.lower()) for p in t.match):
            return t
    return None


# --------------------------------------------------------------------------- verdicts
@dataclass(frozen=True)
class MetricVerdict:
    """One metric of one case: flight test, model, error (model - flight test), tolerance and
    verdict (PASS / FAIL / n/a with the reason)."""

    name: str
    label: str
    unit: str
    flight_test: float
    model: float
    error: float
    tolerance: str
    verdict: str
    reason: str = ""
    flight_test_text: str = ""


def _finite(x) -> bool:
    return isinstance(x, (int, float, np.number)) and math.isfinite(float(x))


def trend_of(x: float, neutral: float | None) -> str:
    """'+', '-' or 'neutral' (within +-``neutral`` of zero; exactly zero without a band)."""
    band = neutral or 0.0
    return "neutral" if abs(x) <= band else ("+" if x > 0 else "-")


def same_trend(ref: float, model: float, neutral: float | None) -> bool:
    """Both neutral, or the same sign: a value within the neutral band (:func:`trend_of`) still
    leans to its side, so a neutral flight test and a mildly signed model on the same side
    agree, and on the other side disagree (an exact zero has no side)."""
    both_neutral = trend_of(ref, neutral) == trend_of(model, neutral) == "neutral"
    return both_neutral or np.sign(ref) == np.sign(model)


def _alternative(t: Tolerance, ref: float) -> bool:
    """Judged on the acceptance range: a range tolerance, or no flight-test value and a range
    of alternative data."""
    return t.judged == "range" or (t.lo_hi is not None and not _finite(ref))


def _judge_value(t: Tolerance, ref: float, model: float) -> tuple[float, str, str]:
    """(error, verdict, reason) of a finite model value."""
    if _alternative(t, ref):
        lo, hi = t.lo_hi
        err = 0.0 if lo <= model <= hi else (model - lo if model < lo else model - hi)
        return err, PASS if err == 0.0 else FAIL, "" if err == 0.0 else f"outside {lo:g}-{hi:g} {t.unit}"
    err = model - ref
    if t.judged == "":
        ok = abs(err) <= t.band(ref) + 1e-9
        return err, PASS if ok else FAIL, "" if ok else f"outside +-{t.band(ref):.3g} {t.unit}".rstrip()
    if t.judged in ("trend", "ctm") and not same_trend(ref, model, t.absolute):
        return err, FAIL, f"wrong trend ({trend_of(model, t.absolute)}, flight test {trend_of(ref, t.absolute)})"
    if t.judged == "trend":
        return err, PASS, ""
    if t.judged == "ctm":
        return err, NA, "trend correct; the magnitude is the evaluator's (CT&M)"
    return err, NA, "judged by the evaluator (representative)"


def judge(spec: MetricSpec, flight_test: float, model: float, flight_test_text: str = "") -> MetricVerdict:
    """A metric's verdict. A model value that is not a finite number never passes."""
    t = spec.tolerance
    if t.judged == "info":
        err = model - flight_test if _finite(model) and _finite(flight_test) else math.nan
        return MetricVerdict(spec.name, spec.label, spec.unit, flight_test, model, err, t.text(), NA,
                             "information only (no tolerance)", flight_test_text)
    if not _alternative(t, flight_test) and not _finite(flight_test):
        return MetricVerdict(spec.name, spec.label, spec.unit, math.nan, model, math.nan, t.text(), NA,
                             "no flight-test value: not recorded or not measurable", flight_test_text)
    if not _finite(model):
        return MetricVerdict(spec.name, spec.label, spec.unit, flight_test, math.nan, math.nan, t.text(),
                             FAIL if t.judged in ("", "range", "trend", "ctm") else NA,
                             "no model value (NaN)", flight_test_text)
    err, verdict, reason = _judge_value(t, flight_test, float(model))
    return MetricVerdict(spec.name, spec.label, spec.unit, flight_test, float(model), err, t.text(), verdict,
                         reason, flight_test_text)


def combine(verdicts: list[str]) -> str:
    """A case's or test's verdict from its parts: any FAIL fails; else any PASS passes; else n/a."""
    if FAIL in verdicts:
        return FAIL
    return PASS if PASS in verdicts else NA


# --------------------------------------------------------------------------- the results file
STATIC_METRICS = {       # results-file metric text -> metric key
    "Airspeed (KTAS)": "ktas", "Vertical Speed (FPM)": "vs_fpm", "Elevator Angle": "elevator_deg",
    "Pitch": "pitch_deg", "Percent Power": "pct_power", "RPM": "rpm", "T_i": "t_i_s", "T_t": "t_t_s",
    "ΔT": "response_time_s",
}
STATIC_KINDS = {"1.c.1": "climb", "supp. flaps climb": "climb", "2.c.5": "trim", "1.f.1": "engine",
                "1.f.2": "engine"}
IC_COLUMNS = ("weight_lb", "cg_in", "flaps_deg", "pressure_alt_ft", "ktas", "vs_fpm", "pitch_deg", "roll_deg",
              "elevator_deg", "aileron_deg", "rudder_deg", "throttle_norm")

@dataclass(frozen=True)
class Reference:
    """A flight-test value as the results file gives it: a number (``650 ± 32``: value and
    scatter), a range (``2 - 4``), or nothing (NaN)."""

    metric: str
    value: float
    text: str
    scatter: float = math.nan
    thesis_model: float = math.nan


@dataclass(frozen=True)
class StaticCase:
    """A static objective test case of the results file: its rows, the snapshot row with its
    initial condition (``initial_values``, data signs) and the trim the model flies there."""

    id: str                          # result row (C.40)
    initial: str                     # snapshot row (C.39) or "" (none)
    test_id: str                     # catalogue id
    title: str
    kind: str                        # climb | trim | engine
    condition: Condition | None
    references: tuple[Reference, ...]
    initial_values: dict = field(default_factory=dict)
    assumptions: tuple[str, ...] = ()
    problem: str = ""                # why the case cannot be flown ("" = it can)


def parse_reference(metric: str, text) -> Reference:
    """'650 ± 32' -> 650 (scatter 32); '82%' -> 82; a range '2 - 4' or '' -> NaN (the text kept)."""
    t = "" if text is None else str(text).strip()
    if not t or t.lower() == "nan" or math.isfinite(range_value(t)[0]):
        return Reference(metric, math.nan, "" if t.lower() == "nan" else t)
    parts = t.replace("%", "").split("±")
    try:
        value = float(parts[0])
        scatter = float(parts[1]) if len(parts) > 1 else math.nan
    except ValueError:
        return Reference(metric, math.nan, t)
    return Reference(metric, value, t, scatter)


def _number(text) -> float:
    return parse_reference("", text).value


def initial_id(result_id: str) -> str:
    prefix, _, n = result_id.rpartition(".")
    return f"{prefix}.{int(n) - 1}" if n.isdigit() else ""


def _ic_values(row: pd.Series | None) -> dict[str, float]:
    if row is None:
        return {}
    vals = {c: pd.to_numeric(row.get(c), errors="coerce") for c in IC_COLUMNS}
    return {k: float(v) for k, v in vals.items() if v is not None and np.isfinite(v)}


def _condition(kind: str, ic: dict[str, float]) -> tuple[Condition | None, tuple[str, ...], str]:
    """The trim of a static case: (condition, assumptions, problem)."""
    if kind == "engine":
        return ENGINE_CONDITION, ENGINE_ASSUMPTIONS, ""
    need = ("weight_lb", "cg_in", "flaps_deg", "pressure_alt_ft", "ktas") + (("vs_fpm",) if kind == "trim" else ())
    missing = [c for c in need if c not in ic]
    if missing:
        return None, (), f"the initial condition lacks {', '.join(missing)}"
    common = dict(pressure_alt_ft=ic["pressure_alt_ft"], weight_lb=ic["weight_lb"], ktas=ic["ktas"],
                  cg_in=ic["cg_in"], flaps_deg=ic["flaps_deg"])
    if kind == "climb":
        return Condition(**common, mode="full_throttle", throttle=1.0, mixture="climb"), (
            "trimmed at full throttle, full rich, ISA, wings level at the initial condition's weight, CG, flaps, "
            "pressure altitude and true airspeed: the airspeed is the trim's (equal by construction)",
            "the flight-test vertical speed is the mean over the climb (at least 1,000 ft above the initial "
            "condition); the model's is the rate of climb (dh/dt) at the initial condition's altitude"), ""
    bank = ic.get("roll_deg", 0.0)
    return Condition(**common, vs_fpm=ic["vs_fpm"], bank_deg=bank, turn="coordinated" if bank else "straight",
                     mixture="cruise"), (
        "trimmed at the snapshot's weight, CG, flaps, pressure altitude, true airspeed, vertical speed and bank "
        "(a steady coordinated turn), ISA, best-power mixture, throttle free",), ""


def _static_case(tid: str, rows: list[pd.Series], snaps: dict[str, pd.Series]) -> StaticCase | None:
    title = str(rows[0]["title"]).strip()
    test = catalogue_test(title)
    if test is None or test.id not in STATIC_KINDS:
        return None
    kind = STATIC_KINDS[test.id]
    init = initial_id(tid)
    ic = _ic_values(snaps.get(init))
    refs = tuple(Reference(**{**parse_reference(STATIC_METRICS[str(r["metric"]).strip()], r["flight_test"]).__dict__,
                              "thesis_model": _number(r.get("thesis_model"))}) for r in rows)
    cond, assumptions, problem = _condition(kind, ic)
    if kind == "engine" and test.not_possible:
        cond, assumptions, problem = None, (), test.not_possible
    return StaticCase(tid, init if ic else "", test.id, title, kind, cond, refs, ic, assumptions, problem)


def load_static_cases(results: str | Path, snapshots: str | Path) -> list[StaticCase]:
    """The static objective tests of a results file (climbs, trims, engine), with their
    initial conditions from the snapshot file. Dynamic rows are :mod:`.dynamic_tests`'."""
    res, snaps = read_results(results, snapshots)
    grouped: dict[str, list[pd.Series]] = {}
    for _, r in res.iterrows():
        if str(r["metric"]).strip() in STATIC_METRICS:
            grouped.setdefault(str(r["table"]).strip(), []).append(r)
    cases = [_static_case(tid, rows, snaps) for tid, rows in grouped.items()]
    return [c for c in cases if c is not None]


def snapshot_values(snapshots: str | Path) -> dict[str, dict[str, float]]:
    """Every snapshot row's initial-condition values (data signs), by table id."""
    snap = read_csv_checked(Path(snapshots)).rename(columns=lambda c: c.strip())
    if "table" not in snap:
        raise DataError(snapshots, [Problem("column 'table'", "missing")])
    return {str(r["table"]).strip(): _ic_values(r) for _, r in snap.iterrows()}


# --------------------------------------------------------------------------- flight-test files
@dataclass
class FlightTestFiles:
    """What a ``--flight-test`` argument holds, by kind (files recognised from their columns)."""

    results: Path | None = None
    snapshots: Path | None = None
    travel: Path | None = None
    time_histories: list[Path] = field(default_factory=list)     # CSVs with a JSON sidecar
    ignored: list[str] = field(default_factory=list)             # "file: why"


def _csv_kind(path: Path) -> str | None:
    if path.with_suffix(".json").is_file():
        return "time_history"
    try:
        cols = {c.strip() for c in pd.read_csv(path, nrows=0).columns}
    except (pd.errors.ParserError, UnicodeDecodeError, pd.errors.EmptyDataError, OSError):
        return None
    if set(RESULT_COLUMNS) <= cols:
        return "results"
    if {"table", "vs_fpm", "pitch_deg", "ktas"} <= cols:
        return "snapshots"
    if {"axis", "cockpit_control", "surface_min_deg"} <= cols:
        return "travel"
    return None


def classify_files(paths: list[str | Path]) -> FlightTestFiles:
    """Sort files and folders (not recursive) into results, snapshots, control travel and time
    histories; anything else is listed as ignored. Two files of one summary kind: an error."""
    out = FlightTestFiles()
    files: list[Path] = []
    problems = []
    for p in map(Path, paths):
        if p.is_dir():
            files += sorted(q for q in p.iterdir() if q.suffix.lower() == ".csv")
        elif p.is_file():
            files.append(p)
        else:
            problems.append(Problem(str(p), "no such file or folder"))
    for f in files:
        kind = _csv_kind(f) if f.suffix.lower() == ".csv" else None
        if kind == "time_history":
            out.time_histories.append(f)
        elif kind is None:
            out.ignored.append(f"{f.name}: not a flight-test results, snapshot, control-travel or time-history file")
        elif getattr(out, kind) is not None:
            problems.append(Problem(str(f), f"a second {kind} file (first: {getattr(out, kind)})"))
        else:
            setattr(out, kind, f)
    if problems:
        raise DataError("--flight-test", problems)
    return out
