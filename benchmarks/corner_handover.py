"""Corner hand-overs and kicks of the stacks of squares under the slow gravity ramp
(tests/toppling_cases.py, docs/method/dda.md §3.4).

    python benchmarks/corner_handover.py CASE THETA [--frame turned|tilted] [--ramp 20]

Runs `toppling_cases.ramp_topples`'s loading step by step (`toppling_cases.ramp_handovers`) and
prints the corner pairs that changed representation (a vertex-vertex contact one step, a
vertex-edge contact of one vertex on an edge at the other the next, or back), the steps with
one, the largest kick (a step's largest change of a free block's velocity, |Δv| / (g·Δt)) and
whether the stack toppled.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tests"))

import toppling_cases as tc  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("case", choices=list(tc.CASES))
    ap.add_argument("theta", type=float)
    ap.add_argument("--frame", default="turned", choices=tc.SCAN_FRAMES)
    ap.add_argument("--ramp", type=float, default=tc.RAMP_TIMES)
    a = ap.parse_args()
    t0 = time.perf_counter()
    r = tc.ramp_handovers(tc.CASES[a.case][0], a.theta, a.frame, a.ramp)
    print(f"{a.case} {a.theta}° {a.frame} {a.ramp:g}τ: {r['handovers']} hand-overs in {r['steps_with']} of "
          f"{r['steps']} steps, largest kick {r['kick']:.1f} g·Δt, toppled {r['toppled']}, "
          f"wall {time.perf_counter() - t0:.0f} s", flush=True)


if __name__ == "__main__":
    main()
