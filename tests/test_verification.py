"""Verification: DDA against closed-form answers (docs/method/dda.md §7).

Every tolerance below comes from the method, not from what the code happens to give:
- the DDA integrator (Newmark β = 1/2, γ = 1) is exact for constant acceleration, so free
  flight and rigid rotation are checked to round-off (§5.1, §7e, §7h);
- sliding on an incline carries only the start-up perturbation and the one-iteration lag of the
  friction load: < 0.1 % when θ − φ ≥ 5°, < 2 % within 0.5° of the threshold (§7a);
- a block at rest moves only by the elastic offset of its contact springs, h2·W·sinθ/(2p)
  ~ 1e-7 m here: the bound 1e-5 × block size (§7b);
- the stacked column's constant-strain blocks carry the exact average stress (§7f);
- the Goodman–Bray cases are classified with the refined initial-motion criterion and chosen
  robust to ±3° of φ and θ (§7d).
All runs use the default parameters (`params=None`) unless a case needs a fixed time step.
"""

import numpy as np
import pytest

import ddatai as dd
from cases import (G, ROCK, biplanar_critical_friction, biplanar_scene, block_on_incline,
                   downslope_displacement, incline_base, incline_frame, launched_block, sliding_scene)
from ddatai.geometry import polygon_integrals

# ----------------------------------------------------------------------------- §7a sliding
@pytest.mark.parametrize("theta, phi, tol", [
    (30.0, 20.0, 1e-3),
    (30.0, 0.0, 1e-3),
    (45.0, 30.0, 1e-3),
    (40.0, 15.0, 1e-3),
    (30.0, 29.5, 2e-2),   # within 0.5° of the threshold: the start-up perturbation dominates
])
def test_block_slides_down_incline(theta, phi, tol):
    """d(1 s) = ½ g (sinθ − cosθ tanφ) t² on real inclined geometry; contacts end sliding."""
    scene, block = sliding_scene(theta, phi)
    res = dd.simulate(scene, duration=1.0, record_contacts=True)
    th, ph = np.radians(theta), np.radians(phi)
    exact = 0.5 * G * (np.sin(th) - np.cos(th) * np.tan(ph)) * 1.0 ** 2
    d = downslope_displacement(res, block, theta)
    assert res.time[-1] == pytest.approx(1.0, abs=1e-12)
    assert abs(d - exact) / exact < tol, (d, exact)
    _, states = res.contacts(-1)
    assert len(states) == 2 and np.all(states == dd.ContactState.SLIDE)


# ----------------------------------------------------------------------------- §7b resting
@pytest.mark.parametrize("theta, phi", [(20.0, 30.0), (30.0, 35.0), (10.0, 40.0)])
def test_block_rests_on_incline(theta, phi):
    """φ ≥ θ + 5°: the block does not move; drift after 1 s below 1e-5 × block size."""
    scene, block = sliding_scene(theta, phi)
    res = dd.simulate(scene, duration=1.0, record_contacts=True)
    drift = np.linalg.norm(res.centroid[-1, block] - res.centroid[0, block])
    assert drift < 1e-5 * 1.0
    _, states = res.contacts(-1)
    assert np.all(states == dd.ContactState.LOCK)


# ----------------------------------------------------------------------------- §7e free flight
def test_free_flight_is_exact():
    """x = x0 + vx t, y = y0 + vy t − ½ g t², spin constant: exact to round-off (1e-10 rel)."""
    scene = dd.Scene(gravity=G)
    scene.add_block([(0, 0), (2, 0), (2, 1), (0, 1)], material=ROCK, velocity=(3.0, 4.0),
                    angular_velocity=0.5)
    res = dd.simulate(scene, duration=1.5)
    t = res.time
    c0 = res.centroid[0, 0]
    exact = c0 + np.stack([3.0 * t, 4.0 * t - 0.5 * G * t * t], axis=1)
    err = np.abs(res.centroid[:, 0] - exact).max() / np.abs(exact).max()
    assert err < 1e-10
    assert np.allclose(res.velocity[:, 0, 1], 4.0 - G * t, rtol=0, atol=1e-9)
    assert np.allclose(res.rotation[:, 0], 0.5 * t, rtol=0, atol=1e-10)


