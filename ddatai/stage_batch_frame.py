"""More of the equilibrium stage's pseudo-steps evaluated for many members at once
(`ddatai.side_by_side`; docs/guide/performance.md, "Batched studies"), registered with the
others by `ddatai.stage_batch`:

- ``settle_points`` (``ddatai.kinematics.settle_points``): each pseudo-step's settlement — the
  vertices moved by the exact rotation, the stresses and rotations updated, and the block
  geometry at the moved vertices (`ddatai.geometry.polygon_integrals`);
- ``block_terms`` (`ddatai.assembly.assemble_blocks` of the stage's static system): the block
  part of each frame's K and F (pseudo inertia, elasticity, initial stress, body force).

Both over the members' blocks and vertices one member after the other: every term is per
vertex or per block, and each block's sums (its polygon integrals, ``np.add.reduceat`` over its
own vertices) read only its own entries, so each member gets its own floats to the bit
(tests/test_stage_batch_more.py). A member's fixed points, loads and measured points are moved
by its own call.
"""

from __future__ import annotations

import numpy as np

from .assembly import block_terms_numpy
from .geometry import mass_matrix, polygon_integrals
from .kinematics import move_points, rotate_stress
from .side_by_side import bound as _bound, offsets as _offsets


def _split(a: np.ndarray, sizes) -> list:
    return [a[s:s + n] for s, n in zip(_offsets(sizes).tolist(), sizes)]


# ------------------------------------------------------------------ the settlement
_SETTLE_ARGS = ("model", "state", "geom", "disp")


def settle_group(*args, **kwargs):
    model = _bound(args, kwargs, _SETTLE_ARGS)[0]
    return ("settle",) if len(model.vertex_block) else None


def settle_points_many(requests) -> list:
    """`kinematics.settle_points` of each request: the vertices, stresses and rotations of all
    the members moved at once, and the geometry of all their blocks at once (module docstring)."""
    args = [_bound(a, kw, _SETTLE_ARGS) for a, kw in requests]
    models, states, geoms, disps = zip(*args)
    n_vertices = [len(m.vertex_block) for m in models]
    n_blocks = [m.n_blocks for m in models]
    v_at, b_at = _offsets(n_vertices), _offsets(n_blocks)
    block = np.concatenate([m.vertex_block for m in models]) + np.repeat(b_at, n_vertices)
    centroid = np.concatenate([g["centroid"] for g in geoms])
    disp = np.concatenate(disps)
    xy = move_points(np.concatenate([s.vertex_xy for s in states]), block, centroid, disp)
    old = np.concatenate([s.block_stress for s in states])
    elastic = np.concatenate([m.block_elastic for m in models])
    stress = rotate_stress(old + np.einsum("bij,bj->bi", elastic, disp[:, 3:6]), disp[:, 2])
    fixed = np.concatenate([m.block_fixed for m in models])
    stress[fixed] = old[fixed]
    rotation = np.concatenate([s.block_rotation for s in states]) + disp[:, 2]
    offset = np.concatenate([m.vertex_offset[:-1].astype(np.int64) + o for m, o in zip(models, v_at.tolist())] +
                            [np.array([sum(n_vertices)], np.int64)])
    nxt = np.concatenate([m.vertex_next.astype(np.int64) + o for m, o in zip(models, v_at.tolist())])
    geometry = polygon_integrals(xy, offset, block, nxt)
    parts = {k: _split(v, n_blocks) for k, v in geometry.items()}
    out = []
    for k, (m, s, g, d) in enumerate(args):
        c = g["centroid"]
        out.append(s.replace(
            vertex_xy=xy[v_at[k]:v_at[k] + n_vertices[k]], block_stress=stress[b_at[k]:b_at[k] + n_blocks[k]],
            block_rotation=rotation[b_at[k]:b_at[k] + n_blocks[k]],
            fixed_point_xy=move_points(s.fixed_point_xy, m.fixed_point_block, c, d),
            load_xy=move_points(s.load_xy, m.load_block, c, d),
            measured_xy=move_points(s.measured_xy, m.measured_block, c, d),
            geometry={name: part[k] for name, part in parts.items()}))
    return out


# ------------------------------------------------------------------ the block terms of a frame
_BLOCK_ARGS = ("model", "state", "geom", "pattern", "dt", "beta", "static_start")


def block_terms_group(*args, **kwargs):
    """The stage's static system of a NumPy-path model without fixed points, point loads,
    water or bolts (their terms stay each member's own call); None otherwise."""
    model, _, _, pattern, dt, beta, static_start = _bound(args, kwargs, _BLOCK_ARGS)
    if not static_start or not model.numpy_path or pattern.n_rows == 0 or len(model.fixed_point_block) or \
            len(model.load_block) or model.water_unit_weight > 0 or len(model.bolt_block):
        return None
    return ("blocks", float(dt), float(beta), float(model.params.velocity_carry), float(model.gravity[0]),
            float(model.gravity[1]))


def block_terms_many(requests) -> list:
    """`assembly.assemble_blocks` of each request (the stage's static system, `block_terms_group`):
    one `assembly.block_terms_numpy` over all the members' blocks, each member's rows and CSR
    entries moved by the members' before it; each member's (data, rhs)."""
    args = [_bound(a, kw, _BLOCK_ARGS) for a, kw in requests]
    models, states, geoms, patterns = [a[0] for a in args], [a[1] for a in args], [a[2] for a in args], \
        [a[3] for a in args]
    m0, dt, beta = models[0], args[0][4], args[0][5]
    n_rows = [p.n_rows for p in patterns]
    nnz = [p.nnz for p in patterns]
    row_at, data_at = _offsets(n_rows), _offsets(nnz)
    dof = np.concatenate([np.where(m.block_dof >= 0, m.block_dof.astype(np.int64) + o, -1)
                          for m, o in zip(models, row_at.tolist())])
    diag_slot = np.concatenate([p.diag_slot.astype(np.int64) + o for p, o in zip(patterns, data_at.tolist())])
    stride = np.concatenate([p.stride for p in patterns])
    geometry = {k: np.concatenate([g[k] for g in geoms]) for k in ("area", "s1", "s2", "s3")}
    mass = mass_matrix(geometry["area"], geometry["s1"], geometry["s2"], geometry["s3"])
    velocity = np.zeros_like(np.concatenate([s.block_velocity for s in states]))  # static: none
    accel = np.zeros_like(np.concatenate([s.block_accel for s in states]))
    data, rhs = np.zeros(sum(nnz)), np.zeros(6 * sum(n_rows))
    block_terms_numpy(dof, np.concatenate([m.block_density for m in models]),
                      np.concatenate([m.block_elastic for m in models]), geometry["area"], mass, velocity, accel,
                      np.concatenate([s.block_stress for s in states]), float(m0.gravity[0]), float(m0.gravity[1]),
                      dt, m0.params.velocity_carry, beta, diag_slot, stride, data, rhs)
    return list(zip(_split(data, nnz), _split(rhs, [6 * n for n in n_rows])))

