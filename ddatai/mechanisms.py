"""Which blocks the contacts cannot hold in the equilibrium stage (`ddatai.start`): a small model
whose every block limit equilibrium lets move at t = 0, blocks an
iterate throws away from what holds them, and blocks out of balance that an open-close test
shows moving as their loads drive them, and held blocks that settled into the space of released
ones. They are released: they start at t = 0 under sudden gravity."""

from __future__ import annotations

from typing import Optional

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from .contacts import Contacts
from .geometry import displacement_matrix
from .assembly import contact_vectors, load_forces
from .kinematics import block_displacement
from .model_checks import STRAIN_LIMIT
from .limit_equilibrium import _interior_point, answered, applicable, median, unsupported_programs
from .layout import KIND, LOCK, OPEN, SLIDE, VE
from .lowrank import LOWRANK_UNKNOWNS
from .model import ContactMemory, State
from .open_close import open_close
from .records import StepTimer

#: the pseudo time step: free fall over it covers this many median block sizes
FALL_IN_SIZES = 1e4
#: a block that moves more than this fraction of its size √area in the stage, away from the
#: ground (`anchored`), is a mechanism. Over the pseudo time step a block that its contacts
#: cannot hold moves about FALL_IN_SIZES × (its net acceleration / g) sizes away from what
#: held it, so this catches every mechanism whose net acceleration exceeds 2.5e-5 g; a held
#: block moves with its neighbours, by its elastic settlement, which in a soft, tall model
#: exceeds a block size's quarter (a 60-block column with E = 100 MPa: 37 % at its top)
MECHANISM_SIZE = 0.25
#: DDA's first-order rotation (docs/method/dda.md §1.1) moves a point at (X, Y) from the centroid
#: by r0·(−Y, X): the linear map I + r0·[[0, −1], [1, 0]] turns the block by atan r0 and stretches
#: every line by √(1 + r0²). Beyond the rotation whose stretch is the largest strain that a
#: first-order block represents (``model_checks.STRAIN_LIMIT``, 25 %: docs/method/limits.md),
#: √((1 + 0.25)² − 1) = 0.75 rad, an iterate's rotation is no rigid motion (`out_of_range`)
FIRST_ORDER_ROTATION = float(np.sqrt((1.0 + STRAIN_LIMIT) ** 2 - 1.0))
#: at most this many open-close solves in the test of the out-of-balance blocks
MAX_TEST_SOLVES = 12
#: the screen of a model that fails as a whole (`unsupported_at_start`) is tried on models of at
#: most this many free blocks (kgm's judged groups): its program then costs a few ms against the
#: tens of solves that it saves; on larger masses it releases in layers, program after program,
#: and costs more than the return mapping that throws them away (random cut slope sections of
#: 18–46 blocks, tests/extreme_cases.py: 84–363 ms against 67–252)
SCREEN_BLOCKS = 12


def mechanisms(stepper, vertex_xy: np.ndarray, geom: dict, contacts: Contacts, disp: np.ndarray,
                out: np.ndarray, size: np.ndarray) -> np.ndarray:
    """Blocks that ``disp`` moves away by more than MECHANISM_SIZE (not `anchored`), and blocks
    held only by contacts deeper than the penetration limit (the penalty is too soft for their
    load: they start as mechanisms, and the run reports them)."""
    model = stepper.model
    free = ~model.block_fixed
    moved = block_displacement(stepper.model, vertex_xy, geom, disp)
    far = free & ~out & (moved > MECHANISM_SIZE * size)
    mechanism = far & ~anchored(stepper, vertex_xy, geom, contacts, disp, size) if np.count_nonzero(far) else far
    deep = (contacts.state != OPEN) & (-contacts.dn > model.penetration_limit)
    if np.count_nonzero(deep):
        sunk = np.zeros(model.n_blocks, bool)
        sunk[contacts.block_a[deep]] = True
        sunk[contacts.block_b[deep]] = True
        mechanism |= sunk & free & ~out
    return mechanism


