"""More of the equilibrium stage evaluated for many members at once (`ddatai.stage_batch_detect`
and the others registered with `ddatai.stage_batch`): every member's result must be, to the bit,
what its own call gives, whatever the members beside it."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from ddatai import stage_batch, stage_batch_detect, vectorized  # noqa: F401  (registers the operations)
from ddatai.layout import VV
from ddatai.model import build_model
from cases import random_jointed_scene
from test_vectorized import _last_keys, _moved, _passed_corners


def _constants(model):
    return (model.search_distance, model.max_penetration, math.radians(model.params.angle_tolerance))


def _narrow_calls():
    """Narrow-phase calls of many geometries: random jointed squares (vertex-edge and
    vertex-vertex contacts, concave blocks) at rest and moved, and the four squares whose
    diagonal corners passed each other, with and without the last step's keys (the
    persistent hand-over: a vertex-vertex pair read as two vertex-edge contacts)."""
    calls = []
    for seed in range(6):
        model = build_model(random_jointed_scene(seed))
        for k, shift in enumerate((0.0, 0.3, 1.0)):
            xy = _moved(model, 70 + seed + k, shift)
            keys = None
            if k == 2:  # the keys of the contacts at rest, another geometry's
                keys = _last_keys(model, vectorized.detect_contacts(model, model.vertex_xy0)[0])
            calls.append((model, xy, keys))
    model, deep, _, _ = _passed_corners(1e-4)
    handed = _last_keys(model, vectorized.detect_contacts(model, deep)[0])
    for depth in (1e-12, 0.0, 1e-4):
        _, xy, _, _ = _passed_corners(depth)
        calls += [(model, xy, handed), (model, xy, None)]
    return calls


def test_the_narrow_phase_over_many_members_gives_each_its_own_contacts():
    """`stage_batch_detect.narrow_phase_many` on the calls of each group of equal constants,
    every call's own pairs (its broad phase) and keys: each member's contacts and lengths
    equal its own call's to the bit, in its own order; the calls cover vertex-vertex contacts
    and keys that change what a member finds (so a key moved to another member's numbering
    would show)."""
    from ddatai.contacts import PairList

    calls = _narrow_calls()
    groups: dict = {}
    for model, xy, keys in calls:
        pairs = PairList().pairs(model, xy, vectorized.broad_phase)
        groups.setdefault(_constants(model), []).append((model, xy, pairs, keys))
    assert max(len(g) for g in groups.values()) >= 6
    vv = with_keys = 0
    for group in groups.values():
        if len(group) < 2:
            continue
        got = stage_batch_detect.narrow_phase_many([((m, xy, pairs, None, keys), {}) for m, xy, pairs, keys in group])
        for (m, xy, pairs, keys), (cint, length) in zip(group, got):
            want_cint, want_length = vectorized.narrow_phase.__wrapped__(m, xy, pairs, None, keys)
            assert cint.dtype == want_cint.dtype and length.dtype == want_length.dtype
            np.testing.assert_array_equal(cint, want_cint)
            np.testing.assert_array_equal(length, want_length)
            vv += int(np.count_nonzero(cint[:, 0] == VV))
            if keys is not None:
                plain, _ = vectorized.narrow_phase.__wrapped__(m, xy, pairs, None, None)
                with_keys += not np.array_equal(plain, cint)
    assert vv > 0 and with_keys > 0


def test_union_keys_keep_each_member_s_keys_apart_and_sorted():
    """A member's vertex-edge key a·n + b and vertex-vertex key n² + a·n + b in the union's
    numbering: sorted, and each the union's key of the same vertices."""
    rng = np.random.default_rng(3)
    n_vertices = np.array([7, 12, 5])
    at = np.array([0, 7, 19])
    keys, want = [], []
    for n, o in zip(n_vertices.tolist(), at.tolist()):
        a, b = rng.integers(0, n, 6), rng.integers(0, n, 6)
        vv = rng.random(6) < 0.5
        keys.append(np.sort(np.where(vv, n * n, 0) + a * n + b))
        want += [(int(v), a_ + o, b_ + o) for v, a_, b_ in zip(vv, a, b)]
    union = stage_batch_detect._union_keys(keys + [None], np.append(n_vertices, 4), np.append(at, 24), 28)
    assert np.all(np.diff(union) >= 0)
    total = 28
    expected = sorted((total * total if v else 0) + a * total + b for v, a, b in want)
    assert union.tolist() == expected
    assert stage_batch_detect._union_keys([None, np.zeros(0, np.int64)], n_vertices[:2], at[:2], 19) is None


