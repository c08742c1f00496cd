"""ntdda and ddatai's fused engine timed beside each other on the same DDAML files, pair by pair.

    benchmarks/ntdda_beside/build.sh NTDDA_CHECKOUT           # prints the driver's path
    python benchmarks/ntdda_beside.py --driver /tmp/ntdda-beside-build/step_timer
                                      [--cases 1,4,16,64] [--pairs 5] [--steps 2000]
                                      [--cache DIR] [--out FILE.json]

ntdda's grid scene (docs/ntdda.md §5.1: n × n fitted 1 m blocks on a base block held by three
fixed points, ρ = 2000 kg/m³, E = 100 MPa, ν = 0.25, plane stress, p = 1e9 N/m with no automatic
penalty, φ = 30°, dynamic, Δt = 1 ms fixed, g2·w0 = 0.03 m, ntdda's default contact constants,
linear rotation) is written as a DDAML geometry and analysis file pair (`grid_files`). Each pair
of fresh processes runs, on those very files:

- ntdda: our driver (`benchmarks/ntdda_beside/step_timer.c`, linked to ntdda's own library)
  runs ntdda's analysis for ``--steps`` steps from its sudden start; a step's CPU time is the
  mean over the steps after the tenth (step 1 also writes K to a file), its wall time the median
  and the mean over the same steps;
- ddatai: `dd.read_ntdda` reads the files and `dd.simulate` runs them with the fused engine
  (``Params(kernels="fused")``), from ntdda's sudden start (``initial_equilibrium=False``, which
  the files already say), ``--steps`` steps; the fused kernel is loaded from Taichi's offline
  cache by a 10-step run of the same model before the timed run; the timed call records only its
  first and last frames; wall and CPU of that call ÷ steps. In the same process: the call's cost
  apart from its steps (the cheapest of three 10-step calls), so also its CPU a step without it;
  the fused engine alone on the same model (`ddatai.fused.engine.run`, as
  `benchmarks/fused_ab.py` times it); and the engine alone on the scaling benchmarks' `grid`
  (`scaling_scenes.grid_scene`: the same grid with its base a fixed block, one free block fewer).

Threads are pinned in both (OMP/OPENBLAS/MKL_NUM_THREADS=1, one Taichi CPU thread), ntdda first in
each pair. Reported: medians over the pairs, the ddatai ÷ ntdda CPU ratio pair by pair, the
machine's load (``os.getloadavg``) before each pair, and checks that both ran the same model:
the block count, Δt, penalty, and how far the blocks' final centroids lie apart.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import platform
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PINNED = {"OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1", "TI_CPU_MAX_NUM_THREADS": "1"}
GRID_STEP = 0.03  # ntdda's grid runs: largest step displacement g2·w0 [m] (docs/ntdda.md §5.1)
OVERSHOOT = 0.02  # joint lines pass their intersections by this much, as ntdda's examples do

ENVELOPE = """<?xml version="1.0" standalone="no"?>
<!DOCTYPE DDA SYSTEM "{dtd}">
<Berkeley:DDA xmlns:Berkeley="http://www.tsoft.com/~bdoolin/dda">
{body}
</Berkeley:DDA>
"""

ANALYSIS = """<Analysis type="dynamic">
  <Analysistype type="dynamic"/>
  <Rotation type="linear"/>
  <Gravity flag="no"/>
  <Gravaccel value="9.81"/>
  <Autotimestep flag="no"/>
  <Autopenalty flag="no" pfactor="10.0"/>
  <Planestrain flag="no"/>
  <Numtimesteps timesteps="{steps}"/>
  <Maxtimestep maxtimestep="0.001"/>
  <Opencloselimit maxopenclose="8"/>
  <Maxdisplacement maxdisplacement="{g2:.17g}"/>
  <Saveinterval step="1000000"/>
  <AConstants>
    <Openclose value="0.0002"/> <Opencriteria value="2e-07"/> <NormSpringPen value="0.0004"/>
    <AngleOverlap value="3.0"/> <ShearNormRatio value="2.5"/>
  </AConstants>
  <Blockmaterial type="1">
    <Unitmass>2000.0</Unitmass> <Unitweight>19620.0</Unitweight> <Youngsmod>1.0e8</Youngsmod>
    <Poissonratio>0.25</Poissonratio> <Damping>0.0</Damping>
    <Istress>0 0 0</Istress> <Ivelocity>0 0 0</Ivelocity> <Istrain>0 0 0</Istrain>
  </Blockmaterial>
  <Jointproperties type="1">
    <Friction>30.0</Friction> <Cohesion>0.0</Cohesion> <Tensile>0.0</Tensile>
  </Jointproperties>
