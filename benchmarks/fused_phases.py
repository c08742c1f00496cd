"""Where a step of the fused engine spends its time: each phase (a Taichi function of
`ddatai.fused`) timed alone in a small kernel of its own, on a member taken to a representative
state by the real kernel.

    python benchmarks/fused_phases.py [--blocks 64] [--warm 300] [--reps 200]
    python benchmarks/fused_phases.py --members PICKLE [--index 1] [--warm 400]   (a study's member)

The grid scene of `benchmarks/small_models.py` (n × n blocks on a fixed base, ntdda's sudden
start) runs ``--warm`` steps on the fused kernel; then a probe kernel (one thread, a serial loop)
runs one phase ``--reps`` times on that state, and reports CPU µs a call; "nothing" is the probe's
own cost a call (its launch, shared by the repetitions), to subtract. Phases that change what
the next call reads run behind the ones they need (the cost is the difference). Also: the
fused kernel's own time a step over ``--steps`` more steps, the contacts, the free blocks and
the envelope (the factorisation's profile). ``--members``: instead of the grid, member ``--index`` of
a pickle of ``benchmarks/study_members.py build`` (Example II's study), its stops off.
Threads pinned (one Taichi thread)."""

import argparse
import dataclasses
import json
import os
import sys
import time
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT), str(ROOT / "benchmarks")]

