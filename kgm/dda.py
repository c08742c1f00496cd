"""DDA evaluator: judge a group by simulating it with ddatai on its real joint geometry (the
seed paper's developed method; docs/kgm/method.md §6).

A judgement simulates only what it needs: the group and the blocks it touches, which are held
fixed (KGM's "non-members stay in place"); blocks farther away are left out
(`DdaSettings.free_neighbours` lets the touching blocks move and fixes the next ring). The
verdict follows the displacement and velocity criteria documented on `kgm.DdaSettings`. The
factor of safety is found by strength reduction (tanφ/F and c/F on every joint, bisection on F)
and the critical friction angle by bisection on the friction angle of every joint with
cohesion held (§6.4).

This module imports Taichi (through `ddatai.simulate`) only inside the functions that run a
simulation, so `import kgm` stays light.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, replace
from typing import Optional

import numpy as np

from ddatai.params import Joint, Params
from ddatai.scene import Scene

from .blocks import BlockSystem
from .settings import DdaSettings


@dataclass(frozen=True, kw_only=True, eq=False)
class DdaJudgement:
    """One DDA run of a group and its verdict."""

    stable: bool
    """Verdict: False if the group is still moving with d(T) ≥ δ (see `kgm.DdaSettings`)."""
    displacement: float
    """Largest member displacement at the end of the run [m]."""
    speed: float
    """Mean speed of that displacement over the last quarter of the run [m/s]."""
    threshold: float
    """δ: the displacement criterion [m]."""
    duration: float
    """Planned simulated time T [s]."""
    simulated: float
    """Simulated time actually run (less than T when stopped early) [s]."""
    steps: int
    """Time steps taken [-]."""
    wall_time: float
    """Wall-clock time of the run [s]."""
    friction: Optional[float]
    """Friction angle given to every joint [degrees], or None (the scene's joints)."""
    reduction: float
    """Strength-reduction factor F: tanφ/F and c/F on every joint [-]."""
    model_blocks: int
    """Blocks in the simulated sub-model [-]."""
    moving_blocks: int
    """Free blocks in the sub-model [-]."""
    scene_blocks: int
    """Blocks in the whole scene [-]."""
    note: str = ""
    """'stopped early' or the cause of a divergence after the group had failed."""
    batch: int = 1
    """Members of the run it was judged in (`judge_many`: several strengths side by side in one
    model; ``wall_time`` is then that run's) [-]."""


@dataclass(frozen=True, kw_only=True, eq=False)
class DdaTiming:
    """Per-step wall time of the judgement's sub-model against the whole slope."""

    steps: int
    """Steps timed in each run [-]."""
    sub_step_time: float
    """Mean wall time of a step of the sub-model [s]."""
    whole_step_time: float
    """Mean wall time of a step of the whole slope [s]."""
    sub_blocks: int
    """Blocks in the sub-model [-]."""
    whole_blocks: int
    """Blocks in the whole scene [-]."""

    @property
    def saving(self) -> float:
        """Fraction of the whole-slope time saved [-]."""
        return 1.0 - self.sub_step_time / self.whole_step_time


@dataclass(frozen=True, kw_only=True, eq=False)
class DdaEvaluation:
    """DDA verdict, strength-reduction FS and critical friction angle of a group."""

    fs: float
    """Strength-reduction factor of safety [-] (midpoint of the final bisection bracket)."""
    critical_friction: float
    """Friction angle of all joints (cohesion held) at the stability limit [degrees]."""
    judgement: DdaJudgement
    """The run at the scene's own strength (F = 1): the verdict."""
    runs: tuple
    """Every `DdaJudgement` made, in order [-]."""
    wall_time: float
    """Wall-clock time of all runs [s]."""
    timing: Optional[DdaTiming] = None
    """Sub-model vs whole slope per-step timing (if `DdaSettings.compare_whole`)."""


class _StopRun(Exception):
    """Raised from the progress callback to end a run that has clearly failed."""


# ---------------------------------------------------------------------- sub-model
def sub_scene(scene: Scene, system: BlockSystem, blocks: frozenset, *, removed: frozenset = frozenset(),
              free_neighbours: bool = False, friction: Optional[float] = None,
              reduction: float = 1.0) -> tuple[Scene, list[int]]:
    """The part of the scene a judgement needs: the group (free), the blocks touching it
    (fixed, or free with ``free_neighbours`` and then the next ring fixed); removed blocks
    and everything farther away left out. Every joint gets the friction angle ``friction``
    [degrees] if given, and tanφ and c divided by ``reduction``.

    The scene's water table comes along, and so does every bolt with an end in a moving block
    (its other block held fixed if it is not already in the sub-scene), its capacity divided
    by ``reduction`` like the joints' strength (docs/method/water_bolts.md).

    Returns the sub-scene and the original id of each of its blocks.
    """
    ring1 = system.neighbours(blocks, removed)
    moving = set(blocks)
    held = set(ring1)
    if free_neighbours:
        moving |= {b for b in ring1 if not system.block_fixed[b]}
        held = system.neighbours(moving, removed) | {b for b in ring1 if system.block_fixed[b]}
    bolts = [b for b in scene.bolts if b.block1 in moving or b.block2 in moving]
    held |= {blk for b in bolts for blk in (b.block1, b.block2) if blk not in moving}
    sub, ids = scene.subset(sorted(moving | held), held=sorted(held))
    sub.joints = [_reduced(j, friction, reduction) for j in scene.joints]
    # only the bolts that hold a moving block act; their capacity is reduced like the joints
    sub.bolts = [replace(b, capacity=b.capacity / reduction) for b in sub.bolts
                 if ids[b.block1] in moving or ids[b.block2] in moving]
    return sub, ids


def _reduced(joint: Joint, friction: Optional[float], reduction: float) -> Joint:
    from ddatai.params import BartonBandis

    if isinstance(joint, BartonBandis) and friction is None:
        # tan φ(σn)/F at each contact's own stress, c/F (docs/method/barton_bandis.md)
        return replace(joint, reduction=joint.reduction * reduction, cohesion=joint.cohesion / reduction)
    phi = joint.friction if friction is None else float(friction)
    tan_phi = math.tan(math.radians(phi)) / reduction
    return Joint(friction=math.degrees(math.atan(tan_phi)), cohesion=joint.cohesion / reduction,
                 tensile=joint.tensile)


def run_params(params: Optional[Params], settings: DdaSettings) -> Params:
    """The DDA parameters of a judgement: the given ones with the cohesion rule of the settings,
    started from gravitational equilibrium (`ddatai.Params.initial_equilibrium`): switched on at
    once, gravity overshoots the static contact forces and a group near its limit slips in the
    first steps, so the verdict would follow that transient instead of the strength."""
    params = settings.params or params or Params()
    return replace(params, bond_breaks_on_slip=not settings.cohesion_held, initial_equilibrium=True)


def group_size(system: BlockSystem, blocks: frozenset) -> float:
    """√(area of the group) [m], the length the displacement criterion scales with."""
    return math.sqrt(float(system.block_area[sorted(blocks)].sum()))


# ---------------------------------------------------------------------- one judgement
def judge(scene: Scene, system: BlockSystem, blocks: frozenset, *, settings: DdaSettings,
          params: Optional[Params] = None, removed: frozenset = frozenset(),
          friction: Optional[float] = None, reduction: float = 1.0,
          record_every: Optional[int] = None):
    """Simulate the group's sub-model once and decide stable / unstable.

    With ``record_every`` the run is not stopped early and its `ddatai.Results` (of the
    sub-model) are returned too: ``(judgement, results, ids)``; otherwise the judgement alone.
    """
    from ddatai.model import build_model
    from ddatai.results import SimulationError
    from ddatai.run import simulate  # starts Taichi

    sub, ids = sub_scene(scene, system, blocks, removed=removed, free_neighbours=settings.free_neighbours,
                         friction=friction, reduction=reduction)
    prm = run_params(params, settings)
    delta = settings.displacement_ratio * group_size(system, blocks)
    duration = settings.duration or math.sqrt(2.0 * delta / settings.acceleration_resolution)
    model = build_model(sub, prm)  # built once: its origin maps the positions, simulate runs it
    origin = model.origin
    pos = [ids.index(b) for b in sorted(blocks)]
    counts = np.array([len(s.vertices) for s in sub.blocks])
    offset = np.concatenate([[0], np.cumsum(counts)])
    vidx = np.concatenate([np.arange(offset[p], offset[p + 1]) for p in pos])
    starts = np.concatenate([[0], np.cumsum(counts[pos])[:-1]])
    x0 = np.concatenate([sub.blocks[p].vertices for p in pos]) - origin
    stop_at = settings.stop_ratio * delta if record_every is None else math.inf
    times, disp = [0.0], [0.0]

    def progress(state, record):
        # displacement of each member = mean displacement of its vertices (its centroid's for a
        # rigid translation); the group's = the largest
        u = np.add.reduceat(state.vertex_xy[vidx] - x0, starts, axis=0) / counts[pos][:, None]
        times.append(state.time)
        disp.append(float(np.max(np.hypot(u[:, 0], u[:, 1]))))
        if disp[-1] > stop_at:
            raise _StopRun

    t0 = time.perf_counter()
    note = ""
    results = None
    try:
        results = simulate(sub, prm, duration=duration, progress=progress,
                           record_every=record_every or 10 ** 9, model=model)
    except _StopRun:
        note = "stopped early"
    except SimulationError as err:
        if max(disp) < delta:
            raise
        note = f"diverged after failing: {err}"
        results = err.results
    wall = time.perf_counter() - t0
    j = _verdict(np.array(times), np.array(disp), delta=delta, duration=duration, note=note, wall_time=wall,
                 friction=friction, reduction=reduction, model_blocks=len(ids),
                 moving_blocks=sum(not s.fixed for s in sub.blocks), scene_blocks=scene.n_blocks)
    if settings.progress is not None:
        settings.progress(j)
    if record_every is not None:
        return j, results, ids
    return j


def _verdict(t: np.ndarray, d: np.ndarray, *, delta: float, duration: float, note: str, **fields) -> DdaJudgement:
    """The verdict of a run from its displacement history d(t) (`kgm.DdaSettings`): unstable if
    it was stopped or failed after moving, or if d(T) ≥ δ while its mean speed over the last
    quarter of the run is ≥ δ/T."""
    tq = 0.75 * t[-1]
    speed = float((d[-1] - np.interp(tq, t, d)) / max(t[-1] - tq, 1e-300))
    unstable = bool(note) or (d[-1] >= delta and speed >= delta / duration)
    return DdaJudgement(stable=not unstable, displacement=float(d[-1]), speed=speed, threshold=delta,
                        duration=duration, simulated=float(t[-1]), steps=len(t) - 1, note=note, **fields)


# ---------------------------------------------------------------------- bisections
def evaluate_dda(scene: Scene, system: BlockSystem, blocks: frozenset, *, settings: DdaSettings,
                 params: Optional[Params] = None, removed: frozenset = frozenset(),
                 fs_guess: float = 1.0, friction_guess: Optional[float] = None,
                 with_fs: bool = True, with_friction: bool = True) -> DdaEvaluation:
    """Verdict at the scene's strength, FS by strength reduction and the critical friction
    angle, each by bisection on DDA verdicts (docs/kgm/method.md §6.4). The guesses (the
    limit-equilibrium values) only place the first bracket.

    With ``settings.batch`` > 1 the probes of a round — the verdict, probes of F and of φ — run
    side by side in one model (`judge_many`) and each bracket is cut into as many pieces as it
    has probes (a K-section instead of a bisection): the same final brackets, to the same
    tolerances, in a few runs instead of a dozen."""
    from .batched import judge_many

    runs: list[DdaJudgement] = []
    cache: dict[tuple, DdaJudgement] = {}

    def key(friction, reduction):
        return (None if friction is None else round(friction, 9), round(reduction, 12))

    def run(friction=None, reduction=1.0) -> bool:
        k = key(friction, reduction)
        if k not in cache:
            cache[k] = judge(scene, system, blocks, settings=settings, params=params, removed=removed,
                             friction=friction, reduction=reduction)
            runs.append(cache[k])
        return cache[k].stable

    t0 = time.perf_counter()
    fs = phi = math.nan
    if settings.batch > 1:
        searches = {}
        if with_fs:
            f = min(max(fs_guess, 0.1), 10.0) if math.isfinite(fs_guess) and fs_guess > 0 else 1.0
            # x = −ln F: the group is stable for x ≥ −ln FS
            searches["fs"] = _Bracket(guess=-math.log(f), lower=-math.log(50.0), upper=-math.log(0.02),
                                      tolerance=math.log1p(settings.fs_tolerance), step=math.log(1.25))
        if with_friction:
            g = friction_guess if friction_guess is not None else float(np.mean(system.contact_friction))
            searches["phi"] = _Bracket(guess=min(max(g, 0.0), 85.0), lower=0.0, upper=89.0,
                                       tolerance=settings.friction_tolerance, step=2.0)
        first = True
        while first or any(not b.done for b in searches.values()):
            active = [n for n, b in searches.items() if not b.done]
            probes = [(None, 1.0)] if first else []
            share = max(1, (settings.batch - len(probes)) // max(len(active), 1))
            asked = {n: searches[n].proposals(share, share_next=max(1, settings.batch // max(len(active), 1)))
                     for n in active}
            for n, xs in asked.items():
                probes += [(None, math.exp(-x)) if n == "fs" else (x, 1.0) for x in xs]
            todo = [p for p in dict.fromkeys(probes) if key(*p) not in cache]
            for p, j in zip(todo, judge_many(scene, system, blocks, todo, settings=settings, params=params,
                                             removed=removed)):
                cache[key(*p)] = j
                runs.append(j)
            for n, xs in asked.items():
                for x in xs:
                    p = (None, math.exp(-x)) if n == "fs" else (x, 1.0)
                    searches[n].record(x, cache[key(*p)].stable)
            if first and "fs" in searches:  # the verdict is the probe F = 1
                searches["fs"].record(0.0, cache[(None, 1.0)].stable)
            first = False
        if with_fs:
            fs = searches["fs"].limit(lambda x: math.exp(-x), below=math.inf, above=0.0)
        if with_friction:
            phi = searches["phi"].limit(lambda x: x, below=0.0, above=90.0)
    else:
        run()
        if with_fs:
            fs = _bisect_reduction(run, fs_guess, settings.fs_tolerance)
        if with_friction:
            guess = friction_guess if friction_guess is not None else float(np.mean(system.contact_friction))
            phi = _bisect_friction(run, guess, settings.friction_tolerance)
    timing = None
    if settings.compare_whole:
        timing = time_sub_and_whole(scene, system, blocks, settings=settings, params=params, removed=removed)
    return DdaEvaluation(fs=fs, critical_friction=phi, judgement=cache[(None, 1.0)], runs=tuple(runs),
                         wall_time=time.perf_counter() - t0, timing=timing)


class _Bracket:
    """A K-section search for the limit x* of a monotone verdict, stable for x ≥ x* on
    [lower, upper]: each round proposes points that cut the bracket (largest unstable x,
    smallest stable x) into equal pieces, or, while one side is missing, points stepping away
    from what is known (the step doubling each round); done when the bracket is at most
    ``tolerance`` wide or the limit lies outside [lower, upper]."""

    def __init__(self, *, guess: float, lower: float, upper: float, tolerance: float, step: float):
        self.guess, self.lower, self.upper = guess, lower, upper
        self.tolerance, self.step = tolerance, step
        self.stable_min = math.inf      # smallest x judged stable
        self.unstable_max = -math.inf   # largest x judged unstable

    def record(self, x: float, stable: bool) -> None:
        if stable:
            self.stable_min = min(self.stable_min, x)
        else:
            self.unstable_max = max(self.unstable_max, x)

    @property
    def done(self) -> bool:
        s, u = self.stable_min, self.unstable_max
        return (s - u <= self.tolerance) or s <= self.lower or u >= self.upper

    def proposals(self, n: int, share_next: int) -> list:
        s, u = self.stable_min, self.unstable_max
        if math.isfinite(s) and math.isfinite(u):
            return [u + (s - u) * i / (n + 1) for i in range(1, n + 1)]
        # spacing such that the next round, with ``share_next`` probes, closes the bracket
        h = max(self.step if math.isfinite(s) or math.isfinite(u) else 0.0,
                0.95 * self.tolerance * (share_next + 1))
        if not math.isfinite(s) and not math.isfinite(u):
            xs = [self.guess + h * (i - (n - 1) / 2.0) for i in range(n)]
        elif math.isfinite(s):  # all stable so far: look below
            xs = [s - h * 2.0 ** i for i in range(n)]
        else:
            xs = [u + h * 2.0 ** i for i in range(n)]
        xs = sorted({min(max(x, self.lower), self.upper) for x in xs})
        return [x for x in xs if x != s and x != u]

    def limit(self, value, *, below: float, above: float) -> float:
        """The limit in the caller's variable (``value`` maps x): the bracket's midpoint in x;
        ``below`` when even ``lower`` was stable, ``above`` when even ``upper`` failed."""
        s, u = self.stable_min, self.unstable_max
        if s <= self.lower:
            return below
        if u >= self.upper:
            return above
        return value(0.5 * (s + u))


def _bisect_reduction(stable_at, guess: float, tol: float) -> float:
    """F between the largest stable and the smallest unstable reduction (geometric bisection)."""
    step = 1.25
    f = min(max(guess, 0.1), 10.0) if math.isfinite(guess) and guess > 0 else 1.0
    if stable_at(reduction=f):
        lo, hi = f, f * step
        while stable_at(reduction=hi):
            lo, hi = hi, hi * step
            if hi > 50.0:
                return math.inf
    else:
        lo, hi = f / step, f
        while not stable_at(reduction=lo):
            lo, hi = lo / step, lo
            if lo < 0.02:
                return 0.0
    while hi / lo - 1.0 > tol:
        mid = math.sqrt(lo * hi)
        if stable_at(reduction=mid):
            lo = mid
        else:
            hi = mid
    return math.sqrt(lo * hi)


def _bisect_friction(stable_at, guess: float, tol: float) -> float:
    """φ between the largest unstable and the smallest stable friction angle of all joints."""
    step = 2.0
    phi = min(max(guess, 0.0), 85.0)
    if stable_at(friction=phi):
        lo, hi = phi - step, phi
        while lo > 0.0 and stable_at(friction=lo):
            lo, hi = lo - step, lo
        if lo <= 0.0:
            if stable_at(friction=0.0):
                return 0.0
            lo = 0.0
    else:
        lo, hi = phi, phi + step
        while not stable_at(friction=hi):
            lo, hi = hi, hi + step
            if hi > 89.0:
                return 90.0
    while hi - lo > tol:
        mid = 0.5 * (lo + hi)
        if stable_at(friction=mid):
            hi = mid
        else:
            lo = mid
    return 0.5 * (lo + hi)


def time_sub_and_whole(scene: Scene, system: BlockSystem, blocks: frozenset, *, settings: DdaSettings,
                       params: Optional[Params] = None, removed: frozenset = frozenset()) -> DdaTiming:
    """Mean wall time per step of the judgement's sub-model and of the whole slope (all
    remaining blocks free as in the scene), over ``settings.whole_steps`` steps each."""
    from ddatai.results import SimulationError
    from ddatai.run import simulate

    prm = run_params(params, settings)
    sub, ids = sub_scene(scene, system, blocks, removed=removed, free_neighbours=settings.free_neighbours)
    whole = scene
    if removed:
        keep = [b for b in range(scene.n_blocks) if b not in removed]
        whole, _ = scene.subset(keep)

    def per_step(sc) -> float:
        t0 = time.perf_counter()
        try:
            res = simulate(sc, prm, steps=settings.whole_steps, record_every=10 ** 9)
            n = len(res.steps)
        except SimulationError as err:
            n = len(err.results.steps) if err.results is not None else 1
        return (time.perf_counter() - t0) / max(n, 1)

    per_step(sub)  # warm-up: kernel compilation is not part of either cost
    return DdaTiming(steps=settings.whole_steps, sub_step_time=per_step(sub), whole_step_time=per_step(whole),
                     sub_blocks=len(ids), whole_blocks=whole.n_blocks)
