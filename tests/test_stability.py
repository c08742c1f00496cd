"""Numerical stability on stiff and extreme cases.

Every case must run with no NaN, with the deepest penetration of a closed contact below a stated
fraction of the smallest block size, and with energy that does not grow: the work dissipated by
the integrator (`ddatai.energy`, the remainder of the energy balance) must stay non-negative up to
round-off, stated as 1e-5 of the model's energy scale (total weight × model height). Or it must
stop early with a SimulationError naming the step and the cause.
"""

import numpy as np
import pytest

import ddatai as dd
from ddatai.params import UnitWarning
from cases import G, ROCK, block_on_incline, incline_base, sliding_scene

STIFF = dd.Material(density=2700.0, young=1e11, poisson=0.25)


def assert_stable(res, size: float, penetration: float = 1e-3, energy: float = 1e-5):
    """No NaN; penetration < ``penetration`` × size; cumulative integrator dissipation ≥
    −``energy`` × (weight × height)."""
    s = res.steps
    assert np.all(np.isfinite(res.centroid)) and np.all(np.isfinite(res.velocity))
    assert s["max_penetration"].max() < penetration * size
    free = ~res.block_fixed
    xy = res.vertices[0]
    height = float(np.ptp(xy[:, 1]) + np.ptp(xy[:, 0]))
    weight = sum(ROCK.density * G * abs(_area(p)) for b, p in enumerate(res.polygons(0)) if free[b])
    assert np.cumsum(s["integrator_work"]).min() >= -energy * weight * height


def _area(p):
    x, y = p[:, 0], p[:, 1]
    return 0.5 * np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y)


def test_very_stiff_blocks_and_penalty():
    """E = 1e11 Pa and a penalty of 1e13 N/m: a sliding block and a resting column."""
    scene = dd.Scene(gravity=G)
    incline_base(scene, 30.0)
    block = block_on_incline(scene, 30.0, at=4.0, width=1.0, height=1.0, material=STIFF)
    scene.set_joint(dd.Joint(friction=20.0))
    res = dd.simulate(scene, params=dd.Params(penalty=1e13), duration=1.0)
    assert_stable(res, 1.0)
    th = np.radians(30.0)
    exact = 0.5 * G * (np.sin(th) - np.cos(th) * np.tan(np.radians(20.0)))
    t, _ = np.array([np.cos(th), np.sin(th)]), None
    assert abs(-(res.centroid[-1, block] - res.centroid[0, block]) @ t / exact - 1) < 1e-3

    scene = dd.Scene(gravity=G)
    scene.add_block([(-1, -1), (2, -1), (2, 0), (-1, 0)], material=STIFF, fixed=True)
    for k in range(5):
        scene.add_block([(0, k), (1, k), (1, k + 1), (0, k + 1)], material=STIFF)
    assert_stable(dd.simulate(scene, params=dd.Params(penalty=1e13), duration=0.5), 1.0)


def _pile_on_plate(plate_young: float, n: int = 3, gap: float = 0.02):
    """An n × n pile of 1 m blocks of soft rock (E = 0.3 GPa), rows 2 cm apart (they fall
    and strike each other), on a fixed plate of modulus ``plate_young``."""
    soft = dd.Material(density=2500.0, young=300e6, poisson=0.25)
    plate = dd.Material(density=7850.0, young=plate_young, poisson=0.3)
    scene = dd.Scene(gravity=G)
    scene.add_block([(-1, -1), (n + 1, -1), (n + 1, 0), (-1, 0)], material=plate, fixed=True)
    for i in range(n):
        for j in range(n):
            y = gap + j * (1 + gap)
            scene.add_block([(i, y), (i + 1, y), (i + 1, y + 1), (i, y + 1)], material=soft)
    scene.set_joint(dd.Joint(friction=30.0))
    return scene


