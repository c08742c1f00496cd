"""What every judge returns (docs/kgm/architecture.md): a failure `Mode` of a block or group,
the `Evaluation` of a group (its modes, the governing one, why others are not admissible), and
the rules that rank them: `tie_key` (the one tie rule of kgm) and `governing`.

A limit-equilibrium judge takes values (a `kgm.BlockSystem`, a group, the removed blocks) and
returns an `Evaluation`: `kgm.judges.rigid` (the group as one rigid body), `kgm.judges.sarma`
(Sarma mechanisms) and `kgm.judges.toppling` (a row of toppling blocks).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Optional

import numpy as np

from ..kinds import ModeKind


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
    """(2,) rotation centre of a rotation mode: the vertex, or the instantaneous centre of a
    turning on two sliding points (`kgm.judges.turning`) [m]."""
    block_velocity: Optional[dict] = None
    """Relative velocity (2,) of every member in a Sarma mechanism, normalised to max 1 [-]."""
    critical_acceleration: Optional[float] = None
    """Sarma's K_c: horizontal acceleration (in g, toward the direction of motion) that brings
    the mode to limit equilibrium at the actual strength; < 0 means unstable under gravity
    alone [-]."""
    block_modes: Optional[tuple] = None
    """Block toppling only: the Goodman–Bray recursion at limit equilibrium (strength reduced
    by FS), one `kgm.BlockStep` per member (stable, toppling or sliding, with its
    forces), top block first."""
    unbalanced_moment: str = ""
    """Sarma mechanisms: where the translation leaves a member's moment unbalanced at limit
    equilibrium — no points on its faces at which the face forces balance the moment of its
    loads, so the member would turn and a face open at one end — which member and which way;
    '' where every member balances. Such a mode is no limit state: `kgm.evaluate_sarma` takes
    it out and says why (docs/kgm/footwall.md §9)."""


@dataclass(frozen=True, kw_only=True, eq=False)
class Evaluation:
    """Factor of safety of a group from one evaluator, and the mode that governs it."""

    fs: float
    """Factor of safety [-]: strength-reduction factor at limit equilibrium (inf: no mode)."""
    mode: Mode
    """The governing mode (least safe)."""
    modes: tuple
    """All admissible modes found, least safe first."""
    rejected: tuple = ()
    """Why the modes the evaluator looked for and did not keep are not admissible: one line
    each (a rigid face that would cut into a neighbour, a Sarma mechanism with no root of
    K(F) whose forces are compressive, a group that is not a toppling row, ...)."""

    @property
    def critical_friction(self) -> float:
        """`critical_friction_of` this evaluation [degrees]."""
        return critical_friction_of(self)


#: Order of mode kinds among modes of equal FS: the simplest mechanism governs a tie (a group
#: sliding on one plane is a rigid slide and a Sarma mechanism with no shear at once).
KIND_RANK = {ModeKind.LIFTING: 0, ModeKind.SLIDING: 1, ModeKind.ROTATION: 2, ModeKind.SARMA: 3,
            ModeKind.TOPPLING: 4, ModeKind.NONE: 5}


def tie_key(value: float) -> float:
    """The tie rule of every ranking: values equal to 9 significant digits tie (the same plane
    reached by two evaluators, or through two groups, differs only by round-off) [-]."""
    return float(f"{value:.9g}")


def governing(modes: list[Mode], rejected: list[str] = ()) -> Evaluation:
    """The evaluation of a group from the modes a judge found: the least safe governs; a tie in
    FS (`tie_key`) goes to the larger critical friction, then the simpler mode (`KIND_RANK`).
    No mode: FS inf, the group is stable by geometry."""
    modes = sorted(modes, key=lambda m: (tie_key(m.fs), -tie_key(m.critical_friction),
                                         KIND_RANK.get(m.kind, 9)))
    if not modes:
        none = Mode(kind=ModeKind.NONE, fs=math.inf, critical_friction=0.0,
                    sliding_contacts=np.zeros(0, dtype=np.int64))
        return Evaluation(fs=math.inf, mode=none, modes=(), rejected=tuple(rejected))
    return Evaluation(fs=modes[0].fs, mode=modes[0], modes=tuple(modes), rejected=tuple(rejected))


def critical_friction_of(evaluation: Evaluation) -> float:
    """Critical friction angle of the group [degrees]: the group is at limit equilibrium when
    its least safe mode is, i.e. the largest φc over its admissible modes (§4.6); 0 when no
    mode exists."""
    return max((m.critical_friction for m in evaluation.modes), default=0.0)
