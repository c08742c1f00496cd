"""Water pressure and rock bolts in DDA against closed forms (docs/method/water_bolts.md), and
the scene's checks of their input.

Tolerances come from the method: a sliding block's acceleration is exact up to the start-up
perturbation (< 0.1 % at θ − φ ≥ 5°, the verification cases), held here to 1 %; the critical
angle is bracketed to ±0.3°; a floating block's buoyancy is a load of the step's start
geometry (explicit), whose lag changes the period by O((ωΔt)²) ≈ 1e-3 at Δt = 0.01 s, held to
1 %; a bolt holding a frictionless block carries the static demand up to its elastic stretch
(T/k ≈ 3e-4 m turns it by ~1e-4 rad), held to 1 %.
"""

import math
import subprocess
import sys

import numpy as np
import pytest

import ddatai as dd
from cases import G, block_on_incline, downslope_displacement, incline_base, incline_frame

RHO_W = 1000.0
WIDTH, HEIGHT, RHO = 2.0, 1.0, 2500.0          # block on the incline [m, m, kg/m³]
HW = 0.5                                        # water table: 0.5 m (vertically) above the plane [m]
PHI = 30.0                                      # joint friction [degrees]


def wet_incline(theta: float, phi: float = PHI):
    """A block on a plane of dip θ with a water table parallel to the plane, HW above it (the
    block's top is dry). The pressure γw·(HW − n/cosθ) depends only on the distance n from the
    plane, so the water on the block's sides cancels and the net water force is the uplift on
    its base, U = γw·HW·b, normal to the plane."""
    scene = dd.Scene(gravity=G)
    incline_base(scene, theta)
    block = block_on_incline(scene, theta, at=4.0, width=WIDTH, height=HEIGHT)
    scene.set_joint(dd.Joint(friction=phi))
    tn = math.tan(math.radians(theta))
    scene.set_water_table([(-20.0, -20.0 * tn + HW), (30.0, 30.0 * tn + HW)])
    return scene, block


def _weight_and_uplift() -> tuple[float, float]:
    return RHO * G * WIDTH * HEIGHT, RHO_W * G * HW * WIDTH


def critical_angle() -> float:
    """W·sinθ = (W·cosθ − U)·tanφ  ⇒  θc = φ − asin((U/W)·sinφ) [degrees]."""
    w, u = _weight_and_uplift()
    return PHI - math.degrees(math.asin(u / w * math.sin(math.radians(PHI))))


def sliding_acceleration(theta: float) -> float:
    """a = [W·sinθ − (W·cosθ − U)·tanφ] / m, effective normal force N' = W·cosθ − U."""
    w, u = _weight_and_uplift()
    th, ph = math.radians(theta), math.radians(PHI)
    return (w * math.sin(th) - (w * math.cos(th) - u) * math.tan(ph)) / (RHO * WIDTH * HEIGHT)


def test_wet_block_slides_at_the_effective_stress_critical_angle():
    """0.3° below θc the block stays; 0.3° above it slides (a dry block would rest there:
    θc + 0.3° < φ), at the effective-stress acceleration."""
    tc = critical_angle()
    assert tc + 0.3 < PHI - 5.0  # the uplift matters: a dry block holds up to φ
    below, b = wet_incline(tc - 0.3)
    res = dd.simulate(below, duration=0.5)
    assert np.linalg.norm(res.centroid[-1, b] - res.centroid[0, b]) < 1e-5 * HEIGHT
    above, b = wet_incline(tc + 0.3)
    res = dd.simulate(above, duration=0.5)
    d = downslope_displacement(res, b, tc + 0.3)
    exact = 0.5 * sliding_acceleration(tc + 0.3) * 0.5 ** 2
    # within 0.3° of the threshold the start-up perturbation dominates: 2 % (verification cases)
    assert d == pytest.approx(exact, rel=2e-2)


@pytest.mark.parametrize("theta", [30.0, 40.0])
def test_wet_block_accelerates_as_its_effective_normal_force_predicts(theta):
    """d(1 s) = ½·a·t² with a from N' = W·cosθ − U, within 1 %."""
    scene, b = wet_incline(theta)
    res = dd.simulate(scene, duration=1.0)
    d = downslope_displacement(res, b, theta)
    assert d == pytest.approx(0.5 * sliding_acceleration(theta), rel=1e-2)


