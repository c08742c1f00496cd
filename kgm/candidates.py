"""The candidates of the search (docs/kgm/method.md §3.2–3.3), pure geometry below the judges:
the key blocks that seed it, the free neighbours a group can grow by, every connected group of
a few blocks (the exhaustive enumeration), and the toppling rows with the blocks that lean on
them from upslope.

A group is a **toppling row** (docs/kgm/footwall.md §6) when its members form a row of columns
on one stepped base: every member rests on its own base (a face of contacts with the stable
rock on which its active force presses; neighbours' bases within `ROW_BASE_ANGLE`), each pushes
on the next one downslope through an interface (a face shared by the two, across both bases,
facing downslope for both) that rises from its pivot, and the lowest member (the toe) has
nothing, rock or member, in front of it. A face slab lying on its bedding and pushing a toe
block that rests on another joint is a two-block sliding mechanism, not a row. The rows'
Goodman–Bray recursion is the toppling judge's (`kgm.judges.toppling`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable, Iterator, Optional

import numpy as np

from .faces import group_faces, has_free_face, is_removable, parallel_sets, pool
from .system import BlockSystem

#: Least cosine between the active force and a base face's inward normal for the face to carry
#: the block (a base must be pressed, not a wall beside the block) [-].
BASE_MIN_COS = 0.1
#: Least abs(cos) between an interface normal and the base direction for the interface to be
#: "across the base" (60° from the base normal) [-].
INTERFACE_MIN_COS = 0.5
#: Largest angle between the bases of two neighbouring columns of a row [degrees]: the
#: columns stand on one (stepped) base; a toe block on a joint far steeper or flatter than the
#: slab above it is a two-block sliding mechanism, not a toppling row.
ROW_BASE_ANGLE = 30.0
#: Largest distance from a column's pivot to the foot of its interface with the block below,
#: as a fraction of the column's base length [-] (cut blocks: ~1e-12).
ROW_PIVOT_TOL = 0.02



@dataclass(frozen=True, kw_only=True, eq=False)
class RowFace:
    """A face of one member: pooled contacts, their strength, and where its force acts."""

    contacts: np.ndarray   # contact indices
    normal: np.ndarray     # (2,) unit normal into the member
    point: np.ndarray      # (2,) where the face's force acts [m]
    length: float          # Σ L [m]
    cl: float              # Σ c·L [N/m]
    tan_phi: float         # length-weighted tanφ [-]
    tan_at: Optional[Callable[[float], float]] = None
    # Barton–Bandis faces: normal force [N/m] -> tanφ at σn = N/ΣL (docs/method/barton_bandis.md,
    # eq. BB4); None on Mohr–Coulomb faces


@dataclass(frozen=True, kw_only=True, eq=False)
class RowBlock:
    """One member of a toppling row, with the geometry the recursion uses."""

    block: int
    force: np.ndarray       # (2,) active force [N/m]
    moment: float           # its moment about the origin, counter-clockwise [N·m/m]
    base: RowFace             # base face (normal into the block)
    downslope: np.ndarray   # (2,) unit base tangent pointing downslope
    pivot: np.ndarray       # (2,) downslope end of the base [m]
    below: RowFace            # face toward the next block down (for the toe: its free face)
    height: float           # largest distance of the polygon from its base line [m]
    base_length: float      # Σ L of the base [m]


@dataclass(frozen=True, kw_only=True, eq=False)
class TopplingRow:
    """Members of a group that admits block toppling, ordered from the top block to the toe."""

    blocks: tuple  # (RowBlock, ...), top first


# ---------------------------------------------------------------------- key blocks and groups
def key_blocks(system: BlockSystem, removed: frozenset = frozenset()) -> list[int]:
    """Seeds of the search: free blocks with a free face that are removable on their own
    (types I, II and III, §3.2 condition 1)."""
    return [b for b in range(system.n_blocks)
            if b not in removed and not system.block_fixed[b]
            and has_free_face(system, [b], removed) and is_removable(system, frozenset([b]), removed)]


def mobile_neighbours(system: BlockSystem, blocks: frozenset, removed: frozenset) -> list[int]:
    """The free (not fixed), remaining blocks touching a group, ascending."""
    return sorted(b for b in system.neighbours(blocks, removed) if not system.block_fixed[b])


def connected_groups(system: BlockSystem, max_size: int, removed: frozenset = frozenset()) -> Iterator[frozenset]:
    """Every connected set of free, remaining blocks with at most ``max_size`` members, each
    once (the ESU enumeration of connected induced subgraphs)."""
    nodes = [b for b in range(system.n_blocks) if b not in removed and not system.block_fixed[b]]
    adj = {b: set(mobile_neighbours(system, frozenset([b]), removed)) for b in nodes}

    def extend(sub: frozenset, ext: list, v: int, closed_nb: set):
        yield sub
        if len(sub) == max_size:
            return
        ext = list(ext)
        while ext:
            w = ext.pop()
            new = [u for u in adj[w] if u > v and u not in closed_nb and u not in ext]
            yield from extend(sub | {w}, ext + sorted(new), v, closed_nb | adj[w] | {w})

    for v in nodes:
        yield from extend(frozenset([v]), sorted(u for u in adj[v] if u > v), v, adj[v] | {v})


# ---------------------------------------------------------------------- toppling rows
def _face(system: BlockSystem, contacts: np.ndarray, normal: np.ndarray, point: np.ndarray) -> RowFace:
    face = pool(system, contacts)
    return RowFace(contacts=face.contacts, normal=normal, point=point, length=face.length, cl=face.cl,
                 tan_phi=face.tan_phi, tan_at=face.tan_at)


def toppling_row(system: BlockSystem, blocks: frozenset, removed: frozenset = frozenset()
                 ) -> Optional[TopplingRow]:
    """The group as a toppling row (top block first), or None if its geometry is not one
    (`row_geometry` says why)."""
    return row_geometry(system, blocks, removed)[0]


def row_geometry(system: BlockSystem, blocks: frozenset, removed: frozenset = frozenset()
                 ) -> tuple[Optional[TopplingRow], str]:
    """The group as a toppling row (top block first), or (None, why it is not one).

    Goodman & Bray's row is a chain of columns standing side by side on a (stepped) base, all
    leaning the same way: each member rests on its own base (a face of contacts with the rock
    that its active force presses); the bases dip the same way (within `ROW_BASE_ANGLE`); each
    member pushes on the next one downslope through an interface across both bases, facing
    downslope for both; each member's pivot (the downslope end of its base) lies at the foot
    of its interface with the block below, so that the column rises from it with its own
    height (the interface's top, L_n) and width (its base); and the toe has nothing in front
    of it, rock or member. A face slab on its bedding plane pushing a toe block that rests on
    another joint is not such a row: the toe block's base and the slab's run at a large angle,
    or the toe's "downslope" points into the slope and the slab would be the toe."""
    members = sorted(blocks)
    if not members:
        return None, "empty group"
    gf = group_faces(system, frozenset(members), removed)
    cb = system.contact_blocks
    bases: dict[int, tuple] = {}
    for m in members:
        sel = np.flatnonzero(gf.boundary_member == m)
        f = system.block_force[m]
        fnorm = float(np.hypot(*f))
        if fnorm == 0.0 or len(sel) == 0:
            return None, f"block {m} has no base on the rock"
        best = None
        for grp in parallel_sets(gf.boundary_normal[sel]):
            k = sel[grp]
            nrm = gf.boundary_normal[k[0]]
            press = -float(f @ nrm) / fnorm
            if press >= BASE_MIN_COS and (best is None or press > best[0] + 1e-12):
                best = (press, gf.boundary[k], nrm)
        if best is None:
            return None, f"block {m} has no base on the rock that its weight presses"
        tangent = f - (f @ best[2]) * best[2]
        if float(np.hypot(*tangent)) <= 1e-9 * fnorm:
            return None, f"block {m} stands on a level base (no downslope direction)"
        t = tangent / np.hypot(*tangent)
        ends = np.concatenate([system.contact_start[best[1]], system.contact_end[best[1]]])
        bases[m] = (best[1], best[2], t, ends[int(np.argmax(ends @ t))])
    # interfaces between members, pooled per pair; the normal into the first of the pair
    pairs: dict[tuple[int, int], list[int]] = {}
    for k in gf.internal.tolist():
        pairs.setdefault((int(cb[k, 0]), int(cb[k, 1])), []).append(k)
    down: dict[int, int] = {}
    up: dict[int, int] = {}
    min_cos = math.cos(math.radians(ROW_BASE_ANGLE))
    for (a, b), ks in pairs.items():
        ks = np.array(ks)
        n_a = system.contact_normal[ks[0]]  # into a
        ta, tb = bases[a][2], bases[b][2]
        if float(ta @ tb) < min_cos:
            return None, (f"the bases of blocks {a} and {b} dip {_angle(ta, tb):.0f}° apart (a row's columns "
                          f"stand on one stepped base, within {ROW_BASE_ANGLE:g}°)")
        lower, upper = (b, a) if float(n_a @ ta) < 0 else (a, b)  # n into a points upslope: b lies below a
        n_low = n_a if lower == a else -n_a                       # into the lower block
        if min(float(n_low @ bases[lower][2]), float(n_low @ bases[upper][2])) < INTERFACE_MIN_COS:
            return None, (f"the joint between blocks {a} and {b} is not an interface across their bases "
                          f"facing downslope for both (blocks stacked, or side by side the wrong way)")
        if float((bases[lower][3] - bases[upper][3]) @ bases[upper][2]) <= 0.0:
            return None, f"block {lower} does not stand downslope of block {upper}"
        if upper in down or lower in up:
            return None, f"the members do not form a single chain (block {upper if upper in down else lower} forks)"
        down[upper], up[lower] = lower, upper
    tops = [m for m in members if m not in up]
    if len(tops) != 1:
        return None, "the members do not form a single chain of interfaces"
    order = [tops[0]]
    while order[-1] in down:
        order.append(down[order[-1]])
    if len(order) != len(members):
        return None, "the members do not form a single chain of interfaces"
    toe = order[-1]
    # the toe must be free to move downslope: no remaining rock in front of it, and no member
    # (a member in front of the "toe" means the chain was read against the slope)
    t_toe = bases[toe][2]
    sel = np.flatnonzero(gf.boundary_member == toe)
    if np.any(gf.boundary_normal[sel] @ t_toe < -INTERFACE_MIN_COS):
        return None, f"the toe block {toe} is held by rock in front of it"
    for k in gf.internal.tolist():
        if toe in cb[k]:
            n_in = system.contact_normal[k] * (1.0 if cb[k, 0] == toe else -1.0)
            if float(n_in @ t_toe) < -1e-6:
                other = int(cb[k, 1] if cb[k, 0] == toe else cb[k, 0])
                return None, f"the toe block {toe} has block {other} in front of it"
    rows = []
    for i, m in enumerate(order):
        base_k, n_b, t, pivot = bases[m]
        poly = system.polygon(m)
        height = float(((poly - pivot) @ n_b).max())
        base_length = float(system.contact_length[base_k].sum())
        if i + 1 < len(order):
            lo = order[i + 1]
            ks = np.array(pairs.get((m, lo), pairs.get((lo, m))))
            sign = 1.0 if cb[ks[0], 0] == m else -1.0
            n_l = system.contact_normal[ks[0]] * sign
            pts = np.concatenate([system.contact_start[ks], system.contact_end[ks]])
            # the column rises from its pivot: the pivot is the foot of its interface below
            gap = min(_point_segment(pivot, system.contact_start[k], system.contact_end[k]) for k in ks)
            if gap > ROW_PIVOT_TOL * base_length:
                return None, (f"block {m} is not a column on its base: its interface with block {lo} starts "
                              f"{gap:.3g} m from the downslope end of its base (its pivot)")
            point = pts[int(np.argmax((pts - pivot) @ n_b))]
            below = _face(system, ks, n_l, point)
        else:
            # the toe: P_0 pushes up the base at the top of its free downslope face
            front = poly[(poly - pivot) @ t >= -1e-9 * system.scale]
            point = front[int(np.argmax((front - pivot) @ n_b))] if len(front) else pivot
            up_face = rows[-1].below if rows else None
            like = up_face if up_face is not None else _face(system, base_k, n_b, pivot)
            below = RowFace(contacts=np.zeros(0, np.int64), normal=-t, point=point, length=0.0, cl=0.0,
                          tan_phi=like.tan_phi, tan_at=like.tan_at)
        rows.append(RowBlock(block=m, force=system.block_force[m].copy(), moment=float(system.block_moment[m]),
                             base=_face(system, base_k, n_b, pivot), downslope=t, pivot=pivot, below=below,
                             height=height, base_length=base_length))
    return TopplingRow(blocks=tuple(rows)), ""


def _angle(a: np.ndarray, b: np.ndarray) -> float:
    return math.degrees(math.acos(max(-1.0, min(1.0, float(a @ b)))))


def _point_segment(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> float:
    """Distance from p to the segment a–b [m]."""
    d = b - a
    s = 0.0 if not d.any() else min(1.0, max(0.0, float((p - a) @ d) / float(d @ d)))
    return float(np.hypot(*(p - a - s * d)))


def upslope_neighbours(system: BlockSystem, blocks: frozenset, removed: frozenset = frozenset()) -> list[int]:
    """Free blocks that lean on the top block of a toppling row from upslope: the group plus
    one of them is again a toppling row with it on top (the search grows rows this way)."""
    row = toppling_row(system, blocks, removed)
    if row is None:
        return []
    top = row.blocks[0].block
    out = []
    for nb in sorted(system.neighbours([top], removed) - set(blocks)):
        if system.block_fixed[nb]:
            continue
        grown = toppling_row(system, frozenset(blocks) | {nb}, removed)
        if grown is not None and grown.blocks[0].block == nb:
            out.append(nb)
    return out
