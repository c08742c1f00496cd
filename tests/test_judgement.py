"""Open-close judgement: the Taichi kernels (contact law, violations, internal forces) against
their NumPy twins in `ddatai.contact_law` (docs/method/dda.md §2.8, §4), on random contact states and
displacements, and a run judged by either path."""

import numpy as np
import pytest

import ddatai as dd
from cases import perturbed_vertices, random_jointed_scene
from ddatai import backend, open_close
from ddatai.assembly import contact_vectors
from ddatai.contact_law import (contact_law, contact_law_numpy, internal_force, internal_force_numpy,
                                violations, violations_numpy)
from ddatai.contacts import Contacts, detect_contacts
from ddatai.model import ContactMemory, build_model
from ddatai.step import Stepper

FLOAT_FIELDS = ("dn", "ds", "fn", "ft", "strength", "dn_now", "fn_now", "ft_now", "friction_now")
STATE_FIELDS = ("line", "closed", "state", "direction")


def _case(seed, reference="load"):
    """A random jointed scene with random contact states, bonds, strengths, coupling, normal
    forces, and lines that a vertex was already behind at the step start."""
    scene = random_jointed_scene(seed)
    model = build_model(scene, dd.Params(dt=1e-3, kernels="taichi", oc_force_reference=reference,
                                         oc_force_tolerance=1e-3 if reference == "load" else 1e-6))
    rng = np.random.default_rng(seed)
    xy = perturbed_vertices(model, seed, shift=0.2 * model.search_distance)
    cint, length = detect_contacts(model, xy)
    c = Contacts.start(model, xy, cint, length, ContactMemory.empty(), False)
    vv = cint[:, 0] == 1
    c.state[:] = np.where(vv, rng.choice([0, 1], c.n), rng.integers(0, 3, c.n))
    c.line[:] = np.where(vv, rng.integers(0, 2, c.n), 0)
    c.bond[:] = rng.random(c.n) < 0.5
    c.coupled[:] = (rng.random(c.n) < 0.5) & ~vv
    c.shear_dir[:] = rng.choice([-1, 1], c.n)
    c.tensile[:] = rng.uniform(0, 1e5, c.n)
    c.cohesion[:] = rng.uniform(0, 1e5, c.n)
    c.normal_force[:] = rng.uniform(0, 1e5, c.n)
    c.tan_phi[:] = rng.uniform(0, 1.2, c.n)
    backend.ensure("cpu")
    geom = model.block_geometry(xy)
    vec, sca = contact_vectors(model, xy, geom, c)
    behind = rng.random((c.n, 2)) < 0.2
    sca[:, :2] -= np.where(behind, 3.0 * model.penetration_limit, 0.0)
    # a block's weight, the smallest load the judgement measures it by (as `Stepper` has it)
    load = model.block_density * model.block_geometry(model.vertex_xy0)["area"] * float(np.hypot(*model.gravity))
    return model, load, c, vec, sca, rng


@pytest.mark.parametrize("seed", range(6))
@pytest.mark.parametrize("serial", [True, False], ids=["serial-loop", "parallel-loop"])
def test_judgement_kernels_equal_numpy(seed, serial):
    # both convergence tests (Params.oc_force_reference), alternating with the seed
    model, load, c, vec, sca, rng = _case(seed, "load" if seed % 2 else "strength")
    # a heavy fixed block: its weight must not loosen the force tests of its contacts
    load = np.where(model.block_fixed, 1e6 * load, load)
    assert c.n > 20
    scale = model.search_distance
    for trial in range(4):
        disp = np.zeros((model.n_blocks, 6))
        free = ~model.block_fixed
        disp[free, :2] = rng.normal(0, scale, (int(free.sum()), 2))
        disp[free, 2] = rng.normal(0, 0.1 * scale, int(free.sum()))
        disp[free, 3:] = rng.normal(0, 1e-5, (int(free.sum()), 3))
        shift = rng.normal(0, 1e-3 * scale, sca.shape) if trial % 2 else None
        law = contact_law(model, c, vec, sca, disp, shift)
        ref = contact_law_numpy(model, c, vec, sca, disp, shift)
        assert law.packed is not None and ref.packed is None
        for f in FLOAT_FIELDS:
            a, b = getattr(law, f), getattr(ref, f)
            np.testing.assert_allclose(a, b, rtol=1e-12, atol=1e-12 * float(np.abs(b).max(initial=0.0)),
                                       err_msg=f)
        for f in STATE_FIELDS:
            np.testing.assert_array_equal(getattr(law, f), getattr(ref, f), err_msg=f)
        assert law.energy == pytest.approx(ref.energy, rel=1e-12)
        # the random states break the law in many ways: each rule is exercised
        bad = violations(model, c, law, load)
        assert 0 < bad.sum() < c.n
        np.testing.assert_array_equal(bad, violations_numpy(model, c, ref, load))
        force = internal_force(model, c, vec, law, serial)
        np.testing.assert_allclose(force, internal_force_numpy(model, c, vec, ref), rtol=1e-12,
                                   atol=1e-12 * float(np.abs(force).max()))


