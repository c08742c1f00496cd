"""Vectorised wedges: the geometry, block theory and limit equilibrium of many wedges at once
(docs/kgm/wedge.md §5), the fast path beside `kgm.wedges.slope.wedge` (Qhull, linear programs)
that the probabilistic study runs. Same conventions and results (tests compare them).

Per sample: the joint pyramids' finiteness by the exact cone test (extreme rays on pairs of
planes), tapered pyramids by Gordan's alternative (0 in the convex hull of the inward normals:
the signs of the 3×3 minors), the block's vertices by Cramer's rule on every triple of planes,
its faces' areas by the shoelace formula on their angularly sorted vertices, its volume from
the divergence theorem V = ⅓ Σ Aᶠ bᶠ, then the mode analysis of every face and pair of faces
and the least safe admissible mode. Samples are processed in chunks (``CHUNK``) to bound memory.
"""

from __future__ import annotations

import itertools
import math
import os
from dataclasses import dataclass
from typing import Optional

import numpy as np

from .geometry import direction_vector, plane_normal

#: samples per chunk (memory ~ 2 kB a sample)
CHUNK = 16384
#: reason codes of `BatchResult.reason`
REASONS = ("", "not daylighting", "infinite", "tapered", "no volume", "parallel joints", "crack does not cut")
MODES = ("", "falling", "one plane", "two planes", "stable")


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


@dataclass(frozen=True)
class BatchResult:
    """Arrays, one entry per sample."""

    forms: np.ndarray
    reason: np.ndarray
    """Index into `REASONS` (0 where a wedge forms)."""
    fs: np.ndarray
    """Factor of safety (nan where no wedge forms, inf where held, 0 falling)."""
    mode: np.ndarray
    """Index into `MODES`."""
    volume: np.ndarray
    weight: np.ndarray
    normal: np.ndarray
    """(n, m) effective normal force on each joint [N]."""
    sliding: np.ndarray
    """(n, 3) unit sliding direction."""
    height: np.ndarray
    """Height after bench-width / slope-length scaling [m]."""


def evaluate(face_dip, face_dip_direction, upper_dip, upper_dip_direction, height, joint_dip, joint_dip_direction,
             friction, cohesion, *, barton=None, density=2600.0, gravity=9.81, water_fill=None, water_density=1000.0,
             seismic_k=None, seismic_trend=None, seismic_plunge=0.0, active_force=(0.0, 0.0, 0.0),
             passive_force=(0.0, 0.0, 0.0), crack_dip=None, crack_dip_direction=None, crack_distance=None,
             bench_width=None, slope_length=None, height_reference="joint1", workers=None) -> BatchResult:
    """Evaluate n wedges. Scalars broadcast; joint arrays are (n, m) with m = 2 or 3 joints
    (angles in degrees, cohesion in Pa). ``barton``: None or a dict of (n, m) arrays ``jrc``,
    ``jcs`` [Pa], ``residual`` [deg], ``cap`` [deg], ``reduction`` (nan rows: Mohr–Coulomb).
    ``water_fill``: None (dry) or the fill fraction of Hoek & Bray's saturated wedge;
    ``seismic_k``: horizontal coefficient along the static sliding trend (or along
    ``seismic_trend``/``seismic_plunge``). Forces are sums of the active and passive bolts and
    external forces [N]. ``workers`` threads share the chunks (default: the CPUs, at most 4)."""
    jd = np.atleast_2d(np.asarray(joint_dip, dtype=float))
    n = max(jd.shape[0], np.size(height), np.size(face_dip))
    m = jd.shape[-1]
    col = lambda v: None if v is None else np.broadcast_to(np.asarray(v, dtype=float), (n,))   # noqa: E731
    mat = lambda v: np.broadcast_to(np.asarray(v, dtype=float), (n, m))                       # noqa: E731
    data = dict(fd=col(face_dip), fa=col(face_dip_direction), ud=col(upper_dip), ua=col(upper_dip_direction),
                h=col(height), jd=mat(joint_dip), ja=mat(joint_dip_direction), phi=mat(friction), c=mat(cohesion),
                rho=col(density), fill=col(water_fill), k=col(seismic_k), cd=col(crack_dip),
                ca=col(crack_dip_direction), cl=col(crack_distance), bw=col(bench_width), sl=col(slope_length))
    if barton is not None:
        data["bb"] = np.stack([mat(barton[k]) for k in ("jrc", "jcs", "residual", "cap", "reduction")], axis=-1)
    def run(lo: int) -> BatchResult:
        part = {k: (None if v is None else v[lo:lo + CHUNK]) for k, v in data.items()}
        return _chunk(part, m, float(gravity), float(water_density), seismic_trend, float(seismic_plunge),
                      np.asarray(active_force, float), np.asarray(passive_force, float), height_reference)

    starts = list(range(0, n, CHUNK))
    workers = min(len(starts), workers if workers is not None else min(os.cpu_count() or 1, 4))
    if workers > 1:
        # NumPy releases the GIL in its array loops: threads share the chunks without copies
        from concurrent.futures import ThreadPoolExecutor

        with ThreadPoolExecutor(max_workers=workers) as pool:
            out = list(pool.map(run, starts))
    else:
        out = [run(lo) for lo in starts]
    return BatchResult(**{f: np.concatenate([getattr(o, f) for o in out]) for f in BatchResult.__dataclass_fields__})


