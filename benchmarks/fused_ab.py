"""A step of the fused engine, this checkout against another one, paired in fresh processes.

    python benchmarks/fused_ab.py --against OTHER_CHECKOUT [--against-cache DIR] [--cache DIR]
                                  [--cases 1,4,16,64] [--repeats 3] [--steps 2000]

Per step of a single small model, start excluded, amortised over a ``--steps`` run (the fused
part of `benchmarks/small_models.py`: ntdda's grid scenes from ntdda's sudden start, the kernel
loaded before the timed run): each repeat runs the other checkout (A) then this one (B), each in
a fresh process with its own Taichi offline cache (``--against-cache`` and ``--cache``, else
``TI_OFFLINE_CACHE_FILE_PATH``), threads pinned (one Taichi thread, one BLAS thread). Reports
medians of wall and CPU ms a step, the B/A ratio pair by pair, the solves a step and how far the
two runs' final vertices lie apart (the engines' sums may run in another order)."""

import argparse
import json
import os
import platform
import statistics
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
NTDDA_MS = {1: 0.014, 4: 0.030, 16: 0.173, 64: 1.08}
PINNED = {"OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1", "TI_CPU_MAX_NUM_THREADS": "1"}

STEP = """
import dataclasses, json, sys, time
sys.path[:0] = [{root!r}, {root!r} + "/benchmarks"]
import numpy as np
from ddatai.model import build_model
from scaling import grid_scene
from ddatai.fused import engine
from ddatai.fused.pack import Member
scene, params = grid_scene({case})
params = dataclasses.replace(params, initial_equilibrium=False, kernels="numpy", solver="dense")
model = build_model(scene, params)
state = model.initial_state()
engine.run([Member(model=model, state=state, step_end=state.step + 10)])  # the kernel, loaded
t, c = time.perf_counter(), time.process_time()
out = engine.run([Member(model=model, state=state, step_end=state.step + {steps}, record=True)])[0]
wall, cpu = time.perf_counter() - t, time.process_time() - c
assert out.status == "done", out.status
np.save({npy!r}, out.state.vertex_xy)
print(json.dumps(dict(ms=1e3 * wall / {steps}, cpu_ms=1e3 * cpu / {steps},
                      solves=float(out.records["oc_total"].sum()) / {steps})))
"""


def run(root: Path, cache: str, case: int, steps: int, npy: str) -> dict:
    env = {**os.environ, **PINNED}
    if cache:
        env["TI_OFFLINE_CACHE_FILE_PATH"] = cache
    proc = subprocess.run([sys.executable, "-c", STEP.format(root=str(root), case=case, steps=steps, npy=npy)],
                          capture_output=True, text=True, cwd=root, env=env, timeout=3600)
    if proc.returncode != 0:
        raise RuntimeError(proc.stderr[-3000:])
    return json.loads(proc.stdout.strip().splitlines()[-1])


def main() -> None:
    import numpy as np

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--against", required=True, help="the other checkout (A)")
    ap.add_argument("--against-cache", default="", help="A's Taichi offline cache")
    ap.add_argument("--cache", default="", help="this checkout's Taichi offline cache")
    ap.add_argument("--cases", default="16,64")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--steps", type=int, default=2000)
    a = ap.parse_args()
    print(f"machine: {platform.machine()} {platform.processor() or ''}, {os.cpu_count()} CPUs, Python "
          f"{platform.python_version()}; load {os.getloadavg()[0]:.1f} at the start; A = {a.against}, B = this "
          f"checkout; {a.repeats} pairs of fresh processes a case, A then B; medians\n")
    print("| model | ntdda ms/step | A ms/step | B ms/step | B / ntdda | A/B wall (median pair) | "
          "A/B CPU (median pair) | solves/step (A, B) | final vertices, largest A–B distance [m] |")
    print("|---|---|---|---|---|---|---|---|---|")
    for case in (int(c) for c in a.cases.split(",")):
        rows = {"A": [], "B": []}
        gap = 0.0
        for r in range(a.repeats):
            npy = {k: f"/tmp/fused_ab_{os.getpid()}_{k}.npy" for k in rows}
            rows["A"].append(run(Path(a.against).resolve(), a.against_cache, case, a.steps, npy["A"]))
            rows["B"].append(run(ROOT, a.cache or os.environ.get("TI_OFFLINE_CACHE_FILE_PATH", ""), case, a.steps,
                                 npy["B"]))
            gap = max(gap, float(np.max(np.hypot(*(np.load(npy["A"]) - np.load(npy["B"])).T))))
            print(f"  case {case} pair {r}: A {rows['A'][-1]}, B {rows['B'][-1]}", file=sys.stderr, flush=True)
        med = {k: statistics.median(x["ms"] for x in v) for k, v in rows.items()}
        wall = statistics.median(x["ms"] / y["ms"] for x, y in zip(rows["A"], rows["B"]))
        cpu = statistics.median(x["cpu_ms"] / y["cpu_ms"] for x, y in zip(rows["A"], rows["B"]))
        nt = NTDDA_MS.get(case)
        print(f"| grid {case} (sudden start) | {nt} | {med['A']:.4f} | {med['B']:.4f} | "
              f"{med['B'] / nt:.2f}× | {wall:.2f}× | {cpu:.2f}× | {rows['A'][0]['solves']:.2f}, "
              f"{rows['B'][0]['solves']:.2f} | {gap:.2e} |", flush=True)


if __name__ == "__main__":
    main()
