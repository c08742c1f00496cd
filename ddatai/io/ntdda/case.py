"""From the files to a run: ntdda's block cutting and points in blocks, the `NtddaCase` (scene,
parameters, duration or steps), and the measured-points CSV (docs/ntdda.md §2, §5)."""

from __future__ import annotations

import math
import warnings

import numpy as np

from dataclasses import dataclass, replace
from pathlib import Path
from typing import Literal, Optional
from .geometry import cut_segments
from .placement import BlockLocator, block_materials, blocks_inside_other_blocks, clip_fixed_line, ntdda_fixed_points
from ...params import Joint, Material, Params, UnitWarning
from ...scene import Scene
from .records import (NTDDA_GRAVITY, NtddaAnalysis, NtddaBlockMaterial, NtddaFormatError,
                      NtddaGeometry, NtddaQuirkWarning, NtddaWarning, _RATIO_TOL)
from .text import _warn
from .readers import read_ntdda_analysis, read_ntdda_geometry

# ============================================================================ blocks and points
@dataclass(frozen=True, kw_only=True, eq=False)
class NtddaBlocks:
    """A geometry file's blocks and points after ntdda's block cutting and ddatai's rules."""

    polygons: tuple
    """Per block, (n, 2) CCW vertices [length], in ntdda's block order."""
    edge_type: tuple
    """Per block, (n,) joint type (1-based) of each edge, vertex k -> k+1."""
    material: np.ndarray
    """(B,) block material (1-based) from the material lines; 1 by default."""
    w0: float
    """ntdda's domain scale of the joint lines [length]."""
    fixed_block: np.ndarray
    """(nf,) block of each fixed point."""
    fixed_xy: np.ndarray
    """(nf, 2) fixed points [length] (ddatai's rule for fixed lines, docs/guide/ntdda_files.md)."""
    load_block: np.ndarray
    """(nl,) block of each load point."""
    measured_block: np.ndarray
    """(nm,) block of each measured point."""
    warnings: tuple = ()
    """Warning messages issued while cutting and placing points."""


def cut_ntdda_geometry(geometry: NtddaGeometry) -> NtddaBlocks:
    """Cut the blocks and place the points of an ntdda geometry.

    ntdda's order of operations is kept where it decides the result (cutting, then hole
    points, then material lines); the documented choices are: blocks lying inside other blocks
    are deleted before points are located (ntdda deletes them after, leaving points on deleted
    blocks), and fixed lines pin each block they cross at both ends of the line's piece inside
    it (docs/ntdda.md §4.8; ntdda's rule is in ``_fixed_points``).
    """
    g = geometry
    log: list[str] = []
    try:
        cut = cut_segments(g.joints, edge_node_distance=g.edge_node_distance,
                           n_boundary=g.n_boundary_lines)
    except ValueError as exc:
        raise NtddaFormatError(f"{g.path}: {exc}") from None
    polygons = list(cut.polygons)
    edge_type = [g.joint_type[lines] for lines in cut.edge_line]
    w0 = cut.w0

    # hole points delete the first block containing them (dc11)
    doomed = set()
    locator = BlockLocator(polygons, w0)
    for k, xy in enumerate(g.hole_points):
        b = locator.locate(xy)
        if b < 0:
            _warn(log, NtddaWarning, f"{g.path}, {g.hole_where[k]}: hole point ({xy[0]:g}, {xy[1]:g}) "
                  "lies outside every block; ignored")
        else:
            doomed.add(b)
    keep = [b for b in range(len(polygons)) if b not in doomed]
    polygons, edge_type = [polygons[b] for b in keep], [edge_type[b] for b in keep]
    if not polygons:
        raise NtddaFormatError(f"{g.path}: the hole points delete every block")

    # loops of joints not connected to the rest: ntdda's blocks have no holes, so the
    # surrounding block keeps its whole outline and the inner blocks are deleted (dc16)
    inner = blocks_inside_other_blocks(polygons)
    if inner:
        _warn(log, NtddaQuirkWarning, f"{g.path}: {len(inner)} block(s) lie inside another block (joint loops "
              "not connected to the rest); as in ntdda they are deleted and the surrounding block keeps "
              "its full outline")
        keep = [b for b in range(len(polygons)) if b not in set(inner)]
        polygons, edge_type = [polygons[b] for b in keep], [edge_type[b] for b in keep]

    ml = np.concatenate([g.material_lines, g.material_line_type[:, None].astype(float)], axis=1)
    material, unused = block_materials(polygons, ml, w0)
    for k in unused:
        _warn(log, NtddaWarning, f"{g.path}, {g.material_line_where[k]}: material line {k + 1} meets no "
              "block; ignored")

    fixed_block, fixed_xy = _fixed_points(g, polygons, w0, log)

    locator = BlockLocator(polygons, w0)

    def locate(points, where, what):
        out = []
        for k, xy in enumerate(points):
            b = locator.locate(xy)
            if b < 0:
                raise NtddaFormatError(f"{g.path}, {where[k]}: {what} ({xy[0]:g}, {xy[1]:g}) lies outside "
                                       "every block")
            out.append(b)
        return np.array(out, dtype=np.int64)

    return NtddaBlocks(
        polygons=tuple(polygons), edge_type=tuple(edge_type), material=material, w0=w0,
        fixed_block=fixed_block, fixed_xy=fixed_xy,
        load_block=locate(g.load_points, g.load_where, "load point"),
        measured_block=locate(g.measured_points, g.measured_where, "measured point"),
        warnings=tuple(log))


