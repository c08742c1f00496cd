"""Sections from DXF drawings: `read_dxf` turns a CAD section into a `Scene`.

Needs the optional ``ezdxf`` package (``pip install ddatai[dxf]``), imported only when a
drawing is read. A drawing's layers say what each entity is (names are case-insensitive, and
can be changed with the ``layers`` argument):

=================  ==========================================================================
``DOMAIN``         one closed polyline: the outline of the rock mass, cut into blocks
``FIXED``          closed polylines: regions whose blocks are fixed (a block whose centroid
                   lies inside one)
``POINTS``         POINT entities: measured points (each on the block that contains it)
``WATER``          one open polyline: the water table h(x), x increasing (optional)
joint layers       LINE / open polyline traces, one layer per joint property set: each layer
                   named in ``joints`` is cut into the domain with that `Joint`
=================  ==========================================================================

Other layers are ignored (dimensions, text, a title block). A trace end that stops within
``snap`` of the outline or of another trace (a drafting or unit-scaling round-off; default
1e-6 × the section's size) is extended across it, so that it closes its blocks. Polylines with arc segments
(bulges), arcs, circles and splines on a read layer are refused: replace them by straight
segments in the drawing.

Drawing units come from the header variable ``$INSUNITS``: a drawing in millimetres (or cm,
inches, feet) is scaled to metres; a unitless drawing (``$INSUNITS`` 0 or absent) must say its
unit with ``units=`` — a section drawn in millimetres must not run as metres. See
docs/guide/modelling.md, "From the field".
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Mapping, Optional

import numpy as np

from ..params import Joint, Material

#: metres per drawing unit of the $INSUNITS codes a section can use
INSUNITS = {1: ("in", 0.0254), 2: ("ft", 0.3048), 4: ("mm", 1e-3), 5: ("cm", 1e-2), 6: ("m", 1.0),
            7: ("km", 1e3), 10: ("yd", 0.9144), 14: ("dm", 0.1)}
UNIT_SCALE = {name: scale for name, scale in INSUNITS.values()}
#: the layer of each role, as ``read_dxf(layers=...)`` may change them
DEFAULT_LAYERS = {"domain": "DOMAIN", "fixed": "FIXED", "points": "POINTS", "water": "WATER"}


@dataclass(frozen=True, kw_only=True, eq=False)
class DxfSection:
    """The geometry of a section drawing, in metres (`read_dxf_section`)."""

    boundary: np.ndarray
    """(n, 2) outline of the domain [m]."""
    traces: tuple
    """(polyline (k, 2) [m], layer name) of every joint trace, in drawing order."""
    fixed: tuple = ()
    """(k, 2) polygons of the fixed regions [m]."""
    points: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    """(p, 2) measured points [m]."""
    water: Optional[np.ndarray] = None
    """(k, 2) water table [m], None without one."""
    units: str = "m"
    """The drawing's unit."""
    scale: float = 1.0
    """Metres per drawing unit [m]."""


def _ezdxf():
    try:
        import ezdxf
    except ImportError:
        raise ImportError("reading DXF drawings needs the optional package ezdxf: "
                          "pip install 'ddatai[dxf]' (or pip install ezdxf)") from None
    return ezdxf


def drawing_scale(doc, units: Optional[str], path) -> tuple[str, float]:
    """(unit, metres per unit) of a drawing from its header ($INSUNITS), checked against
    ``units``; ValueError when neither says, or they disagree."""
    code = int(doc.header.get("$INSUNITS", 0) or 0)
    if units is not None and units not in UNIT_SCALE:
        raise ValueError(f"read_dxf: units must be one of {sorted(UNIT_SCALE)}, got {units!r}")
    if code in INSUNITS:
        name, scale = INSUNITS[code]
        if units is not None and units != name:
            raise ValueError(f"{path}: the drawing's header says its unit is {name} ($INSUNITS = {code}), "
                             f"but units={units!r} was given; drop units= or fix the drawing's units")
        return name, scale
    if code != 0:
        raise ValueError(f"{path}: the drawing's unit ($INSUNITS = {code}) is not a length unit ddatai reads "
                         f"({', '.join(sorted(UNIT_SCALE))})")
    if units is None:
        raise ValueError(f"{path}: the drawing has no unit ($INSUNITS is 0 or absent), so a section in "
                         f"millimetres would run as metres; say its unit: read_dxf(..., units='m') (or "
                         f"'mm', 'cm', 'ft', 'in'), or set the drawing's units in the CAD program")
    return units, UNIT_SCALE[units]


