"""Run many independent evaluations (simulations, key group analyses) in this process, on local
processes or on a Dask cluster, yielding each result as it completes.

Used by `ddatai.sweep` and `kgm.probabilistic`. Three ways to run, chosen by the caller's
``client`` and ``workers`` arguments:

- ``workers=1`` (and no client): in this process, in order;
- ``workers=N > 1`` (and no client): N local worker processes (`ddatai.workers`, ``spawn``
  start method, so every worker starts its own Taichi runtime once, the first time it needs
  one), each sending every item's result back as it completes;
- a ``dask.distributed.Client``, or a scheduler address such as ``"tcp://host:8786"``: the
  cluster's workers (``pip install ddatai[dask]``).

``workers=None`` lets the caller's cost of one item decide (`default_workers_for`): items that
take milliseconds (a limit-equilibrium sample) run in this process, where starting workers and
shipping every item to them costs more than it saves; items that take seconds (a DDA run) go to
one worker process per CPU.

Work is sent in chunks of several items (one task per chunk) so that a cheap evaluation is not
dominated by the cost of a task.

**Lost workers.** A worker process killed in the middle of an item (the out-of-memory killer, a
crash in a native library) loses that item only: it runs again on another worker, and an item
that was running when its worker died twice is yielded as `ddatai.workers.WorkerLost` in place
of its result while the rest completes (`ddatai.workers`). A Dask cluster runs a task again on
its own when its worker dies (the scheduler's ``allowed-failures``); a chunk that exhausts them
runs again as single items, and a single item that does is yielded as `WorkerLost`. The function and its items must be picklable: a function
defined at the top level of an importable module, or of the script being run (a scene script
loaded by path is run by `ScriptFunction`).

**Scripts.** Worker processes are started with ``spawn``: each imports the script that started
the study again (as ``__mp_main__``) to find the functions defined in it. A script that starts a
study at its top level, outside an ``if __name__ == "__main__":`` block, would start it again in
every worker (Python's `multiprocessing` then breaks the pool). `plan` checks this before any
work (`MainModuleCheck`): with ``workers=None`` such a study runs in this process (and says so
once, with what to add to use the processes); with ``workers > 1`` it stops with one line saying
what to add (`UnguardedMainError`; at an interactive prompt, `InteractiveMainError`).
"""

from __future__ import annotations

import ast
import os
import pickle
import sys
import types
import warnings
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


#: an item's cost for `plan`'s default: "light" (milliseconds: in this process) or "heavy"
#: (seconds: one worker process per CPU)
COSTS = ("light", "heavy")


class UnguardedMainError(SystemExit):
    """A study that needs worker processes was started at the top level of a script without an
    ``if __name__ == "__main__":`` block (or from a prompt, whose functions the workers cannot
    import). Raised before any work; uncaught, Python prints its one-line message and exits
    with status 1 (it is a `SystemExit`: the script cannot go on usefully, and the message is
    the whole story). At an interactive prompt, which a `SystemExit` would close,
    `InteractiveMainError` is raised instead."""


class InteractiveMainError(RuntimeError):
    """`UnguardedMainError`'s message, raised at an interactive prompt (Python's, IPython's, a
    notebook's): the session goes on."""


def _interactive() -> bool:
    return bool(hasattr(sys, "ps1") or sys.flags.interactive or "IPython" in sys.modules)


def default_workers_for(cost: str) -> int:
    """Workers a study uses with ``workers=None``: 1 (this process) for light items, one per
    CPU for heavy ones."""
    if cost not in COSTS:
        raise ValueError(f"cost must be one of {COSTS}, got {cost!r}")
    return 1 if cost == "light" else default_workers()


class _GlobalsRecorder(pickle._Pickler):  # the Python pickler: its save_global can be hooked
    """Pickles an object to nowhere, recording the modules of the functions and classes it
    refers to by name (what a worker process must import)."""

    def __init__(self):
        import io

        super().__init__(io.BytesIO(), protocol=pickle.DEFAULT_PROTOCOL)
        self.modules: dict[str, set] = {}

    def save_global(self, obj, name=None):
        module = getattr(obj, "__module__", None) or "?"
        self.modules.setdefault(module, set()).add(name or getattr(obj, "__qualname__", repr(obj)))
        return super().save_global(obj, name)

    # the dispatch table holds the base class's function for functions: route it here
    dispatch = pickle._Pickler.dispatch.copy()
    dispatch[types.FunctionType] = lambda self, obj: self.save_global(obj)


def main_module_names(fn: Callable) -> list[str]:
    """Names of the functions and classes of the ``__main__`` module that ``fn`` (with what it
    carries: a study's ``build``, a sweep's ``measure``) refers to; a worker process finds them
    only by importing the script again. Raises `pickle.PicklingError` (or what pickling raises)
    for a function that cannot be sent to a worker at all (a lambda, a nested function)."""
    rec = _GlobalsRecorder()
    rec.dump(fn)
    return sorted(rec.modules.get("__main__", ()))


