"""The closed-form cases of the accuracy benchmark (``benchmarks/accuracy.py``): each builds a
fresh scene and measures a run's error against the exact answer. The list below is copied into
``accuracy.md`` from this docstring.

Cases (set-ups of tests/test_verification.py and docs/method/dda.md §7; rock: ρ = 2500 kg/m³,
E = 5 GPa, ν = 0.25; 1 m × 1 m blocks on a real inclined fixed base unless stated):

- sliding: θ = 30°, φ = 20°; relative error of the down-slope distance after 1 s,
  exact d = ½ g (sinθ − cosθ tanφ) t².
- resting: θ = 20°, φ = 30°; drift of the centroid after 1 s divided by the block size (1 m);
  the exact answer is no motion.
- free flight: 2 m × 1 m block, v0 = (3, 4) m/s, ω0 = 0.5 rad/s, 1.5 s; largest centroid error
  over the run divided by the largest exact displacement.
- pushed block: frictionless base, a point load F = F0·t (F0 = 10 kN/s per m) at the centroid;
  largest error of x(t) over 1 s divided by x(1 s), exact x = F0 t³/(6m). A ramp rather than a
  constant force, so that the time integration is exercised (a constant force is integrated
  exactly and only the elastic deformation would show).
- column: 5 blocks stacked on a fixed base, φ = 0, static analysis (``static=True`` is part of
  the case), 1.5 s (150 default steps); largest relative error of σy over the blocks, exact
  σy,k = −ρ g h (n − k − ½).
- toppling: b × h = 0.2 m × 1 m block on θ = 30°, φ = 40° (Goodman–Bray "topple", robust to
  ±3°); relative error of the rotation after 0.3 s against the rigid block pivoting about its
  down-slope corner, I_p ψ'' = −m g r_x(ψ), I_p = m (b² + h²)/3, r the pivot-to-centroid
  vector (initial angular acceleration ψ''(0) = 3 g (h sinθ − b cosθ) / (2 (b² + h²))),
  integrated with solve_ivp; the pivot's friction demand stays below tanφ throughout (checked).
  The regime (stable / slide / topple / slide + topple, §7d thresholds 2e-3 rad and 2e-3 m) is
  reported right/wrong in the table.
- newmark: θ = 20°, φ = 30° under a horizontal ground acceleration a_g = 0.4 g sin(2π·1 Hz·t)
  for 3 s (one-way down-slope sliding, yield acceleration g tan(φ − θ) = 0.176 g); relative
  error of the down-slope displacement relative to the ground against the stick–slip solution
  of ``benchmarks/stick_slip.py``.
- launched: a 1.5 m × 0.8 m block launched at 2 m/s down a 20° plane (φ = 30°); relative error
  of the stopping distance v²/(2g(cosθ tanφ − sinθ)) = 1.0168 m (run 1.6 s, past the stop).
- cohesive: a 1 m block on a 30° plane (φ = 20°) with the cohesion that gives FS = 0.8; it
  slides at once and its bond breaks (Shi's rule): relative error of d(0.5 s) against
  ½ g (sinθ − cosθ tanφ) t².
- bonded_column: ten bonded 1 m blocks (φ = 30°, c = T = 100 kPa) on a fixed base, dynamic,
  0.5 s; largest relative error of σy over every block and frame, exact −ρ g (k − ½) h.
- rocking: a 0.5 m × 2 m block (ρ = 2600 kg/m³, E = 10 GPa, friction 80°) released on a corner
  at half its overturning angle; largest relative error of its first five peaks against
  Housner's (each impact keeps the angular momentum about the new corner, r = 1 − 1.5 sin²α;
  tests/rocking_cases.py). Its error is the impacts' and the free swings' energy (docs/method/
  dda.md §4.6, §5.3), and does not fall monotonically with a fixed Δt.
"""

from __future__ import annotations

import math
import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np

import ddatai as dd
from benchmarks.stick_slip import stick_slip

