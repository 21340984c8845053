"""Aircraft geometry: read and validate the human-editable ``geometry.toml``.

Every dimensional value in the file carries its unit (``"64.5 in"``, or
``{ values = [...], unit = "in" }`` for lists); this module converts all of them to SI
and checks them all before anything else runs. One call reports every problem with the
file and the dotted field path, e.g. ``wing.chord: unit 'deg' is not a length``.
"""
from __future__ import annotations

import math
import re
import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from ..core.errors import GeometryError, Problem
from ..core.units import UNITS

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

# Reference data an aircraft folder can name ([data] table of geometry.toml)
DATA_KINDS = ("poh_climb", "poh_cruise", "flight_test", "flap_climb", "flight_test_results", "g1000")

_QTY = re.compile(r"^\s*([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)\s*(\S*)\s*$")


# --------------------------------------------------------------------------- dataclasses
@dataclass(frozen=True)
class ControlSurface:
    """A trailing-edge control surface or flap on a lifting surface."""

    name: str                      # flap | aileron | elevator | rudder
    kind: str                      # plain | slotted_flap
    y_start_m: float               # [m] spanwise start (from the surface root line)
    y_end_m: float                 # [m] spanwise end
    chord_fraction: float          # [-] control chord / local chord
    deflection_min_rad: float      # [rad]
    deflection_max_rad: float      # [rad]
    detents_rad: tuple[float, ...] = ()   # [rad] flap detents
    transit_time_s: float = 0.0    # [s] full-travel time (flaps)


@dataclass(frozen=True)
class LiftingSurface:
    """One lifting surface, described by stations from its root to its tip.

    For horizontal surfaces ``y_m`` is the spanwise coordinate (the surface is mirrored to
    the left side); for the vertical tail ``y_m`` is the height above its root and the
    surface lies in the plane of symmetry.
    """

    name: str                      # wing | horizontal_tail | vertical_tail
    airfoil: str
    y_m: np.ndarray                # [m] stations, root to tip
    chord_m: np.ndarray            # [m]
    x_le_m: np.ndarray             # [m] leading-edge station (structural x, aft +)
    z_m: np.ndarray                # [m] chord-line height (structural z, up +)
    incidence_rad: np.ndarray      # [rad] section incidence relative to the body x axis
    dihedral_rad: float            # [rad]
    fuselage_half_width_m: float   # [m] strips inboard of this do not lift
    vertical: bool
    controls: tuple[ControlSurface, ...] = ()

    @property
    def symmetric(self) -> bool:
        return not self.vertical

    @property
    def semispan_m(self) -> float:
        return float(self.y_m[-1] - self.y_m[0])

    @property
    def span_m(self) -> float:
        return 2.0 * self.semispan_m if self.symmetric else self.semispan_m

    @property
    def area_m2(self) -> float:
        """Planform area, both sides for symmetric surfaces, including carry-through."""
        a = float(np.trapezoid(self.chord_m, self.y_m))
        return 2.0 * a if self.symmetric else a

    def dense(self, n_per_panel: int = 200) -> dict[str, np.ndarray]:
        """Stations densified with linear interpolation (exact area moments by quadrature)."""
        y = np.unique(np.concatenate([np.linspace(a, b, n_per_panel) for a, b in zip(self.y_m[:-1], self.y_m[1:])]))
        out = {"y": y}
        for k, v in (("chord", self.chord_m), ("x_le", self.x_le_m), ("z", self.z_m), ("incidence", self.incidence_rad)):
            out[k] = np.interp(y, self.y_m, v)
        if not self.vertical:
            out["z"] = out["z"] + (y - self.y_m[0]) * math.tan(self.dihedral_rad)
        return out

    def _chord_weighted(self, values: np.ndarray, d: dict[str, np.ndarray]) -> float:
        return float(np.trapezoid(values * d["chord"], d["y"]) / np.trapezoid(d["chord"], d["y"]))

    @property
    def mac_m(self) -> float:
        d = self.dense()
        return self._chord_weighted(d["chord"], d)

    @property
    def x_quarter_mac_m(self) -> float:
        """Station of the area-weighted quarter-chord point (the mean quarter chord)."""
        d = self.dense()
        return self._chord_weighted(d["x_le"] + 0.25 * d["chord"], d)

    @property
    def z_mean_m(self) -> float:
        d = self.dense()
        return self._chord_weighted(d["z"], d)

    def control(self, name: str) -> ControlSurface | None:
        for c in self.controls:
            if c.name == name:
                return c
        return None


