"""Solves of K = K₀ + ΔK with the factor of K₀ in hand, where ΔK is of low rank (the
Sherman–Morrison–Woodbury identity): the equilibrium stage's iterates (`ddatai.return_mapping`),
whose K changes between two solves only where a contact opens or closes — its normal and shear
springs, a rank-1 term each, docs/method/dda.md §2.8 — while the frame's geometry stays.

ΔK is read from the two matrices themselves (the entries that differ, on the rows and columns
``S`` of the blocks whose contacts changed), its rank r from the eigenvalues of its dense ``|S| × |S|``
part (symmetric to round-off; its singular values otherwise), ΔK = U·Vᵀ; then with Z = K₀⁻¹U
(the r columns solved with the factor in one call, once for this K)

    K⁻¹ b = y − Z (I + Vᵀ Z)⁻¹ Vᵀ y,    y = K₀⁻¹ b,

one solve with the factor a right-hand side. Each solve is checked by its residual and refined
(``ddatai.iterative._refinement``) to the accuracy a Krylov solve is accepted at
(``ddatai.iterative.KRYLOV_ACCEPT``, what a direct solve reaches); where it does not get there
(a capacitance matrix too ill-conditioned, a rank above ``RANK_MAX``, a system below
``LOWRANK_UNKNOWNS``) the caller factorises, and so it does at once where the factor's own solve
left a residual above ``FACTOR_RESIDUAL_MAX`` (an update of it would not get there either).

Against GMRES preconditioned by the same factor (``ddatai.solver``, ``krylov``), which takes
about one iteration (one solve) per rank as well: the later solves of the same K (the stage's
slips change only F, 1–3 solves a K) cost one solve each here, and (rank + 1) again by GMRES
(benchmarks/results/stage_solves.md).
"""

from __future__ import annotations

from typing import Optional

import numpy as np

from .iterative import KRYLOV_ACCEPT, _refinement

#: the largest rank of ΔK solved by updates: the set-up solves the r columns of U with the factor
#: in one call (PARDISO at 1,600 blocks: 1.7 ms for one, 5.5 ms for 8, 8.6 ms for 16; a Cholesky
#: factorisation with its solve 20.7 ms); 6, 12, 24 and 40 measured on the grid's stage, 12 best
#: (benchmarks/results/stage_solves.md)
RANK_MAX = 12
#: ΔK is looked at only while it touches at most this many rows (25 blocks; its dense part's
#: eigendecomposition grows with their cube)
ROWS_MAX = 150
#: systems of fewer unknowns are factorised as before: their factorisations cost too little for the
#: updates' own NumPy work (~1 ms a solve) to pay — paired, the 391-block slope's stage (2,346
#: unknowns) took 1.03–1.14 × main's CPU with them, ntdda's 400-block grid the same, the 1,537-block
#: slope 0.97–1.03 ×, the 1,600- and 6,400-block grids 0.90–0.96 and 0.86 × (benchmarks/results/stage_solves.md)
LOWRANK_UNKNOWNS = 6000
#: eigen- or singular values of ΔK below this fraction of the largest entry of K₀ are its round-off
ROUND_OFF = 1e-13
#: corrections with the updated solve where its first residual is above ``KRYLOV_ACCEPT``
REFINE_PASSES = 2
#: updates are tried only from a factor whose own solve (the factorisation's) left a relative
#: residual of at most this (100 × ``KRYLOV_ACCEPT``): where K is so ill-conditioned that the direct
#: solve itself stays far above the bar, its updates cannot reach it in ``REFINE_PASSES`` either
#: and are set up, refined and thrown away before the factorisation. On ``benchmarks/scaling.py``'s
#: 1,537-block slope family (1,474 free blocks, welded: a direct solve's residual 8e-10 at the
#: median) 273 of the stage's 575 asks ended in a factorisation after that work (210 missed the
#: bar, 63 had a rank above ``RANK_MAX``), 243 of them from such factors, 2.0 s of the stage's
#: 18 s; with this check 44 do, and the stage took 0.91–0.95 × its CPU. On ntdda's grids no factor
#: is above it (the largest 3e-11 at 1,600 blocks): their path is the same to the bit. A function
#: of the computed numbers only: the same model takes the same path on every run
#: (benchmarks/results/stage_solves.md)
FACTOR_RESIDUAL_MAX = 1e-10


