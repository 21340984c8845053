"""Any JSBSim aircraft, one the workbench did not generate, flown by the Simulator and the trim solver.

:func:`read_foreign` reads what the simulator and the trims need from the aircraft's XML (and
its engine and propeller files): mass (empty weight and CG, point masses, tanks), the
propeller (fixed pitch or constant speed, diameter, pitch and governor ranges), the engine
(piston: rated power and RPM), the flap travel and the control-surface ranges where the FCS
gives them, the wing area. :func:`foreign_geometry` turns it into a :class:`ForeignGeometry`,
which has the fields of :class:`~jsbsim_calib.physics.geometry.AircraftGeometry` the simulator,
the trims, the evaluation and the probes use (and no others: there is no strip geometry).
:class:`ForeignSimulator` is a :class:`~jsbsim_calib.jsbsim.simulator.Simulator` on a sandbox copy
of the foreign root: the aircraft folder copied, the root's ``engine/`` and ``systems/``
linked, the aircraft file as it stands plus the sandbox's trim aid, less its data outputs
(``<output>`` files and sockets). It has no calibration
factors and takes no effects.

Conventions (:class:`Conventions`; the same as for a generated aircraft where they can be):

* weight: tanks filled to a share of their capacity (the data's, else the convention's, else
  the file's own contents), the rest on the aircraft's point masses;
* CG: a data row's CG (flight-test snapshots) is reached by moving point mass 0 along x (in
  the file's stations; the other point masses empty); without one (POH points) the CG is the
  one the aircraft gives: the payload spread over its point masses in proportion to their
  declared weights (``poh_cg_in`` moves it instead);
* mixture: the POH procedure of a generated aircraft (same fuel/air ratios: full rich below
  ``full_rich_below_ft``, best power above and in cruise), through FGPiston's lever;
* flaps: ``fcs/flap-cmd-norm`` = flap angle / the FCS's largest flap setting;
* % power: of ``rated_power_hp`` (the POH's engine) or else the engine file's ``maxhp``;
* KIAS -> KCAS: ``airspeed_calibration`` (identity unless borrowed from a workbench aircraft);
* trims: the workbench's trim solver (the trim aid acts only in the sandbox).
"""
from __future__ import annotations

import math
import shutil
import warnings
from dataclasses import dataclass, field, replace
from pathlib import Path

import jsbsim
import numpy as np

from ..core.errors import ModelError, TrimError
from ..factors import FactorSet
from ..core.tempdirs import make_dir
from ..physics.geometry import (AircraftGeometry, ControlSurface, MassSpec, MassStation, Operations, PropellerSpec,
                                ReferenceSpec, Tank)
from ..core.units import FT, HP, IN, LB_PER_GAL_AVGAS, LBM, US_GAL
from .aircraft import add_trim_aid
from ..flight.condition import Condition, TrimResult
from .probes import StallCase, default_conditions, default_stall_cases
from .product import AircraftPaths, load_aircraft_geometry
from .simulator import Simulator
from .xml import Tree, copy, read, sub

LENGTH_IN = {"IN": 1.0, "FT": 12.0, "M": 1.0 / IN, "CM": 0.01 / IN, "MM": 0.001 / IN}
WEIGHT_LB = {"LBS": 1.0, "LB": 1.0, "KG": 1.0 / LBM}
AREA_FT2 = {"FT2": 1.0, "M2": 1.0 / FT**2}
SURFACES = ("elevator", "aileron", "rudder")
NAN = float("nan")


# --------------------------------------------------------------------------- what the files give
@dataclass(frozen=True)
class PointMass:
    name: str
    weight_lb: float                       # [lb] as declared
    location_in: tuple[float, float, float]


@dataclass(frozen=True)
class FuelTank:
    capacity_lb: float                     # [lb]
    contents_lb: float                     # [lb] as declared
    location_in: tuple[float, float, float]


