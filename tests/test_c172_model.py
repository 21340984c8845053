"""Tests of the committed, generated C172 model with real JSBSim.

* the committed files load from the repository root and declare every calibration factor;
* plausibility of the model (lift slope, stall speeds, static and dynamic stability)
  through :mod:`jsbsim_calib.jsbsim.probes`;
* the uncalibrated (baseline) model trims at every POH climb and cruise point;
* every calibration factor moves a trimmed result in the direction its doc line states.

Sign conventions (JSBSim): elevator + trailing edge down, aileron + roll right, rudder +
trailing edge left.
"""
from __future__ import annotations

import csv
import json
import math
from pathlib import Path

import jsbsim
import pytest
from lxml import etree

from jsbsim_calib.jsbsim.aircraft import read_factors
from jsbsim_calib.jsbsim.propulsion import read_baked_factors
from jsbsim_calib.factors import FACTORS, REGISTRY, FactorSet
from jsbsim_calib.flight.condition import Condition, TrimResult
from jsbsim_calib.jsbsim.simulator import Simulator
from jsbsim_calib.jsbsim.probes import Derivatives, StallCase, report, stall_speed, trim_derivatives

REPO = Path(__file__).resolve().parents[1]
AIRCRAFT_XML = REPO / "aircraft" / "c172" / "c172.xml"
PROPELLER_XML = REPO / "engine" / "c172_propeller.xml"

# Conditions (speeds in knots, altitudes in feet)
CRUISE = Condition(5000.0, 2400.0, ktas=110.0, mode="level", mixture="cruise")
CLIMB = Condition(0.0, 2550.0, kcas=75.0, mode="full_throttle", mixture="climb")
FAST_FULL = Condition(5000.0, 2400.0, ktas=110.0, mode="full_throttle", mixture="cruise")  # J about 0.67
SLOW = Condition(3000.0, 2400.0, kcas=70.0, mode="level")
FLAPS30 = Condition(3000.0, 2400.0, kcas=65.0, flaps_deg=30.0, mode="level")
FLAPS20 = Condition(3000.0, 2400.0, kcas=65.0, flaps_deg=20.0, mode="level")
FLAPS10_CLIMB = Condition(0.0, 2550.0, kcas=70.0, flaps_deg=10.0, mode="full_throttle", mixture="climb")
BANKED = Condition(3000.0, 2400.0, kcas=90.0, bank_deg=10.0, turn="straight", mode="level")  # sideslip, aileron, rudder

# POH CG limits [in] with their weights [lb]: forward 35.0 in up to 1950 lb, 41.0 in at 2550 lb, aft 47.3 in
CG_POINTS = ((35.0, 1950.0), (41.0, 2550.0), (47.3, 2550.0))


@pytest.fixture(scope="module")
def committed():
    sim = Simulator(REPO, "c172")
    yield sim
    sim.close()


@pytest.fixture(scope="module")
def baseline_sim():
    sim = Simulator(REPO, "c172", baseline=True)
    yield sim
    sim.close()


@pytest.fixture
def baseline(baseline_sim):
    """The baseline simulator with neutral factors, restored after the test."""
    baseline_sim.set_factors(FactorSet())
    yield baseline_sim
    baseline_sim.set_factors(FactorSet())


def trimmed(sim: Simulator, cond: Condition) -> TrimResult:
    r = sim.trim(cond)
    assert r.trimmed, f"{cond} does not trim: {r.reason}"
    return r


# --------------------------------------------------------------------------- committed files
def test_committed_model_loads_and_declares_every_factor():
    fdm = jsbsim.FGFDMExec(str(REPO))
    fdm.set_debug_level(0)
    assert fdm.load_model("c172") is True
    declared = read_factors(AIRCRAFT_XML)
    tree = etree.parse(str(AIRCRAFT_XML))
    decl = {}
    for el in tree.iter("property"):
        if el.get("value") is not None:
            decl.setdefault((el.text or "").strip(), []).append(float(el.get("value")))
    pm = fdm.get_property_manager()
    problems = []
    for f in FACTORS:
        if len(decl.get(f.property, [])) != 1:
            problems.append(f"{f.name}: {len(decl.get(f.property, []))} declarations of {f.property}")
            continue
        if not pm.hasNode(f.property):
            problems.append(f"{f.name}: JSBSim has no property {f.property}")
            continue
        if not math.isclose(fdm[f.property], declared[f.name], rel_tol=1e-12, abs_tol=1e-12):
            problems.append(f"{f.name}: JSBSim {fdm[f.property]!r}, read_factors {declared[f.name]!r}")
        if not math.isclose(decl[f.property][0], declared[f.name], rel_tol=1e-12, abs_tol=1e-12):
            problems.append(f"{f.name}: XML {decl[f.property][0]!r}, read_factors {declared[f.name]!r}")
    assert not problems, "\n".join(problems)
    # the propeller tables carry the same propeller factors as the aircraft file declares
    baked = read_baked_factors(PROPELLER_XML)
    assert baked is not None
    assert {k: declared[k] for k in baked} == pytest.approx(baked, abs=1e-9)


