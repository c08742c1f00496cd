"""The limit-equilibrium programs of many members solved side by side (`ddatai.limit_batch`):
each member's answer is the one its program gets alone (`limit_equilibrium._solve_program`) to
the interior point's tolerance — the same blocks held, the same blocks moving in the mechanism —,
and each member's stage (`settle_many`) starts it as its own stage alone does (`settle`): the
same blocks held and released, the same solves, the same settled positions. On Example II's
probabilistic study (its first samples, which straddle the critical strength) and on Example I's
group across its critical friction."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ddatai import limit_batch, limit_equilibrium as le
from ddatai.mechanisms import screen_program
from ddatai.start import settle
from ddatai.step import Stepper
from test_stage_screen import group_model

ROOT = Path(__file__).resolve().parents[1]


def study_models(n: int) -> list:
    """The group's sub-model of the first ``n`` samples of Example II's study (seed 1)."""
    from kgm.studies.sampling import read_variables, sample_variables
    from scenes import example_2

    variables, correlation = read_variables(ROOT / "docs" / "kgm" / "example_2_vars.toml")
    samples = sample_variables(variables, n, seed=1, correlation=correlation)
    return [group_model(example_2, friction=float(samples["friction"][i]), cohesion=float(samples["cohesion"][i]))
            for i in range(n)]


def moving(y: np.ndarray) -> np.ndarray:
    """The blocks that move in the mechanism of a program's answer (`unsupported_blocks`, unit
    row scales: a two-block group's rows are of one order)."""
    v = np.abs(y).reshape(-1, 3).sum(axis=1)
    return v > le.MOVING * v.max(initial=0.0)


def test_programs_side_by_side_answer_as_each_alone():
    from scenes import example_1

    models = study_models(6) + [group_model(example_1, friction=f) for f in (9.0, 13.0)]
    programs = [screen_program(Stepper(m), m.initial_state()) for m in models]
    assert all(p is not None for p in programs)
    answers = limit_batch.solve_programs(programs)
    held = 0
    for p in programs:
        alone, together = le._solve_program(*p), answers[le.program_key(*p)]
        assert (alone is None) == (together is None)
        # Σ(r⁺ + r⁻) to the interior point's tolerance: the gap (1e-8 a complementarity pair) on
        # the program's few tens of pairs, well below the held/released line (HELD a block)
        assert abs(alone[0] - together[0]) <= 1e-5
        assert (alone[0] <= le.HELD * 2) == (together[0] <= le.HELD * 2)
        held += alone[0] <= le.HELD * 2
        if alone[0] > le.HELD * 2:
            np.testing.assert_array_equal(moving(alone[1]), moving(together[1]))
    assert 0 < held < len(programs)  # both sides of the critical strength


def test_settle_many_starts_each_member_as_its_own_stage():
    models = study_models(6)
    many = limit_batch.settle_many(models)
    released = 0
    for model, state in zip(models, many):
        alone, record = settle(Stepper(model), model.initial_state())
        released += record.released > 0
        np.testing.assert_array_equal(state.vertex_xy, alone.vertex_xy)
        for name in ("key", "state", "omega", "normal_force", "bond"):
            np.testing.assert_array_equal(getattr(state.memory, name), getattr(alone.memory, name))
    assert 0 < released < len(models)
    assert not le.PRIMED  # the answers solved ahead are dropped after the stages


def test_a_member_s_screen_is_done_once_in_its_batch(monkeypatch):
    """Inside `screened_ahead`, each member's screen is the one done there, once: its stage
    does not screen again, and the released blocks are those of its own screen alone."""
    from ddatai import mechanisms

    models = study_models(4)
    alone = [mechanisms.unsupported_at_start(Stepper(m), m.initial_state()) for m in models]
    calls = []
    programs = mechanisms.screen_programs
    monkeypatch.setattr(mechanisms, "screen_programs", lambda *a: calls.append(1) or programs(*a))
    steppers, states = [Stepper(m) for m in models], [m.initial_state() for m in models]
    with limit_batch.screened_ahead(steppers, states):
        assert len(calls) == len(models)
        for st, s, own in zip(steppers, states, alone):
            np.testing.assert_array_equal(mechanisms.unsupported_at_start(st, s), own)
            settle(st, s)
        assert len(calls) == len(models)  # the stages asked the batch's screens
        # another state of the same stepper is screened on its own
        moved = states[0].replace(vertex_xy=states[0].vertex_xy + 1e-9)
        mechanisms.unsupported_at_start(steppers[0], moved)
        assert len(calls) == len(models) + 1
    assert not mechanisms.SCREENED and not le.PRIMED
    assert any(own.any() for own in alone) and not all(own.any() for own in alone)


