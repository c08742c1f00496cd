"""Start from equilibrium: the model's gravitational (and initial-load) equilibrium before t = 0.

Gravity switched on at t = 0 is an impulsive load: contact springs that start unloaded
overshoot the static forces, bonded joints slip in the first steps and lose their cohesion,
and a slope that limit equilibrium calls stable can fail in its own start-up transient
(docs/method/dda.md §8.12). UDEC/3DEC and FLAC models start with an equilibrium stage, ntdda with its
gravity turn-on phase. ddatai's stage (`Params.initial_equilibrium`, on by default) is a static
solve of the model under its weight, the point loads at t = 0 and its initial stresses:

1. The contacts that touch at t = 0 start closed and locked. The stage applies the contact law
   of a step (no tension beyond a bond's strength, Coulomb friction with cohesion) with one
   difference: joints are Mohr–Coulomb, perfectly plastic — a contact loaded to its strength
   slides and keeps its cohesion while its load moves to the rest of the joint and to other
   joints. The ground acceleration is the dynamic input and is left out.
2. K is the static stiffness (elastic blocks, contact and fixed-point springs) plus the
   inertia of a very long pseudo time step, over which free fall would cover 1e4 block sizes:
   it keeps K regular for a block that nothing holds and does not change a held block's
   displacement measurably.
3. The equilibrium is found by *return mapping* (``_iterate``): every closed contact stays a spring —
   normal, and for a vertex-edge contact shear from its lock point, moved by how far the contact has
   slid —, the slip of a contact whose spring carries more than its Coulomb strength grows by the excess
   (the return mapping of elastic, perfectly plastic friction, Anderson-accelerated), and a contact
   opens where it pulls beyond its tensile strength or closes where it overlaps (K changes only then;
   otherwise the last factor solves the next iterate, and where states change the step stops where the
   energy stops falling). Once no state has changed for NEWTON_AFTER iterations, what is left is the
   slips' linear convergence: the open-close iteration of a static step (semismooth Newton, the contacts
   at their strength sliding) finishes it from there in a few solves where it converges and moves no
   block away, once a pseudo-step (`return_mapping`); an iteration that stalls goes on from there with
   each vertex-edge contact that has opened or closed CHATTER_FLIPS times opening by the return mapping
   of its normal spring (tension cut-off, K kept), as corner contacts of blocks cut by persistent joints
   otherwise do by turns for the whole iteration. It ends when no state changes and every contact force
   is the contact law's within ``ddatai.return_mapping.STAGE_FORCE_TOLERANCE`` (1e-6, stricter than a
   step's ``Params.oc_force_tolerance``) × the load its blocks carry — the law's forces then balance
   every block within that much —, or, where the iteration stalls before, within
   ``Params.oc_state_tolerance``; in that case, and where a bonded contact ends at its strength (the
   run's first step would break its bond, Shi's rule, for the least excess), the open-close iteration of
   a static step finishes from there — its contacts at their strength sliding without springs, where a
   wedge slides until bolts or a wedging joint take its load — and its equilibrium is taken where it
   converges and moves nothing away. A contact without friction and cohesion has no shear spring.
   Semismooth Newton on the same law (the open-close iteration of a step) does not converge here from
   the all-locked start: a block whose contacts are sliding or open in an iterate has no stiffness but
   the pseudo inertia and is thrown ~1e4 sizes, which scrambles its neighbours' states, and in a fitted
   mass of stiff blocks groups of corner contacts flip together for ever (docs/method/dda.md §8.12).
4. A block that moves more than a quarter of its size away from what holds it, or whose
   contacts sink deeper than the penetration limit, is a mechanism that the contacts cannot
   hold: a free block, one balanced on a corner, a column that topples. "Away from what holds
   it": the block is not tied to the ground (fixed blocks, fixed points) through a chain of
   closed contacts across which the two blocks move alike — a tall, soft column settles by
   more than a quarter of a block at its top, every block with its neighbours, and is held. A
   block that slides as a mechanism keeps the return mapping out of balance: where it stalls,
   rigid-block limit equilibrium (`ddatai.limit_equilibrium`, a linear program over the
   contacts touching at t = 0) releases the blocks for which no admissible contact forces
   exist (a small model whose every block they let move is released before the first solve,
   ``ddatai.mechanisms.unsupported_at_start``). Admissible forces do not prove a block held (Coulomb friction is not associated:
   toppling columns have them), so the blocks still out of balance are then tested by the
   open-close iteration of a static step with their contacts at the strength sliding
   (``test_unbalanced``); where it converges, those that move away in it on which their loads
   do positive work are mechanisms (friction only resists: a block that friction pushed away
   against its loads is held). Where limit equilibrium holds every block, neither outcome of
   that test proves anything (non-associated friction: many static solutions); with
   ``Params.start_turn_on``, a slow turn-on of the weight settles the doubt (`ddatai.turn_on`):
   its last state is handed over where nothing moved away, else the blocks in doubt are released.
   Where nothing more is released and the return mapping still
   stalls, the stage ends there (``StartRecord.stalled``): its contacts are handed over at
   most at their strength, and the first steps settle the forces left out of balance, a
   fraction of the load. Models with bolts or a water table, whose forces the program does
   not carry, are tested by the open-close iteration alone. A mechanism is *released*: its contacts
   leave the stage and it starts at t = 0 from its initial position under sudden gravity (as
   without the stage), and the others are solved again from where they were. A held block that
   the stage settled into a released one (deeper than SUNK_FRACTION of the penetration limit)
   leant on it: it is released too and the stage is solved again from t = 0.
5. The held blocks move by the solution (their elastic settlement), their stresses and contact
   springs carry the equilibrium forces, and their velocities are the scene's initial ones:
   each contact is handed over locked, its lock point moved by its slip, and a contact at its
   strength starts locked at it with its bond intact. The stage repeats at the settled
   geometry until the contact forces there balance every block (``balanced``), a fixed-point
   iteration on the geometry: where an increment is as large as the one before (a tall, soft
   stack whose load grows with its deflection faster than its stiffness, P-delta), it does not
   converge and going on throws held blocks away, so the stage ends at the last pseudo-step's
   equilibrium (``StartRecord.unsettled``) and the run's dynamics takes the deflection on; so
   does one whose held blocks move that far where it would release blocks or give up
   (``ddatai.mechanisms.contracting``: what a diverging geometry throws is not a mechanism).
6. If no frictional equilibrium is found (a contracting pseudo-step out of solves, or, with bolts or water,
   out-of-balance blocks that the test does not move, or a first pseudo-step whose iterate left
   DDA's range, ``mechanisms.out_of_range``, ``StartRecord.diverged``), the model starts from its *welded* equilibrium: the
   same static solve with every touching contact held as it is (normal and shear springs, no
   open-close judgement), repeated at the settled geometry until the increment is round-off;
   blocks that move as mechanisms even so are released. Then each contact takes the joint law
   at t = 0: one pulled beyond its tensile strength opens, one sheared beyond its Coulomb
   strength is handed over locked at it (`StartRecord.at_strength`). The first steps release
   only the difference between the welded and the real joint forces instead of the whole
   weight (sudden gravity rings a stiff grid for its whole run and doubles the solves per
   step; docs/method/dda.md §8.12). `StartRecord.welded` says that a run started so
   (``ddatai.welded``). The frictional stage going on from the welded equilibrium, where the
   first pseudo-step left DDA's range, leaves it too (measured on ntdda's grid: the welded
   equilibrium holds it by tension and shear across its vertical joints; §8.12).

So a model that limit equilibrium calls stable moves no more than its elastic settlement, and
one that it calls unstable starts failing at once: its released blocks start under sudden
gravity, and their bonded joints lose their bonds as soon as they slide or open (Shi's rule,
`Params.bond_breaks_on_slip`), as does a bonded joint that the stage finds pulled beyond its
tensile strength. `StartRecord` counts the contacts that reached their strength.
"""