def _chunk(d, m, g, rho_w, s_trend, s_plunge, f_active, f_passive, ref) -> BatchResult:
    n = len(d["h"])
    nf, nu = plane_normal(d["fd"], d["fa"]), plane_normal(d["ud"], d["ua"])
    nj = plane_normal(d["jd"], d["ja"])                                   # (n, m, 3)
    if ref == "face":
        gline = -direction_vector(d["fa"], d["fd"])
    else:
        gline = _cross(nf, nj[:, 0])
    gline = gline * np.sign(gline[:, 2:3] + (gline[:, 2:3] == 0))
    with np.errstate(divide="ignore", invalid="ignore"):
        top_unit = gline / gline[:, 2:3]                                 # crest point at unit height
    has_crack = d["cd"] is not None
    nc = plane_normal(d["cd"], d["ca"]) if has_crack else None
    res = dict(forms=np.zeros(n, bool), reason=np.zeros(n, np.int8), fs=np.full(n, np.nan),
               mode=np.zeros(n, np.int8), volume=np.zeros(n), weight=np.zeros(n), normal=np.zeros((n, m)),
               sliding=np.full((n, 3), np.nan), height=d["h"].copy())
    i_line = _cross(nj[:, 0], nj[:, 1])
    parallel = _norm(i_line) < 1e-9
    any_finite = np.zeros(n, bool)
    any_tapered = np.zeros(n, bool)
    done = np.zeros(n, bool)
    top = top_unit * d["h"][:, None]
    crack_out = _crack_outward(nc, d["cl"], nu, nj[:, 0], nf, top) if has_crack else None
    # rows of the cone tests without their signs: joints (upward normals), face, upper, crack
    rows = np.concatenate([nj, nf[:, None], nu[:, None]] + ([crack_out[0][:, None]] if has_crack else []), axis=1)
    cones = _ConeTests(rows, m, has_crack)
    for code in itertools.product((1.0, -1.0), repeat=m):
        sig = np.array(code)
        inward = nj * sig[None, :, None]
        row_sign = np.concatenate([-sig, np.ones(rows.shape[1] - m)])
        finite = ~cones.nontrivial(row_sign) & ~parallel
        tapered = finite & cones.jp_empty(np.concatenate([sig, np.full(rows.shape[1] - m, -1.0)]))
        any_finite |= finite
        any_tapered |= tapered
        take = np.flatnonzero(finite & ~tapered & ~np.isnan(top[:, 2]))
        if len(take) == 0:
            continue
        sub = {k: (None if v is None else v[take]) for k, v in d.items()}
        scale = _size_scale(nf[take], nu[take], inward[take], top[take], sub["bw"], sub["sl"])
        top_s = top[take] * scale[:, None]
        # half-spaces in the rows' order: joints, slope face, upper face, crack
        a = rows[take] * row_sign[None, :, None]
        b = np.zeros(a.shape[:2])
        b[:, m + 1] = np.einsum("ij,ij->i", nu[take], top_s)
        if has_crack:
            b[:, -1] = _crack_outward(nc[take], sub["cl"], nu[take], nj[take, 0], nf[take], top_s)[1]
        verts, valid = cones.vertices(take, row_sign, b, sub["h"])
        area = _face_areas(a, b, verts, valid)
        volume = np.einsum("ij,ij->i", area, b) / 3.0
        ok = volume > 1e-12 * sub["h"] ** 3
        if has_crack:
            crack_cuts = area[:, -1] > 1e-12 * sub["h"] ** 2
            res["reason"][take[ok & ~crack_cuts & ~done[take]]] = 6
            ok &= crack_cuts
        res["reason"][take[~ok & ~done[take]]] = np.where(res["reason"][take[~ok & ~done[take]]] == 0, 4,
                                                         res["reason"][take[~ok & ~done[take]]])
        if not ok.any():
            continue
        sel = take[ok]
        eq = _equilibrium(a[ok], b[ok], area[ok], verts[ok], valid[ok], volume[ok], top_s[ok], nu[sel], nj[sel],
                          {k: (None if v is None else v[ok]) for k, v in sub.items()}, m, has_crack, g, rho_w,
                          s_trend, s_plunge, f_active, f_passive)
        better = ~done[sel] | (eq["fs"] < res["fs"][sel])
        upd = sel[better]
        for key in ("fs", "mode", "volume", "weight", "normal", "sliding"):
            res[key][upd] = eq[key][better]
        res["height"][upd] = (sub["h"] * scale)[ok][better]
        res["forms"][upd] = True
        res["reason"][upd] = 0
        done[upd] = True
    # why not, where no wedge formed
    nope = ~done & (res["reason"] == 0)
    i_down = i_line * -np.sign(i_line[:, 2:3] + (i_line[:, 2:3] == 0))
    daylights = np.einsum("ij,ij->i", nf, i_down) > 0
    res["reason"][nope & parallel] = 5
    res["reason"][nope & ~parallel & any_tapered] = 3
    rest = nope & ~parallel & ~any_tapered
    res["reason"][rest & ~daylights] = 1
    res["reason"][rest & daylights & ~any_finite] = 2
    res["reason"][rest & daylights & any_finite] = 4
    return BatchResult(**res)


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
        self.jp_det = np.abs(np.linalg.det(rows[:, jp])) if len(jp) == 3 else None
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
        """The JP of the joints (and crack) with these side signs has no interior (Gordan: 0
        in the convex hull of the inward normals; with four, the signed minors of one sign)."""
        n = len(self.rows)
        if self.jp_det is not None:
            return self.jp_det < 1e-12
        if self.jp_minors is None:
            return np.zeros(n, bool)
        s = sign[self.jp_rows]
        lam = self.jp_minors * np.array([np.prod(np.delete(s, k)) for k in range(4)])[None]
        return np.all(lam >= -1e-12, axis=1) | np.all(lam <= 1e-12, axis=1)

    def vertices(self, take, sign, b, size):
        """`_vertices` for the samples ``take`` with these row signs, from the stored
        products: x = (bᵢsᵢ aⱼ×aₖ − bⱼsⱼ aᵢ×aₖ + bₖsₖ aᵢ×aⱼ) / aᵢ·(aⱼ×aₖ) (Cramer, signs cancelled)."""
        r = self.rows.shape[1]
        triples = list(itertools.combinations(range(r), 3))
        ti, tj, tk = (np.array(t) for t in zip(*triples))
        jk = np.array([self.pair_index[(j, k)] for _, j, k in triples])
        ik = np.array([self.pair_index[(i, k)] for i, _, k in triples])
        ij = np.array([self.pair_index[(i, j)] for i, j, _ in triples])
        cross = self.cross[take]
        det = self.triple[take][:, ti, jk]
        good = np.abs(det) > 1e-10
        bs = b * sign[None, :]
        num = (bs[:, ti, None] * cross[:, jk] - bs[:, tj, None] * cross[:, ik] + bs[:, tk, None] * cross[:, ij])
        x = num / np.where(good, det, 1.0)[..., None]
        a = self.rows[take] * sign[None, :, None]
        slack = x @ a.transpose(0, 2, 1) - b[:, None, :]
        valid = good & (_max1(slack.transpose(0, 2, 1)) <= 1e-9 * size[:, None])
        return x, valid


