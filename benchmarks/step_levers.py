"""The step's solve levers on a large failing model, paired in one process from one settled state.

    python benchmarks/step_levers.py [--family slope] [--size 1537] [--steps 8] [--warmup 1]
        [--rounds 2] [--variant NAME=FIELD=VALUE,...]...

The model (``benchmarks/scaling_scenes.py``) is settled once (``ddatai.start.settle``, the
default start of a run; the settled state is kept in the system's temporary folder for the
next run of the same case), then each variant steps from that same settled state with a fresh
`ddatai.step.Stepper` (``--warmup`` steps untimed, then ``--steps`` timed), the variants'
order alternating between ``--rounds`` rounds, so that a pair sees the same load. A variant is
a set of Params fields (as ``scaling.py --params`` reads them); the default variants are the
levers of the symmetric step:

- ``coupled``: today's default (coupled friction, lever arms at each iterate's rotation);
- ``coupled+predicted``: lever arms at the step's predicted rotation (``lever_arm_rotation``);
- ``lagged+predicted``: lagged friction (a symmetric K) with them;
- ``lagged+predicted+updates``: and CHOLMOD's rank updates (``factor_updates``, [cholmod]).

``--krylov-check``: the solver's test of whether a later solve may try GMRES (how many blocks'
rows of K changed since the factor, `ddatai.iterative.changed_blocks`) against its sorting twin
(``changed_blocks_reference``, the code before it), on the K of every solve of ``--steps``
steps of the first variant, alternating, each timed ``--rounds`` × 5 times: the median ms of
each, their ratio, and whether every answer is the same.

Prints, per variant and round: median wall and CPU ms a step, CPU s per simulated second (the
variants' Δt may differ), solves and factorisations (LU among them) a step, the solves done by
GMRES with the last factor, by CHOLMOD updates, by refinement; and the median of the rounds.
Threads pinned (BLAS, MKL and Taichi one each).
"""

from __future__ import annotations

import os

for _k in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "TI_CPU_MAX_NUM_THREADS"):
    os.environ.setdefault(_k, "1")

import argparse  # noqa: E402
import dataclasses  # noqa: E402
import pickle  # noqa: E402
import statistics  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
from scaling_scenes import SCENES, parse_params, use_checkout  # noqa: E402

use_checkout()

DEFAULT_VARIANTS = (
    "coupled=",
    "coupled+predicted=lever_arm_rotation=predicted",
    "lagged+predicted=lever_arm_rotation=predicted,oc_friction=lagged",
    "lagged+predicted+updates=lever_arm_rotation=predicted,oc_friction=lagged,factor_updates=True",
)


def settled_state(family: str, size: int):
    """The settled state of the case (kept in the temporary folder: the stage takes 10–20 s)."""
    import ddatai as dd
    from ddatai.start import settle
    from ddatai.step import Stepper

    scene, params = SCENES[family](size)
    model = dd.build_model(scene, params)
    cache = Path(tempfile.gettempdir()) / f"ddatai_step_levers_{family}_{size}_{model.n_blocks}.pkl"
    if cache.exists():
        state = pickle.loads(cache.read_bytes())
        if len(state.vertex_xy) == len(model.vertex_xy0):
            return scene, params, state
    t0 = time.perf_counter()
    state, _ = settle(Stepper(model), model.initial_state())
    print(f"settled {family} {size} in {time.perf_counter() - t0:.1f} s", flush=True)
    cache.write_bytes(pickle.dumps(state))
    return scene, params, state


def run_variant(scene, params, state, fields: dict, steps: int, warmup: int) -> dict:
    import ddatai as dd
    from ddatai.results import step_wall_time
    from ddatai.step import Stepper

    model = dd.build_model(scene, dataclasses.replace(params, **fields))
    stepper = Stepper(model)
    solver = stepper.solver
    rows, cpu, counts = [], [], []
    for k in range(warmup + steps):
        before = (solver.factorisations, solver.lu_factorisations, solver.krylov, solver.updated, solver.reused)
        c0 = time.process_time()
        state, record = stepper.step(state)
        cpu.append(time.process_time() - c0)
        rows.append(record.row())
        after = (solver.factorisations, solver.lu_factorisations, solver.krylov, solver.updated, solver.reused)
        counts.append(np.subtract(after, before))
    s = np.array(rows, dtype=dd.STEP_DTYPE)[warmup:]
    cpu_t, n = np.array(cpu[warmup:]), np.array(counts[warmup:])
    wall = step_wall_time(s)
    return dict(ms=float(np.median(wall)) * 1e3, cpu_ms=float(np.median(cpu_t)) * 1e3,
                cpu_per_sim=float(cpu_t.sum() / max(float(s["dt"].sum()), 1e-300)),
                solve_ms=float(np.median(s["t_solve"])) * 1e3,
                solves=float(s["oc_total"].mean()), factorisations=float(n[:, 0].mean()),
                lu=float(n[:, 1].mean()), krylov=float(n[:, 2].mean()), updated=float(n[:, 3].mean()),
                reused=float(n[:, 4].mean()), dt_ms=float(s["dt"].mean()) * 1e3,
                cuts=int(s["dt_cuts"].sum()))


