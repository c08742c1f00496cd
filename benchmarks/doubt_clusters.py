"""Why the stage's open-close test of the blocks still out of balance does not converge on the
jointed slope family (benchmarks/scaling_scenes.py ``slope_scene``): the test's iteration
instrumented from outside the library (docs/guide/equilibrium_start.md, "At scale").

For each call of the test (`ddatai.mechanisms.loaded_away` inside `ddatai.return_mapping`), the
blocks out of balance are grouped into clusters linked by closed contacts; the test's
open-close iteration (`ddatai.mechanisms.test_unbalanced`) is then run again, for up to
``--solves`` solves, with each solve's judgement recorded: how many contacts change state,
at which blocks, in which clusters, and which contacts flip back and forth (a contact that
changed state three times or more). The stage itself runs on as without the script (the
library's own call follows the instrumented one).

    PYTHONPATH=$PWD python benchmarks/doubt_clusters.py 400 [--solves 100]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

sys.path.insert(0, str(Path(__file__).resolve().parent))

import ddatai as dd  # noqa: E402
import ddatai.mechanisms as mech  # noqa: E402
import ddatai.open_close as oc  # noqa: E402
import ddatai.return_mapping as rm  # noqa: E402
from ddatai.kinematics import block_displacement  # noqa: E402
from ddatai.layout import LOCK, OPEN, SLIDE  # noqa: E402
from scaling_scenes import slope_scene  # noqa: E402


#: the test on a frame whose pseudo step is this much shorter (free fall over it covers
#: FALL_IN_SIZES / SHORTER² sizes): ``--shorter``
SHORTER = [1.0]
#: run the test with `open_close`'s ``hold_cycles`` (the step's last-try rule) instead: ``--hold``
HOLD = [False]


def clusters(model, contacts, closed, blocks):
    """Label of each block in ``blocks``'s connected clusters through ``closed`` contacts (-1 outside)."""
    n = model.n_blocks
    a, b = contacts.block_a, contacts.block_b
    link = closed & blocks[a] & blocks[b]
    graph = coo_matrix((np.ones(int(link.sum())), (a[link], b[link])), shape=(n, n))
    _, label = connected_components(graph, directed=False)
    out = np.full(n, -1)
    ids = {lab: k for k, lab in enumerate(np.unique(label[blocks]))}
    out[blocks] = [ids[lab] for lab in label[blocks]]
    return out


def instrumented_test(stepper, state, geom, frame, contacts, outcome, guess, unbalanced, out, solves):
    """`test_unbalanced` for up to ``solves`` solves with each judgement recorded: a list of
    (states before, the contacts that must change) per solve, and the test's result."""
    record, thrown = [], []
    judge, law_at, open_close = oc.judge, oc.contact_law, mech.open_close
    size = np.sqrt(geom["area"])

    def spy(model, c, law, bad, *args, **kw):
        before = c.state.copy()
        verdict = judge(model, c, law, bad, *args, **kw)
        record.append((before, bad.copy(), c.state.copy(), thrown[-1] if thrown else 0))
        return verdict

    def spy_law(model, c, vec, sca, solution, *args, **kw):
        moved = block_displacement(model, state.vertex_xy, geom, solution)
        thrown.append(int(np.count_nonzero(~model.block_fixed & ~out & (moved > mech.MECHANISM_SIZE / SHORTER[0] ** 2 * size))))
        return law_at(model, c, vec, sca, solution, *args, **kw)

    def held_cycles(*args, **kw):
        return open_close(*args, **kw, hold_cycles=HOLD[0])

    oc.judge, oc.contact_law, mech.open_close = spy, spy_law, held_cycles
    try:
        tested, n = mech.test_unbalanced(stepper, state, geom, frame, contacts, outcome, guess, unbalanced, solves)
    finally:
        oc.judge, oc.contact_law, mech.open_close = judge, law_at, open_close
    return record, tested, n


