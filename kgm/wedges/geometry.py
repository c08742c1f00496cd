"""Planes, half-spaces and the convex block they cut out (docs/kgm/wedge.md §2).

Axes: x east, y north, z up [m]. A plane is given by its dip ψ and dip direction α [degrees];
its upward unit normal is (sin ψ sin α, sin ψ cos α, cos ψ) (Hoek & Bray's eq. for the normals
of planes 1–5). A direction is given by its trend and plunge [degrees], plunge positive
downwards.

A block is the intersection of half-spaces a·x ≤ b. `polyhedron` checks that they enclose a
bounded region (its recession cone {d: a·d ≤ 0} is the origin only), finds a strictly interior
point as the centre of the largest inscribed ball (the Chebyshev centre, a linear program), and
lets SciPy's ``HalfspaceIntersection`` (Qhull) find the vertices; faces, areas, the volume and
the centroid follow from them. This is the reference path; `kgm.wedges.batched` computes the same
quantities for many blocks at once from closed-form vertex enumeration.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Optional, Sequence

import numpy as np

#: relative tolerance of the geometric tests (a fraction of the block's size)
GEOMETRY_TOLERANCE = 1e-9


def _finite(v) -> bool:
    return isinstance(v, (int, float, np.floating, np.integer)) and not isinstance(v, bool) and math.isfinite(v)


@dataclass(frozen=True)
class Plane:
    """A plane by its dip and dip direction, with the strength of the joint it is (if any).

    ``Plane(dip, dip_direction, joint=None)``: ``dip`` ψ in [0, 90] and ``dip_direction`` α
    (azimuth of the dip, clockwise from north) in degrees; ``joint`` a `ddatai.Joint` (or
    `ddatai.BartonBandis`) for a plane the block can slide on, None for a free face.
    """

    dip: float
    """Dip ψ [degrees], in [0, 90]."""
    dip_direction: float
    """Dip direction α [degrees], clockwise from north; stored modulo 360."""
    joint: Optional[object] = None
    """Strength of the plane as a joint: a `ddatai.Joint` (Mohr–Coulomb) or `ddatai.BartonBandis`;
    None for a free face (slope face, upper face) or a plane without strength."""

    def __post_init__(self) -> None:
        if not (_finite(self.dip) and 0.0 <= self.dip <= 90.0):
            raise ValueError(f"Plane.dip must be an angle in [0, 90] degrees, got {self.dip!r}")
        if not _finite(self.dip_direction):
            raise ValueError(f"Plane.dip_direction must be a finite angle in degrees, got {self.dip_direction!r}")
        object.__setattr__(self, "dip", float(self.dip))
        object.__setattr__(self, "dip_direction", float(self.dip_direction) % 360.0)
        if self.joint is not None:
            from ddatai.params import Joint

            if not isinstance(self.joint, Joint):
                raise ValueError(f"Plane.joint must be a ddatai.Joint (or BartonBandis) or None, "
                                 f"got {type(self.joint).__name__}")

    @property
    def normal(self) -> np.ndarray:
        """Upward unit normal (x east, y north, z up) [-]; horizontal, towards the dip
        direction, for a vertical plane."""
        return plane_normal(self.dip, self.dip_direction)

    @property
    def dip_vector(self) -> np.ndarray:
        """Unit vector down the line of steepest dip [-]."""
        return direction_vector(self.dip_direction, self.dip)

    @property
    def strike(self) -> float:
        """Strike (right-hand rule: dip direction − 90°) [degrees]."""
        return (self.dip_direction - 90.0) % 360.0

    def with_orientation(self, dip: float, dip_direction: float) -> "Plane":
        return Plane(dip, dip_direction, self.joint)


def plane_normal(dip, dip_direction) -> np.ndarray:
    """Upward unit normal of planes (arrays broadcast; last axis x, y, z) [-]."""
    d, a = np.radians(dip), np.radians(dip_direction)
    return np.stack([np.sin(d) * np.sin(a), np.sin(d) * np.cos(a), np.cos(d)], axis=-1)


def direction_vector(trend, plunge) -> np.ndarray:
    """Unit vector of a direction given by trend and plunge (plunge > 0 downwards) [-]."""
    t, p = np.radians(trend), np.radians(plunge)
    return np.stack([np.cos(p) * np.sin(t), np.cos(p) * np.cos(t), -np.sin(p)], axis=-1)


def trend_plunge(v) -> tuple:
    """(trend, plunge) [degrees] of vectors (…, 3); plunge > 0 downwards, trend in [0, 360)."""
    v = np.asarray(v, dtype=float)
    n = np.linalg.norm(v, axis=-1)
    with np.errstate(invalid="ignore", divide="ignore"):
        plunge = np.degrees(np.arcsin(np.clip(-v[..., 2] / n, -1.0, 1.0)))
    trend = np.degrees(np.arctan2(v[..., 0], v[..., 1])) % 360.0
    if np.ndim(plunge) == 0:
        return float(trend), float(plunge)
    return trend, plunge


def dip_and_direction(normal) -> tuple:
    """(dip, dip direction) [degrees] of the plane with this normal (either sense)."""
    n = np.asarray(normal, dtype=float)
    n = n / np.linalg.norm(n)
    if n[2] < 0:
        n = -n
    dip = math.degrees(math.acos(min(1.0, max(-1.0, n[2]))))
    return dip, math.degrees(math.atan2(n[0], n[1])) % 360.0


@dataclass(frozen=True)
class Halfspace:
    """The points x with ``normal``·x ≤ ``offset``: one side of a bounding plane of a block.

    ``normal`` is the plane's unit normal pointing OUT of the block; ``label`` names the plane
    ("joint 1", "slope face", …) in faces, errors and pictures.
    """

    normal: np.ndarray
    offset: float
    label: str
    kind: str = "joint"
    """'joint' (a discontinuity the block rests on or is cut by: its JP constrains motion),
    'crack' (a tension crack: a joint without strength) or 'free' (slope face, upper face)."""

    @staticmethod
    def through(point, outward_normal, label: str, kind: str = "joint") -> "Halfspace":
        n = np.asarray(outward_normal, dtype=float)
        n = n / np.linalg.norm(n)
        return Halfspace(n, float(n @ np.asarray(point, dtype=float)), label, kind)


@dataclass(frozen=True)
class Face:
    """One face of a polyhedron."""

    label: str
    kind: str
    normal: np.ndarray
    """Unit normal pointing out of the block [-]."""
    vertices: np.ndarray
    """Corners (k, 3), counter-clockwise seen from outside [m]."""
    area: float
    """[m²]."""
    centroid: np.ndarray
    """Area centroid [m]."""


@dataclass(frozen=True)
class Polyhedron:
    """A bounded convex block: its vertices, faces, volume and centroid."""

    vertices: np.ndarray
    """(k, 3) [m]."""
    faces: tuple
    """`Face` of every bounding half-space with a non-zero area (others are left out)."""
    volume: float
    """[m³]."""
    centroid: np.ndarray
    """Volume centroid [m]."""
    interior: np.ndarray = field(repr=False, default=None)
    """The Chebyshev centre used as Qhull's interior point [m]."""
    inradius: float = 0.0
    """Radius of the largest ball inside the block [m]."""

    def face(self, label: str) -> Optional[Face]:
        for f in self.faces:
            if f.label == label:
                return f
        return None

    def area(self, label: str) -> float:
        f = self.face(label)
        return 0.0 if f is None else f.area


