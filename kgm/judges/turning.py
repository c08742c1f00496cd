"""The group turning as one body while it slides on two points (docs/kgm/footwall.md §9).

Where no translation of a group — no rigid slide, no Sarma mechanism — balances its moments at
its limit (`kgm.judges.sarma.unbalanced_moment`, `slide_balances`), the group does not
translate: it turns. On the steep
bilinear footwall slabs the slab's lower end lifts off the bedding and the pair turns as one
body, its upper end K sliding down the bedding and the toe block's kink B sliding out along J1
(DDA shows it). Such a rigid motion keeps contact at two points, each sliding on its own face:
its instantaneous centre O is where the two faces' normals through the points meet, and every
other contact opens.

Limit equilibrium of the mode, at the strength tanφ/F: the rock pushes on each point with
N_k·n_k − μ_k·N_k·t_k (μ_k = tanφ_k/F, t_k the point's slip direction); the faces that open
carry nothing and a point has no length, so no cohesion. The normal forces pass through O, so
the force balance r + Σ N_k (n_k − μ_k t_k) = 0 gives N_1, N_2, and the moment about O,

    g(F) = M_O + Σ_k (p_k − O) × (−μ_k N_k t_k) = 0,

with M_O the moment of the active forces about O, gives F. The factor is the least F in
[F_MIN, F_MAX] at which g falls through zero with both N_k ≥ 0, found as the two-block closed
form finds its roots (a fine logarithmic scan refined by bisection); a mode that turns with
compressive forces even at F_MIN has FS 0, as the rigid rotation about a vertex (§4.5 of
docs/kgm/method.md). Every pair of contact points whose motion moves no contact point into its
neighbour is tried, and the least safe is kept.
"""

from __future__ import annotations

import math
from typing import Optional

import numpy as np

from ..faces import group_faces
from ..kinds import ModeKind
from ..system import ANGLE_TOL, DISTANCE_TOL, BlockSystem
from .evaluation import Mode
from .limits import F_MAX, F_MIN

#: Points of the logarithmic scan of F for the turning mode's roots [-].
SCAN_POINTS = 400


def turning_mode(system: BlockSystem, blocks: frozenset, removed: frozenset = frozenset()) -> Optional[Mode]:
    """The least safe rigid turning of the group on two sliding contact points (the module
    docstring), or None where no pair of points admits one. Its ``pivot`` is the instantaneous
    centre O, ``sliding_contacts`` the two contacts; ``critical_friction`` atan(tanφ/FS) of the
    two points' mean tanφ (exact for one friction angle, as there is no cohesion)."""
    faces = group_faces(system, blocks, removed)
    members = np.array(sorted(blocks))
    r = system.block_force[members].sum(axis=0)
    m0 = float(system.block_moment[members].sum())
    if len(faces.boundary) < 2 or float(np.hypot(*r)) == 0.0:
        return None
    idx = faces.boundary
    ends = np.concatenate([system.contact_start[idx], system.contact_end[idx]])
    normals = np.concatenate([faces.boundary_normal, faces.boundary_normal])
    contact = np.concatenate([idx, idx])
    tol = DISTANCE_TOL * system.scale
    # one entry per distinct (point, face direction)
    keep: list[int] = []
    for i in range(len(ends)):
        if not any(np.hypot(*(ends[i] - ends[j])) <= tol and abs(_cross(normals[i], normals[j])) <= ANGLE_TOL
                   for j in keep):
            keep.append(i)
    best: Optional[Mode] = None
    for a_i, i in enumerate(keep):
        for j in keep[a_i + 1:]:
            if np.hypot(*(ends[i] - ends[j])) <= tol or abs(_cross(normals[i], normals[j])) <= ANGLE_TOL:
                continue  # one point: a pivot (the rigid rotation); parallel normals: a translation
            mode = _pair(system, r, m0, ends, normals, contact, i, j, tol)
            if mode is not None and (best is None or mode.fs < best.fs):
                best = mode
    return best


