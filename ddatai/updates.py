"""Cholesky factors that follow the contact springs: CHOLMOD's rank updates (the ``[cholmod]``
extra, docs/method/dda.md §9).

Within one step (or one pseudo-step of the equilibrium stage) the contact vectors are fixed, and
K is the block terms plus one rank-one term per spring: p·a·aᵀ for the normal spring of a closed
contact, a = [∇dn on block i; ∇dn on block j] of its active line, and k_s·s·sᵀ for the shear
spring of a locked vertex-edge one (§2.8). Lagged friction (and the stage's return mapping, whose
contacts are all springs) keeps K symmetric positive definite, so a contact that opens, closes,
locks, slides or changes line changes K by a term of rank one or two, and the Cholesky factor of
the last K becomes the factor of the next one by CHOLMOD's update and downdate
(``cholmod_updown``, Davis & Hager) instead of a new factorisation: ``Springs`` names the springs
in one K, ``Springs.columns`` the columns √p·a (√k_s·s) added and removed between two of them, and
``UpdatedFactor`` keeps the factor, its analysis (one per sparsity pattern) and the springs it
stands for.

What an update costs, measured on the 1,537-block slope's K (9,222 unknowns, 2-core Xeon, one
thread; docs/guide/performance.md): a rank-r update about r/300 of a numeric factorisation (the
first after a factorisation also converts the supernodal factor to the simplicial form the
update needs, about 1/30 of one), and a solve with the updated factor about 1/20. So a solve
whose springs differ from the factor's by at most ``UPDATE_RANK`` columns is done by updates
(``ddatai.solver.SparseSolver.solve``, ``springs``); more, or once the updates since the last factorisation add
up to ``ACCUMULATED_RANK`` columns, factorise. Each updated solve is checked against K itself
(its residual, with refinement by the updated factor, as a factor reused between steps), so
the round-off of many updates can cost a factorisation, never accuracy.

The binding is scikit-sparse (``pip install "ddatai[cholmod]"``), built against the system's
SuiteSparse (Debian/Ubuntu: ``apt-get install libsuitesparse-dev``). Without it nothing here is
used and every solve factorises as before.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import Optional

import numpy as np

from .layout import KIND, LOCK, OPEN, S_E0, S_ES, S_G0, S_GS, VE

#: a solve whose springs differ from the factor's by at most this many columns (rank-one terms)
#: is done by updating the factor; more, and it factorises (the break-even, module docstring)
UPDATE_RANK = 120
#: ... and it factorises once the updates since the last factorisation add up to this many
#: columns (each update is a little less exact than a factorisation; their cost adds up too)
ACCUMULATED_RANK = 600


@functools.lru_cache(maxsize=None)
def available() -> bool:
    """Whether CHOLMOD's binding (scikit-sparse, the ``[cholmod]`` extra) can be imported."""
    try:
        from sksparse import cholmod  # noqa: F401
    except Exception:  # noqa: BLE001 - any import failure (missing library) means "not here"
        return False
    return True


def why_unavailable() -> str:
    """One line saying why CHOLMOD cannot be used here (for skipped tests and messages)."""
    try:
        from sksparse import cholmod  # noqa: F401
    except Exception as err:  # noqa: BLE001
        return (f"CHOLMOD's rank updates need the [cholmod] extra (scikit-sparse built against the "
                f"system's SuiteSparse: apt-get install libsuitesparse-dev; pip install 'ddatai[cholmod]'): {err}")
    return ""


@dataclass(frozen=True, kw_only=True, eq=False)
class Springs:
    """The contact springs in one K: for each contact the line of its normal spring (−1: open)
    and whether it has a shear spring, with the contact vectors and penalties they are made of.
    Two ``Springs`` of the same contact vectors (``vec``, the same array) differ by the
    rank-one terms of ``Springs.columns``."""

    vec: np.ndarray          # (m, N_SLOTS, 6) the contact vectors of the step (`ddatai.assembly.contact_vectors`)
    rows: np.ndarray         # (m, 2, 2) block-row of blocks i and j of line 0 and line 1 (−1: fixed)
    normal: np.ndarray       # (m,) int8: line of the normal spring, −1 for none
    shear: np.ndarray        # (m,) bool: a shear spring (locked vertex-edge contact)
    penalty: float
    shear_penalty: float

    @staticmethod
    def of(model, contacts, vec: np.ndarray, rows: Optional[np.ndarray] = None) -> "Springs":
        """The springs that the contacts' states put in K (`ddatai.assembly.assemble_contacts`):
        a normal spring on the active line of every closed contact, a shear spring on every
        locked vertex-edge one. ``rows``: `block_rows` of these contacts, if already known."""
        closed = contacts.state != OPEN
        return Springs(vec=vec, rows=block_rows(model, contacts) if rows is None else rows,
                       normal=np.where(closed, contacts.line, -1).astype(np.int8),
                       shear=closed & (contacts.state == LOCK) & (contacts.cint[:, KIND] == VE),
                       penalty=float(model.penalty), shear_penalty=float(model.shear_penalty))

    def same_terms(self, other: "Springs") -> bool:
        """Whether ``other``'s springs are made of the same vectors (the same step's geometry)
        and penalties, so that the two K differ only by ``Springs.columns``."""
        return (other is not None and other.vec is self.vec and len(other.normal) == len(self.normal)
                and other.penalty == self.penalty and other.shear_penalty == self.shear_penalty)

    def changed(self, other: "Springs") -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """The contacts whose springs differ from ``other``'s: (normal springs added, normal
        springs removed, shear springs added, shear springs removed), as contact indices."""
        moved = self.normal != other.normal
        return (np.flatnonzero(moved & (self.normal >= 0)), np.flatnonzero(moved & (other.normal >= 0)),
                np.flatnonzero(self.shear & ~other.shear), np.flatnonzero(other.shear & ~self.shear))

    def rank(self, other: "Springs") -> int:
        """How many rank-one terms separate the two K (``Springs.columns``)."""
        return int(sum(len(k) for k in self.changed(other)))

    def columns(self, other: "Springs", n: int):
        """(added, removed): CSC matrices (n, r) whose columns c give this K as ``other``'s
        K + Σ c_add·c_addᵀ − Σ c_rem·c_remᵀ (√p·a of each normal spring on its line, √k_s·s of
        each shear spring)."""
        from scipy.sparse import csc_matrix

        new_n, old_n, new_s, old_s = self.changed(other)
        out = []
        for normal, shear, springs in ((new_n, new_s, self), (old_n, old_s, other)):
            line = springs.normal[normal].astype(np.int64)
            parts = [(normal, line, S_E0 + 2 * line, S_G0 + 2 * line, np.sqrt(self.penalty)),
                     (shear, np.zeros(len(shear), np.int64), np.full(len(shear), S_ES), np.full(len(shear), S_GS),
                      np.sqrt(self.shear_penalty))]
            r_all, v_all, c_all, col = [], [], [], 0
            for k, q, slot_i, slot_j, scale in parts:
                if not len(k):
                    continue
                cols = col + np.arange(len(k))
                col += len(k)
                for side, slot in ((0, slot_i), (1, slot_j)):
                    r = self.rows[k, q, side]
                    on = r >= 0
                    r_all.append(((6 * r[on])[:, None] + np.arange(6)).ravel())
                    v_all.append((scale * self.vec[k[on], slot[on]]).ravel())
                    c_all.append(np.repeat(cols[on], 6))
            if col == 0:
                out.append(None)
                continue
            rr, vv, cc = np.concatenate(r_all), np.concatenate(v_all), np.concatenate(c_all)
            out.append(csc_matrix((vv, (rr, cc)), shape=(n, col)))
        return out[0], out[1]


