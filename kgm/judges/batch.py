"""Many DDA judgements in one run (docs/guide/performance.md, "Batched studies"): the probes of
a bisection round or the samples of a probabilistic study, each a sub-model of a few blocks that
differs from the others only in its joints, run side by side (`ddatai.batch`) with the verdict
of each taken as `kgm.judges.run.run_judgement` takes it, under the same `RunPlan`.

Like `kgm.judges.run`, this module imports Taichi (through `ddatai.simulate`) only inside the
functions that run a simulation.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Optional

import numpy as np

from ddatai.params import Params
from ddatai.scene import Scene

from ..build import Problem
from ..kinds import RunEnd
from ..settings import DdaSettings
from ..strength import Strength
from ..system import BlockSystem
from .fused import judge_fused
from .run import (Report, RestCounter, RunPlan, StopRun, block_displacements, block_speeds, run_judgement, sub_scene,
                  verdict)


class _Cut(Exception):
    """Raised from the progress callback of an exact batch whose step had its Δt cut."""


# ---------------------------------------------------------------------- many judgements in one run
@dataclass(frozen=True, kw_only=True, eq=False)
class Member:
    """One judgement of a batched run (`judge_members`): the group in ``scene`` (its
    ``system``), with every joint's friction angle ``friction`` [degrees] if given and tanφ, c
    divided by ``reduction`` [-], as `kgm.judge` takes them."""

    scene: Scene
    system: BlockSystem
    friction: Optional[float] = None
    reduction: float = 1.0

    @property
    def strength(self) -> Strength:
        return Strength(friction=self.friction, reduction=self.reduction)


def judge_many(scene: Scene, system: BlockSystem, blocks: frozenset, probes, *, settings: DdaSettings,
               params: Optional[Params] = None, removed: frozenset = frozenset(), report: Report = None,
               submodels: Optional[dict] = None) -> list:
    """Judge the group at several strengths ``probes`` (a sequence of ``(friction, reduction)``
    as `kgm.judge` takes them) in one run (`judge_members`; ``submodels`` as it takes it).
    Returns the judgements in the order of ``probes``."""
    members = [Member(scene=scene, system=system, friction=None if f is None else float(f), reduction=float(r))
               for f, r in probes]
    return judge_members(members, blocks, settings=settings, params=params, removed=removed, report=report,
                         submodels=submodels)


def judge_members(members, blocks: frozenset, *, settings: DdaSettings, params: Optional[Params] = None,
                  removed: frozenset = frozenset(), exact: bool = False, report: Report = None,
                  submodels: Optional[dict] = None) -> list:
    """Judge the same group in several members — the scene at several strengths, or the scenes
    of a probabilistic study's samples, which differ only in their joints — in one run: the
    sub-models side by side (`ddatai.batch`), each with the constants of its own model, so that
    each verdict is the one `judge` gives (the members share the step's Δt: a fixed Δt stays;
    the automatic one follows the fastest member, a shorter step than it needs alone). The run
    ends when every member has moved past ``stop_ratio``·δ or come to rest (`kgm.judges.run.RestCounter`),
    or at T. A step of a few blocks costs
    its fixed overhead, so the members share it (docs/guide/performance.md, "Batched studies").

    ``exact``: every verdict is the one its own run gives, not only as a rule: with a fixed Δt
    (`ddatai.Params.dt`) the members take the same steps as alone until one of them makes the
    run cut Δt (a member that fails and falls); the run stops there and the members not yet
    decided are judged again, in two halves (halved again where a half cuts Δt again, down to
    one member a run), so that a probabilistic study's table does not depend on how its samples
    were grouped. With the automatic Δt, one run a member.

    Falls back to one run a member (`run_judgement`) where members cannot share a run (a water
    table, shaking, sub-models whose geometry, δ or model constants differ, a single member), and
    for the members that had not failed when a batched run diverged. ``report`` is called with
    each judgement as it is made; ``submodels``: a dict kept across the batches of one problem,
    in which the fused engine's sub-models are built once (`kgm.judges.fused.prepare_fused`).
    Returns the judgements in the order of ``members``.
    """
    # the fused engine (ddatai.fused) where it pays: every member in its own thread of one launch,
    # as alone (exact by construction)
    fused = judge_fused(members, blocks, settings=settings, params=params, removed=removed, report=report,
                        submodels=submodels)
    if fused is not None:
        return fused
    from ddatai.batch import batch_model, combined_state, member_constants, member_states, side_by_side
    from ddatai.model import build_model
    from ddatai.results import SimulationError
    from ddatai.run import simulate
    from ddatai.limit_batch import settle_many

    def alone(which):
        out = {}
        for k in which:
            m = members[k]
            out[k] = run_judgement(Problem.of(m.scene, m.system, params=params), blocks, m.strength,
                                   RunPlan.of(m.system, blocks, settings, params), removed=removed).judgement
            if report is not None:
                report(out[k])
        return out

    def one_by_one():
        done = alone(range(len(members)))
        return [done[k] for k in range(len(members))]

    plans = [RunPlan.of(m.system, blocks, settings, params) for m in members]
    prm = plans[0].params
    if len(members) < 2 or any(m.scene.water is not None or m.scene.ground_acceleration is not None
                               for m in members) or (exact and prm.dt is None):
        return one_by_one()
    subs = []
    for m in members:
        sub, ids = sub_scene(m.scene, m.system, blocks, removed=removed, free_neighbours=plans[0].free_neighbours,
                             friction=m.friction, reduction=m.reduction)
        subs.append((sub, ids))
    deltas = {plan.delta for plan in plans}
    shapes = {tuple(ids) for _, ids in subs}
    geometry = {np.concatenate([b.vertices for b in sub.blocks]).tobytes() for sub, _ in subs}
    if len(deltas) != 1 or len(shapes) != 1 or len(geometry) != 1:
        return one_by_one()
    models = [build_model(sub, prm) for sub, _ in subs]
    constants = {member_constants(m) for m in models}
    if len(constants) != 1:
        return one_by_one()
    ((w0, penalty),), (delta,), (ids,) = constants, deltas, shapes
    plan = plans[0]
    duration = plan.duration
    # a member that fails keeps moving until the run ends: at most ½·g·T² of free fall, and
    # the speed it left its support with (≤ g·T) for T: members farther apart cannot meet
    first = subs[0][0]
    xy = np.concatenate([b.vertices for b in first.blocks])
    gap = float(np.max(xy.max(axis=0) - xy.min(axis=0))) + 1.5 * first.gravity * duration ** 2
    # each member settled by its own equilibrium stage: the stage decides per model what it
    # holds, releases or welds (`ddatai.batch.combined_state`)
    start = time.perf_counter()
    states = settle_many(models) if prm.initial_equilibrium else [m.initial_state() for m in models]
    pos = [list(ids).index(b) for b in sorted(blocks)]
    stop_at = plan.stop_at
    n_members = len(members)
    times = [[0.0] for _ in members]   # each member's history: time [s] ...
    disp = [[0.0] for _ in members]    # ... and the largest displacement of its group [m]
    decided = np.zeros(n_members, bool)  # moved past stop_at (unstable, stopped early) or at rest
    rest = None  # each member's steps at rest, counted as its own run counts them (`judge`)
    if plan.rest_speed is not None:
        rest = RestCounter(n_members, plan.rest_speed, plan.rest_steps)
    resting = np.zeros(n_members, bool)
    cut = False      # (exact) a step's Δt was cut: the members not decided are judged again
    failure = None
    active = list(range(n_members))  # the members not decided
    while active:
        # the members not decided, side by side; once half of them are decided the others go
        # on without them, from where they are (`ddatai.batch.member_states`)
        batch = side_by_side([subs[k][0] for k in active], gap=gap)
        model = batch_model(batch, prm, w0=w0, penalty=penalty)
        own = [models[k] for k in active]
        initial = combined_state(batch, model, own, [states[k] for k in active])
        moved = block_displacements(model, (batch.block_offset[:-1, None] + np.array(pos)[None, :]).ravel())
        run_t, run_d = [], []  # this run's times and its members' displacements
        passed = np.full(len(active), -1)  # the record of this run at which each was decided
        last = [None]
        if rest is not None:
            speeds = block_speeds(model)
            members_of = np.array(active)

        def progress(state, record):
            if exact and record.dt_cuts > 0:
                raise _Cut
            # as `judge`: a member's displacement is the largest of its group's blocks'
            d = moved(state.vertex_xy).reshape(len(active), len(pos)).max(axis=1)
            run_t.append(state.time)
            run_d.append(d)
            passed[(passed < 0) & (d > stop_at)] = len(run_t) - 1
            if rest is not None:
                fastest = np.maximum.reduceat(speeds(state.block_velocity), batch.block_offset[:-1])
                rested = (passed < 0) & rest.update(fastest, members_of)
                resting[members_of[rested]] = True
                passed[rested] = len(run_t) - 1
            left = np.count_nonzero(passed < 0)
            if not left:
                raise StopRun
            if 2 * left <= len(active) and len(active) > 1:
                last[0] = state
                raise StopRun

        try:
            simulate(batch.scene, model.params, duration=duration, progress=progress, record_every=10 ** 9,
                     model=model, initial_state=initial)
        except StopRun:
            pass
        except _Cut:
            cut = True
        except SimulationError as err:
            failure = err
        # each member's history of this run, up to the record at which it was decided
        run_d = np.array(run_d).reshape(len(run_t), len(active))
        for i, k in enumerate(active):
            end = passed[i] + 1 if passed[i] >= 0 else len(run_t)
            times[k] += run_t[:end]
            disp[k] += run_d[:end, i].tolist()
            decided[k] = passed[i] >= 0
        left = [i for i, k in enumerate(active) if not decided[k]]
        if last[0] is None or not left:
            break
        for i, s in zip(left, member_states(batch, model, own, last[0], which=left)):
            states[active[i]] = s
        active = [active[i] for i in left]
    wall = time.perf_counter() - start
    out, rerun = {}, []
    for k, m in enumerate(members):
        end = (RunEnd.AT_REST if resting[k] else RunEnd.STOPPED_EARLY) if decided[k] else RunEnd.DURATION
        cause = ""
        if cut and not decided[k]:
            rerun.append(k)  # not decided when the run left the steps it takes alone
            continue
        if failure is not None and not decided[k]:
            if max(disp[k]) < delta:
                rerun.append(k)  # it had not failed when the run diverged: judged on its own
                continue
            end, cause = RunEnd.DIVERGED, str(failure)
        out[k] = verdict(np.array(times[k]), np.array(disp[k]), delta=delta, duration=duration, end=end,
                         cause=cause, wall_time=wall, friction=m.friction, reduction=m.reduction,
                         model_blocks=len(ids), moving_blocks=sum(not b.fixed for b in first.blocks),
                         scene_blocks=m.scene.n_blocks, batch=n_members)
        if report is not None:
            report(out[k])
    if cut and len(rerun) > 1:
        # which member made the step cut Δt is not known: the undecided ones are judged again
        # in two halves (a half that cuts again is halved again, down to runs of one member)
        for part in (rerun[:len(rerun) // 2], rerun[len(rerun) // 2:]):
            again = judge_members([members[k] for k in part], blocks, settings=settings, params=params,
                                  removed=removed, exact=True, report=report)
            out.update(zip(part, again))
    else:
        out.update(alone(rerun))
    return [out[k] for k in range(len(members))]