# ----------------------------------------------------------------------------- §7h rotation
def test_free_rotation_keeps_area():
    """Exact rotation update: area constant to 1e-10 and angle error < 1e-10·ωt (§5.3)."""
    scene = dd.Scene(gravity=0.0)
    scene.add_block([(0, 0), (2, 0), (2, 1), (0, 1)], material=ROCK, angular_velocity=1.0)
    res = dd.simulate(scene, params=dd.Params(dt=0.01), steps=1000, record_every=50)
    areas = np.array([polygon_integrals(p, np.array([0, len(p)]))["area"][0]
                      for p in (res.polygons(f)[0] for f in range(res.n_frames))])
    assert np.abs(areas / 2.0 - 1.0).max() < 1e-10
    assert abs(res.rotation[-1, 0] - res.time[-1]) < 1e-10 * res.time[-1]
    # the centroid does not move
    assert np.abs(res.centroid[:, 0] - res.centroid[0, 0]).max() < 1e-10


# ----------------------------------------------------------------------------- point loads
def _pushed_block(force):
    scene = dd.Scene(gravity=G)
    scene.add_block([(-5, -1), (15, -1), (15, 0), (-5, 0)], material=ROCK, fixed=True)
    block = scene.add_block([(0, 0), (1, 0), (1, 1), (0, 1)], material=ROCK)
    scene.set_joint(dd.Joint(friction=0.0))
    scene.add_point_load(block, (0.5, 0.5), force)
    return scene, block


def test_constant_point_load_on_frictionless_base():
    """x = x0 + F t²/(2m): exact for constant acceleration up to the block's elastic
    deformation under the load (F/(E·1 m) ~ 1e-6 relative); tolerance 1e-4."""
    F = 5000.0
    scene, block = _pushed_block((F, 0.0))
    res = dd.simulate(scene, duration=1.0)
    m = ROCK.density * 1.0
    exact = F * res.time ** 2 / (2 * m)
    dx = res.centroid[:, block, 0] - res.centroid[0, block, 0]
    assert np.abs(dx - exact).max() < 1e-4 * exact[-1]
    assert abs(res.centroid[-1, block, 1] - res.centroid[0, block, 1]) < 1e-5


@pytest.mark.parametrize("convergence", [{}, dd.STRICT_CONVERGENCE], ids=["default", "strict"])
def test_time_dependent_point_load(convergence):
    """F(t) = F0·t gives x = F0 t³/(6m). The load is sampled at mid-step, so each step's
    position carries a'Δt³/12 (a' = F0/m): relative error Δt²/(2T²) = 5e-5 at Δt = 0.01 s.
    Under the default open-close test (docs/method/dda.md §4.3) the contacts may hold up to
    oc_force_tolerance × the block's weight W = m·g of shear beyond their strength (zero here),
    against a push of F0·T at the end: a relative error up to tol·m·g/F0 = 2.5e-3 on top (the
    strict test keeps the integrator's 2e-4).
    """
    F0 = 10000.0
    scene, block = _pushed_block(lambda t: (F0 * t, 0.0))
    res = dd.simulate(scene, duration=1.0, params=dd.Params(**convergence))
    m = ROCK.density * 1.0
    exact = F0 * 1.0 ** 3 / (6 * m)
    dx = res.centroid[-1, block, 0] - res.centroid[0, block, 0]
    tol = 2e-4 if convergence else 2e-4 + dd.Params().oc_force_tolerance * m * G / F0
    assert abs(dx - exact) < tol * exact


def test_block_pinned_at_a_corner_swings_as_a_physical_pendulum():
    """A unit block hanging from a fixed point at a corner, released 5° from rest: period
    T = 2π √(I_p / (m g d)) (1 + a²/16), I_p = m(1/6 + d²), d = √½. The integrator's period
    elongation (11/96)(ωΔt)² is ~3e-5 at Δt = 5 ms: tolerance 5e-4."""
    a0 = np.radians(5.0)
    ang = -0.75 * np.pi + a0  # rotate the square so pivot -> centroid points 5° off vertical
    rot = np.array([[np.cos(ang), -np.sin(ang)], [np.sin(ang), np.cos(ang)]])
    scene = dd.Scene(gravity=G)
    block = scene.add_block(np.array([(0, 0), (1, 0), (1, 1), (0, 1)], float) @ rot.T, material=ROCK)
    scene.add_fixed_point(block, (0.0, 0.0))
    res = dd.simulate(scene, params=dd.Params(dt=0.005), duration=4.5)
    x = res.rotation[:, block] - res.rotation[:, block].mean()
    t = res.time
    up = np.flatnonzero((x[:-1] < 0) & (x[1:] >= 0))
    crossing = t[up] - x[up] * (t[up + 1] - t[up]) / (x[up + 1] - x[up])
    period = np.diff(crossing).mean()
    d = np.sqrt(0.5)
    exact = 2 * np.pi * np.sqrt((1 / 6 + d * d) / (G * d)) * (1 + a0 ** 2 / 16)
    assert abs(period / exact - 1) < 5e-4
    # the pivot stays put: the fixed-point spring holds it to W/p_f ~ 1e-9 m, because the
    # constraint includes the second-order rotation terms of the exact update (§5.3)
    assert np.abs(res.vertices[:, res.vertex_offset[block]]).max() < 1e-8


