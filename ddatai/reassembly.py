"""The contact terms of K and F re-assembled after each judgement of an open-close iteration
(docs/method/dda.md §2.8, §9), touching only what changed.

Within one try at a step the contact vectors and the block terms stay; what a judgement changes
is each contact's state (open, locked, sliding), its line, its shear direction and whether its
friction follows the solve (`Contacts.coupled`). K's contact terms depend on nothing else, so a
later solve's K differs from the last one only in the 6×6 blocks of the contacts that changed:
the diagonal blocks of their blocks and the off-diagonal blocks of their pairs. Those blocks are
reset to the block terms and summed again from every contact that adds to them, in contact order
— the additions of a full assembly (`ddatai.assembly.assemble_contacts`), in its order, so that
K comes out bit for bit as a full assembly gives it where that kernel runs serially (on a CPU of
at most four threads, `ddatai.backend.serial_scatter`; a parallel loop sums in any order, and
then both are the same sums to round-off). F changes at every contact (the second-order shift
moves every spring's rest point, and a sliding contact's friction follows the last solve's
normal force), and is assembled whole by its loads alone. Where more than ``WHOLE_SHARE`` of the
contacts would be visited again, K and F are assembled whole in one kernel.

`ContactAssembly.assemble` also returns the block-rows whose K changed, which tell the solver
where K differs from the matrix it last factorised (`ddatai.solver`, Krylov solves).
"""

from __future__ import annotations

from typing import Optional

import numpy as np

from .assembly import BlockPattern, assemble_contacts, contact_terms_numpy
from .contact_law import friction_terms
from .contacts import Contacts
from .layout import OPEN, SLIDE

#: K and F are assembled whole (one kernel, `ddatai.assembly.assemble_contacts`) when the
#: contacts to visit again are more than this share of all contacts: re-summing costs a second
#: kernel launch (F's loads) and the bookkeeping, measured paired per solve on the failing
#: slopes of benchmarks/scaling.py (docs/guide/performance.md)
WHOLE_SHARE = 0.1


