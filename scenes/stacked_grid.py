"""
Stacked pile
============

A stacked pile: an n × n grid of unit blocks on a fixed base (aligned columns).

With ``gap = 0`` every block starts in edge-to-edge contact (the base of the block-count
scaling benchmark and of a verification test, run static). The default scene drops the blocks
from small gaps between the rows and lets the pile settle dynamically.
Run ``python scenes/stacked_grid.py [--gif out/stacked_grid.gif]``.
"""

import ddatai as dd

DURATION = 1.0  # s


def build(n: int = 15, gap: float = 0.02, friction: float = 30.0, static: bool = False,
          dt: float | None = None):
    """Returns (scene, params): n × n blocks of 1 m, rows separated by ``gap`` [m], on a fixed
    base; joints with φ = ``friction`` [degrees]."""
    scene = dd.Scene(gravity=9.81)
    rock = dd.Material(density=2500.0, young=5e9, poisson=0.25)
    scene.add_block([(-1, -1), (n + 1, -1), (n + 1, 0), (-1, 0)], material=rock, fixed=True)
    for j in range(n):
        y = j * (1.0 + gap) + gap
        for i in range(n):
            scene.add_block([(i, y), (i + 1, y), (i + 1, y + 1), (i, y + 1)], material=rock)
    scene.set_joint(dd.Joint(friction=friction))
    return scene, dd.Params(static=static, dt=dt)


if __name__ == "__main__":
    from ddatai.cli import run_as_script

    run_as_script(build, DURATION, "stacked_grid")
