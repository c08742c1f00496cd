"""The toppling tilt of columns, rows and staircases on a tilted plate: from the default start
against slow loads (tests/toppling_cases.py).

    python benchmarks/toppling_start.py [--cases NAME,...] [--tol DEG] [--turn-on] [--out DIR]

For each case: the rigid closed form where there is one (a single column: tan θ = b/h), the
lowest tilt at which the default start topples it, the lowest tilt at which a slow gravity
ramp from rest (no stage) topples it (both by bisection to ``--tol``), and the tilt at which a
slow tilt (0.5°/s from 3° below the start's angle) sets it toppling. ``--turn-on``: the start
with ``Params(start_turn_on=True)`` (the stage's doubt settled by a slow turn-on of the weight).
Writes a Markdown table to DIR/toppling_start.md (default benchmarks/results).
"""

from __future__ import annotations

import argparse
import platform
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tests"))

from toppling_cases import CASES, ramp_topples, slow_tilt_angle, start_topples, threshold  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", default=",".join(CASES))
    ap.add_argument("--tol", type=float, default=0.1)
    ap.add_argument("--rate", type=float, default=0.5, help="slow tilt rate [degrees/s]")
    ap.add_argument("--turn-on", action="store_true", help="start with Params(start_turn_on=True)")
    ap.add_argument("--out", type=Path, default=ROOT / "benchmarks" / "results")
    a = ap.parse_args()
    params = None
    if a.turn_on:
        import ddatai as dd

        params = dd.Params(start_turn_on=True)
    rows = []
    for name in a.cases.split(","):
        case, lo, hi = CASES[name]
        t0 = time.perf_counter()
        start = threshold(lambda th: start_topples(case, th, params), lo, hi, a.tol)
        ramp = threshold(lambda th: ramp_topples(case, th), lo, hi + 2.0, a.tol)
        tilt = slow_tilt_angle(case, start - 3.0, a.rate, hi + 3.0)
        closed = case.closed_form()
        row = (name, "" if closed is None else f"{closed:.2f}", f"{start:.2f}", f"{ramp:.2f}", f"{start - ramp:+.2f}",
               f"{tilt:.2f}", f"{start - tilt:+.2f}", f"{time.perf_counter() - t0:.0f}")
        print(" | ".join(row), flush=True)
        rows.append(row)
    head = ("case", "rigid closed form [°]", "default start [°]", "slow gravity ramp [°]", "start − ramp",
            f"slow tilt {a.rate}°/s [°]", "start − tilt", "wall [s]")
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)] + ["| " + " | ".join(r) + " |" for r in rows]
    a.out.mkdir(parents=True, exist_ok=True)
    note = (f"Bisection to {a.tol}° (the upper end of the final bracket). {platform.processor() or platform.machine()}, "
            f"{time.strftime('%Y-%m-%d')}.")
    (a.out / "toppling_start.md").write_text("\n".join(["# Toppling tilt: the default start against slow loads", "",
                                                         note, ""] + lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
