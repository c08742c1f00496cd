"""Taichi kernels: broad phase, narrow phase (Shi's contact rules), contact vectors, assembly.

Importing this module imports Taichi (it is loaded only when a simulation runs); kernels
compile on first call after `ddatai.backend.ensure`. Every kernel works on NumPy arrays
passed as ``ti.types.ndarray`` (no copies on the CPU backend) and has a plain NumPy twin in
:mod:`ddatai.reference`; tests compare the two.

Conventions (see :mod:`ddatai.model`): block b owns vertices ``voff[b]:voff[b+1]`` in CCW
order, edge k runs from vertex k to ``vnext[k]``. A vertex-edge contact of vertex P1 against
edge k uses the reference line P2 = vnext[k] -> P3 = k, which runs clockwise around the edge's
block, so that the signed normal distance is positive outside (docs/method/dda.md §2.8.1, §3.5).

Contact vectors are stored per contact c in ``vec[c, s, 0:6]`` with slots
``E0, G0`` (normal, line 0), ``E1, G1`` (normal, line 1 of a vertex-vertex contact) and
``ES, GS`` (shear, line 0: the gradient of ds, along which both the shear spring and the
friction force act), and the constant parts in ``sca[c, 0:3]`` = (dn0 line 0, dn0 line 1, ds0);
see docs/method/dda.md §2.8.
"""

import math

import taichi as ti

F64_1 = ti.types.ndarray(dtype=ti.f64, ndim=1)
F64_2 = ti.types.ndarray(dtype=ti.f64, ndim=2)
F64_3 = ti.types.ndarray(dtype=ti.f64, ndim=3)
I32_1 = ti.types.ndarray(dtype=ti.i32, ndim=1)
I32_2 = ti.types.ndarray(dtype=ti.i32, ndim=2)
I8_1 = ti.types.ndarray(dtype=ti.i8, ndim=1)
I8_2 = ti.types.ndarray(dtype=ti.i8, ndim=2)

KIND_VE = 0
KIND_VV = 1
STATE_OPEN = 0
STATE_SLIDE = 1
STATE_LOCK = 2
# slots of the contact vector array
E0, G0, E1, G1, ES, GS = 0, 1, 2, 3, 4, 5
N_SLOTS = 6
TWO_PI = 2.0 * math.pi
#: guards of the narrow phase: an edge this short (or its square) is collapsed — it gets no
#: contact and divides by this instead of 0 (input checks make every edge ≥ 1e-12 of the block)
EDGE_FLOOR = 1e-150
EDGE_FLOOR2 = EDGE_FLOOR * EDGE_FLOOR
#: When the corners of two parallel edges (nearly) coincide, either corner can be the contact
#: vertex; block A's is kept unless B's lies clearly (TIE × edge length) further inside the
#: other edge. Without this the choice follows round-off and the contact's identity, and with
#: it its memory, changes from step to step (aligned grids: every X-junction).
TIE = 1e-3


# --------------------------------------------------------------------------- helpers
@ti.func
def _pt(xy: ti.template(), i):
    return ti.Vector([xy[i, 0], xy[i, 1]])


@ti.func
def _cross(a, b):
    return a[0] * b[1] - a[1] * b[0]


@ti.func
def _wrap(angle, lower):
    """angle wrapped into [lower, lower + 2π)."""
    return angle - TWO_PI * ti.floor((angle - lower) / TWO_PI)


@ti.func
def _edge_param(xy: ti.template(), vnext: ti.template(), e, p):
    """Projection parameter of vertex p on edge e (0 at its start, 1 at its end)."""
    q0 = _pt(xy, e)
    d = _pt(xy, vnext[e]) - q0
    # a collapsed edge (zero length) projects everything to its start instead of dividing by 0
    return (_pt(xy, p) - q0).dot(d) / ti.max(d.dot(d), EDGE_FLOOR2)


@ti.func
def _half_overlap(xy: ti.template(), vnext: ti.template(), e, a, b):
    """Half the length of the overlap of segment (a, b) projected on edge e (§3.6)."""
    q0 = _pt(xy, e)
    d = _pt(xy, vnext[e]) - q0
    l2 = ti.max(d.dot(d), EDGE_FLOOR2)
    ta = (_pt(xy, a) - q0).dot(d) / l2
    tb = (_pt(xy, b) - q0).dot(d) / l2
    lo = ti.max(0.0, ti.min(ta, tb))
    hi = ti.min(1.0, ti.max(ta, tb))
    return 0.5 * ti.max(0.0, hi - lo) * ti.sqrt(l2)


@ti.func
def _convex(xy: ti.template(), vnext: ti.template(), vprev: ti.template(), p):
    P = _pt(xy, p)
    return _cross(_pt(xy, vnext[p]) - P, _pt(xy, vprev[p]) - P) > 0.0


@ti.func
def _nearer_exit(xy: ti.template(), vnext: ti.template(), vprev: ti.template(), P, depth, a, c):
    """Whether point P, at normal distance ``depth`` (< 0) from an edge, lies less deep behind
    the line of edge a (or in front of it), projecting onto a, or nearer than |depth| to an end
    of a, where a meets that edge at the convex corner c (`narrow._Rows.nearer_exit`)."""
    q0 = _pt(xy, a)
    q1 = _pt(xy, vnext[a])
    d = q1 - q0
    l = ti.max(d.norm(), EDGE_FLOOR)
    t = (P - q0).dot(d) / (l * l)
    dn = (P - q0).dot(ti.Vector([d[1], -d[0]]) / l)
    r0 = P - q0
    r1 = P - q1
    # or nearer than ``depth`` to an end of a (past it: a cut's shared corner, moved a hair)
    near = (t < 0.0 and r0[0] * r0[0] + r0[1] * r0[1] < depth * depth) or \
        (t > 1.0 and r1[0] * r1[0] + r1[1] * r1[1] < depth * depth)
    return _convex(xy, vnext, vprev, c) and ((dn > depth and t >= -SLACK and t <= 1.0 + SLACK) or near)


