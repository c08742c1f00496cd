"""Rigid-block limit equilibrium of the touching blocks (docs/method/dda.md §8.12): which free
blocks can their contacts not hold, by any contact forces within the joint law?

The equilibrium stage (`ddatai.start`) asks it where its return mapping stalls: the blocks that
limit equilibrium lets move are released, the rest is held. It is the static (lower-bound)
theorem of rigid-block limit analysis as a linear program (Livesley's): the blocks are rigid,
each touching contact carries at its vertex a normal force N ≥ −T·L (the tensile strength of a
bonded joint, else 0) and a shear force ``|S| ≤ N·tanφ + c·L`` (cohesion while bonded) — in 2D
Coulomb's law is linear —, and the forces on each free block balance λ times its weight and
point loads (x, y and the moment about its centroid):

    maximise λ ≤ 1   such that   A·f + λ·w = 0,   N + T·L ≥ 0,   N·tanφ + c·L ∓ S ≥ 0.

λ = 1: the contacts hold every block. λ < 1: the multipliers y of the equilibrium rows are the
virtual velocities of the collapse mechanism (the kinematic dual); the blocks that move in it
are released, and the program is solved again for the rest (a block that rested on them may go
next) until the rest is held. A frictional, cohesionless mass is homogeneous: λ is then 0 or 1.

The program is solved by a primal-dual interior-point method (Mehrotra's predictor-corrector,
``_interior_point``): the inequalities of a contact involve only its own N and S, so each Newton
step reduces to one sparse symmetric system A·H⁻¹·Aᵀ in the blocks' three rows, with the
sparsity of the blocks' adjacency (a 2,600-block slope: ~0.5 s a program, where a general LP
code takes a minute), and the interior solution's y is the union of the mechanisms of the
critical λ, not one vertex of them. A program of a few blocks (``DENSE_ROWS``) takes its Newton
steps with dense arrays: 14 ms instead of 90 for a two-block group that slides (Example I, II).

Where a model has bolts or a water table, whose forces this program does not carry, it answers
None and the stage keeps its open-close test (``ddatai.mechanisms.test_unbalanced``).
"""

from __future__ import annotations

from typing import Optional

import numpy as np

from .memo import GeometryMemo
from .memo import key as data_key
from .contacts import Contacts
from .layout import E0, V0

#: the contacts hold the blocks where the out-of-balance force left is at most this fraction of
#: a block's load, on the mean
HELD = 1e-5
#: a block moves in the collapse mechanism where its virtual velocity exceeds this fraction of
#: the largest one (the interior point's y is exact to ~1e-8 of it)
MOVING = 1e-3
#: at most this many programs (each releases one more layer of blocks)
MAX_PROGRAMS = 12
#: interior-point iterations of one program; its tolerances on the mean complementarity gap
#: and the scaled equilibrium residual, and on the dual residual (of unit costs). The Newton
#: systems lose accuracy as the gap falls below ~1e-9, the dual residual first (it stalls near
#: 1e-5 on a block at its limit): the identification of the moving blocks needs far less. Where
#: the gap and the equilibrium residual meet IPM_TOLERANCE and the dual residual does not, the
#: iteration ends at its best iterate: the steps beyond lose the dual residual to round-off and
#: diverge (docs/method/dda.md §8.12)
MAX_IPM_ITERATIONS = 80
IPM_TOLERANCE = 1e-8
DUAL_TOLERANCE = 1e-4
#: programs of at most this many equilibrium rows (a third as many blocks) take each Newton step
#: with dense arrays: the sparse products and factorisation cost ~2 ms of fixed overhead a step
#: where the dense ones, on a few blocks, cost microseconds
DENSE_ROWS = 300


def median(values: np.ndarray) -> float:
    """``np.median(values)`` to the bit — the middle value, or the two middle ones' (a + b) / 2,
    NaN of none —, without its ~20 µs of dispatch (a small model's stage asks it of two blocks)."""
    v = np.sort(values, axis=None)
    k = len(v) // 2
    if len(v) % 2:
        return float(v[k])
    return float((v[k - 1] + v[k]) / 2.0) if len(v) else float("nan")


def applicable(model) -> bool:
    """Whether the program carries every force of the stage: not with bolts or a water table."""
    return len(model.bolt_block) == 0 and model.water_xy is None and len(model.water_heads) == 0


