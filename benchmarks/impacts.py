"""What resolving impacts costs (`ddatai.impacts`, docs/method/dda.md §4.6): one run of a case
with the default `Params` or with ``impact_overshoot=None`` (impacts left to the step).

    python benchmarks/impacts.py CASE [--off]
    farm-bench -n 5 --timeout 900 -- python benchmarks/impacts.py pile --vs 'python benchmarks/impacts.py pile --off'

CASE: ``example1-8`` (Example I at φ 8°, its group slides, 2 s), ``example1-14`` (φ 14°, held,
2 s), ``rocking`` (the 0.5 × 2 m block of tests/rocking_cases.py, five impacts), ``pile`` (a
6 × 6 pile of 1 m blocks falling 2 cm row onto row onto a plate, 1 s). Prints the steps, the
time-step cuts and the wall time of the run.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tests"))

import ddatai as dd  # noqa: E402


def case(name: str):
    """(scene, params, duration) of a case."""
    if name.startswith("example1-"):
        from scenes import example_1

        scene, params = example_1.build(friction=float(name.split("-")[1]))
        return scene, params, 2.0
    if name == "rocking":
        from rocking_cases import housner_duration, scene

        return scene(0.5, 2.0, 0.5), dd.Params(), housner_duration(0.5, 2.0, 0.5, 5)
    if name == "pile":
        from test_stability import _pile_on_plate

        return _pile_on_plate(300e6, n=6), dd.Params(), 1.0
    raise SystemExit(f"unknown case {name!r}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("case")
    ap.add_argument("--off", action="store_true", help="impact_overshoot=None")
    a = ap.parse_args()
    scene, params, duration = case(a.case)
    params = params if params is not None else dd.Params()
    if a.off:
        from dataclasses import replace

        params = replace(params, impact_overshoot=None)
    t0 = time.perf_counter()
    res = dd.simulate(scene, params, duration=duration, record_every=10 ** 9)
    wall = time.perf_counter() - t0
    s = res.steps
    print(f"{a.case} impacts {'off' if a.off else 'on'}: {len(s)} steps, {int(s['dt_cuts'].sum())} cuts, "
          f"{wall:.2f} s wall")


if __name__ == "__main__":
    main()
