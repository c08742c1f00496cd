"""ntdda and ddatai's fused engine timed beside each other on the same DDAML files, pair by pair.

    benchmarks/ntdda_beside/build.sh NTDDA_CHECKOUT           # prints the driver's path
    python benchmarks/ntdda_beside.py --driver /tmp/ntdda-beside-build/step_timer
                                      [--cases 1,4,16,64] [--pairs 5] [--steps 2000]
                                      [--start sudden|default|sudden,default]
                                      [--cache DIR] [--out FILE.json]

ntdda's grid scene (docs/ntdda.md §5.1: n × n fitted 1 m blocks on a base block held by three
fixed points, ρ = 2000 kg/m³, E = 100 MPa, ν = 0.25, plane stress, p = 1e9 N/m with no automatic
penalty, φ = 30°, dynamic, Δt = 1 ms fixed, g2·w0 = 0.03 m, ntdda's default contact constants,
linear rotation) is written as a DDAML geometry and analysis file pair (`grid_files`). Each round
of fresh processes runs, on those very files:

- ntdda: our driver (`benchmarks/ntdda_beside/step_timer.c`, linked to ntdda's own library)
  runs ntdda's analysis for ``--steps`` steps from its sudden start, whichever ddatai's start
  (the files leave ntdda's optional gravity turn-on off); a step's CPU time is the mean over the steps after
  the tenth (step 1 also writes K to a file), its wall time the median and the mean over the
  same steps;
- ddatai, from each ``--start`` (`start_params`): `dd.read_ntdda` reads the files and
  `dd.simulate` runs them with the fused engine (``Params(kernels="fused")``), ``--steps``
  steps, from ntdda's sudden start (``sudden``: ``initial_equilibrium=False``, which the files
  say) or from `dd.simulate`'s default start (``default``: the equilibrium stage,
  ``initial_equilibrium=True``; docs/guide/equilibrium_start.md). The stage runs inside the
  call; its CPU is measured there (`ddatai.run.settle` wrapped) and taken out of the call's, and
  reported beside it with `Results.start` (solves, held, released, unsettled). The fused kernel
  is loaded from Taichi's offline cache by a 10-step run of the same model before the timed run;
  the timed call records only its first and last frames; wall and CPU of that call ÷ steps. In
  the same process: the call's cost apart from its steps (the cheapest of three 10-step calls),
  so also its CPU a step without it; the fused engine alone on the same model from the same
  start (`ddatai.fused.engine.run`, as `benchmarks/fused_ab.py` times it); the engine alone on
  the scaling benchmarks' `grid` (`scaling_scenes.grid_scene`: the same grid with its base a
  fixed block, one free block fewer); the solves a step by quarter of the run; the blocks' end
  state (largest speed, sideways drift and sinking from t = 0).

Threads are pinned in both (OMP/OPENBLAS/MKL_NUM_THREADS=1, one Taichi CPU thread), ntdda first in
each round, then ddatai from each start (each paired with that round's ntdda run). Reported:
medians over the pairs, the ddatai ÷ ntdda CPU ratio pair by pair, the machine's load
(``os.getloadavg``) before each round, and checks that both ran the same model: the block count,
Δt, penalty, and how far the blocks' final centroids lie apart (ntdda's and either start's, and
the two starts' from each other).
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
    <Unitmass>2000.0</Unitmass> <Unitweight>19620.0</Unitweight> <Youngsmod>{young}</Youngsmod>
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
sys.path.insert(0, {root!r} + "/benchmarks")
import numpy as np
import ddatai as dd
import ddatai.run as run_module
from ddatai.model import build_model
from ddatai.fused import engine
from ddatai.fused.pack import Member
from ddatai.start import settle
from ddatai.step import Stepper
from ntdda_beside import start_params
case = dd.read_ntdda({geo!r}, {ana!r})
params = start_params(case.params, {start!r})
model = build_model(case.scene, params)
stage_cpu = []  # CPU of the equilibrium stage inside a call [s]: none from the sudden start
def timed_settle(*args, **kwargs):
    c = time.process_time()
    out = stage(*args, **kwargs)
    stage_cpu.append(time.process_time() - c)
    return out
stage, run_module.settle = run_module.settle, timed_settle
def call(n):
    del stage_cpu[:]
    c = time.process_time()
    res = dd.simulate(case.scene, params, steps=n, record_every=n, model=model)
    return time.process_time() - c - sum(stage_cpu), sum(stage_cpu), res
call(10)  # the kernel, loaded
short = min(call(10)[0] for _ in range(3))  # a call's cost apart from its steps (and its stage)
t = time.perf_counter()
cpu, stage_s, res = call({steps})
start = {{k: res.start[k][0].item() for k in res.start.dtype.names}} if len(res.start) else {{}}
wall = time.perf_counter() - t - start.get("wall_time", 0.0)
state = model.initial_state()  # the engine alone, as benchmarks/fused_ab.py times it
if params.initial_equilibrium:
    state = settle(Stepper(model), state)[0]
c = time.process_time()
out = engine.run([Member(model=model, state=state, step_end={steps}, record=True)])[0]
kernel = time.process_time() - c
assert out.status == "done", out.status
from scaling_scenes import grid_scene  # the scaling benchmarks' grid: the same, its base a fixed block
scene, gparams = grid_scene({blocks})
gmodel = build_model(scene, dataclasses.replace(gparams, initial_equilibrium=params.initial_equilibrium,
                                                kernels="numpy", solver="dense"))
gstate = gmodel.initial_state()
if params.initial_equilibrium:
    gstate = settle(Stepper(gmodel), gstate)[0]
engine.run([Member(model=gmodel, state=gstate, step_end=10)])
c = time.process_time()
gout = engine.run([Member(model=gmodel, state=gstate, step_end={steps}, record=True)])[0]
grid_cpu = time.process_time() - c
steps = res.steps
oc = steps["oc_total"]
moved = res.centroid[-1] - res.centroid[0]  # from t = 0 (the settled state after the stage)
print(json.dumps(dict(ms=1e3 * wall / {steps}, cpu_ms=1e3 * cpu / {steps}, steps=int(len(steps)),
                      marginal_cpu_ms=1e3 * (cpu - short) / ({steps} - 10), call_cpu_ms=1e3 * short,
                      engine_cpu_ms=1e3 * kernel / {steps}, launch_ms=1e3 * float(steps["t_solve"].sum()) / {steps},
                      grid_scene_cpu_ms=1e3 * grid_cpu / {steps},
                      grid_scene_solves=float(gout.records["oc_total"].sum()) / {steps},
                      solves=float(oc.sum()) / len(steps), start_protocol={start!r},
                      solves_by_quarter=[float(q.mean()) for q in np.array_split(oc, 4)],
                      solves_first_100=float(oc[:100].mean()), solves_max=int(oc.max()),
                      steps_over_one=int(np.count_nonzero(oc > 1)),
                      stage_cpu_s=stage_s, stage=start, engine=res.meta["engine"]["name"],
                      engine_why=res.meta["engine"].get("why", ""),
                      speed_end=float(np.max(np.hypot(*res.velocity[-1].T))),
                      drift=float(np.max(np.abs(moved[:, 0]))), sink=float(-np.min(moved[:, 1])),
                      blocks=int(model.n_blocks), free=int(model.n_free), dt=float(np.median(steps["dt"])),
                      penalty=float(model.penalty), centroids=np.asarray(res.centroid[-1]).tolist())))
"""


