"""The open-close iteration of one step (docs/method/dda.md §4): semismooth Newton on the
contact law.

Each solve takes the contact states (and the Jacobian of their forces) at the last iterate, so
when no state has to change the solution satisfies the law at every contact. A step of
Newton's method can overshoot into a state that sends the next one back (a contact that carries
almost no normal force, flipping between sticking and sliding); from the second solve on it is
shortened by a backtracking line search on the energy (``line_search``). The iteration returns
its outcome as an ``OpenClose`` value.

The later solves of the iteration differ from the last factorised K by the contacts that
changed state: they are tried by GMRES preconditioned by that factor (`ddatai.solver`,
``krylov``) while few blocks' rows changed. With the contact vertices' lever arms at each
iterate's rotation (`ddatai.lever_arm`, the default) every turning contact's rotation column
moves as well; ``Params.lever_arm_rotation = "predicted"`` keeps the step's predicted rotation
for them through all its solves (one array of contact vectors), so that only the contacts whose
state changed move K (docs/method/dda.md §5.3).

Friction (``Params.oc_friction``): "coupled" (the default) takes a sliding contact's friction
from the normal force of the same solve (a non-symmetric term in K, an LU); "lagged" solves with each sliding contact's friction from
the normal force of the last solve, a load in F, so K is symmetric positive definite (a
Cholesky factor, 0.4 × the cost of the LU of the coupled K at 1,540 blocks); the convergence test asks the
friction to be that of the solve itself, so a contact whose N moved is judged again with its
new N. Where the lagged iteration stalls (the contacts still changing have not become fewer
for ``LAGGED_STALL`` solves), it goes on with coupled friction (N = −p·dn of the same solve, a
non-symmetric term in K, an LU), with the same acceptance test.

The iteration reads what steps reuse from the `ddatai.step.Stepper` it is given (``stepper``):
the model, the solver with its last factor, each block's weight and the scatter mode.
"""

from __future__ import annotations

import time as _time
from dataclasses import dataclass, replace
from typing import Optional

import numpy as np
from scipy.sparse import csr_matrix

from .assembly import BlockPattern, assemble_contacts, second_order
from .lever_arm import lever_shift, midstep_lever_arms, with_lever_arms
from .contact_law import ContactLaw, contact_law, internal_force, judge, violations
from .contacts import Contacts
from .layout import KIND, LOCK, OPEN, SLIDE, VV
from .model import State
from .records import StepTimer
from .updates import Springs, block_rows

#: a lagged-friction iteration (``Params.oc_friction = "lagged"``) goes on with coupled
#: friction once the contacts still changing have not become fewer for this many solves
LAGGED_STALL = 3


def couple_sliding(contacts: Contacts) -> None:
    """Take every sliding vertex-edge contact's friction from the normal force of the solve
    it is in (implicit friction, `Contacts.coupled`), in place."""
    contacts.coupled[:] = (contacts.state == SLIDE) & (contacts.cint[:, KIND] != VV) & (contacts.tan_phi > 0)


@dataclass(frozen=True, kw_only=True, eq=False)
class OpenClose:
    """The outcome of one open-close iteration (`open_close`)."""

    displacement: Optional[np.ndarray]
    """(B, 6) the last solution D, zero for fixed blocks; None when a solve was not finite."""
    iterations: int
    """Solves taken [-]."""
    converged: bool
    """No contact had to change its state after the last solve."""
    changing: np.ndarray
    """(m,) the contacts whose state still had to change after the last solve (none when
    converged)."""
    friction: Optional[np.ndarray] = None
    """(m,) friction magnitude S of each contact in the last solve [N/m] (when converged)."""
    coulomb: float = 0.0
    """Largest |shear force| − Coulomb strength N·tanφ + c·L of a closed contact in the last
    solve [N/m] (when converged)."""
    vec: Optional[np.ndarray] = None
    """The contact vectors of the last solve, with their mid-step lever arms (when converged)."""
    system: Optional[tuple] = None
    """(K's CSR data, whether K is symmetric) of the last solve (when converged; the impact
    velocity's projection solves with it, `ddatai.impacts`)."""


