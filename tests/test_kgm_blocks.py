"""kgm block theory (docs/kgm/method.md §2): contacts from shared edges, free faces, the
half-circle removability test, kinematic modes and block types on hand-made cases."""

import math

import numpy as np
import pytest

import ddatai as dd
import kgm
from kgm.build import build_block_system
from kgm.faces import is_removable, removable_arc
from kgm.judges.rigid import classify_blocks, rigid_modes
from kgm.kinds import ModeKind
from kgm_cases import (ROCK, block_above_incline, block_on_incline, hanging_block, planar_slope, slot_block,
                       tapered_block)
from scenes import example_1, example_2


def _normals(*deg):
    return np.array([(math.cos(math.radians(a)), math.sin(math.radians(a))) for a in deg])


def test_half_circle_test():
    """JP = {s: s·n ≥ 0}: non-empty iff the normals fit in a closed half-circle (§2.2)."""
    assert removable_arc(np.zeros((0, 2))) == ((-math.pi, 2 * math.pi),)     # no contact: free
    (start, width), = removable_arc(_normals(90))                            # one face
    assert start == pytest.approx(0.0, abs=1e-12) and width == pytest.approx(math.pi)
    (start, width), = removable_arc(_normals(80, 20))                        # Ex II group
    assert math.degrees(start) == pytest.approx(-10.0) and math.degrees(width) == pytest.approx(120.0)
    (start, width), = removable_arc(_normals(90, 90.0000001))                # parallel contacts
    assert width == pytest.approx(math.pi, abs=1e-6)
    arcs = removable_arc(_normals(0, 180))                                   # slot: up and down
    assert sorted(round(math.degrees(a)) for a, w in arcs) == [-90, 90] and all(w == 0 for a, w in arcs)
    assert removable_arc(_normals(90, -26.57, 206.57)) is None               # tapered
    assert removable_arc(_normals(0, 120, 240)) is None                      # surrounded
    assert removable_arc(_normals(170, -170)) is not None                    # across ±180°


def test_contacts_and_free_faces_example_1():
    """Shared segments of the four blocks, with lengths from the geometry; free faces."""
    scene, _ = example_1.build()
    s = build_block_system(scene)
    pairs = {tuple(p): L for p, L in zip(s.contact_blocks.tolist(), s.contact_length)}
    tan20 = math.tan(math.radians(20))
    assert pairs[(0, 3)] == pytest.approx(4 / math.cos(math.radians(20)))    # B1 on the joint
    assert pairs[(1, 3)] == pytest.approx(6 / math.cos(math.radians(20)))    # B2 on the joint
    assert pairs[(0, 1)] == pytest.approx(5 - 4 * tan20)                     # cross joint x = -4
    assert pairs[(1, 2)] == pytest.approx(8.8 - 10 * tan20)                  # cross joint x = -10
    assert pairs[(2, 3)] == pytest.approx(6.0)                               # bench
    assert len(pairs) == 5
    # normals point into the first block of the pair
    k = s.contact_blocks.tolist().index([0, 3])
    assert s.contact_normal[k] == pytest.approx([math.sin(math.radians(20)), math.cos(math.radians(20))])
    # B1: toe face (5 m) + top (4 m) are free; B2: top 6 m + its part of x = -4 above B1
    assert s.free_length(0) == pytest.approx(9.0)
    assert s.free_length(1) == pytest.approx(6.0 + 3.8)
    # removing B2 exposes B1's back face
    assert s.free_length(0, removed=frozenset([1])) == pytest.approx(9.0 + 5 - 4 * tan20)
    assert s.free_length(3) > 0 and s.block_fixed.tolist() == [False, False, False, True]


def test_joint_of_a_contact_follows_ddatai_precedence():
    """Pair override, then the joint line of the shared edges (scene.cut), then the default."""
    scene = dd.Scene()
    weak, strong = dd.Joint(friction=12.0, cohesion=1e3), dd.Joint(friction=40.0)
    ids = scene.cut([(0, 0), (4, 0), (4, 2), (0, 2)], [([(2, -1), (2, 3)], weak)], material=ROCK)
    base = scene.add_block([(-1, -1), (5, -1), (5, 0), (-1, 0)], material=ROCK, fixed=True)
    scene.set_joint(dd.Joint(friction=33.0))
    s = build_block_system(scene)
    phi = {tuple(p): f for p, f in zip(s.contact_blocks.tolist(), s.contact_friction)}
    assert phi[tuple(sorted(ids))] == 12.0                       # the cut joint
    assert phi[tuple(sorted((ids[0], base)))] == 33.0            # default joint
    scene.set_joint(strong, between=(ids[1], base))
    s = build_block_system(scene)
    phi = {tuple(p): f for p, f in zip(s.contact_blocks.tolist(), s.contact_friction)}
    assert phi[tuple(sorted((ids[1], base)))] == 40.0            # pair override wins


def test_block_types_of_example_1():
    """§8.4: at φ = 11°, B1 / B2 / B3 are II / III / III; the base is V."""
    scene, _ = example_1.build()
    assert classify_blocks(build_block_system(scene)) == {0: "II", 1: "III", 2: "III", 3: "V"}


