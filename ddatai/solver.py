"""Sparse direct solves of K D = F (one per open-close iteration).

K is symmetric positive definite while every closed contact is locked or carries a friction
load that does not depend on the solution. A sliding contact whose friction is taken
implicitly (the friction force μ·p·(−dn) follows the normal penetration of the same solve,
``ddatai.contact_law``) adds a non-symmetric term, and the solve then uses an LU factorisation
(PARDISO's on the symmetric pattern, with the general LU where its diagonal pivots fail:
``ddatai.pardiso._Pardiso``).

Two backends behind one class:

- ``"scipy"``: SuperLU (`scipy.sparse.linalg.splu`) with the MMD(AᵀA) ordering and diagonal
  pivots — always available (1.7–3.4× faster than the default `spsolve` on DDA matrices);
- ``"pardiso"``: Intel MKL PARDISO through the optional ``pypardiso`` package (about 5× faster
  than SuperLU at 1,600 blocks). Install with ``pip install pypardiso`` (x86-64 only, ~700 MB
  of MKL). ddatai calls MKL itself with its own parameters (``iparm[0] = 1``, so that MKL
  honours them): no iterative refinement, zero-based indices (no copies), the ordering kept
  while the pattern stays, a residual check that refines only where a pivot was perturbed,
  and MKL's conditional numerical reproducibility (the same factor bit for bit on every run
  with the same number of threads).

``Params(solver="auto")`` uses PARDISO when it can be imported and SuperLU otherwise. Both are
direct solvers and give the same solution to round-off (the tests compare them).

**Reusing the last factor.** A step's first solve has the contact states the last step ended
with, and while no block pair gains or loses a contact its K differs from the last one
factorised only through the blocks' small motion (relative changes of 1e-15 in a settled grid,
1e-6 in a stiff ringing one). Such a solve (``reuse=True``) is done by iterative refinement
with the factor in hand — x ← x + K_old⁻¹(b − K x) — while the residual falls at least 20-fold
per pass, to a relative residual of `REUSE_RESIDUAL` or its round-off floor below `REUSE_FLOOR`;
if it falls slower (the states changed, the blocks moved far) the matrix is factorised as
usual (the stepper does not ask when Δt changed). One or a few triangular solves and products
with K cost 1.5–6 ms at 1,600 blocks, a factorisation 11–21 ms (docs/method/dda.md §9).
Where K is the very matrix factorised (the equilibrium stage's iterates whose contact states
did not change: only F moved) and its factorisation perturbed no pivot, the solve with the
factor is the direct solve itself, as accurate as the factorisation's own, and is not refined
(refinement to round-off took 3.4 solves at 1,600 blocks).

**Krylov solves with the last factor** (``krylov``) and **updates of low rank** (``lowrank``): `ddatai.iterative`,
`ddatai.lowrank`.

**One factor at a time.** PARDISO keeps one handle per matrix type (Cholesky and LU), each with
its analysis; a factorisation of one type frees the other's factor (MKL's phase 0, the analysis
kept), which no solve uses again before it is factorised anew, and the last factor with the
matrix its solves hold goes before a new one is made. At 102,400 blocks the two factors were
2.0 and 4.0 GB held at once, and the step's peak memory fell from 9.1–9.2 to 7.4–7.6 GB with the same
solutions to the bit (``benchmarks/memory_phases.py``, docs/guide/performance.md).
"""

from __future__ import annotations

from contextlib import nullcontext
from typing import Optional

import numpy as np


def available(name: str) -> bool:
    """Whether a backend can be used here."""
    if name in ("scipy", "dense"):
        return True
    if name == "cholmod":
        from .updates import available as cholmod_available

        return cholmod_available()
    if name == "pardiso":
        _locate_mkl()
        try:
            import pypardiso  # noqa: F401
        except Exception:  # noqa: BLE001 - any import failure means "not available"
            return False
        return True
    raise ValueError(f"unknown solver {name!r}")


#: "auto" solves a system of at most this many unknowns (6 per free block) densely: LAPACK's
#: Cholesky of a dense 600 × 600 matrix takes ~2 ms, and below ~300 unknowns it beats any
#: sparse factorisation with its ordering and symbolic set-up (benchmarks/small_models.py)
DENSE_UNKNOWNS = 600

