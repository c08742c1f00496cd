"""The block system of a scene (docs/kgm/method.md §2): `BlockSystem`, the flat arrays of
block theory — block areas, centroids, masses and active forces, the contacts (segments shared
by two blocks) with the strength of their joints — and its queries (a block's polygon,
contacts, neighbours, free segments; a joint's friction at a normal stress). `kgm.build` makes
it from a `ddatai.Scene`.

Conventions (§1): x horizontal, y up, gravity −y; a contact's normal points **into** its first
block ``a`` (away from ``b``); a translation s of a block penetrates a neighbour across a
contact when s·n < 0 (n into the block). Everything here is NumPy only.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Iterable, Optional

import numpy as np

from .strength import Strength

#: Two directions closer than this are the same face direction [rad]. Cut blocks have edges
#: parallel to ~1e-12 rad; hand-built scenes to the precision of their coordinates.
ANGLE_TOL = 1e-6
#: Points closer than this fraction of the model size are the same point; edges whose ends lie
#: this close to each other's line are collinear [-].
DISTANCE_TOL = 1e-6
#: Contacts shorter than this fraction of the model size are ignored (corner touches) [-].
MIN_CONTACT = 1e-5
#: Two anti-parallel edges whose lines are at most this fraction of the model size apart are in
#: contact (a gap of that size is drawing precision, not a separation): 1 mm in a 10 m model.
#: A block further from its neighbours is free of them; blocks that overlap are refused.
#: ``build_block_system(scene, contact_gap=...)`` / ``Settings.contact_gap`` set it in metres [-].
CONTACT_GAP = 1e-4
#: Fixed-point iteration on the normal forces of Barton–Bandis faces: at most this many
#: passes, stopped when tan φ(σn) changes by less than BARTON_TOL (docs/method/barton_bandis.md).
BARTON_ITERATIONS = 100
BARTON_TOL = 1e-12


@dataclass(frozen=True, kw_only=True, eq=False)
class BlockSystem:
    """Static block-theory data of a scene: blocks, contacts between them, their strengths.

    Block ids are the scene's block ids. Arrays are flat; contact k joins blocks
    ``contact_blocks[k] = (a, b)`` with a < b.
    """

    vertex_offset: np.ndarray
    """(B+1,) block b owns vertices ``vertex_offset[b]:vertex_offset[b+1]``."""
    vertex_xy: np.ndarray
    """(V, 2) CCW block vertices [m]."""
    block_area: np.ndarray
    """(B,) block areas [m²] (per m of thickness: volume [m³/m])."""
    block_centroid: np.ndarray
    """(B, 2) block centroids [m]."""
    block_mass: np.ndarray
    """(B,) block masses ρ·A [kg/m]."""
    block_force: np.ndarray
    """(B, 2) resultant active force of each block: weight plus constant point loads [N/m]."""
    block_moment: np.ndarray
    """(B,) moment of the active forces about the origin (0, 0), counter-clockwise positive
    [N·m/m]."""
    block_fixed: np.ndarray
    """(B,) bool: fixed in the scene, or pinned by a fixed point (type V, 'infinite')."""
    contact_blocks: np.ndarray
    """(C, 2) int64 blocks (a, b), a < b, sharing contact k."""
    contact_start: np.ndarray
    """(C, 2) first end of the shared segment [m]."""
    contact_end: np.ndarray
    """(C, 2) second end of the shared segment [m]."""
    contact_normal: np.ndarray
    """(C, 2) unit normal of the segment pointing into block a (away from b) [-]."""
    contact_length: np.ndarray
    """(C,) length of the shared segment [m]."""
    contact_friction: np.ndarray
    """(C,) friction angle φ of the joint [degrees]."""
    contact_cohesion: np.ndarray
    """(C,) cohesion c of the joint [Pa]."""
    contact_tensile: np.ndarray
    """(C,) tensile strength of the joint [Pa] (limit-equilibrium evaluators take it as 0,
    docs/kgm/method.md §1; the DDA evaluator uses it as given)."""
    contact_joint: np.ndarray
    """(C,) index of the contact's joint in the scene's joint table."""
    contact_edge: np.ndarray
    """(C, 2) global edge (start-vertex) index of the segment on block a and on block b."""
    contact_span: np.ndarray
    """(C, 2, 2) parameter interval [m from the edge start] of the segment along the edge of
    block a (row 0) and of block b (row 1)."""
    gravity: float
    """Gravitational acceleration [m/s²], acting in −y."""
    scale: float
    """Largest side of the model's bounding box [m]; tolerances are relative to it."""
    block_water: Optional[np.ndarray] = None
    """(B, 2) water force on each block's whole boundary [N/m] (included in ``block_force``),
    None without a water table (docs/method/water_bolts.md)."""
    block_seismic: Optional[np.ndarray] = None
    """(B, 2) pseudo-static seismic force (kh, kv)·W of each block [N/m] (included in
    ``block_force``), None without a seismic coefficient."""
    block_bolt: Optional[np.ndarray] = None
    """(B, 2) active bolt force (pretension) on each block [N/m] (included in
    ``block_force``), None without bolts."""
    block_passive: Optional[np.ndarray] = None
    """(B, 2) passive bolt force (capacity beyond the pretension) on each block [N/m]; a
    resistance, not in ``block_force``; None without bolts."""
    block_passive_moment: Optional[np.ndarray] = None
    """(B,) moment of the passive bolt forces about the origin (0, 0), counter-clockwise
    positive [N·m/m]; None without bolts."""
    contact_water: Optional[np.ndarray] = None
    """(C,) water force ∫p ds on each contact segment [N/m], None without a water table."""
    seismic: tuple = (0.0, 0.0)
    """Seismic coefficients (kh, kv) [-] the system was built with."""
    contact_barton: Optional[np.ndarray] = None
    """(C, 5) Barton–Bandis law of each contact's joint: JRC [-], JCS [Pa], φr [degrees], cap
    of the mobilised angle [degrees], strength reduction F [-]; JRC is NaN on a Mohr–Coulomb
    contact (whose ``contact_friction`` holds). None when no contact has one
    (docs/method/barton_bandis.md)."""

    # ------------------------------------------------------------------ basic queries
    @property
    def n_blocks(self) -> int:
        return len(self.block_fixed)

    @property
    def n_contacts(self) -> int:
        return len(self.contact_length)

    def polygon(self, block: int) -> np.ndarray:
        """(n, 2) CCW vertices of a block [m]."""
        return self.vertex_xy[self.vertex_offset[block]:self.vertex_offset[block + 1]]

    def contacts_of(self, block: int) -> np.ndarray:
        """Indices of the contacts of a block."""
        cb = self.contact_blocks
        return np.flatnonzero((cb[:, 0] == block) | (cb[:, 1] == block))

    def neighbours(self, blocks: Iterable[int], removed: frozenset = frozenset()) -> set[int]:
        """Blocks (fixed ones included) sharing a contact with any of ``blocks``, except the
        blocks themselves and removed blocks."""
        members = set(blocks)
        cb = self.contact_blocks
        # membership by a mask of the blocks (np.isin costs ~20 µs a call on a few contacts);
        # ids outside the system match no contact, as there
        mask = np.zeros(self.n_blocks, bool)
        mask[[b for b in members if 0 <= b < self.n_blocks]] = True
        ina, inb = mask[cb[:, 0]], mask[cb[:, 1]]
        out = set(cb[ina & ~inb, 1].tolist()) | set(cb[inb & ~ina, 0].tolist())
        return out - set(removed)

    def with_strength(self, *, friction: Optional[float] = None, reduction: float = 1.0) -> "BlockSystem":
        """The same system with every joint's friction angle set to ``friction`` [degrees]
        (cohesion held), and/or tanφ and c divided by ``reduction`` (strength reduction,
        docs/kgm/method.md §4.6; the rule is `kgm.strength.Strength`'s)."""
        strength = Strength(friction=friction, reduction=reduction)
        return replace(self, **strength.contact_arrays(self.contact_friction, self.contact_cohesion,
                                                       self.contact_barton))

    def tan_friction(self, contacts: np.ndarray, sigma_n) -> np.ndarray:
        """Friction coefficient of each of ``contacts`` at the normal stress ``sigma_n`` [Pa]
        (a number or one per contact): tan φ of a Mohr–Coulomb joint; tan φ(σn)/F of a
        Barton–Bandis one, φ(σn) = φr + JRC·log10(JCS/σn) bounded to [φr, cap] (σn ≤ 0 takes
        the cap; docs/method/barton_bandis.md, eq. BB1)."""
        contacts = np.asarray(contacts, dtype=np.int64)
        out = np.tan(np.radians(self.contact_friction[contacts]))
        if self.contact_barton is None:
            return out
        law = self.contact_barton[contacts]
        bb = ~np.isnan(law[:, 0])
        if bb.any():
            jrc, jcs, phir, cap, red = law[bb].T
            sigma = np.broadcast_to(np.asarray(sigma_n, dtype=float), contacts.shape)[bb]
            with np.errstate(divide="ignore", invalid="ignore"):
                phi = phir + jrc * np.log10(jcs / sigma)
            phi = np.where(sigma > 0, np.clip(phi, phir, cap), np.where(jrc > 0, cap, phir))  # σn → 0: the limit
            out[bb] = np.tan(np.radians(phi)) / red
        return out

    def face_tan(self, contacts: np.ndarray, normal_force: float) -> float:
        """Length-weighted friction coefficient of pooled contacts carrying ``normal_force``
        [N/m] at a uniform normal stress σn = N/ΣL (eq. BB4)."""
        length = self.contact_length[contacts]
        total = float(length.sum())
        sigma = max(float(normal_force), 0.0) / total if total > 0 else 0.0
        return float((self.tan_friction(contacts, sigma) * length).sum() / max(total, 1e-300))

    def face_tan_function(self, contacts: np.ndarray):
        """`face_tan` of these contacts as a function of the normal force [N/m], for the
        fixed-point iterations that call it many times (plain floats, the law of eq. BB1)."""
        contacts = np.asarray(contacts, dtype=np.int64)
        length = self.contact_length[contacts]
        total = float(length.sum())
        weight = (length / max(total, 1e-300)).tolist()
        tan_mc = np.tan(np.radians(self.contact_friction[contacts])).tolist()
        rows = (self.contact_barton[contacts].tolist() if self.contact_barton is not None
                else [[math.nan] * 5] * len(weight))
        # the Mohr–Coulomb contacts' share is constant; the Barton–Bandis ones follow σn
        fixed = sum(w * t for w, t, row in zip(weight, tan_mc, rows) if math.isnan(row[0]))
        law = [(w, *row) for w, row in zip(weight, rows) if not math.isnan(row[0])]

        def tan_at(normal_force: float) -> float:
            sigma = max(float(normal_force), 0.0) / total if total > 0 else 0.0
            out = fixed
            for w, jrc, jcs, phir, cap, red in law:
                if sigma > 0:
                    phi = min(max(phir + jrc * math.log10(jcs / sigma), phir), cap)
                else:
                    phi = cap if jrc > 0 else phir
                out += w * math.tan(math.radians(phi)) / red
            return out
        return tan_at

    def free_length(self, block: int, removed: frozenset = frozenset()) -> float:
        """Length of the block's boundary that touches no (remaining) block [m]."""
        return float(sum(np.linalg.norm(e - s) for s, e in self.free_segments(block, removed)))

    def free_segments(self, block: int, removed: frozenset = frozenset()) -> list[tuple[np.ndarray, np.ndarray]]:
        """Edge parts of a block exposed to air: not covered by a contact with a block that is
        still there. Contacts with removed blocks become free faces (docs/kgm/method.md §3.3)."""
        lo, hi = self.vertex_offset[block], self.vertex_offset[block + 1]
        xy = self.vertex_xy[lo:hi]
        covered: dict[int, list[tuple[float, float]]] = {}
        for k in self.contacts_of(block):
            a, b = self.contact_blocks[k]
            other = b if a == block else a
            if other in removed:
                continue
            side = 0 if a == block else 1
            e = int(self.contact_edge[k, side])
            covered.setdefault(e, []).append(tuple(self.contact_span[k, side]))
        tol = MIN_CONTACT * self.scale
        out = []
        for i in range(hi - lo):
            p, q = xy[i], xy[(i + 1) % (hi - lo)]
            length = float(np.linalg.norm(q - p))
            t = (q - p) / length
            pos = 0.0
            for s0, s1 in sorted(covered.get(lo + i, [])):
                if s0 - pos > tol:
                    out.append((p + pos * t, p + s0 * t))
                pos = max(pos, s1)
            if length - pos > tol:
                out.append((p + pos * t, q.copy()))
        return out


def cross(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """z component of u × v (2D vectors, broadcast) [-]."""
    return u[..., 0] * v[..., 1] - u[..., 1] * v[..., 0]