def _floating(draft0: float):
    wood = dd.Material(density=600.0, young=1e9, poisson=0.25)
    scene = dd.Scene(gravity=G)
    top = 5.0 - draft0 + 1.0
    b = scene.add_block([(0, top - 1.0), (1, top - 1.0), (1, top), (0, top)], material=wood)
    scene.set_water_table([(-10.0, 5.0), (10.0, 5.0)])
    return scene, b


def test_floating_block_rests_at_its_buoyancy_depth():
    """A 1 m block of ρ = 600 kg/m³ placed at its draft d = ρ/ρw·h = 0.6 m stays there."""
    scene, b = _floating(0.6)
    res = dd.simulate(scene, duration=1.0)
    assert abs(res.centroid[-1, b, 1] - res.centroid[0, b, 1]) < 1e-6


def test_floating_block_oscillates_about_its_buoyancy_depth():
    """Released at half its draft it oscillates about d = 0.6 m (the extremes symmetric about
    it) with the period 2π·√(d/g) of a block on a buoyancy spring ρw·g·b."""
    scene, b = _floating(0.3)
    res = dd.simulate(scene, duration=3.0)
    draft = 5.0 - (res.centroid[:, b, 1] - 0.5)
    d_eq = 600.0 / RHO_W * 1.0
    assert 0.5 * (draft.min() + draft.max()) == pytest.approx(d_eq, rel=1e-2)
    z = draft - d_eq
    up = res.time[1:][(z[:-1] < 0) & (z[1:] >= 0)]
    assert len(up) >= 2
    assert np.diff(up).mean() == pytest.approx(2 * math.pi * math.sqrt(d_eq / G), rel=1e-2)


# ------------------------------------------------------------------ bolts
THETA, ALPHA = 30.0, 20.0  # plane dip; bolt plunge below the plane, pointing upslope [degrees]


def bolted(capacity: float, load=None):
    """A frictionless block on a 30° plane held by a bolt anchored upslope in the base."""
    scene = dd.Scene(gravity=G)
    incline_base(scene, THETA)
    b = block_on_incline(scene, THETA, at=4.0, width=WIDTH, height=HEIGHT)
    scene.set_joint(dd.Joint(friction=0.0))
    t, n = incline_frame(THETA)
    a = math.radians(ALPHA)
    p1 = 5.8 * t + 0.5 * n
    scene.add_bolt(p1, p1 + 3.0 * (math.cos(a) * t - math.sin(a) * n), stiffness=1e8, capacity=capacity)
    if load is not None:
        scene.add_point_load(b, 5.0 * t + 0.5 * n, load)
    return scene, b


def static_demand(extra: float = 0.0) -> float:
    """T·cos α = W·sinθ + P (frictionless plane; P a downslope load) [N/m]."""
    w = RHO * G * WIDTH * HEIGHT
    return (w * math.sin(math.radians(THETA)) + extra) / math.cos(math.radians(ALPHA))


def test_bolt_holds_a_sliding_block_at_the_static_demand():
    """Without the bolt the block slides (φ = 0); with it, it stays and the bolt's tension is
    the static demand within 1 %."""
    scene, b = bolted(math.inf)
    res = dd.simulate(scene, duration=0.5)
    assert abs(downslope_displacement(res, b, THETA)) < 1e-3
    assert res.bolt_force[-1, 0] == pytest.approx(static_demand(), rel=1e-2)
    assert len(res.bolt_events) == 0 and not res.bolt_broken.any()


