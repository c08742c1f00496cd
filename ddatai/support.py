"""DDA terms of water pressure and rock bolts (docs/method/water_bolts.md), NumPy only.

Imported by `ddatai.model`, `ddatai.assembly`, `ddatai.kinematics` and `ddatai.energy` only when a scene has a water table or bolts; a
scene without them builds empty arrays and never loads this module.

* `water_arrays`, `assemble_water`: the hydrostatic pressure (W1) on every edge of every free
  block below the water table, as the exact load vector of DDA's first-order displacement
  field (W2), on the geometry at the start of the step.
* `bolt_arrays`, `assemble_bolts`, `bolt_ends`, `bolt_tension`: Shi's bolt element (B1). A
  bolt end is a material point of its block; as DDA moves every point of a block by one affine
  map, an end is stored by its affine coordinates on three vertices of its block and follows
  them whatever moves the vertices (a step, or the equilibrium stage).
"""

from __future__ import annotations

import numpy as np

from .water import water_points


def t_rows(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """(n, 2, 6) DDA displacement matrices T at centroidal offsets (x, y) [m], the unknowns
    ordered as in `ddatai.kernels` (u0, v0, r0, εx, εy, γxy)."""
    n = len(x)
    t = np.zeros((n, 2, 6))
    t[:, 0, 0] = 1.0
    t[:, 1, 1] = 1.0
    t[:, 0, 2] = -y
    t[:, 1, 2] = x
    t[:, 0, 3] = x
    t[:, 1, 4] = y
    t[:, 0, 5] = 0.5 * y
    t[:, 1, 5] = 0.5 * x
    return t


# ---------------------------------------------------------------------- water
def water_arrays(scene, origin: np.ndarray) -> dict:
    """Model fields of the scene's water table (internal coordinates), or empty ones."""
    water = scene.water
    if water is None:
        return {}
    heads = np.array(water.heads, float).reshape(-1, 2)
    heads[:, 1] -= origin[1]
    return {"water_xy": None if water.xy is None else water.xy - origin, "water_heads": heads,
            "water_unit_weight": float(water.density * scene.gravity)}


def water_load(model, vertex_xy: np.ndarray, centroid: np.ndarray) -> np.ndarray:
    """(B, 6) load vector F_i = Σ_g T_i(x_g)ᵀ · w_g · n_in over the Gauss points of the wet
    edges of every free block (W2); zero rows for fixed blocks."""
    out = np.zeros((model.n_blocks, 6))
    free_vertex = model.block_dof[model.vertex_block] >= 0
    edges = np.flatnonzero(free_vertex)
    start, end = vertex_xy[edges], vertex_xy[model.vertex_next[edges]]
    edge, pts, w = water_points(start, end, model.edge_joint[edges], model.water_xy, model.water_heads,
                                model.water_unit_weight)
    if len(edge) == 0:
        return out
    t = end - start
    n_in = np.stack([-t[:, 1], t[:, 0]], axis=1) / np.hypot(t[:, 0], t[:, 1])[:, None]  # left of CCW edge
    f = w[:, None] * n_in[edge]
    block = model.vertex_block[edges[edge]]
    rel = pts - centroid[block]
    tm = t_rows(rel[:, 0], rel[:, 1])
    np.add.at(out, block, np.einsum("gij,gi->gj", tm, f))    # Tᵀ f per Gauss point
    return out


def assemble_water(model, vertex_xy: np.ndarray, centroid: np.ndarray, rhs: np.ndarray) -> None:
    """The water load (W2) of every free block added to ``rhs`` in place."""
    load = water_load(model, vertex_xy, centroid)
    free = np.flatnonzero(model.block_dof >= 0)
    rows = 6 * model.block_dof[free].astype(np.int64)
    rhs[rows[:, None] + np.arange(6)[None, :]] += load[free]


def support_work(model, vertex_xy: np.ndarray, centroid: np.ndarray, disp: np.ndarray) -> float:
    """Work of the water pressure in a step, F_wᵀ·D with the step's load vector [J/m] (the
    bolts' work is their spring energy, `bolt_energy`)."""
    if model.water_unit_weight == 0.0:
        return 0.0
    return float(np.sum(water_load(model, vertex_xy, centroid) * disp))


def bolt_energy(model, state) -> float:
    """Energy stored in the intact bolts, Σ P0·e + ½·k·e² with e = L − L0 [J/m] (the potential
    whose derivative is the tension N = P0 + k·e, B1)."""
    if not len(model.bolt_block):
        return 0.0
    e = (bolt_tension(model, state.vertex_xy) - model.bolt_pretension) / model.bolt_stiffness
    intact = state.bolt_broken_step < 0
    return float(np.sum((model.bolt_pretension * e + 0.5 * model.bolt_stiffness * e * e)[intact]))


# ---------------------------------------------------------------------- bolts
def bolt_arrays(scene, vertex_xy0: np.ndarray, offset: np.ndarray, origin: np.ndarray) -> dict:
    """Model fields of the scene's bolts: blocks, the affine coordinates of each end on three
    vertices of its block, initial length and properties; empty dict without bolts."""
    bolts = scene.bolts
    if not bolts:
        return {}
    nb = len(bolts)
    block = np.array([(b.block1, b.block2) for b in bolts], dtype=np.int32)
    ends = np.array([(b.xy1, b.xy2) for b in bolts], dtype=float) - origin
    vert = np.zeros((nb, 2, 3), np.int64)
    coef = np.zeros((nb, 2, 2))
    for k in range(nb):
        for e in range(2):
            lo, hi = int(offset[block[k, e]]), int(offset[block[k, e] + 1])
            tri = _wide_triangle(vertex_xy0[lo:hi]) + lo
            a, b, c = vertex_xy0[tri]
            coef[k, e] = np.linalg.solve(np.column_stack([b - a, c - a]), ends[k, e] - a)
            vert[k, e] = tri
    length = np.hypot(*(ends[:, 1] - ends[:, 0]).T)
    return {"bolt_block": block, "bolt_vertex": vert, "bolt_coef": coef, "bolt_length0": length,
            "bolt_stiffness": np.array([b.stiffness for b in bolts]),
            "bolt_pretension": np.array([b.pretension for b in bolts]),
            "bolt_capacity": np.array([b.capacity for b in bolts])}


def _wide_triangle(xy: np.ndarray) -> np.ndarray:
    """Indices of three vertices spanning a large triangle (well-conditioned affine frame)."""
    i = 0
    j = int(np.argmax(np.hypot(*(xy - xy[i]).T)))
    d = xy[j] - xy[i]
    k = int(np.argmax(np.abs(d[0] * (xy[:, 1] - xy[i, 1]) - d[1] * (xy[:, 0] - xy[i, 0]))))
    return np.array([i, j, k])


def bolt_ends(model, vertex_xy: np.ndarray) -> np.ndarray:
    """(nb, 2, 2) current positions of both ends of every bolt [m, internal coordinates]."""
    v = vertex_xy[model.bolt_vertex]                                # (nb, 2, 3, 2)
    c = model.bolt_coef
    return v[:, :, 0] + c[:, :, :1] * (v[:, :, 1] - v[:, :, 0]) + c[:, :, 1:] * (v[:, :, 2] - v[:, :, 0])


def bolt_tension(model, vertex_xy: np.ndarray) -> np.ndarray:
    """(nb,) tension N = P0 + k·(L − L0) of every bolt at these vertex positions [N/m]."""
    e = bolt_ends(model, vertex_xy)
    length = np.hypot(*(e[:, 1] - e[:, 0]).T)
    return model.bolt_pretension + model.bolt_stiffness * (length - model.bolt_length0)


def assemble_bolts(model, vertex_xy: np.ndarray, centroid: np.ndarray, intact: np.ndarray,
                   pattern, data: np.ndarray, rhs: np.ndarray) -> None:
    """Shi's bolt springs (B1) of the intact bolts, in place on the CSR ``data`` and ``rhs``."""
    k = np.flatnonzero(intact)
    if len(k) == 0:
        return
    ends = bolt_ends(model, vertex_xy)[k]                        # (n, 2, 2)
    tension = bolt_tension(model, vertex_xy)[k]
    axis = ends[:, 1] - ends[:, 0]
    axis /= np.hypot(axis[:, 0], axis[:, 1])[:, None]
    bi, bj = model.bolt_block[k, 0], model.bolt_block[k, 1]
    r1, r2 = ends[:, 0] - centroid[bi], ends[:, 1] - centroid[bj]
    e_vec = np.einsum("nij,ni->nj", t_rows(r1[:, 0], r1[:, 1]), axis)   # E = T_i(p1)ᵀ·l
    g_vec = np.einsum("nij,ni->nj", t_rows(r2[:, 0], r2[:, 1]), axis)   # G = T_j(p2)ᵀ·l
    s = model.bolt_stiffness[k][:, None, None]
    ri = model.block_dof[bi].astype(np.int64)
    rj = model.block_dof[bj].astype(np.int64)
    a = np.arange(6)
    for r, c, blocks in ((ri, ri, s * e_vec[:, :, None] * e_vec[:, None, :]),
                         (rj, rj, s * g_vec[:, :, None] * g_vec[:, None, :]),
                         (ri, rj, -s * e_vec[:, :, None] * g_vec[:, None, :]),
                         (rj, ri, -s * g_vec[:, :, None] * e_vec[:, None, :])):
        ok = (r >= 0) & (c >= 0)
        if not ok.any():
            continue
        r, c, blocks = r[ok], c[ok], blocks[ok]
        off = r != c
        slot = pattern.diag_slot[r].astype(np.int64)
        slot[off] = pattern.slots(r[off], c[off])
        stride = pattern.stride[r].astype(np.int64)
        idx = slot[:, None, None] + a[None, :, None] * stride[:, None, None] + a[None, None, :]
        np.add.at(data, idx, blocks)
    for rows, vec, sign in ((ri, e_vec, 1.0), (rj, g_vec, -1.0)):   # F_i += N0·E, F_j −= N0·G
        ok = rows >= 0
        np.add.at(rhs, 6 * rows[ok][:, None] + a[None, :], sign * tension[ok][:, None] * vec[ok])


def bolt_pairs(model) -> tuple[np.ndarray, np.ndarray]:
    """Block-rows (r_i, r_j) of the bolts joining two free blocks (for the sparse pattern)."""
    ri = model.block_dof[model.bolt_block[:, 0]].astype(np.int64)
    rj = model.block_dof[model.bolt_block[:, 1]].astype(np.int64)
    ok = (ri >= 0) & (rj >= 0) & (ri != rj)
    return ri[ok], rj[ok]


def break_bolts(model, state, vertex_xy: np.ndarray, step: int, time: float) -> dict:
    """State fields after a step: every bolt's tension at ``vertex_xy``, and the bolts whose
    tension now exceeds their capacity marked broken at this step (for good)."""
    tension = bolt_tension(model, vertex_xy)
    intact = state.bolt_broken_step < 0
    breaking = intact & (tension > model.bolt_capacity)
    broken_step = np.where(breaking, step, state.bolt_broken_step)
    broken_time = np.where(breaking, time, state.bolt_broken_time)
    broken_force = np.where(breaking, tension, state.bolt_broken_force)
    return {"bolt_force": np.where(broken_step >= 0, 0.0, tension), "bolt_broken_step": broken_step,
            "bolt_broken_time": broken_time, "bolt_broken_force": broken_force}
