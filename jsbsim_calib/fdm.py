"""The one module that drives JSBSim: load an aircraft in a sandbox, set factors, loading
and atmosphere, and trim it to a flight condition.

Trim: JSBSim evaluates the accelerations of a given state (``run_ic`` + the engine's
steady state + one frame with integration suspended); a Newton-type root finder
(MINPACK ``hybr``) drives the six body accelerations to zero by moving angle of attack,
sideslip, elevator, aileron, rudder and either the throttle (flight path given) or the
pitch attitude (throttle given, flight path free: a climb at full throttle). The state is
straight flight at a given bank angle or a coordinated turn. A failed trim says why and
never leaves NaN behind for the next point.

Propeller factors are baked into the propeller tables, so changing them rewrites the
propeller file in the sandbox and reloads the model (a few milliseconds).
"""
from __future__ import annotations

import copy
import math
import shutil
import tempfile
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Mapping

import jsbsim
import numpy as np
from lxml import etree
from scipy.optimize import root

from . import xmlmodel
from .physics.atmosphere import cas_to_tas, isa_pressure, isa_temperature
from .build import AircraftPaths, load_aircraft_geometry, propeller_tree, read_bem_csv
from .physics.engine import poh_mixture
from .physics.mass import loading
from .errors import ModelError, TrimError
from .factors import PROPELLER_FACTORS, REGISTRY, FactorSet
from .units import FT, G0, KT, LB_PER_GAL_AVGAS, LBM, T0, LAPSE

G_FT = G0 / FT
R_EARTH_FT = 20925646.325  # JSBSim's reference radius for geopotential altitude (ft)
CONTROL_LIMIT = 1.0 + 1e-6
TRIM_AID = "external_reactions/trim-aid/magnitude"
TRIM_AID_LBF = 300.0
NEWTON_TOL = 1e-10       # accelerations in g (rotational in rad/s^2): trims repeat to ~1e-10 whatever their start


MODES = {
    "level": "flight path given (vs_fpm), speed given, throttle trims",
    "full_throttle": "throttle given (throttle), speed given, flight path free (a climb)",
    "level_full_throttle": "throttle given, flight path given, speed free (maximum level speed)",
}


@dataclass(frozen=True)
class Condition:
    """A flight condition to trim to. Speeds in knots, altitudes in feet, angles in degrees."""

    pressure_alt_ft: float
    weight_lb: float
    kcas: float | None = None
    ktas: float | None = None
    oat_c: float | None = None            # absolute temperature; else ISA + isa_dev_c
    isa_dev_c: float = 0.0
    cg_in: float | None = None            # None: the aircraft's POH CG
    flaps_deg: float = 0.0
    mode: str = "level"                   # see MODES
    vs_fpm: float = 0.0                   # vertical speed (geometric) for mode 'level'
    throttle: float = 1.0                 # for mode 'full_throttle'
    bank_deg: float = 0.0
    turn: str = "straight"                # straight (heading fixed) | coordinated
    mixture: str | float = "cruise"       # POH procedure: cruise | climb | explicit mixture command
    fuel_fraction: float | None = None    # None: the aircraft's default for POH points
    rpm: float | None = None              # governor setting of a constant-speed propeller (None: maximum)

    def __post_init__(self):
        if (self.kcas is None) == (self.ktas is None):
            raise ValueError("give exactly one of kcas and ktas")
        if self.mode not in MODES:
            raise ValueError(f"mode must be one of {', '.join(MODES)}, not {self.mode!r}")
        if self.turn not in ("straight", "coordinated"):
            raise ValueError(f"turn must be 'straight' or 'coordinated', not {self.turn!r}")

    def temperature_k(self) -> float:
        if self.oat_c is not None:
            return self.oat_c + 273.15
        return float(isa_temperature(self.pressure_alt_ft * FT)) + self.isa_dev_c

    def true_airspeed_kt(self) -> float:
        """True airspeed [kt]: given, or from KCAS at the condition's pressure altitude and temperature."""
        if self.ktas is not None:
            return self.ktas
        return float(cas_to_tas(self.kcas * KT, isa_pressure(self.pressure_alt_ft * FT), self.temperature_k()) / KT)


