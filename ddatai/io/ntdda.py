"""Read ntdda ("DDA for Windows") input files and run them.

ntdda, the Berkeley C port of Shi's DC/DF programs, reads a geometry file (``.geo``: joint
lines, material lines, fixed, load, measured and hole points) and an analysis file (``.ana``:
materials, joint properties, time step, load histories), each either in Shi's original
whitespace-separated text format or in the XML "DDAML" format (docs/ntdda.md §4). The format of
each file is detected from its first characters.

>>> import ddatai as dd
>>> case = dd.read_ntdda("pushblock.geo", "pushblock.ana")     # doctest: +SKIP
>>> print(case.summary())                                       # doctest: +SKIP
>>> res = case.simulate()                                       # doctest: +SKIP
>>> from ddatai.io.ntdda import write_measured_csv
>>> write_measured_csv(res, case, "pushblock.csv")               # doctest: +SKIP

Where ntdda behaves oddly (docs/ntdda.md §3) the reader makes an
explicit choice, documented where it is made and in docs/guide/ntdda_files.md, and warns
with an `NtddaQuirkWarning` when a file relies on the odd behaviour. Settings ddatai does not
implement are ignored with an `NtddaUnsupportedWarning`. A malformed file raises
`NtddaFormatError` (a ``ValueError``) naming the file, the line (text format) or the line and
element (DDAML) and what was expected, before any simulation work.

Units: ntdda files use whatever consistent units their author chose; ddatai's SI names (m, kg,
Pa) then stand for those units. Unit mass ρ enters inertia and unit weight γ the body force,
so the effective gravity is γ/ρ (docs/method/dda.md §6.3).

Run from the command line: ``ddatai run MODEL.geo MODEL.ana --out DIR`` (`ddatai.cli`).
No Taichi at import: the solver is loaded only by `NtddaCase.simulate`.
"""

from __future__ import annotations

import math
import re
import warnings
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Literal, Optional

import numpy as np

from .ntdda_geometry import (BlockLocator, block_materials, blocks_inside_other_blocks,
                             clip_fixed_line, cut_segments, ntdda_fixed_points)
from ..params import Joint, Material, Params, UnitWarning
from ..scene import Scene

Format = Literal["ddaml", "original"]

#: ntdda's contact constants when a DDAML file gives none (constants.c; docs/ntdda.md §4.5).
NTDDA_OPENCLOSE = 2e-4
NTDDA_OPENCRITERIA = 2e-7
NTDDA_NORM_SPRING_PEN = 4e-4
NTDDA_ANGLE_OVERLAP = 3.0
NTDDA_SHEAR_NORM_RATIO = 2.5
#: ntdda's hard-coded open-close iteration cap (analysisdriver.c, docs/ntdda.md §3.4).
NTDDA_OC_LIMIT = 8
#: ntdda's default penalty factor and gravitational acceleration.
NTDDA_PFACTOR = 50.0
NTDDA_GRAVITY = 9.81
#: Relative mismatch of two unit-weight ratios γ/ρ that is reported.
_RATIO_TOL = 1e-6


class NtddaFormatError(ValueError):
    """A malformed or unusable ntdda input file. The message names the file, the line (text
    format) or line and element (DDAML) and what was expected."""


class NtddaWarning(UserWarning):
    """Base class of the warnings issued while reading ntdda files."""


class NtddaQuirkWarning(NtddaWarning):
    """The file relies on an ntdda quirk or bug; ddatai makes the documented choice instead
    (docs/guide/ntdda_files.md)."""


class NtddaUnsupportedWarning(NtddaWarning):
    """The file uses an ntdda setting ddatai does not implement; it is ignored."""


# ============================================================================ raw file content
@dataclass(frozen=True, kw_only=True, eq=False)
class NtddaGeometry:
    """Content of an ntdda geometry file, as written (nothing cut yet).

    Lengths are in the file's length unit. Every record keeps where it came from
    (``*_where``: "line 12" or "line 12, <Joint>") for error messages.
    """

    path: str
    """The file read."""
    format: Format
    """"original" (GHS text) or "ddaml" (XML)."""
    edge_node_distance: float
    """e00: node-merging tolerance relative to the domain scale w0 [-]."""
    joints: np.ndarray
    """(n, 4) joint segments x1 y1 x2 y2 [length]."""
    joint_type: np.ndarray
    """(n,) joint-material index of each segment, 1-based."""
    joint_where: tuple
    """Where each joint line is in the file."""
    n_boundary_lines: int
    """The first segments treated as GHS boundary lines (original format only)."""
    material_lines: np.ndarray
    """(m, 4) material lines x1 y1 x2 y2 [length]."""
    material_line_type: np.ndarray
    """(m,) block-material index of each material line, 1-based."""
    material_line_where: tuple
    """Where each material line is in the file."""
    fixed_lines: np.ndarray
    """(k, 4) fixed lines x1 y1 x2 y2 [length]; a fixed point is a zero-length line."""
    fixed_where: tuple
    """Where each fixed line or point is in the file."""
    load_points: np.ndarray
    """(nl, 2) load points [length]; the i-th pairs with the i-th load history."""
    load_where: tuple
    """Where each load point is in the file."""
    measured_points: np.ndarray
    """(nm, 2) measured points [length]."""
    measured_where: tuple
    """Where each measured point is in the file."""
    hole_points: np.ndarray
    """(nh, 2) hole points [length]: blocks containing one are deleted."""
    hole_where: tuple
    """Where each hole point is in the file."""
    seismic_points: np.ndarray
    """(ns, 2) seismic points [length] (DDAML; ignored, as ntdda does in effect)."""
    n_bolts: int
    """Rock bolts declared (not supported)."""
    bolts_where: str
    """Where the first bolt is declared."""
    warnings: tuple = ()
    """Warning messages issued while reading."""


