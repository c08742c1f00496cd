"""
Sliding block
=============

A block sliding down an inclined plane, next to one that stays (docs/method/dda.md §7a, §7b).

Both blocks sit on one 30° plane; the lower joint has φ = 20° (it slides with
a = g(sinθ − cosθ tanφ)), the upper one φ = 40° (it stays).
Run ``python scenes/sliding_block.py [--gif out/sliding_block.gif]``.
"""

import numpy as np

import ddatai as dd

DURATION = 1.5  # s


def build(theta: float = 30.0, phi_slide: float = 20.0, phi_stay: float = 40.0):
    """Returns (scene, params)."""
    th = np.radians(theta)
    t = np.array([np.cos(th), np.sin(th)])
    n = np.array([-np.sin(th), np.cos(th)])
    rock = dd.Material(density=2500.0, young=5e9, poisson=0.25)
    scene = dd.Scene(gravity=9.81)
    base = scene.add_block([-1.0 * n, 14 * t - 1.0 * n, 14 * t, np.zeros(2)], material=rock, fixed=True)
    slides = scene.add_block([5 * t, 6 * t, 6 * t + n, 5 * t + n], material=rock)
    stays = scene.add_block([10 * t, 11 * t, 11 * t + n, 10 * t + n], material=rock)
    scene.set_joint(dd.Joint(friction=phi_slide), between=(base, slides))
    scene.set_joint(dd.Joint(friction=phi_stay), between=(base, stays))
    return scene, dd.Params()


if __name__ == "__main__":
    from ddatai.cli import run_as_script

    run_as_script(build, DURATION, "sliding_block")
