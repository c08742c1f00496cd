"""The mid-step lever arms at the step's predicted rotation (``Params.lever_arm_rotation =
"predicted"``, docs/method/dda.md §5.3): the same lever arms for all the solves of a step, so
that two solves' K differ only where contacts changed state, with the distances still exact at
each iterate."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import ddatai as dd
import ddatai.step
from ddatai.lever_arm import lever_shift, midstep_lever_arms
from rocking_cases import DEFAULTS, scene


def _swing(**fields):
    """The 0.5 × 2 m block released at 0.2 of its overturning angle, through its first impact
    (tests/rocking_cases.py; 0.26 s), with every solve's contact states and contact vectors
    recorded per open-close iteration."""
    import ddatai.open_close as oc

    iterations: list = []
    original_step_oc, original_assemble = ddatai.step.open_close, oc.assemble_contacts

    def open_close(*args, **kwargs):
        iterations.append([])
        return original_step_oc(*args, **kwargs)

    def assemble(model, contacts, pattern, vec, sca, data, rhs, serial):
        original_assemble(model, contacts, pattern, vec, sca, data, rhs, serial)
        iterations[-1].append((contacts.state.copy(), vec))

    params = dataclasses.replace(DEFAULTS, **fields)
    mp = pytest.MonkeyPatch()
    try:
        mp.setattr(ddatai.step, "open_close", open_close)
        mp.setattr(oc, "assemble_contacts", assemble)
        res = dd.simulate(scene(0.5, 2.0, 0.2), params, duration=0.3, record_every=10 ** 9)
    finally:
        mp.undo()
    return iterations, res


def test_lever_shift_is_the_midstep_shift_at_the_same_rotation():
    """With the columns and the rotation of one call, `lever_shift` gives `midstep_lever_arms`'s
    own shift (both lines of vertex-vertex contacts, the shear line of vertex-edge ones), and
    at another rotation the distances stay exact there: shift = −column·r̄."""
    from ddatai.step import Stepper

    sc = dd.Scene(gravity=9.81)
    rock = dd.Material(density=2600.0, young=1e9, poisson=0.25)
    sc.add_block([(-2, -1), (4, -1), (4, 0), (-2, 0)], material=rock, fixed=True)
    sc.add_block([(0, 0), (1, 0), (1, 1), (0, 1)], material=rock)          # edge to edge
    sc.add_block([(1, 0), (2, 0), (2, 1), (1, 1)], material=rock)          # corner to corner
    sc.add_block([(2.5, 0), (3.2, 0.5), (2.9, 1.0), (2.3, 0.6)], material=rock)
    model = dd.build_model(sc, dd.Params(kernels="numpy", dt=1e-3))
    stepper = Stepper(model)
    state = model.initial_state()
    geom = model.block_geometry(state.vertex_xy)
    contacts, _, _ = stepper.find_contacts(state, geom)
    assert contacts.n >= 4
    rng = np.random.default_rng(3)
    rotation = np.where(model.block_fixed, 0.0, rng.uniform(-0.05, 0.05, model.n_blocks))
    columns, shift = midstep_lever_arms(model, contacts, state.vertex_xy, geom["centroid"], rotation)
    assert np.any(columns) and np.any(shift[:, 2])
    np.testing.assert_allclose(lever_shift(contacts, columns, rotation), shift, rtol=0, atol=1e-15)
    other = 0.3 * rotation
    got = lever_shift(contacts, columns, other)
    np.testing.assert_allclose(got, shift * 0.3, rtol=0, atol=1e-15)


@pytest.mark.parametrize("mode", ["predicted", "iterate"])
def test_predicted_lever_arms_change_k_only_where_states_change(mode):
    """Through the swing's impact (an open-close iteration of 3 solves, the block turning), the
    solves of one iteration assemble K from one array of contact vectors with
    ``lever_arm_rotation="predicted"`` (K then differs between them only by the contacts whose
    state changed: `ddatai.updates.Springs.same_terms`); with each iterate's rotation (the
    default) from vectors that differ from solve to solve (every contact vertex's rotation
    column moved with the iterate)."""
    iterations, _ = _swing(lever_arm_rotation=mode)
    several = [solves for solves in iterations if len(solves) >= 2]
    assert len(several) >= 2, len(several)
    same = [a[1] is b[1] for solves in several for a, b in zip(solves, solves[1:])]
    equal = [np.array_equal(a[1], b[1]) for solves in several for a, b in zip(solves, solves[1:])]
    if mode == "predicted":
        assert all(same), same
    else:
        assert not any(equal), equal


def test_predicted_lever_arms_keep_the_free_swings_energy():
    """The free swing of tests/test_rocking.py keeps its energy to 1e-4 of the rocking energy
    with the lever arms at the predicted rotation too (their slope is the midpoint's to
    O(r̄·(r̄ − r_pred)), second order as each iterate's)."""
    from rocking_cases import free_swing

    drop, gain = free_swing(dataclasses.replace(DEFAULTS, lever_arm_rotation="predicted"))
    assert drop > 40
    assert abs(gain) < 1e-4, gain


def test_bad_lever_arm_rotation_is_named():
    with pytest.raises(ValueError, match="lever_arm_rotation"):
        dd.Params(lever_arm_rotation="midpoint")
