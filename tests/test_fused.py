"""The fused engine (`ddatai.fused`) against today's NumPy path, its reference.

Both run the same step: the same Δt rule, contacts, contact law, open-close iteration and line
search, update and energy. They differ in the order of their sums (the fused engine factorises
its system with a skyline LU, today's path with LAPACK) and so in round-off, which can tip a
contact across one of the open-close iteration's tolerances in a step: a solve more or less
there. Tolerance: a held model (all contacts locked, no contact near a tolerance) is a linear
system solved twice, and its positions agree to ~κ(K)·ε of the motion (1e-9 of the model's size
asked); a model that slides or falls follows the same path to the iteration's force tolerance
(``Params.oc_force_tolerance``, 1e-3 of the load), which over a run of n steps moves a block by
at most that share of its motion: 1e-3 of the largest displacement, plus 1e-9 of the size
(round-off). Verdicts (stable or not, held or moving) are equal.

The fused kernel takes the step that ``Params.midstep_lever_arms`` and ``impact_overshoot`` ask
for, as today's step: the twins run both engines with ``SAME_STEP`` (the step start's lever arms,
impacts left to the step) and with the defaults. The frames' times are compared with
``SAME_STEP``: with impacts resolved, Δt follows the gaps, and the positions' round-off moves the
times by ~1e-11 of them.

The tests that run the fused kernel are in the slow profile (``-m slow``): on a machine whose
Taichi offline cache does not hold the kernel (CI's is empty) the first of them pays its compile
(README, "Performance": minutes on 2 cores), then each takes a few seconds (the kernel loaded
once for the session). The default run checks what needs no kernel: the packing of members and
the engine's choice.
"""

import dataclasses

import numpy as np
import pytest

import ddatai as dd
from ddatai.model import build_model
from ddatai.start import settle
from ddatai.step import Stepper
from scenes import example_1
from test_small_models import dropped_grid
import rocking_cases

#: today's step as the fused kernel takes it: the step start's lever arms, impacts left to the step
SAME_STEP = {"midstep_lever_arms": False, "impact_overshoot": None}


def _numpy_run(model, state, steps):
    stepper = Stepper(model)
    records = []
    for _ in range(steps):
        state, record = stepper.step(state)
        records.append(record)
    return state, records


def _fused_run(model, state, steps):
    from ddatai.fused import engine
    from ddatai.fused.pack import Member

    out = engine.run([Member(model=model, state=state, step_end=state.step + steps, record=True)])[0]
    return out


def stack_444():
    """The stack of 4-4-4 squares (tests/toppling_cases.py) on a plate tilted 20°, under sudden
    gravity: its corner pairs keep their hand-over to the vertex-edge rules from step 21 on
    (docs/method/dda.md §3.4; tests/test_handover_twins.py)."""
    from toppling_cases import CASES as TOPPLING, scene

    return scene(TOPPLING["squares 4-4-4"][0], 20.0), dd.Params(initial_equilibrium=False)


CASES = {
    "example_1_held": (lambda: example_1.build(friction=14.0), True),
    "stack_444_hand_overs": (stack_444, False),
    "example_1_sliding": (lambda: example_1.build(friction=8.0), True),
    "dropped_grid": (dropped_grid, False),
    # released at half its critical tilt: rocking on a corner through impacts within the 60 steps
    "rocking_block": (lambda: (rocking_cases.scene(0.3, 1.0, 0.5), dd.Params(initial_equilibrium=False)), False),
}


#: the step both engines take in the twins: ``SAME_STEP``, and the defaults' (the contact
#: vertices' lever arms at mid-step and resolved impacts, which the kernel also takes when asked)
STEPS = {"start_arms": SAME_STEP, "defaults": {}}


