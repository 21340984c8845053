"""The effect library: physical effects the baseline model lacks, as data.

Each effect is one XML file in ``jsbsim_calib/effects/``: a description, the metrics it
moves, its factor(s) (name, JSBSim property, neutral value, bounds, unit, doc) and the XML it
adds to an aircraft (functions in a ``<system>``, moments in ``<aerodynamics>``), with
placeholders for a few aircraft constants (:func:`constants`). Adding an effect to the
library is adding a file; no code knows a particular effect.

Two conventions let effects change what is *measured* rather than what flies:

* ``fcs/<surface>-ind-deg``: where an aircraft defines it, evaluations compare that
  (indicated) surface position with the data instead of ``fcs/<surface>-pos-deg``;
* ``velocities/position-error-kts``: measured minus true airspeed; trims then fly the true
  speed at which the measured speed equals the data's;
* ``attitude/theta-ind-deg``: the pitch attitude an instrument shows (compared with the data
  instead of ``attitude/theta-deg``).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace
from functools import lru_cache
from pathlib import Path

from . import xmlmodel
from .factors import Factor
from .physics.geometry import AircraftGeometry

LIBRARY_DIR = Path(__file__).resolve().parent / "effects"


@dataclass(frozen=True)
class Effect:
    name: str
    description: str
    affects: tuple[str, ...]        # metrics it moves
    same_as: tuple[str, ...]        # calibration factors of the same form (held, not refitted, with it)
    regressor: str                  # the state it grows with (for reports)
    note: str                       # the physics, from the file's comment
    factors: tuple[Factor, ...]     # short names within the effect (K, K_alpha, ...); step "effect"
    path: Path
    spec: dict                      # parsed file (xmlmodel.read_effect)

    def label(self, f: Factor) -> str:
        return f"{self.name}.{f.name}"

    def as_factors(self) -> dict[str, Factor]:
        """The effect's factors as fit parameters (``effect.K`` names)."""
        return {self.label(f): replace(f, name=self.label(f)) for f in self.factors}


def load_effect(path: Path) -> Effect:
    spec = xmlmodel.read_effect(path)
    factors = tuple(Factor(f["name"], f["property"], f["neutral"], f["lower"], f["upper"], f["unit"], ("effect",),
                           spec["affects"], spec["description"], f["doc"]) for f in spec["factors"])
    return Effect(spec["name"], spec["description"], spec["affects"], spec["same_as"], spec["regressor"], spec["note"],
                  factors, Path(path), spec)


@lru_cache(maxsize=None)
def _library(directory: str) -> tuple[Effect, ...]:
    return tuple(load_effect(p) for p in sorted(Path(directory).glob("*.xml")))


def library(directory: Path | None = None) -> dict[str, Effect]:
    """All effects of a library directory (default: the package's), by name."""
    return {e.name: e for e in _library(str(directory or LIBRARY_DIR))}


def constants(geometry: AircraftGeometry) -> dict[str, float]:
    """The aircraft constants effect files may use."""
    d_ft = geometry.propeller.diameter_m / 0.3048
    return {"prop_radius_ft": d_ft / 2.0, "prop_diameter_ft": d_ft, "prop_disk_area_ft2": math.pi * d_ft**2 / 4.0,
            "wing_span_ft": geometry.reference.span_m / 0.3048}
