"""Newmark sliding block: a rigid block on a plane under ground acceleration (stick–slip).

Reference solution for the seismic case of ``benchmarks/accuracy.py``.

Set-up and derivation
---------------------
A rigid block rests on a plane that rises to the right at angle θ (down-slope is −t,
t = (cosθ, sinθ), outward normal n = (−sinθ, cosθ)); the joint has friction φ, μ = tanφ, no
cohesion. The ground accelerates with a_g(t) = (ax, ay) [m/s²]. In the ground's frame the block
feels gravity (0, −g) and the inertial body force −a_g, so per unit mass

    D(t) = ax cosθ + (g + ay) sinθ      (driving acceleration, down-slope)
    N(t) = (g + ay) cosθ − ax sinθ      (normal pressure / m; must stay > 0, else the block lifts)

A horizontal a_g > 0 (ground moving towards the rising side) drives the block down-slope and
unloads the plane. With s the down-slope displacement of the block relative to the ground:

    stick          s' = 0            while |D| ≤ μN
    slide down     s'' = D − μN      while s' > 0
    slide up       s'' = D + μN      while s' < 0

A stuck block starts sliding down when D − μN rises through 0 and up when D + μN falls through
0; a sliding block stops when s' returns to 0 and then sticks unless the forcing already exceeds
friction the other way (two-way sliding). For a horizontal a_g = ax only:

    slide down when ax > a_y  = g tan(φ − θ),   s'' = (cosθ + μ sinθ)(ax − a_y)
    slide up   when ax < −a_yu, a_yu = g tan(φ + θ),  s'' = (cosθ − μ sinθ)(ax + a_yu)

(θ = 0 gives Newmark's 1965 block on flat ground, a_y = μg both ways.) Rotation and toppling
are excluded: the reference is a sliding block.

The phases are integrated with `scipy.integrate.solve_ivp` (DOP853) and switched by event
detection; `sinusoid_stick_slip` integrates each phase in closed form for a horizontal
sinusoid (the check of the event-driven integrator, in the tests and in the benchmark output).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable, Sequence

import numpy as np

GroundAcceleration = Callable[[float], Sequence[float]]

STICK, DOWN, UP = 0, 1, -1


@dataclass(frozen=True)
class StickSlipSolution:
    """Down-slope displacement s(t) of the block relative to the ground."""

    times: np.ndarray
    """Sample times [s] (the requested ``t_eval``)."""
    displacement: np.ndarray
    """s at ``times`` [m], positive down-slope."""
    velocity: np.ndarray
    """s' at ``times`` [m/s]."""
    phases: list
    """(t_start, t_end, phase) with phase STICK, DOWN (sliding down-slope) or UP."""

    @property
    def final_displacement(self) -> float:
        return float(self.displacement[-1])


def _plane_accelerations(theta: float, g: float, ground_acceleration: GroundAcceleration):
    """D(t), N(t) per unit mass for the plane angle θ [rad] (see the module docstring)."""
    c, s = math.cos(theta), math.sin(theta)

    def driving(t: float) -> float:
        ax, ay = ground_acceleration(t)
        return ax * c + (g + ay) * s

    def normal(t: float) -> float:
        ax, ay = ground_acceleration(t)
        return (g + ay) * c - ax * s

    return driving, normal