@dataclass(frozen=True, kw_only=True)
class NtddaBlockMaterial:
    """One block material of an analysis file (its units are the file's)."""

    unit_mass: float
    """ρ, used for inertia [mass/length³]."""
    unit_weight: Optional[float]
    """γ, the weight per volume [force/length³]; None if the DDAML file omits it."""
    young: float
    """Young's modulus E [force/length²]."""
    poisson: float
    """Poisson's ratio ν [-]."""
    damping: float
    """Block damping (ntdda reads it and never uses it) [-]."""
    stress: tuple
    """Initial stress (σx, σy, τxy) [force/length²]."""
    stress_gradient: tuple
    """Original format: stress change per unit height; σ = stress + y_centroid·gradient."""
    velocity: tuple
    """Initial velocity (vx, vy, ω) [length/time, rad/time]."""
    strain: tuple
    """DDAML ``Istrain`` (never used by ntdda; not supported)."""
    where: str
    """Where the record is in the file."""


@dataclass(frozen=True, kw_only=True)
class NtddaJointMaterial:
    """One joint material: Mohr–Coulomb strength of the contacts on joints of its type."""

    friction: float
    """Friction angle φ [degrees]."""
    cohesion: float
    """Cohesion c [force/length²]."""
    tensile: float
    """Tensile strength T [force/length²]."""
    where: str
    """Where the record is in the file."""


@dataclass(frozen=True, kw_only=True, eq=False)
class NtddaAnalysis:
    """Content of an ntdda analysis file, with ntdda's implicit settings filled in."""

    path: str
    """The file read."""
    format: Format
    """"original" (GHS text) or "ddaml" (XML)."""
    dynamic: bool
    """Dynamic analysis (velocities carried between steps); False: static."""
    n_steps: int
    """Number of time steps."""
    max_time_step: float
    """g1 / ``Maxtimestep``: the fixed time step, or the largest automatic one [time]."""
    auto_time_step: bool
    """ntdda's automatic time step (always on in the original format)."""
    max_displacement: float
    """g2: largest step displacement as a fraction of the domain scale [-]."""
    auto_penalty: bool
    """ntdda's per-step penalty re-estimation (always on in the original format)."""
    penalty_factor: float
    """Penalty = factor × the largest Young's modulus [-]."""
    plane_strain: bool
    """Plane strain (DDAML ``Planestrain``); plane stress otherwise."""
    rotation: str
    """"linear", "secondorder" or "exact" (ddatai always updates rotations exactly)."""
    gravity_turn_on: bool
    """ntdda's gravity turn-on phase (``<Gravity flag="yes">``): ddatai's equilibrium stage
    (`Params.initial_equilibrium`); without it gravity acts suddenly from t = 0, as in ntdda."""
    gravity_acceleration: Optional[float]
    """``Gravaccel`` [length/time²]; None when the file gives none."""
    oc_limit: int
    """Open-close iteration limit."""
    save_interval: int
    """Record every this many steps."""
    contact_damping: float
    """``ContactDamping`` (not supported)."""
    openclose: float
    """ntdda's re-closing tolerance / w0 (read; ddatai keeps its own, docs/guide/method_choices.md)."""
    opencriteria: float
    """ntdda's opening tolerance / w0 (read; ddatai keeps its own, docs/guide/method_choices.md)."""
    norm_spring_pen: float
    """g3: allowed penetration / w0 [-]."""
    angle_overlap: float
    """Angle tolerance of contact detection [degrees]."""
    shear_norm_ratio: float
    """Normal / shear spring ratio [-]."""
    block_materials: tuple
    """`NtddaBlockMaterial` per material index (1-based in the files)."""
    joint_materials: tuple
    """`NtddaJointMaterial` per joint type (1-based in the files)."""
    load_histories: tuple
    """Per load point, an (n, 3) array of records t fx fy [time, force]."""
    load_where: tuple
    """Where each load history is in the file."""
    warnings: tuple = ()
    """Warning messages issued while reading."""


# ============================================================================ small helpers
def _warn(log: list, category, message: str) -> None:
    """Record the message and warn, attributing the warning to the first caller outside
    ddatai (the user's ``read_ntdda`` line)."""
    import sys

    log.append(message)
    package = str(Path(__file__).resolve().parent)
    frame, level = sys._getframe(1), 2
    while frame is not None and str(Path(frame.f_code.co_filename).resolve()).startswith(package):
        frame, level = frame.f_back, level + 1
    warnings.warn(message, category, stacklevel=level)


_NUMBER = re.compile(r"^[+-]?(\d+\.?\d*|\.\d+)([eE][+-]?\d+)?$")
_INTEGER = re.compile(r"^[+-]?\d+$")


def _to_float(token: str) -> Optional[float]:
    if not _NUMBER.match(token):
        return None
    return float(token)


def _detect_format(path: Path, text: str) -> Format:
    """ntdda sniffs the first token (docs/ntdda.md §4.1): ``<?`` is DDAML. We take the first
    non-blank characters, so a leading blank line (an error for ntdda) is accepted."""
    head = text.lstrip()
    if not head:
        raise NtddaFormatError(f"{path}: the file is empty")
    if head.startswith("<"):
        return "ddaml"
    if head.split(None, 1)[0] == "#!0xDDA-v1.5":
        raise NtddaFormatError(f"{path}, line 1: the obsolete 'extended' format #!0xDDA-v1.5 is not "
                               "supported (ntdda cannot read it either); convert it to DDAML")
    return "original"


def _read_text(path) -> tuple[Path, str]:
    p = Path(path)
    try:
        raw = p.read_bytes()
    except OSError as exc:
        raise NtddaFormatError(f"{p}: cannot read the file ({exc.strerror or exc})") from None
    try:
        return p, raw.decode("utf-8")
    except UnicodeDecodeError:
        return p, raw.decode("latin-1")


