"""Probabilistic key group analysis: probability of failure from sampled rock properties and
joint geometry (the probabilistic key group method, docs/kgm/probabilistic.md).

``kgm.probabilistic(build, variables, n)`` draws ``n`` samples of the uncertain inputs, builds
the scene of each with ``build(**sample)`` (a scene script's ``build`` works as it is), finds
its critical key group and that group's factor of safety with the chosen evaluator (rigid,
Sarma or DDA) and collects them into a `Study`: the probability of failure P(FS < 1), the
reliability index, the FS distribution, how often each block belongs to the critical group, and
a table of every sample with its seed, so that any sample can be run again exactly.

Sampling: ``"monte-carlo"`` (independent uniform numbers) or ``"latin-hypercube"`` (one sample
in each of ``n`` equal-probability strata of every variable, `scipy.stats.qmc.LatinHypercube`),
mapped through each variable's inverse distribution function (``ppf``). Correlated variables
(e.g. friction and cohesion) are coupled by a Gaussian copula: the uniform numbers become
standard normal ones, are mixed by the Cholesky factor of the correlation matrix and mapped
back (the correlation given is that of the normal scores). All samples are drawn before any
work from the study's seed, so the table does not depend on the number of workers or on the
order in which samples complete.

Execution (`ddatai.parallel`): by default rigid and Sarma samples (limit equilibrium, about a
millisecond each) run in this process, where they are fastest, and DDA samples (seconds each)
on one local worker process per CPU; ``workers=`` chooses, and ``client=`` (a
``dask.distributed.Client`` or a scheduler address) runs them on a Dask cluster. A script that
starts a study at its top level without an ``if __name__ == "__main__":`` block still gets its
result by default (in this process, with a warning saying what to add); asked for worker
processes explicitly, it stops before any work with one line saying what to add. With ``out=`` every sample
is appended to a CSV file as it completes; a study started again with the same arguments reads
the samples already there and runs only the others.
"""

from __future__ import annotations

import csv
import functools
import inspect
import json
import math
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Mapping, Optional

import numpy as np

from .kinds import METHOD_NAMES, SAMPLINGS, Method, Sampling

METHODS = METHOD_NAMES
#: first line of a study file: what identifies the study (a file of another study is refused)
HEADER_MARK = "# kgm probabilistic study "


