"""Physics checks of a calibrated model: trends the fits never targeted, judged by first principles.

* Climb rate against weight: the model's d(ROC)/dW (central difference of full-throttle climb
  trims at POH climb conditions) against the classic estimate for a climb at fixed speed and
  thrust, d(ROC)/dW = -ROC/W - 2 D_i V / W^2, with the lift-dependent drag D_i = k CL^2 q S from
  the model's own drag polar (dD/dW = 2 k CL = 2 D_i / W); and against the POH's own trend
  where the POH data give more than one weight.
* Drag polar: level-flight trims from the POH climb speed to the top cruise speed (5,000 ft,
  ISA, flaps up); CD = CD0 + k CL^2 fitted over them gives the Oswald efficiency
  e = 1 / (pi AR k); the local e between neighbouring speeds shows how it changes with CL; the
  wing's induced-drag table alone gives a span efficiency CL_w^2 / (pi AR CDi_w).
* Propeller efficiency: eta = T V / P at every POH climb and cruise trim, against the advance
  ratio J = V / (n D) and altitude; the table's eta(J) = J CT / CP (fixed pitch; a
  constant-speed propeller at its median cruise blade angle), its peak and where it lies.

Runs JSBSim trims only; changes nothing.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Callable, Sequence

import numpy as np

from ..core.units import FT, KT
from ..data.schemas import Dataset
from ..factors import FactorSet
from ..flight.condition import Condition, TrimResult
from ..jsbsim.probes import AeroReading
from ..jsbsim.product import AircraftPaths, propeller_tables
from ..jsbsim.simulator import Simulator
from ..physics.atmosphere import isa_temperature
from ..physics.propeller import PropellerTables
from .evaluate import KINDS

WEIGHT_STEP_LB = 50.0            # central difference of the climb rate in weight
POLAR_ALT_FT = 5000.0            # drag polar: level flight here, ISA, flaps up
POLAR_SPEEDS = 8                 # trims from the POH climb speed to the top cruise speed
FPM_PER_FPS = 60.0
HP_FTLBF_S = 550.0
CRUISE_J_MARGIN = 0.05           # the propeller's peak may lie this far outside the cruise J range
# expected ranges (general-aviation singles; the sanity bounds)
OSWALD_RANGE = (0.6, 0.9)
PROPELLER_PEAK_RANGE = (0.75, 0.88)
WEIGHT_RATIO_RANGE = (0.7, 1.3)  # model / classic d(ROC)/dW


# --------------------------------------------------------------------------- results
@dataclass(frozen=True)
class PolarPoint:
    ktas: float                   # [kt]
    cl: float                     # [-] whole aircraft, stability axes (aerodynamic forces only)
    cd: float                     # [-]
    cl_wing: float                # [-] aero/wing/CL
    cdi_wing: float               # [-] aero/wing/CDi (the wing's induced-drag table)
    wing_span_efficiency: float   # [-] cl_wing^2 / (pi AR cdi_wing)


@dataclass(frozen=True)
class DragPolar:
    pressure_alt_ft: float        # [ft]
    weight_lb: float              # [lb]
    aspect_ratio: float           # [-] b^2 / S
    points: tuple[PolarPoint, ...]
    cd0: float                    # [-] CD = cd0 + k CL^2 over the points
    k: float                      # [-]
    oswald_efficiency: float      # [-] 1 / (pi AR k)

    def local_oswald(self) -> list[tuple[float, float]]:
        """(mean CL, e) between neighbouring speeds: e = 1 / (pi AR dCD/dCL^2)."""
        out = []
        pts = sorted(self.points, key=lambda p: p.cl)
        for a, b in zip(pts, pts[1:]):
            slope = (b.cd - a.cd) / (b.cl ** 2 - a.cl ** 2)
            out.append((0.5 * (a.cl + b.cl), 1.0 / (math.pi * self.aspect_ratio * slope) if slope > 0 else math.nan))
        return out


@dataclass(frozen=True)
class WeightSensitivity:
    pressure_alt_ft: float                 # [ft]
    temperature_c: float                   # [deg C]
    kcas: float                            # [kt]
    weight_lb: float                       # [lb]
    roc_fpm: float                         # [ft/min] the model at weight_lb
    cl: float                              # [-] the climb's lift coefficient
    lift_dependent_drag_lbf: float         # [lbf] k CL^2 q S (the model's polar)
    model_droc_dw_fpm_per_lb: float        # [ft/min per lb] central difference of trims
    classic_droc_dw_fpm_per_lb: float      # [ft/min per lb] -ROC/W - 2 D_i V / W^2

    @property
    def ratio(self) -> float:
        return self.model_droc_dw_fpm_per_lb / self.classic_droc_dw_fpm_per_lb


@dataclass(frozen=True)
class PropellerPoint:
    kind: str                     # climb | cruise (the POH point it is trimmed at)
    pressure_alt_ft: float        # [ft]
    ktas: float                   # [kt]
    rpm: float                    # [rpm]
    advance_ratio: float          # [-] V / (n D)
    efficiency: float             # [-] T V / P
    blade_angle_deg: float        # [deg] constant speed; NaN fixed pitch


@dataclass(frozen=True)
class PropellerCheck:
    points: tuple[PropellerPoint, ...]
    curve_advance_ratio: tuple[float, ...]    # [-] the table's breakpoints
    curve_efficiency: tuple[float, ...]       # [-] J CT / CP there (NaN where CT or CP <= 0)
    blade_angle_deg: float                    # [deg] the curve's blade angle (NaN: fixed pitch)
    peak_efficiency: float                    # [-]
    peak_advance_ratio: float                 # [-]
    neutral_peak_efficiency: float            # [-] the same curve of the uncalibrated (BEM) tables
    neutral_peak_advance_ratio: float         # [-]

    def cruise_range(self) -> tuple[float, float]:
        j = [p.advance_ratio for p in self.points if p.kind == "cruise" and math.isfinite(p.advance_ratio)]
        return (min(j), max(j)) if j else (math.nan, math.nan)

    @property
    def peak_in_cruise_range(self) -> bool:
        lo, hi = self.cruise_range()
        return bool(lo - CRUISE_J_MARGIN <= self.peak_advance_ratio <= hi + CRUISE_J_MARGIN)

    def by_altitude(self) -> list[tuple[str, float, float, float, int]]:
        """(kind, pressure altitude, mean J, mean efficiency, points) per kind and altitude."""
        groups: dict[tuple[str, float], list[PropellerPoint]] = {}
        for p in self.points:
            groups.setdefault((p.kind, p.pressure_alt_ft), []).append(p)
        return [(k, a, float(np.mean([p.advance_ratio for p in ps])), float(np.mean([p.efficiency for p in ps])),
                 len(ps)) for (k, a), ps in sorted(groups.items())]


@dataclass(frozen=True)
class Check:
    name: str
    value: str
    expected: str
    ok: bool


@dataclass
class PhysicsChecks:
    aircraft: str
    model: str
    weight: list[WeightSensitivity]
    poh_weights_lb: tuple[float, ...]             # distinct weights of the POH climb data
    poh_droc_dw_fpm_per_lb: float                 # the POH's own trend (NaN: one weight)
    polar: DragPolar
    propeller: PropellerCheck
    wall_time_s: float
    notes: list[str] = field(default_factory=list)

    def checks(self) -> list[Check]:
        """Each physical expectation with the model's value and whether it holds."""
        ws, pr, po = self.weight, self.propeller, self.polar
        ratios = [w.ratio for w in ws]
        lo, hi = pr.cruise_range()
        out = [Check("lighter climbs better: d(ROC)/dW < 0", ", ".join(f"{w.model_droc_dw_fpm_per_lb:+.3f}" for w in ws)
                     + " fpm/lb", "< 0", bool(ws) and all(w.model_droc_dw_fpm_per_lb < 0 for w in ws)),
               Check("d(ROC)/dW model / classic", ", ".join(f"{r:.2f}" for r in ratios),
                     f"{WEIGHT_RATIO_RANGE[0]}-{WEIGHT_RATIO_RANGE[1]}",
                     bool(ratios) and all(WEIGHT_RATIO_RANGE[0] <= r <= WEIGHT_RATIO_RANGE[1] for r in ratios)),
               Check("Oswald efficiency (drag polar)", f"{po.oswald_efficiency:.3f}",
                     f"{OSWALD_RANGE[0]}-{OSWALD_RANGE[1]}", _within(po.oswald_efficiency, OSWALD_RANGE)),
               Check("wing span efficiency (induced-drag table), largest", f"{_max_e(po):.2f}", "<= 1 (planar wing)",
                     bool(_max_e(po) <= 1.0)),
               Check("propeller peak efficiency", f"{pr.peak_efficiency:.3f} at J {pr.peak_advance_ratio:.2f}",
                     f"{PROPELLER_PEAK_RANGE[0]}-{PROPELLER_PEAK_RANGE[1]}",
                     _within(pr.peak_efficiency, PROPELLER_PEAK_RANGE)),
               Check("propeller peak at a cruise J", f"J {pr.peak_advance_ratio:.2f}",
                     f"{lo:.2f}-{hi:.2f} (+-{CRUISE_J_MARGIN})", pr.peak_in_cruise_range)]
        if math.isfinite(self.poh_droc_dw_fpm_per_lb):
            r = np.mean([w.model_droc_dw_fpm_per_lb for w in ws]) / self.poh_droc_dw_fpm_per_lb
            out.insert(2, Check("d(ROC)/dW model / POH", f"{r:.2f}", f"{WEIGHT_RATIO_RANGE[0]}-{WEIGHT_RATIO_RANGE[1]}",
                                _within(r, WEIGHT_RATIO_RANGE)))
        return out


