"""What the fused engine leaves to today's path because of the parameters
(`ddatai.fused.policy`): it takes each iterate's lever arms, so a run or a kgm batch under
``Params(lever_arm_rotation="predicted")`` (docs/method/dda.md §5.3) runs on today's path,
even where ``kernels="fused"`` asks for it, and says why."""

from __future__ import annotations

import ddatai as dd
from ddatai.fused import policy


def _model(params):
    sc = dd.Scene(gravity=9.81)
    rock = dd.Material(density=2600.0, young=1e9, poisson=0.25)
    sc.add_block([(-1.0, -0.2), (1.0, -0.2), (1.0, 0.0), (-1.0, 0.0)], material=rock, fixed=True)
    sc.add_block([(0.0, 0.0), (0.2, 0.0), (0.2, 0.2), (0.0, 0.2)], material=rock)
    return dd.build_model(sc, params)


def test_predicted_lever_arms_run_on_today_s_path_with_their_reason(monkeypatch):
    monkeypatch.setattr(policy, "_loaded", lambda: True)
    for kernels in ("fused", "auto"):
        params = dd.Params(kernels=kernels, lever_arm_rotation="predicted")
        name, why = policy.choose(_model(params), steps=10 ** 6, duration=None, batch=True)
        assert name == "numpy" and "lever_arm_rotation='predicted'" in why
        name, why = policy.choose_batch(params, member_steps=1e9)
        assert name == "today" and "lever arms" in why
    iterate = dd.Params(kernels="fused")
    assert policy.choose(_model(iterate), steps=10, duration=None)[0] == "fused"
    assert policy.choose_batch(iterate, member_steps=10)[0] == "fused"
