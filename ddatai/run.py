"""`simulate`: a DDA run from a scene to its results (docs/method/dda.md §0): the model is
built and checked, brought to equilibrium (`ddatai.start`), and advanced step by step
(`ddatai.step`) while a ``Recorder`` keeps frames and step records; checkpoints and Ctrl-C are
handled here (`ddatai.io.checkpoint`).
"""

from __future__ import annotations

import dataclasses
from typing import Callable, Optional

import numpy as np

from .io.checkpoint import DeferInterrupt, RunTargets, read_checkpoint, write_checkpoint
from .layout import V0
from .model import Model, State, build_model
from .params import Params
from .recorder import Recorder
from .results import Results, SimulationError, SimulationInterrupted, block_materials, run_metadata
from .scene import Scene
from .start import settle
from .step import Stepper, StepOutcome


def simulate(scene: Scene, params: Optional[Params] = None, duration: Optional[float] = None,
             steps: Optional[int] = None, record_every: Optional[int] = None, *,
             record_contacts: Optional[bool] = None,
             progress: Optional[Callable[[State, tuple], None]] = None,
             checkpoint=None, checkpoint_every: Optional[int] = None, resume=None,
             model: Optional[Model] = None, initial_state: Optional[State] = None) -> Results:
    """Run a DDA simulation of ``scene``.

    Parameters
    ----------
    scene : the model to run (validated before any work).
    params : numerical parameters; ``None`` = `Params()` (automatic time step and penalty).
    duration : simulated time to reach [s]; the last step is shortened to end on it.
    steps : number of steps to take, counted from the start of the run (when both are given,
        whichever comes first).
    record_every : record a frame every this many steps (and always the last); default 1.
    record_contacts : also record contact points, states and forces per frame; default False.
    progress : called as ``progress(state, step_record)`` after every step.
    checkpoint : path of a checkpoint file (`ddatai.io.checkpoint`), written every
        ``checkpoint_every`` steps (when given) and when the run is interrupted; each write
        replaces the last.
    checkpoint_every : steps between two checkpoints (each holds every frame recorded so far, so
        one every few hundred steps or more keeps their cost small).
    model : the `Model` of ``scene`` and ``params`` when the caller has built it already
        (`ddatai.build_model`; kgm reads the model's origin before the run): it is not built
        again. It must be the model of this scene and these parameters.
    initial_state : a `State` of ``model`` to start from instead of its initial state and
        equilibrium stage (a batch of members each settled by its own stage,
        `ddatai.batch.combined_state`); needs ``model``.
    resume : a checkpoint to continue from, written by a run of the same scene and ``params``.
        The run goes on to its own ``duration`` / ``steps`` (unless new ones are given) with its
        recording options, and returns the whole run's results: the same numbers as a run that
        was never stopped, bit for bit, when it resumes from a periodic checkpoint (a run that
        writes them starts a new solver after each, as the resumed run does). From the
        checkpoint of an interrupt, the same holds with the SuperLU solver; PARDISO's fresh
        analysis of the resumed step changes the last bits.

    Returns
    -------
    Results. A run that diverges raises `SimulationError` (step, cause, and the results
    recorded so far in ``.results``). Ctrl-C raises `SimulationInterrupted` (a
    `KeyboardInterrupt`) with the results recorded so far in ``.results``, after writing a
    checkpoint if ``checkpoint`` is given.
    """
    if duration is not None and not (np.isfinite(duration) and duration > 0):
        raise ValueError(f"simulate: duration must be a finite number > 0 s, got {duration!r}")
    if steps is not None and not (isinstance(steps, (int, np.integer)) and steps > 0):
        raise ValueError(f"simulate: steps must be a positive integer, got {steps!r}")
    if record_every is not None and not (isinstance(record_every, (int, np.integer)) and record_every > 0):
        raise ValueError(f"simulate: record_every must be a positive integer, got {record_every!r}")
    if checkpoint_every is not None:
        if not (isinstance(checkpoint_every, (int, np.integer)) and checkpoint_every > 0):
            raise ValueError(f"simulate: checkpoint_every must be a positive integer, got {checkpoint_every!r}")
        if checkpoint is None:
            raise ValueError("simulate: checkpoint_every needs a checkpoint path")
    if initial_state is not None and (model is None or resume is not None):
        raise ValueError("simulate: initial_state needs the model it is a state of (model=), and no resume")
    if model is None:
        model = build_model(scene, params)
    elif params is not None and model.params != params:
        raise ValueError("simulate: the model given was built with other parameters than ``params``")
    if resume is not None:
        saved = read_checkpoint(resume, model)
        t = saved.targets
        for name, given, stored in (("record_every", record_every, t.record_every),
                                    ("record_contacts", record_contacts, t.record_contacts)):
            if given is not None and given != stored:
                raise ValueError(f"simulate: the checkpoint was recorded with {name}={stored!r}; "
                                 f"a resumed run keeps it (got {given!r})")
        if duration is None and steps is None:
            duration, steps = t.duration, t.steps
        record_every, record_contacts = t.record_every, t.record_contacts
    record_every = 1 if record_every is None else int(record_every)
    record_contacts = bool(record_contacts)
    if duration is None and steps is None:
        raise ValueError("simulate: give a duration [s] or a number of steps")
    targets = RunTargets(duration=None if duration is None else float(duration),
                         steps=None if steps is None else int(steps),
                         record_every=record_every, record_contacts=record_contacts)
    stepper = Stepper(model)
    recorder = Recorder(model, record_contacts)
    from .fused.policy import choose

    engine, why = choose(model, steps=steps, duration=duration, record_contacts=record_contacts,
                         checkpoint=checkpoint is not None, resume=resume is not None)
    recorder.metadata = run_metadata(scene, model, engine=engine, why=why)
    recorder.block_material = block_materials(scene)[1]
    if resume is not None:
        state = saved.state
        recorder.seed(saved.results, state)
    elif initial_state is not None:
        if initial_state.vertex_xy.shape != model.vertex_xy0.shape:
            raise ValueError(f"simulate: initial_state has {len(initial_state.vertex_xy)} vertices, the model "
                             f"{model.n_vertices}")
        state = initial_state
        recorder.frame(state, model.block_geometry(state.vertex_xy)["centroid"])
    else:
        state = model.initial_state()
        if model.params.initial_equilibrium:
            state, start = settle(stepper, state)
            recorder.start.append(dataclasses.astuple(start))
        recorder.frame(state, model.block_geometry(state.vertex_xy)["centroid"])
    if engine == "fused" and state.in_doubt.any():
        # the first steps of blocks the stage released in doubt take the resolved Δt of
        # `ddatai.in_doubt`, which the fused engine does not apply: today's path runs them
        engine = "numpy" if model.numpy_path else "taichi"
        why = (f"{int(state.in_doubt.sum())} blocks released in doubt by the equilibrium stage: their "
               f"first steps take the resolved time step of today's path (the fused engine has none)")
        recorder.metadata = run_metadata(scene, model, engine=engine, why=why)

    def finished(s: State) -> bool:
        return (duration is not None and s.time >= duration * (1 - 1e-12)) or \
               (steps is not None and s.step >= steps)

    try:
        if engine == "fused" and not finished(state):
            # the fused engine (ddatai.fused): the run in few launches; a step it hands over
            # goes on here, on today's path, from that step's start
            from .fused import single

            state, fused_model, _ = single.run(model, state, recorder, duration=duration, steps=steps,
                                               record_every=record_every, progress=progress)
            if fused_model.penalty != model.penalty:
                stepper.model, stepper.penalty_warned = fused_model, True
        while not finished(state):
            try:
                outcome = stepper.advance(state, t_end=duration)
            except SimulationError as err:
                err.results = recorder.results()
                raise
            # the step's records, its frame and a checkpoint are stored whole: Ctrl-C waits
            with DeferInterrupt():
                recorder.step(outcome.record)
                state = outcome.state
                # the stepper's model: its penalty may have been raised (`Stepper.follow_load`)
                if state.step % record_every == 0 or finished(state):
                    record_frame(recorder, stepper.model, outcome, record_contacts)
                if checkpoint_every is not None and state.step % checkpoint_every == 0:
                    write_checkpoint(checkpoint, state=state, results=recorder.results(), model=stepper.model,
                                     targets=targets)
                    # a resumed run starts with a new solver; so does this one, so that both go
                    # on with the same numbers (PARDISO keeps an analysis of an earlier matrix)
                    stepper.new_solver()
            if progress is not None:
                progress(state, outcome.record)
    except KeyboardInterrupt:
        results = recorder.results()
        written = None
        if checkpoint is not None:
            with DeferInterrupt():
                written = write_checkpoint(checkpoint, state=state, results=results, model=stepper.model,
                                           targets=targets)
        raise SimulationInterrupted(step=state.step, time=state.time, results=results,
                                    checkpoint=written) from None
    return recorder.results()


def record_frame(recorder: Recorder, model: Model, outcome: StepOutcome, record_contacts: bool) -> None:
    """Record a frame of the step's state, with the contacts of the step that produced it."""
    state = outcome.state
    if not record_contacts:
        recorder.frame(state, state.geometry["centroid"])
        return
    c = outcome.contacts
    recorder.frame(state, state.geometry["centroid"], state.vertex_xy[c.cint[:, V0]], c.state,
                   outcome.contact_forces(model))
