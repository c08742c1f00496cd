"""Settings of a KGM analysis: frozen keyword-only dataclasses, validated on construction.

Units are SI (m, s, m/s²); friction angles in degrees.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Callable, Optional

from ddatai.params import Params

from .kinds import LIMIT_EQUILIBRIUM, Method


def _require(cond: bool, message: str) -> None:
    if not cond:
        raise ValueError(message)


def _positive(obj, name: str, allow_none: bool = False) -> None:
    v = getattr(obj, name)
    if v is None and allow_none:
        return
    _require(isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) and v > 0,
             f"{type(obj).__name__}.{name} must be a finite number > 0, got {v!r}")


@dataclass(frozen=True, kw_only=True)
class DdaSettings:
    """How the DDA evaluator judges a group (docs/kgm/method.md §6.3–6.4).

    A run simulates the group and the blocks it touches (held fixed, as KGM assumes
    non-members stay in place; ``free_neighbours`` lets them move and fixes the next ring),
    from its gravitational equilibrium (`ddatai.Params.initial_equilibrium`: gravity switched
    on at once overshoots the static contact forces and a group near its limit slips in the
    first steps — its verdict would follow that transient, not the strength), for a time T. The group is **unstable** if its largest member displacement
    d(T) ≥ δ and it is still moving at the end: its mean speed over the last quarter of the
    run is ≥ δ/T (a group sliding with constant acceleration a has d = aT²/2 and that speed
    7aT/8, so it passes as soon as d ≥ δ). Otherwise it is **stable**: it stayed within δ, or
    it moved and came to rest (arrested). A run whose displacement passes ``stop_ratio``·δ
    is stopped early as unstable, and one whose free blocks have been at rest for
    ``rest_steps`` steps (speeds below ``rest_ratio``·δ/T) as stable.

    δ = ``displacement_ratio`` × √(group area): 0.5 % of the group's size, far above the
    contact settlement N/p and the elastic overshoot of the first steps (≈ 1e-4 of the size
    in the examples), and below any displacement that changes the geometry. T follows from
    the acceleration the judgement must resolve, ``acceleration_resolution`` a_r:
    T = √(2δ/a_r); a group accelerating at a_r just reaches δ. On planar sliding a_r sets the
    friction resolution Δtanφ ≈ a_r/(g cos α) (§6.3): 0.05 m/s² is ≈ 0.3° at α = 20°.
    """

    params: Optional[Params] = None
    """DDA parameters of the runs; None: the scene's (given to `analyze`) or ``ddatai.Params()``."""
    duration: Optional[float] = None
    """Simulated time T of a run [s]; None: √(2δ/a_r)."""
    displacement_ratio: float = 0.005
    """δ as a fraction of the group's size √(area) [-]."""
    acceleration_resolution: float = 0.05
    """a_r: smallest acceleration a run must detect [m/s²] (sets T when ``duration`` is None)."""
    stop_ratio: float = 4.0
    """Stop a run as unstable once the displacement exceeds this many δ [-]."""
    rest_ratio: float = 1e-6
    """Stop a run as stable once every free block has moved slower than this many δ/T for
    ``rest_steps`` steps: at rest, with loads that do not change in time, a step reproduces the
    state it started from, so the rest of the run would add nothing (`kgm.judges.run.RestCounter`);
    0: every stable run goes to T [-]."""
    rest_steps: int = 20
    """Steps a run must stay at rest before it is stopped as stable [-]."""
    cohesion_held: bool = True
    """Joints keep their cohesion while they slide (lose it only when they open), as limit
    equilibrium assumes (docs/kgm/method.md §6.1, §6.6); False: Shi's DDA, where a joint loses it as
    soon as it slips (`ddatai.Params.bond_breaks_on_slip`)."""
    free_neighbours: bool = False
    """Let the blocks touching the group move too (and fix the ones touching them)."""
    friction_tolerance: float = 0.25
    """Width of the final bracket of the critical-friction bisection [degrees]."""
    fs_tolerance: float = 0.02
    """Relative width of the final bracket of the strength-reduction bisection [-]."""
    candidates: int = 1
    """How many of the least safe limit-equilibrium candidates DDA judges [-]."""
    compare_whole: bool = False
    """Also time the whole slope over ``whole_steps`` steps to report the time saved."""
    whole_steps: int = 100
    """Steps of the timing runs of the sub-model and the whole slope [-]."""
    batch: int = 8
    """Probes judged side by side in one run (`kgm.judges.batch.judge_many`): the verdict and the probes
    of a round of the F and φ searches, each bracket cut into as many pieces as it has probes (or
    the fewest that reach the tolerance; on the fused engine a round in two passes, the middle
    probes first: docs/kgm/method.md §6.4); 1: one run a probe and bisections
    (docs/guide/performance.md, "Batched studies") [-]."""
    sample_batch: int = 128
    """Samples of a DDA-judged probabilistic study (verdicts only) judged side by side in one
    run (`kgm.judges.batch.judge_members`, exact: the table is the one of one run a sample), at most so
    many that every worker gets a batch; 1: one run a sample [-]. Large batches pay: a
    member-step costs 1.6 ms alone, 0.17 ms among 16 and 0.036 ms among 128 (Example II's group,
    docs/guide/performance.md "Batched studies")."""
    progress: Optional[Callable[..., None]] = None
    """Called with each `kgm.DdaJudgement` as its run ends (``kgm analyze`` prints a line
    per run); None: silent. The entry points (`kgm.analyze`, `kgm.evaluate`, ...,
    `kgm.probabilistic`, `kgm.judge`) pass it to the judges they call: a judge reports to its
    caller's callback and never to anything above it."""

    def __post_init__(self) -> None:
        _require(self.params is None or isinstance(self.params, Params),
                 f"DdaSettings.params must be a ddatai.Params or None, got {type(self.params).__name__}")
        _positive(self, "duration", allow_none=True)
        for name in ("displacement_ratio", "acceleration_resolution", "friction_tolerance", "fs_tolerance"):
            _positive(self, name)
        _require(isinstance(self.stop_ratio, (int, float)) and self.stop_ratio >= 1.0,
                 f"DdaSettings.stop_ratio must be >= 1, got {self.stop_ratio!r}")
        _require(isinstance(self.rest_ratio, (int, float)) and not isinstance(self.rest_ratio, bool)
                 and 0.0 <= self.rest_ratio <= 1e-3,
                 f"DdaSettings.rest_ratio must be between 0 and 1e-3, got {self.rest_ratio!r}")
        for name in ("candidates", "whole_steps", "batch", "sample_batch", "rest_steps"):
            v = getattr(self, name)
            _require(isinstance(v, int) and not isinstance(v, bool) and v >= 1,
                     f"DdaSettings.{name} must be an integer >= 1, got {v!r}")
        for name in ("cohesion_held", "free_neighbours", "compare_whole"):
            _require(isinstance(getattr(self, name), bool),
                     f"DdaSettings.{name} must be True or False, got {getattr(self, name)!r}")


