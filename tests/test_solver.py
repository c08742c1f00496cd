"""Sparse solver backends: SuperLU (always) and PARDISO (when pypardiso is installed) solve the
DDA system to round-off, and a whole run does not depend on the backend."""

import dataclasses
import importlib.util

import numpy as np
import pytest
from scipy.sparse import csr_matrix

import ddatai as dd
from cases import perturbed_vertices, random_jointed_scene, sliding_scene
from ddatai.assembly import BlockPattern, assemble_blocks, assemble_contacts, contact_vectors
from ddatai.contacts import Contacts, detect_contacts
from ddatai.model import ContactMemory, build_model
from ddatai.solver import SparseSolver, available, resolve
from ddatai.step import Stepper

HAS_PARDISO = importlib.util.find_spec("pypardiso") is not None


def _blocks_and_contacts(seed):
    """A random jointed scene with perturbed vertices: its model, contacts, stepper, pattern,
    contact vectors and the block terms of K and F."""
    model = build_model(random_jointed_scene(seed))
    xy = perturbed_vertices(model, seed, shift=0.1 * model.search_distance)
    state = model.initial_state().replace(vertex_xy=xy)
    cint, length = detect_contacts(model, xy)
    c = Contacts.start(model, xy, cint, length, ContactMemory.empty(), True)
    stepper = Stepper(model)
    geom = model.block_geometry(xy)
    pattern = BlockPattern.build(model, c)
    vec, sca = contact_vectors(model, xy, geom, c)
    data, rhs = assemble_blocks(model, state, geom, pattern, 0.005, beta=0.5)
    return model, c, stepper, pattern, vec, sca, data, rhs


def _system(seed):
    model, c, stepper, pattern, vec, sca, data, rhs = _blocks_and_contacts(seed)
    assemble_contacts(model, c, pattern, vec, sca, data, rhs, stepper.serial_scatter)
    return pattern, data, rhs


@pytest.mark.parametrize("seed", [0, 1])
def test_superlu_solves_the_system(seed):
    pattern, data, rhs = _system(seed)
    n = len(rhs)
    x = SparseSolver("scipy").solve(data, pattern.indices, pattern.indptr, rhs)
    K = csr_matrix((data, pattern.indices, pattern.indptr), shape=(n, n))
    assert np.abs(K @ x - rhs).max() < 1e-10 * np.abs(rhs).max()


@pytest.mark.skipif(not HAS_PARDISO, reason="pypardiso is not installed (optional accelerator)")
def test_pardiso_matches_superlu():
    pattern, data, rhs = _system(2)
    a = SparseSolver("scipy").solve(data, pattern.indices, pattern.indptr, rhs)
    b = SparseSolver("pardiso").solve(data, pattern.indices, pattern.indptr, rhs)
    assert np.abs(a - b).max() < 1e-10 * np.abs(a).max()
    scene, block = sliding_scene(30.0, 20.0)
    r1 = dd.simulate(scene, params=dd.Params(solver="scipy"), duration=0.3)
    r2 = dd.simulate(scene, params=dd.Params(solver="pardiso"), duration=0.3)
    assert np.abs(r1.centroid - r2.centroid).max() < 1e-9


def test_solver_selection():
    assert available("scipy")
    assert resolve("auto") == ("pardiso" if HAS_PARDISO else "scipy")
    with pytest.raises(ValueError, match="solver"):
        dd.Params(solver="cholesky")


@pytest.mark.skipif(not HAS_PARDISO, reason="pypardiso is not installed (optional accelerator)")
def test_pardiso_reuses_analysis_only_for_the_same_structure():
    """A later step's pattern with the same structure reuses the ordering (and still solves the
    new values exactly); a different structure is analysed afresh."""
    import copy

    pattern, data, rhs = _system(0)
    other, data2, rhs2 = _system(1)
    n = len(rhs)
    solver = SparseSolver("pardiso")
    solver.solve(data, pattern.indices, pattern.indptr, rhs, pattern=pattern)
    same = copy.deepcopy(pattern)  # a new object, the same structure
    scaled = data * 1.7 + 0.0
    handle = solver._handles[2]
    analysis = handle.key
    x = solver.solve(scaled, same.indices, same.indptr, rhs, pattern=same)
    assert handle.key is analysis  # the analysis of the first structure is kept
    K = csr_matrix((scaled, pattern.indices, pattern.indptr), shape=(n, n))
    assert np.abs(K @ x - rhs).max() < 1e-10 * np.abs(rhs).max()
    y = solver.solve(data2, other.indices, other.indptr, rhs2, pattern=other)
    assert handle.key is not analysis
    K2 = csr_matrix((data2, other.indices, other.indptr), shape=(len(rhs2), len(rhs2)))
    assert np.abs(K2 @ y - rhs2).max() < 1e-10 * np.abs(rhs2).max()


