"""Block theory in 3D: joint pyramids, finiteness, removability and the mode of a block
(Goodman & Shi 1985; docs/kgm/wedge.md §3).

A block is bounded by joint planes (discontinuities) and free faces (the slope face, the upper
face). Moved to the origin, the joint half-spaces of a block form its **joint pyramid** JP and
the rock sides of the free faces its **excavation pyramid** EP. With n non-parallel joint sets
there are 2ⁿ joint pyramids, one per sign code (above or below each plane). The theorems:

* **finite** if and only if the block pyramid BP = JP ∩ EP is the origin alone;
* a finite block is **removable** if and only if its JP is not empty (holds a direction other
  than the origin; between parallel joints it is a line or a flat cone, along which it slides);
  a finite block with an empty JP is **tapered**: it cannot leave its socket.

Both are linear programs (`jp_is_empty`, `is_finite`). The **mode** of a removable block under
a resultant force r (`admissible_modes`) is lifting/falling (r in JP: it leaves every face),
sliding on one face i (r presses on i and its projection on i leaves every other face) or
sliding on two faces i, j (along their line of intersection, with positive normal forces on
both); with three or more faces pressed and no such mode the block is held by its faces
whatever their strength (stable).
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass
from typing import Optional, Sequence

import numpy as np

#: angular tolerance of the kinematic tests [-] (cosines)
KINEMATIC_TOLERANCE = 1e-9


def jp_is_empty(inward_normals: np.ndarray, tol: float = 1e-9) -> bool:
    """True if the joint pyramid {d: vₖ·d ≥ 0 for all k} is the origin alone (``inward_normals``
    point into the block): no translation leaves the block's joint faces without entering one.
    A JP reduced to a line or a flat cone (a block between parallel joints) is not empty: the
    block slides along it. LP: max Σvₖ·d s.t. vₖ·d ≥ 0, ‖d‖∞ ≤ 1 is 0 and V has rank 3."""
    from scipy.optimize import linprog

    v = np.atleast_2d(np.asarray(inward_normals, dtype=float))
    if len(v) == 0 or np.linalg.matrix_rank(v, tol=1e-9) < 3:
        return False                     # a direction perpendicular to every normal stays free
    if len(v) <= 3:
        return False                     # independent normals: V d = (1, …, 1) has a solution
    res = linprog(c=-v.sum(axis=0), A_ub=-v, b_ub=np.zeros(len(v)), bounds=[(-1, 1)] * 3, method="highs")
    return bool(res.status == 0 and -res.fun <= tol)


def is_finite(inward_joint_normals: np.ndarray, outward_free_normals: np.ndarray, tol: float = 1e-9) -> bool:
    """True if BP = JP ∩ EP = {0} (Goodman & Shi's finiteness theorem), by the LP
    max Σ(−A d) s.t. A d ≤ 0, ‖d‖∞ ≤ 1 with the rows of A the outward normals (−vₖ of the
    joints, the free faces' own): a non-zero d in the cone gives a positive optimum unless it
    lies in A's null space, which a rank test catches."""
    from scipy.optimize import linprog

    rows = [-np.atleast_2d(np.asarray(inward_joint_normals, float)),
            np.atleast_2d(np.asarray(outward_free_normals, float))]
    a = np.vstack([r for r in rows if r.size])
    if np.linalg.matrix_rank(a, tol=1e-9) < 3:
        return False
    res = linprog(c=a.sum(axis=0), A_ub=a, b_ub=np.zeros(len(a)), bounds=[(-1, 1)] * 3, method="highs")
    return bool(res.status == 0 and -res.fun <= tol)


@dataclass(frozen=True)
class JointPyramid:
    """One of the 2ⁿ joint pyramids of n joint sets, judged against the free faces."""

    code: tuple
    """Side of each joint plane the block lies on: +1 above (on the side of its upward
    normal), −1 below (Goodman & Shi's 0 and 1)."""
    empty: bool
    """JP is the origin alone."""
    finite: bool
    """BP = JP ∩ EP = {0}."""

    @property
    def kind(self) -> str:
        """'removable' (finite, JP not empty: a potential key block), 'tapered' (finite, JP
        empty) or 'infinite'."""
        if not self.finite:
            return "infinite"
        return "tapered" if self.empty else "removable"

    @property
    def name(self) -> str:
        """Goodman & Shi's label: a digit per joint, 0 above, 1 below (e.g. '01')."""
        return "".join("0" if s > 0 else "1" for s in self.code)


def joint_pyramids(joint_normals: Sequence, free_outward_normals: Sequence) -> list:
    """Every joint pyramid of the joint sets with these (upward) normals, judged against the
    free faces with these outward normals (`JointPyramid`: empty, finite, kind)."""
    n = np.atleast_2d(np.asarray(joint_normals, dtype=float))
    f = np.atleast_2d(np.asarray(free_outward_normals, dtype=float)) if len(free_outward_normals) else np.zeros((0, 3))
    out = []
    for code in itertools.product((1, -1), repeat=len(n)):
        v = n * np.array(code, dtype=float)[:, None]
        out.append(JointPyramid(code=code, empty=jp_is_empty(v), finite=is_finite(v, f)))
    return out


def key_block_codes(joint_normals: Sequence, free_outward_normals: Sequence) -> list:
    """Codes of the removable joint pyramids (the potential key blocks of these free faces)."""
    return [p.code for p in joint_pyramids(joint_normals, free_outward_normals) if p.kind == "removable"]


@dataclass(frozen=True)
class Mode:
    """A kinematically admissible mode of a rigid block under a resultant r."""

    kind: str
    """'falling' (lifts off every face), 'one plane', 'two planes' or 'stable' (no mode)."""
    planes: tuple
    """Indices of the faces it slides on (empty when falling or stable)."""
    direction: np.ndarray
    """Unit sliding direction [-] (r̂ when falling; zeros when stable)."""
    normal: np.ndarray
    """Normal force on each face that r alone gives [N] (0 on faces it leaves)."""
    driving: float
    """Component of r along the sliding direction [N] (0 when stable)."""

    @property
    def label(self) -> str:
        if self.kind in ("falling", "stable"):
            return self.kind
        return f"sliding on {' and '.join(str(i) for i in self.planes)}"


def admissible_modes(r: np.ndarray, inward_normals: Sequence, tol: float = KINEMATIC_TOLERANCE) -> list:
    """Every admissible `Mode` of a block whose faces have these inward unit normals vₖ under
    the resultant ``r`` (Goodman & Shi's mode analysis). For a removable block and a general r
    there is one; degenerate cases (r exactly along a face, release planes parallel to the
    sliding direction) admit several with the same motion, and the caller keeps the least safe.
    A block with no admissible mode returns [`Mode` 'stable']."""
    r = np.asarray(r, dtype=float)
    v = np.atleast_2d(np.asarray(inward_normals, dtype=float)) if len(inward_normals) else np.zeros((0, 3))
    m = len(v)
    rn = float(np.linalg.norm(r))
    if rn == 0.0:
        return [Mode("stable", (), np.zeros(3), np.zeros(m), 0.0)]
    t = tol * rn
    rv = v @ r
    modes = []
    if np.all(rv >= -t):
        modes.append(Mode("falling", (), r / rn, np.zeros(m), rn))
    for i in range(m):
        if rv[i] >= -t:
            continue
        s = r - rv[i] * v[i]
        sn = float(np.linalg.norm(s))
        if sn <= t:                                  # r normal to the face: held by it
            continue
        s = s / sn
        others = np.delete(v, i, axis=0) @ s
        if np.all(others >= -tol):
            normal = np.zeros(m)
            normal[i] = -rv[i]
            modes.append(Mode("one plane", (i,), s, normal, sn))
    for i, j in itertools.combinations(range(m), 2):
        s = np.cross(v[i], v[j])
        sn = float(np.linalg.norm(s))
        if sn < 1e-9:                                # parallel faces: no line of intersection
            continue
        s = s / sn
        if s @ r < 0:
            s = -s
        if s @ r <= t:
            continue
        others = np.delete(v, [i, j], axis=0) @ s
        if not np.all(others >= -tol):
            continue
        # r − (r·s)s = −(Nᵢvᵢ + Nⱼvⱼ): the normal forces from the 2×2 Gram system
        c = float(v[i] @ v[j])
        perp = r - (s @ r) * s
        bi, bj = -(perp @ v[i]), -(perp @ v[j])
        det = 1.0 - c * c
        ni, nj = (bi - c * bj) / det, (bj - c * bi) / det
        if ni < -t or nj < -t:
            continue
        normal = np.zeros(m)
        normal[i], normal[j] = max(ni, 0.0), max(nj, 0.0)
        modes.append(Mode("two planes", (i, j), s, normal, float(s @ r)))
    if not modes:
        modes.append(Mode("stable", (), np.zeros(3), np.zeros(m), 0.0))
    return modes


def normal_forces(force: np.ndarray, mode: Mode, inward_normals: Sequence) -> np.ndarray:
    """Normal forces on the faces of ``mode`` that a force adds (a passive force or support),
    the sliding direction held [N]: −f·vᵢ on one face, the 2×2 Gram solution on two."""
    v = np.atleast_2d(np.asarray(inward_normals, dtype=float))
    f = np.asarray(force, dtype=float)
    out = np.zeros(len(v))
    if mode.kind == "one plane":
        i = mode.planes[0]
        out[i] = -(f @ v[i])
    elif mode.kind == "two planes":
        i, j = mode.planes
        s = mode.direction
        c = float(v[i] @ v[j])
        perp = f - (s @ f) * s
        bi, bj = -(perp @ v[i]), -(perp @ v[j])
        det = 1.0 - c * c
        out[i], out[j] = (bi - c * bj) / det, (bj - c * bi) / det
    return out


def face_kind_summary(pyramids: Sequence[JointPyramid]) -> dict:
    """Counts of removable, tapered and infinite pyramids."""
    out = {"removable": 0, "tapered": 0, "infinite": 0}
    for p in pyramids:
        out[p.kind] += 1
    return out


def block_pyramid_direction(inward_joint_normals, outward_free_normals) -> Optional[np.ndarray]:
    """A non-zero direction in BP = JP ∩ EP (the block goes on for ever along it), None if
    the block is finite."""
    from .geometry import recession_directions

    rows = [-np.atleast_2d(np.asarray(inward_joint_normals, float)),
            np.atleast_2d(np.asarray(outward_free_normals, float))]
    return recession_directions(np.vstack([r for r in rows if r.size]))
