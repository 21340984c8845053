"""Propeller performance tables from blade-element momentum (BEM) theory.

The tables are the ones JSBSim's ``FGPropeller`` reads:

* ``C_THRUST(J)`` and ``C_POWER(J)`` for a fixed-pitch propeller,
* ``C_THRUST(J, blade angle)`` and ``C_POWER(J, blade angle)`` for a
  constant-speed propeller,

with JSBSim's definitions ``J = V / (n D)``, ``CT = T / (rho n^2 D^4)``,
``CP = P / (rho n^3 D^5)`` (``n`` in rev/s) and the blade angle being the
geometric blade angle at 75 % radius in degrees.

Solver
------
Each blade station is solved independently for its inflow angle ``phi`` (the
angle between the local relative wind and the plane of rotation).  Propeller
sign convention: the axial induction ``a`` *adds* to the flight speed
(``V (1 + a)`` through the disk) and the tangential induction ``a'`` *reduces*
the blade speed (``Omega r (1 - a')``), so ``tan(phi) = V (1 + a) / (Omega r (1 - a'))``.
With the local solidity ``s = B c / (2 pi r)``, the loss factor ``F`` and the
force coefficients normal and tangential to the plane of rotation
``cn = cl cos(phi) - cd sin(phi)`` and ``ct = cl sin(phi) + cd cos(phi)``,
equating blade-element and momentum thrust and torque per annulus gives::

    k  = s cn / (4 F sin(phi)^2)          a / (1 + a) = k
    k' = s ct / (4 F |sin(phi)| cos(phi)) a' / (1 - a') = k'

and the one-unknown residual (S. A. Ning, "A simple solution method for the
blade element momentum equations with guaranteed convergence", Wind Energy
2014, written here in the propeller convention)::

    R(phi) = sin(phi) / (1 + a) - lambda_r cos(phi) (1 + k'),   lambda_r = V / (Omega r)

in which ``1 / (1 + a) = 1 - k`` never divides by zero.  For ``V >= 0``,
``R -> -inf`` as ``phi -> 0+`` (as long as the section lifts at the geometric
blade angle) and ``R(pi/2) > 0``, so a root is bracketed in ``(0, pi/2]``.
The residual is sampled on a 1-degree grid, the first sign change from small
``phi`` is taken (the physical, lowest-inflow solution when stall makes
several roots) and refined with a vectorised Illinois (modified regula falsi)
iteration, which keeps the bracket and converges superlinearly.  The static
case ``V = 0`` needs nothing special (``lambda_r = 0``: the root is ``k = 1``).
Static with negative blade lift at the geometric angle (reverse pitch) has no
root in ``(0, pi/2]``: the flow runs backwards through the disk, the momentum
thrust is ``-4 pi r rho v^2 F`` (root ``k = -1``) and ``phi`` is searched in
``[-pi/2, 0)``.  A station whose blade angle reaches 90 deg (far outside any
propeller setting) can lose its bracket; it is then reported as not converged
(``BEMPoint.converged``, ``provenance["unconverged_points"]``) and the grid
point with the smallest residual is used.

Windmill / propeller-brake region: when the blade produces negative thrust the
induction reverses (``a < 0``).  Past ``a = -0.4`` simple momentum theory
fails (turbulent-wake state); there Buhl's empirical thrust curve
(NREL/TP-500-36834, 2005), which joins momentum theory with equal value and
slope at ``a = -0.4``, replaces it, so the residual stays continuous and
bounded.

Loss factors: Prandtl's tip and hub losses with the local inflow angle,
``F = (2/pi) acos(exp(-f))``, ``f_tip = B/2 (R - r) / (r |sin phi|)``,
``f_hub = B/2 (r - r_hub) / (r_hub |sin phi|)``.  A station where ``F = 0``
(the tip with tip loss, the hub with hub loss) carries no load.

Section Reynolds and Mach numbers use the local relative speed with the small
swirl term neglected, ``W = Omega r / cos(phi)`` (capped at 5 times the
no-induction speed), so the residual is a function of ``phi`` alone and the
bracket stays valid.  At the root this differs from the exact ``W`` only by the
factor ``1 - a'`` (about 1 % outboard, up to about 10 % at the root).

Compressibility (off by default, ``compressibility=True`` to use): the lift
coefficient is divided by the Prandtl-Glauert factor ``sqrt(1 - M^2)`` with the
local Mach number capped at ``MACH_CAP`` = 0.7.  There is no drag-rise model,
so this only makes sense below the critical Mach number; JSBSim's separate
``CT_MACH`` / ``CP_MACH`` tables are the other place for Mach effects.

Thrust and torque are integrated over the stations with the trapezoid rule in
``r``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Callable, Mapping, Protocol, Sequence, runtime_checkable

import numpy as np
from scipy.interpolate import CubicSpline

from ..core.errors import GeometryError, Problem, raise_if

__all__ = [
    "SectionPolar",
    "Blade",
    "helical_blade",
    "BEMPoint",
    "bem_point",
    "PropellerTables",
    "propeller_tables",
    "apply_factors",
    "blade_angle_absorbing",
    "MACH_CAP",
]

MACH_CAP = 0.7                 # [-] local Mach cap of the optional Prandtl-Glauert lift correction
_BUHL_A = 0.4                  # [-] |a| where Buhl's curve takes over from momentum theory
_PHI_GRID_STEP_DEG = 1.0       # [deg] sampling step of the bracket search
_PHI_MIN = 1e-6                # [rad] lower end of the bracket search
_XTOL = 1e-10                  # [rad] root tolerance on phi
_MAX_ITER = 200


@runtime_checkable
class SectionPolar(Protocol):
    """Section aerodynamics: anything with a vectorised ``coefficients`` method.

    ``coefficients(alpha_deg, reynolds)`` takes equal-shape arrays of angle of
    attack [deg] (the full -180..180 deg range) and Reynolds number [-] and
    returns ``(cl, cd, cm)`` arrays of the same shape.
    """

    def coefficients(self, alpha_deg: np.ndarray, reynolds: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        ...


def _frozen_array(x: object) -> np.ndarray:
    a = np.array(x, dtype=float)  # always a copy
    a.setflags(write=False)
    return a


# --------------------------------------------------------------------------- geometry


@dataclass(frozen=True, eq=False)
class Blade:
    """Propeller blade geometry plus its section polar."""

    diameter_m: float            # [m]
    n_blades: int                # [-]
    hub_radius_m: float          # [m] where the blade starts
    r_over_R: np.ndarray         # [-] stations, increasing, from hub to 1.0
    chord_m: np.ndarray          # [m] at the stations
    beta_deg: np.ndarray         # [deg] geometric blade angle at the stations for the reference setting
    section: SectionPolar        # section aerodynamics (cl, cd, cm)(alpha [deg], Re)

    def __post_init__(self) -> None:
        problems: list[Problem] = []
        for name in ("r_over_R", "chord_m", "beta_deg"):
            object.__setattr__(self, name, _frozen_array(getattr(self, name)))
        x, c, b = self.r_over_R, self.chord_m, self.beta_deg
        if not (math.isfinite(self.diameter_m) and self.diameter_m > 0):
            problems.append(Problem("diameter_m", f"must be > 0, got {self.diameter_m!r}"))
        if int(self.n_blades) != self.n_blades or self.n_blades < 1:
            problems.append(Problem("n_blades", f"must be a positive integer, got {self.n_blades!r}"))
        R = 0.5 * self.diameter_m
        if not (math.isfinite(self.hub_radius_m) and 0 <= self.hub_radius_m < R):
            problems.append(Problem("hub_radius_m", f"must be in [0, diameter/2), got {self.hub_radius_m!r}"))
        if x.ndim != 1 or x.size < 3:
            problems.append(Problem("r_over_R", "must be a 1-D array of at least 3 stations"))
        else:
            if not np.all(np.isfinite(x)):
                problems.append(Problem("r_over_R", "must be finite"))
            elif np.any(np.diff(x) <= 0):
                problems.append(Problem("r_over_R", "must be strictly increasing"))
            else:
                if abs(x[-1] - 1.0) > 1e-9:
                    problems.append(Problem("r_over_R", f"last station must be 1.0 (the tip), got {x[-1]!r}"))
                if x[0] <= 0:
                    problems.append(Problem("r_over_R", "first station must be > 0"))
                if R > 0 and x[0] < self.hub_radius_m / R - 1e-9:
                    problems.append(Problem("r_over_R", f"first station {x[0]:.4g} is inside the hub ({self.hub_radius_m / R:.4g})"))
            for name, arr in (("chord_m", c), ("beta_deg", b)):
                if arr.shape != x.shape:
                    problems.append(Problem(name, f"must have the shape of r_over_R {x.shape}, got {arr.shape}"))
                elif not np.all(np.isfinite(arr)):
                    problems.append(Problem(name, "must be finite"))
            if c.shape == x.shape and np.any(c < 0):
                problems.append(Problem("chord_m", "must be >= 0"))
        if not callable(getattr(self.section, "coefficients", None)):
            problems.append(Problem("section", "must have a coefficients(alpha_deg, reynolds) method"))
        raise_if(problems, "Blade", GeometryError)

    @property
    def radius_m(self) -> float:
        """Tip radius [m]."""
        return 0.5 * self.diameter_m

    @property
    def beta75_deg(self) -> float:
        """Geometric blade angle at 0.75 R [deg] (linear interpolation between stations)."""
        return float(np.interp(0.75, self.r_over_R, self.beta_deg))

    def with_beta75(self, beta75_deg: float) -> "Blade":
        """The same blade rotated about its pitch axis so that the 0.75 R angle is ``beta75_deg``."""
        return replace(self, beta_deg=self.beta_deg + (float(beta75_deg) - self.beta75_deg))

    @property
    def activity_factor(self) -> float:
        """Blade activity factor ``100000/16 * integral (c/D) x^3 dx`` over the blade [-]."""
        return float(100000.0 / 16.0 * _trapz(self.chord_m / self.diameter_m * self.r_over_R**3, self.r_over_R))


def _trapz(y: np.ndarray, x: np.ndarray) -> float:
    return float(np.sum(0.5 * (y[1:] + y[:-1]) * np.diff(x)))


def helical_blade(
    diameter_m: float,
    n_blades: int,
    pitch_m: float,
    *,
    hub_radius_m: float,
    chord_over_R: Callable[[np.ndarray], np.ndarray] | Sequence[float] | np.ndarray,
    section: SectionPolar,
    n_stations: int = 25,
) -> Blade:
    """Blade of constant geometric pitch: ``beta(r) = atan(pitch / (2 pi r))``.

    Stations are cosine-spaced from the hub to the tip (dense at both ends,
    where the loss factors change fast) with the station nearest 0.75 R moved
    to exactly 0.75 R, so ``beta75_deg`` is exact.

    ``chord_over_R`` (chord / tip radius) is either a callable of ``r/R``
    (array in, array out), a table of ``(r/R, c/R)`` rows (shape ``(m, 2)``,
    interpolated linearly, constant beyond its ends), or an array of
    ``n_stations`` values at the stations described above.

    Example: McCauley 1A170E/JHA7660 (C172), 76 in diameter and 60 in pitch,
    gives about 18.5 deg at 0.75 R.
    """
    problems: list[Problem] = []
    if not (math.isfinite(diameter_m) and diameter_m > 0):
        problems.append(Problem("diameter_m", f"must be > 0, got {diameter_m!r}"))
    if not (math.isfinite(pitch_m) and pitch_m > 0):
        problems.append(Problem("pitch_m", f"must be > 0, got {pitch_m!r}"))
    if int(n_stations) != n_stations or n_stations < 5:
        problems.append(Problem("n_stations", f"must be an integer >= 5, got {n_stations!r}"))
    R = 0.5 * diameter_m if diameter_m > 0 else float("nan")
    if not (math.isfinite(hub_radius_m) and 0 < hub_radius_m < 0.75 * R):
        problems.append(Problem("hub_radius_m", f"must be in (0, 0.75 * diameter/2), got {hub_radius_m!r}"))
    raise_if(problems, "helical_blade", GeometryError)

    x_hub = hub_radius_m / R
    theta = np.linspace(0.0, math.pi, int(n_stations))
    x = x_hub + (1.0 - x_hub) * 0.5 * (1.0 - np.cos(theta))
    i75 = int(np.argmin(np.abs(x[1:-1] - 0.75))) + 1
    x[i75] = 0.75
    x[0], x[-1] = x_hub, 1.0

    if callable(chord_over_R):
        c_R = np.asarray(chord_over_R(x.copy()), dtype=float)
        c_R = np.broadcast_to(c_R, x.shape).astype(float)
    else:
        arr = np.asarray(chord_over_R, dtype=float)
        if arr.ndim == 2 and arr.shape[1] == 2:
            order = np.argsort(arr[:, 0])
            c_R = np.interp(x, arr[order, 0], arr[order, 1])
        elif arr.shape == x.shape:
            c_R = arr.copy()
        else:
            raise GeometryError(
                "helical_blade",
                Problem("chord_over_R", f"must be a callable, an (m, 2) table or {x.size} values, got shape {arr.shape}"),
            )
    beta = np.degrees(np.arctan(pitch_m / (2.0 * math.pi * x * R)))
    return Blade(
        diameter_m=float(diameter_m),
        n_blades=int(n_blades),
        hub_radius_m=float(hub_radius_m),
        r_over_R=x,
        chord_m=c_R * R,
        beta_deg=beta,
        section=section,
    )


# --------------------------------------------------------------------------- BEM


@dataclass(frozen=True, eq=False)
class BEMPoint:
    """Result of one BEM evaluation (one flight speed, one rpm, one blade angle)."""

    J: float                     # [-] advance ratio V/(n D)
    CT: float                    # [-] T/(rho n^2 D^4)
    CP: float                    # [-] P/(rho n^3 D^5)
    CQ: float                    # [-] Q/(rho n^2 D^5) = CP / (2 pi)
    efficiency: float            # [-] T V / P; nan where P <= 0 (windmilling)
    thrust_N: float              # [N]
    power_W: float               # [W] shaft power absorbed (negative when windmilling)
    converged: bool              # every loaded station found a bracketed, converged root
    torque_Nm: float             # [N m]
    r_over_R: np.ndarray         # [-] stations
    phi_deg: np.ndarray          # [deg] inflow angle per station
    alpha_deg: np.ndarray        # [deg] angle of attack per station
    a: np.ndarray                # [-] axial induction (propeller sign: adds to V); nan when V = 0
    a_prime: np.ndarray          # [-] tangential induction (reduces Omega r)
    F: np.ndarray                # [-] combined Prandtl tip x hub loss factor
    reynolds: np.ndarray         # [-] section Reynolds number used
    dT_dr: np.ndarray            # [N/m] thrust per unit radius (all blades)
    dQ_dr: np.ndarray            # [N m/m] torque per unit radius (all blades)


class _Stations:
    """Per-station constants and the vectorised BEM residual."""

    def __init__(self, blade: Blade, V: float, omega: float, speed_of_sound: float,
                 nu: float, tip_loss: bool, hub_loss: bool, compressibility: bool):
        R = blade.radius_m
        self.R = R
        self.Rh = blade.hub_radius_m
        self.B = float(blade.n_blades)
        self.r = blade.r_over_R * R
        self.c = np.asarray(blade.chord_m, dtype=float)
        self.beta = np.radians(blade.beta_deg)
        self.sigma = self.B * self.c / (2.0 * math.pi * self.r)
        self.omega_r = omega * self.r
        self.lam = V / self.omega_r
        self.V = V
        self.W0 = np.hypot(V, self.omega_r)
        self.nu = nu
        self.a_sound = speed_of_sound
        self.tip_loss = tip_loss
        self.hub_loss = hub_loss and self.Rh > 0
        self.compressibility = compressibility
        self.section = blade.section
        dead = np.zeros(self.r.shape, dtype=bool)
        if self.tip_loss:
            dead |= self.r >= R * (1.0 - 1e-12)
        if self.hub_loss:
            dead |= self.r <= self.Rh * (1.0 + 1e-12)
        dead |= self.c <= 0.0
        self.dead = dead

    def evaluate(self, phi: np.ndarray, idx: np.ndarray) -> dict[str, np.ndarray]:
        """Residual and intermediate quantities at ``phi`` for stations ``idx``.

        ``phi`` has shape ``(len(idx),)`` or ``(len(idx), m)``.
        """
        extra = (slice(None),) + (None,) * (phi.ndim - 1)

        def g(a: np.ndarray) -> np.ndarray:
            return a[idx][extra]

        r, c, beta, sigma, omega_r, lam, W0 = (g(v) for v in (self.r, self.c, self.beta, self.sigma,
                                                               self.omega_r, self.lam, self.W0))
        sphi, cphi = np.sin(phi), np.cos(phi)
        abs_s = np.abs(sphi)
        W_est = np.minimum(omega_r / np.maximum(np.abs(cphi), 1e-12), 5.0 * W0)
        W_est = np.broadcast_to(W_est, phi.shape)
        reynolds = W_est * np.broadcast_to(c, phi.shape) / self.nu
        alpha = np.broadcast_to(beta, phi.shape) - phi
        cl, cd, _ = self.section.coefficients(np.degrees(alpha).ravel(), reynolds.ravel())
        cl = np.broadcast_to(np.asarray(cl, dtype=float).reshape(-1), (phi.size,)).reshape(phi.shape).copy()
        cd = np.broadcast_to(np.asarray(cd, dtype=float).reshape(-1), (phi.size,)).reshape(phi.shape)
        if self.compressibility:
            mach = np.minimum(W_est / self.a_sound, MACH_CAP)
            cl = cl / np.sqrt(1.0 - mach**2)
        cn = cl * cphi - cd * sphi
        ct = cl * sphi + cd * cphi

        with np.errstate(divide="ignore", over="ignore", invalid="ignore"):
            F = np.ones(phi.shape)
            if self.tip_loss:
                f = 0.5 * self.B * (self.R - r) / (r * abs_s)
                F = F * (2.0 / math.pi) * np.arccos(np.exp(-f))
            if self.hub_loss:
                f = 0.5 * self.B * (r - self.Rh) / (self.Rh * abs_s)
                F = F * (2.0 / math.pi) * np.arccos(np.exp(-f))
            k = sigma * cn / (4.0 * F * sphi**2)
            kp = sigma * ct / (4.0 * F * abs_s * cphi)
            inv1pa = 1.0 - k                       # 1/(1+a) from momentum theory, a/(1+a) = k
            buhl = k < -_BUHL_A / (1.0 - _BUHL_A)  # a < -0.4: turbulent-wake state
            if np.any(buhl):
                inv1pa = np.where(buhl, 1.0 / (1.0 - _buhl_induction(-k, F)), inv1pa)
            # R = sin(phi)/(1+a) - lambda cos(phi) (1 + k'), written without the cos(phi) pole
            resid = sphi * inv1pa - lam * (cphi + sigma * ct / (4.0 * F * sphi))
            if self.V == 0.0 and np.any(phi < 0):
                # static, reversed flow through the disk (negative thrust): momentum
                # thrust -4 pi r rho v^2 F, i.e. k = -1, written as sin^2(phi) (1 + k)
                resid = np.where(phi < 0, sphi**2 + sigma * cn / (4.0 * F), resid)
        return dict(resid=resid, F=F, k=k, kp=kp, inv1pa=inv1pa, cl=cl, cd=cd, cn=cn, ct=ct,
                    alpha=alpha, reynolds=reynolds)


def _buhl_induction(kw: np.ndarray, F: np.ndarray) -> np.ndarray:
    """Wind-turbine-sign induction ``aw`` in (0.4, 1) on Buhl's empirical curve.

    Solves ``4 F kw (1 - aw)^2 = 8/9 + (4F - 40/9) aw + (50/9 - 4F) aw^2``
    (blade-element thrust = Buhl's thrust) for the root in (0.4, 1); the left
    side minus the right side is positive at 0.4 (for kw > 2/3) and -2 at 1,
    so exactly one root lies there.  Only meaningful where kw > 2/3.
    """
    kw = np.asarray(kw, dtype=float)
    F = np.broadcast_to(F, kw.shape)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        A = 4.0 * F * kw - 50.0 / 9.0 + 4.0 * F
        Bq = -8.0 * F * kw - 4.0 * F + 40.0 / 9.0
        C = 4.0 * F * kw - 8.0 / 9.0
        disc = np.maximum(Bq * Bq - 4.0 * A * C, 0.0)
        q = -0.5 * (Bq + np.where(Bq >= 0, 1.0, -1.0) * np.sqrt(disc))
        r1 = q / A
        r2 = C / q
        ok1 = (r1 >= 0.4 - 1e-9) & (r1 <= 1.0)
        aw = np.where(ok1, r1, r2)
        aw = np.where(np.isfinite(aw), aw, 0.4)
    return np.clip(aw, 0.4, 1.0 - 1e-12)


def _phi_grid() -> np.ndarray:
    grid = np.concatenate(([_PHI_MIN], np.radians(np.arange(_PHI_GRID_STEP_DEG, 90.0 + 1e-9, _PHI_GRID_STEP_DEG))))
    grid[-1] = 0.5 * math.pi
    return grid


def _bracket_and_refine(st: _Stations, idx: np.ndarray, grid: np.ndarray
                        ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Root of the residual per station on the first sign change along ``grid``.

    Returns ``(phi, converged, bracketed, residual on the grid)``.
    """
    n = idx.size
    G = np.broadcast_to(grid, (n, grid.size))
    Rg = st.evaluate(G, idx)["resid"]
    s = np.sign(Rg)
    change = (s[:, :-1] * s[:, 1:] <= 0) & np.isfinite(Rg[:, :-1]) & np.isfinite(Rg[:, 1:])
    has = change.any(axis=1)
    j = np.argmax(change, axis=1)
    rows = np.arange(n)
    a = np.where(has, grid[j], grid[0])
    b = np.where(has, grid[j + 1], grid[0])
    fa = np.where(has, Rg[rows, j], 1.0)
    fb = np.where(has, Rg[rows, j + 1], 1.0)

    # vectorised Illinois iteration; (a, fa) and (b, fb) always bracket the root
    done = ~has | (fa == 0) | (fb == 0)
    b = np.where(has & (fa == 0), a, b)
    for _ in range(_MAX_ITER):
        if np.all(done):
            break
        with np.errstate(divide="ignore", invalid="ignore"):
            c = b - fb * (b - a) / (fb - fa)
        bad = ~np.isfinite(c) | (c <= np.minimum(a, b)) | (c >= np.maximum(a, b))
        c = np.where(bad, 0.5 * (a + b), c)
        c = np.where(done, b, c)
        fc = np.where(done, fb, st.evaluate(c, idx)["resid"])
        flip = fc * fb < 0
        a = np.where(done, a, np.where(flip, b, a))
        fa = np.where(done, fa, np.where(flip, fb, 0.5 * fa))
        b, fb = c, fc
        done = done | (fc == 0) | (np.abs(b - a) < _XTOL)
    return b, has & done, has, Rg


def _solve_phi(st: _Stations, idx: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Inflow angle [rad] per station in ``idx`` and a per-station converged flag."""
    grid = _phi_grid()
    phi, converged, has, Rg = _bracket_and_refine(st, idx, grid)
    phi = phi.copy()
    if st.V == 0.0 and np.any(~has):
        # static thrust reversal (blade lift negative at the geometric angle): the
        # flow goes backwards through the disk; search phi in [-pi/2, 0)
        sub = np.flatnonzero(~has)
        phi_r, conv_r, has_r, _ = _bracket_and_refine(st, idx[sub], -grid[::-1])
        phi[sub] = phi_r
        converged[sub] = conv_r
        has[sub] = has_r
    if np.any(~has):
        # no sign change anywhere: take the grid point with the smallest |residual|
        best = grid[np.argmin(np.where(np.isfinite(Rg), np.abs(Rg), np.inf), axis=1)]
        phi = np.where(has, phi, best)
    return phi, converged


def bem_point(
    blade: Blade,
    *,
    V_ms: float,
    rpm: float,
    rho: float = 1.225,
    speed_of_sound: float = 340.3,
    kinematic_viscosity: float = 1.46e-5,
    tip_loss: bool = True,
    hub_loss: bool = True,
    compressibility: bool = False,
) -> BEMPoint:
    """Thrust, power and per-station state of ``blade`` at flight speed ``V_ms`` [m/s] and ``rpm``.

    ``rho`` [kg/m^3], ``speed_of_sound`` [m/s] and ``kinematic_viscosity``
    [m^2/s] set the air; see the module docstring for the solver.
    """
    problems: list[Problem] = []
    for name, val, low in (("V_ms", V_ms, 0.0), ("rpm", rpm, None), ("rho", rho, None),
                           ("speed_of_sound", speed_of_sound, None), ("kinematic_viscosity", kinematic_viscosity, None)):
        v = float(val)
        if not math.isfinite(v) or (v < 0 if low is not None else v <= 0):
            problems.append(Problem(name, f"must be {'>= 0' if low is not None else '> 0'}, got {val!r}"))
    raise_if(problems, "bem_point")

    n = rpm / 60.0                    # [rev/s]
    omega = 2.0 * math.pi * n         # [rad/s]
    D = blade.diameter_m
    st = _Stations(blade, float(V_ms), omega, speed_of_sound, kinematic_viscosity,
                   tip_loss, hub_loss, compressibility)
    ns = st.r.size
    live = np.flatnonzero(~st.dead)

    phi = np.arctan2(V_ms, st.omega_r)           # no-induction value for dead stations
    converged_st = np.ones(ns, dtype=bool)
    F = np.zeros(ns)
    a = np.zeros(ns)
    ap = np.zeros(ns)
    dT = np.zeros(ns)
    dQ = np.zeros(ns)
    reynolds = st.W0 * st.c / kinematic_viscosity
    if live.size:
        phi_l, conv_l = _solve_phi(st, live)
        ev = st.evaluate(phi_l, live)
        phi[live] = phi_l
        converged_st[live] = conv_l
        F[live] = ev["F"]
        reynolds[live] = ev["reynolds"]
        inv1pa, kp = ev["inv1pa"], ev["kp"]
        sphi, cphi = np.sin(phi_l), np.cos(phi_l)
        with np.errstate(divide="ignore", invalid="ignore"):
            ap[live] = kp / (1.0 + kp)
            a[live] = (1.0 / inv1pa - 1.0) if V_ms > 0 else np.nan
            W_tan = st.omega_r[live] / ((1.0 + kp) * cphi)
            W_ax = V_ms / (inv1pa * sphi)
        use_ax = (V_ms > 0) & (sphi > cphi)
        W = np.where(use_ax, W_ax, W_tan)
        q = 0.5 * rho * W**2 * st.c[live] * st.B
        dT[live] = q * ev["cn"]
        dQ[live] = q * ev["ct"] * st.r[live]
    alpha = np.degrees(st.beta - phi)

    T = _trapz(dT, st.r)
    Q = _trapz(dQ, st.r)
    P = Q * omega
    CT = T / (rho * n**2 * D**4)
    CQ = Q / (rho * n**2 * D**5)
    CP = P / (rho * n**3 * D**5)
    J = V_ms / (n * D)
    eff = T * V_ms / P if P > 0 else float("nan")
    ok = bool(np.all(converged_st)) and all(math.isfinite(v) for v in (T, Q))
    return BEMPoint(
        J=float(J), CT=float(CT), CP=float(CP), CQ=float(CQ), efficiency=float(eff),
        thrust_N=float(T), power_W=float(P), converged=ok, torque_Nm=float(Q),
        r_over_R=_frozen_array(blade.r_over_R), phi_deg=_frozen_array(np.degrees(phi)),
        alpha_deg=_frozen_array(alpha), a=_frozen_array(a), a_prime=_frozen_array(ap),
        F=_frozen_array(F), reynolds=_frozen_array(reynolds),
        dT_dr=_frozen_array(dT), dQ_dr=_frozen_array(dQ),
    )


# --------------------------------------------------------------------------- tables


@dataclass(frozen=True, eq=False)
class PropellerTables:
    """JSBSim propeller tables (fixed pitch: 1-D in J; constant speed: 2-D in J and blade angle)."""

    J: np.ndarray                      # [-] advance-ratio breakpoints, increasing
    beta75_deg: np.ndarray | None      # [deg] blade-angle breakpoints (None = fixed pitch)
    CT: np.ndarray                     # [-] shape (nJ,) fixed pitch or (nJ, nbeta)
    CP: np.ndarray                     # [-] same shape as CT
    provenance: dict[str, str] = field(default_factory=dict)

    def __post_init__(self) -> None:
        problems: list[Problem] = []
        J = np.asarray(self.J, dtype=float)
        if J.ndim != 1 or J.size < 2 or np.any(np.diff(J) <= 0) or not np.all(np.isfinite(J)):
            problems.append(Problem("J", "must be a finite, strictly increasing 1-D array of >= 2 values"))
        shape: tuple[int, ...] = (J.size,)
        if self.beta75_deg is not None:
            b = np.asarray(self.beta75_deg, dtype=float)
            if b.ndim != 1 or b.size < 1 or np.any(np.diff(b) <= 0):
                problems.append(Problem("beta75_deg", "must be a strictly increasing 1-D array"))
            shape = (J.size, b.size)
        for name in ("CT", "CP"):
            if np.shape(getattr(self, name)) != shape:
                problems.append(Problem(name, f"must have shape {shape}, got {np.shape(getattr(self, name))}"))
        raise_if(problems, "PropellerTables")
        object.__setattr__(self, "J", _frozen_array(self.J))
        if self.beta75_deg is not None:
            object.__setattr__(self, "beta75_deg", _frozen_array(self.beta75_deg))
        object.__setattr__(self, "CT", _frozen_array(self.CT))
        object.__setattr__(self, "CP", _frozen_array(self.CP))
        object.__setattr__(self, "provenance", {str(k): str(v) for k, v in dict(self.provenance).items()})

    @property
    def constant_speed(self) -> bool:
        return self.beta75_deg is not None


def propeller_tables(
    blade: Blade,
    J: Sequence[float] | np.ndarray,
    *,
    rpm: float,
    beta75_deg: Sequence[float] | np.ndarray | None = None,
    rho: float = 1.225,
    speed_of_sound: float = 340.3,
    kinematic_viscosity: float = 1.46e-5,
    tip_loss: bool = True,
    hub_loss: bool = True,
    compressibility: bool = False,
) -> PropellerTables:
    """BEM tables at ``V = J n D`` for every ``J`` (and every blade angle for a constant-speed prop).

    ``J`` should run from 0 to past the zero-thrust advance ratio (e.g. 0..1.4
    for the C172 propeller); ``beta75_deg`` (e.g. 10..40 deg) makes 2-D
    constant-speed tables, ``None`` evaluates the blade as given (fixed pitch).
    The tables are for the given ``rpm`` (Reynolds and, if enabled, Mach
    number depend on it).
    """
    Jarr = np.asarray(J, dtype=float)
    problems: list[Problem] = []
    if Jarr.ndim != 1 or Jarr.size < 2:
        problems.append(Problem("J", "must be a 1-D array of at least 2 advance ratios"))
    elif not np.all(np.isfinite(Jarr)) or np.any(np.diff(Jarr) <= 0) or Jarr[0] < 0:
        problems.append(Problem("J", "must be finite, >= 0 and strictly increasing"))
    if not (math.isfinite(rpm) and rpm > 0):
        problems.append(Problem("rpm", f"must be > 0, got {rpm!r}"))
    betas = None
    if beta75_deg is not None:
        betas = np.asarray(beta75_deg, dtype=float)
        if betas.ndim != 1 or betas.size < 1 or not np.all(np.isfinite(betas)) or np.any(np.diff(betas) <= 0):
            problems.append(Problem("beta75_deg", "must be a finite, strictly increasing 1-D array"))
    raise_if(problems, "propeller_tables")

    n = rpm / 60.0
    blades = [blade] if betas is None else [blade.with_beta75(b) for b in betas]
    CT = np.empty((Jarr.size, len(blades)))
    CP = np.empty_like(CT)
    bad: list[str] = []
    for jb, bl in enumerate(blades):
        for i, Ji in enumerate(Jarr):
            p = bem_point(bl, V_ms=float(Ji * n * bl.diameter_m), rpm=rpm, rho=rho,
                          speed_of_sound=speed_of_sound, kinematic_viscosity=kinematic_viscosity,
                          tip_loss=tip_loss, hub_loss=hub_loss, compressibility=compressibility)
            CT[i, jb], CP[i, jb] = p.CT, p.CP
            if not p.converged:
                bad.append(f"J={Ji:.4g}" + ("" if betas is None else f"/beta75={betas[jb]:.4g}"))
    if betas is None:
        CT, CP = CT[:, 0], CP[:, 0]
    prov = {
        "method": "BEM (Ning 2014 residual, propeller sign), Prandtl tip/hub loss, Buhl high-induction correction",
        "module": __name__,
        "diameter_m": repr(float(blade.diameter_m)),
        "n_blades": str(int(blade.n_blades)),
        "hub_radius_m": repr(float(blade.hub_radius_m)),
        "n_stations": str(blade.r_over_R.size),
        "beta75_deg_reference": repr(blade.beta75_deg),
        "activity_factor": f"{blade.activity_factor:.1f}",
        "section": type(blade.section).__name__,
        "rpm": repr(float(rpm)),
        "rho_kg_m3": repr(float(rho)),
        "speed_of_sound_m_s": repr(float(speed_of_sound)),
        "kinematic_viscosity_m2_s": repr(float(kinematic_viscosity)),
        "tip_loss": str(bool(tip_loss)),
        "hub_loss": str(bool(hub_loss)),
        "compressibility": "Prandtl-Glauert on cl, Mach capped at %g" % MACH_CAP if compressibility else "none",
        "unconverged_points": ", ".join(bad) if bad else "none",
    }
    return PropellerTables(J=Jarr, beta75_deg=betas, CT=CT, CP=CP, provenance=prov)


# --------------------------------------------------------------------------- calibration factors
# the factors the tables take, by name (the factor registry's baked factors,
# jsbsim_calib.factors.PROPELLER_FACTORS; this module does not read the registry)
TABLE_FACTORS = ("J_anchor", "K_CT_shift", "K_CT_scale", "K_CT_tilt", "K_CT_quad",
                 "K_CQ_shift", "K_CQ_scale", "K_CQ_tilt", "K_CQ_quad")


def _interp_extrap(x: np.ndarray, xp: np.ndarray, fp: np.ndarray) -> np.ndarray:
    """Cubic-spline interpolation in ``(xp, fp)`` (smooth in the calibration shifts: linear
    interpolation would make the baked curve kink as a shift crosses a breakpoint),
    linear extrapolation by the end slopes."""
    y = CubicSpline(xp, fp)(np.clip(x, xp[0], xp[-1]))
    lo = x < xp[0]
    hi = x > xp[-1]
    if np.any(lo):
        s = (fp[1] - fp[0]) / (xp[1] - xp[0])
        y = np.where(lo, fp[0] + s * (x - xp[0]), y)
    if np.any(hi):
        s = (fp[-1] - fp[-2]) / (xp[-1] - xp[-2])
        y = np.where(hi, fp[-1] + s * (x - xp[-1]), y)
    return y


def _apply_curve(J_base: np.ndarray, C: np.ndarray, J_out: np.ndarray, same_J: bool,
                 shift: float, scale: float, tilt: float, quad: float, J_anchor: float) -> np.ndarray:
    Jp = J_out + shift
    cols = C[:, None] if C.ndim == 1 else C
    if shift == 0.0 and same_J:
        base = cols.copy()
    else:
        base = np.column_stack([_interp_extrap(Jp, J_base, cols[:, m]) for m in range(cols.shape[1])])
    if not (scale == 1.0 and tilt == 0.0 and quad == 0.0):
        d = Jp - J_anchor
        base = scale * base * (1.0 + tilt * d + quad * d**2)[:, None]
    return base[:, 0] if C.ndim == 1 else base


def apply_factors(base: PropellerTables, factors: Mapping[str, float],
                  J_out: Sequence[float] | np.ndarray | None = None) -> PropellerTables:
    """Calibrated tables from the BEM ``base`` tables and the propeller factors: a value for
    every name of :data:`TABLE_FACTORS` (:func:`jsbsim_calib.factors.propeller_factor_values`
    gives them, neutral where a calibration gives none); each is recorded in the provenance.

    Thrust: ``J' = J + K_CT_shift``,
    ``CT'(J) = K_CT_scale * CT(J') * (1 + K_CT_tilt (J' - J_anchor) + K_CT_quad (J' - J_anchor)^2)``
    with ``CT(J')`` interpolated by a cubic spline in ``base`` (extrapolated by the end
    slopes outside it).  Torque: the same with the ``K_CQ_*`` factors applied
    to ``CP`` (``CP = 2 pi CQ``, so scaling ``CQ`` and ``CP`` is the same).
    Constant-speed tables are treated column by column (per blade angle).
    ``J_out`` gives the output breakpoints (default: those of ``base``).
    Neutral factors on the base breakpoints return the base values bitwise.
    """
    missing = [n for n in TABLE_FACTORS if n not in factors]
    if missing:
        raise ValueError(f"apply_factors: no value for {', '.join(missing)}")
    f = factors
    same_J = J_out is None
    Jo = base.J if J_out is None else np.asarray(J_out, dtype=float)
    if not same_J and Jo.shape == base.J.shape and np.array_equal(Jo, base.J):
        same_J = True
    CT = _apply_curve(base.J, base.CT, Jo, same_J, f["K_CT_shift"], f["K_CT_scale"], f["K_CT_tilt"], f["K_CT_quad"],
                      f["J_anchor"])
    CP = _apply_curve(base.J, base.CP, Jo, same_J, f["K_CQ_shift"], f["K_CQ_scale"], f["K_CQ_tilt"], f["K_CQ_quad"],
                      f["J_anchor"])
    prov = dict(base.provenance)
    for name, value in f.items():
        prov[f"factor.{name}"] = repr(value)
    return PropellerTables(J=Jo, beta75_deg=base.beta75_deg, CT=CT, CP=CP, provenance=prov)


def blade_angle_absorbing(tables: PropellerTables, power_w: float, rpm: float, speed_ms: float, rho: float,
                          diameter_m: float, pitch_range_deg: tuple[float, float]) -> float:
    """Blade angle at 0.75 R [deg] at which a constant-speed propeller with ``tables`` absorbs
    ``power_w`` at ``rpm``, ``speed_ms`` and air density ``rho``, within ``pitch_range_deg``
    (the fine stop where the power coefficient does not rise with the blade angle)."""
    n = rpm / 60.0
    J = speed_ms / (n * diameter_m)
    cp_needed = power_w / (rho * n**3 * diameter_m**5)
    cp = np.array([np.interp(J, tables.J, tables.CP[:, k]) for k in range(len(tables.beta75_deg))])
    lo, hi = pitch_range_deg
    beta = float(np.interp(cp_needed, cp, tables.beta75_deg)) if np.all(np.diff(cp) > 0) else lo
    return min(max(beta, lo), hi)
