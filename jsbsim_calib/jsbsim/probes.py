"""Probes of a loaded aircraft: what JSBSim makes of it, beyond a trim.

* :func:`trim_derivatives` trims the aircraft at a condition and differences JSBSim's
  total aerodynamic forces and moments around the trimmed state: lift slope, static
  stability about the CG, the sideslip derivatives and the rate damping.
* :func:`stall_speed` searches the lowest calibrated airspeed at which the aircraft can be
  trimmed in a steady power-off glide with the elevator inside its stops.
* :func:`report` collects both for one aircraft (:class:`StabilityReport`, JSON through
  ``as_dict()``).
* :func:`aero_curves` sweeps the whole aircraft's lift and drag over angle of attack.

How a state is evaluated: exactly as :meth:`Simulator.trim` sets one. The attitude
(``ic/phi-rad``, ``ic/theta-rad``, ``ic/psi-true-rad``), body velocities (``ic/u-fps``,
``ic/v-fps``, ``ic/w-fps``) and body rates (``ic/p-rad_sec`` ...) are written, then
``run_ic``, the engine's steady state and one frame with integration suspended. Controls,
throttle, mixture, flaps, loading and atmosphere stay those of the trim.

Coefficients: the aerodynamic forces (``forces/fb[xyz]-aero-lbs``, body axes) are
rotated into stability axes for lift and drag (CL, CD); the side force is the body-axis
one (CY). The moments are JSBSim's ``moments/[lmn]-aero-lbsft``: aerodynamic moments
transferred to the CG, body axes. Normalization by qbar S (forces), qbar S b (roll and
yaw) and qbar S cbar (pitch) with JSBSim's own ``aero/qbar-psf`` and ``metrics/*``.

The state ``alphadot``: JSBSim computes the rate of change of angle of attack from the
accelerations of the frame, and the generated models use it (the lag of the wing
downwash at the tail). A perturbed state is not in equilibrium, so alphadot is not zero
there (a 1 deg angle-of-attack step in cruise gives about -0.04 rad/s, a pitch-rate
step gives alphadot close to the pitch rate itself), which would mix Cm_alphadot into
Cm_alpha and Cm_q. The derivatives here are those at alphadot = 0 (their textbook
definition): every perturbed state is evaluated twice, at the trimmed pitch attitude and
at an attitude :data:`THETA_OFFSET_RAD` higher (gravity changes the accelerations and so
alphadot, but not the aerodynamics), and the coefficients are extrapolated linearly to
alphadot = 0. The same pair of evaluations at the trimmed state gives Cm_alphadot and
CL_alphadot.
"""
from __future__ import annotations

import itertools
import math
from dataclasses import asdict, dataclass, field
from typing import Mapping, Sequence

import numpy as np

from ..core.errors import TrimError
from ..core.units import FT, KT
from ..flight.condition import Condition, TrimResult
from ..physics.atmosphere import isa_temperature, kias_from_kcas
from .simulator import Simulator
from .trim import set_atmosphere

# Central-difference steps (half the distance between the two evaluated states)
STEP_ALPHA_RAD = math.radians(1.0)     # [rad] angle of attack
STEP_BETA_RAD = math.radians(1.0)      # [rad] sideslip
STEP_P_HAT = 0.01                      # [-] p b/(2V)  (about 0.1 rad/s at 110 kt)
STEP_R_HAT = 0.01                      # [-] r b/(2V)
STEP_Q_HAT = 0.002                     # [-] q cbar/(2V) (about 0.15 rad/s, 0.7 deg at the tail, at 110 kt)
THETA_OFFSET_RAD = math.radians(30.0)  # [rad] attitude change that moves alphadot (see module doc)

_STALL_KEYS = itertools.count()