# --------------------------------------------------------------------------- plausibility
@pytest.fixture(scope="module")
def derivatives(baseline_sim) -> dict[str, Derivatives]:
    # plausibility is required of the uncalibrated model (the strip-theory physics)
    return {"cruise": trim_derivatives(baseline_sim, CRUISE), "climb": trim_derivatives(baseline_sim, CLIMB)}


@pytest.mark.parametrize("case", ["cruise", "climb"])
def test_lift_slope(derivatives, case):
    d = derivatives[case]
    assert 4.5 <= d.CL_alpha <= 5.5, f"CL_alpha {d.CL_alpha:.3f} /rad at {case}"


@pytest.mark.parametrize("case", ["cruise", "climb"])
def test_lateral_directional_stability_and_damping(derivatives, case):
    d = derivatives[case]
    assert d.Cn_beta > 0, f"Cn_beta {d.Cn_beta:.4f} at {case}: no weathercock stability"
    assert d.Cl_beta < 0, f"Cl_beta {d.Cl_beta:.4f} at {case}: no dihedral effect"
    assert d.CY_beta < 0, f"CY_beta {d.CY_beta:.4f} at {case}"
    assert d.Cl_p < 0, f"Cl_p {d.Cl_p:.4f} at {case}: no roll damping"
    assert d.Cm_q < 0, f"Cm_q {d.Cm_q:.3f} at {case}: no pitch damping"
    assert d.Cn_r < 0, f"Cn_r {d.Cn_r:.4f} at {case}: no yaw damping"


@pytest.mark.parametrize("case", [CRUISE, CLIMB], ids=["cruise", "climb"])
def test_static_stability_across_cg_range(baseline_sim, case):
    res = [trim_derivatives(baseline_sim, Condition(**{**case.__dict__, "weight_lb": w, "cg_in": cg}))
           for cg, w in CG_POINTS]
    for (cg, w), d in zip(CG_POINTS, res):
        assert d.cg_in == pytest.approx(cg, abs=1e-6)
        assert d.Cm_alpha < 0, f"Cm_alpha {d.Cm_alpha:.4f} /rad at CG {cg} in, {w} lb"
        assert d.static_margin > 0
    # consistency of the moment transfer: moving the CG aft by dx (same weight) raises
    # Cm_alpha by about CN_alpha dx / cbar (CN_alpha = CL_alpha + CD, body normal force)
    d41, d47 = res[1], res[2]
    cbar_in = baseline_sim.fdm["metrics/cbarw-ft"] * 12.0
    expected = d41.CL_alpha * (47.3 - 41.0) / cbar_in
    assert d47.Cm_alpha - d41.Cm_alpha == pytest.approx(expected, rel=0.1)


@pytest.mark.parametrize("cg_in", [41.0, 47.3], ids=["forward", "aft"])
def test_clean_power_off_stall_speed(baseline_sim, cg_in):
    s = stall_speed(baseline_sim, 2550.0, cg_in, flaps_deg=0.0, pressure_alt_ft=0.0, power="idle")
    assert math.isfinite(s.kcas), s.reason
    assert 47.0 <= s.kcas <= 55.0, f"stall {s.kcas:.1f} KCAS at CG {cg_in} in ({s.reason})"
    assert s.kias == pytest.approx(s.kcas, abs=1e-9)          # identity airspeed calibration
    assert s.cl_max > 1.2 and 10.0 < s.alpha_deg < 25.0
    # 0.5 kt above the stall the glide trims, elevator within its stops
    r = baseline_sim.trim(Condition(0.0, 2550.0, kcas=s.kcas + 0.5, cg_in=cg_in, mode="full_throttle", throttle=0.0))
    assert r.trimmed, r.reason


