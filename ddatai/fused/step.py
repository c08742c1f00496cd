"""One DDA step of one member in the fused engine (Taichi functions), phase by phase as
``ddatai.step.Stepper.advance`` (docs/method/dda.md §0): Δt (§4.6), detection and transfer (§3),
tries of the open-close iteration with its line search (§4) until one is accepted (§4.4–4.5),
the update (§5) and the energy balance. The phases' bodies live in `ddatai.fused.blocks`,
`ddatai.fused.contacts`, `ddatai.fused.system`, `ddatai.fused.law` and `ddatai.fused.iterate`."""


import taichi as ti

from . import blocks, contacts, law
from .impacts import approach_bound, impact_projection, impacted, plastic_start, swap_start
from .iterate import open_close
from .layout import BW_PREV
from .layout import (BG_AREA, BG_CX, BG_CY, BG_RADIUS, BI_ROW, BI_V0, BI_V1, BM_C, BM_RHO, BS_ACC, BS_ROT, BS_STRESS,
                     BS_VEL, BW_SOL, CAUSE_CYCLES, CAUSE_FAILED, CF_DN, CF_DN0, CF_DS, CF_DS0, CF_LAW, CI_A,
                     CI_B, CI_DIR, CI_KIND, CI_STATE, CI_STATE0, DIVERT, FLAG_AUTO_PENALTY, FLAG_RECORD,
                     FLAG_STATIC, GROW, LF_FRICTION_NOW, MF_ACCEL, MF_BETA, MF_CARRY, MF_DISP_REJECT, MF_DT,
                     MF_DT_CUT, MF_DT_FIXED, MF_DT_GROWTH, MF_DT_MAX, MF_DT_MIN_RATIO, MF_ENERGY,
                     MF_FIXED_PEN, MF_FIXED_RATIO, MF_GX, MF_GY, MF_MAX_STEP, MF_OPEN_RATIO, MF_PEN_LIMIT,
                     MF_PENALTY, MF_ROUNDOFF, MF_SHEAR, MF_SHEAR_RATIO, MF_START_PEN, MF_T_END, MF_TIME,
                     MF_W0, MI_B0, MI_B1, MI_C0, MI_CAUSE, MI_CCAP, MI_FLAGS, MI_HAVE_ENERGY, MI_NC,
                     MI_P0, MI_P1, MI_RAISED, MI_S0, MI_SCAP, MI_SN, MI_STEP, MI_V0, MI_V1, PF_FX, PF_FY,
                     PF_X, PF_X0, PF_Y, PF_Y0, PI_BLOCK, PI_KIND, POINT_FIXED, POINT_LOAD, RC_CLOSED,
                     RC_CONTACT, RC_CONTACTS, RC_COULOMB, RC_CUTS, RC_DT, RC_EXTERNAL, RC_FRICTION,
                     RC_GRAVITATIONAL, RC_INTEGRATOR, RC_KINETIC, RC_MAX_DISP, RC_MAX_PEN, RC_OC,
                     RC_OC_TOTAL, RC_PENALTY, RC_STRAIN, RC_TIME, RUNNING)

VE = 0
OPEN = 0
SLIDE = 1
LOCK = 2
# causes of a rejected try (`ddatai.step.Attempt.cause`)
OK, NAN, OPEN_CLOSE, DISPLACEMENT, INVERTED, PENETRATION = range(6)


@ti.func
def time_step(E: ti.template(), m):
    """Automatic Δt (§4.6, `ddatai.time_step.choose_time_step`), ending on the member's end
    time without a sliver (`time_step.end_on`)."""
    return end_on(E, m, rule(E, m, 1))


@ti.func
def end_on(E: ti.template(), m, limit):
    """Δt shortened to land on the member's end time without a sliver (`time_step.end_on`)."""
    remaining = E.mf[m, MF_T_END] - E.mf[m, MF_TIME]
    out = limit
    if remaining <= limit * (1.0 + 1e-9):
        out = remaining
    elif remaining < 2.0 * limit:
        out = 0.5 * remaining
    return out


