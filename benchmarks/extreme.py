"""Random campaign over valid scenes (tests/extreme_cases.py): each case runs in its own
process with a time limit, with the default parameters; tallies finished, refused before work,
diverged, crashed and timed-out runs and the properties broken.

    python benchmarks/extreme.py --regime rock --n 100 [--seed 0] [--timeout 120] [--steps 200] [--jobs 1]

``--regime cut`` draws rock-like domains cut by random joints (`extreme_cases.random_domain`).
"""

from __future__ import annotations

import argparse
import collections
import json
import subprocess
import sys
import time
from concurrent.futures import ThreadPoolExecutor, as_completed
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))


def one(regime: str, seed: int, steps: int) -> dict:
    from extreme_cases import random_domain, random_spec, run_case

    rng = np.random.default_rng(seed)
    spec = random_domain(rng, steps) if regime == "cut" else random_spec(rng, regime, steps)
    out = run_case(spec)
    return dict(seed=seed, status=out.status, message=out.message, problems=list(out.problems),
                steps=out.steps, spec=repr(spec))


def _run(a, k: int) -> dict:
    cmd = [sys.executable, __file__, "--regime", a.regime, "--steps", str(a.steps), "--one", str(k)]
    t0 = time.perf_counter()
    try:
        proc = subprocess.run(cmd, capture_output=True, text=True, timeout=a.timeout, cwd=ROOT)
        row = json.loads(proc.stdout.strip().splitlines()[-1]) if proc.returncode == 0 else \
            dict(seed=k, status="crash", message=proc.stderr[-500:], problems=[])
    except subprocess.TimeoutExpired:
        row = dict(seed=k, status="timeout", message="", problems=[])
    row["wall_s"] = time.perf_counter() - t0
    return row


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--regime", default="rock", choices=("rock", "extreme", "cut"))
    ap.add_argument("--n", type=int, default=100)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--steps", type=int, default=None, help="steps per case (default 200; cut: 400)")
    ap.add_argument("--timeout", type=float, default=120.0)
    ap.add_argument("--jobs", type=int, default=1, help="cases run at a time, each in its own process")
    ap.add_argument("--one", type=int, help=argparse.SUPPRESS)
    ap.add_argument("--out", type=Path, default=None, help="write every case as JSON lines")
    a = ap.parse_args()
    if a.steps is None:
        a.steps = 400 if a.regime == "cut" else 200
    if a.one is not None:
        print(json.dumps(one(a.regime, a.one, a.steps)))
        return
    tally = collections.Counter()
    lines = []
    t0 = time.perf_counter()
    sink = a.out.open("w") if a.out else None  # each case written as it finishes
    with ThreadPoolExecutor(max_workers=max(1, a.jobs)) as pool:
        futures = [pool.submit(_run, a, k) for k in range(a.seed, a.seed + a.n)]
        for row in (f.result() for f in as_completed(futures)):
            tally[row["status"]] += 1
            if row["problems"]:
                tally["broke a property"] += 1
            lines.append(row)
            if sink:
                sink.write(json.dumps(row) + "\n")
                sink.flush()
            if row["status"] not in ("ok",) or row["problems"]:
                print(f"seed {row['seed']}: {row['status']} {row['message'][:300]} {row['problems']}", flush=True)
    wall = time.perf_counter() - t0
    per_case = sorted(r["wall_s"] for r in lines)
    print(dict(tally))
    print(f"wall time {wall:.0f} s for {a.n} cases ({a.jobs} at a time); per case median "
          f"{per_case[len(per_case) // 2]:.1f} s, longest {per_case[-1]:.1f} s")
    if sink:
        sink.close()


if __name__ == "__main__":
    main()
