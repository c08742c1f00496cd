"""The paper's two examples under the three evaluators, in the paper's table layout.

    python benchmarks/kgm_examples.py [--no-dda]

For each example: the critical key group found by the Sarma-KGM search, then its factor of
safety, critical friction angle and verdict with the rigid (KGM), Sarma (SKGM) and DDA
(developed method) evaluators, the DDA runs and their wall time, and the per-step time of the
DDA sub-model against the whole slope. Prints Markdown (the README's tables).
"""

import argparse
import platform
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # the repository root: scenes/
import kgm  # noqa: E402
from ddatai.scenefile import build_scene  # noqa: E402
from scenes import example_1, example_2, kgm_slope  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--no-dda", action="store_true", help="limit equilibrium only")
    args = ap.parse_args()
    methods = ("rigid", "sarma") if args.no_dda else ("rigid", "sarma", "dda")
    settings = kgm.Settings(dda=kgm.DdaSettings(compare_whole=True))
    print(f"machine: {platform.processor() or platform.machine()}, Python {platform.python_version()}\n")
    for name, mod in (("Example I", example_1), ("Example II", example_2), ("jointed slope", kgm_slope)):
        scene, params = build_scene(mod)  # the loader of ddatai run and kgm analyze
        rep = kgm.analyze(scene, method="sarma", settings=settings)
        group = rep.critical.blocks
        rows = []
        for m in methods:
            t0 = time.perf_counter()
            rows.append(kgm.evaluate(scene, group, m, settings=settings, params=params))
            wall = time.perf_counter() - t0
            if m == "dda":
                d = rows[-1].dda
                j, t = d.judgement, d.timing
                dda_line = (f"DDA: {len(d.runs)} runs in {wall:.1f} s ({sum(r.steps for r in d.runs)} steps); "
                            f"sub-model {j.model_blocks} of {j.scene_blocks} blocks ({j.moving_blocks} free); "
                            f"per step {t.sub_step_time * 1e3:.2f} ms vs whole slope {t.whole_step_time * 1e3:.2f} ms "
                            f"({100 * t.saving:.0f} % saved); at the scene's strength: moved "
                            f"{j.displacement:.4f} m in {j.simulated:.2f} s (δ = {j.threshold:.4f} m, T = {j.duration:.2f} s)")
        print(kgm.format_paper_table(rows, title=f"**{name}**, key group {sorted(group)}"))
        if "dda" in methods:
            print(f"\n{dda_line}")
        print()


if __name__ == "__main__":
    main()