@ti.func
def rule(E: ti.template(), m, grow):
    """`time_step.choose_time_step`; ``grow`` 0: without the growth limit."""
    dt_fixed = E.mf[m, MF_DT_FIXED]
    limit = E.mf[m, MF_DT_MAX]
    if dt_fixed > 0.0:
        limit = dt_fixed
    b0 = E.mi[m, MI_B0]
    b1 = E.mi[m, MI_B1]
    if dt_fixed <= 0.0:
        speed = 0.0
        nfree = 0
        for b in range(b0, b1):
            if E.bint[b, BI_ROW] >= 0:
                nfree += 1
                v = ti.sqrt(E.bst[b, BS_VEL] ** 2 + E.bst[b, BS_VEL + 1] ** 2) + \
                    ti.abs(E.bst[b, BS_VEL + 2]) * E.bgeo[b, BG_RADIUS]
                speed = ti.max(speed, v)
        if nfree > 0:
            acc = ti.sqrt(E.mf[m, MF_GX] ** 2 + E.mf[m, MF_GY] ** 2)
            load_acc = 0.0
            has_load = 0
            for p in range(E.mi[m, MI_P0], E.mi[m, MI_P1]):
                if E.pint[p, PI_KIND] == POINT_LOAD:
                    b = E.pint[p, PI_BLOCK]
                    f = ti.sqrt(E.pf[p, PF_FX] ** 2 + E.pf[p, PF_FY] ** 2)
                    a_load = f / (E.bmat[b, BM_RHO] * E.bgeo[b, BG_AREA])
                    if has_load == 0 or a_load > load_acc:
                        load_acc = a_load
                    has_load = 1
            acc += load_acc
            if E.mi[m, MI_STEP] == 0:
                # initial stresses accelerate a block's strain (ntdda's first-step estimate)
                s_acc = 0.0
                for b in range(b0, b1):
                    if E.bint[b, BI_ROW] >= 0:
                        s = ti.max(ti.abs(E.bst[b, BS_STRESS]), ti.abs(E.bst[b, BS_STRESS + 1]),
                                   ti.abs(E.bst[b, BS_STRESS + 2]))
                        area = E.bgeo[b, BG_AREA]
                        s_acc = ti.max(s_acc, 4.0 * s * ti.sqrt(area) / (area * E.bmat[b, BM_RHO]))
                acc += s_acc
            acc = ti.max(acc, E.mf[m, MF_ACCEL])
            u = E.mf[m, MF_MAX_STEP]
            dt = limit
            if acc > 0 or speed > 0:
                dt = 2.0 * u / (speed + ti.sqrt(speed * speed + 2.0 * acc * u))
            limit = ti.min(limit, dt)
    if grow and E.mf[m, MF_DT] > 0:
        limit = ti.min(limit, E.mf[m, MF_DT_GROWTH] * E.mf[m, MF_DT])
    return limit


