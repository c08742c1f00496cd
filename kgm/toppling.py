"""Block toppling of a row of blocks: the Goodman & Bray (1976) limit-equilibrium recursion on
the real polygons of a group (Hoek & Bray 1981, ch. 10; Wyllie & Mah 2004, §10.3).

A group admits block toppling when its members form a **row** of columns on one stepped base
(`row_geometry`, docs/kgm/footwall.md §6): every member rests on its own base (a face of
contacts with the stable rock on which its active force presses; neighbours' bases within
`ROW_BASE_ANGLE`), each pushes on the next one downslope through an interface (a face shared by
the two, across both bases, facing downslope for both) that rises from its pivot, and the
lowest member (the toe) has nothing, rock or member, in front of it; and its mechanism at limit
equilibrium does not cut into the blocks around it (`toppling_check`). A face slab lying on its
bedding and pushing a toe block that rests on another joint is a two-block sliding mechanism,
not a row. Going from the top block down to the toe, block n receives the force P_n from the
block above and needs

* P_{n-1,t} from the block below to hold it against toppling about the downslope end of its
  base (moment equilibrium about that corner, Goodman & Bray eq. 11 / Wyllie & Mah eq. 10.9):
  in the textbook geometry  P_{n-1,t} = [P_n (M_n − Δx tanφ_d) + W_n/2 (y_n sinψ − Δx cosψ)] / L_n;
* P_{n-1,s} to hold it against sliding on its base (force equilibrium along and across the
  base, Goodman & Bray eq. 13 / Wyllie & Mah eq. 10.10):
  P_{n-1,s} = P_n − W_n (tanφ_p cosψ − sinψ) / (1 − tanφ_p tanφ_d).

The block is stable if neither is positive (it passes 0 on), toppling if P_{n-1,t} > P_{n-1,s}
and sliding otherwise; the larger force goes on to the block below. The interface forces have
shear Q = c·L + P·tanφ_d (the face is closed while it transmits P): on the block below it acts
toward that block's base, on the block above away from it (Hoek & Bray's sign convention). The
slope is stable if and only if the force the toe block needs from below, P_0, is ≤ 0.

Here the recursion is written with vectors on the real geometry instead of the textbook's
rectangles: the active force (weight and point loads) and its moment from the block arrays,
the base from the member's contacts with the stable rock (pooled by direction, length-weighted
tanφ, Σ c·L), the pivot at the downslope end of the base, and each interface force applied at
the point of the shared face farthest from the block's base (Goodman & Bray's M_n and L_n: the
top of the shorter of the two faces, where the toppling columns touch). For the textbook
rectangles the vector equations are exactly the two formulas above. P_0 acts parallel to the
toe's base at the highest point of its free downslope face.

The factor of safety is a strength reduction: tanφ/F and c/F on every joint, F found by
bisection on the sign of P_0 (docs/kgm/method.md §4.6); the critical friction angle is the φ of all
joints (cohesion held) with P_0 = 0, also by bisection.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable, Optional

import numpy as np

from .kinds import BlockState
from .blocks import BARTON_ITERATIONS, BARTON_TOL, BlockSystem, Mode, ModeKind, _cross, _parallel_sets, group_faces

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
#: Bracket of the strength-reduction factor F [-] and bisection steps.
F_MIN, F_MAX = 1e-3, 1e3
#: Largest friction angle of the critical-friction bisection [degrees].
PHI_MAX = 89.9
BISECTION_STEPS = 64


@dataclass(frozen=True, kw_only=True, eq=False)
class _Face:
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
    base: _Face             # base face (normal into the block)
    downslope: np.ndarray   # (2,) unit base tangent pointing downslope
    pivot: np.ndarray       # (2,) downslope end of the base [m]
    below: _Face            # face toward the next block down (for the toe: its free face)
    height: float           # largest distance of the polygon from its base line [m]
    base_length: float      # Σ L of the base [m]


@dataclass(frozen=True, kw_only=True, eq=False)
class TopplingRow:
    """Members of a group that admits block toppling, ordered from the top block to the toe."""

    blocks: tuple  # (RowBlock, ...), top first


@dataclass(frozen=True, kw_only=True, eq=False)
class BlockStep:
    """The recursion's answer for one block (one row of Hoek & Bray's table)."""

    block: int
    """Block id."""
    state: BlockState
    """Stable, toppling or sliding."""
    force_above: float
    """P_n: force from the block above [N/m]."""
    force_toppling: float
    """P_{n-1,t}: force needed from below to prevent toppling [N/m] (±inf: cannot / need not)."""
    force_sliding: float
    """P_{n-1,s}: force needed from below to prevent sliding [N/m]."""
    force_below: float
    """P_{n-1} passed to the block below (0 for a stable block) [N/m]."""
    height: float
    """y_n: height of the block above its base [m]."""
    contact_above: float
    """M_n: height of the upper interface force above the base [m] (0: top block)."""
    contact_below: float
    """L_n: height of the lower interface force above the base [m]."""
    base_dip: float
    """Dip of the base [degrees]."""


# ---------------------------------------------------------------------- geometry of a row
def _face(system: BlockSystem, contacts: np.ndarray, normal: np.ndarray, point: np.ndarray) -> _Face:
    length = system.contact_length[contacts]
    total = float(length.sum())
    ks = np.asarray(contacts, dtype=np.int64)
    tan_at = None
    if system.contact_barton is not None and not np.all(np.isnan(system.contact_barton[ks, 0])):
        tan_at = system.face_tan_function(ks)
    return _Face(contacts=ks, normal=normal, point=point, length=total,
                 cl=float((system.contact_cohesion[contacts] * length).sum()),
                 tan_phi=float((np.tan(np.radians(system.contact_friction[contacts])) * length).sum()
                               / max(total, 1e-300)), tan_at=tan_at)


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
        for grp in _parallel_sets(gf.boundary_normal[sel]):
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
            below = _Face(contacts=np.zeros(0, np.int64), normal=-t, point=point, length=0.0, cl=0.0,
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


# ---------------------------------------------------------------------- the recursion
def _shear_direction(normal: np.ndarray, base_normal: np.ndarray, away_from_base: bool) -> np.ndarray:
    """Unit tangent of an interface pointing away from (or toward) the block's base."""
    s = np.array([-normal[1], normal[0]])
    if (float(s @ base_normal) >= 0.0) != away_from_base:
        s = -s
    return s


