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

    @classmethod
    def fit(cls, table, *, length: float, window: float, trend: float = 0.0, joint: Optional[Joint] = None,
            max_weight: float = 10.0) -> "JointSet":
        """The joint set of a table of mapped traces, corrected for sampling bias
        (`fit_mapping`, docs/method/joint_mapping.md): mean dip, spacing, trace length and gap
        with their spreads.

        ``table``: a CSV path or a mapping / rows with the columns ``dip`` [degrees],
        ``position`` [m], ``length`` [m], ``censored`` [0, 1, 2] and, for a non-persistent set,
        ``gap`` [m]; ``length``: the scanline's length [m]; ``window``: the mapping window's
        height across the scanline [m]; ``trend``: the scanline's direction [degrees CCW from
        +x]; ``joint``: the strength given to the set; ``max_weight``: the cap of Terzaghi's
        weight [-].
        """
        return fit_mapping(table, length=length, window=window, trend=trend, joint=joint,
                           max_weight=max_weight).joint_set

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
    ends: list[np.ndarray] = []
    owner: list[Joint] = []
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
                ends.append(np.array([origin + (a - radius) * d, origin + (b - radius) * d]))
                owner.append(s.joint)
            offset += _truncated_normal(rng, s.spacing, s.spacing_spread)
    out: list[tuple[np.ndarray, Joint]] = []
    if not ends:
        return out
    # clip all traces at once, those whose box misses the domain's left out
    xy = np.array(ends)
    lo_s, hi_s = xy.min(axis=1), xy.max(axis=1)
    near = np.flatnonzero(np.all(hi_s >= lo, axis=1) & np.all(lo_s <= hi, axis=1))
    clipped = shapely.intersection(shapely.linestrings(xy[near]), domain)
    for k, geom in zip(near.tolist(), clipped):
        for part in shapely.get_parts(geom):
            if part.geom_type == "LineString" and part.length > 1e-9 * radius:
                pts = np.asarray(part.coords)
                out.append((np.array([pts[0], pts[-1]]), owner[k]))
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


# ---------------------------------------------------------------------- fitting mapped joints
#: Columns of a mapping table (docs/method/joint_mapping.md); ``gap`` only for non-persistent sets.
MAPPING_COLUMNS = ("dip", "position", "length", "censored", "gap")


@dataclass(frozen=True, kw_only=True)
class MappingFit:
    """A joint set fitted to mapped traces (`fit_mapping`), with what it was fitted from."""

    joint_set: JointSet
    """The fitted set."""
    n_traces: int
    """Traces in the table (all recorded in the window) [-]."""
    n_scanline: int
    """Traces crossing the scanline (Terzaghi's sample) [-]."""
    n_contained: int
    """N2 of Pahl's estimator: traces with both ends seen [-]."""
    n_transecting: int
    """N0 of Pahl's estimator: traces crossing the whole window (both ends censored) [-]."""
    n_gaps: int
    """Rock bridges measured whole inside the window [-]."""
    trace_spacing: float
    """Terzaghi-corrected mean normal spacing of the traces met on the scanline, 1/λ [m]."""
    persistence: float
    """Linear persistence k = L/(L + g) of the set's lines [-] (1: persistent)."""


def read_mapping(table) -> dict:
    """The columns of a mapping table as float arrays (blank cells NaN). ``table``: a CSV file
    (path) with a header row, a mapping of column name to values (a dict, a pandas DataFrame)
    or a sequence of row mappings. Column names are matched case-insensitively;
    ``trace_length`` is taken for ``length``."""
    import csv
    import os

    if isinstance(table, (str, os.PathLike)):
        with open(table, newline="") as f:
            rows = list(csv.DictReader(row for row in f if not row.lstrip().startswith("#")))
        table = rows
    if hasattr(table, "keys"):
        cols = {str(k).strip().lower(): list(table[k]) for k in table.keys()}
    else:
        rows = list(table)
        keys = {str(k) for r in rows for k in r.keys()}
        cols = {k.strip().lower(): [r.get(k, "") for r in rows] for k in keys}
    if "trace_length" in cols and "length" not in cols:
        cols["length"] = cols.pop("trace_length")
    out = {}
    for name in MAPPING_COLUMNS:
        if name not in cols:
            if name == "gap":
                continue
            raise ValueError(f"mapping table: no column {name!r} (columns: {sorted(cols)}); expected "
                             f"{', '.join(MAPPING_COLUMNS)}")
        vals = []
        for k, v in enumerate(cols[name]):
            text = "" if v is None else str(v).strip()
            try:
                vals.append(float(text) if text else math.nan)
            except ValueError:
                raise ValueError(f"mapping table: column {name!r}, row {k + 1}: {v!r} is not a number") from None
        out[name] = np.array(vals, dtype=float)
    return out