@dataclass(frozen=True)
class Fuselage:
    length_m: float                # [m]
    x_nose_m: float                # [m]
    max_width_m: float             # [m]
    max_height_m: float            # [m]
    z_axis_m: float                # [m]
    wetted_area_m2: float          # [m^2]


@dataclass(frozen=True)
class DragItem:
    """Drag area D/q of a part that strip theory does not cover, and its height."""

    name: str
    area_m2: float                 # [m^2] D/q
    z_m: float                     # [m] height where the drag acts (structural z)


@dataclass(frozen=True)
class PropellerSpec:
    model: str
    diameter_m: float              # [m]
    blades: int
    hub_radius_m: float            # [m]
    airfoil: str
    chord_max_m: float             # [m]
    chord_tip_m: float             # [m]
    location_m: np.ndarray         # [m] (x, y, z)
    sense: int                     # +1 clockwise from the cockpit
    ixx_kgm2: float                # [kg m^2]
    pitch_m: float | None = None   # [m] fixed pitch
    # constant-speed propellers
    constant_speed: bool = False
    min_pitch_deg: float = 0.0     # [deg] blade angle at 0.75 R
    max_pitch_deg: float = 0.0     # [deg]
    min_rpm: float = 0.0
    max_rpm: float = 0.0
    reference_pitch_deg: float = 0.0   # [deg] blade angle at 0.75 R of the described blade

    @property
    def beta75_deg(self) -> float:
        if self.pitch_m is not None:
            return math.degrees(math.atan(self.pitch_m / (2 * math.pi * 0.375 * self.diameter_m)))
        return self.reference_pitch_deg


@dataclass(frozen=True)
class EngineSpec:
    model: str
    max_power_w: float             # [W]
    rated_rpm: float               # [rpm]
    idle_rpm: float                # [rpm]
    displacement_m3: float         # [m^3]
    bore_m: float                  # [m]
    stroke_m: float                # [m]
    cylinders: int
    compression_ratio: float
    max_map_pa: float              # [Pa]
    min_map_pa: float              # [Pa]
    location_m: np.ndarray         # [m]
    full_rich_below_m: float = 0.0 # [m] pressure altitude below which POH climbs are full rich


@dataclass(frozen=True)
class Tank:
    name: str
    location_m: np.ndarray         # [m]
    capacity_m3: float             # [m^3]
    unusable_m3: float             # [m^3]


@dataclass(frozen=True)
class MassStation:
    name: str
    location_m: np.ndarray         # [m]
    mass_kg: float                 # [kg]


@dataclass(frozen=True)
class MassSpec:
    empty_mass_kg: float           # [kg]
    empty_cg_m: np.ndarray         # [m]
    max_mass_kg: float             # [kg]
    radius_of_gyration: np.ndarray # [-] Rx, Ry, Rz
    cg_envelope_mass_kg: np.ndarray
    cg_envelope_fwd_m: np.ndarray
    cg_envelope_aft_m: np.ndarray
    stations: tuple[MassStation, ...]


@dataclass(frozen=True)
class GearContact:
    name: str
    type: str                      # BOGEY | STRUCTURE
    location_m: np.ndarray
    spring_n_per_m: float
    damping_n_s_per_m: float
    damping_rebound_n_s_per_m: float | None = None
    max_steer_rad: float = 0.0
    brake_group: str = "NONE"