def _polyline(entity, where: str) -> tuple[np.ndarray, bool]:
    """(points (k, 2) in drawing units, closed) of a LINE, LWPOLYLINE or 2D POLYLINE."""
    kind = entity.dxftype()
    if kind == "LINE":
        s, e = entity.dxf.start, entity.dxf.end
        return np.array([[s[0], s[1]], [e[0], e[1]]], dtype=float), False
    if kind == "LWPOLYLINE":
        ez = tuple(entity.dxf.get("extrusion", (0.0, 0.0, 1.0)))
        if not np.allclose(ez, (0.0, 0.0, 1.0)):
            # its points are in an object coordinate system (a mirrored drawing): explode it
            raise ValueError(f"{where}: a polyline drawn in a mirrored or tilted plane (extrusion "
                             f"{ez}); explode it to lines or redraw it in the world plane")
        pts = np.array(entity.get_points("xyb"), dtype=float).reshape(-1, 3)
        if np.any(pts[:-1, 2] != 0) or (entity.closed and pts[-1, 2] != 0):
            raise ValueError(f"{where}: a polyline with arc segments (bulges); replace the arcs by "
                             f"straight segments")
        return pts[:, :2], bool(entity.closed)
    if kind == "POLYLINE":
        if not entity.is_2d_polyline:
            raise ValueError(f"{where}: a 3D polyline or mesh; draw the section with 2D polylines")
        pts = np.array([(v.dxf.location[0], v.dxf.location[1], v.dxf.bulge) for v in entity.vertices],
                       dtype=float).reshape(-1, 3)
        if np.any(pts[:, 2] != 0):
            raise ValueError(f"{where}: a polyline with arc segments (bulges); replace the arcs by "
                             f"straight segments")
        return pts[:, :2], bool(entity.is_closed)
    raise ValueError(f"{where}: a {kind} entity cannot be read; draw lines and polylines only "
                     f"(replace arcs, circles and splines by straight segments)")


def _closed_ring(pts: np.ndarray, closed: bool) -> Optional[np.ndarray]:
    if len(pts) >= 3 and np.allclose(pts[0], pts[-1]):
        return pts[:-1]
    return pts if closed and len(pts) >= 3 else None


def read_dxf_section(path, *, joint_layers, units: Optional[str] = None,
                     layers: Optional[Mapping[str, str]] = None) -> DxfSection:
    """The pieces of a section drawing (see the module docstring), in metres: the domain
    outline, the joint traces of the ``joint_layers``, the fixed regions, measured points and
    water table."""
    ezdxf = _ezdxf()
    roles = dict(DEFAULT_LAYERS)
    for role, name in (layers or {}).items():
        if role not in roles:
            raise ValueError(f"read_dxf: layers keys must be among {sorted(roles)}, got {role!r}")
        roles[role] = name
    role_of = {name.upper(): role for role, name in roles.items()}
    joint_names = {str(name).upper(): str(name) for name in joint_layers}
    clash = sorted(set(role_of) & set(joint_names))
    if clash:
        raise ValueError(f"read_dxf: layer {clash[0]!r} cannot be both a joint layer and the "
                         f"{role_of[clash[0]]} layer")
    try:
        doc = ezdxf.readfile(str(path))
    except OSError as err:
        raise ValueError(f"{path}: cannot read the drawing ({err})") from None
    except ezdxf.DXFStructureError as err:
        raise ValueError(f"{path}: not a valid DXF drawing ({err})") from None
    unit, scale = drawing_scale(doc, units, path)
    domains, fixed, points, water, traces = [], [], [], [], []
    found_layers = set()
    for entity in doc.modelspace():
        layer = str(entity.dxf.layer)
        key = layer.upper()
        found_layers.add(key)
        role = role_of.get(key)
        if role is None and key not in joint_names:
            continue
        where = f"{path}: layer {layer!r}, {entity.dxftype()} #{entity.dxf.handle}"
        if role == "points":
            if entity.dxftype() != "POINT":
                raise ValueError(f"{where}: the {layer!r} layer holds POINT entities (measured points)")
            loc = entity.dxf.location
            points.append((loc[0] * scale, loc[1] * scale))
            continue
        pts, closed = _polyline(entity, where)
        pts = pts * scale
        if role in ("domain", "fixed"):
            ring = _closed_ring(pts, closed)
            if ring is None:
                raise ValueError(f"{where}: the {layer!r} layer holds closed polylines (a region); this one "
                                 f"is open")
            (domains if role == "domain" else fixed).append(ring)
        elif role == "water":
            water.append(pts)
        else:
            if closed and len(pts) > 2:
                pts = np.vstack([pts, pts[:1]])
            traces.append((pts, joint_names[key]))
    if len(domains) != 1:
        raise ValueError(f"{path}: the {roles['domain']!r} layer must hold exactly one closed polyline (the "
                         f"section's outline), found {len(domains)}"
                         + ("" if domains else f"; layers in the drawing: {sorted(found_layers)}"))
    missing = sorted(set(joint_names) - found_layers)
    if missing:
        raise ValueError(f"{path}: no entity on the joint layer {joint_names[missing[0]]!r} "
                         f"(layers in the drawing: {sorted(found_layers)})")
    if len(water) > 1:
        raise ValueError(f"{path}: the {roles['water']!r} layer must hold one polyline (the water table), "
                         f"found {len(water)}")
    return DxfSection(boundary=domains[0], traces=tuple(traces), fixed=tuple(fixed),
                      points=np.array(points, dtype=float).reshape(-1, 2),
                      water=water[0] if water else None, units=unit, scale=scale)


