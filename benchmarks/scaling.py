"""Block-count scaling of one DDA step: median ms per step, by phase, against block count.

    python benchmarks/scaling.py [--sizes 100,400,1600,6400,25600] [--family grid,stiffgrid,slope]
                                 [--steps N] [--warmup 1] [--arch cpu|gpu] [--solver auto|scipy|pardiso]

Three families (``benchmarks/scaling_scenes.py``): ``grid``, ntdda's scaling scene with its
parameters; ``stiffgrid``, the same grid in stiff rock; ``slope``, a 60° rock slope cut by two
persistent joint sets. The report (tables, growth exponents, chart) is
``benchmarks/scaling_report.py``; fresh-process runs and the paired A/B comparison of two
checkouts (``--baseline``) are ``benchmarks/scaling_paired.py``.

Every (family, size) runs in a fresh process (kernels come from Taichi's offline cache), so
its peak memory (max RSS) is its own. Per size: median ms per step over the timed steps after
the warm-up steps, split into contact detection, assembly, solve and update; open-close
iterations per step; contacts; peak memory; and, up to ``--reference-max`` blocks, the NumPy
reference path (brute-force detection and dense assembly, ``ddatai/reference.py``) on the same
state. The growth exponent is fitted between 1,600 and the largest size. Writes
``benchmarks/results/scaling.md`` and ``scaling.png``. Each run imports ``ddatai`` from this
checkout (``PYTHONPATH``), not from an installed copy.
"""

from __future__ import annotations

import argparse
import json
import resource
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))  # the sibling modules, also when imported as benchmarks.scaling
from scaling_paired import one_run, paired  # noqa: E402
from scaling_report import chart_only, write_report  # noqa: E402
from scaling_scenes import (GRID_STEP, RESULTS, ROOT, SCENES, grid_scene, parse_params,  # noqa: E402,F401
                            protocol_steps, slope_scene, stiffgrid_scene)

FROM_REST_STEPS = 10  # settled protocol: start-up cost measured over the stage and this many steps