# ----------------------------------------------------------------------------- §7f column
@pytest.mark.parametrize("plane", ["stress", "strain"])
def test_stacked_column_stress(plane):
    """n blocks on a fixed base, φ = 0, static: σy,k = −ρ g h (k − ½) from the top, σx = τ = 0."""
    n, h = 5, 1.0
    scene = dd.Scene(gravity=G)
    scene.add_block([(-1, -1), (2, -1), (2, 0), (-1, 0)], material=ROCK, fixed=True)
    ids = [scene.add_block([(0, k * h), (1, k * h), (1, (k + 1) * h), (0, (k + 1) * h)], material=ROCK)
           for k in range(n)]
    scene.set_joint(dd.Joint(friction=0.0))
    res = dd.simulate(scene, params=dd.Params(static=True, plane=plane), steps=150)
    sy = res.stress[-1, ids, 1]
    exact = np.array([-ROCK.density * G * h * (n - k - 0.5) for k in range(n)])
    assert np.abs(sy / exact - 1).max() < 0.01
    assert np.abs(res.stress[-1, ids, 0]).max() < 0.01 * np.abs(exact).max()
    assert np.abs(res.stress[-1, ids, 2]).max() < 0.01 * np.abs(exact).max()
    assert np.all(res.velocity[1:] == 0.0)  # static mode: velocities reset every step


def test_fitted_grid_with_friction_reaches_equilibrium():
    """A 6 × 6 grid of perfectly fitted unit blocks (φ = 30°) on a fixed base, static. Side
    friction lets columns share load, so single blocks differ from the column value, but the
    mean σy of every row is fixed by equilibrium: −ρ g h (n − k − ½) for row k from the bottom.
    Also guards the open-close iteration on a fitted grid, where many contacts carry almost no
    force (X-junctions, side joints) and used to chatter."""
    from scenes.stacked_grid import build

    n = 6
    scene, params = build(n, gap=0.0, static=True, dt=0.005)
    res = dd.simulate(scene, params=params, steps=80, record_every=80)
    sy = res.stress[-1, 1:, 1].reshape(n, n)
    exact = -ROCK.density * G * 1.0 * (n - np.arange(n) - 0.5)
    assert np.abs(sy.mean(axis=1) / exact - 1).max() < 0.01
    assert res.steps["dt_cuts"].sum() == 0


# ----------------------------------------------------------------------------- §7d Goodman–Bray
def refined_mode(r: float, theta: float, phi: float) -> str:
    """Initial motion of a rigid b × h block (r = b/h) released on a plane (docs/method/dda.md §7d)."""
    t, mu = np.tan(np.radians(theta)), np.tan(np.radians(phi))
    if r >= t:
        return "stable" if t <= mu else "slide"
    f = (t + 3 * r + 4 * r * r * t) / (4 + r * r + 3 * r * t)
    if mu >= f:
        return "topple"
    return "slide" if r >= mu else "slide+topple"


GB_CASES = [
    (1.0, 30.0, 40.0, "stable"),
    (0.5, 20.0, 30.0, "stable"),
    (1.0, 30.0, 20.0, "slide"),
    (0.4, 35.0, 10.0, "slide"),
    (0.2, 30.0, 40.0, "topple"),
    (0.15, 30.0, 20.0, "topple"),
    (0.05, 40.0, 8.0, "slide+topple"),
]


