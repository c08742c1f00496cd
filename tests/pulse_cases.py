"""A rigid block under one full cycle of a horizontal sine pulse of ground acceleration: the
rocking equation of motion as the referee (Housner 1963; Makris & Roussos 2000, "Rocking
response of rigid blocks to near-fault ground motions", Géotechnique 50(3):243–262), and the
same block in ddatai (tests/test_pulse_overturning.py).

A b × h block (half-diagonal R, slenderness α = atan(b/h), p = √(3g/(4R))) on a rigid base
whose ground accelerates by a_g(t) = A·sin(2π f t) for 0 ≤ t ≤ 1/f (zero after) rocks, once
|a_g| > g·tan α lifts a corner, by

    θ̈ = −p² · (sin(α·sgn θ − θ) + (a_g/g)·cos(α·sgn θ − θ))

(θ > 0 on its right-hand corner; Makris & Roussos eq. 1), and at each impact (θ through 0)
keeps its angular momentum about the new corner: θ̇ × r, r = 1 − (3/2)·sin²α (Housner). It
overturns once |θ| passes α with the pulse over (no forcing is left to bring it back), or
reaches π/2 (the block on its side). Integrated by `scipy.integrate.solve_ivp` (an 8th-order Runge–Kutta
with events at the impacts, the lift-offs and the overturning; tolerances 1e-10).
"""

from __future__ import annotations

import math

import numpy as np

import ddatai as dd
from rocking_cases import DEFAULTS, G, scene

#: events: the state's tolerance of the integration [rad, rad/s]
RTOL, ATOL = 1e-10, 1e-12


def pulse(amplitude: float, frequency: float):
    """a_g(t) [m/s²] of one full sine cycle of ``amplitude`` [m/s²] and ``frequency`` [Hz]."""
    period = 1.0 / frequency

    def a_g(t: float) -> float:
        return amplitude * math.sin(2.0 * math.pi * frequency * t) if 0.0 <= t <= period else 0.0

    return a_g


def rocking_response(b: float, h: float, amplitude: float, frequency: float, duration: float = 3.0,
                     restitution: float | None = None) -> tuple[bool, float]:
    """(whether the block overturns, its largest |θ| [rad] while it does not) under the pulse,
    from the rocking equation of motion (module docstring); ``restitution``: r (Housner's by
    default)."""
    from scipy.integrate import solve_ivp

    alpha = math.atan(b / h)
    p2 = 3.0 * G / (4.0 * 0.5 * math.hypot(b, h))
    r = 1.0 - 1.5 * math.sin(alpha) ** 2 if restitution is None else restitution
    a_g = pulse(amplitude, frequency)
    t_pulse = 1.0 / frequency
    lift = G * math.tan(alpha)

    def rhs(side):
        def f(t, y):
            th, om = y
            return [om, -p2 * (math.sin(alpha * side - th) + a_g(t) / G * math.cos(alpha * side - th))]
        return f

    t, theta, omega, peak = 0.0, 0.0, 0.0, 0.0
    side = 0  # 0: at rest on its base; ±1: rocking on its right / left corner
    while t < duration:
        if side == 0:
            # at rest until the ground's acceleration lifts a corner: a_g < −g·tanα lifts the
            # right-hand one (the inertial force −m·a_g pushes the block right)
            ts = np.linspace(t, min(duration, max(t, t_pulse)), 20001)
            acc = np.where(ts <= t_pulse, amplitude * np.sin(2.0 * math.pi * frequency * ts), 0.0)
            up = np.flatnonzero(np.abs(acc) > lift)
            if not len(up):
                return False, peak
            t = float(ts[up[0]])
            side = -1 if acc[up[0]] > 0 else 1
            theta, omega = 0.0, 0.0
            # start a hair off the base so that the impact event does not fire at once
            theta = side * 1e-12
        if t >= t_pulse - 1e-12:
            # the pulse is over: the energy (÷ m·g·R) only falls from here (at the impacts), and
            # below the top of the potential, m·g·R at θ = α, the block cannot overturn
            # (past α, it cannot climb back over that top, and falls)
            energy = omega * omega / (2.0 * p2) + math.cos(alpha - side * theta)
            if energy < 1.0:
                if side * theta > alpha:
                    return True, peak
                return False, max(peak, alpha - math.acos(energy))
        crossing = lambda t, y: y[0]  # noqa: E731 - the impact: θ through 0
        crossing.terminal, crossing.direction = True, -side
        # overturned: past α once the pulse is over (nothing is left to bring it back), past
        # π/2 during it
        during = t < t_pulse - 1e-12
        fallen = lambda t, y: side * y[0] - 0.5 * math.pi  # noqa: E731
        fallen.terminal, fallen.direction = True, 1
        tipped = lambda t, y: side * y[0] - alpha  # noqa: E731
        tipped.terminal, tipped.direction = not during, 1
        span_end = t_pulse if during else duration
        sol = solve_ivp(rhs(side), (t, span_end), [theta, omega], method="DOP853",
                        events=(crossing, fallen, tipped), rtol=RTOL, atol=ATOL)
        theta, omega, t = float(sol.y[0, -1]), float(sol.y[1, -1]), float(sol.t[-1])
        if sol.t_events[1].size or (not during and sol.t_events[2].size):
            return True, peak
        peak = max(peak, float(np.max(np.abs(sol.y[0]))))
        if during and not sol.t_events[0].size:
            if side * theta > alpha and side * omega > 0:
                return True, peak
            continue  # the pulse is over: on, with the overturning test past α
        if sol.t_events[0].size:
            # impact on the other corner: the angular momentum about it kept (Housner)
            omega *= r
            theta = 0.0
            if abs(omega) < 1e-4 * math.sqrt(p2):
                side = 0
                continue
            side = -side
            theta = side * 1e-12
    return False, peak


