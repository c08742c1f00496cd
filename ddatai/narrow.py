"""The narrow phase of the NumPy contact detection (`ddatai.vectorized`), for small models.

Shi's vertex-edge / vertex-vertex rules (docs/method/dda.md §3.3–3.6) over every candidate of
every block pair at once, operation for operation as `ddatai.kernels.narrow_phase` (the same
guards ``EDGE_FLOOR`` and ``TIE``, the same mutual-nearest-vertex rule, the same entrance-angle
test, the same shortest-exit rule and ``SLACK``), so that it returns the same contacts, kinds,
lines and lengths.

On a model of a few blocks the arrays hold tens of entries and each NumPy call costs ~1 µs
whatever its size, so the phase is written to make few calls rather than little arithmetic:

- the candidates that depend only on the pair set and the blocks' vertex lists (which vertex
  faces which vertices and edges) are built once per pair set (`PairTopology`) and reused while
  the broad phase returns the same pairs, as it does step after step for a resting or slowly
  moving model;
- all vertex-edge candidates go through one test (`_vertex_edge`): those of every vertex
  against the edges of the other block, and those that a vertex pair hands to the vertex-edge
  rules (a concave vertex of the pair, or a vertex that exits elsewhere), with the vertex
  pairs' exit tests in the same arithmetic: the hand-over candidates are measured whether the
  pair hands them over or not, and go on to the costlier tests where it does.
"""

from __future__ import annotations

import math

import numpy as np

from .contacts import box_bounds, sort_contacts
from .layout import VE, VV
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


class PairTopology:
    """The candidates of a set of block pairs, which depend only on the pairs and on the blocks'
    vertex lists: built once, reused while the broad phase returns the same pairs.

    A pair's two blocks give two "sides": side s < P holds the vertices of block A of pair s,
    side P + s those of block B; the side vertices are listed side by side.
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
        self.facing = other[side]
        #: how many side vertices belong to the A sides (they come first)
        self.n_a = int(per_side[:n_pairs].sum())
        # vertex pairs: every vertex of A against every vertex of B of the same pair (positions
        # in the side list, and the vertices)
        side_start = per_side.cumsum() - per_side
        self.pair_a, rank = _expand(per_side[n_pairs + side[:self.n_a]])
        self.pair_b = side_start[n_pairs + side[self.pair_a]] + rank
        self.pair_va, self.pair_vb = self.vertex[self.pair_a], self.vertex[self.pair_b]
        # vertex-edge: every side vertex against every edge of the block it faces (the side
        # position of the vertex, the vertex, the edge and the edge's end vertex)
        self.edge_k, rank = _expand(off[self.facing + 1] - off[self.facing])
        self.edge_v = self.vertex[self.edge_k]
        self.edge_e = off[self.facing[self.edge_k]] + rank
        self.edge_end = model.vertex_next[self.edge_e]

    def matches(self, model: Model, pairs: np.ndarray) -> bool:
        """Whether this is the topology of ``pairs`` in ``model``."""
        return model.vertex_next is self.vertex_next and np.array_equal(pairs, self.pairs)


class NarrowCache:
    """The last pair set's `PairTopology`, kept between steps (`ddatai.step.Stepper`)."""

    def __init__(self):
        self.topology: PairTopology | None = None

    def topology_of(self, model: Model, pairs: np.ndarray) -> PairTopology:
        if self.topology is None or not self.topology.matches(model, pairs):
            self.topology = PairTopology(model, pairs)
        return self.topology