@pytest.mark.parametrize("shift", [0.0, 1.0])
def test_the_narrow_phase_side_by_side_is_registered(shift):
    """`narrow.narrow_phase` is a side-by-side operation: members running side by side that
    reach it are evaluated together (and get their own contacts)."""
    from functools import partial

    from ddatai import side_by_side

    assert side_by_side._BATCHED["narrow_phase"][1] is stage_batch.narrow_phase_many
    if not side_by_side.available():
        pytest.skip("greenlet is not installed")
    model = build_model(random_jointed_scene(2))
    xys = [_moved(model, 90 + k, shift) for k in range(3)]
    before = side_by_side.EVALUATIONS.copy()
    got = side_by_side.run([partial(vectorized.detect_contacts, model, xy) for xy in xys])
    done = side_by_side.EVALUATIONS - before
    for xy, (cint, length) in zip(xys, got):
        want = vectorized.detect_contacts(model, xy)
        np.testing.assert_array_equal(cint, want[0])
        np.testing.assert_array_equal(length, want[1])
    assert done["narrow_phase", True] == (1 if model.numpy_path else 0)


@pytest.fixture(scope="module")
def members():
    """Example I's group at φ = 12° first (another geometry: every index of the others moved),
    then the first three samples of Example II's study."""
    from scenes import example_1
    from test_limit_batch import study_models
    from test_stage_screen import group_model

    return [group_model(example_1, friction=12.0)] + study_models(3)


def _random_states(models, seed):
    """Each model's initial state with random stresses, its blocks moved a little (another
    geometry each), and a random D of its free blocks."""
    rng = np.random.default_rng(seed)
    out = []
    for m in models:
        s = m.initial_state()
        xy = s.vertex_xy + rng.normal(0.0, 1e-3, s.vertex_xy.shape)
        s = s.replace(vertex_xy=xy, block_stress=rng.normal(0.0, 1e5, s.block_stress.shape),
                      block_rotation=rng.normal(0.0, 1e-3, m.n_blocks), geometry=None)
        disp = np.where(m.block_fixed[:, None], 0.0, rng.normal(0.0, 1e-3, (m.n_blocks, 6)))
        out.append((m, s, m.block_geometry(xy), disp))
    return out


def test_the_settlement_over_many_members_gives_each_its_own_state(members):
    """`stage_batch_frame.settle_points_many`: every field of each member's settled state
    (vertices, stresses, rotations, points, the block geometry at the moved vertices) equals
    its own call's to the bit."""
    from ddatai.kinematics import settle_points

    calls = _random_states(members, 5)
    got = stage_batch.settle_points_many([((m, s, g, d), {}) for m, s, g, d in calls])
    for (m, s, g, d), state in zip(calls, got):
        want = settle_points.__wrapped__(m, s, g, d)
        for name, value in vars(want).items():
            if isinstance(value, np.ndarray):
                np.testing.assert_array_equal(getattr(state, name), value, err_msg=name)
                assert getattr(state, name).dtype == value.dtype, name
            elif isinstance(value, dict):
                assert set(state.geometry) == set(value)
                for k, v in value.items():
                    np.testing.assert_array_equal(state.geometry[k], v, err_msg=k)
            elif isinstance(value, (int, float)):
                assert getattr(state, name) == value, name
        assert state.memory is s.memory
        assert not np.array_equal(state.vertex_xy, s.vertex_xy)  # it moved


