"""Vectorised geometry of many wedges (the fast path of `kgm.wedges.geometry` and
`kgm.wedges.block_theory`, used by `kgm.wedges.batched`): small-vector algebra over the last
axis, the cone tests of every joint pyramid, vertices by Cramer's rule and face areas by the
divergence theorem (docs/kgm/wedge.md §5).
"""

from __future__ import annotations

import itertools

import numpy as np


def _cross(a, b):
    """Cross products over the last axis (cheaper than np.cross on small vectors)."""
    ax, ay, az = a[..., 0], a[..., 1], a[..., 2]
    bx, by, bz = b[..., 0], b[..., 1], b[..., 2]
    return np.stack([ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx], axis=-1)


def _norm(a):
    return np.sqrt(a[..., 0] * a[..., 0] + a[..., 1] * a[..., 1] + a[..., 2] * a[..., 2])


def _max1(x):
    """Maximum over axis 1 by element-wise maxima of its slices (axis 1 is short)."""
    out = x[:, 0].copy()
    for k in range(1, x.shape[1]):
        np.maximum(out, x[:, k], out=out)
    return out


def _min1(x):
    out = x[:, 0].copy()
    for k in range(1, x.shape[1]):
        np.minimum(out, x[:, k], out=out)
    return out


def _crack_outward(nc, distance, nu, n1, nf, top):
    """(outward normal, offset) of the tension crack half-space, the toe (origin) inside."""
    t = _cross(nu, n1)
    t = t / _norm(t)[..., None]
    t = t * -np.sign(np.einsum("ij,ij->i", t, nf) + 1e-300)[:, None]
    q = top + distance[:, None] * t
    s = np.where(np.einsum("ij,ij->i", nc, -q) < 0, 1.0, -1.0)
    o = nc * s[:, None]
    return o, np.einsum("ij,ij->i", o, q)


class _ConeTests:
    """Finiteness, tapering and vertices of every joint pyramid of a chunk, from the rows'
    cross and triple products computed once: flipping a joint's side flips signs only."""

    def __init__(self, rows: np.ndarray, m: int, has_crack: bool):
        self.rows, self.m, self.has_crack = rows, m, has_crack
        r = rows.shape[1]
        self.pairs = list(itertools.combinations(range(r), 2))
        self.pair_index = {p: k for k, p in enumerate(self.pairs)}
        i, j = (np.array(t) for t in zip(*self.pairs))
        self.cross = _cross(rows[:, i], rows[:, j])                       # (n, P, 3)
        self.norm = _norm(self.cross)
        self.triple = rows @ self.cross.transpose(0, 2, 1)                # (n, R, P)
        self.pi, self.pj = i, j
        scale = np.maximum(_max1(self.norm), 1e-300)
        # rank < 3: every triple product vanishes (the rows share a perpendicular direction)
        self.flat = _max1(np.abs(self.triple).reshape(len(rows), -1)) <= 1e-12 * scale
        self.usable = self.norm > 1e-12
        unit = self.triple / np.where(self.usable, self.norm, 1.0)[:, None]
        free = unit[:, m:]                                                # face, upper, crack: sign +1
        self.free_max, self.free_min = _max1(free), _min1(free)
        self.joint_unit = unit[:, :m]
        jp = list(range(m)) + ([r - 1] if has_crack else [])
        self.jp_rows = jp
        self.jp_minors = (np.stack([((-1) ** k) * np.linalg.det(rows[:, np.delete(jp, k)]) for k in range(4)], axis=1)
                          if len(jp) == 4 else None)

    def nontrivial(self, sign: np.ndarray, tol: float = 1e-10) -> np.ndarray:
        """Does {d: sᵣ rowᵣ·d ≤ 0 for all r} hold a non-zero d? (extreme rays ±(aᵢ × aⱼ))."""
        ps = sign[self.pi] * sign[self.pj]
        up = ps > 0
        plus_max = np.where(up, self.free_max, -self.free_min)
        minus_min = np.where(up, self.free_min, -self.free_max)
        joint = self.joint_unit * (sign[:self.m, None] * ps[None, :])[None]
        plus_max = np.maximum(plus_max, _max1(joint))
        minus_min = np.minimum(minus_min, _min1(joint))
        ray = self.usable & ((plus_max <= tol) | (minus_min >= -tol))
        return self.flat | ray.any(axis=1)

    def jp_empty(self, sign: np.ndarray) -> np.ndarray:
        """The JP of the joints (and crack) with these side signs is the origin alone
        (`_jp_empty`, from the unsigned minors computed once)."""
        if self.jp_minors is None:
            return np.zeros(len(self.rows), bool)
        s = sign[self.jp_rows]
        lam = self.jp_minors * np.array([np.prod(np.delete(s, k)) for k in range(4)])[None]
        return np.all(lam > 1e-12, axis=1) | np.all(lam < -1e-12, axis=1)

    def vertices(self, take, sign, b, size):
        """`_vertices` for the samples ``take`` with these row signs, from the stored
        products: x = (bᵢsᵢ aⱼ×aₖ − bⱼsⱼ aᵢ×aₖ + bₖsₖ aᵢ×aⱼ) / aᵢ·(aⱼ×aₖ) (Cramer, signs cancelled)."""
        r = self.rows.shape[1]
        triples = list(itertools.combinations(range(r), 3))
        ti, tj, tk = (np.array(t) for t in zip(*triples))
        jk = np.array([self.pair_index[(j, k)] for _, j, k in triples])
        ik = np.array([self.pair_index[(i, k)] for i, _, k in triples])
        ij = np.array([self.pair_index[(i, j)] for i, j, _ in triples])
        rows = take[:, None]
        det = self.triple[rows, ti[None], jk[None]]
        good = np.abs(det) > 1e-10
        bs = b * sign[None, :]
        num = (bs[:, ti, None] * self.cross[rows, jk[None]] - bs[:, tj, None] * self.cross[rows, ik[None]]
               + bs[:, tk, None] * self.cross[rows, ij[None]])
        x = num / np.where(good, det, 1.0)[..., None]
        a = self.rows[take] * sign[None, :, None]
        slack = x @ a.transpose(0, 2, 1) - b[:, None, :]
        valid = good & (_max1(slack.transpose(0, 2, 1)) <= 1e-9 * size[:, None])
        return x, valid


