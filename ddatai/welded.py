"""The welded equilibrium of the stage (`ddatai.start`, module docstring 6.): the static solve with
every touching contact held as it is (normal and shear springs, no open-close judgement), blocks
that move away even so released; then each contact takes the joint law at t = 0 (`unweld`) and
a contact at its strength is handed over locked at it (`lock_at_strength`, which the frictional
stage's hand-over shares; docs/method/dda.md §8.12).
"""

from __future__ import annotations

import numpy as np

from .assembly import BlockPattern, assemble_blocks, assemble_contacts, contact_vectors
from .contact_law import contact_law, friction_force
from .contacts import Contacts, subset_contacts
from .layout import E0, KIND, LOCK, OPEN, SLIDE, VE
from .mechanisms import mechanisms
from .model import State
from .open_close import solve
from .return_mapping import STAGE_BETA


def unweld(stepper, contacts: Contacts) -> None:
    """The joint law at the end of a welded stage, in place: a contact pulled beyond its
    tensile strength (T·L while bonded, else the round-off force) opens; a locked vertex-edge
    contact whose shear spring carries more than its Coulomb strength N·tanφ + c·L is marked
    sliding, to be handed over locked at that strength (`lock_at_strength`)."""
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


def welded_solve(stepper, state: State, geom: dict, contacts: Contacts, vec: np.ndarray,
                  sca: np.ndarray, pattern: BlockPattern, dt: float):
    """One static solve with every contact in the state it has (the touching ones locked),
    without open-close judgement; the contacts' distances and normal forces are updated to
    the solution in place. Returns D, or None if the solve is not finite."""
    m = stepper.model
    data, rhs = assemble_blocks(stepper.model, state, geom, pattern, dt, STAGE_BETA, static_start=True)
    assemble_contacts(stepper.model, contacts, pattern, vec, sca, data, rhs, stepper.serial_scatter)
    # K is symmetric: a welded stage changes no state, so its vertex-edge contacts stay locked
    # (only vertex-vertex ones are "sliding", with no friction) and none is coupled
    disp = solve(stepper, pattern, data, rhs, reuse=True)  # repeated at a settled geometry
    if not np.all(np.isfinite(disp)):
        return None
    law = contact_law(stepper.model, contacts, vec, sca, disp)
    closed = contacts.state != OPEN
    contacts.normal_force[:] = np.where(closed, np.maximum(-m.penalty * law.dn_now, 0.0), 0.0)
    if law.tan_phi is not None:  # Barton–Bandis: the friction of this normal stress
        contacts.tan_phi[closed] = law.tan_phi[closed]
    contacts.dn[:] = law.dn_now
    contacts.ds[:] = law.ds
    return disp


def welded_step(stepper, state: State, geom: dict, contacts: Contacts, dt: float,
                 released: np.ndarray, size: np.ndarray):
    """One welded pseudo-step (module docstring, 6.): one solve with every touching contact held
    (`welded_solve`); blocks that move away even so are released and the rest solved again.
    Returns (D or None when a solve is not finite, solves, newly released blocks, contacts)."""
    out = released.copy()
    solves = 0
    while True:
        contacts = subset_contacts(contacts, ~(out[contacts.block_a] | out[contacts.block_b]))
        vec, sca = contact_vectors(stepper.model, state.vertex_xy, geom, contacts)
        pattern = BlockPattern.build(stepper.model, contacts)
        disp = welded_solve(stepper, state, geom, contacts, vec, sca, pattern, dt)
        solves += 1
        if disp is None:
            return None, solves, out & ~released, contacts
        mechanism = mechanisms(stepper, state.vertex_xy, geom, contacts, disp, out, size)
        if not mechanism.any():
            return disp, solves, out & ~released, contacts
        out |= mechanism


def lock_at_strength(stepper, contacts: Contacts, vertex_xy: np.ndarray) -> np.ndarray:
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