def test_weak_bolt_breaks_and_the_block_slides_freely(tmp_path):
    """Capacity half the demand: the bolt breaks at the first step (an event, kept by a saved
    and reloaded result), then the block accelerates at g·sinθ within 1 %."""
    scene, b = bolted(0.5 * static_demand())
    res = dd.simulate(scene, duration=0.5)
    res.save(tmp_path / "run.npz")
    again = dd.load_results(tmp_path / "run.npz")
    assert np.array_equal(again.bolt_events, res.bolt_events) and np.array_equal(again.bolt_xy, res.bolt_xy)
    ev = res.bolt_events
    assert len(ev) == 1 and ev[0]["bolt"] == 0 and ev[0]["step"] == 1
    assert ev[0]["force"] > 0.5 * static_demand()
    assert res.bolt_broken[-1, 0] and res.bolt_force[-1, 0] == 0.0
    t = incline_frame(THETA)[0]
    v = -(res.velocity[:, b] @ t)
    i, j = len(res.time) // 3, len(res.time) - 1
    assert (v[j] - v[i]) / (res.time[j] - res.time[i]) == pytest.approx(G * math.sin(math.radians(THETA)), rel=1e-2)


def test_bolt_breaks_when_a_growing_load_exceeds_its_capacity():
    """A downslope load P = r·t raises the demand; the bolt breaks in the step whose mid-step
    demand first exceeds its capacity, t_b = (C·cos α − W·sinθ)/r, then the block slides with
    a = g·sinθ + r·t/m."""
    rate = 2e4  # N/m per s
    cap = 1.2 * static_demand()
    t_dir = incline_frame(THETA)[0]
    scene, b = bolted(cap, load=lambda time: tuple(-rate * time * t_dir))
    res = dd.simulate(scene, dd.Params(dt=0.01), duration=1.0)
    t_b = (cap * math.cos(math.radians(ALPHA)) - RHO * G * WIDTH * HEIGHT * math.sin(math.radians(THETA))) / rate
    ev = res.bolt_events
    assert len(ev) == 1
    assert t_b <= ev[0]["time"] - 0.005 <= t_b + 0.01 + 1e-9   # the mid-step load of its step
    mass = RHO * WIDTH * HEIGHT
    te = float(ev[0]["time"])
    v_end = -(res.velocity[-1, b] @ t_dir)
    exact = G * math.sin(math.radians(THETA)) * (1.0 - te) + rate / (2 * mass) * (1.0 - te ** 2)
    assert v_end == pytest.approx(exact, rel=1e-2)


# ------------------------------------------------------------------ input checks
def _two_blocks():
    s = dd.Scene()
    r = dd.Material(density=2500.0, young=1e9, poisson=0.2)
    s.add_block([(0, 0), (2, 0), (2, 1), (0, 1)], material=r)
    s.add_block([(0, 1), (2, 1), (2, 2), (0, 2)], material=r)
    return s


@pytest.mark.parametrize("table, match", [
    ([(0, 0), (2, 2), (2, 0), (0, 2)], r"crosses itself: segment 0 .* segment 2"),
    ([(0, 0), (1, 0), (0.5, 0)], r"crosses itself: segment 0 .* segment 1"),
    ([(0, 0), (1, 1), (0.5, 2)], r"point 2 \(0.5, 2\) does not lie to the right"),
    ([(0, 0)], "at least two"),
    ([(0, 0), (1, float("nan"))], "point 1 is not finite"),
])
def test_bad_water_table_is_refused(table, match):
    with pytest.raises(ValueError, match=match):
        _two_blocks().set_water_table(table)


@pytest.mark.parametrize("p1, p2, kw, match", [
    ((5, 5), (1, 1.5), {}, r"bolt 0: end p1 \(5, 5\) lies in no block"),
    ((1, 0.5), (9, 9), {}, r"bolt 0: end p2 \(9, 9\) lies in no block"),
    ((1, 0.2), (1, 0.8), {}, "both ends .* lie in block 0"),
    ((1, 0.5), (1, 1.5), {"capacity": -1.0}, "bolt 0: capacity must be a number >= 0"),
    ((1, 0.5), (1, 1.5), {"stiffness": 0.0}, "bolt 0: stiffness must be > 0"),
    ((1, 0.5), (1, 1.5), {"pretension": 5.0, "capacity": 1.0}, "pretension 5 N/m exceeds its capacity"),
])
def test_bad_bolt_is_refused(p1, p2, kw, match):
    s = _two_blocks()
    with pytest.raises(ValueError, match=match):
        s.add_bolt(p1, p2, **{"stiffness": 1e6, **kw})
    assert s.bolts == []