def _fixed_points(g: NtddaGeometry, polygons, w0: float, log: list) -> tuple[np.ndarray, np.ndarray]:
    """Fixed points from fixed lines (docs/ntdda.md §4.8).

    ntdda's rule (dc10): a fixed point where the line crosses each block edge, inset 0.005·w0
    into the block; line ends inside a block are dropped, and a line crossing no edge becomes
    its first end point alone. A line inside one block thus pins it at one point, about which
    it can rotate. ddatai's rule: every block the line passes through is pinned at both ends of
    the line's piece inside it (a line end inside the block, or the crossing of its outline,
    not inset). A zero-length line is a fixed point on the first block containing it. The two
    rules differ when a line end lies strictly inside a block; that is reported.
    """
    import shapely

    tol = 1e-9 * w0
    locator = BlockLocator(polygons, w0)
    blocks, points = [], []

    def add(b, xy):
        for bb, q in zip(blocks, points):
            if bb == b and np.hypot(*(q - xy)) <= tol:
                return
        blocks.append(b)
        points.append(np.asarray(xy, dtype=float))

    for k, line in enumerate(g.fixed_lines):
        where = f"{g.path}, {g.fixed_where[k]}"
        if abs(line[0] - line[2]) + abs(line[1] - line[3]) <= tol:
            b = locator.locate(line[:2])
            if b < 0:
                raise NtddaFormatError(f"{where}: fixed point ({line[0]:g}, {line[1]:g}) lies outside "
                                       "every block")
            add(b, _onto_block(polygons[b], line[:2], w0))
            continue
        touched = False
        for b, poly in enumerate(polygons):
            for xy in clip_fixed_line(poly, line, tol):
                add(b, xy)
                touched = True
        if not touched:
            _warn(log, NtddaWarning, f"{where}: fixed line ({line[0]:g}, {line[1]:g})–({line[2]:g}, "
                  f"{line[3]:g}) passes through no block; ignored")
            continue
        inside = []
        for end in (line[:2], line[2:]):
            b = locator.locate(end)
            if b >= 0 and shapely.Polygon(polygons[b]).exterior.distance(shapely.Point(end)) > tol:
                inside.append((b, end))
        if inside:
            ends = ", ".join(f"({e[0]:g}, {e[1]:g}) in block {b}" for b, e in inside)
            theirs = "; ".join(f"({q[0]:.6g}, {q[1]:.6g})" for _, q in ntdda_fixed_points(polygons, line, w0))
            _warn(log, NtddaQuirkWarning, f"{where}: fixed line ends inside a block at {ends}: ntdda drops "
                  "such end points (a line inside one block pins it at its first end only, docs/ntdda.md "
                  f"§3.7, §4.8) and would fix {theirs}; ddatai pins every block the line crosses "
                  "at both ends of the line's piece inside it")
    return np.array(blocks, dtype=np.int64), np.array(points, dtype=float).reshape(-1, 2)


