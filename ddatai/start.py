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
3. The equilibrium is found by *return mapping* (`_iterate`): every closed contact stays a
   spring — normal, and for a vertex-edge contact shear from its lock point, moved by how far
   the contact has slid —, the slip of a contact whose spring carries more than its Coulomb
   strength grows by the excess (the return mapping of elastic, perfectly plastic friction,
   Anderson-accelerated), and a contact opens where it pulls beyond its tensile strength or
   closes where it overlaps (K changes only then; otherwise the last factor solves the next
   iterate, and where states change the step stops where the energy stops falling). It ends
   when no state changes and every contact force is the contact law's within
   ``Params.oc_force_tolerance`` × the load its blocks carry — the law's forces then balance
   every block within that much —, or, where the iteration stalls before, within
   ``Params.oc_state_tolerance``; in that case, and where a bonded contact ends at its strength
   (the run's first step would break its bond, Shi's rule, for the least excess), the
   open-close iteration of a static step finishes from there — its contacts at their strength
   sliding without springs, where a wedge slides until bolts or a wedging joint take its load —
   and its equilibrium is taken where it converges and moves nothing away. A contact without
   friction and cohesion has no shear spring. Semismooth Newton on the same law (the open-close
   iteration of a step) does not converge here from the all-locked start: a block whose contacts are
   sliding or open in an iterate has no stiffness but the pseudo inertia and is thrown ~1e4
   sizes, which scrambles its neighbours' states, and in a fitted mass of stiff blocks groups
   of corner contacts flip together for ever (docs/method/dda.md §8.12).
4. A block that moves more than a quarter of its size away from what holds it, or whose
   contacts sink deeper than the penetration limit, is a mechanism that the contacts cannot
   hold: a free block, one balanced on a corner, a column that topples. "Away from what holds
   it": the block is not tied to the ground (fixed blocks, fixed points) through a chain of
   closed contacts across which the two blocks move alike — a tall, soft column settles by
   more than a quarter of a block at its top, every block with its neighbours, and is held. A
   block that slides as a mechanism keeps the return mapping out of balance: the blocks still
   out of balance when it stalls are tested by the open-close iteration of a static step with
   their contacts at the strength sliding (`_test_unbalanced`), and those that move away in it
   on which their loads do positive work are mechanisms (friction only resists: a block that
   friction pushed away against its loads is held). A mechanism is *released*: its contacts
   leave the stage and it starts at t = 0 from its initial position under sudden gravity (as
   without the stage), and the others are solved again from where they were.
5. The held blocks move by the solution (their elastic settlement), their stresses and contact
   springs carry the equilibrium forces, and their velocities are the scene's initial ones:
   each contact is handed over locked, its lock point moved by its slip, and a contact at its
   strength starts locked at it with its bond intact. The stage repeats at the settled
   geometry until the contact forces there balance every block (`_balanced`).
6. If no frictional equilibrium is found (a pseudo-step out of iterations, or out-of-balance
   blocks that the test does not move), the model starts from its *welded* equilibrium: the
   same static solve with every touching contact held as it is (normal and shear springs, no
   open-close judgement), repeated at the settled geometry until the increment is round-off;
   blocks that move as mechanisms even so are released. Then each contact takes the joint law
   at t = 0: one pulled beyond its tensile strength opens, one sheared beyond its Coulomb
   strength is handed over locked at it (`StartRecord.at_strength`). The first steps release
   only the difference between the welded and the real joint forces instead of the whole
   weight (sudden gravity rings a stiff grid for its whole run and doubles the solves per
   step; docs/method/dda.md §8.12). `StartRecord.welded` says that a run started so.

