"""The narrow phase of the NumPy contact detection (`ddatai.vectorized`), for small models.

Shi's vertex-edge / vertex-vertex rules (docs/method/dda.md §3.3–3.6) over every candidate of
every block pair at once, operation for operation as `ddatai.kernels.narrow_phase` (the same
guards ``EDGE_FLOOR`` and ``TIE``, the same mutual-nearest-vertex rule, the same entrance-angle
test, the same shortest-exit rule and ``SLACK``), so that it returns the same contacts, kinds,
lines and lengths.

On a model of a few blocks the arrays hold tens of entries and each NumPy call costs ~1 µs
whatever its size, so the phase is written to make few calls rather than little arithmetic:

- the candidates that depend only on the pair set and the blocks' vertex lists (which vertex
  faces which vertices and edges) are built once per pair set (``PairTopology``) and reused while
  the broad phase returns the same pairs, as it does step after step for a resting or slowly
  moving model;
- every vertex of a pair is measured against every edge of the other block in one pass
  (``_Rows``: the normal distance, the projection parameter, the distance to the edge's start).
  The kernel's tests all read from it: the vertex-vertex distances of the mutual-nearest rule
  (an edge is named by its start vertex), the vertex-edge tests (``kernels._ve_test``), the
  shortest-exit rule, which measures the vertex against the edges next to its edge
  (``kernels._nearer_exit``) and against every edge of the block (``kernels._outside_convex``),
  and the vertex pairs' exit tests (``kernels._edge_edge_exit``). The kernel tests every vertex
  against every edge too; this only does it with a few large array operations.
"""

from __future__ import annotations

import math

import numpy as np

from . import side_by_side
from .contacts import PairList, sort_contacts
from .layout import VE, VV
from .model import Model

#: the narrow phase's guards, as `ddatai.kernels` (kept here so that this module does not
#: import Taichi; ``tests/test_vectorized.py`` checks that they agree)
EDGE_FLOOR = 1e-150
EDGE_FLOOR2 = EDGE_FLOOR * EDGE_FLOOR
TIE = 1e-3
SLACK = 1e-9
#: a vertex of a vertex pair that has passed its partner's corner along one of its edges and lies
#: deeper than this share of d9 behind that edge goes to the vertex-edge rules (`_past_corner`)
PASSED_DEPTH = 1e-6
TWO_PI = 2.0 * math.pi
#: the wedges of a vertex pair do not overlap iff their angles and the two gaps sum to 2π
#: within this (`kernels._vertex_vertex`)
_AROUND = 1e-6
#: the lower ends of the wrapped angles wA, wB, e5, e6 of a vertex pair, in units of h1
_WRAP_LOWER = np.array([[0.0], [0.0], [-1.0], [-1.0]])


