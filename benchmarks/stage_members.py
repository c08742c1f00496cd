"""The equilibrium stage of small models, member by member: two checkouts side by side.

    python benchmarks/stage_members.py [--samples 80] [--repeats 3] [--vs OTHER_CHECKOUT]

The members are those a user of the paper's method settles: the sub-models of Example II's
DDA-judged study (group {0, 1} of ``scenes/example_2.py``, friction N(22°, 2°), cohesion
N(20 kPa, 5 kPa), correlated −0.3, seed 1, ``--samples`` of them; two free blocks, 12 unknowns)
and the 15 probes of ``kgm.evaluate(Example I, [0, 1], "dda")``'s bisection (as
``kgm.judges.fused`` settles them). They are built once, in this checkout, and pickled; each
child process then settles every member in the checkout it is given (``ddatai.start.settle``,
the first limit-equilibrium programs solved side by side first, as ``settle_many`` does, outside
the timing) and reports each stage's CPU time (this process's, the machine being shared), its
held and released blocks, its solves and the settled vertices. With ``--vs``, this checkout and
the other alternate in fresh processes, ``--repeats`` times each; printed: per checkout the
median over the repeats of the median stage of a held and of a released member, the total, and
whether every member's held and released blocks are the same in both (and how far the settled
vertices differ); and the stages of the members that the return mapping released (after its
solves). Threads pinned (BLAS, Taichi one each).
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PINNED = {k: "1" for k in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "TI_CPU_MAX_NUM_THREADS")}

BUILD = r"""
import dataclasses, pickle, sys
sys.path.insert(0, {root!r})
import ddatai as dd
from ddatai.io.scenefile import build_scene
from ddatai.parallel import ScriptFunction
from kgm.build import prepare
from kgm.judges.run import RunPlan, sub_scene
from kgm.settings import DdaSettings, Settings
from kgm.studies.sampling import read_variables, sample_variables
from pathlib import Path
root = Path({root!r})
variables, correlation = read_variables(root / "docs" / "kgm" / "example_2_vars.toml")
samples = sample_variables(variables, {samples}, seed=1, correlation=correlation)
build = ScriptFunction(str(root / "scenes" / "example_2.py"))
settings = Settings(dda=DdaSettings(params=dd.Params(dt=0.0013, penalty_ratio=1.0, kernels="fused")))
members = []
for i in range({samples}):
    scene, params = build_scene(build, friction=float(samples["friction"][i]), cohesion=float(samples["cohesion"][i]))
    problem = prepare(scene, settings=settings, params=params)
    plan = RunPlan.of(problem.system, frozenset({{0, 1}}), settings.dda, problem.params)
    sub, ids = sub_scene(problem.scene, problem.system, frozenset({{0, 1}}), free_neighbours=plan.free_neighbours)
    members.append(("example_2", sub, plan.params))
# Example I's probes: the models kgm settles in its bisection (numpy kernels: the same stages)
import ddatai.limit_batch as lb
import kgm
from scenes import example_1
caught = []
settle_many = lb.settle_many
def catch(models, states=None):
    caught.extend(models)
    return settle_many(models, states)
lb.settle_many = catch
scene, params = example_1.build()
kgm.evaluate(scene, [0, 1], "dda", params=dataclasses.replace(params, kernels="numpy"))
members += [("example_1", m, None) for m in caught]
pickle.dump(members, open({out!r}, "wb"))
print(len(members))
"""

TIME = r"""
import json, pickle, sys, time
sys.path.insert(0, {root!r})
from ddatai.limit_batch import screened_ahead
from ddatai.model import build_model
from ddatai.start import settle
from ddatai.step import Stepper
members = pickle.load(open({members!r}, "rb"))
models = [(kind, m if p is None else build_model(m, p)) for kind, m, p in members]
settle(Stepper(models[0][1]), models[0][1].initial_state())  # imports, first calls
rows = []
for kind, m in models:
    st, s0 = Stepper(m), m.initial_state()
    with screened_ahead([st], [s0]):
        t = time.process_time()
        state, rec = settle(st, s0)
        cpu = time.process_time() - t
    rows.append(dict(kind=kind, ms=1e3 * cpu, held=int(rec.held), released=int(rec.released), solves=int(rec.solves),
                     xy=state.vertex_xy.tolist()))
print(json.dumps(rows))
"""


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--samples", type=int, default=80)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--vs", default="", help="another checkout, timed alternately with this one")
    a = ap.parse_args()
    env = {**os.environ, **PINNED}
    roots = [str(ROOT)] + ([str(Path(a.vs).resolve())] if a.vs else [])
    with tempfile.TemporaryDirectory() as tmp:
        members = str(Path(tmp) / "members.pkl")
        subprocess.run([sys.executable, "-c", BUILD.format(root=str(ROOT), samples=a.samples, out=members)],
                       check=True, env=env, cwd=ROOT, capture_output=True)
        got = {r: [] for r in roots}
        for rep in range(a.repeats):
            for r in (roots if rep % 2 == 0 else roots[::-1]):
                out = subprocess.run([sys.executable, "-c", TIME.format(root=r, members=members)], check=True,
                                     env=env, cwd=r, capture_output=True, text=True).stdout
                got[r].append(json.loads(out.strip().splitlines()[-1]))
    import numpy as np

    print(f"load {os.getloadavg()[0]:.1f}; CPU time of each stage; medians over {a.repeats} repeats")
    print("| checkout | members | held: median stage ms | released: median stage ms | total ms | solves |")
    print("|---|---|---|---|---|---|")
    for kind in ("example_2", "example_1"):
        for r in roots:
            runs = [[x for x in rows if x["kind"].startswith(kind)] for rows in got[r]]
            held = [statistics.median([x["ms"] for x in rows if not x["released"]] or [0.0]) for rows in runs]
            rel = [statistics.median([x["ms"] for x in rows if x["released"]] or [0.0]) for rows in runs]
            print(f"| {r} | {kind}: {len(runs[0])} ({sum(not x['released'] for x in runs[0])} held) | "
                  f"{statistics.median(held):.2f} | {statistics.median(rel):.2f} | "
                  f"{statistics.median(sum(x['ms'] for x in rows) for rows in runs):.0f} | "
                  f"{sum(x['solves'] for x in runs[0])} |")
    # the members that the return mapping released after its stalls (the screen's take no solve)
    print("| checkout | released after solves: members | their median stage ms (median of repeats) | their total ms |")
    print("|---|---|---|---|")
    for r in roots:
        runs = [[x for x in rows if x["released"] and x["solves"]] for rows in got[r]]
        print(f"| {r} | {len(runs[0])} | {statistics.median(statistics.median([x['ms'] for x in rows] or [0.0]) for rows in runs):.2f} | "
              f"{statistics.median(sum(x['ms'] for x in rows) for rows in runs):.0f} |")
    if a.vs:
        x, y = got[roots[0]][0], got[roots[1]][0]
        same = all((p["held"], p["released"]) == (q["held"], q["released"]) for p, q in zip(x, y))
        dxy = max(float(np.abs(np.array(p["xy"]) - np.array(q["xy"])).max()) for p, q in zip(x, y))
        print(f"held and released blocks the same on every member: {same}; settled vertices differ by at most {dxy:.1e} m")


if __name__ == "__main__":
    main()
