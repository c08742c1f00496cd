"""One DDA time step, and `simulate` (docs/method/dda.md §0 skeleton).

``Stepper.step(state)`` reads like the algorithm::

    dt = choose_time_step            (§4.6)
    contacts = detect + transfer     (§3)
    repeat                           (step-restart loop)
        K, F = block terms           (§2.1–2.6)
        repeat                       (open-close iteration, §4: semismooth Newton)
            add contact springs and friction for the assumed states
            solve K D = F            (sparse Cholesky; LU where friction is implicit; the first
                                      solve refines with the last factor while it can)
            evaluate the contact law at D; shorten the step by a line search if it overshoots
            judge: contacts whose state breaks the law (or mismatches the motion) change
        until no contact has to change   else: dt *= 0.3, restart
        reject if displacement > 3·g2·w0, penetration too deep, or not finite: shorter dt, restart
    update vertices (exact rotation), stresses, velocities, points     (§5)

`simulate` first brings the model to equilibrium (`ddatai.start`) unless
``Params.initial_equilibrium`` is off. Each phase is timed into the step record
(`ddatai.results.STEP_DTYPE`).
"""

from __future__ import annotations

import dataclasses
import math
import time as _time
from dataclasses import dataclass
from typing import Callable, Optional

import numpy as np

from .contacts import KIND, V0, BlockPattern, Contacts, _Buffers, detect_contacts, N_SLOTS
from .geometry import mass_matrix
from .model import ContactKind, ContactState, Model, State, build_model
from .params import Params
from .results import Recorder, Results, SimulationError
from .scene import Scene

OPEN, SLIDE, LOCK = int(ContactState.OPEN), int(ContactState.SLIDE), int(ContactState.LOCK)
VE, VV = int(ContactKind.VE), int(ContactKind.VV)
# contact-vector slots (see ddatai.kernels)
S_E0, S_G0, S_E1, S_G1, S_ES, S_GS = range(6)


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
    friction: Optional[np.ndarray] = None  # friction magnitude S of each contact in the accepted solve
    vec: Optional[np.ndarray] = None       # contact vectors of the accepted solve
    coulomb: float = 0.0                   # largest (|shear force| − S)/S of a closed contact
    culprits: tuple = ()                   # (block a, block b) of the contacts behind a failure
    culprit_force: float = 0.0             # normal force of the deepest contact [N/m]
    changing: int = 0                      # contacts still changing state (open-close failure)


