"""`Scene`: the user-facing builder of a DDA model (blocks, joints, points, loads, shaking).

A scene is plain Python/NumPy data. Every input is validated when it is added, so an error
names the offending block, joint or parameter before any simulation work. `build_model`
(in :mod:`ddatai.model`) turns a scene into the flat static arrays the solver uses.
"""

from __future__ import annotations

import copy
from dataclasses import dataclass, replace
from typing import Callable, Optional, Sequence, Union

import numpy as np

from .cutting import cut as _cut_domain
from .geometry import validate_polygon
from .params import Joint, Material

Force = Union[Sequence[float], Callable[[float], Sequence[float]]]


@dataclass(frozen=True, kw_only=True)
class BlockSpec:
    """One block as the user gave it (after validation)."""

    vertices: np.ndarray
    """(n, 2) CCW vertices [m]."""
    material: Material
    """Block material."""
    fixed: bool
    """Fixed blocks do not move (they move with the ground under seismic input)."""
    velocity: tuple[float, float]
    """Initial velocity of the centroid (vx, vy) [m/s]."""
    angular_velocity: float
    """Initial angular velocity [rad/s], counter-clockwise positive."""
    stress: tuple[float, float, float]
    """Initial stress (σx, σy, τxy) [Pa], compression negative."""
    edge_joint: np.ndarray
    """(n,) index into the scene's joint table of the joint each edge (vertex k → k+1) lies
    on, or -1 (no joint line: the default joint applies)."""


@dataclass(frozen=True, kw_only=True)
class PointSpec:
    block: int
    """Block the point belongs to."""
    xy: tuple[float, float]
    """Initial position [m]."""
    force: Optional[Force] = None
    """Point load: (fx, fy) [N per m thickness] or a function t [s] -> (fx, fy)."""


#: the attributes of a `Scene` that refer to its blocks by id (`Scene.subset` renumbers them)
BLOCK_REFERENCES = ("blocks", "pair_joints", "fixed_points", "point_loads", "measured_points", "bolts")


