"""The key-group search (docs/kgm/method.md §3): seeds, greedy growth, least safe group,
progressive removal; an exhaustive enumeration of connected groups to cross-check it; and
the public one-group evaluations.

Key group (§3.2): a connected set of free blocks that contains a key block (a removable block
with a free face: types I, II and III — a seed need not fail on its own), has a free face, is
removable as a whole (the half-circle test on its boundary normals) and is active (the
evaluator finds a failure mode). Every key block is a seed; a seed grows by the neighbour that
lowers FS most while the group stays a key group, until no neighbour lowers it by more than
`Settings.growth_tolerance` (§3.3–3.4). The least safe of the grown groups is the critical
group; in progressive mode it is removed (its contacts with the remaining blocks become free
faces) if unstable, and the search repeats until the least safe group is stable.

With ``method="dda"`` the limit-equilibrium evaluator named by `Settings.screening` proposes
the groups (a DDA simulation per candidate merge would be far too slow, §3.6) and DDA judges
the least safe `DdaSettings.candidates` of them on their real geometry, as in the paper's
procedure: KGM selects the key group, DDA analyses it.
"""

from __future__ import annotations

import math
import time
from typing import Iterator, Optional

import numpy as np

from .blocks import (BlockSystem, build_block_system, check_group, classify_blocks, has_free_face,
                     is_connected, is_removable)
from .evaluators import Evaluation, critical_friction_of, evaluate_rigid, evaluate_sarma, tie_key
from .kinds import METHODS, Method
from .report import GroupResult, Report, contact_polylines
from .toppling import upslope_neighbours
from .settings import Settings



def _check_method(method: str, seismic=None) -> Method:
    method = Method.of(method)
    if method is Method.DDA and seismic is not None:
        raise ValueError("seismic coefficients are a limit-equilibrium load ('rigid' or 'sarma'); a DDA "
                         "run is dynamic: give the scene a ground acceleration instead")
    return method


def _check_scene(scene):
    from ddatai.scene import Scene

    if not isinstance(scene, Scene):
        raise ValueError(f"scene must be a ddatai.Scene, got {type(scene).__name__}")
    if scene.n_blocks == 0:
        raise ValueError("the scene has no blocks")
    return scene


class _Evaluator:
    """A limit-equilibrium evaluator with a per-round cache of group evaluations."""

    JUDGES = {Method.RIGID: evaluate_rigid, Method.SARMA: evaluate_sarma}

    def __init__(self, system: BlockSystem, method: Method, settings: Settings, removed: frozenset):
        self.system, self.settings, self.removed = system, settings, removed
        self.judge = self.JUDGES[method]
        self.cache: dict[frozenset, Evaluation] = {}

    def __call__(self, blocks: frozenset) -> Evaluation:
        ev = self.cache.get(blocks)
        if ev is None:
            ev = self.judge(self.system, blocks, self.removed)
            self.cache[blocks] = ev
        return ev


# ---------------------------------------------------------------------- key groups
def key_blocks(system: BlockSystem, removed: frozenset = frozenset()) -> list[int]:
    """Seeds of the search: free blocks with a free face that are removable on their own
    (types I, II and III, §3.2 condition 1)."""
    return [b for b in range(system.n_blocks)
            if b not in removed and not system.block_fixed[b]
            and has_free_face(system, [b], removed) and is_removable(system, frozenset([b]), removed)]


def is_key_group(system: BlockSystem, blocks: frozenset, evaluation: Evaluation, seeds,
                 removed: frozenset = frozenset()) -> bool:
    """§3.2: contains a key block, free face, removable (finite: no fixed member), active
    (a failure mode exists), connected."""
    if any(system.block_fixed[b] or b in removed for b in blocks):
        return False
    return (bool(set(blocks) & set(seeds)) and has_free_face(system, blocks, removed)
            and is_removable(system, blocks, removed) and math.isfinite(evaluation.fs)
            and is_connected(system, blocks))


