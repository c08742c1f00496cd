"""A single `ddatai.simulate` run on the fused engine: launches of one member, each of many steps,
its frames (every ``record_every`` steps and at the end) and step records written by the kernel
and handed to the run's ``Recorder`` as today's path hands them. Where the caller watches every
step (``progress``) a launch takes one step."""

from __future__ import annotations

import math
import warnings
from typing import Callable, Optional

import numpy as np

from . import layout as L

#: steps a launch takes at most (its records and frames are drained between launches)
LAUNCH_STEPS = 2048


def _frames_into(recorder, model, frames: np.ndarray) -> None:
    """Frames written by the kernel (`ddatai.fused.layout.FR_BLOCK`) as `Recorder.frame` records
    them (a model the fused engine runs has no bolts)."""
    nb, nv, origin = model.n_blocks, model.n_vertices, model.origin
    nf, nl = len(model.fixed_point_block), len(model.load_block)
    loads = np.array([f for f in model.load_force], dtype=float).reshape(-1, 2)
    f = recorder.frames
    for row in frames:
        blocks = row[1:1 + L.FR_BLOCK * nb].reshape(nb, L.FR_BLOCK)
        vertices = row[1 + L.FR_BLOCK * nb:1 + L.FR_BLOCK * nb + 2 * nv].reshape(nv, 2)
        points = row[1 + L.FR_BLOCK * nb + 2 * nv:].reshape(-1, 2)
        f["time"].append(float(row[0]))
        f["centroid"].append(blocks[:, 0:2] + origin)
        f["rotation"].append(blocks[:, 2].copy())
        f["velocity"].append(blocks[:, 3:5].copy())
        f["angular_velocity"].append(blocks[:, 5].copy())
        f["stress"].append(blocks[:, 6:9].copy())
        f["vertices"].append(vertices + origin)
        f["fixed_points"].append(points[:nf] + origin)
        f["load_points"].append(points[nf:nf + nl] + origin)
        f["measured"].append(points[nf + nl:] + origin)
        f["load_forces"].append(loads.copy())
        recorder.contact_count.append(0)


def run(model, state, recorder, *, duration: Optional[float], steps: Optional[int], record_every: int,
        progress: Optional[Callable] = None):
    """Advance ``state`` of ``model`` on the fused engine until the run's end, recording into
    ``recorder``. Returns (state, model, diverted): the state where it stopped, the model with the
    run's penalty, and whether a step was handed to today's path (its caller goes on from
    ``state`` with a `ddatai.step.Stepper`)."""
    from ..records import STEP_DTYPE, StepRecord
    from ..step import PenaltyWarning
    from .engine import Session
    from .pack import Member

    member = Member(model=model, state=state, t_end=duration if duration is not None else math.inf,
                    step_end=steps if steps is not None else -1, record=True, frame_every=record_every)
    session = Session([member], arch=model.params.arch, launch_steps=LAUNCH_STEPS)
    warned = False
    while True:
        wall = session.launch(np.array([1]) if progress is not None else None)
        _, rows = session.take(0)
        if len(rows):
            rows["t_solve"] = wall / len(rows)
            recorder.step_rows(rows)
        _frames_into(recorder, model, session.frames(0))
        mi = session.arrays["mi"][0]
        if mi[L.MI_RAISED] and not warned:
            warned = True
            warnings.warn(f"the automatic penalty was raised to {float(session.arrays['mf'][0, L.MF_PENALTY]):.3g} Pa "
                          f"for the rest of the run: the load built up beyond what it was chosen for (each step's "
                          f"p: Results.steps['penalty'], docs/method/limits.md)", PenaltyWarning, stacklevel=4)
        status = session.status(0)
        if status == L.GROW:
            session = Session([session.carried(0, 2)], arch=model.params.arch, launch_steps=LAUNCH_STEPS)
            continue
        if progress is not None and len(rows):
            progress(session.state(0), StepRecord(**{k: rows[-1][k].item() for k in STEP_DTYPE.names}))
        if status == L.DIVERT:
            return session.state(0), session.model(0), True
        if status != L.RUNNING:
            return session.state(0), session.model(0), False
