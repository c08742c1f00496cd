"""Small models: the fused engine against today's NumPy path, ntdda beside them, and what a user of
the paper's method feels.

    python benchmarks/small_models.py [--repeats 3] [--steps 2000] [--samples 200]

Every figure is paired: the two paths alternate in fresh processes, ``--repeats`` times; medians.

1. Per step of a single small model, start excluded, amortised over a ``--steps`` run: ntdda's
   grid scene (`scaling.grid_scene`: n × n unit blocks on a fixed base, Δt = 1 ms, p = 1e9) of
   1, 4, 16 and 64 blocks from ntdda's sudden start, and the paper's Example I (φ = 14°) after
   its equilibrium stage. "numpy": today's small-model path (`Params(kernels="numpy")`, dense
   LAPACK solves); "fused": the fused engine (`Params(kernels="fused")`, its kernel loaded before
   the timed run). ntdda's time on the same grids from its side-by-side run on a quiet machine
   (docs/ntdda.md: 0.014 / 0.030 / 0.173 / 1.08 ms), or with ``--ntdda-driver PATH`` (ntdda's
   step timer, `benchmarks/ntdda_beside/build.sh`) ntdda measured beside them: in each repeat,
   ntdda's wall ms a step on the same grid written as DDAML files (`ntdda_beside.grid_files`:
   ntdda's own model, whose base block is held by three fixed points), median over the repeats.
2. The equilibrium stage of those models (NumPy, both paths).
3. `kgm.evaluate(Example I, [0, 1], "dda")`: today's path (the judgements side by side in one
   NumPy model) against the fused engine (``kernels="fused"``), each in a fresh process: the
   first call (the fused kernel taken from Taichi's offline cache) and a second one in the same
   process.
4. Example II's DDA-judged probabilistic study (friction N(22°, 2°), cohesion N(20 kPa, 5 kPa),
   ``--samples`` samples, 2 workers): samples a second, today's path against the fused engine
   (``kernels="fused"``: each worker loads the kernel once), and whether the tables are the
   same. Run ``python -m ddatai.fused`` once first: the fused kernel compiled and cached. With
   ``--stage-ab``, both on the fused engine instead: the equilibrium stage as before its
   limit-equilibrium screen (benchmarks/stage_as_before.py: the stage's code paths of the
   commit before it, in this checkout, whose fused kernel is cached) against today's.
5. The equilibrium stage of the study's members (the group's sub-model at each sample's
   strength): per member, with the limit-equilibrium screen (``settle(screen=True)``, the
   default) against the return mapping alone (``screen=False``), alternating in one process,
   and whether the held and released blocks are the same.
6. From a fresh interpreter to the second step of Example I (``Params(kernels="auto")``).

Threads are pinned in every child process (BLAS and Taichi one thread each: the machine is
shared); the study's 2 workers are the only parallelism.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
#: ntdda, ms per step on the same n × n grids from its sudden start, side by side on a quiet
#: 2-core machine (docs/ntdda.md; the project's recorded comparison)
NTDDA_MS = {1: 0.014, 4: 0.030, 16: 0.173, 64: 1.08}

STEP = """
import json, sys, time
sys.path[:0] = [{root!r}, {root!r} + "/benchmarks"]
import dataclasses
import numpy as np
import ddatai as dd
from ddatai.model import build_model
from ddatai.start import settle
from ddatai.step import Stepper
case, path, steps = {case!r}, {path!r}, {steps}
if case == "example_1":
    from scenes import example_1
    scene, params = example_1.build(friction=14.0)
else:
    from scaling import grid_scene
    scene, params = grid_scene(int(case))
    params = dataclasses.replace(params, initial_equilibrium=False)  # ntdda's sudden start
params = dataclasses.replace(params, kernels="numpy", solver="dense")
model = build_model(scene, params)
stepper = Stepper(model)
state = model.initial_state()
t = time.perf_counter()
stage_solves = 0
if params.initial_equilibrium:
    state, start = settle(stepper, state)
    stage_solves = start.solves
