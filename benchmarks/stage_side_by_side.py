"""A batch's equilibrium stages side by side (``ddatai.side_by_side``) against one after the
other, in one process.

    python benchmarks/stage_side_by_side.py [--samples 200] [--batch 40] [--rounds 3] [--evaluate 11]

The members of Example II's DDA-judged study (``benchmarks/stage_levers.py``'s samples: group
{0, 1} of ``scenes/example_2.py``, friction N(22°, 2°), cohesion N(20 kPa, 5 kPa), correlated
−0.3, seed 1) settled as ``ddatai.limit_batch.settle_many`` settles them, a batch of
``--batch`` at a time: the screens ahead (``screened_ahead``), then every member's
``ddatai.start.settle`` side by side (their contact assembly, contact law and block
displacements evaluated for the members waiting at them at once, `ddatai.stage_batch`) or one
after the other (``side_by_side.ENABLED = False``, the code before), batch by batch, the order
alternating, ``--rounds`` times. Each batch's CPU time (this process's: the machine is shared,
and a pair in one process sees the same load) and a hash of each settled state (vertices and
contact memory) with its record's held, released and solves. Threads pinned (BLAS one).

Prints the CPU ms a member of a batch's stages takes each way, their ratio, the median ratio of
the pairs, and whether every member's settled state and record are the same to the bit.

``--evaluate N``: then ``kgm.evaluate(Example I, [0, 1], "dda")`` (``scenes/example_1.py``, its
own parameters) with the fused kernel loaded in the process, once to warm, then N pairs alternating side by side and one after the other:
the median CPU and wall seconds of a call each way, the median pair ratio, how many calls took
at most 0.5 s, and each way's critical friction and FS (the same in every call).
"""

from __future__ import annotations

import argparse
import os

for _k in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_k, "1")

import statistics  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from functools import partial  # noqa: E402
from pathlib import Path  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

from stage_levers import _digest, _members  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--samples", type=int, default=200)
    ap.add_argument("--batch", type=int, default=40)
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--evaluate", type=int, default=0)
    a = ap.parse_args()
    from ddatai import side_by_side, stage_batch  # noqa: F401  (registers the stage's operations)
    from ddatai.limit_batch import screened_ahead
    from ddatai.start import settle
    from ddatai.step import Stepper

    models = _members(a.samples)
    batches = [models[b:b + a.batch] for b in range(0, len(models), a.batch)]
    print(f"# {a.samples} members in batches of {a.batch}, {a.rounds} rounds; greenlet: "
          f"{side_by_side.available()}; load {os.getloadavg()[0]:.1f}", flush=True)
    times = {True: [], False: []}
    same = True
    held = 0
    for r in range(a.rounds):
        for i, part in enumerate(batches):
            digests = {}
            for together in ((True, False) if (r + i) % 2 else (False, True)):
                side_by_side.ENABLED = together
                steppers, states = [Stepper(m) for m in part], [m.initial_state() for m in part]
                c = time.process_time()
                with screened_ahead(steppers, states):
                    out = side_by_side.run([partial(settle, st, s) for st, s in zip(steppers, states)])
                times[together].append((time.process_time() - c) / len(part))
                digests[together] = [(_digest(s), rec.held, rec.released, rec.solves) for s, rec in out]
                if together and r == 0:
                    held += sum(rec.held > 0 for _, rec in out)
            same &= digests[True] == digests[False]
    side_by_side.ENABLED = True
    on, off = statistics.fmean(times[True]), statistics.fmean(times[False])
    pairs = statistics.median(b / a for a, b in zip(times[True], times[False]))
    print(f"side by side {1e3 * on:.2f} ms, one after the other {1e3 * off:.2f} ms (CPU, a member's share of its "
          f"batch's stages; {held} of {a.samples} members hold blocks); ratio {off / on:.3f}, median pair "
          f"{pairs:.3f}; every settled state and record the same to the bit: {same}; load "
          f"{os.getloadavg()[0]:.1f}")
    if a.evaluate:
        evaluate(a.evaluate)


def evaluate(pairs: int) -> None:
    import kgm
    from ddatai import side_by_side
    from scenes import example_1

    from ddatai.fused import warm

    warm.warm()  # the fused kernel in this process (from Taichi's offline cache): kgm's bisection takes it
    scene, params = example_1.build()
    kgm.evaluate(scene, [0, 1], "dda", params=params)  # what the first call needs
    got = {True: [], False: []}
    for r in range(pairs):
        for together in ((True, False) if r % 2 else (False, True)):
            side_by_side.ENABLED = together
            c, w = time.process_time(), time.perf_counter()
            row = kgm.evaluate(scene, [0, 1], "dda", params=params)
            got[together].append((time.process_time() - c, time.perf_counter() - w, round(row.critical_friction, 6),
                                  round(row.fs, 6)))
    side_by_side.ENABLED = True
    for together, label in ((True, "side by side"), (False, "one after the other")):
        g = got[together]
        print(f"kgm.evaluate(Example I, [0, 1], 'dda') {label}: CPU median {statistics.median(x[0] for x in g):.3f} s, "
              f"wall median {statistics.median(x[1] for x in g):.3f} s, <= 0.5 s CPU in "
              f"{sum(x[0] <= 0.5 for x in g)} of {len(g)}; (critical friction, FS): {sorted({x[2:] for x in g})}")
    ratio = statistics.median(b[0] / a[0] for a, b in zip(got[True], got[False]))
    print(f"median pair ratio (one after the other / side by side, CPU) {ratio:.3f}; load {os.getloadavg()[0]:.1f}")


if __name__ == "__main__":
    main()