def test_stall_speed_falls_with_flaps_and_aft_cg(baseline_sim):
    fwd = stall_speed(baseline_sim, 2550.0, 41.0)
    aft = stall_speed(baseline_sim, 2550.0, 47.3)
    flaps = stall_speed(baseline_sim, 2550.0, 41.0, flaps_deg=30.0)
    assert aft.kcas < fwd.kcas
    assert flaps.kcas < fwd.kcas - 2.0
    assert flaps.cl_max > fwd.cl_max


def test_report_is_json_safe(committed):
    too_slow = Condition(0.0, 2550.0, kcas=30.0, mode="level")
    rep = report(committed, {"cruise": CRUISE, "too slow": too_slow}, stall_cases=[StallCase(2550.0, 47.3)]).as_dict()
    json.dumps(rep, allow_nan=False)
    assert rep["aircraft"] == "c172"
    assert rep["derivatives"]["cruise"]["CL_alpha"] == pytest.approx(trim_derivatives(committed, CRUISE).CL_alpha)
    assert "error" in rep["derivatives"]["too slow"]
    assert rep["stall"][0]["kcas"] == pytest.approx(stall_speed(committed, 2550.0, 47.3).kcas, abs=0.1)


# --------------------------------------------------------------------------- POH points
def _poh_points():
    pts = []
    with open(REPO / "data" / "c172_poh_climb.csv", newline="") as fh:
        for i, row in enumerate(csv.DictReader(fh)):
            pts.append(pytest.param(Condition(float(row["pressure_alt_ft"]), float(row["weight_lb"]),
                                              kcas=float(row["kias"]), oat_c=float(row["oat_c"]),
                                              mode="full_throttle", mixture="climb"), id=f"climb{i}"))
    with open(REPO / "data" / "c172_poh_cruise.csv", newline="") as fh:
        for i, row in enumerate(csv.DictReader(fh)):
            pts.append(pytest.param(Condition(float(row["pressure_alt_ft"]), float(row["weight_lb"]),
                                              ktas=float(row["ktas"]), isa_dev_c=float(row["temp_dev_c"]),
                                              mode="level", mixture="cruise"), id=f"cruise{i}"))
    return pts


POH_POINTS = _poh_points()


def test_poh_point_count():
    assert len(POH_POINTS) == 64


@pytest.mark.parametrize("cond", POH_POINTS)
def test_baseline_trims_at_poh_point(baseline_sim, cond):
    r = baseline_sim.trim(cond)
    assert r.trimmed, r.reason
    assert r.rpm > 1000


# --------------------------------------------------------------------------- factor directions
CHECKS = {}


def check(name):
    def deco(fn):
        CHECKS[name] = fn
        return fn
    return deco


def moved(name: str, frac: float = 0.25) -> float:
    """Neutral + frac of the factor's range (inside its bounds)."""
    f = REGISTRY[name]
    return min(f.neutral + frac * (f.upper - f.lower), f.upper)


def effect(sim: Simulator, cond: Condition, changes: dict, base: dict | None = None):
    """Trimmed results before and after applying ``changes`` on top of ``base``."""
    base = dict(base or {})
    sim.set_factors(FactorSet(base))
    r0 = trimmed(sim, cond)
    sim.set_factors(FactorSet({**base, **changes}))
    r1 = trimmed(sim, cond)
    return r0, r1


def up(name: str, frac: float = 0.25) -> dict:
    return {name: moved(name, frac)}


# steady stage
@check("alpha_shift")
def _alpha_shift(sim):
    r0, r1 = effect(sim, CRUISE, up("alpha_shift"))
    assert r1.alpha_deg < r0.alpha_deg - 0.3          # more lift at the same alpha


@check("K_cl_slope")
def _k_cl_slope(sim):
    r0, r1 = effect(sim, CRUISE, up("K_cl_slope"))
    assert r1.alpha_deg < r0.alpha_deg - 0.1


@check("K_cl_offset")
def _k_cl_offset(sim):
    r0, r1 = effect(sim, CRUISE, up("K_cl_offset"))
    assert r1.alpha_deg < r0.alpha_deg - 0.3


@check("K_cd0_slope")
def _k_cd0_slope(sim):
    c0, c1 = effect(sim, CRUISE, up("K_cd0_slope"))
    assert c1.power_hp > c0.power_hp + 1.0 and c1.rpm > c0.rpm + 5.0
    k0, k1 = effect(sim, CLIMB, up("K_cd0_slope"))
    assert k1.roc_fpm < k0.roc_fpm - 10.0


