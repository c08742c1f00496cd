"""Start from equilibrium: the model's gravitational (and initial-load) equilibrium before t = 0.

Gravity switched on at t = 0 is an impulsive load: contact springs that start unloaded
overshoot the static forces, bonded joints slip in the first steps and lose their cohesion,
and a slope that limit equilibrium calls stable can fail in its own start-up transient
(docs/method/dda.md §8.12). UDEC/3DEC and FLAC models start with an equilibrium stage, ntdda with its
gravity turn-on phase. ddatai's stage (`Params.initial_equilibrium`, on by default) is a static
solve of the model under its weight, the point loads at t = 0 and its initial stresses:

1. The contacts that touch at t = 0 start locked; the open-close iteration then applies the
   contact law of a step (no tension beyond a bond's strength, Coulomb friction with
   cohesion) with one difference: joints are Mohr–Coulomb, perfectly plastic — a contact
   loaded to its strength slides and keeps its cohesion while its load moves to the rest of
   the joint and to other joints. The ground acceleration is the dynamic input and is left out.
2. K is the static stiffness (elastic blocks, contact and fixed-point springs) plus the
   inertia of a very long pseudo time step, over which free fall would cover 1e4 block sizes:
   it keeps K regular for a block that nothing holds and does not change a held block's
   displacement measurably.
3. A block that moves more than a quarter of its size away from what holds it, or whose
   contacts sink deeper than the penetration limit, is a mechanism that the contacts cannot
   hold: a free block, one balanced on a corner, a column that topples, a group that limit
   equilibrium calls unstable. "Away from what holds it": the block is not tied to the ground
   (fixed blocks, fixed points) through a chain of closed contacts across which the two blocks
   move alike — a tall, soft column settles by more than a quarter of a block at its top, every
   block with its neighbours, and is held. A mechanism is *released*: its contacts leave the
   stage and it starts at t = 0 from its initial position under sudden gravity (as without the
   stage), and the others are solved again.
4. The held blocks move by the solution (their elastic settlement), their stresses and contact
   springs carry the equilibrium forces, and their velocities are the scene's initial ones. A
   contact that reached its strength in the stage starts locked at its strength with its bond
   intact.

5. If the static open-close iteration does not converge (contacts near zero force in a fitted
   mass of blocks flip between states), the stage starts again as a ladder of pseudo-steps with
   inertia: Δt from the run's step, doubling up to the static pseudo time step, each starting
   from the contact states of the last; a pseudo-step that does not converge is retried with a
   shorter Δt while the ladder climbs past the Δt of its last failure. Each solve then stays close to the last, as in a
   dynamic step.
6. If the ladder fails too (a stiff, fitted mass of blocks whose joints slip by microns under
   the Poisson effect of their own weight: thousands of contacts near the Coulomb limit, whose
   frictional equilibrium semismooth Newton does not find from the all-locked start), the
   model starts from its *welded* equilibrium: the same static solve with every touching
   contact held as it is (normal and shear springs, no open-close judgement), repeated at the
   settled geometry until the increment is round-off; blocks that move as mechanisms even so
   are released. Then each contact takes the joint law at t = 0: one pulled beyond its tensile
   strength opens, one sheared beyond its Coulomb strength is handed over locked at it
   (`StartRecord.at_strength`). The first steps release only the difference between the welded
   and the real joint forces instead of the whole weight (sudden gravity rings a stiff grid
   for its whole run and doubles the solves per step; docs/method/dda.md §8.12).
   `StartRecord.welded` says that a run started so.

So a model that limit equilibrium calls stable moves no more than its elastic settlement, and
one that it calls unstable starts failing at once: its released blocks start under sudden
gravity, and their bonded joints lose their bonds as soon as they slide or open (Shi's rule,
`Params.bond_breaks_on_slip`), as does a bonded joint that the stage finds pulled beyond its
tensile strength. `StartRecord` counts the contacts that reached their strength.
"""

from __future__ import annotations

import time as _time
from dataclasses import dataclass

import numpy as np