ROOT = Path(__file__).resolve().parents[1]
G = 9.81
ROCK = dd.Material(density=2500.0, young=5e9, poisson=0.25)

Measure = Callable[["dd.Results"], tuple[float, str]]


# ----------------------------------------------------------------------------- scene builders
def incline_frame(theta_deg: float) -> tuple[np.ndarray, np.ndarray]:
    """Unit vectors along (rising to the right) and normal to a plane of angle θ."""
    th = math.radians(theta_deg)
    return np.array([math.cos(th), math.sin(th)]), np.array([-math.sin(th), math.cos(th)])


def add_incline_base(scene, theta_deg: float, length: float = 12.0, depth: float = 1.0) -> int:
    """A fixed base whose top face rises at θ from the origin; down-slope is −t."""
    t, n = incline_frame(theta_deg)
    return scene.add_block([-depth * n, length * t - depth * n, length * t, np.zeros(2)],
                           material=ROCK, fixed=True)


def add_block_on_incline(scene, theta_deg: float, at: float, width: float, height: float) -> int:
    """A width × height block whose lower down-slope corner (vertex 0) is `at` along the plane."""
    t, n = incline_frame(theta_deg)
    p0 = at * t
    return scene.add_block([p0, p0 + width * t, p0 + width * t + height * n, p0 + height * n],
                           material=ROCK)


def downslope_displacement(results, block: int, theta_deg: float, frame: int = -1) -> float:
    t, _ = incline_frame(theta_deg)
    return float(-(results.centroid[frame, block] - results.centroid[0, block]) @ t)


# ----------------------------------------------------------------------------- cases
@dataclass(frozen=True)
class Case:
    """A closed-form case: ``build()`` returns a fresh scene and the function that measures
    the error of a run of it against the exact answer."""

    key: str
    label: str
    metric: str
    duration: float
    build: Callable[[], tuple["dd.Scene", Measure]]
    base_params: dict = field(default_factory=dict)
    """Params fields that are part of the set-up (the static column), not swept."""
    record_every: int = 10 ** 9
    """1 where the error is taken over the whole history; else first and last frames only."""
    has_contacts: bool = True
    """False: the contact parameters (penalty, tolerances) do not enter; they are not swept."""


def sliding_case() -> Case:
    theta, phi, T = 30.0, 20.0, 1.0

    def build():
        scene = dd.Scene(gravity=G)
        add_incline_base(scene, theta)
        block = add_block_on_incline(scene, theta, at=4.0, width=1.0, height=1.0)
        scene.set_joint(dd.Joint(friction=phi))
        th, ph = math.radians(theta), math.radians(phi)
        exact = 0.5 * G * (math.sin(th) - math.cos(th) * math.tan(ph)) * T * T

        def measure(res):
            return abs(downslope_displacement(res, block, theta) - exact) / exact, ""
        return scene, measure

    return Case("sliding", "sliding (30° plane, friction 20°)", "relative error of d(1 s)", T, build)


def resting_case() -> Case:
    theta, phi, T, size = 20.0, 30.0, 1.0, 1.0

    def build():
        scene = dd.Scene(gravity=G)
        add_incline_base(scene, theta)
        block = add_block_on_incline(scene, theta, at=4.0, width=size, height=size)
        scene.set_joint(dd.Joint(friction=phi))

        def measure(res):
            drift = float(np.linalg.norm(res.centroid[-1, block] - res.centroid[0, block]))
            return drift / size, ""
        return scene, measure

    return Case("resting", "resting (20° plane, friction 30°)", "drift after 1 s / block size (1 m)", T, build)


def free_flight_case() -> Case:
    T, v0, w0 = 1.5, (3.0, 4.0), 0.5

    def build():
        scene = dd.Scene(gravity=G)
        block = scene.add_block([(0, 0), (2, 0), (2, 1), (0, 1)], material=ROCK, velocity=v0,
                                angular_velocity=w0)

        def measure(res):
            t = res.time
            move = np.stack([v0[0] * t, v0[1] * t - 0.5 * G * t * t], axis=1)
            err = np.abs(res.centroid[:, block] - res.centroid[0, block] - move).max()
            return float(err / np.abs(move).max()), ""
        return scene, measure

    return Case("free_flight", "free flight", "largest centroid error / largest displacement",
                T, build, record_every=1, has_contacts=False)


