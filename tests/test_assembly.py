"""Assembly: the Taichi kernels (straight into a fixed CSR pattern) against the dense NumPy
reference, term by term (docs/method/dda.md §2), on random small scenes and random contact states."""

import numpy as np
import pytest
from scipy.sparse import csr_matrix

import ddatai as dd
from cases import perturbed_vertices, random_jointed_scene
from ddatai import reference
from ddatai import backend
from ddatai.assembly import BlockPattern, assemble_blocks, assemble_contacts, contact_vectors
from ddatai.contact_law import friction_force
from ddatai.contacts import Contacts, detect_contacts
from ddatai.kinematics import newmark_beta
from ddatai.model import ContactMemory, build_model


def _random_case(seed, static=False, plane="strain"):
    scene = random_jointed_scene(seed)
    rng = np.random.default_rng(seed)
    for b in rng.choice(np.arange(1, scene.n_blocks), size=2, replace=False):
        xy = scene.polygon(int(b)).mean(axis=0)
        scene.add_fixed_point(int(b), xy)
        scene.add_point_load(int(b), xy, (float(rng.normal(0, 1e4)), float(rng.normal(0, 1e4))))
    model = build_model(scene, dd.Params(static=static, plane=plane, kernels="taichi"))
    xy = perturbed_vertices(model, seed, shift=0.2 * model.search_distance)
    nb = model.n_blocks
    state = model.initial_state().replace(
        vertex_xy=xy,
        block_velocity=rng.normal(0, 1, (nb, 6)),
        block_stress=rng.normal(0, 1e5, (nb, 3)),
        block_accel=rng.normal(0, 1, (nb, 6)), step=3,
        fixed_point_xy=model.fixed_point_xy0 + rng.normal(0, 1e-4, model.fixed_point_xy0.shape),
        load_xy=model.load_xy0 + rng.normal(0, 1e-3, model.load_xy0.shape))
    cint, length = detect_contacts(model, xy)
    c = Contacts.start(model, xy, cint, length, ContactMemory.empty(), False)
    c.state[:] = rng.integers(0, 3, c.n)
    c.line[:] = np.where(cint[:, 0] == 1, rng.integers(0, 2, c.n), 0)
    c.bond[:] = rng.random(c.n) < 0.5
    c.shear_dir[:] = rng.choice([-1, 1], c.n)
    c.omega[:] = rng.uniform(0, 1, c.n)
    c.dn[:] = rng.normal(-1e-6, 1e-6, c.n)
    c.normal_force[:] = rng.uniform(0, 1e5, c.n)
    c.cohesion[:] = rng.uniform(0, 1e5, c.n)
    return model, state, c


@pytest.mark.parametrize("seed, static, plane", [(0, False, "strain"), (1, True, "stress"),
                                                 (2, False, "stress"), (3, False, "strain")])
@pytest.mark.parametrize("serial", [True, False], ids=["serial-loop", "parallel-loop"])
def test_taichi_assembly_equals_dense_reference(seed, static, plane, serial):
    """Both loop modes of the contact kernel (serial on small CPUs, parallel with atomic adds
    elsewhere: `ddatai.backend.serial_scatter`)."""
    model, state, c = _random_case(seed, static, plane)
    backend.ensure("cpu")
    geom = model.block_geometry(state.vertex_xy)
    pattern = BlockPattern.build(model, c)
    vec, sca = contact_vectors(model, state.vertex_xy, geom, c)
    dt = 0.003
    data, rhs = assemble_blocks(model, state, geom, pattern, dt, newmark_beta(model.params, state))
    assemble_contacts(model, c, pattern, vec, sca, data, rhs, serial)
    n = 6 * pattern.n_rows
    K = csr_matrix((data, pattern.indices, pattern.indptr), shape=(n, n)).toarray()
    friction = friction_force(c)
    Kr, Fr = reference.assemble_dense(
        model, state.vertex_xy, state.block_velocity, state.block_stress, state.fixed_point_xy,
        state.load_xy, np.array([f for f in model.load_force]), dt, model.gravity, c, vec, sca, friction,
        accel=state.block_accel, beta=model.params.newmark_beta)
    scale = np.abs(Kr).max()
    assert np.allclose(K, Kr, rtol=1e-12, atol=1e-13 * scale)
    assert np.allclose(rhs, Fr, rtol=1e-12, atol=1e-13 * np.abs(Fr).max())
    assert np.allclose(K, K.T, rtol=0, atol=1e-13 * scale)
    assert np.all(np.linalg.eigvalsh(K) > 0)  # SPD: every free block carries inertia