from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from .assembly import BlockPattern, assemble_blocks, assemble_contacts, contact_vectors, load_forces
from .contact_law import contact_law, friction_force
from .contacts import Contacts
from .geometry import displacement_matrix
from .kinematics import block_displacement, settle_points
from .layout import E0, KIND, LOCK, OPEN, SLIDE, VE
from .model import ContactMemory, State
from .open_close import open_close, solve
from .records import StepTimer

#: the pseudo time step: free fall over it covers this many median block sizes
FALL_IN_SIZES = 1e4
#: a block that moves more than this fraction of its size √area in the stage, away from the
#: ground (`_anchored`), is a mechanism. Over the pseudo time step a block that its contacts
#: cannot hold moves about FALL_IN_SIZES × (its net acceleration / g) sizes away from what
#: held it, so this catches every mechanism whose net acceleration exceeds 2.5e-5 g; a held
#: block moves with its neighbours, by its elastic settlement, which in a soft, tall model
#: exceeds a block size's quarter (a 60-block column with E = 100 MPa: 37 % at its top)
MECHANISM_SIZE = 0.25
#: a block of an iterate that did not converge moving more than this many times the free fall
#: of the pseudo-step (FALL_IN_SIZES sizes) is not moving as a mechanism: the iterate went astray
FREE_FALL_BOUND = 2.0
#: at most this many solves in a pseudo-step (each adds contacts that open, close or slide, or
#: releases mechanisms)
MAX_SOLVES = 30
#: a pseudo-step of the ladder (below) whose increment is this fraction of the median block
#: size has settled as far as inertia lets it: the ladder jumps to the static step
LADDER_DONE = 1e-8
#: a pseudo-step of the ladder that does not converge is tried again with a smaller Δt at most
#: this many times in all, and only while the ladder climbs past its last failure
MAX_LADDER_RETRIES = 8
#: Newmark's β of the stage's system: that of a first step (the stage's pseudo-steps have no
#: acceleration history; `kinematics.newmark_beta`)
STAGE_BETA = 0.5
#: at most this many pseudo-steps (each re-solves the increment at the settled geometry; the
#: second is ~strain × the first, the third round-off)
MAX_PSEUDO_STEPS = 8


@dataclass(frozen=True, kw_only=True)
class StartRecord:
    """What the equilibrium stage did (`Results.start`)."""

    solves: int
    """Static solves of the stage (0: nothing to settle) [-]."""
    held: int
    """Free blocks held in equilibrium by their contacts [-]."""
    released: int
    """Free blocks released as mechanisms (start under sudden gravity) [-]."""
    settlement: float
    """Largest vertex displacement of a held block in the stage [m]."""
    at_strength: int
    """Contacts of held blocks that reached their strength in the stage (they start locked at
    it, bonds intact) [-]."""
    wall_time: float
    """Wall time of the stage [s]."""
    welded: bool = False
    """The Mohr–Coulomb stage did not converge, and the model started from its welded
    equilibrium with each contact then at most at its strength (module docstring, 6.)."""


#: the record of a model with nothing to settle
NOTHING = StartRecord(solves=0, held=0, released=0, settlement=0.0, at_strength=0, wall_time=0.0)


def needs_settling(model) -> bool:
    """Whether anything loads the model at t = 0: gravity, point loads or initial stresses."""
    if model.n_free == 0:
        return False
    loaded = bool(np.any(model.gravity != 0.0)) or len(model.load_block) > 0
    return loaded or bool(np.any(model.initial_stress[~model.block_fixed] != 0.0))


