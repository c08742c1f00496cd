"""Scene builders for the verification tests (closed-form set-ups of dda-method.md §7).

Inclines use real inclined geometry: a fixed base whose top face rises at angle θ along
t = (cos θ, sin θ); blocks rest on it, rotated by θ. Down-slope is -t.
"""

import numpy as np

import ddatai as dd

G = 9.81
ROCK = dd.Material(density=2500.0, young=5e9, poisson=0.25)


def incline_frame(theta_deg: float):
    th = np.radians(theta_deg)
    t = np.array([np.cos(th), np.sin(th)])
    n = np.array([-np.sin(th), np.cos(th)])
    return t, n


def incline_base(scene: dd.Scene, theta_deg: float, length: float = 12.0, depth: float = 1.0) -> int:
    t, n = incline_frame(theta_deg)
    base = [-depth * n, length * t - depth * n, length * t, np.zeros(2)]
    return scene.add_block(base, material=ROCK, fixed=True)


def block_on_incline(scene: dd.Scene, theta_deg: float, at: float, width: float, height: float,
                     lift: float = 0.0, material=ROCK) -> int:
    """A width × height block whose lower-left corner is at distance `at` along the slope."""
    t, n = incline_frame(theta_deg)
    p0 = at * t + lift * n
    return scene.add_block([p0, p0 + width * t, p0 + width * t + height * n, p0 + height * n],
                           material=material)


def sliding_scene(theta: float, phi: float, width: float = 1.0, height: float = 1.0):
    scene = dd.Scene(gravity=G)
    incline_base(scene, theta)
    block = block_on_incline(scene, theta, at=4.0, width=width, height=height)
    scene.set_joint(dd.Joint(friction=phi))
    return scene, block


def downslope_displacement(results, block: int, theta: float, frame: int = -1) -> float:
    t, _ = incline_frame(theta)
    return float(-(results.centroid[frame, block] - results.centroid[0, block]) @ t)


def random_jointed_scene(seed: int, n_joints=(3, 7)) -> dd.Scene:
    """A 10 m square cut by random persistent joints; the lowest block is fixed."""
    rng = np.random.default_rng(seed)
    scene = dd.Scene(gravity=G)
    joints = []
    for _ in range(rng.integers(*n_joints)):
        p = rng.uniform(0, 10, 2)
        ang = rng.uniform(0, np.pi)
        d = 20 * np.array([np.cos(ang), np.sin(ang)])
        joints.append(([p - d, p + d], dd.Joint(friction=float(rng.uniform(10, 40)))))
    ids = scene.cut([(0, 0), (10, 0), (10, 10), (0, 10)], joints, material=ROCK)
    scene.set_fixed(ids[0])
    return scene


def perturbed_vertices(model, seed: int, shift: float, angle: float = 0.002) -> np.ndarray:
    """Move every block rigidly by a random translation (σ = shift) and rotation (σ = angle):
    gives touching, slightly separated and slightly penetrating contacts of every kind."""
    rng = np.random.default_rng(seed)
    xy = model.vertex_xy0.copy()
    centroid = model.block_geometry(xy)["centroid"]
    for b in range(model.n_blocks):
        s = slice(model.vertex_offset[b], model.vertex_offset[b + 1])
        th = rng.normal(0, angle)
        rot = np.array([[np.cos(th), -np.sin(th)], [np.sin(th), np.cos(th)]])
        xy[s] = centroid[b] + (xy[s] - centroid[b]) @ rot.T + rng.normal(0, shift, 2)
    return xy