</Analysis>"""

DDATAI = """
import dataclasses, json, sys, time
sys.path.insert(0, {root!r})
import numpy as np
import ddatai as dd
from ddatai.model import build_model
from ddatai.fused import engine
from ddatai.fused.pack import Member
case = dd.read_ntdda({geo!r}, {ana!r})
params = dataclasses.replace(case.params, kernels="fused", initial_equilibrium=False)
model = build_model(case.scene, params)
dd.simulate(case.scene, params, steps=10, record_every=10, model=model)  # the kernel, loaded
def call(n):
    c = time.process_time()
    dd.simulate(case.scene, params, steps=n, record_every=n, model=model)
    return time.process_time() - c
short = min(call(10) for _ in range(3))  # a call's cost apart from its steps
t, c = time.perf_counter(), time.process_time()
res = dd.simulate(case.scene, params, steps={steps}, record_every={steps}, model=model)
wall, cpu = time.perf_counter() - t, time.process_time() - c
state = model.initial_state()  # the engine alone, as benchmarks/fused_ab.py times it
c = time.process_time()
out = engine.run([Member(model=model, state=state, step_end={steps}, record=True)])[0]
kernel = time.process_time() - c
assert out.status == "done", out.status
sys.path.insert(0, {root!r} + "/benchmarks")  # the scaling benchmarks' grid: the same, its base a fixed block
from scaling_scenes import grid_scene
scene, gparams = grid_scene({blocks})
gmodel = build_model(scene, dataclasses.replace(gparams, initial_equilibrium=False, kernels="numpy", solver="dense"))
gstate = gmodel.initial_state()
engine.run([Member(model=gmodel, state=gstate, step_end=10)])
c = time.process_time()
gout = engine.run([Member(model=gmodel, state=gstate, step_end={steps}, record=True)])[0]
grid_cpu = time.process_time() - c
steps = res.steps
print(json.dumps(dict(ms=1e3 * wall / {steps}, cpu_ms=1e3 * cpu / {steps}, steps=int(len(steps)),
                      marginal_cpu_ms=1e3 * (cpu - short) / ({steps} - 10), call_cpu_ms=1e3 * short,
                      engine_cpu_ms=1e3 * kernel / {steps}, launch_ms=1e3 * float(steps["t_solve"].sum()) / {steps},
                      grid_scene_cpu_ms=1e3 * grid_cpu / {steps},
                      grid_scene_solves=float(gout.records["oc_total"].sum()) / {steps},
                      solves=float(steps["oc_total"].sum()) / len(steps), engine=res.meta["engine"]["name"],
                      blocks=int(model.n_blocks), free=int(model.n_free), dt=float(np.median(steps["dt"])),
                      penalty=float(model.penalty), centroids=np.asarray(res.centroid[-1]).tolist())))
