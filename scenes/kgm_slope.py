"""
Jointed slope for the Key Group Method
======================================

A jointed rock slope for the Key Group Method: many blocks, key groups of several blocks,
progressive failure, and the time a DDA judgement saves by simulating only the group.

A 30 m high slope with a 65° face is cut by two persistent joint sets: J1 dipping 35° out of
the slope (spacing 7 m) and J2 dipping 80° into it (spacing 9 m); all joints φ = 30°,
c = 20 kPa. Blocks touching the model's back, bottom or far-toe boundary are fixed (they
continue beyond the model: block type V). Run ``kgm analyze scenes/kgm_slope.py
--progressive`` or ``python scenes/kgm_slope.py`` (plain DDA run of the whole slope).
"""

import numpy as np

import ddatai as dd

DURATION = 1.0  # s
HEIGHT, FACE = 30.0, 65.0                 # m, degrees
LEFT, BOTTOM, RIGHT = -60.0, -15.0, 25.0  # model boundary [m]


def build(friction: float = 30.0, cohesion: float = 20e3, spacing1: float = 7.0, spacing2: float = 9.0):
    """Returns (scene, params). ``friction`` [degrees], ``cohesion`` [Pa], joint spacings [m]."""
    crest = (-HEIGHT / np.tan(np.radians(FACE)), HEIGHT)
    domain = [(LEFT, BOTTOM), (RIGHT, BOTTOM), (RIGHT, 0.0), (0.0, 0.0), crest, (LEFT, HEIGHT)]
    rock = dd.Material(density=2600.0, young=5e9, poisson=0.25)
    joint = dd.Joint(friction=friction, cohesion=cohesion)
    traces = []
    for dip, spacing, shift, ks in ((35.0, spacing1, 0.0, range(-10, 12)), (180.0 - 80.0, spacing2, -3.0, range(-12, 4))):
        d = np.array([np.cos(np.radians(dip)), -np.sin(np.radians(dip))])
        n = np.array([-d[1], d[0]])
        for k in ks:
            p = np.array([shift, 0.0]) + k * spacing * n
            traces.append(([p - 150 * d, p + 150 * d], joint))
    scene = dd.Scene(gravity=9.81)
    for b in scene.cut(domain, traces, material=rock, slivers="merge"):
        v = scene.blocks[b].vertices
        if v[:, 1].min() < BOTTOM + 1e-6 or v[:, 0].min() < LEFT + 1e-6 or v[:, 0].max() > RIGHT - 1e-6:
            scene.set_fixed(b)
    return scene, dd.Params(dt=0.002, penalty_ratio=10.0)


if __name__ == "__main__":
    from ddatai.cli import run_as_script

    run_as_script(build, DURATION, "kgm_slope")
