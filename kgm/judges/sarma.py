"""The Sarma judge (SKGM, docs/kgm/method.md §5): the blocks of a group translate separately,
each sliding on its own contacts with the stable rock while the shared joints between members
shear, all at the same mobilised strength (c/F, tanφ/F), with Sarma's critical acceleration K_c.

For each mechanism of the group (`kgm.judges.mechanisms`) its statics: on every closed face the
normal force N ≥ 0 and, where it slips, the shear opposes the slip at the limit c*·L + N·tanφ*;
a face that does not slip carries an unknown shear within that limit. With the horizontal
inertia force K·W this gives 2n equations in the unknown forces and K, solved in the
least-squares sense (a determinate mechanism is square; a redundant one takes any admissible
force distribution). The factor of safety is the least F at which K(F) falls through 0 with
admissible forces, the critical friction angle the φ with K = 0 at F = 1, every root found
(`kgm.judges.limits`). Like Sarma's slices, the mechanisms see only the faces: a block corner
that would have to cut into the rock at a joint junction is not checked — DDA checks it on the
real geometry (scenes/example_2.py). The statics balance forces only; at the limit the members'
moments are checked (`unbalanced_moment`), and a mode whose members cannot balance them says so
(`kgm.Mode.unbalanced_moment`) and is no limit state (docs/kgm/footwall.md §9).

`evaluate_sarma`: the least safe of the rigid modes (`kgm.judges.rigid`), these mechanisms and
block toppling (`kgm.judges.toppling`), §5.3; translations (rigid slides, Sarma mechanisms) that
cannot balance their moments taken out, and where none can, the group's turning on two sliding
points (`kgm.judges.turning`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Optional

import numpy as np

from ..kinds import ModeKind
from ..system import BARTON_ITERATIONS, BARTON_TOL, BlockSystem
from .evaluation import Evaluation, Mode, governing
from .toppling import with_toppling
from .turning import slide_balances, turning_mode
from .limits import F_MAX, F_MIN, PHI_MAX, first_limit, pencil_roots, scan_roots, smallest_singular
from .mechanisms import Faces, Mechanism, face_name, mechanism_label, mechanisms, merge_faces
from .rigid import rigid_modes


def evaluate_sarma(system: BlockSystem, blocks: frozenset, removed: frozenset = frozenset()) -> Evaluation:
    """SKGM: least safe of the rigid modes, the Sarma mechanisms (docs/kgm/method.md §5.3) and
    block toppling."""
    rejected: list[str] = []
    modes = rigid_modes(system, blocks, removed, rejected=rejected)
    if len(blocks) > 1 and not any(m.fs == 0.0 for m in modes):
        found, why = sarma_checks(system, blocks, removed)
        rejected += why
        modes, more = _turning(system, blocks, removed, modes, found)
        rejected += more
    return governing(with_toppling(system, blocks, removed, modes, rejected), rejected)



def _turning(system: BlockSystem, blocks: frozenset, removed: frozenset, rigid: list, sarma: list
             ) -> tuple[list[Mode], list[str]]:
    """The rigid and Sarma modes of a group with the translations (rigid slides, Sarma
    mechanisms) that cannot balance their moments at their limit taken out (docs/kgm/footwall.md
    §9). Where another translation balances them, its forces are admissible at every F up to its
    limit (a stronger joint only widens the bounds), so the group stands there and the
    unbalanced ones are no limit states; where none does, no admissible equilibrium holds the
    group at any translation's limit: it turns, and its turning on two sliding points
    (`kgm.judges.turning`) replaces them. Returns (modes, one line for each translation taken
    out). Passive bolts, whose resistance depends on the motion, are left to the translations:
    with them nothing is taken out."""
    modes = rigid + sarma
    if system.block_passive is not None:
        return modes, []
    moves = [m for m in modes if m.kind in (ModeKind.SLIDING, ModeKind.SARMA)]

    def unbalanced(m: Mode) -> str:
        if m.kind == ModeKind.SARMA:
            return m.unbalanced_moment
        return "" if slide_balances(system, blocks, m) else "the resultant's line misses the face"

    why = {id(m): unbalanced(m) for m in moves}
    gone = [m for m in moves if why[id(m)]]
    if not gone:
        return modes, []
    held = [m for m in moves if not why[id(m)]]
    turn = None if held else turning_mode(system, blocks, removed)
    if not held and turn is None:
        return modes, []
    instead = (f"a translation that balances them holds the group up to FS {min(m.fs for m in held):.3f}" if held
               else "the group turns instead")
    notes = [f"{m.kind.value}, FS {m.fs:.3f}: moment not balanced at its limit: {why[id(m)]} ({instead})"
             for m in gone]
    return [m for m in modes if not why.get(id(m))] + ([turn] if turn is not None else []), notes


@dataclass(frozen=True, kw_only=True, eq=False)
class _Statics:
    k: float               # horizontal acceleration K [g] toward the motion
    admissible: bool       # N >= 0 everywhere, unslipped shear within its limit
    normal: np.ndarray     # (f,) normal force of each face [N/m] (0 on open faces)
    why: str = ""          # what is not admissible (tension on a face, shear beyond its limit)
    face_force: Optional[np.ndarray] = None  # (f, 2) force of each closed face on its member a [N/m]


def _system(mech: Mechanism, faces: Faces, force: np.ndarray, weight: np.ndarray,
            reduction: float, tan_phi: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The mechanism's equilibrium m·[N, S, K] = rhs at the strength (c/F, tanφ/F): 2n rows
    (the members' force balance), one column per closed face's normal force, one per
    unslipped face's shear, and K last. Every entry is affine in 1/F and in tanφ (F = inf
    gives the frictionless, cohesionless system). Returns (m, rhs, closed, stuck)."""
    n = len(weight)
    closed = np.flatnonzero(mech.closed)
    stuck = closed[mech.slip_sign[closed] == 0]
    vx = mech.velocity[0::2] @ weight
    e = np.array([1.0 if vx >= 0 else -1.0, 0.0])
    cols = len(closed) + len(stuck) + 1
    m = np.zeros((2 * n, cols))
    rhs = -force.reshape(-1).copy()
    tphi = tan_phi / reduction
    for col, k in enumerate(closed):
        a, b, s = faces.a[k], faces.b[k], mech.slip_sign[k]
        nvec, tvec = faces.normal[k], faces.tangent[k]
        # face force on a: N·n − s·(c*L + N tanφ*)·t  (shear opposes the slip of a, §5.2)
        col_vec = nvec - s * tphi[k] * tvec
        const = -s * faces.cl[k] / reduction * tvec
        m[2 * a:2 * a + 2, col] += col_vec
        rhs[2 * a:2 * a + 2] -= const
        if b >= 0:
            m[2 * b:2 * b + 2, col] -= col_vec
            rhs[2 * b:2 * b + 2] += const
    for j, k in enumerate(stuck):
        col = len(closed) + j
        a, b = faces.a[k], faces.b[k]
        m[2 * a:2 * a + 2, col] += faces.tangent[k]
        if b >= 0:
            m[2 * b:2 * b + 2, col] -= faces.tangent[k]
    for i in range(n):
        m[2 * i:2 * i + 2, -1] = weight[i] * e
    return m, rhs, closed, stuck