# ---------------------------------------------------------------------------- text tokens
class _Tokens:
    """Whitespace-separated tokens of an original-format file, with their line numbers
    (ntdda reads these files with scanf, so line breaks carry no meaning)."""

    def __init__(self, path: Path, text: str):
        self.path = path
        self.items = [(tok, n) for n, line in enumerate(text.splitlines(), start=1) for tok in line.split()]
        self.pos = 0
        self.last_line = len(text.splitlines())

    def where(self) -> str:
        return f"line {self.items[self.pos][1]}" if self.pos < len(self.items) else f"line {self.last_line}"

    def _next(self, what: str) -> tuple[str, int]:
        if self.pos >= len(self.items):
            raise NtddaFormatError(f"{self.path}, line {self.last_line}: the file ends early "
                                   f"(truncated, or a count in the header is too large): expected {what}")
        item = self.items[self.pos]
        self.pos += 1
        return item

    def real(self, what: str) -> float:
        tok, line = self._next(what)
        x = _to_float(tok)
        if x is None:
            raise NtddaFormatError(f"{self.path}, line {line}: expected {what} (a number), got {tok!r}")
        return x

    def integer(self, what: str, minimum: int = 0) -> int:
        tok, line = self._next(what)
        if not _INTEGER.match(tok):
            raise NtddaFormatError(f"{self.path}, line {line}: expected {what} (a whole number), got {tok!r}")
        k = int(tok)
        if k < minimum:
            raise NtddaFormatError(f"{self.path}, line {line}: expected {what} >= {minimum}, got {k}")
        return k

    def index(self, what: str) -> int:
        """A 1-based type index; ntdda reads it as a real and truncates, we accept whole values."""
        tok, line = self._next(what)
        x = _to_float(tok)
        if x is None or x != math.floor(x) or x < 1:
            raise NtddaFormatError(f"{self.path}, line {line}: expected {what} (a whole number >= 1), "
                                   f"got {tok!r}")
        return int(x)

    def records(self, count: int, width: int, what: str) -> tuple[np.ndarray, tuple]:
        rows, where = [], []
        for k in range(count):
            where.append(self.where())
            rows.append([self.real(f"{what} {k + 1}: {name}") for name in _FIELDS[width]])
        return np.array(rows, dtype=float).reshape(count, width), tuple(where)

    def finish(self, what: str) -> None:
        if self.pos < len(self.items):
            tok, line = self.items[self.pos]
            raise NtddaFormatError(f"{self.path}, line {line}: unexpected extra data {tok!r} after {what} "
                                   "(does a count in the header not match the records?)")


_FIELDS = {2: ("x", "y"), 4: ("x1", "y1", "x2", "y2")}


# ---------------------------------------------------------------------------- DDAML
@dataclass(eq=False)
class _Element:
    name: str
    attrs: dict
    line: int
    children: list = field(default_factory=list)
    text_parts: list = field(default_factory=list)

    @property
    def text(self) -> str:
        return "".join(self.text_parts)

    def where(self) -> str:
        return f"line {self.line}, <{self.name}>"


def _parse_xml(path: Path, text: str) -> _Element:
    """Parse DDAML with expat, keeping line numbers. Names are matched by local name (the
    ``Berkeley:`` prefix is optional, as in ntdda); DTDs are neither fetched nor validated."""
    import xml.parsers.expat as expat

    parser = expat.ParserCreate()
    roots: list[_Element] = []
    stack: list[_Element] = []

    def start(name, attrs):
        el = _Element(name=name.split(":")[-1], attrs={k.split(":")[-1]: v for k, v in attrs.items()},
                      line=parser.CurrentLineNumber)
        (stack[-1].children if stack else roots).append(el)
        stack.append(el)

    def end(name):
        stack.pop()

    def chars(data):
        if stack:
            stack[-1].text_parts.append(data)

    parser.StartElementHandler = start
    parser.EndElementHandler = end
    parser.CharacterDataHandler = chars
    try:
        parser.Parse(text.encode("utf-8"), True)
    except expat.ExpatError as exc:
        raise NtddaFormatError(f"{path}, line {exc.lineno}: not well-formed XML "
                               f"({expat.ErrorString(exc.code)}; truncated file?)") from None
    return roots[0]


class _Xml:
    """Typed access to DDAML elements with errors that name file, line and element."""

    def __init__(self, path: Path):
        self.path = path

    def fail(self, el: _Element, what: str):
        raise NtddaFormatError(f"{self.path}, {el.where()}: {what}")

    def numbers(self, el: _Element, count: int, what: str) -> list[float]:
        toks = el.text.split()
        if len(toks) != count:
            self.fail(el, f"expected {count} numbers ({what}), got {len(toks)}: {el.text.strip()!r}")
        out = []
        for tok in toks:
            x = _to_float(tok)
            if x is None:
                self.fail(el, f"expected {count} numbers ({what}), got {tok!r}")
            out.append(x)
        return out

    def attr_real(self, el: _Element, name: str, default=None, *, minimum=None, positive=False) -> float:
        if name not in el.attrs:
            if default is None:
                self.fail(el, f"missing attribute {name}=\"...\" (a number)")
            return default
        x = _to_float(el.attrs[name].strip())
        if x is None:
            self.fail(el, f"attribute {name} must be a number, got {el.attrs[name]!r}")
        if positive and not x > 0:
            self.fail(el, f"attribute {name} must be > 0, got {el.attrs[name]!r}")
        if minimum is not None and x < minimum:
            self.fail(el, f"attribute {name} must be >= {minimum:g}, got {el.attrs[name]!r}")
        return x

    def attr_int(self, el: _Element, name: str, *, minimum: int) -> int:
        if name not in el.attrs:
            self.fail(el, f"missing attribute {name}=\"...\" (a whole number >= {minimum})")
        tok = el.attrs[name].strip()
        if not _INTEGER.match(tok) or int(tok) < minimum:
            self.fail(el, f"attribute {name} must be a whole number >= {minimum}, got {el.attrs[name]!r}")
        return int(tok)

    def attr_flag(self, el: _Element, name: str = "flag") -> bool:
        value = el.attrs.get(name)
        if value is None or value.strip().lower() not in ("yes", "no"):
            self.fail(el, f"attribute {name} must be \"yes\" or \"no\", got {value!r}")
        return value.strip().lower() == "yes"

    def value(self, el: _Element, what: str) -> float:
        return self.numbers(el, 1, what)[0]