def grid_files(n_blocks: int, directory: Path, steps: int, young: float = 1.0e8) -> tuple[Path, Path]:
    """Write ntdda's n × n grid (docs/ntdda.md §5.1) as DDAML ``grid{N}.geo`` and ``grid{N}.ana``.

    Joint lines: the base block's outline [−1, n + 1] × [−1, 0], the grid's columns x = 0 … n over
    y ∈ [0, n] and rows y = 1 … n over x ∈ [0, n], each passing its ends by `OVERSHOOT`. Three
    fixed points in the base; measured points at the top-left, top-right and bottom-middle block
    centres. g2 is set so that g2·w0 = 0.03 m with ntdda's w0 = (n + 2)/2. ``young``: the blocks'
    Young's modulus [Pa] (the grid's 100 MPa; another value tests how a result depends on it)."""
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
    ana.write_text(ENVELOPE.format(dtd="analysis.dtd", body=ANALYSIS.format(
        steps=steps, g2=GRID_STEP / w0, young="1.0e8" if young == 1.0e8 else f"{young:.6e}")))
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


START = ("sudden", "default")  # ddatai's start: ntdda's sudden gravity, or `dd.simulate`'s default


def start_params(params, start: str):
    """ddatai's parameters for a ``start`` protocol on the files' ``params`` (`dd.read_ntdda`): the
    fused engine (``kernels="fused"``) from ntdda's sudden start (``"sudden"``:
    ``initial_equilibrium=False``, which the files say) or from `dd.simulate`'s default start, the
    equilibrium stage (``"default"``: ``initial_equilibrium=True``, ``Params``' default;
    docs/guide/equilibrium_start.md). Nothing else changes."""
    import dataclasses

    if start not in START:
        raise ValueError(f"start_params: start must be one of {START}, got {start!r}")
    return dataclasses.replace(params, kernels="fused", initial_equilibrium=start == "default")


