"""The trim solver: a simulator's aircraft brought to equilibrium at a flight condition.

JSBSim evaluates the accelerations of a given state (``run_ic`` + the engine's steady state +
one frame with integration suspended); a Newton-type root finder (MINPACK ``hybr``) drives the
six body accelerations to zero by moving angle of attack, sideslip, elevator, aileron, rudder
and either the throttle (flight path given) or the pitch attitude (throttle given, flight path
free: a climb at full throttle), or the speed (throttle and flight path given). A governed
propeller adds its blade angle, which holds the set RPM. The state is straight flight at a
given bank angle or a coordinated turn. A failed trim says why and never leaves NaN behind for
the next point.

The pieces, in the order a trim runs them: :func:`_prepare` (loading, atmosphere, mixture,
flaps, governor), :class:`_Equilibrium` (the state of the unknowns and its residual),
:func:`_warm_start` (Newton steps, shortened where they cross a kink, with the Jacobian kept
from the last trim of the same point)
or :func:`_solve` (``hybr`` from the warm result, then from a cold start), :func:`_result`
(what the trimmed state shows, and why it does not count as trimmed).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
from scipy.optimize import root

from ..core import numerics
from ..core.errors import TrimError
from ..core.units import FT, G0, HP, KT, LAPSE, T0
from ..flight.condition import Condition, TrimResult
from ..physics.atmosphere import isa_at_ft
from ..physics.engine import poh_mixture
from ..physics.geometry import AircraftGeometry

G_FT = G0 / FT
R_EARTH_FT = 20925646.325  # JSBSim's reference radius for geopotential altitude (ft)
CONTROL_LIMIT = 1.0 + 1e-6
TRIM_AID = "external_reactions/trim-aid/magnitude"
TRIM_AID_LBF = 300.0
NEWTON_TOL = 1e-10       # accelerations in g (rotational in rad/s^2): trims repeat to ~1e-10 whatever their start
NEWTON_STEPS = 12        # Newton steps of a warm start at most
NEWTON_SHARES = (1.0, 0.5, 0.25)   # the share of a Newton step tried, in turn, until one lowers the residual
EQUILIBRIUM_TOL = 2e-4   # a state whose largest residual is above this is no equilibrium
CLIMB_VS_FPM = 50.0      # [ft/min] above this a point past the throttle stop is a climb (see trim_at_stop)

OUTPUTS = {
    "alpha_deg": "aero/alpha-deg", "beta_deg": "aero/beta-deg", "theta_deg": "attitude/theta-deg",
    "phi_deg": "attitude/phi-deg", "gamma_deg": "flight-path/gamma-deg", "ktas": "velocities/vtrue-kts",
    "kcas": "velocities/vc-kts", "throttle": "fcs/throttle-pos-norm", "mixture": "fcs/mixture-pos-norm",
    "rpm": "propulsion/engine/engine-rpm", "power_hp": "propulsion/engine/power-hp",
    "gph": "propulsion/engine/fuel-flow-rate-gph", "thrust_lbf": "propulsion/engine/thrust-lbs",
    "map_inhg": "propulsion/engine/map-inhg", "elevator_deg": "fcs/elevator-pos-deg",
    "aileron_deg": "fcs/aileron-pos-deg", "rudder_deg": "fcs/rudder-pos-deg", "qbar_psf": "aero/qbar-psf",
}
POSITION_ERROR = "velocities/position-error-kts"   # measured - true airspeed, where an aircraft defines it
PITCH_INDICATED = "attitude/theta-ind-deg"         # pitch as the attitude instrument shows it, where defined
ACCELS = ("accelerations/udot-ft_sec2", "accelerations/vdot-ft_sec2", "accelerations/wdot-ft_sec2",
          "accelerations/pdot-rad_sec2", "accelerations/qdot-rad_sec2", "accelerations/rdot-rad_sec2")
ACCEL_SCALE = np.array([G_FT, G_FT, G_FT, 1.0, 1.0, 1.0])    # the residual: accelerations in g, rotational in rad/s^2
# what a trim's unknowns set, in this order (_Equilibrium.set_state)
STATE = ("ic/phi-rad", "ic/theta-rad", "ic/psi-true-rad", "ic/u-fps", "ic/v-fps", "ic/w-fps",
         "ic/p-rad_sec", "ic/q-rad_sec", "ic/r-rad_sec", "fcs/throttle-cmd-norm", TRIM_AID,
         "fcs/elevator-cmd-norm", "fcs/aileron-cmd-norm", "fcs/rudder-cmd-norm")
# what a trim writes besides the initial conditions and the loading (Simulator.set_loading): a
# reset of the JSBSim sets these back to their values at the load (Simulator.fresh)
WRITES = STATE[9:] + ("atmosphere/delta-T", "fcs/mixture-cmd-norm", "fcs/flap-cmd-norm",
                      "propulsion/engine/blade-angle", "propulsion/engine/constant-speed-mode",
                      "fcs/advance-cmd-norm")


# --------------------------------------------------------------------------- atmosphere
def set_atmosphere(fdm, pressure_alt_ft: float, temperature_k: float) -> float:
    """Geometric altitude and temperature bias giving this pressure altitude and temperature;
    returns the geometric altitude [ft].

    JSBSim's temperature bias shifts the whole profile, which changes the pressure at a
    given height: solve (troposphere, closed form on geopotential height, then a
    correction against JSBSim's own pressure altitude).
    """
    hp_m = pressure_alt_ft * FT
    t_std = isa_at_ft(pressure_alt_ft)[0]
    dT = temperature_k - t_std                       # bias of the whole profile [K]
    # geopotential height where the biased profile has the pressure of hp
    h_gp = hp_m * (T0 + dT) / T0 if hp_m < 11000 else hp_m + dT / LAPSE
    h_gp_ft = h_gp / FT
    h_geo = R_EARTH_FT * h_gp_ft / (R_EARTH_FT - h_gp_ft)
    fdm["atmosphere/delta-T"] = dT * 1.8
    for _ in range(4):
        fdm["ic/h-sl-ft"] = h_geo
        fdm.run_ic()
        err = fdm["atmosphere/pressure-altitude"] - pressure_alt_ft
        if abs(err) < 0.05:
            break
        h_geo -= err * (T0 + dT) / T0
    return h_geo


def flap_max_deg(geometry: AircraftGeometry) -> float:
    f = geometry.wing.control("flap")
    return math.degrees(f.deflection_max_rad) if f else 1.0


# --------------------------------------------------------------------------- the problem
@dataclass
class _Equilibrium:
    """The trim unknowns of one condition and their residual: x = (alpha, beta, throttle or
    pitch attitude or speed ratio, elevator, aileron, rudder commands[, blade angle])."""

    sim: object
    cond: Condition
    V0: float                 # [ft/s] true airspeed of the condition
    phi: float                # [rad] bank
    rpm_set: float | None     # governor setting (a constant-speed propeller), else None

    def __post_init__(self):
        # the property nodes a residual sets and reads (one JSBSim for the whole trim)
        self.state_nodes, self.accel_nodes = self.sim.nodes(STATE), self.sim.nodes(ACCELS)

    @property
    def full(self) -> bool:
        return self.cond.mode == "full_throttle"

    @property
    def speed_free(self) -> bool:
        return self.cond.mode == "level_full_throttle"

    @property
    def governed(self) -> bool:
        return self.rpm_set is not None

    def blade(self, x) -> float:
        cs = self.sim.geometry.propeller
        return min(max(x[6], cs.min_pitch_deg), cs.max_pitch_deg)

    def set_state(self, x) -> None:
        cond, phi = self.cond, self.phi
        a, b = x[0], x[1]
        V = self.V0 * x[2] if self.speed_free else self.V0
        omega = G_FT * math.tan(phi) / V if cond.turn == "coordinated" else 0.0
        if self.full:
            th, thr = x[2], cond.throttle
        else:
            thr = cond.throttle if self.speed_free else x[2]
            gamma = math.asin(max(-1.0, min(1.0, cond.vs_fpm / 60.0 / V)))
            ca, cb = math.cos(a) * math.cos(b), math.sin(b) * math.sin(phi) + math.sin(a) * math.cos(b) * math.cos(phi)
            th = math.atan2(cb, ca) + math.asin(max(-1.0, min(1.0, math.sin(gamma) / math.hypot(ca, cb))))
        values = (phi, th, 0.0,                                                 # STATE, in its order
                  V * math.cos(a) * math.cos(b), V * math.sin(b), V * math.sin(a) * math.cos(b),
                  -omega * math.sin(th), omega * math.sin(phi) * math.cos(th), omega * math.cos(phi) * math.cos(th),
                  min(max(thr, 0.0), 1.0),
                  # beyond the throttle stops a thrust aid along the thrust line keeps the
                  # residual continuous (sandbox only): TRIM_AID_LBF per unit of throttle
                  TRIM_AID_LBF * (min(thr, 0.0) + max(thr - 1.0, 0.0)),
                  x[3], x[4], x[5])
        for node, v in zip(self.state_nodes, values):
            node.set_double_value(v)
        fdm = self.sim.fdm
        if self.governed:
            fdm["propulsion/engine/blade-angle"] = self.blade(x)
        fdm.run_ic()
        fdm.get_propulsion().get_steady_state()
        fdm.run()

    def residual(self, x) -> np.ndarray:
        self.sim.evals += 1
        self.set_state(x)
        r = np.array([node.get_double_value() for node in self.accel_nodes]) / ACCEL_SCALE
        if self.governed:
            # past a pitch stop the blade stays on the stop and the unknown measures the
            # RPM the governor cannot hold (under-speed on the fine stop, over-speed on the coarse)
            beyond = x[6] - self.blade(x)
            r = np.append(r, (self.sim.fdm["propulsion/engine/engine-rpm"] - self.rpm_set) / 100.0 - beyond / 10.0)
        if not all(map(math.isfinite, r.tolist())):
            return np.full(len(x), 1e3)
        # keep the solver inside the physical ranges: continue the residual linearly past them
        excess = max(0.0, abs(x[3]) - 1) + max(0.0, abs(x[4]) - 1) + max(0.0, abs(x[5]) - 1)
        return r + 10.0 * excess * np.sign(r + 1e-12)

    def cold_start(self, p_amb: float, t_std: float, T: float) -> np.ndarray:
        """A start from the lift the weight needs at the condition's dynamic pressure."""
        cond, V = self.cond, self.V0
        q = 0.5 * 0.0023769 * (V**2) * (p_amb / 101325.0) * (t_std / T) / (t_std / 288.15)
        S = self.sim.geometry.reference.wing_area_m2 / FT**2
        cl = cond.weight_lb / max(q * S, 1e-6)
        a0 = max(-0.1, min(0.25, (cl - 0.25 - 0.02 * cond.flaps_deg) / 4.8))
        cold = np.array([a0, 0.0, a0 + 0.08 if self.full else (1.0 if self.speed_free else 0.65), 0.0, 0.0, 0.0])
        if self.governed:
            cs = self.sim.geometry.propeller
            cold = np.append(cold, 0.5 * (cs.min_pitch_deg + cs.max_pitch_deg))
        return cold


def _prepare(sim, cond: Condition) -> tuple[_Equilibrium, float, float]:
    """Loading, atmosphere, mixture, flaps and governor of the condition; the problem, its
    mixture command and its ambient pressure [Pa]. Raises :class:`TrimError` for a loading
    that cannot be reached."""
    fdm = sim.fdm
    sim.set_loading(cond.weight_lb, cond.cg_in, cond.fuel_fraction)
    T = cond.temperature_k()
    set_atmosphere(fdm, cond.pressure_alt_ft, T)
    p_amb = isa_at_ft(cond.pressure_alt_ft)[1]
    if isinstance(cond.mixture, str):
        mix = poh_mixture(p_amb, climb=cond.mixture == "climb",
                          full_rich_below_m=sim.geometry.engine.full_rich_below_m)
    else:
        mix = float(cond.mixture)
    fdm["fcs/mixture-cmd-norm"] = mix
    fdm["fcs/flap-cmd-norm"] = cond.flaps_deg / max(1e-9, flap_max_deg(sim.geometry))
    V = cond.true_airspeed_kt() * KT / FT
    cs = sim.geometry.propeller
    rpm_set = None
    if cs.constant_speed:
        # an ideal governor: the blade angle is a trim unknown that holds the set RPM
        rpm_set = min(cs.max_rpm, max(cs.min_rpm, cond.rpm if cond.rpm is not None else cs.max_rpm))
        fdm["propulsion/engine/constant-speed-mode"] = 0.0
        fdm["fcs/advance-cmd-norm"] = (rpm_set - cs.min_rpm) / max(1.0, cs.max_rpm - cs.min_rpm)
    return _Equilibrium(sim, cond, V, math.radians(cond.bank_deg), rpm_set), mix, p_amb


# --------------------------------------------------------------------------- solving
def _jacobian(residual, x, fx, h=1e-5):
    J = np.empty((len(fx), len(x)))
    for i in range(len(x)):
        xi = np.array(x, float)
        xi[i] += h
        J[:, i] = (residual(xi) - fx) / h
    return J


def _warm_start(problem: _Equilibrium, cached) -> tuple[tuple, int]:
    """Newton steps with the Jacobian kept from the last trim of this point (factored once:
    ``cached`` is (x, :func:`_factored` J)), each step shortened (1, 1/2, 1/4 of it) until it
    lowers the largest residual: the tables interpolate linearly and the throttle has stops, so
    a full step from a kept Jacobian can cross a kink that a shorter one does not (without the
    shorter steps, 45 % of the level trims fell back to ``hybr``). Returns (x, norm, the
    factored J) and the evaluations."""
    x, lu = np.array(cached[0], float), cached[1]
    fx = problem.residual(x)
    nfev = 1
    for _ in range(NEWTON_STEPS):
        norm = _largest(fx)
        if norm < NEWTON_TOL or lu is None:        # converged, or a singular Jacobian: no step
            break
        d = numerics.lu_solve(lu, fx)             # not np.linalg: the same bits on every CPU
        for share in NEWTON_SHARES:
            x_new = x - share * d
            f_new = problem.residual(x_new)
            nfev += 1
            if _largest(f_new) < norm:
                break
        else:
            break
        x, fx = x_new, f_new
    return (x, _largest(fx), lu), nfev


def _factored(J: np.ndarray):
    """J as the Newton steps use it (:func:`numerics.lu_factor`), or None where it is singular."""
    try:
        return numerics.lu_factor(J)
    except numerics.SingularMatrixError:
        return None


def _largest(r: np.ndarray) -> float:
    """The largest absolute residual (a residual is finite: :meth:`_Equilibrium.residual`)."""
    return max(map(abs, r.tolist()))


def _solve(problem: _Equilibrium, starts: list) -> tuple[tuple, int]:
    """``hybr`` from each start until one reaches an equilibrium: the best (x, norm, factored J), evaluations."""
    best, nfev = None, 0
    for x0 in starts:
        # finite-difference steps of 1e-4 (relative, absolute near 0): well above the
        # engine steady-state noise, well below the scale of the solution
        sol = root(problem.residual, x0, method="hybr", options={"xtol": 1e-10, "maxfev": 300, "eps": 1e-8})
        nfev += sol.nfev
        x = sol.x if np.all(np.isfinite(sol.x)) else x0
        fx = problem.residual(x)
        nfev += 1
        norm = _largest(fx)
        J = _jacobian(problem.residual, x, fx)
        nfev += 6
        if best is None or norm < best[1]:
            best = (x, norm, _factored(J))
        if norm < EQUILIBRIUM_TOL:
            break
    return best, nfev


def _result(problem: _Equilibrium, x, nfev: int, mix: float, T: float) -> TrimResult:
    """The trimmed state (left in JSBSim), with the reasons it does not count as trimmed."""
    sim, cond = problem.sim, problem.cond
    fdm = sim.fdm
    r = problem.residual(x)          # leaves the trimmed state in JSBSim
    res = _largest(r)
    out = TrimResult(cond, True, residual=res, evals=nfev + 1)
    shown = tuple(sim.indicated.get(k, p) for k, p in OUTPUTS.items())      # as an instrument shows it, where defined
    for k, node in zip(OUTPUTS, sim.nodes(shown)):
        setattr(out, k, node.get_double_value())
    out.throttle = cond.throttle if (problem.full or problem.speed_free) else float(x[2])
    out.extra["throttle_required"] = out.throttle
    out.extra["trim_aid_lbf"] = float(fdm[TRIM_AID])
    out.mixture = mix
    out.pct_power = 100.0 * out.power_hp / (sim.geometry.engine.max_power_w / HP)
    out.roc_fpm = float(fdm["velocities/h-dot-fps"]) * 60.0
    t_std = isa_at_ft(cond.pressure_alt_ft)[0]
    out.roc_pressure_fpm = out.roc_fpm * t_std / T
    out.torque_lbft = out.power_hp * 550.0 / max(out.rpm * 2 * math.pi / 60.0, 1e-6)
    problems = []
    if res > EQUILIBRIUM_TOL:
        problems.append(f"no equilibrium (residual {res:.2g})")
    for i, name in ((3, "elevator"), (4, "aileron"), (5, "rudder")):
        if abs(x[i]) > CONTROL_LIMIT:
            problems.append(f"{name} beyond its stop ({x[i]:+.2f} of travel)")
    if problem.governed:
        cs = sim.geometry.propeller
        out.extra["blade_angle_deg"] = float(problem.blade(x))
        out.extra["governor"] = ("fine stop" if x[6] < cs.min_pitch_deg - 1e-6 else
                                 "coarse stop" if x[6] > cs.max_pitch_deg + 1e-6 else "governing")
    if cond.mode == "level" and x[2] > 1.0 + 1e-4:
        problems.append(f"needs more than full throttle ({fdm[TRIM_AID]:.0f} lbf short)")
    if cond.mode == "level" and x[2] < -1e-4:
        problems.append("needs less than idle throttle")
    if not math.isfinite(out.rpm) or out.rpm < 100:
        problems.append("engine not running")
    if problems:
        out.trimmed = False
        out.reason = "; ".join(problems)
    return out


def _trim_once(sim, cond: Condition, key=None) -> TrimResult:
    """One trim at the condition's airspeed as given."""
    sim.trims += 1
    try:
        problem, mix, p_amb = _prepare(sim, cond)
    except TrimError as exc:
        return TrimResult(cond, False, str(exc))
    T = cond.temperature_k()
    sim.fdm.suspend_integration()
    best, nfev = None, 0
    cached = sim.trim_cache.get(key) if key is not None else None
    if cached is not None:
        best, nfev = _warm_start(problem, cached)
    if best is None or best[1] > NEWTON_TOL:
        cold = problem.cold_start(p_amb, isa_at_ft(cond.pressure_alt_ft)[0], T)
        found, n = _solve(problem, ([best[0]] if best is not None else []) + [cold])
        nfev += n
        if best is None or found[1] < best[1]:
            best = found
    x, _, lu = best
    out = _result(problem, x, nfev, mix, T)
    sim.fdm[TRIM_AID] = 0.0
    if not out.trimmed:
        _recover(sim)
    elif key is not None:
        sim.trim_cache[key] = (x.copy(), lu)       # the next warm start: the point and its Jacobian, factored
    return out


def _recover(sim) -> None:
    """After a failed trim: clear NaN from the engine state before the next point (a JSBSim
    that a reset may not bring back to a fresh load's bits: the next fresh start loads anew)."""
    fdm = sim.fdm
    if not all(math.isfinite(fdm[p]) for p in ("propulsion/engine/engine-rpm", "propulsion/engine/map-inhg")):
        sim.distrust()
        fdm.reset_to_initial_conditions(0)
        fdm["propulsion/set-running"] = -1
        fdm.set_trim_status(True)


# --------------------------------------------------------------------------- the public trims
def trim(sim, cond: Condition, key=None) -> TrimResult:
    """Trim to a condition. ``key`` identifies the point for warm starts.

    Where the aircraft defines a pitot-static position error (``velocities/position-
    error-kts``, measured minus true, in calibrated knots), the condition's airspeed is
    the measured one: the trim is repeated at the true speed that shows it."""
    if not sim.has_position_error:
        return _trim_once(sim, cond, key)
    if cond.mode == "level_full_throttle":          # speed free: report the measured speed
        t = _trim_once(sim, cond, key)
        err = float(sim.fdm[POSITION_ERROR])
        t.extra["position_error_kt"] = err
        t.ktas += err * t.ktas / max(t.kcas, 1e-6)
        t.kcas += err
        return t
    measured = cond.ktas if cond.ktas is not None else cond.kcas
    c, t, err = cond, None, 0.0
    for _ in range(8):
        t = _trim_once(sim, c, key)
        if not t.trimmed:
            break
        err = float(sim.fdm[POSITION_ERROR])
        scale = t.ktas / max(t.kcas, 1e-6) if cond.ktas is not None else 1.0
        want = measured - err * scale
        now = c.ktas if cond.ktas is not None else c.kcas
        if abs(want - now) < 0.005:
            break
        c = replace(cond, ktas=want) if cond.ktas is not None else replace(cond, kcas=want)
    t.condition = cond
    t.extra["position_error_kt"] = err
    return t


def trim_at_stop(sim, cond: Condition, key=None) -> TrimResult:
    """A level or climbing point flown at full throttle instead: a climb
    (``vs_fpm`` > :data:`CLIMB_VS_FPM`) keeps its speed and lets the rate of climb go
    free; level flight keeps the flight path and lets the speed go free."""
    if cond.vs_fpm > CLIMB_VS_FPM:
        c = replace(cond, mode="full_throttle", throttle=1.0)
    else:
        c = replace(cond, mode="level_full_throttle", throttle=1.0)
    return trim(sim, c, None if key is None else (key, "full throttle"))


def trim_level(sim, cond: Condition, key=None, speed_tolerance_kt: float = 3.0,
               vs_tolerance_fpm: float = 100.0) -> TrimResult:
    """Level (or steadily climbing) point; when it needs more than full throttle, flown at
    full throttle instead (:func:`trim_at_stop`), accepted if the speed reached is within
    ``speed_tolerance_kt`` of the data (Part 60 airspeed tolerance) or, for a climb, the
    rate of climb within ``vs_tolerance_fpm`` (Part 60 climb tolerance); reported with
    the shortfall."""
    t = trim(sim, cond, key)
    if t.trimmed or not t.reason.startswith("needs more than full throttle") or ";" in t.reason:
        return t
    ft = trim_at_stop(sim, cond, key)
    if not ft.trimmed:
        return t
    ft.condition = cond
    if cond.vs_fpm > CLIMB_VS_FPM:
        short = cond.vs_fpm - ft.roc_fpm
        ft.extra["vs_shortfall_fpm"] = short
        ok, what = short <= vs_tolerance_fpm, f"{ft.roc_fpm:.0f} ft/min, {short:.0f} ft/min"
    else:
        want = cond.ktas if cond.ktas is not None else t.ktas
        short = want - ft.ktas
        ft.extra["ktas_shortfall"] = short
        ok, what = short <= speed_tolerance_kt, f"{ft.ktas:.1f} kt, {short:.1f} kt"
    if not ok:
        ft.trimmed = False
        ft.reason = f"full throttle reaches {what} short"
    else:
        ft.reason = f"at full throttle: {what} short of the data"
    return ft
