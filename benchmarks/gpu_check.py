"""The fused engine on a CUDA GPU: its twin tests, and how many DDA judgements a second it runs.

    python benchmarks/gpu_check.py [--members 4096] [--timeout 200]

1. ``pytest -m gpu tests/test_fused.py`` (the fused engine on CUDA against the NumPy path).
2. Example II's critical group (blocks 0 and 1 of ``scenes/example_2.py``) judged by DDA at
   ``--members`` friction angles drawn from its study's N(22°, 2°) (cohesion 20 kPa): each
   member its own sub-model, settled by the equilibrium stage on the CPU (16 distinct angles,
   their settled states shared by the members nearest in angle), then every member's run in
   one launch of the fused engine, one thread a member, with a judgement's stops; on CUDA,
   then on the CPU for the same members. Prints judgements per second of the launch (the runs),
   and of the whole pipeline (the stage and the sub-models included, per member).

Takes about three minutes on a GPU machine, most of it the kernel's first compile for CUDA.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

ONE = r"""
import json, math, sys, time
sys.path[:0] = [{root!r}]
import numpy as np
from ddatai.parallel import ScriptFunction
from ddatai.model import build_model
from ddatai.start import settle
from ddatai.step import Stepper
from ddatai.fused import engine
from ddatai.fused.pack import Member
from kgm.blocks import build_block_system
from kgm.judgement import group_size, run_params, sub_scene
from kgm.settings import DdaSettings
arch, n = {arch!r}, {n}
build = ScriptFunction({script!r})
settings = DdaSettings()
rng = np.random.default_rng(1)
angles = rng.normal(22.0, 2.0, n)
grid = np.linspace(angles.min(), angles.max(), 16)
t0 = time.perf_counter()
states = {{}}
for phi in grid:
    scene, params = build(friction=float(phi), cohesion=20e3)
    system = build_block_system(scene)
    sub, ids = sub_scene(scene, system, frozenset({{0, 1}}))
    model = build_model(sub, run_params(params, settings))
    states[float(phi)] = (model, settle(Stepper(model), model.initial_state())[0], ids, system)
stage = (time.perf_counter() - t0) / len(grid)
delta = settings.displacement_ratio * group_size(states[float(grid[0])][3], frozenset({{0, 1}}))
duration = math.sqrt(2.0 * delta / settings.acceleration_resolution)
members = []
for phi in angles:
    model, state, ids, _ = states[float(grid[np.argmin(np.abs(grid - phi))])]
    members.append(Member(model=model, state=state, t_end=duration, stop_at=settings.stop_ratio * delta,
                          rest_limit=settings.rest_ratio * delta / duration, rest_steps=settings.rest_steps,
                          group=(ids.index(0), ids.index(1))))
engine.run(members[:2], arch=arch)  # the kernel's compile (or load from the cache)
t0 = time.perf_counter()
out = engine.run(members, arch=arch)
wall = time.perf_counter() - t0
print(json.dumps(dict(arch=arch, members=n, wall=wall, per_second=n / wall, stage_s=stage,
                      statuses={{s: sum(o.status == s for o in out) for s in {{o.status for o in out}}}},
                      steps=float(np.mean([len(o.history) for o in out])))))
"""


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--members", type=int, default=4096)
    ap.add_argument("--timeout", type=int, default=200)
    a = ap.parse_args()
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    t0 = time.perf_counter()
    tests = subprocess.run([sys.executable, "-m", "pytest", "-q", "-m", "gpu", "tests/test_fused.py", "-p",
                            "no:cacheprovider"], cwd=ROOT, env=env, capture_output=True, text=True,
                           timeout=a.timeout)
    print(tests.stdout.strip().splitlines()[-1] if tests.stdout.strip() else tests.stderr[-2000:])
    print(f"twin tests on CUDA: rc {tests.returncode}, {time.perf_counter() - t0:.0f} s")
    for arch in ("cuda", "cpu"):
        code = ONE.format(root=str(ROOT), arch=arch, n=a.members, script=str(ROOT / "scenes" / "example_2.py"))
        proc = subprocess.run([sys.executable, "-c", code], cwd=ROOT, env=env, capture_output=True, text=True,
                              timeout=a.timeout)
        if proc.returncode != 0:
            print(f"{arch}: failed\n{proc.stderr[-3000:]}")
            continue
        r = json.loads(proc.stdout.strip().splitlines()[-1])
        print(f"{arch}: {r['members']} judgements in {r['wall']:.2f} s: {r['per_second']:.0f} a second "
              f"(the runs; {r['steps']:.0f} steps each on average; verdicts {r['statuses']}); the stage "
              f"{1e3 * r['stage_s']:.1f} ms a member on the CPU, so the whole pipeline "
              f"{1.0 / (r['stage_s'] + r['wall'] / r['members']):.0f} a second on one core")


if __name__ == "__main__":
    main()
