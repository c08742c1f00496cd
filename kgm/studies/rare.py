"""Probabilistic studies of rare failures: ``kgm.probabilistic(..., sampling="subset")`` and
``sampling="importance"`` (docs/kgm/reliability.md).

A Monte Carlo study needs about 100/P_f samples for a c.o.v. of 10 %. Here the estimators of
`kgm.studies.reliability` run on the study's own samples instead: the uncertain inputs are
reached from independent standard normal variables u through the Gaussian copula of the study's
correlated sampling (Nataf's transformation with the normal scores' correlation: z = L·u,
xᵢ = Fᵢ⁻¹(Φ(zᵢ))), and the limit state is g = FS − 1 of the sample's critical group (or of
``group``): limit equilibrium for ``method="rigid"`` and ``"sarma"``; for ``method="dda"`` the
DDA strength-reduction factor (the bisection of `kgm.evaluate`: each sample several DDA runs),
since a stable/unstable verdict alone gives subset simulation nothing to climb.

Every evaluation is a row of the study's table and of its file (``out=``), in the order the
estimator asked for them; the estimator is deterministic given its seed and the values of g, so
a study started again with the same arguments replays its file (each row's values checked bit
for bit) and evaluates only what the file lacks. A batch of evaluations — a level's first
samples, one step of all its Markov chains, FORM's gradient probes, the importance samples —
runs in parallel on the study's workers or Dask cluster, started once for the whole study
(`ddatai.parallel.Executor`).
"""

from __future__ import annotations

import csv
import functools
import math
import time
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Mapping, Optional

import numpy as np

#: the two samplings of this module, as `kgm.probabilistic` names them
RARE_SAMPLINGS = ("subset", "importance")


@dataclass(frozen=True, kw_only=True)
class SubsetSampling:
    """``sampling=`` of `kgm.probabilistic` for subset simulation with other settings than the
    defaults of ``sampling="subset"`` (`kgm.studies.reliability.subset_simulation`); ``n`` of the
    study is the samples a level."""

    p0: float = 0.1
    """Conditional probability of each intermediate level [-]."""
    proposal: str = "conditional"
    """Proposal of the modified Metropolis chains: 'conditional' or 'random-walk'."""
    spread: Optional[float] = None
    """Proposal's standard deviation in u (None: adapted) [-]."""
    max_levels: int = 20
    """Most levels (P_f below about p0^max_levels reads 0) [-]."""

    name = "subset"

    def identity(self) -> dict:
        return dict(p0=self.p0, proposal=self.proposal, spread=self.spread, max_levels=self.max_levels)


@dataclass(frozen=True, kw_only=True)
class ImportanceSampling:
    """``sampling=`` of `kgm.probabilistic` for FORM and importance sampling with other settings
    than the defaults of ``sampling="importance"``; ``n`` of the study is the importance
    samples (FORM's evaluations come first)."""

    step: Optional[float] = None
    """FORM's forward-difference step in u (None: 0.05; 0.5 for method="dda", whose FS is
    resolved to `kgm.DdaSettings.fs_tolerance`) [-]."""
    tol: float = 1e-3
    """FORM's tolerance on g and on the design point's direction [-]."""
    max_iterations: int = 30
    batch: Optional[int] = None
    """Importance samples a batch (None: all at once) [-]."""

    name = "importance"

    def identity(self) -> dict:
        return dict(step=self.step, tol=self.tol, max_iterations=self.max_iterations, batch=self.batch)


def rare_sampling(sampling) -> Optional[Any]:
    """The settings of a subset or importance sampling (`SubsetSampling`,
    `ImportanceSampling`), or None for the other samplings."""
    if isinstance(sampling, (SubsetSampling, ImportanceSampling)):
        return sampling
    if sampling == "subset":
        return SubsetSampling()
    if sampling == "importance":
        return ImportanceSampling()
    return None


# ---------------------------------------------------------------------- u -> the variables
class Transform:
    """The study's variables from independent standard normal u: z = L·u (L the Cholesky factor
    of the normal scores' correlation), xᵢ = Fᵢ⁻¹(Φ(zᵢ)) (by the upper tail where zᵢ > 0, so
    that both tails keep their precision); constants stay."""

    def __init__(self, variables: Mapping, correlation: Optional[Mapping]):
        from .. import probability

        self.variables = dict(variables)
        self.names = tuple(variables)
        self.sampled = [k for k, v in variables.items() if hasattr(v, "ppf")]
        self.chol = np.linalg.cholesky(probability._correlation_matrix(self.sampled, correlation)) \
            if correlation else np.eye(len(self.sampled))

    @property
    def dim(self) -> int:
        return len(self.sampled)

    def __call__(self, u: np.ndarray) -> dict:
        from scipy.special import ndtr

        u = np.atleast_2d(np.asarray(u, dtype=float))
        z = u @ self.chol.T
        out = {}
        for k, v in self.variables.items():
            if k in self.sampled:
                zk = z[:, self.sampled.index(k)]
                out[k] = np.where(zk < 0.0, v.ppf(ndtr(zk)), v.isf(ndtr(-zk))).astype(float)
            else:
                out[k] = np.full(len(u), float(v))
        return out


