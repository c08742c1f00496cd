"""Blocks from a set of joint segments, cut the way ntdda ("DDA for Windows") cuts them.

`ddatai.cutting.cut` cuts a *given* domain polygon by joint traces. An ntdda geometry file has
no domain polygon: the outline is itself made of joint lines, and the blocks are the closed
regions of the whole line set after Shi's block-cutting program (GHS "DC", ntdda `blocks.c`,
docs/ntdda.md §2) has merged close nodes and dropped dangling segments. Reproducing those
rules matters: they decide how many vertices a block has (circleslope's slices, docs/ntdda.md §4.7)
and the order in which blocks are numbered (ntdda's outputs refer to blocks by that number).

The steps, in ntdda's order (function names of `blocks.c` in brackets):

1. domain scale w0 = 1.02·max(H/2, W/2.6) of the joint end points' bounding box [dc02];
2. intersections of every pair of segments; an intersection closer than 1.25·e00·w0 to an
   earlier node is merged into it (boundary lines excepted) [dc04, lns];
3. lines met by one node only are dropped, and so are nodes left on one line [dc05];
4. edges between consecutive nodes along each line; edges that cross another edge after the
   merging, and edges passing within e00·w0 of a node, are deleted; dangling edges are pruned
   [dc05, dc06];
5. faces are walked around the nodes (edges sorted by direction) and the interior ones become
   blocks, numbered in the order the walk finds them [dc07, dc08];
6. vertices on the straight line of their neighbours are removed [dc09].

What ntdda does after cutting (hole points, blocks inside blocks, material lines, fixed lines,
points in blocks) is in `ddatai.io.ntdda.placement`, as separate functions, so that
``ddatai.io.ntdda`` can apply its documented choices between them; its names, and those of the
segment tests (`ddatai.io.ntdda.segments`), are importable from here too. NumPy and shapely
only; no Taichi.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

# re-exported only: this module was their home, and callers still import them from here
from .placement import (BlockLocator, block_containing, block_materials, blocks_inside_other_blocks,
                        clip_fixed_line, ntdda_fixed_points)
from .segments import PARAMETER_TOL, domain_scale, segment_intersection

__all__ = ["CutBlocks", "cut_segments", "domain_scale", "segment_intersection", "BlockLocator",
           "block_containing", "block_materials", "blocks_inside_other_blocks", "clip_fixed_line",
           "ntdda_fixed_points"]

#: Collinear-vertex test of dc09, relative to w0² (twice the triangle area < 1e-9·w0²).
_COLLINEAR_TOL = 1e-9


@dataclass(frozen=True, kw_only=True, eq=False)
class CutBlocks:
    """Blocks cut from joint segments, in ntdda's block order."""

    polygons: tuple
    """Per block, the (n, 2) CCW vertices [length units of the file]."""
    edge_line: tuple
    """Per block, (n,) int: index of the input segment each edge (vertex k -> k+1) lies on."""
    w0: float
    """ntdda's domain scale 1.02·max(H/2, W/2.6) of the segments' bounding box [length]."""

    @property
    def n_blocks(self) -> int:
        return len(self.polygons)


class _NodeIndex:
    """Nodes in creation order with a grid for 'first node within distance r' queries."""

    def __init__(self, radius: float):
        self.radius = radius
        self.xy: list[tuple[float, float]] = []
        self.cells: dict = {}

    def _cell(self, x: float, y: float):
        if self.radius <= 0:
            return (x, y)
        return (int(np.floor(x / self.radius)), int(np.floor(y / self.radius)))

    def first_within(self, x: float, y: float) -> int:
        """Lowest-numbered node within ``radius`` of (x, y), or -1 (ntdda scans nodes in order)."""
        if self.radius <= 0:
            return min(self.cells.get((x, y), [-1]))
        cx, cy = self._cell(x, y)
        best = -1
        for dx in (-1, 0, 1):
            for dy in (-1, 0, 1):
                for k in self.cells.get((cx + dx, cy + dy), ()):
                    nx, ny = self.xy[k]
                    if (best < 0 or k < best) and np.hypot(nx - x, ny - y) <= self.radius:
                        best = k
        return best

    def add(self, x: float, y: float) -> int:
        k = len(self.xy)
        self.xy.append((x, y))
        self.cells.setdefault(self._cell(x, y), []).append(k)
        return k