def _section(xml: _Xml, root: _Element, name: str, other: str) -> _Element:
    """The first ``name`` element: the root itself or a child of it (ntdda looks for the
    first child of that name)."""
    if root.name == name:
        return root
    for child in root.children:
        if child.name == name:
            return child
    found = root.name if root.name == other else next((c.name for c in root.children if c.name == other), None)
    hint = (f" (found <{other}>: are the geometry and analysis files swapped?)" if found else "")
    xml.fail(root, f"expected a <{name}> element{hint}")


# ============================================================================ geometry readers
def read_ntdda_geometry(path) -> NtddaGeometry:
    """Read an ntdda geometry file (original text or DDAML, detected automatically).

    Raises `NtddaFormatError` for a malformed file. Warns about ignored content.
    """
    p, text = _read_text(path)
    log: list[str] = []
    if _detect_format(p, text) == "ddaml":
        return _read_ddaml_geometry(p, text, log)
    return _read_original_geometry(p, text, log)


def _read_original_geometry(path: Path, text: str, log: list) -> NtddaGeometry:
    """GHS "DC" input (docs/ntdda.md §4.2): e00, eight counts, then the records in a fixed order."""
    tk = _Tokens(path, text)
    e00 = tk.real("e00 (the minimum edge-node distance)")
    if e00 < 0:
        raise NtddaFormatError(f"{path}, line 1: e00 must be >= 0, got {e00:g}")
    n_joints = tk.integer("the number of joint lines", minimum=3)
    boundary_where = tk.where()
    n_boundary = tk.integer("the number of boundary lines")
    n_mat = tk.integer("the number of material lines")
    bolts_where = tk.where()
    n_bolts = tk.integer("the number of bolts")
    n_fixed = tk.integer("the number of fixed lines")
    n_load = tk.integer("the number of load points")
    n_meas = tk.integer("the number of measured points")
    n_hole = tk.integer("the number of hole points")
    if n_boundary > n_joints:
        raise NtddaFormatError(f"{path}, {boundary_where}: {n_boundary} boundary lines but only "
                               f"{n_joints} joint lines")
    if n_bolts:
        # ntdda accepts the count with a warning but never reads the bolt records, so the rest
        # of the file is misread (docs/ntdda.md §3.8); no bolt records to read into ddatai's bolts
        raise NtddaFormatError(f"{path}, {bolts_where}: {n_bolts} rock bolts declared; ntdda files' bolt "
                               "records are not read (ntdda misreads the rest of such a file): declare 0 "
                               "and add the bolts with Scene.add_bolt")
    joints, jtype, jwhere = [], [], []
    for k in range(n_joints):
        jwhere.append(tk.where())
        joints.append([tk.real(f"joint line {k + 1}: {f}") for f in _FIELDS[4]])
        jtype.append(tk.index(f"joint line {k + 1}: joint type"))
    mats, mtype, mwhere = [], [], []
    for k in range(n_mat):
        mwhere.append(tk.where())
        mats.append([tk.real(f"material line {k + 1}: {f}") for f in _FIELDS[4]])
        mtype.append(tk.index(f"material line {k + 1}: block material"))
    fixed, fwhere = tk.records(n_fixed, 4, "fixed line")
    load, lwhere = tk.records(n_load, 2, "load point")
    meas, mswhere = tk.records(n_meas, 2, "measured point")
    hole, hwhere = tk.records(n_hole, 2, "hole point")
    tk.finish("the last hole point" if n_hole else "the last record")
    geom = NtddaGeometry(
        path=str(path), format="original", edge_node_distance=e00,
        joints=np.array(joints, dtype=float).reshape(-1, 4), joint_type=np.array(jtype, dtype=np.int64),
        joint_where=tuple(jwhere), n_boundary_lines=n_boundary,
        material_lines=np.array(mats, dtype=float).reshape(-1, 4),
        material_line_type=np.array(mtype, dtype=np.int64), material_line_where=tuple(mwhere),
        fixed_lines=fixed, fixed_where=fwhere, load_points=load, load_where=lwhere,
        measured_points=meas, measured_where=mswhere, hole_points=hole, hole_where=hwhere,
        seismic_points=np.zeros((0, 2)), n_bolts=0, bolts_where="", warnings=tuple(log))
    _check_joint_lengths(geom)
    return geom


