"""The Simulator: one aircraft loaded in JSBSim, in a private sandbox root.

It holds the sandbox (a copy of the aircraft with a trim aid, its engine file and its
propeller tables baked with the current propeller factors), the loading, and the values of
the calibration factors and of added effects. Propeller factors are baked into the propeller
tables, so changing them re-bakes the sandbox's propeller file and reloads the model (a few
milliseconds). Trimming is :mod:`jsbsim_calib.jsbsim.trim` (``sim.trim(cond)`` calls it).

Use it in a ``with`` block: the sandbox is removed when the block ends, also on an exception.
"""
from __future__ import annotations

import shutil
from pathlib import Path
from typing import Mapping

import jsbsim

from ..core.errors import AircraftFileError, ModelError, Problem, raise_if
from ..factors import PROPELLER_FACTORS, REGISTRY, FactorSet
from ..physics.mass import loading
from ..core.tempdirs import make_dir
from . import trim as trim_solver
from .aircraft import (add_effect, add_trim_aid, declared_factors, effect_constants, effect_property_values,
                       effect_values, moment_of_inertia, set_effect_values, set_factor_values,
                       set_moment_of_inertia)
from ..flight.condition import Condition, TrimResult
from .product import (AircraftPaths, Propeller, check_consistent, load_aircraft_geometry, propeller_bytes,
                      read_bem_csv, recover_product, write_aircraft)
from .propulsion import read_baked_factors
from .xml import Tree, copy, parse, read, structure_problems, tostring, tree, write_bytes

INDICATED_SURFACES = ("elevator", "aileron", "rudder")    # fcs/<surface>-ind-deg, where an aircraft defines it
PROPELLER_CACHE = 64         # baked propeller files kept per simulator (a fit's Jacobian: one per propeller factor)


