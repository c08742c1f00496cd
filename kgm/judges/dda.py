"""The DDA judge: a group judged by simulating it with ddatai on its real joint geometry (the
seed paper's developed method; docs/kgm/method.md §6).

A judgement simulates only what it needs: the group and the blocks it touches, which are held
fixed (KGM's "non-members stay in place"); blocks farther away are left out
(`DdaSettings.free_neighbours` lets the touching blocks move and fixes the next ring). The
verdict follows the displacement and velocity criteria documented on `kgm.DdaSettings`
(`kgm.judges.run`). The factor of safety is found by strength reduction (tanφ/F and c/F on every
joint) and the critical friction angle on the friction angle of every joint with cohesion held
(§6.4), each by bisection on verdicts, or by K-sections whose probes run side by side
(`kgm.judges.batch`). The searches' bounds are this module's (`F_LOW`, `F_HIGH`, `PHI_HIGH`).

This module imports Taichi (through `ddatai.simulate`) only inside the functions that run a
simulation, so ``import kgm`` stays light.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Optional

import numpy as np

from ddatai.params import Params
from ddatai.scene import Scene

from ..build import Problem
from ..settings import DdaSettings, Settings
from ..strength import Strength
from ..system import BlockSystem
from .batch import judge_many
from .fused import judged_apart
from .run import DdaJudgement, Report, RunPlan, run_judgement, run_params, sub_scene

#: Bracket of the strength-reduction factor F of the DDA searches: a group stable at F_HIGH has
#: FS inf, one unstable at F_LOW FS 0 [-]; the first probe is the limit-equilibrium guess kept
#: within [GUESS_LOW, GUESS_HIGH] and the bracket grows by F_STEP [-].
F_LOW, F_HIGH = 0.02, 50.0
GUESS_LOW, GUESS_HIGH, F_STEP = 0.1, 10.0, 1.25
#: The critical friction searches: a group unstable at PHI_HIGH has φc 90° [degrees]; the first
#: probe is the guess kept within [0, PHI_GUESS_MAX] and the bracket grows by PHI_STEP.
PHI_HIGH, PHI_GUESS_MAX, PHI_STEP = 89.0, 85.0, 2.0


@dataclass(frozen=True, kw_only=True, eq=False)
class DdaTiming:
    """Per-step wall time of the judgement's sub-model against the whole slope."""

    steps: int
    """Steps timed in each run [-]."""
    sub_step_time: float
    """Mean wall time of a step of the sub-model [s]."""
    whole_step_time: float
    """Mean wall time of a step of the whole slope [s]."""
    sub_blocks: int
    """Blocks in the sub-model [-]."""
    whole_blocks: int
    """Blocks in the whole scene [-]."""

    @property
    def saving(self) -> float:
        """Fraction of the whole-slope time saved [-]."""
        return 1.0 - self.sub_step_time / self.whole_step_time


@dataclass(frozen=True, kw_only=True, eq=False)
class DdaEvaluation:
    """DDA verdict, strength-reduction FS and critical friction angle of a group."""

    fs: float
    """Strength-reduction factor of safety [-] (midpoint of the final bracket, geometric)."""
    critical_friction: float
    """Friction angle of all joints (cohesion held) at the stability limit [degrees]."""
    judgement: DdaJudgement
    """The run at the scene's own strength (F = 1): the verdict."""
    runs: tuple
    """Every `DdaJudgement` made, in order [-]."""
    wall_time: float
    """Wall-clock time of all runs [s]."""
    timing: Optional[DdaTiming] = None
    """Sub-model vs whole slope per-step timing (if `DdaSettings.compare_whole`)."""

    def bracket(self, what: str = "fs") -> tuple[float, float]:
        """The runs around the limit: for ``"fs"`` (largest F judged stable, smallest F judged
        unstable), for ``"friction"`` (largest φ judged unstable, smallest φ judged stable); nan
        where no run was on that side. The first exceeds the second where DDA's verdicts are not
        monotone near the limit — the band in which a run's verdict depends on details of its
        dynamics (docs/kgm/method.md §6.4); ``fs`` and ``critical_friction`` are then its middle."""
        if what == "fs":
            stable = [j.reduction for j in self.runs if j.friction is None and j.stable]
            unstable = [j.reduction for j in self.runs if j.friction is None and not j.stable]
            return (max(stable, default=math.nan), min(unstable, default=math.nan))
        if what == "friction":
            stable = [j.friction for j in self.runs if j.friction is not None and j.reduction == 1.0 and j.stable]
            unstable = [j.friction for j in self.runs if j.friction is not None and j.reduction == 1.0
                        and not j.stable]
            return (max(unstable, default=math.nan), min(stable, default=math.nan))
        raise ValueError(f"DdaEvaluation.bracket: what must be 'fs' or 'friction', got {what!r}")


