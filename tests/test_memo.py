"""A scene built again at another strength reuses its geometric checks and searches
(`ddatai.memo`), and every result is the one computed afresh, to the bit."""

import importlib.util
from pathlib import Path

import numpy as np
import pytest

import ddatai as dd
from ddatai import geometry
from ddatai.memo import GeometryMemo, key
from ddatai.model import build_model
from kgm import build as kgm_build

ROOT = Path(__file__).resolve().parents[1]


def _example_2():
    spec = importlib.util.spec_from_file_location("example_2_scene", ROOT / "scenes" / "example_2.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod.build


def _same(a, b, where=""):
    """Equal to the bit, field by field (arrays, dataclasses, containers, numbers)."""
    if isinstance(a, np.ndarray):
        assert isinstance(b, np.ndarray) and a.dtype == b.dtype and a.shape == b.shape, where
        assert a.tobytes() == b.tobytes(), where
    elif hasattr(a, "__dataclass_fields__"):
        assert type(a) is type(b), where
        for f in a.__dataclass_fields__:
            _same(getattr(a, f), getattr(b, f), f"{where}.{f}")
    elif isinstance(a, dict):
        assert a.keys() == b.keys(), where
        for k in a:
            _same(a[k], b[k], f"{where}[{k!r}]")
    elif isinstance(a, (list, tuple)):
        assert len(a) == len(b), where
        for i, (x, y) in enumerate(zip(a, b)):
            _same(x, y, f"{where}[{i}]")
    elif isinstance(a, float) and np.isnan(a):
        assert isinstance(b, float) and np.isnan(b), where
    else:
        assert a == b, where


def _clear():
    geometry._POLYGONS.clear()
    geometry._OVERLAP_FREE.clear()
    kgm_build._CONTACTS.clear()
    kgm_build._SYSTEMS.clear()


def test_a_study_scene_built_again_is_the_scene_built_afresh():
    """Example II at three strengths, each built, its block system and its model made with
    the memos warm and again with them cleared: the same arrays to the bit, and the memos
    hit on the second and later strengths."""
    build = _example_2()
    strengths = [(22.0, 2e4), (19.5, 1.2e4), (25.1, 8.1e3)]
    _clear()
    warm = []
    for friction, cohesion in strengths:
        scene, params = build(friction=friction, cohesion=cohesion)
        warm.append((scene, kgm_build.build_block_system(scene), build_model(scene, params)))
    assert kgm_build._SYSTEMS.hits == 2 and geometry._OVERLAP_FREE.hits >= 2
    assert geometry._POLYGONS.hits >= 2 * scene.n_blocks
    for (friction, cohesion), (scene_w, system_w, model_w) in zip(strengths, warm):
        _clear()
        scene, params = build(friction=friction, cohesion=cohesion)
        system = kgm_build.build_block_system(scene)
        model = build_model(scene, params)
        for a, b in zip(scene_w.blocks, scene.blocks):
            _same(a, b, "block")
        _same(system_w, system, "system")
        _same(vars(model_w), vars(model), "model")


def test_a_result_handed_out_is_a_copy():
    """A caller that changes what it got does not change the next caller's result."""
    square = [(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)]
    first = dd.validate_polygon(square)
    first[0] = (9.0, 9.0)
    assert np.array_equal(dd.validate_polygon(square), np.array(square))
    memo = GeometryMemo(2)
    got = memo.get(key(np.arange(3.0)), lambda: [(1, 2.0)])
    got.append((3, 4.0))
    assert memo.get(key(np.arange(3.0)), lambda: None) == [(1, 2.0)]


def test_bad_input_is_refused_every_time():
    """Errors are never kept: an overlapping pair or a bad polygon raises at each call."""
    for _ in range(2):
        with pytest.raises(ValueError, match="block 7: polygon has zero area"):
            dd.validate_polygon([(0, 0), (1, 1), (1, 0), (0, 1)], name="block 7")
        scene = dd.Scene()
        m = dd.Material(density=2600.0, young=1e9, poisson=0.25)
        scene.add_block([(0, 0), (2, 0), (2, 1), (0, 1)], material=m, fixed=True)
        scene.add_block([(1, 0.5), (3, 0.5), (3, 1.5), (1, 1.5)], material=m)
        with pytest.raises(ValueError, match="blocks 0 and 1 overlap"):
            kgm_build.build_block_system(scene)


def test_the_memo_keeps_only_its_most_recent_entries():
    memo = GeometryMemo(2)
    for i in range(3):
        memo.get(key(np.full(2, float(i))), lambda i=i: float(i))
    assert memo.misses == 3
    memo.get(key(np.full(2, 0.0)), lambda: -1.0)  # dropped: computed again
    assert memo.misses == 4
    assert memo.get(key(np.full(2, 2.0)), lambda: -1.0) == 2.0
    assert memo.hits == 1


def test_threads_share_the_memo_safely():
    """A study's threaded workers build their scenes at once: every thread gets the result
    computed alone."""
    from concurrent.futures import ThreadPoolExecutor

    memo = GeometryMemo(3)
    arrays = [np.full((4, 2), float(i % 5)) for i in range(200)]

    def one(a):
        return memo.get(key(a), lambda: a.sum())

    with ThreadPoolExecutor(4) as pool:
        got = list(pool.map(one, arrays))
    assert got == [a.sum() for a in arrays]
    assert memo.hits + memo.misses == 200


def test_a_large_scene_is_checked_without_the_memo(monkeypatch):
    """Scenes above MEMO_SCENE_VERTICES are checked and searched afresh, nothing kept."""
    monkeypatch.setattr(geometry, "MEMO_SCENE_VERTICES", 3)
    monkeypatch.setattr(kgm_build, "MEMO_SCENE_VERTICES", 3)
    _clear()
    scene, _ = _example_2()()
    for _ in range(2):
        kgm_build.build_block_system(scene)
    assert geometry._OVERLAP_FREE.hits + geometry._OVERLAP_FREE.misses == 0
    assert kgm_build._CONTACTS.hits + kgm_build._CONTACTS.misses == 0
