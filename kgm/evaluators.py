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
from .toppling import toppling_mode

#: Velocity tolerance of the mechanism checks, relative to the fastest member [-].
VELOCITY_TOL = 1e-7
#: Bracket of the strength-reduction factor F searched for K(F) = 0 [-].
F_MIN, F_MAX = 1e-3, 1e3
#: Largest friction angle tried in critical-friction searches [degrees].
PHI_MAX = 89.9


@dataclass(frozen=True, kw_only=True, eq=False)
class Evaluation:
    """Factor of safety of a group from one evaluator, and the mode that governs it."""

    fs: float
    """Factor of safety [-]: strength-reduction factor at limit equilibrium (inf: no mode)."""
    mode: Mode
    """The governing mode (least safe)."""
    modes: tuple
    """All admissible modes found, least safe first."""


def _governing(modes: list[Mode]) -> Evaluation:
    modes = sorted(modes, key=lambda m: (m.fs, -m.critical_friction))
    if not modes:
        none = Mode(kind=ModeKind.NONE, fs=math.inf, critical_friction=0.0,
                    sliding_contacts=np.zeros(0, dtype=np.int64))
        return Evaluation(fs=math.inf, mode=none, modes=())
    return Evaluation(fs=modes[0].fs, mode=modes[0], modes=tuple(modes))


def _with_toppling(system: BlockSystem, blocks: frozenset, removed: frozenset, modes: list[Mode]) -> list[Mode]:
    """The modes plus the group's block-toppling mode where its geometry admits one (a row of
    two or more blocks; a single block's toppling is the rigid rotation, §4.5)."""
    if len(blocks) > 1 and not any(m.fs == 0.0 for m in modes):
        mode = toppling_mode(system, blocks, removed)
        if mode is not None:
            modes = modes + [mode]
    return modes


def evaluate_rigid(system: BlockSystem, blocks: frozenset, removed: frozenset = frozenset()) -> Evaluation:
    """KGM: the group as one rigid body (docs/kgm/method.md §4), and its block toppling."""
    return _governing(_with_toppling(system, blocks, removed, rigid_modes(system, blocks, removed)))


def evaluate_sarma(system: BlockSystem, blocks: frozenset, removed: frozenset = frozenset()) -> Evaluation:
    """SKGM: least safe of the rigid modes, the Sarma mechanisms (docs/kgm/method.md §5.3) and
    block toppling."""
    modes = rigid_modes(system, blocks, removed)
    if len(blocks) > 1 and not any(m.fs == 0.0 for m in modes):
        modes += sarma_modes(system, blocks, removed)
    return _governing(_with_toppling(system, blocks, removed, modes))


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
                  tan_at=tan_at)


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


def _statics(mech: _Mechanism, faces: _Faces, force: np.ndarray, weight: np.ndarray,
             reduction: float, tan_phi: np.ndarray, check: bool = True) -> Optional[_Statics]:
    """Forces of the mechanism at the strength (c/F, tanφ/F) and the K that balances them;
    ``check`` also decides whether the forces are admissible (root searches need only K)."""
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
    scale = np.maximum(np.abs(m).max(axis=0), 1e-300)
    sol, *_ = np.linalg.lstsq(m / scale, rhs, rcond=None)
    sol = sol / scale
    if np.linalg.norm(m @ sol - rhs) > 1e-7 * max(np.linalg.norm(rhs), 1.0):
        return None  # no equilibrium with these contacts (e.g. a member with no support)
    if not check:
        normal = np.zeros(len(faces.a))
        normal[closed] = sol[:len(closed)]
        return _Statics(k=float(sol[-1]), admissible=False, normal=normal)
    # K must not depend on the redundant (statically indeterminate) forces
    _, sv, vh = np.linalg.svd(m / scale)
    rank = int(np.sum(sv > 1e-10 * sv[0]))
    if rank < cols and np.any(np.abs(vh[rank:, -1]) > 1e-8):
        return None
    tol = 1e-9 * float(weight.sum())
    ok = _forces_admissible(sol, closed, stuck, faces, tphi, reduction, tol)
    if not ok and rank < cols:
        # statically indeterminate (e.g. members sliding together on one plane): the
        # minimum-norm forces may pull on a face while another distribution does not; look
        # for any admissible one (a small linear feasibility problem)
        alt = _admissible_forces(m, rhs, closed, stuck, faces, tphi, reduction)
        if alt is not None:
            sol, ok = alt, True
    normal = np.zeros(len(faces.a))
    normal[closed] = sol[:len(closed)]
    return _Statics(k=float(sol[-1]), admissible=ok, normal=normal)


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


