"""K and F of an iteration whose contacts keep their vectors, iterate after iterate: K is
re-assembled only on the rows of the blocks whose contacts changed state, F in full
(docs/method/dda.md §2.8).

The equilibrium stage's return mapping (`ddatai.return_mapping`) solves many times at one
geometry: each iterate K changes only where contacts open or close (a median of 4 of the
1,537-block slope's ~9,000 contacts, against ~1,000–1,900 whose slips move and so move F),
and the last K is kept. A contact's terms reach only the rows of its two blocks, and each
entry of a block-row is the sum of that block's terms and of the terms of the contacts that
touch it, added in the contacts' order. So the rows of the blocks touched by a changed contact
are assembled again from the block terms with every contact that touches those blocks, in the
same order, by the same kernel, and copied into the kept K: the result is the full assembly's,
float for float. F moves with the slips of the contacts at their strength: its contact terms
are added in full, in NumPy (``contact_rhs``: the same products added in the kernel's order, a
quarter of the kernel's time, which also adds the ~24 entries of K of each contact).

The Taichi path only: on the small-model NumPy path (`Model.numpy_path`) a full assembly costs
about what the bookkeeping does.
"""

from __future__ import annotations

import numpy as np

from .assembly import BlockPattern, assemble_contacts
from .contact_law import friction_terms
from .contacts import Contacts
from .layout import KIND, LOCK, OPEN, S_E0, S_ES, S_G0, S_GS, SLIDE, VE

#: past this share of the block-rows touched by changed contacts, K is assembled in full
FULL_ABOVE = 0.5

_SIX = np.arange(6)


def _subset(contacts: Contacts, keep: np.ndarray) -> Contacts:
    return Contacts(**{k: v[keep] for k, v in vars(contacts).items()})


def contact_rhs(model, contacts: Contacts, vec: np.ndarray, sca: np.ndarray, rhs: np.ndarray) -> None:
    """Add the contact terms of F alone, those of `assembly.assemble_contacts` (§2.8), to
    ``rhs`` in place: −p·d₀·∇dn of each closed contact's active line, −k_s·d_s·∇ds of a locked
    vertex-edge one, −sgn·S·∇ds of a sliding one (S = a − b·dn₀, `contact_law.friction_terms`),
    in the kernel's order (contact by contact, the normal spring first)."""
    closed = np.flatnonzero(contacts.state != OPEN)
    if not len(closed):
        return
    cint, dof, vblock = contacts.cint, model.block_dof, model.vertex_block
    q = contacts.line[closed].astype(np.int64)
    ri = dof[vblock[cint[closed, 1 + 2 * q]]].astype(np.int64)
    rj = dof[vblock[cint[closed, 2 + 2 * q]]].astype(np.int64)
    state = contacts.state[closed]
    ve = cint[closed, KIND] == VE
    locked, sliding = ve & (state == LOCK), ve & (state == SLIDE)
    normal = (-model.penalty) * sca[closed, q]
    const, slope = friction_terms(model, contacts)
    c = closed[sliding]
    friction = contacts.shear_dir[c].astype(np.float64) * (const[c] - slope[c] * sca[c, 0])
    shear = np.zeros(len(closed))
    shear[locked] = (-model.shear_penalty) * sca[closed[locked], 2]
    shear[sliding] = -friction
    values = np.empty((len(closed), 4, 6))
    values[:, 0] = normal[:, None] * vec[closed, S_E0 + 2 * q]
    values[:, 1] = normal[:, None] * vec[closed, S_G0 + 2 * q]
    values[:, 2] = shear[:, None] * vec[closed, S_ES]
    values[:, 3] = shear[:, None] * vec[closed, S_GS]
    rows = np.stack([ri, rj, ri, rj], axis=1)                                  # (n, 4)
    keep = (rows >= 0) & np.stack([np.ones_like(ve), np.ones_like(ve), ve, ve], axis=1)
    at = 6 * rows[:, :, None] + _SIX
    np.add.at(rhs, at[keep].ravel(), values[keep].ravel())


