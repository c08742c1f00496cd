"""The contact law and the open-close judgement (docs/method/dda.md §2.8, §4.2–4.3).

Each function here has a Taichi kernel path and a NumPy twin beside it (``*_numpy``); tests
compare them (tests/test_judgement.py). The kernels (`kernels.contact_law`,
`kernels.violations`, `kernels.internal_force`) serve Mohr–Coulomb joints. Models with
Barton–Bandis joints take the NumPy path: their friction follows the law's own normal stress
(docs/method/barton_bandis.md, eq. BB1–BB3), which the kernels do not evaluate.

- `contact_law`: the law at a solution D — each contact's normal distance, state, forces and
  Coulomb strength, and the forces of the state it has now;
- `violations`: which contacts' assumed states break the law or mismatch their motion;
- `judge`: apply those changes (in place on the contacts) and return the ``Judgement``;
- `internal_force`: the generalised forces of the law's contact forces (the line search's
  energy gradient).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Optional

import numpy as np

from . import side_by_side
from .contacts import Contacts, barton_tan
from .layout import KIND, LOCK, OPEN, S_E0, S_E1, S_ES, S_G0, S_G1, S_GS, SLIDE, VV
from .model import Model


@dataclass(frozen=True, kw_only=True, eq=False)
class ContactLaw:
    """The contact law evaluated at one solution D (`contact_law`); (m,) arrays."""

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


@dataclass(frozen=True, kw_only=True, eq=False)
class Judgement:
    """What `judge` decided about one solve."""

    changed: bool
    """Some contact had to change its state: the open-close iteration goes on."""
    bad: np.ndarray
    """(m,) the contacts whose assumed state broke the law (`violations`)."""
    coulomb: float = 0.0
    """When none changed: the largest |shear force| − Coulomb strength of a closed vertex-edge
    contact at the solution [N/m]."""
    friction: Optional[np.ndarray] = None
    """When none changed: the friction magnitude S of each contact in the solve [N/m]."""


def friction_force(contacts: Contacts) -> np.ndarray:
    """Coulomb limit N·tanφ + c·L (bonded) of each contact, N from the last solve in which
    the contact was closed (§2.8.4)."""
    return contacts.normal_force * contacts.tan_phi + contacts.cohesion * contacts.length * contacts.bond


def friction_terms(model: Model, contacts: Contacts) -> tuple[np.ndarray, np.ndarray]:
    """(a, b) of each sliding contact's friction magnitude S = a − b·dn in the next solve:
    a coupled contact takes N = −p·dn of that solve (a = c·L, b = p·tanφ), the others the
    N of an earlier one (a = `friction_force`, b = 0)."""
    cohesion = contacts.cohesion * contacts.length * contacts.bond
    a = np.where(contacts.coupled, cohesion, friction_force(contacts))
    b = np.where(contacts.coupled, model.penalty * contacts.tan_phi, 0.0)
    return a, b


def friction_used(model: Model, contacts: Contacts, dn: np.ndarray) -> np.ndarray:
    """Friction magnitude S each contact's state applies in a solve with normal distance
    ``dn`` (`friction_terms`)."""
    const, slope = friction_terms(model, contacts)
    return const - slope * dn


def law_inputs(contacts: Contacts) -> tuple[np.ndarray, np.ndarray]:
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


def contact_law(model: Model, contacts: Contacts, vec: np.ndarray, sca: np.ndarray, disp: np.ndarray,
                shift: Optional[np.ndarray] = None) -> ContactLaw:
    """The contact law at the displacements ``disp`` (§2.8, §4.3), without changing
    ``contacts`` (`contact_law_numpy` states it). A Taichi kernel evaluates it
    (`kernels.contact_law`); models with Barton–Bandis joints, whose friction follows the
    law's own normal stress, and small models (`Model.numpy_path`) take the NumPy path, which is
    also the kernel's reference."""
    if contacts.n == 0 or len(model.joint_barton) or model.numpy_path:
        return contact_law_numpy(model, contacts, vec, sca, disp, shift)
    from . import kernels as K

    cstate, cvalue = law_inputs(contacts)
    constant = sca if shift is None else sca + shift
    out_f = np.empty((10, contacts.n))
    out_i = np.empty((4, contacts.n), np.int8)
    K.contact_law(contacts.cint, cstate, cvalue, contacts.block_a, contacts.block_b, vec,
                  np.ascontiguousarray(constant), np.ascontiguousarray(disp), model.penalty,
                  model.shear_penalty, model.penetration_limit, out_f, out_i)
    return ContactLaw(dn=out_f[K.LAW_DN], ds=out_f[K.LAW_DS], line=out_i[K.LAW_LINE],
                      closed=out_i[K.LAW_CLOSED].view(bool), state=out_i[K.LAW_STATE],
                      direction=out_i[K.LAW_DIRECTION], fn=out_f[K.LAW_FN], ft=out_f[K.LAW_FT],
                      strength=out_f[K.LAW_STRENGTH], dn_now=out_f[K.LAW_DN_NOW],
                      fn_now=out_f[K.LAW_FN_NOW], ft_now=out_f[K.LAW_FT_NOW],
                      friction_now=out_f[K.LAW_FRICTION_NOW],
                      energy=float(np.sum(out_f[K.LAW_ENERGY])), packed=(out_f, out_i))


