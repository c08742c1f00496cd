"""Impacts in the fused engine (Taichi functions), as ``ddatai.impacts`` and
``ddatai.step.Stepper.advance`` (docs/method/dda.md §4.6, §5.2): a closing predicted from the
contact point's velocity and acceleration over max(Δt, τ); the step before it ends
IMPACT_LEAD·τ before the contact; the impact step's accepted solve finds which contacts hold,
and the step is taken again (by `ddatai.fused.step`) from the impacted blocks' carried velocity
projected onto what they admit, K⁻¹(ρM/βΔt²)·k·v with that solve's factor: Housner's plastic
impact at the step's start. An impact taking at most IMPACT_NEGLIGIBLE of the kinetic energy is
left to the step."""


import taichi as ti

from . import blocks, system
from ..kernels.common import E0, E1, G0, G1
from .layout import (BG_AREA, BI_ROW, BM_RHO, BS_ACC, BS_VEL, BW_A0, BW_IMPACT, BW_PREV, BW_SOL, BW_V0,
                     CF_SCA, CI_A, CI_B, CI_CLOSING, CI_KIND, CI_STATE, MF_CARRY, MF_IMPACT, MF_PEN_LIMIT,
                     MF_PENALTY, MI_B0, MI_B1, MI_C0, MI_NC, MI_NF, MI_STEP, MI_X0, XS_RHS)

OPEN = 0
VV = 1
#: as ``ddatai.impacts``: the impact step IMPACT_OMEGA/√(p/m), the lead IMPACT_LEAD of it, the
#: negligible share of the kinetic energy
IMPACT_OMEGA = 20.0
IMPACT_LEAD = 0.002
IMPACT_NEGLIGIBLE = 1e-6


@ti.func
def _normal_rate(E: ti.template(), c, line, col):
    """The rate of contact c's normal distance (line 0 or 1) under the blocks' ``bst`` 6-vectors
    at ``col`` (velocities or accelerations; `impacts._normal_rate`)."""
    a = E.cint[c, CI_A]
    b = E.cint[c, CI_B]
    se = E0
    sg = G0
    ba = a
    bb = b
    if line == 1:
        se = E1
        sg = G1
        ba = b
        bb = a
    r = 0.0
    for k in ti.static(range(6)):
        r += E.cvec[c, 6 * se + k] * E.bst[ba, col + k] + E.cvec[c, 6 * sg + k] * E.bst[bb, col + k]
    return r


@ti.func
def _closing(E: ti.template(), m, c, dt, frac):
    """(hard, t_close, τ) of contact c (`impacts.approach_bound`): whether it closes past the
    overshoot within max(Δt, τ), when, and its impact step."""
    gap = E.cf[c, CF_SCA]
    line = 0
    if E.cint[c, CI_KIND] == VV and E.cf[c, CF_SCA + 1] > gap:
        line = 1
        gap = E.cf[c, CF_SCA + 1]
    speed = -_normal_rate(E, c, line, BS_VEL)
    accel = -_normal_rate(E, c, line, BS_ACC)
    hard = 0
    t_close = 0.0
    tau = 0.0
    a = E.cint[c, CI_A]
    b = E.cint[c, CI_B]
    # a contact closed at the step's start carries its approach in its spring: not a closing
    if (speed > 0.0 or accel > 0.0) and E.cint[c, CI_STATE] == OPEN and \
            (E.bint[a, BI_ROW] >= 0 or E.bint[b, BI_ROW] >= 0):
        mass = 0.0
        if E.bint[a, BI_ROW] >= 0:
            mass = E.bmat[a, BM_RHO] * E.bgeo[a, BG_AREA]
        if E.bint[b, BI_ROW] >= 0:
            mb = E.bmat[b, BM_RHO] * E.bgeo[b, BG_AREA]
            if E.bint[a, BI_ROW] < 0 or mb < mass:
                mass = mb
        tau = IMPACT_OMEGA / ti.sqrt(E.mf[m, MF_PENALTY] / mass)
        g = ti.max(gap, 0.0)
        horizon = ti.max(dt, tau)
        if frac * E.mf[m, MF_PEN_LIMIT] + g < speed * horizon + 0.5 * accel * horizon * horizon:
            hard = 1
            root = speed + ti.sqrt(ti.max(speed * speed + 2.0 * accel * g, 0.0))
            if g > 0.0:
                if root > 0.0:
                    t_close = 2.0 * g / root
                else:
                    t_close = 2.0 * g
    return hard, t_close, tau


