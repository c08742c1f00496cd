"""A scene's block system (docs/kgm/method.md §2.1, §2.5): `build_block_system` turns a
`ddatai.Scene` into a `kgm.BlockSystem` — its contacts from collinear overlapping edges of two
blocks, with the joint of each pair, the active forces (weight, constant point loads, water,
pseudo-static seismic load, bolts) and the fixed blocks. Scenes kgm cannot analyse statically
(a ground acceleration, loads that vary in time, overlapping blocks) are refused here, before any
work. `prepare` makes the `Problem` an analysis works on, once per entry point.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Optional

import numpy as np

from ddatai.geometry import MEMO_SCENE_VERTICES, check_overlaps, polygon_integrals
from ddatai.memo import GeometryMemo, key, scene_key

from .settings import Settings
from .system import CONTACT_GAP, DISTANCE_TOL, MIN_CONTACT, BlockSystem, cross


def build_block_system(scene, *, seismic=None, contact_gap: Optional[float] = None) -> BlockSystem:
    """Block-theory arrays of a `ddatai.Scene`: contacts from shared edges with their joint
    properties, active forces, fixed flags (docs/kgm/method.md §2.1, §2.5).

    The joint of a contact is, as in ddatai: the pair override ``scene.pair_joints[(a, b)]``,
    else the joint line the shared edges lie on (``BlockSpec.edge_joint``), else the default
    joint (index 0). Where the two edges name different joints, the one with the lower
    friction angle is used: ddatai applies each edge's joint to the contacts at the other
    block's vertices, so the segment carries both; limit equilibrium needs one value, and the
    weaker is the safe choice.

    Blocks with a fixed point are treated as fixed (the point holds them in DDA). Constant point
    loads are included in the active force. Limit equilibrium is static: a scene with a ground
    acceleration or a point load that varies with time is refused (ValueError); give the
    earthquake as the pseudo-static ``seismic`` = (kh, kv) instead.

    Water, bolts and the seismic coefficient (docs/method/water_bolts.md): the water force on
    each block's boundary, the active bolt forces (pretension) and the seismic force
    (kh·W, kv·W) — kh positive towards +x, kv positive upwards — join the active force and its
    moment; the passive bolt forces (capacity − pretension) are kept apart as a resistance.

    Contacts: anti-parallel edges of two blocks whose lines are at most ``contact_gap`` [m]
    apart (None: `CONTACT_GAP` × the model size) and that overlap along them by more than
    `MIN_CONTACT` × the model size. Blocks whose interiors overlap are refused (ValueError
    naming them), as ddatai refuses them.
    """
    specs = scene.blocks
    if not specs:
        raise ValueError("the scene has no blocks")
    if scene.ground_acceleration is not None:
        raise ValueError("kgm is a limit-equilibrium (static) analysis and cannot use the scene's ground "
                         "acceleration: give a pseudo-static seismic coefficient instead, "
                         "kgm.analyze(scene, seismic=(kh, kv)), on a scene without one "
                         "(scene.set_ground_acceleration(None))")
    for k, pt in enumerate(scene.point_loads):
        if callable(pt.force):
            raise ValueError(f"point load {k} on block {pt.block} varies with time: kgm is a static analysis "
                             f"and needs a constant (fx, fy); give the design value as a constant load")
    kh, kv = _check_seismic(seismic)
    if contact_gap is not None and (isinstance(contact_gap, bool) or not isinstance(contact_gap, (int, float)) or
                                    not np.isfinite(contact_gap) or contact_gap < 0):
        raise ValueError(f"contact_gap must be a finite distance >= 0 m, got {contact_gap!r}")
    # what depends on the scene's geometry alone is made once for the scenes that differ at most
    # in their joints' values (a study's samples: `ddatai.memo.scene_key`); the joints' part
    # is each scene's own
    small = sum(len(s.vertices) for s in specs) <= MEMO_SCENE_VERTICES
    k = scene_key(scene) if small else None
    args = (scene, kh, kv, None if contact_gap is None else float(contact_gap))
    part = dict(_geometry_part(*args) if k is None else _SYSTEMS.get((k, *args[1:]), lambda: _geometry_part(*args)))
    return _with_joints(scene, part)


def _geometry_part(scene, kh: float, kv: float, contact_gap: Optional[float]) -> tuple:
    """`build_block_system`'s fields that do not depend on the joints' values, as (name, value)
    pairs, with ``rows``: each contact's blocks and the joints of its two edges (ja, jb)."""
    specs = scene.blocks
    counts = np.array([len(s.vertices) for s in specs])
    offset = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
    xy = np.concatenate([s.vertices for s in specs]).astype(float)
    scale = float(np.max(np.ptp(xy, axis=0)))
    if contact_gap is None:
        contact_gap = CONTACT_GAP * scale
    check_overlaps(scene, what="kgm analyses blocks that touch, never overlap")
    nb = len(specs)
    integrals = polygon_integrals(xy, offset)
    area, centroid = integrals["area"], integrals["centroid"]
    density = np.array([s.material.density for s in specs])
    mass = density * area
    g = float(scene.gravity)
    force = np.zeros((nb, 2))
    force[:, 1] = -mass * g
    moment = centroid[:, 0] * force[:, 1] - centroid[:, 1] * force[:, 0]
    for pt in scene.point_loads:
        f = np.asarray(pt.force, dtype=float)
        force[pt.block] += f
        moment[pt.block] += pt.xy[0] * f[1] - pt.xy[1] * f[0]
    extra = {}
    if kh or kv:
        # pseudo-static seismic load k·W at each block's centroid
        # (docs/method/water_bolts.md, eq. S1)
        f = np.stack([kh * mass * g, kv * mass * g], axis=1)
        force += f
        moment += centroid[:, 0] * f[:, 1] - centroid[:, 1] * f[:, 0]
        extra["block_seismic"] = f
    if getattr(scene, "water", None) is not None:
        from ddatai.water import polygon_water_force

        edge_joint = np.concatenate([s.edge_joint for s in specs])
        f, m = polygon_water_force(xy, offset, scene.water, g, edge_joint)   # eq. W1–W2 on every boundary
        force += f
        moment += m
        extra["block_water"] = f
    if getattr(scene, "bolts", None):
        act, act_m, pas, pas_m = _bolt_forces(scene.bolts, nb)
        force += act
        moment += act_m
        extra["block_bolt"], extra["block_passive"], extra["block_passive_moment"] = act, pas, pas_m
    fixed = np.array([s.fixed for s in specs], dtype=bool)
    for pt in scene.fixed_points:
        fixed[pt.block] = True

    contacts = _find_contacts(specs, offset, xy, scale, max(float(contact_gap), DISTANCE_TOL * scale))
    rows = []
    for (a, b, ea, eb, s0, s1, sb0, sb1) in contacts:
        ja = int(specs[a].edge_joint[ea - offset[a]])
        jb = int(specs[b].edge_joint[eb - offset[b]])
        rows.append((a, b, ea, eb, s0, s1, sb0, sb1, ja, jb))
    c = len(rows)
    cb = np.array([(r[0], r[1]) for r in rows], dtype=np.int64).reshape(c, 2)
    edge = np.array([(r[2], r[3]) for r in rows], dtype=np.int64).reshape(c, 2)
    span = np.array([((r[4], r[5]), (r[6], r[7])) for r in rows], dtype=float).reshape(c, 2, 2)
    p0 = xy[edge[:, 0]] if c else np.zeros((0, 2))
    nxt = np.where(edge[:, 0] + 1 < offset[cb[:, 0] + 1], edge[:, 0] + 1, offset[cb[:, 0]]) if c else edge[:, 0]
    t = (xy[nxt] - p0) if c else np.zeros((0, 2))
    t = t / np.linalg.norm(t, axis=1, keepdims=True) if c else t
    start = p0 + span[:, 0, :1] * t if c else np.zeros((0, 2))
    end = p0 + span[:, 0, 1:] * t if c else np.zeros((0, 2))
    # block a's edge runs CCW, so its interior lies to the left: the left normal points into a
    normal = np.stack([-t[:, 1], t[:, 0]], axis=1) if c else np.zeros((0, 2))
    return tuple(dict(
        vertex_offset=offset, vertex_xy=xy, block_area=area, block_centroid=centroid,
        block_mass=mass, block_force=force, block_moment=moment, block_fixed=fixed,
        contact_blocks=cb, contact_start=start, contact_end=end, contact_normal=normal,
        contact_length=np.linalg.norm(end - start, axis=1) if c else np.zeros(0),
        contact_edge=edge, contact_span=span, gravity=g, scale=scale, seismic=(kh, kv),
        rows=[(r[0], r[1], r[8], r[9]) for r in rows], **extra).items())


