"""What a large model's return-mapping iterate (``ddatai.return_mapping``, ``_iterate``) need not
evaluate contact by contact (docs/method/dda.md §8.12): the line search's slope summed once for
the contacts that provably keep their state along the whole step, and the blocks' displacements
bounded before they are measured vertex by vertex.

- ``LineSearch`` is ``return_steps.line_search``'s bisection of the energy's slope, piecewise
  linear in α ∈ [0, 1]. A contact contributes p·dn(α)·∂dn/∂α + k_s·ds(α)·∂ds/∂α while it is
  closed, on the line that is less penetrated; dn(α) = dn + α·r is evaluated in floats as a
  monotone function of α (a rounded product, then a rounded sum), so a contact closed (or
  open) at both α = 0 and α = 1 is closed (open) at every α the bisection tries, and a
  vertex-vertex contact whose two lines keep their order at both ends by more than their
  round-off keeps it in between (the difference is linear in α). Those contacts' terms are
  linear in α: their sums a + b·α are formed once, and only the others (those that open,
  close or change line on the way, tens among thousands) are evaluated at each of the 30
  bisections. The slope is the same up to the order of its sums (round-off): α can differ
  from the full evaluation's only where the slope is within round-off of zero, by the
  bisection's own resolution (2⁻³⁰ of the step) where it does. The distances at D and their
  rates along the step come from one sparse product of the frame's contact vectors with both.
- ``FarBlocks``: a vertex at distance ρ from its centroid moves by at most
  ‖(u₀, v₀)‖ + ρ·(abs(r₀) + ‖ε‖) (the finite rotation moves it by 2ρ·abs(sin(r₀/2)) ≤ ρ·abs(r₀), the
  strain ε = [[εx, γ/2], [γ/2, εy]] by at most ρ·‖ε‖_F): where that bound, with a margin for
  the round-off of the vertices' coordinates, stays below the distance at which a block is
  far (``MECHANISM_SIZE``·size) for every block, none is, exactly as measured vertex by vertex
  (``kinematics.block_displacement``), which is done otherwise.

Both apply from ``lowrank.LOWRANK_UNKNOWNS`` unknowns (1,000 free blocks): a smaller model, or a
member of a batch run side by side, takes the reference path bit for bit.
"""

from __future__ import annotations

import numpy as np

from .contacts import Contacts
from .kinematics import block_displacement, block_radius
from scipy.sparse import csr_matrix

from .layout import KIND, S_E0, S_E1, S_ES, S_G0, S_G1, S_GS, VV
from .return_steps import blocks_slope, root

#: relative round-off of a contact's two normal distances below which a vertex-vertex contact's
#: line order is evaluated at every bisection (each distance is dn + α·r, a few roundings)
ORDER_ROUNDOFF = 1e-13
#: relative margin of the displacement bound (its own roundings), and the vertices' coordinates'
#: round-off it adds (the measured displacement is moved − original coordinates)
BOUND_MARGIN = 1e-9

_SIX = np.arange(6)


class LineSearch:
    """``return_steps.line_search`` (its arguments, its energy and bisection) for the contacts of one
    frame, with the terms of the contacts that keep their state along the step summed once (module
    docstring). The distances' rows (dn of line 0, dn of line 1, ds: §2.8.1, linear in D) are one
    sparse matrix of the frame's contact vectors, applied to D and to the step in one product."""

    def __init__(self, model, frame, contacts: Contacts):
        n, v = contacts.n, frame.vec
        a = 6 * contacts.block_a[:, None] + _SIX
        b = 6 * contacts.block_b[:, None] + _SIX
        columns = np.empty((n, 3, 12), np.int64)
        values = np.empty((n, 3, 12))
        for row, (first, second, near, far) in enumerate(((S_E0, S_G0, a, b), (S_G1, S_E1, a, b),
                                                          (S_ES, S_GS, a, b))):
            columns[:, row, :6], columns[:, row, 6:] = near, far
            values[:, row, :6], values[:, row, 6:] = v[:, first], v[:, second]
        self.rows = csr_matrix((values.ravel(), columns.ravel(), np.arange(0, 36 * n + 1, 12)),
                               shape=(3 * n, 6 * model.n_blocks))

    def __call__(self, stepper, frame, contacts: Contacts, sca: np.ndarray, disp: np.ndarray,
                 step: np.ndarray, shearing: np.ndarray) -> float:
        model = stepper.model
        curvature, slope0 = blocks_slope(stepper, frame, disp, step)
        vv = contacts.cint[:, KIND] == VV
        measured = (self.rows @ np.column_stack([disp.ravel(), step.ravel()])).reshape(-1, 3, 2)
        dn0, r0 = measured[:, 0, 0] + sca[:, 0], measured[:, 0, 1]
        dn1, r1 = np.where(vv, measured[:, 1, 0] + sca[:, 1], -np.inf), np.where(vv, measured[:, 1, 1], 0.0)
        ds, rs = np.where(vv, 0.0, measured[:, 2, 0] + sca[:, 2]), np.where(vv, 0.0, measured[:, 2, 1])
        return _bisect(model, contacts, vv, shearing, curvature, slope0, dn0, dn1, ds, r0, r1, rs)