def test_block_types_hand_made():
    """I (sliding, lifting, falling down a slot, toppling), II, III, IV and V on hand-made cases."""
    scene, b = tapered_block()
    assert classify_blocks(build_block_system(scene))[b] == "IV"             # narrows to its free face
    scene, b = hanging_block()
    s = build_block_system(scene)
    assert classify_blocks(s)[b] == "I" and rigid_modes(s, frozenset([b]))[0].kind == ModeKind.LIFTING
    scene, b = slot_block()
    s = build_block_system(scene)
    assert is_removable(s, frozenset([b])) and classify_blocks(s)[b] == "I"   # falls, nothing presses
    scene, b = slot_block(cohesion=20e3)
    m = rigid_modes(build_block_system(scene), frozenset([b]))
    assert m[0].fs == pytest.approx(2 * 20e3 * 2.0 / (2500 * 9.81 * 2.0))  # c·L on both walls / W
    for phi, expect in ((20.0, "I"), (40.0, "II")):                          # α = 30°
        scene, _, b = block_on_incline(theta=30.0, width=4.0, height=1.0, friction=phi, cohesion=0.0)
        assert classify_blocks(build_block_system(scene))[b] == expect
    scene = dd.Scene()
    b = scene.add_block([(0, 0), (2, 0), (2, 1), (0, 1)], material=ROCK)    # on flat ground
    scene.add_block([(-2, -1), (4, -1), (4, 0), (-2, 0)], material=ROCK, fixed=True)
    assert classify_blocks(build_block_system(scene)) == {0: "III", 1: "V"}


def test_toppling_criterion():
    """A block on an incline topples when b/h < tan α (§4.5), whatever its friction."""
    for width, height, topples in ((1.0, 4.0, True), (1.0, 2.0, False), (4.0, 1.0, False)):
        scene, _, b = block_on_incline(theta=20.0, width=width, height=height, friction=40.0, cohesion=0.0)
        modes = rigid_modes(build_block_system(scene), frozenset([b]))
        rot = [m for m in modes if m.kind == ModeKind.ROTATION]
        assert bool(rot) == topples, (width, height)
        if topples:  # about the down-slope base corner
            assert rot[0].pivot == pytest.approx([math.cos(math.radians(20)), -math.sin(math.radians(20))])


def test_group_removability_example_2():
    """The active block A alone lifts only (type III); with P the group slides out (§8.3)."""
    scene, _ = example_2.build(cross_joint_offset=0.0, cross_joint_angle=45.0)
    s = build_block_system(scene)
    assert classify_blocks(s) == {0: "II", 1: "III", 2: "V"}
    assert rigid_modes(s, frozenset([1])) == []
    assert is_removable(s, frozenset([0, 1]))


def test_planar_slope_geometry():
    """The Hoek–Bray block: area from the closed form, plane length (H − z)/sin ψp."""
    scene, b = planar_slope(height=20.0, face=60.0, plane=30.0, crack=5.0)
    s = build_block_system(scene)
    cot = lambda a: 1 / math.tan(math.radians(a))
    area = 0.5 * 20 ** 2 * ((1 - (5 / 20) ** 2) * cot(30) - cot(60))
    assert s.block_area[b] == pytest.approx(area, rel=1e-12)
    k = s.contacts_of(b)
    assert sorted(s.contact_length[k]) == pytest.approx(sorted([5.0, 15 / math.sin(math.radians(30))]))


def test_a_gap_within_the_contact_tolerance_is_a_contact():
    """A block drawn 1 mm above its plane (CONTACT_GAP × 26 m = 2.6 mm) rests on it: the same FS
    as touching (c·A + W cosθ tanφ)/(W sinθ); 5 cm above, it is free (lifting)."""
    from kgm.system import CONTACT_GAP

    touching = kgm.analyze(block_above_incline(0.0), method="rigid").critical
    w = ROCK.density * 9.81 * 10.0
    t = np.radians(30.0)
    exact = (20e3 * 10.0 + w * np.cos(t) * np.tan(np.radians(35.0))) / (w * np.sin(t))
    assert touching.fs == pytest.approx(exact, rel=1e-9)
    gap = kgm.analyze(block_above_incline(1e-3), method="rigid").critical
    assert gap.fs == pytest.approx(exact, rel=1e-9) and gap.mode.kind == touching.mode.kind
    system = build_block_system(block_above_incline(1e-3))
    assert system.n_contacts == 1 and system.scale * CONTACT_GAP > 1e-3
    far = kgm.analyze(block_above_incline(0.05), method="rigid").critical
    assert far.mode.kind == ModeKind.LIFTING and far.fs == 0.0
    # the tolerance is a setting [m]
    tight = kgm.analyze(block_above_incline(1e-3), method="rigid", settings=kgm.Settings(contact_gap=1e-4))
    assert tight.critical.mode.kind == ModeKind.LIFTING
    loose = kgm.analyze(block_above_incline(0.05), method="rigid", settings=kgm.Settings(contact_gap=0.06))
    assert loose.critical.fs == pytest.approx(exact, rel=1e-9)
    with pytest.raises(ValueError, match="contact_gap"):
        kgm.Settings(contact_gap=-1.0)


@pytest.mark.parametrize("depth", [1e-3, 0.1])
def test_overlapping_blocks_are_refused_as_ddatai_refuses_them(depth):
    scene = block_above_incline(-depth)
    with pytest.raises(ValueError, match=r"blocks 0 and 1 overlap .* m deep\): kgm analyses blocks that touch"):
        kgm.analyze(scene, method="rigid")
    with pytest.raises(ValueError, match="blocks 0 and 1 overlap"):
        dd.build_model(scene)