def pushed_block_case() -> Case:
    T, F0 = 1.0, 10000.0

    def build():
        scene = dd.Scene(gravity=G)
        scene.add_block([(-5, -1), (15, -1), (15, 0), (-5, 0)], material=ROCK, fixed=True)
        block = scene.add_block([(0, 0), (1, 0), (1, 1), (0, 1)], material=ROCK)
        scene.set_joint(dd.Joint(friction=0.0))
        scene.add_point_load(block, (0.5, 0.5), lambda t: (F0 * t, 0.0))
        mass = ROCK.density * 1.0

        def measure(res):
            exact = F0 * res.time ** 3 / (6 * mass)
            x = res.centroid[:, block, 0] - res.centroid[0, block, 0]
            return float(np.abs(x - exact).max() / (F0 * T ** 3 / (6 * mass))), ""
        return scene, measure

    return Case("pushed", "pushed block (F = F0·t)", "largest error of x(t) / x(1 s)", T, build,
                record_every=1)


def column_case() -> Case:
    n, h, T = 5, 1.0, 1.5

    def build():
        scene = dd.Scene(gravity=G)
        scene.add_block([(-1, -1), (2, -1), (2, 0), (-1, 0)], material=ROCK, fixed=True)
        ids = [scene.add_block([(0, k * h), (1, k * h), (1, (k + 1) * h), (0, (k + 1) * h)], material=ROCK)
               for k in range(n)]
        scene.set_joint(dd.Joint(friction=0.0))
        exact = np.array([-ROCK.density * G * h * (n - k - 0.5) for k in range(n)])

        def measure(res):
            return float(np.abs(res.stress[-1, ids, 1] / exact - 1).max()), ""
        return scene, measure

    return Case("column", "stacked column stress", "largest relative error of σy (static)", T, build,
                base_params={"static": True})


def pivoting_block_rotation(width: float, height: float, theta_deg: float, phi_deg: float,
                            t_end: float) -> tuple[float, float]:
    """Rotation ψ(t_end) [rad] of a rigid block pivoting about its down-slope corner, and the
    largest friction demand |T|/N at the pivot over [0, t_end] (must stay below tanφ).

    Pivot-to-centroid vector r(ψ) = R(ψ) r0, r0 = (b/2) t + (h/2) n; moment of gravity about
    the pivot −m g r_x, so I_p ψ'' = −m g r_x(ψ) with I_p = m (b² + h²)/3 (ψ counter-clockwise,
    which for a plane rising to the right is toppling down-slope). The pivot reaction per unit
    mass is a_c − g⃗ with a_c = ψ'' ẑ×r − ψ'² r.
    """
    from scipy.integrate import solve_ivp

    t, n = incline_frame(theta_deg)
    r0 = 0.5 * width * t + 0.5 * height * n
    ip = (width ** 2 + height ** 2) / 3.0  # per unit mass

    def r_of(psi):
        c, s = math.cos(psi), math.sin(psi)
        return np.array([c * r0[0] - s * r0[1], s * r0[0] + c * r0[1]])

    def rhs(_, y):
        return [y[1], -G * r_of(y[0])[0] / ip]

    sol = solve_ivp(rhs, (0.0, t_end), [0.0, 0.0], method="DOP853", rtol=1e-12, atol=1e-14,
                    dense_output=True)
    demand = 0.0
    for tau in np.linspace(0.0, t_end, 301):
        psi, omega = sol.sol(tau)
        r = r_of(psi)
        alpha = -G * r[0] / ip
        a_c = alpha * np.array([-r[1], r[0]]) - omega ** 2 * r
        reaction = a_c + np.array([0.0, G])
        normal, shear = reaction @ n, reaction @ t
        if normal <= 0:
            return float(sol.y[0, -1]), math.inf
        demand = max(demand, abs(shear) / normal)
    return float(sol.y[0, -1]), demand


