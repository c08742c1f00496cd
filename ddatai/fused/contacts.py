"""The fused engine's contacts of one member (Taichi functions): detection with the step's rules
(every block pair whose boxes, enlarged by d0/2, overlap, then Shi's narrow phase of
``ddatai.kernels.detection.pair_contacts``, the same functions as the kernel path), the canonical
order, the transfer of the last step's memory (``ddatai.contacts.Contacts.start``, §3.7), the
contact vectors (``ddatai.kernels.assembly.contact_vectors``, §2.8), the second-order shift
(§5.3) and the memory handed to the next step (``Contacts.memory``)."""


import taichi as ti

from ..kernels.common import E0, E1, ES, G0, GS, _cross, _dot2, _norm2, _pt, _trow
from ..kernels.detection import pair_contacts
from .layout import (BG_CX, BG_CY, BI_ROW, BI_V0, BI_V1, BW_BOX, BW_ROT, BW_TRIG, CF_ARM, CF_COH, CF_DN,
                     CF_DN0, CF_DS, CF_DS0,
                     CF_LEN, CF_NF, CF_NF0, CF_OMEGA, CF_SCA, CF_SHIFT, CF_TAN, CF_TEN, CI_A, CI_B, CI_BOND,
                     CI_BOND0, CI_COUPLED, CI_COUPLED0, CI_DIR, CI_DIR0, CI_E0, CI_E1, CI_JOINT, CI_KIND,
                     CI_LINE, CI_LINE0, CI_STATE, CI_STATE0, CI_V0, CI_V1, FLAG_BOND_SLIP, JF_COH, JF_TAN,
                     JF_TEN, MEMF_DN, MEMF_NF, MEMF_OMEGA, MEMI_BOND, MEMI_DIR, MEMI_K2, MEMI_KIND, MEMI_LINE,
                     MEMI_STATE, MEMI_V0, MF_D0, MF_D9, MF_H1, MF_OPEN_TOL, MF_PENALTY, MF_SHEAR, MI_B0, MI_B1,
                     MI_C0, MI_CCAP, MI_FLAGS, MI_NC, MI_NF, MI_NM, MI_Q0, MI_Q1, MI_R0, MI_STEP)

VE = 0
VV = 1
OPEN = 0
SLIDE = 1
LOCK = 2


@ti.func
def _store_row(vec: ti.template(), c, slot, v):
    """Contact vector ``slot`` of contact c (``cvec[c, 6·slot : 6·slot + 6]``)."""
    for a in ti.static(range(6)):
        vec[c, 6 * slot + a] = v[a]


