"""Block-count scaling of one DDA step: median ms per step, by phase, against block count.

    python benchmarks/scaling.py [--sizes 100,400,1600,6400,25600] [--family grid,stiffgrid,slope]
                                 [--steps N] [--warmup 1] [--arch cpu|gpu] [--solver auto|scipy|pardiso]

Three families:

- ``grid``: ntdda's scaling scene (``docs/ntdda.md`` §5) with its parameters: a
  fitted n × n grid of 1 m blocks on a fixed base, ρ = 2000 kg/m³, E = 100 MPa, ν = 0.25, plane
  stress, p = 1e9 N/m, φ = 30°, dynamic, Δt = 1 ms, step displacement g2·w0 = 0.03 m;
- ``stiffgrid``: the same grid in stiff rock (``scenes/stacked_grid.py``, gap 0: E = 5 GPa,
  ρ = 2500 kg/m³, automatic penalty 50·E = 250 GPa, plane strain, Δt = 1 ms). Its contact
  springs (period 2π·√(m/p) = 0.6 ms) are not resolved by the step, so the sudden start rings
  hard and the open-close iteration takes 3× as many iterations as on ``grid``;
- ``slope``: a 60° rock slope cut by two persistent joint sets (35° bedding, 105° cross set)
  whose spacing is chosen for the wanted block count; blocks below the toe and far behind the
  face are fixed; dynamic, Δt = 1 ms.

Every (family, size) runs in a fresh process (kernels come from Taichi's offline cache), so
its peak memory (max RSS) is its own. Per size: median ms per step over the timed steps after
the warm-up steps, split into contact detection, assembly, solve and update; open-close
iterations per step; contacts; peak memory; and, up to ``--reference-max`` blocks, the NumPy
reference path (brute-force detection and dense assembly, ``ddatai/reference.py``) on the same
state. The growth exponent is fitted between 1,600 and the largest size. Writes
``benchmarks/results/scaling.md`` and ``scaling.png``.
"""

from __future__ import annotations

import argparse
import json
import math
import platform
import resource
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "benchmarks" / "results"
# ntdda (Berkeley DDA), same grid scene, same machine type: seconds per step (docs/ntdda.md §5)
NTDDA_GRID = {16: 9.8e-5, 64: 7.0e-4, 256: 1.00e-2, 1024: 0.112, 4096: 1.085, 16384: 17.20}
# ntdda: seconds per open-close iteration and mean OC iterations per step (same table)
NTDDA_GRID_OC = {1024: (0.063, 1.76), 4096: (1.05, 1.11), 16384: (17.16, 1.00)}
GRID_STEP = 0.03  # ntdda's grid runs: largest step displacement g2·w0 [m]
FROM_REST_STEPS = 10  # settled protocol: start-up cost measured over the stage and this many steps


def slope_scene(n_blocks: int):
    """A slope cut by two persistent joint sets, spacing chosen for about ``n_blocks`` blocks."""
    import ddatai as dd

    rock = dd.Material(density=2600.0, young=10e9, poisson=0.25)
    scene = dd.Scene(gravity=9.81)
    height = 30.0
    toe = (10.0, 0.0)
    crest = (10.0 + height / math.tan(math.radians(60.0)), height)
    outline = [(0.0, -6.0), (60.0, -6.0), (60.0, height), crest, toe, (0.0, 0.0)]
    area = 60.0 * 36.0 - 0.5 * height * (crest[0] - toe[0]) - 10.0 * height
    # 0.63: measured ratio of blocks to area·sinα/s² (blocks cut by the outline are smaller)
    spacing = math.sqrt(0.63 * area * math.sin(math.radians(70.0)) / n_blocks)
    sets = [dd.JointSet(dip=35.0, spacing=spacing, joint=dd.Joint(friction=28.0)),
            dd.JointSet(dip=105.0, spacing=spacing, joint=dd.Joint(friction=35.0))]
    # slivers (a few mm² where three joints nearly meet) merged into a neighbour, as the scenes
    # do: left in, one of them holds the sudden start of the 1,600-block slope in an
    # open-close cycle at Δt = 3e-7 s
    ids = scene.cut(outline, dd.joint_sets(outline, sets, seed=1), material=rock, slivers="merge")
    centroid = np.array([scene.polygon(b).mean(axis=0) for b in ids])
    for b, c in zip(ids, centroid):
        if c[1] < 0.0 or c[0] > 50.0:
            scene.set_fixed(b)
    return scene, dd.Params(dt=1e-3)


