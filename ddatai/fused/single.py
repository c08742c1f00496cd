"""A single `ddatai.simulate` run on the fused engine: launches of one member, each up to the
next recorded frame (or one step, where the caller watches every step through ``progress``),
the frames and step records handed to the run's ``Recorder`` as today's path hands them."""

from __future__ import annotations

import math
import warnings
from typing import Callable, Optional

import numpy as np

from . import layout as L

#: steps a launch takes at most when nothing asks for a frame before
LAUNCH_STEPS = 1024


def run(model, state, recorder, *, duration: Optional[float], steps: Optional[int], record_every: int,
        progress: Optional[Callable] = None):
    """Advance ``state`` of ``model`` on the fused engine until the run's end, recording into
    ``recorder``. Returns (state, model, diverted): the state where it stopped, the model with the
    run's penalty, and whether a step was handed to today's path (its caller goes on from
    ``state`` with a `ddatai.step.Stepper`)."""
    from ..records import STEP_DTYPE, StepRecord
    from .engine import Session
    from .pack import Member

    def finished(s_time, s_step):
        return (duration is not None and s_time >= duration * (1 - 1e-12)) or (steps is not None and s_step >= steps)

    member = Member(model=model, state=state, t_end=duration if duration is not None else math.inf,
                    step_end=steps if steps is not None else -1, record=True)
    session = Session([member], arch=model.params.arch, launch_steps=LAUNCH_STEPS)
    warned = False
    while True:
        mi = session.arrays["mi"][0]
        step = int(mi[L.MI_STEP])
        budget = 1 if progress is not None else record_every - step % record_every
        wall = session.launch(np.array([budget]))
        _, rows = session.take(0)
        if len(rows):
            rows["t_solve"] = wall / len(rows)
            recorder.steps.extend(tuple(r) for r in rows)
        status = session.status(0)
        if mi[L.MI_RAISED] and not warned:
            warned = True
            from ..step import PenaltyWarning

            warnings.warn(f"the automatic penalty was raised to {float(session.arrays['mf'][0, L.MF_PENALTY]):.3g} Pa "
                          f"for the rest of the run: the load built up beyond what it was chosen for (each step's "
                          f"p: Results.steps['penalty'], docs/method/limits.md)", PenaltyWarning, stacklevel=4)
        if status == L.GROW:
            session = Session([session.carried(0, 2)], arch=model.params.arch, launch_steps=LAUNCH_STEPS)
            continue
        now = session.state(0) if len(rows) or status != L.RUNNING else None
        if now is not None and len(rows):
            if progress is not None:
                progress(now, StepRecord(**{k: rows[-1][k].item() for k in STEP_DTYPE.names}))
            if now.step % record_every == 0 or finished(now.time, now.step):
                b0, b1 = int(mi[L.MI_B0]), int(mi[L.MI_B1])
                centroid = session.arrays["bgeo"][b0:b1, L.BG_CX:L.BG_CY + 1].copy()
                recorder.frame(now, centroid)
        if status == L.DIVERT:
            return now, session.model(0), True
        if status != L.RUNNING:
            return now, session.model(0), False