@ti.func
def approach_bound(E: ti.template(), m, dt, rule_dt):
    """The step's Δt where a contact is about to close, the contacts it is the impact step of
    flagged in ``CI_CLOSING`` (`ddatai.impacts.approach_bound`); ``rule_dt`` the displacement
    rule's Δt without its growth limit."""
    frac = E.mf[m, MF_IMPACT]
    base = E.mi[m, MI_C0]
    nc = E.mi[m, MI_NC]
    for c in range(base, base + nc):
        E.cint[c, CI_CLOSING] = 0
    out = dt
    if frac >= 0.0 and nc > 0 and E.mi[m, MI_STEP] > 0:
        any_hard = 0
        any_now = 0
        tau_now = 0.0
        flight = 0.0
        for c in range(base, base + nc):
            hard, t_close, tau = _closing(E, m, c, dt, frac)
            if hard:
                lead = t_close - IMPACT_LEAD * tau
                if any_hard == 0 or lead < flight:
                    flight = lead
                any_hard = 1
                if t_close <= 2.0 * IMPACT_LEAD * tau:
                    any_now = 1
                    tau_now = ti.max(tau_now, tau)
        if any_hard and any_now == 0:
            out = ti.min(dt, flight)
        elif any_now:
            out = ti.min(rule_dt, tau_now)
            for c in range(base, base + nc):
                hard, t_close, tau = _closing(E, m, c, dt, frac)
                if hard and t_close <= out:
                    E.cint[c, CI_CLOSING] = 1
    return out


@ti.func
def impacted(E: ti.template(), m):
    """Flag in ``BW_IMPACT`` the free blocks of the contacts found closing that the step's solve
    closed (`impacts.impacted`). Returns whether any."""
    any_hit = 0
    for b in range(E.mi[m, MI_B0], E.mi[m, MI_B1]):
        E.bwork[b, BW_IMPACT] = 0.0
    base = E.mi[m, MI_C0]
    for c in range(base, base + E.mi[m, MI_NC]):
        if E.cint[c, CI_CLOSING] != 0 and E.cint[c, CI_STATE] != OPEN:
            for side in ti.static(range(2)):
                b = E.cint[c, CI_A + side]
                if E.bint[b, BI_ROW] >= 0:
                    E.bwork[b, BW_IMPACT] = 1.0
                    any_hit = 1
    return any_hit


@ti.func
def impact_projection(E: ti.template(), m, dt, beta):
    """The carried velocity k·v projected onto what the accepted solve's closed contacts admit,
    K⁻¹·(ρM/(βΔt²))·k·v with the solve's factor (`Stepper.impact_projection`), into ``BW_SOL``
    (the accepted solution kept in ``BW_PREV``). Returns whether the plastic impact of the
    impacted blocks is negligible (`impacts.negligible`)."""
    n = 6 * E.mi[m, MI_NF]
    rhs = E.mi[m, MI_X0] + XS_RHS * n
    carry = E.mf[m, MF_CARRY]
    for i in range(n):
        E.xvec[rhs + i] = 0.0
    for b in range(E.mi[m, MI_B0], E.mi[m, MI_B1]):
        for a in ti.static(range(6)):
            E.bwork[b, BW_PREV + a] = E.bwork[b, BW_SOL + a]
        r = E.bint[b, BI_ROW]
        if r >= 0:
            M = blocks.mass(E, b)
            rho = E.bmat[b, BM_RHO]
            for i in ti.static(range(6)):
                s = 0.0
                for j in ti.static(range(6)):
                    s += M[i, j] * carry * E.bst[b, BS_VEL + j]
                E.xvec[rhs + 6 * r + i] = rho * s / (beta * dt * dt)
    system.solve(E, m)
    lost = 0.0
    kinetic = 0.0
    for b in range(E.mi[m, MI_B0], E.mi[m, MI_B1]):
        if E.bwork[b, BW_IMPACT] != 0.0:
            M = blocks.mass(E, b)
            rho = E.bmat[b, BM_RHO]
            for i in ti.static(range(6)):
                for j in ti.static(range(6)):
                    vi = carry * E.bst[b, BS_VEL + i]
                    vj = carry * E.bst[b, BS_VEL + j]
                    ci = vi - E.bwork[b, BW_SOL + i]
                    cj = vj - E.bwork[b, BW_SOL + j]
                    lost += rho * ci * M[i, j] * cj
                    kinetic += rho * vi * M[i, j] * vj
    return lost <= IMPACT_NEGLIGIBLE * kinetic


@ti.func
def swap_start(E: ti.template(), m):
    """Exchange the blocks' velocities and accelerations with those kept in ``BW_V0``/``BW_A0``
    (the state before the plastic impact and after it)."""
    for b in range(E.mi[m, MI_B0], E.mi[m, MI_B1]):
        for a in ti.static(range(6)):
            v = E.bst[b, BS_VEL + a]
            E.bst[b, BS_VEL + a] = E.bwork[b, BW_V0 + a]
            E.bwork[b, BW_V0 + a] = v
            acc = E.bst[b, BS_ACC + a]
            E.bst[b, BS_ACC + a] = E.bwork[b, BW_A0 + a]
            E.bwork[b, BW_A0 + a] = acc


@ti.func
def plastic_start(E: ti.template(), m):
    """The impacted blocks moving at their projected velocity (``BW_SOL``), without acceleration
    history (`impacts.plastic_start`); the state before kept in ``BW_V0``/``BW_A0``."""
    for b in range(E.mi[m, MI_B0], E.mi[m, MI_B1]):
        for a in ti.static(range(6)):
            E.bwork[b, BW_V0 + a] = E.bst[b, BS_VEL + a]
            E.bwork[b, BW_A0 + a] = E.bst[b, BS_ACC + a]
            if E.bwork[b, BW_IMPACT] != 0.0:
                E.bst[b, BS_VEL + a] = E.bwork[b, BW_SOL + a]
                E.bst[b, BS_ACC + a] = 0.0
