"""The fused engine (`ddatai.fused`) against today's NumPy path, its reference.

Both run the same step: the same Δt rule, contacts, contact law, open-close iteration and line
search, update and energy. They differ in the order of their sums (the fused engine factorises
its system with a skyline LU, today's path with LAPACK) and so in round-off, which can tip a
contact across one of the open-close iteration's tolerances in a step: a solve more or less
there. Tolerance: a held model (all contacts locked, no contact near a tolerance) is a linear
system solved twice, and its positions agree to ~κ(K)·ε of the motion (1e-9 of the model's size
asked); a model that slides or falls follows the same path to the iteration's force tolerance
(``Params.oc_force_tolerance``, 1e-3 of the load), which over a run of n steps moves a block by
at most that share of its motion: 1e-3 of the largest displacement, plus 1e-9 of the size
(round-off). Verdicts (stable or not, held or moving) are equal.
"""

import dataclasses

import numpy as np
import pytest

import ddatai as dd
from ddatai.model import build_model
from ddatai.start import settle
from ddatai.step import Stepper
from scenes import example_1


def dropped_grid(n: int = 3):
    """n × n stiff blocks dropped 5 mm onto a fixed base: impacts, sliding, lock-slide changes."""
    s = dd.Scene(gravity=9.81)
    rock = dd.Material(density=2500.0, young=5e9, poisson=0.25)
    s.add_block([(-1, -1), (n + 1, -1), (n + 1, 0), (-1, 0)], material=rock, fixed=True)
    for j in range(n):
        for i in range(n):
            y = 0.005 + j * 1.001
            s.add_block([(i, y), (i + 1, y), (i + 1, y + 1), (i, y + 1)], material=rock)
    s.set_joint(dd.Joint(friction=30.0))
    return s, dd.Params(dt=1e-3)


def _numpy_run(model, state, steps):
    stepper = Stepper(model)
    records = []
    for _ in range(steps):
        state, record = stepper.step(state)
        records.append(record)
    return state, records


def _fused_run(model, state, steps):
    from ddatai.fused import engine
    from ddatai.fused.pack import Member

    out = engine.run([Member(model=model, state=state, step_end=state.step + steps, record=True)])[0]
    return out


CASES = {
    "example_1_held": (lambda: example_1.build(friction=14.0), True),
    "example_1_sliding": (lambda: example_1.build(friction=8.0), True),
    "dropped_grid": (dropped_grid, False),
}


@pytest.mark.parametrize("case", sorted(CASES))
def test_fused_steps_follow_the_numpy_path(case):
    """The same steps from the same state (after the NumPy path's equilibrium stage where the
    case starts from one): positions within the module's tolerance, the same Δt, solves within
    one a step."""
    build, stage = CASES[case]
    scene, params = build()
    params = dataclasses.replace(params or dd.Params(), kernels="numpy", solver="dense")
    model = build_model(scene, params)
    state = model.initial_state()
    if stage:
        state, _ = settle(Stepper(model), state)
    steps = 60
    ref, records = _numpy_run(model, state, steps)
    out = _fused_run(model, state, steps)
    assert out.status == "done" and out.state.step == state.step + steps
    size = float(np.ptp(model.vertex_xy0, axis=0).max())
    moved = float(np.abs(ref.vertex_xy - state.vertex_xy).max())
    assert np.abs(out.state.vertex_xy - ref.vertex_xy).max() <= 1e-3 * moved + 1e-9 * size
    np.testing.assert_allclose(out.records["dt"], [r.dt for r in records], rtol=1e-6)
    solves = np.array([r.oc_total for r in records])
    assert np.abs(out.records["oc_total"] - solves).max() <= 1