def _statics(mech: Mechanism, faces: Faces, force: np.ndarray, weight: np.ndarray,
             reduction: float, tan_phi: np.ndarray, check: bool = True) -> Optional[_Statics]:
    """Forces of the mechanism at the strength (c/F, tanφ/F) and the K that balances them;
    ``check`` also decides whether the forces are admissible (root searches need only K)."""
    m, rhs, closed, stuck = _system(mech, faces, force, weight, reduction, tan_phi)
    cols = m.shape[1]
    tphi = tan_phi / reduction
    scale = np.maximum(np.abs(m).max(axis=0), 1e-300)
    sol, *_ = np.linalg.lstsq(m / scale, rhs, rcond=None)
    sol = sol / scale
    if np.linalg.norm(m @ sol - rhs) > 1e-7 * max(np.linalg.norm(rhs), 1.0):
        return None  # no equilibrium with these contacts (e.g. a member with no support)
    if not check:
        normal = np.zeros(len(faces.a))
        normal[closed] = sol[:len(closed)]
        return _Statics(k=float(sol[-1]), admissible=False, normal=normal, why="not checked")
    # K must not depend on the redundant (statically indeterminate) forces
    _, sv, vh = np.linalg.svd(m / scale)
    rank = int(np.sum(sv > 1e-10 * sv[0]))
    if rank < cols and np.any(np.abs(vh[rank:, -1]) > 1e-8):
        return None
    tol = 1e-9 * float(weight.sum())
    ok, why = _forces_admissible(sol, closed, stuck, faces, tphi, reduction, tol)
    if not ok and rank < cols:
        # statically indeterminate (e.g. members sliding together on one plane): the
        # minimum-norm forces may pull on a face while another distribution does not; look
        # for any admissible one (a small linear feasibility problem)
        alt = _admissible_forces(m, rhs, closed, stuck, faces, tphi, reduction)
        if alt is not None:
            sol, ok, why = alt, True, ""
    normal = np.zeros(len(faces.a))
    normal[closed] = sol[:len(closed)]
    face_force = np.zeros((len(faces.a), 2))
    for col, k in enumerate(closed):  # the columns of `_system`
        n_k, s = sol[col], mech.slip_sign[k]
        face_force[k] = n_k * faces.normal[k] - s * (faces.cl[k] / reduction + n_k * tphi[k]) * faces.tangent[k]
    for j, k in enumerate(stuck):
        face_force[k] += sol[len(closed) + j] * faces.tangent[k]
    return _Statics(k=float(sol[-1]), admissible=ok, normal=normal, why=why, face_force=face_force)