class ContactSystem:
    """K and F of the iterates of one pseudo-step (module docstring): the block terms
    ``block_data``, ``block_rhs`` (`assembly.assemble_blocks`) with the contact terms at the
    fixed vectors ``vec`` on ``pattern``. `system` returns them for the contacts' states and
    constant parts of an iterate; K is a new array where it changed and the same one where it
    did not (never written in place: the solver compares it with the factorised one)."""

    def __init__(self, model, pattern: BlockPattern, vec: np.ndarray, block_data: np.ndarray,
                 block_rhs: np.ndarray, serial_scatter: bool):
        self.model, self.pattern, self.vec = model, pattern, vec
        self.block_data, self.block_rhs = block_data, block_rhs
        self.serial_scatter = serial_scatter
        self.data = None   # the last K
        self.key = None    # what K depends on of each contact, as K was assembled
        self.full = 0      # assemblies of all contacts
        self.partial = 0   # re-assemblies of some block-rows
        self.kept = 0      # iterates whose K had not changed

    @staticmethod
    def _key(contacts: Contacts) -> tuple:
        """What a contact's terms in K depend on besides its vectors: its state and line, and for
        friction coupled to the solve's normal force its direction and tanφ."""
        return (contacts.state.copy(), contacts.line.copy(), contacts.coupled.copy(),
                contacts.shear_dir.copy(), contacts.tan_phi.copy())

    def system(self, contacts: Contacts, sca: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(K's CSR data, F) with the contacts' terms for their states and ``sca``."""
        model = self.model
        if model.numpy_path or self.data is None or len(self.key[0]) != contacts.n:
            return self._assemble_all(contacts, sca)
        changed = np.zeros(contacts.n, bool)
        for old, new in zip(self.key, self._key(contacts)):
            changed |= old != new
        if changed.any():
            touched = np.zeros(model.n_blocks, bool)
            touched[contacts.block_a[changed]] = touched[contacts.block_b[changed]] = True
            touched &= ~model.block_fixed  # a fixed block has no rows (nor its other contacts a part)
            rows = model.block_dof[touched]
            rows = rows[rows >= 0]
            if len(rows) > FULL_ABOVE * self.pattern.n_rows:
                return self._assemble_all(contacts, sca)
            self.data = self._rows_again(contacts, sca, touched, rows)
            self.key = self._key(contacts)
            self.partial += 1
        else:
            self.kept += 1
        rhs = self.block_rhs.copy()
        contact_rhs(model, contacts, self.vec, sca, rhs)
        return self.data, rhs

    def _assemble_all(self, contacts: Contacts, sca: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        data, rhs = self.block_data.copy(), self.block_rhs.copy()
        assemble_contacts(self.model, contacts, self.pattern, self.vec, sca, data, rhs, self.serial_scatter)
        self.data, self.key = data, self._key(contacts)
        self.full += 1
        return data, rhs

    def _rows_again(self, contacts: Contacts, sca: np.ndarray, touched: np.ndarray, rows: np.ndarray
                    ) -> np.ndarray:
        """The last K with the block-rows ``rows`` (of the blocks ``touched``) assembled again
        from the block terms and every contact that touches those blocks, in order."""
        near = touched[contacts.block_a] | touched[contacts.block_b]
        pattern = self.pattern
        scratch, scratch_rhs = self.block_data.copy(), np.zeros_like(self.block_rhs)
        local = _subset(contacts, near)
        part = BlockPattern(**{**vars(pattern), "slot_ab": pattern.slot_ab[near], "slot_ba": pattern.slot_ba[near]})
        assemble_contacts(self.model, local, part, self.vec[near], sca[near], scratch, scratch_rhs,
                          self.serial_scatter)
        # block-row r is contiguous in the CSR data: indptr[6r] up to indptr[6r + 6]
        start = pattern.indptr[6 * rows].astype(np.int64)
        count = pattern.indptr[6 * rows + 6].astype(np.int64) - start
        at = np.repeat(start - np.cumsum(count) + count, count) + np.arange(int(count.sum()))
        data = self.data.copy()
        data[at] = scratch[at]
        return data
