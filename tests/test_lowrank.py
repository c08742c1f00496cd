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