# ---------------------------------------------------------------------- results
@dataclass(frozen=True, kw_only=True, eq=False)
class StudyLevel:
    """A level of a subset simulation in the study's terms (`Study.levels`)."""

    fs_threshold: float
    """The next domain is FS ≤ this (1 + the threshold of g; 1 at the last level) [-]."""
    probability: float
    """Fraction of the level's samples with FS ≤ ``fs_threshold`` [-]."""
    cov: float
    """Its c.o.v., Au & Beck's, with the chains' correlation [-]."""
    gamma: float
    """The chains' correlation factor γ [-]."""
    acceptance: float
    """Fraction of the chain moves accepted (nan at level 0) [-]."""
    evaluations: int
    """Evaluations up to the end of the level [-]."""
    u: np.ndarray
    """The level's samples in standard normal space (n, d) [-]."""
    values: dict
    """The level's samples in the variables' units: name -> (n,)."""
    fs: np.ndarray
    """Their FS (n,) [-]."""


@dataclass(frozen=True, kw_only=True, eq=False)
class DesignPoint:
    """FORM's design point (`Study.design_point`): the most probable combination of the inputs
    at which the slope fails; the variables with the largest |α| drive failure."""

    values: dict
    """The variables at the design point, in their units: name -> value."""
    u: np.ndarray
    """The design point in standard normal space (d,) [-]."""
    beta: float
    """Reliability index |u*| (negative where the median inputs fail) [-]."""
    alpha: dict
    """Sensitivity of each sampled variable: αᵢ = −(∂g/∂uᵢ)/|∇g| (Σ αᵢ² = 1; αᵢ < 0: failure
    lies towards low values of the variable's normal score) [-]."""
    fs: float
    """FS at the design point (≈ 1) [-]."""
    iterations: int
    evaluations: int
    converged: bool

    @property
    def pf(self) -> float:
        """First-order P_f = Φ(−β) [-]."""
        from scipy.special import ndtr

        return float(ndtr(-self.beta))


# ---------------------------------------------------------------------- the limit state of a study
class _LimitState:
    """g(u) = FS − 1 of the study's samples: each batch of points becomes samples (Transform),
    evaluated on the executor (or read from the file being resumed), appended to the file and
    to the rows; returns their g (nan for a lost sample)."""

    def __init__(self, *, fn, executor, transform: Transform, seed: int, cached: dict, writer, progress):
        self.fn, self.executor, self.transform, self.seed = fn, executor, transform, seed
        self.cached, self.writer, self.progress = cached, writer, progress
        self.rows: dict = {}      # index -> (values, seed, fs, failed, critical, lost)
        self.count = 0

    def seed_of(self, index: int) -> int:
        return int(np.random.SeedSequence([self.seed, 0x6B676D, index]).generate_state(1, dtype=np.uint32)[0])

    def __call__(self, u: np.ndarray) -> np.ndarray:
        from ddatai.workers import WorkerLost

        from ..probability import _describe

        x = self.transform(u)
        names = self.transform.names
        first, self.count = self.count, self.count + len(u)
        todo = {}
        for j in range(len(u)):
            index = first + j
            values = {k: float(x[k][j]) for k in names}
            if index in self.cached:
                theirs, row = self.cached[index]
                if any(theirs[k] != values[k] for k in names):
                    raise ValueError(f"the study file holds other values for evaluation {index} ({_describe(theirs)}) "
                                     f"than this study asks ({_describe(values)}): a file of another study "
                                     "(another build or variables?); use another file or delete it")
                self.rows[index] = (values, self.seed_of(index), *row)
            else:
                todo[index] = (index, values, self.seed_of(index))
        for index, row in self.executor.run(list(todo.items())):
            values = todo[index][1]
            if isinstance(row, WorkerLost):
                warnings.warn(f"kgm.probabilistic: evaluation {index} ({_describe(values)}) recorded as lost, taken "
                              f"as safe: {row}", RuntimeWarning, stacklevel=4)
                row = (math.nan, False, "", True)
            else:
                row = (*row, False)
            self.rows[index] = (values, self.seed_of(index), *row)
            if self.writer is not None:
                self.writer.append(index, self.seed_of(index), [values[k] for k in names], *row)
            if self.progress is not None:
                self.progress(len(self.rows), None)
        return np.array([self.rows[i][2] - 1.0 for i in range(first, self.count)])


