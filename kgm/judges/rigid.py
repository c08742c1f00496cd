"""The rigid judge (KGM, docs/kgm/method.md §4): the group glued into one rigid body, limit
equilibrium on its admissible modes (lifting, sliding on a face, rotation about a vertex), and
its block toppling (`kgm.judges.toppling`)."""

from __future__ import annotations

from ..blocks import BlockSystem, rigid_modes
from ..toppling import with_toppling
from .evaluation import Evaluation, governing


def evaluate_rigid(system: BlockSystem, blocks: frozenset, removed: frozenset = frozenset()) -> Evaluation:
    """KGM: the group as one rigid body (docs/kgm/method.md §4), and its block toppling."""
    rejected: list[str] = []
    modes = rigid_modes(system, blocks, removed, rejected=rejected)
    return governing(with_toppling(system, blocks, removed, modes, rejected), rejected)