So a model that limit equilibrium calls stable moves no more than its elastic settlement, and
one that it calls unstable starts failing at once: its released blocks start under sudden
gravity, and their bonded joints lose their bonds as soon as they slide or open (Shi's rule,
`Params.bond_breaks_on_slip`), as does a bonded joint that the stage finds pulled beyond its
tensile strength. `StartRecord` counts the contacts that reached their strength.
"""

from __future__ import annotations

import time as _time
from dataclasses import dataclass, replace
from typing import Optional

import numpy as np

from .contacts import KIND, BlockPattern, Contacts, detect_contacts
from .model import ContactKind, ContactMemory, ContactState, State

OPEN, SLIDE, LOCK = int(ContactState.OPEN), int(ContactState.SLIDE), int(ContactState.LOCK)
# contact-vector slots (`ddatai.kernels`): normal gradients of line 0 and of line 1, shear gradient
_E0, _G0, _E1, _G1, _ES, _GS = range(6)

#: the pseudo time step: free fall over it covers this many median block sizes
FALL_IN_SIZES = 1e4
#: a block that moves more than this fraction of its size √area in the stage, away from the
#: ground (`_anchored`), is a mechanism. Over the pseudo time step a block that its contacts
#: cannot hold moves about FALL_IN_SIZES × (its net acceleration / g) sizes away from what
#: held it, so this catches every mechanism whose net acceleration exceeds 2.5e-5 g; a held
#: block moves with its neighbours, by its elastic settlement, which in a soft, tall model
#: exceeds a block size's quarter (a 60-block column with E = 100 MPa: 37 % at its top)
MECHANISM_SIZE = 0.25
#: at most this many return-mapping iterations in a pseudo-step before the blocks that are
#: still out of balance are tested as mechanisms (`_unbalanced`); most pseudo-steps need
#: 10–40, each one solve (a refinement with the last factor while no contact opens or closes)
MAX_ITERATIONS = 120
#: ... and the test comes earlier once the iteration has stalled: no contact opened or closed
#: and the largest out-of-balance force did not halve in this many iterations
STALL_ITERATIONS = 20
#: at most this many open-close solves in the test of the out-of-balance blocks
MAX_TEST_SOLVES = 12
#: ... and in finishing an iteration that stalled within the looser tolerance only
MAX_FINISH_SOLVES = 8
#: a pseudo-step that has not found its equilibrium in this many solves gives up (the welded
#: start follows, module docstring 6.)
MAX_STAGE_SOLVES = 150
#: the line search halves its interval this many times (`_line_search`)
LINE_SEARCH_BISECTIONS = 30
#: Anderson acceleration of the slips keeps this many past iterates (`_anderson`), and starts
#: again when the largest out-of-balance force has not halved in this many iterations
ANDERSON_DEPTH = 8
ANDERSON_RESTART = 4
#: round-off of the balance of the settled geometry that ends the pseudo-steps (`_balanced`), as a
#: fraction of the load that a contact's blocks carry
BALANCE_ROUNDOFF = 1e-12
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
    """The frictional stage found no equilibrium, and the model started from its welded
    equilibrium with each contact then at most at its strength (module docstring, 6.)."""
    factorisations: int = 0
    """Factorisations of K among the solves (the others reuse the last factor) [-]."""


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
    factorised = stepper.solver.factorisations
    geom = model.block_geometry(state.vertex_xy)
    size = np.sqrt(geom["area"])
    dt_static = _pseudo_time_step(stepper, geom, size)
    settled, record, converged = _stage(stepper, state, size, dt_static, t0, welded=welded)
    if not converged:
        # no frictional equilibrium found: start from the welded one, each contact then at most
        # at its strength (module docstring, 6.), rather than under sudden gravity
        settled, again, _ = _stage(stepper, state, size, dt_static, t0, welded=True)
        record = replace(again, solves=record.solves + again.solves)
    return settled, replace(record, factorisations=stepper.solver.factorisations - factorised,
                            wall_time=_time.perf_counter() - t0)


def _stage(stepper, state: State, size: np.ndarray, dt: float, t0: float,
           welded: bool = False) -> tuple[State, StartRecord, bool]:
    """Pseudo-steps with Δt = ``dt`` (the static pseudo time step) until the increment is
    round-off, each the return-mapping iteration of `_return_mapping` (``welded``: one solve
    with the touching contacts held, `_welded_step`, the contacts then taking the joint law,
    `_unweld`). Returns (state, record, whether every pseudo-step found its equilibrium)."""
    model = stepper.model
    free = ~model.block_fixed
    initial = state
    released = np.zeros(model.n_blocks, bool)
    memory = ContactMemory.empty()
    last = None  # the contacts of the last pseudo-step
    solves = 0
    for pseudo_steps in range(MAX_PSEUDO_STEPS):
        geom = state.geometry if state.geometry is not None else model.block_geometry(state.vertex_xy)
        cint, length = detect_contacts(model, state.vertex_xy, stepper.buffers)
        contacts = Contacts.start(model, state.vertex_xy, cint, length, memory, True)
        contacts = _subset(contacts, ~(released[contacts.block_a] | released[contacts.block_b]))
        if not np.any(contacts.state != OPEN):
            break  # nothing (left) touches: nothing to hold
        if welded:
            disp, n, found, contacts = _welded_step(stepper, state, geom, contacts, dt, released, size)
        else:
            frame = _Frame.build(stepper, state, geom, contacts, dt)
            if pseudo_steps >= 2 and _balanced(stepper, frame, contacts, geom, size):
                # the settled geometry holds: its contact forces balance every block (a second
                # pseudo-step first, which takes the first one's linearisation error out)
                break
            disp, n, found, contacts = _return_mapping(stepper, state, geom, contacts, dt, released, size,
                                                       frame)
        solves += n
        if disp is None:  # no equilibrium found
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
        step = float(_block_displacement(stepper, state.vertex_xy, geom, disp).max(initial=0.0))
        state = _apply(stepper, state, geom, disp)
        last = contacts
        # the contacts go on into the next pseudo-step as they ended: locked ones with their
        # lock points moved by their slip, those at their strength sliding (`Contacts.start`
        # anchors them at their friction), all with their bonds
        memory = contacts.memory(bond_breaks_on_slip=False)
        if step <= model.open_tol:
            break  # the increment is round-off: an equilibrium of the settled geometry
    if solves == 0:
        return initial, NOTHING, True
    at_strength: set = set()
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


@dataclass(frozen=True, kw_only=True)
class _Frame:
    """What one pseudo-step keeps: its geometry, the contact vectors there, the sparsity
    pattern, and the block part of K and F (pseudo inertia included)."""

    vertex_xy: np.ndarray
    vec: np.ndarray
    sca: np.ndarray
    pattern: BlockPattern
    data: np.ndarray
    rhs: np.ndarray
    k_blocks: object  # the block part of K as a CSR matrix (the energy of `_line_search`)

    @staticmethod
    def build(stepper, state: State, geom: dict, contacts: Contacts, dt: float) -> "_Frame":
        from scipy.sparse import csr_matrix

        vec, sca = stepper.contact_vectors(state.vertex_xy, geom, contacts)
        pattern = BlockPattern.build(stepper.model, contacts)
        data, rhs = stepper.assemble_blocks(state, geom, pattern, dt, static_start=True)
        n = 6 * pattern.n_rows
        return _Frame(vertex_xy=state.vertex_xy, vec=vec, sca=sca, pattern=pattern, data=data, rhs=rhs,
                      k_blocks=csr_matrix((data, pattern.indices, pattern.indptr), shape=(n, n)))


@dataclass(kw_only=True)
class _Guess:
    """The return-mapping iteration's contact unknowns besides D: which contacts are closed,
    the entrance line of a vertex-vertex one, and how far each vertex-edge one has slid (its
    lock point moved that far along the edge) [m]."""

    closed: np.ndarray
    line: np.ndarray
    slip: np.ndarray

    @staticmethod
    def start(contacts: Contacts) -> "_Guess":
        return _Guess(closed=contacts.state != OPEN, line=contacts.line.copy(), slip=np.zeros(contacts.n))

    def subset(self, keep: np.ndarray) -> "_Guess":
        return _Guess(**{k: v[keep] for k, v in vars(self).items()})


@dataclass(kw_only=True)
class _Outcome:
    """Where `_iterate` ended."""

    disp: Optional[np.ndarray] = None    # D, None when a solve was not finite
    solves: int = 0
    converged: bool = False
    strict: bool = False                 # converged within ``Params.oc_force_tolerance``
    law: object = None                   # the contact law at D (`Stepper.contact_law`)
    excess: Optional[np.ndarray] = None  # shear spring force beyond the strength [N/m]
    loose: Optional[np.ndarray] = None   # each contact's force tolerance [N/m]


def _return_mapping(stepper, state: State, geom: dict, contacts: Contacts, dt: float,
                    released: np.ndarray, size: np.ndarray, frame: "Optional[_Frame]" = None):
    """One pseudo-step (module docstring, 1.–3.): the return-mapping iteration (`_iterate`);
    blocks that move away in it, or that it leaves out of balance and that then move away in
    the open-close test (`_test_unbalanced`), are released, and the rest iterated again from
    where they were. Returns (D, or None when no equilibrium was found; solves; the newly
    released blocks; the contacts as handed over, `_hand_over`)."""
    out = released.copy()
    solves = 0
    guess = None
    while solves < MAX_STAGE_SOLVES:
        keep = ~(out[contacts.block_a] | out[contacts.block_b])
        if frame is None or not keep.all():
            contacts = _subset(contacts, keep)
            guess = guess.subset(keep) if guess is not None else None
            frame = _Frame.build(stepper, state, geom, contacts, dt)
        outcome, guess = _iterate(stepper, frame, contacts, geom, out, size, guess)
        solves += outcome.solves
        if outcome.disp is None:
            return None, solves, out & ~released, contacts
        contacts.state[:] = np.where(guess.closed, contacts.state, OPEN)
        contacts.dn[:] = outcome.law.dn_now
        mechanism = _mechanisms(stepper, state.vertex_xy, geom, contacts, outcome.disp, out, size)
        if not mechanism.any() and not outcome.converged:
            # out of balance after the iteration: those blocks that move away in the open-close
            # iteration, their contacts at the strength sliding, are mechanisms
            unbalanced = _unbalanced(stepper.model, contacts, outcome)
            tested, n = _test_unbalanced(stepper, state, geom, frame, contacts, outcome, guess, unbalanced)
            solves += n
            if tested is not None:
                moving = unbalanced & _mechanisms(stepper, state.vertex_xy, geom, tested[1], tested[0],
                                                  out, size)
                mechanism = _driven(stepper, state, geom, tested[1], tested[0], moving)
        if not mechanism.any():
            if not outcome.converged:
                return None, solves, out & ~released, contacts
            break
        out |= mechanism
    else:
        return None, solves, out & ~released, contacts
    law = outcome.law
    ve = contacts.cint[:, KIND] == int(ContactKind.VE)
    at_strength = guess.closed & ve & \
        (stepper.model.shear_penalty * np.abs(law.ds) >= law.strength * (1.0 - 1e-9))
    bonded = contacts.bond & ((contacts.cohesion > 0.0) | (contacts.tensile > 0.0))
    if not outcome.strict or np.any(at_strength & bonded):
        # within the looser tolerance only (a wedge that must slide by millimetres until bolts
        # or a wedging joint take its load: each iterate slides it by its excess over the stiff
        # shear spring), or a bonded contact at its strength, which the run's first step would
        # break (Shi's rule) for the least excess beyond it: the open-close iteration from
        # here, its contacts at their strength sliding without springs, finishes the
        # equilibrium to the step's own tolerances where it converges and moves nothing away
        finished, n = _test_unbalanced(stepper, state, geom, frame, contacts, outcome, guess,
                                       ~stepper.model.block_fixed, MAX_FINISH_SOLVES)
        solves += n
        if finished is not None and finished[2] and \
                not _mechanisms(stepper, state.vertex_xy, geom, finished[1], finished[0], out, size).any():
            disp, contacts = finished[0], finished[1]
            _shift_lock_points(stepper, state.vertex_xy, contacts, guess.slip)
            contacts.coupled[:] = False
            return disp, solves, out & ~released, contacts
    _hand_over(stepper, state.vertex_xy, contacts, outcome.law, guess)
    return outcome.disp, solves, out & ~released, contacts


def _iterate(stepper, frame: _Frame, contacts: Contacts, geom: dict, out: np.ndarray,
             size: np.ndarray, guess: Optional[_Guess]) -> tuple[_Outcome, _Guess]:
    """The return-mapping iteration of one pseudo-step (module docstring, 1.–2.). Every closed
    contact is a spring — normal, and for a vertex-edge one shear from its lock point moved by
    its slip — so that no block loses its stiffness while the iteration finds which contacts
    open and how far each slides:

    - solve K D = F with the closed contacts and slips of this iterate (K changes only when a
      contact opens or closes, and the last factor solves it otherwise: `ddatai.solver`,
      reuse), and move D towards the solution as far as the energy falls (`_line_search`);
    - a contact opens where it pulls beyond its tensile strength, closes where it overlaps, and
      a vertex-vertex one changes line where the other is less penetrated — each only where
      that changes a force by more than the tolerance (below);
    - the slip of a closed vertex-edge contact grows by what its shear spring carries beyond the
      Coulomb strength N·tanφ + c·L of its own normal force (the return mapping of elastic,
      perfectly plastic friction, which keeps its cohesion while sliding), Anderson-accelerated
      (`_anderson`).

    Converged when no contact opens, closes or changes line and no spring exceeds its strength
    by more than the tolerance, ``Params.oc_force_tolerance`` × the load that the contact's
    blocks carry (their weight or their largest contact force): the contact law's forces are
    then in equilibrium within that much. A block that moves away by more than MECHANISM_SIZE
    ends the iteration (`_mechanisms`), and so do MAX_ITERATIONS iterations or a stall."""
    model, p = stepper.model, stepper.params
    free = ~model.block_fixed
    ve = contacts.cint[:, KIND] == int(ContactKind.VE)
    vv = ~ve
    if guess is None:
        guess = _Guess.start(contacts)
    # a contact without friction and cohesion carries no shear: no shear spring
    shearing = ve & ((contacts.tan_phi > 0.0) | ((contacts.cohesion * contacts.length > 0.0) & contacts.bond))
    weight = model.block_density * geom["area"] * float(np.hypot(*model.gravity))
    tensile = np.where(contacts.bond, contacts.tensile * contacts.length, 0.0)
    pen, ks = model.penalty, model.shear_penalty
    disp = np.zeros((model.n_blocks, 6))
    history: list = []
    changed = True  # the closed contacts changed: K is factorised
    best, best_at = np.inf, 0
    outcome = _Outcome()
    accepted = None  # the last iterate within ``Params.oc_state_tolerance``
    for it in range(1, MAX_ITERATIONS + 1):
        contacts.state[:] = np.where(guess.closed, np.where(shearing, LOCK, SLIDE), OPEN)
        contacts.line[:] = guess.line
        contacts.coupled[:] = False
        sca = frame.sca.copy()
        sca[:, 2] -= guess.slip  # ds from the lock point moved by the slip
        data, rhs = frame.data.copy(), frame.rhs.copy()
        stepper.assemble_contacts(contacts, frame.pattern, frame.vec, sca, data, rhs)
        target = stepper.solve(frame.pattern, data, rhs, reuse=not changed)
        outcome.solves += 1
        if not np.all(np.isfinite(target)):
            outcome.disp = None
            return outcome, guess
        # where contacts opened or closed, the step stops where the energy stops falling (slips
        # alone change only F: the solution is the minimiser)
        alpha = _line_search(stepper, frame, contacts, sca, disp, target - disp, shearing) \
            if changed and it > 1 else 1.0
        disp = target if alpha == 1.0 else disp + alpha * (target - disp)
        law = stepper.contact_law(_coupled(contacts), frame.vec, sca, disp)
        outcome.disp, outcome.law = disp, law
        moved = _block_displacement(stepper, frame.vertex_xy, geom, disp)
        far = free & ~out & (moved > MECHANISM_SIZE * size)
        if far.any() and np.any(far & ~_anchored(stepper, frame.vertex_xy, geom, contacts, disp, size)):
            return outcome, guess  # a block moves away from what holds it: `_mechanisms` tells
        # the load that each contact's blocks carry, and the force tolerance
        level = weight.copy()
        np.maximum.at(level, contacts.block_a, np.abs(law.fn))
        np.maximum.at(level, contacts.block_b, np.abs(law.fn))
        carried = np.maximum(level[contacts.block_a], level[contacts.block_b])
        loose = p.oc_force_tolerance * carried + model.force_roundoff
        outcome.loose = loose
        # normal, as the open-close judgement (`Stepper.violations`): a closed contact opens where
        # it pulls beyond its tensile strength (the strict tolerance), an open one closes where
        # it overlaps and a vertex-vertex one changes line where the other is less penetrated,
        # both where that moves a force by more than ``Params.oc_state_tolerance`` of the load
        state_loose = p.oc_state_tolerance * carried + model.force_roundoff
        closes = ~guess.closed & law.closed & (law.fn > state_loose)
        opens = guess.closed & ~law.closed & (pen * law.dn - tensile > loose)
        switch = vv & guess.closed & law.closed & (law.line != guess.line) & \
            (pen * np.abs(law.dn - law.dn_now) > state_loose)
        changed = bool(np.any(closes | opens | switch))
        guess.closed = (guess.closed | closes) & ~opens
        guess.line = np.where(closes | switch, law.line, guess.line).astype(np.int8)
        # shear: the return mapping
        trial = ks * law.ds
        excess = np.where(shearing & guess.closed, np.abs(trial) - law.strength, -np.inf)
        outcome.excess = excess
        dslip = np.where(excess > 0, np.maximum(excess, 0.0) / ks * np.sign(trial), 0.0)
        if not changed and alpha == 1.0 and np.all(excess <= state_loose):
            # within the looser tolerance: kept in case the strict one is not reached
            accepted = (replace(outcome, disp=disp.copy(), converged=True),
                        _Guess(closed=guess.closed.copy(), line=guess.line.copy(), slip=guess.slip + dslip),
                        dslip)
            if np.all(excess <= loose):
                # the last correction brings each spring to at most its strength; the forces it
                # moves are within the tolerance
                guess.slip = guess.slip + dslip
                law.ds[:] = law.ds - dslip
                outcome.converged = outcome.strict = True
                return outcome, guess
        unbalance = float(np.max(np.maximum(excess, 0.0) / loose, initial=0.0))
        if changed or alpha < 1.0:
            history.clear()
            best, best_at = np.inf, it
        elif unbalance < 0.5 * best:
            best, best_at = unbalance, it
        elif it - best_at >= STALL_ITERATIONS:
            break  # the slips no longer converge: out-of-balance blocks are tested
        elif (it - best_at) % ANDERSON_RESTART == 0:
            history.clear()  # the acceleration has stagnated: start it again from here
        guess.slip = _anderson(history, guess.slip, guess.slip + dslip)
    if accepted is not None:
        outcome, guess, dslip = accepted
        outcome.law.ds[:] = outcome.law.ds - dslip
    return outcome, guess


def _balanced(stepper, frame: _Frame, contacts: Contacts, geom: dict, size: np.ndarray) -> bool:
    """Whether the contacts as the last pseudo-step handed them over hold every block at this
    (settled) geometry to round-off: at D = 0 each keeps its state by the contact law, no shear
    spring exceeds its strength, and the contact law's forces balance each block's loads (force
    and moment rows), each within BALANCE_ROUNDOFF of the load its blocks carry (a block held
    by a weak spring, a bolt, must not keep a residual of the tolerance of `_iterate`)."""
    model = stepper.model
    c = _coupled(contacts)
    law = stepper.contact_law(c, frame.vec, frame.sca, np.zeros((model.n_blocks, 6)))
    ve = c.cint[:, KIND] == int(ContactKind.VE)
    closed = c.state != OPEN
    weight = model.block_density * geom["area"] * float(np.hypot(*model.gravity))
    level = weight.copy()
    np.maximum.at(level, c.block_a, np.abs(law.fn))
    np.maximum.at(level, c.block_b, np.abs(law.fn))
    loose = BALANCE_ROUNDOFF * np.maximum(level[c.block_a], level[c.block_b])
    tensile = np.where(c.bond, c.tensile * c.length, 0.0)
    if np.any(closed & ~law.closed & (model.penalty * law.dn - tensile > loose)) or \
            np.any(~closed & law.closed & (law.fn > loose)):
        return False
    locked = ve & closed & (c.state == LOCK)
    excess = np.where(locked, model.shear_penalty * np.abs(law.ds) - law.strength, 0.0)
    if np.any(excess > loose):
        return False
    residual = np.abs((frame.rhs - stepper.internal_force(c, frame.vec, law)).reshape(-1, 6))
    rows = stepper.free_idx
    allowed = BALANCE_ROUNDOFF * level[rows]
    return bool(np.all(residual[:, :2] <= allowed[:, None]) and
                np.all(residual[:, 2:] <= (allowed * size[rows])[:, None]))


def _coupled(contacts: Contacts) -> Contacts:
    """A copy whose friction follows the normal force of the solve it is evaluated at."""
    c = contacts.copy()
    c.coupled[:] = True
    return c


def _measures(vec: np.ndarray, sca: Optional[np.ndarray], contacts: Contacts, disp: np.ndarray):
    """(dn of line 0, dn of line 1 (−∞ for a vertex-edge contact), ds) at ``disp`` (with the
    constant parts ``sca``), or their rates along ``disp`` (``sca`` None): §2.8.1, linear in D."""
    da, db = disp[contacts.block_a], disp[contacts.block_b]
    vv = contacts.cint[:, KIND] == int(ContactKind.VV)
    dn0 = np.einsum("ij,ij->i", vec[:, _E0], da) + np.einsum("ij,ij->i", vec[:, _G0], db)
    dn1 = np.einsum("ij,ij->i", vec[:, _E1], db) + np.einsum("ij,ij->i", vec[:, _G1], da)
    ds = np.einsum("ij,ij->i", vec[:, _ES], da) + np.einsum("ij,ij->i", vec[:, _GS], db)
    if sca is not None:
        dn0, dn1, ds = dn0 + sca[:, 0], dn1 + sca[:, 1], ds + sca[:, 2]
    return dn0, np.where(vv, dn1, -np.inf if sca is not None else 0.0), np.where(vv, 0.0, ds)


def _line_search(stepper, frame: _Frame, contacts: Contacts, sca: np.ndarray, disp: np.ndarray,
                 step: np.ndarray, shearing: np.ndarray) -> float:
    """α ∈ (0, 1] that minimises along ``disp`` + α·``step`` the energy of the iterate: the
    blocks' ½DᵀKD − FᵀD, ½p·dn² of each contact closed there (the less penetrated line of a
    vertex-vertex one, up to the tensile allowance), ½k_s·(ds − slip)² of each closed
    vertex-edge one with friction or cohesion (``shearing``). The solution of the iterate's K
    minimises it as long as no contact opens or closes on the way; where some do, the energy's
    slope, piecewise linear in α, has its root before 1 (bisection), and the iterate stops
    there: contacts that all flip together cannot flip back and forth."""
    model = stepper.model
    rows = stepper.free_idx
    x, v = disp[rows].ravel(), step[rows].ravel()
    kv = frame.k_blocks @ v
    curvature = float(v @ kv)
    slope0 = float(kv @ x) - float(frame.rhs @ v)  # vᵀ(K x − F), K symmetric
    dn0, dn1, ds = _measures(frame.vec, sca, contacts, disp)
    r0, r1, rs = _measures(frame.vec, None, contacts, step)
    allowance = np.where(contacts.bond, contacts.tensile * contacts.length / model.penalty, 0.0)

    def slope(a: float) -> float:
        n0, n1 = dn0 + a * r0, dn1 + a * r1
        one = n1 > n0
        dn = np.where(one, n1, n0)
        closed = dn <= allowance
        normal = np.where(closed, model.penalty * dn, 0.0)
        shear = np.where(closed & shearing, model.shear_penalty * (ds + a * rs), 0.0)
        return curvature * a + slope0 + float(normal @ np.where(one, r1, r0)) + float(shear @ rs)

    if slope(1.0) <= 0.0:
        return 1.0
    lo, hi = 0.0, 1.0
    for _ in range(LINE_SEARCH_BISECTIONS):
        mid = 0.5 * (lo + hi)
        if slope(mid) < 0.0:
            lo = mid
        else:
            hi = mid
    return max(lo, 1.0 / 2 ** LINE_SEARCH_BISECTIONS)


def _anderson(history: list, x: np.ndarray, g: np.ndarray) -> np.ndarray:
    """Anderson acceleration (depth ANDERSON_DEPTH) of the fixed point x = g(x) of the slips:
    the combination of the last iterates whose residuals g − x cancel best (least squares)."""
    history.append((x, g))
    if len(history) > ANDERSON_DEPTH + 1:
        history.pop(0)
    if len(history) < 2:
        return g
    f = np.array([gi - xi for xi, gi in history])
    gs = np.array([gi for _, gi in history])
    df, dg = (f[1:] - f[:-1]).T, (gs[1:] - gs[:-1]).T
    gamma = np.linalg.lstsq(df, f[-1], rcond=None)[0]
    return g - dg @ gamma


def _mechanisms(stepper, vertex_xy: np.ndarray, geom: dict, contacts: Contacts, disp: np.ndarray,
                out: np.ndarray, size: np.ndarray) -> np.ndarray:
    """Blocks that ``disp`` moves away by more than MECHANISM_SIZE (not `_anchored`), and blocks
    held only by contacts deeper than the penetration limit (the penalty is too soft for their
    load: they start as mechanisms, and the run reports them)."""
    model = stepper.model
    free = ~model.block_fixed
    moved = _block_displacement(stepper, vertex_xy, geom, disp)
    far = free & ~out & (moved > MECHANISM_SIZE * size)
    mechanism = far & ~_anchored(stepper, vertex_xy, geom, contacts, disp, size) if far.any() else far
    deep = (contacts.state != OPEN) & (-contacts.dn > model.penetration_limit)
    if deep.any():
        sunk = np.zeros(model.n_blocks, bool)
        sunk[contacts.block_a[deep]] = True
        sunk[contacts.block_b[deep]] = True
        mechanism |= sunk & free & ~out
    return mechanism


def _unbalanced(model, contacts: Contacts, outcome: _Outcome) -> np.ndarray:
    """Blocks with a contact whose shear spring still exceeds its strength by more than the
    tolerance where `_iterate` stopped."""
    if outcome.excess is None:
        return np.zeros(model.n_blocks, bool)
    over = outcome.excess > outcome.loose
    blocks = np.zeros(model.n_blocks, bool)
    blocks[contacts.block_a[over]] = True
    blocks[contacts.block_b[over]] = True
    return blocks & ~model.block_fixed


def _test_unbalanced(stepper, state: State, geom: dict, frame: _Frame, contacts: Contacts,
                     outcome: _Outcome, guess: _Guess, unbalanced: np.ndarray,
                     max_solves: int = MAX_TEST_SOLVES):
    """The open-close iteration of a static step (`Stepper.open_close`, Mohr–Coulomb: bonds
    kept) from where `_iterate` stopped: closed vertex-edge contacts at or beyond their strength
    slide against their shear (friction of their own normal force), the others are locked with
    their lock points moved by their slip. A block that the contacts cannot hold then moves
    ~FALL_IN_SIZES × its net acceleration / g sizes; one that they hold stays. Returns
    ((D, the contacts as judged, whether the iteration converged), solves), or (None, solves)
    when a solve is not finite."""
    from .step import _Timer

    model = stepper.model
    c = contacts.copy()
    ve = c.cint[:, KIND] == int(ContactKind.VE)
    law = outcome.law
    sca = frame.sca.copy()
    sca[:, 2] -= guess.slip
    at = guess.closed & ve & (outcome.excess >= 0.0) & \
        (unbalanced[c.block_a] | unbalanced[c.block_b])
    c.state[:] = np.where(guess.closed, np.where(ve & ~at, LOCK, SLIDE), OPEN)
    c.line[:] = guess.line
    c.shear_dir[:] = np.where(law.ds >= 0.0, 1, -1)
    c.coupled[:] = at & (c.tan_phi > 0)
    c.normal_force[:] = np.where(guess.closed, np.maximum(law.fn, 0.0), 0.0)
    disp, n, converged = stepper.open_close(state, geom, c, frame.pattern, frame.vec, sca, frame.data,
                                            frame.rhs,
                                            np.zeros(model.n_blocks), _Timer(), max_solves, break_bonds=False,
                                            reuse_first=False)
    if disp is None:
        return None, n
    return (disp, c, converged), n


def _driven(stepper, state: State, geom: dict, contacts: Contacts, disp: np.ndarray,
            moving: np.ndarray) -> np.ndarray:
    """The ``moving`` blocks that move as their loads drive them: groups of them (linked by
    closed contacts) on which gravity and the point loads do positive work over ``disp``.
    Friction resists motion and never drives it: a group that the test's friction pushed
    against its loads (its contacts at their strength all sliding, where some of them would
    stick) is held."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    model = stepper.model
    if not moving.any():
        return moving
    link = (contacts.state != OPEN) & moving[contacts.block_a] & moving[contacts.block_b]
    n = model.n_blocks
    graph = coo_matrix((np.ones(int(link.sum())), (contacts.block_a[link], contacts.block_b[link])),
                       shape=(n, n))
    _, label = connected_components(graph, directed=False)
    work = model.block_density * geom["area"] * (disp[:, :2] @ np.asarray(model.gravity, float))
    if len(model.load_block):
        from .geometry import displacement_matrix

        at = displacement_matrix(state.load_xy, geom["centroid"][model.load_block])
        moved = np.einsum("nij,nj->ni", at, disp[model.load_block])
        np.add.at(work, model.load_block, np.einsum("ni,ni->n", stepper._load_forces(0.0), moved))
    group = np.bincount(label[moving], weights=work[moving], minlength=n)
    return moving & (group[label] > 0.0)


