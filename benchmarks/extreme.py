"""Random campaign over valid scenes (tests/extreme_cases.py): each case runs in its own
process with a time limit, with the default parameters; tallies finished, refused before work,
diverged, crashed and timed-out runs and the properties broken.

    python benchmarks/extreme.py --regime rock --n 100 [--seed 0] [--timeout 120] [--steps 200]
"""

from __future__ import annotations

import argparse
import collections
import json
import subprocess
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))


def one(regime: str, seed: int, steps: int) -> dict:
    from extreme_cases import random_spec, run_case

    spec = random_spec(np.random.default_rng(seed), regime, steps)
    out = run_case(spec)
    return dict(seed=seed, status=out.status, message=out.message, problems=list(out.problems),
                steps=out.steps, spec=repr(spec))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--regime", default="rock", choices=("rock", "extreme"))
    ap.add_argument("--n", type=int, default=100)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--steps", type=int, default=200)
    ap.add_argument("--timeout", type=float, default=120.0)
    ap.add_argument("--one", type=int, help=argparse.SUPPRESS)
    ap.add_argument("--out", type=Path, default=None, help="write every case as JSON lines")
    a = ap.parse_args()
    if a.one is not None:
        print(json.dumps(one(a.regime, a.one, a.steps)))
        return
    tally = collections.Counter()
    lines = []
    for k in range(a.seed, a.seed + a.n):
        cmd = [sys.executable, __file__, "--regime", a.regime, "--steps", str(a.steps), "--one", str(k)]
        try:
            proc = subprocess.run(cmd, capture_output=True, text=True, timeout=a.timeout, cwd=ROOT)
            row = json.loads(proc.stdout.strip().splitlines()[-1]) if proc.returncode == 0 else \
                dict(seed=k, status="crash", message=proc.stderr[-500:], problems=[])
        except subprocess.TimeoutExpired:
            row = dict(seed=k, status="timeout", message="", problems=[])
        tally[row["status"]] += 1
        if row["problems"]:
            tally["broke a property"] += 1
        lines.append(row)
        if row["status"] not in ("ok",) or row["problems"]:
            print(f"seed {k}: {row['status']} {row['message'][:200]} {row['problems']}", flush=True)
    print(dict(tally))
    if a.out:
        a.out.write_text("\n".join(json.dumps(r) for r in lines) + "\n")


if __name__ == "__main__":
    main()
