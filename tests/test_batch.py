"""Independent models run side by side in one (`ddatai.batch`) and the kgm judgements that use
it (`kgm.judges.batch.judge_members`): each member moves as it does alone, each verdict is the one its
own run gives, and a batched bisection finds the closed-form limit."""

import math

import numpy as np
import pytest
import scipy.stats as st

import ddatai as dd
import kgm
import kgm_cases
from cases import downslope_displacement, sliding_scene
from ddatai.batch import batch_model, combined_state, member_constants, side_by_side
from ddatai.model import build_model
from ddatai.start import settle
from ddatai.step import Stepper
from kgm.build import build_block_system
from kgm.judges.batch import Member, judge_many, judge_members
from kgm.judges.run import judge

G = 9.81
THETA = 30.0


def _run_batch(scenes, params, steps):
    models = [build_model(s, params) for s in scenes]
    (w0, penalty), = {member_constants(m) for m in models}
    batch = side_by_side(scenes, gap=50.0)
    model = batch_model(batch, params, w0=w0, penalty=penalty)
    states = [settle(Stepper(m), m.initial_state())[0] for m in models]
    res = dd.simulate(batch.scene, model.params, steps=steps, model=model,
                      initial_state=combined_state(batch, model, models, states))
    return batch, model, res


def test_members_move_as_they_do_alone():
    """Blocks on a 30° plane with φ = 15°, 25° (slide at a = g(sinθ − cosθ·tanφ)) and 45°
    (holds), side by side: every member's centroid path is its own run's to round-off, and the
    sliding ones follow the closed form."""
    params = dd.Params(dt=2e-3)
    phis = (15.0, 45.0, 25.0)
    scenes = [sliding_scene(THETA, phi)[0] for phi in phis]
    block = sliding_scene(THETA, 15.0)[1]
    steps = 150
    batch, model, res = _run_batch(scenes, params, steps)
    assert model.w0 == build_model(scenes[0], params).w0
    for k, (scene, phi) in enumerate(zip(scenes, phis)):
        alone = dd.simulate(scene, params, steps=steps)
        path = res.centroid[:, batch.block_offset[k]:batch.block_offset[k + 1]] - batch.shift[k]
        assert np.abs(path - alone.centroid).max() <= 1e-9 * (1.0 + np.abs(alone.centroid).max())
        s = downslope_displacement(alone, block, THETA)
        t = res.time[-1]
        a = max(G * (math.sin(math.radians(THETA)) - math.cos(math.radians(THETA)) * math.tan(math.radians(phi))), 0)
        if a > 0:
            assert s == pytest.approx(0.5 * a * t * t, rel=0.02)
        else:
            assert abs(s) < 1e-6


def test_each_member_keeps_its_own_joints_and_points():
    """Member k's default joint, pair overrides, points and loads follow its blocks."""
    a, b = sliding_scene(THETA, 20.0)[0], sliding_scene(THETA, 40.0)[0]
    b.set_joint(dd.Joint(friction=10.0), between=(0, 1))
    b.add_measured_point(1, b.blocks[1].vertices.mean(axis=0))
    batch = side_by_side([a, b], gap=3.0)
    sc = batch.scene
    assert batch.block_offset.tolist() == [0, 2, 4]
    assert [sc.joints[k].friction for k in sc.blocks[1].edge_joint] == [20.0] * 4
    assert [sc.joints[k].friction for k in sc.blocks[3].edge_joint] == [40.0] * 4
    assert {pair: sc.joints[k].friction for pair, k in sc.pair_joints.items()} == {(2, 3): 10.0}
    assert sc.measured_points[0].block == 3
    assert sc.measured_points[0].xy[0] == pytest.approx(b.measured_points[0].xy[0] + batch.shift[1][0])
    xa = np.concatenate([blk.vertices for blk in sc.blocks[:2]])[:, 0].max()
    xb = np.concatenate([blk.vertices for blk in sc.blocks[2:]])[:, 0].min()
    assert xb - xa == pytest.approx(3.0)


def test_side_by_side_refuses_what_members_cannot_share():
    a = sliding_scene(THETA, 20.0)[0]
    with pytest.raises(ValueError, match="member 1 has gravity"):
        side_by_side([a, dd.Scene(gravity=3.0)], gap=1.0)
    wet = sliding_scene(THETA, 20.0)[0]
    wet.set_water_table([(-50.0, 1.0), (50.0, 1.0)])
    with pytest.raises(ValueError, match="member 1 has a water table"):
        side_by_side([a, wet], gap=1.0)
    with pytest.raises(ValueError, match="gap"):
        side_by_side([a], gap=-1.0)


