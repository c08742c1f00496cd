"""The equilibrium stage's first pseudo-step stops where its iterate leaves DDA's range of
validity (`ddatai.mechanisms.out_of_range`, docs/method/dda.md §8.12): an iterate that throws a
block by a rotation beyond the first-order one (√(1 + r0²) − 1 above the 25 % strain limit of a
first-order block: 0.75 rad) while the blocks it keeps overlap one another by a quarter of a
block is not evidence of a mechanism, and the stage starts from the welded equilibrium
(``StartRecord.diverged``) instead of releasing what it threw. On ntdda's tall grid a frictional
pseudo-step from that welded equilibrium leaves DDA's range as well: the welded start stays."""

import numpy as np
import pytest

import ddatai as dd
from ddatai import mechanisms, return_mapping, start
from ddatai.contacts import Contacts
from ddatai.layout import OPEN
from ddatai.model import ContactMemory, build_model
from ddatai.step import Stepper
from tests.test_start import partly_failing_scene, stacked_grid


def test_the_first_order_rotation_bound_is_the_strain_limit_s_stretch():
    """I + r0·J stretches every line by √(1 + r0²): 25 % at 0.75 rad."""
    r = mechanisms.FIRST_ORDER_ROTATION
    assert r == pytest.approx(0.75, abs=1e-12)
    assert np.hypot(1.0, r) - 1.0 == pytest.approx(0.25, abs=1e-12)


def _row_of_three():
    """Three 1 m blocks side by side on a fixed base, their contacts as at t = 0, and a zero D."""
    model = build_model(stacked_grid(3, 1), dd.Params(dt=1e-3))
    stepper = Stepper(model)
    xy = model.initial_state().vertex_xy
    cint, length = stepper.detect(xy, ContactMemory.empty())
    contacts = Contacts.start(model, xy, cint, length, ContactMemory.empty(), True)
    return stepper, contacts, np.zeros((model.n_blocks, 6)), np.ones(model.n_blocks)


def _between(contacts, a, b):
    return ((contacts.block_a == a) & (contacts.block_b == b)) | ((contacts.block_a == b) & (contacts.block_b == a))


@pytest.mark.parametrize("rotation, overlap, pair, closed, out_of_range", [
    (0.80, 0.30, (1, 2), False, True),    # thrown by 0.80 rad, the kept blocks 1 and 2 overlap 0.30
    (0.80, 0.30, (1, 0), False, True),    # ... a kept block into the fixed base
    (0.70, 0.30, (1, 2), False, False),   # the rotation within the first-order range
    (0.80, 0.20, (1, 2), False, False),   # the overlap less than a quarter of a block
    (0.80, 0.30, (2, 3), False, False),   # the thrown block into a kept one: how a mechanism moves
    (0.80, 0.30, (1, 2), True, False),    # a closed contact: a spring, not an overlap
])
def test_out_of_range_takes_a_thrown_rotation_beyond_first_order_and_kept_blocks_overlapping(
        rotation, overlap, pair, closed, out_of_range):
    stepper, contacts, disp, size = _row_of_three()
    thrown = np.zeros(stepper.model.n_blocks, bool)
    thrown[3] = True
    disp[3, 2] = rotation
    at = _between(contacts, *pair)
    assert at.any()
    contacts.state[at] = contacts.state[at] if closed else OPEN
    if closed:
        assert np.all(contacts.state[at] != OPEN)
    contacts.dn[at] = -overlap
    assert mechanisms.out_of_range(stepper, contacts, disp, np.zeros_like(thrown), thrown, size) == out_of_range


def test_a_first_pseudo_step_out_of_range_starts_welded_and_says_why(monkeypatch):
    """`partly_failing_scene`: A slides (thrown by translation, a valid first-order motion: the
    rule does not apply) and is released, as before. Where the first pseudo-step's throw is
    out of range (forced here), the stage releases nothing and the model starts from its welded
    equilibrium, every block held, and `Results.start` says so (``diverged``)."""
    scene, a, b, c = partly_failing_scene()
    res = dd.simulate(scene, params=dd.Params(dt=1e-3), steps=1)
    assert not res.start[0]["diverged"] and not res.start[0]["welded"] and res.start[0]["released"] == 1
    seen = []

    def forced(*args, **kwargs):
        seen.append(mechanisms.out_of_range(*args, **kwargs))
        return True

    monkeypatch.setattr(return_mapping, "out_of_range", forced)
    res = dd.simulate(scene, params=dd.Params(dt=1e-3), steps=1)
    rec = res.start[0]
    assert seen == [False]  # asked once, at the first throw, which the rule itself lets go
    assert rec["diverged"] and rec["welded"] and rec["held"] == 3 and rec["released"] == 0


