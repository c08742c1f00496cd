"""Each probe of ``kgm.evaluate(Example I, [0, 1], "dda")`` judged by this checkout and by another
one (``--against``, e.g. a clone of main), to the bit: the search may ask other probes than the
other checkout's search asks, but a probe at the same (friction, reduction) must be judged the
same.

    python benchmarks/evaluate_probes.py --against ../main

This checkout runs the evaluation (fused engine, threads pinned) and records its rounds (the
probes `kgm.judges.dda` hands `judge_many` together) and each probe's judgement and settled
stage; the other checkout, in its own process, judges the same rounds with its own
``judge_many``. Both report, probe by probe: stable, how the run ended, the final displacement
(``repr``), steps, and the settled stage (a hash of its vertices, velocities and contact memory,
and its held, released and solves). Prints the rounds, φc and FS, and whether every probe agreed.
The fused kernel is taken from Taichi's offline cache (``python -m ddatai.fused`` first).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from pathlib import Path

for _k in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "TI_CPU_MAX_NUM_THREADS"):
    os.environ.setdefault(_k, "1")

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(Path(__file__).resolve().parent))
from evaluate_pair import state_digest  # noqa: E402


def judged(root: str, rounds) -> dict:
    """In checkout ``root`` (first on ``sys.path``): the evaluation's rounds (``rounds`` None: run
    the evaluation and take its rounds) judged by its ``judge_many``, each probe's figures."""
    sys.path.insert(0, root)
    import dataclasses

    import kgm
    import kgm.judges.dda as dda_module
    import ddatai.start as start
    from kgm.build import prepare
    from scenes import example_1

    stages, asked = [], []
    settle, judge_many = start.settle, dda_module.judge_many

    def settle_logged(stepper, state, *a, **k):  # the stages start in the members' order
        slot = len(stages)
        stages.append(None)
        s, rec = out = settle(stepper, state, *a, **k)
        stages[slot] = [state_digest(s), int(rec.held), int(rec.released), int(rec.solves)]
        return out

    def judge_many_logged(scene, system, blocks, todo, **k):
        stages.clear()
        out = judge_many(scene, system, blocks, todo, **k)
        asked.append([[[f, r], bool(j.stable), str(j.end), repr(j.displacement), int(j.steps), stage]
                      for (f, r), j, stage in zip(todo, out, stages)])
        return out

    start.settle = settle_logged
    scene, params = example_1.build()
    params = dataclasses.replace(params, kernels="fused")
    if rounds is None:
        dda_module.judge_many = judge_many_logged
        row = kgm.evaluate(scene, [0, 1], "dda", params=params)
        return {"rounds": asked, "fs": repr(row.fs), "phi": repr(row.critical_friction)}
    problem = prepare(scene, params=params)
    for todo in rounds:
        judge_many_logged(scene, problem.system, frozenset([0, 1]), [tuple(p) for p in todo],
                          settings=problem.settings.dda, params=params)
    return {"rounds": asked}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--against", required=True, help="the other checkout's root (e.g. a clone of main)")
    ap.add_argument("--worker", help=argparse.SUPPRESS)
    a = ap.parse_args()
    if a.worker:
        rounds = json.loads(sys.stdin.read())
        print(json.dumps(judged(a.worker, rounds)))
        return
    other = str(Path(a.against).resolve())
    here = judged(str(ROOT), None)
    rounds = [[p[0] for p in r] for r in here["rounds"]]
    proc = subprocess.run([sys.executable, __file__, "--against", other, "--worker", other], cwd=other,
                          input=json.dumps(rounds), capture_output=True, text=True, check=True)
    there = json.loads(proc.stdout.strip().splitlines()[-1])
    same = 0
    for k, (mine, theirs) in enumerate(zip(here["rounds"], there["rounds"])):
        print(f"round {k + 1}: {len(mine)} probes")
        for p, q in zip(mine, theirs):
            same += p == q
            (f, r), stable, end, disp, steps, stage = p
            print(f"  φ {f if f is None else round(f, 4)}, F {r:.4f}: stable {stable}, {end}, displacement {disp}, "
                  f"{steps} steps, stage {stage}; the other checkout: {'the same' if p == q else q}")
    n = sum(map(len, here["rounds"]))
    print(f"φc {here['phi']}, FS {here['fs']}; {len(here['rounds'])} rounds, {n} probes; the same to the bit "
          f"in the other checkout: {same} of {n}")


if __name__ == "__main__":
    main()
