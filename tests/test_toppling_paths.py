"""The slow-load reference of the stacks of square blocks depends on the loading path
(tests/toppling_cases.py, docs/guide/equilibrium_start.md, *The square stacks' slow loads by
path*).

The reference R of `tests/test_toppling_start.py` is the lowest tilt at which a gravity ramp
(10, 20 or 40 rocking time constants, both frames) topples a case. On the stacks of 0.1 m
squares the ramps that set R topple them before a fifth of their weight is on, and a tilting
table at full weight topples them 2–4.5° higher, at a tilt that depends on where the table
started. A single column has one threshold on every path (its closed form). So for the stacks
no start can lie within 0.5° of every slow load; these tests pin the measured paths (slow
profile: 20–80 s a run idle, 2–3 × that loaded).
"""

from __future__ import annotations

import math

import pytest

from toppling_cases import CASES, column, ramp_toppling_share, tilting_table

#: (case, tilt [degrees], frame, ramp [rocking time constants]): the lowest toppling loadings of
#: the scan (`SLOW_POINTS` of tests/test_toppling_start.py) -> the share of the weight on the
#: stack when it has toppled, measured (its motion starts at 3–8 % of the weight)
LOW_WEIGHT = {("squares 4-4-4", 22.1, "tilted", 40.0): 0.192, ("squares 4-4-4", 22.3, "turned", 40.0): 0.169,
              ("squares 3-4-5", 24.25, "turned", 40.0): 0.181,
              ("squares 4-5-6-7", 16.0, "turned", 40.0): 0.191}


@pytest.mark.slow
@pytest.mark.parametrize("name,theta,frame,ramp", list(LOW_WEIGHT))
def test_the_lowest_slow_loads_topple_the_square_stacks_before_a_fifth_of_their_weight_is_on(name, theta, frame, ramp):
    """The 40-constant ramps that set each stack's R topple it at 17–19 % of its weight (to
    0.01: the ramp's smoothstep when a vertex has moved 5 % of the tallest column), not under
    the weight that the start applies (a rigid block's toppling tilt does not depend on g; the
    4-4-4 stack at 22.3° stands under the start and the 10- and 20-constant ramps stand at
    22.6°). ~10–35 s a case idle."""
    share = ramp_toppling_share(CASES[name][0], theta, frame, ramp)
    assert share is not None, (name, theta)
    assert abs(share - LOW_WEIGHT[name, theta, frame, ramp]) < 0.01, share
    assert share < 0.2


#: a tilting table (`tilting_table`, 0.25°/s): (case, starting tilt) -> (the tilt range in which
#: it has toppled [degrees]); measured 26.88° and 24.47° for the 4-4-4 stack, 27.16° for 3-4-5,
#: 17.17° for 4-5-6-7, 22.12° for the column b/h = 0.4 (closed form 21.80°; the ~1 s fall lags
#: the tilt by ~0.3°)
TABLE = {("squares 4-4-4", 20.0): (26.5, 27.0), ("squares 4-4-4", 24.0): (24.3, 24.6),
         ("squares 3-4-5", 20.0): (26.9, 27.4), ("squares 4-5-6-7", 14.0): (17.0, 17.4),
         ("column 0.4", 20.0): (21.8, 22.3)}


@pytest.mark.slow
@pytest.mark.parametrize("name,theta0", list(TABLE))
def test_a_tilting_table_at_full_weight_topples_the_4_4_4_stack_where_its_start_decides(name, theta0):
    """Gravity ramped in at θ0, then the tilt raised at 0.25°/s at full weight: the column
    b/h = 0.4 topples at its closed form (plus the fall's lag) wherever the table starts; the
    4-4-4 squares, ramped in at 20°, lean (0.3–1.4 mm) and stand to 26.2° and topple at 26.9°,
    but ramped in at 24° they topple at 24.5° (0.125°/s: 24.4°). Against the start's 22.45°
    and the gravity ramps' 22.1°, the stack's slow-load threshold spans 22.1–26.9° by path.
    The 3-4-5 squares (from 20°) topple at 27.2° and the 4-5-6-7 (from 14°) at 17.2°: 3° and
    1.2° above their gravity ramps' R. ~80 s (4-4-4 and 3-4-5 from 20°), ~40 s (4-5-6-7),
    ~15 s (4-4-4 from 24°), ~25 s (column) idle."""
    case = column(0.4, 1.0) if name == "column 0.4" else CASES[name][0]
    lo, hi = TABLE[name, theta0]
    angle = tilting_table(case, theta0, hi + 0.5)
    assert not math.isnan(angle) and lo < angle <= hi, angle


@pytest.mark.slow
def test_the_low_weight_toppling_is_the_same_with_a_time_step_of_a_sixteenth():
    """The turned 40-constant ramp at 22.3° with Δt ≤ 0.6 ms (τ/160 of a square; 2,900 steps)
    topples the 4-4-4 squares at the same share of their weight as with the default 10 ms
    (0.167 against 0.169, both frames alike): the reference's low-weight toppling is not its
    time step's. ~1 min idle."""
    share = ramp_toppling_share(CASES["squares 4-4-4"][0], 22.3, "turned", 40.0, dt_max=6e-4)
    assert share is not None and abs(share - 0.167) < 0.01, share


@pytest.mark.slow
def test_tighter_open_close_tolerances_do_not_take_the_low_weight_toppling_away():
    """The open–close tolerances are fractions of a block's full weight (`Stepper.block_load`),
    so under a ramp at share s they are 1/s of the forces: 2.5 % at s = 0.04. With them 100×
    tighter (1e-5) the turned 40-constant ramp stands at 22.3° (35 µm), but topples the 4-4-4
    squares at 22.6° at 8 % of their weight (0.079; also 1e-6 in the tilted frame): the
    low-weight toppling is not their slack. ~20 s idle."""
    case = CASES["squares 4-4-4"][0]
    tight = dict(oc_force_tolerance=1e-5, oc_state_tolerance=1e-5)
    assert ramp_toppling_share(case, 22.3, "turned", 40.0, **tight) is None
    share = ramp_toppling_share(case, 22.6, "turned", 40.0, **tight)
    assert share is not None and abs(share - 0.079) < 0.01, share
