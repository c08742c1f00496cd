"""Toppling families on a tilted base and their slow-load references (tests/test_toppling_start.py,
benchmarks/toppling_start.py).

A case is a row of columns standing side by side on a fixed plate: column k is ``widths[k]``
wide and a stack of blocks of the given heights. The plate is tilted by θ towards the first
column (the free face, at x = 0 before the tilt), so that the columns topple towards it.

The tilt at which a case topples is found three ways:

- **from the default start** (`start_topples`): the scene built on a plate tilted by θ, run
  with ``dd.simulate`` and the default `Params` (the equilibrium stage first); it toppled when
  a vertex moved more than ``TOPPLED`` × the tallest column in ``DURATION`` (the criterion of
  the single column b/h = 0.4 in the project's stop check: 0.05 m of 1 m in 1.5 s);
- **under a slow gravity ramp** (`ramp_topples`): the same model from rest without the stage
  (``initial_equilibrium=False``), gravity ramped from 0 to g at the fixed tilt over
  ``RAMP_TIMES`` rocking time constants (smoothstep), then held: the model's own weight applied to
  the model as given, slowly — the loading path of the stage, done dynamically;
- **under a slow tilt** (`slow_tilt_angle`): the plate horizontal in the model, gravity ramped
  in at θ0 and then turned by a ground acceleration at a constant rate (the ground's frame,
  docs/method/dda.md §2.4: a body force −ρ·a_g turns g·(0, −1) into g·(−sin θ, −cos θ)), as a
  laboratory tilting table loads a stack; it toppled when a free block's rotation has grown by
  ``ONSET_ROTATION`` since the tilt began to rise.

The ramp is set in rocking time constants √(I_corner/(m·g·R)) of the slenderest column, R
its corner-to-centroid distance (`rocking_time`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

import ddatai as dd

G = 9.81
#: laboratory rock (the stack of the slow-tilt study): soft enough that its contacts settle visibly
LAB_ROCK = dd.Material(density=2600.0, young=350e6, poisson=0.25)
#: the stop check's column rock
ROCK = dd.Material(density=2600.0, young=10e9, poisson=0.25)
#: toppled: a vertex moved more than this fraction of the tallest column [-] ...
TOPPLED = 0.05
#: ... within this much simulated time [s]
DURATION = 1.5
#: the gravity ramp takes this many rocking time constants of the slenderest column
#: (`rocking_time`), then holds for ``HOLD_TIMES`` (a column past its threshold by δ rotates
#: as δ·(cosh(t/τ) − 1): 0.1° past it, by 0.05 in 6 τ)
RAMP_TIMES = 20.0
HOLD_TIMES = 8.0
#: slow tilt: onset of toppling, a free block's rotation grown by this much [rad]
ONSET_ROTATION = 1e-4


@dataclass(frozen=True)
class ToppleCase:
    """A row of columns on a plate; column k: ``widths[k]`` wide, blocks of ``heights[k]``."""

    name: str
    widths: tuple
    heights: tuple               # per column, the heights of its blocks from the bottom [m]
    friction: float              # every joint [degrees]
    material: dd.Material = field(default=ROCK)

    @property
    def tallest(self) -> float:
        return max(sum(h) for h in self.heights)

    def polygons(self) -> list:
        out, x = [], 0.0
        for w, col in zip(self.widths, self.heights):
            y = 0.0
            for h in col:
                out.append([(x, y), (x + w, y), (x + w, y + h), (x, y + h)])
                y += h
            x += w
        return out

    def closed_form(self):
        """The rigid single column's toppling tilt, atan(b/h) [degrees]; None for a group."""
        if len(self.widths) == 1:
            return math.degrees(math.atan(self.widths[0] / self.tallest))
        return None


def column(b: float, h: float, friction: float = 45.0, material=ROCK) -> ToppleCase:
    return ToppleCase(f"column b/h={b / h:g}", (b,), ((h,),), friction, material)