def _first_per_group(group: np.ndarray, dist: np.ndarray, index: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """For each group: the entry of smallest ``dist``, the lowest ``index`` on ties
    (`kernels._nearest`). Returns (groups, position of that entry)."""
    order = np.lexsort((index, dist, group))
    g = group[order]
    first = np.ones(len(g), bool)
    first[1:] = g[1:] != g[:-1]
    return g[first], order[first]


def _mutual_nearest(geo: _Geometry, topo: PairTopology, d0: float) -> np.ndarray:
    """(n,) the side position of each side vertex's mutual-nearest vertex of the other block
    within d0, −1 where it has none (`kernels._nearest`: |Q − P|, the lowest index on ties)."""
    va, vb = topo.pair_va, topo.pair_vb
    dx = geo.x[vb] - geo.x[va]
    dy = geo.y[vb] - geo.y[va]
    dist = np.sqrt(dx * dx + dy * dy)
    close = (dist <= d0).nonzero()[0]
    nearest = np.full(len(topo.vertex), -1)
    if not len(close):
        return nearest
    ka, kb, dist = topo.pair_a[close], topo.pair_b[close], dist[close]
    g, at = _first_per_group(ka, dist, vb[close])
    nearest[g] = kb[at]
    g, at = _first_per_group(kb, dist, va[close])
    nearest[g] = ka[at]
    has = (nearest >= 0).nonzero()[0]
    nearest[has[nearest[nearest[has]] != has]] = -1
    return nearest


def narrow_phase(model: Model, vertex_xy: np.ndarray, pairs: np.ndarray, cache: NarrowCache | None = None
                 ) -> tuple[np.ndarray, np.ndarray]:
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
    nxt, prv = model.vertex_next, model.vertex_prev
    geo = _Geometry(model, vertex_xy)
    vertex = topo.vertex

    # 1. mutual-nearest vertex pairs within d0, A's vertex P and B's vertex Q
    nearest = _mutual_nearest(geo, topo, d0)
    pa = (nearest[:topo.n_a] >= 0).nonzero()[0]
    P, Q = vertex[pa], vertex[nearest[pa]]
    partner = np.where(nearest >= 0, vertex[nearest], -1)
    handoff = _VertexPairs(geo, P, Q, h1, nxt, prv) if len(pa) else None

    # 2., 3. every side vertex near the other block's box against every edge of that block,
    # except the edges that end at its mutual-nearest partner. A vertex accepted against an
    # edge lies within max(d0, d9) of it (projection on the edge, dn in [−d9, d0]): every
    # accepted candidate is among these. The margin is 1.5× that reach so that round-off
    # cannot drop one; the exact tests follow.
    lo, hi = box_bounds(model, vertex_xy, 1.5 * max(d0, d9))
    xy, facing = vertex_xy[vertex], topo.facing
    near = ((xy >= lo[facing]) & (xy <= hi[facing])).all(axis=1)
    k, mate = topo.edge_k, partner[topo.edge_k]
    keep = (near[k] & (mate != topo.edge_e) & (mate != topo.edge_end)).nonzero()[0]
    v, e = topo.edge_v[keep], topo.edge_e[keep]
    ok, length, ee = _vertex_edge(geo, v, e, handoff, d0, d9, math.sin(h1))
    # the accepted candidates: the tested vertex-edge ones, then the edge-edge contacts of the
    # vertex pairs, then their vertex-vertex contacts
    if handoff is not None:
        v, e = np.concatenate([v, handoff.ve_v]), np.concatenate([e, handoff.ve_e])
    cint = np.full((len(ok) + len(ee), 5), -1, np.int32)
    cint[:, 0] = VE
    cint[:len(ok), 1], cint[:len(ok), 2] = v[ok], e[ok]
    if len(ee):
        cint[len(ok):, 1], cint[len(ok):, 2] = handoff.par_v[ee], handoff.par_e[ee]
    if handoff is not None and len(handoff.vv_p):
        vv = ~handoff.vv_elsewhere
        rows = np.stack([np.full(int(vv.sum()), VV), handoff.vv_p[vv], handoff.vv_ep[vv],
                         handoff.vv_q[vv], handoff.vv_eq[vv]], axis=1).astype(np.int32)
        cint = np.concatenate([cint, rows])
        length = np.concatenate([length, np.zeros(len(rows))])
    return sort_contacts(cint, length)


class _VertexPairs:
    """The mutual-nearest vertex pairs (P of A, Q of B) sorted by Shi's vertex-pair rules
    (§3.3–3.6), and what they hand to the vertex-edge rules.

    - One vertex concave: the convex one goes against both edges meeting at the concave one.
    - Both convex, the wedges apart and one gap below h1 (``par``): edge-edge; the contact vertex
      is whichever lies inside the other's edge, A's on a tie (``TIE``).
    - Both convex, the wedges apart, no gap below h1 (``vv``): vertex-vertex, the entrance lines
      the edges across the smaller gap.
    - A ``par`` vertex, or a ``vv`` vertex, that lies behind its line and exits by the edge at the
      line's far corner, or lies deeper than d9 (§3.3 rule 3): the vertex pair is no contact,
      each such vertex goes against both edges at its partner by the vertex-edge rules.

    The hand-over candidates (``ve_v``, ``ve_e``: every vertex v of ``hand_v`` against both
    edges at its partner w) are listed whether the pair hands them over or not; `handed` says
    which, once the exit tests (``exit_v``, ``exit_e``, ``exit_w``) are known.
    """

    def __init__(self, geo: _Geometry, P: np.ndarray, Q: np.ndarray, h1: float, nxt, prv):
        cP, cQ = geo.convex[P], geo.convex[Q]
        one = (cP != cQ).nonzero()[0]
        one_v = np.where(cP[one], P[one], Q[one])
        one_w = np.where(cP[one], Q[one], P[one])
        both = (cP & cQ).nonzero()[0]
        P, Q = P[both], Q[both]
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
        self.par_v = np.where(keep, p, q)
        self.par_e = np.where(keep, edge_p, edge_q)
        par_w = np.where(keep, q, p)
        # the far end of the vertex's edge that lies along the line
        self.par_end = np.where(s5, np.where(keep, prv[p], nxt[q]), np.where(keep, nxt[p], prv[q]))
        # vertex-vertex: the entrance lines are the edges across the smaller gap (e5 unless e6
        # is clearly smaller)
        k = (apart & ~par).nonzero()[0]
        self.vv_p, self.vv_q = p, q = P[k], Q[k]
        small5 = e5[k] <= e6[k] + h1
        self.vv_ep, self.vv_eq = np.where(small5, q, prv[q]), np.where(small5, prv[p], p)
        # the exit tests: each edge-edge vertex on its edge, each vertex-vertex vertex on its
        # entrance line; w: the partner, an end of that edge
        self.exit_v = np.concatenate([self.par_v, p, q])
        self.exit_e = np.concatenate([self.par_e, self.vv_ep, self.vv_eq])
        exit_w = np.concatenate([par_w, q, p])
        # the hand-over candidates: the concave pairs' convex vertices, then the exit tests'
        hand_v = np.concatenate([one_v, self.exit_v])
        hand_w = np.concatenate([one_w, exit_w])
        self.exit_w = exit_w
        self.n_one, self.n_par = len(one), len(self.par_v)
        self.ve_v = np.concatenate([hand_v, hand_v])
        self.ve_e = np.concatenate([prv[hand_w], hand_w])

    def handed(self, elsewhere: np.ndarray) -> np.ndarray:
        """Which hand-over candidates the pairs hand over, given which exit tests' vertices
        exit elsewhere (or lie deeper than d9); sets ``par_elsewhere`` and ``vv_elsewhere``."""
        n_par, n_vv = self.n_par, len(self.vv_p)
        self.par_elsewhere = elsewhere[:n_par]
        self.vv_elsewhere = elsewhere[n_par:n_par + n_vv] | elsewhere[n_par + n_vv:]
        hand = np.concatenate([np.ones(self.n_one, bool), self.par_elsewhere, self.vv_elsewhere,
                               self.vv_elsewhere])
        return np.concatenate([hand, hand])


def _vertex_edge(geo: _Geometry, p: np.ndarray, e: np.ndarray, pairs: _VertexPairs | None, d0: float,
                 d9: float, sin_h1: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Distance and entrance-angle criteria (§3.3, §3.4; `kernels._ve_test`) of vertices p
    against edges e, whose projection on the edge must fall on it, and of the vertex pairs'
    hand-over candidates (no projection test), with the pairs' exit tests.

    Returns (positions of the accepted candidates among [p, pairs.ve_v], their contact lengths
    L — half the overlap of an edge-edge contact, else 0 — followed by the lengths of the
    pairs' edge-edge contacts, and the positions of those among ``pairs.par_v``)."""
    n_test = n_ve = len(p)
    if pairs is not None:
        n_ve += len(pairs.ve_v)
        p = np.concatenate([p, pairs.ve_v, pairs.exit_v])
        e = np.concatenate([e, pairs.ve_e, pairs.exit_e])
    x, y = geo.x, geo.y
    l = geo.length[e]
    nx, ny = geo.nx[e], geo.ny[e]
    px, py = x[p] - x[e], y[p] - y[e]
    dn = px * nx + py * ny
    t = (px * geo.dx[e] + py * geo.dy[e]) / (l * l)
    on_edge = (t >= 0.0) & (t <= 1.0)
    on_edge[n_test:] = True
    # a collapsed edge has no normal; a concave vertex never contacts as a vertex
    k = ((l[:n_ve] > EDGE_FLOOR) & (dn[:n_ve] <= d0) & (dn[:n_ve] >= -d9) & geo.convex[p[:n_ve]] &
         on_edge[:n_ve]).nonzero()[0]
    if pairs is not None:
        # the pairs' exit tests first: a vertex behind its edge's line (beyond round-off) that
        # exits by the edge at the far corner (the edge at the partner w is no exit: the
        # vertex's own edge lies along the line), or lies deeper than d9, is handed over; the
        # candidates not handed over go no further
        exit_dn = dn[n_ve:]
        out = exit_dn < -SLACK * d9
        q = out.nonzero()[0]
        eq, at_start = pairs.exit_e[q], pairs.exit_w[q] == pairs.exit_e[q]
        far = np.where(at_start, geo.nxt[eq], geo.prv[eq])  # the edge at e's far corner
        out[q] = geo.nearer_exit(pairs.exit_v[q], exit_dn[q], far, np.where(at_start, far, eq)) | \
            (exit_dn[q] < -d9)
        k = k[np.concatenate([np.ones(n_test, bool), pairs.handed(out)])[k]]
    # behind the edge's line, but nearer the line of the edge that meets it at a convex corner
    # (or in front of it: outside the block): the vertex entered, or lies on, that edge, not
    # this one (§3.3, the shortest exit)
    behind = (dn[k] < -SLACK * d9).nonzero()[0]
    if len(behind):
        pb, eb, depth = p[k[behind]], e[k[behind]], dn[k[behind]]
        # the edges before and after e in one call (halves of its result)
        n, after = len(eb), geo.nxt[eb]
        exits = geo.nearer_exit(np.concatenate([pb, pb]), np.concatenate([depth, depth]),
                                np.concatenate([geo.prv[eb], after]), np.concatenate([eb, after]))
        keep = np.ones(len(k), bool)
        keep[behind[exits[:n] | exits[n:] | geo.outside_convex(pb, eb, SLACK * d9)]] = False
        k = k[keep]
    p, e, nx, ny = p[k], e[k], nx[k], ny[k]
    # the vertex's material wedge must lie on the outer side of the edge within h1
    r1n = geo.r1x[p] * nx + geo.r1y[p] * ny
    r2n = geo.r2x[p] * nx + geo.r2y[p] * ny
    lim1 = sin_h1 * geo.n1[p]
    lim2 = sin_h1 * geo.n2[p]
    ok = ((r1n >= -lim1) & (r2n >= -lim2)).nonzero()[0]
    p, e, r1n, r2n, lim1, lim2 = p[ok], e[ok], r1n[ok], r2n[ok], lim1[ok], lim2[ok]
    # edge-edge: one of the vertex's edges parallel to the line within h1, the one to the next
    # vertex first (§3.6); and the pairs' edge-edge contacts, in the same call
    along1 = np.abs(r1n) <= lim1
    along = (along1 | (np.abs(r2n) <= lim2)).nonzero()[0]
    v = p[along]
    ends = [np.where(along1[along], geo.nxt[v], geo.prv[v])]
    edges, vertices = [e[along]], [v]
    ee = np.zeros(0, np.int64)
    if pairs is not None:
        ee = (~pairs.par_elsewhere).nonzero()[0]
        edges.append(pairs.par_e[ee])
        vertices.append(pairs.par_v[ee])
        ends.append(pairs.par_end[ee])
    length = np.zeros(len(p) + len(ee))
    if len(length):
        along = np.concatenate([along, len(p) + np.arange(len(ee))])
        length[along] = geo.half_overlap(np.concatenate(edges), np.concatenate(vertices), np.concatenate(ends))
    return k[ok], length, ee
