"""The narrow phase: Shi's vertex-edge and vertex-vertex rules for each candidate block pair
(docs/method/dda.md §3.3–3.6), and the ``@ti.func`` tests it is made of (the NumPy twin is
``ddatai.narrow``, operation for operation)."""

import taichi as ti

from .common import (EDGE_FLOOR, EDGE_FLOOR2, I32_1, I32_2, F64_1, F64_2, KIND_VE, KIND_VV, MEM_K2, MEM_KIND, MEM_V0,
                     PASSED_DEPTH, SLACK, TIE, TWO_PI, _beyond, _box, _cross, _dot2, _norm2, _pt, _wrap)


@ti.func
def _edge_param(xy: ti.template(), vnext: ti.template(), e, p):
    """Projection parameter of vertex p on edge e (0 at its start, 1 at its end)."""
    q0 = _pt(xy, e)
    d = _pt(xy, vnext[e]) - q0
    # a collapsed edge (zero length) projects everything to its start instead of dividing by 0
    return _dot2(_pt(xy, p) - q0, d) / ti.max(_dot2(d, d), EDGE_FLOOR2)


@ti.func
def _half_overlap(xy: ti.template(), vnext: ti.template(), e, a, b):
    """Half the length of the overlap of segment (a, b) projected on edge e (§3.6)."""
    q0 = _pt(xy, e)
    d = _pt(xy, vnext[e]) - q0
    l2 = ti.max(_dot2(d, d), EDGE_FLOOR2)
    ta = _dot2(_pt(xy, a) - q0, d) / l2
    tb = _dot2(_pt(xy, b) - q0, d) / l2
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
    l = ti.max(_norm2(d), EDGE_FLOOR)
    t = _dot2(P - q0, d) / (l * l)
    dn = _dot2(P - q0, ti.Vector([d[1], -d[0]]) / l)
    r0 = P - q0
    r1 = P - q1
    # or nearer than ``depth`` to an end of a (past it: a cut's shared corner, moved a hair)
    near = (t < 0.0 and r0[0] * r0[0] + r0[1] * r0[1] < depth * depth) or \
        (t > 1.0 and r1[0] * r1[0] + r1[1] * r1[1] < depth * depth)
    return _convex(xy, vnext, vprev, c) and ((dn > depth and t >= -SLACK and t <= 1.0 + SLACK) or near)


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
        l = ti.max(_norm2(d), EDGE_FLOOR)
        if _dot2(P - q0, ti.Vector([d[1], -d[0]]) / l) > -slack:
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
    l = ti.max(_norm2(d), EDGE_FLOOR)
    P = _pt(xy, p)
    dn = _dot2(P - q0, ti.Vector([d[1], -d[0]]) / l)
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
def _past_corner(xy: ti.template(), vnext: ti.template(), vprev: ti.template(), p, w, d9, sin_h1, persist):
    """Whether vertex p, of a vertex-vertex pair (p, w), has passed w's corner along an edge at
    w: it projects onto that edge beyond round-off from w (``TIE``) and lies deeper than
    ``PASSED_DEPTH`` × d9 behind its line, but within the angle tolerance h1 of it seen from w
    (it slid past the corner along the edge, where a corner that entered head on lies as far
    behind as along; `narrow._past_corner`, docs/method/dda.md §3.4). Its contact is then that
    edge's, not a corner's. ``persist`` (a pair handed over last step, ``_handed_over``): whether
    p still lies past w at all, projecting onto the edge beyond ``SLACK`` from w and on or
    behind its line, within h1 of it, at any depth (a vertex clear of the line ends it)."""
    P = _pt(xy, p)
    t = ti.Vector([0.0, 0.0])
    dn = ti.Vector([0.0, 0.0])
    l = ti.Vector([0.0, 0.0])
    for k in ti.static(range(2)):
        e = w
        if k == 1:
            e = vprev[w]
        q0 = _pt(xy, e)
        d = _pt(xy, vnext[e]) - q0
        l[k] = ti.max(_norm2(d), EDGE_FLOOR)
        t[k] = _dot2(P - q0, d) / (l[k] * l[k])
        dn[k] = _dot2(P - q0, ti.Vector([d[1], -d[0]]) / l[k])
    deep = -PASSED_DEPTH * d9
    beyond = TIE
    if persist != 0:
        beyond = SLACK
    out = 0
    along0 = t[0] * l[0]           # along the edge (w, next w), w at t = 0
    along1 = (1.0 - t[1]) * l[1]   # along the edge (prev w, w), w at t = 1
    # deeper than PASSED_DEPTH × d9 behind the line; on or behind it, where persisting
    behind0 = dn[0] < deep or (persist != 0 and dn[0] <= 0.0)
    behind1 = dn[1] < deep or (persist != 0 and dn[1] <= 0.0)
    if t[0] > beyond and t[0] <= 1.0 and behind0 and -dn[0] < sin_h1 * along0:
        out = 1
    if 1.0 - t[1] > beyond and t[1] >= 0.0 and behind1 and -dn[1] < sin_h1 * along1:
        out = 1
    return out


