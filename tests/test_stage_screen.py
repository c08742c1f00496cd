"""The equilibrium stage's screen (`ddatai.mechanisms.unsupported_at_start`): a small model whose every
free block rigid-block limit equilibrium lets move at t = 0 is released before the stage's first
solve, instead of after a return mapping that stalls. Against the stage without it
(``settle(screen=False)``, the reference): the same blocks held and released, the same welded or
not; where the screen releases nothing, the reference's start to the bit (its programs are
answered once where asked twice, the same floats); where it releases every block, the initial
state, as the reference hands it over. On Example I's and Example II's groups across their
critical strengths, the first samples of Example II's probabilistic study, and random stacks,
cut blocks and cut slope sections (tests/extreme_cases.py). The slow profile (``-m slow``, ~30 s
on 2 cores) takes 100 samples of the study and 60 random scenes.

LAPACK called directly (`ddatai.dense`) gives SciPy's floats and errors."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest
from scipy.linalg import LinAlgError, cho_factor, cho_solve, lu_factor, lu_solve

import ddatai as dd
from ddatai import limit_equilibrium
from ddatai.dense import LU, Cholesky
from ddatai.model import build_model
from ddatai.mechanisms import SCREEN_BLOCKS, unsupported_at_start
from ddatai.return_mapping import STALL_ITERATIONS
from ddatai.start import settle
from ddatai.step import Stepper
from extreme_cases import build, random_domain, random_spec

ROOT = Path(__file__).resolve().parents[1]


def group_model(module, blocks=frozenset({0, 1}), **strength):
    """The sub-model on which kgm judges ``blocks`` of a scene script's scene (`kgm.judges.run`)."""
    from kgm.build import prepare
    from kgm.judges.run import RunPlan, sub_scene
    from kgm.settings import DdaSettings, Settings

    scene, params = module.build(**strength)
    settings = Settings(dda=DdaSettings(params=params))
    problem = prepare(scene, settings=settings, params=params)
    plan = RunPlan.of(problem.system, blocks, settings.dda, problem.params)
    sub, _ = sub_scene(problem.scene, problem.system, blocks, free_neighbours=plan.free_neighbours)
    return build_model(sub, plan.params)


def compare(model, undecided: list | None = None) -> tuple:
    """The stage with and without the screen on ``model``: asserts the same outcome (module
    docstring); returns (held, released, whether the screen released the model). With
    ``undecided`` (a list), a model that the screen releases whole while the reference holds
    some of it after a return mapping that stalled (more solves than ``STALL_ITERATIONS``: one
    whose outcome round-off decides) is appended there instead: the screen on the safe side, releasing what rigid-block limit equilibrium
    cannot hold."""
    screened = unsupported_at_start(Stepper(model), model.initial_state()).any()
    state, record = settle(Stepper(model), model.initial_state(), screen=True)
    ref_state, ref = settle(Stepper(model), model.initial_state(), screen=False)
    if undecided is not None and screened and record.released == model.n_free > ref.released:
        undecided.append((ref.held, ref.released, ref.solves))
        return record.held, record.released, True
    assert (record.held, record.released, record.welded) == (ref.held, ref.released, ref.welded)
    if screened:
        assert record.held == 0 and record.released == model.n_free and record.solves == 0
        np.testing.assert_array_equal(state.vertex_xy, model.initial_state().vertex_xy)
        np.testing.assert_array_equal(state.vertex_xy, ref_state.vertex_xy)
        assert len(state.memory.key) == len(ref_state.memory.key) == 0
    else:
        assert record.solves == ref.solves
        np.testing.assert_array_equal(state.vertex_xy, ref_state.vertex_xy)
        for name in ("key", "state", "omega", "normal_force", "bond"):
            np.testing.assert_array_equal(getattr(state.memory, name), getattr(ref_state.memory, name))
    return record.held, record.released, bool(screened)


def test_lapack_called_directly_gives_scipys_floats_and_errors():
    rng = np.random.default_rng(3)
    for n in (6, 12, 30):
        a = rng.normal(size=(n, n))
        spd = a @ a.T + n * np.eye(n)
        b = rng.normal(size=n)
        np.testing.assert_array_equal(Cholesky(spd).solve(b), cho_solve(cho_factor(spd, check_finite=False), b))
        lu = LU(a)
        assert not lu.singular
        np.testing.assert_array_equal(lu.solve(b), lu_solve(lu_factor(a, check_finite=False), b))
    with pytest.raises(LinAlgError, match="not positive definite"):
        Cholesky(-np.eye(3))
    assert LU(np.array([[1.0, 2.0], [2.0, 4.0]])).singular


def test_a_program_asked_again_is_answered_as_the_first_time():
    """The limit-equilibrium program of Example II's group below its critical strength, twice:
    the same blocks; the answer kept is not changed by what a caller does with it."""
    from scenes import example_2

    model = group_model(example_2, friction=18.0, cohesion=15e3)
    stepper = Stepper(model)
    first = unsupported_at_start(stepper, model.initial_state())
    limit_equilibrium._SOLVED.clear()
    again = [unsupported_at_start(stepper, model.initial_state()) for _ in range(2)]
    assert first.sum() == model.n_free == 2
    for found in again:
        np.testing.assert_array_equal(found, first)