def snap_traces(boundary: np.ndarray, traces, snap: float) -> list[np.ndarray]:
    """The trace polylines with every end that stops within ``snap`` [m] of the outline or of
    another trace extended onto it (`ddatai.cutting.snap_trace_ends`, which `Scene.cut` also
    applies), so that noding meets it there."""
    from ..cutting import snap_trace_ends
    return snap_trace_ends(boundary, traces, snap)[0]


def read_dxf(path, *, material: Material, joints: Mapping[str, Joint], default_joint: Optional[Joint] = None,
             units: Optional[str] = None, layers: Optional[Mapping[str, str]] = None,
             gravity: float = 9.81, snap: Optional[float] = None):
    """A `Scene` from a section drawing (see the module docstring for its layers).

    ``joints`` maps each joint layer to its `Joint` (or `BartonBandis`); the domain outline is
    cut by their traces (`Scene.cut`) into blocks of ``material``; blocks whose centroid lies in
    a ``FIXED`` region are fixed; ``POINTS`` become measured points; a ``WATER`` polyline the
    water table. ``default_joint`` is the scene's default joint (for contacts on no trace).
    ``units``: the drawing's unit when its header gives none ('m', 'mm', ...); ``layers``:
    other names for the roles (``{"domain": "OUTLINE"}``); ``snap`` [m]: trace ends this close
    to the outline or another trace are extended across it (default 1e-6 × the section's
    size). Returns the Scene.

    >>> scene = dd.read_dxf("section.dxf", material=rock,                    # doctest: +SKIP
    ...                     joints={"BEDDING": dd.Joint(friction=22.0)})
    """
    import shapely

    from ..scene import Scene

    if not isinstance(material, Material):
        raise ValueError(f"read_dxf: material must be a ddatai.Material, got {type(material).__name__}")
    if not hasattr(joints, "items"):
        raise ValueError(f"read_dxf: joints must map joint layer names to ddatai.Joint, got {type(joints).__name__}")
    for name, jt in joints.items():
        if not isinstance(jt, Joint):
            raise ValueError(f"read_dxf: joints[{name!r}] must be a ddatai.Joint, got {type(jt).__name__}")
    if default_joint is not None and not isinstance(default_joint, Joint):
        raise ValueError(f"read_dxf: default_joint must be a ddatai.Joint, got {type(default_joint).__name__}")
    section = read_dxf_section(path, joint_layers=list(joints), units=units, layers=layers)
    size = float(np.ptp(section.boundary, axis=0).max())
    if snap is None:
        snap = 1e-6 * size
    elif not (isinstance(snap, (int, float)) and np.isfinite(snap) and snap >= 0):
        raise ValueError(f"read_dxf: snap must be a finite distance >= 0 m, got {snap!r}")
    polylines = [pts for pts, _ in section.traces]
    scene = Scene(gravity=gravity)
    # Scene.cut extends the trace ends that stop within ``snap`` of the outline or a trace
    ids = scene.cut(section.boundary, [(pts, joints[name]) for pts, (_, name) in zip(polylines, section.traces)],
                    material, snap_ends=float(snap))
    if default_joint is not None:
        scene.set_joint(default_joint)
    if section.fixed:
        regions = shapely.union_all([shapely.Polygon(r) for r in section.fixed])
        for b in ids:
            if regions.covers(shapely.Polygon(scene.polygon(b)).centroid):
                scene.set_fixed(b)
    if len(section.points):
        polys = [shapely.Polygon(scene.polygon(b)) for b in ids]
        for p in section.points:
            pt = shapely.Point(p)
            dist = [poly.distance(pt) for poly in polys]
            k = int(np.argmin(dist))
            if dist[k] > 1e-9 * max(1.0, float(np.ptp(section.boundary, axis=0).max())):
                raise ValueError(f"{path}: measured point ({p[0]:g}, {p[1]:g}) m lies outside the section")
            scene.add_measured_point(ids[k], tuple(p))
    if section.water is not None:
        scene.set_water_table(section.water)
    return scene


