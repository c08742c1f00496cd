"""Block theory on the blocks of a `ddatai.Scene` (docs/kgm/method.md §2).

`build_block_system` turns a scene into flat arrays: block areas, centroids, masses and active
forces, the **contacts** (segments shared by two blocks, found from collinear overlapping
edges, with the joint properties of that pair) and, on demand, the **free segments** (edge
parts that touch no block). On top of these:

* `removable_arc` – the half-circle test on contact normals (§2.2, computational form);
* `group_faces`, `is_removable` – the boundary contacts of a block or group and its joint
  pyramid;
* `rigid_modes` – the kinematic modes of a rigid block or group under its resultant (§2.4):
  lifting, single-face sliding, rotation about a vertex, each with its factor of safety;
* `classify_blocks` – the block types I–V of Goodman & Shi (§2.3).

Conventions (§1): x horizontal, y up, gravity −y; a contact's normal points **into** its first
block ``a`` (away from ``b``); a translation s of a block penetrates a neighbour across a
contact when s·n < 0 (n into the block). Everything here is NumPy and shapely only.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Iterable, Optional

import numpy as np

from ddatai.geometry import check_overlaps, polygon_integrals

from .kinds import ModeKind  # noqa: F401  (its home is kgm.kinds; kgm.blocks.ModeKind stays)

#: Two directions closer than this are the same face direction [rad]. Cut blocks have edges
#: parallel to ~1e-12 rad; hand-built scenes to the precision of their coordinates.
ANGLE_TOL = 1e-6
#: Points closer than this fraction of the model size are the same point; edges whose ends lie
#: this close to each other's line are collinear [-].
DISTANCE_TOL = 1e-6
#: Contacts shorter than this fraction of the model size are ignored (corner touches) [-].
MIN_CONTACT = 1e-5
#: Two anti-parallel edges whose lines are at most this fraction of the model size apart are in
#: contact (a gap of that size is drawing precision, not a separation): 1 mm in a 10 m model.
#: A block further from its neighbours is free of them; blocks that overlap are refused. ``build_block_system(scene, contact_gap=...)`` / ``Settings.contact_gap`` set
#: it in metres [-].
CONTACT_GAP = 1e-4
#: Fixed-point iteration on the normal forces of Barton–Bandis faces: at most this many
#: passes, stopped when tan φ(σn) changes by less than BARTON_TOL (docs/method/barton_bandis.md).
BARTON_ITERATIONS = 100
BARTON_TOL = 1e-12


@dataclass(frozen=True, kw_only=True, eq=False)
class BlockSystem:
    """Static block-theory data of a scene: blocks, contacts between them, their strengths.

    Block ids are the scene's block ids. Arrays are flat; contact k joins blocks
    ``contact_blocks[k] = (a, b)`` with a < b.
    """

    vertex_offset: np.ndarray
    """(B+1,) block b owns vertices ``vertex_offset[b]:vertex_offset[b+1]``."""
    vertex_xy: np.ndarray
    """(V, 2) CCW block vertices [m]."""
    block_area: np.ndarray
    """(B,) block areas [m²] (per m of thickness: volume [m³/m])."""
    block_centroid: np.ndarray
    """(B, 2) block centroids [m]."""
    block_mass: np.ndarray
    """(B,) block masses ρ·A [kg/m]."""
    block_force: np.ndarray
    """(B, 2) resultant active force of each block: weight plus constant point loads [N/m]."""
    block_moment: np.ndarray
    """(B,) moment of the active forces about the origin (0, 0), counter-clockwise positive
    [N·m/m]."""
    block_fixed: np.ndarray
    """(B,) bool: fixed in the scene, or pinned by a fixed point (type V, 'infinite')."""
    contact_blocks: np.ndarray
    """(C, 2) int64 blocks (a, b), a < b, sharing contact k."""
    contact_start: np.ndarray
    """(C, 2) first end of the shared segment [m]."""
    contact_end: np.ndarray
    """(C, 2) second end of the shared segment [m]."""
    contact_normal: np.ndarray
    """(C, 2) unit normal of the segment pointing into block a (away from b) [-]."""
    contact_length: np.ndarray
    """(C,) length of the shared segment [m]."""
    contact_friction: np.ndarray
    """(C,) friction angle φ of the joint [degrees]."""
    contact_cohesion: np.ndarray
    """(C,) cohesion c of the joint [Pa]."""
    contact_tensile: np.ndarray
    """(C,) tensile strength of the joint [Pa] (limit-equilibrium evaluators take it as 0,
    docs/kgm/method.md §1; the DDA evaluator uses it as given)."""
    contact_joint: np.ndarray
    """(C,) index of the contact's joint in the scene's joint table."""
    contact_edge: np.ndarray
    """(C, 2) global edge (start-vertex) index of the segment on block a and on block b."""
    contact_span: np.ndarray
    """(C, 2, 2) parameter interval [m from the edge start] of the segment along the edge of
    block a (row 0) and of block b (row 1)."""
    gravity: float
    """Gravitational acceleration [m/s²], acting in −y."""
    scale: float
    """Largest side of the model's bounding box [m]; tolerances are relative to it."""
    block_water: Optional[np.ndarray] = None
    """(B, 2) water force on each block's whole boundary [N/m] (included in ``block_force``),
    None without a water table (docs/method/water_bolts.md)."""
    block_seismic: Optional[np.ndarray] = None
    """(B, 2) pseudo-static seismic force (kh, kv)·W of each block [N/m] (included in
    ``block_force``), None without a seismic coefficient."""
    block_bolt: Optional[np.ndarray] = None
    """(B, 2) active bolt force (pretension) on each block [N/m] (included in
    ``block_force``), None without bolts."""
    block_passive: Optional[np.ndarray] = None
    """(B, 2) passive bolt force (capacity beyond the pretension) on each block [N/m]; a
    resistance, not in ``block_force``; None without bolts."""
    block_passive_moment: Optional[np.ndarray] = None
    """(B,) moment of the passive bolt forces about the origin (0, 0), counter-clockwise
    positive [N·m/m]; None without bolts."""
    contact_water: Optional[np.ndarray] = None
    """(C,) water force ∫p ds on each contact segment [N/m], None without a water table."""
    seismic: tuple = (0.0, 0.0)
    """Seismic coefficients (kh, kv) [-] the system was built with."""
    contact_barton: Optional[np.ndarray] = None
    """(C, 5) Barton–Bandis law of each contact's joint: JRC [-], JCS [Pa], φr [degrees], cap
    of the mobilised angle [degrees], strength reduction F [-]; JRC is NaN on a Mohr–Coulomb
    contact (whose ``contact_friction`` holds). None when no contact has one
    (docs/method/barton_bandis.md)."""

    # ------------------------------------------------------------------ basic queries
    @property
    def n_blocks(self) -> int:
        return len(self.block_fixed)

    @property
    def n_contacts(self) -> int:
        return len(self.contact_length)

    def polygon(self, block: int) -> np.ndarray:
        """(n, 2) CCW vertices of a block [m]."""
        return self.vertex_xy[self.vertex_offset[block]:self.vertex_offset[block + 1]]

    def contacts_of(self, block: int) -> np.ndarray:
        """Indices of the contacts of a block."""
        cb = self.contact_blocks
        return np.flatnonzero((cb[:, 0] == block) | (cb[:, 1] == block))

    def neighbours(self, blocks: Iterable[int], removed: frozenset = frozenset()) -> set[int]:
        """Blocks (fixed ones included) sharing a contact with any of ``blocks``, except the
        blocks themselves and removed blocks."""
        members = set(blocks)
        cb = self.contact_blocks
        ina = np.isin(cb[:, 0], list(members))
        inb = np.isin(cb[:, 1], list(members))
        out = set(cb[ina & ~inb, 1].tolist()) | set(cb[inb & ~ina, 0].tolist())
        return out - set(removed)

    def with_strength(self, *, friction: Optional[float] = None, reduction: float = 1.0) -> "BlockSystem":
        """The same system with every joint's friction angle set to ``friction`` [degrees]
        (cohesion held), and/or tanφ and c divided by ``reduction`` (strength reduction,
        docs/kgm/method.md §4.6)."""
        phi = self.contact_friction if friction is None else np.full(self.n_contacts, float(friction))
        tan_phi = np.tan(np.radians(phi)) / reduction
        barton = self.contact_barton
        if barton is not None:
            # a set friction angle replaces every law; a reduction divides tan φ(σn) too
            barton = None if friction is not None else barton * np.array([1, 1, 1, 1, reduction])
        return replace(self, contact_friction=np.degrees(np.arctan(tan_phi)),
                       contact_cohesion=self.contact_cohesion / reduction, contact_barton=barton)

    def tan_friction(self, contacts: np.ndarray, sigma_n) -> np.ndarray:
        """Friction coefficient of each of ``contacts`` at the normal stress ``sigma_n`` [Pa]
        (a number or one per contact): tan φ of a Mohr–Coulomb joint; tan φ(σn)/F of a
        Barton–Bandis one, φ(σn) = φr + JRC·log10(JCS/σn) bounded to [φr, cap] (σn ≤ 0 takes
        the cap; docs/method/barton_bandis.md, eq. BB1)."""
        contacts = np.asarray(contacts, dtype=np.int64)
        out = np.tan(np.radians(self.contact_friction[contacts]))
        if self.contact_barton is None:
            return out
        law = self.contact_barton[contacts]
        bb = ~np.isnan(law[:, 0])
        if bb.any():
            jrc, jcs, phir, cap, red = law[bb].T
            sigma = np.broadcast_to(np.asarray(sigma_n, dtype=float), contacts.shape)[bb]
            with np.errstate(divide="ignore", invalid="ignore"):
                phi = phir + jrc * np.log10(jcs / sigma)
            phi = np.where(sigma > 0, np.clip(phi, phir, cap), np.where(jrc > 0, cap, phir))  # σn → 0: the limit
            out[bb] = np.tan(np.radians(phi)) / red
        return out

    def face_tan(self, contacts: np.ndarray, normal_force: float) -> float:
        """Length-weighted friction coefficient of pooled contacts carrying ``normal_force``
        [N/m] at a uniform normal stress σn = N/ΣL (eq. BB4)."""
        length = self.contact_length[contacts]
        total = float(length.sum())
        sigma = max(float(normal_force), 0.0) / total if total > 0 else 0.0
        return float((self.tan_friction(contacts, sigma) * length).sum() / max(total, 1e-300))

    def face_tan_function(self, contacts: np.ndarray):
        """`face_tan` of these contacts as a function of the normal force [N/m], for the
        fixed-point iterations that call it many times (plain floats, the law of eq. BB1)."""
        contacts = np.asarray(contacts, dtype=np.int64)
        length = self.contact_length[contacts]
        total = float(length.sum())
        weight = (length / max(total, 1e-300)).tolist()
        tan_mc = np.tan(np.radians(self.contact_friction[contacts])).tolist()
        rows = (self.contact_barton[contacts].tolist() if self.contact_barton is not None
                else [[math.nan] * 5] * len(weight))
        # the Mohr–Coulomb contacts' share is constant; the Barton–Bandis ones follow σn
        fixed = sum(w * t for w, t, row in zip(weight, tan_mc, rows) if math.isnan(row[0]))
        law = [(w, *row) for w, row in zip(weight, rows) if not math.isnan(row[0])]

        def tan_at(normal_force: float) -> float:
            sigma = max(float(normal_force), 0.0) / total if total > 0 else 0.0
            out = fixed
            for w, jrc, jcs, phir, cap, red in law:
                if sigma > 0:
                    phi = min(max(phir + jrc * math.log10(jcs / sigma), phir), cap)
                else:
                    phi = cap if jrc > 0 else phir
                out += w * math.tan(math.radians(phi)) / red
            return out
        return tan_at

    def free_length(self, block: int, removed: frozenset = frozenset()) -> float:
        """Length of the block's boundary that touches no (remaining) block [m]."""
        return float(sum(np.linalg.norm(e - s) for s, e in self.free_segments(block, removed)))

    def free_segments(self, block: int, removed: frozenset = frozenset()) -> list[tuple[np.ndarray, np.ndarray]]:
        """Edge parts of a block exposed to air: not covered by a contact with a block that is
        still there. Contacts with removed blocks become free faces (docs/kgm/method.md §3.3)."""
        lo, hi = self.vertex_offset[block], self.vertex_offset[block + 1]
        xy = self.vertex_xy[lo:hi]
        covered: dict[int, list[tuple[float, float]]] = {}
        for k in self.contacts_of(block):
            a, b = self.contact_blocks[k]
            other = b if a == block else a
            if other in removed:
                continue
            side = 0 if a == block else 1
            e = int(self.contact_edge[k, side])
            covered.setdefault(e, []).append(tuple(self.contact_span[k, side]))
        tol = MIN_CONTACT * self.scale
        out = []
        for i in range(hi - lo):
            p, q = xy[i], xy[(i + 1) % (hi - lo)]
            length = float(np.linalg.norm(q - p))
            t = (q - p) / length
            pos = 0.0
            for s0, s1 in sorted(covered.get(lo + i, [])):
                if s0 - pos > tol:
                    out.append((p + pos * t, p + s0 * t))
                pos = max(pos, s1)
            if length - pos > tol:
                out.append((p + pos * t, q.copy()))
        return out