stage = time.perf_counter() - t
if path == "numpy":
    for _ in range(10):  # warm-up: the first factorisations
        state, _ = stepper.step(state)
    t = time.perf_counter()
    solves = 0
    for _ in range(steps):
        state, record = stepper.step(state)
        solves += record.oc_total
    wall = time.perf_counter() - t
else:
    from ddatai.fused import engine
    from ddatai.fused.pack import Member
    engine.run([Member(model=model, state=state, step_end=state.step + 10)])  # the kernel, loaded
    t = time.perf_counter()
    out = engine.run([Member(model=model, state=state, step_end=state.step + steps, record=True)])[0]
    wall = time.perf_counter() - t
    solves = int(out.records["oc_total"].sum())
    assert out.status == "done", out.status
print(json.dumps(dict(ms=1e3 * wall / steps, solves=solves / steps, stage_s=stage, stage_solves=stage_solves,
                      blocks=model.n_free)))
"""

KGM = """
import dataclasses, sys, time
sys.path.insert(0, {root!r})
import kgm
from scenes import example_1
scene, params = example_1.build()
params = dataclasses.replace(params, kernels={kernels!r})
walls = []
for _ in range(2):
    t = time.perf_counter()
    row = kgm.evaluate(scene, [0, 1], "dda", params=params)
    walls.append(time.perf_counter() - t)
print(walls[0], walls[1], row.fs, row.critical_friction, len(row.dda.runs))
"""

STUDY = """
import sys, time
sys.path.insert(0, {root!r})
from pathlib import Path
import numpy as np
import ddatai as dd
from ddatai.parallel import ScriptFunction
from kgm.studies.probabilistic import probabilistic
from kgm.studies.sampling import read_variables
from kgm.settings import DdaSettings, Settings
variables, correlation = read_variables(Path({root!r}) / "docs" / "kgm" / "example_2_vars.toml")
build = ScriptFunction({script!r})
settings = Settings(dda=DdaSettings(params=dd.Params(dt=0.0013, penalty_ratio=1.0, kernels={kernels!r})))
t = time.perf_counter()
study = probabilistic(build, variables, {n}, method="dda", seed=1, group={{0, 1}}, correlation=correlation,
                      workers=2, settings=settings)
wall = time.perf_counter() - t
np.save({out!r}, study.table["failed"])
print(wall, study.pf)
"""

FIRST_STEP = """
import time
t0 = time.perf_counter()
import sys
sys.path.insert(0, {root!r})
import ddatai as dd
from scenes import example_1
scene, params = example_1.build(friction=14.0)
res = dd.simulate(scene, params, steps=2)
print(time.perf_counter() - t0, res.meta["engine"]["name"])
"""


STAGE = """
import json, sys, time
sys.path.insert(0, {root!r})
import numpy as np
import ddatai as dd
from scenes import example_2
from kgm.build import prepare
from kgm.judges.run import RunPlan, sub_scene
from kgm.settings import DdaSettings, Settings
from kgm.studies.sampling import read_variables, sample_variables
from pathlib import Path
from ddatai.model import build_model
from ddatai.start import settle
from ddatai.step import Stepper
variables, correlation = read_variables(Path({root!r}) / "docs" / "kgm" / "example_2_vars.toml")
samples = sample_variables(variables, {n}, seed=1, correlation=correlation)
settings = Settings(dda=DdaSettings(params=dd.Params(dt=0.0013, penalty_ratio=1.0)))
rows = []
for i in range({n}):
    scene, params = example_2.build(friction=float(samples["friction"][i]), cohesion=float(samples["cohesion"][i]))
    problem = prepare(scene, settings=settings, params=params)
    plan = RunPlan.of(problem.system, frozenset({{0, 1}}), settings.dda, problem.params)
    sub, _ = sub_scene(problem.scene, problem.system, frozenset({{0, 1}}), free_neighbours=plan.free_neighbours)
    model = build_model(sub, plan.params)
    got = {{}}
    for screen in ((True, False) if i % 2 else (False, True)):
        t = time.perf_counter()
        _, record = settle(Stepper(model), model.initial_state(), screen=screen)
        got[screen] = (time.perf_counter() - t, record.held, record.released, record.solves)
    rows.append(got)