def _mobile_neighbours(system: BlockSystem, blocks: frozenset, removed: frozenset) -> list[int]:
    return sorted(b for b in system.neighbours(blocks, removed) if not system.block_fixed[b])


def grow(system: BlockSystem, seed: int, evaluate, seeds, settings: Settings,
         removed: frozenset = frozenset()) -> tuple[frozenset, Evaluation]:
    """Greedy growth from a seed (§3.3): add the neighbour that lowers FS most while the group
    stays a key group; stop when none lowers it by more than the tolerance.

    When no single neighbour helps and the group is a toppling row (`kgm.toppling`), the row
    is also grown upslope one leaning block at a time to its top: the blocks above add their
    push only once a toppling one is reached (Goodman & Bray's upper blocks are stable, their
    toe blocks slide), so the least safe of these longer rows is taken, if it lowers FS."""
    group = frozenset([seed])
    ev = evaluate(group)
    while True:
        best = None
        if len(group) < settings.max_group_size:
            for nb in _mobile_neighbours(system, group, removed):
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


def connected_groups(system: BlockSystem, max_size: int, removed: frozenset = frozenset()) -> Iterator[frozenset]:
    """Every connected set of free, remaining blocks with at most ``max_size`` members, each
    once (the ESU enumeration of connected induced subgraphs)."""
    nodes = [b for b in range(system.n_blocks) if b not in removed and not system.block_fixed[b]]
    adj = {b: set(_mobile_neighbours(system, frozenset([b]), removed)) for b in nodes}

    def extend(sub: frozenset, ext: list, v: int, closed_nb: set):
        yield sub
        if len(sub) == max_size:
            return
        ext = list(ext)
        while ext:
            w = ext.pop()
            new = [u for u in adj[w] if u > v and u not in closed_nb and u not in ext]
            yield from extend(sub | {w}, ext + sorted(new), v, closed_nb | adj[w] | {w})

    for v in nodes:
        yield from extend(frozenset([v]), sorted(u for u in adj[v] if u > v), v, adj[v] | {v})


def exhaustive(scene, method: str = Method.SARMA, *, max_size: int = 4, settings: Optional[Settings] = None,
               removed: frozenset = frozenset(), seismic=None) -> list[tuple[frozenset, float]]:
    """All key groups of up to ``max_size`` blocks with their limit-equilibrium FS, least safe
    first (exponential: for small models and for checking the greedy search, §3.3)."""
    method = _check_method(method)
    if method is Method.DDA:
        raise ValueError("exhaustive: method must be 'rigid' or 'sarma' (a DDA run per group is "
                         "too slow for an enumeration)")
    settings = settings or Settings()
    system = build_block_system(_check_scene(scene), seismic=seismic, contact_gap=settings.contact_gap)
    evaluate = _Evaluator(system, method, settings, frozenset(removed))
    seeds = key_blocks(system, frozenset(removed))
    out = []
    for g in connected_groups(system, max_size, frozenset(removed)):
        ev = evaluate(g)
        if is_key_group(system, g, ev, seeds, frozenset(removed)):
            out.append((g, ev.fs))
    return sorted(out, key=lambda x: _order(x[1], x[0]))


# ---------------------------------------------------------------------- results
def _le_result(system: BlockSystem, blocks: frozenset, ev: Evaluation, method: Method, settings: Settings,
               seed: Optional[int] = None, iteration: int = 0) -> GroupResult:
    return GroupResult(blocks=blocks, fs=ev.fs, critical_friction=critical_friction_of(ev),
                       stable=ev.fs >= settings.fs_target, mode=ev.mode,
                       surface=contact_polylines(system, ev.mode.sliding_contacts), evaluator=method,
                       seed=seed, iteration=iteration, modes=ev.modes, rejected=ev.rejected,
                       **_loads_of(system, blocks, ev))