@pytest.mark.slow
@pytest.mark.parametrize("step", sorted(STEPS))
@pytest.mark.parametrize("case", sorted(CASES))
def test_fused_steps_follow_the_numpy_path(case, step):
    """The same steps from the same state (after the NumPy path's equilibrium stage where the
    case starts from one): positions within the module's tolerance and the same Δt; the solves of
    a step differ at most at two steps of the run (round-off tipping a contact across a tolerance
    of the iteration, as between today's dense and sparse solvers, tests/test_small_models.py)."""
    build, stage = CASES[case]
    scene, params = build()
    params = dataclasses.replace(params or dd.Params(), kernels="numpy", solver="dense", **STEPS[step])
    model = build_model(scene, params)
    state = model.initial_state()
    if stage:
        state, _ = settle(Stepper(model), state)
    steps = 60
    ref, records = _numpy_run(model, state, steps)
    out = _fused_run(model, state, steps)
    assert out.status == "done" and out.state.step == state.step + steps
    size = float(np.ptp(model.vertex_xy0, axis=0).max())
    moved = float(np.abs(ref.vertex_xy - state.vertex_xy).max())
    assert np.abs(out.state.vertex_xy - ref.vertex_xy).max() <= 1e-3 * moved + 1e-9 * size
    np.testing.assert_allclose(out.records["dt"], [r.dt for r in records], rtol=1e-6)
    solves = np.array([r.oc_total for r in records])
    assert np.count_nonzero(out.records["oc_total"] != solves) <= 2


@pytest.mark.slow
def test_the_largest_model_auto_runs_fused_follows_the_numpy_path():
    """The largest square dropped grid "auto" runs fused alone (``FUSED_BLOCKS``: 14 × 14 blocks),
    under ``Params(kernels="auto")`` as a user runs it: `dd.simulate`, 60 steps through its
    impacts and slips, picks the fused engine (the kernel in the process) and gives the NumPy
    path's frames and Δt within the module's tolerance (``SAME_STEP``, as the frames are compared
    above: with impacts resolved Δt follows the gaps), its solves differing at most at two steps
    (the NumPy path with SciPy's sparse LU: a dense one of 1,176 unknowns costs ~0.2 s a solve).
    ~10 s with the kernel loaded."""
    import math

    from ddatai.fused import engine, policy

    n = math.isqrt(policy.FUSED_BLOCKS)
    scene, params = dropped_grid(n)
    if not engine.LAUNCHED:  # the kernel in the process: "auto" takes it for a run of any length
        tiny = build_model(*dropped_grid(1))
        _fused_run(tiny, tiny.initial_state(), 1)
    runs = {}
    for kernels in ("auto", "numpy"):
        runs[kernels] = dd.simulate(scene, dataclasses.replace(params, kernels=kernels, solver="scipy", **SAME_STEP),
                                    steps=60, record_every=10)
    a, b = runs["auto"], runs["numpy"]
    assert b.meta["engine"]["name"] == "numpy" and len(b.vertex_offset) - 1 == n * n + 1
    assert a.meta["engine"]["name"] == "fused", a.meta["engine"]
    np.testing.assert_allclose(a.steps["dt"], b.steps["dt"], rtol=1e-6)
    size = float(np.ptp(b.vertices[0], axis=0).max())
    moved = float(np.abs(b.vertices[-1] - b.vertices[0]).max())
    assert np.abs(a.vertices - b.vertices).max() <= 1e-3 * moved + 1e-9 * size
    assert np.count_nonzero(a.steps["oc_total"] != b.steps["oc_total"]) <= 2


@pytest.mark.slow
def test_the_fused_engine_keeps_the_corner_hand_overs_of_the_numpy_path():
    """The tilted stack of squares, 60 steps: each member keeps its last step's contacts
    (its memory region) and its detection keeps a corner pair's hand-over as the NumPy path's
    does (docs/method/dda.md §3.4), so the run ends with the same contacts, and at the end the
    hand-over decides the detection (read without the last step's contacts it differs)."""
    from ddatai import vectorized

    scene, params = stack_444()
    model = build_model(scene, dataclasses.replace(params, kernels="numpy", solver="dense"))
    state = model.initial_state()
    ref, _ = _numpy_run(model, state, 60)
    out = _fused_run(model, state, 60)
    assert out.status == "done"
    xy = ref.vertex_xy
    assert not np.array_equal(vectorized.detect_contacts(model, xy, None, ref.memory.key)[0],
                              vectorized.detect_contacts(model, xy)[0])
    np.testing.assert_array_equal(out.state.memory.key, ref.memory.key)
    np.testing.assert_array_equal(out.state.memory.state, ref.memory.state)