class Scene:
    """A 2D block system to simulate.

    Parameters
    ----------
    gravity : float
        Gravitational acceleration [m/s²], acting in -y. 0 switches gravity off.

    Examples
    --------
    >>> import ddatai as dd
    >>> scene = dd.Scene(gravity=9.81)
    >>> rock = dd.Material(density=2500.0, young=5e9, poisson=0.25)
    >>> base = scene.add_block([(0, 0), (4, 0), (4, 1), (0, 1)], material=rock, fixed=True)
    >>> top = scene.add_block([(1, 1), (2, 1), (2, 2), (1, 2)], material=rock)
    >>> scene.set_joint(dd.Joint(friction=35.0))
    >>> scene.n_blocks
    2
    """

    def __init__(self, gravity: float = 9.81):
        if not (isinstance(gravity, (int, float)) and np.isfinite(gravity) and gravity >= 0):
            raise ValueError(f"Scene.gravity must be a finite number >= 0 m/s², got {gravity!r}")
        self.gravity = float(gravity)
        self.blocks: list[BlockSpec] = []
        #: joint table; entry 0 is the default joint (see `set_joint`)
        self.joints: list[Joint] = [Joint()]
        self.pair_joints: dict[tuple[int, int], int] = {}
        self.fixed_points: list[PointSpec] = []
        self.point_loads: list[PointSpec] = []
        self.measured_points: list[PointSpec] = []
        self.ground_acceleration: Optional[Callable[[float], Sequence[float]]] = None
        #: `ddatai.water.WaterTable` or None (no water: nothing is computed for it)
        self.water = None
        #: `ddatai.water.BoltSpec` of every rock bolt, in the order added
        self.bolts: list = []

    # ------------------------------------------------------------------ blocks
    @property
    def n_blocks(self) -> int:
        return len(self.blocks)

    def add_block(self, vertices, *, material: Material, fixed: bool = False,
                  velocity: Sequence[float] = (0.0, 0.0), angular_velocity: float = 0.0,
                  stress: Sequence[float] = (0.0, 0.0, 0.0)) -> int:
        """Add a polygonal block; returns its id (0-based, in the order blocks are added).

        ``vertices`` is a simple polygon in either orientation [m]; ``velocity`` the initial
        centroid velocity [m/s]; ``angular_velocity`` [rad/s]; ``stress`` the initial stress
        (σx, σy, τxy) [Pa].
        """
        bid = len(self.blocks)
        name = f"block {bid}"
        xy = validate_polygon(vertices, name=name)
        self._check_block_args(name, material, velocity, angular_velocity, stress)
        self.blocks.append(BlockSpec(
            vertices=xy, material=material, fixed=bool(fixed),
            velocity=(float(velocity[0]), float(velocity[1])),
            angular_velocity=float(angular_velocity),
            stress=(float(stress[0]), float(stress[1]), float(stress[2])),
            edge_joint=np.full(len(xy), -1, dtype=np.int64)))
        return bid

    @staticmethod
    def _check_block_args(name, material, velocity, angular_velocity, stress) -> None:
        if not isinstance(material, Material):
            raise ValueError(f"{name}: material must be a ddatai.Material, got {type(material).__name__}")
        v = np.asarray(velocity, dtype=float)
        if v.shape != (2,) or not np.all(np.isfinite(v)):
            raise ValueError(f"{name}: velocity must be a finite (vx, vy) pair, got {velocity!r}")
        if not np.isfinite(angular_velocity):
            raise ValueError(f"{name}: angular_velocity must be finite, got {angular_velocity!r}")
        s = np.asarray(stress, dtype=float)
        if s.shape != (3,) or not np.all(np.isfinite(s)):
            raise ValueError(f"{name}: stress must be a finite (σx, σy, τxy) triple, got {stress!r}")

    def cut(self, boundary, joints: Sequence, material: Material, *, fixed: bool = False,
            max_blocks: Optional[float] = None, slivers: str = "warn",
            snap_ends: Optional[float] = None) -> list[int]:
        """Cut the domain polygon ``boundary`` by joint traces and add the resulting blocks.

        ``joints`` is a list of ``(polyline, Joint)``: each polyline (k >= 2 points) is a
        persistent or finite trace. Traces, or parts of them, that do not close a block are
        dropped. Every block edge remembers the joint it lies on, and contacts along that edge
        use that joint's properties. Returns the ids of the new blocks (ordered by centroid,
        bottom to top, then left to right). A cut that would make more blocks than the machine
        can simulate is refused before cutting (`ddatai.cutting.ModelSizeError`, with the
        estimate; ``max_blocks`` sets the limit, inf: none; `ddatai.cutting.cut`). Sliver
        blocks (≥ 50:1, or < 1e-4 of the median block) are reported (``slivers="warn"``, a
        `ddatai.cutting.SliverWarning`) or merged into a neighbour (``slivers="merge"``);
        blocks thinner than the contacts' penetration band are merged either way
        (``slivers="keep"`` keeps every block).
        A trace end that stops at most ``snap_ends`` [m] short of another trace or of the
        boundary (default 1e-6 × the boundary's size: coordinates typed to six decimals) is
        extended onto it; one short by more, up to 1e-5 × the size, is warned about
        (`ddatai.cutting.TraceGapWarning`, with the trace, the gap and what to do).
        """
        if not isinstance(material, Material):
            raise ValueError(f"cut: material must be a ddatai.Material, got {type(material).__name__}")
        traces, jts = [], []
        for k, item in enumerate(joints):
            try:
                trace, jt = item
            except (TypeError, ValueError):
                raise ValueError(f"joint {k}: expected a (polyline, Joint) pair") from None
            if not isinstance(jt, Joint):
                raise ValueError(f"joint {k}: expected a ddatai.Joint, got {type(jt).__name__}")
            traces.append(trace)
            jts.append(jt)
        pieces = _cut_domain(boundary, traces, max_blocks=max_blocks, slivers=slivers, snap_ends=snap_ends)
        # one joint-table entry per distinct Joint value
        table_index = {}
        for jt in jts:
            if jt not in table_index:
                table_index[jt] = self._joint_index(jt)
        ids = []
        for xy, edge_trace in pieces:
            edge_joint = np.array([table_index[jts[t]] if t >= 0 else -1 for t in edge_trace],
                                  dtype=np.int64)
            bid = len(self.blocks)
            self.blocks.append(BlockSpec(vertices=xy, material=material, fixed=bool(fixed),
                                         velocity=(0.0, 0.0), angular_velocity=0.0,
                                         stress=(0.0, 0.0, 0.0), edge_joint=edge_joint))
            ids.append(bid)
        return ids

    def subset(self, keep: Sequence[int], *, held: Sequence[int] = ()) -> tuple["Scene", list[int]]:
        """A scene of the blocks ``keep`` (in that order), the blocks in ``held`` fixed.

        Everything that refers to blocks (``BLOCK_REFERENCES``: joint overrides between block
        pairs, fixed points, point loads, measured points, bolts) is renumbered, and kept where
        all its blocks are kept; every other attribute (gravity, the joint table, the water
        table, the shaking, and any added later) is the scene's own. The one place that cuts a
        scene down (kgm judges a key group on such a sub-scene).

        Returns the sub-scene and, for each of its blocks, its id in this scene.
        """
        ids = [self._block_id(b) for b in keep]
        if len(set(ids)) != len(ids):
            raise ValueError("Scene.subset: a block is kept twice")
        new_id = {b: i for i, b in enumerate(ids)}
        hold = {self._block_id(b) for b in held}
        if not hold <= set(new_id):
            raise ValueError(f"Scene.subset: held blocks {sorted(hold - set(new_id))} are not kept")
        sub = copy.copy(self)
        sub.joints = list(self.joints)
        sub.blocks = [replace(self.blocks[b], fixed=True) if b in hold and not self.blocks[b].fixed
                      else self.blocks[b] for b in ids]
        sub.pair_joints = {(new_id[i], new_id[j]): k for (i, j), k in self.pair_joints.items()
                           if i in new_id and j in new_id}
        sub.fixed_points = [replace(p, block=new_id[p.block]) for p in self.fixed_points if p.block in new_id]
        sub.point_loads = [replace(p, block=new_id[p.block]) for p in self.point_loads if p.block in new_id]
        sub.measured_points = [replace(p, block=new_id[p.block]) for p in self.measured_points
                               if p.block in new_id]
        sub.bolts = [replace(b, block1=new_id[b.block1], block2=new_id[b.block2]) for b in self.bolts
                     if b.block1 in new_id and b.block2 in new_id]
        return sub, ids

    def set_fixed(self, block: int, fixed: bool = True) -> None:
        """Mark a block fixed (or free)."""
        b = self._block_id(block)
        spec = self.blocks[b]
        self.blocks[b] = BlockSpec(vertices=spec.vertices, material=spec.material, fixed=bool(fixed),
                                   velocity=spec.velocity, angular_velocity=spec.angular_velocity,
                                   stress=spec.stress, edge_joint=spec.edge_joint)

    def polygon(self, block: int) -> np.ndarray:
        """The (n, 2) CCW vertices of a block as given [m]."""
        return self.blocks[self._block_id(block)].vertices.copy()

    # ------------------------------------------------------------------ joints
    def _joint_index(self, joint: Joint) -> int:
        for k, jt in enumerate(self.joints[1:], start=1):
            if jt == joint:
                return k
        self.joints.append(joint)
        return len(self.joints) - 1

    def set_joint(self, joint: Joint, between: Optional[tuple[int, int]] = None) -> None:
        """Set the default joint (``between=None``) or override it for all contacts of a pair.

        Precedence for a contact: the pair override, then the joint line its reference edge
        lies on (from `cut`), then the default joint.
        """
        if not isinstance(joint, Joint):
            raise ValueError(f"set_joint: expected a ddatai.Joint, got {type(joint).__name__}")
        if between is None:
            self.joints[0] = joint
            return
        try:
            i, j = between
        except (TypeError, ValueError):
            raise ValueError(f"set_joint: between must be a pair of block ids, got {between!r}") from None
        i, j = self._block_id(i), self._block_id(j)
        if i == j:
            raise ValueError(f"set_joint: between must name two different blocks, got ({i}, {j})")
        self.pair_joints[(min(i, j), max(i, j))] = self._joint_index(joint)

    # ------------------------------------------------------------------ points and loads
    def _block_id(self, block) -> int:
        if isinstance(block, (bool, np.bool_)) or not isinstance(block, (int, np.integer)):
            raise ValueError(f"block id must be an integer, got {block!r}")
        if not 0 <= int(block) < len(self.blocks):
            raise ValueError(f"unknown block id {block} (the scene has {len(self.blocks)} blocks)")
        return int(block)

    def _point_in_block(self, block, xy, what: str) -> tuple[int, tuple[float, float]]:
        b = self._block_id(block)
        p = np.asarray(xy, dtype=float)
        if p.shape != (2,) or not np.all(np.isfinite(p)):
            raise ValueError(f"{what} on block {b}: point must be a finite (x, y) pair, got {xy!r}")
        import shapely

        poly = shapely.Polygon(self.blocks[b].vertices)
        size = float(np.ptp(self.blocks[b].vertices, axis=0).max())
        if poly.distance(shapely.Point(p)) > 1e-9 * size:
            raise ValueError(f"{what} at ({p[0]:g}, {p[1]:g}) is outside block {b}")
        return b, (float(p[0]), float(p[1]))

    def add_fixed_point(self, block: int, xy: Sequence[float]) -> None:
        """Pin a point of a block to its initial position with a stiff spring."""
        b, p = self._point_in_block(block, xy, "fixed point")
        self.fixed_points.append(PointSpec(block=b, xy=p))

    def add_point_load(self, block: int, xy: Sequence[float], force: Force) -> None:
        """Apply a point load at a material point of a block.

        ``force`` is a constant (fx, fy) [N per m thickness] or a function t [s] -> (fx, fy),
        evaluated at the middle of each time step. The point moves with the block.
        """
        b, p = self._point_in_block(block, xy, "point load")
        if callable(force):
            try:
                f0 = np.asarray(force(0.0), dtype=float)
            except Exception as exc:  # noqa: BLE001 - report any failure of the user's function
                raise ValueError(f"point load on block {b}: force(0.0) failed: {exc}") from None
            if f0.shape != (2,) or not np.all(np.isfinite(f0)):
                raise ValueError(f"point load on block {b}: force(t) must return a finite (fx, fy), "
                                 f"got {f0!r} at t=0")
        else:
            f = np.asarray(force, dtype=float)
            if f.shape != (2,) or not np.all(np.isfinite(f)):
                raise ValueError(f"point load on block {b}: force must be a finite (fx, fy) pair "
                                 f"or a function of time, got {force!r}")
            force = (float(f[0]), float(f[1]))
        self.point_loads.append(PointSpec(block=b, xy=p, force=force))

    def add_measured_point(self, block: int, xy: Sequence[float]) -> int:
        """Track a material point of a block; its positions are recorded in the results.
        Returns the point's index in ``Results.measured``."""
        b, p = self._point_in_block(block, xy, "measured point")
        self.measured_points.append(PointSpec(block=b, xy=p))
        return len(self.measured_points) - 1

    # ------------------------------------------------------------------ water and bolts
    def set_water_table(self, polyline, *, density: float = 1000.0, heads=None) -> None:
        """Put the scene under a water table h(x): ``polyline`` of (x, y) points [m] with x
        strictly increasing, linear between them and held level beyond its ends; None (and no
        ``heads``) removes the water.

        The pressure is hydrostatic below the table, p = ρw·g·(h(x) − y) [Pa] with ``density``
        ρw [kg/m³] and the scene's gravity, and acts on every block edge below it (joint faces
        of both blocks and free faces). The water is uncoupled: it does not flow and the table
        does not move with the blocks. A water-filled tension crack of Hoek & Bray (water depth
        z_w in the crack, pressure falling linearly to zero where the sliding plane daylights) is
        the table level at the crack's water level behind the crack, then straight down to the
        daylight point. Raises ValueError (naming the points or segments) for a table that
        crosses itself or runs backwards.

        ``heads`` {Joint: head [m]} gives joint lines of `cut` their own hydraulic head: on the
        edges of such a joint (the faces of both its blocks) p = ρw·g·(head − y) replaces the
        table (water confined in that joint); with ``polyline`` None only those joints carry
        water.
        """
        if polyline is None and not heads:
            self.water = None
            return
        from .water import check_water_table

        resolved = []
        for jt, head in (heads or {}).items():
            if not isinstance(jt, Joint) or jt not in self.joints[1:]:
                raise ValueError(f"water heads: {jt!r} is not a joint line of the scene (give a Joint "
                                 f"the scene was cut with)")
            if isinstance(head, bool) or not isinstance(head, (int, float)) or not np.isfinite(head):
                raise ValueError(f"water heads: the head of {jt!r} must be a finite height [m], got {head!r}")
            resolved.append((self.joints.index(jt, 1), float(head)))
        self.water = check_water_table(polyline, density, tuple(resolved))

    def add_bolt(self, p1: Sequence[float], p2: Sequence[float], *, stiffness: float,
                 pretension: float = 0.0, capacity: float = float("inf")) -> int:
        """Add a rock bolt (Shi's bolt element) from ``p1`` to ``p2`` [m]: an axial spring of
        ``stiffness`` [N/m per m thickness] between the material point at ``p1`` of the block
        that holds it and the one at ``p2`` of another block, tensioned to ``pretension`` [N/m]
        at its initial length, breaking for good when its tension exceeds ``capacity`` [N/m]
        (inf: never). Tension positive. Forces are per metre of thickness (a row of bolts at
        spacing S, T each, is T/S). Returns the bolt's index. Raises ValueError naming the bolt
        for an end in no block, both ends in one block, or a negative or non-finite value.
        """
        import math

        k = len(self.bolts)
        name = f"bolt {k}"
        for what, v, lo in (("stiffness", stiffness, None), ("pretension", pretension, 0.0)):
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
                raise ValueError(f"{name}: {what} must be a finite number, got {v!r}")
        if stiffness <= 0:
            raise ValueError(f"{name}: stiffness must be > 0 N/m, got {stiffness!r}")
        if pretension < 0:
            raise ValueError(f"{name}: pretension must be >= 0 N/m (tension positive), got {pretension!r}")
        if isinstance(capacity, bool) or not isinstance(capacity, (int, float)) or math.isnan(capacity) \
                or capacity < 0:
            raise ValueError(f"{name}: capacity must be a number >= 0 N/m (inf: unbreakable), got {capacity!r}")
        if pretension > capacity:
            raise ValueError(f"{name}: pretension {pretension:g} N/m exceeds its capacity {capacity:g} N/m")
        ends = []
        for label, p in (("p1", p1), ("p2", p2)):
            q = np.asarray(p, dtype=float)
            if q.shape != (2,) or not np.all(np.isfinite(q)):
                raise ValueError(f"{name}: {label} must be a finite (x, y) pair, got {p!r}")
            ends.append(q)
        if np.hypot(*(ends[1] - ends[0])) == 0:
            raise ValueError(f"{name}: p1 and p2 are the same point {tuple(ends[0])!r}")
        found = [self._blocks_at(q) for q in ends]
        for label, q, ids in zip(("p1", "p2"), ends, found):
            if not ids:
                raise ValueError(f"{name}: end {label} ({q[0]:g}, {q[1]:g}) lies in no block")
        b1, b2 = _bolt_blocks(found[0], found[1])
        if b1 == b2:
            raise ValueError(f"{name}: both ends ({ends[0][0]:g}, {ends[0][1]:g}) and ({ends[1][0]:g}, "
                             f"{ends[1][1]:g}) lie in block {b1}; a bolt joins two blocks")
        from .water import BoltSpec

        self.bolts.append(BoltSpec(block1=b1, block2=b2, xy1=(float(ends[0][0]), float(ends[0][1])),
                                   xy2=(float(ends[1][0]), float(ends[1][1])), stiffness=float(stiffness),
                                   pretension=float(pretension), capacity=float(capacity)))
        return k

    def _blocks_at(self, q: np.ndarray) -> list[int]:
        """Blocks whose polygon holds the point (on an edge counts), interior ones first."""
        import shapely

        inside, edge = [], []
        pt = shapely.Point(q)
        for b, spec in enumerate(self.blocks):
            lo, hi = spec.vertices.min(axis=0), spec.vertices.max(axis=0)
            size = float(np.max(hi - lo))
            tol = 1e-9 * size
            if np.any(q < lo - tol) or np.any(q > hi + tol):
                continue
            poly = shapely.Polygon(spec.vertices)
            if poly.contains(pt):
                inside.append(b)
            elif poly.distance(pt) <= tol:
                edge.append(b)
        return inside + edge

    def set_ground_acceleration(self, fn) -> None:
        """Shake the ground: ``fn(t) -> (ax, ay)`` [m/s²], or a sampled record
        ``(times, accelerations)`` with times (n,) [s] and accelerations (n, 2) or (n,)
        (horizontal only), linearly interpolated and zero outside the record.

        Fixed blocks move with the ground; the simulation runs in the ground's frame, where
        every free block feels the inertial body force -ρ·a_g(t). All results (positions,
        velocities) are therefore relative to the ground.
        """
        if fn is None:
            self.ground_acceleration = None
            return
        if not callable(fn):
            fn = _sampled_record(fn)
        try:
            a0 = np.asarray(fn(0.0), dtype=float)
        except Exception as exc:  # noqa: BLE001
            raise ValueError(f"ground acceleration: fn(0.0) failed: {exc}") from None
        if a0.shape != (2,) or not np.all(np.isfinite(a0)):
            raise ValueError(f"ground acceleration: fn(t) must return a finite (ax, ay), got {a0!r} at t=0")
        self.ground_acceleration = fn