def released_in_doubt(start, released: int) -> bool:
    """Whether an equilibrium stage's record (a row of `Results.start`) released ``released``
    blocks, held none, and released some of them in doubt (`ddatai.in_doubt`: the run's first
    steps then resolve their rocking). Not how many: a block is released in doubt where the
    stage's open-close test (`ddatai.mechanisms.MAX_TEST_SOLVES` solves) did not converge, and
    on these stacks, at the edge of toppling, which tests converge depends on round-off — the
    4-4-4 squares at 23.25° release 11 of 12 in doubt with OpenBLAS's AVX2 kernels and 10 with
    its AVX-512 ones (``OPENBLAS_CORETYPE``). The run's time step reads only whether a block is
    watched, and every released block moves."""
    return (int(start["released"]) == released and int(start["held"]) == 0
            and 1 <= int(start["in_doubt"]) <= released)


def rocking_time(case: ToppleCase) -> float:
    """1/p = √(4R/(3g)) of the slenderest column, R its corner-to-centroid distance: the time
    constant of rigid rocking about a corner (Housner 1963), the time in which a column past
    its threshold falls [s]."""
    return max(math.sqrt(4.0 * 0.5 * math.hypot(w, sum(col)) / (3.0 * G))
               for w, col in zip(case.widths, case.heights))


def scene(case: ToppleCase, theta: float) -> dd.Scene:
    """The case on a plate tilted by ``theta`` [degrees] towards its first column."""
    c, s = math.cos(math.radians(theta)), math.sin(math.radians(theta))

    def turn(points):
        return [(c * x - s * y, s * x + c * y) for x, y in points]

    polys = case.polygons()
    length = sum(case.widths)
    margin = 0.5 * length + case.tallest
    sc = dd.Scene(gravity=G)
    sc.add_block(turn([(-margin, -0.3 * margin), (length + margin, -0.3 * margin), (length + margin, 0.0),
                       (-margin, 0.0)]), material=case.material, fixed=True)
    for p in polys:
        sc.add_block(turn(p), material=case.material)
    sc.set_joint(dd.Joint(friction=case.friction))
    return sc


class _Toppled(Exception):
    pass


def _run_until_toppled(sc: dd.Scene, params, duration: float, limit: float) -> bool:
    """Run ``sc`` for ``duration``; True as soon as a vertex has moved more than ``limit`` [m]
    (the run stops there)."""
    model = dd.build_model(sc, params)

    def watch(state, _record):
        if float(np.abs(state.vertex_xy - model.vertex_xy0).max()) > limit:
            raise _Toppled

    try:
        dd.simulate(sc, params, duration=duration, progress=watch, model=model)
    except _Toppled:
        return True
    return False


def start_duration(case: ToppleCase) -> float:
    """How long a run from the start is watched [s]: as long as the slow load's whole run, its
    ramp and its hold at full gravity ((RAMP_TIMES + HOLD_TIMES) rocking time constants, in
    which the slow load may topple the case), and at least DURATION. A stack that the stage
    releases in doubt starts under sudden gravity and may stop after its first jolt (the 4-4-4
    squares at 23.25°: 2 mm in 0.17 s, then nothing to 4.7 s) or rock on slowly."""
    return max(DURATION, (RAMP_TIMES + HOLD_TIMES) * rocking_time(case))


def start_topples(case: ToppleCase, theta: float, params=None) -> bool:
    """Whether the case topples at tilt ``theta`` from the default start (``params`` None),
    watched for `start_duration`."""
    return _run_until_toppled(scene(case, theta), params, start_duration(case), TOPPLED * case.tallest)


def _turning_gravity(theta_of_t, scale_of_t):
    """The ground acceleration that turns gravity g·(0, −1) into scale·g·(−sin θ, −cos θ)."""
    def accel(t):
        th, s = theta_of_t(t), scale_of_t(t)
        return (G * s * math.sin(th), -G + G * s * math.cos(th))
    return accel


