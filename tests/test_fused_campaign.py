"""The fused engine on a random campaign of small models (tests/extreme_cases.py): thrown stacks
and randomly cut blocks ("rock" regime) and randomly cut slope sections ("cut" regime), each
run on the fused engine and on today's NumPy path from the same start. No new divergence: a
run that finishes on the NumPy path finishes fused too (or is handed to today's path by the
engine, which then finishes it), with the campaign's properties (finite values, no
penetration beyond the limit, no energy created, Coulomb's law at every closed contact); a
refusal before work is the same refusal. The whole campaign is in the slow profile (``-m slow``:
8 short and 60 longer scenes, ~10 min on 2 cores once the fused kernel is compiled; README,
"Performance")."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from extreme_cases import build, check, random_domain, random_spec

import ddatai as dd

pytestmark = pytest.mark.slow


def _run(spec, kernels: str):
    try:
        scene, steps = build(spec)
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            params = dd.Params(kernels=kernels, **({"dt": spec.dt} if spec.dt else {}))
            model = dd.build_model(scene, params)
    except ValueError as err:
        return "refused", str(err), None, None
    strained = any("elastic strain" in str(w.message) for w in caught)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            res = dd.simulate(scene, params, steps=steps)
    except dd.SimulationError as err:
        return "diverged", str(err), None, None
    return "ok", "", res, check(res, model, energy=not strained)


def _compare(spec):
    numpy_status, numpy_why, numpy_res, _ = _run(spec, "numpy")
    status, why, res, problems = _run(spec, "fused")
    if numpy_status == "ok":
        assert status == "ok", f"fused: {status} ({why}) where the NumPy path finished"
        assert not problems, problems
        assert res.meta["engine"]["name"] in ("fused", "numpy"), res.meta["engine"]
    elif numpy_status == "refused":
        assert (status, why) == (numpy_status, numpy_why)
    return numpy_status, status, None if res is None else res.meta["engine"]["name"]


DEFAULT_SEEDS = range(4)


@pytest.mark.parametrize("seed", DEFAULT_SEEDS)
def test_fused_campaign_rock(seed):
    """A few rock-like scenes (stacks and cut blocks, 25 steps): no new divergence."""
    _compare(random_spec(np.random.default_rng(1000 + seed), "rock", steps=25))


@pytest.mark.parametrize("seed", DEFAULT_SEEDS)
def test_fused_campaign_cut_domains(seed):
    """A few randomly cut slope sections (35 steps): no new divergence."""
    _compare(random_domain(np.random.default_rng(seed), steps=35))


@pytest.mark.parametrize("seed", range(4, 34))
def test_fused_campaign_rock_long(seed):
    _compare(random_spec(np.random.default_rng(1000 + seed), "rock", steps=60))


@pytest.mark.parametrize("seed", range(4, 34))
def test_fused_campaign_cut_domains_long(seed):
    _compare(random_domain(np.random.default_rng(seed), steps=60))
