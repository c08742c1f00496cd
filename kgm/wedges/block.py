"""A polyhedral block on its faces: its loads, its limit equilibrium and the `Wedge` result
(docs/kgm/wedge.md §4). `kgm.wedge` builds a slope's wedge and judges it here;
`polyhedral_block` judges any block given by its bounding half-spaces (a prism on a plane
between release joints, a block cut by any joints).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Optional, Sequence

import numpy as np

from .block_theory import JointPyramid, Mode, joint_pyramids, jp_is_empty
from .geometry import Halfspace, NoBlock, Polyhedron, _finite, polyhedron, trend_plunge
from .mechanics import (Bolt, Contact, Equilibrium, Force, Seismic, Water, equilibrium, required_force,
                        seismic_load, worst_force)


@dataclass(frozen=True)
class Support:
    """The support that raises a wedge's factor of safety to a design value."""

    fs: float
    """Design factor of safety [-]."""
    force: float
    """Smallest active anchor force, in its optimum direction [N]."""
    trend: float
    """Trend of that force [degrees]."""
    plunge: float
    """Plunge of that force [degrees] (negative: upwards)."""
    pressure: float
    """Pressure on the wedge's slope face, normal to it, that gives the same FS [Pa]
    (shotcrete or a pressure support)."""


@dataclass(frozen=True, kw_only=True, eq=False)
class Wedge:
    """A wedge of a slope and its limit equilibrium (from `wedge`)."""

    forms: bool
    """A finite, removable wedge with a volume forms."""
    reason: str
    """Why none forms ('' when one does)."""
    fs: float = math.nan
    """Factor of safety [-] (inf: held without friction; 0: falls; nan: no wedge)."""
    mode: str = ""
    """'falling', 'sliding on joint 1', 'sliding on joint 1 and joint 2', 'stable' or ''."""
    volume: float = 0.0
    """[m³]."""
    weight: float = 0.0
    """[N]."""
    sliding: tuple = (math.nan, math.nan)
    """(trend, plunge) of the sliding (or falling) direction [degrees]."""
    normal_forces: tuple = ()
    """Effective normal force on each joint, in the order given [N] (0 where it opens)."""
    normal_force_on: dict = field(default_factory=dict)
    """Label ('joint 1', …, 'tension crack') -> effective normal force [N]."""
    areas: dict = field(default_factory=dict)
    """Label -> area of the wedge's face on that plane [m²] (joints, crack, slope and upper face)."""
    water_pressure: dict = field(default_factory=dict)
    """Label -> average water pressure [Pa]."""
    height: float = math.nan
    """Height used after bench-width and slope-length scaling [m]."""
    intersection: tuple = (math.nan, math.nan)
    """(trend, plunge) of the line of intersection of joints 1 and 2, downwards [degrees]."""
    pyramid: str = ""
    """Goodman & Shi code of the wedge's joint pyramid (0 above, 1 below each joint)."""
    pyramids: tuple = ()
    """Every `JointPyramid` of the joints with the slope and upper faces."""
    acceleration: float = 0.0
    """Acceleration along the sliding direction if released [m/s²] (0 when FS ≥ 1)."""
    driving: float = 0.0
    """Driving force S [N]."""
    resisting: float = 0.0
    """Resisting force [N]."""
    block: Optional[Polyhedron] = field(default=None, repr=False)
    """The wedge's vertices and faces."""
    contacts: tuple = field(default=(), repr=False)
    active: np.ndarray = field(default=None, repr=False)
    """Active resultant r [N]."""
    passive: np.ndarray = field(default=None, repr=False)
    """Passive resultant p [N]."""
    mass: float = 0.0
    """[kg]."""
    inputs: dict = field(default_factory=dict, repr=False)
    """The arguments of `wedge` (to redraw or re-run it)."""

    def required_support(self, fs: float = 1.5) -> Support:
        """Smallest anchor force (optimum direction) and slope-face pressure that raise FS to
        ``fs`` (Hoek & Bray's minimum anchor force, docs/kgm/wedge.md §4.4)."""
        if not self.forms:
            raise ValueError(f"no wedge forms ({self.reason}): nothing to support")
        if not (_finite(fs) and fs > 0):
            raise ValueError(f"design factor of safety must be > 0, got {fs!r}")
        t, d = required_force(self.contacts, self.active, self.passive, self.mass, fs)
        face = self.block.face("slope face")
        pressure = 0.0
        if face is not None and t > 0:
            tp, _ = required_force(self.contacts, self.active, self.passive, self.mass, fs, direction=-face.normal)
            pressure = tp / face.area
        tr, pl = trend_plunge(d)
        return Support(fs=float(fs), force=t, trend=tr, plunge=pl, pressure=pressure)

    def worst_force(self, force: float) -> tuple:
        """(least FS, trend, plunge) for an external force of ``force`` [N] in its worst
        direction (Hoek & Bray's minimum factor of safety, docs/kgm/wedge.md §4.4)."""
        if not self.forms:
            raise ValueError(f"no wedge forms ({self.reason})")
        if not (_finite(force) and force >= 0):
            raise ValueError(f"force must be >= 0 N, got {force!r}")
        fs, d = worst_force(self.contacts, self.active, self.passive, self.mass, force)
        t, p = trend_plunge(d)
        return fs, t, p

    def stereonet(self, path, **kw):
        """Write the stereonet of its joint pyramids (`kgm.wedges.pictures.stereonet`)."""
        from .pictures import stereonet

        return stereonet(self, path, **kw)

    def write_png(self, path, **kw):
        """Draw the wedge on its slope to a PNG (`kgm.wedges.pictures.write_png`)."""
        from .pictures import write_png

        return write_png(self, path, **kw)

    def write_gif(self, path, **kw):
        """A turning GIF of the wedge on its slope (`kgm.wedges.pictures.write_gif`)."""
        from .pictures import write_gif

        return write_gif(self, path, **kw)

    def write_vtp(self, path):
        """Write the wedge for ParaView (`kgm.wedges.vtk.write_vtp`)."""
        from .vtk import write_vtp

        return write_vtp(self, path)

    def summary(self) -> str:
        if not self.forms:
            return f"no wedge: {self.reason}"
        n = ", ".join(f"{k} {v:.4g} N" for k, v in self.normal_force_on.items())
        return (f"wedge {self.pyramid}: FS = {self.fs:.4f} ({self.mode}), V = {self.volume:.4g} m³, "
                f"W = {self.weight:.4g} N, sliding {self.sliding[0]:.1f}°/{self.sliding[1]:.1f}°; normal forces: {n}")