def run_ddatai(geo: Path, ana: Path, steps: int, cache: str, start: str = "sudden") -> dict:
    """ddatai's fused engine on ``geo`` + ``ana`` through `dd.simulate`, in a fresh process, from
    the ``start`` protocol (`start_params`)."""
    env = {**os.environ, **PINNED}
    if cache:
        env["TI_OFFLINE_CACHE_FILE_PATH"] = cache
    blocks = int(Path(geo).stem.removeprefix("grid"))
    code = DDATAI.format(root=str(ROOT), geo=str(geo), ana=str(ana), steps=steps, blocks=blocks, start=start)
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


#: a row's key for ddatai's run from each start protocol ("ddatai": the sudden start, as before)
SIDE = {"sudden": "ddatai", "default": "ddatai_default"}


def measure(driver: str, cases, pairs: int, steps: int, cache: str, starts=("sudden",), log=sys.stderr,
            young: float = 1.0e8) -> dict:
    """``pairs`` rounds of fresh processes per case: ntdda, then ddatai from each of ``starts``
    (in turn first; each ddatai run paired with the ntdda run of its round); every run's figures."""
    out = {}
    with tempfile.TemporaryDirectory(prefix="ntdda_beside_files_") as tmp:
        for case in cases:
            geo, ana = grid_files(case, Path(tmp), steps, young)
            rows = []
            for p in range(pairs):
                row = dict(load=os.getloadavg()[0], ntdda=run_ntdda(driver, geo, ana))
                nt = row["ntdda"]
                for start in starts if p % 2 == 0 else starts[::-1]:  # either start first by turns
                    dd_ = row[SIDE[start]] = run_ddatai(geo, ana, steps, cache, start)
                    row[f"gap_{start}"] = centroid_gap(nt, dd_)
                    stage = dd_["stage"]
                    print(f"  grid {case} pair {p} {start}: load {row['load']:.1f}, ntdda {nt['mean_cpu_ms']:.4f} ms "
                          f"CPU ({nt['oc_per_step']:.2f} OC), ddatai {dd_['cpu_ms']:.4f} ms CPU (marginal "
                          f"{dd_['marginal_cpu_ms']:.4f}, engine {dd_['engine_cpu_ms']:.4f}; {dd_['solves']:.2f} "
                          f"solves, {dd_['engine']}), ratio {dd_['cpu_ms'] / nt['mean_cpu_ms']:.2f}, centroids "
                          f"within {row[f'gap_{start}']:.2e} m"
                          + (f"; stage {dd_['stage_cpu_s']:.3f} s CPU, {stage['solves']} solves, held "
                             f"{stage['held']}, released {stage['released']}" if stage else ""),
                          file=log, flush=True)
                if "gap_sudden" in row:
                    row["gap"] = row["gap_sudden"]  # the name the earlier pages' JSON uses
                rows.append(row)
            out[case] = rows
    return out


def _ratios(rows, key: str, side: str = "ddatai") -> list[float]:
    return [r[side][key] / r["ntdda"]["mean_cpu_ms"] for r in rows if side in r and key in r[side]]


def _spread(ratios: list[float]) -> str:
    if not ratios:
        return "–"
    return f"**{statistics.median(ratios):.2f}×** ({min(ratios):.2f}–{max(ratios):.2f}, {len(ratios)} pairs)"


def _median(values, fmt: str = ".4f") -> str:
    values = list(values)
    return format(statistics.median(values), fmt) if values else "–"


def _side(rows, side: str) -> list[dict]:
    return [r[side] for r in rows if side in r]


def _per_step(rows, side: str) -> str:
    """ddatai's median CPU ms a step (solves a step, their range over the pairs)."""
    dd_ = _side(rows, side)
    if not dd_:
        return "–"
    solves = [d["solves"] for d in dd_]
    span = f"{min(solves):.2f}" if max(solves) - min(solves) < 0.005 else f"{min(solves):.2f}–{max(solves):.2f}"
    return f"{_median(d['cpu_ms'] for d in dd_)} ({span})"