#: round-off slack of the shortest-exit rule (§3.3 rule 3): of d9 for a vertex on an edge's
#: line, of the edge for its projection (a cut's shared vertex lies on its neighbours' lines
#: and at their ends, to round-off)
SLACK = 1e-9


@ti.func
def _outside_convex(xy: ti.template(), vnext: ti.template(), vprev: ti.template(), P, e, slack):
    """Whether point P lies in front of some edge of the convex block of edge e (or on its line,
    within ``slack``): outside it, or on its boundary (`narrow.narrow_phase`)."""
    convex = _convex(xy, vnext, vprev, e)
    front = 0
    j = vnext[e]
    while j != e:
        q0 = _pt(xy, j)
        d = _pt(xy, vnext[j]) - q0
        l = ti.max(d.norm(), EDGE_FLOOR)
        if (P - q0).dot(ti.Vector([d[1], -d[0]]) / l) > -slack:
            front = 1
        if not _convex(xy, vnext, vprev, j):
            convex = 0
        j = vnext[j]
    return convex and front == 1


@ti.func
def _edge_edge_exit(xy: ti.template(), vnext: ti.template(), vprev: ti.template(), p, e, w, d9):
    """Whether vertex p, put on edge e by the edge-edge rule of the vertex pair (p, w), w an end
    of e, lies behind e's line (beyond round-off) but less deep behind (or in front of) the
    line of the edge meeting e at its far, convex corner, projecting onto it (it entered that
    edge: §3.3 rule 3), or deeper than d9 (the window of rule 2): no contact of e
    (`narrow._VertexPairs`). The edge at w is no exit: p's own edge lies along
    e, so p cannot have entered that edge."""
    q0 = _pt(xy, e)
    d = _pt(xy, vnext[e]) - q0
    l = ti.max(d.norm(), EDGE_FLOOR)
    P = _pt(xy, p)
    dn = (P - q0).dot(ti.Vector([d[1], -d[0]]) / l)
    a = vprev[e]
    c = e
    if w == e:
        a = vnext[e]
        c = vnext[e]
    out = 0
    if dn < -SLACK * d9:
        if _nearer_exit(xy, vnext, vprev, P, dn, a, c) or dn < -d9:
            out = 1
    return out


@ti.func
def _ve_test(xy: ti.template(), vnext: ti.template(), vprev: ti.template(), p, e,
             d0, d9, sin_h1, check_projection):
    """Distance and entrance-angle criteria for vertex p against edge e (§3.3, §3.4).

    Returns (accepted, contact length L of an edge-edge contact or 0).
    """
    q0 = _pt(xy, e)
    d = _pt(xy, vnext[e]) - q0
    l = ti.max(d.norm(), EDGE_FLOOR)
    P = _pt(xy, p)
    t = (P - q0).dot(d) / (l * l)
    n = ti.Vector([d[1], -d[0]]) / l  # outward normal of a CCW edge
    dn = (P - q0).dot(n)
    ok = 1
    if l <= EDGE_FLOOR:  # a collapsed edge has no normal: no contact (reference.narrow_phase)
        ok = 0
    if check_projection != 0:
        if t < 0.0 or t > 1.0:
            ok = 0
    if dn > d0 or dn < -d9:
        ok = 0
    if dn < -SLACK * d9 and ok == 1:
        # behind the edge's line, but nearer the line of the edge that meets it at a convex
        # corner (or in front of it: outside the block): the vertex entered, or lies on, that
        # edge, not this one (§3.3, the shortest exit)
        if _nearer_exit(xy, vnext, vprev, P, dn, vprev[e], e) or \
                _nearer_exit(xy, vnext, vprev, P, dn, vnext[e], vnext[e]) or \
                _outside_convex(xy, vnext, vprev, P, e, SLACK * d9):
            ok = 0
    r1 = _pt(xy, vnext[p]) - P
    r2 = _pt(xy, vprev[p]) - P
    n1 = r1.norm()
    n2 = r2.norm()
    # a concave vertex never contacts as a vertex; the vertex's material wedge must lie on the
    # outer side of the edge within the angle tolerance h1
    if _cross(r1, r2) <= 0.0:
        ok = 0
    if r1.dot(n) < -sin_h1 * n1 or r2.dot(n) < -sin_h1 * n2:
        ok = 0
    length = 0.0
    if ok == 1:
        if ti.abs(r1.dot(n)) <= sin_h1 * n1:
            length = _half_overlap(xy, vnext, e, p, vnext[p])
        elif ti.abs(r2.dot(n)) <= sin_h1 * n2:
            length = _half_overlap(xy, vnext, e, p, vprev[p])
    return ok, length


@ti.func
def _emit(out_int: ti.template(), out_len: ti.template(), count: ti.template(),
          kind, v0, e0, v1, e1, length):
    k = ti.atomic_add(count[0], 1)
    if k < out_int.shape[0]:
        out_int[k, 0] = kind
        out_int[k, 1] = v0
        out_int[k, 2] = e0
        out_int[k, 3] = v1
        out_int[k, 4] = e1
        out_len[k] = length


@ti.func
def _nearest(xy: ti.template(), P, lo, hi, limit):
    """Index of the vertex in [lo, hi) nearest to P within `limit` (ties: lowest index), or -1."""
    best = -1
    best_d = limit
    for k in range(lo, hi):
        dist = (_pt(xy, k) - P).norm()
        if dist < best_d or (dist == best_d and best == -1):
            best = k
            best_d = dist
    return best


