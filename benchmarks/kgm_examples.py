"""The paper's two examples under the three evaluators, in the paper's table layout.

    python benchmarks/kgm_examples.py [--no-dda] [--gif DIR]

For each example: the critical key group found by the Sarma-KGM search, then its factor of
safety, critical friction angle and verdict with the rigid (KGM), Sarma (SKGM) and DDA
(developed method) evaluators, the DDA runs and their wall time, and the per-step time of the
DDA sub-model against the whole slope. Prints Markdown (the tables of docs/kgm/guide.md).

``--gif DIR`` also draws the DDA run of each paper example's key group at the scene's strength
(``DIR/example_1.gif``, ``DIR/example_2.gif``; the documentation's are ``--gif docs/kgm``), titled
with the factor of safety and critical friction angle of the same evaluation as the table, so
that the documentation's tables and pictures come from one run of this script.
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
    ap.add_argument("--gif", metavar="DIR", help="also write DIR/example_1.gif and DIR/example_2.gif")
    args = ap.parse_args()
    if args.gif and args.no_dda:
        ap.error("--gif draws the DDA runs: it cannot be combined with --no-dda")
    methods = ("rigid", "sarma") if args.no_dda else ("rigid", "sarma", "dda")
    settings = kgm.Settings(dda=kgm.DdaSettings(compare_whole=True))
    print(f"machine: {platform.processor() or platform.machine()}, Python {platform.python_version()}\n")
    gifs = {"Example I": "example_1.gif", "Example II": "example_2.gif"}
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
            if args.gif and name in gifs:
                path = Path(args.gif) / gifs[name]
                write_dda_gif(path, scene, params, group, rows[-1], settings)
                print(f"\nwrote {path}")
        print()


def write_dda_gif(path: Path, scene, params, group, row, settings) -> None:
    """The DDA run of ``group`` at the scene's strength, titled with ``row``'s (the DDA
    evaluation's) factor of safety, critical friction angle and verdict."""
    import numpy as np

    from ddatai.render import write_gif
    from kgm.blocks import build_block_system
    from kgm.dda import judge

    dt = params.dt if params is not None and params.dt is not None else 0.005
    judgement = row.dda.judgement
    every = max(1, int(judgement.duration / dt / 80))  # about 80 frames
    _, res, ids = judge(scene, build_block_system(scene), frozenset(group), settings=settings.dda,
                        params=params, record_every=every)
    labels = np.array([0 if b in group else -1 for b in ids])
    title = (f"KGM + DDA: group {sorted(group)}, {row.verdict}, FS {row.fs:.3f}, "
             f"critical friction {row.critical_friction:.2f}°")  # the GIF font has no φ
    path.parent.mkdir(parents=True, exist_ok=True)
    write_gif(res, path, labels=labels, label_names=["critical key group"], title=title)


if __name__ == "__main__":
    main()