@pytest.mark.slow
def test_simulate_on_the_fused_engine_records_the_numpy_path_s_frames():
    """`dd.simulate` with ``Params(kernels="fused")``: the same frames (every 7 steps and the last)
    and step records as the NumPy path, within the module's tolerance; ``Results.meta`` names the
    engine and why."""
    runs = {}
    for kernels in ("fused", "numpy"):
        scene, params = dropped_grid(3)
        runs[kernels] = dd.simulate(scene, dataclasses.replace(params, kernels=kernels, **SAME_STEP), steps=60,
                                     record_every=7)
    a, b = runs["fused"], runs["numpy"]
    assert a.meta["engine"] == {"name": "fused", "why": "Params(kernels='fused')"}
    assert b.meta["engine"]["name"] == "numpy"
    np.testing.assert_allclose(a.time, b.time, rtol=1e-12)
    np.testing.assert_allclose(a.steps["time"], b.steps["time"], rtol=1e-12)
    size = float(np.ptp(b.vertices[0], axis=0).max())
    moved = float(np.abs(b.vertices[-1] - b.vertices[0]).max())
    assert np.abs(a.vertices - b.vertices).max() <= 1e-3 * moved + 1e-9 * size
    assert np.count_nonzero(a.steps["oc_total"] != b.steps["oc_total"]) <= 2


@pytest.mark.slow
def test_kgm_judgements_on_the_fused_engine_are_the_numpy_path_s():
    """The block on a 30° plane judged at φ = 20°, 29°, 31° and 40° in one launch (kgm's default)
    and one by one on the NumPy path: the same verdicts, notes and step counts, displacements
    within 1e-3 of δ."""
    import kgm
    import kgm_cases
    from kgm.build import build_block_system
    from kgm.judges.batch import Member as Probe, judge_members
    from kgm.judges.run import judge

    scene, _, b = kgm_cases.block_on_incline(theta=30.0, width=2.0, height=1.0, friction=35.0, cohesion=0.0)
    system = build_block_system(scene)
    settings = kgm.DdaSettings(duration=0.5)
    probes = [20.0, 29.0, 31.0, 40.0]
    fused = judge_members([Probe(scene=scene, system=system, friction=f) for f in probes], frozenset([b]),
                          settings=settings, params=dd.Params(dt=2e-3, kernels="fused"), exact=True)
    for f, j in zip(probes, fused):
        ref = judge(scene, system, frozenset([b]), settings=settings, params=dd.Params(dt=2e-3, kernels="numpy"),
                    friction=f)
        assert (j.stable, j.note, j.steps) == (ref.stable, ref.note, ref.steps)
        assert j.displacement == pytest.approx(ref.displacement, abs=1e-3 * ref.threshold)
    assert [j.stable for j in fused] == [False, False, True, True]


@pytest.mark.slow
def test_a_member_whose_contacts_outgrow_their_region_goes_on_with_more():
    """A contact region of one contact: the member is launched again, from the start of the step
    that overflowed, with twice the room, until its contacts fit; the run is the one with room
    enough (never truncated), also where its end state is not asked for (``states=False``)."""
    from ddatai.fused import engine
    from ddatai.fused.pack import Member

    scene, params = dropped_grid(3)
    model = build_model(scene, dataclasses.replace(params, kernels="numpy"))
    state = model.initial_state()
    roomy = engine.run([Member(model=model, state=state, step_end=30)])[0]
    tight = engine.run([Member(model=model, state=state, step_end=30, contacts=1)])[0]
    assert tight.status == roomy.status == "done"
    assert tight.launches > roomy.launches
    np.testing.assert_array_equal(tight.state.vertex_xy, roomy.state.vertex_xy)
    # without the end states (a batch of judgements): the same run, its state not read back
    light = engine.run([Member(model=model, state=state, step_end=30, contacts=1)], states=False)[0]
    assert light.status == "done" and light.state is None and light.launches == tight.launches
    np.testing.assert_array_equal(light.history, tight.history)


