"""Scene builders for the verification tests (closed-form set-ups of docs/method/dda.md §7).

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


def launched_block(theta: float, phi: float, speed: float, width: float = 1.5, height: float = 0.8,
                   cohesion: float = 0.0, at: float = 6.0, length: float = 14.0):
    """A width × height block on a θ incline (real geometry) launched along it at ``speed``
    [m/s], positive down-slope. Returns (scene, block)."""
    scene = dd.Scene(gravity=G)
    incline_base(scene, theta, length=length)
    t, n = incline_frame(theta)
    p0 = at * t
    block = scene.add_block([p0, p0 + width * t, p0 + width * t + height * n, p0 + height * n],
                            material=ROCK, velocity=tuple(-speed * t))
    scene.set_joint(dd.Joint(friction=phi, cohesion=cohesion))
    return scene, block


# ----------------------------------------------------------------------------- bi-planar pair
#: an upper block A on a 50° plane pushes a lower block B along a flat base through a vertical
#: interface that meets the steep plane 1.2 m above the kink (B's foot covers the kink)
BIPLANAR = dict(dip=50.0, foot=1.2, upper_length=3.0, upper_top=4.5, lower_toe=1.5, lower_top=2.4)


def biplanar_polygons(dip, foot, upper_length, upper_top, lower_toe, lower_top):
    th = np.radians(dip)
    up = np.array([-np.cos(th), np.sin(th)])       # up the steep plane from the kink (0, 0)
    x_i = -foot / np.tan(th)
    i = np.array([x_i, foot])                      # foot of the interface on the steep plane
    u = i + upper_length * up
    upper = [i, (x_i, upper_top), (u[0], upper_top), u]
    lower = [i, (0.0, 0.0), (lower_toe, 0.0), (lower_toe, lower_top), (x_i, lower_top)]
    far = 8.0 * up
    base = [(far[0], -2.0), (lower_toe + 6.0, -2.0), (lower_toe + 6.0, 0.0), (0.0, 0.0), far]
    return upper, lower, base


def biplanar_scene(phi: float, **geometry):
    upper, lower, base = biplanar_polygons(**{**BIPLANAR, **geometry})
    scene = dd.Scene(gravity=G)
    a = scene.add_block(upper, material=ROCK)
    b = scene.add_block(lower, material=ROCK)
    scene.add_block(base, material=ROCK, fixed=True)
    scene.set_joint(dd.Joint(friction=phi))
    return scene, (a, b)


def biplanar_critical_friction(**geometry) -> float:
    """Limit equilibrium of the pair with friction φ on all three surfaces [degrees].

    B on the flat base, pushed by A with E (horizontal) and dragged down by the interface
    friction μE: E = μ·N_B, N_B = W_B + μE ⇒ E = μ W_B/(1 − μ²). A on the steep plane (dip α),
    sliding down it, held by its normal force N_A with friction μN_A up the plane and by B
    with E and μE (up): N_A (sin α − μ cos α) = E, N_A (cos α + μ sin α) + μE = W_A. The
    critical μ is the root of E·[(cos α + μ sin α)/(sin α − μ cos α) + μ] = W_A."""
    from scipy.optimize import brentq
    from ddatai.geometry import polygon_integrals
    g = {**BIPLANAR, **geometry}
    upper, lower, _ = biplanar_polygons(**g)
    area = [float(polygon_integrals(np.asarray(p, float), np.array([0, len(p)]))["area"][0]) for p in (upper, lower)]
    w_a, w_b = area  # weights per unit ρg
    a = np.radians(g["dip"])

    def f(mu):
        e = w_b * mu / (1 - mu * mu)
        return e * ((np.cos(a) + mu * np.sin(a)) / (np.sin(a) - mu * np.cos(a)) + mu) - w_a

    return float(np.degrees(np.arctan(brentq(f, 1e-9, min(np.tan(a), 1.0) - 1e-9))))


def law_slack(model, stepper, contacts) -> np.ndarray:
    """(m,) how far an accepted step's contact forces may miss Coulomb's law: the open-close
    force tolerance × the load of the contact's free blocks (their weight or largest contact
    force; `ddatai.contact_law.violations_numpy`), or × the contact's strength under the strict
    test, plus the round-off force p·open_tolerance·w0."""
    p = model.params
    strength = contacts.normal_force * contacts.tan_phi + contacts.cohesion * contacts.length * contacts.bond
    if p.oc_force_reference == "strength":
        return p.oc_force_tolerance * strength + model.force_roundoff
    level = stepper.block_load.copy()
    np.maximum.at(level, contacts.block_a, np.abs(contacts.normal_force))
    np.maximum.at(level, contacts.block_b, np.abs(contacts.normal_force))
    level[model.block_fixed] = 0.0
    carried = np.maximum(level[contacts.block_a], level[contacts.block_b])
    return p.oc_force_tolerance * carried + model.force_roundoff