from __future__ import annotations

import time as _time
from dataclasses import dataclass, replace

import numpy as np

from .contact_law import contact_law, internal_force
from .contacts import Contacts, coupled, subset_contacts
from .kinematics import block_displacement, settle_points
from .layout import KIND, LOCK, OPEN, SLIDE, VE
from .model import ContactMemory, State
from .mechanisms import pseudo_time_step, restore, sunk_into_released, unsupported_at_start
from .return_mapping import Frame, return_mapping
from .threads import dense_solves
from .turn_on import feasible, turn_on
from .in_doubt import watched
from .welded import lock_at_strength, unweld, welded_step
#: at most this many pseudo-steps (each re-solves the increment at the settled geometry; the
#: second is ~strain × the first, the third round-off)
MAX_PSEUDO_STEPS = 8
#: round-off of the balance of the settled geometry that ends the pseudo-steps (`balanced`), as a
#: fraction of the load that a contact's blocks carry
BALANCE_ROUNDOFF = 1e-12
#: a held block that the stage settled into a released block deeper than this fraction of the
#: penetration limit is released too (``mechanisms.sunk_into_released``): ~1e-5·w0, far beyond a
#: held block's elastic settlement towards a neighbour and far below an overlap that kicks
SUNK_FRACTION = 0.01
#: a pseudo-step whose increment is at least this fraction of the last one's does not contract
GEOMETRY_CONTRACTION = 1.0
#: ``_pseudo_steps``' "no equilibrium" where the first pseudo-step left DDA's range (truthy)
DIVERGED = "diverged"


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
    """The frictional stage found no equilibrium, and the model started from its welded
    equilibrium with each contact then at most at its strength (module docstring, 6.)."""
    factorisations: int = 0
    """Factorisations of K among the solves (the others reuse the last factor) [-]."""
    stalled: bool = False
    """The return mapping stalled where rigid-block limit equilibrium holds every block left:
    the stage ended there, its contacts at most at their strength and its forces out of
    balance by a fraction of the load, which the first steps settle (module docstring, 4.)."""
    unsettled: bool = False
    """The pseudo-steps stopped contracting (an increment at the settled geometry as large as the
    one before: a tall, soft stack whose load grows with its deflection faster than its
    stiffness): the stage ended at the last pseudo-step's equilibrium and the run's dynamics
    takes the deflection from there (module docstring, 5.)."""
    turn_on_steps: int = 0
    """Steps of the slow gravity turn-on that settled the stage's doubt (`ddatai.turn_on`; 0:
    none ran) [-]."""
    in_doubt: int = 0
    """Released blocks that no converged test moved or held (in doubt): their first steps are
    resolved (`ddatai.in_doubt`) [-]."""
    diverged: bool = False
    """The first pseudo-step's iterate left DDA's range before it released anything
    (``ddatai.mechanisms.out_of_range``): the model started welded (module docstring, 6.)."""


