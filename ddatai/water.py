"""Water and rock bolts as data: the water table, the bolt table, and the exact integration of
hydrostatic pressure over block edges (docs/method/water_bolts.md). NumPy and shapely only.

Water is **uncoupled**: the water table is given, the water does not flow, and the pressure at
a point is hydrostatic below it,

    p(x, y) = ρw · g · (h(x) − y)   where y < h(x), else 0                       (W1)

with h(x) the water table (a polyline, linear between its points and held level beyond its
ends). The pressure acts on every block edge below the table, along the edge's inward normal:
on free faces and on both blocks of a joint alike, so a joint's contact springs carry the
effective normal force N' = N − U and friction is effective-stress.

Along an edge, h(x(s)) is linear between the abscissas of the table's points, and p is linear
between those and the points where the edge crosses the table; `edge_pressure_points` splits
each edge there and returns two Gauss points per piece. With DDA's first-order displacement
field T(x, y) linear too, the integrand Tᵀ·p·n is quadratic on every piece, so the two-point
rule integrates the load vector F = ∫ Tᵀ p n ds exactly (W2).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Optional

import numpy as np

#: Gauss–Legendre abscissas on [0, 1] of the two-point rule (weights ½ each).
_GAUSS = np.array([0.5 - 0.5 / np.sqrt(3.0), 0.5 + 0.5 / np.sqrt(3.0)])


@dataclass(frozen=True, kw_only=True, eq=False)
class WaterTable:
    """A water table (phreatic surface) over the scene (`Scene.set_water_table`)."""

    xy: Optional[np.ndarray]
    """(k, 2) points of the table h(x) [m], x strictly increasing; held level beyond the ends.
    None: no table (water only in the joints given ``heads``)."""
    density: float = 1000.0
    """Water density ρw [kg/m³]; the pressure is ρw·g·(h − y) [Pa] with the scene's gravity g."""
    heads: tuple = ()
    """((joint, head), ...): joint-table index and its own hydraulic head [m] (a level table
    that replaces h(x) on the edges of that joint line only, both blocks' faces)."""


@dataclass(frozen=True, kw_only=True, eq=False)
class BoltSpec:
    """A rock bolt as the user gave it (`Scene.add_bolt`): an axial spring between a material
    point of one block and a material point of another (Shi's bolt element). Forces are per
    metre of thickness: a row of bolts at spacing S, each of force T, is a bolt of T/S."""

    block1: int
    """Block holding the first end."""
    block2: int
    """Block holding the second end."""
    xy1: tuple[float, float]
    """First end, initial position [m]."""
    xy2: tuple[float, float]
    """Second end, initial position [m]."""
    stiffness: float
    """Axial stiffness k: force per unit extension [N/m per m thickness = Pa]."""
    pretension: float
    """Tension at the initial length [N/m], >= 0; the active force of limit equilibrium."""
    capacity: float
    """Tensile capacity [N/m] (inf: unbreakable); the bolt breaks for good when its tension
    exceeds it, and limit equilibrium mobilises it as the passive force."""


def check_water_table(polyline, density: float, heads: tuple = ()) -> WaterTable:
    """Validate a water table (``polyline`` may be None when ``heads``, already resolved to
    (joint index, head) pairs, are given); raise ValueError naming the offending item."""
    if not (isinstance(density, (int, float)) and np.isfinite(density) and density > 0):
        raise ValueError(f"water table: density must be a finite number > 0 kg/m³, got {density!r}")
    if polyline is None:
        return WaterTable(xy=None, density=float(density), heads=tuple(heads))
    xy = np.asarray(polyline, dtype=float)
    if xy.ndim != 2 or xy.shape[1] != 2 or len(xy) < 2:
        raise ValueError(f"water table: expected a polyline of at least two (x, y) points, got shape {xy.shape}")
    bad = np.flatnonzero(~np.all(np.isfinite(xy), axis=1))
    if len(bad):
        raise ValueError(f"water table: point {int(bad[0])} is not finite: {tuple(xy[bad[0]])!r}")
    import shapely

    crossing = None if shapely.LineString(xy).is_simple and _no_fold(xy) else _self_crossing(xy)
    if crossing is not None:
        i, j = crossing
        raise ValueError(f"water table crosses itself: segment {i} ({_pt(xy[i])} → {_pt(xy[i + 1])}) and "
                         f"segment {j} ({_pt(xy[j])} → {_pt(xy[j + 1])})")
    back = np.flatnonzero(np.diff(xy[:, 0]) <= 0)
    if len(back):
        k = int(back[0]) + 1
        raise ValueError(f"water table: point {k} {_pt(xy[k])} does not lie to the right of point {k - 1} "
                         f"{_pt(xy[k - 1])}; a water table is a height h(x), its x must increase strictly")
    return WaterTable(xy=xy.copy(), density=float(density), heads=tuple(heads))