@dataclass(frozen=True, kw_only=True, eq=False)
class Study:
    """Outcome of `probabilistic`."""

    n: int
    """Samples [-]."""
    pf: float
    """Probability of failure: the fraction of samples whose critical group fails (FS < 1, or
    unstable under DDA) [-]."""
    beta: float
    """Reliability index β = (mean FS − 1) / standard deviation of FS, over the samples with a
    finite FS (the definition of RocPlane and Slide, exact for a normally distributed FS) [-];
    nan when fewer than two samples have a finite FS."""
    table: np.ndarray
    """One row per sample, in sample order (a NumPy structured array): ``index``, ``seed``,
    the sampled variables (their names), ``fs``, ``failed`` and ``critical`` (the critical
    group's block ids, space-separated)."""
    variables: tuple
    """Names of the sampled variables, in table order."""
    method: str
    """Evaluator: 'rigid', 'sarma' or 'dda'."""
    sampling: str
    """'monte-carlo' or 'latin-hypercube'."""
    seed: int
    """Seed of the study."""
    resumed: int = 0
    """Samples read from an earlier run's file instead of evaluated [-]."""
    wall_time: float = 0.0
    """Wall time of this call [s]."""

    @property
    def fs(self) -> np.ndarray:
        """Factor of safety of every sample's critical group [-] (inf: no failure mode; nan: a
        DDA verdict without strength reduction)."""
        return self.table["fs"]

    @property
    def failed(self) -> np.ndarray:
        return self.table["failed"]

    @property
    def beta_pf(self) -> float:
        """The reliability index that P_f corresponds to, −Φ⁻¹(P_f) [-] (±inf when no sample or
        every sample failed)."""
        from scipy.stats import norm

        return float(-norm.ppf(self.pf))

    def pf_interval(self, confidence: float = 0.95) -> tuple[float, float]:
        """Confidence interval of P_f (Wilson's score interval for a binomial proportion; for
        Monte Carlo sampling — Latin hypercube estimates are tighter)."""
        from scipy.stats import norm

        z = float(norm.ppf(0.5 + 0.5 * confidence))
        n, p = self.n, self.pf
        centre = (p + z * z / (2 * n)) / (1 + z * z / n)
        half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / (1 + z * z / n)
        return max(0.0, centre - half), min(1.0, centre + half)

    def block_frequency(self) -> dict:
        """Block id -> fraction of the samples in whose critical group it is [-] (a map of the
        probable failure surface)."""
        counts: dict = {}
        for row in self.table["critical"]:
            for b in str(row).split():
                counts[int(b)] = counts.get(int(b), 0) + 1
        return {b: c / self.n for b, c in sorted(counts.items())}

    def fs_quantiles(self, q=(0.05, 0.5, 0.95)) -> dict:
        """Quantiles of the FS distribution [-]."""
        return {float(p): float(np.quantile(self.fs, p)) for p in q}

    def summary(self) -> str:
        lo, hi = self.pf_interval()
        finite = self.fs[np.isfinite(self.fs)]
        mean = float(np.mean(finite)) if len(finite) else math.inf
        return (f"{self.n} samples ({self.sampling}, {self.method}, seed {self.seed}): "
                f"P_f = {self.pf:.4f} (95 % {lo:.4f}-{hi:.4f}), beta = {self.beta:.3f}, "
                f"mean FS = {mean:.3f}")

    def to_csv(self, path) -> Path:
        """Write the table (with the study's header line) to ``path``; returns the path."""
        path = Path(path)
        with open(path, "w", newline="") as fh:
            fh.write(HEADER_MARK + json.dumps(self._identity()) + "\n")
            w = csv.writer(fh)
            w.writerow(self.table.dtype.names)
            for row in self.table:
                w.writerow([_cell(v) for v in row])
        return path

    def _identity(self) -> dict:
        return dict(n=self.n, seed=self.seed, sampling=self.sampling, method=self.method,
                    variables=list(self.variables))

    def write_png(self, scene, path, *, size=(640, 480), title: Optional[str] = None) -> Path:
        """Draw the scene's blocks coloured by `block_frequency` (white: never in the critical
        group, dark red: always; fixed blocks grey) with a colour bar; returns the path."""
        return write_frequency_png(scene, self.block_frequency(), path, size=size,
                                   title=title or f"P_f = {self.pf:.3f}, {self.n} samples")


def _cell(v) -> Any:
    if isinstance(v, (np.floating, float)):
        return repr(float(v))
    if isinstance(v, (np.bool_, bool)):
        return int(bool(v))
    if isinstance(v, np.integer):
        return int(v)
    return str(v)


# ---------------------------------------------------------------------- sampling
def sample_variables(variables: Mapping, n: int, *, sampling: str = Sampling.MONTE_CARLO, seed: int = 0,
                     correlation: Optional[Mapping] = None) -> dict:
    """The ``n`` samples of a study: name -> array (n,). ``variables`` maps names to frozen
    `scipy.stats` distributions (anything with ``ppf``) or to constants; ``correlation`` maps
    pairs of names to the correlation of their normal scores (module docstring)."""
    _check_sampling(variables, n, sampling, correlation)
    names = [k for k, v in variables.items() if hasattr(v, "ppf")]
    rng = np.random.default_rng(seed)
    d = len(names)
    if d == 0:
        u = np.zeros((n, 0))
    elif sampling == Sampling.MONTE_CARLO:
        u = rng.random((n, d))
    else:
        from scipy.stats import qmc

        u = qmc.LatinHypercube(d=d, seed=rng).random(n)
    # ppf(0) is −inf for unbounded distributions: keep u inside (0, 1)
    u = np.clip(u, np.finfo(float).tiny, 1.0 - np.finfo(float).eps)
    if correlation:
        from scipy.stats import norm

        c = _correlation_matrix(names, correlation)
        u = norm.cdf(norm.ppf(u) @ np.linalg.cholesky(c).T)
    out = {}
    for k, v in variables.items():
        if hasattr(v, "ppf"):
            out[k] = np.asarray(v.ppf(u[:, names.index(k)]), dtype=float)
        else:
            out[k] = np.full(n, v)
    return out


