"""The fused engine's factorisation, triangular solves and line-search gradient against candidate
rewrites (`benchmarks/fused_factor_variants.py`), on one member's real system: the same inputs,
the outputs compared with today's (bit for bit, and the largest relative difference), CPU µs a
call.

    python benchmarks/fused_factor_probe.py [--blocks 64] [--warm 300] [--reps 200] [--rounds 3]
    python benchmarks/fused_factor_probe.py --members PICKLE [--index 1] [--warm 400]

The grid scene of `benchmarks/small_models.py` (n × n blocks on a fixed base, ntdda's sudden
start), or member ``--index`` of a pickle of ``benchmarks/study_members.py build``, runs ``--warm``
steps on the fused kernel (loaded from the offline cache); then a probe kernel assembles the
system of the next step's first solve (detection, transfer, block terms, second-order terms,
K = K0 + the contact springs) and times, alone, ``system.factor``, ``system.solve`` and
``system.block_gradient`` against the variants (each factor call re-assembles K first; the
assembly alone is timed and subtracted). Both of the factorisation's paths are timed on the same
K (LU without the symmetry shortcut is valid on a symmetric K too). Threads pinned. Results:
benchmarks/results/small_models_fused_step.md."""

import argparse
import json
import os
import sys
import time
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT), str(ROOT / "benchmarks")]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--blocks", type=int, default=64)
    ap.add_argument("--warm", type=int, default=300)
    ap.add_argument("--reps", type=int, default=200)
    ap.add_argument("--rounds", type=int, default=3, help="alternating rounds of all variants (median)")
    ap.add_argument("--members", default="", help="a pickle of `benchmarks/study_members.py build`: probe one of "
                    "its members instead of the grid")
    ap.add_argument("--index", type=int, default=1, help="which member of --members (counted over its batches)")
    a = ap.parse_args()

    import dataclasses
    import statistics

    import numpy as np
    import taichi as ti

    from ddatai import backend
    from ddatai.model import build_model
    from scaling import grid_scene

    backend.ensure("cpu")
    from ddatai.fused import blocks, contacts, system
    from ddatai.fused import layout as L
    from ddatai.fused.arrays import Pack
    from ddatai.fused.engine import Session
    from ddatai.fused.pack import Member
    import fused_factor_variants as V

    if a.members:
        import pickle

        study = [m for b in pickle.loads(Path(a.members).read_bytes()) for m in b]
        member = dataclasses.replace(study[a.index], record=True, step_end=a.warm + 10, stop_at=float("inf"),
                                     rest_limit=-1.0)
    else:
        scene, params = grid_scene(a.blocks)
        params = dataclasses.replace(params, initial_equilibrium=False, kernels="numpy", solver="dense")
        model = build_model(scene, params)
        member = Member(model=model, state=model.initial_state(), step_end=a.warm + 10, record=True)
    factor_b = V.factor
    solve_b = V.solve
    s = Session([member], launch_steps=4096)
    s.launch(np.array([a.warm]))
    A = s.arrays
    args = Pack(**A)

    @ti.kernel
    def probe(E: Pack, phase: ti.i32, symmetric_in: ti.i32, reps: ti.i32) -> ti.f64:
        acc = 0.0
        dt = E.mf[0, L.MF_DT]
        beta = E.mf[0, L.MF_BETA]
        ti.loop_config(serialize=True)
        for r in range(reps):
            if phase == 0:  # the first solve's system
                n = contacts.detect(E, 0)
                contacts.start(E, 0, n)
                contacts.vectors(E, 0)
                contacts.envelope(E, 0)
                contacts.restore(E, 0)
                system.clear_block_terms(E, 0)
                blocks.block_terms(E, 0, dt, beta)
                contacts.second_order_shift(E, 0, 1)
                contacts.lever_arms(E, 0, 1)
            elif phase == 1:
                system.load_block_terms(E, 0)
                acc += system.contact_terms(E, 0)
            elif phase == 2:
                system.load_block_terms(E, 0)
                system.contact_terms(E, 0)
                acc += system.factor(E, 0, symmetric_in)
            elif phase == 3:
                system.load_block_terms(E, 0)
                system.contact_terms(E, 0)
                acc += factor_b(E, 0, symmetric_in)
            elif phase == 4:
                acc += system.solve(E, 0)
            elif phase == 5:
                acc += solve_b(E, 0)
            elif phase == 6:
                acc += 0.0
            elif phase == 7 or phase == 8:
                nf = E.mi[0, L.MI_NF]
                brhs = E.mi[0, L.MI_X0] + L.XS_BRHS * 6 * nf
                grad = E.mi[0, L.MI_X0] + L.XS_GRAD * 6 * nf
                if phase == 7:
                    system.block_gradient(E, 0, L.BW_SOL, brhs, grad)
                else:
                    V.block_gradient(E, 0, L.BW_SOL, brhs, grad)

        return acc

    probe(args, 0, 1, 1)
    symmetric = int(probe(args, 1, 1, 1))
    nf = int(A["mi"][0, L.MI_NF])
    r0 = int(A["mi"][0, L.MI_R0])
    env = A["env"][r0:r0 + nf]
    out = dict(blocks=a.blocks, free=nf, contacts=int(A["mi"][0, L.MI_NC]), k_symmetric=symmetric,
               envelope_mean=float(np.mean(6 * (np.arange(nf) - env) + 6)))
    # bit for bit: the factor (both paths) and the solution
    same = {}
    for sym in (1, 0):
        probe(args, 2, sym, 1)
        k_a = np.array(A["kmat"])
        probe(args, 4, 0, 1)
        x_a = np.array(A["xvec"])
        probe(args, 5, 0, 1)  # the variant's solve on today's factor
        x_b = np.array(A["xvec"])
        probe(args, 3, sym, 1)
        k_b = np.array(A["kmat"])
        probe(args, 7, sym, 1)
        g_a = np.array(A["xvec"])
        probe(args, 8, sym, 1)
        same[f"gradient_sym{sym}"] = bool(np.array_equal(g_a, np.array(A["xvec"])))
        same[f"factor_sym{sym}"] = bool(np.array_equal(k_a, k_b))
        same[f"solve_sym{sym}"] = bool(np.array_equal(x_a, x_b))
        same[f"factor_sym{sym}_max_relative_difference"] = float(np.max(np.abs(k_a - k_b) / np.maximum(np.abs(k_a), 1e-300)))
        same[f"solve_sym{sym}_max_relative_difference"] = float(np.max(np.abs(x_a - x_b) / np.maximum(np.abs(x_a), 1e-300)))
    out["bit_identical"] = same
    names = {1: "assemble", 2: "assemble+factor", 3: "assemble+factor (variant)", 4: "solve", 5: "solve (variant)",
             6: "nothing", 7: "block gradient", 8: "block gradient (variant)"}
    times = {(ph, sym): [] for ph in names for sym in (1, 0)}
    for _ in range(a.rounds):
        for sym in (1, 0):
            for ph in names:
                probe(args, 2, sym, 1)  # a factor in K for the solves
                probe(args, ph, sym, 2)
                t = time.process_time()
                probe(args, ph, sym, a.reps)
                times[(ph, sym)].append(1e6 * (time.process_time() - t) / a.reps)
    us = {f"{names[ph]} [{'symmetric' if sym else 'LU'}]": round(statistics.median(v), 2)
          for (ph, sym), v in times.items()}
    for sym, tag in ((1, "symmetric"), (0, "LU")):
        us[f"factor alone [{tag}]"] = round(us[f"assemble+factor [{tag}]"] - us[f"assemble [{tag}]"], 2)
        us[f"factor alone, variant [{tag}]"] = round(us[f"assemble+factor (variant) [{tag}]"] -
                                                     us[f"assemble [{tag}]"], 2)
    out["us"] = us
    out["load"] = os.getloadavg()[0]
    print(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
