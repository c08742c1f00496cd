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
    for name in ("assemble_contacts", "stage_law", "contact_law_numpy", "block_displacement", "contact_vectors",
                 "narrow_phase", "settle_points", "block_terms", "contacts_start", "second_order",
                 "midstep_lever_arms", "violations", "iterate_update"):
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


def test_each_operation_over_many_members_gives_each_its_own_floats(members):
    """`ddatai.stage_batch`'s operations on members with other contact counts (Example II's
    group at three strengths, its contacts at t = 0 less one or two, locked, some sliding with
    coupled friction, a random D): every field of each member's result, its K data and F, and
    its contact vectors equal its own call's to the bit."""
    from ddatai.assembly import BlockPattern, assemble_blocks, assemble_contacts, contact_vectors
    from ddatai.contact_law import contact_law_numpy, stage_law
    from ddatai.contacts import Contacts
    from ddatai.kinematics import block_displacement
    from ddatai.layout import SLIDE
    from ddatai.model import ContactMemory

    from ddatai.return_mapping import subset_contacts

    rng = np.random.default_rng(7)
    calls = []
    for k, m in enumerate(members[:3]):
        st, s = Stepper(m), m.initial_state()
        c = Contacts.start(m, s.vertex_xy, *st.detect(s.vertex_xy), ContactMemory.empty(), True)
        c = subset_contacts(c, np.arange(c.n) < c.n - k)  # other contact counts
        c.state[::3] = SLIDE
        c.coupled[::2] = True
        c.normal_force[:] = rng.uniform(0.0, 1e5, c.n)
        geom = m.block_geometry(s.vertex_xy)
        vec, sca = contact_vectors(m, s.vertex_xy, geom, c)
        pattern = BlockPattern.build(m, c)
        data, rhs = assemble_blocks(m, s, geom, pattern, 1.0, 0.5, static_start=True)
        disp = np.where(m.block_fixed[:, None], 0.0, rng.normal(0.0, 1e-4, (m.n_blocks, 6)))
        calls.append((m, c, vec, sca, disp, geom, pattern, data, rhs))
    assert len({c.n for _, c, *_ in calls}) == 3
    # one group: the constants that members evaluated together share
    assert len({stage_batch._law_group(m, c, vec, sca, disp) for m, c, vec, sca, disp, *_ in calls}) == 1
    assert len({stage_batch._assembly_group(m, c) for m, c, *_ in calls}) == 1
    law = {"stage_law": (stage_law, stage_batch.stage_law_many),
           "contact_law_numpy": (contact_law_numpy, stage_batch.contact_law_many)}
    for plain, many in law.values():
        together = many([((m, c, vec, sca, disp), {}) for m, c, vec, sca, disp, *_ in calls])
        for (m, c, vec, sca, disp, *_), got in zip(calls, together):
            want = plain.__wrapped__(m, c, vec, sca, disp)
            for name, value in vars(want).items():
                if isinstance(value, np.ndarray):
                    np.testing.assert_array_equal(getattr(got, name), value, err_msg=name)
                else:
                    assert getattr(got, name) == value, name
    alone = [(data.copy(), rhs.copy()) for *_, data, rhs in calls]
    for (m, c, vec, sca, _, _, pattern, _, _), (data, rhs) in zip(calls, alone):
        assemble_contacts.__wrapped__(m, c, pattern, vec, sca, data, rhs, False)
    stage_batch.assemble_contacts_many([((m, c, pattern, vec, sca, data, rhs, False), {})
                                        for m, c, vec, sca, _, _, pattern, data, rhs in calls])
    for (*_, data, rhs), (want_data, want_rhs) in zip(calls, alone):
        np.testing.assert_array_equal(data, want_data)
        np.testing.assert_array_equal(rhs, want_rhs)
    # and Example I's group first (another geometry: every index of the others moved)
    first = members[-1]
    c = Contacts.start(first, first.vertex_xy0, *Stepper(first).detect(first.vertex_xy0), ContactMemory.empty(), True)
    geom = first.block_geometry(first.vertex_xy0)
    others = [(first, c, *contact_vectors(first, first.vertex_xy0, geom, c), None, geom)] + calls
    vectors = stage_batch.contact_vectors_many([((m, m.vertex_xy0, geom, c), {}) for m, c, _, _, _, geom, *_ in others])
    for (m, c, vec, sca, _, geom, *_), (got_vec, got_sca) in zip(others, vectors):
        np.testing.assert_array_equal(got_vec, vec)
        np.testing.assert_array_equal(got_sca, sca)
    moved = stage_batch.block_displacement_many([((m, m.vertex_xy0, geom, disp), {})
                                                 for m, _, _, _, disp, geom, *_ in calls])
    for (m, _, _, _, disp, geom, *_), got in zip(calls, moved):
        np.testing.assert_array_equal(got, block_displacement.__wrapped__(m, m.vertex_xy0, geom, disp))


