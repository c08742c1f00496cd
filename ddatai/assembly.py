"""Assembly of the step's linear system K·D = F (docs/method/dda.md §2.1–2.8).

- `BlockPattern`: the CSR layout of the global matrix for one step, one dense 6×6 block per
  free block and per coupled pair (touching blocks, bolted blocks);
- `assemble_blocks`: the terms that do not depend on contact states — inertia, elasticity,
  initial stress, body force, fixed points, point loads, water pressure and bolts (§2.1–2.6);
- `contact_vectors` and `assemble_contacts`: the normal and shear springs of closed contacts
  and the friction loads of sliding ones (§2.8);
- ``second_order``: the second-order rotation terms of the constraints (§5.3).

Taichi kernels (`ddatai.kernels`) do the per-block and per-contact work; their NumPy twins are
in `ddatai.reference` (dense assembly), and tests compare them.
"""

from __future__ import annotations

import copy
from dataclasses import dataclass
from typing import ClassVar, Optional

import numpy as np

from . import side_by_side, vectorized
from .contact_law import friction_terms
from .contacts import Contacts
from .geometry import displacement_matrix, mass_matrix
from .layout import KIND, LOCK, N_SLOTS, OPEN, S_E0, S_ES, S_G0, S_GS, SLIDE, VE
from .model import Model, State
from .reference import second_order_shift


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

    #: every coupled block pair stores both of its 6×6 blocks, so the pattern is symmetric even
    #: where friction makes the values not (the solver's LU then works on the symmetric
    #: structure: `ddatai.pardiso._Pardiso`)
    structurally_symmetric: ClassVar[bool] = True

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
            # a shallow copy with the contacts' slots (dataclasses.replace re-runs __init__)
            reused = copy.copy(previous)
            reused.slot_ab, reused.slot_ba = _block_slots(key, at, nr, ra, rb), _block_slots(key, at, nr, rb, ra)
            return reused
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


@side_by_side.operation("contact_vectors")
def contact_vectors(model: Model, vertex_xy: np.ndarray, geom: dict, contacts: Contacts
                    ) -> tuple[np.ndarray, np.ndarray]:
    """Normal/shear vectors e, g, e_s, g_s, t_j and constant parts of every contact (§2.8):
    ``vec`` (m, N_SLOTS, 6) by `ddatai.layout` slot, ``sca`` (m, 3) = (dn0 line 0, dn0 line 1, ds0)."""
    m = contacts.n
    if model.numpy_path:
        return vectorized.contact_vectors(model, vertex_xy, np.ascontiguousarray(geom["centroid"]),
                                          contacts.cint, contacts.omega)
    vec = np.zeros((m, N_SLOTS, 6))
    sca = np.zeros((m, 3))
    if m:
        from . import kernels as K

        K.contact_vectors(vertex_xy, model.vertex_block, model.vertex_next,
                          np.ascontiguousarray(geom["centroid"]), contacts.cint, contacts.omega, vec, sca)
    return vec, sca