@pytest.mark.parametrize("r, theta, phi, mode", GB_CASES)
def test_goodman_bray_case_is_robust(r, theta, phi, mode):
    """The chosen cases keep their mode under ±3° of φ and θ (so they test the code, not the
    boundary); pure-sliding cases also have tilt margin tanβ_c = (r − μ)/(1 + μr) > 0.1."""
    for dth in (-3, 0, 3):
        for dph in (-3, 0, 3):
            assert refined_mode(r, theta + dth, phi + dph) == mode
    if mode == "slide":
        mu = np.tan(np.radians(phi))
        assert (r - mu) / (1 + mu * r) > 0.1


@pytest.mark.parametrize("r, theta, phi, mode", GB_CASES)
def test_goodman_bray_regimes(r, theta, phi, mode):
    """Stable / slide / topple / slide+topple at T = 0.3 s: toppling if the block rotated more
    than 2e-3 rad, sliding if its down-slope corner slid more than 2e-3 m (§7d)."""
    h = 2.0 if r < 0.1 else 1.0
    scene = dd.Scene(gravity=G)
    incline_base(scene, theta)
    block = block_on_incline(scene, theta, at=4.0, width=r * h, height=h)
    scene.set_joint(dd.Joint(friction=phi))
    res = dd.simulate(scene, duration=0.3)
    t, _ = incline_frame(theta)
    corner0 = res.polygons(0)[block][0]  # lower down-slope corner
    slide = float(-(res.polygons(-1)[block][0] - corner0) @ t)
    rotation = float(res.rotation[-1, block])
    got = {(False, False): "stable", (True, False): "slide", (False, True): "topple",
           (True, True): "slide+topple"}[(slide > 2e-3, rotation > 2e-3)]
    assert got == mode, (slide, rotation)
    if mode == "topple":
        assert rotation > 0  # counter-clockwise: it falls down-slope (down-slope is −t)


# ----------------------------------------------------------------------------- §7i two blocks
@pytest.mark.parametrize("phi1, phi2", [(20.0, 10.0), (20.0, 25.0), (35.0, 10.0)])
def test_two_stacked_blocks_on_incline(phi1, phi2):
    """Bottom 2×1 block on the plane (φ1), top 1×1 block on it (φ2), θ = 30°, T = 0.5 s."""
    theta, T = 30.0, 0.5
    scene = dd.Scene(gravity=G)
    base = incline_base(scene, theta)
    b1 = block_on_incline(scene, theta, at=3.0, width=2.0, height=1.0)
    b2 = block_on_incline(scene, theta, at=3.5, width=1.0, height=1.0, lift=1.0)
    scene.set_joint(dd.Joint(friction=phi1), between=(base, b1))
    scene.set_joint(dd.Joint(friction=phi2), between=(b1, b2))
    res = dd.simulate(scene, duration=T)
    th = np.radians(theta)
    m1, m2 = 2.0, 1.0
    mu1, mu2 = np.tan(np.radians(phi1)), np.tan(np.radians(phi2))
    if mu2 >= mu1:
        a1 = a2 = max(0.0, G * (np.sin(th) - np.cos(th) * mu1))
    else:
        a2 = G * (np.sin(th) - np.cos(th) * mu2)
        a1 = max(0.0, G * np.sin(th) + mu2 * (m2 / m1) * G * np.cos(th) - mu1 * (m1 + m2) / m1 * G * np.cos(th))
    for block, a in ((b1, a1), (b2, a2)):
        exact = 0.5 * a * T * T
        d = downslope_displacement(res, block, theta)
        if exact == 0:
            assert abs(d) < 1e-5
        else:
            assert abs(d - exact) / exact < 5e-3, (block, d, exact)


# ----------------------------------------------------------------------------- joint strength
def test_cohesion_holds_or_fails_a_block():
    """A bonded joint holds while c·L ≥ W(sinθ − cosθ tanφ); below it the bond breaks and the
    block slides (θ = 30°, φ = 20°, L = 1 m)."""
    theta, phi = 30.0, 20.0
    th = np.radians(theta)
    need = ROCK.density * G * (np.sin(th) - np.cos(th) * np.tan(np.radians(phi)))
    moved = {}
    for factor in (2.0, 0.5):
        scene, block = sliding_scene(theta, phi)
        scene.set_joint(dd.Joint(friction=phi, cohesion=factor * need))
        res = dd.simulate(scene, duration=0.5)
        moved[factor] = downslope_displacement(res, block, theta)
    assert abs(moved[2.0]) < 1e-5
    free_slide = 0.5 * G * (np.sin(th) - np.cos(th) * np.tan(np.radians(phi))) * 0.5 ** 2
    assert 0.8 * free_slide < moved[0.5] <= free_slide * 1.001