@dataclass(frozen=True)
class ForeignPropeller:
    file: str
    diameter_in: float                     # [in]
    blades: int
    constant_speed: bool                   # the file gives a governor range (<maxrpm>)
    min_pitch_deg: float                   # [deg]
    max_pitch_deg: float                   # [deg]
    min_rpm: float
    max_rpm: float
    location_in: tuple[float, float, float]
    sense: int


@dataclass(frozen=True)
class ForeignEngine:
    file: str
    max_hp: float                          # [hp] <maxhp>
    max_rpm: float
    idle_rpm: float


@dataclass(frozen=True)
class ForeignAircraft:
    """What a JSBSim aircraft file (with its engine and propeller) says, in its own units (lb, in, ft)."""

    name: str
    title: str
    path: Path
    wing_area_ft2: float
    wingspan_ft: float
    chord_ft: float
    empty_weight_lb: float
    empty_cg_in: tuple[float, float, float]
    point_masses: tuple[PointMass, ...]
    tanks: tuple[FuelTank, ...]
    engine: ForeignEngine
    propeller: ForeignPropeller
    flap_max_deg: float | None             # the FCS's largest flap setting (None: not found)
    surface_ranges_deg: dict[str, tuple[float, float]]
    contact_x_in: tuple[float, float]      # [in] fore and aft ends of the contact points

    @property
    def fuel_capacity_lb(self) -> float:
        return sum(t.capacity_lb for t in self.tanks)

    @property
    def fuel_share(self) -> float:
        """The file's fuel contents as a share of capacity."""
        return sum(t.contents_lb for t in self.tanks) / max(self.fuel_capacity_lb, 1e-9)

    @property
    def loaded_weight_lb(self) -> float:
        return self.empty_weight_lb + sum(p.weight_lb for p in self.point_masses) + sum(t.contents_lb for t in self.tanks)


def _number(el, what: str, source: Path) -> float:
    try:
        return float(el.text)
    except (AttributeError, TypeError, ValueError):
        raise ModelError(f"{source}: {what} missing or not a number") from None


def _quantity(parent, tag: str, units: dict[str, float], default_unit: str, source: Path, default=None) -> float:
    el = parent.find(tag) if parent is not None else None
    if el is None:
        if default is not None:
            return default
        raise ModelError(f"{source}: <{tag}> missing")
    unit = (el.get("unit") or default_unit).upper()
    if unit not in units:
        raise ModelError(f"{source}: <{tag}> unit '{unit}' not understood (known: {', '.join(units)})")
    return _number(el, f"<{tag}>", source) * units[unit]


def _location(el, source: Path) -> tuple[float, float, float]:
    if el is None:
        raise ModelError(f"{source}: a <location> is missing")
    f = LENGTH_IN[(el.get("unit") or "IN").upper()]
    return tuple(_number(el.find(a), f"location <{a}>", source) * f for a in "xyz")


def _find_file(paths: AircraftPaths, sub_dir: str, name: str, what: str) -> Path:
    for c in (paths.folder / sub_dir / f"{name}.xml", paths.root / "engine" / f"{name}.xml"):
        if c.is_file():
            return c
    raise ModelError(f"{what} file '{name}' of {paths.aircraft_xml} not found in {paths.folder / sub_dir} or "
                     f"{paths.root / 'engine'}")


def _mass(root, source: Path) -> tuple[float, tuple, tuple[PointMass, ...]]:
    mb = root.find("mass_balance")
    if mb is None:
        raise ModelError(f"{source}: no <mass_balance>")
    empty = _quantity(mb, "emptywt", WEIGHT_LB, "LBS", source)
    cg = _location(mb.find("location[@name='CG']"), source)
    masses = tuple(PointMass(pm.get("name") or f"point mass {i}", _quantity(pm, "weight", WEIGHT_LB, "LBS", source),
                             _location(pm.find("location"), source))
                   for i, pm in enumerate(mb.findall("pointmass")))
    return empty, cg, masses


