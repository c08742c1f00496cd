"""The whole curve: time per step of ntdda's grid from 1 block to 102,400, ddatai beside ntdda,
drawn from the benchmarks' saved results (nothing is run).

    python benchmarks/curve.py [--out benchmarks/results/curve.png]

- ddatai, small models: `benchmarks/small_models.py`'s table (``results/small_models.md``: the
  NumPy path of up to 64 free blocks, the kernels at 256; per step after the equilibrium stage,
  one solve a step);
- ddatai, ntdda's protocol: `benchmarks/scaling.py`'s grid rows (``results/scaling.json``: from
  rest under sudden gravity, several open-close solves a step while the grid rings);
- ntdda: its side-by-side run on the same files, 1 to 1,024 blocks (docs/ntdda.md), and its
  recorded scaling runs at 4,096 and 16,384.

The chart needs matplotlib (the ``[plot]`` extra).
"""

from __future__ import annotations

import argparse
import json
import re
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "benchmarks" / "results"
sys.path.insert(0, str(ROOT / "benchmarks"))

#: ntdda ms per step of the n × n grid: run side by side with ddatai on the same files (1 to
#: 1,024 blocks) and its recorded scaling runs beyond (docs/ntdda.md); the same machine type
NTDDA_MS = {1: 0.020, 4: 0.041, 16: 0.164, 64: 2.03, 256: 26.5, 1024: 289.0, 4096: 1085.0, 16384: 17200.0}


def small_model_rows(path: Path) -> list[tuple[int, float, float]]:
    """(blocks, NumPy path ms/step, kernels ms/step) of the grid rows of small_models.md."""
    rows = []
    for line in path.read_text().splitlines():
        m = re.match(r"\|\s*grid (\d+)\s*\|\s*(\d+)\s*\|[^|]*\|\s*([\d.]+)\s*\|\s*([\d.]+)\s*\|", line)
        if m:
            rows.append((int(m.group(2)), float(m.group(3)), float(m.group(4))))
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=RESULTS / "curve.png")
    args = ap.parse_args()
    from loglog_chart import NO_CHART, Panel, Series, draw_loglog_chart, have_matplotlib

    small = small_model_rows(RESULTS / "small_models.md")
    # the faster of the two paths at each size: what Params(kernels="auto") picks
    ours_small = [(n, min(a, b) / 1e3) for n, a, b in small]
    rows = json.loads((RESULTS / "scaling.json").read_text())
    ours_rest = sorted((r["blocks"], r["ms_per_step"] / 1e3) for r in rows if r["family"] == "grid")
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
    series = [Series(label="ddatai, after the equilibrium stage (1 solve a step)", points=ours_small, line=ours_small),
              Series(label="ddatai, ntdda's protocol (from rest, the grid rings)", points=ours_rest, line=ours_rest),
              Series(label="ntdda", points=nt, line=nt, dashed=True, color="#000000")]
    draw_loglog_chart(args.out, [Panel("n × n grid of unit blocks on a fixed base", series)],
                      title="Time per DDA step, 1 to 102,400 blocks", x_label="blocks", y_label="seconds per step",
                      notes=["ddatai: benchmarks/small_models.py and benchmarks/scaling.py; ntdda: docs/ntdda.md "
                             "(side by side on the same files up to 1,024 blocks). 2-core x86 machines, shared."])
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
