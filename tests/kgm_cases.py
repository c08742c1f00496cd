"""Hand-made block systems for the kgm tests (closed-form and block-theory cases).

Slopes face +x; blocks are added free unless noted; ``ROCK`` has ρ = 2500 kg/m³.
"""

import numpy as np

import ddatai as dd

G = 9.81
RHO = 2500.0
ROCK = dd.Material(density=RHO, young=5e9, poisson=0.25)


def planar_slope(height=20.0, face=60.0, plane=30.0, crack=5.0, friction=30.0, cohesion=25e3):
    """Hoek & Bray's planar failure with a dry vertical tension crack (docs/kgm/method.md §4.2):
    a face of dip ψf and height H, a horizontal upper surface, a sliding plane of dip ψp
    daylighting at the toe (0, 0) and a crack of depth z. Returns (scene, block id)."""
    cot_f, cot_p = 1.0 / np.tan(np.radians(face)), 1.0 / np.tan(np.radians(plane))
    xc = -(height - crack) * cot_p  # crack position, where the plane is at depth z
    scene = dd.Scene(gravity=G)
    block = scene.add_block([(0, 0), (-height * cot_f, height), (xc, height), (xc, height - crack)],
                            material=ROCK)
    scene.add_block([(-80, -20), (30, -20), (30, 0), (0, 0), (xc, height - crack), (xc, height),
                     (-80, height)], material=ROCK, fixed=True)
    scene.set_joint(dd.Joint(friction=friction, cohesion=cohesion))
    return scene, block


def hoek_bray_fs(height, face, plane, crack, friction, cohesion, gamma=RHO * G):
    """FS = [cA + W cosψp tanφ] / [W sinψp], W = ½γH²[(1 − (z/H)²)cotψp − cotψf],
    A = (H − z)/sinψp (dry, no seismic load; docs/kgm/method.md §4.2)."""
    p, f = np.radians(plane), np.radians(face)
    w = 0.5 * gamma * height ** 2 * ((1 - (crack / height) ** 2) / np.tan(p) - 1 / np.tan(f))
    a = (height - crack) / np.sin(p)
    return (cohesion * a + w * np.cos(p) * np.tan(np.radians(friction))) / (w * np.sin(p))


def block_on_incline(theta=30.0, width=10.0, height=1.0, friction=25.0, cohesion=20e3):
    """A width × height block resting on a fixed incline of dip θ (down-slope toward +x)."""
    t = np.array([np.cos(np.radians(theta)), -np.sin(np.radians(theta))])   # down-slope
    n = np.array([np.sin(np.radians(theta)), np.cos(np.radians(theta))])    # up, normal
    scene = dd.Scene(gravity=G)
    base = scene.add_block([-5 * t - 3 * n, (width + 15) * t - 3 * n, (width + 15) * t, -5 * t],
                           material=ROCK, fixed=True)
    p0 = np.zeros(2)
    block = scene.add_block([p0, p0 + width * t, p0 + width * t + height * n, p0 + height * n],
                            material=ROCK)
    scene.set_joint(dd.Joint(friction=friction, cohesion=cohesion))
    return scene, base, block


def block_above_incline(offset, theta=30.0):
    """`block_on_incline`'s 10 × 1 m block moved ``offset`` [m] along the plane's
    normal (> 0: a gap, < 0: an overlap); the model is ~25 m across."""
    t = np.array([np.cos(np.radians(theta)), -np.sin(np.radians(theta))])
    n = np.array([np.sin(np.radians(theta)), np.cos(np.radians(theta))])
    scene = dd.Scene(gravity=9.81)
    scene.add_block([-5 * t - 3 * n, 25 * t - 3 * n, 25 * t, -5 * t], material=ROCK, fixed=True)
    p0 = offset * n
    scene.add_block([p0, p0 + 10 * t, p0 + 10 * t + n, p0 + n], material=ROCK)
    scene.set_joint(dd.Joint(friction=35.0, cohesion=20e3))
    return scene


def tapered_block():
    """A trapezoid narrowing toward its free top, wedged between two fixed blocks (type IV)."""
    scene = dd.Scene(gravity=G)
    b = scene.add_block([(0, 0), (4, 0), (3, 2), (1, 2)], material=ROCK)
    scene.add_block([(-3, -1), (7, -1), (7, 0), (0, 0)], material=ROCK, fixed=True)        # floor
    scene.add_block([(-3, 0), (0, 0), (1, 2), (-3, 2)], material=ROCK, fixed=True)          # left
    scene.add_block([(4, 0), (7, 0), (7, 2), (3, 2)], material=ROCK, fixed=True)            # right
    scene.set_joint(dd.Joint(friction=30.0))
    return scene, b


def slot_block(cohesion=0.0):
    """A 1 × 2 block in a vertical slot between two fixed blocks, open below and above."""
    scene = dd.Scene(gravity=G)
    b = scene.add_block([(0, 0), (1, 0), (1, 2), (0, 2)], material=ROCK)
    scene.add_block([(-2, -1), (0, -1), (0, 3), (-2, 3)], material=ROCK, fixed=True)
    scene.add_block([(1, -1), (3, -1), (3, 3), (1, 3)], material=ROCK, fixed=True)
    scene.set_joint(dd.Joint(friction=30.0, cohesion=cohesion))
    return scene, b