@side_by_side.operation("block_terms")
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
    if model.numpy_path:
        block_terms, point_terms = block_terms_numpy, point_terms_numpy
    else:
        from . import kernels as K

        block_terms, point_terms = K.assemble_blocks, K.assemble_points
    block_terms(dof, model.block_density, model.block_elastic, geom["area"], mass,
                velocity, accel, state.block_stress, float(body[0]),
                float(body[1]), dt, model.params.velocity_carry, beta,
                pattern.diag_slot, pattern.stride, data, rhs)
    centroid = np.ascontiguousarray(geom["centroid"])
    if len(model.fixed_point_block):
        # restoring spring towards the original position (§2.6)
        force = model.fixed_point_penalty * (model.fixed_point_xy0 - state.fixed_point_xy)
        stiff = np.full(len(model.fixed_point_block), model.fixed_point_penalty)
        point_terms(model.fixed_point_block, state.fixed_point_xy, force, stiff,
                    dof, centroid, pattern.diag_slot, pattern.stride, data, rhs)
    if len(model.load_block):
        point_terms(model.load_block, state.load_xy, load_forces(model, t_mid),
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


@side_by_side.operation("assemble_contacts")
def assemble_contacts(model: Model, contacts: Contacts, pattern: BlockPattern, vec: np.ndarray,
                      sca: np.ndarray, data: np.ndarray, rhs: np.ndarray, serial_scatter: bool) -> None:
    """Add springs of closed contacts and friction loads of sliding ones, in place (§2.8).
    ``data`` None (the NumPy path only): F's terms alone (`reassembly.ContactSystem`)."""
    if contacts.n == 0:
        return
    const, slope = friction_terms(model, contacts)
    if model.numpy_path:
        contact_terms_numpy(contacts.cint, contacts.state, contacts.line, model.vertex_block, model.block_dof,
                            vec, sca, const, slope, contacts.shear_dir, pattern, model.penalty,
                            model.shear_penalty, data, rhs)
        return
    from . import kernels as K

    K.assemble_contacts(contacts.cint, contacts.state, contacts.line, model.vertex_block, model.block_dof,
                        vec, sca, const, slope, contacts.shear_dir,
                        pattern.slot_ab, pattern.slot_ba, pattern.diag_slot, pattern.stride,
                        model.penalty, model.shear_penalty, data, rhs, serial_scatter)


@side_by_side.operation("second_order")
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
    if not np.count_nonzero(rotation):
        return shift
    xy, centroid, nxt, vb = state.vertex_xy, geom["centroid"], m.vertex_next, m.vertex_block

    def q(points, blocks):
        X = points - centroid[blocks]
        r = rotation[blocks]
        cos_1, sin_r = np.cos(r) - 1.0, np.sin(r) - r
        out = np.empty_like(X)
        out[:, 0] = cos_1 * X[:, 0] + sin_r * -X[:, 1]
        out[:, 1] = cos_1 * X[:, 1] + sin_r * X[:, 0]
        return out

    if contacts.n:
        # q of every vertex once (a vertex appears in several contacts), then ∂Δ/∂P·q and
        # ∂s/∂P·q per contact line
        if model.numpy_path:
            shift[:] = second_order_shift(model, xy, q(xy, vb), contacts.cint, contacts.omega)
        else:
            from . import kernels as K

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


# ------------------------------------------------------------------ NumPy twins of the kernels
# The small-model path (`Model.numpy_path`): the same terms, vectorised over blocks and
# contacts, with no kernel launch (a launch costs ~0.3–0.5 ms of Python-side argument passing,
# more than a small model's whole work). The Taichi kernels `assemble_blocks`,
# `assemble_points` and `assemble_contacts` document the terms; tests compare the paths.
_SIX = np.arange(6)
#: the left factor (k·u: 0, k·w: 1) of the blocks (i, i), (i, j), (j, j), (j, i) (`_Scatter.outer`)
_LEFT = np.array([0, 0, 1, 1])


def _diagonal_positions(diag_slot: np.ndarray, stride: np.ndarray, rows: np.ndarray) -> np.ndarray:
    """(n, 6, 6) positions in the CSR data of the diagonal 6×6 blocks of block-rows ``rows``."""
    return (diag_slot[rows].astype(np.int64)[:, None, None] + _SIX[None, :, None] *
            stride[rows].astype(np.int64)[:, None, None] + _SIX[None, None, :])


def block_terms_numpy(dof, density, elastic, area, mass, velocity, accel, stress, body_x, body_y, dt,
                      carry, beta, diag_slot, stride, data, rhs) -> None:
    """`kernels.assemble_blocks` in NumPy: inertia with Newmark's carry-over, elasticity,
    initial stress and body force of every free block, in place."""
    free = np.flatnonzero(dof >= 0)
    r = dof[free].astype(np.int64)
    rho, s = density[free], area[free]
    k = (rho / (beta * dt * dt))[:, None, None] * mass[free]
    k[:, 3:, 3:] += s[:, None, None] * elastic[free]
    data[_diagonal_positions(diag_slot, stride, r)] += k  # one diagonal block per free block
    carried = (rho / (beta * dt) * carry)[:, None] * velocity[free] + (rho * (0.5 / beta - 1.0))[:, None] * accel[free]
    f = np.einsum("nac,nc->na", mass[free], carried)
    f[:, 3:] -= s[:, None] * stress[free]
    f[:, 0] += rho * s * body_x
    f[:, 1] += rho * s * body_y
    rhs[(6 * r)[:, None] + _SIX] += f


def point_terms_numpy(point_block, point_xy, point_force, stiffness, dof, centroid, diag_slot, stride,
                      data, rhs) -> None:
    """`kernels.assemble_points` in NumPy: K += k·TᵀT, F += Tᵀf of every point on a free block."""
    on = dof[point_block] >= 0
    if not np.count_nonzero(on):
        return
    b = point_block[on]
    r = dof[b].astype(np.int64)
    t = displacement_matrix(point_xy[on], centroid[b])              # (n, 2, 6)
    k = stiffness[on]
    if np.any(k != 0.0):
        np.add.at(data, _diagonal_positions(diag_slot, stride, r), k[:, None, None] * np.einsum("nia,nib->nab", t, t))
    np.add.at(rhs, (6 * r)[:, None] + _SIX, np.einsum("nia,ni->na", t, point_force[on]))


class _Scatter:
    """The additions of a set of contacts to the CSR data and to the right-hand side, gathered
    as (positions, values) pieces and added with one ``np.add.at`` each: ``np.add.at`` adds its
    entries one after another in their order, so one call over the pieces in order gives the
    floats of one call per piece, without the fixed cost of a call per piece and block side."""

    def __init__(self, pattern: BlockPattern):
        self.pattern = pattern
        self.data_at, self.data_add, self.rhs_at, self.rhs_add = [], [], [], []

    def outer(self, rows_i, rows_j, slot_ij, slot_ji, k, u, w, u2, w2) -> None:
        """k·[u; w][u2; w2]ᵀ of each contact (u, u2 on block-row/column i, w, w2 on j): the
        diagonal blocks of free i and j, and the off-diagonal ones where both are free. The four
        6 × 6 blocks of every contact are formed at once (a few dozen NumPy calls are most of a
        small model's assembly) and taken in the order (i, i), (i, j), (j, j), (j, i), each over
        the contacts in order: the entries, and the floats, of one piece per block side."""
        diag_slot, stride = self.pattern.diag_slot, self.pattern.stride
        on_i, on_j = rows_i >= 0, rows_j >= 0
        both = on_i & on_j
        # the blocks that exist, (block side, contact) in the order of the sides, then contacts;
        # only those are formed (a contact with a fixed block has one of four)
        side, c = np.array([on_i, both, on_j, both]).nonzero()
        left = k[:, None] * np.array([u, w])                              # (2, n, 6): k·u, k·w
        right = np.array([u2, w2, w2, u2])
        values = left[_LEFT[side], c][:, :, None] * right[side, c][:, None, :]  # (kept, 6, 6)
        base = np.array([diag_slot[rows_i], slot_ij, diag_slot[rows_j], slot_ji], np.int64)[side, c]
        rows_stride = stride[np.array([rows_i, rows_i, rows_j, rows_j])[side, c]].astype(np.int64)
        at = base[:, None, None] + rows_stride[:, None, None] * _SIX[:, None] + _SIX
        self.data_at.append(at.ravel())
        self.data_add.append(values.ravel())

    def force(self, rows_i, rows_j, f_i, f_j) -> None:
        """Forces f_i on the rows of free blocks i, f_j on those of free blocks j."""
        rows = np.array([rows_i, rows_j])
        on = rows >= 0
        self.rhs_at.append(((6 * rows[on])[:, None] + _SIX).ravel())
        self.rhs_add.append(np.array([f_i, f_j])[on].ravel())

    def add_to(self, data: np.ndarray, rhs: np.ndarray) -> None:
        if self.data_at:
            np.add.at(data, np.concatenate(self.data_at), np.concatenate(self.data_add))
        if self.rhs_at:
            np.add.at(rhs, np.concatenate(self.rhs_at), np.concatenate(self.rhs_add))


def contact_terms_numpy(cint, state, line, vblock, dof, vec, sca, friction_const, friction_slope, shear_dir,
                        pattern: BlockPattern, penalty: float, shear_penalty: float, data, rhs) -> None:
    """`kernels.assemble_contacts` in NumPy: the normal spring of every closed contact (on its
    active line), the shear spring of a locked vertex-edge one, the friction of a sliding one
    (with its non-symmetric term when the friction is coupled to this solve's normal force).
    ``data`` None: F's terms alone, the same floats (its additions are F's own, apart from K's)."""
    closed = np.flatnonzero(state != OPEN)
    if not len(closed):
        return
    q = line[closed].astype(np.int64)
    kinds = cint[closed, KIND]
    i = vblock[cint[closed, 1 + 2 * q]]
    j = vblock[cint[closed, 2 + 2 * q]]
    ri, rj = dof[i].astype(np.int64), dof[j].astype(np.int64)
    sij = np.where(q == 1, pattern.slot_ba[closed], pattern.slot_ab[closed])
    sji = np.where(q == 1, pattern.slot_ab[closed], pattern.slot_ba[closed])
    u, w = vec[closed, S_E0 + 2 * q], vec[closed, S_G0 + 2 * q]   # the active line's gradients
    d0 = sca[closed, q]
    scatter = _Scatter(pattern)
    stiffness = data is not None
    if stiffness:
        scatter.outer(ri, rj, sij, sji, np.full(len(closed), penalty), u, w, u, w)
    scatter.force(ri, rj, (-penalty * d0)[:, None] * u, (-penalty * d0)[:, None] * w)
    ve = kinds == VE
    locked = ve & (state[closed] == LOCK)
    sliding = ve & (state[closed] == SLIDE)
    if np.count_nonzero(locked):
        c = closed[locked]
        es, gs = vec[c, S_ES], vec[c, S_GS]
        if stiffness:
            scatter.outer(ri[locked], rj[locked], sij[locked], sji[locked], np.full(len(c), shear_penalty),
                          es, gs, es, gs)
        f = (-shear_penalty * sca[c, 2])[:, None]
        scatter.force(ri[locked], rj[locked], f * es, f * gs)
    if np.count_nonzero(sliding):
        c = closed[sliding]
        sgn = shear_dir[c].astype(np.float64)
        # internal force sgn·S(D)·∇ds with S = a − b·(dn0 + ∇dnᵀD)
        f = (sgn * (friction_const[c] - friction_slope[c] * sca[c, 0]))[:, None]
        es, gs = vec[c, S_ES], vec[c, S_GS]
        scatter.force(ri[sliding], rj[sliding], -f * es, -f * gs)
        coupled = friction_slope[c] != 0.0
        if stiffness and np.count_nonzero(coupled):
            cc = c[coupled]
            sel = np.flatnonzero(sliding)[coupled]
            scatter.outer(ri[sel], rj[sel], sij[sel], sji[sel], -sgn[coupled] * friction_slope[cc],
                          vec[cc, S_ES], vec[cc, S_GS], vec[cc, S_E0], vec[cc, S_G0])
    scatter.add_to(data, rhs)