#: the record of a model with nothing to settle
NOTHING = StartRecord(solves=0, held=0, released=0, settlement=0.0, at_strength=0, wall_time=0.0)


def needs_settling(model) -> bool:
    """Whether anything loads the model at t = 0: gravity, point loads or initial stresses."""
    if model.n_free == 0:
        return False
    loaded = bool(np.any(model.gravity != 0.0)) or len(model.load_block) > 0
    return loaded or bool(np.any(model.initial_stress[~model.block_fixed] != 0.0))


def settle(stepper, state: State, welded: bool = False, screen: bool = True) -> tuple[State, StartRecord]:
    """The model's equilibrium at t = 0 (module docstring). Returns the settled state, whose
    contact memory carries the held contacts into the first step, and the stage's record.
    ``welded``: go straight to the welded equilibrium (6.), without the frictional stage.
    ``screen``: release at once a model whose every free block limit equilibrium lets move
    (``ddatai.mechanisms.unsupported_at_start``); False: only as the return mapping finds them (the tests' reference)."""
    t0 = _time.perf_counter()
    model = stepper.model
    if not needs_settling(model):
        return state, NOTHING
    with dense_solves(stepper.solver):  # its many small solves on one BLAS thread, asked for once
        factorised = stepper.solver.factorisations
        geom = model.block_geometry(state.vertex_xy)
        size = np.sqrt(geom["area"])
        dt_static = pseudo_time_step(stepper, geom, size)
        settled, record, converged = _stage(stepper, state, size, dt_static, t0, welded=welded, screen=screen,
                                            slow=not welded and model.params.start_turn_on and feasible(model))
        if not converged:
            # no frictional equilibrium: start from the welded one (module docstring, 6.)
            settled, again, _ = _stage(stepper, state, size, dt_static, t0, welded=True)
            record = replace(again, solves=record.solves + again.solves, diverged=record.diverged)
    return settled, replace(record, factorisations=stepper.solver.factorisations - factorised,
                            wall_time=_time.perf_counter() - t0)