def test_batched_verdicts_are_the_runs_alone():
    """The block on the 30° plane judged at φ = 20°, 29°, 31° and 40° in one run: each verdict,
    displacement and step count is its own run's (`exact`, fixed Δt)."""
    scene, _, b = kgm_cases.block_on_incline(theta=THETA, width=2.0, height=1.0, friction=35.0, cohesion=0.0)
    system = build_block_system(scene)
    settings = kgm.DdaSettings(duration=0.5)
    params = dd.Params(dt=2e-3)
    probes = [(20.0, 1.0), (29.0, 1.0), (31.0, 1.0), (40.0, 1.0)]
    many = judge_members([Member(scene=scene, system=system, friction=f, reduction=r) for f, r in probes],
                         frozenset([b]), settings=settings, params=params, exact=True)
    assert [j.stable for j in many] == [False, False, True, True]
    assert all(j.batch == 4 for j in many)
    for (f, r), j in zip(probes, many):
        alone = judge(scene, system, frozenset([b]), settings=settings, params=params, friction=f, reduction=r)
        assert (j.stable, j.steps, j.note) == (alone.stable, alone.steps, alone.note)
        assert j.displacement == pytest.approx(alone.displacement, rel=1e-9, abs=1e-12)
    # the strength-reduction probes of the same group, as judge_many takes them
    fs = judge_many(scene, system, frozenset([b]), [(None, 1.0), (None, 1.5)], settings=settings, params=params)
    assert [j.stable for j in fs] == [True, False]  # FS = tan35°/tan30° = 1.21


def test_batched_and_sequential_bisections_agree_with_the_closed_form():
    """φc = θ and FS = tanφ/tanθ of one block on a plane, by the batched K-section (the default)
    and by one run a probe (``batch=1``): both within the tolerance plus the judgement's
    friction resolution Δtanφ ≈ a_r/(g cosθ) (docs/kgm/method.md §6.3), and in far fewer runs
    of the batch."""
    phi = 40.0
    scene, _, b = kgm_cases.block_on_incline(theta=THETA, width=2.0, height=1.0, friction=phi, cohesion=0.0)
    system = build_block_system(scene)
    from kgm.judges.dda import evaluate_dda

    tan_t = math.tan(math.radians(THETA))
    for batch in (16, 1):
        s = kgm.DdaSettings(batch=batch)
        dtan = s.acceleration_resolution / (G * math.cos(math.radians(THETA)))
        ev = evaluate_dda(scene, system, frozenset([b]), settings=s, fs_guess=1.3, friction_guess=35.0)
        assert ev.fs == pytest.approx(math.tan(math.radians(phi)) / tan_t, abs=s.fs_tolerance + dtan / tan_t)
        dphi = math.degrees(math.atan(tan_t + dtan)) - THETA
        assert ev.critical_friction == pytest.approx(THETA, abs=s.friction_tolerance + dphi)
        runs = len({j.wall_time for j in ev.runs}) if batch > 1 else len(ev.runs)
        if batch > 1:
            assert runs <= 3
        else:
            assert runs >= 8


def test_probabilistic_table_does_not_depend_on_the_batch():
    """A DDA-judged study with a fixed Δt: the same table whether its samples run one a run or
    side by side."""
    variables = {"friction": st.uniform(20.0, 20.0)}
    tables = []
    for batch in (1, 4):
        study = kgm.probabilistic(kgm_cases.incline_scene_fixed_dt, variables, 6, method="dda", group={1}, seed=5,
                                  workers=1, settings=kgm.Settings(dda=kgm.DdaSettings(sample_batch=batch, duration=0.4)))
        tables.append(study.table)
    a, b = tables
    assert all(np.array_equal(a[k], b[k], equal_nan=a[k].dtype.kind == "f") for k in a.dtype.names)
    clear = np.abs(a["friction"] - THETA) > 1.0
    assert np.array_equal(a["failed"][clear], a["friction"][clear] < THETA)