def test_a_scene_without_water_or_bolts_loads_nothing_for_them():
    """No water, no bolts: the model has empty bolt arrays and no water table, and neither the
    water nor the support module is imported (by building or by a step)."""
    code = """
import sys
import ddatai as dd
s = dd.Scene()
r = dd.Material(density=2500.0, young=1e9, poisson=0.2)
s.add_block([(0, 0), (4, 0), (4, 1), (0, 1)], material=r, fixed=True)
s.add_block([(1, 1), (2, 1), (2, 2), (1, 2)], material=r)
m = dd.build_model(s)
assert m.water_xy is None and len(m.bolt_block) == 0
res = dd.simulate(s, steps=2)
assert res.bolt_xy.size == 0 and res.water_table.size == 0
print([k for k in ("ddatai.water", "ddatai.support") if k in sys.modules])
"""
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip().splitlines()[-1] == "[]"


# ------------------------------------------------------------------ the bolted slope scene
def test_bolted_slope_design_reaches_the_target_and_holds():
    """scenes/bolted_slope.py: kgm's FS grows with every row of bolts and the design is the
    first row count with FS ≥ 1.5; DDA lets the unbolted wedge slide and holds the designed
    one (its bolts intact and under their capacity)."""
    from scenes import bolted_slope as bs

    rows, history = bs.design()
    assert history[0] < 1.0 and history[-1] >= bs.FS_TARGET > history[-2]
    assert all(b > a for a, b in zip(history, history[1:]))
    unbolted, params = bs.build("none")
    res = dd.simulate(unbolted, params, duration=1.0, record_every=10)
    free = ~res.block_fixed
    assert np.hypot(*(res.centroid[-1] - res.centroid[0]).T)[free].min() > 0.5    # slid
    bolted_scene, params = bs.build("design")
    assert len(bolted_scene.bolts) == rows
    res = dd.simulate(bolted_scene, params, duration=1.0, record_every=10)
    assert np.hypot(*(res.centroid[-1] - res.centroid[0]).T)[free].max() < 0.01   # held
    assert len(res.bolt_events) == 0 and np.all(res.bolt_force[-1] < bs.BOLT_CAPACITY)


def test_weak_bolting_breaks_and_the_picture_shows_it(tmp_path):
    """One row of half-capacity bolts: the bolt breaks (an event) and the wedge slides; a frame
    draws the water table, and the broken bolt in its own colour."""
    pytest.importorskip("PIL")
    from PIL import Image

    from ddatai import render
    from scenes import bolted_slope as bs

    scene, params = bs.build("weak")
    res = dd.simulate(scene, params, duration=0.5, record_every=10)
    assert len(res.bolt_events) == 1 and res.bolt_broken[-1].all()
    free = ~res.block_fixed
    assert np.hypot(*(res.centroid[-1] - res.centroid[0]).T)[free].min() > 0.1
    path = tmp_path / "weak.png"
    dd.write_png(res, path, size=(480, 300))
    pixels = {tuple(p) for p in np.asarray(Image.open(path).convert("RGB")).reshape(-1, 3).tolist()}
    assert render.WATER in pixels and render.BROKEN_BOLT in pixels


@pytest.mark.parametrize("case", ["floating", "bolt holds", "bolt breaks"])
def test_energy_balance_counts_water_and_bolts(case):
    """The water's work enters the external work and the bolts' spring energy the contact
    energy, so the integrator creates no energy: its cumulative work stays above −1e-5 of
    weight × size (the stability suite's bound); a breaking bolt's stored energy is
    dissipated (positive)."""
    if case == "floating":
        scene, b = _floating(0.3)
        res = dd.simulate(scene, duration=3.0)
        scale = 600.0 * G * 1.0 * 1.0
    else:
        scene, b = bolted(math.inf if case == "bolt holds" else 0.5 * static_demand())
        res = dd.simulate(scene, duration=0.5)
        scale = RHO * G * WIDTH * HEIGHT * HEIGHT
    work = np.cumsum(res.steps["integrator_work"])
    assert work.min() > -1e-5 * scale
    if case == "floating":
        assert abs(res.steps["external_work"].sum()) > 1.0   # the buoyancy did work
    if case == "bolt breaks":
        # the spring energy F²/2k stored at the break is dissipated, not lost from the balance
        stored = res.bolt_events[0]["force"] ** 2 / (2 * 1e8)
        assert work[-1] > 0.5 * stored


