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

import ddatai as dd
from ddatai import in_doubt
from toppling_cases import CASES, scene

#: a 0.1 m square's rocking time constant √(4R/(3g)), R = 0.1/√2 [s]
TAU_SQUARE = math.sqrt(4.0 * 0.1 / math.sqrt(2.0) / (3.0 * 9.81))


def test_a_stack_released_in_doubt_steps_at_a_resolved_time_step_and_rocks_away():
    """4-4-4 squares at 23.25°, 0.05 s: the stage releases 11 of the 12 blocks in doubt (one
    with certainty); every step is at most τ/80 = 1.23 ms (τ = 0.098 s, the squares' rocking
    time constant) where the default would grow to 10 ms, and at 0.05 s a vertex has moved
    more than 1.2 mm (1.56–1.69 mm with Δt ≤ 0.5–2 ms, and 1.66 mm with this rule; 0.81 mm with
    the default 10 ms, on the way to standing). ~1 s idle."""
    res = dd.simulate(scene(CASES["squares 4-4-4"][0], 23.25), duration=0.05)
    start = res.start[0]
    assert start["released"] == 12 and start["in_doubt"] == 11 and start["held"] == 0
    assert float(res.steps["dt"].max()) <= TAU_SQUARE / in_doubt.RESOLVE * (1 + 1e-9)
    assert float(np.abs(res.vertices[-1] - res.vertices[0]).max()) > 1.2e-3
