"""Plain NumPy reference implementations of the Taichi kernels (for tests and debugging).

Slow and obvious: Python loops over pairs and vertices, dense matrices. Each function here
computes what one kernel (or kernel group) of :mod:`ddatai.kernels` computes, written
independently from the formulas of docs/method/dda.md, so that the tests comparing the two catch
mistakes in either. Use only on small models.
"""

from __future__ import annotations

import math

import numpy as np

from .geometry import displacement_matrix, mass_matrix
from .layout import KIND, VE, VV, ContactState
from .model import Model

#: as `kernels.EDGE_FLOOR` (kept here so the reference does not import Taichi)
EDGE_FLOOR = 1e-150
EDGE_FLOOR2 = EDGE_FLOOR * EDGE_FLOOR

TIE = 1e-3  # same as ddatai.kernels.TIE
SLACK = 1e-9  # same as ddatai.kernels.SLACK
PASSED_DEPTH = 1e-6  # same as ddatai.kernels.PASSED_DEPTH


# --------------------------------------------------------------------------- broad phase
def broad_phase(model: Model, vertex_xy: np.ndarray, margin: float) -> np.ndarray:
    """All pairs (i < j, not both fixed) whose boxes enlarged by margin/2 overlap (brute force)."""
    starts = model.vertex_offset[:-1]
    lo = np.minimum.reduceat(vertex_xy, starts, axis=0) - 0.5 * margin
    hi = np.maximum.reduceat(vertex_xy, starts, axis=0) + 0.5 * margin
    out = []
    nb = len(lo)
    for i in range(nb):
        j = np.arange(i + 1, nb)
        hit = (lo[i, 0] <= hi[j, 0]) & (lo[j, 0] <= hi[i, 0]) & (lo[i, 1] <= hi[j, 1]) & (lo[j, 1] <= hi[i, 1])
        hit &= ~(model.block_fixed[i] & model.block_fixed[j])
        out.extend((i, int(k)) for k in j[hit])
    return np.array(out, dtype=np.int32).reshape(-1, 2)


# --------------------------------------------------------------------------- narrow phase
def _angle(v) -> float:
    return math.atan2(v[1], v[0])


def _wrap(a: float, lower: float) -> float:
    return a - 2 * math.pi * math.floor((a - lower) / (2 * math.pi))


