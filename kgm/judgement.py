"""One DDA judgement of a group (the seed paper's developed method; docs/kgm/method.md §6): the
sub-model of the group and the blocks it touches, one run, its verdict. `kgm.dda` builds the
factor of safety and the critical friction angle on it, `kgm.batched` runs many at once.

This module imports Taichi (through `ddatai.simulate`) only inside the function that runs a
simulation, so ``import kgm`` stays light.
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
from .kinds import RunEnd
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
    """'stopped early' (past `kgm.DdaSettings.stop_ratio`·δ), 'at rest' (stopped as stable,
    `kgm.judgement.RestCounter`) or the cause of a divergence after the group had failed
    (``end`` says which)."""
    batch: int = 1
    """Members of the run it was judged in (`judge_many`: several strengths side by side in one
    model; ``wall_time`` is then that run's) [-]."""
    end: RunEnd = RunEnd.DURATION
    """How the run ended (`kgm.kinds.RunEnd`): its duration T, at rest, stopped early, or
    diverged after the group had failed."""


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
    (`ddatai.kinematics.block_radius`, at the model's start) times its rotation and strain
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
    point loads given as functions of time, `kgm.blocks.build_block_system`), and a step from rest
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

    if record_every is None:
        # the fused engine (ddatai.fused) where it runs the sub-model: the run in few launches
        from .batched import Member
        from .fused_runs import judge_fused

        fused = judge_fused([Member(scene=scene, system=system, friction=friction, reduction=reduction)], blocks,
                            settings=settings, params=params, removed=removed)
        if fused is not None:
            return fused[0]
    sub, ids = sub_scene(scene, system, blocks, removed=removed, free_neighbours=settings.free_neighbours,
                         friction=friction, reduction=reduction)
    prm = run_params(params, settings)
    delta = settings.displacement_ratio * group_size(system, blocks)
    duration = settings.duration or math.sqrt(2.0 * delta / settings.acceleration_resolution)
    model = build_model(sub, prm)  # built once: its origin maps the positions, simulate runs it
    moved = block_displacements(model, [ids.index(b) for b in sorted(blocks)])
    stop_at = settings.stop_ratio * delta if record_every is None else math.inf
    times, disp = [0.0], [0.0]
    rest = None
    if record_every is None and settings.rest_ratio > 0.0:
        rest = RestCounter(1, settings.rest_ratio * delta / duration, settings.rest_steps)
        speeds = block_speeds(model)
    resting = [False]

    def progress(state, record):
        # the group's displacement: the largest of its members'
        times.append(state.time)
        disp.append(float(np.max(moved(state.vertex_xy))))
        if disp[-1] > stop_at:
            raise _StopRun
        if rest is not None and rest.update(np.array([speeds(state.block_velocity).max(initial=0.0)]))[0]:
            resting[0] = True
            raise _StopRun

    t0 = time.perf_counter()
    end, cause = RunEnd.DURATION, ""
    results = None
    try:
        results = simulate(sub, prm, duration=duration, progress=progress,
                           record_every=record_every or 10 ** 9, model=model)
    except _StopRun:
        end = RunEnd.AT_REST if resting[0] else RunEnd.STOPPED_EARLY
    except SimulationError as err:
        if max(disp) < delta:
            raise
        end, cause = RunEnd.DIVERGED, str(err)
        results = err.results
    wall = time.perf_counter() - t0
    j = _verdict(np.array(times), np.array(disp), delta=delta, duration=duration, end=end, cause=cause,
                 wall_time=wall,
                 friction=friction, reduction=reduction, model_blocks=len(ids),
                 moving_blocks=sum(not s.fixed for s in sub.blocks), scene_blocks=scene.n_blocks)
    if settings.progress is not None:
        settings.progress(j)
    if record_every is not None:
        return j, results, ids
    return j


def _verdict(t: np.ndarray, d: np.ndarray, *, delta: float, duration: float, end: RunEnd, cause: str = "",
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