def stiffness_key(contacts: Contacts, slope: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """What of each contact K depends on (`ddatai.assembly.assemble_contacts`): its state, the
    line of a closed one, and the signed friction slope −dir·b of a sliding one (non-zero only
    where its friction is coupled to the solve)."""
    state = contacts.state.copy()
    line = np.where(state != OPEN, contacts.line, -1).astype(np.int8)
    coupled = np.where(state == SLIDE, contacts.shear_dir * slope, 0.0)
    return state, line, coupled


class ContactAssembly:
    """K and F of one try at a step (``data0``, ``pattern``, ``vec`` fixed) for the contacts'
    states of each solve. ``serial``: the kernels' loop mode (`ddatai.backend.serial_scatter`)."""

    def __init__(self, model, pattern: BlockPattern, vec: np.ndarray, data0: np.ndarray, serial: bool):
        self.model, self.pattern, self.vec, self.data0, self.serial = model, pattern, vec, data0, serial
        self.data: Optional[np.ndarray] = None  # K of the last assembly
        self.key: Optional[tuple] = None        # the contacts' K-terms of the last assembly
        dof = model.block_dof
        self.rows_a: Optional[np.ndarray] = None
        self.rows_b: Optional[np.ndarray] = None
        self._dof = dof

    def assemble(self, contacts: Contacts, sca: np.ndarray, rhs: np.ndarray
                 ) -> tuple[np.ndarray, Optional[np.ndarray]]:
        """K for the contacts' states (a new array where it changed, else the last one: never
        written after it is returned), and the contact loads added to ``rhs`` in place.
        Returns (K data, block-rows whose entries may differ from the last K: sorted, None for
        a whole assembly)."""
        model, pattern = self.model, self.pattern
        const, slope = friction_terms(model, contacts)
        key = stiffness_key(contacts, slope)
        if self.data is None or contacts.n == 0:
            return self._whole(contacts, sca, rhs, key), None
        changed = np.flatnonzero((key[0] != self.key[0]) | (key[1] != self.key[1]) | (key[2] != self.key[2]))
        if not len(changed):
            self._loads(contacts, sca, const, slope, rhs)
            self.key = key
            return self.data, np.zeros(0, np.int64)
        if len(changed) > WHOLE_SHARE * contacts.n:
            return self._whole(contacts, sca, rhs, key), None
        if self.rows_a is None:
            self.rows_a = self._dof[contacts.block_a].astype(np.int64)
            self.rows_b = self._dof[contacts.block_b].astype(np.int64)
        ra, rb = self.rows_a, self.rows_b
        rows = np.union1d(ra[changed], rb[changed])
        rows = rows[rows >= 0]
        row_on = np.zeros(pattern.n_rows, np.int8)
        row_on[rows] = 1
        # every contact that adds to a changed block: those touching a changed block-row
        visit = np.flatnonzero(((ra >= 0) & (row_on[np.maximum(ra, 0)] != 0)) |
                               ((rb >= 0) & (row_on[np.maximum(rb, 0)] != 0)))
        if len(visit) > WHOLE_SHARE * contacts.n:
            return self._whole(contacts, sca, rhs, key), None
        self._loads(contacts, sca, const, slope, rhs)
        # the off-diagonal blocks of the changed contacts' pairs (both blocks free)
        n = pattern.n_rows
        pair = np.minimum(ra, rb) * n + np.maximum(ra, rb)
        both = (ra >= 0) & (rb >= 0)
        changed_pairs = np.unique(pair[changed][both[changed]])
        pair_on = (both & np.isin(pair, changed_pairs)).view(np.int8) if len(changed_pairs) else \
            np.zeros(contacts.n, np.int8)
        data = self.data.copy()
        at = self._positions(rows, changed_pairs)
        data[at] = self.data0[at]
        self._stiffness(contacts, slope, visit, row_on, np.ascontiguousarray(pair_on, dtype=np.int8), data)
        self.data, self.key = data, key
        return data, rows

    # ------------------------------------------------------------------ pieces
    def _whole(self, contacts, sca, rhs, key) -> np.ndarray:
        data = self.data0.copy()
        assemble_contacts(self.model, contacts, self.pattern, self.vec, sca, data, rhs, self.serial)
        self.data, self.key = data, key
        return data

    def _positions(self, rows: np.ndarray, pairs: np.ndarray) -> np.ndarray:
        """Positions in the CSR data of the diagonal blocks of ``rows`` and of both
        off-diagonal blocks of each pair key lo·n + hi in ``pairs``."""
        p = self.pattern
        n = p.n_rows
        lo, hi = pairs // n, pairs % n
        r = np.concatenate([rows, lo, hi])
        slot = np.concatenate([p.diag_slot[rows].astype(np.int64), p.slots(lo, hi).astype(np.int64),
                               p.slots(hi, lo).astype(np.int64)])
        six = np.arange(6)
        return (slot[:, None, None] + p.stride[r].astype(np.int64)[:, None, None] * six[None, :, None] +
                six[None, None, :]).ravel()

    def _stiffness(self, contacts, slope, visit, row_on, pair_on, data) -> None:
        m, p = self.model, self.pattern
        if m.numpy_path:
            keep = np.zeros(contacts.n, bool)
            keep[visit] = True
            state = np.where(keep, contacts.state, 0).astype(np.int8)  # unvisited: as if open
            contact_terms_numpy(contacts.cint, state, contacts.line, m.vertex_block, m.block_dof, self.vec,
                                None, None, slope, contacts.shear_dir, p, m.penalty, m.shear_penalty, data,
                                None, row_on=row_on, pair_on=pair_on)
            return
        from . import kernels as K

        K.assemble_contact_stiffness(np.ascontiguousarray(visit, dtype=np.int32), contacts.cint, contacts.state,
                                     contacts.line, m.vertex_block, m.block_dof, self.vec, slope,
                                     contacts.shear_dir, p.slot_ab, p.slot_ba, p.diag_slot, p.stride,
                                     row_on, pair_on, m.penalty, m.shear_penalty, data, self.serial)

    def _loads(self, contacts, sca, const, slope, rhs) -> None:
        m = self.model
        if m.numpy_path:
            contact_terms_numpy(contacts.cint, contacts.state, contacts.line, m.vertex_block, m.block_dof,
                                self.vec, sca, const, slope, contacts.shear_dir, self.pattern, m.penalty,
                                m.shear_penalty, None, rhs)
            return
        from . import kernels as K

        K.assemble_contact_loads(contacts.cint, contacts.state, contacts.line, m.vertex_block, m.block_dof,
                                 self.vec, np.ascontiguousarray(sca), const, slope, contacts.shear_dir,
                                 m.penalty, m.shear_penalty, rhs, self.serial)
