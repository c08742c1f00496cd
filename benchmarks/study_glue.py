"""The glue of Example II's DDA-judged study, process by process, on two checkouts, paired.

    python benchmarks/study_glue.py --a CHECKOUT-A --b CHECKOUT-B [--samples 400] [--repeats 3]

What each of a study's processes does beside the equilibrium stage and the fused kernel's runs
(`kgm.studies.probabilistic._prepared_then_run`), replayed in one fresh process a checkout, A and
B alternating, threads pinned (BLAS, OpenMP and Taichi one thread each), CPU seconds of the
thread that does it (``time.thread_time``; the machine is shared):

* **worker**: ``_prepare_batch`` (the preparing worker's function: each sample's scene, problem,
  sub-model, the batch's plans) less the stages (``ddatai.limit_batch.settle_many``, timed
  apart), and the pickling of what it sends (``_prepare_sent`` where the checkout has it);
* **parent**: what the study's process does with each prepared batch (unpickle the worker's
  message, pickle each group again for the runner's queue);
* **runner**: its main thread on each group (unpickle the queue's message, ``_finish_batch``:
  the packing, the launches' Python side, the read-back, the verdicts), the kernel's own thread
  apart (``kernel``: the process's CPU less the main thread's).

The collector's passes are timed apart (``gc_worker``, ``gc_runner``: ``gc.callbacks``) and taken
out of the parts: in one process replaying both sides a full pass falls where the allocation
count takes it (~40–50 ms over the ~100,000 objects of a process that loaded the kernel), not
where it falls in a study's own processes (which take what they hold at their start out of those
passes, `kgm.studies.probabilistic._keep_for_life`).

Batches of the study's ``SAVED_BATCH`` samples (128) of friction N(22°, 2°), cohesion
N(20 kPa, 5 kPa) correlated −0.3, seed 1, group {0, 1} of ``scenes/example_2.py``, Δt 1.3 ms,
p = 1·E, the fused engine (``benchmarks/small_models.py``'s study); the kernel loaded from
Taichi's offline cache first (its load not counted). Prints each run, the medians in ms a sample,
and whether both checkouts give every sample the same verdict.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from small_models import PINNED  # noqa: E402

#: one checkout's glue, in one process (module docstring); prints a JSON line
GLUE = """
import functools, gc, json, pickle, sys, time
sys.path.insert(0, {root!r})
from pathlib import Path
import ddatai as dd
import ddatai.limit_batch as limit_batch
from ddatai.parallel import ScriptFunction
from kgm.kinds import Method
from kgm.settings import DdaSettings, Settings
from kgm.studies import probabilistic as pr
from kgm.studies.sampling import read_variables, sample_seeds, sample_variables
root = Path({root!r})
variables, correlation = read_variables(root / "docs" / "kgm" / "example_2_vars.toml")
n = {n}
samples = sample_variables(variables, n, seed=1, correlation=correlation)
seeds = sample_seeds(1, n)
items = [(i, {{k: float(samples[k][i]) for k in variables}}, int(seeds[i])) for i in range(n)]
settings = Settings(dda=DdaSettings(params=dd.Params(dt=0.0013, penalty_ratio=1.0, kernels="fused")))
job = pr._Job(build=ScriptFunction(str(root / "scenes" / "example_2.py")), method=Method.DDA, settings=settings,
              group=frozenset({{0, 1}}), pass_seed=False)
batches = [tuple(items[i:i + pr.SAVED_BATCH]) for i in range(0, n, pr.SAVED_BATCH)]
prepare = getattr(pr, "_prepare_sent", pr._prepare_batch)
stage = [0.0]
collector = [0.0, 0.0]  # the collector's passes [s]: their CPU, and when the last began
def passes(phase, info):
    if phase == "start":
        collector[1] = time.thread_time()
    else:
        collector[0] += time.thread_time() - collector[1]
gc.callbacks.append(passes)
settle_many = limit_batch.settle_many
def timed(models):
    t, g = time.thread_time(), collector[0]
    try:
        return settle_many(models)
    finally:
        stage[0] += time.thread_time() - t - (collector[0] - g)
