"""Trace the equilibrium stage (`ddatai.start`) on ntdda's grid, optionally with its Young's
modulus and penalty scaled, to reproduce a large grid's start on a smaller one.

    python benchmarks/stage_trace.py SIZE [--young-factor F] [--penalty-factor F]
    python benchmarks/stage_trace.py SIZE --scaling     # scaling.py's settled run, traced

The grid's start is set by dimensionless ratios: with 1 m blocks, its settlement in block sizes
∝ n²·ρ·g/E, its base penetration ∝ n·ρ·g/p and the contraction ratio of its pseudo-steps
(weight over buckling weight, docs/guide/equilibrium_start.md) ∝ n³·ρ·g/p for an n × n grid. The
80 × 80 grid with E/4 and p/2 has the 160 × 160 grid's settlement and penetration (its
contraction ratio is a quarter of it, still far past 1). Each line says what the stage did: every
return-mapping iteration (`return_mapping._iterate`: solves, whether it converged, the largest
block displacement), every release (`mechanisms`, `unsupported_blocks`, `loaded_away`) and each
pseudo-step's increment. ``--scaling`` runs `benchmarks/scaling.py`'s settled protocol
(`run_one`, one step) with the same trace and prints its JSON record last.
"""

from __future__ import annotations

import argparse
import json
import time

from scaling_scenes import GRID_STEP, use_checkout

use_checkout()


def trace() -> None:
    """Wrap the stage's phases so that each prints one line (CPU seconds since the start)."""
    import numpy as np

    from ddatai import return_mapping as rm
    from ddatai import start as st
    from ddatai.kinematics import block_displacement

    t0 = time.process_time()

    def say(text: str) -> None:
        print(f"[{time.process_time() - t0:8.1f} s] {text}", flush=True)

    iterate = rm._iterate

    def traced_iterate(stepper, frame, contacts, geom, out, size, guess, freeze=False, tail=None):
        outcome, g = iterate(stepper, frame, contacts, geom, out, size, guess, freeze, tail)
        moved = None if outcome.disp is None else \
            float(block_displacement(stepper.model, frame.vertex_xy, geom, outcome.disp)[~out].max(initial=0.0))
        say(f"  iteration: {outcome.solves} solves, converged {outcome.converged}, steady {outcome.steady}, "
            f"freeze {freeze}, closed {int(g.closed.sum())}/{len(g.closed)}, largest move {moved} m, "
            f"released so far {int(np.count_nonzero(out & ~stepper.model.block_fixed))}")
        return outcome, g

    rm._iterate = traced_iterate
    for name in ("mechanisms", "unsupported_blocks", "loaded_away"):
        phase = getattr(rm, name)

        def traced(*args, _phase=phase, _name=name, **kw):
            out = _phase(*args, **kw)
            found = out[0] if isinstance(out, tuple) else out
            if found is not None and np.any(found):
                say(f"  {_name}: {int(np.count_nonzero(found))} blocks")
            return out

        setattr(rm, name, traced)
    mapping = st.return_mapping

    def traced_mapping(*args, **kw):
        out = mapping(*args, **kw)
        say(f" pseudo-step: {out[1]} solves, {int(out[2].sum())} released, equilibrium {out[0] is not None}, "
            f"stalled {out[4]}, does not contract {out[5]}, out of range {out[6] if len(out) > 6 else '-'}")
        return out

    st.return_mapping = traced_mapping
    measure = st.block_displacement

    def traced_measure(*args, **kw):
        out = measure(*args, **kw)
        say(f" increment {float(out.max(initial=0.0)):.4g} m")
        return out

    st.block_displacement = traced_measure


def scaled_grid(size: int, young: float, penalty: float, penetration: float = 1.0, columns: int = 0):
    """ntdda's grid (`scaling_scenes.grid_scene`) with E × ``young``, p × ``penalty`` and the
    penetration ratio g3 (the penetration limit 2.5·g3·w0) × ``penetration``; ``columns`` > 0: that
    many columns of size // columns rows (a tall grid keeps the square grid's column height)."""
    import dataclasses

    import ddatai as dd
    from scaling_scenes import grid_scene

    scene, params = grid_scene(size)
    n = int(round(size ** 0.5))
    width, height = (columns, size // columns) if columns else (n, n)
    rock = dd.Material(density=2000.0, young=1e8 * young, poisson=0.25)
    scaled = dd.Scene(gravity=9.81)
    scaled.add_block([(-1, -1), (width + 1, -1), (width + 1, 0), (-1, 0)], material=rock, fixed=True)
    for j in range(height):
        for i in range(width):
            scaled.add_block([(i, j), (i + 1, j), (i + 1, j + 1), (i, j + 1)], material=rock)
    scaled.set_joint(dd.Joint(friction=30.0))
    return scaled, dataclasses.replace(params, penalty=params.penalty * penalty,
                                       penetration_ratio=params.penetration_ratio * penetration)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("size", type=int)
    ap.add_argument("--young-factor", type=float, default=1.0)
    ap.add_argument("--penalty-factor", type=float, default=1.0)
    ap.add_argument("--penetration-factor", type=float, default=1.0,
                    help="g3 (Params.penetration_ratio) × this: keeps a penetration's ratio to the limit")
    ap.add_argument("--columns", type=int, default=0, help="a grid of this many columns (SIZE // COLUMNS rows)")
    ap.add_argument("--scaling", action="store_true", help="scaling.py's settled run (unscaled grid), traced")
    a = ap.parse_args()
    trace()
    if a.scaling:
        from scaling import run_one

        print(json.dumps(run_one("grid", a.size, 1, 0, "cpu", "auto", 0, "settled")), flush=True)
        return
    import ddatai as dd
    from ddatai.start import settle
    from ddatai.step import Stepper

    scene, params = scaled_grid(a.size, a.young_factor, a.penalty_factor, a.penetration_factor, a.columns)
    model = dd.build_model(scene, params)
    assert abs(model.max_step - GRID_STEP) < 1e-12
    cpu = time.process_time()
    _, record = settle(Stepper(model), model.initial_state())
    print(record)
    print(f"stage CPU {time.process_time() - cpu:.1f} s")


if __name__ == "__main__":
    main()