# ---------------------------------------------------------------------- bisections
def evaluate_dda(scene: Scene, system: BlockSystem, blocks: frozenset, *, settings: DdaSettings,
                 params: Optional[Params] = None, removed: frozenset = frozenset(),
                 fs_guess: float = 1.0, friction_guess: Optional[float] = None,
                 with_fs: bool = True, with_friction: bool = True, report: Report = None) -> DdaEvaluation:
    """`dda_evaluation` of the group in ``scene`` (its ``system``) under ``settings``."""
    return dda_evaluation(Problem.of(scene, system, settings=Settings(dda=settings), params=params), blocks,
                          removed=removed, fs_guess=fs_guess, friction_guess=friction_guess, with_fs=with_fs,
                          with_friction=with_friction, report=report)


def dda_evaluation(problem: Problem, blocks: frozenset, *, removed: frozenset = frozenset(), fs_guess: float = 1.0,
                   friction_guess: Optional[float] = None, with_fs: bool = True, with_friction: bool = True,
                   report: Report = None) -> DdaEvaluation:
    """Verdict at the scene's strength, FS by strength reduction and the critical friction
    angle, each by bisection on DDA verdicts (docs/kgm/method.md §6.4), under the problem's
    `kgm.DdaSettings`. The guesses (the limit-equilibrium values) only place the first bracket;
    ``report`` is called with each judgement as its run ends.

    With ``settings.batch`` > 1 the probes of a round — the verdict, probes of F and of φ — run
    side by side in one model (`kgm.judges.batch.judge_many`) and each bracket is cut into as
    many pieces as it has probes (a K-section instead of a bisection): the same final brackets,
    to the same tolerances, in a few runs instead of a dozen."""
    scene, system, settings, params = problem.scene, problem.system, problem.settings.dda, problem.params
    plan = RunPlan.of(system, blocks, settings, params)
    runs: list[DdaJudgement] = []
    cache: dict[tuple, DdaJudgement] = {}

    def key(friction, reduction):
        return (None if friction is None else round(friction, 9), round(reduction, 12))

    def run(friction=None, reduction=1.0) -> bool:
        k = key(friction, reduction)
        if k not in cache:
            cache[k] = run_judgement(problem, blocks, Strength(friction=friction, reduction=reduction), plan,
                                     removed=removed).judgement
            if report is not None:
                report(cache[k])
            runs.append(cache[k])
        return cache[k].stable

    t0 = time.perf_counter()
    fs = phi = math.nan
    if friction_guess is None:
        friction_guess = float(np.mean(system.contact_friction))
    if settings.batch > 1:
        searches = _searches(settings, fs_guess if with_fs else None, friction_guess if with_friction else None)

        submodels: dict = {}  # the sub-model built once for every round (`kgm.judges.fused.prepare_fused`)

        def judge_round(probes):
            todo = [p for p in dict.fromkeys(probes) if key(*p) not in cache]
            for p, j in zip(todo, judge_many(scene, system, blocks, todo, settings=settings, params=params,
                                             removed=removed, report=report, submodels=submodels)):
                cache[key(*p)] = j
                runs.append(j)
            return [cache[key(*p)].stable for p in probes]

        # on the fused engine each member pays its own stage and run: a round pays by the member
        # and is judged in two passes; today's side-by-side batch shares a step among a round's
        # members, and a round judged at once pays less there
        two_pass = judged_apart(scene, system, blocks, plan, removed=removed, submodels=submodels)
        _k_sections(searches, judge_round, settings.batch, two_pass=two_pass)
        if with_fs:
            fs = searches["fs"].limit(lambda x: math.exp(-x), below=math.inf, above=0.0)
        if with_friction:
            phi = searches["phi"].limit(lambda x: x, below=0.0, above=90.0)
    else:
        run()
        if with_fs:
            fs = _bisect_reduction(run, fs_guess, settings.fs_tolerance)
        if with_friction:
            phi = _bisect_friction(run, friction_guess, settings.friction_tolerance)
    timing = None
    if settings.compare_whole:
        timing = time_sub_and_whole(scene, system, blocks, settings=settings, params=params, removed=removed)
    return DdaEvaluation(fs=fs, critical_friction=phi, judgement=cache[(None, 1.0)], runs=tuple(runs),
                         wall_time=time.perf_counter() - t0, timing=timing)