def _stage(rows) -> str:
    """The equilibrium stage of the default start: median CPU s (solves; held / released; flags)."""
    dd_ = _side(rows, SIDE["default"])
    if not dd_:
        return "–"
    stages = [d["stage"] for d in dd_]
    solves = sorted({s["solves"] for s in stages})
    flags = [f for f in ("unsettled", "stalled", "welded") if any(s[f] for s in stages)]
    return (f"{_median((d['stage_cpu_s'] for d in dd_), '.3f')} ({'/'.join(map(str, solves))} solves; "
            f"held {max(s['held'] for s in stages)}, released {max(s['released'] for s in stages)}"
            f"{'; ' + ', '.join(flags) if flags else ''})")


def summary(results: dict) -> str:
    """One line a size: ntdda, ddatai from either start, the stage, the ratios pair by pair."""
    lines = ["| blocks | ntdda CPU ms/step (OC/step) | ddatai, sudden start: CPU ms/step (solves/step) | ÷ ntdda, "
             "median (range, pairs) | ddatai, default start, stage excluded: CPU ms/step (solves/step) | ÷ ntdda, "
             "median (range, pairs) | the stage: CPU s (solves; held, released) | engine | load |",
             "|---|---|---|---|---|---|---|---|---|"]
    for case, rows in results.items():
        nt = [r["ntdda"] for r in rows]
        engines = sorted({d["engine"] for side in SIDE.values() for d in _side(rows, side)})
        loads = [r["load"] for r in rows]
        lines.append(
            f"| {case} | {_median(n['mean_cpu_ms'] for n in nt)} ({_median((n['oc_per_step'] for n in nt), '.2f')}) | "
            f"{_per_step(rows, SIDE['sudden'])} | {_spread(_ratios(rows, 'cpu_ms'))} | "
            f"{_per_step(rows, SIDE['default'])} | {_spread(_ratios(rows, 'cpu_ms', SIDE['default']))} | "
            f"{_stage(rows)} | {', '.join(engines)} | {min(loads):.1f}–{max(loads):.1f} |")
    return "\n".join(lines)


def end_states(results: dict) -> str:
    """Where the blocks are after the run, from either start: at rest on the base, and how far the
    final centroids lie from ntdda's and from each other's."""
    lines = ["| blocks | start | the stage's settlement [m] | largest speed at the end [m/s] | largest sideways "
             "drift from t = 0 [m] | largest sinking from t = 0 [m] | final centroids from ntdda's [m] | from the "
             "other start's [m] |", "|---|---|---|---|---|---|---|---|"]
    import numpy as np

    for case, rows in results.items():
        both = [r for r in rows if all(side in r for side in SIDE.values())]
        apart = max((float(np.max(np.hypot(*(np.asarray(r[SIDE['sudden']]['centroids'])
                                            - np.asarray(r[SIDE['default']]['centroids'])).T))) for r in both),
                    default=math.nan)
        for start, side in SIDE.items():
            dd_ = _side(rows, side)
            if not dd_ or "speed_end" not in dd_[0]:
                continue
            gaps = [r.get(f"gap_{start}", r.get("gap", math.nan)) for r in rows if side in r]
            settled = max((d["stage"]["settlement"] for d in dd_ if d["stage"]), default=None)
            lines.append(f"| {case} | {start} | {'–' if settled is None else f'{settled:.1e}'} | "
                         f"{max(d['speed_end'] for d in dd_):.1e} | "
                         f"{max(d['drift'] for d in dd_):.1e} | {max(d['sink'] for d in dd_):.1e} | "
                         f"{max(gaps):.1e} | {apart:.1e} |")
    return "\n".join(lines)