@ti.func
def detect(E: ti.template(), m):
    """The contacts of member m at ``vxy`` into its region, in the canonical order; returns
    their number (more than the region holds: the member is re-launched with a larger one).
    Reads the last step's contacts (``memi``, ``MI_NM`` rows of the region) as the kernel path
    reads ``ContactMemory.key``."""
    b0 = E.mi[m, MI_B0]
    b1 = E.mi[m, MI_B1]
    base = E.mi[m, MI_C0]
    cap = E.mi[m, MI_CCAP]
    d0 = E.mf[m, MF_D0]
    d9 = E.mf[m, MF_D9]
    h1 = E.mf[m, MF_H1]
    sin_h1 = ti.sin(h1)
    half = 0.5 * d0
    # the last step's contacts (`hand_over`, sorted), which keep a corner pair's hand-over to
    # the vertex-edge rules (docs/method/dda.md §3.4)
    mend = base + E.mi[m, MI_NM]
    E.ccount[m] = 0
    # each block's box once (not once a pair)
    for A in range(b0, b1):
        alo = ti.Vector([1e300, 1e300])
        ahi = ti.Vector([-1e300, -1e300])
        for k in range(E.bint[A, BI_V0], E.bint[A, BI_V1]):
            alo = ti.min(alo, _pt(E.vxy, k))
            ahi = ti.max(ahi, _pt(E.vxy, k))
        for q in ti.static(range(2)):
            E.bwork[A, BW_BOX + q] = alo[q]
            E.bwork[A, BW_BOX + 2 + q] = ahi[q]
    for A in range(b0, b1):
        alo = ti.Vector([E.bwork[A, BW_BOX], E.bwork[A, BW_BOX + 1]])
        ahi = ti.Vector([E.bwork[A, BW_BOX + 2], E.bwork[A, BW_BOX + 3]])
        for B in range(A + 1, b1):
            if E.bint[A, BI_ROW] >= 0 or E.bint[B, BI_ROW] >= 0:
                blo = ti.Vector([E.bwork[B, BW_BOX], E.bwork[B, BW_BOX + 1]])
                bhi = ti.Vector([E.bwork[B, BW_BOX + 2], E.bwork[B, BW_BOX + 3]])
                # boxes enlarged by d0/2 on every side (`contacts.box_bounds`) that overlap
                if alo[0] - half <= bhi[0] + half and blo[0] - half <= ahi[0] + half and \
                        alo[1] - half <= bhi[1] + half and blo[1] - half <= ahi[1] + half:
                    pair_contacts(E.vxy, E.vnext, E.vprev, E.bint[A, BI_V0], E.bint[A, BI_V1],
                                  E.bint[B, BI_V0], E.bint[B, BI_V1], d0, d9, sin_h1, h1,
                                  E.memi, base, mend, E.cint, E.clen, E.ccount, m, base, cap)
    n = E.ccount[m]
    if n <= cap:
        _sort(E, base, n)
    return n


@ti.func
def _key(E: ti.template(), c):
    """(kind, vertex0, edge0 or vertex1): the contact's identity (`contacts.contact_keys`)."""
    k2 = E.cint[c, CI_E0]
    if E.cint[c, CI_KIND] == VV:
        k2 = E.cint[c, CI_V1]
    return E.cint[c, CI_KIND], E.cint[c, CI_V0], k2


@ti.func
def _less(a0, a1, a2, b0, b1, b2):
    return a0 < b0 or (a0 == b0 and (a1 < b1 or (a1 == b1 and a2 < b2)))


@ti.func
def _sort(E: ti.template(), base, n):
    """Insertion sort of the region by key (the canonical order of `contacts.sort_contacts`)."""
    for i in range(base + 1, base + n):
        k0, k1, k2 = _key(E, i)
        row = ti.Vector([E.cint[i, q] for q in ti.static(range(5))])
        length = E.clen[i]
        j = i - 1
        while j >= base:
            j0, j1, j2 = _key(E, j)
            if not _less(k0, k1, k2, j0, j1, j2):
                break
            for q in ti.static(range(5)):
                E.cint[j + 1, q] = E.cint[j, q]
            E.clen[j + 1] = E.clen[j]
            j -= 1
        for q in ti.static(range(5)):
            E.cint[j + 1, q] = row[q]
        E.clen[j + 1] = length


@ti.func
def _signed_distance(E: ti.template(), v, e):
    """Signed distance of vertex v from the line of edge e, positive outside its block."""
    q0 = _pt(E.vxy, e)
    d = _pt(E.vxy, E.vnext[e]) - q0
    r = _pt(E.vxy, v) - q0
    return (r[0] * d[1] - r[1] * d[0]) / ti.sqrt(d[0] * d[0] + d[1] * d[1])


