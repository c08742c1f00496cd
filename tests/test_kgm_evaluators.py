"""kgm limit-equilibrium evaluators against closed forms and the targets of docs/kgm/method.md §8.4.

Tolerances: closed forms to round-off (1e-9 relative); §8.4 values to half a unit of the last
digit given there (they are rounded)."""

import math

import numpy as np
import pytest

import kgm
from kgm.build import build_block_system
from kgm.judges.evaluation import critical_friction_of
from kgm.judges.rigid import evaluate_rigid
from kgm.judges.sarma import evaluate_sarma, sarma_modes
from kgm_cases import bent_chain, block_on_incline, hoek_bray_fs, planar_slope
from scenes import example_1, example_2


@pytest.mark.parametrize("height,face,plane,crack,friction,cohesion", [
    (20.0, 60.0, 30.0, 5.0, 30.0, 25e3),
    (30.0, 70.0, 35.0, 8.0, 25.0, 10e3),
    (12.0, 50.0, 25.0, 0.0, 35.0, 0.0),
])
def test_rigid_planar_sliding_closed_form(height, face, plane, crack, friction, cohesion):
    """Hoek & Bray planar failure, dry, with cohesion and a tension crack (§4.2)."""
    scene, b = planar_slope(height, face, plane, crack, friction, cohesion)
    ev = evaluate_rigid(build_block_system(scene), frozenset([b]))
    assert ev.mode.kind.value == "sliding"
    assert ev.fs == pytest.approx(hoek_bray_fs(height, face, plane, crack, friction, cohesion), rel=1e-9)
    # tan φc = (T − cL)/N' with the same geometry (§4.6): FS(φc) = 1
    phi_c = critical_friction_of(ev)
    assert kgm.factor_of_safety(_with_friction(scene, phi_c), [b], method="rigid") == pytest.approx(1.0, rel=1e-9)


def _with_friction(scene, phi):
    import ddatai as dd

    j = scene.joints[0]
    scene.set_joint(dd.Joint(friction=phi, cohesion=j.cohesion))
    return scene


def test_single_block_rigid_equals_sarma_closed_form():
    """α = 30°, c = 20 kPa, L = 10 m, W = 1 MN/m, φ = 25°: FS = 1.2077, K_c = 0.09447 (§8.4;
    K_c = (cL + W cosα tanφ − W sinα)/(W (cosα + sinα tanφ)), §5.2)."""
    height = 1e6 / (2500 * 9.81 * 10.0)
    scene, _, b = block_on_incline(theta=30.0, width=10.0, height=height, friction=25.0, cohesion=20e3)
    s = build_block_system(scene)
    a, phi, c, L, W = math.radians(30), math.radians(25), 20e3, 10.0, 1e6
    fs = (c * L + W * math.cos(a) * math.tan(phi)) / (W * math.sin(a))
    kc = (c * L + W * math.cos(a) * math.tan(phi) - W * math.sin(a)) / (W * (math.cos(a) + math.sin(a) * math.tan(phi)))
    assert fs == pytest.approx(1.2077, abs=5e-5) and kc == pytest.approx(0.09447, abs=5e-6)
    rigid = evaluate_rigid(s, frozenset([b]))
    sarma = sarma_modes(s, frozenset([b]))          # the mechanism path, without the rigid modes
    assert len(sarma) == 1
    for mode in (rigid.mode, sarma[0]):
        assert mode.fs == pytest.approx(fs, rel=1e-9)
        assert mode.critical_acceleration == pytest.approx(kc, rel=1e-9)
    assert sarma[0].critical_friction == pytest.approx(rigid.mode.critical_friction, abs=1e-9)


def test_example_1_targets():
    """§8.4: φc{B1,B2} = 11.02°, φc B1 = 8.41°, FS{B1,B2}(15°) = 1.201, FS B1(11°) = 1.128;
    Sarma equals rigid because both blocks slide on one plane (§5.3)."""
    scene, _ = example_1.build()
    s = build_block_system(scene)
    g = frozenset([0, 1])
    for ev in (evaluate_rigid(s, g), evaluate_sarma(s, g)):
        assert critical_friction_of(ev) == pytest.approx(11.02, abs=0.005)
    assert critical_friction_of(evaluate_rigid(s, frozenset([0]))) == pytest.approx(8.41, abs=0.005)
    assert evaluate_rigid(s, frozenset([0])).fs == pytest.approx(1.128, abs=5e-4)
    s15 = s.with_strength(friction=15.0)
    assert evaluate_rigid(s15, g).fs == pytest.approx(1.201, abs=5e-4)
    assert evaluate_sarma(s15, g).fs == pytest.approx(evaluate_rigid(s15, g).fs, rel=1e-9)
    for m in ("rigid", "sarma"):
        assert kgm.critical_friction(scene, [0, 1], method=m) == pytest.approx(11.02, abs=0.005)


