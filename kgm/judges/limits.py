"""Root and sign searches of the limit-equilibrium judges, and their bounds (one home for
both): the strength-reduction factor F is searched in [F_MIN, F_MAX], the critical friction
angle in [0, PHI_MAX] (docs/kgm/method.md §4.6, docs/kgm/footwall.md §5).

* `pencil_roots` – every root of Sarma's K(x) at once, where the equilibrium is square and
  affine in x (x = 1/F or tanφ): the real eigenvalues of a matrix pencil;
* `scan_roots` – the sign changes of K where it is not (Barton–Bandis faces, indeterminate
  mechanisms), refined by `root` (Illinois false position);
* `first_limit` – the least root at which K crosses zero the mechanism's way with admissible
  forces;
* `bisect` – where a verdict turns from False to True (the toppling row's F and φc).
"""

from __future__ import annotations

from typing import Callable, Optional

import numpy as np

#: Bracket of the strength-reduction factor F searched for a limit state [-].
F_MIN, F_MAX = 1e-3, 1e3
#: Largest friction angle tried in critical-friction searches [degrees].
PHI_MAX = 89.9
#: Points of the root scan where the pencil of `pencil_roots` does not apply, over the
#: bracket and around each near-singular point of the equilibrium [-].
SCAN_SAMPLES, POLE_SAMPLES = 48, 32
#: Largest absolute K at an accepted root [g]: a crossing with a larger one is a pole or a 0/0 point.
ROOT_K_TOL = 1e-6
#: Steps of `bisect` [-].
BISECTION_STEPS = 64


def root(fn: Callable[[float], float], lo: float, hi: float, tol: float) -> float:
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


def pencil_roots(affine: Callable[[float], tuple], lo: float, hi: float) -> Optional[list[float]]:
    """Every x in [lo, hi] at which the mechanism balances without an inertia force (K = 0),
    when its equilibrium m(x)·[N, S, K] = rhs(x) is square and affine in x (Mohr–Coulomb faces:
    x = 1/F or tanφ, `kgm.judges.sarma`); None otherwise.

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


def scan_roots(k_of: Callable[[float], float], sigma_of: Callable[[float], float], lo: float, hi: float,
                *, falling: bool) -> list[float]:
    """Roots of K(u) on [lo, hi] where the pencil does not apply (Barton–Bandis faces, a
    statically indeterminate mechanism): the sign changes of K on SCAN_SAMPLES points, and on
    POLE_SAMPLES more points around each point where the equilibrium is closest to singular
    (a local minimum of ``sigma_of``, the smallest singular value of the scaled system): a
    pole of K sits there, and a root beside it crosses zero between two coarse points that
    both see the same sign. Each sign change in the mechanism's direction is refined by
    `root`; a pole found that way is rejected later (K is not small there)."""
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
            out.append(float(pts[i + 1]) if b == 0 else root(k_of, float(pts[i]), float(pts[i + 1]), 1e-12))
    return out


def first_limit(candidates: list[float], k_of: Callable[[float], float], admissible: Callable[[float], tuple],
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


def smallest_singular(m: np.ndarray) -> float:
    """Smallest singular value of m with unit columns (0: singular, a pole of K)."""
    scaled = m / np.maximum(np.linalg.norm(m, axis=0), 1e-300)
    return float(np.linalg.svd(scaled, compute_uv=False)[-1])


def bisect(stands, lo: float, hi: float) -> float:
    """The point in [lo, hi] where ``stands(x)`` turns from False (at lo) to True (at hi)."""
    for _ in range(BISECTION_STEPS):
        mid = 0.5 * (lo + hi)
        if stands(mid):
            hi = mid
        else:
            lo = mid
    return 0.5 * (lo + hi)
