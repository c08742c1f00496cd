"""Goodman & Bray's block-toppling example: limit equilibrium (kgm rigid/sarma) against DDA.

    python benchmarks/toppling.py [--no-dda] [--tolerance DEG]

The critical friction angle of the textbook row (blocks 1–13; Hoek & Bray 1981, Wyllie & Mah
2004 §10.3: 38.15°) from the Goodman–Bray recursion of `kgm` and from ddatai DDA
(`kgm.critical_friction(..., method="dda")`: bisection on φ of every joint, the group and the
blocks it touches simulated from gravitational equilibrium). A benchmark, not a test: the DDA
bisection takes minutes.
"""

import argparse
import platform
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # the repository root: scenes/
import kgm  # noqa: E402
from ddatai.scenefile import build_scene  # noqa: E402
from scenes import toppling_slope  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--no-dda", action="store_true", help="limit equilibrium only")
    ap.add_argument("--tolerance", type=float, default=0.25, help="DDA bisection bracket [degrees]")
    args = ap.parse_args()
    print(f"machine: {platform.processor() or platform.machine()}, Python {platform.python_version()}\n")
    scene, params = build_scene(toppling_slope, friction=toppling_slope.PUBLISHED_CRITICAL_FRICTION)
    group = list(range(13))  # textbook blocks 1–13
    print("| method | critical friction angle | wall time |")
    print("|---|---|---|")
    print(f"| published (Goodman & Bray 1976) | {toppling_slope.PUBLISHED_CRITICAL_FRICTION:.2f}° | - |")
    methods = ("rigid", "sarma") if args.no_dda else ("rigid", "sarma", "dda")
    settings = kgm.Settings(dda=kgm.DdaSettings(friction_tolerance=args.tolerance))
    for m in methods:
        t0 = time.perf_counter()
        phi = kgm.critical_friction(scene, group, method=m, settings=settings, params=params)
        print(f"| kgm {m} | {phi:.2f}° | {time.perf_counter() - t0:.1f} s |", flush=True)


if __name__ == "__main__":
    main()
