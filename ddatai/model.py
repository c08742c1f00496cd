"""Model (static arrays built once), State (what a step rewrites) and the contact memory.

Data flows one way: `Scene` -> `build_model` -> `Model` + `Model.initial_state()` -> `step`.
Everything is flat NumPy arrays with offsets; block b owns vertices
``vertex_offset[b]:vertex_offset[b+1]``, and its edge k runs from vertex k to
``vertex_next[k]`` (edges are identified by their start vertex).

Internally all coordinates are relative to ``Model.origin`` (the centre of the model's
bounding box), so that penetrations of ~1e-8 m stay representable on models placed far from
the origin (docs/method/dda.md §8.9). Results are returned in the user's coordinates.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field, replace
from functools import cached_property
from typing import Callable, Optional

import numpy as np

from .geometry import polygon_integrals
from .layout import ContactKind, ContactState  # noqa: F401  (re-exported: ddatai.model.ContactState)
from .model_checks import PRECISION_EXTENT, automatic_penalty, check_strain, column_load, loads_at_start
from .params import Params
from .scene import Scene


#: the largest model (free blocks) that `Params(kernels="auto")` runs in NumPy: below it a Taichi
#: kernel launch (~0.3–0.5 ms of Python-side argument passing, ~11 a step) costs more than the
#: vectorised work (benchmarks/small_models.py)
SMALL_MODEL_BLOCKS = 64


@dataclass(frozen=True, kw_only=True, eq=False)
class Model:
    """Static description of a DDA model: never changes during a run."""

    origin: np.ndarray
    """(2,) user coordinates of the internal origin [m]."""
    vertex_offset: np.ndarray
    """(B+1,) int32 offsets of each block's vertices."""
    vertex_block: np.ndarray
    """(V,) int32 block owning each vertex."""
    vertex_next: np.ndarray
    """(V,) int32 next vertex of the same block (CCW); edge k runs k -> vertex_next[k]."""
    vertex_prev: np.ndarray
    """(V,) int32 previous vertex of the same block."""
    vertex_xy0: np.ndarray
    """(V, 2) initial vertex positions, relative to ``origin`` [m]."""
    edge_joint: np.ndarray
    """(V,) int32 joint-table index of each edge (0 = the default joint)."""
    block_fixed: np.ndarray
    """(B,) bool fixed blocks (no unknowns)."""
    block_dof: np.ndarray
    """(B,) int32 block-row of each free block in the global system, -1 for fixed blocks."""
    block_density: np.ndarray
    """(B,) mass density [kg/m³]."""
    block_elastic: np.ndarray
    """(B, 3, 3) elasticity matrix C (plane strain or plane stress) [Pa]."""
    joint_tan_phi: np.ndarray
    """(J,) tangent of the friction angle [-]."""
    joint_friction: np.ndarray
    """(J,) friction angle [degrees]."""
    joint_cohesion: np.ndarray
    """(J,) cohesion [Pa]."""
    joint_tensile: np.ndarray
    """(J,) tensile strength [Pa]."""
    pair_key: np.ndarray
    """(P,) int64 sorted keys i*B + j (i < j) of block pairs with a joint override."""
    pair_joint: np.ndarray
    """(P,) int32 joint-table index of each override."""
    gravity: np.ndarray
    """(2,) gravitational acceleration vector [m/s²]."""
    fixed_point_block: np.ndarray
    """(nf,) int32 block of each fixed point."""
    fixed_point_xy0: np.ndarray
    """(nf, 2) target (initial) position of each fixed point [m, internal coordinates]."""
    load_block: np.ndarray
    """(nl,) int32 block of each point load."""
    load_xy0: np.ndarray
    """(nl, 2) initial position of each load point [m, internal coordinates]."""
    load_force: tuple
    """(nl,) constant (fx, fy) [N/m] or function t -> (fx, fy) per load."""
    measured_block: np.ndarray
    """(nm,) int32 block of each measured point."""
    measured_xy0: np.ndarray
    """(nm, 2) initial position of each measured point [m, internal coordinates]."""
    ground_acceleration: Optional[Callable[[float], tuple]]
    """Ground acceleration a_g(t) -> (ax, ay) [m/s²] or None."""
    initial_velocity: np.ndarray
    """(B, 6) initial generalized velocities (vx, vy, ω, 0, 0, 0)."""
    initial_stress: np.ndarray
    """(B, 3) initial stress (σx, σy, τxy) [Pa]."""

    w0: float
    """Length scale of the tolerances [m]: half the larger side of the model's bounding box
    (ntdda's w0), at most 10 × the median size √area of the free blocks."""
    max_step: float
    """g2·w0: largest vertex displacement wanted in one step [m]."""
    search_distance: float
    """d0: contact search distance [m]."""
    max_penetration: float
    """d9: deepest penetration still detected as a contact [m]."""
    open_tol: float
    """Round-off length of the open-close judgement, open_tolerance·w0 [m]; contacts touching
    within it start closed on the first step."""
    force_roundoff: float
    """Round-off force of the open-close judgement, p·open_tol [N/m]."""
    penetration_limit: float
    """Largest penetration accepted at the end of a step [m]."""
    penalty: float
    """Normal contact spring p [N/m per m]."""
    shear_penalty: float
    """Shear contact spring p/h2 [N/m per m]."""
    fixed_point_penalty: float
    """Fixed-point spring [N/m per m]."""
    params: Params
    """The parameters the model was built with."""
    numpy_path: bool = False
    """A step's per-block and per-contact work runs in NumPy, not in Taichi kernels
    (`Params.kernels`: forced, or a small model on the CPU)."""
    water_xy: Optional[np.ndarray] = None
    """(k, 2) water table h(x) [m, internal coordinates], None: no water
    (docs/method/water_bolts.md)."""
    water_unit_weight: float = 0.0
    """ρw·g of the water [N/m³]; 0: no water."""
    water_heads: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    """(n, 2) joint-table index and own hydraulic head [m, internal coordinates] of the joints
    whose water replaces the table on their edges."""
    bolt_block: np.ndarray = field(default_factory=lambda: np.zeros((0, 2), np.int32))
    """(nb, 2) blocks of the two ends of every bolt."""
    bolt_vertex: np.ndarray = field(default_factory=lambda: np.zeros((0, 2, 3), np.int64))
    """(nb, 2, 3) three vertices of each end's block spanning its affine frame."""
    bolt_coef: np.ndarray = field(default_factory=lambda: np.zeros((0, 2, 2)))
    """(nb, 2, 2) affine coordinates of each end on those vertices [-]."""
    bolt_length0: np.ndarray = field(default_factory=lambda: np.zeros(0))
    """(nb,) initial bolt lengths [m]."""
    bolt_stiffness: np.ndarray = field(default_factory=lambda: np.zeros(0))
    """(nb,) axial stiffness [N/m per m thickness]."""
    bolt_pretension: np.ndarray = field(default_factory=lambda: np.zeros(0))
    """(nb,) tension at the initial length [N/m]."""
    bolt_capacity: np.ndarray = field(default_factory=lambda: np.zeros(0))
    """(nb,) tensile capacity [N/m] (inf: unbreakable)."""
    joint_barton: np.ndarray = field(default_factory=lambda: np.zeros((0, 6)))
    """(J, 6) Barton–Bandis law of every joint: JRC [-], JCS [Pa], φr [degrees], the cap of the
    mobilised angle [degrees], the strength reduction F [-] and the peak displacement δp of
    softening [m] (NaN: none); JRC is NaN on a Mohr–Coulomb joint. Empty (0, 6) when the model
    has no Barton–Bandis joint: then nothing is computed for it (docs/method/barton_bandis.md)."""

    @property
    def n_blocks(self) -> int:
        return len(self.block_fixed)

    @property
    def n_vertices(self) -> int:
        return len(self.vertex_block)

    @cached_property
    def n_free(self) -> int:
        # cached: the fields never change (a run's new penalty is a new Model, `with_penalty`)
        return int(np.count_nonzero(~self.block_fixed))

    @cached_property
    def block_compliance(self) -> np.ndarray:
        """(B, 3, 3) C⁻¹ of every block [1/Pa] (the strain energy's, `ddatai.energy`)."""
        return np.linalg.inv(self.block_elastic)

    def with_penalty(self, penalty: float) -> "Model":
        """This model with the normal contact penalty p [Pa] and what follows from it (the
        shear and fixed-point penalties, the force round-off) set anew (`ddatai.step`'s
        penalty that follows the load)."""
        p = self.params
        return replace(self, penalty=float(penalty), shear_penalty=float(penalty) / p.shear_ratio,
                       fixed_point_penalty=p.fixed_point_ratio * float(penalty),
                       force_roundoff=p.open_tolerance * self.w0 * float(penalty))

    def with_joints(self, joints) -> "Model":
        """This model with the joint table ``joints`` (as many `ddatai.Joint` as it has): what
        `build_model` gives for its scene with those joints, without building the blocks again
        (a kgm batch's members share one geometry and differ only in their joints' strengths)."""
        if len(joints) != len(self.joint_friction):
            raise ValueError(f"with_joints: the model has {len(self.joint_friction)} joints, got {len(joints)}")
        friction = np.array([j.friction for j in joints], dtype=float)
        return replace(self, joint_tan_phi=np.tan(np.radians(friction)), joint_friction=friction,
                       joint_cohesion=np.array([j.cohesion for j in joints], dtype=float),
                       joint_tensile=np.array([j.tensile for j in joints], dtype=float),
                       joint_barton=_barton_arrays(joints).get("joint_barton", np.zeros((0, 6))))

    def initial_state(self) -> "State":
        """State at t = 0."""
        return State(
            time=0.0, step=0,
            vertex_xy=self.vertex_xy0.copy(),
            block_velocity=self.initial_velocity.copy(),
            block_stress=self.initial_stress.copy(),
            block_accel=np.zeros((self.n_blocks, 6)),
            block_rotation=np.zeros(self.n_blocks),
            fixed_point_xy=self.fixed_point_xy0.copy(),
            load_xy=self.load_xy0.copy(),
            measured_xy=self.measured_xy0.copy(),
            dt=0.0, accel=0.0,
            memory=ContactMemory.empty(),
            **({} if not len(self.bolt_block) else {
                "bolt_force": self.bolt_pretension.copy(),
                "bolt_broken_step": np.full(len(self.bolt_block), -1, np.int64),
                "bolt_broken_time": np.full(len(self.bolt_block), np.nan),
                "bolt_broken_force": np.full(len(self.bolt_block), np.nan)}),
        )

    def block_geometry(self, vertex_xy: np.ndarray) -> dict[str, np.ndarray]:
        """Area, centroid and central moments of every block at the given vertex positions."""
        return polygon_integrals(vertex_xy, self.vertex_offset, self.vertex_block, self.vertex_next)


