"""Does the equilibrium stage's held set turn on round-off, and where? (benchmarks/results/stage_in_doubt.md,
"Which blocks the stage holds, against round-off"). The library is unchanged: its functions are wrapped
from outside.

    PYTHONPATH=$PWD python benchmarks/stage_roundoff.py outcome slope:1600 [--solver scipy] [--jitter 1e-13 --seed 1]
    PYTHONPATH=$PWD python benchmarks/stage_roundoff.py trace slope:1600 --solver pardiso --out /tmp/p.pkl
    PYTHONPATH=$PWD python benchmarks/stage_roundoff.py compare /tmp/p.pkl /tmp/s.pkl
    PYTHONPATH=$PWD python benchmarks/stage_roundoff.py beside slope:1600 --solves 120

- ``outcome``: the stage's record (held, released, in doubt, solves, welded) and the held set's hash;
  ``--jitter a``: each solve's D (return mapping, open-close test, finish) multiplied by 1 + a·r, r
  uniform in [−1, 1] (seeded): a perturbation at the size of a solve's round-off; ``--take-thrown``,
  ``--floor-still`` and ``--floor-keeps-thrown``: levers tried and not kept (`take_thrown`,
  `floor_still`, `floor_keeps_thrown`).
  ``CASE``: ``family:size`` of `scaling_scenes` or ``scene:name`` (``scenes/name.py``).
- ``trace``: every return-mapping iterate's contact judgement (`ddatai.return_update.iterate_update`):
  each state rule's quantity minus its bar over the bar (``q``: closing, N − tol_state; opening,
  pen·dn − T·L − tol; change of line, pen·|Δdn| − tol_state; the shear excess over its tolerance),
  the contacts that change, and the block decisions (thrown, limit equilibrium, the open-close test).
- ``compare``: the first iterate at which two traces judge differently, each run's ``q`` of the contacts
  judged differently there, and the spread of ``q`` between the runs iterate by iterate before it.
- ``beside``: along one run (PARDISO), each of the first N return-mapping solves solved again by
  SuperLU (the same K and F): how far the solver alone moves each decision's ``q`` (its round-off), the
  decisions inside that band, and the solve's condition as |K|·|x|/|b| and the largest motion of its target.
"""

from __future__ import annotations

import argparse
import dataclasses
import hashlib
import pickle
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

import ddatai as dd  # noqa: E402
import scaling_scenes  # noqa: E402
from ddatai import iterate_skips, mechanisms as mech, open_close as oc, return_mapping as rm  # noqa: E402
from ddatai.layout import KIND, VE  # noqa: E402
from ddatai.start import settle  # noqa: E402
from ddatai.step import Stepper  # noqa: E402


def build(case: str, solver: str):
    """``family:size`` (`scaling_scenes`) or ``scene:name`` (``scenes/name.py``'s ``build``)."""
    family, size = case.split(":")
    if family == "scene":
        sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
        scene, params = __import__(f"scenes.{size}", fromlist=["build"]).build()[:2]
    else:
        scene, params = getattr(scaling_scenes, family + "_scene")(int(size))
    model = dd.build_model(scene, dataclasses.replace(params, solver=solver))
    return model, Stepper(model)


def held_set(model, state) -> np.ndarray:
    """Held blocks: a released block starts where it was (moved exactly 0), a held one settled."""
    moved = np.zeros(model.n_blocks)
    np.maximum.at(moved, model.vertex_block, np.hypot(*(state.vertex_xy - model.vertex_xy0).T))
    return (moved > 0.0) & ~model.block_fixed


def margins(model, contacts, law, guess, flips, freeze, tensile, chatter_flips, u) -> dict:
    """Each state rule's quantity minus its bar, over the bar (NaN where the rule is not asked)."""
    pen = model.penalty
    ve = contacts.cint[:, KIND] == VE
    frozen = ve & (flips >= chatter_flips) & freeze
    return dict(
        close=np.where(~guess.closed & law.closed, (law.fn - u.state_loose) / u.state_loose, np.nan),
        open=np.where(~frozen & guess.closed & ~law.closed, (pen * law.dn - tensile - u.loose) / u.loose, np.nan),
        switch=np.where(~ve & guess.closed & law.closed & (law.line != guess.line),
                        (pen * np.abs(law.dn - law.dn_now) - u.state_loose) / u.state_loose, np.nan),
        excess=np.where(np.isfinite(u.excess), (u.excess - u.loose) / u.loose, np.nan))