def _hand_over(stepper, vertex_xy: np.ndarray, contacts: Contacts, law, guess: _Guess) -> None:
    """The contacts as the pseudo-step leaves them, in place: each closed vertex-edge contact
    locked with its lock point moved by its slip (its shear spring carries the force that the
    iteration found, at most its strength) — marked sliding where that is its strength, to be
    locked at it (`_lock_at_strength`) —, vertex-vertex ones closed on their line; normal
    forces and distances of the solution."""
    model = stepper.model
    ve = contacts.cint[:, KIND] == int(ContactKind.VE)
    closed = guess.closed
    _shift_lock_points(stepper, vertex_xy, contacts, np.where(closed, guess.slip, 0.0))
    strength = law.strength
    at = closed & ve & (model.shear_penalty * np.abs(law.ds) >= strength * (1.0 - 1e-9))
    contacts.state[:] = np.where(closed, np.where(ve & ~at, LOCK, SLIDE), OPEN)
    contacts.shear_dir[:] = np.where(law.ds >= 0.0, 1, -1)
    contacts.line[:] = guess.line
    contacts.coupled[:] = False
    contacts.dn[:] = law.dn_now
    contacts.ds[:] = np.where(ve, law.ds, 0.0)
    contacts.normal_force[:] = np.where(closed, np.maximum(-model.penalty * law.dn_now, 0.0), 0.0)
    if law.tan_phi is not None:  # Barton–Bandis: the friction of this normal stress
        contacts.tan_phi[closed] = law.tan_phi[closed]


