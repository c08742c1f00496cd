"""Samples per second of a probabilistic key group study on 1 and 2 local workers.

    python benchmarks/probabilistic.py [--n 200] [--method dda] [--workers 1,2] [--batch 1,16]

The study is Example II's critical group (blocks 0 and 1 of ``scenes/example_2.py``) with its
joint friction angle N(22°, 2°) and cohesion N(20 kPa, 5 kPa) truncated at 0, correlated
−0.3 (``docs/kgm/example_2_vars.toml``), judged by DDA (each sample: one run of the group at its
own strength, the verdict) or by the rigid / Sarma evaluators. Prints, per
worker count and DDA batch size (`kgm.DdaSettings.sample_batch`: samples judged side by side
in one run), the wall time, samples per second, the speed-up over the first row and P_f; the tables of
all rows must be identical (the study's samples and verdicts depend on neither).
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
    args = ap.parse_args()

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


if __name__ == "__main__":
    main()
