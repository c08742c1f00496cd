"""A small model's later pseudo-steps try Newton sooner (`ddatai.return_mapping.NEWTON_LATER`,
docs/method/dda.md §8.12): they start from the states the last pseudo-step handed over, so the
open-close iteration finishes them once an iterate after the first has changed no state, where
the first pseudo-step waits NEWTON_AFTER iterates. Against the stage that waits NEWTON_AFTER in
every pseudo-step (the reference): the same blocks held and released, welded or not, and the
settled vertices within the stage's own tolerance as a length, ``STAGE_FORCE_TOLERANCE`` × the
largest free block's size (the stage's equilibria differ by forces of that fraction of the load;
measured: at most 1e-8 m on Example II's 35 m blocks, 400 samples), with no more solves in all.
On Example I's group at 14° (held) and 8° (partly released), the first samples of Example II's
study (two held, two released by the screen) and random small models; the slow profile
(``-m slow``, ~6 s on 2 cores) takes the study's first 100 samples and 30 random scenes of each
kind."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from ddatai import return_mapping
from ddatai.model import SMALL_MODEL_BLOCKS
from ddatai.return_mapping import NEWTON_AFTER, STAGE_FORCE_TOLERANCE
from ddatai.start import settle
from ddatai.step import Stepper
from tests.test_stage_screen import FIRST_SAMPLES, group_model, random_model, study_members, study_samples


def _both(monkeypatch, model) -> tuple:
    """(state, record) of the stage as it is and of the reference (NEWTON_AFTER everywhere)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        now = settle(Stepper(model), model.initial_state())
        with monkeypatch.context() as m:
            m.setattr(return_mapping, "NEWTON_LATER", NEWTON_AFTER)
            reference = settle(Stepper(model), model.initial_state())
    return now, reference


def _compare(monkeypatch, models, fewer: bool = False) -> list:
    """Asserts the module docstring's outcome on each model (with ``fewer``, strictly fewer solves in
    all: the later pseudo-steps took the shorter path); returns the (held, released) of each."""
    out, solves, reference_solves = [], 0, 0
    for model in models:
        assert model.n_free <= SMALL_MODEL_BLOCKS
        (state, record), (ref_state, ref) = _both(monkeypatch, model)
        assert (record.held, record.released, record.welded, record.stalled) == \
            (ref.held, ref.released, ref.welded, ref.stalled)
        geom = model.block_geometry(model.initial_state().vertex_xy)
        size = float(np.sqrt(geom["area"][~model.block_fixed]).max())
        np.testing.assert_allclose(state.vertex_xy, ref_state.vertex_xy, rtol=0.0,
                                   atol=STAGE_FORCE_TOLERANCE * size)
        solves, reference_solves = solves + record.solves, reference_solves + ref.solves
        out.append((record.held, record.released))
    assert solves < reference_solves if fewer else solves <= reference_solves
    return out


def test_example_1_s_group_starts_as_with_newton_after_three_iterates(monkeypatch):
    from scenes import example_1

    outcomes = _compare(monkeypatch, [group_model(example_1, friction=f) for f in (14.0, 8.0)])
    assert outcomes[0][1] == 0 and outcomes[1][1] > 0


def test_the_study_s_first_samples_start_as_with_newton_after_three_iterates(monkeypatch):
    outcomes = _compare(monkeypatch, study_members(FIRST_SAMPLES), fewer=True)
    assert [released == 0 for _, released in outcomes] == [True, False, False, True]


@pytest.mark.parametrize("kind, seed", [("rock", 13), ("rock", 26), ("domain", 24)])
def test_random_small_models_start_as_with_newton_after_three_iterates(monkeypatch, kind, seed):
    """Two blocks held (12 solves before, 11 now), a stack of four half released after 147
    solves, a cut slope section of five, one held."""
    _compare(monkeypatch, [random_model(kind, seed)])


@pytest.mark.slow
def test_a_hundred_study_samples_start_as_with_newton_after_three_iterates(monkeypatch):
    outcomes = _compare(monkeypatch, study_members(study_samples(100)), fewer=True)
    assert sum(released == 0 for _, released in outcomes) > 20


@pytest.mark.slow
@pytest.mark.parametrize("kind", ["rock", "domain"])
def test_random_campaign_starts_as_with_newton_after_three_iterates(monkeypatch, kind):
    models = []
    for seed in range(30):
        try:
            model = random_model(kind, seed)
        except ValueError:  # refused before any work: nothing to start
            continue
        if model.n_free <= SMALL_MODEL_BLOCKS:
            models.append(model)
    _compare(monkeypatch, models)