def slide_balances(system: BlockSystem, blocks: frozenset, mode: Mode) -> bool:
    """Whether a rigid slide of the group (``mode``, kind SLIDING) balances its moment at its
    limit: the face's reaction, −r at the limit, must act at a point of the face (the line of r
    must cross the face between its ends; several pooled contacts share it in any proportion, so
    any point between their extreme ends will do)."""
    members = np.array(sorted(blocks))
    r = system.block_force[members].sum(axis=0)
    m0 = float(system.block_moment[members].sum())
    k = np.asarray(mode.sliding_contacts, dtype=np.int64)
    if len(k) == 0:
        return True
    ends = np.concatenate([system.contact_start[k], system.contact_end[k]])
    arm = ends[:, 0] * r[1] - ends[:, 1] * r[0]           # p × r at each end
    tol = 1e-9 * float(np.hypot(*r)) * system.scale
    return bool(arm.min() - tol <= m0 <= arm.max() + tol)


def _pair(system, r, m0, ends, normals, contact, i, j, tol) -> Optional[Mode]:
    """The turning mode on points i and j, if it is admissible and has a limit."""
    p, n = ends[[i, j]], normals[[i, j]]
    a, _ = np.linalg.solve(np.column_stack([n[0], -n[1]]), p[1] - p[0])
    centre = p[0] + a * n[0]
    moment = m0 - _cross(centre, r)                       # M_O: the active forces about O
    if abs(moment) <= 1e-9 * float(np.hypot(*r)) * system.scale:
        return None
    omega = 1.0 if moment > 0 else -1.0
    d = ends - centre
    vel = omega * np.stack([-d[:, 1], d[:, 0]], axis=1)
    if np.any((vel * normals).sum(axis=1) < -tol):
        return None  # a contact point would move into its neighbour
    v = vel[[i, j]]
    speed = np.hypot(v[:, 0], v[:, 1])
    if np.any(speed <= tol):
        return None
    t = v / speed[:, None]
    tan_phi = np.tan(np.radians(system.contact_friction[contact[[i, j]]]))
    arm = p - centre

    def g(f: float) -> tuple[float, np.ndarray]:
        mu = tan_phi / f
        cols = n - mu[:, None] * t
        det = _cross(cols[0], cols[1])
        if abs(det) <= 1e-12:
            return math.nan, np.full(2, math.nan)
        force = np.linalg.solve(cols.T, -r)
        turn = moment + sum(_cross(arm[k], -mu[k] * force[k] * t[k]) for k in range(2))
        return omega * turn, force

    grid = np.exp(np.linspace(math.log(F_MIN), math.log(F_MAX), SCAN_POINTS + 1))
    vals = [g(f) for f in grid]
    fs = None
    for k in range(SCAN_POINTS):
        (g0, _), (g1, _) = vals[k], vals[k + 1]
        if not (math.isfinite(g0) and math.isfinite(g1)) or not (g0 < 0.0 <= g1):
            continue  # held (g < 0) at the lower F, turning (g > 0) at the higher one
        lo, hi = grid[k], grid[k + 1]
        for _ in range(60):
            mid = math.sqrt(lo * hi)
            if g(mid)[0] < 0.0:
                lo = mid
            else:
                hi = mid
        root = math.sqrt(lo * hi)
        turn, force = g(root)
        if abs(turn) <= 1e-6 * abs(moment) + 1.0 and np.all(force >= 0.0):
            fs = root
            break
    if fs is None:
        g0, force = vals[0]
        if not (math.isfinite(g0) and g0 > 0.0 and np.all(force >= 0.0)):
            return None
        fs = 0.0  # turns with compressive contacts even at F_MIN
    phi_c = 90.0 if fs == 0.0 else math.degrees(math.atan(float(tan_phi.mean()) / fs))
    return Mode(kind=ModeKind.ROTATION, fs=fs, critical_friction=phi_c,
                sliding_contacts=np.unique(contact[[i, j]]).astype(np.int64), pivot=centre)


def _cross(a, b) -> float:
    return float(a[0] * b[1] - a[1] * b[0])