def recursion(row: TopplingRow, *, reduction: float = 1.0, friction: Optional[float] = None) -> tuple:
    """Goodman & Bray's recursion from the top block to the toe at the strength (tanφ/F, c/F)
    on every joint (``reduction`` F), or with every joint's friction set to ``friction``
    [degrees] (cohesion held). Returns one `BlockStep` per member, top first; the last one's
    ``force_below`` is P_0, the force the toe needs from below (stable iff ≤ 0)."""
    def tan_of(face: _Face, normal: float) -> float:
        if friction is not None:
            t = math.tan(math.radians(friction))
        else:  # a Barton–Bandis face: at its own normal force (eq. BB4)
            t = face.tan_phi if face.tan_at is None else face.tan_at(max(normal, 0.0))
        return t / reduction

    steps = []
    p_above = 0.0
    above: Optional[_Face] = None  # the face of the block above, normal into that block
    for rb in row.blocks:
        n_b, t, o = rb.base.normal, rb.downslope, rb.pivot
        # toppling sense: the rotation about the pivot that moves the block's top downslope
        sense = 1.0 if float(np.array([-n_b[1], n_b[0]]) @ t) > 0 else -1.0
        m_force = sense * (rb.moment - _cross(o, rb.force))  # moment of the active force about o
        f_above = np.zeros(2)
        m_above = 0.0
        if above is not None and p_above > 0.0:
            n_u = -above.normal  # into this block
            s_u = _shear_direction(n_u, n_b, away_from_base=False)
            q = p_above * tan_of(above, p_above) + above.cl / reduction
            f_above = p_above * n_u + q * s_u
            m_above = sense * _cross(above.point - o, f_above)
        lo = rb.below
        s_l = _shear_direction(lo.normal, n_b, away_from_base=True)
        cl_l = lo.cl / reduction
        bb = friction is None and (lo.tan_at is not None or rb.base.tan_at is not None)
        # Barton–Bandis faces take tanφ at the normal force they carry, which the answer sets:
        # P_{n-1} on the face below, the reaction R on the base; iterated to the fixed point
        # (eq. BB6). Mohr–Coulomb faces: one pass.
        p_t = p_s = 0.0
        for _ in range(BARTON_ITERATIONS if bb else 1):
            tan_l = tan_of(lo, p_t)
            unit = lo.normal + tan_l * s_l          # force on the block per unit P_{n-1}
            # toppling (Goodman & Bray eq. 11): moment about the pivot, base reaction through it
            lever = sense * _cross(lo.point - o, unit)
            driving = m_force + m_above + sense * _cross(lo.point - o, cl_l * s_l)
            if lever < -1e-12 * rb.height:
                new_t = -driving / lever
            else:
                new_t = math.inf if driving > 0 else -math.inf  # the force below cannot hold it
            # sliding (Goodman & Bray eq. 13): forces along and across the base, S = c·A + R tanφ_p
            tan_l = tan_of(lo, p_s)
            unit = lo.normal + tan_l * s_l
            k_t = float((rb.force + f_above + cl_l * s_l) @ t)
            k_n = float((rb.force + f_above + cl_l * s_l) @ n_b)
            reaction = -(k_n + max(p_s, 0.0) * float(unit @ n_b))   # R on the base
            tan_b, cl_b = tan_of(rb.base, reaction), rb.base.cl / reduction
            denominator = float(unit @ t) + tan_b * float(unit @ n_b)
            if denominator < -1e-12:
                new_s = (cl_b - k_t - tan_b * k_n) / denominator
            else:
                new_s = -math.inf  # pushing from below only jams it on its base: it cannot slide
            done = all(a == b or (math.isfinite(a) and math.isfinite(b) and
                                  abs(a - b) <= BARTON_TOL * (1.0 + abs(a)))
                       for a, b in ((p_t, new_t), (p_s, new_s)))
            p_t, p_s = new_t, new_s
            if done or not (math.isfinite(p_t) and math.isfinite(p_s)):
                break
        if p_t <= 0.0 and p_s <= 0.0:
            state, p_below = BlockState.STABLE, 0.0
        elif p_t > p_s:
            state, p_below = BlockState.TOPPLING, p_t
        else:
            state, p_below = BlockState.SLIDING, p_s
        steps.append(BlockStep(
            block=rb.block, state=state, force_above=p_above, force_toppling=p_t, force_sliding=p_s,
            force_below=p_below, height=rb.height,
            contact_above=float((above.point - o) @ n_b) if above is not None else 0.0,
            contact_below=float((lo.point - o) @ n_b),
            base_dip=float(np.degrees(math.atan2(abs(t[1]), abs(t[0]))))))
        p_above, above = p_below, lo
    return tuple(steps)


