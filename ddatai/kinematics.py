"""The update of a step's solution D (docs/method/dda.md §5): material points moved with the
exact rotation (§5.3), stresses updated and rotated with their blocks (§5.4), velocities and
accelerations by Newmark's rule (§5.2). The equilibrium stage (`ddatai.start`) moves its held
blocks with the same functions.
"""

from __future__ import annotations

from typing import Optional

import numpy as np

from . import side_by_side
from .contacts import Contacts
from .model import Model, State
from .params import Params


def move_points(xy: np.ndarray, block: np.ndarray, centroid: np.ndarray, disp: np.ndarray) -> np.ndarray:
    """Displace material points with the exact-rotation update (docs/method/dda.md §5.3):
    translation and strain from D, the rigid rotation r0 applied as a finite rotation, so a
    spinning block keeps its area."""
    if len(xy) == 0:
        return xy.copy()
    d = disp[block]
    X = xy[:, 0] - centroid[block, 0]
    Y = xy[:, 1] - centroid[block, 1]
    c, s = np.cos(d[:, 2]), np.sin(d[:, 2])
    out = np.empty_like(xy)
    out[:, 0] = xy[:, 0] + (d[:, 0] + d[:, 3] * X + 0.5 * d[:, 5] * Y + X * (c - 1.0) - Y * s)
    out[:, 1] = xy[:, 1] + (d[:, 1] + d[:, 4] * Y + 0.5 * d[:, 5] * X + X * s + Y * (c - 1.0))
    return out


