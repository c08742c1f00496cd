"""One try of a step of one member in the fused engine (Taichi functions): the block terms and
the open-close iteration with its line search, as ``ddatai.step.Stepper.attempt`` and
``ddatai.open_close.open_close`` (docs/method/dda.md §4): each solve takes the contact states at
the last iterate; from the second solve on a step that overshoots into states that send the
next one back is shortened by a backtracking (Armijo) line search on the energy; lagged
friction that stalls goes on coupled. The step's last try at the shortest Δt, where today's
path holds cycling contacts closed (``open_close.hold_cycling``), is recognised here (a set of
states met again) and handed to today's path."""


import taichi as ti

from . import blocks, contacts, law, system
from .layout import (BG_CX, BG_CY, BI_ROW, BS_ACC, BS_VEL, BW_D, BW_PREV, BW_ROT, BW_SOL, BW_TRIG, CF_TAN, CI_COUPLED,
                     CI_KIND, CI_LAW, CI_STATE, FLAG_LAGGED, FLAG_MIDSTEP, LI_BAD, MF_CARRY, MF_FIXED_PEN, MI_B0,
                     MI_B1, MI_C0, MI_FLAGS, MI_NC,
                     MI_NF, MI_OC_MAX, MI_P0, MI_P1, MI_X0, PF_X, PF_Y, PI_BLOCK, PI_KIND, POINT_FIXED,
                     XS_BRHS, XS_GRAD, XS_HASH, XS_RHS)

OK, NAN, OPEN_CLOSE = 0, 1, 2
VE = 0
SLIDE = 1
#: states hashed modulo this prime (products stay exact in float64) to recognise a cycle
HASH_PRIME = 67108859.0
#: the line search stops halving at this step (`open_close.line_search`)
SMALLEST_STEP = 1.0 / 256


@ti.func
def _fixed_point_shift(E: ti.template(), m, rhs):
    """Second-order terms of the fixed-point springs, −p_f·Tᵀq, into ``xvec[rhs:]``
    (`assembly.second_order`)."""
    fpp = E.mf[m, MF_FIXED_PEN]
    for p in range(E.mi[m, MI_P0], E.mi[m, MI_P1]):
        b = E.pint[p, PI_BLOCK]
        r = E.bint[b, BI_ROW]
        if E.pint[p, PI_KIND] == POINT_FIXED and r >= 0:
            X = E.pf[p, PF_X] - E.bgeo[b, BG_CX]
            Y = E.pf[p, PF_Y] - E.bgeo[b, BG_CY]
            c1 = E.bwork[b, BW_TRIG]
            sr = E.bwork[b, BW_TRIG + 1]
            qx = c1 * X + sr * -Y
            qy = c1 * Y + sr * X
            # T(X, Y)ᵀ q
            tq = ti.Vector([qx, qy, -Y * qx + X * qy, X * qx, Y * qy, 0.5 * (Y * qx + X * qy)])
            for a in ti.static(range(6)):
                E.xvec[rhs + 6 * r + a] += -fpp * tq[a]


@ti.func
def _states_hash(E: ti.template(), m):
    h = 0.0
    base = E.mi[m, MI_C0]
    for c in range(base, base + E.mi[m, MI_NC]):
        h = (h * 3.0 + ti.cast(E.cint[c, CI_STATE], ti.f64)) % HASH_PRIME
    return h


@ti.func
def _copy_disp(E: ti.template(), m, src, dst):
    for b in range(E.mi[m, MI_B0], E.mi[m, MI_B1]):
        for a in ti.static(range(6)):
            E.bwork[b, dst + a] = E.bwork[b, src + a]


@ti.func
def _trial(E: ti.template(), m, alpha):
    """The trial point D = D_last + α·(D_solution − D_last) into ``BW_D``."""
    for b in range(E.mi[m, MI_B0], E.mi[m, MI_B1]):
        for a in ti.static(range(6)):
            E.bwork[b, BW_D + a] = E.bwork[b, BW_PREV + a] + alpha * (E.bwork[b, BW_SOL + a] - E.bwork[b, BW_PREV + a])


