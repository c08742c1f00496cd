"""Probabilistic key group analysis: probability of failure from sampled rock properties and
joint geometry (the probabilistic key group method, docs/kgm/probabilistic.md).

``kgm.probabilistic(build, variables, n)`` draws ``n`` samples of the uncertain inputs, builds
the scene of each with ``build(**sample)`` (a scene script's ``build`` works as it is), finds
its critical key group and that group's factor of safety with the chosen evaluator (rigid,
Sarma or DDA) and collects them into a `Study`: the probability of failure P(FS < 1), the
reliability index, the FS distribution, how often each block belongs to the critical group, and
a table of every sample with its seed, so that any sample can be run again exactly.

The samples (`kgm.studies.sampling`: Monte Carlo or Latin hypercube, correlated by a Gaussian
copula) are all drawn before any work from the study's seed, so the table does not depend on the
number of workers or on the order in which samples complete. Each sample is screened by limit
equilibrium (`Screened`); under DDA its critical group is then judged on its real geometry, the
samples whose groups are the same judged side by side in one run. Its outcome is a
`kgm.studies.study.SampleRow`, appended to the study file as it completes.

Execution (`ddatai.parallel`): by default rigid and Sarma samples (limit equilibrium, about a
millisecond each) run in this process, where they are fastest, and DDA samples (seconds each)
on one local worker process per CPU; ``workers=`` chooses, and ``client=`` (a
``dask.distributed.Client`` or a scheduler address) runs them on a Dask cluster. On local
workers, DDA verdicts on the fused engine are prepared in NumPy by all the workers but one, the
only one that loads the fused kernel and runs them (``_prepared_then_run``). A script that
starts a study at its top level without an ``if __name__ == "__main__":`` block still gets its
result by default (in this process, with a warning saying what to add); asked for worker
processes explicitly, it stops before any work with one line saying what to add. With ``out=``
every sample is appended to a CSV file as it completes (`kgm.studies.study`); a study started
again with the same arguments reads the samples already there and runs only the others.
"""

from __future__ import annotations

import functools
import math
import pickle
import time
import warnings
from collections import deque
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Mapping, Optional

from ddatai.workers import WorkerLost

from ..analysis import analyze_problem, evaluate_group
from ..build import Problem, prepare
from ..faces import check_connected_group
from ..judges.batch import Member, judge_members
from ..judges.dda import dda_evaluation
from ..kinds import METHOD_NAMES, Method, Sampling
from ..report import GroupResult
from ..settings import DdaSettings, Settings
from .rare import Transform, rare_sampling, rare_study
from .sampling import _check_build, _check_sampling, _scalar, sample_seeds, sample_variables
from .study import SampleRow, Study, StudyFile, monte_carlo_cov, pf_of, read_samples, reliability_index, study_table

#: most DDA samples judged side by side in one batch of a study (`DdaSettings.sample_batch`'s
#: default): a batch's verdicts are saved when it ends, about every 1.3 s of the two processes'
#: CPU on Example II (~10 ms a sample). A larger batch shares each side-by-side evaluation of the
#: members' stages among more of them (`ddatai.side_by_side`: ~60 µs an evaluation whatever its
#: members): Example II's preparing worker took ~5.9 ms a sample in batches of 40, ~5.0 in
#: batches of 128, no less in batches of 256 (benchmarks/results/study_throughput.md) [-]
SAVED_BATCH = 128

# ---------------------------------------------------------------------- one sample
@dataclass(frozen=True)
class _Job:
    """What a worker needs to evaluate samples (picklable)."""

    build: Callable
    method: Method
    settings: Any
    group: Optional[frozenset]
    pass_seed: bool
    dda_fs: bool = False


@dataclass(frozen=True, kw_only=True, eq=False)
class Screened:
    """A sample screened by limit equilibrium: its problem (its scene and block system, the
    study's settings, the Params its ``build`` returned), its critical group by the screening
    method (None: the sample has no key group, nothing can fail) and its row as that method
    gives it."""

    problem: Problem
    """The sample's problem, prepared once: DDA judges its group on the same block system."""
    result: Optional[GroupResult]
    """The critical group by the screening method, or None (no key group, or a given group whose
    DDA verdict alone the row takes: ``group``)."""
    row: SampleRow
    """The sample's row by the screening method."""
    group: Optional[frozenset] = None
    """The group DDA judges (the critical one, or the study's given group); None: nothing can
    fail."""


