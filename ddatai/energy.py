"""Energy bookkeeping of a DDA step (NumPy only).

Per unit thickness [J/m]:

- kinetic      T  = Σ ½ ρ vᵀ M v            (generalized velocities, M of §1.3)
- gravitational Vg = Σ ρ S (−g · c)           (c: block centroid; zero at the model origin)
- strain       U  = Σ ½ S σᵀ C⁻¹ σ           (constant stress per block, total stress)
- contact      Uc = Σ ½ p dn² (closed) + ½ ks ds² (locked) + ½ p_f u² (fixed points)

Over a step, the work of the point loads and of the ground motion's inertial forces enters,
friction dissipates Ff times the slip's magnitude, and what is left of the balance is the work dissipated by the
integrator (Newmark's numerical damping and the penalty springs' losses):
``integrator = external − ΔE − friction``. It must not be negative: a step that creates energy
is a numerical instability. ``ddatai.results.STEP_DTYPE`` carries all of these.
"""

from __future__ import annotations

import numpy as np

from .geometry import displacement_matrix, mass_matrix
from .layout import KIND, LOCK, OPEN, S_ES, S_GS, SLIDE, VE


def mechanical_energy(model, geom: dict, velocity: np.ndarray, stress: np.ndarray,
                      fixed_point_xy: np.ndarray) -> tuple[float, float, float, float]:
    """(kinetic, gravitational, strain, fixed-point spring) energy of the free blocks [J/m]."""
    free = ~model.block_fixed
    area = geom["area"][free]
    rho = model.block_density[free]
    mass = mass_matrix(area, geom["s1"][free], geom["s2"][free], geom["s3"][free])
    v = velocity[free]
    kinetic = 0.5 * float(np.einsum("b,bi,bij,bj->", rho, v, mass, v))
    gravitational = -float(np.sum(rho * area * (geom["centroid"][free] @ model.gravity)))
    compliance = model.block_compliance[free]
    s = stress[free]
    strain = 0.5 * float(np.einsum("b,bi,bij,bj->", area, s, compliance, s))
    springs = 0.0
    if len(model.fixed_point_block):
        gap = model.fixed_point_xy0 - fixed_point_xy
        springs = 0.5 * model.fixed_point_penalty * float(np.sum(gap * gap))
    return kinetic, gravitational, strain, springs


def contact_energy(model, contacts) -> float:
    """½ p dn² of closed contacts (active line) plus ½ ks ds² of locked ones [J/m]."""
    if contacts is None or contacts.n == 0:
        return 0.0
    closed = contacts.state != OPEN
    locked = contacts.state == LOCK
    return 0.5 * (model.penalty * float(np.sum(contacts.dn[closed] ** 2)) +
                  model.shear_penalty * float(np.sum(contacts.ds[locked] ** 2)))


def friction_work(contacts, vec: np.ndarray, friction: np.ndarray, disp: np.ndarray) -> float:
    """Work dissipated by the friction of sliding vertex-edge contacts in a step [J/m]:
    S·dir·(e_sᵀ Di + g_sᵀ Dj), the friction force times the slip of the vertex along the edge
    (§2.8.4); ``friction`` is each contact's S in the accepted solve."""
    sliding = (contacts.state == SLIDE) & (contacts.cint[:, KIND] == VE)
    if not sliding.any():
        return 0.0
    a, b = contacts.block_a[sliding], contacts.block_b[sliding]
    slip = np.einsum("ij,ij->i", vec[sliding, S_ES], disp[a]) + np.einsum("ij,ij->i", vec[sliding, S_GS], disp[b])
    return float(np.sum(friction[sliding] * contacts.shear_dir[sliding] * slip))


def external_work(model, geom: dict, disp: np.ndarray, load_xy: np.ndarray, load_force: np.ndarray,
                  ground: np.ndarray) -> float:
    """Work of the point loads and of the ground motion's inertial body force −ρ a_g in a step
    (linear displacements T·D, as in the step equations) [J/m]."""
    work = 0.0
    if len(model.load_block):
        b = model.load_block
        t = displacement_matrix(load_xy, geom["centroid"][b])
        u = np.einsum("nij,nj->ni", t, disp[b])
        work += float(np.sum(load_force * u))
    if ground is not None:
        free = ~model.block_fixed
        mass = model.block_density[free] * geom["area"][free]
        work -= float(np.sum(mass[:, None] * ground[None, :] * disp[free, :2]))
    return work


def state_energy(model, state, geom: dict, contacts) -> tuple[float, float, float, float]:
    """(kinetic, gravitational, strain, contact) energy of a state [J/m]: the contact term holds
    the contact springs, the fixed-point springs and the bolts."""
    kinetic, gravitational, strain, springs = mechanical_energy(
        model, geom, state.block_velocity, state.block_stress, state.fixed_point_xy)
    if len(model.bolt_block):
        from .support import bolt_energy  # loaded only by models with bolts

        springs += bolt_energy(model, state)
    return kinetic, gravitational, strain, springs + contact_energy(model, contacts)


def step_work(model, state, geom: dict, disp: np.ndarray, contacts, vec: np.ndarray,
              friction: np.ndarray, load_force: np.ndarray, dt: float) -> tuple[float, float]:
    """(external work, friction dissipation) of an accepted step from ``state`` with solution
    ``disp`` [J/m]; ``load_force``: the point loads at mid-step [N/m]."""
    t_mid = state.time + 0.5 * dt
    ground = np.asarray(model.ground_acceleration(t_mid), float) if model.ground_acceleration is not None else None
    external = external_work(model, geom, disp, state.load_xy, load_force, ground)
    if model.water_unit_weight > 0:
        from .support import support_work  # loaded only by models with water

        external += support_work(model, state.vertex_xy, geom["centroid"], disp)
    dissipated = friction_work(contacts, vec, friction, disp) if contacts.n else 0.0
    return external, dissipated