@pytest.mark.slow
def test_a_step_the_engine_cannot_take_is_taken_on_today_s_path():
    """A step that no Δt above the shortest makes converge (``dt_min_ratio`` close to 1, a block
    thrown onto a plane): the fused engine hands it to today's path, which raises the error it
    raises alone, with the same step and cause."""
    errors = {}
    for kernels in ("fused", "numpy"):
        s = dd.Scene(gravity=9.81)
        rock = dd.Material(density=2500.0, young=5e9, poisson=0.25)
        s.add_block([(-2, -1), (4, -1), (4, 0), (-2, 0)], material=rock, fixed=True)
        s.add_block([(0, 0.02), (1, 0.02), (1, 1.02), (0, 1.02)], material=rock, velocity=(0.0, -8.0))
        params = dd.Params(dt=0.05, dt_min_ratio=0.5, initial_equilibrium=False, kernels=kernels)
        with pytest.raises(dd.SimulationError) as err:
            dd.simulate(s, params, steps=40)
        errors[kernels] = err.value
    assert (errors["fused"].step, errors["fused"].cause) == (errors["numpy"].step, errors["numpy"].cause)


def test_auto_takes_the_fused_engine_where_it_pays(monkeypatch):
    """``Params(kernels="auto")``: a small model's long run on the fused engine once the kernel is
    compiled (cached); a short run, a model the engine does not cover, or many free blocks on
    today's path; each with its reason."""
    from ddatai.fused import policy

    scene, params = dropped_grid(2)
    model = build_model(scene, params)
    monkeypatch.setattr(policy, "_loaded", lambda: False)
    monkeypatch.setattr(policy, "kernel_cached", lambda arch="cpu": True)
    assert policy.choose(model, steps=100_000, duration=None)[0] == "fused"
    name, why = policy.choose(model, steps=10, duration=None)
    assert name == "numpy" and "do not pay" in why
    monkeypatch.setattr(policy, "kernel_cached", lambda arch="cpu": False)
    assert policy.choose(model, steps=100_000, duration=None)[0] == "numpy"
    assert policy.choose(model, steps=10, duration=None, batch=True)[0] == "fused"
    name, why = policy.choose(model, steps=10 ** 7, duration=None, record_contacts=True)
    assert name == "numpy" and "contacts are recorded" in why
    # kgm's batches: "fused" always; "auto" once the kernel is in the process, or where the
    # batch pays its load (cached) or its first compile; never on a fresh machine for a few runs
    auto, fused = dd.Params(), dd.Params(kernels="fused")
    assert policy.choose_batch(fused, member_steps=10)[0] == "fused"
    assert policy.choose_batch(dd.Params(kernels="numpy"), member_steps=1e9)[0] == "today"
    name, why = policy.choose_batch(auto, member_steps=8 * 1000)
    assert name == "today" and "first compile" in why
    assert policy.choose_batch(auto, member_steps=1e8)[0] == "fused"
    monkeypatch.setattr(policy, "kernel_cached", lambda arch="cpu": True)
    assert policy.choose_batch(auto, member_steps=8 * 1000)[0] == "today"
    assert policy.choose_batch(auto, member_steps=400 * 1000)[0] == "fused"
    monkeypatch.setattr(policy, "_loaded", lambda: True)
    assert policy.choose_batch(auto, member_steps=10)[0] == "fused"
    shaken = dropped_grid(2)[0]
    shaken.set_ground_acceleration(lambda t: (0.1, 0.0))
    name, why = policy.choose(build_model(shaken, params), steps=10, duration=None, batch=True)
    assert name == "numpy" and "shaken" in why