def settle(stepper, state: State, welded: bool = False) -> tuple[State, StartRecord]:
    """The model's equilibrium at t = 0 (module docstring). Returns the settled state, whose
    contact memory carries the held contacts into the first step, and the stage's record.
    ``welded``: go straight to the welded equilibrium (6.), without the frictional stage."""
    t0 = _time.perf_counter()
    model = stepper.model
    if not needs_settling(model):
        return state, NOTHING
    geom = model.block_geometry(state.vertex_xy)
    size = np.sqrt(geom["area"])
    dt_static = _pseudo_time_step(stepper, geom, size)
    if welded:
        return _stage(stepper, state, size, dt_static, None, t0, welded=True)[:2]
    settled, record, converged = _stage(stepper, state, size, dt_static, None, t0)
    if not converged:
        # the static solve did not converge (contacts near zero force in a fitted mass of
        # blocks flip between states): approach it through pseudo-steps whose inertia keeps
        # each solve close to the last — Δt doubling from the run's step, each starting from
        # the contact states of the last, until the increments are round-off
        p = stepper.params
        dt = min(p.dt if p.dt is not None else p.dt_max, dt_static)
        settled, again, converged = _stage(stepper, state, size, dt_static, dt, t0)
        record = StartRecord(**{**vars(again), "solves": record.solves + again.solves})
    if not converged:
        # no frictional equilibrium found: start from the welded one, each contact then at most
        # at its strength (module docstring, 6.), rather than under sudden gravity
        settled, again, _ = _stage(stepper, state, size, dt_static, None, t0, welded=True)
        record = StartRecord(**{**vars(again), "solves": record.solves + again.solves})
    return settled, record


def _stage(stepper, state: State, size: np.ndarray, dt_static: float, dt_ladder, t0: float,
           welded: bool = False) -> tuple[State, StartRecord, bool]:
    """Pseudo-steps: with Δt = ``dt_static`` until the increment is round-off, or (the ladder)
    from ``dt_ladder`` doubling up to ``dt_static`` — a pseudo-step that does not converge is
    tried again with a smaller Δt (a quarter at the start, then half-way in log to the last
    that converged), and once an increment is round-off the ladder goes to ``dt_static``.
    ``welded``: every pseudo-step is one solve with the touching contacts held, and the
    contacts then take the joint law (`_unweld`). Returns (state, record, whether the
    open-close iterations converged)."""
    model = stepper.model
    free = ~model.block_fixed
    initial = state
    released = np.zeros(model.n_blocks, bool)
    at_strength: set = set()
    memory = ContactMemory.empty()
    last = None  # contacts of the last pseudo-step that converged
    solves = 0
    dt = dt_static if dt_ladder is None else dt_ladder
    converged_dt = None  # the last Δt of the ladder that converged
    failed_dt = None     # and the last that did not
    retries = 0
    budget = MAX_PSEUDO_STEPS + (0 if dt_ladder is None else 4 * int(np.log2(dt_static / dt_ladder)) + 16)
    for _ in range(budget):
        geom = state.geometry if state.geometry is not None else model.block_geometry(state.vertex_xy)
        cint, length = stepper.detect(state.vertex_xy)
        contacts = Contacts.start(model, state.vertex_xy, cint, length, memory, True)
        contacts = _subset(contacts, ~(released[contacts.block_a] | released[contacts.block_b]))
        if not np.any(contacts.state != OPEN):
            break  # nothing (left) touches: nothing to hold
        disp, n, found, contacts = _static_solve(stepper, state, geom, contacts, dt, released, size,
                                                 welded)
        solves += n
        # a pseudo-step of the ladder that fails is retried shorter, as long as the ladder has
        # climbed past the Δt of its last failure (else it is cycling there: give up)
        progress = failed_dt is None or dt > failed_dt * (1.0 + 1e-9)
        if disp is None and dt_ladder is not None and progress and retries < MAX_LADDER_RETRIES \
                and dt < dt_static:
            retries += 1
            failed_dt = dt
            dt = 0.25 * dt if converged_dt is None else float(np.sqrt(converged_dt * dt))
            continue
        if disp is None:  # no equilibrium: start under sudden gravity, as without the stage
            return initial, StartRecord(solves=solves, held=0, released=int(np.count_nonzero(free)),
                                        settlement=0.0, at_strength=0,
                                        wall_time=_time.perf_counter() - t0), False
        if found.any():
            # a released block starts from where it was at t = 0
            released |= found
            state = _restore(model, state, initial, found)
            geom = state.geometry
        held = free & ~released
        disp[~held] = 0.0
        step = float(block_displacement(model, state.vertex_xy, geom, disp).max(initial=0.0))
        state = settle_points(model, state, geom, disp)
        last = contacts
        # the contact states go on into the next pseudo-step (sliding ones keep sliding: locked
        # at their strength, an O(strain) increment would tip them over again and the next
        # open-close iteration would start from scratch)
        memory = contacts.memory(bond_breaks_on_slip=False)
        if step <= model.open_tol and dt >= dt_static:
            break  # the increment is round-off: an equilibrium of the settled geometry
        if dt < dt_static:
            converged_dt = dt
            # along the ladder, an increment of round-off size means the inertia no longer
            # holds anything back: go to the static step
            dt = dt_static if step <= LADDER_DONE * float(np.median(size)) else min(2.0 * dt, dt_static)
    if solves == 0:
        return initial, NOTHING, True
    if last is not None and welded:
        _unweld(stepper, last)
    if last is not None:
        # contacts sliding at their strength are handed over locked at it (force-continuous):
        # the stage ends in an equilibrium of springs, and they keep their bonds
        sliding = _lock_at_strength(stepper, last, state.vertex_xy)
        at_strength |= _keys(last, sliding)
        memory = last.memory(stepper.params.bond_breaks_on_slip)
    held = free & ~released
    moved = np.hypot(*(state.vertex_xy - initial.vertex_xy).T)
    settlement = float(np.max(moved[held[model.vertex_block]], initial=0.0))
    record = StartRecord(solves=solves, held=int(np.count_nonzero(held)),
                         released=int(np.count_nonzero(free & released)), settlement=settlement,
                         at_strength=len(at_strength & set(memory.key.tolist())),
                         wall_time=_time.perf_counter() - t0, welded=welded)
    return state.replace(memory=memory), record, True


