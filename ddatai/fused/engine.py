"""The fused engine's driver: launches of its one kernel over many members, between which it
drains what the members recorded, re-launches members whose contacts outgrew their region with
twice the room (from the start of the step that overflowed: nothing is truncated), and hands a
member whose step leaves what the engine does to today's path (`ddatai.step.Stepper`), from
that step's start.

``run`` takes ``ddatai.fused.pack.Member`` values and returns one ``Outcome`` each; a ``Session`` holds
the arrays of one launch between calls (a single run recorded every few steps). Both start
Taichi (``ddatai.backend.ensure``); the kernel compiles once for every model size, from Taichi's
offline cache after the first time on a machine (`ddatai.fused.policy`).
"""

from __future__ import annotations

import time
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Optional

import numpy as np

from . import layout as L
from .pack import Member, member_model, pack, unpack_state

#: steps a member takes in one launch at most (its history and records are drained between)
LAUNCH_STEPS = 512
#: the kernel has run in this process (`ddatai.fused.policy`: it costs nothing more now)
LAUNCHED = False

#: names of the statuses (`Outcome.status`)
STATUS = {L.RUNNING: "running", L.DONE: "done", L.STOP_MOVED: "moved", L.STOP_REST: "at rest",
          L.GROW: "grow", L.DIVERT: "diverted", L.WAITING: "waiting"}
_RECORD_FIELDS = ("time", "dt", "oc_iterations", "oc_total", "dt_cuts", "contacts", "closed", "max_penetration",
                  "max_displacement", "kinetic", "gravitational", "strain", "contact", "external_work",
                  "friction_work", "integrator_work", "coulomb", "penalty")


@dataclass(kw_only=True, eq=False)
class Outcome:
    """How a member's run ended on the fused engine."""

    status: str
    """"done" (its end time or step count), "moved" (its group passed the stop distance), "at
    rest", or "diverted" (a step that today's path takes over, ``cause``)."""
    state: object
    """Its `ddatai.model.State` at the end (for "diverted": at the start of the step handed over);
    None where `run` was asked for none (``states=False``) and the run did not divert."""
    model: object
    """Its model with the penalty the run ended with."""
    history: np.ndarray
    """(steps, 2) time [s] and its group's largest displacement [m] after every step."""
    records: np.ndarray
    """Its step records (``ddatai.records.STEP_DTYPE``) when asked for, else empty."""
    cause: str = ""
    """Why it was diverted: "cycles" (the step's last try at the shortest Δt, where today's path
    holds cycling contacts) or "failed" (no Δt converged: today's path reports the error)."""
    quiet: int = 0
    """Steps at rest at the end (a run that goes on elsewhere keeps counting)."""
    penalty_raised: bool = False
    """The automatic penalty was raised in the run (`ddatai.step.PenaltyWarning`)."""
    launches: int = 0
    wall_time: float = 0.0
    """Wall time of the launches it ran in [s]."""


def records_of(rows: np.ndarray, seconds_per_step: float) -> np.ndarray:
    """Step records (``STEP_DTYPE``) from the engine's rows. The engine times its launches, not
    the phases of a step: each step's share of its launch is written as its solve time."""
    from ..records import STEP_DTYPE

    out = np.zeros(len(rows), STEP_DTYPE)
    if not len(rows):  # not recorded (a judgement's run): nothing to copy, field by field
        return out
    for col, name in enumerate(_RECORD_FIELDS):
        out[name] = rows[:, col]
    out["t_solve"] = seconds_per_step
    return out


@contextmanager
def _short_source_positions():
    """While Taichi turns the kernel's Python into its IR, every node's source position is its
    file and line, without the code snippet Taichi formats (textwrap) for each of the ~35,000
    nodes of the fused kernel, for its error messages: some 40 % of that work, which every
    process does again before it takes the compiled kernel from the offline cache."""
    from taichi.lang.ast import ast_transformer_utils as utils

    context = utils.ASTTransformerContext
    original = context.get_pos_info

    def position(self, node):
        return f'File "{self.file}", line {node.lineno + self.lineno_offset}, in {self.func.func.__name__}:\n'

    context.get_pos_info = position
    try:
        yield
    finally:
        context.get_pos_info = original