def _smoothstep(t: float, ramp: float) -> float:
    if t >= ramp:
        return 1.0
    x = t / ramp
    return x * x * (3.0 - 2.0 * x)


def ramp_topples(case: ToppleCase, theta: float, frame: str = "turned", ramp_times: float = RAMP_TIMES,
                 dt_max: float | None = None) -> bool:
    """Whether the case topples at ``theta`` with gravity ramped in slowly from rest, no stage,
    over ``ramp_times`` rocking time constants: ``frame`` "turned", the plate horizontal in the
    model and gravity turned by θ; "tilted", the plate tilted by θ in the model (as the start
    sees it) and gravity ramped vertically. ``dt_max``: the run's largest time step
    (`Params.dt_max`; None: the default, 10 ms) — RESOLVED_DT resolves the stacks of squares."""
    tau = rocking_time(case)
    ramp, hold = ramp_times * tau, HOLD_TIMES * tau
    th = math.radians(theta) if frame == "turned" else 0.0
    sc = scene(case, 0.0 if frame == "turned" else theta)
    sc.set_ground_acceleration(_turning_gravity(lambda t: th, lambda t: _smoothstep(t, ramp)))
    params = dd.Params(initial_equilibrium=False) if dt_max is None else \
        dd.Params(initial_equilibrium=False, dt_max=dt_max)
    return _run_until_toppled(sc, params, ramp + hold, TOPPLED * case.tallest)


#: a time step that resolves the slow load of the stacks of 0.1 m squares [s] (their rocking
#: time constant is 0.15–0.18 s: τ/80). At the default 10 ms (τ/17) the ramp of 20 constants
#: sets the 4-4-4 stack rocking at 23.25° from ~1 % of its weight, growing ~12/s (gravity at
#: that share drives at most ~1/s), and topples it, where 10 and 40 constants, 2 ms or lagged
#: friction hold it (docs/guide/equilibrium_start.md)
RESOLVED_DT = 2e-3


def _corner_pairs(model, memory) -> tuple[set, set]:
    """(the vertex pairs of vertex-vertex contacts, the (vertex, edge end) pairs of vertex-edge
    contacts) of a step's contact memory."""
    nv = model.n_vertices
    from ddatai.layout import VV

    vv = memory.kind == VV
    first, second = np.divmod(memory.key[vv] - nv * nv, nv)
    pairs = {(int(min(a, b)), int(max(a, b))) for a, b in zip(first, second)}
    ends = set()
    for a, e in zip(*np.divmod(memory.key[~vv], nv)):
        for w in (int(e), int(model.vertex_next[e])):
            ends.add((int(min(a, w)), int(max(a, w))))
    return pairs, ends


def ramp_handovers(case: ToppleCase, theta: float, frame: str = "turned", ramp_times: float = RAMP_TIMES,
                   kernels: str = "auto") -> dict:
    """`ramp_topples`'s run step by step, counting the corner hand-overs: the vertex pairs (P, Q)
    that change representation between steps, a vertex-vertex contact one step and a
    vertex-edge contact of P on an edge at Q (or of Q on an edge at P) the next, or back
    (docs/method/dda.md §3.4); and the kicks, each step's largest change of a free block's
    velocity |Δv| / (g·Δt). Returns steps, hand-overs, steps with one, the largest kick and
    whether the case toppled. ``kernels``: `Params.kernels` (a small model: the NumPy path, or
    "taichi", the kernel path)."""
    from ddatai.step import Stepper

    tau = rocking_time(case)
    ramp, hold = ramp_times * tau, HOLD_TIMES * tau
    th = math.radians(theta) if frame == "turned" else 0.0
    sc = scene(case, 0.0 if frame == "turned" else theta)
    sc.set_ground_acceleration(_turning_gravity(lambda t: th, lambda t: _smoothstep(t, ramp)))
    model = dd.build_model(sc, dd.Params(initial_equilibrium=False, kernels=kernels))
    stepper = Stepper(model)
    state = model.initial_state()
    free = ~model.block_fixed
    out = dict(steps=0, handovers=0, steps_with=0, kick=0.0, toppled=False)
    last_vv, last_ends = set(), set()
    while state.time < ramp + hold:
        new = stepper.advance(state).state
        dv = np.hypot(*(new.block_velocity[free, :2] - state.block_velocity[free, :2]).T)
        out["kick"] = max(out["kick"], float(dv.max()) / (G * (new.time - state.time)))
        vv, ends = _corner_pairs(model, new.memory)
        n = len((last_vv - vv) & ends) + len((vv - last_vv) & last_ends)
        out["handovers"] += n
        out["steps_with"] += n > 0
        out["steps"] += 1
        last_vv, last_ends, state = vv, ends, new
        if float(np.abs(state.vertex_xy - model.vertex_xy0).max()) > TOPPLED * case.tallest:
            out["toppled"] = True
            break
    return out