def stick_slip(theta_deg: float, phi_deg: float, ground_acceleration: GroundAcceleration,
               t_end: float, *, gravity: float = 9.81, t_eval: Sequence[float] | None = None,
               breaks: Sequence[float] = (), rtol: float = 1e-11, atol: float = 1e-13,
               max_step: float = 0.01) -> StickSlipSolution:
    """Integrate the stick–slip equation of a rigid block on an incline from rest at t = 0.

    ``ground_acceleration(t) -> (ax, ay)`` [m/s²]; ``breaks``: times where it is discontinuous
    (each phase is integrated piecewise between them, so no step straddles a jump);
    ``max_step`` [s] bounds the solver step so that no stick/slip switch inside a step is
    missed (keep it below a quarter period of the forcing). Raises ``ValueError`` if the
    block would lift off the plane (N ≤ 0).
    """
    from scipy.integrate import solve_ivp

    mu = math.tan(math.radians(phi_deg))
    piece = [0.0, float(t_end)]  # the piece between breaks being integrated
    nudge = 1e-12 * max(1.0, float(t_end))

    def inside_piece(t: float) -> tuple[float, float]:
        # solvers evaluate at both ends of a piece; sample a jump at a break from inside the
        # piece, so each piece sees only its own side of the jump
        return ground_acceleration(min(max(t, piece[0] + nudge), piece[1] - nudge))

    driving, normal = _plane_accelerations(math.radians(theta_deg), gravity, inside_piece)
    t_eval = np.array([t_end] if t_eval is None else t_eval, dtype=float)
    if np.any(t_eval < 0) or np.any(t_eval > t_end) or np.any(np.diff(t_eval) < 0):
        raise ValueError("stick_slip: t_eval must be increasing and within [0, t_end]")
    edges = sorted({0.0, float(t_end), *(float(b) for b in breaks if 0.0 < b < t_end)})

    def check_contact(t: float) -> None:
        if normal(t) <= 0.0:
            raise ValueError(f"stick_slip: the block lifts off the plane at t = {t:.6g} s (N ≤ 0)")

    def phase_at(t: float, v: float) -> int:
        if v > 0:
            return DOWN
        if v < 0:
            return UP
        d, n = driving(t), mu * normal(t)
        if d - n > 0:
            return DOWN
        if d + n < 0:
            return UP
        return STICK

    def rhs(phase: int):
        def f(t, y):
            return [y[1], driving(t) - phase * mu * normal(t)]
        return f

    # stick: leave when the forcing exceeds friction one way or the other
    def starts_down(t, y):
        return driving(t) - mu * normal(t)
    starts_down.terminal, starts_down.direction = True, 1.0

    def starts_up(t, y):
        return driving(t) + mu * normal(t)
    starts_up.terminal, starts_up.direction = True, -1.0

    # slide: stop when the relative velocity returns to zero (s' falls through 0 going down)
    def stops_down(t, y):
        return y[1]
    stops_down.terminal, stops_down.direction = True, -1.0

    def stops_up(t, y):
        return y[1]
    stops_up.terminal, stops_up.direction = True, 1.0

    out_s = np.zeros(len(t_eval))
    out_v = np.zeros(len(t_eval))
    phases: list = []
    t, s, v = 0.0, 0.0, 0.0
    forced = None  # the phase an event has just decided (its forcing is 0 at the event time)
    check_contact(0.0)
    while t < t_end:
        seg_end = next(e for e in edges if e > t)
        piece[:] = [max(e for e in edges if e <= t), seg_end]
        phase = forced if forced is not None else phase_at(t, v)
        forced = None
        events = {STICK: [starts_down, starts_up], DOWN: [stops_down], UP: [stops_up]}[phase]
        sol = solve_ivp(rhs(phase) if phase != STICK else (lambda t, y: [0.0, 0.0]),
                        (t, seg_end), [s, v], method="DOP853", rtol=rtol, atol=atol,
                        max_step=max_step, events=events, dense_output=True)
        if sol.status < 0:
            raise RuntimeError(f"stick_slip: solve_ivp failed at t = {t:.6g} s: {sol.message}")
        t_stop = float(sol.t[-1])
        inside = (t_eval >= t) & (t_eval <= t_stop)
        if np.any(inside):
            y = sol.sol(t_eval[inside])
            out_s[inside] = y[0] if phase != STICK else s
            out_v[inside] = y[1] if phase != STICK else 0.0
        phases.append((t, t_stop, phase))
        s = float(sol.y[0, -1]) if phase != STICK else s
        v = float(sol.y[1, -1]) if phase != STICK else 0.0
        if sol.status == 1:  # an event ended the phase
            if phase == STICK:
                forced = DOWN if len(sol.t_events[0]) else UP
            else:
                # stopped: phase_at then decides from the forcing whether it sticks or, beyond
                # friction the other way, slides back at once (two-way sliding)
                v = 0.0
        check_contact(t_stop)
        t = t_stop
    return StickSlipSolution(times=t_eval, displacement=out_s, velocity=out_v, phases=phases)


