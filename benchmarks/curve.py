"""The whole curve: time per step of ntdda's grid from 1 block to 102,400, ddatai beside ntdda,
drawn from the benchmarks' saved results (nothing is run).

    python benchmarks/curve.py [--out benchmarks/results/curve.png]

- ddatai, after the equilibrium stage: `benchmarks/scaling.py --protocol settled`'s grid rows
  (``results/scaling_settled.json``: a run's default start, then one open-close solve a step
  while the stage holds the grid; ``Params(kernels="auto")``: the NumPy path up to 64 free
  blocks, the Taichi kernels beyond);
- ddatai, ntdda's protocol: `benchmarks/scaling.py`'s grid rows (``results/scaling.json``: from
  rest under sudden gravity, several open-close solves a step while the grid rings);
- ntdda: its side-by-side run on the same files, 1 to 1,024 blocks (docs/ntdda.md), and its
  recorded scaling runs at 4,096 and 16,384.

The chart needs matplotlib (the ``[plot]`` extra).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "benchmarks" / "results"
sys.path.insert(0, str(ROOT / "benchmarks"))

#: ntdda ms per step of the n × n grid: run side by side with ddatai on the same files (1 to
#: 1,024 blocks) and its recorded scaling runs beyond (docs/ntdda.md); the same machine type
NTDDA_MS = {1: 0.020, 4: 0.041, 16: 0.164, 64: 2.03, 256: 26.5, 1024: 289.0, 4096: 1085.0, 16384: 17200.0}


def grid_rows(path: Path) -> list[tuple[int, float]]:
    """(free blocks, seconds per step) of the ``grid`` rows of a scaling.py result file: the CPU
    time of its one-thread process where the row has it (on a shared machine the wall time
    measures the load; a one-thread process's CPU time is its wall time on a quiet one), else
    the wall time."""
    rows = json.loads(path.read_text())
    return sorted((r["blocks"], r.get("cpu_ms_per_step", r["ms_per_step"]) / 1e3) for r in rows
                  if r["family"] == "grid")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=RESULTS / "curve.png")
    args = ap.parse_args()
    from loglog_chart import NO_CHART, Panel, Series, draw_loglog_chart, have_matplotlib

    ours_small = grid_rows(RESULTS / "scaling_settled.json")
    ours_rest = grid_rows(RESULTS / "scaling.json")
    nt = sorted((n, ms / 1e3) for n, ms in NTDDA_MS.items())
    print("| blocks | ntdda ms/step | ddatai ms/step, after the stage | ddatai ms/step, from rest (ntdda's protocol) |")
    print("|---|---|---|---|")
    sizes = sorted({n for n, _ in nt} | {n for n, _ in ours_small} | {n for n, _ in ours_rest})
    lookup = [dict(nt), dict(ours_small), dict(ours_rest)]
    for n in sizes:
        cells = [f"{1e3 * d[n]:.3g}" if n in d else "–" for d in lookup]
        print(f"| {n:,} | " + " | ".join(cells) + " |")
    if not have_matplotlib():
        print(NO_CHART, file=sys.stderr)
        return
    series = [Series(label="ddatai, after the equilibrium stage", points=ours_small, line=ours_small),
              Series(label="ddatai, ntdda's protocol (from rest, the grid rings)", points=ours_rest, line=ours_rest),
              Series(label="ntdda", points=nt, line=nt, dashed=True, color="#000000")]
    draw_loglog_chart(args.out, [Panel("n × n grid of unit blocks on a fixed base", series)],
                      title="Time per DDA step, 1 to 102,400 blocks", x_label="blocks", y_label="seconds per step",
                      notes=["ddatai: benchmarks/scaling.py (settled and ntdda's protocols); ntdda: docs/ntdda.md "
                             "(side by side on the same files up to 1,024 blocks). ddatai: CPU time, one thread; 2-core x86 "
                             "machines, shared."])
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