class NoBlock(ValueError):
    """The half-spaces do not cut out a block; ``reason`` says why ('unbounded', 'empty')."""

    def __init__(self, reason: str, message: str):
        super().__init__(message)
        self.reason = reason


def recession_directions(normals: np.ndarray, tol: float = 1e-10) -> Optional[np.ndarray]:
    """A non-zero direction d with normals·d ≤ 0 for every row (the region is unbounded along
    it), or None when the cone {d: A d ≤ 0} is the origin alone.

    Exact in 3D: a polyhedral cone other than {0} either contains a line (A has rank < 3: its
    null space) or has an extreme ray on the intersection of two of its planes (±aᵢ × aⱼ).
    """
    a = np.asarray(normals, dtype=float)
    if np.linalg.matrix_rank(a, tol=1e-9) < 3:
        _, _, vt = np.linalg.svd(a)
        return vt[-1]
    m = len(a)
    for i in range(m):
        for j in range(i + 1, m):
            d = np.cross(a[i], a[j])
            nd = np.linalg.norm(d)
            if nd < 1e-12:
                continue
            d = d / nd
            for s in (d, -d):
                if np.all(a @ s <= tol):
                    return s
    return None


def chebyshev_centre(normals: np.ndarray, offsets: np.ndarray, bound: float) -> tuple[np.ndarray, float]:
    """Centre and radius of the largest ball inside {x: A x ≤ b} (‖x‖∞ ≤ ``bound``), by
    `scipy.optimize.linprog`: maximise r subject to aᵢ·x + r‖aᵢ‖ ≤ bᵢ."""
    from scipy.optimize import linprog

    a = np.asarray(normals, dtype=float)
    norms = np.linalg.norm(a, axis=1)
    a_ub = np.hstack([a, norms[:, None]])
    res = linprog(c=[0, 0, 0, -1.0], A_ub=a_ub, b_ub=np.asarray(offsets, dtype=float),
                  bounds=[(-bound, bound)] * 3 + [(0, None)], method="highs")
    if res.status != 0:
        return np.zeros(3), 0.0
    return res.x[:3], float(res.x[3])


