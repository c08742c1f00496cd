"""The iterates' K and F re-assembled only where contacts changed (`ddatai.reassembly`) against
the full assembly (`assembly.assemble_contacts`), on random small scenes whose contact states
and slips change from iterate to iterate (docs/method/dda.md §2.8)."""

import numpy as np
import pytest

from ddatai import backend
from ddatai.assembly import BlockPattern, assemble_blocks, assemble_contacts, contact_vectors
from ddatai.kinematics import newmark_beta
from ddatai.layout import LOCK, OPEN, SLIDE
from ddatai import reassembly
from ddatai.reassembly import ContactSystem, contact_rhs
from test_assembly import _random_case


def _full(model, c, pattern, vec, sca, data0, rhs0, serial):
    data, rhs = data0.copy(), rhs0.copy()
    assemble_contacts(model, c, pattern, vec, sca, data, rhs, serial)
    return data, rhs


def _setup(seed):
    model, state, c = _random_case(seed)
    backend.ensure("cpu")
    geom = model.block_geometry(state.vertex_xy)
    pattern = BlockPattern.build(model, c)
    vec, sca = contact_vectors(model, state.vertex_xy, geom, c)
    data0, rhs0 = assemble_blocks(model, state, geom, pattern, 0.003, newmark_beta(model.params, state))
    return model, c, pattern, vec, sca, data0, rhs0


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_contact_loads_are_the_full_assemblys(seed):
    """F's contact terms alone (`kernels.assemble_contact_loads`, and its NumPy twin), with
    random states, lines, coupled and explicit friction: the full kernel's F, float for float
    with the serial loop (the same terms added in the same order), and the twin within
    round-off."""
    from ddatai import kernels as K
    from ddatai.contact_law import friction_terms

    model, c, pattern, vec, sca, data0, rhs0 = _setup(seed)
    rng = np.random.default_rng(seed + 20)
    c.coupled[:] = (rng.random(c.n) < 0.5) & (c.cint[:, 0] == 0)
    _, rhs = _full(model, c, pattern, vec, sca, data0, rhs0, True)
    loads = rhs0.copy()
    const, slope = friction_terms(model, c)
    K.assemble_contact_loads(c.cint, c.state, c.line, model.vertex_block, model.block_dof, vec, sca, const, slope,
                             c.shear_dir, model.penalty, model.shear_penalty, loads, True)
    assert np.array_equal(loads, rhs)
    twin = rhs0.copy()
    contact_rhs(model, c, vec, sca, twin)
    assert np.allclose(twin, rhs, rtol=1e-13, atol=1e-14 * np.abs(rhs).max())


@pytest.mark.parametrize("seed", [0, 1, 2, 3])
@pytest.mark.parametrize("serial", [True, False], ids=["serial-loop", "parallel-loop"])
def test_iterates_reassembled_where_contacts_changed(seed, serial, monkeypatch):
    """Ten iterates: each opens, closes, locks or frees a few contacts (some switch lines, some
    none at all) and moves the slips of many: K equals the full assembly's (float for float with
    the serial loop, whose sum order is fixed, and F too); K is the same array where no
    state changed."""
    monkeypatch.setattr(reassembly, "PARTIAL_FROM", 0)  # these scenes have fewer contacts
    model, c, pattern, vec, sca, data0, rhs0 = _setup(seed)
    rng = np.random.default_rng(seed + 30)
    system = ContactSystem(model, pattern, vec, data0, rhs0, serial)
    last = None
    for it in range(10):
        if it % 3 != 2:  # every third iterate keeps the states: only the slips move
            flip = rng.choice(c.n, size=max(1, c.n // 20), replace=False)
            c.state[flip] = rng.choice([OPEN, SLIDE, LOCK], len(flip))
            vv = flip[c.cint[flip, 0] == 1]
            c.line[vv] = rng.integers(0, 2, len(vv))
        s = sca.copy()
        s[:, 2] -= rng.normal(0, 1e-4, c.n) * (rng.random(c.n) < 0.3)
        data, rhs = system.system(c, s)
        full_data, full_rhs = _full(model, c, pattern, vec, s, data0, rhs0, serial)
        if serial:
            assert np.array_equal(data, full_data) and np.array_equal(rhs, full_rhs)
        else:
            assert np.allclose(data, full_data, rtol=1e-13, atol=1e-14 * np.abs(full_data).max())
            assert np.allclose(rhs, full_rhs, rtol=1e-13, atol=1e-14 * np.abs(full_rhs).max())
        if it % 3 == 2:
            assert data is last
        last = data
    assert system.full == 1 and system.kept >= 3 and system.partial + system.full + system.kept == 10


def test_few_contacts_assembled_in_full():
    """Below ``PARTIAL_FROM`` contacts every iterate assembles K in full (a partial one costs
    more there), with the same K and F."""
    model, c, pattern, vec, sca, data0, rhs0 = _setup(0)
    assert c.n < reassembly.PARTIAL_FROM
    system = ContactSystem(model, pattern, vec, data0, rhs0, True)
    for _ in range(3):
        c.state[:3] = (c.state[:3] + 1) % 3
        data, rhs = system.system(c, sca)
        full_data, full_rhs = _full(model, c, pattern, vec, sca, data0, rhs0, True)
        assert np.array_equal(data, full_data) and np.array_equal(rhs, full_rhs)
    assert system.full == 3
