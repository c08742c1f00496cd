"""Sparse symmetric positive definite solves of K D = F (one per open-close iteration).

Two backends behind one function:

- ``"scipy"``: SuperLU (`scipy.sparse.linalg.splu`) in symmetric mode with the MMD(AᵀA)
  ordering and no pivoting — always available (measured: 1.7–3.4× faster than the default
  `spsolve` on DDA matrices, ``../shared/reference/performance.md`` §1.2);
- ``"pardiso"``: Intel MKL PARDISO through the optional ``pypardiso`` package, SPD mode on the
  upper triangle, phases called directly (about 5× faster than SuperLU at 1,600 blocks on the
  development machine). Install with ``pip install pypardiso`` (x86-64 only, ~700 MB of MKL).

``Params(solver="auto")`` uses PARDISO when it can be imported and SuperLU otherwise. Both are
direct solvers and give the same solution to round-off (the tests compare them).
"""

from __future__ import annotations

import numpy as np


def available(name: str) -> bool:
    """Whether a backend can be used here."""
    if name == "scipy":
        return True
    if name == "pardiso":
        try:
            import pypardiso  # noqa: F401
        except Exception:  # noqa: BLE001 - any import failure means "not available"
            return False
        return True
    raise ValueError(f"unknown solver {name!r}")


def resolve(name: str) -> str:
    """The backend a ``Params.solver`` value selects."""
    if name == "auto":
        return "pardiso" if available("pardiso") else "scipy"
    if not available(name):
        raise ValueError(f"Params.solver = {name!r} is not available here (pip install pypardiso)")
    return name


class SparseSolver:
    """Solves K x = b for symmetric positive definite K given by its CSR arrays (full storage).

    ``pattern`` identifies the sparsity pattern: while it stays the same object (a step's
    `BlockPattern`), or a new one with the same ``indptr``/``indices`` (the next step, when no
    block pair gained or lost a contact), PARDISO keeps its symbolic analysis (fill-reducing
    ordering, ~55 % of a factorisation at 1,600 blocks) and only refactorises; SuperLU cannot
    reuse one and orders every time.
    """

    def __init__(self, backend: str):
        self.backend = resolve(backend)
        self._pardiso = None
        self._pattern = None     # the pattern PARDISO's analysis belongs to
        self._structure = None   # its (indptr, indices), to recognise it in a later step
        self._upper = None       # (positions of the upper-triangle entries, indptr, indices) of it

    def solve(self, data: np.ndarray, indices: np.ndarray, indptr: np.ndarray, rhs: np.ndarray,
              pattern: object = None) -> np.ndarray:
        n = len(indptr) - 1
        if self.backend == "pardiso":
            return self._solve_pardiso(data, indices, indptr, rhs, n, pattern)
        from scipy.sparse import csc_matrix
        from scipy.sparse.linalg import splu

        # K is symmetric, so its CSR arrays are also its CSC arrays
        k = csc_matrix((data, indices, indptr), shape=(n, n))
        try:
            lu = splu(k, permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                      options=dict(SymmetricMode=True))
            return lu.solve(rhs)
        except RuntimeError:  # singular factor: reported as a non-finite solution
            return np.full(n, np.nan)

    def _solve_pardiso(self, data, indices, indptr, rhs, n, pattern) -> np.ndarray:
        import pypardiso
        from scipy.sparse import csr_matrix

        if self._pardiso is None:
            # one solver object for the whole run: constructing one costs ~0.1 s
            self._pardiso = pypardiso.PyPardisoSolver(mtype=2)  # real symmetric positive definite
            self._pardiso.set_iparm(8, 0)  # no iterative refinement: the direct solve is exact
        solver = self._pardiso
        fresh = pattern is None or pattern is not self._pattern
        if fresh and pattern is not None and self._structure is not None:
            old_indptr, old_indices = self._structure
            # the same arrays (a `BlockPattern` reused across steps) or equal ones
            if (old_indptr is indptr and old_indices is indices) or (
                    len(old_indptr) == len(indptr) and len(old_indices) == len(indices)
                    and np.array_equal(old_indptr, indptr) and np.array_equal(old_indices, indices)):
                self._pattern, fresh = pattern, False
        if fresh:
            # PARDISO reads the upper triangle: which CSR entries those are, once per pattern
            rows = np.repeat(np.arange(n), np.diff(indptr))
            mask = indices >= rows
            counts = np.bincount(rows[mask], minlength=n)
            upper_indptr = np.concatenate([[0], np.cumsum(counts)])
            # positions, not a boolean mask: a take is ~10x faster than boolean indexing
            self._upper = (np.flatnonzero(mask), upper_indptr, indices[mask])
            self._pattern = pattern
            # kept by reference: pattern arrays are never written after `BlockPattern.build`
            self._structure = (indptr, indices) if pattern is not None else None
        upper_pos, upper_indptr, upper_indices = self._upper
        upper = csr_matrix((data.take(upper_pos), upper_indices, upper_indptr), shape=(n, n))
        try:
            # 13: analysis + factorisation + solve; 23: factorisation + solve with the analysis
            solver.set_phase(13 if fresh else 23)
            x = solver._call_pardiso(upper, np.ascontiguousarray(rhs, dtype=np.float64))
        except Exception:  # noqa: BLE001 - a failed factorisation is a non-finite solution
            self._pattern = self._structure = None
            return np.full(n, np.nan)
        return np.asarray(x).reshape(n)