@dataclass(frozen=True)
class Derivatives:
    """Stability derivatives at a trimmed condition: body axes, moments about the CG,
    alphadot = 0. Rate derivatives are per unit nondimensional rate."""

    condition: Condition
    alpha_deg: float          # [deg] trimmed angle of attack
    elevator_deg: float       # [deg] trimmed elevator (+ trailing edge down)
    ktas: float               # [kt] true airspeed
    kcas: float               # [kt] calibrated airspeed
    qbar_psf: float           # [lbf/ft^2] dynamic pressure
    cg_in: float              # [in] CG station (JSBSim inertia/cg-x-in)
    CL: float                 # [-] trimmed lift coefficient (stability axes)
    CL_alpha: float           # [1/rad]
    CD_alpha: float           # [1/rad]
    Cm_alpha: float           # [1/rad] about the CG
    CY_beta: float            # [1/rad]
    Cl_beta: float            # [1/rad]
    Cn_beta: float            # [1/rad]
    CY_p: float               # [-] per unit p b/(2V)
    Cl_p: float               # [-] per unit p b/(2V)
    Cn_p: float               # [-] per unit p b/(2V)
    CY_r: float               # [-] per unit r b/(2V)
    Cl_r: float               # [-] per unit r b/(2V)
    Cn_r: float               # [-] per unit r b/(2V)
    CL_q: float               # [-] per unit q cbar/(2V)
    Cm_q: float               # [-] per unit q cbar/(2V)
    CL_alphadot: float        # [-] per unit alphadot cbar/(2V)
    Cm_alphadot: float        # [-] per unit alphadot cbar/(2V)
    static_margin: float      # [-] fraction of cbar: -Cm_alpha / CL_alpha

    def as_dict(self) -> dict:
        d = {k: v for k, v in asdict(self).items() if k != "condition"}
        d["condition"] = asdict(self.condition)
        return _json_safe(d)


@dataclass(frozen=True)
class StallResult:
    """Lowest trimmable speed of a steady glide (or the point where CL stops rising)."""

    weight_lb: float          # [lb]
    cg_in: float              # [in]
    flaps_deg: float          # [deg]
    pressure_alt_ft: float    # [ft]
    throttle: float           # [-] throttle command of the glide (0 = idle)
    kcas: float               # [kt] stall speed, calibrated (NaN when not found)
    kias: float               # [kt] stall speed, indicated (aircraft's airspeed calibration)
    cl_max: float             # [-] trimmed lift coefficient at the stall speed (stability axes)
    alpha_deg: float          # [deg] trimmed angle of attack there
    elevator_deg: float       # [deg] trimmed elevator there (+ trailing edge down)
    gamma_deg: float          # [deg] glide path angle there
    reason: str               # why the search stopped below kcas
    trims: int                # number of trims the search used

    def as_dict(self) -> dict:
        return _json_safe(asdict(self))


# --------------------------------------------------------------------------- state handling
@dataclass(frozen=True)
class _State:
    V: float        # [ft/s]
    alpha: float    # [rad]
    beta: float     # [rad]
    phi: float      # [rad]
    theta: float    # [rad]
    psi: float      # [rad]
    p: float        # [rad/s]
    q: float        # [rad/s]
    r: float        # [rad/s]

    def with_(self, **kw) -> "_State":
        d = asdict(self)
        d.update(kw)
        return _State(**d)


def _read_state(fdm) -> _State:
    """The state the last trim evaluation wrote into the initial conditions."""
    u, v, w = fdm["ic/u-fps"], fdm["ic/v-fps"], fdm["ic/w-fps"]
    V = math.sqrt(u * u + v * v + w * w)
    return _State(V, math.atan2(w, u), math.asin(v / V), fdm["ic/phi-rad"], fdm["ic/theta-rad"],
                  fdm["ic/psi-true-rad"], fdm["ic/p-rad_sec"], fdm["ic/q-rad_sec"], fdm["ic/r-rad_sec"])


def _set_state(fdm, s: _State) -> None:
    """Set a state and evaluate it as Simulator.trim does."""
    fdm["ic/phi-rad"] = s.phi
    fdm["ic/theta-rad"] = s.theta
    fdm["ic/psi-true-rad"] = s.psi
    fdm["ic/u-fps"] = s.V * math.cos(s.alpha) * math.cos(s.beta)
    fdm["ic/v-fps"] = s.V * math.sin(s.beta)
    fdm["ic/w-fps"] = s.V * math.sin(s.alpha) * math.cos(s.beta)
    fdm["ic/p-rad_sec"] = s.p
    fdm["ic/q-rad_sec"] = s.q
    fdm["ic/r-rad_sec"] = s.r
    fdm.run_ic()
    fdm.get_propulsion().get_steady_state()
    fdm.run()


