"""The first frame's opening cascade of the equilibrium stage (`ddatai.return_mapping._iterate`):
each iterate's contacts changed (closed, opened, line changed), its line search's α and whether
its solve factorised, and the stage's factorisations, for a first guess of the contacts' states:

    PYTHONPATH=$PWD python benchmarks/stage_cascade.py grid 1600              # the stage as it is
    ... --guess vertex-open   # VV contacts of block pairs that touch only at a vertex start open
    ... --guess record        # as it is, saving where the first iteration ends (/tmp/stage_cascade_first_*.npz)
    ... --guess oracle        # the first iteration started from what --guess record saved: the
                              # bound of any first guess (the right states at the first iterate)

Nothing in the library changes: the first `_iterate` call gets the guess; PARDISO's
factorisations (phases 12, 13, 22, 23) are counted. One process; warm enough for counts, not
for timings (`cold_ab.py` times).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

import ddatai as dd  # noqa: E402
import ddatai.pardiso as pardiso  # noqa: E402
import ddatai.return_mapping as rm  # noqa: E402
import ddatai.return_steps as rs  # noqa: E402
import ddatai.iterate_skips as skips  # noqa: E402
from ddatai.layout import KIND, VE  # noqa: E402
import scaling_scenes  # noqa: E402

SAVED = "/tmp/stage_cascade_first_{family}_{n}.npz"  # where --guess record saves (per model)


def first_guess(kind: str, stepper, contacts, saved_at: str) -> "rm.Guess | None":
    """The first iterate's guess of ``kind`` (None: the stage's own, every touching contact closed)."""
    if kind in ("none", "record"):
        return None
    guess = rm.Guess.start(contacts)
    if kind == "oracle":
        saved = np.load(saved_at)
        guess.closed[:], guess.line[:] = saved["closed"], saved["line"]
    elif kind == "vertex-open":
        ve = contacts.cint[:, KIND] == VE
        nb = np.int64(stepper.model.n_blocks)
        pair = np.minimum(contacts.block_a, contacts.block_b).astype(np.int64) * nb + \
            np.maximum(contacts.block_a, contacts.block_b)
        lone = ~ve & ~np.isin(pair, np.unique(pair[ve]))
        print(f"VV contacts of pairs touching only at a vertex, started open: {lone.sum()} of {(~ve).sum()}")
        guess.closed[lone] = False
    return guess


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("family")
    ap.add_argument("n", type=int)
    ap.add_argument("--guess", default="none", choices=["none", "record", "oracle", "vertex-open"])
    ap.add_argument("--lines", type=int, default=40, help="iterates of the first frame printed")
    args = ap.parse_args()
    scene, params = getattr(scaling_scenes, f"{args.family}_scene")(args.n)
    saved_at = SAVED.format(family=args.family, n=args.n)
    counts = {"factorisations": 0}
    rows: list = []
    first: dict = {}
    call, iterate, update, solve = pardiso._Pardiso.call, rm._iterate, rm.iterate_update, rm.solve
    searches = {"ls": rs.line_search, "skip": skips.LineSearch.__call__}

    def counted(self, phase, *a, **k):
        if phase in (12, 13, 22, 23):
            counts["factorisations"] += 1
        return call(self, phase, *a, **k)

    def iterated(stepper, frame, contacts, geom, out, size, guess, *a, **k):
        if first:
            return iterate(stepper, frame, contacts, geom, out, size, guess, *a, **k)
        first["contacts"] = contacts.n
        first["closed"] = int(np.count_nonzero(contacts.state != rm.OPEN))
        first["band"] = int(np.count_nonzero((contacts.state == rm.OPEN) & (contacts.dn <= 0.0)))
        given = first_guess(args.guess, stepper, contacts, saved_at)
        outcome, raw = iterate(stepper, frame, contacts, geom, out, size,
                               given if given is not None else guess, *a, **k)
        if args.guess == "record":
            np.savez(saved_at, closed=raw.closed, line=raw.line)
        first.update(solves=outcome.solves, factorisations=counts["factorisations"], done=True)
        return outcome, raw

    def updated(model, contacts, law, guess, *a, **k):
        u = update(model, contacts, law, guess, *a, **k)
        if "done" not in first and rows:
            rows[-1].update(changed=int(np.count_nonzero(u.changed)),
                            closing=int(np.count_nonzero(u.closed & ~guess.closed)),
                            opening=int(np.count_nonzero(~u.closed & guess.closed)))
        return u

    def solved(*a, **k):
        before = counts["factorisations"]
        x = solve(*a, **k)
        if "done" not in first:
            rows.append(dict(factorised=counts["factorisations"] - before, alpha=1.0))
        return x

    def searched_ls(*a, **k):
        alpha = searches["ls"](*a, **k)
        if "done" not in first and rows:
            rows[-1]["alpha"] = alpha
        return alpha

    def searched_skip(self, *a, **k):
        alpha = searches["skip"](self, *a, **k)
        if "done" not in first and rows:
            rows[-1]["alpha"] = alpha
        return alpha

    pardiso._Pardiso.call, rm._iterate, rm.iterate_update, rm.solve = counted, iterated, updated, solved
    rm.line_search, skips.LineSearch.__call__ = searched_ls, searched_skip
    t = time.process_time()
    dd.simulate(scene, params, steps=1)
    cpu = time.process_time() - t
    print(f"{args.family} {args.n}, guess {args.guess}: first iteration {first['contacts']} contacts "
          f"({first['closed']} closed at its start, {first['band']} open at dn <= 0), "
          f"{first['solves']} solves, {first['factorisations']} factorisations by its end; "
          f"the stage and step 1: {counts['factorisations']} factorisations, {cpu:.2f} s CPU (one process)")
    print("iterate  changed  closing  opening  alpha     factorised")
    for i, r in enumerate(rows[:args.lines], 1):
        print(f"{i:7d}  {r.get('changed', -1):7d}  {r.get('closing', -1):7d}  {r.get('opening', -1):7d}  "
              f"{r['alpha']:.6f}  {r['factorised']}")


if __name__ == "__main__":
    main()
