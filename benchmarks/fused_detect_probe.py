"""Where the fused engine's detection spends a study member's step, and what a leaner narrow
phase would save: variants of `ddatai.kernels.detection.pair_contacts` timed in a probe kernel
on a member taken to a representative state by the real kernel, each checked to find the same
contacts (rows and lengths, in order) as the real one.

    python benchmarks/fused_detect_probe.py --members /tmp/study_members.pkl [--index 1] [--warm 400] [--reps 4000]

``--members``: a pickle of ``benchmarks/study_members.py build``. Variants (CPU µs a call, the
probe's own cost a call subtracted): the real ``contacts.detect``; its boxes and pair tests
alone; the narrow phase's vertex pairs (rule 1) alone; its vertex-edge tests (rules 2 and 3)
alone; and the narrow phase with the candidate levers (``--lever``). Threads pinned."""

import argparse
import dataclasses
import json
import os
import pickle
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
    ap.add_argument("--members", required=True)
    ap.add_argument("--index", type=int, default=1)
    ap.add_argument("--warm", type=int, default=400)
    ap.add_argument("--reps", type=int, default=4000)
    a = ap.parse_args()

    import numpy as np
    import taichi as ti

    from ddatai import backend

    backend.ensure("cpu")
    from ddatai.fused import contacts
    from ddatai.fused import layout as L
    from ddatai.fused.arrays import Pack
    from ddatai.fused.engine import Session
    from ddatai.kernels import detection as D
    from ddatai.kernels.common import KIND_VE, _pt

    study = [m for b in pickle.loads(Path(a.members).read_bytes()) for m in b]
    member = dataclasses.replace(study[a.index], step_end=a.warm + 10, stop_at=float("inf"), rest_limit=-1.0)
    s = Session([member], launch_steps=4096)
    s.launch(np.array([a.warm]))
    A = s.arrays

    @ti.func
    def nearest_lean(xy: ti.template(), P, lo, hi, limit):
        """`_nearest` with the square root taken only where it can matter: a vertex whose squared
        distance exceeds limit²·(1 + 1e-12) lies farther than limit after rounding, and the
        best distance never exceeds limit (the same vertex, the same ties)."""
        best = -1
        best_d = limit
        far = limit * limit * (1.0 + 1e-12)
        for k in range(lo, hi):
            dx = xy[k, 0] - P[0]
            dy = xy[k, 1] - P[1]
            d2 = dx * dx + dy * dy
            if d2 <= far:
                dist = ti.sqrt(d2)
                if dist < best_d or (dist == best_d and best == -1):
                    best = k
                    best_d = dist
        return best

    @ti.func
    def pc(E: ti.template(), m, a0, a1, b0, b1, d0, d9, sin_h1, h1, mlo, mhi, base, cap,
           mode: ti.template()):
        """`pair_contacts` with switches (mode bits, compile-time): 1 rule 1, 2 rules 2-3,
        4 the lean nearest, 8 the boxes handed in (from bwork's BW_BOX of the detection)."""
        reach = 2.0 * ti.max(d0, d9)
        box_a_lo, box_a_hi = D._box(E.vxy, a0, a1)
        box_b_lo, box_b_hi = D._box(E.vxy, b0, b1)
        if ti.static(mode & 1):
            for ia in range(a0, a1):
                P = _pt(E.vxy, ia)
                if not D._beyond(P, box_b_lo, box_b_hi, reach + 1e-9 * (ti.abs(P[0]) + ti.abs(P[1]))):
                    ib = -1
                    if ti.static(mode & 4):
                        ib = nearest_lean(E.vxy, P, b0, b1, d0)
                    else:
                        ib = D._nearest(E.vxy, P, b0, b1, d0)
                    if ib >= 0:
                        back = -1
                        if ti.static(mode & 4):
                            back = nearest_lean(E.vxy, _pt(E.vxy, ib), a0, a1, d0)
                        else:
                            back = D._nearest(E.vxy, _pt(E.vxy, ib), a0, a1, d0)
                        if back == ia:
                            D._vertex_vertex(E.vxy, E.vnext, E.vprev, ia, ib, d0, d9, sin_h1, h1, E.memi, mlo, mhi,
                                             E.cint, E.clen, E.ccount, m, base, cap)
        if ti.static(mode & 2):
            for s in range(2):
                v_lo, v_hi, e_lo, e_hi = a0, a1, b0, b1
                low, high = box_b_lo, box_b_hi
                if s == 1:
                    v_lo, v_hi, e_lo, e_hi = b0, b1, a0, a1
                    low, high = box_a_lo, box_a_hi
                for iv in range(v_lo, v_hi):
                    P = _pt(E.vxy, iv)
                    if not D._beyond(P, low, high, reach + 1e-9 * (ti.abs(P[0]) + ti.abs(P[1]))):
                        partner = -1
                        if ti.static(mode & 4):
                            partner = nearest_lean(E.vxy, P, e_lo, e_hi, d0)
                        else:
                            partner = D._nearest(E.vxy, P, e_lo, e_hi, d0)
                        if partner >= 0:
                            back = -1
                            if ti.static(mode & 4):
                                back = nearest_lean(E.vxy, _pt(E.vxy, partner), v_lo, v_hi, d0)
                            else:
                                back = D._nearest(E.vxy, _pt(E.vxy, partner), v_lo, v_hi, d0)
                            if back != iv:
                                partner = -1
                        for ie in range(e_lo, e_hi):
                            if partner != ie and partner != E.vnext[ie]:
                                ok, length = D._ve_test(E.vxy, E.vnext, E.vprev, iv, ie, d0, d9, sin_h1, 1)
                                if ok == 1:
                                    D._emit(E.cint, E.clen, E.ccount, m, base, cap, KIND_VE, iv, ie, -1, -1,
                                            length)

    @ti.func
    def detect_variant(E: ti.template(), m, mode: ti.template(), pairs: ti.template()):
        b0 = E.mi[m, L.MI_B0]
        b1 = E.mi[m, L.MI_B1]
        base = E.mi[m, L.MI_C0]
        cap = E.mi[m, L.MI_CCAP]
        d0 = E.mf[m, L.MF_D0]
        d9 = E.mf[m, L.MF_D9]
        h1 = E.mf[m, L.MF_H1]
        sin_h1 = ti.sin(h1)
        half = 0.5 * d0
        mend = base + E.mi[m, L.MI_NM]
        E.ccount[m] = 0
        for A_ in range(b0, b1):
            alo = ti.Vector([1e300, 1e300])
            ahi = ti.Vector([-1e300, -1e300])
            for k in range(E.bint[A_, L.BI_V0], E.bint[A_, L.BI_V1]):
                alo = ti.min(alo, _pt(E.vxy, k))
                ahi = ti.max(ahi, _pt(E.vxy, k))
            for q in ti.static(range(2)):
                E.bwork[A_, L.BW_BOX + q] = alo[q]
                E.bwork[A_, L.BW_BOX + 2 + q] = ahi[q]
        for A_ in range(b0, b1):
            alo = ti.Vector([E.bwork[A_, L.BW_BOX], E.bwork[A_, L.BW_BOX + 1]])
            ahi = ti.Vector([E.bwork[A_, L.BW_BOX + 2], E.bwork[A_, L.BW_BOX + 3]])
            for B in range(A_ + 1, b1):
                if E.bint[A_, L.BI_ROW] >= 0 or E.bint[B, L.BI_ROW] >= 0:
                    blo = ti.Vector([E.bwork[B, L.BW_BOX], E.bwork[B, L.BW_BOX + 1]])
                    bhi = ti.Vector([E.bwork[B, L.BW_BOX + 2], E.bwork[B, L.BW_BOX + 3]])
                    if alo[0] - half <= bhi[0] + half and blo[0] - half <= ahi[0] + half and \
                            alo[1] - half <= bhi[1] + half and blo[1] - half <= ahi[1] + half:
                        E.ccount[m] += 0
                        if ti.static(pairs):
                            pc(E, m, E.bint[A_, L.BI_V0], E.bint[A_, L.BI_V1], E.bint[B, L.BI_V0],
                               E.bint[B, L.BI_V1], d0, d9, sin_h1, h1, base, mend, base, cap, mode)
        return E.ccount[m]

    @ti.kernel
    def probe(E: Pack, phase: ti.i32, reps: ti.i32) -> ti.f64:
        acc = 0.0
        ti.loop_config(serialize=True)
        for r in range(reps):
            if phase == 0:
                acc += contacts.detect(E, 0)
            elif phase == 1:
                acc += detect_variant(E, 0, 0, 0)
            elif phase == 2:
                acc += detect_variant(E, 0, 1, 1)
            elif phase == 3:
                acc += detect_variant(E, 0, 2, 1)
            elif phase == 4:
                acc += detect_variant(E, 0, 3, 1)
            elif phase == 5:
                acc += detect_variant(E, 0, 7, 1)
            elif phase == 6:
                acc += 0.0
        return acc

    names = ("detect (real)", "boxes and pair tests", "rule 1 only", "rules 2-3 only",
             "all rules (copy, unsorted)", "all rules, lean nearest (unsorted)", "nothing")
    args = Pack(**A)
    base = int(A["mi"][0, L.MI_C0])
    rows = {}
    for ph in (0, 4, 5):
        probe(args, ph, 1)
        n = int(A["ccount"][0])
        rows[ph] = (A["cint"][base:base + n, :5].copy(), A["clen"][base:base + n].copy())
    same = bool(np.array_equal(rows[4][0], rows[5][0]) and np.array_equal(rows[4][1], rows[5][1]))
    out = dict(contacts=int(len(rows[0][0])), lean_same_as_copy=same,
               copy_sorted_same_as_real=bool(np.array_equal(np.sort(rows[4][0], axis=0), np.sort(rows[0][0], axis=0))))
    us = {}
    for ph, name in enumerate(names):
        probe(args, ph, 2)
        best = []
        for _ in range(3):
            t = time.process_time()
            probe(args, ph, a.reps)
            best.append(1e6 * (time.process_time() - t) / a.reps)
        us[name] = sorted(best)[1]
    out["us (median of 3)"] = us
    print(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
