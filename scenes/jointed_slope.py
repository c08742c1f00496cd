"""
Jointed slope
=============

A jointed rock slope under gravity: which blocks move.

A 30 m high, 60° slope cut by two joint sets: bedding dipping 35° out of the face (φ = 22°,
below its dip, so blocks daylighting in the face can slide) and a steep cross set with short
rock bridges. Blocks below the toe level and far behind the face are fixed; the speed colours show
the blocks that slide out. Run ``python scenes/jointed_slope.py [--gif out/jointed_slope.gif]``.
"""

import numpy as np

import ddatai as dd

DURATION = 2.0  # s


def build(seed: int = 7, bedding_spacing: float = 3.0, cross_spacing: float = 4.0):
    """Returns (scene, params)."""
    rock = dd.Material(density=2600.0, young=10e9, poisson=0.25)
    scene = dd.Scene(gravity=9.81)
    toe, crest = (10.0, 0.0), (10.0 + 30.0 / np.tan(np.radians(60.0)), 30.0)
    outline = [(0.0, -6.0), (60.0, -6.0), (60.0, 30.0), crest, toe, (0.0, 0.0)]
    # the face looks to −x: traces rising to +x at 35° dip out of the face
    sets = [dd.JointSet(dip=35.0, spacing=bedding_spacing, spacing_spread=0.5, dip_spread=2.0,
                        joint=dd.Joint(friction=22.0)),
            dd.JointSet(dip=105.0, spacing=cross_spacing, trace_length=14.0, gap=1.0, spacing_spread=0.8,
                        dip_spread=4.0, joint=dd.Joint(friction=35.0))]
    ids = scene.cut(outline, dd.joint_sets(outline, sets, seed=seed), material=rock, slivers="merge")
    for b in ids:
        c = scene.polygon(b).mean(axis=0)
        if c[1] < 0.0 or c[0] > 50.0:
            scene.set_fixed(b)
    scene.set_joint(dd.Joint(friction=35.0))
    return scene, dd.Params()


if __name__ == "__main__":
    from ddatai.cli import run_as_script

    run_as_script(build, DURATION, "jointed_slope")
