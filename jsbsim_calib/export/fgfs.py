"""Flying an exported aircraft in FlightGear and in JSBSim's runner, and comparing the two.

* :func:`runner_cruise` flies the aircraft's cruise script (``scripts/NAME_cruise.xml``: JSBSim's
  trim at 5,500 ft and 110 KTAS, then 60 s with the controls fixed) in JSBSim's runner and
  records altitude, true airspeed and RPM; it also gives the trimmed state and controls
  (:class:`CruiseStart`).
* :func:`fly_flightgear` starts FlightGear (``fgfs``, under ``xvfb-run`` when there is no
  display) with the exported aircraft in the air at that state, FlightGear's start-up trim on,
  the autopilot off, and records the same quantities over FlightGear's property server
  (telnet, 127.0.0.1) for the same time with the controls fixed.
* :func:`compare` gives the largest differences (:class:`Agreement`).

Start-up conventions, measured with FlightGear 2020.3 (stated, not hidden): the speed is given
as body velocities (``--uBody``/``--wBody``) and the pitch attitude of the runner's trim
(``--pitch``), because FlightGear converts ``--vc`` with its start-up atmosphere, before its
weather is set (1.6-1.8 kt of true airspeed off at 5,500 ft); starting at the runner's trimmed
state also keeps FlightGear's start-up trim from settling on a flight path 0.4 deg off level.
The weather is ISA and calm (``--metar`` 15 C, 1013 hPa, no wind, no turbulence).
"""
from __future__ import annotations

import csv
import math
import os
import shutil
import socket
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Sequence

from ..core.errors import CalibError, ModelError
from ..jsbsim.product import AircraftPaths

KT_TO_FPS = 1852.0 / 3600.0 / 0.3048
ISA_CALM_METAR = "XXXX 012345Z 00000KT 9999 SKC 15/05 Q1013"
RENDERING_LIGHT = ("--disable-clouds", "--disable-clouds3d", "--fog-disable", "--disable-random-objects",
                   "--disable-random-vegetation", "--disable-random-buildings", "--disable-ai-traffic",
                   "--disable-real-weather-fetch", "--disable-terrasync", "--geometry=640x480",
                   "--prop:/sim/rendering/shaders/quality-level=0")
RECORDED = {"time_s": "simulation/sim-time-sec", "altitude_ft": "position/h-sl-ft",
            "ktas": "velocities/vtrue-kts", "rpm": "propulsion/engine/engine-rpm"}
START = {"alpha_deg": "aero/alpha-deg", "theta_deg": "attitude/theta-deg", "throttle": "fcs/throttle-cmd-norm",
         "mixture": "fcs/mixture-cmd-norm", "pitch_trim": "fcs/pitch-trim-cmd-norm"}


@dataclass(frozen=True)
class Sample:
    """One recorded instant."""

    time_s: float          # [s] since the recording started
    altitude_ft: float     # [ft] above sea level
    ktas: float            # [kt] true airspeed
    rpm: float             # [rpm] engine speed


@dataclass(frozen=True)
class CruiseStart:
    """The trimmed cruise of the runner: state and controls to start FlightGear with."""

    altitude_ft: float
    ktas: float
    alpha_deg: float
    theta_deg: float
    throttle: float
    mixture: float
    pitch_trim: float
    heading_deg: float = 90.0      # the cruise initial conditions' heading

    @property
    def ubody_fps(self) -> float:
        return self.ktas * KT_TO_FPS * math.cos(math.radians(self.alpha_deg))

    @property
    def wbody_fps(self) -> float:
        return self.ktas * KT_TO_FPS * math.sin(math.radians(self.alpha_deg))


@dataclass(frozen=True)
class Agreement:
    """Largest |FlightGear - runner| over the compared samples."""

    altitude_ft: float
    ktas: float
    rpm: float
    samples: int

    def within(self, altitude_ft: float, ktas: float, rpm: float) -> bool:
        return self.altitude_ft <= altitude_ft and self.ktas <= ktas and self.rpm <= rpm


# --------------------------------------------------------------------------- JSBSim's runner
def runner_executable() -> str:
    """JSBSim's runner of the installed jsbsim package (``jsbsim`` beside the Python executable)."""
    exe = shutil.which("jsbsim", path=str(Path(sys.executable).parent)) or shutil.which("jsbsim")
    if exe is None:
        raise ModelError("JSBSim's runner 'jsbsim' not found (pip install jsbsim)")
    return exe


def _log_directive(csv_path: Path, properties: Sequence[str]) -> str:
    rows = "\n".join(f"  <property> {p} </property>" for p in properties)
    return f'<?xml version="1.0"?>\n<output name="{csv_path}" type="CSV" rate="10">\n{rows}\n</output>\n'


