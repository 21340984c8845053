"""The propeller slipstream model against momentum theory.

* the pure functions of :mod:`jsbsim_calib.physics.slipstream` against an actuator disc worked
  out from first principles (mass flow, momentum, energy, continuity, angular momentum);
* the generated aircraft computes in JSBSim, at a trimmed full-power climb, the disc thrust
  coefficient, the tail's dynamic-pressure gain and the swirl at the fin that the theory gives
  for the thrust and torque JSBSim's own propeller makes;
* switched on, it acts as the physics says: a power effect (nothing at idle), the swirl of a
  clockwise propeller needs right rudder, as the P-factor does.
"""
from __future__ import annotations

import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from jsbsim_calib.factors import FactorSet
from jsbsim_calib.flight.condition import Condition
from jsbsim_calib.generate import swirl_torque_shape
from jsbsim_calib.jsbsim.product import load_aircraft_geometry
from jsbsim_calib.jsbsim.simulator import Simulator
from jsbsim_calib.physics import slipstream as ss
from jsbsim_calib.physics.aero.model import slipstream_geometry

REPO = Path(__file__).resolve().parents[1]
RHO = 1.1           # kg/m3
V = 40.0            # m/s
R = 0.95            # m


def actuator_disc(a: float) -> dict:
    """An actuator disc with axial induction ``a`` from first principles: the disc velocity
    V (1 + a), the far wake V (1 + 2a) (the pressure jump spent half before the disc, half after)."""
    area = math.pi * R ** 2
    mdot = RHO * area * V * (1 + a)
    v_wake = V * (1 + 2 * a)
    thrust = mdot * (v_wake - V)                                    # momentum
    power = 0.5 * mdot * (v_wake ** 2 - V ** 2)                     # energy
    r_wake = math.sqrt(mdot / (RHO * math.pi * v_wake))             # continuity
    return {"area": area, "mdot": mdot, "v_wake": v_wake, "thrust": thrust, "power": power, "r_wake": r_wake,
            "tc": thrust / (0.5 * RHO * V ** 2 * area)}


@pytest.mark.parametrize("a", [0.0, 0.02, 0.1, 0.3, 1.0])
def test_thrust_coefficient_wake_pressure_and_contraction_follow_the_actuator_disc(a):
    d = actuator_disc(a)
    assert d["power"] == pytest.approx(d["thrust"] * V * (1 + a), rel=1e-12)       # Froude: power = T x disc speed
    assert float(ss.axial_induction(d["tc"])) == pytest.approx(a, abs=1e-12)
    assert float(ss.dynamic_pressure_ratio(d["tc"])) == pytest.approx((d["v_wake"] / V) ** 2, rel=1e-12)
    assert float(ss.contraction_ratio(d["tc"])) * R == pytest.approx(d["r_wake"], rel=1e-12)


def test_a_static_disc_contracts_to_one_over_root_two():
    assert float(ss.contraction_ratio(1e12)) == pytest.approx(1 / math.sqrt(2), rel=1e-5)
    assert float(ss.contraction_ratio(0.0)) == 1.0
    assert float(ss.axial_induction(-0.3)) == 0.0           # windmilling: no slipstream, not a NaN


@pytest.mark.parametrize("r_over_R", [0.3, 0.6, 0.9])
def test_swirl_carries_the_torque_as_angular_momentum(r_over_R):
    """A free vortex w_t r = const behind the disc: the torque is the angular momentum flux
    mdot w_t r; the swirl angle at r in the far wake is w_t / V_wake."""
    a = 0.15
    d = actuator_disc(a)
    torque = 180.0                                          # N m
    wt_r = torque / d["mdot"]
    r = r_over_R * R
    expected = (wt_r / r) / d["v_wake"]
    qc = torque / (0.5 * RHO * V ** 2 * d["area"] * R)
    assert float(ss.swirl_angle_rad(qc, d["tc"], r_over_R)) == pytest.approx(expected, rel=1e-12)


def test_the_swirl_of_a_real_blade_carries_its_torque_as_angular_momentum(repo_geometry):
    """The far-wake swirl of :func:`swirl_arm`, with the C172 blade's own torque shape (a BEM
    solution), integrated as angular momentum flux over the contracted slipstream: the torque."""
    shape = swirl_torque_shape(repo_geometry, REPO)
    x, s = shape
    assert float(np.sum(0.5 * (s[1:] + s[:-1]) * np.diff(x))) == pytest.approx(1.0, rel=1e-12)
    tc, torque = 0.6, 450.0
    a = float(ss.axial_induction(tc))
    q = 0.5 * RHO * V ** 2
    qc = torque / (q * math.pi * R ** 2 * R)
    v_wake = V * (1 + 2 * a)
    r_w = np.linspace(1e-4, R, 20001)
    angle = qc * ss.swirl_arm(r_w / R, tc, shape) / ((1 + a) * (1 + 2 * a))
    flux = RHO * v_wake * (angle * v_wake) * r_w * 2 * math.pi * r_w
    assert float(np.sum(0.5 * (flux[1:] + flux[:-1]) * np.diff(r_w))) == pytest.approx(torque, rel=2e-3)
    # a free vortex is the same formula with s = 2 r/R
    np.testing.assert_allclose(ss.swirl_arm(np.array([0.3, 0.6]), tc),
                               ss.swirl_angle_rad(1.0, tc, np.array([0.3, 0.6])) * (1 + a) * (1 + 2 * a), rtol=1e-12)


