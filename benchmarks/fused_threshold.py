"""Where the fused engine stops paying for a single `ddatai.simulate`: the fused engine against
today's path (what ``Params(kernels="auto")`` runs without it), paired in fresh processes.

    python benchmarks/fused_threshold.py [--cases grid:36,grid:64,slope:100,...]
                                         [--steps 36:1000,100:500,196:300] [--pairs 2]
                                         [--protocol ntdda|settled] [--out FILE.jsonl]

Each case (family:size, the families of `benchmarks/scaling_scenes.py`; the slope's size is the
wanted block count, its free blocks as cut) runs ``dd.simulate`` in two fresh processes, today's
path then the fused engine (the order alternates pair by pair), threads pinned (one BLAS and one
Taichi thread). "today": ``kernels="auto"`` with the fused engine's size limit at zero
(`ddatai.fused.policy.FUSED_BLOCKS`): the NumPy path up to ``ddatai.model.SMALL_MODEL_BLOCKS``
free blocks, the Taichi kernels above, the solver "auto" (dense up to
``ddatai.solver.DENSE_UNKNOWNS`` unknowns, PARDISO or SciPy above). "fused": ``kernels="fused"``.

Per process: the model is built and, with ``--protocol settled``, settled by its equilibrium
stage (in NumPy or the Taichi kernels: the same on both paths, not timed); then a first
``dd.simulate`` of 10 steps (the process's start: the fused kernel taken from Taichi's offline
cache, or today's kernels, the first factorisations) and a timed ``dd.simulate`` of the case's
steps from the same state (wall and CPU per step; the model built once, before both). Also the
solves a step, the process's peak memory (max RSS), the fused engine's matrix slab (2·(6n)²
doubles, `ddatai.fused.pack`), relaunches with a larger contact region (never truncated) and
steps handed to today's path, and how far the two runs' final vertices lie apart. Rows go to
``--out`` as JSON lines; ``--table`` prints the Markdown table of such a file.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PINNED = {k: "1" for k in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "TI_CPU_MAX_NUM_THREADS")}

CHILD = """
import dataclasses, json, resource, sys, time, warnings
sys.path[:0] = [{root!r}, {root!r} + "/benchmarks"]
warnings.simplefilter("ignore")
import numpy as np
import ddatai as dd
from ddatai.fused import engine, policy, single
from ddatai.model import build_model
from ddatai.start import settle
from ddatai.step import Stepper
from scaling_scenes import SCENES
family, size, steps, path, settled = {family!r}, {size}, {steps}, {path!r}, {settled}
scene, params = SCENES[family](size)
params = dataclasses.replace(params, initial_equilibrium=False, solver={solver!r} if path == "today" else "auto",
                             kernels="fused" if path == "fused" else "auto")
if path == "today":
    policy.FUSED_BLOCKS = 0  # "auto" without the fused engine: today's path at every size
handed, grown = [], []
_run, _carried = single.run, engine.Session.carried
def run_counted(*a, **k):
    out = _run(*a, **k)
    handed.append(bool(out[2]))
    return out
def carried_counted(self, i, factor=1):
    grown.append(factor)
    return _carried(self, i, factor)
single.run, engine.Session.carried = run_counted, carried_counted
model = build_model(scene, params)
state = model.initial_state()
stage_s = 0.0
if settled:
    t = time.perf_counter()
    state, _ = settle(Stepper(model), state)
    stage_s = time.perf_counter() - t
state = state.replace(step=0)
t, c = time.perf_counter(), time.process_time()
first = dd.simulate(scene, params, steps=10, record_every=10, model=model, initial_state=state)
first_s, first_cpu = time.perf_counter() - t, time.process_time() - c
t, c = time.perf_counter(), time.process_time()
res = dd.simulate(scene, params, steps=steps, record_every=steps, model=model, initial_state=state)
wall, cpu = time.perf_counter() - t, time.process_time() - c
engine_name = res.meta["engine"]["name"]
assert engine_name == ("fused" if path == "fused" else "numpy" if model.numpy_path else "taichi"), res.meta["engine"]
np.save({npy!r}, res.vertices[-1])
s = res.steps
print(json.dumps(dict(family=family, size=size, blocks=int(model.n_free), path=path, engine=engine_name,
                      solver=params.solver,
                      settled=settled, steps=steps, ms=1e3 * wall / steps, cpu_ms=1e3 * cpu / steps,
                      first_s=first_s, first_cpu_s=first_cpu, stage_s=stage_s,
                      solves=float(s["oc_total"].sum()) / steps, contacts=float(np.median(s["contacts"])),
                      sim_s=float(res.time[-1]) if hasattr(res, "time") else None,
                      peak_mb=resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0,
                      slab_mb=2 * (6 * model.n_free) ** 2 * 8 / 2**20, handed=any(handed), grown=len(grown))))
