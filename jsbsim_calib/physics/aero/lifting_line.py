"""Numerical lifting-line theory for several lifting surfaces at once.

Each lifting surface is cut into spanwise strips; each strip carries a horseshoe vortex
(bound segment on the quarter-chord line, trailing legs running downstream with the
free stream). The strip circulation follows the section lift curve at the local angle of
attack, the local angle including the velocity induced by every horseshoe (Prandtl's
lifting-line idea in the discrete form of Phillips & Snyder, J. Aircraft 37(4), 2000).

The system is linear in the circulation once a section lift slope ``a0`` and zero-lift
angle ``alpha0`` are given per strip; nonlinear section behaviour is added outside, by
evaluating the stored airfoil polars at the effective angle this module provides.

Axes: aircraft body axes (x forward, y right, z down), origin at the aerodynamic
reference point, SI units.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from ..geometry import LiftingSurface


@dataclass(frozen=True)
class Strips:
    """Arrays describing N spanwise strips (one horseshoe vortex each)."""

    surface: np.ndarray        # [-] surface name per strip
    side: np.ndarray           # [-] +1 right half, -1 left half, 0 vertical surface
    node_a: np.ndarray         # [m] (N,3) bound-vortex start
    node_b: np.ndarray         # [m] (N,3) bound-vortex end
    point: np.ndarray          # [m] (N,3) control point (bound-segment midpoint)
    chord: np.ndarray          # [m] (N,)
    width: np.ndarray          # [m] (N,) strip width normal to the body x axis
    e_chord: np.ndarray        # [-] (N,3) unit vector leading edge -> trailing edge
    e_normal: np.ndarray       # [-] (N,3) unit normal: flow through it gives positive lift
    e_span: np.ndarray         # [-] (N,3) unit vector along the bound vortex (node_a -> node_b)
    eta: np.ndarray            # [m] distance of the strip centre from the surface root along the span
    profile: np.ndarray        # [-] True where the strip has profile drag (outside the fuselage)

    @property
    def n(self) -> int:
        return len(self.chord)

    @property
    def area(self) -> np.ndarray:
        return self.chord * self.width

    def mask(self, surface: str) -> np.ndarray:
        return self.surface == surface

    def subset(self, mask: np.ndarray) -> "Strips":
        return Strips(**{k: getattr(self, k)[mask] for k in self.__dataclass_fields__})


def structural_to_body(xyz_m: np.ndarray, ref_m: np.ndarray) -> np.ndarray:
    """Structural frame (x aft, y right, z up) -> body axes (x fwd, y right, z down) about ref."""
    d = np.asarray(xyz_m, float) - ref_m
    return np.stack([-d[..., 0], d[..., 1], -d[..., 2]], axis=-1)


def cosine_spacing(n: int) -> np.ndarray:
    """n+1 nodes on [0, 1], clustered at both ends."""
    return 0.5 * (1.0 - np.cos(np.linspace(0.0, math.pi, n + 1)))


def surface_strips(surf: LiftingSurface, ref_m: np.ndarray, n_half: int) -> Strips:
    """Strips of one surface (both halves for a symmetric surface).

    ``n_half`` strips per half-span, cosine-clustered towards root and tip.
    """
    y0, y1 = surf.y_m[0], surf.y_m[-1]
    s = y0 + (y1 - y0) * cosine_spacing(n_half)
    # make sure the panel breaks and control-surface edges are nodes
    extra = [c for c in surf.y_m[1:-1]]
    for c in surf.controls:
        extra += [c.y_start_m, c.y_end_m]
    extra.append(surf.fuselage_half_width_m)
    for e in extra:
        if y0 < e < y1:
            k = int(np.argmin(np.abs(s - e)))
            if 0 < k < len(s) - 1:
                s[k] = e
    s = np.unique(s)
    chord = np.interp(s, surf.y_m, surf.chord_m)
    x_le = np.interp(s, surf.y_m, surf.x_le_m)
    z = np.interp(s, surf.y_m, surf.z_m)
    xq = x_le + 0.25 * chord
    if surf.vertical:
        nodes = np.stack([xq, np.zeros_like(s), z], axis=-1)            # structural
        halves = [(0, nodes)]
    else:
        zz = z + (s - y0) * math.tan(surf.dihedral_rad)
        right = np.stack([xq, s, zz], axis=-1)
        left = right[::-1] * np.array([1.0, -1.0, 1.0])
        halves = [(-1, left), (1, right)]
    cols: dict[str, list] = {k: [] for k in Strips.__dataclass_fields__}
    for side, nod in halves:
        nb = structural_to_body(nod, ref_m)
        a, b = nb[:-1], nb[1:]
        mid = 0.5 * (a + b)
        span_vec = b - a
        e_span = span_vec / np.linalg.norm(span_vec, axis=1)[:, None]
        # strip width across the flow (the streamwise component of a swept segment carries no area)
        width = np.linalg.norm(span_vec[:, 1:], axis=1)
        # spanwise coordinate of the strip centres (from the surface root line)
        if surf.vertical:
            sc = 0.5 * (s[:-1] + s[1:])
        else:
            sc = 0.5 * (np.abs(nod[:-1, 1]) + np.abs(nod[1:, 1]))
        c_mid = np.interp(sc, surf.y_m, surf.chord_m)
        inc_mid = np.interp(sc, surf.y_m, surf.incidence_rad)
        # streamwise chord (Phillips & Snyder): 'aft' lies in the surface plane; the section
        # incidence rotates it nose-up about the in-plane axis normal to the chord
        aft = np.array([-1.0, 0.0, 0.0])
        e_chord = []
        e_norm = []
        for k in range(len(c_mid)):
            es = e_span[k]
            n0 = np.cross(aft, es)
            n0 /= np.linalg.norm(n0)
            axis = np.cross(n0, aft)
            axis /= np.linalg.norm(axis)
            ca = _rotate(aft, axis, inc_mid[k])
            nrm = np.cross(ca, es)
            e_chord.append(ca)
            e_norm.append(nrm / np.linalg.norm(nrm))
        cols["surface"].append(np.full(len(c_mid), surf.name, dtype=object))
        cols["side"].append(np.full(len(c_mid), side))
        cols["node_a"].append(a)
        cols["node_b"].append(b)
        cols["point"].append(mid)
        cols["chord"].append(c_mid)
        cols["width"].append(width)
        cols["e_chord"].append(np.array(e_chord))
        cols["e_normal"].append(np.array(e_norm))
        cols["e_span"].append(e_span)
        cols["eta"].append(sc - y0)
        cols["profile"].append(sc >= surf.fuselage_half_width_m)
    return Strips(**{k: np.concatenate(v) for k, v in cols.items()})


def _rotate(v: np.ndarray, axis: np.ndarray, angle: float) -> np.ndarray:
    """Rodrigues rotation of v about the unit axis by angle (right hand)."""
    c, s = math.cos(angle), math.sin(angle)
    return v * c + np.cross(axis, v) * s + axis * np.dot(axis, v) * (1 - c)


def combine(*strips: Strips) -> Strips:
    return Strips(**{k: np.concatenate([getattr(s, k) for s in strips]) for k in Strips.__dataclass_fields__})


def influence(src: Strips, points: np.ndarray, wake_dir: np.ndarray, core_m: float) -> np.ndarray:
    """Velocity at ``points`` (M,3) induced by each unit-strength horseshoe of ``src``: (M, N, 3).

    Trailing legs leave the bound-vortex ends along the unit vector ``wake_dir``. A
    smoothing core of radius ``core_m`` removes the singularity near vortex lines.
    The bound segment does not act on a point lying on its own line.
    """
    u = wake_dir / np.linalg.norm(wake_dir)
    r1 = points[:, None, :] - src.node_a[None, :, :]
    r2 = points[:, None, :] - src.node_b[None, :, :]
    n1 = np.linalg.norm(r1, axis=-1)
    n2 = np.linalg.norm(r2, axis=-1)
    d2 = core_m**2

    def leg(r, nr):
        cr = np.cross(u, r)
        dist2 = np.sum(cr * cr, axis=-1)
        den = nr * (nr - np.sum(u * r, axis=-1))
        with np.errstate(divide="ignore", invalid="ignore"):
            f = np.where(den > 1e-12, 1.0 / den, 0.0) * dist2 / (dist2 + d2)
        return cr * f[..., None]

    cx = np.cross(r1, r2)
    cx2 = np.sum(cx * cx, axis=-1)
    seg = src.node_b - src.node_a
    seg2 = np.sum(seg * seg, axis=-1)[None, :]
    dist2 = cx2 / seg2
    den = n1 * n2 * (n1 * n2 + np.sum(r1 * r2, axis=-1))
    with np.errstate(divide="ignore", invalid="ignore"):
        fb = np.where((den > 1e-12) & (cx2 > 1e-14 * seg2 * seg2), (n1 + n2) / den, 0.0) * dist2 / (dist2 + d2)
    bound = cx * fb[..., None]
    return (leg(r2, n2) - leg(r1, n1) + bound) / (4.0 * math.pi)


def mirrored_image(strips: Strips, mask: np.ndarray, z_plane_body: float) -> Strips:
    """Image horseshoes of the masked strips in the plane z = z_plane (body axes).

    A fin standing on the fuselage acts as if it continued into its mirror image (the
    fuselage is a reflection plane): the image carries the same circulation with its bound
    segment running from the image tip to the root, so the root trailing vortex cancels.
    """
    sub = strips.subset(mask)

    def mirror(p):
        q = p.copy()
        q[:, 2] = 2.0 * z_plane_body - q[:, 2]
        return q

    return replace(sub, node_a=mirror(sub.node_b), node_b=mirror(sub.node_a), point=mirror(sub.point))


@dataclass
class LiftingLine:
    """Linear lifting-line system for fixed strips and wake direction.

    ``image_mask``/``image_plane_z`` add reflection-plane images for the masked strips
    (a fin on the fuselage).
    """

    strips: Strips
    wake_dir: np.ndarray
    core_m: float
    image_mask: np.ndarray | None = None
    image_plane_z: float = 0.0
    V: np.ndarray = field(init=False)   # (N,N,3) influence of unit circulation

    def __post_init__(self):
        self.V = influence(self.strips, self.strips.point, self.wake_dir, self.core_m)
        if self.image_mask is not None and np.any(self.image_mask):
            img = mirrored_image(self.strips, self.image_mask, self.image_plane_z)
            self.V[:, self.image_mask, :] += influence(img, self.strips.point, self.wake_dir, self.core_m)

    def induced_velocity(self, gamma: np.ndarray) -> np.ndarray:
        return np.einsum("ijk,j->ik", self.V, gamma)

    def solve(self, onset: np.ndarray, a0: np.ndarray, alpha0: np.ndarray) -> np.ndarray:
        """Circulation [m^2/s] for onset velocities (N,3) [m/s] (air velocity relative to the strip).

        Linear section law cl = a0 (alpha - alpha0) with alpha measured from the chord, flow
        from below positive; small-angle linearisation of the induced angle.
        """
        s = self.strips
        Umag = np.linalg.norm(onset, axis=1)
        alpha_geo = np.arctan2(np.sum(onset * s.e_normal, 1), np.sum(onset * s.e_chord, 1))
        k = 0.5 * s.chord * a0
        Vn = np.einsum("ijk,ik->ij", self.V, s.e_normal)          # normal induced velocity per unit gamma
        A = np.eye(s.n) - k[:, None] * Vn
        rhs = k * Umag * (alpha_geo - alpha0)
        return np.linalg.solve(A, rhs)

    def angles(self, onset: np.ndarray, gamma: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Geometric and induced angle of attack [rad] per strip (alpha_eff = geo - induced)."""
        s = self.strips
        Umag = np.linalg.norm(onset, axis=1)
        alpha_geo = np.arctan2(np.sum(onset * s.e_normal, 1), np.sum(onset * s.e_chord, 1))
        w = self.induced_velocity(gamma)
        alpha_ind = -np.sum(w * s.e_normal, 1) / Umag
        return alpha_geo, alpha_ind


