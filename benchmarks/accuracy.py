"""Error against run time on the closed-form cases.

    python benchmarks/accuracy.py [--quick] [--cases sliding,newmark,...] [--repeat N] [--out DIR]

For every case with an exact answer, runs DDA with the default parameters and with one
parameter changed at a time (fixed time step; automatic time step with a different ``dt_max``;
penalty ratio p/E; the open-close state tolerance and the round-off (opening) tolerance;
gravity switched on at t = 0 instead of the equilibrium start), and records the error against the exact
answer and the wall time of ``dd.simulate`` (scene building excluded, kernels compiled by a
warm-up run first, each configuration run once per pass; with ``--repeat N``, N passes and the
shortest time kept). Prints a Markdown table and writes ``DIR/accuracy.md`` (tables, machine,
date), ``DIR/accuracy.csv`` (every run) and ``DIR/accuracy.png`` (log–log chart of error
against wall time, one curve per case: the lowest error reached within a given time, with the
defaults marked). Default DIR: benchmarks/results.

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

import argparse
import csv
import datetime
import math
import os
import platform
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Optional

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))  # run as a script: make `benchmarks` importable

import ddatai as dd  # noqa: E402
from benchmarks.loglog_chart import NO_CHART, PALETTE, Panel, Series, draw_loglog_chart, have_matplotlib  # noqa: E402
from benchmarks.stick_slip import sinusoid_stick_slip, stick_slip  # noqa: E402

G = 9.81
ROCK = dd.Material(density=2500.0, young=5e9, poisson=0.25)
ERROR_FLOOR = 1e-16  # errors at round-off are drawn on this floor of the chart

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


# ----------------------------------------------------------------------------- sweeps
@dataclass(frozen=True)
class Config:
    """One parameter setting: the defaults, or the defaults with one field changed."""

    group: str
    label: str
    overrides: dict


DEFAULT_LABEL = "defaults"
CONTACT_GROUPS = ("penalty", "state", "open", "convergence")
WRONG_ANSWER_ERROR = 0.5
"""An error this large is a wrong answer (the block did not move, did not topple): such runs
are listed and drawn but kept off the best curve."""


def sweep_configs(quick: bool) -> list[Config]:
    if quick:
        return [Config("defaults", DEFAULT_LABEL, {}), Config("dt", "dt = 0.02 s", {"dt": 0.02})]
    configs = [Config("defaults", DEFAULT_LABEL, {})]
    configs += [Config("dt", f"dt = {v:g} s", {"dt": v}) for v in (0.02, 0.01, 0.005, 0.002, 0.001, 0.0005)]
    configs += [Config("dt_max", f"auto, dt_max = {v:g} s", {"dt_max": v})
                for v in (0.05, 0.02, 0.005, 0.002, 0.001)]
    configs += [Config("penalty", f"p = {v:g} E", {"penalty_ratio": v})
                for v in (5.0, 10.0, 20.0, 100.0, 500.0, 1000.0)]
    configs += [Config("state", f"state tol {v:g}", {"oc_state_tolerance": v})
                for v in (1e-5, 1e-4, 1e-2)]
    configs += [Config("start", "sudden gravity", {"initial_equilibrium": False})]
    # the strict open-close test of earlier versions (Coulomb within 1e-6 of each contact's
    # strength) against the default (1e-3 of the load carried; docs/method/dda.md §4.3)
    configs += [Config("convergence", "strict convergence", {"oc_force_reference": "strength",
                                                             "oc_force_tolerance": 1e-6})]
    configs += [Config("open", f"open tol {v:g} w0", {"open_tolerance": v})
                for v in (1e-14, 1e-12, 1e-11, 1e-10)]  # larger values are rejected: they act
    #                                           as tension and shear allowances (docs/guide/accuracy.md)
    return configs


@dataclass
class Run:
    case: str
    config: Config
    error: float
    wall: float
    cpu: float
    steps: int
    oc_mean: float
    dt_cuts: int
    note: str


def applies(case: Case, config: Config) -> bool:
    return case.has_contacts or config.group not in CONTACT_GROUPS


def case_params(case: Case, config: Config) -> Optional["dd.Params"]:
    """None (the library's defaults, as a user would call it) unless the case or the config
    sets a field."""
    fields = {**case.base_params, **config.overrides}
    return dd.Params(**fields) if fields else None


def run_case(case: Case, config: Config) -> Run:
    """Build the scene (untimed), time `dd.simulate` only, measure the error."""
    scene, measure = case.build()
    params = case_params(case, config)
    wall0, cpu0 = time.perf_counter(), time.process_time()
    try:
        res = dd.simulate(scene, params=params, duration=case.duration, record_every=case.record_every)
        failure = None
    except dd.SimulationError as err:
        res, failure = err.results, f"diverged ({err.cause}) at t = {err.time:.3g} s"
    wall, cpu = time.perf_counter() - wall0, time.process_time() - cpu0
    steps = res.steps if res is not None else None
    n = len(steps) if steps is not None else 0
    oc = float(steps["oc_iterations"].mean()) if n else math.nan
    cuts = int(steps["dt_cuts"].sum()) if n else 0
    if failure:
        return Run(case.key, config, math.nan, wall, cpu, n, oc, cuts, failure)
    error, note = measure(res)
    return Run(case.key, config, float(error), wall, cpu, n, oc, cuts, note)


def warm_up(cases: list[Case]) -> None:
    """Compile every Taichi kernel the cases use (contacts, loads, ground motion) untimed."""
    for case in cases:
        scene, _ = case.build()
        dd.simulate(scene, params=case_params(case, Config("defaults", DEFAULT_LABEL, {})),
                    steps=3, record_every=10 ** 9)


# ----------------------------------------------------------------------------- analysis
def pareto_front(runs: list[Run]) -> list[Run]:
    """The runs no other run beats in both wall time and error, fastest first."""
    front, best = [], math.inf
    for r in sorted((r for r in runs if r.error < WRONG_ANSWER_ERROR), key=lambda r: (r.wall, r.error)):
        if r.error < best:
            front.append(r)
            best = r.error
    return front


def best_error_staircase(runs: list[Run]) -> list[tuple[float, float]]:
    """The lowest error reached within a given wall time, as (wall, error) corners of a step
    function from the fastest run to the slowest: the case's best curve on the chart."""
    front = pareto_front(runs)
    if not front:
        return []
    slowest = max(r.wall for r in runs)
    corners = [(front[0].wall, front[0].error)]
    for r in front[1:]:
        corners += [(r.wall, corners[-1][1]), (r.wall, r.error)]
    corners.append((max(slowest, corners[-1][0]), corners[-1][1]))
    return corners


@dataclass
class CaseSummary:
    case: Case
    default: Run
    best: Run
    dominating: list[Run]
    """Runs at least as accurate as the defaults (within 1 %), more than 20 % faster and with
    fewer steps (settings that take the same steps do the same work: their differences in
    wall time are the machine's noise)."""
    tenfold: Optional[Run]
    """The cheapest run with at most a tenth of the defaults' error."""


def summarise(case: Case, runs: list[Run]) -> CaseSummary:
    default = next(r for r in runs if r.config.label == DEFAULT_LABEL)
    ok = [r for r in runs if math.isfinite(r.error)]
    best = min(ok, key=lambda r: (max(r.error, ERROR_FLOOR), r.wall))
    dominating = sorted((r for r in ok if r is not default and r.wall < 0.8 * default.wall
                         and r.steps < default.steps and r.error <= 1.01 * default.error),
                        key=lambda r: (r.error, r.wall))
    better = [r for r in ok if r.error <= 0.1 * default.error]
    tenfold = min(better, key=lambda r: r.wall) if better else None
    return CaseSummary(case, default, best, dominating, tenfold)


# ----------------------------------------------------------------------------- output
def machine_description() -> str:
    cpu = platform.processor() or platform.machine()
    try:
        with open("/proc/cpuinfo") as fh:
            names = [line.split(":", 1)[1].strip() for line in fh if line.startswith("model name")]
        if names:
            cpu = names[0]
    except OSError:
        pass
    usable = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    import scipy
    import taichi

    return (f"{platform.platform()}, {cpu}, {os.cpu_count()} logical cores ({usable} usable), "
            f"Python {platform.python_version()}, NumPy {np.__version__}, SciPy {scipy.__version__}, "
            f"Taichi {'.'.join(map(str, taichi.__version__))} (CPU backend)")


def git_revision() -> str:
    try:
        out = subprocess.run(["git", "-C", str(ROOT), "rev-parse", "--short", "HEAD"],
                             capture_output=True, text=True, timeout=10)
        dirty = subprocess.run(["git", "-C", str(ROOT), "status", "--porcelain", "--", "ddatai",
                                "benchmarks/accuracy.py", "benchmarks/stick_slip.py"],
                               capture_output=True, text=True, timeout=10).stdout.strip()
        return out.stdout.strip() + (" + uncommitted changes" if dirty else "")
    except (OSError, subprocess.SubprocessError):
        return "unknown"


def format_error(r: Run) -> str:
    if not math.isfinite(r.error):
        return "diverged"
    return f"{r.error:.1e}" if r.error > 0 else "0"


def results_table(cases: list[Case], configs: list[Config], runs: dict) -> str:
    head = "| parameters | " + " | ".join(c.label for c in cases) + " |"
    rule = "|---|" + "---|" * len(cases)
    lines = [head, rule]
    for cfg in configs:
        cells = []
        for c in cases:
            r = runs.get((c.key, cfg.label))
            if r is None:
                cells.append("n/a (no contacts)")
                continue
            cell = f"{format_error(r)} · {r.wall:.2f} s"
            if r.note and math.isfinite(r.error):
                cell += f" ({r.note})"
            cells.append(cell)
        label = f"**{cfg.label}**" if cfg.label == DEFAULT_LABEL else cfg.label
        lines.append(f"| {label} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def summary_table(summaries: list[CaseSummary]) -> str:
    lines = ["| case | error measure | defaults: error · wall | best in sweep | as accurate as the "
             "defaults, > 20 % faster, fewer steps | cheapest 10× more accurate (wall factor) |",
             "|---|---|---|---|---|---|"]
    for s in summaries:
        d = s.default
        dom = ", ".join(f"{r.config.label} ({format_error(r)} · {r.wall:.2f} s)" for r in s.dominating[:3])
        if len(s.dominating) > 3:
            dom += f", … ({len(s.dominating)} in all)"
        if s.tenfold is None:
            ten = "not reached in the sweep"
        else:
            ten = (f"{s.tenfold.config.label}: {format_error(s.tenfold)} · {s.tenfold.wall:.2f} s "
                   f"(×{s.tenfold.wall / d.wall:.2g})")
        lines.append(f"| {s.case.label} | {s.case.metric} | {format_error(d)} · {d.wall:.2f} s | "
                     f"{s.best.config.label}: {format_error(s.best)} · {s.best.wall:.2f} s | "
                     f"{dom or 'none'} | {ten} |")
    return "\n".join(lines)


def detail_table(cases: list[Case], configs: list[Config], runs: dict) -> str:
    lines = ["| case | parameters | error | wall [s] | CPU [s] | steps | open–close it./step | Δt cuts | note |",
             "|---|---|---|---|---|---|---|---|---|"]
    for c in cases:
        for cfg in configs:
            r = runs.get((c.key, cfg.label))
            if r is None:
                continue
            lines.append(f"| {c.key} | {cfg.label} | {format_error(r)} | {r.wall:.3f} | {r.cpu:.3f} | "
                         f"{r.steps} | {r.oc_mean:.2f} | {r.dt_cuts} | {r.note} |")
    return "\n".join(lines)


def write_runs_csv(path: Path, cases: list[Case], configs: list[Config], runs: dict) -> None:
    """Every run, machine-readable (errors and timings at full precision)."""
    with open(path, "w", newline="") as fh:
        out = csv.writer(fh)
        out.writerow(["case", "group", "parameters", "error", "wall_s", "cpu_s", "steps",
                      "oc_iterations_per_step", "dt_cuts", "note"])
        for c in cases:
            for cfg in configs:
                r = runs.get((c.key, cfg.label))
                if r is not None:
                    out.writerow([c.key, cfg.group, cfg.label, repr(r.error), f"{r.wall:.6f}",
                                  f"{r.cpu:.6f}", r.steps, f"{r.oc_mean:.4f}", r.dt_cuts, r.note])


def newmark_convergence() -> str:
    """The stick–slip reference at several solver tolerances and against the per-phase closed
    form (benchmarks/stick_slip.py): shows that the reference is converged."""
    c = NEWMARK
    closed = sinusoid_stick_slip(c.theta, c.phi, c.amplitude, c.frequency, c.duration, gravity=G)
    rows = ["| solver | s(3 s) [m] | difference from closed form [m] |", "|---|---|---|"]
    for rtol, max_step in ((1e-6, 0.05), (1e-9, 0.01), (1e-12, 0.005)):
        s = stick_slip(c.theta, c.phi, newmark_ground_acceleration, c.duration, gravity=G,
                       rtol=rtol, atol=rtol * 1e-2, max_step=max_step).final_displacement
        rows.append(f"| DOP853 + events, rtol {rtol:g}, max step {max_step:g} s | {s:.15f} | {s - closed:.1e} |")
    rows.append(f"| closed form per phase + brentq | {closed:.15f} | 0 |")
    return "\n".join(rows)


def redraw_chart(csv_path: Path, png_path: Path) -> None:
    """Draw the chart again from an earlier sweep's ``accuracy.csv`` (no simulation)."""
    from types import SimpleNamespace

    known = {c.key: c for c in all_cases()}
    with open(csv_path, newline="") as fh:
        rows = list(csv.DictReader(fh))
    keys = list(dict.fromkeys(r["case"] for r in rows))
    cases, runs, summaries = [], {}, []
    for key in keys:
        mine = [r for r in rows if r["case"] == key]
        as_runs = [SimpleNamespace(case=key, error=float(r["error"]), wall=float(r["wall_s"])) for r in mine]
        for r, run in zip(mine, as_runs):
            runs[(key, r["parameters"])] = run
        default = next((run for r, run in zip(mine, as_runs) if r["parameters"] == DEFAULT_LABEL), as_runs[0])
        cases.append(known[key])
        summaries.append(SimpleNamespace(default=default))
    draw_chart(png_path, cases, runs, summaries)


#: the chart's panels: cases grouped by what sets their error (docs/guide/accuracy.md), at most
#: four curves a panel
CHART_PANELS = (("time integration sets the error", ("pushed", "toppling", "newmark")),
                ("the contact law's round-off force sets it", ("sliding", "cohesive", "launched")),
                ("round-off and elastic deformation set it", ("resting", "free_flight", "column", "bonded_column")))


def draw_chart(path: Path, cases: list[Case], runs: dict, summaries: list[CaseSummary]) -> None:
    """Error against wall time (matplotlib, the [plot] extra): one panel per group of
    `CHART_PANELS`, each case's runs as dots, its best curve as a line and its defaults as a
    diamond."""
    series = {}
    for case, summary in zip(cases, summaries):
        case_runs = [r for (k, _), r in runs.items() if k == case.key]
        d = summary.default
        series[case.key] = Series(
            label=case.label,
            points=[(r.wall, r.error) for r in case_runs if math.isfinite(r.error)],
            line=best_error_staircase(case_runs),
            highlight=(d.wall, d.error) if math.isfinite(d.error) else None)
    panels = []
    placed = set()
    for title, keys in CHART_PANELS:
        mine = [series[k] for k in keys if k in series]
        for i, s in enumerate(mine):
            s.color = PALETTE[i]
        placed |= set(keys)
        if mine:
            panels.append(Panel(title, mine))
    rest = [s for k, s in series.items() if k not in placed]
    for start in range(0, len(rest), 4):
        for i, s in enumerate(rest[start:start + 4]):
            s.color = PALETTE[i]
        panels.append(Panel("other cases", rest[start:start + 4]))
    draw_loglog_chart(path, panels, title="DDA error against run time, closed-form cases",
                      x_label="wall time of dd.simulate [s]", y_label="error against the exact answer",
                      highlight_legend="default parameters",
                      notes=["dots: one parameter changed at a time (dt, dt_max, p/E, close and open tolerance; "
                             "see accuracy.md); lines: the lowest error reached in that wall time or less "
                             f"(errors >= {WRONG_ANSWER_ERROR:g}, wrong answers, left off); "
                             f"errors < {ERROR_FLOOR:g}: hollow, on the floor"],
                      y_floor=ERROR_FLOOR)


def main(argv: Optional[list[str]] = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="the defaults and dt = 0.02 s only (smoke test, ~20 s)")
    ap.add_argument("--cases", default="", help="comma-separated subset of: " +
                    ", ".join(c.key for c in all_cases()))
    ap.add_argument("--repeat", type=int, default=1,
                    help="passes over the sweep; each setting keeps its shortest wall time (default 1)")
    ap.add_argument("--out", type=Path, default=ROOT / "benchmarks" / "results",
                    help="folder for accuracy.md and accuracy.png")
    ap.add_argument("--chart-from", type=Path, metavar="CSV",
                    help="only draw OUT/accuracy.png again from an earlier sweep's accuracy.csv")
    a = ap.parse_args(argv)
    if a.chart_from:
        redraw_chart(a.chart_from, a.out / "accuracy.png")
        return 0
    cases = all_cases()
    if a.cases:
        wanted = a.cases.split(",")
        unknown = set(wanted) - {c.key for c in cases}
        if unknown:
            ap.error(f"unknown case(s): {', '.join(sorted(unknown))}")
        cases = [c for c in cases if c.key in wanted]
    configs = sweep_configs(a.quick)

    started = datetime.datetime.now().astimezone()
    wall0 = time.perf_counter()
    warm_up(cases)
    runs = {}
    # repeated passes over the whole sweep, keeping each setting's shortest wall time: on a
    # shared machine others' load only ever adds time, and a burst of it hits different
    # settings in different passes (the runs are deterministic: same error every pass)
    for rep in range(a.repeat):
        for case in cases:
            for cfg in configs:
                if not applies(case, cfg):
                    continue
                r = run_case(case, cfg)
                if (case.key, cfg.label) not in runs or r.wall < runs[case.key, cfg.label].wall:
                    runs[case.key, cfg.label] = r
                print(f"  pass {rep + 1} {case.key:12s} {cfg.label:24s} error {format_error(r):>8s}  "
                      f"wall {r.wall:7.3f} s  steps {r.steps:6d}  {r.note}", file=sys.stderr, flush=True)
    total = time.perf_counter() - wall0
    summaries = [summarise(c, [runs[c.key, cfg.label] for cfg in configs if applies(c, cfg)])
                 for c in cases]

    table = results_table(cases, configs, runs)
    machine = machine_description()
    print(table)
    print(f"\nmachine: {machine}")
    a.out.mkdir(parents=True, exist_ok=True)
    md = [
        "# Error against run time (`benchmarks/accuracy.py`)",
        "",
        f"- Date: {started:%Y-%m-%d %H:%M %Z}; code: {git_revision()}; command: "
        f"`python benchmarks/accuracy.py{' --quick' if a.quick else ''}"
        f"{' --cases ' + a.cases if a.cases else ''}{f' --repeat {a.repeat}' if a.repeat > 1 else ''}`; "
        f"total {total:.0f} s.",
        f"- Machine: {machine}.",
        "- Wall time: `dd.simulate` only (scene building excluded), after a warm-up that compiles "
        "the kernels; " + ("one run per setting." if a.repeat == 1 else
                           f"the shortest of {a.repeat} runs per setting, one in each of {a.repeat} passes "
                           "over the sweep (the machine is shared; others' load only adds time).") + " The CPU time of the process and the "
        "step count (in Details) are steadier measures of cost.",
        "- Each row changes one parameter from the defaults (`dd.Params()`; the column case "
        "always runs `static=True`); **defaults** is `params=None`. Every run at full precision: "
        "`accuracy.csv`; what the numbers mean: docs/guide/accuracy.md.",
        "",
        "![error against run time](accuracy.png)",
        "",
        "## Summary",
        "",
        summary_table(summaries),
        "",
        "## Error · wall time per setting",
        "",
        table,
        "",
        "## Cases",
        "",
        "Cases (" + __doc__.split("Cases (", 1)[1].strip(),
        "",
        "## Newmark reference: convergence of the stick–slip solution",
        "",
        newmark_convergence(),
        "",
        "## Details",
        "",
        detail_table(cases, configs, runs),
        "",
    ]
    (a.out / "accuracy.md").write_text("\n".join(md))
    write_runs_csv(a.out / "accuracy.csv", cases, configs, runs)
    if have_matplotlib():
        draw_chart(a.out / "accuracy.png", cases, runs, summaries)
    else:
        print(NO_CHART, file=sys.stderr)
    drawn = "accuracy.png, " if have_matplotlib() else ""
    print(f"\nwrote accuracy.md, {drawn}accuracy.csv in {a.out} ({total:.0f} s)", file=sys.stderr)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