def _statics_at(mech: Mechanism, faces: Faces, force: np.ndarray, weight: np.ndarray,
                reduction: float, check: bool = True) -> Optional[_Statics]:
    """`_statics` with the faces' own friction: Mohr–Coulomb faces as they are; Barton–Bandis
    faces take tanφ at their normal stress, which the statics give, so the forces are iterated
    to their fixed point (eq. BB6: solve with tanφ, update tanφ(N/L), until it changes by less
    than BARTON_TOL; docs/method/barton_bandis.md)."""
    if faces.tan_at is None:
        return _statics(mech, faces, force, weight, reduction, faces.tan_phi, check=check)
    tan_phi = faces.tan_phi
    for _ in range(BARTON_ITERATIONS):
        st = _statics(mech, faces, force, weight, reduction, tan_phi, check=False)
        if st is None:
            return None
        new = np.where(mech.closed, faces.tan_at(st.normal), tan_phi)
        done = np.all(np.abs(new - tan_phi) <= BARTON_TOL * (1.0 + np.abs(tan_phi)))
        tan_phi = new
        if done:
            break
    return _statics(mech, faces, force, weight, reduction, tan_phi, check=check)


def _forces_admissible(sol, closed, stuck, faces, tphi, reduction, tol) -> tuple[bool, str]:
    """No tension on a closed face; unslipped shear within its Mohr–Coulomb limit (§5.2).
    Returns (admissible, what is not: the face and its force)."""
    normal = sol[:len(closed)]
    if np.any(normal < -tol):
        i = int(np.argmin(normal))
        return False, f"tension {normal[i] / 1e3:.3g} kN/m on {face_name(faces, int(closed[i]))}"
    pos = {int(k): i for i, k in enumerate(closed)}
    for j, k in enumerate(stuck):
        limit = faces.cl[k] / reduction + max(normal[pos[int(k)]], 0.0) * tphi[k]
        if abs(sol[len(closed) + j]) > limit * (1 + 1e-9) + tol:
            return False, f"shear beyond its strength on {face_name(faces, int(k))}"
    return True, ""


def _admissible_forces(m, rhs, closed, stuck, faces, tphi, reduction) -> Optional[np.ndarray]:
    """Forces with m·u = rhs, N ≥ 0 and |S| ≤ c*L + N·tanφ* on unslipped faces, or None."""
    from scipy.optimize import linprog

    cols = m.shape[1]
    scale = np.maximum(np.abs(m).max(axis=0), 1e-300)
    bounds = [(0, None)] * len(closed) + [(None, None)] * (cols - len(closed))
    a_ub, b_ub = [], []
    pos = {int(k): i for i, k in enumerate(closed)}
    for j, k in enumerate(stuck):
        for sgn in (1.0, -1.0):
            row = np.zeros(cols)
            row[len(closed) + j] = sgn / scale[len(closed) + j]
            row[pos[int(k)]] = -tphi[k] / scale[pos[int(k)]]
            a_ub.append(row)
            b_ub.append(faces.cl[k] / reduction)
    res = linprog(np.zeros(cols), A_ub=np.array(a_ub) if a_ub else None, b_ub=b_ub or None,
                  A_eq=m / scale, b_eq=rhs, bounds=bounds, method="highs")
    return res.x / scale if res.status == 0 else None