class Simulator:
    """One aircraft loaded in JSBSim, in a private sandbox root, ready to be trimmed.

    ``factors``: values to start from (default: those declared in the aircraft file);
    ``baseline=True``: all factors neutral (the uncalibrated model).
    """

    def __init__(self, root: Path | str, name: str, *, factors: FactorSet | None = None, baseline: bool = False):
        self.root = Path(root).resolve()
        self.paths = AircraftPaths(self.root, name)
        self.name = name
        recover_product(self.paths)                 # a write killed half way: finished or rolled back
        if not self.paths.aircraft_xml.is_file():
            raise ModelError(f"{self.paths.aircraft_xml} not found: run 'jsbsim-calib generate {name}'")
        self.geometry = load_aircraft_geometry(self.root, name)
        self.bem = read_bem_csv(self.paths.propeller_bem)
        on_disk = read(self.paths.aircraft_xml)
        raise_if([Problem(f"line {ln}" if ln else "", why) for ln, why in
                  structure_problems(on_disk, self.root / "engine")], self.paths.aircraft_xml, AircraftFileError)
        declared = FactorSet(declared_factors(on_disk, self.paths.aircraft_xml))
        check_consistent(self.paths, on_disk)
        self._check_baked(declared)
        if not self.paths.engine_xml.is_file():
            raise ModelError(f"{self.paths.engine_xml} not found: run 'jsbsim-calib generate {name}'")
        read(self.paths.engine_xml)                  # a broken engine file named here, not by JSBSim's loader
        self.declared = declared                     # the values the aircraft file declares
        self.factors = FactorSet() if baseline else (factors if factors is not None else declared)
        self._box = make_dir("jsbsim-calib-")
        try:
            (self._box / "aircraft" / name).mkdir(parents=True)
            (self._box / "engine").mkdir()
            (self._box / "systems").mkdir()
            self._tree = read(self.paths.aircraft_xml)
            self.effect_values: dict[str, float] = effect_property_values(self._tree)
            shutil.copy(self.paths.engine_xml, self._box / "engine")
            self._box_paths = AircraftPaths(self._box, name)
            self._propellers: dict[tuple, bytes] = {}
            self._write_sandbox(aircraft=True, propeller=True)
            self._baked = {k: self.factors[k] for k in PROPELLER_FACTORS}
            self.loads = 0
            self.fdm = self._load()
        except BaseException:
            self.close()
            raise
        self.trim_cache: dict = {}
        self.trims = 0
        self.evals = 0

    @classmethod
    def from_dir(cls, aircraft_dir: Path | str, root: Path | str = ".", **kw) -> "Simulator":
        """An aircraft folder anywhere (``<dir>/<name>.xml``, ``geometry.toml``,
        ``propeller_bem.csv``): flown as its XML stands. When the folder is not inside a
        JSBSim root, engines, airfoils and data come from ``root``."""
        d = Path(aircraft_dir).resolve()
        if d.parent.name == "aircraft" and (d.parent.parent / "engine").is_dir():
            return cls(d.parent.parent, d.name, **kw)
        stage = make_dir("jsbsim-calib-root-")
        try:
            (stage / "aircraft").mkdir()
            (stage / "aircraft" / d.name).symlink_to(d, target_is_directory=True)
            for sub in ("engine", "airfoils", "data", "scripts"):
                if (Path(root).resolve() / sub).exists():
                    (stage / sub).symlink_to(Path(root).resolve() / sub, target_is_directory=True)
            sim = cls(stage, d.name, **kw)
        except BaseException:
            shutil.rmtree(stage, ignore_errors=True)
            raise
        sim._stage = stage
        return sim

    @classmethod
    def with_aircraft(cls, root: Path | str, name: str, aircraft: Tree, factors: FactorSet,
                      effect_values_by_property: Mapping[str, float] | None = None) -> "Simulator":
        """A simulator of ``aircraft``, a parsed aircraft file of ``name`` in ``root`` as it
        flies (effects included), at ``factors``; effect values by property (default: as the
        file declares them)."""
        sim = cls(root, name, factors=factors)
        try:
            sim._tree = copy(aircraft)
            sim.effect_values = dict(effect_property_values(aircraft) if effect_values_by_property is None
                                     else effect_values_by_property)
            sim._write_sandbox(aircraft=True, propeller=False)
            sim.fdm = sim._load()
        except BaseException:
            sim.close()
            raise
        return sim

    # ------------------------------------------------------------------ pickling (executors)
    def __getstate__(self) -> dict:
        """A simulator pickles as what it flies: root, name, the aircraft as loaded (effects
        included), factor and effect values. Unpickled, it builds its own sandbox."""
        return {"root": str(self.root), "name": self.name, "tree": tostring(self._tree),
                "factors": self.factors.as_dict(), "extra": self.factors.extra,
                "effect_values": dict(self.effect_values)}

    def __setstate__(self, state: dict) -> None:
        aircraft = tree(parse(state["tree"].decode(), "pickled aircraft"))
        made = Simulator.with_aircraft(state["root"], state["name"], aircraft,
                                       FactorSet(state["factors"], state["extra"]), state["effect_values"])
        self.__dict__.update(made.__dict__)
        made.__dict__.update(_box=None, _stage=None)      # the sandbox is this one's now

    def fresh(self) -> None:
        """Reload the aircraft from the sandbox (factor and effect values as set): a JSBSim
        with no history, so that what runs next depends only on the values, not on what ran
        before (warm starts aside: :attr:`trim_cache`)."""
        self.fdm = self._load()

    def clone(self) -> "Simulator":
        """A second simulator of the aircraft as it stands here (effects and values included)."""
        return Simulator.with_aircraft(self.root, self.name, self._tree, self.factors, self.effect_values)

    # ------------------------------------------------------------------ sandbox
    def _check_baked(self, declared: FactorSet) -> None:
        if not self.paths.propeller_xml.is_file():
            raise ModelError(f"{self.paths.propeller_xml} not found: run 'jsbsim-calib generate {self.name}'")
        baked = read_baked_factors(self.paths.propeller_xml)
        diff = [f"{k}: aircraft file {declared[k]:g}, propeller tables {v:g}" for k, v in baked.items()
                if k in declared and abs(declared[k] - v) > 1e-9]
        if diff:
            raise ModelError(f"{self.paths.aircraft_xml.name} declares propeller factors that differ from those baked "
                             f"into {self.paths.propeller_xml.name} ({'; '.join(diff)}); propeller factors act "
                             f"through the tables: run 'jsbsim-calib generate {self.name}' after editing them")

    def _write_sandbox(self, *, aircraft: bool, propeller: bool) -> None:
        """The sandbox's aircraft (with the trim aid) and/or propeller at the current factors.
        Propeller tables are baked once per set of propeller factors (kept in memory: a fit's
        Jacobian steps a propeller factor and back many times)."""
        if aircraft:
            box = copy(self._tree)
            add_trim_aid(box, self.geometry.propeller.location_m)
            write_aircraft(self._box_paths, self.factors, aircraft=box, effect_values=self.effect_values)
            self._propeller_xml = self._box_paths.propeller_xml     # named in the file just written: read once
        if propeller:
            key = tuple(self.factors[k] for k in PROPELLER_FACTORS)
            baked = self._propellers.get(key)
            if baked is None:
                if len(self._propellers) >= PROPELLER_CACHE:
                    self._propellers.pop(next(iter(self._propellers)))
                baked = self._propellers[key] = propeller_bytes(
                    self._propeller_xml.stem, Propeller(self.geometry, self.bem, self.name), self.factors)
            write_bytes(self._propeller_xml, baked)

    @property
    def sandbox(self) -> Path:
        """The private JSBSim root this simulator flies (aircraft as flown, engine, propeller)."""
        return self._box

    def new_exec(self) -> jsbsim.FGFDMExec:
        """A fresh FGFDMExec on the sandbox root, quiet, nothing loaded (for scripts)."""
        jsbsim.FGJSBBase().debug_lvl = 0      # no start-up banner on stdout (JSON goes there)
        fdm = jsbsim.FGFDMExec(str(self._box))
        fdm.set_debug_level(0)
        fdm.disable_output()
        return fdm

    def property_values(self) -> dict[str, float]:
        """The factor and effect values flown here, by property (propeller factors: in the tables)."""
        out = {f.property: self.factors[name] for name, f in REGISTRY.items() if not f.baked}
        out.update(self.effect_values)
        return out

    def _load(self) -> jsbsim.FGFDMExec:
        fdm = self.new_exec()
        if not fdm.load_model(self.name):
            raise ModelError(f"JSBSim could not load {self.name} from {self._box}")
        # the values first: what the initialization computes then depends on them only, not on
        # the values the sandbox file declared when it was written (a fresh load is history-free)
        for name, f in REGISTRY.items():
            if not f.baked:
                fdm[f.property] = self.factors[name]
        for k, v in self.effect_values.items():
            fdm[k] = v
        fdm["ic/terrain-elevation-ft"] = -30000.0     # no ground contact at any trim point
        fdm["ic/h-sl-ft"] = 5000.0
        fdm["ic/vt-fps"] = 150.0
        fdm.run_ic()
        fdm["propulsion/set-running"] = -1
        fdm.set_trim_status(True)                     # flaps and actuators reach their command at once
        self.loads += 1
        pm = fdm.get_property_manager()
        # outputs an aircraft shows as instruments would (effects that change what is measured)
        self.indicated = {f"{s}_deg": f"fcs/{s}-ind-deg" for s in INDICATED_SURFACES if pm.hasNode(f"fcs/{s}-ind-deg")}
        if pm.hasNode(trim_solver.PITCH_INDICATED):
            self.indicated["theta_deg"] = trim_solver.PITCH_INDICATED
        self.has_position_error = pm.hasNode(trim_solver.POSITION_ERROR)
        return fdm

    def nodes(self, names: tuple[str, ...]) -> list:
        """The property nodes of these names in the JSBSim loaded now (kept per load): a value
        set or read through a node is the one ``fdm[name]`` sets or reads, without the lookup
        of the name (a trim's residual sets 14 and reads 6, about 9 us a residual of 70)."""
        if getattr(self, "_nodes_of", None) is not self.fdm:        # a new load: new nodes
            self._nodes_of, self._nodes = self.fdm, {}
        got = self._nodes.get(names)
        if got is None:
            pm = self.fdm.get_property_manager()
            got = self._nodes[names] = [pm.get_node(n) for n in names]
        return got

    def close(self) -> None:
        self.fdm = self._nodes_of = None
        if self._box is not None:
            shutil.rmtree(self._box, ignore_errors=True)
        if getattr(self, "_stage", None):
            shutil.rmtree(self._stage, ignore_errors=True)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def __del__(self):
        try:
            if self._box is not None:
                shutil.rmtree(self._box, ignore_errors=True)
            if getattr(self, "_stage", None):
                shutil.rmtree(self._stage, ignore_errors=True)
        except Exception:
            pass

    # ------------------------------------------------------------------ effects
    def add_effect(self, effect, values: Mapping[str, float] | None = None) -> None:
        """Add a library effect (:class:`jsbsim_calib.calibration.effects.Effect`) to the loaded
        aircraft and reload."""
        add_effect(self._tree, effect, effect_constants(self.geometry), values)
        for f in effect.factors:
            self.effect_values[f.property] = float((values or {}).get(f.property, f.neutral))
        self._write_sandbox(aircraft=True, propeller=False)
        self.fdm = self._load()
        self.trim_cache.clear()

    def set_effect_values(self, values: Mapping[str, float]) -> None:
        """Set effect factor properties (by property name)."""
        for k, v in values.items():
            if k not in self.effect_values:
                raise ModelError(f"the aircraft has no effect factor {k}")
            self.effect_values[k] = float(v)
            self.fdm[k] = float(v)

    def set_moment_of_inertia(self, axis: str, value: float, note: str = "") -> None:
        """Set an empty-aircraft moment of inertia (``ixx``, ``iyy``, ``izz``; slug ft2) and reload."""
        set_moment_of_inertia(self._tree, axis, value, note)
        self._write_sandbox(aircraft=True, propeller=False)
        self.fdm = self._load()
        self.trim_cache.clear()

    def moment_of_inertia(self, axis: str) -> float:
        return moment_of_inertia(self._tree, axis)

    @property
    def effects(self) -> list[str]:
        return list(effect_values(self._tree))

    def aircraft_tree(self) -> Tree:
        """The aircraft as it flies here (factor and effect values included, no sandbox aids)."""
        set_factor_values(self._tree, self.factors)
        set_effect_values(self._tree, self.effect_values)
        return copy(self._tree)

    # ------------------------------------------------------------------ factors and loading
    def set_factors(self, factors: FactorSet) -> bool:
        """Apply factor values: properties directly, propeller factors by re-baking + reload.
        Returns True when it reloaded (a fresh JSBSim at these values: :meth:`fresh` needs
        not run again)."""
        extra = {f.property: float(factors[n]) for n, f in factors.extra.items()}
        unknown = [k for k in extra if k not in self.effect_values]
        if unknown:
            raise ModelError(f"the aircraft has no effect factor {unknown[0]}")
        prop_changed = any(abs(factors[k] - self._baked[k]) > 0 for k in PROPELLER_FACTORS)
        self.factors = factors
        self.effect_values.update(extra)
        if prop_changed:
            self._write_sandbox(aircraft=False, propeller=True)
            self._baked = {k: factors[k] for k in PROPELLER_FACTORS}
            self.fdm = self._load()              # the values are set before its initialization
            return True
        for name, f in REGISTRY.items():
            if not f.baked:
                self.fdm[f.property] = factors[name]
        for k, v in extra.items():
            self.fdm[k] = v
        return False

    def set_loading(self, weight_lb: float, cg_in: float | None = None, fuel_fraction: float | None = None) -> None:
        """Total weight and CG station through the payload point mass; other stations empty
        (:func:`jsbsim_calib.physics.mass.loading`)."""
        fdm = self.fdm
        for i in range(1, len(self.geometry.mass.stations) + 1):
            fdm[f"inertia/pointmass-weight-lbs[{i}]"] = 0.0
        load = loading(self.geometry, weight_lb, cg_in, fuel_fraction)
        for i, contents in enumerate(load.tank_contents_lb):
            fdm[f"propulsion/tank[{i}]/contents-lbs"] = contents
        fdm["inertia/pointmass-weight-lbs[0]"] = load.payload_lb
        fdm["inertia/pointmass-location-X-inches[0]"] = load.payload_station_in

    # ------------------------------------------------------------------ trims (jsbsim_calib.jsbsim.trim)
    def trim(self, cond: Condition, key=None) -> TrimResult:
        return trim_solver.trim(self, cond, key)

    def trim_level(self, cond: Condition, key=None, speed_tolerance_kt: float = 3.0,
                   vs_tolerance_fpm: float = 100.0) -> TrimResult:
        return trim_solver.trim_level(self, cond, key, speed_tolerance_kt, vs_tolerance_fpm)

    def trim_at_stop(self, cond: Condition, key=None) -> TrimResult:
        return trim_solver.trim_at_stop(self, cond, key)