def _within(v: float, rng: tuple[float, float]) -> bool:
    return bool(math.isfinite(v) and rng[0] <= v <= rng[1])


def _max_e(po: DragPolar) -> float:
    e = [p.wing_span_efficiency for p in po.points if math.isfinite(p.wing_span_efficiency)]
    return max(e) if e else math.nan


# --------------------------------------------------------------------------- drag polar
def _trim_reading(sim: Simulator, cond: Condition) -> tuple[TrimResult, AeroReading]:
    t = sim.trim(cond)
    return t, AeroReading.of(sim.fdm)


def polar_point(sim: Simulator, cond: Condition) -> PolarPoint | None:
    """Lift and drag coefficients of a level trim (None when it does not trim)."""
    t, r = _trim_reading(sim, cond)
    if not t.trimmed:
        return None
    lift, drag = r.lift_drag_lbf()
    qs = r.qbar_psf * r.area_ft2
    ar = r.span_ft ** 2 / r.area_ft2
    clw, cdiw = float(sim.fdm["aero/wing/CL"]), float(sim.fdm["aero/wing/CDi"])
    e_w = clw ** 2 / (math.pi * ar * cdiw) if cdiw > 0 else math.nan
    return PolarPoint(float(t.ktas), lift / qs, drag / qs, clw, cdiw, e_w)