@dataclass(frozen=True, kw_only=True, eq=False)
class ContactMemory:
    """What a contact carries from one step to the next (docs/method/dda.md §3.7).

    Rows are sorted by ``key`` (see `contact_keys`), so a new contact finds its predecessor by
    binary search.
    """

    key: np.ndarray
    """(m,) int64 identity of the contact: vertex and reference edge (VE) or both vertices (VV)."""
    state: np.ndarray
    """(m,) int8 `ContactState` at the end of the step."""
    line: np.ndarray
    """(m,) int8 active entrance line of a VV contact."""
    omega: np.ndarray
    """(m,) lock position ω on the reference edge (kept only while locked)."""
    bond: np.ndarray
    """(m,) bool joint still intact (cohesion and tensile strength act)."""
    shear_dir: np.ndarray
    """(m,) int8 sign of the last sliding direction (friction opposes it)."""
    dn: np.ndarray
    """(m,) normal distance at the end of the step [m] (negative: penetration)."""
    normal_force: np.ndarray
    """(m,) compressive normal force at the end of the step [N/m]."""
    kind: np.ndarray
    """(m,) int8 `ContactKind` at the end of the step."""
    slip: np.ndarray = field(default_factory=lambda: np.zeros(0))
    """(m,) shear displacement slid so far [m] (softening Barton–Bandis joints; empty when
    the model has none)."""

    @staticmethod
    def empty() -> "ContactMemory":
        z = np.zeros(0)
        return ContactMemory(key=np.zeros(0, np.int64), state=z.astype(np.int8), line=z.astype(np.int8),
                             omega=z, bond=z.astype(bool), shear_dir=z.astype(np.int8), dn=z,
                             normal_force=z, kind=z.astype(np.int8))


