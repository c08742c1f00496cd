"""Assembly of the step's linear system K·D = F (docs/method/dda.md §2.1–2.8).

- `BlockPattern`: the CSR layout of the global matrix for one step, one dense 6×6 block per
  free block and per coupled pair (touching blocks, bolted blocks);
- `assemble_blocks`: the terms that do not depend on contact states — inertia, elasticity,
  initial stress, body force, fixed points, point loads, water pressure and bolts (§2.1–2.6);
- `contact_vectors` and `assemble_contacts`: the normal and shear springs of closed contacts
  and the friction loads of sliding ones (§2.8);
- `second_order`: the second-order rotation terms of the constraints (§5.3).

Taichi kernels (`ddatai.kernels`) do the per-block and per-contact work; their NumPy twins are
in `ddatai.reference` (dense assembly), and tests compare them.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Optional

import numpy as np

from .contact_law import friction_terms
from .contacts import Contacts
from .geometry import displacement_matrix, mass_matrix
from .layout import N_SLOTS
from .model import Model, State


@dataclass(kw_only=True, eq=False)
class BlockPattern:
    """CSR layout of the global stiffness matrix for one step (full symmetric storage).

    Entry (a, b) of the 6×6 block (r, c) lives at ``data[slot + a*stride[r] + b]``, where
    ``slot`` is the block's slot and ``stride[r] = 6 × (blocks in block-row r)``.
    """

    n_rows: int
    """Number of block-rows (free blocks)."""
    indptr: np.ndarray
    indices: np.ndarray
    diag_slot: np.ndarray
    """(n_rows,) slot of each diagonal block."""
    stride: np.ndarray
    """(n_rows,) scalar row length of each block-row."""
    slot_ab: np.ndarray
    """(m,) slot of block (row of block_a, column of block_b) for each contact, -1 if none."""
    slot_ba: np.ndarray
    """(m,) slot of block (row of block_b, column of block_a), -1 if none."""
    pair_key: np.ndarray
    """(pairs,) sorted keys lo·n_rows + hi of the coupled block pairs (lo < hi)."""
    block_key: np.ndarray
    """(6×6 blocks,) sorted keys row·n_rows + col of every stored 6×6 block."""
    block_slot: np.ndarray
    """(6×6 blocks,) slot of each stored block, in the order of ``block_key``."""

    @property
    def nnz(self) -> int:
        return len(self.indices)

    def slots(self, r: np.ndarray, c: np.ndarray) -> np.ndarray:
        """Slot of the 6×6 block (block-row r, block-column c) for each entry, −1 where r or c
        is a fixed block (−1) or r == c."""
        return _block_slots(self.block_key, self.block_slot, self.n_rows, r, c)

    @staticmethod
    def build(model: Model, contacts: Contacts, previous: Optional["BlockPattern"] = None
              ) -> "BlockPattern":
        """The pattern for ``contacts``. When the coupled block pairs are those of ``previous``
        (a settled model keeps them for many steps), its layout is reused and only the
        contacts' slots are looked up (saves ~5 ms per step at 1,600 blocks; the solver then
        also keeps its ordering)."""
        nr = model.n_free
        dof = model.block_dof
        ra = dof[contacts.block_a].astype(np.int64)
        rb = dof[contacts.block_b].astype(np.int64)
        coupled = (ra >= 0) & (rb >= 0) & (ra != rb)
        lo = np.minimum(ra[coupled], rb[coupled])
        hi = np.maximum(ra[coupled], rb[coupled])
        if len(model.bolt_block):
            # a bolt couples its two blocks even where they do not touch (docs/method/water_bolts.md,
            # B1); ddatai.support is loaded only by models with water or bolts
            from .support import bolt_pairs

            bi, bj = bolt_pairs(model)
            lo, hi = np.concatenate([lo, np.minimum(bi, bj)]), np.concatenate([hi, np.maximum(bi, bj)])
        pair = np.unique(lo * nr + hi)
        if (previous is not None and previous.n_rows == nr and len(previous.pair_key) == len(pair)
                and np.array_equal(previous.pair_key, pair)):
            key, at = previous.block_key, previous.block_slot
            return dataclasses.replace(previous, slot_ab=_block_slots(key, at, nr, ra, rb),
                                       slot_ba=_block_slots(key, at, nr, rb, ra))
        lo, hi = pair // nr, pair % nr
        diag = np.arange(nr, dtype=np.int64)
        rows = np.concatenate([diag, lo, hi])
        cols = np.concatenate([diag, hi, lo])
        bkey = rows * nr + cols
        order = np.argsort(bkey)
        bkey, rows, cols = bkey[order], rows[order], cols[order]
        ncols = np.bincount(rows, minlength=nr)
        first = np.concatenate([[0], np.cumsum(ncols)[:-1]])
        pos = np.arange(len(rows)) - first[rows]
        base = 36 * first
        stride = 6 * ncols
        slot = base[rows] + 6 * pos
        a = np.arange(6)
        # scalar row 6r+a starts at base[r] + a*stride[r]
        indptr = np.empty(6 * nr + 1, np.int64)
        indptr[:-1] = (base[:, None] + a[None, :] * stride[:, None]).ravel()
        indptr[-1] = 36 * len(rows)
        idx = slot[:, None, None] + a[None, :, None] * stride[rows][:, None, None] + a[None, None, :]
        indices = np.empty(36 * len(rows), np.int32)
        indices[idx.ravel()] = np.broadcast_to(6 * cols[:, None, None] + a[None, None, :],
                                               idx.shape).ravel()
        return BlockPattern(
            n_rows=nr, indptr=indptr.astype(np.int32), indices=indices,
            diag_slot=slot[np.searchsorted(bkey, diag * nr + diag)].astype(np.int32),
            stride=stride.astype(np.int32), slot_ab=_block_slots(bkey, slot, nr, ra, rb),
            slot_ba=_block_slots(bkey, slot, nr, rb, ra), pair_key=pair, block_key=bkey, block_slot=slot)


def _block_slots(block_key: np.ndarray, block_slot: np.ndarray, n_rows: int, r: np.ndarray,
                 c: np.ndarray) -> np.ndarray:
    """Slot of the 6×6 block (r, c) for each entry, -1 where r or c is fixed or r == c."""
    out = np.full(len(r), -1, np.int32)
    ok = (r >= 0) & (c >= 0) & (r != c)
    out[ok] = block_slot[np.searchsorted(block_key, r[ok] * n_rows + c[ok])]
    return out


def load_forces(model: Model, t: float) -> np.ndarray:
    """(nl, 2) force of each point load at time ``t`` [N/m] (a constant or a function of t)."""
    return np.array([f(t) if callable(f) else f for f in model.load_force], dtype=float).reshape(-1, 2)


def contact_vectors(model: Model, vertex_xy: np.ndarray, geom: dict, contacts: Contacts
                    ) -> tuple[np.ndarray, np.ndarray]:
    """Normal/shear vectors e, g, e_s, g_s, t_j and constant parts of every contact (§2.8):
    ``vec`` (m, N_SLOTS, 6) by `ddatai.layout` slot, ``sca`` (m, 3) = (dn0 line 0, dn0 line 1, ds0)."""
    m = contacts.n
    vec = np.zeros((m, N_SLOTS, 6))
    sca = np.zeros((m, 3))
    if m:
        from . import kernels as K

        K.contact_vectors(vertex_xy, model.vertex_block, model.vertex_next,
                          np.ascontiguousarray(geom["centroid"]), contacts.cint, contacts.omega, vec, sca)
    return vec, sca


def assemble_blocks(model: Model, state: State, geom: dict, pattern: BlockPattern, dt: float, beta: float,
                    static_start: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """The part of K and F that does not depend on contact states: inertia, elasticity,
    initial stress, body force, fixed points and point loads (§2.1–2.6), the loads and
    ground acceleration taken at mid-step; ``beta``: Newmark's β of the step
    (`kinematics.newmark_beta`). ``static_start``: the equilibrium stage's system
    (`ddatai.start`): loads at t = 0, no ground acceleration, the state's velocities and
    accelerations ignored."""
    data = np.zeros(pattern.nnz)
    rhs = np.zeros(6 * pattern.n_rows)
    if pattern.n_rows == 0:
        return data, rhs
    from . import kernels as K

    dof = model.block_dof
    t_mid = state.time if static_start else state.time + 0.5 * dt
    body = model.gravity.copy()
    if model.ground_acceleration is not None and not static_start:
        # the ground's frame: every block feels -a_g(t) (§2.4, seismic body force)
        body -= np.asarray(model.ground_acceleration(t_mid), dtype=float)
    mass = mass_matrix(geom["area"], geom["s1"], geom["s2"], geom["s3"])
    velocity, accel = state.block_velocity, state.block_accel
    if static_start:
        velocity, accel = np.zeros_like(velocity), np.zeros_like(accel)
    K.assemble_blocks(dof, model.block_density, model.block_elastic, geom["area"], mass,
                      velocity, accel, state.block_stress, float(body[0]),
                      float(body[1]), dt, model.params.velocity_carry, beta,
                      pattern.diag_slot, pattern.stride, data, rhs)
    centroid = np.ascontiguousarray(geom["centroid"])
    if len(model.fixed_point_block):
        # restoring spring towards the original position (§2.6)
        force = model.fixed_point_penalty * (model.fixed_point_xy0 - state.fixed_point_xy)
        stiff = np.full(len(model.fixed_point_block), model.fixed_point_penalty)
        K.assemble_points(model.fixed_point_block, state.fixed_point_xy, force, stiff,
                          dof, centroid, pattern.diag_slot, pattern.stride, data, rhs)
    if len(model.load_block):
        K.assemble_points(model.load_block, state.load_xy, load_forces(model, t_mid),
                          np.zeros(len(model.load_block)), dof, centroid, pattern.diag_slot,
                          pattern.stride, data, rhs)
    if model.water_unit_weight > 0 or len(model.bolt_block):
        # water pressure (W2) and bolt springs (B1), docs/method/water_bolts.md; ddatai.support is
        # loaded only by models that have them
        from .support import assemble_bolts, assemble_water

        if model.water_unit_weight > 0:
            assemble_water(model, state.vertex_xy, centroid, rhs)
        if len(model.bolt_block):
            assemble_bolts(model, state.vertex_xy, centroid, state.bolt_broken_step < 0, pattern, data, rhs)
    return data, rhs


def assemble_contacts(model: Model, contacts: Contacts, pattern: BlockPattern, vec: np.ndarray,
                      sca: np.ndarray, data: np.ndarray, rhs: np.ndarray, serial_scatter: bool) -> None:
    """Add springs of closed contacts and friction loads of sliding ones, in place (§2.8)."""
    if contacts.n == 0:
        return
    from . import kernels as K

    const, slope = friction_terms(model, contacts)
    K.assemble_contacts(contacts.cint, contacts.state, contacts.line, model.vertex_block, model.block_dof,
                        vec, sca, const, slope, contacts.shear_dir,
                        pattern.slot_ab, pattern.slot_ba, pattern.diag_slot, pattern.stride,
                        model.penalty, model.shear_penalty, data, rhs, serial_scatter)


def second_order(model: Model, contacts: Contacts, state: State, geom: dict, rotation: np.ndarray,
                 rhs: np.ndarray) -> np.ndarray:
    """Second-order rotation terms of the constraints, for the exact-rotation update (§5.3).

    The step equations use the linearised displacement T·D, but points are moved with the
    exact rotation, which adds q = (cos r − 1)X + (sin r − r)JX (≈ −½r²X, JX = (−Y, X)) to a
    point at X from its block's centroid. A block swinging about a constrained point (a
    fixed point, a contact at a pivot corner) would drift outwards by q every step and be
    pulled back, the constraint doing work: energy grows ∝ ω²Δt. Folding q, evaluated with
    the rotation r of the latest iterate, into the constant parts of the contact distances
    (returned, (m, 3): dn line 0, dn line 1, ds) and into the fixed-point springs (added to
    ``rhs`` in place) makes the constraints hold for the exact update.
    """
    m = model
    shift = np.zeros((contacts.n, 3))
    if not np.any(rotation):
        return shift
    xy, centroid, nxt, vb = state.vertex_xy, geom["centroid"], m.vertex_next, m.vertex_block

    def q(points, blocks):
        X = points - centroid[blocks]
        r = rotation[blocks]
        jx = np.stack([-X[:, 1], X[:, 0]], axis=1)
        return (np.cos(r) - 1.0)[:, None] * X + (np.sin(r) - r)[:, None] * jx

    if contacts.n:
        from . import kernels as K

        # q of every vertex once (a vertex appears in several contacts), then ∂Δ/∂P·q and
        # ∂s/∂P·q per contact line
        K.second_order_shift(xy, nxt, q(xy, vb), contacts.cint, contacts.omega, shift)
    if len(m.fixed_point_block):
        fb = m.fixed_point_block
        rows = m.block_dof[fb]
        use = rows >= 0
        pts = state.fixed_point_xy[use]
        t = displacement_matrix(pts, centroid[fb[use]])
        load = -m.fixed_point_penalty * np.einsum("nij,ni->nj", t, q(pts, fb[use]))
        np.add.at(rhs, (6 * rows[use])[:, None] + np.arange(6)[None, :], load)
    return shift
