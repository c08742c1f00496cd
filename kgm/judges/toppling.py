"""The toppling judge: block toppling of a row of blocks, the Goodman & Bray (1976)
limit-equilibrium recursion on the real polygons of a group (Hoek & Bray 1981, ch. 10; Wyllie &
Mah 2004, §10.3).

A group admits block toppling when its members form a **row** of columns on one stepped base
(`kgm.candidates.row_geometry`, docs/kgm/footwall.md §6): every member rests on its own base (a face of
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
from typing import Optional

import numpy as np

from ..candidates import RowFace, TopplingRow, row_geometry
from ..faces import group_faces
from ..kinds import BlockState, ModeKind
from ..system import BARTON_ITERATIONS, BARTON_TOL, BlockSystem, cross
from .evaluation import Mode
from .limits import F_MAX, F_MIN, PHI_MAX, bisect


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
    def tan_of(face: RowFace, normal: float) -> float:
        if friction is not None:
            t = math.tan(math.radians(friction))
        else:  # a Barton–Bandis face: at its own normal force (eq. BB4)
            t = face.tan_phi if face.tan_at is None else face.tan_at(max(normal, 0.0))
        return t / reduction

    steps = []
    p_above = 0.0
    above: Optional[RowFace] = None  # the face of the block above, normal into that block
    for rb in row.blocks:
        n_b, t, o = rb.base.normal, rb.downslope, rb.pivot
        # toppling sense: the rotation about the pivot that moves the block's top downslope
        sense = 1.0 if float(np.array([-n_b[1], n_b[0]]) @ t) > 0 else -1.0
        m_force = sense * (rb.moment - cross(o, rb.force))  # moment of the active force about o
        f_above = np.zeros(2)
        m_above = 0.0
        if above is not None and p_above > 0.0:
            n_u = -above.normal  # into this block
            s_u = _shear_direction(n_u, n_b, away_from_base=False)
            q = p_above * tan_of(above, p_above) + above.cl / reduction
            f_above = p_above * n_u + q * s_u
            m_above = sense * cross(above.point - o, f_above)
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
            lever = sense * cross(lo.point - o, unit)
            driving = m_force + m_above + sense * cross(lo.point - o, cl_l * s_l)
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
    return math.exp(-bisect(lambda x: _is_stable(row, w, reduction=math.exp(-x)),
                             -math.log(F_MAX), -math.log(F_MIN)))


def row_critical_friction(row: TopplingRow) -> float:
    """Friction angle of every joint (cohesion held) with P_0 = 0 [degrees], by bisection; 0
    if the row stands without friction, 90 if no friction angle holds it."""
    w = _weight(row)
    if _is_stable(row, w, friction=0.0):
        return 0.0
    if not _is_stable(row, w, friction=PHI_MAX):
        return 90.0
    return bisect(lambda phi: _is_stable(row, w, friction=phi), 0.0, PHI_MAX)


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


def with_toppling(system: BlockSystem, blocks: frozenset, removed: frozenset, modes: list[Mode],
                  rejected: list[str]) -> list[Mode]:
    """The modes plus the group's block-toppling mode where its geometry admits one (a row of
    two or more blocks; a single block's toppling is the rigid rotation, §4.5); why not in
    ``rejected`` otherwise."""
    if len(blocks) > 1 and not any(m.fs == 0.0 for m in modes):
        mode, why = toppling_check(system, blocks, removed)
        if mode is not None:
            modes = modes + [mode]
        else:
            rejected.append(f"toppling: {why}")
    return modes