def _read_ddaml_geometry(path: Path, text: str, log: list) -> NtddaGeometry:
    """DDAML geometry (docs/ntdda.md §4.4)."""
    xml = _Xml(path)
    geo = _section(xml, _parse_xml(path, text), "Geometry", "Analysis")
    e00 = 0.0  # ntdda's calloc'ed default when <Edgenodedist> is absent: no node merging
    joints, jtype, jwhere = [], [], []
    mats, mtype, mwhere = [], [], []
    fixed, fwhere = [], []
    points = {"Loadpointlist": ([], []), "Measuredpointlist": ([], []), "Holepointlist": ([], []),
              "Seismicpointlist": ([], [])}
    n_bolts, bolts_where = 0, ""

    def children(lst: _Element, allowed: tuple) -> list:
        out = []
        for ch in lst.children:
            if ch.name in allowed:
                out.append(ch)
            else:
                xml.fail(ch, f"unexpected element inside <{lst.name}>: expected "
                             + " or ".join(f"<{a}>" for a in allowed))
        return out

    for el in geo.children:
        if el.name == "Edgenodedist":
            e00 = xml.attr_real(el, "distance", minimum=0.0)
        elif el.name == "Jointlist":
            for j in children(el, ("Joint",)):
                jtype.append(xml.attr_int(j, "type", minimum=1))
                joints.append(xml.numbers(j, 4, "x1 y1 x2 y2"))
                jwhere.append(j.where())
        elif el.name == "Fixedpointlist":
            for f in children(el, ("Point", "Line")):
                if f.name == "Point":
                    x, y = xml.numbers(f, 2, "x y")
                    fixed.append([x, y, x, y])
                else:
                    fixed.append(xml.numbers(f, 4, "x1 y1 x2 y2"))
                fwhere.append(f.where())
        elif el.name in points:
            for pt in children(el, ("Point",)):
                points[el.name][0].append(xml.numbers(pt, 2, "x y"))
                points[el.name][1].append(pt.where())
        elif el.name == "Matlinelist":
            for m in children(el, ("Line",)):
                mtype.append(xml.attr_int(m, "type", minimum=1))
                mats.append(xml.numbers(m, 4, "x1 y1 x2 y2"))
                mwhere.append(m.where())
        elif el.name == "Boltlist":
            bolts = children(el, ("Bolt",))
            if bolts:
                n_bolts, bolts_where = len(bolts), bolts[0].where()
        elif el.name == "Boundlist":
            # ntdda parses it into a list it never allocates and crashes (docs/ntdda.md §3.9)
            xml.fail(el, "<Boundlist> is not supported (ntdda crashes on it); put these lines "
                         "in <Jointlist>")
        else:
            _warn(log, NtddaUnsupportedWarning, f"{path}, {el.where()}: unknown element ignored")
    if not joints:
        xml.fail(geo, "expected a <Jointlist> with at least 3 <Joint> elements")
    if n_bolts:
        raise NtddaFormatError(f"{path}, {bolts_where}: {n_bolts} rock bolts; ntdda files' bolt records are "
                               "not read (remove the <Boltlist> and add the bolts with Scene.add_bolt)")
    seismic = points["Seismicpointlist"]
    if seismic[0]:
        # ntdda parses the record into a local variable and never applies it (docs/ntdda.md §3.6)
        _warn(log, NtddaQuirkWarning, f"{path}, {seismic[1][0]}: seismic points ignored: ntdda never "
              "applies seismic loads (its time history is lost, docs/ntdda.md §3.6), and ddatai does "
              "not read them either (use Scene.set_ground_acceleration)")

    def arr(rows, width):
        return np.array(rows, dtype=float).reshape(-1, width)

    geom = NtddaGeometry(
        path=str(path), format="ddaml", edge_node_distance=e00,
        joints=arr(joints, 4), joint_type=np.array(jtype, dtype=np.int64), joint_where=tuple(jwhere),
        n_boundary_lines=0, material_lines=arr(mats, 4),
        material_line_type=np.array(mtype, dtype=np.int64), material_line_where=tuple(mwhere),
        fixed_lines=arr(fixed, 4), fixed_where=tuple(fwhere),
        load_points=arr(points["Loadpointlist"][0], 2), load_where=tuple(points["Loadpointlist"][1]),
        measured_points=arr(points["Measuredpointlist"][0], 2),
        measured_where=tuple(points["Measuredpointlist"][1]),
        hole_points=arr(points["Holepointlist"][0], 2), hole_where=tuple(points["Holepointlist"][1]),
        seismic_points=arr(seismic[0], 2), n_bolts=0, bolts_where="", warnings=tuple(log))
    _check_joint_lengths(geom)
    return geom


def _check_joint_lengths(geom: NtddaGeometry) -> None:
    if len(geom.joints) < 3:
        raise NtddaFormatError(f"{geom.path}: {len(geom.joints)} joint lines; at least 3 are needed "
                               "to close a block")
    seg = geom.joints
    scale = max(float(np.ptp(seg[:, [0, 2]])), float(np.ptp(seg[:, [1, 3]])))
    zero = np.hypot(seg[:, 2] - seg[:, 0], seg[:, 3] - seg[:, 1]) <= 1e-12 * max(scale, 1e-300)
    if zero.any():
        k = int(np.flatnonzero(zero)[0])
        raise NtddaFormatError(f"{geom.path}, {geom.joint_where[k]}: joint line {k + 1} has zero length")


# ============================================================================ analysis readers
def read_ntdda_analysis(path) -> NtddaAnalysis:
    """Read an ntdda analysis file (original text or DDAML, detected automatically)."""
    p, text = _read_text(path)
    log: list[str] = []
    if _detect_format(p, text) == "ddaml":
        return _read_ddaml_analysis(p, text, log)
    return _read_original_analysis(p, text, log)


