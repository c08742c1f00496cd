"""Limit-equilibrium evaluators of a block group: rigid (KGM) and Sarma-type (SKGM).

* `evaluate_rigid` – the group glued into one rigid body, limit equilibrium on its admissible
  modes (docs/kgm/method.md §2.4, §4): the original KGM.
* `evaluate_sarma` – the blocks of the group translate separately: each slides on its own
  contacts with the stable rock and the shared joints between members shear, all at the same
  mobilised strength (c/F, tanφ/F), with Sarma's critical acceleration K_c (§5). The group's
  factor of safety is the least over these mechanisms and the rigid modes (§5.3).

Both add **block toppling** (`kgm.toppling`, Goodman & Bray 1976) when the group's geometry
admits it (a row of blocks on their own bases, each pushing on the next one downslope): the
group's FS is that of the least safe admissible mechanism, translation, rotation or toppling.

The DDA evaluator lives in :mod:`kgm.dda` (it starts Taichi) and is imported only when used.

Sarma mechanisms (§5.2, generalised to any group): with member velocities v ∈ R^{2n}, every
contact face k between member a and block b (a member, or stable rock with v_b = 0) must not
penetrate: (v_a − v_b)·n_k ≥ 0 (n_k into a). The single-degree-of-freedom mechanisms Sarma
assumes — every block slides on its own base, every shared joint slides (or opens) — are the
extreme rays of this cone, where 2n − 1 independent face conditions hold with equality; they
are found by the double-description method (or, when the cone contains a line, that line:
every face stays closed). Members that move together because the geometry makes them (one
plane under both) share a face with no slip. Each mechanism is checked (every member moves,
no face penetrates, the active forces drive it), then its statics: on every closed face the
normal force N ≥ 0 and, where it slips, the shear opposes the slip at the limit c*·L + N·tanφ*;
a face that does not slip carries an unknown shear within that limit. With the horizontal
inertia force K·W this gives 2n equations in the unknown forces and K, solved in the
least-squares sense (a determinate mechanism is square; a redundant one takes any admissible
force distribution). Like Sarma's slices, the mechanisms see only the faces: a block corner
that would have to cut into the rock at a joint junction is not checked — DDA checks it on the
real geometry (scenes/example_2.py).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable, Optional

import numpy as np

from .blocks import BlockSystem, Mode, ModeKind, _parallel_sets, group_faces, rigid_modes
from .toppling import toppling_check

#: Velocity tolerance of the mechanism checks, relative to the fastest member [-].
VELOCITY_TOL = 1e-7
#: Bracket of the strength-reduction factor F searched for K(F) = 0 [-].
F_MIN, F_MAX = 1e-3, 1e3
#: Largest friction angle tried in critical-friction searches [degrees].
PHI_MAX = 89.9
#: Points of the root scan where the pencil of ``_pencil_roots`` does not apply, over the
#: bracket and around each near-singular point of the equilibrium [-].
SCAN_SAMPLES, POLE_SAMPLES = 48, 32
#: |K| at an accepted root [g]: a crossing with a larger |K| is a pole or a 0/0 point.
ROOT_K_TOL = 1e-6


@dataclass(frozen=True, kw_only=True, eq=False)
class Evaluation:
    """Factor of safety of a group from one evaluator, and the mode that governs it."""

    fs: float
    """Factor of safety [-]: strength-reduction factor at limit equilibrium (inf: no mode)."""
    mode: Mode
    """The governing mode (least safe)."""
    modes: tuple
    """All admissible modes found, least safe first."""
    rejected: tuple = ()
    """Why the modes the evaluator looked for and did not keep are not admissible: one line
    each (a rigid face that would cut into a neighbour, a Sarma mechanism with no root of
    K(F) whose forces are compressive, a group that is not a toppling row, ...)."""


#: Order of mode kinds among modes of equal FS: the simplest mechanism governs a tie (a group
#: sliding on one plane is a rigid slide and a Sarma mechanism with no shear at once).
_KIND_RANK = {ModeKind.LIFTING: 0, ModeKind.SLIDING: 1, ModeKind.ROTATION: 2, ModeKind.SARMA: 3,
              ModeKind.TOPPLING: 4, ModeKind.NONE: 5}


def tie_key(value: float) -> float:
    """The tie rule of every ranking: values equal to 9 significant digits tie (the same plane
    reached by two evaluators, or through two groups, differs only by round-off) [-]."""
    return float(f"{value:.9g}")


def _governing(modes: list[Mode], rejected: list[str] = ()) -> Evaluation:
    # a tie in FS (`tie_key`) goes to the larger critical friction, then the simpler mode
    modes = sorted(modes, key=lambda m: (tie_key(m.fs), -tie_key(m.critical_friction),
                                         _KIND_RANK.get(m.kind, 9)))
    if not modes:
        none = Mode(kind=ModeKind.NONE, fs=math.inf, critical_friction=0.0,
                    sliding_contacts=np.zeros(0, dtype=np.int64))
        return Evaluation(fs=math.inf, mode=none, modes=(), rejected=tuple(rejected))
    return Evaluation(fs=modes[0].fs, mode=modes[0], modes=tuple(modes), rejected=tuple(rejected))


def _with_toppling(system: BlockSystem, blocks: frozenset, removed: frozenset, modes: list[Mode],
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


def evaluate_rigid(system: BlockSystem, blocks: frozenset, removed: frozenset = frozenset()) -> Evaluation:
    """KGM: the group as one rigid body (docs/kgm/method.md §4), and its block toppling."""
    rejected: list[str] = []
    modes = rigid_modes(system, blocks, removed, rejected=rejected)
    return _governing(_with_toppling(system, blocks, removed, modes, rejected), rejected)


def evaluate_sarma(system: BlockSystem, blocks: frozenset, removed: frozenset = frozenset()) -> Evaluation:
    """SKGM: least safe of the rigid modes, the Sarma mechanisms (docs/kgm/method.md §5.3) and
    block toppling."""
    rejected: list[str] = []
    modes = rigid_modes(system, blocks, removed, rejected=rejected)
    if len(blocks) > 1 and not any(m.fs == 0.0 for m in modes):
        found, why = sarma_checks(system, blocks, removed)
        modes += found
        rejected += why
    return _governing(_with_toppling(system, blocks, removed, modes, rejected), rejected)


def critical_friction_of(evaluation: Evaluation) -> float:
    """Critical friction angle of the group [degrees]: the group is at limit equilibrium when
    its least safe mode is, i.e. the largest φc over its admissible modes (§4.6); 0 when no
    mode exists."""
    return max((m.critical_friction for m in evaluation.modes), default=0.0)


# ---------------------------------------------------------------------- Sarma mechanisms
@dataclass(frozen=True, kw_only=True, eq=False)
class _Faces:
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


def _merge_faces(system: BlockSystem, members: list[int], removed: frozenset) -> _Faces:
    pos = {b: i for i, b in enumerate(members)}
    gf = group_faces(system, frozenset(members), removed)
    entries = []  # (a, b, contacts, normal)
    # boundary contacts: pooled per member and direction (parallel contacts of one member give
    # the same kinematic condition whichever non-member they touch)
    for mem in sorted(set(gf.boundary_member.tolist())):
        sel = np.flatnonzero(gf.boundary_member == mem)
        for grp in _parallel_sets(gf.boundary_normal[sel]):
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
        for grp in _parallel_sets(nrm):
            entries.append((i, j, ks[grp], nrm[grp[0]]))
    f = len(entries)
    normal = np.array([e[3] for e in entries]).reshape(f, 2)
    length = np.array([system.contact_length[e[2]].sum() for e in entries])
    cl = np.array([(system.contact_cohesion[e[2]] * system.contact_length[e[2]]).sum() for e in entries])
    tan_phi = np.array([(np.tan(np.radians(system.contact_friction[e[2]])) * system.contact_length[e[2]]).sum()
                        for e in entries]) / np.maximum(length, 1e-300)
    tan_at = None
    if system.contact_barton is not None:
        face_fns = tuple(system.face_tan_function(e[2]) for e in entries)
        tan_at = lambda normal: np.array([f(nk) for f, nk in zip(face_fns, normal)])  # noqa: E731
    return _Faces(a=np.array([e[0] for e in entries], dtype=np.int64),
                  b=np.array([e[1] for e in entries], dtype=np.int64),
                  normal=normal, tangent=np.stack([normal[:, 1], -normal[:, 0]], axis=1) if f else normal,
                  cl=cl, length=length, tan_phi=tan_phi, contacts=tuple(e[2] for e in entries),
                  tan_at=tan_at, members=tuple(members))


def _pos_of(blocks: np.ndarray, pos: dict) -> np.ndarray:
    return np.array([pos[int(b)] for b in blocks])


def _rows(faces: _Faces, n: int, which: str) -> np.ndarray:
    """Kinematic rows: relative velocity of a w.r.t. b along each face's normal or tangent."""
    vec = faces.normal if which == "normal" else faces.tangent
    rows = np.zeros((len(faces.a), 2 * n))
    for k, (a, b) in enumerate(zip(faces.a, faces.b)):
        rows[k, 2 * a:2 * a + 2] = vec[k]
        if b >= 0:
            rows[k, 2 * b:2 * b + 2] = -vec[k]
    return rows