@check("K_cd0_offset")
def _k_cd0_offset(sim):
    # 25 % of the range (+0.025) nearly doubles the parasitic drag: use 10 % (+0.01)
    c0, c1 = effect(sim, CRUISE, up("K_cd0_offset", 0.1))
    assert c1.power_hp > c0.power_hp + 1.0
    k0, k1 = effect(sim, CLIMB, up("K_cd0_offset", 0.1))
    assert k1.roc_fpm < k0.roc_fpm - 10.0


@check("K_cdi")
def _k_cdi(sim):
    k0, k1 = effect(sim, CLIMB, up("K_cdi"))
    assert k1.roc_fpm < k0.roc_fpm - 5.0
    # induced drag: the effect is larger at high lift (slow) than in cruise, relative to the power
    c0, c1 = effect(sim, CRUISE, up("K_cdi"))
    s0, s1 = effect(sim, SLOW, up("K_cdi"))
    assert (s1.power_hp / s0.power_hp) > (c1.power_hp / c0.power_hp) > 1.0


@check("J_anchor")
def _j_anchor(sim):
    # alone (no tilt, no curvature) it has no effect
    r0, r1 = effect(sim, FAST_FULL, up("J_anchor"))
    assert r1.rpm == pytest.approx(r0.rpm, abs=1e-6) and r1.roc_fpm == pytest.approx(r0.roc_fpm, abs=1e-6)
    # with a thrust tilt it matters: CT' = CT (1 + tilt (J - J_anchor)): a higher anchor, less thrust
    r0, r1 = effect(sim, FAST_FULL, up("J_anchor"), base={"K_CT_tilt": 0.05})
    assert r1.roc_fpm < r0.roc_fpm - 2.0


@check("K_CT_shift")
def _k_ct_shift(sim):
    r0, r1 = effect(sim, CLIMB, up("K_CT_shift"))
    assert r1.roc_fpm < r0.roc_fpm - 10.0             # less thrust


@check("K_CT_scale")
def _k_ct_scale(sim):
    k0, k1 = effect(sim, CLIMB, up("K_CT_scale"))
    assert k1.roc_fpm > k0.roc_fpm + 10.0
    c0, c1 = effect(sim, CRUISE, up("K_CT_scale"))
    assert c1.rpm < c0.rpm - 5.0


@check("K_CT_tilt")
def _k_ct_tilt(sim):
    # anchor well below the operating J (about 0.67): + tilt = more thrust there
    r0, r1 = effect(sim, FAST_FULL, up("K_CT_tilt"), base={"J_anchor": 0.45})
    assert r1.roc_fpm > r0.roc_fpm + 5.0


@check("K_CT_quad")
def _k_ct_quad(sim):
    r0, r1 = effect(sim, FAST_FULL, up("K_CT_quad"), base={"J_anchor": 0.45})
    assert r1.roc_fpm > r0.roc_fpm + 2.0              # more thrust away from the anchor


@check("K_CQ_shift")
def _k_cq_shift(sim):
    r0, r1 = effect(sim, CLIMB, up("K_CQ_shift"))
    assert r1.rpm > r0.rpm + 10.0                      # less torque, higher RPM


@check("K_CQ_scale")
def _k_cq_scale(sim):
    r0, r1 = effect(sim, CLIMB, up("K_CQ_scale"))
    assert r1.rpm < r0.rpm - 10.0                      # more power absorbed, lower RPM


@check("K_CQ_tilt")
def _k_cq_tilt(sim):
    r0, r1 = effect(sim, FAST_FULL, up("K_CQ_tilt"), base={"J_anchor": 0.45})
    assert r1.rpm < r0.rpm - 2.0                       # more torque above the anchor


@check("K_CQ_quad")
def _k_cq_quad(sim):
    r0, r1 = effect(sim, FAST_FULL, up("K_CQ_quad"), base={"J_anchor": 0.45})
    assert r1.rpm < r0.rpm - 1.0                       # more torque away from the anchor


@check("K_HP")
def _k_hp(sim):
    r0, r1 = effect(sim, CLIMB, up("K_HP"))
    assert r1.roc_fpm > r0.roc_fpm + 20.0
    assert r1.power_hp > r0.power_hp + 2.0


@check("K_FF")
def _k_ff(sim):
    r0, r1 = effect(sim, CRUISE, up("K_FF"))
    assert r1.gph > r0.gph * 1.03
    assert r1.power_hp == pytest.approx(r0.power_hp, rel=0.01)