@dataclass(frozen=True)
class Operations:
    poh_cg_m: float                # [m]
    poh_fuel_fraction: float       # [-]
    asi_kias_kt: np.ndarray        # [kt]
    asi_kcas_kt: np.ndarray        # [kt]
    # the flight envelope (optional; NaN: not stated): data outside it are refused or warned
    # about (jsbsim_calib.data.envelope)
    service_ceiling_m: float = math.nan     # [m] pressure altitude where the best climb falls to 100 ft/min
    never_exceed_kias_kt: float = math.nan  # [kt] Vne, indicated
    stall_landing_kias_kt: float = math.nan  # [kt] Vso: stall speed, landing flaps, max weight, indicated

    @property
    def airspeed_calibration(self) -> tuple[np.ndarray, np.ndarray]:
        """The airspeed-calibration table: (KIAS points, KCAS points) [kt], flaps up."""
        return self.asi_kias_kt, self.asi_kcas_kt


@dataclass(frozen=True)
class ReferenceSpec:
    wing_area_m2: float            # [m^2]
    span_m: float                  # [m]


@dataclass(frozen=True)
class AircraftGeometry:
    """Everything generate needs, in SI."""

    name: str
    title: str
    path: Path
    reference: ReferenceSpec
    wing: LiftingSurface
    horizontal_tail: LiftingSurface
    vertical_tail: LiftingSurface
    fuselage: Fuselage
    drag: tuple[DragItem, ...]
    propeller: PropellerSpec
    engine: EngineSpec
    fuel_type: str
    tanks: tuple[Tank, ...]
    mass: MassSpec
    gear: tuple[GearContact, ...]
    operations: Operations
    control_travel_file: Path | None = None
    data_files: dict[str, Path] = field(default_factory=dict)   # kind -> reference data file

    @property
    def surfaces(self) -> tuple[LiftingSurface, ...]:
        return (self.wing, self.horizontal_tail, self.vertical_tail)

    @property
    def cbar_m(self) -> float:
        return self.wing.mac_m

    @property
    def aero_reference_point_m(self) -> np.ndarray:
        """AERORP: the wing's mean quarter chord (x), on the wing chord plane (z)."""
        return np.array([self.wing.x_quarter_mac_m, 0.0, self.wing.z_mean_m])


