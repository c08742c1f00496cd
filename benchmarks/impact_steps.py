"""Where a failing model's solves go, step by step: each step's Δt, its kind (a lead step that
ends before a closing, an impact step, a plain step), its solves, rejected attempts and CPU time.

    python benchmarks/impact_steps.py [--family slope] [--size 391] [--steps 100] [--params NAME=VALUE,...]

After the equilibrium stage (the settled protocol of ``benchmarks/scaling.py``; its first step
untimed), each step's kind comes from `ddatai.impacts.approach_bound` (recorded as the step calls
it): ``lead`` where it shortened the step to end before a closing, ``impact`` where the step is
the impact step of a closing (``retaken`` where the plastic impact took it again), else
``plain``; ``after`` marks the step right after a lead or impact step. Prints the steps and a
summary by kind: steps, simulated time, solves and CPU seconds.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from scaling_scenes import case_parser, case_scene, use_checkout  # noqa: E402

use_checkout()


def main() -> None:
    import ddatai as dd
    import ddatai.step as step_module
    from ddatai.start import settle
    from ddatai.step import Stepper

    ap = case_parser(__doc__, steps=100)
    ap.add_argument("--quiet", action="store_true", help="only the summary")
    a = ap.parse_args()
    scene, params = case_scene(a)
    model = dd.build_model(scene, params)
    stepper = Stepper(model)
    cpu = time.process_time()
    state, start = settle(stepper, model.initial_state())
    print(f"{a.family} {model.n_free:,} free blocks; stage {time.process_time() - cpu:.1f} s CPU, held {start.held}, "
          f"released {start.released}, welded {bool(start.welded)}")
    state, _ = stepper.step(state)
    seen = {}
    original = step_module.approach_bound

    def recording(model, state, contacts, vec, sca, dt):
        bound, closing = original(model, state, contacts, vec, sca, dt)
        seen.update(dt=dt, bound=bound, closing=bool(closing.any()))
        return bound, closing

    step_module.approach_bound = recording
    rows, last_kind = [], "plain"
    for _ in range(a.steps):
        seen.clear()
        t = time.process_time()
        state, rec = stepper.step(state)
        t = time.process_time() - t
        kind = "impact" if seen.get("closing") else "lead" if seen.get("bound", np.inf) < seen.get("dt", 0.0) else "plain"
        after = last_kind in ("lead", "impact")
        rows.append((kind, after, rec.dt, rec.oc_total, rec.oc_iterations, rec.dt_cuts, t))
        if not a.quiet:
            print(f"{state.step:5d} {kind:6s}{' after' if after else '      '} dt {rec.dt * 1e3:8.4f} ms  solves {rec.oc_total:3d} "
                  f"(accepted {rec.oc_iterations:3d}, cuts {rec.dt_cuts})  {t * 1e3:7.0f} ms CPU")
        last_kind = kind
    sim = sum(r[2] for r in rows)
    total = sum(r[6] for r in rows)
    print(f"\n{len(rows)} steps, {sim * 1e3:.2f} ms simulated, {total:.2f} s CPU: {total / sim:.0f} CPU s per simulated s, "
          f"{sum(r[3] for r in rows) / len(rows):.2f} solves a step")
    print("| kind | steps | simulated ms | solves | solves/step | cuts | CPU s |\n|---|---|---|---|---|---|---|")
    for label, pick in (("lead", lambda r: r[0] == "lead"), ("impact", lambda r: r[0] == "impact"),
                        ("plain after lead/impact", lambda r: r[0] == "plain" and r[1]),
                        ("plain otherwise", lambda r: r[0] == "plain" and not r[1])):
        sel = [r for r in rows if pick(r)]
        if sel:
            print(f"| {label} | {len(sel)} | {sum(r[2] for r in sel) * 1e3:.2f} | {sum(r[3] for r in sel)} | "
                  f"{sum(r[3] for r in sel) / len(sel):.1f} | {sum(r[5] for r in sel)} | {sum(r[6] for r in sel):.2f} |")


if __name__ == "__main__":
    main()
