"""Re-assembly after a judgement (`ddatai.reassembly`): K and F of the contacts' new states,
summed again only in the blocks whose contacts changed, against a whole assembly of the same
states (docs/method/dda.md §9), on random small scenes with random state changes."""

import dataclasses

import numpy as np
import pytest

from ddatai import backend
from ddatai.assembly import BlockPattern, assemble_blocks, assemble_contacts, contact_vectors
from ddatai.kinematics import newmark_beta
from ddatai import reassembly
from ddatai.reassembly import ContactAssembly
from test_assembly import _random_case


def _change(c, rng, share):
    """Random judgements of a ``share`` of the contacts: state, line, shear direction, coupling."""
    k = rng.random(c.n) < share
    c.state[k] = rng.integers(0, 3, int(k.sum()))
    ve = c.cint[:, 0] == 0
    flip = k & ~ve & (rng.random(c.n) < 0.5)
    c.line[flip] = 1 - c.line[flip]
    turn = k & (rng.random(c.n) < 0.5)
    c.shear_dir[turn] = -c.shear_dir[turn]
    c.coupled[k] = (rng.random(int(k.sum())) < 0.5) & ve[k]
    c.normal_force[:] = rng.uniform(0, 1e5, c.n)  # the last solve's N: F at every contact


@pytest.mark.parametrize("seed, numpy_path, serial", [(0, False, True), (1, False, False), (2, True, False)],
                         ids=["kernels-serial", "kernels-parallel", "numpy"])
def test_reassembly_gives_the_whole_assembly(seed, numpy_path, serial, monkeypatch):
    """Solves with a few contacts changed (blocks re-summed), none changed, and most changed
    (assembled whole): K and F as a whole assembly of the same states gives them, bit for bit
    where the kernels sum serially (the same additions in the same order), to round-off where
    a parallel loop sums in any order; and the block-rows it reports cover every change of K.
    (``WHOLE_SHARE``, a cost threshold, is raised: a small scene's few contacts touch a large
    share of it.)"""
    monkeypatch.setattr(reassembly, "WHOLE_SHARE", 0.5)
    model, state, c = _random_case(seed)
    model = dataclasses.replace(model, numpy_path=numpy_path)
    rng = np.random.default_rng(seed + 20)
    c.coupled[:] = (rng.random(c.n) < 0.5) & (c.cint[:, 0] == 0)
    backend.ensure("cpu")
    geom = model.block_geometry(state.vertex_xy)
    pattern = BlockPattern.build(model, c)
    vec, sca = contact_vectors(model, state.vertex_xy, geom, c)
    data0, rhs0 = assemble_blocks(model, state, geom, pattern, 0.003, newmark_beta(model.params, state))
    assembly = ContactAssembly(model, pattern, vec, data0, serial)
    last = None
    partial = 0
    for share in (0.0, 0.05, 0.05, 0.0, 0.02, 0.9, 0.1):
        _change(c, rng, share)
        shifted = sca + rng.normal(0, 1e-5, sca.shape)  # a new second-order shift at every solve
        rhs = rhs0.copy()
        data, rows = assembly.assemble(c, shifted, rhs)
        full, full_rhs = data0.copy(), rhs0.copy()
        assemble_contacts(model, c, pattern, vec, shifted, full, full_rhs, serial)
        if serial or numpy_path:
            assert np.array_equal(data, full) and np.array_equal(rhs, full_rhs)
        else:
            assert np.allclose(data, full, rtol=1e-13, atol=1e-14 * np.abs(full).max())
            assert np.allclose(rhs, full_rhs, rtol=1e-13, atol=1e-14 * np.abs(full_rhs).max())
        if last is not None and rows is not None:
            moved = np.flatnonzero(np.abs(data - last) > 1e-12 * np.abs(full).max())
            row_of = np.searchsorted(pattern.indptr, moved, side="right") - 1
            assert set(np.unique(row_of // 6)) <= set(rows.tolist())
            partial += 1
        last = data.copy()
    assert partial >= 2  # the re-summed path was taken, not only whole assemblies


class _WholeAssembly(ContactAssembly):
    """The assembly before re-assembly: every solve's K and F summed whole."""

    def assemble(self, contacts, sca, rhs):
        data = self.data0.copy()
        assemble_contacts(self.model, contacts, self.pattern, self.vec, sca, data, rhs, self.serial)
        return data, None


def test_a_failing_stack_runs_as_with_whole_assemblies(monkeypatch):
    """Four slender columns capped by a slab on a 30° plane at φ = 25°, released from rest
    (contacts opening, closing, locking and sliding: up to 24 solves a step at first), on the
    Taichi kernels: the run with re-assembly ends with the positions of the run that assembles
    every solve whole — bit for bit where the kernels sum serially
    (`ddatai.backend.serial_scatter`), to round-off otherwise. (Re-summed at any share of the
    contacts, ``WHOLE_SHARE``: a small model's few contacts touch a large share of it.)"""
    monkeypatch.setattr(reassembly, "WHOLE_SHARE", 1.0)
    import ddatai as dd
    from ddatai import open_close
    from cases import G, block_on_incline, incline_base

    scene = dd.Scene(gravity=G)
    incline_base(scene, 30.0)
    for col in range(4):
        block_on_incline(scene, 30.0, at=3.0 + col * 0.45, width=0.4, height=1.2)
    block_on_incline(scene, 30.0, at=3.0, width=1.75, height=0.4, lift=1.2)
    scene.set_joint(dd.Joint(friction=25.0))
    params = dd.Params(kernels="taichi", initial_equilibrium=False, dt=2e-3)
    runs = []
    for cls in (ContactAssembly, _WholeAssembly):
        monkeypatch.setattr(open_close, "ContactAssembly", cls)
        runs.append(dd.simulate(scene, params, steps=20, record_every=20))
    new, old = runs
    assert int(new.steps["oc_total"].sum()) > 40  # the states did change
    end_new, end_old = new.vertices[-1], old.vertices[-1]
    if backend.serial_scatter():
        assert np.array_equal(new.steps["oc_total"], old.steps["oc_total"])
        assert np.array_equal(end_new, end_old)
    else:
        assert np.allclose(end_new, end_old, rtol=0, atol=1e-9)
