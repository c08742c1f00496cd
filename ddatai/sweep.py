"""Parameter studies: many simulations of one scene script, one row of results per run, on local
processes or a Dask cluster (`ddatai.parallel`).

>>> rows = dd.sweep(build, {"friction": [20, 25, 30], "young": [1e9, 5e9]}, duration=1.0)  # doctest: +SKIP
>>> rows["friction"], rows["max_displacement"], rows["finished"]                          # doctest: +SKIP

``grid_or_samples`` is either a grid (name -> list of values: every combination is run, the
last name varying fastest) or a sequence of samples (dicts of keyword arguments). Each run
builds its scene with ``build(**values)`` (a ``Scene`` or ``(Scene, Params)``), simulates it
for ``duration`` seconds and measures it: by default the largest displacement of any free
block's centroid, the largest speed at the end, the steps, Δt cuts and open–close iterations,
the simulated time reached and whether it finished (a run that diverges is a row with
``finished = False`` and its cause, not an exception); ``measure(results) -> {name: number}``
adds the caller's own columns. A run whose worker process dies (killed by the out-of-memory
killer, a crash in a native library) runs again on another worker; one that kills its worker
twice is a row with ``finished = False`` and a ``cause`` that says so (`ddatai.workers`), and
the other runs complete.
"""

from __future__ import annotations

import functools
import itertools
import time
from dataclasses import dataclass
from typing import Callable, Mapping, Optional, Sequence

import numpy as np

#: columns every row has, after the run's parameters
BASE_COLUMNS = ("finished", "cause", "time_reached", "steps", "dt_cuts", "oc_iterations",
                "max_displacement", "final_speed", "wall_time")


@dataclass(frozen=True)
class _Run:
    build: Callable
    duration: float
    measure: Optional[Callable]


def _run_one(job: _Run, values: dict) -> dict:
    from .results import SimulationError
    from .run import simulate

    from .io.scenefile import build_scene

    t0 = time.perf_counter()
    scene, params = build_scene(job.build, **values)
    finished, cause = True, ""
    try:
        res = simulate(scene, params, duration=job.duration, record_every=10 ** 9)
    except SimulationError as err:
        finished, cause, res = False, err.cause, err.results
    row = dict(finished=finished, cause=cause)
    if res is None or len(res.time) == 0:
        row.update(time_reached=0.0, steps=0, dt_cuts=0, oc_iterations=0, max_displacement=np.nan,
                   final_speed=np.nan)
    else:
        free = ~res.block_fixed
        moved = np.hypot(*(res.centroid[-1] - res.centroid[0]).T)[free]
        speed = np.hypot(*res.velocity[-1].T)[free]
        row.update(time_reached=float(res.time[-1]), steps=int(len(res.steps)),
                   dt_cuts=int(res.steps["dt_cuts"].sum()) if len(res.steps) else 0,
                   oc_iterations=int(res.steps["oc_iterations"].sum()) if len(res.steps) else 0,
                   max_displacement=float(moved.max(initial=0.0)), final_speed=float(speed.max(initial=0.0)))
        if job.measure is not None:
            extra = job.measure(res)
            if not isinstance(extra, Mapping):
                raise ValueError(f"measure(results) must return a mapping of column names to numbers, "
                                 f"got {type(extra).__name__}")
            clash = set(extra) & (set(BASE_COLUMNS) | set(values))
            if clash:
                raise ValueError(f"measure(results) returned reserved column names {sorted(clash)}")
            row.update({k: float(v) for k, v in extra.items()})
    row["wall_time"] = time.perf_counter() - t0
    return row


def _expand(grid_or_samples) -> list[dict]:
    if isinstance(grid_or_samples, Mapping):
        names = list(grid_or_samples)
        for k in names:
            v = grid_or_samples[k]
            if isinstance(v, (str, bytes)) or not isinstance(v, (Sequence, np.ndarray)) or len(v) == 0:
                raise ValueError(f"sweep grid: {k!r} must be a non-empty list of values, got {v!r}")
        return [dict(zip(names, combo)) for combo in itertools.product(*(list(grid_or_samples[k]) for k in names))]
    samples = list(grid_or_samples)
    if not samples or not all(isinstance(s, Mapping) for s in samples):
        raise ValueError("sweep: give a grid {name: [values]} or a non-empty list of dicts of build() arguments")
    return [dict(s) for s in samples]