def _fs_of_values(fn: Callable, names: tuple, values: Mapping) -> np.ndarray:
    """FS of samples given by their values (name -> array), evaluated here one by one: the
    limit-state contour of `kgm.studies.plots` (limit-equilibrium studies only)."""
    m = len(next(iter(values.values())))
    return np.array([fn((-1, {k: float(values[k][j]) for k in names}, 0))[0] for j in range(m)])


def _read_cached(path: Path, identity: dict, names: tuple) -> dict:
    """index -> (values, (fs, failed, critical, lost)) of the evaluations in a study file
    (`kgm.probability._read_done` checks the identity and drops a partial last line)."""
    from ..probability import _read_done

    done = _read_done(path, identity, names)
    if not done:
        return {}
    with open(path, newline="") as fh:
        fh.readline()
        rows = {int(r["index"]): {k: float(r[k]) for k in names} for r in csv.DictReader(fh)}
    return {i: (rows[i], done[i]) for i in done}


# ---------------------------------------------------------------------- the study
def rare_study(build, variables: Mapping, n: int, *, method: str, sampling, seed: int,
               correlation: Optional[Mapping], group, settings, client, workers: Optional[int], out,
               geometry_seed: Optional[bool], progress: Optional[Callable], t0: float):
    """`kgm.probabilistic` with ``sampling="subset"`` or ``"importance"`` (module docstring)."""
    from ddatai.parallel import Executor, plan

    from .. import probability as pr
    from . import reliability

    options = rare_sampling(sampling)
    pr._check_sampling(variables, n, "monte-carlo", correlation)
    if geometry_seed:
        raise ValueError(f"geometry_seed=True with sampling={options.name!r}: a new joint realisation per sample "
                         "is not a variable of the limit state these estimators follow; use Monte Carlo")
    pr._check_build(build, variables, False)
    transform = Transform(variables, correlation)
    if transform.dim == 0:
        raise ValueError(f"sampling={options.name!r} needs at least one variable with a distribution")
    names = transform.names
    group = None if group is None else frozenset(int(b) for b in group)
    identity = dict(n=n, seed=seed, sampling=options.name, method=method, variables=list(names),
                    group=None if group is None else sorted(group), dda_fs=method == "dda",
                    estimator=dict(options.identity(), sampled=transform.sampled))
    cached = _read_cached(Path(out), identity, names) if out is not None else {}
    # under DDA the limit state is the strength-reduction factor: the bisection of every sample
    job = pr._Job(build=build, method=method, settings=settings, group=group, pass_seed=False,
                  dda_fs=method == "dda")
    fn = functools.partial(pr._evaluate, job)
    workers = plan(fn, client=client, workers=workers, cost="heavy" if method == "dda" else "light",
                   caller="kgm.probabilistic")
    writer = pr._Appender(Path(out), identity, names) if out is not None else None
    try:
        with Executor(fn, client=client, workers=workers) as executor:
            g = _LimitState(fn=fn, executor=executor, transform=transform, seed=seed, cached=cached,
                            writer=writer, progress=progress)
            if options.name == "subset":
                estimate = reliability.subset_simulation(g, transform.dim, n=n, p0=options.p0, seed=seed,
                                                         proposal=options.proposal, spread=options.spread,
                                                         max_levels=options.max_levels)
                design = None
            else:
                step = options.step or (0.5 if method == "dda" else 0.05)
                found = reliability.form(g, transform.dim, step=step, tol=options.tol,
                                         max_iterations=options.max_iterations)
                design = _design_point(found, transform)
                estimate = reliability.importance_sampling(g, transform.dim, centre=found.u, n=n, seed=seed,
                                                           batch=options.batch)
    finally:
        if writer is not None:
            writer.close()
    contour = None if method == "dda" else functools.partial(_fs_of_values, fn, names)
    return _study(g, estimate, design, transform, identity, method, seed, len(cached), t0, contour)


def _design_point(found, transform: Transform) -> DesignPoint:
    values = {k: float(v[0]) for k, v in transform(found.u[None]).items()}
    return DesignPoint(values=values, u=found.u, beta=found.beta,
                       alpha={k: float(a) for k, a in zip(transform.sampled, found.alpha)}, fs=found.g + 1.0,
                       iterations=found.iterations, evaluations=found.evaluations, converged=found.converged)