def test_the_block_terms_over_many_members_give_each_its_own_k_and_f(members):
    """`stage_batch_frame.block_terms_many` (the stage's static system): each member's block part
    of K and F equals its own `assemble_blocks` call's to the bit, on patterns of other sizes
    (Example I's group and Example II's, their contacts at t = 0) and random stresses; a model
    with fixed points or point loads is left to its own call (no group)."""
    from ddatai.assembly import BlockPattern, assemble_blocks
    from ddatai.contacts import Contacts, subset_contacts
    from ddatai.model import ContactMemory
    from ddatai.step import Stepper

    calls = []
    for k, (m, s, g, _) in enumerate(_random_states(members, 9)):
        c = Contacts.start(m, s.vertex_xy, *Stepper(m).detect(s.vertex_xy), ContactMemory.empty(), True)
        if k == 1:  # its free blocks uncoupled: a pattern of another size
            c = subset_contacts(c, m.block_fixed[c.block_a] | m.block_fixed[c.block_b])
        calls.append((m, s, g, BlockPattern.build(m, c), 0.37, 0.5, True))
    assert len({p.nnz for *_, p, _, _, _ in calls}) >= 2
    assert len({stage_batch.block_terms_group(m, s, g, p, dt, beta, st) for m, s, g, p, dt, beta, st in calls}) == 1
    got = stage_batch.block_terms_many([(c, {}) for c in calls])
    for c, (data, rhs) in zip(calls, got):
        want_data, want_rhs = assemble_blocks.__wrapped__(*c)
        np.testing.assert_array_equal(data, want_data)
        np.testing.assert_array_equal(rhs, want_rhs)
        assert np.any(data != 0.0) and np.any(rhs != 0.0)
    m, s, g, p, *_ = calls[0]
    assert stage_batch.block_terms_group(m, s, g, p, 0.37, 0.5, False) is None  # a step's: not the stage's


def _start_calls():
    """`Contacts.start` calls of random jointed squares (vertex-vertex contacts among them) and of
    Example II's group: with no memory on the first step, and with a memory of the contacts at rest
    (random states — sliding ones re-anchored at their friction —, lines, bonds, forces) at
    moved vertices, on the first step and after it."""
    from ddatai.contacts import Contacts
    from ddatai.layout import LOCK, OPEN, SLIDE
    from ddatai.model import ContactMemory
    from ddatai.step import Stepper
    from test_limit_batch import study_models

    rng = np.random.default_rng(11)
    models = [build_model(random_jointed_scene(seed)) for seed in range(4)] + study_models(2)
    for k in (1, 2):  # joints of their own on some block pairs (``Model.pair_key``)
        m = models[k]
        pairs = np.unique(np.sort(m.vertex_block[vectorized.detect_contacts(m, m.vertex_xy0)[0][:, 1:3]], axis=1),
                          axis=0)[::2].astype(np.int64)
        models[k] = dataclasses.replace(m, pair_key=pairs[:, 0] * m.n_blocks + pairs[:, 1],
                                        pair_joint=rng.integers(0, len(m.joint_tan_phi), len(pairs)).astype(np.int32))
    calls = []
    for k, m in enumerate(models):
        st = Stepper(m)
        rest = Contacts.start(m, m.vertex_xy0, *st.detect(m.vertex_xy0), ContactMemory.empty(), True)
        calls.append((m, m.vertex_xy0, *st.detect(m.vertex_xy0), ContactMemory.empty(), True))
        rest.state[:] = rng.choice(np.array([OPEN, LOCK, SLIDE], np.int8), rest.n)
        rest.line[:] = rng.integers(0, 2, rest.n)
        rest.bond[:] = rng.random(rest.n) < 0.5
        rest.normal_force[:] = rng.uniform(0.0, 1e5, rest.n)
        rest.omega[:] = rng.uniform(0.0, 1.0, rest.n)
        rest.shear_dir[:] = rng.choice(np.array([-1, 1], np.int8), rest.n)
        memory = rest.memory(bond_breaks_on_slip=False)
        xy = _moved(m, 40 + k, 0.5)
        cint, length = vectorized.detect_contacts(m, xy)
        calls += [(m, xy, cint, length, memory, False), (m, xy, cint, length, memory, True)]
    return calls