#: ntdda's soft rock, the tall grid's (E = 100 MPa, ρ = 2000 kg/m³)
DENSITY, YOUNG = 2000.0, 1e8


def _tall_grid():
    """ntdda's soft grid (E = 100 MPa, p = 1 GPa, φ = 30°) 40 columns wide and 160 rows tall: its
    side columns have the 160 × 160 grid's height."""
    rock = dd.Material(density=DENSITY, young=YOUNG, poisson=0.25)
    return build_model(stacked_grid(40, 160, rock), dd.Params(dt=1e-3, penalty=1e9, plane="stress",
                                                              max_displacement_ratio=0.003))


@pytest.mark.slow
def test_a_tall_grid_whose_first_pseudo_step_diverges_starts_welded(monkeypatch):
    """The tall grid's first pseudo-step's return mapping, 34 solves in (its corner contacts
    still opening and closing), turns two blocks near the top by 1.34 and 1.03 rad, and the
    blocks it keeps overlap by 0.30 of a block; releasing the two released 6,387 of the 6,400
    blocks in 1,053 solves (105 s of CPU). Out of range (`ddatai.mechanisms.out_of_range`), the
    stage starts welded, every block held: 42 solves. Held as springs, the grid stands as one
    column 40 m wide: its welded pseudo-steps, a fixed-point iteration on the geometry, contract
    by the weight over the buckling weight, Greenhill's (H / l_cr)³ for a clamped column under
    its own weight (`tests.test_pseudo_steps`: within 10 %, the joints' E/p), 0.77 at
    l_cr = 174.6 m. ~20 s."""
    increments = []
    measure = start.block_displacement

    def logged(*args):
        out = measure(*args)
        increments.append(float(out.max(initial=0.0)))
        return out

    monkeypatch.setattr(start, "block_displacement", logged)
    model = _tall_grid()
    _, record = start.settle(Stepper(model), model.initial_state())
    assert record.diverged and record.welded
    assert record.held == model.n_free and record.released == 0
    assert record.solves < 60
    width, height = 40.0, 160.0
    critical = 1.986 * (YOUNG * width ** 2 / 12.0 / (DENSITY * 9.81)) ** (1.0 / 3.0)
    assert len(increments) == start.MAX_PSEUDO_STEPS  # the first pseudo-step found none
    assert increments[-1] / increments[-2] == pytest.approx((height / critical) ** 3, rel=0.1)


@pytest.mark.slow
def test_the_frictional_stage_from_the_tall_grid_s_welded_equilibrium_leaves_dda_s_range_too():
    """Why the tall grid stays welded: a frictional pseudo-step from its welded equilibrium (the
    settled geometry, each contact as the welded stage hands it over: pulled ones open, those
    beyond their Coulomb strength locked at it) does not hold it either. The welded equilibrium
    holds the grid as one column by tension and shear across its vertical joints — the joint law
    opens half of their contacts and finds most of the others beyond their strength —, and
    without them its columns lean out (the outer column's top 1.16 m in 47 iterates) until 826
    contacts open at once and the iterate turns blocks near the top by 31 rad while the blocks it
    keeps overlap: out of DDA's range (`ddatai.mechanisms.out_of_range`), as the first
    pseudo-step from t = 0 (benchmarks/stage_from_welded.py,
    benchmarks/results/stage_divergence.md). ~12 s."""
    from ddatai.mechanisms import pseudo_time_step
    from ddatai.return_mapping import Frame
    from ddatai.threads import dense_solves

    model = _tall_grid()
    stepper = Stepper(model)
    welded, record = start.settle(stepper, model.initial_state(), welded=True)
    assert record.welded and record.held == model.n_free
    geom0 = model.block_geometry(model.initial_state().vertex_xy)
    size = np.sqrt(geom0["area"])
    released = np.zeros(model.n_blocks, bool)
    with dense_solves(stepper.solver):
        geom = model.block_geometry(welded.vertex_xy)
        cint, length = stepper.detect(welded.vertex_xy, welded.memory)
        contacts = Contacts.start(model, welded.vertex_xy, cint, length, welded.memory, True)
        dt = pseudo_time_step(stepper, geom0, size)
        frame = Frame.build(stepper, welded, geom, contacts, dt)
        assert not start.balanced(stepper, frame, contacts, geom, size)
        disp, solves, found, _, _, _, diverged = return_mapping.return_mapping(
            stepper, welded, geom, contacts, dt, released, size, frame, None, released.copy())
    assert disp is None and diverged and not found.any()
    assert solves < return_mapping.MAX_ITERATIONS