@ti.func
def _vertex_vertex(xy: ti.template(), vnext: ti.template(), vprev: ti.template(), ia, ib,
                   d0, d9, sin_h1, h1, out_int: ti.template(), out_len: ti.template(),
                   count: ti.template()):
    """Vertices ia (block A) and ib (block B) are mutual nearest within d0 (§3.3 case 1, §3.4)."""
    cP = _convex(xy, vnext, vprev, ia)
    cQ = _convex(xy, vnext, vprev, ib)
    if cP and not cQ:
        # concave Q: P against both edges meeting at Q
        for s in ti.static(range(2)):
            e = vprev[ib] if s == 0 else ib
            ok, length = _ve_test(xy, vnext, vprev, ia, e, d0, d9, sin_h1, 0)
            if ok == 1:
                _emit(out_int, out_len, count, KIND_VE, ia, e, -1, -1, length)
    elif cQ and not cP:
        for s in ti.static(range(2)):
            e = vprev[ia] if s == 0 else ia
            ok, length = _ve_test(xy, vnext, vprev, ib, e, d0, d9, sin_h1, 0)
            if ok == 1:
                _emit(out_int, out_len, count, KIND_VE, ib, e, -1, -1, length)
    elif cP and cQ:
        P = _pt(xy, ia)
        Q = _pt(xy, ib)
        rA1 = _pt(xy, vnext[ia]) - P
        rA2 = _pt(xy, vprev[ia]) - P
        rB1 = _pt(xy, vnext[ib]) - Q
        rB2 = _pt(xy, vprev[ib]) - Q
        a1 = ti.atan2(rA1[1], rA1[0])
        a2 = ti.atan2(rA2[1], rA2[0])
        b1 = ti.atan2(rB1[1], rB1[0])
        b2 = ti.atan2(rB2[1], rB2[0])
        wA = _wrap(a2 - a1, 0.0)
        wB = _wrap(b2 - b1, 0.0)
        e5 = _wrap(b1 - a2, -h1)  # free gap between A's edge (prev->P) and B's edge (Q->next)
        e6 = _wrap(a1 - b2, -h1)  # free gap between B's edge (prev->Q) and A's edge (P->next)
        # the two wedges do not overlap (beyond h1) iff the four angles go once around
        if ti.abs(wA + wB + e5 + e6 - TWO_PI) < 1e-6:
            if e5 < h1 or e6 < h1:
                # edge-edge: A's edge (prev[ia], ia) parallel to B's edge (ib, next[ib]) (e5),
                # or A's edge (ia, next[ia]) parallel to B's edge (prev[ib], ib) (e6); the
                # contact vertex v is whichever lies inside the other's edge e (ties: A's),
                # its partner w an end of e, and `end` the far end of v's edge along the line
                v, e, end, w = ia, ib, vprev[ia], ib
                if e5 < h1:
                    tP = _edge_param(xy, vnext, ib, ia)
                    tQ = _edge_param(xy, vnext, vprev[ia], ib)
                    if ti.min(tP, 1.0 - tP) < ti.min(tQ, 1.0 - tQ) - TIE:
                        v, e, end, w = ib, vprev[ia], vnext[ib], ia
                else:
                    tP = _edge_param(xy, vnext, vprev[ib], ia)
                    tQ = _edge_param(xy, vnext, ia, ib)
                    if ti.min(tP, 1.0 - tP) >= ti.min(tQ, 1.0 - tQ) - TIE:
                        v, e, end, w = ia, vprev[ib], vnext[ia], ib
                    else:
                        v, e, end, w = ib, ia, vprev[ib], ia
                if _edge_edge_exit(xy, vnext, vprev, v, e, w, d9) == 0:
                    _emit(out_int, out_len, count, KIND_VE, v, e, -1, -1, _half_overlap(xy, vnext, e, v, end))
                else:
                    # parallel, but v entered the edge at the far corner or lies deeper than d9
                    # (§3.3): v against both edges meeting at w, by the vertex-edge rules
                    for s in ti.static(range(2)):
                        e2 = vprev[w] if s == 0 else w
                        ok, length = _ve_test(xy, vnext, vprev, v, e2, d0, d9, sin_h1, 0)
                        if ok == 1:
                            _emit(out_int, out_len, count, KIND_VE, v, e2, -1, -1, length)
            else:
                # genuine vertex-vertex: the entrance lines are the edges across the smaller gap
                # (e5 unless e6 is clearly smaller, so equal gaps do not flip between steps)
                eA = ib
                eB = vprev[ia]
                if e5 > e6 + h1:
                    eA = vprev[ib]
                    eB = ia
                if _edge_edge_exit(xy, vnext, vprev, ia, eA, ib, d9) == 0 and \
                        _edge_edge_exit(xy, vnext, vprev, ib, eB, ia, d9) == 0:
                    _emit(out_int, out_len, count, KIND_VV, ia, eA, ib, eB, 0.0)
                else:
                    # a vertex behind its entrance line entered the edge at the line's far
                    # corner, or lies beyond d9 (§3.3 rule 3): each vertex against both edges
                    # meeting at the other, by the vertex-edge rules
                    for s in ti.static(range(4)):
                        v = ia if s < 2 else ib
                        w = ib if s < 2 else ia
                        e2 = vprev[w] if s % 2 == 0 else w
                        ok, length = _ve_test(xy, vnext, vprev, v, e2, d0, d9, sin_h1, 0)
                        if ok == 1:
                            _emit(out_int, out_len, count, KIND_VE, v, e2, -1, -1, length)


# --------------------------------------------------------------------------- broad phase
@ti.func
def _cell_hash(cx, cy, table):
    h = (ti.cast(cx, ti.i64) * 73856093) ^ (ti.cast(cy, ti.i64) * 19349663)
    return ti.cast((h % table + table) % table, ti.i32)


@ti.kernel
def grid_bin(lo: F64_2, hi: F64_2, big: I32_1, h: ti.f64, ox: ti.f64, oy: ti.f64, table: ti.i32,
             cell: I32_2, bucket: I32_1, bucket_count: I32_1):
    """Bin each small box by its centre into a hashed uniform grid of cell size h."""
    for b in range(lo.shape[0]):
        if big[b] == 0:
            cx = ti.cast(ti.floor((0.5 * (lo[b, 0] + hi[b, 0]) - ox) / h), ti.i32)
            cy = ti.cast(ti.floor((0.5 * (lo[b, 1] + hi[b, 1]) - oy) / h), ti.i32)
            cell[b, 0] = cx
            cell[b, 1] = cy
            k = _cell_hash(cx, cy, table)
            bucket[b] = k
            ti.atomic_add(bucket_count[k], 1)


