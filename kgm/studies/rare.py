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
import time
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Mapping, Optional

import numpy as np

from ..kinds import Method, Sampling
from .estimates import design_point, form_step, generalised_beta, study_levels
from .sampling import _correlation_matrix
from .study import SampleRow, Study, StudyFile, read_samples, study_table


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

    name = Sampling.SUBSET

    def identity(self) -> dict:
        return dict(p0=self.p0, proposal=self.proposal, spread=self.spread, max_levels=self.max_levels)


@dataclass(frozen=True, kw_only=True)
class ImportanceSampling:
    """``sampling=`` of `kgm.probabilistic` for FORM and importance sampling with other settings
    than the defaults of ``sampling="importance"``; ``n`` of the study is the importance
    samples (FORM's evaluations come first)."""

    step: Optional[float] = None
    """FORM's forward-difference step in u (None: 0.05; 0.5 under DDA, whose FS is resolved to
    `kgm.DdaSettings.fs_tolerance`) [-]."""
    tol: float = 1e-3
    """FORM's tolerance on g and on the design point's direction [-]."""
    max_iterations: int = 30
    batch: Optional[int] = None
    """Importance samples a batch (None: all at once) [-]."""

    name = Sampling.IMPORTANCE

    def identity(self) -> dict:
        return dict(step=self.step, tol=self.tol, max_iterations=self.max_iterations, batch=self.batch)


def rare_sampling(sampling) -> Optional[Any]:
    """The settings of a subset or importance sampling (`SubsetSampling`,
    `ImportanceSampling`), or None for the other samplings."""
    if isinstance(sampling, (SubsetSampling, ImportanceSampling)):
        return sampling
    if sampling == Sampling.SUBSET:
        return SubsetSampling()
    if sampling == Sampling.IMPORTANCE:
        return ImportanceSampling()
    return None


# ---------------------------------------------------------------------- u -> the variables
class Transform:
    """The study's variables from independent standard normal u: z = L·u (L the Cholesky factor
    of the normal scores' correlation), xᵢ = Fᵢ⁻¹(Φ(zᵢ)) (by the upper tail where zᵢ > 0, so
    that both tails keep their precision); constants stay."""

    def __init__(self, variables: Mapping, correlation: Optional[Mapping]):
        self.variables = dict(variables)
        self.names = tuple(variables)
        self.sampled = [k for k, v in variables.items() if hasattr(v, "ppf")]
        self.chol = np.linalg.cholesky(_correlation_matrix(self.sampled, correlation)) \
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


# ---------------------------------------------------------------------- the limit state of a study
class _LimitState:
    """g(u) = FS − 1 of the study's samples: each batch of points becomes samples (Transform),
    evaluated on the executor (or read from the file being resumed), appended to the file and
    to the rows; returns their g (nan for a lost sample)."""

    def __init__(self, *, executor, transform: Transform, seed: int, cached: dict, writer, progress, describe):
        self.executor, self.transform, self.seed = executor, transform, seed
        self.cached, self.writer, self.progress, self.describe = cached, writer, progress, describe
        self.rows: dict = {}      # index -> (values, seed, SampleRow)
        self.count = 0

    def seed_of(self, index: int) -> int:
        """The evaluation's seed in the table (unused by ``build``: no new joints per sample)."""
        return int(np.random.SeedSequence([self.seed, 0x6B676D, index]).generate_state(1, dtype=np.uint32)[0])

    def __call__(self, u: np.ndarray) -> np.ndarray:
        from ddatai.workers import WorkerLost

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
                    raise ValueError(f"the study file holds other values for evaluation {index} "
                                     f"({self.describe(theirs)}) than this study asks ({self.describe(values)}): "
                                     "a file of another study (another build or variables?); use another file "
                                     "or delete it")
                self.rows[index] = (values, self.seed_of(index), row)
            else:
                todo[index] = (index, values, self.seed_of(index))
        for index, row in self.executor.run(list(todo.items())):
            values = todo[index][1]
            if isinstance(row, WorkerLost):
                warnings.warn(f"kgm.probabilistic: evaluation {index} ({self.describe(values)}) recorded as lost, "
                              f"taken as safe: {row}", RuntimeWarning, stacklevel=4)
                row = SampleRow.given_up()
            self.rows[index] = (values, self.seed_of(index), row)
            if self.writer is not None:
                self.writer.append(index, self.seed_of(index), [values[k] for k in names], row)
            if self.progress is not None:
                self.progress(len(self.rows), None)
        return np.array([self.rows[i][2].fs - 1.0 for i in range(first, self.count)])