def test_contacts_start_over_many_members_gives_each_its_own_contacts():
    """`stage_batch_contacts.contacts_start_many` on each group of calls with equal constants:
    every field of each member's contacts equals its own `Contacts.start`'s to the bit (the same
    ``cint`` and ``length`` objects handed back); the calls cover memories found and not,
    sliding contacts re-anchored, vertex-vertex contacts and members of other sizes."""
    from ddatai.contacts import Contacts
    from ddatai.layout import SLIDE, VV

    groups: dict = {}
    for c in _start_calls():
        key = stage_batch.start_group(*c)
        if key is not None:
            groups.setdefault(key, []).append(c)
    assert max(len(g) for g in groups.values()) >= 6
    seen_vv = seen_sliding = paired = 0
    for group in groups.values():
        if len(group) < 2:
            continue
        got = stage_batch.contacts_start_many([(c, {}) for c in group])
        for c, contacts in zip(group, got):
            want = Contacts.start.__wrapped__(*c)
            for name, value in vars(want).items():
                np.testing.assert_array_equal(getattr(contacts, name), value, err_msg=name)
                assert getattr(contacts, name).dtype == value.dtype, name
            assert contacts.cint is c[2] and contacts.length is c[3]
            seen_vv += int(np.count_nonzero(contacts.cint[:, 0] == VV))
            paired += len(c[0].pair_key) > 0
            seen_sliding += int(np.count_nonzero((contacts.state == SLIDE) & (c[4].key.size > 0)))
    assert seen_vv > 0 and seen_sliding > 0 and paired > 0


def test_the_open_close_terms_over_many_members_give_each_its_own(members):
    """`stage_batch_finish`'s operations on Example I's group and Example II's (other geometries
    and contact counts, some contacts sliding and coupled, a random D that rotates the blocks):
    each member's second-order shifts, lever arms and state test equal its own calls' to the bit;
    a member whose blocks do not rotate is left to its own call (its terms are zeros)."""
    from ddatai.assembly import contact_vectors, second_order
    from ddatai.contact_law import contact_law, violations_numpy
    from ddatai.contacts import Contacts, subset_contacts
    from ddatai.layout import SLIDE
    from ddatai.lever_arm import midstep_lever_arms
    from ddatai.model import ContactMemory
    from ddatai.step import Stepper

    calls = []
    for k, (m, s, g, disp) in enumerate(_random_states(members + members[:1], 13)):
        st = Stepper(m)
        c = Contacts.start(m, s.vertex_xy, *st.detect(s.vertex_xy), ContactMemory.empty(), True)
        c = subset_contacts(c, np.arange(c.n) < c.n - k % 3)  # other contact counts
        c.state[::3] = SLIDE
        c.coupled[::2] = True
        vec, sca = contact_vectors(m, s.vertex_xy, g, c)
        law = contact_law(m, c, vec, sca, disp)
        calls.append((m, s, g, c, disp[:, 2].copy(), law, st.block_load))
    assert len({c.n for _, _, _, c, *_ in calls}) >= 3
    ops = {"second_order": (lambda m, s, g, c, r, law, load: (m, c, s, g, r, np.zeros(6 * m.n_free)),
                            second_order, stage_batch.second_order_many, stage_batch.second_order_group),
           "lever": (lambda m, s, g, c, r, law, load: (m, c, s.vertex_xy, g["centroid"], r), midstep_lever_arms,
                     stage_batch.lever_arms_many, stage_batch.lever_arms_group),
           "violations": (lambda m, s, g, c, r, law, load: (m, c, law, load), violations_numpy,
                          stage_batch.violations_many, stage_batch.violations_group)}
    for name, (arguments, plain, many, group) in ops.items():
        groups: dict = {}
        for c in calls:
            groups.setdefault(group(*arguments(*c)), []).append(arguments(*c))
        assert None not in groups and max(len(g) for g in groups.values()) >= 3, name
        args = [a for g in groups.values() if len(g) > 1 for a in g]
        got = [out for g in groups.values() if len(g) > 1 for out in many([(a, {}) for a in g])]
        for a, out in zip(args, got):
            want = plain.__wrapped__(*a)
            for x, y in zip(out if isinstance(out, tuple) else (out,), want if isinstance(want, tuple) else (want,)):
                np.testing.assert_array_equal(x, y, err_msg=name)
                assert x.dtype == y.dtype and np.signbit(x).tolist() == np.signbit(y).tolist(), name
            assert np.any(want[0] if isinstance(want, tuple) else want), name  # not all zeros
    m, s, g, c, r, *_ = calls[0]
    assert stage_batch.second_order_group(m, c, s, g, np.zeros_like(r), None) is None
    assert stage_batch.lever_arms_group(m, c, s.vertex_xy, g["centroid"], np.zeros_like(r)) is None