@ti.func
def accept(E: ti.template(), m):
    """The acceptance checks of a converged solution (§4.5, `Stepper.accept`): the vertices
    moved by D (into ``vnew``), the largest displacement and penetration. Returns (cause,
    largest vertex displacement, deepest penetration, ratio)."""
    umax = 0.0
    # block by block (a block's vertices are contiguous): the rotation's cosine and sine once a
    # block; a fixed block's vertices stay where they are (its D is zero)
    for b in range(E.mi[m, MI_B0], E.mi[m, MI_B1]):
        if E.bint[b, BI_ROW] >= 0:
            r = E.bwork[b, BW_SOL + 2]
            c = ti.cos(r)
            s = ti.sin(r)
            for v in range(E.bint[b, BI_V0], E.bint[b, BI_V1]):
                nx, ny = blocks.moved_by(E, b, E.vxy[v, 0], E.vxy[v, 1], BW_SOL, c, s)
                E.vnew[v, 0] = nx
                E.vnew[v, 1] = ny
                umax = ti.max(umax, ti.sqrt((nx - E.vxy[v, 0]) ** 2 + (ny - E.vxy[v, 1]) ** 2))
        else:
            for v in range(E.bint[b, BI_V0], E.bint[b, BI_V1]):
                E.vnew[v, 0] = E.vxy[v, 0]
                E.vnew[v, 1] = E.vxy[v, 1]
    pen = 0.0
    base = E.mi[m, MI_C0]
    for c in range(base, base + E.mi[m, MI_NC]):
        if E.cint[c, CI_STATE] != OPEN:
            pen = ti.max(pen, -E.cf[c, CF_DN])
    ratio = umax / E.mf[m, MF_MAX_STEP]
    cause = OK
    if ratio > E.mf[m, MF_DISP_REJECT]:
        cause = DISPLACEMENT
    else:
        inverted = 0
        for b in range(E.mi[m, MI_B0], E.mi[m, MI_B1]):
            if E.bint[b, BI_ROW] >= 0:
                e0 = E.bwork[b, BW_SOL + 3]
                e1 = E.bwork[b, BW_SOL + 4]
                e2 = E.bwork[b, BW_SOL + 5]
                if (1.0 + e0) * (1.0 + e1) - 0.25 * e2 * e2 <= 0.0:
                    inverted = 1
        if inverted == 1:
            cause = INVERTED
        elif pen > E.mf[m, MF_PEN_LIMIT]:
            cause = PENETRATION
    return cause, umax, pen, ratio


@ti.func
def energies(E: ti.template(), m, dn_col, ds_col, state_col):
    """(kinetic, gravitational, strain, contact) energy of the member's state [J/m]
    (`ddatai.energy.state_energy`): contacts with their distances in ``cf[:, dn_col]``,
    ``cf[:, ds_col]`` and their states in ``cint[:, state_col]``."""
    kinetic = 0.0
    grav = 0.0
    strain = 0.0
    for b in range(E.mi[m, MI_B0], E.mi[m, MI_B1]):
        if E.bint[b, BI_ROW] >= 0:
            kinetic += blocks.kinetic_energy(E, b)
            grav -= E.bmat[b, BM_RHO] * E.bgeo[b, BG_AREA] * \
                (E.bgeo[b, BG_CX] * E.mf[m, MF_GX] + E.bgeo[b, BG_CY] * E.mf[m, MF_GY])
            strain += blocks.strain_energy(E, b)
    springs = 0.0
    for p in range(E.mi[m, MI_P0], E.mi[m, MI_P1]):
        if E.pint[p, PI_KIND] == POINT_FIXED:
            springs += (E.pf[p, PF_X0] - E.pf[p, PF_X]) ** 2 + (E.pf[p, PF_Y0] - E.pf[p, PF_Y]) ** 2
    springs *= 0.5 * E.mf[m, MF_FIXED_PEN]
    normal = 0.0
    shear = 0.0
    base = E.mi[m, MI_C0]
    for c in range(base, base + E.mi[m, MI_NC]):
        st = E.cint[c, state_col]
        if st != OPEN:
            normal += E.cf[c, dn_col] ** 2
        if st == LOCK:
            shear += E.cf[c, ds_col] ** 2
    contact = 0.5 * (E.mf[m, MF_PENALTY] * normal + E.mf[m, MF_SHEAR] * shear)
    return kinetic, grav, strain, springs + contact


