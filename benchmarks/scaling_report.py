"""The scaling benchmark's report: its tables, growth exponents and chart, and the ntdda
figures it sets beside them (`benchmarks/scaling.py` measures; this module only formats).
"""

from __future__ import annotations

import json
import math
import platform
import sys
import time
from pathlib import Path

import numpy as np

from scaling_scenes import ROOT, SCENES

# ntdda (Berkeley DDA), same grid scene, same machine type: seconds per step (docs/ntdda.md §5)
NTDDA_GRID = {16: 9.8e-5, 64: 7.0e-4, 256: 1.00e-2, 1024: 0.112, 4096: 1.085, 16384: 17.20}
# ntdda: seconds per open-close iteration and mean OC iterations per step (same table)
NTDDA_GRID_OC = {1024: (0.063, 1.76), 4096: (1.05, 1.11), 16384: (17.16, 1.00)}


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
    head = "| family | blocks | contacts | ms/step | CPU ms/step | ms per OC iteration | OC it./step | ms per 1-OC step (steps) | contacts ms | assembly ms | solve ms | judge + update ms | peak MB | solver |"
    lines = [head + (" stage s (solves) |" if staged else ""), "|---" * (15 if staged else 14) + "|"]
    for r in rows:
        one = f"{r['ms_one_oc']:.1f} ({r['one_oc_steps']})" if r.get("ms_one_oc") else "–"
        stage = ""
        if staged:
            stage = (f" {r['start_s']:.2f} ({r['start_solves']}{', welded' if r.get('start_welded') else ''}) |"
                     if "start_s" in r else " – |")
        # CPU time of the (one-thread) process: on a shared machine the wall time is the load's
        cpu = f"{r['cpu_ms_per_step']:.1f}" if "cpu_ms_per_step" in r else "–"
        lines.append(f"| {r['family']} | {r['blocks']:,} | {r['contacts']:,} | {r['ms_per_step']:.1f} | {cpu} | "
                     f"{r['ms_per_oc']:.1f} | {r['oc_per_step']:.1f} | {one} | {r['ms_contacts']:.1f} | {r['ms_assembly']:.1f} | "
                     f"{r['ms_solve']:.1f} | {r['ms_update']:.1f} | {r['peak_mb']:.0f} | {r['solver']} |" + stage)
    nt = [r for r in rows if r["family"] == "grid" and r["blocks"] in NTDDA_GRID_OC]
    if nt:
        lines += ["", "Against ntdda on the same grid scene with the same parameters (docs/ntdda.md §5, "
                  "same machine type). ntdda converges in 1-2 open-close iterations because it tolerates "
                  "penetrations up to 2e-4·w0 before closing a contact and ignores lock/slide changes; "
                  "ddatai iterates until no contact changes state (its CPU time where recorded):", "",
                  "| blocks | ntdda s/step | ddatai s/step | per step: ntdda / ddatai | ntdda s per OC it. | ddatai s per OC it. | per OC it.: ntdda / ddatai | OC it./step ntdda / ddatai |",
                  "|---|---|---|---|---|---|---|---|"]
        for r in nt:
            per_oc, its = NTDDA_GRID_OC[r["blocks"]]
            # the one-thread process's CPU time where recorded (a shared machine's wall time is its load's)
            step = r.get("cpu_ms_per_step", r["ms_per_step"]) / 1e3
            one = step * r["ms_per_oc"] / r["ms_per_step"]
            lines.append(f"| {r['blocks']:,} | {NTDDA_GRID[r['blocks']]:.3f} | {step:.3f} | "
                         f"{NTDDA_GRID[r['blocks']] / step:.1f}x | {per_oc:.3f} | "
                         f"{one:.4f} | {per_oc / one:.0f}x | {its:.2f} / {r['oc_per_step']:.1f} |")
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
    lines = ["| family | blocks | solves/step: median (mean, max) | factorisations/step: median (mean) | steps solved again (a Δt cut or an impact) | stage: s | stage: solves (factorised) | stage: held/released | stage + first 10 steps: ms/step |",
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



def write_report(rows: list[dict], protocol: str, arch: str, out: Path, suffix: str) -> None:
    """Print and write OUT/scaling{suffix}.md (the tables, the growth exponents), .json and .png."""
    rows.sort(key=lambda r: (list(SCENES).index(r["family"]), r["blocks"]))
    start = ("from a start at rest under sudden gravity (ntdda's protocol: the blocks settle, the grids "
             "ring, and the open-close iteration count varies from step to step)" if protocol == "ntdda" else
             "after the equilibrium stage (the settled protocol: a run's default start; a stage that does "
             "not converge leaves the model to sudden gravity, as the held/released column shows)")
    text = [f"# Block-count scaling, {protocol} protocol ({time.strftime('%Y-%m-%d')})", "", f"Machine: {machine()}; "
            f"Taichi arch {arch}; median of the timed steps after the warm-up steps, {start}; steps per size "
            f"in scaling{suffix}.json.", "", table(rows), "", "Open-close solves per step, cut attempts "
            "included, and the factorisations among them:", "", solves_table(rows), ""]
    for family in sorted({r["family"] for r in rows}):
        own = [r for r in rows if r["family"] == family]
        step, oc = growth_exponent(own), growth_exponent(own, key="ms_per_oc")
        one = growth_exponent([r for r in own if r.get("ms_one_oc")], key="ms_one_oc")
        cpu = growth_exponent([r for r in own if "cpu_ms_per_step" in r], key="cpu_ms_per_step")
        # the sizes the fit really spans (the range is 1,600 to 25,600)
        span = [r["blocks"] for r in own if 1600 * 0.9 <= r["blocks"] <= 25600 * 1.1]
        where = f"{min(span):,} to {max(span):,}" if len(span) >= 2 else "1,600 to 25,600"
        text.append(f"Growth exponent from {where} blocks ({family}): {step:.2f} per step, {oc:.2f} per "
                    f"open-close iteration" + ("" if math.isnan(one) else f", {one:.2f} per 1-OC step") +
                    ("" if math.isnan(cpu) else f", {cpu:.2f} per step in CPU time"))
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
    out.mkdir(parents=True, exist_ok=True)
    (out / f"scaling{suffix}.md").write_text("\n".join(text) + "\n")
    (out / f"scaling{suffix}.json").write_text(json.dumps(rows, indent=1))
    if rows:
        chart(rows, out / f"scaling{suffix}.png")
