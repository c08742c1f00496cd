"""The equilibrium stage's regular NumPy work evaluated for many members at once
(`ddatai.side_by_side`; docs/method/dda.md §8.12, docs/guide/performance.md, "Batched studies").

Each operation here takes the calls of several members — small models on the NumPy path
(`Model.numpy_path`) with the same constants (penalty, shear penalty, penetration limit) — and
evaluates them as one call of the same NumPy code over their arrays concatenated with a member
axis: contacts one member after the other, their vertex, block, CSR-row and CSR-slot indices
moved by the members before them. The terms are element-wise per contact, and the scatters
(``np.add.at``) add their entries one after another in order, so every entry of a member gets
its own terms in its own order: each member's result is, to the bit, the one its own call gives
(tests/test_stage_batch.py). Then each member's slice is handed back to it.

- ``assemble_contacts`` (`ddatai.assembly.assemble_contacts`): the contact springs and friction
  loads added into each member's K and F, in place;
- ``stage_law`` (``ddatai.contact_law.stage_law``): the return mapping's contact law;
- ``contact_law_numpy`` (``ddatai.contact_law.contact_law_numpy``): the whole law (the
  open-close iteration of the stage's finish and tests, the balance check);
- ``contact_vectors`` (`ddatai.assembly.contact_vectors`): each pseudo-step's contact vectors
  (3 % of a 200-sample study's stages, benchmarks/results/study_throughput.md);
- ``narrow_phase`` (``ddatai.narrow.narrow_phase``): each pseudo-step's contact detection, one
  narrow phase over the members' union (`ddatai.stage_batch_detect`);
- ``contacts_start`` (``ddatai.contacts.Contacts.start``): each pseudo-step's contacts with their
  joints and memory (`ddatai.stage_batch_contacts`);
- ``settle_points`` (``ddatai.kinematics.settle_points``): each pseudo-step's settlement and block
  geometry, and ``block_terms`` (`ddatai.assembly.assemble_blocks` of the stage's static system):
  each frame's block part of K and F (`ddatai.stage_batch_frame`);
- ``second_order``, ``midstep_lever_arms`` and ``violations``: the per-solve terms and state test
  of the open-close finish, and ``iterate_update``: a return-mapping iterate's judgement of its
  contacts (`ddatai.stage_batch_finish`).
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from . import side_by_side
from .side_by_side import bound as _bound, offsets as _offsets
from .assembly import contact_terms_numpy
from .contact_law import ContactLaw, StageLaw, _law_core, _law_terms, friction_terms
from .kinematics import vertex_displacement
from .stage_batch_contacts import contacts_start_many, start_group
from .stage_batch_detect import narrow_group, narrow_phase_many
from .stage_batch_index import contact_index, frozen, kept
from .stage_batch_finish import (iterate_update_group, iterate_update_many, lever_arms_group, lever_arms_many,
                                 second_order_group, second_order_many, violations_group, violations_many)
from .stage_batch_frame import block_terms_group, block_terms_many, settle_group, settle_points_many
from .vectorized import contact_vectors as vectors_numpy

def _cat(arrays) -> np.ndarray:
    return np.concatenate(arrays)


def _shifted(arrays, by, counts) -> np.ndarray:
    """The index arrays concatenated, member k's moved by ``by[k]`` where ≥ 0 (−1: none)."""
    a = _cat(arrays)
    return np.where(a >= 0, a + np.repeat(by, counts).reshape((-1,) + (1,) * (a.ndim - 1)), a)


def _split(a: np.ndarray, starts: np.ndarray, counts) -> list:
    return [a[s:s + n] for s, n in zip(starts.tolist(), counts)]


#: the contact fields that each operation reads besides ``cint``
_ASSEMBLY_FIELDS = ("state", "line", "shear_dir", "coupled", "cohesion", "length", "bond", "normal_force", "tan_phi")
_STAGE_LAW_FIELDS = ("line", "bond", "tensile", "length", "tan_phi", "cohesion")
_LAW_FIELDS = _STAGE_LAW_FIELDS + ("coupled", "normal_force", "state", "shear_dir")


