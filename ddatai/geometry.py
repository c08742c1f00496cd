"""Block polygons: validation, polygon integrals and cutting a domain by joint lines.

NumPy and shapely only (never Taichi). Blocks are simple polygons stored counter-clockwise
(CCW) without a repeated closing vertex. Many blocks are stored as one flat vertex array plus
offsets (``xy[offset[b]:offset[b+1]]`` is block b), the layout the rest of the code uses.
"""

from __future__ import annotations

from typing import Sequence

import numpy as np

#: Relative tolerance below which a vertex is treated as lying on the line of its neighbours
#: (abs(sin) of the turning angle). Shapely's noding leaves such vertices at T-junctions; they are
#: removed because a flat vertex duplicates the edge contacts around it.
COLLINEAR_TOL = 1e-10


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


def polygon_integrals(xy: np.ndarray, offset: np.ndarray) -> dict[str, np.ndarray]:
    """Area, centroid and central second moments of many CCW polygons (docs/method/dda.md §1.2).

    Parameters
    ----------
    xy : (V, 2) float64 vertices of all blocks, CCW per block.
    offset : (B+1,) int; block b owns ``xy[offset[b]:offset[b+1]]``.

    Returns
    -------
    dict with ``area`` (B,) [m²], ``centroid`` (B, 2) [m], and the central moments
    ``s1 = ∫X² dA``, ``s2 = ∫Y² dA``, ``s3 = ∫XY dA`` (B,) [m⁴], X, Y centroidal.

    The triangle-fan sums are evaluated relative to each block's first vertex, so a model far
    from the origin loses no precision (docs/method/dda.md §1.2, numerical tip).
    """
    offset = np.asarray(offset)
    counts = np.diff(offset)
    block = np.repeat(np.arange(len(counts)), counts)
    origin = xy[offset[:-1]]
    local = xy - origin[block]
    nxt_idx = np.arange(len(xy)) + 1
    nxt_idx[offset[1:] - 1] = offset[:-1]
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
    return {
        "area": s,
        "centroid": origin + np.stack([xc, yc], axis=1),
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


#: peak memory of a simulation per block [bytes] (benchmarks/results/scaling.md: 4.8 GB for
#: 102,400 blocks with ~6 contacts each, ~47 kB a block over a ~170 MB base)
MEMORY_PER_BLOCK = 48e3
#: the base memory of a run (Python, NumPy, Taichi, SciPy) [bytes]
MEMORY_BASE = 200e6
#: environment variable that overrides the largest model `cut` builds (a number of blocks, or
#: "inf"); ``ddatai run --force`` sets it to "inf"
MAX_BLOCKS_ENV = "DDATAI_MAX_BLOCKS"


class ModelSizeError(ValueError):
    """A cut would make a model far larger than this machine can simulate (the message gives the
    estimate, the joints that make it and how to go on)."""


def available_memory() -> float:
    """Memory this machine can still give a process [bytes] (Linux MemAvailable; else the
    physical memory; inf where neither is known)."""
    try:
        with open("/proc/meminfo") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return float(line.split()[1]) * 1024.0
    except OSError:
        pass
    try:
        import os

        return float(os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES"))
    except (AttributeError, ValueError, OSError):
        return float("inf")


def max_blocks_here() -> float:
    """The largest model `cut` builds without being asked: what fits in 80 % of the available
    memory at `MEMORY_PER_BLOCK`, unless the `MAX_BLOCKS_ENV` variable says otherwise."""
    import os

    env = os.environ.get(MAX_BLOCKS_ENV)
    if env:
        try:
            return float(env)
        except ValueError:
            raise ValueError(f"{MAX_BLOCKS_ENV}={env!r} must be a number of blocks or 'inf'") from None
    return max(0.0, (0.8 * available_memory() - MEMORY_BASE) / MEMORY_PER_BLOCK)


def estimate_blocks(domain, lines) -> tuple[int, int, int]:
    """Upper bound on the blocks that cutting ``domain`` (a shapely Polygon) by ``lines``
    (shapely LineStrings) makes, without cutting: Euler's count for an arrangement of chords,
    1 + (trace pieces inside the domain) + (their crossings inside it) — exact for persistent
    joints, an upper bound for traces that end inside blocks. Returns (blocks, pieces,
    crossings)."""
    import shapely

    if not lines:
        return 1, 0, 0
    clipped = shapely.intersection(np.asarray(lines, dtype=object), domain)
    parts = shapely.get_parts(clipped)
    parts = parts[shapely.length(parts) > 0] if len(parts) else parts
    if not len(parts):
        return 1, 0, 0
    tree = shapely.STRtree(parts)
    i, j = tree.query(parts, predicate="intersects")
    crossings = int(np.count_nonzero(i < j))
    return 1 + len(parts) + crossings, len(parts), crossings


#: a block whose minimum rotated rectangle is this many times longer than wide is a sliver [-]:
#: in scenes/jointed_slope.py with 0.3 m / 0.4 m spacings a free 52:1 block beside a fixed one
#: ran away at step 1; with the blocks of 50:1 and more merged the run goes on
SLIVER_ASPECT = 50.0
#: ... and so is one smaller than this fraction of the median block [-]
SLIVER_AREA = 1e-4


class SliverWarning(UserWarning):
    """`cut` made sliver blocks (thin or tiny pieces between nearly parallel or nearly
    meeting joints) and kept them: they need time steps and penalties far from the rest of the
    model and can stop a run; ``slivers="merge"`` merges each into a neighbour."""


def _sliver_measures(faces) -> tuple[np.ndarray, np.ndarray]:
    """Aspect ratio (long / short side of the minimum rotated rectangle) and area of faces."""
    import shapely

    rect = shapely.oriented_envelope(faces)
    aspect = np.ones(len(faces))
    for k, r in enumerate(rect):
        xy = np.asarray(r.exterior.coords) if r.geom_type == "Polygon" else None
        if xy is None or len(xy) < 4:
            aspect[k] = np.inf
            continue
        a, b = np.linalg.norm(xy[1] - xy[0]), np.linalg.norm(xy[2] - xy[1])
        aspect[k] = max(a, b) / max(min(a, b), 1e-300)
    return aspect, shapely.area(faces)


def _slivers(faces) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(which faces are slivers, their aspect ratios, their areas): `SLIVER_ASPECT` and more,
    or smaller than `SLIVER_AREA` × the median face."""
    aspect, area = _sliver_measures(faces)
    return (aspect >= SLIVER_ASPECT) | (area < SLIVER_AREA * np.median(area)), aspect, area


def _merge_slivers(faces: list, scale: float) -> tuple[list, int]:
    """Merge every sliver (`SLIVER_ASPECT`, `SLIVER_AREA`) into the neighbour with which it
    shares the longest boundary (the joint piece between them disappears), thinnest first,
    while the union is a simple polygon. Returns (faces, merged)."""
    import shapely

    faces = list(faces)
    merged = 0
    while True:
        sliver, aspect, _ = _slivers(faces)
        if not sliver.any() or len(faces) < 2:
            return faces, merged
        order = np.argsort(-aspect)
        done = False
        tree = shapely.STRtree(faces)
        for k in (int(i) for i in order if sliver[i]):
            near = [int(j) for j in tree.query(faces[k], predicate="touches") if j != k]
            if not near:
                continue
            shared = [shapely.length(shapely.intersection(faces[k].boundary, faces[j].boundary)) for j in near]
            for j in [near[i] for i in np.argsort(shared)[::-1]]:
                union = shapely.union(faces[k], faces[j], grid_size=None)
                union = shapely.simplify(union, 1e-12 * scale)
                if union.geom_type == "Polygon" and not union.interiors and union.is_valid:
                    faces[j] = union
                    del faces[k]
                    merged += 1
                    done = True
                    break
            if done:
                break
        if not done:
            return faces, merged


def cut(boundary, joints: Sequence, *, snap: float | None = None,
        max_blocks: float | None = None, slivers: str = "warn") -> list[tuple[np.ndarray, np.ndarray]]:
    """Cut a domain polygon by joint traces into blocks.

    Parameters
    ----------
    boundary : (n, 2) vertices of the domain polygon (any orientation).
    joints : sequence of polylines, each (k, 2) with k >= 2; a trace may be persistent (crossing
        the domain) or finite. Parts of traces outside the domain are ignored, and parts that
        do not close a block (dangling ends, isolated traces) are dropped, as in DDA's block
        cutting.
    snap : distance [m] below which an edge counts as lying on a joint trace; default 1e-9 ×
        the domain size.
    max_blocks : refuse (`ModelSizeError`, before cutting) when `estimate_blocks` exceeds this;
        None: `max_blocks_here` (what the machine's memory can simulate; a joint spacing typed
        10× too small makes 100× the blocks), inf: never.
    slivers : blocks whose minimum rotated rectangle is ≥ `SLIVER_ASPECT` times longer than
        wide, or smaller than `SLIVER_AREA` × the median block: ``"warn"`` keeps them with a
        `SliverWarning` naming the worst; ``"merge"`` merges each into the neighbour it shares
        the longest boundary with (the joint piece between them disappears; the union must be a
        simple polygon, else the sliver stays and is warned about); ``"keep"`` says nothing.

    Returns
    -------
    list of ``(vertices, edge_joint)``: the CCW vertices of each block and, for each edge
    (from vertex k to k+1), the index into ``joints`` of the trace it lies on, or -1 for an edge
    on the domain boundary. Blocks are ordered by centroid (y, then x).
    """
    import shapely

    outline = validate_polygon(boundary, name="cut boundary")
    domain = shapely.Polygon(outline)
    scale = float(np.ptp(outline, axis=0).max())
    tol = 1e-9 * scale if snap is None else float(snap)
    lines = []
    for k, trace in enumerate(joints):
        arr = np.asarray(trace, dtype=np.float64)
        if arr.ndim != 2 or arr.shape[1] != 2 or len(arr) < 2 or not np.all(np.isfinite(arr)):
            raise ValueError(f"joint {k}: a trace must be a polyline of at least 2 finite (x, y) points")
        if np.ptp(arr, axis=0).max() <= 0:
            raise ValueError(f"joint {k}: trace has zero length")
        lines.append(shapely.LineString(arr))
    limit = max_blocks_here() if max_blocks is None else float(max_blocks)
    if np.isfinite(limit):
        estimate, pieces, crossings = estimate_blocks(domain, lines)
        if estimate > limit:
            need = (MEMORY_BASE + MEMORY_PER_BLOCK * estimate) / 1e9
            raise ModelSizeError(
                f"cut: {len(lines)} joint traces ({pieces} pieces inside the boundary, {crossings} crossings) "
                f"would make up to {estimate:,} blocks, about {need:.1f} GB to simulate, beyond the "
                f"{limit:,.0f} blocks this machine can hold ({available_memory() / 1e9:.1f} GB available): "
                f"check the joint spacings (a spacing in the wrong unit makes 100× the blocks); to go on "
                f"anyway pass max_blocks=float('inf') (ddatai run --force)")
    noded = shapely.union_all([domain.exterior, *lines])
    faces = shapely.get_parts(shapely.polygonize(shapely.get_parts(noded)))
    inside = [f for f in faces if f.area > 1e-12 * scale * scale
              and domain.contains(f.representative_point())]
    if not inside:
        raise ValueError("cut: the joints produce no block inside the boundary")
    if slivers not in ("warn", "merge", "keep"):
        raise ValueError(f"cut: slivers must be 'warn', 'merge' or 'keep', got {slivers!r}")
    if slivers == "merge":
        inside, _ = _merge_slivers(inside, scale)
    if slivers != "keep" and len(inside) > 1:
        sliver, aspect, area = _slivers(inside)
        thin = np.flatnonzero(sliver)
        if len(thin):
            import warnings

            worst = int(thin[np.argmax(aspect[thin])])
            warnings.warn(f"cut: {len(thin)} sliver block(s) (aspect ≥ {SLIVER_ASPECT:g}:1 or area < "
                          f"{SLIVER_AREA:g} × the median {np.median(area):.3g} m²); the thinnest is "
                          f"{aspect[worst]:.0f}:1, {area[worst]:.3g} m², near "
                          f"({inside[worst].centroid.x:.3g}, {inside[worst].centroid.y:.3g}) m. Slivers need far smaller "
                          f"time steps and can stop a run: cut(..., slivers='merge') merges each into a neighbour",
                          SliverWarning, stacklevel=4)

    blocks = []
    for face in inside:
        xy = validate_polygon(np.asarray(face.exterior.coords)[:-1], name="cut block")
        blocks.append(xy)
    centroid = np.array([_centroid(b) for b in blocks])
    order = np.lexsort((np.round(centroid[:, 0] / scale, 9), np.round(centroid[:, 1] / scale, 9)))
    blocks = [blocks[i] for i in order]

    counts = np.array([len(b) for b in blocks])
    offset = np.concatenate([[0], np.cumsum(counts)])
    xy_all = np.concatenate(blocks)
    nxt = np.arange(len(xy_all)) + 1
    nxt[offset[1:] - 1] = offset[:-1]
    edge_joint = np.full(len(xy_all), np.iinfo(np.int64).max, dtype=np.int64)
    if lines:
        tree = shapely.STRtree(lines)
        a, b = xy_all, xy_all[nxt]
        edges = shapely.linestrings(np.stack([a, b], axis=1))
        e_idx, j_idx = tree.query(edges, predicate="dwithin", distance=tol)
        if len(e_idx):
            # an edge lies on a trace when both of its end points do (not just one touching it)
            line_arr = np.asarray(lines, dtype=object)[j_idx]
            on = (shapely.distance(shapely.points(a[e_idx]), line_arr) <= tol) & \
                 (shapely.distance(shapely.points(b[e_idx]), line_arr) <= tol)
            np.minimum.at(edge_joint, e_idx[on], j_idx[on])
    edge_joint[edge_joint == np.iinfo(np.int64).max] = -1
    return [(blocks[k], edge_joint[offset[k]:offset[k + 1]].copy()) for k in range(len(blocks))]


def _centroid(xy: np.ndarray) -> np.ndarray:
    ints = polygon_integrals(xy, np.array([0, len(xy)]))
    return ints["centroid"][0]


#: Two blocks overlap when their common area exceeds this fraction of the smaller one's [-]
#: (cut blocks share edges to round-off, ~1e-16 of their area).
OVERLAP_AREA = 1e-9


def check_overlaps(scene, *, what: str = "") -> None:
    """Raise ValueError naming the first pair of blocks whose interiors overlap (common area
    above `OVERLAP_AREA` of the smaller), with the overlap's area and its depth (area over
    half its perimeter: the thickness of a thin overlap) [m]; ``what`` is added to the
    message."""
    import shapely

    polys = np.array([shapely.Polygon(s.vertices) for s in scene.blocks], dtype=object)
    if len(polys) < 2:
        return
    tree = shapely.STRtree(polys)
    a, b = tree.query(polys, predicate="intersects")
    keep = a < b
    a, b = a[keep], b[keep]
    if not len(a):
        return
    common = shapely.intersection(polys[a], polys[b])
    inter = shapely.area(common)
    areas = shapely.area(polys)
    bad = inter > OVERLAP_AREA * np.minimum(areas[a], areas[b])
    if bad.any():
        k = int(np.flatnonzero(bad)[0])
        depth = 2.0 * inter[k] / max(float(shapely.length(common[k])), 1e-300)
        raise ValueError(f"blocks {a[k]} and {b[k]} overlap at the start (overlap area {inter[k]:.3g} m², "
                         f"about {depth:.3g} m deep)" + (f": {what}" if what else ""))
