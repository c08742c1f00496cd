"""The accuracy benchmark's analysis and output (``benchmarks/accuracy.py``): the fastest runs
for their error (Pareto front), each case's summary, the Markdown tables, the CSV of every run,
the Newmark reference's convergence table and the log–log chart."""

from __future__ import annotations

import csv
import math
import os
import platform
import subprocess
from dataclasses import dataclass
from pathlib import Path
from typing import Optional

import numpy as np

from benchmarks.accuracy_cases import G, NEWMARK, ROOT, Case, all_cases, newmark_ground_acceleration
from benchmarks.accuracy_sweep import DEFAULT_LABEL, WRONG_ANSWER_ERROR, Config, Run
from benchmarks.loglog_chart import PALETTE, Panel, Series, draw_loglog_chart
from benchmarks.stick_slip import sinusoid_stick_slip, stick_slip

ERROR_FLOOR = 1e-16  # errors at round-off are drawn on this floor of the chart


# ----------------------------------------------------------------------------- analysis
def pareto_front(runs: list[Run]) -> list[Run]:
    """The runs no other run beats in both wall time and error, fastest first."""
    front, best = [], math.inf
    for r in sorted((r for r in runs if r.error < WRONG_ANSWER_ERROR), key=lambda r: (r.wall, r.error)):
        if r.error < best:
            front.append(r)
            best = r.error
    return front


def best_error_staircase(runs: list[Run]) -> list[tuple[float, float]]:
    """The lowest error reached within a given wall time, as (wall, error) corners of a step
    function from the fastest run to the slowest: the case's best curve on the chart."""
    front = pareto_front(runs)
    if not front:
        return []
    slowest = max(r.wall for r in runs)
    corners = [(front[0].wall, front[0].error)]
    for r in front[1:]:
        corners += [(r.wall, corners[-1][1]), (r.wall, r.error)]
    corners.append((max(slowest, corners[-1][0]), corners[-1][1]))
    return corners


@dataclass
class CaseSummary:
    case: Case
    default: Run
    best: Run
    dominating: list[Run]
    """Runs at least as accurate as the defaults (within 1 %), more than 20 % faster and with
    fewer steps (settings that take the same steps do the same work: their differences in
    wall time are the machine's noise)."""
    tenfold: Optional[Run]
    """The cheapest run with at most a tenth of the defaults' error."""


def summarise(case: Case, runs: list[Run]) -> CaseSummary:
    default = next(r for r in runs if r.config.label == DEFAULT_LABEL)
    ok = [r for r in runs if math.isfinite(r.error)]
    best = min(ok, key=lambda r: (max(r.error, ERROR_FLOOR), r.wall))
    dominating = sorted((r for r in ok if r is not default and r.wall < 0.8 * default.wall
                         and r.steps < default.steps and r.error <= 1.01 * default.error),
                        key=lambda r: (r.error, r.wall))
    better = [r for r in ok if r.error <= 0.1 * default.error]
    tenfold = min(better, key=lambda r: r.wall) if better else None
    return CaseSummary(case, default, best, dominating, tenfold)


# ----------------------------------------------------------------------------- output
def machine_description() -> str:
    cpu = platform.processor() or platform.machine()
    try:
        with open("/proc/cpuinfo") as fh:
            names = [line.split(":", 1)[1].strip() for line in fh if line.startswith("model name")]
        if names:
            cpu = names[0]
    except OSError:
        pass
    usable = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    import scipy
    import taichi

    return (f"{platform.platform()}, {cpu}, {os.cpu_count()} logical cores ({usable} usable), "
            f"Python {platform.python_version()}, NumPy {np.__version__}, SciPy {scipy.__version__}, "
            f"Taichi {'.'.join(map(str, taichi.__version__))} (CPU backend)")