def unsupported_blocks(model, vertex_xy: np.ndarray, geom: dict, contacts: Contacts,
                       touching: np.ndarray, out: np.ndarray, solve=None) -> Optional[np.ndarray]:
    """(B,) the free blocks (not ``out``) that the ``touching`` contacts cannot hold under the
    model's weight and point loads at t = 0 by rigid-block limit equilibrium (module docstring);
    None where the program does not apply (`applicable`) or does not converge. ``solve``: the
    programs' solver, ``solve(a, b, tan_phi, cohesion, tensile) -> (unbalance, y) or None``
    (default `_interior_point`; `ddatai.limit_batch` passes one that collects the programs)."""
    return answered(unsupported_programs(model, vertex_xy, geom, contacts, touching, out), solve or _interior_point)


def answered(programs, solve, program=None):
    """The value that the generator ``programs`` returns when each program it yields is answered
    by ``solve(*program)`` (`unsupported_programs`); ``program``: the one at which it already
    stands (`ddatai.limit_batch.screened_ahead` took its first program to solve it ahead)."""
    try:
        if program is None:
            program = next(programs)
        while True:
            program = programs.send(solve(*program))
    except StopIteration as end:
        return end.value


def unsupported_programs(model, vertex_xy: np.ndarray, geom: dict, contacts: Contacts,
                         touching: np.ndarray, out: np.ndarray):
    """`unsupported_blocks` as a generator: it yields each program ``(a, b, tan_phi, cohesion,
    tensile)`` and is sent its answer, and returns the blocks (or None): a member's screen
    can stop at its first program, whose answer is solved side by side with the other
    members', and go on from there (`ddatai.limit_batch.screened_ahead`)."""
    if not applicable(model):
        return None
    centroid = geom["centroid"]
    size = np.sqrt(geom["area"])
    g = np.asarray(model.gravity, float)
    weight = model.block_density * geom["area"] * float(np.hypot(*g))
    # the load of each block: weight and point loads at t = 0 (force, moment about the centroid)
    load = np.zeros((model.n_blocks, 3))
    load[:, :2] = (model.block_density * geom["area"])[:, None] * g
    if len(model.load_block):
        from .assembly import load_forces

        f = load_forces(model, 0.0)
        arm = model.load_xy0 - centroid[model.load_block]
        np.add.at(load, (model.load_block, 0), f[:, 0])
        np.add.at(load, (model.load_block, 1), f[:, 1])
        np.add.at(load, (model.load_block, 2), arm[:, 0] * f[:, 1] - arm[:, 1] * f[:, 0])
        np.maximum.at(weight, model.load_block, np.hypot(f[:, 0], f[:, 1]))
    unloaded = ~np.any(load != 0.0, axis=1)
    anchored = np.zeros(model.n_blocks, bool)
    anchored[model.fixed_point_block] = True  # a fixed point holds its block
    # each contact on its active line: the vertex of block a against the edge of block b, the
    # force on a being N·n + S·t (n the edge's outward normal), its reaction on b
    line = contacts.line.astype(np.int64)
    rows = np.arange(contacts.n)
    vertex = contacts.cint[rows, V0 + 2 * line]
    edge = contacts.cint[rows, E0 + 2 * line]
    block_a, block_b = model.vertex_block[vertex], model.vertex_block[edge]
    tangent = vertex_xy[model.vertex_next[edge]] - vertex_xy[edge]
    tangent /= np.hypot(tangent[:, 0], tangent[:, 1])[:, None]
    normal = np.stack([tangent[:, 1], -tangent[:, 0]], axis=1)
    point = vertex_xy[vertex]
    cohesion = np.where(contacts.bond, contacts.cohesion * contacts.length, 0.0)
    tensile = np.where(contacts.bond, contacts.tensile * contacts.length, 0.0)

    released = np.zeros(model.n_blocks, bool)
    for _ in range(MAX_PROGRAMS):
        gone = out | released
        tested = ~model.block_fixed & ~gone & ~anchored & ~unloaded
        sel = np.flatnonzero(touching & ~gone[block_a] & ~gone[block_b])
        # a loaded block that touches nothing is a mechanism without a program
        touched = np.zeros(model.n_blocks, bool)
        touched[block_a[sel]] = touched[block_b[sel]] = True
        if np.any(tested & ~touched):
            released |= tested & ~touched
            continue
        n_blocks = int(np.count_nonzero(tested))
        if n_blocks == 0:
            break
        row_of = np.full(model.n_blocks, -1)
        row_of[tested] = np.arange(n_blocks)
        # in units of the blocks' loads: each block's rows by its weight (its moment row by
        # weight × size), the contact forces by the median weight: coefficients of order one
        scale = np.empty((n_blocks, 3))
        scale[:, 0] = scale[:, 1] = weight[tested]
        scale[:, 2] = weight[tested] * size[tested]
        scale = scale.ravel()
        unit = median(weight[tested])
        equilibrium = _kept_matrix(sel, block_a, block_b, point, normal, tangent, centroid, row_of,
                                   3 * n_blocks, unit / scale)
        outcome = yield (equilibrium, load[tested].ravel() / scale, contacts.tan_phi[sel],
                         cohesion[sel] / unit, tensile[sel] / unit)
        if outcome is None:
            return None
        unbalance, y = outcome
        if unbalance <= HELD * n_blocks:
            break
        velocity = (y * unit / scale).reshape(-1, 3)
        speed = np.abs(velocity[:, 0]) + np.abs(velocity[:, 1]) + np.abs(velocity[:, 2]) * size[tested]
        moving = np.zeros(model.n_blocks, bool)
        moving[np.flatnonzero(tested)] = speed > MOVING * float(speed.max(initial=0.0))
        if not moving.any():
            return None
        released |= moving
    return released


