"""Joint-set generator: statistical joint traces for `Scene.cut`.

A joint set in a 2D section is a family of roughly parallel traces: their apparent dip, their
perpendicular spacing, and — for non-persistent joints — the length of each trace and the gap
(rock bridge) between successive traces on the same line. Each quantity may scatter: spacing,
trace length and gap follow normal distributions truncated at 5 % of their mean, the dip of
each line a normal distribution in degrees. The generator is reproducible for a seed.

The first line of a set is placed at a uniform random offset within one spacing, and the lines
cover the boundary's bounding box; traces are clipped to the boundary polygon.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Optional, Sequence

import numpy as np

from .params import Joint


@dataclass(frozen=True, kw_only=True)
class JointSet:
    """One joint set in the section plane."""

    dip: float
    """Apparent dip of the traces [degrees], measured counter-clockwise from +x, in [0, 180)."""
    spacing: float
    """Mean perpendicular distance between successive traces [m], > 0."""
    trace_length: Optional[float] = None
    """Mean length of a trace [m]; None = persistent (traces cross the whole domain)."""
    gap: float = 0.0
    """Mean gap (rock bridge) between successive traces on one line [m]; non-persistent sets."""
    dip_spread: float = 0.0
    """Standard deviation of each line's dip [degrees]."""
    spacing_spread: float = 0.0
    """Standard deviation of the spacing [m]."""
    trace_spread: float = 0.0
    """Standard deviation of the trace length [m]."""
    gap_spread: float = 0.0
    """Standard deviation of the gap [m]."""
    joint: Joint = field(default_factory=Joint)
    """Strength of the joints of this set (carried to the contacts by `Scene.cut`)."""

    def __post_init__(self) -> None:
        def check(name: str, ok: bool, what: str) -> None:
            if not ok:
                raise ValueError(f"JointSet.{name} must be {what}, got {getattr(self, name)!r}")

        finite = lambda v: isinstance(v, (int, float)) and math.isfinite(v)  # noqa: E731
        check("dip", finite(self.dip) and 0.0 <= self.dip < 180.0, "in [0, 180) degrees")
        check("spacing", finite(self.spacing) and self.spacing > 0, "a number > 0 m")
        check("trace_length", self.trace_length is None or (finite(self.trace_length) and self.trace_length > 0),
              "None (persistent) or a number > 0 m")
        check("gap", finite(self.gap) and self.gap >= 0, "a number >= 0 m")
        if self.trace_length is not None:
            check("gap", self.gap > 0, "> 0 m for a non-persistent set (else use trace_length=None)")
        for name in ("dip_spread", "spacing_spread", "trace_spread", "gap_spread"):
            check(name, finite(getattr(self, name)) and getattr(self, name) >= 0, "a number >= 0")
        check("joint", isinstance(self.joint, Joint), "a ddatai.Joint")


def _truncated_normal(rng: np.random.Generator, mean: float, sd: float) -> float:
    if sd == 0:
        return mean
    while True:
        x = rng.normal(mean, sd)
        if x >= 0.05 * mean:
            return float(x)


def joint_sets(boundary, sets: Sequence[JointSet], seed: int = 0) -> list[tuple[np.ndarray, Joint]]:
    """Generate joint traces of several sets inside a domain polygon.

    Returns a list of ``(polyline (2, 2) array [m], Joint)``, ready for
    ``scene.cut(boundary, traces, material)``.

    >>> from ddatai.jointsets import JointSet, joint_sets
    >>> box = [(0, 0), (10, 0), (10, 5), (0, 5)]
    >>> traces = joint_sets(box, [JointSet(dip=30.0, spacing=1.0)], seed=1)
    >>> len(traces) > 0
    True
    """
    import shapely

    from .geometry import validate_polygon

    outline = validate_polygon(boundary, name="joint_sets boundary")
    domain = shapely.Polygon(outline)
    if not sets:
        return []
    for k, s in enumerate(sets):
        if not isinstance(s, JointSet):
            raise ValueError(f"joint set {k}: expected a ddatai.JointSet, got {type(s).__name__}")
    rng = np.random.default_rng(seed)
    lo, hi = outline.min(axis=0), outline.max(axis=0)
    centre = 0.5 * (lo + hi)
    radius = 0.5 * float(np.hypot(*(hi - lo))) * 1.01
    out: list[tuple[np.ndarray, Joint]] = []
    for s in sets:
        base = math.radians(s.dip)
        normal = np.array([-math.sin(base), math.cos(base)])
        # lines at perpendicular offsets covering the bounding circle
        offset = -radius + rng.uniform(0.0, s.spacing)
        while offset <= radius:
            dip = base + math.radians(rng.normal(0.0, s.dip_spread)) if s.dip_spread else base
            d = np.array([math.cos(dip), math.sin(dip)])
            origin = centre + offset * normal
            for a, b in _segments(rng, s, 2.0 * radius):
                seg = shapely.LineString([origin + (a - radius) * d, origin + (b - radius) * d])
                clipped = shapely.intersection(seg, domain)
                for part in shapely.get_parts(clipped):
                    if part.geom_type == "LineString" and part.length > 1e-9 * radius:
                        xy = np.asarray(part.coords)
                        out.append((np.array([xy[0], xy[-1]]), s.joint))
            offset += _truncated_normal(rng, s.spacing, s.spacing_spread)
    return out


def _segments(rng: np.random.Generator, s: JointSet, length: float):
    """(start, end) positions of the traces along one line of the given length."""
    if s.trace_length is None:
        yield 0.0, length
        return
    # start at a random phase of one trace + gap period, so lines are not aligned
    pos = -rng.uniform(0.0, s.trace_length + s.gap)
    while pos < length:
        trace = _truncated_normal(rng, s.trace_length, s.trace_spread)
        a, b = max(pos, 0.0), min(pos + trace, length)
        if b > a:
            yield a, b
        pos += trace + _truncated_normal(rng, s.gap, s.gap_spread)