def test_tensile_strength_holds_a_hanging_block():
    """A 1 m block glued under a fixed block hangs while T·L ≥ W and falls freely otherwise."""
    W = ROCK.density * G * 1.0
    drop = {}
    for factor in (2.0, 0.5):
        scene = dd.Scene(gravity=G)
        scene.add_block([(-2, 0), (3, 0), (3, 1), (-2, 1)], material=ROCK, fixed=True)
        block = scene.add_block([(0, -1), (1, -1), (1, 0), (0, 0)], material=ROCK)
        scene.set_joint(dd.Joint(friction=30.0, cohesion=1e5, tensile=factor * W))
        res = dd.simulate(scene, duration=0.3)
        drop[factor] = res.centroid[0, block, 1] - res.centroid[-1, block, 1]
    assert abs(drop[2.0]) < 1e-5
    assert drop[0.5] == pytest.approx(0.5 * G * 0.3 ** 2, rel=1e-3)


# ----------------------------------------------------------------------------- seismic input
@pytest.mark.parametrize("as_record", [False, True])
def test_block_slides_under_constant_ground_acceleration(as_record):
    """Ground acceleration a_g = 0.5 g on a block with φ = 10°: relative to the ground the
    block slides back with a = a_g − g tanφ (exact, constant acceleration); the fixed base stays
    put in the ground frame."""
    ag = 0.5 * G
    scene = dd.Scene(gravity=G)
    base = scene.add_block([(-10, -1), (10, -1), (10, 0), (-10, 0)], material=ROCK, fixed=True)
    block = scene.add_block([(0, 0), (1, 0), (1, 1), (0, 1)], material=ROCK)
    scene.set_joint(dd.Joint(friction=10.0))
    if as_record:
        scene.set_ground_acceleration((np.array([0.0, 10.0]), np.array([ag, ag])))
    else:
        scene.set_ground_acceleration(lambda t: (ag, 0.0))
    res = dd.simulate(scene, duration=1.0)
    exact = -0.5 * (ag - G * np.tan(np.radians(10.0))) * 1.0 ** 2
    dx = res.centroid[-1, block, 0] - res.centroid[0, block, 0]
    assert abs(dx - exact) < 1e-3 * abs(exact)
    assert np.all(res.centroid[:, base] == res.centroid[0, base])


# ----------------------------------------------------------------------------- moving blocks
# A rigid block that slides with friction decelerates at a constant rate, so the integrator is
# exact for it (§5.1): whatever error remains comes from the contact law, and a correct one
# meets the rigid closed form within the blocks' elastic compliance. Tolerance 1 %.

def _along(res, block, theta):
    t, n = incline_frame(theta)
    d = res.centroid[:, block] - res.centroid[0, block]
    v = res.velocity[:, block]
    return -d @ t, d @ n, -v @ t   # down-slope displacement, lift, down-slope speed


@pytest.mark.parametrize("theta, phi, speed", [
    (0.0, 30.0, 1.0),    # the guide's block (docs/guide/modelling.md), on a flat base
    (0.0, 30.0, 3.0),
    (20.0, 30.0, 2.0),   # launched down a 20° plane
    (20.0, 30.0, -2.0),  # launched up it: decelerates at g(sinθ + cosθ tanφ), then stays
])
def test_launched_block_stops_at_the_closed_form_distance(theta, phi, speed):
    """Stopping distance v²/2a and time |v|/a with a = g(cosθ tanφ ∓ sinθ); half-way in time
    the speed is v/2; no lift-off (the block keeps its base contacts)."""
    th, mu = np.radians(theta), np.tan(np.radians(phi))
    a = G * (np.cos(th) * mu - np.sign(speed) * np.sin(th))
    stop_time = abs(speed) / a
    scene, block = launched_block(theta, phi, speed)
    res = dd.simulate(scene, duration=1.25 * stop_time + 0.05)
    d, lift, v = _along(res, block, theta)
    assert d[-1] == pytest.approx(speed * abs(speed) / (2 * a), rel=0.01)
    half = np.interp(0.5 * stop_time, res.time, v)
    assert half == pytest.approx(0.5 * speed, rel=0.01)
    assert np.abs(v[-1]) < 1e-3 * abs(speed)
    moving = res.time < 0.98 * stop_time
    assert np.all(np.abs(v[moving]) > 0.0) and np.all(v[moving] * speed > 0)  # never backwards
    assert np.abs(lift).max() < 1e-5


