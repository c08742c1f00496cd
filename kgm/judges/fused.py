"""DDA judgements on the fused engine (`ddatai.fused`): each member's sub-model is settled by its
own equilibrium stage (`ddatai.start`), then every member runs in one launch, one thread each,
with its own Δt and iterations — as it would run alone — and with the stops of a judgement in
the kernel: past ``stop_ratio``·δ (stopped early), at rest for ``rest_steps`` steps, or at T.
The verdict is taken from each run's history as `kgm.judges.run.run_judgement` takes it. A
member whose step leaves what the engine does goes on on today's path from that step's start.

Which engine judges a batch is ``ddatai.fused.policy.choose_batch``'s: "fused" always, "auto"
where the batch pays the kernel (in the process already, loaded from Taichi's offline cache, or
compiled the first time on the machine; docs/guide/performance.md).

Like `kgm.judges.run`, this module imports Taichi only inside the function that runs the members.
"""

from __future__ import annotations

import copy
import dataclasses
import time
from dataclasses import dataclass
from typing import Optional

import numpy as np

from ddatai.params import Params

from ..kinds import RunEnd
from ..settings import DdaSettings
from .run import Report, RestCounter, RunPlan, block_displacements, block_speeds, group_size, sub_scene, verdict

#: steps a judgement's member takes in one launch at most: most runs end in the first (Example
#: II's group: 709–1,390 steps to fail), where ``ddatai.fused.engine.LAUNCH_STEPS`` took three
#: launches, each ~0.6 ms of the runner's Python (0.04 ms a sample of a study); the verdicts are
#: the same (each member runs as alone whatever the launches), the history buffer 32 kB a member
LAUNCH_STEPS = 2048


def judge_fused(members, blocks: frozenset, *, settings: DdaSettings, params: Optional[Params] = None,
                removed: frozenset = frozenset(), report: Report = None,
                submodels: Optional[dict] = None) -> Optional[list]:
    """The judgements of ``members`` (`kgm.judges.batch.Member`: a scene, its block system, a
    friction and a strength reduction) on the fused engine, in their order; None where the
    engine does not judge them (``Params.kernels`` "numpy" or "taichi", "auto" where the batch
    does not pay the kernel, or a sub-model with what the engine leaves to today's path:
    ``ddatai.fused.pack.covers``). ``report`` is called with each judgement; ``submodels``: as
    `prepare_fused` takes it."""
    prepared = prepare_fused(members, blocks, settings=settings, params=params, removed=removed,
                             submodels=submodels)
    return None if prepared is None else run_prepared(prepared, report=report)


def judged_apart(scene, system, blocks: frozenset, plan: RunPlan, *, removed: frozenset = frozenset(),
                 submodels: Optional[dict] = None) -> bool:
    """Whether the fused engine judges this group's batches whatever their size, one member too
    (``Params(kernels="fused")``, or the kernel in this process: ``choose_batch`` for one
    member's steps), its sub-model being one the engine runs (``ddatai.fused.pack.covers``):
    there each member pays its own stage and run. The sub-model is built into ``submodels``
    (`prepare_fused`'s), where the batches take it."""
    from ddatai.fused.pack import covers
    from ddatai.fused.policy import choose_batch

    prm = plan.params
    if choose_batch(prm, member_steps=plan.duration / (prm.dt if prm.dt is not None else prm.dt_max))[0] != "fused":
        return False
    sub, ids = sub_scene(scene, system, blocks, removed=removed, free_neighbours=plan.free_neighbours)
    model, _ = _submodel({} if submodels is None else submodels, scene, system, plan, sub, ids, prm)
    return covers(model) is None


def _submodel(shared: dict, scene, system, plan: RunPlan, sub, ids, prm) -> tuple:
    """(the model of the sub-scene ``sub`` of ``scene``'s group under ``prm``, whether it was
    built now): built once into ``shared`` for the sub-scenes that differ at most in their
    joints' values (`ddatai.memo.scene_key`: a study's samples, a bisection's probes), keyed
    by that, the plan's free neighbours, the sub-model's blocks and ``prm``; a sub-scene
    without a key (it holds a function) by its scene and block system."""
    from ddatai.memo import scene_key
    from ddatai.model import build_model

    geometry = scene_key(sub)
    key = (geometry if geometry is not None else (id(scene), id(system)), plan.free_neighbours, tuple(ids), prm)
    if key in shared:
        return shared[key], False
    shared[key] = build_model(sub, prm)
    return shared[key], True


