"""Sectional airfoil polars over the full -180..180 deg range, stored as CSV with provenance.

The aerodynamic preprocessor (strip theory / lifting line) and the propeller blade-element
code need the section coefficients cl, cd and cm (about the quarter chord) at any angle of
attack and at several Reynolds numbers. Running an airfoil tool at calibration time would be
slow and would make results depend on the tool being installed, so the polars are computed
once and stored under ``airfoils/<name>.csv``:

* inside the range where NeuralFoil is trustworthy (its ``analysis_confidence`` output, up to
  a few degrees past cl_max on each side) the coefficients are NeuralFoil's;
* beyond it a Viterna-Corrigan post-stall model (:func:`viterna_extend`) carries them out to
  +-180 deg with flat-plate-like behaviour.

Reading a stored file needs only numpy. Recomputing one (:func:`compute_airfoil`,
:func:`regenerate`) needs the optional dependency NeuralFoil
(``pip install jsbsim-calib[airfoils]``). Recomputing with the same versions gives
byte-identical files: the format has fixed number formatting and no timestamps.

Angles are in degrees in this module's interface (as in every airfoil table), everything
else is SI / dimensionless.
"""
from __future__ import annotations

import csv
import io
import math
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Sequence

import numpy as np

from ..core.errors import CalibError, DataError, GeometryError, Problem, raise_if

__all__ = [
    "AIRFOIL_DIR",
    "DEFAULT_REYNOLDS",
    "STORED_AIRFOILS",
    "Airfoil",
    "MissingDependencyError",
    "Polar",
    "available_airfoils",
    "compute_airfoil",
    "load_airfoil",
    "naca4_coordinates",
    "normalize_airfoil_name",
    "read_airfoil_csv",
    "regenerate",
    "viterna_extend",
    "write_airfoil_csv",
]

#: Reynolds numbers [-] of the stored polars. A light-aircraft wing (chord 1.0-1.6 m at
#: 25-90 m/s) spans about 1.5e6..9e6; the low end covers tails and propeller blades.
DEFAULT_REYNOLDS: tuple[float, ...] = (0.5e6, 1e6, 2e6, 3e6, 5e6, 8e6, 12e6)

#: Folder of the stored polar files in the repository (``<repo>/airfoils``).
AIRFOIL_DIR: Path = Path(__file__).resolve().parents[2] / "airfoils"

#: The airfoils stored in :data:`AIRFOIL_DIR` and what they stand for. The text is written
#: into the ``usage`` line of each file's header by :func:`compute_airfoil`.
STORED_AIRFOILS: dict[str, str] = {
    "naca2412": "Cessna 172 wing section (root and tip).",
    "naca0009": "Symmetric 9 % section for horizontal and vertical tails.",
    "naca0012": "Symmetric 12 % section for horizontal and vertical tails.",
    "clarky": "Clark Y, propeller blade section (flat lower surface, 11.7 % thick).",
    "naca2412-tr05": "Cessna 172 wing section, riveted aluminium: transition fixed at 5 % chord.",
    "naca0009-tr05": "Cessna 172 tail section, riveted aluminium: transition fixed at 5 % chord.",
    "clarky-tr05": "Metal propeller blade section with leading-edge erosion: transition fixed at 5 % chord.",
    "nlf0115": (
        "STAND-IN for the Cirrus SR20 wing section, whose coordinates are not published: the "
        "SR20/SR22 wing section is reported as a proprietary John Roncz design (secondary source "
        "citing D. Lednicer, 'The Incomplete Guide to Airfoil Usage'), and the Cirrus SR22 POH "
        "(section 7, wings) describes the wing cross section only as 'a blend of several high "
        "performance airfoils'. NASA NLF(1)-0115 is used instead: a 15 % natural-laminar-flow "
        "section designed at NASA Langley for general-aviation aircraft with wing loadings of "
        "720-960 N/m^2 (SR20 at 3050 lb: about 1000 N/m^2), design cl_max 1.5 at Re 2.6e6, "
        "cm0 -0.055 (Selig, Maughmer & Somers, J. Aircraft 32(4), 1995)."
    ),
}

#: The post-stall model, as written into the file header.
_POST_STALL_METHOD = (
    "Viterna-Corrigan from the matching angles to +-90 deg; flat plate cl = cd_max/2 sin(2a) "
    "and cd = cd_max sin^2(a) + cd_reverse cos^2(a) beyond +-90 deg; cm from the normal force "
    "with the centre of pressure at x/c = 0.5 - 0.25 cos(a), blended linearly into the matched cm"
)

_ALPHA_FMT = "{:.2f}"
_COEF_FMT = "{:.6f}"
_COLUMNS = ("reynolds", "alpha_deg", "cl", "cd", "cm", "source")
_SOURCES = ("neuralfoil", "viterna")
_NAME_OK = re.compile(r"[a-z0-9][a-z0-9_.\-]*")


class MissingDependencyError(CalibError, ImportError):
    """An optional dependency needed for this operation is not installed."""


def normalize_airfoil_name(name: str) -> str:
    """Canonical airfoil name: lower case, no blanks (``"NACA 2412"`` -> ``"naca2412"``)."""
    return "".join(str(name).split()).lower()


