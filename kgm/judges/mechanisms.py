"""The kinematics of Sarma mechanisms (docs/kgm/method.md §5.2, generalised to any group): a
group's contacts merged into faces, and the single-degree-of-freedom velocity fields of its
members (`kgm.judges.sarma` finds their statics).

With member velocities v ∈ R^{2n}, every contact face k between member a and block b (a member,
or stable rock with v_b = 0) must not penetrate: (v_a − v_b)·n_k ≥ 0 (n_k into a). The
single-degree-of-freedom mechanisms Sarma assumes — every block slides on its own base, every
shared joint slides (or opens) — are the extreme rays of this cone, where 2n − 1 independent
face conditions hold with equality; they are found by the double-description method (or, when
the cone contains a line, that line: every face stays closed). Members that move together
because the geometry makes them (one plane under both) share a face with no slip. Each
mechanism is checked: every member moves, no face penetrates, the active forces drive it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable, Optional

import numpy as np

from ..faces import group_faces, parallel_sets, pool
from ..system import BlockSystem

#: Velocity tolerance of the mechanism checks, relative to the fastest member [-].
VELOCITY_TOL = 1e-7


@dataclass(frozen=True, kw_only=True, eq=False)
class Faces:
    """Contacts of a group merged into faces: one per (member, neighbour side, direction)."""

    a: np.ndarray          # (f,) member position (0..n-1) on the normal's side
    b: np.ndarray          # (f,) member position of the other side, -1 for a non-member
    normal: np.ndarray     # (f, 2) unit normal into a
    tangent: np.ndarray    # (f, 2) unit tangent (normal rotated clockwise)
    cl: np.ndarray         # (f,) Σ c·L [N/m]
    length: np.ndarray     # (f,) Σ L [m]
    tan_phi: np.ndarray    # (f,) length-weighted tanφ (uniform normal stress on the face)
    contacts: tuple        # (f,) arrays of contact indices
    tan_at: Optional[Callable[[np.ndarray], np.ndarray]] = None
    # Barton–Bandis faces: (f,) normal forces [N/m] -> each face's tanφ at σn = N/L (eq. BB4);
    # None when every face is Mohr–Coulomb
    members: tuple = ()    # block id of each member position (for messages)
    ends: Optional[np.ndarray] = None
    # (f, 2, 2) the face's two extreme points along its tangent [m] (where its resultant may act)


def merge_faces(system: BlockSystem, members: list[int], removed: frozenset) -> Faces:
    pos = {b: i for i, b in enumerate(members)}
    gf = group_faces(system, frozenset(members), removed)
    entries = []  # (a, b, contacts, normal)
    # boundary contacts: pooled per member and direction (parallel contacts of one member give
    # the same kinematic condition whichever non-member they touch)
    for mem in sorted(set(gf.boundary_member.tolist())):
        sel = np.flatnonzero(gf.boundary_member == mem)
        for grp in parallel_sets(gf.boundary_normal[sel]):
            k = sel[grp]
            entries.append((pos[mem], -1, gf.boundary[k], gf.boundary_normal[k[0]]))
    # internal contacts: per member pair and direction, normal into the lower-position member
    cb = system.contact_blocks
    pairs: dict[tuple[int, int], list[int]] = {}
    for k in gf.internal.tolist():
        i, j = pos[int(cb[k, 0])], pos[int(cb[k, 1])]
        pairs.setdefault((min(i, j), max(i, j)), []).append(k)
    for (i, j), ks in sorted(pairs.items()):
        ks = np.array(ks)
        nrm = system.contact_normal[ks] * np.where(_pos_of(cb[ks, 0], pos) == i, 1.0, -1.0)[:, None]
        for grp in parallel_sets(nrm):
            entries.append((i, j, ks[grp], nrm[grp[0]]))
    f = len(entries)
    normal = np.array([e[3] for e in entries]).reshape(f, 2)
    pooled = [pool(system, e[2]) for e in entries]
    length = np.array([p.length for p in pooled])
    cl = np.array([p.cl for p in pooled])
    tan_phi = np.array([p.tan_phi for p in pooled])
    tan_at = None
    if system.contact_barton is not None:
        # every face follows its law at its own stress (a Mohr–Coulomb one: a constant)
        face_fns = tuple(p.tan_at or system.face_tan_function(p.contacts) for p in pooled)
        tan_at = lambda normal: np.array([f(nk) for f, nk in zip(face_fns, normal)])  # noqa: E731
    return Faces(a=np.array([e[0] for e in entries], dtype=np.int64),
                  b=np.array([e[1] for e in entries], dtype=np.int64),
                  normal=normal, tangent=np.stack([normal[:, 1], -normal[:, 0]], axis=1) if f else normal,
                  cl=cl, length=length, tan_phi=tan_phi, contacts=tuple(e[2] for e in entries),
                  tan_at=tan_at, members=tuple(members), ends=_ends(system, entries, normal))


def _ends(system: BlockSystem, entries: list, normal: np.ndarray) -> np.ndarray:
    """(f, 2, 2) the first and last point of each face's contact segments along its tangent."""
    out = np.zeros((len(entries), 2, 2))
    for i, e in enumerate(entries):
        pts = np.concatenate([system.contact_start[e[2]], system.contact_end[e[2]]])
        along = pts @ np.array([normal[i, 1], -normal[i, 0]])
        out[i] = pts[np.argmin(along)], pts[np.argmax(along)]
    return out


def _pos_of(blocks: np.ndarray, pos: dict) -> np.ndarray:
    return np.array([pos[int(b)] for b in blocks])