def _restore(model, state: State, initial: State, blocks: np.ndarray) -> State:
    """``state`` with the given blocks (and their points) back where ``initial`` has them."""
    v = blocks[model.vertex_block]
    xy = np.where(v[:, None], initial.vertex_xy, state.vertex_xy)
    b = blocks[:, None]

    def points(now, then, owner):
        return np.where(blocks[owner][:, None], then, now) if len(owner) else now

    return state.replace(
        vertex_xy=xy, block_stress=np.where(b, initial.block_stress, state.block_stress),
        block_rotation=np.where(blocks, initial.block_rotation, state.block_rotation),
        fixed_point_xy=points(state.fixed_point_xy, initial.fixed_point_xy, model.fixed_point_block),
        load_xy=points(state.load_xy, initial.load_xy, model.load_block),
        measured_xy=points(state.measured_xy, initial.measured_xy, model.measured_block),
        geometry=model.block_geometry(xy))


def _pseudo_time_step(stepper, geom, size) -> float:
    """Δt over which free fall covers FALL_IN_SIZES median block sizes (module docstring, 2.)."""
    model = stepper.model
    accel = float(np.hypot(*model.gravity))
    if len(model.load_block):
        loads = load_forces(model, 0.0)
        mass = model.block_density * geom["area"]
        accel = max(accel, float(np.max(np.hypot(loads[:, 0], loads[:, 1]) / mass[model.load_block])))
    if accel == 0.0:  # initial stresses only: any acceleration scale will do
        accel = 1.0
    return float(np.sqrt(2.0 * FALL_IN_SIZES * np.median(size[~model.block_fixed]) / accel))


def _unweld(stepper, contacts: Contacts) -> None:
    """The joint law at the end of a welded stage, in place: a contact pulled beyond its
    tensile strength (T·L while bonded, else the round-off force) opens; a locked vertex-edge
    contact whose shear spring carries more than its Coulomb strength N·tanφ + c·L is marked
    sliding, to be handed over locked at that strength (`_lock_at_strength`)."""
    m = stepper.model
    closed = contacts.state != OPEN
    tensile = np.where(contacts.bond, contacts.tensile * contacts.length, 0.0)
    pulled = closed & (m.penalty * contacts.dn > tensile + m.force_roundoff)
    contacts.state[pulled] = OPEN
    contacts.normal_force[pulled] = 0.0
    ve = contacts.cint[:, KIND] == VE
    over = ve & (contacts.state == LOCK) & \
        (m.shear_penalty * np.abs(contacts.ds) > friction_force(contacts) + m.force_roundoff)
    contacts.state[over] = SLIDE
    contacts.shear_dir[over] = np.where(contacts.ds[over] >= 0, 1, -1)


