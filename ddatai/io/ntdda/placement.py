"""What ntdda does with the blocks after cutting them (docs/ntdda.md §4): the block carrying a
point (`BlockLocator`, crr), blocks lying inside other blocks (dc16), block materials from
material lines (dc13), and fixed lines, both ntdda's points (dc10) and ddatai's rule (§4.8).
``ddatai.io.ntdda.case`` applies them in ntdda's order with its documented choices between
them. NumPy and shapely only.
"""

from __future__ import annotations

import numpy as np

from .segments import segment_intersection


class BlockLocator:
    """Finds the block carrying a point the way ntdda's crr does: the first block (in order)
    that has a vertex within 1e-5·w0 of the point, or contains it, or has it on an edge."""

    def __init__(self, polygons, w0: float):
        import shapely

        self.polygons = [np.asarray(p, dtype=float) for p in polygons]
        self.w0 = w0
        self._shapes = [shapely.Polygon(p) for p in self.polygons]
        self._tree = shapely.STRtree(self._shapes)

    def locate(self, xy) -> int:
        """Block index, or -1 if no block carries the point."""
        import shapely

        p = np.asarray(xy, dtype=float)
        probe = shapely.Point(float(p[0]), float(p[1]))
        near = 1e-5 * self.w0
        for b in sorted(self._tree.query(probe, predicate="dwithin", distance=near).tolist()):
            if np.min(np.hypot(*(self.polygons[b] - p).T)) < near or \
                    self._shapes[b].distance(probe) <= 1e-9 * self.w0:
                return b
        return -1


def block_containing(polygons, xy, w0: float) -> int:
    """First block (in order) carrying the point (see `BlockLocator`), or -1."""
    return BlockLocator(polygons, w0).locate(xy)


def blocks_inside_other_blocks(polygons) -> list[int]:
    """Blocks lying inside another block (ntdda dc16 deletes them).

    A set of joint loops not connected to the rest leaves the surrounding block without a hole
    (ntdda blocks have no holes), so the inner blocks overlap it.
    """
    import shapely

    polys = [shapely.Polygon(p) for p in polygons]
    tree = shapely.STRtree(polys)
    inside = []
    for b, poly in enumerate(polys):
        probe = _probe_inside_first_edge(np.asarray(polygons[b], dtype=float), poly)
        for other in tree.query(probe, predicate="within"):
            if other != b:
                inside.append(b)
                break
    return inside


def _probe_inside_first_edge(ring: np.ndarray, poly):
    """A point just inside the block next to the middle of its first edge (ntdda's dc16 probe:
    a block's centre may lie in a hole it does not have)."""
    import shapely

    edge = ring[1] - ring[0]
    length = float(np.hypot(*edge))
    inward = np.array([-edge[1], edge[0]]) / length
    mid = 0.5 * (ring[0] + ring[1])
    step = 1e-6 * length
    for _ in range(20):
        probe = shapely.Point(*(mid + step * inward))
        if poly.contains(probe):
            return probe
        step *= 0.5
    return poly.representative_point()


def block_materials(polygons, material_lines, w0: float) -> tuple[np.ndarray, list[int]]:
    """Material index of every block from material lines (dc13), default 1 (1-based).

    Every block having an edge that the material line meets (ntdda's lns test) gets the line's
    material; a line that meets no edge gives it to the block containing its first end point.
    Later lines win. Returns the per-block materials and the indices of material lines that
    reached no block.
    """
    mat = np.zeros(len(polygons), dtype=np.int64)
    unused = []
    for k, (x1, y1, x2, y2, m) in enumerate(np.asarray(material_lines, dtype=float).reshape(-1, 5)):
        touched = False
        for b, poly in enumerate(polygons):
            hit, _, _ = segment_intersection(w0, (x1, y1), (x2, y2), poly, np.roll(poly, -1, axis=0))
            if hit.any():
                mat[b] = int(m)
                touched = True
        if not touched:
            b = BlockLocator(polygons, w0).locate((x1, y1))
            if b >= 0:
                mat[b] = int(m)
            else:
                unused.append(k)
    mat[mat == 0] = 1
    return mat, unused


def clip_fixed_line(polygon: np.ndarray, line, tol: float) -> list[np.ndarray]:
    """End points of the pieces of a fixed line inside a block (ddatai's rule, docs/ntdda.md §4.8).

    Returns a list of (2,) points: both ends of every piece of positive length of the line
    within the closed polygon (a line end inside the block, or where the line crosses the
    block's outline), without duplicates closer than ``tol``.
    """
    import shapely

    piece = shapely.intersection(shapely.LineString([line[:2], line[2:]]), shapely.Polygon(polygon))
    points: list[np.ndarray] = []
    for part in shapely.get_parts(piece):
        if part.geom_type != "LineString" or part.length <= tol:
            continue
        xy = np.asarray(part.coords)
        for q in (xy[0], xy[-1]):
            if all(np.hypot(*(q - p)) > tol for p in points):
                points.append(q.copy())
    return points


def ntdda_fixed_points(polygons, line, w0: float) -> list[tuple[int, np.ndarray]]:
    """The fixed points ntdda (dc10) makes from one fixed line, as (block, point) pairs.

    A zero-length line is its point. Otherwise: one point per block edge the line crosses,
    inset 0.005·w0 into that block; if it crosses no edge, its first end point (block -1 here:
    ntdda locates it later). Used only to tell the user where ddatai's rule differs.
    """
    line = np.asarray(line, dtype=float)
    if abs(line[0] - line[2]) + abs(line[1] - line[3]) <= 1e-9 * w0:
        return [(-1, line[:2].copy())]
    out = []
    for b, poly in enumerate(polygons):
        nxt = np.roll(poly, -1, axis=0)
        hit, t1, _ = segment_intersection(w0, line[:2], line[2:], poly, nxt)
        for e in np.flatnonzero(hit):
            x0 = line[:2] + (line[2:] - line[:2]) * t1[e]
            edge = nxt[e] - poly[e]
            inward = np.array([-edge[1], edge[0]]) / np.hypot(*edge)
            out.append((b, x0 + 0.005 * w0 * inward))
    if not out:
        out.append((-1, line[:2].copy()))
    return out