def grid_scene(n_blocks: int):
    """ntdda's grid (docs/ntdda.md §5) with ntdda's material, penalty and step limit."""
    import ddatai as dd

    n = int(round(math.sqrt(n_blocks)))
    scene = dd.Scene(gravity=9.81)
    rock = dd.Material(density=2000.0, young=1e8, poisson=0.25)
    scene.add_block([(-1, -1), (n + 1, -1), (n + 1, 0), (-1, 0)], material=rock, fixed=True)
    for j in range(n):
        for i in range(n):
            scene.add_block([(i, j), (i + 1, j), (i + 1, j + 1), (i, j + 1)], material=rock)
    scene.set_joint(dd.Joint(friction=30.0))
    # ntdda fixed g2·w0 = 0.03 m for every N; ddatai's w0 is half the larger side (n + 2 m),
    # at most 10 × the block size (`build_model`; run_one checks the result)
    w0 = min(0.5 * (n + 2), 10.0)
    return scene, dd.Params(dt=1e-3, penalty=1e9, plane="stress", max_displacement_ratio=GRID_STEP / w0)


def stiffgrid_scene(n_blocks: int):
    sys.path.insert(0, str(ROOT))
    from scenes.stacked_grid import build

    n = int(round(math.sqrt(n_blocks)))
    return build(n, gap=0.0, static=False, dt=1e-3)


SCENES = {"grid": grid_scene, "stiffgrid": stiffgrid_scene, "slope": slope_scene}


def parse_params(text: str) -> dict:
    """``--params`` "NAME=VALUE,..." as Params fields (True/False, None, numbers, else text)."""
    out = {}
    for item in filter(None, (text or "").split(",")):
        name, value = item.split("=", 1)
        if value in ("True", "False"):
            out[name] = value == "True"
        elif value == "None":
            out[name] = None
        else:
            try:
                out[name] = float(value) if any(ch in value for ch in ".e") else int(value)
            except ValueError:
                out[name] = value
    return out


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
                     start_welded=bool(rec.welded))
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
    if model.n_blocks <= reference_max:
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


def protocol_steps(size: int) -> int:
    """Timed steps per size of ntdda's scaling runs (100 for N ≤ 1,024, 20 at 4,096, 4 at 16,384),
    with 1,600 taken with the small sizes."""
    return 100 if size <= 1600 else 20 if size <= 6400 else 4


def growth_exponent(rows: list[dict], lo: int = 1600, hi: int = 25600, key: str = "ms_per_step") -> float:
    """Least-squares slope of log(time) against log(blocks) over lo..hi blocks (the issue's range)."""
    pts = [(r["blocks"], r[key]) for r in rows if lo * 0.9 <= r["blocks"] <= hi * 1.1]
    if len(pts) < 2:
        return float("nan")
    x, y = np.log([p[0] for p in pts]), np.log([p[1] for p in pts])
    return float(np.polyfit(x, y, 1)[0])


def machine() -> str:
    cpu = platform.processor() or platform.machine()
    try:
        for line in open("/proc/cpuinfo"):
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    import os

    return f"{cpu}, {os.cpu_count()} cores, Python {platform.python_version()}, {platform.system()}"