def _welded_solve(stepper, state: State, geom: dict, contacts: Contacts, vec: np.ndarray,
                  sca: np.ndarray, pattern: BlockPattern, dt: float):
    """One static solve with every contact in the state it has (the touching ones locked),
    without open-close judgement; the contacts' distances and normal forces are updated to
    the solution in place. Returns D, or None if the solve is not finite."""
    m = stepper.model
    data, rhs = assemble_blocks(m, state, geom, pattern, dt, STAGE_BETA, static_start=True)
    assemble_contacts(m, contacts, pattern, vec, sca, data, rhs, stepper.serial_scatter)
    # K is symmetric: a welded stage changes no state, so its vertex-edge contacts stay locked
    # (only vertex-vertex ones are "sliding", with no friction) and none is coupled
    disp = solve(stepper, pattern, data, rhs, reuse=True)  # repeated at a settled geometry
    if not np.all(np.isfinite(disp)):
        return None
    law = contact_law(m, contacts, vec, sca, disp)
    closed = contacts.state != OPEN
    contacts.normal_force[:] = np.where(closed, np.maximum(-m.penalty * law.dn_now, 0.0), 0.0)
    if law.tan_phi is not None:  # Barton–Bandis: the friction of this normal stress
        contacts.tan_phi[closed] = law.tan_phi[closed]
    contacts.dn[:] = law.dn_now
    contacts.ds[:] = law.ds
    return disp


def _static_solve(stepper, state: State, geom: dict, contacts: Contacts, dt: float,
                  released: np.ndarray, size: np.ndarray, welded: bool = False):
    """One pseudo-step: the open-close iteration of the static system at this geometry, with
    Mohr–Coulomb joints (``welded``: one solve with the contacts held as they are); blocks that
    turn out to be mechanisms are released and the rest solved again. Returns (D or None when
    it does not converge, solves, newly released blocks, the contacts left); sliding contacts
    end locked at their strength."""
    model = stepper.model
    free = ~model.block_fixed
    out = released.copy()
    solves = 0
    while True:
        contacts = _subset(contacts, ~(out[contacts.block_a] | out[contacts.block_b]))
        vec, sca = contact_vectors(model, state.vertex_xy, geom, contacts)
        pattern = BlockPattern.build(model, contacts)
        if welded:
            disp = _welded_solve(stepper, state, geom, contacts, vec, sca, pattern, dt)
            n, converged = 1, True
        else:
            data0, rhs0 = assemble_blocks(model, state, geom, pattern, dt, STAGE_BETA, static_start=True)
            oc = open_close(stepper, state, geom, contacts, pattern, vec, sca, data0, rhs0,
                            np.zeros(model.n_blocks), StepTimer(), MAX_SOLVES, break_bonds=False)
            disp, n, converged = oc.displacement, oc.iterations, oc.converged
        solves += n
        if disp is None:
            return None, solves, out & ~released, contacts
        moved = block_displacement(model, state.vertex_xy, geom, disp)
        if not converged and np.any((moved > FREE_FALL_BOUND * FALL_IN_SIZES * size)[free & ~out]):
            # a motion beyond free fall over the pseudo-step is no mechanism but an iterate that
            # went astray (contacts near zero force flipping in a stiff, fitted mass of blocks)
            return None, solves, out & ~released, contacts
        # a block that moved far is a mechanism unless it moved with the ground: a tall, soft
        # column settles by more than MECHANISM_SIZE at its top, every block with its neighbours
        far = free & ~out & (moved > MECHANISM_SIZE * size)
        mechanism = far & ~_anchored(stepper, state.vertex_xy, geom, contacts, disp, size) if far.any() else far
        # a block held only by contacts deeper than the penetration limit is not held (the
        # penalty is too soft for its load): it starts as a mechanism, and the run reports it
        deep = (contacts.state != OPEN) & (-contacts.dn > model.penetration_limit)
        if deep.any():
            sunk = np.zeros(model.n_blocks, bool)
            sunk[contacts.block_a[deep]] = True
            sunk[contacts.block_b[deep]] = True
            mechanism |= sunk & free & ~out
        if not mechanism.any():
            if not converged:  # no mechanism to blame: the held blocks found no equilibrium
                return None, solves, out & ~released, contacts
            break
        # release them and solve the rest again without their contacts. The iteration need not
        # have converged: a mechanism moves up to ~FALL_IN_SIZES sizes in the pseudo-step, its
        # contacts slide off their edges and their states cycle, so its open-close iteration
        # has no answer to converge to — its last iterate already shows it moving away (no
        # faster than free fall: checked above)
        out |= mechanism
    return disp, solves, out & ~released, contacts