def _tanks(root, source: Path) -> tuple[FuelTank, ...]:
    out = []
    for t in root.findall("propulsion/tank"):
        if (t.get("type") or "FUEL").upper() != "FUEL":
            continue
        cap = _quantity(t, "capacity", WEIGHT_LB, "LBS", source)
        out.append(FuelTank(cap, _quantity(t, "contents", WEIGHT_LB, "LBS", source, default=0.0),
                            _location(t.find("location"), source)))
    return tuple(out)


def _engine(paths: AircraftPaths, eng_el) -> ForeignEngine:
    f = _find_file(paths, "Engines", eng_el.get("file"), "engine")
    root = read(f).getroot()
    if root.tag != "piston_engine":
        raise ModelError(f"{f}: a <{root.tag}>; the trim solver flies piston engines with a propeller only")
    return ForeignEngine(eng_el.get("file"), _number(root.find("maxhp"), "<maxhp>", f),
                         _number(root.find("maxrpm"), "<maxrpm>", f),
                         float(root.findtext("idlerpm") or 600.0))


def _propeller(paths: AircraftPaths, thr_el) -> ForeignPropeller:
    f = _find_file(paths, "Engines", thr_el.get("file"), "propeller")
    root = read(f).getroot()
    if root.tag != "propeller":
        raise ModelError(f"{f}: a <{root.tag}>; the trim solver flies propellers only")
    lo, hi = float(root.findtext("minpitch") or 0.0), float(root.findtext("maxpitch") or 0.0)
    governed = root.find("maxrpm") is not None and hi > lo
    return ForeignPropeller(thr_el.get("file"), _quantity(root, "diameter", LENGTH_IN, "IN", f),
                            int(float(root.findtext("numblades") or 2)), governed, lo, hi,
                            float(root.findtext("minrpm") or 0.0), float(root.findtext("maxrpm") or 0.0),
                            _location(thr_el.find("location"), paths.aircraft_xml),
                            int(float(thr_el.findtext("sense") or 1)))


def _propulsion(paths: AircraftPaths, root) -> tuple[ForeignEngine, ForeignPropeller]:
    engines = root.findall("propulsion/engine")
    if len(engines) != 1 or engines[0].find("thruster") is None:
        raise ModelError(f"{paths.aircraft_xml}: {len(engines)} engines; the trim solver flies one piston engine "
                         "with a propeller")
    return _engine(paths, engines[0]), _propeller(paths, engines[0].find("thruster"))


def _inputs(component) -> list[str]:
    return [(i.text or "").strip().lstrip("-") for i in component.findall("input")]


def flap_max_deg(root) -> float | None:
    """The largest flap setting the FCS reaches from ``fcs/flap-cmd-norm`` (a kinematic's last
    setting, scaled; or an aerosurface_scale's range), None when the FCS does not say."""
    for comp in root.iter("kinematic"):
        if any(i.endswith("flap-cmd-norm") for i in _inputs(comp)) and comp.find("noscale") is None:
            pos = [float(s.findtext("position")) for s in comp.findall("traverse/setting")]
            if pos:
                return max(pos)
    for comp in root.iter("aerosurface_scale"):
        if any(i.endswith("flap-cmd-norm") for i in _inputs(comp)) and comp.find("range/max") is not None:
            return float(comp.findtext("range/max"))
    return None


def surface_ranges_deg(root) -> dict[str, tuple[float, float]]:
    """Surface travel [deg] from the aerosurface_scale components whose output is the surface's
    position in degrees (gain 1) or radians (gain 0.01745)."""
    out = {}
    for comp in root.iter("aerosurface_scale"):
        target = (comp.findtext("output") or "").strip()
        gain = float(comp.findtext("gain") or 1.0)
        for s in SURFACES:
            hit = f"{s}-pos-deg" in target and abs(gain - 1) < 1e-6 or f"{s}-pos-rad" in target and abs(gain - 0.01745) < 1e-3
            if hit and comp.find("range/min") is not None and s not in out:
                out[s] = (float(comp.findtext("range/min")), float(comp.findtext("range/max")))
    return out