@ti.func
def start(E: ti.template(), m, n):
    """Joint properties and the last step's memory attached to the n detected contacts
    (`ddatai.contacts.Contacts.start`: states transferred by identity, lock points kept while
    locked, a sliding contact's lock point S/k_s behind its vertex, new contacts touching on the
    first step closed and bonded)."""
    base = E.mi[m, MI_C0]
    mend = base + E.mi[m, MI_NM]
    mp = base
    p = E.mf[m, MF_PENALTY]
    first = E.mi[m, MI_STEP] == 0
    for c in range(base, base + n):
        kind = E.cint[c, CI_KIND]
        v = E.cint[c, CI_V0]
        e = E.cint[c, CI_E0]
        k0, k1, k2 = _key(E, c)
        a = E.vblock[v]
        b = E.vblock[e]
        joint = E.vjoint[e]
        lo = ti.min(a, b)
        hi = ti.max(a, b)
        for q in range(E.mi[m, MI_Q0], E.mi[m, MI_Q1]):
            if E.pj[q, 0] == lo and E.pj[q, 1] == hi:
                joint = E.pj[q, 2]
        dn0 = _signed_distance(E, v, e)
        p2 = _pt(E.vxy, E.vnext[e])
        d = _pt(E.vxy, e) - p2
        omega = _dot2(_pt(E.vxy, v) - p2, d) / _dot2(d, d)
        tan = E.jf[joint, JF_TAN]
        coh = E.jf[joint, JF_COH]
        length = E.clen[c]
        state = OPEN
        # a VV contact starts on its less penetrated line, and its start normal force is that
        # line's penetration (`Contacts.start`)
        dn1 = -1e300
        line = 0
        if kind == VV:
            dn1 = _signed_distance(E, E.cint[c, CI_V1], E.cint[c, CI_E1])
            line = ti.cast(dn1 > dn0, ti.i32)
        dline = dn0
        if line == 1:
            dline = dn1
        nf = p * ti.max(-dline, 0.0)
        bond = 0
        sdir = 1
        found = 0
        while mp < mend:
            if not _less(E.memi[mp, MEMI_KIND], E.memi[mp, MEMI_V0], E.memi[mp, MEMI_K2], k0, k1, k2):
                break
            mp += 1
        if mp < mend:
            if E.memi[mp, MEMI_KIND] == k0 and E.memi[mp, MEMI_V0] == k1 and E.memi[mp, MEMI_K2] == k2:
                found = 1
        if found == 1:
            state = E.memi[mp, MEMI_STATE]
            line = E.memi[mp, MEMI_LINE]
            bond = E.memi[mp, MEMI_BOND]
            sdir = E.memi[mp, MEMI_DIR]
            if kind == VV:
                dline = dn0
                if line == 1:
                    dline = dn1
                nf = p * ti.max(-dline, 0.0)
            if state != OPEN:
                nf = E.memf[mp, MEMF_NF]
            if state == LOCK:
                omega = E.memf[mp, MEMF_OMEGA]
            if state == SLIDE and kind == VE:
                # the lock point S/k_s behind the vertex: a lock starts from the friction force
                strength = nf * tan + coh * length * bond
                edge = ti.sqrt(_dot2(d, d))
                omega -= sdir * strength / (E.mf[m, MF_SHEAR] * edge)
        elif first:
            touching = ti.max(dn0, dn1) <= E.mf[m, MF_OPEN_TOL]
            if kind == VV:
                if touching:
                    state = SLIDE
            elif touching:
                state = LOCK
                if length > 0:
                    bond = 1
        E.cint[c, CI_STATE] = state
        E.cint[c, CI_LINE] = line
        E.cint[c, CI_BOND] = bond
        E.cint[c, CI_DIR] = sdir
        E.cint[c, CI_COUPLED] = ti.cast(state == SLIDE and kind == VE and tan > 0, ti.i32)
        E.cint[c, CI_JOINT] = joint
        E.cint[c, CI_A] = a
        E.cint[c, CI_B] = b
        E.cf[c, CF_LEN] = length
        E.cf[c, CF_OMEGA] = omega
        E.cf[c, CF_DN] = dn0
        E.cf[c, CF_DS] = 0.0
        E.cf[c, CF_NF] = nf
        E.cf[c, CF_TAN] = tan
        E.cf[c, CF_COH] = coh
        E.cf[c, CF_TEN] = E.jf[joint, JF_TEN]
    E.mi[m, MI_NC] = n


