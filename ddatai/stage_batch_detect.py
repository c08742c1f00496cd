"""The equilibrium stage's contact detection for many members at once (`ddatai.side_by_side`;
docs/guide/performance.md, "Batched studies").

``narrow_phase`` (``ddatai.narrow.narrow_phase``, the NumPy narrow phase of a small model) of the
members waiting at it, with the same search distance, penetration limit and angle tolerance,
is evaluated once on their *union*: one model whose vertices, blocks and block pairs are the
members' one after the other, each member's indices moved by the vertices and blocks of the
members before it. Every test of the narrow phase reads one vertex, one edge or one row (a
vertex against an edge) of one block pair, so no member's entries meet another's; its group
operations (the nearest vertex of each side vertex, a block's convexity, whether a vertex lies
in front of any edge of a block) run within one side vertex or one block. The contacts of the
union, in canonical order (kind, vertex, edge, ...), are then each member's in its own
canonical order once its indices are moved back (a constant shift keeps the order); the last
step's contact keys (``last_keys``: vertex · V + edge) are moved to the union's numbering the
same way. So each member gets its own contacts and lengths to the bit
(tests/test_stage_batch_more.py). Registered with the others by `ddatai.stage_batch`.
"""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np

from .narrow import narrow_phase
from .side_by_side import bound as _bound, offsets as _offsets

_ARGS = ("model", "vertex_xy", "pairs", "cache", "last_keys")


def narrow_group(*args, **kwargs):
    model, _, pairs = _bound(args, kwargs, _ARGS)[:3]
    if not model.numpy_path or len(pairs) == 0:
        return None
    return ("narrow", float(model.search_distance), float(model.max_penetration),
            float(math.radians(model.params.angle_tolerance)))


def _union_keys(keys: list, n_vertices: np.ndarray, at: np.ndarray, total: int) -> "np.ndarray | None":
    """The members' sorted contact keys (`contacts.contact_keys`) in the union's numbering,
    sorted: a vertex-edge key a·n + b becomes (a + o)·N + (b + o), a vertex-vertex key
    n² + a·n + b becomes N² + (a + o)·N + (b + o) (member k's vertex-edge keys lie between
    o·N and (o + n)·N, so the members' follow one another in order; every vertex-vertex key
    is above them)."""
    if all(k is None or len(k) == 0 for k in keys):
        return None
    big = np.int64(total)
    parts_ve, parts_vv = [], []
    for k, n, o in zip(keys, n_vertices.tolist(), at.tolist()):
        if k is None or len(k) == 0:
            continue
        k = np.asarray(k, np.int64)
        n = np.int64(n)
        vv = k >= n * n
        a, b = np.divmod(np.where(vv, k - n * n, k), n)
        union = (a + o) * big + (b + o)
        parts_ve.append(union[~vv])
        parts_vv.append(big * big + union[vv])
    return np.concatenate(parts_ve + parts_vv)


def narrow_phase_many(requests) -> list:
    """`narrow.narrow_phase` of each request, one narrow phase over the members' union (module
    docstring): each member's (cint, length), as its own call gives them."""
    args = [_bound(a, kw, _ARGS) for a, kw in requests]
    models = [a[0] for a in args]
    n_vertices = np.array([len(m.vertex_block) for m in models], np.int64)
    n_blocks = np.array([m.n_blocks for m in models], np.int64)
    v_at, b_at = _offsets(n_vertices), _offsets(n_blocks)
    total = int(n_vertices.sum())
    shift_v = np.repeat(v_at, n_vertices)
    offset = np.concatenate([m.vertex_offset[:-1].astype(np.int64) + o for m, o in zip(models, v_at.tolist())] +
                            [np.array([total], np.int64)])
    m0 = models[0]
    union = SimpleNamespace(
        vertex_next=np.concatenate([m.vertex_next for m in models]) + shift_v.astype(m0.vertex_next.dtype),
        vertex_prev=np.concatenate([m.vertex_prev for m in models]) + shift_v.astype(m0.vertex_prev.dtype),
        vertex_block=np.concatenate([m.vertex_block for m in models]) +
        np.repeat(b_at, n_vertices).astype(m0.vertex_block.dtype),
        vertex_offset=offset.astype(m0.vertex_offset.dtype), n_vertices=total,
        search_distance=m0.search_distance, max_penetration=m0.max_penetration, params=m0.params)
    pairs = [np.asarray(a[2]) for a in args]
    n_pairs = [len(p) for p in pairs]
    all_pairs = np.concatenate(pairs) + np.repeat(b_at, n_pairs).astype(pairs[0].dtype)[:, None]
    xy = np.concatenate([np.asarray(a[1]) for a in args])
    keys = _union_keys([a[4] for a in args], n_vertices, v_at, total)
    cint, length = narrow_phase(union, xy, all_pairs, None, keys)
    # each member's contacts: those of its vertices (column 1), in order; indices moved back
    member = np.searchsorted(v_at, cint[:, 1], side="right") - 1
    back = np.where(cint[:, 1:] >= 0, cint[:, 1:] - v_at[member][:, None].astype(cint.dtype), cint[:, 1:])
    cint = np.concatenate([cint[:, :1], back], axis=1)
    order = np.argsort(member, kind="stable")
    counts = np.bincount(member, minlength=len(models))
    starts = _offsets(counts)
    cint, length = cint[order], length[order]
    return [(cint[s:s + n], length[s:s + n]) for s, n in zip(starts.tolist(), counts.tolist())]

