"""Vectorised NumPy contact detection and contact vectors, for small models.

A Taichi kernel launch costs ~0.3–0.5 ms of Python-side argument passing whatever the work,
so on a model of a few blocks the four or five launches of ``ddatai.contacts.detect_contacts``
and ``ddatai.assembly.contact_vectors`` cost more than the geometry itself. This module does the
same work in whole-array NumPy operations, with no Python loop over blocks, vertices or
contacts, and no Taichi:

- `broad_phase`: all block pairs (i < j, not both fixed) whose boxes, enlarged by margin/2,
  overlap, by a sweep along x (sort, then each box against the boxes that start within it);
- `narrow_phase`: Shi's vertex-edge / vertex-vertex rules (docs/method/dda.md §3.3–3.6)
  evaluated over every (vertex, vertex) and (vertex, edge) candidate of every block pair at
  once, operation for operation as `ddatai.kernels.narrow_phase` (the same guards
  ``EDGE_FLOOR`` and ``TIE``, the same mutual-nearest-vertex rule, the same entrance-angle
  test), so that it returns the same contacts, kinds, lines and lengths;
- `detect_contacts`: both, in the canonical order of ``ddatai.contacts.sort_contacts``;
- `contact_vectors`: the normal and shear vectors of every contact line (§2.8.1–2.8.4), as
  `ddatai.kernels.contact_vectors`.

``tests/test_vectorized.py`` compares every function with the kernel path;
``benchmarks/detection.py`` times both and finds the block count where the kernels win.
"""

from __future__ import annotations

import math

import numpy as np

from .contacts import box_bounds, sort_contacts
from .layout import N_SLOTS, S_ES, S_GS, VE, VV
from .model import Model

#: the narrow phase's guards, as `ddatai.kernels` (kept here so that this module does not
#: import Taichi; ``tests/test_vectorized.py`` checks that they agree)
EDGE_FLOOR = 1e-150
EDGE_FLOOR2 = EDGE_FLOOR * EDGE_FLOOR
TIE = 1e-3
SLACK = 1e-9
TWO_PI = 2.0 * math.pi
#: the wedges of a vertex pair do not overlap iff their angles and the two gaps sum to 2π
#: within this (`kernels._vertex_vertex`)
_AROUND = 1e-6