@ti.func
def vectors(E: ti.template(), m):
    """Contact vectors and constant parts of every contact (§2.8.1–2.8.4, positions relative to
    the contact vertex), the step-start ds = ds0 of a vertex-edge contact, and the backup of
    the open-close fields that every try of the step starts from."""
    base = E.mi[m, MI_C0]
    for c in range(base, base + E.mi[m, MI_NC]):
        kind = E.cint[c, CI_KIND]
        for q in range(1 + kind):
            p1 = E.cint[c, 1 + 2 * q]
            k = E.cint[c, 2 + 2 * q]
            P1 = _pt(E.vxy, p1)
            x2 = _pt(E.vxy, E.vnext[k]) - P1
            x3 = _pt(E.vxy, k) - P1
            length = _norm2(x3 - x2)
            bi = E.vblock[p1]
            bj = E.vblock[k]
            ci = ti.Vector([E.bgeo[bi, BG_CX], E.bgeo[bi, BG_CY]])
            cj = ti.Vector([E.bgeo[bj, BG_CX], E.bgeo[bj, BG_CY]])
            X1 = P1 - ci
            X2 = x2 + P1 - cj
            X3 = x3 + P1 - cj
            ev = _trow(x2[1] - x3[1], x3[0] - x2[0], X1) / length
            gv = (_trow(x3[1], -x3[0], X2) + _trow(-x2[1], x2[0], X3)) / length
            E.cf[c, CF_SCA + q] = _cross(x2, x3) / length
            _store_row(E.cvec, c, E0 + 2 * q, ev)
            _store_row(E.cvec, c, G0 + 2 * q, gv)
            if q == 0 and kind == VE:
                w = E.cf[c, CF_OMEGA]
                t = (x3 - x2) / length
                E.cf[c, CF_SCA + 2] = _dot2((-(1.0 - w) * x2 - w * x3), x3 - x2) / length
                c2 = (2.0 * (1.0 - w) * x2 - (1.0 - 2.0 * w) * x3) / length
                c3 = (-(1.0 - 2.0 * w) * x2 - 2.0 * w * x3) / length
                _store_row(E.cvec, c, ES, _trow(t[0], t[1], X1))
                _store_row(E.cvec, c, GS, _trow(c2[0], c2[1], X2) + _trow(c3[0], c3[1], X3))
        if kind == VV:
            E.cf[c, CF_SCA + 2] = 0.0
        else:
            E.cf[c, CF_DS] = E.cf[c, CF_SCA + 2]
        # the step start's lever arms of the vertex slots (each solve's are set from them)
        E.cf[c, CF_ARM] = E.cvec[c, 6 * E0 + 2]
        E.cf[c, CF_ARM + 1] = E.cvec[c, 6 * E1 + 2]
        E.cf[c, CF_ARM + 2] = E.cvec[c, 6 * ES + 2]
        E.cint[c, CI_STATE0] = E.cint[c, CI_STATE]
        E.cint[c, CI_LINE0] = E.cint[c, CI_LINE]
        E.cint[c, CI_BOND0] = E.cint[c, CI_BOND]
        E.cint[c, CI_DIR0] = E.cint[c, CI_DIR]
        E.cint[c, CI_COUPLED0] = E.cint[c, CI_COUPLED]
        E.cf[c, CF_DN0] = E.cf[c, CF_DN]
        E.cf[c, CF_DS0] = E.cf[c, CF_DS]
        E.cf[c, CF_NF0] = E.cf[c, CF_NF]


