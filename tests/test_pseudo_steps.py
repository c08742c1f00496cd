"""The equilibrium stage's pseudo-steps (`ddatai.start`, docs/method/dda.md §8.12) are a
fixed-point iteration on the geometry: each solves the static increment at the last one's settled
shape, without the geometric stiffness of the blocks' own weight. Its increments therefore shrink
by the ratio of the weight to the buckling weight, q·H³ / (7.837·E·I) for a free-standing column
under its own weight (Greenhill: the critical height l = 1.986·(E·I/q)^(1/3)), and it stops
contracting — the stage ends ``unsettled`` — exactly where the column buckles under its weight.
Checked on stacks of ntdda's soft grid (E = 100 MPa, ρ = 2000 kg/m³), 8 blocks wide, whose
monolithic critical height is 59.7 m."""

import numpy as np
import pytest

import ddatai as dd
from ddatai import start
from ddatai.model import build_model
from ddatai.step import Stepper
from tests.test_start import soft_stack, stacked_grid

WIDTH = 8.0          # m
DENSITY, YOUNG = 2000.0, 1e8
#: Greenhill's critical height of a clamped column of this width under its own weight [m]
CRITICAL_HEIGHT = 1.986 * (YOUNG * WIDTH ** 2 / 12.0 / (DENSITY * 9.81)) ** (1.0 / 3.0)


def _settled_with_increments(monkeypatch, model) -> tuple[list, object]:
    """The stage of ``model`` and its pseudo-steps' increments (each one's largest block move) [m]."""
    increments = []
    measure = start.block_displacement

    def logged(model, xy, geom, disp):
        out = measure(model, xy, geom, disp)
        increments.append(float(out.max(initial=0.0)))
        return out

    monkeypatch.setattr(start, "block_displacement", logged)
    _, record = start.settle(Stepper(model), model.initial_state())
    return increments, record


def _increments(monkeypatch, height: int) -> tuple[list, object]:
    scene, params = soft_stack(int(WIDTH), height)
    return _settled_with_increments(monkeypatch, build_model(scene, params))


@pytest.mark.parametrize("height", [40, 64])
def test_the_pseudo_steps_contract_by_the_weight_over_the_buckling_weight(monkeypatch, height):
    """The ratio of the second and third pseudo-steps' increments is (H / l_cr)³ within 10 %
    (the joints add E/p = 10 % to the blocks' compliance, so the stack is a little softer than a
    monolithic column): 0.30 at 40 m, which settles, 1.23 at 64 m, where the stage stops
    contracting and ends unsettled, every block held."""
    increments, record = _increments(monkeypatch, height)
    ratio = increments[2] / increments[1]
    greenhill = (height / CRITICAL_HEIGHT) ** 3
    assert ratio == pytest.approx(greenhill, rel=0.1)
    assert record.unsettled == (greenhill > 1.0)
    assert record.held == int(WIDTH) * height and not record.welded


@pytest.mark.slow
def test_a_grid_past_its_buckling_weight_ends_unsettled_before_its_divergence_throws_blocks():
    """ntdda's 40 × 40 soft grid with E/4 and the penalty /16 (its pseudo-steps' contraction ratio
    ∝ ρ·g·H³/p, 16 × the unscaled grid's 0.25: the 160 × 160 grid's regime): the first
    pseudo-step holds every block (0.90 m of settlement); the second, at the settled geometry,
    moves the held blocks 2.0 m and throws the two base-corner blocks, whose contacts there sink
    beyond the penetration limit, and releasing them released 1,597 of the 1,600 blocks. A
    pseudo-step that would release blocks while its held blocks move at least as far as the last
    increment does not contract (``ddatai.mechanisms.contracting``): the stage ends at the first
    pseudo-step's equilibrium, every block held (``unsettled``), as where nothing is thrown.
    ~10 s (the stage: 126 solves)."""
    soft = dd.Material(density=DENSITY, young=YOUNG / 4.0, poisson=0.25)
    model = build_model(stacked_grid(40, 40, soft), dd.Params(dt=1e-3, penalty=1e9 / 16.0, plane="stress"))
    with pytest.MonkeyPatch.context() as patch:
        increments, record = _settled_with_increments(patch, model)
    assert record.unsettled and not record.welded
    assert record.held == model.n_free and record.released == 0
    # the stage ends at the first pseudo-step's equilibrium: its settlement is that increment
    assert len(increments) == 1 and record.settlement == pytest.approx(increments[0], rel=1e-9)


def _first_pseudo_step(model, contraction: float):
    """`return_mapping.return_mapping` on the model as given, as the stage's pseudo-steps call
    it, with ``contraction`` as the last pseudo-step's increment [m]."""
    from ddatai.contacts import Contacts
    from ddatai.mechanisms import pseudo_time_step
    from ddatai.model import ContactMemory
    from ddatai.return_mapping import return_mapping

    stepper = Stepper(model)
    state = model.initial_state()
    geom = model.block_geometry(state.vertex_xy)
    size = np.sqrt(geom["area"])
    cint, length = stepper.detect(state.vertex_xy, ContactMemory.empty())
    contacts = Contacts.start(model, state.vertex_xy, cint, length, ContactMemory.empty(), True)
    return return_mapping(stepper, state, geom, contacts, pseudo_time_step(stepper, geom, size),
                          np.zeros(model.n_blocks, bool), size, contraction=contraction)


def test_a_pseudo_step_whose_held_blocks_do_not_contract_releases_nothing():
    """`tests.test_start.partly_failing_scene`: block A slides down its 30° plane (φ = 25°), B and
    C hold, settling by microns. A pseudo-step whose held blocks move less than the last
    increment (here 1 m) releases A, as the first pseudo-step does; one whose held blocks move
    at least as far (here 1e-12 m: the pseudo-steps do not contract, `mechanisms.contracting`)
    releases nothing and hands no equilibrium back: the stage then ends at the last
    pseudo-step's (``unsettled``)."""
    from tests.test_start import partly_failing_scene

    scene, a, b, c = partly_failing_scene()
    model = build_model(scene, dd.Params(dt=1e-3))
    disp, _, found, _, _, diverging, _ = _first_pseudo_step(model, contraction=1.0)
    assert disp is not None and not diverging
    assert found[a] and not found[b] and not found[c]
    disp, _, found, _, _, diverging, _ = _first_pseudo_step(model, contraction=1e-12)
    assert disp is None and diverging and not found.any()