@dataclass(frozen=True)
class AeroReading:
    """JSBSim's aerodynamic forces and moments of the state it holds, with what normalizes them."""

    fx_lbf: float             # body axes
    fy_lbf: float
    fz_lbf: float
    l_lbft: float             # about the CG, body axes
    m_lbft: float
    n_lbft: float
    qbar_psf: float
    area_ft2: float
    span_ft: float
    chord_ft: float
    alpha_rad: float
    alphadot_rad_s: float
    speed_fps: float

    @classmethod
    def of(cls, fdm) -> "AeroReading":
        return cls(fdm["forces/fbx-aero-lbs"], fdm["forces/fby-aero-lbs"], fdm["forces/fbz-aero-lbs"],
                   fdm["moments/l-aero-lbsft"], fdm["moments/m-aero-lbsft"], fdm["moments/n-aero-lbsft"],
                   fdm["aero/qbar-psf"], fdm["metrics/Sw-sqft"], fdm["metrics/bw-ft"], fdm["metrics/cbarw-ft"],
                   fdm["aero/alpha-rad"], fdm["aero/alphadot-rad_sec"], fdm["velocities/vt-fps"])

    def lift_drag_lbf(self, alpha_rad: float | None = None) -> tuple[float, float]:
        """Lift and drag: the body-axis forces rotated into stability axes at ``alpha_rad``
        (default JSBSim's angle of attack)."""
        a = self.alpha_rad if alpha_rad is None else alpha_rad
        return (self.fx_lbf * math.sin(a) - self.fz_lbf * math.cos(a),
                -self.fx_lbf * math.cos(a) - self.fz_lbf * math.sin(a))


_KEYS = ("CL", "CD", "CY", "Cl", "Cm", "Cn")


def _raw_coefficients(fdm, s: _State) -> tuple[np.ndarray, float]:
    """Aerodynamic coefficients (order of _KEYS) of a state and its alphadot cbar/(2V)."""
    _set_state(fdm, s)
    r = AeroReading.of(fdm)
    lift, drag = r.lift_drag_lbf()
    qS = r.qbar_psf * r.area_ft2
    out = np.array([lift / qS, drag / qS, r.fy_lbf / qS, r.l_lbft / (qS * r.span_ft), r.m_lbft / (qS * r.chord_ft),
                    r.n_lbft / (qS * r.span_ft)])
    adot_hat = r.alphadot_rad_s * r.chord_ft / (2.0 * r.speed_fps)
    if not (np.all(np.isfinite(out)) and math.isfinite(adot_hat)):
        raise TrimError("JSBSim returned non-finite aerodynamic forces for a perturbed state")
    return out, adot_hat


def _coefficients(fdm, s: _State) -> tuple[np.ndarray, np.ndarray]:
    """Coefficients of a state at alphadot = 0, and their derivative with alphadot cbar/(2V)."""
    c1, ad1 = _raw_coefficients(fdm, s)
    c2, ad2 = _raw_coefficients(fdm, s.with_(theta=s.theta + THETA_OFFSET_RAD))
    if abs(ad2 - ad1) < 1e-12:
        return c1, np.zeros_like(c1)
    slope = (c2 - c1) / (ad2 - ad1)
    return c1 - slope * ad1, slope


def _central(fdm, s: _State, field: str, step: float) -> np.ndarray:
    plus = _coefficients(fdm, s.with_(**{field: getattr(s, field) + step}))[0]
    minus = _coefficients(fdm, s.with_(**{field: getattr(s, field) - step}))[0]
    return (plus - minus) / (2.0 * step)


