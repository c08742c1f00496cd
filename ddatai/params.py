"""Material, joint and solver parameters: frozen keyword-only dataclasses.

Everything here is plain Python (no NumPy, no Taichi), validated on construction so that a bad
value fails with a `ValueError` naming the parameter before any simulation work is done.

Units are SI throughout (m, kg, s, N, Pa); friction angles are the one exception and are given
in degrees. Forces and stiffnesses are per metre of thickness (plane problems of unit
thickness), so a contact penalty has units of N/m per m = Pa.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Literal, Optional


class UnitWarning(UserWarning):
    """A value valid in SI units but implausible for rock: most likely given in another unit
    (friction in radians, density in g/cm³, Young's modulus in MPa). The message names the
    value and the likely unit; silence it with ``warnings.simplefilter("ignore", UnitWarning)``
    for a deliberate model (a soft analogue material, a frictionless test)."""


#: Plausible ranges for rock in SI units; a value outside is warned about with its likely unit
#: (rock densities are 1,000–5,000 kg/m³, moduli 0.1–200 GPa; soils and ores reach a little
#: beyond, so the bounds leave room).
DENSITY_RANGE = (100.0, 2.0e4)      # kg/m³
YOUNG_MIN = 1.0e5                   # Pa
STRENGTH_MIN = 100.0                # Pa, a cohesion or tensile strength that is not 0
FRICTION_RADIANS = math.pi / 2      # degrees: a friction angle at or below this looks like radians
#: The strict open-close convergence test (``dataclasses.replace(params, **STRICT_CONVERGENCE)``):
#: Coulomb's law and the tensile strength within 1e-6 of each contact's own strength, the test
#: of earlier versions (`Params.oc_force_reference`).
STRICT_CONVERGENCE = {"oc_force_reference": "strength", "oc_force_tolerance": 1e-6}


def unit_hint(name: str, value: float) -> Optional[str]:
    """Why ``value`` of the parameter ``name`` ("density" [kg/m³], "young" [Pa], "friction"
    [degrees], "cohesion" or "tensile" [Pa]) looks like another unit, or None if it is
    plausible for rock."""
    v = float(value)
    if name == "density":
        if v < 10.0:
            return (f"density = {v:g} kg/m³ is implausible for rock (1,000–5,000 kg/m³): it looks like "
                    f"g/cm³ or t/m³ ({v:g} g/cm³ = {v * 1e3:g} kg/m³)")
        if v < DENSITY_RANGE[0]:
            return (f"density = {v:g} kg/m³ is implausible for rock (1,000–5,000 kg/m³): it looks like "
                    f"a unit weight in kN/m³ ({v:g} kN/m³ is a density of {v * 1e3 / 9.81:.4g} kg/m³)")
        if v > DENSITY_RANGE[1]:
            return (f"density = {v:g} kg/m³ is implausible for rock (1,000–5,000 kg/m³): it looks like "
                    f"a unit weight in N/m³ ({v:g} N/m³ is a density of {v / 9.81:.4g} kg/m³)")
    elif name == "young":
        if 0 < v <= 1e3:
            return (f"young = {v:g} Pa (Young's modulus) is implausible for rock (0.1–200 GPa): it "
                    f"looks like GPa ({v:g} GPa = {v * 1e9:g} Pa)")
        if 0 < v < YOUNG_MIN:
            return (f"young = {v:g} Pa (Young's modulus) is implausible for rock (0.1–200 GPa): it "
                    f"looks like MPa ({v:g} MPa = {v * 1e6:g} Pa)")
    elif name == "friction":
        if 0 < v <= FRICTION_RADIANS:
            return (f"friction = {v:g}° is implausible for a rock joint: friction is an angle in degrees, "
                    f"and this looks like radians ({v:g} rad = {math.degrees(v):.4g}°) or a friction "
                    f"coefficient tan φ (φ = {math.degrees(math.atan(v)):.4g}°)")
    elif name in ("cohesion", "tensile"):
        if 0 < v < STRENGTH_MIN:
            return (f"{name} = {v:g} Pa is implausibly small for a rock joint: it looks like kPa "
                    f"({v:g} kPa = {v * 1e3:g} Pa) or MPa ({v:g} MPa = {v * 1e6:g} Pa)")
    return None


def likely_unit_mistake(material: "Material") -> str:
    """"; likely cause: …" naming a `Material` value that looks like another unit, for the end
    of an error message; empty if none does."""
    hints = [h for name in ("young", "density") if (h := unit_hint(name, getattr(material, name)))]
    return ("; likely cause: Material." + "; Material.".join(hints)) if hints else ""


def _warn_units(owner: str, names: tuple[str, ...], obj) -> None:
    import warnings

    for name in names:
        hint = unit_hint(name, getattr(obj, name))
        if hint is not None:
            # stacklevel 4: the line that built the Material / Joint (past __init__ and __post_init__)
            warnings.warn(f"{owner}.{hint}", UnitWarning, stacklevel=4)


def _require(cond: bool, message: str) -> None:
    if not cond:
        raise ValueError(message)


def _finite(x: float) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)


@dataclass(frozen=True, kw_only=True)
class Material:
    """Linear elastic, isotropic block material."""

    density: float
    """Mass density ρ [kg/m³], > 0. Used for inertia and for gravity (body force ρ·g)."""
    young: float
    """Young's modulus E [Pa], > 0."""
    poisson: float
    """Poisson's ratio ν [-], in [0, 0.5)."""

    def __post_init__(self) -> None:
        _require(_finite(self.density) and self.density > 0,
                 f"Material.density must be a finite number > 0 kg/m³, got {self.density!r}")
        _require(_finite(self.young) and self.young > 0,
                 f"Material.young (Young's modulus) must be a finite number > 0 Pa, got {self.young!r}")
        _require(_finite(self.poisson) and 0.0 <= self.poisson < 0.5,
                 f"Material.poisson must be in [0, 0.5), got {self.poisson!r}")
        for name in ("density", "young", "poisson"):
            object.__setattr__(self, name, float(getattr(self, name)))
        _warn_units("Material", ("density", "young"), self)


@dataclass(frozen=True, kw_only=True)
class Joint:
    """Mohr–Coulomb joint (contact) properties with a tensile cut-off.

    Cohesion and tensile strength act only while a contact is intact ("bonded"): on an
    edge-to-edge contact of the initial geometry, until the contact first leaves the locked
    state (or, with ``Params(bond_breaks_on_slip=False)``, until it first opens). After that
    only friction remains (residual strength).
    """

    friction: float = 30.0
    """Friction angle φ [degrees], in [0, 90)."""
    cohesion: float = 0.0
    """Cohesion c [Pa], >= 0; acts over the contact length of an edge-to-edge contact."""
    tensile: float = 0.0
    """Tensile strength T [Pa], >= 0; acts over the contact length of an edge-to-edge contact."""

    def __post_init__(self) -> None:
        _require(_finite(self.friction) and 0.0 <= self.friction < 90.0,
                 f"Joint.friction (angle in degrees) must be in [0, 90), got {self.friction!r}")
        _require(_finite(self.cohesion) and self.cohesion >= 0,
                 f"Joint.cohesion must be a finite number >= 0 Pa, got {self.cohesion!r}")
        _require(_finite(self.tensile) and self.tensile >= 0,
                 f"Joint.tensile (tensile strength) must be a finite number >= 0 Pa, got {self.tensile!r}")
        for name in ("friction", "cohesion", "tensile"):
            object.__setattr__(self, name, float(getattr(self, name)))
        _warn_units("Joint", ("friction", "cohesion", "tensile"), self)


@dataclass(frozen=True, kw_only=True)
class Params:
    """Numerical parameters of a DDA run. ``None`` means "choose automatically" (documented rule).

    The defaults are meant to give accurate answers on the verification cases of
    ``tests/test_verification.py`` without tuning; see docs/guide/how_it_works.md, "Numerical defaults".
    """

    dt: Optional[float] = None
    """Time step [s]. ``None``: automatic (displacement rule below, capped by ``dt_max``).
    A fixed value is the step used whenever a step converges; a step that fails the
    open-close iteration or the displacement check is retried with a shorter one and the
    step then grows back towards ``dt`` (at most ``dt_growth`` per step)."""
    dt_max: float = 0.01
    """Largest automatic time step [s]."""
    impact_overshoot: Optional[float] = 0.01
    """Impacts: closing past this × the penetration limit (``ddatai.impacts``; None: off) [-]."""
    midstep_lever_arms: bool = True
    """Contact vertices' lever arms at mid-step (docs/method/dda.md §5.3; False: the step start's)."""
    lever_arm_rotation: Literal["iterate", "predicted"] = "iterate"
    """Rotation of the mid-step lever arms: each solve's iterate, or the one "predicted" by the
    step's carried motion for all its solves (K changes only where states do; docs/method/dda.md §5.3)."""
    dt_min_ratio: float = 1e-4
    """Smallest time step, as a fraction of ``dt`` (or ``dt_max``) [-]. A step that cannot be
    made to converge above it stops the run with a `SimulationError`."""
    dt_growth: float = 1.3
    """Largest growth of the automatic time step from one step to the next [-]."""
    dt_cut: float = 0.3
    """Factor applied to the time step when the open-close iteration fails [-] (Shi: 0.3)."""
    max_displacement_ratio: float = 0.005
    """g2: largest vertex displacement allowed in one step, as a fraction of the model scale
    w0 = half the larger side of the model's bounding box, at most 10 × the median size of the
    free blocks [-]. Sets the automatic time step
    and the contact search distance d0 = 2.5·g2·w0."""
    displacement_reject: float = 3.0
    """A step whose largest vertex displacement exceeds this many times g2·w0 is redone with
    dt/√R [-] (ntdda: 3)."""

    penalty: Optional[float] = None
    """Normal contact spring p [N/m per m thickness = Pa]. ``None``: ``penalty_ratio`` × the
    largest Young's modulus of the free blocks (fixed blocks do not deform in the model, so
    their modulus does not set it)."""
    penalty_ratio: float = 50.0
    """Automatic penalty as a multiple of the free blocks' largest Young's modulus [-] (ntdda: 50)."""
    shear_ratio: float = 2.5
    """h2: normal / shear contact spring ratio [-]; the shear spring is p/h2 (Shi: 2.5)."""
    fixed_point_ratio: float = 100.0
    """Fixed-point spring as a multiple of the contact penalty [-] (ntdda: 100)."""

    initial_equilibrium: bool = True
    """Start from equilibrium: before t = 0 the model is brought to its static equilibrium under
    gravity, the point loads at t = 0 and the initial stresses, with the contacts touching at
    t = 0 held (locked, bonds intact); then the first step applies the real contact strengths,
    so contacts loaded beyond them slide or open at once (`ddatai.start`; the usual first stage
    of UDEC/3DEC and FLAC models, and ntdda's gravity turn-on phase). False: gravity is switched
    on suddenly at t = 0 (Shi, ntdda without its gravity phase)."""
    start_turn_on: bool = False
    """Where the stage is in doubt, settle it by a slow turn-on of the weight (`ddatai.turn_on`)
    instead of releasing the blocks in doubt: the start then follows a slow load, at its cost,
    and inside its scatter (docs/guide/equilibrium_start.md, why it is off by default)."""
    static: bool = False
    """Static (quasi-static) analysis: block velocities are reset to zero after every step."""
    dynamic_ratio: float = 1.0
    """k: fraction of the velocity carried into the next step [-], 1 = fully dynamic;
    0 < k < 1 is kinetic damping. Ignored (taken as 0) when ``static`` is true."""
    newmark_beta: float = 0.5625
    """β of the Newmark integrator (γ = 1) [-]. DDA's constant-acceleration scheme is β = ½
    (Shi 1988, docs/method/dda.md §5.1): exact for constant acceleration, but its spectral radius
    returns to 1 for stiff modes (Ω = ωΔt ≫ 1), so the velocity of a block stopped by a stiff
    contact flips sign every step and is never damped (impacts rebound elastically and the
    stored velocity is released when the contact opens). β = (γ + ½)²/4 = 9/16 damps stiff
    modes to 1/3 per step with the same low-frequency behaviour, and stays exact for constant
    acceleration (it carries the previous acceleration). The first step always uses β = ½."""
    plane: Literal["strain", "stress"] = "strain"
    """Plane strain or plane stress elasticity."""
    bond_breaks_on_slip: bool = True
    """True (Shi, ntdda): a bonded joint loses its cohesion and tensile strength for good as
    soon as it leaves the locked state (slides or opens). False: it keeps them while it slides
    and loses them only when it opens (tension cut-off) — the Mohr–Coulomb joint of
    limit-equilibrium methods, where c acts on a sliding surface (docs/kgm/method.md §6.1, §6.6);
    `kgm`'s DDA evaluator uses it to compare critical friction angles with KGM/SKGM."""

    oc_max_iterations: int = 20
    """Largest number of open-close iterations in one step before the time step is cut. Calm
    steps need 1–3; impacts in a pile can need 10–20, and an iteration is cheaper than a cut
    (a 225-block pile dropped onto its base: 37 s with 20, 52 s with 10)."""
    open_tolerance: float = 1e-12
    """Round-off allowance of the open-close judgement, as a fraction of w0 [-]: a contact's
    force may differ from the contact law by the force of a spring stretched this far,
    p·open_tolerance·w0 (so a closed contact opens once it pulls harder than that, beyond the
    tensile strength T·L of a bonded joint). It only absorbs round-off: a tolerance like
    ntdda's f0 = 2e-7 would let contacts carry tensions of p·f0·w0 (thousands of kN at rock
    penalties) and blocks could never topple."""
    oc_force_tolerance: float = 1e-3
    """Open-close convergence, the contact law [-]: in an accepted step every locked contact's
    shear force is at most its Coulomb strength S = N·tanφ + c·L, every sliding contact's
    friction is S of that step, and no contact pulls harder than its tensile strength — each
    within this fraction of the force named by ``oc_force_reference`` (plus the round-off force
    above). The default, 1e-3 of the load the contact's blocks carry, moves a critical tanφ by
    at most ~1e-3 (~0.05°; docs/method/dda.md §4.3)."""
    oc_force_reference: Literal["load", "strength"] = "load"
    """What ``oc_force_tolerance`` is a fraction of: "load", the load the contact's blocks carry
    (their weight or largest contact force, as for ``oc_state_tolerance``), or "strength", the
    contact's own (N·tanφ + c·L, T·L): the strict test of earlier versions, with 1e-6
    (`STRICT_CONVERGENCE`)."""
    oc_friction: Literal["coupled", "lagged"] = "coupled"
    """Sliding friction: "coupled", N of the same solve (an LU); "lagged", N of the last solve as a load (a
    Cholesky; coupled where it stalls): 1.4–6× the solves on the failing slope (docs/guide/performance.md)."""
    factor_updates: bool = False
    """CHOLMOD rank updates where states change (stage, lagged; `ddatai.updates`); off: no time saved."""
    oc_state_tolerance: float = 1e-3
    """Open-close convergence, state and motion [-]: a contact's state may differ from what its
    motion calls for (open but overlapping, sliding where it would stick) while the force that
    makes is below this fraction of the load its blocks carry (their weight or their largest
    contact force) — 1e-3 of a block's weight is an overlap of ~1e-10 m for rock. Without it,
    contacts that carry almost nothing (the head joints of a loaded grid) flip between open and
    closed, or between sticking and sliding, for many solves at forces that move nothing."""
    penetration_ratio: float = 4e-4
    """g3: penetration allowed, as a fraction of w0 [-]; a step whose largest penetration
    exceeds 2.5·g3·w0 is redone with a shorter time step, and a run that cannot keep under it
    stops with a `SimulationError` (runaway penetration)."""
    angle_tolerance: float = 3.0
    """h1: angle tolerance of the contact entrance test and of edge parallelism [degrees]."""

    solver: str = "auto"
    """Direct solver of each open-close iteration: "scipy" (SuperLU, always available),
    "pardiso" (Intel MKL PARDISO through the optional ``pypardiso`` package, ~5× faster at
    1,600 blocks), "dense" (LAPACK on the dense matrix: the fastest for small models) or
    "auto" (dense up to ``ddatai.solver.DENSE_UNKNOWNS`` unknowns, then PARDISO when installed,
    else SuperLU). See `ddatai.solver`."""
    arch: str = "cpu"
    """Taichi backend for contact detection and assembly: "cpu", "gpu" (CUDA/Vulkan/Metal,
    whichever is present) or "cuda"."""
    kernels: str = "auto"
    """Where a run's work runs: "fused" (`ddatai.fused`: a small model's whole run in one Taichi kernel, many
    runs side by side), "taichi" (today's step, its per-block and per-contact work in Taichi kernels on
    ``arch``), "numpy" (today's step in NumPy, no Taichi) or "auto": the fused engine where it pays its kernel
    and takes the same step (`ddatai.fused.policy`), else NumPy up to ``SMALL_MODEL_BLOCKS`` free blocks on the
    CPU, Taichi beyond; ``Results.meta["engine"]`` says which ran and why."""

    def __post_init__(self) -> None:
        def pos(name: str) -> None:
            v = getattr(self, name)  # None: automatic (dt, penalty) or off (impact_overshoot)
            _require((v is None and name in ("dt", "penalty", "impact_overshoot")) or (_finite(v) and v > 0),
                     f"Params.{name} must be a finite number > 0, got {v!r}")
        for name in ("dt", "penalty", "impact_overshoot", "penalty_ratio", "shear_ratio", "fixed_point_ratio",
                     "max_displacement_ratio", "open_tolerance", "oc_force_tolerance", "oc_state_tolerance",
                     "penetration_ratio", "angle_tolerance", "dt_min_ratio", "dt_max"):
            pos(name)
        _require(_finite(self.dt_growth) and self.dt_growth >= 1.0,
                 f"Params.dt_growth must be >= 1, got {self.dt_growth!r}")
        _require(_finite(self.dt_cut) and 0.0 < self.dt_cut < 1.0,
                 f"Params.dt_cut must be in (0, 1), got {self.dt_cut!r}")
        _require(_finite(self.displacement_reject) and self.displacement_reject >= 1.0,
                 f"Params.displacement_reject must be >= 1, got {self.displacement_reject!r}")
        _require(_finite(self.dynamic_ratio) and 0.0 <= self.dynamic_ratio <= 1.0,
                 f"Params.dynamic_ratio must be in [0, 1], got {self.dynamic_ratio!r}")
        _require(_finite(self.newmark_beta) and 0.5 <= self.newmark_beta <= 1.0,
                 f"Params.newmark_beta must be in [0.5, 1], got {self.newmark_beta!r}")
        _require(self.plane in ("strain", "stress"),
                 f"Params.plane must be 'strain' or 'stress', got {self.plane!r}")
        _require(isinstance(self.oc_max_iterations, int) and self.oc_max_iterations >= 2,
                 f"Params.oc_max_iterations must be an integer >= 2, got {self.oc_max_iterations!r}")
        _require(self.angle_tolerance < 30.0,
                 f"Params.angle_tolerance must be < 30 degrees, got {self.angle_tolerance!r}")
        # a closed contact carries tensions up to p·open_tolerance·w0: above ~1e-10 that rivals
        # block weights and blocks stop toppling (benchmarks/results/accuracy.md)
        _require(self.open_tolerance <= 1e-10,
                 f"Params.open_tolerance must be <= 1e-10 (a tension allowance of p·f0·w0), "
                 f"got {self.open_tolerance!r}")
        _require(self.oc_state_tolerance < 0.1,
                 f"Params.oc_state_tolerance must be < 0.1 (a fraction of a block's load), "
                 f"got {self.oc_state_tolerance!r}")
        _require(self.oc_force_tolerance < 0.1,
                 f"Params.oc_force_tolerance must be < 0.1 (a fraction of a contact's load or strength), "
                 f"got {self.oc_force_tolerance!r}")
        for name, allowed in (("oc_friction", ("lagged", "coupled")), ("lever_arm_rotation", ("iterate", "predicted")),
                              ("oc_force_reference", ("load", "strength"))):
            value = getattr(self, name)
            _require(value in allowed, f"Params.{name} must be {' or '.join(map(repr, allowed))}, got {value!r}")
        _require(self.dt_min_ratio < 1.0, f"Params.dt_min_ratio must be < 1, got {self.dt_min_ratio!r}")
        _require(self.solver in ("auto", "scipy", "pardiso", "dense"),
                 f"Params.solver must be 'auto', 'scipy', 'pardiso' or 'dense', got {self.solver!r}")
        _require(self.kernels in ("auto", "taichi", "numpy", "fused"),
                 f"Params.kernels must be 'auto', 'fused', 'taichi' or 'numpy', got {self.kernels!r}")
        _require(isinstance(self.arch, str) and self.arch in ("cpu", "gpu", "cuda", "vulkan", "metal"),
                 f"Params.arch must be one of 'cpu', 'gpu', 'cuda', 'vulkan', 'metal', got {self.arch!r}")
        for name in ("factor_updates", "initial_equilibrium", "start_turn_on", "bond_breaks_on_slip", "midstep_lever_arms"):
            _require(isinstance(getattr(self, name), bool),
                     f"Params.{name} must be True or False, got {getattr(self, name)!r}")

    @property
    def velocity_carry(self) -> float:
        """k actually used: 0 in static mode, ``dynamic_ratio`` otherwise."""
        return 0.0 if self.static else self.dynamic_ratio


#: Upper bound of a Barton–Bandis joint's mobilised friction angle [degrees]: Barton & Choubey
#: (1977) advise that φr + JRC·log10(JCS/σn) be taken no higher than 70° (the law climbs
#: without bound as σn → 0) — docs/method/barton_bandis.md.
BB_MAX_FRICTION = 70.0


@dataclass(frozen=True, kw_only=True)
class BartonBandis(Joint):
    """Barton–Bandis joint: the friction angle mobilised at normal stress σn is

        φ(σn) = φr + JRC·log10(JCS/σn),  τ = σn·tan φ(σn) (+ c while bonded)

    (Barton & Choubey 1977), bounded to φr ≤ φ(σn) ≤ ``max_friction``: at σn ≥ JCS the
    asperities are sheared through and the residual angle φr acts; as σn → 0 the angle is
    capped (70° by default). A `Joint` with a stress-dependent friction angle, accepted
    wherever one is: DDA evaluates φ(σn) at each contact's own normal stress (its normal force
    over its length) inside the open–close iteration; `kgm` at each face's normal stress in
    its limit equilibrium (docs/method/barton_bandis.md). ``friction`` is the residual angle φr
    (the least the joint mobilises), for anything that needs a single angle.
    """

    friction: float = field(init=False, default=0.0)
    """Residual friction angle φr [degrees] (set from ``residual_friction``)."""
    jrc: float
    """Joint roughness coefficient JRC [-], in [0, 20] (Barton's profiles; 0 = planar)."""
    jcs: float
    """Joint wall compressive strength JCS [Pa], > 0 (the UCS of fresh joint walls, less when
    weathered; typically 10–200 MPa)."""
    residual_friction: float
    """Residual friction angle φr [degrees], in [0, ``max_friction``)."""
    max_friction: float = BB_MAX_FRICTION
    """Cap of the mobilised friction angle [degrees], in (φr, 90)."""
    reduction: float = 1.0
    """Strength-reduction factor F [-], > 0: the mobilised tan φ(σn) is divided by F (the
    cohesion is reduced on its own field). 1 for a real joint; `kgm` sets it when it searches a
    factor of safety by strength reduction."""
    peak_displacement: Optional[float] = None
    """Softening switch: δp [m], > 0, the shear displacement at peak strength. In DDA a contact
    that has slid δ beyond it mobilises JRC·m(δ/δp), m falling from 1 at δp to 0 at 100·δp
    (Barton's mobilisation table, `jrc_mobilised`; `barton_peak_displacement` estimates δp).
    None (default): no softening, the peak JRC throughout. Limit equilibrium (`kgm`) takes
    the peak."""

    def __post_init__(self) -> None:
        name = type(self).__name__
        _require(_finite(self.jrc) and 0.0 <= self.jrc <= 20.0,
                 f"{name}.jrc (joint roughness coefficient) must be in [0, 20], got {self.jrc!r}")
        _require(_finite(self.jcs) and self.jcs > 0,
                 f"{name}.jcs (joint wall compressive strength) must be a finite number > 0 Pa, got {self.jcs!r}")
        _require(_finite(self.max_friction) and 0.0 < self.max_friction < 90.0,
                 f"{name}.max_friction (angle in degrees) must be in (0, 90), got {self.max_friction!r}")
        _require(_finite(self.residual_friction) and 0.0 <= self.residual_friction < self.max_friction,
                 f"{name}.residual_friction (angle in degrees) must be in [0, max_friction = "
                 f"{self.max_friction!r}), got {self.residual_friction!r}")
        _require(_finite(self.reduction) and self.reduction > 0,
                 f"{name}.reduction must be a finite number > 0, got {self.reduction!r}")
        _require(self.peak_displacement is None or (_finite(self.peak_displacement) and self.peak_displacement > 0),
                 f"{name}.peak_displacement (softening) must be None or a finite number > 0 m, "
                 f"got {self.peak_displacement!r}")
        _require(_finite(self.cohesion) and self.cohesion >= 0,
                 f"{name}.cohesion must be a finite number >= 0 Pa, got {self.cohesion!r}")
        _require(_finite(self.tensile) and self.tensile >= 0,
                 f"{name}.tensile (tensile strength) must be a finite number >= 0 Pa, got {self.tensile!r}")
        for attr in ("jrc", "jcs", "residual_friction", "max_friction", "reduction"):
            object.__setattr__(self, attr, float(getattr(self, attr)))
        object.__setattr__(self, "friction", self.residual_friction)
        super().__post_init__()
        if self.jcs < 1e5:
            import warnings

            warnings.warn(f"{name}.jcs = {self.jcs:g} Pa is implausibly small for a joint wall "
                          f"(10–200 MPa): it looks like MPa ({self.jcs:g} MPa = {self.jcs * 1e6:g} Pa)",
                          UnitWarning, stacklevel=3)

    def mobilised_friction(self, sigma_n):
        """φ(σn) [degrees] at normal stress ``sigma_n`` [Pa] (scalar or array; σn ≤ 0 gives
        the cap), bounded to [φr, max_friction]; strength reduction not applied."""
        import numpy as np

        s = np.asarray(sigma_n, dtype=float)
        with np.errstate(divide="ignore", invalid="ignore"):
            phi = self.residual_friction + self.jrc * np.log10(self.jcs / np.where(s > 0, s, np.nan))
        # σn → 0: the cap (the residual angle of a smooth joint, JRC = 0: its limit)
        zero = self.max_friction if self.jrc > 0 else self.residual_friction
        phi = np.where(s > 0, np.clip(phi, self.residual_friction, self.max_friction), zero)
        return float(phi) if phi.ndim == 0 else phi

    def tan_friction(self, sigma_n):
        """tan φ(σn) / F [-]: the friction coefficient mobilised at ``sigma_n`` [Pa], reduced."""
        import numpy as np

        return np.tan(np.radians(self.mobilised_friction(sigma_n))) / self.reduction

    def shear_strength(self, sigma_n):
        """τ = σn·tan φ(σn)/F + c [Pa] at normal stress ``sigma_n`` [Pa] (0 tension assumed
        for σn ≤ 0 beyond the cohesion)."""
        import numpy as np

        s = np.asarray(sigma_n, dtype=float)
        return np.maximum(s, 0.0) * self.tan_friction(s) + self.cohesion


#: Barton's JRC mobilisation beyond the peak: (δ/δp, JRC_mob/JRC_peak) (Barton 1982; Barton,
#: Bandis & Bakhtar 1985), interpolated linearly in log10(δ/δp); 0 beyond 100·δp
#: (docs/method/barton_bandis.md, eq. BB7)
JRC_MOBILISATION = ((1.0, 1.0), (2.0, 0.85), (4.0, 0.70), (10.0, 0.50), (100.0, 0.0))


def jrc_mobilised(slip, peak_displacement):
    """JRC_mob/JRC_peak [-] after a slip δ [m] with peak displacement δp [m] (arrays
    broadcast; eq. BB7): 1 up to δp, Barton's table beyond, 0 from 100·δp on."""
    import numpy as np

    ratio = np.maximum(np.asarray(slip, dtype=float) / np.asarray(peak_displacement, dtype=float), 1.0)
    x, y = np.log10([r for r, _ in JRC_MOBILISATION]), [m for _, m in JRC_MOBILISATION]
    return np.interp(np.log10(ratio), x, y)


def barton_peak_displacement(length: float, jrc: float) -> float:
    """Barton and Bandis' estimate of the peak shear displacement δp = (L/500)·(JRC/L)^0.33 [m]
    of a joint of length L [m] (the block size along it) and roughness JRC [-] (eq. BB8)."""
    _require(_finite(length) and length > 0, f"barton_peak_displacement: length must be > 0 m, got {length!r}")
    _require(_finite(jrc) and jrc > 0, f"barton_peak_displacement: jrc must be > 0, got {jrc!r}")
    return (length / 500.0) * (jrc / length) ** 0.33