def block_rows(model, contacts) -> np.ndarray:
    """(m, 2, 2) block-row of the blocks of each contact line: [line 0: vertex's block, edge's
    block; line 1: the same of the second line of a vertex-vertex contact], −1 for a fixed block
    (the rows `ddatai.assembly.assemble_contacts` adds each spring to)."""
    vb, dof = model.vertex_block, model.block_dof
    cint = contacts.cint
    out = np.empty((contacts.n, 2, 2), np.int64)
    for q in (0, 1):
        out[:, q, 0] = dof[vb[cint[:, 1 + 2 * q]]]
        out[:, q, 1] = dof[vb[cint[:, 2 + 2 * q]]]
    return out


class UpdatedFactor:
    """A CHOLMOD Cholesky factor of K that follows the springs (module docstring): the
    analysis of the sparsity pattern (kept while the pattern stays), the factor, the springs it
    stands for and the rank of the updates since it was factorised."""

    def __init__(self):
        self._analysis = None  # ((indptr, indices), symbolic supernodal factor)
        self.factor = None
        self.springs: Optional[Springs] = None
        self.accumulated = 0
        self.updates = 0       # solves done by updating (counted by the solver)

    def forget(self) -> None:
        """Drop the factor (another matrix was solved: it no longer stands for the last K)."""
        self.factor, self.springs, self.accumulated = None, None, 0

    def factorise(self, data: np.ndarray, indices: np.ndarray, indptr: np.ndarray, n: int, same,
                  springs: Springs) -> bool:
        """Factorise K (CSR of a symmetric K = its CSC); returns False where it is not positive
        definite (the caller then solves it by LU). ``same(key, indptr, indices)``: whether a
        stored structure is this one (``SparseSolver._same``)."""
        from scipy.sparse import csc_matrix
        from sksparse import cholmod

        k = csc_matrix((data, indices, indptr), shape=(n, n))
        if self._analysis is None or not same(self._analysis[0], indptr, indices):
            # AMD: as good as METIS on these 2-D block graphs and 2× quicker to order
            self._analysis = ((indptr, indices), cholmod.analyze(k, mode="supernodal", ordering_method="amd"))
        factor = self._analysis[1].copy()  # the symbolic analysis, copied: the factor is updated in place
        try:
            factor.cholesky_inplace(k)
        except cholmod.CholmodNotPositiveDefiniteError:
            self.forget()
            return False
        self.factor, self.springs, self.accumulated = factor, springs, 0
        return True

    def update(self, springs: Springs, n: int) -> bool:
        """Make the factor stand for ``springs`` by rank updates; False where it cannot (no
        factor, another step's vectors, too many columns: ``UPDATE_RANK``, ``ACCUMULATED_RANK``), or
        where a downdate loses positive definiteness (the factor is then dropped)."""
        if self.factor is None or not springs.same_terms(self.springs):
            return False
        rank = springs.rank(self.springs)
        if rank > UPDATE_RANK or self.accumulated + rank > ACCUMULATED_RANK:
            return False
        if rank:
            from sksparse import cholmod

            added, removed = springs.columns(self.springs, n)
            try:
                # the additions first: the matrix stays further from singular on the way
                if added is not None:
                    self.factor.update_inplace(added, subtract=False)
                if removed is not None:
                    self.factor.update_inplace(removed, subtract=True)
            except cholmod.CholmodError:
                self.forget()
                return False
        self.springs, self.accumulated = springs, self.accumulated + rank
        return True

    def solve(self, rhs: np.ndarray) -> np.ndarray:
        return self.factor.solve_A(rhs)