@ti.func
def work(E: ti.template(), m):
    """(external work, friction dissipation) of the accepted solve (`ddatai.energy.step_work`):
    the point loads on the linear displacements T·D; friction S·dir·slip of the sliding
    vertex-edge contacts, S of the accepted solve (law slot 0)."""
    external = 0.0
    for p in range(E.mi[m, MI_P0], E.mi[m, MI_P1]):
        if E.pint[p, PI_KIND] == POINT_LOAD:
            b = E.pint[p, PI_BLOCK]
            X = E.pf[p, PF_X] - E.bgeo[b, BG_CX]
            Y = E.pf[p, PF_Y] - E.bgeo[b, BG_CY]
            d = blocks.block_disp_row(E, b, BW_SOL)
            ux = d[0] - Y * d[2] + X * d[3] + 0.5 * Y * d[5]
            uy = d[1] + X * d[2] + Y * d[4] + 0.5 * X * d[5]
            external += E.pf[p, PF_FX] * ux + E.pf[p, PF_FY] * uy
    friction = 0.0
    base = E.mi[m, MI_C0]
    for c in range(base, base + E.mi[m, MI_NC]):
        if E.cint[c, CI_STATE] == SLIDE and E.cint[c, CI_KIND] == VE:
            slip = law._dot(E, c, 4, E.cint[c, CI_A], BW_SOL) + law._dot(E, c, 5, E.cint[c, CI_B], BW_SOL)
            friction += E.cf[c, CF_LAW + LF_FRICTION_NOW] * ti.cast(E.cint[c, CI_DIR], ti.f64) * slip
    return external, friction


@ti.func
def update(E: ti.template(), m, dt, beta):
    """The state after the accepted step (`ddatai.kinematics.update`): vertices and points moved
    with the exact rotation, stresses incremented and rotated, Newmark's velocities and
    accelerations (γ = 1), the largest velocity change, the geometry at the new vertices."""
    carry = E.mf[m, MF_CARRY]
    static = (E.mi[m, MI_FLAGS] & FLAG_STATIC) != 0
    accel = 0.0
    for p in range(E.mi[m, MI_P0], E.mi[m, MI_P1]):
        nx, ny = blocks.moved(E, E.pint[p, PI_BLOCK], E.pf[p, PF_X], E.pf[p, PF_Y], BW_SOL)
        E.pf[p, PF_X] = nx
        E.pf[p, PF_Y] = ny
    for b in range(E.mi[m, MI_B0], E.mi[m, MI_B1]):
        d = blocks.block_disp_row(E, b, BW_SOL)
        if E.bint[b, BI_ROW] >= 0:
            sx = E.bst[b, BS_STRESS]
            sy = E.bst[b, BS_STRESS + 1]
            t = E.bst[b, BS_STRESS + 2]
            inc = ti.Vector([0.0, 0.0, 0.0])
            for i in ti.static(range(3)):
                for j in ti.static(range(3)):
                    inc[i] += E.bmat[b, BM_C + 3 * i + j] * d[3 + j]
            nsx, nsy, nt = blocks.rotate_stress(sx + inc[0], sy + inc[1], t + inc[2], d[2])
            E.bst[b, BS_STRESS] = nsx
            E.bst[b, BS_STRESS + 1] = nsy
            E.bst[b, BS_STRESS + 2] = nt
            dvx = 0.0
            dvy = 0.0
            dvr = 0.0
            for a in ti.static(range(6)):
                v_old = E.bst[b, BS_VEL + a]
                carried = carry * v_old
                acc_new = (d[a] - carried * dt) / (beta * dt * dt) - (0.5 / beta - 1.0) * E.bst[b, BS_ACC + a]
                v_new = carried + dt * acc_new
                if a == 0:
                    dvx = v_new - v_old
                elif a == 1:
                    dvy = v_new - v_old
                elif a == 2:
                    dvr = v_new - v_old
                if static:
                    v_new = 0.0
                    acc_new = 0.0
                E.bst[b, BS_VEL + a] = v_new
                E.bst[b, BS_ACC + a] = acc_new
            accel = ti.max(accel, ti.sqrt(dvx * dvx + dvy * dvy) + ti.abs(dvr) * E.bgeo[b, BG_RADIUS])
        E.bst[b, BS_ROT] += d[2]
    for v in range(E.mi[m, MI_V0], E.mi[m, MI_V1]):
        E.vxy[v, 0] = E.vnew[v, 0]
        E.vxy[v, 1] = E.vnew[v, 1]
    for b in range(E.mi[m, MI_B0], E.mi[m, MI_B1]):
        if E.bint[b, BI_ROW] >= 0:  # a fixed block's vertices did not move: nor did its geometry
            blocks.geometry(E, b)
            E.bgeo[b, BG_RADIUS] = blocks.radius(E, b)
    return accel / dt


