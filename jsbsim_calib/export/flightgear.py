"""A calibrated aircraft as a FlightGear aircraft folder.

FlightGear's JSBSim interface loads ``<aero>NAME</aero>`` as ``NAME.xml`` from the aircraft
folder and the engine and propeller files from its ``Engines/`` folder (system files from
``Systems/``). :func:`export_flightgear` writes::

    OUT/NAME-set.xml        FlightGear's aircraft definition: <flight-model>jsb</flight-model>, <aero>NAME</aero>
    OUT/NAME.xml            the calibrated aircraft, byte for byte the product
    OUT/Engines/*.xml       its engine and propeller files, byte for byte
    OUT/Systems/*.xml       system files the aircraft names (none for a generated aircraft)
    OUT/Models/NAME.ac      a placeholder 3D model (a flat outline of wing, fuselage and tail)
    OUT/README.md           how to install and fly it

No panel (FlightGear's generic instruments), no sound configuration, no Nasal. Fly it with
``fgfs --fg-aircraft=PARENT_OF_OUT --aircraft=NAME`` (the folder's parent holds aircraft
folders; FlightGear finds ``NAME-set.xml`` in them).
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from xml.sax.saxutils import escape

from ..core.errors import ModelError
from ..jsbsim.product import AircraftPaths
from ..jsbsim.xml import read, write_bytes

MODEL_SPAN_FT = 36.0        # [ft] placeholder model span when the aircraft file states none
FT_TO_M = 0.3048


@dataclass(frozen=True)
class FlightGearExport:
    """What :func:`export_flightgear` wrote."""

    folder: Path                  # the aircraft folder (OUT)
    name: str                     # the aircraft name (--aircraft=NAME, <aero>NAME</aero>)
    files: tuple[Path, ...]       # every file written

    @property
    def set_file(self) -> Path:
        return self.folder / f"{self.name}-set.xml"


def referenced_files(aircraft_xml: Path) -> dict[str, list[str]]:
    """Files an aircraft file names: ``{"engine": [...], "thruster": [...], "system": [...]}``."""
    root = read(aircraft_xml).getroot()
    out: dict[str, list[str]] = {"engine": [], "thruster": [], "system": []}
    for eng in root.iter("engine"):
        if eng.get("file"):
            out["engine"].append(eng.get("file"))
        for thr in eng.iter("thruster"):
            if thr.get("file"):
                out["thruster"].append(thr.get("file"))
    for tag in ("system", "autopilot", "flight_control"):
        out["system"] += [el.get("file") for el in root.iter(tag) if el.get("file")]
    return out


def _find(candidates: list[Path], what: str, name: str) -> Path:
    for c in candidates:
        if c.is_file():
            return c
    raise ModelError(f"{what} file '{name}' not found (looked in {', '.join(str(c.parent) for c in candidates)})")


def _propulsion_sources(paths: AircraftPaths, refs: dict[str, list[str]]) -> list[Path]:
    """Engine and propeller files, where JSBSim looks for them (aircraft folder's Engines/, the root's engine/)."""
    out = []
    for kind in ("engine", "thruster"):
        for f in refs[kind]:
            out.append(_find([paths.folder / "Engines" / f"{f}.xml", paths.root / "engine" / f"{f}.xml"], kind, f))
    return out


def _system_sources(paths: AircraftPaths, refs: dict[str, list[str]]) -> list[Path]:
    return [_find([paths.folder / "Systems" / f"{f}.xml", paths.folder / f"{f}.xml", paths.root / "systems" / f"{f}.xml"],
                  "system", f) for f in refs["system"]]


def set_xml(name: str, title: str) -> str:
    """``NAME-set.xml``: the JSBSim flight model named NAME, the placeholder model, no panel."""
    return f"""<?xml version="1.0" encoding="UTF-8"?>
<!-- FlightGear aircraft definition written by jsbsim-calib (export flightgear). The flight
     model is the calibrated JSBSim aircraft {escape(name)}.xml in this folder; engine and
     propeller files are in Engines/. -->
<PropertyList>
  <sim>
    <description>{escape(title)} (jsbsim-calib, calibrated)</description>
    <author>jsbsim-calib (generated)</author>
    <status>alpha</status>
    <rating>
      <FDM type="int">3</FDM>
      <systems type="int">0</systems>
      <cockpit type="int">0</cockpit>
      <model type="int">0</model>
    </rating>
    <flight-model>jsb</flight-model>
    <aero>{escape(name)}</aero>
    <model>
      <path>Models/{escape(name)}.ac</path>
    </model>
    <view n="0">
      <internal type="bool">true</internal>
    </view>
  </sim>
