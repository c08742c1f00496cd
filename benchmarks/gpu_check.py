"""The fused engine on a CUDA GPU: how many DDA judgements a second it runs, and its twin tests.

    pip install -e .[test] && python benchmarks/gpu_check.py [--members 1000,10000] [--budget 270]

1. Example II's critical group (blocks 0 and 1 of ``scenes/example_2.py``, its sub-model of 3
   blocks) judged by DDA at ``--members`` friction angles drawn from its study's N(22°, 2°)
   (cohesion 20 kPa), each with a judgement's stops (4δ, at rest, T). The members' equilibrium
   stages run on the CPU in NumPy, once for each of 16 angles spanning the draw (a member takes
   the settled state of the angle nearest its own), then every member runs in one launch of
   the fused engine on CUDA, one thread a member. Prints, for each size, the launch's
   judgements a second, and what the whole pipeline would give with one NumPy stage a member
   on one CPU core (the study's stage is not in the kernel).
2. ``pytest -m gpu tests/test_fused.py``, beside 1. in its own process: the fused engine on
   CUDA against the NumPy path (Example I at 8°, a dropped 3 × 3 grid).

Each of the two processes compiles the CUDA kernel (one CPU thread each, side by side: the wall
time of one compile). Everything stops inside ``--budget`` seconds and prints a compact table.
``--cpu`` adds the same members on the CPU for comparison (its own compile: minutes).
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

ONE = r"""
import json, math, sys, time
t_start = time.perf_counter()
sys.path[:0] = [{root!r}]
import numpy as np
from ddatai.parallel import ScriptFunction
from ddatai.model import build_model
from ddatai.start import settle
from ddatai.step import Stepper
from ddatai.fused import engine
from ddatai.fused.pack import Member
from kgm.build import build_block_system
from kgm.judges.run import RunPlan, sub_scene
from kgm.settings import DdaSettings
arch, sizes = {arch!r}, {sizes!r}
build = ScriptFunction({script!r})
settings = DdaSettings()
group = frozenset({{0, 1}})
rng = np.random.default_rng(1)
angles = rng.normal(22.0, 2.0, max(sizes))
grid = np.linspace(angles.min(), angles.max(), 16)
t0 = time.perf_counter()
states = {{}}
for phi in grid:
    scene, params = build(friction=float(phi), cohesion=20e3)
    system = build_block_system(scene)
    plan = RunPlan.of(system, group, settings, params)
    sub, ids = sub_scene(scene, system, group)
    model = build_model(sub, plan.params)
    states[float(phi)] = (model, settle(Stepper(model), model.initial_state())[0], ids, plan)
stage = (time.perf_counter() - t0) / len(grid)
def members(n):
    out = []
    for phi in angles[:n]:
        model, state, ids, plan = states[float(grid[np.argmin(np.abs(grid - phi))])]
        out.append(Member(model=model, state=state, t_end=plan.duration, stop_at=plan.stop_at,
                          rest_limit=plan.rest_speed or -1.0, rest_steps=plan.rest_steps,
                          group=(ids.index(0), ids.index(1))))
    return out
t0 = time.perf_counter()
engine.run(members(2), arch=arch)  # the kernel's compile (or its load from the offline cache)
compile_s = time.perf_counter() - t0
print(json.dumps(dict(kind="compile", arch=arch, seconds=compile_s, stage_s=stage)), flush=True)
for n in sizes:
    ms = members(n)
    t0 = time.perf_counter()
    out = engine.run(ms, arch=arch)
    wall = time.perf_counter() - t0
    print(json.dumps(dict(kind="run", arch=arch, members=n, wall=wall, per_second=n / wall, stage_s=stage,
                          statuses={{s: sum(o.status == s for o in out) for s in sorted({{o.status for o in out}})}},
                          steps=float(np.mean([len(o.history) for o in out])))), flush=True)
