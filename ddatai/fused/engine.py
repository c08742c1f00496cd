"""The fused engine's driver: launches of its one kernel over many members, between which it
drains what the members recorded, re-launches members whose contacts outgrew their region with
twice the room (from the start of the step that overflowed: nothing is truncated), and hands a
member whose step leaves what the engine does to today's path (`Stepper`), from that step's
start.

`run` takes `ddatai.fused.pack.Member` values and returns one `Outcome` each. It starts Taichi
(`ddatai.backend.ensure`); the kernel compiles once per process for every model size, from
Taichi's offline cache after the first time (docs/guide/performance.md).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Optional

import numpy as np

from . import layout as L
from .pack import Member, member_model, pack, unpack_state

#: steps a member takes in one launch at most (its history and records are drained between)
LAUNCH_STEPS = 512

#: names of the statuses (`Outcome.status`)
STATUS = {L.RUNNING: "running", L.DONE: "done", L.STOP_MOVED: "moved", L.STOP_REST: "at rest",
          L.GROW: "grow", L.DIVERT: "diverted", L.WAITING: "waiting"}


@dataclass(kw_only=True, eq=False)
class Outcome:
    """How a member's run ended on the fused engine."""

    status: str
    """"done" (its end time or step count), "moved" (its group passed the stop distance), "at
    rest", or "diverted" (a step that today's path takes over, ``cause``)."""
    state: object
    """Its `ddatai.model.State` at the end (for "diverted": at the start of the step handed over)."""
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


def _kernel():
    from . import kernel

    return kernel.run


def _records(rows: np.ndarray, seconds_per_step: float) -> np.ndarray:
    from ..records import STEP_DTYPE

    out = np.zeros(len(rows), STEP_DTYPE)
    names = ("time", "dt", "oc_iterations", "oc_total", "dt_cuts", "contacts", "closed", "max_penetration",
             "max_displacement", "kinetic", "gravitational", "strain", "contact", "external_work",
             "friction_work", "integrator_work", "coulomb", "penalty")
    for col, name in enumerate(names):
        out[name] = rows[:, col]
    # the engine times its launches, not the phases of a step: each step's share of its launch
    out["t_solve"] = seconds_per_step
    return out


def run(members: list, *, arch: str = "cpu", launch_steps: int = LAUNCH_STEPS) -> list:
    """Run every member (`Member`) to its end on the fused engine; one `Outcome` each."""
    from .. import backend
    from .arrays import Pack

    backend.ensure(arch)
    kernel = _kernel()
    outcomes: list[Optional[Outcome]] = [None] * len(members)
    history = [[] for _ in members]
    records = [[] for _ in members]
    launches = [0] * len(members)
    walls = [0.0] * len(members)
    active = list(range(len(members)))
    while active:
        batch = [members[k] for k in active]
        A = pack(batch, launch_steps)
        while True:
            t0 = time.perf_counter()
            kernel(Pack(**A), len(batch))
            wall = time.perf_counter() - t0
            mi = A["mi"]
            taken = max(1, int(np.sum(mi[:, L.MI_HN])))
            grow = []
            for i, k in enumerate(active):
                launches[k] += 1
                walls[k] += wall
                hn = int(mi[i, L.MI_HN])
                h0 = int(mi[i, L.MI_H0])
                if hn:
                    history[k].append(A["hist"][h0:h0 + hn].copy())
                sn = int(mi[i, L.MI_SN])
                if sn:
                    s0 = int(mi[i, L.MI_S0])
                    records[k].append(_records(A["rec"][s0:s0 + sn], wall / taken))
                mi[i, L.MI_HN] = 0
                mi[i, L.MI_SN] = 0
                status = int(mi[i, L.MI_STATUS])
                if status == L.GROW:
                    grow.append(i)
                elif status not in (L.RUNNING, L.WAITING):
                    outcomes[k] = _outcome(A, i, members[k], status, history[k], records[k], launches[k], walls[k])
                    mi[i, L.MI_STATUS] = L.WAITING
            if grow:
                # more room for the contacts: every member not finished goes on in a new pack
                for i, k in enumerate(active):
                    if outcomes[k] is None:
                        members[k] = _carried(A, i, members[k], 2 if i in grow else 1)
                break
            if not np.any(mi[:, L.MI_STATUS] == L.RUNNING):
                break
        active = [k for k in active if outcomes[k] is None]
    return outcomes


def _carried(A: dict, i: int, member: Member, factor: int) -> Member:
    """Member i of the arrays as a `Member` that goes on from where it is, its contact region
    ``factor`` times as large."""
    return Member(model=member_model(A, i, member), state=unpack_state(A, i, member), t_end=member.t_end,
                  step_end=member.step_end, stop_at=member.stop_at, rest_limit=member.rest_limit,
                  rest_steps=member.rest_steps, group=member.group, record=member.record,
                  start_penalty=member.start_penalty, quiet=int(A["mi"][i, L.MI_QUIET]),
                  contacts=factor * member.contacts)


def _outcome(A, i, member, status, history, records, launches, wall) -> Outcome:
    from ..records import STEP_DTYPE

    cause = {L.CAUSE_CYCLES: "cycles", L.CAUSE_FAILED: "failed"}.get(int(A["mi"][i, L.MI_CAUSE]), "")
    return Outcome(status=STATUS[status], state=unpack_state(A, i, member), model=member_model(A, i, member),
                   history=np.concatenate(history) if history else np.zeros((0, 2)),
                   records=np.concatenate(records) if records else np.zeros(0, STEP_DTYPE),
                   cause=cause if status == L.DIVERT else "", quiet=int(A["mi"][i, L.MI_QUIET]),
                   penalty_raised=bool(A["mi"][i, L.MI_RAISED]), launches=launches, wall_time=wall)


_unused = (math, field)
