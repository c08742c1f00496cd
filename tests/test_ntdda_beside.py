"""The parameters `benchmarks/ntdda_beside.py` gives ddatai for each start protocol, on ntdda's
grid files (docs/ntdda.md §5.3): only the start and the engine change, and the default start's
equilibrium stage holds ntdda's grid as it stands."""

from __future__ import annotations

import dataclasses
import sys
from pathlib import Path

import pytest

import ddatai as dd
from ddatai.model import build_model
from ddatai.start import settle
from ddatai.step import Stepper

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
from ntdda_beside import grid_files, start_params  # noqa: E402


@pytest.fixture(scope="module")
def grid4(tmp_path_factory):
    geo, ana = grid_files(4, tmp_path_factory.mktemp("grid"), steps=20)
    return dd.read_ntdda(geo, ana)


def test_start_params_change_only_the_start_and_the_engine(grid4):
    base = grid4.params
    assert base.initial_equilibrium is False  # the files say no gravity turn-on: ntdda's sudden start
    sudden, default = start_params(base, "sudden"), start_params(base, "default")
    assert (sudden.initial_equilibrium, default.initial_equilibrium) == (False, True)
    assert sudden.kernels == default.kernels == "fused"
    assert dataclasses.replace(default, initial_equilibrium=False) == sudden
    assert dataclasses.replace(sudden, kernels=base.kernels) == base
    with pytest.raises(ValueError, match="start must be one of"):
        start_params(base, "settled")


def test_default_start_holds_ntdda_grid(grid4):
    """A 2 × 2 grid of fitted 1 m blocks on a base block (4 m × 1 m) held at mid-height by three
    fixed points, under its weight alone: every contact is a flat face under vertical load, so
    limit equilibrium holds every block and the stage must release none. The top blocks' top
    corners settle by at least the grid's own shortening, which for DDA's constant-strain blocks
    (docs/method/dda.md; free sides, plane stress) is ρg·(0.5 + 1.5)·1 m²/E, and by at most that
    plus the base's shortening above its fixed points (its mean stress under the grid and its own
    weight at most 1.5ρg·1 m, over 0.5 m) and the penalty springs' (a block's weight on two
    contacts in each of the three layers under the top block, the whole weight on three fixed
    points)."""
    params = dataclasses.replace(start_params(grid4.params, "default"), kernels="numpy")
    model = build_model(grid4.scene, params)
    state, record = settle(Stepper(model), model.initial_state())
    assert (record.held, record.released) == (model.n_free, 0) == (5, 0)
    assert not (record.unsettled or record.stalled or record.welded)
    weight, young, p = 2000.0 * 9.81, 1.0e8, params.penalty  # ρg [N/m³], E [Pa], p [N/m]
    grid = weight * (0.5 + 1.5) / young
    base = 1.5 * weight * 0.5 / young
    springs = weight * (1 + 2 + 2) / (2 * p) + weight * (4 + 4) / (3 * p)
    assert grid <= record.settlement <= grid + base + springs
    assert not state.in_doubt.any()
