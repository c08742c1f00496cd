"""What a model's loads ask of it, checked and sized when it is built (`ddatai.build_model`;
docs/method/limits.md): the stress at the base of each block from the blocks and loads above
it, the elastic strain that stress (or an impact at a block's initial speed) gives, refused
beyond what a first-order DDA block represents, and the automatic contact penalty.
"""

from __future__ import annotations

import warnings

import numpy as np
import shapely

from .params import likely_unit_mistake
from .scene import Scene


#: the elastic strain of a block from its weight and what rests on it (ρ·g·H/E), or from an
#: impact at its initial speed (v·√(ρ/E), the uniform strain that stores its kinetic energy):
#: beyond STRAIN_WARNING a warning (a first-order DDA block updates one uniform strain as a
#: small strain, whose error grows as ε/2 of it: 2.5 % at 5 %); beyond STRAIN_LIMIT the model
#: is refused: its blocks would deform by a quarter of their size, which the equilibrium stage
#: cannot tell from a mechanism (`ddatai.start.MECHANISM_SIZE`), and their contacts and penalty
#: springs leave the method (a frictionless soft mass at 35 % turned singular in its 46th step)
#: (docs/method/limits.md)
STRAIN_WARNING = 0.05
STRAIN_LIMIT = 0.25
#: a model whose extent is this many times its median block size is warned about (precision)
PRECISION_EXTENT = 1e6
#: the automatic penalty keeps the static contact penetration under the weight of a model's
#: columns and point loads within this share of the penetration limit 2.5·g3·w0 ...
STATIC_PENETRATION_SHARE = 0.05
#: ... and the penetration v·√(m/p) of an impact at a block's initial speed within this share
#: (the estimate is the undamped impact of a block on a rigid wall; the implicit step, longer
#: than the contact's period, spreads the impact and stops shallower). A stiffer choice (0.25)
#: made the spring 16× stiffer and a 4-block pile-up at 40 m/s diverged: with friction coupled
#: to the normal force, K's non-symmetric contact terms then dwarf the blocks' inertia
IMPACT_PENETRATION_SHARE = 1.0


def loads_at_start(scene: Scene) -> np.ndarray:
    """(n_loads, 3): block, |force| at t = 0 [N/m] of every point load."""
    out = np.zeros((len(scene.point_loads), 2))
    for k, p in enumerate(scene.point_loads):
        f = p.force(0.0) if callable(p.force) else p.force
        out[k] = (p.block, float(np.hypot(*np.asarray(f, float)[:2])))
    return out


def column_load(xy0, offset, fixed, density, areas, gravity, loads) -> np.ndarray:
    """(B,) the vertical stress at the base of each free block from its own weight and that of
    the free blocks above it (those overlapping it in x), plus the point loads on them,
    spread over the wider of the two blocks [Pa]: the load its contacts carry at rest."""
    nb = len(offset) - 1
    x_lo = np.minimum.reduceat(xy0[:, 0], offset[:-1])
    x_hi = np.maximum.reduceat(xy0[:, 0], offset[:-1])
    y_lo = np.minimum.reduceat(xy0[:, 1], offset[:-1])
    weight = density * areas * abs(gravity)
    if len(loads):
        np.add.at(weight, loads[:, 0].astype(int), loads[:, 1])
    weight[fixed] = 0.0
    out = np.zeros(nb)
    free = np.flatnonzero(~fixed & (weight > 0.0))  # only loaded blocks press on others
    if not len(free):
        return out
    width = np.maximum(x_hi - x_lo, 1e-300)
    top = float(xy0[:, 1].max())
    # candidate pairs from a tree of the loaded blocks' boxes, queried with each free block's
    # strip from its base up (chunks keep the pair lists in bounded memory)
    tree = shapely.STRtree(shapely.box(x_lo[free], y_lo[free], x_hi[free], top))
    targets = np.flatnonzero(~fixed)
    for start in range(0, len(targets), 4096):
        b = targets[start:start + 4096]
        q, c = tree.query(shapely.box(x_lo[b], y_lo[b], x_hi[b], top), predicate="intersects")
        bb, cc = b[q], free[c]
        # strict overlap in x (boxes that only touch do not press), at or above b's base
        keep = (x_lo[cc] < x_hi[bb]) & (x_hi[cc] > x_lo[bb]) & (y_lo[cc] >= y_lo[bb])
        bb, cc = bb[keep], cc[keep]
        out += np.bincount(bb, weights=weight[cc] / np.maximum(width[cc], width[bb]), minlength=nb)
    return out