def _law_core(m: Model, contacts: Contacts, vec: np.ndarray, sca: np.ndarray, disp: np.ndarray,
              shift: Optional[np.ndarray]):
    """The part of `contact_law_numpy` that `stage_law` shares: (dn, ds, line, closed,
    strength, dn_now, tan φ, vv, ve, the tensile allowance)."""
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
    if np.count_nonzero(vv):
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
        tan_phi = tan_phi.copy()
        bb = np.flatnonzero(~np.isnan(m.joint_barton[contacts.joint, 0]))
        tan_phi[bb] = barton_tan(m, contacts.joint[bb], m.penalty * np.maximum(-dn[bb], 0.0),
                                 contacts.length[bb], contacts.slip[bb])
    strength = m.penalty * np.maximum(-dn, 0.0) * tan_phi + \
        contacts.cohesion * contacts.length * contacts.bond
    return dn, ds, line, closed, strength, dn_now, tan_phi, vv, ve, allowance


@side_by_side.operation("contact_law_numpy")
def contact_law_numpy(model: Model, contacts: Contacts, vec: np.ndarray, sca: np.ndarray,
                      disp: np.ndarray, shift: Optional[np.ndarray] = None) -> ContactLaw:
    """The contact law at the displacements ``disp`` (§2.8, §4.3), without changing
    ``contacts``: the NumPy path of `contact_law` (the path of Barton–Bandis joints).

    A contact is closed while its normal distance dn ≤ T·L/p (bonded) or 0, with normal
    force −p·dn; a closed vertex-edge contact sticks while its shear spring force k_s·ds ≤
    S = N·tanφ + c·L (bonded), else it slides with friction S against the sign of ds (the
    return mapping of a penalty-regularised Coulomb law: ds is measured from the lock point
    of the step start, so a sliding contact's trial force starts at its friction). Also
    the forces that the state each contact has now gives at ``disp``.
    """
    m = model
    dn, ds, line, closed, strength, dn_now, tan_phi, vv, ve, allowance = _law_core(m, contacts, vec, sca, disp,
                                                                                  shift)
    fields, normal_energy, huber = _law_terms(m, contacts, dn, ds, closed, strength, dn_now, vv, ve, allowance)
    energy = float(np.add.reduce(normal_energy) + np.add.reduce(huber[closed & ve]))  # np.sum's, without its wrapper
    return ContactLaw(dn=dn, ds=ds, line=line, closed=closed, strength=strength, dn_now=dn_now, energy=energy,
                      tan_phi=tan_phi if len(m.joint_barton) else None, **fields)