#: the dense backend factorises a system of at most this many unknowns (32 free blocks) where a
#: later solve of an open-close iteration would try GMRES with the last factor (``krylov``):
#: LAPACK's factorisation and solve of such a matrix cost less than GMRES's set-up and one
#: iteration (the equilibrium stage of a two-block group solves ~24 systems of 12 unknowns; paired
#: on this machine: 12 unknowns, a factorisation ~50 µs, GMRES ~300 µs more; 192: ~0.9 against
#: ~1.5 ms). Both reach a direct solve's accuracy, so their solutions differ at round-off only
DENSE_KRYLOV_UNKNOWNS = 192


def resolve(name: str, unknowns: Optional[int] = None) -> str:
    """The backend a ``Params.solver`` value selects (for a system of ``unknowns``, if known)."""
    if name == "auto":
        if unknowns is not None and unknowns <= DENSE_UNKNOWNS:
            return "dense"
        return "pardiso" if available("pardiso") else "scipy"
    if not available(name):
        raise ValueError(f"Params.solver = {name!r} is not available here (pip install pypardiso)")
    return name


from .pardiso import (PardisoError, _locate_mkl, _Pardiso, _upper_triangle,  # noqa: F401 (PardisoError: public)
                      symmetric_pattern)
from .threads import limited, one_blas_thread
from .iterative import (KRYLOV_ACCEPT, KRYLOV_BLOCKS, KRYLOV_ITERATIONS, REFINE_ABOVE, REFINE_PASSES,
                        REUSE_PASSES, REUSE_RATE, REUSE_RESIDUAL, _refinement, changed_blocks, gmres,
                        refine_to_roundoff)
from . import lowrank as _lowrank  # noqa: E402