#: equilibrium matrices built lately, by the bytes of their data: the members of a batch (a
#: study's samples, a bisection's probes) are one geometry, and their screens' first programs
#: the same matrix (`_kept_matrix`)
_MATRICES = GeometryMemo(8)


def _kept_matrix(*args):
    """`_equilibrium_matrix`, or a copy of the one built lately from the same data (the same
    bytes in: the same matrix out)."""
    return _MATRICES.get(data_key(*args), lambda: _equilibrium_matrix(*args))


def _equilibrium_matrix(sel, block_a, block_b, point, normal, tangent, centroid, row_of, n_rows, row_scale):
    """A (n_rows × 2m, CSR): the force and moment that each contact's N (columns 0..m−1) and S
    (m..2m−1) put on the tested blocks, each block's rows scaled by ``row_scale``."""
    from scipy.sparse import csr_matrix

    m = len(sel)
    r_idx, c_idx, vals = [], [], []
    for blocks, sign in ((block_a[sel], 1.0), (block_b[sel], -1.0)):
        r = row_of[blocks]
        on = r >= 0
        k = np.flatnonzero(on)
        arm = point[sel][on] - centroid[blocks[on]]
        for direction, offset in ((normal[sel][on], 0), (tangent[sel][on], m)):
            moment = arm[:, 0] * direction[:, 1] - arm[:, 1] * direction[:, 0]
            for comp, value in ((0, direction[:, 0]), (1, direction[:, 1]), (2, moment)):
                rr = 3 * r[on] + comp
                r_idx.append(rr)
                c_idx.append(k + offset)
                vals.append(sign * value * row_scale[rr])
    return csr_matrix((np.concatenate(vals), (np.concatenate(r_idx), np.concatenate(c_idx))), shape=(n_rows, 2 * m))


#: programs solved lately, by their data: the stage asks the same program twice where its
#: screen at t = 0 (`ddatai.mechanisms.unsupported_at_start`) and a stalled return mapping's first test
#: see the same touching contacts (every contact detected at t = 0 touching)
_SOLVED: dict = {}
_SOLVED_KEPT = 8
#: answers to programs solved side by side ahead of the stages that ask them
#: (`ddatai.limit_batch.screened_ahead`), by their data, kept while those stages run
PRIMED: dict = {}


def program_key(a, b, tan_phi, cohesion, tensile) -> tuple:
    """A program's data as a key (its bytes)."""
    return tuple((v.dtype.str, v.shape, v.tobytes()) for v in
                 (np.asarray(x) for x in (a.data, a.indices, a.indptr, a.shape, b, tan_phi, cohesion, tensile)))


def _interior_point(a, b, tan_phi, cohesion, tensile):
    """`_solve_program`, or its answer to the same program asked lately or solved ahead (the
    same bytes)."""
    key = program_key(a, b, tan_phi, cohesion, tensile)
    if key in PRIMED:
        out = PRIMED[key]
        return None if out is None else (out[0], out[1].copy())
    if key in _SOLVED:
        out = _SOLVED[key]
        return None if out is None else (out[0], out[1].copy())
    out = _solve_program(a, b, tan_phi, cohesion, tensile)
    if len(_SOLVED) >= _SOLVED_KEPT:
        _SOLVED.pop(next(iter(_SOLVED)))
    _SOLVED[key] = None if out is None else (out[0], out[1].copy())
    return out


