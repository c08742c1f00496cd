"""The contact law and the open-close judgement of one member in the fused engine (Taichi
functions), contact by contact as ``ddatai.contact_law.contact_law_numpy``,
``ddatai.contact_law.violations_numpy``, ``ddatai.contact_law.judge`` and
``ddatai.contact_law.internal_force_numpy`` (docs/method/dda.md §2.8, §4.2–4.3): the law's fields
of one evaluation go to a *slot* of the contact tables (0: at the solution, 1: at the line
search's trial point)."""


import taichi as ti

from ..kernels.common import E0, E1, ES, G0, G1, GS
from .layout import (BG_LOAD, BI_ROW, BW_LEVEL, CF_COH, CF_DN, CF_DS, CF_LAW, CF_LEN, CF_NF, CF_SCA,
                     CF_SHIFT, CF_TAN, CF_TEN, CI_A, CI_B, CI_BOND, CI_COUPLED, CI_DIR, CI_KIND, CI_LAW,
                     CI_LINE, CI_STATE, FLAG_BOND_SLIP, FLAG_BY_LOAD, LF_DN, LF_DN_NOW, LF_DS, LF_ENERGY,
                     LF_FN, LF_FN_NOW, LF_FRICTION_NOW, LF_FT, LF_FT_NOW, LF_STRENGTH, LI_BAD, LI_CLOSED,
                     LI_DIR, LI_LINE, LI_STATE, MF_OC_FORCE_TOL, MF_OC_STATE_TOL, MF_PEN_LIMIT, MF_PENALTY,
                     MF_ROUNDOFF, MF_SHEAR, MI_B0, MI_B1, MI_C0, MI_FLAGS, MI_NC)

VV = 1
OPEN = 0
SLIDE = 1
LOCK = 2


@ti.func
def _dot(E: ti.template(), c, slot, b, col):
    acc = 0.0
    for a in ti.static(range(6)):
        acc += E.cvec[c, 6 * slot + a] * E.bwork[b, col + a]
    return acc


@ti.func
def evaluate(E: ti.template(), m, col, slot):
    """The contact law at the displacements in ``bwork[:, col:col+6]`` into ``slot``, without
    changing the contacts' states (`contact_law_numpy`). Returns the contacts' spring energy
    with the friction of the next solve [J/m]."""
    p = E.mf[m, MF_PENALTY]
    ks = E.mf[m, MF_SHEAR]
    limit_depth = E.mf[m, MF_PEN_LIMIT]
    total = 0.0
    base = E.mi[m, MI_C0]
    for c in range(base, base + E.mi[m, MI_NC]):
        a = E.cint[c, CI_A]
        b = E.cint[c, CI_B]
        vv = E.cint[c, CI_KIND] == VV
        now = E.cint[c, CI_STATE]
        coupled = E.cint[c, CI_COUPLED] != 0
        bond = ti.cast(E.cint[c, CI_BOND] != 0, ti.f64)
        tan_phi = E.cf[c, CF_TAN]
        length = E.cf[c, CF_LEN]
        cohesion = E.cf[c, CF_COH] * length * bond
        dn0 = E.cf[c, CF_SCA] + E.cf[c, CF_SHIFT] + _dot(E, c, E0, a, col) + _dot(E, c, G0, b, col)
        dn_now = dn0
        dn = dn0
        line = 0
        ds = 0.0
        if vv:
            # line 1: vertex1 (of block b) against an edge of block a
            dn1 = E.cf[c, CF_SCA + 1] + E.cf[c, CF_SHIFT + 1] + _dot(E, c, E1, b, col) + _dot(E, c, G1, a, col)
            if E.cint[c, CI_LINE] == 1:
                dn_now = dn1
            # the entrance line: the less penetrated, but never one the vertex was already behind
            # at the step start by more than the penetration limit (§2.8.7)
            behind0 = E.cf[c, CF_SCA] < -limit_depth
            behind1 = E.cf[c, CF_SCA + 1] < -limit_depth
            if behind0 != behind1:
                line = ti.cast(behind0, ti.i32)
            else:
                line = ti.cast(dn1 > dn0, ti.i32)
            if line == 1:
                dn = dn1
        else:
            ds = E.cf[c, CF_SCA + 2] + E.cf[c, CF_SHIFT + 2] + _dot(E, c, ES, a, col) + _dot(E, c, GS, b, col)
        allowance = bond * E.cf[c, CF_TEN] * length / p
        closed = dn <= allowance
        strength = p * ti.max(-dn, 0.0) * tan_phi + cohesion
        stale = E.cf[c, CF_NF] * tan_phi + cohesion
        used = stale
        if coupled:
            used = strength
        trial = ks * ds
        stick = ti.abs(trial) <= used
        sign_ds = 0.0
        if ds > 0.0:
            sign_ds = 1.0
        elif ds < 0.0:
            sign_ds = -1.0
        ft = 0.0
        state = OPEN
        if closed:
            state = SLIDE
            if not vv:
                ft = sign_ds * used
                if stick:
                    ft = trial
                    state = LOCK
        energy = 0.5 * p * allowance * allowance
        if dn <= allowance:
            energy = 0.5 * p * dn * dn
        if closed and not vv:
            lim = used / ks
            if ti.abs(ds) <= lim:
                energy += 0.5 * ks * ds * ds
            else:
                energy += used * (ti.abs(ds) - 0.5 * lim)
        total += energy
        fn_now = 0.0
        if now != OPEN:
            fn_now = -p * dn_now
        friction_now = stale
        if coupled:
            friction_now = cohesion - p * tan_phi * dn_now
        ft_now = 0.0
        if not vv:
            if now == LOCK:
                ft_now = trial
            elif now == SLIDE:
                ft_now = ti.cast(E.cint[c, CI_DIR], ti.f64) * friction_now
        fn = 0.0
        if closed:
            fn = -p * dn
        f = CF_LAW + 10 * slot
        E.cf[c, f + LF_DN] = dn
        E.cf[c, f + LF_DS] = ds
        E.cf[c, f + LF_FN] = fn
        E.cf[c, f + LF_FT] = ft
        E.cf[c, f + LF_STRENGTH] = strength
        E.cf[c, f + LF_DN_NOW] = dn_now
        E.cf[c, f + LF_FN_NOW] = fn_now
        E.cf[c, f + LF_FT_NOW] = ft_now
        E.cf[c, f + LF_FRICTION_NOW] = friction_now
        E.cf[c, f + LF_ENERGY] = energy
        i = CI_LAW + 5 * slot
        E.cint[c, i + LI_LINE] = line
        E.cint[c, i + LI_CLOSED] = ti.cast(closed, ti.i32)
        E.cint[c, i + LI_STATE] = state
        direction = -1
        if ds >= 0.0:
            direction = 1
        E.cint[c, i + LI_DIR] = direction
    return total


