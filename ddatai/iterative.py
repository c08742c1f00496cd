"""Iterative solves with a factor in hand (`ddatai.solver`): iterative refinement with the factor
of a nearby matrix (a step's first solve, ``reuse``; a factor with perturbed pivots) and GMRES
preconditioned by the factor of a matrix that differs in a few contacts' terms (the later solves
of an open-close iteration, ``krylov``). Both stop at a direct solve's accuracy or give up, and
the solver then factorises. The module docstring of `ddatai.solver` gives the rules and the
costs measured.

**Krylov solves with the last factor.** The later solves of an open-close iteration differ
from the matrix last factorised by the terms of the contacts whose state changed (each lock ↔
slide or open ↔ closed change a rank-1 or rank-2 term) while the geometry is the same. Such a
solve (``krylov=True``) is done by GMRES preconditioned by the factor in hand (``gmres``, right
preconditioning, at most ``KRYLOV_ITERATIONS`` iterations) to a relative residual of
``KRYLOV_RESIDUAL``, the accuracy of a direct solve. GMRES takes about one iteration per block
whose rows of K changed (measured on the 1,540-block slope), and an iteration (a solve with the
factor, 1.7–2.9 ms there, and a product with K) costs 1/10 of a Cholesky factorisation (25 ms)
and 1/25 of an LU (55–70 ms). So it is tried only while the changed entries of K lie in the
rows of at most ``KRYLOV_BLOCKS`` blocks (half a factorisation's cost in iterations, by the
factor's type; fixed numbers, not timings, so that a run takes the same path every time), and
stops after twice as many iterations; where it does not converge the matrix is factorised, and
that factor preconditions the next solves.
"""

from __future__ import annotations

import numpy as np

#: relative residual |K x − b| / |b| above which a solve with perturbed pivots is refined
REFINE_ABOVE = 1e-10
#: a solve by refinement with an earlier factor (``reuse``) stops at this relative residual
#: |K x − b|max / |b|max — what a direct solve reaches (PARDISO's LU, whose pivots may be
#: perturbed by 1e-13, often less) ...
REUSE_RESIDUAL = 1e-14
#: ... or where a pass no longer reduces it by REUSE_RATE while it is below this (round-off of
#: the residual itself: the solution then agrees with a direct solve to ~1e-14) ...
REUSE_FLOOR = 1e-12
#: ... and gives up (and factorises) when a pass reduces the residual by less than this factor
#: above REUSE_FLOOR
REUSE_RATE = 0.05
#: ... or after this many corrections
REUSE_PASSES = 5
#: refinement where MKL perturbed a pivot makes at most this many corrections
REFINE_PASSES = 3
#: a Krylov solve (``krylov``) stops at this relative residual |K x − b|₂ / |b|₂ ...
KRYLOV_RESIDUAL = 1e-13
#: ... and is accepted when its true relative residual |K x − b|max / |b|max is at most this
#: (what a direct solve reaches, `REUSE_FLOOR`) ...
KRYLOV_ACCEPT = 1e-12
#: ... and gives up (the matrix is factorised) after this many iterations (each one solve
#: with the factor and one product with K) ...
KRYLOV_ITERATIONS = 30
#: a Krylov solve is tried only while the entries of K that differ from the factorised matrix
#: lie in the rows of at most this many blocks, with a Cholesky factor (symmetric) and with an
#: LU: GMRES takes about one iteration per changed block, and these are about half the cost of
#: the factorisation in iterations (module docstring); it stops after twice as many
KRYLOV_BLOCKS = {True: 5, False: 12}


def changed_blocks(data: np.ndarray, old: np.ndarray, indptr: np.ndarray) -> int:
    """How many blocks (6 rows each) of K hold an entry that differs between ``data`` and
    ``old`` (two CSR data arrays of one structure): one pass over the entries and a reduction
    per row, no sort (`changed_blocks_reference` sorts the changed entries' rows: 8–21 ms at
    1,537 blocks, where every solve's K changes everywhere and the answer only says "too many
    for GMRES"; benchmarks/step_levers.py)."""
    neq = data != old
    if not neq.any():
        return 0
    n = len(indptr) - 1
    starts = indptr[:-1]
    filled = starts < indptr[1:]  # a reduction per row that has entries (an empty row changed nothing)
    changed = np.zeros(n, bool)
    changed[filled] = np.logical_or.reduceat(neq, starts[filled])
    return int(np.count_nonzero(changed[: n - n % 6].reshape(-1, 6).any(axis=1))) + bool(changed[n - n % 6:].any())