def _law_terms(m, contacts, dn, ds, closed, strength, dn_now, vv, ve, allowance):
    """The rest of `contact_law_numpy` from `_law_core`'s terms: ({state, direction, fn, ft,
    fn_now, ft_now, friction_now}, each contact's normal spring energy, its shear (Huber)
    energy), element-wise (`ddatai.stage_batch` evaluates it for many members at once)."""
    # the friction the next solve can apply: N of the last one (or of this one, coupled)
    used = np.where(contacts.coupled, strength, friction_force(contacts))
    trial = m.shear_penalty * ds
    stick = np.abs(trial) <= used
    ft = np.where(closed & ve, np.where(stick, trial, np.sign(ds) * used), 0.0)
    state = np.where(closed, np.where(ve & stick, LOCK, SLIDE), OPEN).astype(np.int8)
    # energy of the contact springs with that friction: ½p·dn² (up to the tensile
    # strength) and the Huber function of ds (½k_s·ds², then linear at the friction)
    normal_energy = 0.5 * m.penalty * np.where(dn <= allowance, dn * dn, allowance * allowance)
    limit = used / m.shear_penalty
    huber = np.where(np.abs(ds) <= limit, 0.5 * m.shear_penalty * ds * ds, used * (np.abs(ds) - 0.5 * limit))
    # the forces of the current states at this D
    now = contacts.state
    fn_now = np.where(now == OPEN, 0.0, -m.penalty * dn_now)
    friction_now = friction_used(m, contacts, dn_now)
    ft_now = np.where(now == LOCK, trial, np.where(now == SLIDE, contacts.shear_dir * friction_now, 0.0))
    ft_now[vv] = 0.0
    fields = dict(state=state, direction=np.where(ds >= 0, 1, -1).astype(np.int8),
                  fn=np.where(closed, -m.penalty * dn, 0.0), ft=ft, fn_now=fn_now, ft_now=ft_now,
                  friction_now=friction_now)
    return fields, normal_energy, huber


@dataclass(frozen=True, kw_only=True, eq=False)
class StageLaw:
    """The fields of `ContactLaw` that the equilibrium stage's return mapping reads
    (`stage_law`), the same arrays."""

    dn: np.ndarray
    ds: np.ndarray
    line: np.ndarray
    closed: np.ndarray
    fn: np.ndarray
    strength: np.ndarray
    dn_now: np.ndarray
    tan_phi: Optional[np.ndarray] = None


@side_by_side.operation("stage_law")
def stage_law(model: Model, contacts: Contacts, vec: np.ndarray, sca: np.ndarray, disp: np.ndarray):
    """`contact_law` of the equilibrium stage's return mapping (its contacts coupled: the
    strength of this solve's N): on the NumPy path only the fields it reads (`StageLaw`: its
    ~sixty calls an iterate on arrays of a few contacts are most of a small model's stage), the
    same floats as `contact_law_numpy`'s; on the kernel path the kernel's whole law."""
    if not (contacts.n == 0 or len(model.joint_barton) or model.numpy_path):
        c = contacts.copy()
        c.coupled[:] = True
        return contact_law(model, c, vec, sca, disp)
    dn, ds, line, closed, strength, dn_now, tan_phi, _, _, _ = _law_core(model, contacts, vec, sca, disp, None)
    return StageLaw(dn=dn, ds=ds, line=line, closed=closed, fn=np.where(closed, -model.penalty * dn, 0.0),
                    strength=strength, dn_now=dn_now, tan_phi=tan_phi if len(model.joint_barton) else None)


def violations(model: Model, contacts: Contacts, law: ContactLaw, block_load: np.ndarray) -> np.ndarray:
    """Contacts whose assumed state must change, given the law at the solution
    (`violations_numpy` states the rules): a Taichi kernel (`kernels.violations`) for a
    law the kernel evaluated, the NumPy path otherwise. ``block_load``: each block's weight
    [N/m], the smallest load the state test measures it by."""
    if law.packed is None:
        return violations_numpy(model, contacts, law, block_load)
    from . import kernels as K

    p = model.params
    cstate, cvalue = law_inputs(contacts)
    bad = np.empty(contacts.n, np.int8)
    K.violations(contacts.cint, cstate, cvalue, contacts.block_a, contacts.block_b, law.packed[0],
                 law.packed[1], block_load.copy(), model.block_fixed.view(np.int8), model.penalty,
                 p.oc_force_tolerance, int(p.oc_force_reference == "load"), p.oc_state_tolerance,
                 model.force_roundoff, bad)
    return bad.view(bool)


