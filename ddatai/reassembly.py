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
are added in full by a kernel that adds them alone (`kernels.assemble_contact_loads`, the
same terms in the same order, without the 144 entries of K that each spring adds with them;
its NumPy twin is ``contact_rhs``).

From ``PARTIAL_FROM`` contacts on, on the Taichi path: with fewer, and on the small-model
NumPy path (`Model.numpy_path`), a full assembly costs no more than the bookkeeping.
"""

from __future__ import annotations

import numpy as np

from .assembly import BlockPattern, assemble_contacts
from .contact_law import friction_terms
from .contacts import Contacts
from .layout import KIND, LOCK, N_SLOTS, OPEN, S_E0, S_ES, S_G0, S_GS, SLIDE, VE

#: past this share of the block-rows touched by changed contacts, K is assembled in full
FULL_ABOVE = 0.5
#: with fewer contacts than this, every iterate assembles K in full: the two kernel launches
#: and the bookkeeping of a partial one cost more (the stage of the 391-block slope, ~2,300
#: contacts: 1.49 ms an iterate in full, 1.65 ms partial; ~9,300 contacts: 4.4–6.4 ms in full,
#: 3.0–3.4 ms partial; benchmarks/results/large_round5.md)
PARTIAL_FROM = 4000

_SIX = np.arange(6)


def contact_rhs(model, contacts: Contacts, vec: np.ndarray, sca: np.ndarray, rhs: np.ndarray) -> None:
    """The NumPy twin of `kernels.assemble_contact_loads`: add the contact terms of F alone,
    those of `assembly.assemble_contacts` (§2.8), to ``rhs`` in place: −p·d₀·∇dn of each closed
    contact's active line, −k_s·d_s·∇ds of a locked vertex-edge one, −sgn·S·∇ds of a sliding
    one (S = a − b·dn₀, `contact_law.friction_terms`), the same products added in the kernel's
    order (contact by contact, the normal spring first). Entries on no free block's rows go to
    a sink past the end (no masks: a gather and one ``np.add.at``)."""
    closed = np.flatnonzero(contacts.state != OPEN)
    if not len(closed):
        return
    dof, vblock = model.block_dof, model.vertex_block
    cint = contacts.cint[closed]
    line1 = contacts.line[closed] == 1
    ri = dof[vblock[np.where(line1, cint[:, 3], cint[:, 1])]].astype(np.int64)
    rj = dof[vblock[np.where(line1, cint[:, 4], cint[:, 2])]].astype(np.int64)
    state = contacts.state[closed]
    ve = cint[:, KIND] == VE
    sliding = ve & (state == SLIDE)
    near = sca[closed]
    coefficient = np.empty((len(closed), 4))
    coefficient[:, 0] = (-model.penalty) * np.where(line1, near[:, 1], near[:, 0])
    coefficient[:, 1] = coefficient[:, 0]
    coefficient[:, 2] = np.where(ve & (state == LOCK), (-model.shear_penalty) * near[:, 2], 0.0)
    if np.count_nonzero(sliding):
        const, slope = friction_terms(model, contacts)
        c = closed[sliding]
        coefficient[sliding, 2] = -(contacts.shear_dir[c].astype(np.float64) * (const[c] - slope[c] * sca[c, 0]))
    coefficient[:, 3] = coefficient[:, 2]
    # the four gradients of each contact, one gather: (n, 4, 6)
    first = N_SLOTS * closed + S_E0 + 2 * line1
    slots = np.stack([first, first + (S_G0 - S_E0), N_SLOTS * closed + S_ES, N_SLOTS * closed + S_GS], axis=1)
    gradient = vec.reshape(-1, 6)[slots]
    sink = len(rhs) // 6                                              # a block-row past the last
    rows = np.empty((len(closed), 4), np.int64)
    rows[:, 0] = rows[:, 2] = np.where(ri >= 0, ri, sink)
    rows[:, 1] = rows[:, 3] = np.where(rj >= 0, rj, sink)
    rows[~ve, 2:] = sink                                              # no shear term
    extended = np.zeros(len(rhs) + 6)
    extended[:len(rhs)] = rhs
    np.add.at(extended, (6 * rows[:, :, None] + _SIX).ravel(), (coefficient[:, :, None] * gradient).ravel())
    rhs[:] = extended[:len(rhs)]


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
        self.scratch = self.scratch_rhs = None  # what `_rows_again` assembles into

    @staticmethod
    def _key(contacts: Contacts, copy: bool = True) -> tuple:
        """What a contact's terms in K depend on besides its vectors: its state and line, and for
        friction coupled to the solve's normal force its direction and tanφ."""
        fields = (contacts.state, contacts.line, contacts.coupled, contacts.shear_dir, contacts.tan_phi)
        return tuple(a.copy() for a in fields) if copy else fields

    def system(self, contacts: Contacts, sca: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(K's CSR data, F) with the contacts' terms for their states and ``sca``."""
        model = self.model
        if model.numpy_path or contacts.n < PARTIAL_FROM or self.data is None or \
                len(self.key[0]) != contacts.n:
            return self._assemble_all(contacts, sca)
        from . import kernels as K

        const, slope = friction_terms(model, contacts)
        changed = np.zeros(contacts.n, bool)
        for old, new in zip(self.key, self._key(contacts)):
            changed |= old != new
        if np.count_nonzero(changed):
            touched = self._blocks(contacts, changed)
            if np.count_nonzero(touched) > FULL_ABOVE * self.pattern.n_rows:
                return self._assemble_all(contacts, sca)
            self.data = self._rows_again(K, contacts, sca, const, slope, touched)
            self.key = self._key(contacts)
            self.partial += 1
        else:
            self.kept += 1
        rhs = self.block_rhs.copy()
        K.assemble_contact_loads(contacts.cint, contacts.state, contacts.line, model.vertex_block, model.block_dof,
                                 self.vec, sca, const, slope, contacts.shear_dir, model.penalty,
                                 model.shear_penalty, rhs, self.serial_scatter)
        return self.data, rhs

    def _assemble_all(self, contacts: Contacts, sca: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        if self.model.numpy_path:
            # K again only where what it depends on changed: else the last K, F's terms alone
            # (`assembly.contact_terms_numpy`, the same floats), as `system` does on the kernels
            key = b"".join(a.tobytes() for a in self._key(contacts, copy=False))
            if self.data is not None and key == self.key:
                rhs = self.block_rhs.copy()
                assemble_contacts(self.model, contacts, self.pattern, self.vec, sca, None, rhs, self.serial_scatter)
                self.kept += 1
                return self.data, rhs
        data, rhs = self.block_data.copy(), self.block_rhs.copy()
        assemble_contacts(self.model, contacts, self.pattern, self.vec, sca, data, rhs, self.serial_scatter)
        self.data, self.key = data, key if self.model.numpy_path else self._key(contacts)
        self.full += 1
        return data, rhs

    def _blocks(self, contacts: Contacts, which: np.ndarray) -> np.ndarray:
        """(B,) the free blocks of the contacts ``which`` (a fixed block has no rows)."""
        blocks = np.zeros(self.model.n_blocks, bool)
        blocks[contacts.block_a[which]] = blocks[contacts.block_b[which]] = True
        return blocks & ~self.model.block_fixed

    def _row_entries(self, blocks: np.ndarray) -> np.ndarray:
        """Positions in the CSR data of the block-rows of ``blocks``: block-row r is contiguous,
        indptr[6r] up to indptr[6r + 6]."""
        rows = self.model.block_dof[blocks]
        indptr = self.pattern.indptr
        start = indptr[6 * rows].astype(np.int64)
        count = indptr[6 * rows + 6].astype(np.int64) - start
        return np.repeat(start - np.cumsum(count) + count, count) + np.arange(int(count.sum()))

    def _rows_again(self, K, contacts: Contacts, sca: np.ndarray, const: np.ndarray, slope: np.ndarray,
                    touched: np.ndarray) -> np.ndarray:
        """The last K with the block-rows of the blocks ``touched`` assembled again from the block
        terms and every contact that touches those blocks, in order, by the kernel of the full
        assembly (into a scratch copy whose rows it writes are first reset to the block terms)."""
        near = np.flatnonzero(touched[contacts.block_a] | touched[contacts.block_b])
        if self.scratch is None:
            self.scratch, self.scratch_rhs = self.block_data.copy(), np.zeros_like(self.block_rhs)
        else:
            written = self._row_entries(self._blocks(contacts, near))
            self.scratch[written] = self.block_data[written]
        model, pattern = self.model, self.pattern
        K.assemble_contacts(contacts.cint[near], contacts.state[near], contacts.line[near], model.vertex_block,
                            model.block_dof, self.vec[near], sca[near], const[near], slope[near],
                            contacts.shear_dir[near], pattern.slot_ab[near], pattern.slot_ba[near],
                            pattern.diag_slot, pattern.stride, model.penalty, model.shear_penalty,
                            self.scratch, self.scratch_rhs, self.serial_scatter)
        at = self._row_entries(touched)
        data = self.data.copy()
        data[at] = self.scratch[at]
        return data
