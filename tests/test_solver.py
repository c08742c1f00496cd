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
    x = solver.solve(scaled, same.indices, same.indptr, rhs, pattern=same)
    assert solver._pattern is same
    K = csr_matrix((scaled, pattern.indices, pattern.indptr), shape=(n, n))
    assert np.abs(K @ x - rhs).max() < 1e-10 * np.abs(rhs).max()
    y = solver.solve(data2, other.indices, other.indptr, rhs2, pattern=other)
    K2 = csr_matrix((data2, other.indices, other.indptr), shape=(len(rhs2), len(rhs2)))
    assert np.abs(K2 @ y - rhs2).max() < 1e-10 * np.abs(rhs2).max()
