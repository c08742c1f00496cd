"""Why the equilibrium stage factorises: each of its solves, the path that asked for it and
the path the solver took, and how far K had moved from the matrix last factorised.

    python benchmarks/stage_solves.py [--family slope] [--size 1600] [--params NAME=VALUE,...] [--krylov]

Runs the stage (`ddatai.start.settle`) with a recording solver. For each solve: the caller
(``_iterate``: the return-mapping iteration, `ddatai.return_mapping`; ``open_close``: the
open–close iteration of ``_finish`` / ``test_unbalanced``), what the caller offered (reuse,
krylov, springs), what the solver did (``direct``: K is the factorised matrix; ``refined``;
``krylov``; ``updated``: CHOLMOD updates; ``factor``: a factorisation), the blocks in whose
rows K differs from the factorised matrix, and the solve's CPU time. Prints a summary.
``--krylov``: the lever measured in ``results/stage_solves.md`` (1.), without changing the code:
each symmetric solve of the stage whose K is not the factorised matrix is offered GMRES with the
last factor (`ddatai.solver`, ``krylov``), and each GMRES try is recorded (iterations, whether
it reached its tolerance, its true residual against ``KRYLOV_ACCEPT``).
"""

from __future__ import annotations

import collections
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from scaling_scenes import case_parser, case_scene, use_checkout  # noqa: E402

use_checkout()


def _caller() -> str:
    f = sys._getframe(2)
    while f is not None:
        name = f.f_code.co_name
        if name in ("_iterate", "open_close", "welded_solve"):
            return name
        f = f.f_back
    return "other"


def main() -> None:
    import ddatai as dd
    from ddatai.solver import SparseSolver
    from ddatai.start import settle
    from ddatai.step import Stepper

    ap = case_parser(__doc__, size=1600)
    ap.add_argument("--krylov", action="store_true", help="offer GMRES with the last factor (module docstring)")
    a = ap.parse_args()
    scene, params = case_scene(a)
    model = dd.build_model(scene, params)
    stepper = Stepper(model)
    log = []

    class Recording(SparseSolver):
        def solve(self, data, indices, indptr, rhs, pattern=None, symmetric=True, reuse=False,
                  krylov=False, springs=None):
            blocks = -1
            if self._factored_data is not None and len(self._factored_data) == len(data):
                changed = np.flatnonzero(data != self._factored_data)
                blocks = len(np.unique((np.searchsorted(indptr, changed, side="right") - 1) // 6))
            before = (self.factorisations, self.reused, self.krylov, self.updated)
            exact, iterations = self._exact, self.krylov_iterations
            t0 = time.process_time()
            x = super().solve(data, indices, indptr, rhs, pattern, symmetric, reuse, krylov, springs)
            dt = time.process_time() - t0
            after = (self.factorisations, self.reused, self.krylov, self.updated)
            took = ["factor", "reused", "krylov", "updated"][int(np.argmax(np.subtract(after, before)))] \
                if after != before else "?"
            if took == "reused" and exact and blocks == 0:
                took = "direct"
            log.append(dict(caller=_caller(), reuse=reuse, krylov=krylov, springs=springs is not None,
                            symmetric=symmetric, took=took, blocks=blocks, ms=1e3 * dt,
                            gmres=self.krylov_iterations - iterations))
            return x

    stepper.solver = Recording(params.solver, unknowns=6 * model.n_free)
    tries = []
    if a.krylov:
        import ddatai.return_mapping as rm
        import ddatai.solver as sv

        plain_solve, plain_gmres = rm.solve, sv.gmres

        def offering(stepper, pattern, data, rhs, symmetric=True, reuse=False, krylov=False, springs=None):
            f = stepper.solver._factored_data
            if springs is None and symmetric and not krylov and \
                    (not reuse or f is None or len(f) != len(data) or not np.array_equal(f, data)):
                krylov, reuse = True, False
            return plain_solve(stepper, pattern, data, rhs, symmetric, reuse, krylov, springs)

        def recording_gmres(k, b, solve, **kw):
            x, iterations, done = plain_gmres(k, b, solve, **kw)
            residual = float(np.abs(b - k @ x).max()) / max(float(np.abs(b).max()), 1e-300)
            tries.append((iterations, done, residual))
            return x, iterations, done

        rm.solve, sv.gmres = offering, recording_gmres
    t0, c0 = time.perf_counter(), time.process_time()
    state, start = settle(stepper, model.initial_state())
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    print(f"{a.family} {model.n_free:,} free blocks, backend {stepper.solver.backend}: stage {wall:.1f} s wall, "
          f"{cpu:.1f} s CPU; held {start.held}, released {start.released}, welded {bool(start.welded)}; "
          f"{len(log)} solves, {stepper.solver.factorisations} factorisations")
    groups = collections.Counter((r["caller"], r["symmetric"], r["reuse"], r["krylov"], r["took"]) for r in log)
    ms = collections.defaultdict(float)
    for r in log:
        ms[(r["caller"], r["symmetric"], r["reuse"], r["krylov"], r["took"])] += r["ms"]
    print("caller        sym  reuse krylov took      solves  CPU s  median changed blocks")
    for key, n in groups.most_common():
        blocks = [r["blocks"] for r in log if (r["caller"], r["symmetric"], r["reuse"], r["krylov"], r["took"]) == key]
        print(f"{key[0]:13s} {key[1]!s:5s} {key[2]!s:5s} {key[3]!s:6s} {key[4]:8s} {n:6d} {ms[key] / 1e3:8.2f}  "
              f"{np.median(blocks):8.0f}")
    failed = [r for r in log if r["took"] == "factor" and r["gmres"] > 0]
    done = [r for r in log if r["took"] == "krylov"]
    print(f"GMRES: {len(done)} solves, {sum(r['gmres'] for r in done)} iterations, {sum(r['ms'] for r in done) / 1e3:.2f} s CPU; "
          f"{len(failed)} gave up ({sum(r['gmres'] for r in failed)} iterations) and factorised, "
          f"{sum(r['ms'] for r in failed) / 1e3:.2f} s CPU with their factorisations")
    per = [r["ms"] for r in log if r["took"] == "factor" and r["gmres"] == 0 and r["blocks"] >= 0]
    if per:
        print(f"a factorisation (no GMRES before it): median {np.median(per):.1f} ms CPU")
    if tries:
        from ddatai.iterative import KRYLOV_ACCEPT

        t = np.array(tries, dtype=float)
        stopped = t[:, 1] == 0
        rejected = (t[:, 1] == 1) & (t[:, 2] > KRYLOV_ACCEPT)
        print(f"GMRES tries: {len(t)}; stopped at the iteration limit {int(stopped.sum())}; reached the tolerance "
              f"but true residual > KRYLOV_ACCEPT {int(rejected.sum())} (their residuals: median "
              f"{np.median(t[rejected, 2]) if rejected.any() else 0:.1e}); accepted residuals: median "
              f"{np.median(t[~stopped & ~rejected, 2]) if (~stopped & ~rejected).any() else 0:.1e}")
    fac = [r["blocks"] for r in log if r["took"] == "factor" and r["blocks"] >= 0]
    if fac:
        q = np.percentile(fac, [10, 25, 50, 75, 90])
        print("factorisations: blocks whose rows changed since the last one, percentiles 10/25/50/75/90:",
              " ".join(f"{v:.0f}" for v in q), f"; ≤ 5: {sum(b <= 5 for b in fac)}, ≤ 12: {sum(b <= 12 for b in fac)}, "
              f"≤ 30: {sum(b <= 30 for b in fac)} of {len(fac)}")


if __name__ == "__main__":
    main()