# ---------------------------------------------------------------------- building
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
    counts = np.array([len(s.vertices) for s in specs])
    offset = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
    xy = np.concatenate([s.vertices for s in specs]).astype(float)
    scale = float(np.max(np.ptp(xy, axis=0)))
    if contact_gap is None:
        contact_gap = CONTACT_GAP * scale
    elif isinstance(contact_gap, bool) or not isinstance(contact_gap, (int, float)) or \
            not np.isfinite(contact_gap) or contact_gap < 0:
        raise ValueError(f"contact_gap must be a finite distance >= 0 m, got {contact_gap!r}")
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
    joints = scene.joints
    rows = []
    for (a, b, ea, eb, s0, s1, sb0, sb1) in contacts:
        ja = int(specs[a].edge_joint[ea - offset[a]])
        jb = int(specs[b].edge_joint[eb - offset[b]])
        key = (min(a, b), max(a, b))
        if key in scene.pair_joints:
            j = scene.pair_joints[key]
        elif ja >= 0 and jb >= 0 and ja != jb:
            j = ja if joints[ja].friction <= joints[jb].friction else jb
        elif ja >= 0 or jb >= 0:
            j = max(ja, jb)
        else:
            j = 0
        rows.append((a, b, ea, eb, s0, s1, sb0, sb1, j))
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
    jidx = np.array([r[8] for r in rows], dtype=np.int64)
    return BlockSystem(
        vertex_offset=offset, vertex_xy=xy, block_area=area, block_centroid=centroid,
        block_mass=mass, block_force=force, block_moment=moment, block_fixed=fixed,
        contact_blocks=cb, contact_start=start, contact_end=end, contact_normal=normal,
        contact_length=np.linalg.norm(end - start, axis=1) if c else np.zeros(0),
        contact_friction=np.array([joints[j].friction for j in jidx], dtype=float),
        contact_cohesion=np.array([joints[j].cohesion for j in jidx], dtype=float),
        contact_tensile=np.array([joints[j].tensile for j in jidx], dtype=float),
        contact_joint=jidx, contact_edge=edge, contact_span=span, gravity=g, scale=scale,
        contact_water=_contact_water(scene, start, end, jidx, g) if "block_water" in extra else None,
        seismic=(kh, kv), contact_barton=_barton_law(joints, jidx), **extra)


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