def _with_joints(scene, part: dict) -> BlockSystem:
    """The block system of ``scene`` from its `_geometry_part`: each contact's joint and its
    strengths from the scene's joint table."""
    joints = scene.joints
    jidx = []
    for (a, b, ja, jb) in part.pop("rows"):
        key = (min(a, b), max(a, b))
        if key in scene.pair_joints:
            j = scene.pair_joints[key]
        elif ja >= 0 and jb >= 0 and ja != jb:
            j = ja if joints[ja].friction <= joints[jb].friction else jb
        elif ja >= 0 or jb >= 0:
            j = max(ja, jb)
        else:
            j = 0
        jidx.append(j)
    jidx = np.array(jidx, dtype=np.int64)
    return BlockSystem(
        contact_friction=np.array([joints[j].friction for j in jidx], dtype=float),
        contact_cohesion=np.array([joints[j].cohesion for j in jidx], dtype=float),
        contact_tensile=np.array([joints[j].tensile for j in jidx], dtype=float),
        contact_joint=jidx,
        contact_water=_contact_water(scene, part["contact_start"], part["contact_end"], jidx, part["gravity"])
        if "block_water" in part else None,
        contact_barton=_barton_law(joints, jidx), **part)


def _barton_law(joints, jidx: np.ndarray) -> Optional[np.ndarray]:
    """`BlockSystem.contact_barton` of the contacts' joints, None if none is Barton–Bandis."""
    from ddatai.params import BartonBandis

    if not any(isinstance(joints[j], BartonBandis) for j in set(jidx.tolist())):
        return None
    law = np.full((len(jidx), 5), np.nan)
    for k, j in enumerate(jidx.tolist()):
        jt = joints[j]
        if isinstance(jt, BartonBandis):
            law[k] = (jt.jrc, jt.jcs, jt.residual_friction, jt.max_friction, jt.reduction)
    return law