@side_by_side.operation("violations")
def violations_numpy(model: Model, contacts: Contacts, law: ContactLaw, block_load: np.ndarray) -> np.ndarray:
    """Contacts whose assumed state must change, given the law at the solution.

    Within ``oc_force_tolerance`` × the load its free blocks carry (their weight or their
    largest contact force; ``oc_force_reference="load"``, the default) or × the contact's own strength
    (``"strength"``, the strict test), plus the round-off force p·open_tolerance·w0: Coulomb's
    law (a locked contact's shear force ≤ S, a sliding one's friction = S of this solve) and
    the tensile strength (a closed contact pulls at most T·L while bonded, else not at all).
    Within ``oc_state_tolerance`` × the load its blocks carry: the match of state
    and motion — an open contact that overlaps, a sliding one that would stick or slide
    the other way. A contact that carries almost nothing (a head joint of a loaded grid)
    then does not keep the iteration flipping it between open and closed, or between
    sticking and sliding, at forces far below anything that moves its blocks (§4.3)."""
    m, p = model, model.params
    vv = contacts.cint[:, KIND] == VV
    now = contacts.state
    atol = m.force_roundoff
    # the load each block carries: its weight, or its largest contact force
    level = block_load.copy()
    np.maximum.at(level, contacts.block_a, np.abs(law.fn))
    np.maximum.at(level, contacts.block_b, np.abs(law.fn))
    carried = np.maximum(level[contacts.block_a], level[contacts.block_b])
    tensile = np.where(contacts.bond, contacts.tensile * contacts.length, 0.0)
    by_load = p.oc_force_reference == "load"
    if by_load:
        # the force tests: the load of the contact's free blocks only (a fixed block's weight
        # and the forces on it are held by its support, not by the contact)
        free_level = np.where(m.block_fixed, 0.0, level)
        reference = np.maximum(free_level[contacts.block_a], free_level[contacts.block_b])
    strict = p.oc_force_tolerance * (reference if by_load else law.strength) + atol
    strict_tension = p.oc_force_tolerance * (reference if by_load else tensile) + atol
    locked = (now == LOCK) & ~vv
    sliding = (now == SLIDE) & ~vv & law.closed
    coulomb = locked & (np.abs(law.ft_now) > law.strength + strict)
    friction = sliding & (np.abs(law.friction_now - law.strength) > strict)
    tension = (now != OPEN) & (-law.fn_now > tensile + strict_tension)
    loose = p.oc_state_tolerance * carried + atol
    state = (np.abs(law.fn_now - law.fn) > loose) | (np.abs(law.ft_now - law.ft) > loose)
    # a VV contact whose other line is clearly less penetrated switches
    state |= vv & (now != OPEN) & (law.line != contacts.line) & (m.penalty * np.abs(law.dn - law.dn_now) > loose)
    return coulomb | friction | tension | state


