"""The Simulator: one aircraft loaded in JSBSim, in a private sandbox root.

It holds the sandbox (a copy of the aircraft with a trim aid, its engine file and its
propeller tables baked with the current propeller factors), the loading, and the values of
the calibration factors and of added effects. Propeller factors are baked into the propeller
tables, so changing them re-bakes the sandbox's propeller file and reloads the model (a few
milliseconds). Trimming is :mod:`jsbsim_calib.jsbsim.trim` (``sim.trim(cond)`` calls it).

Use it in a ``with`` block: the sandbox is removed when the block ends, also on an exception.
"""
from __future__ import annotations

import _thread
import shutil
import threading
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
from .templates import reset_ic_xml
from .xml import Tree, copy, parse, read, structure_problems, tostring, tree, write_bytes

INDICATED_SURFACES = ("elevator", "aileron", "rudder")    # fcs/<surface>-ind-deg, where an aircraft defines it
PROPELLER_CACHE = 64         # baked propeller files kept per simulator (a fit's Jacobian: one per propeller factor)
KEPT_JSBSIMS = 6             # loaded JSBSims kept per simulator, one per set of propeller factors (about 3 MB each)
START_SPEED_FPS = 150.0      # [ft/s] true airspeed of the initial conditions after a load (never zero)
DONT_RUN_IC = 2              # JSBSim's FGFDMExec::DONT_EXECUTE_RUN_IC (reset_to_initial_conditions)
INTERRUPT_DELAY_S = 0.05     # a Ctrl-C caught in a finalizer is raised again this much later


def _interrupt_main_later() -> None:
    """A Ctrl-C caught in a finalizer, raised again in the main thread once the finalizer has
    returned. Raised there and then (``_thread.interrupt_main`` from the main thread, or from a
    thread whose start the finalizer waits for), Python prints it as an ignored exception and
    carries on: ``tests/test_interrupts.py`` catches both."""
    timer = threading.Timer(INTERRUPT_DELAY_S, _thread.interrupt_main)
    timer.daemon = True
    timer.start()