@pytest.mark.parametrize("friction, cohesion, screened", [
    (16.6, 21.0e3, True),      # limit equilibrium lets both blocks move: screened
    (21.0, 19.5e3, True),      # the same, near the critical strength
    (22.08, 20.178e3, False),  # rigid blocks held: released by the open-close test (Sarma's mechanism)
    (23.2, 17.5e3, False),     # held
])
def test_example_2_s_group_starts_as_without_the_screen(friction, cohesion, screened):
    from scenes import example_2

    held, out, by_screen = compare(group_model(example_2, friction=friction, cohesion=cohesion))
    assert by_screen == screened
    assert (held, out) == ((2, 0) if friction > 23 else (0, 2))


@pytest.mark.parametrize("friction", [8.0, 10.9, 11.1, 14.0])
def test_example_1_s_group_starts_as_without_the_screen(friction):
    """Example I's key group {0, 1} (critical friction 10.96°) below and above its strength."""
    from scenes import example_1

    compare(group_model(example_1, friction=friction))


#: (friction [degrees], cohesion [Pa]) of the first samples of Example II's DDA-judged study
#: (docs/kgm/example_2_vars.toml, seed 1), as `kgm.studies.sampling` draws them (checked in
#: the slow profile: drawing them imports scipy.stats, ~1 s)
FIRST_SAMPLES = [(22.059273513331792, 27822.600313879666), (19.876368003088785, 29376.448393184604),
                 (21.018668583377455, 19813.787616431637), (23.890250983628036, 17487.474774729246)]


def study_samples(n: int) -> list:
    """The (friction, cohesion) of the first ``n`` samples of Example II's DDA-judged study."""
    from kgm.studies.sampling import read_variables, sample_variables

    variables, correlation = read_variables(ROOT / "docs" / "kgm" / "example_2_vars.toml")
    samples = sample_variables(variables, n, seed=1, correlation=correlation)
    return [(float(samples["friction"][i]), float(samples["cohesion"][i])) for i in range(n)]


def study_members(samples) -> list:
    from scenes import example_2

    return [group_model(example_2, friction=f, cohesion=c) for f, c in samples]


def test_the_study_s_first_samples_start_as_without_the_screen():
    """Two held, two released by the screen."""
    outcomes = [compare(model) for model in study_members(FIRST_SAMPLES)]
    assert [screened for *_, screened in outcomes] == [False, True, True, False]


def random_model(kind: str, seed: int):
    spec = random_spec(np.random.default_rng(1000 + seed), "rock") if kind == "rock" else \
        random_domain(np.random.default_rng(seed))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        scene, _ = build(spec)
        return build_model(scene, dd.Params(kernels="numpy", **({"dt": spec.dt} if spec.dt else {})))


@pytest.mark.parametrize("kind, seed", [("rock", 2), ("rock", 6), ("rock", 10), ("rock", 18), ("domain", 22),
                                        ("domain", 20)])
def test_random_small_models_start_as_without_the_screen(kind, seed):
    """Stacks and cut blocks released whole, in part or held, and cut slope sections of 6 and
    10 free blocks (one released whole)."""
    model = random_model(kind, seed)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        compare(model)


def test_a_large_mass_is_not_screened():
    """Beyond SCREEN_BLOCKS free blocks the program would cost more than it saves: none
    released by the screen, even where every block fails (a cut slope section of 26)."""
    model = random_model("domain", 1)
    assert model.n_free > SCREEN_BLOCKS
    assert not unsupported_at_start(Stepper(model), model.initial_state()).any()


@pytest.mark.slow
def test_a_hundred_study_samples_start_as_without_the_screen():
    """Example II's study, its first 100 samples (~20 s on 2 cores); the first of them are
    FIRST_SAMPLES. One of them the reference does not decide: sample 88 (φ 17.75°, c 23.1 kPa),
    which limit equilibrium lets move whole, the stage without the screen releases whole after
    a return mapping with AVX2 BLAS kernels and holds one block of after 73 solves with AVX-512
    ones (``OPENBLAS_CORETYPE``); the screen releases it whole on both."""
    samples = study_samples(100)
    assert samples[:len(FIRST_SAMPLES)] == FIRST_SAMPLES
    undecided = []
    outcomes = [compare(model, undecided) for model in study_members(samples)]
    assert sum(screened for *_, screened in outcomes) > 20
    assert len(undecided) <= 1 and all(solves > STALL_ITERATIONS for *_, solves in undecided)


@pytest.mark.slow
@pytest.mark.parametrize("kind", ["rock", "domain"])
def test_random_campaign_starts_as_without_the_screen(kind):
    """30 random scenes of each kind (~3 s each on 2 cores)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for seed in range(30):
            try:
                model = random_model(kind, seed)
            except ValueError:  # refused before any work: nothing to start
                continue
            compare(model)