def test_bolt_between_two_free_blocks_couples_them():
    """A bolt between two free blocks on a frictionless base (no contact between them: the
    pair is coupled through the bolt alone), one pulled by F: the centre of mass accelerates at
    F/(mA + mB) (the bolt's forces are internal), and the tension oscillates about
    N̄ = F·mA/(mA + mB) with ω = √(k·(1/mA + 1/mB)); over whole periods its mean is N̄
    (Newmark's damping shrinks the swing, not the mean)."""
    rock = dd.Material(density=2500.0, young=5e9, poisson=0.25)
    s = dd.Scene(gravity=G)
    s.add_block([(0, 0), (10, 0), (10, 1), (0, 1)], material=rock, fixed=True)
    a = s.add_block([(2, 1), (3, 1), (3, 2), (2, 2)], material=rock)
    b = s.add_block([(4, 1), (6, 1), (6, 2), (4, 2)], material=rock)
    s.set_joint(dd.Joint(friction=0.0))
    k, force = 1e5, 3000.0
    s.add_bolt((2.5, 1.5), (5.0, 1.5), stiffness=k)
    s.add_point_load(b, (5.5, 1.5), (force, 0.0))
    m_a, m_b = 2500.0, 5000.0
    period = 2 * math.pi / math.sqrt(k * (1 / m_a + 1 / m_b))
    res = dd.simulate(s, dd.Params(dt=0.005), duration=3 * period)
    t = res.time
    com = (m_a * res.centroid[:, a, 0] + m_b * res.centroid[:, b, 0]) / (m_a + m_b)
    assert com[-1] - com[0] == pytest.approx(0.5 * force / (m_a + m_b) * t[-1] ** 2, rel=1e-4)
    mean = np.trapezoid(res.bolt_force[:, 0], t) / t[-1]
    assert mean == pytest.approx(force * m_a / (m_a + m_b), rel=1e-2)


# ------------------------------------------------------------------ a joint with its own head
def _confined_joint(theta: float, phi: float, head: float):
    """A 2 × 1 m block cut from the rock of a θ plane by one joint line, water confined in that
    joint at a level head (no water table): only the block's base carries pressure."""
    t, n = incline_frame(theta)
    domain = [-n, 12 * t - n, 12 * t, 6 * t, 6 * t + n, 4 * t + n, 4 * t, 0 * t]
    scene = dd.Scene(gravity=G)
    joint = dd.Joint(friction=phi)
    ids = scene.cut(domain, [([4 * t, 6 * t], joint)], material=dd.Material(density=RHO, young=5e9, poisson=0.25))
    for b in ids:
        scene.set_fixed(b, bool(scene.polygon(b).mean(axis=0) @ n < 0))
    scene.set_joint(joint)
    scene.set_water_table(None, heads={joint: head})
    return scene, next(b for b in ids if not scene.blocks[b].fixed)


def test_joint_with_its_own_head_lifts_the_block():
    """U = γw·b·(head − y_base) on the base only; as the block slides the base goes down and U
    grows by γw·b·sinθ per metre: m·s'' = A + B·s, s(t) = (A/B)·(cosh(√(B/m)·t) − 1) with
    A = W·sinθ − (W·cosθ − U0)·tanφ, B = γw·b·sinθ·tanφ. kgm's FS with U0 exact; DDA's
    slide within 1 % (the pressure is taken on each step's start geometry)."""
    import kgm

    theta, phi, head = 30.0, 20.0, 3.5
    scene, b = _confined_joint(theta, phi, head)
    th, ph = math.radians(theta), math.radians(phi)
    w = RHO * G * WIDTH * HEIGHT
    u0 = RHO_W * G * WIDTH * (head - 5.0 * math.sin(th))      # base centre at 5 m along the plane
    assert kgm.factor_of_safety(scene, [b], method="rigid") == pytest.approx(
        (w * math.cos(th) - u0) * math.tan(ph) / (w * math.sin(th)), rel=1e-9)
    res = dd.simulate(scene, duration=1.0)
    d = downslope_displacement(res, b, theta)
    mass = RHO * WIDTH * HEIGHT
    a0 = w * math.sin(th) - (w * math.cos(th) - u0) * math.tan(ph)
    b0 = RHO_W * G * WIDTH * math.sin(th) * math.tan(ph)
    assert d == pytest.approx(a0 / b0 * (math.cosh(math.sqrt(b0 / mass) * 1.0) - 1.0), rel=1e-2)