def toppling_case() -> Case:
    theta, phi, b, h, T = 30.0, 40.0, 0.2, 1.0, 0.3

    def build():
        scene = dd.Scene(gravity=G)
        add_incline_base(scene, theta)
        block = add_block_on_incline(scene, theta, at=4.0, width=b, height=h)
        scene.set_joint(dd.Joint(friction=phi))
        exact, demand = pivoting_block_rotation(b, h, theta, phi, T)
        if not demand < math.tan(math.radians(phi)):
            raise AssertionError(f"toppling case: the pivot would slip (demand {demand:.3f})")
        t, _ = incline_frame(theta)

        def measure(res):
            corner0 = res.polygons(0)[block][0]
            slide = float(-(res.polygons(-1)[block][0] - corner0) @ t)
            rotation = float(res.rotation[-1, block])
            mode = {(False, False): "stable", (True, False): "slide", (False, True): "topple",
                    (True, True): "slide+topple"}[(slide > 2e-3, rotation > 2e-3)]
            return abs(rotation - exact) / exact, "" if mode == "topple" else f"WRONG: {mode}"
        return scene, measure

    return Case("toppling", "toppling (b/h = 0.2)", "relative error of the rotation at 0.3 s "
                "(regime right/wrong in notes)", T, build)


@dataclass(frozen=True)
class ShakingSetup:
    """The Newmark case: plane angle and friction [°], horizontal a_g = A sin(2πft)."""

    theta: float = 20.0
    phi: float = 30.0
    amplitude: float = 0.4 * G
    frequency: float = 1.0
    duration: float = 3.0


NEWMARK = ShakingSetup()


def newmark_ground_acceleration(t: float) -> tuple[float, float]:
    return (NEWMARK.amplitude * math.sin(2 * math.pi * NEWMARK.frequency * t), 0.0)


def newmark_reference() -> float:
    """s(T) of the stick–slip equation (event-driven solve_ivp, tight tolerances)."""
    c = NEWMARK
    return stick_slip(c.theta, c.phi, newmark_ground_acceleration, c.duration,
                      gravity=G, rtol=1e-12, atol=1e-14, max_step=0.005).final_displacement


def newmark_case() -> Case:
    c = NEWMARK
    theta = c.theta

    def build():
        scene = dd.Scene(gravity=G)
        add_incline_base(scene, theta)
        block = add_block_on_incline(scene, theta, at=6.0, width=1.0, height=1.0)
        scene.set_joint(dd.Joint(friction=c.phi))
        scene.set_ground_acceleration(newmark_ground_acceleration)
        exact = newmark_reference()

        def measure(res):
            return abs(downslope_displacement(res, block, theta) - exact) / exact, ""
        return scene, measure

    return Case("newmark", "Newmark block (0.4 g, 1 Hz)", "relative error of the displacement "
                "relative to the ground after 3 s", c.duration, build)


def launched_case() -> Case:
    """A block already moving: launched down a plane flatter than its friction angle."""
    theta, phi, v0, T = 20.0, 30.0, 2.0, 1.6
    th, mu = math.radians(theta), math.tan(math.radians(phi))
    decel = G * (math.cos(th) * mu - math.sin(th))
    exact = v0 * v0 / (2.0 * decel)

    def build():
        scene = dd.Scene(gravity=G)
        add_incline_base(scene, theta, length=14.0)
        t, n = incline_frame(theta)
        p0 = 6.0 * t
        block = scene.add_block([p0, p0 + 1.5 * t, p0 + 1.5 * t + 0.8 * n, p0 + 0.8 * n], material=ROCK,
                                velocity=tuple(-v0 * t))
        scene.set_joint(dd.Joint(friction=phi))

        def measure(res):
            return abs(downslope_displacement(res, block, theta) - exact) / exact, ""
        return scene, measure

    return Case("launched", "launched block (2 m/s down a 20° plane, friction 30°)",
                "relative error of the stopping distance", T, build)


