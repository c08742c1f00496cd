"""The wedge of a rock slope: `wedge` builds it from a slope face, an upper face, a height and
two (or three) joints, judges its block theory and its limit equilibrium (docs/kgm/wedge.md).

The toe of the wedge, where the joints meet the slope face, is the origin; x east, y north,
z up [m]. ``height`` H is the vertical height of the crest above the toe measured along the
trace of joint 1 on the face (Hoek & Bray's H1, SWedge's slope height); with
``height_reference="face"`` it is measured up the face's line of steepest dip instead. A
tension crack is a plane at ``distance`` L behind the crest, measured along the trace of
joint 1 on the upper face (Hoek & Bray's L); a third joint is a basal joint through the toe
(a pentahedral wedge). ``bench_width`` and ``slope_length`` limit the wedge as SWedge does: the wedge is
scaled about its toe (H reduced) until it lies within that horizontal distance behind the
crest and that length along the crest.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Optional, Sequence

import numpy as np

from .block import Wedge, judge, water_pressures
from .block_theory import JointPyramid, block_pyramid_direction, jp_is_empty
from .geometry import Halfspace, NoBlock, Plane, Polyhedron, _finite, polyhedron, trend_plunge
from .mechanics import Bolt, Force, Water, seismic_load


@dataclass(frozen=True)
class TensionCrack:
    """A tension crack: its orientation and its ``distance`` L behind the crest along the trace
    of joint 1 on the upper face [m]. No strength (it opens); water fills it with the joints."""

    plane: Plane
    distance: float

    def __post_init__(self) -> None:
        if not isinstance(self.plane, Plane):
            raise ValueError(f"TensionCrack.plane must be a kgm.Plane, got {type(self.plane).__name__}")
        if not (_finite(self.distance) and self.distance > 0):
            raise ValueError(f"TensionCrack.distance must be > 0 m, got {self.distance!r}")


def wedge(face: Plane, upper: Plane, height: float, joints: Sequence[Plane], *, density: float = 2600.0,
          water: Optional[Water] = None, seismic=None, bolts: Sequence[Bolt] = (),
          tension_crack: Optional[TensionCrack] = None, bench_width: Optional[float] = None,
          slope_length: Optional[float] = None, forces: Sequence[Force] = (), gravity: float = 9.81,
          height_reference: str = "joint1") -> Wedge:
    """The wedge that ``joints`` (two, or three with a basal joint, each a `Plane` with a
    ``joint``) cut from a slope with this ``face`` and ``upper`` face, ``height`` H [m], and
    its factor of safety (module docstring; docs/kgm/wedge.md).

    ``density`` ρ [kg/m³] and ``gravity`` g [m/s²] give W = ρ g V; ``water`` a `Water`;
    ``seismic`` a coefficient k (horizontal, along the sliding trend), a `Seismic` or a vector
    in g; ``bolts`` `Bolt` s; ``forces`` external `Force` s; ``tension_crack`` a `TensionCrack`
    or a (Plane, distance) pair. Returns a `Wedge`; where no wedge forms, ``forms`` is False and
    ``reason`` says why (not daylighting, infinite, tapered, no volume).
    """
    inputs = dict(face=face, upper=upper, height=height, joints=tuple(joints), density=density, water=water,
                  seismic=seismic, bolts=tuple(bolts), tension_crack=tension_crack, bench_width=bench_width,
                  slope_length=slope_length, forces=tuple(forces), gravity=gravity, height_reference=height_reference)
    crack = _check(inputs)
    seismic = seismic_load(seismic)
    nf, nu = face.normal, upper.normal
    nj = np.array([j.normal for j in joints])
    labels = [f"joint {k + 1}" for k in range(len(joints))]
    top = _crest_point(nf, nu, nj[0], face, height_reference)
    pyramids, candidates = _pyramids(nf, nu, nj, crack, top * height)
    if not candidates:
        return Wedge(forms=False, reason=_why_none(pyramids, nf, nu, nj), pyramids=tuple(pyramids), inputs=inputs)
    best = None
    for code in candidates:
        scale = _size_scale(nf, nu, nj, code, top * height, bench_width, slope_length)
        halfspaces = _halfspaces(nf, nu, nj, code, top * scale * height, crack, labels)
        try:
            block = polyhedron(halfspaces, scale=height)
        except NoBlock as exc:
            reason = f"no volume: {exc}"
            continue
        if crack is not None and block.area("tension crack") <= 0.0:
            reason = "the tension crack does not cut the wedge"
            continue
        w = _judge(block, code, joints, labels, crack, top * scale * height, nu, density, gravity, water, seismic,
                   bolts, forces, scale * height, nj, pyramids, inputs)
        if best is None or w.fs < best.fs:
            best = w
    if best is None:
        return Wedge(forms=False, reason=reason, pyramids=tuple(pyramids), inputs=inputs)
    return best


def _check(inputs: dict) -> Optional[tuple]:
    face, upper, joints = inputs["face"], inputs["upper"], inputs["joints"]
    for name in ("face", "upper"):
        if not isinstance(inputs[name], Plane):
            raise ValueError(f"wedge: {name} must be a kgm.Plane, got {type(inputs[name]).__name__}")
    if not 2 <= len(joints) <= 3:
        raise ValueError(f"wedge: joints must be two joint planes (and an optional basal joint), got {len(joints)}")
    for k, j in enumerate(joints):
        if not isinstance(j, Plane):
            raise ValueError(f"wedge: joint {k + 1} must be a kgm.Plane, got {type(j).__name__}")
        if j.joint is None:
            raise ValueError(f"wedge: joint {k + 1} ({j.dip:g}/{j.dip_direction:g}) needs its strength: "
                             f"kgm.Plane(dip, dip_direction, joint=ddatai.Joint(...))")
    for name in ("height", "density", "gravity"):
        v = inputs[name]
        if not (_finite(v) and v > 0):
            raise ValueError(f"wedge: {name} must be a finite number > 0, got {v!r}")
    for name in ("bench_width", "slope_length"):
        v = inputs[name]
        if v is not None and not (_finite(v) and v > 0):
            raise ValueError(f"wedge: {name} must be None or a length > 0 m, got {v!r}")
    if face.dip <= upper.dip:
        raise ValueError(f"wedge: the slope face ({face.dip:g}°) must be steeper than the upper face ({upper.dip:g}°)")
    if inputs["water"] is not None and not isinstance(inputs["water"], Water):
        raise ValueError(f"wedge: water must be a kgm.Water or None, got {type(inputs['water']).__name__}")
    for b in inputs["bolts"]:
        if not isinstance(b, Bolt):
            raise ValueError(f"wedge: bolts must be kgm.Bolt, got {type(b).__name__}")
    for f in inputs["forces"]:
        if not isinstance(f, Force):
            raise ValueError(f"wedge: forces must be kgm.Force, got {type(f).__name__}")
    if inputs["height_reference"] not in ("joint1", "face"):
        raise ValueError(f"wedge: height_reference must be 'joint1' or 'face', got {inputs['height_reference']!r}")
    crack = inputs["tension_crack"]
    if crack is None:
        return None
    if not isinstance(crack, TensionCrack):
        try:
            crack = TensionCrack(*crack)
        except TypeError:
            raise ValueError(f"wedge: tension_crack must be a kgm.TensionCrack or (Plane, distance), got {crack!r}") from None
    return crack.plane.normal, crack.distance


def _crest_point(nf, nu, n1, face: Plane, reference: str) -> np.ndarray:
    """The point of the crest at unit height above the toe (joint 1's trace, or the face's
    dip line)."""
    if reference == "face":
        g = -face.dip_vector
    else:
        g = np.cross(nf, n1)
        if abs(g[2]) < 1e-9 * np.linalg.norm(g):
            raise ValueError("wedge: joint 1 strikes parallel to the slope face, so its trace on the face is "
                             "horizontal and cannot measure the height; use height_reference='face'")
    g = g if g[2] > 0 else -g
    return g / g[2]


def _pyramids(nf, nu, nj, crack, top) -> tuple[list, list]:
    """Every joint pyramid with the slope and upper faces as free faces (the crack, when there
    is one, as a joint on the toe's side); codes of the finite removable ones."""
    import itertools

    free = np.array([nf, nu])
    pyramids, candidates = [], []
    crack_inward = None
    if crack is not None:
        crack_inward = -_halfspaces(nf, nu, nj, (1,) * len(nj), top, crack, [""] * len(nj))[-1].normal
    for code in itertools.product((1, -1), repeat=len(nj)):
        v = nj * np.array(code, dtype=float)[:, None]
        if crack_inward is not None:
            v = np.vstack([v, crack_inward])
        # finiteness by the exact cone test (the LP of block_theory.is_finite gives the same)
        p = JointPyramid(code=code, empty=jp_is_empty(v), finite=block_pyramid_direction(v, free) is None)
        pyramids.append(p)
        if p.kind == "removable":
            candidates.append(code)
    return pyramids, candidates


def _halfspaces(nf, nu, nj, code, top, crack, labels) -> list:
    out = [Halfspace(nf.copy(), 0.0, "slope face", "free"),
           Halfspace(nu.copy(), float(nu @ top), "upper face", "free")]
    for n, s, label in zip(nj, code, labels):
        out.append(Halfspace(-s * n, 0.0, label, "joint"))
    if crack is not None:
        nc, distance = crack
        t = np.cross(nu, nj[0])
        t = t / np.linalg.norm(t)
        if t @ nf > 0:
            t = -t
        q = top + distance * t
        o = nc if nc @ (np.zeros(3) - q) < 0 else -nc
        out.append(Halfspace(o, float(o @ q), "tension crack", "crack"))
    return out


def _size_scale(nf, nu, nj, code, top, bench_width, slope_length) -> float:
    """Factor (≤ 1) on the height that keeps the wedge within the bench width behind the crest
    and the slope length along it (the wedge without crack scales about its toe)."""
    if bench_width is None and slope_length is None:
        return 1.0
    block = polyhedron(_halfspaces(nf, nu, nj, code, top, None, ["joint 1", "joint 2", "joint 3"][:len(nj)]))
    h = -nf[:2] / np.linalg.norm(nf[:2])
    behind = np.max((block.vertices[:, :2] - top[:2]) @ h)
    along = (block.vertices[:, :2] @ np.array([h[1], -h[0]]))
    scale = 1.0
    if bench_width is not None and behind > bench_width:
        scale = min(scale, bench_width / behind)
    if slope_length is not None and np.ptp(along) > slope_length:
        scale = min(scale, slope_length / np.ptp(along))
    return scale


def _why_none(pyramids, nf, nu, nj) -> str:
    i = np.cross(nj[0], nj[1])
    if np.linalg.norm(i) < 1e-9:
        return "joints 1 and 2 are parallel: they cut no wedge"
    if any(p.kind == "tapered" for p in pyramids):
        return "tapered: the block is finite but its joint pyramid is empty (it cannot leave its socket)"
    i = i if i[2] < 0 else -i                       # downwards along the line of intersection
    t, p = trend_plunge(i)
    if nf @ i <= 0:
        return (f"not daylighting: the line of intersection ({t:.1f}°/{p:.1f}°) does not daylight in the slope "
                f"face (it plunges into the slope), so the wedge would be infinite")
    if nu @ (-i) <= 0:
        return (f"infinite: the line of intersection ({t:.1f}°/{p:.1f}°) does not reach the upper face, so the "
                f"wedge does not close behind the crest")
    return "infinite: every joint pyramid meets the rock's excavation pyramid (BP = JP ∩ EP is not {0})"


def _judge(block: Polyhedron, code, joints, labels, crack, top, nu, density, gravity, water, seismic, bolts, forces,
           height, nj, pyramids, inputs) -> Wedge:
    strength = {label: j.joint for label, j in zip(labels, joints)}
    contacts = [f for f in block.faces if f.kind != "free"]
    pressures = water_pressures(water, block, contacts, nj, top, nu, gravity) if water is not None else {}
    return judge(block, strength, density=density, gravity=gravity, water_pressures=pressures, seismic=seismic,
                 bolts=bolts, forces=forces, nj=nj, height=height,
                 pyramid="".join("0" if s > 0 else "1" for s in code), pyramids=tuple(pyramids), inputs=inputs)