def _bolt_blocks(at1: list[int], at2: list[int]) -> tuple[int, int]:
    """Blocks of a bolt's ends: the first candidate of each, preferring two different blocks
    when an end lies on an edge shared by two."""
    for b1 in at1:
        for b2 in at2:
            if b1 != b2:
                return b1, b2
    return at1[0], at2[0]


def _sampled_record(record) -> Callable[[float], tuple[float, float]]:
    try:
        times, acc = record
    except (TypeError, ValueError):
        raise ValueError("ground acceleration: expected a function fn(t) -> (ax, ay) "
                         "or a (times, accelerations) record") from None
    t = np.asarray(times, dtype=float)
    a = np.asarray(acc, dtype=float)
    if a.ndim == 1:
        a = np.stack([a, np.zeros_like(a)], axis=1)
    if t.ndim != 1 or len(t) < 2 or a.shape != (len(t), 2):
        raise ValueError(f"ground acceleration record: times (n,) and accelerations (n, 2) or (n,) "
                         f"with n >= 2 expected, got {t.shape} and {np.shape(acc)}")
    if not (np.all(np.isfinite(t)) and np.all(np.isfinite(a)) and np.all(np.diff(t) > 0)):
        raise ValueError("ground acceleration record: times must be finite and strictly increasing, "
                         "accelerations finite")

    def fn(time: float) -> tuple[float, float]:
        return (float(np.interp(time, t, a[:, 0], left=0.0, right=0.0)),
                float(np.interp(time, t, a[:, 1], left=0.0, right=0.0)))

    fn.record = (t, a)  # type: ignore[attr-defined]
    return fn