def check_strain(specs, fixed, column, vel, density, young) -> None:
    """Warn about a block whose weight-and-load strain or impact strain exceeds STRAIN_WARNING;
    refuse one beyond STRAIN_LIMIT."""
    free = ~fixed
    static = np.where(free, column / young, 0.0)
    speed = np.hypot(vel[:, 0], vel[:, 1])
    impact = np.where(free, speed * np.sqrt(density / young), 0.0)
    for name, strain, why, change in (
            ("weight", static, "the weight of the blocks above it and its loads, ρ·g·H/E",
             "a larger Young's modulus, a lower density or gravity, or smaller loads"),
            ("impact", impact, "an impact at its initial speed v·√(ρ/E)",
             "a lower initial speed or a larger Young's modulus")):
        if not np.any(strain > STRAIN_WARNING):
            continue
        b = int(np.argmax(strain))
        m = specs[b].material
        what = (f"block {b}: elastic strain {strain[b]:.3g} from {why} (E = {m.young:.3g} Pa, "
                f"ρ = {m.density:.4g} kg/m³"
                + (f", v = {speed[b]:.3g} m/s" if name == "impact" else f", stress {column[b]:.3g} Pa") + ")")
        if strain[b] > STRAIN_LIMIT:
            raise ValueError(f"{what} exceeds {STRAIN_LIMIT:g}, beyond what a first-order DDA block can "
                             f"represent (docs/method/limits.md); give it {change}{likely_unit_mistake(m)}")
        warnings.warn(f"{what} exceeds {STRAIN_WARNING:g}: a first-order DDA block's small-strain "
                      f"update loses accuracy (error ~ε/2 of the strain, docs/method/limits.md); "
                      f"consider {change}", stacklevel=3)


def automatic_penalty(params, young, fixed, column, vel, density, areas, xy0, offset, limit) -> float:
    """The automatic contact penalty (docs/method/limits.md): ``penalty_ratio`` × the largest
    Young's modulus of the free blocks, raised where the model's loads would push the contacts
    too deep for it — the static penetration σ·size/p of the most loaded block within
    STATIC_PENETRATION_SHARE of the penetration limit, and the penetration v·√(m/p) of an
    impact at a block's initial speed within IMPACT_PENETRATION_SHARE of it.

    Fixed blocks do not set it: their deformation is not modelled (no degrees of freedom), so
    their modulus says nothing about the stiffness the contacts must match. Soft blocks
    (0.3 GPa) on a steel plate (200 GPa) would otherwise get springs 670× stiffer than their
    own, and a falling pile of them cut its time step to 1e-4 s and below."""
    free = ~fixed
    if not free.any():
        return params.penalty_ratio * float(np.max(young))
    p = params.penalty_ratio * float(np.max(young[free]))
    size = np.sqrt(areas)
    static = float(np.max((column * size)[free])) / (STATIC_PENETRATION_SHARE * limit)
    centroid = np.add.reduceat(xy0, offset[:-1]) / np.diff(offset)[:, None]
    radius = np.maximum.reduceat(np.hypot(*(xy0 - np.repeat(centroid, np.diff(offset), axis=0)).T),
                                 offset[:-1])
    speed = np.hypot(vel[:, 0], vel[:, 1]) + np.abs(vel[:, 2]) * radius
    impact = float(np.max((density * areas * speed ** 2)[free])) / (IMPACT_PENETRATION_SHARE * limit) ** 2
    return max(p, static, impact)