def git_revision() -> str:
    try:
        out = subprocess.run(["git", "-C", str(ROOT), "rev-parse", "--short", "HEAD"],
                             capture_output=True, text=True, timeout=10)
        dirty = subprocess.run(["git", "-C", str(ROOT), "status", "--porcelain", "--", "ddatai",
                                "benchmarks/accuracy.py", "benchmarks/accuracy_cases.py",
                                "benchmarks/accuracy_sweep.py", "benchmarks/accuracy_report.py",
                                "benchmarks/stick_slip.py"],
                               capture_output=True, text=True, timeout=10).stdout.strip()
        return out.stdout.strip() + (" + uncommitted changes" if dirty else "")
    except (OSError, subprocess.SubprocessError):
        return "unknown"


def format_error(r: Run) -> str:
    if not math.isfinite(r.error):
        return "diverged"
    return f"{r.error:.1e}" if r.error > 0 else "0"


def results_table(cases: list[Case], configs: list[Config], runs: dict) -> str:
    head = "| parameters | " + " | ".join(c.label for c in cases) + " |"
    rule = "|---|" + "---|" * len(cases)
    lines = [head, rule]
    for cfg in configs:
        cells = []
        for c in cases:
            r = runs.get((c.key, cfg.label))
            if r is None:
                cells.append("n/a (no contacts)")
                continue
            cell = f"{format_error(r)} · {r.wall:.2f} s"
            if r.note and math.isfinite(r.error):
                cell += f" ({r.note})"
            cells.append(cell)
        label = f"**{cfg.label}**" if cfg.label == DEFAULT_LABEL else cfg.label
        lines.append(f"| {label} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def summary_table(summaries: list[CaseSummary]) -> str:
    lines = ["| case | error measure | defaults: error · wall | best in sweep | as accurate as the "
             "defaults, > 20 % faster, fewer steps | cheapest 10× more accurate (wall factor) |",
             "|---|---|---|---|---|---|"]
    for s in summaries:
        d = s.default
        dom = ", ".join(f"{r.config.label} ({format_error(r)} · {r.wall:.2f} s)" for r in s.dominating[:3])
        if len(s.dominating) > 3:
            dom += f", … ({len(s.dominating)} in all)"
        if s.tenfold is None:
            ten = "not reached in the sweep"
        else:
            ten = (f"{s.tenfold.config.label}: {format_error(s.tenfold)} · {s.tenfold.wall:.2f} s "
                   f"(×{s.tenfold.wall / d.wall:.2g})")
        lines.append(f"| {s.case.label} | {s.case.metric} | {format_error(d)} · {d.wall:.2f} s | "
                     f"{s.best.config.label}: {format_error(s.best)} · {s.best.wall:.2f} s | "
                     f"{dom or 'none'} | {ten} |")
    return "\n".join(lines)


def detail_table(cases: list[Case], configs: list[Config], runs: dict) -> str:
    lines = ["| case | parameters | error | wall [s] | CPU [s] | steps | open–close it./step | Δt cuts | note |",
             "|---|---|---|---|---|---|---|---|---|"]
    for c in cases:
        for cfg in configs:
            r = runs.get((c.key, cfg.label))
            if r is None:
                continue
            lines.append(f"| {c.key} | {cfg.label} | {format_error(r)} | {r.wall:.3f} | {r.cpu:.3f} | "
                         f"{r.steps} | {r.oc_mean:.2f} | {r.dt_cuts} | {r.note} |")
    return "\n".join(lines)


def write_runs_csv(path: Path, cases: list[Case], configs: list[Config], runs: dict) -> None:
    """Every run, machine-readable (errors and timings at full precision)."""
    with open(path, "w", newline="") as fh:
        out = csv.writer(fh)
        out.writerow(["case", "group", "parameters", "error", "wall_s", "cpu_s", "steps",
                      "oc_iterations_per_step", "dt_cuts", "note"])
        for c in cases:
            for cfg in configs:
                r = runs.get((c.key, cfg.label))
                if r is not None:
                    out.writerow([c.key, cfg.group, cfg.label, repr(r.error), f"{r.wall:.6f}",
                                  f"{r.cpu:.6f}", r.steps, f"{r.oc_mean:.4f}", r.dt_cuts, r.note])


def newmark_convergence() -> str:
    """The stick–slip reference at several solver tolerances and against the per-phase closed
    form (benchmarks/stick_slip.py): shows that the reference is converged."""
    c = NEWMARK
    closed = sinusoid_stick_slip(c.theta, c.phi, c.amplitude, c.frequency, c.duration, gravity=G)
    rows = ["| solver | s(3 s) [m] | difference from closed form [m] |", "|---|---|---|"]
    for rtol, max_step in ((1e-6, 0.05), (1e-9, 0.01), (1e-12, 0.005)):
        s = stick_slip(c.theta, c.phi, newmark_ground_acceleration, c.duration, gravity=G,
                       rtol=rtol, atol=rtol * 1e-2, max_step=max_step).final_displacement
        rows.append(f"| DOP853 + events, rtol {rtol:g}, max step {max_step:g} s | {s:.15f} | {s - closed:.1e} |")
    rows.append(f"| closed form per phase + brentq | {closed:.15f} | 0 |")
    return "\n".join(rows)


def redraw_chart(csv_path: Path, png_path: Path) -> None:
    """Draw the chart again from an earlier sweep's ``accuracy.csv`` (no simulation)."""
    from types import SimpleNamespace

    known = {c.key: c for c in all_cases()}
    with open(csv_path, newline="") as fh:
        rows = list(csv.DictReader(fh))
    keys = list(dict.fromkeys(r["case"] for r in rows))
    cases, runs, summaries = [], {}, []
    for key in keys:
        mine = [r for r in rows if r["case"] == key]
        as_runs = [SimpleNamespace(case=key, error=float(r["error"]), wall=float(r["wall_s"])) for r in mine]
        for r, run in zip(mine, as_runs):
            runs[(key, r["parameters"])] = run
        default = next((run for r, run in zip(mine, as_runs) if r["parameters"] == DEFAULT_LABEL), as_runs[0])
        cases.append(known[key])
        summaries.append(SimpleNamespace(default=default))
    draw_chart(png_path, cases, runs, summaries)


#: the chart's panels: cases grouped by what sets their error (docs/guide/accuracy.md), at most
#: four curves a panel
CHART_PANELS = (("time integration sets the error", ("pushed", "toppling", "newmark")),
                ("the contact law's round-off force sets it", ("sliding", "cohesive", "launched")),
                ("round-off and elastic deformation set it", ("resting", "free_flight", "column", "bonded_column")))


def draw_chart(path: Path, cases: list[Case], runs: dict, summaries: list[CaseSummary]) -> None:
    """Error against wall time (matplotlib, the [plot] extra): one panel per group of
    `CHART_PANELS`, each case's runs as dots, its best curve as a line and its defaults as a
    diamond."""
    series = {}
    for case, summary in zip(cases, summaries):
        case_runs = [r for (k, _), r in runs.items() if k == case.key]
        d = summary.default
        series[case.key] = Series(
            label=case.label,
            points=[(r.wall, r.error) for r in case_runs if math.isfinite(r.error)],
            line=best_error_staircase(case_runs),
            highlight=(d.wall, d.error) if math.isfinite(d.error) else None)
    panels = []
    placed = set()
    for title, keys in CHART_PANELS:
        mine = [series[k] for k in keys if k in series]
        for i, s in enumerate(mine):
            s.color = PALETTE[i]
        placed |= set(keys)
        if mine:
            panels.append(Panel(title, mine))
    rest = [s for k, s in series.items() if k not in placed]
    for start in range(0, len(rest), 4):
        for i, s in enumerate(rest[start:start + 4]):
            s.color = PALETTE[i]
        panels.append(Panel("other cases", rest[start:start + 4]))
    draw_loglog_chart(path, panels, title="DDA error against run time, closed-form cases",
                      x_label="wall time of dd.simulate [s]", y_label="error against the exact answer",
                      highlight_legend="default parameters",
                      notes=["dots: one parameter changed at a time (dt, dt_max, p/E, close and open tolerance; "
                             "see accuracy.md); lines: the lowest error reached in that wall time or less "
                             f"(errors >= {WRONG_ANSWER_ERROR:g}, wrong answers, left off); "
                             f"errors < {ERROR_FLOOR:g}: hollow, on the floor"],
                      y_floor=ERROR_FLOOR)
