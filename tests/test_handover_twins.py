"""The persistent corner hand-over (docs/method/dda.md §3.4) in the three implementations of the
detection: a vertex pair that had a vertex-edge contact on an edge at its partner last step keeps
the vertex-edge rules while either vertex projects onto an edge at its partner beyond round-off
and lies on or behind its line (within h1). The NumPy narrow phase (`ddatai.narrow`) is the
reference; the Taichi narrow phase (`ddatai.contacts.detect_contacts`, ``last_keys``) reads the
last step's sorted contact keys as its memory rows (`ddatai.contacts.memory_rows`), and the fused
engine its members' memory regions (the fused twin is in tests/test_fused.py, slow)."""

import dataclasses

import numpy as np
import pytest

import ddatai as dd
from cases import ROCK, random_jointed_scene
from ddatai import vectorized
from ddatai.contacts import _Buffers, contact_keys, detect_contacts, memory_rows
from ddatai.layout import VE, VV
from ddatai.model import build_model
from ddatai.step import Stepper
from test_vectorized import SHIFTS, _moved, _passed_corners
from toppling_cases import CASES, ramp_handovers, scene


def _keys(model, cint):
    return np.sort(contact_keys(cint, model.n_vertices))


def _same(model, xy, keys):
    """The kernel path's contacts with the last step's ``keys`` == the NumPy path's."""
    cint_v, length_v = vectorized.detect_contacts(model, xy, None, keys)
    cint_k, length_k = detect_contacts(model, xy, _Buffers(), keys)
    assert np.array_equal(cint_k, cint_v)
    d0 = model.search_distance
    assert np.allclose(length_k, length_v, rtol=1e-12, atol=1e-12 * d0)
    return cint_v


#: the passed corners (``test_vectorized._passed_corners``: Q behind block 0's top edge by
#: ``depth``, the upper row slid by ``slide``) read with the keys of their hand-over at 1e-4
#: deep: whether the pair stays handed over (two vertex-edge contacts) or is a vertex-vertex
#: contact again
PERSIST = {"1e-12 behind the line": (1e-12, 2e-3, True), "on the line": (0.0, 2e-3, True),
           "the rows slid back": (1e-12, -2e-3, False), "0.1 µm clear of the line": (-1e-7, 2e-3, False)}


@pytest.mark.parametrize("case", list(PERSIST))
def test_the_kernel_path_keeps_and_ends_the_hand_over_as_the_numpy_path(case):
    """Read with the last step's keys, the Taichi narrow phase keeps the hand-over of the passed
    corners 1e-12 behind and on the line, and ends it where the rows slid back or the vertex is
    0.1 µm clear of the line, as the NumPy narrow phase; read without keys both give the pair's
    one vertex-vertex contact (or, slid back, none of the pair's vertex-edge contacts)."""
    depth, slide, kept = PERSIST[case]
    model, deep, P, Q = _passed_corners(1e-4)
    handed = _keys(model, vectorized.detect_contacts(model, deep)[0])
    assert {(VE, Q, P), (VE, P, Q)} <= {tuple(r[:3]) for r in vectorized.detect_contacts(model, deep)[0].tolist()}
    _, xy, _, _ = _passed_corners(depth, slide=slide)
    pair = {(VE, Q, P, -1, -1), (VE, P, Q, -1, -1)}
    fresh = _same(model, xy, None)
    assert not {tuple(r) for r in fresh.tolist()} & pair
    cint = _same(model, xy, handed)
    assert ({tuple(r) for r in cint.tolist()} & pair == pair) == kept
    b = model.vertex_block
    diagonal = [r[0] for r in cint.tolist() if {b[r[1]], b[r[2]]} == {0, 3}]
    if kept:
        assert VV not in diagonal
    elif slide > 0:
        assert np.array_equal(cint, fresh)