def sarma_modes(system: BlockSystem, blocks: frozenset, removed: frozenset = frozenset()) -> list[Mode]:
    """Admissible Sarma mechanisms of a group with their FS, K_c and critical friction angle.

    FS: the least F at which K(F) falls through 0 with admissible forces (Sarma 1979: reduce
    the strength until the critical acceleration vanishes, §5.1–5.2); every root of K is
    found (`kgm.judges.limits.pencil_roots`; docs/kgm/footwall.md §5). K_c = K(1). Critical friction: the φ of
    all joints (cohesion held) at which K_c = 0, the same way (§4.6). A mechanism with no
    root whose forces are admissible (tension on a face) is dropped (§5.2); ``sarma_checks``
    says why.
    """
    return sarma_checks(system, blocks, removed)[0]


def sarma_checks(system: BlockSystem, blocks: frozenset, removed: frozenset = frozenset()
                 ) -> tuple[list[Mode], list[str]]:
    """`sarma_modes` and one line per mechanism it dropped, saying why (no root of K(F) in
    [F_MIN, F_MAX], or the roots' forces are not admissible), or why the group has none."""
    members = sorted(blocks)
    n = len(members)
    faces = merge_faces(system, members, removed)
    force = system.block_force[members]
    passive = system.block_passive[members] if system.block_passive is not None else None
    weight = system.block_mass[members] * system.gravity
    modes, notes = [], []
    found_mechanisms = mechanisms(faces, force, n)
    if not found_mechanisms:
        notes.append("no Sarma mechanism: the members cannot move apart on their faces without cutting "
                     "into a neighbour, or the active forces do not drive them")
    lo, hi = math.log(F_MIN), math.log(F_MAX)
    for mech in found_mechanisms:
        label = mechanism_label(mech, faces)

        def k_of_u(u, _m=mech):
            st = _statics_at(_m, faces, _loaded(force, passive, _m, math.exp(u)), weight, math.exp(u),
                             check=False)
            return math.nan if st is None else st.k

        def admissible_at_u(u, _m=mech):
            st = _statics_at(_m, faces, _loaded(force, passive, _m, math.exp(u)), weight, math.exp(u))
            if st is None:
                return False, "no force distribution balances it"
            return st.admissible, st.why

        def affine(x, _m=mech):  # x = 1/F
            red = math.inf if x == 0 else 1.0 / x
            m, rhs, _, _ = _system(_m, faces, _loaded(force, passive, _m, red), weight, red, faces.tan_phi)
            return m, rhs

        def sigma_of(u, _m=mech):
            f = math.exp(u)
            return smallest_singular(_system(_m, faces, _loaded(force, passive, _m, f), weight, f, faces.tan_phi)[0])

        # K(F) falls as F grows where the forces are admissible; outside that range (tension
        # on a face) the linear solution means nothing: find every root, keep the least whose
        # forces are admissible (§5.2)
        roots = pencil_roots(affine, 1.0 / F_MAX, 1.0 / F_MIN) if faces.tan_at is None else None
        if roots is not None:
            candidates = [-math.log(x) for x in roots if x > 0]
        else:
            candidates = scan_roots(k_of_u, sigma_of, lo, hi, falling=True)
        u, rejected = first_limit(candidates, k_of_u, admissible_at_u, falling=True,
                                   name=lambda v: f"F = {math.exp(v):.4g}")
        if u is not None:
            fs = math.exp(u)
        elif k_of_u(lo) <= 0 and admissible_at_u(lo)[0]:
            fs = 0.0  # fails even with a thousand times the strength
        else:
            why = f"K(F) has no root for F in [{F_MIN:g}, {F_MAX:g}]"
            if rejected:
                why = f"no root of K(F) for F in [{F_MIN:g}, {F_MAX:g}] has admissible forces: " + "; ".join(rejected)
            notes.append(f"Sarma mechanism {label}: {why}")
            continue
        turning = ""
        if fs > 0.0 and passive is None:
            at_limit = _statics_at(mech, faces, _loaded(force, passive, mech, fs), weight, fs)
            if at_limit is not None and at_limit.face_force is not None:
                turning = unbalanced_moment(mech, faces, at_limit.face_force, system.block_moment[members],
                                            float(weight.sum() * system.scale))
        kc = _statics_at(mech, faces, _loaded(force, passive, mech, 1.0), weight, 1.0, check=False)
        phi_c = _mechanism_critical_friction(mech, faces, _loaded(force, passive, mech, 1.0), weight)
        if phi_c is None:
            notes.append(f"Sarma mechanism {label}: not admissible (no friction angle in [0°, {PHI_MAX}°] brings it "
                         f"to limit equilibrium with admissible forces)")
            continue
        sliding = np.concatenate([faces.contacts[k] for k in np.flatnonzero(mech.closed & (faces.b < 0))]
                                 or [np.zeros(0, np.int64)])
        sheared = np.concatenate([faces.contacts[k] for k in
                                  np.flatnonzero(mech.closed & (faces.b >= 0) & (mech.slip_sign != 0))]
                                 or [np.zeros(0, np.int64)])
        vel = {b: mech.velocity[2 * i:2 * i + 2].copy() for i, b in enumerate(members)}
        modes.append(Mode(kind=ModeKind.SARMA, fs=fs, critical_friction=phi_c,
                          sliding_contacts=np.sort(sliding), sheared_contacts=np.sort(sheared),
                          block_velocity=vel,
                          critical_acceleration=(kc.k if kc is not None else math.nan),
                          unbalanced_moment=turning))
    return modes, notes


