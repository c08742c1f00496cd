"""Console command ``kgm``.

    kgm analyze SCENE.py [--method rigid|sarma|dda] [--progressive] [--compare] [--contact-gap M] [--gif PATH]
    kgm wedge INPUT.toml [--png PATH] [--gif PATH] [--stereonet PATH] [--vtp PATH] [--csv PATH]

SCENE.py is a scene script with ``build()`` returning a `ddatai.Scene` or ``(scene, params)``
(the convention of ``scenes/``). Prints the block types, the candidate key groups (least safe
first) and the critical group; ``--compare`` adds the paper-layout table of the critical group
under all three evaluators; ``--gif`` draws the scene with the critical group highlighted
(for ``dda``: its simulated motion) with `ddatai.render.write_gif`. ``kgm wedge`` analyses a
3D wedge of a rock slope from a TOML file (`kgm.wedges.cli`, docs/kgm/wedge.md).

    kgm study SCENE.py --vars VARS.toml [--sampling monte-carlo|latin-hypercube|subset|importance] ...

(``kgm probabilistic``, the same command): the probability of failure with uncertain inputs
(`kgm.probabilistic`); ``--sampling subset`` or ``importance`` for small probabilities
(docs/kgm/reliability.md), with ``--plot-levels`` and ``--plot-convergence`` pictures.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from typing import Optional, Sequence

import numpy as np

from .analysis import analyze, evaluate
from .build import prepare
from .judges.run import RunPlan, judge
from .kinds import (LIMIT_EQUILIBRIUM, METHOD_NAMES, METHODS, RARE_SAMPLINGS, SAMPLINGS, BlockState, Method, RunEnd,
                    Sampling)
from .report import format_paper_table
from .settings import DdaSettings, Settings
from .studies.probabilistic import probabilistic
from .studies.sampling import read_variables


def load_scene(path: str, joints: Optional[str] = None):
    """Run a scene script's ``build()`` (`ddatai.io.scenefile`, the loader of ``ddatai run``), or
    read a DXF section with its ``joints`` TOML file; returns (scene, params or None). A broken
    script is a `ValueError` with one line."""
    from ddatai.io.scenefile import build_scene, load_scene_script

    return build_scene(load_scene_script(path, joints=joints))


def _dda_progress(err):
    """A line on stderr as each DDA run ends (a DDA analysis makes tens of runs)."""
    count = [0]

    def show(j) -> None:
        count[0] += 1
        if j.friction is not None:
            strength = f"φ = {j.friction:.2f}°"
        elif j.reduction != 1.0:
            strength = f"strength / {j.reduction:.3f}"
        else:
            strength = "the scene's strength"
        verdict = "stable" if j.stable else "unstable"
        print(f"  DDA run {count[0]} at {strength}: {verdict}, moved {j.displacement:.3g} m in "
              f"{j.simulated:.3g} s ({j.steps} steps, {j.wall_time:.1f} s)", file=err, flush=True)

    return show


def scene_frame(scene):
    """The scene as one-frame `ddatai.Results` (for drawing a limit-equilibrium result without
    running a simulation)."""
    from ddatai.results import STEP_DTYPE, Results

    xy = np.concatenate([s.vertices for s in scene.blocks])
    counts = [len(s.vertices) for s in scene.blocks]
    offset = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
    nb = scene.n_blocks
    centroid = np.array([s.vertices.mean(axis=0) for s in scene.blocks])
    support = {}  # the water table and the bolts, drawn where the scene has them
    if scene.water is not None and scene.water.xy is not None:
        support["water_table"] = scene.water.xy
    if scene.bolts:
        support["bolt_xy"] = np.array([[(b.xy1, b.xy2) for b in scene.bolts]], dtype=float)
        support["bolt_force"] = np.array([[b.pretension for b in scene.bolts]], dtype=float)
        support["bolt_broken"] = np.zeros((1, len(scene.bolts)), bool)
    return Results(time=np.zeros(1), centroid=centroid[None], rotation=np.zeros((1, nb)),
                   velocity=np.zeros((1, nb, 2)), angular_velocity=np.zeros((1, nb)),
                   stress=np.zeros((1, nb, 3)), vertices=xy[None], vertex_offset=offset,
                   block_fixed=np.array([s.fixed for s in scene.blocks]),
                   measured=np.zeros((1, 0, 2)), contact_offset=np.zeros(2, np.int64),
                   contact_xy=np.zeros((0, 2)), contact_state=np.zeros(0, np.int8),
                   steps=np.zeros(0, dtype=STEP_DTYPE), **support)


def write_result_gif(path: str, scene, report, params=None, settings=None) -> None:
    """Draw the analysis: the critical group highlighted (progressive: every removed group by
    its round); for a DDA analysis, the simulated motion of the critical group's sub-model."""
    try:
        from ddatai.render import write_gif
    except ImportError:
        raise RuntimeError("--gif needs ddatai.render (write_gif), which this ddatai does not have") from None
    settings = settings or Settings()
    crit = report.critical
    if report.method == Method.DDA and crit is not None:
        # the run of the verdict again, recorded: the analysis's problem (its contact gap) and plan
        problem = prepare(scene, settings=settings, params=params)
        plan = RunPlan.of(problem.system, crit.blocks, settings.dda, params)
        dt = plan.params.dt if plan.params.dt is not None else 0.005
        every = max(1, int(crit.dda.judgement.duration / dt / 80))
        _, res, ids = judge(problem.scene, problem.system, crit.blocks, settings=settings.dda, params=params,
                            record_every=every)
        labels = np.array([0 if b in crit.blocks else -1 for b in ids])
        title = f"KGM + DDA: group {sorted(crit.blocks)}, {crit.verdict} (FS {crit.fs:.2f})"
        write_gif(res, path, labels=labels, label_names=["critical key group"], title=title)
        return
    res = scene_frame(scene)
    labels = np.full(scene.n_blocks, -1)
    if report.removed:
        for i, g in enumerate(report.removed):
            labels[sorted(g)] = i
        names = [f"removed in round {i + 1}" for i in range(len(report.removed))]
        title = f"progressive {report.method}: {len(report.removed)} groups removed"
    elif crit is not None and crit.block_modes:
        # a toppling group: each block coloured by its state at limit equilibrium
        states = [BlockState.TOPPLING, BlockState.SLIDING, BlockState.STABLE]
        for b, state in crit.block_modes.items():
            labels[b] = states.index(state)
        names = [f"{state.value} (critical group)" for state in states]
        title = (f"{report.method}: {crit.mode.kind.value} of {len(crit.blocks)} blocks, FS {crit.fs:.2f} "
                 f"({crit.verdict})")
    else:
        if crit is not None:
            labels[sorted(crit.blocks)] = 0
        names = ["critical key group"]
        title = (f"{report.method}: group {sorted(crit.blocks)}, FS {crit.fs:.2f} ({crit.verdict})"
                 if crit is not None else f"{report.method}: no key group")
    write_gif(res, path, labels=labels, label_names=names, fps=1, title=title)