def polyhedron(halfspaces: Sequence[Halfspace], *, scale: Optional[float] = None) -> Polyhedron:
    """The bounded convex block cut out by ``halfspaces`` (reference path: LP + Qhull).

    Raises `NoBlock` with ``reason`` 'unbounded' (its recession cone is not the origin: a
    direction along which the region goes on for ever) or 'empty' (no interior: the largest
    inscribed ball has a radius below ``GEOMETRY_TOLERANCE`` × ``scale``). ``scale`` is a
    length of the model [m] (default: the largest plane offset, at least 1).
    """
    from scipy.spatial import HalfspaceIntersection

    a = np.array([h.normal for h in halfspaces], dtype=float)
    b = np.array([h.offset for h in halfspaces], dtype=float)
    scale = float(scale) if scale else max(1.0, float(np.max(np.abs(b))))
    ray = recession_directions(a)
    if ray is not None:
        t, p = trend_plunge(ray)
        raise NoBlock("unbounded", f"the planes do not enclose a finite block: it goes on for ever along "
                                   f"trend {t:.1f}°, plunge {p:.1f}°")
    centre, radius = chebyshev_centre(a, b, bound=1e3 * scale)
    tol = GEOMETRY_TOLERANCE * scale
    if radius <= tol:
        raise NoBlock("empty", "the planes do not enclose a volume (the block is empty or flat)")
    hs = HalfspaceIntersection(np.hstack([a, -b[:, None]]), centre)
    pts = _unique_points(hs.intersections, 1e-9 * scale)
    faces = []
    for h, an, bn in zip(halfspaces, a, b):
        on = np.abs(pts @ an - bn) <= 1e-7 * scale
        if on.sum() < 3:
            continue
        poly = _ordered(pts[on], an)
        area, c = _polygon_area_centroid(poly, an)
        if area <= (1e-9 * scale) ** 2 * 1e3:
            continue
        faces.append(Face(h.label, h.kind, an.copy(), poly, area, c))
    volume, centroid = _volume_centroid(faces)
    return Polyhedron(pts, tuple(faces), volume, centroid, centre, radius)


def _unique_points(p: np.ndarray, tol: float) -> np.ndarray:
    out: list = []
    for q in p:
        if not any(np.linalg.norm(q - r) <= tol for r in out):
            out.append(q)
    return np.array(out)


def _ordered(points: np.ndarray, normal: np.ndarray) -> np.ndarray:
    """Points of a convex face, counter-clockwise seen from the side ``normal`` points to."""
    c = points.mean(axis=0)
    u = points[0] - c
    if np.linalg.norm(u) < 1e-300:
        u = points[1] - c
    u = u / np.linalg.norm(u)
    v = np.cross(normal, u)
    ang = np.arctan2((points - c) @ v, (points - c) @ u)
    return points[np.argsort(ang)]


def _polygon_area_centroid(poly: np.ndarray, normal: np.ndarray) -> tuple[float, np.ndarray]:
    c0 = poly.mean(axis=0)
    area, acc = 0.0, np.zeros(3)
    for k in range(len(poly)):
        p, q = poly[k], poly[(k + 1) % len(poly)]
        t = 0.5 * float(np.cross(p - c0, q - c0) @ normal)
        area += t
        acc += t * (c0 + p + q) / 3.0
    return area, (acc / area if area > 0 else c0)


def _volume_centroid(faces) -> tuple[float, np.ndarray]:
    """Volume and centroid of a closed polyhedron from its faces (divergence theorem: the sum
    of the tetrahedra from the origin to each face triangle)."""
    vol, acc = 0.0, np.zeros(3)
    for f in faces:
        p0 = f.vertices[0]
        for k in range(1, len(f.vertices) - 1):
            p, q = f.vertices[k], f.vertices[k + 1]
            v = float(np.dot(p0, np.cross(p, q))) / 6.0
            vol += v
            acc += v * (p0 + p + q) / 4.0
    return vol, (acc / vol if vol > 0 else np.zeros(3))
