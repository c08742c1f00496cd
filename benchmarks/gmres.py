"""SciPy's GMRES against the project's own, as the Krylov solve of an open-close iteration's later
solves (`ddatai.solver`, ``krylov``): K of the 391-block slope's first step with a few contacts'
states changed, preconditioned by the factor of K before the change.

    python benchmarks/gmres.py [--size 400] [--rounds 15]

Interleaved in one process (own, SciPy, own, ...): median time per solve, iterations and the
true relative residual |K x − b|max / |b|max of each. Prints a Markdown table.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))


def scipy_gmres(k, b: np.ndarray, solve, tol: float = 1e-13, max_iterations: int = 30
                ) -> tuple[np.ndarray, int, bool]:
    """GMRES for K x = b (`scipy.sparse.linalg.gmres`, one cycle of at most ``max_iterations``
    iterations), preconditioned by ``solve`` (a factor of a matrix near K) and started from
    x0 = solve(b). Returns (x, iterations, whether it reached ``tol`` × |b|₂ by SciPy's measure,
    the preconditioned residual; the caller checks the true one)."""
    from scipy.sparse.linalg import LinearOperator, gmres

    n = len(b)
    x0 = solve(b)
    if not np.all(np.isfinite(x0)):
        return x0, 0, False
    r = b - k @ x0
    if float(np.linalg.norm(r)) <= tol * float(np.linalg.norm(b)):
        return x0, 0, True
    iterations = []
    x, info = gmres(k, b, x0=x0, rtol=tol, atol=0.0, restart=max_iterations, maxiter=1,
                    M=LinearOperator((n, n), matvec=lambda v: solve(np.ascontiguousarray(v)), dtype=float),
                    callback=iterations.append, callback_type="pr_norm")
    return x, len(iterations), info == 0


def systems(size: int, changes: tuple, seed: int = 2):
    from scipy.sparse import csr_matrix

    import ddatai as dd
    from ddatai.assembly import assemble_blocks, assemble_contacts
    from ddatai.step import Stepper
    from scaling import slope_scene

    scene, params = slope_scene(size)
    model = dd.build_model(scene, params)
    stepper = Stepper(model)
    state = model.initial_state()
    geom = model.block_geometry(state.vertex_xy)
    c, vec, sca = stepper.find_contacts(state, geom)
    pattern = stepper.pattern
    data0, rhs0 = assemble_blocks(model, state, geom, pattern, 1e-3, 0.5)
    n = 6 * pattern.n_rows
    rng = np.random.default_rng(seed)
    closed = np.flatnonzero(c.state != dd.ContactState.OPEN)
    out = []
    for n_changed in (0,) + tuple(changes):
        k = c.copy()
        pick = rng.choice(closed, size=n_changed, replace=False)
        k.state[pick] = np.where(rng.random(n_changed) < 0.5, dd.ContactState.OPEN, dd.ContactState.SLIDE)
        k.normal_force[pick] = 1e5
        data, rhs = data0.copy(), rhs0.copy()
        assemble_contacts(model, k, pattern, vec, sca, data, rhs, stepper.serial_scatter)
        out.append((csr_matrix((data, pattern.indices, pattern.indptr), shape=(n, n)), rhs))
    return out


def main() -> None:
    from scipy.sparse.linalg import splu

    from ddatai import iterative

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", type=int, default=400)
    ap.add_argument("--rounds", type=int, default=15)
    a = ap.parse_args()
    changes = (1, 2, 4, 8)
    (k0, _), *changed = systems(a.size, changes)
    lu = splu(k0.tocsc(), permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0, options=dict(SymmetricMode=True))
    impls = {"own": iterative.gmres, "scipy": scipy_gmres}
    rows = {(name, m): [] for name in impls for m in changes}
    for _ in range(a.rounds):
        for m, (k, b) in zip(changes, changed):
            for name, fn in impls.items():
                t = time.perf_counter()
                x, its, done = fn(k, b, lu.solve, max_iterations=iterative.KRYLOV_ITERATIONS)
                dt = time.perf_counter() - t
                res = float(np.abs(k @ x - b).max() / np.abs(b).max())
                rows[name, m].append((dt, its, done, res))
    print("| contacts changed | own: ms, iterations, residual | SciPy: ms, iterations, residual | time SciPy / own |")
    print("|---|---|---|---|")
    for m in changes:
        own, sci = np.array(rows["own", m]), np.array(rows["scipy", m])
        print(f"| {m} | {np.median(own[:, 0]) * 1e3:.2f}, {np.median(own[:, 1]):.0f}, {np.max(own[:, 3]):.1e} | "
              f"{np.median(sci[:, 0]) * 1e3:.2f}, {np.median(sci[:, 1]):.0f}, {np.max(sci[:, 3]):.1e} | "
              f"{np.median(sci[:, 0] / own[:, 0]):.2f} |")


if __name__ == "__main__":
    main()