def _loads_of(system: BlockSystem, blocks: frozenset, ev: Evaluation) -> dict:
    """The water, bolt and seismic loads of a group for its report row (only those present)."""
    members = sorted(blocks)
    out = {}
    if system.contact_water is not None:
        surface = np.concatenate([ev.mode.sliding_contacts, ev.mode.sheared_contacts]).astype(np.int64)
        out["water_force"] = float(system.contact_water[np.unique(surface)].sum())
    if system.block_bolt is not None:
        out["bolt_force"] = float(np.hypot(*(system.block_bolt[members] + system.block_passive[members]).sum(axis=0)))
    if system.block_seismic is not None:
        out["seismic"] = system.seismic
    return out


def _dda_result(scene, system: BlockSystem, le: GroupResult, settings: Settings, params,
                removed: frozenset) -> GroupResult:
    from .dda import evaluate_dda

    dres = evaluate_dda(scene, system, le.blocks, settings=settings.dda, params=params, removed=removed,
                        fs_guess=le.fs, friction_guess=le.critical_friction)
    return GroupResult(blocks=le.blocks, fs=dres.fs, critical_friction=dres.critical_friction,
                       stable=dres.judgement.stable, mode=le.mode, surface=le.surface, evaluator=Method.DDA,
                       seed=le.seed, iteration=le.iteration, dda=dres, water_force=le.water_force,
                       bolt_force=le.bolt_force, seismic=le.seismic, modes=le.modes, rejected=le.rejected)


def _order(fs: float, blocks: frozenset) -> tuple:
    """Ranking key: FS (equal to 9 significant digits counts as a tie: the same plane reached
    through different groups differs only by round-off), then fewer blocks, then ids."""
    return (tie_key(fs), len(blocks), sorted(blocks))


def _rank(results: list[GroupResult]) -> list[GroupResult]:
    return sorted(results, key=lambda g: _order(g.fs, g.blocks))


def _round(scene, system: BlockSystem, method: Method, settings: Settings, params, removed: frozenset,
           iteration: int) -> list[GroupResult]:
    """One search round: candidate key groups, least safe first (DDA-judged ones first)."""
    le_method = method.screened_by(settings.screening)
    evaluate = _Evaluator(system, le_method, settings, removed)
    seeds = key_blocks(system, removed)
    found: dict[frozenset, GroupResult] = {}
    for seed in seeds:
        group, ev = grow(system, seed, evaluate, seeds, settings, removed)
        if group in found or not is_key_group(system, group, ev, seeds, removed):
            continue
        found[group] = _le_result(system, group, ev, le_method, settings, seed=seed, iteration=iteration)
    ranked = _rank(list(found.values()))
    if method is Method.DDA and ranked:
        n = settings.dda.candidates
        judged = _rank([_dda_result(scene, system, g, settings, params, removed) for g in ranked[:n]])
        ranked = judged + ranked[n:]
    return ranked


def analyze(scene, method: str = Method.SARMA, progressive: bool = False, *, settings: Optional[Settings] = None,
            params=None, seismic=None) -> Report:
    """Key Group Method analysis of a scene (docs/kgm/method.md §3).

    Parameters
    ----------
    scene : ddatai.Scene
        The block system; fixed blocks are the stable rock (type V).
    method : 'rigid' (KGM), 'sarma' (SKGM) or 'dda' (KGM + DDA, the seed paper's method).
    progressive : remove the least safe group while it is unstable and search again.
    settings : `kgm.Settings` (search and DDA settings); None: defaults.
    params : `ddatai.Params` of the DDA runs (e.g. the scene module's), unless
        ``settings.dda.params`` is given.
    seismic : pseudo-static seismic coefficients (kh, kv) [-] (or kh alone): a force
        (kh·W, kv·W) on every block, kh positive towards +x, kv positive upwards (rigid and
        sarma only). The scene's water table and bolts are always included
        (docs/method/water_bolts.md); a scene with a ground acceleration or a time-varying
        point load is refused (ValueError).
    """
    t0 = time.perf_counter()
    method = _check_method(method, seismic)
    settings = settings or Settings()
    if not isinstance(settings, Settings):
        raise ValueError(f"settings must be a kgm.Settings, got {type(settings).__name__}")
    system = build_block_system(_check_scene(scene), seismic=seismic, contact_gap=settings.contact_gap)
    removed: frozenset = frozenset()
    history, removal, first = [], [], None
    for it in range(settings.max_iterations):
        ranked = _round(scene, system, method, settings, params, removed, it)
        if first is None:
            first = ranked
        if not ranked:
            break
        crit = ranked[0]
        history.append(crit)
        if not progressive or crit.stable:
            break
        removal.append(crit.blocks)
        removed = removed | crit.blocks
    if progressive and removal:
        gone = frozenset().union(*removal)
        cb = system.contact_blocks
        edge = np.flatnonzero(np.isin(cb[:, 0], list(gone)) ^ np.isin(cb[:, 1], list(gone)))
        surface = contact_polylines(system, edge)
    else:
        surface = history[0].surface if history else ()
    return Report(method=method, critical=first[0] if first else None, groups=tuple(first or ()),
                  block_types=classify_blocks(system), history=tuple(history), removed=tuple(removal),
                  failure_surface=surface, fs_target=settings.fs_target, wall_time=time.perf_counter() - t0)