def sinusoid_stick_slip(theta_deg: float, phi_deg: float, amplitude: float, frequency: float,
                        t_end: float, *, gravity: float = 9.81) -> float:
    """s(t_end) for a horizontal a_g = A sin(2πft), each phase integrated in closed form.

    Down-slope sliding: s'' = c (A sin ωt − a_y), c = cosθ + μ sinθ, so from (t0, s0, v0)
        v(t) = v0 + c[(A/ω)(cos ωt0 − cos ωt) − a_y τ]
        s(t) = s0 + v0 τ + c[(A/ω) cos ωt0 τ − (A/ω²)(sin ωt − sin ωt0) − a_y τ²/2],  τ = t − t0
    and the same for up-slope sliding with c' = cosθ − μ sinθ and −a_yu in place of a_y.
    Start times are roots of A sin ωt = a_y (or −a_yu); stop times (v = 0) by bracketing on a
    fine grid and `brentq`. Independent of `stick_slip` (no ODE solver).
    """
    from scipy.optimize import brentq

    th, mu = math.radians(theta_deg), math.tan(math.radians(phi_deg))
    w = 2 * math.pi * frequency
    # thresholds in terms of ax: slide down when ax > a_down, up when ax < a_up
    a_down = gravity * (mu * math.cos(th) - math.sin(th)) / (math.cos(th) + mu * math.sin(th))
    a_up = -gravity * (math.sin(th) + mu * math.cos(th)) / (math.cos(th) - mu * math.sin(th))
    gain = {DOWN: math.cos(th) + mu * math.sin(th), UP: math.cos(th) - mu * math.sin(th)}
    level = {DOWN: a_down, UP: a_up}

    def velocity(phase, t0, v0, t):
        return v0 + gain[phase] * ((amplitude / w) * (math.cos(w * t0) - math.cos(w * t)) - level[phase] * (t - t0))

    def position(phase, t0, s0, v0, t):
        tau = t - t0
        return s0 + v0 * tau + gain[phase] * ((amplitude / w) * math.cos(w * t0) * tau
                                              - (amplitude / w ** 2) * (math.sin(w * t) - math.sin(w * t0))
                                              - 0.5 * level[phase] * tau * tau)

    def next_start(t0):
        """Earliest t ≥ t0 where the stuck block starts to slide, and which way."""
        best = (math.inf, STICK)
        for phase, a in ((DOWN, a_down), (UP, a_up)):
            if abs(a) >= amplitude:
                continue
            base = math.asin(a / amplitude)
            # A sin ωt crosses a upwards (down-slope start) at ωt = base + 2πk,
            # downwards (up-slope start) at ωt = π − base + 2πk
            phase0 = base if phase == DOWN else math.pi - base
            k = math.ceil((w * t0 - phase0) / (2 * math.pi) - 1e-12)
            best = min(best, ((phase0 + 2 * math.pi * k) / w, phase))
        return best

    t, s = 0.0, 0.0
    period = 1.0 / frequency
    while t < t_end:
        ax = amplitude * math.sin(w * t)
        if t > 0 and (ax > a_down or ax < a_up):
            # stopped while the forcing already exceeds friction the other way: two-way
            # sliding reverses at once
            t_start, phase = t, (DOWN if ax > a_down else UP)
        else:
            t_start, phase = next_start(t)
        if t_start >= t_end:
            break
        # stop: first sign change of v after the start, bracketed on a grid of period/2000
        grid = t_start + np.arange(1, 4001) * (period / 2000)
        v = np.array([velocity(phase, t_start, 0.0, x) for x in grid])
        turn = np.flatnonzero(np.sign(v) != phase)
        t_stop = brentq(lambda x: velocity(phase, t_start, 0.0, x),
                        grid[turn[0] - 1] if turn[0] else t_start + 1e-12, grid[turn[0]], xtol=1e-15, rtol=1e-15)
        if t_stop >= t_end:
            return position(phase, t_start, s, 0.0, t_end)
        s = position(phase, t_start, s, 0.0, t_stop)
        t = t_stop
    return s