def test_f_alone_is_the_full_assembly_s_f_and_k_is_kept_while_states_stay(members):
    """The contact assembly asked for F alone (``data`` None: the return mapping's iterates whose
    K has not changed, `reassembly.ContactSystem`) gives the F of the full assembly to the bit,
    alone and side by side beside members that ask for K too (and again from the members' kept
    indices, `ddatai.stage_batch_index`); ContactSystem keeps the last K while the contacts'
    states stay, and assembles it again, the same as a fresh one, once they change."""
    from ddatai.assembly import BlockPattern, assemble_blocks, assemble_contacts, contact_vectors
    from ddatai.contacts import Contacts
    from ddatai.layout import OPEN, SLIDE
    from ddatai.model import ContactMemory
    from ddatai.reassembly import ContactSystem

    rng = np.random.default_rng(11)
    calls = []
    for m in members[:3]:
        st, s = Stepper(m), m.initial_state()
        c = Contacts.start(m, s.vertex_xy, *st.detect(s.vertex_xy), ContactMemory.empty(), True)
        c.state[::3] = SLIDE
        c.coupled[::2] = True
        c.normal_force[:] = rng.uniform(0.0, 1e5, c.n)
        geom = m.block_geometry(s.vertex_xy)
        vec, sca = contact_vectors(m, s.vertex_xy, geom, c)
        sca = sca + rng.normal(0.0, 1e-5, sca.shape)
        pattern = BlockPattern.build(m, c)
        data, rhs = assemble_blocks(m, s, geom, pattern, 1.0, 0.5, static_start=True)
        calls.append((m, c, pattern, vec, sca, data, rhs))
    full = []
    for m, c, pattern, vec, sca, data, rhs in calls:
        d, r = data.copy(), rhs.copy()
        assemble_contacts.__wrapped__(m, c, pattern, vec, sca, d, r, False)
        r_alone = rhs.copy()
        assemble_contacts.__wrapped__(m, c, pattern, vec, sca, None, r_alone, False)
        np.testing.assert_array_equal(r_alone, r)
        full.append((d, r))
    assert len({stage_batch._assembly_group(*call) for call in calls}) == 1
    for ask_k in ([True, False, True], [False] * 3, [False] * 3):
        got = [(data.copy() if k else None, rhs.copy()) for k, (*_, data, rhs) in zip(ask_k, calls)]
        stage_batch.assemble_contacts_many([((m, c, pattern, vec, sca, d, r, False), {})
                                            for (m, c, pattern, vec, sca, _, _), (d, r) in zip(calls, got)])
        for (d, r), (want_d, want_r) in zip(got, full):
            np.testing.assert_array_equal(r, want_r)
            if d is not None:
                np.testing.assert_array_equal(d, want_d)
    m, c, pattern, vec, sca, data, rhs = calls[0]
    system = ContactSystem(m, pattern, vec, data, rhs, False)
    k0, f0 = system.system(c, sca)
    k1, f1 = system.system(c, sca + 1e-6)
    assert k1 is k0 and system.kept == 1 and system.full == 1
    want = rhs.copy()
    assemble_contacts.__wrapped__(m, c, pattern, vec, sca + 1e-6, data.copy(), want, False)
    np.testing.assert_array_equal(f1, want)
    c.state[1] = OPEN
    k2, _ = system.system(c, sca)
    want_k = data.copy()
    assemble_contacts.__wrapped__(m, c, pattern, vec, sca, want_k, rhs.copy(), False)
    assert k2 is not k0 and system.full == 2
    np.testing.assert_array_equal(k2, want_k)
    assert not np.array_equal(k2, k0)
