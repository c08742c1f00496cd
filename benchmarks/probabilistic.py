"""Samples per second of a probabilistic key group study on 1 and 2 local workers.

    python benchmarks/probabilistic.py [--n 200] [--method dda] [--workers 1,2] [--batch 1,16]

The study is Example II's critical group (blocks 0 and 1 of ``scenes/example_2.py``) with its
joint friction angle N(22°, 2°) and cohesion N(20 kPa, 5 kPa) truncated at 0, correlated
−0.3 (``docs/kgm/example_2_vars.toml``), judged by DDA (each sample: one run of the group at its
own strength, the verdict) or by the rigid / Sarma evaluators. Prints, per
worker count and DDA batch size (`kgm.DdaSettings.sample_batch`: samples judged side by side
in one run), the wall time, samples per second, the speed-up over the first row and P_f; the tables of
all rows must be identical (the study's samples and verdicts depend on neither).

    python benchmarks/probabilistic.py --targets [--seeds 3] [--scatter-seeds 100]

Small probabilities of failure (docs/kgm/reliability.md): a block on a 30° plane with its
friction angle N(μ, 2°), μ set for P_f = 1e-4 and 1e-6 exactly (Φ((30 − μ)/2)), by subset
simulation (1,000 samples a level) and importance sampling (FORM, then 1,000 samples), each run
through kgm.probabilistic with the rigid evaluator on the scene (``--seeds`` runs: evaluations,
P_f, its reported c.o.v., wall time), and the same estimators on the closed-form limit state over
``--scatter-seeds`` seeds (the c.o.v. measured as the scatter of the estimates, beside the mean
reported one). The targets: c.o.v. ≤ 0.3 with ≤ 5,000 evaluations at 1e-4, ≤ 8,000 at 1e-6.
"""

from __future__ import annotations

import argparse
import os
import platform
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def _same(a: np.ndarray, b: np.ndarray) -> bool:
    """Equal tables, nan equal to nan (a DDA verdict without strength reduction has FS nan)."""
    return a.dtype == b.dtype and all(
        np.array_equal(a[k], b[k], equal_nan=a[k].dtype.kind == "f") for k in a.dtype.names)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=200)
    ap.add_argument("--method", default="dda", choices=("rigid", "sarma", "dda"))
    ap.add_argument("--workers", default="1,2")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--batch", default="128", help="DDA batch sizes to run, comma-separated")
    ap.add_argument("--targets", action="store_true", help="small P_f: subset and importance sampling (docstring)")
    ap.add_argument("--seeds", type=int, default=3, help="--targets: runs through the scene per case")
    ap.add_argument("--scatter-seeds", type=int, default=100, help="--targets: closed-form runs per case")
    args = ap.parse_args()
    if args.targets:
        targets(args)
        return

    from ddatai.parallel import ScriptFunction
    from kgm.studies.probabilistic import probabilistic
    from kgm.studies.sampling import read_variables
    from kgm.settings import DdaSettings, Settings

    variables, correlation = read_variables(ROOT / "docs" / "kgm" / "example_2_vars.toml")
    build = ScriptFunction(str(ROOT / "scenes" / "example_2.py"))
    print(f"# Example II group {{0, 1}}, {args.n} samples, method {args.method}, "
          f"{platform.processor() or platform.machine()}, {os.cpu_count()} CPUs")
    print("| workers | batch | wall [s] | samples/s | speed-up | P_f | mean FS |")
    print("|---|---|---|---|---|---|---|")
    base, ref = None, None
    runs = [(int(w), int(b)) for b in args.batch.split(",") for w in args.workers.split(",")]
    for w, b in runs:
        t0 = time.perf_counter()
        study = probabilistic(build, variables, args.n, method=args.method, seed=args.seed, group={0, 1},
                              correlation=correlation, workers=w, settings=Settings(dda=DdaSettings(sample_batch=b)))
        wall = time.perf_counter() - t0
        base = base or wall
        if ref is not None and not _same(study.table, ref.table):
            raise SystemExit(f"tables differ between the first row and {w} workers, batch {b}")
        ref = ref if ref is not None else study
        fs = study.fs[np.isfinite(study.fs)]
        mean = f"{fs.mean():.3f}" if len(fs) else "— (verdicts only)"
        print(f"| {w} | {b} | {wall:.1f} | {args.n / wall:.2f} | {base / wall:.2f} | {study.pf:.3f} | {mean} |",
              flush=True)


THETA, SD = 30.0, 2.0  # the plane's dip and the friction angle's standard deviation [degrees]


def targets(args) -> None:
    import math

    import scipy.stats as st

    sys.path.insert(0, str(ROOT / "tests"))
    import kgm_cases
    from kgm.studies.probabilistic import probabilistic
    from kgm.studies import reliability

    print(f"# small P_f targets, {platform.processor() or platform.machine()}, {os.cpu_count()} CPUs")
    print("| P_f exact | estimator | run | evaluations | P_f | reported c.o.v. | wall [s] |")
    print("|---|---|---|---|---|---|---|")
    summary = []
    for exact in (1e-4, 1e-6):
        mean = THETA - SD * st.norm.ppf(exact)
        variables = {"friction": st.norm(mean, SD)}
        for sampling in ("subset", "importance"):
            for seed in range(args.seeds):
                t0 = time.perf_counter()
                study = probabilistic(kgm_cases.incline_scene, variables, 1000, method="rigid", group={1},
                                      sampling=sampling, seed=seed, workers=1)
                print(f"| {exact:g} | {sampling} | seed {seed} | {study.evaluations} | {study.pf:.3g} | "
                      f"{study.pf_cov:.3f} | {time.perf_counter() - t0:.1f} |", flush=True)

            # the same estimator on the closed form: g(u) = tan(μ + σu)/tanθ − 1
            def g(u, mean=mean):
                return np.tan(np.radians(mean + SD * u[:, 0])) / math.tan(math.radians(THETA)) - 1.0

            runs = []
            for seed in range(args.scatter_seeds):
                if sampling == "subset":
                    r = reliability.subset_simulation(g, 1, n=1000, seed=seed)
                    runs.append((r.pf, r.cov, r.evaluations))
                else:
                    f = reliability.form(g, 1)
                    r = reliability.importance_sampling(g, 1, centre=f.u, n=1000, seed=seed)
                    runs.append((r.pf, r.cov, r.evaluations + f.evaluations))
            pf, cov, ev = (np.array(x) for x in zip(*runs))
            summary.append(f"| {exact:g} | {sampling} | {ev.mean():.0f} (max {ev.max()}) | {pf.mean() / exact:.3f} | "
                           f"{cov.mean():.3f} | {pf.std(ddof=1) / pf.mean():.3f} |")
    print(f"\n# the estimators on the closed form, {args.scatter_seeds} seeds each")
    print("| P_f exact | estimator | evaluations, mean | mean P_f / exact | mean reported c.o.v. | scatter c.o.v. |")
    print("|---|---|---|---|---|---|")
    print("\n".join(summary))


if __name__ == "__main__":
    main()
