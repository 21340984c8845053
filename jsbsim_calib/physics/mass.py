"""Mass properties: the empty aircraft's inertia, and how a weight and CG are reached.

JSBSim units at the interface where the data state them (lb, in); SI otherwise.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..core.errors import TrimError
from ..core.units import IN, LB_PER_GAL_AVGAS, LBM, US_GAL
from .geometry import AircraftGeometry

PAYLOAD_STATIONS_IN = (-60.0, 200.0)   # [in] where a payload point mass can plausibly sit


def empty_inertia(geom: AircraftGeometry) -> np.ndarray:
    """Empty-aircraft inertia [kg m^2] such that the aircraft at max weight with the default
    loading and full fuel has the radii-of-gyration inertia of the data README."""
    W = geom.mass.max_mass_kg
    b = geom.reference.span_m
    L = geom.fuselage.length_m
    R = geom.mass.radius_of_gyration
    total = np.array([b**2 * W * R[0] ** 2 / 4, L**2 * W * R[1] ** 2 / 4, ((b + L) / 2) ** 2 * W * R[2] ** 2 / 4])
    masses = [(s.mass_kg, s.location_m) for s in geom.mass.stations]
    masses += [(t.capacity_m3 / US_GAL * LB_PER_GAL_AVGAS * LBM, t.location_m) for t in geom.tanks]
    m_tot = geom.mass.empty_mass_kg + sum(m for m, _ in masses)
    cg = (geom.mass.empty_mass_kg * geom.mass.empty_cg_m + sum(m * r for m, r in masses)) / m_tot
    point = np.zeros(3)
    for m, r in masses + [(geom.mass.empty_mass_kg, geom.mass.empty_cg_m)]:
        d = r - cg
        point += m * np.array([d[1] ** 2 + d[2] ** 2, d[0] ** 2 + d[2] ** 2, d[0] ** 2 + d[1] ** 2])
    return np.maximum(total - point, 0.1 * total)


@dataclass(frozen=True)
class Loading:
    """A weight and CG reached with fuel and one payload point mass (the other stations empty)."""

    tank_contents_lb: tuple[float, ...]   # [lb] per tank
    payload_lb: float                     # [lb]
    payload_station_in: float             # [in]


def loading(geom: AircraftGeometry, weight_lb: float, cg_in: float | None = None,
            fuel_fraction: float | None = None) -> Loading:
    """Fuel (``fuel_fraction`` of capacity, default the POH points' share, less where the weight
    does not allow it) and the payload that give ``weight_lb`` at ``cg_in`` (default the POH CG).
    Raises :class:`TrimError` when the weight or CG cannot be reached."""
    cg_in = geom.operations.poh_cg_m / IN if cg_in is None else cg_in
    frac = geom.operations.poh_fuel_fraction if fuel_fraction is None else fuel_fraction
    empty = geom.mass.empty_mass_kg / LBM
    x_e = geom.mass.empty_cg_m[0] / IN
    tanks = [(t.capacity_m3 / US_GAL * LB_PER_GAL_AVGAS, t.location_m[0] / IN) for t in geom.tanks]
    fuel_cap = sum(c for c, _ in tanks)
    fuel = min(frac * fuel_cap, max(weight_lb - empty - 1.0, 0.0))
    payload = weight_lb - empty - fuel
    if payload < 0:
        raise TrimError(f"weight {weight_lb:g} lb is below the empty weight {empty:g} lb")
    moment = weight_lb * cg_in - empty * x_e - sum(fuel * cap / fuel_cap * x for cap, x in tanks)
    x_p = moment / payload if payload > 1e-6 else cg_in
    if not PAYLOAD_STATIONS_IN[0] <= x_p <= PAYLOAD_STATIONS_IN[1]:
        raise TrimError(f"CG {cg_in:g} in at {weight_lb:g} lb cannot be reached with the payload "
                        f"(it would sit at station {x_p:.0f} in)")
    return Loading(tuple(fuel * cap / fuel_cap for cap, _ in tanks), payload, x_p)
