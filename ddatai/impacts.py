"""Impacts (docs/method/dda.md §4.6, §5.2): the step that ends just before a contact closes, the
impact step that follows it, and the plastic impact at its start that leaves the impacted
blocks without a rebound at the contact.

DDA's integrator (Newmark, γ = 1, §5.1) turns the closing of a stiff contact spring within one
step into a rebound: where the step is long beside the spring's period, its implicit solve
stops the approach at the contact, and the update v_n+1 = v + Δt·a_n+1 sends the contact apart
at (1/β − 1) × the approach speed (0.78 of it at β = 9/16, all of it at Shi's β = ½); where the
step resolves the spring's period, the spring gives the approach back, less the integrator's
damping. A rocking block (Housner 1963: a plastic impact that keeps the momentum about the
new corner) then loses energy that depends on Δt, non-monotonically, and the automatic Δt of
10 ms lost 40 % of the fifth peak. Here a closing is predicted from the contact point's
velocity and acceleration (``approach_bound``); the step before it ends IMPACT_LEAD of an impact
step before it; the impact step is IMPACT_OMEGA/√(p/m) long (the spring settles within it);
its solve finds which contacts hold, and the step is taken again from the impacted blocks'
velocity projected onto what they admit (`Stepper.impact_projection`, ``plastic_start``): a
plastic impact at the step's start, restitution 0, the momentum about the contact kept. The
retake's open-close iteration starts from the contact states the first try converged to
(``resumed``): the same step and Δt, only the impacted blocks' start velocity changed.
"""

from __future__ import annotations

import numpy as np

from .geometry import mass_matrix
from .layout import KIND, OPEN, S_E0, S_E1, S_G0, S_G1, VV
from .contacts import Contacts
from .model import Model, State
from .time_step import choose_time_step

#: the impact step: this many inverse frequencies √(m/p) of the contact spring, long beside the
#: spring's period so that the step's implicit solve settles it
IMPACT_OMEGA = 20.0
#: the step before a closing ends this fraction of an impact step before it: the impact step
#: then starts at the contact (the projected velocity leaves the corner this fraction of an
#: impact step's approach above it: 0.05 made a squat rocking block fly and land again, −2 to
#: −20 % of an impact's energy)
IMPACT_LEAD = 0.002
#: an impact that takes at most this share of its blocks' kinetic energy (a contact that only
#: brushed them, a sliding block's vertex crossing a joint's edge) is left to the step: taking
#: the step again would change its result by less than the open-close tolerances
IMPACT_NEGLIGIBLE = 1e-6


def approach_bound(model: Model, state: State, contacts, vec: np.ndarray, sca: np.ndarray,
                   dt: float) -> tuple[float, np.ndarray]:
    """The step's Δt where a contact is about to close (module docstring), and which contacts
    this step is the impact step of. A contact open at the step's start (one the last step's
    solve closed carries its approach in its spring: ntdda's grid under sudden gravity took the
    compression of its closed joints for impacts, every step taken again) of gap g (0 where
    penetrated) closing at rate c (the
    rate of its normal distance at the step start's velocities, −(e·v_a + g·v_b) of
    docs/method/dda.md §2.8.1) and accelerating at k (the same at the last step's
    accelerations: a rocking block's corner gains 6 % of its approach in its last 10 ms step)
    closes when c·H + ½·k·H² > g + δ over the horizon H = max(Δt, τ), δ =
    ``Params.impact_overshoot`` × the penetration limit (a contact at rest does not close);
    τ = IMPACT_OMEGA/ω is its impact step, ω = √(p/m) the contact spring's frequency, m the
    lighter free block's mass (the horizon: a step the growth limit holds short after a lead
    step still sees the closing). Where it closes at t_c > 2·IMPACT_LEAD·τ, the step ends
    IMPACT_LEAD·τ before (in flight); else this is its impact step, τ long (at most the
    displacement rule's Δt, without its growth limit), and the contacts closing within it its
    impacts. Returns (Δt, the contacts impacting)."""
    frac = model.params.impact_overshoot
    none = np.zeros(contacts.n, bool)
    if frac is None or contacts.n == 0 or state.step == 0:
        return dt, none
    a, b = contacts.block_a, contacts.block_b
    vv = contacts.cint[:, KIND] == VV
    gap = sca[:, 0].copy()
    pick = np.zeros(contacts.n, bool)
    if vv.any():
        pick[vv] = sca[vv, 1] > gap[vv]  # the less penetrated line (Shi's entrance line)
        gap[pick] = sca[pick, 1]
    # the closing speed and acceleration of each contact's normal distance (the contact
    # point's, from its blocks' velocities and accelerations of the last step)
    speed = -_normal_rate(vec, a, b, pick, state.block_velocity)
    accel = -_normal_rate(vec, a, b, pick, state.block_accel)
    # a contact closed at the step's start (by the last step's accepted solve) carries its
    # approach in its spring: loading, not a closing
    moving = np.flatnonzero(((speed > 0.0) | (accel > 0.0)) & (contacts.state == OPEN))
    if not len(moving):
        return dt, none
    geom = state.geometry if state.geometry is not None else model.block_geometry(state.vertex_xy)
    mass = np.where(model.block_fixed, np.inf, model.block_density * geom["area"])
    # the impact step of each: τ = IMPACT_OMEGA/√(p/m)
    tau = IMPACT_OMEGA / np.sqrt(model.penalty / np.minimum(mass[a[moving]], mass[b[moving]]))
    c, k, g = speed[moving], accel[moving], np.maximum(gap[moving], 0.0)
    # closing past the overshoot δ within the step, or within its impact step where the step
    # is shorter (a step the growth limit holds short after a lead step)
    horizon = np.maximum(dt, tau)
    hard = frac * model.penetration_limit + g < c * horizon + 0.5 * k * horizon * horizon
    if not hard.any():
        return dt, none
    moving, tau, c, k, g = moving[hard], tau[hard], c[hard], k[hard], g[hard]
    # the first root of ½·k·t² + c·t = g, in the form that does not cancel (`time_step`)
    root = c + np.sqrt(np.maximum(c * c + 2.0 * k * g, 0.0))
    t_close = np.where(g > 0.0, 2.0 * g / np.where(root > 0.0, root, 1.0), 0.0)
    now = t_close <= 2.0 * IMPACT_LEAD * tau
    if not now.any():
        # in flight: the step ends IMPACT_LEAD of an impact step before the first closing
        return float(min(dt, np.min(t_close - IMPACT_LEAD * tau))), none
    # the impact: a step long beside the contact spring's period, which its implicit solve
    # settles, at most what the displacement rule allows without its growth limit (a lead
    # step shortened by a closing does not hold it back); the contacts that close within it
    # are its impacts
    step = float(min(choose_time_step(model, state.replace(dt=0.0), geom), tau[now].max()))
    closing = np.zeros(contacts.n, bool)
    closing[moving[t_close <= step]] = True
    return step, closing