def _read_runner_csv(path: Path, properties: Sequence[str]) -> list[dict[str, float]]:
    with open(path, newline="") as fh:
        rows = list(csv.reader(fh))
    head = [h.strip() for h in rows[0]]
    cols = [next(i for i, h in enumerate(head) if h.endswith(p)) for p in properties]
    return [{"t": float(r[0]), **{p: float(r[c]) for p, c in zip(properties, cols)}} for r in rows[1:] if r]


def runner_cruise(root: Path | str, name: str, workdir: Path | str | None = None) -> tuple[list[Sample], CruiseStart]:
    """Fly ``scripts/NAME_cruise.xml`` in JSBSim's runner at 60 Hz: the samples after the trim
    (10 Hz) and the trimmed start."""
    paths = AircraftPaths(Path(root).resolve(), name)
    if not paths.script.is_file():
        raise ModelError(f"{paths.script} not found: run 'jsbsim-calib generate {name}'")
    if workdir is None:
        with tempfile.TemporaryDirectory(prefix="jsbsim-calib-runner-") as work:
            return runner_cruise(root, name, work)
    work = Path(workdir)
    props = list(RECORDED.values())[1:] + list(START.values())
    (work / "log.xml").write_text(_log_directive(work / "runner.csv", props))
    proc = subprocess.run([runner_executable(), f"--root={paths.root}", f"--script={paths.script}",
                           "--simulation-rate=60", f"--logdirectivefile={work / 'log.xml'}"],
                          capture_output=True, timeout=300)
    if proc.returncode != 0 or not (work / "runner.csv").is_file():
        raise ModelError(f"JSBSim's runner failed on {paths.script}: {proc.stderr.decode(errors='replace')[-400:]}")
    rows = [r for r in _read_runner_csv(work / "runner.csv", props) if r["t"] > 0.05]    # after the trim
    first = rows[0]
    start = CruiseStart(first[RECORDED["altitude_ft"]], first[RECORDED["ktas"]],
                        **{k: first[p] for k, p in START.items()})
    t0 = first["t"]
    samples = [Sample(r["t"] - t0, r[RECORDED["altitude_ft"]], r[RECORDED["ktas"]], r[RECORDED["rpm"]]) for r in rows]
    return samples, start


# --------------------------------------------------------------------------- FlightGear
def find_fgfs() -> str | None:
    """``fgfs`` on PATH, or where Debian installs it (/usr/games, not on root's PATH)."""
    return shutil.which("fgfs") or shutil.which("fgfs", path="/usr/games")


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def fgfs_arguments(fgfs: str, aircraft_folder: Path, name: str, start: CruiseStart, port: int) -> list[str]:
    """The command line: the aircraft in the air at the start state, JSBSim, ISA calm, the
    property server (telnet) on 127.0.0.1:port, no sound, noon, light rendering."""
    ctl = "/controls/engines/engine[0]"
    return [fgfs, f"--fg-aircraft={aircraft_folder.parent}", f"--aircraft={name}", "--fdm=jsb", "--in-air",
            f"--altitude={start.altitude_ft:.3f}", f"--uBody={start.ubody_fps:.5f}", "--vBody=0",
            f"--wBody={start.wbody_fps:.5f}", f"--pitch={start.theta_deg:.6f}", "--roll=0",
            f"--heading={start.heading_deg:g}", "--trim", "--model-hz=60", "--timeofday=noon", "--disable-sound",
            f"--metar={ISA_CALM_METAR}", "--wind=0@0", "--turbulence=0", f"--telnet=socket,bi,10,127.0.0.1,{port},tcp",
            "--prop:/sim/presets/running=true", f"--prop:{ctl}/magnetos=3",
            f"--prop:{ctl}/throttle={start.throttle:.6f}", f"--prop:{ctl}/mixture={start.mixture:.6f}",
            f"--prop:/controls/flight/elevator-trim={start.pitch_trim:.6f}",
            "--prop:/autopilot/locks/altitude=off", "--prop:/autopilot/locks/heading=off",
            "--prop:/autopilot/locks/speed=off",
            *RENDERING_LIGHT]


def with_display(args: list[str]) -> list[str]:
    """Under ``xvfb-run`` when there is no X display (FlightGear needs OpenGL)."""
    if os.environ.get("DISPLAY"):
        return args
    xvfb = shutil.which("xvfb-run")
    if xvfb is None:
        raise CalibError("FlightGear: no display and no xvfb-run (apt-get install xvfb)")
    return [xvfb, "-a", "-s", "-screen 0 800x600x24", *args]


