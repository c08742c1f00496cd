"""Random valid scenes for the property-based suite (tests/test_extreme.py) and the random
campaign (benchmarks/extreme.py): stacks of convex and non-convex blocks with random velocities
and spins, and domains cut by random joints, with and without gravity, point loads and ground
shaking, across rock-like and extreme parameters.

A case is a plain `CaseSpec` (every number that defines it), so that a failing case prints as
a literal that a regression test can hold. `build(spec)` turns it into a Scene.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ddatai.geometry import polygon_integrals, signed_area
#: parameter ranges per regime: (low, high); "log" ranges are sampled log-uniformly
REGIMES = {
    # the rock masses of slope and tunnel models
    "rock": dict(size=(0.01, 100.0), density=(1800.0, 3200.0), young=(0.3e9, 100e9),
                 poisson=(0.1, 0.35), friction=(10.0, 50.0), strength=(0.0, 1e6), speed=20.0,
                 spin=2.0),
    # soft, heavy, frictionless, very stiff: everything a valid scene may hold
    "extreme": dict(size=(0.01, 100.0), density=(800.0, 20000.0), young=(1e6, 300e9),
                    poisson=(0.0, 0.45), friction=(0.0, 60.0), strength=(0.0, 1e7), speed=20.0,
                    spin=5.0),
    # whole rock-like domains cut by random joints, the way sections are made (`random_domain`):
    # outline size across [m], joint strength (c, T) 0 or log-uniform in `strength`, a user Δt
    # in `user_dt` in 30 % of the scenes
    "cut": dict(size=(0.2, 2000.0), density=(1800.0, 3200.0), young=(0.3e9, 100e9),
                poisson=(0.1, 0.35), friction=(10.0, 50.0), strength=(100.0, 1e6),
                gravity=(0.0, 9.81, 30.0), traces=(2, 13), user_dt=(1e-6, 0.1)),
}
SHAPES = ("rect", "polygon", "ell")


@dataclass(frozen=True, kw_only=True)
class CaseSpec:
    """One random scene. Lengths in block sizes unless stated."""

    kind: str                    # "stack", "cut" or "domain"
    size: float                  # block size L [m]
    density: float               # [kg/m³]
    young: float                 # [Pa]
    poisson: float               # [-]
    friction: float              # [degrees]
    cohesion: float              # [Pa]
    tensile: float               # [Pa]
    gravity: float               # [m/s²]
    shapes: tuple = ()           # stack: one of SHAPES per block
    aspects: tuple = ()          # stack: width / height per block
    gaps: tuple = ()             # stack: gap below each block [L]
    shifts: tuple = ()           # stack: horizontal offset of each block [L]
    velocities: tuple = ()       # stack: (vx, vy) per block [m/s]
    spins: tuple = ()            # stack: angular velocity per block [rad/s]
    joints: tuple = ()           # cut, domain: (x0, y0, dip [degrees]) per joint, position in domain sizes
    outline: tuple = ()          # domain: the outline's vertices, in domain sizes (size = its width)
    dt: float = 0.0              # a user time step Params.dt [s]; 0: automatic
    load: float = 0.0            # point load on the first free block, in its weight at 9.81 m/s² [-]
    shaking: float = 0.0         # ground acceleration amplitude [m/s²] (horizontal, 2 Hz)
    steps: int = 30


def _polygon(shape: str, width: float, height: float) -> list:
    if shape == "rect":
        return [(0, 0), (width, 0), (width, height), (0, height)]
    if shape == "polygon":  # a convex hexagon-like block sitting on a flat edge
        return [(0, 0), (width, 0), (width * 1.15, 0.5 * height), (width, height), (0, height),
                (-0.15 * width, 0.5 * height)]
    # "ell": non-convex L-shaped block
    return [(0, 0), (width, 0), (width, 0.4 * height), (0.45 * width, 0.4 * height),
            (0.45 * width, height), (0, height)]


def build(spec: CaseSpec):
    """(Scene, steps) of a case."""
    import ddatai as dd

    L = spec.size
    rock = dd.Material(density=spec.density, young=spec.young, poisson=spec.poisson)
    joint = dd.Joint(friction=spec.friction, cohesion=spec.cohesion, tensile=spec.tensile)
    scene = dd.Scene(gravity=spec.gravity)
    free: list[int] = []
    if spec.kind == "stack":
        scene.add_block([(-3 * L, -L), (4 * L, -L), (4 * L, 0), (-3 * L, 0)], material=rock, fixed=True)
        y = 0.0
        for shape, aspect, gap, shift, v, w in zip(spec.shapes, spec.aspects, spec.gaps, spec.shifts,
                                                   spec.velocities, spec.spins):
            width = L * math.sqrt(aspect)
            height = L / math.sqrt(aspect)
            y += gap * L
            poly = [(shift * L + px, y + py) for px, py in _polygon(shape, width, height)]
            free.append(scene.add_block(poly, material=rock, velocity=tuple(v), angular_velocity=w))
            y += height
    elif spec.kind == "domain":
        outline = [(L * x, L * y) for x, y in spec.outline]
        h = max(y for _, y in spec.outline)
        lines = []
        for x0, y0, dip in spec.joints:
            c, s = math.cos(math.radians(dip)), math.sin(math.radians(dip))
            p = np.array([x0 * L, y0 * h * L])
            d = np.array([c, s]) * 3.0 * L * (1.0 + h)
            lines.append((np.array([p - d, p + d]), joint))
        import warnings

        with warnings.catch_warnings():
            # slivers are kept, as a user who ignores the warning keeps them
            warnings.simplefilter("ignore")
            free = scene.cut(outline, lines, material=rock)
        scene.set_fixed(free[0])  # the lowest block (`Scene.cut` orders them bottom to top)
        free = free[1:]
    else:
        width, height = 4.0 * L, 3.0 * L
        scene.add_block([(-L, -L), (width + L, -L), (width + L, 0), (-L, 0)], material=rock, fixed=True)
        lines = []
        for x0, y0, dip in spec.joints:
            c, s = math.cos(math.radians(dip)), math.sin(math.radians(dip))
            p = np.array([x0 * width, y0 * height])
            d = np.array([c, s]) * 3.0 * (width + height)
            lines.append((np.array([p - d, p + d]), joint))
        free = scene.cut([(0, 0), (width, 0), (width, height), (0, height)], lines, material=rock)
    scene.set_joint(joint)
    if spec.load and free:
        b = free[0]
        import shapely

        c = shapely.Polygon(scene.polygon(b)).representative_point().coords[0]
        weight = spec.density * 9.81 * abs(signed_area(scene.polygon(b)))
        scene.add_point_load(b, tuple(c), (0.6 * spec.load * weight, -0.8 * spec.load * weight))
    if spec.shaking:
        amp = spec.shaking
        scene.set_ground_acceleration(lambda t: (amp * math.sin(2 * math.pi * 2.0 * t), 0.0))
    return scene, spec.steps


def random_spec(rng: np.random.Generator, regime: str, steps: int = 30) -> CaseSpec:
    """A case drawn with NumPy (the campaign); tests/test_extreme.py draws the same ranges with
    hypothesis."""
    r = REGIMES[regime]

    def log(lo_hi):
        lo, hi = lo_hi
        return float(math.exp(rng.uniform(math.log(lo), math.log(hi))))

    strength = r["strength"][1]
    base = dict(size=log(r["size"]), density=float(rng.uniform(*r["density"])), young=log(r["young"]),
                poisson=float(rng.uniform(*r["poisson"])), friction=float(rng.uniform(*r["friction"])),
                cohesion=float(rng.choice([0.0, rng.uniform(0, strength)])),
                tensile=float(rng.choice([0.0, rng.uniform(0, strength)])),
                gravity=float(rng.choice([0.0, 9.81])),
                load=float(rng.choice([0.0, 0.0, rng.uniform(0, 10)])),
                shaking=float(rng.choice([0.0, 0.0, rng.uniform(0, 5)])), steps=steps)
    if rng.random() < 0.6:
        n = int(rng.integers(1, 5))
        return CaseSpec(kind="stack", shapes=tuple(str(rng.choice(SHAPES)) for _ in range(n)),
                        aspects=tuple(float(math.exp(rng.uniform(-1.2, 1.2))) for _ in range(n)),
                        gaps=tuple(float(rng.choice([0.0, rng.uniform(0, 0.5)])) for _ in range(n)),
                        shifts=tuple(float(rng.uniform(-0.5, 0.5)) for _ in range(n)),
                        velocities=tuple((float(rng.normal(0, r["speed"])), float(rng.normal(0, r["speed"])))
                                         for _ in range(n)),
                        spins=tuple(float(rng.normal(0, r["spin"])) for _ in range(n)), **base)
    n = int(rng.integers(1, 4))
    return CaseSpec(kind="cut", joints=tuple((float(rng.uniform(0.2, 0.8)), float(rng.uniform(0.2, 0.8)),
                                              float(rng.uniform(0, 180))) for _ in range(n)), **base)


def random_domain(rng: np.random.Generator, steps: int = 400) -> CaseSpec:
    """A rock-like domain cut by random joints (the "cut" regime): a five-sided outline (a
    slope section: base, back, crest, face, toe) 0.2 m to 2 km across, cut by 2–13 straight
    traces of random position and dip, its lowest block fixed; gravity 0, 9.81 or 30 m/s²;
    joints with φ 10–50° and c, T each either 0 or 100 Pa–1 MPa; the default `Params`, or in
    30 % of the scenes a user Δt of 1 µs–0.1 s."""
    r = REGIMES["cut"]

    def log(lo_hi):
        lo, hi = lo_hi
        return float(math.exp(rng.uniform(math.log(lo), math.log(hi))))

    height = float(rng.uniform(0.4, 1.0))
    crest = float(rng.uniform(0.2, 0.8))     # where the crest ends and the face begins
    toe = float(rng.uniform(0.1, 0.6)) * height   # height of the toe on the front
    outline = ((0.0, 0.0), (1.0, 0.0), (1.0, height), (crest, height), (0.0, toe))
    n = int(rng.integers(r["traces"][0], r["traces"][1] + 1))
    joints = tuple((float(rng.uniform(0.05, 0.95)), float(rng.uniform(0.05, 0.95)),
                    float(rng.uniform(0.0, 180.0))) for _ in range(n))
    return CaseSpec(kind="domain", outline=outline, joints=joints, size=log(r["size"]),
                    density=float(rng.uniform(*r["density"])), young=log(r["young"]),
                    poisson=float(rng.uniform(*r["poisson"])), friction=float(rng.uniform(*r["friction"])),
                    cohesion=0.0 if rng.random() < 0.5 else log(r["strength"]),
                    tensile=0.0 if rng.random() < 0.5 else log(r["strength"]),
                    gravity=float(rng.choice(r["gravity"])),
                    dt=log(r["user_dt"]) if rng.random() < 0.3 else 0.0, steps=steps)


@dataclass
class Outcome:
    """What a case did: ``status`` is "ok", "refused" (ValueError before any work), "diverged"
    (SimulationError), "crash" (any other exception); ``problems`` lists the properties a
    finished run broke."""

    status: str
    message: str = ""
    problems: tuple = ()
    steps: int = 0


def run_case(spec: CaseSpec, params: "dict | None" = None) -> Outcome:
    """Run a case with the default parameters (or these ``Params`` fields) and check the properties of the run:
    every recorded value finite; no accepted step with a penetration above the limit; no
    energy created (the balance's rest, friction + integrator work, is ≥ 0 within the energy
    that penalty springs can hold at the recorded penetrations); Coulomb's law at every closed
    contact within the open-close tolerances."""
    import ddatai as dd

    import warnings

    try:
        scene, steps = build(spec)
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            model = dd.build_model(scene, dd.Params(**params) if params else None)
    except ValueError as err:
        return Outcome("refused", str(err))
    # a model warned for block strains beyond what a first-order block carries accurately
    # (docs/method/limits.md) is held to everything but the energy balance
    strained = any("elastic strain" in str(w.message) for w in caught)
    try:
        res = dd.simulate(scene, dd.Params(dt=spec.dt) if spec.dt else None, steps=steps)
    except dd.SimulationError as err:
        return Outcome("diverged", str(err), steps=0 if err.results is None else len(err.results.steps))
    except ValueError as err:  # refused before any step
        return Outcome("refused", str(err))
    except Exception as err:  # noqa: BLE001 - the campaign tallies crashes
        return Outcome("crash", f"{type(err).__name__}: {err}")
    return Outcome("ok", problems=tuple(check(res, model, energy=not strained)), steps=len(res.steps))


def check(res, model, energy: bool = True) -> list[str]:
    """The properties of a finished run (`run_case`); returns what it broke. ``energy=False``
    leaves out the energy balance."""
    out = []
    s = res.steps
    arrays = {"vertices": res.vertices, "centroid": res.centroid, "velocity": res.velocity,
              "angular_velocity": res.angular_velocity, "stress": res.stress}
    for name, a in arrays.items():
        if not np.all(np.isfinite(a)):
            out.append(f"{name} not finite")
    for name in s.dtype.names:
        if not np.all(np.isfinite(s[name])):
            out.append(f"step record {name} not finite")
    over = s["max_penetration"] > model.penetration_limit
    if over.any():
        out.append(f"penetration {s['max_penetration'].max():.3g} m above the limit "
                   f"{model.penetration_limit:.3g} m at step {int(np.argmax(over)) + 1}")
    # energy: at the end of every step, kinetic + potential + strain + contact energy ≤ the
    # start + the external work. The balance's rest (friction + integrator work) summed from the
    # start is what the run did not turn into energy; below zero the run created energy.
    # Allowance: the energy of every closed contact's penalty spring at the step's deepest
    # penetration (an open-close change within a step can release at most that), summed, plus
    # the open-close tolerances: a spring's energy at the opening tolerance per contact, and
    # oc_force_tolerance of the energies and of the external work (a contact's forces
    # obey the law to that fraction, so the work they do does too)
    p = model.penalty
    rest = np.cumsum(s["friction_work"] + s["integrator_work"])
    scale = np.abs(s["kinetic"]) + np.abs(s["gravitational"]) + np.abs(s["strain"]) + np.abs(s["contact"])
    allowance = np.cumsum(s["closed"] * 0.5 * p * s["max_penetration"] ** 2 + (s["closed"] + 1) * p * model.open_tol ** 2) \
        + model.params.oc_force_tolerance * (np.maximum.accumulate(scale) + np.cumsum(np.abs(s["external_work"])))
    # DDA keeps density, not mass: a block whose area changes with its volumetric strain
    # gains or loses ρ·ΔS of mass, whose weight and motion the energies count (a block
    # released from its settled, compressed state rises by ρ·ΔS·g·y, y its height above
    # the model's centre). That term is the method's, allowed for block by block
    allowance = allowance + np.maximum.accumulate(_mass_change_energy(res, model))[1:]
    # a spinning block: DDA's first-order displacement field turns a block by its rotation r0
    # linearly, the exact-rotation update corrects the vertices, and the second-order rest
    # (ωΔt)²/2 lands in the strain and the velocities: up to ½Iω²·(ωΔt)² per step (the
    # "rotation" limit of docs/guide/verification.md). Allowed, summed over the steps
    allowance = allowance + np.cumsum(_rotation_error(res, model))
    # the law's round-off force p·open_tolerance·w0 (`Model.force_roundoff`): a contact whose
    # forces lie below it is judged within round-off (a sliding one may slip against its
    # friction), so each closed contact's forces may do that force times the step's largest
    # displacement of work that the law would not. It matters only where every contact force
    # is below it (a weightless model shaken at 1e-5 g: forces ~1e-3 N against 0.06 N)
    allowance = allowance + np.cumsum(s["closed"] * model.force_roundoff * s["max_displacement"])
    created = -rest - allowance
    if energy and np.any(created > 0):
        k = int(np.argmax(created))
        out.append(f"energy created by step {k + 1}: {-rest[k]:.3g} J/m, allowance {allowance[k]:.3g} J/m")
    # Coulomb: |shear| − S ≤ oc_force_tolerance × the load carried (at most the largest contact
    # force p·pen or the heaviest block's weight) or × S (the strict test), + round-off;
    # S ≤ p·pen·tanφ + c·L
    params = model.params
    strength = p * s["max_penetration"] * float(np.max(model.joint_tan_phi, initial=0.0)) + \
        float(np.max(model.joint_cohesion, initial=0.0)) * 2.0 * model.w0
    if params.oc_force_reference == "load":
        weight = model.block_density * model.block_geometry(model.vertex_xy0)["area"] * float(np.hypot(*model.gravity))
        strength = np.maximum(p * s["max_penetration"], float(np.max(weight, initial=0.0)))
    bound = params.oc_force_tolerance * strength + 10.0 * model.force_roundoff
    if np.any(s["coulomb"] > bound):
        k = int(np.argmax(s["coulomb"] - bound))
        out.append(f"Coulomb exceeded by {s['coulomb'][k]:.3g} N/m at step {k + 1}")
    return out


def _mass_change_energy(res, model) -> np.ndarray:
    """(frames,) energy of the mass that DDA's constant-density blocks gained or lost since
    frame 0: Σ ρ·|S − S0|·(|g·(y − y_model centre)| + ½v²) + 2|S − S0|/S0·½Iω² over the free
    blocks [J/m]."""
    area = np.array([polygon_integrals(frame, res.vertex_offset)["area"] for frame in res.vertices])
    free = ~res.block_fixed
    g = float(np.hypot(*model.gravity))
    height = np.abs(res.centroid[..., 1] - model.origin[1])
    speed2 = res.velocity[..., 0] ** 2 + res.velocity[..., 1] ** 2
    per_block = model.block_density * np.abs(area - area[0]) * (g * height + 0.5 * speed2)
    # the spin: I grows as S² under a uniform strain, so ½Iω² by 2|ΔS|/S of itself
    spin = 0.5 * _polar_moment(res, model) * res.angular_velocity ** 2
    per_block = per_block + 2.0 * np.abs(area - area[0]) / np.abs(area[0]) * spin
    return np.sum(per_block[:, free], axis=1)


def _polar_moment(res, model) -> np.ndarray:
    """(B,) ρ·∫r² dA about each block's centroid, frame 0 [kg·m]."""
    moments = polygon_integrals(res.vertices[0], res.vertex_offset)
    return model.block_density * (moments["s1"] + moments["s2"])


def _rotation_error(res, model) -> np.ndarray:
    """(steps,) ½Iω²·(ωΔt)² of the free blocks at the start of each step [J/m]."""
    inertia = _polar_moment(res, model)
    omega = res.angular_velocity[:-1]  # frames are recorded every step: frame k starts step k + 1
    dt = res.steps["dt"][:, None]
    per_block = 0.5 * inertia * omega ** 2 * (omega * dt) ** 2
    return np.sum(per_block[:, ~res.block_fixed], axis=1)
