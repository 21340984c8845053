"""Strip theory: section polars on lifting-line strips, any flight state, any deflection.

For a flight state (angle of attack, sideslip, body rates, control deflections) the
circulation of every strip satisfies the nonlinear lifting-line condition

    Gamma_i = 1/2 |U_i| c_i cl_i(alpha_geo_i - alpha_ind_i(Gamma))

with ``cl`` from the stored airfoil polar (plus control increments). It is solved by
Newton's method. Strip forces then follow from the section cl, cd, cm at the effective
angle, applied at the local dynamic pressure in the local flow direction; summing them
gives forces and moments about the aerodynamic reference point. Damping and sideslip
derivatives are differences of these sums (strip integration of body rates).

All quantities are dimensionless by construction: the free-stream speed is 1 and the
density 1, so a force divided by (0.5 * S_ref) is a coefficient.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..geometry import AircraftGeometry, LiftingSurface
from .lifting_line import LiftingLine, Strips, combine, freestream_dir, onset_velocity, surface_strips
from .sections import Deflection, deflection, section_coefficients, section_lift

# Sign of each control's deflection on the strips it covers (positive = more strip lift),
# per side (+1 right half, -1 left half, 0 vertical). JSBSim conventions for the inputs:
# flap and elevator positive trailing edge down; aileron positive = roll right (right
# trailing edge up, left down); rudder positive = trailing edge left (nose-left yaw).
CONTROL_SIGN = {
    "flap": {1: 1.0, -1: 1.0},
    "elevator": {1: 1.0, -1: 1.0},
    "aileron": {1: -1.0, -1: 1.0},
    "rudder": {0: -1.0},
}


_STEP = 0.25                                    # [deg] resolution of the tabulated strip polars
_GRID = np.arange(-180.0, 180.0 + _STEP / 2, _STEP)


@dataclass
class StripSolution:
    alpha: float
    beta: float
    gamma: np.ndarray
    onset: np.ndarray          # (N,3) onset velocity incl. body-rate terms
    alpha_geo: np.ndarray      # [rad]
    alpha_ind: np.ndarray      # [rad]
    cl: np.ndarray
    cd: np.ndarray
    cm: np.ndarray
    converged: bool
    residual: float = 0.0      # max |lifting-line residual| of the circulation [m^2/s per unit speed]

    @property
    def alpha_eff(self) -> np.ndarray:
        return self.alpha_geo - self.alpha_ind


class StripModel:
    """Strips of some lifting surfaces with their sections, ready to be solved."""

    def __init__(self, geom: AircraftGeometry, airfoils: dict, surfaces: tuple[LiftingSurface, ...],
                 ref_m: np.ndarray, n_half: int = 24, core_m: float | None = None,
                 dynamic_pressure_ratio: dict[str, float] | None = None):
        self.geom = geom
        self.ref_m = ref_m
        parts = [surface_strips(s, ref_m, n_half if not s.vertical else max(8, n_half // 2)) for s in surfaces]
        self.strips: Strips = combine(*parts)
        st = self.strips
        self.surfaces = {s.name: s for s in surfaces}
        self.airfoil = {s.name: airfoils[s.airfoil] for s in surfaces}
        self.core_m = core_m if core_m is not None else 1e-4 * geom.reference.span_m
        n = st.n
        self.E = np.zeros(n)
        self.kind = np.full(n, "plain", dtype=object)
        self.ctrl = np.full(n, "", dtype=object)
        for s in surfaces:
            m = st.mask(s.name)
            for c in s.controls:
                on = m & (st.eta >= c.y_start_m - 1e-9) & (st.eta <= c.y_end_m + 1e-9)
                self.E[on] = c.chord_fraction
                self.kind[on] = c.kind
                self.ctrl[on] = c.name
        self.kind = self.kind.astype(str)
        self.ctrl = self.ctrl.astype(str)
        self.reynolds = np.full(n, np.nan)
        # every airfoil's stored polars tabulated on the common grid, stacked: (3, all Reynolds
        # rows, n_alpha); per airfoil the log of its Reynolds numbers and its first row
        tables, self._airfoil_rows, first = [], {}, 0
        for name, af in self.airfoil.items():
            res = np.asarray(af.reynolds, float)
            t = np.empty((3, len(res), len(_GRID)))
            for k, r in enumerate(res):
                t[0, k], t[1, k], t[2, k] = af.polar(float(r)).coefficients(_GRID)
            tables.append(t)
            self._airfoil_rows[name] = (np.log(res), first)
            first += len(res)
        self._stack = np.concatenate(tables, axis=1)
        self._re_at: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None    # rows either side, weight
        # dynamic-pressure ratio per strip (tail surfaces in the wing/fuselage wake)
        self.q_ratio = np.ones(n)
        for name, r in (dynamic_pressure_ratio or {}).items():
            self.q_ratio[st.surface == name] = r
        # the fuselage is a reflection plane for a fin standing on it
        self.image_mask = np.zeros(n, bool)
        self.image_z = 0.0
        for s in surfaces:
            if s.vertical:
                self.image_mask |= st.mask(s.name)
                self.image_z = -(s.z_m[0] - ref_m[2])
        self._lines: dict[float, LiftingLine] = {}

    # ------------------------------------------------------------------ helpers
    def set_reynolds(self, speed_ms: float, rho: float, mu: float) -> None:
        """Reynolds number of every strip for a speed: each strip's polar becomes its airfoil's
        stored polars interpolated linearly in log(Re), clamped at the ends (as Airfoil.polar),
        evaluated where the solution asks (:meth:`_clean`)."""
        re = rho * speed_ms * self.strips.chord / mu
        if self._re_at is not None and np.allclose(re, self.reynolds, rtol=1e-9):
            return
        self.reynolds = re
        n = self.strips.n
        lo, hi, w = np.zeros(n, int), np.zeros(n, int), np.zeros(n)
        for name, (log_re, first) in self._airfoil_rows.items():
            idx = np.flatnonzero(self.strips.surface == name)
            if len(log_re) == 1:
                lo[idx] = hi[idx] = first
                continue
            x = np.clip(np.log(re[idx]), log_re[0], log_re[-1])
            j = np.clip(np.searchsorted(log_re, x) - 1, 0, len(log_re) - 2)
            lo[idx], hi[idx] = first + j, first + j + 1
            w[idx] = (x - log_re[j]) / (log_re[j + 1] - log_re[j])
        self._re_at = (lo, hi, w)
        a, b = np.searchsorted(_GRID, -2.0), np.searchsorted(_GRID, 4.0)
        all_rows = np.arange(n)
        self._slope = ((self._clean(0, all_rows, np.full(n, b)) - self._clean(0, all_rows, np.full(n, a)))
                       / math.radians(_GRID[b] - _GRID[a]))

    def _clean(self, k: int, rows: np.ndarray, col: np.ndarray) -> np.ndarray:
        """Coefficient ``k`` (cl, cd, cm) of the strips ``rows`` at grid columns ``col``, at
        their Reynolds numbers (a strip of a single-polar airfoil: that polar, exactly)."""
        lo, hi, w = self._re_at
        t, wr = self._stack[k], w[rows]
        return t[lo[rows], col] * (1.0 - wr) + t[hi[rows], col] * wr

    def _at(self, alpha_deg, rows):
        """The table columns either side of alpha [deg], the weight of the upper one, the rows."""
        a = (np.asarray(alpha_deg, float) + 180.0) % 360.0
        pos = a / _STEP
        i = np.minimum(pos.astype(int), len(_GRID) - 2)
        return i, pos - i, (np.arange(self.strips.n) if rows is None else rows)

    def _coefficient(self, k: int, i: np.ndarray, w: np.ndarray, r: np.ndarray) -> np.ndarray:
        """Coefficient ``k`` of the strips ``r`` between grid columns ``i`` and ``i + 1`` (weight ``w``)."""
        return self._clean(k, r, i) * (1.0 - w) + self._clean(k, r, i + 1) * w

    def polar(self, alpha_deg: np.ndarray, rows: np.ndarray | None = None):
        """Clean-section cl, cd, cm of the strips (all, or ``rows``) at alpha [deg]."""
        at = self._at(alpha_deg, rows)
        return tuple(self._coefficient(k, *at) for k in range(3))

    def polar_cl(self, alpha_deg: np.ndarray) -> np.ndarray:
        """Clean-section cl of every strip at alpha [deg] (:meth:`polar`'s cl, alone)."""
        return self._coefficient(0, *self._at(alpha_deg, None))

    def line(self, alpha: float, beta: float = 0.0) -> LiftingLine:
        """Lifting line with the wake along the free stream in the plane of symmetry.

        Sideslip does not yaw the wake: with the control points on the bound vortex, a
        yawed wake gives a spurious destabilizing rolling moment proportional to lift (the
        opposite effect of the leading half-wing's upwash needs chordwise resolution, which
        a lifting line does not have), so the wake stays unyawed.
        """
        key = round(alpha, 9)
        if key not in self._lines:
            if len(self._lines) > 64:
                self._lines.clear()
            self._lines[key] = LiftingLine(self.strips, freestream_dir(alpha, 0.0), self.core_m,
                                           self.image_mask, self.image_z)
        return self._lines[key]

    def deltas(self, controls: dict[str, float] | None) -> np.ndarray:
        """Per-strip deflection [rad] (positive = more lift) from control inputs [rad]."""
        d = np.zeros(self.strips.n)
        for name, value in (controls or {}).items():
            if value == 0.0:
                continue
            on = self.ctrl == name
            for side, sign in CONTROL_SIGN[name].items():
                d[on & (self.strips.side == side)] = sign * value
        return d

    def sections(self, alpha_eff: np.ndarray, delta: np.ndarray):
        """cl, cd, cm of all strips at effective angles [rad] with deflections [rad]."""
        return section_coefficients(self.polar, alpha_eff, delta, self.E, self.kind, self._slope)

    def lift(self, alpha_eff: np.ndarray, d: Deflection) -> np.ndarray:
        """cl of all strips at effective angles [rad] with the increments ``d`` of
        :meth:`deflection` (:meth:`sections`' cl, alone)."""
        return section_lift(self.polar_cl, alpha_eff, d)

    def deflection(self, delta: np.ndarray) -> Deflection:
        """The control-surface increments of the strips at deflections [rad]."""
        return deflection(delta, self.E, self.kind, self._slope)

    @property
    def lift_slope(self) -> np.ndarray:
        """Linear lift slope of each strip's section [1/rad] (-2..4 deg)."""
        return self._slope

    # ------------------------------------------------------------------ solve
    def solve(self, alpha: float, beta: float = 0.0, omega=(0.0, 0.0, 0.0), controls: dict | None = None,
              gamma0: np.ndarray | None = None, max_iter: int = 60) -> StripSolution:
        """Nonlinear lifting-line solution for a state. Angles [rad], rates nondimensional
        by V = 1 (i.e. omega in rad per unit length travelled)."""
        st = self.strips
        ll = self.line(alpha, beta)
        U = onset_velocity(st.point, alpha, beta, omega, V=1.0)
        Umag = np.linalg.norm(U, axis=1)
        alpha_geo = np.arctan2(np.sum(U * st.e_normal, 1), np.sum(U * st.e_chord, 1))
        delta = self.deltas(controls)
        d = self.deflection(delta)
        Vn = np.einsum("ijk,ik->ij", ll.V, st.e_normal)
        half_c = 0.5 * st.chord

        def residual(g):
            a_ind = -(Vn @ g) / Umag
            cl = self.lift(alpha_geo - a_ind, d)
            return g - half_c * Umag * cl, a_ind

        if gamma0 is None:
            # linear start: slope and zero-lift angle from the polar
            a0 = self.lift_slope
            cl0 = self.lift(np.zeros(st.n), d)
            alpha0 = -cl0 / a0
            gamma = ll.solve(U, a0, alpha0)
        else:
            gamma = gamma0.copy()
        r, a_ind = residual(gamma)
        norm = np.linalg.norm(r)
        converged = norm < 1e-10
        h = 1e-4
        it = 0
        while not converged and it < max_iter:
            it += 1
            cl_p = self.lift(alpha_geo - a_ind + h, d)
            cl_m = self.lift(alpha_geo - a_ind - h, d)
            slope = (cl_p - cl_m) / (2 * h)
            J = np.eye(st.n) - (half_c * slope)[:, None] * Vn
            try:
                step = np.linalg.solve(J, -r)
            except np.linalg.LinAlgError:
                break
            lam = 1.0
            for _ in range(12):
                g_new = gamma + lam * step
                r_new, a_new = residual(g_new)
                if np.linalg.norm(r_new) < (1 - 1e-4 * lam) * norm:
                    break
                lam *= 0.5
            else:
                break
            gamma, r, a_ind, norm = g_new, r_new, a_new, np.linalg.norm(r_new)
            converged = norm < 1e-10 * max(1.0, np.abs(gamma).max())
        cl, cd, cm = self.sections(alpha_geo - a_ind, delta)
        return StripSolution(alpha, beta, gamma, U, alpha_geo, a_ind, cl, cd, cm, bool(converged),
                             float(np.max(np.abs(r))))

    # ------------------------------------------------------------------ loads
    def strip_forces(self, sol: StripSolution, mask: np.ndarray | None = None) -> np.ndarray:
        """Force on each strip (N,3), body axes, for V = 1 and rho = 1 (q = 0.5 |U|^2)."""
        st = self.strips
        U = sol.onset
        w = self.line(sol.alpha, sol.beta).induced_velocity(sol.gamma)
        Ul = U + w
        e_d = Ul / np.linalg.norm(Ul, axis=1)[:, None]
        e_l = np.cross(Ul, st.e_span)
        e_l /= np.linalg.norm(e_l, axis=1)[:, None]
        q = 0.5 * np.sum(U * U, axis=1) * self.q_ratio
        cd = np.where(st.profile, sol.cd, 0.0)
        f = (q * st.area)[:, None] * (sol.cl[:, None] * e_l + cd[:, None] * e_d)
        if mask is not None:
            f = f * mask[:, None]
        return f

    def loads(self, sol: StripSolution, mask: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Total force and moment (about the reference point) [body axes], V = rho = 1.

        The moment includes the section quarter-chord moments (about the span axis).
        """
        st = self.strips
        f = self.strip_forces(sol, mask)
        q = 0.5 * np.sum(sol.onset * sol.onset, axis=1) * self.q_ratio
        m_sec = (q * st.area * st.chord * sol.cm)[:, None] * st.e_span
        if mask is not None:
            m_sec = m_sec * mask[:, None]
        M = np.sum(np.cross(st.point, f), axis=0) + np.sum(m_sec, axis=0)
        return f.sum(axis=0), M


def wind_to_coeffs(F: np.ndarray, M: np.ndarray, alpha: float, beta: float, S: float, b: float, c: float) -> dict:
    """Body-axis force/moment (V = rho = 1) -> CL, CD, CY (wind axes) and Cl, Cm, Cn (body)."""
    qS = 0.5 * S
    ca, sa, cb, sb = math.cos(alpha), math.sin(alpha), math.cos(beta), math.sin(beta)
    # body -> wind rotation
    x_w = np.array([ca * cb, sb, sa * cb])
    y_w = np.array([-ca * sb, cb, -sa * sb])
    z_w = np.array([-sa, 0.0, ca])
    return {
        "CD": -F @ x_w / qS,
        "CY": F @ y_w / qS,
        "CL": -F @ z_w / qS,
        "Cl": M[0] / (qS * b),
        "Cm": M[1] / (qS * c),
        "Cn": M[2] / (qS * b),
    }