#: the slow-load reference of a toppling tilt is a scan: the lowest tilt, on a grid of
#: SCAN_STEP degrees, at which the gravity ramp of any of these frames and ramp lengths (in
#: rocking time constants) topples the case (`scan_topples`); on stacks of square blocks the
#: ramp's outcome near the threshold depends on the frame and the ramp's rate, so one ramp is no
#: reference and the lowest over the scan is the conservative one (docs/guide/equilibrium_start.md)
SCAN_FRAMES = ("turned", "tilted")
SCAN_RAMPS = (10.0, 20.0, 40.0)
SCAN_STEP = 0.25


def scan_topples(case: ToppleCase, theta: float) -> tuple:
    """The first (frame, ramp length) of the scan under which the case topples at ``theta``
    (`ramp_topples`), or () where every one of them holds it (6 runs then)."""
    for ramp in SCAN_RAMPS:
        for frame in SCAN_FRAMES:
            if ramp_topples(case, theta, frame, ramp):
                return frame, ramp
    return ()


def slow_tilt_angle(case: ToppleCase, theta0: float, rate: float, theta_max: float) -> float:
    """The tilt [degrees] at which the case starts to topple when tilted from ``theta0`` at
    ``rate`` [degrees/s] (gravity ramped in at θ0 over RAMP_TIMES rocking time constants and
    held for HOLD_TIMES first); nan if it stands up to ``theta_max``."""
    from ddatai.model import build_model
    from ddatai.step import Stepper

    tau = rocking_time(case)
    ramp, hold = RAMP_TIMES * tau, HOLD_TIMES * tau
    th0, r = math.radians(theta0), math.radians(rate)

    def tilt(t):
        return th0 + r * max(0.0, t - ramp - hold)

    sc = scene(case, 0.0)
    sc.set_ground_acceleration(_turning_gravity(tilt, lambda t: _smoothstep(t, ramp)))
    model = build_model(sc, dd.Params(initial_equilibrium=False))
    stepper = Stepper(model)
    state = model.initial_state()
    free = ~model.block_fixed
    reference = None
    while True:
        state = stepper.advance(state).state
        if reference is None and state.time >= ramp + hold:
            reference = state.block_rotation.copy()
        if reference is not None and np.abs(state.block_rotation - reference)[free].max() > ONSET_ROTATION:
            return math.degrees(tilt(state.time))
        if math.degrees(tilt(state.time)) > theta_max:
            return float("nan")