def table(rows: list[dict]) -> str:
    staged = any("start_s" in r for r in rows)  # the settled protocol: the stage beside the steps
    head = "| family | blocks | contacts | ms/step | ms per OC iteration | OC it./step | ms per 1-OC step (steps) | contacts ms | assembly ms | solve ms | judge + update ms | peak MB | solver |"
    lines = [head + (" stage s (solves) |" if staged else ""), "|---" * (14 if staged else 13) + "|"]
    for r in rows:
        one = f"{r['ms_one_oc']:.1f} ({r['one_oc_steps']})" if r.get("ms_one_oc") else "–"
        stage = ""
        if staged:
            stage = (f" {r['start_s']:.2f} ({r['start_solves']}{', welded' if r.get('start_welded') else ''}) |"
                     if "start_s" in r else " – |")
        lines.append(f"| {r['family']} | {r['blocks']:,} | {r['contacts']:,} | {r['ms_per_step']:.1f} | "
                     f"{r['ms_per_oc']:.1f} | {r['oc_per_step']:.1f} | {one} | {r['ms_contacts']:.1f} | {r['ms_assembly']:.1f} | "
                     f"{r['ms_solve']:.1f} | {r['ms_update']:.1f} | {r['peak_mb']:.0f} | {r['solver']} |" + stage)
    nt = [r for r in rows if r["family"] == "grid" and r["blocks"] in NTDDA_GRID_OC]
    if nt:
        lines += ["", "Against ntdda on the same grid scene with the same parameters (docs/ntdda.md §5, "
                  "same machine type). ntdda converges in 1-2 open-close iterations because it tolerates "
                  "penetrations up to 2e-4·w0 before closing a contact and ignores lock/slide changes; "
                  "ddatai iterates until no contact changes state:", "",
                  "| blocks | ntdda s/step | ddatai s/step | per step: ntdda / ddatai | ntdda s per OC it. | ddatai s per OC it. | per OC it.: ntdda / ddatai | OC it./step ntdda / ddatai |",
                  "|---|---|---|---|---|---|---|---|"]
        for r in nt:
            per_oc, its = NTDDA_GRID_OC[r["blocks"]]
            lines.append(f"| {r['blocks']:,} | {NTDDA_GRID[r['blocks']]:.3f} | {r['ms_per_step'] / 1e3:.3f} | "
                         f"{NTDDA_GRID[r['blocks']] / (r['ms_per_step'] / 1e3):.1f}x | {per_oc:.3f} | "
                         f"{r['ms_per_oc'] / 1e3:.4f} | {per_oc / (r['ms_per_oc'] / 1e3):.0f}x | {its:.2f} / {r['oc_per_step']:.1f} |")
    ref = [r for r in rows if "ref_detect_ms" in r]
    if ref:
        lines += ["", "NumPy reference path on the same state (brute-force detection, dense assembly) against the Taichi kernels:", "",
                  "| family | blocks | detection: reference / Taichi ms | one assembly: dense NumPy / Taichi ms | same contacts |",
                  "|---|---|---|---|---|"]
        for r in ref:
            lines.append(f"| {r['family']} | {r['blocks']:,} | {r['ref_detect_ms']:.1f} / {r['ti_detect_ms']:.2f} | "
                         f"{r['ref_assemble_ms']:.1f} / {r['ti_assemble_ms']:.2f} | {r['same_contacts']} |")
    return "\n".join(lines)