def _onto_block(poly: np.ndarray, xy, w0: float) -> np.ndarray:
    """A point ntdda counts as on a block (within 1e-5·w0 of a vertex) moved onto that vertex,
    so that ddatai's stricter on-block test accepts it."""
    d = np.hypot(*(poly - np.asarray(xy, dtype=float)).T)
    k = int(np.argmin(d))
    return poly[k].copy() if 0 < d[k] < 1e-5 * w0 else np.asarray(xy, dtype=float)


# ============================================================================ the case
@dataclass(frozen=True, kw_only=True)
class NtddaPoint:
    """A point whose positions are recorded (``Results.measured[:, index]``)."""

    name: str
    """"M1", "M2", ... for measured points, "L1", ... for load points."""
    kind: Literal["measured", "load"]
    index: int
    """Column in ``Results.measured``."""
    block: int
    """Block (0-based, ntdda's order) the point moves with."""
    xy: tuple
    """Initial position [length]."""


@dataclass(frozen=True, kw_only=True, eq=False)
class NtddaCase:
    """An ntdda model ready to run: ``simulate(case.scene, case.params, duration=case.duration,
    steps=case.steps, record_every=case.record_every)``, or `NtddaCase.simulate`."""

    scene: Scene
    """Blocks (ntdda's order and numbering, 0-based), joints, fixed points, loads, measured
    points; gravity is the effective γ/ρ (docs/guide/ntdda_files.md)."""
    params: Params
    """Time step, penalty, open-close limit, static/dynamic, plane stress/strain from the file."""
    duration: Optional[float]
    """Simulated time [time]: steps × Δt for a fixed time step; None with an automatic time
    step, where ntdda counts steps (then ``steps`` is set)."""
    steps: Optional[int]
    """Number of steps to take with an automatic time step; None with a fixed one."""
    record_every: int
    """Record a frame every this many steps (the file's save interval)."""
    points: tuple
    """``NtddaPoint`` per recorded point: measured points, then load points."""
    geometry: NtddaGeometry
    """What the geometry file says."""
    analysis: NtddaAnalysis
    """What the analysis file says."""
    blocks: NtddaBlocks
    """The cut blocks, their materials and where the points went."""
    gravity: float
    """Effective gravitational acceleration γ/ρ [length/time²]."""
    warnings: tuple = ()
    """Every warning message issued while reading and building the case."""

    def simulate(self, **kwargs):
        """Run the case with `ddatai.simulate`; keyword arguments override ``duration``,
        ``steps``, ``record_every`` or pass others (``progress``, ``record_contacts``)."""
        from ...run import simulate

        run = dict(duration=self.duration, steps=self.steps, record_every=self.record_every)
        run.update(kwargs)
        return simulate(self.scene, self.params, **run)

    def summary(self) -> str:
        """A few lines describing the model and how it will be run."""
        g, a, p = self.geometry, self.analysis, self.params
        n_meas = sum(pt.kind == "measured" for pt in self.points)
        n_load = sum(pt.kind == "load" for pt in self.points)
        if p.dt is not None:
            timing = f"fixed dt = {p.dt:g}, {a.n_steps} steps ({self.duration:g} time units)"
        else:
            timing = f"automatic dt <= {p.dt_max:g}, {a.n_steps} steps"
        lines = [
            f"ntdda model: {Path(g.path).name} ({g.format}) + {Path(a.path).name} ({a.format})",
            f"  blocks: {self.scene.n_blocks}   joint lines: {len(g.joints)}   joint materials: "
            f"{len(a.joint_materials)}   block materials: {len(a.block_materials)}",
            f"  fixed points: {len(self.scene.fixed_points)}   load points: {n_load}   "
            f"measured points: {n_meas}",
            f"  analysis: {'dynamic' if a.dynamic else 'static'}, {timing}, g2 = {a.max_displacement:g}",
            f"  penalty = {p.penalty:g} ({a.penalty_factor:g} x max E), open-close limit "
            f"{p.oc_max_iterations}, plane {p.plane}, gravity = {self.gravity:g}",
        ]
        if self.warnings:
            lines.append(f"  {len(self.warnings)} warning(s) while reading (see above)")
        return "\n".join(lines)