def test_stiff_fixed_plate_does_not_set_the_automatic_penalty():
    """Soft blocks (0.3 GPa) falling onto a steel plate (200 GPa, fixed): the automatic
    penalty is 50 × the free blocks' E (the plate does not deform in the model), so the run
    is the same, step for step, as on a plate of the blocks' own modulus. With the penalty of
    the plate's 200 GPa this pile took 128 steps for 1 s with 9 time-step cuts down to
    2.9e-4 s (a 6 × 6 pile 441 steps, Δt down to 3.9e-5 s) instead of 100 at Δt = 10 ms."""
    from ddatai.model import build_model

    stiff, same = _pile_on_plate(200e9), _pile_on_plate(300e6)
    assert build_model(stiff).penalty == build_model(same).penalty == 50 * 300e6
    runs = [dd.simulate(s, duration=0.5, record_every=1000) for s in (stiff, same)]
    assert np.array_equal(runs[0].steps["dt"], runs[1].steps["dt"])
    assert np.array_equal(runs[0].centroid[-1], runs[1].centroid[-1])
    # Δt stays at dt_max = 10 ms but where the rows land: the impact steps of √(m/p)·20 = 8.2 ms
    # (`ddatai.impacts`) and two cuts as the 2 cm gaps close (55 steps, 2.4 ms the shortest; 51
    # steps and no cut before impacts were resolved); with the plate's 200 GPa penalty the cuts
    # went down to 2.9e-4 s
    assert runs[0].time[-1] == pytest.approx(0.5) and runs[0].steps["dt_cuts"].sum() <= 2
    assert runs[0].steps["dt"].min() >= 0.002
    assert_stable(runs[0], 1.0)


def test_slivers_and_tiny_blocks_beside_large_ones():
    """A 10 m × 0.1 m slab and a standing 0.05 m × 5 m sliver (1:100); a 1 mm block on a
    100 m base."""
    scene = dd.Scene(gravity=G)
    scene.add_block([(-1, -1), (12, -1), (12, 0), (-1, 0)], material=ROCK, fixed=True)
    scene.add_block([(0, 0), (10, 0), (10, 0.1), (0, 0.1)], material=ROCK)
    scene.add_block([(2, 0.1), (3, 0.1), (3, 1.1), (2, 1.1)], material=ROCK)
    scene.add_block([(5, 0.1), (5.05, 0.1), (5.05, 5.1), (5, 5.1)], material=ROCK)
    assert_stable(dd.simulate(scene, duration=0.5), 0.05)

    scene = dd.Scene(gravity=G)
    scene.add_block([(-50, -100), (50, -100), (50, 0), (-50, 0)], material=ROCK, fixed=True)
    tiny = scene.add_block([(0, 0), (0.001, 0), (0.001, 0.001), (0, 0.001)], material=ROCK)
    scene.add_block([(5, 0), (6, 0), (6, 1), (5, 1)], material=ROCK)
    res = dd.simulate(scene, duration=0.2)
    assert_stable(res, 0.001, penetration=0.1)
    # the tiny block rests: it moves less than a tenth of its size
    assert np.linalg.norm(res.centroid[-1, tiny] - res.centroid[0, tiny]) < 1e-4


def test_density_contrast_1_to_1000():
    # deliberately not rock (a 1:1000 contrast): the unit check says so, which is right
    with pytest.warns(UnitWarning, match="density = 2.5 kg/m³"):
        light = dd.Material(density=2.5, young=5e9, poisson=0.25)
    scene = dd.Scene(gravity=G)
    scene.add_block([(-2, -1), (3, -1), (3, 0), (-2, 0)], material=ROCK, fixed=True)
    scene.add_block([(0, 0), (1, 0), (1, 1), (0, 1)], material=light)
    scene.add_block([(0, 1), (1, 1), (1, 2), (0, 2)], material=ROCK)
    assert_stable(dd.simulate(scene, duration=0.5), 1.0)


@pytest.mark.parametrize("theta, phi", [(10.0, 0.0), (40.0, 89.0)])
def test_friction_zero_and_89_degrees(theta, phi):
    """φ = 0 slides freely; φ = 89° (tanφ = 57) holds a 1 × 1 block on 40° (b/h ≥ tanθ, so it
    cannot topple either)."""
    scene, block = sliding_scene(theta, phi)
    res = dd.simulate(scene, duration=0.5)
    assert_stable(res, 1.0)
    d = np.linalg.norm(res.centroid[-1, block] - res.centroid[0, block])
    if phi == 0.0:
        assert d == pytest.approx(0.5 * G * np.sin(np.radians(theta)) * 0.25, rel=1e-3)
    else:
        assert d < 1e-5


def test_cohesion_and_tension_hold_an_overhang():
    """A 3 m × 1 m cantilever glued to a wall's face by c = T = 2 MPa: it stays."""
    scene = dd.Scene(gravity=G)
    scene.add_block([(0, 0), (2, 0), (2, 3), (0, 3)], material=ROCK, fixed=True)
    arm = scene.add_block([(2, 2), (5, 2), (5, 3), (2, 3)], material=ROCK)
    scene.set_joint(dd.Joint(friction=30.0, cohesion=2e6, tensile=2e6))
    res = dd.simulate(scene, duration=0.5)
    assert_stable(res, 1.0)
    assert np.linalg.norm(res.centroid[-1, arm] - res.centroid[0, arm]) < 1e-4