#: Largest group whose moment check enumerates its member subsets (2^n cuts); larger ones
#: solve the same feasibility problem as a linear programme [-].
CUT_MEMBERS = 12


def unbalanced_moment(mech: Mechanism, faces: Faces, face_force: np.ndarray, moment: np.ndarray,
                      size: float) -> str:
    """'' where the members of a mechanism at limit equilibrium can balance their moments, else
    which members turn and which way (`kgm.Mode.unbalanced_moment`).

    Sarma's statics balance forces only. Each closed face's force may act anywhere on the face
    (its normal stress distribution is free, compressive since N ≥ 0), so about the origin it
    gives its member a moment M_k between those of the force at the face's two ends; the members
    balance when such M_k exist with, for every member i, moment_i + Σ_{a_k = i} M_k −
    Σ_{b_k = i} M_k = 0 (a shared face acts on both sides at one point). This is Sarma's (1979)
    acceptability check that the line of thrust stays within the slices, for any group. The
    equations are a flow network (members and the rock as nodes, faces as arcs with bounds), so
    by Hoffman's circulation theorem they have a solution iff every set S of members can be
    balanced by the faces that cross its boundary, each within its bounds: 2^n − 1 interval
    checks (a linear programme beyond `CUT_MEMBERS`). ``moment``: (n,) the members' active
    moments about the origin [N·m/m] (K = 0 at the limit); ``size``: a force times a length
    [N·m/m] the tolerance is relative to."""
    closed = np.flatnonzero(mech.closed)
    if faces.ends is None or len(closed) == 0:
        return ""
    ends = faces.ends[closed]                                   # (c, 2, 2)
    f = face_force[closed]
    arm = ends[:, :, 0] * f[:, None, 1] - ends[:, :, 1] * f[:, None, 0]   # (c, 2): p × F at each end
    lo, hi = arm.min(axis=1), arm.max(axis=1)
    n = len(moment)
    tol = 1e-9 * max(size, 1.0)
    a, b = faces.a[closed], faces.b[closed]
    if n > CUT_MEMBERS:
        return _moments_by_programme(a, b, lo, hi, moment, tol)
    for mask in sorted(range(1, 2 ** n), key=lambda m: bin(m).count("1")):   # single members first
        inside = np.array([(mask >> i) & 1 for i in range(n)], dtype=bool)
        sign = inside[a].astype(float) - np.where(b >= 0, inside[np.maximum(b, 0)], False)
        m_s = float(moment[inside].sum())
        low = m_s + float(np.where(sign > 0, lo, 0.0).sum() - np.where(sign < 0, hi, 0.0).sum())
        high = m_s + float(np.where(sign > 0, hi, 0.0).sum() - np.where(sign < 0, lo, 0.0).sum())
        if low > tol or high < -tol:
            way = "counter-clockwise" if low > tol else "clockwise"
            ids = [faces.members[i] if faces.members else i for i in np.flatnonzero(inside)]
            who = f"block {ids[0]} would turn" if len(ids) == 1 else f"blocks {ids} would turn together"
            return (f"{who} {way}: no points on the faces balance the moment (at least "
                    f"{min(abs(low), abs(high)) / 1e3:.3g} kN·m/m left)")
    return ""