def test_member_states_cut_out_what_combined_state_put_in():
    """A batch's state split into its members' states (to go on without the decided ones) gives
    back each member's own state: positions, contact memory (identities renumbered), stresses."""
    from ddatai.batch import member_states

    params = dd.Params(dt=2e-3)
    scenes = [sliding_scene(THETA, phi)[0] for phi in (15.0, 45.0, 25.0)]
    models = [build_model(s, params) for s in scenes]
    (w0, penalty), = {member_constants(m) for m in models}
    batch = side_by_side(scenes, gap=50.0)
    model = batch_model(batch, params, w0=w0, penalty=penalty)
    states = [settle(Stepper(m), m.initial_state())[0] for m in models]
    for _ in range(3):
        states = [Stepper(m).step(s)[0] for m, s in zip(models, states)]
    assert all(len(s.memory.key) for s in states)
    back = member_states(batch, model, models, combined_state(batch, model, models, states), which=[2, 0])
    for k, s in zip([2, 0], back):
        own = states[k]
        assert np.allclose(s.vertex_xy, own.vertex_xy, rtol=0, atol=1e-12)
        assert np.array_equal(s.memory.key, own.memory.key)
        assert np.array_equal(s.memory.state, own.memory.state)
        assert np.array_equal(s.memory.omega, own.memory.omega)
        assert np.array_equal(s.block_stress, own.block_stress) and s.time == own.time


@pytest.mark.parametrize("limit", [0.0, 3.3, 11.02, 40.0, 88.9, 89.5])
def test_k_section_closes_on_a_monotone_limit(limit):
    """The batched search alone, on a verdict stable for φ ≥ limit: it ends within the tolerance
    of the limit (0 and 90 where the limit lies outside [0°, 89°]), 16 probes a round."""
    from kgm.judges.dda import _Bracket

    b = _Bracket(guess=20.0, lower=0.0, upper=89.0, tolerance=0.25, step=2.0)
    rounds = 0
    while not b.done:
        xs = b.proposals(16, share_next=16)
        assert xs and len(xs) <= 16
        for x in xs:
            b.record(x, x >= limit)
        rounds += 1
    got = b.limit(lambda x: x, below=0.0, above=90.0)
    if limit <= 0.0:
        assert got == 0.0
    elif limit > 89.0:
        assert got == 90.0
    else:
        assert abs(got - limit) <= 0.125 + 1e-12
    assert rounds <= 6


def test_k_section_stops_on_verdicts_that_turn_over():
    """Verdicts that are not monotone near the limit (stable at 10.4°, unstable at 10.6°): the
    bracket turns over, the search stops, the limit is the middle of the band."""
    from kgm.judges.dda import _Bracket

    b = _Bracket(guess=10.0, lower=0.0, upper=89.0, tolerance=0.25, step=2.0)
    for x, stable in [(9.0, False), (10.4, True), (10.6, False), (12.0, True)]:
        b.record(x, stable)
    assert b.done
    assert b.limit(lambda x: x, below=0.0, above=90.0) == pytest.approx(10.5)


def test_a_batch_whose_step_cuts_dt_judges_its_members_again():
    """With a fixed Δt of 40 ms the block at φ = 5° accelerates until a step moves it too far and
    Δt is cut: its batch no longer takes the steps the others take alone, so the members not yet
    decided are judged again (in halves): every verdict, step count and displacement is still its
    own run's. (Today's side-by-side batch, ``Params(kernels="numpy")``: the fused engine runs
    every member alone, tests/test_fused.py.)"""
    scene, _, b = kgm_cases.block_on_incline(theta=THETA, width=2.0, height=1.0, friction=35.0, cohesion=0.0)
    system = build_block_system(scene)
    settings = kgm.DdaSettings(duration=1.5, stop_ratio=400.0)
    params = dd.Params(dt=0.04, kernels="numpy")
    probes = [(5.0, 1.0), (29.5, 1.0), (40.0, 1.0), (25.0, 1.0)]
    many = judge_members([Member(scene=scene, system=system, friction=f, reduction=r) for f, r in probes],
                         frozenset([b]), settings=settings, params=params, exact=True)
    assert min(j.batch for j in many) < len(probes)  # judged again, in smaller batches
    for (f, r), j in zip(probes, many):
        alone = judge(scene, system, frozenset([b]), settings=settings, params=params, friction=f, reduction=r)
        assert (j.stable, j.steps, j.note) == (alone.stable, alone.steps, alone.note)
        assert j.displacement == pytest.approx(alone.displacement, rel=1e-9, abs=1e-12)
    assert [j.stable for j in many] == [False, False, True, False]


