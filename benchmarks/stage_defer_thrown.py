"""A lever tried on the equilibrium stage and not kept (benchmarks/results/stage_in_doubt.md, "Deferring the
openings that throw a block"): where a return-mapping iterate's solve throws a block, the contacts of that
block which the iterate's judgement had just opened are kept closed and the system solved again, before the
line search. The library is unchanged: the rule is patched into the source of
`return_mapping._iterate` (the patch asserts that it still applies).

    PYTHONPATH=$PWD python benchmarks/stage_defer_thrown.py CASE [--plain] [--max-deferrals N] [--keep-if-throws]
                                                          [--unsupported-only] [--solver scipy] [--jitter 1e-12 --seed 2]

- a block is *thrown* by a target D when D moves it farther than ``mechanisms.MECHANISM_SIZE`` × its size
  (the stage's far test, the only displacement bound of the iteration: the line search has none) and it
  does not move with what holds it (`mechanisms.anchored`);
- ``--max-deferrals N``: a contact's opening is deferred at most N times in one `_iterate` (default 1;
  1000: always); the re-solve is kept only where it throws no block (else the openings are taken as
  judged, the re-solve wasted) unless ``--keep-if-throws``;
- ``--unsupported-only``: only blocks left with no closed contact count as thrown;
- ``--plain``: the library as it is (the pairing's A side).

Prints one line: held, released, in doubt, solves, factorisations (``solver.factorisations``), line
searches ending at their floor (2⁻³⁰), the openings deferred and the re-solves undone, the held set's
hash (`stage_roundoff.held_set`) and the stage's CPU time (one process). ``CASE``: as
`stage_roundoff.py` (``slope:1600``, ``scene:kgm_slope``).
"""

from __future__ import annotations

import argparse
import hashlib
import inspect
import sys
import time
import warnings
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

import stage_roundoff as sr  # noqa: E402
from ddatai import iterate_skips, open_close as oc, return_mapping as rm, return_steps as rs  # noqa: E402
from ddatai.kinematics import block_displacement  # noqa: E402
from ddatai.layout import OPEN  # noqa: E402
from ddatai.mechanisms import anchored  # noqa: E402
from ddatai.start import settle  # noqa: E402

COUNTS = {"deferred": 0, "undone": 0, "floor": 0}
RULE = {"max": 1, "keep_if_throws": False, "unsupported_only": False}


def thrown_contacts(stepper, frame, contacts, geom, target, movable, far_at, size, far_blocks):
    """(C,) the contacts of the blocks that ``target`` throws (module docstring)."""
    model = stepper.model
    far = far_blocks(target, movable, far_at) if far_blocks is not None else \
        movable & (block_displacement(model, frame.vertex_xy, geom, target) > far_at)
    if not np.count_nonzero(far):
        return np.zeros(contacts.n, bool)
    thrown = far & ~anchored(stepper, frame.vertex_xy, geom, contacts, target, size)
    if RULE["unsupported_only"]:
        closed = contacts.state != OPEN
        touching = np.zeros(model.n_blocks, bool)
        touching[contacts.block_a[closed]] = touching[contacts.block_b[closed]] = True
        thrown &= ~touching
    return thrown[contacts.block_a] | thrown[contacts.block_b]


DEFER = """
        if it > 1 and changed and np.count_nonzero(opened):
            deferred = opened & (deferrals < RULE["max"]) & thrown_contacts(
                stepper, frame, contacts, geom, target, movable, far_at, size, far_blocks)
            if np.count_nonzero(deferred):
                guess.closed = guess.closed | deferred
                deferrals += deferred
                contacts.state[:] = np.where(guess.closed, closed_state, OPEN)
                data, rhs = system.system(contacts, sca)
                springs = Springs.of(model, contacts, frame.vec, rows) if rows is not None else None
                again = solve(stepper, frame.pattern, data, rhs, springs=springs, lowrank=few)
                outcome.solves += 1
                if np.count_nonzero(np.isfinite(again)) < again.size:
                    outcome.disp = None
                    return outcome, guess
                if not RULE["keep_if_throws"] and np.count_nonzero(thrown_contacts(
                        stepper, frame, contacts, geom, again, movable, far_at, size, far_blocks)):
                    guess.closed = guess.closed & ~deferred
                    COUNTS["undone"] += 1
                else:
                    target = again
                    COUNTS["deferred"] += int(np.count_nonzero(deferred))
"""