def _print_report(rep, out) -> None:
    types = ", ".join(f"{b}:{t}" for b, t in sorted(rep.block_types.items()))
    print(f"method: {rep.method}   block types: {types}", file=out)
    print("", file=out)
    print(rep.table() if rep.groups else "no key group", file=out)
    crit = rep.critical
    if crit is not None:
        print("", file=out)
        print(f"critical key group {sorted(crit.blocks)}: FS {crit.fs:.3f}, critical friction "
              f"{crit.critical_friction:.2f}°, mode {crit.mode.kind.value}, {crit.verdict}", file=out)
        if crit.sarma_above_dda is not None:
            above = "inf" if math.isinf(crit.sarma_above_dda) else f"{100 * crit.sarma_above_dda:.1f}"
            print(f"  Sarma above DDA by {above} % (Sarma {crit.screening_fs:.3f}): DDA's factor "
                  f"{crit.fs:.3f} governs", file=out)
        for line in crit.surface:
            pts = " -> ".join(f"({x:.2f}, {y:.2f})" for x, y in line)
            print(f"  failure surface: {pts}", file=out)
        if crit.dda is not None:
            d = crit.dda
            j = d.judgement
            ran = (f"was at rest after {j.simulated:.2f} s of T = {j.duration:.2f} s, {j.displacement:.4f} m "
                   f"from its start" if j.end is RunEnd.AT_REST else
                   f"moved {j.displacement:.4f} m in {j.simulated:.2f} s")
            print(f"  DDA: {len(d.runs)} runs, {d.wall_time:.1f} s; at the scene's strength the group {ran} "
                  f"(criterion {j.threshold:.4f} m); "
                  f"sub-model {j.model_blocks} of {j.scene_blocks} blocks ({j.moving_blocks} free)", file=out)
            if d.timing is not None:
                t = d.timing
                print(f"  time per step: sub-model {t.sub_step_time * 1e3:.2f} ms, whole slope "
                      f"{t.whole_step_time * 1e3:.2f} ms ({100 * t.saving:.0f} % saved)", file=out)
    if rep.removed:
        print("", file=out)
        for i, (g, h) in enumerate(zip(rep.removed, rep.history)):
            print(f"round {i + 1}: removed {sorted(g)} (FS {h.fs:.3f})", file=out)
        last = rep.history[-1] if len(rep.history) > len(rep.removed) else None
        print("then stable" + (f": least safe group {sorted(last.blocks)} FS {last.fs:.3f}" if last else
                               ": no key group left"), file=out)
    print(f"\nanalysis time {rep.wall_time:.2f} s", file=out)