def changed_blocks_reference(data: np.ndarray, old: np.ndarray, indptr: np.ndarray) -> int:
    """`changed_blocks` as first written (the changed entries' rows sorted): its NumPy twin."""
    changed = np.flatnonzero(data != old)
    if not len(changed):
        return 0
    rows = np.searchsorted(indptr, changed, side="right") - 1
    return len(np.unique(rows // 6))


def gmres(k, b: np.ndarray, solve, tol: float = KRYLOV_RESIDUAL, max_iterations: int = KRYLOV_ITERATIONS
          ) -> tuple[np.ndarray, int, bool]:
    """GMRES for K x = b, right-preconditioned by ``solve`` (a factor of a matrix near K), from
    x0 = solve(b): Arnoldi with classical Gram–Schmidt done twice (BLAS products; as accurate
    as modified Gram–Schmidt), Givens rotations for the least-squares problem. Returns (x,
    iterations, whether the residual estimate reached ``tol`` × |b|₂).

    Kept instead of `scipy.sparse.linalg.gmres` with the factor as its preconditioner, which
    ``benchmarks/gmres.py`` measured paired on the 391-block slope's K with 1–8 contacts changed:
    SciPy's preconditions from the left, so it applies the factor twice more per solve (to b and
    to the first residual) and stops on the preconditioned residual — 1.2–1.9× the time at the
    same iteration counts, and a true residual of 1.3e-12 with 4 contacts changed, above what
    the solver accepts (``KRYLOV_ACCEPT``, which would cost a factorisation); this one starts from
    x0 = solve(b), preconditions from the right and so minimises the true residual."""
    from scipy.linalg import solve_triangular

    x0 = solve(b)
    r = b - k @ x0
    bnorm = float(np.linalg.norm(b))
    beta = float(np.linalg.norm(r))
    if not np.isfinite(beta):
        return x0, 0, False
    if beta <= tol * bnorm:
        return x0, 0, True
    n, m = len(b), max_iterations
    basis = np.empty((m + 1, n))
    precond = np.empty((m, n))
    h = np.zeros((m + 1, m))
    cs, sn = np.zeros(m), np.zeros(m)
    g = np.zeros(m + 1)
    g[0] = beta
    basis[0] = r / beta
    done, j = False, 0
    for j in range(m):
        precond[j] = solve(np.ascontiguousarray(basis[j]))
        w = k @ precond[j]
        v = basis[: j + 1]
        c1 = v @ w
        w = w - c1 @ v
        c2 = v @ w
        w = w - c2 @ v
        h[: j + 1, j] = c1 + c2
        h[j + 1, j] = float(np.linalg.norm(w))
        if h[j + 1, j] > 0.0:
            basis[j + 1] = w / h[j + 1, j]
        for i in range(j):  # the earlier rotations on the new column
            h[i, j], h[i + 1, j] = cs[i] * h[i, j] + sn[i] * h[i + 1, j], -sn[i] * h[i, j] + cs[i] * h[i + 1, j]
        rho = float(np.hypot(h[j, j], h[j + 1, j]))
        if rho == 0.0 or not np.isfinite(rho):
            return x0, j + 1, False
        cs[j], sn[j] = h[j, j] / rho, h[j + 1, j] / rho
        h[j, j], h[j + 1, j] = rho, 0.0
        g[j], g[j + 1] = cs[j] * g[j], -sn[j] * g[j]
        estimate = abs(g[j + 1])
        if estimate <= tol * bnorm:  # (a breakdown, h[j+1, j] = 0, is an exact solution: 0)
            done = True
            break
    y = solve_triangular(h[: j + 1, : j + 1], g[: j + 1], check_finite=False)
    return x0 + y @ precond[: j + 1], j + 1, done


def _refinement(k, b: np.ndarray, x: np.ndarray, solve, target: float, passes: int,
                rate: "float | None" = None) -> tuple[np.ndarray, float, bool]:
    """Iterative refinement x ← x + solve(b − K x), ``solve`` applying the factor of a matrix
    at or near K, with at most ``passes`` corrections. Returns (x, its relative residual
    |b − K x|max / |b|max, whether it reached ``target``). With a ``rate``, it stops as soon
    as a pass reduces the residual by less than that factor: done (the better of the last two
    x) if both residuals are below `REUSE_FLOOR` — the residual's own round-off —, not done
    otherwise."""
    scale = max(float(np.maximum.reduce(np.abs(b))), 1e-300)
    best, last = x, 1.0
    for done in range(passes + 1):
        if np.count_nonzero(np.isfinite(x)) < x.size:
            return best, last, False
        r = b - k @ x
        residual = float(np.maximum.reduce(np.abs(r))) / scale
        if residual <= target:
            return x, residual, True
        if rate is not None and residual > rate * last:
            if residual <= REUSE_FLOOR and last <= REUSE_FLOOR:
                return (x, residual, True) if residual < last else (best, last, True)
            return x, residual, False
        if done == passes:
            break
        best, last = x, residual
        x = x + solve(np.ascontiguousarray(r))
    return x, residual, False


def refine_to_roundoff(k, b: np.ndarray, x: np.ndarray, solve, passes: int = REUSE_PASSES
                       ) -> tuple[np.ndarray, float, bool]:
    """Iterative refinement x ← x + solve(b − K x) of a solve by an updated factor (`ddatai.updates`),
    done when x solves K x = b as well as a backward-stable direct solve does: its componentwise
    backward error (Oettli–Prager) max |b − K x|ᵢ / (|K|·|x| + |b|)ᵢ at most m·ε, m the most
    entries in a row of K (the bound on the rounding of the m-term sums of a row; a fresh
    factorisation's solves measure 1.3–1.6 ε on the jointed slope's K, updated ones 2–5 ε), or
    its residual within ``REUSE_RESIDUAL`` × |b|max. It gives up (not done) after ``passes``
    corrections, or where a pass does not reduce the residual by ``REUSE_RATE``. Returns (x,
    relative residual |b − K x|max / |b|max, done)."""
    scale = max(float(np.abs(b).max()), 1e-300)
    bound = (int(np.max(np.diff(k.indptr), initial=1)) + 1) * np.finfo(float).eps
    abs_k, abs_b = abs(k), np.abs(b)
    last = np.inf
    for done in range(passes + 1):
        if not np.isfinite(x).all():
            return x, np.inf, False
        r = b - k @ x
        residual = float(np.abs(r).max())
        if residual <= REUSE_RESIDUAL * scale or np.all(np.abs(r) <= bound * (abs_k @ np.abs(x) + abs_b)):
            return x, residual / scale, True
        if residual > REUSE_RATE * last or done == passes:
            break
        last = residual
        x = x + solve(np.ascontiguousarray(r))
    return x, residual / scale, False
