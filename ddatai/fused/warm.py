"""Compile the fused engine's kernel ahead of a session (or take it from Taichi's offline cache),
so that ``Params(kernels="auto")`` runs kgm's judgements and small simulations on it from the
first call (`ddatai.fused.policy`):

    python -m ddatai.fused [--arch cpu|cuda]

The compile is paid once per machine, architecture and version of the kernel's source; it is kept
in Taichi's offline cache (``~/.cache/taichi/ticache``, or ``TI_OFFLINE_CACHE_FILE_PATH``).
"""

from __future__ import annotations

import time


def warm(arch: str = "cpu") -> float:
    """Run the fused kernel once (a block on a plane, two steps) on ``arch``: compiled the first
    time on this machine, loaded from the offline cache after. Returns the wall time [s]."""
    from ..model import build_model
    from ..params import Params
    from ..scene import Joint, Material, Scene
    from . import engine
    from .pack import Member

    t0 = time.perf_counter()
    scene = Scene(gravity=9.81)
    rock = Material(density=2500.0, young=5e9, poisson=0.25)
    scene.add_block([(-1.0, -1.0), (3.0, -1.0), (3.0, 0.0), (-1.0, 0.0)], material=rock, fixed=True)
    scene.add_block([(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)], material=rock)
    scene.set_joint(Joint(friction=30.0))
    model = build_model(scene, Params(dt=1e-3, kernels="numpy", initial_equilibrium=False))
    engine.run([Member(model=model, state=model.initial_state(), step_end=2)], arch=arch)
    return time.perf_counter() - t0


def main(argv=None) -> int:
    import argparse

    from .policy import cache_dir

    ap = argparse.ArgumentParser(prog="python -m ddatai.fused", description=__doc__.split("\n\n")[0])
    ap.add_argument("--arch", default="cpu", choices=("cpu", "cuda"))
    args = ap.parse_args(argv)
    seconds = warm(args.arch)
    print(f"the fused kernel ({args.arch}) is ready: {seconds:.1f} s; Taichi's offline cache: {cache_dir()}")
    return 0