@pytest.mark.skipif(not HAS_PARDISO, reason="pypardiso is not installed (optional accelerator)")
def test_pardiso_frees_the_other_types_factor_and_keeps_its_analysis():
    """A factorisation of one matrix type frees the factor the other type's handle holds (no
    solve uses it before it is factorised anew): at 102,400 blocks a Cholesky factor of 2 GB
    and an LU factor of 4 GB were held at once. The analysis stays, and the next factorisation
    of that type gives the solution of a fresh solver's, bit for bit."""
    pattern, data, rhs = _system(0)
    _, lu_data, _ = _non_symmetric(0)
    solver = SparseSolver("pardiso")
    args = (pattern.indices, pattern.indptr, rhs)
    x1 = solver.solve(data, *args, pattern=pattern)
    chol = solver._handles[2]
    assert chol.factored
    y1 = solver.solve(lu_data, *args, pattern=pattern, symmetric=False)
    lu = solver._handles[1]  # the coupled K: LU on its symmetric pattern
    assert lu.factored and not chol.factored and chol.key is not None  # factor freed, analysis kept
    x2 = solver.solve(data, *args, pattern=pattern)
    assert chol.factored and not lu.factored and lu.key is not None
    y2 = solver.solve(lu_data, *args, pattern=pattern, symmetric=False)
    assert np.array_equal(x1, x2) and np.array_equal(y1, y2)
    assert np.array_equal(x2, SparseSolver("pardiso").solve(data, *args, pattern=pattern))
    assert np.array_equal(y2, SparseSolver("pardiso").solve(lu_data, *args, pattern=pattern, symmetric=False))


def _non_symmetric(seed):
    """The system with implicit friction on every closed contact: K is not symmetric."""
    pattern, data, rhs = _system(seed)
    rng = np.random.default_rng(seed)
    n = len(rhs)
    K = csr_matrix((data, pattern.indices, pattern.indptr), shape=(n, n))
    rows = np.repeat(np.arange(n), np.diff(pattern.indptr))
    off = rows != pattern.indices
    data = data + off * rng.normal(0, 0.05, len(data)) * np.abs(data)
    assert abs(csr_matrix((data, pattern.indices, pattern.indptr), shape=(n, n)) - K.T).max() > 0
    return pattern, data, rhs


@pytest.mark.parametrize("backend", ["scipy", pytest.param("pardiso", marks=pytest.mark.skipif(
    not HAS_PARDISO, reason="pypardiso is not installed (optional accelerator)"))])
def test_non_symmetric_solve(backend):
    pattern, data, rhs = _non_symmetric(3)
    n = len(rhs)
    x = SparseSolver(backend).solve(data, pattern.indices, pattern.indptr, rhs, symmetric=False)
    K = csr_matrix((data, pattern.indices, pattern.indptr), shape=(n, n))
    assert np.abs(K @ x - rhs).max() < 1e-10 * np.abs(rhs).max()


@pytest.mark.skipif(not HAS_PARDISO, reason="pypardiso is not installed (optional accelerator)")
def test_pardiso_takes_its_parameters():
    """MKL ignores every iparm unless iparm[0] = 1, and then refines each solve twice; ddatai's
    settings must stick: no refinement performed, METIS ordering, zero-based indices."""
    pattern, data, rhs = _system(0)
    solver = SparseSolver("pardiso")
    solver.solve(data, pattern.indices, pattern.indptr, rhs)
    ip = solver._handles[2].iparm
    assert ip[0] == 1 and ip[1] == 2 and ip[7] == 0 and ip[34] == 1
    assert solver._handles[2].refinement_steps == 0
    pattern, data, rhs = _non_symmetric(1)
    solver.solve(data, pattern.indices, pattern.indptr, rhs, symmetric=False)
    h = solver._handles[1]
    assert h.iparm[0] == 1 and h.iparm[7] == 0 and h.refinement_steps == 0


