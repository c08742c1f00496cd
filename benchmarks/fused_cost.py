"""The fused engine's kernel: its compile time (or load time, from Taichi's offline cache) and its
cost per step, for one checkout:

    python benchmarks/fused_cost.py [--root CHECKOUT] [--steps 400] [--cache DIR]

``--root`` is the checkout whose ``ddatai`` runs (default: this one), so that two versions of the
kernel can be timed side by side (a plain copy of the other commit, ``git archive``); ``--cache``
sets ``TI_OFFLINE_CACHE_FILE_PATH`` (an empty directory: the first call compiles). Threads are
pinned (BLAS and Taichi one thread each: the machine is shared). Prints one JSON line: the first
call's wall time (``warm_s``, `ddatai.fused.warm`: compile or load, and two steps of a block on a
plane) and ms per step, amortised over ``--steps``, of ntdda's grid scenes of 1 and 16 blocks
(`scaling_scenes.grid_scene`, sudden start) and the paper's Example I after its equilibrium stage.
Pair two checkouts by running them alternately, and say the machine's load.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

PINNED = {k: "1" for k in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "TI_CPU_MAX_NUM_THREADS")}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--root", default=str(Path(__file__).resolve().parents[1]))
    ap.add_argument("--steps", type=int, default=400)
    ap.add_argument("--cache", default=None)
    a = ap.parse_args()
    os.environ.update(PINNED)
    if a.cache:
        os.environ["TI_OFFLINE_CACHE_FILE_PATH"] = a.cache
    sys.path[:0] = [a.root, str(Path(__file__).resolve().parent)]
    import dataclasses

    import ddatai
    from ddatai.fused import engine
    from ddatai.fused.pack import Member
    from ddatai.fused.warm import warm
    from ddatai.model import build_model
    from ddatai.start import settle
    from ddatai.step import Stepper

    assert Path(ddatai.__file__).resolve().is_relative_to(Path(a.root).resolve()), ddatai.__file__
    out = {"root": a.root, "warm_s": warm()}
    print(json.dumps(out), flush=True)
    from scaling_scenes import grid_scene
    from scenes import example_1

    for case in ("grid_1", "grid_16", "example_1"):
        if case == "example_1":
            scene, params = example_1.build(friction=14.0)
        else:
            scene, params = grid_scene(int(case.split("_")[1]))
            params = dataclasses.replace(params, initial_equilibrium=False)
        model = build_model(scene, dataclasses.replace(params, kernels="numpy", solver="dense"))
        state = model.initial_state()
        if model.params.initial_equilibrium:
            state, _ = settle(Stepper(model), state)
        engine.run([Member(model=model, state=state, step_end=state.step + 10)])
        t = time.perf_counter()
        res = engine.run([Member(model=model, state=state, step_end=state.step + a.steps)])[0]
        assert res.status == "done", res.status
        out[case + "_ms"] = 1e3 * (time.perf_counter() - t) / a.steps
    print(json.dumps(out))


if __name__ == "__main__":
    main()