def toe_force(row: TopplingRow, *, reduction: float = 1.0, friction: Optional[float] = None) -> float:
    """P_0: the force the toe block needs from below [N/m] (≤ 0: the row is stable)."""
    return recursion(row, reduction=reduction, friction=friction)[-1].force_below


def _is_stable(row: TopplingRow, weight: float, **strength) -> bool:
    return toe_force(row, **strength) <= 1e-12 * weight


def _weight(row: TopplingRow) -> float:
    return float(sum(np.hypot(*rb.force) for rb in row.blocks))


def _bisect(stands, lo: float, hi: float) -> float:
    """The point in [lo, hi] where ``stands(x)`` turns from False (at lo) to True (at hi)."""
    for _ in range(BISECTION_STEPS):
        mid = 0.5 * (lo + hi)
        if stands(mid):
            hi = mid
        else:
            lo = mid
    return 0.5 * (lo + hi)


def row_factor_of_safety(row: TopplingRow) -> float:
    """Strength-reduction factor F with P_0 = 0 (tanφ/F, c/F on every joint), by bisection on
    log F; 0 if the row fails with a thousand times the strength, inf if it stands with a
    thousandth of it."""
    w = _weight(row)
    if not _is_stable(row, w, reduction=F_MIN):
        return 0.0
    if _is_stable(row, w, reduction=F_MAX):
        return math.inf
    # the row stands at small F and fails at large F: bisect on −log F
    return math.exp(-_bisect(lambda x: _is_stable(row, w, reduction=math.exp(-x)),
                             -math.log(F_MAX), -math.log(F_MIN)))


