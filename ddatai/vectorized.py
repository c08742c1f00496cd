"""Vectorised NumPy contact detection and contact vectors, for small models.

A Taichi kernel launch costs ~0.3–0.5 ms of Python-side argument passing whatever the work,
so on a model of a few blocks the four or five launches of ``ddatai.contacts.detect_contacts``
and ``ddatai.assembly.contact_vectors`` cost more than the geometry itself. This module does the
same work in whole-array NumPy operations, with no Python loop over blocks, vertices or
contacts, and no Taichi:

- `broad_phase`: all block pairs (i < j, not both fixed) whose boxes, enlarged by margin/2,
  overlap, by a sweep along x (sort, then each box against the boxes that start within it);
- `narrow_phase` (``ddatai.narrow``): Shi's vertex-edge / vertex-vertex rules (docs/method/dda.md
  §3.3–3.6) evaluated over every (vertex, vertex) and (vertex, edge) candidate of every block
  pair at once, operation for operation as `ddatai.kernels.narrow_phase` (the same guards
  ``EDGE_FLOOR`` and ``TIE``, the same mutual-nearest-vertex rule, the same entrance-angle
  test), so that it returns the same contacts, kinds, lines and lengths;
- `detect_contacts`: both, in the canonical order of ``ddatai.contacts.sort_contacts``;
- `contact_vectors`: the normal and shear vectors of every contact line (§2.8.1–2.8.4), as
  `ddatai.kernels.contact_vectors`.

``tests/test_vectorized.py`` compares every function with the kernel path;
``benchmarks/detection.py`` times both and finds the block count where the kernels win.
"""

from __future__ import annotations

import numpy as np

from .contacts import box_bounds
from .layout import N_SLOTS, S_ES, S_GS, VE, VV
from .model import Model
# the narrow phase and its guards (re-exported: `vectorized.narrow_phase`, ``EDGE_FLOOR`` …)
from .narrow import EDGE_FLOOR, SLACK, TIE, TWO_PI, NarrowCache, _expand, narrow_phase  # noqa: F401

# --------------------------------------------------------------------------- broad phase
def broad_phase(model: Model, vertex_xy: np.ndarray, margin: float) -> np.ndarray:
    """Candidate block pairs (i < j, not both fixed) whose boxes, enlarged by margin/2, overlap.

    Returns a (P, 2) int32 array sorted by (i, j), as ``ddatai.contacts.broad_phase``.
    """
    lo, hi = box_bounds(model, vertex_xy, 0.5 * margin)
    nb = len(lo)
    if nb < 2:
        return np.zeros((0, 2), np.int32)
    # sweep along x: with the boxes sorted by their left side, box a meets in x exactly the
    # boxes after it whose left side is at most a's right side (a's left side is at most
    # theirs, hence at most their right side)
    order = lo[:, 0].argsort(kind="stable")
    left = lo[order, 0]
    count = left.searchsorted(hi[order, 0], side="right") - np.arange(1, nb + 1)
    first, rank = _expand(np.maximum(count, 0))
    a, b = order[first], order[first + 1 + rank]
    fixed = model.block_fixed
    hit = (lo[a, 1] <= hi[b, 1]) & (lo[b, 1] <= hi[a, 1]) & ~(fixed[a] & fixed[b])
    a, b = a[hit], b[hit]
    i, j = np.minimum(a, b), np.maximum(a, b)
    o = np.lexsort((j, i))
    out = np.empty((len(o), 2), np.int32)
    out[:, 0], out[:, 1] = i[o], j[o]
    return out