def test_immersion_is_the_geometry_of_the_contracted_cylinder():
    g = ss.TailGeometry(radius_m=1.0, ht_semispan_m=2.0, ht_height_m=0.6, fin_root_m=0.2, fin_tip_m=1.8,
                        wing_height_m=-0.5, wing_area_m2=15.0, wing_root_chord_m=1.5, fuselage_half_width_m=0.4)
    tc = np.array([0.0, 3.0])
    rs = ss.contraction_ratio(tc)
    np.testing.assert_allclose(ss.ht_fraction(g, tc), np.sqrt(rs ** 2 - 0.36) / 2.0, rtol=1e-12)
    np.testing.assert_allclose(ss.fin_fraction(g, tc), (rs - 0.2) / 1.6, rtol=1e-12)
    np.testing.assert_allclose(ss.wing_fraction(g, tc), 2 * (np.sqrt(rs ** 2 - 0.25) - 0.4) * 1.5 / 15.0, rtol=1e-12)
    assert np.all(np.diff(ss.ht_fraction(g, np.array([0.0, 1.0, 5.0]))) < 0)   # the slipstream narrows with Tc
    high = ss.TailGeometry(**{**g.__dict__, "fin_root_m": 1.2, "wing_height_m": 1.1})
    assert float(ss.fin_fraction(high, 0.5)) == 0.0 and float(ss.fin_swirl_arm(high, 0.5)) == 0.0
    assert float(ss.wing_fraction(high, 0.5)) == 0.0


def test_the_c172_high_wing_is_outside_and_the_sr20_low_wing_root_inside():
    c172 = slipstream_geometry(load_aircraft_geometry(REPO, "c172"))
    sr20 = slipstream_geometry(load_aircraft_geometry(REPO, "sr20"))
    tables = {k: ss.immersion_tables(g) for k, g in (("c172", c172), ("sr20", sr20))}
    assert np.all(tables["c172"]["wing_fraction"] == 0.0)
    assert np.all(tables["sr20"]["wing_fraction"][:3] > 0.0)
    assert np.all(tables["c172"]["ht_fraction"] > 0.0) and np.all(tables["c172"]["fin_fraction"] > 0.0)


@pytest.fixture(scope="module")
def repo_geometry():
    return load_aircraft_geometry(REPO, "c172")


CLIMB = Condition(2000.0, 2450.0, kcas=75.0, mode="full_throttle", mixture="climb")
IDLE = Condition(3000.0, 2450.0, kcas=70.0, mode="full_throttle", throttle=0.0)


@pytest.fixture(scope="module")
def c172():
    sim = Simulator(REPO, "c172")
    yield sim
    sim.close()


def _trim(sim, cond, **switches):
    sim.set_factors(sim.declared.updated(switches))
    t = sim.trim(cond)
    assert t.trimmed, t.reason
    return t


def test_jsbsim_computes_the_theory_from_its_own_thrust_and_torque(c172):
    t = _trim(c172, CLIMB, K_slip=1.0, K_swirl=1.0)
    fdm = c172.fdm
    g = slipstream_geometry(c172.geometry, swirl_torque_shape(c172.geometry, REPO))
    area_ft2 = ss.disc_area_m2(g.radius_m) / 0.3048 ** 2
    tc = fdm["propulsion/engine/thrust-lbs"] / (fdm["aero/qbar-psf"] * area_ft2)
    assert 0.2 < tc < 2.0                                   # a full-power climb at 75 KCAS
    assert fdm["aero/slipstream/tc"] == pytest.approx(tc, rel=1e-6)
    tables = ss.immersion_tables(g)
    f_h = np.interp(tc, ss.TC_GRID, tables["ht_fraction"])
    assert fdm["aero/slipstream/ht-gain"] == pytest.approx(1 + f_h * tc, rel=1e-4)
    torque_lbft = abs(fdm["propulsion/engine/propeller-torque-ftlb"])      # JSBSim's own propeller torque ...
    shaft_lbft = fdm["propulsion/engine/power-hp"] * 550.0 / (fdm["propulsion/engine/propeller-rpm"] * math.pi / 30.0)
    assert shaft_lbft == pytest.approx(torque_lbft, rel=1e-3)                # ... is what the model uses: P / omega
    qc = torque_lbft / (fdm["aero/qbar-psf"] * area_ft2 * g.radius_m / 0.3048)
    arm = np.interp(tc, ss.TC_GRID, tables["fin_swirl_arm"])
    a = float(ss.axial_induction(tc))
    swirl = qc * arm / ((1 + a) * (1 + 2 * a))
    assert abs(fdm["aero/slipstream/fin-sideslip-rad"]) == pytest.approx(swirl, rel=2e-3)
    assert math.isfinite(t.elevator_deg) and math.isfinite(t.rudder_deg)


