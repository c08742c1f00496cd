"""Local worker processes that survive a lost worker (`ddatai.parallel`'s local executor).

A worker process can die in the middle of an item: the kernel's out-of-memory killer, a crash
in a native library, a user's ``kill``. `concurrent.futures.ProcessPoolExecutor` then breaks as
a whole (``BrokenProcessPool``): every pending item fails, including those running on the other,
healthy workers, and a study saves nothing of them. Here each worker holds one chunk at a time
over its own pipe and sends back each item's result as it completes, so the parent knows, when
a worker dies, exactly which item was running on it:

* the items of the chunk that had completed have already been yielded;
* the items after it had not started: they go back to the queue, charged with nothing;
* the item that was running is charged one death and runs again, alone, on another worker
  (a fresh one is started in place of the dead). An item that can be split into parts (a batch
  of a study's samples judged side by side: ``split``) runs again as its parts, each alone, so
  that one sample that kills its worker takes none of the others with it again. An item that
  was running when its worker died ``max_deaths`` times (default 2) is given up: `WorkerLost`
  is yielded in place of its result, and the rest of the work completes.

An exception raised by the function is not a death: it is raised in the caller, with the
worker's traceback as its cause, and the workers are stopped. A worker that dies before it is
ready (it cannot import what the function needs, or is killed while starting) is replaced;
when that happens ``START_FAILURES`` times in a row the run stops with an error saying so.
"""

from __future__ import annotations

import os
import pickle
import signal
import traceback
from collections import deque
from dataclasses import dataclass
from typing import Any, Callable, Iterator, Optional, Sequence

#: consecutive workers that die before they are ready before `run_processes` gives up [-]
START_FAILURES = 3
#: a stopping worker's time to exit before it is killed [s]
JOIN_TIMEOUT = 2.0


@dataclass(frozen=True, kw_only=True)
class WorkerLost:
    """In place of an item's result: its worker process died each time it ran (`ddatai.workers`).
    A study records the sample as lost (with its values) and completes the others."""

    deaths: int
    """Times a worker died while running the item [-]."""
    exitcode: Optional[int] = None
    """Exit status of the last worker that died (−N: killed by signal N; None: not known, e.g. on
    a Dask cluster)."""

    def __str__(self) -> str:
        times = "once" if self.deaths == 1 else f"{self.deaths} times"
        return f"its worker process died {times} while running it ({describe_exit(self.exitcode)})"


def describe_exit(code: Optional[int]) -> str:
    """'killed by SIGKILL', 'exit status 1', or 'exit status not known'."""
    if code is None:
        return "exit status not known"
    if code < 0:
        try:
            return f"killed by {signal.Signals(-code).name}"
        except ValueError:
            return f"killed by signal {-code}"
    return f"exit status {code}"


class RemoteTraceback(Exception):
    """The traceback of an exception raised in a worker process (the cause of the exception
    re-raised in the caller)."""

    def __init__(self, tb: str):
        super().__init__(tb)
        self.tb = tb

    def __str__(self) -> str:
        return f'\n"""\n{self.tb}"""'


def _pickled_exception(exc: BaseException) -> bytes:
    try:
        data = pickle.dumps(exc)
        pickle.loads(data)
        return data
    except Exception:  # noqa: BLE001 - an exception that does not survive pickling
        return pickle.dumps(RuntimeError(f"{type(exc).__name__}: {exc}"))


def _serve(conn, payload: bytes) -> None:
    """A worker: load the function, then run the chunks it is sent, one message per item."""
    try:
        fn = pickle.loads(payload)
    except BaseException as exc:  # noqa: BLE001 - reported to the parent, which raises it
        conn.send(("fatal", _pickled_exception(exc), traceback.format_exc()))
        return
    conn.send(("ready", os.getpid()))
    while True:
        try:
            chunk = conn.recv()
        except (EOFError, OSError):  # the parent has gone
            return
        if chunk is None:
            return
        for index, item in chunk:
            try:
                conn.send(("result", index, fn(item)))
            except Exception as exc:  # noqa: BLE001 - raised in the caller
                conn.send(("error", index, _pickled_exception(exc), traceback.format_exc()))
                break
        conn.send(("done",))


class _Worker:
    """One worker process, its pipe and the items of its chunk not yet returned."""

    def __init__(self, ctx, payload: bytes):
        self.conn, child = ctx.Pipe(duplex=True)
        self.process = ctx.Process(target=_serve, args=(child, payload), name="ddatai-worker")
        self.process.start()
        child.close()
        self.ready = False
        self.chunk: Optional[deque] = None  # (index, item) sent and not yet returned

    @property
    def idle(self) -> bool:
        return self.ready and self.chunk is None

    def give(self, chunk: list) -> None:
        self.chunk = deque(chunk)
        self.conn.send(chunk)

    def messages(self) -> tuple[list, bool]:
        """The messages waiting, and whether the pipe has closed (the worker died)."""
        out = []
        try:
            while self.conn.poll():
                out.append(self.conn.recv())
        except (EOFError, OSError):
            return out, True
        return out, False

    def stop(self, *, kill: bool = False) -> None:
        if not kill and self.idle and self.process.is_alive():
            try:
                self.conn.send(None)
            except OSError:
                pass
            self.process.join(JOIN_TIMEOUT)
        if self.process.is_alive():
            self.process.kill()
            self.process.join(JOIN_TIMEOUT)
        self.conn.close()