def drag_polar(sim: Simulator, speeds_ktas: Sequence[float], weight_lb: float,
               pressure_alt_ft: float = POLAR_ALT_FT) -> DragPolar:
    """Level-flight trims at these true airspeeds (ISA, flaps up) and the parabolic polar through them."""
    pts = [polar_point(sim, Condition(pressure_alt_ft=pressure_alt_ft, weight_lb=weight_lb, ktas=float(v)))
           for v in speeds_ktas]
    pts = tuple(p for p in pts if p is not None)
    ar = float(sim.fdm["metrics/bw-ft"]) ** 2 / float(sim.fdm["metrics/Sw-sqft"])
    if len(pts) < 3:
        return DragPolar(pressure_alt_ft, weight_lb, ar, pts, math.nan, math.nan, math.nan)
    cl2 = np.array([p.cl ** 2 for p in pts])
    cd = np.array([p.cd for p in pts])
    k, cd0 = np.polyfit(cl2, cd, 1)
    return DragPolar(pressure_alt_ft, weight_lb, ar, pts, float(cd0), float(k),
                     float(1.0 / (math.pi * ar * k)) if k > 0 else math.nan)


def polar_speeds(sim: Simulator, climb: Dataset, cruise: Dataset, n: int = POLAR_SPEEDS,
                 pressure_alt_ft: float = POLAR_ALT_FT) -> np.ndarray:
    """From the POH climb speed (as true airspeed at the polar's altitude) to the top cruise speed."""
    kcas = min(c.kcas for c in KINDS["poh_climb"].conditions(climb, sim.geometry))
    lo = Condition(pressure_alt_ft=pressure_alt_ft, weight_lb=1.0, kcas=kcas).true_airspeed_kt()
    hi = float(cruise.frame["ktas"].max())
    return np.linspace(lo, hi, n)