def trim_derivatives(sim: Simulator, cond: Condition) -> Derivatives:
    """Trim at ``cond`` and difference JSBSim's aerodynamic coefficients about that state.

    Central differences with steps :data:`STEP_ALPHA_RAD`, :data:`STEP_BETA_RAD`,
    :data:`STEP_P_HAT`, :data:`STEP_Q_HAT`, :data:`STEP_R_HAT` (nondimensional rates by
    b/(2V) or cbar/(2V)). Raises :class:`TrimError` when the condition does not trim.
    The simulator is left in the trimmed state.
    """
    res: TrimResult = sim.trim(cond)
    if not res.trimmed:
        raise TrimError(f"no trim at {cond}: {res.reason}", res.residual)
    fdm = sim.fdm
    fdm.suspend_integration()
    s0 = _read_state(fdm)
    b, c = fdm["metrics/bw-ft"], fdm["metrics/cbarw-ft"]
    cg_in = fdm["inertia/cg-x-in"]
    base, dadot = _coefficients(fdm, s0)
    i = {k: n for n, k in enumerate(_KEYS)}
    d_a = _central(fdm, s0, "alpha", STEP_ALPHA_RAD)
    d_b = _central(fdm, s0, "beta", STEP_BETA_RAD)
    d_p = _central(fdm, s0, "p", STEP_P_HAT * 2.0 * s0.V / b) * (2.0 * s0.V / b)
    d_r = _central(fdm, s0, "r", STEP_R_HAT * 2.0 * s0.V / b) * (2.0 * s0.V / b)
    d_q = _central(fdm, s0, "q", STEP_Q_HAT * 2.0 * s0.V / c) * (2.0 * s0.V / c)
    _set_state(fdm, s0)                  # leave the trimmed state behind
    cl_a, cm_a = float(d_a[i["CL"]]), float(d_a[i["Cm"]])
    return Derivatives(
        condition=cond, alpha_deg=res.alpha_deg, elevator_deg=res.elevator_deg, ktas=res.ktas, kcas=res.kcas,
        qbar_psf=res.qbar_psf, cg_in=cg_in, CL=float(base[i["CL"]]),
        CL_alpha=cl_a, CD_alpha=float(d_a[i["CD"]]), Cm_alpha=cm_a,
        CY_beta=float(d_b[i["CY"]]), Cl_beta=float(d_b[i["Cl"]]), Cn_beta=float(d_b[i["Cn"]]),
        CY_p=float(d_p[i["CY"]]), Cl_p=float(d_p[i["Cl"]]), Cn_p=float(d_p[i["Cn"]]),
        CY_r=float(d_r[i["CY"]]), Cl_r=float(d_r[i["Cl"]]), Cn_r=float(d_r[i["Cn"]]),
        CL_q=float(d_q[i["CL"]]), Cm_q=float(d_q[i["Cm"]]),
        CL_alphadot=float(dadot[i["CL"]]), Cm_alphadot=float(dadot[i["Cm"]]),
        static_margin=-cm_a / cl_a if cl_a != 0 else float("nan"),
    )


# --------------------------------------------------------------------------- stall
def _lift_coefficient(sim: Simulator) -> float:
    """Stability-axis lift coefficient of the state JSBSim holds."""
    r = AeroReading.of(sim.fdm)
    return r.lift_drag_lbf()[0] / (r.qbar_psf * r.area_ft2)


def _envelope_end(kcas: float, trim_reason: str) -> str:
    """The stall search's note where the glide stops trimming: the expected end of the envelope,
    not an error (the trim's own words stay in the trim result)."""
    limit = "the elevator at its stop" if "elevator" in trim_reason else "no steady glide"
    return f"stall: {limit} below {kcas:.1f} KCAS (the expected end of the envelope)"


def stall_speed(sim: Simulator, weight_lb: float, cg_in: float, flaps_deg: float = 0.0,
                pressure_alt_ft: float = 0.0, *, power: str | float = "idle", start_kcas: float = 70.0,
                step_kt: float = 2.0, min_kcas: float = 20.0, resolution_kt: float = 0.1,
                isa_dev_c: float = 0.0) -> StallResult:
    """Minimum calibrated airspeed of a steady glide (flight path free), elevator within its stops.

    ``power='idle'``: throttle 0 (power-off stall); a number is a throttle command. The
    search goes down from ``start_kcas`` in steps of ``step_kt`` and then bisects to
    ``resolution_kt``. The stall is the first speed at which either the trim fails (no
    equilibrium, elevator at its stop, engine stopped) or the trimmed lift coefficient
    no longer rises as the speed falls (CL max passed, checked over ``resolution_kt``).
    """
    throttle = 0.0 if power == "idle" else float(power)
    if not 0.0 <= throttle <= 1.0:
        raise ValueError(f"power must be 'idle' or a throttle command in [0, 1], not {power!r}")
    key = ("stability.stall_speed", next(_STALL_KEYS))
    trims = 0

    def point(v: float):
        nonlocal trims
        trims += 1
        cond = Condition(pressure_alt_ft, weight_lb, kcas=v, cg_in=cg_in, flaps_deg=flaps_deg,
                         mode="full_throttle", throttle=throttle, isa_dev_c=isa_dev_c)
        r = sim.trim(cond, key=key)
        return r, (_lift_coefficient(sim) if r.trimmed else float("nan"))

    def flying(v: float, ref: tuple | None = None):
        """(ok, why, trim result, CL) at v: ok when v trims on the front side of the lift
        curve (CL above that of ``ref``, a faster point (speed, CL); without ``ref``, the
        point ``resolution_kt`` faster)."""
        r, cl = point(v)
        if not r.trimmed:
            return False, _envelope_end(v, r.reason), r, cl
        if ref is None:
            r_hi, cl_hi = point(v + resolution_kt)
            if not r_hi.trimmed:
                return False, _envelope_end(v + resolution_kt, r_hi.reason), r, cl
            ref = (v + resolution_kt, cl_hi)
            r, cl = point(v)                       # leave this speed's state behind
        if cl <= ref[1]:
            return False, f"lift coefficient stops rising below {ref[0]:.1f} KCAS (CL {cl:.4f} <= {ref[1]:.4f})", r, cl
        return True, "", r, cl

    r0, cl0 = point(start_kcas)
    if not r0.trimmed:
        nan = float("nan")
        return StallResult(weight_lb, cg_in, flaps_deg, pressure_alt_ft, throttle, nan, nan, nan, nan, nan, nan,
                           f"no trim at the start speed {start_kcas:g} KCAS: {r0.reason}", trims)
    hi, r_hi, cl_hi = start_kcas, r0, cl0
    lo = None
    reason = f"trimmed down to the lowest speed searched ({min_kcas:g} KCAS)"
    v = start_kcas
    while v - step_kt >= min_kcas - 1e-9:
        v -= step_kt
        ok, why, r, cl = flying(v, (hi, cl_hi))
        if not ok:
            lo, reason = v, why
            break
        hi, r_hi, cl_hi = v, r, cl
    if lo is not None:
        while hi - lo > resolution_kt + 1e-9:
            mid = 0.5 * (hi + lo)
            ok, why, r, cl = flying(mid)
            if ok:
                hi, r_hi, cl_hi = mid, r, cl
            else:
                lo, reason = mid, why
        # leave the stall point's trimmed state in the simulator
        r_hi, cl_hi = point(hi)
    return StallResult(weight_lb, cg_in, flaps_deg, pressure_alt_ft, throttle, hi, kias_from_kcas(hi, sim.geometry.operations.airspeed_calibration), cl_hi,
                       r_hi.alpha_deg, r_hi.elevator_deg, r_hi.gamma_deg, reason, trims)