def cut_segments(segments, *, edge_node_distance: float, n_boundary: int = 0) -> CutBlocks:
    """Cut the plane by joint segments into blocks, following ntdda's block cutting.

    Parameters
    ----------
    segments : (n, 4) end points ``x1 y1 x2 y2`` of each joint segment [length].
    edge_node_distance : ntdda's e00 (relative): intersections closer than 1.25·e00·w0 merge
        into one node, and an edge passing within e00·w0 of a node is deleted.
    n_boundary : the first ``n_boundary`` segments are boundary lines: their intersections are
        never merged and their edges never deleted (GHS's "boundary lines", docs/ntdda.md §4.2).

    Returns
    -------
    CutBlocks, in ntdda's block order. Raises ``ValueError`` if the lines close no block or
    form a block whose outline is not a simple polygon (a slit or bridge).
    """
    seg = np.asarray(segments, dtype=float).reshape(-1, 4)
    n = len(seg)
    if n < 3:
        raise ValueError(f"block cutting needs at least 3 joint lines, got {n}")
    w0 = domain_scale(seg)
    e00 = float(edge_node_distance)
    p_start, p_end = seg[:, :2], seg[:, 2:]

    # -- 2. intersections, merged into earlier nodes (dc04) --------------------------------
    nodes = _NodeIndex(1.25 * e00 * w0)
    reg: list[dict[int, float]] = []          # per node: line -> parameter t along that line

    def register(i: int, js: np.ndarray) -> None:
        if len(js) == 0:
            return
        hit, t1, t2 = segment_intersection(w0, p_start[i], p_end[i], p_start[js], p_end[js])
        for j, a, b in zip(js[hit], t1[hit], t2[hit]):
            x0 = p_start[i, 0] + (p_end[i, 0] - p_start[i, 0]) * a
            y0 = p_start[i, 1] + (p_end[i, 1] - p_start[i, 1]) * a
            k = nodes.first_within(x0, y0) if i >= n_boundary else -1
            if k < 0:
                k = nodes.add(x0, y0)
                reg.append({})
            reg[k][i] = float(a)
            reg[k][int(j)] = float(b)

    # ntdda intersects each line with the boundary lines first, then with the other lines
    for i in range(1, n):
        register(i, np.arange(min(i, n_boundary)))
    for i in range(1, n):
        register(i, np.arange(n_boundary, i))

    # -- 3. drop lines met at one node, and nodes left on one line (dc05) -------------------
    line_nodes: list[set] = [set() for _ in range(n)]
    for k, lines in enumerate(reg):
        for i in lines:
            line_nodes[i].add(k)
    changed = True
    while changed:
        changed = False
        for i in range(n):
            if len(line_nodes[i]) != 1:
                continue
            (k,) = line_nodes[i]
            del reg[k][i]
            line_nodes[i].clear()
            changed = True
            if len(reg[k]) == 1:
                (other,) = reg[k]
                del reg[k][other]
                line_nodes[other].discard(k)
    alive = [k for k in range(len(reg)) if reg[k]]
    renum = {k: m for m, k in enumerate(alive)}
    node_xy = np.array([nodes.xy[k] for k in alive], dtype=float).reshape(-1, 2)
    n_nodes = len(alive)

    # -- 4. edges along each line, in ntdda's registration order (dc05) --------------------
    neighbours: list[list[int]] = [[] for _ in range(n_nodes)]
    edge_line: dict[tuple[int, int], int] = {}
    for i in range(n):
        on_line = sorted(((reg[k][i], renum[k]) for k in sorted(line_nodes[i]) if k in renum),
                         key=lambda item: item[0])
        for (_, a), (_, b) in zip(on_line[:-1], on_line[1:]):
            key = (min(a, b), max(a, b))
            if key not in edge_line:
                edge_line[key] = i
                neighbours[a].append(b)
                neighbours[b].append(a)

    def is_boundary(key) -> bool:
        return edge_line[key] < n_boundary

    _delete_crossing_edges(node_xy, neighbours, edge_line, is_boundary, w0)
    _delete_edges_near_nodes(node_xy, neighbours, edge_line, is_boundary, w0 * e00)
    _prune_dangling(neighbours)

    # -- 5. faces (dc07, dc08) ---------------------------------------------------------------
    polygons, lines = _walk_faces(node_xy, neighbours, edge_line)

    # -- 6. collinear vertices (dc09) -------------------------------------------------------
    out_poly, out_line = [], []
    for ring, ring_lines in zip(polygons, lines):
        ring, ring_lines = _merge_collinear(ring, ring_lines, w0)
        if len(ring) >= 3:
            out_poly.append(ring)
            out_line.append(ring_lines)
    if not out_poly:
        raise ValueError("the joint lines close no block (after ntdda's block cutting)")
    return CutBlocks(polygons=tuple(out_poly), edge_line=tuple(out_line), w0=w0)