def _forces_admissible(sol, closed, stuck, faces, tphi, reduction, tol) -> bool:
    """No tension on a closed face; unslipped shear within its Mohr–Coulomb limit (§5.2)."""
    normal = sol[:len(closed)]
    if np.any(normal < -tol):
        return False
    pos = {int(k): i for i, k in enumerate(closed)}
    for j, k in enumerate(stuck):
        limit = faces.cl[k] / reduction + max(normal[pos[int(k)]], 0.0) * tphi[k]
        if abs(sol[len(closed) + j]) > limit * (1 + 1e-9) + tol:
            return False
    return True


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


def _admissible_root(fn: Callable[[float], float], admissible: Callable[[float], bool], lo: float,
                     hi: float, *, increasing: bool = False, samples: int = 48) -> Optional[float]:
    """Root of fn on [lo, hi] where the mechanism's forces are admissible: the sign changes of
    fn on a uniform grid, each refined by `_root`, the first admissible one kept. fn falls
    through the root (increasing=False, K against log F) or rises (K against tanφ)."""
    x = np.linspace(lo, hi, samples + 1)
    f = np.array([fn(v) for v in x])
    for i in range(samples):
        a, b = f[i], f[i + 1]
        if not (np.isfinite(a) and np.isfinite(b)):
            continue
        crosses = (a > 0 >= b) if not increasing else (a < 0 <= b)
        if not crosses:
            continue
        r = x[i + 1] if b == 0 else _root(fn, x[i], x[i + 1], 1e-12)
        if admissible(r):
            return r
    return None


def sarma_modes(system: BlockSystem, blocks: frozenset, removed: frozenset = frozenset()) -> list[Mode]:
    """Admissible Sarma mechanisms of a group with their FS, K_c and critical friction angle.

    FS: the F at which K(F) = 0 (Sarma 1979: reduce the strength until the critical
    acceleration vanishes, §5.1–5.2); K_c = K(1). Critical friction: the φ of all joints
    (cohesion held) at which K_c = 0, by bisection (§4.6). A mechanism whose forces are
    inadmissible (tension on a face) at its solution is dropped (§5.2).
    """
    members = sorted(blocks)
    n = len(members)
    faces = _merge_faces(system, members, removed)
    force = system.block_force[members]
    passive = system.block_passive[members] if system.block_passive is not None else None
    weight = system.block_mass[members] * system.gravity
    modes = []
    for mech in _mechanisms(faces, force, n):
        def k_of_u(u, _m=mech):
            st = _statics_at(_m, faces, _loaded(force, passive, _m, math.exp(u)), weight, math.exp(u),
                             check=False)
            return math.nan if st is None else st.k

        def admissible_at_u(u, _m=mech):
            st = _statics_at(_m, faces, _loaded(force, passive, _m, math.exp(u)), weight, math.exp(u))
            return st is not None and st.admissible

        # K(F) falls as F grows where the forces are admissible; outside that range (tension
        # on a face) the linear solution means nothing, so scan log F for the sign changes and
        # keep the root whose forces are admissible (§5.2)
        u = _admissible_root(k_of_u, admissible_at_u, math.log(F_MIN), math.log(F_MAX))
        if u is not None:
            fs = math.exp(u)
        elif k_of_u(math.log(F_MIN)) <= 0 and admissible_at_u(math.log(F_MIN)):
            fs = 0.0  # fails even with a thousand times the strength
        else:
            continue
        kc = _statics_at(mech, faces, _loaded(force, passive, mech, 1.0), weight, 1.0, check=False)
        phi_c = _mechanism_critical_friction(mech, faces, _loaded(force, passive, mech, 1.0), weight)
        if phi_c is None:
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
    return modes


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
    """φ of all faces (cohesion held) with K(F = 1) = 0, by bisection on φ (§4.6)."""
    def k_of(phi: float) -> float:
        tan_phi = np.full(len(faces.a), math.tan(math.radians(phi)))
        st = _statics(mech, faces, force, weight, 1.0, tan_phi, check=False)
        return math.nan if st is None else st.k

    def admissible(phi: float) -> bool:
        tan_phi = np.full(len(faces.a), math.tan(math.radians(phi)))
        st = _statics(mech, faces, force, weight, 1.0, tan_phi)
        return st is not None and st.admissible

    if k_of(0.0) >= 0 and admissible(0.0):
        return 0.0
    phi = _admissible_root(k_of, admissible, 0.0, PHI_MAX, increasing=True)
    if phi is None:
        return 90.0 if k_of(PHI_MAX) < 0 and admissible(PHI_MAX) else None
    return float(phi)
