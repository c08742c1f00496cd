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


def _grid(n_free: int, params):
    """``n_free`` unit blocks in rows of 14 on a fixed base (no run: the choice reads the model)."""
    sc = dd.Scene(gravity=9.81)
    rock = dd.Material(density=2600.0, young=1e9, poisson=0.25)
    sc.add_block([(-1.0, -1.0), (15.0, -1.0), (15.0, 0.0), (-1.0, 0.0)], material=rock, fixed=True)
    for k in range(n_free):
        i, j = k % 14, k // 14
        sc.add_block([(i, j), (i + 1, j), (i + 1, j + 1), (i, j + 1)], material=rock)
    return dd.build_model(sc, params)


def test_auto_runs_a_single_model_fused_up_to_its_measured_size(monkeypatch):
    """``Params(kernels="auto")`` runs a single simulation of at most ``FUSED_BLOCKS`` free blocks
    on the fused engine where the run pays the kernel, and a larger one on today's path, saying
    why: the limit lies above the NumPy path's (``SMALL_MODEL_BLOCKS``), so between the two a
    model that does not run fused runs on the Taichi kernels (the limit measured where the fused
    step stops paying against them, benchmarks/results/fused_threshold.md)."""
    from ddatai.model import SMALL_MODEL_BLOCKS

    monkeypatch.setattr(policy, "_loaded", lambda: True)
    assert SMALL_MODEL_BLOCKS < policy.FUSED_BLOCKS
    params = dd.Params()
    at, above = _grid(policy.FUSED_BLOCKS, params), _grid(policy.FUSED_BLOCKS + 1, params)
    assert (at.n_free, above.n_free) == (policy.FUSED_BLOCKS, policy.FUSED_BLOCKS + 1)
    name, why = policy.choose(at, steps=2000, duration=None)
    assert name == "fused" and "in this process" in why
    name, why = policy.choose(above, steps=2000, duration=None)
    assert name == "taichi" and f"{policy.FUSED_BLOCKS + 1} free blocks" in why and str(policy.FUSED_BLOCKS) in why
    # asked for, or a batch: the fused engine at any size
    assert policy.choose(above, steps=10, duration=None, batch=True)[0] == "fused"
    asked = _grid(policy.FUSED_BLOCKS + 1, dd.Params(kernels="fused"))
    assert policy.choose(asked, steps=10, duration=None)[0] == "fused"
    # a model of the size loaded from the offline cache: a run pays the load only where it is long
    monkeypatch.setattr(policy, "_loaded", lambda: False)
    monkeypatch.setattr(policy, "kernel_cached", lambda arch="cpu": True)
    name, why = policy.choose(at, steps=2000, duration=None)
    assert name == "taichi" and "do not pay" in why
    assert policy.choose(at, steps=int(policy.LOAD_SECONDS / policy.STEP_SAVING), duration=None)[0] == "fused"


def test_a_mid_sized_model_pays_the_kernel_s_load_in_fewer_steps(monkeypatch):
    """With the kernel in Taichi's offline cache but not in the process, a single run of 36–144
    free blocks takes the fused engine once its steps save ``LOAD_SECONDS`` at the measured
    ``MID_STEP_SAVING`` a step (benchmarks/results/fused_threshold.md), a smaller or larger model
    only at ``STEP_SAVING`` a step."""
    monkeypatch.setattr(policy, "_loaded", lambda: False)
    monkeypatch.setattr(policy, "kernel_cached", lambda arch="cpu": True)
    params = dd.Params()
    pays = int(round(policy.LOAD_SECONDS / policy.MID_STEP_SAVING))
    for n in policy.MID_BLOCKS:
        model = _grid(n, params)
        assert policy.choose(model, steps=pays, duration=None)[0] == "fused"
        name, why = policy.choose(model, steps=pays - 100, duration=None)
        assert name != "fused" and "do not pay" in why
    for n in (policy.MID_BLOCKS[0] - 1, policy.MID_BLOCKS[1] + 1):
        assert policy.choose(_grid(n, params), steps=pays, duration=None)[0] != "fused"