@pytest.mark.skipif(not HAS_PARDISO, reason="pypardiso is not installed (optional accelerator)")
def test_coupled_k_is_factorised_on_its_symmetric_pattern():
    """The coupled K (friction tied to the same solve's normal force) is not symmetric, but its
    pattern is (a contact couples its blocks both ways): PARDISO's structurally symmetric LU
    (matrix type 1, no scaling or matching: its analysis 0.43–0.84 and its memory 0.85–0.89 of
    the general LU's on the project's matrices) solves it, with no pivot perturbed, to the residual of the general
    solver's solve and to SuperLU's solution; a pattern that is not symmetric goes to the
    general solver."""
    pattern, data, rhs = _non_symmetric(4)
    n = len(rhs)
    k = csr_matrix((data, pattern.indices, pattern.indptr), shape=(n, n))
    solver = SparseSolver("pardiso")
    x = solver.solve(data, pattern.indices, pattern.indptr, rhs, pattern=pattern, symmetric=False)
    h = solver._handles[1]
    assert sorted(solver._handles) == [1] and h.mtype == 1 and h.perturbed_pivots == 0
    assert h.iparm[10] == 0 and h.iparm[12] == 0  # no scaling, no matching
    general = SparseSolver("pardiso")
    general._structure = ((pattern.indptr, pattern.indices), False)  # as if the pattern were not symmetric
    y = general.solve(data, pattern.indices, pattern.indptr, rhs, symmetric=False)
    assert sorted(general._handles) == [11]
    scale = np.abs(rhs).max()
    assert np.abs(k @ x - rhs).max() <= max(4 * np.abs(k @ y - rhs).max(), 1e-14 * scale)
    assert np.abs(x - SparseSolver("scipy").solve(data, pattern.indices, pattern.indptr, rhs,
                                                  symmetric=False)).max() < 1e-10 * np.abs(x).max()


@pytest.mark.skipif(not HAS_PARDISO, reason="pypardiso is not installed (optional accelerator)")
def test_structurally_symmetric_lu_falls_back_to_matching_where_its_pivots_fail():
    """Diagonal pivots cannot factorise a matrix with zeros on its diagonal: PARDISO perturbs
    them, refinement does not reach the solver's residual, and the matrix is factorised again
    by the general LU with weighted matching, which solves it to round-off."""
    from scipy.sparse import eye, random as sparse_random

    n = 60
    a = sparse_random(n, n, density=0.2, random_state=1, format="csr")
    a = (a + a.T + eye(n)).tocsr()
    a.sort_indices()
    rng = np.random.default_rng(0)
    rows = np.repeat(np.arange(n), np.diff(a.indptr))
    vals = a.data * (1 + 0.3 * rng.standard_normal(len(a.data)))
    vals[(rows == a.indices) & (rows % 2 == 0)] = 0.0  # stored zeros on half the diagonal
    k = csr_matrix((vals, a.indices, a.indptr), shape=(n, n))
    b = rng.standard_normal(n)
    solver = SparseSolver("pardiso")
    x = solver.solve(k.data, k.indices, k.indptr, b, symmetric=False)
    assert solver._handles[1].perturbed_pivots > 0 and solver.perturbed_fallbacks == 1
    assert solver._handles[11].factored and not solver._handles[1].factored
    assert np.abs(k @ x - b).max() < 1e-12 * np.abs(b).max()
    # the same structure again: straight to the general LU
    y = solver.solve(1.5 * k.data, k.indices, k.indptr, b, symmetric=False)
    assert solver.perturbed_fallbacks == 1 and solver._handles[11].factored
    assert np.abs(1.5 * (k @ y) - b).max() < 1e-12 * np.abs(b).max()