def read_ntdda(geo_path, ana_path) -> NtddaCase:
    """Read an ntdda geometry file and analysis file (each original text or DDAML) into a
    ready-to-run `NtddaCase`.

    Raises `NtddaFormatError` (a ``ValueError``) for malformed or inconsistent files, naming
    the file, the line or element and what was expected; warns with `NtddaQuirkWarning` where
    the files rely on an ntdda quirk and with `NtddaUnsupportedWarning` for ignored settings.
    """
    geometry = read_ntdda_geometry(geo_path)
    analysis = read_ntdda_analysis(ana_path)
    return build_ntdda_case(geometry, analysis)


def build_ntdda_case(geometry: NtddaGeometry, analysis: NtddaAnalysis) -> NtddaCase:
    """Turn the content of the two files into a Scene, Params and run length."""
    g, a = geometry, analysis
    log: list[str] = list(g.warnings) + list(a.warnings)
    _check_references(g, a, log)
    blocks = cut_ntdda_geometry(g)
    log += blocks.warnings
    gravity = _effective_gravity(g, a, blocks, log)

    with warnings.catch_warnings():
        # an ntdda file's values are in the file's own consistent units, not a unit slip
        warnings.simplefilter("ignore", UnitWarning)
        materials = [Material(density=m.unit_mass, young=m.young, poisson=m.poisson) for m in a.block_materials]
        joints = [Joint(friction=j.friction, cohesion=j.cohesion, tensile=j.tensile) for j in a.joint_materials]
    scene = Scene(gravity=gravity)
    for b, (poly, types) in enumerate(zip(blocks.polygons, blocks.edge_type)):
        mat = a.block_materials[blocks.material[b] - 1]
        nxt = np.roll(poly, -1, axis=0)
        # a block is its own domain cut by its edges, so that each edge keeps its joint
        (bid,) = scene.cut(poly, [(np.array([poly[k], nxt[k]]), joints[t - 1]) for k, t in enumerate(types)],
                           material=materials[blocks.material[b] - 1])
        stress, velocity = _initial_state(poly, mat)
        if any(stress) or any(velocity):
            spec = scene.blocks[bid]
            scene.blocks[bid] = replace(spec, stress=stress, velocity=velocity[:2],
                                        angular_velocity=velocity[2])
    for b, xy in zip(blocks.fixed_block, blocks.fixed_xy):
        scene.add_fixed_point(int(b), xy)

    points = []
    for k, (b, xy) in enumerate(zip(blocks.measured_block, g.measured_points)):
        idx = scene.add_measured_point(int(b), xy)
        points.append(NtddaPoint(name=f"M{k + 1}", kind="measured", index=idx, block=int(b),
                                 xy=(float(xy[0]), float(xy[1]))))
    duration = a.n_steps * a.max_time_step if not a.auto_time_step else None
    end_time = a.n_steps * a.max_time_step
    for k, (b, xy) in enumerate(zip(blocks.load_block, g.load_points)):
        if k < len(a.load_histories):
            hist = a.load_histories[k]
            force = _load_function(hist)
            if end_time > hist[-1, 0] * (1 + 1e-12):
                _warn(log, NtddaQuirkWarning, f"{a.path}, {a.load_where[k]}: the load history ends at "
                      f"t = {hist[-1, 0]:g} but the run lasts {'about ' if a.auto_time_step else ''}"
                      f"{end_time:g}; ntdda then reads an unset record (docs/ntdda.md §3.11), ddatai holds "
                      "the last force")
            if hist[0, 0] > 0:
                _warn(log, NtddaWarning, f"{a.path}, {a.load_where[k]}: the load history starts at "
                      f"t = {hist[0, 0]:g} > 0; ddatai holds the first force before it")
        else:
            force = (0.0, 0.0)
            _warn(log, NtddaQuirkWarning, f"{g.path}, {g.load_where[k]}: load point {k + 1} has no load "
                  f"history in {a.path} (ntdda cannot load it from an original-format analysis file, "
                  "docs/ntdda.md §3.8); it carries no load and is only tracked")
        scene.add_point_load(int(b), xy, force)
        idx = scene.add_measured_point(int(b), xy)
        points.append(NtddaPoint(name=f"L{k + 1}", kind="load", index=idx, block=int(b),
                                 xy=(float(xy[0]), float(xy[1]))))

    max_young = max(m.young for m in a.block_materials)
    params = Params(
        dt=None if a.auto_time_step else a.max_time_step,
        dt_max=a.max_time_step,
        max_displacement_ratio=a.max_displacement,
        penalty=a.penalty_factor * max_young,
        penalty_ratio=a.penalty_factor,
        shear_ratio=a.shear_norm_ratio,
        penetration_ratio=a.norm_spring_pen,
        angle_tolerance=a.angle_overlap,
        static=not a.dynamic,
        plane="strain" if a.plane_strain else "stress",
        oc_max_iterations=a.oc_limit,
        # ntdda's gravity turn-on phase settles the model before its run: ddatai's equilibrium
        # stage; without it ntdda switches gravity on at t = 0, and so does ddatai
        initial_equilibrium=a.gravity_turn_on,
    )
    return NtddaCase(scene=scene, params=params, duration=duration,
                     steps=a.n_steps if a.auto_time_step else None, record_every=a.save_interval,
                     points=tuple(points), geometry=g, analysis=a, blocks=blocks, gravity=gravity,
                     warnings=tuple(log))