def _contacts_x(root, source: Path) -> tuple[float, float]:
    xs = [_location(c.find("location"), source)[0] for c in root.findall("ground_reactions/contact")]
    return (min(xs), max(xs)) if xs else (-100.0, 300.0)


def read_foreign(root: Path | str, name: str) -> ForeignAircraft:
    """Read aircraft ``name`` of JSBSim root ``root`` (``aircraft/NAME/NAME.xml``). Raises
    :class:`ModelError` naming the file and element that is missing or not understood."""
    paths = AircraftPaths(Path(root).resolve(), name)
    if not paths.aircraft_xml.is_file():
        known = sorted(p.name for p in (paths.root / "aircraft").iterdir() if p.is_dir()) if (paths.root / "aircraft").is_dir() else []
        raise ModelError(f"{paths.aircraft_xml} not found (aircraft in {paths.root}: {', '.join(known[:40]) or 'none'})")
    src = paths.aircraft_xml
    el = read(src).getroot()
    metrics = el.find("metrics")
    empty, cg, masses = _mass(el, src)
    engine, prop = _propulsion(paths, el)
    return ForeignAircraft(
        name, el.get("name") or name, src, _quantity(metrics, "wingarea", AREA_FT2, "FT2", src),
        _quantity(metrics, "wingspan", LENGTH_IN, "FT", src) / 12.0, _quantity(metrics, "chord", LENGTH_IN, "FT", src) / 12.0,
        empty, cg, masses, _tanks(el, src), engine, prop, flap_max_deg(el), surface_ranges_deg(el), _contacts_x(el, src))


# --------------------------------------------------------------------------- loading
@dataclass(frozen=True)
class ForeignLoading:
    """Tank contents and point masses (weight, x station) that give a weight and CG."""

    tank_contents_lb: tuple[float, ...]
    point_masses: tuple[tuple[float, float], ...]     # per point mass: ([lb], [in] x station)

    def cg_in(self, ac: ForeignAircraft) -> float:
        moments = [(ac.empty_weight_lb, ac.empty_cg_in[0])]
        moments += [(w, t.location_in[0]) for w, t in zip(self.tank_contents_lb, ac.tanks)]
        moments += list(self.point_masses)
        return sum(w * x for w, x in moments) / sum(w for w, _ in moments)


def _fuel(ac: ForeignAircraft, weight_lb: float, share: float) -> tuple[float, ...]:
    fuel = min(share * ac.fuel_capacity_lb, max(weight_lb - ac.empty_weight_lb - 1.0, 0.0))
    return tuple(fuel * t.capacity_lb / max(ac.fuel_capacity_lb, 1e-9) for t in ac.tanks)


def _spread(ac: ForeignAircraft, payload: float) -> tuple[tuple[float, float], ...]:
    """The payload over the point masses in proportion to their declared weights (equally if all are empty)."""
    declared = [p.weight_lb for p in ac.point_masses]
    total = sum(declared)
    shares = [w / total for w in declared] if total > 0 else [1.0 / len(declared)] * len(declared)
    return tuple((payload * s, p.location_in[0]) for s, p in zip(shares, ac.point_masses))