def _seismic(text: str) -> tuple[float, float]:
    """'0.1' or '0.1,0.05' -> (kh, kv)."""
    try:
        parts = [float(v) for v in text.split(",")]
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected KH or KH,KV (numbers), got {text!r}") from None
    if len(parts) not in (1, 2):
        raise argparse.ArgumentTypeError(f"expected KH or KH,KV, got {text!r}")
    return (parts[0], parts[1] if len(parts) == 2 else 0.0)


def main(argv: Optional[Sequence[str]] = None, out=None) -> int:
    out = out or sys.stdout
    parser = argparse.ArgumentParser(prog="kgm", description="Key Group Method analysis of a ddatai scene")
    sub = parser.add_subparsers(dest="command", required=True)
    an = sub.add_parser("analyze", help="find and judge the key groups of a scene")
    an.add_argument("scene", help="scene script with build() -> Scene or (Scene, Params), or a SECTION.dxf")
    an.add_argument("--joints", metavar="TOML", help="a SECTION.dxf's material and joint layers")
    an.add_argument("--method", choices=METHOD_NAMES, default=Method.SARMA.value)
    an.add_argument("--progressive", action="store_true", help="remove unstable groups and repeat")
    an.add_argument("--seismic", metavar="KH[,KV]", type=_seismic,
                    help="pseudo-static seismic coefficients (kh towards +x, kv upwards) [-], rigid and sarma")
    an.add_argument("--compare", action="store_true",
                    help="also judge the critical group with all three evaluators (paper table)")
    an.add_argument("--compare-whole", action="store_true",
                    help="dda: time the sub-model against the whole slope")
    an.add_argument("--contact-gap", metavar="M", type=float, default=None,
                    help="blocks whose facing edges are at most this far apart are in contact [m] "
                         "(default: 1e-4 of the model's size)")
    an.add_argument("--gif", metavar="PATH", help="write a GIF of the result")
    an.add_argument("--force", action="store_true",
                    help="build the scene even when it looks larger than this machine can simulate")
    pr = sub.add_parser("probabilistic", aliases=["study"],
                        help="probability of failure with uncertain inputs (Monte Carlo, subset simulation, "
                             "importance sampling)")
    pr.add_argument("scene", help="scene script whose build(**sample) takes the variables as keyword arguments")
    pr.add_argument("--vars", required=True, metavar="TOML", help="variables file (distributions, correlation)")
    pr.add_argument("--n", type=int, default=1000,
                    help="samples (default 1000); subset: samples a level; importance: importance samples")
    pr.add_argument("--method", choices=METHOD_NAMES, default=Method.SARMA.value)
    pr.add_argument("--sampling", choices=SAMPLINGS, default=Sampling.MONTE_CARLO.value,
                    help="subset (subset simulation) and importance (FORM, then importance sampling) for small P_f")
    pr.add_argument("--p0", type=float, default=0.1, help="subset: conditional probability of a level (default 0.1)")
    pr.add_argument("--plot-levels", metavar="PATH",
                    help="subset/importance: draw the samples over the two variables that drive failure")
    pr.add_argument("--plot-convergence", metavar="PATH", help="subset/importance: draw P_f against evaluations")
    pr.add_argument("--seed", type=int, default=0)
    pr.add_argument("--group", metavar="IDS", help="judge this group (comma-separated block ids) in every sample")
    pr.add_argument("--workers", type=int, default=None,
                    help="local worker processes (default: this process for rigid and sarma, one per CPU for dda)")
    pr.add_argument("--scheduler", metavar="ADDRESS", help="run on a Dask cluster, e.g. tcp://host:8786")
    pr.add_argument("--out", metavar="CSV", help="append samples to this file as they finish (and resume it)")
    pr.add_argument("--png", metavar="PATH", help="draw how often each block is in the critical group")
    from .wedges.cli import add_parser as add_wedge_parser

    add_wedge_parser(sub)
    args = parser.parse_args(argv)
    if args.command == "wedge":
        from .wedges.cli import run as run_wedge

        return run_wedge(args, out)
    if getattr(args, "force", False):
        from ddatai.cli import _allow_any_size

        _allow_any_size(args)
    if args.command in ("probabilistic", "study"):
        return _probabilistic(args, out)

    try:
        scene, params = load_scene(args.scene, getattr(args, "joints", None))
        settings = Settings(dda=DdaSettings(compare_whole=args.compare_whole, progress=_dda_progress(sys.stderr)),
                            contact_gap=args.contact_gap)
        rep = analyze(scene, method=args.method, progressive=args.progressive, settings=settings, params=params,
                      seismic=args.seismic)
        _print_report(rep, out)
        if args.compare and rep.critical is not None:
            t0 = time.perf_counter()
            methods = LIMIT_EQUILIBRIUM if args.seismic else METHODS   # dda: no k·W
            rows = [evaluate(scene, rep.critical.blocks, m, settings=settings, params=params, seismic=args.seismic)
                    if m != rep.method else rep.critical for m in methods]
            print("", file=out)
            print(format_paper_table(rows, title=f"group {sorted(rep.critical.blocks)}"), file=out)
            print(f"(comparison {time.perf_counter() - t0:.1f} s)", file=out)
        if args.gif:
            write_result_gif(args.gif, scene, rep, params, settings)
            print(f"wrote {args.gif}", file=out)
    except (ValueError, RuntimeError) as exc:
        print(f"kgm: error: {exc}", file=sys.stderr)
        return 2
    return 0