COLUMNS = ("ms", "cpu_ms", "cpu_per_sim", "solve_ms", "solves", "factorisations", "lu", "krylov", "updated",
           "reused", "dt_ms", "cuts")


def krylov_check(scene, params, state, fields: dict, steps: int, rounds: int) -> None:
    """The ``--krylov-check`` comparison (module docstring)."""
    import ddatai as dd
    from ddatai import iterative
    from ddatai.solver import SparseSolver
    from ddatai.step import Stepper

    cases = []
    original = SparseSolver._solve_krylov

    def record(self, data, indices, indptr, rhs, n):
        if self._factored_data is not None and len(self._factored_data) == len(data):
            cases.append((np.array(data), self._factored_data.copy(), indptr))
        return original(self, data, indices, indptr, rhs, n)

    SparseSolver._solve_krylov = record
    try:
        stepper = Stepper(dd.build_model(scene, dataclasses.replace(params, **fields)))
        for _ in range(steps):
            state, _ = stepper.step(state)
    finally:
        SparseSolver._solve_krylov = original
    times = {"changed_blocks": [], "changed_blocks_reference": []}
    same = True
    for r in range(rounds * 5):
        for name in (times if r % 2 == 0 else list(times)[::-1]):
            f = getattr(iterative, name)
            t0 = time.perf_counter()
            answers = [f(*c) for c in cases]
            times[name].append((time.perf_counter() - t0) / max(len(cases), 1) * 1e3)
            if name == "changed_blocks":
                new = answers
            else:
                old = answers
        same &= new == old
    med = {k: statistics.median(v) for k, v in times.items()}
    print(f"krylov check on {len(cases)} solves' K ({len(cases[0][0]) if cases else 0} entries): "
          f"changed_blocks {med['changed_blocks']:.3f} ms, reference {med['changed_blocks_reference']:.3f} ms, "
          f"ratio {med['changed_blocks'] / med['changed_blocks_reference']:.3f}; same answers: {same}; "
          f"blocks changed (median) {statistics.median(new) if cases else 0}", flush=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--family", default="slope", choices=tuple(SCENES))
    ap.add_argument("--size", type=int, default=1537)
    ap.add_argument("--steps", type=int, default=8)
    ap.add_argument("--warmup", type=int, default=1)
    ap.add_argument("--rounds", type=int, default=2)
    ap.add_argument("--variant", action="append", default=None, help="NAME=FIELD=VALUE,... (repeatable)")
    ap.add_argument("--krylov-check", action="store_true", help="time the solver's GMRES test (docstring)")
    args = ap.parse_args()
    variants = [v.split("=", 1) for v in (args.variant or DEFAULT_VARIANTS)]
    scene, params, state = settled_state(args.family, args.size)
    if args.krylov_check:
        krylov_check(scene, params, state, parse_params(variants[0][1]), args.steps, args.rounds)
        return
    results: dict = {name: [] for name, _ in variants}
    print(f"{args.family} {args.size}: {args.steps} steps after {args.warmup}, {args.rounds} rounds; "
          f"load {os.getloadavg()[0]:.2f}", flush=True)
    print("variant".ljust(28) + "".join(c.rjust(9) for c in COLUMNS), flush=True)
    for r in range(args.rounds):
        order = variants if r % 2 == 0 else variants[::-1]
        for name, text in order:
            out = run_variant(scene, params, state, parse_params(text), args.steps, args.warmup)
            results[name].append(out)
            print(f"{name[:27]:28}" + "".join(f"{out[c]:9.3g}" for c in COLUMNS), flush=True)
    print("median of rounds", flush=True)
    for name, _ in variants:
        med = {c: statistics.median(o[c] for o in results[name]) for c in COLUMNS}
        print(f"{name[:27]:28}" + "".join(f"{med[c]:9.3g}" for c in COLUMNS), flush=True)
    print(f"load {os.getloadavg()[0]:.2f}", flush=True)


if __name__ == "__main__":
    main()