@ti.func
def follow_load(E: ti.template(), m, max_pen):
    """Raise the automatic penalty for the rest of the run when the step's deepest contact went
    past half the penetration limit (`ddatai.step.Stepper.follow_load`). Returns whether."""
    raised = 0
    limit = E.mf[m, MF_PEN_LIMIT]
    p = E.mf[m, MF_PENALTY]
    if (E.mi[m, MI_FLAGS] & FLAG_AUTO_PENALTY) != 0 and max_pen > 0.5 * limit:
        new = ti.min(p * max_pen / (0.25 * limit), 100.0 * E.mf[m, MF_START_PEN])
        if new > p:
            E.mf[m, MF_PENALTY] = new
            E.mf[m, MF_SHEAR] = new / E.mf[m, MF_SHEAR_RATIO]
            E.mf[m, MF_FIXED_PEN] = E.mf[m, MF_FIXED_RATIO] * new
            E.mf[m, MF_ROUNDOFF] = E.mf[m, MF_OPEN_RATIO] * E.mf[m, MF_W0] * new
            E.mi[m, MI_RAISED] = 1
            raised = 1
    return raised


@ti.func
def step(E: ti.template(), m):
    """Advance member m one step. Returns RUNNING (accepted), GROW (its contacts outgrew their
    region: nothing changed) or DIVERT (a try that today's path takes over: nothing changed).
    With ``FLAG_RECORD`` the step's record goes to the next row of the member's ``rec``."""
    result = RUNNING
    dt = time_step(E, m)
    n = contacts.detect(E, m)
    if n > E.mi[m, MI_CCAP]:
        result = GROW
    else:
        contacts.start(E, m, n)
        contacts.vectors(E, m)
        contacts.envelope(E, m)
        beta = E.mf[m, MF_BETA]
        if E.mi[m, MI_STEP] == 0:
            beta = 0.5
        shortest = E.mf[m, MF_DT_MAX] * E.mf[m, MF_DT_MIN_RATIO]
        if E.mf[m, MF_DT_FIXED] > 0.0:
            shortest = E.mf[m, MF_DT_FIXED] * E.mf[m, MF_DT_MIN_RATIO]
        # the step before a closing ends just before it; the impact step (`ddatai.impacts`)
        bound = approach_bound(E, m, dt, rule(E, m, 0))
        dt = end_on(E, m, ti.max(bound, ti.min(dt, shortest)))
        static = (E.mi[m, MI_FLAGS] & FLAG_STATIC) != 0
        # 0: the tries of the step; 1: the impact step taken again from the plastic impact at
        # its start; 2: that failed, the accepted try again from the state before the impact
        retry = 0
        applied = 0
        cuts = 0
        oc_total = 0
        cause = OK
        iterations = 0
        umax = 0.0
        pen = 0.0
        coulomb = 0.0
        while True:
            last = dt * E.mf[m, MF_DT_CUT] < shortest and retry != 1
            # each try starts from the step start's contact states; the impact step taken again
            # from the first try's converged ones, left in place (`ddatai.impacts.resumed`)
            if retry != 1:
                contacts.restore(E, m)
            cycled, cause_oc, its, excess = open_close(E, m, dt, beta, last)
            cause = cause_oc
            iterations = its
            coulomb = excess
            if retry != 2:
                oc_total += its
            if cycled:
                result = DIVERT
                E.mi[m, MI_CAUSE] = CAUSE_CYCLES
                break
            ratio = 0.0
            if cause == OK:
                cause, umax, pen, ratio = accept(E, m)
            if retry == 1:
                if cause == OK:
                    break
                swap_start(E, m)  # the state before the impact, and its accepted try again
                applied = 0
                retry = 2
                continue
            if retry == 2:
                break
            if cause == OK:
                if not static and impacted(E, m):
                    # a plastic impact at the step's start: the impacted blocks take the step
                    # again from their velocity projected onto what its closed contacts admit
                    if impact_projection(E, m, dt, beta):
                        for b in range(E.mi[m, MI_B0], E.mi[m, MI_B1]):
                            for a in ti.static(range(6)):
                                E.bwork[b, BW_SOL + a] = E.bwork[b, BW_PREV + a]
                        break
                    plastic_start(E, m)
                    applied = 1
                    retry = 1
                    continue
                break
            cuts += 1
            new_dt = dt * E.mf[m, MF_DT_CUT]
            if cause == DISPLACEMENT:
                new_dt = dt / ti.sqrt(ratio)
            if new_dt < shortest:
                result = DIVERT
                E.mi[m, MI_CAUSE] = CAUSE_FAILED
                break
            dt = new_dt
        if result == RUNNING:
            external, friction = work(E, m)
            accel = 0.0
            k1 = 0.0
            g1 = 0.0
            s1 = 0.0
            c1 = 0.0
            # the energy at the step's start (once: then the last step's end energy), the update,
            # the energy at its end (one place in the compiled kernel for both energies)
            for phase in range(2):
                if phase == 1:
                    accel = update(E, m, dt, beta)
                    contacts.hand_over(E, m)
                if phase == 1 or E.mi[m, MI_HAVE_ENERGY] == 0:
                    dn_col = CF_DN0
                    ds_col = CF_DS0
                    state_col = CI_STATE0
                    if phase == 1:
                        dn_col = CF_DN
                        ds_col = CF_DS
                        state_col = CI_STATE
                    if phase == 0 and applied:
                        swap_start(E, m)  # the energy before the plastic impact
                    k1, g1, s1, c1 = energies(E, m, dn_col, ds_col, state_col)
                    if phase == 0 and applied:
                        swap_start(E, m)
                    if phase == 0:
                        E.mf[m, MF_ENERGY] = k1 + g1 + s1 + c1
            total = k1 + g1 + s1 + c1
            dissipated = external - (total - E.mf[m, MF_ENERGY]) - friction
            E.mf[m, MF_ENERGY] = total
            E.mi[m, MI_HAVE_ENERGY] = 1
            E.mf[m, MF_TIME] += dt
            E.mf[m, MF_DT] = dt
            E.mf[m, MF_ACCEL] = accel
            E.mi[m, MI_STEP] += 1
            if (E.mi[m, MI_FLAGS] & FLAG_RECORD) != 0 and E.mi[m, MI_SN] < E.mi[m, MI_SCAP]:
                closed = 0
                base = E.mi[m, MI_C0]
                for c in range(base, base + E.mi[m, MI_NC]):
                    if E.cint[c, CI_STATE] != OPEN:
                        closed += 1
                row = E.mi[m, MI_S0] + E.mi[m, MI_SN]
                E.rec[row, RC_TIME] = E.mf[m, MF_TIME]
                E.rec[row, RC_DT] = dt
                E.rec[row, RC_OC] = iterations
                E.rec[row, RC_OC_TOTAL] = oc_total
                E.rec[row, RC_CUTS] = cuts
                E.rec[row, RC_CONTACTS] = E.mi[m, MI_NC]
                E.rec[row, RC_CLOSED] = closed
                E.rec[row, RC_MAX_PEN] = ti.max(pen, 0.0)
                E.rec[row, RC_MAX_DISP] = umax
                E.rec[row, RC_KINETIC] = k1
                E.rec[row, RC_GRAVITATIONAL] = g1
                E.rec[row, RC_STRAIN] = s1
                E.rec[row, RC_CONTACT] = c1
                E.rec[row, RC_EXTERNAL] = external
                E.rec[row, RC_FRICTION] = friction
                E.rec[row, RC_INTEGRATOR] = dissipated
                E.rec[row, RC_COULOMB] = coulomb
                E.rec[row, RC_PENALTY] = E.mf[m, MF_PENALTY]
                E.mi[m, MI_SN] += 1
            if follow_load(E, m, ti.max(pen, 0.0)):
                E.mi[m, MI_HAVE_ENERGY] = 0
    return result