@ti.func
def _remembered(mem: ti.template(), lo, hi, v, e):
    """Whether rows ``lo:hi`` of the last step's contact memory (sorted by identity: kind,
    vertex0, edge0 or vertex1; columns ``MEM_*``) hold the vertex-edge contact of vertex v on
    edge e: a binary search (the vertex-edge rows come first, kind 0)."""
    a = lo
    b = hi
    while a < b:
        mid = a + (b - a) // 2
        below = 0
        if mem[mid, MEM_KIND] == KIND_VE:
            if mem[mid, MEM_V0] < v or (mem[mid, MEM_V0] == v and mem[mid, MEM_K2] < e):
                below = 1
        if below == 1:
            a = mid + 1
        else:
            b = mid
    found = 0
    if a < hi:
        if mem[a, MEM_KIND] == KIND_VE and mem[a, MEM_V0] == v and mem[a, MEM_K2] == e:
            found = 1
    return found


@ti.func
def _handed_over(vprev: ti.template(), mem: ti.template(), lo, hi, ia, ib):
    """Whether the vertex pair (ia, ib) was handed to the vertex-edge rules last step: a vertex
    was in a vertex-edge contact on an edge at its partner, (w, next w) or (prev w, w) — the
    keys ia·n + ib, ia·n + prev ib, ib·n + ia, ib·n + prev ia of `narrow._VertexPairs`."""
    found = 0
    for k in range(4):
        v, e = ia, ib
        if k == 1:
            e = vprev[ib]
        elif k == 2:
            v, e = ib, ia
        elif k == 3:
            v, e = ib, vprev[ia]
        if found == 0:
            found = _remembered(mem, lo, hi, v, e)
    return found