def _evaluate(job: _Job, item: tuple) -> SampleRow:
    """The row of one sample; errors name the sample."""
    index, values, seed = item
    try:
        screened = _screen(job, item)
        if screened.group is None or job.method is not Method.DDA:
            return screened.row
        problem = screened.problem
        fs_guess = screened.result.fs if screened.result is not None else 1.0
        dres = dda_evaluation(problem, screened.group, fs_guess=fs_guess, with_fs=job.dda_fs,
                              with_friction=False, report=problem.settings.dda.progress)
        return SampleRow(fs=float(dres.fs), failed=not bool(dres.judgement.stable), critical=screened.row.critical)
    except Exception as exc:
        raise _failed(index, values, seed, exc) from exc


def _failed(index, values, seed, exc) -> RuntimeError:
    return RuntimeError(f"sample {index} ({_describe(values)}, seed {seed}) failed: {type(exc).__name__}: {exc}")


def _screen(job: _Job, item: tuple) -> Screened:
    """The sample built and its critical group found by the screening method (or by the job's
    limit-equilibrium method)."""
    index, values, seed = item
    kwargs = dict(values)
    if job.pass_seed:
        kwargs["seed"] = int(seed)
    from ddatai.io.scenefile import build_scene

    scene, params = build_scene(job.build, **kwargs)
    settings = job.settings or Settings()
    problem = prepare(scene, settings=settings, params=params)
    # DDA judges the critical group of the screening evaluator (a DDA-ranked search runs
    # DDA on every candidate): the verdict from one run at the sample's strength, FS by
    # strength reduction only when asked (several runs)
    method = job.method.screened_by(settings.screening)
    if job.group is not None and job.method is Method.DDA and not job.dda_fs:
        # a given group judged by its DDA verdict alone: the screening method's FS would be
        # computed and dropped (the row's FS is nan), so only the group is checked
        group = check_connected_group(problem.system, job.group)
        return Screened(problem=problem, result=None, row=SampleRow.of_group(math.nan, False, group), group=group)
    if job.group is not None:
        result = evaluate_group(problem, job.group, method)
    else:
        result = analyze_problem(problem, method).critical
    if result is None:
        return Screened(problem=problem, result=None, row=SampleRow(fs=math.inf, failed=False))
    return Screened(problem=problem, result=result,
                    row=SampleRow.of_group(result.fs, not bool(result.stable), result.blocks),
                    group=frozenset(result.blocks))


def _screened_groups(job: _Job, items: tuple) -> tuple:
    """``(decided, groups)`` of several samples, each screened on its own: ``decided`` the
    ``(index, SampleRow)`` of the samples with no key group, ``groups`` the others by key group
    and parameters, ``{(blocks, params): [(item, Member, Screened)]}`` (the samples whose critical
    groups are the same blocks of the same geometry, to be judged side by side). Errors name the
    sample."""
    decided, groups = [], {}
    for item in items:
        index, values, seed = item
        try:
            screened = _screen(job, item)
        except Exception as exc:
            raise _failed(index, values, seed, exc) from exc
        if screened.group is None:
            decided.append((index, screened.row))
            continue
        member = Member(scene=screened.problem.scene, system=screened.problem.system)
        groups.setdefault((screened.group, screened.problem.params), []).append((item, member, screened))
    return decided, groups


def _judge_group(job: _Job, blocks, params, entries: list) -> list:
    """[(index, `SampleRow`)] of one `_screened_groups` group judged side by side in one run
    (`kgm.judges.batch.judge_members`; the verdict of each is the one a run of its own gives).
    Errors name the sample (each sample then judged on its own, `_evaluate`)."""
    settings = entries[0][2].problem.settings
    try:
        verdicts = judge_members([member for _, member, _ in entries], blocks, settings=settings.dda,
                                 params=params, exact=True, report=settings.dda.progress)
    except Exception:
        # which sample: each on its own, so that the error names it
        return [(item[0], _evaluate(job, item)) for item, _, _ in entries]
    return [(item[0], SampleRow(fs=math.nan, failed=not j.stable, critical=screened.row.critical))
            for (item, _, screened), j in zip(entries, verdicts)]


