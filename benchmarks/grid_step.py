"""Time per DDA step on an n × n grid of unit blocks resting on a fixed base.

    python benchmarks/grid_step.py [--n 20] [--steps 40] [--warmup 5] [--dt 0.001] [--dynamic]

Prints the median wall time per step and its split into contact detection, assembly, solve
and update (each step's own record), after warm-up steps (kernels compiled). Blocks start in
contact (edge to edge), so every step carries the full contact set.
"""

import argparse
import platform
import sys
import time
from pathlib import Path

import numpy as np

import ddatai as dd
from ddatai.results import STEP_PHASES, step_wall_time

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # the repository root: scenes/
from scenes.stacked_grid import build  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=20)
    ap.add_argument("--steps", type=int, default=40)
    ap.add_argument("--warmup", type=int, default=5)
    ap.add_argument("--dt", type=float, default=0.001)
    ap.add_argument("--dynamic", action="store_true", help="dynamic run (default: static)")
    a = ap.parse_args()
    scene, params = build(a.n, gap=0.0, static=not a.dynamic, dt=a.dt)
    t0 = time.perf_counter()
    res = dd.simulate(scene, params=params, steps=a.warmup + a.steps, record_every=10 ** 9)
    wall = time.perf_counter() - t0
    s = res.steps[a.warmup:]
    total = step_wall_time(s)
    print(f"machine: {platform.machine()} {platform.processor() or ''} python {platform.python_version()}")
    print(f"{a.n}x{a.n} grid ({'dynamic' if a.dynamic else 'static'}): {scene.n_blocks - 1} free blocks, dt = {a.dt} s, "
          f"{a.steps} timed steps after {a.warmup} warm-up (run wall {wall:.1f} s)")
    print(f"contacts/step {np.median(s['contacts']):.0f}, open-close iterations/step "
          f"{np.median(s['oc_iterations']):.1f}, dt cuts {int(s['dt_cuts'].sum())}")
    print("| phase | median ms/step |\n|---|---|")
    for name in (f"t_{phase}" for phase in STEP_PHASES):
        print(f"| {name[2:]} | {1e3 * np.median(s[name]):.2f} |")
    print(f"| total | {1e3 * np.median(total):.2f} |")


if __name__ == "__main__":
    main()
