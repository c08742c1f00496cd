"""ntdda files as read: the errors and warnings of the reader, ntdda's constants and the
raw content of a geometry and an analysis file (docs/ntdda.md)."""

from __future__ import annotations


import numpy as np

from dataclasses import dataclass
from typing import Literal, Optional

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


