"""The first steps of blocks that the equilibrium stage released in doubt resolve their rocking
(`ddatai.in_doubt`, docs/guide/equilibrium_start.md "The start against a slow load").

The 4-4-4 stack of 0.1 m squares on a plate tilted 23.25° (tests/toppling_cases.py): the stage
releases its blocks in doubt, and under sudden gravity they topple with Δt ≤ 0.5, 1 and 2 ms
(at 0.31–0.35 s) and stand with the default 10 ms (2 mm in 0.17 s, then at rest), where a slow
load topples them. The slow profile's checks of the whole runs are in
tests/test_toppling_start.py.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

import ddatai as dd
from ddatai import in_doubt
from toppling_cases import CASES, released_in_doubt, scene

#: a 0.1 m square's rocking time constant √(4R/(3g)), R = 0.1/√2 [s]
TAU_SQUARE = math.sqrt(4.0 * 0.1 / math.sqrt(2.0) / (3.0 * 9.81))


def test_a_stack_released_in_doubt_steps_at_a_resolved_time_step_and_rocks_away():
    """4-4-4 squares at 23.25°, 0.05 s: the stage releases the 12 blocks, 10 or 11 of them in
    doubt as round-off has it (`toppling_cases.released_in_doubt`); every step is at most τ/160 = 0.61 ms (τ = 0.098 s, the squares' rocking
    time constant) where the default would grow to 10 ms, and at 0.05 s a vertex has moved
    more than 1.2 mm (1.56–1.69 mm with Δt ≤ 0.5–2 ms, and 1.66 mm with this rule; 0.81 mm with
    the default 10 ms, on the way to standing). ~1 s idle."""
    res = dd.simulate(scene(CASES["squares 4-4-4"][0], 23.25), duration=0.05)
    start = res.start[0]
    assert released_in_doubt(start, 12)
    assert float(res.steps["dt"].max()) <= TAU_SQUARE / in_doubt.RESOLVE * (1 + 1e-9)
    assert float(np.abs(res.vertices[-1] - res.vertices[0]).max()) > 1.2e-3


def _square_on_plate():
    """A 0.1 m square (τ = 0.098 s) on a fixed plate, its state with the square watched."""
    sc = dd.Scene(gravity=9.81)
    rock = dd.Material(density=2600.0, young=350e6, poisson=0.25)
    sc.add_block([(-1.0, -0.1), (1.0, -0.1), (1.0, 0.0), (-1.0, 0.0)], material=rock, fixed=True)
    sc.add_block([(0.0, 0.0), (0.1, 0.0), (0.1, 0.1), (0.0, 0.1)], material=rock)
    model = dd.build_model(sc)
    state = model.initial_state()
    return model, state.replace(in_doubt=in_doubt.watched(model, np.array([False, True])))


def test_the_watch_resolves_the_rocking_time_constant_and_ends_at_rest_or_when_moved_away():
    """`ddatai.in_doubt` on one square: Δt ≤ τ/160 while watched (the automatic Δt otherwise 10
    ms); watched before one τ even at rest; at rest (vertex speed < 1e-6·g·τ ≈ 1 µm/s) after τ
    the watch ends; moving at 1 mm/s after τ it goes on; moved 0.11 m (more than its size,
    0.1 m) the square leaves it; after 20 τ it ends whatever moves."""
    from ddatai.time_step import choose_time_step

    model, state = _square_on_plate()
    geom = model.block_geometry(state.vertex_xy)
    assert in_doubt.RESOLVE == 160.0
    assert in_doubt.time_step(model, state, geom) == pytest.approx(TAU_SQUARE / 160.0, rel=1e-12)
    assert choose_time_step(model, state, geom) <= TAU_SQUARE / 160.0 * (1 + 1e-12)
    assert choose_time_step(model, state.replace(in_doubt=np.zeros(0, bool)), geom) > 10 * TAU_SQUARE / 160.0
    early = state.replace(time=0.5 * TAU_SQUARE)
    assert in_doubt.follow(model, state, early).any()
    rest = state.replace(time=1.5 * TAU_SQUARE)
    assert not in_doubt.follow(model, state, rest).any()
    moving = rest.replace(block_velocity=np.array([[0.0] * 6, [1e-3, 0, 0, 0, 0, 0]]))
    assert in_doubt.follow(model, state, moving).any()
    assert not in_doubt.follow(model, state, moving.replace(time=20.5 * TAU_SQUARE)).any()
    away = moving.replace(vertex_xy=state.vertex_xy + np.where(model.vertex_block[:, None] == 1, 0.11, 0.0),
                          geometry=None)
    assert not in_doubt.follow(model, state, away).any()


def test_runs_with_blocks_released_in_doubt_leave_the_fused_engine_for_today_s_path(monkeypatch):
    """The fused engine has no resolved Δt for blocks released in doubt: `dd.simulate` asked for
    it (``Params(kernels="fused")``) runs the 4-4-4 stack at 23.25° on today's path and says
    why, and a kgm batch prepared for it (`kgm.judges.fused.run_prepared`) runs such a member on
    today's path from its settled start; the engine is never called with it (it is not loaded
    here: the stand-in below fails if it is). ~1 s idle."""
    from types import SimpleNamespace

    from ddatai.fused import engine
    from ddatai.fused.pack import Member
    from kgm.judges.fused import Prepared, run_prepared

    sc = scene(CASES["squares 4-4-4"][0], 23.25)
    res = dd.simulate(sc, dd.Params(kernels="fused"), steps=2)
    assert res.meta["engine"]["name"] == "numpy" and "in doubt" in res.meta["engine"]["why"]
    assert float(res.steps["dt"].max()) <= TAU_SQUARE / in_doubt.RESOLVE * (1 + 1e-9)

    from ddatai.start import settle
    from ddatai.step import Stepper

    model = dd.build_model(sc)
    state, record = settle(Stepper(model), model.initial_state())
    assert record.in_doubt >= 1 and state.in_doubt.sum() == record.in_doubt
    monkeypatch.setattr(engine, "run", lambda runs, arch="cpu": pytest.fail("the fused engine was called"))
    free = tuple(int(b) for b in np.flatnonzero(~model.block_fixed))
    run = Member(model=model, state=state, t_end=0.01, stop_at=0.05, rest_limit=-1.0, rest_steps=10, group=free)
    plan = SimpleNamespace(duration=0.01, delta=0.0125, params=dd.Params())
    [judgement] = run_prepared(Prepared(runs=[run], plans=[plan], fields=[dict(friction=38.0, reduction=1.0, model_blocks=model.n_blocks, moving_blocks=len(free), scene_blocks=model.n_blocks)], seconds=0.0))
    # today's path from the start: the whole 0.01 s at the resolved Δt (≥ 0.01 / 0.61 ms steps)
    assert judgement.simulated == pytest.approx(0.01) and judgement.steps >= 16
