"""The analyses of kgm (docs/kgm/method.md §3, docs/kgm/architecture.md): `analyze`, `evaluate`,
`factor_of_safety`, `critical_friction` and `exhaustive`.

Each entry point checks its method, prepares the `kgm.build.Problem` once (the scene's block
system, the settings, the DDA parameters; `kgm.build.prepare`) and passes it down. `analyze`
reads like the method: each round, the key groups grown from the key blocks and judged by limit
equilibrium (`kgm.search`), their rows (`kgm.report`), least safe first; with ``method="dda"``
DDA judges the least safe `kgm.DdaSettings.candidates` of them on their real geometry, as in the
paper's procedure — KGM selects the key group, DDA analyses it (a DDA run per candidate merge
would be far too slow, §3.6); in progressive mode the critical group is removed while it is
unstable (its contacts with the remaining blocks become free faces) and the search repeats.

The functions on a prepared problem (`analyze_problem`, `evaluate_group`, `judge_by_dda`) are
what the studies (`kgm.studies`) run for each sample.
"""

from __future__ import annotations

import time
from typing import Optional

import numpy as np

from .build import Problem, prepare
from .faces import check_connected_group, check_group
from .judges.dda import dda_evaluation
from .judges.rigid import classify_blocks
from .kinds import Method
from .report import GroupResult, Report, contact_polylines, group_result, judged_by_dda
from .search import JUDGES, CachedJudge, every_key_group, rank_key, search_round
from .settings import Settings


def check_method(method, seismic=None) -> Method:
    """The method named ``method`` (ValueError otherwise); a seismic load needs limit equilibrium."""
    method = Method.of(method)
    if method is Method.DDA and seismic is not None:
        raise ValueError("seismic coefficients are a limit-equilibrium load ('rigid' or 'sarma'); a DDA "
                         "run is dynamic: give the scene a ground acceleration instead")
    return method


def rank(results: list[GroupResult]) -> list[GroupResult]:
    """Groups least safe first (`kgm.search.rank_key`)."""
    return sorted(results, key=lambda g: rank_key(g.fs, g.blocks))


# ---------------------------------------------------------------------- a whole slope
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
    method = check_method(method, seismic)
    problem = prepare(scene, settings=settings, params=params, seismic=seismic)
    return analyze_problem(problem, method, progressive, started=t0)


def analyze_problem(problem: Problem, method: Method, progressive: bool = False, *,
                    started: Optional[float] = None) -> Report:
    """`analyze` on a prepared problem (``started``: the ``time.perf_counter()`` its wall time
    counts from; None: now)."""
    t0 = time.perf_counter() if started is None else started
    settings, system = problem.settings, problem.system
    removed: frozenset = frozenset()
    history, removal, first = [], [], None
    for it in range(settings.max_iterations):
        ranked = _round(problem, method, removed, it)
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


def _round(problem: Problem, method: Method, removed: frozenset, iteration: int) -> list[GroupResult]:
    """One search round: candidate key groups, least safe first (DDA-judged ones first)."""
    settings, system = problem.settings, problem.system
    screening = method.screened_by(settings.screening)
    found = search_round(system, CachedJudge(system, screening, removed), settings, removed)
    ranked = rank([group_result(system, f.blocks, f.evaluation, screening, settings.fs_target, seed=f.seed,
                                iteration=iteration) for f in found])
    if method is Method.DDA and ranked:
        n = settings.dda.candidates
        judged = rank([judge_by_dda(problem, g, removed) for g in ranked[:n]])
        ranked = judged + ranked[n:]
    return ranked


def exhaustive(scene, method: str = Method.SARMA, *, max_size: int = 4, settings: Optional[Settings] = None,
               removed: frozenset = frozenset(), seismic=None) -> list[tuple[frozenset, float]]:
    """All key groups of up to ``max_size`` blocks with their limit-equilibrium FS, least safe
    first (exponential: for small models and for checking the greedy search, §3.3)."""
    method = check_method(method)
    if method is Method.DDA:
        raise ValueError("exhaustive: method must be 'rigid' or 'sarma' (a DDA run per group is "
                         "too slow for an enumeration)")
    problem = prepare(scene, settings=settings, seismic=seismic)
    removed = frozenset(removed)
    found = every_key_group(problem.system, CachedJudge(problem.system, method, removed), max_size, removed)
    return sorted(((g, ev.fs) for g, ev in found), key=lambda x: rank_key(x[1], x[0]))


# ---------------------------------------------------------------------- one group
def evaluate(scene, blocks, method: str = Method.SARMA, *, settings: Optional[Settings] = None,
             params=None, seismic=None) -> GroupResult:
    """Evaluate one group (any connected set of free blocks) with one evaluator: FS, critical
    friction angle, governing mode, failure surface, verdict (``seismic`` as in `analyze`)."""
    method = check_method(method, seismic)
    return evaluate_group(prepare(scene, settings=settings, params=params, seismic=seismic), blocks, method)


def evaluate_group(problem: Problem, blocks, method: Method) -> GroupResult:
    """`evaluate` on a prepared problem."""
    system, settings = problem.system, problem.settings
    group = check_connected_group(system, blocks)
    screening = method.screened_by(settings.screening)
    row = group_result(system, group, JUDGES[screening](system, group, frozenset()), screening, settings.fs_target)
    return judge_by_dda(problem, row) if method is Method.DDA else row


def judge_by_dda(problem: Problem, row: GroupResult, removed: frozenset = frozenset()) -> GroupResult:
    """A group's limit-equilibrium row judged by DDA (`kgm.judges.dda.dda_evaluation`, the
    brackets placed by the row's FS and critical friction; each run reported to
    `kgm.DdaSettings.progress`)."""
    dda = dda_evaluation(problem, row.blocks, removed=removed, fs_guess=row.fs, friction_guess=row.critical_friction,
                         report=problem.settings.dda.progress)
    return judged_by_dda(row, dda)


def factor_of_safety(scene, blocks, method: str = Method.SARMA, *, settings: Optional[Settings] = None,
                     params=None, seismic=None) -> float:
    """Factor of safety of a group [-] (inf: the group has no failure mode; ``seismic`` as
    in `analyze`)."""
    method = check_method(method, seismic)
    if method is not Method.DDA:
        return evaluate(scene, blocks, method, settings=settings, seismic=seismic).fs
    return _dda_limit(prepare(scene, settings=settings, params=params), blocks, fs=True).fs


def critical_friction(scene, blocks, method: str = Method.SARMA, *, settings: Optional[Settings] = None,
                      params=None, seismic=None) -> float:
    """Friction angle of all joints (cohesion held) at which the group reaches limit
    equilibrium [degrees]: closed form for 'rigid' (§4.6), bisection for 'sarma' and 'dda'."""
    method = check_method(method, seismic)
    if method is not Method.DDA:
        return evaluate(scene, blocks, method, settings=settings, seismic=seismic).critical_friction
    return _dda_limit(prepare(scene, settings=settings, params=params), blocks, fs=False).critical_friction


def _dda_limit(problem: Problem, blocks, fs: bool):
    """DDA evaluation of one group for either the factor of safety (``fs``) or the critical
    friction, bracketed from the screening method's answer."""
    group = check_group(problem.system, blocks)
    row = evaluate_group(problem, group, problem.settings.screening)
    report = problem.settings.dda.progress
    if fs:
        return dda_evaluation(problem, group, fs_guess=row.fs, with_friction=False, report=report)
    return dda_evaluation(problem, group, friction_guess=row.critical_friction, with_fs=False, report=report)