def _axial_mean(angle_deg: np.ndarray, weight: np.ndarray) -> tuple[float, float]:
    """Weighted mean and standard deviation of axial angles [degrees, mod 180] (the doubled-
    angle circular mean, eq. M1)."""
    a = np.radians(2.0 * angle_deg)
    mean = 0.5 * math.degrees(math.atan2(float(np.sum(weight * np.sin(a))), float(np.sum(weight * np.cos(a)))))
    mean %= 180.0
    dev = (angle_deg - mean + 90.0) % 180.0 - 90.0
    return mean, math.sqrt(float(np.sum(weight * dev * dev) / np.sum(weight)))


def _contained_moments(x: np.ndarray, h: np.ndarray) -> tuple[float, float]:
    """Mean and standard deviation of lengths seen whole in a window of height h (along the
    trace), each weighted by 1/(h − x), the inverse of its chance of being seen whole
    (Horvitz–Thompson, eq. M5)."""
    keep = x < h
    w = 1.0 / (h[keep] - x[keep])
    x = x[keep]
    if len(x) < 2:
        return (float(x[0]) if len(x) else math.nan), 0.0
    mean = float(np.sum(w * x) / np.sum(w))
    var = float(np.sum(w * (x - mean) ** 2) / np.sum(w))
    n_eff = float(np.sum(w) ** 2 / np.sum(w * w))
    return mean, math.sqrt(var * n_eff / (n_eff - 1.0)) if n_eff > 1 else 0.0