def _is_main_guard(node: ast.AST) -> bool:
    """``if __name__ == "__main__":`` (either order of the comparison)."""
    if not (isinstance(node, ast.If) and isinstance(node.test, ast.Compare) and len(node.test.ops) == 1
            and isinstance(node.test.ops[0], ast.Eq)):
        return False
    sides = [node.test.left, node.test.comparators[0]]
    return (any(isinstance(x, ast.Name) and x.id == "__name__" for x in sides)
            and any(isinstance(x, ast.Constant) and x.value == "__main__" for x in sides))


def _guarded_lines(source: str) -> list[tuple[int, int]]:
    """Line ranges of the top-level ``if __name__ == "__main__":`` blocks of a script."""
    tree = ast.parse(source)
    return [(node.lineno, node.end_lineno or node.lineno) for node in tree.body if _is_main_guard(node)]


@dataclass(frozen=True, kw_only=True)
class MainModuleCheck:
    """Whether worker processes started with ``spawn`` can run ``fn``, seen from the script
    that runs (`check_main_module`)."""

    names: tuple
    """Functions and classes of ``__main__`` that ``fn`` needs."""
    script: Optional[str]
    """The script's path (None: a prompt, a notebook or ``python -c``, which workers cannot
    import)."""
    line: Optional[int]
    """The script's line that started the study, when that line is outside an
    ``if __name__ == "__main__":`` block (None: guarded, or not started from the script's top
    level)."""

    @property
    def ok(self) -> bool:
        return not self.names or (self.script is not None and self.line is None)

    def advice(self, caller: str) -> str:
        """One line: what to change so that worker processes can run the study."""
        what = ", ".join(self.names)
        if self.script is None:
            return (f"{caller}: worker processes cannot import {what}, defined at a prompt or in a notebook: "
                    f"define it in a module or script file, or pass workers=1 to run in this process")
        return (f"{caller}: worker processes import {self.script} again to find {what}, and would start the "
                f"study again from line {self.line}: put the code that starts it under "
                f'`if __name__ == "__main__":` in {self.script}, or pass workers=1 to run in this process')


def check_main_module(fn: Callable) -> MainModuleCheck:
    """Can spawned worker processes run ``fn``? They import the running script again as
    ``__mp_main__`` to find what ``fn`` needs of it; that runs the script's top-level code, so
    the study must not be started from there outside an ``if __name__ == "__main__":`` block."""
    names = tuple(main_module_names(fn))
    if not names:
        return MainModuleCheck(names=(), script=None, line=None)
    main = sys.modules.get("__main__")
    script = getattr(main, "__file__", None)
    if script is None or not os.path.isfile(script):
        return MainModuleCheck(names=names, script=None, line=None)
    # the frame running the script's top-level code, if the study was started from it
    frame, line = sys._getframe(1), None
    while frame is not None:
        if frame.f_code.co_name == "<module>" and frame.f_globals is getattr(main, "__dict__", None):
            line = frame.f_lineno
            break
        frame = frame.f_back
    if line is not None:
        try:
            with open(script, encoding="utf-8") as fh:
                guarded = _guarded_lines(fh.read())
        except (OSError, SyntaxError, UnicodeDecodeError):
            guarded = []
        if any(lo <= line <= hi for lo, hi in guarded):
            line = None
    return MainModuleCheck(names=names, script=script, line=line)


def plan(fn: Callable, *, client=None, workers: Optional[int] = None, cost: str = "heavy",
         caller: str = "study") -> int:
    """The number of local workers a study runs on (1: this process; ignored with a client),
    decided before any work: ``workers`` when given, else by ``cost`` (`default_workers_for`).
    Where worker processes cannot run ``fn`` from the running script (`check_main_module`), an
    explicit ``workers > 1`` raises `UnguardedMainError` and the default runs in this process
    with a `RuntimeWarning` saying what to add."""
    check_execution(client, workers)
    if client is not None:
        return workers or 1
    n = workers if workers is not None else default_workers_for(cost)
    if n == 1:
        return 1
    try:
        check = check_main_module(fn)
    except Exception as exc:  # noqa: BLE001 - a function that cannot be pickled at all
        if workers is not None:
            raise ValueError(f"{caller}: worker processes cannot be sent {fn!r}: {type(exc).__name__}: {exc}; "
                             "define it at the top level of a module, or pass workers=1") from None
        return 1
    if check.ok:
        return n
    if workers is not None:
        if _interactive():
            raise InteractiveMainError(check.advice(caller))
        raise UnguardedMainError(check.advice(caller))
    warnings.warn(check.advice(caller).replace(", or pass workers=1 to run in this process", "") +
                  f" to use {n} worker processes; running in this process", RuntimeWarning, stacklevel=3)
    return 1