def details(results: dict, side: str = "ddatai") -> str:
    """Where ddatai's time goes from one start (``side``: a row's key, `SIDE`)."""
    lines = ["| blocks | a `dd.simulate` call apart from its steps (and its stage), CPU ms | `dd.simulate` per step, "
             "the call's cost excluded, CPU ms | ÷ ntdda, median (range) | the fused engine alone, CPU ms/step | "
             "÷ ntdda, median (range) | the engine alone on the scaling `grid` (base fixed), CPU ms/step (solves) | "
             "÷ ntdda, median (range) | same model (blocks, Δt, p) | final centroids from ntdda's [m] |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    start = next(k for k, v in SIDE.items() if v == side)
    for case, rows in results.items():
        rows = [r for r in rows if side in r]
        if not rows:
            continue
        nt = [r["ntdda"] for r in rows]
        dd_ = [r[side] for r in rows]
        same = all(n["blocks"] == d["blocks"] and abs(n["dt"] - d["dt"]) < 1e-12 * n["dt"]
                   and abs(n["penalty"] - d["penalty"]) < 1e-9 * n["penalty"] for n, d in zip(nt, dd_))
        lines.append(
            f"| {case} | {_median((d['call_cpu_ms'] for d in dd_), '.1f')} | "
            f"{_median(d['marginal_cpu_ms'] for d in dd_)} | {_spread(_ratios(rows, 'marginal_cpu_ms', side))} | "
            f"{_median(d['engine_cpu_ms'] for d in dd_)} | {_spread(_ratios(rows, 'engine_cpu_ms', side))} | "
            f"{_median(d['grid_scene_cpu_ms'] for d in dd_ if 'grid_scene_cpu_ms' in d)} "
            f"({max((d['grid_scene_solves'] for d in dd_ if 'grid_scene_solves' in d), default=math.nan):.2f}) | "
            f"{_spread(_ratios(rows, 'grid_scene_cpu_ms', side))} | "
            f"{'yes' if same else 'NO'} ({dd_[0]['blocks']}, {dd_[0]['dt']:g} s, {dd_[0]['penalty']:.3g} N/m) | "
            f"{max(r.get(f'gap_{start}', r.get('gap', math.nan)) for r in rows):.1e} |")
    return "\n".join(lines)


def solve_trace(results: dict) -> str:
    """ddatai's solves a step over the run, by quarter, from each start (where they go)."""
    lines = ["| blocks | start | solves/step, first 100 steps | by quarter of the run | steps with more than one "
             "solve | most in a step |", "|---|---|---|---|---|---|"]
    for case, rows in results.items():
        for start, side in SIDE.items():
            dd_ = [d for d in _side(rows, side) if "solves_by_quarter" in d]
            if dd_:
                d = dd_[0]  # the runs are deterministic: every pair's counts are the same
                lines.append(f"| {case} | {start} | {d['solves_first_100']:.2f} | "
                             f"{', '.join(f'{q:.2f}' for q in d['solves_by_quarter'])} | {d['steps_over_one']} | "
                             f"{d['solves_max']} |")
    return "\n".join(lines)


def table(results: dict) -> str:
    """The markdown tables of `measure`'s results: medians over the pairs, ratios pair by pair."""
    parts = [summary(results)]
    for start, side in SIDE.items():
        if any(side in r for rows in results.values() for r in rows):
            parts.append(f"Where ddatai's time goes, {start} start:\n\n" + details(results, side))
    parts += [t for t in (end_states(results), solve_trace(results)) if t.count("\n") > 1]  # rows, not headers only
    return "\n\n".join(parts)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--driver", help="ntdda's step timer (benchmarks/ntdda_beside/build.sh)")
    ap.add_argument("--cases", default="1,4,16,64")
    ap.add_argument("--pairs", type=int, default=5)
    ap.add_argument("--steps", type=int, default=2000)
    ap.add_argument("--cache", default="", help="Taichi offline cache holding the fused kernel "
                    "(default: TI_OFFLINE_CACHE_FILE_PATH or Taichi's own)")
    ap.add_argument("--start", default="sudden",
                    help="ddatai's start: sudden (ntdda's, as the files say), default (dd.simulate's "
                    "equilibrium stage; ntdda still starts suddenly), or sudden,default (both, paired "
                    "with the same ntdda run)")
    ap.add_argument("--young", type=float, default=1.0e8,
                    help="the blocks' Young's modulus [Pa] in the files (the grid's 1e8; ntdda's 16-block run "
                    "takes one solve a step at 1e8 and two at 0.99e8: benchmarks/results/iterations_16.md)")
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
    starts = tuple(a.start.split(","))
    if not starts or any(s not in START for s in starts):
        ap.error(f"--start: one or more of {', '.join(START)}, comma-separated")
    if not a.driver:
        ap.error("--driver is needed (or --tables)")
    print(f"machine: {platform.machine()} {platform.processor() or ''}, {os.cpu_count()} CPUs, Python "
          f"{platform.python_version()}; load {os.getloadavg()[0]:.1f} at the start; {a.pairs} pairs of fresh "
          f"processes a size, ntdda then ddatai, {a.steps} steps; ntdda from its sudden start, ddatai from "
          f"{' and from '.join(starts)} start; E = {a.young:.4g} Pa; threads pinned\n")
    results = measure(a.driver, [int(c) for c in a.cases.split(",")], a.pairs, a.steps,
                      a.cache or os.environ.get("TI_OFFLINE_CACHE_FILE_PATH", ""), starts, young=a.young)
    if a.out:
        Path(a.out).write_text(json.dumps({str(k): v for k, v in results.items()}))
    print(table(results))


if __name__ == "__main__":
    main()
