"""Build the aerodynamic tables of an aircraft from its geometry by strip theory.

The chain (each step a function, all in SI):

1. ``wing_tables``      wing strips over angle of attack and the calibration shift of the
                        section angle (method eq. 3.1-3.5): CL_w, CD0_w, CDi_w, Cm_w.
2. ``flap_tables``      increments of the flapped wing, and the wing downwash at the tail.
3. ``tail_tables``      horizontal tail and elevator versus the local tail angle.
4. ``lateral_tables``   sideslip, roll/yaw-rate and aileron/rudder effects of the whole
                        configuration (wing + tails) by differences of the strip model.
5. ``body_tables``      fuselage and drag items (empirical, :mod:`.body`).

``build_aero`` runs them in order and returns an :class:`AeroModel`: named tables and
constants that :mod:`jsbsim_calib.jsbsim.aircraft` writes into the aircraft file.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..atmosphere import density, isa_pressure, isa_temperature, viscosity
from ..geometry import AircraftGeometry
from ..slipstream import FREE_VORTEX, TC_GRID, TailGeometry, disc_area_m2, immersion_tables
from ...core.units import FT, G0
from . import body
from .lifting_line import freestream_dir, influence
from .sections import dcm_ddelta, eta_deflection, profile_drag_increment
from .strips import StripModel, wind_to_coeffs

# Half-degree steps where aircraft trim (-6 to 20 deg): JSBSim interpolates tables linearly, and
# the slope jumps at the breakpoints make the calibration's cost rugged (README, "Reproducible fits")
ALPHA_DEG = np.concatenate([[-90, -60, -45, -30, -25, -20, -18, -16, -14, -12, -10, -8], np.arange(-6.0, 20.01, 0.5),
                            [21, 22, 23, 24, 25, 27, 30, 35, 40, 45, 60, 90]]).astype(float)
SHIFT_DEG = np.array([-6.0, -4.5, -3.0, -1.5, 0.0, 1.5, 3.0, 4.5, 6.0])
LAT_ALPHA_DEG = np.array([-10, -5, 0, 2, 4, 6, 8, 10, 12, 14, 16, 18, 20, 24, 30], float)
ALPHA_H_DEG = np.array([-90, -45, -30, -25, -20, -18, -16, -14, -12, -10, -8, -6, -4, -2, 0, 2, 4, 6, 8, 10, 12,
                        14, 16, 18, 20, 25, 30, 45, 90], float)
REFERENCE_ALTITUDE_M = 5000 * FT      # Reynolds numbers are those of 1-g flight here, at max weight


@dataclass(frozen=True)
class Table:
    """A lookup table over one or two named breakpoint axes (degrees unless stated)."""

    row_name: str
    row: np.ndarray
    data: np.ndarray
    description: str
    col_name: str | None = None
    col: np.ndarray | None = None


@dataclass
class AeroModel:
    """Named tables and constants of the aerodynamic model (coefficients on S_ref)."""

    S_m2: float
    b_m: float
    cbar_m: float
    aerorp_m: np.ndarray               # structural frame
    tables: dict[str, Table] = field(default_factory=dict)
    constants: dict[str, tuple[float, str]] = field(default_factory=dict)

    def const(self, name: str) -> float:
        return self.constants[name][0]

    def add_const(self, name: str, value: float, doc: str) -> None:
        self.constants[name] = (float(value), doc)


def reference_speed(geom: AircraftGeometry, CL: np.ndarray) -> np.ndarray:
    """Speed of 1-g flight [m/s] at max weight and the reference altitude for a lift coefficient."""
    h = REFERENCE_ALTITUDE_M
    rho = density(isa_pressure(h), isa_temperature(h))
    CLc = np.clip(CL, 0.15, None)
    return np.sqrt(2.0 * geom.mass.max_mass_kg * G0 / (rho * geom.reference.wing_area_m2 * CLc))


CRUISE_CL = 0.4     # lift coefficient of the reference cruise speed (tails, fuselage Reynolds number)


def _reference_air():
    h = REFERENCE_ALTITUDE_M
    t = isa_temperature(h)
    return float(density(isa_pressure(h), t)), float(viscosity(t))


def _coeffs(sm: StripModel, sol, geom: AircraftGeometry, mask=None):
    F, M = sm.loads(sol, mask)
    return wind_to_coeffs(F, M, sol.alpha, sol.beta, geom.reference.wing_area_m2, geom.reference.span_m, geom.cbar_m)


def _sweep(sm: StripModel, geom: AircraftGeometry, alphas_deg: np.ndarray, controls: dict | None = None,
           omega=(0.0, 0.0, 0.0), beta: float = 0.0, reynolds_from_lift: bool = True):
    """Solve the strip model over angles of attack (continuation from 0 outwards).

    Reynolds numbers follow the 1-g speed for the lift found (two passes).
    Returns the list of solutions in the order of ``alphas_deg``.
    """
    rho, mu = _reference_air()
    order = np.argsort(np.abs(alphas_deg - 2.0), kind="stable")
    sols: dict[int, object] = {}
    prev_pos = prev_neg = None
    for idx in order:
        a = math.radians(alphas_deg[idx])
        g0 = prev_pos if alphas_deg[idx] >= 2.0 else prev_neg
        cl_est = 0.1 + 4.8 * (a + 0.03)
        for _ in range(2 if reynolds_from_lift else 1):
            if reynolds_from_lift:
                sm.set_reynolds(float(reference_speed(geom, np.array(cl_est))), rho, mu)
            sol = sm.solve(a, beta, omega, controls, gamma0=g0)
            if not sol.converged:
                # past the stall: try the linear start too and keep the better solution
                alt = sm.solve(a, beta, omega, controls, gamma0=None)
                if alt.converged or alt.residual < sol.residual:
                    sol = alt
            cl_est = _coeffs(sm, sol, geom)["CL"]
        sols[idx] = sol
        if sol.converged:
            if alphas_deg[idx] >= 2.0:
                prev_pos = sol.gamma
            else:
                prev_neg = sol.gamma
    return [sols[i] for i in range(len(alphas_deg))]


# --------------------------------------------------------------------------- 1. wing
def wing_tables(geom: AircraftGeometry, airfoils: dict, model: AeroModel, n_half: int = 24) -> StripModel:
    """Wing coefficients versus alpha and the section-angle shift (method eq. 3.1-3.5).

    For each strip: cl, cd = polar(alpha_eff + shift); in global wind axes
    cl_w = cl cos(ai) - cd sin(ai), cd_0 = cd cos(ai), cd_i = cl sin(ai).
    """
    ref = model.aerorp_m
    sm = StripModel(geom, airfoils, (geom.wing,), ref, n_half)
    st = sm.strips
    S, c = model.S_m2, model.cbar_m
    sols = _sweep(sm, geom, ALPHA_DEG)
    rho, mu = _reference_air()
    nA, nS = len(ALPHA_DEG), len(SHIFT_DEG)
    CL = np.zeros((nA, nS)); CD0 = np.zeros((nA, nS)); CDi = np.zeros((nA, nS)); CM = np.zeros((nA, nS))
    cos_dih = np.abs(st.e_span[:, 1])          # lift of a strip with dihedral tilts by the dihedral
    area = st.area
    delta = np.zeros(st.n)
    re_per_m = np.zeros(nA)
    for i, sol in enumerate(sols):
        CLlin = _coeffs(sm, sol, geom)["CL"]
        v_ref = float(reference_speed(geom, np.array(CLlin)))
        re_per_m[i] = rho * v_ref / mu
        sm.set_reynolds(v_ref, rho, mu)
        ai = sol.alpha_ind
        for j, s in enumerate(np.radians(SHIFT_DEG)):
            cl, cd, cm = sm.sections(sol.alpha_eff + s, delta)
            cd_p = np.where(st.profile, cd, 0.0)
            clw = cl * np.cos(ai) - cd_p * np.sin(ai)
            CL[i, j] = np.sum(clw * cos_dih * area) / S
            CD0[i, j] = np.sum(cd_p * np.cos(ai) * area) / S
            CDi[i, j] = np.sum(cl * np.sin(ai) * area) / S
            CM[i, j] = np.sum(cm * st.chord * area) / (S * c)
    model.tables["wing_CL"] = Table("alpha", ALPHA_DEG, CL, "wing lift (wind axes), strips at alpha_eff + shift",
                                    "shift", SHIFT_DEG)
    model.tables["wing_CD0"] = Table("alpha", ALPHA_DEG, CD0, "wing profile drag", "shift", SHIFT_DEG)
    model.tables["wing_CDi"] = Table("alpha", ALPHA_DEG, CDi, "wing induced drag", "shift", SHIFT_DEG)
    model.tables["wing_Cm"] = Table("alpha", ALPHA_DEG, CM, "wing section pitching moment (sum of strip cm)",
                                    "shift", SHIFT_DEG)
    model.tables["wing_Re"] = Table("alpha", ALPHA_DEG, re_per_m * FT,
                                    "Reynolds number per foot at which the wing tables were built (1-g flight "
                                    "at max weight, reference altitude)")
    model.add_const("wing_area_ratio", np.sum(area) / S, "wing strip area / S_ref (weight of K_cl_offset)")
    model.add_const("wing_profile_ratio", np.sum(area[st.profile]) / S,
                    "wing strips with profile drag / S_ref (weight of K_cd0_offset)")
    model.add_const("wing_cm_ratio", np.sum(area * st.chord) / (S * c), "sum(c dS)/(S cbar) (weight of K_cm_offset)")
    # lift-weighted station of the strip quarter chords (moment arm of the wing lift)
    i4 = int(np.argmin(np.abs(ALPHA_DEG - 4.0)))
    f = sm.strip_forces(sols[i4])
    lift = -f[:, 2]
    x_arm = -np.sum(st.point[:, 0] * lift) / np.sum(lift)          # structural (aft +) offset from AERORP
    model.add_const("wing_arm_x", x_arm, "station of the wing lift behind the AERORP [m] (structural x)")
    return sm


# --------------------------------------------------------------------------- 2. flaps
def flap_tables(geom: AircraftGeometry, airfoils: dict, model: AeroModel, n_half: int = 24) -> None:
    """Flap increments on the wing and the wing downwash at the horizontal tail."""
    flap = geom.wing.control("flap")
    ref = model.aerorp_m
    S, c = model.S_m2, model.cbar_m
    sm = StripModel(geom, airfoils, (geom.wing,), ref, n_half)
    ht = StripModel(geom, airfoils, (geom.horizontal_tail,), ref, n_half // 2).strips
    flaps_deg = np.array([0.0]) if flap is None else np.unique(np.round(np.concatenate([
        np.linspace(math.degrees(flap.deflection_min_rad), math.degrees(flap.deflection_max_rad), 7),
        np.degrees(flap.detents_rad)]), 3))
    nA, nF = len(ALPHA_DEG), len(flaps_deg)
    out = {k: np.zeros((nA, nF)) for k in ("CL", "CD0", "CDi", "Cm")}
    eps = np.zeros((nA, nF))
    st = sm.strips
    cos_dih = np.abs(st.e_span[:, 1])
    for k, fd in enumerate(flaps_deg):
        sols = _sweep(sm, geom, ALPHA_DEG, controls={"flap": math.radians(fd)})
        for i, sol in enumerate(sols):
            ai = sol.alpha_ind
            cd_p = np.where(st.profile, sol.cd, 0.0)
            out["CL"][i, k] = np.sum((sol.cl * np.cos(ai) - cd_p * np.sin(ai)) * cos_dih * st.area) / S
            out["CD0"][i, k] = np.sum(cd_p * np.cos(ai) * st.area) / S
            out["CDi"][i, k] = np.sum(sol.cl * np.sin(ai) * st.area) / S
            F, M = sm.loads(sol)
            out["Cm"][i, k] = M[1] / (0.5 * S * c)
            # downwash: mean angle induced by the wing vortices at the tail strips
            # the wake is a sheet of finite thickness: smooth it over 10 % of the wing chord
            V = influence(st, ht.point, freestream_dir(sol.alpha, 0.0), 0.1 * c)
            w = np.einsum("ijk,j->ik", V, sol.gamma)
            wn = -np.sum(w * ht.e_normal, 1)         # positive: downwash (reduces tail angle)
            eps[i, k] = math.degrees(np.sum(wn * ht.area) / np.sum(ht.area))
    for key in ("CL", "CD0", "CDi", "Cm"):
        model.tables[f"flap_d{key}"] = Table("alpha", ALPHA_DEG, out[key] - out[key][:, :1],
                                             f"flap increment of wing {key}", "flap", flaps_deg)
    model.tables["downwash"] = Table("alpha", ALPHA_DEG, eps, "wing downwash at the horizontal tail [deg]",
                                     "flap", flaps_deg)
    i0, i1 = np.searchsorted(ALPHA_DEG, [0.0, 6.0])
    model.add_const("deps_dalpha", (eps[i1, 0] - eps[i0, 0]) / (ALPHA_DEG[i1] - ALPHA_DEG[i0]),
                    "downwash gradient at the tail, clean [-]")
    # per-degree estimates that give the flap calibration factors a physical size (eq. 3.42/3.44)
    if flap is not None:
        on = sm.ctrl == "flap"
        dmax = flap.deflection_max_rad
        dcd = profile_drag_increment(dmax, flap.chord_fraction, flap.kind) / math.degrees(dmax)
        dcm = dcm_ddelta(flap.chord_fraction) * eta_deflection(dmax, flap.kind) * math.pi / 180.0
        model.add_const("flap_dcd0_per_deg", dcd * np.sum(st.area[on]) / S,
                        "flap profile-drag estimate per degree, on S_ref (scaled by K_dcd0_flaps)")
        model.add_const("flap_dcm_per_deg", dcm * np.sum(st.area[on] * st.chord[on]) / (S * c),
                        "flap section pitching-moment estimate per degree (scaled by K_dcm_flaps)")
    else:
        model.add_const("flap_dcd0_per_deg", 0.0, "no flaps")
        model.add_const("flap_dcm_per_deg", 0.0, "no flaps")


# --------------------------------------------------------------------------- 3. tail
def tail_tables(geom: AircraftGeometry, airfoils: dict, model: AeroModel, eta: float, n_half: int = 16) -> None:
    """Horizontal tail alone versus its local angle of attack and the elevator."""
    ht = geom.horizontal_tail
    ref = model.aerorp_m
    S, c = model.S_m2, model.cbar_m
    sm = StripModel(geom, airfoils, (ht,), ref, n_half)
    st = sm.strips
    elev = ht.control("elevator")
    de = np.unique(np.concatenate([np.linspace(math.degrees(elev.deflection_min_rad),
                                               math.degrees(elev.deflection_max_rad), 12), [0.0]]))
    nA, nE = len(ALPHA_H_DEG), len(de)
    tab = {k: np.zeros((nA, nE)) for k in ("CL", "CD0", "CDi", "Cm")}
    rho, mu = _reference_air()
    sm.set_reynolds(float(reference_speed(geom, np.array(CRUISE_CL))), rho, mu)
    for k, d in enumerate(de):
        sols = _sweep(sm, geom, ALPHA_H_DEG, controls={"elevator": math.radians(d)}, reynolds_from_lift=False)
        for i, sol in enumerate(sols):
            ai = sol.alpha_ind
            cd_p = np.where(st.profile, sol.cd, 0.0)
            tab["CL"][i, k] = np.sum((sol.cl * np.cos(ai) - cd_p * np.sin(ai)) * st.area) / S
            tab["CD0"][i, k] = np.sum(cd_p * np.cos(ai) * st.area) / S
            tab["CDi"][i, k] = np.sum(sol.cl * np.sin(ai) * st.area) / S
            tab["Cm"][i, k] = np.sum(sol.cm * st.chord * st.area) / (S * c)
    k0 = int(np.argmin(np.abs(de)))
    for key in ("CL", "CD0", "CDi", "Cm"):
        model.tables[f"ht_{key}"] = Table("alpha_h", ALPHA_H_DEG, tab[key][:, k0],
                                          f"horizontal tail {key} on S_ref (local tail angle)")
    model.tables["elev_dCL"] = Table("alpha_h", ALPHA_H_DEG, tab["CL"] - tab["CL"][:, k0:k0 + 1],
                                     "elevator lift increment on S_ref", "elevator", de)
    model.tables["elev_dCD"] = Table("alpha_h", ALPHA_H_DEG, (tab["CD0"] + tab["CDi"]) - (tab["CD0"] + tab["CDi"])[:, k0:k0 + 1],
                                     "elevator drag increment on S_ref", "elevator", de)
    model.tables["elev_dCm"] = Table("alpha_h", ALPHA_H_DEG, tab["Cm"] - tab["Cm"][:, k0:k0 + 1],
                                     "elevator section pitching-moment increment", "elevator", de)
    x_ac = ht.x_quarter_mac_m
    model.add_const("ht_arm_x", x_ac - ref[0], "horizontal tail quarter chord behind the AERORP [m]")
    model.add_const("ht_arm_z", ht.z_mean_m - ref[2], "horizontal tail height above the AERORP [m]")
    model.add_const("ht_eta", eta, "dynamic-pressure ratio at the horizontal tail [-]")
    model.add_const("ht_area_ratio", ht.area_m2 / S, "S_ht / S_ref")
    model.add_const("ht_profile_ratio", np.sum(st.area[st.profile]) / S, "tail strips with profile drag / S_ref")
    on = sm.ctrl == "elevator"
    model.add_const("elevator_span", np.sum(st.width[on]), "elevator span, both sides [m]")


# --------------------------------------------------------------------------- 4. lateral
def lateral_tables(geom: AircraftGeometry, airfoils: dict, model: AeroModel, eta: float, n_half: int = 20) -> None:
    """Sideslip, rate and lateral-control effects of wing + tails by central differences."""
    ref = model.aerorp_m
    S, b, c = model.S_m2, model.b_m, model.cbar_m
    surfaces = (geom.wing, geom.horizontal_tail, geom.vertical_tail)
    sm = StripModel(geom, airfoils, surfaces, ref, n_half,
                    dynamic_pressure_ratio={"horizontal_tail": eta, "vertical_tail": eta})
    wing_only = sm.strips.surface == "wing"
    fin_only = sm.strips.surface == "vertical_tail"
    names = ["CY_beta", "Cl_beta", "Cn_beta", "CY_p", "Cl_p", "Cn_p", "CY_r", "Cl_r", "Cn_r", "CL_q", "Cm_q"]
    out = {k: np.zeros(len(LAT_ALPHA_DEG)) for k in names}
    fin = {f"vt_{k}_beta": np.zeros(len(LAT_ALPHA_DEG)) for k in ("CY", "Cl", "Cn")}
    ail = geom.wing.control("aileron")
    rud = geom.vertical_tail.control("rudder")
    da = np.linspace(math.degrees(ail.deflection_min_rad), math.degrees(ail.deflection_max_rad), 9) if ail else np.zeros(1)
    da = np.unique(np.concatenate([da, [0.0]]))
    dr = np.linspace(math.degrees(rud.deflection_min_rad), math.degrees(rud.deflection_max_rad), 9) if rud else np.zeros(1)
    dr = np.unique(np.concatenate([dr, [0.0]]))
    ail_t = {k: np.zeros((len(LAT_ALPHA_DEG), len(da))) for k in ("Cl", "Cn", "CY", "CD")}
    rud_t = {k: np.zeros((len(LAT_ALPHA_DEG), len(dr))) for k in ("Cl", "Cn", "CY", "CD")}
    base = _sweep(sm, geom, LAT_ALPHA_DEG)
    db = math.radians(1.0)
    dp = 0.02
    for i, sol0 in enumerate(base):
        a = sol0.alpha
        g0 = sol0.gamma

        def co(beta=0.0, omega=(0.0, 0.0, 0.0), controls=None, mask=None):
            s = sm.solve(a, beta, omega, controls, gamma0=g0)
            return _coeffs(sm, s, geom, mask)

        cp, cm_ = co(beta=db), co(beta=-db)
        for k in ("CY", "Cl", "Cn"):
            out[f"{k}_beta"][i] = (cp[k] - cm_[k]) / (2 * db)
        cp, cm_ = co(beta=db, mask=fin_only), co(beta=-db, mask=fin_only)
        for k in ("CY", "Cl", "Cn"):           # the fin alone: what a sidewash at the fin does (swirl)
            fin[f"vt_{k}_beta"][i] = (cp[k] - cm_[k]) / (2 * db)
        for rate, axis, ref_len in (("p", 0, b), ("r", 2, b)):
            om = np.zeros(3)
            om[axis] = 2.0 * dp / ref_len
            cp, cm_ = co(omega=om), co(omega=-om)
            for k in ("CY", "Cl", "Cn"):
                out[f"{k}_{rate}"][i] = (cp[k] - cm_[k]) / (2 * dp)
        om = np.array([0.0, 2.0 * dp / c, 0.0])
        cp, cm_ = co(omega=om, mask=wing_only), co(omega=-om, mask=wing_only)
        out["CL_q"][i] = (cp["CL"] - cm_["CL"]) / (2 * dp)
        out["Cm_q"][i] = (cp["Cm"] - cm_["Cm"]) / (2 * dp)
        c0 = co()
        for j, d in enumerate(da):
            cj = co(controls={"aileron": math.radians(d)}) if d != 0 else c0
            for k in ail_t:
                ail_t[k][i, j] = cj[k] - c0[k]
        for j, d in enumerate(dr):
            cj = co(controls={"rudder": math.radians(d)}) if d != 0 else c0
            for k in rud_t:
                rud_t[k][i, j] = cj[k] - c0[k]
    # body contributions
    out["CY_beta"] += body.fuselage_sideforce_slope_per_rad(geom)
    out["Cn_beta"] += body.fuselage_yaw_slope_per_rad(geom)
    out["Cl_beta"] += body.wing_body_dihedral_effect_per_rad(geom)
    units = {"beta": "per rad of sideslip", "p": "per unit p b/(2V)", "r": "per unit r b/(2V)",
             "q": "per unit q cbar/(2V), wing only (the tail acts through its local angle)"}
    for k, v in out.items():
        model.tables[k] = Table("alpha", LAT_ALPHA_DEG, v, f"{k} {units[k.split('_')[1]]}")
    for k, v in fin.items():
        model.tables[k] = Table("alpha", LAT_ALPHA_DEG, v, f"{k[3:]} of the fin alone, per rad of sideslip at the fin")
    for k, v in ail_t.items():
        model.tables[f"ail_d{k}"] = Table("alpha", LAT_ALPHA_DEG, v, f"aileron increment of {k}", "aileron", da)
    for k, v in rud_t.items():
        model.tables[f"rud_d{k}"] = Table("alpha", LAT_ALPHA_DEG, v, f"rudder increment of {k}", "rudder", dr)
    vt = geom.vertical_tail
    st = sm.strips
    on_vt = st.surface == "vertical_tail"
    rho, mu = _reference_air()
    sm.set_reynolds(float(reference_speed(geom, np.array(CRUISE_CL))), rho, mu)
    _, cd, _ = sm.sections(np.zeros(st.n), np.zeros(st.n))
    model.add_const("vt_CD0", eta * np.sum(cd[on_vt] * st.area[on_vt]) / S, "vertical-tail profile drag on S_ref")
    model.add_const("vt_profile_ratio", np.sum(st.area[on_vt]) / S, "vertical-tail area / S_ref")
    model.add_const("vt_arm_x", vt.x_quarter_mac_m - ref[0], "vertical tail quarter chord behind the AERORP [m]")
    model.add_const("vt_arm_z", vt.z_mean_m - ref[2], "vertical tail mean height above the AERORP [m]")
    on = sm.ctrl == "rudder"
    model.add_const("rudder_span", np.sum(st.width[on]), "rudder span [m]")
    model.add_const("rudder_arm_z", (np.sum(st.width[on] * -st.point[on, 2]) / np.sum(st.width[on])) if on.any() else 0.0,
                    "rudder mean height above the AERORP [m]")
    on = sm.ctrl == "aileron"
    y = np.abs(st.point[on, 1])
    model.add_const("aileron_moment_arm2", np.sum(st.width[on] * y) if on.any() else 0.0,
                    "sum over both ailerons of span * |y| [m^2] (roll moment of a unit circulation offset)")


# --------------------------------------------------------------------------- 5. body
def body_tables(geom: AircraftGeometry, model: AeroModel) -> None:
    rho, mu = _reference_air()
    v = float(reference_speed(geom, np.array(CRUISE_CL)))
    cd0 = body.fuselage_zero_lift_drag(geom, rho * v / mu)
    model.add_const("cruise_Re_per_ft", rho * v / mu * FT,
                    "Reynolds number per foot of the tail and fuselage drag (reference cruise)")
    a = np.radians(ALPHA_DEG)
    cn = body.fuselage_crossflow_normal_force(geom, a)
    cma = body.fuselage_pitch_slope_per_rad(geom)
    model.tables["body_CL"] = Table("alpha", ALPHA_DEG, cn * np.cos(a), "fuselage crossflow lift")
    model.tables["body_CD"] = Table("alpha", ALPHA_DEG, cd0 + cn * np.sin(a), "fuselage drag (friction + crossflow)")
    model.tables["body_Cm"] = Table("alpha", ALPHA_DEG, cma * 0.5 * np.sin(2 * a), "fuselage pitching moment (Munk-type)")
    cdi, z_items = body.drag_items(geom)
    model.add_const("fus_CD0", cd0, "fuselage zero-lift drag on S_ref")
    model.add_const("items_CD0", cdi, "gear, struts, cooling and protuberances on S_ref")
    model.add_const("items_arm_z", z_items, "drag-weighted height of the drag items above the AERORP [m]")
    model.add_const("fus_arm_z", geom.fuselage.z_axis_m - model.aerorp_m[2], "fuselage axis above the AERORP [m]")


def slipstream_geometry(geom: AircraftGeometry, torque_shape=FREE_VORTEX) -> TailGeometry:
    """The tails and the wing root relative to the propeller's thrust line; ``torque_shape``:
    the blade's (:func:`jsbsim_calib.physics.slipstream.torque_shape`), default a free vortex."""
    p = geom.propeller
    z_t = float(p.location_m[2])
    vt = geom.vertical_tail
    wing = geom.wing
    root_chord = float(np.interp(wing.fuselage_half_width_m, wing.y_m, wing.chord_m))
    return TailGeometry(radius_m=0.5 * p.diameter_m, ht_semispan_m=geom.horizontal_tail.semispan_m,
                        ht_height_m=geom.horizontal_tail.z_mean_m - z_t, fin_root_m=float(vt.z_m[0]) - z_t,
                        fin_tip_m=float(vt.z_m[-1]) - z_t, wing_height_m=float(wing.z_m[0]) - z_t,
                        wing_area_m2=geom.reference.wing_area_m2, wing_root_chord_m=root_chord,
                        fuselage_half_width_m=wing.fuselage_half_width_m, torque_shape=torque_shape)


