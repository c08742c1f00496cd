"""A rigid block rocking on a fixed base, against Housner (1963) (tests/test_rocking.py,
benchmarks/accuracy.py's rocking curve).

A b × h block stands on one corner, leaning by θ0 (a fraction of its overturning angle
α = atan(b/h)), and is let go from rest; friction 80° keeps it from sliding. Housner's block
rocks about a corner without losing energy, and at each impact on the other corner keeps its
angular momentum about that corner: the angular velocity is multiplied by
r = 1 − (3/2)·sin²α (a rectangle). So the peaks θk follow, with R the half diagonal,

    cos(α − θk+1) − cos α = r² · (cos(α − θk) − cos α)

(the energy m·g·R·(cos(α − θ) − cos α) of the rocking at the peaks, × r² per impact).
"""

from __future__ import annotations

import math

import numpy as np

import ddatai as dd

G = 9.81
ROCK = dd.Material(density=2600.0, young=10e9, poisson=0.25)
#: friction of the base: no sliding (Housner's block rocks, never slides)
FRICTION = 80.0
#: the default `Params` on today's step (`ddatai.step`): the fused engine (`ddatai.fused`) has
#: neither the resolved impacts nor the lever arms at mid-step yet, and "auto" takes it for a
#: small model in a process that has loaded its kernel
DEFAULTS = dd.Params(kernels="numpy")


def scene(b: float, h: float, fraction: float, material: dd.Material = ROCK) -> dd.Scene:
    """The b × h block on its right-hand corner, leaning left by ``fraction`` of atan(b/h)."""
    theta = fraction * math.atan(b / h)
    c, s = math.cos(theta), math.sin(theta)
    block = [(b + c * (x - b) + s * y, -s * (x - b) + c * y) for x, y in [(0, 0), (b, 0), (b, h), (0, h)]]
    sc = dd.Scene(gravity=G)
    sc.add_block([(-2 * h, -0.5), (b + 2 * h, -0.5), (b + 2 * h, 0.0), (-2 * h, 0.0)], material=material,
                 fixed=True)
    sc.add_block(block, material=material)
    sc.set_joint(dd.Joint(friction=FRICTION))
    return sc


def housner_peaks(b: float, h: float, fraction: float, n: int) -> np.ndarray:
    """Housner's first ``n`` peak tilts after the release [rad]."""
    alpha = math.atan(b / h)
    r = 1.0 - 1.5 * math.sin(alpha) ** 2
    theta, out = fraction * alpha, []
    for _ in range(n):
        theta = alpha - math.acos(math.cos(alpha) + r * r * (math.cos(alpha - theta) - math.cos(alpha)))
        out.append(theta)
    return np.array(out)


def housner_duration(b: float, h: float, fraction: float, n: int) -> float:
    """Time to the ``n``-th peak after the release [s]: each half cycle from a peak θ to the
    impact takes (1/p)·artanh(√(1 − (1 − θ/α)²))-ish of Housner's linearised rocking,
    p = √(3g/(4R)); twice that from an impact to the next peak."""
    alpha = math.atan(b / h)
    p = math.sqrt(3.0 * G / (4.0 * 0.5 * math.hypot(b, h)))
    peaks = [fraction * alpha] + list(housner_peaks(b, h, fraction, n))
    quarter = [math.acosh(1.0 / (1.0 - t / alpha)) / p for t in peaks]
    return quarter[0] + 2.0 * sum(quarter[1:n]) + quarter[n]


def tilt_peaks(b: float, h: float, fraction: float, n: int, params=None) -> tuple[np.ndarray, object]:
    """The first ``n`` peak tilts [rad] after the release in a ddatai run (the tilt of the
    block's base edge, recorded at every step), and the run's `Results`."""
    sc = scene(b, h, fraction)
    params = DEFAULTS if params is None else params
    model = dd.build_model(sc, params)
    start = model.vertex_offset[1]
    tilt = []

    def watch(state, _record):
        d = state.vertex_xy[start + 1] - state.vertex_xy[start]
        tilt.append(math.atan2(d[1], d[0]))

    res = dd.simulate(sc, params, duration=1.05 * housner_duration(b, h, fraction, n), progress=watch, record_every=10 ** 9,
                      model=model)
    tilt = np.array(tilt)
    sign = np.sign(tilt)
    # a half cycle between sign changes of the tilt; its peak is its largest |tilt|
    cuts = np.nonzero(sign[1:] * sign[:-1] < 0)[0] + 1
    halves = np.split(np.abs(tilt), cuts)
    return np.array([x.max() for x in halves[1:n + 1]]), res


def free_swing(params, b: float = 0.5, h: float = 2.0, fraction: float = 0.5) -> tuple[int, float]:
    """The swing from the release to the first impact: (its steps, its energy gain over it as a
    fraction of the rocking energy m·g·R·(cos(α − θ0) − cos α)). The impact is the first step
    whose energy falls by more than 5 % of the rocking energy (r²'s share)."""
    _, res = tilt_peaks(b, h, fraction, 1, params=params)
    s = res.steps
    alpha = math.atan(b / h)
    rocking = ROCK.density * b * h * G * 0.5 * math.hypot(b, h) * (math.cos(alpha - fraction * alpha) - math.cos(alpha))
    energy = s["kinetic"] + s["gravitational"] + s["strain"] + s["contact"]
    drop = int(np.flatnonzero(np.diff(energy) < -0.05 * rocking)[0])
    return drop, float((energy[drop] - energy[0]) / rocking)
