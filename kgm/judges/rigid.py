"""The rigid judge (KGM, docs/kgm/method.md §2.4, §4): the group glued into one rigid body under
its resultant, limit equilibrium on its admissible modes — lifting, sliding on one face
(parallel contacts pooled), rotation about a vertex — each with its factor of safety, and its
block toppling (`kgm.judges.toppling`); and the block types I–V of Goodman & Shi (§2.3) that
follow from the rigid modes of each block.
"""

from __future__ import annotations

import math
from typing import Optional

import numpy as np

from ..faces import group_faces, has_free_face, is_removable, parallel_sets, pool
from ..kinds import ModeKind
from ..system import ANGLE_TOL, BARTON_ITERATIONS, BARTON_TOL, DISTANCE_TOL, BlockSystem
from .evaluation import Evaluation, Mode, governing
from .toppling import with_toppling


def evaluate_rigid(system: BlockSystem, blocks: frozenset, removed: frozenset = frozenset()) -> Evaluation:
    """KGM: the group as one rigid body (docs/kgm/method.md §4), and its block toppling."""
    rejected: list[str] = []
    modes = rigid_modes(system, blocks, removed, rejected=rejected)
    return governing(with_toppling(system, blocks, removed, modes, rejected), rejected)


def rigid_modes(system: BlockSystem, blocks: frozenset, removed: frozenset = frozenset(),
                rejected: Optional[list] = None) -> list[Mode]:
    """Admissible modes of the group glued into one rigid body under its resultant
    (docs/kgm/method.md §2.4 and §4; the original KGM evaluator).

    * lifting: the resultant r opens every contact (r·n_k > 0): FS = 0;
    * sliding on face i (contacts sharing one normal direction, pooled): r presses on it and
      its projection s on the face penetrates no other contact: FS = (Σ c·L + N' tanφ)/T with
      N' = −r·n_i and T = r·s (§4.2, force ratio = strength-reduction FS for one plane);
    * rotation about a vertex V of the contact set: the rigid rotation makes no contact point
      penetrate and the moment of r about V drives it (§4.5): FS = 0, as faces that open carry
      no tension.

    Returns every admissible mode (an empty list: no mode, the group is stable by geometry);
    ``rejected``, a list, receives one line saying why the faces and pivots tried are not
    admissible.
    """
    faces = group_faces(system, blocks, removed)
    members = np.array(sorted(blocks))
    r = system.block_force[members].sum(axis=0)
    m0 = float(system.block_moment[members].sum())
    rnorm = float(np.hypot(*r))
    if rnorm == 0.0:
        return []
    # passive bolt force: a resistance mobilised by the motion (docs/method/water_bolts.md, B2)
    passive = (system.block_passive[members].sum(axis=0) if system.block_passive is not None
               else np.zeros(2))
    n = faces.boundary_normal
    idx = faces.boundary
    modes: list[Mode] = []
    rn = n @ r
    if len(idx) == 0 or np.all(rn > ANGLE_TOL * rnorm):
        d = r / rnorm
        modes.append(Mode(kind=ModeKind.LIFTING, fs=max(-float(passive @ d), 0.0) / rnorm,
                          critical_friction=90.0, sliding_contacts=np.zeros(0, np.int64), direction=d))
        return modes
    if np.all(rn >= -ANGLE_TOL * rnorm):
        # r lies on the edge of the joint pyramid: the group moves along r, sliding without
        # normal force on the contacts parallel to r (e.g. down a vertical slot); only their
        # cohesion (and passive bolts) resist (§4.2 with N' = 0)
        k = idx[np.abs(rn) <= ANGLE_TOL * rnorm]
        cl = pool(system, k).cl - float(passive @ (r / rnorm))
        modes.append(Mode(kind=ModeKind.SLIDING, fs=cl / rnorm, critical_friction=90.0 if cl < rnorm else 0.0,
                          sliding_contacts=k, direction=r / rnorm))
        return modes
    # faces: contacts grouped by normal direction (parallel faces slide together, §2.4 item 2)
    not_pressed, cut_in = 0, []
    for face in parallel_sets(n):
        ni = n[face[0]]
        normal_force = -float(r @ ni)
        if normal_force <= ANGLE_TOL * rnorm:
            not_pressed += 1
            continue
        s = r + normal_force * ni
        snorm = float(np.hypot(*s))
        if snorm <= ANGLE_TOL * rnorm:
            not_pressed += 1
            continue  # r is normal to the face: no driving shear
        s /= snorm
        others = np.setdiff1d(np.arange(len(idx)), face)
        into = others[n[others] @ s < -ANGLE_TOL]
        if len(into):
            dip = math.degrees(math.atan2(-ni[0], ni[1]))  # the face's dip, + toward +x
            cut_in.append(f"on the face dipping {abs(dip):.0f}° would cut into block "
                          f"{int(faces.boundary_other[into[0]])}")
            continue
        k = idx[face]
        # B2: the passive force's normal part presses the face (N' grows by −P·n), its part
        # against the motion (−P·s) adds to the resisting shear
        fs, phi_c = _sliding_fs(system, k, normal_force - float(passive @ ni), snorm,
                                resisting=-float(passive @ s))
        kc = _sliding_kc(system, members, k, ni, s, r + passive)
        modes.append(Mode(kind=ModeKind.SLIDING, fs=fs, critical_friction=phi_c, sliding_contacts=k,
                          direction=s, critical_acceleration=kc))
    held = None
    if system.block_passive_moment is not None:
        held = (passive, float(system.block_passive_moment[members].sum()))
    found = _toppling_pivot(system, idx, n, r, m0, held)
    if found is not None:
        pivot, fs_rot = found
        modes.append(Mode(kind=ModeKind.ROTATION, fs=fs_rot, critical_friction=90.0 if fs_rot < 1.0 else 0.0,
                          sliding_contacts=np.zeros(0, np.int64), pivot=pivot))
    if rejected is not None:
        why = [f"sliding {c}" for c in cut_in]
        if not_pressed:
            why.append(f"{not_pressed} face(s) not pressed by the resultant")
        if found is None:
            why.append("no pivot about which it can rotate")
        rejected.append(("rigid (one body): " if len(members) > 1 else "rigid: ") + "; ".join(why))
    return modes


