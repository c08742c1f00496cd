"""One DDA time step (docs/method/dda.md §0 skeleton), phase by phase.

`Stepper.step` reads like the algorithm::

    dt = choose_time_step                        (§4.6)             ddatai.time_step
    contacts = detect + transfer                 (§3)               ddatai.contacts
    repeat                                       (step-restart loop)
        K, F = block terms                       (§2.1–2.6)         ddatai.assembly
        open-close iteration                     (§4)               ddatai.open_close
            add contact springs and friction for the assumed states   ddatai.assembly
            solve K D = F                        (sparse Cholesky; LU where friction is
                                                  implicit; the first solve refines with the
                                                  last factor while it can)
            evaluate the contact law at D; shorten the step by a line search if it overshoots
            judge: contacts whose state breaks the law (or mismatches the motion) change
                                                                    ddatai.contact_law
        until no contact has to change   else: dt *= 0.3, restart
        accept unless displacement > 3·g2·w0, penetration too deep, or not finite: shorter dt
    update vertices (exact rotation), stresses, velocities, points     (§5)   ddatai.kinematics
    the watch of blocks the stage released in doubt (Δt resolves them)        ddatai.in_doubt
    energy and work of the step                                              ddatai.energy

Each phase is timed under its own name into the step's `StepRecord`
(``ddatai.results.STEP_DTYPE``). ``ddatai.run.simulate`` runs the steps (after the equilibrium
stage of `ddatai.start`); a `Stepper` holds only what steps reuse: the model, the solver and
its last factor, the sparse pattern, the detection buffers and candidates.
"""

from __future__ import annotations

import copy

import math
import time as _time
import warnings
from dataclasses import dataclass, replace
from typing import Optional

import numpy as np

from . import backend, in_doubt, vectorized
from .assembly import BlockPattern, assemble_blocks, contact_vectors, load_forces
from .contact_law import accumulate_slip
from .contacts import Contacts, _Buffers, detect_contacts
from .diagnosis import failure_message
from .geometry import mass_matrix
from .energy import state_energy, step_work
from .kinematics import max_vertex_displacement, move_points, newmark_beta, update
from .layout import KIND, LOCK, OPEN, SLIDE, VV
from .model import Model, State
from .open_close import open_close, solve
from .records import StepRecord, StepTimer
from .results import SimulationError
from .solver import SparseSolver
from .impacts import approach_bound, impacted, negligible, plastic_start, resumed
from .time_step import choose_time_step, end_on


class PenaltyWarning(UserWarning):
    """The automatic penalty was raised during a run, the load having built up beyond what it
    was chosen for (`Stepper.follow_load`)."""


#: the automatic penalty is raised when a contact goes deeper than this share of the
#: penetration limit [-] ...
PENALTY_RAISE_AT = 0.5
#: ... to carry the same force at this share [-] ...
PENALTY_TARGET = 0.25
#: ... and at most to this many times the penalty the run started with [-]
PENALTY_RAISE_MAX = 100.0


@dataclass(frozen=True, kw_only=True, eq=False)
class Attempt:
    """One try at a step with a given Δt: its solution and the acceptance checks (§4.4–4.5)."""

    ok: bool
    cause: str = ""
    """Why it was rejected: "nan", "open-close", "displacement", "inverted" or "penetration"."""
    displacement: Optional[np.ndarray] = None  # (B, 6) solution D, zero for fixed blocks
    vertex_xy: Optional[np.ndarray] = None     # (V, 2) the vertices moved by D (the state's next)
    contacts: Optional[Contacts] = None
    iterations: int = 0
    max_displacement: float = 0.0    # largest vertex displacement [m]
    max_penetration: float = 0.0     # deepest closed contact [m]
    ratio: float = 0.0               # max_displacement / g2·w0
    friction: Optional[np.ndarray] = None  # friction magnitude S of each contact in the accepted solve
    vec: Optional[np.ndarray] = None       # contact vectors of the accepted solve
    coulomb: float = 0.0                   # largest (|shear force| − S) of a closed contact [N/m]
    culprits: tuple = ()                   # (block a, block b) of the contacts behind a failure
    culprit_force: float = 0.0             # normal force of the deepest contact [N/m] (inverted: the block's largest step strain)
    culprit_start: float = 0.0             # penetration of the deepest contact at the step's start [m]
    changing: int = 0                      # contacts still changing state (open-close failure)
    system: Optional[tuple] = None         # (K's CSR data, symmetric) of the accepted solve