</PropertyList>
"""


def placeholder_model(span_ft: float) -> str:
    """A flat AC3D outline (wing, fuselage, tailplane) of about the aircraft's span: FlightGear
    flies without a model; this one only gives the outside views something to show."""
    b = span_ft * FT_TO_M / 2.0
    L = 0.75 * span_ft * FT_TO_M
    # AC3D: x right, y up, z toward the viewer (FlightGear reads the nose along -z here)
    polys = {
        "wing": [(-b, 0.0, -0.3 * L), (b, 0.0, -0.3 * L), (b, 0.0, -0.1 * L), (-b, 0.0, -0.1 * L)],
        "fuselage": [(0.0, 0.0, -0.55 * L), (0.35, 0.0, -0.2 * L), (0.0, 0.0, 0.45 * L), (-0.35, 0.0, -0.2 * L)],
        "tailplane": [(-0.3 * b, 0.0, 0.35 * L), (0.3 * b, 0.0, 0.35 * L), (0.3 * b, 0.0, 0.45 * L),
                      (-0.3 * b, 0.0, 0.45 * L)],
        "fin": [(0.0, 0.0, 0.3 * L), (0.0, 0.2 * L, 0.42 * L), (0.0, 0.2 * L, 0.47 * L), (0.0, 0.0, 0.47 * L)],
    }
    lines = ["AC3Db", 'MATERIAL "white" rgb 0.9 0.9 0.9  amb 0.3 0.3 0.3  emis 0 0 0  spec 0.2 0.2 0.2  shi 10  trans 0',
             "OBJECT world", f"kids {len(polys)}"]
    for name, verts in polys.items():
        lines += ["OBJECT poly", f'name "{name}"', f"numvert {len(verts)}"]
        lines += [f"{x:.3f} {y:.3f} {z:.3f}" for x, y, z in verts]
        lines += ["numsurf 1", "SURF 0x30", "mat 0", f"refs {len(verts)}"]
        lines += [f"{i} 0 0" for i in range(len(verts))]
        lines += ["kids 0"]
    return "\n".join(lines) + "\n"


def readme_text(name: str, title: str, folder_name: str) -> str:
    return f"""# {title}: FlightGear aircraft (jsbsim-calib)

The calibrated JSBSim model `{name}.xml` with its engine and propeller (`Engines/`), written by
`jsbsim-calib export flightgear {name} --out {folder_name}`. No panel (FlightGear's generic
instruments), a placeholder 3D model, no sounds.

## Install and fly

1. Install FlightGear (Debian/Ubuntu: `sudo apt-get install flightgear`; elsewhere
   https://www.flightgear.org/download/).
2. Keep this folder inside a folder of aircraft, e.g. `~/fgaircraft/{folder_name}`, and start:

       fgfs --fg-aircraft=$HOME/fgaircraft --aircraft={name}

   In the air at cruise: `fgfs --fg-aircraft=$HOME/fgaircraft --aircraft={name} --in-air
   --altitude=5500 --vc=101 --heading=90 --timeofday=noon`.

The flight model runs in FlightGear's own copy of JSBSim (FlightGear 2020.3: an older JSBSim
than the 1.3.3 the model was calibrated with). Measured with FlightGear 2020.3 on the C172:
started at the cruise of `scripts/c172_cruise.xml` (5,500 ft, 110 KTAS), FlightGear's trim and
60 s with the controls fixed agree with JSBSim 1.3.3's runner within 3 ft, 0.2 kt and 4 rpm
(same throttle at full rich: 0.891). FlightGear's start-up sets a running engine to full rich;
leaned (mixture lever 0.87) FlightGear's JSBSim needs 0.853 of throttle where 1.3.3 needs 0.891.
"""


def _span_ft(aircraft_xml: Path) -> float:
    el = read(aircraft_xml).getroot().find("metrics/wingspan")
    try:
        value = float(el.text)
    except (AttributeError, TypeError, ValueError):
        return MODEL_SPAN_FT
    return value * (1.0 / FT_TO_M if (el.get("unit") or "FT").upper() == "M" else 1.0)


def export_flightgear(root: Path | str, name: str, out: Path | str) -> FlightGearExport:
    """Write aircraft ``name`` of JSBSim root ``root`` as a FlightGear aircraft folder ``out``
    (created; files already there are replaced). Raises :class:`ModelError` when the aircraft
    or a file it names is missing."""
    paths = AircraftPaths(Path(root).resolve(), name)
    if not paths.aircraft_xml.is_file():
        raise ModelError(f"{paths.aircraft_xml} not found: no aircraft '{name}' in {paths.root}")
    refs = referenced_files(paths.aircraft_xml)
    out = Path(out).resolve()
    title = read(paths.aircraft_xml).getroot().get("name") or name
    copies = [(paths.aircraft_xml, out / f"{name}.xml")]
    copies += [(src, out / "Engines" / src.name) for src in _propulsion_sources(paths, refs)]
    copies += [(src, out / "Systems" / src.name) for src in _system_sources(paths, refs)]
    written = []
    for src, dst in copies:
        write_bytes(dst, src.read_bytes())
        written.append(dst)
    texts = {out / f"{name}-set.xml": set_xml(name, title),
             out / "Models" / f"{name}.ac": placeholder_model(_span_ft(paths.aircraft_xml)),
             out / "README.md": readme_text(name, title, out.name)}
    for dst, text in texts.items():
        write_bytes(dst, text.encode())
        written.append(dst)
    return FlightGearExport(out, name, tuple(written))
