"""Each pseudo-step's `Contacts.start` for many members at once (`ddatai.side_by_side`;
docs/guide/performance.md, "Batched studies"), registered with the others by `ddatai.stage_batch`.

``contacts_start`` of the members waiting at it with the same penalty, shear penalty, round-off
length and first-step flag (models without Barton–Bandis joints, memories without slips) is
evaluated once over their contacts one member after the other: each contact's key is made from
its own member's vertex numbers and vertex count, its joint from its member's tables (the
members' joint tables one after the other), its distances and lock position from its own
vertices; the memory lookups search each member's sorted keys, raised by the member's rank
times a bound above every key (so that a member's keys can only meet its own). Every term is per
contact, so each member gets its own contacts to the bit (tests/test_stage_batch_more.py).
"""

from __future__ import annotations

import numpy as np

from .contacts import Contacts, edge_projection, signed_distance
from .layout import E0, E1, KIND, LOCK, OPEN, SLIDE, V0, V1, VE
from .side_by_side import bound as _bound, offsets as _offsets

_ARGS = ("model", "vertex_xy", "cint", "length", "memory", "first_step")


def start_group(*args, **kwargs):
    model, _, cint, _, memory, first_step = _bound(args, kwargs, _ARGS)
    if len(cint) == 0 or len(model.joint_barton) or len(memory.slip) or not model.numpy_path:
        return None
    return ("start", float(model.penalty), float(model.shear_penalty), float(model.open_tol), bool(first_step))


def _ranked(keys: list, member_keys_bound: int) -> np.ndarray:
    """Sorted keys of each member raised by its rank × the bound: one sorted array."""
    return np.concatenate([np.asarray(k, np.int64) + np.int64(r) * member_keys_bound for r, k in enumerate(keys)])


