"""Rigid-block limit equilibrium of the touching blocks (`ddatai.limit_equilibrium`; docs/method/
dda.md §8.12), against closed forms: a block on a plane slides where tanφ < tanθ, and with
cohesion where W·sinθ > W·cosθ·tanφ + c·l; a column on a plane topples where its weight's line
leaves its base (b/h < tanθ) whatever its friction; a pushed block holds up to W·tanφ; a block
resting on one that slides goes with it; and the equilibrium stage releases exactly the blocks
that it lets move on the jointed slope, where the stage used to end welded."""

import functools
import math

import numpy as np
import pytest

import ddatai as dd
from ddatai import limit_equilibrium
from ddatai.contacts import Contacts
from ddatai.layout import OPEN
from ddatai.model import ContactMemory, build_model
from ddatai.start import settle
from ddatai.step import Stepper
from tests.cases import G, ROCK, block_on_incline, incline_base, incline_frame


def lets_move(model, stepper=None):
    """(B,) the blocks that limit equilibrium lets move at t = 0, over the contacts touching
    then (None: it does not apply)."""
    xy = model.vertex_xy0
    cint, length = (stepper or Stepper(model)).detect(xy)
    contacts = Contacts.start(model, xy, cint, length, ContactMemory.empty(), True)
    return limit_equilibrium.unsupported_blocks(model, xy, model.block_geometry(xy), contacts,
                                                contacts.state != OPEN, np.zeros(model.n_blocks, bool))


def unsupported(scene, params=None):
    """`lets_move` of the scene's model, as a sorted list of blocks (None: it does not apply)."""
    found = lets_move(build_model(scene, params or dd.Params(kernels="numpy")))
    return None if found is None else np.flatnonzero(found).tolist()


def plane(theta, friction, cohesion=0.0, width=1.0, height=1.0):
    scene = dd.Scene(gravity=G)
    incline_base(scene, theta)
    block = block_on_incline(scene, theta, at=4.0, width=width, height=height)
    scene.set_joint(dd.Joint(friction=friction, cohesion=cohesion))
    return scene, block


@pytest.mark.parametrize("theta", [20.0, 35.0])
def test_a_block_on_a_plane_slides_where_tan_phi_is_below_tan_theta(theta):
    """Sliding: held for φ = θ + 0.5°, released for φ = θ − 0.5° (no cohesion)."""
    scene, block = plane(theta, theta + 0.5)
    assert unsupported(scene) == []
    scene, block = plane(theta, theta - 0.5)
    assert unsupported(scene) == [block]


def test_cohesion_holds_a_block_up_to_its_closed_form():
    """W·sinθ = W·cosθ·tanφ + c·l: c* = ρ·g·h·(sinθ − cosθ·tanφ) for a block of base l and
    height h (the joint is bonded at t = 0, so its cohesion counts); 2 % either side."""
    theta, phi, h = 35.0, 20.0, 1.0
    t, p = math.radians(theta), math.radians(phi)
    critical = ROCK.density * G * h * (math.sin(t) - math.cos(t) * math.tan(p))
    scene, block = plane(theta, phi, cohesion=1.02 * critical)
    assert unsupported(scene) == []
    scene, block = plane(theta, phi, cohesion=0.98 * critical)
    assert unsupported(scene) == [block]


@pytest.mark.parametrize("height, topples", [(4.0, True), (2.0, False)])
def test_a_column_on_a_plane_topples_where_its_weight_leaves_its_base(height, topples):
    """θ = 20°, φ = 45° (no sliding), base b = 1 m: the weight's line leaves the base where
    b/h < tanθ = 0.364 — a 4 m column topples, a 2 m one stands."""
    scene, block = plane(20.0, 45.0, width=1.0, height=height)
    assert unsupported(scene) == ([block] if topples else [])


@pytest.mark.parametrize("ratio, held", [(0.98, True), (1.02, False)])
def test_a_pushed_block_holds_up_to_its_weight_times_tan_phi(ratio, held):
    """A 1 m block on a flat base pushed sideways at its centroid by F: held while F ≤ W·tanφ."""
    phi = 30.0
    scene = dd.Scene(gravity=G)
    scene.add_block([(-5, -1), (5, -1), (5, 0), (-5, 0)], material=ROCK, fixed=True)
    block = scene.add_block([(0, 0), (1, 0), (1, 1), (0, 1)], material=ROCK)
    scene.set_joint(dd.Joint(friction=phi))
    weight = ROCK.density * G * 1.0
    scene.add_point_load(block, (0.5, 0.5), (ratio * weight * math.tan(math.radians(phi)), 0.0))
    assert unsupported(scene) == ([] if held else [block])


def test_a_block_resting_on_a_sliding_one_goes_with_it():
    """Two blocks stacked on a 30° plane, the joint under the lower one at φ = 25° (it slides),
    the one between them at φ = 60° (the upper one alone would stay on the lower): both go, the
    second in the program solved after the first released the lower one — or in the same."""
    theta = 30.0
    scene = dd.Scene(gravity=G)
    base = incline_base(scene, theta)
    lower = block_on_incline(scene, theta, at=4.0, width=2.0, height=1.0)
    upper = block_on_incline(scene, theta, at=4.5, width=1.0, height=1.0, lift=1.0)
    scene.set_joint(dd.Joint(friction=60.0))
    scene.set_joint(dd.Joint(friction=25.0), between=(base, lower))
    assert unsupported(scene) == sorted([lower, upper])


def test_bolts_and_water_are_left_to_the_open_close_test():
    """The program does not carry bolt or water forces: it answers None."""
    scene, block = plane(30.0, 20.0)
    t, n = incline_frame(30.0)
    p = 4.5 * t + 0.5 * n
    scene.add_bolt(p, p - 0.8 * n, stiffness=1e8)
    assert unsupported(scene) is None