PHASES = ("detect", "start+vectors+envelope", "try setup (restore, K0, F0)", "shift+lever arms",
          "load K0", "load K0+contacts", "load K0+contacts+factor", "solve", "law+block energy",
          "violations", "gradient+internal force", "restore", "restore+judge", "accept", "energies+work",
          "time step rules", "detect without the sort", "approach bound", "hand over",
          "group displacement+fastest", "nothing (the probe's own cost a call)",
          "update (last: it moves the member)")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--blocks", type=int, default=64)
    ap.add_argument("--warm", type=int, default=300)
    ap.add_argument("--steps", type=int, default=300)
    ap.add_argument("--reps", type=int, default=200)
    ap.add_argument("--members", default="", help="a pickle of `benchmarks/study_members.py build`: probe one of "
                    "its members (a study's) instead of the grid")
    ap.add_argument("--index", type=int, default=0, help="which member of --members (counted over its batches)")
    a = ap.parse_args()

    import numpy as np
    import taichi as ti

    from ddatai import backend
    from ddatai.model import build_model
    from scaling import grid_scene

    backend.ensure("cpu")
    from ddatai.fused import blocks, contacts, law, system
    from ddatai.fused import layout as L
    from ddatai.fused.arrays import Pack
    from ddatai.fused.engine import Session
    from ddatai.fused.pack import Member
    from ddatai.fused.impacts import approach_bound
    from ddatai.fused.kernel import _fastest, _group_displacement
    from ddatai.fused.step import accept, energies, rule, time_step, update, work

    if a.members:
        import pickle

        study = [m for b in pickle.loads(Path(a.members).read_bytes()) for m in b]
        member = dataclasses.replace(study[a.index], record=True, step_end=a.warm + a.steps + 10,
                                     stop_at=float("inf"), rest_limit=-1.0)
    else:
        scene, params = grid_scene(a.blocks)
        params = dataclasses.replace(params, initial_equilibrium=False, kernels="numpy", solver="dense")
        model = build_model(scene, params)
        member = Member(model=model, state=model.initial_state(), step_end=a.warm + a.steps + 10, record=True)
    s = Session([member], launch_steps=4096)
    t = time.perf_counter()
    s.launch(np.array([a.warm]))
    first = time.perf_counter() - t
    t = time.process_time()
    s.launch(np.array([a.steps]))
    wall = time.process_time() - t
    _, rows = s.take(0)
    oc = float(np.mean(rows["oc_total"]))
    # the state of the last step's start is not kept: detect again at the current one
    A = s.arrays

    from ddatai.kernels.common import _pt
    from ddatai.kernels.detection import pair_contacts

    @ti.func
    def _unsorted(E: ti.template(), m):
        """`contacts.detect` without its sort (the pair loop and the narrow phase)."""
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
        for A in range(b0, b1):
            alo = ti.Vector([1e300, 1e300])
            ahi = ti.Vector([-1e300, -1e300])
            for k in range(E.bint[A, L.BI_V0], E.bint[A, L.BI_V1]):
                alo = ti.min(alo, _pt(E.vxy, k))
                ahi = ti.max(ahi, _pt(E.vxy, k))
            for B in range(A + 1, b1):
                if E.bint[A, L.BI_ROW] >= 0 or E.bint[B, L.BI_ROW] >= 0:
                    blo = ti.Vector([1e300, 1e300])
                    bhi = ti.Vector([-1e300, -1e300])
                    for k in range(E.bint[B, L.BI_V0], E.bint[B, L.BI_V1]):
                        blo = ti.min(blo, _pt(E.vxy, k))
                        bhi = ti.max(bhi, _pt(E.vxy, k))
                    if alo[0] - half <= bhi[0] + half and blo[0] - half <= ahi[0] + half and \
                            alo[1] - half <= bhi[1] + half and blo[1] - half <= ahi[1] + half:
                        pair_contacts(E.vxy, E.vnext, E.vprev, E.bint[A, L.BI_V0], E.bint[A, L.BI_V1],
                                      E.bint[B, L.BI_V0], E.bint[B, L.BI_V1], d0, d9, sin_h1, h1,
                                      E.memi, base, mend, E.cint, E.clen, E.ccount, m, base, cap)
        return E.ccount[m]

    @ti.kernel
    def probe(E: Pack, phase: ti.i32, reps: ti.i32) -> ti.f64:
        acc = 0.0
        dt = E.mf[0, L.MF_DT]
        beta = E.mf[0, L.MF_BETA]
        ti.loop_config(serialize=True)
        for r in range(reps):
            if phase == 0:
                acc += contacts.detect(E, 0)
            elif phase == 1:
                contacts.start(E, 0, E.ccount[0])
                contacts.vectors(E, 0)
                contacts.envelope(E, 0)
            elif phase == 2:
                contacts.restore(E, 0)
                system.clear_block_terms(E, 0)
                blocks.block_terms(E, 0, dt, beta)
            elif phase == 3:
                contacts.second_order_shift(E, 0, 1)
                contacts.lever_arms(E, 0, 1)
            elif phase >= 4 and phase <= 6:
                system.load_block_terms(E, 0)
                symmetric = 1
                if phase >= 5:
                    symmetric = system.contact_terms(E, 0)
                    acc += symmetric
                if phase >= 6:
                    acc += system.factor(E, 0, symmetric)
            elif phase == 7:
                acc += system.solve(E, 0)
            elif phase == 8:
                nf = E.mi[0, L.MI_NF]
                brhs = E.mi[0, L.MI_X0] + L.XS_BRHS * 6 * nf
                acc += law.evaluate(E, 0, L.BW_SOL, 0) + system.block_energy(E, 0, L.BW_SOL, brhs)
            elif phase == 9:
                acc += law.violations(E, 0, 0)
            elif phase == 10:
                nf = E.mi[0, L.MI_NF]
                brhs = E.mi[0, L.MI_X0] + L.XS_BRHS * 6 * nf
                grad = E.mi[0, L.MI_X0] + L.XS_GRAD * 6 * nf
                system.block_gradient(E, 0, L.BW_SOL, brhs, grad)
                law.internal_force(E, 0, 1, grad)
            elif phase == 11:
                contacts.restore(E, 0)
            elif phase == 12:
                contacts.restore(E, 0)
                changed, excess = law.judge(E, 0, 0, 1)
                acc += changed + excess
            elif phase == 13:
                cause, umax, pen, ratio = accept(E, 0)
                acc += umax
            elif phase == 14:
                k1, g1, s1, c1 = energies(E, 0, L.CF_DN, L.CF_DS, L.CI_STATE)
                ext, fr = work(E, 0)
                acc += k1 + g1 + s1 + c1 + ext + fr
            elif phase == 15:
                acc += time_step(E, 0) + rule(E, 0, 0)
            elif phase == 16:
                acc += _unsorted(E, 0)
            elif phase == 17:
                acc += approach_bound(E, 0, dt, dt)
            elif phase == 18:
                contacts.hand_over(E, 0)
            elif phase == 19:
                acc += _group_displacement(E, 0) + _fastest(E, 0)
            elif phase == 20:
                acc += 0.0
            elif phase == 21:
                acc += update(E, 0, dt, beta)
        return acc

    args = Pack(**A)
    # a consistent iterate: detect, start, one try's setup, one solve (its law in slot 0)
    t = time.perf_counter()
    for ph in (0, 1, 2, 3, 6, 7, 8, 9):
        probe(args, ph, 1)
    compile_s = time.perf_counter() - t
    nf = int(A["mi"][0, L.MI_NF])
    r0 = int(A["mi"][0, L.MI_R0])
    env = A["env"][r0:r0 + nf]
    width = 6 * (np.arange(nf) - env) + 6  # unknowns from a block-row's first column to its diagonal block's end
    out = dict(blocks=a.blocks, free=nf, contacts=int(A["mi"][0, L.MI_NC]), solves_per_step=oc,
               kernel_cpu_ms_per_step=1e3 * wall / a.steps, warm_launch_s=first, probe_compile_s=compile_s,
               envelope_mean=float(np.mean(width)), envelope_max=int(np.max(width)),
               envelope_entries=int(6 * np.sum(width)))
    us = {}
    for ph, name in enumerate(PHASES):
        probe(args, ph, 2)
        t = time.process_time()
        probe(args, ph, a.reps)
        us[name] = 1e6 * (time.process_time() - t) / a.reps
        # the state the next phases read (a consistent iterate again)
        if ph == 16:
            probe(args, 0, 1)
        if ph in (4, 5, 11, 12, 16):
            for q in (11, 2, 3, 6, 7, 8, 9):
                probe(args, q, 1)
    out["us"] = us
    print(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
