"""What a fresh process pays to take the fused kernel from Taichi's offline cache, phase by phase.

    python benchmarks/fused_load.py [--cache DIR] [--repeats 5] [--init KEY=VALUE ...]
                                    [--against OTHER_CHECKOUT --against-cache DIR]

Each repeat is a fresh process, threads pinned (one Taichi thread, one BLAS thread), that runs
`ddatai.fused.warm.warm` twice and times (wall and CPU): the import of ddatai, `ti.init`
(`ddatai.backend.ensure`), each Taichi kernel's Python-to-IR transform (``Kernel.materialize``),
its compile or cache load (``Program.compile_kernel``: the offline cache's key and hit, and for
the LLVM backends the machine code made of the cached module) and its launch, then the whole
second `warm`. ``--init KEY=VALUE`` adds options to ``ti.init`` (through `ddatai.backend`'s
``_INIT_OPTIONS``, for experiments; such an option may change the cache key and compile afresh).
Prints one JSON line a process and the medians. ``--against``: each repeat runs the other
checkout (A, with its own warm cache ``--against-cache``) then this one (B), in fresh processes,
and prints both sides' medians, the B/A ratios of the paired first launches and process totals
(CPU), and the size of the largest file in each cache (the ``run`` kernel's LLVM module).
"""

import argparse
import json
import os
import statistics
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PINNED = {"OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1", "TI_CPU_MAX_NUM_THREADS": "1"}

PROBE = r"""
import json, sys, time
T0 = (time.perf_counter(), time.process_time())
def now():
    return (time.perf_counter(), time.process_time())
def since(t):
    w, c = now()
    return (w - t[0], c - t[1])
sys.path.insert(0, {root!r})
t = now(); import ddatai, ddatai.fused.engine, ddatai.fused.warm; imp = since(t)
from ddatai import backend
opts = json.loads({opts!r})
if opts:
    import taichi as ti
    orig = ti.init
    def init(*a, **k):
        k.update(opts)
        return orig(*a, **k)
    ti.init = init
t = now(); backend.ensure("cpu"); ini = since(t)
import taichi as ti
from taichi.lang import impl, kernel_impl
phases = []
names = {{}}
orig_mat = kernel_impl.Kernel.materialize
def materialize(self, *a, **k):
    t = now(); r = orig_mat(self, *a, **k); phases.append(("ast", self.func.__name__) + since(t))
    for v in self.compiled_kernels.values():
        names[id(v)] = self.func.__name__
    return r
kernel_impl.Kernel.materialize = materialize
class Prog:
    def __init__(self, prog): self._p = prog
    def __getattr__(self, name): return getattr(self._p, name)
    def compile_kernel(self, cfg, caps, k):
        t = now(); r = self._p.compile_kernel(cfg, caps, k); phases.append(("compile", names.get(id(k), "?")) + since(t)); return r
    def launch_kernel(self, data, ctx):
        t = now(); r = self._p.launch_kernel(data, ctx); phases.append(("launch", "") + since(t)); return r
rt = impl.get_runtime()
rt.prog = Prog(rt.prog)
if {gc_off}:
    import gc; gc.disable()
if {src_cache}:  # experiment: read each ti.func's source once, not at every inlined call
    import functools
    kernel_impl.getsourcefile = functools.lru_cache(None)(kernel_impl.getsourcefile)
    kernel_impl.getsourcelines = functools.lru_cache(None)(kernel_impl.getsourcelines)
t = now(); ddatai.fused.warm.warm(); first = since(t)
t = now(); ddatai.fused.warm.warm(); second = since(t)
total = since(T0)
def tot(kind, big):
    return [sum(p[2] for p in phases if p[0] == kind and (p[1].startswith("run") == big)),
            sum(p[3] for p in phases if p[0] == kind and (p[1].startswith("run") == big))]
print(json.dumps(dict(import_=imp, init=ini, first=first, second=second, total=total,
    ast_run=tot("ast", True), compile_run=tot("compile", True), ast_other=tot("ast", False),
    compile_other=tot("compile", False), launches=[sum(p[2] for p in phases if p[0] == "launch"), sum(p[3] for p in phases if p[0] == "launch")],
    kernels=sorted({{p[1] for p in phases if p[0] == "compile"}}))))
"""


def _probe(root: Path, cache: str, opts: dict, a) -> dict:
    env = {**os.environ, **PINNED}
    if cache:
        env["TI_OFFLINE_CACHE_FILE_PATH"] = cache
    proc = subprocess.run([sys.executable, "-c", PROBE.format(root=str(root), opts=json.dumps(opts), gc_off=a.gc_off, src_cache=a.source_cache)],
                          capture_output=True, text=True, cwd=root, env=env, timeout=3600)
    if proc.returncode != 0:
        raise RuntimeError(proc.stderr[-3000:])
    return json.loads(proc.stdout.strip().splitlines()[-1])


def _largest(cache: str) -> int:
    """Bytes of the largest file under ``cache`` (the ``run`` kernel's cached LLVM module)."""
    files = [f for f in Path(cache).rglob("*") if f.is_file()] if cache else []
    return max((f.stat().st_size for f in files), default=0)


def _medians(rows: list) -> None:
    for key in ("import_", "init", "ast_run", "compile_run", "ast_other", "compile_other", "launches", "first", "second", "total"):
        w = statistics.median(r[key][0] for r in rows)
        c = statistics.median(r[key][1] for r in rows)
        print(f"  {key:14s} {w:7.3f} / {c:7.3f}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cache", default=os.environ.get("TI_OFFLINE_CACHE_FILE_PATH", ""))
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--init", nargs="*", default=[], help="extra ti.init options, KEY=VALUE (VALUE as JSON)")
    ap.add_argument("--gc-off", action="store_true", help="Python's garbage collector off during the first run")
    ap.add_argument("--source-cache", action="store_true", help="read each Taichi function's source once a process")
    ap.add_argument("--against", default="", help="another checkout (A), run before this one (B) in each repeat")
    ap.add_argument("--against-cache", default="", help="A's warm Taichi offline cache")
    a = ap.parse_args()
    opts = {k: json.loads(v) for k, v in (o.split("=", 1) for o in a.init)}
    sides = {"B": (ROOT, a.cache)}
    if a.against:
        sides = {"A": (Path(a.against).resolve(), a.against_cache), **sides}
    rows = {k: [] for k in sides}
    print(f"load {os.getloadavg()[0]:.1f} at the start; caches {dict((k, v[1] or '(default)') for k, v in sides.items())}; "
          f"ti.init extra {opts}; gc off {a.gc_off}; source cache {a.source_cache}")
    for _ in range(a.repeats):
        for k, (root, cache) in sides.items():
            rows[k].append(_probe(root, cache, opts, a))
            print(k, json.dumps(rows[k][-1]), flush=True)
    print(f"load {os.getloadavg()[0]:.1f} at the end; medians over {a.repeats} processes a side, wall / CPU [s]:")
    for k, (root, cache) in sides.items():
        print(f"{k} = {root} (largest cache file {_largest(cache) / 1e6:.2f} MB):")
        _medians(rows[k])
    if a.against:
        for key in ("launches", "total"):
            ratio = statistics.median(b[key][1] / x[key][1] for x, b in zip(rows["A"], rows["B"]))
            print(f"B/A {key} CPU, median of the pairs: {ratio:.3f}")


if __name__ == "__main__":
    main()