class SparseSolver:
    """Solves K x = b for K given by its CSR arrays (full storage).

    ``symmetric=True`` (the default) promises a symmetric positive definite K; otherwise K is
    factorised by LU. ``pattern`` identifies the sparsity pattern: while it stays the same
    object (a step's `BlockPattern`), or a new one with the same ``indptr``/``indices`` (the
    next step, when no block pair gained or lost a contact), PARDISO keeps its symbolic
    analysis (fill-reducing ordering, ~55 % of a factorisation at 1,600 blocks) and only
    refactorises; SuperLU cannot reuse one and orders every time.
    """

    def __init__(self, backend: str, unknowns: Optional[int] = None):
        self.backend = resolve(backend, unknowns)
        self._dense_rows = None  # (structure key, row of each CSR entry) of the dense backend
        self._handles: dict[int, _Pardiso] = {}
        self._upper = None       # (structure key, positions of the upper triangle, indptr, indices)
        self._structure = None   # (structure key, whether it is symmetric) of the last non-symmetric K
        self.perturbed_fallbacks = 0  # LU of the symmetric pattern redone with matching (`_factorise`)
        self.last_residual = 0.0  # relative residual of the last PARDISO solve, when it was checked
        # the last factorisation: (symmetric, (indptr, indices), solve(r) with its factor); its matrix
        self._factor = self._factored_data = None
        # whether the factor in hand is the exact factor of ``_factored_data`` (a direct
        # factorisation without perturbed pivots): a solve with it then needs no refinement
        self._exact = False
        self.factorisations = 0  # numeric factorisations so far
        self.lu_factorisations = 0  # those of a non-symmetric K (LU)
        self.reused = 0          # solves done by refinement with an earlier factor (``reuse``)
        self.krylov = 0          # solves done by GMRES with an earlier factor (``krylov``)
        self.krylov_iterations = 0  # GMRES iterations of those
        self.updated = 0         # solves done by CHOLMOD rank updates of the last factor (``springs``)
        self.lowrank = 0         # solves done by the Woodbury identity with the factor (``lowrank``)
        self._lowrank = self._factored_solve = None  # its state and the factorisation's own (b, x): `ddatai.lowrank`
        # the CHOLMOD factor that follows the contact springs (`ddatai.updates`), where the
        # [cholmod] extra is installed and the system is solved sparse
        self._updating = None
        if self.backend != "dense" and available("cholmod"):
            from .updates import UpdatedFactor

            self._updating = UpdatedFactor()

    def __del__(self):
        for h in getattr(self, "_handles", {}).values():
            try:
                h.release()
            except Exception:  # noqa: BLE001 - interpreter shutdown
                pass

    @property
    def updates(self) -> bool:
        """Whether symmetric solves given their ``springs`` follow them by CHOLMOD's rank updates
        (`ddatai.updates`: the [cholmod] extra, a sparse backend)."""
        return self._updating is not None

    def solve(self, data: np.ndarray, indices: np.ndarray, indptr: np.ndarray, rhs: np.ndarray,
              pattern: object = None, symmetric: bool = True, reuse: bool = False,
              krylov: bool = False, springs=None, lowrank: bool = False) -> np.ndarray:
        """x with K x = ``rhs``. ``reuse``: K is expected to be close to the last matrix
        factorised (module docstring): try refinement with that factor first. ``krylov``: K
        differs from it by the terms of a few contacts: try GMRES preconditioned by it first.
        ``springs`` (`ddatai.updates.Springs`, a symmetric K): the contact springs in K; where
        CHOLMOD is installed, K is solved by rank updates of the last factor while its springs
        differ from that factor's by few terms, and factorised by CHOLMOD otherwise (so that
        the next solves can update it). ``lowrank``: K differs from the Cholesky factor's matrix
        by a term of low rank, solved by the factor and the Woodbury identity (`ddatai.lowrank`)."""
        n = len(indptr) - 1
        if springs is not None and symmetric and self._updating is not None:
            return self._solve_updating(data, indices, indptr, rhs, n, springs, reuse, pattern)
        if lowrank and symmetric and self.backend != "dense":
            x = _lowrank.solve_updated(self, data, indices, indptr, rhs, n)
            if x is not None:
                return x
        if self._updating is not None:
            self._updating.forget()  # another K: its factor no longer follows the springs
        if self.backend == "dense" and n <= DENSE_KRYLOV_UNKNOWNS:
            krylov = False  # a factorisation costs less than GMRES here (DENSE_KRYLOV_UNKNOWNS)
        if krylov:
            x = self._solve_krylov(data, indices, indptr, rhs, n)
            if x is not None:
                self.krylov += 1
                return x
        elif reuse:
            x = self._solve_reusing(data, indices, indptr, rhs, n, symmetric)
            if x is not None:
                self.reused += 1
                return x
        self.factorisations += 1
        self.lu_factorisations += not symmetric
        # the last factor and its matrix are replaced now: let them go before the new ones are
        # made (the solve with the old factor holds its matrix, 0.26 GB at 102,400 blocks)
        self._factor = self._factored_data = self._lowrank = self._factored_solve = None
        # the matrix of the factor, against which a Krylov solve measures its change; the factor exact
        # unless PARDISO perturbs a pivot (`_solve_pardiso`); its own solve kept (`ddatai.lowrank.factorised`)
        self._factored_data, self._exact = np.array(data, dtype=np.float64), True
        x = self._factorise(self._factored_data, indices, indptr, rhs, n, symmetric, pattern)
        return _lowrank.factorised(self, rhs, x, n, symmetric)

    def _solve_updating(self, data, indices, indptr, rhs, n, springs, reuse, pattern=None) -> np.ndarray:
        """The symmetric solve with springs (`solve`): by updates of the factor in hand, each
        checked by its residual against K and refined as a reused factor is (`_refinement`);
        a step's first solve (``reuse``, another step's vectors) by refinement with the last
        factor first; otherwise a CHOLMOD factorisation, or the backend's LU where K is not
        positive definite."""
        u = self._updating
        self._exact = False  # CHOLMOD's factors follow the springs by updates: always checked
        b = np.ascontiguousarray(rhs, dtype=np.float64)
        if u.factor is not None and self._same(self._factor[1] if self._factor else None, indptr, indices) \
                and u.update(springs, n):
            from scipy.sparse import csr_matrix

            k = csr_matrix((data, indices, indptr), shape=(n, n))
            x, residual, done = refine_to_roundoff(k, b, u.solve(b), u.solve)
            if done:
                self._factor = (True, (indptr, indices), u.factor.solve_A)
                self._factored_data = np.array(data, dtype=np.float64)
                self.updated += 1
                self.last_residual = residual
                return x
        elif reuse:
            x = self._solve_reusing(data, indices, indptr, rhs, n, True)
            if x is not None:
                self.reused += 1
                u.forget()  # the factor is of the last step's K, not of these springs
                return x
        self.factorisations += 1
        self._factored_data = np.array(data, dtype=np.float64)
        if u.factorise(data, indices, indptr, n, self._same, springs):
            self._factor = (True, (indptr, indices), u.factor.solve_A)
            return u.solve(b)
        self.lu_factorisations += 1  # not positive definite: LU
        return self._factorise(self._factored_data, indices, indptr, rhs, n, False, pattern)

    def factor_solve(self, rhs: np.ndarray) -> "np.ndarray | None":
        """K⁻¹·rhs with the last factor (the matrix last factorised); None without one."""
        if self._factor is None:
            return None
        return self._factor[2](np.ascontiguousarray(rhs, dtype=np.float64))

    def _factorise(self, data, indices, indptr, rhs, n, symmetric, pattern=None) -> np.ndarray:
        """Factorise K (``data``: the solver's copy, ``_factored_data``) and solve."""
        if self.backend == "pardiso":
            if symmetric:
                return self._solve_pardiso(data, indices, indptr, rhs, n, 2)
            if self._symmetric_structure(pattern, indptr, indices, n):
                # LU on the symmetric pattern with diagonal pivots (`ddatai.pardiso._Pardiso`);
                # where a pivot had to be perturbed and refinement does not repair the solve,
                # the general solver with its weighted matching
                x = self._solve_pardiso(data, indices, indptr, rhs, n, 1)
                if x is not None:
                    return x
            return self._solve_pardiso(data, indices, indptr, rhs, n, 11)
        if self.backend == "dense":
            return self._solve_dense(data, indices, indptr, rhs, n, symmetric)
        from scipy.sparse import csc_matrix, csr_matrix
        from scipy.sparse.linalg import splu

        if symmetric:
            k = csc_matrix((data, indices, indptr), shape=(n, n))  # CSR of a symmetric K = its CSC
        else:
            k = csr_matrix((data, indices, indptr), shape=(n, n)).tocsc()
        try:
            lu = splu(k, permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                      options=dict(SymmetricMode=True))
        except RuntimeError:  # singular factor: reported as a non-finite solution
            self._factor = None
            return np.full(n, np.nan)
        self._factor = (symmetric, (indptr, indices), lu.solve)
        return lu.solve(rhs)

    def _solve_reusing(self, data, indices, indptr, rhs, n, symmetric) -> "np.ndarray | None":
        """Iterative refinement with the last factor (module docstring); None where it does not
        apply (another structure or matrix type, no factor) or does not converge fast."""
        if self._factor is None:
            return None
        factor_symmetric, key, solve = self._factor
        if factor_symmetric != symmetric or not self._same(key, indptr, indices):
            return None
        b = np.ascontiguousarray(rhs, dtype=np.float64)
        if not np.count_nonzero(b):
            return np.zeros(n)
        if self._exact and self.backend != "dense" and len(self._factored_data) == len(data) and \
                np.array_equal(self._factored_data, data):
            # K is the matrix factorised (the equilibrium stage's iterates whose contact states
            # did not change: only F moved): the solve is a direct one, the one the
            # factorisation itself would give, which is not refined either; refinement to
            # round-off took 3.4 solves at 1,600 blocks (benchmarks/results/large_round4.md)
            self.last_residual = 0.0
            return solve(b)
        if self.backend == "dense":
            k = self._dense(data, indices, indptr, n)
        else:
            from scipy.sparse import csr_matrix

            k = csr_matrix((data, indices, indptr), shape=(n, n))
        x, residual, done = _refinement(k, b, solve(b), solve, REUSE_RESIDUAL, REUSE_PASSES, REUSE_RATE)
        if not done:
            return None  # K has moved too far from the factor: factorise
        self.last_residual = residual
        return x

    def _solve_krylov(self, data, indices, indptr, rhs, n) -> "np.ndarray | None":
        """GMRES preconditioned by the last factor (module docstring); None where it does not
        apply (another structure, no factor) or does not converge fast. The factor may be of
        the other matrix type (a Cholesky factor preconditions a non-symmetric K and the
        reverse)."""
        if self._factor is None:
            return None
        factor_symmetric, key, solve = self._factor
        if not self._same(key, indptr, indices) or self._factored_data is None or \
                len(self._factored_data) != len(data):
            return None
        budget = KRYLOV_BLOCKS[bool(factor_symmetric)]
        if changed_blocks(data, self._factored_data, indptr) > budget:
            return None  # about one iteration per changed block: factorise instead
        from scipy.sparse import csr_matrix

        b = np.ascontiguousarray(rhs, dtype=np.float64)
        if not np.count_nonzero(b):
            return np.zeros(n)
        k = self._dense(data, indices, indptr, n) if self.backend == "dense" else \
            csr_matrix((data, indices, indptr), shape=(n, n))
        x, iterations, done = gmres(k, b, solve, max_iterations=min(2 * budget + 2, KRYLOV_ITERATIONS))
        self.krylov_iterations += iterations
        if not done or not np.all(np.isfinite(x)):
            return None
        residual = float(np.abs(b - k @ x).max()) / max(float(np.abs(b).max()), 1e-300)
        if residual > KRYLOV_ACCEPT:
            return None
        self.last_residual = residual
        return x

    def _rows(self, indptr, indices, n) -> np.ndarray:  # the row of each CSR entry, kept per structure
        if self._dense_rows is None or not self._same(self._dense_rows[0], indptr, indices):
            self._dense_rows = ((indptr, indices), np.repeat(np.arange(n), np.diff(indptr)))
        return self._dense_rows[1]

    def _dense(self, data, indices, indptr, n) -> np.ndarray:
        """K as a dense (n, n) array (the row of each CSR entry kept per structure)."""
        k = np.zeros((n, n))
        k[self._rows(indptr, indices, n), indices] = data
        return k

    def _solve_dense(self, data, indices, indptr, rhs, n, symmetric) -> np.ndarray:
        """LAPACK on the dense K: Cholesky when K is symmetric (LU if it turns out not positive
        definite), LU with partial pivoting otherwise; BLAS on one thread (`ddatai.threads`, once)."""
        with nullcontext() if limited() else one_blas_thread():
            return self._solve_dense_one_thread(data, indices, indptr, rhs, n, symmetric)

    def _solve_dense_one_thread(self, data, indices, indptr, rhs, n, symmetric) -> np.ndarray:
        from .dense import LU, Cholesky

        k = self._dense(data, indices, indptr, n)
        b = np.ascontiguousarray(rhs, dtype=np.float64)
        solve = None
        if symmetric:
            try:
                solve = Cholesky(k).solve  # LAPACK called directly: `ddatai.dense`
            except np.linalg.LinAlgError:
                solve = None
        if solve is None:
            if not np.all(np.isfinite(k)):
                self._factor = None
                return np.full(n, np.nan)
            lu = LU(k)
            if lu.singular or np.any(np.diag(lu.lu) == 0.0):  # singular: reported as a non-finite solution
                self._factor = None
                return np.full(n, np.nan)
            solve = lu.solve
        self._factor = (symmetric, (indptr, indices), solve)
        return solve(b)

    def _handle(self, mtype: int) -> _Pardiso:
        h = self._handles.get(mtype)
        if h is None:
            # one handle per matrix type for the whole run: the analysis is kept in it
            h = self._handles[mtype] = _Pardiso(mtype)
        return h

    @staticmethod
    def _same(key, indptr, indices) -> bool:
        if key is None:
            return False
        old_indptr, old_indices = key
        return (old_indptr is indptr and old_indices is indices) or (
            len(old_indptr) == len(indptr) and len(old_indices) == len(indices)
            and np.array_equal(old_indptr, indptr) and np.array_equal(old_indices, indices))

    def _symmetric_structure(self, pattern, indptr, indices, n) -> bool:
        """Whether K's pattern is symmetric: a `BlockPattern` is by construction (each coupled
        block pair stores both 6×6 blocks); another structure is checked once. A structure
        whose LU of type 1 once failed (`_solve_pardiso`) goes to type 11 from then on."""
        known = self._structure is not None and self._same(self._structure[0], indptr, indices)
        if not known and getattr(pattern, "structurally_symmetric", False):
            return True
        if not known:
            self._structure = ((indptr, indices), symmetric_pattern(indptr, indices, n))
        return self._structure[1]

    def _solve_pardiso(self, data, indices, indptr, rhs, n, mtype) -> "np.ndarray | None":
        """Factorise with the handle of matrix type ``mtype`` (2: Cholesky of the upper
        triangle; 1 or 11: LU of the full matrix) and solve. None where type 1 perturbed a
        pivot and refinement did not bring the residual below `REFINE_ABOVE` (the caller then
        factorises with type 11)."""
        symmetric = mtype == 2
        h = self._handle(mtype)
        for other in self._handles.values():
            if other is not h:
                other.release_factor()  # no solve uses it again before it is factorised anew
        fresh = not self._same(h.key, indptr, indices)
        if symmetric:
            # PARDISO reads the upper triangle: which CSR entries those are, once per structure
            if self._upper is None or not self._same(self._upper[0], indptr, indices):
                self._upper = None  # the last structure's arrays go before the new ones are made
                self._upper = _upper_triangle(indptr, indices, n)
            _, pos, a_ptr, a_idx = self._upper
            a_data = data.take(pos)
        else:
            a_ptr = np.ascontiguousarray(indptr, dtype=np.int32)
            a_idx = np.ascontiguousarray(indices, dtype=np.int32)
            # ``data`` is the solver's own copy of K (``_factored_data``, passed by `solve`): the
            # solves with the factor hold no caller's array, beside which the next iterate's K is made
            a_data = np.ascontiguousarray(data, dtype=np.float64)
        b = np.ascontiguousarray(rhs, dtype=np.float64)
        try:
            if fresh:
                h.release()
            # 13: analysis + factorisation + solve; 23: factorisation + solve with the analysis
            x = h.call(13 if fresh else 23, a_data, a_ptr, a_idx, b)
            if fresh:
                # kept by reference: pattern arrays are never written after `BlockPattern.build`
                h.key, h.n = (indptr, indices), n
            if h.perturbed_pivots:
                self._exact = False
                x, done = self._refine(h, data, indices, indptr, a_data, a_ptr, a_idx, b, x, n)
                if not done and mtype == 1:
                    self.perturbed_fallbacks += 1
                    h.release_factor()
                    self._factor = None
                    self._structure = ((indptr, indices), False)  # type 11 for this structure
                    return None
        except PardisoError:  # a failed factorisation is a non-finite solution
            h.key = None
            self._factor = None
            if mtype == 1:
                self._structure = ((indptr, indices), False)
                return None
            return np.full(n, np.nan)
        # the factor stays in the handle until its next factorisation: solves with it for
        # ``reuse`` (a perturbed pivot makes it inexact: refinement checks every solve anyway)
        self._factor = (symmetric, (indptr, indices),
                        lambda r: h.call(33, a_data, a_ptr, a_idx, r))
        return x

    def _refine(self, h, data, indices, indptr, a_data, a_ptr, a_idx, b, x, n) -> tuple:
        """Iterative refinement where MKL perturbed a pivot: a few solves with the same factor,
        while the relative residual is above `REFINE_ABOVE`. Returns (x, whether it got there)."""
        from scipy.sparse import csr_matrix

        k = csr_matrix((data, indices, indptr), shape=(n, n))
        x, self.last_residual, done = _refinement(k, b, x, lambda r: h.call(33, a_data, a_ptr, a_idx, r),
                                                  REFINE_ABOVE, REFINE_PASSES)
        return x, done