@dataclass(frozen=True, kw_only=True, eq=False)
class Prepared:
    """A batch of judgements made ready for the fused engine (`prepare_fused`): each member's
    sub-model settled by its own equilibrium stage, as a run of the engine, with what its
    verdict needs. Picklable: a study's worker processes prepare batches in NumPy and one
    process, which has loaded the kernel, runs them (`run_prepared`)."""

    runs: list
    """One ``ddatai.fused.pack.Member`` a member."""
    plans: list
    """Each member's `RunPlan`."""
    fields: list
    """Each member's figures for its `DdaJudgement` (friction, reduction, model, moving and
    scene blocks, batch)."""
    seconds: float
    """Wall time of the preparation (the sub-models and their stages) [s]."""

    def __reduce__(self):
        # from a study's preparing worker to its runner: the members' start states (two dozen
        # small arrays each) go field by field, one array a field for the batch; pickled one
        # by one they cost ~85 µs a sample of the two processes' CPU
        runs = [copy.copy(run) for run in self.runs]
        for run in runs:
            run.state = None
        return _unpickled, (runs, _columns([run.state for run in self.runs]), self.plans, self.fields, self.seconds)


def _unpickled(runs: list, states: tuple, plans: list, fields: list, seconds: float) -> Prepared:
    for run, state in zip(runs, _rows(states)):
        run.state = state
    return Prepared(runs=runs, plans=plans, fields=fields, seconds=seconds)


def _columns(objects: list) -> tuple:
    """Instances of one dataclass as columns (`_rows` gives them back, bit for bit): a field
    that is an array of one dtype and one shape but its length in every instance, their
    concatenation and lengths; a dataclass field, its columns; any other, its values."""
    kind = type(objects[0]) if objects else None
    if kind is None or not dataclasses.is_dataclass(kind) or any(type(o) is not kind for o in objects):
        return ("values", list(objects))
    columns = {}
    for f in dataclasses.fields(kind):
        values = [getattr(o, f.name) for o in objects]
        first = values[0]
        if dataclasses.is_dataclass(first) and not isinstance(first, type):
            columns[f.name] = _columns(values)
        elif isinstance(first, np.ndarray) and first.ndim and all(
                isinstance(v, np.ndarray) and v.ndim and v.dtype == first.dtype and v.shape[1:] == first.shape[1:]
                for v in values):
            columns[f.name] = ("joined", np.concatenate(values), np.cumsum([0] + [len(v) for v in values]).tolist())
        else:
            columns[f.name] = ("values", values)
    return ("fields", kind, len(objects), columns)


def _rows(columns: tuple) -> list:
    """The instances of `_columns` (a joined field's arrays are disjoint views of its column)."""
    if columns[0] == "values":
        return columns[1]
    _, kind, n, fields = columns
    values = {}
    for name, c in fields.items():
        if c[0] == "fields":
            values[name] = _rows(c)
        elif c[0] == "joined":
            values[name] = [c[1][a:b] for a, b in zip(c[2], c[2][1:])]
        else:
            values[name] = c[1]
    return [kind(**{name: v[k] for name, v in values.items()}) for k in range(n)]


def prepare_fused(members, blocks: frozenset, *, settings: DdaSettings, params: Optional[Params] = None,
                  removed: frozenset = frozenset(), submodels: Optional[dict] = None) -> Optional[Prepared]:
    """The batch of `judge_fused` up to its launch, in NumPy (no Taichi): the sub-models built
    and settled, or None where the fused engine does not judge them (`judge_fused`).
    ``submodels``: a dict the caller keeps across the batches of one problem (a bisection's
    rounds, whose scene and block system stay alive), in which each scene's sub-model is built
    once; each member takes its own joints from it (`ddatai.model.Model.with_joints`). The
    members whose sub-scenes differ at most in their joints share one sub-model within the
    batch too (a study's samples, each its own scene)."""
    from ddatai.fused.pack import Member as Run
    from ddatai.fused.pack import covers
    from ddatai.fused.policy import choose_batch

    if not members:
        return Prepared(runs=[], plans=[], fields=[], seconds=0.0)
    # one plan for the members whose groups have the same area (the probes of a bisection
    # round, a study's samples of one geometry): the plan depends on the system through it alone
    by_size: dict = {}
    plans = []
    for m in members:
        size = group_size(m.system, blocks)
        if size not in by_size:
            by_size[size] = RunPlan.of(m.system, blocks, settings, params)
        plans.append(by_size[size])
    prm = plans[0].params
    steps = sum(p.duration / (prm.dt if prm.dt is not None else prm.dt_max) for p in plans)
    if choose_batch(prm, member_steps=steps)[0] != "fused":
        return None
    start = time.perf_counter()
    built, shared = [], ({} if submodels is None else submodels)
    for m, plan in zip(members, plans):
        sub, ids = sub_scene(m.scene, m.system, blocks, removed=removed, free_neighbours=plan.free_neighbours,
                             friction=m.friction, reduction=m.reduction)
        # the members of one geometry share the sub-model's blocks: built once, each member
        # with its own joints (`ddatai.model.Model.with_joints`)
        model, fresh = _submodel(shared, m.scene, m.system, plan, sub, ids, prm)
        model = model if fresh else model.with_joints(sub.joints)
        if covers(model) is not None:
            return None
        built.append((sub, ids, model))
    from ddatai.limit_batch import settle_many

    # each member settled by its own equilibrium stage: it decides what the model holds (the
    # stages' limit-equilibrium screens solved side by side first, `ddatai.limit_batch`)
    models = [model for _, _, model in built]
    states = settle_many(models) if prm.initial_equilibrium else [m.initial_state() for m in models]
    runs, fields = [], []
    for m, (sub, ids, model), plan, state in zip(members, built, plans, states):
        runs.append(Run(model=model, state=state, t_end=plan.duration, stop_at=plan.stop_at,
                        rest_limit=-1.0 if plan.rest_speed is None else plan.rest_speed,
                        rest_steps=plan.rest_steps, group=tuple(ids.index(b) for b in sorted(blocks))))
        fields.append(dict(friction=m.friction, reduction=m.reduction, model_blocks=len(ids),
                           moving_blocks=sum(not s.fixed for s in sub.blocks), scene_blocks=m.scene.n_blocks,
                           batch=len(members)))
    return Prepared(runs=runs, plans=plans, fields=fields, seconds=time.perf_counter() - start)