# --------------------------------------------------------------------------- report
def _json_safe(x):
    if isinstance(x, dict):
        return {str(k): _json_safe(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_json_safe(v) for v in x]
    if isinstance(x, (bool, str)) or x is None:
        return x
    if isinstance(x, (int, np.integer)):
        return int(x)
    if isinstance(x, (float, np.floating)):
        return float(x) if math.isfinite(x) else None
    return str(x)


@dataclass(frozen=True)
class StallCase:
    """One stall search: loading and configuration."""

    weight_lb: float                    # [lb]
    cg_in: float                        # [in]
    flaps_deg: float = 0.0              # [deg]
    pressure_alt_ft: float = 0.0        # [ft]


def default_stall_cases(sim: Simulator) -> tuple[StallCase, ...]:
    """Max weight at the forward and aft CG limits, flaps up and fully down."""
    m = sim.geometry.mass
    w = m.max_mass_kg / 0.45359237
    fwd = float(np.interp(m.max_mass_kg, m.cg_envelope_mass_kg, m.cg_envelope_fwd_m)) / 0.0254
    aft = float(np.interp(m.max_mass_kg, m.cg_envelope_mass_kg, m.cg_envelope_aft_m)) / 0.0254
    flap = sim.geometry.wing.control("flap")
    flaps = [0.0] + ([round(math.degrees(flap.deflection_max_rad), 6)] if flap else [])
    return tuple(StallCase(round(w, 6), round(cg, 6), f) for f in flaps for cg in (fwd, aft))


def default_conditions(sim: Simulator) -> dict[str, Condition]:
    """Named conditions for :func:`report`: at maximum weight, level cruise at a lift
    coefficient of 0.3 and a full-throttle climb at 0.8, 3000 ft ISA, both CG limits."""
    m = sim.geometry.mass
    w_lb = m.max_mass_kg / 0.45359237
    area_ft2 = sim.geometry.reference.wing_area_m2 / 0.3048**2
    out = {}
    for label, cg_m in (("fwd", float(np.interp(m.max_mass_kg, m.cg_envelope_mass_kg, m.cg_envelope_fwd_m))),
                        ("aft", float(np.interp(m.max_mass_kg, m.cg_envelope_mass_kg, m.cg_envelope_aft_m)))):
        for name, cl, mode in (("cruise", 0.3, "level"), ("climb", 0.8, "full_throttle")):
            kcas = math.sqrt(w_lb / (0.5 * 0.0023769 * area_ft2 * cl)) / 1.68781
            out[f"{name} {label} CG"] = Condition(pressure_alt_ft=3000.0, weight_lb=round(w_lb, 1),
                                                  kcas=round(kcas, 1), cg_in=round(cg_m / 0.0254, 2),
                                                  mode=mode, mixture="climb" if mode != "level" else "cruise")
    return out


AXES = "body axes, moments about the CG, alphadot = 0; rates per unit p b/(2V), q cbar/(2V), r b/(2V)"


@dataclass(frozen=True)
class TrimFailure:
    """A condition of the report that does not trim, and why."""

    condition: Condition
    error: str

    def as_dict(self) -> dict:
        return {"error": self.error, "condition": asdict(self.condition)}


@dataclass(frozen=True)
class StabilityReport:
    """Stability derivatives at named conditions and stall speeds of one aircraft."""

    aircraft: str
    factors_changed: dict[str, float]               # calibration factors away from neutral
    derivatives: dict[str, Derivatives | TrimFailure]
    stall: list[StallResult] = field(default_factory=list)
    axes: str = AXES

    def as_dict(self) -> dict:
        """JSON-safe (NaN as null): the schema ``check --json`` writes."""
        return _json_safe({"aircraft": self.aircraft, "factors_changed": dict(self.factors_changed), "axes": self.axes,
                           "derivatives": {k: d.as_dict() for k, d in self.derivatives.items()},
                           "stall": [s.as_dict() for s in self.stall]})


def report(sim: Simulator, conditions: Mapping[str, Condition] | None = None,
           stall_cases: Sequence[StallCase] | None = None) -> StabilityReport:
    """Derivatives at each named condition and stall speeds.

    ``conditions`` defaults to :func:`default_conditions`, ``stall_cases`` to
    :func:`default_stall_cases`. A condition that does not
    trim is reported with its reason instead of derivatives.
    """
    derivatives: dict[str, Derivatives | TrimFailure] = {}
    for name, cond in (default_conditions(sim) if conditions is None else conditions).items():
        try:
            derivatives[name] = trim_derivatives(sim, cond)
        except TrimError as exc:
            derivatives[name] = TrimFailure(cond, str(exc))
    stall = [stall_speed(sim, case.weight_lb, case.cg_in, case.flaps_deg, case.pressure_alt_ft)
             for case in (default_stall_cases(sim) if stall_cases is None else stall_cases)]
    return StabilityReport(sim.name, dict(sim.factors.changed()), derivatives, stall)


# --------------------------------------------------------------------------- aerodynamic curves
@dataclass(frozen=True)
class AeroCurves:
    """Whole-aircraft lift and drag coefficients (aerodynamic forces only) over angle of attack."""

    alpha_deg: np.ndarray     # [deg]
    CL: np.ndarray            # [-] stability axes
    CD: np.ndarray            # [-]


def aero_curves(sim: Simulator, alphas_deg=np.arange(-6.0, 22.01, 1.0), ktas: float = 90.0,
                pressure_alt_ft: float = 5000.0) -> AeroCurves:
    """Lift curve and drag polar at ``ktas``, ISA, 2400 lb, elevator neutral, clean."""
    fdm = sim.fdm
    sim.set_loading(2400.0)
    set_atmosphere(fdm, pressure_alt_ft, float(isa_temperature(pressure_alt_ft * FT)))
    V = ktas * KT / FT
    CL, CD = [], []
    fdm["fcs/flap-cmd-norm"] = 0.0
    for c in ("fcs/elevator-cmd-norm", "fcs/aileron-cmd-norm", "fcs/rudder-cmd-norm"):
        fdm[c] = 0.0
    for a_deg in alphas_deg:
        a = math.radians(a_deg)
        fdm["ic/phi-rad"] = 0.0
        fdm["ic/theta-rad"] = a
        fdm["ic/u-fps"] = V * math.cos(a)
        fdm["ic/v-fps"] = 0.0
        fdm["ic/w-fps"] = V * math.sin(a)
        for r in ("p", "q", "r"):
            fdm[f"ic/{r}-rad_sec"] = 0.0
        fdm.run_ic()
        fdm.run()
        reading = AeroReading.of(fdm)
        q = reading.qbar_psf * reading.area_ft2
        lift, drag = reading.lift_drag_lbf(a)
        CL.append(lift / q)
        CD.append(drag / q)
    return AeroCurves(np.asarray(alphas_deg, float), np.array(CL), np.array(CD))