def _shift_lock_points(stepper, vertex_xy: np.ndarray, contacts: Contacts, slip: np.ndarray) -> None:
    """Move the lock point of each vertex-edge contact along its edge by its ``slip`` [m], in
    place: ds = (P1 − P0)·t falls by l·Δω when the lock point P0 moves by Δω along the edge."""
    model = stepper.model
    shift = (contacts.cint[:, KIND] == int(ContactKind.VE)) & (slip != 0.0)
    if shift.any():
        edge = contacts.cint[shift, 2]
        length = np.hypot(*(vertex_xy[edge] - vertex_xy[model.vertex_next[edge]]).T)
        contacts.omega[shift] += slip[shift] / length


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
        loads = stepper._load_forces(0.0)
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
    ve = contacts.cint[:, KIND] == int(ContactKind.VE)
    over = ve & (contacts.state == LOCK) & \
        (m.shear_penalty * np.abs(contacts.ds) > stepper.friction_force(contacts) + m.force_roundoff)
    contacts.state[over] = SLIDE
    contacts.shear_dir[over] = np.where(contacts.ds[over] >= 0, 1, -1)


def _welded_solve(stepper, state: State, geom: dict, contacts: Contacts, vec: np.ndarray,
                  sca: np.ndarray, pattern: BlockPattern, dt: float):
    """One static solve with every contact in the state it has (the touching ones locked),
    without open-close judgement; the contacts' distances and normal forces are updated to
    the solution in place. Returns D, or None if the solve is not finite."""
    m = stepper.model
    data, rhs = stepper.assemble_blocks(state, geom, pattern, dt, static_start=True)
    stepper.assemble_contacts(contacts, pattern, vec, sca, data, rhs)
    # K is symmetric: a welded stage changes no state, so its vertex-edge contacts stay locked
    # (only vertex-vertex ones are "sliding", with no friction) and none is coupled
    disp = stepper.solve(pattern, data, rhs, reuse=True)  # repeated at a settled geometry
    if not np.all(np.isfinite(disp)):
        return None
    law = stepper.contact_law(contacts, vec, sca, disp)
    closed = contacts.state != OPEN
    contacts.normal_force[:] = np.where(closed, np.maximum(-m.penalty * law.dn_now, 0.0), 0.0)
    if law.tan_phi is not None:  # Barton–Bandis: the friction of this normal stress
        contacts.tan_phi[closed] = law.tan_phi[closed]
    contacts.dn[:] = law.dn_now
    contacts.ds[:] = law.ds
    return disp