def _solve_program(a, b, tan_phi, cohesion, tensile):
    """min Σ(r⁺ + r⁻) such that a·[N; S] + r⁺ − r⁻ = −b, N + tensile ≥ 0, N·tanφ + cohesion ∓ S
    ≥ 0, r± ≥ 0 (module docstring), by Mehrotra's predictor-corrector. The inequalities are
    C·x + d ≥ 0 with x = (N, S, r⁺, r⁻): three rows per contact on its own (N, S) and the bounds
    of r±, so H = Cᵀ·(z/s)·C is 2×2-block diagonal and each Newton step solves
    (a·H⁻¹·aᵀ + diag(s/z of r⁺ and r⁻))·dy = r, positive definite whatever the contacts (the
    out-of-balance forces keep it so where a mechanism leaves a·H⁻¹·aᵀ singular). Returns
    (Σ(r⁺ + r⁻), y), or None if it does not converge."""
    # the last iterates may overflow where round-off takes over: they are judged finite or not
    with np.errstate(all="ignore"):
        return _mehrotra(a, b, tan_phi, cohesion, tensile)


def _mehrotra(a, b, tan_phi, cohesion, tensile):
    """``_interior_point``'s iteration."""
    from scipy.sparse import diags

    from .solver import SparseSolver

    m, n = len(tan_phi), a.shape[0]
    dense = n <= DENSE_ROWS
    solver = None if dense else SparseSolver("auto")
    if dense:
        a = a.toarray()
        at = a.T
        a_n, a_s = a[:, :m], a[:, m:]
    else:
        at = a.T.tocsr()
    mu_ = tan_phi
    d = np.concatenate([tensile, cohesion, cohesion, np.zeros(2 * n)])

    def c_times(nn, ss, rp, rm):
        return np.concatenate([nn, mu_ * nn - ss, mu_ * nn + ss, rp, rm])

    def ct_times(v):  # Cᵀ·v -> (N, S, r⁺, r⁻ parts)
        v2, v3 = v[m:2 * m], v[2 * m:3 * m]
        return v[:m] + mu_ * (v2 + v3), v3 - v2, v[3 * m:3 * m + n], v[3 * m + n:]

    nn, ss = np.zeros(m), np.zeros(m)
    rp, rm = np.maximum(-b, 0.0) + 1.0, np.maximum(b, 0.0) + 1.0
    s = np.maximum(c_times(nn, ss, rp, rm) + d, 1.0)
    z = np.ones_like(s)
    y = np.zeros(n)
    size = 1.0 + float(np.abs(b).max(initial=0.0))
    best = None  # the iterate of smallest gap among those close to feasible
    for _ in range(MAX_IPM_ITERATIONS):
        aty = at @ y
        ctz = ct_times(z)
        rd = (-aty[:m] - ctz[0], -aty[m:] - ctz[1], 1.0 - y - ctz[2], 1.0 + y - ctz[3])
        re = a @ np.concatenate([nn, ss]) + rp - rm + b
        ri = c_times(nn, ss, rp, rm) + d - s
        gap = float(s @ z) / len(s)
        primal = max(np.abs(re).max(initial=0.0), np.abs(ri).max(initial=0.0)) / size
        dual = max(np.abs(r).max(initial=0.0) for r in rd)
        if not np.isfinite(gap + primal + dual):
            break
        if primal < 100.0 * IPM_TOLERANCE and dual < 10.0 * DUAL_TOLERANCE and (best is None or gap < best[0]):
            best = (gap, float(rp.sum() + rm.sum()), y.copy())
        if primal < IPM_TOLERANCE and gap < IPM_TOLERANCE:
            if dual < DUAL_TOLERANCE:
                return float(rp.sum() + rm.sum()), y
            break  # the dual residual lost to round-off: the steps from here diverge
        q = z / s
        q1, q2, q3, q4, q5 = q[:m], q[m:2 * m], q[2 * m:3 * m], q[3 * m:3 * m + n], q[3 * m + n:]
        # H per contact [[q1 + μ²(q2 + q3), μ(q3 − q2)], [μ(q3 − q2), q2 + q3]], inverted
        h11, h12, h22 = q1 + mu_ * mu_ * (q2 + q3), mu_ * (q3 - q2), q2 + q3
        det = np.maximum(q1 * h22 + 4.0 * mu_ * mu_ * q2 * q3, 1e-300)  # h11·h22 − h12², without cancellation
        i11, i12, i22 = h22 / det, -h12 / det, h11 / det
        if dense:
            # a·H⁻¹·aᵀ = a_N·diag(i11)·a_Nᵀ + X + Xᵀ + a_S·diag(i22)·a_Sᵀ, X = a_N·diag(i12)·a_Sᵀ
            cross = (a_n * i12) @ a_s.T
            newton_matrix = (a_n * i11) @ a_n.T + cross + cross.T + (a_s * i22) @ a_s.T
            newton_matrix[np.diag_indices(n)] += 1.0 / q4 + 1.0 / q5
            try:
                lu = _DenseFactor(newton_matrix)
            except np.linalg.LinAlgError:  # round-off ended the iteration
                break
        else:
            lu = _SparseFactor(solver, (a @ _block_inverse(i11, i12, i22) @ at + diags(1.0 / q4 + 1.0 / q5)).tocsr())
            if not lu.finite:  # round-off ended the iteration
                break

        def newton(rc):
            # q_x = −r_d + Cᵀ·S⁻¹·(r_c − Z·r_i); M·dy = −r_e − E·H⁻¹·q_x; dx = H⁻¹·(q_x + Eᵀ·dy)
            t = ct_times((rc - z * ri) / s)
            qn, qs, qp, qm = (-r + u for r, u in zip(rd, t))
            hn, hs = i11 * qn + i12 * qs, i12 * qn + i22 * qs
            dy = lu.solve(-re - (a @ np.concatenate([hn, hs]) + qp / q4 - qm / q5))
            atdy = at @ dy
            pn, ps = qn + atdy[:m], qs + atdy[m:]
            dn, dsh = i11 * pn + i12 * ps, i12 * pn + i22 * ps
            dp, dm = (qp + dy) / q4, (qm - dy) / q5
            dslack = c_times(dn, dsh, dp, dm) + ri
            return dn, dsh, dp, dm, dy, dslack, (rc - z * dslack) / s

        aff = newton(-s * z)
        a_p, a_d = _step(s, aff[5]), _step(z, aff[6])
        gap_aff = float((s + a_p * aff[5]) @ (z + a_d * aff[6])) / len(s)
        sigma = (gap_aff / max(gap, 1e-300)) ** 3
        dn, dsh, dp, dm, dy, dslack, dz = newton(sigma * gap - s * z - aff[5] * aff[6])
        a_p, a_d = 0.99 * _step(s, dslack), 0.99 * _step(z, dz)
        nn, ss, rp, rm, s = nn + a_p * dn, ss + a_p * dsh, rp + a_p * dp, rm + a_p * dm, s + a_p * dslack
        y, z = y + a_d * dy, z + a_d * dz
    # round-off ended it short of the tolerances: its best iterate, if close enough
    return (best[1], best[2]) if best is not None and best[0] < 1e3 * IPM_TOLERANCE else None