def test_members_share_the_first_detection_only_by_its_key():
    """`ddatai.batch_detect`: the members on one geometry detect once; each member's detections
    after adopting it (at t = 0 and at a settled geometry, through the kept pairs and their
    topology) are its own detection's to the bit; a model whose detection reads other data
    (another geometry, another search distance) keeps its own."""
    from dataclasses import replace

    from ddatai.batch_detect import detection_key, share_detection
    from ddatai.contacts import Contacts
    from ddatai.model import ContactMemory
    from scenes import example_1

    models = study_models(3)
    other = group_model(example_1, friction=12.0)
    wider = replace(models[0], search_distance=2.0 * models[0].search_distance)
    assert detection_key(wider, wider.vertex_xy0) != detection_key(models[0], models[0].vertex_xy0)
    batch = models + [other, wider]
    steppers, states = [Stepper(m) for m in batch], [m.initial_state() for m in batch]
    assert share_detection(steppers, states) == len(models) - 1
    assert len({detection_key(st.model, s.vertex_xy) for st, s in zip(steppers, states)}) == 3
    for st, s in zip(steppers, states):
        own = Stepper(st.model)
        free = ~st.model.block_fixed[st.model.vertex_block]
        settled = s.vertex_xy + np.where(free[:, None], [[1e-5, -2e-5]], 0.0)  # within the pairs' skin
        # the first pseudo-step's memory: the contacts at t = 0 (the narrow phase reads their keys)
        memory = Contacts.start(st.model, s.vertex_xy, *own.detect(s.vertex_xy), ContactMemory.empty(), True) \
            .memory(bond_breaks_on_slip=False)
        own = Stepper(st.model)
        for xy, last in ((s.vertex_xy, None), (settled, None), (settled, memory), (s.vertex_xy, memory)):
            for got, want in zip(st.detect(xy, last), own.detect(xy, last)):
                np.testing.assert_array_equal(got, want)
                assert got.dtype == want.dtype


def _lp_optimum(a, b, tan_phi, cohesion, tensile) -> float:
    """min Σ(r⁺ + r⁻) of the program (`limit_equilibrium._solve_program`) by SciPy's HiGHS
    (a simplex/interior-point code of its own): the reference."""
    from scipy.optimize import linprog
    from scipy.sparse import csr_matrix, diags, hstack, identity, vstack

    m, n = len(tan_phi), a.shape[0]
    one, none = identity(m), csr_matrix((m, m))
    # −N ≤ T·L, S − N·tanφ ≤ c·L, −S − N·tanφ ≤ c·L (x = N, S, r⁺, r⁻)
    upper = hstack([vstack([-one, -diags(tan_phi), -diags(tan_phi)]), vstack([none, one, -one]),
                    csr_matrix((3 * m, 2 * n))])
    out = linprog(np.r_[np.zeros(2 * m), np.ones(2 * n)], A_ub=upper.tocsr(), b_ub=np.r_[tensile, cohesion, cohesion],
                  A_eq=hstack([a, identity(n), -identity(n)]).tocsr(), b_eq=-b,
                  bounds=[(None, None)] * (2 * m) + [(0.0, None)] * (2 * n), method="highs")
    assert out.status == 0
    return float(out.fun)


def test_the_interior_point_answers_the_programs_optimum():
    """The interior point stops where its gap and equilibrium residual meet IPM_TOLERANCE and its
    dual residual does not (the steps after it lose the dual residual to round-off and diverge),
    at its best iterate: Σ(r⁺ + r⁻) is the program's optimum (HiGHS) to the interior point's
    tolerance — its best iterates' gap (≤ ~1e-7 a complementarity pair) on the program's few tens
    of pairs, and HiGHS's own (1e-7) — 1e-5, a half of the held/released line (HELD a block), side
    by side and alone, held and released members (Example II's first study samples, Example I's
    group either side of its critical friction)."""
    from scenes import example_1

    models = study_models(12) + [group_model(example_1, friction=f) for f in (9.0, 13.0)]
    programs = [screen_program(Stepper(m), m.initial_state()) for m in models]
    answers = limit_batch.solve_programs(programs)
    held = 0
    for p in programs:
        optimum = _lp_optimum(*p)
        for got in (answers[le.program_key(*p)], le._solve_program(*p)):
            assert abs(got[0] - optimum) <= 1e-5
        held += optimum <= le.HELD * 2
    assert 0 < held < len(programs)
