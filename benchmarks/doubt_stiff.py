"""Whether the stage's return mapping, continued with every block kept stiff, converges where
its test of the blocks in doubt does not (jointed slope family, `scaling_scenes.slope_scene`;
benchmarks/results/stage_in_doubt.md, "A stiff test of the blocks in doubt").

At each call of the open-close test of the blocks out of balance that limit equilibrium holds
(`ddatai.mechanisms.loaded_away` with ``converged_only``, inside `ddatai.return_mapping`), the
script first continues the return mapping (`return_mapping._iterate`) from where it stopped
(its last guess: slips, openings by return mapping, closed contacts) for up to ``--solves``
solves, stalling after ``--stall`` iterations without halving the largest excess, with each
vertex-edge contact that has opened or closed ``--flips`` times (0: every one) opening by the
return mapping of its normal spring, K kept: every closed contact keeps its normal and shear
springs, so no block loses its stiffness (the candidate that the section "Left open" named).
It reports whether it converges within the stage's strict tolerance, its solves and CPU time,
the blocks still out of balance, and whether what is left is a steady slide (contacts whose slip
grows by the same amount each iterate: a mechanism that each iterate moves by its excess over
the shear spring) or a decaying one. The stage then goes on as without the script (the
library's own test follows); ``--adopt`` stops the run where a continuation converges (it would
change the verdict: the library would have to hand over that equilibrium).

    PYTHONPATH=$PWD python benchmarks/doubt_stiff.py 400 [--solves 1000 --stall 200 --flips 0]
    PYTHONPATH=$PWD python benchmarks/doubt_stiff.py 400 --solves 1500 --stall 300 --rounds 10
"""

from __future__ import annotations

import argparse
import inspect
import sys
import time
from collections import deque
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

import ddatai as dd  # noqa: E402
import ddatai.mechanisms as mech  # noqa: E402
import ddatai.return_mapping as rm  # noqa: E402
import ddatai.start as start  # noqa: E402
from ddatai.contacts import subset_contacts  # noqa: E402
from scaling_scenes import slope_scene  # noqa: E402

#: the last iterations over which a slide counts as steady (its slip increment the same)
WINDOW = 50


def continued(stepper, state, geom, frame, contacts, raw, out, size, args):
    """The return mapping continued from ``raw`` (module docstring): (outcome, report line)."""
    model = stepper.model
    saved = rm.MAX_ITERATIONS, rm.STALL_ITERATIONS, rm.CHATTER_FLIPS, rm.anderson, rm.solve
    slips: deque = deque(maxlen=2 * WINDOW + 1)
    factorised = [0]

    def anderson(history, x, g):
        slips.append(g[:contacts.n].copy())
        return saved[3](history, x, g)

    def solve(*a, **kw):
        factorised[0] += not kw.get("reuse", False)
        return saved[4](*a, **kw)

    rm.MAX_ITERATIONS, rm.STALL_ITERATIONS, rm.CHATTER_FLIPS = args.solves, args.stall, args.flips
    rm.anderson, rm.solve = anderson, solve
    c = contacts.copy()
    t0 = time.process_time()
    try:
        outcome, _ = rm._iterate(stepper, frame, c, geom, out, size, raw.copy(), True)
    finally:
        rm.MAX_ITERATIONS, rm.STALL_ITERATIONS, rm.CHATTER_FLIPS, rm.anderson, rm.solve = saved
    cpu = time.process_time() - t0
    if outcome.disp is None:
        return outcome, f"a solve not finite after {outcome.solves} solves"
    thrown = rm.mechanisms(stepper, state.vertex_xy, geom, c, outcome.disp, out, size)
    left = mech.out_of_balance(model, c, outcome) & ~out
    over = outcome.excess > outcome.loose
    ratio = float(np.max(np.maximum(outcome.excess, 0.0) / outcome.loose, initial=0.0))
    steady = "n/a"
    if len(slips) == slips.maxlen and over.any():
        late = slips[-1] - slips[WINDOW]      # the slip of the last WINDOW iterations
        early = slips[WINDOW] - slips[0]      # ... and of the WINDOW before
        moving = over & (np.abs(late) > 0.0)
        same = moving & (np.abs(late - early) <= 0.05 * np.abs(late))
        blocks = np.zeros(model.n_blocks, bool)
        blocks[c.block_a[same]] = True
        blocks[c.block_b[same]] = True
        steady = (f"{int(same.sum())} of {int(over.sum())} contacts over the tolerance slide steadily "
                  f"(slip of the last {WINDOW} iterates within 5 % of the {WINDOW} before) at "
                  f"{int((blocks & ~model.block_fixed).sum())} blocks; median slip ratio late/early "
                  f"{np.median(np.abs(late[moving]) / np.maximum(np.abs(early[moving]), 1e-300)):.3g}")
    return outcome, (f"continued: {outcome.solves} solves ({factorised[0]} factorised), {cpu:.2f} CPU s, "
                     f"converged (strict) {outcome.strict}, blocks out of balance {int(left.sum())}, "
                     f"largest excess / tolerance {ratio:.3g}, thrown {int(thrown.sum())}; {steady}")