def _bisect(model, contacts: Contacts, vv: np.ndarray, shearing: np.ndarray, curvature: float, slope0: float,
            dn0, dn1, ds, r0, r1, rs) -> float:
    """The bisection of ``LineSearch`` from the distances at D (``dn0``, ``dn1``, ``ds``) and their
    rates along the step (``r0``, ``r1``, ``rs``)."""
    allowance = np.where(contacts.bond, contacts.tensile * contacts.length / model.penalty, 0.0)
    pen, ks = model.penalty, model.shear_penalty
    # at α = 0 and α = 1 (the same floats as the bisection's: 1.0·r = r)
    a0, a1, b0, b1 = dn0, dn0 + r0, dn1, dn1 + r1
    one0, one1 = b0 > a0, b1 > a1
    scale = np.where(vv, np.abs(dn0) + np.abs(r0) + np.abs(np.where(vv, dn1, 0.0)) + np.abs(r1), 0.0)
    ordered = ~vv | ((one0 == one1) & (np.abs(np.where(vv, b0 - a0, 1.0)) > ORDER_ROUNDOFF * scale) &
                     (np.abs(np.where(vv, b1 - a1, 1.0)) > ORDER_ROUNDOFF * scale))
    closed0 = np.where(one0, b0, a0) <= allowance
    closed1 = np.where(one1, b1, a1) <= allowance
    fixed = ordered & (closed0 == closed1)
    # the fixed contacts' terms, linear in α: p·(d + α·r)·r on the active line while closed,
    # k_s·(ds + α·rs)·rs with a shear spring
    closed = fixed & closed0
    d = np.where(one0, dn1, dn0)[closed]
    r = np.where(one0, r1, r0)[closed]
    sheared = (fixed & closed0 & shearing)
    c0 = float(pen * d @ r) + float(ks * ds[sheared] @ rs[sheared])
    c1 = float(pen * r @ r) + float(ks * rs[sheared] @ rs[sheared])
    live = np.flatnonzero(~fixed)
    dn0, dn1, ds, r0, r1, rs = dn0[live], dn1[live], ds[live], r0[live], r1[live], rs[live]
    allowance, shearing = allowance[live], shearing[live]
    linear0, linear1 = slope0 + c0, curvature + c1

    def slope(a: float) -> float:
        n0, n1 = dn0 + a * r0, dn1 + a * r1
        one = n1 > n0
        dn = np.where(one, n1, n0)
        closed = dn <= allowance
        normal = np.where(closed, pen * dn, 0.0)
        shear = np.where(closed & shearing, ks * (ds + a * rs), 0.0)
        return linear1 * a + linear0 + float(normal @ np.where(one, r1, r0)) + float(shear @ rs)

    return root(slope)


def displacement_bound(disp: np.ndarray, radius: np.ndarray) -> np.ndarray:
    """(B,) a bound of how far D ``disp`` (B, 6) moves any vertex of each block within ``radius``
    [m] of its centroid [m] (module docstring; the exact rotation of ``kinematics.move_points``)."""
    strain = np.sqrt(disp[:, 3] ** 2 + disp[:, 4] ** 2 + 0.5 * disp[:, 5] ** 2)
    return np.hypot(disp[:, 0], disp[:, 1]) + radius * (np.abs(disp[:, 2]) + strain)


class FarBlocks:
    """The blocks that an iterate's D moves farther than ``far_at`` [m] (B,) (module docstring):
    none where the bound proves it, else measured vertex by vertex."""

    def __init__(self, model, vertex_xy: np.ndarray, geom: dict):
        self.model, self.vertex_xy, self.geom = model, vertex_xy, geom
        self.radius = block_radius(model, vertex_xy, geom["centroid"])
        # the round-off of a measured displacement: a few ulps of the largest coordinate
        self.roundoff = 8.0 * np.finfo(float).eps * float(np.abs(vertex_xy).max(initial=0.0))
        self.measured = 0  # iterates whose bound did not prove it

    def __call__(self, disp: np.ndarray, movable: np.ndarray, far_at: np.ndarray) -> np.ndarray:
        bound = displacement_bound(disp[movable], self.radius[movable])
        if (bound * (1.0 + BOUND_MARGIN) + self.roundoff < far_at[movable]).all():
            return np.zeros(len(movable), bool)
        self.measured += 1
        return movable & (block_displacement(self.model, self.vertex_xy, self.geom, disp) > far_at)
