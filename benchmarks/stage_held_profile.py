"""Where a held member's equilibrium stage goes when the members run side by side.

    python benchmarks/stage_held_profile.py [--samples 200] [--batch 40] [--off OP1,OP2] [--root CHECKOUT]

The held members of Example II's DDA-judged study (``benchmarks/stage_levers.py``'s first
``--samples`` members, those whose stage holds blocks: 73 of 200) settled as
``ddatai.limit_batch.settle_many`` settles them — the screens ahead, then their stages side by
side (`ddatai.side_by_side`), batches of ``--batch`` —, once to warm, then timed. Each member
runs in its own greenlet, so a timer around a function inside it would count the other members'
work and the scheduler's; here every greenlet keeps its own CPU clock (``greenlet.settrace``
adds the CPU time between two switches to the greenlet switched from), and the stage's functions
are timed on the clock of the member that calls them: their own time, what the scheduler's
evaluations of the side-by-side operations take (``side_by_side._evaluate``, timed apart) left
out. Printed per member (CPU ms, calls): the total, the scheduler's evaluations by operation,
and the stage's parts (nested: a part's time includes the parts indented below it). The timers
cost ~10 % (the total is above the plain one). ``--off``: operations evaluated one member at a
time (removed from ``side_by_side``'s registry), to count what each takes side by side.
Threads pinned (BLAS one).
"""

from __future__ import annotations

import argparse
import collections
import functools
import os

for _k in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "TI_CPU_MAX_NUM_THREADS"):
    os.environ.setdefault(_k, "1")

import sys  # noqa: E402
import time  # noqa: E402
from functools import partial  # noqa: E402
from pathlib import Path  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

#: (module, attribute, label, static method) of the parts timed, in the order printed
PARTS = (
    ("ddatai.start", "_stage", "stage", False),
    ("ddatai.step", "Stepper.detect", "  detection", False),
    ("ddatai.contacts", "Contacts.start", "  Contacts.start", True),
    ("ddatai.return_mapping", "Frame.build", "  Frame.build", True),
    ("ddatai.return_mapping", "BlockPattern.build", "    pattern", True),
    ("ddatai.return_mapping", "assemble_blocks", "    block terms", False),
    ("ddatai.start", "balanced", "  balanced", False),
    ("ddatai.start", "return_mapping", "  return_mapping", False),
    ("ddatai.return_mapping", "_iterate", "    _iterate", False),
    ("ddatai.return_mapping", "solve", "      its solves", False),
    ("ddatai.return_mapping", "line_search", "      line search", False),
    ("ddatai.return_mapping", "_finish", "    _finish", False),
    ("ddatai.open_close", "solve", "      the open-close solves", False),
    ("ddatai.open_close", "judge", "      judge", False),
    ("ddatai.start", "settle_points", "  settle_points", False),
)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--samples", type=int, default=200)
    ap.add_argument("--batch", type=int, default=40)
    ap.add_argument("--off", default="")
    ap.add_argument("--root", default=str(ROOT))
    a = ap.parse_args()
    sys.path.insert(0, str(Path(a.root).resolve()))
    import importlib

    import greenlet

    from ddatai import side_by_side

    importlib.import_module("ddatai.stage_batch")  # registers the stage's operations
    from ddatai.limit_batch import screened_ahead
    from ddatai.start import settle
    from ddatai.step import Stepper
    from stage_levers import _members

    for name in filter(None, a.off.split(",")):
        side_by_side._BATCHED.pop(name)
    held = []
    for m in _members(a.samples):
        st, s = Stepper(m), m.initial_state()
        with screened_ahead([st], [s]):
            if settle(st, s)[1].held:
                held.append(m)
    batches = [held[b:b + a.batch] for b in range(0, len(held), a.batch)]

    def run_all():
        for part in batches:
            steppers, states = [Stepper(m) for m in part], [m.initial_state() for m in part]
            with screened_ahead(steppers, states):
                side_by_side.run([partial(settle, st, s) for st, s in zip(steppers, states)])

    clock = collections.defaultdict(float)
    last = [time.process_time()]

    def trace(event, args):
        if event in ("switch", "throw"):
            now = time.process_time()
            clock[args[0]] += now - last[0]
            last[0] = now

    def own() -> float:
        return clock[greenlet.getcurrent()] + time.process_time() - last[0]

    spent, calls = collections.Counter(), collections.Counter()
    for module, attr, label, static in PARTS:
        owner = importlib.import_module(module)
        *path, name = attr.split(".")
        for p in path:
            owner = getattr(owner, p)
        fn = getattr(owner, name)

        def timed(*args, _fn=fn, _label=label, **kwargs):
            t = own()
            try:
                return _fn(*args, **kwargs)
            finally:
                spent[_label] += own() - t
                calls[_label] += 1

        functools.update_wrapper(timed, fn)
        setattr(owner, name, staticmethod(timed) if static else timed)
    evaluated, members = collections.Counter(), collections.Counter()
    evaluate = side_by_side._evaluate

    def timed_evaluate(name, requests):
        t = time.process_time()
        try:
            return evaluate(name, requests)
        finally:
            evaluated[name] += time.process_time() - t
            members[name] += len(requests)

    side_by_side._evaluate = timed_evaluate
    greenlet.settrace(trace)
    run_all()  # warm
    for c in (spent, calls, evaluated, members, clock):
        c.clear()
    t = time.process_time()
    run_all()
    total = time.process_time() - t
    greenlet.settrace(None)
    n = len(held)
    print(f"{n} held members of {a.samples}, batches of {a.batch}; off: {a.off or 'none'}; load "
          f"{os.getloadavg()[0]:.1f}; CPU ms a member (timers included)")
    print(f"total {1e3 * total / n:.2f}; the scheduler's evaluations {1e3 * sum(evaluated.values()) / n:.2f}:")
    for name, v in evaluated.most_common():
        print(f"  {name:22s} {1e3 * v / n:6.3f} ms, {members[name] / n:5.1f} member-calls")
    print("the stage's own parts:")
    for _, _, label, _ in PARTS:
        print(f"{label:22s} {1e3 * spent[label] / n:6.3f} ms, {calls[label] / n:5.1f} calls")


if __name__ == "__main__":
    main()