# --------------------------------------------------------------------------- reader
class _Reader:
    """Reads fields from a parsed TOML document, collecting every problem."""

    def __init__(self, path: Path, doc: dict[str, Any]):
        self.path = path
        self.doc = doc
        self.problems: list[Problem] = []
        self.read: set[str] = set()          # every key asked for (unknown keys: the others)

    def bad(self, where: str, message: str) -> None:
        self.problems.append(Problem(where, message))

    def raw(self, where: str, required: bool = True, mark: bool = True) -> Any:
        if mark:
            self.read.add(where)
        node: Any = self.doc
        for part in re.split(r"\.", where):
            m = re.match(r"^(\w+)\[(\d+)\]$", part)
            key, idx = (m.group(1), int(m.group(2))) if m else (part, None)
            if not isinstance(node, dict) or key not in node:
                if required:
                    self.bad(where, "missing")
                return None
            node = node[key]
            if idx is not None:
                if not isinstance(node, list) or idx >= len(node):
                    if required:
                        self.bad(where, "missing")
                    return None
                node = node[idx]
        return node

    def _unit(self, where: str, unit: str, dim: str) -> float | None:
        table = UNITS[dim]
        if unit in table:
            return table[unit]
        for other, t in UNITS.items():
            if unit in t:
                self.bad(where, f"unit '{unit}' is a {other} unit, expected {dim} ({', '.join(u for u in table if u)})")
                return None
        self.bad(where, f"unknown unit '{unit}', expected {dim} ({', '.join(u for u in table if u)})")
        return None

    def qty(self, where: str, dim: str, *, required: bool = True, default: float | None = None,
            positive: bool = False, nonneg: bool = False) -> float:
        v = self.raw(where, required=required and default is None)
        if v is None:
            return float("nan") if default is None else default
        if isinstance(v, (int, float)) and not isinstance(v, bool):
            if dim == "dimensionless":
                val = float(v)
            else:
                self.bad(where, f"needs a unit, e.g. \"{v} {next(iter(UNITS[dim]))}\"")
                return float("nan")
        elif isinstance(v, str):
            m = _QTY.match(v)
            if not m:
                self.bad(where, f"cannot read '{v}' as a number with a unit")
                return float("nan")
            f = self._unit(where, m.group(2), dim)
            if f is None:
                return float("nan")
            val = float(m.group(1)) * f
        else:
            self.bad(where, f"expected a quantity string like \"1.0 {next(iter(UNITS[dim]))}\", got {type(v).__name__}")
            return float("nan")
        if not math.isfinite(val):
            self.bad(where, f"{v!r} is not a finite number")
            return float("nan")
        if positive and not val > 0:
            self.bad(where, f"must be positive, got {v}")
        if nonneg and val < 0:
            self.bad(where, f"must not be negative, got {v}")
        return val

    def arr(self, where: str, dim: str, *, n: int | None = None, required: bool = True,
            nonneg: bool = False, positive: bool = False, increasing: bool = False) -> np.ndarray:
        v = self.raw(where, required=required)
        if v is None:
            return np.full(n or 0, np.nan)
        if not isinstance(v, dict) or "values" not in v:
            self.bad(where, "expected { values = [...], unit = \"...\" }")
            return np.full(n or 0, np.nan)
        vals = v["values"]
        if not isinstance(vals, list) or not all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in vals):
            self.bad(where, "values must be a list of numbers")
            return np.full(n or 0, np.nan)
        unit = v.get("unit", "")
        f = self._unit(where, unit, dim) if (unit or dim != "dimensionless") else 1.0
        if f is None:
            return np.full(len(vals), np.nan)
        a = np.asarray(vals, dtype=float) * f
        if not np.all(np.isfinite(a)):
            self.bad(where, f"values must be finite numbers, got {vals}")
        if n is not None and len(a) != n:
            self.bad(where, f"expected {n} values, got {len(a)}")
        if nonneg and np.any(a < 0):
            self.bad(where, f"values must not be negative, got {vals}")
        if positive and np.any(a <= 0):
            self.bad(where, f"values must be positive, got {vals}")
        if increasing and np.any(np.diff(a) <= 0):
            self.bad(where, f"values must increase, got {vals}")
        return a

    def text(self, where: str, *, required: bool = True, default: str = "", choices: Sequence[str] | None = None) -> str:
        v = self.raw(where, required=required and not default)
        if v is None:
            return default
        if not isinstance(v, str):
            self.bad(where, f"expected text, got {v!r}")
            return default
        if choices is not None and v not in choices:
            self.bad(where, f"'{v}' is not one of {', '.join(choices)}")
        return v

    def number(self, where: str, *, required: bool = True, default: float | None = None,
               lo: float | None = None, hi: float | None = None) -> float:
        v = self.raw(where, required=required and default is None)
        if v is None:
            return float("nan") if default is None else default
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
            self.bad(where, f"expected a plain (finite) number, got {v!r}")
            return float("nan")
        if (lo is not None and v < lo) or (hi is not None and v > hi):
            self.bad(where, f"{v} is outside [{lo}, {hi}]")
        return float(v)

    def integer(self, where: str, **kw) -> int:
        """A whole number (0 when missing or bad: the problem is recorded)."""
        v = self.number(where, **kw)
        return int(v) if math.isfinite(v) else 0

    def count(self, where: str, key: str) -> int:
        v = self.raw(where, required=False, mark=False)
        if v is None:
            return 0
        if not isinstance(v, dict):
            self.bad(where, "expected a table")
            return 0
        lst = v.get(key, [])
        if not isinstance(lst, list):
            self.bad(f"{where}.{key}", "expected a list of tables ([[...]])")
            return 0
        return len(lst)