def test_the_stage_releases_what_limit_equilibrium_lets_move_on_the_jointed_slope():
    """scenes/jointed_slope.py: its bedding daylights, 25 of its 75 free blocks have no admissible
    contact forces (they slide), and the return mapping stalls on the rest (where Newton, the
    open-close iteration of a static step, finishes it or not by round-off: one thread or two).
    The stage releases those 25 (it used to end welded: every block held, each joint then at most
    at its strength), and where the open-close test of the blocks still out of balance does not
    converge, those 40 too (in doubt, release: docs/guide/equilibrium_start.md). Which of the two
    happens is round-off (threads, BLAS): it holds 50 and releases the 25, or holds 10 and
    releases 65; either way the run's first step moves no held block by more than its
    settlement."""
    from scenes import jointed_slope

    scene, params = jointed_slope.build()[:2]
    expected = unsupported(scene, params)
    assert len(expected) == 25
    res = dd.simulate(scene, params, steps=1)
    start = res.start[0]
    assert not start["welded"]
    assert (start["held"], start["released"]) in {(50, 25), (10, 65)}
    moved = np.hypot(*(res.centroid[-1] - res.centroid[0]).T)
    held = np.setdiff1d(np.flatnonzero(moved >= 0), expected)
    assert moved[held].max() <= max(start["settlement"], 1e-6)


@functools.lru_cache(maxsize=1)
def _jointed_slope_family_start():
    """The 400-block slope's start (~10 s), once for the two tests that read it."""
    from benchmarks.scaling import slope_scene

    scene, params = slope_scene(400)
    model = build_model(scene, params)
    stepper = Stepper(model)
    moving = lets_move(model, stepper)
    state, record = settle(stepper, model.initial_state())
    moved = np.zeros(model.n_blocks)
    np.maximum.at(moved, model.vertex_block, np.hypot(*(state.vertex_xy - model.vertex_xy0).T))
    released = (moved == 0.0) & ~model.block_fixed
    return record, moving, released


@pytest.mark.slow
def test_the_jointed_slope_family_starts_from_its_frictional_equilibrium():
    """The 400-block slope of the scaling benchmark (35° bedding out of a 60° face, φ = 28°;
    ~10 s): it used to start welded. The stage releases every block that limit equilibrium
    lets move (155 at t = 0) and hands the rest over as its converged test says, releasing
    those in doubt (docs/guide/equilibrium_start.md)."""
    record, moving, released = _jointed_slope_family_start()
    assert not record.welded
    assert released.sum() == record.released
    assert np.all(released[moving]) and moving.sum() >= 150


@pytest.mark.slow
@pytest.mark.xfail(strict=True, reason=(
    "in doubt, release: the open-close test of the blocks limit equilibrium leaves out of "
    "balance does not converge at this size, and the stage releases 387 of the 391 free blocks "
    "(155 let move) where it held more than 200 before the rule (docs/guide/equilibrium_start.md, "
    "'At scale: what the stage does not settle')"))
def test_the_jointed_slope_family_releases_at_most_a_tenth_more_than_limit_equilibrium():
    """A converged test of the blocks in doubt would hold most of them: at most a tenth more
    released than limit equilibrium lets move (~10 s)."""
    record, moving, released = _jointed_slope_family_start()
    assert record.held > 200
    assert released.sum() - moving.sum() <= 0.1 * moving.sum()


@pytest.mark.parametrize("case", ["plane held", "plane slides", "cohesion", "example_1 at 8", "jointed_slope"])
def test_dense_newton_steps_give_the_programs_of_the_sparse_ones(case, monkeypatch):
    """`limit_equilibrium.DENSE_ROWS`: a program of a few blocks takes its interior-point
    Newton steps with dense arrays, a large one with sparse ones. Both give the same blocks:
    planes either side of tanφ = tanθ and of the cohesion's closed form, Example I at 8° (B1 and
    B2 slide) and the jointed slope's 25 of 75."""
    from scenes import example_1, jointed_slope

    theta = 30.0
    t = math.radians(theta)
    critical = ROCK.density * G * (math.sin(t) - math.cos(t) * math.tan(math.radians(20.0)))
    scene = {"plane held": lambda: plane(theta, theta + 0.5)[0],
             "plane slides": lambda: plane(theta, theta - 0.5)[0],
             "cohesion": lambda: plane(theta, 20.0, cohesion=0.98 * critical)[0],
             "example_1 at 8": lambda: example_1.build(friction=8.0)[0],
             "jointed_slope": lambda: jointed_slope.build()[0]}[case]()
    dense = unsupported(scene)
    monkeypatch.setattr(limit_equilibrium, "DENSE_ROWS", 0)
    assert unsupported(scene) == dense
    expected = {"plane held": 0, "plane slides": 1, "cohesion": 1, "example_1 at 8": 2, "jointed_slope": 25}[case]
    assert len(dense) == expected


def test_the_median_is_numpys_to_the_bit():
    """`limit_equilibrium.median` (the program's unit force, the stage's pseudo time step) gives
    ``np.median``'s float, odd and even counts, ties and a column of a 2-D array; NaN of none."""
    rng = np.random.default_rng(7)
    for n in range(1, 12):
        for values in (rng.lognormal(size=n) * 1e5, np.round(rng.uniform(size=n), 1), rng.normal(size=(n, 2))[:, 1]):
            assert limit_equilibrium.median(values) == float(np.median(values))
    assert np.isnan(limit_equilibrium.median(np.zeros(0)))