def _expand(counts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(owner, rank) of the entries of runs of the given lengths: owner k repeated counts[k]
    times, rank 0 … counts[k] − 1 within each run."""
    owner = np.arange(len(counts)).repeat(counts)
    start = counts.cumsum() - counts
    return owner, np.arange(len(owner)) - start[owner]


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


class PairTopology:
    """The candidates of a set of block pairs, which depend only on the pairs and on the blocks'
    vertex lists: built once, reused while the broad phase returns the same pairs.

    A pair's two blocks give two "sides": side s < P holds the vertices of block A of pair s,
    side P + s those of block B; the side vertices are listed side by side (A's sides first),
    each side's vertices in order. A "row" is one side vertex against one edge of the other
    block: every row of a side vertex, its edges in order, then those of the next.
    """

    def __init__(self, model: Model, pairs: np.ndarray):
        self.pairs = pairs.copy()
        self.vertex_next = model.vertex_next  # the vertex lists this was built for (`matches`)
        off = model.vertex_offset.astype(np.int64)
        n_pairs = len(pairs)
        A, B = pairs[:, 0].astype(np.int64), pairs[:, 1].astype(np.int64)
        own, other = np.concatenate([A, B]), np.concatenate([B, A])
        per_side = off[own + 1] - off[own]
        side, rank = _expand(per_side)
        #: (n,) the side vertices, and the block that each faces
        self.vertex = off[own[side]] + rank
        facing = other[side]
        n_edges = off[facing + 1] - off[facing]
        #: (n,) the first row of each side vertex, and the row of (k, edge e) less e
        self.row_start = n_edges.cumsum() - n_edges
        self.row_base = self.row_start - off[facing]
        #: (R,) each row's side position, vertex, edge and the edge's end vertex
        self.row_k, rank = _expand(n_edges)
        self.row_v = self.vertex[self.row_k]
        self.row_e = off[facing[self.row_k]] + rank
        self.row_end = model.vertex_next[self.row_e]
        #: (R,) the rows of the same vertex against the edges before and after the row's edge
        self.row_before = self.row_base[self.row_k] + model.vertex_prev[self.row_e]
        self.row_after = self.row_base[self.row_k] + self.row_end
        #: how many side vertices belong to the A sides
        self.n_a = int(per_side[:n_pairs].sum())
        # the rows of A's vertices are the vertex pairs (an edge is named by its start vertex):
        # the side positions of their B vertices
        self.n_pair_rows = int(n_edges[:self.n_a].sum())
        side_start = per_side.cumsum() - per_side
        b_side = n_pairs + side[self.row_k[:self.n_pair_rows]]
        self.pair_b = side_start[b_side] + self.row_e[:self.n_pair_rows] - off[own[b_side]]

    def matches(self, model: Model, pairs: np.ndarray) -> bool:
        """Whether this is the topology of ``pairs`` in ``model``."""
        return model.vertex_next is self.vertex_next and np.array_equal(pairs, self.pairs)


class NarrowCache:
    """The last pair set's `PairTopology` and the candidate pairs (`ddatai.contacts.PairList`),
    kept between steps (`ddatai.step.Stepper`)."""

    def __init__(self):
        self.topology: PairTopology | None = None
        self.pair_list = PairList()

    def topology_of(self, model: Model, pairs: np.ndarray) -> PairTopology:
        if self.topology is None or not self.topology.matches(model, pairs):
            self.topology = PairTopology(model, pairs)
        return self.topology


class _Rows:
    """Every row's vertex p measured against its edge e, once (`kernels._ve_test`,
    `_nearer_exit`, `_outside_convex`, `_nearest` compute the same, with the same operations):
    P − e's start, its square length, the normal distance dn, and the projection parameter t."""

    def __init__(self, geo: _Geometry, topo: PairTopology):
        v, e = topo.row_v, topo.row_e
        px, py = geo.x[v] - geo.x[e], geo.y[v] - geo.y[e]
        self.d2 = px * px + py * py
        self.dn = px * geo.nx[e] + py * geo.ny[e]
        self.l = geo.length[e]
        self.t = (px * geo.dx[e] + py * geo.dy[e]) / (self.l * self.l)
        self.topo, self.convex = topo, geo.convex

    def nearer_exit(self, row_a: np.ndarray, depth: np.ndarray, c: np.ndarray) -> np.ndarray:
        """Whether the vertices of rows ``row_a``, at normal distances ``depth`` (< 0) from some
        edge, lie less deep behind the line of the row's edge a (or in front of it), projecting
        onto a, or nearer than |depth| to an end of a, where a meets that edge at the convex
        corner c (`kernels._nearer_exit`)."""
        t, dn, d2 = self.t[row_a], self.dn[row_a], depth * depth
        near = ((t < 0.0) & (self.d2[row_a] < d2)) | ((t > 1.0) & (self.d2[self.topo.row_after[row_a]] < d2))
        return self.convex[c] & (((dn > depth) & (t >= -SLACK) & (t <= 1.0 + SLACK)) | near)


def _first_per_group(group: np.ndarray, dist: np.ndarray, index: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """For each group: the entry of smallest ``dist``, the lowest ``index`` on ties
    (`kernels._nearest`). Returns (groups, position of that entry)."""
    order = np.lexsort((index, dist, group))
    g = group[order]
    first = np.ones(len(g), bool)
    first[1:] = g[1:] != g[:-1]
    return g[first], order[first]


def _mutual_nearest(rows: _Rows, topo: PairTopology, d0: float) -> np.ndarray:
    """(n,) the side position of each side vertex's mutual-nearest vertex of the other block
    within d0, −1 where it has none (`kernels._nearest`: |Q − P|, the lowest index on ties)."""
    dist = np.sqrt(rows.d2[:topo.n_pair_rows])
    close = (dist <= d0).nonzero()[0]
    nearest = np.full(len(topo.vertex), -1)
    if not len(close):
        return nearest
    ka, kb, dist = topo.row_k[close], topo.pair_b[close], dist[close]
    g, at = _first_per_group(ka, dist, topo.row_e[close])
    nearest[g] = kb[at]
    g, at = _first_per_group(kb, dist, topo.row_v[close])
    nearest[g] = ka[at]
    has = (nearest >= 0).nonzero()[0]
    nearest[has[nearest[nearest[has]] != has]] = -1
    return nearest


@side_by_side.operation("narrow_phase")
def narrow_phase(model: Model, vertex_xy: np.ndarray, pairs: np.ndarray, cache: NarrowCache | None = None,
                 last_keys: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Contacts of the candidate block pairs (A < B): (cint (m, 5) int32 — kind, vertex0,
    edge0, vertex1, edge1 — and length (m,)), in canonical order (``contacts.sort_contacts``).

    Shi's rules of docs/method/dda.md §3.3–3.6 as `ddatai.kernels.narrow_phase`, over all
    pairs at once: (1) each vertex of A and vertex of B that are mutual nearest within d0 go
    through the vertex-pair rules; (2) every vertex of one block is tested against every edge
    of the other, except the edges that end at its mutual-nearest partner. ``cache`` keeps the
    pairs' topology for the next call.
    """
    pairs = np.asarray(pairs)
    if len(pairs) == 0:
        return np.zeros((0, 5), np.int32), np.zeros(0)
    topo = (cache or NarrowCache()).topology_of(model, pairs)
    d0, d9 = model.search_distance, model.max_penetration
    h1 = math.radians(model.params.angle_tolerance)
    geo = _Geometry(model, vertex_xy)
    rows = _Rows(geo, topo)

    # 1. mutual-nearest vertex pairs within d0: A's vertex P (side position kP), B's Q (kQ)
    nearest = _mutual_nearest(rows, topo, d0)
    kP = (nearest[:topo.n_a] >= 0).nonzero()[0]
    kQ = nearest[kP]
    pairs_ = _VertexPairs(geo, rows, topo.vertex[kP], topo.vertex[kQ], kP, kQ, h1, d9, last_keys, model.n_vertices) \
        if len(kP) else None

    # 2., 3. every vertex against every edge of the other block (its projection on the edge),
    # except the edges that end at its mutual-nearest partner; and the rows that the vertex
    # pairs hand over (no projection test)
    partner = np.where(nearest >= 0, topo.vertex[nearest], -1)[topo.row_k]
    t = rows.t
    candidate = (partner != topo.row_e) & (partner != topo.row_end) & (t >= 0.0) & (t <= 1.0)
    if pairs_ is not None:
        candidate[pairs_.handed_rows] = True
    # a collapsed edge has no normal; a concave vertex never contacts as a vertex
    dn = rows.dn
    k = (candidate & (rows.l > EDGE_FLOOR) & (dn <= d0) & (dn >= -d9) & geo.convex[topo.row_v]).nonzero()[0]
    # behind the edge's line, but nearer the line of the edge that meets it at a convex corner
    # (or in front of it: outside the block): the vertex entered, or lies on, that edge, not
    # this one (§3.3, the shortest exit)
    behind = k[dn[k] < -SLACK * d9]
    if len(behind):
        depth, after = dn[behind], topo.row_after[behind]
        exits = rows.nearer_exit(topo.row_before[behind], depth, topo.row_e[behind]) | \
            rows.nearer_exit(after, depth, topo.row_end[behind])
        # outside the convex block of the edge: in front of (or on) one of its edges' lines
        kb = topo.row_k[behind]
        front = np.logical_or.reduceat(dn > -SLACK * d9, topo.row_start)[kb]
        outside = geo.block_convex[geo.vblock[topo.row_e[behind]]] & front
        drop = np.zeros(len(dn), bool)
        drop[behind[exits | outside]] = True
        k = k[~drop[k]]
    p, e = topo.row_v[k], topo.row_e[k]
    # the vertex's material wedge must lie on the outer side of the edge within h1
    nx, ny = geo.nx[e], geo.ny[e]
    r1n = geo.r1x[p] * nx + geo.r1y[p] * ny
    r2n = geo.r2x[p] * nx + geo.r2y[p] * ny
    sin_h1 = math.sin(h1)
    lim1 = sin_h1 * geo.n1[p]
    lim2 = sin_h1 * geo.n2[p]
    ok = ((r1n >= -lim1) & (r2n >= -lim2)).nonzero()[0]
    p, e, r1n, r2n, lim1, lim2 = p[ok], e[ok], r1n[ok], r2n[ok], lim1[ok], lim2[ok]
    # edge-edge: one of the vertex's edges parallel to the line within h1, the one to the next
    # vertex first (§3.6); and the vertex pairs' edge-edge contacts, in the same call
    along1 = np.abs(r1n) <= lim1
    along = (along1 | (np.abs(r2n) <= lim2)).nonzero()[0]
    v = p[along]
    ends, edges, vertices = [np.where(along1[along], geo.nxt[v], geo.prv[v])], [e[along]], [v]
    vv_rows = []
    if pairs_ is not None:
        ee = (~pairs_.par_elsewhere).nonzero()[0]
        p, e = np.concatenate([p, pairs_.par_v[ee]]), np.concatenate([e, pairs_.par_e[ee]])
        along = np.concatenate([along, len(along1) + np.arange(len(ee))])
        edges.append(pairs_.par_e[ee])
        vertices.append(pairs_.par_v[ee])
        ends.append(pairs_.par_end[ee])
        vv = (~pairs_.vv_elsewhere).nonzero()[0]
        if len(vv):
            vv_rows.append(np.stack([np.full(len(vv), VV), pairs_.vv_p[vv], pairs_.vv_ep[vv],
                                     pairs_.vv_q[vv], pairs_.vv_eq[vv]], axis=1).astype(np.int32))
    length = np.zeros(len(p))
    if len(along):
        length[along] = geo.half_overlap(np.concatenate(edges), np.concatenate(vertices), np.concatenate(ends))
    cint = np.full((len(p), 5), -1, np.int32)
    cint[:, 0] = VE
    cint[:, 1], cint[:, 2] = p, e
    if vv_rows:
        cint = np.concatenate([cint] + vv_rows)
        length = np.concatenate([length, np.zeros(len(vv_rows[0]))])
    return sort_contacts(cint, length)


class _VertexPairs:
    """The mutual-nearest vertex pairs (P of A, Q of B; side positions kP, kQ) sorted by Shi's
    vertex-pair rules (§3.3–3.6), and the rows they hand to the vertex-edge rules.

    - One vertex concave: the convex one goes against both edges meeting at the concave one.
    - Both convex, the wedges apart and one gap below h1 (``par``): edge-edge; the contact vertex
      is whichever lies inside the other's edge, A's on a tie (``TIE``).
    - Both convex, the wedges apart, no gap below h1 (``vv``): vertex-vertex, the entrance lines
      the edges across the smaller gap.
    - A ``par`` vertex, or a ``vv`` vertex, that lies behind its line (beyond round-off) and
      exits by the edge at the line's far corner, or lies deeper than d9 (§3.3 rule 3;
      `kernels._edge_edge_exit`): the vertex pair is no contact, and each vertex goes against
      both edges at its partner by the vertex-edge rules. The edge at the partner is no exit:
      the vertex's own edge lies along the line.
    """

    def __init__(self, geo: _Geometry, rows: _Rows, P, Q, kP, kQ, h1: float, d9: float,
                 last_keys: np.ndarray | None = None, n_vertices: int = 0):
        nxt, prv, topo = geo.nxt, geo.prv, rows.topo
        cP, cQ = geo.convex[P], geo.convex[Q]
        one = (cP != cQ).nonzero()[0]
        one_k = np.where(cP[one], kP[one], kQ[one])
        one_w = np.where(cP[one], Q[one], P[one])
        both = (cP & cQ).nonzero()[0]
        P, Q, kP, kQ = P[both], Q[both], kP[both], kQ[both]
        PQ = np.concatenate([P, Q])
        a1, b1 = np.arctan2(geo.r1y[PQ], geo.r1x[PQ]).reshape(2, -1)
        a2, b2 = np.arctan2(geo.r2y[PQ], geo.r2x[PQ]).reshape(2, -1)
        # the wedges' angles wA, wB and the free gaps e5 (between A's edge prev->P and B's
        # edge Q->next) and e6 (between B's edge prev->Q and A's edge P->next)
        angles = np.concatenate([a2 - a1, b2 - b1, b1 - a2, a1 - b2]).reshape(4, -1)
        wA, wB, e5, e6 = _wrap(angles, _WRAP_LOWER * h1)
        # the two wedges do not overlap (beyond h1) iff the four angles go once around
        apart = np.abs(wA + wB + e5 + e6 - TWO_PI) < _AROUND
        par5 = apart & (e5 < h1)
        par = par5 | (apart & (e6 < h1))
        # edge-edge: A's edge (prev P, P) parallel to B's edge (Q, next Q) (e5), or A's edge
        # (P, next P) parallel to B's edge (prev Q, Q) (e6)
        k = par.nonzero()[0]
        p, q, s5 = P[k], Q[k], par5[k]
        edge_p = np.where(s5, q, prv[q])  # B's edge that P lies on
        edge_q = np.where(s5, prv[p], p)  # A's edge that Q lies on
        tP = geo.edge_param(edge_p, p)
        tQ = geo.edge_param(edge_q, q)
        keep = np.minimum(tP, 1.0 - tP) >= np.minimum(tQ, 1.0 - tQ) - TIE
        self.par_v, self.par_e = np.where(keep, p, q), np.where(keep, edge_p, edge_q)
        par_k, par_w = np.where(keep, kP[k], kQ[k]), np.where(keep, q, p)
        # the far end of the vertex's edge that lies along the line
        self.par_end = np.where(s5, np.where(keep, prv[p], nxt[q]), np.where(keep, nxt[p], prv[q]))
        # vertex-vertex: the entrance lines are the edges across the smaller gap (e5 unless e6
        # is clearly smaller)
        k = (apart & ~par).nonzero()[0]
        self.vv_p, self.vv_q = p, q = P[k], Q[k]
        kp, kq = kP[k], kQ[k]
        small5 = e5[k] <= e6[k] + h1
        self.vv_ep, self.vv_eq = np.where(small5, q, prv[q]), np.where(small5, prv[p], p)
        # the exit tests: each edge-edge vertex on its edge, each vertex-vertex vertex on its
        # entrance line; w: the partner, an end of that edge
        exit_k = np.concatenate([par_k, kp, kq])
        exit_e = np.concatenate([self.par_e, self.vv_ep, self.vv_eq])
        exit_w = np.concatenate([par_w, q, p])
        r = topo.row_base[exit_k] + exit_e
        depth = rows.dn[r]
        out = depth < -SLACK * d9
        o = out.nonzero()[0]
        r, depth, at_start = r[o], depth[o], exit_w[o] == exit_e[o]
        far = np.where(at_start, topo.row_after[r], topo.row_before[r])  # the edge at the far corner
        out[o] = rows.nearer_exit(far, depth, np.where(at_start, topo.row_e[far], exit_e[o])) | (depth < -d9)
        n_par, n_vv = len(par_k), len(kp)
        self.par_elsewhere = out[:n_par]
        # and a vertex that has passed its partner's corner along one of its edges
        self.vv_elsewhere = out[n_par:n_par + n_vv] | out[n_par + n_vv:] | \
            _past_corner(rows, kp, q, prv, d9, math.sin(h1)) | _past_corner(rows, kq, p, prv, d9, math.sin(h1))
        if last_keys is not None and len(last_keys) and n_vv:
            # a pair handed over last step stays handed over while either vertex lies past its
            # partner at all, on or behind the edge's line (hysteresis): pushed out by its vertex-edge contact to within
            # PASSED_DEPTH x d9, it went back to one vertex-vertex contact, whose one line let
            # the other vertex sink, to be handed over again the step after (docs/method/dda.md
            # §3.4). Handed over: a vertex was in a vertex-edge contact (key vertex·n + edge) on
            # an edge at its partner, (w, next w) or (prev w, w)
            nv = np.int64(n_vertices)
            p64, q64 = p.astype(np.int64), q.astype(np.int64)
            keys = np.stack([p64 * nv + q64, p64 * nv + prv[q], q64 * nv + p64, q64 * nv + prv[p]])
            at = np.minimum(np.searchsorted(last_keys, keys), len(last_keys) - 1)
            was = (last_keys[at] == keys).any(axis=0) & ~self.vv_elsewhere
            if was.any():
                w = was.nonzero()[0]
                self.vv_elsewhere[w] = _past_corner(rows, kp[w], q[w], prv, d9, math.sin(h1), persist=True) | \
                    _past_corner(rows, kq[w], p[w], prv, d9, math.sin(h1), persist=True)
        # the handed-over rows: the concave pairs' convex vertices, and the exits' vertices
        handed = np.concatenate([np.ones(len(one), bool), self.par_elsewhere, self.vv_elsewhere,
                                 self.vv_elsewhere]).nonzero()[0]
        hand_k = np.concatenate([one_k, exit_k])[handed]
        hand_w = np.concatenate([one_w, exit_w])[handed]
        base = topo.row_base[hand_k]
        self.handed_rows = np.concatenate([base + prv[hand_w], base + hand_w])


def _past_corner(rows: _Rows, k: np.ndarray, w: np.ndarray, prv: np.ndarray, d9: float, sin_h1: float,
                 persist: bool = False) -> np.ndarray:
    """Whether each vertex (side position k) of a vertex-vertex pair has passed its partner w's
    corner along an edge at w: it projects onto the edge (w, next w) or (prev w, w) beyond
    round-off from w and lies deeper than ``PASSED_DEPTH`` × d9 behind that edge's line, but
    within the angle tolerance h1 of it seen from w: it slid past the corner along the edge,
    where a corner that entered head on lies as far behind as along (`kernels._past_corner`).
    The corners of diagonal blocks where four squares meet pass each other as soon as a row
    slides: each then lies on the other's edge, two vertex-edge contacts that one
    vertex-vertex contact, acting on one line, cannot hold. The vertex
    left out sank unresisted (36 µm, or 24 µm after a 3.9 mm slide) until the pair's lines
    changed, and its depth was pushed out in one step: a 0.1 m square at 0.04–0.08 m/s in
    a 0.27 ms step (docs/method/dda.md §3.4).

    ``persist``: whether a vertex of a pair handed over last step still lies past its partner
    at all: it projects onto the edge beyond round-off (``SLACK``) from w and lies on or behind
    the edge's line, within h1 of it, at any depth (`narrow_phase`, ``last_keys``). A vertex
    clear of the line ends it: a shrinking edge-to-edge contact whose block lifts off keeps no
    open vertex-edge contact at the edge's end (ntdda's push block, tests/test_ntdda.py)."""
    base = rows.topo.row_base[k]
    if persist:
        r0, r1 = base + w, base + prv[w]
        t0, t1 = rows.t[r0], rows.t[r1]
        along0, along1 = t0 * rows.l[r0], (1.0 - t1) * rows.l[r1]
        dn0, dn1 = rows.dn[r0], rows.dn[r1]
        return ((t0 > SLACK) & (t0 <= 1.0) & (dn0 <= 0.0) & (-dn0 < sin_h1 * along0)) | \
            ((1.0 - t1 > SLACK) & (t1 >= 0.0) & (dn1 <= 0.0) & (-dn1 < sin_h1 * along1))
    deep = -PASSED_DEPTH * d9
    r0, r1 = base + w, base + prv[w]      # the edges (w, next w), w at t = 0, and (prev w, w)
    t0, l0, dn0 = rows.t[r0], rows.l[r0], rows.dn[r0]
    t1, l1, dn1 = rows.t[r1], rows.l[r1], rows.dn[r1]
    along0, along1 = t0 * l0, (1.0 - t1) * l1
    return ((t0 > TIE) & (t0 <= 1.0) & (dn0 < deep) & (-dn0 < sin_h1 * along0)) | \
        ((1.0 - t1 > TIE) & (t1 >= 0.0) & (dn1 < deep) & (-dn1 < sin_h1 * along1))