@ti.func
def violations(E: ti.template(), m, slot):
    """Mark (``LI_BAD`` of ``slot``) the contacts whose assumed state must change given the law
    of ``slot`` (`violations_numpy` states the rules). Returns how many."""
    p = E.mf[m, MF_PENALTY]
    atol = E.mf[m, MF_ROUNDOFF]
    force_tol = E.mf[m, MF_OC_FORCE_TOL]
    state_tol = E.mf[m, MF_OC_STATE_TOL]
    by_load = (E.mi[m, MI_FLAGS] & FLAG_BY_LOAD) != 0
    f = CF_LAW + 10 * slot
    i = CI_LAW + 5 * slot
    for b in range(E.mi[m, MI_B0], E.mi[m, MI_B1]):
        E.bwork[b, BW_LEVEL] = E.bgeo[b, BG_LOAD]
    base = E.mi[m, MI_C0]
    nc = E.mi[m, MI_NC]
    for c in range(base, base + nc):
        fn = ti.abs(E.cf[c, f + LF_FN])
        a = E.cint[c, CI_A]
        b = E.cint[c, CI_B]
        E.bwork[a, BW_LEVEL] = ti.max(E.bwork[a, BW_LEVEL], fn)
        E.bwork[b, BW_LEVEL] = ti.max(E.bwork[b, BW_LEVEL], fn)
    count = 0
    for c in range(base, base + nc):
        a = E.cint[c, CI_A]
        b = E.cint[c, CI_B]
        vv = E.cint[c, CI_KIND] == VV
        now = E.cint[c, CI_STATE]
        strength = E.cf[c, f + LF_STRENGTH]
        carried = ti.max(E.bwork[a, BW_LEVEL], E.bwork[b, BW_LEVEL])
        tensile = 0.0
        if E.cint[c, CI_BOND] != 0:
            tensile = E.cf[c, CF_TEN] * E.cf[c, CF_LEN]
        strict = force_tol * strength + atol
        strict_tension = force_tol * tensile + atol
        if by_load:
            # the load of the contact's free blocks only
            free_carried = 0.0
            if E.bint[a, BI_ROW] >= 0:
                free_carried = E.bwork[a, BW_LEVEL]
            if E.bint[b, BI_ROW] >= 0:
                free_carried = ti.max(free_carried, E.bwork[b, BW_LEVEL])
            strict = force_tol * free_carried + atol
            strict_tension = strict
        out = False
        if not vv and now == LOCK:
            out = ti.abs(E.cf[c, f + LF_FT_NOW]) > strength + strict
        if not vv and now == SLIDE and E.cint[c, i + LI_CLOSED] != 0:
            out = out or ti.abs(E.cf[c, f + LF_FRICTION_NOW] - strength) > strict
        if now != OPEN:
            out = out or -E.cf[c, f + LF_FN_NOW] > tensile + strict_tension
        loose = state_tol * carried + atol
        out = out or ti.abs(E.cf[c, f + LF_FN_NOW] - E.cf[c, f + LF_FN]) > loose or \
            ti.abs(E.cf[c, f + LF_FT_NOW] - E.cf[c, f + LF_FT]) > loose
        if vv and now != OPEN and E.cint[c, i + LI_LINE] != E.cint[c, CI_LINE]:
            out = out or p * ti.abs(E.cf[c, f + LF_DN] - E.cf[c, f + LF_DN_NOW]) > loose
        E.cint[c, i + LI_BAD] = ti.cast(out, ti.i32)
        if out:
            count += 1
    return count