def _jp_empty(v: np.ndarray) -> np.ndarray:
    """JP = {d: V d ≥ 0} has no interior (Gordan: 0 is in the convex hull of the rows; with
    four rows, the null vector of Vᵀ is the signed 3×3 minors, all of one sign)."""
    n, r, _ = v.shape
    if r < 3:
        return np.zeros(n, bool)
    if r == 3:
        return np.abs(np.linalg.det(v)) < 1e-12
    if r != 4:
        raise ValueError("batched block theory handles up to four joint planes")
    minors = np.stack([((-1) ** k) * np.linalg.det(np.delete(v, k, axis=1)) for k in range(4)], axis=1)
    return np.all(minors >= -1e-12, axis=1) | np.all(minors <= 1e-12, axis=1)


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


def _tan_friction(phi, bb, sigma):
    """tan φ of each joint at normal stress σ: Mohr–Coulomb or the Barton–Bandis law of
    `ddatai.BartonBandis` (φr + JRC log10(JCS/σ) in [φr, cap], reduced)."""
    t = np.tan(np.radians(phi))
    if bb is None:
        return t
    jrc, jcs, phir, cap, red = np.moveaxis(bb, -1, 0)
    with np.errstate(divide="ignore", invalid="ignore"):
        mob = phir + jrc * np.log10(jcs / sigma)
    mob = np.where(sigma > 0, np.clip(mob, phir, cap), np.where(jrc > 0, cap, phir))
    return np.where(np.isnan(jrc), t, np.tan(np.radians(mob)) / red)


