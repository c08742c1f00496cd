"""What changes between the solves of a step's open–close iteration, and so what a factor update,
a Krylov solve or a re-assembly of the changed contacts could reach.

    python benchmarks/solve_changes.py [--family slope] [--size 391] [--steps 4] [--params NAME=VALUE,...]

After the equilibrium stage (the settled protocol of ``benchmarks/scaling.py``), for each later
solve of each timed step: in how many blocks' rows K differs from the matrix last factorised,
and how the solver did it (``K``: GMRES with the last factor, ``F``: a factorisation;
`ddatai.solver`). GMRES is tried while at most ``KRYLOV_BLOCKS`` blocks' rows changed (about
one iteration a block); a CHOLMOD rank update (`ddatai.updates`, one or two columns a changed
contact) or a re-assembly of only the changed contacts' blocks pays likewise only where few
blocks' rows changed. Prints the counts and a summary.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from scaling_scenes import case_parser, case_scene, use_checkout  # noqa: E402

use_checkout()


def main() -> None:
    import ddatai as dd
    from ddatai.iterative import KRYLOV_BLOCKS
    from ddatai.solver import SparseSolver
    from ddatai.start import settle
    from ddatai.step import Stepper

    a = case_parser(__doc__).parse_args()
    scene, params = case_scene(a)
    model = dd.build_model(scene, params)
    stepper = Stepper(model)
    state, start = settle(stepper, model.initial_state())
    state, _ = stepper.step(state)  # the first step after the stage, untimed as in scaling.py
    log = []

    class Recording(SparseSolver):
        """The solver, noting each later solve's change against the factorised matrix."""

        def _solve_krylov(self, data, indices, indptr, rhs, n):
            rows = -1
            if self._factored_data is not None and len(self._factored_data) == len(data):
                changed = np.flatnonzero(data != self._factored_data)
                rows = len(np.unique((np.searchsorted(indptr, changed, side="right") - 1) // 6))
            x = super()._solve_krylov(data, indices, indptr, rhs, n)
            log.append([rows, x is not None])
            return x

    solver = Recording(params.solver, unknowns=6 * model.n_free)
    stepper.solver = solver
    print(f"{a.family} {model.n_free:,} free blocks; stage: held {start.held}, released {start.released}, "
          f"welded {bool(start.welded)}")
    total = []
    for _ in range(a.steps):
        log.clear()
        state, record = stepper.step(state)
        print(f"solves {record.oc_total:3d}, contacts {record.contacts:,}: changed block rows (K: GMRES, F: "
              f"factorised) " + " ".join(f"{r}{'K' if k else 'F'}" for r, k in log))
        total += log
    rows = np.array([r for r, _ in total] or [0])
    budget = KRYLOV_BLOCKS[False]
    print(f"later solves {len(total)}: {np.mean(rows <= budget):.0%} within GMRES's budget (<= {budget} block "
          f"rows), {np.mean(rows <= 2 * budget):.0%} within twice it, {np.mean(rows <= 5 * budget):.0%} within "
          f"{5 * budget}; median {np.median(rows):.0f} of {model.n_free:,} block rows")


if __name__ == "__main__":
    main()