def _sliding_fs(system: BlockSystem, contacts: np.ndarray, normal_force: float, shear: float,
                resisting: float = 0.0) -> tuple[float, float]:
    """FS and critical friction angle of rigid sliding on pooled contacts (§4.2, §4.6), with
    a resisting shear of passive bolts ``resisting`` [N/m] (B2).

    The normal force is spread over the pooled segments in proportion to their lengths
    (uniform normal stress), so the face's friction is the length-weighted mean of tanφ.
    """
    cl = pool(system, contacts).cl
    normal_force = max(normal_force, 0.0)
    # Barton–Bandis: the friction of the face's own normal stress N'/ΣL, which rigid sliding
    # fixes whatever the strength, so FS is the force ratio at it (eq. BB4–BB5)
    tan_phi = system.face_tan(contacts, normal_force)
    fs = (cl + normal_force * tan_phi + resisting) / shear
    # tan φc = (T − c·L − P_s)/N'  (§4.6); 0 if cohesion (and bolts) alone hold the face
    excess = shear - cl - resisting
    tan_c = excess / normal_force if normal_force > 0 else (math.inf if excess > 0 else 0.0)
    return fs, (float(np.degrees(np.arctan(tan_c))) if tan_c > 0 else 0.0)


def _sliding_kc(system: BlockSystem, members: np.ndarray, contacts: np.ndarray, n: np.ndarray,
                s: np.ndarray, r: np.ndarray) -> float:
    """Sarma's critical acceleration of a rigid sliding mode (§5.2 with one block):
    r + K·W·e + N·n − (c·L + N tanφ)·s = 0, e horizontal toward the motion; solved for N, K."""
    weight = float(system.block_mass[members].sum()) * system.gravity
    e = np.array([1.0 if s[0] >= 0 else -1.0, 0.0])
    cl = pool(system, contacts).cl
    tan_phi = system.face_tan(contacts, -float(r @ n))
    for _ in range(BARTON_ITERATIONS if system.contact_barton is not None else 1):
        a = np.column_stack([n - tan_phi * s, weight * e])
        try:
            sol = np.linalg.solve(a, -r + cl * s)
        except np.linalg.LinAlgError:
            return float("nan")
        if system.contact_barton is None:
            break
        # Barton–Bandis: N depends on K; iterate tan φ(N/ΣL) to its fixed point (eq. BB6)
        new = system.face_tan(contacts, float(sol[0]))
        if abs(new - tan_phi) <= BARTON_TOL * (1.0 + abs(tan_phi)):
            break
        tan_phi = new
    return float(sol[1])