"""


def child(family: str, size: int, steps: int, path: str, settled: bool, npy: str, solver: str = "auto") -> dict:
    code = CHILD.format(root=str(ROOT), family=family, size=size, steps=steps, path=path, settled=settled, npy=npy,
                        solver=solver)
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT,
                          env={**os.environ, **PINNED}, timeout=3600)
    if proc.returncode != 0:
        raise RuntimeError(proc.stderr[-3000:])
    return json.loads(proc.stdout.strip().splitlines()[-1])


def steps_for(size: int, spec: str) -> int:
    """The step count of ``size`` from "SIZE:STEPS,..." (the entry of the largest SIZE ≤ size)."""
    table = sorted((int(a), int(b)) for a, b in (x.split(":") for x in spec.split(",")))
    return [b for a, b in table if a <= size][-1] if size >= table[0][0] else table[0][1]


def table(rows: list) -> str:
    """The Markdown table of paired rows (JSON lines of `main`)."""
    cases = {}
    for r in rows:
        cases.setdefault((r["family"], r["size"], r["settled"], r.get("today_solver", "auto")), []).append(r)
    out = ["| family | start | free blocks | steps | fused ms/step (CPU) | today's ms/step (CPU) | today's engine "
           "| today/fused CPU, each pair | today/fused wall, each pair | solves/step (fused, today) "
           "| first 10 steps s (fused, today) | peak RSS MB (fused, today) | fused slab MB | relaunches, handed over "
           "| final vertices apart [m] |",
           "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for (family, size, settled, solver), rs in sorted(cases.items(), key=lambda kv: (kv[0][3], kv[0][2], kv[0][0],
                                                                                     kv[1][0]["blocks"])):
        f = [r for r in rs if r["path"] == "fused"]
        t = [r for r in rs if r["path"] == "today"]
        n = min(len(f), len(t))
        if not n:
            continue
        f, t = f[:n], t[:n]
        cpu = [b["cpu_ms"] / a["cpu_ms"] for a, b in zip(f, t)]
        wall = [b["ms"] / a["ms"] for a, b in zip(f, t)]
        med = lambda rr, k: statistics.median(x[k] for x in rr)  # noqa: E731
        out.append(
            f"| {family} | {'settled' if settled else 'sudden'} | {f[0]['blocks']} | {f[0]['steps']} "
            f"| {med(f, 'ms'):.2f} ({med(f, 'cpu_ms'):.2f}) | {med(t, 'ms'):.2f} ({med(t, 'cpu_ms'):.2f}) "
            f"| {t[0]['engine']}{'' if solver == 'auto' else ', solver ' + solver} "
            f"| {', '.join(f'{x:.2f}' for x in cpu)} | {', '.join(f'{x:.2f}' for x in wall)} "
            f"| {med(f, 'solves'):.2f}, {med(t, 'solves'):.2f} | {med(f, 'first_s'):.1f}, {med(t, 'first_s'):.1f} "
            f"| {med(f, 'peak_mb'):.0f}, {med(t, 'peak_mb'):.0f} | {f[0]['slab_mb']:.1f} "
            f"| {sum(x['grown'] for x in f)}, {sum(x['handed'] for x in f)} "
            f"| {max(x.get('gap_m', 0.0) for x in f):.1e} |")
    return "\n".join(out)


def main() -> None:
    import numpy as np

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", default="grid:36,grid:49,grid:64,grid:100,grid:144,grid:196,grid:256")
    ap.add_argument("--steps", default="36:1000,100:500,196:300", help="SIZE:STEPS,...: steps from each size on")
    ap.add_argument("--pairs", type=int, default=2)
    ap.add_argument("--protocol", default="ntdda", choices=("ntdda", "settled"))
    ap.add_argument("--today-solver", default="auto",
                    help="Params.solver of today's path (scipy: what a machine without the [fast] extra gets)")
    ap.add_argument("--out", type=Path, default=Path("/tmp/fused_threshold.jsonl"))
    ap.add_argument("--table", type=Path, default=None, help="print the table of this JSON-lines file and stop")
    a = ap.parse_args()
    if a.table is not None:
        print(table([json.loads(x) for x in a.table.read_text().splitlines() if x.strip()]))
        return
    print(f"load {os.getloadavg()}; cache {os.environ.get('TI_OFFLINE_CACHE_FILE_PATH', '(default)')}", flush=True)
    for case in a.cases.split(","):
        family, size = case.split(":")
        size = int(size)
        steps = steps_for(size, a.steps)
        for k in range(a.pairs):
            npy = {p: f"/tmp/fused_threshold_{os.getpid()}_{p}.npy" for p in ("fused", "today")}
            rows = {}
            for path in (("today", "fused") if k % 2 == 0 else ("fused", "today")):
                rows[path] = child(family, size, steps, path, a.protocol == "settled", npy[path], a.today_solver)
            gap = float(np.max(np.hypot(*(np.load(npy["fused"]) - np.load(npy["today"])).T)))
            with a.out.open("a") as fh:
                for path, row in rows.items():
                    extra = {"gap_m": gap, "load": os.getloadavg()[0], "today_solver": a.today_solver}
                    fh.write(json.dumps({**row, **extra}) + "\n")
            f, t = rows["fused"], rows["today"]
            print(f"{family} {f['blocks']} ({'settled' if a.protocol == 'settled' else 'sudden'}) pair {k}: fused "
                  f"{f['ms']:.2f} ms ({f['cpu_ms']:.2f} CPU), {f['solves']:.2f} solves; today [{t['engine']}] "
                  f"{t['ms']:.2f} ms ({t['cpu_ms']:.2f} CPU), {t['solves']:.2f} solves; CPU ratio "
                  f"{t['cpu_ms'] / f['cpu_ms']:.2f}; first {f['first_s']:.1f} / {t['first_s']:.1f} s; RSS "
                  f"{f['peak_mb']:.0f} / {t['peak_mb']:.0f} MB; grown {f['grown']}, handed {f['handed']}; "
                  f"gap {gap:.2e} m; load {os.getloadavg()[0]:.1f}", flush=True)


if __name__ == "__main__":
    main()
