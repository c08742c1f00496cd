"""The record of each step and of the equilibrium stage (the rows of `Results.steps` and
`Results.start`), and the timer of a step's phases."""

from __future__ import annotations

import time as _time
from dataclasses import dataclass

import numpy as np

#: One record per accepted step. Times in seconds of wall-clock, except ``time`` and ``dt``.
STEP_DTYPE = np.dtype([
    ("time", "f8"),             # simulated time at the end of the step [s]
    ("dt", "f8"),               # time step used [s]
    ("oc_iterations", "i4"),    # open-close iterations of the accepted attempt
    ("oc_total", "i4"),         # open-close iterations including rejected attempts
    ("dt_cuts", "i4"),          # rejected attempts (time-step cuts) before acceptance
    ("contacts", "i4"),         # contacts detected
    ("closed", "i4"),           # contacts closed (sliding or locked) at the end of the step
    ("max_penetration", "f8"),  # deepest penetration of a closed contact [m]
    ("max_displacement", "f8"), # largest vertex displacement in the step [m]
    ("t_contacts", "f8"),       # wall time: contact detection and transfer [s]
    ("t_assembly", "f8"),       # wall time: block and contact terms [s]
    ("t_solve", "f8"),          # wall time: sparse factorisation and solves [s]
    ("t_update", "f8"),         # wall time: the update of points, stresses and velocities [s]
    # energy at the end of the step and work during it [J per m of thickness] (ddatai.energy)
    ("kinetic", "f8"),          # ½ ρ vᵀ M v of the free blocks
    ("gravitational", "f8"),    # ρ S (−g·c), zero at the model's centre
    ("strain", "f8"),           # ½ S σᵀ C⁻¹ σ
    ("contact", "f8"),          # penalty springs of closed / locked contacts and fixed points
    ("external_work", "f8"),    # work of point loads and of the ground motion in the step
    ("friction_work", "f8"),    # work dissipated by sliding friction in the step
    ("integrator_work", "f8"),  # the rest of the balance: dissipated by the integrator (>= 0)
    ("coulomb", "f8"),          # largest |shear force| − Coulomb strength N·tanφ + c·L of a closed
                                # contact in the accepted solve [N/m]; at most oc_force_tolerance ×
                                # its blocks' load (or its strength: Params.oc_force_reference)
                                # + p·open_tolerance·w0 (Coulomb's law holds)
    ("t_time_step", "f8"),      # wall time: the choice of Δt [s]
    ("t_judge", "f8"),          # wall time: contact law, line search and open-close judgement [s]
    ("t_accept", "f8"),         # wall time: the acceptance checks of the solution [s]
    ("t_energy", "f8"),         # wall time: energy and work bookkeeping [s]
    ("penalty", "f8"),          # normal contact penalty p of the step [Pa]: the automatic one is
                                # raised in a run whose load outgrows it (ddatai.step.follow_load)
])

#: the wall-time fields of a step record, one per phase of the step (`ddatai.step`) [s]
STEP_PHASES = ("time_step", "contacts", "assembly", "solve", "judge", "accept", "update", "energy")


class StepTimer:
    """Wall time of each phase of a step (`STEP_PHASES`) [s]."""

    def __init__(self):
        self.t = dict.fromkeys(STEP_PHASES, 0.0)

    def add(self, phase: str, since: float) -> float:
        """Add the time since ``since`` to ``phase``; returns now (the next phase's start)."""
        now = _time.perf_counter()
        self.t[phase] += now - since
        return now


def step_wall_time(steps: np.ndarray) -> np.ndarray:
    """(S,) wall time of each recorded step [s]: the sum of its phases (records written before
    a phase was timed on its own have fewer fields; their sum is the same whole)."""
    names = steps.dtype.names or ()
    return sum((steps[f"t_{k}"] for k in STEP_PHASES if f"t_{k}" in names), np.zeros(len(steps)))


@dataclass(frozen=True, kw_only=True)
class StepRecord:
    """What one accepted step did (a row of `STEP_DTYPE`; the fields are documented there)."""

    time: float
    dt: float
    oc_iterations: int
    oc_total: int
    dt_cuts: int
    contacts: int
    closed: int
    max_penetration: float
    max_displacement: float
    t_contacts: float
    t_assembly: float
    t_solve: float
    t_update: float
    kinetic: float
    gravitational: float
    strain: float
    contact: float
    external_work: float
    friction_work: float
    integrator_work: float
    coulomb: float
    t_time_step: float
    t_judge: float
    t_accept: float
    t_energy: float
    penalty: float

    def row(self) -> tuple:
        """The record as a tuple in the field order of `STEP_DTYPE`."""
        return tuple(getattr(self, name) for name in STEP_DTYPE.names)

#: the equilibrium stage before t = 0 (`ddatai.start.StartRecord`), one record per run
START_DTYPE = np.dtype([
    ("solves", "i4"),           # static solves of the stage (0: nothing to settle or stage off)
    ("held", "i4"),             # free blocks held in equilibrium
    ("released", "i4"),         # free blocks released as mechanisms (sudden gravity)
    ("settlement", "f8"),       # largest vertex displacement of a held block [m]
    ("at_strength", "i4"),      # contacts of held blocks at their strength at t = 0
    ("wall_time", "f8"),        # wall time of the stage [s]
    ("welded", "?"),            # started from the welded equilibrium (no frictional one found)
    ("factorisations", "i4"),   # factorisations of K among the solves
    ("stalled", "?"),           # its last pseudo-step stalled where limit equilibrium holds every block
    ("unsettled", "?"),         # its pseudo-steps stopped contracting: ended at the last equilibrium
    ("turn_on_steps", "i4"),    # steps of the slow gravity turn-on that settled its doubt (0: none)
    ("in_doubt", "i4"),         # of the released blocks, those released in doubt (first steps resolved)
    ("diverged", "?"),          # its first pseudo-step left DDA's range: started welded
])

#: a rock bolt that broke (docs/method/water_bolts.md), one record per broken bolt
BOLT_EVENT_DTYPE = np.dtype([
    ("bolt", "i4"),             # the bolt's index (order of Scene.add_bolt)
    ("step", "i8"),             # the step at whose end its tension exceeded its capacity
    ("time", "f8"),             # time at the end of that step [s]
    ("force", "f8"),            # the tension that broke it [N/m]
])