def _equilibrium(a, b, area, verts, valid, volume, top, nu, nj, d, m, has_crack, g, rho_w, s_trend, s_plunge,
                 f_active, f_passive) -> dict:
    n = len(volume)
    contact = list(range(m)) + ([a.shape[1] - 1] if has_crack else [])
    v = -a[:, contact]                                       # inward normals of joints (and crack)
    A = area[:, contact]
    mass = d["rho"] * volume
    weight = mass * g
    r = np.zeros((n, 3))
    r[:, 2] = -weight
    if d["fill"] is not None:
        head = _hoek_bray_head(a, b, verts, valid, top, nu, nj, has_crack)
        u = d["fill"] * rho_w * g * head
        r += np.einsum("nk,nki->ni", u[:, None] * A, v)
    r += f_active
    p = np.broadcast_to(f_passive, (n, 3))
    phi = d["phi"]
    c = d["c"]
    bb = d.get("bb")
    if has_crack:                                            # the crack: no strength
        phi = np.concatenate([phi, np.zeros((n, 1))], axis=1)
        c = np.concatenate([c, np.zeros((n, 1))], axis=1)
        if bb is not None:
            bb = np.concatenate([bb, np.full((n, 1, 5), np.nan)], axis=1)
    if d["k"] is not None:
        if s_trend is None:
            static = _modes(r, p, v, A, phi, c, bb, mass)
            dirn = static["sliding"].copy()
            fallback = _cross(nj[:, 0], nj[:, 1])
            fallback = fallback * -np.sign(fallback[:, 2:3] + (fallback[:, 2:3] == 0))
            bad = ~np.isfinite(dirn).all(axis=1) | (np.hypot(dirn[:, 0], dirn[:, 1]) < 1e-12)
            dirn[bad] = fallback[bad]
            h = dirn[:, :2] / np.hypot(dirn[:, 0], dirn[:, 1])[..., None]
            kdir = np.concatenate([h, np.zeros((n, 1))], axis=1)
        else:
            kdir = np.broadcast_to(direction_vector(s_trend, s_plunge), (n, 3))
        r = r + (d["k"] * weight)[:, None] * kdir
    out = _modes(r, p, v, A, phi, c, bb, mass)
    out["volume"], out["weight"] = volume, weight
    out["normal"] = out["normal"][:, :m]
    return out