def _stage(stepper, state: State, size: np.ndarray, dt: float, t0: float,
           welded: bool = False, screen: bool = False, slow: bool = False) -> tuple[State, StartRecord, bool]:
    """Pseudo-steps with Δt = ``dt`` (the static pseudo time step) until the increment is
    round-off, each the return-mapping iteration of `return_mapping` (``welded``: one solve
    with the touching contacts held, `welded_step`, the contacts then taking the joint law,
    `unweld`). ``slow``: blocks in doubt (`return_mapping`, ``doubt``) are settled by a slow
    turn-on of the weight (`turn_on`); where it moves a block away, the stage is done again
    releasing them. Returns (state, record, whether every pseudo-step found its equilibrium)."""
    model = stepper.model
    free = ~model.block_fixed
    initial = state
    released = unsupported_at_start(stepper, state) if screen and not welded else np.zeros(model.n_blocks, bool)
    in_doubt, solves = np.zeros(model.n_blocks, bool), 0  # in_doubt: released as no converged test decided
    while True:
        doubt = np.zeros(model.n_blocks, bool) if slow else None
        state, last, memory, n, stalled, unsettled, failed = _pseudo_steps(stepper, initial, state, released, size,
                                                                           dt, welded, doubt, in_doubt)
        diverged = failed == DIVERGED
        solves += n
        if doubt is not None and np.count_nonzero(doubt) and not failed:
            slow_end = turn_on(stepper, initial, released, SUNK_FRACTION)
            if slow_end is not None:
                state, out, steps = slow_end
                moved = np.hypot(*(state.vertex_xy - initial.vertex_xy).T)[(free & ~out)[model.vertex_block]]
                return state, StartRecord(solves=solves, held=int(np.count_nonzero(free & ~out)),
                                          released=int(np.count_nonzero(free & out)), stalled=True, turn_on_steps=steps,
                                          settlement=float(np.max(moved, initial=0.0)), wall_time=_time.perf_counter() - t0,
                                          at_strength=int(np.count_nonzero(state.memory.state == SLIDE))), True
            again, record, converged = _stage(stepper, initial, size, dt, t0, welded, screen)
            return again, replace(record, solves=solves + record.solves), converged
        if failed:
            return initial, StartRecord(solves=solves, held=0, released=int(np.count_nonzero(free)),
                                        settlement=0.0, at_strength=0, diverged=diverged,
                                        wall_time=_time.perf_counter() - t0), False
        # a held block that settled into a released one would start overlapping it: the first
        # steps would throw both apart (the run's penalty raised many times over, its first
        # steps out of Coulomb's law: docs/method/dda.md §8.12). Its equilibrium leaned on the
        # released block: in doubt, it is released too, and the rest is solved again from t = 0
        sunk = sunk_into_released(stepper, state, released, SUNK_FRACTION)
        if not np.count_nonzero(sunk):
            break
        released |= sunk
        state = initial
    if solves == 0:
        gone = int(np.count_nonzero(free & released))
        return initial, NOTHING if not gone else replace(NOTHING, released=gone,
                                                         wall_time=_time.perf_counter() - t0), True
    at_strength: set = set()
    if last is not None and welded:
        unweld(stepper, last)
    if last is not None:
        # contacts sliding at their strength are handed over locked at it (force-continuous):
        # the stage ends in an equilibrium of springs, and they keep their bonds
        sliding = lock_at_strength(stepper, last, state.vertex_xy)
        at_strength |= set(last.key[sliding].tolist())
        memory = last.memory(stepper.params.bond_breaks_on_slip)
    held = free & ~released
    moved = np.hypot(*(state.vertex_xy - initial.vertex_xy).T)
    settlement = float(np.max(moved[held[model.vertex_block]], initial=0.0))
    record = StartRecord(solves=solves, held=int(np.count_nonzero(held)),
                         released=int(np.count_nonzero(free & released)), settlement=settlement,
                         at_strength=len(at_strength & set(memory.key.tolist())),
                         wall_time=_time.perf_counter() - t0, welded=welded, stalled=stalled,
                         unsettled=unsettled, in_doubt=int(np.count_nonzero(in_doubt)))
    return state.replace(memory=memory, in_doubt=watched(model, in_doubt)), record, True