def report(call, stepper, state, geom, frame, contacts, outcome, guess, out, solves):
    model = stepper.model
    unbalanced = mech.out_of_balance(model, contacts, outcome) & ~out
    closed = guess.closed
    label = clusters(model, contacts, closed, unbalanced)
    k = int(label.max()) + 1
    sizes = np.bincount(label[label >= 0], minlength=k)
    if SHORTER[0] != 1.0:
        dt = mech.pseudo_time_step(stepper, geom, np.sqrt(geom["area"])) / SHORTER[0]
        frame = rm.Frame.build(stepper, state, geom, contacts, dt)
    t0 = time.process_time()
    record, tested, n = instrumented_test(stepper, state, geom, frame, contacts, outcome, guess, unbalanced, out, solves)
    cpu = time.process_time() - t0
    a, b = contacts.block_a, contacts.block_b
    print(f"\n## test call {call}: {int(unbalanced.sum())} blocks out of balance (held so far "
          f"{int((~model.block_fixed & ~out).sum())}), {k} clusters through closed contacts; sizes "
          f"(largest first) {sorted(sizes.tolist(), reverse=True)[:15]}; {int((sizes == 1).sum())} singletons")
    conv = tested[2] if tested is not None else None
    print(f"test: {n} solves, converged {conv}, {cpu:.2f} CPU s")
    flips = np.zeros(contacts.n, int)
    per_cluster_last = np.full(k, -1)
    print("solve | contacts changing | of them at out-of-balance blocks | clusters touched | at held blocks only | "
          "flipping (changed >= 3 times so far) | open->closed | closed->open | lock->slide | slide->lock | "
          "held blocks the solve moves > 1/4 size (/ SHORTER²)")
    for i, (before, bad, after, far) in enumerate(record):
        flips += bad
        blk = np.zeros(model.n_blocks, bool)
        blk[a[bad]] = True
        blk[b[bad]] = True
        at_unb = bad & (unbalanced[a] | unbalanced[b])
        touched = np.unique(np.concatenate([label[a[bad]], label[b[bad]]]))
        touched = touched[touched >= 0]
        per_cluster_last[touched] = i + 1
        print(f"{i + 1:5d} | {int(bad.sum()):5d} | {int(at_unb.sum()):5d} | {len(touched):4d} | "
              f"{int((bad & ~at_unb).sum()):4d} | {int(((flips >= 3) & bad).sum()):4d} | "
              f"{int(((before == OPEN) & (after != OPEN)).sum()):4d} | {int(((before != OPEN) & (after == OPEN)).sum()):4d} | "
              f"{int(((before == LOCK) & (after == SLIDE)).sum()):4d} | {int(((before == SLIDE) & (after == LOCK)).sum()):4d} | "
              f"{far:4d}")
    last = len(record)
    # clusters still changing in the last 5 solves, and those that had settled before
    late = per_cluster_last > last - 5
    print(f"clusters with a contact changing in the last 5 solves: {int(late.sum())} of {k} "
          f"({int(sizes[late].sum())} of {int(sizes.sum())} blocks); sizes {sorted(sizes[late].tolist(), reverse=True)}")
    quiet = per_cluster_last <= last - 5
    print(f"clusters quiet for the last 5+ solves: {int(quiet.sum())} ({int(sizes[quiet].sum())} blocks); "
          f"never touched: {int((per_cluster_last < 0).sum())} ({int(sizes[per_cluster_last < 0].sum())} blocks)")
    keys = [after.tobytes() for _, _, after, _ in record]
    print(f"distinct sets of contact states after the {len(keys)} judgements: {len(set(keys))} "
          f"(a set reached again is what `open_close.hold_cycling` / `cycling` act on)")
    cyc = flips >= 3
    cb = np.zeros(model.n_blocks, bool)
    cb[a[cyc]] = True
    cb[b[cyc]] = True
    print(f"contacts that changed >= 3 times: {int(cyc.sum())}, at {int(cb.sum())} blocks, in clusters "
          f"{np.unique(label[cb][label[cb] >= 0]).tolist()}; at held (not out-of-balance) blocks: "
          f"{int((cb & ~unbalanced).sum())}")
    if tested is not None:
        moved = mech.mechanisms(stepper, state.vertex_xy, geom, tested[1], tested[0], out, np.sqrt(geom['area']))
        print(f"the last iterate throws {int(moved.sum())} blocks ({int((moved & unbalanced).sum())} out of balance)")
    return label, sizes, per_cluster_last


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("n", type=int, nargs="?", default=400)
    ap.add_argument("--solves", type=int, default=100)
    ap.add_argument("--hold", action="store_true")
    ap.add_argument("--shorter", type=float, default=1.0)
    ap.add_argument("--stalled", type=int, default=0,
                    help="hand the blocks of an unconverged test over held (the stalled end, as before the "
                         "in-doubt rule) and run this many steps: how far do they move?")
    args = ap.parse_args()
    HOLD[0] = args.hold
    SHORTER[0] = args.shorter
    if args.stalled:
        return stalled_run(args.n, args.stalled)
    scene, params = slope_scene(args.n)
    calls = []
    original = rm.loaded_away

    def wrapped(stepper, state, geom, frame, contacts, outcome, guess, out, size, converged_only=False):
        calls.append(1)
        if converged_only:
            report(len(calls), stepper, state, geom, frame, contacts, outcome, guess, out, args.solves)
        return original(stepper, state, geom, frame, contacts, outcome, guess, out, size, converged_only)

    rm.loaded_away = wrapped
    t = time.process_time()
    r = dd.simulate(scene, params, steps=1)
    print("\nstart record:", dict(zip(r.start.dtype.names, r.start[0].tolist())),
          f"CPU {time.process_time() - t:.1f} s (with the instrumented tests)")


