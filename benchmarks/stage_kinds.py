"""The equilibrium stages of a study's members side by side, kind by kind: two checkouts paired.

    python benchmarks/stage_kinds.py [--samples 200] [--batch 40] [--repeats 2] [--vs OTHER_CHECKOUT]

The members of Example II's DDA-judged study (``benchmarks/stage_levers.py``'s: group {0, 1}
of ``scenes/example_2.py``, friction N(22°, 2°), cohesion N(20 kPa, 5 kPa) correlated −0.3,
seed 1; two free blocks, 12 unknowns), built once in this checkout and pickled, split by what
their stage does (each settled alone once, here): *held* (blocks held), *released after
solves* (the return mapping stalls, the open-close test releases) and *released by the screen*
(before any solve). Each child process, a fresh one per checkout and repeat (alternating, threads
pinned), settles each kind's members as ``ddatai.limit_batch.settle_many`` does — the screens
ahead, then every member's ``ddatai.start.settle`` side by side (`ddatai.side_by_side`), batches
of ``--batch`` — once to warm, then timed: the CPU time (this process's; the machine is shared)
of each kind's batches over its members, and a digest of every member's settled state (vertices,
contact memory) with its held and released blocks and solves. Printed: per checkout and kind
the ms a member (each repeat, and the median), and whether every member's digest is the same
in both checkouts. Also the ``side_by_side.EVALUATIONS`` of the timed held batches.
"""

from __future__ import annotations

import argparse
import json
import os
import pickle
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PINNED = {k: "1" for k in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "TI_CPU_MAX_NUM_THREADS")}

TIME = r"""
import hashlib, json, pickle, sys, time
from functools import partial
sys.path.insert(0, {root!r})
import numpy as np
from ddatai import side_by_side, stage_batch  # noqa: F401  (registers the stage's operations)
from ddatai.limit_batch import screened_ahead
from ddatai.start import settle
from ddatai.step import Stepper
models, kinds = pickle.load(open({members!r}, "rb"))

def digest(state):
    h = hashlib.sha256(state.vertex_xy.tobytes())
    for _, v in sorted(vars(state.memory).items()):
        if isinstance(v, np.ndarray):
            h.update(v.tobytes())
    return h.hexdigest()[:16]

def batches(idx):
    for b in range(0, len(idx), {batch}):
        part = [models[i] for i in idx[b:b + {batch}]]
        steppers, states = [Stepper(m) for m in part], [m.initial_state() for m in part]
        with screened_ahead(steppers, states):
            yield side_by_side.run([partial(settle, st, s) for st, s in zip(steppers, states)])

out = {{}}
for kind, idx in kinds.items():
    list(batches(idx))  # warm
    before = side_by_side.EVALUATIONS.copy()
    t = time.process_time()
    got = [x for part in batches(idx) for x in part]
    ms = 1e3 * (time.process_time() - t) / max(len(idx), 1)
    done = side_by_side.EVALUATIONS - before
    out[kind] = dict(ms=ms, digests=[(digest(s), int(r.held), int(r.released), int(r.solves)) for s, r in got],
                     evaluations={{f"{{k[0]}}{{'' if k[1] else ' (alone)'}}": v for k, v in sorted(done.items())}})
print(json.dumps(out))
"""


def _classify(models) -> dict:
    from ddatai.limit_batch import screened_ahead
    from ddatai.start import settle
    from ddatai.step import Stepper

    kinds = {"held": [], "released after solves": [], "released by the screen": []}
    for i, m in enumerate(models):
        st, s = Stepper(m), m.initial_state()
        with screened_ahead([st], [s]):
            _, rec = settle(st, s)
        kind = "held" if rec.held else ("released after solves" if rec.solves else "released by the screen")
        kinds[kind].append(i)
    return kinds


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--samples", type=int, default=200)
    ap.add_argument("--batch", type=int, default=40)
    ap.add_argument("--repeats", type=int, default=2)
    ap.add_argument("--vs", default="", help="another checkout, timed alternately with this one")
    a = ap.parse_args()
    os.environ.update(PINNED)
    sys.path.insert(0, str(ROOT))
    sys.path.insert(0, str(ROOT / "benchmarks"))
    from stage_levers import _members

    models = _members(a.samples)
    kinds = _classify(models)
    roots = [str(ROOT)] + ([str(Path(a.vs).resolve())] if a.vs else [])
    got = {r: [] for r in roots}
    loads = []
    with tempfile.TemporaryDirectory() as tmp:
        members = str(Path(tmp) / "members.pkl")
        with open(members, "wb") as f:
            pickle.dump((models, kinds), f)
        for rep in range(a.repeats):
            for r in (roots if rep % 2 == 0 else roots[::-1]):
                loads.append(os.getloadavg()[0])
                out = subprocess.run([sys.executable, "-c", TIME.format(root=r, members=members, batch=a.batch)],
                                     check=True, env={**os.environ, **PINNED}, cwd=r, capture_output=True,
                                     text=True).stdout
                got[r].append(json.loads(out.strip().splitlines()[-1]))
    print(f"{a.samples} members ({', '.join(f'{len(v)} {k}' for k, v in kinds.items())}), batches of {a.batch}, "
          f"{a.repeats} repeats; load {min(loads):.1f}-{max(loads):.1f}; CPU ms a member side by side")
    print("| checkout | " + " | ".join(kinds) + " | ms a sample (all kinds) |")
    print("|---|" + "---|" * (len(kinds) + 1))
    for r in roots:
        cells = []
        for k in kinds:
            ms = [run[k]["ms"] for run in got[r]]
            cells.append(", ".join(f"{x:.2f}" for x in ms) + f" (median {statistics.median(ms):.2f})")
        total = [sum(run[k]["ms"] * len(kinds[k]) for k in kinds) / a.samples for run in got[r]]
        print(f"| {r} | " + " | ".join(cells) + f" | {statistics.median(total):.2f} |")
    for r in roots:
        print(f"evaluations of the held batches, {r}: {got[r][0]['held']['evaluations']}")
    if a.vs:
        same = all(got[roots[0]][0][k]["digests"] == got[roots[1]][0][k]["digests"] for k in kinds)
        print(f"every member's settled state, held and released blocks and solves the same to the bit: {same}")


if __name__ == "__main__":
    main()
