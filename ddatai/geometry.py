"""Block polygons: validation, polygon integrals, the displacement matrix T, overlap checks
(cutting a domain by joint lines is `ddatai.cutting`).

NumPy and shapely only (never Taichi). Blocks are simple polygons stored counter-clockwise
(CCW) without a repeated closing vertex. Many blocks are stored as one flat vertex array plus
offsets (``xy[offset[b]:offset[b+1]]`` is block b), the layout the rest of the code uses.
"""

from __future__ import annotations

from typing import Optional

import numpy as np

from .memo import GeometryMemo, key

#: Relative tolerance below which a vertex is treated as lying on the line of its neighbours
#: (abs(sin) of the turning angle). Shapely's noding leaves such vertices at T-junctions; they are
#: removed because a flat vertex duplicates the edge contacts around it.
COLLINEAR_TOL = 1e-10
#: polygons of at most this many vertices keep their validated form (``ddatai.memo``)
MEMO_VERTICES = 256
#: scenes of at most this many vertices keep their overlap check and kgm's edge contacts
MEMO_SCENE_VERTICES = 20_000
_POLYGONS = GeometryMemo(4096)
_OVERLAP_FREE = GeometryMemo(16)


def validate_polygon(vertices, *, name: str = "block") -> np.ndarray:
    """Return the polygon as a (n, 2) float64 CCW array, or raise ``ValueError`` naming ``name``.

    Checks: finite coordinates, at least 3 distinct non-collinear vertices, a simple ring (no
    self-intersection) and positive area. A repeated closing vertex, repeated consecutive
    vertices and vertices lying on the line of their neighbours are removed; clockwise input
    is reversed.
    """
    try:
        xy = np.asarray(vertices, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name}: vertices must be a sequence of (x, y) pairs ({exc})") from None
    if xy.ndim == 2 and len(xy) <= MEMO_VERTICES:
        # a polygon met before (a study's scene built again): its result (`ddatai.memo`)
        return _POLYGONS.get(key(xy), lambda: _validated(xy, name))
    return _validated(xy, name)


def _validated(xy: np.ndarray, name: str) -> np.ndarray:
    """`validate_polygon` of the float64 array ``xy``."""
    if xy.ndim != 2 or xy.shape[1] != 2:
        raise ValueError(f"{name}: vertices must have shape (n, 2), got {xy.shape}")
    if not np.all(np.isfinite(xy)):
        raise ValueError(f"{name}: vertices contain NaN or infinite coordinates")
    scale = float(np.ptp(xy, axis=0).max()) if len(xy) else 0.0
    if scale <= 0:
        raise ValueError(f"{name}: degenerate polygon (all vertices coincide)")
    xy = _drop_repeated(xy, 1e-12 * scale)
    if len(xy) < 3:
        raise ValueError(f"{name}: a polygon needs at least 3 distinct vertices, got {len(xy)}")
    import shapely

    area = signed_area(xy)
    if abs(area) <= 1e-12 * scale * scale:
        raise ValueError(f"{name}: polygon has zero area")
    if not shapely.LinearRing(xy).is_simple:
        raise ValueError(f"{name}: polygon is self-intersecting (not a simple polygon)")
    if area < 0:
        xy = xy[::-1].copy()
    xy = _drop_collinear(xy)
    if len(xy) < 3:
        raise ValueError(f"{name}: polygon has zero area (all vertices collinear)")
    return np.ascontiguousarray(xy)


def _drop_repeated(xy: np.ndarray, tol: float) -> np.ndarray:
    keep = np.ones(len(xy), dtype=bool)
    d = np.linalg.norm(np.roll(xy, -1, axis=0) - xy, axis=1)
    keep[d <= tol] = False  # vertex equal to its successor (this also drops a closing repeat)
    if not keep.any():
        return xy[:1]
    return xy[keep]


def _drop_collinear(xy: np.ndarray) -> np.ndarray:
    """Remove vertices whose turning angle is zero within COLLINEAR_TOL (repeat until none)."""
    while len(xy) > 3:
        prev = np.roll(xy, 1, axis=0)
        nxt = np.roll(xy, -1, axis=0)
        a = xy - prev
        b = nxt - xy
        cross = a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]
        norm = np.linalg.norm(a, axis=1) * np.linalg.norm(b, axis=1)
        dot = (a * b).sum(axis=1)
        flat = (np.abs(cross) <= COLLINEAR_TOL * norm) & (dot > 0)
        if not flat.any():
            break
        xy = xy[~flat]
    return xy


def signed_area(xy: np.ndarray) -> float:
    """Signed area of one polygon (positive when CCW) [m²]."""
    x = xy[:, 0] - xy[0, 0]
    y = xy[:, 1] - xy[0, 1]
    return 0.5 * float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y))