def solve(stepper, pattern: BlockPattern, data: np.ndarray, rhs: np.ndarray,
          symmetric: bool = True, reuse: bool = False, krylov: bool = False, springs=None,
          lowrank: bool = False) -> np.ndarray:
    """Solve K D = F (`ddatai.solver`); returns D as (B, 6) with zeros for fixed blocks.
    ``symmetric=False`` when coupled friction made K non-symmetric; ``reuse`` when K should
    be close to the matrix last factorised (a step's first solve: the same contact states
    at a slightly moved geometry), which the solver then tries to solve with that factor;
    ``krylov`` when K differs from it by a few contacts' states (a later solve of the
    iteration: GMRES preconditioned by that factor); ``springs`` (`ddatai.updates.Springs`) the
    contact springs of a symmetric K, which the solver follows by rank updates of its factor
    where CHOLMOD is installed; ``lowrank`` when K differs from it by a few contacts' springs
    (the equilibrium stage's iterates: `ddatai.lowrank`)."""
    d = np.zeros((stepper.model.n_blocks, 6))
    if pattern.n_rows == 0:
        return d
    x = stepper.solver.solve(data, pattern.indices, pattern.indptr, rhs, pattern=pattern,
                             symmetric=symmetric, reuse=reuse, krylov=krylov, springs=springs, lowrank=lowrank)
    d[stepper.free_idx] = x.reshape(-1, 6)
    return d


def open_close(stepper, state: State, geom: dict, contacts: Contacts, pattern: BlockPattern,
               vec: np.ndarray, sca: np.ndarray, data0: np.ndarray, rhs0: np.ndarray,
               rotation: np.ndarray, timer: "StepTimer", max_iterations: int, break_bonds: bool = True,
               reuse_first: bool = True, hold_cycles: bool = False, give_up_cycles: bool = False,
               friction: Optional[str] = None) -> OpenClose:
    """The open-close iteration (§4) in place on ``contacts``, from the block terms ``data0``,
    ``rhs0`` (`assembly.assemble_blocks`) and the rotation predicted for the step (for the
    second-order terms). ``reuse_first``: the first solve may try the last factor (the states
    are the ones it was made with; `solve`). ``break_bonds``: bonds fail by the joint law
    (off in the equilibrium stage, whose joints are Mohr–Coulomb). ``hold_cycles``: a cycle of
    states holds its contacts closed (`hold_cycling`; the step's last try, at the shortest Δt).
    ``give_up_cycles``: a cycle of states ends the try at once, not converged (`cycling`; a
    step's tries before the last, which a shorter Δt follows). ``friction``: "coupled" or
    "lagged" for this iteration (None: ``Params.oc_friction``)."""
    model = stepper.model
    n = 6 * pattern.n_rows
    block_k = None   # K of the block terms, for the line search (built when first needed)
    previous = None  # last iterate D
    disp = None
    verdict = None
    lagged = (friction or stepper.params.oc_friction) == "lagged"
    if lagged:
        contacts.coupled[:] = False  # friction from the last solve's N: K symmetric
    fewest, since = contacts.n + 1, 0  # the fewest contacts changing, solves since then
    # the rows of each contact's springs, where the solver follows them by factor updates
    rows = block_rows(model, contacts) if stepper.solver.updates and stepper.params.factor_updates else None
    seen = {contacts.state.tobytes(): 0}  # each set of states tried, and when (`hold_cycling`)
    recurring: dict = {}  # how often each set of states came back (`cycling`)
    history = [contacts.state.copy()]
    held = np.zeros(contacts.n, bool)
    start_vec = vec  # the contact vectors at the step's start; each solve's have its lever arms
    frozen = None    # the lever arms at the predicted rotation, for all solves (`Params.lever_arm_rotation`)
    for it in range(1, max_iterations + 1):
        t0 = _time.perf_counter()
        data = rhs = None  # the last iterate's K goes before the next one is made (0.26 GB at 102,400 blocks)
        data, rhs = data0.copy(), rhs0.copy()
        shift = second_order(model, contacts, state, geom, rotation, rhs)
        if stepper.params.midstep_lever_arms:  # the contacts' lever arms at mid-step (`ddatai.lever_arm`, §5.3)
            if stepper.params.lever_arm_rotation == "iterate":
                columns, moved = midstep_lever_arms(model, contacts, state.vertex_xy, geom["centroid"], rotation)
                vec = with_lever_arms(start_vec, columns)
            else:
                # at the predicted rotation, once: K then changes between the solves only where
                # contacts change state (one ``vec`` array: `ddatai.updates.Springs.same_terms`)
                if frozen is None:
                    columns, _ = midstep_lever_arms(model, contacts, state.vertex_xy, geom["centroid"], rotation)
                    frozen = (columns, with_lever_arms(start_vec, columns))
                columns, vec = frozen
                moved = lever_shift(contacts, columns, rotation)
            shift += moved
        block_rhs = rhs.copy()
        assemble_contacts(model, contacts, pattern, vec, sca + shift, data, rhs, stepper.serial_scatter)
        t0 = timer.add("assembly", t0)
        symmetric = not np.count_nonzero(contacts.coupled & (contacts.state == SLIDE) & (contacts.tan_phi > 0))
        # the first solve has the states the last one ended with: K has moved only with
        # the blocks, and the last factor may still solve it (`ddatai.solver`, reuse)
        # the later solves differ from the last factor by the contacts that changed state
        # since: while they are few, GMRES preconditioned by it (`ddatai.solver`, krylov)
        # and where CHOLMOD is installed the lagged iteration's K, symmetric at every solve,
        # follows the springs that changed by updates of the last factor (`ddatai.updates`); a
        # coupled iteration's K turns non-symmetric at its first sliding contact, and its first
        # solve is factorised by the backend (PARDISO's Cholesky is cheaper than CHOLMOD's)
        springs = Springs.of(model, contacts, vec, rows) if symmetric and lagged and rows is not None else None
        solution = solve(stepper, pattern, data, rhs, symmetric=symmetric, reuse=reuse_first and it == 1,
                         krylov=it > 1, springs=springs)
        t0 = timer.add("solve", t0)
        if np.count_nonzero(np.isfinite(solution)) < solution.size:
            return OpenClose(displacement=None, iterations=it, converged=False,
                             changing=np.zeros(contacts.n, bool))
        law = contact_law(model, contacts, vec, sca, solution, shift)
        bad = hold_closed(contacts, law, violations(model, contacts, law, stepper.block_load), held)
        disp = solution
        if previous is not None and np.count_nonzero(bad):
            if block_k is None:
                block_k = csr_matrix((data0, pattern.indices, pattern.indptr), shape=(n, n))
            damped, damped_law = line_search(stepper, contacts, vec, sca, shift, previous, solution, law,
                                             block_k, block_rhs)
            # the shortened step stops before the contacts that change state on the way to
            # the solution; if none has changed there yet, the states change as the
            # solution asks (the step then continues in the next piece)
            if damped is not solution:
                damped_bad = hold_closed(contacts, damped_law,
                                         violations(model, contacts, damped_law, stepper.block_load), held)
                if np.count_nonzero(damped_bad):
                    disp, law, bad = damped, damped_law, damped_bad
        rotation = disp[:, 2].copy()
        verdict = judge(model, contacts, law, bad, break_bonds, couple=not lagged)
        timer.add("judge", t0)
        if uncouple_pulling(contacts, law, held) and not verdict.changed:
            verdict = replace(verdict, changed=True)  # solved again without the tension's friction
        if not verdict.changed and disp is solution:
            return OpenClose(displacement=disp, iterations=it, converged=True, changing=verdict.bad,
                             friction=verdict.friction, coulomb=verdict.coulomb, vec=vec,
                             system=(data, symmetric))
        previous = disp
        if hold_cycles:
            hold_cycling(contacts, seen, history, held)
        elif give_up_cycles and cycling(contacts, recurring):
            # the iteration has come back to a set of states for the third time: it cycles, and
            # the solves left before ``max_iterations`` would be spent going round (`cycling`)
            return OpenClose(displacement=disp, iterations=it, converged=False, changing=verdict.bad)
        if lagged:
            changing = int(np.count_nonzero(verdict.bad))
            fewest, since = (changing, 0) if changing < fewest else (fewest, since + 1)
            if since >= LAGGED_STALL:
                # stalled: the coupled iteration (LU) from here, with the same acceptance test
                lagged = False
                couple_sliding(contacts)
    return OpenClose(displacement=disp, iterations=max_iterations, converged=False,
                     changing=verdict.bad if verdict is not None else np.zeros(contacts.n, bool))