def rotate_stress(stress: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """Rotate the stress tensor with the block (objective update, §5.4)."""
    c, s = np.cos(angle), np.sin(angle)
    sx, sy, t = stress[:, 0], stress[:, 1], stress[:, 2]
    out = np.empty_like(stress)
    out[:, 0] = c * c * sx - 2 * c * s * t + s * s * sy
    out[:, 1] = s * s * sx + 2 * c * s * t + c * c * sy
    out[:, 2] = c * s * (sx - sy) + (c * c - s * s) * t
    return out


def newmark_beta(params: Params, state: State) -> float:
    """β for this step: Shi's ½ on the first step (no acceleration history), then Params'."""
    return 0.5 if state.step == 0 else params.newmark_beta


def block_radius(model: Model, vertex_xy: np.ndarray, centroid: np.ndarray) -> np.ndarray:
    """(B,) largest distance of each block's vertices from its centroid [m]."""
    r = np.hypot(*(vertex_xy - centroid[model.vertex_block]).T)
    return np.maximum.reduceat(r, model.vertex_offset[:-1])


def vertex_displacement(model: Model, vertex_xy: np.ndarray, geom: dict, disp: np.ndarray,
                        moved_xy: Optional[np.ndarray] = None) -> np.ndarray:
    """(V,) how far each vertex moves with the solution ``disp`` [m]; ``moved_xy``: the
    vertices moved by it (`move_points`), when already known."""
    if moved_xy is None:
        moved_xy = move_points(vertex_xy, model.vertex_block, geom["centroid"], disp)
    moved = moved_xy - vertex_xy
    return np.hypot(moved[:, 0], moved[:, 1])


@side_by_side.operation("block_displacement")
def block_displacement(model: Model, vertex_xy: np.ndarray, geom: dict, disp: np.ndarray) -> np.ndarray:
    """(B,) largest vertex displacement of each block [m]."""
    return np.maximum.reduceat(vertex_displacement(model, vertex_xy, geom, disp), model.vertex_offset[:-1])


def max_vertex_displacement(model: Model, vertex_xy: np.ndarray, geom: dict, disp: np.ndarray,
                            moved_xy: Optional[np.ndarray] = None) -> float:
    """Largest vertex displacement of the solution [m] (the step's acceptance test, §4.5)."""
    return float(np.max(vertex_displacement(model, vertex_xy, geom, disp, moved_xy), initial=0.0))


def moved(model: Model, state: State, geom: dict, disp: np.ndarray, vertex_xy: Optional[np.ndarray] = None) -> dict:
    """The fields of ``state`` that a solution ``disp`` moves: vertices and points (exact
    rotation, §5.3), stresses (strain increment, then rotated with the block, §5.4; fixed
    blocks keep theirs) and the accumulated rotation — what a step and the equilibrium stage's
    settlement share. ``vertex_xy``: the vertices moved by ``disp``, when already known (the
    acceptance test moved them)."""
    centroid = geom["centroid"]
    if vertex_xy is None:
        vertex_xy = move_points(state.vertex_xy, model.vertex_block, centroid, disp)
    stress = state.block_stress + np.einsum("bij,bj->bi", model.block_elastic, disp[:, 3:6])
    stress = rotate_stress(stress, disp[:, 2])
    stress[model.block_fixed] = state.block_stress[model.block_fixed]
    return dict(
        vertex_xy=vertex_xy, block_stress=stress, block_rotation=state.block_rotation + disp[:, 2],
        fixed_point_xy=move_points(state.fixed_point_xy, model.fixed_point_block, centroid, disp),
        load_xy=move_points(state.load_xy, model.load_block, centroid, disp),
        measured_xy=move_points(state.measured_xy, model.measured_block, centroid, disp))


@side_by_side.operation("settle_points")
def settle_points(model: Model, state: State, geom: dict, disp: np.ndarray) -> State:
    """``state`` with its blocks moved by a static increment ``disp`` and its stress added
    (the equilibrium stage's settlement): velocities untouched, fixed blocks' stress kept."""
    fields = moved(model, state, geom, disp)
    return state.replace(**fields, geometry=model.block_geometry(fields["vertex_xy"]))


def update(model: Model, state: State, geom: dict, disp: np.ndarray, contacts: Contacts, dt: float,
           vertex_xy: Optional[np.ndarray] = None) -> State:
    """The state after an accepted step: vertices and points moved (exact rotation, §5.3),
    stresses (§5.4), velocities and accelerations (§5.2), bolts, and the contact memory that
    the next step starts from. ``vertex_xy``: the vertices moved by ``disp``, when already
    known (`moved`)."""
    m, p = model, model.params
    fields = moved(m, state, geom, disp, vertex_xy)
    # Newmark, γ = 1: a_{n+1} = (D − v Δt)/(βΔt²) − (1/(2β) − 1) a_n, v_{n+1} = v + Δt a_{n+1}
    # (β = ½: v_{n+1} = 2D/Δt − v, Shi's update, §5.2)
    beta = newmark_beta(p, state)
    carried = p.velocity_carry * state.block_velocity
    block_accel = (disp - carried * dt) / (beta * dt * dt) - (0.5 / beta - 1.0) * state.block_accel
    velocity = carried + dt * block_accel
    velocity[m.block_fixed] = 0.0
    block_accel[m.block_fixed] = 0.0
    radius = block_radius(m, state.vertex_xy, geom["centroid"])
    dv = velocity - state.block_velocity
    accel = float(np.max(np.hypot(dv[:, 0], dv[:, 1]) + np.abs(dv[:, 2]) * radius, initial=0.0)) / dt
    if p.static:
        velocity[:] = 0.0
        block_accel[:] = 0.0
    bolts = {}
    if len(m.bolt_block):
        # bolt tensions on the moved ends; those beyond their capacity break (B1)
        from .support import break_bolts

        bolts = break_bolts(m, state, fields["vertex_xy"], state.step + 1, state.time + dt)
    return State(
        geometry=m.block_geometry(fields["vertex_xy"]), time=state.time + dt, step=state.step + 1,
        block_velocity=velocity, block_accel=block_accel, dt=dt, accel=accel,
        memory=contacts.memory(p.bond_breaks_on_slip), **fields, **bolts)