def foreign_loading(ac: ForeignAircraft, weight_lb: float, cg_in: float | None = None,
                    fuel_share: float | None = None) -> ForeignLoading:
    """The loading of the module's conventions. Raises :class:`TrimError` when the weight or CG
    cannot be reached (below the empty weight, no point mass, payload outside the aircraft)."""
    tanks = _fuel(ac, weight_lb, ac.fuel_share if fuel_share is None else fuel_share)
    payload = weight_lb - ac.empty_weight_lb - sum(tanks)
    if payload < -1e-6:
        raise TrimError(f"weight {weight_lb:g} lb is below the empty weight {ac.empty_weight_lb:g} lb")
    if not ac.point_masses:
        if payload > 1e-6:
            raise TrimError(f"{ac.name} declares no point mass to carry {payload:.0f} lb of payload")
        return ForeignLoading(tanks, ())
    rest = tuple((0.0, p.location_in[0]) for p in ac.point_masses[1:])
    if cg_in is None:
        return ForeignLoading(tanks, _spread(ac, payload))
    empty = ForeignLoading(tanks, ((0.0, ac.point_masses[0].location_in[0]),) + rest)
    moment = weight_lb * cg_in - empty.cg_in(ac) * (weight_lb - payload)
    x_p = moment / payload if payload > 1e-6 else cg_in
    lo, hi = ac.contact_x_in
    if not lo <= x_p <= hi:
        raise TrimError(f"CG {cg_in:g} in at {weight_lb:g} lb cannot be reached with the payload (it would sit at "
                        f"station {x_p:.0f} in, outside the aircraft's contact points {lo:g} to {hi:g} in)")
    return ForeignLoading(tanks, ((payload, x_p),) + rest)


# --------------------------------------------------------------------------- the geometry the simulator sees
@dataclass(frozen=True)
class Conventions:
    """Operating conventions a JSBSim file does not state (see the module doc)."""

    full_rich_below_ft: float = 3000.0            # [ft] POH leaning altitude (the C172S POH's)
    fuel_share: float | None = None               # [-] None: the file's own contents
    poh_cg_in: float | None = None                # [in] None: the CG the aircraft gives
    rated_power_hp: float | None = None           # [hp] basis of % power; None: the engine file's maxhp
    max_weight_lb: float | None = None            # [lb] for check; None: the file's loaded weight
    airspeed_calibration_kt: tuple[tuple[float, ...], tuple[float, ...]] = ((40.0, 160.0), (40.0, 160.0))


def conventions_like(geometry: AircraftGeometry, **changes) -> Conventions:
    """The operating conventions of a workbench aircraft (its POH): leaning altitude, fuel share,
    rated power, maximum weight, airspeed calibration. Not its CG: stations are the file's own."""
    base = Conventions(geometry.engine.full_rich_below_m / FT, geometry.operations.poh_fuel_fraction, None,
                       geometry.engine.max_power_w / HP, geometry.mass.max_mass_kg / LBM,
                       (tuple(geometry.operations.asi_kias_kt), tuple(geometry.operations.asi_kcas_kt)))
    return replace(base, **changes)


@dataclass(frozen=True)
class ForeignEngineSpec:
    """The engine fields of EngineSpec the trims use."""

    model: str
    max_power_w: float             # [W] basis of % power
    rated_rpm: float
    idle_rpm: float
    full_rich_below_m: float       # [m]


@dataclass(frozen=True)
class ForeignSurface:
    """A lifting surface as far as the file tells: its controls."""

    name: str
    controls: tuple[ControlSurface, ...] = ()

    def control(self, name: str) -> ControlSurface | None:
        return next((c for c in self.controls if c.name == name), None)


@dataclass(frozen=True)
class ForeignGeometry:
    """The fields of :class:`AircraftGeometry` the simulator, trims, evaluation and probes use."""

    name: str
    title: str
    path: Path
    reference: ReferenceSpec
    wing: ForeignSurface
    horizontal_tail: ForeignSurface
    vertical_tail: ForeignSurface
    propeller: PropellerSpec
    engine: ForeignEngineSpec
    fuel_type: str
    tanks: tuple[Tank, ...]
    mass: MassSpec
    operations: Operations
    cbar_m: float
    control_travel_file: Path | None = None
    data_files: dict[str, Path] = field(default_factory=dict)
    stated_max_weight_lb: float = NAN    # [lb] the envelope's limit; NaN: a JSBSim file does not state it


def _control(name: str, lo_deg: float, hi_deg: float) -> ControlSurface:
    return ControlSurface(name, "plain", NAN, NAN, NAN, math.radians(lo_deg), math.radians(hi_deg))


