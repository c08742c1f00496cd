"""
Masonry wall under shaking
==========================

A dry-stone wall toppling out of plane under sinusoidal ground shaking.

The cross-section of a free-standing dry-stone wall, 0.6 m thick and 2.8 m high: 14 courses
of 0.2 m, alternately two 0.3 m stones and three 0.2 m stones (joints staggered), on a fixed
foundation, joints φ = 35° without cohesion. The ground shakes horizontally with
a_g(t) = A sin(2π f t), A = 0.35 g, f = 1.5 Hz: more than the rocking threshold g·b/h = 0.21 g
of the wall as a whole, so it rocks, the courses open and the wall collapses. Results are
relative to the foundation (the ground's frame).
Run ``python scenes/masonry_wall.py [--gif out/masonry_wall.gif]``.
"""

import numpy as np

import ddatai as dd

DURATION = 3.0  # s


def build(courses: int = 14, amplitude_g: float = 0.35, frequency: float = 1.5):
    """Returns (scene, params)."""
    stone = dd.Material(density=2200.0, young=5e9, poisson=0.2)
    scene = dd.Scene(gravity=9.81)
    h, width = 0.2, 0.6
    scene.add_block([(-1.5, -0.3), (width + 1.5, -0.3), (width + 1.5, 0.0), (-1.5, 0.0)],
                    material=stone, fixed=True)
    for c in range(courses):
        y = c * h
        edges = [0.0, 0.3, 0.6] if c % 2 == 0 else [0.0, 0.2, 0.4, 0.6]
        for x0, x1 in zip(edges[:-1], edges[1:]):
            scene.add_block([(x0, y), (x1, y), (x1, y + h), (x0, y + h)], material=stone)
    scene.set_joint(dd.Joint(friction=35.0))
    a = amplitude_g * 9.81
    scene.set_ground_acceleration(lambda t: (a * np.sin(2 * np.pi * frequency * t), 0.0))
    # resolve the shaking: at least 50 steps per period
    return scene, dd.Params(dt_max=1.0 / (50 * frequency))


if __name__ == "__main__":
    from ddatai.cli import run_as_script

    run_as_script(build, DURATION, "masonry_wall")