class _SparseFactor:
    """The factor of a large positive definite Newton matrix (CSR) by the project's sparse
    solver (`ddatai.solver.SparseSolver`: PARDISO's Cholesky where installed, its symbolic
    analysis kept from one Newton step to the next, as the pattern stays; SuperLU otherwise),
    solving as ``splu``'s: SuperLU's default ordering took 0.26 s a step on the 6,400-block
    grid's program."""

    def __init__(self, solver, matrix):
        matrix.sort_indices()
        self.solver = solver
        x = solver.solve(matrix.data, matrix.indices, matrix.indptr, np.zeros(matrix.shape[0]), symmetric=True)
        self.finite = bool(np.all(np.isfinite(x)))

    def solve(self, rhs: np.ndarray) -> np.ndarray:
        return self.solver.factor_solve(rhs)


class _DenseFactor:
    """The Cholesky factor of a small positive definite Newton matrix, solving as ``splu``'s
    (LAPACK called directly, `ddatai.dense`: tens of Newton steps a program)."""

    def __init__(self, matrix: np.ndarray):
        from .dense import Cholesky
        from .threads import one_blas_thread

        with one_blas_thread():  # a few hundred rows: no gain from threads (`ddatai.threads`)
            self.factor = Cholesky(matrix)

    def solve(self, rhs: np.ndarray) -> np.ndarray:
        return self.factor.solve(rhs)


def _block_inverse(i11, i12, i22):
    """The 2m × 2m matrix [[diag(i11), diag(i12)], [diag(i12), diag(i22)]] (CSR)."""
    from scipy.sparse import bmat, diags

    return bmat([[diags(i11), diags(i12)], [diags(i12), diags(i22)]], format="csr")


def _step(v, dv) -> float:
    """The largest α ≤ 1 with v + α·dv ≥ 0."""
    neg = dv < 0
    return float(min(1.0, np.min(-v[neg] / dv[neg], initial=np.inf)))