def detect_contacts(model: Model, vertex_xy: np.ndarray, cache: NarrowCache | None = None,
                    last_keys: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Broad + narrow phase in NumPy. Returns (cint, length) in canonical order, as
    ``ddatai.contacts.detect_contacts``. ``cache`` keeps the candidate pairs (a Verlet list,
    ``ddatai.contacts.PairList``) and the pairs' candidates between calls (``ddatai.narrow.NarrowCache``).
    ``last_keys``: the sorted keys of the last step's contacts (``ContactMemory.key``), which
    keep a corner pair's hand-over to the vertex-edge rules (``narrow.narrow_phase``)."""
    if cache is None:
        return narrow_phase(model, vertex_xy, broad_phase(model, vertex_xy, model.search_distance), None, last_keys)
    return narrow_phase(model, vertex_xy, cache.pair_list.pairs(model, vertex_xy, broad_phase), cache, last_keys)


# --------------------------------------------------------------------------- contact vectors
def _trow(a: np.ndarray, b: np.ndarray, X0: np.ndarray, X1: np.ndarray) -> np.ndarray:
    """a·row 1 + b·row 2 of T(X) (docs/method/dda.md §1.1) at centroidal points X = (X0, X1),
    as (n, 6) (`kernels._trow`)."""
    out = np.empty((len(a), 6))
    out[:, 0] = a
    out[:, 1] = b
    out[:, 2] = b * X0 - a * X1
    out[:, 3] = a * X0
    out[:, 4] = b * X1
    out[:, 5] = 0.5 * (a * X1 + b * X0)
    return out


def contact_vectors(model: Model, vertex_xy: np.ndarray, centroid: np.ndarray, cint: np.ndarray,
                    omega: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Linearised normal and shear distances of every contact line (docs/method/dda.md
    §2.8.1–2.8.4), as `ddatai.kernels.contact_vectors`: ``vec`` (m, N_SLOTS, 6) by
    `ddatai.layout` slot and ``sca`` (m, 3) = (dn0 line 0, dn0 line 1, ds0). Positions are
    taken relative to the contact vertex P1 so that the constant parts keep full precision."""
    m = len(cint)
    vec = np.zeros((m, N_SLOTS, 6))
    sca = np.zeros((m, 3))
    if not m:
        return vec, sca
    nxt, vblock = model.vertex_next, model.vertex_block
    centroid = np.asarray(centroid)
    # every line: line 0 of each contact, then line 1 of each vertex-vertex contact
    vv = (cint[:, 0] == VV).nonzero()[0]
    ve = (cint[:, 0] == VE).nonzero()[0]  # line 0 of contact c is line c
    p1 = np.concatenate([cint[:, 1], cint[vv, 3]])
    k = np.concatenate([cint[:, 2], cint[vv, 4]])
    n = len(p1)
    P1 = vertex_xy[p1]
    x2 = vertex_xy[nxt[k]] - P1
    x3 = vertex_xy[k] - P1
    s = x3 - x2
    l = np.sqrt(s[:, 0] * s[:, 0] + s[:, 1] * s[:, 1])
    cj = centroid[vblock[k]]
    X1, X2, X3 = P1 - centroid[vblock[p1]], x2 + P1 - cj, x3 + P1 - cj
    dn0 = (x2[:, 0] * x3[:, 1] - x2[:, 1] * x3[:, 0]) / l
    sca[:, 0] = dn0[:m]
    sca[vv, 1] = dn0[m:]
    # the coefficients of the rows of T at P1, P2, P3, for all lines in one batch: ∂Δ/∂P1,
    # ∂Δ/∂P2, ∂Δ/∂P3 with P1 at the origin, and for line 0 of a vertex-edge contact the
    # derivatives of ds = (P1 − P0)·(P3 − P2)/l with P0 = (1 − ω)P2 + ωP3 (§2.8.3)
    x2x, x2y, x3x, x3y = x2[:, 0], x2[:, 1], x3[:, 0], x3[:, 1]
    a = [x2y - x3y, x3y, -x2y]
    b = [x3x - x2x, -x3x, x2x]
    at = [X1, X2, X3]
    if len(ve):
        w = omega[ve]
        x2x, x2y, x3x, x3y, sx, sy, le = x2x[ve], x2y[ve], x3x[ve], x3y[ve], s[ve, 0], s[ve, 1], l[ve]
        sca[ve, 2] = ((-(1.0 - w) * x2x - w * x3x) * sx + (-(1.0 - w) * x2y - w * x3y) * sy) / le
        a += [sx / le, (2.0 * (1.0 - w) * x2x - (1.0 - 2.0 * w) * x3x) / le,
              (-(1.0 - 2.0 * w) * x2x - 2.0 * w * x3x) / le]
        b += [sy / le, (2.0 * (1.0 - w) * x2y - (1.0 - 2.0 * w) * x3y) / le,
              (-(1.0 - 2.0 * w) * x2y - 2.0 * w * x3y) / le]
        at += [X1[ve], X2[ve], X3[ve]]
    X = np.concatenate(at)
    rows = _trow(np.concatenate(a), np.concatenate(b), X[:, 0], X[:, 1])
    li = l[:, None]
    e_vec = rows[:n] / li
    g_vec = (rows[n:2 * n] + rows[2 * n:3 * n]) / li
    vec[:, 0], vec[:, 1] = e_vec[:m], g_vec[:m]
    vec[vv, 2], vec[vv, 3] = e_vec[m:], g_vec[m:]
    if len(ve):
        nve = len(ve)
        vec[ve, S_ES] = rows[3 * n:3 * n + nve]
        vec[ve, S_GS] = rows[3 * n + nve:3 * n + 2 * nve] + rows[3 * n + 2 * nve:]
    return vec, sca