@ti.func
def open_close(E: ti.template(), m, dt, beta, last):
    """One try of the step with Δt = ``dt``: the block terms, then the open-close iteration
    in place on the contacts, from the states they hold (the step's: `contacts.restore`, or the
    first try's converged ones for the impact step taken again: `ddatai.fused.step`). The
    accepted iterate is left in ``BW_SOL``. ``last``: the step's last try (a cycle of states is
    then handed to today's path). Returns (cycled, cause OK / NAN / OPEN_CLOSE, solves, the converged solve's
    largest excess of a shear force over its strength)."""
    nf = E.mi[m, MI_NF]
    n = 6 * nf
    xs = E.mi[m, MI_X0]
    rhs = xs + XS_RHS * n
    brhs = xs + XS_BRHS * n
    grad = xs + XS_GRAD * n
    hashes = xs + XS_HASH * n
    system.clear_block_terms(E, m)
    blocks.block_terms(E, m, dt, beta)
    carry = E.mf[m, MF_CARRY]
    for b in range(E.mi[m, MI_B0], E.mi[m, MI_B1]):
        rot = 0.0
        if E.bint[b, BI_ROW] >= 0:
            # the rotation predicted from the carried motion (for the second-order terms)
            rot = dt * carry * E.bst[b, BS_VEL + 2] + 0.5 * dt * dt * E.bst[b, BS_ACC + 2]
        E.bwork[b, BW_ROT] = rot
    lagged = (E.mi[m, MI_FLAGS] & FLAG_LAGGED) != 0
    base = E.mi[m, MI_C0]
    nc = E.mi[m, MI_NC]
    if lagged:
        for c in range(base, base + nc):
            E.cint[c, CI_COUPLED] = 0
    fewest = nc + 1
    since = 0
    n_seen = 0
    if last:
        E.xvec[hashes] = _states_hash(E, m)
        n_seen = 1
    has_previous = 0
    cause = OPEN_CLOSE
    cycled = 0
    iterations = E.mi[m, MI_OC_MAX]
    coulomb = 0.0
    it = 1
    while it <= E.mi[m, MI_OC_MAX]:
        any_rotation = 0
        for b in range(E.mi[m, MI_B0], E.mi[m, MI_B1]):
            rot = E.bwork[b, BW_ROT]
            if rot != 0.0:
                any_rotation = 1
            # each block's once, not each contact vertex's (`contacts._q`, `contacts._dq`); a
            # fixed block's rotation is +0 (its D is), whose terms are +0 exactly
            t0 = 0.0
            t1 = 0.0
            t2 = 0.0
            t3 = 0.0
            if E.bint[b, BI_ROW] >= 0:
                t0 = ti.cos(rot) - 1.0
                t1 = ti.sin(rot) - rot
                t2 = ti.cos(0.5 * rot) - 1.0
                t3 = ti.sin(0.5 * rot)
            E.bwork[b, BW_TRIG] = t0
            E.bwork[b, BW_TRIG + 1] = t1
            E.bwork[b, BW_TRIG + 2] = t2
            E.bwork[b, BW_TRIG + 3] = t3
        contacts.second_order_shift(E, m, any_rotation)
        # the vertex's lever arms at mid-step (Params.midstep_lever_arms; else the step start's)
        contacts.lever_arms(E, m, any_rotation and (E.mi[m, MI_FLAGS] & FLAG_MIDSTEP) != 0)
        system.load_block_terms(E, m)
        if any_rotation:
            _fixed_point_shift(E, m, rhs)
        for i in range(n):
            E.xvec[brhs + i] = E.xvec[rhs + i]
        symmetric = system.contact_terms(E, m)
        finite = system.factor(E, m, symmetric)
        if finite:
            finite = system.solve(E, m)
        if not finite:
            cause = NAN
            iterations = it
            break
        # the law at the solution; from the second solve on, where a contact must change, the
        # line search from the last iterate: every evaluation of the law at one place (one
        # copy of it in the compiled kernel), ``stage`` 0: the solution (slot 0), 1: the last
        # iterate, 2: a trial point (slot 1) (`open_close.line_search`)
        slot = 0
        disp = BW_SOL
        stage = 0
        energy_solution = 0.0
        base_energy = 0.0
        slope = 0.0
        alpha = 1.0
        while True:
            col = BW_SOL
            s = 0
            if stage == 1:
                col = BW_PREV
                s = 1
            elif stage == 2:
                col = BW_D
                s = 1
            energy = law.evaluate(E, m, col, s)
            if stage != 0 or has_previous != 0:
                # the energy at the solution is read only by a line search (from the second solve)
                energy += system.block_energy(E, m, col, brhs)
            bad = 0
            if stage != 1:
                bad = law.violations(E, m, s)  # (one place in the compiled kernel)
            if stage == 0:
                energy_solution = energy
                if has_previous == 0 or bad == 0:
                    break
                stage = 1
                continue
            if stage == 1:
                base_energy = energy
                system.block_gradient(E, m, BW_PREV, brhs, grad)
                law.internal_force(E, m, 1, grad)
                slope = 0.0
                for b in range(E.mi[m, MI_B0], E.mi[m, MI_B1]):
                    r = E.bint[b, BI_ROW]
                    if r >= 0:
                        for a in range(6):
                            slope += E.xvec[grad + 6 * r + a] * (E.bwork[b, BW_SOL + a] - E.bwork[b, BW_PREV + a])
                if slope >= 0 or energy_solution <= base_energy + 1e-4 * slope:
                    break  # not a descent direction (coupled friction), or the whole step is taken
                stage = 2
            elif alpha <= SMALLEST_STEP or energy <= base_energy + 1e-4 * alpha * slope:
                # the shortened step stops before the contacts that change state on the way;
                # where none changes there yet, the states change as the solution asks
                if bad > 0:
                    slot = 1
                    disp = BW_D
                break
            alpha *= 0.5
            _trial(E, m, alpha)
        for b in range(E.mi[m, MI_B0], E.mi[m, MI_B1]):
            E.bwork[b, BW_ROT] = E.bwork[b, disp + 2]
        changed, excess = law.judge(E, m, slot, not lagged)
        if changed == 0 and slot == 0:
            cause = OK
            iterations = it
            coulomb = excess
            break
        _copy_disp(E, m, disp, BW_PREV)
        has_previous = 1
        if last:
            h = _states_hash(E, m)
            for k in range(n_seen):
                if E.xvec[hashes + k] == h:
                    cycled = 1
            E.xvec[hashes + n_seen] = h
            n_seen += 1
            if cycled:
                iterations = it
                break
        if lagged:
            changing = 0
            for c in range(base, base + nc):
                if E.cint[c, CI_LAW + 5 * slot + LI_BAD] != 0:
                    changing += 1
            if changing < fewest:
                fewest = changing
                since = 0
            else:
                since += 1
            if since >= 3:
                # stalled: coupled friction (LU) from here, with the same acceptance test
                lagged = False
                for c in range(base, base + nc):
                    E.cint[c, CI_COUPLED] = ti.cast(E.cint[c, CI_STATE] == SLIDE and E.cint[c, CI_KIND] == VE
                                                    and E.cf[c, CF_TAN] > 0, ti.i32)
        it += 1
    return cycled, cause, iterations, coulomb