def _evaluate_batch(job: _Job, items: tuple) -> list:
    """[(index, `SampleRow`)] of DDA verdicts of several samples (``dda_fs`` off): each sample
    screened on its own, then the samples whose critical groups are the same blocks of the same
    geometry judged side by side in one run (`_judge_group`). Errors name the sample."""
    decided, groups = _screened_groups(job, items)
    rows = dict(decided)
    for (blocks, params), entries in groups.items():
        rows.update(_judge_group(job, blocks, params, entries))
    return [(item[0], rows[item[0]]) for item in items]


def _prepare_batch(job: _Job, items: tuple) -> tuple:
    """`_evaluate_batch` up to the fused engine's launch, in NumPy (a study's worker process,
    which never loads the kernel): ``(rows, work)``, the ``(index, SampleRow)`` of the samples
    decided here (no key group, or a batch that the fused engine does not judge, judged here as
    `_evaluate_batch` judges it), and ``[(entries, prepared)]`` for `_finish_batch`: each group's
    samples ``(item, critical)`` and its `kgm.judges.fused.Prepared` batch. Errors name the
    sample."""
    from ..judges.fused import prepare_fused

    rows, groups = _screened_groups(job, items)
    work = []
    for (blocks, params), entries in groups.items():
        settings = entries[0][2].problem.settings
        try:
            prepared = prepare_fused([member for _, member, _ in entries], blocks, settings=settings.dda,
                                     params=params)
        except Exception:
            prepared = None  # judged here, each sample on its own where it errs (`_judge_group`)
        if prepared is None:
            rows += _judge_group(job, blocks, params, entries)
            continue
        work.append(([(item, screened.row.critical) for item, _, screened in entries], prepared))
    return rows, work


def _prepare_sent(job: _Job, items: tuple) -> tuple:
    """`_prepare_batch` as a preparing worker sends it: each group ``(indices, bytes)``, its
    samples' indices and its work pickled once, here; the study's process hands the bytes to the
    runner as they are, unpickling and pickling again none of the prepared members."""
    rows, work = _prepare_batch(job, items)
    _keep_for_life()
    return rows, [([item[0] for item, _ in part[0]], pickle.dumps(part, pickle.HIGHEST_PROTOCOL)) for part in work]


def _keep_for_life() -> None:
    """In a study's worker process, once (its first batch prepared, or the kernel loaded): the
    objects alive then (modules, the scene script, the kernel) taken out of the collector's full
    passes (`gc.freeze`), each of which walked them all again (~30–40 ms a pass)."""
    import gc
    import multiprocessing

    if multiprocessing.parent_process() is not None and not gc.get_freeze_count():
        gc.collect()
        gc.freeze()


@dataclass(frozen=True)
class _Whole:
    """A batch that the study's idle runner judges whole, from its screens (`_prepared_then_run`)."""

    items: tuple


def _finish_batch(job: _Job, work) -> list:
    """[(index, `SampleRow`)] of a `_prepare_batch` group run in one launch of the fused engine
    (`kgm.judges.fused.run_prepared`; errors name the sample, each then judged alone), of a
    `_Whole` judged here from its start; none of an architecture's name (the kernel loaded)."""
    from ..judges.fused import run_prepared

    if isinstance(work, _Whole):
        return _evaluate_batch(job, work.items)
    if isinstance(work, bytes):  # a group as its preparing worker pickled it (`_prepare_sent`)
        work = pickle.loads(work)
    if isinstance(work, str):  # the kernel loaded ahead of the first batch, on this architecture
        from ddatai.fused.warm import warm

        warm(work)
        _keep_for_life()
        return []
    entries, prepared = work
    try:
        verdicts = run_prepared(prepared, report=(job.settings or Settings()).dda.progress)
    except Exception:
        return [(item[0], _evaluate(job, item)) for item, _ in entries]
    return [(item[0], SampleRow(fs=math.nan, failed=not j.stable, critical=critical))
            for (item, critical), j in zip(entries, verdicts)]