@ti.func
def _ve_test(xy: ti.template(), vnext: ti.template(), vprev: ti.template(), p, e,
             d0, d9, sin_h1, check_projection):
    """Distance and entrance-angle criteria for vertex p against edge e (§3.3, §3.4).

    Returns (accepted, contact length L of an edge-edge contact or 0).
    """
    q0 = _pt(xy, e)
    d = _pt(xy, vnext[e]) - q0
    l = ti.max(_norm2(d), EDGE_FLOOR)
    P = _pt(xy, p)
    t = _dot2(P - q0, d) / (l * l)
    n = ti.Vector([d[1], -d[0]]) / l  # outward normal of a CCW edge
    dn = _dot2(P - q0, n)
    ok = 1
    if l <= EDGE_FLOOR:  # a collapsed edge has no normal: no contact (reference.narrow_phase)
        ok = 0
    if check_projection != 0:
        if t < 0.0 or t > 1.0:
            ok = 0
    if dn > d0 or dn < -d9:
        ok = 0
    length = 0.0
    # the other criteria only ever reject: most vertex-edge pairs of a block pair fail the
    # distance test above, and skip them (the same contacts)
    if ok == 1:
        if dn < -SLACK * d9:
            # behind the edge's line, but nearer the line of the edge that meets it at a convex
            # corner (or in front of it: outside the block): the vertex entered, or lies on, that
            # edge, not this one (§3.3, the shortest exit)
            if _nearer_exit(xy, vnext, vprev, P, dn, vprev[e], e) or \
                    _nearer_exit(xy, vnext, vprev, P, dn, vnext[e], vnext[e]) or \
                    _outside_convex(xy, vnext, vprev, P, e, SLACK * d9):
                ok = 0
        r1 = _pt(xy, vnext[p]) - P
        r2 = _pt(xy, vprev[p]) - P
        n1 = _norm2(r1)
        n2 = _norm2(r2)
        # a concave vertex never contacts as a vertex; the vertex's material wedge must lie on
        # the outer side of the edge within the angle tolerance h1
        if _cross(r1, r2) <= 0.0:
            ok = 0
        if _dot2(r1, n) < -sin_h1 * n1 or _dot2(r2, n) < -sin_h1 * n2:
            ok = 0
        if ok == 1:
            if ti.abs(_dot2(r1, n)) <= sin_h1 * n1:
                length = _half_overlap(xy, vnext, e, p, vnext[p])
            elif ti.abs(_dot2(r2, n)) <= sin_h1 * n2:
                length = _half_overlap(xy, vnext, e, p, vprev[p])
    return ok, length


@ti.func
def _emit(out_int: ti.template(), out_len: ti.template(), count: ti.template(), slot, base, cap,
          kind, v0, e0, v1, e1, length):
    """Append a contact to the region ``base:base + cap`` of the outputs, counted in
    ``count[slot]`` (the count may pass ``cap``: the caller grows the region and detects again).
    The narrow-phase kernel has one region (slot 0, base 0, the whole array); the fused engine
    one per member (`ddatai.fused`)."""
    k = ti.atomic_add(count[slot], 1)
    if k < cap:
        out_int[base + k, 0] = kind
        out_int[base + k, 1] = v0
        out_int[base + k, 2] = e0
        out_int[base + k, 3] = v1
        out_int[base + k, 4] = e1
        out_len[base + k] = length


@ti.func
def _nearest(xy: ti.template(), P, lo, hi, limit):
    """Index of the vertex in [lo, hi) nearest to P within `limit` (ties: lowest index), or -1.
    The square root only where it can matter: a vertex whose squared distance passes
    limit²·(1 + 1e-12) lies farther than ``limit`` after rounding too, and the best distance
    never passes ``limit`` (the same vertex, the same ties)."""
    best = -1
    best_d = limit
    far = limit * limit * (1.0 + 1e-12)
    for k in range(lo, hi):
        r = _pt(xy, k) - P
        square = r[0] * r[0] + r[1] * r[1]
        if square <= far:
            dist = ti.sqrt(square)
            if dist < best_d or (dist == best_d and best == -1):
                best = k
                best_d = dist
    return best


