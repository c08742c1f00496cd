"""Small models: the fixed cost of a step, paired NumPy path against Taichi kernels, and what a
user of the paper's method feels.

    python benchmarks/small_models.py [--repeats 3] [--steps 200]

1. Per step, after the equilibrium stage, on ntdda's grid scene (`scaling.grid_scene`: n × n unit
   blocks on a fixed base, Δt = 1 ms, p = 1e9) of 1, 4, 16, 64 and 256 blocks and on the paper's
   Example I (4 blocks, φ = 14°): the small-model path (`Params(kernels="numpy",
   solver="dense")`, what "auto" picks up to `SMALL_MODEL_BLOCKS`) and the Taichi kernels with a
   sparse solver (`kernels="taichi"`, PARDISO when installed), each in its own fresh process,
   interleaved A/B ``--repeats`` times; medians. ntdda's per-step times on the same grids (its
   recorded side-by-side run on this machine type, docs/ntdda.md) are printed beside them.
2. The equilibrium stage's wall time and solves on the same models.
3. From a fresh interpreter to the second step of Example I (the import, the model, the stage and
   one step; Taichi's offline cache warm).
4. `kgm.evaluate(Example I scene, [0, 1], "dda")`: the DDA verdict with its critical-friction
   bisection, wall time.
"""

from __future__ import annotations

import argparse
import json
import platform
import statistics
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
#: ntdda, ms per step on the same n × n grids, side by side on this machine type (2-core EPYC,
#: shared): the project's recorded comparison (docs/ntdda.md)
NTDDA_MS = {1: 0.020, 4: 0.041, 16: 0.164, 64: 2.03, 256: 26.5}
PATHS = {"numpy": dict(kernels="numpy", solver="dense"), "taichi": dict(kernels="taichi", solver="auto")}

ONE = """
import dataclasses, json, sys, time
sys.path[:0] = [{root!r}, {root!r} + "/benchmarks"]
import numpy as np
import ddatai as dd
from ddatai.model import build_model
from ddatai.records import STEP_PHASES
from ddatai.start import settle
from ddatai.step import Stepper
case, path, steps = {case!r}, {path!r}, {steps}
if case == "example_1":
    from scenes import example_1
    scene, params = example_1.build(friction=14.0)
else:
    from scaling import grid_scene
    scene, params = grid_scene(int(case))
params = dataclasses.replace(params, **{options!r})
model = build_model(scene, params)
stepper = Stepper(model)
t = time.perf_counter()
state, start = settle(stepper, model.initial_state())
stage = time.perf_counter() - t
for _ in range(10):  # warm-up: compilation, the first factorisation
    state, _ = stepper.step(state)
times, solves = [], []
for _ in range(steps):
    t = time.perf_counter()
    state, record = stepper.step(state)
    times.append(time.perf_counter() - t)
    solves.append(record.oc_total)
print(json.dumps(dict(ms=1e3 * float(np.median(times)), solves=float(np.mean(solves)), stage_s=stage,
                      stage_solves=start.solves, welded=start.welded, blocks=model.n_free,
                      solver=stepper.solver.backend, numpy_path=model.numpy_path)))
"""

FIRST_STEP = """
import time
t0 = time.perf_counter()
import sys
sys.path.insert(0, {root!r})
import ddatai as dd
from scenes import example_1
scene, params = example_1.build(friction=14.0)
dd.simulate(scene, params, steps=2)
print(time.perf_counter() - t0)
"""

KGM = """
import sys, time
sys.path.insert(0, {root!r})
import kgm
from scenes import example_1
scene, params = example_1.build()
t = time.perf_counter()
row = kgm.evaluate(scene, [0, 1], "dda", params=params)
print(time.perf_counter() - t, row.fs, row.critical_friction, len(row.dda.runs))
"""


def run(code: str) -> str:
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT)
    if proc.returncode != 0:
        raise RuntimeError(proc.stderr[-3000:])
    return proc.stdout.strip().splitlines()[-1]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--steps", type=int, default=200)
    ap.add_argument("--cases", default="1,4,16,64,256,example_1")
    ap.add_argument("--no-kgm", action="store_true")
    a = ap.parse_args()
    print(f"machine: {platform.machine()} {platform.processor() or ''}, Python {platform.python_version()}; "
          f"medians of {a.repeats} fresh processes a path, A/B interleaved, {a.steps} steps each after 10 "
          f"warm-up steps\n")
    print("| model | blocks | ntdda ms/step | NumPy path ms/step | Taichi kernels ms/step | Taichi / NumPy | "
          "NumPy / ntdda | solves/step | stage: NumPy s (solves) | stage: Taichi s |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for case in a.cases.split(","):
        got = {p: [] for p in PATHS}
        for _ in range(a.repeats):
            for path, options in PATHS.items():
                got[path].append(json.loads(run(ONE.format(root=str(ROOT), case=case, path=path,
                                                           steps=a.steps, options=options))))
        med = {p: statistics.median(r["ms"] for r in rows) for p, rows in got.items()}
        stage = {p: statistics.median(r["stage_s"] for r in rows) for p, rows in got.items()}
        first = got["numpy"][0]
        name = "Example I (φ 14°)" if case == "example_1" else f"grid {case}"
        nt = NTDDA_MS.get(first["blocks"]) if case != "example_1" else None
        print(f"| {name} | {first['blocks']} | {nt if nt is not None else '–'} | {med['numpy']:.3f} | "
              f"{med['taichi']:.3f} | {med['taichi'] / med['numpy']:.1f}× | "
              f"{(med['numpy'] / nt) if nt else float('nan'):.1f}× | {first['solves']:.2f} | "
              f"{stage['numpy']:.3f} ({first['stage_solves']}{', welded' if first['welded'] else ''}) | "
              f"{stage['taichi']:.3f} |", flush=True)
    firsts = sorted(float(run(FIRST_STEP.format(root=str(ROOT)))) for _ in range(a.repeats))
    print(f"\nfresh interpreter to the second step of Example I: median {statistics.median(firsts):.2f} s "
          f"({', '.join(f'{f:.2f}' for f in firsts)})")
    if not a.no_kgm:
        wall, fs, phi, runs = run(KGM.format(root=str(ROOT))).split()
        print(f"kgm.evaluate(Example I, [0, 1], 'dda'): {float(wall):.2f} s ({runs} DDA runs; FS {float(fs):.3f}, "
              f"critical friction {float(phi):.2f}°)")


if __name__ == "__main__":
    main()