#: a set of contact states that the iteration reaches this many times in one try is a cycle
#: (`cycling`)
CYCLE_RECURRENCES = 3


def cycling(contacts: Contacts, recurring: dict) -> bool:
    """Whether the judgement has brought the contacts (their states and VV lines) to a set of
    states reached ``CYCLE_RECURRENCES`` times in this try, counted in ``recurring`` (in place).
    Reached once before, a set may still lead elsewhere (the line search starts from a
    different iterate, friction from another normal force); reached three times, the iteration
    goes round a cycle (with a contact open the solve closes it, with it closed it pulls free),
    and the try is given up at once for a shorter Δt rather than after ``oc_max_iterations``
    solves (a step of the 1,474-block slope went round a 2-cycle of 5–9 contacts from its 12th
    solve to its 20th). A set kept from one solve to the next is not a return (``recurring[None]``
    holds the last one). The step's last try holds such contacts closed instead (`hold_cycling`)."""
    key = contacts.state.tobytes() + contacts.line.tobytes()
    if recurring.get(None) == key:
        # the same states as the last solve's: not a return but an iteration still converging
        # on them (lagged friction's forces, the force tolerance of strict convergence)
        return False
    recurring[None] = key
    recurring[key] = recurring.get(key, 0) + 1
    return recurring[key] >= CYCLE_RECURRENCES