def solves_table(rows: list[dict]) -> str:
    """Open-close solves per step, the factorisations among them (a step's first solve may reuse
    the last factor, `ddatai.solver`), and, for the settled protocol, the start-up."""
    lines = ["| family | blocks | solves/step: median (mean, max) | factorisations/step: median (mean) | steps with a cut attempt | stage: s | stage: solves (factorised) | stage: held/released | stage + first 10 steps: ms/step |",
             "|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        if "median_solves" not in r:
            continue
        if "start_s" in r:
            welded = ", welded" if r.get("start_welded") else ""
            stage = (f"{r['start_s']:.2f} | {r['start_solves']} ({r.get('start_factorisations', '–')}) | "
                     f"{r['start_held']:,}/{r['start_released']:,}{welded}")
        else:
            stage = "– | – | –"
        rest = f"{r['from_rest_ms_per_step']:.0f}" if "from_rest_ms_per_step" in r else "–"
        fact = (f"{r['median_factorisations']:.0f} ({r['factorisations_per_step']:.1f})"
                if "median_factorisations" in r else "–")
        lines.append(f"| {r['family']} | {r['blocks']:,} | {r['median_solves']:.0f} ({r['solves_per_step']:.1f}, "
                     f"{r['max_solves']}) | {fact} | {r['capped_steps']} | {stage} | {rest} |")
    return "\n".join(lines)


def chart(rows: list[dict], path: Path) -> None:
    """Time per step against block count (matplotlib, the [plot] extra): one panel for the
    time per step of each family (with ntdda's grid), one for the sparse solve's share, one per
    open-close iteration against ntdda's."""
    sys.path.insert(0, str(ROOT / "benchmarks"))
    from loglog_chart import NO_CHART, Panel, Series, draw_loglog_chart, have_matplotlib

    if not have_matplotlib():
        print(NO_CHART, file=sys.stderr)
        return
    families = [f for f in SCENES if any(r["family"] == f for r in rows)]

    def curve(family: str, key: str) -> list:
        return sorted((r["blocks"], r[key] / 1e3) for r in rows if r["family"] == family and key in r)

    nt = sorted(NTDDA_GRID.items())
    per_step = [Series(label=f"ddatai {f}", points=curve(f, "ms_per_step"), line=curve(f, "ms_per_step"))
                for f in families] + [Series(label="ntdda grid (same machine type)", points=nt, line=nt, dashed=True,
                                             color="#000000")]
    solve = [Series(label=f"ddatai {f}", points=curve(f, "ms_solve"), line=curve(f, "ms_solve")) for f in families]
    nt_oc = sorted((n, v[0]) for n, v in NTDDA_GRID_OC.items())
    oc = [Series(label="ddatai grid", points=curve("grid", "ms_per_oc"), line=curve("grid", "ms_per_oc")),
          Series(label="ntdda grid", points=nt_oc, line=nt_oc, dashed=True, color="#000000")]
    panels = [Panel("whole step", per_step), Panel("sparse solves of a step", solve),
              Panel("per open-close iteration (grid)", oc)]
    draw_loglog_chart(path, panels, title="Time per DDA step against block count", x_label="blocks",
                      y_label="seconds")


def chart_only(out: Path, suffix: str) -> None:
    """Draw OUT/scaling{suffix}.png again from OUT/scaling{suffix}.json (no run)."""
    rows = json.loads((out / f"scaling{suffix}.json").read_text())
    chart(rows, out / f"scaling{suffix}.png")


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
            steps = a.steps if a.steps is not None else protocol_steps(size)
            cmd = [sys.executable, __file__, "--one", family, str(size), "--steps", str(steps),
                   "--warmup", str(a.warmup), "--arch", a.arch, "--solver", a.solver,
                   "--reference-max", str(a.reference_max), "--protocol", a.protocol, "--kernels", a.kernels]
            t = time.perf_counter()
            proc = subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT)
            if proc.returncode != 0:
                print(f"{family} {size}: failed\n{proc.stderr[-2000:]}", file=sys.stderr)
                continue
            row = json.loads(proc.stdout.strip().splitlines()[-1])
            row.update(steps=steps, warmup=a.warmup)
            rows = [r for r in rows if (r["family"], r["blocks"]) != (family, row["blocks"])] + [row]
            print(f"{family:9s} {row['blocks']:7,d} blocks: {row['ms_per_step']:9.1f} ms/step "
                  f"({row['oc_per_step']:.1f} OC it.), peak {row['peak_mb']:.0f} MB, run {time.perf_counter() - t:.0f} s",
                  flush=True)
    rows.sort(key=lambda r: (list(SCENES).index(r["family"]), r["blocks"]))
    start = ("from a start at rest under sudden gravity (ntdda's protocol: the blocks settle, the grids "
             "ring, and the open-close iteration count varies from step to step)" if a.protocol == "ntdda" else
             "after the equilibrium stage (the settled protocol: a run's default start; a stage that does "
             "not converge leaves the model to sudden gravity, as the held/released column shows)")
    text = [f"# Block-count scaling, {a.protocol} protocol ({time.strftime('%Y-%m-%d')})", "", f"Machine: {machine()}; "
            f"Taichi arch {a.arch}; median of the timed steps after the warm-up steps, {start}; steps per size "
            f"in scaling{suffix}.json.", "", table(rows), "", "Open-close solves per step, cut attempts "
            "included, and the factorisations among them:", "", solves_table(rows), ""]
    for family in sorted({r["family"] for r in rows}):
        own = [r for r in rows if r["family"] == family]
        step, oc = growth_exponent(own), growth_exponent(own, key="ms_per_oc")
        one = growth_exponent([r for r in own if r.get("ms_one_oc")], key="ms_one_oc")
        # the sizes the fit really spans (the range is 1,600 to 25,600)
        span = [r["blocks"] for r in own if 1600 * 0.9 <= r["blocks"] <= 25600 * 1.1]
        where = f"{min(span):,} to {max(span):,}" if len(span) >= 2 else "1,600 to 25,600"
        text.append(f"Growth exponent from {where} blocks ({family}): {step:.2f} per step, {oc:.2f} per "
                    f"open-close iteration" + ("" if math.isnan(one) else f", {one:.2f} per 1-OC step"))
    text += ["", "With ntdda's protocol the large sizes time only steps 2-5, before the ringing of the sudden "
             "start builds up, so they take fewer open-close iterations per step than the small sizes; the "
             "cost of a step at a fixed iteration count (per 1-OC step, per iteration) is the measure of "
             "growth."]
    big = [r for r in rows if r["blocks"] > 30000]
    for r in big:
        base = [q for q in rows if q["family"] == r["family"] and 20000 < q["blocks"] <= 30000]
        if base:
            q = base[0]
            e = math.log(r["ms_per_oc"] / q["ms_per_oc"]) / math.log(r["blocks"] / q["blocks"])
            text.append(f"From {q['blocks']:,} to {r['blocks']:,} blocks ({r['family']}): exponent {e:.2f} per "
                        f"open-close iteration")
    print("\n".join(text))
    a.out.mkdir(parents=True, exist_ok=True)
    (a.out / f"scaling{suffix}.md").write_text("\n".join(text) + "\n")
    (a.out / f"scaling{suffix}.json").write_text(json.dumps(rows, indent=1))
    if rows:
        chart(rows, a.out / f"scaling{suffix}.png")