def _k_section_on(fs_limit, phi_limit, *, fs_guess, phi_guess, all_probes=False, batch=8, two_pass=False):
    """`dda_evaluation`'s batched searches (`kgm.judges.dda._searches`, `_k_sections`) on a
    synthetic monotone verdict: stable for F ≤ ``fs_limit`` and φ ≥ ``phi_limit``. Returns (FS,
    φc, the probes of each round, or of each pass with ``two_pass``); ``all_probes``: each
    closing round cut into as many pieces as it has probes (the rule before the fewest were
    taken)."""
    from kgm.judges import dda

    searches = dda._searches(kgm.DdaSettings(), fs_guess, phi_guess)
    if all_probes:
        for b in searches.values():
            b.closing = lambda: 10 ** 9
    rounds = []

    def judge_round(probes):
        rounds.append(list(probes))
        return [r <= fs_limit if f is None else f >= phi_limit for f, r in probes]

    dda._k_sections(searches, judge_round, batch, two_pass=two_pass)
    fs = searches["fs"].limit(lambda x: math.exp(-x), below=math.inf, above=0.0)
    phi = searches["phi"].limit(lambda x: x, below=0.0, above=90.0)
    return fs, phi, rounds


@pytest.mark.parametrize("fs_limit, phi_limit, fs_guess, phi_guess", [
    (0.9994, 10.96, 0.9988, 11.025),  # Example I's limits and limit-equilibrium guesses
    (1.21, 30.0, 1.3, 35.0), (0.62, 17.3, 0.9, 15.0), (3.7, 44.4, 2.0, 40.0), (1.0, 0.0, 1.0, 5.0)])
def test_k_section_closes_with_the_fewest_probes_that_reach_the_tolerance(fs_limit, phi_limit, fs_guess, phi_guess):
    """A round whose bracket is found takes only the probes that close it to the tolerance: on a
    monotone verdict, FS and φc within the tolerances of the limits (FS to ``fs_tolerance``
    relative, φc to ``friction_tolerance``; each the middle of its final bracket, so within half
    of it) as with every probe of the round used, in as many rounds, with fewer probes or as
    many; and the closing round's probes are the fewest that close it."""
    s = kgm.DdaSettings()
    fs, phi, rounds = _k_section_on(fs_limit, phi_limit, fs_guess=fs_guess, phi_guess=phi_guess)
    fs_all, phi_all, rounds_all = _k_section_on(fs_limit, phi_limit, fs_guess=fs_guess, phi_guess=phi_guess,
                                                all_probes=True)
    half = 0.5 * math.log1p(s.fs_tolerance) + 1e-12
    for f in (fs, fs_all):
        assert abs(math.log(f / fs_limit)) <= half
    for p in (phi, phi_all):
        assert p == 0.0 if phi_limit <= 0.0 else abs(p - phi_limit) <= 0.5 * s.friction_tolerance + 1e-12
    assert abs(math.log(fs / fs_all)) <= math.log1p(s.fs_tolerance) and abs(phi - phi_all) <= s.friction_tolerance
    assert len(rounds) == len(rounds_all) and sum(map(len, rounds)) <= sum(map(len, rounds_all))
    assert all(len(r) <= s.batch for r in rounds)
    # the last round of each search: one probe fewer would have left a piece wider than the tolerance
    phis = sorted(f for r in rounds[1:] for f, _ in r if f is not None)
    if len(rounds) > 1 and phis and phi_limit > 0.0:
        lo = max(f for r in rounds[:-1] for f, _ in r if f is not None and f < phi_limit)
        hi = min(f for r in rounds[:-1] for f, _ in r if f is not None and f >= phi_limit)
        last = [f for f, _ in rounds[-1] if f is not None]
        if last and lo < min(last) and max(last) < hi:
            assert (hi - lo) / (len(last) + 1) <= s.friction_tolerance < (hi - lo) / len(last)