def run(fn: Callable, items: Sequence[tuple[int, Any]], *, client=None, workers: Optional[int] = None,
        chunk: Optional[int] = None, split: Optional[Callable] = None,
        max_deaths: int = 2) -> Iterator[tuple[int, Any]]:
    """Evaluate ``fn(item)`` for every ``(index, item)``; yields ``(index, result)`` in
    completion order (any order: callers key results by index). An exception in ``fn`` is
    raised here, naming nothing more than ``fn`` did: callers wrap ``fn`` to name the item.
    ``workers=None`` means one process per CPU here: callers decide it first with `plan`.

    A worker process that dies (killed, crashed) loses only the item it was running: that item
    runs again on another worker (``split(item) -> [(index, part)]`` gives the parts of a
    divisible item, each run alone), and one that was running when its worker died
    ``max_deaths`` times is yielded as `ddatai.workers.WorkerLost` in place of its result
    (`ddatai.workers`; on a Dask cluster, after the cluster's own retries). In this process
    (``workers=1``) there is no worker to lose. `Executor` runs batch after batch on the same
    workers."""
    check_execution(client, workers)
    items = list(items)
    if not items:
        return
    if client is None and (workers == 1 or len(items) == 1):
        for index, item in items:
            yield index, fn(item)
        return
    with Executor(fn, client=client, workers=workers) as executor:
        yield from executor.run(items, chunk=chunk, split=split, max_deaths=max_deaths)


class Executor:
    """Runs ``fn`` on batch after batch of items with the same workers (`run`'s three ways: in
    this process, on local worker processes started once, or on a Dask cluster, connected
    once): a study that chooses each batch from the results of the one before (subset
    simulation's chains, `kgm.studies.reliability`) starts no worker per batch. A context
    manager; `close` stops the workers."""

    def __init__(self, fn: Callable, *, client=None, workers: Optional[int] = None):
        check_execution(client, workers)
        self.fn = fn
        self.n_workers = 1 if client is None and workers == 1 else (workers or default_workers())
        self._client, self._own, self._pool = client, False, None

    def __enter__(self) -> "Executor":
        return self

    def __exit__(self, *exc) -> None:
        self.close(kill=exc[0] is not None)

    def close(self, *, kill: bool = False) -> None:
        if self._pool is not None:
            self._pool.close(kill=kill)
            self._pool = None
        if self._own:
            self._client.close()
            self._own, self._client = False, None

    def run(self, items: Sequence[tuple[int, Any]], *, chunk: Optional[int] = None, split: Optional[Callable] = None,
            max_deaths: int = 2) -> Iterator[tuple[int, Any]]:
        """`run` of these items on this executor's workers."""
        items = list(items)
        if not items:
            return
        if self._client is None and self.n_workers == 1:
            for index, item in items:
                yield index, self.fn(item)
            return
        # about 4 chunks per worker keeps them all busy to the end; at most 64 items a chunk (local
        # workers send each item's result back as it completes; a Dask task returns its chunk whole)
        size = chunk or max(1, min(64, len(items) // (4 * self.n_workers) or 1))
        chunks = _chunks(items, size)
        if self._client is None:
            from .workers import ProcessPool

            if self._pool is None:
                self._pool = ProcessPool(self.fn, self.n_workers)
            yield from self._pool.run(chunks, split=split, max_deaths=max_deaths)
            return
        if isinstance(self._client, str):
            try:
                from dask.distributed import Client
            except ImportError as exc:  # pragma: no cover - depends on the environment
                raise ImportError("running on a Dask cluster needs dask.distributed: pip install ddatai[dask]") \
                    from exc
            self._client, self._own = Client(self._client), True
        yield from _run_dask(self.fn, chunks, self._client, split, max_deaths)


def _run_dask(fn, chunks, client, split, max_deaths: int) -> Iterator[tuple[int, Any]]:
    try:
        from dask.distributed import as_completed
        from distributed.scheduler import KilledWorker
    except ImportError as exc:  # pragma: no cover - depends on the environment
        raise ImportError("running on a Dask cluster needs dask.distributed: pip install ddatai[dask]") from exc
    from .workers import WorkerLost

    # the scheduler runs a task again when its worker dies, up to its 'allowed-failures';
    # then the task errs with KilledWorker: a chunk of several items runs again as single
    # items (the one that kills its workers takes none of the others with it again), a
    # divisible item as its parts, and a single item once more; a single item that errs so
    # twice is given up (WorkerLost). A worker's death charges the task it was running and
    # any queued on it (the scheduler's 'worker-saturation'), hence the second chance.
    chunk_of = {client.submit(_run_chunk, fn, c, pure=False): c for c in chunks}
    killed: dict = {}  # index -> KilledWorker errors of the item alone
    pending = as_completed(list(chunk_of))
    try:
        for future in pending:
            c = chunk_of.pop(future)
            try:
                results = future.result()
            except KilledWorker as exc:
                parts = [[it] for it in c] if len(c) > 1 else \
                    [[p] for p in (split(c[0][1]) if split is not None else None) or ()]
                if len(parts) < 2:
                    index = c[0][0]
                    killed[index] = killed.get(index, 0) + 1
                    if killed[index] >= max_deaths:
                        yield index, WorkerLost(deaths=killed[index] * (int(exc.allowed_failures) + 1))
                        continue
                    parts = [c]
                for part in parts:
                    f = client.submit(_run_chunk, fn, part, pure=False)
                    chunk_of[f] = part
                    pending.add(f)
                continue
            yield from results
    finally:
        client.cancel([f for f in chunk_of if not f.done()])
