"""The fused engine's contact sort after detection (``contacts._sort``) with and without a stable
counting pass by (kind, the block of vertex0) before it (``by_block`` below), on the grid scene of
`benchmarks/small_models.py` at its packing (ntdda's sudden start): the contacts as the narrow
phase finds them, then each variant sorts that same region; the order is checked against numpy's
stable sort by key, CPU µs a call (the copy of the unsorted region subtracted).

    python benchmarks/fused_sort_probe.py [--blocks 64] [--reps 2000] [--rounds 3]

Threads pinned. Results: benchmarks/results/small_models_fused_step.md."""

import argparse
import dataclasses
import json
import os
import statistics
import sys
import time
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("TI_CPU_MAX_NUM_THREADS", "1")
ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT), str(ROOT / "benchmarks")]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--blocks", type=int, default=64)
    ap.add_argument("--reps", type=int, default=2000)
    ap.add_argument("--rounds", type=int, default=3)
    a = ap.parse_args()

    import numpy as np
    import taichi as ti

    from ddatai import backend
    from ddatai.model import build_model
    from scaling import grid_scene

    backend.ensure("cpu")
    from ddatai.fused import contacts
    from ddatai.fused import layout as L
    from ddatai.fused.arrays import Pack
    from ddatai.fused.engine import Session
    from ddatai.fused.pack import Member

    scene, params = grid_scene(a.blocks)
    params = dataclasses.replace(params, initial_equilibrium=False, kernels="numpy", solver="dense")
    model = build_model(scene, params)
    s = Session([Member(model=model, state=model.initial_state(), step_end=10)], launch_steps=4096)
    A = s.arrays
    args = Pack(**A)
    base = int(A["mi"][0, L.MI_C0])

    @ti.func
    def bucket(E: ti.template(), c, b0, nb):
        """(kind, the block of vertex0): the key's leading part, as one of 2·nb buckets."""
        return E.cint[c, L.CI_KIND] * nb + E.vblock[E.cint[c, L.CI_V0]] - b0

    @ti.func
    def by_block(E: ti.template(), base, n, b0, nb):
        """A stable counting pass of the n > 2·nb contacts by `bucket` before the insertion sort:
        the narrow phase finds them pair by pair, a block's contacts spread over its pairs, so
        the insertion sort alone moves each far; after this pass only within a bucket. The order
        is the insertion sort's (stable by the whole key) whatever this pass does. Scratch: the
        columns that ``contacts.start`` writes next (counts in CI_JOINT of the first 2·nb + 1
        rows, the rows' copies in CI_STATE .. CI_STATE + 4 and ``cf[:, CF_LEN]``)."""
        for k in range(2 * nb + 1):
            E.cint[base + k, L.CI_JOINT] = 0
        for c in range(base, base + n):
            E.cint[base + 1 + bucket(E, c, b0, nb), L.CI_JOINT] += 1
        for k in range(1, 2 * nb + 1):
            E.cint[base + k, L.CI_JOINT] += E.cint[base + k - 1, L.CI_JOINT]
        for c in range(base, base + n):
            k = bucket(E, c, b0, nb)
            d = base + E.cint[base + k, L.CI_JOINT]
            E.cint[base + k, L.CI_JOINT] = d - base + 1
            for q in ti.static(range(5)):
                E.cint[d, L.CI_STATE + q] = E.cint[c, q]
            E.cf[d, L.CF_LEN] = E.clen[c]
        for c in range(base, base + n):
            for q in ti.static(range(5)):
                E.cint[c, q] = E.cint[c, L.CI_STATE + q]
            E.clen[c] = E.cf[c, L.CF_LEN]

    @ti.func
    def no_sort(E: ti.template(), base, n):
        pass

    @ti.kernel
    def arrive(E: Pack) -> ti.i32:
        return contacts.detect(E, 0)

    keep = contacts._sort
    contacts._sort = no_sort  # the contacts in the narrow phase's order
    n = int(arrive(args))
    contacts._sort = keep
    rows = A["cint"][base:base + n, :5].copy()
    lens = A["clen"][base:base + n].copy()
    k2 = np.where(rows[:, 0] == 1, rows[:, 3], rows[:, 2])
    order = np.lexsort((k2, rows[:, 1], rows[:, 0]))
    moves = int(sum(np.sum(order[:i] > order[i]) for i in range(n)))  # inversions: the insertion sort's shifts
    snap_i = ti.field(ti.i32, shape=(n, 5))
    snap_f = ti.field(ti.f64, shape=n)
    snap_i.from_numpy(rows)
    snap_f.from_numpy(lens)

    @ti.kernel
    def probe(E: Pack, phase: ti.i32, reps: ti.i32) -> ti.i32:
        b0 = E.mi[0, L.MI_B0]
        nb = E.mi[0, L.MI_B1] - b0
        ti.loop_config(serialize=True)
        for r in range(reps):
            for c in range(n):
                for q in ti.static(range(5)):
                    E.cint[base + c, q] = snap_i[c, q]
                E.clen[base + c] = snap_f[c]
            if phase == 2:
                by_block(E, base, n, b0, nb)
            if phase >= 1:
                contacts._sort(E, base, n)
        return nb

    times = {0: [], 1: [], 2: []}
    same = {}
    for _ in range(a.rounds):
        for ph in (0, 1, 2):
            probe(args, ph, 1)
            t = time.process_time()
            probe(args, ph, a.reps)
            times[ph].append((time.process_time() - t) / a.reps * 1e6)
            if ph:
                out = A["cint"][base:base + n, :5]
                same[ph] = bool(np.array_equal(out, rows[order])
                                and np.array_equal(A["clen"][base:base + n], lens[order]))
    med = {ph: statistics.median(v) for ph, v in times.items()}
    print(json.dumps({"blocks": a.blocks, "contacts": n, "insertion_shifts": moves, "copy_us": round(med[0], 2),
                      "sort_us": round(med[1] - med[0], 2), "counting_then_sort_us": round(med[2] - med[0], 2),
                      "order_as_numpy": same, "rounds_us": {k: [round(x, 2) for x in v] for k, v in times.items()},
                      "load": os.getloadavg()[0]}))


if __name__ == "__main__":
    main()