def _normal_rate(vec: np.ndarray, a: np.ndarray, b: np.ndarray, line1: np.ndarray, field: np.ndarray) -> np.ndarray:
    """(m,) the rate of each contact's normal distance under the blocks' 6-vectors ``field``
    (velocities, or accelerations): e·f_a + g·f_b of its line 0, or of line 1 (vertex on
    block b) where ``line1``."""
    rate = np.einsum("ij,ij->i", vec[:, S_E0], field[a]) + np.einsum("ij,ij->i", vec[:, S_G0], field[b])
    if line1.any():
        rate[line1] = np.einsum("ij,ij->i", vec[line1, S_E1], field[b[line1]]) + \
            np.einsum("ij,ij->i", vec[line1, S_G1], field[a[line1]])
    return rate


def impacted(model: Model, closing: np.ndarray, contacts) -> np.ndarray:
    """(B,) the blocks of the contacts that `approach_bound` found closing and the step's
    solve closed: the blocks of the step's impacts."""
    hit = closing & (contacts.state != OPEN)
    out = np.zeros(model.n_blocks, bool)
    out[contacts.block_a[hit]] = True
    out[contacts.block_b[hit]] = True
    return out & ~model.block_fixed


def negligible(model: Model, state: State, geom: dict, projected: np.ndarray, blocks: np.ndarray) -> bool:
    """Whether the plastic impact of the ``blocks`` takes at most IMPACT_NEGLIGIBLE of their
    kinetic energy: ½(v − v₊)ᵀM(v − v₊) (the projection is orthogonal in the mass's metric)
    against ½vᵀMv."""
    idx = np.flatnonzero(blocks)
    mass = model.block_density[idx, None, None] * mass_matrix(geom["area"][idx], geom["s1"][idx],
                                                               geom["s2"][idx], geom["s3"][idx])
    v = model.params.velocity_carry * state.block_velocity[idx]
    change = v - projected[idx]
    lost = np.einsum("ni,nij,nj->", change, mass, change)
    return bool(lost <= IMPACT_NEGLIGIBLE * np.einsum("ni,nij,nj->", v, mass, v))


def plastic_start(state: State, projected: np.ndarray, blocks: np.ndarray) -> State:
    """``state`` with the impacted ``blocks`` moving at their ``projected`` velocity, without
    acceleration history: the state just after a plastic impact at the step's start (Housner's:
    ``projected``, `Stepper.impact_projection`, keeps the momentum about the contact and leaves
    no approach), from which the impact step is taken again (the step's energy balance starts
    from the state before the impact, and books the impact's loss)."""
    velocity, accel = state.block_velocity.copy(), state.block_accel.copy()
    velocity[blocks] = projected[blocks]
    accel[blocks] = 0.0
    return state.replace(block_velocity=velocity, block_accel=accel)


def resumed(start: Contacts, accepted: Contacts) -> Contacts:
    """The contacts from which the impact step is taken again: ``start`` (the step's contacts as
    detected, each try's first guess) with the open-close fields the first try converged to,
    from ``accepted`` (its accepted solve's). The retake is the same step at the same Δt, only the
    impacted blocks' start velocity projected (``plastic_start``), so its iteration's natural
    first guess is where the first one ended (docs/method/dda.md §4.6, *Impacts*), not the step
    start's states it began from: each solve judges the law afresh, and the retake is accepted
    by the same tests as any try. Taken: the state, the VV contact's active line, the sliding
    direction, whether its friction is coupled, the normal force the friction of an uncoupled
    one reads (what each solve assumes) and the bonds: v₊ was projected with the accepted solve's
    contacts, a bond broken there among them (a rocking block's old corner, bonded since the
    start, lifting off as the new one lands). The distances stay the step start's."""
    out = start.copy()
    for name in ("state", "line", "shear_dir", "coupled", "normal_force", "bond"):
        getattr(out, name)[:] = getattr(accepted, name)
    return out