def _check_references(g: NtddaGeometry, a: NtddaAnalysis, log: list) -> None:
    """Joint types and material-line materials must exist in the analysis file; every load
    point needs a history when the analysis file gives any."""
    n_j, n_b = len(a.joint_materials), len(a.block_materials)
    for k, t in enumerate(g.joint_type):
        if t > n_j:
            raise NtddaFormatError(f"{g.path}, {g.joint_where[k]}: joint line {k + 1} has joint type {t}, but "
                                   f"{a.path} defines {n_j} joint material(s)")
    for k, t in enumerate(g.material_line_type):
        if t > n_b:
            raise NtddaFormatError(f"{g.path}, {g.material_line_where[k]}: material line {k + 1} has block "
                                   f"material {t}, but {a.path} defines {n_b} block material(s)")
    n_l, n_h = len(g.load_points), len(a.load_histories)
    if n_h and n_h < n_l:
        raise NtddaFormatError(f"{a.path}: {n_h} load histories (<Loadpoint>) for the {n_l} load points of "
                               f"{g.path}: expected one per load point, in order")
    if n_h > n_l:
        _warn(log, NtddaWarning, f"{a.path}: {n_h} load histories but {g.path} has {n_l} load points; "
              "the extra histories are ignored")


def _effective_gravity(g: NtddaGeometry, a: NtddaAnalysis, blocks: NtddaBlocks, log: list) -> float:
    """Gravity g such that the body force of every block is ρ·g (docs/method/dda.md §6.3).

    Rule: ``Gravaccel`` when the file gives it; otherwise γ/ρ of block material 1. ntdda uses
    γ₁/ρ₁ for original-format files and ``Gravaccel`` (9.81 by default) for DDAML, ignoring
    ``Unitweight``. Reported: a DDAML file without ``Gravaccel`` whose γ₁/ρ₁ is not 9.81 (ntdda
    would use 9.81), and materials whose γ is not ρ·g (one gravity serves all blocks; their
    unit weight is not honoured, as in ntdda).
    """
    m1 = a.block_materials[0]
    if a.gravity_acceleration is not None:
        grav = a.gravity_acceleration
    elif m1.unit_weight is not None:
        grav = m1.unit_weight / m1.unit_mass
        if a.format == "ddaml" and not math.isclose(grav, NTDDA_GRAVITY, rel_tol=_RATIO_TOL):
            _warn(log, NtddaQuirkWarning, f"{a.path}, {m1.where}: no <Gravaccel>: ntdda would use g = "
                  f"{NTDDA_GRAVITY} and ignore <Unitweight>; ddatai uses γ/ρ = {m1.unit_weight:g}/"
                  f"{m1.unit_mass:g} = {grav:g}")
    else:
        grav = NTDDA_GRAVITY
    used = set(int(m) for m in blocks.material)
    for k, m in enumerate(a.block_materials, start=1):
        if m.unit_weight is None or k not in used:
            continue
        if not math.isclose(m.unit_weight, m.unit_mass * grav, rel_tol=_RATIO_TOL, abs_tol=1e-300):
            _warn(log, NtddaQuirkWarning, f"{a.path}, {m.where}: unit weight {m.unit_weight:g} is not unit "
                  f"mass × g = {m.unit_mass:g} × {grav:g}; one gravity acts on all blocks, so this "
                  f"material's weight is {m.unit_mass * grav:g} per volume (as in ntdda)")
    return grav


