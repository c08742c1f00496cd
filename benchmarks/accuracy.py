"""Error against run time on the closed-form cases.

    python benchmarks/accuracy.py [--quick] [--cases sliding,newmark,...] [--repeat N] [--out DIR]

For every case with an exact answer, runs DDA with the default parameters and with one
parameter changed at a time (fixed time step; automatic time step with a different ``dt_max``;
penalty ratio p/E; the open-close state tolerance and the round-off (opening) tolerance;
gravity switched on at t = 0 instead of the equilibrium start), and records the error against the exact
answer and the wall time of ``dd.simulate`` (scene building excluded, kernels compiled by a
warm-up run first, each configuration run once per pass; with ``--repeat N``, N passes and the
shortest time kept). Prints a Markdown table and writes ``DIR/accuracy.md`` (tables, machine,
date), ``DIR/accuracy.csv`` (every run) and ``DIR/accuracy.png`` (log–log chart of error
against wall time, one curve per case: the lowest error reached within a given time, with the
defaults marked). Default DIR: benchmarks/results.

The cases, their set-ups and error measures: ``benchmarks/accuracy_cases.py`` (its docstring is
copied into accuracy.md); the sweep: ``benchmarks/accuracy_sweep.py``; the tables and the
chart: ``benchmarks/accuracy_report.py``.
"""

from __future__ import annotations

import argparse
import datetime
import sys
import time
from pathlib import Path
from typing import Optional

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))  # run as a script: make `benchmarks` importable

from benchmarks import accuracy_cases  # noqa: E402
from benchmarks.accuracy_cases import (  # noqa: E402
    G, NEWMARK, ROCK, Case, Measure, ShakingSetup, add_block_on_incline, add_incline_base, all_cases,
    bonded_column_case, cohesive_case, column_case, downslope_displacement, free_flight_case,
    incline_frame, launched_case, newmark_case, newmark_ground_acceleration, newmark_reference,
    pivoting_block_rotation, pushed_block_case, resting_case, rocking_case, sliding_case,
    toppling_case)
from benchmarks.accuracy_report import (  # noqa: E402
    CHART_PANELS, ERROR_FLOOR, CaseSummary, best_error_staircase, detail_table, draw_chart,
    format_error, git_revision, machine_description, newmark_convergence, pareto_front, redraw_chart,
    results_table, summarise, summary_table, write_runs_csv)
from benchmarks.accuracy_sweep import (  # noqa: E402
    CONTACT_GROUPS, DEFAULT_LABEL, WRONG_ANSWER_ERROR, Config, Run, applies, case_params, run_case,
    sweep_configs, warm_up)
from benchmarks.loglog_chart import NO_CHART, have_matplotlib  # noqa: E402

#: every name is importable from here, as before the benchmark was split into its modules
__all__ = ["G", "NEWMARK", "ROCK", "Case", "Measure", "ShakingSetup", "add_block_on_incline",
           "add_incline_base", "all_cases", "bonded_column_case", "cohesive_case", "column_case",
           "downslope_displacement", "free_flight_case", "incline_frame", "launched_case", "newmark_case",
           "newmark_ground_acceleration", "newmark_reference", "pivoting_block_rotation",
           "pushed_block_case", "resting_case", "rocking_case", "sliding_case", "toppling_case",
           "CHART_PANELS", "ERROR_FLOOR", "CaseSummary", "best_error_staircase", "detail_table",
           "draw_chart", "format_error", "git_revision", "machine_description", "newmark_convergence",
           "pareto_front", "redraw_chart", "results_table", "summarise", "summary_table", "write_runs_csv",
           "CONTACT_GROUPS", "DEFAULT_LABEL", "WRONG_ANSWER_ERROR", "Config", "Run", "applies",
           "case_params", "run_case", "sweep_configs", "warm_up", "main"]