def _rows(faces: Faces, n: int, which: str) -> np.ndarray:
    """Kinematic rows: relative velocity of a w.r.t. b along each face's normal or tangent."""
    vec = faces.normal if which == "normal" else faces.tangent
    rows = np.zeros((len(faces.a), 2 * n))
    for k, (a, b) in enumerate(zip(faces.a, faces.b)):
        rows[k, 2 * a:2 * a + 2] = vec[k]
        if b >= 0:
            rows[k, 2 * b:2 * b + 2] = -vec[k]
    return rows


@dataclass(frozen=True, kw_only=True, eq=False)
class Mechanism:
    velocity: np.ndarray   # (2n,) member velocities, max |v_i| = 1
    closed: np.ndarray     # (f,) bool: face stays in contact
    slip_sign: np.ndarray  # (f,) sign of the slip of a relative to b on closed faces (0: none)


def mechanisms(faces: Faces, force: np.ndarray, n: int) -> list[Mechanism]:
    """Single-degree-of-freedom velocity fields of the group (see the module docstring): the
    extreme rays of the cone of non-penetrating member velocities {v : A v ≥ 0}, or its
    lineality if that is a single direction (every face stays closed, as in Sarma's
    mechanism of docs/kgm/method.md §8.3)."""
    d = 2 * n
    nrows = _rows(faces, n, "normal")
    if len(nrows) == 0:
        return []
    _, sv, vh = np.linalg.svd(nrows)
    rank = int(np.sum(sv > 1e-9 * sv[0]))
    if rank == d - 1:
        rays = np.array([vh[-1], -vh[-1]])
    elif rank == d:
        rays = extreme_rays(nrows)
    else:
        return []  # two or more free directions: no single mechanism
    out = []
    f = force.reshape(-1)
    tangents = _rows(faces, n, "tangent")
    for v in rays:
        speed = np.hypot(v[0::2], v[1::2])
        if np.any(speed < 1e-6 * speed.max()):
            continue  # a member that does not move belongs to no mechanism of this group
        v = v / speed.max()
        gap = nrows @ v
        if np.any(gap < -VELOCITY_TOL):
            continue  # penetrates a face
        if f @ v <= 1e-9 * np.abs(f).max():
            continue  # the active forces do not drive it
        closed = np.abs(gap) <= VELOCITY_TOL
        slip = tangents @ v
        sign = np.where(closed & (np.abs(slip) > VELOCITY_TOL), np.sign(slip), 0.0)
        out.append(Mechanism(velocity=v, closed=closed, slip_sign=sign))
    return out


def extreme_rays(a: np.ndarray, tol: float = 1e-9) -> np.ndarray:
    """Extreme rays of the pointed cone {x : a·x ≥ 0} (``a`` of full column rank), by the
    double-description method (Motzkin; Fukuda & Prodon 1996): start from the simplicial cone
    of d independent rows and add the other rows one at a time, keeping the rays on the
    feasible side and combining each adjacent pair the new row separates."""
    m, d = a.shape
    a = a / np.linalg.norm(a, axis=1, keepdims=True)
    basis: list[int] = []
    for i in range(m):
        if np.linalg.matrix_rank(a[basis + [i]], tol=1e-9) == len(basis) + 1:
            basis.append(i)
        if len(basis) == d:
            break
    rays = np.linalg.inv(a[basis]).T  # ray j: a[basis]·r = e_j
    rays /= np.linalg.norm(rays, axis=1, keepdims=True)
    done = list(basis)
    for i in (i for i in range(m) if i not in basis):
        val = rays @ a[i]
        pos, neg = np.flatnonzero(val > tol), np.flatnonzero(val < -tol)
        keep = val >= -tol
        new = []
        if len(pos) and len(neg):
            active = np.abs(rays @ a[done].T) <= tol
            for p in pos:
                for q in neg:
                    common = active[p] & active[q]
                    # adjacent rays share d − 2 independent active constraints
                    if common.sum() < d - 2 or np.linalg.matrix_rank(a[done][common], tol=1e-9) != d - 2:
                        continue
                    r = val[p] * rays[q] - val[q] * rays[p]
                    new.append(r / np.linalg.norm(r))
        rays = np.concatenate([rays[keep]] + ([np.array(new)] if new else []))
        done.append(i)
    return _unique_rays(rays)


def _unique_rays(rays: np.ndarray) -> np.ndarray:
    out: list[np.ndarray] = []
    for r in rays:
        if not any(np.abs(r - o).max() < 1e-7 for o in out):
            out.append(r)
    return np.array(out).reshape(-1, rays.shape[1])


def face_name(faces: Faces, k: int) -> str:
    """'the face of block a on the stable rock' / 'the joint between blocks a and b'."""
    def name(i: int) -> str:
        return f"block {faces.members[i]}" if faces.members else f"member {i}"
    if faces.b[k] < 0:
        return f"the face of {name(faces.a[k])} on the stable rock"
    return f"the joint between {name(faces.a[k])} and {name(faces.b[k])}"


def mechanism_label(mech: Mechanism, faces: Faces) -> str:
    """'{0 → 0°, 1 ↓ 310°}'-like: each member and the direction it moves [degrees from +x]."""
    parts = []
    for i, b in enumerate(faces.members):
        v = mech.velocity[2 * i:2 * i + 2]
        parts.append(f"block {b} at {math.degrees(math.atan2(v[1], v[0])) % 360:.0f}°")
    return "(" + ", ".join(parts) + ")"