def hanging_block():
    """A block glued under an overhang only: its resultant pulls it off its one contact."""
    scene = dd.Scene(gravity=G)
    b = scene.add_block([(0, 0), (2, 0), (2, 1), (0, 1)], material=ROCK)
    scene.add_block([(-1, 1), (3, 1), (3, 2), (-1, 2)], material=ROCK, fixed=True)
    return scene, b


def bent_chain(friction=25.0, cohesion=0.0):
    """Three blocks on a base that bends from 35° (upper two) to 10° (toe block), vertical
    cross joints, all joints alike. Alone, the toe block slides on the gentle plane (type II)
    and the upper ones are pushed into their lower neighbour (type III). Ids 0 (toe) .. 2."""
    def down(p, length, dip):
        a = np.radians(dip)
        return p + length * np.array([-np.cos(a), np.sin(a)])  # up-slope along the plane

    b0 = np.zeros(2)
    j = down(b0, 6.0, 10.0)
    k = down(j, 5.0, 35.0)
    m = down(k, 5.0, 35.0)
    scene = dd.Scene(gravity=G)
    ids = [scene.add_block([b0, (0, 4), (j[0], 4), j], material=ROCK),
           scene.add_block([j, (j[0], 9), (k[0], 9), k], material=ROCK),
           scene.add_block([k, (k[0], 9), (m[0], 9), m], material=ROCK)]
    scene.add_block([(-20, -5), (5, -5), (5, 0), b0, j, k, m, (-20, m[1])], material=ROCK, fixed=True)
    scene.set_joint(dd.Joint(friction=friction, cohesion=cohesion))
    return scene, ids


def incline_scene(friction=30.0, cohesion=0.0, theta=30.0, width=10.0, height=1.0):
    """`block_on_incline` as a ``build(**sample) -> Scene`` for probabilistic studies (the
    block is block 1; FS = (c·A + W cosθ tanφ) / (W sinθ), A = width)."""
    return block_on_incline(theta=theta, width=width, height=height, friction=friction, cohesion=cohesion)[0]


def incline_scene_fixed_dt(friction=30.0, cohesion=0.0):
    """`incline_scene` with its `Params`: a fixed Δt of 2 ms (as the paper's examples)."""
    return incline_scene(friction=friction, cohesion=cohesion), dd.Params(dt=2e-3)


def incline_fs(friction, cohesion, theta=30.0, width=10.0, height=1.0):
    """Closed-form FS of `incline_scene`'s block."""
    t = np.radians(theta)
    w = RHO * G * width * height
    return (cohesion * width + w * np.cos(t) * np.tan(np.radians(friction))) / (w * np.sin(t))


def incline_scene_slow(friction=30.0, cohesion=0.0, delay=0.05):
    """`incline_scene` that takes ``delay`` seconds to build (a study that can be killed
    half-way)."""
    import time

    time.sleep(delay)
    return incline_scene(friction=friction, cohesion=cohesion)


def jointed_scene(friction=30.0, seed=0):
    """A 20 m slope face cut by one random joint set (`dd.joint_sets` with ``seed``): a new
    realisation of the rock mass per seed."""
    scene = dd.Scene(gravity=G)
    outline = [(-10, -5), (30, -5), (30, 20), (14, 20), (6, 0), (-10, 0)]
    sets = [dd.JointSet(dip=35.0, spacing=4.0, spacing_spread=1.0, dip_spread=3.0,
                        joint=dd.Joint(friction=friction))]
    ids = scene.cut(outline, dd.joint_sets(outline, sets, seed=seed), material=ROCK)
    for b in ids:
        c = scene.polygon(b).mean(axis=0)
        if c[1] < 0.0 or c[0] > 26.0:
            scene.set_fixed(b)
    scene.set_joint(dd.Joint(friction=friction))
    return scene


#: `incline_scene_killing` kills its process for a friction angle above this [degrees]
KILL_ABOVE = 44.17
#: environment variable naming a file: `incline_scene_dies_once` kills its process while the file
#: does not exist (and creates it)
DIE_ONCE = "KGM_CASES_DIE_ONCE"


def incline_scene_killing(friction=30.0, cohesion=0.0):
    """`incline_scene`, except that a sample with friction above `KILL_ABOVE` kills the worker
    process that builds it, every time (a sample that always crashes its worker)."""
    if friction > KILL_ABOVE:
        from worker_cases import kill_this_worker

        kill_this_worker()
    return incline_scene(friction=friction, cohesion=cohesion)


def incline_scene_dies_once(friction=30.0, cohesion=0.0):
    """`incline_scene`, except that the first sample with friction above 40° built while the
    file named by `DIE_ONCE` does not exist creates it and kills its worker (a worker lost once,
    to a cause outside the sample)."""
    import os

    mark = os.environ.get(DIE_ONCE)
    if mark and friction > 40.0 and not os.path.exists(mark):
        open(mark, "w").close()
        from worker_cases import kill_this_worker

        kill_this_worker()
    return incline_scene(friction=friction, cohesion=cohesion)


def planar_scene(friction=30.0, cohesion=25e3):
    """`planar_slope` (H = 20 m, face 60°, plane 30°, crack 5 m) as a ``build(**sample) ->
    Scene`` for probabilistic studies: the sliding block is block 0, FS = `hoek_bray_fs`."""
    scene, block = planar_slope(friction=friction, cohesion=cohesion)
    assert block == 0
    return scene