class ProcessPool:
    """Worker processes running ``fn``, kept between calls of `run` (a study that evaluates its
    samples batch after batch starts its workers once). Use as a context manager, or `close`."""

    def __init__(self, fn: Callable, n_workers: int):
        import multiprocessing

        # spawn, not fork: a forked child would inherit a half-initialised Taichi runtime or MKL
        # thread pool of the parent
        self._ctx = multiprocessing.get_context("spawn")
        self._payload = pickle.dumps(fn)
        self.n_workers = int(n_workers)
        self._workers: list[_Worker] = []
        self._start_failures = 0

    def __enter__(self) -> "ProcessPool":
        return self

    def __exit__(self, *exc) -> None:
        self.close(kill=exc[0] is not None)

    def close(self, *, kill: bool = False) -> None:
        """Stop the workers (``kill``: at once, whatever they are doing)."""
        for w in self._workers:
            w.stop(kill=kill)
        self._workers = []

    def run(self, chunks: Sequence[list], *, split: Optional[Callable] = None,
            max_deaths: int = 2) -> Iterator[tuple[int, Any]]:
        """Evaluate ``fn(item)`` for every ``(index, item)`` of ``chunks``; yields ``(index,
        result)`` as each completes, or ``(index, WorkerLost)`` for an item given up (module
        docstring). ``split(item)``: the item's parts as ``[(index, part)]`` (one result
        each), to run alone after a death; None or a single part: not divisible. Left before
        its end (an error, a caller that stops), the workers still busy are killed."""
        from multiprocessing.connection import wait

        queue = deque(list(c) for c in chunks if len(c))
        deaths: dict = {}       # index -> deaths charged to that item
        workers = self._workers
        ok = False
        try:
            while queue or any(w.chunk for w in workers):
                while len(workers) < min(self.n_workers, len(queue) + sum(w.chunk is not None for w in workers)):
                    workers.append(_Worker(self._ctx, self._payload))
                for w in workers:
                    if w.idle and queue:
                        w.give(queue.popleft())
                waiting = {w.conn: w for w in workers}
                waiting.update({w.process.sentinel: w for w in workers})
                touched = {id(waiting[r]): waiting[r] for r in wait(list(waiting))}
                for w in touched.values():
                    msgs, closed = w.messages()
                    for msg in msgs:
                        kind = msg[0]
                        if kind == "ready":
                            w.ready, self._start_failures = True, 0
                        elif kind == "result":
                            w.chunk.popleft()
                            yield msg[1], msg[2]
                        elif kind == "done":
                            w.chunk = None
                        elif kind in ("error", "fatal"):
                            exc = pickle.loads(msg[-2])
                            exc.__cause__ = RemoteTraceback(msg[-1])
                            raise exc
                    if not closed and w.process.is_alive():
                        continue
                    # the worker died: its item in flight is charged, the rest go back to the queue
                    w.process.join(JOIN_TIMEOUT)
                    code = w.process.exitcode
                    workers.remove(w)
                    w.conn.close()
                    if not w.ready:
                        self._start_failures += 1
                        if self._start_failures >= START_FAILURES:
                            raise RuntimeError(f"{self._start_failures} worker processes in a row died as they "
                                               f"started ({describe_exit(code)}): they cannot start on this "
                                               "machine (memory?); pass workers=1 to run in this process")
                        continue
                    if not w.chunk:
                        continue
                    (index, item), rest = w.chunk[0], list(w.chunk)[1:]
                    if rest:
                        queue.appendleft(rest)
                    count = deaths[index] = deaths.get(index, 0) + 1
                    parts = split(item) if split is not None else None
                    if parts is not None and len(parts) > 1:
                        for part in reversed(parts):
                            deaths[part[0]] = count
                            queue.appendleft([part])
                    elif count >= max_deaths:
                        yield index, WorkerLost(deaths=count, exitcode=code)
                    else:
                        queue.appendleft([(index, item)])
            ok = True
        finally:
            if not ok:  # a busy worker's results would reach the next run: stop it
                for w in [w for w in workers if w.chunk is not None or not w.ready]:
                    w.stop(kill=True)
                    workers.remove(w)


def run_processes(fn: Callable, chunks: Sequence[list], n_workers: int, *, split: Optional[Callable] = None,
                  max_deaths: int = 2) -> Iterator[tuple[int, Any]]:
    """`ProcessPool.run` on a pool of its own, closed at the end."""
    with ProcessPool(fn, n_workers) as pool:
        yield from pool.run(chunks, split=split, max_deaths=max_deaths)