def test_switched_on_it_is_a_power_effect_and_the_swirl_needs_right_rudder(c172):
    off, on = _trim(c172, CLIMB, K_slip=0.0, K_swirl=0.0), _trim(c172, CLIMB, K_slip=1.0, K_swirl=0.0)
    idle_off, idle_on = _trim(c172, IDLE, K_slip=0.0, K_swirl=0.0), _trim(c172, IDLE, K_slip=1.0, K_swirl=0.0)
    climb_shift = abs(on.elevator_deg - off.elevator_deg)
    assert climb_shift > 0.05
    assert abs(idle_on.elevator_deg - idle_off.elevator_deg) < 0.05 * climb_shift
    no_pf = _trim(c172, CLIMB, K_slip=0.0, K_swirl=0.0, K_PF=0.0)
    swirl = _trim(c172, CLIMB, K_slip=0.0, K_swirl=1.0, K_PF=0.0)
    pf = _trim(c172, CLIMB, K_slip=0.0, K_swirl=0.0, K_PF=2.0)
    # the same way as the P-factor (nose-left yaw with power: right rudder), by a sizeable amount
    assert np.sign(swirl.rudder_deg - no_pf.rudder_deg) == np.sign(pf.rudder_deg - no_pf.rudder_deg)
    assert abs(swirl.rudder_deg - no_pf.rudder_deg) > 0.3 and abs(pf.rudder_deg - no_pf.rudder_deg) > 0.3


@pytest.mark.slow
def test_the_slipstream_command_calibrates_a_variant_and_writes_its_report(tmp_path):
    """`jsbsim-calib slipstream sr20 --stage steady --variant theory --max-nfev 5`: stage 1 from
    neutral with the theory switched on (a real fit, shortened); the fitted variant needs stage 2a
    and is left out."""
    r = subprocess.run([sys.executable, "-m", "jsbsim_calib.cli", "--root", str(REPO), "slipstream", "sr20",
                        "--stage", "steady", "--variant", "theory", "--variant", "fitted", "--max-nfev", "5", "--report-dir",
                        str(tmp_path)], capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr
    assert "variant fitted: left out" in r.stderr
    md = (tmp_path / "sr20" / "slipstream.md").read_text()
    row = next(line for line in md.splitlines() if line.startswith("| poh_climb roc_fpm RMSE"))
    theory = float(row.split("|")[2])
    # measured 18.7 fpm after 5 evaluations (the whole fit: 7.04, reports/sr20/slipstream.md); same bits on
    # every CPU and executor
    assert theory == pytest.approx(18.7, abs=0.3)
    assert "| K_slip | 1 |" in md and "The product (aircraft/sr20/sr20.xml) holds" in md


def test_the_comparison_table_has_a_column_per_variant_and_no_number_for_a_nan():
    """The slipstream report's console table (fast: no chain flown; the command's own test above
    flies one), a figure that is not a number shown as '-'."""
    from jsbsim_calib.calibration.variants import SLIPSTREAM, VariantResult
    from jsbsim_calib.factors import FactorSet
    from jsbsim_calib.report.variants_report import _cell, format_comparison, table
    results = [VariantResult(v, FactorSet(), {}, {}, {}, 0.0) for v in SLIPSTREAM]
    head, rows = table(results)
    assert head == ["figure"] + [v.name for v in SLIPSTREAM] and all(len(r) == len(head) for r in rows)
    assert _cell(float("nan")) == "-" and "model variants" in format_comparison("c172", results)


@pytest.mark.slow
def test_variants_on_a_pool_are_independent_chains_with_the_same_bits():
    """Two variants of the SR20's stage 1 (shortened) as independent tasks on a pool of two
    workers end on this process's factors, bit for bit, in the variants' order."""
    from jsbsim_calib.calibration.variants import SLIPSTREAM, compare_variants
    from jsbsim_calib.core.executor import ProcessExecutor
    chosen = [v for v in SLIPSTREAM if v.name in ("off", "theory")]
    here = compare_variants(REPO, "sr20", chosen, stages="steady", max_nfev=3)
    with ProcessExecutor(2) as pool:
        there = compare_variants(REPO, "sr20", chosen, stages="steady", max_nfev=3, executor=pool)
    assert [r.variant.name for r in there] == ["off", "theory"]
    assert [r.factors for r in here] == [r.factors for r in there]
    assert here[0].factors != here[1].factors
