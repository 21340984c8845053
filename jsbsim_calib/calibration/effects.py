"""The effect library: physical effects the baseline model lacks, as data.

Each effect is one XML file in ``jsbsim_calib/calibration/effects/``: a description, the metrics it
moves, its factor(s) (name, JSBSim property, neutral value, bounds, unit, doc: records of
:class:`jsbsim_calib.factors.Factor` with step ``effect``) and the XML it adds to an aircraft
(functions in a ``<system>``, moments in ``<aerodynamics>``), with placeholders for a few
aircraft constants (:func:`jsbsim_calib.jsbsim.aircraft.effect_constants`). Adding an effect
to the library is adding a file; no code knows a particular effect.

Two conventions let effects change what is *measured* rather than what flies:

* ``fcs/<surface>-ind-deg``: where an aircraft defines it, evaluations compare that
  (indicated) surface position with the data instead of ``fcs/<surface>-pos-deg``;
* ``velocities/position-error-kts``: measured minus true airspeed; trims then fly the true
  speed at which the measured speed equals the data's;
* ``attitude/theta-ind-deg``: the pitch attitude an instrument shows (compared with the data
  instead of ``attitude/theta-deg``).
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from functools import lru_cache
from pathlib import Path

from ..core.errors import ModelError
from ..factors import Factor
from ..jsbsim.xml import is_comment, parse

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
    text: str                       # the file, placeholders such as {prop_radius_ft} left in place

    def label(self, f: Factor) -> str:
        return f"{self.name}.{f.name}"

    def as_factors(self) -> dict[str, Factor]:
        """The effect's factors as fit parameters (``effect.K`` names)."""
        return {self.label(f): replace(f, name=self.label(f)) for f in self.factors}


def _words(text: str | None) -> str:
    return " ".join((text or "").split())


def load_effect(path: Path) -> Effect:
    """Read an effect file: its name, what it affects, its factors and its XML parts."""
    try:
        text = Path(path).read_text()
    except OSError as exc:
        raise ModelError(f"{path}: cannot read effect: {exc}") from None
    root = parse(text, str(path))
    if root.tag != "effect" or not root.get("name"):
        raise ModelError(f"{path}: the root element must be <effect name=...>")
    note = ""
    prev = root.getprevious()
    while prev is not None:
        if is_comment(prev):
            note = _words(prev.text)
        prev = prev.getprevious()
    affects = tuple((root.get("affects") or "").split())
    description = _words(root.findtext("description"))
    factors = []
    for f in root.findall("factor"):
        try:
            factors.append(Factor(f.get("name"), f.get("property"), float(f.get("neutral")), float(f.get("lower")),
                                  float(f.get("upper")), f.get("unit", "-"), ("effect",), affects, description,
                                  _words(f.text)))
        except (TypeError, ValueError):
            raise ModelError(f"{path}: factor needs name, property, neutral, lower, upper") from None
    if not factors:
        raise ModelError(f"{path}: an effect needs at least one <factor>")
    return Effect(root.get("name"), description, affects, tuple((root.get("same_as") or "").split()),
                  _words(root.findtext("regressor")), note, tuple(factors), Path(path), text)


@lru_cache(maxsize=None)
def _library(directory: str) -> tuple[Effect, ...]:
    return tuple(load_effect(p) for p in sorted(Path(directory).glob("*.xml")))


def library(directory: Path | None = None) -> dict[str, Effect]:
    """All effects of a library directory (default: the package's), by name."""
    return {e.name: e for e in _library(str(directory or LIBRARY_DIR))}
