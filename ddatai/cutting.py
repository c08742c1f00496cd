"""Cutting a domain into blocks by joint traces (`Scene.cut`): the model-size estimate that
refuses a far larger model than intended before any work, trace ends that nearly reach another
trace or the outline snapped onto it (or warned about), and slivers reported and merged.

NumPy and shapely only (never Taichi).
"""

from __future__ import annotations

from typing import Sequence

import numpy as np

from .geometry import polygon_integrals, validate_polygon

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


def contact_band(faces) -> float:
    """The contacts' penetration band d9 [m] of a model of these faces with the default
    `Params` (`build_model`: max(0.3·2.5·g2, 3·g3)·w0, w0 half the larger side of the model, at
    most 10 × the median √area of its blocks)."""
    import shapely

    from .params import Params

    p = Params()
    lo_x, lo_y, hi_x, hi_y = shapely.total_bounds(faces)
    w0 = min(0.5 * max(hi_x - lo_x, hi_y - lo_y), 10.0 * float(np.median(np.sqrt(shapely.area(faces)))))
    return max(0.75 * p.max_displacement_ratio, 3.0 * p.penetration_ratio) * w0


def _thickness(faces) -> np.ndarray:
    """2·area/perimeter of faces (a triangle's inradius, half a strip's width) [m]: what
    `ddatai.diagnosis.slivers` compares with the penetration band."""
    import shapely

    return 2.0 * shapely.area(faces) / np.maximum(shapely.length(faces), 1e-300)


def _merge_slivers(faces: list, scale: float, band: float | None = None) -> tuple[list, int]:
    """Merge every sliver (`SLIVER_ASPECT`, `SLIVER_AREA`) — or, given ``band``, every face
    thinner than it (`_thickness`) — into the neighbour with which it shares the longest
    boundary (the joint piece between them disappears), thinnest first, while the union is a
    simple polygon. Returns (faces, merged)."""
    import shapely

    faces = list(faces)
    merged = 0
    while True:
        if band is None:
            sliver, aspect, _ = _slivers(faces)
        else:
            thickness = _thickness(faces)
            sliver, aspect = thickness < band, 1.0 / np.maximum(thickness, 1e-300)
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


#: Trace ends that stop this close to another trace or the domain's outline (× the domain's
#: size) are extended onto it (`cut`, ``snap_ends``): coordinates typed to six decimals, or a
#: drawing's round-off, leave a joint ~1 µm short of the one it meets, and a trace that does
#: not reach closes no block and is dropped. The DXF reader's default (`ddatai.io.dxf`).
SNAP_ENDS = 1e-6
#: Ends that stop short by more than the snap distance but less than this (× the domain's
#: size) are warned about (`TraceGapWarning`): a joint meant to end 0.1 mm from another in a
#: 10 m model is rare, a drawing error common; random finite traces end that close to another
#: one seldom (at 1e-4, the finite traces of tests/test_model_size.py's 100 m box had one end
#: 7.5 mm from another).
NEAR_MISS = 1e-5


class TraceGapWarning(UserWarning):
    """`cut` found joint traces that stop just short of another trace or of the outline
    (beyond ``snap_ends``) and so close no block there: the message names the traces, the
    gaps and how to close them."""


def _trace_ends(traces: list, boundary: np.ndarray, reach: float) -> list[tuple]:
    """The ends of the traces that stop short of another trace or the outline within
    ``reach`` [m]: (trace k, which end 0/-1, gap [m], target index: 0 the outline, j + 1
    trace j, the end point (2,), unit direction (2,) of the trace at that end, pointing out)."""
    import shapely

    lines = [shapely.LineString(t) for t in traces]
    others = [shapely.LinearRing(boundary)] + lines
    domain = shapely.Polygon(boundary)
    tree = shapely.STRtree(others)
    out = []
    for k, t in enumerate(traces):
        for end, prev in ((-1, -2), (0, 1)):
            p = shapely.Point(t[end])
            if not domain.covers(p):
                continue  # the trace leaves the domain: the outline cuts it
            last = shapely.LineString([t[prev], t[end]])
            # a target the end's segment reaches (touches or crosses) near the end is met, not
            # missed (an end a hair past a trace it crossed)
            near = [int(i) for i in tree.query(p, predicate="dwithin", distance=reach)
                    if i != k + 1 and not _reaches(last, others[int(i)], p, reach)]
            if not near:
                continue
            gap, target = min((others[i].distance(p), i) for i in near)
            d = t[end] - t[prev]
            out.append((k, end, float(gap), target, t[end].copy(), d / np.hypot(*d)))
    return out


def _reaches(segment, target, end, reach: float) -> bool:
    """Whether ``segment`` meets ``target`` within ``reach`` of its ``end`` point."""
    import shapely

    hit = shapely.intersection(segment, target)
    return not hit.is_empty and hit.distance(end) <= reach