def fit_mapping(table, *, length: float, window: float, trend: float = 0.0, joint: Optional[Joint] = None,
                max_weight: float = 10.0) -> MappingFit:
    """Fit a `JointSet` to traces of one set mapped in a window along a scanline.

    The survey (docs/method/joint_mapping.md): a straight scanline of ``length`` [m] in the
    section plane, trending ``trend`` [degrees CCW from +x], in the middle of a window of height
    ``window`` [m] across it. Every trace of the set in the window whose line, extended, crosses
    the scanline between its ends is one row: ``dip`` its apparent dip [degrees, 0–180],
    ``position`` where the trace itself crosses the scanline [m from its start; blank if it
    stops short of it], ``length`` the part seen in the window [m], ``censored`` how many of
    its two ends lie beyond the window (0, 1, 2), and ``gap`` the rock bridge from its up-dip
    end to the next trace on its line when both are seen in the window [m; blank otherwise].

    Estimators, each correcting a sampling bias:

    * dip: Terzaghi's weight 1/abs(sin δ) (δ between trace and scanline, capped at ``max_weight``)
      on the traces crossing the scanline, doubled-angle mean (eq. M1–M2);
    * trace length: Pahl's estimator μ = h·(N + N0 − N2)/(N − N0 + N2) for censored traces in a
      window of height h along the set (eq. M3), its spread from the traces seen whole,
      weighted by their chance of being seen whole (eq. M5); all traces transecting: persistent;
    * gap: the rock bridges seen whole, weighted likewise (eq. M5);
    * spacing: the Terzaghi-weighted frequency λ of traces on the scanline gives their normal
      spacing 1/λ; the lines carry traces over a fraction k = L/(L + g) of their length, so
      the spacing of the lines is k/λ, and its spread follows from the spacings along the
      scanline (sums of a geometric number of line spacings, eq. M4).
    """
    def positive(name, v):
        if not (isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) and v > 0):
            raise ValueError(f"JointSet.fit: {name} must be a finite number > 0, got {v!r}")

    positive("length (of the scanline) [m]", length)
    positive("window (height of the mapping window) [m]", window)
    positive("max_weight", max_weight)
    if not (isinstance(trend, (int, float)) and math.isfinite(trend)):
        raise ValueError(f"JointSet.fit: trend must be a finite angle in degrees, got {trend!r}")
    if joint is not None and not isinstance(joint, Joint):
        raise ValueError(f"JointSet.fit: joint must be a ddatai.Joint, got {type(joint).__name__}")
    cols = read_mapping(table)
    dip, pos, seen, cens = cols["dip"], cols["position"], cols["length"], cols["censored"]
    n = len(dip)
    if n < 2:
        raise ValueError(f"JointSet.fit: the table has {n} traces; at least 2 are needed")
    for name, ok, what in (
            ("dip", np.isfinite(dip) & (dip >= 0) & (dip < 180), "an angle in [0, 180) degrees"),
            ("length", np.isfinite(seen) & (seen > 0), "a number > 0 m"),
            ("censored", np.isin(cens, (0.0, 1.0, 2.0)), "0, 1 or 2 (ends beyond the window)"),
            ("position", np.isnan(pos) | ((pos >= 0) & (pos <= length)), "blank or in [0, length] m")):
        bad = np.flatnonzero(~ok)
        if len(bad):
            k = int(bad[0])
            raise ValueError(f"JointSet.fit: column {name!r}, row {k + 1}: {cols[name][k]!r} must be {what}")
    sin_d = np.abs(np.sin(np.radians(dip - trend)))
    if np.any(sin_d < 1e-9):
        raise ValueError("JointSet.fit: a trace parallel to the scanline cannot cross it (dip = trend)")
    weight = np.minimum(1.0 / sin_d, max_weight)           # Terzaghi (eq. M2)
    on_line = np.isfinite(pos)
    if np.count_nonzero(on_line) < 2:
        raise ValueError("JointSet.fit: fewer than 2 traces cross the scanline (column 'position')")
    mean_dip, dip_sd = _axial_mean(dip[on_line], weight[on_line])
    # trace length: Pahl (eq. M3), h along each trace's line
    h_row = window / sin_d
    h = float(np.mean(h_row))
    n0, n2 = int(np.sum(cens == 2)), int(np.sum(cens == 0))
    persistent = n0 == n
    trace_length = trace_sd = None
    gap = gap_sd = 0.0
    n_gaps = 0
    k = 1.0
    if not persistent:
        trace_length = h * (n + n0 - n2) / (n - n0 + n2)
        contained = cens == 0
        trace_sd = _contained_moments(seen[contained], h_row[contained])[1] if contained.any() else 0.0
        if np.count_nonzero(contained) < 2:
            import warnings

            warnings.warn(f"JointSet.fit: {np.count_nonzero(contained)} trace(s) seen whole in the window "
                          f"(h = {h:.3g} m along the set, mean trace {trace_length:.3g} m): the spread of "
                          f"the trace length cannot be estimated and is set to 0; map a higher window",
                          UserWarning, stacklevel=3)
        gaps = cols.get("gap")
        seen_gap = np.isfinite(gaps) if gaps is not None else np.zeros(n, bool)
        n_gaps = int(np.count_nonzero(seen_gap))
        if n_gaps < 2:
            raise ValueError("JointSet.fit: the set is not persistent (traces end in the window) and the "
                             "table measures fewer than 2 rock bridges (column 'gap'): the gap, and with it "
                             "the spacing of the joint lines, cannot be fitted")
        if np.any(gaps[seen_gap] <= 0):
            raise ValueError("JointSet.fit: column 'gap' must be > 0 m where given")
        gap, gap_sd = _contained_moments(gaps[seen_gap], h_row[seen_gap])
        k = trace_length / (trace_length + gap)
    # spacing: Terzaghi frequency on the scanline (eq. M4)
    lam = float(np.sum(weight[on_line])) / length
    trace_spacing = 1.0 / lam
    spacing = k * trace_spacing
    steps = np.diff(np.sort(pos[on_line])) * abs(math.sin(math.radians(mean_dip - trend)))
    var_obs = float(np.var(steps, ddof=1)) if len(steps) > 1 else 0.0
    spacing_sd = math.sqrt(max(k * var_obs - (1.0 - k) * spacing ** 2 / k, 0.0))
    js = JointSet(dip=float(mean_dip), spacing=float(spacing), trace_length=trace_length, gap=float(gap),
                  dip_spread=float(dip_sd), spacing_spread=float(spacing_sd),
                  trace_spread=float(trace_sd or 0.0), gap_spread=float(gap_sd),
                  joint=joint if joint is not None else Joint())
    return MappingFit(joint_set=js, n_traces=n, n_scanline=int(np.count_nonzero(on_line)), n_contained=n2,
                      n_transecting=n0, n_gaps=n_gaps, trace_spacing=trace_spacing, persistence=k)
