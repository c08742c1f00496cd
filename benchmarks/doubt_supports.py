"""The stage's open-close test of the blocks out of balance with the blocks it holds as supports
(docs/guide/equilibrium_start.md, "At scale"), measured from outside the library.

On the jointed slope family (benchmarks/scaling_scenes.py ``slope_scene``) the test of the
blocks that the return mapping leaves out of balance (`ddatai.mechanisms.test_unbalanced`)
does not converge: its iterates throw blocks that the stage holds. Here, where it does not
converge with every block free, it is run again with the held blocks that are not out of
balance fixed — a penalty of SUPPORT × (the contact penalty + the block's largest diagonal
term) on their six unknowns, their loads taken off — so that only the blocks out of balance
move, against the held ones as against fixed blocks. Where that converges, its verdict is
taken (`driven`: moved away by more than a quarter of their size, their loads doing positive
work over it); where it does not, they are released in doubt, as on main.

    PYTHONPATH=$PWD python benchmarks/doubt_supports.py 400 [--solves 100] [--steps 800]
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

import ddatai as dd  # noqa: E402
import ddatai.mechanisms as mech  # noqa: E402
import ddatai.return_mapping as rm  # noqa: E402
from ddatai.layout import LOCK  # noqa: E402
from scaling_scenes import slope_scene  # noqa: E402

#: the held blocks' added stiffness, against the contact penalty and their own diagonal
SUPPORT = 1e6
LOG: list = []
#: ``--trace``: each solve of the test with supports recorded (`doubt_clusters.instrumented_test`)
TRACE = [False]


def trace(stepper, state, geom, framed, contacts, outcome, guess, unbalanced, out, supports, solves):
    """The test with supports solve by solve: contacts changing state, blocks thrown, recurrences."""
    from doubt_clusters import instrumented_test

    record, tested, n = instrumented_test(stepper, state, geom, framed, contacts, outcome, guess, unbalanced,
                                          out, solves)
    a, b = contacts.block_a, contacts.block_b
    rows = []
    for i, (before, bad, after, far) in enumerate(record):
        at_support = bad & (supports[a] | supports[b])
        rows.append((i + 1, int(bad.sum()), int(at_support.sum()), far))
    keys = [after.tobytes() for _, _, after, _ in record]
    print(f"trace ({int((unbalanced & ~out).sum())} out of balance, {int(supports.sum())} supports): "
          f"{n} solves, converged {None if tested is None else tested[2]}, distinct state sets {len(set(keys))}")
    print("  (solve, contacts changing, of them touching a support, blocks thrown > 1/4 size):",
          [r for r in rows if r[0] <= 10 or r[0] % 10 == 0])
    if tested is not None:
        moved = dd.kinematics.block_displacement(stepper.model, state.vertex_xy, geom, tested[0])
        size = np.sqrt(geom["area"])
        far = (moved > mech.MECHANISM_SIZE * size) & unbalanced & ~out
        judged = tested[1]
        # blocks without a locked contact in the last judgement: no shear stiffness but the pseudo inertia
        locked = np.zeros(len(size), bool)
        lk = judged.state == LOCK
        locked[judged.block_a[lk]] = True
        locked[judged.block_b[lk]] = True
        work = mech.driven(stepper, state, geom, judged, tested[0], far)
        print(f"  last iterate: supports move at most {np.max(moved[supports] / size[supports], initial=0):.3g} "
              f"of their size; blocks out of balance moved > 1/4 size: {int(far.sum())}, of them without a "
              f"locked contact {int((far & ~locked).sum())}, with their loads doing positive work "
              f"(`driven`) {int(work.sum())}; not moved: {int((unbalanced & ~out & ~far).sum())}, of them "
              f"without a locked contact {int((unbalanced & ~out & ~far & ~locked).sum())}")


def supported_frame(stepper, frame, supports):
    """``frame`` with the ``supports`` blocks' unknowns held by a stiff spring and no load."""
    model = stepper.model
    pattern = frame.pattern
    rows = model.block_dof[supports]
    rows = rows[rows >= 0].astype(np.int64)
    data, rhs = frame.data.copy(), frame.rhs.copy().reshape(-1, 6)
    a = np.arange(6)
    diag = pattern.diag_slot[rows][:, None] + a[None, :] * pattern.stride[rows][:, None] + a[None, :]
    stiff = SUPPORT * (model.penalty + np.abs(data[diag]).max(axis=1, keepdims=True))
    data[diag] += stiff
    rhs[rows] = 0.0
    return dataclasses.replace(frame, data=data, rhs=rhs.reshape(frame.rhs.shape))