def one_run(tree: Path, family: str, size: int, a, params: str = "") -> "dict | None":
    """One (family, size) measured by ``tree``'s own benchmarks/scaling.py in a fresh process."""
    steps = a.steps if a.steps is not None else protocol_steps(size)
    # this script measures both (the same harness), importing ddatai from ``tree``
    cmd = [sys.executable, __file__, "--one", family, str(size), "--steps", str(steps),
           "--warmup", str(a.warmup), "--arch", a.arch, "--solver", a.solver, "--reference-max", "0",
           "--protocol", a.protocol, "--kernels", a.kernels] + (["--params", params] if params else [])
    proc = subprocess.run(cmd, capture_output=True, text=True, cwd=tree, env={**__import__("os").environ,
                                                                            "PYTHONPATH": str(tree)})
    if proc.returncode != 0:
        print(f"{tree} {family} {size}: failed\n{proc.stderr[-2000:]}", file=sys.stderr)
        return None
    return json.loads(proc.stdout.strip().splitlines()[-1])


#: what the paired table compares: (key, heading, format)
PAIRED = [("ms_per_step", "ms/step", "{:.1f}"), ("cpu_ms_per_step", "CPU ms/step", "{:.1f}"),
          ("ms_assembly", "assembly ms/step", "{:.1f}"), ("ms_judge", "judge ms/step", "{:.1f}"),
          ("ms_solve", "solve ms/step", "{:.1f}"), ("solves_per_step", "solves/step", "{:.2f}"),
          ("sim_ms_per_step", "simulated ms/step", "{:.3f}"), ("cpu_s_per_sim_s", "CPU s per simulated s", "{:.0f}"),
          ("factorisations_per_step", "factorisations/step", "{:.2f}"), ("start_s", "stage s", "{:.2f}"),
          ("start_cpu_s", "stage CPU s", "{:.2f}"),
          ("start_solves", "stage solves", "{:.0f}"), ("start_factorisations", "stage factorisations", "{:.0f}"),
          ("from_rest_ms_per_step", "stage + 10 steps ms/step", "{:.0f}"), ("peak_mb", "peak MB", "{:.0f}")]