"""


def _lines(proc_out: str) -> list:
    rows = []
    for line in proc_out.splitlines():
        line = line.strip()
        if line.startswith("{"):
            try:
                rows.append(json.loads(line))
            except json.JSONDecodeError:
                pass
    return rows


def _study(arch: str, sizes: list, timeout: float, env: dict) -> list:
    code = ONE.format(root=str(ROOT), arch=arch, sizes=sizes, script=str(ROOT / "scenes" / "example_2.py"))
    try:
        proc = subprocess.run([sys.executable, "-c", code], cwd=ROOT, env=env, capture_output=True, text=True,
                              timeout=max(timeout, 1))
        rows = _lines(proc.stdout)
        if proc.returncode != 0:
            print(f"{arch}: rc {proc.returncode}\n{proc.stderr[-2500:]}")
    except subprocess.TimeoutExpired as err:
        out = err.stdout.decode() if isinstance(err.stdout, bytes) else (err.stdout or "")
        rows = _lines(out)
        print(f"{arch}: stopped at the budget ({timeout:.0f} s)")
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--members", default="1000,10000", help="comma-separated launch sizes")
    ap.add_argument("--budget", type=float, default=270.0, help="seconds for everything")
    ap.add_argument("--cpu", action="store_true", help="also on the CPU (its own compile)")
    a = ap.parse_args()
    sizes = [int(s) for s in a.members.split(",")]
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    t_all = time.perf_counter()

    def left() -> float:
        return a.budget - (time.perf_counter() - t_all)

    try:
        gpu = subprocess.run(["nvidia-smi", "--query-gpu=name,memory.total", "--format=csv,noheader"],
                             capture_output=True, text=True, timeout=20).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        gpu = "no nvidia-smi"
    print(f"GPU: {gpu}; CPUs: {os.cpu_count()}; Python {sys.version.split()[0]}")
    # the twin tests beside the study: each process compiles the CUDA kernel (a compile is
    # one CPU thread, so two side by side take no longer than one), then each goes on alone
    tests = subprocess.Popen([sys.executable, "-m", "pytest", "-q", "-m", "gpu", "tests/test_fused.py", "-p",
                              "no:cacheprovider"], cwd=ROOT, env=env, stdout=subprocess.PIPE,
                             stderr=subprocess.PIPE, text=True, start_new_session=True)
    t0 = time.perf_counter()
    rows = []
    for arch in ("cuda", "cpu") if a.cpu else ("cuda",):
        rows += _study(arch, sizes, left() - 10, env)
    tests_line, tests_rc = "stopped at the budget", None
    try:
        out, err = tests.communicate(timeout=max(left() - 3, 1))
        lines = out.strip().splitlines()
        tests_line, tests_rc = (lines[-1] if lines else err[-500:]), tests.returncode
        if tests.returncode != 0:
            print(out[-2500:], err[-1500:])
    except subprocess.TimeoutExpired:
        os.killpg(tests.pid, signal.SIGKILL)  # pytest and the test's own CUDA process
        tests.communicate()
    print("\n| what | arch | members | wall s | judgements/s (launch) | pipeline/s, 1 CPU core for the stage | "
          "mean steps | verdicts |")
    print("|---|---|---|---|---|---|---|---|")
    for r in rows:
        if r["kind"] == "compile":
            print(f"| first launch (compile or cache load) | {r['arch']} | 2 | {r['seconds']:.1f} | | "
                  f"stage {1e3 * r['stage_s']:.1f} ms a member | | |")
        else:
            pipe = 1.0 / (r["stage_s"] + r["wall"] / r["members"])
            print(f"| Example II group, N(22°, 2°) | {r['arch']} | {r['members']} | {r['wall']:.2f} | "
                  f"{r['per_second']:.0f} | {pipe:.0f} | {r['steps']:.0f} | {r['statuses']} |")
    print(f"| twin tests (pytest -m gpu tests/test_fused.py), done by | cuda | | {time.perf_counter() - t0:.0f} | "
          f"{tests_line} (rc {tests_rc}) | | | |")
    print(f"\ntotal {time.perf_counter() - t_all:.0f} s")


if __name__ == "__main__":
    main()
