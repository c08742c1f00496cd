"""DDA judgements on the fused engine (`ddatai.fused`): each member's sub-model is settled by its
own equilibrium stage (`ddatai.start`), then every member runs in one launch, one thread each,
with its own Δt and iterations — as it would run alone — and with the stops of a judgement in
the kernel: past ``stop_ratio``·δ (stopped early), at rest for ``rest_steps`` steps, or at T.
The verdict is taken from each run's history as `kgm.judgement.judge` takes it. A member whose
step leaves what the engine does goes on on today's path from that step's start.

Like `kgm.dda`, this module imports Taichi only inside the function that runs the members.
"""

from __future__ import annotations

import math
import time
from typing import Optional

import numpy as np

from ddatai.params import Params

from .judgement import RestCounter, _verdict, block_displacements, block_speeds, group_size, run_params, sub_scene
from .kinds import RunEnd
from .settings import DdaSettings


def judge_fused(members, blocks: frozenset, *, settings: DdaSettings, params: Optional[Params] = None,
                removed: frozenset = frozenset()) -> Optional[list]:
    """The judgements of ``members`` (`kgm.batched.Member`: a scene, its block system, a
    friction and a strength reduction) on the fused engine, in their order; None where the
    engine does not run them (``Params.kernels`` "numpy" or "taichi", or a sub-model with what
    the engine leaves to today's path: ``ddatai.fused.pack.covers``)."""
    from ddatai.fused.pack import Member as Run
    from ddatai.fused.pack import covers
    from ddatai.model import build_model
    from ddatai.start import settle
    from ddatai.step import Stepper

    prm = run_params(params, settings)
    if prm.kernels not in ("auto", "fused") or prm.arch not in ("cpu", "cuda", "gpu"):
        return None
    start = time.perf_counter()
    plans = []
    for m in members:
        sub, ids = sub_scene(m.scene, m.system, blocks, removed=removed, free_neighbours=settings.free_neighbours,
                             friction=m.friction, reduction=m.reduction)
        model = build_model(sub, prm)
        if covers(model) is not None:
            return None
        delta = settings.displacement_ratio * group_size(m.system, blocks)
        duration = settings.duration or math.sqrt(2.0 * delta / settings.acceleration_resolution)
        plans.append((m, sub, ids, model, delta, duration))
    runs = []
    for m, sub, ids, model, delta, duration in plans:
        # each member settled by its own equilibrium stage: it decides what the model holds
        state = settle(Stepper(model), model.initial_state())[0] if prm.initial_equilibrium else model.initial_state()
        rest = settings.rest_ratio * delta / duration if settings.rest_ratio > 0.0 else -1.0
        runs.append(Run(model=model, state=state, t_end=duration, stop_at=settings.stop_ratio * delta,
                        rest_limit=rest, rest_steps=settings.rest_steps,
                        group=tuple(ids.index(b) for b in sorted(blocks))))
    from ddatai.fused import engine

    outcomes = engine.run(runs, arch=prm.arch)
    wall = time.perf_counter() - start
    out = []
    for (m, sub, ids, model, delta, duration), run, o in zip(plans, runs, outcomes):
        times = np.concatenate([[0.0], o.history[:, 0]])
        disp = np.concatenate([[0.0], o.history[:, 1]])
        end, cause = {"moved": RunEnd.STOPPED_EARLY, "at rest": RunEnd.AT_REST}.get(o.status, RunEnd.DURATION), ""
        if o.status == "diverted":
            times, disp, end, cause = _go_on(o, run, times, disp, delta, duration, settings)
        j = _verdict(times, disp, delta=delta, duration=duration, end=end, cause=cause, wall_time=wall,
                     friction=m.friction, reduction=m.reduction, model_blocks=len(ids),
                     moving_blocks=sum(not s.fixed for s in sub.blocks), scene_blocks=m.scene.n_blocks,
                     batch=len(members))
        if settings.progress is not None:
            settings.progress(j)
        out.append(j)
    return out


def _go_on(outcome, run, times, disp, delta, duration, settings):
    """A member handed over by the fused engine, run on today's path from where it stopped, with
    the stops of `kgm.judgement.judge`. Returns its whole history and how it ended."""
    from ddatai.results import SimulationError
    from ddatai.step import Stepper

    model = run.model
    stepper = Stepper(model)
    if outcome.model.penalty != model.penalty:
        stepper.model, stepper.penalty_warned = outcome.model, True
    moved = block_displacements(model, list(run.group))
    speeds = block_speeds(model)
    rest = RestCounter(1, run.rest_limit, run.rest_steps) if run.rest_limit >= 0 else None
    if rest is not None:
        rest.quiet[:] = outcome.quiet
    times, disp = list(times), list(disp)
    state = outcome.state
    while state.time < duration * (1 - 1e-12):
        try:
            state, _ = stepper.step(state, t_end=duration)
        except SimulationError as err:
            if max(disp) < delta:
                raise
            return np.array(times), np.array(disp), RunEnd.DIVERGED, str(err)
        times.append(state.time)
        disp.append(float(np.max(moved(state.vertex_xy))))
        if disp[-1] > run.stop_at:
            return np.array(times), np.array(disp), RunEnd.STOPPED_EARLY, ""
        if rest is not None and rest.update(np.array([speeds(state.block_velocity).max(initial=0.0)]))[0]:
            return np.array(times), np.array(disp), RunEnd.AT_REST, ""
    return np.array(times), np.array(disp), RunEnd.DURATION, ""