def _correlation_matrix(names: list, correlation: Mapping) -> np.ndarray:
    c = np.eye(len(names))
    for pair, rho in correlation.items():
        if not (isinstance(pair, tuple) and len(pair) == 2 and all(p in names for p in pair) and pair[0] != pair[1]):
            raise ValueError(f"correlation key {pair!r} must be a pair of two different sampled variables "
                             f"(distributions) among {names}")
        if not (isinstance(rho, (int, float)) and -1.0 < rho < 1.0):
            raise ValueError(f"correlation of {pair} must be a number in (-1, 1), got {rho!r}")
        i, j = names.index(pair[0]), names.index(pair[1])
        c[i, j] = c[j, i] = float(rho)
    if np.min(np.linalg.eigvalsh(c)) <= 0.0:
        raise ValueError("the correlation matrix of the sampled variables is not positive definite")
    return c


def _check_sampling(variables, n, sampling, correlation) -> None:
    if not isinstance(variables, Mapping) or not variables:
        raise ValueError("variables must be a non-empty mapping of names to scipy.stats distributions "
                         "(e.g. {'friction': scipy.stats.norm(30, 3)}) or constants")
    for k, v in variables.items():
        if not isinstance(k, str) or not k.isidentifier():
            raise ValueError(f"variable name {k!r} must be a valid keyword argument name of build()")
        if k in ("seed", "index", "fs", "failed", "critical"):
            raise ValueError(f"variable name {k!r} is reserved (a column of the study table)")
        if not hasattr(v, "ppf") and not isinstance(v, (int, float)):
            raise ValueError(f"variable {k!r} must be a frozen scipy.stats distribution (with ppf) or a "
                             f"number, got {type(v).__name__}")
    if not isinstance(n, int) or isinstance(n, bool) or n < 1:
        raise ValueError(f"n (number of samples) must be an integer >= 1, got {n!r}")
    if sampling not in SAMPLINGS:
        raise ValueError(f"sampling must be one of {SAMPLINGS}, got {sampling!r}")
    if correlation is not None and not isinstance(correlation, Mapping):
        raise ValueError("correlation must be a mapping {(name1, name2): rho}")


def sample_seeds(seed: int, n: int) -> np.ndarray:
    """The per-sample seeds of a study (given to ``build(seed=...)`` when it takes one: a new
    realisation of the joint sets per sample), independent of the sampled values."""
    return np.random.SeedSequence([int(seed), 0x6B676D]).generate_state(n, dtype=np.uint32).astype(np.int64)


# ---------------------------------------------------------------------- one sample
@dataclass(frozen=True)
class _Job:
    """What a worker needs to evaluate samples (picklable)."""

    build: Callable
    method: str
    settings: Any
    group: Optional[frozenset]
    pass_seed: bool
    dda_fs: bool = False


def _evaluate(job: _Job, item: tuple) -> tuple:
    """(fs, failed, critical block ids) of one sample; errors name the sample."""
    index, values, seed = item
    try:
        screened = _screen(job, item)
        if screened[0] is None or job.method is not Method.DDA:
            return screened[3]
        scene, params, result, _, settings = screened
        from .blocks import build_block_system
        from .dda import evaluate_dda

        dres = evaluate_dda(scene, build_block_system(scene, contact_gap=settings.contact_gap),
                            frozenset(result.blocks), settings=settings.dda,
                            params=params, fs_guess=result.fs, with_fs=job.dda_fs, with_friction=False)
        return float(dres.fs), not bool(dres.judgement.stable), screened[3][2]
    except Exception as exc:
        raise _failed(index, values, seed, exc) from exc


def _failed(index, values, seed, exc) -> RuntimeError:
    return RuntimeError(f"sample {index} ({_describe(values)}, seed {seed}) failed: {type(exc).__name__}: {exc}")


