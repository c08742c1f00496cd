"""Corner hand-overs and kicks of the stacks of squares under the slow gravity ramp
(tests/toppling_cases.py, docs/method/dda.md §3.4).

    python benchmarks/corner_handover.py CASE THETA [--frame turned|tilted] [--ramp 20]

Runs `toppling_cases.ramp_topples`'s loading step by step and counts, per step, the corner
pairs (P, Q) that change representation: a vertex-vertex contact (P, Q) one step and a
vertex-edge contact of P on an edge at Q (or of Q on an edge at P) the next, or back. A "kick"
is a step's largest change of a free block's velocity, |Δv| / (g·Δt). Prints the hand-overs,
the steps with one, the largest and the 99th-percentile kick, and whether the stack toppled.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tests"))

import ddatai as dd  # noqa: E402
import toppling_cases as tc  # noqa: E402
from ddatai.layout import VE  # noqa: E402


def corner_pairs(model, memory) -> tuple[set, set]:
    """(vertex-vertex pairs, vertex-edge (vertex, partner) pairs at an edge's end) of a memory."""
    nv = model.n_vertices
    vv = memory.kind != VE
    first, second = np.divmod(memory.key[vv] - nv * nv, nv)
    pairs = {(int(min(a, b)), int(max(a, b))) for a, b in zip(first, second)}
    v, e = np.divmod(memory.key[~vv], nv)
    ends = set()
    for a, b in zip(v, e):
        for w in (int(b), int(model.vertex_next[b])):
            ends.add((int(min(a, w)), int(max(a, w))))
    return pairs, ends


def run(case, theta: float, frame: str, ramp_times: float) -> dict:
    from ddatai.step import Stepper

    tau = tc.rocking_time(case)
    ramp, hold = ramp_times * tau, tc.HOLD_TIMES * tau
    th = math.radians(theta) if frame == "turned" else 0.0
    sc = tc.scene(case, 0.0 if frame == "turned" else theta)
    sc.set_ground_acceleration(tc._turning_gravity(lambda t: th, lambda t: tc._smoothstep(t, ramp)))
    model = dd.build_model(sc, dd.Params(initial_equilibrium=False))
    stepper = Stepper(model)
    state = model.initial_state()
    free = ~model.block_fixed
    limit = tc.TOPPLED * case.tallest
    steps = handovers = stepped = 0
    kicks = []
    last_vv, last_ends = set(), set()
    toppled = False
    while state.time < ramp + hold:
        new = stepper.advance(state).state
        dt = new.time - state.time
        dv = np.hypot(*(new.block_velocity[free, :2] - state.block_velocity[free, :2]).T)
        kicks.append(float(dv.max()) / (tc.G * dt))
        vv, ends = corner_pairs(model, new.memory)
        n = len((last_vv - vv) & ends) + len((vv - last_vv) & last_ends)
        handovers += n
        stepped += n > 0
        last_vv, last_ends = vv, ends
        state = new
        steps += 1
        if float(np.abs(state.vertex_xy - model.vertex_xy0).max()) > limit:
            toppled = True
            break
    return dict(steps=steps, handovers=handovers, steps_with=stepped, kick_max=max(kicks),
                kick_p99=float(np.percentile(kicks, 99)), toppled=toppled, time=state.time)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("case")
    ap.add_argument("theta", type=float)
    ap.add_argument("--frame", default="turned")
    ap.add_argument("--ramp", type=float, default=tc.RAMP_TIMES)
    a = ap.parse_args()
    t0 = time.perf_counter()
    r = run(tc.CASES[a.case][0], a.theta, a.frame, a.ramp)
    print(f"{a.case} {a.theta}° {a.frame} {a.ramp:g}τ: {r['handovers']} hand-overs in {r['steps_with']} of "
          f"{r['steps']} steps, kicks max {r['kick_max']:.1f} p99 {r['kick_p99']:.2f} g·Δt, "
          f"toppled {r['toppled']} at t {r['time']:.3f} s, wall {time.perf_counter() - t0:.0f} s", flush=True)


if __name__ == "__main__":
    main()
