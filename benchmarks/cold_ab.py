"""A fresh process's cost from its start to a model's first step, paired between two checkouts.

    python benchmarks/cold_ab.py --baseline OTHER_CHECKOUT [--cases grid:1600,grid:400,slope:400,example_1]
                                 [--repeat 3] [--cache DIR]

Each repeat runs every case in a fresh process on the baseline (A) and on this checkout (B),
alternately (A B, then B A the next repeat), threads pinned (``OMP/OPENBLAS/MKL_NUM_THREADS=1``,
``TI_CPU_MAX_NUM_THREADS=1``), both on the same warm Taichi offline cache (``--cache``, default
``TI_OFFLINE_CACHE_FILE_PATH``; run once unmeasured first so that it holds both checkouts'
kernels). A process imports ddatai, builds the model, runs the equilibrium stage
(`ddatai.start.settle`, the settled protocol of ``benchmarks/scaling.py``) and one step, and
reports CPU (``getrusage``: the interpreter's start included) and wall (from the parent's clock
before it started the process) at: the import, the stage's end (its own CPU too: what
``scaling.py --protocol settled`` calls ``start_cpu_s``) and the first step's end; and a hash of
the state after the step, which must be the same on both sides. Prints one JSON line a process,
then a table of medians with the B/A ratio of each pair's medians.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PINNED = {"OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1", "TI_CPU_MAX_NUM_THREADS": "1"}

PROBE = r"""
import hashlib, json, resource, sys, time
T0 = float(sys.argv[1])
def cpu():
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime
sys.path.insert(0, {bench!r}); sys.path.insert(0, {scenes!r})
import ddatai as dd
out = dict(import_cpu=cpu(), import_wall=time.time() - T0)
case = {case!r}
if case == "example_1":
    from scenes.example_1 import build
    scene, params = build()
else:
    import scaling_scenes
    family, size = case.split(":")
    scene, params = getattr(scaling_scenes, family + "_scene")(int(size))
from ddatai.start import settle
from ddatai.step import Stepper
from ddatai import backend
model = dd.build_model(scene, params)
stepper = Stepper(model)
state = model.initial_state()
c = cpu()
state, rec = settle(stepper, state)
out.update(stage_cpu=cpu() - c, start_cpu=cpu(), start_wall=time.time() - T0, solves=int(rec.solves),
           factorisations=int(rec.factorisations), held=int(rec.held), released=int(rec.released),
           lowrank=int(getattr(stepper.solver, "lowrank", -1)))
if {save!r}:
    import numpy as np
    np.save({save!r} + "/" + case.replace(":", "_") + "_" + str(int(T0 * 1e6)) + ".npy", state.vertex_xy)
state, _ = stepper.step(state)
out.update(first_step_cpu=cpu(), first_step_wall=time.time() - T0, taichi=backend.current())
h = hashlib.sha256()
for a in (state.vertex_xy, state.block_velocity, state.block_stress):
    h.update(a.tobytes())
out["state"] = h.hexdigest()[:16]
print("RESULT " + json.dumps(out))
"""

FIELDS = ["import_cpu", "stage_cpu", "start_cpu", "start_wall", "first_step_cpu", "first_step_wall"]


def one(tree: Path, case: str, cache: str, save: str = "") -> dict:
    code = PROBE.format(bench=str(tree / "benchmarks"), scenes=str(tree), case=case, save=save)
    env = {**os.environ, **PINNED, "PYTHONPATH": str(tree)}
    if cache:
        env["TI_OFFLINE_CACHE_FILE_PATH"] = cache
    t0 = time.time()
    proc = subprocess.run([sys.executable, "-c", code, repr(t0)], capture_output=True, text=True, cwd=tree, env=env)
    line = [x for x in proc.stdout.splitlines() if x.startswith("RESULT ")]
    if proc.returncode or not line:
        raise RuntimeError(f"{tree} {case} failed:\n{proc.stderr[-3000:]}")
    return json.loads(line[0][7:])


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--baseline", required=True)
    ap.add_argument("--cases", default="grid:1600,grid:400,slope:400,example_1")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--cache", default=os.environ.get("TI_OFFLINE_CACHE_FILE_PATH", ""))
    ap.add_argument("--save", default="", help="a folder: each process saves its settled vertices there "
                    "(CASE_TIME.npy), to compare the two sides' positions")
    a = ap.parse_args()
    trees = {"A": Path(a.baseline).resolve(), "B": ROOT}
    runs: dict = {}
    loads = [os.getloadavg()[0]]
    for r in range(a.repeat):
        for case in a.cases.split(","):
            for side in ("AB" if r % 2 == 0 else "BA"):
                res = one(trees[side], case, a.cache, a.save and str(Path(a.save, side).resolve()))
                runs.setdefault((case, side), []).append(res)
                print(json.dumps(dict(repeat=r, case=case, side=side, load=os.getloadavg()[0], **res)), flush=True)
        loads.append(os.getloadavg()[0])
    print(f"\nA = {trees['A']}, B = {trees['B']}; {a.repeat} fresh processes a side and case, alternating; "
          f"load (1 min) {min(loads):.2f}-{max(loads):.2f}; medians, s")
    print("| case | side | " + " | ".join(FIELDS) + " | solves | factorisations | held/released | state |")
    print("|---|---|" + "---|" * (len(FIELDS) + 4))
    for case in a.cases.split(","):
        med = {}
        for side in "AB":
            rs = runs[(case, side)]
            med[side] = {f: statistics.median(x[f] for x in rs) for f in FIELDS}
            states = sorted({x["state"] for x in rs})
            print(f"| {case} | {side} | " + " | ".join(f"{med[side][f]:.3f}" for f in FIELDS) +
                  f" | {rs[0]['solves']} | {rs[0].get('factorisations')} | {rs[0].get('held')}/{rs[0].get('released')}"
                  f" | {','.join(states)} |")
        print(f"| {case} | B/A | " + " | ".join(f"{med['B'][f] / med['A'][f]:.3f}" for f in FIELDS) + " | | | | " +
              ("same" if {x['state'] for x in runs[(case, 'A')]} == {x['state'] for x in runs[(case, 'B')]}
               else "DIFFERENT") + " |")


if __name__ == "__main__":
    main()
