"""Synthetic flight-test trims: a truth aircraft flown by JSBSim, written as snapshot CSV.

The truth is any aircraft folder (its XML as it stands: an effect written into it by hand
flies as JSBSim flies it). :func:`campaign` lays out a flight-test campaign, deterministic
for a seed, spread like the real one and wider:

======================  =====  ============================================================
block                   share  conditions
======================  =====  ============================================================
full-power climbs       1/6    flaps 0 and 10, 70-88 KCAS, 1,500-9,000 ft, full throttle;
                               the climb rate is the truth's (``throttle_norm`` = 1)
level cruise            1/4    90-125 KTAS, 2,000-10,000 ft, throttle for level flight
climbs and descents     1/8    part power, -500 to +300 ft/min, 85-115 KTAS
flaps 10/20/30          1/4    level or -300 ft/min, 62-95 KCAS
banked turns            1/6    steady coordinated turns, 15-30 deg bank either way, level
======================  =====  ============================================================

Weights are spread from 80 % of maximum to maximum, CG stations over the envelope at that
weight, ISA. Measurement noise (Gaussian, seeded; ``noise`` scales it, 0 = none): pitch and
roll 0.1 deg, surfaces 0.15 deg, true airspeed 0.3 kt, vertical speed 15 ft/min, pressure
altitude 10 ft. Cockpit controls follow the noisy surfaces through the aircraft's
control-travel table (piecewise linear through neutral). Points the truth cannot trim are
left out and counted.
"""
from __future__ import annotations

import csv
import math
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Callable

import numpy as np

from ..physics.atmosphere import isa_temperature_c, ktas_from_kcas
from ..flight.condition import Condition, TrimResult
from ..jsbsim.simulator import Simulator
from ..data.flighttest import (CONTROL_COLUMNS, SURFACE_METRICS, ControlAxis, load_control_travel, snapshot_value)

NOISE = {"pitch_deg": 0.1, "roll_deg": 0.1, "surface_deg": 0.15, "ktas": 0.3, "vs_fpm": 15.0,
         "pressure_alt_ft": 10.0}
COLUMNS = ("table", "title", "weight_lb", "cg_in", "flaps_deg", "pressure_alt_ft", "ktas", "vs_fpm", "pitch_deg",
           "roll_deg", "heading_deg", "elevator_deg", "aileron_deg", "rudder_deg", "column_in", "wheel_deg",
           "pedal_in", "throttle_norm", "rpm")


@dataclass(frozen=True)
class Point:
    title: str
    condition: Condition
    climb: bool            # full power: the climb rate is an output