class Simulator:
    """One aircraft loaded in JSBSim, in a private sandbox root, ready to be trimmed.

    ``factors``: values to start from (default: those declared in the aircraft file);
    ``baseline=True``: all factors neutral (the uncalibrated model).
    """

    warm_reset = True            # fresh() resets a JSBSim that has only trimmed (see fresh)
    _fdm = None
    _used = True
    _trimming = False
    resets = 0

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
            self._reset_ic = self._box / "fresh-load.xml"
            write_bytes(self._reset_ic, reset_ic_xml(START_SPEED_FPS).encode())
            self._propellers: dict[tuple, bytes] = {}
            self._kept: dict[tuple, jsbsim.FGFDMExec] = {}      # loaded JSBSims by propeller factors
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
        """A JSBSim with no history (factor and effect values as set), so that what runs next
        depends only on the values, not on what ran before (warm starts aside:
        :attr:`trim_cache`): the loaded one reset (:meth:`_reset`: a fresh load's bits) where it
        has only trimmed since its load or its last reset, else the aircraft loaded anew from the
        sandbox (the JSBSim was handed out through :attr:`fdm`: what was done with it is not
        known)."""
        if self.warm_reset and self._fdm is not None and not self._used:
            self._reset()
        else:
            self.fdm = self._load()

    @property
    def fdm(self) -> jsbsim.FGFDMExec:
        """The loaded JSBSim. Handed out here, outside a trim, it may be used for anything: the
        next :meth:`fresh` loads the aircraft anew instead of resetting it."""
        if not self._trimming:
            self._used = True
        return self._fdm

    @fdm.setter
    def fdm(self, value) -> None:
        self._fdm, self._used = value, False

    def distrust(self) -> None:
        """The JSBSim here may carry a history that a reset does not clear (a failed trim left NaN
        in its engine): the next :meth:`fresh` loads the aircraft anew."""
        self._used = True

    def _trimmed(self, solve, cond: Condition, *args) -> TrimResult:
        """A trim (``solve``: a function of :mod:`jsbsim_calib.jsbsim.trim`), which leaves a JSBSim
        that :meth:`_reset` brings back to a fresh load's bits."""
        self._trimming = True
        try:
            return solve(self, cond, *args)
        finally:
            self._trimming = False

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
            self._kept.clear()                    # JSBSims of the aircraft as it was
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
        pm = fdm.get_property_manager()
        # what the trims and the loading write, as loaded: a reset sets them back (fresh)
        self._as_loaded = {n: fdm[n] for n in trim_solver.WRITES + self._loading_properties(fdm) if pm.hasNode(n)}
        self._dt = fdm.get_delta_t()
        self._initialize(fdm)
        self.loads += 1
        # outputs an aircraft shows as instruments would (effects that change what is measured)
        self.indicated = {f"{s}_deg": f"fcs/{s}-ind-deg" for s in INDICATED_SURFACES if pm.hasNode(f"fcs/{s}-ind-deg")}
        if pm.hasNode(trim_solver.PITCH_INDICATED):
            self.indicated["theta_deg"] = trim_solver.PITCH_INDICATED
        self.has_position_error = pm.hasNode(trim_solver.POSITION_ERROR)
        return fdm

    def _initialize(self, fdm: jsbsim.FGFDMExec) -> None:
        """What follows a load: the factor and effect values first (what the initialization
        computes then depends on them only, not on the values the sandbox file declared when it
        was written: a fresh load is history-free), then initial conditions clear of the ground
        and the engine running."""
        for name, f in REGISTRY.items():
            if not f.baked:
                fdm[f.property] = self.factors[name]
        for k, v in self.effect_values.items():
            fdm[k] = v
        fdm["ic/terrain-elevation-ft"] = -30000.0     # no ground contact at any trim point
        fdm["ic/h-sl-ft"] = 5000.0
        fdm["ic/vt-fps"] = START_SPEED_FPS
        fdm.run_ic()
        fdm["propulsion/set-running"] = -1
        fdm.set_trim_status(True)                     # flaps and actuators reach their command at once

    def _reset(self) -> None:
        """The loaded JSBSim brought back to a fresh load's bits (about 0.1 ms against a load's
        7): what the trims wrote set back to its values at the load (the loading counts: the
        reset's initialization runs with it), the models re-initialized, the initial conditions
        read from a file that sets them exactly (no round-off wind left), then what follows a
        load. ``tests/test_executor.py`` checks every property against a fresh load's after
        trims of every kind, and the main job's test rewrites the product byte for byte."""
        fdm = self._fdm
        for n, v in self._as_loaded.items():
            fdm[n] = v
        fdm.set_dt(self._dt)                          # as loaded (a trim suspends the integration)
        fdm.reset_to_initial_conditions(DONT_RUN_IC)
        fdm.load_ic(str(self._reset_ic), False)
        self._initialize(fdm)
        self.resets += 1

    @staticmethod
    def _loading_properties(fdm: jsbsim.FGFDMExec) -> tuple[str, ...]:
        """The point masses and tank contents of the loaded aircraft (what set_loading writes)."""
        names = []
        for pattern in ("inertia/pointmass-", "/contents-lbs"):
            names += [line.split()[0] for line in fdm.query_property_catalog(pattern).splitlines()
                      if line.strip() and line.split()[0].startswith(("inertia/pointmass-", "propulsion/tank"))]
        return tuple(dict.fromkeys(names))

    def nodes(self, names: tuple[str, ...]) -> list:
        """The property nodes of these names in the JSBSim loaded now (kept per load): a value
        set or read through a node is the one ``fdm[name]`` sets or reads, without the lookup
        of the name (a trim's residual sets 14 and reads 6, about 9 us a residual of 70)."""
        if getattr(self, "_nodes_of", None) is not self._fdm:       # a new load: new nodes
            self._nodes_of, self._nodes = self._fdm, {}
        got = self._nodes.get(names)
        if got is None:
            pm = self._fdm.get_property_manager()
            got = self._nodes[names] = [pm.get_node(n) for n in names]
        return got

    def close(self) -> None:
        self.fdm = self._nodes_of = None
        self._kept = {}
        self._remove_sandbox()

    def _remove_sandbox(self) -> None:
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
            self._remove_sandbox()
        except KeyboardInterrupt:
            _interrupt_main_later()
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
            self._fdm[k] = float(v)

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
        """Apply factor values: properties directly, propeller factors by the JSBSim of their
        tables (:meth:`_switch_propeller`). Returns True when it changed the JSBSim (a fresh one
        at these values: :meth:`fresh` needs not run again)."""
        extra = {f.property: float(factors[n]) for n, f in factors.extra.items()}
        unknown = [k for k in extra if k not in self.effect_values]
        if unknown:
            raise ModelError(f"the aircraft has no effect factor {unknown[0]}")
        prop_changed = any(abs(factors[k] - self._baked[k]) > 0 for k in PROPELLER_FACTORS)
        self.factors = factors
        self.effect_values.update(extra)
        if prop_changed:
            self._switch_propeller()
            return True
        for name, f in REGISTRY.items():
            if not f.baked:
                self._fdm[f.property] = factors[name]
        for k, v in extra.items():
            self._fdm[k] = v
        return False

    def _switch_propeller(self) -> None:
        """Fly the propeller factors now set: on a JSBSim kept from an earlier switch to them,
        reset (:meth:`_reset`: a fresh load's bits), or on the aircraft loaded with the tables
        baked for them. The JSBSim left keeps its tables for the next switch back (a fit's
        Jacobian steps a propeller factor and back, and a worker takes its columns in any
        order), unless it was handed out (:attr:`fdm`)."""
        if self._fdm is not None and not self._used and self.warm_reset:
            self._kept[tuple(self._baked[k] for k in PROPELLER_FACTORS)] = self._fdm     # the tables it flies
            while len(self._kept) > KEPT_JSBSIMS:
                self._kept.pop(next(iter(self._kept)))
        self._baked = {k: self.factors[k] for k in PROPELLER_FACTORS}
        kept = self._kept.pop(tuple(self._baked[k] for k in PROPELLER_FACTORS), None)
        if kept is not None:
            self._fdm, self._used = kept, False
            self._reset()
        else:
            self._write_sandbox(aircraft=False, propeller=True)
            self.fdm = self._load()              # the values are set before its initialization

    def set_loading(self, weight_lb: float, cg_in: float | None = None, fuel_fraction: float | None = None) -> None:
        """Total weight and CG station through the payload point mass; other stations empty
        (:func:`jsbsim_calib.physics.mass.loading`)."""
        fdm = self._fdm
        for i in range(1, len(self.geometry.mass.stations) + 1):
            fdm[f"inertia/pointmass-weight-lbs[{i}]"] = 0.0
        load = loading(self.geometry, weight_lb, cg_in, fuel_fraction)
        for i, contents in enumerate(load.tank_contents_lb):
            fdm[f"propulsion/tank[{i}]/contents-lbs"] = contents
        fdm["inertia/pointmass-weight-lbs[0]"] = load.payload_lb
        fdm["inertia/pointmass-location-X-inches[0]"] = load.payload_station_in

    # ------------------------------------------------------------------ trims (jsbsim_calib.jsbsim.trim)
    def trim(self, cond: Condition, key=None) -> TrimResult:
        return self._trimmed(trim_solver.trim, cond, key)

    def trim_level(self, cond: Condition, key=None, speed_tolerance_kt: float = 3.0,
                   vs_tolerance_fpm: float = 100.0) -> TrimResult:
        return self._trimmed(trim_solver.trim_level, cond, key, speed_tolerance_kt, vs_tolerance_fpm)

    def trim_at_stop(self, cond: Condition, key=None) -> TrimResult:
        return self._trimmed(trim_solver.trim_at_stop, cond, key)