def _counter(err):
    """A line on stderr, rewritten, counting the evaluations of a subset or importance study
    (their number is not known in advance)."""

    def show(done, _total) -> None:
        if err.isatty():
            print(f"\r{done} evaluations", end="", file=err, flush=True)

    return show


def _print_rare(study, out) -> None:
    """The levels of a subset study, or the design point of an importance study."""
    if study.levels:
        print("level  FS threshold  P(next | level)  c.o.v.  gamma  acceptance  evaluations", file=out)
        for j, lv in enumerate(study.levels):
            print(f"{j:5d}  {lv.fs_threshold:12.4f}  {lv.probability:15.4f}  {lv.cov:6.3f}  {lv.gamma:5.2f}  "
                  f"{lv.acceptance:10.2f}  {lv.evaluations:11d}", file=out)
    dp = study.design_point
    if dp is not None:
        values = ", ".join(f"{k} = {v:.6g}" for k, v in dp.values.items())
        alpha = ", ".join(f"{k} {a:+.3f}" for k, a in sorted(dp.alpha.items(), key=lambda kv: -abs(kv[1])))
        print(f"design point (FORM, {dp.iterations} iterations, {dp.evaluations} evaluations"
              f"{'' if dp.converged else ', NOT converged'}): {values}; FS {dp.fs:.4f}", file=out)
        print(f"beta = {dp.beta:.4f} (FORM P_f = {dp.pf:.3g}); sensitivities alpha: {alpha}", file=out)


def _probabilistic(args, out) -> int:
    from ddatai.parallel import ScriptFunction

    def bar(done, total):
        if sys.stderr.isatty() or done == total:
            width = 30
            k = int(width * done / total)
            print(f"\r[{'#' * k}{'.' * (width - k)}] {done}/{total} samples", end="" if done < total else "\n",
                  file=sys.stderr, flush=True)

    try:
        variables, correlation = read_variables(args.vars)
        group = None if not args.group else [int(b) for b in args.group.split(",")]
        sampling = args.sampling
        if sampling == Sampling.SUBSET and args.p0 != 0.1:
            from .studies.rare import SubsetSampling

            sampling = SubsetSampling(p0=args.p0)
        rare = args.sampling in RARE_SAMPLINGS
        study = probabilistic(ScriptFunction(args.scene), variables, args.n, method=args.method,
                              sampling=sampling, seed=args.seed, correlation=correlation or None,
                              group=group, client=args.scheduler, workers=args.workers, out=args.out,
                              progress=_counter(sys.stderr) if rare else bar)
        print(study.summary(), file=out)
        if rare:
            _print_rare(study, out)
            for path, draw in ((args.plot_levels, study.plot_levels), (args.plot_convergence, study.plot_convergence)):
                if path:
                    draw(path)
                    print(f"wrote {path}", file=out)
            if args.out:
                print(f"evaluations in {args.out}", file=out)
            return 0
        print("FS quantiles 5/50/95 %: " + ", ".join(f"{v:.3f}" for v in study.fs_quantiles().values()), file=out)
        freq = study.block_frequency()
        top = sorted(freq.items(), key=lambda kv: -kv[1])[:10]
        print("blocks most often in the critical group: " + ", ".join(f"{b} ({f:.0%})" for b, f in top), file=out)
        if args.out:
            print(f"samples in {args.out}", file=out)
        if args.png:
            scene, _ = load_scene(args.scene)
            study.write_png(scene, args.png)
            print(f"wrote {args.png}", file=out)
    except (ValueError, RuntimeError, FileNotFoundError) as exc:
        print(f"kgm: error: {exc}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