@dataclass(frozen=True, kw_only=True, eq=False)
class State:
    """Everything a step rewrites. `step` returns a new State; the old one is left untouched."""

    time: float
    """Simulated time [s]."""
    step: int
    """Number of accepted steps."""
    vertex_xy: np.ndarray
    """(V, 2) current vertex positions [m, internal coordinates]."""
    block_velocity: np.ndarray
    """(B, 6) generalized velocities (u̇0, v̇0, ṙ0, ε̇x, ε̇y, γ̇xy) [m/s, rad/s, 1/s]."""
    block_stress: np.ndarray
    """(B, 3) stress (σx, σy, τxy) [Pa], compression negative."""
    block_accel: np.ndarray
    """(B, 6) generalized accelerations at the end of the last step (Newmark) [m/s², ...]."""
    block_rotation: np.ndarray
    """(B,) accumulated rigid rotation [rad], counter-clockwise positive."""
    fixed_point_xy: np.ndarray
    """(nf, 2) current positions of the fixed points (material points of their blocks) [m]."""
    load_xy: np.ndarray
    """(nl, 2) current positions of the load points [m]."""
    measured_xy: np.ndarray
    """(nm, 2) current positions of the measured points [m]."""
    dt: float
    """Time step of the last accepted step [s] (0 before the first)."""
    accel: float
    """Largest block acceleration seen in the last step [m/s²] (for the automatic time step)."""
    memory: ContactMemory = field(default_factory=ContactMemory.empty)
    """Contact data carried to the next step."""
    energy: Optional[float] = None
    """Mechanical energy (kinetic, gravitational, strain, contact) at the end of the last step
    [J/m]; None before the first step."""
    geometry: Optional[dict] = None
    """Polygon integrals of ``vertex_xy`` (a cache filled by the step that produced the state)."""
    bolt_force: np.ndarray = field(default_factory=lambda: np.zeros(0))
    """(nb,) tension of every bolt at the end of the last step [N/m] (0 once broken)."""
    bolt_broken_step: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    """(nb,) step at which each bolt broke, -1 while intact."""
    bolt_broken_time: np.ndarray = field(default_factory=lambda: np.zeros(0))
    """(nb,) time at the end of that step [s] (NaN while intact)."""
    bolt_broken_force: np.ndarray = field(default_factory=lambda: np.zeros(0))
    """(nb,) tension that broke it [N/m] (NaN while intact)."""
    in_doubt: np.ndarray = field(default_factory=lambda: np.zeros(0, bool))
    """(B,) the blocks that the equilibrium stage released in doubt and whose first steps the
    automatic Δt resolves, until they rest or move away (`ddatai.in_doubt`); empty: none."""

    def replace(self, **changes) -> "State":
        return replace(self, **changes)


