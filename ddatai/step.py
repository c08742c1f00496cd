"""One DDA time step, and `simulate` (dda-method.md §0 skeleton).

``Stepper.step(state)`` reads like the algorithm::

    dt = choose_time_step            (§4.6)
    contacts = detect + transfer     (§3)
    repeat                           (step-restart loop)
        K, F = block terms           (§2.1–2.6)
        repeat                       (open-close iteration, §4)
            add contact springs and friction loads for the assumed states
            solve K D = F            (SciPy sparse LU in symmetric mode)
            judge contacts: new states from dn, ds
        until no state changes       else: dt *= 0.3, restart
        reject if displacement > 3·g2·w0, penetration too deep, or not finite: shorter dt, restart
    update vertices (exact rotation), stresses, velocities, points     (§5)

Each phase is timed into the step record (`ddatai.results.STEP_DTYPE`).
"""

from __future__ import annotations

import math
import time as _time
from dataclasses import dataclass
from typing import Callable, Optional

import numpy as np

from .contacts import E0, KIND, V0, BlockPattern, Contacts, _Buffers, detect_contacts, N_SLOTS
from .geometry import mass_matrix
from .model import ContactKind, ContactState, Model, State, build_model
from .params import Params
from .results import Recorder, Results, SimulationError
from .scene import Scene

OPEN, SLIDE, LOCK = int(ContactState.OPEN), int(ContactState.SLIDE), int(ContactState.LOCK)
VE, VV = int(ContactKind.VE), int(ContactKind.VV)
#: open-close iteration from which contacts cycling between locked and sliding are held locked
ANTI_CYCLING_FROM = 4
# contact-vector slots (see ddatai.kernels)
S_E0, S_G0, S_E1, S_G1, S_ES, S_GS, S_TJ = range(7)


@dataclass
class _Attempt:
    """Outcome of one try at a step with a given dt."""

    ok: bool
    cause: str = ""
    displacement: Optional[np.ndarray] = None  # (B, 6) solution D, zero for fixed blocks
    contacts: Optional[Contacts] = None
    iterations: int = 0
    max_displacement: float = 0.0
    max_penetration: float = 0.0
    ratio: float = 0.0
    friction: Optional[np.ndarray] = None  # friction loads of the accepted solve
    vec: Optional[np.ndarray] = None       # contact vectors of the accepted solve


class _Timer:
    def __init__(self):
        self.t = {"contacts": 0.0, "assembly": 0.0, "solve": 0.0, "update": 0.0}

    def add(self, phase: str, since: float) -> float:
        now = _time.perf_counter()
        self.t[phase] += now - since
        return now


