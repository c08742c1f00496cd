"""A study's samples that differ only in their joints share what depends on their geometry alone
(`ddatai.memo.scene_key`): the block system's joint-free part (`kgm.build.build_block_system`)
and a batch's sub-model (`kgm.judges.fused.prepare_fused`, `ddatai.model.Model.with_joints`).
Each sample still gets its own strengths, to the bit what it gets built alone, and samples whose
geometry differs share nothing."""

import importlib.util
from dataclasses import fields, replace
from pathlib import Path

import numpy as np

import ddatai as dd
from ddatai.memo import scene_key
from ddatai.model import build_model
from kgm import build as kgm_build
from kgm.judges.batch import Member
from kgm.judges.fused import prepare_fused
from kgm.judges.run import RunPlan, sub_scene
from kgm.settings import DdaSettings

ROOT = Path(__file__).resolve().parents[1]
GROUP = frozenset({0, 1})


def _example_2():
    spec = importlib.util.spec_from_file_location("example_2_scene", ROOT / "scenes" / "example_2.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod.build


def _same(a, b) -> bool:
    if isinstance(a, np.ndarray):
        return isinstance(b, np.ndarray) and a.dtype == b.dtype and a.shape == b.shape and a.tobytes() == b.tobytes()
    if isinstance(a, float) and isinstance(b, float) and np.isnan(a) and np.isnan(b):
        return True
    return a == b


def _assert_same(x, y):
    for f in fields(x):
        assert _same(getattr(x, f.name), getattr(y, f.name)), f.name


def _two_joint_lines(scene, f1: float, f2: float):
    """The scene with block 0's and 1's edges on joint 1 and block 2's on joint 2 (friction f1
    and f2): a contact between blocks 0 and 2 takes the weaker of the two."""
    scene.joints = [scene.joints[0], dd.Joint(friction=f1, cohesion=1e4), dd.Joint(friction=f2, cohesion=3e4)]
    scene.blocks = [replace(s, edge_joint=np.full(len(s.vertices), 1 if b < 2 else 2, np.int64))
                    for b, s in enumerate(scene.blocks)]
    return scene


def test_scene_key_says_geometry_not_joints():
    build = _example_2()
    a, _ = build(friction=20.0, cohesion=1e4)
    b, _ = build(friction=25.0, cohesion=3e4)
    c, _ = build(cross_joint_offset=2.5)
    assert scene_key(a) is not None and scene_key(a) == scene_key(b)
    assert scene_key(a) != scene_key(c)
    d, _ = build()
    inside = tuple(np.mean(d.blocks[0].vertices, axis=0))
    d.add_point_load(0, inside, (0.0, -1e3))
    e, _ = build()
    e.add_point_load(0, inside, (0.0, np.nextafter(-1e3, 0.0)))  # one ulp apart
    assert scene_key(d) != scene_key(e) and scene_key(d) != scene_key(a)
    a.set_ground_acceleration(lambda t: (0.1 * t, 0.0))
    assert scene_key(a) is None  # a function: never taken for another scene


def test_block_systems_share_geometry_and_keep_their_joints():
    build = _example_2()
    kgm_build._SYSTEMS.clear()
    warm = [kgm_build.build_block_system(_two_joint_lines(build()[0], f1, f2))
            for f1, f2 in ((30.0, 20.0), (20.0, 30.0))]
    assert kgm_build._SYSTEMS.hits == 1 and kgm_build._SYSTEMS.misses == 1
    # the contacts between blocks 0 and 2 take the weaker joint: another joint at each strength
    pair = np.all(warm[0].contact_blocks == (0, 2), axis=1)
    assert pair.any() and np.all(warm[0].contact_joint[pair] == 2) and np.all(warm[1].contact_joint[pair] == 1)
    assert np.all(warm[0].contact_friction[pair] == 20.0) and np.all(warm[1].contact_friction[pair] == 20.0)
    assert not _same(warm[0].contact_cohesion, warm[1].contact_cohesion)
    for (f1, f2), got in zip(((30.0, 20.0), (20.0, 30.0)), warm):
        kgm_build._SYSTEMS.clear()
        _assert_same(got, kgm_build.build_block_system(_two_joint_lines(build()[0], f1, f2)))
    other = kgm_build.build_block_system(build(cross_joint_offset=2.5)[0])
    assert kgm_build._SYSTEMS.misses == 2 and not _same(other.vertex_xy, warm[0].vertex_xy)


def test_a_batch_shares_its_sub_model_across_samples_of_one_geometry():
    build = _example_2()
    params = dd.Params(dt=0.0013, penalty_ratio=1.0, kernels="fused")
    settings = DdaSettings(params=params)
    scenes = [build(friction=f, cohesion=c)[0] for f, c in ((22.0, 2e4), (19.0, 1e4))] + \
        [build(friction=22.0, cohesion=2e4, cross_joint_offset=2.5)[0]]
    members = [Member(scene=s, system=kgm_build.build_block_system(s)) for s in scenes]
    prepared = prepare_fused(members, GROUP, settings=settings)
    models = [run.model for run in prepared.runs]
    assert models[1].vertex_xy0 is models[0].vertex_xy0  # one build for the first two
    assert models[2].vertex_xy0 is not models[0].vertex_xy0 and not _same(models[2].vertex_xy0, models[0].vertex_xy0)
    for m, model in zip(members, models):
        plan = RunPlan.of(m.system, GROUP, settings)
        sub, _ = sub_scene(m.scene, m.system, GROUP, free_neighbours=plan.free_neighbours)
        _assert_same(model, build_model(sub, plan.params))  # each with its own joints, to the bit
    assert models[0].joint_friction[0] == 22.0 and models[1].joint_friction[0] == 19.0


def test_a_screen_matrix_built_again_is_a_copy_of_the_same():
    """The limit-equilibrium matrix of one geometry, kept for the next member's screen
    (``ddatai.limit_equilibrium._kept_matrix``), is the one built afresh, handed out as a copy."""
    from ddatai import limit_equilibrium as le

    rng = np.random.default_rng(3)
    m, nb = 6, 3
    args = (np.arange(m), rng.integers(0, nb, m), rng.integers(0, nb, m), rng.random((m, 2)), rng.random((m, 2)),
            rng.random((m, 2)), rng.random((nb, 2)), np.array([0, 1, -1]), 6, rng.random(6) + 0.5)
    le._MATRICES.clear()
    first = le._kept_matrix(*args)
    first.data[:] = np.nan  # a caller's change does not reach the next caller
    again = le._kept_matrix(*args)
    fresh = le._equilibrium_matrix(*args)
    assert len(le._MATRICES) == 1
    for f in ("data", "indices", "indptr"):
        assert _same(getattr(again, f), getattr(fresh, f))
    other = le._kept_matrix(*args[:-1], args[-1] * 2.0)
    assert len(le._MATRICES) == 2 and not _same(other.data, fresh.data)
