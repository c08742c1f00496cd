"""Invalid input raises ValueError naming the offending block, joint or parameter before any
simulation work; a diverging run stops with an error naming the step and the cause and keeps
the frames recorded so far."""

import re

import numpy as np
import pytest

import ddatai as dd
from cases import G, ROCK, sliding_scene


def scene_with_block():
    scene = dd.Scene()
    scene.add_block([(0, 0), (1, 0), (1, 1), (0, 1)], material=ROCK)
    return scene


@pytest.mark.parametrize("kwargs, name", [
    (dict(density=-1.0, young=1e9, poisson=0.2), "density"),
    (dict(density=2500.0, young=0.0, poisson=0.2), "young"),
    (dict(density=2500.0, young=1e9, poisson=0.5), "poisson"),
    (dict(density=2500.0, young=1e9, poisson=-0.1), "poisson"),
    (dict(density=float("nan"), young=1e9, poisson=0.2), "density"),
])
def test_bad_material(kwargs, name):
    with pytest.raises(ValueError, match=name):
        dd.Material(**kwargs)


@pytest.mark.parametrize("kwargs, name", [
    (dict(friction=90.0), "friction"),
    (dict(friction=-1.0), "friction"),
    (dict(cohesion=-5.0), "cohesion"),
    (dict(tensile=-1.0), "tensile"),
])
def test_bad_joint(kwargs, name):
    with pytest.raises(ValueError, match=name):
        dd.Joint(**kwargs)


@pytest.mark.parametrize("kwargs, name", [
    (dict(dt=-0.01), "dt"), (dict(penalty=0.0), "penalty"), (dict(dt_cut=1.5), "dt_cut"),
    (dict(plane="axisymmetric"), "plane"), (dict(oc_max_iterations=1), "oc_max_iterations"),
    (dict(dynamic_ratio=2.0), "dynamic_ratio"), (dict(arch="tpu"), "arch"),
])
def test_bad_params(kwargs, name):
    with pytest.raises(ValueError, match=name):
        dd.Params(**kwargs)


def test_bad_block_polygons_name_the_block():
    scene = scene_with_block()
    with pytest.raises(ValueError, match="block 1.*self-intersecting"):
        scene.add_block([(0, 2), (2, 4), (2, 2), (0, 3)], material=ROCK)
    with pytest.raises(ValueError, match="block 1.*zero area"):
        scene.add_block([(0, 2), (1, 2), (2, 2)], material=ROCK)
    with pytest.raises(ValueError, match="block 1.*velocity"):
        scene.add_block([(0, 2), (1, 2), (1, 3)], material=ROCK, velocity=(1.0, np.inf))
    with pytest.raises(ValueError, match="block 1.*material"):
        scene.add_block([(0, 2), (1, 2), (1, 3)], material="granite")
    assert scene.n_blocks == 1  # nothing was added


def test_overlapping_blocks_are_named():
    scene = scene_with_block()
    scene.add_block([(0, 5), (1, 5), (1, 6)], material=ROCK)
    scene.add_block([(0.5, 0.5), (2, 0.5), (2, 2)], material=ROCK)
    with pytest.raises(ValueError, match="blocks 0 and 2 overlap"):
        dd.simulate(scene, steps=1)


def test_points_outside_their_block_and_unknown_ids():
    scene = scene_with_block()
    with pytest.raises(ValueError, match="outside block 0"):
        scene.add_fixed_point(0, (2.0, 0.5))
    with pytest.raises(ValueError, match="outside block 0"):
        scene.add_point_load(0, (0.5, 1.5), (1.0, 0.0))
    with pytest.raises(ValueError, match="unknown block id 3"):
        scene.add_point_load(3, (0.5, 0.5), (1.0, 0.0))
    with pytest.raises(ValueError, match="unknown block id"):
        scene.set_joint(dd.Joint(), between=(0, 7))
    with pytest.raises(ValueError, match="point load on block 0"):
        scene.add_point_load(0, (0.5, 0.5), (1.0, 2.0, 3.0))
    scene.add_point_load(0, (1.0, 1.0), (1.0, 0.0))  # on the boundary: allowed


