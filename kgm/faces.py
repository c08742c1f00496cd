"""The faces of a block or group (docs/kgm/method.md §2.2–2.3): its boundary and internal
contacts, its removability (the half-circle test on the normals of its joint pyramid), its free
faces and connectivity, a group's validation, contacts grouped by direction, and the one rule
for contacts pooled into a face (`pool`: ΣL, Σc·L, length-weighted tanφ, and the Barton–Bandis
law at the face's normal force), which every judge's faces use.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable, Iterable, Optional

import numpy as np

from .system import ANGLE_TOL, BlockSystem


@dataclass(frozen=True, kw_only=True, eq=False)
class GroupFaces:
    """Contacts of a group (a block or a set of blocks) split into boundary and internal ones."""

    boundary: np.ndarray
    """Indices of the contacts between a member and a remaining non-member."""
    boundary_normal: np.ndarray
    """(m, 2) unit normals of those contacts pointing into the group [-]."""
    boundary_member: np.ndarray
    """(m,) the member block of each boundary contact."""
    boundary_other: np.ndarray
    """(m,) the non-member block of each boundary contact."""
    internal: np.ndarray
    """Indices of the contacts between two members."""


def check_group(system: BlockSystem, blocks, *, removed: frozenset = frozenset(),
                what: str = "group") -> frozenset:
    """Validate a group of block ids: non-empty, known, free (not fixed), not removed.
    Returns it as a frozenset; raises ValueError naming the offending block."""
    try:
        ids = list(blocks)
    except TypeError:
        raise ValueError(f"{what} must be an iterable of block ids, got {blocks!r}") from None
    if not ids:
        raise ValueError(f"{what} is empty: give at least one block id")
    out = set()
    for b in ids:
        if isinstance(b, (bool, np.bool_)) or not isinstance(b, (int, np.integer)):
            raise ValueError(f"{what}: block id must be an integer, got {b!r}")
        if not 0 <= int(b) < system.n_blocks:
            raise ValueError(f"{what}: unknown block id {b} (the scene has {system.n_blocks} blocks)")
        if system.block_fixed[int(b)]:
            raise ValueError(f"{what}: block {b} is fixed; a key group holds only free blocks")
        if int(b) in removed:
            raise ValueError(f"{what}: block {b} has been removed")
        out.add(int(b))
    return frozenset(out)


def check_connected_group(system: BlockSystem, blocks) -> frozenset:
    """`check_group`, and the group one connected set (`is_connected`): the group a user names
    for one evaluation; raises ValueError saying which check failed."""
    group = check_group(system, blocks)
    if not is_connected(system, group):
        raise ValueError(f"group {sorted(group)} is not connected: its blocks must share contacts")
    return group


def is_connected(system: BlockSystem, blocks: frozenset) -> bool:
    """Whether the blocks form one connected set through shared contacts (§3.2, condition 5)."""
    blocks = set(blocks)
    start = next(iter(blocks))
    seen, todo = {start}, [start]
    while todo:
        b = todo.pop()
        for nb in system.neighbours([b]):
            if nb in blocks and nb not in seen:
                seen.add(nb)
                todo.append(nb)
    return seen == blocks


def group_faces(system: BlockSystem, blocks: frozenset, removed: frozenset = frozenset()) -> GroupFaces:
    """Boundary and internal contacts of a group; contacts with removed blocks are free."""
    cb = system.contact_blocks
    members = np.array(sorted(blocks), dtype=np.int64)
    gone = np.array(sorted(removed), dtype=np.int64)
    ina, inb = np.isin(cb[:, 0], members), np.isin(cb[:, 1], members)
    alive = ~(np.isin(cb[:, 0], gone) | np.isin(cb[:, 1], gone))
    bnd = np.flatnonzero(alive & (ina ^ inb))
    internal = np.flatnonzero(alive & ina & inb)
    sign = np.where(ina[bnd], 1.0, -1.0)
    return GroupFaces(boundary=bnd, boundary_normal=system.contact_normal[bnd] * sign[:, None],
                      boundary_member=np.where(ina[bnd], cb[bnd, 0], cb[bnd, 1]),
                      boundary_other=np.where(ina[bnd], cb[bnd, 1], cb[bnd, 0]),
                      internal=internal)


# ---------------------------------------------------------------------- removability
def removable_arc(normals: np.ndarray, tol: float = ANGLE_TOL) -> Optional[tuple[tuple[float, float], ...]]:
    """Joint pyramid of a block or group in 2D (docs/kgm/method.md §2.2, computational form).

    ``normals`` (m, 2) are the contact normals pointing into the block. The admissible
    translations are JP = {s : s·n_k ≥ 0 for all k}; each condition is a half-circle of
    directions, so JP is not empty if and only if all normals lie in a closed half-circle,
    i.e. the largest circular gap between their angles is ≥ π.

    Returns None when the block is not removable, else the arcs of admissible directions as
    (start, width) [rad] (directions start ... start + width counter-clockwise): one arc of
    width π − (spread of the normals), or 2π with no contacts; two arcs of width 0 (both
    directions of a line) when the normals point two exactly opposite ways (a slot).
    """
    normals = np.asarray(normals, dtype=float).reshape(-1, 2)
    if len(normals) == 0:
        return ((-math.pi, 2.0 * math.pi),)
    th = np.sort(np.arctan2(normals[:, 1], normals[:, 0]))
    gaps = np.diff(np.append(th, th[0] + 2.0 * math.pi))
    order = np.argsort(gaps)[::-1]
    k = int(order[0])
    if gaps[k] < math.pi - tol:
        return None
    # the normals span the arc from th[k+1] (min) counter-clockwise to th[k] (max)
    th_min, th_max = th[(k + 1) % len(th)], th[k]
    spread = (th_max - th_min) % (2.0 * math.pi)
    if spread > math.pi:  # all normals equal up to round-off (th_max a hair below th_min)
        spread = 0.0
    if len(th) > 1 and gaps[order[1]] >= math.pi - tol:
        # two gaps of π: normals in exactly two opposite directions, JP is a line
        return ((_wrap(th_max - 0.5 * math.pi), 0.0), (_wrap(th_max + 0.5 * math.pi), 0.0))
    return ((_wrap(th_max - 0.5 * math.pi), max(math.pi - spread, 0.0)),)


def _wrap(a: float) -> float:
    return (a + math.pi) % (2.0 * math.pi) - math.pi


def is_removable(system: BlockSystem, blocks: frozenset, removed: frozenset = frozenset()) -> bool:
    """A finite block or group is removable if its joint pyramid is not empty (§2.2): the
    half-circle test on the normals of its contacts with the remaining blocks."""
    faces = group_faces(system, blocks, removed)
    return removable_arc(faces.boundary_normal) is not None


def has_free_face(system: BlockSystem, blocks: Iterable[int], removed: frozenset = frozenset()) -> bool:
    """Whether any member has a free segment (an edge part exposed to air)."""
    return any(system.free_segments(b, removed) for b in blocks)


def parallel_sets(normals: np.ndarray) -> list[np.ndarray]:
    """Indices of the normals grouped by direction (within ANGLE_TOL)."""
    th = np.arctan2(normals[:, 1], normals[:, 0])
    out: list[list[int]] = []
    dirs: list[float] = []
    for i, a in enumerate(th):
        for g, d in enumerate(dirs):
            if abs(_wrap(a - d)) <= ANGLE_TOL:
                out[g].append(i)
                break
        else:
            dirs.append(a)
            out.append([i])
    return [np.array(g) for g in out]


# ---------------------------------------------------------------------- pooled faces
@dataclass(frozen=True, kw_only=True, eq=False)
class Face:
    """Contacts pooled into one face (parallel contacts that slide or press together): the
    normal force spreads over their segments in proportion to their lengths (a uniform normal
    stress σn = N/ΣL), so the face's cohesion is Σc·L and its friction the length-weighted mean
    of tanφ (docs/kgm/method.md §4.2; eq. BB4 of docs/method/barton_bandis.md)."""

    contacts: np.ndarray
    """Indices of the pooled contacts (int64)."""
    length: float
    """ΣL [m]."""
    cl: float
    """Σ c·L [N/m]."""
    tan_phi: float
    """Length-weighted tanφ of the contacts' friction angles [-] (Mohr–Coulomb)."""
    tan_at: Optional[Callable[[float], float]] = None
    """Where a contact is Barton–Bandis: normal force [N/m] -> the face's tanφ at σn = N/ΣL
    (`BlockSystem.face_tan_function`); None on a Mohr–Coulomb face."""


def pool(system: BlockSystem, contacts) -> Face:
    """The contacts ``contacts`` pooled into one `Face`."""
    ks = np.asarray(contacts, dtype=np.int64)
    length = system.contact_length[ks]
    total = float(length.sum())
    tan_at = None
    if system.contact_barton is not None and not np.all(np.isnan(system.contact_barton[ks, 0])):
        tan_at = system.face_tan_function(ks)
    return Face(contacts=ks, length=total, cl=float((system.contact_cohesion[ks] * length).sum()),
                tan_phi=float((np.tan(np.radians(system.contact_friction[ks])) * length).sum() / max(total, 1e-300)),
                tan_at=tan_at)