def _prepared_then_run(job: _Job, batches: list, workers: int):
    """(index, row) of every sample of ``batches`` on ``workers`` local processes, one a CPU:
    the runner, the only one that loads the fused kernel (once a study), runs what the others
    prepare in NumPy (`_prepare_sent`, `_finish_batch`, `ddatai.workers.Runner`), one batch
    each a round; about to idle (loaded, no whole batch and at most one prepared in hand), it
    judges the last batch not yet begun whole (`_Whole`). A prepared batch lost with the runner
    is recorded as lost, sample by sample (docs/kgm/probabilistic.md)."""
    from ddatai.workers import ProcessPool, Runner

    params = (job.settings or Settings()).dda.params
    samples, whole = {}, {}  # in the runner's hands by key: prepared batches' samples, whole batches, the load
    todo, alone = deque(batches), deque()  # alone: a whole batch's samples lost with the runner
    with Runner(functools.partial(_finish_batch, job)) as runner, \
            ProcessPool(functools.partial(_prepare_sent, job), max(1, workers - 1)) as pool:
        if params is not None and params.kernels == "fused" and params.arch in ("cpu", "cuda", "gpu"):
            runner.submit("load", params.arch)  # the study asks for the fused engine: loaded now
            whole["load"] = ()

        def taken(results):
            for key, rows in results:
                indices, batch = samples.pop(key, ()), whole.pop(key, None)
                if isinstance(rows, WorkerLost) and batch is not None:  # to the others, a sample a batch
                    alone.extend((item,) for item in batch)
                elif isinstance(rows, WorkerLost):
                    yield from ((index, rows) for index in indices)
                else:
                    yield from rows

        while todo or alone or runner.pending:
            yield from taken(runner.poll(timeout=0.0 if todo or alone else 1.0))
            if not todo and not alone:
                continue
            if todo and not whole and len(samples) <= 1:  # the runner idle soon: the last batch whole there
                batch = todo.pop()
                whole[("whole", batch[0][0])] = batch
                runner.submit(("whole", batch[0][0]), _Whole(batch))
                continue
            given = [alone.popleft() if alone else todo.popleft()
                     for _ in range(min(pool.n_workers, len(alone) + len(todo)))]
            for index, out in pool.run([[(b[0][0], b)] for b in given], split=_split_batch):
                if isinstance(out, WorkerLost):
                    yield index, out
                    continue
                rows, work = out
                yield from rows
                for k, (indices, sent) in enumerate(work):
                    samples[(index, k)] = indices
                    runner.submit((index, k), sent)
                yield from taken(runner.poll())


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
    n : samples (subset simulation: samples a level; importance sampling: importance samples,
        after FORM's evaluations).
    method : evaluator of each sample's critical group: 'rigid', 'sarma' or 'dda'.
    sampling : 'monte-carlo' or 'latin-hypercube'; for small probabilities of failure
        'subset' (subset simulation) or 'importance' (FORM, then importance sampling at its
        design point), or their settings `kgm.SubsetSampling` / `kgm.ImportanceSampling`
        (`kgm.studies.rare`, docs/kgm/reliability.md): the limit state FS − 1, under DDA the
        strength-reduction factor of every sample.
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
    progress : called as ``progress(done, n)`` after each completed sample (subset and
        importance sampling: ``progress(evaluations, None)``, their number not known ahead).
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
        if not isinstance(settings, Settings):
            raise ValueError(f"settings must be a kgm.Settings, got {type(settings).__name__}")
    options = rare_sampling(sampling)
    if options is not None:  # subset simulation, importance sampling
        return _rare(build, variables, n, options, method=method, seed=seed, correlation=correlation, group=group,
                     settings=settings, client=client, workers=workers, out=out, geometry_seed=geometry_seed,
                     progress=progress, t0=t0)
    pass_seed = _check_build(build, variables, geometry_seed)
    samples = sample_variables(variables, n, sampling=sampling, seed=seed, correlation=correlation)
    seeds = sample_seeds(seed, n)
    names = tuple(variables)
    group = None if group is None else frozenset(int(b) for b in group)
    identity = dict(n=n, seed=seed, sampling=sampling, method=method, variables=list(names),
                    group=None if group is None else sorted(group), dda_fs=bool(dda_fs))

    done: dict = {}
    if out is not None:
        done = read_samples(Path(out), identity, names)
    resumed = len(done)
    items = [(i, {k: _scalar(samples[k][i]) for k in names}, int(seeds[i])) for i in range(n) if i not in done]
    job = _Job(build=build, method=method, settings=settings, group=group, pass_seed=pass_seed, dda_fs=bool(dda_fs))
    # before any work: this process for limit-equilibrium samples, processes for DDA, and a
    # script whose workers could not import what the study needs is told what to add
    workers = plan(functools.partial(_evaluate, job), client=client, workers=workers,
                   cost="heavy" if method is Method.DDA else "light", caller="kgm.probabilistic")
    # DDA verdicts: samples judged side by side, a batch of them per item (kgm.judges.batch.judge_members)
    size = (settings.dda if settings is not None else DdaSettings()).sample_batch \
        if method is Method.DDA and not dda_fs else 1
    if size > 1:
        # one batch a worker or more (a larger batch shares a step among more samples: per
        # sample a batch of 128 costs a fifth of one of 16); none larger than asked, nor than
        # SAVED_BATCH: a batch's samples reach the file when the batch ends
        sharing = 1 if client is None and workers == 1 else _n_workers(client, workers)
        size = max(1, min(size, SAVED_BATCH, -(-len(items) // sharing)))
        batches = [tuple(items[i:i + size]) for i in range(0, len(items), size)]
        if client is None and workers > 1:
            # all the workers but one prepare each batch in NumPy and that one runs them on the
            # fused kernel, loaded once a study (a batch that the fused engine does not judge is
            # judged where it was prepared)
            flat = _prepared_then_run(job, batches, workers)
        else:
            flat = _rows_of_batches(run(functools.partial(_evaluate_batch, job), [(b[0][0], b) for b in batches],
                                        client=client, workers=workers, chunk=1, split=_split_batch))
    else:
        flat = run(functools.partial(_evaluate, job), [(it[0], it) for it in items], client=client, workers=workers)
    writer = StudyFile(Path(out), identity, names) if out is not None else None
    by_index = {it[0]: it for it in items}
    try:
        for index, row in flat:
            if isinstance(row, WorkerLost):
                warnings.warn(f"kgm.probabilistic: sample {index} ({_describe(by_index[index][1])}, seed "
                              f"{int(seeds[index])}) recorded as lost: {row}", RuntimeWarning, stacklevel=2)
                row = SampleRow.given_up()
            done[index] = row
            if writer is not None:
                writer.append(index, int(seeds[index]), [samples[k][index] for k in names], row)
            if progress is not None:
                progress(len(done), n)
    finally:
        if writer is not None:
            writer.close()
    table = study_table(n, names, samples, seeds, done)
    return Study(n=n, pf=pf_of(table), beta=reliability_index(table["fs"]), table=table, variables=names,
                 method=method, sampling=sampling, seed=seed, resumed=resumed,
                 wall_time=time.perf_counter() - t0, pf_cov=monte_carlo_cov(table), evaluations=n)


def _rare(build, variables: Mapping, n: int, options, *, method: Method, seed: int, correlation, group, settings,
          client, workers, out, geometry_seed, progress, t0: float) -> Study:
    """Subset simulation or importance sampling (`kgm.studies.rare`) on this module's samples:
    each evaluation a sample as `_evaluate` runs it, under DDA with its FS by strength
    reduction (the limit state; a verdict alone gives the estimators nothing to climb)."""
    from ddatai.parallel import plan

    _check_sampling(variables, n, Sampling.MONTE_CARLO, correlation)
    if geometry_seed:
        raise ValueError(f"geometry_seed=True with sampling={options.name.value!r}: a new joint realisation per "
                         "sample is not a variable of the limit state these estimators follow; use Monte Carlo")
    _check_build(build, variables, False)
    transform = Transform(variables, correlation)
    if transform.dim == 0:
        raise ValueError(f"sampling={options.name.value!r} needs at least one variable with a distribution")
    group = None if group is None else frozenset(int(b) for b in group)
    job = _Job(build=build, method=method, settings=settings, group=group, pass_seed=False,
               dda_fs=method is Method.DDA)
    fn = functools.partial(_evaluate, job)
    workers = plan(fn, client=client, workers=workers, cost="heavy" if method is Method.DDA else "light",
                   caller="kgm.probabilistic")
    return rare_study(fn, transform, options, n, method=method, seed=seed, group=group, client=client,
                      workers=workers, out=out, progress=progress, describe=_describe, t0=t0)


def _split_batch(batch: tuple) -> list:
    """A batch of samples as its single samples (run alone after a worker died running it)."""
    return [(item[0], (item,)) for item in batch]


def _rows_of_batches(results):
    """(index, row) of each sample of each batch's results; a lost one as it comes."""
    for index, rows in results:
        if isinstance(rows, WorkerLost):
            yield index, rows
        else:
            yield from rows


def _n_workers(client, workers: Optional[int]) -> int:
    """How many evaluate at once: the local workers, or the Dask cluster's."""
    if client is None:
        from ddatai.parallel import default_workers

        return workers or default_workers()
    try:
        return max(1, len(client.scheduler_info()["workers"]))
    except Exception:
        return 1