def _screen(job: _Job, item: tuple) -> tuple:
    """The sample's scene, its parameters, its critical group by the screening evaluator (or
    by the job's limit-equilibrium method), the sample's row (fs, failed, critical) as that
    evaluator gives it, and the settings; ``(None, None, None, row, None)`` when the sample has
    no key group (nothing can fail)."""
    index, values, seed = item
    kwargs = dict(values)
    if job.pass_seed:
        kwargs["seed"] = int(seed)
    from ddatai.io.scenefile import build_scene

    scene, params = build_scene(job.build, **kwargs)
    from . import search
    from .settings import Settings

    settings = job.settings or Settings()
    # DDA judges the critical group of the screening evaluator (a DDA-ranked search runs
    # DDA on every candidate): the verdict from one run at the sample's strength, FS by
    # strength reduction only when asked (several runs)
    method = job.method.screened_by(settings.screening)
    if job.group is not None:
        result = search.evaluate(scene, job.group, method, settings=settings, params=params)
    else:
        result = search.analyze(scene, method, settings=settings, params=params).critical
    if result is None:
        return None, None, None, (math.inf, False, ""), None
    critical = " ".join(str(b) for b in sorted(result.blocks))
    return scene, params, result, (float(result.fs), not bool(result.stable), critical), settings


def _evaluate_batch(job: _Job, items: tuple) -> list:
    """[(index, (fs, failed, critical))] of DDA verdicts of several samples (``dda_fs`` off):
    each sample screened on its own, then the samples whose critical groups are the same blocks
    of the same geometry judged side by side in one run (`kgm.batched.judge_members`; the verdict
    of each is the one a run of its own gives). Errors name the sample."""
    from .blocks import build_block_system
    from .batched import Member, judge_members

    rows, groups = {}, {}
    for item in items:
        index, values, seed = item
        try:
            scene, params, result, row, settings = _screen(job, item)
        except Exception as exc:
            raise _failed(index, values, seed, exc) from exc
        if scene is None:
            rows[index] = row
            continue
        member = Member(scene=scene, system=build_block_system(scene, contact_gap=settings.contact_gap))
        groups.setdefault((frozenset(result.blocks), params), []).append((item, member, row[2], settings))
    for (blocks, params), entries in groups.items():
        settings = entries[0][3]
        try:
            verdicts = judge_members([e[1] for e in entries], blocks, settings=settings.dda, params=params,
                                     exact=True)
        except Exception:
            # which sample: each on its own, so that the error names it
            for item, member, critical, _ in entries:
                rows[item[0]] = _evaluate(job, item)
            continue
        for (item, _, critical, _), j in zip(entries, verdicts):
            rows[item[0]] = (math.nan, not j.stable, critical)
    return [(item[0], rows[item[0]]) for item in items]


def _describe(values: Mapping) -> str:
    return ", ".join(f"{k}={v:.6g}" if isinstance(v, float) else f"{k}={v}" for k, v in values.items())