def outcome(a):
    model, stepper = build(a.case, a.solver)
    rng = np.random.default_rng(a.seed)
    plain = oc.solve

    def jittered(*args, **kw):
        d = plain(*args, **kw)
        return d * (1.0 + a.jitter * rng.uniform(-1.0, 1.0, d.shape)) if a.jitter else d

    for mod in (rm, oc, sys.modules["ddatai.welded"]):
        mod.solve = jittered
    if a.take_thrown:
        take_thrown(model)
    if a.floor_still:
        floor_still()
    if a.floor_keeps_thrown:
        floor_keeps_thrown(model)
    t = time.process_time()
    state, rec = settle(stepper, model.initial_state())
    held = held_set(model, state)
    print(f"case={a.case} solver={a.solver} jitter={a.jitter:g} seed={a.seed} held={rec.held} released={rec.released} "
          f"in_doubt={rec.in_doubt} solves={rec.solves} welded={rec.welded} stalled={rec.stalled} "
          f"held_set={hashlib.sha256(held.tobytes()).hexdigest()[:12]} stage_cpu={time.process_time() - t:.1f}")


def take_thrown(model):
    """Experiment (not the library's rule): where an iterate's solve moves a free block more than
    MECHANISM_SIZE of its size away from what holds it (`mechanisms.anchored`; a block released
    earlier in the pseudo-step, which falls under the pseudo inertia alone, counts: so after the
    pseudo-step's first release no iterate is line-searched), the iterate takes the whole solve and
    its far test releases what it throws."""
    from ddatai.kinematics import block_displacement

    search, geoms = iterate_skips.LineSearch.__call__, {}

    def searched(self, stepper, frame, contacts, sca, disp, step, shearing):
        geom = geoms.setdefault(id(frame.vertex_xy), model.block_geometry(frame.vertex_xy))
        size = np.sqrt(geom["area"])
        target = disp + step
        far = ~model.block_fixed & (block_displacement(model, frame.vertex_xy, geom, target) > mech.MECHANISM_SIZE * size)
        if np.count_nonzero(far) and np.count_nonzero(far & ~mech.anchored(stepper, frame.vertex_xy, geom, contacts,
                                                                           target, size)):
            return 1.0
        return search(self, stepper, frame, contacts, sca, disp, step, shearing)

    iterate_skips.LineSearch.__call__ = searched
    rm.line_search = lambda *args: searched(None, *args)


def floor_still():
    """Experiment (not the library's rule): where the line search ends at its floor, 2^-30 of the
    step (the energy rises from the first bisection's resolution on: a target that throws blocks),
    the iterate does not move (α = 0); its new contact states are judged again at the same D."""
    from ddatai.return_steps import LINE_SEARCH_BISECTIONS

    floor = 1.0 / 2 ** LINE_SEARCH_BISECTIONS
    large, small = iterate_skips.LineSearch.__call__, rm.line_search

    def still(f):
        def g(*args):
            alpha = f(*args)
            return 0.0 if alpha <= floor else alpha
        return g

    iterate_skips.LineSearch.__call__ = still(large)
    rm.line_search = still(small)


def floor_keeps_thrown(model):
    """Experiment (not the library's rule): where the line search ends at its floor (2^-30 of the step),
    the blocks that the solve throws away from what holds it keep their D (their target, solved at a
    condition ~1e12, is not mixed into the iterate); the other blocks take the floor step."""
    from ddatai.kinematics import block_displacement
    from ddatai.return_steps import LINE_SEARCH_BISECTIONS

    floor = 1.0 / 2 ** LINE_SEARCH_BISECTIONS
    plain, large, small, geoms, last = rm.solve, iterate_skips.LineSearch.__call__, rm.line_search, {}, {}

    def solve(*args, **kw):
        last["target"] = plain(*args, **kw)
        return last["target"]

    def keep(stepper, frame, contacts, disp, alpha):
        if alpha > floor:
            return alpha
        geom = geoms.setdefault(id(frame.vertex_xy), model.block_geometry(frame.vertex_xy))
        size = np.sqrt(geom["area"])
        target = last["target"]
        far = ~model.block_fixed & (block_displacement(model, frame.vertex_xy, geom, target) > mech.MECHANISM_SIZE * size)
        if np.count_nonzero(far):
            thrown = far & ~mech.anchored(stepper, frame.vertex_xy, geom, contacts, target, size)
            target[thrown] = disp[thrown]  # in place: the iterate's D is disp + α (target − disp)
        return alpha

    def searched_large(self, stepper, frame, contacts, sca, disp, step, shearing):
        return keep(stepper, frame, contacts, disp, large(self, stepper, frame, contacts, sca, disp, step, shearing))

    def searched_small(stepper, frame, contacts, sca, disp, step, shearing):
        return keep(stepper, frame, contacts, disp, small(stepper, frame, contacts, sca, disp, step, shearing))

    rm.solve, iterate_skips.LineSearch.__call__, rm.line_search = solve, searched_large, searched_small