def _elastic_matrix(young: float, poisson: float, plane: str) -> np.ndarray:
    """C of docs/method/dda.md §2.1 (plane strain = plane stress with E/(1-ν²), ν/(1-ν))."""
    if plane == "strain":
        e = young / (1.0 - poisson ** 2)
        nu = poisson / (1.0 - poisson)
    else:
        e, nu = young, poisson
    f = e / (1.0 - nu * nu)
    return f * np.array([[1.0, nu, 0.0], [nu, 1.0, 0.0], [0.0, 0.0, (1.0 - nu) / 2.0]])


def build_model(scene: Scene, params: Optional[Params] = None, *,
                length_scale: Optional[float] = None) -> Model:
    """Turn a `Scene` into a `Model`, validating what can only be checked on the whole model
    (at least one free block, no overlapping blocks). ``length_scale``: w0 [m], the length of
    the tolerances (`Model.w0`), given instead of taken from the model's extent (a batch of
    independent members keeps each member's own: `ddatai.batch`)."""
    params = params or Params()
    if not isinstance(params, Params):
        raise ValueError(f"params must be a ddatai.Params, got {type(params).__name__}")
    specs = scene.blocks
    if not specs:
        raise ValueError("the scene has no blocks")
    _check_overlaps(scene)
    nb = len(specs)
    counts = np.array([len(s.vertices) for s in specs])
    offset = np.concatenate([[0], np.cumsum(counts)]).astype(np.int32)
    xy_user = np.concatenate([s.vertices for s in specs])
    lo, hi = xy_user.min(axis=0), xy_user.max(axis=0)
    origin = 0.5 * (lo + hi)
    xy0 = xy_user - origin
    # Length scale of the tolerances (search distance, allowed step displacement, open/close):
    # ntdda's w0, half the model's larger side, capped at 10 × the median size √area of the
    # free blocks. Tied to the whole model, the search distance 2.5·g2·w0 of a 160 m grid of
    # 1 m blocks is a whole block and every vertex collects contacts with far edges
    # (docs/method/dda.md §8.8: 9× the contacts at 25,600 blocks).
    w0 = 0.5 * float(np.max(hi - lo))
    fixed_flags = np.array([s.fixed for s in specs], dtype=bool)
    areas = polygon_integrals(xy0, offset)["area"]
    sizes = np.sqrt(areas[~fixed_flags] if (~fixed_flags).any() else areas)
    w0 = min(w0, 10.0 * float(np.median(sizes)))
    if length_scale is not None:
        if not (np.isfinite(length_scale) and length_scale > 0):
            raise ValueError(f"build_model: length_scale must be a finite length > 0 m, got {length_scale!r}")
        w0 = float(length_scale)
    extent = float(np.max(hi - lo))
    if extent >= PRECISION_EXTENT * float(np.median(sizes)):
        # the block farthest from the bulk of the model (the median of the block centres)
        centres = np.array([np.mean(s.vertices, axis=0) for s in specs])
        far = int(np.argmax(np.hypot(*(centres - np.median(centres, axis=0)).T)))
        warnings.warn(f"the model spans {extent:.3g} m, {extent / float(np.median(sizes)):.3g} × its median "
                      f"block size {float(np.median(sizes)):.3g} m (block {far} lies farthest from the "
                      f"others): double precision resolves ~{extent * 2.2e-16:.1g} m there, close to the "
                      f"contacts' opening tolerance (docs/method/limits.md); move distant blocks closer "
                      f"or model them separately", stacklevel=2)

    vblock = np.repeat(np.arange(nb, dtype=np.int32), counts)
    idx = np.arange(len(xy0), dtype=np.int32)
    vnext = idx + 1
    vnext[offset[1:] - 1] = offset[:-1]
    vprev = idx - 1
    vprev[offset[:-1]] = offset[1:] - 1
    edge_joint = np.concatenate([s.edge_joint for s in specs]).astype(np.int32)
    edge_joint[edge_joint < 0] = 0

    fixed = np.array([s.fixed for s in specs], dtype=bool)
    dof = np.full(nb, -1, dtype=np.int32)
    dof[~fixed] = np.arange(np.count_nonzero(~fixed), dtype=np.int32)
    density = np.array([s.material.density for s in specs], dtype=float)
    elastic = np.stack([_elastic_matrix(s.material.young, s.material.poisson, params.plane) for s in specs])

    joints = scene.joints
    friction = np.array([j.friction for j in joints], dtype=float)
    pkeys = np.array([i * nb + j for (i, j) in scene.pair_joints], dtype=np.int64)
    pjoint = np.array(list(scene.pair_joints.values()), dtype=np.int32)
    order = np.argsort(pkeys)

    def points(specs_, with_force=False):
        blk = np.array([p.block for p in specs_], dtype=np.int32)
        pxy = np.array([p.xy for p in specs_], dtype=float).reshape(-1, 2) - origin
        if with_force:
            return blk, pxy, tuple(p.force for p in specs_)
        return blk, pxy

    fp_block, fp_xy = points(scene.fixed_points)
    ld_block, ld_xy, ld_force = points(scene.point_loads, with_force=True)
    ms_block, ms_xy = points(scene.measured_points)

    vel = np.zeros((nb, 6))
    vel[:, 0] = [s.velocity[0] for s in specs]
    vel[:, 1] = [s.velocity[1] for s in specs]
    vel[:, 2] = [s.angular_velocity for s in specs]
    vel[fixed] = 0.0
    stress = np.array([s.stress for s in specs], dtype=float)

    max_step = params.max_displacement_ratio * w0
    d0 = 2.5 * max_step
    d9 = max(0.3 * d0, 3.0 * params.penetration_ratio * w0)
    d0 = max(d0, d9)
    young = np.array([s.material.young for s in specs], dtype=float)
    loads = loads_at_start(scene)
    column = column_load(xy0, offset, fixed, density, areas, scene.gravity, loads)
    check_strain(specs, fixed, column, vel, density, young)
    penalty = params.penalty if params.penalty is not None else \
        automatic_penalty(params, young, fixed, column, vel, density, areas, xy0, offset,
                           2.5 * params.penetration_ratio * w0)

    return Model(
        origin=origin, vertex_offset=offset, vertex_block=vblock, vertex_next=vnext, vertex_prev=vprev,
        vertex_xy0=xy0, edge_joint=edge_joint, block_fixed=fixed, block_dof=dof,
        block_density=density, block_elastic=elastic,
        joint_tan_phi=np.tan(np.radians(friction)), joint_friction=friction,
        joint_cohesion=np.array([j.cohesion for j in joints], dtype=float),
        joint_tensile=np.array([j.tensile for j in joints], dtype=float),
        pair_key=pkeys[order], pair_joint=pjoint[order],
        gravity=np.array([0.0, -scene.gravity]),
        fixed_point_block=fp_block, fixed_point_xy0=fp_xy,
        load_block=ld_block, load_xy0=ld_xy, load_force=ld_force,
        measured_block=ms_block, measured_xy0=ms_xy,
        ground_acceleration=scene.ground_acceleration,
        initial_velocity=vel, initial_stress=stress,
        w0=w0, max_step=max_step, search_distance=d0, max_penetration=d9,
        open_tol=params.open_tolerance * w0, force_roundoff=params.open_tolerance * w0 * float(penalty),
        penetration_limit=2.5 * params.penetration_ratio * w0,
        penalty=float(penalty), shear_penalty=float(penalty) / params.shear_ratio,
        fixed_point_penalty=params.fixed_point_ratio * float(penalty),
        params=params,
        numpy_path=params.kernels == "numpy" or (
            params.kernels in ("auto", "fused") and params.arch == "cpu"
            and int(np.count_nonzero(~fixed)) <= SMALL_MODEL_BLOCKS),
        **_support_arrays(scene, xy0, offset, origin),
        **_barton_arrays(joints),
    )


def _barton_arrays(joints) -> dict:
    """``joint_barton`` of a model whose joint table holds a Barton–Bandis joint; none else."""
    from .params import BartonBandis

    if not any(isinstance(j, BartonBandis) for j in joints):
        return {}
    law = np.full((len(joints), 6), np.nan)
    for k, j in enumerate(joints):
        if isinstance(j, BartonBandis):
            law[k] = (j.jrc, j.jcs, j.residual_friction, j.max_friction, j.reduction,
                      np.nan if j.peak_displacement is None else j.peak_displacement)
    return {"joint_barton": law}


def _support_arrays(scene: Scene, xy0: np.ndarray, offset: np.ndarray, origin: np.ndarray) -> dict:
    """Water and bolt fields of the model; none (and no import) for a scene without them."""
    if scene.water is None and not scene.bolts:
        return {}
    from .support import bolt_arrays, water_arrays

    return {**water_arrays(scene, origin), **bolt_arrays(scene, xy0, offset, origin)}


def _check_overlaps(scene: Scene) -> None:
    """Raise ValueError naming the first pair of blocks whose interiors overlap."""
    from .geometry import check_overlaps
    check_overlaps(scene)