# ---------------------------------------------------------------------- the study
def probabilistic(build, variables: Mapping, n: int, *, method: str = Method.SARMA,
                  sampling: str = Sampling.MONTE_CARLO, seed: int = 0, correlation: Optional[Mapping] = None,
                  group=None, settings=None, client=None, workers: Optional[int] = None,
                  out=None, geometry_seed: Optional[bool] = None, progress: Optional[Callable] = None,
                  dda_fs: bool = False) -> Study:
    """Probability of failure of a slope with uncertain inputs (module docstring).

    Parameters
    ----------
    build : ``build(**sample) -> Scene`` or ``-> (Scene, Params)``: a function defined at the
        top level of an importable module, or the path of a scene script (its ``build``).
    variables : name -> frozen `scipy.stats` distribution (normal, lognormal, truncated normal,
        uniform, triangular...) or a constant; each name is a keyword argument of ``build``.
    n : samples.
    method : evaluator of each sample's critical group: 'rigid', 'sarma' or 'dda'.
    sampling : 'monte-carlo' or 'latin-hypercube'.
    seed : seed of the study (the samples and the per-sample seeds follow from it).
    correlation : {(name1, name2): ρ} between sampled variables (Gaussian copula).
    group : evaluate this group of blocks in every sample instead of searching for the
        critical one (faster; block ids must mean the same blocks in every sample).
    settings : `kgm.Settings` of the analyses.
    client : None (this machine), a ``dask.distributed.Client`` or a scheduler address.
    workers : local worker processes. None: in this process for 'rigid' and 'sarma' (a
        limit-equilibrium sample takes milliseconds: worker processes would cost more
        than they save), one per CPU for 'dda'; 1: in this process; N: N processes (the
        table is the same whatever the number).
    out : CSV file to which every sample is appended as it completes; an existing file of the
        same study is resumed (its samples are not run again).
    geometry_seed : pass each sample's seed to ``build(seed=...)`` (a new joint-set
        realisation per sample); None: when ``build`` has a ``seed`` parameter.
    progress : called as ``progress(done, n)`` after each completed sample.
    dda_fs : with ``method="dda"``, also find each sample's FS by strength reduction (several
        DDA runs a sample); by default only the verdict at the sample's strength (one run),
        which is all P_f needs, and ``fs`` is nan.
    """
    from ddatai.parallel import ScriptFunction, check_execution, plan, run

    t0 = time.perf_counter()
    if method not in METHOD_NAMES:
        raise ValueError(f"method must be one of {METHOD_NAMES}, got {method!r}")
    method = Method(method)
    if isinstance(build, (str, Path)):
        build = ScriptFunction(str(build))
    if not callable(build):
        raise ValueError(f"build must be a function or the path of a scene script, got {type(build).__name__}")
    check_execution(client, workers)
    if not isinstance(seed, int) or isinstance(seed, bool):
        raise ValueError(f"seed must be an integer, got {seed!r}")
    if settings is not None:
        from .settings import Settings

        if not isinstance(settings, Settings):
            raise ValueError(f"settings must be a kgm.Settings, got {type(settings).__name__}")
    pass_seed = _check_build(build, variables, geometry_seed)
    samples = sample_variables(variables, n, sampling=sampling, seed=seed, correlation=correlation)
    seeds = sample_seeds(seed, n)
    names = tuple(variables)
    group = None if group is None else frozenset(int(b) for b in group)
    identity = dict(n=n, seed=seed, sampling=sampling, method=method, variables=list(names),
                    group=None if group is None else sorted(group), dda_fs=bool(dda_fs))

    done: dict = {}
    if out is not None:
        done = _read_done(Path(out), identity, names)
    resumed = len(done)
    items = [(i, {k: _scalar(samples[k][i]) for k in names}, int(seeds[i])) for i in range(n) if i not in done]
    job = _Job(build=build, method=method, settings=settings, group=group, pass_seed=pass_seed, dda_fs=bool(dda_fs))
    # before any work: this process for limit-equilibrium samples, processes for DDA, and a
    # script whose workers could not import what the study needs is told what to add
    workers = plan(functools.partial(_evaluate, job), client=client, workers=workers,
                   cost="heavy" if method is Method.DDA else "light", caller="kgm.probabilistic")
    # DDA verdicts: samples judged side by side, a batch of them per item (kgm.batched.judge_members)
    from .settings import DdaSettings

    size = (settings.dda if settings is not None else DdaSettings()).sample_batch \
        if method is Method.DDA and not dda_fs else 1
    if size > 1:
        # one batch a worker or more (a larger batch shares a step among more samples: per
        # sample a batch of 128 costs a fifth of one of 16); none larger than asked
        sharing = 1 if client is None and workers == 1 else _n_workers(client, workers)
        size = max(1, min(size, -(-len(items) // sharing)))
        batches = [tuple(items[i:i + size]) for i in range(0, len(items), size)]
        results = run(functools.partial(_evaluate_batch, job), [(b[0][0], b) for b in batches],
                      client=client, workers=workers, chunk=1)
        flat = (row for _, rows in results for row in rows)
    else:
        flat = run(functools.partial(_evaluate, job), [(it[0], it) for it in items], client=client, workers=workers)
    writer = _Appender(Path(out), identity, names) if out is not None else None
    try:
        for index, (fs, failed, critical) in flat:
            done[index] = (fs, failed, critical)
            if writer is not None:
                writer.append(index, int(seeds[index]), [samples[k][index] for k in names], fs, failed, critical)
            if progress is not None:
                progress(len(done), n)
    finally:
        if writer is not None:
            writer.close()
    table = _table(n, names, samples, seeds, done)
    return Study(n=n, pf=float(np.mean(table["failed"])), beta=_beta(table["fs"]), table=table, variables=names,
                 method=method, sampling=sampling, seed=seed, resumed=resumed,
                 wall_time=time.perf_counter() - t0)


def _n_workers(client, workers: Optional[int]) -> int:
    """How many evaluate at once: the local workers, or the Dask cluster's."""
    if client is None:
        from ddatai.parallel import default_workers

        return workers or default_workers()
    try:
        return max(1, len(client.scheduler_info()["workers"]))
    except Exception:
        return 1


def _beta(fs: np.ndarray) -> float:
    """β = (mean FS − 1) / sd(FS) over the finite FS (`Study.beta`)."""
    finite = fs[np.isfinite(fs)]
    if len(finite) < 2 or np.std(finite) == 0:
        return math.nan
    return float((np.mean(finite) - 1.0) / np.std(finite, ddof=1))


def _scalar(v):
    return float(v) if isinstance(v, (np.floating, float)) else v.item() if isinstance(v, np.generic) else v


def _check_build(build, variables: Mapping, geometry_seed: Optional[bool]) -> bool:
    """Whether to pass ``seed=``; raises if ``build`` does not take a variable's name."""
    fn = build.resolve() if hasattr(build, "resolve") else build
    try:
        sig = inspect.signature(fn)
    except (TypeError, ValueError):
        return bool(geometry_seed)
    params = sig.parameters
    var_kw = any(p.kind is inspect.Parameter.VAR_KEYWORD for p in params.values())
    for k in variables:
        if k not in params and not var_kw:
            raise ValueError(f"variable {k!r} is not a parameter of build{sig} ({getattr(fn, '__name__', fn)})")
    takes_seed = "seed" in params or var_kw
    if geometry_seed and not takes_seed:
        raise ValueError(f"geometry_seed=True but build{sig} has no 'seed' parameter")
    return takes_seed and "seed" in params if geometry_seed is None else bool(geometry_seed)


def _table_dtype(names: tuple, width: int) -> list:
    """Columns of a study table (`Study.table`); ``width``: characters of the longest
    ``critical`` entry."""
    return [("index", np.int64), ("seed", np.int64)] + [(k, np.float64) for k in names] + \
        [("fs", np.float64), ("failed", bool), ("critical", f"U{width}")]


def _table(n: int, names: tuple, samples: dict, seeds: np.ndarray, done: dict) -> np.ndarray:
    table = np.zeros(n, dtype=_table_dtype(names, max([len(done[i][2]) for i in done] + [1])))
    table["index"] = np.arange(n)
    table["seed"] = seeds
    for k in names:
        table[k] = samples[k]
    for i, (fs, failed, critical) in done.items():
        table["fs"][i], table["failed"][i], table["critical"][i] = fs, failed, critical
    return table


# ---------------------------------------------------------------------- the study file
class _Appender:
    """Appends completed samples to a study file, one line each, flushed (a killed study loses
    at most the samples in flight)."""

    def __init__(self, path: Path, identity: dict, names: tuple):
        fresh = not path.exists() or path.stat().st_size == 0
        path.parent.mkdir(parents=True, exist_ok=True)
        self.fh = open(path, "a", newline="")
        self.writer = csv.writer(self.fh)
        if fresh:
            self.fh.write(HEADER_MARK + json.dumps(identity) + "\n")
            self.writer.writerow(["index", "seed", *names, "fs", "failed", "critical"])
            self.fh.flush()

    def append(self, index, seed, values, fs, failed, critical) -> None:
        self.writer.writerow([index, seed, *[repr(float(v)) for v in values], repr(float(fs)), int(failed), critical])
        self.fh.flush()

    def close(self) -> None:
        self.fh.close()


def _read_done(path: Path, identity: dict, names: tuple) -> dict:
    """Samples already in a study file: index -> (fs, failed, critical). A file of another
    study is refused; a last line cut short by a kill is ignored (and rewritten)."""
    if not path.exists() or path.stat().st_size == 0:
        return {}
    with open(path, newline="") as fh:
        first = fh.readline()
        if not first.startswith(HEADER_MARK):
            raise ValueError(f"{path} is not a kgm probabilistic study file (no '{HEADER_MARK.strip()}' line)")
        theirs = json.loads(first[len(HEADER_MARK):])
        if theirs != identity:
            raise ValueError(f"{path} holds another study ({theirs}); this one is {identity}: "
                             "use another file or delete it")
        lines = fh.read().splitlines(keepends=True)
    done = {}
    good = []
    header = lines[0] if lines else ""
    for line in lines[1:]:
        row = next(csv.reader([line]))
        if not line.endswith("\n") or len(row) != len(names) + 5:
            break  # cut short
        try:
            done[int(row[0])] = (float(row[-3]), bool(int(row[-2])), row[-1])
        except ValueError:
            break
        good.append(line)
    if len(good) != len(lines) - 1:  # drop a partial last line before appending
        with open(path, "w", newline="") as fh:
            fh.write(first + header + "".join(good))
    return done


def read_study(path) -> Study:
    """A study from its CSV file (`Study.to_csv` or a study's ``out`` file), complete or not:
    the rows present, in sample order."""
    path = Path(path)
    with open(path, newline="") as fh:
        first = fh.readline()
        if not first.startswith(HEADER_MARK):
            raise ValueError(f"{path} is not a kgm probabilistic study file")
        identity = json.loads(first[len(HEADER_MARK):])
        rows = list(csv.DictReader(fh))
    names = tuple(identity["variables"])
    rows = sorted((r for r in rows if r.get("critical") is not None), key=lambda r: int(r["index"]))
    table = np.zeros(len(rows), dtype=_table_dtype(names, max([len(r["critical"]) for r in rows] + [1])))
    for j, r in enumerate(rows):
        table[j] = (int(r["index"]), int(r["seed"]), *[float(r[k]) for k in names], float(r["fs"]),
                    bool(int(r["failed"])), r["critical"])
    return Study(n=len(rows), pf=float(np.mean(table["failed"])) if len(rows) else math.nan, beta=_beta(table["fs"]),
                 table=table, variables=names, method=identity["method"], sampling=identity["sampling"],
                 seed=identity["seed"])


# ---------------------------------------------------------------------- the picture
def write_frequency_png(scene, frequency: Mapping, path, *, size=(640, 480), title: str = "") -> Path:
    """The scene's blocks coloured by how often each is in the critical group (Pillow)."""
    from PIL import Image, ImageDraw

    w, h = size
    polys = [np.asarray(scene.polygon(b), float) for b in range(scene.n_blocks)]
    allxy = np.concatenate(polys)
    lo, hi = allxy.min(axis=0), allxy.max(axis=0)
    bar = 60
    scale = min((w - bar - 20) / max(hi[0] - lo[0], 1e-12), (h - 50) / max(hi[1] - lo[1], 1e-12))

    def px(p):
        return [(float(10 + (x - lo[0]) * scale), float(h - 10 - (y - lo[1]) * scale)) for x, y in p]

    def colour(f):  # white -> dark red
        f = min(max(f, 0.0), 1.0)
        return (255, int(255 - 215 * f), int(255 - 235 * f)) if f < 0.5 else \
            (int(255 - 115 * (f - 0.5) * 2), int(147 - 107 * (f - 0.5) * 2), int(137 - 117 * (f - 0.5) * 2))

    img = Image.new("RGB", (w, h), (250, 250, 250))
    d = ImageDraw.Draw(img)
    fixed = {b for b in range(scene.n_blocks) if scene.blocks[b].fixed} if hasattr(scene, "blocks") else set()
    for b, p in enumerate(polys):
        fill = (190, 190, 190) if b in fixed else colour(float(frequency.get(b, 0.0)))
        d.polygon(px(p), fill=fill, outline=(60, 60, 60))
    x0 = w - bar + 10
    for k in range(100):
        y = h - 40 - k * (h - 80) / 100.0
        d.rectangle([x0, y - (h - 80) / 100.0, x0 + 15, y], fill=colour(k / 99.0))
    d.text((x0 + 18, 35), "1", fill=(0, 0, 0))
    d.text((x0 + 18, h - 50), "0", fill=(0, 0, 0))
    d.text((x0 - 10, 15), "freq.", fill=(0, 0, 0))
    if title:
        d.text((10, 5), title, fill=(0, 0, 0))
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    img.save(path)
    return path


# ---------------------------------------------------------------------- variables file
def variables_from_mapping(spec: Mapping) -> tuple[dict, dict]:
    """Variables and correlations from a plain mapping (a TOML file's tables), e.g.::

        [friction]                     # degrees
        distribution = "normal"        # normal | lognormal | truncated-normal | uniform | triangular | constant
        mean = 30.0
        sd = 3.0
        [cohesion]                     # Pa
        distribution = "truncated-normal"
        mean = 20e3
        sd = 5e3
        min = 0.0
        [correlation]
        "friction,cohesion" = -0.5

    lognormal takes the variable's own mean and sd; uniform min and max; triangular min, mode
    and max; truncated-normal mean, sd and optional min and max; constant value. Returns
    (variables, correlation) for `probabilistic`."""
    import scipy.stats as st

    variables, correlation = {}, {}
    for name, v in spec.items():
        if name == "correlation":
            for pair, rho in dict(v).items():
                a, _, b = str(pair).partition(",")
                correlation[(a.strip(), b.strip())] = rho
            continue
        if not isinstance(v, Mapping) or "distribution" not in v:
            raise ValueError(f"variable {name!r}: a table with 'distribution' and its parameters, got {v!r}")
        kind = v["distribution"]
        need = {"normal": ("mean", "sd"), "lognormal": ("mean", "sd"), "truncated-normal": ("mean", "sd"),
                "uniform": ("min", "max"), "triangular": ("min", "mode", "max"), "constant": ("value",)}
        if kind not in need:
            raise ValueError(f"variable {name!r}: distribution must be one of {sorted(need)}, got {kind!r}")
        missing = [k for k in need[kind] if k not in v]
        if missing:
            raise ValueError(f"variable {name!r} ({kind}) needs {', '.join(missing)}")
        if kind in ("normal", "lognormal", "truncated-normal") and not v["sd"] > 0:
            raise ValueError(f"variable {name!r}: sd must be > 0, got {v['sd']!r}")
        if kind == "normal":
            variables[name] = st.norm(v["mean"], v["sd"])
        elif kind == "lognormal":
            if not v["mean"] > 0:
                raise ValueError(f"variable {name!r}: a lognormal mean must be > 0, got {v['mean']!r}")
            s2 = math.log1p((v["sd"] / v["mean"]) ** 2)
            variables[name] = st.lognorm(math.sqrt(s2), scale=v["mean"] / math.sqrt(1.0 + (v["sd"] / v["mean"]) ** 2))
        elif kind == "truncated-normal":
            lo, hi = v.get("min", -math.inf), v.get("max", math.inf)
            variables[name] = st.truncnorm((lo - v["mean"]) / v["sd"], (hi - v["mean"]) / v["sd"],
                                           loc=v["mean"], scale=v["sd"])
        elif kind == "uniform":
            if not v["max"] > v["min"]:
                raise ValueError(f"variable {name!r}: max must be > min")
            variables[name] = st.uniform(v["min"], v["max"] - v["min"])
        elif kind == "triangular":
            lo, mode, hi = v["min"], v["mode"], v["max"]
            if not lo <= mode <= hi or not hi > lo:
                raise ValueError(f"variable {name!r}: needs min <= mode <= max and max > min")
            variables[name] = st.triang((mode - lo) / (hi - lo), loc=lo, scale=hi - lo)
        else:
            variables[name] = float(v["value"])
    return variables, correlation


def read_variables(path) -> tuple[dict, dict]:
    """`variables_from_mapping` of a TOML file."""
    try:
        import tomllib
    except ImportError:  # Python 3.10
        try:
            import tomli as tomllib
        except ImportError as exc:
            raise ValueError("reading a variables file needs Python 3.11 (tomllib) or pip install tomli") from exc
    path = Path(path)
    if not path.is_file():
        raise ValueError(f"variables file not found: {path}")
    with open(path, "rb") as fh:
        try:
            spec = tomllib.load(fh)
        except tomllib.TOMLDecodeError as exc:
            raise ValueError(f"{path}: not valid TOML: {exc}") from None
    return variables_from_mapping(spec)