def trace(a):
    model, stepper = build(a.case, a.solver)
    log: list = []
    judge = rm.iterate_update

    def judged(model, contacts, law, guess, flips, freeze, shearing, weight, tensile, ft, cf):
        u = judge(model, contacts, law, guess, flips, freeze, shearing, weight, tensile, ft, cf)
        log.append(dict(kind="iterate", changed=np.flatnonzero(u.changed), n=contacts.n,
                        **margins(model, contacts, law, guess, flips, freeze, tensile, cf, u)))
        return u

    rm.iterate_update = judged

    def wrap(mod, name):
        f = getattr(mod, name)

        def g(*args, **kw):
            r = f(*args, **kw)
            first = r[0] if isinstance(r, tuple) else r
            log.append(dict(kind=name, blocks=np.flatnonzero(first) if isinstance(first, np.ndarray) and
                            first.dtype == bool else None, result=str(r[1:]) if isinstance(r, tuple) else None))
            return r
        setattr(mod, name, g)

    for name in ("mechanisms", "unsupported_blocks", "loaded_away"):
        wrap(rm, name)
    tested = mech.test_unbalanced

    def test(*args, **kw):
        r = tested(*args, **kw)
        log.append(dict(kind="test_unbalanced", blocks=None,
                        result=f"converged={None if r[0] is None else r[0][2]} solves={r[1]}"))
        return r

    mech.test_unbalanced = test
    state, rec = settle(stepper, model.initial_state())
    print(a.solver, rec)
    with open(a.out, "wb") as f:
        pickle.dump(dict(record=str(rec), log=log, held=held_set(model, state)), f)


def compare(a):
    A, B = (pickle.load(open(p, "rb")) for p in (a.first, a.second))
    print("A:", A["record"], "\nB:", B["record"])
    print(f"held sets differ in {np.count_nonzero(A['held'] != B['held'])} blocks")
    la, lb = A["log"], B["log"]
    it = 0
    print("iterate | contacts changing A/B | spread of q between the runs: excess median, max; state rules median, max")
    for x, y in zip(la, lb):
        if x["kind"] != y["kind"]:
            print("the runs part at a", x["kind"], "against a", y["kind"])
            return
        if x["kind"] != "iterate":
            bx, by = (z["blocks"] if z["blocks"] is not None else np.zeros(0, int) for z in (x, y))
            if not np.array_equal(bx, by) or x["result"] != y["result"]:
                print(f"after iterate {it}: {x['kind']} decides differently: A {len(bx)} blocks {x['result']}, "
                      f"B {len(by)} blocks {y['result']}")
                return
            continue
        it += 1
        spread = {}
        for name in ("excess", "close", "open", "switch"):
            m = np.isfinite(x[name]) & np.isfinite(y[name])
            spread[name] = np.abs(x[name][m] - y[name][m])
        state = np.concatenate([spread["close"], spread["open"], spread["switch"]])
        if it <= 3 or it % 10 == 0 or not np.array_equal(x["changed"], y["changed"]):
            print(f"{it} | {len(x['changed'])}/{len(y['changed'])} | {np.median(spread['excess']):.2e}, "
                  f"{spread['excess'].max(initial=0):.2e}; "
                  f"{np.median(state) if len(state) else np.nan:.2e}, {state.max(initial=0):.2e}")
        if not np.array_equal(x["changed"], y["changed"]):
            diff = np.setxor1d(x["changed"], y["changed"])
            print(f"first difference at iterate {it}: contacts {diff.tolist()} change in one run only")
            for c in diff:
                for name in ("close", "open", "switch"):
                    if np.isfinite(x[name][c]) or np.isfinite(y[name][c]):
                        print(f"  contact {c}, rule {name}: q A {x[name][c]:+.6e}, B {y[name][c]:+.6e} (of the bar)")
            return