@ti.func
def _vertex_vertex(xy: ti.template(), vnext: ti.template(), vprev: ti.template(), ia, ib,
                   d0, d9, sin_h1, h1, mem: ti.template(), mlo, mhi, out_int: ti.template(),
                   out_len: ti.template(), count: ti.template(), slot, base, cap):
    """Vertices ia (block A) and ib (block B) are mutual nearest within d0 (§3.3 case 1, §3.4).
    ``mem[mlo:mhi]``: the last step's contacts (``_handed_over``).

    Where the rules fall back on the vertex-edge tests of a vertex against both edges meeting at
    its partner, those tests run in one loop at the end over the (vertex, partner) pairs that
    asked for them, in the order the rules name them: one copy of `_ve_test` in the compiled
    kernel instead of one a case (compile time; the same contacts in the same order)."""
    cP = _convex(xy, vnext, vprev, ia)
    cQ = _convex(xy, vnext, vprev, ib)
    # (vertex, partner) pairs whose vertex is tested against both edges meeting at the partner
    v1, w1, v2, w2 = -1, -1, -1, -1
    if cP and not cQ:
        # concave Q: P against both edges meeting at Q
        v1, w1 = ia, ib
    elif cQ and not cP:
        v1, w1 = ib, ia
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
                    _emit(out_int, out_len, count, slot, base, cap, KIND_VE, v, e, -1, -1,
                          _half_overlap(xy, vnext, e, v, end))
                else:
                    # parallel, but v entered the edge at the far corner or lies deeper than d9
                    # (§3.3): v against both edges meeting at w, by the vertex-edge rules
                    v1, w1 = v, w
            else:
                # genuine vertex-vertex: the entrance lines are the edges across the smaller gap
                # (e5 unless e6 is clearly smaller, so equal gaps do not flip between steps)
                eA = ib
                eB = vprev[ia]
                if e5 > e6 + h1:
                    eA = vprev[ib]
                    eB = ia
                exits = 0
                for k in range(2):  # ia against its entrance line eA, then ib against eB
                    p, e, w = ia, eA, ib
                    if k == 1:
                        p, e, w = ib, eB, ia
                    exits += _edge_edge_exit(xy, vnext, vprev, p, e, w, d9)
                # a vertex that has passed its partner's corner along one of its edges (the
                # corners of diagonal blocks where four squares meet, after the rows slid): the
                # vertex-edge tests give both vertices' contacts, one line could hold only one;
                # and a pair handed over last step stays handed over while either vertex lies
                # past its partner at all, on or behind the edge's line (docs/method/dda.md
                # §3.4, `narrow._VertexPairs`): tests k = 0, 1 as found, k = 2, 3 persisting.
                # One loop: one copy of `_past_corner` in the compiled kernel
                for k in range(4):
                    if k == 2:
                        if exits != 0 or _handed_over(vprev, mem, mlo, mhi, ia, ib) == 0:
                            break
                    p, w = ia, ib
                    if k % 2 == 1:
                        p, w = ib, ia
                    exits += _past_corner(xy, vnext, vprev, p, w, d9, sin_h1, k // 2)
                if exits == 0:
                    _emit(out_int, out_len, count, slot, base, cap, KIND_VV, ia, eA, ib, eB, 0.0)
                else:
                    # a vertex behind its entrance line entered the edge at the line's far
                    # corner, or lies beyond d9 (§3.3 rule 3): each vertex against both edges
                    # meeting at the other, by the vertex-edge rules
                    v1, w1, v2, w2 = ia, ib, ib, ia
    for k in range(4):
        v = v1
        w = w1
        if k >= 2:
            v = v2
            w = w2
        if v >= 0:
            e2 = w
            if k % 2 == 0:
                e2 = vprev[w]
            ok, length = _ve_test(xy, vnext, vprev, v, e2, d0, d9, sin_h1, 0)
            if ok == 1:
                _emit(out_int, out_len, count, slot, base, cap, KIND_VE, v, e2, -1, -1, length)


@ti.func
def pair_contacts(xy: ti.template(), vnext: ti.template(), vprev: ti.template(), a0, a1, b0, b1,
                  d0, d9, sin_h1, h1, mem: ti.template(), mlo, mhi, out_int: ti.template(),
                  out_len: ti.template(), count: ti.template(), slot, base, cap):
    """The contacts of the block pair whose vertices are ``a0:a1`` (A) and ``b0:b1`` (B), by
    Shi's rules (docs/method/dda.md §3.3–3.6), appended to an output region (``_emit``).
    ``mem[mlo:mhi]``: the last step's contacts, sorted by identity (columns ``MEM_*``), which
    keep a corner pair's hand-over to the vertex-edge rules (``_handed_over``; none: mlo = mhi)."""
    # A vertex farther outside the other block's box than twice the largest distance the rules
    # accept (d0 from a vertex, max(d0, d9) from an edge onto which it projects; twice, and a
    # relative hair, so that round-off cannot matter) has no contact with it and no mutual-
    # nearest partner in it: it is skipped (the same contacts, found in the same order)
    reach = 2.0 * ti.max(d0, d9)
    box_a_lo, box_a_hi = _box(xy, a0, a1)
    box_b_lo, box_b_hi = _box(xy, b0, b1)
    # 1. vertex pairs closer than d0 (mutual nearest): vertex-vertex rules
    for ia in range(a0, a1):
        P = _pt(xy, ia)
        if not _beyond(P, box_b_lo, box_b_hi, reach + 1e-9 * (ti.abs(P[0]) + ti.abs(P[1]))):
            ib = _nearest(xy, P, b0, b1, d0)
            if ib >= 0:
                if _nearest(xy, _pt(xy, ib), a0, a1, d0) == ia:
                    _vertex_vertex(xy, vnext, vprev, ia, ib, d0, d9, sin_h1, h1, mem, mlo, mhi, out_int,
                                   out_len, count, slot, base, cap)
    # 2. vertices of A against edges of B, and 3. vertices of B against edges of A,
    # skipping a vertex whose mutual-nearest partner is an end of the edge (that pair was
    # handled above). A vertex near an edge's end that is not that end's mutual nearest
    # (the end pairs with another vertex) is tested here: skipping it by distance alone
    # lost the contact of a wedge's tip sliding along a joint next to the other block's
    # corner while the tip sank into it
    for s in range(2):
        v_lo, v_hi, e_lo, e_hi = a0, a1, b0, b1
        low, high = box_b_lo, box_b_hi
        if s == 1:
            v_lo, v_hi, e_lo, e_hi = b0, b1, a0, a1
            low, high = box_a_lo, box_a_hi
        for iv in range(v_lo, v_hi):
            P = _pt(xy, iv)
            if not _beyond(P, low, high, reach + 1e-9 * (ti.abs(P[0]) + ti.abs(P[1]))):
                partner = _nearest(xy, P, e_lo, e_hi, d0)
                if partner >= 0:
                    if _nearest(xy, _pt(xy, partner), v_lo, v_hi, d0) != iv:
                        partner = -1
                hair = reach + 1e-9 * (ti.abs(P[0]) + ti.abs(P[1]))
                for ie in range(e_lo, e_hi):
                    # a vertex farther than that outside the edge's own box neither projects
                    # onto it within the distances the rules accept (the same argument as for
                    # the block's box above): skipped before the tests' roots and divisions
                    q0 = _pt(xy, ie)
                    q1 = _pt(xy, vnext[ie])
                    if partner != ie and partner != vnext[ie] and \
                            not _beyond(P, ti.min(q0, q1), ti.max(q0, q1), hair):
                        ok, length = _ve_test(xy, vnext, vprev, iv, ie, d0, d9, sin_h1, 1)
                        if ok == 1:
                            _emit(out_int, out_len, count, slot, base, cap, KIND_VE, iv, ie, -1, -1, length)


@ti.kernel
def narrow_phase(pairs: I32_2, xy: F64_2, voff: I32_1, vnext: I32_1, vprev: I32_1,
                 d0: ti.f64, d9: ti.f64, h1: ti.f64, mem: I32_2, n_mem: ti.i32, out_int: I32_2, out_len: F64_1,
                 count: I32_1):
    """Shi's narrow phase for each candidate block pair (A < B) (docs/method/dda.md §3.3–3.6).

    mem[:n_mem]: the last step's contacts (kind, vertex0, edge0 or vertex1), sorted
    (``ddatai.contacts.memory_rows``). out_int rows: (kind, vertex0, edge0, vertex1, edge1);
    out_len: contact length.
    """
    sin_h1 = ti.sin(h1)
    for p in range(pairs.shape[0]):
        A = pairs[p, 0]
        B = pairs[p, 1]
        pair_contacts(xy, vnext, vprev, voff[A], voff[A + 1], voff[B], voff[B + 1], d0, d9, sin_h1, h1,
                      mem, 0, n_mem, out_int, out_len, count, 0, 0, out_int.shape[0])