def test_block_thrown_onto_a_plane_slides_with_coulomb_deceleration():
    """A block dropped 5 mm with 2 m/s across a flat base (φ = 30°). The impact takes the
    Coulomb impulse μ·(normal impulse) off its speed (it may bounce a little: DDA's impacts
    are partly elastic); once it stays on the base it slides with deceleration μg until it
    stops, and it never moves backwards."""
    mu = np.tan(np.radians(30.0))
    scene = dd.Scene(gravity=G)
    scene.add_block([(-1, -1), (14, -1), (14, 0), (-1, 0)], material=ROCK, fixed=True)
    block = scene.add_block([(0, 0.005), (1.5, 0.005), (1.5, 0.805), (0, 0.805)], material=ROCK,
                            velocity=(2.0, 0.0))
    scene.set_joint(dd.Joint(friction=30.0))
    res = dd.simulate(scene, duration=0.5)
    t = res.time
    x = res.centroid[:, block, 0]
    vx = res.velocity[:, block, 0]
    y = res.centroid[:, block, 1] - res.centroid[0, block, 1]
    on_base = np.abs(y + 0.005) < 1e-5
    # the sliding phase: from the last landing, while the speed is clearly positive
    last_flight = np.flatnonzero(~on_base)[-1]
    sliding = (np.arange(len(t)) > last_flight + 1) & (vx > 0.05)
    assert np.count_nonzero(sliding) > 10
    slope = np.polyfit(t[sliding], vx[sliding], 1)[0]
    assert slope == pytest.approx(-G * mu, rel=0.01)
    # not a bound from the method: at the stop the integrator reverses the velocity inside the
    # contact springs (measured 1.5e-6 m back; docs/guide/verification.md, limits)
    assert np.all(np.diff(x) >= -1e-5)
    assert abs(vx[-1]) < 1e-3


@pytest.mark.parametrize("fs, breaks", [(1.3, True), (0.8, True), (0.8, False)])
def test_cohesive_block_under_sudden_gravity(fs, breaks):
    """A 1 m block on a 30° plane (φ = 20°) whose cohesion gives FS = (c·L + W cosθ tanφ)/(W sinθ).
    FS 1.3: it holds (moves less than 1e-5 m). FS 0.8: it slides at once, with
    a = g(sinθ − cosθ tanφ) once the bond breaks (Shi's rule, the default) or
    a = g(sinθ − cosθ tanφ) − c·L/m if joints keep their cohesion while sliding."""
    theta, phi, T = 30.0, 20.0, 0.5
    th, mu = np.radians(theta), np.tan(np.radians(phi))
    weight = ROCK.density * G
    cohesion = weight * (fs * np.sin(th) - np.cos(th) * mu)
    scene, block = sliding_scene(theta, phi)
    scene.set_joint(dd.Joint(friction=phi, cohesion=cohesion))
    res = dd.simulate(scene, params=dd.Params(bond_breaks_on_slip=breaks), duration=T)
    d = downslope_displacement(res, block, theta)
    if fs > 1:
        assert abs(d) < 1e-5
        return
    a = G * (np.sin(th) - np.cos(th) * mu) - (0.0 if breaks else cohesion / ROCK.density)
    assert d == pytest.approx(0.5 * a * T * T, rel=0.01)


def test_bonded_column_starts_in_equilibrium():
    """Ten bonded 1 m blocks on a fixed base under gravity, dynamic run with the defaults: the
    equilibrium start gives every block σy = −ρ g (k − ½) h (k from the top) at once, no joint
    breaks, and nothing rings (σy stays within 1 %, speeds stay elastic)."""
    n = 10
    scene = dd.Scene(gravity=G)
    scene.add_block([(-1, -1), (2, -1), (2, 0), (-1, 0)], material=ROCK, fixed=True)
    ids = [scene.add_block([(0, k), (1, k), (1, k + 1), (0, k + 1)], material=ROCK) for k in range(n)]
    scene.set_joint(dd.Joint(friction=30.0, cohesion=1e5, tensile=1e5))
    res = dd.simulate(scene, duration=0.5, record_contacts=True)
    exact = np.array([-ROCK.density * G * (n - k - 0.5) for k in range(n)])
    sy = res.stress[:, ids, 1]
    assert np.abs(sy / exact - 1).max() < 0.01
    _, states = res.contacts(-1)
    assert np.all(states == dd.ContactState.LOCK)
    assert res.start["held"][0] == n and res.start["released"][0] == 0
    # not a bound from the method: "does not ring" (sudden gravity rings tall stacks at ~0.1 m/s)
    assert np.abs(res.velocity[:, ids]).max() < 1e-4


