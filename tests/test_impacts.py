"""Which approaches are impacts (docs/method/dda.md §4.6, `ddatai.impacts`): a contact that
closes within the step, not one that a solve already closed and that keeps compressing under
its load. The rocking block against Housner is tests/test_rocking.py."""

from __future__ import annotations

import dataclasses
import sys
from pathlib import Path

import numpy as np
import rocking_cases

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


def retakes(model, steps: int, run) -> tuple[np.ndarray, np.ndarray]:
    """(the solves of each retaken step's first try, of its retake) over ``steps`` steps of
    ``run(model, state, steps)``, which gives the step records' ``oc_total`` and
    ``oc_iterations`` (the accepted try's: the retake's)."""
    total, accepted = run(model, model.initial_state(), steps)
    again = total > accepted
    return total[again] - accepted[again], accepted[again]


def numpy_records(model, state, steps: int) -> tuple[np.ndarray, np.ndarray]:
    """``retakes``' records on the NumPy path."""
    from ddatai.step import Stepper

    stepper, rows = Stepper(model), []
    for _ in range(steps):
        state, record = stepper.step(state)
        rows.append((record.oc_total, record.oc_iterations))
    return tuple(np.array(rows).T)


def rocking_model():
    """The 0.5 × 2 m rocking block of tests/rocking_cases.py released at half its overturning
    angle, without the equilibrium stage; 150 steps hold its first two impacts (steps 52, 138)."""
    params = dd.Params(kernels="numpy", solver="dense", initial_equilibrium=False)
    return dd.build_model(rocking_cases.scene(0.5, 2.0, 0.5), params)


def test_the_impact_step_is_taken_again_from_the_first_try_s_states():
    """A rocking block's impact step (docs/method/dda.md §4.6): its first try starts from the
    step start's states (the old corner locked, the new one open) and takes three solves to
    find the new corner closed and the old one open; the retake from the plastic impact's
    velocity starts from those converged states (`ddatai.impacts.resumed`), which the projected
    velocity, turning the block about the new corner, satisfies at once: one solve (three when
    it started again from the step start's states). 0.4 s."""
    first, again = retakes(rocking_model(), 150, numpy_records)
    assert len(first) == 2, first
    assert np.all(first == 3), first
    assert np.all(again == 1), again