def _fs_of_values(fn: Callable, names: tuple, values: Mapping) -> np.ndarray:
    """FS of samples given by their values (name -> array), evaluated here one by one: the
    limit-state contour of `kgm.studies.plots` (limit-equilibrium studies only)."""
    m = len(next(iter(values.values())))
    return np.array([fn((-1, {k: float(values[k][j]) for k in names}, 0)).fs for j in range(m)])


def _read_cached(path: Path, identity: dict, names: tuple) -> dict:
    """index -> (values, `SampleRow`) of the evaluations in a study file (`read_samples`
    checks the identity and drops a partial last line)."""
    done = read_samples(path, identity, names)
    if not done:
        return {}
    with open(path, newline="") as fh:
        fh.readline()
        rows = {int(r["index"]): {k: float(r[k]) for k in names} for r in csv.DictReader(fh)}
    return {i: (rows[i], done[i]) for i in done}


# ---------------------------------------------------------------------- the study
def identity_of(options, *, n: int, seed: int, method, names: tuple, sampled: list, group) -> dict:
    """The first line of a subset or importance study's file: what determines its evaluations."""
    return dict(n=n, seed=seed, sampling=options.name, method=method, variables=list(names),
                group=None if group is None else sorted(group), dda_fs=method == Method.DDA,
                estimator=dict(options.identity(), sampled=list(sampled)))


def rare_study(fn: Callable, transform: Transform, options, n: int, *, method, seed: int, group, client,
               workers: int, out, progress: Optional[Callable], describe: Callable, t0: float) -> Study:
    """`kgm.probabilistic` with ``sampling="subset"`` or ``"importance"`` (module docstring):
    ``fn`` evaluates one sample (``(index, values, seed) -> SampleRow``, under DDA by strength
    reduction), on ``workers`` local processes or the Dask ``client``."""
    from ddatai.parallel import Executor

    from . import reliability

    names = transform.names
    identity = identity_of(options, n=n, seed=seed, method=method, names=names, sampled=transform.sampled,
                           group=group)
    cached = _read_cached(Path(out), identity, names) if out is not None else {}
    writer = StudyFile(Path(out), identity, names) if out is not None else None
    design = None
    try:
        with Executor(fn, client=client, workers=workers) as executor:
            g = _LimitState(executor=executor, transform=transform, seed=seed, cached=cached, writer=writer,
                            progress=progress, describe=describe)
            if options.name == Sampling.SUBSET:
                estimate = reliability.subset_simulation(g, transform.dim, n=n, p0=options.p0, seed=seed,
                                                         proposal=options.proposal, spread=options.spread,
                                                         max_levels=options.max_levels)
            else:
                found = reliability.form(g, transform.dim, step=form_step(options.step, method), tol=options.tol,
                                         max_iterations=options.max_iterations)
                design = design_point(found, transform.sampled,
                                      {k: float(v[0]) for k, v in transform(found.u[None]).items()})
                estimate = reliability.importance_sampling(g, transform.dim, centre=found.u, n=n, seed=seed,
                                                           batch=options.batch)
    finally:
        if writer is not None:
            writer.close()
    count = g.count
    samples = {k: np.array([g.rows[i][0][k] for i in range(count)]) for k in names}
    seeds = np.array([g.rows[i][1] for i in range(count)], dtype=np.int64)
    table = study_table(count, names, samples, seeds, {i: g.rows[i][2] for i in range(count)})
    levels = study_levels(estimate, transform) if options.name == Sampling.SUBSET else ()
    pf = float(estimate.pf)
    return Study(n=count, pf=pf, beta=generalised_beta(pf), table=table, variables=names, method=method,
                 sampling=options.name, seed=seed, resumed=len(cached), wall_time=time.perf_counter() - t0,
                 pf_cov=float(estimate.cov), levels=levels, evaluations=count, design_point=design,
                 estimate=estimate,
                 limit_state=None if method == Method.DDA else functools.partial(_fs_of_values, fn, names))
