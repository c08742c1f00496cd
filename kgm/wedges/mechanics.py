"""Vector limit equilibrium of a rigid block on its faces (docs/kgm/wedge.md §4).

Forces are split, as in SWedge and Hoek & Bray's comprehensive solution, into

* the **active** resultant r = W + k·W + water forces + external forces + active bolts: it sets
  the mode and the sliding direction ŝ (`kgm.wedges.block_theory.admissible_modes`), and its
  component along ŝ is the driving force S = r·ŝ;
* the **passive** resultant p of passive bolts: it only resists, adding normal force on the
  sliding faces and its component against the motion, −p·ŝ.

With the normal force Nᵢ on sliding face i (from r and p, the sliding direction held) the
shear strength is Qᵢ = Nᵢ·tan φᵢ(σᵢ) + cᵢAᵢ, σᵢ = Nᵢ/Aᵢ (Mohr–Coulomb: φ constant;
Barton–Bandis: the project's joint law `ddatai.BartonBandis.tan_friction`, the same as in 2D).
Water forces are part of r, so Nᵢ is the effective normal force. Then

    FS = (Σ Qᵢ − p·ŝ) / S                       (sliding on one or two planes)
    FS = max(0, −p·r̂) / ‖r‖                      (falling: only passive support holds it)
    FS = ∞                                       (no admissible mode)

and the block's acceleration along ŝ when it is not held is a = (S − ΣQᵢ + p·ŝ)/m.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Optional, Sequence

import numpy as np

from .block_theory import Mode, admissible_modes, normal_forces
from .geometry import _finite, direction_vector


@dataclass(frozen=True)
class Water:
    """Water in the joints and the tension crack.

    ``Water()`` is Hoek & Bray's fully saturated wedge ("filled fissures"): average pressure
    u = γw·Hw/6 on the joints, where Hw is the vertical height between the ends of the
    line of intersection of joints 1 and 2, or, with a tension crack, u = γw·H5w/3 on the
    joints and the crack, H5w the depth of the crack's lowest point on that line below the
    upper face (Hoek & Bray 1981, Appendix 2; Wyllie & Mah 2004, eq. III.58–III.59).
    ``fill`` < 1 is a partly filled wedge, simulated as Wyllie & Mah (§III.3) advise by the
    unit weight of water times ``fill``. ``pressures`` gives the average pressure on each
    joint and the crack instead (in that order) [Pa]: a custom distribution.
    """

    fill: float = 1.0
    """Fraction of the fissures filled [-], in [0, 1]."""
    density: float = 1000.0
    """ρw [kg/m³]; γw = ρw·g."""
    pressures: Optional[tuple] = None
    """Average pressure on joint 1, joint 2 (basal joint) and the crack [Pa]; None: Hoek & Bray."""

    def __post_init__(self) -> None:
        if not (_finite(self.fill) and 0.0 <= self.fill <= 1.0):
            raise ValueError(f"Water.fill must be a fraction in [0, 1], got {self.fill!r}")
        if not (_finite(self.density) and self.density > 0):
            raise ValueError(f"Water.density must be > 0 kg/m³, got {self.density!r}")
        if self.pressures is not None:
            p = tuple(self.pressures)
            if not all(_finite(x) and x >= 0 for x in p):
                raise ValueError(f"Water.pressures must be pressures >= 0 Pa, got {self.pressures!r}")
            object.__setattr__(self, "pressures", tuple(float(x) for x in p))


@dataclass(frozen=True)
class Seismic:
    """Pseudo-static seismic load k·W in a direction: ``Seismic(k)`` is horizontal along the
    trend of the static sliding direction (the most unfavourable horizontal direction for
    sliding along it); ``trend``/``plunge`` fix the direction [degrees]."""

    k: float
    """Seismic coefficient [-] (a fraction of g), >= 0."""
    trend: Optional[float] = None
    """Trend of the force [degrees]; None: the trend of the sliding direction without it."""
    plunge: float = 0.0
    """Plunge of the force [degrees] (> 0 downwards)."""

    def __post_init__(self) -> None:
        if not (_finite(self.k) and self.k >= 0):
            raise ValueError(f"Seismic.k (seismic coefficient) must be a number >= 0, got {self.k!r}")
        if self.trend is not None and not _finite(self.trend):
            raise ValueError(f"Seismic.trend must be an angle in degrees or None, got {self.trend!r}")
        if not (_finite(self.plunge) and -90.0 <= self.plunge <= 90.0):
            raise ValueError(f"Seismic.plunge must be in [-90, 90] degrees, got {self.plunge!r}")


def seismic_load(seismic) -> Optional[Seismic]:
    """A `Seismic` from None, a coefficient k (horizontal, along the sliding trend), a
    `Seismic`, or a vector (kx, ky, kz) in g (x east, y north, z up)."""
    if seismic is None or isinstance(seismic, Seismic):
        return seismic
    if _finite(seismic):
        return Seismic(float(seismic))
    try:
        v = np.asarray(seismic, dtype=float).reshape(3)
    except (TypeError, ValueError):
        raise ValueError(f"seismic must be None, a coefficient k, a kgm.Seismic or a vector (kx, ky, kz) in g, "
                         f"got {seismic!r}") from None
    if not np.all(np.isfinite(v)):
        raise ValueError(f"seismic vector must be finite, got {seismic!r}")
    k = float(np.linalg.norm(v))
    if k == 0.0:
        return None
    from .geometry import trend_plunge

    t, p = trend_plunge(v)
    return Seismic(k, t, p)


@dataclass(frozen=True)
class Bolt:
    """A bolt, anchor or cable acting on the block: ``force`` [N] along the direction given by
    ``trend`` and ``plunge`` [degrees] (the direction it pulls the block; an anchor installed
    upwards into the slope from the face has the trend of the face's dip direction + 180° and a
    negative plunge). ``kind``: 'active' (tensioned: enters the driving resultant) or 'passive'
    (mobilised by the motion: only resists, SWedge's passive bolts)."""

    force: float
    trend: float
    plunge: float
    kind: str = "active"

    def __post_init__(self) -> None:
        if not (_finite(self.force) and self.force >= 0):
            raise ValueError(f"Bolt.force must be >= 0 N, got {self.force!r}")
        if not (_finite(self.trend) and _finite(self.plunge) and -90.0 <= self.plunge <= 90.0):
            raise ValueError(f"Bolt trend/plunge must be angles (plunge in [-90, 90]), got "
                             f"{self.trend!r}/{self.plunge!r}")
        if self.kind not in ("active", "passive"):
            raise ValueError(f"Bolt.kind must be 'active' or 'passive', got {self.kind!r}")

    @property
    def vector(self) -> np.ndarray:
        return self.force * direction_vector(self.trend, self.plunge)


@dataclass(frozen=True)
class Force:
    """An external force on the block [N] along trend/plunge [degrees] (active), e.g. a
    foundation load."""

    force: float
    trend: float
    plunge: float

    def __post_init__(self) -> None:
        if not (_finite(self.force) and self.force >= 0):
            raise ValueError(f"Force.force must be >= 0 N, got {self.force!r}")
        if not (_finite(self.trend) and _finite(self.plunge) and -90.0 <= self.plunge <= 90.0):
            raise ValueError(f"Force trend/plunge must be angles (plunge in [-90, 90]), got "
                             f"{self.trend!r}/{self.plunge!r}")

    @property
    def vector(self) -> np.ndarray:
        return self.force * direction_vector(self.trend, self.plunge)


@dataclass(frozen=True)
class Contact:
    """A face the block may slide on: inward unit normal, area, strength."""

    label: str
    normal: np.ndarray
    """Unit normal pointing into the block [-]."""
    area: float
    """[m²]."""
    joint: Optional[object] = None
    """`ddatai.Joint`/`BartonBandis`; None: no strength (a tension crack)."""

    def tan_friction(self, normal_force: float) -> float:
        """tan φ at σn = N/A (Barton–Bandis) or tan φ (Mohr–Coulomb) [-]."""
        j = self.joint
        if j is None:
            return 0.0
        if hasattr(j, "tan_friction"):
            sigma = max(normal_force, 0.0) / self.area if self.area > 0 else 0.0
            return float(j.tan_friction(sigma))
        return math.tan(math.radians(j.friction))

    @property
    def cohesion(self) -> float:
        return 0.0 if self.joint is None else float(self.joint.cohesion)


@dataclass(frozen=True)
class Equilibrium:
    """The limit equilibrium of a block."""

    fs: float
    """Factor of safety [-] (inf: no admissible mode; 0: falling without passive support)."""
    mode: Mode
    """The mode (its sliding direction, its faces)."""
    normal: np.ndarray
    """Effective normal force on each contact face, active and passive [N]."""
    shear_strength: np.ndarray
    """Shear strength Qᵢ mobilisable on each face [N]."""
    driving: float
    """S = r·ŝ [N]."""
    resisting: float
    """ΣQᵢ − p·ŝ [N]."""
    acceleration: float
    """Acceleration along ŝ if the block is released, (S − resisting)/m when positive [m/s²]."""


def equilibrium(contacts: Sequence[Contact], active: np.ndarray, passive: Optional[np.ndarray] = None,
                mass: float = 1.0) -> Equilibrium:
    """Limit equilibrium of a block on ``contacts`` under the active resultant ``active`` and
    the passive one ``passive`` [N] (module docstring); of several admissible modes (degenerate
    geometry) the least safe is kept."""
    r = np.asarray(active, dtype=float)
    p = np.zeros(3) if passive is None else np.asarray(passive, dtype=float)
    v = np.array([c.normal for c in contacts]) if contacts else np.zeros((0, 3))
    best = None
    for mode in admissible_modes(r, v):                  # falling, one plane, two planes
        eq = _judge(mode, contacts, v, r, p, mass)
        # a tie (release planes without load) keeps the mode with fewer faces
        if best is None or eq.fs < best.fs * (1.0 - 1e-12):
            best = eq
    return best


def _judge(mode: Mode, contacts, v, r, p, mass) -> Equilibrium:
    m = len(contacts)
    if mode.kind == "stable":
        present = np.array([c.area > 0 for c in contacts], bool)
        normal = np.zeros(m)
        normal[present] = _held_normals(r + p, v[present])
        return Equilibrium(math.inf, mode, normal, np.zeros(m), 0.0, 0.0, 0.0)
    if mode.kind == "falling":
        held = max(0.0, -float(p @ mode.direction))
        rn = float(np.linalg.norm(r))
        fs = held / rn
        return Equilibrium(fs, mode, np.zeros(m), np.zeros(m), rn, held, max(0.0, (rn - held) / mass))
    normal = mode.normal + normal_forces(p, mode, v)
    strength = np.zeros(m)
    for i in mode.planes:
        n = max(float(normal[i]), 0.0)
        normal[i] = n
        strength[i] = n * contacts[i].tan_friction(n) + contacts[i].cohesion * contacts[i].area
    resisting = float(strength.sum() - p @ mode.direction)
    s = mode.driving
    fs = math.inf if s <= 0 else max(resisting, 0.0) / s
    return Equilibrium(fs, mode, normal, strength, s, resisting, max(0.0, (s - resisting) / mass))


def _held_normals(f: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Frictionless normal forces (least squares, non-negative) that balance f on a block held
    by its faces (reported for a stable block)."""
    if len(v) == 0:
        return np.zeros(0)
    from scipy.optimize import nnls

    n, _ = nnls(v.T, -f)
    return n


def required_force(contacts: Sequence[Contact], active: np.ndarray, passive: Optional[np.ndarray], mass: float,
                   fs_target: float, direction: Optional[np.ndarray] = None) -> tuple[float, np.ndarray]:
    """Smallest active force (magnitude [N], unit direction) that raises FS to ``fs_target``.

    With ``direction`` None the direction is the optimum for the current mode (closed form:
    Hoek & Bray's minimum anchor force, Wyllie & Mah eq. III.99–III.111, extended to passive
    forces and any faces): FS = F is linear in the force T along d, Q₀ + T g·d = F(S₀ − T ŝ·d),
    so T = (F·S₀ − Q₀)/‖g + F ŝ'‖ along d ∥ g − F ŝ. A mode that changes on the way (contact
    lost on a face) is caught by re-solving along that direction with a root search on the full
    equilibrium. Returns (0, d) when FS already reaches the target.
    """
    r = np.asarray(active, dtype=float)
    eq = equilibrium(contacts, r, passive, mass)
    if eq.fs >= fs_target:
        return 0.0, (-r / np.linalg.norm(r) if np.linalg.norm(r) > 0 else np.zeros(3))
    v = np.array([c.normal for c in contacts]) if contacts else np.zeros((0, 3))
    if direction is None:
        direction = _optimum_direction(eq, contacts, v, r, fs_target)
    d = np.asarray(direction, dtype=float)
    d = d / np.linalg.norm(d)

    def gap(t: float) -> float:
        e = equilibrium(contacts, r + t * d, passive, mass)
        return min(e.fs, 1e6) - fs_target

    scale = float(np.linalg.norm(r)) or 1.0
    hi = scale * 1e-3
    while gap(hi) < 0:
        hi *= 2.0
        if hi > 1e6 * scale:
            raise ValueError(f"no force along {d} raises FS to {fs_target} (its component against "
                             f"sliding is too small)")
    from scipy.optimize import brentq

    t = brentq(gap, 0.0, hi, xtol=1e-12 * scale, rtol=1e-13, maxiter=200)
    return float(t), d


def _optimum_direction(eq: Equilibrium, contacts, v, r, f: float) -> np.ndarray:
    mode = eq.mode
    if mode.kind == "falling" or mode.kind == "stable":
        return -r / np.linalg.norm(r)
    s = mode.direction
    g = _strength_gradient(eq, contacts, v)
    d = g - f * s
    return d / np.linalg.norm(d)


def worst_force(contacts: Sequence[Contact], active: np.ndarray, passive: Optional[np.ndarray], mass: float,
                magnitude: float) -> tuple[float, np.ndarray]:
    """The least FS an external force of this ``magnitude`` [N] can give, and its direction
    (Hoek & Bray's minimum factor of safety for a load E in its worst direction, Wyllie & Mah
    eq. III.81–III.98, for any mode). With Q₀, S₀ the strength and drive without it and g the
    strength a unit force adds through the normal forces (g ⟂ ŝ), F = Q/S is least along
    d = −(g − F ŝ)/‖g − F ŝ‖ where (Q₀ − F S₀)² = E²(‖g‖² + F²): the smaller root. A mode that
    changes under the load (contact lost) is caught by minimising the full equilibrium over
    directions from there."""
    r = np.asarray(active, dtype=float)
    eq = equilibrium(contacts, r, passive, mass)
    e = float(magnitude)
    if e <= 0:
        return eq.fs, np.zeros(3)
    if eq.mode.kind in ("falling", "stable"):
        d = r / np.linalg.norm(r) if eq.mode.kind == "falling" else -_held_direction(contacts)
        return equilibrium(contacts, r + e * d, passive, mass).fs, d
    v = np.array([c.normal for c in contacts])
    g = _strength_gradient(eq, contacts, v)
    s = eq.mode.direction
    q0, s0 = eq.resisting, eq.driving
    a2, a1, a0 = s0 * s0 - e * e, -2.0 * (q0 * s0 - e * e * float(g @ s)), q0 * q0 - e * e * float(g @ g)
    if abs(a2) < 1e-300:
        f = a0 / -a1
    else:
        disc = max(a1 * a1 - 4 * a2 * a0, 0.0)
        roots = sorted([(-a1 - math.sqrt(disc)) / (2 * a2), (-a1 + math.sqrt(disc)) / (2 * a2)])
        f = next((x for x in roots if x <= q0 / s0 + 1e-12 and x >= 0), 0.0)
    d = -(g - f * s)
    d = d / np.linalg.norm(d)
    full = equilibrium(contacts, r + e * d, passive, mass).fs
    if abs(full - f) <= 1e-9 * max(1.0, f):
        return f, d
    from scipy.optimize import minimize

    def fs_at(x):
        u = np.array([math.cos(x[1]) * math.sin(x[0]), math.cos(x[1]) * math.cos(x[0]), -math.sin(x[1])])
        return min(equilibrium(contacts, r + e * u, passive, mass).fs, 1e6)

    t0 = math.atan2(d[0], d[1])
    p0 = -math.asin(max(-1.0, min(1.0, d[2])))
    res = minimize(fs_at, [t0, p0], method="Nelder-Mead", options=dict(xatol=1e-10, fatol=1e-12, maxiter=4000))
    t, p = res.x
    d = np.array([math.cos(p) * math.sin(t), math.cos(p) * math.cos(t), -math.sin(p)])
    return float(res.fun), d


def _held_direction(contacts) -> np.ndarray:
    v = np.array([c.normal for c in contacts])
    d = v.sum(axis=0)
    return d / np.linalg.norm(d)


def _strength_gradient(eq: Equilibrium, contacts, v) -> np.ndarray:
    """g: the shear strength a unit force along each axis adds through the normal forces of
    the mode's faces (tan φ at the current normal stress) [-]."""
    g = np.zeros(3)
    for i in eq.mode.planes:
        unit = np.zeros(3)
        for axis in range(3):
            e = np.zeros(3)
            e[axis] = 1.0
            unit[axis] = normal_forces(e, eq.mode, v)[i]
        g += contacts[i].tan_friction(eq.normal[i]) * unit
    return g