def onset_velocity(points: np.ndarray, alpha: float, beta: float, omega=(0.0, 0.0, 0.0), V: float = 1.0) -> np.ndarray:
    """Air velocity relative to points of the aircraft, body axes [m/s].

    Aircraft velocity (u, v, w) = V (cos a cos b, sin b, sin a cos b); body rates
    omega = (p, q, r) [rad/s]. The air moves relative to the aircraft at -(v_cg + omega x r).
    """
    vb = V * np.array([math.cos(alpha) * math.cos(beta), math.sin(beta), math.sin(alpha) * math.cos(beta)])
    return -(vb[None, :] + np.cross(np.asarray(omega, float)[None, :], points))


def freestream_dir(alpha: float, beta: float) -> np.ndarray:
    """Unit vector pointing downstream (direction the air moves relative to the aircraft)."""
    return -np.array([math.cos(alpha) * math.cos(beta), math.sin(beta), math.sin(alpha) * math.cos(beta)])


def kutta_joukowski(strips: Strips, gamma: np.ndarray, local_velocity: np.ndarray, rho: float = 1.0) -> np.ndarray:
    """Force on each bound segment (N,3) [N]: rho * Gamma * (V_local x dl)."""
    dl = strips.node_b - strips.node_a
    return rho * gamma[:, None] * np.cross(local_velocity, dl)