def _read_original_analysis(path: Path, text: str, log: list) -> NtddaAnalysis:
    """GHS "DF" input (docs/ntdda.md §4.3) and ntdda's implicit settings for it."""
    tk = _Tokens(path, text)
    where = tk.where()
    kind = tk.integer("the analysis type (0 static, 1 dynamic)")
    if kind not in (0, 1):
        raise NtddaFormatError(f"{path}, {where}: the analysis type must be 0 (static) or 1 (dynamic), "
                               f"got {kind}")
    n_steps = tk.integer("the number of time steps", minimum=1)
    n_bmat = tk.integer("the number of block materials", minimum=1)
    n_jmat = tk.integer("the number of joint materials", minimum=1)
    where = tk.where()
    g2 = tk.real("g2 (the maximum displacement ratio)")
    if not g2 > 0:
        raise NtddaFormatError(f"{path}, {where}: g2 (maximum displacement ratio) must be > 0, got {g2:g}")
    where = tk.where()
    g1 = tk.real("g1 (the maximum time step)")
    if not g1 > 0:
        raise NtddaFormatError(f"{path}, {where}: g1 (maximum time step) must be > 0, got {g1:g}")
    names = ("unit mass", "unit weight", "Young's modulus", "Poisson's ratio", "sxx", "syy", "sxy",
             "txx", "tyy", "txy", "vx", "vy", "vr")
    bmats = []
    for k in range(n_bmat):
        where = tk.where()
        v = [tk.real(f"block material {k + 1}: {name}") for name in names]
        bmats.append(_block_material(path, where, unit_mass=v[0], unit_weight=v[1], young=v[2],
                                     poisson=v[3], damping=0.0, stress=tuple(v[4:7]),
                                     stress_gradient=tuple(v[7:10]), velocity=tuple(v[10:13]),
                                     strain=(0.0, 0.0, 0.0)))
    jmats = []
    for k in range(n_jmat):
        where = tk.where()
        v = [tk.real(f"joint material {k + 1}: {name}") for name in ("friction angle", "cohesion",
                                                                     "tensile strength")]
        jmats.append(_joint_material(path, where, *v))
    tk.finish("the last joint material")
    # ntdda's original-format reader replaces the contact constants by uninitialised memory
    # (docs/ntdda.md §3.12: NaN at step 1, circleslope crashes); ddatai uses ntdda's defaults
    _warn(log, NtddaQuirkWarning, f"{path}: original-format analysis file: ntdda leaves the contact "
          "constants uninitialised for this format (its runs end in NaN, docs/ntdda.md §3.12); "
          "ddatai uses ntdda's default constants")
    _warn(log, NtddaUnsupportedWarning, f"{path}: ntdda re-estimates the penalty every step for "
          "original-format files (automatic penalty); ddatai keeps it at 50 × the largest Young's "
          "modulus")
    for m in bmats:
        if any(m.stress_gradient):
            _warn(log, NtddaQuirkWarning, f"{path}, {m.where}: stress gradients (txx tyy txy) given: "
                  "ntdda also uses them as initial velocities (docs/ntdda.md §4.3, §3.14); "
                  "ddatai applies them only as σ = s + y_centroid·t")
        if any(m.velocity):
            _warn(log, NtddaQuirkWarning, f"{path}, {m.where}: initial velocities given: ntdda ignores "
                  "them in this format (it reads the stress gradients instead, docs/ntdda.md §3.14); "
                  "ddatai applies them")
    return NtddaAnalysis(
        path=str(path), format="original", dynamic=kind == 1, n_steps=n_steps, max_time_step=g1,
        auto_time_step=True, max_displacement=g2, auto_penalty=True, penalty_factor=NTDDA_PFACTOR,
        plane_strain=False, rotation="linear", gravity_turn_on=False, gravity_acceleration=None,
        oc_limit=NTDDA_OC_LIMIT, save_interval=1, contact_damping=0.0,
        openclose=NTDDA_OPENCLOSE, opencriteria=NTDDA_OPENCRITERIA, norm_spring_pen=NTDDA_NORM_SPRING_PEN,
        angle_overlap=NTDDA_ANGLE_OVERLAP, shear_norm_ratio=NTDDA_SHEAR_NORM_RATIO,
        block_materials=tuple(bmats), joint_materials=tuple(jmats), load_histories=(), load_where=(),
        warnings=tuple(log))


def _block_material(path, where, **kw) -> NtddaBlockMaterial:
    m = NtddaBlockMaterial(where=where, **kw)
    if not m.unit_mass > 0:
        raise NtddaFormatError(f"{path}, {where}: unit mass must be > 0, got {m.unit_mass:g}")
    if m.unit_weight is not None and m.unit_weight < 0:
        raise NtddaFormatError(f"{path}, {where}: unit weight must be >= 0, got {m.unit_weight:g}")
    if not m.young > 0:
        raise NtddaFormatError(f"{path}, {where}: Young's modulus must be > 0, got {m.young:g}")
    if not 0.0 <= m.poisson < 0.5:
        raise NtddaFormatError(f"{path}, {where}: Poisson's ratio must be in [0, 0.5), got {m.poisson:g}")
    return m


def _joint_material(path, where, friction, cohesion, tensile) -> NtddaJointMaterial:
    if not 0.0 <= friction < 90.0:
        raise NtddaFormatError(f"{path}, {where}: friction angle must be in [0, 90) degrees, got {friction:g}")
    if cohesion < 0 or tensile < 0:
        raise NtddaFormatError(f"{path}, {where}: cohesion and tensile strength must be >= 0, "
                               f"got {cohesion:g} and {tensile:g}")
    return NtddaJointMaterial(friction=friction, cohesion=cohesion, tensile=tensile, where=where)


