"""The frictional stage from the welded equilibrium (a welded predictor): does it hold ntdda's grid
where the first pseudo-step's return mapping left DDA's range (`ddatai.start`, 6.)?

    python benchmarks/stage_from_welded.py SIZE [--columns N] [--no-limit]
    python benchmarks/stage_from_welded.py SIZE [--columns N] --first   # the first pseudo-step from t = 0

Runs the welded stage (``settle(..., welded=True)``: the same equilibrium that the stage falls back
on, with each contact then taking the joint law: pulled ones open, those beyond their Coulomb
strength locked at it), then one frictional pseudo-step (`return_mapping`) from there: the
settled geometry, the contacts as the welded stage hands them over, the contraction test against
the welded stage's last increment (``--no-limit``: none, as a first pseudo-step's, with its
out-of-range test). Prints, at the predictor, the joints' contacts by orientation and height
(closed, opened by the joint law, beyond their strength, the median normal force of those
left closed), then every
return-mapping iterate of the pseudo-step (the largest block move and where, the largest
rotation, the closed contacts, those that would open or close and those beyond strength, the
vertical joints' and the vertex-vertex ones among them) and what it threw. ``--first``: the same
lines for the stage's first pseudo-step from t = 0 instead. Results:
benchmarks/results/stage_divergence.md.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from scaling_scenes import use_checkout

use_checkout()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("size", type=int)
    ap.add_argument("--columns", type=int, default=0, help="a grid of this many columns (SIZE // COLUMNS rows)")
    ap.add_argument("--no-limit", action="store_true", help="no contraction test (a first pseudo-step's)")
    ap.add_argument("--first", action="store_true", help="trace the first pseudo-step from t = 0 instead")
    a = ap.parse_args()

    import ddatai as dd
    from ddatai import start as st
    from ddatai.layout import KIND, OPEN, SLIDE, VE
    from ddatai.model import ContactMemory
    from ddatai.step import Stepper
    from stage_trace import scaled_grid

    width = a.columns or int(round(a.size ** 0.5))
    scene, params = scaled_grid(a.size, 1.0, 1.0, 1.0, a.columns)
    model = dd.build_model(scene, params)
    t0 = time.process_time()

    def where(b: int) -> str:
        return f"{b} (row {(b - 1) // width}, column {(b - 1) % width})"

    def joints(c):
        """vertical joints (side by side), horizontal ones (one above the other), the base's"""
        both = (c.block_a > 0) & (c.block_b > 0)
        apart = np.abs(c.block_a - c.block_b)
        return both & (apart == 1), both & (apart == width), ~both

    # the welded stage, its increments and, at its hand-over, the joint law's verdict
    increments, seen = [], {}
    measure, unweld = st.block_displacement, st.unweld

    def logged(*args):
        out = measure(*args)
        increments.append(float(out.max(initial=0.0)))
        return out

    def judged(stepper, c):
        before = c.state != OPEN
        unweld(stepper, c)
        # copies: the stage then locks those beyond their strength at it (`lock_at_strength`)
        seen.update(c=c, before=before, state=c.state.copy(), force=c.normal_force.copy())

    st.block_displacement, st.unweld = logged, judged
    stepper = Stepper(model)
    if a.first:
        trace_pseudo_step(a, model, stepper, model.initial_state().replace(memory=ContactMemory.empty()), np.inf, where,
                          joints, t0)
        return
    predictor, record = st.settle(stepper, model.initial_state(), welded=True)
    st.block_displacement, st.unweld = measure, unweld
    print(f"[{time.process_time() - t0:7.1f} s] welded: {record.solves} solves, increments "
          + ", ".join(f"{d:.3g}" for d in increments) + " m", flush=True)
    c, before, judged_state, force = seen["c"], seen["before"], seen["state"], seen["force"]
    ve = c.cint[:, KIND] == VE
    rows = (np.maximum(c.block_a, c.block_b) - 1) // width
    height = int(rows.max()) + 1
    for name, sel in zip(("vertical", "horizontal", "base"), joints(c)):
        for lo in range(0, height, max(height // 4, 1)):
            s = sel & before & (rows >= lo) & (rows < lo + max(height // 4, 1))
            if s.any():
                print(f"  {name:10s} rows {lo:3d}+: closed {int(s.sum()):6d}, opened by the law {int((s & (judged_state == OPEN)).sum()):6d},"
                      f" beyond strength {int((s & ve & (judged_state == SLIDE)).sum()):6d}, median N "
                      f"{np.median(force[pressed]) if (pressed := s & ve & (judged_state != OPEN)).any() else 0.0:.3g} N/m")
    trace_pseudo_step(a, model, stepper, predictor, np.inf if a.no_limit else st.GEOMETRY_CONTRACTION * increments[-1],
                      where, joints, t0)


def trace_pseudo_step(a, model, stepper, state, limit: float, where, joints, t0: float) -> None:
    """One frictional pseudo-step from ``state`` (its geometry and contact memory), traced iterate
    by iterate, ``limit``: the contraction test's last increment [m]."""
    from ddatai import return_mapping as rm
    from ddatai import start as st
    from ddatai.contacts import Contacts
    from ddatai.layout import KIND, OPEN, VE
    from ddatai.mechanisms import pseudo_time_step
    from ddatai.return_mapping import Frame, return_mapping
    from ddatai.threads import dense_solves

    free = ~model.block_fixed
    vertical = {}
    block_displacement, stage_law, mechanisms = rm.block_displacement, rm.stage_law, rm.mechanisms
    count = [0]

    def traced_moves(model_, xy, geom, disp):
        out = block_displacement(model_, xy, geom, disp)
        count[0] += 1
        moved = np.where(free, out, 0.0)
        b, r = int(np.argmax(moved)), int(np.argmax(np.abs(disp[:, 2])))
        print(f"  iterate {count[0]:3d}: largest move {moved[b]:.3g} m at {where(b)}, largest rotation "
              f"{abs(disp[r, 2]):.3g} rad at {where(r)}", flush=True)
        return out

    def traced_law(model_, contacts, vec, sca, disp):
        law = stage_law(model_, contacts, vec, sca, disp)
        closed = contacts.state != OPEN
        if "vertical" not in vertical or len(vertical["vertical"]) != contacts.n:
            vertical["vertical"] = joints(contacts)[0]
        v = vertical["vertical"]
        beyond = closed & (contacts.cint[:, KIND] == VE) & (model.shear_penalty * np.abs(law.ds) > law.strength)
        opens, closes = closed & ~law.closed, ~closed & law.closed
        corner = contacts.cint[:, KIND] != VE
        print(f"      closed {int(closed.sum())} (vertical joints {int((closed & v).sum())}), would open "
              f"{int(opens.sum())} (vertical joints {int((opens & v).sum())}, vertex-vertex {int((opens & corner).sum())}), "
              f"would close {int(closes.sum())} ({int((closes & v).sum())}, {int((closes & corner).sum())}), "
              f"beyond strength {int(beyond.sum())} (vertical joints {int((beyond & v).sum())})")
        return law

    def traced_mechanisms(*args, **kw):
        out = mechanisms(*args, **kw)
        if out.any():
            print("  thrown: " + ", ".join(where(int(b)) for b in np.flatnonzero(out)), flush=True)
        return out

    rm.block_displacement, rm.stage_law, rm.mechanisms = traced_moves, traced_law, traced_mechanisms
    geom0 = model.block_geometry(model.initial_state().vertex_xy)
    size = np.sqrt(geom0["area"])
    released = np.zeros(model.n_blocks, bool)
    with dense_solves(stepper.solver):
        dt = pseudo_time_step(stepper, geom0, size)
        geom = model.block_geometry(state.vertex_xy)
        cint, length = stepper.detect(state.vertex_xy, state.memory)
        contacts = Contacts.start(model, state.vertex_xy, cint, length, state.memory, True)
        frame = Frame.build(stepper, state, geom, contacts, dt)
        if not a.first:
            print(f"  balanced at the predictor: {st.balanced(stepper, frame, contacts, geom, size)}")
        disp, n, found, _, stalled, unsettled, diverged = return_mapping(
            stepper, state, geom, contacts, dt, released, size, frame, None, np.zeros(model.n_blocks, bool),
            contraction=limit)
    print(f"[{time.process_time() - t0:7.1f} s] frictional pseudo-step from {'t = 0' if a.first else 'the predictor'}: {n} solves, "
          f"equilibrium {disp is not None}, released {int(found.sum())}, stalled {stalled}, "
          f"does not contract {unsettled}, out of range {diverged}")


if __name__ == "__main__":
    main()