def narrow_phase(model: Model, vertex_xy: np.ndarray, pairs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Shi's vertex-edge / vertex-vertex contact rules (docs/method/dda.md §3.3–3.6), pair by pair.

    Returns (cint (m, 5): kind, vertex0, edge0, vertex1, edge1; length (m,)), unsorted.
    """
    xy = vertex_xy
    nxt, prv, off = model.vertex_next, model.vertex_prev, model.vertex_offset
    d0, d9 = model.search_distance, model.max_penetration
    h1 = math.radians(model.params.angle_tolerance)
    sin_h1 = math.sin(h1)
    rows, lengths = [], []

    def emit(kind, v0, e0, v1=-1, e1=-1, length=0.0):
        rows.append((kind, v0, e0, v1, e1))
        lengths.append(length)

    def param(e, p):
        q0, q1 = xy[e], xy[nxt[e]]
        d = q1 - q0
        return float(np.dot(xy[p] - q0, d) / max(float(np.dot(d, d)), EDGE_FLOOR2))

    def half_overlap(e, a, b):
        ta, tb = param(e, a), param(e, b)
        lo, hi = max(0.0, min(ta, tb)), min(1.0, max(ta, tb))
        return 0.5 * max(0.0, hi - lo) * float(np.linalg.norm(xy[nxt[e]] - xy[e]))

    def convex(p):
        r1, r2 = xy[nxt[p]] - xy[p], xy[prv[p]] - xy[p]
        return r1[0] * r2[1] - r1[1] * r2[0] > 0

    def outside_convex(P, e, slack):
        # P in front of some edge of the convex block of edge e (or on its line): outside it
        b = model.vertex_block[e]
        edges = range(off[b], off[b + 1])
        if not all(convex(j) for j in edges):
            return False
        for j in edges:
            d = xy[nxt[j]] - xy[j]
            l = max(float(np.linalg.norm(d)), EDGE_FLOOR)
            if float(np.dot(P - xy[j], np.array([d[1], -d[0]]) / l)) > -slack:
                return True
        return False

    def nearer_exit(P, depth, a, c):
        # P less deep behind edge a than ``depth`` (projecting onto a); a meets the edge at
        # the convex corner c
        d = xy[nxt[a]] - xy[a]
        l = max(float(np.linalg.norm(d)), EDGE_FLOOR)
        t = float(np.dot(P - xy[a], d)) / l ** 2
        dn = float(np.dot(P - xy[a], np.array([d[1], -d[0]]) / l))
        # or nearer than |depth| to an end of a (past it: a cut's shared corner, moved a hair)
        r0, r1 = P - xy[a], P - xy[nxt[a]]
        near = (t < 0.0 and r0[0] * r0[0] + r0[1] * r0[1] < depth * depth) or \
            (t > 1.0 and r1[0] * r1[0] + r1[1] * r1[1] < depth * depth)
        return convex(c) and ((dn > depth and -SLACK <= t <= 1.0 + SLACK) or near)

    def line_exit(v, e, partner):
        # v, put on edge e by a vertex pair (the partner an end of e), lies behind e's line
        # but less deep behind (or in front of) the edge meeting e at its far, convex corner
        # (the shortest exit; the edge at the partner is no exit: v is never tested against
        # it), or deeper than d9
        d = xy[nxt[e]] - xy[e]
        l = max(float(np.linalg.norm(d)), EDGE_FLOOR)
        P = xy[v]
        dn = float(np.dot(P - xy[e], np.array([d[1], -d[0]]) / l))
        a, c = (nxt[e], nxt[e]) if partner == e else (prv[e], e)
        return dn < -SLACK * d9 and (nearer_exit(P, dn, a, c) or dn < -d9)

    def past_corner(v, w):
        # v has passed its partner w's corner along an edge at w: it projects onto the edge
        # beyond round-off from w and lies deeper than PASSED_DEPTH x d9 behind its line, but
        # within h1 of it seen from w (slid past the corner, not entered head on)
        t, dn, ln = [], [], []
        for e in (w, prv[w]):
            d = xy[nxt[e]] - xy[e]
            l = max(float(np.linalg.norm(d)), EDGE_FLOOR)
            t.append(float(np.dot(xy[v] - xy[e], d)) / l ** 2)
            dn.append(float(np.dot(xy[v] - xy[e], np.array([d[1], -d[0]]) / l)))
            ln.append(l)
        deep = -PASSED_DEPTH * d9
        along = (t[0] * ln[0], (1.0 - t[1]) * ln[1])
        return (t[0] > TIE and t[0] <= 1.0 and dn[0] < deep and -dn[0] < sin_h1 * along[0]) or \
            (1.0 - t[1] > TIE and t[1] >= 0.0 and dn[1] < deep and -dn[1] < sin_h1 * along[1])

    def edge_edge(v, e, partner, end):
        # the edge-edge contact of a vertex pair, unless v exits elsewhere (`line_exit`): then
        # v against both edges at its partner
        if not line_exit(v, e, partner):
            emit(VE, v, e, length=half_overlap(e, v, end))
            return
        for e2 in (prv[partner], partner):
            ok, L = ve_test(v, e2, False)
            if ok:
                emit(VE, v, e2, length=L)

    def ve_test(p, e, check_projection):
        q0, q1, P = xy[e], xy[nxt[e]], xy[p]
        d = q1 - q0
        l = max(float(np.linalg.norm(d)), EDGE_FLOOR)
        t = float(np.dot(P - q0, d)) / l ** 2
        n = np.array([d[1], -d[0]]) / l
        dn = float(np.dot(P - q0, n))
        if l <= EDGE_FLOOR:  # a collapsed edge has no normal: no contact
            return False, 0.0
        if check_projection and not 0.0 <= t <= 1.0:
            return False, 0.0
        if dn > d0 or dn < -d9 or not convex(p):
            return False, 0.0
        if dn < -SLACK * d9 and (nearer_exit(P, dn, prv[e], e) or nearer_exit(P, dn, nxt[e], nxt[e])
                         or outside_convex(P, e, SLACK * d9)):
            # behind the edge's line, but nearer (or in front of) the line of the edge that
            # meets it at a convex corner: it entered, or lies on, that edge (the shortest exit)
            return False, 0.0
        r1, r2 = xy[nxt[p]] - P, xy[prv[p]] - P
        n1, n2 = np.linalg.norm(r1), np.linalg.norm(r2)
        if np.dot(r1, n) < -sin_h1 * n1 or np.dot(r2, n) < -sin_h1 * n2:
            return False, 0.0
        if abs(np.dot(r1, n)) <= sin_h1 * n1:
            return True, half_overlap(e, p, nxt[p])
        if abs(np.dot(r2, n)) <= sin_h1 * n2:
            return True, half_overlap(e, p, prv[p])
        return True, 0.0

    def nearest(P, lo, hi):
        dist = np.linalg.norm(xy[lo:hi] - P, axis=1)
        k = int(np.argmin(dist))
        return lo + k if dist[k] <= d0 else -1

    for A, B in pairs:
        a0, a1, b0, b1 = off[A], off[A + 1], off[B], off[B + 1]
        for ia in range(a0, a1):
            ib = nearest(xy[ia], b0, b1)
            if ib < 0 or nearest(xy[ib], a0, a1) != ia:
                continue
            cP, cQ = convex(ia), convex(ib)
            if cP and not cQ:
                for e in (prv[ib], ib):
                    ok, L = ve_test(ia, e, False)
                    if ok:
                        emit(VE, ia, e, length=L)
            elif cQ and not cP:
                for e in (prv[ia], ia):
                    ok, L = ve_test(ib, e, False)
                    if ok:
                        emit(VE, ib, e, length=L)
            elif cP and cQ:
                P, Q = xy[ia], xy[ib]
                a1_, a2_ = _angle(xy[nxt[ia]] - P), _angle(xy[prv[ia]] - P)
                b1_, b2_ = _angle(xy[nxt[ib]] - Q), _angle(xy[prv[ib]] - Q)
                wA, wB = _wrap(a2_ - a1_, 0.0), _wrap(b2_ - b1_, 0.0)
                e5, e6 = _wrap(b1_ - a2_, -h1), _wrap(a1_ - b2_, -h1)
                if abs(wA + wB + e5 + e6 - 2 * math.pi) >= 1e-6:
                    continue  # wedges overlap: already interpenetrated
                if e5 < h1:
                    tP, tQ = param(ib, ia), param(prv[ia], ib)
                    if min(tP, 1 - tP) >= min(tQ, 1 - tQ) - TIE:
                        edge_edge(ia, ib, ib, prv[ia])
                    else:
                        edge_edge(ib, prv[ia], ia, nxt[ib])
                elif e6 < h1:
                    tP, tQ = param(prv[ib], ia), param(ia, ib)
                    if min(tP, 1 - tP) >= min(tQ, 1 - tQ) - TIE:
                        edge_edge(ia, prv[ib], ib, nxt[ia])
                    else:
                        edge_edge(ib, ia, ia, prv[ib])
                else:
                    eA, eB = (ib, prv[ia]) if e5 <= e6 + h1 else (prv[ib], ia)
                    if not (line_exit(ia, eA, ib) or line_exit(ib, eB, ia) or past_corner(ia, ib)
                            or past_corner(ib, ia)):
                        emit(VV, ia, eA, ib, eB)
                        continue
                    # a vertex behind its entrance line entered the edge at the line's far
                    # corner, or lies beyond d9, or passed its partner's corner: each vertex
                    # against both edges at the other
                    for v, w in ((ia, ib), (ib, ia)):
                        for e2 in (prv[w], w):
                            ok, L = ve_test(v, e2, False)
                            if ok:
                                emit(VE, v, e2, length=L)
        # vertex against edge, unless the vertex's mutual-nearest partner is an end of the edge
        # (that pair was handled above; kernels.narrow_phase)
        for (v_lo, v_hi), (e_lo, e_hi) in (((a0, a1), (b0, b1)), ((b0, b1), (a0, a1))):
            for iv in range(v_lo, v_hi):
                partner = nearest(xy[iv], e_lo, e_hi)
                if partner >= 0 and nearest(xy[partner], v_lo, v_hi) != iv:
                    partner = -1
                for ie in range(e_lo, e_hi):
                    if partner not in (ie, nxt[ie]):
                        ok, L = ve_test(iv, ie, True)
                        if ok:
                            emit(VE, iv, ie, length=L)
    return np.array(rows, dtype=np.int32).reshape(-1, 5), np.array(lengths, dtype=float)


def detect_contacts(model: Model, vertex_xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Reference broad + narrow phase, in canonical order."""
    from .contacts import sort_contacts

    pairs = broad_phase(model, vertex_xy, model.search_distance)
    return sort_contacts(*narrow_phase(model, vertex_xy, pairs))


# --------------------------------------------------------------------------- contact vectors
def contact_vectors(model: Model, vertex_xy: np.ndarray, centroid: np.ndarray, cint: np.ndarray,
                    omega: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(vec (m, 6, 6), sca (m, 3)) as `kernels.contact_vectors`, from the T matrix (§1.1, §2.8)."""
    m = len(cint)
    vec = np.zeros((m, 6, 6))
    sca = np.zeros((m, 3))
    nxt, vb = model.vertex_next, model.vertex_block
    for c in range(m):
        kind = cint[c, 0]
        for q in range(1 + kind):
            p1, k = cint[c, 1 + 2 * q], cint[c, 2 + 2 * q]
            P1, P2, P3 = vertex_xy[p1], vertex_xy[nxt[k]], vertex_xy[k]
            i, j = vb[p1], vb[k]
            T1 = displacement_matrix(P1, centroid[i])
            T2 = displacement_matrix(P2, centroid[j])
            T3 = displacement_matrix(P3, centroid[j])
            (x1, y1), (x2, y2), (x3, y3) = P1, P2, P3
            l = math.hypot(x3 - x2, y3 - y2)
            delta = (x2 - x1) * (y3 - y1) - (y2 - y1) * (x3 - x1)
            sca[c, q] = delta / l
            vec[c, 2 * q] = (T1.T @ np.array([y2 - y3, x3 - x2])) / l
            vec[c, 2 * q + 1] = (T2.T @ np.array([y3 - y1, x1 - x3]) + T3.T @ np.array([y1 - y2, x2 - x1])) / l
            if q == 0 and kind == VE:
                w = omega[c]
                t = (P3 - P2) / l
                P0 = (1 - w) * P2 + w * P3
                sca[c, 2] = np.dot(P1 - P0, P3 - P2) / l
                vec[c, 4] = T1.T @ t
                vec[c, 5] = (T2.T @ (-P1 + 2 * (1 - w) * P2 - (1 - 2 * w) * P3) +
                             T3.T @ (P1 - (1 - 2 * w) * P2 - 2 * w * P3)) / l
    return vec, sca


# --------------------------------------------------------------------------- assembly
def second_order_shift(model: Model, vertex_xy: np.ndarray, q: np.ndarray, cint: np.ndarray,
                       omega: np.ndarray) -> np.ndarray:
    """Twin of `kernels.second_order_shift`: (m, 3) shifts of dn (line 0, line 1) and ds."""
    nxt = model.vertex_next
    shift = np.zeros((len(cint), 3))
    for line in (0, 1):
        # every contact's line 0 (a slice: no gather), the line 1 of vertex-vertex ones
        rows = slice(None) if line == 0 else np.flatnonzero(cint[:, KIND] == VV)
        if line == 1 and not len(rows):
            continue
        p1, k = cint[rows, 1 + 2 * line], cint[rows, 2 + 2 * line]
        P1, P2, P3 = vertex_xy[p1], vertex_xy[nxt[k]], vertex_xy[k]
        q1, q2, q3 = q[p1], q[nxt[k]], q[k]
        x1, y1, x2, y2, x3, y3 = P1[:, 0], P1[:, 1], P2[:, 0], P2[:, 1], P3[:, 0], P3[:, 1]
        length = np.hypot(x3 - x2, y3 - y2)
        # ∂Δ/∂P1, ∂Δ/∂P2, ∂Δ/∂P3 (§2.8.1)
        shift[rows, line] = ((y2 - y3) * q1[:, 0] + (x3 - x2) * q1[:, 1] +
                             (y3 - y1) * q2[:, 0] + (x1 - x3) * q2[:, 1] +
                             (y1 - y2) * q3[:, 0] + (x2 - x1) * q3[:, 1]) / length
        if line == 0:
            # ∂s/∂P1, ∂s/∂P2, ∂s/∂P3 of s = (P1 − P0)·(P3 − P2) (§2.8.3)
            w = omega[rows][:, None]
            b1 = P3 - P2
            b2 = -P1 + 2 * (1 - w) * P2 - (1 - 2 * w) * P3
            b3 = P1 - (1 - 2 * w) * P2 - 2 * w * P3
            ve = cint[:, 0] == VE
            shift[:, 2] = np.where(ve, ((b1 * q1).sum(1) + (b2 * q2).sum(1) + (b3 * q3).sum(1)) / length, 0.0)
    return shift


def assemble_dense(model: Model, vertex_xy: np.ndarray, velocity: np.ndarray, stress: np.ndarray,
                   fixed_point_xy: np.ndarray, load_xy: np.ndarray, load_force: np.ndarray,
                   dt: float, body_acc: np.ndarray, contacts, vec: np.ndarray, sca: np.ndarray,
                   friction_force: np.ndarray, accel: np.ndarray | None = None,
                   beta: float = 0.5, friction_slope: np.ndarray | None = None
                   ) -> tuple[np.ndarray, np.ndarray]:
    """Dense K (6n × 6n) and F over the free blocks, term by term (§2.1–2.8).

    A sliding contact's friction magnitude is S = friction_force − friction_slope·dn, acting
    against its sliding direction along ∇ds (implicit friction where the slope is μ·p)."""
    geom = model.block_geometry(vertex_xy)
    free = np.flatnonzero(~model.block_fixed)
    row = {int(b): r for r, b in enumerate(free)}
    n = 6 * len(free)
    K = np.zeros((n, n))
    F = np.zeros(n)
    carry = model.params.velocity_carry
    M = mass_matrix(geom["area"], geom["s1"], geom["s2"], geom["s3"])

    def sl(b):
        r = row[int(b)]
        return slice(6 * r, 6 * r + 6)

    accel = np.zeros_like(velocity) if accel is None else accel
    for b in free:
        rho, s = model.block_density[b], geom["area"][b]
        # inertia ρ M a_{n+1} with a_{n+1} = (D − vΔt)/(βΔt²) − (1/(2β) − 1) a_n (Newmark, γ = 1)
        K[sl(b), sl(b)] += rho / (beta * dt ** 2) * M[b]
        K[sl(b), sl(b)][3:, 3:] += s * model.block_elastic[b]
        F[sl(b)] += rho * M[b] @ (carry * velocity[b] / (beta * dt) + (1 / (2 * beta) - 1) * accel[b])
        F[sl(b)][3:] -= s * stress[b]
        F[sl(b)][:2] += rho * s * body_acc
    for p, b in enumerate(model.fixed_point_block):
        if b in row:
            T = displacement_matrix(fixed_point_xy[p], geom["centroid"][b])
            K[sl(b), sl(b)] += model.fixed_point_penalty * T.T @ T
            F[sl(b)] += model.fixed_point_penalty * T.T @ (model.fixed_point_xy0[p] - fixed_point_xy[p])
    for p, b in enumerate(model.load_block):
        if b in row:
            T = displacement_matrix(load_xy[p], geom["centroid"][b])
            F[sl(b)] += T.T @ load_force[p]

    vb = model.vertex_block

    def spring(k, u, w, d, i, j):
        if i in row:
            K[sl(i), sl(i)] += k * np.outer(u, u)
            F[sl(i)] -= k * d * u
        if j in row:
            K[sl(j), sl(j)] += k * np.outer(w, w)
            F[sl(j)] -= k * d * w
        if i in row and j in row:
            K[sl(i), sl(j)] += k * np.outer(u, w)
            K[sl(j), sl(i)] += k * np.outer(w, u)

    slope = np.zeros(contacts.n) if friction_slope is None else friction_slope
    for c in range(contacts.n):
        st = contacts.state[c]
        if st == ContactState.OPEN:
            continue
        q = int(contacts.line[c])
        i = int(vb[contacts.cint[c, 1 + 2 * q]])
        j = int(vb[contacts.cint[c, 2 + 2 * q]])
        spring(model.penalty, vec[c, 2 * q], vec[c, 2 * q + 1], sca[c, q], i, j)
        if contacts.cint[c, 0] == VE:
            if st == ContactState.LOCK:
                spring(model.shear_penalty, vec[c, 4], vec[c, 5], sca[c, 2], i, j)
            else:
                # internal force dir·S(D)·∇ds, S = a − b·(dn0 + ∇dnᵀD): the D part goes to K
                sgn = contacts.shear_dir[c]
                f = sgn * (friction_force[c] - slope[c] * sca[c, 0])
                rows = {i: vec[c, 4], j: vec[c, 5]}
                cols = {i: vec[c, 0], j: vec[c, 1]}
                for r, u in rows.items():
                    if r in row:
                        F[sl(r)] -= f * u
                        for col, v in cols.items():
                            if col in row:
                                K[sl(r), sl(col)] -= sgn * slope[c] * np.outer(u, v)
    return K, F
