"""Updates of low rank of the factor in hand (`ddatai.lowrank`, ``SparseSolver.solve(lowrank=True)``):
the equilibrium stage's iterates, whose K differs from the matrix factorised by the springs of the
contacts that opened or closed, are solved by the factor and the Woodbury identity to a direct
solve's accuracy, and a change beyond ``RANK_MAX`` (or a system below ``LOWRANK_UNKNOWNS``) is
factorised."""

import numpy as np
import pytest
from scipy.sparse import csr_matrix

from ddatai.iterative import KRYLOV_ACCEPT
from ddatai.lowrank import RANK_MAX, LowRankSolve
from ddatai.solver import SparseSolver
from test_solver import BACKENDS, _changed_states


def _direct(backend, pattern, data, rhs):
    return SparseSolver(backend).solve(data, pattern.indices, pattern.indptr, rhs)


@pytest.mark.parametrize("backend", BACKENDS)
def test_update_of_the_factor_matches_the_direct_solve(backend, monkeypatch):
    """One and two contacts changed (a rank of at most 2 each: normal and shear spring): the
    solve by the old factor and the identity has a direct solve's residual and its solution
    (1e-10 relative), with no factorisation, and another F on the same K reuses the update;
    every closed contact changed is factorised, and the new factor serves the next solves."""
    from ddatai import lowrank

    pattern, systems = _changed_states(2, (1, 2, None))
    (data0, rhs0), few, more, many = systems
    n = len(rhs0)
    solver = SparseSolver(backend)
    solver.solve(data0, pattern.indices, pattern.indptr, rhs0, pattern=pattern)
    solver.solve(few[0], pattern.indices, pattern.indptr, few[1], pattern=pattern, lowrank=True)
    assert (solver.factorisations, solver.lowrank) == (2, 0)  # too small a system: factorised as before
    monkeypatch.setattr(lowrank, "LOWRANK_UNKNOWNS", 0)  # this one has a few hundred unknowns
    solver = SparseSolver(backend)
    solver.solve(data0, pattern.indices, pattern.indptr, rhs0, pattern=pattern, lowrank=True)
    assert (solver.factorisations, solver.lowrank) == (1, 0)  # no factor yet
    x = solver.solve(data0.copy(), pattern.indices, pattern.indptr, 0.5 * rhs0, pattern=pattern, lowrank=True)
    assert (solver.factorisations, solver.lowrank, solver.reused) == (1, 0, 1)  # the matrix factorised
    assert np.abs(x - _direct(backend, pattern, data0, 0.5 * rhs0)).max() < 1e-10 * np.abs(x).max()
    for changed, (data, rhs) in ((1, few), (2, more)):
        direct = _direct(backend, pattern, data, rhs)
        k = csr_matrix((data, pattern.indices, pattern.indptr), shape=(n, n))
        for scale in (1.0, -2.0):  # the slips move F only: the same update solves it again
            x = solver.solve(data.copy(), pattern.indices, pattern.indptr, scale * rhs, pattern=pattern,
                             lowrank=True)
            assert np.abs(k @ x - scale * rhs).max() <= KRYLOV_ACCEPT * np.abs(scale * rhs).max()
            assert np.abs(x - scale * direct).max() < 1e-10 * np.abs(scale * direct).max()
        assert 0 < solver._lowrank[2].rank <= 2 * changed
    assert (solver.factorisations, solver.lowrank) == (1, 4)
    data, rhs = many
    x = solver.solve(data, pattern.indices, pattern.indptr, rhs, pattern=pattern, lowrank=True)
    assert (solver.factorisations, solver.lowrank) == (2, 4)
    assert np.abs(x - _direct(backend, pattern, data, rhs)).max() < 1e-10 * np.abs(x).max()