def campaign(sim: Simulator, n: int = 48, seed: int = 0) -> list[Point]:
    """Conditions of a synthetic flight-test campaign (see the module doc)."""
    rng = np.random.default_rng(seed)
    g = sim.geometry
    m = g.mass
    w_max = m.max_mass_kg / 0.45359237
    flap = g.wing.control("flap")
    flap_max = math.degrees(flap.deflection_max_rad) if flap else 0.0
    flap_steps = [f for f in (10.0, 20.0, 30.0) if f <= flap_max + 1e-6] or [0.0]

    def loading():
        w = float(rng.uniform(0.8, 1.0) * w_max)
        kg = w * 0.45359237
        fwd = float(np.interp(kg, m.cg_envelope_mass_kg, m.cg_envelope_fwd_m)) / 0.0254
        aft = float(np.interp(kg, m.cg_envelope_mass_kg, m.cg_envelope_aft_m)) / 0.0254
        return round(w, 0), round(float(rng.uniform(fwd, aft)), 1)

    def tas(kcas, h):
        return float(ktas_from_kcas(kcas, h, isa_temperature_c(h)))

    blocks = [("climb", n // 6), ("cruise", n // 4), ("part power", n // 8), ("flaps", n // 4)]
    blocks.append(("turn", n - sum(k for _, k in blocks)))
    out = []
    for kind, count in blocks:
        for _ in range(count):
            w, cg = loading()
            if kind == "climb":
                h = float(rng.uniform(1500, 9000))
                f = float(rng.choice([0.0, 0.0, 10.0])) if flap_max else 0.0
                c = Condition(h, w, ktas=tas(rng.uniform(70, 88), h), cg_in=cg, flaps_deg=f, mode="full_throttle",
                              mixture="climb")
                out.append(Point(f"full-power climb, flaps {f:g}", c, True))
            elif kind == "cruise":
                h = float(rng.uniform(2000, 10000))
                c = Condition(h, w, ktas=float(rng.uniform(90, 125)), cg_in=cg, mode="level")
                out.append(Point("level cruise", c, False))
            elif kind == "part power":
                h = float(rng.uniform(2000, 8000))
                c = Condition(h, w, ktas=float(rng.uniform(85, 115)), cg_in=cg, mode="level",
                              vs_fpm=float(rng.uniform(-500, 300)))
                out.append(Point("part-power climb or descent", c, False))
            elif kind == "flaps":
                h = float(rng.uniform(2000, 6000))
                f = float(rng.choice(flap_steps))
                c = Condition(h, w, ktas=tas(rng.uniform(62, 95) if f < 25 else rng.uniform(62, 85), h), cg_in=cg,
                              flaps_deg=f, mode="level", vs_fpm=float(rng.choice([0.0, -300.0])))
                out.append(Point(f"flaps {f:g}", c, False))
            else:
                h = float(rng.uniform(2000, 8000))
                bank = float(rng.uniform(15, 30) * rng.choice([-1, 1]))
                f = float(rng.choice([0.0, 0.0, 10.0])) if flap_max else 0.0
                c = Condition(h, w, ktas=float(rng.uniform(80, 110)), cg_in=cg, flaps_deg=f, mode="level",
                              bank_deg=bank, turn="coordinated")
                out.append(Point(f"steady turn, {bank:+.0f} deg bank", c, False))
    return out


def _controls(travel: dict[str, ControlAxis] | None, row: dict) -> None:
    if not travel:
        return
    for surface, ax in travel.items():
        neutral = 0.0 if ax.control_min < 0 < ax.control_max else ax.linear_neutral
        a = replace(ax, neutral=neutral)
        row[CONTROL_COLUMNS.get(ax.control, ax.control)] = round(a.control_position(row[SURFACE_METRICS[surface]]), 3)


def synthesize(sim: Simulator, *, n: int = 48, seed: int = 0, noise: float = 1.0,
               progress: Callable[[str], None] | None = None) -> tuple[list[dict], list[str]]:
    """Trim the truth at the campaign's conditions; rows of the snapshot schema and the
    reasons of points left out."""
    rng = np.random.default_rng(seed + 7919)
    travel = load_control_travel(sim.geometry.control_travel_file) if sim.geometry.control_travel_file else None
    rows, skipped = [], []
    points = campaign(sim, n, seed)
    for k, p in enumerate(points):
        c = p.condition
        t: TrimResult = sim.trim(c) if p.climb else sim.trim_level(c)
        if not t.trimmed or (not p.climb and "full throttle" in t.reason):
            skipped.append(f"{p.title} at {c.pressure_alt_ft:.0f} ft, {c.ktas:.0f} KTAS: {t.reason or 'not trimmed'}")
            continue
        e = lambda key: noise * NOISE[key] * float(rng.standard_normal())
        vs = t.roc_fpm if p.climb else c.vs_fpm
        row = {"table": f"S.{k + 1}", "title": p.title, "weight_lb": c.weight_lb, "cg_in": c.cg_in,
               "flaps_deg": c.flaps_deg, "pressure_alt_ft": round(c.pressure_alt_ft + e("pressure_alt_ft"), 1),
               "ktas": round(c.ktas + e("ktas"), 2), "vs_fpm": round(vs + e("vs_fpm"), 1),
               "pitch_deg": round(t.theta_deg + e("pitch_deg"), 3), "roll_deg": round(t.phi_deg + e("roll_deg"), 3),
               "heading_deg": round(float(rng.uniform(0, 360)), 1)}
        for m in SURFACE_METRICS.values():
            row[m] = round(snapshot_value(m, t) + e("surface_deg"), 3)
        _controls(travel, row)
        row["throttle_norm"] = 1.0 if p.climb else ""
        row["rpm"] = ""
        rows.append(row)
        if progress:
            progress(f"synth: {k + 1}/{len(points)} {p.title}")
    return rows, skipped


def write_csv(rows: list[dict], path: Path) -> None:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=COLUMNS, extrasaction="ignore")
        w.writeheader()
        for r in rows:
            w.writerow({k: r.get(k, "") for k in COLUMNS})