def run_one(family: str, size: int, steps: int, warmup: int, arch: str, solver: str,
            reference_max: int, protocol: str = "ntdda", kernels: str = "auto", extra: str = "") -> dict:
    """Measure one (family, size) in this process; returns a JSON-able record.

    ``protocol``: ``ntdda`` starts at rest under sudden gravity (ntdda's scaling runs);
    ``settled`` first runs the equilibrium stage (`ddatai.start.settle`, the default start of a
    run) and times the steps after it, and also reports the start-up cost: the stage's wall time,
    solves (and the factorisations among them), held and released blocks and whether it fell back to
    the welded start, and the wall time per step of the stage plus the first ``FROM_REST_STEPS``
    steps."""
    import dataclasses

    import ddatai as dd
    from ddatai.results import step_wall_time
    from ddatai.start import settle
    from ddatai.step import Stepper

    t0 = time.perf_counter()
    scene, params = SCENES[family](size)
    params = dataclasses.replace(params, arch=arch, solver=solver, kernels=kernels, **parse_params(extra))
    build_s = time.perf_counter() - t0
    model = dd.build_model(scene, params)
    if family == "grid" and abs(model.max_step - GRID_STEP) > 1e-12:
        raise RuntimeError(f"grid: step displacement {model.max_step} m, not ntdda's {GRID_STEP} m")
    stepper = Stepper(model)
    state = model.initial_state()
    start = {}
    t_run = time.perf_counter()
    if protocol == "settled":
        cpu = time.process_time()
        state, rec = settle(stepper, state)
        start = dict(start_s=rec.wall_time, start_cpu_s=time.process_time() - cpu, start_solves=rec.solves, start_held=rec.held,
                     start_released=rec.released, start_factorisations=rec.factorisations,
                     start_welded=bool(rec.welded), start_unsettled=bool(rec.unsettled),
                     start_stalled=bool(rec.stalled))
    records, factorised, cpu = [], [], []
    for k in range(warmup + steps):
        cpu.append(time.process_time())
        before = stepper.solver.factorisations
        state, record = stepper.step(state)
        records.append(record.row())
        factorised.append(stepper.solver.factorisations - before)
        cpu[-1] = time.process_time() - cpu[-1]
        if k + 1 == FROM_REST_STEPS and protocol == "settled":
            start["from_rest_ms_per_step"] = (time.perf_counter() - t_run) / FROM_REST_STEPS * 1e3
    all_steps = np.array(records, dtype=dd.STEP_DTYPE)
    s = all_steps[warmup:]
    # "update": the open-close judgement, the update and the rest of the step (Δt, acceptance,
    # energy), as one column beside detection, assembly and solve
    rest = s["t_judge"] + s["t_update"] + s["t_time_step"] + s["t_accept"] + s["t_energy"]
    phases = {name: float(np.median(s[f"t_{name}"])) * 1e3 for name in ("contacts", "assembly", "solve")}
    phases["update"] = float(np.median(rest)) * 1e3
    phases["judge"] = float(np.median(s["t_judge"])) * 1e3  # the judgement alone (within "update")
    total = step_wall_time(s)
    out = dict(family=family, blocks=int(model.n_free), all_blocks=int(model.n_blocks), arch=arch,
               solver=stepper.solver.backend + (" numpy" if model.numpy_path else ""), build_s=build_s,
               ms_per_step=float(np.median(total)) * 1e3, cpu_ms_per_step=float(np.median(cpu[warmup:])) * 1e3,
               ms_per_oc=float(np.median(total / np.maximum(s["oc_iterations"], 1))) * 1e3,
               # the time a simulated second takes (steps of a failing model differ in Δt)
               cpu_s_per_sim_s=float(np.sum(cpu[warmup:]) / max(float(np.sum(s["dt"])), 1e-300)),
               sim_ms_per_step=float(np.mean(s["dt"])) * 1e3,
               oc_per_step=float(np.mean(s["oc_iterations"])), dt_cuts=int(s["dt_cuts"].sum()),
               protocol=protocol, solves_per_step=float(np.mean(s["oc_total"])),
               median_solves=float(np.median(s["oc_total"])), max_solves=int(s["oc_total"].max()),
               capped_steps=int(np.count_nonzero(s["oc_total"] > s["oc_iterations"])), **start,
               factorisations_per_step=float(np.mean(factorised[warmup:])),
               median_factorisations=float(np.median(factorised[warmup:])),
               contacts=int(np.median(s["contacts"])), **{f"ms_{k}": v for k, v in phases.items()})
    # ntdda's "s per 1-OC step": the cost of a step whose first solve already has the right states
    one = s["oc_total"] == 1
    out["ms_one_oc"] = float(np.median(total[one])) * 1e3 if one.any() else None
    out["one_oc_steps"] = int(one.sum())
    if model.n_blocks <= reference_max and not model.numpy_path:
        # the Taichi kernels against their NumPy reference: a model on the small-model NumPy
        # path (`Params(kernels="auto")`, at most 64 free blocks) has no kernels to time
        out.update(reference_timings(model, stepper, state))
    out["peak_mb"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
    return out


def reference_timings(model, stepper, state) -> dict:
    """NumPy reference path on the current state: detection, and one dense assembly, against
    the Taichi kernels' detection and one sparse assembly."""
    from ddatai import reference
    from ddatai.assembly import BlockPattern, assemble_blocks, assemble_contacts, contact_vectors
    from ddatai.contact_law import friction_force
    from ddatai.contacts import Contacts, detect_contacts
    from ddatai.kinematics import newmark_beta

    geom = model.block_geometry(state.vertex_xy)
    t = time.perf_counter()
    cint, length = reference.detect_contacts(model, state.vertex_xy)
    ref_detect = time.perf_counter() - t
    t = time.perf_counter()
    cint_k, length_k = detect_contacts(model, state.vertex_xy, stepper.buffers)
    ti_detect = time.perf_counter() - t
    contacts = Contacts.start(model, state.vertex_xy, cint_k, length_k, state.memory, False)
    vec, sca = contact_vectors(model, state.vertex_xy, geom, contacts)
    pattern = BlockPattern.build(model, contacts)
    beta = newmark_beta(model.params, state)
    t = time.perf_counter()
    data, rhs = assemble_blocks(model, state, geom, pattern, 1e-3, beta)
    assemble_contacts(model, contacts, pattern, vec, sca, data, rhs, stepper.serial_scatter)
    ti_assemble = time.perf_counter() - t
    t = time.perf_counter()
    reference.assemble_dense(model, state.vertex_xy, state.block_velocity, state.block_stress,
                             state.fixed_point_xy, state.load_xy, np.zeros((len(model.load_block), 2)),
                             1e-3, model.gravity, contacts, vec, sca, friction_force(contacts),
                             accel=state.block_accel, beta=beta)
    ref_assemble = time.perf_counter() - t
    return dict(ref_detect_ms=ref_detect * 1e3, ti_detect_ms=ti_detect * 1e3,
                ref_assemble_ms=ref_assemble * 1e3, ti_assemble_ms=ti_assemble * 1e3,
                same_contacts=bool(len(cint) == len(cint_k) and np.array_equal(cint, cint_k)))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", default="1,4,16,64,100,256,400,1024,1600,4096,6400,16384,25600")
    ap.add_argument("--family", default="grid,stiffgrid,slope")
    ap.add_argument("--steps", type=int, default=None,
                    help="timed steps per size; default ntdda's protocol (docs/ntdda.md §5): "
                         "100 up to 1,600 blocks, 20 up to 6,400, 4 beyond")
    ap.add_argument("--warmup", type=int, default=1,
                    help="untimed first steps (compilation, the first factorisation); ntdda: 1")
    ap.add_argument("--arch", default="cpu", choices=("cpu", "gpu", "cuda"))
    ap.add_argument("--solver", default="auto", choices=("auto", "scipy", "pardiso", "dense"))
    ap.add_argument("--kernels", default="auto", choices=("auto", "taichi", "numpy"),
                    help="Params.kernels: the small-model NumPy path or the Taichi kernels")
    ap.add_argument("--reference-max", type=int, default=450)
    ap.add_argument("--protocol", default="ntdda", choices=("ntdda", "settled"),
                    help="ntdda: from rest under sudden gravity (ntdda's scaling runs, the comparison "
                         "table); settled: the equilibrium stage first (a run's default start), steps "
                         "timed after it, start-up cost reported")
    ap.add_argument("--chart-only", action="store_true",
                    help="only draw OUT/scaling.png (OUT/scaling_settled.png with --protocol settled) again "
                         "from the saved .json")
    ap.add_argument("--baseline", type=Path, default=None,
                    help="another checkout of ddatai (the code before a change): each (family, size) runs "
                         "there and here in turn, --repeat times, in fresh processes, and a paired table "
                         "(medians, ratio of each pair) is written to OUT/scaling_paired.md")
    ap.add_argument("--repeat", type=int, default=3, help="pairs per (family, size) with --baseline")
    ap.add_argument("--params", default="",
                    help="Params fields NAME=VALUE,... for the runs (with --baseline: for A, this checkout)")
    ap.add_argument("--baseline-params", default="", help="with --baseline: Params fields for B")
    ap.add_argument("--cases", default=None,
                    help="with --baseline: FAMILY:SIZE,... to pair instead of every --family × --sizes "
                         "(e.g. slope:391,slope:1537,grid:1600)")
    ap.add_argument("--one", nargs=2, metavar=("FAMILY", "SIZE"), help=argparse.SUPPRESS)
    ap.add_argument("--out", type=Path, default=RESULTS)
    ap.add_argument("--append", action="store_true",
                    help="merge these sizes into the rows already in OUT/scaling.json (e.g. a 100,000-block "
                         "run with fewer steps) and rewrite the table and chart")
    a = ap.parse_args()
    if a.one:
        print(json.dumps(run_one(a.one[0], int(a.one[1]), a.steps, a.warmup, a.arch, a.solver, a.reference_max,
                                 a.protocol, a.kernels, a.params)))
        return
    if a.baseline is not None:
        paired(a)
        return
    rows = []
    suffix = ("" if a.arch == "cpu" else f"_{a.arch}") + ("" if a.protocol == "ntdda" else f"_{a.protocol}")
    if a.chart_only:
        chart_only(a.out, suffix)
        return
    if a.append and (a.out / f"scaling{suffix}.json").exists():
        rows = json.loads((a.out / f"scaling{suffix}.json").read_text())
    for family in a.family.split(","):
        for size in (int(s) for s in a.sizes.split(",") if s):
            t = time.perf_counter()
            row = one_run(ROOT, family, size, a, a.params, a.reference_max)
            if row is None:
                continue
            rows = [r for r in rows if (r["family"], r["blocks"]) != (family, row["blocks"])] + [row]
            print(f"{family:9s} {row['blocks']:7,d} blocks: {row['ms_per_step']:9.1f} ms/step "
                  f"({row['oc_per_step']:.1f} OC it.), peak {row['peak_mb']:.0f} MB, run {time.perf_counter() - t:.0f} s",
                  flush=True)
    write_report(rows, a.protocol, a.arch, a.out, suffix)


if __name__ == "__main__":
    main()