limit_batch.settle_many = timed
prepare(job, batches[0][:2])  # the worker's first calls (imports, the script) not counted
stage[0] = 0.0
worker = send = parent = 0.0
gc_worker = collector[0]
queued = []
for b, batch in enumerate(batches):
    t, g = time.thread_time(), collector[0]
    out = prepare(job, batch)
    worker += time.thread_time() - t - (collector[0] - g)
    t = time.thread_time()
    message = pickle.dumps(("result", b, out), pickle.HIGHEST_PROTOCOL)  # the worker's pipe
    send += time.thread_time() - t
    t = time.thread_time()
    _, _, (rows, work) = pickle.loads(message)  # the study's process: from the worker ...
    for k, part in enumerate(work):
        queued.append(pickle.dumps(((b, k), part[1] if isinstance(part[1], bytes) else part),
                                   pickle.HIGHEST_PROTOCOL))  # ... to the runner's queue
    parent += time.thread_time() - t
pr._finish_batch(job, "cpu")  # the kernel loaded (offline cache), not counted
pr._finish_batch(job, pickle.loads(queued[0])[1])  # its first batch's launch not counted
gc_worker = collector[0] - gc_worker
main, process, verdicts, g0 = 0.0, 0.0, {{}}, collector[0]
for message in queued[1:]:
    t, c, g = time.thread_time(), time.process_time(), collector[0]
    key, item = pickle.loads(message)
    verdicts.update((i, bool(row.failed)) for i, row in pr._finish_batch(job, item))
    main += time.thread_time() - t - (collector[0] - g)
    process += time.process_time() - c - (collector[0] - g)
m = len(verdicts)
print(json.dumps(dict(worker=1e3 * (worker - stage[0]) / n, stage=1e3 * stage[0] / n, send=1e3 * send / n,
                      parent=1e3 * parent / n, runner=1e3 * main / m, kernel=1e3 * (process - main) / m,
                      gc_worker=1e3 * gc_worker / n, gc_runner=1e3 * (collector[0] - g0) / m,
                      failed={{str(i): verdicts[i] for i in sorted(verdicts)}})))
"""

PARTS = ("worker", "send", "parent", "runner", "stage", "kernel", "gc_worker", "gc_runner")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--a", required=True, help="checkout A (e.g. this branch)")
    ap.add_argument("--b", required=True, help="checkout B (e.g. main)")
    ap.add_argument("--samples", type=int, default=400)
    ap.add_argument("--repeats", type=int, default=3)
    a = ap.parse_args()
    runs = {"A": [], "B": []}
    print(f"# the study's glue, ms of CPU a sample; {a.samples} samples; load {os.getloadavg()[0]:.1f}", flush=True)
    for rep in range(a.repeats):
        for name, root in (("A", a.a), ("B", a.b)):
            root = str(Path(root).resolve())
            proc = subprocess.run([sys.executable, "-c", GLUE.format(root=root, n=a.samples)], capture_output=True,
                                  text=True, cwd=root, env={**os.environ, **PINNED}, timeout=3600)
            if proc.returncode != 0:
                raise SystemExit(proc.stderr[-3000:])
            r = json.loads(proc.stdout.strip().splitlines()[-1])
            runs[name].append(r)
            glue = sum(r[p] for p in PARTS[:4])
            print(f"run {rep + 1} {name}: " + ", ".join(f"{p} {r[p]:.3f}" for p in PARTS)
                  + f"; glue {glue:.3f}; load {os.getloadavg()[0]:.1f}", flush=True)
    for name, root in (("A", a.a), ("B", a.b)):
        med = {p: statistics.median(r[p] for r in runs[name]) for p in PARTS}
        glue = statistics.median(sum(r[p] for p in PARTS[:4]) for r in runs[name])
        print(f"{name} ({root}) medians: " + ", ".join(f"{p} {med[p]:.3f}" for p in PARTS) + f"; glue {glue:.3f}")
    # the samples both replays judged (each leaves its first batch, its checkout's size, uncounted)
    ref = runs["B"][0]["failed"]
    common = set(ref).intersection(*(r["failed"] for r in runs["A"] + runs["B"]))
    same = all(r["failed"][i] == ref[i] for r in runs["A"] + runs["B"] for i in common)
    print(f"the same verdicts sample by sample: {same} ({len(common)} samples judged in every replay)")


if __name__ == "__main__":
    main()
