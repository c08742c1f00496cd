"""Which approaches are impacts (docs/method/dda.md §4.6, `ddatai.impacts`): a contact that
closes within the step, not one that a solve already closed and that keeps compressing under
its load. The rocking block against Housner is tests/test_rocking.py."""

from __future__ import annotations

import dataclasses
import sys
from pathlib import Path

import numpy as np
import pytest

import ddatai as dd


def test_closed_joints_loaded_suddenly_are_no_impacts():
    """ntdda's 2 × 2 grid of unit blocks resting in contact on a fixed base, gravity switched on
    at once (its scaling runs' sudden start): the joints are closed from the first step and
    compress while the grid rings on its springs. None of that is an impact, so no step is
    taken again from a plastic impact (before the rule asked for a contact open at the step's
    start: 10 of the first 12 steps, each solved twice). 0.7 s at a load of 2."""
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
    from scaling_scenes import grid_scene

    scene, params = grid_scene(4)
    res = dd.simulate(scene, params=dataclasses.replace(params, initial_equilibrium=False), steps=12,
                      record_every=10**9)
    s = res.steps
    assert len(s) == 12
    assert np.all(s["oc_total"] == s["oc_iterations"]), s["oc_total"] - s["oc_iterations"]


def _dropping_block(gap: float, speed: float, dt: float, dt_before_lead: float = 0.0):
    """A 1 m block of stiff rock ``gap`` above a fixed base, falling at ``speed``, in a run at a
    fixed Δt of 1 ms whose last step was ``dt`` long (``dt_before_lead``: `State`)."""
    from ddatai.step import Stepper

    scene = dd.Scene(gravity=9.81)
    rock = dd.Material(density=2500.0, young=5e9, poisson=0.25)
    scene.add_block([(-1, -1), (2, -1), (2, 0), (-1, 0)], material=rock, fixed=True)
    scene.add_block([(0, gap), (1, gap), (1, 1 + gap), (0, 1 + gap)], material=rock)
    scene.set_joint(dd.Joint(friction=30.0))
    model = dd.build_model(scene, dd.Params(dt=1e-3, initial_equilibrium=False))
    state = model.initial_state()
    velocity = state.block_velocity.copy()
    velocity[1, 1] = -speed
    return Stepper(model), state.replace(step=1, dt=dt, dt_before_lead=dt_before_lead, block_velocity=velocity)


def test_a_lead_step_does_not_hold_back_the_steps_after_it():
    """A lead step ends just before a contact closes (dda.md §4.6): its length says where the
    contact is, not what the open-close iteration can carry, so the next step's growth limit
    counts from the step before it (a failing slope's 5 µs lead step after a 0.1 ms step held
    its next seven steps below 0.032 ms, 3 solves each)."""
    stepper, state = _dropping_block(gap=5e-4, speed=1.0, dt=1e-3)
    lead = stepper.advance(state)
    assert lead.record.dt < 0.6e-3  # ends before the closing, ~0.5 ms away
    assert lead.state.dt_before_lead == 1e-3
    # in free flight after a 2 µs lead step: the 1 ms of the step before it, not 1.3 × 2 µs
    stepper, state = _dropping_block(gap=0.5, speed=0.0, dt=2e-6, dt_before_lead=1e-3)
    outcome = stepper.advance(state)
    assert outcome.record.dt == 1e-3 and outcome.state.dt_before_lead == 0.0
    stepper, state = _dropping_block(gap=0.5, speed=0.0, dt=2e-6)
    assert stepper.advance(state).record.dt == pytest.approx(1.3 * 2e-6, rel=1e-12)


def test_the_impact_step_keeps_the_growth_limit_of_the_run():
    """The impact step is τ = 20/√(p/m) long, at most what the time-step rule allows with its
    growth limit counted from the step before the lead step: a run that its open-close
    iteration holds at 0.1 ms does not jump to a 1 ms impact step (a failing slope's impact
    steps failed first there: 29–31 solves a step against ~10, cut to 0.3 and solved again).
    0.1 s."""
    stepper, state = _dropping_block(gap=0.0, speed=0.05, dt=1e-4)
    outcome = stepper.advance(state)
    assert outcome.record.dt == pytest.approx(1.3e-4, rel=1e-12)
    assert outcome.record.oc_total > outcome.record.oc_iterations  # the impact: taken again
    # the lead step before it does not hold it back: it grows from the 0.5 ms before that
    stepper, state = _dropping_block(gap=0.0, speed=0.05, dt=1e-6, dt_before_lead=5e-4)
    assert stepper.advance(state).record.dt == pytest.approx(1.3 * 5e-4, rel=1e-12)