def judge(model: Model, contacts: Contacts, law: ContactLaw, bad: np.ndarray,
          break_bonds: bool = True, couple: bool = True) -> Judgement:
    """Open-close judgement (§4.2–4.3) in place on ``contacts``.

    The solve assumed a state for each contact; ``law`` (`contact_law` at the solution)
    says which state the contact's motion calls for. A contact must change (``bad``, from
    `violations`) if its assumed state breaks the contact law — a locked contact holding more
    than its Coulomb strength, a sliding one whose friction is not N·tanφ + c·L of this solve,
    a closed one pulling harder than its tensile strength — or if its state does not match
    its motion by more than a small force (an open contact that overlaps, a sliding one
    that would stick). Such a contact takes the law's state, a sliding one with its friction
    from the solve it is in (it becomes `coupled`: implicit friction; with ``couple=False``, the
    lagged friction of ``Params.oc_friction``, from the normal force of this solve in the next),
    and the step iterates again. When none must change, every contact obeys no-tension and Coulomb's
    law at the solution.
    """
    p = model.params
    vv = contacts.cint[:, KIND] == VV
    # a bonded joint that the law opens (tension beyond T·L) or, with Shi's rule, makes
    # slide has failed in this step: it loses its cohesion and tensile strength now, and
    # the step is solved again without them (its strength is not carried through the step
    # in which it breaks)
    if break_bonds:  # (none break in the equilibrium stage, whose joints are Mohr–Coulomb)
        breaks = contacts.bond & (law.state != LOCK) & bad & \
            ((law.state == OPEN) | (p.bond_breaks_on_slip & (law.state == SLIDE)))
        if np.count_nonzero(breaks):
            contacts.bond[breaks] = False
    changed = bool(np.count_nonzero(bad))
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
        if couple:
            contacts.coupled |= slide
        contacts.shear_dir[slide] = law.direction[slide]
        contacts.state[bad] = law.state[bad]
        contacts.line[bad] = law.line[bad]
    closed = law.closed
    contacts.normal_force[closed] = np.maximum(law.fn[closed], 0.0)
    # a contact left closed (within the state tolerance) that the law opens carries no normal
    # force: its friction bound is 0, not the force of an earlier solve; nor does an open VV
    # contact (it has no friction: its force is only what it hands on)
    contacts.normal_force[~closed & ((contacts.state != OPEN) | vv)] = 0.0
    if law.tan_phi is not None:
        # Barton–Bandis: the next solve's secant friction is that of this solve's σn (eq.
        # BB3); a sliding contact whose friction was not it is a `violations` Coulomb
        # mismatch, so at convergence every contact holds the law at its own stress
        contacts.tan_phi[closed] = law.tan_phi[closed]
    contacts.dn[:] = np.where(bad, law.dn, law.dn_now)
    contacts.ds[:] = law.ds
    if changed:
        return Judgement(changed=True, bad=bad)
    closed_ve = (contacts.state != OPEN) & ~vv
    return Judgement(changed=False, bad=bad,
                     coulomb=float(np.maximum.reduce((np.abs(law.ft_now) - law.strength)[closed_ve], initial=0.0)),
                     friction=law.friction_now)


def internal_force(model: Model, contacts: Contacts, vec: np.ndarray, law: ContactLaw,
                   serial_scatter: bool) -> np.ndarray:
    """Generalised forces (6 per free block) of the contact forces of ``law``: the gradient
    of the spring energies, p·dn·∇dn of a closed contact and f_t·∇ds of its shear force
    (`kernels.internal_force` for a law the kernel evaluated)."""
    if law.packed is None or contacts.n == 0:
        return internal_force_numpy(model, contacts, vec, law)
    from . import kernels as K

    out = np.zeros(6 * model.n_free)
    K.internal_force(contacts.block_a, contacts.block_b, model.block_dof, vec, law.packed[0], law.packed[1],
                     out, serial_scatter)
    return out


def internal_force_numpy(model: Model, contacts: Contacts, vec: np.ndarray, law: ContactLaw) -> np.ndarray:
    """`internal_force` in NumPy (the path of a NumPy law, and the kernel's reference)."""
    rows = model.n_free
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
    dof = model.block_dof
    for blocks, f in ((contacts.block_a, fa), (contacts.block_b, fb)):
        r = dof[blocks]
        use = r >= 0
        out += np.bincount((6 * r[use])[:, None].repeat(6, 1).ravel() + np.tile(k, int(use.sum())),
                           weights=f[use].ravel(), minlength=6 * rows)
    return out


def accumulate_slip(model: Model, contacts: Contacts, vec: np.ndarray, disp: np.ndarray) -> None:
    """Add the step's slip |e_sᵀ·D_a + g_sᵀ·D_b| (the vertex's displacement along the edge,
    §2.8.4) to every sliding vertex-edge contact on a softening joint (eq. BB7), in place."""
    c = contacts
    soft = (c.state == SLIDE) & (c.cint[:, KIND] != VV) & ~np.isnan(model.joint_barton[c.joint, 5])
    if np.count_nonzero(soft):
        k = np.flatnonzero(soft)
        step = np.einsum("ij,ij->i", vec[k, S_ES], disp[c.block_a[k]]) + \
            np.einsum("ij,ij->i", vec[k, S_GS], disp[c.block_b[k]])
        c.slip[k] += np.abs(step)