def overturning_threshold(b: float, h: float, frequency: float, low: float, high: float,
                          restitution: float | None = None, tol: float = 1e-3) -> float:
    """The smallest amplitude [m/s²] in (``low``, ``high``) at which the referee overturns the
    block (bisection; the block must survive ``low`` and overturn at ``high``)."""
    assert not rocking_response(b, h, low, frequency, restitution=restitution)[0]
    assert rocking_response(b, h, high, frequency, restitution=restitution)[0]
    while high - low > tol * high:
        mid = 0.5 * (low + high)
        if rocking_response(b, h, mid, frequency, restitution=restitution)[0]:
            high = mid
        else:
            low = mid
    return high


def dda_response(b: float, h: float, amplitude: float, frequency: float, duration: float = 3.0,
                 params=None) -> tuple[bool, float]:
    """(whether the block overturns, its largest tilt [rad]) in ddatai with ``params`` (the
    defaults on today's step, `rocking_cases.DEFAULTS`): the block of `rocking_cases.scene` standing upright, the ground shaken by the
    pulse (`Scene.set_ground_acceleration`). The run stops once the verdict is known: the block
    past twice its overturning angle (falling), or the pulse over with the block's energy
    below the top of its potential (it cannot overturn any more; the tilt it can still reach
    is counted, as the referee counts it)."""
    sc = scene(b, h, 0.0)
    a_g = pulse(amplitude, frequency)
    sc.set_ground_acceleration(lambda t: (a_g(t), 0.0))
    params = DEFAULTS if params is None else params
    model = dd.build_model(sc, params)
    start = model.vertex_offset[1]
    alpha = math.atan(b / h)
    p2 = 3.0 * G / (4.0 * 0.5 * math.hypot(b, h))
    peak = [0.0]

    def watch(state, _record):
        d = state.vertex_xy[start + 1] - state.vertex_xy[start]
        tilt = abs(math.atan2(d[1], d[0]))
        peak[0] = max(peak[0], tilt)
        if tilt > 2.0 * alpha:
            raise _Verdict(True)
        if state.time >= 1.0 / frequency and tilt < alpha:
            energy = state.block_velocity[1, 2] ** 2 / (2.0 * p2) + math.cos(alpha - tilt)
            if energy < 1.0:
                peak[0] = max(peak[0], alpha - math.acos(energy))
                raise _Verdict(False)

    try:
        dd.simulate(sc, params, duration=duration, progress=watch, model=model, record_every=10 ** 9)
    except _Verdict as verdict:
        return verdict.overturned, peak[0]
    return False, peak[0]


class _Verdict(Exception):
    """The run's verdict is known (`dda_response`)."""

    def __init__(self, overturned: bool):
        super().__init__()
        self.overturned = overturned
