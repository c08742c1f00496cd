"""One DDA judgement of a group (the seed paper's developed method; docs/kgm/method.md §6): the
sub-model of the group and the blocks it touches, one run, its verdict.

The judge takes values and returns one: `run_judgement` takes the `kgm.build.Problem`, the
group, its strength (`kgm.strength.Strength`) and a `RunPlan` (the run's parameters, δ, T,
when it stops), and returns a `Run` (the `DdaJudgement`, and the run's results when asked).
The engine underneath (`ddatai.simulate` on the sub-model) is called in that one place; many
runs side by side are `kgm.judges.batch`, the factor of safety and critical friction on their
verdicts `kgm.judges.dda`. The caller reports each judgement (`kgm.DdaSettings.progress` at the
entry points).

This module imports Taichi (through `ddatai.simulate`) only inside the function that runs a
simulation, so ``import kgm`` stays light.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, replace
from typing import Any, Callable, Optional

import numpy as np

from ddatai.params import Params
from ddatai.scene import Scene

from ..build import Problem
from ..kinds import RunEnd
from ..settings import DdaSettings, Settings
from ..strength import Strength
from ..system import BlockSystem

#: Called with each judgement as its run ends (`kgm.DdaSettings.progress`), or None.
Report = Optional[Callable[["DdaJudgement"], None]]


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
    """'stopped early' (past `kgm.DdaSettings.stop_ratio`·δ), 'at rest' (stopped as stable,
    `kgm.judges.run.RestCounter`) or the cause of a divergence after the group had failed
    (``end`` says which)."""
    batch: int = 1
    """Members of the run it was judged in (`kgm.judges.batch.judge_many`: several strengths side
    by side in one model; ``wall_time`` is then that run's) [-]."""
    end: RunEnd = RunEnd.DURATION
    """How the run ended (`kgm.kinds.RunEnd`): its duration T, at rest, stopped early, or
    diverged after the group had failed."""



class StopRun(Exception):
    """Raised from ddatai's progress callback to end a run that is decided (`kgm.judges.batch`
    raises it too)."""


@dataclass(frozen=True, kw_only=True)
class RunPlan:
    """How a judgement of a group runs (`kgm.DdaSettings`, docs/kgm/method.md §6.3): the DDA
    parameters, the displacement criterion δ, the simulated time T, and when a run stops before
    T — past ``stop_ratio``·δ as unstable, at rest as stable. One plan serves every judgement of
    the group (any strength), alone or side by side (`kgm.judges.batch`)."""

    params: Params
    """DDA parameters of the runs (`run_params`)."""
    delta: float
    """δ = displacement_ratio·√(group area) [m]."""
    duration: float
    """T: the given duration, or √(2δ/a_r) [s]."""
    stop_ratio: float
    """A run that is not recorded stops as unstable once its displacement passes this many δ [-]."""
    rest_speed: Optional[float]
    """A run stops as stable once its free blocks have moved slower than this for
    ``rest_steps`` steps (rest_ratio·δ/T) [m/s]; None: never."""
    rest_steps: int
    """Steps at rest before a run stops [-]."""
    free_neighbours: bool
    """The blocks touching the group move too (`sub_scene`)."""

    @classmethod
    def of(cls, system: BlockSystem, blocks: frozenset, settings: DdaSettings,
           params: Optional[Params] = None) -> "RunPlan":
        """The plan of the judgements of ``blocks`` in ``system`` under ``settings`` (``params``:
        the DDA parameters given to the entry point, unless ``settings.params``)."""
        delta = settings.displacement_ratio * group_size(system, blocks)
        duration = settings.duration or math.sqrt(2.0 * delta / settings.acceleration_resolution)
        return cls(params=run_params(params, settings), delta=delta, duration=duration,
                   stop_ratio=settings.stop_ratio,
                   rest_speed=settings.rest_ratio * delta / duration if settings.rest_ratio > 0.0 else None,
                   rest_steps=settings.rest_steps, free_neighbours=settings.free_neighbours)

    @property
    def stop_at(self) -> float:
        """The displacement past which a run stops as unstable [m]."""
        return self.stop_ratio * self.delta


@dataclass(frozen=True, kw_only=True, eq=False)
class Run:
    """What `run_judgement` returns: the judgement, and for a recorded run its results."""

    judgement: "DdaJudgement"
    """The verdict and the run's figures."""
    results: Any = None
    """`ddatai.Results` of the sub-model (a recorded run), else None."""
    ids: tuple = ()
    """The original id of each block of the sub-model."""


# ---------------------------------------------------------------------- sub-model
def sub_scene(scene: Scene, system: BlockSystem, blocks: frozenset, *, removed: frozenset = frozenset(),
              free_neighbours: bool = False, friction: Optional[float] = None,
              reduction: float = 1.0) -> tuple[Scene, list[int]]:
    """The part of the scene a judgement needs: the group (free), the blocks touching it
    (fixed, or free with ``free_neighbours`` and then the next ring fixed); removed blocks
    and everything farther away left out. Every joint gets the friction angle ``friction``
    [degrees] if given, and tanφ and c divided by ``reduction`` (`kgm.strength.Strength`).

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
    strength = Strength(friction=friction, reduction=reduction)
    sub.joints = [strength.joint(j) for j in scene.joints]
    # only the bolts that hold a moving block act; their capacity is reduced like the joints
    sub.bolts = [replace(b, capacity=strength.capacity(b.capacity)) for b in sub.bolts
                 if ids[b.block1] in moving or ids[b.block2] in moving]
    return sub, ids


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
def block_displacements(model, blocks):
    """A function of the vertex positions (of ``model``) giving the displacement of each block
    in ``blocks`` (ids in the model) from where it started: the mean displacement of its vertices
    (its centroid's for a rigid translation) [m]."""
    offset = model.vertex_offset
    counts = np.diff(offset)[blocks]
    vidx = np.concatenate([np.arange(offset[b], offset[b + 1]) for b in blocks])
    starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
    x0 = model.vertex_xy0[vidx]

    def moved(vertex_xy: np.ndarray) -> np.ndarray:
        u = np.add.reduceat(vertex_xy[vidx] - x0, starts, axis=0) / counts[:, None]
        return np.hypot(u[:, 0], u[:, 1])

    return moved


def block_speeds(model):
    """A function of the generalized velocities (of ``model``, (B, 6)) giving a bound of each
    block's vertex speeds [m/s]: the speed of its reference point plus its radius
    (``ddatai.kinematics.block_radius``, at the model's start) times its rotation and strain
    rates (0 for fixed blocks)."""
    from ddatai.kinematics import block_radius

    xy = model.vertex_xy0
    radius = block_radius(model, xy, model.block_geometry(xy)["centroid"])
    free = ~np.asarray(model.block_fixed)

    def speeds(velocity: np.ndarray) -> np.ndarray:
        v = np.hypot(velocity[:, 0], velocity[:, 1]) + radius * np.abs(velocity[:, 2:]).sum(axis=1)
        return np.where(free, v, 0.0)

    return speeds


class RestCounter:
    """Counts, per run, the consecutive steps at which every free block moves slower than
    ``limit`` [m/s] (`kgm.DdaSettings.rest_ratio`·δ/T). A run that has been that still for
    ``steps`` steps is at rest: its loads do not change in time (kgm refuses ground shaking and
    point loads given as functions of time, `kgm.build.build_block_system`), and a step from rest
    with its contacts locked reproduces the state it started from (the contact forces balance
    the loads), so its displacement at T is the one it has, and its speed over the last quarter
    of the run 0. The limit sits far above round-off (~1e-16 of the coordinates a step, ~1e-10
    m/s in a batch of members 500 m from the origin) and far below motion: a block perched at an
    unstable equilibrium leaves it as e^(λt), λ ≈ √(g/L) for a block of size L, and over
    T = √(2δ/a_r) with δ = 0.005·L and a_r = 0.05 m/s², λT ≈ √(0.2·g) ≈ 1.4: from 1e-6·δ/T it
    moves some 3e-6·δ by T (docs/kgm/method.md §6.3)."""

    def __init__(self, runs: int, limit: float, steps: int):
        self.limit, self.steps = limit, steps
        self.quiet = np.zeros(runs, np.int64)

    def update(self, fastest: np.ndarray, runs=slice(None)) -> np.ndarray:
        """Record the fastest block speed of the runs ``runs`` (all by default) at this step;
        returns which of them are at rest."""
        self.quiet[runs] = np.where(fastest <= self.limit, self.quiet[runs] + 1, 0)
        return self.quiet[runs] >= self.steps


def run_judgement(problem: Problem, blocks: frozenset, strength: Strength, plan: RunPlan, *,
                  removed: frozenset = frozenset(), record_every: Optional[int] = None) -> Run:
    """Simulate the group's sub-model once at ``strength`` and decide stable / unstable.

    With ``record_every`` the run is not stopped before T and its `ddatai.Results` (of the
    sub-model) come with the judgement, a frame every so many steps.
    """
    from ddatai.model import build_model
    from ddatai.results import SimulationError
    from ddatai.run import simulate  # starts Taichi

    sub, ids = sub_scene(problem.scene, problem.system, blocks, removed=removed,
                         free_neighbours=plan.free_neighbours, friction=strength.friction,
                         reduction=strength.reduction)
    prm, delta, duration = plan.params, plan.delta, plan.duration
    model = build_model(sub, prm)  # built once: its origin maps the positions, simulate runs it
    moved = block_displacements(model, [ids.index(b) for b in sorted(blocks)])
    stop_at = plan.stop_at if record_every is None else math.inf
    times, disp = [0.0], [0.0]
    rest = None
    if record_every is None and plan.rest_speed is not None:
        rest = RestCounter(1, plan.rest_speed, plan.rest_steps)
        speeds = block_speeds(model)
    resting = [False]

    def progress(state, record):
        # the group's displacement: the largest of its members'
        times.append(state.time)
        disp.append(float(np.max(moved(state.vertex_xy))))
        if disp[-1] > stop_at:
            raise StopRun
        if rest is not None and rest.update(np.array([speeds(state.block_velocity).max(initial=0.0)]))[0]:
            resting[0] = True
            raise StopRun

    t0 = time.perf_counter()
    end, cause = RunEnd.DURATION, ""
    results = None
    try:
        results = simulate(sub, prm, duration=duration, progress=progress,
                           record_every=record_every or 10 ** 9, model=model)
    except StopRun:
        end = RunEnd.AT_REST if resting[0] else RunEnd.STOPPED_EARLY
    except SimulationError as err:
        if max(disp) < delta:
            raise
        end, cause = RunEnd.DIVERGED, str(err)
        results = err.results
    wall = time.perf_counter() - t0
    j = verdict(np.array(times), np.array(disp), delta=delta, duration=duration, end=end, cause=cause,
                wall_time=wall, friction=strength.friction, reduction=strength.reduction, model_blocks=len(ids),
                moving_blocks=sum(not s.fixed for s in sub.blocks), scene_blocks=problem.scene.n_blocks)
    return Run(judgement=j, results=results if record_every is not None else None, ids=tuple(ids))


def judge(scene: Scene, system: BlockSystem, blocks: frozenset, *, settings: DdaSettings,
          params: Optional[Params] = None, removed: frozenset = frozenset(),
          friction: Optional[float] = None, reduction: float = 1.0,
          record_every: Optional[int] = None):
    """Simulate the group's sub-model once and decide stable / unstable (`run_judgement` with
    the plan of ``settings``; ``settings.progress``, if set, is called with the judgement).

    With ``record_every`` the run is not stopped early and its `ddatai.Results` (of the
    sub-model) are returned too: ``(judgement, results, ids)``; otherwise the judgement alone.
    """
    problem = Problem.of(scene, system, settings=Settings(dda=settings), params=params)
    run = run_judgement(problem, blocks, Strength(friction=friction, reduction=reduction),
                        RunPlan.of(system, blocks, settings, params), removed=removed, record_every=record_every)
    if settings.progress is not None:
        settings.progress(run.judgement)
    if record_every is not None:
        return run.judgement, run.results, list(run.ids)
    return run.judgement


def verdict(t: np.ndarray, d: np.ndarray, *, delta: float, duration: float, end: RunEnd, cause: str = "",
             **fields) -> DdaJudgement:
    """The verdict of a run from its displacement history d(t) (`kgm.DdaSettings`): unstable if
    it was stopped or failed after moving, or if d(T) ≥ δ while its mean speed over the last
    quarter of the run is ≥ δ/T. A run stopped at rest (`RestCounter`) stays where it is until
    T: its history goes on flat, as the steps it did not take would have recorded it."""
    simulated, steps = float(t[-1]), len(t) - 1
    if end is RunEnd.AT_REST and t[-1] < duration:
        t, d = np.append(t, duration), np.append(d, d[-1])
    tq = 0.75 * t[-1]
    speed = float((d[-1] - np.interp(tq, t, d)) / max(t[-1] - tq, 1e-300))
    unstable = end in (RunEnd.STOPPED_EARLY, RunEnd.DIVERGED) or (d[-1] >= delta and speed >= delta / duration)
    return DdaJudgement(stable=not unstable, displacement=float(d[-1]), speed=speed, threshold=delta,
                        duration=duration, simulated=simulated, steps=steps, note=end.note(cause), end=end,
                        **fields)