@dataclass(frozen=True, kw_only=True)
class Settings:
    """The key-group search (docs/kgm/method.md §3.3–3.4)."""

    fs_target: float = 1.0
    """A group with FS below this is unstable (removed in progressive mode) [-]."""
    growth_tolerance: float = 1e-4
    """A neighbour joins a group only if it lowers FS by more than this [-]."""
    max_group_size: int = 8
    """Largest number of blocks in a group [-]."""
    max_row_size: int = 32
    """Largest number of blocks in a toppling row grown along its interfaces (its toppling
    evaluation is linear in its length, so rows may be longer than ``max_group_size``) [-]."""
    max_iterations: int = 100
    """Largest number of removal rounds in progressive mode [-]."""
    screening: Method = Method.SARMA
    """Limit-equilibrium evaluator that proposes the candidate groups DDA judges: 'rigid' or
    'sarma' (a `kgm.kinds.Method`; a name is taken)."""
    dda: DdaSettings = field(default_factory=DdaSettings)
    """How the DDA evaluator runs."""
    contact_gap: Optional[float] = None
    """Blocks whose facing edges are at most this far apart are in contact [m]; None:
    `kgm.system.CONTACT_GAP` × the model size (1 mm in a 10 m model)."""

    def __post_init__(self) -> None:
        _positive(self, "fs_target")
        _require(isinstance(self.growth_tolerance, (int, float)) and self.growth_tolerance >= 0,
                 f"Settings.growth_tolerance must be >= 0, got {self.growth_tolerance!r}")
        for name in ("max_group_size", "max_row_size", "max_iterations"):
            v = getattr(self, name)
            _require(isinstance(v, int) and not isinstance(v, bool) and v >= 1,
                     f"Settings.{name} must be an integer >= 1, got {v!r}")
        _require(isinstance(self.screening, str) and self.screening in LIMIT_EQUILIBRIUM,
                 f"Settings.screening must be 'rigid' or 'sarma', got {self.screening!r}")
        object.__setattr__(self, "screening", Method(self.screening))
        _require(self.contact_gap is None or (isinstance(self.contact_gap, (int, float))
                                              and not isinstance(self.contact_gap, bool)
                                              and 0 <= self.contact_gap < float("inf")),
                 f"Settings.contact_gap must be None or a distance >= 0 m, got {self.contact_gap!r}")
        _require(isinstance(self.dda, DdaSettings),
                 f"Settings.dda must be a kgm.DdaSettings, got {type(self.dda).__name__}")
