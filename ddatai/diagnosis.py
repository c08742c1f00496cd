"""Why a step failed: the message of `SimulationError`, with the numbers, the blocks or contacts
involved, and what to change (docs/method/limits.md)."""

from __future__ import annotations

import numpy as np

from .model import Model
from .params import unit_hint


def failure_message(model: Model, attempt, step: int, time: float, dt: float) -> str:
    """The message of a step that failed even at the shortest Δt; ``attempt`` is the step's
    last `ddatai.step.Attempt`."""
    m, p = model, model.params
    if attempt.cause == "open-close":
        named = ", ".join(f"blocks {a}-{b}" for a, b in attempt.culprits)
        what = (f"the open-close iteration did not converge in {p.oc_max_iterations} iterations "
                f"({attempt.changing} contacts still changing state, e.g. between {named})")
        advice = "raise Params.oc_max_iterations, or loosen Params.oc_state_tolerance" + \
            slivers(model, {b for pair in attempt.culprits for b in pair})
    elif attempt.cause == "nan":
        what = "the solution is not finite (NaN or infinite displacements)"
        advice = ("the system is singular or overflowed: check the blocks' Young's moduli and "
                  f"densities and the penalty p = {m.penalty:.3g} Pa")
    elif attempt.cause == "penetration":
        (a, b), force = attempt.culprits[0], attempt.culprit_force
        what = (f"runaway penetration: {attempt.max_penetration:.4g} m between blocks {a} and {b} "
                f"exceeds the limit 2.5·g3·w0 = {m.penetration_limit:.4g} m (contact force "
                f"{force:.3g} N/m against the penalty p = {m.penalty:.3g} Pa)")
        advice = ("raise Params.penalty (or penalty_ratio) so that force/p stays well below the limit, "
                  "or raise Params.penetration_ratio (docs/method/limits.md)")
        if attempt.culprit_start > m.penetration_limit:
            # no Δt helps a contact that is too deep before the step moves anything
            what += (f"; the contact entered the step already {attempt.culprit_start:.4g} m deep, "
                     f"which no time step can undo")
        advice += slivers(model, {a, b})
    elif attempt.cause == "inverted":
        (b, _), strain = attempt.culprits[0], attempt.culprit_force
        what = f"block {b} is turned inside out by the step (strain {strain:.3g})"
        advice = "lower the time step, or merge the block into a neighbour" + slivers(model, {b})
    else:
        what = (f"the step displacement {attempt.max_displacement:.4g} m exceeds "
                f"{p.displacement_reject:g} × g2·w0 = {p.displacement_reject * m.max_step:.4g} m")
        advice = "lower Params.max_displacement_ratio or the time step"
    return (f"simulation diverged at step {step} (t = {time:.6g} s): {what}, even with the "
            f"time step cut to {dt:.3g} s; {advice}{unit_causes(model)}")


def slivers(model: Model, blocks) -> str:
    """The free blocks among ``blocks`` thinner than the contacts' penetration band d9 (their
    thickness 2·area/perimeter), named as a likely cause; empty if none is."""
    from .geometry import polygon_integrals

    m = model
    off = m.vertex_offset
    out = []
    for b in sorted(int(x) for x in blocks if 0 <= x < m.n_blocks and not m.block_fixed[x]):
        xy = m.vertex_xy0[off[b]:off[b + 1]]
        area = abs(float(polygon_integrals(xy, np.array([0, len(xy)]))["area"][0]))
        perimeter = float(np.sum(np.hypot(*(np.roll(xy, -1, axis=0) - xy).T)))
        thickness = 2.0 * area / max(perimeter, 1e-300)
        if thickness < m.max_penetration:
            out.append(f"block {b} is a sliver {thickness:.3g} m thick (area {area:.3g} m²), thinner than "
                       f"the contacts' penetration band {m.max_penetration:.3g} m")
    if not out:
        return ""
    return (". Likely cause: " + "; ".join(out) + ": merge it into a neighbour (Scene.cut(..., "
            "slivers='merge'), docs/method/limits.md)")


def unit_causes(model: Model) -> str:
    """The model's material and joint values that look like another unit (`unit_hint`), as
    the likely cause of a failure; empty if none does."""
    m, p = model, model.params
    values = [("Material", "density", float(d)) for d in np.unique(m.block_density)]
    if p.penalty is None:  # the automatic penalty comes from the free blocks' largest Young's modulus
        values.append(("Material", "young", m.penalty / p.penalty_ratio))
    values += [("Joint", name, float(v)) for name, arr in (("friction", m.joint_friction),
                                                           ("cohesion", m.joint_cohesion),
                                                           ("tensile", m.joint_tensile))
               for v in np.unique(arr)]
    hints = [f"{owner}.{h}" for owner, name, v in values if (h := unit_hint(name, v)) is not None]
    return ". Likely cause: " + "; ".join(hints) if hints else ""