# ---------------------------------------------------------------------- one group
def evaluate(scene, blocks, method: str = Method.SARMA, *, settings: Optional[Settings] = None,
             params=None, seismic=None) -> GroupResult:
    """Evaluate one group (any connected set of free blocks) with one evaluator: FS, critical
    friction angle, governing mode, failure surface, verdict (``seismic`` as in `analyze`)."""
    method = _check_method(method, seismic)
    settings = settings or Settings()
    system = build_block_system(_check_scene(scene), seismic=seismic, contact_gap=settings.contact_gap)
    group = check_group(system, blocks)
    if not is_connected(system, group):
        raise ValueError(f"group {sorted(group)} is not connected: its blocks must share contacts")
    le_method = method.screened_by(settings.screening)
    ev = _Evaluator(system, le_method, settings, frozenset())(group)
    le = _le_result(system, group, ev, le_method, settings)
    return _dda_result(scene, system, le, settings, params, frozenset()) if method is Method.DDA else le


def factor_of_safety(scene, blocks, method: str = Method.SARMA, *, settings: Optional[Settings] = None,
                     params=None, seismic=None) -> float:
    """Factor of safety of a group [-] (inf: the group has no failure mode; ``seismic`` as
    in `analyze`)."""
    method = _check_method(method, seismic)
    if method is not Method.DDA:
        return evaluate(scene, blocks, method, settings=settings, seismic=seismic).fs
    return _judge_with_dda(scene, blocks, settings, params, fs=True).fs


def critical_friction(scene, blocks, method: str = Method.SARMA, *, settings: Optional[Settings] = None,
                      params=None, seismic=None) -> float:
    """Friction angle of all joints (cohesion held) at which the group reaches limit
    equilibrium [degrees]: closed form for 'rigid' (§4.6), bisection for 'sarma' and 'dda'."""
    method = _check_method(method, seismic)
    if method is not Method.DDA:
        return evaluate(scene, blocks, method, settings=settings, seismic=seismic).critical_friction
    return _judge_with_dda(scene, blocks, settings, params, fs=False).critical_friction


def _judge_with_dda(scene, blocks, settings: Optional[Settings], params, fs: bool):
    """DDA evaluation of one group for either the factor of safety (``fs``) or the critical
    friction, bracketed from the screening method's answer."""
    settings = settings or Settings()
    system = build_block_system(_check_scene(scene), contact_gap=settings.contact_gap)
    group = check_group(system, blocks)
    le = evaluate(scene, group, settings.screening, settings=settings)
    from .dda import evaluate_dda

    if fs:
        return evaluate_dda(scene, system, group, settings=settings.dda, params=params, fs_guess=le.fs,
                            with_friction=False)
    return evaluate_dda(scene, system, group, settings=settings.dda, params=params,
                        friction_guess=le.critical_friction, with_fs=False)
