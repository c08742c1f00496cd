"""Studies and sweeps that survive their workers (`ddatai.workers`): a worker process killed in
the middle of a sample (SIGKILL, as the out-of-memory killer sends it) loses that sample only;
it runs again on another worker, and a sample that kills its worker twice is recorded as lost
with its values while the rest completes. On a Dask cluster, after the cluster's own retries."""

import importlib.util
import math
import warnings

import numpy as np
import pytest
import scipy.stats as st

import kgm
import kgm_cases
import worker_cases
from ddatai.workers import WorkerLost, describe_exit, run_processes

#: Latin hypercube over 20-45° with 30 samples: one sample in each 5/6° stratum, so exactly one
#: above kgm_cases.KILL_ABOVE (the top stratum starts at 44.1667°)
VARIABLES = {"friction": st.uniform(20.0, 25.0)}
N = 30


def _study(build, **kw):
    return kgm.probabilistic(build, VARIABLES, N, method="rigid", group={1}, sampling="latin-hypercube", seed=5,
                             **kw)


def test_a_killed_worker_loses_only_the_item_it_ran():
    chunks = [[(i, i) for i in range(k, k + 5)] for k in range(0, 20, 5)]
    out = dict(run_processes(worker_cases.kills_on_seven, chunks, 2))
    # every other item completes once; item 7 killed its worker twice (alone the second time)
    assert sorted(out) == list(range(20))
    assert all(out[i] == i * i for i in range(20) if i != 7)
    lost = out[7]
    assert isinstance(lost, WorkerLost) and lost.deaths == 2 and lost.exitcode == -9
    assert "died 2 times" in str(lost) and "SIGKILL" in str(lost)
    assert describe_exit(1) == "exit status 1" and describe_exit(None) == "exit status not known"


def test_a_divisible_item_runs_again_as_its_parts():
    """A batch (one item of several samples) killed by one of them: its parts run alone, the
    killer is lost, the others complete."""
    batches = [(0, tuple((i, i) for i in range(0, 5))), (5, tuple((i, i) for i in range(5, 10)))]

    def split(batch):
        return [(i, ((i, x),)) for i, x in batch]

    rows = {}
    for index, result in run_processes(worker_cases.kills_on_seven_in_batch, [[b] for b in batches], 2, split=split):
        if isinstance(result, WorkerLost):
            rows[index] = result
        else:
            rows.update(result)
    assert sorted(rows) == list(range(10))
    assert isinstance(rows[7], WorkerLost) and rows[7].deaths == 2
    assert all(rows[i] == i * i for i in range(10) if i != 7)


def test_each_result_comes_back_as_it_completes_not_with_its_chunk(tmp_path):
    """Item 1 of a chunk waits for a file that the caller writes on receiving item 0's result:
    it sees it only if item 0's result came back before the chunk ended (a study saves every
    sample as it completes)."""
    mark = str(tmp_path / "got-0")
    out = {}
    for index, result in run_processes(worker_cases.waits_for_mark, [[(0, (0, mark)), (1, (1, mark))]], 1):
        out[index] = result
        if index == 0:
            open(mark, "w").close()
    assert out == {0: True, 1: True}


def test_an_exception_is_raised_with_the_workers_traceback():
    with pytest.raises(ValueError, match="three is refused") as info:
        list(run_processes(worker_cases.fails_on_three, [[(i, i) for i in range(6)]], 2))
    assert "fails_on_three" in str(info.value.__cause__)


def _check_lost_sample(study, ref, out, build, **kw):
    """The study's one lost sample (the top stratum's, friction above KILL_ABOVE): recorded with
    its values, the others as an uninterrupted study gives them; the file holds it, so that
    resuming runs nothing and reads the same table back. ``ref``: the study run in this
    process, nothing lost."""
    assert not ref.lost.any()
    killer = np.flatnonzero(ref.table["friction"] > kgm_cases.KILL_ABOVE)
    assert len(killer) == 1
    assert np.flatnonzero(study.lost).tolist() == killer.tolist()
    row = study.table[killer[0]]
    # recorded with its values: index, seed and friction as drawn; no FS, not failed
    assert row["friction"] == ref.table["friction"][killer[0]] and row["seed"] == ref.table["seed"][killer[0]]
    assert math.isnan(row["fs"]) and not row["failed"] and row["critical"] == ""
    others = ~study.lost
    for k in ("index", "seed", "friction", "fs", "failed", "critical"):
        assert np.array_equal(study.table[k][others], ref.table[k][others]), k
    # P_f over the samples evaluated, and the summary says what was left out
    assert study.pf == pytest.approx(np.mean(ref.failed[others]))
    assert "1 sample(s) lost" in study.summary()
    calls = []
    again = _study(build, out=out, progress=lambda d, n: calls.append(d), **kw)
    assert again.resumed == N and not calls
    back = kgm.read_study(out)
    for k in study.table.dtype.names:
        assert np.array_equal(again.table[k], study.table[k], equal_nan=k == "fs"), k
        assert np.array_equal(back.table[k], study.table[k], equal_nan=k == "fs"), k
    assert back.pf == study.pf