def slipstream_tables(geom: AircraftGeometry, model: AeroModel, torque_shape=FREE_VORTEX) -> None:
    """Momentum-theory slipstream (:mod:`jsbsim_calib.physics.slipstream`): the shares of the
    horizontal tail, the fin and the wing inside it and the swirl geometry at the fin (from the
    blade's torque shape), against the disc thrust coefficient Tc."""
    g = slipstream_geometry(geom, torque_shape)
    docs = {"ht_fraction": "share of the horizontal tail span in the slipstream",
            "fin_fraction": "share of the fin height in the slipstream",
            "fin_swirl_arm": "swirl geometry s/(4 (r/R)(r_w/R)) over the immersed fin (s: the blade's torque shape): "
                             "swirl angle = Qc x this / ((1+a)(1+2a))",
            "wing_fraction": "share of the reference wing area in the slipstream (root strips)"}
    for k, v in immersion_tables(g).items():
        model.tables[f"slip_{k}"] = Table("tc", TC_GRID, v, docs[k] + " (against the disc thrust coefficient Tc)")
    model.add_const("disc_area", disc_area_m2(g.radius_m), "propeller disc area [m^2]")
    model.add_const("disc_radius", g.radius_m, "propeller radius [m]")
    model.add_const("prop_sense", float(geom.propeller.sense), "propeller rotation sense (1: clockwise from behind)")


def build_aero(geom: AircraftGeometry, airfoils: dict, *, tail_eta: float = 0.9, n_half: int = 24,
               progress=None, torque_shape=FREE_VORTEX) -> AeroModel:
    """Run the chain: slipstream, wing, flaps and downwash, tail, lateral, body (``torque_shape``:
    the propeller's, for the swirl)."""
    model = AeroModel(geom.reference.wing_area_m2, geom.reference.span_m, geom.cbar_m, geom.aero_reference_point_m)
    steps = [("slipstream", lambda: slipstream_tables(geom, model, torque_shape)),
             ("wing", lambda: wing_tables(geom, airfoils, model, n_half)),
             ("flaps", lambda: flap_tables(geom, airfoils, model, n_half)),
             ("tail", lambda: tail_tables(geom, airfoils, model, tail_eta, max(8, n_half * 2 // 3))),
             ("lateral", lambda: lateral_tables(geom, airfoils, model, tail_eta, max(12, n_half * 2 // 3))),
             ("body", lambda: body_tables(geom, model))]
    for name, fn in steps:
        if progress:
            progress(name)
        fn()
    return model