def test_example_1_k_section_takes_4_probes_fewer():
    """Example I's searches (FS 0.9994 and φc 10.96° by DDA, the guesses Sarma's 0.9988 and
    11.025°): the second round's φ bracket, 9.84–11.02°, is closed to 0.25° by 4 probes, not
    by the round's 8; 11 probes instead of 15, in the same two rounds, and φc moves by less
    than the tolerance (10.91° against 10.96°)."""
    fs, phi, rounds = _k_section_on(0.9994, 10.96, fs_guess=0.9988, phi_guess=11.025)
    fs_all, phi_all, rounds_all = _k_section_on(0.9994, 10.96, fs_guess=0.9988, phi_guess=11.025, all_probes=True)
    assert [len(r) for r in rounds_all] == [7, 8] and [len(r) for r in rounds] == [7, 4]
    assert fs == fs_all and phi == pytest.approx(10.906, abs=1e-3) and phi_all == pytest.approx(10.959, abs=1e-3)


CASES = [(0.9994, 10.96, 0.9988, 11.025), (1.21, 30.0, 1.3, 35.0), (0.62, 17.3, 0.9, 15.0), (3.7, 44.4, 2.0, 40.0),
         (1.0, 0.0, 1.0, 5.0), (1.05, 11.9, 0.7, 3.0), (0.015, 89.5, 1.0, 30.0), (60.0, 0.3, 10.0, 1.0)]


@pytest.mark.parametrize("fs_limit, phi_limit, fs_guess, phi_guess", CASES)
def test_two_pass_rounds_give_the_brackets_of_the_rounds_judged_at_once(fs_limit, phi_limit, fs_guess, phi_guess):
    """Each round in two passes (the middle probes, then those their verdicts leave open), on a
    monotone verdict: the same FS and φc as each round judged at once — to the bit, unless the
    first pass already closed a search, then within its tolerance — from fewer probes or as
    many, in at most twice as many passes as rounds."""
    s = kgm.DdaSettings()
    fs, phi, rounds = _k_section_on(fs_limit, phi_limit, fs_guess=fs_guess, phi_guess=phi_guess)
    fs2, phi2, passes = _k_section_on(fs_limit, phi_limit, fs_guess=fs_guess, phi_guess=phi_guess, two_pass=True)
    assert abs(math.log(fs2 / fs)) <= math.log1p(s.fs_tolerance) if math.isfinite(fs) and fs > 0 else fs2 == fs
    assert abs(phi2 - phi) <= s.friction_tolerance
    asked = {p for r in passes for p in r}  # (dda_evaluation judges a probe asked again once)
    assert len(asked) <= len({p for r in rounds for p in r})
    assert len(passes) <= 2 * len(rounds)


def test_two_pass_rounds_are_the_same_to_the_bit_where_no_first_pass_closes_a_search():
    """Example I's searches and a block's (FS 1.21, φc 30° from guesses 1.3 and 35°): each search's
    final bracket, hence FS and φc, the same to the bit in two passes as in one."""
    for case in (CASES[0], CASES[1]):
        one = _k_section_on(*case[:2], fs_guess=case[2], phi_guess=case[3])
        two = _k_section_on(*case[:2], fs_guess=case[2], phi_guess=case[3], two_pass=True)
        assert one[:2] == two[:2]


def test_example_1_two_pass_rounds_take_7_probes():
    """Example I (FS 0.9994 and φc 10.96° by DDA, the guesses 0.9988 and 11.025°): the verdict
    and the two guesses first; F = 1 unstable and F = 0.9988 stable close FS, φ = 11.02° stable
    leaves only 9.84° of the first round open; the second round's 4 probes are judged as 10.31°,
    then 10.55° and 10.79°: 7 probes instead of 15, FS and φc those of the rounds judged at once."""
    fs, phi, passes = _k_section_on(0.9994, 10.96, fs_guess=0.9988, phi_guess=11.025, two_pass=True)
    assert [len(p) for p in passes] == [3, 1, 1, 2]
    assert (fs, phi) == _k_section_on(0.9994, 10.96, fs_guess=0.9988, phi_guess=11.025)[:2]


