"""A lever of a batch's equilibrium stages against the code it replaced, in one process.

    python benchmarks/batch_levers.py [--samples 200] [--batch 40] [--rounds 3] [--lever screen|detect|all]

The members of Example II's DDA-judged study (``benchmarks/stage_levers.py``'s samples: group
{0, 1} of ``scenes/example_2.py``, friction N(22°, 2°), cohesion N(20 kPa, 5 kPa), correlated
−0.3, seed 1) settled as ``ddatai.limit_batch.settle_many`` settles them, a batch of
``--batch`` at a time (``screened_ahead``, then each member's ``ddatai.start.settle``), with
the lever and with the code before it put back, batch by batch, the order alternating,
``--rounds`` times; each batch's CPU time (this process's: the machine is shared, and a pair in
one process sees the same load) and a hash of each settled state (vertices and contact memory).
Levers:

- ``screen``: each member's screen done once, in ``screened_ahead`` (its first program solved
  side by side, the rest as the stage alone asks them), and the batch's first detection shared
  (``ddatai.batch_detect``), against ``screened_ahead`` before: each member's first program
  built and solved ahead, and the member's stage doing its screen again;
- ``detect``: the first detection shared, against each member detecting on its own (the
  screens done once in both).

Prints, per lever, the CPU ms a member of a batch's stages take with and without it, their
ratio, the median ratio of the pairs, and whether every settled state is the same to the bit.
Threads pinned (BLAS one).
"""

from __future__ import annotations

import argparse
import contextlib
import os

for _k in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_k, "1")

import statistics  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

from stage_levers import _digest, _members  # noqa: E402


@contextlib.contextmanager
def _programs_ahead(steppers, states):
    """``screened_ahead`` before the screens were done once: each member's first program built
    and solved ahead (side by side), the member's stage then doing its whole screen."""
    from ddatai import limit_batch as lb, limit_equilibrium as le
    from ddatai.mechanisms import screen_program

    programs = [p for p in (screen_program(st, s) for st, s in zip(steppers, states)) if p is not None]
    answers = lb.solve_programs(programs)
    le.PRIMED.update(answers)
    try:
        yield
    finally:
        for key in answers:
            le.PRIMED.pop(key, None)


def _levers() -> dict:
    """{name: (the batch's context without the lever, with it)}."""
    from ddatai import batch_detect, limit_batch

    share = batch_detect.share_detection

    @contextlib.contextmanager
    def unshared(steppers, states):
        batch_detect.share_detection = lambda *args: 0
        try:
            with limit_batch.screened_ahead(steppers, states):
                yield
        finally:
            batch_detect.share_detection = share

    return {"screen": (_programs_ahead, limit_batch.screened_ahead),
            "detect": (unshared, limit_batch.screened_ahead)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--samples", type=int, default=200)
    ap.add_argument("--batch", type=int, default=40)
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--lever", default="all", choices=("screen", "detect", "all"))
    a = ap.parse_args()
    from ddatai.start import settle
    from ddatai.step import Stepper

    models = _members(a.samples)
    batches = [models[b:b + a.batch] for b in range(0, len(models), a.batch)]
    levers = _levers()
    names = list(levers) if a.lever == "all" else [a.lever]
    print(f"# {a.samples} members in batches of {a.batch}, {a.rounds} rounds; load {os.getloadavg()[0]:.1f}")
    for name in names:
        contexts = levers[name]
        times = {True: [], False: []}
        same = True
        for r in range(a.rounds):
            for i, part in enumerate(batches):
                digests = {}
                for lever_on in ((True, False) if (r + i) % 2 else (False, True)):
                    steppers, states = [Stepper(m) for m in part], [m.initial_state() for m in part]
                    c = time.process_time()
                    with contexts[lever_on](steppers, states):
                        settled = [settle(st, s)[0] for st, s in zip(steppers, states)]
                    times[lever_on].append((time.process_time() - c) / len(part))
                    digests[lever_on] = [_digest(s) for s in settled]
                same &= digests[True] == digests[False]
        on, off = statistics.fmean(times[True]), statistics.fmean(times[False])
        pairs = statistics.median(b / a for a, b in zip(times[True], times[False]))
        print(f"{name}: {1e3 * on:.2f} ms with, {1e3 * off:.2f} ms without (CPU, a member's share of its batch's "
              f"stages); without/with {off / on:.3f}, median pair {pairs:.3f}; settled states the same to the bit: "
              f"{same}")


if __name__ == "__main__":
    main()