def stalled_run(n, steps):
    """The start with an unconverged test's blocks handed over held (stalled), then ``steps``
    steps: the largest motion of the blocks the stage held, against its settlement."""
    scene, params = slope_scene(n)
    original = rm.loaded_away

    def stalled(stepper, state, geom, frame, contacts, outcome, guess, out, size, converged_only=False):
        mechanism, solves, doubtful = original(stepper, state, geom, frame, contacts, outcome, guess, out, size,
                                               converged_only)
        if doubtful:
            # how far out of balance the stalled hand-over is: the largest shear excess over the
            # strength, against the weight of the block it acts on
            model = stepper.model
            weight = model.block_density * geom["area"] * float(np.hypot(*model.gravity))
            excess = np.maximum(outcome.excess, 0.0)
            per = np.maximum(excess / weight[contacts.block_a], excess / weight[contacts.block_b])
            print(f"stalled hand-over: shear excess over strength, largest / block weight {per.max():.3g}, "
                  f"median of those over the tolerance {np.median(per[outcome.excess > outcome.loose]):.3g}, "
                  f"{int((outcome.excess > outcome.loose).sum())} contacts over the tolerance")
        return (np.zeros_like(mechanism), solves, False) if doubtful else (mechanism, solves, doubtful)

    rm.loaded_away = stalled
    t = time.process_time()
    r = dd.simulate(scene, params, steps=steps, record_every=max(1, steps // 4))
    start = dict(zip(r.start.dtype.names, r.start[0].tolist()))
    print("start record (unconverged test's blocks held):", start, f"CPU {time.process_time() - t:.1f} s")
    off = r.vertex_offset
    v0 = r.vertices[0]
    block = np.repeat(np.arange(len(off) - 1), np.diff(off))
    free = ~r.block_fixed
    initial = dd.build_model(scene, params).vertex_xy0
    fixed_vertex = r.block_fixed[block]
    initial = initial + (v0[fixed_vertex] - initial[fixed_vertex]).mean(axis=0)  # the model's origin shift
    moved0 = np.zeros(len(off) - 1)
    np.maximum.at(moved0, block, np.hypot(*(v0 - initial).T))
    held = free & (moved0 > 0.0)
    print(f"held by the stage: {int(held.sum())}; settlement (largest) {moved0.max():.3g} m")
    model = dd.build_model(scene, params)
    from ddatai.contacts import Contacts
    from ddatai.model import ContactMemory
    from ddatai.step import Stepper
    stepper = Stepper(model)
    cint, length = stepper.detect(model.vertex_xy0)
    c = Contacts.start(model, model.vertex_xy0, cint, length, ContactMemory.empty(), True)
    touching = c.state != OPEN
    released = free & ~held
    near = np.zeros(len(off) - 1, bool)  # held blocks touching a released one at t = 0
    near[c.block_a[touching & released[c.block_b]]] = True
    near[c.block_b[touching & released[c.block_a]]] = True
    near &= held
    print(f"held blocks touching a released one at t = 0: {int(near.sum())}")
    for f in range(1, len(r.time)):
        d = np.zeros(len(off) - 1)
        np.maximum.at(d, block, np.hypot(*(r.vertices[f] - v0).T))
        dh = d[held]
        print(f"t = {r.time[f]:.4f} s: held blocks moved from the start: max {dh.max():.3g} m, "
              f"> 1 mm: {int((dh > 1e-3).sum())}, > 10 x settlement: {int((dh > 10 * moved0.max()).sum())}, "
              f"median {np.median(dh):.3g} m; released blocks: median {np.median(d[free & ~held]):.3g} m; "
              f"> 1 mm and touching a released block: {int(((d > 1e-3) & near).sum())}; largest motion of held "
              f"blocks not touching one {d[held & ~near].max():.3g} m")


if __name__ == "__main__":
    main()