def test_the_return_mapping_judgement_over_many_members_gives_each_its_own(members):
    """`stage_batch_finish.iterate_update_many` (a return-mapping iterate's judgement of its
    contacts) on members of other contact counts, with random guesses (closed contacts, lines,
    normal openings), flip counts, freezing on some members and not others, and the stage's law
    at a random D: every field of each member's judgement equals its own call's to the bit, and
    the members' contacts close, open and slip (the terms are not all trivial)."""
    from ddatai.assembly import contact_vectors
    from ddatai.contact_law import stage_law
    from ddatai.contacts import Contacts, subset_contacts
    from ddatai.layout import KIND, VE
    from ddatai.model import ContactMemory
    from ddatai.return_mapping import CHATTER_FLIPS, STAGE_FORCE_TOLERANCE, Guess
    from ddatai.return_update import iterate_update
    from ddatai.step import Stepper

    rng = np.random.default_rng(17)
    calls = []
    for k, (m, s, g, disp) in enumerate(_random_states(members + members[1:], 19)):
        c = Contacts.start(m, s.vertex_xy, *Stepper(m).detect(s.vertex_xy), ContactMemory.empty(), True)
        c = subset_contacts(c, np.arange(c.n) < c.n - k % 3)
        vec, sca = contact_vectors(m, s.vertex_xy, g, c)
        law = stage_law.__wrapped__(m, c, vec, sca, disp * 1e-3)
        guess = Guess(closed=rng.random(c.n) < 0.7, line=rng.integers(0, 2, c.n).astype(np.int8),
                      slip=np.zeros(c.n), gap=np.where(rng.random(c.n) < 0.3, rng.uniform(0, 1e-6, c.n), 0.0))
        ve = c.cint[:, KIND] == VE
        shearing = ve & ((c.tan_phi > 0.0) | ((c.cohesion * c.length > 0.0) & c.bond))
        weight = m.block_density * g["area"] * float(np.hypot(*m.gravity))
        tensile = np.where(c.bond, c.tensile * c.length, 0.0)
        calls.append((m, c, law, guess, rng.integers(0, 4, c.n), k % 2 == 0, shearing, weight, tensile,
                      min(m.params.oc_force_tolerance, STAGE_FORCE_TOLERANCE), CHATTER_FLIPS))
    groups: dict = {}
    for c in calls:
        groups.setdefault(stage_batch.iterate_update_group(*c), []).append(c)
    assert None not in groups and max(len(g) for g in groups.values()) >= 4
    flipped = slipped = gapped = 0
    for group in groups.values():
        got = stage_batch.iterate_update_many([(c, {}) for c in group])
        for c, out in zip(group, got):
            want = iterate_update.__wrapped__(*c)
            for name, x, y in zip(want._fields, out, want):
                np.testing.assert_array_equal(x, y, err_msg=name)
                assert x.dtype == y.dtype, name
            flipped += int(np.count_nonzero(want.flipped))
            slipped += int(np.count_nonzero(want.dslip))
            gapped += int(np.count_nonzero(want.gapping))
    assert flipped > 0 and slipped > 0 and gapped > 0