def _pt(p) -> str:
    return f"({p[0]:g}, {p[1]:g})"


def _no_fold(xy: np.ndarray) -> bool:
    """No two consecutive segments turn back along one line (a fold shapely calls simple)."""
    d = np.diff(xy, axis=0)
    cross = d[:-1, 0] * d[1:, 1] - d[:-1, 1] * d[1:, 0]
    dot = (d[:-1] * d[1:]).sum(axis=1)
    size = np.hypot(d[:-1, 0], d[:-1, 1]) * np.hypot(d[1:, 0], d[1:, 1])
    return not np.any((np.abs(cross) <= 1e-12 * size) & (dot < 0))


def _self_crossing(xy: np.ndarray):
    """First pair (i, j) of non-adjacent segments of the polyline that touch, or of adjacent
    segments that overlap (turn back on each other), else None."""
    n = len(xy) - 1
    for i in range(n):
        for j in range(i + 1, n):
            p, r = xy[i], xy[i + 1] - xy[i]
            q, s = xy[j], xy[j + 1] - xy[j]
            rxs = r[0] * s[1] - r[1] * s[0]
            qp = q - p
            if j == i + 1:
                # adjacent: they share xy[i+1]; they cross only by folding back along a line
                if abs(rxs) <= 1e-12 * np.hypot(*r) * np.hypot(*s) and r @ s < 0:
                    return i, j
                continue
            if abs(rxs) > 1e-15:
                t = (qp[0] * s[1] - qp[1] * s[0]) / rxs
                u = (qp[0] * r[1] - qp[1] * r[0]) / rxs
                if -1e-12 <= t <= 1 + 1e-12 and -1e-12 <= u <= 1 + 1e-12:
                    return i, j
            elif abs(qp[0] * r[1] - qp[1] * r[0]) <= 1e-12 * max(np.hypot(*r), 1e-300) * max(np.hypot(*qp), 1.0):
                # collinear: overlap of the parameter ranges
                rr = float(r @ r)
                t0, t1 = sorted(((q - p) @ r / rr, (xy[j + 1] - p) @ r / rr))
                if t1 >= 0 and t0 <= 1:
                    return i, j
    return None