def patch() -> None:
    """`return_mapping._iterate` with the deferral (module docstring) patched into its source."""
    source = inspect.getsource(rm._iterate)
    anchor_solve = "            outcome.disp = None\n            return outcome, guess\n"
    anchor_judged = "        guess.closed, guess.line = u.closed, u.line\n"
    anchor_loop = "    for it in range(1, MAX_ITERATIONS + 1):\n"
    assert source.count(anchor_solve) == 1 and source.count(anchor_judged) == 1 and source.count(anchor_loop) == 1, \
        "_iterate's source changed: the patch no longer applies"
    patched = source.replace(anchor_solve, anchor_solve + DEFER.lstrip("\n"), 1).replace(
        anchor_judged, "        opened = guess.closed & ~u.closed\n" + anchor_judged, 1).replace(
        anchor_loop, "    opened = np.zeros(contacts.n, bool)\n    deferrals = np.zeros(contacts.n, np.int64)\n"
        + anchor_loop, 1)
    rm.__dict__.update(thrown_contacts=thrown_contacts, RULE=RULE, COUNTS=COUNTS, OPEN=OPEN)
    exec(compile(patched, rm.__file__, "exec"), rm.__dict__)


def main():
    warnings.filterwarnings("ignore")
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("case")
    ap.add_argument("--plain", action="store_true")
    ap.add_argument("--max-deferrals", type=int, default=1)
    ap.add_argument("--keep-if-throws", action="store_true")
    ap.add_argument("--unsupported-only", action="store_true")
    ap.add_argument("--solver", default="auto")
    ap.add_argument("--jitter", type=float, default=0.0)
    ap.add_argument("--seed", type=int, default=0)
    a = ap.parse_args()
    RULE.update(max=a.max_deferrals, keep_if_throws=a.keep_if_throws, unsupported_only=a.unsupported_only)
    if not a.plain:
        patch()
    model, stepper = sr.build(a.case, a.solver)
    rng, plain_solve, plain_root = np.random.default_rng(a.seed), oc.solve, rs.root

    def jittered(*args, **kw):
        d = plain_solve(*args, **kw)
        return d * (1.0 + a.jitter * rng.uniform(-1.0, 1.0, d.shape)) if a.jitter else d

    def root(slope):
        alpha = plain_root(slope)
        COUNTS["floor"] += alpha <= 1.0 / 2 ** rs.LINE_SEARCH_BISECTIONS
        return alpha

    for mod in (rm, oc, sys.modules["ddatai.welded"]):
        mod.solve = jittered
    rs.root = iterate_skips.root = root
    t = time.process_time()
    state, rec = settle(stepper, model.initial_state())
    cpu = time.process_time() - t
    held = sr.held_set(model, state)
    rule = "plain" if a.plain else (f"defer max={a.max_deferrals}" + " keep-if-throws" * a.keep_if_throws
                                    + " unsupported-only" * a.unsupported_only)
    print(f"{a.case} {rule} solver={a.solver} jitter={a.jitter:g} seed={a.seed}: held={rec.held} "
          f"released={rec.released} in_doubt={rec.in_doubt} solves={rec.solves} "
          f"factorisations={stepper.solver.factorisations} floor_steps={COUNTS['floor']} "
          f"deferred={COUNTS['deferred']} undone={COUNTS['undone']} welded={rec.welded} "
          f"held_set={hashlib.sha256(held.tobytes()).hexdigest()[:12]} stage_cpu={cpu:.1f}")


if __name__ == "__main__":
    main()
