"""The fused engine's one kernel: every member of a launch runs in its own thread, step after
step, up to the launch's step budget, its end (time or step count), a stop, or a step that
needs more room (``GROW``) or today's path (``DIVERT``). Members that share a launch share nothing
else: each runs with its own Δt and its own iterations, as it would alone.

After each accepted step a member records, in its region of ``hist``, its time and the largest
displacement of its group's blocks from the model's start (the mean displacement of a block's
vertices; `kgm`'s measure), then stops when that displacement passes its stop distance
(``STOP_MOVED``) or when its free blocks have moved slower than its rest speed for its rest
steps (``STOP_REST``, ``kgm.judgement.RestCounter``). The kernel compiles once for every model size:
sizes and capacities are the arrays' (runtime) shapes and the members' offsets.
"""


import taichi as ti

from .arrays import Pack
from .layout import (BG_CX, BG_CY, BG_RADIUS0, BI_ROW, BI_V0, BI_V1, BS_ROT, BS_STRESS, BS_VEL, DONE, FR_BLOCK,
                     MF_REST_LIMIT, MF_STOP_AT, MF_T_END, MF_TIME, MI_B0, MI_B1, MI_F0, MI_FCAP, MI_FEVERY,
                     MI_FN, MI_FSIZE, MI_G0, MI_G1, MI_H0, MI_HCAP, MI_HN, MI_LAUNCH_STEPS, MI_P0, MI_P1,
                     MI_QUIET, MI_REST_STEPS, MI_STATUS, MI_STEP, MI_STEP_END, MI_V0, MI_V1, PF_X, PF_Y,
                     RUNNING, STOP_MOVED, STOP_REST)
from .step import step


@ti.func
def _finished(E: ti.template(), m):
    t_end = E.mf[m, MF_T_END]
    return E.mf[m, MF_TIME] >= t_end * (1 - 1e-12) or \
        (E.mi[m, MI_STEP_END] >= 0 and E.mi[m, MI_STEP] >= E.mi[m, MI_STEP_END])


@ti.func
def _group_displacement(E: ti.template(), m):
    """The largest displacement of the member's group blocks from the model's start [m]
    (`kgm.judgement.block_displacements`)."""
    d = 0.0
    for g in range(E.mi[m, MI_G0], E.mi[m, MI_G1]):
        b = E.gidx[g]
        v0 = E.bint[b, BI_V0]
        v1 = E.bint[b, BI_V1]
        ux = 0.0
        uy = 0.0
        for v in range(v0, v1):
            ux += E.vxy[v, 0] - E.vxy0[v, 0]
            uy += E.vxy[v, 1] - E.vxy0[v, 1]
        count = ti.cast(v1 - v0, ti.f64)
        d = ti.max(d, ti.sqrt((ux / count) ** 2 + (uy / count) ** 2))
    return d


@ti.func
def _fastest(E: ti.template(), m):
    """A bound of the fastest vertex speed of the member's free blocks (`kgm.judgement.block_speeds`)."""
    fastest = 0.0
    for b in range(E.mi[m, MI_B0], E.mi[m, MI_B1]):
        if E.bint[b, BI_ROW] >= 0:
            v = ti.sqrt(E.bst[b, BS_VEL] ** 2 + E.bst[b, BS_VEL + 1] ** 2) + E.bgeo[b, BG_RADIUS0] * \
                (ti.abs(E.bst[b, BS_VEL + 2]) + ti.abs(E.bst[b, BS_VEL + 3]) + ti.abs(E.bst[b, BS_VEL + 4]) +
                 ti.abs(E.bst[b, BS_VEL + 5]))
            fastest = ti.max(fastest, v)
    return fastest


@ti.func
def _frame(E: ti.template(), m):
    """The member's state into its next frame (`ddatai.fused.layout.FR_BLOCK`)."""
    at = E.mi[m, MI_F0] + E.mi[m, MI_FN] * E.mi[m, MI_FSIZE]
    E.frame[at] = E.mf[m, MF_TIME]
    at += 1
    for b in range(E.mi[m, MI_B0], E.mi[m, MI_B1]):
        E.frame[at + 0] = E.bgeo[b, BG_CX]
        E.frame[at + 1] = E.bgeo[b, BG_CY]
        E.frame[at + 2] = E.bst[b, BS_ROT]
        E.frame[at + 3] = E.bst[b, BS_VEL]
        E.frame[at + 4] = E.bst[b, BS_VEL + 1]
        E.frame[at + 5] = E.bst[b, BS_VEL + 2]
        for k in ti.static(range(3)):
            E.frame[at + 6 + k] = E.bst[b, BS_STRESS + k]
        at += FR_BLOCK
    for v in range(E.mi[m, MI_V0], E.mi[m, MI_V1]):
        E.frame[at] = E.vxy[v, 0]
        E.frame[at + 1] = E.vxy[v, 1]
        at += 2
    for p in range(E.mi[m, MI_P0], E.mi[m, MI_P1]):
        E.frame[at] = E.pf[p, PF_X]
        E.frame[at + 1] = E.pf[p, PF_Y]
        at += 2
    E.mi[m, MI_FN] += 1


@ti.kernel
def run(E: Pack, members: ti.i32):
    """Advance every RUNNING member of the launch (one thread a member)."""
    for m in range(members):
        if E.mi[m, MI_STATUS] == RUNNING:
            taken = 0
            while taken < E.mi[m, MI_LAUNCH_STEPS]:
                if _finished(E, m):
                    E.mi[m, MI_STATUS] = DONE
                    break
                result = step(E, m)
                if result != RUNNING:
                    E.mi[m, MI_STATUS] = result
                    break
                taken += 1
                every = E.mi[m, MI_FEVERY]
                if every > 0 and E.mi[m, MI_FN] < E.mi[m, MI_FCAP]:
                    if E.mi[m, MI_STEP] % every == 0 or _finished(E, m):
                        _frame(E, m)
                d = _group_displacement(E, m)
                if E.mi[m, MI_HN] < E.mi[m, MI_HCAP]:
                    row = E.mi[m, MI_H0] + E.mi[m, MI_HN]
                    E.hist[row, 0] = E.mf[m, MF_TIME]
                    E.hist[row, 1] = d
                    E.mi[m, MI_HN] += 1
                if d > E.mf[m, MF_STOP_AT]:
                    E.mi[m, MI_STATUS] = STOP_MOVED
                    break
                if E.mf[m, MF_REST_LIMIT] >= 0.0:
                    if _fastest(E, m) <= E.mf[m, MF_REST_LIMIT]:
                        E.mi[m, MI_QUIET] += 1
                    else:
                        E.mi[m, MI_QUIET] = 0
                    if E.mi[m, MI_QUIET] >= E.mi[m, MI_REST_STEPS]:
                        E.mi[m, MI_STATUS] = STOP_REST
                        break
                if every > 0 and E.mi[m, MI_FN] >= E.mi[m, MI_FCAP]:
                    break  # the frames are full: the driver takes them before the next launch
            if E.mi[m, MI_STATUS] == RUNNING and _finished(E, m):
                E.mi[m, MI_STATUS] = DONE