def test_example_2_reconstruction_targets():
    """§8.4 on the §8.3 geometry: rigid FS 1.586, φc 13.87°; Sarma FS 0.895, K_c −0.112,
    φc 24.46°; P alone 1.718. The Sarma mechanism: A down J2, P out along J1, v_P = 1.047 v_A."""
    scene, _ = example_2.build(cross_joint_offset=0.0, cross_joint_angle=45.0)
    s = build_block_system(scene)
    g = frozenset([0, 1])
    rigid, sarma = evaluate_rigid(s, g), evaluate_sarma(s, g)
    assert rigid.fs == pytest.approx(1.586, abs=5e-4) and critical_friction_of(rigid) == pytest.approx(13.87, abs=0.005)
    assert sarma.mode.kind.value == "sarma"
    assert sarma.fs == pytest.approx(0.895, abs=5e-4)
    assert sarma.mode.critical_acceleration == pytest.approx(-0.112, abs=5e-4)
    assert critical_friction_of(sarma) == pytest.approx(24.46, abs=0.005)
    assert evaluate_rigid(s, frozenset([0])).fs == pytest.approx(1.718, abs=5e-4)
    v = sarma.mode.block_velocity
    assert np.hypot(*v[0]) / np.hypot(*v[1]) == pytest.approx(1.047, abs=5e-4)
    # directions: P along J1 (15°), A along J2 (70°), to the 1 mm rounding of the coordinates
    assert math.degrees(math.atan2(-v[0][1], v[0][0])) == pytest.approx(15.0, abs=1e-3)
    assert math.degrees(math.atan2(-v[1][1], v[1][0])) == pytest.approx(70.0, abs=1e-3)


def test_example_2_scene_rigid_stable_sarma_unstable():
    """The example's claim for limit equilibrium: rigid KGM stable, Sarma-KGM unstable."""
    scene, _ = example_2.build()
    assert kgm.factor_of_safety(scene, [0, 1], method="rigid") > 1.0
    assert kgm.factor_of_safety(scene, [0, 1], method="sarma") < 1.0


def test_sarma_fs_is_the_strength_reduction_at_kc_zero():
    """At FS the mechanism's critical acceleration vanishes; at φc with c held, so does K_c."""
    scene, _ = bent_chain()
    s = build_block_system(scene)
    g = frozenset([0, 1, 2])
    ev = evaluate_sarma(s, g)
    assert ev.mode.kind.value == "sarma"
    reduced = s.with_strength(reduction=ev.fs)
    assert evaluate_sarma(reduced, g).fs == pytest.approx(1.0, rel=1e-8)
    phi_c = critical_friction_of(ev)
    at_phi_c = evaluate_sarma(s.with_strength(friction=phi_c), g)
    assert at_phi_c.fs == pytest.approx(1.0, rel=1e-8)
    assert at_phi_c.mode.critical_acceleration == pytest.approx(0.0, abs=1e-8)


def test_sarma_can_be_lower_or_equal_but_reports_the_least_safe():
    """FS_sarma = min(rigid modes, Sarma mechanisms) (§5.3): never above the rigid FS."""
    for scene, g in ((example_1.build()[0], [0, 1]), (example_2.build()[0], [0, 1]), (bent_chain()[0], [0, 1, 2])):
        assert kgm.factor_of_safety(scene, g, method="sarma") <= kgm.factor_of_safety(scene, g, method="rigid") + 1e-12


def test_extreme_rays_against_brute_force():
    """Double description against the definition: a ray of {x: A x ≥ 0} is extreme iff the
    constraints active on it have rank d − 1 (every such null direction that satisfies all
    constraints, enumerated over all (d − 1)-subsets of rows)."""
    import itertools

    from kgm.judges.mechanisms import extreme_rays

    rng = np.random.default_rng(7)
    for d, m in ((2, 5), (3, 7), (4, 8), (5, 9)):
        a = rng.normal(size=(m, d))
        a[:, 0] = np.abs(a[:, 0]) + 0.5          # x = e_0 is interior: the cone is not empty
        got = extreme_rays(a)
        want = []
        for rows in itertools.combinations(range(m), d - 1):
            _, sv, vh = np.linalg.svd(a[list(rows)])
            if sv[-1] < 1e-9:
                continue
            for x in (vh[-1], -vh[-1]):
                if np.all(a @ x >= -1e-9) and not any(np.abs(x - w).max() < 1e-7 for w in want):
                    want.append(x)
        assert len(got) == len(want), (d, m)
        for w in want:
            assert any(np.abs(g - w).max() < 1e-7 for g in got)