def _surface(r: _Reader, key: str, vertical: bool, known_airfoils: set[str] | None) -> LiftingSurface:
    y = r.arr(f"{key}.y", "length", nonneg=True, increasing=True)
    n = len(y)
    if n < 2 and not r.problems:
        r.bad(f"{key}.y", "needs at least two stations (root and tip)")
    chord = r.arr(f"{key}.chord", "length", n=n, positive=True)
    x_le = r.arr(f"{key}.x_leading_edge", "length", n=n)
    z = r.arr(f"{key}.z", "length", n=n)
    inc = r.arr(f"{key}.incidence", "angle", n=n)
    airfoil = r.text(f"{key}.airfoil")
    if known_airfoils is not None and airfoil and airfoil not in known_airfoils:
        r.bad(f"{key}.airfoil", f"unknown airfoil '{airfoil}'; stored airfoils: {', '.join(sorted(known_airfoils))}"
              " (add one with 'jsbsim-calib airfoil NAME')")
    dihedral = r.qty(f"{key}.dihedral", "angle", default=0.0)
    half_width = r.qty(f"{key}.fuselage_half_width", "length", default=0.0, nonneg=True)
    controls = []
    for i in range(r.count(key, "controls")):
        w = f"{key}.controls[{i}]"
        name = r.text(f"{w}.name", choices=("flap", "aileron", "elevator", "rudder"))
        kind = r.text(f"{w}.kind", default="plain", choices=("plain", "slotted_flap"))
        y0 = r.qty(f"{w}.y_start", "length", nonneg=True)
        y1 = r.qty(f"{w}.y_end", "length", positive=True)
        if y0 >= y1:
            r.bad(f"{w}.y_end", "must be larger than y_start")
        if len(y) and np.isfinite(y1) and y1 > y[-1] + 1e-9:
            r.bad(f"{w}.y_end", "lies beyond the tip station")
        cf = r.number(f"{w}.chord_fraction", lo=0.05, hi=0.6)
        defl = r.arr(f"{w}.deflection", "angle", n=2)
        if len(defl) == 2 and defl[0] >= defl[1]:
            r.bad(f"{w}.deflection", "give [minimum, maximum]")
        det = r.arr(f"{w}.detents", "angle", required=False)
        tt = r.qty(f"{w}.transit_time", "time", default=0.0, nonneg=True)
        controls.append(ControlSurface(name, kind, y0, y1, cf, float(defl[0]) if len(defl) else 0.0,
                                       float(defl[1]) if len(defl) > 1 else 0.0, tuple(det.tolist()), tt))
    return LiftingSurface(key, airfoil, y, chord, x_le, z, inc, dihedral, half_width, vertical, tuple(controls))


def _vec3(r: _Reader, where: str, dim: str = "length") -> np.ndarray:
    return r.arr(where, dim, n=3)


def _propeller(r: _Reader, known: set[str] | None) -> PropellerSpec:
    pitch = r.qty("propeller.pitch", "length", required=False, default=float("nan"))
    cs = r.raw("propeller.constant_speed", required=False)
    prop = PropellerSpec(
        model=r.text("propeller.model", default="propeller"),
        diameter_m=r.qty("propeller.diameter", "length", positive=True),
        blades=r.integer("propeller.blades", lo=1, hi=8),
        hub_radius_m=r.qty("propeller.hub_radius", "length", positive=True),
        airfoil=r.text("propeller.airfoil"),
        chord_max_m=r.qty("propeller.chord_max", "length", positive=True),
        chord_tip_m=r.qty("propeller.chord_tip", "length", positive=True),
        location_m=_vec3(r, "propeller.location"),
        sense=r.integer("propeller.sense", default=1.0),
        ixx_kgm2=r.qty("propeller.ixx", "inertia", positive=True),
        pitch_m=None if math.isnan(pitch) else pitch,
        constant_speed=cs is not None,
        min_pitch_deg=math.degrees(r.qty("propeller.constant_speed.min_pitch", "angle")) if cs else 0.0,
        max_pitch_deg=math.degrees(r.qty("propeller.constant_speed.max_pitch", "angle")) if cs else 0.0,
        min_rpm=r.number("propeller.constant_speed.min_rpm") if cs else 0.0,
        max_rpm=r.number("propeller.constant_speed.max_rpm") if cs else 0.0,
        reference_pitch_deg=math.degrees(r.qty("propeller.constant_speed.reference_pitch", "angle")) if cs else 0.0,
    )
    if prop.pitch_m is None and not prop.constant_speed:
        r.bad("propeller.pitch", "missing (a fixed-pitch propeller needs its geometric pitch; "
              "a constant-speed one needs a [propeller.constant_speed] table)")
    if known is not None and prop.airfoil and prop.airfoil not in known:
        r.bad("propeller.airfoil", f"unknown airfoil '{prop.airfoil}'; stored airfoils: {', '.join(sorted(known))}")
    return prop