def write_dxf_section(path, *, boundary, traces, fixed=(), points=(), water=None, units: str = "m") -> None:
    """Write a section drawing that `read_dxf` reads: ``boundary`` (n, 2) [m], ``traces`` a list
    of (polyline, layer name), ``fixed`` polygons, ``points``, ``water`` polyline, all in metres,
    written in ``units`` (the header's $INSUNITS says which)."""
    ezdxf = _ezdxf()
    if units not in UNIT_SCALE:
        raise ValueError(f"write_dxf_section: units must be one of {sorted(UNIT_SCALE)}, got {units!r}")
    code = {name: c for c, (name, _) in INSUNITS.items()}[units]
    k = 1.0 / UNIT_SCALE[units]
    doc = ezdxf.new("R2010")
    doc.header["$INSUNITS"] = code
    doc.header["$MEASUREMENT"] = 0 if units in ("in", "ft", "yd") else 1
    msp = doc.modelspace()
    for name in {"DOMAIN", "FIXED", "POINTS", "WATER", *(layer for _, layer in traces)}:
        doc.layers.add(name)
    msp.add_lwpolyline((np.asarray(boundary, float) * k).tolist(), close=True, dxfattribs={"layer": "DOMAIN"})
    for ring in fixed:
        msp.add_lwpolyline((np.asarray(ring, float) * k).tolist(), close=True, dxfattribs={"layer": "FIXED"})
    for pts, layer in traces:
        pts = np.asarray(pts, float) * k
        if len(pts) == 2:
            msp.add_line(tuple(pts[0]), tuple(pts[1]), dxfattribs={"layer": layer})
        else:
            msp.add_lwpolyline(pts.tolist(), dxfattribs={"layer": layer})
    for p in points:
        msp.add_point((float(p[0]) * k, float(p[1]) * k), dxfattribs={"layer": "POINTS"})
    if water is not None:
        msp.add_lwpolyline((np.asarray(water, float) * k).tolist(), dxfattribs={"layer": "WATER"})
    doc.saveas(str(path))


# ---------------------------------------------------------------------- joints file (command line)
def read_joints_file(path) -> dict:
    """The keyword arguments of `read_dxf` (and the run's ``duration``) from a TOML joints file
    (docs/guide/modelling.md, "From the field")::

        units = "m"              # optional: the drawing's unit when its header has none
        duration = 2.0           # optional: simulated time of ``ddatai run`` [s]
        [material]               # the blocks' material (SI)
        density = 2600.0
        young = 10e9
        poisson = 0.25
        [default]                # optional: the joint of contacts on no trace
        friction = 35.0
        [joints.BEDDING]         # one table per joint layer: a Joint ...
        jrc = 4.0                # ... or, with jrc, a BartonBandis
        jcs = 30e6
        residual_friction = 24.0
        [layers]                 # optional: other layer names of the roles
        domain = "OUTLINE"

    Every mistake is a ValueError naming the file and the key."""
    try:
        import tomllib
    except ImportError:  # Python 3.10
        import tomli as tomllib
    from ..params import BartonBandis

    try:
        with open(path, "rb") as f:
            data = tomllib.load(f)
    except OSError as err:
        raise ValueError(f"{path}: cannot read the joints file ({err})") from None
    except tomllib.TOMLDecodeError as err:
        raise ValueError(f"{path}: not a valid TOML file ({err})") from None
    known = {"units", "duration", "gravity", "material", "default", "joints", "layers"}
    unknown = sorted(set(data) - known)
    if unknown:
        raise ValueError(f"{path}: unknown key {unknown[0]!r} (expected {', '.join(sorted(known))})")

    def joint(table, where):
        if not isinstance(table, dict):
            raise ValueError(f"{path}: {where} must be a table of joint properties")
        try:
            return BartonBandis(**table) if "jrc" in table else Joint(**table)
        except TypeError as err:
            raise ValueError(f"{path}: {where}: {err}") from None
        except ValueError as err:
            raise ValueError(f"{path}: {where}: {err}") from None

    if "material" not in data or not isinstance(data["material"], dict):
        raise ValueError(f"{path}: a [material] table (density, young, poisson) is needed for the blocks")
    try:
        material = Material(**data["material"])
    except (TypeError, ValueError) as err:
        raise ValueError(f"{path}: [material]: {err}") from None
    joints = data.get("joints")
    if not isinstance(joints, dict) or not joints:
        raise ValueError(f"{path}: a [joints.LAYER] table per joint layer of the drawing is needed")
    out = {"material": material, "joints": {name: joint(t, f"[joints.{name}]") for name, t in joints.items()}}
    if "default" in data:
        out["default_joint"] = joint(data["default"], "[default]")
    for key in ("units", "gravity", "layers", "duration"):
        if key in data:
            out[key] = data[key]
    return out