def judge(block: Polyhedron, joints: dict, *, density, gravity, water_pressures: dict, seismic, bolts, forces,
          nj=None, **fields) -> "Wedge":
    """The `Wedge` result of a block: its contacts (faces of kind 'joint' with their strength
    ``joints[label]``, 'crack' without), its active and passive loads and its equilibrium.
    ``water_pressures`` maps face labels to average pressures [Pa]; ``nj`` the normals of
    joints 1 and 2 (for the seismic fallback direction and the line of intersection)."""
    contacts = []
    for f in block.faces:
        if f.kind == "free":
            continue
        contacts.append(Contact(f.label, -f.normal, f.area, joints.get(f.label) if f.kind == "joint" else None))
    mass = density * block.volume
    weight = mass * gravity
    active = np.array([0.0, 0.0, -weight])
    for c in contacts:
        active = active + water_pressures.get(c.label, 0.0) * c.area * c.normal
    for f in forces:
        active = active + f.vector
    passive = np.zeros(3)
    for b in bolts:
        if b.kind == "active":
            active = active + b.vector
        else:
            passive = passive + b.vector
    if seismic is not None:
        active = active + _seismic_vector(seismic, weight, contacts, active, passive, mass, nj)
    eq: Equilibrium = equilibrium(contacts, active, passive, mass)
    names = [c.label for c in contacts]
    on = {c.label: float(eq.normal[k]) for k, c in enumerate(contacts)}
    mode = eq.mode
    if mode.kind in ("one plane", "two planes"):
        mode_name = "sliding on " + " and ".join(names[i] for i in mode.planes)
    else:
        mode_name = mode.kind
    sliding = trend_plunge(mode.direction) if mode.kind != "stable" else (math.nan, math.nan)
    inter = (math.nan, math.nan)
    if nj is not None and np.linalg.norm(np.cross(nj[0], nj[1])) > 1e-12:
        i = np.cross(nj[0], nj[1])
        inter = trend_plunge(i if i[2] < 0 else -i)
    labels = [k for k in joints]
    fields.setdefault("normal_forces", tuple(on.get(k, 0.0) for k in labels))
    return Wedge(forms=True, reason="", fs=eq.fs, mode=mode_name, volume=block.volume, weight=weight, sliding=sliding,
                 normal_force_on=on, areas={f.label: f.area for f in block.faces}, water_pressure=dict(water_pressures),
                 intersection=inter, acceleration=eq.acceleration, driving=eq.driving, resisting=eq.resisting,
                 block=block, contacts=tuple(contacts), active=active, passive=passive, mass=mass, **fields)


