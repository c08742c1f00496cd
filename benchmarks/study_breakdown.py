"""Where a sample of Example II's DDA-judged study spends its time, phase by phase, in one process.

    python benchmarks/study_breakdown.py [--n 200] [--batch 40] [--json out.json] [--root CHECKOUT]

The study of ``benchmarks/probabilistic.py`` (friction N(22°, 2°), cohesion N(20 kPa, 5 kPa),
correlated −0.3, seed 1, group {0, 1} of ``scenes/example_2.py``, Δt 1.3 ms, p = 1·E) taken
apart as ``kgm.studies.probabilistic._evaluate_batch`` and ``kgm.judges.fused.judge_fused`` run
it, each phase timed on its own: the screen (the scene built, prepared and judged by Sarma
limit equilibrium), the sub-model (``sub_scene`` and ``build_model``, or, where the checkout has
them, the sub-models a batch shares, ``kgm.judges.fused._submodel``), each member's
equilibrium stage (``ddatai.start.settle``: held or released, its solves), the packing of a
launch and the fused kernel's runs (``ddatai.fused.engine.run``, batches of ``--batch``
members: each member's steps and how its run ended). Where the stages run side by side
(`ddatai.side_by_side`), a member's stage time is its share of its batch's. Threads are pinned (BLAS and Taichi one
thread each); the fused kernel is loaded (from Taichi's offline cache) before anything is
timed, by default in this process's CPU seconds (``--clock wall``: wall time). Prints a table
and, with ``--json``, every member's figures. ``--root``: the checkout whose
``ddatai`` and ``kgm`` are timed (default this one; its scenes and variables are this one's).

The screen by limit equilibrium (``screen_le``: Sarma on the given group) is timed in every
checkout; a study that judges a given group by its DDA verdict alone no longer runs it
(`kgm.studies.probabilistic._screen`), and ``screens side by side`` exists only where the
stages' programs are solved side by side (`ddatai.limit_batch`).
"""

from __future__ import annotations

import argparse
import json
import os

for _k in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "TI_CPU_MAX_NUM_THREADS"):
    os.environ.setdefault(_k, "1")

