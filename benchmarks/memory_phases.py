"""Where a large step's memory and time go: peak resident memory (VmHWM / VmRSS sampled) and
NumPy's traced allocations by phase, MKL PARDISO's own memory report, and the time of each phase.

    python benchmarks/memory_phases.py [--family grid] [--size 102400] [--steps 4] [--warmup 1]
                                       [--trace] [--out FILE.json]

One (family, size) of `benchmarks/scaling.py`'s families, ntdda's protocol (from rest under sudden
gravity), in this process. A sampling thread reads ``/proc/self/status`` every 10 ms and keeps,
for each phase (the innermost wrapped call running), the largest VmRSS seen; each wrapped call
also records VmHWM before and after it, so that the phase in which the process's high-water mark
rose is named. ``--trace`` adds `tracemalloc` (NumPy's arrays are traced): the traced peak by
phase, and the largest live allocations (by source line) when the solver is entered and when
the process's peak is reached in it. PARDISO's report: MKL's iparm(15) (peak memory of the
symbolic analysis), iparm(16) (permanent memory of the analysis) and iparm(17) (memory of the
numerical factorisation and solve), in KB, after each analysis and factorisation.
Linux only (``/proc``). Prints a table and writes a JSON record.
"""

from __future__ import annotations

import argparse
import collections
import functools
import hashlib
import json
import sys
import threading
import time
import tracemalloc
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from scaling_scenes import SCENES, parse_params  # noqa: E402

_STACK: list = ["setup"]
_RSS_MAX: dict = collections.defaultdict(int)     # phase -> largest VmRSS sampled [kB]
_HWM_RISE: dict = collections.defaultdict(int)    # phase -> kB the high-water mark rose within it
_TIME: dict = collections.defaultdict(float)      # phase -> exclusive wall seconds
_CPU: dict = collections.defaultdict(float)       # phase -> inclusive CPU seconds
_CALLS: dict = collections.defaultdict(int)
_TRACED_PEAK: dict = collections.defaultdict(int)  # phase -> tracemalloc peak within it [B]
_SNAPSHOTS: dict = {}
_PARDISO: list = []


def status() -> dict:
    out = {}
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith(("VmRSS", "VmHWM")):
                k, v = line.split(":")
                out[k] = int(v.split()[0])
    return out


def sampler(stop: threading.Event) -> None:
    while not stop.is_set():
        rss = status()["VmRSS"]
        phase = _STACK[-1]
        if rss > _RSS_MAX[phase]:
            _RSS_MAX[phase] = rss
        stop.wait(0.01)


def top_lines(limit: int = 15) -> list:
    snap = tracemalloc.take_snapshot().filter_traces([tracemalloc.Filter(False, tracemalloc.__file__)])
    stats = snap.statistics("lineno")
    return [(f"{s.traceback[0].filename.split('/ddatai/')[-1]}:{s.traceback[0].lineno}", round(s.size / 2**20, 1),
             s.count) for s in stats[:limit]]


def _close(label: str, parent: str, t0: float, c0: float, hwm0: int) -> float:
    """Leave phase ``label``: its wall and CPU time (taken from its parent's), calls and rise
    of the high-water mark; returns its wall time."""
    _STACK.pop()
    dt = time.perf_counter() - t0
    _TIME[label] += dt
    _TIME[parent] -= dt
    _CPU[label] += time.process_time() - c0
    _CALLS[label] += 1
    _HWM_RISE[label] += status()["VmHWM"] - hwm0
    return dt


def wrap(owner, name: str, label: str, snapshot: bool = False) -> None:
    fn = getattr(owner, name)
    if getattr(fn, "_wrapped", False):
        return

    @functools.wraps(fn)
    def inner(*args, **kwargs):
        parent = _STACK[-1]
        hwm0 = status()["VmHWM"]
        t0, c0 = time.perf_counter(), time.process_time()
        if tracemalloc.is_tracing():
            if snapshot and label + " (entry)" not in _SNAPSHOTS:
                _SNAPSHOTS[label + " (entry)"] = top_lines()
            _, before_peak = tracemalloc.get_traced_memory()
            tracemalloc.reset_peak()
        _STACK.append(label)
        try:
            return fn(*args, **kwargs)
        finally:
            _close(label, parent, t0, c0, hwm0)
            if tracemalloc.is_tracing():
                _, peak = tracemalloc.get_traced_memory()
                _TRACED_PEAK[label] = max(_TRACED_PEAK[label], peak)
                # the parent's peak includes this child's
                tracemalloc.reset_peak()
                _TRACED_PEAK[parent] = max(_TRACED_PEAK[parent], peak, before_peak)
    inner._wrapped = True
    setattr(owner, name, inner)


