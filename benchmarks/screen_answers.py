"""The limit-equilibrium answers of a study's screens in two checkouts, program by program.

    python benchmarks/screen_answers.py --vs OTHER_CHECKOUT [--samples 2000] [--batch 40]

The members of Example II's DDA-judged study (``benchmarks/stage_levers.py``'s: group {0, 1}
of ``scenes/example_2.py``, friction N(22°, 2°), cohesion N(20 kPa, 5 kPa) correlated −0.3,
seed 1), built once here and pickled. A fresh process per checkout (threads pinned) answers
each member's screen (``ddatai.mechanisms.screen_programs``) as a batch does: its first program
solved side by side with its batch's (``ddatai.limit_batch.solve_programs``, batches of
``--batch``), its later ones alone (``limit_equilibrium._solve_program``); and each program
alone too. Printed, for each way of solving: how many answers are the same to the bit in both
checkouts; the largest difference of the unbalance Σ(r⁺ + r⁻) and of y (of its largest
component); how many verdicts differ — held (Σ(r⁺ + r⁻) ≤ ``HELD`` a block) or not, the blocks
that move in the mechanism (``MOVING``) —; and whether every screen released the same blocks.
Also each checkout's interior-point iterations (Newton steps) over all the programs alone.
"""

from __future__ import annotations

import argparse
import os
import pickle
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
PINNED = {k: "1" for k in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "TI_CPU_MAX_NUM_THREADS")}

ANSWER = r"""
import pickle, sys
sys.path.insert(0, {root!r})
import numpy as np
from ddatai import limit_batch, limit_equilibrium as le
from ddatai.mechanisms import screen_programs
from ddatai.step import Stepper
models = pickle.load(open({members!r}, "rb"))
steps = [0]
cholesky = le._DenseFactor.__init__
def counted(self, matrix):
    steps[0] += 1
    cholesky(self, matrix)
le._DenseFactor.__init__ = counted

def plain(out):
    return None if out is None else (float(out[0]), np.asarray(out[1]).copy())

out = []
for b in range(0, len(models), {batch}):
    part = models[b:b + {batch}]
    screens = [screen_programs(Stepper(m), m.initial_state()) for m in part]
    firsts = []
    for g in screens:
        try:
            firsts.append(next(g))
        except StopIteration:
            firsts.append(None)
    answers = limit_batch.solve_programs([p for p in firsts if p is not None])
    for g, first in zip(screens, firsts):
        batch, alone = [], []
        program = first
        try:
            while program is not None:
                got = answers[le.program_key(*program)] if not batch else le._solve_program(*program)
                alone.append(plain(le._solve_program(*program)))
                batch.append(plain(got))
                program = g.send(got)
        except StopIteration as end:
            released = end.value
        out.append(dict(batch=batch, alone=alone, released=None if released is None else np.asarray(released)))
pickle.dump(dict(members=out, steps=steps[0]), open({answers!r}, "wb"))
"""


def _verdicts(answer, n_blocks):
    from ddatai import limit_equilibrium as le

    if answer is None:
        return None
    unbalance, y = answer
    v = np.abs(y).reshape(-1, 3).sum(axis=1)
    return bool(unbalance <= le.HELD * n_blocks), tuple(v > le.MOVING * v.max(initial=0.0))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--samples", type=int, default=2000)
    ap.add_argument("--batch", type=int, default=40)
    ap.add_argument("--vs", required=True, help="another checkout")
    a = ap.parse_args()
    os.environ.update(PINNED)
    sys.path.insert(0, str(ROOT))
    sys.path.insert(0, str(ROOT / "benchmarks"))
    from stage_levers import _members

    models = _members(a.samples)
    roots = [str(ROOT), str(Path(a.vs).resolve())]
    got = []
    with tempfile.TemporaryDirectory() as tmp:
        members = str(Path(tmp) / "members.pkl")
        with open(members, "wb") as f:
            pickle.dump(models, f)
        for k, r in enumerate(roots):
            answers = str(Path(tmp) / f"answers{k}.pkl")
            subprocess.run([sys.executable, "-c", ANSWER.format(root=r, members=members, batch=a.batch,
                                                                answers=answers)],
                           check=True, env={**os.environ, **PINNED}, cwd=r)
            with open(answers, "rb") as f:
                got.append(pickle.load(f))
    print(f"{a.samples} members, batches of {a.batch}; {roots[0]} against {roots[1]}")
    for r, g in zip(roots, got):
        n = sum(len(m["alone"]) for m in g["members"])
        print(f"{r}: {n} programs, {g['steps']} Newton steps alone ({g['steps'] / max(n, 1):.1f} a program)")
    same_released = all(
        (x["released"] is None) == (y["released"] is None) and
        (x["released"] is None or np.array_equal(x["released"], y["released"]))
        for x, y in zip(got[0]["members"], got[1]["members"]))
    print("| answers | programs | the same to the bit | max abs Δ unbalance | max Δ y / max abs y | "
          "None in one only | verdicts differ |")
    print("|---|---|---|---|---|---|---|")
    for way in ("batch", "alone"):
        n = bits = none = flips = 0
        d_unb = d_y = 0.0
        for x, y, model in zip(got[0]["members"], got[1]["members"], models):
            for p, q in zip(x[way], y[way]):
                n += 1
                if (p is None) != (q is None):
                    none += 1
                    continue
                if p is None:
                    bits += 1
                    continue
                bits += p[0] == q[0] and np.array_equal(p[1], q[1])
                d_unb = max(d_unb, abs(p[0] - q[0]))
                d_y = max(d_y, float(np.abs(p[1] - q[1]).max(initial=0.0) / max(np.abs(q[1]).max(initial=0.0), 1e-300)))
                blocks = len(p[1]) // 3
                flips += _verdicts(p, blocks) != _verdicts(q, blocks)
            n += abs(len(x[way]) - len(y[way]))
        print(f"| {way} | {n} | {bits} | {d_unb:.2e} | {d_y:.2e} | {none} | {flips} |")
    print(f"every screen released the same blocks: {same_released}")


if __name__ == "__main__":
    main()