@ti.kernel
def grid_scatter(big: I32_1, bucket: I32_1, bucket_start: I32_1, bucket_fill: I32_1, sorted_ids: I32_1):
    """Counting sort of the small boxes by bucket (bucket_start = exclusive prefix sum)."""
    for b in range(big.shape[0]):
        if big[b] == 0:
            k = bucket[b]
            s = ti.atomic_add(bucket_fill[k], 1)
            sorted_ids[bucket_start[k] + s] = b


@ti.func
def _boxes_overlap(lo: ti.template(), hi: ti.template(), a, b):
    return (lo[a, 0] <= hi[b, 0] and lo[b, 0] <= hi[a, 0] and
            lo[a, 1] <= hi[b, 1] and lo[b, 1] <= hi[a, 1])


@ti.kernel
def grid_query(lo: F64_2, hi: F64_2, big: I32_1, fixed: I32_1, cell: I32_2, table: ti.i32,
               bucket_start: I32_1, sorted_ids: I32_1, pairs: I32_2, count: I32_1):
    """Pairs (i < j) of small boxes that overlap, found in the 3×3 neighbouring cells."""
    for b in range(lo.shape[0]):
        if big[b] == 0:
            cx = cell[b, 0]
            cy = cell[b, 1]
            for dx in range(-1, 2):
                for dy in range(-1, 2):
                    k = _cell_hash(cx + dx, cy + dy, table)
                    for s in range(bucket_start[k], bucket_start[k + 1]):
                        o = sorted_ids[s]
                        # the hash may merge cells: keep only boxes of this very cell
                        if o > b and cell[o, 0] == cx + dx and cell[o, 1] == cy + dy:
                            if not (fixed[b] == 1 and fixed[o] == 1) and _boxes_overlap(lo, hi, b, o):
                                n = ti.atomic_add(count[0], 1)
                                if n < pairs.shape[0]:
                                    pairs[n, 0] = b
                                    pairs[n, 1] = o