def _surfaces(ac: ForeignAircraft) -> tuple[ForeignSurface, ForeignSurface, ForeignSurface]:
    r = ac.surface_ranges_deg
    wing = [_control("aileron", *r["aileron"])] if "aileron" in r else []
    if ac.flap_max_deg is not None:
        wing.append(_control("flap", 0.0, ac.flap_max_deg))
    tail = (_control("elevator", *r["elevator"]),) if "elevator" in r else ()
    fin = (_control("rudder", *r["rudder"]),) if "rudder" in r else ()
    return ForeignSurface("wing", tuple(wing)), ForeignSurface("horizontal_tail", tail), ForeignSurface("vertical_tail", fin)


def _propeller_spec(p: ForeignPropeller) -> PropellerSpec:
    return PropellerSpec(p.file, p.diameter_in * IN, p.blades, NAN, "", NAN, NAN, np.array(p.location_in) * IN, p.sense,
                         NAN, None, p.constant_speed, p.min_pitch_deg, p.max_pitch_deg, p.min_rpm, p.max_rpm,
                         p.min_pitch_deg)


def _mass_spec(ac: ForeignAircraft, conv: Conventions) -> MassSpec:
    w = conv.max_weight_lb or ac.loaded_weight_lb
    cg = foreign_loading(ac, w, conv.poh_cg_in, conv.fuel_share).cg_in(ac)
    stations = tuple(MassStation(p.name, np.array(p.location_in) * IN, p.weight_lb * LBM) for p in ac.point_masses)
    return MassSpec(ac.empty_weight_lb * LBM, np.array(ac.empty_cg_in) * IN, w * LBM, np.full(3, NAN),
                    np.array([w * LBM]), np.array([cg * IN]), np.array([cg * IN]), stations)


def foreign_geometry(ac: ForeignAircraft, conv: Conventions = Conventions()) -> ForeignGeometry:
    """The geometry the simulator sees; the CG envelope is the one CG of the conventions at the
    maximum weight."""
    wing, tail, fin = _surfaces(ac)
    mass = _mass_spec(ac, conv)
    tanks = tuple(Tank(f"tank {i}", np.array(t.location_in) * IN, t.capacity_lb / LB_PER_GAL_AVGAS * US_GAL, 0.0)
                  for i, t in enumerate(ac.tanks))
    kias, kcas = (np.array(v, float) for v in conv.airspeed_calibration_kt)
    ops = Operations(float(mass.cg_envelope_fwd_m[0]), ac.fuel_share if conv.fuel_share is None else conv.fuel_share,
                     kias, kcas)
    engine = ForeignEngineSpec(ac.engine.file, (conv.rated_power_hp or ac.engine.max_hp) * HP, ac.engine.max_rpm,
                               ac.engine.idle_rpm, conv.full_rich_below_ft * FT)
    return ForeignGeometry(ac.name, ac.title, ac.path, ReferenceSpec(ac.wing_area_ft2 * FT**2, ac.wingspan_ft * FT),
                           wing, tail, fin, _propeller_spec(ac.propeller), engine, "AVGAS", tanks, mass, ops,
                           ac.chord_ft * FT, stated_max_weight_lb=conv.max_weight_lb or NAN)


# --------------------------------------------------------------------------- the simulator
def _stage_root(root: Path, name: str, box: Path) -> None:
    """The sandbox root: the aircraft folder copied, the root's engine/ and systems/ linked."""
    shutil.copytree(root / "aircraft" / name, box / "aircraft" / name, symlinks=True)
    for sub_dir in ("engine", "systems"):
        if (root / sub_dir).is_dir():
            (box / sub_dir).symlink_to(root / sub_dir, target_is_directory=True)


