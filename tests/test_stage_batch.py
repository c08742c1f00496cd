"""The equilibrium stages of a batch's members side by side (`ddatai.side_by_side`,
`ddatai.stage_batch`): each member's stage runs its own code, and the contact assembly, the
contact law and the block displacements of the members waiting at them are evaluated at once;
every member must come out as its own stage alone gives it, to the bit — the same blocks held
and released, the same solves, the same settled vertices and contact memory — on Example II's
study members (held and released ones) and Example I's group beside them (another geometry
in the same batch)."""

from __future__ import annotations

from functools import partial

import numpy as np
import pytest

from ddatai import limit_batch, side_by_side, stage_batch  # noqa: F401  (registers the stage's operations)
from ddatai.start import settle
from ddatai.step import Stepper
from test_limit_batch import study_models
from test_stage_screen import group_model

pytestmark = pytest.mark.skipif(not side_by_side.available(), reason="greenlet is not installed: the members "
                                "run one after the other (tests/test_limit_batch.py covers that)")

RECORD = ("held", "released", "solves", "factorisations", "at_strength", "settlement", "welded", "stalled",
          "unsettled", "turn_on_steps")


def assert_same(together, alone):
    (state, record), (ref_state, ref) = together, alone
    assert [getattr(record, k) for k in RECORD] == [getattr(ref, k) for k in RECORD]
    np.testing.assert_array_equal(state.vertex_xy, ref_state.vertex_xy)
    for name, value in vars(ref_state.memory).items():
        if isinstance(value, np.ndarray):
            np.testing.assert_array_equal(getattr(state.memory, name), value, err_msg=name)
    np.testing.assert_array_equal(state.block_stress, ref_state.block_stress)


@pytest.fixture(scope="module")
def members():
    """The first four samples of Example II's study (two held, two released) and Example I's
    group at φ = 12° (held: another geometry, the same constants)."""
    from scenes import example_1

    return study_models(4) + [group_model(example_1, friction=12.0)]


def test_stages_side_by_side_are_each_member_s_own_to_the_bit(members):
    models = members
    alone = [settle(Stepper(m), m.initial_state()) for m in models]
    before = side_by_side.EVALUATIONS.copy()
    together = side_by_side.run([partial(settle, Stepper(m), m.initial_state()) for m in models])
    for t, a in zip(together, alone):
        assert_same(t, a)
    held = [r.held > 0 for _, r in alone]
    assert any(held) and not all(held)  # both sides of the critical strength
    done = side_by_side.EVALUATIONS - before
    for name in ("assemble_contacts", "stage_law", "contact_law_numpy", "block_displacement"):
        assert done[name, True] > 0, name  # evaluated for several members at once


def test_settle_many_runs_the_members_side_by_side(members):
    models = members[:4]
    before = side_by_side.EVALUATIONS.copy()
    many = limit_batch.settle_many(models)
    assert sum((side_by_side.EVALUATIONS - before).values()) > 0
    for state, m in zip(many, models):
        ref, _ = settle(Stepper(m), m.initial_state())
        np.testing.assert_array_equal(state.vertex_xy, ref.vertex_xy)


def test_run_keeps_order_and_raises_a_member_s_error_after_the_others(monkeypatch):
    finished = []

    def member(k):
        if k == 1:
            raise ValueError("member 1")
        finished.append(k)
        return 10 * k

    with pytest.raises(ValueError, match="member 1"):
        side_by_side.run([partial(member, k) for k in range(4)])
    assert finished == [0, 2, 3]
    assert side_by_side.run([partial(member, k) for k in (0, 2, 3)]) == [0, 20, 30]
    assert not side_by_side.ACTIVE
    # a run inside a member runs its calls one after the other; without greenlet, all do
    assert side_by_side.run([lambda: side_by_side.run([partial(member, 2), partial(member, 3)]), lambda: 5]) == \
        [[20, 30], 5]
    monkeypatch.setattr(side_by_side, "_Member", False)
    assert not side_by_side.available()
    assert side_by_side.run([partial(member, k) for k in (3, 0)]) == [30, 0]


def test_an_operation_s_error_is_its_member_s_own(members):
    """Where the batched evaluation raises, each member is evaluated alone, and a member whose
    own call raises gets its error where it called, the others their results."""
    from ddatai.kinematics import block_displacement

    m = members[0]
    geom = m.block_geometry(m.vertex_xy0)
    disp = np.zeros((m.n_blocks, 6))
    disp[:, 0] = 1e-3

    def member(bad):
        try:
            return block_displacement(m, m.vertex_xy0, geom, disp[:1] if bad else disp)
        except IndexError:
            return "raised"

    out = side_by_side.run([partial(member, False), partial(member, True), partial(member, False)])
    assert out[1] == "raised"
    np.testing.assert_array_equal(out[0], block_displacement(m, m.vertex_xy0, geom, disp))
    np.testing.assert_array_equal(out[2], out[0])