def rounds(stepper, state, geom, frame, contacts, raw, out, size, args) -> str:
    """``--rounds R``: the continuation (`continued`'s settings) repeated up to R times, each time
    releasing what it throws (`return_mapping.mechanisms`) or, where it stalls, the blocks of its
    steady slides (contacts over the tolerance whose slip of the last WINDOW iterates is within
    5 % of the WINDOW before) on which their loads do positive work over the last WINDOW
    iterates' displacement (`mechanisms.driven`), until it converges within the strict tolerance
    or releases nothing. A report line."""
    model = stepper.model
    free = ~model.block_fixed
    dt = mech.pseudo_time_step(stepper, geom, size)  # the stage's: the first pseudo-step's geometry
    saved = rm.MAX_ITERATIONS, rm.STALL_ITERATIONS, rm.CHATTER_FLIPS, rm.anderson, rm.stage_law
    now, c, guess = out.copy(), contacts.copy(), raw.copy()
    t0, solves, lines = time.process_time(), 0, []
    for k in range(args.rounds):
        slips: deque = deque(maxlen=2 * WINDOW + 1)
        disps: deque = deque(maxlen=2 * WINDOW + 1)
        n = c.n

        def anderson(history, x, g):
            slips.append(g[:n].copy())
            return saved[3](history, x, g)

        def law(m, cc, vec, sca, disp, *a, **kw):
            disps.append(disp.copy())
            return saved[4](m, cc, vec, sca, disp, *a, **kw)

        rm.MAX_ITERATIONS, rm.STALL_ITERATIONS, rm.CHATTER_FLIPS = args.solves, args.stall, args.flips
        rm.anderson, rm.stage_law = anderson, law
        try:
            outcome, guess = rm._iterate(stepper, frame, c, geom, now, size, guess, True)
        finally:
            rm.MAX_ITERATIONS, rm.STALL_ITERATIONS, rm.CHATTER_FLIPS, rm.anderson, rm.stage_law = saved
        solves += outcome.solves
        if outcome.disp is None:
            lines.append(f"round {k + 1}: a solve not finite")
            break
        if outcome.strict:
            lines.append(f"round {k + 1}: {outcome.solves} solves, converged: {int((free & ~now).sum())} held")
            break
        release = rm.mechanisms(stepper, state.vertex_xy, geom, c, outcome.disp, now, size)
        why = "thrown"
        over = outcome.excess > outcome.loose
        if not release.any() and len(slips) == slips.maxlen and over.any():
            late, early = slips[-1] - slips[WINDOW], slips[WINDOW] - slips[0]
            same = over & (np.abs(late) > 0.0) & (np.abs(late - early) <= 0.05 * np.abs(late))
            blocks = np.zeros(model.n_blocks, bool)
            blocks[c.block_a[same]] = True
            blocks[c.block_b[same]] = True
            blocks &= free & ~now
            release = mech.driven(stepper, state, geom, c, disps[-1] - disps[WINDOW], blocks)
            why = f"of {int(blocks.sum())} sliding steadily, driven"
        ratio = float(np.max(np.maximum(outcome.excess, 0.0) / outcome.loose, initial=0.0))
        lines.append(f"round {k + 1}: {outcome.solves} solves, out of balance "
                     f"{int((mech.out_of_balance(model, c, outcome) & ~now).sum())}, largest excess / tolerance "
                     f"{ratio:.3g}, released {int(release.sum())} ({why})")
        if not release.any():
            break
        now |= release
        keep = ~(now[c.block_a] | now[c.block_b])
        c, guess = subset_contacts(c, keep), guess.subset(keep)
        frame = rm.Frame.build(stepper, state, geom, c, dt)
    return (f"rounds: {solves} solves, {time.process_time() - t0:.2f} CPU s, released {int((now & ~out).sum())}; "
            + "; ".join(lines))