@dataclass(frozen=True, kw_only=True, eq=False)
class _Mechanism:
    velocity: np.ndarray   # (2n,) member velocities, max |v_i| = 1
    closed: np.ndarray     # (f,) bool: face stays in contact
    slip_sign: np.ndarray  # (f,) sign of the slip of a relative to b on closed faces (0: none)


def _mechanisms(faces: _Faces, force: np.ndarray, n: int) -> list[_Mechanism]:
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
        rays = _extreme_rays(nrows)
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
        out.append(_Mechanism(velocity=v, closed=closed, slip_sign=sign))
    return out


def _extreme_rays(a: np.ndarray, tol: float = 1e-9) -> np.ndarray:
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


@dataclass(frozen=True, kw_only=True, eq=False)
class _Statics:
    k: float               # horizontal acceleration K [g] toward the motion
    admissible: bool       # N >= 0 everywhere, unslipped shear within its limit
    normal: np.ndarray     # (f,) normal force of each face [N/m] (0 on open faces)
    why: str = ""          # what is not admissible (tension on a face, shear beyond its limit)


def _system(mech: _Mechanism, faces: _Faces, force: np.ndarray, weight: np.ndarray,
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


def _statics(mech: _Mechanism, faces: _Faces, force: np.ndarray, weight: np.ndarray,
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
    return _Statics(k=float(sol[-1]), admissible=ok, normal=normal, why=why)


def _statics_at(mech: _Mechanism, faces: _Faces, force: np.ndarray, weight: np.ndarray,
                reduction: float, check: bool = True) -> Optional[_Statics]:
    """`_statics` with the faces' own friction: Mohr–Coulomb faces as they are; Barton–Bandis
    faces take tanφ at their normal stress, which the statics give, so the forces are iterated
    to their fixed point (eq. BB6: solve with tanφ, update tanφ(N/L), until it changes by less
    than BARTON_TOL; docs/method/barton_bandis.md)."""
    if faces.tan_at is None:
        return _statics(mech, faces, force, weight, reduction, faces.tan_phi, check=check)
    from .blocks import BARTON_ITERATIONS, BARTON_TOL

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
        return False, f"tension {normal[i] / 1e3:.3g} kN/m on {_face_name(faces, int(closed[i]))}"
    pos = {int(k): i for i, k in enumerate(closed)}
    for j, k in enumerate(stuck):
        limit = faces.cl[k] / reduction + max(normal[pos[int(k)]], 0.0) * tphi[k]
        if abs(sol[len(closed) + j]) > limit * (1 + 1e-9) + tol:
            return False, f"shear beyond its strength on {_face_name(faces, int(k))}"
    return True, ""


def _face_name(faces: _Faces, k: int) -> str:
    """'the face of block a on the stable rock' / 'the joint between blocks a and b'."""
    def name(i: int) -> str:
        return f"block {faces.members[i]}" if faces.members else f"member {i}"
    if faces.b[k] < 0:
        return f"the face of {name(faces.a[k])} on the stable rock"
    return f"the joint between {name(faces.a[k])} and {name(faces.b[k])}"


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


def _root(fn: Callable[[float], float], lo: float, hi: float, tol: float) -> float:
    """Root of a monotone fn on [lo, hi] (fn(lo), fn(hi) of opposite signs): bisection
    accelerated by the Illinois false-position step."""
    flo, fhi = fn(lo), fn(hi)
    side = 0
    for _ in range(200):
        x = (lo * fhi - hi * flo) / (fhi - flo) if fhi != flo else 0.5 * (lo + hi)
        if not lo < x < hi:
            x = 0.5 * (lo + hi)
        fx = fn(x)
        if (fx > 0) == (flo > 0):
            lo, flo = x, fx
            if side == -1:
                fhi *= 0.5
            side = -1
        else:
            hi, fhi = x, fx
            if side == 1:
                flo *= 0.5
            side = 1
        if hi - lo <= tol * max(1.0, abs(x)) or fx == 0:
            break
    return 0.5 * (lo + hi) if fx != 0 else x


def _pencil_roots(affine: Callable[[float], tuple], lo: float, hi: float) -> Optional[list[float]]:
    """Every x in [lo, hi] at which the mechanism balances without an inertia force (K = 0),
    when its equilibrium m(x)·[N, S, K] = rhs(x) is square and affine in x (Mohr–Coulomb faces:
    x = 1/F or tanφ, `_system`); None otherwise.

    By Cramer's rule K(x) = det[m_f(x) | rhs(x)] / det m(x) (m_f: m without K's column). The
    numerator is continuous in x (a polynomial), and its zeros are the roots of K; the zeros
    of the denominator are poles, where K jumps through infinity and changes sign without a
    root. det(P + x·Q) = 0 with P = [m_f | rhs](0) and Q = [m_f | rhs](1) − P is a generalised
    eigenvalue problem: its finite real eigenvalues are all the roots at once, none stepped
    over however close it lies to a pole (docs/kgm/footwall.md §5)."""
    m0, r0 = affine(0.0)
    m1, r1 = affine(1.0)
    mh, rh = affine(0.5)
    if m0.shape[0] != m0.shape[1]:
        return None  # redundant (statically indeterminate) or overdetermined: scan instead
    p = np.column_stack([m0[:, :-1], r0])
    q = np.column_stack([m1[:, :-1], r1]) - p
    half = np.column_stack([mh[:, :-1], rh])
    size = max(float(np.abs(p).max()), float(np.abs(q).max()), 1e-300)
    if np.abs(half - (p + 0.5 * q)).max() > 1e-9 * size:
        return None  # not affine in x
    scale = np.maximum(np.maximum(np.abs(p).max(axis=0), np.abs(q).max(axis=0)), 1e-300)
    p, q = p / scale, q / scale
    # a singular pencil (det ≡ 0 for every x) has no isolated roots: scan instead
    probes = (lo, 0.5 * (lo + hi), hi, 0.37 * lo + 0.63 * hi)
    hadamard = [float(np.prod(np.linalg.norm(p + x * q, axis=0))) for x in probes]
    if all(abs(np.linalg.det(p + x * q)) <= 1e-12 * max(h, 1e-300) for x, h in zip(probes, hadamard)):
        return None
    from scipy.linalg import eigvals

    with np.errstate(all="ignore"):
        w = eigvals(p, -q)
    real = w[np.isfinite(w) & (np.abs(w.imag) <= 1e-9 * np.maximum(1.0, np.abs(w)))].real
    return sorted(float(x) for x in real if lo <= x <= hi)


def _scan_roots(k_of: Callable[[float], float], sigma_of: Callable[[float], float], lo: float, hi: float,
                *, falling: bool) -> list[float]:
    """Roots of K(u) on [lo, hi] where the pencil does not apply (Barton–Bandis faces, a
    statically indeterminate mechanism): the sign changes of K on SCAN_SAMPLES points, and on
    POLE_SAMPLES more points around each point where the equilibrium is closest to singular
    (a local minimum of ``sigma_of``, the smallest singular value of the scaled system): a
    pole of K sits there, and a root beside it crosses zero between two coarse points that
    both see the same sign. Each sign change in the mechanism's direction is refined by
    `_root`; a pole found that way is rejected later (|K| is not small there)."""
    u = np.linspace(lo, hi, SCAN_SAMPLES + 1)
    sig = np.array([sigma_of(v) for v in u])
    extra = []
    for i in range(1, len(u) - 1):
        if np.isfinite(sig[i]) and sig[i] <= sig[i - 1] and sig[i] <= sig[i + 1]:
            extra.append(np.linspace(u[i - 1], u[i + 1], POLE_SAMPLES + 1))
    pts = np.unique(np.concatenate([u] + extra))
    k = np.array([k_of(v) for v in pts])
    out = []
    for i in range(len(pts) - 1):
        a, b = k[i], k[i + 1]
        if not (np.isfinite(a) and np.isfinite(b)):
            continue
        if (a > 0 >= b) if falling else (a < 0 <= b):
            out.append(float(pts[i + 1]) if b == 0 else _root(k_of, float(pts[i]), float(pts[i + 1]), 1e-12))
    return out


def _first_limit(candidates: list[float], k_of: Callable[[float], float], admissible: Callable[[float], tuple],
                 *, falling: bool, name: Callable[[float], str]) -> tuple[Optional[float], list[str]]:
    """The least candidate u at which K crosses zero in the mechanism's direction (falls as F
    grows, rises with φ) with admissible forces, and a note on each crossing rejected (its
    forces: tension on a face, a shear beyond its strength). A candidate where K does not
    cross (a pole, a touch, a removable singularity of K = 0/0) is no limit state."""
    notes = []
    for u in sorted(candidates):
        d = 1e-7 * max(1.0, abs(u))
        a, b, mid = k_of(u - d), k_of(u + d), k_of(u)
        if not (np.isfinite(a) and np.isfinite(b) and np.isfinite(mid)) or abs(mid) > ROOT_K_TOL:
            continue
        if not ((a > 0 > b) if falling else (a < 0 < b)):
            continue
        ok, why = admissible(u)
        if ok:
            return u, notes
        notes.append(f"{name(u)}: {why}")
    return None, notes


def _sigma(m: np.ndarray) -> float:
    """Smallest singular value of m with unit columns (0: singular, a pole of K)."""
    scaled = m / np.maximum(np.linalg.norm(m, axis=0), 1e-300)
    return float(np.linalg.svd(scaled, compute_uv=False)[-1])


def sarma_modes(system: BlockSystem, blocks: frozenset, removed: frozenset = frozenset()) -> list[Mode]:
    """Admissible Sarma mechanisms of a group with their FS, K_c and critical friction angle.

    FS: the least F at which K(F) falls through 0 with admissible forces (Sarma 1979: reduce
    the strength until the critical acceleration vanishes, §5.1–5.2); every root of K is
    found (``_pencil_roots``; docs/kgm/footwall.md §5). K_c = K(1). Critical friction: the φ of
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
    faces = _merge_faces(system, members, removed)
    force = system.block_force[members]
    passive = system.block_passive[members] if system.block_passive is not None else None
    weight = system.block_mass[members] * system.gravity
    modes, notes = [], []
    mechanisms = _mechanisms(faces, force, n)
    if not mechanisms:
        notes.append("no Sarma mechanism: the members cannot move apart on their faces without cutting "
                     "into a neighbour, or the active forces do not drive them")
    lo, hi = math.log(F_MIN), math.log(F_MAX)
    for mech in mechanisms:
        label = _mechanism_label(mech, faces)

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
            return _sigma(_system(_m, faces, _loaded(force, passive, _m, f), weight, f, faces.tan_phi)[0])

        # K(F) falls as F grows where the forces are admissible; outside that range (tension
        # on a face) the linear solution means nothing: find every root, keep the least whose
        # forces are admissible (§5.2)
        roots = _pencil_roots(affine, 1.0 / F_MAX, 1.0 / F_MIN) if faces.tan_at is None else None
        if roots is not None:
            candidates = [-math.log(x) for x in roots if x > 0]
        else:
            candidates = _scan_roots(k_of_u, sigma_of, lo, hi, falling=True)
        u, rejected = _first_limit(candidates, k_of_u, admissible_at_u, falling=True,
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
                          critical_acceleration=(kc.k if kc is not None else math.nan)))
    return modes, notes


def _mechanism_label(mech: _Mechanism, faces: _Faces) -> str:
    """'{0 → 0°, 1 ↓ 310°}'-like: each member and the direction it moves [degrees from +x]."""
    parts = []
    for i, b in enumerate(faces.members):
        v = mech.velocity[2 * i:2 * i + 2]
        parts.append(f"block {b} at {math.degrees(math.atan2(v[1], v[0])) % 360:.0f}°")
    return "(" + ", ".join(parts) + ")"


def _loaded(force: np.ndarray, passive: Optional[np.ndarray], mech: _Mechanism, reduction: float) -> np.ndarray:
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


def _mechanism_critical_friction(mech: _Mechanism, faces: _Faces, force: np.ndarray,
                                 weight: np.ndarray) -> Optional[float]:
    """φ of all faces (cohesion held) with K(F = 1) = 0 (§4.6): the least φ at which K rises
    through zero with admissible forces, every root found as for the FS (``_pencil_roots`` in
    x = tanφ, else `_scan_roots`)."""
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
        return _sigma(_system(mech, faces, force, weight, 1.0, tan_of(phi))[0])

    if k_of(0.0) >= 0 and admissible(0.0)[0]:
        return 0.0
    roots = _pencil_roots(affine, 0.0, math.tan(math.radians(PHI_MAX)))
    if roots is not None:
        candidates = [math.degrees(math.atan(x)) for x in roots]
    else:
        candidates = _scan_roots(k_of, sigma_of, 0.0, PHI_MAX, falling=False)
    phi, _ = _first_limit(candidates, k_of, admissible, falling=False, name=lambda v: f"φ = {v:.4g}°")
    if phi is None:
        return 90.0 if k_of(PHI_MAX) < 0 and admissible(PHI_MAX)[0] else None
    return float(phi)