BACKENDS = ["scipy", pytest.param("pardiso", marks=pytest.mark.skipif(
    not HAS_PARDISO, reason="pypardiso is not installed (optional accelerator)"))]


@pytest.mark.parametrize("backend", BACKENDS)
def test_reused_factor_solves_a_nearby_matrix_to_round_off(backend):
    """A step's first solve (``reuse``): K a little moved from the matrix last factorised is
    solved by refinement with the old factor, to the direct solution's accuracy and without a
    factorisation; a matrix that moved far, or a different matrix type, is factorised."""
    pattern, data, rhs = _system(3)
    n = len(rhs)
    solver = SparseSolver(backend)
    solver.solve(data, pattern.indices, pattern.indptr, rhs, pattern=pattern)
    assert (solver.factorisations, solver.reused) == (1, 0)
    rng = np.random.default_rng(0)
    # a settled step's change: the blocks moved by ~1e-6 of their size (symmetric)
    near = data * (1.0 + 1e-6 * rng.standard_normal(len(data)))
    near = 0.5 * (near + csr_matrix((near, pattern.indices, pattern.indptr), shape=(n, n)).T.tocsr()
                  .sorted_indices().data)
    rhs2 = rhs * (1.0 + 0.1 * rng.standard_normal(n))
    x = solver.solve(near, pattern.indices, pattern.indptr, rhs2, pattern=pattern, reuse=True)
    assert (solver.factorisations, solver.reused) == (1, 1)
    direct = SparseSolver(backend).solve(near, pattern.indices, pattern.indptr, rhs2)
    K = csr_matrix((near, pattern.indices, pattern.indptr), shape=(n, n))
    assert np.abs(K @ x - rhs2).max() <= 1e-12 * np.abs(rhs2).max()
    assert np.abs(x - direct).max() < 1e-10 * np.abs(direct).max()
    # the time step cut to a third: the inertia on the diagonal triples, refinement stalls
    far = near.copy()
    diag = np.flatnonzero(pattern.indices == np.repeat(np.arange(n), np.diff(pattern.indptr)))
    far[diag] *= 3.0
    x = solver.solve(far, pattern.indices, pattern.indptr, rhs2, pattern=pattern, reuse=True)
    assert (solver.factorisations, solver.reused) == (2, 1)
    K = csr_matrix((far, pattern.indices, pattern.indptr), shape=(n, n))
    assert np.abs(K @ x - rhs2).max() <= 1e-10 * np.abs(rhs2).max()
    # a non-symmetric solve never refines with a symmetric factor (or the reverse)
    solver.solve(far, pattern.indices, pattern.indptr, rhs2, pattern=pattern, symmetric=False, reuse=True)
    assert (solver.factorisations, solver.reused) == (3, 1)


def test_a_settled_run_reuses_its_factor_and_follows_the_factorised_run():
    """A 3 × 3 stack of stiff blocks resting on its base from the equilibrium start: its steps'
    first solves (the only ones) reuse the factor, and the run is the same as one that
    factorises every solve."""
    from ddatai.start import settle

    scene = dd.Scene(gravity=9.81)
    rock = dd.Material(density=2500.0, young=5e9, poisson=0.25)
    scene.add_block([(-1, -1), (4, -1), (4, 0), (-1, 0)], material=rock, fixed=True)
    for j in range(3):
        for i in range(3):
            scene.add_block([(i, j), (i + 1, j), (i + 1, j + 1), (i, j + 1)], material=rock)
    scene.set_joint(dd.Joint(friction=35.0))
    runs = []
    for reuse in (True, False):
        model = build_model(scene, dd.Params(dt=1e-3, solver="scipy"))
        stepper = Stepper(model)
        if not reuse:
            solve = stepper.solver.solve
            stepper.solver.solve = lambda *a, reuse=False, **k: solve(*a, **k)
        state, _ = settle(stepper, model.initial_state())
        before = stepper.solver.factorisations
        solves = []
        for _ in range(40):
            state, record = stepper.step(state)
            solves.append(record.oc_total)
        runs.append((state.vertex_xy, solves, stepper.solver.factorisations - before, stepper.solver.reused))
    (xy_r, solves_r, fact_r, reused_r), (xy_f, solves_f, fact_f, reused_f) = runs
    assert solves_r == solves_f and reused_f == 0
    assert reused_r >= 35 and fact_r <= sum(solves_r) - 35 and fact_f == sum(solves_f)
    assert np.abs(xy_r - xy_f).max() < 1e-12
    # it rests: the stack moved by its elastic settlement only
    assert np.abs(xy_r - model.vertex_xy0).max() < 1e-4