def main(argv: Optional[list[str]] = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="the defaults and dt = 0.02 s only (smoke test, ~20 s)")
    ap.add_argument("--cases", default="", help="comma-separated subset of: " +
                    ", ".join(c.key for c in all_cases()))
    ap.add_argument("--repeat", type=int, default=1,
                    help="passes over the sweep; each setting keeps its shortest wall time (default 1)")
    ap.add_argument("--out", type=Path, default=ROOT / "benchmarks" / "results",
                    help="folder for accuracy.md and accuracy.png")
    ap.add_argument("--chart-from", type=Path, metavar="CSV",
                    help="only draw OUT/accuracy.png again from an earlier sweep's accuracy.csv")
    a = ap.parse_args(argv)
    if a.chart_from:
        redraw_chart(a.chart_from, a.out / "accuracy.png")
        return 0
    cases = all_cases()
    if a.cases:
        wanted = a.cases.split(",")
        unknown = set(wanted) - {c.key for c in cases}
        if unknown:
            ap.error(f"unknown case(s): {', '.join(sorted(unknown))}")
        cases = [c for c in cases if c.key in wanted]
    configs = sweep_configs(a.quick)

    started = datetime.datetime.now().astimezone()
    wall0 = time.perf_counter()
    warm_up(cases)
    runs = {}
    # repeated passes over the whole sweep, keeping each setting's shortest wall time: on a
    # shared machine others' load only ever adds time, and a burst of it hits different
    # settings in different passes (the runs are deterministic: same error every pass)
    for rep in range(a.repeat):
        for case in cases:
            for cfg in configs:
                if not applies(case, cfg):
                    continue
                r = run_case(case, cfg)
                if (case.key, cfg.label) not in runs or r.wall < runs[case.key, cfg.label].wall:
                    runs[case.key, cfg.label] = r
                print(f"  pass {rep + 1} {case.key:12s} {cfg.label:24s} error {format_error(r):>8s}  "
                      f"wall {r.wall:7.3f} s  steps {r.steps:6d}  {r.note}", file=sys.stderr, flush=True)
    total = time.perf_counter() - wall0
    summaries = [summarise(c, [runs[c.key, cfg.label] for cfg in configs if applies(c, cfg)])
                 for c in cases]

    table = results_table(cases, configs, runs)
    machine = machine_description()
    print(table)
    print(f"\nmachine: {machine}")
    a.out.mkdir(parents=True, exist_ok=True)
    md = [
        "# Error against run time (`benchmarks/accuracy.py`)",
        "",
        f"- Date: {started:%Y-%m-%d %H:%M %Z}; code: {git_revision()}; command: "
        f"`python benchmarks/accuracy.py{' --quick' if a.quick else ''}"
        f"{' --cases ' + a.cases if a.cases else ''}{f' --repeat {a.repeat}' if a.repeat > 1 else ''}`; "
        f"total {total:.0f} s.",
        f"- Machine: {machine}.",
        "- Wall time: `dd.simulate` only (scene building excluded), after a warm-up that compiles "
        "the kernels; " + ("one run per setting." if a.repeat == 1 else
                           f"the shortest of {a.repeat} runs per setting, one in each of {a.repeat} passes "
                           "over the sweep (the machine is shared; others' load only adds time).") + " The CPU time of the process and the "
        "step count (in Details) are steadier measures of cost.",
        "- Each row changes one parameter from the defaults (`dd.Params()`; the column case "
        "always runs `static=True`); **defaults** is `params=None`. Every run at full precision: "
        "`accuracy.csv`; what the numbers mean: docs/guide/accuracy.md.",
        "",
        "![error against run time](accuracy.png)",
        "",
        "## Summary",
        "",
        summary_table(summaries),
        "",
        "## Error · wall time per setting",
        "",
        table,
        "",
        "## Cases",
        "",
        "Cases (" + accuracy_cases.__doc__.split("Cases (", 1)[1].strip(),
        "",
        "## Newmark reference: convergence of the stick–slip solution",
        "",
        newmark_convergence(),
        "",
        "## Details",
        "",
        detail_table(cases, configs, runs),
        "",
    ]
    (a.out / "accuracy.md").write_text("\n".join(md))
    write_runs_csv(a.out / "accuracy.csv", cases, configs, runs)
    if have_matplotlib():
        draw_chart(a.out / "accuracy.png", cases, runs, summaries)
    else:
        print(NO_CHART, file=sys.stderr)
    drawn = "accuracy.png, " if have_matplotlib() else ""
    print(f"\nwrote accuracy.md, {drawn}accuracy.csv in {a.out} ({total:.0f} s)", file=sys.stderr)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