class LowRankSolve:
    """K⁻¹ for one K = K₀ + U·Vᵀ (module docstring), from ``solve0`` (K₀'s factor)."""

    def __init__(self, changed: np.ndarray, values: np.ndarray, k, solve0, u: np.ndarray, v: np.ndarray,
                 many: bool = False):
        # K is K₀ but at the CSR entries ``changed``, where it holds ``values``: a later K is matched by them
        self.changed, self.values = changed, values
        self.k = k          # K as CSR, for the residual
        self.solve0 = solve0
        if many and u.shape[1] > 1:  # one call for the r columns (PARDISO: 8 in 3.3 solves' time)
            self.z = solve0(np.ascontiguousarray(u.T)).T
        else:
            self.z = np.column_stack([solve0(np.ascontiguousarray(c)) for c in u.T]) if u.shape[1] else u
        self.v = v
        self.capacitance = np.eye(u.shape[1]) + v.T @ self.z
        self.rank = u.shape[1]

    @staticmethod
    def build(data: np.ndarray, data0: np.ndarray, changed: np.ndarray, indices: np.ndarray, indptr: np.ndarray,
              solve0, row_of: np.ndarray, scale: float, many: bool = False) -> "Optional[LowRankSolve]":
        """The update of K₀ (CSR data ``data0``, factor ``solve0``) to K (``data``, the same
        structure, differing at the entries ``changed``; ``row_of``: each entry's row; ``scale``: the
        largest entry of K₀), or None where ΔK's rank is above `RANK_MAX`."""
        from scipy.sparse import csr_matrix

        n = len(indptr) - 1
        if len(changed) > ROWS_MAX * ROWS_MAX:
            return None
        rows, cols = row_of[changed], indices[changed]
        support = np.union1d(rows, cols)
        if len(support) > ROWS_MAX:
            return None
        delta = np.zeros((len(support), len(support)))
        delta[np.searchsorted(support, rows), np.searchsorted(support, cols)] = data[changed] - data0[changed]
        if np.abs(delta - delta.T).max(initial=0.0) <= ROUND_OFF * scale:
            # the springs' terms, symmetric to round-off (which the residual check sees): ΔK = Q Λ Qᵀ
            sigma, left = np.linalg.eigh(0.5 * (delta + delta.T))
            right = left.T
        else:
            left, sigma, right = np.linalg.svd(delta)
        keep = np.abs(sigma) > ROUND_OFF * scale
        rank = int(np.count_nonzero(keep))
        if rank > RANK_MAX:
            return None
        u = np.zeros((n, rank))
        v = np.zeros((n, rank))
        u[support] = left[:, keep] * sigma[keep]
        v[support] = right[keep].T
        k = csr_matrix((np.array(data, dtype=np.float64), indices, indptr), shape=(n, n))
        return LowRankSolve(changed, k.data[changed], k, solve0, u, v, many)

    def apply(self, b: np.ndarray) -> np.ndarray:
        """K⁻¹ b by the identity (unchecked)."""
        y = self.solve0(np.ascontiguousarray(b))
        if not self.rank:
            return y
        return y - self.z @ np.linalg.solve(self.capacitance, self.v.T @ y)

    def solve(self, b: np.ndarray) -> "Optional[np.ndarray]":
        """x with K x = b to ``KRYLOV_ACCEPT`` (relative residual, max norm), refined where
        needed; None where it does not get there."""
        b = np.ascontiguousarray(b, dtype=np.float64)
        if not np.any(b):
            return np.zeros_like(b)
        x, _, done = _refinement(self.k, b, self.apply(b), self.apply, KRYLOV_ACCEPT, REFINE_PASSES)
        return x if done and np.all(np.isfinite(x)) else None


def solve_updated(solver, data, indices, indptr, rhs, n) -> "Optional[np.ndarray]":
    """`ddatai.solver.SparseSolver.solve` with ``lowrank``: K solved as an update of low rank of the
    matrix of the solver's Cholesky factor (the direct solve where it is that matrix); None where
    it is not one (fewer unknowns than `LOWRANK_UNKNOWNS`, another structure or factor type, a rank
    above `RANK_MAX`, no accurate solve)."""
    factor, factored = solver._factor, solver._factored_data
    if n < LOWRANK_UNKNOWNS or factor is None or not factor[0] or not solver._same(factor[1], indptr, indices) \
            or factored is None or len(factored) != len(data):
        return None
    # one pass over K: where it differs from the factor's matrix (`LowRankSolve` matches a later K by that)
    changed = np.flatnonzero(data != factored)
    if solver._exact and not len(changed):
        solver.reused += 1  # the matrix factorised: its direct solve (`SparseSolver._solve_reusing`)
        return factor[2](np.ascontiguousarray(rhs, dtype=np.float64))
    # ``solver._lowrank``: (the factor's matrix, its largest entry, the last K's update, whether the
    # factor's own solve reached `FACTOR_RESIDUAL_MAX`)
    last = solver._lowrank
    if last is None or last[0] is not factored:
        last = solver._lowrank = (factored, float(np.abs(factored).max(initial=0.0)), None,
                                  _reaches(solver._factored_solve, factored, indices, indptr, n))
    if not last[3]:
        return None  # the factor's own solve is far from the bar: factorise (`FACTOR_RESIDUAL_MAX`)
    update = last[2]
    if update is None or not np.array_equal(update.changed, changed) or \
            not np.array_equal(update.values, data[changed]):
        solver._lowrank = (factored, last[1], None, True)
        update = LowRankSolve.build(data, factored, changed, indices, indptr, factor[2],
                                    solver._rows(indptr, indices, n), last[1], many=solver.backend == "pardiso")
        if update is None:
            return None
        solver._lowrank = (factored, last[1], update, True)
    x = update.solve(rhs)
    solver.lowrank += x is not None
    return x


def factorised(solver, rhs, x, n, symmetric) -> np.ndarray:
    """Keep a copy of a factorisation's own solve (K₀ x = b) where its factor may be updated
    (`solve_updated`), for the check of `FACTOR_RESIDUAL_MAX` on the first update asked of it;
    returns x."""
    solver._factored_solve = (np.array(rhs, dtype=np.float64), np.array(x, dtype=np.float64)) \
        if symmetric and n >= LOWRANK_UNKNOWNS and solver.backend != "dense" else None
    return x


def _reaches(factored_solve, data0, indices, indptr, n) -> bool:
    """Whether the factorisation's own solve (b, x) has a relative residual (max norm) of at most
    `FACTOR_RESIDUAL_MAX` against K₀ (CSR data ``data0``); True where it was not kept."""
    if factored_solve is None:
        return True
    from scipy.sparse import csr_matrix

    b, x = factored_solve
    scale = float(np.abs(b).max(initial=0.0))
    if scale == 0.0:
        return True
    if not np.all(np.isfinite(x)):
        return False
    k = csr_matrix((data0, indices, indptr), shape=(n, n))
    return float(np.abs(b - k @ x).max()) <= FACTOR_RESIDUAL_MAX * scale