def _read_ddaml_analysis(path: Path, text: str, log: list) -> NtddaAnalysis:
    """DDAML analysis (docs/ntdda.md §4.5). Elements are dispatched by name like ntdda does;
    unknown ones are reported (ntdda ignores them silently)."""
    xml = _Xml(path)
    ana = _section(xml, _parse_xml(path, text), "Analysis", "Geometry")
    s = dict(dynamic=False, rotation="linear", gravity_turn_on=False, gravity_acceleration=None,
             auto_time_step=False, auto_penalty=False, penalty_factor=None, plane_strain=False,
             n_steps=None, max_time_step=None, max_displacement=None, save_interval=1,
             oc_limit=None, contact_damping=0.0, openclose=NTDDA_OPENCLOSE,
             opencriteria=NTDDA_OPENCRITERIA, norm_spring_pen=NTDDA_NORM_SPRING_PEN,
             angle_overlap=NTDDA_ANGLE_OVERLAP, shear_norm_ratio=NTDDA_SHEAR_NORM_RATIO)
    bmats, jmats, histories, hwhere = [], [], [], []
    autopenalty_el = None
    oc_el = None
    for el in ana.children:
        name = el.name
        if name == "Analysistype":
            kind = el.attrs.get("type", "").strip().lower()
            if kind not in ("static", "dynamic"):
                xml.fail(el, f"attribute type must be \"static\" or \"dynamic\", got {el.attrs.get('type')!r}")
            s["dynamic"] = kind == "dynamic"
        elif name == "Rotation":
            kind = el.attrs.get("type", "").strip().lower()
            if kind not in ("linear", "secondorder", "exact"):
                xml.fail(el, "attribute type must be \"linear\", \"secondorder\" or \"exact\", "
                             f"got {el.attrs.get('type')!r}")
            s["rotation"] = kind
        elif name == "Gravity":
            s["gravity_turn_on"] = xml.attr_flag(el)
        elif name == "Gravaccel":
            s["gravity_acceleration"] = xml.attr_real(el, "value", minimum=0.0)
        elif name == "Autotimestep":
            s["auto_time_step"] = xml.attr_flag(el)
        elif name == "Autopenalty":
            s["auto_penalty"] = xml.attr_flag(el)
            autopenalty_el = el
            if "pfactor" in el.attrs:
                s["penalty_factor"] = xml.attr_real(el, "pfactor", positive=True)
        elif name == "Planestrain":
            s["plane_strain"] = xml.attr_flag(el)
        elif name == "Numtimesteps":
            s["n_steps"] = xml.attr_int(el, "timesteps", minimum=1)
        elif name == "Maxtimestep":
            s["max_time_step"] = xml.attr_real(el, "maxtimestep", positive=True)
        elif name == "Mintimestep":
            xml.attr_real(el, "mintimestep", minimum=0.0)  # parsed but unused, as in ntdda
        elif name == "Maxdisplacement":
            s["max_displacement"] = xml.attr_real(el, "maxdisplacement", positive=True)
        elif name == "Saveinterval":
            step = el.attrs.get("step", "").strip()
            if _INTEGER.match(step) and int(step) >= 1:
                s["save_interval"] = int(step)
            elif step in ("", "0"):
                s["save_interval"] = 10
                _warn(log, NtddaQuirkWarning, f"{path}, {el.where()}: no save interval given; ntdda "
                      "then saves every 10 steps, and so does ddatai")
            else:
                xml.fail(el, f"attribute step must be a whole number >= 1, got {el.attrs.get('step')!r}")
        elif name in ("Opencloselimit", "OCLimit"):
            s["oc_limit"] = xml.attr_int(el, "maxopenclose", minimum=2)
            oc_el = el
        elif name == "ContactDamping":
            s["contact_damping"] = xml.attr_real(el, "value", minimum=0.0)
            if s["contact_damping"] > 0:
                _warn(log, NtddaUnsupportedWarning, f"{path}, {el.where()}: contact damping is not "
                      "supported; ignored")
        elif name == "AConstants":
            _read_constants(xml, el, s, log)
        elif name == "Blockmaterial":
            bmats.append(_read_ddaml_block_material(xml, el, log))
        elif name == "Jointproperties":
            jmats.append(_read_ddaml_joint_material(xml, el))
        elif name == "Loadpointlist":
            for lp in el.children:
                if lp.name != "Loadpoint":
                    xml.fail(lp, "unexpected element inside <Loadpointlist>: expected <Loadpoint>")
                histories.append(_read_load_history(xml, lp))
                hwhere.append(lp.where())
        elif name == "Timehistory":
            _warn(log, NtddaQuirkWarning, f"{path}, {el.where()}: seismic time history ignored: ntdda "
                  "loses it and never applies it (docs/ntdda.md §3.6); use Scene.set_ground_acceleration")
        elif name in ("Writevertices", "Boltproperties"):
            pass  # output selection; bolt properties without bolts
        else:
            _warn(log, NtddaUnsupportedWarning, f"{path}, {el.where()}: unknown element ignored")

    for key, element, attr in (("n_steps", "Numtimesteps", "timesteps"),
                               ("max_time_step", "Maxtimestep", "maxtimestep"),
                               ("max_displacement", "Maxdisplacement", "maxdisplacement")):
        if s[key] is None:
            xml.fail(ana, f"expected a <{element} {attr}=\"...\"/> element (ntdda's default 0 cannot run)")
    if not bmats:
        xml.fail(ana, "expected at least one <Blockmaterial> element")
    if s["penalty_factor"] is None:
        # without pfactor ntdda sets the penalty to 0 and blocks sink into each other (docs/ntdda.md §3.5)
        s["penalty_factor"] = NTDDA_PFACTOR
        where = autopenalty_el.where() if autopenalty_el is not None else "<Analysis>"
        _warn(log, NtddaQuirkWarning, f"{path}, {where}: no pfactor given: ntdda would use a penalty of "
              f"0 (blocks sink into each other, docs/ntdda.md §3.5); ddatai uses pfactor = {NTDDA_PFACTOR:g}")
    if s["oc_limit"] is None:
        s["oc_limit"] = NTDDA_OC_LIMIT
    elif s["oc_limit"] != NTDDA_OC_LIMIT:
        what = ("ntdda ignores <OCLimit> (it only reads <Opencloselimit>)" if oc_el.name == "OCLimit"
                else "ntdda's driver ignores it")
        _warn(log, NtddaQuirkWarning, f"{path}, {oc_el.where()}: open-close limit {s['oc_limit']}: {what} "
              f"and always stops at {NTDDA_OC_LIMIT} iterations (docs/ntdda.md §3.4); ddatai uses "
              f"{s['oc_limit']}")
    if s["auto_penalty"]:
        _warn(log, NtddaUnsupportedWarning, f"{path}, {autopenalty_el.where()}: ntdda's automatic penalty "
              f"re-estimation is not supported; the penalty stays at pfactor × the largest Young's modulus")
    if s["plane_strain"]:
        _warn(log, NtddaQuirkWarning, f"{path}: plane strain: ntdda's plane-strain stiffness is too stiff by "
              "(1+ν)/(1−ν) (docs/guide/method_choices.md); ddatai uses the correct one")
    return NtddaAnalysis(path=str(path), format="ddaml", block_materials=tuple(bmats),
                         joint_materials=tuple(jmats), load_histories=tuple(histories),
                         load_where=tuple(hwhere), warnings=tuple(log), **s)