@pytest.mark.gpu
def test_fused_engine_on_cuda_follows_the_numpy_path():
    """The fused engine on a CUDA GPU (one thread a member there too): the NumPy path's run of
    Example I at 8°, of the dropped grid and of the tilted stack of squares through its corner
    hand-overs, within the module's tolerance (a subprocess: the test session's Taichi runs on
    the CPU)."""
    import shutil
    import subprocess
    import sys
    from pathlib import Path

    if shutil.which("nvidia-smi") is None:
        pytest.skip("no CUDA device (nvidia-smi not found)")
    root = Path(__file__).resolve().parents[1]
    code = f"""
import sys, dataclasses
sys.path[:0] = [{str(root)!r}, {str(root / 'tests')!r}]
import numpy as np
import ddatai as dd
from ddatai.model import build_model
from ddatai.start import settle
from ddatai.step import Stepper
from ddatai.fused import engine
from ddatai.fused.pack import Member
from scenes import example_1
from test_fused import dropped_grid, stack_444, _numpy_run, SAME_STEP
for build, stage in ((lambda: example_1.build(friction=8.0), True), (dropped_grid, False), (stack_444, False)):
    scene, params = build()
    model = build_model(scene, dataclasses.replace(params or dd.Params(), kernels="numpy", solver="dense", **SAME_STEP))
    state = model.initial_state()
    if stage:
        state, _ = settle(Stepper(model), state)
    ref, _ = _numpy_run(model, state, 60)
    out = engine.run([Member(model=model, state=state, step_end=state.step + 60)], arch="cuda")[0]
    size = float(np.ptp(model.vertex_xy0, axis=0).max())
    moved = float(np.abs(ref.vertex_xy - state.vertex_xy).max())
    assert out.status == "done", out.status
    assert np.abs(out.state.vertex_xy - ref.vertex_xy).max() <= 1e-3 * moved + 1e-9 * size
print("ok")
"""
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=900)
    assert proc.returncode == 0 and proc.stdout.strip().endswith("ok"), proc.stderr[-3000:]


def test_members_packed_side_by_side_come_back_as_they_went_in():
    """`ddatai.fused.pack` (NumPy, no Taichi): two members with contact memory (a dropped grid
    after 20 steps of the NumPy path, Example I after its stage) laid side by side in the
    engine's arrays come back bit for bit: positions, velocities, stresses, Δt and the contact
    memory keyed as today's path keys it. The blocks' geometry, computed over the launch's
    vertices at once, is each member's own to the bit (`Model.block_geometry` and
    `block_radius` at its state and at its start, the weight scale ρ·A₀·|g|)."""
    from ddatai.fused import layout as L
    from ddatai.fused.pack import Member, pack, unpack_state
    from ddatai.kinematics import block_radius

    scene, params = dropped_grid(3)
    grid = build_model(scene, dataclasses.replace(params, kernels="numpy"))
    grid_state, _ = _numpy_run(grid, grid.initial_state(), 20)
    scene, params = example_1.build(friction=14.0)
    ex1 = build_model(scene, dataclasses.replace(params or dd.Params(), kernels="numpy"))
    ex1_state, _ = settle(Stepper(ex1), ex1.initial_state())
    members = [Member(model=grid, state=grid_state, step_end=40), Member(model=ex1, state=ex1_state, step_end=40)]
    arrays = pack(members, 16)
    for k, (m, state) in enumerate(zip(members, (grid_state, ex1_state))):
        back = unpack_state(arrays, k, m)
        assert len(state.memory.key) > 0
        for name in ("vertex_xy", "block_velocity", "block_accel", "block_stress", "block_rotation"):
            np.testing.assert_array_equal(getattr(back, name), getattr(state, name), err_msg=name)
        assert (back.time, back.step, back.dt) == (state.time, state.step, state.dt)
        for name in ("key", "state", "line", "omega", "bond", "shear_dir", "dn", "normal_force", "kind"):
            np.testing.assert_array_equal(getattr(back.memory, name), getattr(state.memory, name), err_msg=name)
        b0, b1 = arrays["mi"][k, L.MI_B0], arrays["mi"][k, L.MI_B1]
        got, mo = arrays["bgeo"][b0:b1], m.model
        now, start = mo.block_geometry(state.vertex_xy), mo.block_geometry(mo.vertex_xy0)
        assert not np.array_equal(state.vertex_xy, mo.vertex_xy0)
        for col, want in ((L.BG_AREA, now["area"]), (L.BG_CX, now["centroid"][:, 0]), (L.BG_CY, now["centroid"][:, 1]),
                          (L.BG_S1, now["s1"]), (L.BG_S2, now["s2"]), (L.BG_S3, now["s3"]),
                          (L.BG_RADIUS, block_radius(mo, state.vertex_xy, now["centroid"])),
                          (L.BG_RADIUS0, block_radius(mo, mo.vertex_xy0, start["centroid"])),
                          (L.BG_LOAD, mo.block_density * start["area"] * float(np.hypot(*mo.gravity)))):
            np.testing.assert_array_equal(got[:, col], want, err_msg=str(col))