# pitch stage
@check("alpha_shift_addl")
def _alpha_shift_addl(sim):
    r0, r1 = effect(sim, CRUISE, up("alpha_shift_addl"))
    assert r1.theta_deg < r0.theta_deg - 0.2


@check("K_cm_slope")
def _k_cm_slope(sim):
    r0, r1 = effect(sim, CRUISE, up("K_cm_slope"))
    assert r1.elevator_deg < r0.elevator_deg - 0.3     # more nose-down wing moment: elevator further up


@check("K_cm_offset")
def _k_cm_offset(sim):
    r0, r1 = effect(sim, CRUISE, up("K_cm_offset"))
    assert r1.elevator_deg > r0.elevator_deg + 0.3     # nose-up: elevator trims further down


# control stage
def _more_effective(sim, cond: Condition, name: str, surface: str, at_least_deg: float) -> None:
    """A slope factor > 1: the same trim needs at least 10 % less of the surface."""
    r0, r1 = effect(sim, cond, up(name))
    assert abs(getattr(r0, surface)) > at_least_deg
    assert abs(getattr(r1, surface)) < 0.9 * abs(getattr(r0, surface))


@check("K_de_slope")
def _k_de_slope(sim):
    _more_effective(sim, FLAPS30, "K_de_slope", "elevator_deg", 2.0)


@check("K_de_offset")
def _k_de_offset(sim):
    c0, c1 = effect(sim, CRUISE, up("K_de_offset"))
    s0, s1 = effect(sim, SLOW, up("K_de_offset"))
    # tail lift up = nose down: the elevator trims further trailing edge up ...
    assert c1.elevator_deg < c0.elevator_deg - 0.05
    assert s1.elevator_deg < s0.elevator_deg - 0.05
    # ... and the offset falls with speed
    assert abs(s1.elevator_deg - s0.elevator_deg) > abs(c1.elevator_deg - c0.elevator_deg)


@check("K_da_slope")
def _k_da_slope(sim):
    _more_effective(sim, BANKED, "K_da_slope", "aileron_deg", 1.0)


@check("K_da_offset")
def _k_da_offset(sim):
    r0, r1 = effect(sim, CRUISE, up("K_da_offset"))
    assert r1.aileron_deg < r0.aileron_deg - 0.1       # right-roll moment: aileron trims left


@check("K_dr_slope")
def _k_dr_slope(sim):
    _more_effective(sim, BANKED, "K_dr_slope", "rudder_deg", 1.0)


@check("K_dr_offset")
def _k_dr_offset(sim):
    r0, r1 = effect(sim, CRUISE, up("K_dr_offset"))
    assert r1.rudder_deg < r0.rudder_deg - 0.1         # nose-left moment: rudder trims trailing edge right


# P-factor
@check("K_PF")
def _k_pf(sim):
    r0, r1 = effect(sim, CLIMB, up("K_PF"))
    assert r1.rudder_deg < r0.rudder_deg - 0.05        # right rudder (trailing edge right, negative)
    # it grows with thrust and alpha: much less at cruise
    c0, c1 = effect(sim, CRUISE, up("K_PF"))
    assert abs(c1.rudder_deg - c0.rudder_deg) < abs(r1.rudder_deg - r0.rudder_deg)


# the slipstream switches (model physics, not fitted: jsbsim_calib.physics.slipstream)
@check("K_slip")
def _k_slip(sim):
    # more tail power with thrust: the same tail load for less elevator, the wing's lift unchanged
    c0, c1 = effect(sim, CLIMB, up("K_slip"))
    k0, k1 = effect(sim, CRUISE, up("K_slip"))
    assert c1.elevator_deg > c0.elevator_deg + 0.1 and abs(c1.alpha_deg - c0.alpha_deg) < 0.05
    assert abs(c1.elevator_deg - c0.elevator_deg) > 2.0 * abs(k1.elevator_deg - k0.elevator_deg)


@check("K_swirl")
def _k_swirl(sim):
    c0, c1 = effect(sim, CLIMB, up("K_swirl"))
    k0, k1 = effect(sim, CRUISE, up("K_swirl"))
    assert c1.rudder_deg < c0.rudder_deg - 1.0          # right rudder (trailing edge right, negative)
    assert abs(c1.rudder_deg - c0.rudder_deg) > 1.5 * abs(k1.rudder_deg - k0.rudder_deg)


