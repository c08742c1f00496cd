"""The equilibrium start never makes a model more stable than a slow load does
(tests/toppling_cases.py, docs/guide/equilibrium_start.md).

The reference for a toppling tilt is the same model loaded slowly from rest without the stage:
gravity ramped in at the fixed tilt over 20 rocking time constants and held for 8
(`ramp_topples`), the loading path of the stage done dynamically; for the Goodman–Bray slope,
its critical friction angle under the same ramp. The start's angle must lie within 0.5° of it
and never on the stable side (to the 0.05° to which the tests place it). Where the stage
cannot decide (limit equilibrium holds every block, the return mapping stalls), the start
settles its doubt by the same slow turn-on (`ddatai.turn_on`), so a start near a stack's
threshold costs about as much as the reference.

The runs that place the slow load's angle take 5–40 s each, so the comparisons are in the slow
profile (``-m slow``: the bracket checks ~1 min a case idle, 2–4 min loaded; the family's
bisections ~5 min a case idle, ~15 min loaded); the default run checks the single column
against its closed form tan θ = b/h from the default start on both sides of it (~1 s each) and
the turn-on on a small column on both sides of its threshold.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

import ddatai as dd
from toppling_cases import (CASES, column, gb_ramp_fails, gb_start_fails, ramp_topples, scene, start_topples,
                             threshold)

#: the slow load's angle is placed to this [degrees]
RESOLUTION = 0.05
#: the start's angle may lie this far below the slow load's [degrees]
BELOW = 0.5


def test_a_slender_column_past_its_threshold_topples_from_the_default_start():
    """b/h = 0.4 (0.4 × 1.0 m, E 10 GPa, ρ 2600 kg/m³, φ 45°) on a plate tilted 23.5°, past its
    rigid threshold atan(0.4) = 21.8° (tan 23.5° = 0.435 > 0.4): the stage releases it and it
    topples from the default start under `dd.simulate` (its top moves more than 0.05 m within
    0.8 s: a column 1.7° past its threshold falls as 0.03·(cosh(t/τ) − 1) rad, τ = 0.27 s)."""
    res = dd.simulate(scene(column(0.4, 1.0), 23.5), duration=0.8)
    assert res.start["released"][0] == 1
    assert float(np.abs(res.vertices[-1] - res.vertices[0]).max()) > 0.05


def test_a_slender_column_short_of_its_threshold_stands_from_the_default_start():
    """The same column at 21.3°, 0.5° short of atan(0.4): the stage holds it, and it moves less
    than 0.1 mm in 0.8 s (its elastic settlement): the start does not topple a column that the
    closed form and the slow load hold (they topple it between 21.80° and 21.85°, the table of
    docs/guide/equilibrium_start.md)."""
    res = dd.simulate(scene(column(0.4, 1.0), 21.3), duration=0.8)
    assert res.start["released"][0] == 0 and res.start["held"][0] == 1
    assert float(np.abs(res.vertices[-1] - res.vertices[0]).max()) < 1e-4


#: case: the slow gravity ramp's bracket (lo stands, hi topples) [degrees], measured by bisection
#: to 0.05° (benchmarks/toppling_start.py). The 3-4-5 stack's is its lowest toppling tilt: the
#: ramp's outcome there is not monotone in the tilt (it topples at 24.25°, stands at 24.5–25.0°
#: and topples again from 25.03°, where bisection from 12–28° lands; docs/guide/equilibrium_start.md)
SLOW_LOAD = {
    "column 0.4": (21.80, 21.85),
    "row 3 x 0.25": (24.5703, 24.5977),
    "stair 0.25": (27.5781, 27.6055),
    "squares 3-4-5": (24.20, 24.25),
    "squares 4-5-6-7": (18.8125, 18.8594),
    "squares 4-4-4": (22.0527, 22.0859),
}


@pytest.mark.slow
@pytest.mark.parametrize("name", SLOW_LOAD)
def test_the_start_topples_within_half_a_degree_below_the_slow_load_never_above(name):
    """Four runs around the slow load's bracket (lo, hi]: the ramp stands at lo and topples at
    hi (its angle R in (lo, hi]); the start topples at hi (S ≤ hi < R + 0.05°: never above, to
    the bracket's width) and stands at lo − 0.45° (S > R − 0.5°). ~1 min a case idle, 2–4 min
    loaded (each start of a stack near its threshold runs the slow turn-on, ~700 steps)."""
    case = CASES[name][0]
    lo, hi = SLOW_LOAD[name]
    assert hi - lo <= RESOLUTION + 1e-9
    assert ramp_topples(case, hi) and not ramp_topples(case, lo)
    assert start_topples(case, hi), f"the start holds {name} at {hi}°, where a slow load topples it"
    assert not start_topples(case, lo - BELOW + RESOLUTION), \
        f"the start topples {name} at {lo - BELOW + RESOLUTION}°, {BELOW}° or more below the slow load"


#: the Goodman–Bray slope at 1:100 (`toppling_cases.goodman_bray`): the slow ramp's bracket of
#: the critical friction angle (it fails at lo, holds at hi) [degrees], bisection to 1/32°;
#: the rigid-block limit equilibrium's 38.15° lies in it
GB_SLOW_LOAD = (38.125, 38.15625)


@pytest.mark.slow
def test_the_start_fails_the_goodman_bray_slope_wherever_a_slow_load_does_and_within_half_a_degree():
    """Never more stable than the slow load: the start fails the slope at the highest friction
    at which the ramp does (lo), and holds it 0.45° above the ramp's hi (its critical friction
    within 0.5° of the slow load's). ~2 min idle."""
    lo, hi = GB_SLOW_LOAD
    assert gb_ramp_fails(lo) and not gb_ramp_fails(hi)
    assert gb_start_fails(lo), f"the start holds the slope at φ = {lo}°, where a slow load fails it"
    assert not gb_start_fails(hi + BELOW - RESOLUTION), \
        f"the start fails the slope at φ = {hi + BELOW - RESOLUTION}°, {BELOW}° or more above the slow load"


@pytest.mark.slow
@pytest.mark.parametrize("name", list(CASES))
def test_toppling_family_start_against_slow_load(name):
    """Bisection of both angles (to RESOLUTION; ~5 min a case idle, ~15 min loaded): the start
    never above the slow load, S ≤ R + RESOLUTION, and within BELOW under it, S > R − BELOW,
    R the bisection's (for the 3-4-5 stack, whose slow load is not monotone in the tilt, its
    lowest toppling tilt, SLOW_LOAD); a single column's slow-load angle within 0.2° below the
    rigid closed form atan(b/h) (elastic contacts topple a little earlier than a rigid block,
    never later)."""
    case, lo, hi = CASES[name]
    ramp = threshold(lambda th: ramp_topples(case, th), lo, hi + 2.0, RESOLUTION)
    start = threshold(lambda th: start_topples(case, th), lo, hi, RESOLUTION)
    lowest = min(ramp, SLOW_LOAD.get(name, (ramp, ramp))[1])
    assert start <= lowest + RESOLUTION, (start, ramp, lowest)
    assert start > lowest - BELOW, (start, ramp, lowest)
    closed = case.closed_form()
    if closed is not None:
        assert closed - 0.2 < ramp <= closed + RESOLUTION, (ramp, closed)


def _turn_on_of(theta: float, b: float = 0.02, h: float = 0.08):
    """`ddatai.turn_on.turn_on` of a b × h column (E 10 GPa, φ 45°) on a plate tilted by
    ``theta``, nothing released; and the model."""
    from ddatai.step import Stepper
    from ddatai.turn_on import turn_on

    model = dd.build_model(scene(column(b, h), theta))
    return turn_on(Stepper(model), model.initial_state(), np.zeros(model.n_blocks, bool), 0.01), model


def test_the_slow_turn_on_hands_over_a_standing_column_at_rest_and_gives_up_on_a_toppling_one():
    """A 0.02 × 0.08 m column (rigid threshold atan(0.25) = 14.04°): 1° short of it the turn-on
    (28 rocking time constants √(4R/3g) = 0.075 s: 2.1 s, ~210 steps) ends with the column
    settled by its elastic settlement (< 1e-5 m: its weight on 10 GPa rock and the contact
    springs), at rest at t = 0; 1° past it the column rocks away on its corner and the turn-on
    gives up (the stage then releases it)."""
    held, model = _turn_on_of(13.0)
    assert held is not None
    state, released, steps = held
    assert not released.any()
    assert state.time == 0.0 and state.step == 0 and steps > 100
    assert np.all(state.block_velocity == 0.0)
    assert float(np.abs(state.vertex_xy - model.vertex_xy0).max()) < 1e-5
    assert _turn_on_of(15.0)[0] is None