# --------------------------------------------------------------------------- broad phase
def _expand(counts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(owner, rank) of the entries of runs of the given lengths: owner k repeated counts[k]
    times, rank 0 … counts[k] − 1 within each run."""
    owner = np.arange(len(counts)).repeat(counts)
    start = counts.cumsum() - counts
    return owner, np.arange(len(owner)) - start[owner]


def broad_phase(model: Model, vertex_xy: np.ndarray, margin: float) -> np.ndarray:
    """Candidate block pairs (i < j, not both fixed) whose boxes, enlarged by margin/2, overlap.

    Returns a (P, 2) int32 array sorted by (i, j), as ``ddatai.contacts.broad_phase``.
    """
    lo, hi = box_bounds(model, vertex_xy, 0.5 * margin)
    nb = len(lo)
    if nb < 2:
        return np.zeros((0, 2), np.int32)
    # sweep along x: with the boxes sorted by their left side, box a meets in x exactly the
    # boxes after it whose left side is at most a's right side (a's left side is at most
    # theirs, hence at most their right side)
    order = lo[:, 0].argsort(kind="stable")
    left = lo[order, 0]
    count = left.searchsorted(hi[order, 0], side="right") - np.arange(1, nb + 1)
    first, rank = _expand(np.maximum(count, 0))
    a, b = order[first], order[first + 1 + rank]
    fixed = model.block_fixed
    hit = (lo[a, 1] <= hi[b, 1]) & (lo[b, 1] <= hi[a, 1]) & ~(fixed[a] & fixed[b])
    a, b = a[hit], b[hit]
    i, j = np.minimum(a, b), np.maximum(a, b)
    o = np.lexsort((j, i))
    out = np.empty((len(o), 2), np.int32)
    out[:, 0], out[:, 1] = i[o], j[o]
    return out


# --------------------------------------------------------------------------- narrow phase
def _wrap(angle: np.ndarray, lower) -> np.ndarray:
    """angle wrapped into [lower, lower + 2π) (`kernels._wrap`)."""
    return angle - TWO_PI * np.floor((angle - lower) / TWO_PI)


class _Geometry:
    """Per-vertex and per-edge quantities of the narrow phase, each computed once for all
    vertices with the operations (and their order) of the kernel's helpers."""

    def __init__(self, model: Model, xy: np.ndarray):
        nxt, prv = model.vertex_next, model.vertex_prev
        self.nxt, self.prv = nxt, prv
        # contiguous coordinates: faster to gather from than the columns of xy
        self.x, self.y = x, y = np.ascontiguousarray(xy[:, 0]), np.ascontiguousarray(xy[:, 1])
        # the vertex's edges r1 = next − P, r2 = prev − P (`kernels._ve_test`, `_convex`)
        self.r1x, self.r1y = x[nxt] - x, y[nxt] - y
        self.r2x, self.r2y = x[prv] - x, y[prv] - y
        self.n1 = np.sqrt(self.r1x * self.r1x + self.r1y * self.r1y)
        self.n2 = np.sqrt(self.r2x * self.r2x + self.r2y * self.r2y)
        self.convex = self.r1x * self.r2y - self.r1y * self.r2x > 0.0
        self.vblock, self.off = model.vertex_block, model.vertex_offset.astype(np.int64)
        self.block_convex = np.logical_and.reduceat(self.convex, self.off[:-1])
        # edge k = (k, next[k]): direction d, squared length, clamped length, outward normal
        self.dx, self.dy = self.r1x, self.r1y
        self.dd = self.dx * self.dx + self.dy * self.dy
        self.l2 = np.maximum(self.dd, EDGE_FLOOR2)
        self.length = np.maximum(np.sqrt(self.dd), EDGE_FLOOR)
        self.nx, self.ny = self.dy / self.length, -self.dx / self.length

    def edge_param(self, e: np.ndarray, p: np.ndarray) -> np.ndarray:
        """Projection parameter of vertex p on edge e (`kernels._edge_param`)."""
        x, y = self.x, self.y
        return ((x[p] - x[e]) * self.dx[e] + (y[p] - y[e]) * self.dy[e]) / self.l2[e]

    def half_overlap(self, e: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        """Half the overlap of segment (a, b) projected on edge e (`kernels._half_overlap`, §3.6)."""
        l2 = self.l2[e]
        ta = self.edge_param(e, a)
        tb = self.edge_param(e, b)
        lo = np.maximum(0.0, np.minimum(ta, tb))
        hi = np.minimum(1.0, np.maximum(ta, tb))
        return 0.5 * np.maximum(0.0, hi - lo) * np.sqrt(l2)

    def outside_convex(self, p: np.ndarray, e: np.ndarray, slack: float) -> np.ndarray:
        """Whether vertices p lie in front of some edge of the convex block of their edge e (or
        on its line, within ``slack``): outside it, or on its boundary (`kernels._outside_convex`)."""
        block = self.vblock[e]
        convex = self.block_convex[block]
        out = np.zeros(len(p), bool)
        k = convex.nonzero()[0]
        if not len(k):
            return out
        owner, rank = _expand(self.off[block[k] + 1] - self.off[block[k]])
        j = self.off[block[k]][owner] + rank
        v = p[k][owner]
        dn = (self.x[v] - self.x[j]) * self.nx[j] + (self.y[v] - self.y[j]) * self.ny[j]
        front = np.zeros(len(k), bool)
        np.logical_or.at(front, owner, dn > -slack)
        out[k] = front
        return out

    def nearer_exit(self, p: np.ndarray, depth: np.ndarray, a: np.ndarray, c: np.ndarray) -> np.ndarray:
        """Whether vertices p, at normal distances ``depth`` (< 0) from their edges, lie less
        deep behind the lines of edges a (or in front of them), projecting onto a, or nearer
        than |depth| to an end of a, where a meets that edge at the convex corner c
        (`kernels._nearer_exit`)."""
        px, py = self.x[p] - self.x[a], self.y[p] - self.y[a]
        l = self.length[a]
        t = (px * self.dx[a] + py * self.dy[a]) / (l * l)
        dn = px * self.nx[a] + py * self.ny[a]
        qx, qy = self.x[p] - self.x[self.nxt[a]], self.y[p] - self.y[self.nxt[a]]
        near = ((t < 0.0) & (px * px + py * py < depth * depth)) | ((t > 1.0) & (qx * qx + qy * qy < depth * depth))
        return self.convex[c] & (((dn > depth) & (t >= -SLACK) & (t <= 1.0 + SLACK)) | near)

    def edge_edge_exit(self, p: np.ndarray, e: np.ndarray, w: np.ndarray, d9: float) -> np.ndarray:
        """Whether vertices p, put on edges e by vertex pairs (p, w), w an end of e, exit by the
        edge at e's far corner, or lie deeper than d9 (§3.3; `kernels._edge_edge_exit`)."""
        dn = (self.x[p] - self.x[e]) * self.nx[e] + (self.y[p] - self.y[e]) * self.ny[e]
        out = dn < -SLACK * d9
        k = out.nonzero()[0]
        pb, eb, depth, at_start = p[k], e[k], dn[k], w[k] == e[k]
        far = np.where(at_start, self.nxt[eb], self.prv[eb])  # the edge at e's far corner
        out[k] = self.nearer_exit(pb, depth, far, np.where(at_start, far, eb)) | (depth < -d9)
        return out

    def ve_test(self, p: np.ndarray, e: np.ndarray, check_projection: np.ndarray, d0: float,
                d9: float, sin_h1: float) -> tuple[np.ndarray, np.ndarray]:
        """Distance and entrance-angle criteria of vertices p against edges e (§3.3, §3.4;
        `kernels._ve_test`); the projection on the edge must fall on it where
        ``check_projection``. Returns (positions of the accepted candidates, their contact
        lengths L: half the overlap of an edge-edge contact, else 0)."""
        x, y = self.x, self.y
        l = self.length[e]
        nx, ny = self.nx[e], self.ny[e]
        px, py = x[p] - x[e], y[p] - y[e]
        dn = px * nx + py * ny
        t = (px * self.dx[e] + py * self.dy[e]) / (l * l)
        # a collapsed edge has no normal; a concave vertex never contacts as a vertex
        k = ((l > EDGE_FLOOR) & (dn <= d0) & (dn >= -d9) & self.convex[p] &
                           (~check_projection | ((t >= 0.0) & (t <= 1.0)))).nonzero()[0]
        # behind the edge's line, but nearer the line of the edge that meets it at a convex
        # corner (or in front of it: outside the block): the vertex entered, or lies on, that
        # edge, not this one (§3.3, the shortest exit)
        behind = (dn[k] < -SLACK * d9).nonzero()[0]
        if len(behind):
            pb, eb, depth = p[k[behind]], e[k[behind]], dn[k[behind]]
            # the edges before and after e in one call (halves of its result)
            n, after = len(eb), self.nxt[eb]
            exits = self.nearer_exit(np.concatenate([pb, pb]), np.concatenate([depth, depth]),
                                     np.concatenate([self.prv[eb], after]), np.concatenate([eb, after]))
            keep = np.ones(len(k), bool)
            keep[behind[exits[:n] | exits[n:] | self.outside_convex(pb, eb, SLACK * d9)]] = False
            k = k[keep]
        p, e, nx, ny = p[k], e[k], nx[k], ny[k]
        # the vertex's material wedge must lie on the outer side of the edge within h1
        r1n = self.r1x[p] * nx + self.r1y[p] * ny
        r2n = self.r2x[p] * nx + self.r2y[p] * ny
        lim1 = sin_h1 * self.n1[p]
        lim2 = sin_h1 * self.n2[p]
        ok = ((r1n >= -lim1) & (r2n >= -lim2)).nonzero()[0]
        p, e, r1n, r2n, lim1, lim2 = p[ok], e[ok], r1n[ok], r2n[ok], lim1[ok], lim2[ok]
        # edge-edge: one of the vertex's edges parallel to the line within h1, the one to the
        # next vertex first (§3.6)
        along1 = np.abs(r1n) <= lim1
        along = (along1 | (np.abs(r2n) <= lim2)).nonzero()[0]
        length = np.zeros(len(p))
        if len(along):
            v = p[along]
            end = np.where(along1[along], self.nxt[v], self.prv[v])
            length[along] = self.half_overlap(e[along], v, end)
        return k[ok], length


def _first_per_group(group: np.ndarray, dist: np.ndarray, index: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """For each group: the entry of smallest ``dist``, the lowest ``index`` on ties
    (`kernels._nearest`). Returns (groups, position of that entry)."""
    order = np.lexsort((index, dist, group))
    g = group[order]
    first = np.ones(len(g), bool)
    first[1:] = g[1:] != g[:-1]
    return g[first], order[first]


def narrow_phase(model: Model, vertex_xy: np.ndarray, pairs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Contacts of the candidate block pairs (A < B): (cint (m, 5) int32 — kind, vertex0,
    edge0, vertex1, edge1 — and length (m,)), in canonical order (``contacts.sort_contacts``).

    Shi's rules of docs/method/dda.md §3.3–3.6 as `ddatai.kernels.narrow_phase`, over all
    pairs at once: (1) each vertex of A and vertex of B that are mutual nearest within d0 go
    through the vertex-pair rules; (2) every vertex of one block is tested against every edge
    of the other, except the edges that end at its mutual-nearest partner.
    """
    pairs = np.asarray(pairs)
    none = np.zeros((0, 5), np.int32), np.zeros(0)
    if len(pairs) == 0:
        return none
    off = model.vertex_offset.astype(np.int64)
    d0, d9 = model.search_distance, model.max_penetration
    h1 = math.radians(model.params.angle_tolerance)
    xy = vertex_xy
    nxt, prv = model.vertex_next, model.vertex_prev
    geo = _Geometry(model, xy)

    # 0. The vertices of each block of a pair that lie near the other block's box. A vertex
    # accepted against an edge lies within max(d0, d9) of it (projection on the edge, dn in
    # [−d9, d0]), and a vertex within d0 of a vertex of the other block lies within d0 of that
    # block's box: every candidate of the rules below is among these. The margin is 1.5× that
    # reach so that round-off cannot drop one; the exact tests follow.
    reach = 1.5 * max(d0, d9)
    (lo_x, lo_y), (hi_x, hi_y) = (b.T.copy() for b in box_bounds(model, xy, reach))
    n_pairs = len(pairs)
    A = pairs[:, 0].astype(np.int64)
    B = pairs[:, 1].astype(np.int64)
    # "sides": side s < n_pairs holds the vertices of A of pair s, side n_pairs + s those of B
    own = np.concatenate([A, B])
    other = np.concatenate([B, A])
    side, rank = _expand(off[own + 1] - off[own])
    vertex = off[own[side]] + rank
    o = other[side]
    x, y = geo.x[vertex], geo.y[vertex]
    near = ((x >= lo_x[o]) & (x <= hi_x[o]) & (y >= lo_y[o]) & (y <= hi_y[o])).nonzero()[0]
    if not len(near):
        return none
    # the near vertices, sorted by side (A's of every pair, then B's)
    vertex, side = vertex[near], side[near]
    n_near = len(vertex)
    per_side = np.bincount(side, minlength=2 * n_pairs)
    side_start = per_side.cumsum() - per_side

    # 1. mutual-nearest vertex pairs within d0: every near vertex of A against every near
    # vertex of B of the same pair
    n_a = int(per_side[:n_pairs].sum())
    partner_count = per_side[n_pairs + side[:n_a]]
    ka, rank = _expand(partner_count)
    kb = side_start[n_pairs + side[ka]] + rank
    va, vb = vertex[ka], vertex[kb]
    dx = geo.x[vb] - geo.x[va]
    dy = geo.y[vb] - geo.y[va]
    dist = np.sqrt(dx * dx + dy * dy)  # `kernels._nearest`: |Q − P|
    close = (dist <= d0).nonzero()[0]
    ka, kb, va, vb, dist = ka[close], kb[close], va[close], vb[close], dist[close]
    nearest = np.full(n_near, -1)
    g, at = _first_per_group(ka, dist, vb)
    nearest[g] = kb[at]
    g, at = _first_per_group(kb, dist, va)
    nearest[g] = ka[at]
    has = nearest >= 0
    mutual = has.copy()
    mutual[has] = nearest[nearest[has]] == has.nonzero()[0]
    partner = np.where(mutual, vertex[np.maximum(nearest, 0)], -1)

    ve_v, ve_e, ve_check = [], [], []   # vertex-edge candidates for `_Geometry.ve_test`
    out_v, out_e, out_len = [], [], []  # edge-edge contacts of vertex pairs
    vv_rows = []
    pa = mutual[:n_a].nonzero()[0]
    if len(pa):
        P = vertex[pa]
        Q = vertex[nearest[pa]]
        cP, cQ = geo.convex[P], geo.convex[Q]
        # one vertex concave: the convex one against both edges meeting at the concave one
        one = (cP != cQ).nonzero()[0]
        if len(one):
            v = np.where(cP[one], P[one], Q[one])
            w = np.where(cP[one], Q[one], P[one])
            ve_v += [v, v]
            ve_e += [prv[w], w]
            ve_check.append(np.zeros(2 * len(v), bool))
        both = (cP & cQ).nonzero()[0]
        if len(both):
            P, Q = P[both], Q[both]
            PQ = np.concatenate([P, Q])
            a1, b1 = np.arctan2(geo.r1y[PQ], geo.r1x[PQ]).reshape(2, -1)
            a2, b2 = np.arctan2(geo.r2y[PQ], geo.r2x[PQ]).reshape(2, -1)
            # the wedges' angles wA, wB and the free gaps e5 (between A's edge prev->P and B's
            # edge Q->next) and e6 (between B's edge prev->Q and A's edge P->next)
            angles = np.concatenate([a2 - a1, b2 - b1, b1 - a2, a1 - b2]).reshape(4, -1)
            wA, wB, e5, e6 = _wrap(angles, np.array([[0.0], [0.0], [-h1], [-h1]]))
            # the two wedges do not overlap (beyond h1) iff the four angles go once around
            apart = np.abs(wA + wB + e5 + e6 - TWO_PI) < _AROUND
            par5 = apart & (e5 < h1)
            par = par5 | (apart & (e6 < h1))
            k = par.nonzero()[0]
            if len(k):
                # edge-edge: A's edge (prev P, P) parallel to B's edge (Q, next Q) (e5), or A's
                # edge (P, next P) parallel to B's edge (prev Q, Q) (e6). The contact vertex is
                # whichever lies inside the other's edge, A's on a tie (`kernels.TIE`)
                p, q, s5 = P[k], Q[k], par5[k]
                edge_p = np.where(s5, q, prv[q])  # B's edge that P lies on
                edge_q = np.where(s5, prv[p], p)  # A's edge that Q lies on
                tP = geo.edge_param(edge_p, p)
                tQ = geo.edge_param(edge_q, q)
                keep = np.minimum(tP, 1.0 - tP) >= np.minimum(tQ, 1.0 - tQ) - TIE
                v = np.where(keep, p, q)
                e = np.where(keep, edge_p, edge_q)
                # the far end of the vertex's edge that lies along the line
                end = np.where(s5, np.where(keep, prv[p], nxt[q]), np.where(keep, nxt[p], prv[q]))
                # parallel, but a vertex that exits by the edge at the far corner, or lies deeper
                # than d9 (§3.3), goes against both edges at its partner w by the vertex-edge rules
                elsewhere = geo.edge_edge_exit(v, e, np.where(keep, q, p), d9)
                w = np.where(keep, q, p)[elsewhere]
                ve_v += [v[elsewhere], v[elsewhere]]
                ve_e += [prv[w], w]
                ve_check.append(np.zeros(2 * len(w), bool))
                v, e, end = v[~elsewhere], e[~elsewhere], end[~elsewhere]
                out_v.append(v)
                out_e.append(e)
                out_len.append(geo.half_overlap(e, v, end))
            k = (apart & ~par).nonzero()[0]
            if len(k):
                # genuine vertex-vertex: the entrance lines are the edges across the smaller
                # gap (e5 unless e6 is clearly smaller)
                p, q = P[k], Q[k]
                small5 = e5[k] <= e6[k] + h1
                e_p, e_q = np.where(small5, q, prv[q]), np.where(small5, prv[p], p)
                # a vertex behind its entrance line that entered the edge at the line's far
                # corner, or lies beyond d9 (§3.3 rule 3): each vertex against both edges at
                # the other, by the vertex-edge rules
                out = geo.edge_edge_exit(p, e_p, q, d9) | geo.edge_edge_exit(q, e_q, p, d9)
                ve_v += [p[out], p[out], q[out], q[out]]
                ve_e += [prv[q[out]], q[out], prv[p[out]], p[out]]
                ve_check.append(np.zeros(4 * int(out.sum()), bool))
                p, q, e_p, e_q = p[~out], q[~out], e_p[~out], e_q[~out]
                vv_rows.append(np.stack([np.full(len(p), VV), p, e_p, q, e_q], axis=1).astype(np.int32))

    # 2., 3. every near vertex against every edge of the other block, except the edges that
    # end at its mutual-nearest partner
    o = other[side]
    kv, rank = _expand(off[o + 1] - off[o])
    v = vertex[kv]
    e = off[o[kv]] + rank
    mate = partner[kv]
    keep = ((mate != e) & (mate != nxt[e])).nonzero()[0]
    ve_v.append(v[keep])
    ve_e.append(e[keep])
    ve_check.append(np.ones(len(keep), bool))
    v, e = np.concatenate(ve_v), np.concatenate(ve_e)
    ok, length = geo.ve_test(v, e, np.concatenate(ve_check), d0, d9, math.sin(h1))
    out_v.append(v[ok])
    out_e.append(e[ok])
    out_len.append(length)

    v = np.concatenate(out_v)
    ve_rows = np.full((len(v), 5), -1, np.int32)
    ve_rows[:, 0] = VE
    ve_rows[:, 1] = v
    ve_rows[:, 2] = np.concatenate(out_e)
    cint = np.concatenate([ve_rows] + vv_rows)
    length = np.concatenate(out_len + [np.zeros(len(cint) - len(v))])
    return sort_contacts(cint, length)


def detect_contacts(model: Model, vertex_xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Broad + narrow phase in NumPy. Returns (cint, length) in canonical order, as
    ``ddatai.contacts.detect_contacts``."""
    return narrow_phase(model, vertex_xy, broad_phase(model, vertex_xy, model.search_distance))


# --------------------------------------------------------------------------- contact vectors
def _trow(a: np.ndarray, b: np.ndarray, X0: np.ndarray, X1: np.ndarray) -> np.ndarray:
    """a·row 1 + b·row 2 of T(X) (docs/method/dda.md §1.1) at centroidal points X = (X0, X1),
    as (n, 6) (`kernels._trow`)."""
    out = np.empty((len(a), 6))
    out[:, 0] = a
    out[:, 1] = b
    out[:, 2] = b * X0 - a * X1
    out[:, 3] = a * X0
    out[:, 4] = b * X1
    out[:, 5] = 0.5 * (a * X1 + b * X0)
    return out


def contact_vectors(model: Model, vertex_xy: np.ndarray, centroid: np.ndarray, cint: np.ndarray,
                    omega: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Linearised normal and shear distances of every contact line (docs/method/dda.md
    §2.8.1–2.8.4), as `ddatai.kernels.contact_vectors`: ``vec`` (m, N_SLOTS, 6) by
    `ddatai.layout` slot and ``sca`` (m, 3) = (dn0 line 0, dn0 line 1, ds0). Positions are
    taken relative to the contact vertex P1 so that the constant parts keep full precision."""
    m = len(cint)
    vec = np.zeros((m, N_SLOTS, 6))
    sca = np.zeros((m, 3))
    if not m:
        return vec, sca
    nxt, vblock = model.vertex_next, model.vertex_block
    centroid = np.asarray(centroid)
    # every line: line 0 of each contact, then line 1 of each vertex-vertex contact
    vv = (cint[:, 0] == VV).nonzero()[0]
    ve = (cint[:, 0] == VE).nonzero()[0]  # line 0 of contact c is line c
    p1 = np.concatenate([cint[:, 1], cint[vv, 3]])
    k = np.concatenate([cint[:, 2], cint[vv, 4]])
    n = len(p1)
    P1 = vertex_xy[p1]
    x2 = vertex_xy[nxt[k]] - P1
    x3 = vertex_xy[k] - P1
    s = x3 - x2
    l = np.sqrt(s[:, 0] * s[:, 0] + s[:, 1] * s[:, 1])
    cj = centroid[vblock[k]]
    X1, X2, X3 = P1 - centroid[vblock[p1]], x2 + P1 - cj, x3 + P1 - cj
    dn0 = (x2[:, 0] * x3[:, 1] - x2[:, 1] * x3[:, 0]) / l
    sca[:, 0] = dn0[:m]
    sca[vv, 1] = dn0[m:]
    # the coefficients of the rows of T at P1, P2, P3, for all lines in one batch: ∂Δ/∂P1,
    # ∂Δ/∂P2, ∂Δ/∂P3 with P1 at the origin, and for line 0 of a vertex-edge contact the
    # derivatives of ds = (P1 − P0)·(P3 − P2)/l with P0 = (1 − ω)P2 + ωP3 (§2.8.3)
    x2x, x2y, x3x, x3y = x2[:, 0], x2[:, 1], x3[:, 0], x3[:, 1]
    a = [x2y - x3y, x3y, -x2y]
    b = [x3x - x2x, -x3x, x2x]
    at = [X1, X2, X3]
    if len(ve):
        w = omega[ve]
        x2x, x2y, x3x, x3y, sx, sy, le = x2x[ve], x2y[ve], x3x[ve], x3y[ve], s[ve, 0], s[ve, 1], l[ve]
        sca[ve, 2] = ((-(1.0 - w) * x2x - w * x3x) * sx + (-(1.0 - w) * x2y - w * x3y) * sy) / le
        a += [sx / le, (2.0 * (1.0 - w) * x2x - (1.0 - 2.0 * w) * x3x) / le,
              (-(1.0 - 2.0 * w) * x2x - 2.0 * w * x3x) / le]
        b += [sy / le, (2.0 * (1.0 - w) * x2y - (1.0 - 2.0 * w) * x3y) / le,
              (-(1.0 - 2.0 * w) * x2y - 2.0 * w * x3y) / le]
        at += [X1[ve], X2[ve], X3[ve]]
    X = np.concatenate(at)
    rows = _trow(np.concatenate(a), np.concatenate(b), X[:, 0], X[:, 1])
    li = l[:, None]
    e_vec = rows[:n] / li
    g_vec = (rows[n:2 * n] + rows[2 * n:3 * n]) / li
    vec[:, 0], vec[:, 1] = e_vec[:m], g_vec[:m]
    vec[vv, 2], vec[vv, 3] = e_vec[m:], g_vec[m:]
    if len(ve):
        nve = len(ve)
        vec[ve, S_ES] = rows[3 * n:3 * n + nve]
        vec[ve, S_GS] = rows[3 * n + nve:3 * n + 2 * nve] + rows[3 * n + 2 * nve:]
    return vec, sca
