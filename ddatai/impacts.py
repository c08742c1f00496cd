"""Impacts (docs/method/dda.md §4.6, §5.2): the step that ends just before a contact closes, the
impact step that follows it, and the plastic impact that leaves the impacted blocks without a
rebound at the contact.

DDA's integrator (Newmark, γ = 1, §5.1) turns the closing of a stiff contact spring within one
step into a rebound: where the step is long beside the spring's period, its implicit solve
stops the approach at the contact, and the update v_n+1 = v + Δt·a_n+1 sends the contact apart
at (1/β − 1) × the approach speed (0.78 of it at β = 9/16, all of it at Shi's β = ½); where the
step resolves the spring's period, the spring gives the approach back, less the integrator's
damping. A rocking block (Housner 1963: a plastic impact that keeps the momentum about the
new corner) then loses energy that depends on Δt, non-monotonically, and the automatic Δt of
10 ms lost 40 % of the fifth peak. Here the step before a closing ends IMPACT_LEAD of an impact
step before it; the impact step is IMPACT_OMEGA/√(p/m) long (the spring settles within it);
and the impacted blocks leave the step at its mean velocity (`plastic_velocity`), a plastic
impact, restitution 0, the momentum about the contact kept.
"""

from __future__ import annotations

import numpy as np

from .geometry import mass_matrix
from .layout import KIND, OPEN, S_E0, S_E1, S_G0, S_G1, VV
from .model import Model, State
from .time_step import choose_time_step

#: the impact step: this many inverse frequencies √(m/p) of the contact spring, long beside the
#: spring's period so that the step's implicit solve settles it
IMPACT_OMEGA = 20.0
#: the step before a closing ends this fraction of an impact step before it: the impact step
#: then starts at the contact (what the step's mean velocity carries of the flight before it
#: is this fraction of the approach)
IMPACT_LEAD = 0.05


def approach_bound(model: Model, state: State, contacts, vec: np.ndarray, sca: np.ndarray,
                   dt: float) -> tuple[float, np.ndarray]:
    """The step's Δt where a contact is about to close (module docstring), and which contacts
    this step is the impact step of. A contact of gap g (0 once closed) closing at rate r (the
    rate of its normal distance at the step start's velocities, e·v_a + g·v_b of
    docs/method/dda.md §2.8.1) closes within the step when r·Δt > g + δ, δ =
    ``Params.impact_overshoot`` × the penetration limit (a contact at rest does not close).
    Its impact step is τ = IMPACT_OMEGA/ω, ω = √(p/m) the contact spring's frequency, m the
    lighter free block's mass. Where it closes later than τ, the step ends IMPACT_LEAD·τ before
    (in flight); else this is its impact step, τ long (at most the displacement rule's Δt,
    without its growth limit). Returns (Δt, the contacts impacting)."""
    frac = model.params.impact_overshoot
    none = np.zeros(contacts.n, bool)
    if frac is None or contacts.n == 0 or state.step == 0:
        return dt, none
    v = state.block_velocity
    a, b = contacts.block_a, contacts.block_b
    vv = contacts.cint[:, KIND] == VV
    rate = np.einsum("ij,ij->i", vec[:, S_E0], v[a]) + np.einsum("ij,ij->i", vec[:, S_G0], v[b])
    gap = sca[:, 0].copy()
    if vv.any():
        rate1 = np.einsum("ij,ij->i", vec[vv, S_E1], v[b[vv]]) + np.einsum("ij,ij->i", vec[vv, S_G1], v[a[vv]])
        gap1 = sca[vv, 1]
        pick = gap1 > gap[vv]  # the less penetrated line (Shi's entrance line)
        rate[vv] = np.where(pick, rate1, rate[vv])
        gap[vv] = np.where(pick, gap1, gap[vv])
    allowed = frac * model.penetration_limit
    closing = (rate < 0.0) & (np.maximum(gap, 0.0) + allowed < -rate * dt)
    if not closing.any():
        return dt, none
    geom = state.geometry if state.geometry is not None else model.block_geometry(state.vertex_xy)
    mass = np.where(model.block_fixed, np.inf, model.block_density * geom["area"])
    m = np.minimum(mass[a[closing]], mass[b[closing]])
    impact = IMPACT_OMEGA / np.sqrt(model.penalty / m)  # the impact step of each
    t_close = np.maximum(gap[closing], 0.0) / -rate[closing]
    early = t_close > impact
    if early.any():
        # in flight: the step ends IMPACT_LEAD of an impact step before the first closing
        return float(min(dt, np.min(t_close[early] - IMPACT_LEAD * impact[early]))), none
    # the impact: a step long beside the contact spring's period, which its implicit solve
    # settles (the plastic impact of `plastic_velocity`), at most what the displacement rule
    # allows without its growth limit (a lead step shortened by a closing does not hold it back)
    rule = choose_time_step(model, state.replace(dt=0.0), geom)
    return float(min(rule, impact.max())), closing


def plastic_velocity(model: Model, geom: dict, disp: np.ndarray, velocity: np.ndarray,
                     blocks: np.ndarray, dt: float) -> np.ndarray:
    """``velocity`` (B, 6, the update's) with the impacted ``blocks`` leaving the step at its mean
    velocity D/Δt: the step's implicit solve has stopped the approach at the contact (D projects
    the blocks' motion onto what the closed contact admits, in the metric of their mass: the
    momentum about the contact kept), and the mean velocity carries no rebound — Housner's
    plastic impact. An impact does not add energy: a block whose mean velocity would carry more
    kinetic energy than the update's (a block that a contact brushed, its motion otherwise
    free: D/Δt lags its acceleration by half a step) keeps the update's."""
    v = velocity.copy()
    idx = np.nonzero(blocks & ~model.block_fixed)[0]
    if len(idx) == 0:
        return v
    mass = model.block_density[idx, None, None] * mass_matrix(geom["area"][idx], geom["s1"][idx],
                                                               geom["s2"][idx], geom["s3"][idx])
    mean = disp[idx] / dt
    kinetic_mean = np.einsum("ni,nij,nj->n", mean, mass, mean)
    kinetic_update = np.einsum("ni,nij,nj->n", velocity[idx], mass, velocity[idx])
    keep = kinetic_mean <= kinetic_update
    v[idx[keep]] = mean[keep]
    return v