@pytest.mark.skipif(not HAS_PARDISO, reason="pypardiso is not installed (optional accelerator)")
def test_pardiso_runs_are_bit_for_bit_reproducible():
    """MKL's threads sum in varying order unless PARDISO runs in its conditional numerical
    reproducibility mode (iparm[33]): without it, runs of the 382-block jointed slope differed
    from the first by 1e-13 to 5e-13 m after 30 steps (in 4 of 5 repeats), enough for a chaotic
    scene to take another path. With it, runs on the same machine are identical."""
    from benchmarks.scaling import slope_scene

    ends = []
    for _ in range(2):
        scene, params = slope_scene(400)
        res = dd.simulate(scene, params=dataclasses.replace(params, solver="pardiso"), steps=30,
                          record_every=10**9)
        ends.append(res.vertices[-1])
    assert np.array_equal(ends[0], ends[1])


def _changed_states(seed, changes):
    """A system K, F and the same geometry with ``changes`` contacts' states changed (closed
    ones opened, locked ones sliding; None: all closed ones): the later solves of an
    open-close iteration."""
    model, c, stepper, pattern, vec, sca, data0, rhs0 = _blocks_and_contacts(seed)
    systems = []
    rng = np.random.default_rng(seed)
    closed = np.flatnonzero(c.state != dd.ContactState.OPEN)
    changes = [len(closed) if n is None else n for n in changes]
    assert len(closed) >= max(changes) >= 20, len(closed)
    for n_changed in (0,) + tuple(changes):
        k = c.copy()
        pick = rng.choice(closed, size=n_changed, replace=False)
        k.state[pick] = np.where(rng.random(n_changed) < 0.5, dd.ContactState.OPEN, dd.ContactState.SLIDE)
        k.normal_force[pick] = 1e5
        data, rhs = data0.copy(), rhs0.copy()
        assemble_contacts(model, k, pattern, vec, sca, data, rhs, stepper.serial_scatter)
        systems.append((data, rhs * (1.0 + 0.1 * rng.standard_normal(len(rhs)))))
    return pattern, systems


@pytest.mark.parametrize("backend", ["dense", *BACKENDS])
def test_krylov_solve_with_the_last_factor_matches_the_direct_solve(backend, monkeypatch):
    """A later solve of a step (``krylov``): K differs from the matrix last factorised by a few
    contacts' states; GMRES preconditioned by the old factor gives the direct solution (1e-10
    relative) at a direct solve's residual, without a factorisation. Many changes exhaust its
    iterations: the matrix is factorised, and the new factor serves the next solves. (The dense
    backend tries GMRES only above ``DENSE_KRYLOV_UNKNOWNS``, which this small system is made
    to exceed.)"""
    from ddatai import solver as solver_module
    from ddatai.solver import KRYLOV_ACCEPT

    monkeypatch.setattr(solver_module, "DENSE_KRYLOV_UNKNOWNS", 0)
    pattern, systems = _changed_states(2, (1, 2, None))
    (data0, rhs0), few, more, many = systems
    n = len(rhs0)
    solver = SparseSolver(backend)
    solver.solve(data0, pattern.indices, pattern.indptr, rhs0, pattern=pattern)
    for data, rhs in (few, more):
        x = solver.solve(data, pattern.indices, pattern.indptr, rhs, pattern=pattern, krylov=True)
        direct = SparseSolver(backend).solve(data, pattern.indices, pattern.indptr, rhs)
        K = csr_matrix((data, pattern.indices, pattern.indptr), shape=(n, n))
        assert np.abs(K @ x - rhs).max() <= KRYLOV_ACCEPT * np.abs(rhs).max()
        assert np.abs(x - direct).max() < 1e-10 * np.abs(direct).max()
    assert (solver.factorisations, solver.krylov) == (1, 2)
    assert 0 < solver.krylov_iterations <= 2 * 12
    data, rhs = many
    x = solver.solve(data, pattern.indices, pattern.indptr, rhs, pattern=pattern, krylov=True)
    assert (solver.factorisations, solver.krylov) == (2, 2)
    direct = SparseSolver(backend).solve(data, pattern.indices, pattern.indptr, rhs)
    assert np.abs(x - direct).max() < 1e-10 * np.abs(direct).max()
    # the factor of the many changes preconditions the next solve (here: the same matrix)
    x = solver.solve(data, pattern.indices, pattern.indptr, 0.5 * rhs, pattern=pattern, krylov=True)
    assert (solver.factorisations, solver.krylov) == (2, 3)
    assert np.abs(x - 0.5 * direct).max() < 1e-10 * np.abs(direct).max()