@dataclass
class ContactLaw:
    """The contact law evaluated at one solution D (`Stepper.contact_law`); (m,) arrays."""

    dn: np.ndarray         # normal distance of the less penetrated line [m]
    ds: np.ndarray         # shear displacement from the lock point [m]
    line: np.ndarray       # that line (VV contacts)
    closed: np.ndarray     # closed by the law
    state: np.ndarray      # the law's state (open, sliding, locked)
    direction: np.ndarray  # sliding direction sign(ds)
    fn: np.ndarray         # the law's normal force, compression positive [N/m]
    ft: np.ndarray         # the law's shear force along ∇ds [N/m]
    strength: np.ndarray   # Coulomb strength N·tanφ + c·L [N/m]
    dn_now: np.ndarray     # normal distance of the line the current state uses [m]
    fn_now: np.ndarray     # normal force of the current state at D [N/m]
    ft_now: np.ndarray     # shear force of the current state at D [N/m]
    friction_now: np.ndarray  # friction magnitude of the current (sliding) state at D [N/m]
    energy: float          # spring energy of the contacts with the friction of the next solve [J/m]
    tan_phi: Optional[np.ndarray] = None  # Barton–Bandis: tan φ(σn) at the law's σn (None: MC only)
    packed: Optional[tuple] = None  # the kernel's (float rows, int rows) the fields are views of


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
        # a block's weight, the smallest load the open-close judgement measures it by [N/m]
        self._block_load = model.block_density * model.block_geometry(model.vertex_xy0)["area"] * \
            float(np.hypot(*model.gravity))
        self._load_stiff = np.zeros(len(model.load_block))
        # softening Barton–Bandis joints: contacts remember how far they have slid
        self._softening = bool(len(model.joint_barton)) and bool(np.any(~np.isnan(model.joint_barton[:, 5])))
        self._factored_at = None  # (Δt, β) of the last attempt: its factor may serve the next

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
        # the shear springs as the step finds them (the lock point carried from the last step,
        # or the stage's force at strength): their energy belongs to the step's start energy
        contacts0.ds[:] = np.where(contacts0.cint[:, KIND] == VV, 0.0, sca[:, 2])
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
        if self._softening:
            self._accumulate_slip(attempt)
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
                  *energy, work[0], work[1], dissipated, attempt.coulomb)
        self.last_contacts = attempt.contacts
        return new_state, record

    def _accumulate_slip(self, attempt: "_Attempt") -> None:
        """Add the step's slip |e_sᵀ·D_a + g_sᵀ·D_b| (the vertex's displacement along the edge,
        §2.8.4) to every sliding vertex-edge contact on a softening joint (eq. BB7)."""
        c, vec, d = attempt.contacts, attempt.vec, attempt.displacement
        soft = (c.state == SLIDE) & (c.cint[:, KIND] != VV) & ~np.isnan(self.model.joint_barton[c.joint, 5])
        if soft.any():
            k = np.flatnonzero(soft)
            step = np.einsum("ij,ij->i", vec[k, S_ES], d[c.block_a[k]]) + \
                np.einsum("ij,ij->i", vec[k, S_GS], d[c.block_b[k]])
            c.slip[k] += np.abs(step)

    def energies(self, state: State, geom: dict, contacts: Optional[Contacts]) -> tuple:
        """(kinetic, gravitational, strain, contact) energy of a state [J/m] (ddatai.energy)."""
        from .energy import contact_energy, mechanical_energy

        kinetic, gravitational, strain, springs = mechanical_energy(
            self.model, geom, state.block_velocity, state.block_stress, state.fixed_point_xy)
        if len(self.model.bolt_block):
            from .support import bolt_energy

            springs += bolt_energy(self.model, state)
        return kinetic, gravitational, strain, springs + contact_energy(self.model, contacts)

    def work(self, state: State, geom: dict, attempt: _Attempt, dt: float) -> tuple[float, float]:
        """(external work, friction dissipation) of the accepted step [J/m]."""
        from .energy import external_work, friction_work

        m = self.model
        t_mid = state.time + 0.5 * dt
        ground = np.asarray(m.ground_acceleration(t_mid), float) if m.ground_acceleration is not None else None
        loads = self._load_forces(t_mid) if len(m.load_block) else np.zeros((0, 2))
        external = external_work(m, geom, attempt.displacement, state.load_xy, loads, ground)
        if m.water_unit_weight > 0:
            from .support import support_work

            external += support_work(m, state.vertex_xy, geom["centroid"], attempt.displacement)
        friction = friction_work(attempt.contacts, attempt.vec, attempt.friction, attempt.displacement) \
            if attempt.contacts.n else 0.0
        return external, friction

    def _failure_message(self, attempt: _Attempt, state: State, dt: float) -> str:
        """Why a step failed, with the numbers, the blocks or contacts, and what to change."""
        step = state.step + 1
        m, p = self.model, self.params
        if attempt.cause == "open-close":
            named = ", ".join(f"blocks {a}-{b}" for a, b in attempt.culprits)
            what = (f"the open-close iteration did not converge in {p.oc_max_iterations} iterations "
                    f"({attempt.changing} contacts still changing state, e.g. between {named})")
            advice = "raise Params.oc_max_iterations, or loosen Params.oc_state_tolerance"
        elif attempt.cause == "nan":
            what = "the solution is not finite (NaN or infinite displacements)"
            advice = ("the system is singular or overflowed: check the blocks' Young's moduli and "
                      f"densities and the penalty p = {m.penalty:.3g} Pa")
        elif attempt.cause == "penetration":
            (a, b), force = attempt.culprits[0], attempt.culprit_force
            what = (f"runaway penetration: {attempt.max_penetration:.4g} m between blocks {a} and {b} "
                    f"exceeds the limit 2.5·g3·w0 = {m.penetration_limit:.4g} m (contact force "
                    f"{force:.3g} N/m against the penalty p = {m.penalty:.3g} Pa)")
            advice = ("raise Params.penalty (or penalty_ratio) so that force/p stays well below the limit, "
                      "or raise Params.penetration_ratio (docs/method/limits.md)")
        else:
            what = (f"the step displacement {attempt.max_displacement:.4g} m exceeds "
                    f"{p.displacement_reject:g} × g2·w0 = {p.displacement_reject * m.max_step:.4g} m")
            advice = "lower Params.max_displacement_ratio or the time step"
        return (f"simulation diverged at step {step} (t = {state.time:.6g} s): {what}, even with the "
                f"time step cut to {dt:.3g} s; {advice}{self._unit_causes()}")

    def _unit_causes(self) -> str:
        """The model's material and joint values that look like another unit (`unit_hint`), as
        the likely cause of a failure; empty if none does."""
        from .params import unit_hint

        m, p = self.model, self.params
        values = [("Material", "density", float(d)) for d in np.unique(m.block_density)]
        if p.penalty is None:  # the automatic penalty comes from the largest Young's modulus
            values.append(("Material", "young", m.penalty / p.penalty_ratio))
        values += [("Joint", name, float(v)) for name, arr in (("friction", m.joint_friction),
                                                               ("cohesion", m.joint_cohesion),
                                                               ("tensile", m.joint_tensile))
                   for v in np.unique(arr)]
        hints = [f"{owner}.{h}" for owner, name, v in values if (h := unit_hint(name, v)) is not None]
        return ". Likely cause: " + "; ".join(hints) if hints else ""

    # ------------------------------------------------------------------ phases
    def choose_time_step(self, state: State, geom: dict) -> float:
        """Automatic Δt (docs/method/dda.md §4.6): the step whose predicted largest vertex
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
            if acc > 0 or speed > 0:
                # the positive root of ½·a·Δt² + v·Δt = u in the form that does not cancel:
                # (−v + √(v² + 2au))/a loses every digit when a is round-off small beside v²/u
                # (a fast block without gravity: Δt came out 0)
                dt = 2.0 * u / (speed + math.sqrt(speed * speed + 2.0 * acc * u))
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

    def assemble_blocks(self, state: State, geom: dict, pattern: BlockPattern, dt: float,
                        static_start: bool = False) -> tuple[np.ndarray, np.ndarray]:
        """The part of K and F that does not depend on contact states: inertia, elasticity,
        initial stress, body force, fixed points and point loads (§2.1–2.6), the loads and
        ground acceleration taken at mid-step. ``static_start``: the equilibrium stage's system
        (`ddatai.start`): loads at t = 0, no ground acceleration, the state's velocities and
        accelerations ignored."""
        from . import kernels as K

        model = self.model
        data = np.zeros(pattern.nnz)
        rhs = np.zeros(6 * pattern.n_rows)
        if pattern.n_rows == 0:
            return data, rhs
        t_mid = state.time if static_start else state.time + 0.5 * dt
        body = model.gravity.copy()
        if model.ground_acceleration is not None and not static_start:
            # the ground's frame: every block feels -a_g(t) (§2.4, seismic body force)
            body -= np.asarray(model.ground_acceleration(t_mid), dtype=float)
        mass = mass_matrix(geom["area"], geom["s1"], geom["s2"], geom["s3"])
        velocity, accel = state.block_velocity, state.block_accel
        if static_start:
            velocity, accel = np.zeros_like(velocity), np.zeros_like(accel)
        K.assemble_blocks(self.dof, model.block_density, model.block_elastic, geom["area"], mass,
                          velocity, accel, state.block_stress, float(body[0]),
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
        if model.water_unit_weight > 0 or len(model.bolt_block):
            # water pressure (W2) and bolt springs (B1), docs/method/water_bolts.md
            from .support import assemble_bolts, assemble_water

            if model.water_unit_weight > 0:
                assemble_water(model, state.vertex_xy, centroid, rhs)
            if len(model.bolt_block):
                assemble_bolts(model, state.vertex_xy, centroid, state.bolt_broken_step < 0, pattern, data, rhs)
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
        const, slope = self.friction_terms(contacts)
        K.assemble_contacts(contacts.cint, contacts.state, contacts.line, m.vertex_block, self.dof,
                            vec, sca, const, slope, contacts.shear_dir,
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

    def friction_terms(self, contacts: Contacts) -> tuple[np.ndarray, np.ndarray]:
        """(a, b) of each sliding contact's friction magnitude S = a − b·dn in the next solve:
        a coupled contact takes N = −p·dn of that solve (a = c·L, b = p·tanφ), the others the
        N of an earlier one (a = `friction_force`, b = 0)."""
        cohesion = contacts.cohesion * contacts.length * contacts.bond
        a = np.where(contacts.coupled, cohesion, self.friction_force(contacts))
        b = np.where(contacts.coupled, self.model.penalty * contacts.tan_phi, 0.0)
        return a, b

    def solve(self, pattern: BlockPattern, data: np.ndarray, rhs: np.ndarray, symmetric: bool = True,
              reuse: bool = False) -> np.ndarray:
        """Solve K D = F (`ddatai.solver`); returns D as (B, 6) with zeros for fixed blocks.
        ``symmetric=False`` when coupled friction made K non-symmetric; ``reuse`` when K should
        be close to the matrix last factorised (a step's first solve: the same contact states
        at a slightly moved geometry), which the solver then tries to solve with that factor."""
        d = np.zeros((self.model.n_blocks, 6))
        if pattern.n_rows == 0:
            return d
        x = self.solver.solve(data, pattern.indices, pattern.indptr, rhs, pattern=pattern,
                              symmetric=symmetric, reuse=reuse)
        d[self.free_idx] = x.reshape(-1, 6)
        return d

    def contact_law(self, contacts: Contacts, vec: np.ndarray, sca: np.ndarray, disp: np.ndarray,
                    shift: Optional[np.ndarray] = None) -> "ContactLaw":
        """The contact law at the displacements ``disp`` (§2.8, §4.3), without changing
        ``contacts`` (`contact_law_numpy` states it). A Taichi kernel evaluates it
        (`kernels.contact_law`); models with Barton–Bandis joints, whose friction follows the
        law's own normal stress, take the NumPy path, which is also the kernel's reference."""
        if contacts.n == 0 or len(self.model.joint_barton):
            return self.contact_law_numpy(contacts, vec, sca, disp, shift)
        from . import kernels as K

        m = self.model
        cstate, cvalue = self._law_inputs(contacts)
        constant = sca if shift is None else sca + shift
        out_f = np.empty((10, contacts.n))
        out_i = np.empty((4, contacts.n), np.int8)
        K.contact_law(contacts.cint, cstate, cvalue, contacts.block_a, contacts.block_b, vec,
                      np.ascontiguousarray(constant), np.ascontiguousarray(disp), m.penalty,
                      m.shear_penalty, m.penetration_limit, out_f, out_i)
        return ContactLaw(dn=out_f[K.LAW_DN], ds=out_f[K.LAW_DS], line=out_i[K.LAW_LINE],
                          closed=out_i[K.LAW_CLOSED].view(bool), state=out_i[K.LAW_STATE],
                          direction=out_i[K.LAW_DIRECTION], fn=out_f[K.LAW_FN], ft=out_f[K.LAW_FT],
                          strength=out_f[K.LAW_STRENGTH], dn_now=out_f[K.LAW_DN_NOW],
                          fn_now=out_f[K.LAW_FN_NOW], ft_now=out_f[K.LAW_FT_NOW],
                          friction_now=out_f[K.LAW_FRICTION_NOW],
                          energy=float(np.sum(out_f[K.LAW_ENERGY])), packed=(out_f, out_i))

    @staticmethod
    def _law_inputs(contacts: Contacts) -> tuple[np.ndarray, np.ndarray]:
        """The per-contact inputs of the judgement kernels, field-major: (state, line, coupled,
        bond, shear direction) as int8 and (tan φ, cohesion, tensile strength, length, normal
        force) as float64 (`kernels.IN_*`)."""
        cstate = np.empty((5, contacts.n), np.int8)
        cstate[0], cstate[1], cstate[2] = contacts.state, contacts.line, contacts.coupled
        cstate[3], cstate[4] = contacts.bond, contacts.shear_dir
        cvalue = np.empty((5, contacts.n))
        cvalue[0], cvalue[1], cvalue[2] = contacts.tan_phi, contacts.cohesion, contacts.tensile
        cvalue[3], cvalue[4] = contacts.length, contacts.normal_force
        return cstate, cvalue

    def contact_law_numpy(self, contacts: Contacts, vec: np.ndarray, sca: np.ndarray, disp: np.ndarray,
                          shift: Optional[np.ndarray] = None) -> "ContactLaw":
        """The contact law at the displacements ``disp`` (§2.8, §4.3), without changing
        ``contacts``: the NumPy path of `contact_law`.

        A contact is closed while its normal distance dn ≤ T·L/p (bonded) or 0, with normal
        force −p·dn; a closed vertex-edge contact sticks while its shear spring force k_s·ds ≤
        S = N·tanφ + c·L (bonded), else it slides with friction S against the sign of ds (the
        return mapping of a penalty-regularised Coulomb law: ds is measured from the lock point
        of the step start, so a sliding contact's trial force starts at its friction). Also
        the forces that the state each contact has now gives at ``disp``.
        """
        m = self.model
        a, b = contacts.block_a, contacts.block_b
        da, db = disp[a], disp[b]
        shift = np.zeros_like(sca) if shift is None else shift
        dn0 = sca[:, 0] + shift[:, 0] + np.einsum("ij,ij->i", vec[:, S_E0], da) + \
            np.einsum("ij,ij->i", vec[:, S_G0], db)
        vv = contacts.cint[:, KIND] == VV
        ve = ~vv
        dn_now = dn0.copy()   # normal distance of the line the contact's state uses
        dn = dn0.copy()       # of the line the law uses: the less penetrated one
        line = np.zeros(contacts.n, np.int8)
        if vv.any():
            # line 1: vertex1 (of block b) against an edge of block a
            dn1 = sca[vv, 1] + shift[vv, 1] + np.einsum("ij,ij->i", vec[vv, S_E1], db[vv]) + \
                np.einsum("ij,ij->i", vec[vv, S_G1], da[vv])
            dnl = np.stack([dn0[vv], dn1], axis=1)
            rows = np.arange(len(dn1))
            dn_now[vv] = dnl[rows, contacts.line[vv]]
            # the entrance line: the less penetrated one (Shi), but never a line the vertex was
            # already behind at the step start by more than any contact may penetrate — it
            # passed that line's extension outside the other block and can only enter through
            # the other line (a corner thrown past a corner would otherwise be pushed out
            # sideways through a face it never crossed, gaining energy; docs/method/dda.md §2.8.7)
            behind = sca[vv, :2] < -m.penetration_limit
            line[vv] = np.where(behind[:, 0] != behind[:, 1], behind[:, 0], dn1 > dn0[vv]).astype(np.int8)
            dn[vv] = dnl[rows, line[vv]]
        ds = np.where(ve, sca[:, 2] + shift[:, 2] + np.einsum("ij,ij->i", vec[:, S_ES], da) +
                      np.einsum("ij,ij->i", vec[:, S_GS], db), 0.0)
        # normal: closed while not pulled beyond the tensile strength of a bonded joint
        allowance = np.where(contacts.bond, contacts.tensile * contacts.length / m.penalty, 0.0)
        closed = dn <= allowance
        tan_phi = contacts.tan_phi
        if len(m.joint_barton):
            # Barton–Bandis joints: the friction of the law's own normal stress (eq. BB1–BB2)
            from .contacts import barton_tan

            tan_phi = tan_phi.copy()
            bb = np.flatnonzero(~np.isnan(m.joint_barton[contacts.joint, 0]))
            tan_phi[bb] = barton_tan(m, contacts.joint[bb], m.penalty * np.maximum(-dn[bb], 0.0),
                                     contacts.length[bb], contacts.slip[bb])
        strength = m.penalty * np.maximum(-dn, 0.0) * tan_phi + \
            contacts.cohesion * contacts.length * contacts.bond
        # the friction the next solve can apply: N of the last one (or of this one, coupled)
        used = np.where(contacts.coupled, strength, self.friction_force(contacts))
        trial = m.shear_penalty * ds
        stick = np.abs(trial) <= used
        ft = np.where(closed & ve, np.where(stick, trial, np.sign(ds) * used), 0.0)
        state = np.where(closed, np.where(ve & stick, LOCK, SLIDE), OPEN).astype(np.int8)
        # energy of the contact springs with that friction: ½p·dn² (up to the tensile
        # strength) and the Huber function of ds (½k_s·ds², then linear at the friction)
        normal_energy = 0.5 * m.penalty * np.where(dn <= allowance, dn * dn, allowance * allowance)
        limit = used / m.shear_penalty
        huber = np.where(np.abs(ds) <= limit, 0.5 * m.shear_penalty * ds * ds, used * (np.abs(ds) - 0.5 * limit))
        energy = float(np.sum(normal_energy) + np.sum(huber[closed & ve]))
        # the forces of the current states at this D
        now = contacts.state
        fn_now = np.where(now == OPEN, 0.0, -m.penalty * dn_now)
        friction_now = self._friction_used(contacts, dn_now)
        ft_now = np.where(now == LOCK, trial, np.where(now == SLIDE, contacts.shear_dir * friction_now, 0.0))
        ft_now[vv] = 0.0
        return ContactLaw(dn=dn, ds=ds, line=line, closed=closed, state=state,
                          direction=np.where(ds >= 0, 1, -1).astype(np.int8), fn=np.where(closed, -m.penalty * dn, 0.0),
                          ft=ft, strength=strength, dn_now=dn_now, fn_now=fn_now, ft_now=ft_now,
                          friction_now=friction_now, energy=energy,
                          tan_phi=tan_phi if len(m.joint_barton) else None)

    def judge(self, contacts: Contacts, law: "ContactLaw", break_bonds: bool = True,
              bad: Optional[np.ndarray] = None) -> bool:
        """Open-close judgement (§4.2–4.3) in place; returns True if a contact must change.

        The solve assumed a state for each contact; ``law`` (`contact_law` at the solution)
        says which state the contact's motion calls for. A contact must change (`violations`)
        if its assumed state breaks the contact law — a locked contact holding more than its
        Coulomb strength, a sliding one whose friction is not N·tanφ + c·L of this solve, a
        closed one pulling harder than its tensile strength — or if its state does not match
        its motion by more than a small force (an open contact that overlaps, a sliding one
        that would stick). Such a contact takes the law's state, a sliding one with its friction
        from the solve it is in (it becomes `coupled`: implicit friction), and the step
        iterates again. When none must change, every contact obeys no-tension and Coulomb's
        law at the solution.
        """
        p = self.params
        vv = contacts.cint[:, KIND] == VV
        if bad is None:  # `violations` of this law, unless the caller has them
            bad = self.violations(contacts, law)
        # a bonded joint that the law opens (tension beyond T·L) or, with Shi's rule, makes
        # slide has failed in this step: it loses its cohesion and tensile strength now, and
        # the step is solved again without them (its strength is not carried through the step
        # in which it breaks)
        breaks = break_bonds & contacts.bond & (law.state != LOCK) & bad & \
            ((law.state == OPEN) | (p.bond_breaks_on_slip & (law.state == SLIDE)))
        if breaks.any():
            contacts.bond[breaks] = False
        self.last_bad = bad
        changed = bool(np.any(bad))
        if changed:
            # a sliding contact whose slip turns round passes through sticking: it locks
            # (Shi's rule) and slides the other way only if its spring then exceeds S. Newton's
            # step in the sliding state has no shear stiffness, so the reversed friction would
            # overshoot the sticking range again, and the contact would flip for ever
            turns = bad & (contacts.state == SLIDE) & (law.state == SLIDE) & (law.direction != contacts.shear_dir)
            law.state[turns] = LOCK
            slide = bad & (law.state == SLIDE) & ~vv
            # friction from the same solve from now on: the normal force of the last solve is
            # stale for a contact that was locked or open in it, or whose force moved
            contacts.coupled |= slide
            contacts.shear_dir[slide] = law.direction[slide]
            contacts.state[bad] = law.state[bad]
            contacts.line[bad] = law.line[bad]
        closed = law.closed
        contacts.normal_force[closed] = np.maximum(law.fn[closed], 0.0)
        # a contact left closed (within the state tolerance) that the law opens carries no normal
        # force: its friction bound is 0, not the force of an earlier solve
        contacts.normal_force[~closed & (contacts.state != OPEN)] = 0.0
        if law.tan_phi is not None:
            # Barton–Bandis: the next solve's secant friction is that of this solve's σn (eq.
            # BB3); a sliding contact whose friction was not it is a `violations` Coulomb
            # mismatch, so at convergence every contact holds the law at its own stress
            contacts.tan_phi[closed] = law.tan_phi[closed]
        contacts.dn[:] = np.where(bad, law.dn, law.dn_now)
        contacts.ds[:] = law.ds
        if not changed:
            closed_ve = (contacts.state != OPEN) & ~vv
            self._coulomb = float(np.max((np.abs(law.ft_now) - law.strength)[closed_ve], initial=0.0))
            self._friction = law.friction_now
        return changed

    def violations(self, contacts: Contacts, law: "ContactLaw") -> np.ndarray:
        """Contacts whose assumed state must change, given the law at the solution
        (`violations_numpy` states the rules): a Taichi kernel (`kernels.violations`) for a
        law the kernel evaluated, the NumPy path otherwise."""
        if law.packed is None:
            return self.violations_numpy(contacts, law)
        from . import kernels as K

        m, p = self.model, self.params
        cstate, cvalue = self._law_inputs(contacts)
        bad = np.empty(contacts.n, np.int8)
        K.violations(contacts.cint, cstate, cvalue, contacts.block_a, contacts.block_b, law.packed[0],
                     law.packed[1], self._block_load.copy(), m.penalty, p.oc_force_tolerance,
                     p.oc_state_tolerance, m.force_roundoff, bad)
        return bad.view(bool)

    def violations_numpy(self, contacts: Contacts, law: "ContactLaw") -> np.ndarray:
        """Contacts whose assumed state must change, given the law at the solution.

        Strict, within ``oc_force_tolerance`` of the contact's own strength (plus the round-off
        force p·open_tolerance·w0): Coulomb's law (a locked contact's shear force ≤ S, a
        sliding one's friction = S of this solve) and the tensile strength (a closed contact
        pulls at most T·L while bonded, else not at all). Within ``oc_state_tolerance`` × the
        load its blocks carry (their weight or their largest contact force): the match of state
        and motion — an open contact that overlaps, a sliding one that would stick or slide
        the other way. A contact that carries almost nothing (a head joint of a loaded grid)
        then does not keep the iteration flipping it between open and closed, or between
        sticking and sliding, at forces far below anything that moves its blocks."""
        m, p = self.model, self.params
        vv = contacts.cint[:, KIND] == VV
        now = contacts.state
        atol = m.force_roundoff
        strict = p.oc_force_tolerance * law.strength + atol
        locked = (now == LOCK) & ~vv
        sliding = (now == SLIDE) & ~vv & law.closed
        coulomb = locked & (np.abs(law.ft_now) > law.strength + strict)
        friction = sliding & (np.abs(law.friction_now - law.strength) > strict)
        tensile = np.where(contacts.bond, contacts.tensile * contacts.length, 0.0)
        tension = (now != OPEN) & (-law.fn_now > tensile + p.oc_force_tolerance * tensile + atol)
        # the load each block carries: its weight, or its largest contact force
        level = self._block_load.copy()
        np.maximum.at(level, contacts.block_a, np.abs(law.fn))
        np.maximum.at(level, contacts.block_b, np.abs(law.fn))
        loose = p.oc_state_tolerance * np.maximum(level[contacts.block_a], level[contacts.block_b]) + atol
        state = (np.abs(law.fn_now - law.fn) > loose) | (np.abs(law.ft_now - law.ft) > loose)
        # a VV contact whose other line is clearly less penetrated switches
        state |= vv & (now != OPEN) & (law.line != contacts.line) & (m.penalty * np.abs(law.dn - law.dn_now) > loose)
        return coulomb | friction | tension | state

    def _friction_used(self, contacts: Contacts, dn: np.ndarray) -> np.ndarray:
        """Friction magnitude S each contact's state applies in a solve with normal distance
        ``dn`` (`friction_terms`)."""
        const, slope = self.friction_terms(contacts)
        return const - slope * dn

    def internal_force(self, contacts: Contacts, vec: np.ndarray, law: "ContactLaw") -> np.ndarray:
        """Generalised forces (6 per free block) of the contact forces of ``law``: the gradient
        of the spring energies, p·dn·∇dn of a closed contact and f_t·∇ds of its shear force
        (`kernels.internal_force` for a law the kernel evaluated)."""
        if law.packed is None or contacts.n == 0:
            return self.internal_force_numpy(contacts, vec, law)
        from . import kernels as K

        out = np.zeros(6 * self.model.n_free)
        K.internal_force(contacts.block_a, contacts.block_b, self.dof, vec, law.packed[0], law.packed[1],
                         out, self._serial_scatter)
        return out

    def internal_force_numpy(self, contacts: Contacts, vec: np.ndarray, law: "ContactLaw") -> np.ndarray:
        """`internal_force` in NumPy (the path of a NumPy law, and the kernel's reference)."""
        rows = self.model.n_free
        out = np.zeros(6 * rows)
        if contacts.n == 0:
            return out
        pull = np.where(law.closed, -law.fn, 0.0)  # p·dn
        line1 = (law.line == 1)[:, None]
        grad_a = np.where(line1, vec[:, S_G1], vec[:, S_E0])
        grad_b = np.where(line1, vec[:, S_E1], vec[:, S_G0])
        fa = pull[:, None] * grad_a + law.ft[:, None] * vec[:, S_ES]
        fb = pull[:, None] * grad_b + law.ft[:, None] * vec[:, S_GS]
        k = np.arange(6)
        for blocks, f in ((contacts.block_a, fa), (contacts.block_b, fb)):
            r = self.dof[blocks]
            use = r >= 0
            out += np.bincount((6 * r[use])[:, None].repeat(6, 1).ravel() + np.tile(k, int(use.sum())),
                               weights=f[use].ravel(), minlength=6 * rows)
        return out

    def open_close(self, state: State, geom: dict, contacts: Contacts, pattern: BlockPattern,
                   vec: np.ndarray, sca: np.ndarray, data0: np.ndarray, rhs0: np.ndarray,
                   rotation: np.ndarray, timer: "_Timer", max_iterations: int, break_bonds: bool = True,
                   reuse_first: bool = True) -> tuple[Optional[np.ndarray], int, bool]:
        """The open-close iteration (§4) in place on ``contacts``: (D, iterations, converged);
        D is None when a solve is not finite. ``reuse_first``: the first solve may try the last
        factor (the states are the ones it was made with; `solve`).

        Semismooth Newton on the contact law: each solve takes the contact states (and the
        Jacobian of their forces) at the last iterate, so when no state has to change the
        solution satisfies the law at every contact. A step of Newton's method can overshoot
        into a state that sends the next one back (a contact that carries almost no normal
        force, flipping between sticking and sliding); from the second solve on it is
        shortened by a backtracking line search on the energy (`_line_search`).
        """
        from scipy.sparse import csr_matrix

        n = 6 * pattern.n_rows
        block_k = None   # K of the block terms, for the line search (built when first needed)
        previous = None  # last iterate D
        disp = None
        for it in range(1, max_iterations + 1):
            t0 = _time.perf_counter()
            data, rhs = data0.copy(), rhs0.copy()
            shift = self.second_order(contacts, state, geom, rotation, pattern, rhs)
            block_rhs = rhs.copy()
            self.assemble_contacts(contacts, pattern, vec, sca + shift, data, rhs)
            t0 = timer.add("assembly", t0)
            symmetric = not bool(np.any(contacts.coupled & (contacts.state == SLIDE) & (contacts.tan_phi > 0)))
            # the first solve has the states the last one ended with: K has moved only with
            # the blocks, and the last factor may still solve it (`ddatai.solver`, reuse)
            solution = self.solve(pattern, data, rhs, symmetric=symmetric, reuse=reuse_first and it == 1)
            t0 = timer.add("solve", t0)
            if not np.all(np.isfinite(solution)):
                return None, it, False
            law = self.contact_law(contacts, vec, sca, solution, shift)
            bad = self.violations(contacts, law)
            disp = solution
            if previous is not None and bad.any():
                if block_k is None:
                    block_k = csr_matrix((data0, pattern.indices, pattern.indptr), shape=(n, n))
                damped, damped_law = self._line_search(contacts, vec, sca, shift, previous, solution, law,
                                                       block_k, block_rhs)
                # the shortened step stops before the contacts that change state on the way to
                # the solution; if none has changed there yet, the states change as the
                # solution asks (the step then continues in the next piece)
                if damped is not solution:
                    damped_bad = self.violations(contacts, damped_law)
                    if damped_bad.any():
                        disp, law, bad = damped, damped_law, damped_bad
            rotation = disp[:, 2].copy()
            changed = self.judge(contacts, law, break_bonds, bad=bad)
            timer.add("update", t0)
            if not changed and disp is solution:
                return disp, it, True
            previous = disp
        return disp, max_iterations, False

    def _line_search(self, contacts, vec, sca, shift, previous, solution, law, block_k, block_rhs):
        """Backtracking (Armijo) from the last iterate towards the new solution on the energy
        Π(D) = ½·Dᵀ·K_blocks·D − F_blocksᵀ·D + the contact springs' energy (penalty springs, and
        the Huber potential of each shear spring at its friction): with the friction held, Π is
        convex and the solution of the solve minimises its quadratic piece at the last iterate,
        so the step is a descent direction and Π falls at every iterate."""
        rows = self.free_idx

        def energy(d, lw):
            x = d[rows].ravel()
            return 0.5 * float(x @ (block_k @ x)) - float(block_rhs @ x) + lw.energy

        law_prev = self.contact_law(contacts, vec, sca, previous, shift)
        base = energy(previous, law_prev)
        grad = block_k @ previous[rows].ravel() - block_rhs + self.internal_force(contacts, vec, law_prev)
        slope = float(grad @ (solution - previous)[rows].ravel())
        if slope >= 0:  # not a descent direction (coupled friction): take the step
            return solution, law
        alpha, d, lw = 1.0, solution, law
        while alpha > 1.0 / 256:
            if energy(d, lw) <= base + 1e-4 * alpha * slope:
                break
            alpha *= 0.5
            d = previous + alpha * (solution - previous)
            lw = self.contact_law(contacts, vec, sca, d, shift)
        return d, lw

    def _attempt(self, state: State, geom: dict, contacts0: Contacts, pattern: BlockPattern,
                 vec0: np.ndarray, sca0: np.ndarray, dt: float, timer: _Timer) -> _Attempt:
        """Block terms, then the open-close iteration, then the acceptance checks (§4.4–4.5)."""
        p, m = self.params, self.model
        t0 = _time.perf_counter()
        contacts = contacts0.copy()
        vec, sca = vec0.copy(), sca0.copy()
        data0, rhs0 = self.assemble_blocks(state, geom, pattern, dt)
        timer.add("assembly", t0)
        # rotation of each block in this step: predicted from the carried motion, then the
        # latest iterate's (for the second-order terms of the constraints)
        rotation = dt * p.velocity_carry * state.block_velocity[:, 2] + 0.5 * dt * dt * state.block_accel[:, 2]
        rotation[m.block_fixed] = 0.0
        # the last factor can solve the first solve only at the Δt (and β) it was made with:
        # the inertia 2M/Δt² is a large part of K (`ddatai.solver`, reuse)
        factored_at = (dt, self.newmark_beta(state))
        reuse, self._factored_at = factored_at == self._factored_at, factored_at
        disp, it, converged = self.open_close(state, geom, contacts, pattern, vec, sca, data0, rhs0,
                                              rotation, timer, p.oc_max_iterations, reuse_first=reuse)
        if disp is None:
            return _Attempt(ok=False, cause="nan", iterations=it)
        if not converged:
            bad = np.flatnonzero(self.last_bad)  # of the last judgement
            pairs = tuple(sorted({(int(contacts.block_a[i]), int(contacts.block_b[i])) for i in bad[:200]})[:3])
            return _Attempt(ok=False, cause="open-close", iterations=it, culprits=pairs, changing=len(bad))
        t0 = _time.perf_counter()
        umax = self._max_vertex_displacement(state.vertex_xy, geom, disp)
        closed = contacts.state != OPEN
        depth = np.where(closed, -contacts.dn, 0.0)
        deepest = int(np.argmax(depth)) if contacts.n else -1
        pen = float(depth[deepest]) if contacts.n else 0.0
        ratio = umax / m.max_step
        result = _Attempt(ok=True, displacement=disp, contacts=contacts, iterations=it,
                          max_displacement=umax, max_penetration=max(pen, 0.0), ratio=ratio,
                          friction=self._friction, vec=vec, coulomb=self._coulomb)
        if ratio > p.displacement_reject:
            result.ok, result.cause = False, "displacement"
        elif pen > m.penetration_limit:
            result.ok, result.cause = False, "penetration"
            result.culprits = ((int(contacts.block_a[deepest]), int(contacts.block_b[deepest])),)
            result.culprit_force = float(contacts.normal_force[deepest])
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
        bolts = {}
        if len(m.bolt_block):
            # bolt tensions on the moved ends; those beyond their capacity break (B1)
            from .support import break_bolts

            bolts = break_bolts(m, state, xy, state.step + 1, state.time + dt)
        return State(
            geometry=m.block_geometry(xy),
            time=state.time + dt, step=state.step + 1, vertex_xy=xy, block_velocity=velocity,
            block_stress=stress, block_accel=block_accel, block_rotation=state.block_rotation + disp[:, 2],
            fixed_point_xy=fp, load_xy=lp, measured_xy=mp, dt=dt, accel=accel,
            memory=contacts.memory(p.bond_breaks_on_slip), **bolts)

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
    """Displace material points with the exact-rotation update (docs/method/dda.md §5.3):
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
             steps: Optional[int] = None, record_every: Optional[int] = None, *,
             record_contacts: Optional[bool] = None,
             progress: Optional[Callable[[State, tuple], None]] = None,
             checkpoint=None, checkpoint_every: Optional[int] = None, resume=None) -> Results:
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
    checkpoint : path of a checkpoint file (`ddatai.checkpoint`), written every
        ``checkpoint_every`` steps (when given) and when the run is interrupted; each write
        replaces the last.
    checkpoint_every : steps between two checkpoints (each holds every frame recorded so far, so
        one every few hundred steps or more keeps their cost small).
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
    from .checkpoint import DeferInterrupt, RunTargets, read_checkpoint, write_checkpoint
    from .results import SimulationInterrupted
    from .solver import SparseSolver

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
    model = build_model(scene, params)
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
    from .results import block_materials, run_metadata

    recorder.metadata = run_metadata(scene, model)
    recorder.block_material = block_materials(scene)[1]
    if resume is not None:
        state = saved.state
        recorder.seed(saved.results, state)
    else:
        state = model.initial_state()
        if model.params.initial_equilibrium:
            from .start import settle

            state, start = settle(stepper, state)
            recorder.start.append(dataclasses.astuple(start))
        recorder.frame(state, model.block_geometry(state.vertex_xy)["centroid"])

    def finished(s: State) -> bool:
        return (duration is not None and s.time >= duration * (1 - 1e-12)) or \
               (steps is not None and s.step >= steps)

    try:
        while not finished(state):
            try:
                new_state, record = stepper.step(state, t_end=duration)
            except SimulationError as err:
                err.results = recorder.results()
                raise
            # the step's records, its frame and a checkpoint are stored whole: Ctrl-C waits
            with DeferInterrupt():
                recorder.step(record)
                state = new_state
                if state.step % record_every == 0 or finished(state):
                    _record_frame(recorder, stepper, state, record_contacts)
                if checkpoint_every is not None and state.step % checkpoint_every == 0:
                    write_checkpoint(checkpoint, state=state, results=recorder.results(), model=model,
                                     targets=targets)
                    # a resumed run starts with a new solver; so does this one, so that both go
                    # on with the same numbers (PARDISO keeps an analysis of an earlier matrix)
                    stepper.solver = SparseSolver(model.params.solver)
            if progress is not None:
                progress(state, record)
    except KeyboardInterrupt:
        results = recorder.results()
        written = None
        if checkpoint is not None:
            with DeferInterrupt():
                written = write_checkpoint(checkpoint, state=state, results=results, model=model,
                                           targets=targets)
        raise SimulationInterrupted(step=state.step, time=state.time, results=results,
                                    checkpoint=written) from None
    return recorder.results()


def _record_frame(recorder: Recorder, stepper: Stepper, state: State, record_contacts: bool) -> None:
    """Record a frame of ``state``, with the contacts of the step that produced it."""
    if not record_contacts:
        recorder.frame(state, state.geometry["centroid"])
        return
    c = stepper.last_contacts
    recorder.frame(state, state.geometry["centroid"], state.vertex_xy[c.cint[:, V0]], c.state,
                   _contact_forces(stepper, c))


def _contact_forces(stepper: Stepper, c: Contacts) -> tuple[np.ndarray, np.ndarray]:
    """Normal (compression positive) and shear force [N/m] of each contact of an accepted step:
    the contact law at its last solve, in which no contact changed state (`Stepper.judge`) — a
    locked contact's shear spring k_s·ds, a sliding one's friction, nothing for an open one."""
    closed = c.state != OPEN
    normal = np.where(closed, c.normal_force, 0.0)
    ve = c.cint[:, KIND] != VV
    friction = np.broadcast_to(np.asarray(getattr(stepper, "_friction", 0.0), float), (c.n,))
    shear = np.where(c.state == LOCK, stepper.model.shear_penalty * c.ds,
                     np.where(c.state == SLIDE, c.shear_dir * friction, 0.0))
    return normal, np.where(ve, shear, 0.0)
