"""Count the equilibrium stage's open/close flips (`return_mapping._iterate`) by the force and
the gap that decided them: are the stage's refactorisations spent on contacts that carry
round-off-level forces?

    python benchmarks/stage_chatter.py --family grid --size 1600
    python benchmarks/stage_chatter.py --family grid --size 6400 --columns 40   # 40 wide, 160 tall

Nothing in the library changes: ``return_mapping.stage_law`` (called once an iterate, after the
solve, on the contacts in the states of that iterate) and ``return_mapping._iterate`` are wrapped.
Between two successive iterates of one `_iterate` call, a contact whose closed state differs
opened or closed on the law of the earlier iterate; that law's normal force pen·|dn| [N/m] (the
pull that opened it, or the overlap force that closed it) is counted against
``Model.force_roundoff`` (p·open_tolerance·w0) and against the weight of the lighter free block
of the contact, and its normal distance |dn| against ``Model.open_tol`` (open_tolerance·w0) and
ntdda's closing band 2e-4·w0. Each flip is classed as a vertical-joint or horizontal-joint
vertex-edge contact (by the edge's direction) or a vertex-vertex one. Prints, per `_iterate`
call, the iterates that changed states (each a factorisation), and the totals; with
``--iterates``, one line per iterate with changes.
"""

from __future__ import annotations

import argparse
import collections
import time

import numpy as np

from scaling_scenes import SCENES, use_checkout

use_checkout()

#: decades of the deciding force over the lighter free block's weight
FORCE_BINS = (0.0, 1e-12, 1e-9, 1e-6, 1e-3, 1e-1, np.inf)
FORCE_NAMES = ("<1e-12", "1e-12..1e-9", "1e-9..1e-6", "1e-6..1e-3", "1e-3..0.1", ">=0.1")