"""


def grid_files(n_blocks: int, directory: Path, steps: int) -> tuple[Path, Path]:
    """Write ntdda's n × n grid (docs/ntdda.md §5.1) as DDAML ``grid{N}.geo`` and ``grid{N}.ana``.

    Joint lines: the base block's outline [−1, n + 1] × [−1, 0], the grid's columns x = 0 … n over
    y ∈ [0, n] and rows y = 1 … n over x ∈ [0, n], each passing its ends by `OVERSHOOT`. Three
    fixed points in the base; measured points at the top-left, top-right and bottom-middle block
    centres. g2 is set so that g2·w0 = 0.03 m with ntdda's w0 = (n + 2)/2."""
    n = int(round(n_blocks ** 0.5))
    if n * n != n_blocks:
        raise ValueError(f"grid_files: {n_blocks} blocks is not a square grid")
    e = OVERSHOOT
    lines = [(-1 - e, -1, n + 1 + e, -1), (-1 - e, 0, n + 1 + e, 0),
             (-1, -1 - e, -1, e), (n + 1, -1 - e, n + 1, e)]
    lines += [(i, -e, i, n + e) for i in range(n + 1)]
    lines += [(-e, j, n + e, j) for j in range(1, n + 1)]
    joints = "\n".join(f'      <Joint type="1"> {x1:g} {y1:g} {x2:g} {y2:g} </Joint>' for x1, y1, x2, y2 in lines)
    fixed = " ".join(f"<Point> {x:g} -0.5 </Point>" for x in (-0.5, n / 2, n + 0.5))
    measured = " ".join(f"<Point> {x:g} {y:g} </Point>" for x, y in ((0.5, n - 0.5), (n - 0.5, n - 0.5),
                                                                        ((n // 2) + 0.5, 0.5)))
    geometry = (f'<Berkeley:Geometry>\n   <Berkeley:Edgenodedist distance="0.001"/>\n   <Jointlist>\n{joints}\n'
                f'   </Jointlist>\n   <Fixedpointlist> {fixed} </Fixedpointlist>\n'
                f'   <Measuredpointlist> {measured} </Measuredpointlist>\n</Berkeley:Geometry>')
    w0 = (n + 2) / 2
    geo, ana = directory / f"grid{n_blocks}.geo", directory / f"grid{n_blocks}.ana"
    geo.write_text(ENVELOPE.format(dtd="geometry.dtd", body=geometry))
    ana.write_text(ENVELOPE.format(dtd="analysis.dtd", body=ANALYSIS.format(steps=steps, g2=GRID_STEP / w0)))
    return geo, ana


def run_ntdda(driver: str, geo: Path, ana: Path) -> dict:
    """ntdda's analysis of ``geo`` + ``ana`` in a fresh process and a fresh working directory (its
    output files go under ./output/ there)."""
    with tempfile.TemporaryDirectory(prefix="ntdda_beside_") as cwd:
        proc = subprocess.run([driver, str(geo), str(ana)], capture_output=True, text=True, cwd=cwd,
                              env={**os.environ, **PINNED}, timeout=3600)
    if proc.returncode != 0:
        raise RuntimeError(f"ntdda driver failed ({proc.returncode}): {proc.stderr[-2000:]}")
    return json.loads(proc.stdout.strip().splitlines()[-1])


def run_ddatai(geo: Path, ana: Path, steps: int, cache: str) -> dict:
    """ddatai's fused engine on ``geo`` + ``ana`` through `dd.simulate`, in a fresh process."""
    env = {**os.environ, **PINNED}
    if cache:
        env["TI_OFFLINE_CACHE_FILE_PATH"] = cache
    blocks = int(Path(geo).stem.removeprefix("grid"))
    code = DDATAI.format(root=str(ROOT), geo=str(geo), ana=str(ana), steps=steps, blocks=blocks)
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT, env=env,
                          timeout=3600)
    if proc.returncode != 0:
        raise RuntimeError(f"ddatai run failed: {proc.stderr[-3000:]}")
    return json.loads(proc.stdout.strip().splitlines()[-1])


def centroid_gap(a: dict, b: dict) -> float:
    """Largest distance between the two runs' final block centroids [m] (ntdda's block k + 1 is
    ddatai's block k: `dd.read_ntdda` numbers them in ntdda's order)."""
    import numpy as np

    return float(np.max(np.hypot(*(np.asarray(a["centroids"]) - np.asarray(b["centroids"])).T)))


def measure(driver: str, cases, pairs: int, steps: int, cache: str, log=sys.stderr) -> dict:
    """``pairs`` pairs of fresh processes per case, ntdda then ddatai; every run's figures."""
    out = {}
    with tempfile.TemporaryDirectory(prefix="ntdda_beside_files_") as tmp:
        for case in cases:
            geo, ana = grid_files(case, Path(tmp), steps)
            rows = []
            for p in range(pairs):
                load = os.getloadavg()[0]
                nt = run_ntdda(driver, geo, ana)
                dd_ = run_ddatai(geo, ana, steps, cache)
                rows.append(dict(load=load, ntdda=nt, ddatai=dd_, gap=centroid_gap(nt, dd_)))
                print(f"  grid {case} pair {p}: load {load:.1f}, ntdda {nt['mean_cpu_ms']:.4f} ms CPU "
                      f"({nt['oc_per_step']:.2f} OC), ddatai {dd_['cpu_ms']:.4f} ms CPU (marginal "
                      f"{dd_['marginal_cpu_ms']:.4f}, engine {dd_['engine_cpu_ms']:.4f}; {dd_['solves']:.2f} solves, "
                      f"{dd_['engine']}), ratio {dd_['cpu_ms'] / nt['mean_cpu_ms']:.2f}, centroids within "
                      f"{rows[-1]['gap']:.2e} m", file=log, flush=True)
            out[case] = rows
    return out


def _ratios(rows, key: str) -> list[float]:
    return [r["ddatai"][key] / r["ntdda"]["mean_cpu_ms"] for r in rows if key in r["ddatai"]]


def _spread(ratios: list[float]) -> str:
    if not ratios:
        return "–"
    return f"**{statistics.median(ratios):.2f}×** ({min(ratios):.2f}–{max(ratios):.2f}, {len(ratios)} pairs)"


def _median(values) -> str:
    values = list(values)
    return f"{statistics.median(values):.4f}" if values else "–"


def table(results: dict) -> str:
    """The markdown tables of `measure`'s results: medians over the pairs, ratios pair by pair."""
    lines = ["| blocks | ntdda CPU ms/step | ntdda wall ms/step (median step) | ntdda OC/step | ddatai CPU ms/step "
             "(`dd.simulate` ÷ steps) | solves/step | ddatai ÷ ntdda, pair by pair | median (range) | load |",
             "|---|---|---|---|---|---|---|---|---|"]
    for case, rows in results.items():
        nt = [r["ntdda"] for r in rows]
        dd_ = [r["ddatai"] for r in rows]
        ratios = _ratios(rows, "cpu_ms")
        loads = [r["load"] for r in rows]
        lines.append(
            f"| {case} | {statistics.median(n['mean_cpu_ms'] for n in nt):.4f} | "
            f"{statistics.median(n['median_ms'] for n in nt):.4f} | {nt[0]['oc_per_step']:.2f} | "
            f"{statistics.median(d['cpu_ms'] for d in dd_):.4f} | {dd_[0]['solves']:.2f} | "
            f"{', '.join(f'{r:.2f}' for r in ratios)} | {_spread(ratios)} | {min(loads):.1f}–{max(loads):.1f} |")
    lines += ["", "| blocks | a `dd.simulate` call apart from its steps, CPU ms | `dd.simulate` per step, the call's "
              "cost excluded, CPU ms | ÷ ntdda, median (range) | the fused engine alone, CPU ms/step | ÷ ntdda, "
              "median (range) | the engine alone on the scaling `grid` (base fixed), CPU ms/step (solves) | ÷ ntdda, "
              "median (range) | same model (blocks, Δt, p) | final centroids apart [m] |",
              "|---|---|---|---|---|---|---|---|---|---|"]
    for case, rows in results.items():
        nt = [r["ntdda"] for r in rows]
        dd_ = [r["ddatai"] for r in rows]
        same = all(n["blocks"] == d["blocks"] and abs(n["dt"] - d["dt"]) < 1e-12 * n["dt"]
                   and abs(n["penalty"] - d["penalty"]) < 1e-9 * n["penalty"] for n, d in zip(nt, dd_))
        lines.append(
            f"| {case} | {statistics.median(d['call_cpu_ms'] for d in dd_):.1f} | "
            f"{statistics.median(d['marginal_cpu_ms'] for d in dd_):.4f} | "
            f"{_spread(_ratios(rows, 'marginal_cpu_ms'))} | "
            f"{statistics.median(d['engine_cpu_ms'] for d in dd_):.4f} | {_spread(_ratios(rows, 'engine_cpu_ms'))} | "
            f"{_median(d['grid_scene_cpu_ms'] for d in dd_ if 'grid_scene_cpu_ms' in d)} "
            f"({max((d['grid_scene_solves'] for d in dd_ if 'grid_scene_solves' in d), default=math.nan):.2f}) | "
            f"{_spread(_ratios(rows, 'grid_scene_cpu_ms'))} | "
            f"{'yes' if same else 'NO'} ({dd_[0]['blocks']}, {dd_[0]['dt']:g} s, {dd_[0]['penalty']:.3g} N/m) | "
            f"{max(r['gap'] for r in rows):.1e} |")
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--driver", help="ntdda's step timer (benchmarks/ntdda_beside/build.sh)")
    ap.add_argument("--cases", default="1,4,16,64")
    ap.add_argument("--pairs", type=int, default=5)
    ap.add_argument("--steps", type=int, default=2000)
    ap.add_argument("--cache", default="", help="Taichi offline cache holding the fused kernel "
                    "(default: TI_OFFLINE_CACHE_FILE_PATH or Taichi's own)")
    ap.add_argument("--out", default="", help="also write every run's figures to this JSON file")
    ap.add_argument("--tables", nargs="+", default=[], metavar="FILE.json",
                    help="no runs: the tables of the pairs saved by earlier --out runs, pooled")
    a = ap.parse_args()
    if a.tables:
        pooled: dict = {}
        for path in a.tables:
            for case, rows in json.loads(Path(path).read_text()).items():
                pooled.setdefault(int(case), []).extend(rows)
        print(table(dict(sorted(pooled.items()))))
        return
    if not a.driver:
        ap.error("--driver is needed (or --tables)")
    print(f"machine: {platform.machine()} {platform.processor() or ''}, {os.cpu_count()} CPUs, Python "
          f"{platform.python_version()}; load {os.getloadavg()[0]:.1f} at the start; {a.pairs} pairs of fresh "
          f"processes a size, ntdda then ddatai, {a.steps} steps from ntdda's sudden start, threads pinned\n")
    results = measure(a.driver, [int(c) for c in a.cases.split(",")], a.pairs, a.steps,
                      a.cache or os.environ.get("TI_OFFLINE_CACHE_FILE_PATH", ""))
    if a.out:
        Path(a.out).write_text(json.dumps({str(k): v for k, v in results.items()}))
    print(table(results))


if __name__ == "__main__":
    main()
