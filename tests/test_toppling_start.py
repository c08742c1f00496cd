"""The equilibrium start never makes a model more stable than a slow load does
(tests/toppling_cases.py, docs/guide/equilibrium_start.md).

The reference for a toppling tilt is the same model loaded slowly from rest without the stage:
gravity ramped in at the fixed tilt over 20 rocking time constants (`ramp_topples`), the
loading path of the stage done dynamically. The start's toppling tilt must lie within 0.5° of
it and never above it (to the 0.05° to which the tests place it). Each case checks four runs
around ``x``, the upper end of the slow load's bracket measured by benchmarks/toppling_start.py:
the slow load topples at ``x`` and stands at ``x − 0.05°`` (so its angle R ∈ (x − 0.05°, x]), the
start topples at ``x`` (S ≤ x < R + 0.05°) and stands at ``x − 0.45°`` (S > R − 0.5°).

The runs that place the slow load's angle take 5–10 s each (a ramp of 20 rocking time
constants), so the comparisons are in the slow profile (``-m slow``: the two bracket checks
~15 s each idle; the family's bisections ~2 min a case idle, ~10 min loaded); the default run
checks the single column against its closed form tan θ = b/h from the default start on both
sides of it (~1 s each).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

import ddatai as dd
from toppling_cases import CASES, column, ramp_topples, scene, start_topples, threshold

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


#: case: x, the upper end of the slow gravity ramp's bracket [degrees] (benchmarks/toppling_start.py)
DEFAULT_CASES = {"column 0.4": 21.85, "row 3 x 0.25": 24.6}


@pytest.mark.slow
@pytest.mark.parametrize("name", DEFAULT_CASES)
def test_the_start_topples_within_half_a_degree_below_the_slow_load_never_above(name):
    """Four runs around the slow load's angle (~15 s idle, ~40 s loaded)."""
    case = CASES[name][0]
    x = DEFAULT_CASES[name]
    assert ramp_topples(case, x) and not ramp_topples(case, x - RESOLUTION)
    assert start_topples(case, x), f"the start holds {name} at {x}°, where a slow load topples it"
    assert not start_topples(case, x - BELOW + RESOLUTION), \
        f"the start topples {name} at {x - BELOW + RESOLUTION}°, {BELOW}° or more below the slow load"


#: cases where the start topples the stack well below the slow load (measured, bisection to
#: 0.2°): its stage stalls from a tilt on, and the open-close test of the out-of-balance
#: blocks does not converge, so they are released (in doubt) — or, before, handed over held
#: with forces out of balance that the first steps turned into toppling. Safe, not within
#: the band: the slow load holds these stacks 3–4° further (not met; docs/guide/equilibrium_start.md)
CONSERVATIVE = {"squares 3-4-5": (20.2, 24.25), "squares 4-5-6-7": (15.8, 19.0)}


@pytest.mark.slow
@pytest.mark.parametrize("name", list(CASES))
def test_toppling_family_start_against_slow_load(name):
    """Bisection of both angles (to RESOLUTION; ~2 min a case idle, ~10 min loaded): the start
    never above the slow load, S ≤ R + RESOLUTION; within BELOW under it, S > R − BELOW, but for
    the CONSERVATIVE cases (there S < R − BELOW, as measured); a single column's slow-load angle
    within 0.2° below the rigid closed form atan(b/h) (elastic contacts topple a little earlier
    than a rigid block, never later)."""
    case, lo, hi = CASES[name]
    ramp = threshold(lambda th: ramp_topples(case, th), lo, hi + 2.0, RESOLUTION)
    start = threshold(lambda th: start_topples(case, th), lo, hi, RESOLUTION)
    assert start <= ramp + RESOLUTION, (start, ramp)
    if name in CONSERVATIVE:
        assert start < ramp - BELOW, (start, ramp)
    else:
        assert start > ramp - BELOW, (start, ramp)
    closed = case.closed_form()
    if closed is not None:
        assert closed - 0.2 < ramp <= closed + RESOLUTION, (ramp, closed)