def _engine(r: _Reader) -> EngineSpec:
    eng = EngineSpec(
        model=r.text("engine.model", default="engine"),
        max_power_w=r.qty("engine.max_power", "power", positive=True),
        rated_rpm=r.number("engine.rated_rpm", lo=500, hi=10000),
        idle_rpm=r.number("engine.idle_rpm", lo=100, hi=3000),
        displacement_m3=r.qty("engine.displacement", "volume", positive=True),
        bore_m=r.qty("engine.bore", "length", positive=True),
        stroke_m=r.qty("engine.stroke", "length", positive=True),
        cylinders=r.integer("engine.cylinders", lo=1, hi=18),
        compression_ratio=r.number("engine.compression_ratio", lo=4, hi=15),
        max_map_pa=r.qty("engine.max_manifold_pressure", "pressure", positive=True),
        min_map_pa=r.qty("engine.min_manifold_pressure", "pressure", positive=True),
        location_m=_vec3(r, "engine.location"),
        full_rich_below_m=r.qty("engine.full_rich_below", "length", default=0.0, nonneg=True),
    )
    r.text("engine.type", choices=("piston",))
    return eng


def _tanks(r: _Reader) -> tuple[Tank, ...]:
    tanks = tuple(Tank(r.text(f"fuel.tanks[{i}].name"), _vec3(r, f"fuel.tanks[{i}].location"),
                       r.qty(f"fuel.tanks[{i}].capacity", "volume", positive=True),
                       r.qty(f"fuel.tanks[{i}].unusable", "volume", default=0.0, nonneg=True))
                  for i in range(r.count("fuel", "tanks")))
    if not tanks:
        r.bad("fuel.tanks", "missing (at least one [[fuel.tanks]])")
    return tanks


def _mass(r: _Reader) -> MassSpec:
    stations = tuple(MassStation(r.text(f"mass.stations[{i}].name"), _vec3(r, f"mass.stations[{i}].location"),
                                 r.qty(f"mass.stations[{i}].weight", "mass", nonneg=True))
                     for i in range(r.count("mass", "stations")))
    env_w = r.arr("mass.cg_envelope_weight", "mass", positive=True, increasing=True)
    return MassSpec(
        empty_mass_kg=r.qty("mass.empty_weight", "mass", positive=True),
        empty_cg_m=_vec3(r, "mass.empty_cg"),
        max_mass_kg=r.qty("mass.max_weight", "mass", positive=True),
        radius_of_gyration=r.arr("mass.radius_of_gyration", "dimensionless", n=3, positive=True),
        cg_envelope_mass_kg=env_w,
        cg_envelope_fwd_m=r.arr("mass.cg_envelope_forward", "length", n=len(env_w)),
        cg_envelope_aft_m=r.arr("mass.cg_envelope_aft", "length", n=len(env_w)),
        stations=stations,
    )


def _gear(r: _Reader) -> tuple[GearContact, ...]:
    gear = []
    for i in range(r.count("gear", "contacts")):
        w = f"gear.contacts[{i}]"
        reb = r.raw(f"{w}.damping_rebound", required=False)
        gear.append(GearContact(
            r.text(f"{w}.name"), r.text(f"{w}.type", choices=("BOGEY", "STRUCTURE")), _vec3(r, f"{w}.location"),
            r.qty(f"{w}.spring", "stiffness", positive=True), r.qty(f"{w}.damping", "damping", nonneg=True),
            None if reb is None else r.qty(f"{w}.damping_rebound", "damping", nonneg=True),
            r.qty(f"{w}.steerable", "angle", default=0.0, nonneg=True),
            r.text(f"{w}.brake_group", default="NONE", choices=("NONE", "LEFT", "RIGHT", "CENTER", "NOSE", "TAIL"))))
    if not any(g.type == "BOGEY" for g in gear):
        r.bad("gear.contacts", "needs at least one BOGEY contact (wheel)")
    return tuple(gear)