def beside(a):
    import scipy.sparse as sp
    from scipy.sparse.linalg import splu
    from ddatai.kinematics import block_displacement

    model, stepper = build(a.case, a.solver)
    geom = model.block_geometry(model.vertex_xy0)
    size = np.sqrt(geom["area"])
    g = dict(k=0, alt=None, alpha=1.0)
    plain, search, law_of, judge = rm.solve, iterate_skips.LineSearch.__call__, rm.stage_law, rm.iterate_update
    rows = []

    def solve(stepper_, pattern, data, rhs, **kw):
        d = plain(stepper_, pattern, data, rhs, **kw)
        g["k"] += 1
        g["alpha"], g["alt"], g["target"] = 1.0, None, d
        if g["k"] <= a.solves:
            nn = 6 * pattern.n_rows
            k = sp.csr_matrix((data, pattern.indices, pattern.indptr), shape=(nn, nn))
            x = d[stepper_.free_idx].reshape(-1)
            alt = np.zeros_like(d)
            alt[stepper_.free_idx] = splu(k.tocsc()).solve(rhs).reshape(-1, 6)
            g["alt"] = alt
            moved = block_displacement(model, model.vertex_xy0, geom, d) / size
            apart = block_displacement(model, model.vertex_xy0, geom, d - alt) / size
            g["row"] = dict(solve=g["k"], condition=float(abs(k).sum(axis=1).max() * np.abs(x).max() / np.abs(rhs).max()),
                            target_moved=float(moved.max()), apart=float(apart.max()),
                            apart_kept=float(apart[moved < mech.MECHANISM_SIZE].max(initial=0.0)))
        return d

    def searched(self, *args, **kw):
        g["alpha"] = search(self, *args, **kw)
        return g["alpha"]

    small_search = rm.line_search  # a model below ``LOWRANK_UNKNOWNS``: `return_steps.line_search`

    def small_searched(*args, **kw):
        g["alpha"] = small_search(*args, **kw)
        return g["alpha"]

    def law(model_, contacts, vec, sca, disp):
        g["law"] = None if g["alt"] is None else \
            law_of(model_, contacts, vec, sca, disp + g["alpha"] * (g["alt"] - g["target"]))
        return law_of(model_, contacts, vec, sca, disp)

    def judged(model_, contacts, law_, guess, flips, freeze, shearing, weight, tensile, ft, cf):
        u = judge(model_, contacts, law_, guess, flips, freeze, shearing, weight, tensile, ft, cf)
        if g.get("law") is not None:
            v = judge(model_, contacts, g["law"], guess, flips, freeze, shearing, weight, tensile, ft, cf)
            q = margins(model_, contacts, law_, guess, flips, freeze, tensile, cf, u)
            r = margins(model_, contacts, g["law"], guess, flips, freeze, tensile, cf, v)
            row = dict(g["row"], changed=int(np.count_nonzero(u.changed)),
                       differ=int(np.count_nonzero(u.changed != v.changed)))
            for name in q:
                m = np.isfinite(q[name]) & np.isfinite(r[name])
                d = np.abs(q[name][m] - r[name][m])
                row[name] = (float(d.max(initial=0.0)), float(np.abs(q[name][m]).min(initial=np.inf)),
                             int(np.count_nonzero(np.abs(q[name][m]) <= d)), int(m.sum()))
            rows.append(row)
            g["law"] = None
        return u

    rm.solve, iterate_skips.LineSearch.__call__, rm.stage_law, rm.iterate_update = solve, searched, law, judged
    rm.line_search = small_searched
    state, rec = settle(stepper, model.initial_state())
    print(rec)
    print("| solve | |K||x|/|b| | target's largest motion [sizes] | solvers apart: largest, on blocks moved < 0.25 "
          "[sizes] | contacts changing (differently) | excess: round-off of q, inside | close: round-off, "
          "nearest |q|, inside | open: round-off, nearest |q|, inside |")
    print("|---|---|---|---|---|---|---|---|")
    for r in rows:
        cell = lambda n: (f"{r[n][0]:.1e}, {r[n][1]:.1e}, {r[n][2]}/{r[n][3]}" if r[n][3] else "—")  # noqa: E731
        print(f"| {r['solve']} | {r['condition']:.1e} | {r['target_moved']:.3g} | {r['apart']:.2e}, {r['apart_kept']:.2e} "
              f"| {r['changed']} ({r['differ']}) | {r['excess'][0]:.1e}, {r['excess'][2]}/{r['excess'][3]} "
              f"| {cell('close')} | {cell('open')} |")
    inside = sum(r[n][2] for r in rows for n in ("close", "open", "switch"))
    asked = sum(r[n][3] for r in rows for n in ("close", "open", "switch"))
    print(f"state decisions inside their solve's round-off: {inside} of {asked}; "
          f"judged differently by the other solver's D: {sum(r['differ'] for r in rows)}")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    p = sub.add_parser("outcome")
    p.add_argument("case")
    p.add_argument("--solver", default="auto")
    p.add_argument("--jitter", type=float, default=0.0)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--take-thrown", action="store_true", help="experiment: `take_thrown`")
    p.add_argument("--floor-still", action="store_true", help="experiment: `floor_still`")
    p.add_argument("--floor-keeps-thrown", action="store_true", help="experiment: `floor_keeps_thrown`")
    p = sub.add_parser("trace")
    p.add_argument("case")
    p.add_argument("--solver", default="auto")
    p.add_argument("--out", required=True)
    p = sub.add_parser("compare")
    p.add_argument("first")
    p.add_argument("second")
    p = sub.add_parser("beside")
    p.add_argument("case")
    p.add_argument("--solver", default="pardiso")
    p.add_argument("--solves", type=int, default=120)
    a = ap.parse_args()
    {"outcome": outcome, "trace": trace, "compare": compare, "beside": beside}[a.cmd](a)


if __name__ == "__main__":
    main()