def _remove_edge(neighbours, edge_line, a: int, b: int) -> None:
    neighbours[a].remove(b)
    neighbours[b].remove(a)
    del edge_line[(min(a, b), max(a, b))]


def _delete_crossing_edges(node_xy, neighbours, edge_line, is_boundary, w0) -> None:
    """Delete one edge of every pair that crosses after nodes were merged (dc06, first part).

    ntdda scans node i, node j and their edges in order and deletes j's edge (i's if j's lies
    on a boundary line). Crossings only appear where merging moved a node, so candidates come
    from an R-tree and only they are replayed in ntdda's order.
    """
    import shapely

    keys = list(edge_line)
    if len(keys) < 2:
        return
    ends = np.array(keys)
    lines = shapely.linestrings(np.stack([node_xy[ends[:, 0]], node_xy[ends[:, 1]]], axis=1))
    tree = shapely.STRtree(lines)
    ia, ib = tree.query(lines, predicate="dwithin", distance=1e-6 * w0)
    keep = ia < ib
    ia, ib = ia[keep], ib[keep]
    if len(ia) == 0:
        return
    events = []
    pos = [{nb: p for p, nb in enumerate(lst)} for lst in neighbours]
    for e, f in zip(ia, ib):
        (a, b), (c, d) = keys[e], keys[f]
        if len({a, b, c, d}) < 4 or (is_boundary(keys[e]) and is_boundary(keys[f])):
            continue
        hit, _, _ = segment_intersection(w0, node_xy[a], node_xy[b], node_xy[c], node_xy[d],
                                         collinear=False)
        if not hit:
            continue
        # every way ntdda's loops meet this pair: (i, i1) one edge, (j, j1) the other
        for (i, i1), (j, j1) in (((a, b), (c, d)), ((b, a), (c, d)), ((a, b), (d, c)), ((b, a), (d, c)),
                                 ((c, d), (a, b)), ((d, c), (a, b)), ((c, d), (b, a)), ((d, c), (b, a))):
            events.append((i, j, pos[i][i1], pos[j][j1], i1, j1))
    for i, j, _, _, i1, j1 in sorted(events):
        ki, kj = (min(i, i1), max(i, i1)), (min(j, j1), max(j, j1))
        if ki not in edge_line or kj not in edge_line:
            continue
        # the parameters are the same from either end, so the pair still crosses
        victim = ki if is_boundary(kj) else kj
        _remove_edge(neighbours, edge_line, *victim)


def _delete_edges_near_nodes(node_xy, neighbours, edge_line, is_boundary, distance) -> None:
    """Delete every non-boundary edge that passes within ``distance`` = e00·w0 of a node other
    than its own end points, with the foot of the perpendicular on the edge (dc06, second
    part): such an edge nearly duplicates a path through that node."""
    import shapely

    keys = [k for k in edge_line if not is_boundary(k)]
    if not keys or distance <= 0 or len(node_xy) < 3:
        return
    ends = np.array(keys)
    a, b = node_xy[ends[:, 0]], node_xy[ends[:, 1]]
    lines = shapely.linestrings(np.stack([a, b], axis=1))
    tree = shapely.STRtree(shapely.points(node_xy))
    e_idx, n_idx = tree.query(lines, predicate="dwithin", distance=distance * (1 + 1e-12))
    own = (n_idx == ends[e_idx, 0]) | (n_idx == ends[e_idx, 1])
    e_idx, n_idx = e_idx[~own], n_idx[~own]
    if len(e_idx) == 0:
        return
    d = b[e_idx] - a[e_idx]
    t = np.einsum("ij,ij->i", node_xy[n_idx] - a[e_idx], d) / np.einsum("ij,ij->i", d, d)
    foot = a[e_idx] + t[:, None] * d
    dist = np.hypot(*(node_xy[n_idx] - foot).T)
    near = (t >= -PARAMETER_TOL) & (t <= 1 + PARAMETER_TOL) & (dist <= distance)
    for e in sorted(set(e_idx[near].tolist())):
        _remove_edge(neighbours, edge_line, *keys[e])


