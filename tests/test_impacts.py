"""Which approaches are impacts (docs/method/dda.md §4.6, `ddatai.impacts`): a contact that
closes within the step, not one that a solve already closed and that keeps compressing under
its load. The rocking block against Housner is tests/test_rocking.py."""

from __future__ import annotations

import dataclasses
import sys
from pathlib import Path

import numpy as np

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