def test_bad_joints_in_cut_are_named():
    scene = dd.Scene()
    with pytest.raises(ValueError, match="joint 1"):
        scene.cut([(0, 0), (2, 0), (2, 2), (0, 2)], [([(1, -1), (1, 3)], dd.Joint()),
                                                      ([(0, 1)], dd.Joint())], material=ROCK)
    with pytest.raises(ValueError, match="joint 0"):
        scene.cut([(0, 0), (2, 0), (2, 2), (0, 2)], [([(1, -1), (1, 3)], "weak")], material=ROCK)


def test_bad_ground_acceleration_and_run_arguments():
    scene = scene_with_block()
    with pytest.raises(ValueError, match="ground acceleration"):
        scene.set_ground_acceleration(lambda t: 3.0)
    with pytest.raises(ValueError, match="ground acceleration record"):
        scene.set_ground_acceleration(([0.0, 1.0, 0.5], [1.0, 2.0, 3.0]))
    with pytest.raises(ValueError, match="duration"):
        dd.simulate(scene)
    with pytest.raises(ValueError, match="duration"):
        dd.simulate(scene, duration=-1.0)
    with pytest.raises(ValueError, match="params"):
        dd.simulate(scene, params={"dt": 0.01}, steps=1)
    with pytest.raises(ValueError, match="no blocks"):
        dd.simulate(dd.Scene(), steps=1)


def test_nan_load_stops_with_step_and_cause():
    """A load that turns NaN at t > 0.05 s: the run stops at the first step that uses it,
    names the step and the cause, and keeps the frames recorded before it."""
    scene, block = sliding_scene(30.0, 40.0)
    scene.add_point_load(block, scene.polygon(block).mean(axis=0),
                         lambda t: (0.0, float("nan")) if t > 0.05 else (0.0, 0.0))
    with pytest.raises(dd.SimulationError, match=r"step 6 .*not finite") as info:
        dd.simulate(scene, params=dd.Params(dt=0.01), duration=1.0)
    err = info.value
    assert err.step == 6 and err.cause == "nan"
    assert err.results is not None and err.results.n_frames == 6
    assert err.results.time[-1] == pytest.approx(0.05)
    assert np.all(np.isfinite(err.results.centroid))


def test_open_close_failure_is_reported_not_accepted():
    """With the iteration cap at 2 and no room to cut the time step, a block landing on a base
    cannot converge: the run stops with cause 'open-close' instead of accepting the iterate."""
    scene = dd.Scene(gravity=G)
    scene.add_block([(-2, -1), (3, -1), (3, 0), (-2, 0)], material=ROCK, fixed=True)
    scene.add_block([(0, 0.01), (1, 0.01), (1, 1.01), (0, 1.01)], material=ROCK, velocity=(0.3, -1.0))
    scene.set_joint(dd.Joint(friction=30.0))
    params = dd.Params(dt=0.005, oc_max_iterations=2, dt_min_ratio=0.5)
    with pytest.raises(dd.SimulationError) as info:
        dd.simulate(scene, params=params, duration=0.5)
    assert info.value.cause == "open-close"
    assert "open-close iteration did not converge" in str(info.value)
    assert info.value.results.n_frames == info.value.step


def test_runaway_penetration_is_reported():
    """A penalty far too soft for a heavy block lets it sink: stopped as runaway penetration."""
    scene = dd.Scene(gravity=G)
    scene.add_block([(-2, -1), (3, -1), (3, 0), (-2, 0)], material=ROCK, fixed=True)
    scene.add_block([(0, 0), (1, 0), (1, 1), (0, 1)], material=ROCK)
    with pytest.raises(dd.SimulationError) as info:
        dd.simulate(scene, params=dd.Params(penalty=1e3, dt=0.01, dt_min_ratio=0.01), duration=1.0)
    assert info.value.cause == "penetration"
    msg = str(info.value)
    assert "runaway penetration" in msg
    assert "between blocks 0 and 1" in msg or "between blocks 1 and 0" in msg
    assert "Params.penalty" in msg  # what to change
    # the two numbers differ where they are printed
    pen, limit = re.search(r"penetration: ([0-9.e+-]+) m .* limit 2.5·g3·w0 = ([0-9.e+-]+) m", msg).groups()
    assert float(pen) > float(limit)