def polygon_integrals(xy: np.ndarray, offset: np.ndarray, block: Optional[np.ndarray] = None,
                      nxt_idx: Optional[np.ndarray] = None) -> dict[str, np.ndarray]:
    """Area, centroid and central second moments of many CCW polygons (docs/method/dda.md §1.2).

    Parameters
    ----------
    xy : (V, 2) float64 vertices of all blocks, CCW per block.
    offset : (B+1,) int; block b owns ``xy[offset[b]:offset[b+1]]``.
    block, nxt_idx : (V,) int, optional; the block of each vertex and the next vertex of its
        block (a `Model`'s ``vertex_block`` and ``vertex_next``), derived from ``offset`` when
        not given.

    Returns
    -------
    dict with ``area`` (B,) [m²], ``centroid`` (B, 2) [m], and the central moments
    ``s1 = ∫X² dA``, ``s2 = ∫Y² dA``, ``s3 = ∫XY dA`` (B,) [m⁴], X, Y centroidal.

    The triangle-fan sums are evaluated relative to each block's first vertex, so a model far
    from the origin loses no precision (docs/method/dda.md §1.2, numerical tip).
    """
    offset = np.asarray(offset)
    if block is None:
        counts = np.diff(offset)
        block = np.repeat(np.arange(len(counts)), counts)
    if nxt_idx is None:
        nxt_idx = np.arange(len(xy)) + 1
        nxt_idx[offset[1:] - 1] = offset[:-1]
    origin = xy[offset[:-1]]
    local = xy - origin[block]
    x1, y1 = local[:, 0], local[:, 1]
    x2, y2 = local[nxt_idx, 0], local[nxt_idx, 1]
    f = x1 * y2 - x2 * y1
    starts = offset[:-1]

    def total(v: np.ndarray) -> np.ndarray:
        return np.add.reduceat(v, starts) if len(v) else np.zeros(0)

    s = total(f) / 2.0
    sx = total(f * (x1 + x2)) / 6.0
    sy = total(f * (y1 + y2)) / 6.0
    sxx = total(f * (x1 * x1 + x1 * x2 + x2 * x2)) / 12.0
    syy = total(f * (y1 * y1 + y1 * y2 + y2 * y2)) / 12.0
    sxy = total(f * (2 * x1 * y1 + x1 * y2 + x2 * y1 + 2 * x2 * y2)) / 24.0
    xc = sx / s
    yc = sy / s
    centroid = np.empty_like(origin)
    centroid[:, 0] = origin[:, 0] + xc
    centroid[:, 1] = origin[:, 1] + yc
    return {
        "area": s,
        "centroid": centroid,
        "s1": sxx - xc * sx,
        "s2": syy - yc * sy,
        "s3": sxy - xc * sy,
    }


def mass_matrix(area: np.ndarray, s1: np.ndarray, s2: np.ndarray, s3: np.ndarray) -> np.ndarray:
    """M = ∫ TᵀT dA for each block, (B, 6, 6) [m², m³, m⁴] (docs/method/dda.md §1.3; × ρ for mass)."""
    n = len(area)
    m = np.zeros((n, 6, 6))
    m[:, 0, 0] = area
    m[:, 1, 1] = area
    m[:, 2, 2] = s1 + s2
    m[:, 2, 3] = m[:, 3, 2] = -s3
    m[:, 2, 4] = m[:, 4, 2] = s3
    m[:, 2, 5] = m[:, 5, 2] = (s1 - s2) / 2
    m[:, 3, 3] = s1
    m[:, 3, 5] = m[:, 5, 3] = s3 / 2
    m[:, 4, 4] = s2
    m[:, 4, 5] = m[:, 5, 4] = s3 / 2
    m[:, 5, 5] = (s1 + s2) / 4
    return m


def displacement_matrix(point: np.ndarray, centroid: np.ndarray) -> np.ndarray:
    """T(x, y) of docs/method/dda.md §1.1 for many points, (n, 2, 6): u = T D."""
    X = point[..., 0] - centroid[..., 0]
    Y = point[..., 1] - centroid[..., 1]
    t = np.zeros(X.shape + (2, 6))
    t[..., 0, 0] = 1.0
    t[..., 0, 2] = -Y
    t[..., 0, 3] = X
    t[..., 0, 5] = Y / 2
    t[..., 1, 1] = 1.0
    t[..., 1, 2] = X
    t[..., 1, 4] = Y
    t[..., 1, 5] = X / 2
    return t


#: Two blocks overlap when their common area exceeds this fraction of the smaller one's [-]
#: (cut blocks share edges to round-off, ~1e-16 of their area).
OVERLAP_AREA = 1e-9


def check_overlaps(scene, *, what: str = "") -> None:
    """Raise ValueError naming the first pair of blocks whose interiors overlap (common area
    above `OVERLAP_AREA` of the smaller), with the overlap's area and its depth (area over
    half its perimeter: the thickness of a thin overlap) [m]; ``what`` is added to the
    message."""
    # the same polygons as a check that passed (a study's scene built again): passed (`ddatai.memo`)
    if len(scene.blocks) < 2:
        return
    xy = np.concatenate([s.vertices for s in scene.blocks])
    if len(xy) > MEMO_SCENE_VERTICES:  # a large scene: its key would cost memory, and it rarely repeats
        _check_overlaps(scene, what)
        return
    _OVERLAP_FREE.get(key(xy, np.array([len(s.vertices) for s in scene.blocks])), lambda: _check_overlaps(scene, what))


def _check_overlaps(scene, what: str) -> bool:
    """`check_overlaps`: True, or ValueError."""
    import shapely

    polys = np.array([shapely.Polygon(s.vertices) for s in scene.blocks], dtype=object)
    if len(polys) < 2:
        return True
    tree = shapely.STRtree(polys)
    a, b = tree.query(polys, predicate="intersects")
    keep = a < b
    a, b = a[keep], b[keep]
    if not len(a):
        return True
    common = shapely.intersection(polys[a], polys[b])
    inter = shapely.area(common)
    areas = shapely.area(polys)
    bad = inter > OVERLAP_AREA * np.minimum(areas[a], areas[b])
    if bad.any():
        k = int(np.flatnonzero(bad)[0])
        depth = 2.0 * inter[k] / max(float(shapely.length(common[k])), 1e-300)
        raise ValueError(f"blocks {a[k]} and {b[k]} overlap at the start (overlap area {inter[k]:.3g} m², "
                         f"about {depth:.3g} m deep)" + (f": {what}" if what else ""))
    return True
