"""Limit equilibrium asked before the first return-mapping iterate of a large model's first
pseudo-step, instead of only where the iteration stalls (`ddatai.return_mapping`; the library
unchanged: the change is patched into `return_mapping.return_mapping`'s source here).

On the jointed slope family the first pseudo-step's return mapping releases its mechanisms one
throw at a time — on the 1,537-block slope 15 iterations that each end by throwing 1 to 10
blocks, ~280 solves with most of them factorisations, before it stalls and limit equilibrium
releases 593 blocks at once. The blocks that limit equilibrium lets move have no admissible
contact forces (the static theorem): no equilibrium of the stage holds them, so releasing them
first is never on the unsafe side; what can change is the path, and with it which of the
other blocks end held, released or in doubt.

    PYTHONPATH=$PWD python benchmarks/stage_le_first.py 1600 [--main] [--family grid]
"""

from __future__ import annotations

import argparse
import inspect
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import ddatai as dd  # noqa: E402
import ddatai.limit_equilibrium as le  # noqa: E402
import ddatai.return_mapping as rm  # noqa: E402
import ddatai.start as start  # noqa: E402
import scaling_scenes  # noqa: E402

#: asked first only in models of more free blocks than this (`model.SMALL_MODEL_BLOCKS`)
FIRST_ABOVE = 64


def le_first(at_throw: bool) -> None:
    """Patch `return_mapping.return_mapping`, in a first pseudo-step (no last increment) of a model
    of more than FIRST_ABOVE free blocks: the blocks that limit equilibrium lets move are released
    (``out``) before the loop (``at_throw`` False), or with the first blocks that an iterate throws
    (``at_throw``: a model that holds, whose iterates throw nothing, never asks), and its answer is
    kept (``asked``) for the released blocks it leaves."""
    source = inspect.getsource(rm.return_mapping)
    if at_throw:
        anchor = "        out |= mechanism\n    else:\n"
        early = (
            "        if thrown and asked is None and not np.isfinite(contraction) and stepper.model.n_free > FIRST_ABOVE:\n"
            "            found = unsupported_blocks(stepper.model, state.vertex_xy, geom,\n"
            "                                       Contacts(**{**vars(contacts), 'line': line0}), touching, out | mechanism)\n"
            "            if found is not None:\n"
            "                mechanism = mechanism | (found & ~out)\n"
            "                asked = out | mechanism, found\n")
        patched = source.replace(anchor, early + anchor)
    else:
        anchor = "    while solves < MAX_STAGE_SOLVES:\n"
        early = (
            "    if not np.isfinite(contraction) and stepper.model.n_free > FIRST_ABOVE:\n"
            "        asked = out.copy(), unsupported_blocks(stepper.model, state.vertex_xy, geom,\n"
            "                                               Contacts(**{**vars(contacts), 'line': line0}), touching, out)\n"
            "        if asked[1] is not None and np.any(asked[1] & ~out):\n"
            "            out = out | asked[1]\n"
            "            asked = out.copy(), asked[1]\n")
        patched = source.replace(anchor, early + anchor)
    assert source.count(anchor) == 1, "return_mapping's source changed: the patch no longer applies"
    rm.FIRST_ABOVE = FIRST_ABOVE
    exec(compile(patched, rm.__file__, "exec"), rm.__dict__)
    start.return_mapping = rm.return_mapping


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("n", type=int, nargs="?", default=1600)
    ap.add_argument("--family", default="slope")
    ap.add_argument("--main", action="store_true", help="main's stage (nothing patched), the pair's other arm")
    ap.add_argument("--before", action="store_true", help="asked before the loop, not at the first throw")
    args = ap.parse_args()
    if not args.main:
        le_first(not args.before)
    spent = [0.0, 0]
    original = le.unsupported_blocks

    def timed(*a, **kw):
        t = time.process_time()
        try:
            return original(*a, **kw)
        finally:
            spent[0] += time.process_time() - t
            spent[1] += 1

    rm.unsupported_blocks = timed
    scene, params = getattr(scaling_scenes, f"{args.family}_scene")(args.n)
    stage = start._stage
    cpu = [0.0]

    def timed_stage(*a, **kw):
        t = time.process_time()
        try:
            return stage(*a, **kw)
        finally:
            cpu[0] += time.process_time() - t

    start._stage = timed_stage
    t = time.process_time()
    r = dd.simulate(scene, params, steps=1)
    record = dict(zip(r.start.dtype.names, r.start[0].tolist()))
    print(args.family, args.n, "main" if args.main else "before" if args.before else "at-throw",
          {k: record[k] for k in ("solves", "factorisations", "held", "released", "in_doubt", "settlement")},
          f"stage CPU {cpu[0]:.2f} s; limit equilibrium {spent[1]} calls {spent[0]:.2f} s; "
          f"CPU incl. build+1 step {time.process_time() - t:.2f}", flush=True)


if __name__ == "__main__":
    main()