class Stepper:
    """Advances a `Model` one step at a time. Holds only reusable buffers, never state."""

    def __init__(self, model: Model):
        from . import backend

        backend.ensure(model.params.arch)
        self._serial_scatter = backend.serial_scatter()
        self._pattern: Optional[BlockPattern] = None  # last step's, reused while the pairs stay
        from . import kernels  # noqa: F401  (imports Taichi; compiled on first use)

        self.model = model
        self.params = model.params
        self.buffers = _Buffers()
        self.dof = model.block_dof
        self.free = ~model.block_fixed
        self.free_idx = np.flatnonzero(self.free)
        from .solver import SparseSolver

        self.solver = SparseSolver(model.params.solver)
        self._fp_stiff = np.full(len(model.fixed_point_block), model.fixed_point_penalty)
        self._load_stiff = np.zeros(len(model.load_block))

    # ------------------------------------------------------------------ public
    def step(self, state: State, t_end: Optional[float] = None) -> tuple[State, tuple]:
        """Advance one step (ending at most at ``t_end``). Returns (new state, step record)."""
        timer = _Timer()
        t0 = _time.perf_counter()
        model, p = self.model, self.params
        geom = state.geometry if state.geometry is not None else model.block_geometry(state.vertex_xy)
        dt_nominal = self.choose_time_step(state, geom)
        dt = dt_nominal
        if t_end is not None:
            # land exactly on t_end without leaving a sliver of a step
            remaining = t_end - state.time
            if remaining <= dt * (1.0 + 1e-9):
                dt = remaining
            elif remaining < 2.0 * dt:
                dt = 0.5 * remaining
        dt_floor = (p.dt if p.dt is not None else p.dt_max) * p.dt_min_ratio

        t0 = timer.add("update", t0)
        cint, length = detect_contacts(model, state.vertex_xy, self.buffers)
        contacts0 = Contacts.start(model, state.vertex_xy, cint, length, state.memory, state.step == 0)
        pattern = self._pattern = BlockPattern.build(model, contacts0, self._pattern)
        vec, sca = self.contact_vectors(state.vertex_xy, geom, contacts0)
        t0 = timer.add("contacts", t0)

        cuts = 0
        oc_total = 0
        while True:
            attempt = self._attempt(state, geom, contacts0, pattern, vec, sca, dt, timer)
            oc_total += attempt.iterations
            if attempt.ok:
                break
            cuts += 1
            if attempt.cause == "displacement":
                new_dt = dt / math.sqrt(attempt.ratio)
            else:
                new_dt = dt * p.dt_cut
            if new_dt < dt_floor:
                raise SimulationError(self._failure_message(attempt, state, dt),
                                      step=state.step + 1, time=state.time, cause=attempt.cause)
            dt = new_dt

        t0 = _time.perf_counter()
        new_state = self.update(state, geom, attempt.displacement, attempt.contacts, dt)
        if state.energy is None:
            state = state.replace(energy=sum(self.energies(state, geom, contacts0)))
        energy = self.energies(new_state, new_state.geometry, attempt.contacts)
        work = self.work(state, geom, attempt, dt)
        new_state = new_state.replace(energy=sum(energy))
        # balance: what external work did not go into the energy or friction, the integrator took
        dissipated = work[0] - (new_state.energy - state.energy) - work[1]
        timer.add("update", t0)
        closed = attempt.contacts.state != OPEN
        record = (new_state.time, dt, attempt.iterations, oc_total, cuts, contacts0.n,
                  int(np.count_nonzero(closed)), attempt.max_penetration, attempt.max_displacement,
                  timer.t["contacts"], timer.t["assembly"], timer.t["solve"], timer.t["update"],
                  *energy, work[0], work[1], dissipated)
        self.last_contacts = attempt.contacts
        return new_state, record

    def energies(self, state: State, geom: dict, contacts: Optional[Contacts]) -> tuple:
        """(kinetic, gravitational, strain, contact) energy of a state [J/m] (ddatai.energy)."""
        from .energy import contact_energy, mechanical_energy

        kinetic, gravitational, strain, springs = mechanical_energy(
            self.model, geom, state.block_velocity, state.block_stress, state.fixed_point_xy)
        return kinetic, gravitational, strain, springs + contact_energy(self.model, contacts)

    def work(self, state: State, geom: dict, attempt: _Attempt, dt: float) -> tuple[float, float]:
        """(external work, friction dissipation) of the accepted step [J/m]."""
        from .energy import external_work, friction_work

        m = self.model
        t_mid = state.time + 0.5 * dt
        ground = np.asarray(m.ground_acceleration(t_mid), float) if m.ground_acceleration is not None else None
        loads = self._load_forces(t_mid) if len(m.load_block) else np.zeros((0, 2))
        external = external_work(m, geom, attempt.displacement, state.load_xy, loads, ground)
        friction = friction_work(attempt.contacts, attempt.vec, attempt.friction, attempt.displacement) \
            if attempt.contacts.n else 0.0
        return external, friction

    def _failure_message(self, attempt: _Attempt, state: State, dt: float) -> str:
        step = state.step + 1
        what = {
            "open-close": f"the open-close iteration did not converge in {self.params.oc_max_iterations} "
                          "iterations",
            "nan": "the solution is not finite (NaN or infinite displacements)",
            "penetration": f"runaway penetration: {attempt.max_penetration:.3g} m exceeds the limit "
                           f"{self.model.penetration_limit:.3g} m",
            "displacement": f"the step displacement {attempt.max_displacement:.3g} m exceeds "
                            f"{self.params.displacement_reject:g} × g2·w0 = "
                            f"{self.params.displacement_reject * self.model.max_step:.3g} m",
        }[attempt.cause]
        return (f"simulation diverged at step {step} (t = {state.time:.6g} s): {what}, even with the "
                f"time step cut to {dt:.3g} s")

    # ------------------------------------------------------------------ phases
    def choose_time_step(self, state: State, geom: dict) -> float:
        """Automatic Δt (dda-method.md §4.6): the step whose predicted largest vertex
        displacement, ½·a·Δt² + v·Δt, equals g2·w0; at most ``dt_max`` and at most
        ``dt_growth`` × the previous step. A fixed ``Params.dt`` is used as given, growing back
        by ``dt_growth`` per step after a cut."""
        p, model = self.params, self.model
        limit = p.dt if p.dt is not None else p.dt_max
        if p.dt is None and len(self.free_idx):
            radius = self._block_radius(state.vertex_xy, geom["centroid"])
            v = state.block_velocity
            speed = float(np.max((np.hypot(v[:, 0], v[:, 1]) + np.abs(v[:, 2]) * radius)[self.free]))
            acc = float(np.hypot(*model.gravity))
            if model.ground_acceleration is not None:
                acc += float(np.hypot(*model.ground_acceleration(state.time)))
            if len(model.load_block):
                f = self._load_forces(state.time)
                mass = model.block_density * geom["area"]
                acc += float(np.max(np.hypot(f[:, 0], f[:, 1]) / mass[model.load_block]))
            if state.step == 0:
                # initial stresses accelerate a block's strain (ntdda's first-step estimate)
                s = np.abs(state.block_stress).max(axis=1)
                area = geom["area"]
                acc += float(np.max((4.0 * s * np.sqrt(area) / (area * model.block_density))[self.free]))
            # the forcing bounds the acceleration of a free block; the last step's observed
            # accelerations (contacts, impacts) may exceed it
            acc = max(acc, state.accel)
            u = model.max_step
            if acc > 0:
                dt = (-speed + math.sqrt(speed * speed + 2.0 * acc * u)) / acc
            elif speed > 0:
                dt = u / speed
            else:
                dt = limit
            limit = min(limit, dt)
        if state.dt > 0:
            limit = min(limit, p.dt_growth * state.dt)
        return limit

    def contact_vectors(self, vertex_xy: np.ndarray, geom: dict, contacts: Contacts
                        ) -> tuple[np.ndarray, np.ndarray]:
        """Normal/shear vectors e, g, e_s, g_s, t_j and constant parts of every contact (§2.8)."""
        from . import kernels as K

        m = contacts.n
        vec = np.zeros((m, N_SLOTS, 6))
        sca = np.zeros((m, 3))
        if m:
            K.contact_vectors(vertex_xy, self.model.vertex_block, self.model.vertex_next,
                              np.ascontiguousarray(geom["centroid"]), contacts.cint, contacts.omega, vec, sca)
        return vec, sca

    def assemble_blocks(self, state: State, geom: dict, pattern: BlockPattern, dt: float
                        ) -> tuple[np.ndarray, np.ndarray]:
        """The part of K and F that does not depend on contact states: inertia, elasticity,
        initial stress, body force, fixed points and point loads (§2.1–2.6)."""
        from . import kernels as K

        model = self.model
        data = np.zeros(pattern.nnz)
        rhs = np.zeros(6 * pattern.n_rows)
        if pattern.n_rows == 0:
            return data, rhs
        t_mid = state.time + 0.5 * dt
        body = model.gravity.copy()
        if model.ground_acceleration is not None:
            # the ground's frame: every block feels -a_g(t) (§2.4, seismic body force)
            body -= np.asarray(model.ground_acceleration(t_mid), dtype=float)
        mass = mass_matrix(geom["area"], geom["s1"], geom["s2"], geom["s3"])
        K.assemble_blocks(self.dof, model.block_density, model.block_elastic, geom["area"], mass,
                          state.block_velocity, state.block_accel, state.block_stress, float(body[0]),
                          float(body[1]), dt, self.params.velocity_carry, self.newmark_beta(state),
                          pattern.diag_slot, pattern.stride, data, rhs)
        centroid = np.ascontiguousarray(geom["centroid"])
        if len(model.fixed_point_block):
            # restoring spring towards the original position (§2.6)
            force = model.fixed_point_penalty * (model.fixed_point_xy0 - state.fixed_point_xy)
            K.assemble_points(model.fixed_point_block, state.fixed_point_xy, force, self._fp_stiff,
                              self.dof, centroid, pattern.diag_slot, pattern.stride, data, rhs)
        if len(model.load_block):
            K.assemble_points(model.load_block, state.load_xy, self._load_forces(t_mid), self._load_stiff,
                              self.dof, centroid, pattern.diag_slot, pattern.stride, data, rhs)
        return data, rhs

    def newmark_beta(self, state: State) -> float:
        """β for this step: Shi's ½ on the first step (no acceleration history), then Params'."""
        return 0.5 if state.step == 0 else self.params.newmark_beta

    def assemble_contacts(self, contacts: Contacts, pattern: BlockPattern, vec: np.ndarray,
                          sca: np.ndarray, data: np.ndarray, rhs: np.ndarray) -> None:
        """Add springs of closed contacts and friction loads of sliding ones, in place (§2.8)."""
        from . import kernels as K

        if contacts.n == 0:
            return
        m = self.model
        K.assemble_contacts(contacts.cint, contacts.state, contacts.line, m.vertex_block, self.dof,
                            vec, sca, self.friction_force(contacts), contacts.shear_dir,
                            pattern.slot_ab, pattern.slot_ba, pattern.diag_slot, pattern.stride,
                            m.penalty, m.shear_penalty, data, rhs, self._serial_scatter)

    def second_order(self, contacts: Contacts, state: State, geom: dict, rotation: np.ndarray,
                     pattern: BlockPattern, rhs: np.ndarray) -> np.ndarray:
        """Second-order rotation terms of the constraints, for the exact-rotation update (§5.3).

        The step equations use the linearised displacement T·D, but points are moved with the
        exact rotation, which adds q = (cos r − 1)X + (sin r − r)JX (≈ −½r²X, JX = (−Y, X)) to a
        point at X from its block's centroid. A block swinging about a constrained point (a
        fixed point, a contact at a pivot corner) would drift outwards by q every step and be
        pulled back, the constraint doing work: energy grows ∝ ω²Δt. Folding q, evaluated with
        the rotation r of the latest iterate, into the constant parts of the contact distances
        (returned, (m, 3): dn line 0, dn line 1, ds) and into the fixed-point springs (added to
        ``rhs`` in place) makes the constraints hold for the exact update.
        """
        m = self.model
        shift = np.zeros((contacts.n, 3))
        if not np.any(rotation):
            return shift
        xy, centroid, nxt, vb = state.vertex_xy, geom["centroid"], m.vertex_next, m.vertex_block

        def q(points, blocks):
            X = points - centroid[blocks]
            r = rotation[blocks]
            jx = np.stack([-X[:, 1], X[:, 0]], axis=1)
            return (np.cos(r) - 1.0)[:, None] * X + (np.sin(r) - r)[:, None] * jx

        if contacts.n:
            from . import kernels as K

            # q of every vertex once (a vertex appears in several contacts), then ∂Δ/∂P·q and
            # ∂s/∂P·q per contact line
            K.second_order_shift(xy, nxt, q(xy, vb), contacts.cint, contacts.omega, shift)
        if len(m.fixed_point_block):
            from .geometry import displacement_matrix

            fb = m.fixed_point_block
            rows = self.dof[fb]
            use = rows >= 0
            pts = state.fixed_point_xy[use]
            t = displacement_matrix(pts, centroid[fb[use]])
            load = -m.fixed_point_penalty * np.einsum("nij,ni->nj", t, q(pts, fb[use]))
            np.add.at(rhs, (6 * rows[use])[:, None] + np.arange(6)[None, :], load)
        return shift

    def friction_force(self, contacts: Contacts) -> np.ndarray:
        """Coulomb limit N·tanφ + c·L (bonded) of each contact, N from the last solve in which
        the contact was closed (§2.8.4)."""
        return contacts.normal_force * contacts.tan_phi + contacts.cohesion * contacts.length * contacts.bond

    def solve(self, pattern: BlockPattern, data: np.ndarray, rhs: np.ndarray) -> np.ndarray:
        """Solve K D = F (`ddatai.solver`); returns D as (B, 6) with zeros for fixed blocks."""
        d = np.zeros((self.model.n_blocks, 6))
        if pattern.n_rows == 0:
            return d
        x = self.solver.solve(data, pattern.indices, pattern.indptr, rhs, pattern=pattern)
        d[self.free_idx] = x.reshape(-1, 6)
        return d

    def judge(self, contacts: Contacts, vec: np.ndarray, sca: np.ndarray, disp: np.ndarray,
              vertex_xy: np.ndarray, geom: dict, shift: Optional[np.ndarray] = None,
              flips: Optional[np.ndarray] = None, hold: bool = False) -> bool:
        """Open-close judgement (§4.2–4.3) in place; returns True if any state changed.

        Normal: an open contact closes when it penetrates deeper than close_tol; a closed one
        opens when its normal distance exceeds open_tol (+ T·L/p while bonded). Shear (vertex-
        edge contacts, force form): locked while k_s|ds| <= N tanφ + cL; a sliding contact
        locks again when the sliding direction reverses by more than reversal_tol (φ > 0.9°).
        """
        m = self.model
        ci = contacts.cint
        a, b = contacts.block_a, contacts.block_b
        da, db = disp[a], disp[b]
        shift = np.zeros_like(sca) if shift is None else shift
        dn0 = sca[:, 0] + shift[:, 0] + np.einsum("ij,ij->i", vec[:, S_E0], da) + \
            np.einsum("ij,ij->i", vec[:, S_G0], db)
        kind = ci[:, KIND]
        vv = kind == VV
        ve = ~vv
        dn = dn0.copy()
        line = contacts.line.copy()
        prev = contacts.state
        was_open = prev == OPEN
        if vv.any():
            # line 1: vertex1 (of block b) against an edge of block a. The less penetrated line
            # acts; a closed contact switches only when the other line is clearly less
            # penetrated (beyond open_tol), so exact ties (touching corners) do not flip.
            dn1 = sca[vv, 1] + shift[vv, 1] + np.einsum("ij,ij->i", vec[vv, S_E1], db[vv]) + \
                np.einsum("ij,ij->i", vec[vv, S_G1], da[vv])
            dnl = np.stack([dn0[vv], dn1], axis=1)
            cur = line[vv].astype(np.int64)
            other = 1 - cur
            rows = np.arange(len(cur))
            switch = dnl[rows, other] > dnl[rows, cur] + np.where(was_open[vv], 0.0, m.open_tol)
            line[vv] = np.where(switch, other, cur).astype(np.int8)
            dn[vv] = dnl[rows, line[vv]]
        # an open contact closes when it penetrates; a closed one opens as soon as it pulls
        # harder than the tensile strength of a bonded joint (force p·dn > T·L)
        allowance = np.where(contacts.bond, contacts.tensile * contacts.length / m.penalty, 0.0)
        closed = np.where(was_open, dn < -m.close_tol, dn <= allowance + m.open_tol)

        new_state = np.where(closed, SLIDE, OPEN).astype(np.int8)
        omega_changed = False
        just_closed = closed & was_open & ve
        if just_closed.any():
            # lock position: where the vertex crossed the reference line during the step (§2.8.3)
            self._omega_at_crossing(contacts, just_closed, dn0, sca, disp, vertex_xy, geom)
            omega_changed = True
        if omega_changed:
            vec[:], sca[:] = self.contact_vectors(vertex_xy, geom, contacts)
        ds = sca[:, 2] + shift[:, 2] + np.einsum("ij,ij->i", vec[:, S_ES], da) + \
            np.einsum("ij,ij->i", vec[:, S_GS], db)
        normal = m.penalty * np.maximum(-dn, 0.0)
        strength = normal * contacts.tan_phi + contacts.cohesion * contacts.length * contacts.bond
        # a round-off allowance on ds (not open_tol: any larger allowance would act as a
        # cohesion ks·allowance per contact)
        holds = m.shear_penalty * (np.abs(ds) - m.roundoff) <= strength
        sliding_before = prev == SLIDE
        # a sliding contact locks when its motion in this step runs against its sliding
        # direction (ds is measured from an anchor that carries the friction force, so the
        # motion is ds - ds at the step start)
        motion = ds - sca[:, 2]
        turned = sliding_before & (motion * contacts.shear_dir < -m.reversal_tol)
        frictional = contacts.friction_deg > 0.9
        lock = closed & ve & np.where(sliding_before, turned & frictional, holds)
        new_state[lock] = LOCK
        # a new sliding direction: contacts that start sliding, and frictionless ones that turn
        # round (smaller reversals keep the direction: they are round-off, not stick)
        start_slide = closed & ve & ~lock & ((prev != SLIDE) | (turned & ~frictional))
        # direction of the new sliding: the motion in this step when it is significant (in an
        # impact the vertex may move against the spring's stretch, and friction must oppose the
        # motion), else the spring's stretch (Shi's rule, right for quasi-static loading); for a
        # contact that just closed, ds is the motion since the crossing
        significant = ~was_open & (np.abs(motion) > m.reversal_tol)
        new_dir = np.where(np.where(significant, motion, ds) >= 0, 1, -1).astype(np.int8)
        contacts.shear_dir[start_slide] = new_dir[start_slide]

        # the entrance line of a vertex-vertex contact matters only while it is closed
        switched = vv & (line != contacts.line) & (new_state != OPEN) & (prev != OPEN)
        change = (new_state != prev) | switched
        if flips is not None:
            if hold:
                # anti-cycling: a closed contact switching between locked and sliding for the
                # third time in this attempt is cycling with others at the friction limit;
                # hold it locked (its force stays within the cycle's amplitude of the limit) so
                # that the rest can settle. Open/closed decisions are never held: forcing a
                # separating contact shut, or a penetrating one open, injects energy.
                cycling = change & (flips >= 2) & ve & (prev != OPEN) & (new_state != OPEN)
                new_state[cycling] = LOCK
                change = (new_state != prev) | switched
            flips += change
        changed = bool(np.any(change))
        contacts.normal_force[~was_open] = normal[~was_open]
        contacts.state[:] = new_state
        contacts.line[:] = line
        contacts.dn[:] = dn
        contacts.ds[:] = ds
        return changed

    def _omega_at_crossing(self, contacts: Contacts, sel: np.ndarray, dn0: np.ndarray, sca: np.ndarray,
                           disp: np.ndarray, vertex_xy: np.ndarray, geom: dict) -> None:
        from .geometry import displacement_matrix

        m = self.model
        ci = contacts.cint[sel]
        start = sca[sel, 0]
        end = dn0[sel]
        frac = np.where(start > 0, start / np.maximum(start - end, 1e-300), 0.0)
        frac = np.clip(frac, 0.0, 1.0)
        idx = np.stack([ci[:, V0], m.vertex_next[ci[:, E0]], ci[:, E0]], axis=1)  # P1, P2, P3
        blocks = m.vertex_block[idx]
        pts = vertex_xy[idx]
        u = np.einsum("nkij,nkj->nki", displacement_matrix(pts, geom["centroid"][blocks]), disp[blocks])
        pts = pts + frac[:, None, None] * u
        d = pts[:, 2] - pts[:, 1]
        contacts.omega[sel] = ((pts[:, 0] - pts[:, 1]) * d).sum(axis=1) / (d * d).sum(axis=1)

    def _attempt(self, state: State, geom: dict, contacts0: Contacts, pattern: BlockPattern,
                 vec0: np.ndarray, sca0: np.ndarray, dt: float, timer: _Timer) -> _Attempt:
        """Block terms, then the open-close iteration, then the acceptance checks (§4.4–4.5)."""
        p, m = self.params, self.model
        t0 = _time.perf_counter()
        contacts = contacts0.copy()
        vec, sca = vec0.copy(), sca0.copy()
        data0, rhs0 = self.assemble_blocks(state, geom, pattern, dt)
        t0 = timer.add("assembly", t0)
        converged = False
        disp = None
        it = 0
        flips = np.zeros(contacts.n, np.int64)
        # rotation of each block in this step: predicted from the carried motion, then the
        # latest iterate's (for the second-order terms of the constraints)
        rotation = dt * p.velocity_carry * state.block_velocity[:, 2] + 0.5 * dt * dt * state.block_accel[:, 2]
        rotation[m.block_fixed] = 0.0
        for it in range(1, p.oc_max_iterations + 1):
            data, rhs = data0.copy(), rhs0.copy()
            shift = self.second_order(contacts, state, geom, rotation, pattern, rhs)
            self.assemble_contacts(contacts, pattern, vec, sca + shift, data, rhs)
            t0 = timer.add("assembly", t0)
            disp = self.solve(pattern, data, rhs)
            t0 = timer.add("solve", t0)
            if not np.all(np.isfinite(disp)):
                return _Attempt(ok=False, cause="nan", iterations=it)
            rotation = disp[:, 2].copy()
            friction = self.friction_force(contacts)  # the loads of this solve, for the energy balance
            changed = self.judge(contacts, vec, sca, disp, state.vertex_xy, geom, shift=shift, flips=flips,
                                 hold=it >= ANTI_CYCLING_FROM)
            t0 = timer.add("update", t0)
            if not changed:
                converged = True
                break
        if not converged:
            return _Attempt(ok=False, cause="open-close", iterations=it)
        umax = self._max_vertex_displacement(state.vertex_xy, geom, disp)
        closed = contacts.state != OPEN
        pen = float(np.max(-contacts.dn[closed], initial=0.0))
        ratio = umax / m.max_step
        result = _Attempt(ok=True, displacement=disp, contacts=contacts, iterations=it,
                          max_displacement=umax, max_penetration=max(pen, 0.0), ratio=ratio,
                          friction=friction, vec=vec)
        if ratio > p.displacement_reject:
            result.ok, result.cause = False, "displacement"
        elif pen > m.penetration_limit:
            result.ok, result.cause = False, "penetration"
        timer.add("update", t0)
        return result

    def update(self, state: State, geom: dict, disp: np.ndarray, contacts: Contacts, dt: float) -> State:
        """Move vertices and points (exact rotation, §5.3), update stresses (§5.4), velocities
        (§5.2) and the contact memory."""
        m, p = self.model, self.params
        centroid = geom["centroid"]
        xy = _move_points(state.vertex_xy, m.vertex_block, centroid, disp)
        fp = _move_points(state.fixed_point_xy, m.fixed_point_block, centroid, disp)
        lp = _move_points(state.load_xy, m.load_block, centroid, disp)
        mp = _move_points(state.measured_xy, m.measured_block, centroid, disp)
        strain = disp[:, 3:6]
        stress = state.block_stress + np.einsum("bij,bj->bi", m.block_elastic, strain)
        stress = _rotate_stress(stress, disp[:, 2])
        stress[m.block_fixed] = state.block_stress[m.block_fixed]
        # Newmark, γ = 1: a_{n+1} = (D − v Δt)/(βΔt²) − (1/(2β) − 1) a_n, v_{n+1} = v + Δt a_{n+1}
        # (β = ½: v_{n+1} = 2D/Δt − v, Shi's update, §5.2)
        beta = self.newmark_beta(state)
        carried = p.velocity_carry * state.block_velocity
        block_accel = (disp - carried * dt) / (beta * dt * dt) - (0.5 / beta - 1.0) * state.block_accel
        velocity = carried + dt * block_accel
        velocity[m.block_fixed] = 0.0
        block_accel[m.block_fixed] = 0.0
        radius = self._block_radius(state.vertex_xy, centroid)
        dv = velocity - state.block_velocity
        accel = float(np.max(np.hypot(dv[:, 0], dv[:, 1]) + np.abs(dv[:, 2]) * radius, initial=0.0)) / dt
        if p.static:
            velocity[:] = 0.0
            block_accel[:] = 0.0
        return State(
            geometry=m.block_geometry(xy),
            time=state.time + dt, step=state.step + 1, vertex_xy=xy, block_velocity=velocity,
            block_stress=stress, block_accel=block_accel, block_rotation=state.block_rotation + disp[:, 2],
            fixed_point_xy=fp, load_xy=lp, measured_xy=mp, dt=dt, accel=accel,
            memory=contacts.memory(p.bond_breaks_on_slip))

    # ------------------------------------------------------------------ helpers
    def _load_forces(self, t: float) -> np.ndarray:
        return np.array([f(t) if callable(f) else f for f in self.model.load_force], dtype=float).reshape(-1, 2)

    def _block_radius(self, vertex_xy: np.ndarray, centroid: np.ndarray) -> np.ndarray:
        r = np.hypot(*(vertex_xy - centroid[self.model.vertex_block]).T)
        return np.maximum.reduceat(r, self.model.vertex_offset[:-1])

    def _max_vertex_displacement(self, vertex_xy, geom, disp) -> float:
        moved = _move_points(vertex_xy, self.model.vertex_block, geom["centroid"], disp) - vertex_xy
        return float(np.max(np.hypot(moved[:, 0], moved[:, 1]), initial=0.0))