def out_of_balance(model, contacts: Contacts, outcome) -> np.ndarray:
    """Blocks with a contact whose shear spring still exceeds its strength by more than the
    tolerance where `_iterate` stopped."""
    if outcome.excess is None:
        return np.zeros(model.n_blocks, bool)
    over = outcome.excess > outcome.loose
    blocks = np.zeros(model.n_blocks, bool)
    blocks[contacts.block_a[over]] = True
    blocks[contacts.block_b[over]] = True
    return blocks & ~model.block_fixed


def finish_friction(model) -> "str | None":
    """The friction of the stage's Newton finish (``return_mapping._finish``): "lagged" from
    ``lowrank.LOWRANK_UNKNOWNS`` unknowns (1,000 free blocks), else None (the run's,
    ``Params.oc_friction``). Coupled friction makes the finish's K non-symmetric at its first
    sliding contact: an LU with an analysis of its own, ~40 ms at 1,600 blocks against a Cholesky
    factorisation's ~21 ms on the iterates' analysis, 14 of them in ntdda's grid's stage. Lagged
    friction (each sliding contact's friction from the last solve's normal force, a load in F)
    keeps K symmetric; its convergence test asks the friction of the solve itself, so the
    equilibrium found meets the same tolerances, and where it stalls the iteration goes on coupled
    (`open_close.open_close`, ``LAGGED_STALL``). Smaller models, and every member of a batch, keep
    the run's friction and their stage bit for bit (benchmarks/results/stage_solves.md)."""
    return "lagged" if 6 * model.n_free >= LOWRANK_UNKNOWNS else None


def test_unbalanced(stepper, state: State, geom: dict, frame, contacts: Contacts,
                     outcome, guess, unbalanced: np.ndarray,
                     max_solves: int = MAX_TEST_SOLVES, friction: Optional[str] = None):
    """The open-close iteration of a static step (`Stepper.open_close`, Mohr–Coulomb: bonds
    kept) from where `_iterate` stopped: closed vertex-edge contacts at or beyond their strength
    slide against their shear (friction of their own normal force), the others are locked with
    their lock points moved by their slip. A block that the contacts cannot hold then moves
    ~FALL_IN_SIZES × its net acceleration / g sizes; one that they hold stays. Returns
    ((D, the contacts as judged, whether the iteration converged), solves), or (None, solves)
    when a solve is not finite. ``friction``: the iteration's (`open_close.open_close`)."""
    model = stepper.model
    c = contacts.copy()
    ve = c.cint[:, KIND] == VE
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
    oc = open_close(stepper, state, geom, c, frame.pattern, frame.vec, sca, frame.data, frame.rhs,
                    np.zeros(model.n_blocks), StepTimer(), max_solves, break_bonds=False, reuse_first=False,
                    friction=friction)
    disp, n, converged = oc.displacement, oc.iterations, oc.converged
    if disp is None:
        return None, n
    return (disp, c, converged), n


def driven(stepper, state: State, geom: dict, contacts: Contacts, disp: np.ndarray,
            moving: np.ndarray) -> np.ndarray:
    """The ``moving`` blocks that move as their loads drive them: groups of them (linked by
    closed contacts) on which gravity and the point loads do positive work over ``disp``.
    Friction resists motion and never drives it: a group that the test's friction pushed
    against its loads (its contacts at their strength all sliding, where some of them would
    stick) is held."""
    model = stepper.model
    if not np.count_nonzero(moving):
        return moving
    link = (contacts.state != OPEN) & moving[contacts.block_a] & moving[contacts.block_b]
    n = model.n_blocks
    graph = coo_matrix((np.ones(int(link.sum())), (contacts.block_a[link], contacts.block_b[link])),
                       shape=(n, n))
    _, label = connected_components(graph, directed=False)
    work = model.block_density * geom["area"] * (disp[:, :2] @ np.asarray(model.gravity, float))
    if len(model.load_block):
        at = displacement_matrix(state.load_xy, geom["centroid"][model.load_block])
        moved = np.einsum("nij,nj->ni", at, disp[model.load_block])
        np.add.at(work, model.load_block, np.einsum("ni,ni->n", load_forces(stepper.model, 0.0), moved))
    group = np.bincount(label[moving], weights=work[moving], minlength=n)
    return moving & (group[label] > 0.0)


