"""The members' index structure of a side-by-side evaluation (`ddatai.stage_batch`,
`ddatai.stage_batch_finish`), kept while the same members come again (docs/guide/performance.md,
"Batched studies").

An operation over many members concatenates their contacts with every vertex, block, CSR-row and
CSR-slot index moved by the members' before it. Those moved indices depend only on the members'
models, their contacts' ``cint``, ``block_a``, ``block_b`` and their sparsity patterns, which no
one writes in place: the same contacts come back iterate after iterate of a pseudo-step (a
return mapping's 10–100 iterates, an open-close finish's solves), and so do the same members,
waiting together at the same operation. So each union of indices is made once and kept, keyed by
the identity of the arrays it was made from, which it holds (an identity is then never another
array's), the last ``KEPT`` of them. The result is the same arrays, so each member's floats stay
its own, to the bit (tests/test_stage_batch.py).
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from .side_by_side import offsets

#: unions kept (a batch's members wait in a few groups at a time; each entry holds a few arrays
#: of the members' contacts)
KEPT = 64
_KEPT: dict = {}


def kept(kind, sources: tuple, make):
    """``make()``, the union of ``kind`` (hashable: a name with any sizes it depends on) made
    from ``sources`` (arrays and models that no one writes in place), made once while the same
    ``sources`` come again."""
    key = (kind,) + tuple(map(id, sources))
    hit = _KEPT.get(key)
    if hit is not None:
        return hit[1]
    value = make()
    if len(_KEPT) >= KEPT:
        del _KEPT[next(iter(_KEPT))]
    _KEPT[key] = (sources, value)  # holding the sources keeps their identities theirs
    return value


def frozen(a: np.ndarray) -> np.ndarray:
    a.setflags(write=False)  # kept for later calls: never written (an operation that did would raise)
    return a


def contact_index(models, contacts) -> SimpleNamespace:
    """The members' contacts one after the other: ``counts`` (list), ``at`` (where each member's
    start), ``cint`` with its vertices and ``block_a``, ``block_b`` with their blocks moved by the
    members' before each (int64)."""
    sources = tuple(models) + tuple(x for c in contacts for x in (c.cint, c.block_a, c.block_b))

    def make():
        counts = [len(c.cint) for c in contacts]
        v_at = offsets([len(m.vertex_block) for m in models])
        b_at = offsets([m.n_blocks for m in models])
        local = np.concatenate([c.cint for c in contacts])
        at_v = np.repeat(v_at, counts)[:, None]
        cint = np.concatenate([local[:, :1], np.where(local[:, 1:] >= 0, local[:, 1:] + at_v, local[:, 1:])], axis=1)
        at_b = np.repeat(b_at, counts)
        return SimpleNamespace(counts=counts, at=frozen(offsets(counts)), n=int(sum(counts)), cint=frozen(cint),
                               block_a=frozen(np.concatenate([c.block_a for c in contacts]) + at_b),
                               block_b=frozen(np.concatenate([c.block_b for c in contacts]) + at_b))
    return kept("contacts", sources, make)
