"""How far each iterate of the equilibrium stage's return mapping (`ddatai.return_mapping`) moves:
the energy line search where contacts open or close, so that contacts flipping together cannot
flip back, and Anderson mixing of the slips (docs/method/dda.md §8.12)."""

from __future__ import annotations

from typing import Optional

import numpy as np

from .contacts import Contacts
from .layout import KIND, S_E0, S_E1, S_ES, S_G0, S_G1, S_GS, VV

#: the line search halves its interval this many times (`line_search`)
LINE_SEARCH_BISECTIONS = 30
#: Anderson acceleration of the slips keeps this many past iterates (`anderson`)
ANDERSON_DEPTH = 8


def _measures(vec: np.ndarray, sca: Optional[np.ndarray], contacts: Contacts, disp: np.ndarray):
    """(dn of line 0, dn of line 1 (−∞ for a vertex-edge contact), ds) at ``disp`` (with the
    constant parts ``sca``), or their rates along ``disp`` (``sca`` None): §2.8.1, linear in D."""
    da, db = disp[contacts.block_a], disp[contacts.block_b]
    vv = contacts.cint[:, KIND] == VV
    dn0 = np.einsum("ij,ij->i", vec[:, S_E0], da) + np.einsum("ij,ij->i", vec[:, S_G0], db)
    dn1 = np.einsum("ij,ij->i", vec[:, S_E1], db) + np.einsum("ij,ij->i", vec[:, S_G1], da)
    ds = np.einsum("ij,ij->i", vec[:, S_ES], da) + np.einsum("ij,ij->i", vec[:, S_GS], db)
    if sca is not None:
        dn0, dn1, ds = dn0 + sca[:, 0], dn1 + sca[:, 1], ds + sca[:, 2]
    return dn0, np.where(vv, dn1, -np.inf if sca is not None else 0.0), np.where(vv, 0.0, ds)


def line_search(stepper, frame, contacts: Contacts, sca: np.ndarray, disp: np.ndarray,
                step: np.ndarray, shearing: np.ndarray) -> float:
    """α ∈ (0, 1] (``frame``: the pseudo-step's `return_mapping.Frame`) that minimises along ``disp`` + α·``step`` the energy of the iterate: the
    blocks' ½DᵀKD − FᵀD, ½p·dn² of each contact closed there (the less penetrated line of a
    vertex-vertex one, up to the tensile allowance), ½k_s·(ds − slip)² of each closed
    vertex-edge one with friction or cohesion (``shearing``). The solution of the iterate's K
    minimises it as long as no contact opens or closes on the way; where some do, the energy's
    slope, piecewise linear in α, has its root before 1 (bisection), and the iterate stops
    there: contacts that all flip together cannot flip back and forth."""
    model = stepper.model
    curvature, slope0 = blocks_slope(stepper, frame, disp, step)
    dn0, dn1, ds = _measures(frame.vec, sca, contacts, disp)
    r0, r1, rs = _measures(frame.vec, None, contacts, step)
    allowance = np.where(contacts.bond, contacts.tensile * contacts.length / model.penalty, 0.0)

    def slope_vv(a: float) -> float:
        n0, n1 = dn0 + a * r0, dn1 + a * r1
        one = n1 > n0
        dn = np.where(one, n1, n0)
        closed = dn <= allowance
        normal = np.where(closed, model.penalty * dn, 0.0)
        shear = np.where(closed & shearing, model.shear_penalty * (ds + a * rs), 0.0)
        return curvature * a + slope0 + float(normal @ np.where(one, r1, r0)) + float(shear @ rs)

    def slope_ve(a: float) -> float:  # the same where every contact is vertex-edge (line 1 −∞, rate 0)
        dn = dn0 + a * r0
        closed = dn <= allowance
        normal = np.where(closed, model.penalty * dn, 0.0)
        shear = np.where(closed & shearing, model.shear_penalty * (ds + a * rs), 0.0)
        return curvature * a + slope0 + float(normal @ r0) + float(shear @ rs)

    slope = slope_vv if np.count_nonzero(contacts.cint[:, KIND] == VV) else slope_ve
    return root(slope)


def blocks_slope(stepper, frame, disp: np.ndarray, step: np.ndarray) -> tuple:
    """The blocks' part of the line search's slope, linear in α: its rate vᵀKv and its value
    at α = 0, vᵀ(K x − F) (K symmetric; x, v: ``disp`` and ``step`` of the free blocks)."""
    rows = stepper.free_idx
    x, v = disp[rows].ravel(), step[rows].ravel()
    kv = frame.k_blocks @ v
    return float(v @ kv), float(kv @ x) - float(frame.rhs @ v)


def root(slope) -> float:
    """The step α ∈ (0, 1] where the line search stops: 1 where the energy still falls there,
    else a root of ``slope`` by ``LINE_SEARCH_BISECTIONS`` bisections,
    never below their resolution."""
    if slope(1.0) <= 0.0:
        return 1.0
    lo, hi = 0.0, 1.0
    for _ in range(LINE_SEARCH_BISECTIONS):
        mid = 0.5 * (lo + hi)
        if slope(mid) < 0.0:
            lo = mid
        else:
            hi = mid
    return max(lo, 1.0 / 2 ** LINE_SEARCH_BISECTIONS)


def anderson(history: list, x: np.ndarray, g: np.ndarray) -> np.ndarray:
    """Anderson acceleration (depth ANDERSON_DEPTH) of the fixed point x = g(x) of the slips:
    the combination of the last iterates whose residuals g − x cancel best (least squares)."""
    history.append((g - x, g))  # each iterate's residual, made once
    if len(history) > ANDERSON_DEPTH + 1:
        history.pop(0)
    if len(history) < 2:
        return g
    f = np.array([fi for fi, _ in history])
    gs = np.array([gi for _, gi in history])
    df, dg = (f[1:] - f[:-1]).T, (gs[1:] - gs[:-1]).T
    gamma = np.linalg.lstsq(df, f[-1], rcond=None)[0]
    return g - dg @ gamma
