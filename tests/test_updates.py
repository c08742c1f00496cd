"""Cholesky factors that follow the contact springs (`ddatai.updates`, the ``[cholmod]`` extra):
the rank-one terms of the springs that change between two solves are the difference of the two
assembled K; a solve by CHOLMOD's updates of the last factor equals a fresh factorisation's
within the round-off that K's conditioning allows; a factor that does not stand for K is caught
by the residual check; and the equilibrium start holds and releases the same blocks with the
updates as without them."""

import dataclasses

import numpy as np
import pytest

import ddatai as dd
from ddatai import updates
from ddatai.assembly import BlockPattern, assemble_blocks, assemble_contacts
from ddatai.layout import KIND, LOCK, OPEN, SLIDE, VE, VV
from ddatai.model import build_model
from ddatai.solver import SparseSolver
from ddatai.start import settle
from ddatai.step import Stepper
from ddatai.updates import Springs, block_rows

needs_cholmod = pytest.mark.skipif(not updates.available(), reason=updates.why_unavailable() or "CHOLMOD present")


def _step_system(seed: int = 7):
    """The first step's contacts, vectors and block terms of `scenes/jointed_slope.py` (75 free
    blocks, vertex-edge and vertex-vertex contacts), solved sparse."""
    from scenes.jointed_slope import build

    scene, params = build(seed=seed)
    model = build_model(scene, dataclasses.replace(params, solver="scipy", kernels="numpy"))
    stepper = Stepper(model)
    state = model.initial_state()
    geom = model.block_geometry(state.vertex_xy)
    contacts, vec, sca = stepper.find_contacts(state, geom)
    data0, rhs0 = assemble_blocks(model, state, geom, stepper.pattern, 1e-3, 0.5)
    return model, stepper, contacts, vec, sca, data0, rhs0


def _matrix(model, stepper, contacts, vec, sca, data0, rhs0):
    from scipy.sparse import csr_matrix

    data, rhs = data0.copy(), rhs0.copy()
    contacts.coupled[:] = False  # lagged friction: K symmetric
    assemble_contacts(model, contacts, stepper.pattern, vec, sca, data, rhs, stepper.serial_scatter)
    n = 6 * stepper.pattern.n_rows
    return csr_matrix((data, stepper.pattern.indices, stepper.pattern.indptr), shape=(n, n)), data, rhs


def _new_states(contacts, rng, share: float):
    """A copy of ``contacts`` with a random ``share`` of them in another state (open, sliding,
    locked; a closed vertex-vertex contact may change line)."""
    out = contacts.copy()
    pick = rng.random(contacts.n) < share
    vv = contacts.cint[:, KIND] == VV
    out.state[pick] = rng.choice([OPEN, SLIDE, LOCK], int(pick.sum()))
    out.state[pick & vv & (out.state == LOCK)] = SLIDE  # vertex-vertex contacts have no shear spring
    swap = pick & vv & (rng.random(contacts.n) < 0.5)
    out.line[swap] = 1 - out.line[swap]
    return out


def test_spring_columns_are_the_difference_of_the_assembled_matrices():
    """K(new states) − K(old states), both assembled, equals Σ c·cᵀ over the columns added minus
    those removed (`Springs.columns`) to the round-off of the assembly (1e-12 of the penalty),
    for open/close, lock/slide and line changes of vertex-edge and vertex-vertex contacts."""
    model, stepper, contacts, vec, sca, data0, rhs0 = _step_system()
    assert np.any(contacts.cint[:, KIND] == VV) and np.any(contacts.cint[:, KIND] == VE)
    rng = np.random.default_rng(3)
    rows = block_rows(model, contacts)
    old = contacts
    k_old, _, _ = _matrix(model, stepper, old, vec, sca, data0, rhs0)
    for share in (0.02, 0.2, 0.6):
        new = _new_states(old, rng, share)
        k_new, _, _ = _matrix(model, stepper, new, vec, sca, data0, rhs0)
        s_old, s_new = Springs.of(model, old, vec, rows), Springs.of(model, new, vec, rows)
        added, removed = s_new.columns(s_old, k_new.shape[0])
        assert s_new.rank(s_old) == (0 if added is None else added.shape[1]) + (0 if removed is None else removed.shape[1])
        low_rank = (added @ added.T if added is not None else 0) - (removed @ removed.T if removed is not None else 0)
        assert np.abs((k_new - k_old - low_rank).toarray()).max() <= 1e-12 * model.penalty
        old, k_old = new, k_new