def _wrap_deg(alpha_deg: np.ndarray) -> np.ndarray:
    """Angles [deg] wrapped into [-180, 180] (the tables are periodic: values at +-180 agree)."""
    a = np.asarray(alpha_deg, dtype=float)
    inside = (a >= -180.0) & (a <= 180.0)
    return np.where(inside, a, np.mod(a + 180.0, 360.0) - 180.0)


# --------------------------------------------------------------------------------------------
# Polar and Airfoil
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class Polar:
    """Section coefficients at one Reynolds number over the full -180..180 deg range.

    Arrays are read-only after construction. Coefficients between the tabulated angles are
    interpolated linearly (:meth:`coefficients`).
    """

    name: str              # airfoil name
    reynolds: float        # [-] chord Reynolds number
    mach: float            # [-] Mach number the coefficients are for
    alpha_deg: np.ndarray  # [deg] strictly increasing, first -180, last 180
    cl: np.ndarray         # [-] lift coefficient
    cd: np.ndarray         # [-] drag coefficient
    cm: np.ndarray         # [-] pitching-moment coefficient about the quarter chord, nose up > 0
    source: tuple[str, ...] | None = None  # per point: "neuralfoil" or "viterna" (None: unknown)

    def __post_init__(self) -> None:
        problems: list[Problem] = []
        where = f"{self.name} Re={self.reynolds:.4g}"
        arrays = {}
        for key in ("alpha_deg", "cl", "cd", "cm"):
            arr = np.array(getattr(self, key), dtype=float).reshape(-1)
            arr.setflags(write=False)
            arrays[key] = arr
            object.__setattr__(self, key, arr)
        n = arrays["alpha_deg"].size
        if not (math.isfinite(self.reynolds) and self.reynolds > 0):
            problems.append(Problem(where, f"reynolds must be positive, got {self.reynolds}"))
        if not (math.isfinite(self.mach) and 0.0 <= self.mach < 1.0):
            problems.append(Problem(where, f"mach must be in [0, 1), got {self.mach}"))
        for key, arr in arrays.items():
            if arr.size != n:
                problems.append(Problem(where, f"{key} has {arr.size} values, alpha_deg has {n}"))
            elif not np.all(np.isfinite(arr)):
                problems.append(Problem(where, f"{key} has non-finite values"))
        a = arrays["alpha_deg"]
        if n < 2:
            problems.append(Problem(where, "needs at least 2 angles"))
        else:
            if np.any(np.diff(a) <= 0):
                bad = float(a[1:][np.diff(a) <= 0][0])
                problems.append(Problem(where, f"alpha_deg not strictly increasing at {bad:g} deg"))
            if a[0] != -180.0 or a[-1] != 180.0:
                problems.append(Problem(
                    where, f"alpha_deg must run from -180 to 180, got {a[0]:g}..{a[-1]:g}"))
        if self.source is not None:
            src = tuple(str(s) for s in self.source)
            object.__setattr__(self, "source", src)
            if len(src) != n:
                problems.append(Problem(where, f"source has {len(src)} values, alpha_deg has {n}"))
        raise_if(problems, self.name, DataError)

    # -- evaluation ---------------------------------------------------------------------------

    def coefficients(self, alpha_deg) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(cl, cd, cm) [-] at ``alpha_deg`` [deg] (any shape; wrapped into -180..180)."""
        a = _wrap_deg(alpha_deg)
        return (np.interp(a, self.alpha_deg, self.cl),
                np.interp(a, self.alpha_deg, self.cd),
                np.interp(a, self.alpha_deg, self.cm))

    # -- characteristic numbers -----------------------------------------------------------------

    def _window(self, lo: float = -30.0, hi: float = 30.0) -> tuple[np.ndarray, ...]:
        m = (self.alpha_deg >= lo) & (self.alpha_deg <= hi)
        return self.alpha_deg[m], self.cl[m], self.cd[m], self.cm[m]

    @property
    def lift_slope_per_rad(self) -> float:
        """[1/rad] least-squares slope of cl over the linear range -4..+6 deg."""
        a, cl, _, _ = self._window(-4.0, 6.0)
        if a.size < 2:
            a = np.linspace(-4.0, 6.0, 11)
            cl = self.coefficients(a)[0]
        return float(np.polyfit(np.radians(a), cl, 1)[0])

    @property
    def alpha_zero_lift_deg(self) -> float:
        """[deg] angle of zero lift: the rising zero crossing of cl nearest 0 deg (within +-15 deg)."""
        a, cl, _, _ = self._window(-15.0, 15.0)
        d = np.diff(cl)
        idx = np.nonzero((cl[:-1] <= 0.0) & (cl[1:] > 0.0) | (cl[:-1] < 0.0) & (cl[1:] >= 0.0))[0]
        idx = idx[d[idx] > 0]
        if idx.size == 0:  # no crossing in the window: extrapolate the linear fit
            slope_deg = self.lift_slope_per_rad * math.pi / 180.0
            return float(-self.coefficients(0.0)[0] / slope_deg)
        roots = a[idx] - cl[idx] * (a[idx + 1] - a[idx]) / (cl[idx + 1] - cl[idx])
        return float(roots[np.argmin(np.abs(roots))])

    @property
    def cl_max(self) -> float:
        """[-] maximum lift coefficient within -30..30 deg."""
        return float(np.max(self._window()[1]))

    @property
    def alpha_cl_max_deg(self) -> float:
        """[deg] angle of :attr:`cl_max`."""
        a, cl, _, _ = self._window()
        return float(a[np.argmax(cl)])

    @property
    def cl_min(self) -> float:
        """[-] minimum (most negative) lift coefficient within -30..30 deg."""
        return float(np.min(self._window()[1]))

    @property
    def alpha_cl_min_deg(self) -> float:
        """[deg] angle of :attr:`cl_min`."""
        a, cl, _, _ = self._window()
        return float(a[np.argmin(cl)])

    @property
    def cd_min(self) -> float:
        """[-] minimum drag coefficient within -30..30 deg."""
        return float(np.min(self._window()[2]))

    @property
    def cm0(self) -> float:
        """[-] quarter-chord moment coefficient at zero lift."""
        return float(self.coefficients(self.alpha_zero_lift_deg)[2])


@dataclass(frozen=True, eq=False)
class Airfoil:
    """An airfoil's polars at several Reynolds numbers, with the provenance of the data."""

    name: str                        # canonical airfoil name, e.g. "naca2412"
    polars: tuple[Polar, ...]        # sorted by Reynolds number (sorted on construction)
    provenance: dict[str, str] = field(default_factory=dict)  # header "key: value" lines

    def __post_init__(self) -> None:
        polars = tuple(sorted(self.polars, key=lambda p: p.reynolds))
        object.__setattr__(self, "polars", polars)
        object.__setattr__(self, "provenance", dict(self.provenance))
        problems: list[Problem] = []
        if not polars:
            problems.append(Problem(self.name, "has no polars"))
        res = [p.reynolds for p in polars]
        for r0, r1 in zip(res, res[1:]):
            if r1 == r0:
                problems.append(Problem(self.name, f"two polars at Re {r0:.0f}"))
        for key, value in self.provenance.items():
            if "\n" in str(key) or "\n" in str(value) or ":" in str(key):
                problems.append(Problem(self.name, f"provenance entry {key!r} cannot be written"))
        raise_if(problems, self.name, DataError)

    @property
    def reynolds(self) -> np.ndarray:
        """[-] Reynolds numbers of the stored polars, ascending."""
        return np.array([p.reynolds for p in self.polars], dtype=float)

    def _bracket(self, reynolds: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Lower polar index and log-Re weight of the upper one, clamped to the stored range."""
        res = self.reynolds
        if res.size == 1:
            shape = np.shape(reynolds)
            return np.zeros(shape, dtype=int), np.zeros(shape)
        rey = np.asarray(reynolds, dtype=float)
        if np.any(~np.isfinite(rey) | (rey <= 0)):
            raise ValueError(f"{self.name}: Reynolds numbers must be positive and finite")
        pos = np.interp(np.log(rey), np.log(res), np.arange(res.size, dtype=float))
        k0 = np.minimum(np.floor(pos).astype(int), res.size - 2)
        return k0, pos - k0

    def polar(self, reynolds: float) -> Polar:
        """The polar at ``reynolds`` [-].

        Linear in log(Re) between the two neighbouring stored polars; outside the stored
        range the nearest stored polar is returned unchanged (clamped, no extrapolation).
        """
        k0, w = self._bracket(np.asarray(float(reynolds)))
        k0, w = int(k0), float(w)
        if w == 0.0:
            return self.polars[k0]
        if w == 1.0:
            return self.polars[k0 + 1]
        pa, pb = self.polars[k0], self.polars[k0 + 1]
        grid = np.union1d(pa.alpha_deg, pb.alpha_deg)
        ca, cb = pa.coefficients(grid), pb.coefficients(grid)
        cl, cd, cm = ((1.0 - w) * xa + w * xb for xa, xb in zip(ca, cb))
        return Polar(self.name, float(reynolds), pa.mach, grid, cl, cd, cm)

    def coefficients(self, alpha_deg, reynolds) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(cl, cd, cm) [-] at ``alpha_deg`` [deg] and ``reynolds`` [-] (arrays broadcast together).

        Same interpolation as :meth:`polar` (linear in alpha, linear in log(Re), clamped in Re).
        """
        alpha, rey = np.broadcast_arrays(np.asarray(alpha_deg, dtype=float),
                                        np.asarray(reynolds, dtype=float))
        k0, w = self._bracket(rey)
        tables = [p.coefficients(alpha) for p in self.polars]  # [polar][coef] -> array
        out = []
        for c in range(3):
            stack = np.stack([t[c] for t in tables])  # (n_polars, *shape)
            lo = np.take_along_axis(stack, k0[np.newaxis, ...], axis=0)[0]
            if len(self.polars) == 1:
                out.append(lo)
                continue
            hi = np.take_along_axis(stack, (k0 + 1)[np.newaxis, ...], axis=0)[0]
            out.append((1.0 - w) * lo + w * hi)
        return out[0], out[1], out[2]


# --------------------------------------------------------------------------------------------
# CSV storage
# --------------------------------------------------------------------------------------------


def _fmt(fmt: str, value: float) -> str:
    s = fmt.format(value)
    if s.startswith("-") and float(s) == 0.0:  # no "-0.000000": keeps files reproducible
        s = s[1:]
    return s


def write_airfoil_csv(airfoil: Airfoil, path) -> None:
    """Write ``airfoil`` to ``path``: ``# key: value`` provenance lines, then the table.

    Table columns: ``reynolds,alpha_deg,cl,cd,cm,source``. Fixed formatting (Re as an
    integer, alpha with 2 decimals, coefficients with 6), no timestamps, ``\\n`` line ends.
    """
    buf = io.StringIO()
    for key, value in airfoil.provenance.items():
        buf.write(f"# {key}: {value}\n")
    buf.write(",".join(_COLUMNS) + "\n")
    for p in airfoil.polars:
        re_s = _fmt("{:.0f}", p.reynolds)
        src = p.source if p.source is not None else ("unknown",) * p.alpha_deg.size
        for a, cl, cd, cm, s in zip(p.alpha_deg, p.cl, p.cd, p.cm, src):
            buf.write(",".join((re_s, _fmt(_ALPHA_FMT, a), _fmt(_COEF_FMT, cl),
                                _fmt(_COEF_FMT, cd), _fmt(_COEF_FMT, cm), s)) + "\n")
    Path(path).write_bytes(buf.getvalue().encode("utf-8"))


def read_airfoil_csv(path) -> Airfoil:
    """Read a file written by :func:`write_airfoil_csv`.

    The name comes from the ``airfoil`` header line (else the file name), the Mach number
    from the ``mach`` line (else 0). Raises :class:`DataError` listing every problem found.
    """
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise DataError(path, f"cannot read airfoil file: {exc}") from exc
    lines = text.splitlines()
    provenance: dict[str, str] = {}
    problems: list[Problem] = []
    i = 0
    while i < len(lines) and lines[i].startswith("#"):
        body = lines[i][1:].strip()
        if body:
            key, sep, value = body.partition(":")
            if not sep:
                problems.append(Problem(f"line {i + 1}", "header line is not '# key: value'"))
            else:
                provenance[key.strip()] = value.strip()
        i += 1
    name = normalize_airfoil_name(provenance.get("airfoil", path.stem))
    mach = 0.0
    if "mach" in provenance:
        try:
            mach = float(provenance["mach"])
        except ValueError:
            problems.append(Problem("header mach", f"not a number: {provenance['mach']!r}"))
    if i >= len(lines) or tuple(c.strip() for c in lines[i].split(",")) != _COLUMNS:
        problems.append(Problem(f"line {i + 1}", f"expected the column line {','.join(_COLUMNS)}"))
        raise DataError(path, problems)
    rows: dict[float, list[tuple[float, float, float, float, str]]] = {}
    for lineno, row in enumerate(csv.reader(lines[i + 1:]), start=i + 2):
        if not row or not "".join(row).strip():
            continue
        if len(row) != len(_COLUMNS):
            problems.append(Problem(f"line {lineno}", f"expected {len(_COLUMNS)} columns, got {len(row)}"))
            continue
        try:
            values = [float(v) for v in row[:5]]
        except ValueError:
            problems.append(Problem(f"line {lineno}", f"non-numeric value in {row[:5]}"))
            continue
        source = row[5].strip()
        if source not in _SOURCES + ("unknown",):
            problems.append(Problem(f"line {lineno}", f"source must be one of {_SOURCES}, got {source!r}"))
        rows.setdefault(values[0], []).append((values[1], values[2], values[3], values[4], source))
    if not rows:
        problems.append(Problem(str(path), "no data rows"))
    raise_if(problems, path, DataError)
    polars = []
    for reyn, pts in rows.items():
        a, cl, cd, cm, src = zip(*pts)
        try:
            polars.append(Polar(name, reyn, mach, np.array(a), np.array(cl), np.array(cd),
                                np.array(cm), tuple(src)))
        except DataError as exc:
            problems.extend(exc.problems)
    raise_if(problems, path, DataError)
    return Airfoil(name, tuple(polars), provenance)


def available_airfoils(search_dirs: Sequence[Path]) -> list[str]:
    """Sorted names of the airfoil files (``<name>.csv``) in ``search_dirs``."""
    names = set()
    for d in search_dirs:
        d = Path(d)
        if d.is_dir():
            names.update(p.stem for p in d.glob("*.csv"))
    return sorted(names)


def airfoil_path(name: str, search_dirs: Sequence[Path]) -> Path:
    """``<dir>/<name>.csv`` of the first of ``search_dirs`` that has it.

    An unknown name raises :class:`GeometryError` naming it and listing the available ones.
    """
    key = normalize_airfoil_name(name)
    dirs = [Path(d) for d in search_dirs]
    if _NAME_OK.fullmatch(key):  # plain file names only: no paths
        for d in dirs:
            candidate = d / f"{key}.csv"
            if candidate.is_file():
                return candidate
    available = available_airfoils(dirs)
    listed = ", ".join(available) if available else "none"
    searched = ", ".join(str(d) for d in dirs) if dirs else "no folders given"
    raise GeometryError(f"airfoil {name!r}", [Problem(
        "airfoil", f"unknown airfoil {name!r}; available airfoils: {listed} (searched {searched})")])


def load_airfoil(name: str, search_dirs: Sequence[Path]) -> Airfoil:
    """Read ``<dir>/<name>.csv`` from the first of ``search_dirs`` that has it (:func:`airfoil_path`)."""
    return read_airfoil_csv(airfoil_path(name, search_dirs))


# --------------------------------------------------------------------------------------------
# Post-stall extension
# --------------------------------------------------------------------------------------------


def _viterna_side(alpha_deg: np.ndarray, a_match_deg: float, cl_m: float, cd_m: float,
                  cm_m: float, cd_max: float, cd_reverse: float) -> tuple[np.ndarray, ...]:
    """The model for angles beyond a positive matching angle, ``a_match_deg`` < alpha <= 180."""
    a = np.radians(alpha_deg)
    am = math.radians(a_match_deg)
    s, c = math.sin(am), math.cos(am)
    a1 = cd_max / 2.0
    a2 = (cl_m - cd_max * s * c) * s / c**2
    b2 = (cd_m - cd_max * s**2) / c
    sa, ca = np.sin(a), np.cos(a)
    front = alpha_deg <= 90.0
    with np.errstate(divide="ignore", invalid="ignore"):
        cl_front = a1 * np.sin(2 * a) + a2 * ca**2 / sa
    cl = np.where(front, cl_front, a1 * np.sin(2 * a))
    cd = np.where(front, cd_max * sa**2 + b2 * ca, cd_max * sa**2 + cd_reverse * ca**2)
    # Flat-plate moment: normal force acting at x/c = 0.5 - 0.25 cos(alpha) (1/4 chord at 0,
    # mid chord at 90 deg, 3/4 chord in reversed flow at 180 deg); offset blended to match.
    def cm_plate(ang, cl_, cd_):
        cn = cl_ * np.cos(ang) + cd_ * np.sin(ang)
        return -cn * 0.25 * (1.0 - np.cos(ang))
    offset = cm_m - float(cm_plate(am, cl_m, cd_m))
    w = np.clip((90.0 - alpha_deg) / (90.0 - a_match_deg), 0.0, 1.0)
    cm = cm_plate(a, cl, cd) + offset * w
    return cl, cd, cm


def viterna_extend(alpha_deg, cl, cd, cm, *, cd_max: float, alpha_match_hi_deg: float,
                   alpha_match_lo_deg: float, step_deg: float = 5.0,
                   cd_reverse: float = 0.025) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Extend a polar known between the matching angles to the full -180..180 deg range.

    Between ``alpha_match_lo_deg`` and ``alpha_match_hi_deg`` [deg] the input points are kept
    (cl, cd, cm at the matching angles are interpolated from the input if they fall between
    points). Beyond them, on the angles that are multiples of ``step_deg`` [deg]:

    * matching angle .. +-90 deg: Viterna-Corrigan,
      ``cl = cd_max/2 sin 2a + A2 cos^2 a / sin a``, ``cd = cd_max sin^2 a + B2 cos a``,
      with A2 and B2 chosen so that cl and cd are continuous at the matching angle;
    * +-90 .. +-180 deg (trailing edge first): flat plate, ``cl = cd_max/2 sin 2a`` and
      ``cd = cd_max sin^2 a + cd_reverse cos^2 a``, so cl(+-180) = 0 and cd(+-180) = cd_reverse;
    * cm: the normal force ``cn = cl cos a + cd sin a`` acting at x/c = 0.5 - 0.25 cos a
      (centre of pressure from the quarter chord to mid chord at 90 deg, three-quarter chord
      in reversed flow), ``cm = -cn (x_cp - 0.25)``; so cm(90) = -cd_max/4 (about -0.5 for a
      2-D section). The difference to the matched cm is faded out linearly between the
      matching angle and +-90 deg, so cm is continuous too.

    The negative side uses the same model mirrored (a symmetric section stays symmetric).
    ``cd_max`` [-] is the drag at 90 deg (about 2.0 for an infinite-span flat plate);
    ``cd_reverse`` [-] the drag in reversed flow at 180 deg.

    Returns ``(alpha_deg, cl, cd, cm)`` over -180..180 deg, strictly increasing.
    """
    a = np.asarray(alpha_deg, dtype=float).reshape(-1)
    cl, cd, cm = (np.asarray(x, dtype=float).reshape(-1) for x in (cl, cd, cm))
    hi, lo = float(alpha_match_hi_deg), float(alpha_match_lo_deg)
    problems = []
    if not (a.size == cl.size == cd.size == cm.size and a.size >= 2):
        problems.append(Problem("viterna_extend", "alpha_deg, cl, cd and cm must have equal length >= 2"))
    elif np.any(np.diff(a) <= 0):
        problems.append(Problem("viterna_extend", "alpha_deg must be strictly increasing"))
    if not (0.0 < hi < 90.0 and -90.0 < lo < 0.0):
        problems.append(Problem("viterna_extend", f"matching angles must be in (0, 90) and (-90, 0) deg, got {hi}, {lo}"))
    elif a.size >= 2 and not (a[0] <= lo and hi <= a[-1]):
        problems.append(Problem("viterna_extend", f"matching angles {lo}..{hi} deg outside the input range {a[0]:g}..{a[-1]:g} deg"))
    if not (cd_max > 0 and cd_reverse > 0 and step_deg > 0):
        problems.append(Problem("viterna_extend", "cd_max, cd_reverse and step_deg must be positive"))
    raise_if(problems, "viterna_extend", GeometryError)

    def at(x):
        return float(np.interp(x, a, cl)), float(np.interp(x, a, cd)), float(np.interp(x, a, cm))

    inner = (a >= lo) & (a <= hi)
    a_in, cl_in, cd_in, cm_in = a[inner], cl[inner], cd[inner], cm[inner]
    if a_in.size == 0 or a_in[0] > lo:
        a_in = np.concatenate(([lo], a_in))
        vals = at(lo)
        cl_in, cd_in, cm_in = (np.concatenate(([v], x)) for v, x in zip(vals, (cl_in, cd_in, cm_in)))
    if a_in[-1] < hi:
        a_in = np.concatenate((a_in, [hi]))
        vals = at(hi)
        cl_in, cd_in, cm_in = (np.concatenate((x, [v])) for v, x in zip(vals, (cl_in, cd_in, cm_in)))

    # Extension angles: multiples of step_deg beyond the matching angles, plus +-180.
    n = int(math.floor(180.0 / step_deg + 1e-9))
    grid = np.unique(np.concatenate((np.arange(1, n + 1) * step_deg, [180.0])))
    gap = 1e-6
    pos = grid[grid > hi + gap]
    neg = -grid[grid > -lo + gap][::-1]

    clh, cdh, cmh = cl_in[-1], cd_in[-1], cm_in[-1]
    cl_p, cd_p, cm_p = _viterna_side(pos, hi, clh, cdh, cmh, cd_max, cd_reverse)
    cll, cdl, cml = cl_in[0], cd_in[0], cm_in[0]
    # Mirror: alpha -> -alpha, cl -> -cl, cm -> -cm, cd unchanged.
    cl_n, cd_n, cm_n = _viterna_side(-neg, -lo, -cll, cdl, -cml, cd_max, cd_reverse)
    cl_n, cm_n = -cl_n, -cm_n

    alpha_full = np.concatenate((neg, a_in, pos))
    cl_full = np.concatenate((cl_n, cl_in, cl_p))
    cd_full = np.concatenate((cd_n, cd_in, cd_p))
    cm_full = np.concatenate((cm_n, cm_in, cm_p))
    # Exact periodic end values (cl = 0 and equal cd, cm at -180 and +180).
    cl_full[0] = cl_full[-1] = 0.0
    cd_full[0] = cd_full[-1] = cd_reverse
    cm_full[0] = cm_full[-1] = 0.0
    return alpha_full, cl_full, cd_full, cm_full



# --------------------------------------------------------------------------------------------
# Geometry
# --------------------------------------------------------------------------------------------


def naca4_coordinates(code: str, n_points: int = 161) -> np.ndarray:
    """Coordinates (N, 2) [x/c, y/c] of a NACA 4-digit section with a closed trailing edge.

    ``code`` is the four digits (``"2412"``, also ``"naca2412"``). Points are cosine spaced,
    in Selig order: upper surface from the trailing edge to the leading edge, then the lower
    surface back to the trailing edge; the leading edge point is shared, so ``n_points`` must
    be odd. Thickness uses the closed-trailing-edge coefficient -0.1036 for x^4; thickness is
    laid off perpendicular to the mean line (Abbott & von Doenhoff, Theory of Wing Sections,
    sec. 6.4).
    """
    digits = normalize_airfoil_name(code)
    if digits.startswith("naca"):
        digits = digits[4:]
    problems = []
    if len(digits) != 4 or not digits.isdigit():
        problems.append(Problem("naca4", f"{code!r} is not a NACA 4-digit code"))
    if not (isinstance(n_points, (int, np.integer)) and n_points >= 11 and n_points % 2 == 1):
        problems.append(Problem("naca4", f"n_points must be an odd integer >= 11, got {n_points!r}"))
    if not problems:
        m, p, t = int(digits[0]) / 100.0, int(digits[1]) / 10.0, int(digits[2:]) / 100.0
        if t <= 0:
            problems.append(Problem("naca4", f"{code!r} has zero thickness"))
        if (m > 0) != (p > 0):
            problems.append(Problem("naca4", f"{code!r}: camber and its position must both be zero or both non-zero"))
    raise_if(problems, code, GeometryError)

    n_side = (n_points + 1) // 2
    beta = np.linspace(0.0, math.pi, n_side)
    x = 0.5 * (1.0 - np.cos(beta))  # 0 (leading edge) .. 1 (trailing edge)
    yt = 5.0 * t * (0.2969 * np.sqrt(x) - 0.1260 * x - 0.3516 * x**2 + 0.2843 * x**3 - 0.1036 * x**4)
    yc = np.zeros_like(x)
    dyc = np.zeros_like(x)
    if m > 0:
        fore = x < p
        yc = np.where(fore, m / p**2 * (2 * p * x - x**2), m / (1 - p) ** 2 * ((1 - 2 * p) + 2 * p * x - x**2))
        dyc = np.where(fore, 2 * m / p**2 * (p - x), 2 * m / (1 - p) ** 2 * (p - x))
    theta = np.arctan(dyc)
    xu, yu = x - yt * np.sin(theta), yc + yt * np.cos(theta)
    xl, yl = x + yt * np.sin(theta), yc - yt * np.cos(theta)
    upper = np.column_stack((xu, yu))[::-1]  # trailing edge -> leading edge
    lower = np.column_stack((xl, yl))[1:]    # leading edge (shared) excluded -> trailing edge
    return np.vstack((upper, lower))


def _is_naca4(name: str) -> bool:
    return len(name) == 8 and name.startswith("naca") and name[4:].isdigit()


# --------------------------------------------------------------------------------------------
# Computing polars with NeuralFoil
# --------------------------------------------------------------------------------------------


def _import_neuralfoil():
    try:
        import neuralfoil  # noqa: F401
        import aerosandbox  # noqa: F401
    except ImportError as exc:
        raise MissingDependencyError(
            "computing airfoil polars needs NeuralFoil, which is not installed: "
            "pip install jsbsim-calib[airfoils]") from exc
    return neuralfoil, aerosandbox


def _package_version(module, dist: str) -> str:
    version = getattr(module, "__version__", None)
    if version:
        return str(version)
    try:
        from importlib.metadata import version as _v
        return _v(dist)
    except Exception:  # pragma: no cover - metadata missing
        return "unknown"


def split_transition(name: str) -> tuple[str, float | None]:
    """``"naca2412-tr05"`` -> (``"naca2412"``, 0.05): a ``-trNN`` suffix fixes boundary-layer
    transition at NN % chord on both surfaces (a production surface with protruding rivets
    or joints); no suffix means free transition (``n_crit``)."""
    key = normalize_airfoil_name(name)
    base, sep, tail = key.rpartition("-tr")
    if sep and tail.isdigit() and base:
        return base, int(tail) / 100.0
    return key, None


def _neuralfoil_eval(airfoil_obj, alpha_deg: np.ndarray, reynolds: float, n_crit: float,
                     model_size: str, xtr: float = 1.0) -> dict[str, np.ndarray]:
    """NeuralFoil at the given angles [deg] and one Reynolds number [-] (incompressible)."""
    nf, _ = _import_neuralfoil()
    out = nf.get_aero_from_airfoil(airfoil=airfoil_obj, alpha=np.asarray(alpha_deg, dtype=float),
                                   Re=float(reynolds), n_crit=n_crit, xtr_upper=xtr, xtr_lower=xtr,
                                   model_size=model_size)
    return {k: np.asarray(out[k], dtype=float).reshape(-1)
            for k in ("analysis_confidence", "CL", "CD", "CM")}


def _matching_angles(alpha: np.ndarray, cl: np.ndarray, conf: np.ndarray, confidence_min: float,
                     stall_margin_deg: float, max_cl_step: float, name: str,
                     reynolds: float) -> tuple[float, float]:
    """Matching angles [deg] (upper, lower) between NeuralFoil and the post-stall model.

    cl_max (cl_min) is searched in the range around 0 deg where NeuralFoil's confidence stays
    at or above ``confidence_min``. From there the NeuralFoil range goes on outwards for at
    most ``stall_margin_deg``, while the confidence stays high enough and cl changes by no
    more than ``max_cl_step`` between neighbouring angles: an abrupt stall (cl collapsing
    within a fraction of a degree) is left to the continuous post-stall model.
    """
    i0 = int(np.argmin(np.abs(alpha)))
    if conf[i0] < confidence_min:
        raise GeometryError(name, [Problem(f"Re {reynolds:.4g}", (
            f"NeuralFoil confidence at 0 deg is {conf[i0]:.2f} < {confidence_min}; "
            "the section is outside its training range"))])
    hi = i0
    while hi + 1 < alpha.size and conf[hi + 1] >= confidence_min:
        hi += 1
    lo = i0
    while lo > 0 and conf[lo - 1] >= confidence_min:
        lo -= 1

    def walk(i_peak: int, direction: int) -> float:
        j = i_peak
        while True:
            k = j + direction
            if not (lo <= k <= hi) or abs(alpha[k] - alpha[i_peak]) > stall_margin_deg + 1e-9:
                break
            if abs(cl[k] - cl[j]) > max_cl_step:
                break
            j = k
        return float(alpha[j])

    i_max = i0 + int(np.argmax(cl[i0:hi + 1]))
    i_min = lo + int(np.argmin(cl[lo:i0 + 1]))
    return walk(i_max, +1), walk(i_min, -1)


def compute_airfoil(name: str, reynolds: Sequence[float], *, coordinates=None, n_crit: float = 9.0,
                    mach: float = 0.0, model_size: str = "xlarge", cd_max: float = 2.0,
                    cd_reverse: float = 0.025, confidence_min: float = 0.5,
                    stall_margin_deg: float = 4.0, max_cl_drop_per_deg: float = 0.3,
                    step_deg: float = 0.5, extension_step_deg: float = 5.0) -> Airfoil:
    """Compute the polars of an airfoil at ``reynolds`` [-] with NeuralFoil plus a post-stall model.

    Coordinates: ``nacaXXXX`` names use :func:`naca4_coordinates`; other names come from
    aerosandbox's copy of the UIUC database (``asb.Airfoil(name).coordinates``), unless
    ``coordinates`` (N, 2) [x/c, y/c] in Selig order are given.

    NeuralFoil (``model_size``, transition amplification ``n_crit``) is evaluated every
    ``step_deg`` [deg] from -30 to 30 deg. It is used from 0 deg outwards while its
    ``analysis_confidence`` is at least ``confidence_min`` (0.5: NeuralFoil rates the
    analysis more likely trustworthy than not), and at most ``stall_margin_deg`` past cl_max
    (past cl_min on the negative side), stopping before cl changes faster than
    ``max_cl_drop_per_deg`` [1/deg] (an abrupt stall); :func:`viterna_extend` with
    ``cd_max``, ``cd_reverse`` and ``extension_step_deg`` takes over beyond. NeuralFoil is
    incompressible; for ``mach`` > 0 cl and cm are scaled by Prandtl-Glauert 1/sqrt(1-M^2).

    Needs NeuralFoil (``pip install jsbsim-calib[airfoils]``): raises
    :class:`MissingDependencyError` without it.
    """
    nf, asb = _import_neuralfoil()
    key = normalize_airfoil_name(name)
    shape, xtr = split_transition(key)
    res = sorted({float(r) for r in reynolds})
    problems = []
    if not res or any(not (math.isfinite(r) and r > 0) for r in res):
        problems.append(Problem("reynolds", f"need positive Reynolds numbers, got {list(reynolds)}"))
    if not (0.0 <= mach < 0.7):
        problems.append(Problem("mach", f"must be in [0, 0.7) (Prandtl-Glauert), got {mach}"))
    raise_if(problems, key, GeometryError)

    if coordinates is not None:
        coords = np.asarray(coordinates, dtype=float)
        coord_source = "explicit coordinates passed to compute_airfoil"
    elif _is_naca4(shape):
        coords = naca4_coordinates(shape)
        coord_source = ("NACA 4-digit equations (Abbott & von Doenhoff), closed trailing edge, "
                        "161 cosine-spaced points, jsbsim_calib.airfoil.naca4_coordinates")
    else:
        try:
            coords = np.asarray(asb.Airfoil(shape).coordinates, dtype=float)
        except Exception as exc:  # aerosandbox raises various errors for unknown names
            raise GeometryError(key, [Problem("airfoil", f"no coordinates for {name!r} in "
                                              f"aerosandbox's airfoil database: {exc}")]) from exc
        coord_source = (f"UIUC Airfoil Coordinates Database file {shape}.dat as shipped in "
                        f"aerosandbox {_package_version(asb, 'aerosandbox')}")
    if coords.ndim != 2 or coords.shape[1] != 2 or coords.shape[0] < 10 or not np.all(np.isfinite(coords)):
        raise GeometryError(key, [Problem("coordinates", f"need an (N, 2) array of finite x/c, y/c with N >= 10, got shape {coords.shape}")])
    af_obj = asb.Airfoil(name=key, coordinates=coords)

    alpha_nf = np.round(np.arange(-30.0, 30.0 + step_deg / 2, step_deg), 6)
    pg = 1.0 / math.sqrt(1.0 - mach**2)
    polars = []
    for reyn in res:
        out = _neuralfoil_eval(af_obj, alpha_nf, reyn, n_crit, model_size, 1.0 if xtr is None else xtr)
        a_hi, a_lo = _matching_angles(alpha_nf, out["CL"], out["analysis_confidence"],
                                      confidence_min, stall_margin_deg,
                                      max_cl_drop_per_deg * step_deg, key, reyn)
        a, cl, cd, cm = viterna_extend(alpha_nf, out["CL"] * pg, out["CD"], out["CM"] * pg,
                                       cd_max=cd_max, alpha_match_hi_deg=a_hi,
                                       alpha_match_lo_deg=a_lo, step_deg=extension_step_deg,
                                       cd_reverse=cd_reverse)
        source = tuple("neuralfoil" if a_lo <= x <= a_hi else "viterna" for x in a)
        polars.append(Polar(key, reyn, float(mach), a, cl, cd, cm, source))

    provenance = {
        "airfoil": key,
        "usage": STORED_AIRFOILS.get(key, "not in jsbsim_calib.airfoil.STORED_AIRFOILS"),
        "coordinates": coord_source,
        "tool": f"NeuralFoil {_package_version(nf, 'neuralfoil')}",
        "cst_fit": f"aerosandbox {_package_version(asb, 'aerosandbox')} (8+8 Kulfan weights, inside NeuralFoil)",
        "model_size": model_size,
        "n_crit": f"{n_crit:g}",
        "transition": ("free (e^N method)" if xtr is None else
                       f"fixed at {xtr:g} chord on both surfaces (production surface, protruding rivets)"),
        "mach": f"{mach:g}",
        "compressibility": "none (incompressible)" if mach == 0 else "Prandtl-Glauert on cl and cm",
        "neuralfoil_range": (f"from 0 deg outwards while analysis_confidence >= {confidence_min:g}, "
                             f"at most {stall_margin_deg:g} deg past cl_max / cl_min and only while "
                             f"cl changes by at most {max_cl_drop_per_deg:g} per deg, "
                             f"{step_deg:g} deg steps"),
        "post_stall": _POST_STALL_METHOD,
        "cd_max": f"{cd_max:g}",
        "cd_reverse": f"{cd_reverse:g}",
        "extension_step_deg": f"{extension_step_deg:g}",
        "reynolds": " ".join(f"{r:.0f}" for r in res),
        "columns": "reynolds [-], alpha_deg [deg], cl [-], cd [-], cm [-] about c/4 nose up, "
                   "source (neuralfoil or viterna)",
        "regenerate": f"jsbsim-calib airfoil {key}",
        "regenerate_python": (f"python -c \"from jsbsim_calib.airfoil import regenerate; "
                              f"regenerate('{key}', 'airfoils')\""),
    }
    return Airfoil(key, tuple(polars), provenance)


def regenerate(name: str, out_dir, reynolds: Sequence[float] = DEFAULT_REYNOLDS) -> Path:
    """Recompute ``name`` with the default settings and write ``<out_dir>/<name>.csv``.

    Returns the path written. Needs NeuralFoil (``pip install jsbsim-calib[airfoils]``).
    """
    airfoil = compute_airfoil(name, reynolds)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    path = out / f"{airfoil.name}.csv"
    write_airfoil_csv(airfoil, path)
    return path