def test_impact_at_50_m_per_s():
    """A block thrown at 50 m/s onto the base: it never passes through the base, and rebounds
    slower than it came (the integrator damps the stiff contact: restitution about 0.3)."""
    scene = dd.Scene(gravity=G)
    scene.add_block([(-5, -2), (5, -2), (5, 0), (-5, 0)], material=ROCK, fixed=True)
    block = scene.add_block([(0, 1), (1, 1), (1, 2), (0, 2)], material=ROCK, velocity=(0.0, -50.0))
    res = dd.simulate(scene, duration=0.2)
    assert_stable(res, 1.0)
    # no vertex passes through the base (the centroid does dip: at 50 m/s the impact stress
    # ρ·c·v ≈ 2e8 Pa compresses the block elastically by about 1 cm)
    o = res.vertex_offset
    assert res.vertices[:, o[block]:o[block + 1], 1].min() > -1e-3
    assert 0.0 < res.velocity[-1, block, 1] < 0.5 * 50.0


@pytest.mark.parametrize("dt, steps", [(0.1, None), (1e-5, 2000)])
def test_very_large_and_very_small_time_steps(dt, steps):
    """Δt = 0.1 s (the displacement check cuts it as needed) and Δt = 1e-5 s (2000 steps).

    At Δt = 1e-5 s the penalty contact's own vibration (ω = √(2p/m) ≈ 1.4e4 rad/s) is resolved
    and hardly damped, so gravity switched on at t = 0 makes the contact ring and the early slide
    runs ahead of the rigid answer (the start-up perturbation that grows as Δt shrinks, Doolin &
    Sitar 2002): 16 % after 0.02 s. That run is checked for stability and a 25 % bound."""
    scene, block = sliding_scene(30.0, 20.0)
    params = dd.Params(dt=dt, dt_max=max(dt, 0.01))
    res = dd.simulate(scene, params=params, duration=None if steps else 1.0, steps=steps)
    assert_stable(res, 1.0)
    th = np.radians(30.0)
    a = G * (np.sin(th) - np.cos(th) * np.tan(np.radians(20.0)))
    t = res.time[-1]
    moved = np.linalg.norm(res.centroid[-1, block] - res.centroid[0, block])
    assert moved == pytest.approx(0.5 * a * t * t, rel=1e-3 if steps is None else 0.25)


def test_long_run_of_a_resting_pile():
    """A 2 × 2 fitted pile, dynamic, 10,000 steps of 1 ms: after settling (1 s) the top block
    creeps less than 1e-5 × its size in the remaining 9 s, and the energy never grows."""
    from scenes.stacked_grid import build

    scene, params = build(2, gap=0.0, static=False, dt=1e-3)
    res = dd.simulate(scene, params=params, steps=10_000, record_every=500)
    assert_stable(res, 1.0)
    top = res.centroid[:, -1]
    settled = np.searchsorted(res.time, 1.0)
    assert np.linalg.norm(top[-1] - top[settled]) < 1e-5


def test_block_wedged_in_a_narrow_notch():
    """A wedge fitting a notch whose faces close downwards at 10° off vertical: near-singular
    contact geometry. Self-locking (10° < φ = 30°): it is held in place."""
    tan = np.tan(np.radians(10.0))
    scene = dd.Scene(gravity=G)
    scene.add_block([(-3, -1), (2 * tan, -1), (0, 1), (-3, 1)], material=ROCK, fixed=True)
    scene.add_block([(1 - 2 * tan, -1), (4, -1), (4, 1), (1, 1)], material=ROCK, fixed=True)
    wedge = scene.add_block([(tan, 0), (1 - tan, 0), (1, 1), (0, 1)], material=ROCK)
    res = dd.simulate(scene, duration=0.5)
    assert_stable(res, 1.0)
    assert np.linalg.norm(res.centroid[-1, wedge] - res.centroid[0, wedge]) < 1e-5


def test_vertex_to_vertex_contact():
    """A block balanced corner-on-corner on a fixed block tips off without blowing up."""
    scene = dd.Scene(gravity=G)
    scene.add_block([(-1, -1), (0, -1), (0, 0), (-1, 0)], material=ROCK, fixed=True)
    scene.add_block([(0, 0), (1, 0), (1, 1), (0, 1)], material=ROCK)
    res = dd.simulate(scene, duration=0.5, record_contacts=True)
    assert_stable(res, 1.0)
    _, first = res.contacts(1) if res.contact_offset[-1] else (None, None)
    assert res.centroid[-1, 1, 1] < res.centroid[0, 1, 1]  # it fell
