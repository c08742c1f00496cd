"""`ddatai.workers.Runner`: one worker process that runs the items sent to it in order, keeping
what it loaded (a study's process that holds the fused kernel), and survives its own death: the
items not yet returned run again in a fresh process, and the item it was running when it died
twice is recorded as lost. And the split of a DDA-judged study's batch that feeds it:
`kgm.studies.probabilistic._prepare_batch` settles the members in NumPy without the kernel."""

import math
import pickle

import numpy as np
import pytest

import worker_cases
from ddatai.workers import RemoteTraceback, Runner, WorkerLost


def test_the_runner_returns_every_item_in_the_order_sent():
    with Runner(worker_cases.square) as runner:
        for k in range(6):
            runner.submit(("batch", k), k)
        assert runner.pending == 6
        out = list(runner.drain())
        assert runner.pending == 0
    assert out == [(("batch", k), k * k) for k in range(6)]
    with pytest.raises(ValueError, match="already running"):
        with Runner(worker_cases.square) as runner:
            runner.submit(0, 1)
            runner.submit(0, 2)


def test_a_runner_that_dies_runs_the_rest_again_and_gives_up_the_killer():
    """Item 7 kills its process every time: the items before it have returned, those after it
    run in a fresh process, and 7 is given up after its second death."""
    with Runner(worker_cases.kills_on_seven) as runner:
        for k in (1, 2, 7, 3, 4):
            runner.submit(k, k)
        out = dict(runner.drain())
    assert sorted(out) == [1, 2, 3, 4, 7]
    assert all(out[k] == k * k for k in (1, 2, 3, 4))
    assert isinstance(out[7], WorkerLost) and out[7].deaths == 2 and out[7].exitcode == -9


def test_an_error_in_the_runner_is_raised_with_its_traceback():
    with Runner(worker_cases.fails_on_three) as runner:
        for k in (1, 3, 5):
            runner.submit(k, k)
        with pytest.raises(ValueError, match="three is refused") as info:
            list(runner.drain())
    assert isinstance(info.value.__cause__, RemoteTraceback)
    assert "fails_on_three" in str(info.value.__cause__)


def test_a_study_s_worker_process_keeps_what_it_holds_out_of_the_collector_once():
    """`_keep_for_life` in a worker process: the objects alive then are left out of the
    collector's full passes (`gc.freeze`), once; in the study's own process nothing is."""
    import gc

    from kgm.studies.probabilistic import _keep_for_life

    with Runner(worker_cases.frozen_by_keep_for_life) as runner:
        runner.submit(0, None)
        [(_, (before, once, twice))] = list(runner.drain())
    assert before == 0 and once > 1000 and twice == once
    count = gc.get_freeze_count()
    _keep_for_life()
    assert gc.get_freeze_count() == count


def test_a_study_batch_is_prepared_without_the_fused_kernel(monkeypatch):
    """`_prepare_batch` of two Example II samples on the fused engine: each member's sub-model
    built and settled by its own stage (NumPy), nothing launched; the samples keep their order
    and their critical group, and the batch pickles (to the runner) and comes back bit for bit."""
    from pathlib import Path

    import ddatai as dd
    from ddatai.fused import engine
    from ddatai.parallel import ScriptFunction
    from kgm.kinds import Method
    from kgm.settings import DdaSettings, Settings
    from kgm.studies.probabilistic import _Job, _prepare_batch

    def refused(*args, **kwargs):
        raise AssertionError("a study's worker launched the fused kernel")

    monkeypatch.setattr(engine, "run", refused)
    root = Path(__file__).resolve().parents[1]
    settings = Settings(dda=DdaSettings(params=dd.Params(dt=0.0013, penalty_ratio=1.0, kernels="fused")))
    job = _Job(build=ScriptFunction(str(root / "scenes" / "example_2.py")), method=Method.DDA, settings=settings,
               group=frozenset({0, 1}), pass_seed=False)
    items = tuple((i, {"friction": f, "cohesion": 20e3}, 7 + i) for i, f in enumerate((16.0, 30.0)))
    rows, work = _prepare_batch(job, items)
    assert rows == []
    (entries, prepared), = work
    assert [item[0] for item, _ in entries] == [0, 1]
    assert all(critical == (0, 1) or set(critical) == {0, 1} for _, critical in entries)
    assert len(prepared.runs) == 2 and len(prepared.plans) == 2
    assert all(math.isfinite(p.delta) and p.delta > 0 for p in prepared.plans)
    # every member starts from its own stage's state (time 0, settled or released)
    assert all(run.state.time == 0.0 for run in prepared.runs)
    # sent to the runner (the states field by field, `Prepared.__reduce__`): back bit for bit
    back = pickle.loads(pickle.dumps(prepared, pickle.HIGHEST_PROTOCOL))
    for run, got in zip(prepared.runs, back.runs):
        assert (got.t_end, got.stop_at, got.group) == (run.t_end, run.stop_at, run.group)
        for name, value in vars(run.state).items():
            for part, want in (vars(value).items() if name == "memory" else [(name, value)]):
                have = getattr(got.state.memory, part) if name == "memory" else getattr(got.state, part)
                assert type(have) is type(want) and getattr(have, "dtype", None) == getattr(want, "dtype", None), part
                np.testing.assert_equal(have, want, err_msg=part)


