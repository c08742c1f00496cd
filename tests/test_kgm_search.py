"""kgm key-group search (docs/kgm/method.md §3): greedy against exhaustive enumeration on small
models, progressive removal, the report, and bad input."""

import itertools

import numpy as np
import pytest

import ddatai as dd
import kgm
from kgm.build import build_block_system
from kgm.faces import is_connected
from kgm.candidates import connected_groups
from kgm_cases import ROCK, bent_chain, planar_slope
from scenes import example_1, example_2

SMALL_MODELS = {
    "example_1": lambda: example_1.build()[0],
    "example_1_phi15": lambda: example_1.build(friction=15.0)[0],
    "example_2": lambda: example_2.build()[0],
    "example_2_reconstruction": lambda: example_2.build(cross_joint_offset=0.0, cross_joint_angle=45.0)[0],
    "bent_chain": lambda: bent_chain()[0],
    "bent_chain_cohesive": lambda: bent_chain(friction=20.0, cohesion=30e3)[0],
}


@pytest.mark.parametrize("method", ["rigid", "sarma"])
@pytest.mark.parametrize("model", sorted(SMALL_MODELS))
def test_greedy_finds_the_exhaustive_minimum(model, method):
    """On small models the greedy search ends on the least safe key group of all connected
    groups (same group, same FS)."""
    scene = SMALL_MODELS[model]()
    rep = kgm.analyze(scene, method=method)
    best = kgm.exhaustive(scene, method=method, max_size=4)
    assert rep.critical is not None and best
    assert rep.critical.blocks == best[0][0]
    assert rep.critical.fs == pytest.approx(best[0][1], rel=1e-12)


def test_key_groups_of_the_examples():
    """Example I: the two-block group {B1, B2} at φc 11.02°; Example II: rigid stable, Sarma
    unstable on the same group {P, A}; the seeds include type-III blocks."""
    rep = kgm.analyze(example_1.build()[0], method="rigid")
    assert rep.critical.blocks == frozenset({0, 1})
    assert rep.critical.critical_friction == pytest.approx(11.02, abs=0.005)
    assert rep.block_types == {0: "II", 1: "III", 2: "III", 3: "V"}
    assert kgm.key_blocks(build_block_system(example_1.build()[0])) == [0, 1, 2]
    scene = example_2.build()[0]
    rigid, sarma = kgm.analyze(scene, method="rigid"), kgm.analyze(scene, method="sarma")
    assert rigid.critical.blocks == sarma.critical.blocks == frozenset({0, 1})
    assert rigid.critical.stable and not sarma.critical.stable
    assert rigid.critical.mode.kind.value == "sliding" and sarma.critical.mode.kind.value == "sarma"


def test_a_group_fails_where_no_single_block_does():
    """The bent chain: alone the toe block is safe (FS 2.6) and the others have no mode, but the
    three fail together in Sarma's mechanism — found only because type-III blocks are seeds
    and groups grow (§3.1)."""
    scene, ids = bent_chain()
    rep = kgm.analyze(scene, method="sarma")
    assert all(rep.block_types[b] in ("II", "III") for b in ids)
    assert rep.critical.blocks == frozenset(ids) and rep.critical.fs < 1.0


def test_connected_groups_enumerates_each_connected_subset_once():
    """ESU enumeration against brute force over all subsets of a cut block system."""
    scene = dd.Scene()
    joints = [([(-1, y), (11, y + 1.5)], dd.Joint()) for y in (2.0, 5.0, 8.0)] + \
             [([(x, -1), (x + 2, 11)], dd.Joint()) for x in (2.0, 6.0)]
    scene.cut([(0, 0), (10, 0), (10, 10), (0, 10)], joints, material=ROCK)
    scene.set_fixed(0)
    s = build_block_system(scene)
    free = [b for b in range(s.n_blocks) if not s.block_fixed[b]]
    got = list(connected_groups(s, 4))
    assert len(got) == len(set(got))
    want = {frozenset(c) for k in range(1, 5) for c in itertools.combinations(free, k)
            if is_connected(s, frozenset(c))}
    assert set(got) == want


