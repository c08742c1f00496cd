"""Runs of the scaling benchmark in fresh processes, and the paired A/B comparison of two
checkouts (`benchmarks/scaling.py --baseline`): B then A, ``--repeat`` pairs a case, medians and
the median of the pairs' ratios.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from scaling_report import machine
from scaling_scenes import ROOT, protocol_steps

SCALING = Path(__file__).resolve().with_name("scaling.py")


def one_run(tree: Path, family: str, size: int, a, params: str = "", reference_max: int = 0) -> "dict | None":
    """One (family, size) measured in a fresh process by this checkout's harness
    (``benchmarks/scaling.py --one``) with ``import ddatai`` from ``tree``: the same harness
    measures both sides of a pair, each on its own code. Returns its record, or None if it failed."""
    steps = a.steps if a.steps is not None else protocol_steps(size)
    cmd = [sys.executable, str(SCALING), "--one", family, str(size), "--steps", str(steps),
           "--warmup", str(a.warmup), "--arch", a.arch, "--solver", a.solver, "--reference-max", str(reference_max),
           "--protocol", a.protocol, "--kernels", a.kernels] + (["--params", params] if params else [])
    proc = subprocess.run(cmd, capture_output=True, text=True, cwd=tree, env={**os.environ, "PYTHONPATH": str(tree)})
    if proc.returncode != 0:
        print(f"{tree} {family} {size}: failed\n{proc.stderr[-2000:]}", file=sys.stderr)
        return None
    row = json.loads(proc.stdout.strip().splitlines()[-1])
    row.update(steps=steps, warmup=a.warmup)
    return row


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