def test_a_study_runs_on_its_workers_count_and_the_idle_runner_judges_the_last_batch_whole(monkeypatch):
    """`_prepared_then_run` with ``workers=2``: one preparing process beside the runner (not
    two), every sample's row once; a runner about to idle (no whole batch and at most one
    prepared in hand) takes the last batch not yet begun and judges it whole, and the samples of
    a whole batch lost with it are prepared by the others; a prepared batch reaches the runner
    as the bytes its worker pickled (in-process stand-ins for the processes, the phases
    stubbed: only the schedule is tested)."""
    from types import SimpleNamespace

    import ddatai.workers
    from kgm.studies import probabilistic as pr

    class Pool:
        sizes = []

        def __init__(self, fn, n_workers):
            self.fn, self.n_workers = fn, n_workers
            Pool.sizes.append(n_workers)

        def __enter__(self):
            return self

        def __exit__(self, *exc):
            pass

        def run(self, chunks, *, split=None):
            for chunk in chunks:
                for index, item in chunk:
                    yield index, self.fn(item)

    class Busy:  # returns its items only when drained: never idle once it has one
        given = []

        def __init__(self, fn):
            self.fn, self.items = fn, []

        def __enter__(self):
            return self

        def __exit__(self, *exc):
            pass

        def submit(self, key, item):
            self.items.append((key, item))
            Busy.given.append(item)

        @property
        def pending(self):
            return len(self.items)

        def poll(self, timeout=0.0):  # waiting, as if each item had taken that long
            return self.drain() if timeout > 0 else []

        def drain(self):
            out, self.items = [(key, self.fn(item)) for key, item in self.items], []
            return out

    class Eager(Busy):  # returns its items at the next poll: idle whenever asked
        def poll(self, timeout=0.0):
            return self.drain()

    class Lagging(Busy):  # returns at each poll all but the item it has just been given
        def poll(self, timeout=0.0):
            if timeout > 0:
                return self.drain()
            out = [(key, self.fn(item)) for key, item in self.items[:-1]]
            self.items = self.items[-1:]
            return out

    class Losing(Eager):  # dies twice with every batch it is given whole
        def drain(self):
            return [(key, WorkerLost(deaths=2) if isinstance(item, pr._Whole) else out)
                    for (key, item), (_, out) in zip(self.items, super().drain())]

    monkeypatch.setattr(ddatai.workers, "ProcessPool", Pool)
    monkeypatch.setattr(pr, "_prepare_batch", lambda job, items: ([], [([(it, (0, 1)) for it in items], "prepared")]))
    monkeypatch.setattr(pr, "_evaluate_batch", lambda job, items: [(it[0], "whole") for it in items])
    import kgm.judges.fused

    monkeypatch.setattr(kgm.judges.fused, "run_prepared", lambda prepared, report=None: [SimpleNamespace(stable=True)] * 3)
    monkeypatch.setattr(pr, "SampleRow", lambda **kw: "run")  # the runs' verdicts not looked at
    job = pr._Job(build=None, method=None, settings=None, group=None, pass_seed=False)
    batches = [tuple((3 * b + k, {}, 0) for k in range(3)) for b in range(4)]

    monkeypatch.setattr(ddatai.workers, "Runner", Busy)
    rows = list(pr._prepared_then_run(job, batches, 2))
    assert Pool.sizes == [1]
    assert sorted(i for i, _ in rows) == list(range(12))
    assert dict(rows) == {i: "whole" if i >= 9 else "run" for i in range(12)}  # idle only at the start
    sent = [item for item in Busy.given if not isinstance(item, pr._Whole)]
    assert len(sent) == 3 and all(isinstance(item, bytes) for item in sent)  # as pickled by the worker

    monkeypatch.setattr(ddatai.workers, "Runner", Eager)
    rows = list(pr._prepared_then_run(job, batches, 3))
    assert Pool.sizes == [1, 2]
    assert sorted(i for i, _ in rows) == list(range(12)) and {r for _, r in rows} == {"whole"}

    # a runner with one prepared batch in hand and none whole is about to idle: it takes one whole
    monkeypatch.setattr(ddatai.workers, "Runner", Lagging)
    rows = list(pr._prepared_then_run(job, batches, 2))
    assert dict(rows) == {i: "whole" if i >= 6 else "run" for i in range(12)}

    # a whole batch lost with the runner: its samples prepared by the others, one a batch
    monkeypatch.setattr(ddatai.workers, "Runner", Losing)
    rows = list(pr._prepared_then_run(job, batches, 2))
    assert sorted(i for i, _ in rows) == list(range(12)) and {r for _, r in rows} == {"run"}