def ramp_toppling_share(case: ToppleCase, theta: float, frame: str = "turned",
                        ramp_times: float = RAMP_TIMES, **params) -> float | None:
    """`ramp_topples`'s run: the share of the weight s(t) (the smoothstep of the ramp) on the
    case when it has toppled (a vertex moved more than TOPPLED × the tallest column), or None
    where it stands. The ramps that topple the stacks of squares at the lowest tilts do so at
    17–19 % of their weight (docs/guide/equilibrium_start.md). ``params``: `Params` fields other
    than the default (``initial_equilibrium`` is False)."""
    tau = rocking_time(case)
    ramp, hold = ramp_times * tau, HOLD_TIMES * tau
    th = math.radians(theta) if frame == "turned" else 0.0
    sc = scene(case, 0.0 if frame == "turned" else theta)
    sc.set_ground_acceleration(_turning_gravity(lambda t: th, lambda t: _smoothstep(t, ramp)))
    params = dd.Params(initial_equilibrium=False, **params)
    model = dd.build_model(sc, params)
    when = []

    def watch(state, _record):
        if float(np.abs(state.vertex_xy - model.vertex_xy0).max()) > TOPPLED * case.tallest:
            when.append(state.time)
            raise _Toppled

    try:
        dd.simulate(sc, params, duration=ramp + hold, progress=watch, model=model)
    except _Toppled:
        return _smoothstep(when[0], ramp)
    return None


def tilting_table(case: ToppleCase, theta0: float, theta_max: float, rate: float = 0.25) -> float:
    """A tilting table at full weight: gravity ramped in at ``theta0`` (the plate horizontal,
    gravity turned; RAMP_TIMES rocking time constants, then held HOLD_TIMES), then the tilt
    raised at ``rate`` [degrees/s] to ``theta_max``. Returns the tilt [degrees] at which the case
    has toppled — a vertex moved more than TOPPLED × the tallest column from where it was when
    the tilt began to rise (the tilt then lags the onset by the fall, ~1 s) —, nan if it stands."""
    tau = rocking_time(case)
    ramp, hold = RAMP_TIMES * tau, HOLD_TIMES * tau
    th0, th1, r = math.radians(theta0), math.radians(theta_max), math.radians(rate)

    def tilt(t):
        return min(th0 + r * max(0.0, t - ramp - hold), th1)

    sc = scene(case, 0.0)
    sc.set_ground_acceleration(_turning_gravity(tilt, lambda t: _smoothstep(t, ramp)))
    params = dd.Params(initial_equilibrium=False)
    model = dd.build_model(sc, params)
    begin, at = [], []

    def watch(state, _record):
        if state.time < ramp + hold:
            return
        if not begin:
            begin.append(state.vertex_xy.copy())
        if float(np.abs(state.vertex_xy - begin[0]).max()) > TOPPLED * case.tallest:
            at.append(math.degrees(tilt(state.time)))
            raise _Toppled

    try:
        dd.simulate(sc, params, duration=ramp + hold + (th1 - th0) / r, progress=watch, model=model)
    except _Toppled:
        return at[0]
    return float("nan")


def threshold(topples, lo: float, hi: float, tol: float = 0.1) -> float:
    """Bisection for the lowest tilt in (lo, hi] at which ``topples(theta)``; ``lo`` must
    stand and ``hi`` topple (checked). Returns the upper end of the final bracket [degrees]."""
    if topples(lo):
        raise ValueError(f"the case topples already at the lower bracket {lo}°")
    if not topples(hi):
        raise ValueError(f"the case stands at the upper bracket {hi}°")
    return _bisect(topples, lo, hi, tol)[1]


def _bisect(turned, lo: float, hi: float, tol: float) -> tuple[float, float]:
    """The bracket (lo, hi], at most ``tol`` wide, where ``turned`` goes from False to True."""
    while hi - lo > tol:
        mid = 0.5 * (lo + hi)
        if turned(mid):
            hi = mid
        else:
            lo = mid
    return lo, hi


def _squares(counts, a: float = 0.1, friction: float = 38.0) -> ToppleCase:
    """Columns of a × a square blocks, ``counts`` blocks high, of the laboratory rock."""
    return ToppleCase(f"squares {'-'.join(map(str, counts))}", tuple([a] * len(counts)),
                      tuple(tuple([a] * n) for n in counts), friction, LAB_ROCK)