def test_a_lost_sample_is_recorded_with_its_values_and_the_rest_completes(tmp_path, monkeypatch):
    """The study's side, in this process: the executor gives up the top stratum's sample
    (`WorkerLost` in place of its row, as `ddatai.workers` yields it after two deaths); the
    real deaths are `test_a_sample_that_kills_its_worker_twice_is_recorded_and_the_rest_completes`
    (slow)."""
    import ddatai.parallel

    run = ddatai.parallel.run

    def losing(fn, items, **kw):
        items = list(items)
        friction = {index: item[1]["friction"] for index, item in items}
        for index, row in run(fn, items, **kw):
            yield index, WorkerLost(deaths=2, exitcode=-9) if friction[index] > kgm_cases.KILL_ABOVE else row

    ref = _study(kgm_cases.incline_scene, workers=1)
    monkeypatch.setattr(ddatai.parallel, "run", losing)
    out = tmp_path / "study.csv"
    with pytest.warns(RuntimeWarning, match=r"sample \d+ \(friction=4[45]\.\d+, seed \d+\) recorded as lost: its "
                                            r"worker process died 2 times"):
        study = _study(kgm_cases.incline_scene, workers=1, out=out)
    _check_lost_sample(study, ref, out, kgm_cases.incline_scene, workers=1)


@pytest.mark.slow
def test_a_sample_that_kills_its_worker_twice_is_recorded_and_the_rest_completes(tmp_path):
    """Worker processes killed by SIGKILL in the middle of a study. About 6 s on the shared
    machine (four workers start, each importing kgm)."""
    out = tmp_path / "study.csv"
    with pytest.warns(RuntimeWarning, match=r"sample \d+ \(friction=4[45]\.\d+, seed \d+\) recorded as lost: its "
                                            r"worker process died 2 times"):
        study = _study(kgm_cases.incline_scene_killing, workers=2, out=out)
    _check_lost_sample(study, _study(kgm_cases.incline_scene, workers=1), out, kgm_cases.incline_scene_killing,
                       workers=2)


@pytest.mark.slow
def test_a_worker_lost_once_changes_nothing(tmp_path, monkeypatch):
    """A worker killed once, by a cause outside its sample: the sample runs again on another
    worker and the table is the uninterrupted one, bit for bit. About 3 s on the shared machine
    (three workers start)."""
    monkeypatch.setenv(kgm_cases.DIE_ONCE, str(tmp_path / "died"))
    out = tmp_path / "study.csv"
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)  # nothing lost
        study = _study(kgm_cases.incline_scene_dies_once, workers=2, out=out)
    assert (tmp_path / "died").exists()  # a worker was killed
    ref = _study(kgm_cases.incline_scene, workers=1)
    assert np.array_equal(study.table, ref.table) and not study.lost.any()
    assert np.array_equal(kgm.read_study(out).table, ref.table)


def test_an_old_study_file_without_the_lost_column_is_resumed(tmp_path):
    """A file written before studies recorded lost samples (no 'lost' column), cut after 12
    samples: resumed as it is (rewritten with the column), the same table as a whole run."""
    import json

    ref = _study(kgm_cases.incline_scene, workers=1)
    identity = dict(n=N, seed=5, sampling="latin-hypercube", method="rigid", variables=["friction"], group=[1],
                    dda_fs=False)
    from kgm.studies.study import HEADER_MARK

    lines = [HEADER_MARK + json.dumps(identity) + "\n", "index,seed,friction,fs,failed,critical\r\n"]
    for r in ref.table[:12]:
        lines.append(f"{r['index']},{r['seed']},{float(r['friction'])!r},{float(r['fs'])!r},{int(r['failed'])},"
                     f"{r['critical']}\r\n")
    out = tmp_path / "old.csv"
    out.write_text("".join(lines), newline="")
    study = _study(kgm_cases.incline_scene, workers=1, out=out)
    assert study.resumed == 12 and np.array_equal(study.table, ref.table)
    assert np.array_equal(kgm.read_study(out).table, ref.table)


@pytest.mark.slow
def test_a_sweep_run_that_kills_its_worker_twice_is_a_row_saying_so():
    """About 8 s on the shared machine (two workers start Taichi for their DDA runs)."""
    import ddatai as dd

    rows = dd.sweep(kgm_cases.incline_scene_killing, {"friction": [20.0, 44.5, 35.0]}, duration=0.05, workers=2)
    assert rows["finished"].tolist() == [True, False, True]
    assert rows["cause"][1].startswith("lost: its worker process died 2 times")
    assert np.isnan(rows["max_displacement"][1]) and rows["friction"][1] == 44.5


@pytest.mark.slow
@pytest.mark.skipif(importlib.util.find_spec("distributed") is None,
                    reason="dask.distributed is an optional extra (pip install ddatai[dask])")
def test_on_a_dask_cluster_an_item_that_kills_its_workers_is_given_up_after_the_clusters_retries():
    """About 20 s on the shared machine (a local cluster started, three of its workers killed)."""
    import dask
    from dask.distributed import Client, LocalCluster

    from ddatai.parallel import run

    # the scheduler gives a task up after its first worker death (default: 3 more tries) and
    # queues no task on a busy worker, so that the test kills three workers: the chunk's, then
    # twice the item's alone
    config = {"distributed.scheduler.allowed-failures": 0, "distributed.scheduler.worker-saturation": 1.0}
    with dask.config.set(config):
        with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster, \
                Client(cluster) as client:
            out = dict(run(worker_cases.kills_on_seven, [(i, i) for i in range(12)], client=client, chunk=4))
    assert sorted(out) == list(range(12))
    assert all(out[i] == i * i for i in range(12) if i != 7)
    assert isinstance(out[7], WorkerLost) and out[7].deaths == 2 and "exit status not known" in str(out[7])