def test_a_run_judged_by_the_kernels_follows_the_numpy_path(monkeypatch):
    """A 4 × 4 stiff grid dropped 5 mm onto its base (impacts, sliding, lock-slide changes):
    50 steps judged by the kernels and by the NumPy path give the same solves and positions."""
    def scene():
        s = dd.Scene(gravity=9.81)
        rock = dd.Material(density=2500.0, young=5e9, poisson=0.25)
        s.add_block([(-1, -1), (5, -1), (5, 0), (-1, 0)], material=rock, fixed=True)
        for j in range(4):
            for i in range(4):
                y = 0.005 + j
                s.add_block([(i, y), (i + 1, y), (i + 1, y + 1), (i, y + 1)], material=rock)
        s.set_joint(dd.Joint(friction=30.0))
        return s

    params = dd.Params(dt=1e-3, initial_equilibrium=False, kernels="taichi")
    runs = []
    for numpy_path in (False, True):
        model = build_model(scene(), params)
        stepper = Stepper(model)
        # the open-close iteration's law (and line search): the kernel or the NumPy twin
        monkeypatch.setattr(open_close, "contact_law", contact_law_numpy if numpy_path else contact_law)
        state, solves = model.initial_state(), []
        for _ in range(50):
            state, record = stepper.step(state)
            solves.append(record.oc_total)
        runs.append((state.vertex_xy.copy(), solves))
    (xy_k, solves_k), (xy_n, solves_n) = runs
    assert solves_k == solves_n
    assert np.abs(xy_k - xy_n).max() < 1e-9
    # the grid has fallen onto its base and moved
    assert np.abs(xy_k - build_model(scene(), params).vertex_xy0).max() > 4e-3


@pytest.mark.parametrize("seed", range(3))
def test_force_tests_measure_the_load_of_free_blocks(seed):
    """The default force tests (``oc_force_reference = "load"``) take the load of a contact's
    free blocks: a heavy fixed block does not loosen them. A locked contact on the fixed block
    holding its strength + ½ tolerance passes, + 2 × tolerance is marked — by the kernel and its
    NumPy twin alike."""
    model, load, c, vec, sca, rng = _case(seed, "load")
    load = np.where(model.block_fixed, 1e6 * load, load)
    disp = np.zeros((model.n_blocks, 6))
    law = contact_law(model, c, vec, sca, disp)
    ref = contact_law_numpy(model, c, vec, sca, disp)
    # the load of the free blocks, as the judgement computes it
    level = load.copy()
    np.maximum.at(level, c.block_a, np.abs(ref.fn))
    np.maximum.at(level, c.block_b, np.abs(ref.fn))
    level[model.block_fixed] = 0.0
    free = np.maximum(level[c.block_a], level[c.block_b])
    on_fixed = (model.block_fixed[c.block_a] | model.block_fixed[c.block_b]) & (c.cint[:, 0] == 0)
    c.state[on_fixed] = dd.ContactState.LOCK
    c.bond[on_fixed] = False
    picked = np.flatnonzero(on_fixed)
    assert len(picked) >= 2
    tol = model.params.oc_force_tolerance
    for factor, marked in ((0.5, False), (2.0, True)):
        for lw in (law, ref):
            # the law as the solve would find it: the locked spring at strength + factor × tol
            lw.ft_now[picked] = lw.strength[picked] + factor * tol * free[picked]
            lw.ft[picked] = lw.ft_now[picked]
            lw.fn_now[picked] = lw.fn[picked]
        np.testing.assert_array_equal(violations(model, c, law, load)[picked],
                                      violations_numpy(model, c, ref, load)[picked])
        assert np.all(violations_numpy(model, c, ref, load)[picked] == marked)


@pytest.mark.parametrize("seed", range(4))
def test_the_stage_law_is_the_numpy_law_of_coupled_contacts(seed):
    """`stage_law` (the equilibrium stage's return mapping) gives, bit for bit, the fields of
    `contact_law_numpy` on the contacts coupled (the strength of this solve's N) that the stage
    reads, on random states, bonds, strengths, lines and displacements, without Taichi."""
    from ddatai.contact_law import stage_law
    from ddatai.vectorized import detect_contacts as detect_numpy

    scene = random_jointed_scene(seed)
    model = build_model(scene, dd.Params(dt=1e-3, kernels="numpy"))
    rng = np.random.default_rng(seed)
    xy = perturbed_vertices(model, seed, shift=0.2 * model.search_distance)
    cint, length = detect_numpy(model, xy)
    c = Contacts.start(model, xy, cint, length, ContactMemory.empty(), False)
    assert c.n > 20
    vv = cint[:, 0] == 1
    c.state[:] = np.where(vv, rng.choice([0, 1], c.n), rng.integers(0, 3, c.n))
    c.line[:] = np.where(vv, rng.integers(0, 2, c.n), 0)
    c.bond[:] = rng.random(c.n) < 0.5
    c.tensile[:] = rng.uniform(0, 1e5, c.n)
    c.cohesion[:] = rng.uniform(0, 1e5, c.n)
    c.tan_phi[:] = rng.uniform(0, 1.2, c.n)
    vec, sca = contact_vectors(model, xy, model.block_geometry(xy), c)
    sca[:, :2] -= np.where(rng.random((c.n, 2)) < 0.2, 3.0 * model.penetration_limit, 0.0)
    coupled = c.copy()
    coupled.coupled[:] = True
    scale = model.search_distance
    for _ in range(3):
        disp = np.zeros((model.n_blocks, 6))
        free = ~model.block_fixed
        disp[free, :3] = rng.normal(0, scale, (int(free.sum()), 3)) * [1.0, 1.0, 0.1]
        law, ref = stage_law(model, c, vec, sca, disp), contact_law_numpy(model, coupled, vec, sca, disp)
        assert 0 < law.closed.sum() < c.n
        for f in ("dn", "ds", "line", "closed", "fn", "strength", "dn_now"):
            assert getattr(law, f).tobytes() == getattr(ref, f).tobytes(), f
        assert law.tan_phi is None and ref.tan_phi is None