def _pseudo_steps(stepper, initial: State, state: State, released: np.ndarray, size: np.ndarray, dt: float,
                  welded: bool, doubt: "np.ndarray | None" = None, in_doubt: "np.ndarray | None" = None):
    """The pseudo-steps of `_stage` from ``state`` with the ``released`` blocks out (updated in place with
    the blocks it releases; ``doubt``, ``in_doubt``: `return_mapping`'s). Returns (state, the last
    pseudo-step's contacts, their memory, solves, stalled, unsettled, whether a pseudo-step found no equilibrium:
    DIVERGED where the first one left DDA's range, `return_mapping`)."""
    model = stepper.model
    free = ~model.block_fixed
    memory = ContactMemory.empty()
    last = None  # the contacts of the last pseudo-step
    solves = 0
    stalled = False  # set by a pseudo-step that stalls, which then ends the stage
    increment = np.inf  # the last pseudo-step's largest displacement [m] (none yet: no limit)
    unsettled = False
    pattern = None  # the last frame's (`Frame.build`)
    for pseudo_steps in range(MAX_PSEUDO_STEPS):
        geom = state.geometry if state.geometry is not None else model.block_geometry(state.vertex_xy)
        cint, length = stepper.detect(state.vertex_xy, memory)
        contacts = Contacts.start(model, state.vertex_xy, cint, length, memory, True)
        contacts = subset_contacts(contacts, ~(released[contacts.block_a] | released[contacts.block_b]))
        if not np.count_nonzero(contacts.state != OPEN):
            break  # nothing (left) touches: nothing to hold
        if welded:
            disp, n, found, contacts = welded_step(stepper, state, geom, contacts, dt, released, size)
        else:
            frame = Frame.build(stepper, state, geom, contacts, dt, pattern)
            pattern = frame.pattern  # the next pseudo-step's contacts mostly couple the same blocks
            if pseudo_steps >= 2 and balanced(stepper, frame, contacts, geom, size):
                # the settled geometry holds: its contact forces balance every block (a second
                # pseudo-step first, which takes the first one's linearisation error out)
                break
            marked = None if in_doubt is None else in_doubt.copy()
            disp, n, found, contacts, stalled, unsettled, diverged = return_mapping(
                stepper, state, geom, contacts, dt, released, size, frame, doubt, in_doubt,
                contraction=GEOMETRY_CONTRACTION * increment)
            if diverged:
                return state, last, memory, solves + n, stalled, unsettled, DIVERGED
            if unsettled and marked is not None:
                in_doubt[:] = marked  # it released nothing: nothing it marked is in doubt
        solves += n
        if unsettled:
            break  # it would throw what its divergence moves: the last equilibrium, as below
        if disp is None:  # no equilibrium found
            return state, last, memory, solves, stalled, unsettled, True
        if np.count_nonzero(found):
            # a released block starts from where it was at t = 0
            released |= found
            state = restore(model, state, initial, found)
            geom = state.geometry
        held = free & ~released
        disp[~held] = 0.0
        step = float(block_displacement(stepper.model, state.vertex_xy, geom, disp).max(initial=0.0))
        if not np.count_nonzero(found) and step >= GEOMETRY_CONTRACTION * increment:
            # the pseudo-steps are a fixed-point iteration on the geometry (each solves the
            # static increment at the last one's settled shape); where an increment does not
            # shrink, the iteration does not converge — the load grows with the deflection
            # (a tall, soft column's P-delta) faster than the stiffness — and going on throws
            # held blocks away: the stage ends at the last pseudo-step's equilibrium and the
            # run's dynamics takes the deflection from there (docs/method/dda.md §8.12)
            unsettled = True
            break
        increment = step
        state = settle_points(stepper.model, state, geom, disp)
        last = contacts
        # the contacts go on into the next pseudo-step as they ended: locked ones with their
        # lock points moved by their slip, those at their strength sliding (`Contacts.start`
        # anchors them at their friction), all with their bonds
        memory = contacts.memory(bond_breaks_on_slip=False)
        if step <= model.open_tol:
            break  # the increment is round-off: an equilibrium of the settled geometry
        if stalled:
            # the return mapping stalled where limit equilibrium holds every block: another
            # pseudo-step would stall the same way; the first steps settle what is left
            break
    return state, last, memory, solves, stalled, unsettled, False