def test_rounds_go_two_pass_where_the_fused_engine_judges_them_whatever_their_size():
    """Two passes where each member pays its own stage and run (``kernels="fused"`` on a model
    the fused engine runs; its sub-model then built once, for the rounds to take), not on
    today's side-by-side batch, which shares a step among a round's members (``kernels="numpy"``,
    or a model with water, which the fused engine leaves to today's path)."""
    from kgm.judges.fused import judged_apart
    from kgm.judges.run import RunPlan

    def apart(kernels, water=False, kept=None):
        scene, _, b = kgm_cases.block_on_incline(theta=THETA, width=2.0, height=1.0, friction=35.0, cohesion=0.0)
        if water:
            scene.set_water_table([(-100.0, 0.5), (100.0, 0.5)])
        system = build_block_system(scene)
        plan = RunPlan.of(system, frozenset([b]), kgm.DdaSettings(), dd.Params(kernels=kernels))
        return judged_apart(scene, system, frozenset([b]), plan, submodels=kept)

    kept = {}
    assert apart("fused", kept=kept) and len(kept) == 1
    assert not apart("numpy") and not apart("fused", water=True)


def test_the_rounds_of_one_evaluation_build_their_sub_model_once(monkeypatch):
    """`prepare_fused` with a dict of sub-models kept across the rounds of one evaluation (as
    `dda_evaluation` keeps it): the sub-model is built once for both rounds, and every member's
    model and settled state are those of the rounds prepared each on its own, to the bit."""
    from dataclasses import fields

    import ddatai.model
    from kgm.judges.fused import prepare_fused

    scene, _, b = kgm_cases.block_on_incline(theta=THETA, width=2.0, height=1.0, friction=35.0, cohesion=0.0)
    system = build_block_system(scene)
    settings, params = kgm.DdaSettings(), dd.Params(kernels="fused")
    rounds = [[(25.0, 1.0), (40.0, 1.0), (None, 1.0)], [(None, 1.3), (33.0, 1.0)]]
    built = []
    build = ddatai.model.build_model
    monkeypatch.setattr(ddatai.model, "build_model", lambda *a, **k: built.append(1) or build(*a, **k))

    def prepared(submodels):
        return [prepare_fused([Member(scene=scene, system=system, friction=f, reduction=r) for f, r in probes],
                              frozenset([b]), settings=settings, params=params, submodels=submodels)
                for probes in rounds]

    kept = {}
    once = prepared(kept)
    assert len(built) == 1 and len(kept) == 1
    alone = prepared(None)
    assert len(built) == 3  # one a round without the dict

    def same(x, y):
        return x.tobytes() == y.tobytes() if isinstance(x, np.ndarray) else x == y or (x is None and y is None)

    for a, z in zip(once, alone):
        for ra, rz in zip(a.runs, z.runs):
            assert all(same(getattr(ra.model, f.name), getattr(rz.model, f.name)) for f in fields(rz.model))
            assert same(ra.state.vertex_xy, rz.state.vertex_xy) and same(ra.state.memory.key, rz.state.memory.key)
            assert same(ra.state.memory.state, rz.state.memory.state)
    assert not same(once[0].runs[0].model.joint_tan_phi, once[0].runs[1].model.joint_tan_phi)


def test_a_two_pass_evaluation_finds_the_closed_form_critical_friction(monkeypatch):
    """`dda_evaluation` with its rounds in two passes (forced here on today's side-by-side batch,
    where the fused engine would take them): φc of one block on a plane within the tolerance plus
    the judgement's friction resolution of θ (as `test_batched_and_sequential_bisections_agree_
    with_the_closed_form`), its final bracket within the tolerance, each pass smaller than a
    round of 8."""
    import kgm.judges.dda as dda_module
    from kgm.judges.dda import evaluate_dda

    monkeypatch.setattr(dda_module, "judged_apart", lambda *a, **k: True)
    scene, _, b = kgm_cases.block_on_incline(theta=THETA, width=2.0, height=1.0, friction=40.0, cohesion=0.0)
    system = build_block_system(scene)
    s = kgm.DdaSettings(acceleration_resolution=0.2)  # T halved: a coarser resolution, runs half as long
    ev = evaluate_dda(scene, system, frozenset([b]), settings=s, friction_guess=35.0, with_fs=False)
    tan_t = math.tan(math.radians(THETA))
    dphi = math.degrees(math.atan(tan_t + s.acceleration_resolution / (G * math.cos(math.radians(THETA))))) - THETA
    assert ev.critical_friction == pytest.approx(THETA, abs=s.friction_tolerance + dphi)
    unstable, stable = ev.bracket("friction")
    assert 0.0 < stable - unstable <= s.friction_tolerance
    assert max(j.batch for j in ev.runs) <= 4 < s.batch