def test_head_of_an_unknown_joint_is_refused():
    s = _two_blocks()
    with pytest.raises(ValueError, match="is not a joint line of the scene"):
        s.set_water_table(None, heads={dd.Joint(friction=12.0): 3.0})


@pytest.mark.parametrize("offset, slides", [(-0.2, True), (0.2, False)])
def test_wet_biplanar_pair_in_dda_at_the_effective_stress_critical_friction(offset, slides):
    """The bi-planar pair (tests/cases.py) under a level table 2 m above the kink: water on
    every face, the shared one included. Its critical φ is kgm's (checked against the
    effective-weight closed form in tests/test_kgm_water.py); DDA slides 0.2° below it and
    holds 0.2° above it (starting under sudden gravity: held blocks settle by ~1e-4 m, then
    rest)."""
    import kgm
    from cases import biplanar_scene

    table = [(-10.0, 2.0), (10.0, 2.0)]
    scene, (a, b) = biplanar_scene(20.0)
    scene.set_water_table(table)
    phi = kgm.critical_friction(scene, [a, b], method="sarma") + offset
    scene, (a, b) = biplanar_scene(phi)
    scene.set_water_table(table)
    res = dd.simulate(scene, dd.Params(initial_equilibrium=False), duration=1.0)
    moved = np.linalg.norm(res.centroid[-1, [a, b]] - res.centroid[0, [a, b]], axis=1).max()
    if slides:
        assert moved > 2e-3
    else:
        assert moved < 1e-3 and np.abs(res.velocity[-1, [a, b]]).max() < 1e-4


def test_water_load_vector_is_the_exact_integral():
    """The load vector of every DDA unknown (translations, rotation, strains) equals the
    boundary integral ∮ Tᵀ·p·n_in ds of (W1) by brute force (10⁵ midpoints per edge, error
    O(h²) ≈ 1e-10 relative) on an irregular block cut by a kinked, sloping table that crosses
    edges and has a kink above the block."""
    from ddatai.support import t_rows, water_load

    scene = dd.Scene(gravity=G)
    rock = dd.Material(density=RHO, young=5e9, poisson=0.25)
    poly = np.array([(0.0, 0.0), (3.0, -0.5), (4.0, 1.5), (2.5, 3.0), (0.5, 2.2)])
    scene.add_block(poly, material=rock)
    table = np.array([(-1.0, 1.0), (2.0, 2.6), (5.0, 0.4)])
    scene.set_water_table(table)
    model = dd.build_model(scene)
    state = model.initial_state()
    geom = model.block_geometry(state.vertex_xy)
    load = water_load(model, state.vertex_xy, geom["centroid"])[0]
    xy = poly - model.origin
    c = geom["centroid"][0]
    expected = np.zeros(6)
    s = (np.arange(100_000) + 0.5) / 100_000
    for p, q in zip(xy, np.roll(xy, -1, axis=0)):
        pts = p + s[:, None] * (q - p)
        head = np.interp(pts[:, 0], table[:, 0] - model.origin[0], table[:, 1] - model.origin[1]) - pts[:, 1]
        pressure = RHO_W * G * np.maximum(head, 0.0)
        t = q - p
        n_in = np.array([-t[1], t[0]]) / np.hypot(*t)
        tm = t_rows(pts[:, 0] - c[0], pts[:, 1] - c[1])
        expected += np.einsum("gij,g,i->j", tm, pressure, n_in) * np.hypot(*t) / len(s)
    assert np.abs(load - expected).max() <= 1e-8 * np.abs(expected).max()