def anchored(stepper, vertex_xy, geom, contacts: Contacts, disp: np.ndarray, size: np.ndarray) -> np.ndarray:
    """Blocks tied to the ground — fixed blocks and blocks with fixed points — through chains of
    closed contacts across which the two blocks move alike: each block's vertices, moved by its
    own displacement field and by its neighbour's (T·D of docs/method/dda.md §1.1), differ by
    less than MECHANISM_SIZE × the smaller block's size. A held block differs from its
    neighbour by its strain and the contact springs' give; a mechanism slides, opens or turns
    away from what holds it by about FALL_IN_SIZES × its net acceleration / g sizes."""
    model = stepper.model
    n = model.n_blocks
    closed = contacts.state != OPEN
    # the block pairs in touch, in order (one key a pair: a sort of integers, where a unique of
    # rows took 45 ms an iterate on the 6,400-block grid)
    key = np.unique(np.minimum(contacts.block_a[closed], contacts.block_b[closed]).astype(np.int64) * n +
                    np.maximum(contacts.block_a[closed], contacts.block_b[closed]))
    pairs = np.stack([key // n, key % n], axis=1)
    alike = np.ones(len(pairs), bool)
    centroid = geom["centroid"]
    off = model.vertex_offset
    for own, other in ((pairs[:, 0], pairs[:, 1]), (pairs[:, 1], pairs[:, 0])):
        if not len(pairs):
            break
        # the vertices of `own`, pair by pair
        count = off[own + 1] - off[own]
        first = np.cumsum(count) - count
        row = np.repeat(np.arange(len(pairs)), count)
        vertex = np.repeat(off[own] - first, count) + np.arange(int(count.sum()))
        xy = vertex_xy[vertex]
        u = _moved_by(xy, centroid[own[row]], disp[own[row]]) - _moved_by(xy, centroid[other[row]], disp[other[row]])
        gap = np.maximum.reduceat(np.hypot(u[:, 0], u[:, 1]), first)
        alike &= gap < MECHANISM_SIZE * np.minimum(size[pairs[:, 0]], size[pairs[:, 1]])
    graph = coo_matrix((np.ones(int(alike.sum())), (pairs[alike, 0], pairs[alike, 1])), shape=(n, n))
    _, label = connected_components(graph, directed=False)
    ground = model.block_fixed.copy()
    ground[model.fixed_point_block] = True
    return np.isin(label, label[ground])


def _moved_by(point: np.ndarray, centroid: np.ndarray, disp: np.ndarray) -> np.ndarray:
    """(n, 2) T(x, y)·D of docs/method/dda.md §1.1, point by point (`geometry.displacement_matrix`
    written out: no (n, 2, 6) matrices)."""
    x, y = point[:, 0] - centroid[:, 0], point[:, 1] - centroid[:, 1]
    return np.stack([disp[:, 0] - y * disp[:, 2] + x * disp[:, 3] + 0.5 * y * disp[:, 5],
                     disp[:, 1] + x * disp[:, 2] + y * disp[:, 4] + 0.5 * x * disp[:, 5]], axis=1)


def loaded_away(stepper, state: State, geom: dict, frame, contacts: Contacts, outcome, guess,
                out: np.ndarray, size: np.ndarray, converged_only: bool = False) -> tuple[np.ndarray, int, bool]:
    """The blocks out of balance where the return mapping stopped (`out_of_balance`) that move
    away in the open-close test (`test_unbalanced`) as their loads drive them (`driven`):
    mechanisms. ``converged_only``: where that iteration does not converge, every out-of-balance
    block (an unconverged iterate throws blocks that a converged one holds, but nothing then
    proves them held: in doubt, release). Returns (mechanism, solves, whether it was released in
    doubt: the run's first steps then resolve its rocking, `ddatai.in_doubt`)."""
    unbalanced = out_of_balance(stepper.model, contacts, outcome)
    tested, solves = test_unbalanced(stepper, state, geom, frame, contacts, outcome, guess, unbalanced)
    if tested is None:
        return np.zeros(stepper.model.n_blocks, bool), solves, False
    if converged_only and not tested[2]:
        # the test did not converge: nothing proves these blocks held, and a stage handing them
        # over held would start a toppling stack at rest (forces that non-associated friction
        # cannot reach exist for it). In doubt, they are released: a block released but stable
        # stays where it is in the first steps (docs/guide/equilibrium_start.md)
        return unbalanced & ~out, solves, True
    moving = unbalanced & mechanisms(stepper, state.vertex_xy, geom, tested[1], tested[0], out, size)
    return driven(stepper, state, geom, tested[1], tested[0], moving), solves, False


def sunk_into_released(stepper, state: State, released: np.ndarray, fraction: float) -> np.ndarray:
    """Held blocks that overlap a released block (back where it was at t = 0) deeper than
    ``fraction`` × the penetration limit: they settled into the space of a block whose
    support the stage had taken away: they are released too (`ddatai.start`)."""
    model = stepper.model
    out = np.zeros(model.n_blocks, bool)
    if not np.count_nonzero(released):
        return out
    held = ~model.block_fixed & ~released
    cint, length = stepper.detect(state.vertex_xy)
    contacts = Contacts.start(model, state.vertex_xy, cint, length, ContactMemory.empty(), True)
    a, b = contacts.block_a, contacts.block_b
    mixed = (held[a] & released[b]) | (released[a] & held[b])
    if not np.count_nonzero(mixed):
        return out
    geom = model.block_geometry(state.vertex_xy)
    _, sca = contact_vectors(model, state.vertex_xy, geom, contacts)
    depth = -np.where(contacts.cint[:, KIND] == VE, sca[:, 0], np.maximum(sca[:, 0], sca[:, 1]))
    deep = mixed & (depth > fraction * model.penetration_limit)
    out[a[deep]] = True
    out[b[deep]] = True
    return out & held


def restore(model, state: State, initial: State, blocks: np.ndarray) -> State:
    """``state`` with the given blocks (and their points) back where ``initial`` has them: a
    released block starts where it was at t = 0."""
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


def unsupported_at_start(stepper, state: State) -> np.ndarray:
    """(B,) every free block of a model of at most SCREEN_BLOCKS where rigid-block limit
    equilibrium (`ddatai.limit_equilibrium`) lets every one of them move at t = 0 — no
    admissible forces of the contacts detected then, the open ones among them counted as if they
    touched, balance their loads —, else none. The stage then releases them before its first
    solve (`ddatai.start`, 4.): a group of a few blocks that fails as a whole (a kgm judgement
    below its critical strength) is released at once instead of after a return mapping that
    stalls, tens of solves later. The return mapping could hold none of them: its equilibrium
    is a set of such forces, to its tolerance; counting the open contacts too, a block held by
    a neighbour it touches only after it settles is not released here. Where limit equilibrium
    lets only some blocks move, the stage finds them as without the screen (a mechanism thrown
    away in the return mapping first, the program on the rest), and releases the same blocks.
    None where nothing touches, or where the program does not apply (bolts, water) or does
    not converge. Inside `ddatai.limit_batch.screened_ahead`, the answer that the batch found
    for this stepper at this state (the same computation, done once)."""
    ahead = SCREENED.get(id(stepper))
    if ahead is not None and ahead[0] is stepper and ahead[1] is state:
        return ahead[2].copy()
    return answered(screen_programs(stepper, state), _interior_point)


#: the screens that `ddatai.limit_batch.screened_ahead` finished ahead, while its stages run:
#: {id(stepper): (stepper, state, released)}
SCREENED: dict = {}


def screen_program(stepper, state: State):
    """The data ``(a, b, tan_phi, cohesion, tensile)`` of the first limit-equilibrium program
    that `unsupported_at_start` solves for this model, or None where it solves none
    (`ddatai.limit_batch`: the programs of many members solved side by side)."""
    try:
        return next(screen_programs(stepper, state))
    except StopIteration:
        return None


def screen_programs(stepper, state: State):
    """`unsupported_at_start` as a generator (`limit_equilibrium.unsupported_programs`): it
    yields the screen's programs, is sent their answers, and returns the released blocks."""
    model = stepper.model
    none = np.zeros(model.n_blocks, bool)
    free = ~model.block_fixed
    if not applicable(model) or not np.count_nonzero(free) or np.count_nonzero(free) > SCREEN_BLOCKS:
        return none
    geom = state.geometry if state.geometry is not None else model.block_geometry(state.vertex_xy)
    cint, length = stepper.detect(state.vertex_xy)
    contacts = Contacts.start(model, state.vertex_xy, cint, length, ContactMemory.empty(), True)
    if not np.any(contacts.state != OPEN):
        return none  # nothing touches: the stage has nothing to hold or release
    found = yield from unsupported_programs(model, state.vertex_xy, geom, contacts, np.ones(contacts.n, bool), none)
    return free if found is not None and np.all(found[free]) else none


def contracting(stepper, vertex_xy: np.ndarray, geom: dict, disp: np.ndarray, out: np.ndarray,
                contraction: float) -> bool:
    """Whether the blocks still held (free, not ``out``) move less than ``contraction`` [m] (the
    last pseudo-step's increment) by ``disp``: the pseudo-steps, a fixed-point iteration on the
    geometry, still contract. Where they do not (a grid past its buckling weight: each
    increment at the settled geometry larger than the one before), what an iterate throws away
    is that divergence, not a block the contacts cannot hold: at 80 × 80 blocks with E and the
    penalty scaled to the 160 × 160 grid's settlement and penetration, the second pseudo-step's
    first iterate moved the blocks it held 13 m (and threw 139 more) after the first
    pseudo-step's 3.0 m, and releasing what it threw released 6,392 of 6,400 blocks in 2,582
    solves (docs/guide/equilibrium_start.md)."""
    if not np.isfinite(contraction):
        return True
    held = ~stepper.model.block_fixed & ~out
    moved = block_displacement(stepper.model, vertex_xy, geom, disp)
    return float(np.max(moved[held], initial=0.0)) < contraction


def out_of_range(stepper, contacts: Contacts, disp: np.ndarray, out: np.ndarray, thrown: np.ndarray,
                 size: np.ndarray) -> bool:
    """Whether the iterate ``disp`` that throws the ``thrown`` blocks (`mechanisms`) has left DDA's
    range of validity, so that what it throws is not shown to be a mechanism: it throws a block
    by a rotation beyond FIRST_ORDER_ROTATION (its first-order motion is no rigid motion, only
    a direction) while the blocks it keeps — free, not ``out`` nor thrown, and the fixed ones —
    overlap one another across an open contact by more than MECHANISM_SIZE × the smaller
    block's size (a vertex a quarter of a block inside its neighbour, the measure by which the
    stage calls a block moved away). A block thrown by translation is a valid first-order
    motion, and a toppling block that the iterate turns by hundreds of radians leaves the
    blocks it does not throw apart. On ntdda's grid, the first pseudo-step's return mapping, its
    corner contacts still opening and closing, turned blocks by 1.34 rad while kept blocks
    overlapped by 0.30 of a block (40 × 160 blocks), by 7.4 rad with overlaps of 7.3 blocks
    (160 × 160), and releasing what it threw released most of the grid
    (docs/guide/equilibrium_start.md). The stage then finds no frictional equilibrium
    (`ddatai.start`, ``StartRecord.diverged``)."""
    if not np.any(thrown & (np.abs(disp[:, 2]) > FIRST_ORDER_ROTATION)):
        return False
    kept = ~out & ~thrown  # fixed blocks are never out
    a, b = contacts.block_a, contacts.block_b
    both = (contacts.state == OPEN) & kept[a] & kept[b]
    return bool(np.any(-contacts.dn[both] > MECHANISM_SIZE * np.minimum(size[a[both]], size[b[both]])))


def pseudo_time_step(stepper, geom, size) -> float:
    """Δt over which free fall covers FALL_IN_SIZES median block sizes (`ddatai.start`, 2.)."""
    model = stepper.model
    accel = float(np.hypot(*model.gravity))
    if len(model.load_block):
        loads = load_forces(stepper.model, 0.0)
        mass = model.block_density * geom["area"]
        accel = max(accel, float(np.max(np.hypot(loads[:, 0], loads[:, 1]) / mass[model.load_block])))
    if accel == 0.0:  # initial stresses only: any acceleration scale will do
        accel = 1.0
    return float(np.sqrt(2.0 * FALL_IN_SIZES * median(size[~model.block_fixed]) / accel))