def cohesive_case() -> Case:
    """A bonded block at FS = 0.8 under gravity from t = 0: it slides at once, with friction only
    once its bond has broken."""
    theta, phi, fs, T = 30.0, 20.0, 0.8, 0.5
    th, mu = math.radians(theta), math.tan(math.radians(phi))
    cohesion = ROCK.density * G * (fs * math.sin(th) - math.cos(th) * mu)
    exact = 0.5 * G * (math.sin(th) - math.cos(th) * mu) * T * T

    def build():
        scene = dd.Scene(gravity=G)
        add_incline_base(scene, theta)
        block = add_block_on_incline(scene, theta, at=4.0, width=1.0, height=1.0)
        scene.set_joint(dd.Joint(friction=phi, cohesion=cohesion))

        def measure(res):
            return abs(downslope_displacement(res, block, theta) - exact) / exact, ""
        return scene, measure

    return Case("cohesive", "cohesive block at FS 0.8 (30° plane)", "relative error of d(0.5 s)", T, build)


def bonded_column_case() -> Case:
    """Ten bonded blocks (φ = 30°) under gravity from t = 0, dynamic."""
    n, T = 10, 0.5

    def build():
        scene = dd.Scene(gravity=G)
        scene.add_block([(-1, -1), (2, -1), (2, 0), (-1, 0)], material=ROCK, fixed=True)
        ids = [scene.add_block([(0, k), (1, k), (1, k + 1), (0, k + 1)], material=ROCK) for k in range(n)]
        scene.set_joint(dd.Joint(friction=30.0, cohesion=1e5, tensile=1e5))
        exact = np.array([-ROCK.density * G * (n - k - 0.5) for k in range(n)])

        def measure(res):
            return float(np.abs(res.stress[:, ids, 1] / exact - 1).max()), ""
        return scene, measure

    return Case("bonded_column", "bonded column, 10 blocks, dynamic", "largest relative error of σy "
                "over the run", T, build, record_every=1)


def rocking_case() -> Case:
    """The 0.5 × 2 m block of tests/rocking_cases.py released at half its overturning angle,
    five impacts against Housner's peaks."""
    if str(ROOT / "tests") not in sys.path:
        sys.path.insert(0, str(ROOT / "tests"))
    from rocking_cases import housner_duration, housner_peaks, scene

    b, h, fraction, n = 0.5, 2.0, 0.5, 5

    def build():
        sc = scene(b, h, fraction)
        exact = housner_peaks(b, h, fraction, n)

        def measure(res):
            start = res.vertex_offset[1]
            d = res.vertices[:, start + 1] - res.vertices[:, start]
            tilt = np.arctan2(d[:, 1], d[:, 0])
            sign = np.sign(tilt)
            halves = np.split(np.abs(tilt), np.nonzero(sign[1:] * sign[:-1] < 0)[0] + 1)
            peaks = np.array([x.max() for x in halves[1:n + 1]])
            if len(peaks) < n:
                return 1.0, f"WRONG: {len(peaks)} impacts"
            return float(np.max(np.abs(peaks / exact - 1.0))), ""
        return sc, measure

    # today's step (`ddatai.step`): the fused engine, which "auto" takes for a small model once
    # its kernel is loaded in the process, has neither the resolved impacts nor the lever arms
    # at mid-step yet (38–90 % errors here)
    return Case("rocking", "rocking block (b/h = 0.25, 5 impacts)", "largest relative error of the "
                "first five peaks against Housner's", 1.05 * housner_duration(b, h, fraction, n), build,
                base_params={"kernels": "numpy"}, record_every=1)


def all_cases() -> list[Case]:
    return [sliding_case(), resting_case(), free_flight_case(), pushed_block_case(), column_case(),
            toppling_case(), newmark_case(), launched_case(), cohesive_case(), bonded_column_case(),
            rocking_case()]