def _find_contacts(specs, offset, xy, scale, gap) -> list[tuple]:
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
        d0 = _cross(ta[:, None, :], pb[None, :, :] - pa[:, None, :])
        d1 = _cross(ta[:, None, :], qb[None, :, :] - pa[:, None, :])
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


def _cross(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    return u[..., 0] * v[..., 1] - u[..., 1] * v[..., 0]


# ---------------------------------------------------------------------- faces of a group
@dataclass(frozen=True, kw_only=True, eq=False)
class GroupFaces:
    """Contacts of a group (a block or a set of blocks) split into boundary and internal ones."""

    boundary: np.ndarray
    """Indices of the contacts between a member and a remaining non-member."""
    boundary_normal: np.ndarray
    """(m, 2) unit normals of those contacts pointing into the group [-]."""
    boundary_member: np.ndarray
    """(m,) the member block of each boundary contact."""
    boundary_other: np.ndarray
    """(m,) the non-member block of each boundary contact."""
    internal: np.ndarray
    """Indices of the contacts between two members."""


def check_group(system: BlockSystem, blocks, *, removed: frozenset = frozenset(),
                what: str = "group") -> frozenset:
    """Validate a group of block ids: non-empty, known, free (not fixed), not removed.
    Returns it as a frozenset; raises ValueError naming the offending block."""
    try:
        ids = list(blocks)
    except TypeError:
        raise ValueError(f"{what} must be an iterable of block ids, got {blocks!r}") from None
    if not ids:
        raise ValueError(f"{what} is empty: give at least one block id")
    out = set()
    for b in ids:
        if isinstance(b, (bool, np.bool_)) or not isinstance(b, (int, np.integer)):
            raise ValueError(f"{what}: block id must be an integer, got {b!r}")
        if not 0 <= int(b) < system.n_blocks:
            raise ValueError(f"{what}: unknown block id {b} (the scene has {system.n_blocks} blocks)")
        if system.block_fixed[int(b)]:
            raise ValueError(f"{what}: block {b} is fixed; a key group holds only free blocks")
        if int(b) in removed:
            raise ValueError(f"{what}: block {b} has been removed")
        out.add(int(b))
    return frozenset(out)


def is_connected(system: BlockSystem, blocks: frozenset) -> bool:
    """Whether the blocks form one connected set through shared contacts (§3.2, condition 5)."""
    blocks = set(blocks)
    start = next(iter(blocks))
    seen, todo = {start}, [start]
    while todo:
        b = todo.pop()
        for nb in system.neighbours([b]):
            if nb in blocks and nb not in seen:
                seen.add(nb)
                todo.append(nb)
    return seen == blocks


def group_faces(system: BlockSystem, blocks: frozenset, removed: frozenset = frozenset()) -> GroupFaces:
    """Boundary and internal contacts of a group; contacts with removed blocks are free."""
    cb = system.contact_blocks
    members = np.array(sorted(blocks), dtype=np.int64)
    gone = np.array(sorted(removed), dtype=np.int64)
    ina, inb = np.isin(cb[:, 0], members), np.isin(cb[:, 1], members)
    alive = ~(np.isin(cb[:, 0], gone) | np.isin(cb[:, 1], gone))
    bnd = np.flatnonzero(alive & (ina ^ inb))
    internal = np.flatnonzero(alive & ina & inb)
    sign = np.where(ina[bnd], 1.0, -1.0)
    return GroupFaces(boundary=bnd, boundary_normal=system.contact_normal[bnd] * sign[:, None],
                      boundary_member=np.where(ina[bnd], cb[bnd, 0], cb[bnd, 1]),
                      boundary_other=np.where(ina[bnd], cb[bnd, 1], cb[bnd, 0]),
                      internal=internal)


# ---------------------------------------------------------------------- removability
def removable_arc(normals: np.ndarray, tol: float = ANGLE_TOL) -> Optional[tuple[tuple[float, float], ...]]:
    """Joint pyramid of a block or group in 2D (docs/kgm/method.md §2.2, computational form).

    ``normals`` (m, 2) are the contact normals pointing into the block. The admissible
    translations are JP = {s : s·n_k ≥ 0 for all k}; each condition is a half-circle of
    directions, so JP is not empty if and only if all normals lie in a closed half-circle,
    i.e. the largest circular gap between their angles is ≥ π.

    Returns None when the block is not removable, else the arcs of admissible directions as
    (start, width) [rad] (directions start ... start + width counter-clockwise): one arc of
    width π − (spread of the normals), or 2π with no contacts; two arcs of width 0 (both
    directions of a line) when the normals point two exactly opposite ways (a slot).
    """
    normals = np.asarray(normals, dtype=float).reshape(-1, 2)
    if len(normals) == 0:
        return ((-math.pi, 2.0 * math.pi),)
    th = np.sort(np.arctan2(normals[:, 1], normals[:, 0]))
    gaps = np.diff(np.append(th, th[0] + 2.0 * math.pi))
    order = np.argsort(gaps)[::-1]
    k = int(order[0])
    if gaps[k] < math.pi - tol:
        return None
    # the normals span the arc from th[k+1] (min) counter-clockwise to th[k] (max)
    th_min, th_max = th[(k + 1) % len(th)], th[k]
    spread = (th_max - th_min) % (2.0 * math.pi)
    if spread > math.pi:  # all normals equal up to round-off (th_max a hair below th_min)
        spread = 0.0
    if len(th) > 1 and gaps[order[1]] >= math.pi - tol:
        # two gaps of π: normals in exactly two opposite directions, JP is a line
        return ((_wrap(th_max - 0.5 * math.pi), 0.0), (_wrap(th_max + 0.5 * math.pi), 0.0))
    return ((_wrap(th_max - 0.5 * math.pi), max(math.pi - spread, 0.0)),)


def _wrap(a: float) -> float:
    return (a + math.pi) % (2.0 * math.pi) - math.pi


def is_removable(system: BlockSystem, blocks: frozenset, removed: frozenset = frozenset()) -> bool:
    """A finite block or group is removable if its joint pyramid is not empty (§2.2): the
    half-circle test on the normals of its contacts with the remaining blocks."""
    faces = group_faces(system, blocks, removed)
    return removable_arc(faces.boundary_normal) is not None


def has_free_face(system: BlockSystem, blocks: Iterable[int], removed: frozenset = frozenset()) -> bool:
    """Whether any member has a free segment (an edge part exposed to air)."""
    return any(system.free_segments(b, removed) for b in blocks)


# ---------------------------------------------------------------------- rigid modes
@dataclass(frozen=True, kw_only=True, eq=False)
class Mode:
    """A failure mode of a block or group and what it needs to hold (docs/kgm/method.md §2.4, §5.2)."""

    kind: ModeKind
    """Lifting, sliding, rotation, Sarma mechanism or none."""
    fs: float
    """Factor of safety of this mode [-] (inf: cannot fail this way)."""
    critical_friction: float
    """Friction angle of all joints (cohesion held) at which this mode reaches limit
    equilibrium [degrees]; 0 if cohesion alone holds it, 90 if no friction angle does
    (lifting, toppling)."""
    sliding_contacts: np.ndarray
    """Indices of the boundary contacts that slide (the failure surface) [-]."""
    sheared_contacts: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    """Indices of the internal contacts that shear (Sarma mechanisms only)."""
    direction: Optional[np.ndarray] = None
    """(2,) unit sliding direction of a rigid translation [-]."""
    pivot: Optional[np.ndarray] = None
    """(2,) rotation centre of a toppling mode [m]."""
    block_velocity: Optional[dict] = None
    """Relative velocity (2,) of every member in a Sarma mechanism, normalised to max 1 [-]."""
    critical_acceleration: Optional[float] = None
    """Sarma's K_c: horizontal acceleration (in g, toward the direction of motion) that brings
    the mode to limit equilibrium at the actual strength; < 0 means unstable under gravity
    alone [-]."""
    block_modes: Optional[tuple] = None
    """Block toppling only: the Goodman–Bray recursion at limit equilibrium (strength reduced
    by FS), one `kgm.toppling.BlockStep` per member (stable, toppling or sliding, with its
    forces), top block first."""


def rigid_modes(system: BlockSystem, blocks: frozenset, removed: frozenset = frozenset(),
                rejected: Optional[list] = None) -> list[Mode]:
    """Admissible modes of the group glued into one rigid body under its resultant
    (docs/kgm/method.md §2.4 and §4; the original KGM evaluator).

    * lifting: the resultant r opens every contact (r·n_k > 0): FS = 0;
    * sliding on face i (contacts sharing one normal direction, pooled): r presses on it and
      its projection s on the face penetrates no other contact: FS = (Σ c·L + N' tanφ)/T with
      N' = −r·n_i and T = r·s (§4.2, force ratio = strength-reduction FS for one plane);
    * rotation about a vertex V of the contact set: the rigid rotation makes no contact point
      penetrate and the moment of r about V drives it (§4.5): FS = 0, as faces that open carry
      no tension.

    Returns every admissible mode (an empty list: no mode, the group is stable by geometry);
    ``rejected``, a list, receives one line saying why the faces and pivots tried are not
    admissible.
    """
    faces = group_faces(system, blocks, removed)
    members = np.array(sorted(blocks))
    r = system.block_force[members].sum(axis=0)
    m0 = float(system.block_moment[members].sum())
    rnorm = float(np.hypot(*r))
    if rnorm == 0.0:
        return []
    # passive bolt force: a resistance mobilised by the motion (docs/method/water_bolts.md, B2)
    passive = (system.block_passive[members].sum(axis=0) if system.block_passive is not None
               else np.zeros(2))
    n = faces.boundary_normal
    idx = faces.boundary
    modes: list[Mode] = []
    rn = n @ r
    if len(idx) == 0 or np.all(rn > ANGLE_TOL * rnorm):
        d = r / rnorm
        modes.append(Mode(kind=ModeKind.LIFTING, fs=max(-float(passive @ d), 0.0) / rnorm,
                          critical_friction=90.0, sliding_contacts=np.zeros(0, np.int64), direction=d))
        return modes
    if np.all(rn >= -ANGLE_TOL * rnorm):
        # r lies on the edge of the joint pyramid: the group moves along r, sliding without
        # normal force on the contacts parallel to r (e.g. down a vertical slot); only their
        # cohesion (and passive bolts) resist (§4.2 with N' = 0)
        k = idx[np.abs(rn) <= ANGLE_TOL * rnorm]
        cl = float((system.contact_cohesion[k] * system.contact_length[k]).sum()) - float(passive @ (r / rnorm))
        modes.append(Mode(kind=ModeKind.SLIDING, fs=cl / rnorm, critical_friction=90.0 if cl < rnorm else 0.0,
                          sliding_contacts=k, direction=r / rnorm))
        return modes
    # faces: contacts grouped by normal direction (parallel faces slide together, §2.4 item 2)
    not_pressed, cut_in = 0, []
    for face in _parallel_sets(n):
        ni = n[face[0]]
        normal_force = -float(r @ ni)
        if normal_force <= ANGLE_TOL * rnorm:
            not_pressed += 1
            continue
        s = r + normal_force * ni
        snorm = float(np.hypot(*s))
        if snorm <= ANGLE_TOL * rnorm:
            not_pressed += 1
            continue  # r is normal to the face: no driving shear
        s /= snorm
        others = np.setdiff1d(np.arange(len(idx)), face)
        into = others[n[others] @ s < -ANGLE_TOL]
        if len(into):
            dip = math.degrees(math.atan2(-ni[0], ni[1]))  # the face's dip, + toward +x
            cut_in.append(f"on the face dipping {abs(dip):.0f}° would cut into block "
                          f"{int(faces.boundary_other[into[0]])}")
            continue
        k = idx[face]
        # B2: the passive force's normal part presses the face (N' grows by −P·n), its part
        # against the motion (−P·s) adds to the resisting shear
        fs, phi_c = _sliding_fs(system, k, normal_force - float(passive @ ni), snorm,
                                resisting=-float(passive @ s))
        kc = _sliding_kc(system, members, k, ni, s, r + passive)
        modes.append(Mode(kind=ModeKind.SLIDING, fs=fs, critical_friction=phi_c, sliding_contacts=k,
                          direction=s, critical_acceleration=kc))
    held = None
    if system.block_passive_moment is not None:
        held = (passive, float(system.block_passive_moment[members].sum()))
    found = _toppling_pivot(system, idx, n, r, m0, held)
    if found is not None:
        pivot, fs_rot = found
        modes.append(Mode(kind=ModeKind.ROTATION, fs=fs_rot, critical_friction=90.0 if fs_rot < 1.0 else 0.0,
                          sliding_contacts=np.zeros(0, np.int64), pivot=pivot))
    if rejected is not None:
        why = [f"sliding {c}" for c in cut_in]
        if not_pressed:
            why.append(f"{not_pressed} face(s) not pressed by the resultant")
        if found is None:
            why.append("no pivot about which it can rotate")
        rejected.append(("rigid (one body): " if len(members) > 1 else "rigid: ") + "; ".join(why))
    return modes


def _parallel_sets(normals: np.ndarray) -> list[np.ndarray]:
    """Indices of the normals grouped by direction (within ANGLE_TOL)."""
    th = np.arctan2(normals[:, 1], normals[:, 0])
    out: list[list[int]] = []
    dirs: list[float] = []
    for i, a in enumerate(th):
        for g, d in enumerate(dirs):
            if abs(_wrap(a - d)) <= ANGLE_TOL:
                out[g].append(i)
                break
        else:
            dirs.append(a)
            out.append([i])
    return [np.array(g) for g in out]


def _sliding_fs(system: BlockSystem, contacts: np.ndarray, normal_force: float, shear: float,
                resisting: float = 0.0) -> tuple[float, float]:
    """FS and critical friction angle of rigid sliding on pooled contacts (§4.2, §4.6), with
    a resisting shear of passive bolts ``resisting`` [N/m] (B2).

    The normal force is spread over the pooled segments in proportion to their lengths
    (uniform normal stress), so the face's friction is the length-weighted mean of tanφ.
    """
    length = system.contact_length[contacts]
    cl = float((system.contact_cohesion[contacts] * length).sum())
    normal_force = max(normal_force, 0.0)
    # Barton–Bandis: the friction of the face's own normal stress N'/ΣL, which rigid sliding
    # fixes whatever the strength, so FS is the force ratio at it (eq. BB4–BB5)
    tan_phi = system.face_tan(contacts, normal_force)
    fs = (cl + normal_force * tan_phi + resisting) / shear
    # tan φc = (T − c·L − P_s)/N'  (§4.6); 0 if cohesion (and bolts) alone hold the face
    excess = shear - cl - resisting
    tan_c = excess / normal_force if normal_force > 0 else (math.inf if excess > 0 else 0.0)
    return fs, (float(np.degrees(np.arctan(tan_c))) if tan_c > 0 else 0.0)


def _sliding_kc(system: BlockSystem, members: np.ndarray, contacts: np.ndarray, n: np.ndarray,
                s: np.ndarray, r: np.ndarray) -> float:
    """Sarma's critical acceleration of a rigid sliding mode (§5.2 with one block):
    r + K·W·e + N·n − (c·L + N tanφ)·s = 0, e horizontal toward the motion; solved for N, K."""
    weight = float(system.block_mass[members].sum()) * system.gravity
    e = np.array([1.0 if s[0] >= 0 else -1.0, 0.0])
    length = system.contact_length[contacts]
    cl = float((system.contact_cohesion[contacts] * length).sum())
    tan_phi = system.face_tan(contacts, -float(r @ n))
    for _ in range(BARTON_ITERATIONS if system.contact_barton is not None else 1):
        a = np.column_stack([n - tan_phi * s, weight * e])
        try:
            sol = np.linalg.solve(a, -r + cl * s)
        except np.linalg.LinAlgError:
            return float("nan")
        if system.contact_barton is None:
            break
        # Barton–Bandis: N depends on K; iterate tan φ(N/ΣL) to its fixed point (eq. BB6)
        new = system.face_tan(contacts, float(sol[0]))
        if abs(new - tan_phi) <= BARTON_TOL * (1.0 + abs(tan_phi)):
            break
        tan_phi = new
    return float(sol[1])


def _toppling_pivot(system: BlockSystem, idx: np.ndarray, n: np.ndarray, r: np.ndarray,
                    m0: float, passive: Optional[tuple] = None) -> Optional[tuple[np.ndarray, float]]:
    """A vertex V of the contact set about which the rigid rotation is admissible (no contact
    end point moves into its neighbour) and driven by the moment of r (§4.5), with its factor
    of safety FS_rot = M_resisting/|M_V|; or None. Faces that open carry nothing, so only
    passive bolts resist (``passive`` = their resultant P and moment about the origin M_P;
    docs/method/water_bolts.md, B2): M_resisting = −sign(ω)·(M_P − V × P). Without them every
    admissible pivot has FS 0 and the first is returned; with them, the least safe."""
    if len(idx) == 0:
        return None
    ends = np.concatenate([system.contact_start[idx], system.contact_end[idx]])
    normals = np.concatenate([n, n])
    tol = DISTANCE_TOL * system.scale
    rnorm = float(np.hypot(*r))
    candidates = _unique_points(ends, tol)
    best = None
    for v in candidates:
        moment = m0 - (v[0] * r[1] - v[1] * r[0])  # moment of r about V
        if abs(moment) <= 1e-9 * rnorm * system.scale:
            continue
        omega = 1.0 if moment > 0 else -1.0
        d = ends - v
        vel = omega * np.stack([-d[:, 1], d[:, 0]], axis=1)
        if np.all((vel * normals).sum(axis=1) >= -tol):
            fs = 0.0
            if passive is not None:
                p, mp = passive
                fs = max(-omega * (mp - (v[0] * p[1] - v[1] * p[0])), 0.0) / abs(moment)
            if best is None or fs < best[1]:
                best = (v, fs)
            if fs == 0.0:
                break
    return best


def _unique_points(p: np.ndarray, tol: float) -> np.ndarray:
    out: list[np.ndarray] = []
    for q in p:
        if not any(np.hypot(*(q - o)) <= tol for o in out):
            out.append(q)
    return np.array(out)


# ---------------------------------------------------------------------- block types
BLOCK_TYPES = ("I", "II", "III", "IV", "V")


def block_type(system: BlockSystem, block: int, removed: frozenset = frozenset(),
               modes: Optional[list[Mode]] = None) -> str:
    """Goodman–Shi type of one block (docs/kgm/method.md §2.3) from block theory (rigid modes):

    V fixed (infinite); IV not removable (tapered or locked, or no free face); III removable
    with no failure mode under its resultant; II removable with a mode and FS ≥ 1; I key block
    (FS < 1).
    """
    if system.block_fixed[block]:
        return "V"
    g = frozenset([block])
    if not has_free_face(system, g, removed) or not is_removable(system, g, removed):
        return "IV"
    modes = rigid_modes(system, g, removed) if modes is None else modes
    if not modes:
        return "III"
    return "I" if min(m.fs for m in modes) < 1.0 else "II"


def classify_blocks(system: BlockSystem, removed: frozenset = frozenset()) -> dict[int, str]:
    """Type I–V of every remaining block (removed blocks are left out)."""
    return {b: block_type(system, b, removed) for b in range(system.n_blocks) if b not in removed}