# --------------------------------------------------------------------------- climb rate and weight
def trend_rows(conds: Sequence[Condition]) -> list[int]:
    """POH climb points for the weight trend: lowest, middle and highest altitude, each at the
    temperature nearest standard."""
    alts = sorted({c.pressure_alt_ft for c in conds})
    out = []
    for a in sorted({alts[0], alts[len(alts) // 2], alts[-1]}):
        rows = [i for i, c in enumerate(conds) if c.pressure_alt_ft == a]
        isa = float(isa_temperature(a * FT))
        out.append(min(rows, key=lambda i: abs(conds[i].temperature_k() - isa)))
    return out


def weight_sensitivity(sim: Simulator, cond: Condition, polar: DragPolar,
                       step_lb: float = WEIGHT_STEP_LB) -> WeightSensitivity | None:
    """The model's d(ROC)/dW at a full-throttle climb condition, and the classic estimate."""
    up = sim.trim(replace(cond, weight_lb=cond.weight_lb + step_lb))
    down = sim.trim(replace(cond, weight_lb=cond.weight_lb - step_lb))
    mid, r = _trim_reading(sim, cond)
    if not (up.trimmed and down.trimmed and mid.trimmed):
        return None
    qs = r.qbar_psf * r.area_ft2
    lift, _ = r.lift_drag_lbf()
    cl = lift / qs
    di = polar.k * cl ** 2 * qs
    v_fpm = mid.ktas * KT / FT * FPM_PER_FPS
    w = cond.weight_lb
    classic = -mid.roc_fpm / w - 2.0 * di * v_fpm / w ** 2
    return WeightSensitivity(cond.pressure_alt_ft, cond.temperature_k() - 273.15, float(mid.kcas), w,
                             float(mid.roc_fpm), cl, di, (up.roc_fpm - down.roc_fpm) / (2.0 * step_lb), classic)


def poh_weight_trend(climb: Dataset) -> tuple[tuple[float, ...], float]:
    """The POH's distinct climb weights and its d(ROC)/dW (slope at equal altitude and
    temperature, averaged; NaN with one weight)."""
    f = climb.frame
    weights = tuple(sorted(set(f["weight_lb"].astype(float))))
    if len(weights) < 2:
        return weights, math.nan
    temp = "oat_c" if "oat_c" in f else "temp_dev_c"
    slopes = []
    for _, g in f.groupby(["pressure_alt_ft", temp]):
        if g["weight_lb"].nunique() > 1:
            slopes.append(float(np.polyfit(g["weight_lb"].astype(float), g["roc_fpm"].astype(float), 1)[0]))
    return weights, float(np.mean(slopes)) if slopes else math.nan


# --------------------------------------------------------------------------- propeller
def propeller_point(sim: Simulator, kind: str, t: TrimResult) -> PropellerPoint:
    v_fps = t.ktas * KT / FT
    n_rps = t.rpm / 60.0
    d_ft = sim.geometry.propeller.diameter_m / FT
    eta = t.thrust_lbf * v_fps / (t.power_hp * HP_FTLBF_S) if t.power_hp > 0 else math.nan
    return PropellerPoint(kind, float(t.condition.pressure_alt_ft), float(t.ktas), float(t.rpm),
                          v_fps / (n_rps * d_ft) if n_rps > 0 else math.nan, float(eta),
                          float(t.extra.get("blade_angle_deg", math.nan)))


def operating_points(sim: Simulator, data: dict[str, Dataset]) -> tuple[PropellerPoint, ...]:
    """Propeller efficiency at every POH climb and cruise point the model trims."""
    out = []
    for kind, label in (("poh_climb", "climb"), ("poh_cruise", "cruise")):
        for cond in KINDS[kind].conditions(data[kind], sim.geometry):
            t = sim.trim_level(cond) if cond.mode == "level" else sim.trim(cond)
            if t.trimmed:
                out.append(propeller_point(sim, label, t))
    return tuple(out)


def efficiency_curve(tables: PropellerTables, blade_angle_deg: float = math.nan) -> tuple[np.ndarray, np.ndarray]:
    """eta(J) = J CT / CP along the table (a constant-speed table at ``blade_angle_deg``)."""
    J = np.asarray(tables.J, float)
    ct, cp = np.asarray(tables.CT, float), np.asarray(tables.CP, float)
    if tables.constant_speed:
        b = np.asarray(tables.beta75_deg, float)
        ct = np.array([np.interp(blade_angle_deg, b, row) for row in ct])
        cp = np.array([np.interp(blade_angle_deg, b, row) for row in cp])
    ok = (ct > 0) & (cp > 0)
    return J, np.where(ok, J * np.where(ok, ct, 1.0) / np.where(ok, cp, 1.0), np.nan)


def _peak(J: np.ndarray, eta: np.ndarray) -> tuple[float, float]:
    if not np.any(np.isfinite(eta)):
        return math.nan, math.nan
    i = int(np.nanargmax(eta))
    return float(eta[i]), float(J[i])


def propeller_check(sim: Simulator, data: dict[str, Dataset], paths: AircraftPaths) -> PropellerCheck:
    pts = operating_points(sim, data)
    blades = [p.blade_angle_deg for p in pts if p.kind == "cruise" and math.isfinite(p.blade_angle_deg)]
    beta = float(np.median(blades)) if blades else math.nan
    J, eta = efficiency_curve(propeller_tables(paths, sim.factors), beta)
    J0, eta0 = efficiency_curve(propeller_tables(paths, FactorSet()), beta)
    peak, j_peak = _peak(J, eta)
    peak0, j0 = _peak(J0, eta0)
    return PropellerCheck(pts, tuple(map(float, J)), tuple(map(float, eta)), beta, peak, j_peak, peak0, j0)


# --------------------------------------------------------------------------- all
def physics_checks(sim: Simulator, data: dict[str, Dataset], paths: AircraftPaths, *, model: str = "calibrated",
                   progress: Callable[[str], None] | None = None) -> PhysicsChecks:
    """Every check on the model ``sim`` holds, with its POH climb and cruise data (``poh_climb``,
    ``poh_cruise``) as the conditions."""
    say = progress or (lambda s: None)
    t0 = time.perf_counter()
    climb, cruise = data["poh_climb"], data["poh_cruise"]
    weight_lb = float(climb.frame["weight_lb"].max())
    say("physics checks: drag polar")
    polar = drag_polar(sim, polar_speeds(sim, climb, cruise), weight_lb)
    say("physics checks: climb rate against weight")
    conds = KINDS["poh_climb"].conditions(climb, sim.geometry)
    ws = [weight_sensitivity(sim, conds[i], polar) for i in trend_rows(conds)]
    weights, poh_trend = poh_weight_trend(climb)
    say("physics checks: propeller efficiency")
    prop = propeller_check(sim, data, paths)
    out = PhysicsChecks(sim.name, model, [w for w in ws if w is not None], weights, poh_trend, polar, prop,
                        time.perf_counter() - t0)
    if len(weights) < 2:
        out.notes.append(f"the POH climb data give one weight ({weights[0]:.0f} lb): the model's trend is "
                         "compared with the classic estimate only")
    return out


def run_physics_checks(root: Path | str, name: str, data: dict[str, Dataset],
                       progress: Callable[[str], None] | None = None) -> PhysicsChecks:
    """The checks on the aircraft as it stands (its product factors)."""
    with Simulator(Path(root), name) as sim:
        return physics_checks(sim, data, AircraftPaths(Path(root), name), model="product", progress=progress)