def row_critical_friction(row: TopplingRow) -> float:
    """Friction angle of every joint (cohesion held) with P_0 = 0 [degrees], by bisection; 0
    if the row stands without friction, 90 if no friction angle holds it."""
    w = _weight(row)
    if _is_stable(row, w, friction=0.0):
        return 0.0
    if not _is_stable(row, w, friction=PHI_MAX):
        return 90.0
    return _bisect(lambda phi: _is_stable(row, w, friction=phi), 0.0, PHI_MAX)


def toppling_mode(system: BlockSystem, blocks: frozenset, removed: frozenset = frozenset()) -> Optional[Mode]:
    """The block-toppling mode of a group (Goodman & Bray 1976), or None if the group is not a
    toppling row, stands even with a thousandth of its strength, has no toppling block at
    limit equilibrium (a row whose blocks only slide is a translational mechanism, left to the
    rigid and Sarma evaluators), or its mechanism would cut into the rock (`toppling_check`
    says which). ``Mode.block_modes`` holds the recursion at limit equilibrium (strength
    reduced by FS), top block first."""
    return toppling_check(system, blocks, removed)[0]


def toppling_check(system: BlockSystem, blocks: frozenset, removed: frozenset = frozenset()
                   ) -> tuple[Optional[Mode], str]:
    """`toppling_mode` and, when there is none, why (one line)."""
    row, why = row_geometry(system, blocks, removed)
    if row is None:
        return None, f"not a toppling row: {why}"
    fs = row_factor_of_safety(row)
    if not math.isfinite(fs):
        return None, "the row stands even with a thousandth of its strength"
    steps = recursion(row, reduction=fs if fs > 0 else F_MIN)
    if not any(s.state == BlockState.TOPPLING for s in steps):
        return None, "at limit equilibrium its blocks only slide (a translation: the rigid and Sarma modes)"
    cut = _cuts_into_rock(system, row, steps, frozenset(blocks), removed)
    if cut:
        return None, f"not admissible: {cut}"
    moving = [rb for rb, s in zip(row.blocks, steps) if s.state != BlockState.STABLE]
    # the failure surface: the bases the moving blocks slide or pivot on
    sliding = np.concatenate([rb.base.contacts for rb in moving])
    sheared = np.concatenate([rb.below.contacts for rb in moving] or [np.zeros(0, np.int64)])
    return Mode(kind=ModeKind.TOPPLING, fs=fs, critical_friction=row_critical_friction(row),
                sliding_contacts=np.sort(sliding), sheared_contacts=np.sort(sheared),
                pivot=row.blocks[-1].pivot.copy(), block_modes=steps), ""


def _cuts_into_rock(system: BlockSystem, row: TopplingRow, steps: tuple, blocks: frozenset,
                    removed: frozenset) -> str:
    """Whether the mechanism at limit equilibrium is kinematically admissible against the
    blocks outside the row: a toppling member rotates about its pivot (its top downslope), a
    sliding one translates down its base; neither may move into a non-member across a
    contact (§2.4). Returns what cuts in, or ''."""
    gf = group_faces(system, blocks, removed)
    tol = 1e-9 * system.scale
    for rb, st in zip(row.blocks, steps):
        if st.state == BlockState.STABLE:
            continue
        sel = np.flatnonzero(gf.boundary_member == rb.block)
        if not len(sel):
            continue
        k = gf.boundary[sel]
        n_in = gf.boundary_normal[sel]
        for ends in (system.contact_start[k], system.contact_end[k]):
            if st.state == BlockState.TOPPLING:
                n_b, t = rb.base.normal, rb.downslope
                omega = 1.0 if float(np.array([-n_b[1], n_b[0]]) @ t) > 0 else -1.0
                r = ends - rb.pivot
                vel = omega * np.stack([-r[:, 1], r[:, 0]], axis=1) / max(rb.height, rb.base_length)
            else:
                vel = np.broadcast_to(rb.downslope, ends.shape)
            bad = np.flatnonzero((vel * n_in).sum(axis=1) < -1e-6 * np.hypot(vel[:, 0], vel[:, 1]) - tol)
            if len(bad):
                other = int(gf.boundary_other[sel[bad[0]]])
                how = "toppling about its pivot" if st.state == BlockState.TOPPLING else "sliding down its base"
                return f"block {rb.block} {how} would cut into block {other}"
    return ""


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
