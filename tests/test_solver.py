"""Sparse solver backends: SuperLU (always) and PARDISO (when pypardiso is installed) solve the
DDA system to round-off, and a whole run does not depend on the backend."""

import importlib.util

import numpy as np
import pytest
from scipy.sparse import csr_matrix

import ddatai as dd
from cases import perturbed_vertices, random_jointed_scene, sliding_scene
from ddatai.contacts import BlockPattern, Contacts, detect_contacts
from ddatai.model import ContactMemory, build_model
from ddatai.solver import SparseSolver, available, resolve
from ddatai.step import Stepper

HAS_PARDISO = importlib.util.find_spec("pypardiso") is not None


def _system(seed):
    model = build_model(random_jointed_scene(seed))
    xy = perturbed_vertices(model, seed, shift=0.1 * model.search_distance)
    state = model.initial_state().replace(vertex_xy=xy)
    cint, length = detect_contacts(model, xy)
    c = Contacts.start(model, xy, cint, length, ContactMemory.empty(), True)
    stepper = Stepper(model)
    geom = model.block_geometry(xy)
    pattern = BlockPattern.build(model, c)
    vec, sca = stepper.contact_vectors(xy, geom, c)
    data, rhs = stepper.assemble_blocks(state, geom, pattern, 0.005)
    stepper.assemble_contacts(c, pattern, vec, sca, data, rhs)
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
    h = solver._handles[11]
    assert h.iparm[0] == 1 and h.iparm[7] == 0 and h.refinement_steps == 0