@ti.kernel
def big_query(lo: F64_2, hi: F64_2, big: I32_1, big_ids: I32_1, fixed: I32_1,
              pairs: I32_2, count: I32_1):
    """Pairs involving a big box (larger than a grid cell), tested against every box."""
    nb = lo.shape[0]
    for t in range(big_ids.shape[0] * nb):
        q = big_ids[t // nb]
        b = t % nb
        # a pair of two big boxes is reported once, from the lower index
        if b != q and (big[b] == 0 or b > q):
            if not (fixed[b] == 1 and fixed[q] == 1) and _boxes_overlap(lo, hi, b, q):
                n = ti.atomic_add(count[0], 1)
                if n < pairs.shape[0]:
                    pairs[n, 0] = ti.min(b, q)
                    pairs[n, 1] = ti.max(b, q)


# --------------------------------------------------------------------------- narrow phase
@ti.kernel
def narrow_phase(pairs: I32_2, xy: F64_2, voff: I32_1, vnext: I32_1, vprev: I32_1,
                 d0: ti.f64, d9: ti.f64, h1: ti.f64, out_int: I32_2, out_len: F64_1, count: I32_1):
    """Shi's narrow phase for each candidate block pair (A < B) (docs/method/dda.md §3.3–3.6).

    out_int rows: (kind, vertex0, edge0, vertex1, edge1); out_len: contact length.
    """
    sin_h1 = ti.sin(h1)
    for p in range(pairs.shape[0]):
        A = pairs[p, 0]
        B = pairs[p, 1]
        a0, a1 = voff[A], voff[A + 1]
        b0, b1 = voff[B], voff[B + 1]
        # 1. vertex pairs closer than d0 (mutual nearest): vertex-vertex rules
        for ia in range(a0, a1):
            P = _pt(xy, ia)
            ib = _nearest(xy, P, b0, b1, d0)
            if ib >= 0:
                if _nearest(xy, _pt(xy, ib), a0, a1, d0) == ia:
                    _vertex_vertex(xy, vnext, vprev, ia, ib, d0, d9, sin_h1, h1, out_int, out_len, count)
        # 2. vertices of A against edges of B, and 3. vertices of B against edges of A,
        # skipping a vertex whose mutual-nearest partner is an end of the edge (that pair was
        # handled above). A vertex near an edge's end that is not that end's mutual nearest
        # (the end pairs with another vertex) is tested here: skipping it by distance alone
        # lost the contact of a wedge's tip sliding along a joint next to the other block's
        # corner while the tip sank into it
        for s in ti.static(range(2)):
            v_lo, v_hi = (a0, a1) if s == 0 else (b0, b1)
            e_lo, e_hi = (b0, b1) if s == 0 else (a0, a1)
            for iv in range(v_lo, v_hi):
                P = _pt(xy, iv)
                partner = _nearest(xy, P, e_lo, e_hi, d0)
                if partner >= 0:
                    if _nearest(xy, _pt(xy, partner), v_lo, v_hi, d0) != iv:
                        partner = -1
                for ie in range(e_lo, e_hi):
                    if partner != ie and partner != vnext[ie]:
                        ok, length = _ve_test(xy, vnext, vprev, iv, ie, d0, d9, sin_h1, 1)
                        if ok == 1:
                            _emit(out_int, out_len, count, KIND_VE, iv, ie, -1, -1, length)


# --------------------------------------------------------------------------- contact vectors
@ti.func
def _trow(a, b, X):
    """a·T(X)row1 + b·T(X)row2 as a 6-vector (T of docs/method/dda.md §1.1, X centroidal)."""
    return ti.Vector([a, b, -a * X[1] + b * X[0], a * X[0], b * X[1], 0.5 * (a * X[1] + b * X[0])])


@ti.func
def _store(vec: ti.template(), c, slot, v):
    for a in ti.static(range(6)):
        vec[c, slot, a] = v[a]


@ti.kernel
def contact_vectors(xy: F64_2, vblock: I32_1, vnext: I32_1, centroid: F64_2, cint: I32_2,
                    omega: F64_1, vec: F64_3, sca: F64_2):
    """Linearised normal and shear distances of every contact line (docs/method/dda.md §2.8.1–2.8.4).

    cint rows: (kind, vertex0, edge0, vertex1, edge1). Positions are taken relative to the
    contact vertex P1 so that the constant parts keep full precision.
    """
    for c in range(cint.shape[0]):
        nl = 1 + cint[c, 0]
        for q in range(nl):
            p1 = cint[c, 1 + 2 * q]
            k = cint[c, 2 + 2 * q]
            P1 = _pt(xy, p1)
            x2 = _pt(xy, vnext[k]) - P1
            x3 = _pt(xy, k) - P1
            l = (x3 - x2).norm()
            ci = ti.Vector([centroid[vblock[p1], 0], centroid[vblock[p1], 1]])
            cj = ti.Vector([centroid[vblock[k], 0], centroid[vblock[k], 1]])
            X1 = P1 - ci
            X2 = x2 + P1 - cj
            X3 = x3 + P1 - cj
            # ∂Δ/∂P1, ∂Δ/∂P2, ∂Δ/∂P3 with P1 at the origin
            ev = _trow(x2[1] - x3[1], x3[0] - x2[0], X1) / l
            gv = (_trow(x3[1], -x3[0], X2) + _trow(-x2[1], x2[0], X3)) / l
            sca[c, q] = _cross(x2, x3) / l
            _store(vec, c, E0 + 2 * q, ev)
            _store(vec, c, G0 + 2 * q, gv)
            if q == 0 and cint[c, 0] == KIND_VE:
                w = omega[c]
                t = (x3 - x2) / l
                # ds = (P1 - P0)·(P3 - P2)/l with P0 = (1-ω)P2 + ωP3 (§2.8.3)
                sca[c, 2] = (-(1.0 - w) * x2 - w * x3).dot(x3 - x2) / l
                c2 = (2.0 * (1.0 - w) * x2 - (1.0 - 2.0 * w) * x3) / l
                c3 = (-(1.0 - 2.0 * w) * x2 - 2.0 * w * x3) / l
                _store(vec, c, ES, _trow(t[0], t[1], X1))
                _store(vec, c, GS, _trow(c2[0], c2[1], X2) + _trow(c3[0], c3[1], X3))


@ti.kernel
def second_order_shift(xy: F64_2, vnext: I32_1, q: F64_2, cint: I32_2, omega: F64_1, shift: F64_2):
    """Second-order rotation terms of the contact distances (docs/method/dda.md §5.3): with q the
    exact-minus-linear displacement of every vertex, shift = ∂Δ/∂P·q for each normal line and
    ∂s/∂P·q for the shear of a vertex-edge contact (§2.8.1, §2.8.3)."""
    for c in range(cint.shape[0]):
        nl = 1 + cint[c, 0]
        for line in range(nl):
            p1 = cint[c, 1 + 2 * line]
            k = cint[c, 2 + 2 * line]
            p2 = vnext[k]
            P1, P2, P3 = _pt(xy, p1), _pt(xy, p2), _pt(xy, k)
            q1, q2, q3 = _pt(q, p1), _pt(q, p2), _pt(q, k)
            length = (P3 - P2).norm()
            shift[c, line] = ((P2[1] - P3[1]) * q1[0] + (P3[0] - P2[0]) * q1[1] +
                              (P3[1] - P1[1]) * q2[0] + (P1[0] - P3[0]) * q2[1] +
                              (P1[1] - P2[1]) * q3[0] + (P2[0] - P1[0]) * q3[1]) / length
            if line == 0 and cint[c, 0] == KIND_VE:
                w = omega[c]
                b1 = P3 - P2
                b2 = -P1 + 2.0 * (1.0 - w) * P2 - (1.0 - 2.0 * w) * P3
                b3 = P1 - (1.0 - 2.0 * w) * P2 - 2.0 * w * P3
                shift[c, 2] = (b1.dot(q1) + b2.dot(q2) + b3.dot(q3)) / length


# --------------------------------------------------------------------------- assembly
@ti.kernel
def assemble_blocks(dof: I32_1, density: F64_1, elastic: F64_3, area: F64_1, mass: F64_3,
                    velocity: F64_2, accel: F64_2, stress: F64_2, body_acc_x: ti.f64,
                    body_acc_y: ti.f64, dt: ti.f64, carry: ti.f64, beta: ti.f64,
                    diag_slot: I32_1, stride: I32_1, data: F64_1, rhs: F64_1):
    """Per-block terms: inertia with velocity and acceleration carry-over (Newmark, γ = 1;
    β = ½ is Shi's §2.5), elasticity (§2.1), initial stress (§2.2) and body force (§2.4;
    gravity minus ground acceleration).

    With D = v Δt + Δt²((½ − β) a_n + β a_{n+1}) the inertia force ρ M a_{n+1} adds
    ρM/(βΔt²) to K and ρM (v/(βΔt) + (1/(2β) − 1) a_n) to F (v = carry × velocity)."""
    for b in range(dof.shape[0]):
        r = dof[b]
        if r >= 0:
            rho = density[b]
            s = area[b]
            c_inertia = rho / (beta * dt * dt)
            c_velocity = rho / (beta * dt) * carry
            c_accel = rho * (0.5 / beta - 1.0)
            base = diag_slot[r]
            st = stride[r]
            for a in range(6):
                mv = 0.0
                for c in range(6):
                    k = c_inertia * mass[b, a, c]
                    if a >= 3 and c >= 3:
                        k += s * elastic[b, a - 3, c - 3]
                    data[base + a * st + c] += k
                    mv += mass[b, a, c] * (c_velocity * velocity[b, c] + c_accel * accel[b, c])
                rhs[6 * r + a] += mv
            for a in range(3):
                rhs[6 * r + 3 + a] -= s * stress[b, a]
            rhs[6 * r + 0] += rho * s * body_acc_x
            rhs[6 * r + 1] += rho * s * body_acc_y


@ti.kernel
def assemble_points(point_block: I32_1, point_xy: F64_2, point_force: F64_2, stiffness: F64_1,
                    dof: I32_1, centroid: F64_2, diag_slot: I32_1, stride: I32_1,
                    data: F64_1, rhs: F64_1):
    """Point springs and point loads: K += k TᵀT, F += Tᵀ f (§2.3, §2.6)."""
    for p in range(point_block.shape[0]):
        b = point_block[p]
        r = dof[b]
        if r >= 0:
            X = ti.Vector([point_xy[p, 0] - centroid[b, 0], point_xy[p, 1] - centroid[b, 1]])
            t1 = _trow(1.0, 0.0, X)
            t2 = _trow(0.0, 1.0, X)
            k = stiffness[p]
            base = diag_slot[r]
            st = stride[r]
            if k != 0.0:
                for a in range(6):
                    for c in range(6):
                        ti.atomic_add(data[base + a * st + c], k * (t1[a] * t1[c] + t2[a] * t2[c]))
            for a in range(6):
                ti.atomic_add(rhs[6 * r + a], t1[a] * point_force[p, 0] + t2[a] * point_force[p, 1])


@ti.func
def _outer_rows(vec: ti.template(), c, s, t_own, t_other, k, r, r_other, off_slot,
                diag_slot: ti.template(), stride: ti.template(), data: ti.template()):
    """Add k·v vᵀ-type terms on the rows of one block r: k·vec[c, s]·vec[c, t_own]ᵀ to its
    diagonal block and k·vec[c, s]·vec[c, t_other]ᵀ to the block at ``off_slot`` (its row,
    the other block's column), if that block is free."""
    if r >= 0:
        base = diag_slot[r]
        st = stride[r]
        for a in range(6):
            va = k * vec[c, s, a]
            for b in range(6):
                ti.atomic_add(data[base + a * st + b], va * vec[c, t_own, b])
            if r_other >= 0:
                for b in range(6):
                    ti.atomic_add(data[off_slot + a * st + b], va * vec[c, t_other, b])


@ti.func
def _outer(vec: ti.template(), c, su, sw, tu, tw, k, ri, rj, sij, sji,
           diag_slot: ti.template(), stride: ti.template(), data: ti.template()):
    """Add k·[u; w][u'; w']ᵀ (u = vec[c, su], w = vec[c, sw] on the rows of blocks i, j;
    u' = vec[c, tu], w' = vec[c, tw] on their columns): a rank-one term, non-symmetric unless
    (tu, tw) = (su, sw)."""
    _outer_rows(vec, c, su, tu, tw, k, ri, rj, sij, diag_slot, stride, data)
    _outer_rows(vec, c, sw, tw, tu, k, rj, ri, sji, diag_slot, stride, data)


@ti.func
def _spring(vec: ti.template(), c, su, sw, k, d0, ri, rj, sij, sji,
            diag_slot: ti.template(), stride: ti.template(), data: ti.template(), rhs: ti.template()):
    """Add the spring energy ½ k (d0 + uᵀDi + wᵀDj)² of contact c (u = vec[c, su], w = vec[c, sw])."""
    _outer(vec, c, su, sw, su, sw, k, ri, rj, sij, sji, diag_slot, stride, data)
    for a in range(6):
        if ri >= 0:
            ti.atomic_add(rhs[6 * ri + a], -k * d0 * vec[c, su, a])
        if rj >= 0:
            ti.atomic_add(rhs[6 * rj + a], -k * d0 * vec[c, sw, a])


@ti.kernel
def assemble_contacts(cint: I32_2, state: I8_1, line: I8_1, vblock: I32_1, dof: I32_1,
                      vec: F64_3, sca: F64_2, friction_const: F64_1, friction_slope: F64_1,
                      shear_dir: I8_1, slot_ab: I32_1, slot_ba: I32_1, diag_slot: I32_1,
                      stride: I32_1, penalty: ti.f64, shear_penalty: ti.f64, data: F64_1, rhs: F64_1,
                      serial: ti.template()):
    """Contact springs for the assumed states, and friction of sliding contacts (§2.8).

    A sliding contact's friction force has magnitude S = a − b·dn (a = ``friction_const``,
    b = ``friction_slope``) and acts against ``shear_dir`` along the gradient of ds. With b = 0
    it is a load (S from an earlier solve, Shi's explicit friction); with b = μ·p it follows
    the normal penetration dn of this very solve (implicit friction) and adds the
    non-symmetric term −dir·b·∇ds ∇dnᵀ to K. `slot_ab`/`slot_ba` locate the off-diagonal
    blocks of the pair (block of vertex0, block of edge0) in the CSR data array. ``serial``:
    run the loop on one thread (`ddatai.backend.serial_scatter`).
    """
    ti.loop_config(serialize=serial)
    for c in range(cint.shape[0]):
        st = state[c]
        if st != STATE_OPEN:
            q = ti.cast(line[c], ti.i32)
            i = vblock[cint[c, 1 + 2 * q]]
            j = vblock[cint[c, 2 + 2 * q]]
            ri = dof[i]
            rj = dof[j]
            sij = slot_ab[c]
            sji = slot_ba[c]
            if q == 1:
                sij = slot_ba[c]
                sji = slot_ab[c]
            _spring(vec, c, E0 + 2 * q, G0 + 2 * q, penalty, sca[c, q], ri, rj, sij, sji,
                    diag_slot, stride, data, rhs)
            if cint[c, 0] == KIND_VE:
                if st == STATE_LOCK:
                    _spring(vec, c, ES, GS, shear_penalty, sca[c, 2], ri, rj, sij, sji,
                            diag_slot, stride, data, rhs)
                else:
                    sgn = ti.cast(shear_dir[c], ti.f64)
                    # internal force sgn·S(D)·∇ds with S = a − b·(dn0 + ∇dnᵀD)
                    f = sgn * (friction_const[c] - friction_slope[c] * sca[c, 0])
                    for a in range(6):
                        if ri >= 0:
                            ti.atomic_add(rhs[6 * ri + a], -f * vec[c, ES, a])
                        if rj >= 0:
                            ti.atomic_add(rhs[6 * rj + a], -f * vec[c, GS, a])
                    if friction_slope[c] != 0.0:
                        _outer(vec, c, ES, GS, E0, G0, -sgn * friction_slope[c], ri, rj, sij, sji,
                               diag_slot, stride, data)


# --------------------------------------------------------------------------- open-close judgement
# columns of the contact-law kernel's outputs (`ddatai.contact_law.ContactLaw` fields)
LAW_DN, LAW_DS, LAW_FN, LAW_FT, LAW_STRENGTH, LAW_DN_NOW, LAW_FN_NOW, LAW_FT_NOW, LAW_FRICTION_NOW, \
    LAW_ENERGY = range(10)
LAW_LINE, LAW_CLOSED, LAW_STATE, LAW_DIRECTION = range(4)
# columns of its per-contact inputs
IN_STATE, IN_LINE, IN_COUPLED, IN_BOND, IN_SHEAR_DIR = range(5)
IN_TAN_PHI, IN_COHESION, IN_TENSILE, IN_LENGTH, IN_NORMAL_FORCE = range(5)


@ti.func
def _dot6(vec: ti.template(), c, s, d: ti.template(), b):
    acc = 0.0
    for a in ti.static(range(6)):
        acc += vec[c, s, a] * d[b, a]
    return acc


@ti.kernel
def contact_law(cint: I32_2, cstate: I8_2, cvalue: F64_2, block_a: I32_1, block_b: I32_1,
                vec: F64_3, sca: F64_2, disp: F64_2, penalty: ti.f64, shear_penalty: ti.f64,
                penetration_limit: ti.f64, out_f: F64_2, out_i: I8_2):
    """The contact law at the displacements ``disp``, contact by contact (docs/method/dda.md
    §2.8, §4.3; ``ddatai.contact_law.contact_law`` documents it; its NumPy twin is ``contact_law_numpy``).

    ``cstate`` rows IN_* (field-major, (5, m)): the contact's state, line, coupled, bond, shear direction;
    ``cvalue`` rows: tan φ, cohesion, tensile strength, length, normal force of the last solve;
    ``sca`` the constant parts with the second-order shift already added. Writes the LAW_*
    rows of ``out_f`` ((10, m)) (forces, distances, the contact's spring energy) and ``out_i`` ((4, m)).
    """
    for c in range(cint.shape[0]):
        a = block_a[c]
        b = block_b[c]
        vv = cint[c, 0] == KIND_VV
        now = ti.cast(cstate[IN_STATE, c], ti.i32)
        coupled = cstate[IN_COUPLED, c] != 0
        bond = ti.cast(cstate[IN_BOND, c] != 0, ti.f64)
        tan_phi = cvalue[IN_TAN_PHI, c]
        cohesion = cvalue[IN_COHESION, c] * cvalue[IN_LENGTH, c] * bond
        dn0 = sca[c, 0] + _dot6(vec, c, E0, disp, a) + _dot6(vec, c, G0, disp, b)
        dn_now = dn0
        dn = dn0
        line = 0
        ds = 0.0
        if vv:
            # line 1: vertex1 (of block b) against an edge of block a
            dn1 = sca[c, 1] + _dot6(vec, c, E1, disp, b) + _dot6(vec, c, G1, disp, a)
            if cstate[IN_LINE, c] == 1:
                dn_now = dn1
            # the entrance line: the less penetrated, but never one the vertex was already
            # behind at the step start by more than the penetration limit (§2.8.7)
            behind0 = sca[c, 0] < -penetration_limit
            behind1 = sca[c, 1] < -penetration_limit
            if behind0 != behind1:
                line = ti.cast(behind0, ti.i32)
            else:
                line = ti.cast(dn1 > dn0, ti.i32)
            if line == 1:
                dn = dn1
        else:
            ds = sca[c, 2] + _dot6(vec, c, ES, disp, a) + _dot6(vec, c, GS, disp, b)
        allowance = bond * cvalue[IN_TENSILE, c] * cvalue[IN_LENGTH, c] / penalty
        closed = dn <= allowance
        strength = penalty * ti.max(-dn, 0.0) * tan_phi + cohesion
        stale = cvalue[IN_NORMAL_FORCE, c] * tan_phi + cohesion
        used = stale
        if coupled:
            used = strength
        trial = shear_penalty * ds
        stick = ti.abs(trial) <= used
        sign_ds = 0.0
        if ds > 0.0:
            sign_ds = 1.0
        elif ds < 0.0:
            sign_ds = -1.0
        ft = 0.0
        state = STATE_OPEN
        if closed:
            state = STATE_SLIDE
            if not vv:
                ft = sign_ds * used
                if stick:
                    ft = trial
                    state = STATE_LOCK
        # spring energy with the friction of the next solve: ½p·dn² (up to the tensile
        # strength), and the Huber function of ds (½k_s·ds², then linear at the friction)
        energy = 0.5 * penalty * allowance * allowance
        if dn <= allowance:
            energy = 0.5 * penalty * dn * dn
        if closed and not vv:
            limit = used / shear_penalty
            if ti.abs(ds) <= limit:
                energy += 0.5 * shear_penalty * ds * ds
            else:
                energy += used * (ti.abs(ds) - 0.5 * limit)
        # the forces of the contact's current state at this D
        fn_now = 0.0
        if now != STATE_OPEN:
            fn_now = -penalty * dn_now
        friction_now = stale
        if coupled:
            friction_now = cohesion - penalty * tan_phi * dn_now
        ft_now = 0.0
        if not vv:
            if now == STATE_LOCK:
                ft_now = trial
            elif now == STATE_SLIDE:
                ft_now = ti.cast(cstate[IN_SHEAR_DIR, c], ti.f64) * friction_now
        fn = 0.0
        if closed:
            fn = -penalty * dn
        out_f[LAW_DN, c] = dn
        out_f[LAW_DS, c] = ds
        out_f[LAW_FN, c] = fn
        out_f[LAW_FT, c] = ft
        out_f[LAW_STRENGTH, c] = strength
        out_f[LAW_DN_NOW, c] = dn_now
        out_f[LAW_FN_NOW, c] = fn_now
        out_f[LAW_FT_NOW, c] = ft_now
        out_f[LAW_FRICTION_NOW, c] = friction_now
        out_f[LAW_ENERGY, c] = energy
        out_i[LAW_LINE, c] = ti.cast(line, ti.i8)
        out_i[LAW_CLOSED, c] = ti.cast(closed, ti.i8)
        out_i[LAW_STATE, c] = ti.cast(state, ti.i8)
        direction = -1
        if ds >= 0.0:
            direction = 1
        out_i[LAW_DIRECTION, c] = ti.cast(direction, ti.i8)


@ti.kernel
def violations(cint: I32_2, cstate: I8_2, cvalue: F64_2, block_a: I32_1, block_b: I32_1,
               law_f: F64_2, law_i: I8_2, level: F64_1, fixed: I8_1, penalty: ti.f64,
               force_tolerance: ti.f64, by_load: ti.i32, state_tolerance: ti.f64, roundoff: ti.f64,
               bad: I8_1):
    """Contacts whose assumed state must change given the law at the solution
    (``ddatai.contact_law.violations`` documents the rules; the NumPy twin is ``violations_numpy``).
    ``level`` enters as each block's weight and leaves as the load the block carries (its
    weight or its largest contact force). ``by_load``: the force tolerance is a fraction of
    that load, of the contact's free blocks only (1; ``fixed``: each block's flag), or of the
    contact's own strength (0; ``Params.oc_force_reference``)."""
    for c in range(cint.shape[0]):
        f = ti.abs(law_f[LAW_FN, c])
        ti.atomic_max(level[block_a[c]], f)
        ti.atomic_max(level[block_b[c]], f)
    for c in range(cint.shape[0]):
        vv = cint[c, 0] == KIND_VV
        now = ti.cast(cstate[IN_STATE, c], ti.i32)
        strength = law_f[LAW_STRENGTH, c]
        carried = ti.max(level[block_a[c]], level[block_b[c]])
        tensile = 0.0
        if cstate[IN_BOND, c] != 0:
            tensile = cvalue[IN_TENSILE, c] * cvalue[IN_LENGTH, c]
        strict = force_tolerance * strength + roundoff
        strict_tension = force_tolerance * tensile + roundoff
        if by_load != 0:
            free_carried = 0.0
            if fixed[block_a[c]] == 0:
                free_carried = level[block_a[c]]
            if fixed[block_b[c]] == 0:
                free_carried = ti.max(free_carried, level[block_b[c]])
            strict = force_tolerance * free_carried + roundoff
            strict_tension = strict
        out = False
        if not vv and now == STATE_LOCK:
            # Coulomb: a locked contact holds at most its strength
            out = ti.abs(law_f[LAW_FT_NOW, c]) > strength + strict
        if not vv and now == STATE_SLIDE and law_i[LAW_CLOSED, c] != 0:
            # a sliding contact's friction is the strength of this solve
            out = out or ti.abs(law_f[LAW_FRICTION_NOW, c] - strength) > strict
        if now != STATE_OPEN:
            out = out or -law_f[LAW_FN_NOW, c] > tensile + strict_tension
        loose = state_tolerance * carried + roundoff
        out = out or ti.abs(law_f[LAW_FN_NOW, c] - law_f[LAW_FN, c]) > loose or \
            ti.abs(law_f[LAW_FT_NOW, c] - law_f[LAW_FT, c]) > loose
        if vv and now != STATE_OPEN and law_i[LAW_LINE, c] != cstate[IN_LINE, c]:
            out = out or penalty * ti.abs(law_f[LAW_DN, c] - law_f[LAW_DN_NOW, c]) > loose
        bad[c] = ti.cast(out, ti.i8)


@ti.kernel
def internal_force(block_a: I32_1, block_b: I32_1, dof: I32_1, vec: F64_3, law_f: F64_2, law_i: I8_2,
                   out: F64_1, serial: ti.template()):
    """Generalised forces of the law's contact forces (``ddatai.contact_law.internal_force``,
    which holds the NumPy twin): p·dn·∇dn of each closed contact's active line and f_t·∇ds,
    added into ``out`` (6 per free block). ``serial`` as in `assemble_contacts`."""
    ti.loop_config(serialize=serial)
    for c in range(block_a.shape[0]):
        pull = -law_f[LAW_FN, c]  # p·dn of a closed contact, 0 for an open one
        ft = law_f[LAW_FT, c]
        sa = E0
        sb = G0
        if law_i[LAW_LINE, c] == 1:
            sa = G1
            sb = E1
        ra = dof[block_a[c]]
        rb = dof[block_b[c]]
        for k in ti.static(range(6)):
            if ra >= 0:
                ti.atomic_add(out[6 * ra + k], pull * vec[c, sa, k] + ft * vec[c, ES, k])
            if rb >= 0:
                ti.atomic_add(out[6 * rb + k], pull * vec[c, sb, k] + ft * vec[c, GS, k])
