"""Samples per second of the vectorised wedge evaluator and of a whole wedge study.

    python benchmarks/wedge_batch.py [--n 100000] [--repeat 3] [--workers 1,2]

The wedge is Hoek & Bray's comprehensive example at 30 m (docs/kgm/wedge_example.toml:
cohesion, a tension crack, water, seismic k), its two joints Fisher-scattered (K = 60) with
normal friction angles and a uniform water fill, sampled by Latin hypercube. Prints, per number
of threads, the median wall and CPU time of `kgm.wedges.batched.evaluate` alone and of the
study (sampling, evaluation, table), and the samples per second; the tables of all rows must be
identical. One per-sample evaluation through the reference path (`kgm.wedge`: LP + Qhull) is
timed for comparison.
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


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=100_000)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--workers", default="1,2")
    args = ap.parse_args()
    import kgm
    from kgm.wedges.cli import read_input
    from kgm.wedges.study import _batch_arguments
    from kgm.wedges import batched

    spec = read_input(ROOT / "docs" / "kgm" / "wedge_example.toml")
    study = dict(spec["study"])
    base = spec["wedge"]
    print(f"{platform.processor() or platform.machine()}, {os.cpu_count()} CPUs, load {os.getloadavg()[0]:.1f}; "
          f"n = {args.n}")
    t = time.perf_counter()
    for _ in range(20):
        kgm.wedge(**base)
    print(f"reference path (kgm.wedge, LP + Qhull): {(time.perf_counter() - t) / 20 * 1e3:.1f} ms a wedge")
    samples = kgm.sample_variables(_expand(study["variables"]), args.n, sampling=study["sampling"], seed=1,
                                   correlation=study["correlation"])
    kw = _batch_arguments(base, samples, args.n)
    first = None
    print("threads | evaluate wall s | evaluate cpu s | samples/s | study wall s | study samples/s")
    for workers in (int(w) for w in args.workers.split(",")):
        ev, cpu, st = [], [], []
        for _ in range(args.repeat):
            t, c = time.perf_counter(), time.process_time()
            res = batched.evaluate(**kw, workers=workers)
            ev.append(time.perf_counter() - t)
            cpu.append(time.process_time() - c)
            t = time.perf_counter()
            s = kgm.wedge_study(base, study["variables"], args.n, sampling=study["sampling"], seed=1,
                                correlation=study["correlation"], min_volume=study["min_volume"], workers=workers)
            st.append(time.perf_counter() - t)
        if first is None:
            first = res
        assert np.array_equal(np.nan_to_num(first.fs), np.nan_to_num(res.fs)), "tables differ between thread counts"
        e, c, w = np.median(ev), np.median(cpu), np.median(st)
        print(f"{workers} | {e:.2f} | {c:.2f} | {args.n / e:,.0f} | {w:.2f} | {args.n / w:,.0f}")
    print(s.summary())


def _expand(variables):
    from kgm.wedges.study import Fisher, _Uniform360

    out = {}
    for k, v in variables.items():
        if isinstance(v, Fisher):
            out[f"{k}_angle"], out[f"{k}_azimuth"] = v, _Uniform360()
        else:
            out[k] = v
    return out


if __name__ == "__main__":
    main()