def run_prepared(prepared: Prepared, *, report: Report = None) -> list:
    """The judgements of a `prepare_fused` batch: its members in one launch of the fused engine
    (which this process loads the first time, `ddatai.fused.engine`), each verdict taken from
    its run's history; ``report`` is called with each."""
    from ddatai.fused import engine
    from ddatai.fused import layout

    if not prepared.runs:
        return []
    start = time.perf_counter()
    # a member whose stage released blocks in doubt runs on today's path from its start: their
    # first steps take the resolved Δt of `ddatai.in_doubt`, which the fused engine does not apply
    doubt = [bool(run.state.in_doubt.any()) for run in prepared.runs]
    # the verdicts need each run's history, and the state only of a run handed over (`_go_on`)
    fused = iter(engine.run([r for r, d in zip(prepared.runs, doubt) if not d], arch=prepared.plans[0].params.arch,
                            launch_steps=LAUNCH_STEPS, states=False) if not all(doubt) else [])
    outcomes = [_from_start(run) if d else next(fused) for run, d in zip(prepared.runs, doubt)]
    ends = {engine.STATUS[layout.STOP_MOVED]: RunEnd.STOPPED_EARLY, engine.STATUS[layout.STOP_REST]: RunEnd.AT_REST}
    wall = prepared.seconds + time.perf_counter() - start
    out = []
    for plan, run, fields, o in zip(prepared.plans, prepared.runs, prepared.fields, outcomes):
        times = np.concatenate([[0.0], o.history[:, 0]])
        disp = np.concatenate([[0.0], o.history[:, 1]])
        end, cause = ends.get(o.status, RunEnd.DURATION), ""
        if o.status == engine.STATUS[layout.DIVERT]:
            times, disp, end, cause = _go_on(o, run, times, disp, plan)
        j = verdict(times, disp, delta=plan.delta, duration=plan.duration, end=end, cause=cause, wall_time=wall,
                    **fields)
        if report is not None:
            report(j)
        out.append(j)
    return out


def _from_start(run):
    """A stand-in for the fused engine's outcome of a member it does not run (`run_prepared`):
    handed over at its settled start, nothing recorded, no step at rest yet."""
    from types import SimpleNamespace

    from ddatai.fused import engine
    from ddatai.fused import layout

    return SimpleNamespace(status=engine.STATUS[layout.DIVERT], history=np.zeros((0, 2)), state=run.state,
                           model=run.model, quiet=0)


def _go_on(outcome, run, times, disp, plan: RunPlan):
    """A member handed over by the fused engine, run on today's path from where it stopped, with
    the stops of `kgm.judges.run.run_judgement`. Returns its whole history and how it ended."""
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
    duration = plan.duration
    while state.time < duration * (1 - 1e-12):
        try:
            state, _ = stepper.step(state, t_end=duration)
        except SimulationError as err:
            if max(disp) < plan.delta:
                raise
            return np.array(times), np.array(disp), RunEnd.DIVERGED, str(err)
        times.append(state.time)
        disp.append(float(np.max(moved(state.vertex_xy))))
        if disp[-1] > run.stop_at:
            return np.array(times), np.array(disp), RunEnd.STOPPED_EARLY, ""
        if rest is not None and rest.update(np.array([speeds(state.block_velocity).max(initial=0.0)]))[0]:
            return np.array(times), np.array(disp), RunEnd.AT_REST, ""
    return np.array(times), np.array(disp), RunEnd.DURATION, ""