def test_dense_backend_factorises_small_systems_instead_of_gmres():
    """At most ``DENSE_KRYLOV_UNKNOWNS`` unknowns the dense backend factorises where a solve asks
    for GMRES with the last factor (cheaper there): the same solution as a fresh direct solve
    to round-off, a factorisation counted and no Krylov solve."""
    from ddatai.solver import DENSE_KRYLOV_UNKNOWNS

    pattern, systems = _changed_states(2, (1, 2, None))
    (data0, rhs0), few, more, _ = systems
    n = len(rhs0)
    assert n <= DENSE_KRYLOV_UNKNOWNS
    solver = SparseSolver("dense")
    solver.solve(data0, pattern.indices, pattern.indptr, rhs0, pattern=pattern)
    for data, rhs in (few, more):
        x = solver.solve(data, pattern.indices, pattern.indptr, rhs, pattern=pattern, krylov=True)
        direct = SparseSolver("dense").solve(data, pattern.indices, pattern.indptr, rhs)
        np.testing.assert_array_equal(x, direct)  # the same LAPACK calls on the same matrix
    assert (solver.factorisations, solver.krylov) == (3, 0)


def test_one_blas_thread_nests():
    """A limit inside another keeps BLAS at one thread until the outer one ends, which gives the
    libraries back their count (the equilibrium stage opens one around all its solves)."""
    threadpoolctl = pytest.importorskip("threadpoolctl")
    from ddatai.threads import _controllers, one_blas_thread

    if not _controllers():
        pytest.skip("no BLAS library that threadpoolctl controls")

    def counts():
        return [c.num_threads for c in _controllers()]

    with threadpoolctl.threadpool_limits(limits=2, user_api="blas"):
        before = counts()
        with one_blas_thread():
            assert counts() == [1] * len(before)
            with one_blas_thread():
                assert counts() == [1] * len(before)
            assert counts() == [1] * len(before)
        assert counts() == before


def test_changed_blocks_matches_its_sorting_twin():
    """The count of blocks (6 rows each) whose rows of K changed since the factor, which decides
    whether a later solve tries GMRES (`ddatai.iterative.changed_blocks`: one pass and a
    reduction per row), equals its NumPy twin's that sorts the changed entries' rows, on random
    structures with empty rows (at the start, inside, at the end), none or all or a few entries
    changed."""
    from scipy.sparse import random as sparse_random

    from ddatai.iterative import changed_blocks, changed_blocks_reference

    rng = np.random.default_rng(7)
    for trial in range(40):
        n = 6 * int(rng.integers(1, 30))
        k = sparse_random(n, n, density=float(rng.uniform(0.01, 0.3)), format="csr", random_state=trial)
        if trial % 3 == 0 and n > 12:  # empty rows: the first, one inside, the last
            keep = np.ones(n, bool)
            keep[[0, n // 2, n - 1]] = False
            k = (k.multiply(keep[:, None])).tocsr()
        data, indptr = k.data.copy(), k.indptr
        new = data.copy()
        if len(new):
            which = rng.random(len(new)) < [0.0, 1.0, 0.02, 0.2][trial % 4]
            new[which] += 1.0
        assert changed_blocks(new, data, indptr) == changed_blocks_reference(new, data, indptr), trial