def balanced(stepper, frame: Frame, contacts: Contacts, geom: dict, size: np.ndarray) -> bool:
    """Whether the contacts as the last pseudo-step handed them over hold every block at this
    (settled) geometry to round-off: at D = 0 each keeps its state by the contact law, no shear
    spring exceeds its strength, and the contact law's forces balance each block's loads (force
    and moment rows), each within BALANCE_ROUNDOFF of the load its blocks carry (a block held
    by a weak spring, a bolt, must not keep a residual of the tolerance of ``_iterate``)."""
    model = stepper.model
    c = coupled(contacts)
    law = contact_law(stepper.model, c, frame.vec, frame.sca, np.zeros((model.n_blocks, 6)))
    ve = c.cint[:, KIND] == VE
    closed = c.state != OPEN
    weight = model.block_density * geom["area"] * float(np.hypot(*model.gravity))
    level = weight.copy()
    np.maximum.at(level, c.block_a, np.abs(law.fn))
    np.maximum.at(level, c.block_b, np.abs(law.fn))
    loose = BALANCE_ROUNDOFF * np.maximum(level[c.block_a], level[c.block_b])
    tensile = np.where(c.bond, c.tensile * c.length, 0.0)
    if np.count_nonzero(closed & ~law.closed & (model.penalty * law.dn - tensile > loose)) or \
            np.count_nonzero(~closed & law.closed & (law.fn > loose)):
        return False
    locked = ve & closed & (c.state == LOCK)
    excess = np.where(locked, model.shear_penalty * np.abs(law.ds) - law.strength, 0.0)
    if np.count_nonzero(excess > loose):
        return False
    residual = np.abs((frame.rhs - internal_force(stepper.model, c, frame.vec, law, stepper.serial_scatter)).reshape(-1, 6))
    rows = stepper.free_idx
    allowed = BALANCE_ROUNDOFF * level[rows]
    return bool(np.all(residual[:, :2] <= allowed[:, None]) and
                np.all(residual[:, 2:] <= (allowed * size[rows])[:, None]))