def _operations(r: _Reader) -> Operations:
    kias = r.arr("operations.airspeed_calibration_kias", "speed", increasing=True)
    kcas = r.arr("operations.airspeed_calibration_kcas", "speed", n=len(kias), increasing=True)
    def optional(key: str, dim: str) -> float:
        return r.qty(f"operations.{key}", dim, required=False, positive=r.raw(f"operations.{key}", False) is not None)

    return Operations(r.qty("operations.poh_cg", "length"),
                      r.number("operations.poh_fuel_fraction", lo=0.0, hi=1.0),
                      kias / 0.514444444444, kcas / 0.514444444444,
                      optional("service_ceiling", "length"), optional("never_exceed_speed", "speed") / 0.514444444444,
                      optional("stall_speed_landing", "speed") / 0.514444444444)


def _data_files(r: _Reader, path: Path) -> tuple[dict[str, Path], Path | None]:
    """The reference data files ([data]) and the control-travel table, relative to the root."""
    data_files = {}
    for kind, rel in (r.raw("data", required=False) or {}).items():
        if kind not in DATA_KINDS:
            r.bad(f"data.{kind}", f"unknown data kind; known: {', '.join(DATA_KINDS)}")
            continue
        if not isinstance(rel, str):
            r.bad(f"data.{kind}", "expected a path relative to the repository root")
            continue
        pth = path.parent.parent.parent / rel
        if not pth.is_file():
            r.bad(f"data.{kind}", f"file not found: {pth}")
        data_files[kind] = pth
    travel = r.text("controls.travel_file", required=False)
    travel_path = (path.parent.parent.parent / travel) if travel else None
    if travel_path is not None and not travel_path.is_file():
        r.bad("controls.travel_file", f"file not found: {travel_path}")
    return data_files, travel_path


def _check_consistency(r: _Reader, ref: ReferenceSpec, surfaces: Sequence[LiftingSurface]) -> None:
    wing = surfaces[0]
    for s in surfaces:
        if len(s.y_m) and np.all(np.isfinite(s.y_m)) and s.y_m[0] != 0.0 and not s.vertical:
            r.bad(f"{s.name}.y", "the first station must be the plane of symmetry (0)")
    if np.isfinite(ref.span_m) and len(wing.y_m) and np.isfinite(wing.y_m[-1]):
        if abs(2 * wing.y_m[-1] - ref.span_m) > 0.02 * ref.span_m:
            r.bad("wing.y", f"tip station gives span {2 * wing.y_m[-1]:.3f} m but reference.span is {ref.span_m:.3f} m")


# keys a geometry file may hold that nothing reads (notes for the reader)
ACCEPTED_KEYS = ("aircraft.description", "reference.aerodynamic_reference_point")


def _unknown_keys(r: _Reader) -> None:
    """Every key of the file that no field asked for (a misspelt or invented key is not
    silently ignored), with the keys known at its place."""
    def walk(node: Any, prefix: str) -> None:
        items = node.items() if isinstance(node, dict) else ()
        for key, value in items:
            here = f"{prefix}.{key}" if prefix else str(key)
            if here in r.read:
                continue
            below = [p for p in r.read if p.startswith((here + ".", here + "["))]
            if not below:
                known = sorted({re.split(r"[.\[]", p[len(prefix) + 1 if prefix else 0:])[0] for p in r.read
                                if not prefix or p.startswith(prefix + ".")})
                r.bad(here, f"unknown key; known keys here: {', '.join(known)}")
            elif isinstance(value, list):
                for i, item in enumerate(value):
                    walk(item, f"{here}[{i}]")
            else:
                walk(value, here)
    walk(r.doc, "")


