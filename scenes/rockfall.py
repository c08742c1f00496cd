"""
Rockfall
========

Rockfall: a block bounces and rolls down a jointed slope.

The slope (a 40° cliff over a 25° scree slope) is a fixed rock mass cut by two joint sets, so
its surface is the stepped trace of the joints; a 1.2 m twelve-sided boulder is launched over the
crest. Impacts lose energy through the integrator's damping of stiff contact modes
(``Params.newmark_beta``). Run ``python scenes/rockfall.py [--gif out/rockfall.gif]``.
"""

import numpy as np

import ddatai as dd

DURATION = 4.0  # s


def build(seed: int = 3, friction: float = 35.0):
    """Returns (scene, params)."""
    rock = dd.Material(density=2650.0, young=20e9, poisson=0.25)
    scene = dd.Scene(gravity=9.81)
    # profile: toe at x = 40, scree up to (24, 7.5), cliff up to (12, 17.5), crest plateau
    outline = [(-2.0, -4.0), (44.0, -4.0), (44.0, 0.0), (40.0, 0.0), (24.0, 7.46), (12.0, 17.5),
               (-2.0, 17.5)]
    sets = [dd.JointSet(dip=20.0, spacing=2.5, spacing_spread=0.4, dip_spread=3.0,
                        joint=dd.Joint(friction=friction)),
            dd.JointSet(dip=115.0, spacing=3.0, trace_length=6.0, gap=1.5, spacing_spread=0.5,
                        joint=dd.Joint(friction=friction))]
    traces = dd.joint_sets(outline, sets, seed=seed)
    ids = scene.cut(outline, traces, material=rock, fixed=True, slivers="merge")
    angles = np.radians(15.0 + 30.0 * np.arange(12))
    radius = 0.6
    boulder = radius * np.stack([np.cos(angles), np.sin(angles)], axis=1) + (11.0, 17.5 + radius + 0.01)
    scene.add_block(boulder, material=rock, velocity=(3.0, 0.0), angular_velocity=-5.0)
    scene.set_joint(dd.Joint(friction=friction))
    assert ids  # the mass was cut into blocks
    return scene, dd.Params()


if __name__ == "__main__":
    from ddatai.cli import run_as_script

    run_as_script(build, DURATION, "rockfall")
