"""Run many independent evaluations (simulations, key group analyses) on local processes or on
a Dask cluster, yielding each result as it completes.

Used by `ddatai.sweep` and `kgm.probabilistic`. Three ways to run, chosen by the caller's
``client`` and ``workers`` arguments:

- ``workers=1`` (and no client): in this process, in order — for debugging and small studies;
- no client: a pool of local worker processes (`concurrent.futures.ProcessPoolExecutor`,
  ``spawn`` start method, so every worker starts its own Taichi runtime once, the first time it
  needs one); the default, with no extra package;
- a ``dask.distributed.Client``, or a scheduler address such as ``"tcp://host:8786"``: the
  cluster's workers (``pip install ddatai[dask]``).

Work is sent in chunks of several items (one task per chunk) so that a cheap evaluation (a
rigid limit-equilibrium analysis takes ~2 ms) is not dominated by the cost of a task. The
function and its items must be picklable: a function defined at the top level of an importable
module (a scene script loaded by path is run by `ScriptFunction`).
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from typing import Any, Callable, Iterator, Optional, Sequence


@dataclass(frozen=True)
class ScriptFunction:
    """A scene script's ``build``, by the script's path: picklable, loaded again in each worker
    (a script loaded from a path is not importable by module name there). Calling it returns
    ``(scene, params)`` (`ddatai.io.scenefile.build_scene`)."""

    path: str
    """Path of the scene script [-]."""

    def resolve(self) -> Callable:
        """The script's ``build`` function (for its signature)."""
        return self._script().build

    def _script(self):
        from .io.scenefile import load_scene_script

        script = _SCRIPT_CACHE.get(self.path)
        if script is None:
            script = _SCRIPT_CACHE[self.path] = load_scene_script(self.path)
        return script

    def __call__(self, **kwargs):
        from .io.scenefile import build_scene

        return build_scene(self._script(), **kwargs)


# per-process cache of loaded scripts (a worker loads each script once)
_SCRIPT_CACHE: dict = {}


def _run_chunk(fn: Callable, chunk: Sequence[tuple[int, Any]]) -> list[tuple[int, Any]]:
    """Worker side: evaluate ``fn(item)`` for each (index, item) of a chunk."""
    return [(index, fn(item)) for index, item in chunk]


def default_workers() -> int:
    """Local worker processes by default: the CPUs this process may use."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # not Linux
        return max(1, os.cpu_count() or 1)


def _chunks(items: Sequence[tuple[int, Any]], size: int) -> list[list[tuple[int, Any]]]:
    return [list(items[i:i + size]) for i in range(0, len(items), size)]


def check_execution(client, workers: Optional[int]) -> None:
    """Clear errors for the execution arguments, before any work."""
    if workers is not None and (not isinstance(workers, int) or isinstance(workers, bool) or workers < 1):
        raise ValueError(f"workers must be an integer >= 1, got {workers!r}")
    if client is not None and not isinstance(client, str) and not hasattr(client, "submit"):
        raise ValueError("client must be None, a dask.distributed.Client or a scheduler address "
                         f"such as 'tcp://host:8786', got {type(client).__name__}")


def run(fn: Callable, items: Sequence[tuple[int, Any]], *, client=None, workers: Optional[int] = None,
        chunk: Optional[int] = None) -> Iterator[tuple[int, Any]]:
    """Evaluate ``fn(item)`` for every ``(index, item)``; yields ``(index, result)`` in
    completion order (any order: callers key results by index). An exception in ``fn`` is
    raised here, naming nothing more than ``fn`` did: callers wrap ``fn`` to name the item."""
    check_execution(client, workers)
    items = list(items)
    if not items:
        return
    if client is None and (workers == 1 or len(items) == 1):
        for index, item in items:
            yield index, fn(item)
        return
    n_workers = workers or default_workers()
    # about 4 chunks per worker keeps them all busy to the end; at most 64 items a chunk so that
    # results (and a resumable study's file) arrive often
    size = chunk or max(1, min(64, len(items) // (4 * n_workers) or 1))
    chunks = _chunks(items, size)
    if client is None:
        if n_workers == 1:
            for index, item in items:
                yield index, fn(item)
            return
        yield from _run_processes(fn, chunks, n_workers)
    else:
        yield from _run_dask(fn, chunks, client)


def _run_processes(fn, chunks, n_workers: int) -> Iterator[tuple[int, Any]]:
    import multiprocessing
    from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait

    # spawn, not fork: a forked child would inherit a half-initialised Taichi runtime or MKL
    # thread pool of the parent
    with ProcessPoolExecutor(max_workers=n_workers, mp_context=multiprocessing.get_context("spawn")) as pool:
        pending = {pool.submit(_run_chunk, fn, c) for c in chunks}
        try:
            while pending:
                done, pending = wait(pending, return_when=FIRST_COMPLETED)
                for future in done:
                    yield from future.result()
        finally:
            for future in pending:
                future.cancel()


def _run_dask(fn, chunks, client) -> Iterator[tuple[int, Any]]:
    try:
        from dask.distributed import Client, as_completed
    except ImportError as exc:  # pragma: no cover - depends on the environment
        raise ImportError("running on a Dask cluster needs dask.distributed: pip install ddatai[dask]") from exc
    own = isinstance(client, str)
    if own:
        client = Client(client)
    try:
        futures = [client.submit(_run_chunk, fn, c, pure=False) for c in chunks]
        try:
            for future in as_completed(futures):
                yield from future.result()
        finally:
            client.cancel([f for f in futures if not f.done()])
    finally:
        if own:
            client.close()