def _searches(settings: DdaSettings, fs_guess: Optional[float], friction_guess: Optional[float]) -> dict:
    """The K-section searches of `dda_evaluation` ("fs", "phi"; `_Bracket`), placed by the
    guesses, under ``settings``' tolerances; a search whose guess is None is not made."""
    searches = {}
    if fs_guess is not None:
        f = _first_reduction(fs_guess)
        # x = −ln F: the group is stable for x ≥ −ln FS
        searches["fs"] = _Bracket(guess=-math.log(f), lower=-math.log(F_HIGH), upper=-math.log(F_LOW),
                                  tolerance=math.log1p(settings.fs_tolerance), step=math.log(F_STEP))
    if friction_guess is not None:
        searches["phi"] = _Bracket(guess=_first_friction(friction_guess), lower=0.0, upper=PHI_HIGH,
                                   tolerance=settings.friction_tolerance, step=PHI_STEP)
    return searches


def _k_sections(searches: dict, judge_round, batch: int, two_pass: bool = False) -> None:
    """Rounds of the searches ``searches`` ("fs": x = −ln F, "phi": x = φ; `_Bracket`) until all
    are done: each round, the verdict at the scene's strength (the first) and the active
    searches' probes, at most ``batch`` in all (a search whose bracket is found takes only the
    probes that close it, `_Bracket.proposals`), judged together by ``judge_round`` (a list of
    (friction, reduction) -> a list of verdicts).

    ``two_pass``: a round is judged in two passes, the middle of each search's probes first
    (with the verdict), then only the probes its verdict leaves inside the bracket: a monotone
    verdict already says what the others would give (stable above a stable probe, unstable
    below an unstable one), so the brackets, and every round after, are those of the round
    judged at once, from fewer probes (`_Bracket.open`), or, where the first pass has already
    closed a search to its tolerance, that bracket."""

    def probe(name, x):  # (friction, reduction) of a probe
        return (None, math.exp(-x)) if name == "fs" else (x, 1.0)

    def judge(fixed, asked):
        if not fixed and not asked:
            return
        stable = judge_round(fixed + [probe(n, x) for n, x in asked])
        for (n, x), verdict in zip(asked, stable[len(fixed):]):
            searches[n].record(x, verdict)
        if fixed and "fs" in searches:  # the verdict is the probe F = 1
            searches["fs"].record(0.0, stable[0])

    first = True
    while first or any(not b.done for b in searches.values()):
        active = [n for n, b in searches.items() if not b.done]
        fixed = [(None, 1.0)] if first else []
        share = max(1, (batch - len(fixed)) // max(len(active), 1))
        proposed = {n: searches[n].proposals(share, share_next=max(1, batch // max(len(active), 1)))
                    for n in active}
        if two_pass:
            middle = [(n, xs[(len(xs) - 1) // 2]) for n, xs in proposed.items() if xs]
            judge(fixed, middle)
            judge([], [(n, x) for n, xs in proposed.items() for x in xs
                        if (n, x) not in middle and not searches[n].done and searches[n].open(x)])
        else:
            judge(fixed, [(n, x) for n, xs in proposed.items() for x in xs])
        first = False


class _Bracket:
    """A K-section search for the limit x* of a monotone verdict, stable for x ≥ x* on
    [lower, upper]: each round proposes points that cut the bracket (largest unstable x,
    smallest stable x) into equal pieces (as many as the round has probes, or the fewest no
    wider than ``tolerance`` where those are fewer), or, while one side is missing, points
    stepping away from what is known (the step doubling each round); done when the bracket is at most
    ``tolerance`` wide or the limit lies outside [lower, upper]. Where DDA's verdicts are not
    monotone near the limit (a stable run below an unstable one), the bracket turns over: the
    search stops and the limit is the middle of that band (`DdaEvaluation.bracket`)."""

    def __init__(self, *, guess: float, lower: float, upper: float, tolerance: float, step: float):
        self.guess, self.lower, self.upper = guess, lower, upper
        self.tolerance, self.step = tolerance, step
        self.stable_min = math.inf      # smallest x judged stable
        self.unstable_max = -math.inf   # largest x judged unstable

    def record(self, x: float, stable: bool) -> None:
        if stable:
            self.stable_min = min(self.stable_min, x)
        else:
            self.unstable_max = max(self.unstable_max, x)

    def open(self, x: float) -> bool:
        """Whether a monotone verdict at x is not already known: x lies strictly inside the
        bracket (above every unstable x, below every stable x)."""
        return self.unstable_max < x < self.stable_min

    @property
    def done(self) -> bool:
        s, u = self.stable_min, self.unstable_max
        return (s - u <= self.tolerance) or s <= self.lower or u >= self.upper

    def closing(self) -> int:
        """The fewest probes that cut the bracket into pieces of at most ``tolerance`` [-]."""
        return max(1, math.ceil((self.stable_min - self.unstable_max) / self.tolerance) - 1)

    def proposals(self, n: int, share_next: int) -> list:
        """At most ``n`` points to judge next; where the bracket is found, the fewest of them that
        close it this round if ``n`` can (`closing`): each probe costs its member's stage and run,
        and more would only narrow the bracket below the tolerance asked for."""
        s, u = self.stable_min, self.unstable_max
        if math.isfinite(s) and math.isfinite(u):
            k = min(n, self.closing())
            xs = [u + (s - u) * i / (k + 1) for i in range(1, k + 1)]
            while k < n and max(np.diff([u, *xs, s])) > self.tolerance:  # a piece left over by round-off
                k += 1
                xs = [u + (s - u) * i / (k + 1) for i in range(1, k + 1)]
            return xs
        # spacing such that the next round, with ``share_next`` probes, closes the bracket
        h = max(self.step if math.isfinite(s) or math.isfinite(u) else 0.0,
                0.95 * self.tolerance * (share_next + 1))
        if not math.isfinite(s) and not math.isfinite(u):
            xs = [self.guess + h * (i - (n - 1) / 2.0) for i in range(n)]
        elif math.isfinite(s):  # all stable so far: look below
            xs = [s - h * 2.0 ** i for i in range(n)]
        else:
            xs = [u + h * 2.0 ** i for i in range(n)]
        xs = sorted({min(max(x, self.lower), self.upper) for x in xs})
        return [x for x in xs if x != s and x != u]

    def limit(self, value, *, below: float, above: float) -> float:
        """The limit in the caller's variable (``value`` maps x): the bracket's midpoint in x;
        ``below`` when even ``lower`` was stable, ``above`` when even ``upper`` failed."""
        s, u = self.stable_min, self.unstable_max
        if s <= self.lower:
            return below
        if u >= self.upper:
            return above
        return value(0.5 * (s + u))


def _first_reduction(guess: float) -> float:
    """The first F probed: the guess within [GUESS_LOW, GUESS_HIGH], 1 without one."""
    return min(max(guess, GUESS_LOW), GUESS_HIGH) if math.isfinite(guess) and guess > 0 else 1.0


def _first_friction(guess: float) -> float:
    """The first φ probed: the guess within [0, PHI_GUESS_MAX] [degrees]."""
    return min(max(guess, 0.0), PHI_GUESS_MAX)


def _bisect_reduction(stable_at, guess: float, tol: float) -> float:
    """F between the largest stable and the smallest unstable reduction (geometric bisection)."""
    step = F_STEP
    f = _first_reduction(guess)
    if stable_at(reduction=f):
        lo, hi = f, f * step
        while stable_at(reduction=hi):
            lo, hi = hi, hi * step
            if hi > F_HIGH:
                return math.inf
    else:
        lo, hi = f / step, f
        while not stable_at(reduction=lo):
            lo, hi = lo / step, lo
            if lo < F_LOW:
                return 0.0
    while hi / lo - 1.0 > tol:
        mid = math.sqrt(lo * hi)
        if stable_at(reduction=mid):
            lo = mid
        else:
            hi = mid
    return math.sqrt(lo * hi)


def _bisect_friction(stable_at, guess: float, tol: float) -> float:
    """φ between the largest unstable and the smallest stable friction angle of all joints."""
    step = PHI_STEP
    phi = _first_friction(guess)
    if stable_at(friction=phi):
        lo, hi = phi - step, phi
        while lo > 0.0 and stable_at(friction=lo):
            lo, hi = lo - step, lo
        if lo <= 0.0:
            if stable_at(friction=0.0):
                return 0.0
            lo = 0.0
    else:
        lo, hi = phi, phi + step
        while not stable_at(friction=hi):
            lo, hi = hi, hi + step
            if hi > PHI_HIGH:
                return 90.0
    while hi - lo > tol:
        mid = 0.5 * (lo + hi)
        if stable_at(friction=mid):
            hi = mid
        else:
            lo = mid
    return 0.5 * (lo + hi)


def time_sub_and_whole(scene: Scene, system: BlockSystem, blocks: frozenset, *, settings: DdaSettings,
                       params: Optional[Params] = None, removed: frozenset = frozenset()) -> DdaTiming:
    """Mean wall time per step of the judgement's sub-model and of the whole slope (all
    remaining blocks free as in the scene), over ``settings.whole_steps`` steps each."""
    from ddatai.results import SimulationError
    from ddatai.run import simulate

    prm = run_params(params, settings)
    sub, ids = sub_scene(scene, system, blocks, removed=removed, free_neighbours=settings.free_neighbours)
    whole = scene
    if removed:
        keep = [b for b in range(scene.n_blocks) if b not in removed]
        whole, _ = scene.subset(keep)

    def per_step(sc) -> float:
        t0 = time.perf_counter()
        try:
            res = simulate(sc, prm, steps=settings.whole_steps, record_every=10 ** 9)
            n = len(res.steps)
        except SimulationError as err:
            n = len(err.results.steps) if err.results is not None else 1
        return (time.perf_counter() - t0) / max(n, 1)

    per_step(sub)  # warm-up: kernel compilation is not part of either cost
    return DdaTiming(steps=settings.whole_steps, sub_step_time=per_step(sub), whole_step_time=per_step(whole),
                     sub_blocks=len(ids), whole_blocks=whole.n_blocks)
