"""The key-group search (docs/kgm/method.md §3.2–3.4): candidates (`kgm.candidates`) judged by
a limit-equilibrium judge (`JUDGES`), cached per round, grown greedily; and the enumeration of
every connected key group of a few blocks that checks it.

Key group (§3.2): a connected set of free blocks that contains a key block (a removable block
with a free face: types I, II and III — a seed need not fail on its own), has a free face, is
removable as a whole (the half-circle test on its boundary normals) and is active (the judge
finds a failure mode). Every key block is a seed; a seed grows by the neighbour that lowers FS
most while the group stays a key group, until no neighbour lowers it by more than
`kgm.Settings.growth_tolerance` (§3.3–3.4). A toppling row is also grown upslope. The ranking
of groups (`rank_key`) uses the one tie rule of kgm (`kgm.judges.evaluation.tie_key`). The
entry points that run rounds of it are `kgm.analysis`.
"""

from __future__ import annotations

import importlib
import math
from dataclasses import dataclass
from typing import Optional

from .candidates import connected_groups, key_blocks, mobile_neighbours, upslope_neighbours
from .faces import has_free_face, is_connected, is_removable
from .judges.evaluation import Evaluation, tie_key
from .judges.rigid import evaluate_rigid
from .judges.sarma import evaluate_sarma
from .kinds import Method
from .settings import Settings
from .system import BlockSystem

#: The names this module held before the entry points moved up to `kgm.analysis` and the rows
#: to `kgm.report`, and their homes now (``module`` or ``module:name``): they resolve on first use (PEP 562), for one release,
#: so that old imports keep working without the search importing what stands above it.
FORMER_NAMES = {
    "analyze": "analysis", "evaluate": "analysis", "factor_of_safety": "analysis",
    "critical_friction": "analysis", "exhaustive": "analysis",
    "GroupResult": "report", "Report": "report", "contact_polylines": "report",
    "build_block_system": "build", "check_group": "faces", "classify_blocks": "judges.rigid",
    "critical_friction_of": "judges.evaluation", "METHODS": "kinds:METHOD_NAMES",
}

#: The limit-equilibrium judge of each method that can screen candidates.
JUDGES = {Method.RIGID: evaluate_rigid, Method.SARMA: evaluate_sarma}


class CachedJudge:
    """A limit-equilibrium judge with a per-round cache of group evaluations (the system and the
    removed blocks are the round's; `kgm.BlockSystem` stays a frozen value)."""

    def __init__(self, system: BlockSystem, method: Method, removed: frozenset = frozenset()):
        self.system, self.removed = system, removed
        self.judge = JUDGES[method]
        self.cache: dict[frozenset, Evaluation] = {}

    def __call__(self, blocks: frozenset) -> Evaluation:
        ev = self.cache.get(blocks)
        if ev is None:
            ev = self.judge(self.system, blocks, self.removed)
            self.cache[blocks] = ev
        return ev


@dataclass(frozen=True, kw_only=True, eq=False)
class Found:
    """A key group found by a round of the search."""

    blocks: frozenset
    """Block ids of the group."""
    evaluation: Evaluation
    """Its limit-equilibrium evaluation."""
    seed: int
    """The key block it was grown from."""


def search_round(system: BlockSystem, judge: CachedJudge, settings: Settings,
                 removed: frozenset = frozenset()) -> list[Found]:
    """One round of the search (§3.3): every key block grown into a group; the key groups,
    each once, in the order of their seeds."""
    seeds = key_blocks(system, removed)
    found: dict[frozenset, Found] = {}
    for seed in seeds:
        group, ev = grow(system, seed, judge, seeds, settings, removed)
        if group in found or not is_key_group(system, group, ev, seeds, removed):
            continue
        found[group] = Found(blocks=group, evaluation=ev, seed=seed)
    return list(found.values())


