"""The equilibrium stage's iteration (`ddatai.start`): return mapping on the contacts of one
pseudo-step. Every closed contact stays a spring, its shear measured from a lock point moved by
its slip, while the iteration finds which contacts open and how far each slides (slips
accelerated by Anderson mixing, an energy line search where states change); once its states
stop changing, and at a stalled or bonded-at-strength end, the open-close iteration of a static
step (semismooth Newton; ``mechanisms.finish_friction``) finishes it (``_finish``); blocks the
contacts cannot hold are found (thrown away, or out of balance and moved by their loads) and
released (docs/method/dda.md §8.12).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from functools import cached_property
from typing import Optional

import numpy as np
from scipy.sparse import csr_matrix

from .assembly import BlockPattern, assemble_blocks, contact_vectors
from .contact_law import stage_law
from .contacts import Contacts, subset_contacts
from .kinematics import block_displacement
from .layout import KIND, LOCK, OPEN, SLIDE, VE
from .model import SMALL_MODEL_BLOCKS, State
from .limit_equilibrium import unsupported_blocks
from .open_close import solve
from .reassembly import ContactSystem
from .return_steps import anderson, line_search
from . import iterate_skips
from .return_update import iterate_update
from .lowrank import LOWRANK_UNKNOWNS, RANK_MAX
from .updates import Springs, block_rows
from .mechanisms import (MECHANISM_SIZE, anchored, contracting, finish_friction, loaded_away, mechanisms,
                         out_of_range, test_unbalanced)

#: Newmark's β of the stage's system: that of a first step (the stage's pseudo-steps have no
#: acceleration history; `kinematics.newmark_beta`)
STAGE_BETA = 0.5


#: the stage's equilibrium: every contact force the law's within this fraction of the load its blocks carry
#: (or ``Params.oc_force_tolerance`` if smaller). A step may stop at 1e-3 of it (the accuracy that a
#: critical friction needs); a start that loose leaves forces out of balance by 1e-3 of a weight and the
#: first steps creep (33 µm on scenes/kgm_slope.py), where the stage should hand over a model at rest to round-off
STAGE_FORCE_TOLERANCE = 1e-6
#: at most this many return-mapping iterations in a pseudo-step before the blocks still out of balance are
#: tested as mechanisms (`unbalanced`); most pseudo-steps need 10–40, each one solve (a refinement with the
#: last factor while no contact opens or closes)
MAX_ITERATIONS = 120
#: ... and the test comes earlier once the iteration has stalled: no contact opened or closed
#: and the largest out-of-balance force did not halve in this many iterations
STALL_ITERATIONS = 20
#: ... and in finishing an iteration that stalled within the looser tolerance only
MAX_FINISH_SOLVES = 8
#: a pseudo-step's first iteration stops for Newton once no contact has changed state in this
#: many iterations: the rest is the slips' linear convergence (`_iterate`, ``tail``)
NEWTON_AFTER = 3
#: ... and in a small model's later pseudo-steps (``model.SMALL_MODEL_BLOCKS`` free blocks at most), which start
#: from the last one's equilibrium states: once an iterate after the first changes none (docs/method/dda.md §8.12)
NEWTON_LATER = 1
#: a pseudo-step that has not found its equilibrium in this many solves gives up (welded start)
MAX_STAGE_SOLVES = 1000
#: Anderson acceleration (`return_steps.anderson`) starts again when the largest out-of-balance
#: force has not halved in this many iterations
ANDERSON_RESTART = 4
#: once an iteration has stalled, it goes on from there with each vertex-edge contact that has opened or
#: closed this many times opening by the return mapping of its normal spring (`_iterate`, ``freeze``)
CHATTER_FLIPS = 2


@dataclass(frozen=True, kw_only=True)
class Frame:
    """What one pseudo-step keeps: its geometry, the contact vectors there, the sparsity
    pattern, and the block part of K and F (pseudo inertia included)."""

    vertex_xy: np.ndarray
    vec: np.ndarray
    sca: np.ndarray
    pattern: BlockPattern
    data: np.ndarray
    rhs: np.ndarray

    @cached_property
    def k_blocks(self):
        """The block part of K as CSR (`return_steps.line_search`'s energy), made when first needed."""
        n = 6 * self.pattern.n_rows
        return csr_matrix((self.data, self.pattern.indices, self.pattern.indptr), shape=(n, n))

    @staticmethod
    def build(stepper, state: State, geom: dict, contacts: Contacts, dt: float, previous=None) -> "Frame":
        """``previous``: the last frame's `BlockPattern`, its layout kept where the same blocks couple."""
        vec, sca = contact_vectors(stepper.model, state.vertex_xy, geom, contacts)
        pattern = BlockPattern.build(stepper.model, contacts, previous)
        data, rhs = assemble_blocks(stepper.model, state, geom, pattern, dt, STAGE_BETA, static_start=True)
        return Frame(vertex_xy=state.vertex_xy, vec=vec, sca=sca, pattern=pattern, data=data, rhs=rhs)


@dataclass(kw_only=True)
class Guess:
    """The return-mapping iteration's contact unknowns besides D: which contacts are closed, the entrance
    line of a vertex-vertex one, how far each vertex-edge one has slid (its lock point moved that far along
    the edge) [m], and how far each has opened by the return mapping of its normal spring (`_iterate`) [m]."""

    closed: np.ndarray
    line: np.ndarray
    slip: np.ndarray
    gap: np.ndarray

    @staticmethod
    def start(contacts: Contacts) -> "Guess":
        return Guess(closed=contacts.state != OPEN, line=contacts.line.copy(), slip=np.zeros(contacts.n),
                     gap=np.zeros(contacts.n))

    def copy(self) -> "Guess":
        return Guess(**{k: v.copy() for k, v in vars(self).items()})

    def subset(self, keep: np.ndarray) -> "Guess":
        return Guess(**{k: v[keep] for k, v in vars(self).items()})


@dataclass(kw_only=True)
class Outcome:
    """Where `_iterate` ended."""

    disp: Optional[np.ndarray] = None    # D, None when a solve was not finite
    solves: int = 0
    converged: bool = False
    strict: bool = False                 # converged within ``Params.oc_force_tolerance``
    steady: bool = False                 # stopped early: no state changed for NEWTON_AFTER iterations
    law: object = None                   # the contact law at D (`Stepper.contact_law`)
    excess: Optional[np.ndarray] = None  # shear spring force beyond the strength [N/m]
    loose: Optional[np.ndarray] = None   # each contact's force tolerance [N/m]


def return_mapping(stepper, state: State, geom: dict, contacts: Contacts, dt: float,
                    released: np.ndarray, size: np.ndarray, frame: "Optional[Frame]" = None,
                    doubt: Optional[np.ndarray] = None, in_doubt: Optional[np.ndarray] = None,
                    contraction: float = np.inf):
    """One pseudo-step (module docstring, 1.–3.): the return-mapping iteration (`_iterate`); blocks that move away
    in it, or that it leaves out of balance and that limit equilibrium then lets move
    (`limit_equilibrium.unsupported_blocks`; where that does not apply, those that move away in the open-close test,
    `test_unbalanced`), are released, and the rest iterated again from where they were. Where limit equilibrium
    holds every block left but the iteration has stalled, the pseudo-step ends there (*stalled*: its contacts handed
    over at most at their strength). ``doubt`` (where the stage can settle it by a slow turn-on, `ddatai.turn_on`):
    the blocks that the open-close test would release where limit equilibrium holds every block are marked in it, in
    place, instead, and the pseudo-step ends stalled; else ``in_doubt`` marks those released as that test did not
    converge (`ddatai.in_doubt`). ``contraction``: the last pseudo-step's increment [m]
    (``ddatai.mechanisms.contracting``). Returns (D, or None when no equilibrium was found; solves; the newly
    released blocks; the contacts as handed over, `_hand_over`; whether it stalled; whether it stopped contracting;
    whether the first pseudo-step left DDA's range, ``ddatai.mechanisms.out_of_range``)."""
    out = released.copy()
    solves = 0
    guess, freeze, stalled, newton, asked = None, False, False, True, None
    touching, line0 = contacts.state != OPEN, contacts.line.copy()  # as limit equilibrium counts them
    while solves < MAX_STAGE_SOLVES:
        keep = ~(out[contacts.block_a] | out[contacts.block_b])
        if frame is None or not keep.all():
            contacts = subset_contacts(contacts, keep)
            touching, line0 = touching[keep], line0[keep]
            guess = guess.subset(keep) if guess is not None else None
            if contacts.n == 0 and np.all(out | stepper.model.block_fixed):  # every free block released: an iterate
                # would converge at its first solve, none left for the D that the stage zeroes (`ddatai.start`)
                return np.zeros((stepper.model.n_blocks, 6)), solves, out & ~released, contacts, False, False, False
            frame = Frame.build(stepper, state, geom, contacts, dt, None if frame is None else frame.pattern)
        # Newton (``_finish``) once a pseudo-step from where the states settle, before anything is released
        later = np.isfinite(contraction) and stepper.model.n_free <= SMALL_MODEL_BLOCKS  # a small model's later one
        tail = (NEWTON_LATER if later else NEWTON_AFTER) \
            if newton and not freeze and not np.count_nonzero(out & ~released) else None
        outcome, raw = _iterate(stepper, frame, contacts, geom, out, size, guess, freeze, tail=tail)
        solves += outcome.solves
        if outcome.disp is None:
            return None, solves, out & ~released, contacts, False, False, False
        guess = _opened(raw.copy(), outcome.law)  # the contacts as handed over
        contacts.state[:] = np.where(guess.closed, contacts.state, OPEN)
        contacts.dn[:] = outcome.law.dn_now
        mechanism = mechanisms(stepper, state.vertex_xy, geom, contacts, outcome.disp, out, size)
        thrown = bool(np.count_nonzero(mechanism))  # thrown by the iterate (not by limit equilibrium or the test)
        if outcome.steady:  # cut short for Newton: where it does not finish, the return mapping goes on
            newton = False
            if not np.count_nonzero(mechanism):
                done, n = _finish(stepper, state, geom, frame, contacts, outcome, guess, out, size)
                solves += n
                if done is not None:
                    return done[0], solves, out & ~released, done[1], False, False, False
            guess = raw
            continue
        if not np.count_nonzero(mechanism) and not outcome.converged:
            # out of balance: blocks with no admissible forces go (`limit_equilibrium`; None: n/a); asked
            # again only once ``out`` grew (what it reads, the contacts' geometry and strengths, is the same till then)
            if asked is None or not np.array_equal(asked[0], out):
                asked = out.copy(), unsupported_blocks(stepper.model, state.vertex_xy, geom,
                                                       Contacts(**{**vars(contacts), "line": line0}), touching, out)
            unsupported = asked[1]
            if unsupported is not None and np.count_nonzero(unsupported & ~out):
                # released; the rest goes on with its contacts' chatter suppressed (`_iterate`)
                mechanism, freeze = unsupported & ~out, True
            elif not freeze:
                freeze, guess = True, raw  # once more, flipping contacts opening by return mapping
                continue
            else:
                # admissible forces do not prove a block held (Coulomb friction is not
                # associated: toppling columns have them): the open-close test decides, from a
                # converged iteration only where limit equilibrium applies; where nothing moves
                # the pseudo-step ends here, its forces out of balance by a fraction of the
                # load, which the first steps settle (docs/method/dda.md §8.12)
                mechanism, n, doubtful = loaded_away(stepper, state, geom, frame, contacts, outcome, guess, out,
                                                     size, converged_only=unsupported is not None)
                solves += n
                if doubt is not None and unsupported is not None and np.count_nonzero(mechanism):
                    # neither a converged test nor an unconverged one proves these blocks moved
                    # or held (the static problem of non-associated friction has many
                    # solutions): a slow turn-on of the weight settles it (`ddatai.turn_on`)
                    doubt |= mechanism
                    mechanism = np.zeros_like(mechanism)
                    stalled = True
                else:
                    stalled = unsupported is not None and not np.count_nonzero(mechanism)
                    if doubtful and in_doubt is not None:
                        in_doubt |= mechanism
        if not np.count_nonzero(mechanism) and (outcome.converged or stalled):
            break
        # no equilibrium, or blocks to release: where the held ones do not contract, the
        # pseudo-step ends, releasing nothing (`mechanisms.contracting`)
        diverging = not contracting(stepper, state.vertex_xy, geom, outcome.disp, out | mechanism, contraction)
        if diverging or not np.count_nonzero(mechanism):
            return None, solves, out & ~released, contacts, False, diverging, False
        if thrown and not np.isfinite(contraction) and not np.count_nonzero(out & ~released) and \
                out_of_range(stepper, contacts, outcome.disp, out, mechanism, size):
            # the first pseudo-step threw blocks from an iterate outside DDA's range: releasing them
            # cascades through the model (docs/method/dda.md §8.12); the stage starts welded
            return None, solves, out & ~released, contacts, False, False, True
        out |= mechanism
    else:
        return None, solves, out & ~released, contacts, False, \
            not contracting(stepper, state.vertex_xy, geom, outcome.disp, out, contraction), False
    law, ve = outcome.law, contacts.cint[:, KIND] == VE
    at_strength = guess.closed & ve & \
        (stepper.model.shear_penalty * np.abs(law.ds) >= law.strength * (1.0 - 1e-9))
    bonded = contacts.bond & ((contacts.cohesion > 0.0) | (contacts.tensile > 0.0))
    if not outcome.strict or np.count_nonzero(at_strength & bonded):
        # within the looser tolerance only (a wedge that must slide by millimetres until bolts
        # or a wedging joint take its load: each iterate slides it by its excess over the stiff
        # shear spring), or a bonded contact at its strength, which the run's first step would
        # break (Shi's rule) for the least excess beyond it: the open-close iteration from
        # here, its contacts at their strength sliding without springs, finishes the
        # equilibrium to the step's own tolerances where it converges and moves nothing away
        done, n = _finish(stepper, state, geom, frame, contacts, outcome, guess, out, size)
        solves += n
        if done is not None:
            if doubt is not None:
                doubt[:] = False  # an equilibrium that moves nothing away: no doubt left
            return done[0], solves, out & ~released, done[1], False, False, False
    _hand_over(stepper, state.vertex_xy, contacts, outcome.law, guess)
    return outcome.disp, solves, out & ~released, contacts, stalled, False, False


def _finish(stepper, state: State, geom: dict, frame: Frame, contacts: Contacts, outcome: "Outcome",
            guess: Guess, out: np.ndarray, size: np.ndarray):
    """The open-close iteration of a static step from where `_iterate` stopped (`test_unbalanced`:
    every contact at or beyond its strength sliding, the others locked at their slip): where it
    converges and moves no block away, ((D, the contacts with their lock points moved by the
    slips), solves), else (None, solves)."""
    finished, n = test_unbalanced(stepper, state, geom, frame, contacts, outcome, guess,
                                  ~stepper.model.block_fixed, MAX_FINISH_SOLVES,
                                  friction=finish_friction(stepper.model))
    if finished is None or not finished[2] or \
            np.count_nonzero(mechanisms(stepper, state.vertex_xy, geom, finished[1], finished[0], out, size)):
        return None, n
    disp, done, _ = finished
    _shift_lock_points(stepper, state.vertex_xy, done, guess.slip)
    done.coupled[:] = False
    return (disp, done), n


def _iterate(stepper, frame: Frame, contacts: Contacts, geom: dict, out: np.ndarray,
             size: np.ndarray, guess: Optional[Guess], freeze: bool = False,
             tail: Optional[int] = None) -> tuple[Outcome, Guess]:
    """The return-mapping iteration of one pseudo-step (module docstring, 1.–2.). Every closed
    contact is a spring — normal, and for a vertex-edge one shear from its lock point moved by
    its slip — so that no block loses its stiffness while the iteration finds which contacts
    open and how far each slides:

    - solve K D = F with the closed contacts and slips of this iterate (K changes only when a
      contact opens or closes, and the last factor solves it otherwise: `ddatai.solver`,
      reuse), and move D towards the solution as far as the energy falls (`return_steps.line_search`);
    - a contact opens where it pulls beyond its tensile strength, closes where it overlaps, and
      a vertex-vertex one changes line where the other is less penetrated — each only where
      that changes a force by more than the tolerance (below); with ``freeze`` (an iteration
      that stalled, going on), a vertex-edge contact that has opened or closed CHATTER_FLIPS
      times opens from then on by the return mapping of its normal spring (its rest point
      moved by how far it opens, ``Guess.gap``; K kept);
    - the slip of a closed vertex-edge contact grows by what its shear spring carries beyond the
      Coulomb strength N·tanφ + c·L of its own normal force (the return mapping of elastic,
      perfectly plastic friction, which keeps its cohesion while sliding), Anderson-accelerated
      (`return_steps.anderson`).

    Converged when no contact opens, closes or changes line and no spring exceeds its strength
    by more than the tolerance, ``STAGE_FORCE_TOLERANCE`` (or ``Params.oc_force_tolerance`` if
    smaller) × the load that the contact's blocks carry (their weight or their largest contact force): the contact law's forces are
    then in equilibrium within that much. A block that moves away by more than MECHANISM_SIZE
    ends the iteration (`mechanisms`), and so do MAX_ITERATIONS iterations or a stall, and with
    ``tail`` an iteration whose states have not changed for that many iterations (``steady``: the
    slips' linear convergence is left, which ``_finish`` does in a few solves)."""
    model, p = stepper.model, stepper.params
    free = ~model.block_fixed
    ve = contacts.cint[:, KIND] == VE
    if guess is None:
        guess = Guess.start(contacts)
    # a contact without friction and cohesion carries no shear: no shear spring
    shearing = ve & ((contacts.tan_phi > 0.0) | ((contacts.cohesion * contacts.length > 0.0) & contacts.bond))
    weight = model.block_density * geom["area"] * float(np.hypot(*model.gravity))
    tensile = np.where(contacts.bond, contacts.tensile * contacts.length, 0.0)
    disp = np.zeros((model.n_blocks, 6))
    rows = block_rows(model, contacts) if stepper.solver.updates and p.factor_updates else None
    system = ContactSystem(model, frame.pattern, frame.vec, frame.data, frame.rhs, stepper.serial_scatter)
    # a large model's line search and far blocks skip what provably stays (`ddatai.iterate_skips`)
    large = 6 * model.n_free >= LOWRANK_UNKNOWNS
    searching, far_blocks = (iterate_skips.LineSearch(model, frame, contacts),
                             iterate_skips.FarBlocks(model, frame.vertex_xy, geom)) \
        if large else (line_search, None)
    history: list = []
    flips = np.zeros(contacts.n, np.int64)  # how often each contact opened or closed
    closed_state = np.where(shearing, LOCK, SLIDE)  # a closed contact's state in K
    movable, far_at = free & ~out, MECHANISM_SIZE * size
    force_tolerance = min(p.oc_force_tolerance, STAGE_FORCE_TOLERANCE)
    changed = True  # the closed contacts changed: K is factorised
    few = False     # ... at most RANK_MAX of them (`ddatai.lowrank`)
    best, best_at = np.inf, 0
    outcome = Outcome()
    accepted = None  # the last iterate within ``Params.oc_state_tolerance``
    steady = 0
    for it in range(1, MAX_ITERATIONS + 1):
        contacts.state[:] = np.where(guess.closed, closed_state, OPEN)
        contacts.line[:] = guess.line
        contacts.coupled[:] = False
        sca = frame.sca.copy()
        sca[:, 2] -= guess.slip  # ds from the lock point moved by the slip
        sca[:, 0] -= guess.gap   # dn from the spring's rest point moved by the opening
        # K again only on the rows of blocks whose contacts opened or closed (`ddatai.reassembly`)
        data, rhs = system.system(contacts, sca)
        # K changes only where contacts open or close: the last factor solves it otherwise, and
        # where CHOLMOD is installed its rank updates follow those that do (`ddatai.updates`)
        springs = Springs.of(model, contacts, frame.vec, rows) if rows is not None else None
        # (after the frame's first, updates of low rank of the last factor while few changed: `ddatai.lowrank`)
        target = solve(stepper, frame.pattern, data, rhs, reuse=not changed, springs=springs, lowrank=it > 1 and few)
        outcome.solves += 1
        if np.count_nonzero(np.isfinite(target)) < target.size:
            outcome.disp = None
            return outcome, guess
        # where contacts opened or closed, the step stops where the energy stops falling (slips
        # alone change only F: the solution is the minimiser)
        alpha = searching(stepper, frame, contacts, sca, disp, target - disp, shearing) \
            if changed and it > 1 else 1.0
        disp = target if alpha == 1.0 else disp + alpha * (target - disp)
        law = stage_law(stepper.model, contacts, frame.vec, sca, disp)  # coupled: this solve's N
        outcome.disp, outcome.law = disp, law
        far = far_blocks(disp, movable, far_at) if large else \
            movable & (block_displacement(stepper.model, frame.vertex_xy, geom, disp) > far_at)
        if np.count_nonzero(far) and \
                np.count_nonzero(far & ~anchored(stepper, frame.vertex_xy, geom, contacts, disp, size)):
            return outcome, guess  # a block moves away from what holds it: `mechanisms` tells
        # the contacts' judgement: which close, open or change line, the normal return mapping's
        # openings and the shear springs' excess (`ddatai.return_update`, side by side in a batch)
        u = iterate_update(model, contacts, law, guess, flips, freeze, shearing, weight, tensile,
                           force_tolerance, CHATTER_FLIPS)
        loose, state_loose, excess, dslip, new_gap = u.loose, u.state_loose, u.excess, u.dslip, u.new_gap
        outcome.loose, outcome.excess = loose, excess
        flips += u.flipped
        n_changed = np.count_nonzero(u.changed)
        changed = bool(n_changed)
        few = n_changed <= RANK_MAX  # each a term of rank 1 or 2 in K
        guess.closed, guess.line = u.closed, u.line
        if not changed and alpha == 1.0 and (excess <= state_loose).all():
            # within the looser tolerance: kept in case the strict one is not reached
            accepted = (replace(outcome, disp=disp.copy(), converged=True),
                        Guess(closed=guess.closed.copy(), line=guess.line.copy(), slip=guess.slip + dslip,
                              gap=guess.gap.copy()),
                        dslip)
            if (excess <= loose).all():
                # the last correction brings each spring to at most its strength; the forces it
                # moves are within the tolerance
                guess.slip = guess.slip + dslip
                law.ds[:] = law.ds - dslip
                outcome.converged = outcome.strict = True
                return outcome, guess
        unbalance = float((np.maximum(excess, 0.0) / loose).max(initial=0.0))
        states_moved = changed or alpha < 1.0  # states changed, or the line search stopped short
        steady = 0 if states_moved else steady + 1
        if tail is not None and steady >= tail and it > 1:
            outcome.steady = True
            guess.slip = guess.slip + dslip
            return outcome, guess
        if states_moved:
            history.clear()
            best, best_at = np.inf, it
        elif unbalance < 0.5 * best:
            best, best_at = unbalance, it
        elif it - best_at >= STALL_ITERATIONS:
            break  # the slips no longer converge: out-of-balance blocks are tested
        elif (it - best_at) % ANDERSON_RESTART == 0:
            history.clear()  # the acceleration has stagnated: start it again from here
        n = contacts.n
        mixed = anderson(history, np.concatenate([guess.slip, guess.gap]),
                          np.concatenate([guess.slip + dslip, new_gap]))
        guess.slip, guess.gap = mixed[:n], np.maximum(mixed[n:], 0.0)
    if accepted is not None:
        outcome, guess, dslip = accepted
        outcome.law.ds[:] = outcome.law.ds - dslip
    return outcome, guess


def _opened(guess: Guess, law) -> Guess:
    """The guess with each vertex-edge contact that the normal return mapping opened (gap > 0) open, and the
    law's distances of those contacts measured from the contact again, in place."""
    if law is not None and np.count_nonzero(guess.gap > 0.0):
        gapped = guess.gap > 0.0
        law.dn[gapped] += guess.gap[gapped]
        law.dn_now[gapped] += guess.gap[gapped]
        law.closed[gapped] = False
        law.fn[gapped] = 0.0
    guess.closed = guess.closed & ~(guess.gap > 0.0)
    guess.gap = np.zeros_like(guess.gap)
    return guess


def _hand_over(stepper, vertex_xy: np.ndarray, contacts: Contacts, law, guess: Guess) -> None:
    """The contacts as the pseudo-step leaves them, in place: each closed vertex-edge contact
    locked with its lock point moved by its slip (its shear spring carries the force that the
    iteration found, at most its strength) — marked sliding where that is its strength, to be
    locked at it (`ddatai.welded.lock_at_strength`) —, vertex-vertex ones closed on their line; normal
    forces and distances of the solution."""
    model = stepper.model
    ve = contacts.cint[:, KIND] == VE
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
    shift = (contacts.cint[:, KIND] == VE) & (slip != 0.0)
    if np.count_nonzero(shift):
        edge = contacts.cint[shift, 2]
        length = np.hypot(*(vertex_xy[edge] - vertex_xy[model.vertex_next[edge]]).T)
        contacts.omega[shift] += slip[shift] / length