def hold_cycling(contacts: Contacts, seen: dict, history: list, held: np.ndarray) -> None:
    """When the judgement has brought back a set of contact states already tried (the
    iteration cycles: with a contact open the solve closes it, with it closed it pulls free,
    as at the contacts of a crumb thinner than the penetration band, or of a block wedged among
    many), the contacts that change around the cycle are held closed for the rest of the step
    (an open one locks), in place on ``contacts`` and ``held``; `hold_closed` keeps them so.
    ``seen`` maps each set of states to its place in ``history`` (docs/method/choices.md)."""
    key = contacts.state.tobytes()
    if key not in seen:
        seen[key] = len(history)
        history.append(contacts.state.copy())
        return
    loop = np.array(history[seen[key]:])
    cycling = np.any(loop != loop[0], axis=0) & ~held
    if not np.count_nonzero(cycling):
        return
    contacts.state[cycling & (contacts.state == OPEN)] = LOCK
    held |= cycling
    seen[contacts.state.tobytes()] = len(history)
    history.append(contacts.state.copy())


def uncouple_pulling(contacts: Contacts, law: ContactLaw, held: np.ndarray) -> bool:
    """Held contacts (`hold_cycling`) that slide and pull in this solve take their friction
    from the last solve's normal force (`Contacts.coupled` off: N = 0, friction c·L), not from
    the same solve's, which is the tension and gives a friction against Coulomb's law. In
    place; returns whether any changed."""
    if not np.count_nonzero(held):
        return False  # none held (the usual case): none to uncouple
    pulling = held & contacts.coupled & (contacts.state == SLIDE) & (law.fn_now < 0)
    contacts.coupled[pulling] = False
    return bool(np.count_nonzero(pulling))


def hold_closed(contacts: Contacts, law: ContactLaw, bad: np.ndarray, held: np.ndarray) -> np.ndarray:
    """The contacts that must change (``bad``, `violations`) with the held ones (`hold_cycling`)
    kept closed: where the law opens a held contact it slides instead (friction at its Coulomb
    strength from N ≥ 0, so never more than Coulomb's law allows; the normal spring may pull
    it), in place on ``law``; a held contact changes only from locked to sliding. A held
    contact that pulls takes its friction from the last solve's normal force (zero, not the
    tension: `uncouple_pulling`)."""
    if not np.count_nonzero(held):
        return bad
    pull = held & (law.state == OPEN)
    law.state[pull] = SLIDE
    bad[pull] &= contacts.state[pull] != SLIDE
    # one that cycles between sticking and sliding at its strength (its N, and so S, moves with
    # the state) stays sliding once it slides: its friction is S, within Coulomb's law
    stick = held & (contacts.state == SLIDE) & (law.state == LOCK)
    law.state[stick] = SLIDE
    bad[stick] = False
    # one whose friction, taken from the last solve's normal force where it pulled
    # (`uncouple_pulling`), is now below the strength of this solve's pressing N slides within
    # Coulomb's cone: coupled again it would pull and be uncoupled again, a cycle of two solves
    # at N ≈ 0 that no state change ends
    under = held & (contacts.state == SLIDE) & (law.state == SLIDE) & ~contacts.coupled & \
        (law.friction_now <= law.strength)
    bad[under] = False
    return bad


def line_search(stepper, contacts: Contacts, vec: np.ndarray, sca: np.ndarray, shift: np.ndarray,
                previous: np.ndarray, solution: np.ndarray, law: ContactLaw, block_k, block_rhs: np.ndarray
                ) -> tuple[np.ndarray, ContactLaw]:
    """Backtracking (Armijo) from the last iterate towards the new solution on the energy
    Π(D) = ½·Dᵀ·K_blocks·D − F_blocksᵀ·D + the contact springs' energy (penalty springs, and
    the Huber potential of each shear spring at its friction): with the friction held, Π is
    convex and the solution of the solve minimises its quadratic piece at the last iterate,
    so the step is a descent direction and Π falls at every iterate."""
    model = stepper.model
    rows = stepper.free_idx

    def energy(d, lw):
        x = d[rows].ravel()
        return 0.5 * float(x @ (block_k @ x)) - float(block_rhs @ x) + lw.energy

    law_prev = contact_law(model, contacts, vec, sca, previous, shift)
    base = energy(previous, law_prev)
    grad = block_k @ previous[rows].ravel() - block_rhs + \
        internal_force(model, contacts, vec, law_prev, stepper.serial_scatter)
    slope = float(grad @ (solution - previous)[rows].ravel())
    if slope >= 0:  # not a descent direction (coupled friction): take the step
        return solution, law
    alpha, d, lw = 1.0, solution, law
    while alpha > 1.0 / 256:
        if energy(d, lw) <= base + 1e-4 * alpha * slope:
            break
        alpha *= 0.5
        d = previous + alpha * (solution - previous)
        lw = contact_law(model, contacts, vec, sca, d, shift)
    return d, lw