def test_a_tall_soft_column_settles_as_a_whole():
    """60 plain 1 m blocks (E = 100 MPa, p = 1 GPa, plane stress) on a fixed base: the stage
    settles the top by 0.37 m, more than a quarter of a block, yet holds every block — each
    moves with its neighbours, which a mechanism does not. The settlement is the uniaxial
    column's ρgH²/2E plus the joints' give Σ W_k/2p (two vertex contacts per joint), within
    the largest strain ρgH/E = 1.2 % (the stage solves at the settled geometry, the closed form
    at the initial one); then the column stays where the stage left it."""
    n, rho, young, penalty = 60, 2000.0, 1e8, 1e9
    rock = dd.Material(density=rho, young=young, poisson=0.25)
    scene = dd.Scene(gravity=G)
    scene.add_block([(-1, -1), (2, -1), (2, 0), (-1, 0)], material=rock, fixed=True)
    top = [scene.add_block([(0, k), (1, k), (1, k + 1), (0, k + 1)], material=rock) for k in range(n)][-1]
    scene.set_joint(dd.Joint(friction=30.0))
    res = dd.simulate(scene, params=dd.Params(dt=1e-3, penalty=penalty, plane="stress"), duration=0.1)
    assert res.start["held"][0] == n and res.start["released"][0] == 0
    exact = rho * G * n * n / (2 * young) + sum(rho * G * (n - k) / (2 * penalty) for k in range(n))
    settled = (n - 0.5) - res.centroid[0, top, 1]
    assert settled == pytest.approx(exact, rel=rho * G * n / young)
    assert np.abs(res.centroid[:, top] - res.centroid[0, top]).max() < 1e-3 * exact


@pytest.mark.parametrize("offset, moves", [(-0.2, True), (0.2, False)])
def test_biplanar_pair_critical_friction(offset, moves):
    """Upper block on a 50° plane pushing a lower block along a flat base through a vertical
    interface (friction φ everywhere): limit equilibrium's critical φ (closed form,
    `cases.biplanar_critical_friction`) within 0.2°: the pair slides at φc − 0.2° and holds
    at φc + 0.2°, default start."""
    phi = biplanar_critical_friction() + offset
    scene, (a, b) = biplanar_scene(phi)
    res = dd.simulate(scene, duration=1.0)
    moved = np.linalg.norm(res.centroid[-1, [a, b]] - res.centroid[0, [a, b]], axis=1).max()
    if moves:
        assert moved > 2e-3
    else:
        assert moved < 1e-4


@pytest.mark.parametrize("case", ["launched", "biplanar"])
def test_coulomb_holds_at_every_contact_of_every_step(case):
    """After every accepted step: a locked contact's shear force k_s|ds| is at most its Coulomb
    strength S = N tanφ + c·L, and a sliding contact's friction equals S of that step (relative
    1e-3 plus the round-off force p·1e-12·w0)."""
    from ddatai.model import build_model
    from ddatai.start import settle
    from ddatai.step import Stepper

    if case == "launched":
        scene, _ = launched_block(20.0, 30.0, 2.0)
    else:
        scene, _ = biplanar_scene(biplanar_critical_friction() - 0.3)
    model = build_model(scene)
    stepper = Stepper(model)
    state, _ = settle(stepper, model.initial_state())
    checked = 0
    while state.time < 0.5:
        outcome = stepper.advance(state)
        state, c = outcome.state, outcome.contacts
        strength = c.normal_force * c.tan_phi + c.cohesion * c.length * c.bond
        slack = 1e-3 * strength + model.force_roundoff
        ve = c.cint[:, 0] == dd.ContactKind.VE
        locked = ve & (c.state == dd.ContactState.LOCK)
        sliding = ve & (c.state == dd.ContactState.SLIDE)
        assert np.all(model.shear_penalty * np.abs(c.ds[locked]) <= strength[locked] + slack[locked])
        used = outcome.friction[sliding]
        assert np.all(np.abs(used - strength[sliding]) <= slack[sliding])
        checked += int(np.count_nonzero(locked | sliding))
    assert checked > 0