print(json.dumps([[r[True], r[False]] for r in rows]))
"""

PINNED = {"OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1", "TI_CPU_MAX_NUM_THREADS": "1"}


def run(code: str, timeout: int = 3600) -> str:
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT, timeout=timeout,
                          env={**os.environ, **PINNED})
    if proc.returncode != 0:
        raise RuntimeError(proc.stderr[-3000:])
    return proc.stdout.strip().splitlines()[-1]


def ntdda_wall_ms(driver: str, blocks: int, steps: int) -> float:
    """ntdda's wall ms a step (mean of the steps after the tenth) on its grid of ``blocks``, in a
    fresh process (`ntdda_beside`)."""
    import tempfile

    import ntdda_beside

    with tempfile.TemporaryDirectory(prefix="small_models_ntdda_") as tmp:
        geo, ana = ntdda_beside.grid_files(blocks, Path(tmp), steps)
        return ntdda_beside.run_ntdda(driver, geo, ana)["mean_ms"]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--steps", type=int, default=2000)
    ap.add_argument("--cases", default="1,4,16,64,example_1")
    ap.add_argument("--samples", type=int, default=200)
    ap.add_argument("--skip", default="", help="comma-separated parts to skip: steps, kgm, study, stage, first")
    ap.add_argument("--stage-ab", action="store_true",
                    help="the study on the fused engine, the stage as before its screen against today's")
    ap.add_argument("--stage-samples", type=int, default=60)
    ap.add_argument("--ntdda-driver", default="", help="ntdda's step timer (benchmarks/ntdda_beside/build.sh): "
                    "ntdda measured beside the runs instead of its recorded figures")
    a = ap.parse_args()
    skip = set(filter(None, a.skip.split(",")))
    print(f"machine: {platform.machine()} {platform.processor() or ''}, {os.cpu_count()} CPUs, Python "
          f"{platform.python_version()}; load {os.getloadavg()[0]:.1f}; medians of {a.repeats} fresh processes "
          f"a path, A/B interleaved\n")
    if a.ntdda_driver:
        print(f"ntdda: measured beside the runs ({a.ntdda_driver}, wall ms a step on its DDAML grid files)\n")
    root = str(ROOT)
    if "steps" not in skip:
        print("| model | free blocks | ntdda ms/step | NumPy path ms/step | fused ms/step | fused / ntdda | "
              "NumPy / fused | solves/step (NumPy, fused) | stage s (solves) |")
        print("|---|---|---|---|---|---|---|---|---|")
        for case in a.cases.split(","):
            got = {p: [] for p in ("numpy", "fused")}
            beside = []
            for _ in range(a.repeats):
                for path in got:
                    got[path].append(json.loads(run(STEP.format(root=root, case=case, path=path, steps=a.steps))))
                if a.ntdda_driver and case != "example_1":
                    beside.append(ntdda_wall_ms(a.ntdda_driver, int(case), a.steps))
            med = {p: statistics.median(r["ms"] for r in rows) for p, rows in got.items()}
            first = got["numpy"][0]
            nt = NTDDA_MS.get(first["blocks"]) if case != "example_1" else None
            nt = round(statistics.median(beside), 4) if beside else nt
            name = "Example I (φ 14°)" if case == "example_1" else f"grid {case} (sudden start)"
            stage = statistics.median(r["stage_s"] for r in got["numpy"])
            ratio = f"{med['fused'] / nt:.2f}×" if nt else "–"
            print(f"| {name} | {first['blocks']} | {nt if nt is not None else '–'} | {med['numpy']:.3f} | "
                  f"{med['fused']:.4f} | {ratio} | "
                  f"{med['numpy'] / med['fused']:.0f}× | {first['solves']:.2f}, {got['fused'][0]['solves']:.2f} | "
                  f"{stage:.3f} ({first['stage_solves']}) |", flush=True)
    if "kgm" not in skip:
        rows = {"numpy": [], "fused": []}
        for _ in range(a.repeats):
            for k in rows:
                rows[k].append(run(KGM.format(root=root, kernels=k)).split())
        for k, label in (("numpy", "today's path (kernels='numpy')"), ("fused", "fused engine (kernels='fused')")):
            first = statistics.median(float(r[0]) for r in rows[k])
            second = statistics.median(float(r[1]) for r in rows[k])
            r = rows[k][0]
            print(f"\nkgm.evaluate(Example I, [0, 1], 'dda'), {label}: {first:.2f} s in a fresh process, "
                  f"{second:.2f} s the second time ({r[4]} DDA runs; FS {float(r[2]):.4f}, critical friction "
                  f"{float(r[3]):.3f}°)", flush=True)
    if "study" not in skip:
        # (label, scene script, kernels): today's path against the fused engine, or the fused
        # engine with the stage as before its screen against today's
        example_2 = f"{root}/scenes/example_2.py"
        paths = ([("fused, the stage as before its screen", f"{root}/benchmarks/stage_as_before.py", "fused"),
                  ("fused, today's stage", example_2, "fused")] if a.stage_ab
                 else [("today's path (kernels='numpy')", example_2, "numpy"),
                       ("fused engine (kernels='fused')", example_2, "fused")])
        walls = {label: [] for label, _, _ in paths}
        tables = {}
        for rep in range(max(1, a.repeats - 1)):
            for label, script, k in paths:
                out = f"/tmp/ddatai_study_{len(tables)}.npy"
                wall, pf = run(STUDY.format(root=root, script=script, kernels=k, n=a.samples, out=out)).split()
                walls[label].append(float(wall))
                import numpy as np

                tables[label] = np.load(out)
        first, second = (tables[label] for label, _, _ in paths)
        for label, _, _ in paths:
            w = statistics.median(walls[label])
            print(f"\nExample II DDA-judged study, {a.samples} samples, 2 workers, {label}: {w:.1f} s "
                  f"({a.samples / w:.1f} samples/s; runs {', '.join(f'{x:.1f}' for x in walls[label])} s)", flush=True)
        print(f"the same verdicts on both: {bool((first == second).all())}; load now {os.getloadavg()[0]:.1f}")
    if "stage" not in skip:
        rows = json.loads(run(STAGE.format(root=root, n=a.stage_samples)))
        screened = [r[0] for r in rows]
        alone = [r[1] for r in rows]
        same = all(s[1:3] == r[1:3] for s, r in zip(screened, alone))
        released = [i for i, r in enumerate(alone) if r[2] > 0]
        print(f"\nequilibrium stage of the study's first {len(rows)} members (Example II's group): median "
              f"{1e3 * statistics.median(s[0] for s in screened):.1f} ms with the limit-equilibrium screen, "
              f"{1e3 * statistics.median(r[0] for r in alone):.1f} ms without (means "
              f"{1e3 * statistics.fmean(s[0] for s in screened):.1f}, {1e3 * statistics.fmean(r[0] for r in alone):.1f}; "
              f"{len(released)} members release blocks); solves a member {statistics.fmean(s[3] for s in screened):.1f}, "
              f"{statistics.fmean(r[3] for r in alone):.1f}; the same held and released blocks: {same}", flush=True)
    if "first" not in skip:
        firsts = [run(FIRST_STEP.format(root=root)).split() for _ in range(a.repeats)]
        med = statistics.median(float(f[0]) for f in firsts)
        print(f"\nfresh interpreter to the second step of Example I: median {med:.2f} s "
              f"({', '.join(f[0][:5] for f in firsts)}; engine: {firsts[0][1]})")


if __name__ == "__main__":
    main()