def polyhedral_block(halfspaces: Sequence[Halfspace], joints: dict, *, density: float = 2600.0,
                     gravity: float = 9.81, water_pressures: Optional[dict] = None, seismic=None,
                     bolts: Sequence[Bolt] = (), forces: Sequence[Force] = ()) -> "Wedge":
    """Limit equilibrium of the block cut out by ``halfspaces`` (`kgm.wedges.geometry.Halfspace`,
    outward normals; kind 'joint', 'crack' or 'free'), the joints' strength by label in
    ``joints`` (a `ddatai.Joint` each). Where the half-spaces cut out no finite block, or its
    joint pyramid is empty (tapered: it cannot move), ``forms`` is False with the reason."""
    for h in halfspaces:
        if not isinstance(h, Halfspace):
            raise ValueError(f"polyhedral_block: halfspaces must be kgm.wedges.Halfspace, got {type(h).__name__}")
        if h.kind == "joint" and h.label not in joints:
            raise ValueError(f"polyhedral_block: joint plane {h.label!r} has no strength in joints")
    for k in ("density", "gravity"):
        v = {"density": density, "gravity": gravity}[k]
        if not (_finite(v) and v > 0):
            raise ValueError(f"polyhedral_block: {k} must be > 0, got {v!r}")
    try:
        block = polyhedron(halfspaces)
    except NoBlock as exc:
        reason = "infinite" if exc.reason == "unbounded" else "no volume"
        return Wedge(forms=False, reason=f"{reason}: {exc}")
    inward = np.array([-f.normal for f in block.faces if f.kind != "free"])
    if len(inward) and jp_is_empty(inward):
        return Wedge(forms=False, reason="tapered: the block is finite but its joint pyramid is empty (it cannot leave its "
                            "socket)", block=block, volume=block.volume)
    joints = {h.label: joints[h.label] for h in halfspaces if h.kind == "joint"}
    return judge(block, joints, density=density, gravity=gravity, water_pressures=dict(water_pressures or {}),
                 seismic=seismic_load(seismic), bolts=tuple(bolts), forces=tuple(forces))


def water_pressures(water: Water, block: Polyhedron, contacts, nj, top, nu, gravity) -> dict:
    """Average water pressure on each contact face [Pa] (`Water`): Hoek & Bray's on every joint
    face and the crack, or the given ``pressures`` in the faces' order."""
    if water.pressures is not None:
        if len(water.pressures) != len(contacts):
            raise ValueError(f"Water.pressures has {len(water.pressures)} values for the wedge's "
                             f"{len(contacts)} faces ({', '.join(c.label for c in contacts)})")
        return {c.label: p for c, p in zip(contacts, water.pressures)}
    gamma = water.fill * water.density * gravity
    u = gamma * hoek_bray_head(block, nj, top, nu)
    return {c.label: u for c in contacts}