@pytest.mark.slow
def test_a_dda_judged_study_on_the_fused_engine_has_the_numpy_path_s_table(monkeypatch):
    """Example II's DDA-judged study (friction N(22°, 2°), cohesion N(20 kPa, 5 kPa), 12 samples,
    one worker, the paper's Δt): the same verdict for every sample on the fused engine (one
    launch) as on today's path, and the same probability of failure."""
    from pathlib import Path

    from ddatai.parallel import ScriptFunction
    from kgm.settings import DdaSettings, Settings
    from kgm.studies.probabilistic import probabilistic
    from kgm.studies.sampling import read_variables

    from ddatai.fused import engine

    launched = []
    run = engine.run
    monkeypatch.setattr(engine, "run", lambda members, **kw: launched.append(len(members)) or run(members, **kw))
    root = Path(__file__).resolve().parents[1]
    variables, correlation = read_variables(root / "docs" / "kgm" / "example_2_vars.toml")
    build = ScriptFunction(str(root / "scenes" / "example_2.py"))
    tables = {}
    for kernels in ("fused", "numpy"):
        settings = Settings(dda=DdaSettings(params=dd.Params(dt=0.0013, penalty_ratio=1.0, kernels=kernels)))
        study = probabilistic(build, variables, 12, method="dda", seed=1, group={0, 1}, correlation=correlation,
                              workers=1, settings=settings)
        tables[kernels] = (np.asarray(study.table["failed"]).tolist(), study.pf)
        if kernels == "fused":
            assert sum(launched) == 12  # every sample judged on the fused engine
    assert tables["fused"] == tables["numpy"]
    assert 0 < sum(tables["fused"][0]) < 12


@pytest.mark.slow
def test_a_study_on_local_workers_runs_the_fused_kernel_in_one_process():
    """Example II's DDA-judged study (12 samples) on 2 local workers: one settles each batch in
    NumPy and the other, the only one that loads the fused kernel, runs them
    (`kgm.studies.probabilistic._prepared_then_run`): the same table as in this process. 54 s
    on the shared 2-core machine at a load of ~10 (the kernel loaded in two processes)."""
    from pathlib import Path

    from ddatai.parallel import ScriptFunction
    from kgm.settings import DdaSettings, Settings
    from kgm.studies.probabilistic import probabilistic
    from kgm.studies.sampling import read_variables

    root = Path(__file__).resolve().parents[1]
    variables, correlation = read_variables(root / "docs" / "kgm" / "example_2_vars.toml")
    build = ScriptFunction(str(root / "scenes" / "example_2.py"))
    settings = Settings(dda=DdaSettings(params=dd.Params(dt=0.0013, penalty_ratio=1.0, kernels="fused")))
    tables = []
    for workers in (2, 1):
        study = probabilistic(build, variables, 12, method="dda", seed=1, group={0, 1}, correlation=correlation,
                              workers=workers, settings=settings)
        tables.append((np.asarray(study.table["failed"]).tolist(), study.pf))
    assert tables[0] == tables[1]
    assert 0 < sum(tables[0][0]) < 12


@pytest.mark.slow
def test_the_fused_impact_retake_starts_from_the_first_try_s_states():
    """The kernel's twin of tests/test_impacts.py's retake: the rocking block's two impact steps
    in 150 steps, each first try three solves, each retake one (from the first try's converged
    states, left in place by `ddatai.fused.step`), as on the NumPy path."""
    from test_impacts import numpy_records, retakes, rocking_model

    def fused(model, state, steps):
        out = _fused_run(model, state, steps)
        assert out.status == "done"
        return out.records["oc_total"], out.records["oc_iterations"]

    model = rocking_model()
    got = retakes(model, 150, fused)
    np.testing.assert_array_equal(got, retakes(model, 150, numpy_records))
    assert np.all(got[0] == 3) and np.all(got[1] == 1) and len(got[1]) == 2, got