def _contacts(models, contacts, fields, blocks: bool):
    """The members' contacts concatenated (``fields``, ``cint`` with its vertices moved by the
    members' before them, and with ``blocks`` their blocks so moved: `stage_batch_index`)."""
    index = contact_index(models, contacts)
    out = SimpleNamespace(cint=index.cint, n=index.n, **{k: _cat([getattr(c, k) for c in contacts]) for k in fields})
    if blocks:
        out.block_a, out.block_b = index.block_a, index.block_b
    return out


# ------------------------------------------------------------------ the contact assembly
def _assembly_group(*args, **kwargs):
    model, contacts = _bound(args, kwargs, _ASSEMBLY_ARGS)[:2]
    if not model.numpy_path or contacts.n == 0:
        return None
    return ("assembly", float(model.penalty), float(model.shear_penalty))


def assemble_contacts_many(requests) -> list:
    """``assemble_contacts`` of each request, one `contact_terms_numpy` over all (module
    docstring): each member's K data and F get its own contacts' terms, in place."""
    args = [_bound(a, kw, _ASSEMBLY_ARGS) for a, kw in requests]
    models = [a[0] for a in args]
    contacts = [a[1] for a in args]
    patterns = [a[2] for a in args]
    datas, rhss = [a[5] for a in args], [a[6] for a in args]
    m0 = models[0]
    c = _contacts(models, contacts, _ASSEMBLY_FIELDS, blocks=False)
    const, slope = friction_terms(m0, c)
    # F's terms alone where every member asks only them (data None: its K has not changed);
    # else K too, a member that asks only F getting its K's terms in a scratch array
    stiffness = any(d is not None for d in datas)
    if stiffness:
        datas = [np.zeros(len(p.indices)) if d is None else d for d, p in zip(datas, patterns)]
    data_len, rhs_len = [len(d) for d in datas] if stiffness else [0] * len(datas), [len(r) for r in rhss]

    def union():  # the members' patterns, blocks and rows one after the other (`stage_batch_index`)
        counts = [x.n for x in contacts]
        data_at = _offsets(np.array(data_len))
        rows = np.array([len(m.block_dof) for m in models])
        row_at = _offsets(np.array(rhs_len) // 6)
        n_rows = [len(p.diag_slot) for p in patterns]
        pattern = SimpleNamespace(slot_ab=_shifted([p.slot_ab for p in patterns], data_at, counts),
                                  slot_ba=_shifted([p.slot_ba for p in patterns], data_at, counts),
                                  diag_slot=_shifted([p.diag_slot for p in patterns], data_at, n_rows),
                                  stride=_cat([p.stride for p in patterns]))
        vblock = _cat([m.vertex_block for m in models]) + np.repeat(_offsets(np.array([m.n_blocks for m in models])),
                                                                   [len(m.vertex_block) for m in models])
        dof = _shifted([m.block_dof for m in models], row_at, rows)
        for a in (pattern.slot_ab, pattern.slot_ba, pattern.diag_slot, pattern.stride, vblock, dof):
            frozen(a)
        return pattern, vblock, dof, data_at.tolist(), _offsets(np.array(rhs_len)).tolist()

    pattern, vblock, dof, data_at, rhs_at = kept(
        ("assembly", tuple(data_len), tuple(rhs_len)),
        tuple(models) + tuple(patterns) + tuple(x for c in contacts for x in (c.cint, c.block_a, c.block_b)), union)
    data, rhs = _cat(datas) if stiffness else None, _cat(rhss)
    contact_terms_numpy(c.cint, c.state, c.line, vblock, dof, _cat([a[3] for a in args]), _cat([a[4] for a in args]),
                        const, slope, c.shear_dir, pattern, m0.penalty, m0.shear_penalty, data, rhs)
    for d, s, n in zip([a[5] for a in args] if stiffness else (), data_at, data_len):
        if d is not None:
            d[:] = data[s:s + n]
    for r, s, n in zip(rhss, rhs_at, rhs_len):
        r[:] = rhs[s:s + n]
    return [None] * len(requests)


# ------------------------------------------------------------------ the contact law
def _law_group(*args, **kwargs):
    model, contacts = _bound(args, kwargs, _LAW_ARGS)[:2]
    if contacts.n == 0 or len(model.joint_barton) or not model.numpy_path:
        return None
    return ("law", float(model.penalty), float(model.shear_penalty), float(model.penetration_limit),
            float(model.force_roundoff))


_LAW_ARGS = ("model", "contacts", "vec", "sca", "disp", "shift")
_ASSEMBLY_ARGS = ("model", "contacts", "pattern", "vec", "sca", "data", "rhs", "serial_scatter")



def _law_inputs(requests, fields):
    args = [_bound(a, kw, _LAW_ARGS) for a, kw in requests]
    models = [a[0] for a in args]
    contacts = [a[1] for a in args]
    c = _contacts(models, contacts, fields, blocks=True)
    counts = contact_index(models, contacts).counts
    sca = _cat([a[3] for a in args])
    shifts = [a[5] for a in args]
    shift = None if all(s is None for s in shifts) else \
        _cat([np.zeros_like(a[3]) if s is None else s for a, s in zip(args, shifts)])
    m = SimpleNamespace(penalty=models[0].penalty, shear_penalty=models[0].shear_penalty,
                        penetration_limit=models[0].penetration_limit, joint_barton=models[0].joint_barton)
    return c, counts, m, _cat([a[2] for a in args]), sca, _cat([a[4] for a in args]), shift


def stage_law_many(requests) -> list:
    """`contact_law.stage_law` of each request (a NumPy-path model), one `_law_core` over all."""
    c, counts, m, vec, sca, disp, _ = _law_inputs(requests, _STAGE_LAW_FIELDS)
    dn, ds, line, closed, strength, dn_now, _, _, _, _ = _law_core(m, c, vec, sca, disp, None)
    fn = np.where(closed, -m.penalty * dn, 0.0)
    at = _offsets(np.array(counts))
    parts = [_split(x, at, counts) for x in (dn, ds, line, closed, fn, strength, dn_now)]
    return [StageLaw(dn=p[0], ds=p[1], line=p[2], closed=p[3], fn=p[4], strength=p[5], dn_now=p[6])
            for p in zip(*parts)]


def contact_law_many(requests) -> list:
    """`contact_law.contact_law_numpy` of each request, the law's terms over all at once; each
    member's energy summed over its own contacts, as alone."""
    c, counts, m, vec, sca, disp, shift = _law_inputs(requests, _LAW_FIELDS)
    dn, ds, line, closed, strength, dn_now, _, vv, ve, allowance = _law_core(m, c, vec, sca, disp, shift)
    terms, normal_energy, huber = _law_terms(m, c, dn, ds, closed, strength, dn_now, vv, ve, allowance)
    at = _offsets(np.array(counts))
    fields = dict(dn=dn, ds=ds, line=line, closed=closed, strength=strength, dn_now=dn_now, **terms)
    parts = {k: _split(x, at, counts) for k, x in fields.items()}
    out = []
    for k, (s, n) in enumerate(zip(at.tolist(), counts)):
        shear = closed[s:s + n] & ve[s:s + n]
        energy = float(np.add.reduce(normal_energy[s:s + n]) + np.add.reduce(huber[s:s + n][shear]))  # np.sum's
        out.append(ContactLaw(energy=energy, tan_phi=None, **{name: part[k] for name, part in parts.items()}))
    return out


# ------------------------------------------------------------------ how far blocks move
def block_displacement_many(requests) -> list:
    """`kinematics.block_displacement` of each request (each vertex moved by its block's D with
    the exact rotation, the largest of each block's), one evaluation over all."""
    args = [_bound(a, kw, ("model", "vertex_xy", "geom", "disp")) for a, kw in requests]
    models = [a[0] for a in args]

    def union():  # the members' vertices and blocks one after the other (`stage_batch_index`)
        n_blocks = [m.n_blocks for m in models]
        n_vertices = [len(m.vertex_block) for m in models]
        block = _cat([m.vertex_block for m in models]) + np.repeat(_offsets(np.array(n_blocks)), n_vertices)
        start = _cat([m.vertex_offset[:-1] for m in models]) + np.repeat(_offsets(np.array(n_vertices)), n_blocks)
        return SimpleNamespace(vertex_block=frozen(block)), frozen(start), _offsets(np.array(n_blocks)), n_blocks

    model, start, block_at, n_blocks = kept("displacement", tuple(models), union)
    xy = _cat([a[1] for a in args])
    moved = vertex_displacement(model, xy, {"centroid": _cat([a[2]["centroid"] for a in args])},
                                _cat([a[3] for a in args]))
    return _split(np.maximum.reduceat(moved, start), block_at, n_blocks)


def _displacement_group(*args, **kwargs):
    model = args[0] if args else kwargs["model"]
    return ("displacement",) if len(model.vertex_block) else None


# ------------------------------------------------------------------ the contact vectors
_VECTOR_ARGS = ("model", "vertex_xy", "geom", "contacts")


def contact_vectors_many(requests) -> list:
    """`assembly.contact_vectors` of each request (a NumPy-path model): one `vectorized.contact_vectors`
    over all, with each member's vertices, blocks and next vertices moved by the members' before it
    (its terms are element-wise per contact line: each member's own floats)."""
    args = [_bound(a, kw, _VECTOR_ARGS) for a, kw in requests]
    models = [a[0] for a in args]
    contacts = [a[3] for a in args]
    counts = [c.n for c in contacts]
    n_vertices = [len(m.vertex_block) for m in models]
    vertex_at = np.repeat(_offsets(np.array(n_vertices)), n_vertices)
    block_at = np.repeat(_offsets(np.array([m.n_blocks for m in models])), n_vertices)
    c = _contacts(models, contacts, ("omega",), blocks=False)
    model = SimpleNamespace(vertex_next=_cat([m.vertex_next for m in models]) + vertex_at,
                            vertex_block=_cat([m.vertex_block for m in models]) + block_at)
    vec, sca = vectors_numpy(model, _cat([a[1] for a in args]), _cat([a[2]["centroid"] for a in args]), c.cint, c.omega)
    at = _offsets(np.array(counts))
    return list(zip(_split(vec, at, counts), _split(sca, at, counts)))


def _vectors_group(*args, **kwargs):
    model, _, _, contacts = _bound(args, kwargs, _VECTOR_ARGS)
    return ("vectors",) if model.numpy_path and contacts.n else None


side_by_side.register("block_displacement", _displacement_group, block_displacement_many)
side_by_side.register("contact_vectors", _vectors_group, contact_vectors_many)
side_by_side.register("narrow_phase", narrow_group, narrow_phase_many)
side_by_side.register("contacts_start", start_group, contacts_start_many)
side_by_side.register("settle_points", settle_group, settle_points_many)
side_by_side.register("block_terms", block_terms_group, block_terms_many)
side_by_side.register("second_order", second_order_group, second_order_many)
side_by_side.register("midstep_lever_arms", lever_arms_group, lever_arms_many)
side_by_side.register("violations", violations_group, violations_many)
side_by_side.register("iterate_update", iterate_update_group, iterate_update_many)
side_by_side.register("assemble_contacts", _assembly_group, assemble_contacts_many)
side_by_side.register("stage_law", _law_group, stage_law_many)
side_by_side.register("contact_law_numpy", _law_group, contact_law_many)
