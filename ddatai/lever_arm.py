"""The lever arms of the contact constraints at mid-step (docs/method/dda.md §5.3): the geometric
stiffness of a block's rotation, which the first-order step equations leave out.

The step equations linearise each contact's normal and shear distances at the step's start: a
point X from its block's centroid moves by JX·r for a rotation r (JX = (−Y, X)), and the
second-order terms q(r̄) of the exact update (``assembly.second_order``) only shift the constant
part of the distance. A contact force then turns its block through the lever arm of the step's
start while the block turns by r: the force's torque lags the motion, and a block rocking on a
corner under gravity loses ½·F·R·cos(α − θ)·r² a step (F the corner's force, R its arm): 1.3 %
of its energy every swing at Δt = 10 ms (a spinning block on a pin gains, by the same lag).

Here the rotation column of a contact vertex's gradient is the derivative of the exact update at
half the step's rotation, J·R(r̄/2)·X = JX + q'(r̄/2), the midpoint rule: the distance stays
linear in D, exact at the rotation r̄ of the latest iterate (the constant part takes
−q'(r̄/2)·r̄ with q(r̄)), and its slope is the chord's to O(r̄²), so the force does the work of
the arc (the vertex's energy balance to O(r³) a step, second order).

Only the contact's vertex takes its lever arm at mid-step: the edge's side keeps the step
start's, because the slope of an edge's turn also depends on where its own normal has turned to
(the bilinear term of Δ in the edge's two ends, which the second-order shift leaves out as well);
turning the edge's arms alone made a block tipping off a corner gain 1.8 J of its 4,500 J
(tests/test_stability.py), where the step start's arms gain 0.23 J and the vertex's alone 0.08 J.
"""

from __future__ import annotations

import numpy as np

from . import side_by_side
from .contacts import Contacts
from .layout import KIND, N_SLOTS, S_E0, S_E1, S_ES, VE, VV
from .model import Model


@side_by_side.operation("midstep_lever_arms")
def midstep_lever_arms(model: Model, contacts: Contacts, vertex_xy: np.ndarray, centroid: np.ndarray,
                       rotation: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(columns, shift): ``columns`` (m, N_SLOTS) what the rotation column (index 2) of each
    contact vertex's slots (normal of each line, shear) gains at the mid-step lever arm (module
    docstring); ``shift`` (m, 3) what the constant parts (dn line 0, dn line 1, ds) lose with
    it, −Δcolumn·r̄, so that the distances stay exact at ``rotation`` r̄ (each block's rotation
    in the latest iterate). Zeros where no block rotates."""
    n = contacts.n
    columns = np.zeros((n, N_SLOTS))
    shift = np.zeros((n, 3))
    if n == 0 or not np.any(rotation):
        return columns, shift
    nxt, vb = model.vertex_next, model.vertex_block
    x = vertex_xy - centroid[vb]
    half = 0.5 * rotation[vb]
    cos_1, sin = np.cos(half) - 1.0, np.sin(half)
    # q'(φ)X = J(R(φ) − I)X of every vertex once (φ = r̄/2 of its block)
    dq = np.empty_like(x)
    dq[:, 0] = -sin * x[:, 0] - cos_1 * x[:, 1]
    dq[:, 1] = cos_1 * x[:, 0] - sin * x[:, 1]
    cint = contacts.cint
    rot_a, rot_b = rotation[contacts.block_a], rotation[contacts.block_b]
    for line, slot in enumerate((S_E0, S_E1)):
        rows = slice(None) if line == 0 else np.flatnonzero(cint[:, KIND] == VV)
        if line == 1 and not len(rows):
            continue
        p1, k = cint[rows, 1 + 2 * line], cint[rows, 2 + 2 * line]
        P2, P3 = vertex_xy[nxt[k]], vertex_xy[k]
        q1 = dq[p1]
        length = np.hypot(P3[:, 0] - P2[:, 0], P3[:, 1] - P2[:, 1])
        # ∂Δ/∂P1·q' (§2.8.1): line 0's vertex is on block a, line 1's on block b
        vertex = ((P2[:, 1] - P3[:, 1]) * q1[:, 0] + (P3[:, 0] - P2[:, 0]) * q1[:, 1]) / length
        columns[rows, slot] = vertex
        shift[rows, line] = -vertex * (rot_a if line == 0 else rot_b[rows])
        if line == 0:
            # ∂s/∂P1·q' = (P3 − P2)·q'/l, s = (P1 − P0)·(P3 − P2)/l (§2.8.3), vertex-edge contacts
            vertex_s = np.where(cint[:, KIND] == VE, ((P3 - P2) * q1).sum(1) / length, 0.0)
            columns[:, S_ES] = vertex_s
            shift[:, 2] = -vertex_s * rot_a
    return columns, shift


def lever_shift(contacts: Contacts, columns: np.ndarray, rotation: np.ndarray) -> np.ndarray:
    """(m, 3) the shift of the constant parts (dn line 0, dn line 1, ds) that keeps the distances
    exact at ``rotation`` r̄ (each block's rotation in the latest iterate) with the lever-arm
    ``columns`` of `midstep_lever_arms` taken at another rotation (``Params.lever_arm_rotation
    = "predicted"``): −column·r̄ of the contact vertex's block, as `midstep_lever_arms` gives it
    with columns and r̄ of the same rotation."""
    shift = np.zeros((contacts.n, 3))
    if contacts.n == 0:
        return shift
    rot_a, rot_b = rotation[contacts.block_a], rotation[contacts.block_b]
    shift[:, 0] = -columns[:, S_E0] * rot_a
    shift[:, 1] = np.where(contacts.cint[:, KIND] == VV, -columns[:, S_E1] * rot_b, 0.0)
    shift[:, 2] = -columns[:, S_ES] * rot_a
    return shift


def with_lever_arms(vec: np.ndarray, columns: np.ndarray) -> np.ndarray:
    """The contact vectors ``vec`` (m, N_SLOTS, 6) with ``columns`` added to their rotation
    column (a copy; ``vec`` itself where nothing changes)."""
    if not np.count_nonzero(columns):
        return vec
    out = vec.copy()
    out[:, :, 2] += columns
    return out