@dataclass(frozen=True, kw_only=True, eq=False)
class StepOutcome:
    """An accepted step (`Stepper.advance`)."""

    state: State
    """The state at the end of the step."""
    record: StepRecord
    """What the step did, with the wall time of each phase."""
    contacts: Contacts
    """The step's contacts, in the states of its accepted solve."""
    friction: np.ndarray
    """(m,) friction magnitude S of each contact in the accepted solve [N/m]."""

    def contact_forces(self, model: Model) -> tuple[np.ndarray, np.ndarray]:
        """Normal (compression positive) and shear force [N/m] of each contact: the contact law
        at the accepted solve, in which no contact changed state — a locked contact's shear
        spring k_s·ds, a sliding one's friction, nothing for an open one or a vertex-vertex one."""
        c = self.contacts
        closed = c.state != OPEN
        normal = np.where(closed, c.normal_force, 0.0)
        shear = np.where(c.state == LOCK, model.shear_penalty * c.ds,
                         np.where(c.state == SLIDE, c.shear_dir * self.friction, 0.0))
        return normal, np.where(c.cint[:, KIND] != VV, shear, 0.0)


class Stepper:
    """Advances a `Model` one step at a time. Holds only what steps reuse, never state: the
    sparse solver (and its last factor), the last step's block pattern, the detection buffers."""

    def __init__(self, model: Model):
        # the small-model path runs in NumPy: Taichi is neither imported nor started for it
        if not model.numpy_path:
            backend.ensure(model.params.arch)
        self.serial_scatter = False if model.numpy_path else backend.serial_scatter()
        self.model = model
        self.params = model.params
        self.buffers = _Buffers()
        self.narrow = vectorized.NarrowCache()  # the NumPy narrow phase's candidates of the last pairs
        self._detected = None  # (model, vertex_xy, cint, length, last keys) of the NumPy path's last detection
        self.free_idx = np.flatnonzero(~model.block_fixed)
        self.solver = SparseSolver(model.params.solver, unknowns=6 * model.n_free)
        # a block's weight, the smallest load the open-close judgement measures it by [N/m]
        self.block_load = model.block_density * model.block_geometry(model.vertex_xy0)["area"] * \
            float(np.hypot(*model.gravity))
        # softening Barton–Bandis joints: contacts remember how far they have slid
        self.softening = bool(len(model.joint_barton)) and bool(np.any(~np.isnan(model.joint_barton[:, 5])))
        self.start_penalty, self.penalty_warned = model.penalty, False  # `follow_load`
        self.pattern: Optional[BlockPattern] = None  # last step's, reused while the pairs stay
        self.factored_at = None  # (Δt, β) of the last attempt: its factor may serve the next

    def new_solver(self) -> None:
        """Start a fresh solver (no analysis or factor of an earlier matrix kept)."""
        self.solver = SparseSolver(self.params.solver, unknowns=6 * self.model.n_free)

    def step(self, state: State, t_end: Optional[float] = None) -> tuple[State, StepRecord]:
        """Advance one step (ending at most at ``t_end``). Returns (new state, step record)."""
        outcome = self.advance(state, t_end)
        return outcome.state, outcome.record

    def advance(self, state: State, t_end: Optional[float] = None) -> StepOutcome:
        """Advance one step (ending at most at ``t_end``): the step of the module docstring."""
        timer = StepTimer()
        t0 = _time.perf_counter()
        model = self.model
        geom = state.geometry if state.geometry is not None else model.block_geometry(state.vertex_xy)
        dt = end_on(choose_time_step(model, state, geom), state.time, t_end)
        t0 = timer.add("time_step", t0)

        contacts, vec, sca = self.find_contacts(state, geom)
        t0 = timer.add("contacts", t0)
        bound, closing = approach_bound(model, state, contacts, vec, sca, dt)
        dt = end_on(max(bound, min(dt, self.shortest_time_step())), state.time, t_end)

        cuts = oc_total = 0
        while True:
            # the last try before the run would stop: an open-close cycle holds its contacts
            # closed (`open_close.hold_cycling`) instead of giving up
            last = dt * self.params.dt_cut < self.shortest_time_step()
            attempt = self.attempt(state, geom, contacts, vec, sca, dt, timer, hold_cycles=last)
            oc_total += attempt.iterations
            if attempt.ok:
                break
            cuts += 1
            dt = self.shorter_time_step(attempt, state, dt)

        start = state
        impact = impacted(model, closing, attempt.contacts)
        if impact.any() and not self.params.static:
            # a plastic impact at the step's start (`ddatai.impacts`): the impacted blocks take
            # the step again from their velocity projected onto what its closed contacts admit
            projected = self.impact_projection(state, geom, attempt, dt)
            if not negligible(model, state, geom, projected, impact):
                start = plastic_start(state, projected, impact)
                # its iteration starts from the states the first try converged to (`resumed`)
                again = self.attempt(start, geom, resumed(contacts, attempt.contacts), vec, sca, dt, timer)
                oc_total += again.iterations
                start, attempt = (start, again) if again.ok else (state, attempt)
        t0 = _time.perf_counter()
        if self.softening:
            accumulate_slip(model, attempt.contacts, attempt.vec, attempt.displacement)
        new_state = update(model, start, geom, attempt.displacement, attempt.contacts, dt, attempt.vertex_xy)
        new_state = new_state.replace(in_doubt=in_doubt.follow(model, state, new_state))
        t0 = timer.add("update", t0)
        new_state, energy, work = self.energy_balance(state, new_state, geom, contacts, attempt, dt)
        timer.add("energy", t0)
        record = StepRecord(
            time=new_state.time, dt=dt, oc_iterations=attempt.iterations, oc_total=oc_total, dt_cuts=cuts,
            contacts=contacts.n, closed=int(np.count_nonzero(attempt.contacts.state != OPEN)),
            max_penetration=attempt.max_penetration, max_displacement=attempt.max_displacement,
            kinetic=energy[0], gravitational=energy[1], strain=energy[2], contact=energy[3],
            external_work=work[0], friction_work=work[1], integrator_work=work[2], coulomb=attempt.coulomb,
            penalty=model.penalty, **{f"t_{phase}": t for phase, t in timer.t.items()})
        if self.follow_load(attempt):
            # the next step starts from the energy of its springs at the new penalty (the
            # change is no work done in a step)
            new_state = new_state.replace(energy=None)
        return StepOutcome(state=new_state, record=record, contacts=attempt.contacts, friction=attempt.friction)

    def impact_projection(self, state: State, geom: dict, attempt: Attempt, dt: float) -> np.ndarray:
        """(B, 6) the velocity the step started with (carried, k·v), projected onto what the
        accepted solve's closed contacts admit: K⁻¹·(ρM/(βΔt²))·k·v with the solve's K (the
        mass-metric projection as p → ∞, `ddatai.impacts`); one more solve with its factor."""
        model = self.model
        data, symmetric = attempt.system
        beta = newmark_beta(self.params, state)
        free = self.free_idx
        mass = model.block_density[free, None, None] * mass_matrix(
            geom["area"][free], geom["s1"][free], geom["s2"][free], geom["s3"][free])
        carried = self.params.velocity_carry * state.block_velocity[free]
        rhs = np.zeros(6 * self.pattern.n_rows)
        rows = model.block_dof[free].astype(np.int64)
        rhs[(6 * rows)[:, None] + np.arange(6)] = np.einsum("nij,nj->ni", mass, carried) / (beta * dt * dt)
        return solve(self, self.pattern, data, rhs, symmetric=symmetric, reuse=True)

    def follow_load(self, attempt: Attempt) -> bool:
        """Raise the automatic penalty (``Params.penalty = None``) for the rest of the run when
        the accepted step's deepest contact went past ``PENALTY_RAISE_AT`` of the penetration limit:
        the penalty chosen at the start from the blocks' weight and speed (`build_model`) does
        not follow a load that builds up in the run (cut seed 170: a 366 m domain under 30 m/s²,
        0.013 of the limit for 350 steps, then 0.56 and the limit). p × depth / (``PENALTY_TARGET``
        × limit) takes the same force at that share of the limit; at most ``PENALTY_RAISE_MAX`` ×
        the starting p. Said once in a `PenaltyWarning`, each step's p in ``Results.steps``.
        Returns whether it raised it."""
        m = self.model
        limit = m.penetration_limit
        if self.params.penalty is not None or attempt.max_penetration <= PENALTY_RAISE_AT * limit:
            return False
        new = min(m.penalty * attempt.max_penetration / (PENALTY_TARGET * limit),
                  PENALTY_RAISE_MAX * self.start_penalty)
        if new <= m.penalty:
            return False
        if not self.penalty_warned:
            self.penalty_warned = True
            c = attempt.contacts
            k = int(np.argmax(np.where(c.state != OPEN, -c.dn, -np.inf)))
            warnings.warn(f"the automatic penalty p = {m.penalty:.3g} Pa no longer holds the load: the contact "
                          f"between blocks {int(c.block_a[k])} and {int(c.block_b[k])} is {attempt.max_penetration:.3g} m "
                          f"deep, {attempt.max_penetration / limit:.2g} of the penetration limit {limit:.3g} m; p is "
                          f"raised to {new:.3g} Pa for the rest of the run (each step's p: Results.steps['penalty'], "
                          f"docs/method/limits.md)", PenaltyWarning, stacklevel=4)
        self.model = m.with_penalty(new)
        self.factored_at = None  # K has changed: the last factor no longer solves it
        return True

    # ------------------------------------------------------------------ phases of a step
    def find_contacts(self, state: State, geom: dict) -> tuple[Contacts, np.ndarray, np.ndarray]:
        """The step's contacts (detection, and the memory of the last step transferred, §3),
        with their vectors; the block pattern follows them (reused while the pairs stay)."""
        model = self.model
        cint, length = self.detect(state.vertex_xy, state.memory)
        contacts = Contacts.start(model, state.vertex_xy, cint, length, state.memory, state.step == 0)
        self.pattern = BlockPattern.build(model, contacts, self.pattern)
        vec, sca = contact_vectors(model, state.vertex_xy, geom, contacts)
        # the shear springs as the step finds them (the lock point carried from the last step,
        # or the stage's force at strength): their energy belongs to the step's start energy
        contacts.ds[:] = np.where(contacts.cint[:, KIND] == VV, 0.0, sca[:, 2])
        return contacts, vec, sca

    def detect(self, vertex_xy: np.ndarray, memory=None) -> tuple[np.ndarray, np.ndarray]:
        """The contacts at ``vertex_xy`` (cint, length), canonical order: the Taichi kernels
        (`contacts.detect_contacts`) or, for a small model, their NumPy twin
        (`vectorized.detect_contacts`); both read the last step's contacts (``memory``) to
        keep a corner pair's hand-over to the vertex-edge rules (docs/method/dda.md §3.4)."""
        keys = memory.key if memory is not None and len(memory.key) else None
        if self.model.numpy_path:
            # the equilibrium stage detects at one geometry up to three times in a row (its
            # screen, its first pseudo-step, the release test), about half its detections: the
            # last answer is kept (a copy each way, so that no caller's edit reaches it)
            last = self._detected
            if last is not None and last[0] is self.model and np.array_equal(last[1], vertex_xy) and \
                    _same(last[4], keys):
                return last[2].copy(), last[3].copy()
            cint, length = vectorized.detect_contacts(self.model, vertex_xy, self.narrow, keys)
            self._detected = (self.model, np.array(vertex_xy), cint.copy(), length.copy(),
                              None if keys is None else keys.copy())
            return cint, length
        return detect_contacts(self.model, vertex_xy, self.buffers, keys)

    def adopt_detection(self, other: "Stepper") -> None:
        """This stepper's NumPy detection caches (its last detection, its candidate pairs and
        their topology) as ``other``'s, whose model's detection reads the same data
        (``ddatai.batch_detect.detection_key``): the same answers as its own detection, without
        it (copies, so that no caller's edit reaches the other)."""
        model, xy, cint, length, keys = other._detected
        self._detected = (self.model, xy.copy(), cint.copy(), length.copy(), None if keys is None else keys.copy())
        mine, theirs = self.narrow.pair_list, other.narrow.pair_list
        if theirs.found is not None:
            mine.found, mine.found_at, mine.margin = theirs.found.copy(), theirs.found_at.copy(), theirs.margin
        if other.narrow.topology is not None:
            topology = copy.copy(other.narrow.topology)
            topology.vertex_next = self.model.vertex_next  # equal arrays (the key): `PairTopology.matches`
            self.narrow.topology = topology

    def attempt(self, state: State, geom: dict, contacts0: Contacts, vec0: np.ndarray, sca0: np.ndarray,
                dt: float, timer: StepTimer, hold_cycles: bool = False) -> Attempt:
        """Block terms, then the open-close iteration, then the acceptance checks (§4.4–4.5)."""
        p, m = self.params, self.model
        t0 = _time.perf_counter()
        contacts = contacts0.copy()
        vec, sca = vec0.copy(), sca0.copy()
        beta = newmark_beta(p, state)
        data0, rhs0 = assemble_blocks(m, state, geom, self.pattern, dt, beta)
        timer.add("assembly", t0)
        # rotation of each block in this step: predicted from the carried motion, then the
        # latest iterate's (for the second-order terms of the constraints)
        rotation = dt * p.velocity_carry * state.block_velocity[:, 2] + 0.5 * dt * dt * state.block_accel[:, 2]
        rotation[m.block_fixed] = 0.0
        # the last factor can solve the first solve only at the Δt (and β) it was made with:
        # the inertia 2M/Δt² is a large part of K (`ddatai.solver`, reuse)
        reuse, self.factored_at = (dt, beta) == self.factored_at, (dt, beta)
        oc = open_close(self, state, geom, contacts, self.pattern, vec, sca, data0, rhs0,
                        rotation, timer, p.oc_max_iterations, reuse_first=reuse, hold_cycles=hold_cycles,
                        give_up_cycles=not hold_cycles)
        if oc.displacement is None:
            return Attempt(ok=False, cause="nan", iterations=oc.iterations)
        if not oc.converged:
            bad = np.flatnonzero(oc.changing)
            pairs = tuple(sorted({(int(contacts.block_a[i]), int(contacts.block_b[i])) for i in bad[:200]})[:3])
            return Attempt(ok=False, cause="open-close", iterations=oc.iterations, culprits=pairs,
                           changing=len(bad))
        t0 = _time.perf_counter()
        accepted = self.accept(state, geom, contacts, vec if oc.vec is None else oc.vec, oc, start_dn=contacts0.dn)
        timer.add("accept", t0)
        return accepted

    def accept(self, state: State, geom: dict, contacts: Contacts, vec: np.ndarray, oc,
               start_dn: Optional[np.ndarray] = None) -> Attempt:
        """The acceptance checks of a converged solution (§4.5): the step displacement at most
        ``displacement_reject`` × g2·w0, no block turned inside out,
        no contact deeper than the penetration limit.
        ``start_dn``: the contacts' normal distances at the step's start (for the message of a
        contact that entered the step already too deep, which no Δt can help)."""
        p, m = self.params, self.model
        disp = oc.displacement
        # the vertices moved by D: the largest displacement now, the next state's vertices
        moved_xy = move_points(state.vertex_xy, m.vertex_block, geom["centroid"], disp)
        umax = max_vertex_displacement(m, state.vertex_xy, geom, disp, moved_xy)
        closed = contacts.state != OPEN
        depth = np.where(closed, -contacts.dn, 0.0)
        deepest = int(np.argmax(depth)) if contacts.n else -1
        pen = float(depth[deepest]) if contacts.n else 0.0
        ratio = umax / m.max_step
        result = Attempt(ok=True, displacement=disp, vertex_xy=moved_xy, contacts=contacts, iterations=oc.iterations,
                         max_displacement=umax, max_penetration=max(pen, 0.0), ratio=ratio,
                         friction=oc.friction, vec=vec, coulomb=oc.coulomb, system=getattr(oc, "system", None))
        if ratio > p.displacement_reject:
            return replace(result, ok=False, cause="displacement")
        # a block that the step turns inside out (its area (1+εx)(1+εy) − (γxy/2)² times the
        # old one, ≤ 0) is no body: a thin block between heavy neighbours was inverted by a step
        # whose largest vertex displacement, 1.6 m, passed the test above (cut seed 82)
        strain = disp[:, 3:6]
        area = np.where(m.block_fixed, 1.0, (1.0 + strain[:, 0]) * (1.0 + strain[:, 1]) - 0.25 * strain[:, 2] ** 2)
        worst = int(np.argmin(area)) if len(area) else -1
        if worst >= 0 and area[worst] <= 0.0:
            return replace(result, ok=False, cause="inverted", culprits=((worst, worst),),
                           culprit_force=float(np.max(np.abs(strain[worst]))))
        if pen > m.penetration_limit:
            return replace(result, ok=False, cause="penetration",
                           culprits=((int(contacts.block_a[deepest]), int(contacts.block_b[deepest])),),
                           culprit_force=float(contacts.normal_force[deepest]),
                           culprit_start=0.0 if start_dn is None else max(-float(start_dn[deepest]), 0.0))
        return result

    def shortest_time_step(self) -> float:
        """The shortest Δt a step may be cut to, ``dt_min_ratio`` × the step limit [s]."""
        p = self.params
        return (p.dt if p.dt is not None else p.dt_max) * p.dt_min_ratio

    def shorter_time_step(self, attempt: Attempt, state: State, dt: float) -> float:
        """The Δt of the next try after a rejected attempt (§4.4–4.5); a step that fails even at
        ``dt_min_ratio`` × the step limit raises `SimulationError` with its cause."""
        p = self.params
        if attempt.cause == "displacement":
            new_dt = dt / math.sqrt(attempt.ratio)
        else:
            new_dt = dt * p.dt_cut
        if new_dt < self.shortest_time_step():
            raise SimulationError(failure_message(self.model, attempt, state.step + 1, state.time, dt),
                                  step=state.step + 1, time=state.time, cause=attempt.cause)
        return new_dt

    def energy_balance(self, state: State, new_state: State, geom: dict, contacts0: Contacts,
                       attempt: Attempt, dt: float) -> tuple[State, tuple, tuple]:
        """The energies after the step, the work in it, and the balance: what external work did
        not go into the energy or friction, the integrator took (`ddatai.energy`). Returns
        (new state with its energy, energies, (external, friction, integrator work))."""
        model = self.model
        if state.energy is None:
            state = state.replace(energy=sum(state_energy(model, state, geom, contacts0)))
        energy = state_energy(model, new_state, new_state.geometry, attempt.contacts)
        loads = load_forces(model, state.time + 0.5 * dt) if len(model.load_block) else np.zeros((0, 2))
        external, friction = step_work(model, state, geom, attempt.displacement, attempt.contacts,
                                       attempt.vec, attempt.friction, loads, dt)
        new_state = new_state.replace(energy=sum(energy))
        dissipated = external - (new_state.energy - state.energy) - friction
        return new_state, energy, (external, friction, dissipated)


def _same(a: "np.ndarray | None", b: "np.ndarray | None") -> bool:
    """Whether two detections read the same last step's contact keys (None: no memory)."""
    return (a is None and b is None) or (a is not None and b is not None and np.array_equal(a, b))