@ti.func
def judge(E: ti.template(), m, slot, couple):
    """The open-close judgement (`ddatai.contact_law.judge`) in place on the contacts, with the law
    and the violations of ``slot``: bonds that fail break, the contacts that must change take the
    law's state (a sliding contact whose slip turns round locks first; one that starts sliding
    takes its friction from its own solve when ``couple``), normal forces and distances follow
    the solve. Returns (changed, the largest |shear force| − strength of a closed vertex-edge
    contact when nothing changed)."""
    f = CF_LAW + 10 * slot
    i = CI_LAW + 5 * slot
    bond_slip = (E.mi[m, MI_FLAGS] & FLAG_BOND_SLIP) != 0
    base = E.mi[m, MI_C0]
    nc = E.mi[m, MI_NC]
    changed = 0
    for c in range(base, base + nc):
        if E.cint[c, i + LI_BAD] != 0:
            changed = 1
    coulomb = 0.0
    for c in range(base, base + nc):
        vv = E.cint[c, CI_KIND] == VV
        bad = E.cint[c, i + LI_BAD] != 0
        law_state = E.cint[c, i + LI_STATE]
        if E.cint[c, CI_BOND] != 0 and law_state != LOCK and bad and \
                (law_state == OPEN or (bond_slip and law_state == SLIDE)):
            E.cint[c, CI_BOND] = 0
        if changed and bad:
            if E.cint[c, CI_STATE] == SLIDE and law_state == SLIDE and E.cint[c, i + LI_DIR] != E.cint[c, CI_DIR]:
                law_state = LOCK  # its slip turns round: it passes through sticking
            if law_state == SLIDE and not vv:
                if couple:
                    E.cint[c, CI_COUPLED] = 1
                E.cint[c, CI_DIR] = E.cint[c, i + LI_DIR]
            E.cint[c, CI_STATE] = law_state
            E.cint[c, CI_LINE] = E.cint[c, i + LI_LINE]
        closed = E.cint[c, i + LI_CLOSED] != 0
        if closed:
            E.cf[c, CF_NF] = ti.max(E.cf[c, f + LF_FN], 0.0)
        elif E.cint[c, CI_STATE] != OPEN or vv:
            E.cf[c, CF_NF] = 0.0
        if bad:
            E.cf[c, CF_DN] = E.cf[c, f + LF_DN]
        else:
            E.cf[c, CF_DN] = E.cf[c, f + LF_DN_NOW]
        E.cf[c, CF_DS] = E.cf[c, f + LF_DS]
        if not changed and E.cint[c, CI_STATE] != OPEN and not vv:
            coulomb = ti.max(coulomb, ti.abs(E.cf[c, f + LF_FT_NOW]) - E.cf[c, f + LF_STRENGTH])
    return changed, coulomb


@ti.func
def internal_force(E: ti.template(), m, slot, out):
    """Add the generalised forces of the law's contact forces of ``slot`` (p·dn·∇dn of a closed
    contact's active line and f_t·∇ds) into ``xvec[out:out+n]`` (`internal_force_numpy`)."""
    f = CF_LAW + 10 * slot
    i = CI_LAW + 5 * slot
    base = E.mi[m, MI_C0]
    for c in range(base, base + E.mi[m, MI_NC]):
        pull = -E.cf[c, f + LF_FN]
        ft = E.cf[c, f + LF_FT]
        sa = E0
        sb = G0
        if E.cint[c, i + LI_LINE] == 1:
            sa = G1
            sb = E1
        ra = E.bint[E.cint[c, CI_A], BI_ROW]
        rb = E.bint[E.cint[c, CI_B], BI_ROW]
        for k in ti.static(range(6)):
            if ra >= 0:
                E.xvec[out + 6 * ra + k] += pull * E.cvec[c, 6 * sa + k] + ft * E.cvec[c, 6 * ES + k]
            if rb >= 0:
                E.xvec[out + 6 * rb + k] += pull * E.cvec[c, 6 * sb + k] + ft * E.cvec[c, 6 * GS + k]
