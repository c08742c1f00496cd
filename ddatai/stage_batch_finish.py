"""The per-solve work of the equilibrium stage's iterations for many members at once
(`ddatai.side_by_side`; docs/guide/performance.md, "Batched studies"), registered with the others
by `ddatai.stage_batch`:

- ``second_order`` (``ddatai.assembly.second_order``): the second-order rotation terms of the
  contact distances at the iterate's rotation;
- ``midstep_lever_arms`` (``ddatai.lever_arm.midstep_lever_arms``): the contacts' lever arms at
  mid-step;
- ``violations`` (``ddatai.contact_law.violations_numpy``): which contacts' states must change;
- ``iterate_update`` (``ddatai.return_update.iterate_update``): a return-mapping iterate's
  judgement of its contacts.

Each over the members' contacts, vertices and blocks one after the other, every index moved by
the members' before it: the terms are per contact (and per vertex), and each block's load level
is the largest of its own contacts' forces (a maximum, exact in any order), so each member gets
its own floats and flags to the bit (tests/test_stage_batch_more.py). Members whose blocks do not
rotate (their terms are exactly zero, without arithmetic) and models with fixed points (whose
springs' terms go into F) are left to their own calls.
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from .assembly import second_order
from .contact_law import violations_numpy
from .lever_arm import midstep_lever_arms
from .return_update import Update, iterate_update
from .side_by_side import bound as _bound, offsets as _offsets
from .stage_batch_index import contact_index, frozen, kept


def _split(a: np.ndarray, sizes) -> list:
    return [a[s:s + n] for s, n in zip(_offsets(sizes).tolist(), sizes)]


class _Union:
    """The members' models and contacts one after the other: vertices, blocks and contacts, with
    the vertex and block indices moved by the members' before each (the indices kept while the
    same members come again: `ddatai.stage_batch_index`)."""

    def __init__(self, models, contacts, fields=()):
        index = contact_index(models, contacts)
        self.counts = index.counts
        self.model = kept("union", tuple(models), lambda: _models(models))
        self.contacts = SimpleNamespace(
            cint=index.cint, n=index.n, block_a=index.block_a, block_b=index.block_b,
            **{f: np.concatenate([getattr(c, f) for c in contacts]) for f in fields})


def _models(models) -> SimpleNamespace:
    v_at = _offsets([len(m.vertex_block) for m in models])
    b_at = _offsets([m.n_blocks for m in models])
    return SimpleNamespace(
        vertex_next=frozen(np.concatenate([m.vertex_next.astype(np.int64) + o for m, o in zip(models, v_at.tolist())])),
        vertex_block=frozen(np.concatenate([m.vertex_block.astype(np.int64) + o for m, o in zip(models, b_at.tolist())])))


def _rotating(model, contacts, rotation) -> bool:
    return bool(model.numpy_path and contacts.n and np.any(rotation) and not len(model.fixed_point_block))


# ------------------------------------------------------------------ second-order terms
_SECOND_ARGS = ("model", "contacts", "state", "geom", "rotation", "rhs")


def second_order_group(*args, **kwargs):
    model, contacts, _, _, rotation, _ = _bound(args, kwargs, _SECOND_ARGS)
    return ("second_order",) if _rotating(model, contacts, rotation) else None


def second_order_many(requests) -> list:
    """`assembly.second_order` of each request (rotating members without fixed points)."""
    args = [_bound(a, kw, _SECOND_ARGS) for a, kw in requests]
    models, contacts = [a[0] for a in args], [a[1] for a in args]
    u = _Union(models, contacts, ("omega",))
    state = SimpleNamespace(vertex_xy=np.concatenate([a[2].vertex_xy for a in args]))
    geom = {"centroid": np.concatenate([a[3]["centroid"] for a in args])}
    model = SimpleNamespace(numpy_path=True, fixed_point_block=(), **vars(u.model))
    shift = second_order.__wrapped__(model, u.contacts, state, geom, np.concatenate([a[4] for a in args]), None)
    return _split(shift, u.counts)


# ------------------------------------------------------------------ mid-step lever arms
_LEVER_ARGS = ("model", "contacts", "vertex_xy", "centroid", "rotation")


def lever_arms_group(*args, **kwargs):
    model, contacts, _, _, rotation = _bound(args, kwargs, _LEVER_ARGS)
    return ("lever_arms",) if _rotating(model, contacts, rotation) else None


def lever_arms_many(requests) -> list:
    """`lever_arm.midstep_lever_arms` of each request (rotating members)."""
    args = [_bound(a, kw, _LEVER_ARGS) for a, kw in requests]
    u = _Union([a[0] for a in args], [a[1] for a in args])
    columns, shift = midstep_lever_arms.__wrapped__(u.model, u.contacts, np.concatenate([a[2] for a in args]),
                                                    np.concatenate([a[3] for a in args]),
                                                    np.concatenate([a[4] for a in args]))
    return list(zip(_split(columns, u.counts), _split(shift, u.counts)))


# ------------------------------------------------------------------ the state test
_VIOLATION_ARGS = ("model", "contacts", "law", "block_load")
_VIOLATION_FIELDS = ("state", "bond", "tensile", "length", "line")
_LAW_FIELDS = ("fn", "ft", "strength", "dn", "dn_now", "fn_now", "ft_now", "friction_now", "closed", "line")


def violations_group(*args, **kwargs):
    model, contacts, law, _ = _bound(args, kwargs, _VIOLATION_ARGS)
    if not model.numpy_path or contacts.n == 0 or law.packed is not None:
        return None
    p = model.params
    return ("violations", float(p.oc_force_tolerance), str(p.oc_force_reference), float(p.oc_state_tolerance),
            float(model.force_roundoff), float(model.penalty))


def violations_many(requests) -> list:
    """``contact_law.violations_numpy`` of each request: one state test over all."""
    args = [_bound(a, kw, _VIOLATION_ARGS) for a, kw in requests]
    models = [a[0] for a in args]
    u = _Union(models, [a[1] for a in args], _VIOLATION_FIELDS)
    m0 = models[0]
    model = SimpleNamespace(params=m0.params, force_roundoff=m0.force_roundoff, penalty=m0.penalty,
                            block_fixed=np.concatenate([m.block_fixed for m in models]))
    law = SimpleNamespace(**{f: np.concatenate([getattr(a[2], f) for a in args]) for f in _LAW_FIELDS})
    bad = violations_numpy.__wrapped__(model, u.contacts, law, np.concatenate([a[3] for a in args]))
    return _split(bad, u.counts)


# ------------------------------------------------------------------ the return mapping's judgement
_UPDATE_ARGS = ("model", "contacts", "law", "guess", "flips", "freeze", "shearing", "weight", "tensile",
                "force_tolerance", "chatter_flips")


def iterate_update_group(*args, **kwargs):
    model, contacts, *_, force_tolerance, chatter_flips = _bound(args, kwargs, _UPDATE_ARGS)
    if not model.numpy_path or contacts.n == 0:
        return None
    return ("iterate_update", float(model.penalty), float(model.shear_penalty),
            float(model.params.oc_state_tolerance), float(model.force_roundoff), float(force_tolerance),
            int(chatter_flips))


def iterate_update_many(requests) -> list:
    """`return_update.iterate_update` of each request: one judgement over all the members'
    contacts (each block's load level over its own contacts)."""
    args = [_bound(a, kw, _UPDATE_ARGS) for a, kw in requests]
    models = [a[0] for a in args]
    u = _Union(models, [a[1] for a in args])
    m0 = models[0]
    model = SimpleNamespace(params=m0.params, penalty=m0.penalty, shear_penalty=m0.shear_penalty,
                            force_roundoff=m0.force_roundoff)
    law = SimpleNamespace(**{f: np.concatenate([getattr(a[2], f) for a in args])
                             for f in ("fn", "closed", "dn", "dn_now", "line", "ds", "strength")})
    guess = SimpleNamespace(**{f: np.concatenate([getattr(a[3], f) for a in args]) for f in ("closed", "line", "gap")})
    cat = [np.concatenate([a[k] for a in args]) for k in (4, 6, 7, 8)]
    freeze = np.repeat(np.array([bool(a[5]) for a in args]), u.counts)
    out = iterate_update.__wrapped__(model, u.contacts, law, guess, cat[0], freeze, cat[1], cat[2], cat[3],
                                     args[0][9], args[0][10])
    parts = [_split(x, u.counts) for x in out]
    return [Update(*p) for p in zip(*parts)]