def test_memory_rows_are_the_vertex_edge_keys_in_their_order():
    """(kind 0, vertex, edge) of each vertex-edge key (vertex·n + edge), in the keys' order; the
    vertex-vertex keys (n² + vertex·n + vertex) are left out."""
    n = 10
    keys = np.array([3, 27, 28, 91, n * n + 12, n * n + 45], np.int64)
    rows = memory_rows(keys, n)
    assert rows.dtype == np.int32
    assert rows.tolist() == [[0, 0, 3], [0, 2, 7], [0, 2, 8], [0, 9, 1]]
    assert memory_rows(np.zeros(0, np.int64), n).shape == (0, 3)


def _every_vertex_edge_key(model):
    """The keys of every vertex-edge identity between two blocks: each vertex pair of a
    corner contact was handed over "last step"."""
    v, e = np.meshgrid(np.arange(model.n_vertices), np.arange(model.n_vertices), indexing="ij")
    other = model.vertex_block[v] != model.vertex_block[e]
    return np.sort(v[other].astype(np.int64) * model.n_vertices + e[other])


def _slid_rows(seed: int, n: int = 4):
    """An n × n grid of unit squares on a fixed bottom row, each upper row slid along the joints
    (2 mm either way, or 1 cm), sunk or lifted (0, 1e-12, 1e-5 behind; 0.1 µm clear) and its
    blocks turned (0 or ±0.1° about their lower left corners): X-junctions whose diagonal
    corners have passed each other, on, behind and clear of each other's edges."""
    scene = dd.Scene(gravity=9.81)
    for j in range(n):
        for i in range(n):
            scene.add_block([(i, j), (i + 1, j), (i + 1, j + 1), (i, j + 1)], material=ROCK, fixed=j == 0)
    model = build_model(scene)
    rng = np.random.default_rng(seed)
    xy = model.vertex_xy0.copy()
    slide, sink = rng.choice([-2e-3, 2e-3, -1e-2], n), rng.choice([0.0, -1e-12, 1e-7, -1e-5], n)
    for k in range(n, model.n_blocks):
        m = model.vertex_block == k
        corner = xy[model.vertex_offset[k]].copy()
        turn = np.radians(rng.choice([0.0, 0.0, 0.1, -0.1]))
        c, s = np.cos(turn), np.sin(turn)
        rel = xy[m] - corner
        xy[m] = corner + np.stack([c * rel[:, 0] - s * rel[:, 1], s * rel[:, 0] + c * rel[:, 1]], axis=1)
        xy[m] += (slide[k // n], sink[k // n])
    return model, xy


def test_with_every_vertex_edge_identity_remembered_the_kernel_path_is_the_numpy_path():
    """With every vertex pair taken as handed over last step, the persist test decides every
    corner pair in both narrow phases, and they give the same contacts: on grids of squares
    whose rows slid (some pairs kept handed over, some vertex-vertex contacts still) and on
    random jointed scenes, at the cut geometry and moved (round-off to beyond d9)."""
    kept = vv = 0
    for seed in range(5):
        model, xy = _slid_rows(seed)
        keys = _every_vertex_edge_key(model)
        cint = _same(model, xy, keys)
        kept += not np.array_equal(cint, _same(model, xy, None))
        vv += int(np.count_nonzero(cint[:, 0] == VV))
    assert kept >= 2 and vv  # the rule changed some detections and left some vertex-vertex contacts
    for seed in range(2):
        model = build_model(random_jointed_scene(seed))
        keys = _every_vertex_edge_key(model)
        for k, shift in enumerate(SHIFTS):
            _same(model, _moved(model, 50 + seed + k, shift), keys)


def _stack_444(kernels: str):
    """The stack of 4-4-4 squares (tests/toppling_cases.py) on a plate tilted 20°, under sudden
    gravity: its corner pairs keep their hand-over from step 21 on (detection with the last
    step's keys differs from the one without at 39 of the first 60 steps)."""
    params = dd.Params(initial_equilibrium=False, kernels=kernels, solver="scipy")
    return build_model(scene(CASES["squares 4-4-4"][0], 20.0), params)


@pytest.mark.slow
def test_the_kernel_path_follows_the_numpy_path_through_a_stack_s_hand_overs():
    """60 steps of the tilted stack on both paths (the same solver): the same contacts every
    step, the same solves, positions within 1e-9 of the model's size (the twins' tolerance,
    tests/test_small_models.py); and the hand-over decided the detection at a dozen steps or
    more of the run. ~7 s (the kernels loaded; the machine shared)."""
    models = {k: _stack_444(k) for k in ("numpy", "taichi")}
    assert models["numpy"].numpy_path and not models["taichi"].numpy_path
    steppers = {k: Stepper(m) for k, m in models.items()}
    states = {k: m.initial_state() for k, m in models.items()}
    model = models["numpy"]
    size = float(np.ptp(model.vertex_xy0, axis=0).max())
    persisted = 0
    for _ in range(60):
        state = states["numpy"]
        if len(state.memory.key):
            with_keys = vectorized.detect_contacts(model, state.vertex_xy, None, state.memory.key)[0]
            persisted += not np.array_equal(with_keys, vectorized.detect_contacts(model, state.vertex_xy)[0])
        records = {}
        for k in states:
            states[k], records[k] = steppers[k].step(states[k])
        assert np.array_equal(states["taichi"].memory.key, states["numpy"].memory.key)
        assert records["taichi"].oc_total == records["numpy"].oc_total
        assert np.abs(states["taichi"].vertex_xy - states["numpy"].vertex_xy).max() < 1e-9 * size
    assert persisted >= 12, persisted


@pytest.mark.slow
def test_the_push_block_on_the_kernel_path_takes_ntdda_s_500_steps():
    """ntdda's push block (tests/test_ntdda.py) through `dd.simulate` on the Taichi kernels: the
    block pushed off its base's edge ends the hand-over at its corner once clear of the line,
    so that no open contact at the edge's end cuts a step: 500 steps as ntdda, the load point at
    156.39 (the analytic 17.5 + ½(F/m)t² to 3e-4, as the NumPy path). ~9 s (the machine
    shared; the NumPy path's run, tests/test_ntdda.py, ~7 s)."""
    from test_ntdda import data

    case = dd.read_ntdda(data("pushblock.geo"), data("pushblock.ana"))
    params = dataclasses.replace(case.params, kernels="taichi")
    assert not build_model(case.scene, params).numpy_path
    res = dd.simulate(case.scene, params, duration=case.duration, record_every=case.record_every)
    (load,) = case.points
    assert len(res.steps) == 500 and res.time[-1] == pytest.approx(5.0, abs=1e-9)
    assert res.measured[-1, load.index, 0] == pytest.approx(17.5 + 0.5 * (5000.0 / 450.0) * 5.0 ** 2, rel=3e-4)


@pytest.mark.slow
def test_the_kernel_path_keeps_the_4_5_6_7_stack_s_hand_overs_as_the_numpy_path():
    """The 4-5-6-7 squares under the turned 20-constant ramp at 18° on the Taichi kernels
    (`toppling_cases.ramp_handovers`; the NumPy path's check is
    tests/test_toppling_start.py::test_the_persistent_corner_hand_over_on_the_4_5_6_7_slow_load):
    measured 6 hand-overs in 6 of 652 steps, the largest kick 0.06 g·Δt, the stack stands, as on
    the NumPy path (read afresh each step: 2,018 hand-overs, and the kicks toppled it). ~25 s
    loaded."""
    out = ramp_handovers(CASES["squares 4-5-6-7"][0], 18.0, "turned", 20.0, kernels="taichi")
    assert not out["toppled"]
    assert out["handovers"] <= 10 and out["steps_with"] <= 10, out
    assert out["kick"] < 1.0, out