def test_rank_of_the_change_is_read_from_the_matrices():
    """ΔK = Σ kᵢ·eᵢeᵢᵀ on r distinct rows of a diagonal K₀ has rank r: kept up to ``RANK_MAX``,
    refused (None: factorise) beyond; the update solves K exactly (closed form: K is diagonal)."""
    n = 40
    k0 = np.arange(1.0, n + 1)
    indptr, indices = np.arange(n + 1, dtype=np.int32), np.arange(n, dtype=np.int32)
    for r in (1, RANK_MAX, RANK_MAX + 1):
        data = k0.copy()
        data[np.arange(r) * 3] += 10.0
        update = LowRankSolve.build(data, k0, np.flatnonzero(data != k0), indices, indptr, lambda b: b / k0,
                                    indices, float(k0.max()))
        if r > RANK_MAX:
            assert update is None
            continue
        assert update.rank == r
        b = np.linspace(-1.0, 2.0, n)
        assert np.allclose(update.solve(b), b / data, rtol=1e-14, atol=0.0)


def _chain(stiff: float, soft: np.ndarray):
    """K of a chain of 60 unknowns held by a unit spring at its first: neighbours joined by unit
    springs (``soft``: their values) and every third link by ``stiff`` ones (welded pairs)."""
    n = 60
    k = np.array(soft, dtype=np.float64)
    k[::3] = stiff
    main = np.r_[k, 0.0] + np.r_[0.0, k]
    main[0] += 1.0
    rows = np.r_[np.arange(n), np.arange(n - 1), np.arange(1, n)]
    cols = np.r_[np.arange(n), np.arange(1, n), np.arange(n - 1)]
    m = csr_matrix((np.r_[main, -k, -k], (rows, cols)), shape=(n, n))
    m.sort_indices()
    return m


@pytest.mark.parametrize("backend", BACKENDS)
def test_no_updates_from_a_factor_whose_own_solve_misses_the_bar(backend, monkeypatch):
    """Where K is so ill-conditioned that the direct solve itself leaves a relative residual far
    above ``KRYLOV_ACCEPT`` (a soft chain with links 1e6 times stiffer: ~5e-9), an update of its
    factor cannot reach the bar either (checked: it returns None), and the solver factorises
    without setting one up (``FACTOR_RESIDUAL_MAX``); the same change on the well-conditioned
    chain (stiff = soft) is solved by the update. The solutions are the direct solve's."""
    from ddatai import lowrank

    monkeypatch.setattr(lowrank, "LOWRANK_UNKNOWNS", 0)
    built = []
    build = LowRankSolve.build
    monkeypatch.setattr(LowRankSolve, "build", staticmethod(lambda *a, **k: built.append(1) or build(*a, **k)))
    soft = np.ones(59)
    changed = soft.copy()
    changed[10] = 2.0  # one link's spring doubled: ΔK of rank 1
    b = np.zeros(60)
    b[-1], b[30] = 1.0, -0.3
    for stiff, updated in ((1.0, True), (1e6, False)):
        k0, k1 = _chain(stiff, soft), _chain(stiff, changed)
        solver = SparseSolver(backend)
        x0 = solver.solve(k0.data.copy(), k0.indices, k0.indptr, b)
        own = np.abs(b - k0 @ x0).max() / np.abs(b).max()
        assert (own > lowrank.FACTOR_RESIDUAL_MAX) == (not updated)
        if not updated:  # the update itself misses the bar here: the check only saves its work
            direct_k0 = solver._factor[2]
            update = LowRankSolve.build(k1.data, k0.data, np.flatnonzero(k1.data != k0.data), k1.indices,
                                        k1.indptr, direct_k0, np.repeat(np.arange(60), np.diff(k1.indptr)),
                                        float(np.abs(k0.data).max()))
            assert update is not None and update.rank == 1 and update.solve(b) is None
        built.clear()
        x = solver.solve(k1.data.copy(), k1.indices, k1.indptr, b, lowrank=True)
        assert (solver.factorisations, solver.lowrank, len(built)) == ((1, 1, 1) if updated else (2, 0, 0))
        direct = _direct_csr(backend, k1, b)
        assert np.abs(x - direct).max() <= 1e-10 * np.abs(direct).max()


def _direct_csr(backend, k, b):
    return SparseSolver(backend).solve(k.data.copy(), k.indices, k.indptr, b)