# ---------------------------------------------------------------------- one process, many items
def _serve_in_order(inbox, conn, payload: bytes) -> None:
    """`Runner`'s process: load the function, then run the items of ``inbox`` in the order
    sent, one message per item."""
    try:
        fn = pickle.loads(payload)
    except BaseException as exc:  # noqa: BLE001 - reported to the parent, which raises it
        conn.send(("fatal", None, _pickled_exception(exc), traceback.format_exc()))
        return
    while True:
        message = inbox.get()
        if message is None:
            return
        key, item = message
        try:
            conn.send(("result", key, fn(item)))
        except Exception as exc:  # noqa: BLE001 - raised in the caller
            conn.send(("error", key, _pickled_exception(exc), traceback.format_exc()))
            return


class Runner:
    """One worker process that runs ``fn`` on items sent to it (`submit`), one at a time in the
    order sent, keeping what it loaded between them: a study's one process that has loaded the
    fused kernel and runs the batches its other workers prepared (`kgm.probabilistic`).
    `submit` never waits (a queue's thread sends the item); `poll` takes the results that
    have come, `drain` waits for all. A process that dies loses nothing that completed: a fresh
    one runs the items not yet returned again, and the item it was running when it died
    ``max_deaths`` times (default 2) is given up (`WorkerLost` in place of its result). An
    exception raised by ``fn`` is raised in the caller with the worker's traceback as its cause.
    A context manager; `close` stops the process."""

    def __init__(self, fn: Callable, *, max_deaths: int = 2):
        import multiprocessing

        self._ctx = multiprocessing.get_context("spawn")  # as `ProcessPool`: no half-started runtimes
        self._payload = pickle.dumps(fn)
        self.max_deaths = int(max_deaths)
        self._pending: dict = {}  # key -> item, sent and not yet returned (in the order sent)
        self._deaths: dict = {}   # key -> deaths charged
        self._process = None

    def __enter__(self) -> "Runner":
        return self

    def __exit__(self, *exc) -> None:
        self.close(kill=exc[0] is not None)

    def _start(self) -> None:
        self._inbox = self._ctx.Queue()
        self._conn, child = self._ctx.Pipe(duplex=False)
        self._process = self._ctx.Process(target=_serve_in_order, args=(self._inbox, child, self._payload),
                                          name="ddatai-runner")
        self._process.start()
        child.close()
        for key, item in self._pending.items():
            self._inbox.put((key, item))

    def submit(self, key, item) -> None:
        """Send ``item`` to the process (started the first time); its result comes back under
        ``key`` from `poll` or `drain`."""
        if key in self._pending:
            raise ValueError(f"an item with key {key!r} is already running")
        self._pending[key] = item
        if self._process is None:
            self._start()
        else:
            self._inbox.put((key, item))

    @property
    def pending(self) -> int:
        """Items sent and not yet returned [-]."""
        return len(self._pending)

    def poll(self, timeout: float = 0.0) -> list:
        """The ``(key, result)`` of the items completed since the last call, waiting at most
        ``timeout`` seconds for the first of them [s]."""
        from multiprocessing.connection import wait

        if self._process is None or not self._pending:
            return []
        out = []
        ready = wait([self._conn, self._process.sentinel], timeout)
        closed = False
        if ready:
            try:
                while self._conn.poll():
                    kind, key, *rest = self._conn.recv()
                    if kind == "result":
                        self._pending.pop(key, None)
                        out.append((key, rest[0]))
                    else:  # an exception in fn: raised here, the process has ended
                        exc = pickle.loads(rest[0])
                        exc.__cause__ = RemoteTraceback(rest[1])
                        self.close(kill=True)
                        raise exc
            except (EOFError, OSError):
                closed = True
        if closed and self._pending:
            out += self._lost()
        return out

    def _lost(self) -> list:
        """The process died: the item it was running (the first not returned) is charged a death,
        and a fresh process runs the rest again. Returns the items given up."""
        self._process.join(JOIN_TIMEOUT)
        code = self._process.exitcode
        self._conn.close()
        self._inbox.close()
        self._inbox.cancel_join_thread()
        self._process = None
        key = next(iter(self._pending))
        count = self._deaths[key] = self._deaths.get(key, 0) + 1
        given_up = []
        if count >= self.max_deaths:
            self._pending.pop(key)
            given_up.append((key, WorkerLost(deaths=count, exitcode=code)))
        if self._pending:
            self._start()
        return given_up

    def drain(self) -> Iterator[tuple[Any, Any]]:
        """``(key, result)`` of every item not yet returned, as each completes."""
        while self._pending:
            yield from self.poll(timeout=1.0)

    def close(self, *, kill: bool = False) -> None:
        """Stop the process (``kill``: at once, whatever it is doing)."""
        if self._process is None:
            return
        if not kill and not self._pending and self._process.is_alive():
            self._inbox.put(None)
            self._process.join(JOIN_TIMEOUT)
        if self._process.is_alive():
            self._process.kill()
            self._process.join(JOIN_TIMEOUT)
        self._conn.close()
        self._inbox.close()
        self._inbox.cancel_join_thread()
        self._process = None