def _move_points(xy: np.ndarray, block: np.ndarray, centroid: np.ndarray, disp: np.ndarray) -> np.ndarray:
    """Displace material points with the exact-rotation update (dda-method.md §5.3):
    translation and strain from D, the rigid rotation r0 applied as a finite rotation, so a
    spinning block keeps its area."""
    if len(xy) == 0:
        return xy.copy()
    d = disp[block]
    X = xy[:, 0] - centroid[block, 0]
    Y = xy[:, 1] - centroid[block, 1]
    c, s = np.cos(d[:, 2]), np.sin(d[:, 2])
    ux = d[:, 0] + d[:, 3] * X + 0.5 * d[:, 5] * Y + X * (c - 1.0) - Y * s
    uy = d[:, 1] + d[:, 4] * Y + 0.5 * d[:, 5] * X + X * s + Y * (c - 1.0)
    return xy + np.stack([ux, uy], axis=1)


def _rotate_stress(stress: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """Rotate the stress tensor with the block (objective update, §5.4)."""
    c, s = np.cos(angle), np.sin(angle)
    sx, sy, t = stress[:, 0], stress[:, 1], stress[:, 2]
    return np.stack([c * c * sx - 2 * c * s * t + s * s * sy,
                     s * s * sx + 2 * c * s * t + c * c * sy,
                     c * s * (sx - sy) + (c * c - s * s) * t], axis=1)


def simulate(scene: Scene, params: Optional[Params] = None, duration: Optional[float] = None,
             steps: Optional[int] = None, record_every: int = 1, *, record_contacts: bool = False,
             progress: Optional[Callable[[State, tuple], None]] = None) -> Results:
    """Run a DDA simulation of ``scene``.

    Parameters
    ----------
    scene : the model to run (validated before any work).
    params : numerical parameters; ``None`` = `Params()` (automatic time step and penalty).
    duration : simulated time to reach [s]; the last step is shortened to end on it.
    steps : number of steps to take (when both are given, whichever comes first).
    record_every : record a frame every this many steps (and always the last).
    record_contacts : also record contact points and states per frame.
    progress : called as ``progress(state, step_record)`` after every step.

    Returns
    -------
    Results. A run that diverges raises `SimulationError` (step, cause, and the results
    recorded so far in ``.results``).
    """
    if duration is None and steps is None:
        raise ValueError("simulate: give a duration [s] or a number of steps")
    if duration is not None and not (np.isfinite(duration) and duration > 0):
        raise ValueError(f"simulate: duration must be a finite number > 0 s, got {duration!r}")
    if steps is not None and not (isinstance(steps, (int, np.integer)) and steps > 0):
        raise ValueError(f"simulate: steps must be a positive integer, got {steps!r}")
    if not (isinstance(record_every, (int, np.integer)) and record_every > 0):
        raise ValueError(f"simulate: record_every must be a positive integer, got {record_every!r}")
    model = build_model(scene, params)
    stepper = Stepper(model)
    state = model.initial_state()
    recorder = Recorder(model, record_contacts)
    recorder.frame(state, model.block_geometry(state.vertex_xy)["centroid"])
    n = 0
    while True:
        if duration is not None and state.time >= duration * (1 - 1e-12):
            break
        if steps is not None and n >= steps:
            break
        try:
            state, record = stepper.step(state, t_end=duration)
        except SimulationError as err:
            err.results = recorder.results()
            raise
        n += 1
        recorder.step(record)
        last = (duration is not None and state.time >= duration * (1 - 1e-12)) or \
               (steps is not None and n >= steps)
        if n % record_every == 0 or last:
            cxy = cst = None
            if record_contacts:
                c = stepper.last_contacts
                cxy = state.vertex_xy[c.cint[:, V0]]
                cst = c.state
            recorder.frame(state, state.geometry["centroid"], cxy, cst)
        if progress is not None:
            progress(state, record)
    return recorder.results()