class Session:
    """The arrays of one launch of ``members`` and the kernel, between launches."""

    def __init__(self, members: list, *, arch: str = "cpu", launch_steps: int = LAUNCH_STEPS):
        from .. import backend
        from . import kernel
        from .arrays import Pack
        from .policy import mark_cached

        backend.ensure(arch)
        self.arch = arch
        self.members = members
        self.launch_steps = launch_steps
        self.arrays = pack(members, launch_steps)
        self._pack = Pack
        self._kernel = kernel.run
        self._mark = mark_cached
        self.launches = 0
        self.wall = 0.0

    def launch(self, budget: Optional[np.ndarray] = None) -> float:
        """Advance every running member by at most ``budget`` steps (each; default: the launch
        size). Returns the wall time [s]. Drain ``hist``/``rec`` (`take`) before the next."""
        mi = self.arrays["mi"]
        mi[:, L.MI_LAUNCH_STEPS] = self.launch_steps if budget is None else np.minimum(budget, self.launch_steps)
        mi[:, L.MI_HN] = 0
        mi[:, L.MI_SN] = 0
        mi[:, L.MI_FN] = 0
        t0 = time.perf_counter()
        if self.launches == 0:
            # one argument pack a session: it refers to the arrays, which keep their identity
            # between launches (the members' state is updated in them in place)
            self._args = self._pack(**self.arrays)
            with _short_source_positions():
                self._kernel(self._args, len(self.members))
        else:
            self._kernel(self._args, len(self.members))
        wall = time.perf_counter() - t0
        if self.launches == 0:
            global LAUNCHED
            LAUNCHED = True
            self._mark("cpu" if self.arch == "cpu" else "cuda")
        self.launches += 1
        self.wall += wall
        return wall

    def status(self, i: int) -> int:
        return int(self.arrays["mi"][i, L.MI_STATUS])

    def take(self, i: int, seconds_per_step: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
        """Member i's history rows and step records of the last launch."""
        A, mi = self.arrays, self.arrays["mi"][i]
        h0, hn, s0, sn = (int(mi[c]) for c in (L.MI_H0, L.MI_HN, L.MI_S0, L.MI_SN))
        return A["hist"][h0:h0 + hn].copy(), records_of(A["rec"][s0:s0 + sn], seconds_per_step)

    def frames(self, i: int) -> np.ndarray:
        """Member i's frames of the last launch, (frames, size) (`ddatai.fused.layout.FR_BLOCK`)."""
        mi = self.arrays["mi"][i]
        f0, fn, size = int(mi[L.MI_F0]), int(mi[L.MI_FN]), int(mi[L.MI_FSIZE])
        return self.arrays["frame"][f0:f0 + fn * size].reshape(fn, size).copy()

    def state(self, i: int):
        return unpack_state(self.arrays, i, self.members[i])

    def model(self, i: int):
        return member_model(self.arrays, i, self.members[i])

    def carried(self, i: int, factor: int = 1) -> Member:
        """Member i as a `Member` that goes on from where it is, its contact region ``factor``
        times as large."""
        m = self.members[i]
        return Member(model=self.model(i), state=self.state(i), t_end=m.t_end, step_end=m.step_end,
                      stop_at=m.stop_at, rest_limit=m.rest_limit, rest_steps=m.rest_steps, group=m.group,
                      record=m.record, frame_every=m.frame_every, start_penalty=m.start_penalty,
                      quiet=int(self.arrays["mi"][i, L.MI_QUIET]), contacts=factor * m.contacts)

    def outcome(self, i: int, status: int, history: list, records: list, launches: int, wall: float, *,
                state: bool = True) -> Outcome:
        """Member i's `Outcome`; ``state`` False: without its end state (None), unless diverted."""
        from ..records import STEP_DTYPE

        mi = self.arrays["mi"][i]
        cause = {L.CAUSE_CYCLES: "cycles", L.CAUSE_FAILED: "failed"}.get(int(mi[L.MI_CAUSE]), "")
        return Outcome(status=STATUS[status], state=self.state(i) if state or status == L.DIVERT else None,
                       model=self.model(i),
                       history=np.concatenate(history) if history else np.zeros((0, 2)),
                       records=np.concatenate(records) if any(len(r) for r in records) else np.zeros(0, STEP_DTYPE),
                       cause=cause if status == L.DIVERT else "", quiet=int(mi[L.MI_QUIET]),
                       penalty_raised=bool(mi[L.MI_RAISED]), launches=launches, wall_time=wall)


def run(members: list, *, arch: str = "cpu", launch_steps: int = LAUNCH_STEPS, states: bool = True) -> list:
    """Run every member (`Member`) to its end on the fused engine; one `Outcome` each.
    ``states=False``: an outcome's end state is read back only where the member diverted (a
    batch of judgements takes its verdicts from the histories alone)."""
    members = list(members)
    outcomes: list[Optional[Outcome]] = [None] * len(members)
    history = [[] for _ in members]
    records = [[] for _ in members]
    launches = [0] * len(members)
    walls = [0.0] * len(members)
    active = list(range(len(members)))
    while active:
        session = Session([members[k] for k in active], arch=arch, launch_steps=launch_steps)
        mi = session.arrays["mi"]
        while True:
            running = mi[:, L.MI_STATUS] == L.RUNNING
            wall = session.launch()
            taken = max(1, int(np.sum(mi[running, L.MI_HN])))
            grow = []
            for i, k in enumerate(active):
                if not running[i]:
                    continue
                launches[k] += 1
                walls[k] += wall
                h, r = session.take(i, wall / taken)
                history[k].append(h)
                records[k].append(r)
                status = session.status(i)
                if status == L.GROW:
                    grow.append(i)
                elif status != L.RUNNING:
                    outcomes[k] = session.outcome(i, status, history[k], records[k], launches[k], walls[k],
                                                  state=states)
            if grow:
                # more room for the contacts: every member not finished goes on in a new launch
                for i, k in enumerate(active):
                    if outcomes[k] is None:
                        members[k] = session.carried(i, 2 if i in grow else 1)
                break
            if not np.any(mi[:, L.MI_STATUS] == L.RUNNING):
                break
        active = [k for k in active if outcomes[k] is None]
    return outcomes