def loaded_away(stepper, state, geom, frame, contacts, outcome, guess, out, size, converged_only=False,
                solves_cap=mech.MAX_TEST_SOLVES):
    """`mechanisms.loaded_away`, with the test with supports where the free one does not converge."""
    model = stepper.model
    unbalanced = mech.out_of_balance(model, contacts, outcome)
    t0 = time.process_time()
    tested, solves = mech.test_unbalanced(stepper, state, geom, frame, contacts, outcome, guess, unbalanced)
    entry = dict(unbalanced=int((unbalanced & ~out).sum()), held=int((~model.block_fixed & ~out).sum()),
                 free_solves=solves, free_converged=None if tested is None else bool(tested[2]))
    if tested is None:
        LOG.append(entry)
        return np.zeros(model.n_blocks, bool), solves, False
    if converged_only and not tested[2]:
        supports = ~model.block_fixed & ~out & ~unbalanced
        framed = supported_frame(stepper, frame, supports)
        if TRACE[0]:
            trace(stepper, state, geom, framed, contacts, outcome, guess, unbalanced, out, supports, solves_cap)
        held_test, n = mech.test_unbalanced(stepper, state, geom, framed, contacts, outcome, guess, unbalanced,
                                            solves_cap)
        solves += n
        entry.update(supports=int(supports.sum()), support_solves=n,
                     support_converged=None if held_test is None else bool(held_test[2]))
        if held_test is not None and held_test[2]:
            disp, judged = held_test[0], held_test[1]
            thrown = mech.mechanisms(stepper, state.vertex_xy, geom, judged, disp, out, size)
            moving = unbalanced & thrown
            released = mech.driven(stepper, state, geom, judged, disp, moving)
            moved = dd.kinematics.block_displacement(model, state.vertex_xy, geom, disp) / size
            entry.update(thrown=int(thrown.sum()), thrown_supports=int((thrown & supports).sum()),
                         moving=int(moving.sum()), released=int(released.sum()),
                         held_back=int((unbalanced & ~out & ~released).sum()),
                         support_motion=float(moved[supports].max(initial=0.0)),
                         doubt_motion_median=float(np.median(moved[unbalanced & ~out])),
                         cpu=time.process_time() - t0)
            LOG.append(entry)
            return released, solves, False
        entry["cpu"] = time.process_time() - t0
        LOG.append(entry)
        return unbalanced & ~out, solves, True
    moving = unbalanced & mech.mechanisms(stepper, state.vertex_xy, geom, tested[1], tested[0], out, size)
    LOG.append(entry)
    return mech.driven(stepper, state, geom, tested[1], tested[0], moving), solves, False


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("n", type=int, nargs="?", default=400)
    ap.add_argument("--solves", type=int, default=mech.MAX_TEST_SOLVES, help="solves of the test with supports")
    ap.add_argument("--steps", type=int, default=0, help="steps of the run after the start (held blocks' motion)")
    ap.add_argument("--trace", action="store_true")
    ap.add_argument("--support", type=float, default=SUPPORT, help="the supports' stiffness factor")
    args = ap.parse_args()
    globals()["SUPPORT"] = args.support
    TRACE[0] = args.trace

    def patched(*a, **kw):
        return loaded_away(*a, **kw, solves_cap=args.solves)

    rm.loaded_away = patched
    scene, params = slope_scene(args.n)
    t = time.process_time()
    steps = max(args.steps, 1)
    r = dd.simulate(scene, params, steps=steps, record_every=max(1, steps // 4))
    start = dict(zip(r.start.dtype.names, r.start[0].tolist()))
    print("start record (test with supports):", start, f"CPU {time.process_time() - t:.1f} s")
    for k, e in enumerate(LOG):
        print(f"test call {k + 1}:", e)
    if args.steps:
        motion_table(scene, params, r)


def motion_table(scene, params, r):
    """How far the blocks the stage held move in the run, against its settlement."""
    off = r.vertex_offset
    v0 = r.vertices[0]
    nb = len(off) - 1
    block = np.repeat(np.arange(nb), np.diff(off))
    free = ~r.block_fixed
    initial = dd.build_model(scene, params).vertex_xy0
    fixed_vertex = r.block_fixed[block]
    initial = initial + (v0[fixed_vertex] - initial[fixed_vertex]).mean(axis=0)  # the model's origin shift
    moved0 = np.zeros(nb)
    np.maximum.at(moved0, block, np.hypot(*(v0 - initial).T))
    held = free & (moved0 > 0.0)
    print(f"held by the stage: {int(held.sum())}; settlement (largest) {moved0.max():.3g} m")
    print("| t [s] | held: largest motion from the start | > 1 mm | > 2 x settlement | median | released: median |")
    for f in range(1, len(r.time)):
        d = np.zeros(nb)
        np.maximum.at(d, block, np.hypot(*(r.vertices[f] - v0).T))
        dh = d[held]
        print(f"| {r.time[f]:.4f} | {dh.max() * 1e3:.3g} mm | {int((dh > 1e-3).sum())} | "
              f"{int((dh > 2 * moved0.max()).sum())} | {np.median(dh) * 1e3:.3g} mm | "
              f"{np.median(d[free & ~held]) * 1e3:.3g} mm |")


if __name__ == "__main__":
    main()