def _check_seismic(seismic) -> tuple[float, float]:
    """(kh, kv) from None, a number (kh) or a pair; ValueError for anything else."""
    if seismic is None:
        return 0.0, 0.0
    if isinstance(seismic, (int, float)) and not isinstance(seismic, bool):
        seismic = (seismic, 0.0)
    try:
        kh, kv = (float(v) for v in seismic)
    except (TypeError, ValueError):
        raise ValueError(f"seismic must be (kh, kv) or kh, got {seismic!r}") from None
    if not (math.isfinite(kh) and math.isfinite(kv)):
        raise ValueError(f"seismic coefficients must be finite, got {seismic!r}")
    if abs(kh) >= 1 or abs(kv) >= 1:
        raise ValueError(f"seismic coefficients are fractions of g, |k| < 1; got (kh, kv) = ({kh:g}, {kv:g})")
    return kh, kv


def _bolt_forces(bolts, nb: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Active force (pretension) and its moment about the origin, passive force (capacity
    beyond the pretension; none for an unbreakable bolt) and its moment, of the bolts on every
    block: each end is pulled towards the other (tension positive)."""
    act = np.zeros((nb, 2))
    mom = np.zeros(nb)
    pas = np.zeros((nb, 2))
    pas_m = np.zeros(nb)
    for b in bolts:
        p1, p2 = np.asarray(b.xy1), np.asarray(b.xy2)
        u = (p2 - p1) / np.hypot(*(p2 - p1))
        passive = b.capacity - b.pretension if math.isfinite(b.capacity) else 0.0
        for blk, p, sgn in ((b.block1, p1, 1.0), (b.block2, p2, -1.0)):
            f = sgn * b.pretension * u
            act[blk] += f
            mom[blk] += p[0] * f[1] - p[1] * f[0]
            fp = sgn * passive * u
            pas[blk] += fp
            pas_m[blk] += p[0] * fp[1] - p[1] * fp[0]
    return act, mom, pas, pas_m


def _contact_water(scene, start: np.ndarray, end: np.ndarray, joint: np.ndarray, g: float) -> np.ndarray:
    """∫p ds over every contact segment [N/m] (eq. W1), for the reports."""
    from ddatai.water import water_points

    table = scene.water
    edge, _, w = water_points(start, end, joint, table.xy, np.array(table.heads, float).reshape(-1, 2),
                              table.density * g)
    return np.bincount(edge, weights=w, minlength=len(start)).astype(float)


#: the joint-free part of the block systems of the scenes met last (`build_block_system`)
_SYSTEMS = GeometryMemo(16)

#: the edge contacts of the geometries met last (a study builds its scene again at each sample's
#: strength: the same polygons, the same contacts; `ddatai.memo`)
_CONTACTS = GeometryMemo(16)


def _find_contacts(specs, offset, xy, scale, gap) -> list[tuple]:
    """`_edge_contacts`, kept for the next call with the same vertices, scale and gap (a scene
    of at most ``ddatai.geometry.MEMO_SCENE_VERTICES``)."""
    if len(xy) > MEMO_SCENE_VERTICES:
        return _edge_contacts(specs, offset, xy, scale, gap)
    return _CONTACTS.get(key(np.ascontiguousarray(xy, dtype=np.float64), np.asarray(offset, np.int64),
                             float(scale), float(gap)),
                         lambda: _edge_contacts(specs, offset, xy, scale, gap))


def _edge_contacts(specs, offset, xy, scale, gap) -> list[tuple]:
    """Collinear (within ``gap`` [m]), oppositely directed, overlapping edge pairs of different
    blocks.

    Two CCW polygons that share a boundary traverse it in opposite directions. Returns rows
    (a, b, edge_a, edge_b, s0, s1, sb0, sb1): the overlap is [s0, s1] along a's edge and
    [sb0, sb1] along b's edge (distances from each edge's start) [m].
    """
    import shapely

    tol = gap
    lmin = MIN_CONTACT * scale
    polys = [shapely.Polygon(s.vertices) for s in specs]
    tree = shapely.STRtree(polys)
    ia, ib = tree.query(shapely.buffer(polys, tol), predicate="intersects")
    keep = ia < ib
    out = []
    for a, b in zip(ia[keep].tolist(), ib[keep].tolist()):
        pa = xy[offset[a]:offset[a + 1]]
        pb = xy[offset[b]:offset[b + 1]]
        qa, qb = np.roll(pa, -1, axis=0), np.roll(pb, -1, axis=0)
        la = np.linalg.norm(qa - pa, axis=1)
        lb = np.linalg.norm(qb - pb, axis=1)
        ta = (qa - pa) / la[:, None]
        tb = (qb - pb) / lb[:, None]
        # opposite directions; collinearity itself is decided by the end-point distances below
        anti = (ta @ tb.T) < -0.999
        # distances of b's edge ends from a's edge lines
        d0 = cross(ta[:, None, :], pb[None, :, :] - pa[:, None, :])
        d1 = cross(ta[:, None, :], qb[None, :, :] - pa[:, None, :])
        on_line = anti & (np.abs(d0) <= tol) & (np.abs(d1) <= tol)
        for i, j in zip(*np.nonzero(on_line)):
            s0 = float((pb[j] - pa[i]) @ ta[i])
            s1 = float((qb[j] - pa[i]) @ ta[i])
            lo, hi = max(0.0, min(s0, s1)), min(la[i], max(s0, s1))
            if hi - lo <= lmin:
                continue
            # the same segment along b's edge (b's edge runs the other way)
            pl, ph = pa[i] + lo * ta[i], pa[i] + hi * ta[i]
            u0, u1 = float((ph - pb[j]) @ tb[j]), float((pl - pb[j]) @ tb[j])
            out.append((a, b, int(offset[a] + i), int(offset[b] + j), lo, hi,
                        max(0.0, u0), min(lb[j], u1)))
    return out


# ---------------------------------------------------------------------- the problem
@dataclass(frozen=True, kw_only=True, eq=False)
class Problem:
    """What an analysis works on, made once per entry point (`prepare`): the scene, its block
    system (built with the settings' contact gap and the seismic load), the settings and the
    DDA parameters. Every stage after it — candidates, judges, search, report — takes it or its
    parts, so the system is never built twice and always belongs to its scene."""

    scene: Any
    """The `ddatai.Scene` analysed."""
    system: BlockSystem
    """Its block system."""
    settings: Settings = field(default_factory=Settings)
    """The analysis settings (`kgm.Settings`)."""
    params: Any = None
    """`ddatai.Params` of the DDA runs given to the entry point (`kgm.DdaSettings.params`, when
    set, takes precedence), or None."""

    @classmethod
    def of(cls, scene, system: BlockSystem, *, settings: Optional[Settings] = None, params=None) -> "Problem":
        """A problem of a scene and a system built from it elsewhere (the DDA judges' public
        functions take the two); ValueError when the system cannot be the scene's."""
        if not isinstance(system, BlockSystem):
            raise ValueError(f"system must be a kgm.BlockSystem, got {type(system).__name__}")
        if system.n_blocks != scene.n_blocks:
            raise ValueError(f"the block system has {system.n_blocks} blocks and the scene {scene.n_blocks}: "
                             "build the system from this scene (kgm.build_block_system)")
        return cls(scene=scene, system=system, settings=settings or Settings(), params=params)


def prepare(scene, *, settings: Optional[Settings] = None, params=None, seismic=None) -> Problem:
    """The `Problem` of an analysis, every input checked before any work: the scene (a
    `ddatai.Scene` with blocks), the settings (a `kgm.Settings`; None: defaults), the scene's
    block system with the seismic coefficients (kh, kv) or kh (`build_block_system`)."""
    from ddatai.scene import Scene

    settings = Settings() if settings is None else settings
    if not isinstance(settings, Settings):
        raise ValueError(f"settings must be a kgm.Settings, got {type(settings).__name__}")
    if not isinstance(scene, Scene):
        raise ValueError(f"scene must be a ddatai.Scene, got {type(scene).__name__}")
    if scene.n_blocks == 0:
        raise ValueError("the scene has no blocks")
    system = build_block_system(scene, seismic=seismic, contact_gap=settings.contact_gap)
    return Problem(scene=scene, system=system, settings=settings, params=params)