# flaps
@check("K_dcd0_flaps")
def _k_dcd0_flaps(sim):
    f0, f1 = effect(sim, FLAPS10_CLIMB, up("K_dcd0_flaps"))
    assert f1.roc_fpm < f0.roc_fpm - 5.0
    k0, k1 = effect(sim, CLIMB, up("K_dcd0_flaps"))
    assert k1.roc_fpm == pytest.approx(k0.roc_fpm, abs=1e-6)


@check("K_dcm_flaps")
def _k_dcm_flaps(sim):
    f0, f1 = effect(sim, FLAPS20, up("K_dcm_flaps"))
    assert f1.elevator_deg < f0.elevator_deg - 0.3     # more nose-down with flaps: elevator further up
    c0, c1 = effect(sim, CRUISE, up("K_dcm_flaps"))
    assert c1.elevator_deg == pytest.approx(c0.elevator_deg, abs=1e-9)


@check("K_dcl_flaps")
def _k_dcl_flaps(sim):
    f0, f1 = effect(sim, FLAPS20, {"K_dcl_flaps": 0.8})
    assert f1.theta_deg > f0.theta_deg + 0.3           # less flap lift: higher flaps-down attitude
    c0, c1 = effect(sim, CRUISE, {"K_dcl_flaps": 0.8})
    assert c1.theta_deg == pytest.approx(c0.theta_deg, abs=1e-9)


# damping
def _damping(sim, name: str, attr: str):
    sim.set_factors(FactorSet())
    d0 = getattr(trim_derivatives(sim, CRUISE), attr)
    k = moved(name)
    sim.set_factors(FactorSet({name: k}))
    d1 = getattr(trim_derivatives(sim, CRUISE), attr)
    assert d1 < d0
    assert d1 - d0 == pytest.approx(-k, rel=0.02)      # the documented -K per unit rate


@check("K_Clp")
def _k_clp(sim):
    _damping(sim, "K_Clp", "Cl_p")


@check("K_Cmq")
def _k_cmq(sim):
    _damping(sim, "K_Cmq", "Cm_q")


@check("K_Cnr")
def _k_cnr(sim):
    _damping(sim, "K_Cnr", "Cn_r")


@check("K_Cm_alpha")
def _k_cm_alpha(sim):
    sim.set_factors(FactorSet())
    d0 = trim_derivatives(sim, CRUISE)
    k = moved("K_Cm_alpha")
    sim.set_factors(FactorSet({"K_Cm_alpha": k}))
    d1 = trim_derivatives(sim, CRUISE)
    assert d1.Cm_alpha - d0.Cm_alpha == pytest.approx(k, rel=0.02)     # + K per radian: less stable
    assert d1.Cm_q == pytest.approx(d0.Cm_q, rel=1e-2)      # only through the trim alpha


@check("K_Ip")
def _k_ip(sim):
    # the rotating inertia: the RPM follows the throttle more slowly, in proportion (1.f.1); the
    # trimmed RPM is the same (a steady state does not depend on the inertia)
    from jsbsim_calib.data.dynamic_tests import ENGINE_STEP_S, engine_maneuver
    from jsbsim_calib.evaluation.evaluate_dynamic import response_times
    from jsbsim_calib.jsbsim.trajectory import fly
    out = []
    for k in (1.0, moved("K_Ip")):
        sim.set_factors(FactorSet({"K_Ip": k}))
        tr = fly(sim, engine_maneuver())
        ti, tt = response_times(tr.time_s, tr["rpm"], ENGINE_STEP_S)
        out.append((tt - ti, tr.trim.rpm))
    (t0, rpm0), (t1, rpm1) = out
    assert t1 / t0 == pytest.approx(moved("K_Ip"), rel=0.1) and rpm1 == pytest.approx(rpm0, abs=0.5)


@pytest.mark.parametrize("name", [f.name for f in FACTORS])
def test_factor_moves_result_as_documented(baseline, name):
    assert name in CHECKS, f"no direction check for factor {name}"
    CHECKS[name](baseline)


def test_every_check_is_a_factor():
    assert set(CHECKS) <= set(REGISTRY)


def test_calibrated_product_keeps_stable_signs(committed):
    """The shipped (calibrated) aircraft keeps the stability signs of the physics."""
    for cond in (CRUISE, CLIMB):
        d = trim_derivatives(committed, cond)
        assert d.Cm_alpha < 0 and d.Cn_beta > 0 and d.Cl_beta < 0
        assert d.Cl_p < 0 and d.Cm_q < 0 and d.Cn_r < 0
        assert 3.5 < d.CL_alpha < 6.0
