"""The first steps of the blocks that the equilibrium stage released in doubt
(docs/method/dda.md §8.12, docs/guide/equilibrium_start.md).

Where limit equilibrium admits forces for a block but the return mapping stalls and the
open-close test from there does not converge, nothing proves the block held or moving: the
stage releases it *in doubt* (``ddatai.mechanisms.loaded_away``), and it starts at t = 0 from
where it was, under sudden gravity. Whether such a block — typically every block of a stack of
columns near its toppling tilt — then rocks away or settles is decided in its first rocking
time constants, and the step's own damping decides it where Δt does not resolve the rocking:
DDA's implicit step damps a motion of frequency ω by ~ω·Δt a step and the plastic impacts of
corners that close within a long step take their approach away (`ddatai.impacts`). Measured on
the 4-4-4 stack of 0.1 m squares (τ = 0.098 s a square): at 23.25° with Δt ≤ 0.5, 1 and 2 ms
it topples at 0.31–0.35 s, with the default 10 ms (τ/10) and with 3 ms it moves 2 mm and stops,
while a slow load topples it there; nearer its threshold τ/80 is not enough: at 22.6° it leans
8 mm and stops with Δt ≤ τ/80 (1.23 ms) or 1 ms and topples with 0.7 and 0.5 ms, and with
τ/160 and τ/320 alike (at 0.503 s both). With τ/160 and τ/320 the outcome is the same on a
0.05° grid (it stands at 22.35° and 22.4°, leaning 8.6–10.3 mm, and topples from 22.45°).

So while blocks released in doubt move, the automatic Δt resolves their rocking: at most
τ/RESOLVE, τ = √(4R/(3g)) the rocking time constant about a corner (Housner 1963) of the
smallest of them, R its largest corner-to-centroid distance. A block leaves the watch once it
has moved more than its size √A from where it started (it has failed: no Δt undoes that), and
every block leaves it once, after at least one τ, they rest (largest vertex speed below
REST × g·τ) or after MAX_TIMES × τ (a block creeping for ever does not keep the short steps).
The held blocks and models without such releases step as before. The cost is the resolved
steps of that window: ~RESOLVE a τ (``tests/test_in_doubt.py``, the closing table of
docs/guide/equilibrium_start.md). The fused engine (`ddatai.fused`) does not apply it: a run or a
kgm member with blocks released in doubt runs on today's path (`ddatai.run`, `kgm.judges.fused`).
"""

from __future__ import annotations

import numpy as np

from .kinematics import block_radius

#: the automatic Δt of the watched blocks is at most τ/RESOLVE (τ the rocking time constant):
#: the 4-4-4 squares' outcome is the same with τ/160 and τ/320 from 22.35° to 23.25°, while
#: τ/80 holds them at 22.45–22.6°, where the finer steps topple them (module docstring)
RESOLVE = 160.0
#: at rest: the watched blocks' largest vertex speed below this × g·τ (1 µm/s for τ = 0.1 s)
REST = 1e-6
#: the watch ends after at most this many rocking time constants (the slow load's ramp and hold
#: take 28 of the slenderest column's, ~2 of its blocks' each)
MAX_TIMES = 20.0


def watched(model, released_in_doubt: np.ndarray) -> np.ndarray:
    """`State.in_doubt` at t = 0: the blocks released in doubt, or none (empty) where there are
    none or nothing pulls them (no gravity: no rocking under it)."""
    if not np.any(released_in_doubt & ~model.block_fixed) or not np.any(model.gravity != 0.0):
        return np.zeros(0, bool)
    return released_in_doubt & ~model.block_fixed


def rocking_time(model, state, geom: dict) -> float:
    """τ = √(4R/(3g)) of the smallest watched block [s] (inf: none watched)."""
    blocks = state.in_doubt
    if not blocks.any():
        return np.inf
    radius = block_radius(model, state.vertex_xy, geom["centroid"])[blocks]
    return float(np.sqrt(4.0 * radius.min() / (3.0 * np.hypot(*model.gravity))))


def time_step(model, state, geom: dict) -> float:
    """The largest Δt of the next step that resolves the watched blocks' rocking, τ/RESOLVE
    (inf: none watched) [s]."""
    return rocking_time(model, state, geom) / RESOLVE


def follow(model, before, after) -> np.ndarray:
    """`State.in_doubt` after the step from ``before`` to ``after`` (module docstring): the
    watched blocks less those moved away by more than their size; none once they rest after a
    rocking time constant, or after MAX_TIMES of them."""
    blocks = before.in_doubt
    if not blocks.any():
        return blocks
    geom = after.geometry if after.geometry is not None else model.block_geometry(after.vertex_xy)
    moved = np.maximum.reduceat(np.hypot(*(after.vertex_xy - model.vertex_xy0).T), model.vertex_offset[:-1])
    blocks = blocks & (moved <= np.sqrt(geom["area"]))
    if not blocks.any():
        return np.zeros(0, bool)
    tau = rocking_time(model, after.replace(in_doubt=blocks), geom)
    radius = block_radius(model, after.vertex_xy, geom["centroid"])
    v = after.block_velocity
    speed = float(np.max((np.hypot(v[:, 0], v[:, 1]) + np.abs(v[:, 2]) * radius)[blocks]))
    g = float(np.hypot(*model.gravity))
    if after.time >= MAX_TIMES * tau or (after.time >= tau and speed < REST * g * tau):
        return np.zeros(0, bool)
    return blocks