def _read_constants(xml: _Xml, el: _Element, s: dict, log: list) -> None:
    names = {"Openclose": "openclose", "Opencriteria": "opencriteria", "NormSpringPen": "norm_spring_pen",
             "AngleOverlap": "angle_overlap", "ShearNormRatio": "shear_norm_ratio"}
    for ch in el.children:
        if ch.name in names:
            s[names[ch.name]] = xml.attr_real(ch, "value", positive=True)
        elif ch.name != "MinReflineFactor":
            _warn(log, NtddaUnsupportedWarning, f"{xml.path}, {ch.where()}: unknown contact constant ignored")
    if s["angle_overlap"] >= 30.0:
        xml.fail(el, f"AngleOverlap must be < 30 degrees, got {s['angle_overlap']:g}")
    # ddatai opens and closes contacts with its own much tighter tolerances
    # (docs/guide/method_choices.md); a file that changes ntdda's only gets told
    for key, default, what in (("openclose", NTDDA_OPENCLOSE, "Openclose"),
                               ("opencriteria", NTDDA_OPENCRITERIA, "Opencriteria")):
        if not math.isclose(s[key], default, rel_tol=1e-9):
            _warn(log, NtddaQuirkWarning, f"{xml.path}, {el.where()}: {what} = {s[key]:g} is not used: ddatai "
                  "opens and closes contacts with its own tolerances (docs/guide/method_choices.md)")


def _read_ddaml_block_material(xml: _Xml, el: _Element, log: list) -> NtddaBlockMaterial:
    vals: dict = {}
    triples = {"Istress": "stress", "Ivelocity": "velocity", "Istrain": "strain"}
    scalars = {"Unitmass": "unit_mass", "Unitweight": "unit_weight", "Youngsmod": "young",
               "Poissonratio": "poisson", "Damping": "damping"}
    for ch in el.children:
        if ch.name in scalars:
            vals[scalars[ch.name]] = xml.value(ch, ch.name)
        elif ch.name in triples:
            vals[triples[ch.name]] = tuple(xml.numbers(ch, 3, "three values"))
        else:
            xml.fail(ch, "unexpected element inside <Blockmaterial>")
    for required in ("Unitmass", "Youngsmod", "Poissonratio"):
        if scalars[required] not in vals:
            xml.fail(el, f"missing <{required}>")
    m = _block_material(xml.path, el.where(), unit_mass=vals["unit_mass"],
                        unit_weight=vals.get("unit_weight"), young=vals["young"], poisson=vals["poisson"],
                        damping=vals.get("damping", 0.0), stress=vals.get("stress", (0.0, 0.0, 0.0)),
                        stress_gradient=(0.0, 0.0, 0.0), velocity=vals.get("velocity", (0.0, 0.0, 0.0)),
                        strain=vals.get("strain", (0.0, 0.0, 0.0)))
    where = f"{xml.path}, {el.where()}"
    if any(m.velocity):
        _warn(log, NtddaQuirkWarning, f"{where}: non-zero <Ivelocity>: ntdda also adds y_centroid × "
              "Ivelocity to the initial stresses (its material columns are mixed up, docs/ntdda.md §3.3); "
              "ddatai applies it as initial velocity only")
    if any(m.strain):
        _warn(log, NtddaUnsupportedWarning, f"{where}: non-zero <Istrain> ignored (ntdda never uses it)")
    if m.damping:
        _warn(log, NtddaQuirkWarning, f"{where}: block damping {m.damping:g} ignored: ntdda reads it and "
              "never uses it (docs/ntdda.md §3.13)")
    return m


def _read_ddaml_joint_material(xml: _Xml, el: _Element) -> NtddaJointMaterial:
    vals = {}
    for ch in el.children:
        if ch.name in ("Friction", "Cohesion", "Tensile"):
            vals[ch.name] = xml.value(ch, ch.name)
        else:
            xml.fail(ch, "unexpected element inside <Jointproperties>")
    if "Friction" not in vals:
        xml.fail(el, "missing <Friction> (friction angle in degrees)")
    return _joint_material(xml.path, el.where(), vals["Friction"], vals.get("Cohesion", 0.0),
                           vals.get("Tensile", 0.0))


def _read_load_history(xml: _Xml, el: _Element) -> np.ndarray:
    """``numpoints`` records ``t fx fy`` separated by ';', times strictly increasing."""
    n = xml.attr_int(el, "numpoints", minimum=2)
    records = [r for r in el.text.split(";") if r.strip()]
    if len(records) != n:
        xml.fail(el, f"numpoints = {n} but {len(records)} records 't fx fy;' follow")
    rows = []
    for k, rec in enumerate(records):
        toks = rec.split()
        vals = [_to_float(t) for t in toks]
        if len(toks) != 3 or any(v is None for v in vals):
            xml.fail(el, f"record {k + 1}: expected three numbers 't fx fy', got {rec.strip()!r}")
        rows.append(vals)
    hist = np.array(rows, dtype=float)
    if np.any(np.diff(hist[:, 0]) <= 0):
        xml.fail(el, "record times must be strictly increasing")
    return hist


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
    """`NtddaPoint` per recorded point: measured points, then load points."""
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
        from ..run import simulate

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
    from ..geometry import polygon_integrals
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