def _check_masses(r: _Reader, mass: MassSpec) -> None:
    """Weights that contradict each other: maximum below empty, an envelope beyond the maximum."""
    kg = 2.20462262
    if np.isfinite(mass.empty_mass_kg) and np.isfinite(mass.max_mass_kg) and mass.max_mass_kg < mass.empty_mass_kg:
        r.bad("mass.max_weight", f"{mass.max_mass_kg * kg:.0f} lb is below mass.empty_weight "
                                 f"{mass.empty_mass_kg * kg:.0f} lb")
    env = np.asarray(mass.cg_envelope_mass_kg, float)
    if len(env) and np.all(np.isfinite(env)) and np.isfinite(mass.max_mass_kg) and env[-1] > 1.001 * mass.max_mass_kg:
        r.bad("mass.cg_envelope_weight", f"reaches {env[-1] * kg:.0f} lb, above mass.max_weight "
                                         f"{mass.max_mass_kg * kg:.0f} lb")
    fwd, aft = (np.asarray(a, float) for a in (mass.cg_envelope_fwd_m, mass.cg_envelope_aft_m))
    if len(fwd) == len(aft) and np.any(np.isfinite(fwd) & np.isfinite(aft) & (fwd >= aft)):
        r.bad("mass.cg_envelope_forward", "a forward CG limit at or aft of its aft limit (cg_envelope_aft)")


def load_geometry(path: str | Path, airfoil_dirs: Sequence[Path] | None = None) -> AircraftGeometry:
    """Read and validate ``geometry.toml``. Raises GeometryError listing every problem."""
    path = Path(path)
    if not path.is_file():
        raise GeometryError(path, "file not found")
    try:
        doc = tomllib.loads(path.read_text())
    except tomllib.TOMLDecodeError as exc:
        raise GeometryError(path, f"not valid TOML: {exc}") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise GeometryError(path, f"cannot read: {exc}") from None
    known = None
    if airfoil_dirs is not None:
        known = {p.stem for d in airfoil_dirs if Path(d).is_dir() for p in Path(d).glob("*.csv")}
    r = _Reader(path, doc)

    name = r.text("aircraft.name")
    title = r.text("aircraft.title", default=name or "aircraft")
    ref = ReferenceSpec(r.qty("reference.wing_area", "area", positive=True),
                        r.qty("reference.span", "length", positive=True))
    wing = _surface(r, "wing", False, known)
    ht = _surface(r, "horizontal_tail", False, known)
    vt = _surface(r, "vertical_tail", True, known)

    fus = Fuselage(r.qty("fuselage.length", "length", positive=True), r.qty("fuselage.x_nose", "length"),
                   r.qty("fuselage.max_width", "length", positive=True),
                   r.qty("fuselage.max_height", "length", positive=True),
                   r.qty("fuselage.z_axis", "length", default=0.0),
                   r.qty("fuselage.wetted_area", "area", positive=True))
    drag_doc = r.raw("drag", required=False) or {}
    drag = tuple(DragItem(k, r.qty(f"drag.{k}.area", "area", nonneg=True), r.qty(f"drag.{k}.z", "length"))
                 for k in drag_doc)
    prop = _propeller(r, known)
    eng = _engine(r)
    fuel_type = r.text("fuel.type", choices=("AVGAS",))
    tanks = _tanks(r)
    mass = _mass(r)
    gear = _gear(r)
    ops = _operations(r)
    data_files, travel_path = _data_files(r, path)
    _check_consistency(r, ref, (wing, ht, vt))
    _check_masses(r, mass)
    for k in ACCEPTED_KEYS:
        r.raw(k, required=False)
    _unknown_keys(r)
    if r.problems:
        raise GeometryError(path, r.problems)
    return AircraftGeometry(name, title, path, ref, wing, ht, vt, fus, drag, prop, eng, fuel_type, tanks, mass,
                            gear, ops, travel_path, data_files)