def _prune_dangling(neighbours) -> None:
    """Remove nodes with a single edge until none is left (dc06, last part)."""
    stack = [k for k, lst in enumerate(neighbours) if len(lst) == 1]
    while stack:
        k = stack.pop()
        if len(neighbours[k]) != 1:
            continue
        (m,) = neighbours[k]
        neighbours[k].clear()
        neighbours[m].remove(k)
        if len(neighbours[m]) == 1:
            stack.append(m)


def _walk_faces(node_xy, neighbours, edge_line):
    """Walk the faces of the planar graph in ntdda's order and keep the interior ones (dc08).

    At every node the edges are sorted by direction angle; the walk leaves a node by the edge
    that follows, counter-clockwise, the edge it arrived by. This traces each face clockwise;
    a face whose turning angles sum to more than n·180° is an outer boundary and is skipped.
    Blocks are numbered in the order their first edge is met scanning nodes in order.
    """
    n_nodes = len(neighbours)
    order, angle = [], []
    for k in range(n_nodes):
        nb = neighbours[k]
        if not nb:
            order.append([])
            angle.append(np.zeros(0))
            continue
        d = node_xy[nb] - node_xy[k]
        ang = np.degrees(np.arctan2(d[:, 1], d[:, 0])) % 360.0
        srt = np.argsort(ang, kind="stable")
        order.append([nb[s] for s in srt])
        angle.append(ang[srt])
    position = [{nb: p for p, nb in enumerate(lst)} for lst in order]
    # angle from edge p to the next edge counter-clockwise, at each node
    gap = []
    for ang in angle:
        g = np.diff(ang, append=ang[:1] + 360.0) if len(ang) else ang
        gap.append(g)
    visited = [np.zeros(len(lst), dtype=bool) for lst in order]

    polygons, lines = [], []
    for start in range(n_nodes):
        for p in range(len(order[start])):
            if visited[start][p]:
                continue
            walk, walk_line = [], []
            i1, j0 = start, p
            j1 = order[start][p]
            turn = 0.0
            while True:
                visited[i1][j0] = True
                walk.append(j1)
                back = position[j1][i1]
                turn += gap[j1][back]
                nxt = order[j1][(back + 1) % len(order[j1])]
                i1, j1 = j1, nxt
                j0 = position[i1][j1]
                walk_line.append(edge_line[(min(i1, j1), max(i1, j1))])
                if visited[i1][j0]:
                    break
            if turn > len(walk) * 180.0:
                continue  # the outer boundary of a connected set of lines
            # stored reversed, as ntdda does: counter-clockwise, starting at the start node
            ring = walk[::-1]
            if len(set(ring)) != len(ring):
                xy = node_xy[ring[0]]
                raise ValueError("the joint lines form a block whose outline runs twice through "
                                 f"the node at ({xy[0]:.6g}, {xy[1]:.6g}) (a slit or a bridge "
                                 "between two loops); ddatai blocks must be simple polygons")
            # walk edge walk[l] -> walk[l+1] has line walk_line[l]; in the reversed ring the
            # edge ring[q] -> ring[q+1] is that edge backwards
            m = len(walk)
            ring_line = [walk_line[(m - 2 - q) % m] for q in range(m)]
            polygons.append(node_xy[ring])
            lines.append(np.array(ring_line, dtype=np.int64))
    return polygons, lines


def _merge_collinear(ring: np.ndarray, ring_line: np.ndarray, w0: float):
    """Drop vertices on the straight line of their neighbours (dc09): twice the triangle area
    below 1e-9·w0². All vertices are tested on the unmodified ring. A merged edge takes the
    line of the last original edge it covers (ntdda keeps the line stored at the edge's end
    vertex)."""
    prev = np.roll(ring, 1, axis=0)
    nxt = np.roll(ring, -1, axis=0)
    a = ring - prev
    b = nxt - prev
    flat = np.abs(a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]) <= _COLLINEAR_TOL * w0 * w0
    if not flat.any():
        return ring, ring_line
    keep = np.flatnonzero(~flat)
    if len(keep) < 3:
        return ring[keep], ring_line[keep]
    m = len(ring)
    new_line = []
    for q, k in enumerate(keep):
        nxt_k = keep[(q + 1) % len(keep)]
        new_line.append(ring_line[(nxt_k - 1) % m])
    return ring[keep], np.array(new_line, dtype=np.int64)
