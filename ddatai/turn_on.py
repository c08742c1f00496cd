"""The slow gravity turn-on that settles the equilibrium stage's doubt (`ddatai.start`).

Where the stage's return mapping stalls although rigid-block limit equilibrium holds every block,
the open-close test of the blocks still out of balance decides nothing for certain: friction is
not associated, so the static problem has many solutions (a stack of columns leaning on each
other has admissible forces whether or not it stands), and which one the model takes depends on
how it is loaded. An unconverged test proves no block held; a converged one that moves a block
proves no mechanism either (it is one of the solutions, with every contact at its strength
sliding; another, with some of them sticking, may hold it). Released, such a block starts
under sudden gravity: the contact springs overshoot the static forces, and a stack that a slow
load holds several degrees past the start's tilt topples (docs/guide/equilibrium_start.md).

The reference for a threshold is the model loaded slowly from rest (docs/method/dda.md §8.12),
and with ``Params.start_turn_on`` that is what settles the doubt: the model is run from t = 0
with its weight turned on over RAMP_TIMES rocking time constants of its free part
(``rocking_time``, Housner's √(4R/(3g)), R half the diagonal of the free blocks' bounding box),
by a ground acceleration (1 − s(t))·g that the run's own steps carry (s a smoothstep from 0 to
1; §2.4, the ground's frame), then held for HOLD_TIMES, the blocks that the stage released for
certain moved out of the way. Where no block moves further than MECHANISM_SIZE of its size, the
model stands under its whole weight: the turn-on's last state is handed over at rest (held
blocks settled, contact springs carrying their forces, contacts at their strength as the steps
left them). Where one does, the turn-on stops and the stage releases the blocks in doubt (in
doubt, release). Off by default: on stacks of square blocks the slow load's own outcome near
the threshold scatters by up to 2.5° with the ramp's rate and the model's frame, and a start
that follows one slow load can lie above another (docs/guide/equilibrium_start.md).

The turn-on costs about (RAMP_TIMES + HOLD_TIMES)·τ / dt_max steps; a model whose turn-on would
take more than MAX_STEPS (a slope tens of metres high: τ ≈ 1–4 s) keeps the release in doubt. It applies to
models loaded by gravity alone (no point loads, initial stresses, bolts or water, whose ramps
the stage would have to invent), without a ground acceleration of their own.
"""

from __future__ import annotations

import math
from dataclasses import replace
from typing import Optional

import numpy as np

from .limit_equilibrium import applicable
from .mechanisms import MECHANISM_SIZE, restore, sunk_into_released
from .model import State

#: the weight is turned on over this many rocking time constants (`rocking_time`) ...
RAMP_TIMES = 20.0
#: ... and then held for this many, in which a column past its threshold by δ rotates as
#: δ·(cosh(t/τ) − 1): 0.1° past it, by 2.6 rad (the slow load of tests/toppling_cases.py)
HOLD_TIMES = 8.0
#: a turn-on that would take more steps than this (at ``Params.dt_max``) is not run
MAX_STEPS = 2000
#: blocks that the stage released for certain wait this many free-part extents below the model
AWAY = 4.0


def rocking_time(model, vertex_xy: np.ndarray, blocks: np.ndarray) -> float:
    """√(4R/(3g)) [s], R half the diagonal of the bounding box of ``blocks``: the time constant
    of rigid rocking about a corner (Housner 1963) of a column as large as the group."""
    xy = vertex_xy[blocks[model.vertex_block]]
    radius = 0.5 * float(np.hypot(*(xy.max(axis=0) - xy.min(axis=0))))
    return math.sqrt(4.0 * radius / (3.0 * float(np.hypot(*model.gravity))))


def feasible(model) -> bool:
    """Whether the turn-on applies to the model (module docstring): gravity its only load, no
    ground acceleration, and at most MAX_STEPS steps."""
    if not (applicable(model) and model.ground_acceleration is None and len(model.load_block) == 0):
        return False
    if not np.any(model.gravity != 0.0) or np.any(model.initial_stress[~model.block_fixed] != 0.0):
        return False
    free = ~model.block_fixed
    end = (RAMP_TIMES + HOLD_TIMES) * rocking_time(model, model.vertex_xy0, free)
    return end <= MAX_STEPS * model.params.dt_max


def _smoothstep(t: float, ramp: float) -> float:
    x = min(max(t / ramp, 0.0), 1.0)
    return x * x * (3.0 - 2.0 * x)


def turn_on(stepper, initial: State, released: np.ndarray,
            sunk_fraction: float) -> Optional[tuple[State, np.ndarray, int]]:
    """The model from ``initial`` (t = 0) under its weight turned on slowly (module docstring),
    the ``released`` blocks out of the way. Where no block moved further than MECHANISM_SIZE of
    its size, returns (the state at the end, at rest at t = 0, the released blocks back where
    they were at t = 0; the released blocks, with the held ones that settled into their space
    deeper than ``sunk_fraction`` of the penetration limit, `sunk_into_released`; the steps it
    took), else None."""
    from .results import SimulationError
    from .step import Stepper

    model = stepper.model
    free = ~model.block_fixed
    turned = free & ~released
    if not turned.any():
        return None
    tau = rocking_time(model, initial.vertex_xy, turned)
    ramp, end = RAMP_TIMES * tau, (RAMP_TIMES + HOLD_TIMES) * tau
    gravity = model.gravity.copy()

    def ground(t: float) -> tuple:
        # the ground's frame: every block feels g − a_g = s(t)·g
        return tuple((1.0 - _smoothstep(t, ramp)) * gravity)

    slow = replace(model, ground_acceleration=ground, params=replace(model.params, initial_equilibrium=False))
    xy = initial.vertex_xy.copy()
    if released.any():
        extent = float(np.ptp(xy[:, 1])) + float(np.ptp(xy[:, 0]))
        xy[released[model.vertex_block], 1] -= AWAY * extent
    state = initial.replace(vertex_xy=xy, geometry=None)
    size = np.sqrt(model.block_geometry(initial.vertex_xy)["area"])
    limit = (MECHANISM_SIZE * size)[model.vertex_block]
    watched = turned[model.vertex_block]
    runner = Stepper(slow)
    try:
        while state.time < end * (1.0 - 1e-12):
            state = runner.advance(state, t_end=end).state
            moved = np.hypot(*(state.vertex_xy - xy).T)
            if np.any(moved[watched] > limit[watched]):
                return None  # a block moves away under a slow load: a mechanism
    except SimulationError:
        return None
    steps = state.step
    state = state.replace(time=0.0, step=0, block_velocity=initial.block_velocity.copy(),
                          block_accel=np.zeros_like(initial.block_accel), dt=0.0, accel=0.0, energy=None)
    released = released.copy()
    while True:
        state = restore(model, state, initial, released)
        sunk = sunk_into_released(stepper, state, released, sunk_fraction)
        if not sunk.any():
            return state, released, steps
        released |= sunk