def main() -> None:
    import ddatai as dd
    from ddatai import return_mapping as rm
    from ddatai.layout import KIND, OPEN, VE
    from ddatai.start import settle
    from ddatai.step import Stepper

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--family", default="grid", choices=tuple(SCENES))
    ap.add_argument("--size", type=int, default=1600)
    ap.add_argument("--columns", type=int, default=0, help="grid only: this many columns (SIZE // COLUMNS rows)")
    ap.add_argument("--iterates", action="store_true", help="one line per iterate with changes")
    a = ap.parse_args()
    if a.columns:
        from stage_trace import scaled_grid

        scene, params = scaled_grid(a.size, 1.0, 1.0, 1.0, a.columns)
    else:
        scene, params = SCENES[a.family](a.size)
    model = dd.build_model(scene, params)
    stepper = Stepper(model)
    pen, w0 = float(model.penalty), float(model.w0)
    ntdda_band = 2e-4 * w0
    g = float(np.hypot(*model.gravity))

    calls = []     # per _iterate call: list of per-iterate flip records
    ctx = {}       # the running _iterate call: its contacts, geometry and last law

    law_fn = rm.stage_law

    def recording_law(model_, contacts, vec, sca, disp):
        law = law_fn(model_, contacts, vec, sca, disp)
        closed = contacts.state != OPEN
        prev = ctx.get("prev")
        if prev is not None and len(prev[0]) == contacts.n:
            was_closed, dn, line = prev
            flip = closed != was_closed
            switch = (contacts.cint[:, KIND] != VE) & closed & was_closed & (contacts.line != line)
            calls[-1].append(dict(flip=np.flatnonzero(flip), dn=dn[flip], opened=was_closed[flip],
                                  switch=int(switch.sum()), closed=int(closed.sum())))
        ctx["prev"] = (closed.copy(), law.dn.copy(), contacts.line.copy())
        ctx["fn"] = np.where(closed & law.closed, law.fn, 0.0)
        ctx["overlapping"] = ~closed & law.closed & (law.fn > model_.force_roundoff)  # would close
        ctx["fn_open"] = np.where(ctx["overlapping"], law.fn, 0.0)
        return law

    iterate = rm._iterate

    def recording_iterate(stepper_, frame, contacts, geom, out, size, guess, freeze=False, tail=None):
        calls.append([])
        ctx.clear()
        weight = model.block_density * geom["area"] * g
        free_weight = np.where(model.block_fixed, np.inf, weight)
        lighter = np.minimum(free_weight[contacts.block_a], free_weight[contacts.block_b])
        ve = contacts.cint[:, KIND] == VE
        edge = contacts.cint[:, 2]
        d = frame.vertex_xy[model.vertex_next[edge]] - frame.vertex_xy[edge]
        kind = np.where(ve, np.where(np.abs(d[:, 0]) < np.abs(d[:, 1]), "vert", "horiz"), "vv")
        result = iterate(stepper_, frame, contacts, geom, out, size, guess, freeze, tail)
        for rec in calls[-1]:
            rec["kind"] = kind[rec["flip"]]
            rec["force_w"] = pen * np.abs(rec["dn"]) / lighter[rec["flip"]]
        fn = ctx.get("fn", np.zeros(contacts.n)) / lighter  # the last iterate's normal forces
        carried = {name: fn[(kind == name) & (fn > 0.0)] for name in ("vert", "horiz", "vv")}
        over = ctx.get("overlapping", np.zeros(contacts.n, bool))
        pressed = ctx.get("fn_open", np.zeros(contacts.n))[over] / lighter[over]
        calls[-1] = dict(iterates=calls[-1], freeze=freeze, n=contacts.n, solves=result[0].solves, carried=carried,
                         overlapping=collections.Counter(kind[over].tolist()),
                         overlap_force=np.percentile(pressed, [0, 50, 100]) if len(pressed) else [])
        return result

    rm.stage_law, rm._iterate = recording_law, recording_iterate
    c0 = time.process_time()
    f0 = stepper.solver.factorisations
    _, start = settle(stepper, model.initial_state())
    cpu = time.process_time() - c0
    print(f"{a.family} {a.size}{' columns ' + str(a.columns) if a.columns else ''}: {model.n_free} free blocks; "
          f"stage {cpu:.1f} s CPU (instrumented), {start.solves} solves, "
          f"{stepper.solver.factorisations - f0} factorisations; held {start.held}, released {start.released}, "
          f"welded {bool(start.welded)}")
    print(f"force_roundoff {model.force_roundoff:.3g} N/m, open_tol {model.open_tol:.3g} m, "
          f"ntdda's closing band 2e-4·w0 {ntdda_band:.3g} m, penalty {pen:.3g} N/m")
    total = collections.Counter()
    by_force = collections.Counter()
    by_gap = collections.Counter()
    changing = only_small = only_tiny = only_step = 0
    times = collections.Counter()  # contacts by how often they flipped in one _iterate call
    smallest = []
    reflips = 0                    # flips of a contact that had flipped before in the call
    for k, call in enumerate(calls):
        its = call["iterates"]
        with_changes = [r for r in its if len(r["flip"]) or r["switch"]]
        changing += len(with_changes)
        count = np.zeros(call["n"], np.int64)
        for r in its:
            reflips += int(np.count_nonzero(count[r["flip"]]))
            count[r["flip"]] += 1
        times.update(np.minimum(count[count > 0], 4).tolist())
        print(f"_iterate call {k}: {call['n']} contacts, freeze {call['freeze']}, {call['solves']} solves, "
              f"{len(its) + 1} laws, {len(with_changes)} iterates with state changes; at its last iterate, "
              "pressed contacts (N / lighter block's weight: count, median, < 1e-3): " +
              "; ".join(f"{kind} {len(v)}, {np.median(v) if len(v) else 0:.2e}, {int(np.sum(v < 1e-3))}"
                        for kind, v in call["carried"].items()) +
              f"; open but overlapping beyond force_roundoff (would close): {dict(call['overlapping'])}, "
              f"N / weight min, median, max {np.round(call['overlap_force'], 4)}")
        for i, r in enumerate(its, start=2):
            fw = r["force_w"]
            gap = np.abs(r["dn"])
            if len(gap):
                smallest.append(pen * float(gap.min()) / model.force_roundoff)
            for kind, opened, f, dn in zip(r["kind"].tolist(), r["opened"], fw, gap):
                total[(kind, "opens" if opened else "closes")] += 1
                by_force[(kind, FORCE_NAMES[int(np.searchsorted(FORCE_BINS, f, side="right")) - 1])] += 1
                by_gap[(kind, "<=open_tol" if dn <= model.open_tol else
                        "<=2e-4 w0" if dn <= ntdda_band else ">2e-4 w0")] += 1
            if len(r["flip"]) or r["switch"]:
                only_small += bool(len(fw) and np.all(fw < 1e-6) and not r["switch"])
                only_step += bool(len(fw) and np.all(fw < 1e-3) and not r["switch"])
                only_tiny += bool(len(fw) and np.all(pen * gap <= 10 * model.force_roundoff) and not r["switch"])
                if a.iterates:
                    kinds = collections.Counter(r["kind"].tolist())
                    print(f"  iterate {i}: {len(r['flip'])} flips ({dict(kinds)}; opened {int(r['opened'].sum())}), "
                          f"{r['switch']} vv line switches; force/weight median "
                          f"{np.median(fw) if len(fw) else 0:.2e}, min {fw.min(initial=np.inf):.2e}; "
                          f"|dn| median {np.median(gap) if len(gap) else 0:.2e} m; closed {r['closed']}")
    print(f"iterates with state changes: {changing}; of them only flips < 1e-6 × weight: {only_small}; "
          f"only flips within 10 × force_roundoff: {only_tiny}; only flips < 1e-3 × weight: {only_step}")
    print(f"contacts by flips in one call (1, 2, 3, >=4): {[times[i] for i in (1, 2, 3, 4)]}; "
          f"flips of a contact that had flipped before: {reflips} of {sum(total.values()) if total else 0}")
    print("flips by kind:", dict(total))
    print(f"smallest deciding force: {min(smallest, default=np.inf):.3g} × force_roundoff")
    print("deciding force / lighter block's weight:")
    for kind in ("vert", "horiz", "vv"):
        print(f"  {kind:5s}", "  ".join(f"{name} {by_force[(kind, name)]}" for name in FORCE_NAMES))
    print("deciding |dn|:")
    for kind in ("vert", "horiz", "vv"):
        print(f"  {kind:5s}", "  ".join(f"{name} {by_gap[(kind, name)]}"
                                        for name in ("<=open_tol", "<=2e-4 w0", ">2e-4 w0")))


if __name__ == "__main__":
    main()