def _initial_state(poly: np.ndarray, mat: NtddaBlockMaterial) -> tuple[tuple, tuple]:
    """Initial stress s + y_centroid·t (original format) and velocity (vx, vy, ω)."""
    if not (any(mat.stress) or any(mat.stress_gradient) or any(mat.velocity)):
        return (0.0, 0.0, 0.0), (0.0, 0.0, 0.0)
    from ...geometry import polygon_integrals
    yc = float(polygon_integrals(poly, np.array([0, len(poly)]))["centroid"][0, 1])
    stress = tuple(float(s + yc * t) for s, t in zip(mat.stress, mat.stress_gradient))
    return stress, tuple(float(v) for v in mat.velocity)


def _load_function(hist: np.ndarray):
    """Force history t -> (fx, fy): linear between records, held constant outside them."""
    t, fx, fy = hist[:, 0].copy(), hist[:, 1].copy(), hist[:, 2].copy()
    if np.all(fx == fx[0]) and np.all(fy == fy[0]):
        return (float(fx[0]), float(fy[0]))

    def force(time: float) -> tuple[float, float]:
        return float(np.interp(time, t, fx)), float(np.interp(time, t, fy))

    return force


# ============================================================================ output
def write_measured_csv(results, case: NtddaCase, path) -> None:
    """Write the recorded points of a run to CSV: one row per recorded frame, the time, then
    per point (measured points M1.., load points L1..) its x, y and its displacement dx, dy
    from the initial position (ntdda's cumulative displacement, without ntdda's D9 bug)."""
    measured = np.asarray(results.measured)
    if measured.ndim != 3 or measured.shape[1] != len(case.points):
        held = measured.shape[1] if measured.ndim == 3 else "?"
        raise ValueError(f"write_measured_csv: the results hold {held} measured points but the case "
                         f"records {len(case.points)}; were they produced by this case?")
    header = ["time"]
    cols = [np.asarray(results.time, dtype=float)]
    for pt in case.points:
        xy = measured[:, pt.index]
        header += [f"{pt.name}_x", f"{pt.name}_y", f"{pt.name}_dx", f"{pt.name}_dy"]
        cols += [xy[:, 0], xy[:, 1], xy[:, 0] - xy[0, 0], xy[:, 1] - xy[0, 1]]
    table = np.column_stack(cols) if cols else np.zeros((0, 1))
    with open(path, "w", newline="") as fh:
        fh.write(",".join(header) + "\n")
        for row in table:
            fh.write(",".join(repr(float(v)) for v in row) + "\n")