def every_key_group(system: BlockSystem, judge: CachedJudge, max_size: int,
                    removed: frozenset = frozenset()) -> list[tuple[frozenset, Evaluation]]:
    """All key groups of up to ``max_size`` blocks with their evaluations, in enumeration order
    (exponential: for small models and for checking the greedy search, §3.3)."""
    seeds = key_blocks(system, removed)
    out = []
    for g in connected_groups(system, max_size, removed):
        ev = judge(g)
        if is_key_group(system, g, ev, seeds, removed):
            out.append((g, ev))
    return out


def rank_key(fs: float, blocks: frozenset) -> tuple:
    """Ranking key of groups: FS (`tie_key`: equal to 9 significant digits counts as a tie, the
    same plane reached through different groups differs only by round-off), then fewer blocks,
    then ids."""
    return (tie_key(fs), len(blocks), sorted(blocks))


# ---------------------------------------------------------------------- key groups
def is_key_group(system: BlockSystem, blocks: frozenset, evaluation: Evaluation, seeds,
                 removed: frozenset = frozenset()) -> bool:
    """§3.2: contains a key block, free face, removable (finite: no fixed member), active
    (a failure mode exists), connected."""
    if any(system.block_fixed[b] or b in removed for b in blocks):
        return False
    return (bool(set(blocks) & set(seeds)) and has_free_face(system, blocks, removed)
            and is_removable(system, blocks, removed) and math.isfinite(evaluation.fs)
            and is_connected(system, blocks))


def grow(system: BlockSystem, seed: int, evaluate, seeds, settings: Settings,
         removed: frozenset = frozenset()) -> tuple[frozenset, Evaluation]:
    """Greedy growth from a seed (§3.3): add the neighbour that lowers FS most while the group
    stays a key group; stop when none lowers it by more than the tolerance.

    When no single neighbour helps and the group is a toppling row (`kgm.candidates`), the row
    is also grown upslope one leaning block at a time to its top: the blocks above add their
    push only once a toppling one is reached (Goodman & Bray's upper blocks are stable, their
    toe blocks slide), so the least safe of these longer rows is taken, if it lowers FS."""
    group = frozenset([seed])
    ev = evaluate(group)
    while True:
        best = None
        if len(group) < settings.max_group_size:
            for nb in mobile_neighbours(system, group, removed):
                g2 = group | {nb}
                ev2 = evaluate(g2)
                if not is_key_group(system, g2, ev2, seeds, removed):
                    continue
                if ev2.fs < ev.fs - settings.growth_tolerance and (best is None or ev2.fs < best[1].fs):
                    best = (g2, ev2)
        if best is None:
            best = _grow_row(system, group, ev, evaluate, seeds, settings, removed)
        if best is None:
            break
        group, ev = best
    return group, ev


def _grow_row(system: BlockSystem, group: frozenset, ev: Evaluation, evaluate, seeds, settings: Settings,
              removed: frozenset) -> Optional[tuple[frozenset, Evaluation]]:
    """The least safe toppling row made of the group and the blocks leaning on it from upslope,
    one after the other (a block joins if the row stays a row with it on top), if it lowers FS
    by more than the tolerance; else None."""
    best = None
    row = group
    while len(row) < max(settings.max_row_size, len(group) + 1):
        above = upslope_neighbours(system, row, removed)
        if len(above) != 1:
            break  # the row ends (or forks: not a single row)
        row = row | {above[0]}
        ev2 = evaluate(row)
        if not is_key_group(system, row, ev2, seeds, removed):
            continue
        if ev2.fs < ev.fs - settings.growth_tolerance and (best is None or ev2.fs < best[1].fs):
            best = (row, ev2)
    return best


def __getattr__(name: str):
    """A former name of this module (`FORMER_NAMES`), from its new home."""
    home = FORMER_NAMES.get(name)
    if home is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    module, _, attribute = home.partition(":")
    return getattr(importlib.import_module(f"kgm.{module}"), attribute or name)
