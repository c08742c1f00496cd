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
import os
from dataclasses import dataclass

import numpy as np

from .batched_geometry import _ConeTests, _crack_outward, _cross, _face_areas, _norm, _size_scale
from .geometry import direction_vector, plane_normal

#: samples per chunk (memory ~ 2 kB a sample)
CHUNK = 16384
#: reason codes of `BatchResult.reason`
REASONS = ("", "not daylighting", "infinite", "tapered", "no volume", "parallel joints", "crack does not cut")
MODES = ("", "falling", "one plane", "two planes", "stable")


@dataclass(frozen=True)
class BatchResult:
    """Arrays, one entry per sample."""

    forms: np.ndarray
    reason: np.ndarray
    """Index into `REASONS` (0 where a wedge forms)."""
    fs: np.ndarray
    """Factor of safety (nan where no wedge forms, inf where held, 0 falling)."""
    mode: np.ndarray
    """Index into ``MODES``."""
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
        take = admissible & (fs < best_fs * (1.0 - 1e-12))        # ties keep fewer faces
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
    held = np.flatnonzero(best_mode == 4)
    if len(held):
        # a held block: its frictionless reactions (non-negative least squares, as the reference)
        from scipy.optimize import nnls

        for q in held:
            faces = np.flatnonzero(present[q])
            best_normal[q, faces] = nnls(v[q, faces].T, -(r[q] + p[q]))[0]
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