def contacts_start_many(requests) -> list:
    """`Contacts.start` of each request (module docstring): each member's `Contacts`, with its
    own ``cint`` and ``length``."""
    args = [_bound(a, kw, _ARGS) for a, kw in requests]
    models = [a[0] for a in args]
    m0, first_step = models[0], args[0][5]
    counts = [len(a[2]) for a in args]
    n_vertices = [len(m.vertex_block) for m in models]
    v_at, j_at = _offsets(n_vertices), _offsets([len(m.joint_tan_phi) for m in models])
    member = np.repeat(np.arange(len(args)), counts)
    local = np.concatenate([a[2] for a in args])
    n = len(local)
    at_v = np.repeat(v_at, counts)
    cint = np.where(local[:, 1:] >= 0, local[:, 1:] + at_v[:, None], local[:, 1:])  # vertices in the union
    v0, e0, v1, e1 = (cint[:, c - 1] for c in (V0, E0, V1, E1))
    xy = np.concatenate([a[1] for a in args])
    vnext = np.concatenate([m.vertex_next.astype(np.int64) + o for m, o in zip(models, v_at.tolist())])
    vblock = np.concatenate([m.vertex_block for m in models])  # each member's own block numbers
    length = np.concatenate([a[3] for a in args])
    # the key of each contact (`contacts.contact_keys`), in its member's numbering
    nv = np.repeat(np.array(n_vertices, np.int64), counts)
    k = local[:, V0].astype(np.int64) * nv
    kind = local[:, KIND]
    ve = kind == VE
    key = np.where(ve, k + local[:, E0], nv * nv + k + local[:, V1])
    a, b = vblock[v0], vblock[e0]
    joint = np.concatenate([m.edge_joint for m in models])[e0]
    if any(len(m.pair_key) for m in models):
        bound = np.int64(max(m.n_blocks for m in models)) ** 2
        nb = np.repeat(np.array([m.n_blocks for m in models], np.int64), counts)
        pk = np.minimum(a, b).astype(np.int64) * nb + np.maximum(a, b) + member * bound
        pair_key = _ranked([m.pair_key for m in models], bound)
        pos = np.minimum(np.searchsorted(pair_key, pk), len(pair_key) - 1)
        hit = pair_key[pos] == pk
        joint[hit] = np.concatenate([m.pair_joint for m in models])[pos[hit]]
    union_joint = joint.astype(np.int64) + np.repeat(j_at, counts)
    dn0 = signed_distance(xy, vnext, v0, e0)
    state = np.zeros(n, np.int8)
    line = np.zeros(n, np.int8)
    bond = np.zeros(n, bool)
    shear_dir = np.ones(n, np.int8)
    omega = edge_projection(xy, vnext, v0, e0)
    vv = ~ve
    dn1 = np.full(n, -np.inf)
    if vv.any():
        dn1[vv] = signed_distance(xy, vnext, v1[vv], e1[vv])
    line[vv] = dn1[vv] > dn0[vv]
    normal_force = m0.penalty * np.maximum(-np.where(line == 1, dn1, dn0), 0.0)
    tan_phi = np.concatenate([m.joint_tan_phi for m in models])[union_joint]
    memories = [a[4] for a in args]
    found = np.zeros(n, bool)
    if any(len(mem.key) for mem in memories):
        bound = np.int64(2) * np.int64(max(n_vertices)) ** 2 + 1  # above every key (`contact_keys`)
        mem_key = _ranked([mem.key for mem in memories], bound)
        field = {f: np.concatenate([getattr(mem, f) for mem in memories])
                 for f in ("state", "line", "bond", "shear_dir", "normal_force", "omega")}
        query = key + member * bound
        pos = np.minimum(np.searchsorted(mem_key, query), len(mem_key) - 1)
        found = mem_key[pos] == query
        src = pos[found]
        state[found] = field["state"][src]
        line[found] = field["line"][src]
        normal_force[found & vv] = m0.penalty * np.maximum(-np.where(line == 1, dn1, dn0)[found & vv], 0.0)
        bond[found] = field["bond"][src]
        shear_dir[found] = field["shear_dir"][src]
        closed = found.copy()
        closed[found] = field["state"][src] != OPEN
        normal_force[closed] = field["normal_force"][pos[closed]]
        locked = found.copy()
        locked[found] = field["state"][src] == LOCK
        omega[locked] = field["omega"][pos[locked]]
        sliding = found & (state == SLIDE) & ve
        if sliding.any():
            # the lock point of a sliding contact S/ks behind its vertex (`Contacts.start`)
            cohesion = np.concatenate([m.joint_cohesion for m in models])
            strength = normal_force[sliding] * tan_phi[sliding] + \
                cohesion[union_joint[sliding]] * length[sliding] * bond[sliding]
            edge_len = np.linalg.norm(xy[e0[sliding]] - xy[vnext[e0[sliding]]], axis=1)
            omega[sliding] -= shear_dir[sliding] * strength / (m0.shear_penalty * edge_len)
    if first_step:
        touching = (np.maximum(dn0, dn1) <= m0.open_tol) & ~found  # no memory: every contact is new
        state[touching & ve] = LOCK
        state[touching & vv] = SLIDE
        bond[touching & ve & (length > 0)] = True
    tables = {f: np.concatenate([getattr(m, "joint_" + f) for m in models])[union_joint]
              for f in ("friction", "cohesion", "tensile")}
    out = []
    for r, (s, c) in enumerate(zip(_offsets(counts).tolist(), counts)):
        p = slice(s, s + c)
        out.append(Contacts(
            cint=args[r][2], length=args[r][3], key=key[p], block_a=a[p], block_b=b[p], tan_phi=tan_phi[p],
            joint=joint[p].astype(np.int32), slip=np.zeros(c), friction_deg=tables["friction"][p],
            cohesion=tables["cohesion"][p], tensile=tables["tensile"][p], state=state[p], line=line[p],
            omega=omega[p], bond=bond[p], shear_dir=shear_dir[p], dn=dn0[p], ds=np.zeros(c),
            normal_force=normal_force[p], coupled=((state == SLIDE) & ve & (tan_phi > 0))[p]))
    return out
