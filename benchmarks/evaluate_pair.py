"""``kgm.evaluate(Example I, [0, 1], "dda")`` warm, this checkout against another one (``--against``,
e.g. a clone of main), paired in one go.

    python benchmarks/evaluate_pair.py --against ../main [--pairs 11]

Each checkout runs in its own worker process (its own code first on ``sys.path``, threads pinned:
BLAS one), which loads the fused kernel (from Taichi's offline cache, `ddatai.fused.warm`), calls
the evaluation once to warm, then answers one call at a time; the calls alternate between the
workers, the order flipping every pair. Each call's CPU time is its worker's (``process_time``:
the machine is shared, and the two workers see the same load in turn).

Besides the time, every call reports what it decided, and the two checkouts must agree to the
bit: the critical friction and FS (``repr``), each member's settled stage (a hash of its vertices
and contact memory, and its record's held, released and solves: ``ddatai.start.settle``), and
each probe's verdict (stable, how its run ended, displacement, steps). Prints the median CPU and
wall seconds of a call each way, how many calls took at most 0.5 s CPU, the median pair ratio,
and whether every call agreed.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

for _k in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_k, "1")

ROOT = Path(__file__).resolve().parents[1]


def state_digest(state) -> str:
    """A settled state's fingerprint: vertices, velocities and contact memory, to the bit."""
    import hashlib

    import numpy as np

    h = hashlib.sha256(state.vertex_xy.tobytes())
    h.update(state.block_velocity.tobytes())
    for _, v in sorted(vars(state.memory).items()):
        if isinstance(v, np.ndarray):
            h.update(v.tobytes())
    return h.hexdigest()[:16]


def worker(root: str) -> None:
    """Answer "call" lines on stdin with one JSON line each (a warm call's time and decisions)."""
    sys.path.insert(0, root)
    import kgm
    import kgm.judges.dda as dda_module
    import ddatai.start as start
    from ddatai.fused import warm
    from scenes import example_1

    stages, probes = [], []
    settle, judge_many = start.settle, dda_module.judge_many

    def settle_logged(stepper, state, *a, **k):
        slot = len(stages)
        stages.append(None)
        out = settle(stepper, state, *a, **k)
        s, rec = out
        stages[slot] = [state_digest(s), int(rec.held), int(rec.released), int(rec.solves)]
        return out

    def judge_many_logged(scene, system, blocks, todo, **k):
        out = judge_many(scene, system, blocks, todo, **k)
        probes.extend([[repr(f), repr(r)], bool(j.stable), str(j.end), repr(j.displacement), int(j.steps)]
                      for (f, r), j in zip(todo, out))
        return out

    start.settle = settle_logged
    dda_module.judge_many = judge_many_logged
    warm.warm()
    scene, params = example_1.build()
    kgm.evaluate(scene, [0, 1], "dda", params=params)
    print(json.dumps({"ready": True}), flush=True)
    for line in sys.stdin:
        if line.strip() != "call":
            break
        stages.clear()
        probes.clear()
        c, w = time.process_time(), time.perf_counter()
        row = kgm.evaluate(scene, [0, 1], "dda", params=params)
        cpu, wall = time.process_time() - c, time.perf_counter() - w
        print(json.dumps({"cpu": cpu, "wall": wall, "decided": [repr(row.critical_friction), repr(row.fs),
                                                                stages, probes]}), flush=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--against", required=True, help="the other checkout's root (e.g. a clone of main)")
    ap.add_argument("--pairs", type=int, default=11)
    ap.add_argument("--worker", help=argparse.SUPPRESS)
    a = ap.parse_args()
    if a.worker:
        return worker(a.worker)
    roots = {"this": str(ROOT), "other": str(Path(a.against).resolve())}
    env = dict(os.environ, PYTHONDONTWRITEBYTECODE="1")
    procs = {k: subprocess.Popen([sys.executable, __file__, "--against", r, "--worker", r], cwd=r, env=env,
                                 stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
             for k, r in roots.items()}

    def answer(k):
        while True:  # Taichi's banner goes to stdout too
            line = procs[k].stdout.readline()
            if not line:
                raise SystemExit(f"the worker of {roots[k]} ended")
            if line.startswith("{"):
                return json.loads(line)

    for k in procs:
        answer(k)
    print(f"# this {roots['this']} against {roots['other']}; {a.pairs} pairs; load {os.getloadavg()[0]:.1f}",
          flush=True)
    got = {"this": [], "other": []}
    for r in range(a.pairs):
        for k in (("this", "other") if r % 2 else ("other", "this")):
            procs[k].stdin.write("call\n")
            procs[k].stdin.flush()
            got[k].append(answer(k))
        print(f"pair {r}: this {got['this'][-1]['cpu']:.3f} s, other {got['other'][-1]['cpu']:.3f} s CPU", flush=True)
    for p in procs.values():
        p.stdin.close()
        p.wait()
    for k in ("this", "other"):
        g = got[k]
        print(f"{k} ({roots[k]}): CPU median {statistics.median(x['cpu'] for x in g):.3f} s, wall median "
              f"{statistics.median(x['wall'] for x in g):.3f} s, <= 0.5 s CPU in {sum(x['cpu'] <= 0.5 for x in g)} "
              f"of {len(g)}; critical friction {g[0]['decided'][0]}, FS {g[0]['decided'][1]}")
    ratio = statistics.median(o["cpu"] / t["cpu"] for t, o in zip(got["this"], got["other"]))
    decided = [x["decided"] for k in got for x in got[k]]
    same = all(d == decided[0] for d in decided)
    print(f"median pair ratio (other / this, CPU) {ratio:.3f}; every call decided the same (φc, FS, each member's "
          f"stage and verdict) to the bit: {same} ({len(decided[0][2])} stages, {len(decided[0][3])} probes); load "
          f"{os.getloadavg()[0]:.1f}")


if __name__ == "__main__":
    main()