def _modes(r, p, v, A, phi, c, bb, mass) -> dict:
    """The least safe admissible mode of each block (block_theory.admissible_modes, vectorised)."""
    n, k, _ = v.shape
    present = A > 0
    rn = _norm(r)
    t = 1e-9 * rn
    rv = (v @ r[:, :, None])[..., 0]
    best_fs = np.full(n, np.inf)
    best_mode = np.full(n, 4, np.int8)
    best_normal = np.zeros((n, k))
    best_dir = np.full((n, 3), np.nan)

    def keep(fs, code, normal, direction, admissible):
        take = admissible & (fs < best_fs)
        best_fs[take] = fs[take]
        best_mode[take] = code
        best_normal[take] = normal[take]
        best_dir[take] = direction[take]

    # falling: r leaves every face
    fall = np.all((rv >= -t[:, None]) | ~present, axis=1)
    rhat = r / rn[:, None]
    held = np.maximum(0.0, -np.einsum("ni,ni->n", p, rhat))
    keep(held / rn, 1, np.zeros((n, k)), rhat, fall)
    for i in range(k):
        s = r - rv[:, i:i + 1] * v[:, i]
        sn = _norm(s)
        sh = s / np.maximum(sn, 1e-300)[:, None]
        others = (v @ sh[:, :, None])[..., 0]
        others[:, i] = 0.0
        adm = present[:, i] & (rv[:, i] < -t) & (sn > t) & np.all((others >= -1e-9) | ~present, axis=1)
        normal = np.zeros((n, k))
        normal[:, i] = np.maximum(-rv[:, i] - np.einsum("ni,ni->n", p, v[:, i]), 0.0)
        fs = _fs(normal, A, phi, c, bb, [i], p, sh, sn)
        keep(fs, 2, normal, sh, adm)
    for i, j in itertools.combinations(range(k), 2):
        s = _cross(v[:, i], v[:, j])
        sn = _norm(s)
        s = s / np.maximum(sn, 1e-300)[:, None]
        s = s * np.where(np.einsum("ni,ni->n", s, r) < 0, -1.0, 1.0)[:, None]
        drive = np.einsum("ni,ni->n", s, r)
        others = (v @ s[:, :, None])[..., 0]
        others[:, [i, j]] = 0.0
        cij = np.einsum("ni,ni->n", v[:, i], v[:, j])
        det = np.maximum(1.0 - cij * cij, 1e-300)

        def normals(f):
            perp = f - np.einsum("ni,ni->n", s, f)[:, None] * s
            bi, bj = -np.einsum("ni,ni->n", perp, v[:, i]), -np.einsum("ni,ni->n", perp, v[:, j])
            return (bi - cij * bj) / det, (bj - cij * bi) / det

        ni, nj_ = normals(r)
        pi, pj = normals(p)
        adm = (present[:, i] & present[:, j] & (sn > 1e-9) & (drive > t) & (ni >= -t) & (nj_ >= -t)
               & np.all((others >= -1e-9) | ~present, axis=1))
        normal = np.zeros((n, k))
        normal[:, i], normal[:, j] = np.maximum(ni + pi, 0.0), np.maximum(nj_ + pj, 0.0)
        fs = _fs(normal, A, phi, c, bb, [i, j], p, s, drive)
        keep(fs, 3, normal, s, adm)
    accel_unused = mass  # noqa: F841  (acceleration is reported by the reference path)
    return dict(fs=best_fs, mode=best_mode, normal=best_normal, sliding=best_dir)


def _fs(normal, A, phi, c, bb, planes, p, s, drive):
    q = -np.einsum("ni,ni->n", p, s)
    for i in planes:
        with np.errstate(divide="ignore", invalid="ignore"):
            sigma = np.where(A[:, i] > 0, normal[:, i] / A[:, i], 0.0)
        tan = _tan_friction(phi[:, i], None if bb is None else bb[:, i], sigma)
        q = q + normal[:, i] * tan + c[:, i] * A[:, i]
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(drive > 0, np.maximum(q, 0.0) / drive, np.inf)


def _hoek_bray_head(a, b, verts, valid, top, nu, nj, has_crack):
    """`kgm.wedges.slope.hoek_bray_head`, vectorised."""
    i = _cross(nj[:, 0], nj[:, 1])
    i = i / _norm(i)[..., None]
    i = i * np.sign(i[:, 2:3] + (i[:, 2:3] == 0))
    ai = (a @ i[:, :, None])[..., 0]
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.where(ai > 1e-12, b / ai, np.inf)
    exit_plane = np.argmin(t, axis=1)
    t_end = t[np.arange(len(t)), exit_plane]
    z = np.where(valid, verts[..., 2], np.nan)
    extent = (np.nanmax(z, axis=1) - np.nanmin(z, axis=1)) / 6.0
    on_edge = np.isfinite(t_end) & (t_end > 0)
    end = t_end[:, None] * i
    head = end[:, 2] / 6.0
    if has_crack:
        z_upper = top[:, 2] - (nu[:, 0] * (end[:, 0] - top[:, 0]) + nu[:, 1] * (end[:, 1] - top[:, 1])) / nu[:, 2]
        head = np.where(exit_plane == a.shape[1] - 1, (z_upper - end[:, 2]) / 3.0, head)
    return np.where(on_edge, head, extent)


def sliding_trend_plunge(direction: np.ndarray) -> tuple:
    """(trend, plunge) [degrees] of (n, 3) sliding directions."""
    from .geometry import trend_plunge

    return trend_plunge(direction)


def nan_if(x, mask) -> np.ndarray:
    return np.where(mask, x, math.nan)