import statistics  # noqa: E402
from contextlib import nullcontext  # noqa: E402
from functools import partial  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=200)
    ap.add_argument("--batch", type=int, default=40)
    ap.add_argument("--json", default="")
    ap.add_argument("--root", default=str(ROOT))
    ap.add_argument("--clock", default="cpu", choices=("cpu", "wall"),
                    help="cpu: this process's CPU time (time.process_time; the machine is shared), wall: perf_counter")
    a = ap.parse_args()
    clock = time.process_time if a.clock == "cpu" else time.perf_counter
    sys.path.insert(0, str(Path(a.root).resolve()))

    import ddatai as dd
    from ddatai.io.scenefile import build_scene
    from ddatai.model import build_model
    from ddatai.parallel import ScriptFunction
    from ddatai.start import settle
    from ddatai.step import Stepper
    from ddatai.fused import engine, layout, warm
    from ddatai.fused.pack import Member as Run
    from ddatai.fused.pack import pack
    from kgm.analysis import evaluate_group
    from kgm.build import prepare
    from kgm.judges.run import RunPlan, sub_scene, verdict
    from kgm.kinds import Method, RunEnd
    from kgm.settings import DdaSettings, Settings
    from kgm.studies.sampling import read_variables, sample_seeds, sample_variables

    print(f"# {dd.__file__}; load {os.getloadavg()[0]:.2f}", flush=True)
    t = clock()
    warm.warm()
    print(f"kernel loaded in {clock() - t:.1f} s", flush=True)
    variables, correlation = read_variables(ROOT / "docs" / "kgm" / "example_2_vars.toml")
    samples = sample_variables(variables, a.n, seed=1, correlation=correlation)
    sample_seeds(1, a.n)
    build = ScriptFunction(str(ROOT / "scenes" / "example_2.py"))
    settings = Settings(dda=DdaSettings(params=dd.Params(dt=0.0013, penalty_ratio=1.0, kernels="fused")))
    blocks = frozenset({0, 1})
    rows, runs, subs = [], [], []
    try:
        from ddatai import side_by_side, stage_batch  # noqa: F401  (registers the stage's operations)
    except ImportError:  # before the stages ran side by side
        side_by_side = None
    try:
        from ddatai.limit_batch import screened_ahead
    except ImportError:  # before the programs were solved side by side
        screened_ahead = None
    try:
        from kgm.judges.fused import _submodel  # the sub-models a batch builds (`prepare_fused`)
    except ImportError:  # before the fused judgements kept their sub-models
        _submodel = None
    shared: dict = {}  # a batch's sub-models, as `prepare_fused` keeps them
    for i in range(a.n):
        r = {"i": i, "friction": float(samples["friction"][i]), "cohesion": float(samples["cohesion"][i])}
        t0 = clock()
        scene, params = build_scene(build, friction=r["friction"], cohesion=r["cohesion"])
        t1 = clock()
        problem = prepare(scene, settings=settings, params=params)
        t2 = clock()
        res = evaluate_group(problem, blocks, Method.DDA.screened_by(settings.screening))
        t3 = clock()
        plan = RunPlan.of(problem.system, blocks, settings.dda, problem.params)
        sub, ids = sub_scene(problem.scene, problem.system, blocks, free_neighbours=plan.free_neighbours)
        if _submodel is None:
            model = build_model(sub, plan.params)
        else:
            if i % a.batch == 0:
                shared.clear()
            model, fresh = _submodel(shared, problem.scene, problem.system, plan, sub, ids, plan.params)
            model = model if fresh else model.with_joints(sub.joints)
        t4 = clock()
        r.update(build=t1 - t0, prepare=t2 - t1, screen_le=t3 - t2, submodel=t4 - t3, sarma_fs=float(res.fs))
        rows.append(r)
        subs.append((model, plan, ids))
    # the stages, a batch at a time (as `kgm.judges.fused.judge_fused` settles them)
    ahead = 0.0
    for b0 in range(0, a.n, a.batch):
        part = subs[b0:b0 + a.batch]
        steppers = [Stepper(m) for m, _, _ in part]
        states = [m.initial_state() for m, _, _ in part]
        t0 = clock()
        context = screened_ahead(steppers, states) if screened_ahead is not None else nullcontext()
        with context:
            ahead += clock() - t0
            if side_by_side is not None:
                # the batch's stages side by side (`ddatai.side_by_side`): a member's stage time is
                # its share of the batch's
                t4 = clock()
                settled = side_by_side.run([partial(settle, st, s0) for st, s0 in zip(steppers, states)])
                share = (clock() - t4) / len(part)
            for k, ((model, plan, ids), st, s0) in enumerate(zip(part, steppers, states)):
                if side_by_side is None:
                    t4 = clock()
                    state, record = settle(st, s0)
                    share = clock() - t4
                else:
                    state, record = settled[k]
                rows[b0 + k].update(stage=share, stage_solves=int(record.solves), held=int(record.held),
                                    released=int(record.released))
                runs.append((Run(model=model, state=state, t_end=plan.duration, stop_at=plan.stop_at,
                                 rest_limit=-1.0 if plan.rest_speed is None else plan.rest_speed,
                                 rest_steps=plan.rest_steps, group=tuple(ids.index(b) for b in sorted(blocks))),
                             plan))
    ends = {engine.STATUS[layout.STOP_MOVED]: RunEnd.STOPPED_EARLY, engine.STATUS[layout.STOP_REST]: RunEnd.AT_REST}
    pack_s, run_s = 0.0, 0.0
    for b0 in range(0, a.n, a.batch):
        part = runs[b0:b0 + a.batch]
        t0 = clock()
        pack([m for m, _ in part], engine.LAUNCH_STEPS)
        pack_s += clock() - t0
        t0 = clock()
        outs = engine.run([m for m, _ in part])
        run_s += clock() - t0
        for k, ((m, plan), o) in enumerate(zip(part, outs)):
            times = np.concatenate([[0.0], o.history[:, 0]])
            disp = np.concatenate([[0.0], o.history[:, 1]])
            j = verdict(times, disp, delta=plan.delta, duration=plan.duration, end=ends.get(o.status, RunEnd.DURATION),
                        wall_time=0.0, friction=None, reduction=1.0, model_blocks=0, moving_blocks=0,
                        scene_blocks=0)
            rows[b0 + k].update(status=o.status, steps=len(o.history), launches=o.launches, stable=bool(j.stable),
                                final_disp=float(disp[-1]), delta=plan.delta, T=plan.duration,
                                rest_speed=plan.rest_speed, quiet=o.quiet)
    n = a.n
    tot = {k: sum(r[k] for r in rows) for k in ("build", "prepare", "screen_le", "submodel", "stage")}
    tot["screens side by side"] = ahead
    print(f"\n{n} samples, batches of {a.batch}; {a.clock} time; load {os.getloadavg()[0]:.2f}")
    print("| phase | total [s] | per sample [ms] |")
    print("|---|---|---|")
    for k, v in tot.items():
        print(f"| {k} | {v:.2f} | {1e3 * v / n:.2f} |")
    print(f"| pack (once more, alone) | {pack_s:.2f} | {1e3 * pack_s / n:.2f} |")
    print(f"| fused runs (engine.run, incl. its pack) | {run_s:.2f} | {1e3 * run_s / n:.2f} |")
    allt = sum(tot.values()) + run_s
    print(f"| all but the extra pack | {allt:.2f} | {1e3 * allt / n:.2f} ({n / allt:.1f} samples/s on one core) |")
    by = {}
    for r in rows:
        key = ("released" if r["released"] else "held", r["status"], "stable" if r["stable"] else "failed")
        by.setdefault(key, []).append(r)
    print("\n| stage | run end | verdict | members | stage ms (median) | stage solves (median) | "
          "steps (median, min, max) |")
    print("|---|---|---|---|---|---|---|")
    for key, rs in sorted(by.items()):
        st = [r["steps"] for r in rs]
        print(f"| {key[0]} | {key[1]} | {key[2]} | {len(rs)} | {1e3 * statistics.median(r['stage'] for r in rs):.1f} | "
              f"{statistics.median(r['stage_solves'] for r in rs):.0f} | "
              f"{statistics.median(st):.0f}, {min(st)}, {max(st)} |")
    r0 = rows[0]
    print(f"\nT {r0['T']:.3f} s, δ {r0['delta']:.4f} m, rest speed {r0['rest_speed']:.3g} m/s, "
          f"steps to T {r0['T'] / 0.0013:.0f}")
    if a.json:
        Path(a.json).write_text(json.dumps(rows))


if __name__ == "__main__":
    main()