def retrying() -> None:
    """`return_mapping.return_mapping` with the retry (``--retry``, module docstring) patched into its
    source: where limit equilibrium holds every block left and the iteration has stalled, the
    return mapping goes on once more from its stalled guess (flip counts reset) before the test,
    once for each set of released blocks."""
    source = inspect.getsource(rm.return_mapping)
    patched = source.replace(
        "    touching, line0 =",
        "    retried = None\n    touching, line0 =", 1).replace(
        "            else:\n                # admissible forces do not prove a block held",
        "            elif retried is None or not np.array_equal(retried, out):\n"
        "                retried, guess = out.copy(), raw\n                continue\n"
        "            else:\n                # admissible forces do not prove a block held", 1)
    assert patched.count("retried") == 4, "return_mapping's source changed: the patch no longer applies"
    exec(compile(patched, rm.__file__, "exec"), rm.__dict__)
    start.return_mapping = rm.return_mapping


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("n", type=int, nargs="?", default=400)
    ap.add_argument("--solves", type=int, default=1000)
    ap.add_argument("--stall", type=int, default=200)
    ap.add_argument("--flips", type=int, default=0)
    ap.add_argument("--adopt", action="store_true")
    ap.add_argument("--rounds", type=int, default=0, help="the continuation repeated, releasing its throws and "
                    "driven steady slides (`rounds`)")
    ap.add_argument("--retry", action="store_true", help="the stage with the retry, without the continuation")
    ap.add_argument("--steps", type=int, default=1, help="steps after the start (--retry: the held blocks' motion)")
    args = ap.parse_args()
    if args.retry:
        retrying()
    if args.retry or args.steps > 1:
        return motion_run(args)
    scene, params = slope_scene(args.n)
    original_test, original_iterate = rm.loaded_away, rm._iterate
    last = {}
    calls = []

    def iterate(*a, **kw):
        outcome, raw = original_iterate(*a, **kw)
        last["raw"] = raw.copy()
        return outcome, raw

    def test(stepper, state, geom, frame, contacts, outcome, guess, out, size, converged_only=False):
        if converged_only:
            unbalanced = mech.out_of_balance(stepper.model, contacts, outcome) & ~out
            if args.rounds:
                calls.append(0)
                print(f"test call {len(calls)}: {int(unbalanced.sum())} blocks out of balance; "
                      + rounds(stepper, state, geom, frame, contacts, last["raw"], out, size, args), flush=True)
                return original_test(stepper, state, geom, frame, contacts, outcome, guess, out, size, converged_only)
            done, line = continued(stepper, state, geom, frame, contacts, last["raw"], out, size, args)
            calls.append(done.solves)
            print(f"test call {len(calls)}: {int(unbalanced.sum())} blocks out of balance; {line}", flush=True)
            if args.adopt and done.strict:
                raise SystemExit("a continuation converged: the verdict would change")
        return original_test(stepper, state, geom, frame, contacts, outcome, guess, out, size, converged_only)

    rm.loaded_away, rm._iterate = test, iterate
    t = time.process_time()
    r = dd.simulate(scene, params, steps=1)
    print(args.n, dict(zip(r.start.dtype.names, r.start[0].tolist())),
          f"continuation solves {sum(calls)}; CPU incl. build+1 step {time.process_time() - t:.2f}")


def motion_run(args) -> None:
    """The start (with ``--retry``: the retry patched in) and ``--steps`` steps: the start record, its
    CPU time, and how far the blocks it held move from where it handed them over, against its
    settlement (the check of tests/test_start.py: a held block moves no more than that)."""
    scene, params = slope_scene(args.n)
    t = time.process_time()
    r = dd.simulate(scene, params, steps=1)
    print(args.n, "retry" if args.retry else "main", dict(zip(r.start.dtype.names, r.start[0].tolist())),
          f"CPU incl. build+1 step {time.process_time() - t:.2f}", flush=True)
    if args.steps <= 1:
        return
    r = dd.simulate(scene, params, steps=args.steps, record_every=max(1, args.steps // 4))
    off = r.vertex_offset
    block = np.repeat(np.arange(len(off) - 1), np.diff(off))
    free = ~r.block_fixed
    model = dd.build_model(scene, params)
    initial, v0 = model.vertex_xy0, r.vertices[0]
    fixed = r.block_fixed[block]
    initial = initial + (v0[fixed] - initial[fixed]).mean(axis=0)  # the model's origin shift
    settled = np.zeros(len(off) - 1)
    np.maximum.at(settled, block, np.hypot(*(v0 - initial).T))
    held = free & (settled > 0.0)
    settlement = float(settled.max())
    print(f"held by the stage: {int(held.sum())}; settlement {settlement:.3g} m")
    for f in range(1, len(r.time)):
        moved = np.zeros(len(off) - 1)
        np.maximum.at(moved, block, np.hypot(*(r.vertices[f] - v0).T))
        m = moved[held]
        print(f"| {r.time[f] * 1e3:.1f} ms | {m.max():.3g} m | {int((m > settlement).sum())} | "
              f"{int((m > 1e-3).sum())} | {np.median(m):.3g} m | {np.median(moved[free & ~held]):.3g} m |")


if __name__ == "__main__":
    main()
