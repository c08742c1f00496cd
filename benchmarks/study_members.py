"""The fused engine's cost a member-step on the members of a real study batch (Example II's
DDA-judged study), and what those members' steps do.

    python benchmarks/study_members.py build [--n 200] [--out /tmp/study_members.pkl]
    python benchmarks/study_members.py time --members FILE [--root CHECKOUT] [--only moved] [--reps 3]
    python benchmarks/study_members.py census --members FILE

``build`` runs the study of ``benchmarks/small_models.py`` (friction N(22°, 2°), cohesion N(20 kPa,
5 kPa) correlated −0.3, seed 1, group {0, 1} of ``scenes/example_2.py``, Δt 1.3 ms, p = 1·E) in
one process (``workers=1``) and keeps every batch that the study hands to the fused engine
(``ddatai.fused.engine.run``'s members, as `kgm.judges.fused.run_prepared` packs them:
settled, with their stops) in a pickle. ``time`` loads that pickle in the checkout ``--root``
(its ``ddatai``; the kernel loaded from the offline cache first, not timed), runs every batch
``--reps`` times through ``engine.run`` (``--only moved``: only the members whose run ends by
passing their stop distance, the study's failing members) and prints the CPU µs a member-step
(this process's CPU time over the steps the members took), the median over the repetitions,
with a digest of every member's history (the same digest: the same runs to the bit).
``census`` runs them once with step records: open-close solves a step, contacts, closed
contacts, Δt cuts. Threads pinned (BLAS and Taichi one thread each).
"""

from __future__ import annotations

import argparse
import hashlib
import os

for _k in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "TI_CPU_MAX_NUM_THREADS"):
    os.environ.setdefault(_k, "1")

import dataclasses  # noqa: E402
import json  # noqa: E402
import pickle  # noqa: E402
import statistics  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]


def build(a) -> None:
    sys.path.insert(0, str(ROOT))
    import ddatai as dd
    from ddatai.fused import engine
    from ddatai.parallel import ScriptFunction
    from kgm.settings import DdaSettings, Settings
    from kgm.studies.probabilistic import probabilistic
    from kgm.studies.sampling import read_variables

    batches = []
    real = engine.run

    def keep(members, *args, **kw):
        batches.append(list(members))
        return real(members, *args, **kw)

    engine.run = keep
    variables, correlation = read_variables(ROOT / "docs" / "kgm" / "example_2_vars.toml")
    settings = Settings(dda=DdaSettings(params=dd.Params(dt=0.0013, penalty_ratio=1.0, kernels="fused")))
    study = probabilistic(ScriptFunction(str(ROOT / "scenes" / "example_2.py")), variables, a.n, method="dda",
                          seed=1, group={0, 1}, correlation=correlation, workers=1, settings=settings)
    Path(a.out).write_bytes(pickle.dumps(batches))
    print(f"{sum(map(len, batches))} members in {len(batches)} batches -> {a.out}; P_f {study.pf}")


def _load(a):
    sys.path.insert(0, str(Path(a.root).resolve()))
    import ddatai
    from ddatai.fused import engine, warm

    batches = pickle.loads(Path(a.members).read_bytes())
    print(f"# {ddatai.__file__}; cache {os.environ.get('TI_OFFLINE_CACHE_FILE_PATH', '(default)')}; "
          f"load {os.getloadavg()[0]:.2f}", flush=True)
    t = time.process_time()
    warm.warm()
    print(f"kernel loaded in {time.process_time() - t:.2f} s CPU", flush=True)
    return engine, batches


def _only(engine, batches, only: str):
    if not only:
        return batches
    out = []
    for b in batches:
        keep = [m for m, o in zip(b, engine.run(b)) if o.status == only]
        if keep:
            out.append(keep)
    return out


def time_members(a) -> None:
    engine, batches = _load(a)
    batches = _only(engine, batches, a.only)
    # the kernel's share: CPU time inside the launches (`Session.launch`), the rest is the driver's
    launched = [0.0]
    real = engine.Session.launch

    def launch(self, *args, **kw):
        t = time.process_time()
        out = real(self, *args, **kw)
        launched[0] += time.process_time() - t
        return out

    engine.Session.launch = launch
    per, kern = [], []
    digest = ""
    for rep in range(a.reps):
        cpu, steps, h = 0.0, 0, hashlib.sha256()
        launched[0] = 0.0
        for b in batches:
            t = time.process_time()
            outs = engine.run(b, launch_steps=a.launch_steps) if a.launch_steps else engine.run(b)
            cpu += time.process_time() - t
            for o in outs:
                steps += len(o.history)
                h.update(np.ascontiguousarray(o.history).tobytes())
                h.update(np.ascontiguousarray(o.state.vertex_xy).tobytes())
        per.append(1e6 * cpu / steps)
        kern.append(1e6 * launched[0] / steps)
        digest = h.hexdigest()[:16]
        print(f"rep {rep + 1}: {sum(map(len, batches))} members, {steps} member-steps, {cpu:.3f} s CPU, "
              f"{per[-1]:.3f} µs a member-step ({kern[-1]:.3f} in the launches); load {os.getloadavg()[0]:.2f}",
              flush=True)
    print(json.dumps(dict(us_per_member_step=statistics.median(per), us_in_launches=statistics.median(kern),
                          reps=per, launches=kern, digest=digest, steps=steps)))


def census(a) -> None:
    engine, batches = _load(a)
    rows, statuses = [], {}
    for b in batches:
        outs = engine.run([dataclasses.replace(m, record=True) for m in b])
        for o in outs:
            statuses[o.status] = statuses.get(o.status, 0) + 1
            if o.status == "moved" and len(o.records):
                rows.append(o.records)
    r = np.concatenate(rows)
    oc = r["oc_total"]
    print(f"statuses {statuses}; the 'moved' members' {len(r)} steps:")
    for name in ("oc_total", "oc_iterations", "dt_cuts", "contacts", "closed"):
        v = r[name]
        vals, counts = np.unique(v, return_counts=True)
        top = ", ".join(f"{x:g}: {c}" for x, c in zip(vals[:12], counts[:12]))
        print(f"  {name}: mean {v.mean():.3f}, median {np.median(v):g}, max {v.max():g}  ({top})")
    print(f"  solves a step > 1 in {np.mean(oc > 1):.1%} of steps")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("what", choices=("build", "time", "census"))
    ap.add_argument("--n", type=int, default=200)
    ap.add_argument("--out", default="/tmp/study_members.pkl")
    ap.add_argument("--members", default="/tmp/study_members.pkl")
    ap.add_argument("--root", default=str(ROOT))
    ap.add_argument("--only", default="", help="only the members whose run ends so (e.g. 'moved')")
    ap.add_argument("--reps", type=int, default=3)
    ap.add_argument("--launch-steps", type=int, default=0, help="steps a launch (default: the engine's)")
    a = ap.parse_args()
    {"build": build, "time": time_members, "census": census}[a.what](a)


if __name__ == "__main__":
    main()