def test_pattern_holds_every_contacting_pair():
    """The CSR pattern has one 6×6 block per free block and per pair of contacting free blocks,
    rows sorted, and each contact's slots point at its own pair."""
    model, state, c = _random_case(4)
    pattern = BlockPattern.build(model, c)
    n = 6 * pattern.n_rows
    A = csr_matrix((np.ones(pattern.nnz), pattern.indices, pattern.indptr), shape=(n, n))
    A.sum_duplicates()
    assert A.nnz == pattern.nnz  # no duplicate entries
    rows = model.block_dof[c.block_a]
    cols = model.block_dof[c.block_b]
    coupled = (rows >= 0) & (cols >= 0)
    for k in np.flatnonzero(coupled)[:20]:
        r, col = rows[k], cols[k]
        s = pattern.slot_ab[k]
        assert pattern.indices[s] == 6 * col
        assert pattern.indptr[6 * r] <= s < pattern.indptr[6 * r + 1]


def _subset(c, idx):
    return Contacts(**{k: v[idx] for k, v in vars(c).items()})


def test_pattern_reused_while_the_block_pairs_stay():
    """A pattern built with ``previous`` keeps its layout when the coupled pairs are the same
    (contacts reordered, dropped within a pair) and gives the slots of a fresh build; a new
    pair makes a fresh layout."""
    model, state, c = _random_case(5)
    first = BlockPattern.build(model, c)
    # the same pairs from a shuffled subset that still has every pair
    rng = np.random.default_rng(5)
    order = rng.permutation(c.n)
    key = np.minimum(c.block_a, c.block_b) * model.n_blocks + np.maximum(c.block_a, c.block_b)
    _, keep = np.unique(key[order], return_index=True)
    sub = _subset(c, np.sort(order[np.union1d(keep, np.arange(0, c.n, 2))]))
    fresh = BlockPattern.build(model, sub)
    reused = BlockPattern.build(model, sub, first)
    assert reused.indptr is first.indptr and reused.indices is first.indices
    assert np.array_equal(fresh.indices, reused.indices) and np.array_equal(fresh.indptr, reused.indptr)
    assert np.array_equal(fresh.slot_ab, reused.slot_ab) and np.array_equal(fresh.slot_ba, reused.slot_ba)
    # drop every contact of one coupled pair: a fresh layout with one pair less
    rows, cols = model.block_dof[c.block_a], model.block_dof[c.block_b]
    k = int(np.flatnonzero((rows >= 0) & (cols >= 0) & (rows != cols))[0])
    fewer = _subset(c, np.flatnonzero(key != key[k]))
    smaller = BlockPattern.build(model, fewer, first)
    assert smaller.indices is not first.indices
    assert smaller.nnz == first.nnz - 72
    assert np.array_equal(smaller.indices, BlockPattern.build(model, fewer).indices)


@pytest.mark.parametrize("seed, static, plane", [(0, False, "strain"), (1, True, "stress"), (2, False, "stress")])
def test_numpy_assembly_equals_the_kernels(seed, static, plane):
    """The small-model path's NumPy twins of the assembly kernels (`Model.numpy_path`) give the
    same K and F as the Taichi kernels, with random states (locked, sliding, open, vertex-vertex
    on either line), coupled and explicit friction, fixed points and point loads."""
    import dataclasses

    model, state, c = _random_case(seed, static, plane)
    rng = np.random.default_rng(seed + 10)
    c.coupled[:] = (rng.random(c.n) < 0.5) & (c.cint[:, 0] == 0)
    backend.ensure("cpu")
    geom = model.block_geometry(state.vertex_xy)
    pattern = BlockPattern.build(model, c)
    vec, sca = contact_vectors(model, state.vertex_xy, geom, c)
    out = []
    for numpy_path in (False, True):
        m = dataclasses.replace(model, numpy_path=numpy_path)
        data, rhs = assemble_blocks(m, state, geom, pattern, 0.003, newmark_beta(m.params, state))
        assemble_contacts(m, c, pattern, vec, sca, data, rhs, False)
        out.append((data, rhs))
    (dk, rk), (dn, rn) = out
    assert np.allclose(dn, dk, rtol=1e-12, atol=1e-13 * np.abs(dk).max())
    assert np.allclose(rn, rk, rtol=1e-12, atol=1e-13 * np.abs(rk).max())