def hoek_bray_head(block: Polyhedron, nj, top, nu) -> float:
    """Hoek & Bray's average pressure head on a saturated wedge [m]: Hw/6, Hw the vertical
    height between the ends of the line of intersection of joints 1 and 2; with a tension crack
    cutting that line, H5w/3, H5w the depth of its end on the crack below the upper face (Hoek &
    Bray 1981, Appendix 2; Wyllie & Mah 2004, §III.3). Where the line is not an edge of the
    block (a basal joint below it), the block's vertical extent stands for Hw."""
    i = np.cross(nj[0], nj[1])
    if np.linalg.norm(i) < 1e-12:
        return float(np.ptp(block.vertices[:, 2])) / 6.0
    i = i / np.linalg.norm(i)
    i = i if i[2] > 0 else -i                            # up the line, from the toe
    t_end = math.inf
    exit_face = None
    for f in block.faces:
        d = float(f.normal @ i)
        if d > 1e-12:
            t = float(f.normal @ f.vertices[0]) / d
            if t < t_end:
                t_end, exit_face = t, f
    on_edge = all(float(f.normal @ (0.5 * t_end * i)) <= float(f.normal @ f.vertices[0]) + 1e-9 * t_end
                  for f in block.faces) if math.isfinite(t_end) and t_end > 0 else False
    if not on_edge:
        return float(np.ptp(block.vertices[:, 2])) / 6.0
    end = t_end * i
    if exit_face is not None and exit_face.kind == "crack":
        z_upper = top[2] - (nu[0] * (end[0] - top[0]) + nu[1] * (end[1] - top[1])) / nu[2]
        return (z_upper - end[2]) / 3.0
    return end[2] / 6.0


def _seismic_vector(seismic: Seismic, weight, contacts, active, passive, mass, nj) -> np.ndarray:
    """k·W horizontal along the trend of the static sliding direction (of the line of
    intersection of joints 1 and 2 where the block does not move), or along the given one."""
    trend = seismic.trend
    if trend is None:
        static = equilibrium(contacts, active, passive, mass).mode
        d = static.direction
        if static.kind == "stable" or np.linalg.norm(d[:2]) < 1e-12:
            if nj is None:
                raise ValueError("seismic: the block does not slide (or falls vertically) without the earthquake, "
                                 "so it has no sliding trend to load along; give one: kgm.Seismic(k, trend=...)")
            else:
                i = np.cross(nj[0], nj[1])
                d = i if i[2] < 0 else -i
        trend = math.degrees(math.atan2(d[0], d[1]))
    from .geometry import direction_vector

    return seismic.k * weight * direction_vector(trend, seismic.plunge)


@dataclass(frozen=True)
class KeyBlock:
    """A joint pyramid judged as a block of a free face (Goodman & Shi's types)."""

    pyramid: JointPyramid
    type: str
    """'I' key block (slides: friction-only FS < 1), 'II' potential key block (FS ≥ 1), 'III'
    removable but held whatever the friction (no mode), 'IV' tapered, 'V' infinite."""
    mode: Optional[Mode]
    """Its mode under the force (None for types IV and V)."""
    fs: float
    """Friction-only factor of safety (size-free; nan for IV and V) [-]."""


def face_key_blocks(joints: Sequence, free_outward_normals: Sequence, force=(0.0, 0.0, -1.0)) -> list:
    """Every joint pyramid of ``joints`` (`kgm.Plane` s with their ``joint``) as a block of the
    free faces with these outward normals, typed I–V under ``force`` (default: its weight),
    with its friction-only factor of safety: with c = 0 the normal forces scale with the force,
    so FS does not depend on the block's size or shape, only on its faces' orientations and
    friction angles (a Barton–Bandis joint counts with its residual angle)."""
    normals = np.array([j.normal for j in joints])
    out = []
    for p in joint_pyramids(normals, free_outward_normals):
        if p.kind != "removable":
            out.append(KeyBlock(p, "V" if p.kind == "infinite" else "IV", None, math.nan))
            continue
        contacts = [Contact(f"joint {k + 1}", s * n, 1.0, _friction_only(j.joint))
                    for k, (j, n, s) in enumerate(zip(joints, normals, p.code))]
        eq = equilibrium(contacts, np.asarray(force, float))
        kind = "III" if eq.mode.kind == "stable" else ("I" if eq.fs < 1.0 else "II")
        out.append(KeyBlock(p, kind, eq.mode, eq.fs))
    return out


def _friction_only(joint):
    from ddatai.params import Joint

    return None if joint is None else Joint(friction=joint.friction)