def sandbox_copy(tree: Tree, location_m) -> Tree:
    """A copy of the aircraft with the sandbox's thrust-line trim aid (external_reactions) and
    without its data outputs (``<output>``: files and sockets a trim would otherwise open)."""
    box = copy(tree)
    root = box.getroot()
    for out in root.findall("output"):
        root.remove(out)
    if root.find("external_reactions") is None and root.find("ground_reactions") is None:
        sub(root, "external_reactions")
    add_trim_aid(box, location_m)
    return box


class ForeignSimulator(Simulator):
    """A JSBSim aircraft the workbench did not generate, in a sandbox copy of its root, ready to
    be trimmed (``with ForeignSimulator(root, name) as sim: ...``). No calibration factors, no
    effects; ``conventions`` as in the module doc."""

    warm_reset = False       # its systems are not ours: a fresh start loads it anew (Simulator.fresh)

    def __init__(self, root: Path | str, name: str, conventions: Conventions = Conventions()):
        self.root = Path(root).resolve()
        self.name = name
        self.paths = AircraftPaths(self.root, name)
        self.aircraft = read_foreign(self.root, name)
        self.conventions = conventions
        self.geometry = foreign_geometry(self.aircraft, conventions)
        self.bem = None
        self.factors = FactorSet()
        self.effect_values: dict[str, float] = {}
        self._baked: dict[str, float] = {}
        self._box = make_dir("jsbsim-calib-foreign-")
        try:
            _stage_root(self.root, name, self._box)
            self._tree = read(self.aircraft.path)
            self._write_sandbox(aircraft=True, propeller=False)
            self.loads = 0
            self.fdm = self._load()
        except BaseException:
            self.close()
            raise
        self.trim_cache: dict = {}
        self.trims = 0
        self.evals = 0

    def _write_sandbox(self, *, aircraft: bool, propeller: bool) -> None:
        if aircraft:
            path = self._box / "aircraft" / self.name / f"{self.name}.xml"
            path.unlink(missing_ok=True)           # a copy (never a link into the foreign root)
            sandbox_copy(self._tree, self.geometry.propeller.location_m).write(
                str(path), xml_declaration=True, encoding="UTF-8")

    def _load(self):
        fdm = self.new_exec()
        if not fdm.load_model(self.name):
            raise ModelError(f"JSBSim could not load {self.name} from {self._box}")
        fdm["ic/terrain-elevation-ft"] = -30000.0
        fdm["ic/h-sl-ft"] = 5000.0
        fdm["ic/vt-fps"] = 150.0
        fdm.run_ic()
        fdm["propulsion/set-running"] = -1
        fdm.set_trim_status(True)
        self.loads += 1
        pm = fdm.get_property_manager()
        self.indicated = {}
        if not pm.hasNode("fcs/aileron-pos-deg") and pm.hasNode("fcs/left-aileron-pos-deg"):
            self.indicated["aileron_deg"] = "fcs/left-aileron-pos-deg"      # + trailing edge down, left wing
        self.has_position_error = False
        return fdm

    def clone(self) -> "ForeignSimulator":
        return ForeignSimulator(self.root, self.name, self.conventions)

    def __getstate__(self) -> dict:
        """Pickles (executors) as root, name and conventions; unpickled, it builds its own sandbox."""
        return {"root": str(self.root), "name": self.name, "conventions": self.conventions}

    def __setstate__(self, state: dict) -> None:
        made = ForeignSimulator(state["root"], state["name"], state["conventions"])
        self.__dict__.update(made.__dict__)
        made.__dict__.update(_box=None, _stage=None)      # the sandbox is this one's now

    def property_values(self) -> dict[str, float]:
        return {}

    def aircraft_tree(self) -> Tree:
        return copy(self._tree)

    def add_effect(self, effect, values=None) -> None:
        raise ModelError(f"{self.name} is not a workbench aircraft: effects are added to generated aircraft only")

    def set_factors(self, factors: FactorSet) -> bool:
        if factors.changed():
            raise ModelError(f"{self.name} is not a workbench aircraft: it has no calibration factors")
        return False

    def set_loading(self, weight_lb: float, cg_in: float | None = None, fuel_fraction: float | None = None) -> None:
        """Weight and CG by the module's conventions (tanks, then the point masses)."""
        ac = self.aircraft
        load = foreign_loading(ac, weight_lb, self.conventions.poh_cg_in if cg_in is None else cg_in,
                               self.conventions.fuel_share if fuel_fraction is None else fuel_fraction)
        for i, contents in enumerate(load.tank_contents_lb):
            self.fdm[f"propulsion/tank[{i}]/contents-lbs"] = contents
        for i, (w, x) in enumerate(load.point_masses):
            self.fdm[f"inertia/pointmass-weight-lbs[{i}]"] = w
            self.fdm[f"inertia/pointmass-location-X-inches[{i}]"] = x

    def _no_flaps(self, cond: Condition) -> TrimResult | None:
        if cond.flaps_deg and self.aircraft.flap_max_deg is None:
            return TrimResult(cond, False, f"{self.name}'s FCS gives no flap travel (fcs/flap-cmd-norm)")
        return None

    def trim(self, cond: Condition, key=None) -> TrimResult:
        return self._no_flaps(cond) or super().trim(cond, key)

    def trim_level(self, cond: Condition, key=None, speed_tolerance_kt: float = 3.0,
                   vs_tolerance_fpm: float = 100.0) -> TrimResult:
        return self._no_flaps(cond) or super().trim_level(cond, key, speed_tolerance_kt, vs_tolerance_fpm)

    def trim_at_stop(self, cond: Condition, key=None) -> TrimResult:
        return self._no_flaps(cond) or super().trim_at_stop(cond, key)