def _jp_empty(v: np.ndarray) -> np.ndarray:
    """JP = {d: V d ≥ 0} is the origin alone (Gordan: 0 strictly inside the convex hull of the
    rows; never with three rows or fewer; with four, the null vector of Vᵀ — the signed 3×3
    minors — of one strict sign)."""
    n, r, _ = v.shape
    if r <= 3:
        return np.zeros(n, bool)
    if r != 4:
        raise ValueError("batched block theory handles up to four joint planes")
    minors = np.stack([((-1) ** k) * np.linalg.det(np.delete(v, k, axis=1)) for k in range(4)], axis=1)
    return np.all(minors > 1e-12, axis=1) | np.all(minors < -1e-12, axis=1)


def _size_scale(nf, nu, inward, top, bw, sl) -> np.ndarray:
    n = len(nf)
    if bw is None and sl is None:
        return np.ones(n)
    m = inward.shape[1]
    a = np.concatenate([nf[:, None], nu[:, None], -inward], axis=1)
    b = np.concatenate([np.zeros((n, 1)), np.einsum("ij,ij->i", nu, top)[:, None], np.zeros((n, m))], axis=1)
    verts, valid = _vertices(a, b, np.abs(top[:, 2]))
    h = -nf[:, :2] / np.hypot(nf[:, 0], nf[:, 1])[..., None]
    behind = np.where(valid, ((verts[..., :2] - top[:, None, :2]) @ h[:, :, None])[..., 0], -np.inf).max(axis=1)
    strike = np.stack([h[:, 1], -h[:, 0]], axis=1)
    along = (verts[..., :2] @ strike[:, :, None])[..., 0]
    extent = np.where(valid, along, -np.inf).max(axis=1) - np.where(valid, along, np.inf).min(axis=1)
    scale = np.ones(n)
    if bw is not None:
        scale = np.minimum(scale, np.where(behind > bw, bw / np.maximum(behind, 1e-300), 1.0))
    if sl is not None:
        scale = np.minimum(scale, np.where(extent > sl, sl / np.maximum(extent, 1e-300), 1.0))
    return scale


def _vertices(a, b, size):
    """Vertices of {x: A x ≤ b} by Cramer's rule on every triple of planes: (n, T, 3) points and
    the (n, T) mask of those that solve their triple and satisfy every other plane."""
    r = a.shape[1]
    triples = list(itertools.combinations(range(r), 3))
    i, j, k = (np.array(t) for t in zip(*triples))
    ai, aj, ak = a[:, i], a[:, j], a[:, k]
    cjk, cki, cij = _cross(aj, ak), _cross(ak, ai), _cross(ai, aj)
    det = np.einsum("nti,nti->nt", ai, cjk)
    good = np.abs(det) > 1e-10
    safe = np.where(good, det, 1.0)
    x = (b[:, i, None] * cjk + b[:, j, None] * cki + b[:, k, None] * cij) / safe[..., None]
    slack = x @ a.transpose(0, 2, 1) - b[:, None, :]
    valid = good & (_max1(slack.transpose(0, 2, 1)) <= 1e-9 * size[:, None])
    return x, valid


_EDGES: dict = {}


def _face_areas(a, b, verts, valid):
    """(n, R) area of each plane's face (0 if it does not bound the block), by the divergence
    theorem in the face's plane: A_f = ½ Σ_g L_fg h_fg over its edges (f, g), L_fg the edge's
    length (the farthest pair of valid vertices on planes f and g) and h_fg the distance from
    the foot of the origin on f to the edge's line — no sorting of vertices."""
    n, r, _ = a.shape
    if r not in _EDGES:
        triples = list(itertools.combinations(range(r), 3))
        _EDGES[r] = [((f, g), [t for t, tri in enumerate(triples) if f in tri and g in tri])
                     for f, g in itertools.combinations(range(r), 2)]
    out = np.zeros((n, r))
    for (f, g), idx in _EDGES[r]:
        p, ok = verts[:, idx], valid[:, idx]
        length = np.zeros(n)
        for s, t in itertools.combinations(range(len(idx)), 2):
            dist = _norm(p[:, s] - p[:, t])
            length = np.maximum(length, np.where(ok[:, s] & ok[:, t], dist, 0.0))
        cos = np.einsum("ni,ni->n", a[:, f], a[:, g])
        sin = np.sqrt(np.maximum(1.0 - cos * cos, 0.0))
        with np.errstate(divide="ignore", invalid="ignore"):
            # distance, in plane f, from b_f·a_f to the line a_g·x = b_g (and symmetrically)
            h_f = np.where(sin > 1e-12, (b[:, g] - b[:, f] * cos) / sin, 0.0)
            h_g = np.where(sin > 1e-12, (b[:, f] - b[:, g] * cos) / sin, 0.0)
        out[:, f] += 0.5 * length * h_f
        out[:, g] += 0.5 * length * h_g
    return out
