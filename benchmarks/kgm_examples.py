"""The paper's two examples and the footwall cases under the three evaluators, side by side.

    python benchmarks/kgm_examples.py [--no-dda] [--gif DIR] [--only paper|footwall]

For each example: the critical key group found by the Sarma-KGM search, then its factor of
safety, critical friction angle and verdict with the rigid (KGM), Sarma (SKGM) and DDA
(developed method) evaluators, the DDA runs and their wall time, and the per-step time of the
DDA sub-model against the whole slope. Prints Markdown (the tables of docs/kgm/guide.md).

The footwall cases (`scenes/footwall.py`, docs/kgm/footwall.md): planar slab sliding,
ploughing and bilinear slab failure, each with its closed-form factor of safety (computed by
hand from the geometry, eqs. F1–F8) beside the rigid, Sarma and DDA evaluators of the group.

``--gif DIR`` also draws the DDA run of each paper example's key group at the scene's strength
(``DIR/example_1.gif``, ``DIR/example_2.gif``; the documentation's are ``--gif docs/kgm``), titled
with the factor of safety and critical friction angle of the same evaluation as the table, so
that the documentation's tables and pictures come from one run of this script.
"""

import argparse
import math
import platform
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # the repository root: scenes/
import kgm  # noqa: E402
from ddatai.io.scenefile import build_scene  # noqa: E402
from scenes import example_1, example_2, footwall, kgm_slope  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--no-dda", action="store_true", help="limit equilibrium only")
    ap.add_argument("--gif", metavar="DIR", help="also write DIR/example_1.gif and DIR/example_2.gif")
    ap.add_argument("--only", choices=("paper", "footwall"), help="only the paper's examples or the footwall cases")
    args = ap.parse_args()
    if args.gif and args.no_dda:
        ap.error("--gif draws the DDA runs: it cannot be combined with --no-dda")
    methods = ("rigid", "sarma") if args.no_dda else ("rigid", "sarma", "dda")
    print(f"machine: {platform.processor() or platform.machine()}, Python {platform.python_version()}\n")
    if args.only != "footwall":
        paper_examples(methods, args, kgm.Settings(dda=kgm.DdaSettings(compare_whole=True)))
    if args.only != "paper":
        footwall_cases(methods)


def paper_examples(methods, args, settings) -> None:
    """The seed paper's examples and the jointed slope: the critical group of the Sarma search
    under each evaluator, in the paper's table layout."""
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


def footwall_cases(methods) -> None:
    """Each footwall case: its closed form (F1, or the two-block root F3–F7; the rigid F8) and
    the factor of safety and critical friction of the rigid, Sarma and DDA evaluators of its
    group, with the governing limit-equilibrium mode; then the DDA runs and their time."""
    names = {"rigid": "rigid (KGM)", "sarma": "Sarma (SKGM)", "dda": "DDA (strength reduction)"}
    print("**Footwall slopes** (scenes/footwall.py, docs/kgm/footwall.md): factor of safety (critical "
          "friction angle)\n")
    head = "| case | closed form | " + " | ".join(names[m] for m in methods) + " | governing mode (Sarma) |"
    print(head)
    print("|" + "---|" * (head.count("|") - 1))
    notes = []
    for case in footwall.CASES:
        scene, params = footwall.build(case)
        group = [footwall.SLAB] if case == "planar" else [footwall.P, footwall.A]
        closed = footwall.closed_form_fs(case)
        rigid_closed = footwall.rigid_fs(case)
        cells, gov = [], ""
        for m in methods:
            t0 = time.perf_counter()
            g = kgm.evaluate(scene, group, m, params=params)
            wall = time.perf_counter() - t0
            fs = "no mode (inf)" if math.isinf(g.fs) else f"{g.fs:.4f} ({g.critical_friction:.2f}°)"
            cells.append(fs)
            if m == "sarma":
                gov = g.mode.kind.value
            if m == "dda":
                notes.append(f"{case}: DDA {len(g.dda.runs)} runs, {sum(r.steps for r in g.dda.runs)} steps, "
                             f"{wall:.1f} s; FS {100 * (g.fs / closed - 1):+.1f} % of the closed form")
        ref = f"{closed:.4f}" + ("" if rigid_closed == closed else
                                 f" (rigid {'inf' if math.isinf(rigid_closed) else f'{rigid_closed:.4f}'})")
        print(f"| {case} | {ref} | " + " | ".join(cells) + f" | {gov} |")
    for line in notes:
        print(f"\n{line}")
    print()


def write_dda_gif(path: Path, scene, params, group, row, settings) -> None:
    """The DDA run of ``group`` at the scene's strength, titled with ``row``'s (the DDA
    evaluation's) factor of safety, critical friction angle and verdict."""
    import numpy as np

    from ddatai.render import write_gif
    from kgm import build_block_system, judge

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