#: the Goodman–Bray slope (scenes/toppling_slope.py) at this scale: its rigid-block threshold
#: (φ 38.15°) does not depend on size, and the Young's modulus scaled with it keeps its strains;
#: small, its slow load takes 28 rocking time constants of 0.17 s instead of 1.7 s
GB_SCALE = 0.01
#: ... whose tallest block (40 m at full size) must move this fraction of its height to have failed
GB_HEIGHT = 40.0 * GB_SCALE


def goodman_bray(friction: float) -> dd.Scene:
    """Goodman and Bray's 16 blocks on a stepped base (scenes/toppling_slope.py) at GB_SCALE,
    every joint of friction ``friction`` [degrees], no cohesion."""
    from dataclasses import replace

    from scenes import toppling_slope

    full, _ = toppling_slope.build(friction=friction)
    sc = dd.Scene(gravity=G)
    for spec in full.blocks:
        soft = replace(spec.material, young=spec.material.young * GB_SCALE)
        sc.add_block(np.asarray(spec.vertices) * GB_SCALE, material=soft, fixed=spec.fixed)
    sc.set_joint(dd.Joint(friction=friction, cohesion=0.0, tensile=0.0))
    return sc


def gb_rocking_time() -> float:
    """The rocking time constant of the slenderest block of `goodman_bray` (10 × 40 m at full
    size) [s]."""
    return math.sqrt(4.0 * 0.5 * math.hypot(10.0 * GB_SCALE, GB_HEIGHT) / (3.0 * G))


def gb_start_fails(friction: float) -> bool:
    """Whether `goodman_bray` fails (a vertex moves more than TOPPLED × its tallest block within
    DURATION) from the default start."""
    return _run_until_toppled(goodman_bray(friction), None, DURATION, TOPPLED * GB_HEIGHT)


def gb_ramp_fails(friction: float) -> bool:
    """Whether `goodman_bray` fails with its weight ramped in slowly from rest, no stage
    (RAMP_TIMES rocking time constants, then held HOLD_TIMES)."""
    tau = gb_rocking_time()
    ramp, hold = RAMP_TIMES * tau, HOLD_TIMES * tau
    sc = goodman_bray(friction)
    sc.set_ground_acceleration(_turning_gravity(lambda t: 0.0, lambda t: _smoothstep(t, ramp)))
    return _run_until_toppled(sc, dd.Params(initial_equilibrium=False), ramp + hold, TOPPLED * GB_HEIGHT)


def critical_friction(fails, lo: float, hi: float, tol: float = 0.1) -> float:
    """Bisection for the highest friction angle in [lo, hi) at which ``fails(φ)``; ``lo`` must
    fail and ``hi`` hold (checked). Returns the lower end of the final bracket [degrees]."""
    if not fails(lo):
        raise ValueError(f"the case holds already at the lower bracket {lo}°")
    if fails(hi):
        raise ValueError(f"the case fails at the upper bracket {hi}°")
    return _bisect(lambda phi: not fails(phi), lo, hi, tol)[0]


#: the family: case and a bracket (lo stands, hi topples from the start) [degrees]
CASES = {
    "column 0.2": (column(0.2, 1.0), 10.0, 12.5),
    "column 0.4": (column(0.4, 1.0), 20.5, 23.5),
    "column 0.5": (column(0.5, 1.0), 25.0, 28.0),
    "row 3 x 0.25": (ToppleCase("row 3 x 0.25", (0.25,) * 3, ((1.0,),) * 3, 38.0), 15.0, 27.0),
    "stair 0.25": (ToppleCase("stair 0.25", (0.25,) * 4, ((0.6,), (0.8,), (1.0,), (1.2,)), 38.0), 15.0, 28.0),
    "squares 3-4-5": (_squares((3, 4, 5)), 12.0, 26.0),
    "squares 4-5-6-7": (_squares((4, 5, 6, 7)), 10.0, 20.0),
    "squares 4-4-4": (_squares((4, 4, 4)), 10.0, 25.0),
}