def sweep(build, grid_or_samples, *, duration: float, measure: Optional[Callable] = None, client=None,
          workers: Optional[int] = None, progress: Optional[Callable] = None) -> np.ndarray:
    """Run ``build(**values)`` for every grid point or sample and simulate each for ``duration``
    seconds (module docstring). Returns one row per run, in input order, as a NumPy structured
    array: the run's parameters (numbers), then ``BASE_COLUMNS`` and ``measure``'s columns.

    ``build`` is a function at the top level of an importable module or the path of a scene
    script (its ``build``); ``client``/``workers`` as in `kgm.probabilistic` (None: one local
    worker process per CPU, since each run is a simulation of seconds; 1: in this process; a
    Dask client or scheduler address: the cluster); ``progress(done, total)`` is called after
    each run. A script that calls ``sweep`` at its top level without an
    ``if __name__ == "__main__":`` block runs in this process by default (with a warning saying
    what to add) and stops before any work, with one line saying what to add, when it asks
    for worker processes (`ddatai.parallel.plan`)."""
    from .parallel import ScriptFunction, check_execution, plan, run
    from .workers import WorkerLost

    if isinstance(build, str) or hasattr(build, "__fspath__"):
        build = ScriptFunction(str(build))
    if not callable(build):
        raise ValueError(f"build must be a function or the path of a scene script, got {type(build).__name__}")
    if not (isinstance(duration, (int, float)) and np.isfinite(duration) and duration > 0):
        raise ValueError(f"sweep: duration must be a finite number > 0 s, got {duration!r}")
    check_execution(client, workers)
    runs = _expand(grid_or_samples)
    rows: dict = {}
    job = _Run(build=build, duration=float(duration), measure=measure)
    fn = functools.partial(_run_one, job)
    workers = plan(fn, client=client, workers=workers, cost="heavy", caller="ddatai.sweep")
    for index, row in run(fn, list(enumerate(runs)), client=client,
                          workers=workers, chunk=1):
        if isinstance(row, WorkerLost):
            # a run that killed its worker process twice: a row saying so, the others go on
            row = dict(finished=False, cause=f"lost: {row}", time_reached=np.nan, steps=0, dt_cuts=0,
                       oc_iterations=0, max_displacement=np.nan, final_speed=np.nan, wall_time=np.nan)
        rows[index] = row
        if progress is not None:
            progress(len(rows), len(runs))
    return _to_table(runs, [rows[i] for i in range(len(runs))])


def _to_table(runs: list[dict], rows: list[dict]) -> np.ndarray:
    params = list(runs[0])
    extra = list(dict.fromkeys(k for r in rows for k in r if k not in BASE_COLUMNS))
    width = max([len(r["cause"]) for r in rows] + [1])

    def kind(values):
        if all(isinstance(v, (bool, np.bool_)) for v in values):
            return bool
        if all(isinstance(v, (int, np.integer)) and not isinstance(v, bool) for v in values):
            return np.int64
        if all(isinstance(v, (int, float, np.integer, np.floating)) for v in values):
            return np.float64
        return f"U{max(len(str(v)) for v in values)}"

    dtype = [(k, kind([r[k] for r in runs])) for k in params] + \
        [("finished", bool), ("cause", f"U{width}"), ("time_reached", np.float64), ("steps", np.int64),
         ("dt_cuts", np.int64), ("oc_iterations", np.int64), ("max_displacement", np.float64),
         ("final_speed", np.float64), ("wall_time", np.float64)] + [(k, np.float64) for k in extra]
    table = np.zeros(len(rows), dtype=dtype)
    for j, (values, row) in enumerate(zip(runs, rows)):
        for k in params:
            table[k][j] = str(values[k]) if table.dtype[k].kind == "U" else values[k]
        for k in BASE_COLUMNS:
            table[k][j] = row[k]
        for k in extra:
            table[k][j] = row.get(k, np.nan)
    return table