@ti.func
def restore(E: ti.template(), m):
    """The open-close fields as the step found them (each try starts from them)."""
    base = E.mi[m, MI_C0]
    for c in range(base, base + E.mi[m, MI_NC]):
        E.cint[c, CI_STATE] = E.cint[c, CI_STATE0]
        E.cint[c, CI_LINE] = E.cint[c, CI_LINE0]
        E.cint[c, CI_BOND] = E.cint[c, CI_BOND0]
        E.cint[c, CI_DIR] = E.cint[c, CI_DIR0]
        E.cint[c, CI_COUPLED] = E.cint[c, CI_COUPLED0]
        E.cf[c, CF_DN] = E.cf[c, CF_DN0]
        E.cf[c, CF_DS] = E.cf[c, CF_DS0]
        E.cf[c, CF_NF] = E.cf[c, CF_NF0]


@ti.func
def _q(E: ti.template(), v):
    """Exact-minus-linear displacement of vertex v for its block's rotation r (§5.3):
    (cos r − 1)X + (sin r − r)·JX."""
    b = E.vblock[v]
    X = E.vxy[v, 0] - E.bgeo[b, BG_CX]
    Y = E.vxy[v, 1] - E.bgeo[b, BG_CY]
    c1 = E.bwork[b, BW_TRIG]        # cos r − 1
    sr = E.bwork[b, BW_TRIG + 1]    # sin r − r
    return ti.Vector([c1 * X + sr * -Y, c1 * Y + sr * X])


@ti.func
def second_order_shift(E: ti.template(), m, any_rotation):
    """Second-order rotation terms of the contact distances into ``cf[:, CF_SHIFT:+3]``
    (`reference.second_order_shift`); all zero while no block rotates."""
    base = E.mi[m, MI_C0]
    for c in range(base, base + E.mi[m, MI_NC]):
        for q in ti.static(range(3)):
            E.cf[c, CF_SHIFT + q] = 0.0
        if any_rotation:
            kind = E.cint[c, CI_KIND]
            for line in range(1 + kind):
                p1 = E.cint[c, 1 + 2 * line]
                k = E.cint[c, 2 + 2 * line]
                p2 = E.vnext[k]
                P1 = _pt(E.vxy, p1)
                P2 = _pt(E.vxy, p2)
                P3 = _pt(E.vxy, k)
                q1 = _q(E, p1)
                q2 = _q(E, p2)
                q3 = _q(E, k)
                length = _norm2(P3 - P2)
                E.cf[c, CF_SHIFT + line] = ((P2[1] - P3[1]) * q1[0] + (P3[0] - P2[0]) * q1[1] +
                                            (P3[1] - P1[1]) * q2[0] + (P1[0] - P3[0]) * q2[1] +
                                            (P1[1] - P2[1]) * q3[0] + (P2[0] - P1[0]) * q3[1]) / length
                if line == 0 and kind == VE:
                    w = E.cf[c, CF_OMEGA]
                    b1 = P3 - P2
                    b2 = -P1 + 2.0 * (1.0 - w) * P2 - (1.0 - 2.0 * w) * P3
                    b3 = P1 - (1.0 - 2.0 * w) * P2 - 2.0 * w * P3
                    E.cf[c, CF_SHIFT + 2] = (_dot2(b1, q1) + _dot2(b2, q2) + _dot2(b3, q3)) / length


@ti.func
def _dq(E: ti.template(), v):
    """q'(φ)X = J(R(φ) − I)X of vertex v at half its block's rotation φ = r̄/2 (the lever arm's
    change at mid-step, ``ddatai.lever_arm``)."""
    b = E.vblock[v]
    X = E.vxy[v, 0] - E.bgeo[b, BG_CX]
    Y = E.vxy[v, 1] - E.bgeo[b, BG_CY]
    c1 = E.bwork[b, BW_TRIG + 2]    # cos(r/2) − 1
    s = E.bwork[b, BW_TRIG + 3]     # sin(r/2)
    return ti.Vector([-s * X - c1 * Y, c1 * X - s * Y])