@dataclass
class TrimResult:
    """Trimmed state. Surface angles in JSBSim's signs (elevator + trailing edge down,
    aileron + roll right, rudder + trailing edge left)."""

    condition: Condition
    trimmed: bool
    reason: str = ""
    residual: float = float("nan")
    evals: int = 0
    alpha_deg: float = float("nan")
    beta_deg: float = float("nan")
    theta_deg: float = float("nan")
    phi_deg: float = float("nan")
    gamma_deg: float = float("nan")
    roc_fpm: float = float("nan")           # rate of climb, geometric (tapeline) dh/dt
    roc_pressure_fpm: float = float("nan")  # rate of change of pressure altitude (VSI)
    ktas: float = float("nan")
    kcas: float = float("nan")
    throttle: float = float("nan")
    mixture: float = float("nan")
    rpm: float = float("nan")
    power_hp: float = float("nan")
    pct_power: float = float("nan")
    gph: float = float("nan")
    thrust_lbf: float = float("nan")
    torque_lbft: float = float("nan")
    map_inhg: float = float("nan")
    elevator_deg: float = float("nan")
    aileron_deg: float = float("nan")
    rudder_deg: float = float("nan")
    qbar_psf: float = float("nan")
    extra: dict = field(default_factory=dict)

    def as_dict(self) -> dict:
        d = {k: getattr(self, k) for k in self.__dataclass_fields__ if k not in ("condition", "extra")}
        d.update(self.extra)
        return d


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


