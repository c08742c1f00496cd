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