@needs_cholmod
def test_updated_solves_equal_fresh_factorisations_within_the_conditioning():
    """A sequence of solves whose springs change by a few contacts each: the solver updates its
    factor (CHOLMOD) instead of factorising, and each solution x_u equals the dense LAPACK
    solution x_f within what K's conditioning allows: |x_u − x_f|₂ ≤ κ₂(K)·m·ε·|x_f|₂, m the
    most entries in a row of K (the round-off bound of the residual both reach)."""
    from scipy.linalg import solve as dense_solve

    model, stepper, contacts, vec, sca, data0, rhs0 = _step_system()
    solver = SparseSolver("scipy")
    assert solver.updates
    rng = np.random.default_rng(11)
    rows = block_rows(model, contacts)
    current = contacts
    for share in (0.0, 0.01, 0.01, 0.03, 0.0, 0.02):
        current = _new_states(current, rng, share)
        k, data, rhs = _matrix(model, stepper, current, vec, sca, data0, rhs0)
        pattern = stepper.pattern
        x = solver.solve(data, pattern.indices, pattern.indptr, rhs, springs=Springs.of(model, current, vec, rows))
        dense = k.toarray()
        exact = dense_solve(dense, rhs, assume_a="pos")
        kappa = np.linalg.cond(dense)
        m = int(np.max(np.diff(k.indptr))) + 1
        assert np.linalg.norm(x - exact) <= kappa * m * np.finfo(float).eps * np.linalg.norm(exact)
    assert solver.factorisations == 1 and solver.updated == 5


@needs_cholmod
def test_a_factor_that_does_not_stand_for_k_is_caught_and_refactorised():
    """Springs that misstate K (a contact said open whose springs K has) make the updated factor
    another matrix's: the residual check against K rejects it and K is factorised, so the solution
    is K's own (to 1e-9 relative) whatever the caller said."""
    from scipy.linalg import solve as dense_solve

    model, stepper, contacts, vec, sca, data0, rhs0 = _step_system()
    solver = SparseSolver("scipy")
    rows = block_rows(model, contacts)
    k, data, rhs = _matrix(model, stepper, contacts, vec, sca, data0, rhs0)
    pattern = stepper.pattern
    solver.solve(data, pattern.indices, pattern.indptr, rhs, springs=Springs.of(model, contacts, vec, rows))
    wrong = contacts.copy()
    closed = np.flatnonzero(contacts.state != OPEN)
    wrong.state[closed[: len(closed) // 10]] = OPEN  # K below still has these springs
    x = solver.solve(data, pattern.indices, pattern.indptr, rhs, springs=Springs.of(model, wrong, vec, rows))
    exact = dense_solve(k.toarray(), rhs, assume_a="pos")
    assert np.linalg.norm(x - exact) <= 1e-9 * np.linalg.norm(exact)
    assert solver.factorisations == 2 and solver.updated == 0


def _start(monkeypatch, with_updates: bool):
    """The jointed slope's stage with ``Params(factor_updates=True)``, CHOLMOD there or not."""
    from scenes.jointed_slope import build

    if not with_updates:
        monkeypatch.setattr(updates, "available", lambda: False)
    scene, params = build()
    model = build_model(scene, dataclasses.replace(params, solver="scipy", kernels="numpy", factor_updates=True))
    stepper = Stepper(model)
    state, record = settle(stepper, model.initial_state())
    monkeypatch.undo()
    return record, stepper.solver.updated, state


@pytest.mark.slow
@needs_cholmod
def test_the_start_holds_and_releases_the_same_blocks_with_and_without_updates(monkeypatch):
    """(Slow profile: two starts of the 75-block slope, ~30 s on 2 cores.)
    `scenes/jointed_slope.py`'s equilibrium stage on the sparse path, ``Params(factor_updates=True)``:
    with CHOLMOD's updates
    (most of its solves after a contact opens or closes update the factor) it holds and releases
    the same blocks as with a factorisation at every change (50 held, the 25 that limit
    equilibrium lets move released), with fewer factorisations. (The stage stalls on this model
    and ends with forces out of balance by a fraction of the load, which the first steps settle:
    where it ends depends on the round-off of the path, 0.25 mm of settlement here.)"""
    with_, updated, _ = _start(monkeypatch, True)
    without, none, _ = _start(monkeypatch, False)
    assert updated > 0 and none == 0
    assert not with_.welded and not without.welded
    # 50 held and the 25 released, or 40 more released in doubt where the stalled open-close test
    # does not converge: round-off decides (tests/test_limit_equilibrium.py)
    assert {(with_.held, with_.released), (without.held, without.released)} <= {(50, 25), (10, 65)}
    assert with_.factorisations < without.factorisations