def _toppling_pivot(system: BlockSystem, idx: np.ndarray, n: np.ndarray, r: np.ndarray,
                    m0: float, passive: Optional[tuple] = None) -> Optional[tuple[np.ndarray, float]]:
    """A vertex V of the contact set about which the rigid rotation is admissible (no contact
    end point moves into its neighbour) and driven by the moment of r (§4.5), with its factor
    of safety FS_rot = M_resisting/|M_V|; or None. Faces that open carry nothing, so only
    passive bolts resist (``passive`` = their resultant P and moment about the origin M_P;
    docs/method/water_bolts.md, B2): M_resisting = −sign(ω)·(M_P − V × P). Without them every
    admissible pivot has FS 0 and the first is returned; with them, the least safe."""
    if len(idx) == 0:
        return None
    ends = np.concatenate([system.contact_start[idx], system.contact_end[idx]])
    normals = np.concatenate([n, n])
    tol = DISTANCE_TOL * system.scale
    rnorm = float(np.hypot(*r))
    candidates = _unique_points(ends, tol)
    best = None
    for v in candidates:
        moment = m0 - (v[0] * r[1] - v[1] * r[0])  # moment of r about V
        if abs(moment) <= 1e-9 * rnorm * system.scale:
            continue
        omega = 1.0 if moment > 0 else -1.0
        d = ends - v
        vel = omega * np.stack([-d[:, 1], d[:, 0]], axis=1)
        if np.all((vel * normals).sum(axis=1) >= -tol):
            fs = 0.0
            if passive is not None:
                p, mp = passive
                fs = max(-omega * (mp - (v[0] * p[1] - v[1] * p[0])), 0.0) / abs(moment)
            if best is None or fs < best[1]:
                best = (v, fs)
            if fs == 0.0:
                break
    return best


def _unique_points(p: np.ndarray, tol: float) -> np.ndarray:
    out: list[np.ndarray] = []
    for q in p:
        if not any(np.hypot(*(q - o)) <= tol for o in out):
            out.append(q)
    return np.array(out)


# ---------------------------------------------------------------------- block types
BLOCK_TYPES = ("I", "II", "III", "IV", "V")


def block_type(system: BlockSystem, block: int, removed: frozenset = frozenset(),
               modes: Optional[list[Mode]] = None) -> str:
    """Goodman–Shi type of one block (docs/kgm/method.md §2.3) from block theory (rigid modes):

    V fixed (infinite); IV not removable (tapered or locked, or no free face); III removable
    with no failure mode under its resultant; II removable with a mode and FS ≥ 1; I key block
    (FS < 1).
    """
    if system.block_fixed[block]:
        return "V"
    g = frozenset([block])
    if not has_free_face(system, g, removed) or not is_removable(system, g, removed):
        return "IV"
    modes = rigid_modes(system, g, removed) if modes is None else modes
    if not modes:
        return "III"
    return "I" if min(m.fs for m in modes) < 1.0 else "II"


def classify_blocks(system: BlockSystem, removed: frozenset = frozenset()) -> dict[int, str]:
    """Type I–V of every remaining block (removed blocks are left out)."""
    return {b: block_type(system, b, removed) for b in range(system.n_blocks) if b not in removed}
