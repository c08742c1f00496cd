"""Many small independent models run as one: members laid side by side in a row, far enough
apart that no block of one can reach another, each keeping the model constants it has alone
(docs/guide/performance.md, "Batched studies").

A step of a model of a few blocks costs its fixed overhead (the Python calls of the phases), not
its arithmetic: 1.4 ms for one block, 4.3 ms for 64 on the NumPy path. The verdicts of a
critical-friction bisection or of a probabilistic study are many such models that differ only in
their joints; run side by side they share that overhead. The members interact through nothing but
the step's shared Δt (a fixed Δt stays the same; the automatic one follows the fastest member, as
a shorter Δt than a member needs alone); the solve of the combined model is block-diagonal, one
block per member.

A member keeps what it would have alone because the model's constants that come from the whole
model — the length scale w0 of the tolerances (ntdda's, from the model's extent) and the
automatic penalty — are taken from the members' own models (`batch_model`): members whose own
constants differ cannot share a batch.
"""

from __future__ import annotations

import copy
from dataclasses import dataclass, replace
from typing import Optional, Sequence

import numpy as np

from .model import Model, State, build_model
from .params import Params
from .scene import Scene


#: "auto" solves a batch of at most this many unknowns densely (8 members of 2 free blocks:
#: 96), a larger one sparsely (docs/guide/performance.md, "Batched studies")
BATCH_DENSE_UNKNOWNS = 200


@dataclass(frozen=True, kw_only=True, eq=False)
class Batch:
    """Independent members in one scene (`side_by_side`)."""

    scene: Scene
    """The combined scene: member k's blocks follow member k−1's, translated by ``shift[k]``."""
    block_offset: np.ndarray
    """(K + 1,) member k's blocks are ``block_offset[k]:block_offset[k + 1]`` [-]."""
    shift: np.ndarray
    """(K, 2) translation of each member in the combined scene [m]."""

    @property
    def n_members(self) -> int:
        return len(self.shift)


def side_by_side(members: Sequence[Scene], *, gap: float) -> Batch:
    """One scene holding ``members`` in a row along x, each at least ``gap`` [m] clear of the
    next. Each member keeps its own joint table (its default joint included: edges on no joint
    line and pairs without an override refer to the member's own entries), point loads, fixed and
    measured points and bolts. The members must share gravity and the shaking (the same function
    or none) and have no water table (a water table is a position in space, not a part of a
    member)."""
    if not members:
        raise ValueError("side_by_side: no members")
    if not (np.isfinite(gap) and gap >= 0):
        raise ValueError(f"side_by_side: gap must be a finite length >= 0 m, got {gap!r}")
    first = members[0]
    for k, m in enumerate(members):
        if not isinstance(m, Scene):
            raise ValueError(f"side_by_side: member {k} is a {type(m).__name__}, not a ddatai.Scene")
        if m.gravity != first.gravity:
            raise ValueError(f"side_by_side: member {k} has gravity {m.gravity} m/s², member 0 {first.gravity}")
        if m.ground_acceleration is not first.ground_acceleration:
            raise ValueError(f"side_by_side: member {k} is shaken differently from member 0")
        if m.water is not None:
            raise ValueError(f"side_by_side: member {k} has a water table; members must have none")
        if not m.blocks:
            raise ValueError(f"side_by_side: member {k} has no blocks")
    out = copy.copy(first)
    out.blocks, out.joints, out.pair_joints = [], [], {}
    out.fixed_points, out.point_loads, out.measured_points, out.bolts = [], [], [], []
    shifts, offsets = [], [0]
    x_end = None
    for m in members:
        xy = np.concatenate([b.vertices for b in m.blocks])
        lo, hi = xy.min(axis=0), xy.max(axis=0)
        dx = 0.0 if x_end is None else x_end + gap - lo[0]
        x_end = hi[0] + dx
        shift = np.array([dx, 0.0])
        shifts.append(shift)
        j0, b0 = len(out.joints), len(out.blocks)
        out.joints.extend(m.joints)
        for b in m.blocks:
            # an edge on no joint line takes the member's own default joint (entry 0 of its table)
            edge = np.where(b.edge_joint < 0, j0, b.edge_joint + j0).astype(np.int64)
            out.blocks.append(replace(b, vertices=b.vertices + shift, edge_joint=edge))
        for (i, j), k in m.pair_joints.items():
            out.pair_joints[(i + b0, j + b0)] = k + j0
        for name in ("fixed_points", "point_loads", "measured_points"):
            getattr(out, name).extend(replace(p, block=p.block + b0, xy=(p.xy[0] + dx, p.xy[1]))
                                      for p in getattr(m, name))
        out.bolts.extend(replace(b, block1=b.block1 + b0, block2=b.block2 + b0,
                                 xy1=(b.xy1[0] + dx, b.xy1[1]), xy2=(b.xy2[0] + dx, b.xy2[1]))
                         for b in m.bolts)
        offsets.append(len(out.blocks))
    return Batch(scene=out, block_offset=np.array(offsets), shift=np.array(shifts))