def test_pretension_pulls_a_free_block_towards_the_anchor():
    """A 1 m block on a frictionless base, bolted to a fixed wall 0.5 m away with pretension P0
    (stiffness k): the pair of forces ±P0 pulls it towards the wall until the tension vanishes,
    δ = P0/k. The equilibrium start puts it there at rest; under a sudden start it oscillates
    about δ with ω = √(k/m): over whole periods its mean displacement is δ and the bolt's mean
    tension 0 (its first swing reaches 2δ, less Newmark's damping)."""
    rock = dd.Material(density=2500.0, young=5e9, poisson=0.25)
    p0, k = 1000.0, 1e5
    period = 2 * math.pi / math.sqrt(k / 2500.0)
    for equilibrium in (True, False):
        s = dd.Scene(gravity=G)
        s.add_block([(0, 0), (10, 0), (10, 1), (0, 1)], material=rock, fixed=True)
        s.add_block([(0, 1), (1, 1), (1, 3), (0, 3)], material=rock, fixed=True)      # the wall
        blk = s.add_block([(1.5, 1), (2.5, 1), (2.5, 2), (1.5, 2)], material=rock)
        s.set_joint(dd.Joint(friction=0.0))
        s.add_bolt((2.0, 1.5), (0.5, 1.5), stiffness=k, pretension=p0)
        res = dd.simulate(s, dd.Params(dt=0.005, initial_equilibrium=equilibrium),
                          duration=3 * period if not equilibrium else 0.2)
        moved = 2.0 - res.centroid[:, blk, 0]                                # towards the wall
        if equilibrium:
            assert moved[0] == pytest.approx(p0 / k, rel=1e-3)   # the elastic settlement of the base
            assert np.ptp(moved) < 1e-9 and np.abs(res.bolt_force).max() < 1e-6 * p0
            continue
        t = res.time
        assert np.trapezoid(moved, t) / t[-1] == pytest.approx(p0 / k, rel=1e-2)
        assert abs(np.trapezoid(res.bolt_force[:, 0], t) / t[-1]) < 1e-2 * p0
        assert moved.max() == pytest.approx(2 * p0 / k, rel=5e-2)


@pytest.mark.parametrize("capacity", [15e3, 8e3])
def test_bolted_column_against_overturning(capacity):
    """A 1 × 4 m column pushed over its toe by F = 20 kN/m at its top, bolted at 3 m to a wall
    behind it: the bolt must carry the overturning moment about the toe, T = (F·h − W·b/2)/h_b
    (the heel lifts: the bolt is far softer than the contact). kgm's FS_rot = C/T: with
    C = 15 kN/m (FS 1.45) DDA holds it and the bolt carries T within 1 %; with C = 8 kN/m
    (FS 0.78) the bolt breaks and the column topples."""
    import kgm

    rock = dd.Material(density=RHO, young=5e9, poisson=0.25)
    s = dd.Scene(gravity=G)
    s.add_block([(-4, -1), (4, -1), (4, 0), (-4, 0)], material=rock, fixed=True)
    s.add_block([(-3, 0), (-2, 0), (-2, 5), (-3, 5)], material=rock, fixed=True)       # the wall
    col = s.add_block([(0, 0), (1, 0), (1, 4), (0, 4)], material=rock)
    s.set_joint(dd.Joint(friction=45.0))
    s.add_point_load(col, (0.5, 4.0), (20e3, 0.0))
    s.add_bolt((0.1, 3.0), (-2.5, 3.0), stiffness=1e8, capacity=capacity)
    demand = (20e3 * 4.0 - RHO * G * 4.0 * 0.5) / 3.0
    assert kgm.factor_of_safety(s, [col], method="rigid") == pytest.approx(capacity / demand, rel=1e-9)
    res = dd.simulate(s, duration=1.0)
    if capacity > demand:
        assert res.bolt_force[-1, 0] == pytest.approx(demand, rel=1e-2)
        assert abs(res.rotation[-1, col]) < 1e-3 and len(res.bolt_events) == 0
    else:
        assert len(res.bolt_events) == 1 and abs(res.rotation[-1, col]) > 0.1