def _anchored(stepper, vertex_xy, geom, contacts: Contacts, disp: np.ndarray, size: np.ndarray) -> np.ndarray:
    """Blocks tied to the ground — fixed blocks and blocks with fixed points — through chains of
    closed contacts across which the two blocks move alike: each block's vertices, moved by its
    own displacement field and by its neighbour's (T·D of docs/method/dda.md §1.1), differ by
    less than MECHANISM_SIZE × the smaller block's size. A held block differs from its
    neighbour by its strain and the contact springs' give; a mechanism slides, opens or turns
    away from what holds it by about FALL_IN_SIZES × its net acceleration / g sizes."""
    model = stepper.model
    closed = contacts.state != OPEN
    pa = np.minimum(contacts.block_a[closed], contacts.block_b[closed]).astype(np.int64)
    pb = np.maximum(contacts.block_a[closed], contacts.block_b[closed]).astype(np.int64)
    pairs = np.unique(np.stack([pa, pb], axis=1), axis=0) if len(pa) else np.zeros((0, 2), np.int64)
    alike = np.ones(len(pairs), bool)
    centroid = geom["centroid"]
    off = model.vertex_offset
    for own, other in ((pairs[:, 0], pairs[:, 1]), (pairs[:, 1], pairs[:, 0])):
        # the vertices of `own`, pair by pair
        count = off[own + 1] - off[own]
        row = np.repeat(np.arange(len(pairs)), count)
        start = np.repeat(off[own] - np.cumsum(count) + count, count)
        vertex = start + np.arange(int(count.sum()))
        xy = vertex_xy[vertex]
        u_own = np.einsum("nij,nj->ni", displacement_matrix(xy, centroid[own[row]]), disp[own[row]])
        u_other = np.einsum("nij,nj->ni", displacement_matrix(xy, centroid[other[row]]), disp[other[row]])
        gap = np.zeros(len(pairs))
        np.maximum.at(gap, row, np.hypot(*(u_own - u_other).T))
        alike &= gap < MECHANISM_SIZE * np.minimum(size[pairs[:, 0]], size[pairs[:, 1]])
    n = model.n_blocks
    graph = coo_matrix((np.ones(int(alike.sum())), (pairs[alike, 0], pairs[alike, 1])), shape=(n, n))
    _, label = connected_components(graph, directed=False)
    ground = model.block_fixed.copy()
    ground[model.fixed_point_block] = True
    return np.isin(label, label[ground])


def _keys(contacts: Contacts, sel: np.ndarray) -> set:
    return set(contacts.key[sel].tolist())


def _lock_at_strength(stepper, contacts: Contacts, vertex_xy: np.ndarray) -> np.ndarray:
    """Lock the sliding vertex-edge contacts, their lock point moved so that the shear spring
    carries their friction (force-continuous, as between steps): they keep their bonds.
    Returns which contacts were sliding."""
    m = stepper.model
    sliding = (contacts.state == SLIDE) & (contacts.cint[:, KIND] == VE)
    if sliding.any():
        strength = friction_force(contacts)[sliding]
        edge = contacts.cint[sliding, E0]
        length = np.hypot(*(vertex_xy[edge] - vertex_xy[m.vertex_next[edge]]).T)
        # ds = (P1 − P0)·t falls by l·Δω when the lock point P0 moves by Δω along the edge
        target = contacts.shear_dir[sliding] * strength / m.shear_penalty
        contacts.omega[sliding] += (contacts.ds[sliding] - target) / length
        contacts.ds[sliding] = target
        contacts.state[sliding] = LOCK
        contacts.coupled[sliding] = False
    return sliding


def _subset(contacts: Contacts, keep: np.ndarray) -> Contacts:
    return Contacts(**{k: v[keep] for k, v in vars(contacts).items()})