@ti.func
def lever_arms(E: ti.template(), m, any_rotation):
    """The contact vertex's lever arms at mid-step (``ddatai.lever_arm.midstep_lever_arms``,
    §5.3): the rotation column of the vertex slots (E0, E1, ES) is the step start's plus
    ∂Δ/∂P1·q'(r̄/2) (∂s/∂P1·q' for the shear), and the constant parts (after
    `second_order_shift`) take −that·r̄ (r̄ the vertex's block's rotation in ``BW_ROT``), so the
    distances stay exact at r̄. The step start's columns where no block rotates."""
    base = E.mi[m, MI_C0]
    for c in range(base, base + E.mi[m, MI_NC]):
        E.cvec[c, 6 * E0 + 2] = E.cf[c, CF_ARM]
        E.cvec[c, 6 * E1 + 2] = E.cf[c, CF_ARM + 1]
        E.cvec[c, 6 * ES + 2] = E.cf[c, CF_ARM + 2]
        if any_rotation:
            kind = E.cint[c, CI_KIND]
            for line in range(1 + kind):
                p1 = E.cint[c, 1 + 2 * line]
                k = E.cint[c, 2 + 2 * line]
                P2 = _pt(E.vxy, E.vnext[k])
                P3 = _pt(E.vxy, k)
                q1 = _dq(E, p1)
                length = _norm2(P3 - P2)
                rot = E.bwork[E.vblock[p1], BW_ROT]
                vertex = ((P2[1] - P3[1]) * q1[0] + (P3[0] - P2[0]) * q1[1]) / length
                E.cvec[c, 6 * (E0 + 2 * line) + 2] += vertex
                E.cf[c, CF_SHIFT + line] += -vertex * rot
                if line == 0 and kind == VE:
                    vertex_s = _dot2(P3 - P2, q1) / length
                    E.cvec[c, 6 * ES + 2] += vertex_s
                    E.cf[c, CF_SHIFT + 2] += -vertex_s * rot


@ti.func
def envelope(E: ti.template(), m):
    """The first row coupled to each row of member m's system (its envelope: the rows of the
    free blocks it touches, by contacts of this step)."""
    r0 = E.mi[m, MI_R0]
    for r in range(E.mi[m, MI_NF]):
        E.env[r0 + r] = r
    base = E.mi[m, MI_C0]
    for c in range(base, base + E.mi[m, MI_NC]):
        ri = E.bint[E.cint[c, CI_A], BI_ROW]
        rj = E.bint[E.cint[c, CI_B], BI_ROW]
        if ri >= 0 and rj >= 0:
            lo = ti.min(ri, rj)
            hi = ti.max(ri, rj)
            E.env[r0 + hi] = ti.min(E.env[r0 + hi], lo)


@ti.func
def hand_over(E: ti.template(), m):
    """The memory the next step starts from (`Contacts.memory`): every contact's identity,
    state, line, direction, lock point, dn and N; the bond survives on locked contacts (and on
    sliding ones when bonds do not break on slip)."""
    base = E.mi[m, MI_C0]
    keep_sliding = (E.mi[m, MI_FLAGS] & FLAG_BOND_SLIP) == 0
    for c in range(base, base + E.mi[m, MI_NC]):
        k0, k1, k2 = _key(E, c)
        st = E.cint[c, CI_STATE]
        E.memi[c, MEMI_KIND] = k0
        E.memi[c, MEMI_V0] = k1
        E.memi[c, MEMI_K2] = k2
        E.memi[c, MEMI_STATE] = st
        E.memi[c, MEMI_LINE] = E.cint[c, CI_LINE]
        kept = st == LOCK or (keep_sliding and st == SLIDE)
        E.memi[c, MEMI_BOND] = ti.cast(E.cint[c, CI_BOND] != 0 and kept, ti.i32)
        E.memi[c, MEMI_DIR] = E.cint[c, CI_DIR]
        E.memf[c, MEMF_OMEGA] = E.cf[c, CF_OMEGA]
        E.memf[c, MEMF_DN] = E.cf[c, CF_DN]
        E.memf[c, MEMF_NF] = E.cf[c, CF_NF]
    E.mi[m, MI_NM] = E.mi[m, MI_NC]