def _welded_step(stepper, state: State, geom: dict, contacts: Contacts, dt: float,
                 released: np.ndarray, size: np.ndarray):
    """One welded pseudo-step (module docstring, 6.): one solve with every touching contact held
    (`_welded_solve`); blocks that move away even so are released and the rest solved again.
    Returns (D or None when a solve is not finite, solves, newly released blocks, contacts)."""
    out = released.copy()
    solves = 0
    while True:
        contacts = _subset(contacts, ~(out[contacts.block_a] | out[contacts.block_b]))
        vec, sca = stepper.contact_vectors(state.vertex_xy, geom, contacts)
        pattern = BlockPattern.build(stepper.model, contacts)
        disp = _welded_solve(stepper, state, geom, contacts, vec, sca, pattern, dt)
        solves += 1
        if disp is None:
            return None, solves, out & ~released, contacts
        mechanism = _mechanisms(stepper, state.vertex_xy, geom, contacts, disp, out, size)
        if not mechanism.any():
            return disp, solves, out & ~released, contacts
        out |= mechanism


def _anchored(stepper, vertex_xy, geom, contacts: Contacts, disp: np.ndarray, size: np.ndarray) -> np.ndarray:
    """Blocks tied to the ground — fixed blocks and blocks with fixed points — through chains of
    closed contacts across which the two blocks move alike: each block's vertices, moved by its
    own displacement field and by its neighbour's (T·D of docs/method/dda.md §1.1), differ by
    less than MECHANISM_SIZE × the smaller block's size. A held block differs from its
    neighbour by its strain and the contact springs' give; a mechanism slides, opens or turns
    away from what holds it by about FALL_IN_SIZES × its net acceleration / g sizes."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    from .geometry import displacement_matrix

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


def _block_displacement(stepper, vertex_xy, geom, disp) -> np.ndarray:
    """Largest vertex displacement of each block [m]."""
    from .step import _move_points

    model = stepper.model
    moved = _move_points(vertex_xy, model.vertex_block, geom["centroid"], disp) - vertex_xy
    return np.maximum.reduceat(np.hypot(moved[:, 0], moved[:, 1]), model.vertex_offset[:-1])


def _keys(contacts: Contacts, sel: np.ndarray) -> set:
    return set(contacts.key[sel].tolist())


def _lock_at_strength(stepper, contacts: Contacts, vertex_xy: np.ndarray) -> np.ndarray:
    """Lock the sliding vertex-edge contacts, their lock point moved so that the shear spring
    carries their friction (force-continuous, as between steps): they keep their bonds.
    Returns which contacts were sliding."""
    m = stepper.model
    sliding = (contacts.state == SLIDE) & (contacts.cint[:, 0] == 0)
    if sliding.any():
        strength = stepper.friction_force(contacts)[sliding]
        edge = contacts.cint[sliding, 2]
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


def _apply(stepper, state: State, geom: dict, disp: np.ndarray) -> State:
    """Move the held blocks by their settlement and add its stress (velocities untouched)."""
    from .step import _move_points, _rotate_stress

    m = stepper.model
    centroid = geom["centroid"]
    xy = _move_points(state.vertex_xy, m.vertex_block, centroid, disp)
    stress = state.block_stress + np.einsum("bij,bj->bi", m.block_elastic, disp[:, 3:6])
    stress = _rotate_stress(stress, disp[:, 2])
    stress[m.block_fixed] = state.block_stress[m.block_fixed]
    return state.replace(
        vertex_xy=xy, block_stress=stress, block_rotation=state.block_rotation + disp[:, 2],
        fixed_point_xy=_move_points(state.fixed_point_xy, m.fixed_point_block, centroid, disp),
        load_xy=_move_points(state.load_xy, m.load_block, centroid, disp),
        measured_xy=_move_points(state.measured_xy, m.measured_block, centroid, disp),
        geometry=m.block_geometry(xy))