def snap_trace_ends(boundary, traces, snap: float) -> tuple[list[np.ndarray], list[tuple]]:
    """The traces with every end that stops within ``snap`` [m] of the outline or of another
    trace extended along its last segment to where that line meets it, and a hair (1e-9 × the
    outline's size) across, so that noding joins them; and the ends moved, as (trace k, gap
    [m], target: 0 the outline, j + 1 trace j). An end whose line runs beside the target
    (meets it only more than 1000 gaps further on) is left as it is (`cut` warns about it)."""
    import shapely

    outline = np.asarray(boundary, dtype=float)
    traces = [np.array(t, dtype=float) for t in traces]
    if snap <= 0 or not traces:
        return traces, []
    scale = float(np.ptp(outline, axis=0).max())
    others = [shapely.LinearRing(outline)] + [shapely.LineString(t) for t in traces]
    over = 1e-9 * scale  # cross the target by a hair: the stub beyond it closes nothing
    moved = []
    for k, end, gap, target, p, d in _trace_ends(traces, outline, snap):
        ray = shapely.LineString([p, p + (1e3 * gap + 2.0 * over) * d])
        hit = shapely.intersection(ray, others[target])
        pts = np.array([c for g in shapely.get_parts(hit) for c in np.asarray(g.coords)]).reshape(-1, 2)
        if not len(pts):
            continue
        q = pts[int(np.argmin(np.hypot(*(pts - p).T)))]
        traces[k][end] = q + over * d
        moved.append((k, gap, target))
    return traces, moved


def _warn_trace_gaps(traces: list, outline: np.ndarray, snap: float, scale: float) -> None:
    """`TraceGapWarning` for ends left short of a trace or the outline (beyond ``snap``, or
    within it but running beside the target) by at most `NEAR_MISS` × ``scale``."""
    short = _trace_ends(traces, outline, NEAR_MISS * scale)
    if not short:
        return
    import warnings

    def where(target: int) -> str:
        return "the outline" if target == 0 else f"joint {target - 1}"

    shown = "; ".join(f"joint {k}'s end ({p[0]:.9g}, {p[1]:.9g}) stops {gap:.3g} m short of {where(tg)}"
                      for k, _, gap, tg, p, _ in sorted(short, key=lambda e: e[2])[:3])
    more = f" (and {len(short) - 3} more)" if len(short) > 3 else ""
    widest = max(e[2] for e in short)
    warnings.warn(f"cut: {len(short)} joint trace end(s) stop just short of another trace or the outline, beyond "
                  f"the snap distance {snap:.3g} m: {shown}{more}. Such a trace closes no block there and the "
                  f"part of it that closes none is dropped. If the joints are meant to meet, extend the traces "
                  f"or pass snap_ends={1.5 * widest:.2g} (m) to snap them (read_dxf: snap=)", TraceGapWarning, stacklevel=4)


def cut(boundary, joints: Sequence, *, snap: float | None = None,
        max_blocks: float | None = None, slivers: str = "warn",
        snap_ends: float | None = None) -> list[tuple[np.ndarray, np.ndarray]]:
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
        With "warn" or "merge", blocks thinner than the contacts' penetration band
        (`contact_band`, 2·area/perimeter) are merged too, with a `SliverWarning`: contacts
        cannot resolve them; "keep" keeps them.
    snap_ends : a trace end that stops at most this far [m] short of another trace or of the
        outline is extended onto it (`snap_trace_ends`); default `SNAP_ENDS` × the domain size
        (1e-6: coordinates typed to six decimals), 0: never. Ends short by more, up to
        `NEAR_MISS` × the size, are warned about (`TraceGapWarning`, naming the trace, the gap
        and the ``snap_ends`` that would close it).

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
    if snap_ends is None:
        snap_ends = SNAP_ENDS * scale
    elif isinstance(snap_ends, bool) or not isinstance(snap_ends, (int, float)) or not np.isfinite(snap_ends) \
            or snap_ends < 0:
        raise ValueError(f"cut: snap_ends must be a finite distance >= 0 m, got {snap_ends!r}")
    arrays = []
    for k, trace in enumerate(joints):
        arr = np.asarray(trace, dtype=np.float64)
        if arr.ndim != 2 or arr.shape[1] != 2 or len(arr) < 2 or not np.all(np.isfinite(arr)):
            raise ValueError(f"joint {k}: a trace must be a polyline of at least 2 finite (x, y) points")
        if np.ptp(arr, axis=0).max() <= 0:
            raise ValueError(f"joint {k}: trace has zero length")
        arrays.append(arr)
    arrays, _ = snap_trace_ends(outline, arrays, float(snap_ends))
    _warn_trace_gaps(arrays, outline, float(snap_ends), scale)
    lines = [shapely.LineString(arr) for arr in arrays]
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
        # a block thinner than the contacts' penetration band cannot be resolved by the
        # contact rules at all (a vertex may sit legally deeper than the whole block): merged
        # even where the user left the slivers to a warning (docs/method/limits.md)
        band = contact_band(inside)
        thickness = _thickness(inside)
        if np.any(thickness < band):
            thinnest = int(np.argmin(thickness))
            where, thin = inside[thinnest].centroid, float(thickness[thinnest])
            inside, merged = _merge_slivers(inside, scale, band=band)
            if merged:
                import warnings

                warnings.warn(f"cut: merged {merged} block(s) thinner than the contacts' penetration band "
                              f"{band:.3g} m (2·area/perimeter; the thinnest {thin:.3g} m, near ({where.x:.3g}, "
                              f"{where.y:.3g}) m) into a neighbour each: contacts cannot resolve them "
                              f"(docs/method/limits.md); cut(..., slivers='keep') keeps them",
                              SliverWarning, stacklevel=4)
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
