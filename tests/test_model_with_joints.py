"""`ddatai.model.Model.with_joints`: the model of a scene with other joints, without building the
blocks again (kgm's fused judgements build a batch's sub-model once, `kgm.judges.fused`), is the
model `build_model` gives for that scene, every field to the bit."""

from dataclasses import fields

import numpy as np
import pytest

from ddatai.model import build_model
from ddatai.params import BartonBandis, Joint
from kgm.build import prepare
from kgm.judges.run import RunPlan, sub_scene
from kgm.settings import DdaSettings
from scenes import example_1


def _same(a, b) -> bool:
    if isinstance(a, np.ndarray):
        return a.dtype == b.dtype and a.shape == b.shape and a.tobytes() == b.tobytes()
    return a == b or (a is None and b is None)


@pytest.mark.parametrize("friction,reduction", [(None, 1.0), (7.5, 1.0), (None, 1.37), (23.0, 0.8)])
def test_with_joints_is_build_model(friction, reduction):
    scene, params = example_1.build()
    problem = prepare(scene, params=params)
    blocks = frozenset({0, 1})
    prm = RunPlan.of(problem.system, blocks, DdaSettings(), params).params
    base_sub, ids = sub_scene(scene, problem.system, blocks, friction=20.0, reduction=1.5)
    sub, ids2 = sub_scene(scene, problem.system, blocks, friction=friction, reduction=reduction)
    assert ids == ids2
    derived = build_model(base_sub, prm).with_joints(sub.joints)
    built = build_model(sub, prm)
    assert not _same(build_model(base_sub, prm).joint_tan_phi, built.joint_tan_phi)  # the joints do differ
    for f in fields(built):
        assert _same(getattr(derived, f.name), getattr(built, f.name)), f.name


def test_with_joints_barton_and_count():
    scene, params = example_1.build()
    model = build_model(scene, params)
    n = len(model.joint_friction)
    barton = [BartonBandis(jrc=8.0, jcs=50e6, residual_friction=25.0)] * n
    scene.joints = barton
    assert _same(model.with_joints(barton).joint_barton, build_model(scene, params).joint_barton)
    assert model.with_joints(barton).with_joints([Joint(friction=30.0)] * n).joint_barton.shape == (0, 6)
    with pytest.raises(ValueError, match="joints"):
        model.with_joints([Joint(friction=30.0)] * (n + 1))
