"""
Toppling and sliding columns
============================

Toppling and sliding on one incline: a row of slender columns topples, squat blocks slide.

A 30° plane with joints of φ = 25°. Slender 0.3 × 1.5 m columns (b/h = 0.2 < tan 30°, and
tan 25° = 0.47 above the toppling limit 0.29 of docs/method/dda.md §7d) rotate about their down-slope
corners and fall onto each other; the squat 1.2 × 0.8 m blocks lower down (b/h ≥ tan θ,
tan φ < tan θ) slide. Run ``python scenes/toppling.py [--gif out/toppling.gif]``.
"""

import numpy as np

import ddatai as dd

DURATION = 1.5  # s


def build(theta: float = 30.0, phi: float = 25.0, columns: int = 5, squat: int = 2):
    """Returns (scene, params)."""
    th = np.radians(theta)
    t = np.array([np.cos(th), np.sin(th)])
    n = np.array([-np.sin(th), np.cos(th)])
    rock = dd.Material(density=2600.0, young=10e9, poisson=0.25)
    scene = dd.Scene(gravity=9.81)
    length = 16.0
    scene.add_block([-1.5 * n, length * t - 1.5 * n, length * t, np.zeros(2)], material=rock, fixed=True)

    def box(at, width, height):
        p = at * t
        return [p, p + width * t, p + width * t + height * n, p + height * n]

    for k in range(squat):
        scene.add_block(box(1.0 + 2.0 * k, 1.2, 0.8), material=rock)
    for k in range(columns):
        scene.add_block(box(8.0 + 0.6 * k, 0.3, 1.5), material=rock)
    scene.set_joint(dd.Joint(friction=phi))
    return scene, dd.Params()


if __name__ == "__main__":
    from ddatai.cli import run_as_script

    run_as_script(build, DURATION, "toppling")
