"""The time step Δt of the next step (docs/method/dda.md §4.6)."""

from __future__ import annotations

import math

import numpy as np

from . import in_doubt
from .assembly import load_forces
from .kinematics import block_radius
from .model import Model, State


def choose_time_step(model: Model, state: State, geom: dict) -> float:
    """Automatic Δt (docs/method/dda.md §4.6): the step whose predicted largest vertex
    displacement, ½·a·Δt² + v·Δt, equals g2·w0; at most ``dt_max`` and at most
    ``dt_growth`` × the previous step, and while blocks released in doubt by the equilibrium
    stage are watched (`State.in_doubt`) at most what resolves their rocking
    (`ddatai.in_doubt.time_step`). A fixed ``Params.dt`` is used as given, growing back
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
        if state.in_doubt.any():
            limit = min(limit, in_doubt.time_step(model, state, geom))
    if state.dt > 0:
        limit = min(limit, p.dt_growth * state.dt)
    return limit


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