def paired(a) -> None:
    """The sizes measured by the baseline checkout and by this one in turn (B A B A ..., fresh
    processes), ``--repeat`` pairs each: medians of each and the median of the pairs' ratios."""
    here = ROOT
    lines = [f"# Paired scaling, {a.protocol} protocol ({time.strftime('%Y-%m-%d')})", "",
             f"Machine: {machine()}; B = {a.baseline} {a.baseline_params}, A = {here} {a.params}; each row: "
             f"{a.repeat} pairs in fresh "
             f"processes, B then A, medians (A/B: median of the pairs' ratios).", "",
             "| family | blocks | what | B | A | A/B |", "|---|---|---|---|---|---|"]
    cases = ([(c.split(":")[0], int(c.split(":")[1])) for c in a.cases.split(",") if c] if a.cases else
             [(f, int(s)) for f in a.family.split(",") for s in a.sizes.split(",") if s])
    for family, size in cases:
        runs = {"A": [], "B": []}
        for _ in range(a.repeat):
            for label, tree, params in (("B", a.baseline, a.baseline_params), ("A", here, a.params)):
                row = one_run(tree, family, size, a, params)
                if row is not None:
                    runs[label].append(row)
                    print(f"{label} {family} {size}: {row['ms_per_step']:.1f} ms/step, stage "
                          f"{row.get('start_s', float('nan')):.2f} s", flush=True)
        if not runs["A"] or not runs["B"]:
            continue
        blocks = runs["A"][0]["blocks"]
        held = {k: {(r.get("start_held"), r.get("start_released"), r.get("start_welded")) for r in runs[k]}
                for k in runs}
        for key, head, fmt in PAIRED:
            if key not in runs["A"][0] or key not in runs["B"][0]:
                continue
            va = [r[key] for r in runs["A"]]
            vb = [r[key] for r in runs["B"]]
            ratio = [x / y for x, y in zip(va, vb) if y]
            lines.append(f"| {family} | {blocks:,} | {head} | {fmt.format(np.median(vb))} | "
                         f"{fmt.format(np.median(va))} | {np.median(ratio):.2f} |" if ratio else
                         f"| {family} | {blocks:,} | {head} | {fmt.format(np.median(vb))} | {fmt.format(np.median(va))} | – |")
        lines.append(f"| {family} | {blocks:,} | stage held/released/welded | "
                     f"{'; '.join(map(str, sorted(held['B'], key=str)))} | {'; '.join(map(str, sorted(held['A'], key=str)))} | |")
    text = "\n".join(lines)
    print(text)
    a.out.mkdir(parents=True, exist_ok=True)
    (a.out / "scaling_paired.md").write_text(text + "\n")


if __name__ == "__main__":
    main()