def _study(g: _LimitState, estimate, design, transform: Transform, identity: dict, method: str, seed: int,
           resumed: int, t0: float, contour: Optional[Callable]):
    from scipy.special import ndtri

    from .. import probability as pr

    names = transform.names
    count = g.count
    samples = {k: np.array([g.rows[i][0][k] for i in range(count)]) for k in names}
    seeds = np.array([g.rows[i][1] for i in range(count)], dtype=np.int64)
    done = {i: g.rows[i][2:] for i in range(count)}
    table = pr._table(count, names, samples, seeds, done)
    levels = ()
    if identity["sampling"] == "subset":
        levels = tuple(StudyLevel(fs_threshold=lv.threshold + 1.0, probability=lv.probability, cov=lv.cov,
                                  gamma=lv.gamma, acceptance=lv.acceptance, evaluations=lv.evaluations, u=lv.u,
                                  values=transform(lv.u), fs=lv.g + 1.0) for lv in estimate.levels)
    pf = float(estimate.pf)
    beta = float(-ndtri(pf)) if 0.0 < pf < 1.0 else (math.inf if pf == 0.0 else -math.inf)
    return pr.Study(n=count, pf=pf, beta=beta, table=table, variables=names, method=method,
                    sampling=identity["sampling"], seed=seed, resumed=resumed, wall_time=time.perf_counter() - t0,
                    pf_cov=float(estimate.cov), levels=levels, evaluations=count, design_point=design,
                    estimate=estimate, limit_state=contour)


class _Replay:
    """g served from a study file's rows, in their order (`read_rare_study`)."""

    def __init__(self, fs: np.ndarray):
        self.fs, self.count = fs, 0
        self.row_of: dict = {}  # a point's bytes -> its row

    def __call__(self, u: np.ndarray) -> np.ndarray:
        first, self.count = self.count, self.count + len(u)
        if self.count > len(self.fs):
            raise _Incomplete
        self.row_of.update((np.ascontiguousarray(p).tobytes(), first + j) for j, p in enumerate(u))
        return self.fs[first:self.count] - 1.0


class _Incomplete(Exception):
    pass


def _level_values(table: np.ndarray, names, g: _Replay, u: np.ndarray) -> dict:
    """A level's samples in the variables' units, from the rows that evaluated them."""
    rows = np.array([g.row_of[np.ascontiguousarray(p).tobytes()] for p in u], dtype=int)
    return {k: table[k][rows] for k in names}


def read_rare_study(identity: dict, table: np.ndarray):
    """The `Study` of a subset or importance study file (`kgm.read_study`): the estimator run
    again on the file's values of FS (no evaluation; the file is the log of the estimator's
    requests). A file cut short gives the table with P_f nan."""
    from scipy.special import ndtri

    from .. import probability as pr
    from . import reliability

    est = identity["estimator"]
    dim, n, seed = len(est["sampled"]), identity["n"], identity["seed"]
    complete = len(table) and np.array_equal(table["index"], np.arange(len(table)))
    g = _Replay(np.where(table["lost"], np.nan, table["fs"]))
    estimate = design = None
    try:
        if not complete:
            raise _Incomplete
        if identity["sampling"] == "subset":
            estimate = reliability.subset_simulation(g, dim, n=n, p0=est["p0"], seed=seed, proposal=est["proposal"],
                                                     spread=est["spread"], max_levels=est["max_levels"])
        else:
            found = reliability.form(g, dim, step=est["step"] or (0.5 if identity["method"] == "dda" else 0.05),
                                     tol=est["tol"], max_iterations=est["max_iterations"])
            estimate = reliability.importance_sampling(g, dim, centre=found.u, n=n, seed=seed, batch=est["batch"])
            design = DesignPoint(values={}, u=found.u, beta=found.beta,
                                 alpha={k: float(a) for k, a in zip(est["sampled"], found.alpha)}, fs=found.g + 1.0,
                                 iterations=found.iterations, evaluations=found.evaluations, converged=found.converged)
    except _Incomplete:
        estimate = None
    pf = float(estimate.pf) if estimate is not None and g.count == len(table) else math.nan
    beta = float(-ndtri(pf)) if 0.0 < pf < 1.0 else (math.inf if pf == 0.0 else (-math.inf if pf == 1.0 else math.nan))
    levels = ()
    if estimate is not None and identity["sampling"] == "subset":
        levels = tuple(StudyLevel(fs_threshold=lv.threshold + 1.0, probability=lv.probability, cov=lv.cov,
                                  gamma=lv.gamma, acceptance=lv.acceptance, evaluations=lv.evaluations, u=lv.u,
                                  values=_level_values(table, identity["variables"], g, lv.u), fs=lv.g + 1.0)
                       for lv in estimate.levels)
    return pr.Study(n=len(table), pf=pf, beta=beta, table=table, variables=tuple(identity["variables"]),
                    method=identity["method"], sampling=identity["sampling"], seed=seed,
                    pf_cov=float(estimate.cov) if estimate is not None else math.nan, levels=levels,
                    evaluations=len(table), design_point=design, estimate=estimate)