class Simulator:
    """One aircraft loaded in JSBSim, in a private sandbox root, ready to be trimmed.

    ``factors``: values to start from (default: those declared in the aircraft file);
    ``baseline=True``: all factors neutral (the uncalibrated model).
    """

    def __init__(self, root: Path | str, name: str, *, factors: FactorSet | None = None, baseline: bool = False):
        self.root = Path(root).resolve()
        self.paths = AircraftPaths(self.root, name)
        self.name = name
        if not self.paths.aircraft_xml.is_file():
            raise ModelError(f"{self.paths.aircraft_xml} not found: run 'jsbsim-calib generate {name}'")
        self.geometry = load_aircraft_geometry(self.root, name)
        self.bem = read_bem_csv(self.paths.propeller_bem)
        declared = xmlmodel.read_factors(self.paths.aircraft_xml)
        self._check_baked(declared)
        self.factors = FactorSet() if baseline else (factors if factors is not None else declared)
        self._box = Path(tempfile.mkdtemp(prefix="jsbsim-calib-"))
        (self._box / "aircraft" / name).mkdir(parents=True)
        (self._box / "engine").mkdir()
        (self._box / "systems").mkdir()
        self._tree = etree.parse(str(self.paths.aircraft_xml))
        self.effect_values: dict[str, float] = {p: v for vals in xmlmodel.effect_values(self._tree).values()
                                                for p, v in vals.items()}
        shutil.copy(self.paths.engine_xml, self._box / "engine")
        self._box_paths = AircraftPaths(self._box, name)
        self._write_aircraft(self.factors)
        self._write_propeller(self.factors)
        self._baked = {k: self.factors[k] for k in PROPELLER_FACTORS}
        self.loads = 0
        self.fdm = self._load()
        self._cache: dict = {}
        self.trims = 0
        self.evals = 0

    # ------------------------------------------------------------------ sandbox
    def _check_baked(self, declared: FactorSet) -> None:
        if not self.paths.propeller_xml.is_file():
            raise ModelError(f"{self.paths.propeller_xml} not found: run 'jsbsim-calib generate {self.name}'")
        baked = xmlmodel.read_baked_factors(self.paths.propeller_xml)
        diff = [f"{k}: aircraft file {declared[k]:g}, propeller tables {v:g}" for k, v in baked.items()
                if k in declared and abs(declared[k] - v) > 1e-9]
        if diff:
            raise ModelError(f"{self.paths.aircraft_xml.name} declares propeller factors that differ from those baked "
                             f"into {self.paths.propeller_xml.name} ({'; '.join(diff)}); propeller factors act "
                             f"through the tables: run 'jsbsim-calib generate {self.name}' after editing them")

    def _write_aircraft(self, factors: FactorSet) -> None:
        xmlmodel.set_factor_values(self._tree, factors)
        xmlmodel.set_effect_values(self._tree, self.effect_values)
        box = copy.deepcopy(self._tree)
        xmlmodel.add_trim_aid(box, self.geometry.propeller.location_m)
        xmlmodel.write(box, self._box_paths.aircraft_xml)

    @classmethod
    def from_dir(cls, aircraft_dir: Path | str, root: Path | str = ".", **kw) -> "Simulator":
        """An aircraft folder anywhere (``<dir>/<name>.xml``, ``geometry.toml``,
        ``propeller_bem.csv``): flown as its XML stands. When the folder is not inside a
        JSBSim root, engines, airfoils and data come from ``root``."""
        d = Path(aircraft_dir).resolve()
        if d.parent.name == "aircraft" and (d.parent.parent / "engine").is_dir():
            return cls(d.parent.parent, d.name, **kw)
        stage = Path(tempfile.mkdtemp(prefix="jsbsim-calib-root-"))
        (stage / "aircraft").mkdir()
        (stage / "aircraft" / d.name).symlink_to(d, target_is_directory=True)
        for sub in ("engine", "airfoils", "data", "scripts"):
            if (Path(root).resolve() / sub).exists():
                (stage / sub).symlink_to(Path(root).resolve() / sub, target_is_directory=True)
        sim = cls(stage, d.name, **kw)
        sim._stage = stage
        return sim

    def clone(self) -> "Simulator":
        """A second simulator of the aircraft as it stands here (effects and values included)."""
        other = Simulator(self.root, self.name, factors=self.factors)
        other._tree = copy.deepcopy(self._tree)
        other.effect_values = dict(self.effect_values)
        other._write_aircraft(other.factors)
        other.fdm = other._load()
        return other

    # ------------------------------------------------------------------ effects
    def add_effect(self, effect, values: Mapping[str, float] | None = None) -> None:
        """Add a library effect (:mod:`jsbsim_calib.effects`) to the loaded aircraft and reload."""
        from .effects import constants
        xmlmodel.add_effect(self._tree, effect.spec, constants(self.geometry), values)
        for f in effect.factors:
            self.effect_values[f.property] = float((values or {}).get(f.property, f.neutral))
        self._write_aircraft(self.factors)
        self.fdm = self._load()
        self._cache.clear()

    def set_effect_values(self, values: Mapping[str, float]) -> None:
        """Set effect factor properties (by property name)."""
        for k, v in values.items():
            if k not in self.effect_values:
                raise ModelError(f"the aircraft has no effect factor {k}")
            self.effect_values[k] = float(v)
            self.fdm[k] = float(v)

    @property
    def effects(self) -> list[str]:
        return list(xmlmodel.effect_values(self._tree))

    def aircraft_tree(self):
        """The aircraft as it flies here (factor and effect values included, no sandbox aids)."""
        xmlmodel.set_factor_values(self._tree, self.factors)
        xmlmodel.set_effect_values(self._tree, self.effect_values)
        return copy.deepcopy(self._tree)

    def _write_propeller(self, factors: FactorSet) -> None:
        tree = propeller_tree(self.geometry, self.bem, factors, self.paths)
        xmlmodel.write(tree, self._box_paths.propeller_xml)

    def _load(self) -> jsbsim.FGFDMExec:
        jsbsim.FGJSBBase().debug_lvl = 0      # no start-up banner on stdout (JSON goes there)
        fdm = jsbsim.FGFDMExec(str(self._box))
        fdm.set_debug_level(0)
        fdm.disable_output()
        if not fdm.load_model(self.name):
            raise ModelError(f"JSBSim could not load {self.name} from {self._box}")
        fdm["ic/terrain-elevation-ft"] = -30000.0     # no ground contact at any trim point
        fdm["ic/h-sl-ft"] = 5000.0
        fdm["ic/vt-fps"] = 150.0
        fdm.run_ic()
        fdm["propulsion/set-running"] = -1
        fdm.set_trim_status(True)                     # flaps and actuators reach their command at once
        self.loads += 1
        for name, f in REGISTRY.items():
            if not f.baked:
                fdm[f.property] = self.factors[name]
        for k, v in self.effect_values.items():
            fdm[k] = v
        pm = fdm.get_property_manager()
        self._indicated = {f"{s}_deg": f"fcs/{s}-ind-deg" for s in ("elevator", "aileron", "rudder")
                           if pm.hasNode(f"fcs/{s}-ind-deg")}
        if pm.hasNode(PITCH_INDICATED):
            self._indicated["theta_deg"] = PITCH_INDICATED
        self._position_error = pm.hasNode(POSITION_ERROR)
        return fdm

    def close(self) -> None:
        self.fdm = None
        shutil.rmtree(self._box, ignore_errors=True)
        if getattr(self, "_stage", None):
            shutil.rmtree(self._stage, ignore_errors=True)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def __del__(self):
        try:
            shutil.rmtree(self._box, ignore_errors=True)
            if getattr(self, "_stage", None):
                shutil.rmtree(self._stage, ignore_errors=True)
        except Exception:
            pass

    # ------------------------------------------------------------------ factors
    def set_factors(self, factors: FactorSet) -> None:
        """Apply factor values: properties directly, propeller factors by re-baking + reload."""
        prop_changed = any(abs(factors[k] - self._baked[k]) > 0 for k in PROPELLER_FACTORS)
        self.factors = factors
        if prop_changed:
            self._write_propeller(factors)
            self._baked = {k: factors[k] for k in PROPELLER_FACTORS}
            self.fdm = self._load()
        for name, f in REGISTRY.items():
            if not f.baked:
                self.fdm[f.property] = factors[name]
        extra = {f.property: factors[n] for n, f in factors.extra.items()}
        if extra:
            self.set_effect_values(extra)

    # ------------------------------------------------------------------ loading and atmosphere
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

    def set_atmosphere(self, pressure_alt_ft: float, temperature_k: float) -> None:
        """Geometric altitude and temperature bias giving this pressure altitude and temperature.

        JSBSim's temperature bias shifts the whole profile, which changes the pressure at a
        given height: solve (troposphere, closed form on geopotential height, then a
        correction against JSBSim's own pressure altitude).
        """
        hp_m = pressure_alt_ft * FT
        t_std = float(isa_temperature(hp_m))
        dT = temperature_k - t_std                       # bias of the whole profile [K]
        # geopotential height where the biased profile has the pressure of hp
        h_gp = hp_m * (T0 + dT) / T0 if hp_m < 11000 else hp_m + dT / LAPSE
        h_gp_ft = h_gp / FT
        h_geo = R_EARTH_FT * h_gp_ft / (R_EARTH_FT - h_gp_ft)
        fdm = self.fdm
        fdm["atmosphere/delta-T"] = dT * 1.8
        for _ in range(4):
            fdm["ic/h-sl-ft"] = h_geo
            fdm.run_ic()
            err = fdm["atmosphere/pressure-altitude"] - pressure_alt_ft
            if abs(err) < 0.05:
                break
            h_geo -= err * (T0 + dT) / T0
        self._h_geo = h_geo

    # ------------------------------------------------------------------ trim
    def trim(self, cond: Condition, key=None) -> TrimResult:
        """Trim to a condition. ``key`` identifies the point for warm starts.

        Where the aircraft defines a pitot-static position error (``velocities/position-
        error-kts``, measured minus true, in calibrated knots), the condition's airspeed is
        the measured one: the trim is repeated at the true speed that shows it."""
        if not self._position_error:
            return self._trim(cond, key)
        if cond.mode == "level_full_throttle":          # speed free: report the measured speed
            t = self._trim(cond, key)
            err = float(self.fdm[POSITION_ERROR])
            t.extra["position_error_kt"] = err
            t.ktas += err * t.ktas / max(t.kcas, 1e-6)
            t.kcas += err
            return t
        measured = cond.ktas if cond.ktas is not None else cond.kcas
        c, t, err = cond, None, 0.0
        for _ in range(8):
            t = self._trim(c, key)
            if not t.trimmed:
                break
            err = float(self.fdm[POSITION_ERROR])
            scale = t.ktas / max(t.kcas, 1e-6) if cond.ktas is not None else 1.0
            want = measured - err * scale
            now = c.ktas if cond.ktas is not None else c.kcas
            if abs(want - now) < 0.005:
                break
            c = replace(cond, ktas=want) if cond.ktas is not None else replace(cond, kcas=want)
        t.condition = cond
        t.extra["position_error_kt"] = err
        return t

    def _trim(self, cond: Condition, key=None) -> TrimResult:
        self.trims += 1
        fdm = self.fdm
        try:
            self.set_loading(cond.weight_lb, cond.cg_in, cond.fuel_fraction)
        except TrimError as exc:
            return TrimResult(cond, False, str(exc))
        T = cond.temperature_k()
        self.set_atmosphere(cond.pressure_alt_ft, T)
        p_amb = float(isa_pressure(cond.pressure_alt_ft * FT))
        if isinstance(cond.mixture, str):
            mix = poh_mixture(p_amb, climb=cond.mixture == "climb",
                              full_rich_below_m=self.geometry.engine.full_rich_below_m)
        else:
            mix = float(cond.mixture)
        fdm["fcs/mixture-cmd-norm"] = mix
        fdm["fcs/flap-cmd-norm"] = cond.flaps_deg / max(1e-9, self._flap_max_deg())
        ktas = cond.true_airspeed_kt()
        V = ktas * KT / FT
        phi = math.radians(cond.bank_deg)
        t_std = float(isa_temperature(cond.pressure_alt_ft * FT))
        full = cond.mode == "full_throttle"
        speed_free = cond.mode == "level_full_throttle"
        cs = self.geometry.propeller
        governed = cs.constant_speed
        scale = np.array([G_FT, G_FT, G_FT, 1.0, 1.0, 1.0])
        V0 = V
        if governed:
            # an ideal governor: the blade angle is a trim unknown that holds the set RPM
            rpm_set = min(cs.max_rpm, max(cs.min_rpm, cond.rpm if cond.rpm is not None else cs.max_rpm))
            fdm["propulsion/engine/constant-speed-mode"] = 0.0
            fdm["fcs/advance-cmd-norm"] = (rpm_set - cs.min_rpm) / max(1.0, cs.max_rpm - cs.min_rpm)

        def set_state(x):
            a, b = x[0], x[1]
            V = V0 * x[2] if speed_free else V0
            omega = G_FT * math.tan(phi) / V if cond.turn == "coordinated" else 0.0
            if full:
                th, thr = x[2], cond.throttle
            else:
                thr = cond.throttle if speed_free else x[2]
                gamma = math.asin(max(-1.0, min(1.0, cond.vs_fpm / 60.0 / V)))
                ca, cb = math.cos(a) * math.cos(b), math.sin(b) * math.sin(phi) + math.sin(a) * math.cos(b) * math.cos(phi)
                th = math.atan2(cb, ca) + math.asin(max(-1.0, min(1.0, math.sin(gamma) / math.hypot(ca, cb))))
            fdm["ic/phi-rad"] = phi
            fdm["ic/theta-rad"] = th
            fdm["ic/psi-true-rad"] = 0.0
            fdm["ic/u-fps"] = V * math.cos(a) * math.cos(b)
            fdm["ic/v-fps"] = V * math.sin(b)
            fdm["ic/w-fps"] = V * math.sin(a) * math.cos(b)
            fdm["ic/p-rad_sec"] = -omega * math.sin(th)
            fdm["ic/q-rad_sec"] = omega * math.sin(phi) * math.cos(th)
            fdm["ic/r-rad_sec"] = omega * math.cos(phi) * math.cos(th)
            fdm["fcs/throttle-cmd-norm"] = min(max(thr, 0.0), 1.0)
            # beyond the throttle stops a thrust aid along the thrust line keeps the
            # residual continuous (sandbox only): TRIM_AID_LBF per unit of throttle
            fdm[TRIM_AID] = TRIM_AID_LBF * (min(thr, 0.0) + max(thr - 1.0, 0.0))
            fdm["fcs/elevator-cmd-norm"] = x[3]
            fdm["fcs/aileron-cmd-norm"] = x[4]
            fdm["fcs/rudder-cmd-norm"] = x[5]
            if governed:
                fdm["propulsion/engine/blade-angle"] = min(max(x[6], cs.min_pitch_deg), cs.max_pitch_deg)
            fdm.run_ic()
            fdm.get_propulsion().get_steady_state()
            fdm.run()

        def residual(x):
            self.evals += 1
            set_state(x)
            r = np.array([fdm[p] for p in ACCELS]) / scale
            if governed:
                # past a pitch stop the blade stays on the stop and the unknown measures the
                # RPM the governor cannot hold (under-speed on the fine stop, over-speed on the coarse)
                beyond = x[6] - min(max(x[6], cs.min_pitch_deg), cs.max_pitch_deg)
                r = np.append(r, (fdm["propulsion/engine/engine-rpm"] - rpm_set) / 100.0 - beyond / 10.0)
            if not np.all(np.isfinite(r)):
                return np.full(len(x), 1e3)
            # keep the solver inside the physical ranges: continue the residual linearly past them
            excess = max(0.0, abs(x[3]) - 1) + max(0.0, abs(x[4]) - 1) + max(0.0, abs(x[5]) - 1)
            return r + 10.0 * excess * np.sign(r + 1e-12)

        q = 0.5 * 0.0023769 * (V**2) * (p_amb / 101325.0) * (t_std / T) / (t_std / 288.15)
        S = self.geometry.reference.wing_area_m2 / FT**2
        cl = cond.weight_lb / max(q * S, 1e-6)
        a0 = max(-0.1, min(0.25, (cl - 0.25 - 0.02 * cond.flaps_deg) / 4.8))
        cold = np.array([a0, 0.0, a0 + 0.08 if full else (1.0 if speed_free else 0.65), 0.0, 0.0, 0.0])
        if governed:
            cold = np.append(cold, 0.5 * (cs.min_pitch_deg + cs.max_pitch_deg))
        self.fdm.suspend_integration()
        best = None
        nfev = 0
        cached = self._cache.get(key) if key is not None else None
        if cached is not None:
            # warm start: Newton steps with the Jacobian kept from the last trim of this point
            x, J = np.array(cached[0], float), cached[1]
            fx = residual(x)
            nfev += 1
            for _ in range(8):
                if float(np.max(np.abs(fx))) < NEWTON_TOL:
                    break
                try:
                    x_new = x - np.linalg.solve(J, fx)
                except np.linalg.LinAlgError:
                    break
                f_new = residual(x_new)
                nfev += 1
                if np.max(np.abs(f_new)) >= np.max(np.abs(fx)):
                    break
                x, fx = x_new, f_new
            norm = float(np.max(np.abs(fx)))
            best = (x, norm, J)
        if best is None or best[1] > NEWTON_TOL:
            starts = ([best[0]] if best is not None else []) + [cold]
            for x0 in starts:
                # finite-difference steps of 1e-4 (relative, absolute near 0): well above the
                # engine steady-state noise, well below the scale of the solution
                sol = root(residual, x0, method="hybr", options={"xtol": 1e-10, "maxfev": 300, "eps": 1e-8})
                nfev += sol.nfev
                x = sol.x if np.all(np.isfinite(sol.x)) else x0
                fx = residual(x)
                nfev += 1
                norm = float(np.max(np.abs(fx)))
                J = self._jacobian(residual, x, fx)
                nfev += 6
                if best is None or norm < best[1]:
                    best = (x, norm, J)
                if norm < 2e-4:
                    break
        x, _, J = best
        r = residual(x)          # leaves the trimmed state in JSBSim
        res = float(np.max(np.abs(r)))
        out = TrimResult(cond, True, residual=res, evals=nfev + 1)
        for k, p in OUTPUTS.items():
            setattr(out, k, float(fdm[self._indicated.get(k, p)]))
        out.throttle = cond.throttle if (full or speed_free) else float(x[2])
        out.extra["throttle_required"] = out.throttle
        out.extra["trim_aid_lbf"] = float(fdm[TRIM_AID])
        out.mixture = mix
        out.pct_power = 100.0 * out.power_hp / (self.geometry.engine.max_power_w / 745.69987158227)
        out.roc_fpm = float(fdm["velocities/h-dot-fps"]) * 60.0
        out.roc_pressure_fpm = out.roc_fpm * t_std / T
        out.torque_lbft = out.power_hp * 550.0 / max(out.rpm * 2 * math.pi / 60.0, 1e-6)
        problems = []
        if res > 2e-4:
            problems.append(f"no equilibrium (residual {res:.2g})")
        for i, name in ((3, "elevator"), (4, "aileron"), (5, "rudder")):
            if abs(x[i]) > CONTROL_LIMIT:
                problems.append(f"{name} beyond its stop ({x[i]:+.2f} of travel)")
        if governed:
            out.extra["blade_angle_deg"] = float(min(max(x[6], cs.min_pitch_deg), cs.max_pitch_deg))
            out.extra["governor"] = ("fine stop" if x[6] < cs.min_pitch_deg - 1e-6 else
                                     "coarse stop" if x[6] > cs.max_pitch_deg + 1e-6 else "governing")
        if cond.mode == "level" and x[2] > 1.0 + 1e-4:
            problems.append(f"needs more than full throttle ({fdm[TRIM_AID]:.0f} lbf short)")
        if cond.mode == "level" and x[2] < -1e-4:
            problems.append("needs less than idle throttle")
        if not math.isfinite(out.rpm) or out.rpm < 100:
            problems.append("engine not running")
        fdm[TRIM_AID] = 0.0
        if problems:
            out.trimmed = False
            out.reason = "; ".join(problems)
            self._recover()
        elif key is not None:
            self._cache[key] = (x.copy(), J)
        return out

    @staticmethod
    def _jacobian(residual, x, fx, h=1e-5):
        J = np.empty((len(fx), len(x)))
        for i in range(len(x)):
            xi = np.array(x, float)
            xi[i] += h
            J[:, i] = (residual(xi) - fx) / h
        return J

    CLIMB_VS_FPM = 50.0        # [ft/min] above this a point past the throttle stop is a climb (see trim_at_stop)

    def trim_at_stop(self, cond: Condition, key=None) -> TrimResult:
        """A level or climbing point flown at full throttle instead: a climb
        (``vs_fpm`` > :attr:`CLIMB_VS_FPM`) keeps its speed and lets the rate of climb go
        free; level flight keeps the flight path and lets the speed go free."""
        if cond.vs_fpm > self.CLIMB_VS_FPM:
            c = replace(cond, mode="full_throttle", throttle=1.0)
        else:
            c = replace(cond, mode="level_full_throttle", throttle=1.0)
        return self.trim(c, None if key is None else (key, "full throttle"))

    def trim_level(self, cond: Condition, key=None, speed_tolerance_kt: float = 3.0,
                   vs_tolerance_fpm: float = 100.0) -> TrimResult:
        """Level (or steadily climbing) point; when it needs more than full throttle, flown at
        full throttle instead (:meth:`trim_at_stop`), accepted if the speed reached is within
        ``speed_tolerance_kt`` of the data (Part 60 airspeed tolerance) or, for a climb, the
        rate of climb within ``vs_tolerance_fpm`` (Part 60 climb tolerance); reported with
        the shortfall."""
        t = self.trim(cond, key)
        if t.trimmed or not t.reason.startswith("needs more than full throttle") or ";" in t.reason:
            return t
        ft = self.trim_at_stop(cond, key)
        if not ft.trimmed:
            return t
        ft.condition = cond
        if cond.vs_fpm > self.CLIMB_VS_FPM:
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

    def _flap_max_deg(self) -> float:
        f = self.geometry.wing.control("flap")
        return math.degrees(f.deflection_max_rad) if f else 1.0

    def _recover(self) -> None:
        """After a failed trim: clear NaN from the engine state before the next point."""
        fdm = self.fdm
        if not all(math.isfinite(fdm[p]) for p in ("propulsion/engine/engine-rpm", "propulsion/engine/map-inhg")):
            fdm.reset_to_initial_conditions(0)
            fdm["propulsion/set-running"] = -1
            fdm.set_trim_status(True)