def instrument() -> None:
    import ddatai.assembly as assembly
    import ddatai.contacts as contacts
    import ddatai.open_close as oc
    import ddatai.pardiso as pardiso
    import ddatai.solver as solver
    import ddatai.step as step
    import ddatai.kinematics as kinematics

    wrap(step.Stepper, "find_contacts", "contacts")
    wrap(step.Stepper, "detect", "contacts.detect")
    wrap(contacts.Contacts, "start", "contacts.start")
    wrap(assembly.BlockPattern, "build", "contacts.pattern")
    wrap(step, "contact_vectors", "contacts.vectors")
    wrap(step, "assemble_blocks", "assembly.blocks")
    wrap(step, "approach_bound", "impacts.bound")
    wrap(oc, "assemble_contacts", "assembly.contacts")
    wrap(oc, "second_order", "assembly.second_order")
    wrap(oc, "midstep_lever_arms", "assembly.lever_arms")
    wrap(oc, "contact_law", "judge.contact_law")
    wrap(oc, "violations", "judge.violations")
    wrap(oc, "judge", "judge.judge")
    wrap(oc, "line_search", "judge.line_search")
    wrap(solver.SparseSolver, "solve", "solve", snapshot=True)
    wrap(solver.SparseSolver, "_solve_reusing", "solve.reuse")
    wrap(solver.SparseSolver, "_solve_krylov", "solve.krylov")
    wrap(solver.SparseSolver, "_solve_pardiso", "solve.pardiso")
    wrap(step.Stepper, "accept", "accept")
    wrap(step, "update", "update")
    wrap(step.Stepper, "energy_balance", "energy")
    wrap(step.Stepper, "impact_projection", "impacts.projection")

    call = pardiso._Pardiso.call

    def pardiso_call(self, phase, data, indptr, indices, rhs):
        label = f"pardiso.phase{phase}"
        parent = _STACK[-1]
        hwm0 = status()["VmHWM"]
        t0, c0 = time.perf_counter(), time.process_time()
        _STACK.append(label)
        if phase in (11, 12, 13, 22, 23):
            self.iparm[17] = -1  # ask MKL for the factor's non-zeros (a report; the factor is the same)
        try:
            return call(self, phase, data, indptr, indices, rhs)
        finally:
            dt = _close(label, parent, t0, c0, hwm0)
            if phase in (11, 12, 13, 22, 23):
                ip = self.iparm
                _PARDISO.append(dict(phase=phase, mtype=self.mtype, n=len(indptr) - 1, nnz_upper=int(len(indices)),
                                     peak_symbolic_kb=int(ip[14]), permanent_kb=int(ip[15]),
                                     factor_solve_kb=int(ip[16]), factor_nnz=int(ip[17]), mflops=int(ip[18]),
                                     wall_s=dt, cpu_s=time.process_time() - c0))

    pardiso._Pardiso.call = pardiso_call


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--family", default="grid")
    ap.add_argument("--size", type=int, default=102400)
    ap.add_argument("--steps", type=int, default=4)
    ap.add_argument("--warmup", type=int, default=1)
    ap.add_argument("--params", default="")
    ap.add_argument("--trace", action="store_true")
    ap.add_argument("--out", type=Path, default=None)
    ap.add_argument("--save", type=Path, default=None, help="the last state's vertices (.npy)")
    a = ap.parse_args()
    stop = threading.Event()
    thread = threading.Thread(target=sampler, args=(stop,), daemon=True)
    thread.start()
    if a.trace:
        tracemalloc.start()
    import dataclasses

    import ddatai as dd
    from ddatai.step import Stepper

    instrument()
    t0 = time.perf_counter()
    _STACK.append("build")
    scene, params = SCENES[a.family](a.size)
    params = dataclasses.replace(params, **parse_params(a.params))
    model = dd.build_model(scene, params)
    stepper = Stepper(model)
    state = model.initial_state()
    _STACK.pop()
    _TIME["build"] += time.perf_counter() - t0
    _TIME["setup"] -= time.perf_counter() - t0
    hwm_build = status()["VmHWM"]
    rows = []
    for k in range(a.warmup + a.steps):
        label = "warmup step" if k < a.warmup else "step"
        _STACK.append(label)
        t, c = time.perf_counter(), time.process_time()
        before = stepper.solver.factorisations
        state, rec = stepper.step(state)
        _STACK.pop()
        rows.append(dict(step=k + 1, wall_s=time.perf_counter() - t, cpu_s=time.process_time() - c,
                         solves=int(rec.oc_total), factorisations=stepper.solver.factorisations - before,
                         reused=stepper.solver.reused, krylov=stepper.solver.krylov, contacts=int(rec.contacts),
                         hwm_mb=status()["VmHWM"] / 1024))
        print(json.dumps(rows[-1]), flush=True)
    if a.save:
        np.save(a.save, state.vertex_xy)
    stop.set()
    thread.join()
    total = {k: v for k, v in _TIME.items()}
    out = dict(family=a.family, size=a.size, blocks=int(model.n_free), params=a.params, trace=a.trace,
               hwm_after_build_mb=hwm_build / 1024, hwm_mb=status()["VmHWM"] / 1024, steps=rows,
               rss_max_mb={k: v / 1024 for k, v in sorted(_RSS_MAX.items(), key=lambda kv: -kv[1])},
               hwm_rise_mb={k: v / 1024 for k, v in sorted(_HWM_RISE.items(), key=lambda kv: -kv[1]) if v},
               traced_peak_mb={k: v / 2**20 for k, v in sorted(_TRACED_PEAK.items(), key=lambda kv: -kv[1])},
               wall_exclusive_s={k: v for k, v in sorted(total.items(), key=lambda kv: -kv[1])},
               cpu_inclusive_s=dict(_CPU), calls=dict(_CALLS), pardiso=_PARDISO, snapshots=_SNAPSHOTS,
               nnz=int(stepper.pattern.nnz), n=int(6 * stepper.pattern.n_rows), ddatai=dd.__file__,
               # the outcome, to compare two checkouts bit for bit
               vertex_sha1=hashlib.sha1(state.vertex_xy.tobytes()).hexdigest(),
               velocity_sha1=hashlib.sha1(state.block_velocity.tobytes()).hexdigest())
    text = json.dumps(out, indent=1)
    if a.out:
        a.out.write_text(text)
    print(text)


if __name__ == "__main__":
    main()