def edge_pressure_points(start: np.ndarray, end: np.ndarray, table: np.ndarray, gamma: float
                         ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Quadrature points of the water pressure (W1) on edges start → end (E, 2) [m] below the
    table ``table`` (k, 2) of unit weight ``gamma`` = ρw·g [N/m³].

    Returns (edge, point, weight): for each Gauss point with pressure, its edge index, position
    [m] and weight p·ds [N/m]; the edge's water force is Σ weight · n_in (its inward normal),
    and F = Σ Tᵀ(point)·weight·n_in is the exact load vector (W2).
    """
    start = np.asarray(start, float).reshape(-1, 2)
    end = np.asarray(end, float).reshape(-1, 2)
    e = len(start)
    if e == 0:
        return np.zeros(0, np.int64), np.zeros((0, 2)), np.zeros(0)
    d = end - start
    tx, ty = table[:, 0], table[:, 1]
    # breakpoints 1: the edge passes the abscissa of a table point (h has a kink there)
    with np.errstate(divide="ignore", invalid="ignore"):
        s_kink = (tx[None, :] - start[:, :1]) / d[:, :1]
    s_kink = np.where(np.isfinite(s_kink) & (s_kink > 0) & (s_kink < 1), s_kink, 0.0)
    s = np.sort(np.concatenate([np.zeros((e, 1)), s_kink, np.ones((e, 1))], axis=1), axis=1)

    def head(sv):  # h(x(s)) − y(s): pressure head along each edge [m]
        x = start[:, :1] + sv * d[:, :1]
        y = start[:, 1:] + sv * d[:, 1:]
        return np.interp(x, tx, ty) - y

    # breakpoints 2: the edge crosses the table (head changes sign inside a linear piece)
    g = head(s)
    g0, g1 = g[:, :-1], g[:, 1:]
    with np.errstate(divide="ignore", invalid="ignore"):
        cross = s[:, :-1] + (s[:, 1:] - s[:, :-1]) * g0 / (g0 - g1)
    cross = np.where((g0 * g1 < 0) & np.isfinite(cross), cross, 0.0)
    s = np.sort(np.concatenate([s, cross], axis=1), axis=1)
    lo, hi = s[:, :-1], s[:, 1:]
    length = np.hypot(d[:, 0], d[:, 1])
    edge_idx, pts, wts = [], [], []
    for gq in _GAUSS:
        sg = lo + gq * (hi - lo)
        hg = np.maximum(head(sg), 0.0)
        w = gamma * hg * 0.5 * (hi - lo) * length[:, None]
        keep = w > 0
        rows, cols = np.nonzero(keep)
        edge_idx.append(rows)
        pts.append(start[rows] + sg[rows, cols][:, None] * d[rows])
        wts.append(w[rows, cols])
    return np.concatenate(edge_idx), np.concatenate(pts), np.concatenate(wts)


def water_points(start: np.ndarray, end: np.ndarray, edge_joint: np.ndarray, table: Optional[np.ndarray],
                 heads: np.ndarray, gamma: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """`edge_pressure_points` of edges each on a joint (``edge_joint``, joint-table indices):
    those of a joint with its own head (``heads``: (n, 2) rows joint, head [m]) under that
    level, the others under the table (none where ``table`` is None)."""
    out = []
    own = np.zeros(len(start), bool)
    for j, h in np.asarray(heads, float).reshape(-1, 2):
        sel = np.flatnonzero(edge_joint == int(j))
        own[sel] = True
        e, p, w = edge_pressure_points(start[sel], end[sel], np.array([[0.0, h], [1.0, h]]), gamma)
        out.append((sel[e], p, w))
    if table is not None:
        # edges wholly above the table's highest point carry no pressure: skip them
        sel = np.flatnonzero(~own & (np.minimum(start[:, 1], end[:, 1]) < table[:, 1].max()))
        e, p, w = edge_pressure_points(start[sel], end[sel], table, gamma)
        out.append((sel[e], p, w))
    if not out:
        return np.zeros(0, np.int64), np.zeros((0, 2)), np.zeros(0)
    return (np.concatenate([o[0] for o in out]), np.concatenate([o[1] for o in out]),
            np.concatenate([o[2] for o in out]))


def polygon_water_force(xy: np.ndarray, offset: np.ndarray, table: WaterTable, gravity: float,
                        edge_joint: Optional[np.ndarray] = None) -> tuple[np.ndarray, np.ndarray]:
    """Water force (B, 2) [N/m] and its moment about the origin (B,) [N·m/m] on every block's
    boundary (CCW polygons ``xy`` with ``offset``; ``edge_joint`` the joint of each edge, for
    joints with their own head), by (W1)–(W2)."""
    nb = len(offset) - 1
    nxt = np.arange(len(xy)) + 1
    nxt[np.asarray(offset[1:]) - 1] = offset[:-1]
    block = np.repeat(np.arange(nb), np.diff(offset))
    joint = np.full(len(xy), -1) if edge_joint is None else np.asarray(edge_joint)
    edge, pts, w = water_points(xy, xy[nxt], joint, table.xy, np.array(table.heads, float).reshape(-1, 2),
                                table.density * gravity)
    t = xy[nxt] - xy
    n_in = np.stack([-t[:, 1], t[:, 0]], axis=1) / np.hypot(t[:, 0], t[:, 1])[:, None]  # left of a CCW edge
    f = w[:, None] * n_in[edge]
    force = np.zeros((nb, 2))
    np.add.at(force, block[edge], f)
    moment = np.zeros(nb)
    np.add.at(moment, block[edge], pts[:, 0] * f[:, 1] - pts[:, 1] * f[:, 0])
    return force, moment
