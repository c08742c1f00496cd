"""Example II's DDA-judged study on two checkouts of the project, paired: samples a second.

    python benchmarks/study_ab.py --a /path/to/checkout-A --b /path/to/checkout-B [--samples 400] [--repeats 2]
    python benchmarks/study_ab.py --a ... --b ... --evaluate [--repeats 3]

Each run is a fresh process (``benchmarks/small_models.py``'s study: friction N(22°, 2°),
cohesion N(20 kPa, 5 kPa) correlated −0.3, seed 1, group {0, 1} of ``scenes/example_2.py``,
Δt 1.3 ms, p = 1·E, 2 worker processes, the fused engine), A and B alternating ``--repeats``
times, threads pinned in every process (BLAS and Taichi one thread each): the wall time of
``kgm.probabilistic`` from its call to its table, the workers' start and their load of the
fused kernel (Taichi's offline cache) included, and the CPU time (user + system) of the process
and all its workers (the machine is shared: the wall time follows its load). Prints each run,
the medians, and whether the two checkouts' tables give every sample the same verdict. Run ``python -m ddatai.fused`` in
each checkout first (the kernel compiled and cached); ``--a-cache``/``--b-cache`` give each side
its own Taichi offline cache where their fused kernels differ.

``--evaluate``: instead, ``kgm.evaluate(Example I, [0, 1], "dda")`` (the fused engine) three
times in each fresh process, A and B alternating: the first call's wall time (the kernel's load
included), and the best of the other two, warm, in wall and in CPU seconds (the machine is
shared), with FS and φc.
"""

from __future__ import annotations

import argparse
import os
import resource
import statistics
import subprocess
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from small_models import PINNED, STUDY  # noqa: E402

#: `kgm.evaluate(Example I, [0, 1], "dda")` on the fused engine, three times in one process: the
#: first call's wall time (the kernel's load included), then the wall and CPU times of the others
EVALUATE = """
import dataclasses, sys, time
sys.path.insert(0, {root!r})
import kgm
from scenes import example_1
scene, params = example_1.build()
params = dataclasses.replace(params, kernels="fused")
walls, cpus = [], []
for _ in range(3):
    t, c = time.perf_counter(), time.process_time()
    row = kgm.evaluate(scene, [0, 1], "dda", params=params)
    walls.append(time.perf_counter() - t)
    cpus.append(time.process_time() - c)
print(walls[0], min(walls[1:]), min(cpus[1:]), row.fs, row.critical_friction, len(row.dda.runs))
"""


def _env(a, name: str) -> dict:
    """The environment of side ``name``'s process: threads pinned, its kernel cache."""
    cache = a.a_cache if name == "A" else a.b_cache
    return {**os.environ, **PINNED, **({"TI_OFFLINE_CACHE_FILE_PATH": cache} if cache else {})}


def evaluate(a) -> None:
    walls = {"A": [], "B": []}
    print(f"# kgm.evaluate(Example I, [0, 1], 'dda'), fused; load {os.getloadavg()[0]:.1f}", flush=True)
    for rep in range(a.repeats):
        for name, root in (("A", a.a), ("B", a.b)):
            proc = subprocess.run([sys.executable, "-c", EVALUATE.format(root=str(Path(root).resolve()))],
                                  capture_output=True, text=True, cwd=root, env=_env(a, name), timeout=3600)
            if proc.returncode != 0:
                raise SystemExit(proc.stderr[-3000:])
            first, second, cpu, fs, phi, runs = proc.stdout.strip().splitlines()[-1].split()
            walls[name].append(float(cpu))
            print(f"run {rep + 1} {name}: first {float(first):.2f} s, warm {float(second):.3f} s wall, "
                  f"{float(cpu):.3f} s "
                  f"CPU; FS {float(fs):.4f}, "
                  f"φc {float(phi):.3f}°, {runs} runs; load {os.getloadavg()[0]:.1f}", flush=True)
    for name, root in (("A", a.a), ("B", a.b)):
        print(f"{name} ({root}): warm, CPU, median {statistics.median(walls[name]):.3f} s")
    print(f"B/A (CPU) pair by pair: {', '.join(f'{b / x:.2f}' for x, b in zip(walls['A'], walls['B']))}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--a", required=True, help="checkout A (e.g. this branch)")
    ap.add_argument("--b", required=True, help="checkout B (e.g. main)")
    ap.add_argument("--samples", type=int, default=400)
    ap.add_argument("--repeats", type=int, default=2)
    ap.add_argument("--evaluate", action="store_true", help="kgm.evaluate of Example I instead of the study")
    ap.add_argument("--a-cache", default="", help="Taichi's offline cache for A (TI_OFFLINE_CACHE_FILE_PATH; "
                    "default: the environment's), where A's fused kernel differs from B's")
    ap.add_argument("--b-cache", default="", help="the same for B")
    a = ap.parse_args()
    if a.evaluate:
        evaluate(a)
        return
    walls = {"A": [], "B": []}
    cpus = {"A": [], "B": []}
    tables = {}
    print(f"# Example II DDA-judged study, {a.samples} samples, 2 workers; load {os.getloadavg()[0]:.1f}", flush=True)
    for rep in range(a.repeats):
        for name, root in (("A", a.a), ("B", a.b)):
            out = f"/tmp/ddatai_study_ab_{os.getpid()}_{name}.npy"  # other runs of this script beside
            code = STUDY.format(root=str(Path(root).resolve()), script=f"{Path(root).resolve()}/scenes/example_2.py",
                                kernels="fused", n=a.samples, out=out)
            before = resource.getrusage(resource.RUSAGE_CHILDREN)
            proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=root,
                                  env=_env(a, name), timeout=3600)
            after = resource.getrusage(resource.RUSAGE_CHILDREN)
            if proc.returncode != 0:
                raise SystemExit(proc.stderr[-3000:])
            wall, pf = proc.stdout.strip().splitlines()[-1].split()
            cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
            walls[name].append(float(wall))
            cpus[name].append(cpu)
            tables[name] = np.load(out)
            print(f"run {rep + 1} {name}: {float(wall):.1f} s ({a.samples / float(wall):.1f} samples/s), "
                  f"CPU {cpu:.1f} s (the process and its workers, user + system), P_f {pf}, "
                  f"load {os.getloadavg()[0]:.1f}", flush=True)
    for name, root in (("A", a.a), ("B", a.b)):
        w = statistics.median(walls[name])
        print(f"{name} ({root}): median {w:.1f} s, {a.samples / w:.1f} samples/s; "
              f"CPU median {statistics.median(cpus[name]):.1f} s")
    print(f"B/A (CPU) pair by pair: {', '.join(f'{b / x:.2f}' for x, b in zip(cpus['A'], cpus['B']))}")
    ratios = [b / x for x, b in zip(walls["A"], walls["B"])]
    print(f"B/A pair by pair: {', '.join(f'{r:.2f}' for r in ratios)}; "
          f"the same verdicts sample by sample: {bool(np.array_equal(tables['A'], tables['B']))}")


if __name__ == "__main__":
    main()