def _moments_by_programme(a, b, lo, hi, moment, tol) -> str:
    """`unbalanced_moment`'s feasibility problem as a linear programme (large groups)."""
    from scipy.optimize import linprog

    n = len(moment)
    a_eq = np.zeros((n, len(a)))
    a_eq[a, np.arange(len(a))] += 1.0
    inner = np.flatnonzero(b >= 0)
    a_eq[b[inner], inner] -= 1.0
    scale = max(float(np.abs(lo).max()), float(np.abs(hi).max()), float(np.abs(moment).max()), 1.0)
    res = linprog(np.zeros(len(a)), A_eq=a_eq, b_eq=-moment / scale,
                  bounds=list(zip((lo - tol) / scale, (hi + tol) / scale)), method="highs")
    return "" if res.status == 0 else "the members would turn: no points on their faces balance their moments"


def _loaded(force: np.ndarray, passive: Optional[np.ndarray], mech: Mechanism, reduction: float) -> np.ndarray:
    """Member forces with the passive bolt forces of a mechanism at strength 1/F
    (docs/method/water_bolts.md, B2): each member's passive force splits into its part along
    the member's velocity, a resistance reduced with the joints' strength (÷F), and the rest,
    which acts in full (for one block on one plane: the normal part presses the plane, as in
    RocPlane's passive support)."""
    if passive is None:
        return force
    v = mech.velocity.reshape(-1, 2)
    vhat = v / np.maximum(np.hypot(v[:, 0], v[:, 1]), 1e-300)[:, None]
    along = (passive * vhat).sum(axis=1)
    return force + passive + ((1.0 / reduction - 1.0) * along)[:, None] * vhat


def _mechanism_critical_friction(mech: Mechanism, faces: Faces, force: np.ndarray,
                                 weight: np.ndarray) -> Optional[float]:
    """φ of all faces (cohesion held) with K(F = 1) = 0 (§4.6): the least φ at which K rises
    through zero with admissible forces, every root found as for the FS (`kgm.judges.limits.pencil_roots` in
    x = tanφ, else `kgm.judges.limits.scan_roots`)."""
    def tan_of(phi: float) -> np.ndarray:
        return np.full(len(faces.a), math.tan(math.radians(phi)))

    def k_of(phi: float) -> float:
        st = _statics(mech, faces, force, weight, 1.0, tan_of(phi), check=False)
        return math.nan if st is None else st.k

    def admissible(phi: float) -> tuple[bool, str]:
        st = _statics(mech, faces, force, weight, 1.0, tan_of(phi))
        return (False, "no force distribution balances it") if st is None else (st.admissible, st.why)

    def affine(x: float):  # x = tanφ
        m, rhs, _, _ = _system(mech, faces, force, weight, 1.0, np.full(len(faces.a), x))
        return m, rhs

    def sigma_of(phi: float) -> float:
        return smallest_singular(_system(mech, faces, force, weight, 1.0, tan_of(phi))[0])

    if k_of(0.0) >= 0 and admissible(0.0)[0]:
        return 0.0
    roots = pencil_roots(affine, 0.0, math.tan(math.radians(PHI_MAX)))
    if roots is not None:
        candidates = [math.degrees(math.atan(x)) for x in roots]
    else:
        candidates = scan_roots(k_of, sigma_of, 0.0, PHI_MAX, falling=False)
    phi, _ = first_limit(candidates, k_of, admissible, falling=False, name=lambda v: f"φ = {v:.4g}°")
    if phi is None:
        return 90.0 if k_of(PHI_MAX) < 0 and admissible(PHI_MAX)[0] else None
    return float(phi)