class PropertyClient:
    """FlightGear's property server (telnet protocol, data mode): ``get`` and ``set``."""

    def __init__(self, port: int, timeout_s: float = 120.0, connect_within_s: float = 180.0):
        deadline = time.monotonic() + connect_within_s
        while True:
            try:
                self._sock = socket.create_connection(("127.0.0.1", port), timeout=timeout_s)
                break
            except OSError:
                if time.monotonic() > deadline:
                    raise CalibError(f"FlightGear: no property server on 127.0.0.1:{port}") from None
                time.sleep(0.5)
        self._file = self._sock.makefile("r")
        self._sock.sendall(b"data\r\n")

    def get(self, path: str) -> str:
        self._sock.sendall(f"get {path}\r\n".encode())
        return self._file.readline().strip()

    def get_float(self, path: str) -> float:
        text = self.get(path)
        try:
            return float(text)
        except ValueError:
            raise CalibError(f"FlightGear property {path}: not a number ({text!r})") from None

    def set(self, path: str, value) -> None:
        self._sock.sendall(f"set {path} {value}\r\n".encode())

    def close(self) -> None:
        try:
            self._file.close()
            self._sock.close()
        except OSError:
            pass

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


def wait_initialized(client: PropertyClient, within_s: float = 300.0) -> None:
    deadline = time.monotonic() + within_s
    while client.get("/sim/fdm-initialized") != "true":
        if time.monotonic() > deadline:
            raise CalibError(f"FlightGear's flight model not initialized after {within_s:g} s")
        time.sleep(0.2)


def record(client: PropertyClient, duration_s: float, period_s: float = 0.5) -> list[Sample]:
    """Samples over ``duration_s`` of FlightGear's simulation time (from the first sample)."""
    out: list[Sample] = []
    t0 = None
    deadline = time.monotonic() + 10.0 * duration_s + 60.0
    while True:
        if time.monotonic() > deadline:
            raise CalibError(f"FlightGear ran less than {duration_s:g} s of simulation in {10 * duration_s + 60:g} s")
        v = {k: client.get_float(f"/fdm/jsbsim/{p}") for k, p in RECORDED.items()}
        t0 = v["time_s"] if t0 is None else t0
        out.append(Sample(v["time_s"] - t0, v["altitude_ft"], v["ktas"], v["rpm"]))
        if out[-1].time_s >= duration_s:
            return out
        time.sleep(period_s)


def stop(proc: subprocess.Popen) -> None:
    """End FlightGear and its Xvfb (the process group started for them)."""
    if proc.poll() is None:
        try:
            os.killpg(proc.pid, 15)
            proc.wait(timeout=30)
        except (ProcessLookupError, subprocess.TimeoutExpired):
            os.killpg(proc.pid, 9)


@dataclass(frozen=True)
class FlightGearFlight:
    samples: list[Sample]
    throttle: float           # FlightGear's trimmed throttle
    mixture: float            # FlightGear's mixture (its start-up puts a running engine at full rich)
    wall_time_s: float        # start to stop


def fly_flightgear(aircraft_folder: Path | str, name: str, start: CruiseStart, duration_s: float = 60.0,
                   log_path: Path | str | None = None, fgfs: str | None = None) -> FlightGearFlight:
    """Start FlightGear with the exported aircraft at ``start``, record ``duration_s`` with the
    controls fixed, stop it."""
    fgfs = fgfs or find_fgfs()
    if fgfs is None:
        raise CalibError("FlightGear: fgfs not installed")
    port = free_port()
    args = with_display(fgfs_arguments(fgfs, Path(aircraft_folder).resolve(), name, start, port))
    env = {**os.environ, "DBUS_FATAL_WARNINGS": "0"}      # no session bus in a headless run
    t0 = time.monotonic()
    with open(log_path or os.devnull, "w") as log:
        proc = subprocess.Popen(args, stdout=log, stderr=subprocess.STDOUT, env=env, start_new_session=True)
        try:
            with PropertyClient(port) as client:
                wait_initialized(client)
                throttle = client.get_float("/fdm/jsbsim/fcs/throttle-cmd-norm")
                mixture = client.get_float("/fdm/jsbsim/fcs/mixture-cmd-norm")
                samples = record(client, duration_s)
        except OSError as exc:
            raise CalibError(f"FlightGear's property server: {exc}") from None
        finally:
            stop(proc)
    return FlightGearFlight(samples, throttle, mixture, time.monotonic() - t0)


# --------------------------------------------------------------------------- comparison
def _interp(samples: Sequence[Sample], t: float, field: str) -> float:
    for a, b in zip(samples, samples[1:]):
        if a.time_s <= t <= b.time_s:
            w = (t - a.time_s) / max(b.time_s - a.time_s, 1e-9)
            return (1 - w) * getattr(a, field) + w * getattr(b, field)
    return getattr(samples[-1] if t > samples[-1].time_s else samples[0], field)


def compare(flightgear: Sequence[Sample], runner: Sequence[Sample], duration_s: float = 60.0) -> Agreement:
    """Largest differences at FlightGear's samples within ``duration_s`` (the runner interpolated
    at the same time since its recording started)."""
    pts = [s for s in flightgear if s.time_s <= duration_s + 1e-9]
    diff = {f: max(abs(getattr(s, f) - _interp(runner, s.time_s, f)) for s in pts) for f in ("altitude_ft", "ktas", "rpm")}
    return Agreement(diff["altitude_ft"], diff["ktas"], diff["rpm"], len(pts))
