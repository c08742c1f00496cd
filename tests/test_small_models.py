"""The small-model path (`Params.kernels`, `Model.numpy_path`): a step's per-block and
per-contact work in vectorised NumPy instead of Taichi kernels, and the dense LAPACK solver
(`Params.solver="dense"`), chosen automatically for small models. The same scene run on every
path takes the same solves and ends at the same positions, to round-off."""

import dataclasses

import numpy as np
import pytest

import ddatai as dd
from cases import launched_block
from ddatai.model import SMALL_MODEL_BLOCKS, build_model
from ddatai.solver import DENSE_UNKNOWNS, SparseSolver
from scenes import example_1
from test_water_bolts import bolted, wet_incline

PATHS = [("taichi", "scipy"), ("numpy", "scipy"), ("numpy", "dense"), ("taichi", "dense")]


def dropped_grid(n: int = 3):
    """n × n stiff blocks dropped 5 mm onto a fixed base: impacts, sliding, lock-slide changes."""
    s = dd.Scene(gravity=9.81)
    rock = dd.Material(density=2500.0, young=5e9, poisson=0.25)
    s.add_block([(-1, -1), (n + 1, -1), (n + 1, 0), (-1, 0)], material=rock, fixed=True)
    for j in range(n):
        for i in range(n):
            y = 0.005 + j * 1.001
            s.add_block([(i, y), (i + 1, y), (i + 1, y + 1), (i, y + 1)], material=rock)
    s.set_joint(dd.Joint(friction=30.0))
    return s, dd.Params(dt=1e-3)


CASES = {
    "example_1_sliding": lambda: example_1.build(friction=8.0),
    "dropped_grid": dropped_grid,
    "launched_block": lambda: (launched_block(20.0, 30.0, 2.0)[0], dd.Params(dt=1e-3)),
    "bolted_with_load": lambda: (bolted(1e6, load=(1e4, 0.0))[0], dd.Params(dt=1e-3)),
    "wet_incline": lambda: (wet_incline(35.0)[0], dd.Params(dt=1e-3)),
}


@pytest.mark.parametrize("case", sorted(CASES))
def test_every_path_gives_the_same_run(case):
    """The steps (started under sudden gravity, so that only the step is compared): the NumPy
    twins and the kernels with the same solver take the same solves to the same positions
    (1e-9 of the model's size); the dense and the sparse factorisation differ in round-off, which
    may tip one contact across its tolerance in a step (one more solve there), never more than
    at two steps, and the positions still agree to 1e-9 of the size."""
    runs = {}
    for kernels, solver in PATHS:
        scene, params = CASES[case]()
        params = dataclasses.replace(params or dd.Params(), kernels=kernels, solver=solver,
                                     initial_equilibrium=False)
        res = dd.simulate(scene, params, steps=60, record_every=20)
        runs[kernels, solver] = (res.steps["oc_total"].copy(), res.vertices[-1])
    solves, xy = runs["taichi", "scipy"]
    size = np.ptp(xy, axis=0).max()
    for (kernels, solver), (other_solves, other_xy) in runs.items():
        if solver == "scipy":
            np.testing.assert_array_equal(other_solves, solves)
        else:
            assert np.count_nonzero(other_solves != solves) <= 2
        assert np.abs(other_xy - xy).max() < 1e-9 * size


@pytest.mark.parametrize("friction, held, released", [(14.0, 3, 0), (8.0, 1, 2)])
def test_the_stage_gives_the_same_start_on_every_path(friction, held, released):
    """The equilibrium stage (an iteration to a force tolerance, `ddatai.return_mapping`) holds
    and releases the same blocks of Example I on every path. A held model's settled positions
    agree to a tenth of its settlement: the stage stops once every block balances within its
    tolerance, and the contacts at their strength (5 at 14°) then slide by amounts that the
    round-off of each path leaves a little different (measured: 3.7e-7 m of 1.2e-4 m)."""
    for kernels, solver in PATHS:
        scene, params = example_1.build(friction=friction)
        params = dataclasses.replace(params, kernels=kernels, solver=solver)
        res = dd.simulate(scene, params, steps=1)
        start = res.start[0]
        assert (start["held"], start["released"], bool(start["welded"])) == (held, released, False)
        if released == 0:
            xy = res.vertices[0]
            if (kernels, solver) == PATHS[0]:
                reference = xy
            assert np.abs(xy - reference).max() < 0.1 * start["settlement"]


def test_automatic_choice_by_size():
    """"auto": NumPy and dense LAPACK for a small model, Taichi and a sparse solver for a large
    one; forcing either is kept."""
    small, _ = dropped_grid(3)
    assert build_model(small).numpy_path
    assert not build_model(small, dd.Params(kernels="taichi")).numpy_path
    assert not build_model(small, dd.Params(arch="gpu")).numpy_path  # a GPU asked for: kernels
    large, _ = dropped_grid(9)
    assert 81 > SMALL_MODEL_BLOCKS and not build_model(large).numpy_path
    assert build_model(large, dd.Params(kernels="numpy")).numpy_path
    assert SparseSolver("auto", unknowns=6 * 9).backend == "dense"
    assert SparseSolver("auto", unknowns=DENSE_UNKNOWNS + 6).backend != "dense"
    assert SparseSolver("dense").backend == "dense"
    with pytest.raises(ValueError, match="Params.kernels"):
        dd.Params(kernels="fortran")


def test_dense_solver_matches_superlu_and_reports_a_singular_matrix():
    rng = np.random.default_rng(3)
    n = 30
    a = rng.normal(size=(n, n))
    spd = a @ a.T + n * np.eye(n)
    from scipy.sparse import csr_matrix

    for k, symmetric in ((spd, True), (spd + 0.1 * a, False)):
        m = csr_matrix(k)
        b = rng.normal(size=n)
        x = SparseSolver("dense").solve(m.data, m.indices, m.indptr, b, symmetric=symmetric)
        y = SparseSolver("scipy").solve(m.data, m.indices, m.indptr, b, symmetric=symmetric)
        assert np.allclose(x, y, rtol=1e-10, atol=1e-12)
    singular = csr_matrix(np.zeros((4, 4)) + np.diag([1.0, 1.0, 0.0, 1.0]))
    x = SparseSolver("dense").solve(singular.data, singular.indices, singular.indptr, np.ones(4), symmetric=False)
    assert not np.all(np.isfinite(x))