def member_constants(model: Model) -> tuple[float, float]:
    """The constants a member's own model takes from the whole model: (w0 [m], penalty [N/m])."""
    return float(model.w0), float(model.penalty)


def batch_model(batch: Batch, params: Params, *, w0: float, penalty: float) -> Model:
    """The model of the combined scene with a member's own constants: the length scale ``w0``
    [m] (and every tolerance that follows from it) and the ``penalty`` [N/m] of the members'
    models (`member_constants`; all members must have the same). ``solver="auto"`` solves
    densely up to BATCH_DENSE_UNKNOWNS, sparsely above."""
    from .solver import resolve

    if params.solver == "auto":
        # K is block-diagonal, one block a member: a sparse factorisation costs about the sum
        # of the members', a dense one the cube of their total (11 ms a solve at 600 unknowns);
        # below BATCH_DENSE_UNKNOWNS the dense solve's fewer calls still win
        unknowns = 6 * sum(not b.fixed for b in batch.scene.blocks)
        params = replace(params, solver="dense" if unknowns <= BATCH_DENSE_UNKNOWNS else resolve("auto"))
    return build_model(batch.scene, replace(params, penalty=float(penalty)), length_scale=w0)


def _key_parts(memory, n_vertices: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The two vertex numbers (vertex and edge, or both vertices) of each contact identity
    (`ddatai.contacts.contact_keys`) in a model of ``n_vertices``, and which are vertex-vertex."""
    from .layout import ContactKind

    n = np.int64(n_vertices)
    vv = memory.kind == ContactKind.VV
    key = np.where(vv, memory.key - n * n, memory.key)
    return key // n, key % n, vv


def _key(first: np.ndarray, second: np.ndarray, vv: np.ndarray, n_vertices: int) -> np.ndarray:
    """Contact identities (`ddatai.contacts.contact_keys`) from their two vertex numbers."""
    n = np.int64(n_vertices)
    return np.where(vv, n * n, 0) + first * n + second


def combined_state(batch: Batch, model: Model, members: Sequence[Model], states: Sequence) -> State:
    """The state of the batch's ``model`` made of each member's own ``states`` (of its own model
    ``members[k]``): a member settled by its own equilibrium stage (`ddatai.start.settle`) starts
    the batch as it would start alone — the stage decides per model whether a part is held,
    released or welded, so a batch of members settled together would not. Positions move to the
    batch's coordinates, contact identities to its vertex numbers; energies add up."""
    from .model import ContactMemory

    if len(members) != batch.n_members or len(states) != batch.n_members:
        raise ValueError(f"combined_state: {batch.n_members} members, got {len(members)} models and "
                         f"{len(states)} states")
    v_offset = np.concatenate([[0], np.cumsum([m.n_vertices for m in members])])
    if v_offset[-1] != model.n_vertices:
        raise ValueError("combined_state: the members' models do not make up the batch's model")

    def moved(k, xy):  # member k's internal coordinates -> the batch's
        return xy + (members[k].origin + batch.shift[k] - model.origin)

    def cat(name):
        return np.concatenate([getattr(s, name) for s in states])

    memory = []
    for k, (m, s) in enumerate(zip(members, states)):
        first, second, vv = _key_parts(s.memory, m.n_vertices)
        memory.append(replace(s.memory, key=_key(first + v_offset[k], second + v_offset[k], vv, model.n_vertices)))
    fields = [f for f in ContactMemory.__dataclass_fields__ if f != "key"]
    key = np.concatenate([m.key for m in memory])
    order = np.argsort(key, kind="stable")
    joined = {f: np.concatenate([getattr(m, f) for m in memory])[order] for f in fields
              if all(len(getattr(m, f)) == len(m.key) for m in memory)}
    joined.update({f: np.zeros(0) for f in fields if f not in joined})
    energy = None if any(s.energy is None for s in states) else float(sum(s.energy for s in states))
    first = states[0]
    extra = {} if not len(model.bolt_block) else {
        name: cat(name) for name in ("bolt_force", "bolt_broken_step", "bolt_broken_time", "bolt_broken_force")}
    return State(
        time=first.time, step=first.step,
        vertex_xy=np.concatenate([moved(k, s.vertex_xy) for k, s in enumerate(states)]),
        block_velocity=cat("block_velocity"), block_stress=cat("block_stress"), block_accel=cat("block_accel"),
        block_rotation=cat("block_rotation"),
        fixed_point_xy=np.concatenate([moved(k, s.fixed_point_xy) for k, s in enumerate(states)]).reshape(-1, 2),
        load_xy=np.concatenate([moved(k, s.load_xy) for k, s in enumerate(states)]).reshape(-1, 2),
        measured_xy=np.concatenate([moved(k, s.measured_xy) for k, s in enumerate(states)]).reshape(-1, 2),
        dt=max(s.dt for s in states), accel=max(s.accel for s in states),
        memory=ContactMemory(key=key[order], **joined), energy=energy, in_doubt=_in_doubt(members, states), **extra)


def _in_doubt(members: Sequence[Model], states: Sequence[State]) -> np.ndarray:
    """The batch's `State.in_doubt`: the members' blocks released in doubt (empty: none)."""
    if not any(s.in_doubt.any() for s in states):
        return np.zeros(0, bool)
    return np.concatenate([s.in_doubt if s.in_doubt.any() else np.zeros(m.n_blocks, bool)
                           for m, s in zip(members, states)])


def member_states(batch: Batch, model: Model, members: Sequence[Model], state: State,
                  which: Optional[Sequence[int]] = None) -> list:
    """The states of members ``which`` (all by default) in their own models, cut out of a
    ``state`` of the batch's ``model`` (the inverse of `combined_state`): a batch whose members
    have been decided goes on with the others alone (`side_by_side` of those, `combined_state`
    of these states). The mechanical energy of a member is not known apart: None (a step
    computes it again)."""
    from .model import ContactMemory

    which = range(batch.n_members) if which is None else which
    v_offset = np.concatenate([[0], np.cumsum([m.n_vertices for m in members])])
    b_offset = batch.block_offset

    def offsets(name):
        return np.concatenate([[0], np.cumsum([len(getattr(m, name)) for m in members])])

    points = {name: offsets(name) for name in ("fixed_point_block", "load_block", "measured_block", "bolt_block")}
    mem = state.memory
    first, second, vv = _key_parts(mem, model.n_vertices)
    owner = np.searchsorted(v_offset, first, side="right") - 1
    fields = [f for f in ContactMemory.__dataclass_fields__ if f != "key"]
    out = []
    for k in which:
        m = members[k]
        lo, hi = v_offset[k], v_offset[k + 1]
        b0, b1 = b_offset[k], b_offset[k + 1]
        back = m.origin + batch.shift[k] - model.origin  # member -> batch coordinates

        def part(name, kind):
            p = points[kind]
            return getattr(state, name)[p[k]:p[k + 1]]

        rows = np.flatnonzero(owner == k)
        new_key = _key(first[rows] - lo, second[rows] - lo, vv[rows], m.n_vertices)
        order = np.argsort(new_key, kind="stable")
        memory = ContactMemory(key=new_key[order], **{
            f: (getattr(mem, f)[rows][order] if len(getattr(mem, f)) == len(mem.key) else np.zeros(0))
            for f in fields})
        extra = {} if not len(m.bolt_block) else {
            name: part(name, "bolt_block").copy()
            for name in ("bolt_force", "bolt_broken_step", "bolt_broken_time", "bolt_broken_force")}
        out.append(State(
            time=state.time, step=state.step,
            vertex_xy=state.vertex_xy[lo:hi] - back,
            block_velocity=state.block_velocity[b0:b1].copy(), block_stress=state.block_stress[b0:b1].copy(),
            block_accel=state.block_accel[b0:b1].copy(), block_rotation=state.block_rotation[b0:b1].copy(),
            fixed_point_xy=part("fixed_point_xy", "fixed_point_block") - back,
            load_xy=part("load_xy", "load_block") - back,
            measured_xy=part("measured_xy", "measured_block") - back,
            dt=state.dt, accel=state.accel, memory=memory, energy=None,
            in_doubt=state.in_doubt[b0:b1].copy() if state.in_doubt.any() else np.zeros(0, bool), **extra))
    return out
