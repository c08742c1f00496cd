"""The time step Δt of the next step (docs/method/dda.md §4.6)."""

from __future__ import annotations

import math

import numpy as np

from .assembly import load_forces
from .kinematics import block_radius
from .model import Model, State


def choose_time_step(model: Model, state: State, geom: dict) -> float:
    """Automatic Δt (docs/method/dda.md §4.6): the step whose predicted largest vertex
    displacement, ½·a·Δt² + v·Δt, equals g2·w0; at most ``dt_max`` and at most
    ``dt_growth`` × the previous step. A fixed ``Params.dt`` is used as given, growing back
    by ``dt_growth`` per step after a cut."""
    p = model.params
    free = ~model.block_fixed
    limit = p.dt if p.dt is not None else p.dt_max
    if p.dt is None and model.n_free:
        radius = block_radius(model, state.vertex_xy, geom["centroid"])
        v = state.block_velocity
        speed = float(np.max((np.hypot(v[:, 0], v[:, 1]) + np.abs(v[:, 2]) * radius)[free]))
        acc = float(np.hypot(*model.gravity))
        if model.ground_acceleration is not None:
            acc += float(np.hypot(*model.ground_acceleration(state.time)))
        if len(model.load_block):
            f = load_forces(model, state.time)
            mass = model.block_density * geom["area"]
            acc += float(np.max(np.hypot(f[:, 0], f[:, 1]) / mass[model.load_block]))
        if state.step == 0:
            # initial stresses accelerate a block's strain (ntdda's first-step estimate)
            s = np.abs(state.block_stress).max(axis=1)
            area = geom["area"]
            acc += float(np.max((4.0 * s * np.sqrt(area) / (area * model.block_density))[free]))
        # the forcing bounds the acceleration of a free block; the last step's observed
        # accelerations (contacts, impacts) may exceed it
        acc = max(acc, state.accel)
        u = model.max_step
        if acc > 0 or speed > 0:
            # the positive root of ½·a·Δt² + v·Δt = u in the form that does not cancel:
            # (−v + √(v² + 2au))/a loses every digit when a is round-off small beside v²/u
            # (a fast block without gravity: Δt came out 0)
            dt = 2.0 * u / (speed + math.sqrt(speed * speed + 2.0 * acc * u))
        else:
            dt = limit
        limit = min(limit, dt)
    if state.dt > 0:
        limit = min(limit, p.dt_growth * state.dt)
    return limit


#: the impact step: this many inverse frequencies √(m/p) of the contact spring, long beside the
#: spring's period so that the step's implicit solve settles it
IMPACT_OMEGA = float(__import__("os").environ.get("IMPACT_OMEGA", "20.0"))

IMPACT_LEAD = float(__import__("os").environ.get("IMPACT_LEAD", "0.05"))


def approach_bound(model: Model, state: State, contacts, vec: np.ndarray, sca: np.ndarray,
                   dt: float) -> tuple[float, np.ndarray]:
    """Δt bounded so that no contact closes by more than the allowed overshoot within the step,
    and no shorter than the impact step: a contact of gap g (0 once closed) closing at rate r
    (its normal distance's rate at the step start's velocities, e·v_a + g·v_b of
    docs/method/dda.md §2.8.1) bounds the step to max((g + δ)/r, Ω/ω), δ = ``impact_overshoot``
    × the penetration limit, ω = √(p/m) the contact spring's frequency with m the lighter free
    block's mass, Ω = ``IMPACT_OMEGA`` (docs/method/dda.md §4.6)."""
    from .layout import KIND, OPEN, S_E0, S_E1, S_G0, S_G1, VV
    import os
    frac = model.params.impact_overshoot
    none = np.zeros(contacts.n, bool)
    if frac is None or contacts.n == 0 or state.step == 0:
        return dt, none
    v = state.block_velocity
    a, b = contacts.block_a, contacts.block_b
    vv = contacts.cint[:, KIND] == VV
    rate = np.einsum("ij,ij->i", vec[:, S_E0], v[a]) + np.einsum("ij,ij->i", vec[:, S_G0], v[b])
    gap = sca[:, 0].copy()
    if vv.any():
        rate1 = np.einsum("ij,ij->i", vec[vv, S_E1], v[b[vv]]) + np.einsum("ij,ij->i", vec[vv, S_G1], v[a[vv]])
        gap1 = sca[vv, 1]
        pick = gap1 > gap[vv]  # the less penetrated line (Shi's entrance line)
        rate[vv] = np.where(pick, rate1, rate[vv])
        gap[vv] = np.where(pick, gap1, gap[vv])
    allowed = frac * model.penetration_limit
    closing = (rate < 0.0) & (np.maximum(gap, 0.0) + allowed < -rate * dt)
    if not closing.any():
        return dt, none
    geom_area = model.block_geometry(state.vertex_xy)["area"] if state.geometry is None else state.geometry["area"]
    mass = np.where(model.block_fixed, np.inf, model.block_density * geom_area)
    m = np.minimum(mass[a[closing]], mass[b[closing]])
    impact = IMPACT_OMEGA / np.sqrt(model.penalty / m)  # the impact step of each
    t_close = np.maximum(gap[closing], 0.0) / -rate[closing]
    early = t_close > impact
    if early.any():
        # in flight: the step ends IMPACT_LEAD of an impact step before the first closing
        return float(min(dt, np.min(t_close[early] - IMPACT_LEAD * impact[early]))), none
    # the impact: a step long beside the contact spring's period, which its implicit solve
    # then settles (the plastic impact of `kinematics.update`)
    limit = model.params.dt if model.params.dt is not None else model.params.dt_max
    return float(min(limit, impact.max())), closing


def end_on(dt: float, time: float, t_end) -> float:
    """Δt shortened so that the step lands exactly on ``t_end`` without leaving a sliver of a
    step after it (None: no end)."""
    if t_end is None:
        return dt
    remaining = t_end - time
    if remaining <= dt * (1.0 + 1e-9):
        return remaining
    if remaining < 2.0 * dt:
        return 0.5 * remaining
    return dt
