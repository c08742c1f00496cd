"""What a fresh process pays Taichi before a large model's start does any work: ``import
taichi``, ``ti.init`` (`ddatai.backend.ensure`), and each kernel's first call split into its
parts, against the same kernel's warm calls.

Taichi 1.7 prepares a kernel at its first call in three parts, every process:
``materialize`` (Python: parse the kernel's source, transform its AST with every ``@ti.func``
inlined at each call site, build the frontend IR), ``compile`` (C++: hash the IR for the
offline-cache key, load the cached LLVM module or compile it, JIT it to machine code) and the
launch itself. The script wraps ``Kernel.materialize`` and ``Kernel.launch_kernel`` (the
compile is timed by asking ``prog.compile_kernel`` once before the first launch; the launch's
own compile then hits the in-memory cache); nothing in the library changes.

    OMP_NUM_THREADS=1 ... TI_OFFLINE_CACHE_FILE_PATH=/tmp/coldload_ticache \\
      PYTHONPATH=$PWD python benchmarks/cold_start.py grid 1600 [--steps 1] [--json]

CPU time (``time.process_time``) throughout; the offline cache's files are counted before and
after, so a run that compiled (a miss) says so.
"""

from __future__ import annotations

import json
import os
import sys
import time
from collections import defaultdict
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))


def _cache_files() -> int:
    path = os.environ.get("TI_OFFLINE_CACHE_FILE_PATH", os.path.expanduser("~/.cache/taichi"))
    return sum(len(files) for _, _, files in os.walk(path)) if os.path.isdir(path) else 0


def main():
    t_process = time.process_time()
    w_process = time.perf_counter()
    family, n = sys.argv[1], int(sys.argv[2])
    steps = int(sys.argv[sys.argv.index("--steps") + 1]) if "--steps" in sys.argv else 1
    files_before = _cache_files()
    t = time.process_time()
    import ddatai as dd
    import scaling_scenes
    import_dd = time.process_time() - t
    t = time.process_time()
    import taichi as ti
    from taichi.lang import impl, kernel_impl
    import_ti = time.process_time() - t
    t = time.process_time()
    from ddatai import backend
    backend.ensure("cpu")
    init = time.process_time() - t
    t = time.process_time()
    import ddatai.kernels  # noqa: F401  (the kernels' modules: decorators only, nothing compiled)
    import_kernels = time.process_time() - t

    parts = defaultdict(lambda: defaultdict(float))  # kernel -> part -> CPU s
    calls = defaultdict(list)  # kernel -> CPU s of each launch (first includes nothing compiled: see below)
    compiled = set()
    materialize, launch = kernel_impl.Kernel.materialize, kernel_impl.Kernel.launch_kernel

    def timed_materialize(self, key=None, args=None, arg_features=None):
        fresh = key is not None and key not in self.compiled_kernels
        t0 = time.process_time()
        out = materialize(self, key=key, args=args, arg_features=arg_features)
        if fresh:
            parts[self.func.__name__]["materialize"] += time.process_time() - t0
            parts[self.func.__name__]["instances"] += 1
        return out

    def timed_launch(self, t_kernel, *args):
        name = self.func.__name__
        if id(t_kernel) not in compiled:
            compiled.add(id(t_kernel))
            prog = impl.get_runtime().prog
            t0 = time.process_time()
            prog.compile_kernel(prog.config(), prog.get_device_caps(), t_kernel)
            parts[name]["compile"] += time.process_time() - t0
        t0 = time.process_time()
        out = launch(self, t_kernel, *args)
        calls[name].append(time.process_time() - t0)
        return out

    kernel_impl.Kernel.materialize, kernel_impl.Kernel.launch_kernel = timed_materialize, timed_launch
    scene, params = getattr(scaling_scenes, f"{family}_scene")(n)
    t = time.process_time()
    w = time.perf_counter()
    dd.simulate(scene, params, steps=steps)
    run_cpu, run_wall = time.process_time() - t, time.perf_counter() - w
    rows = []
    for name in sorted(calls, key=lambda k: -(parts[k]["materialize"] + parts[k]["compile"] + calls[k][0])):
        c = calls[name]
        warm = sorted(c[1:])[len(c[1:]) // 2] if len(c) > 1 else float("nan")
        rows.append(dict(kernel=name, instances=int(parts[name]["instances"]), calls=len(c),
                         materialize=parts[name]["materialize"], compile=parts[name]["compile"],
                         first_launch=c[0], warm_launch=warm))
    out = dict(family=family, size=n, steps=steps, import_ddatai=import_dd, import_taichi=import_ti, ti_init=init,
               import_kernels=import_kernels, run_cpu=run_cpu, run_wall=run_wall,
               process_cpu=time.process_time() - t_process, process_wall=time.perf_counter() - w_process,
               cache_files_before=files_before, cache_files_after=_cache_files(), kernels=rows,
               taichi=".".join(map(str, ti.__version__)))
    if "--json" in sys.argv:
        print(json.dumps(out))
        return
    print(f"{family} {n}, {steps} step(s): import ddatai {import_dd:.3f} s, import taichi {import_ti:.3f} s, "
          f"ti.init {init:.3f} s, kernels' modules {import_kernels:.3f} s; run {run_cpu:.2f} s CPU "
          f"({run_wall:.2f} s wall); offline cache files {files_before} -> {out['cache_files_after']}")
    print("| kernel | instances | calls | materialize ms | compile ms | first launch ms | warm launch ms (median) |")
    print("|---|---|---|---|---|---|---|")
    for r in rows:
        print(f"| {r['kernel']} | {r['instances']} | {r['calls']} | {1e3 * r['materialize']:.1f} | "
              f"{1e3 * r['compile']:.1f} | {1e3 * r['first_launch']:.2f} | {1e3 * r['warm_launch']:.2f} |")
    tot_m = sum(r["materialize"] for r in rows)
    tot_c = sum(r["compile"] for r in rows)
    print(f"total: materialize {tot_m:.3f} s, compile {tot_c:.3f} s over {len(rows)} kernels")


if __name__ == "__main__":
    main()