def stall_cases(sim: ForeignSimulator) -> tuple[StallCase, ...]:
    """The stall searches of ``check`` for a foreign aircraft: maximum weight at its one CG,
    flaps up and fully down (no duplicate CG limits)."""
    seen, out = set(), []
    for case in default_stall_cases(sim):
        if (case.weight_lb, case.cg_in, case.flaps_deg) not in seen:
            seen.add((case.weight_lb, case.cg_in, case.flaps_deg))
            out.append(case)
    return tuple(out)


def check_conditions(sim: ForeignSimulator) -> dict[str, Condition]:
    """The derivative conditions of ``check`` for a foreign aircraft: cruise and climb at maximum
    weight and its one CG (the CG limits of a workbench aircraft collapse to it)."""
    return {k.replace(" fwd CG", ""): c for k, c in default_conditions(sim).items() if "fwd" in k}


def resolve_root(text: str | Path) -> Path:
    """A JSBSim root; ``jsbsim`` is the jsbsim package's own root (its stock aircraft)."""
    if str(text) == "jsbsim":
        return Path(jsbsim.get_default_root_dir())
    return Path(text)


def foreign_simulator(root: Path | str, like: str, foreign_root: Path | str, name: str | None = None,
                      **changes) -> ForeignSimulator:
    """Aircraft ``name`` (default ``like``) of ``foreign_root``, with the POH conventions of workbench
    aircraft ``like`` when ``root`` has one by that name (else the defaults of :class:`Conventions`),
    ``changes`` to them by field (e.g. ``poh_cg_in=41.0``)."""
    geometry = AircraftPaths(Path(root), like).geometry
    conv = conventions_like(load_aircraft_geometry(Path(root), like)) if geometry.is_file() else Conventions()
    if not geometry.is_file() and "max_weight_lb" not in changes:
        warnings.warn(f"{name or like}: no workbench aircraft of that name lends its POH conventions; the JSBSim file "
                      "does not state a maximum weight, ceiling or speed limits (the data's envelope is not checked), "
                      "% power is of the engine file's maxhp, KIAS = KCAS, full rich below 3,000 ft")
    return ForeignSimulator(resolve_root(foreign_root), name or like, replace(conv, **changes))