def test_progressive_removal_order_and_surface():
    """Two planar slides side by side on one fixed base: the less safe goes first, then the
    other; the failure surface is where the removed blocks met the rock."""
    scene = dd.Scene()
    scene.add_block([(-30, -10), (30, -10), (30, 0), (-30, 0)], material=ROCK, fixed=True)
    weak = scene.add_block([(-10, 0), (-6, 0), (-6, 1), (-10, 1)], material=ROCK)
    weaker = scene.add_block([(6, 0), (10, 0), (10, 1), (6, 1)], material=ROCK)
    # the ground is flat: give the blocks a push with point loads so they can slide
    scene.add_point_load(weak, (-8, 0.5), (0.6 * 2500 * 9.81 * 4, 0.0))
    scene.add_point_load(weaker, (8, 0.5), (0.7 * 2500 * 9.81 * 4, 0.0))
    scene.set_joint(dd.Joint(friction=30.0))
    rep = kgm.analyze(scene, method="rigid", progressive=True)
    assert rep.removed == (frozenset({weaker}), frozenset({weak}))
    tan30 = np.tan(np.radians(30))
    assert [h.fs for h in rep.history] == pytest.approx([tan30 / 0.7, tan30 / 0.6])
    assert len(rep.failure_surface) == 2
    assert sorted(tuple(line[:, 0].round(9)) for line in rep.failure_surface) == [(-10, -6), (6, 10)]


def test_report_fields_and_table():
    """The report's public fields and its text table."""
    rep = kgm.analyze(example_2.build()[0], method="sarma")
    c = rep.critical
    assert isinstance(c.blocks, frozenset) and c.evaluator == "sarma" and c.verdict == "unstable"
    assert c.critical_acceleration < 0 and c.mode.block_velocity is not None
    assert len(c.surface) == 2  # J2 above Q' and J1: the interface part of J2 opens
    assert "{0, 1}" in rep.table() and "sarma" in rep.table()
    assert rep.history == (c,) and rep.removed == ()
    table = kgm.format_paper_table([kgm.evaluate(example_2.build()[0], [0, 1], m) for m in ("rigid", "sarma")])
    assert "| KGM (rigid group) | 1.586 | 13.87° | stable |" in table
    assert "| SKGM (Sarma) | 0.771 | 28.23° | unstable |" in table


def test_bad_input_is_named():
    scene = example_1.build()[0]
    with pytest.raises(ValueError, match="unknown block id 9"):
        kgm.factor_of_safety(scene, [0, 9], method="rigid")
    with pytest.raises(ValueError, match="empty"):
        kgm.factor_of_safety(scene, [], method="rigid")
    with pytest.raises(ValueError, match="block 3 is fixed"):
        kgm.critical_friction(scene, [1, 3], method="sarma")
    with pytest.raises(ValueError, match="unknown method 'fem'"):
        kgm.analyze(scene, method="fem")
    with pytest.raises(ValueError, match="not connected"):
        kgm.factor_of_safety(scene, [0, 2], method="rigid")
    with pytest.raises(ValueError, match="integer"):
        kgm.factor_of_safety(scene, ["a"], method="rigid")
    with pytest.raises(ValueError, match="ddatai.Scene"):
        kgm.analyze("scene.py")
    with pytest.raises(ValueError, match="Settings.max_group_size"):
        kgm.Settings(max_group_size=0)
    with pytest.raises(ValueError, match="DdaSettings.displacement_ratio"):
        kgm.DdaSettings(displacement_ratio=-1.0)
    with pytest.raises(ValueError, match="DdaSettings.rest_ratio must be between 0 and 1e-3"):
        kgm.DdaSettings(rest_ratio=0.5)
    with pytest.raises(ValueError, match="DdaSettings.rest_steps"):
        kgm.DdaSettings(rest_steps=0)
    with pytest.raises(ValueError, match="Settings.screening"):
        kgm.Settings(screening="dda")
    with pytest.raises(ValueError, match="exhaustive"):
        kgm.exhaustive(scene, method="dda")


def test_planar_slope_search_returns_the_single_key_block():
    scene, b = planar_slope()
    rep = kgm.analyze(scene, method="rigid")
    assert rep.critical.blocks == frozenset({b}) and rep.block_types[b] == "II"
