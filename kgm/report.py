"""Results of a KGM analysis: `GroupResult` (one evaluated group), `Report` (a whole analysis),
the failure-surface polylines and the text tables (docs/kgm/method.md §3.5).

A group's row is made in one place from what its judges returned: `group_result` from a
limit-equilibrium `kgm.judges.evaluation.Evaluation` (its surface and loads with it), and
`judged_by_dda` the same row with the DDA judge's FS, critical friction and verdict (every
other field kept: a field added to `GroupResult` reaches both). Where the screening evaluator was
Sarma and its factor exceeds `SARMA_ABOVE_DDA` times DDA's, the row says so ("Sarma above DDA by
x %") and names DDA's factor as governing (docs/kgm/footwall.md §9)."""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Optional, Sequence

import numpy as np

from .system import DISTANCE_TOL, BlockSystem
from .judges.evaluation import Evaluation, Mode, critical_friction_of
from .kinds import BlockState, Method, ModeKind

#: A group judged by Sarma and by DDA is flagged where Sarma's factor exceeds this multiple of
#: DDA's [-]: DDA's strength-reduction factor is bracketed to `kgm.DdaSettings.fs_tolerance`
#: (2 %) and its verdict resolves the mobilised friction to Δtanφ ≈ a_r/(g cosα), about 2 % of
#: it on the footwall slabs (docs/kgm/method.md §6.3, docs/kgm/footwall.md §7); a Sarma factor
#: more than 5 % above DDA's is beyond both together, a disagreement of the methods on the
#: unsafe side (docs/kgm/footwall.md §9).
SARMA_ABOVE_DDA = 1.05


@dataclass(frozen=True, kw_only=True, eq=False)
class GroupResult:
    """A group of blocks as one evaluator judged it."""

    blocks: frozenset
    """Block ids of the group (the scene's ids)."""
    fs: float
    """Factor of safety [-] (strength reduction; inf: no failure mode)."""
    critical_friction: float
    """Friction angle of all joints (cohesion held) at which the group reaches limit
    equilibrium [degrees]; 90: no friction angle holds it (lifting, toppling)."""
    stable: bool
    """Verdict: FS ≥ the target (rigid, sarma) or the DDA run at the scene's strength."""
    mode: Mode
    """Governing failure mode from limit equilibrium (for dda: from the screening evaluator)."""
    surface: tuple = ()
    """Critical failure surface: polylines (k, 2) [m] of the contacts on which the group slides."""
    evaluator: str = Method.RIGID
    """Evaluator that gave ``fs`` and ``critical_friction``: 'rigid', 'sarma' or 'dda'."""
    seed: Optional[int] = None
    """Key block the greedy search grew the group from."""
    iteration: int = 0
    """Removal round of a progressive analysis (0: the first)."""
    dda: Optional[object] = None
    """`kgm.DdaEvaluation` of a DDA-judged group (runs, times, verdict), else None."""
    water_force: Optional[float] = None
    """Water force ∫p ds on the group's failure surface (the uplift U of its sliding and
    sheared contacts) [N/m]; None: the scene has no water table."""
    bolt_force: Optional[float] = None
    """Resultant of the bolt forces on the group, active (pretension) plus passive (capacity
    beyond it) [N/m]; None: the scene has no bolts."""
    seismic: Optional[tuple] = None
    """Seismic coefficients (kh, kv) [-] of the analysis; None: none given."""
    modes: tuple = ()
    """Every admissible limit-equilibrium mode of the group, least safe first (the first
    governs; for dda: the screening evaluator's)."""
    rejected: tuple = ()
    """Why the other modes the limit-equilibrium evaluator looked for are not admissible, one
    line each (``kgm.judges.evaluation.Evaluation.rejected``)."""
    screening_fs: Optional[float] = None
    """A row judged by DDA: the factor of safety its screening limit-equilibrium evaluator gave
    (``mode.fs`` when a mode governs) [-]; None for a limit-equilibrium row."""
    screened_by: Optional[str] = None
    """A row judged by DDA: the screening evaluator ('rigid' or 'sarma'); None otherwise."""

    @property
    def verdict(self) -> str:
        return "stable" if self.stable else "unstable"

    @property
    def block_modes(self) -> dict:
        """Block toppling (``mode.kind`` TOPPLING): block id -> 'stable', 'toppling' or
        'sliding' at limit equilibrium (Goodman & Bray's recursion); otherwise empty."""
        return {s.block: s.state.value for s in (self.mode.block_modes or ())}

    @property
    def sarma_above_dda(self) -> Optional[float]:
        """How far Sarma's factor lies above DDA's, (FS_Sarma − FS_DDA)/FS_DDA [-] (inf: DDA
        fails it at any strength, or Sarma finds no mode), where the group was screened by Sarma,
        judged by DDA, and FS_Sarma > `SARMA_ABOVE_DDA` · FS_DDA; None otherwise. Where it is
        not None, ``fs`` (DDA's) governs and the row says so (`explain`)."""
        if self.evaluator != Method.DDA or self.screened_by != Method.SARMA or self.screening_fs is None:
            return None
        sarma, dda = self.screening_fs, self.fs
        if math.isnan(sarma) or math.isnan(dda) or math.isinf(dda) or not sarma > SARMA_ABOVE_DDA * dda:
            return None
        return math.inf if math.isinf(sarma) or dda <= 0.0 else sarma / dda - 1.0

    @property
    def critical_acceleration(self) -> Optional[float]:
        """Sarma's K_c of the governing mode [g], if the evaluator computed it."""
        return self.mode.critical_acceleration

    def explain(self) -> str:
        """Which mode governs and why: the governing mode, the other admissible ones (safer),
        and why the modes not kept are not admissible (lines of `format_groups`)."""
        return "\n".join(_explain_lines(self))


@dataclass(frozen=True, kw_only=True, eq=False)
class Report:
    """Outcome of `kgm.analyze`."""

    method: str
    """'rigid', 'sarma' or 'dda'."""
    critical: Optional[GroupResult]
    """Least safe key group of the first round (None: the slope has no key group)."""
    groups: tuple
    """Candidate key groups of the first round, least safe first (`GroupResult`)."""
    block_types: dict
    """Block id -> Goodman–Shi type 'I'..'V' (docs/kgm/method.md §2.3), first round."""
    history: tuple
    """Least safe group of every round, in order; in progressive mode the unstable ones were
    removed one after the other and the last is the first stable one (if any)."""
    removed: tuple = ()
    """Groups removed in progressive mode, in removal order (frozensets of block ids)."""
    failure_surface: tuple = ()
    """Progressive mode: the envelope of the removed blocks against the remaining rock,
    polylines (k, 2) [m]; otherwise the critical group's surface."""
    fs_target: float = 1.0
    """FS below which a group is unstable [-]."""
    wall_time: float = 0.0
    """Wall-clock time of the analysis [s]."""

    def table(self) -> str:
        """Candidate groups as a text table (least safe first)."""
        return format_groups(self.groups)


# ---------------------------------------------------------------------- a group's row
def group_result(system: BlockSystem, blocks: frozenset, evaluation: Evaluation, method: Method, fs_target: float,
                 *, seed: Optional[int] = None, iteration: int = 0) -> GroupResult:
    """The row of a group judged by limit equilibrium (``method``): FS, critical friction,
    verdict against ``fs_target``, governing mode and failure surface, the water, bolt and
    seismic loads of the system where it has them."""
    return GroupResult(blocks=blocks, fs=evaluation.fs, critical_friction=critical_friction_of(evaluation),
                       stable=evaluation.fs >= fs_target, mode=evaluation.mode,
                       surface=contact_polylines(system, evaluation.mode.sliding_contacts), evaluator=method,
                       seed=seed, iteration=iteration, modes=evaluation.modes, rejected=evaluation.rejected,
                       **_loads_of(system, blocks, evaluation))


def judged_by_dda(row: GroupResult, dda) -> GroupResult:
    """The row of a group (judged by limit equilibrium) with the DDA judge's answer
    (`kgm.DdaEvaluation`): its FS, critical friction and verdict at the scene's strength; the
    mode, surface and loads stay the screening method's."""
    return replace(row, fs=dda.fs, critical_friction=dda.critical_friction, stable=dda.judgement.stable,
                   evaluator=Method.DDA, dda=dda, screening_fs=row.fs, screened_by=row.evaluator)


def _loads_of(system: BlockSystem, blocks: frozenset, ev: Evaluation) -> dict:
    """The water, bolt and seismic loads of a group for its report row (only those present)."""
    members = sorted(blocks)
    out = {}
    if system.contact_water is not None:
        surface = np.concatenate([ev.mode.sliding_contacts, ev.mode.sheared_contacts]).astype(np.int64)
        out["water_force"] = float(system.contact_water[np.unique(surface)].sum())
    if system.block_bolt is not None:
        out["bolt_force"] = float(np.hypot(*(system.block_bolt[members] + system.block_passive[members]).sum(axis=0)))
    if system.block_seismic is not None:
        out["seismic"] = system.seismic
    return out


# ---------------------------------------------------------------------- surfaces
def contact_polylines(system: BlockSystem, contacts: Sequence[int]) -> tuple:
    """Chain contact segments that share end points into polylines (k, 2) [m], each ordered
    from left to right."""
    tol = 10 * DISTANCE_TOL * system.scale
    segs = [[system.contact_start[k].copy(), system.contact_end[k].copy()] for k in np.unique(contacts)]
    lines: list[list[np.ndarray]] = []
    while segs:
        line = segs.pop(0)
        grown = True
        while grown:
            grown = False
            for i, (p, q) in enumerate(segs):
                if np.hypot(*(p - line[-1])) <= tol:
                    line.append(q)
                elif np.hypot(*(q - line[-1])) <= tol:
                    line.append(p)
                elif np.hypot(*(q - line[0])) <= tol:
                    line.insert(0, p)
                elif np.hypot(*(p - line[0])) <= tol:
                    line.insert(0, q)
                else:
                    continue
                segs.pop(i)
                grown = True
                break
        arr = np.array(line)
        if arr[0, 0] > arr[-1, 0]:
            arr = arr[::-1]
        lines.append(_drop_collinear(arr))
    return tuple(sorted(lines, key=lambda a: float(a[:, 0].min())))


def _drop_collinear(p: np.ndarray) -> np.ndarray:
    if len(p) < 3:
        return p
    keep = [0]
    for i in range(1, len(p) - 1):
        a, b = p[i] - p[keep[-1]], p[i + 1] - p[i]
        if abs(a[0] * b[1] - a[1] * b[0]) > 1e-9 * np.hypot(*a) * np.hypot(*b):
            keep.append(i)
    keep.append(len(p) - 1)
    return p[keep]


# ---------------------------------------------------------------------- tables
def _fmt(x: Optional[float], digits: int = 3) -> str:
    if x is None or (isinstance(x, float) and math.isnan(x)):
        return "-"
    if math.isinf(x):
        return "inf"
    return f"{x:.{digits}f}"


def format_groups(groups: Sequence[GroupResult]) -> str:
    """Text table of candidate groups: rank, blocks, evaluator, FS, φc, K_c, mode, verdict."""
    # water, bolt and seismic columns only where the analysis has them
    water = any(g.water_force is not None for g in groups)
    bolts = any(g.bolt_force is not None for g in groups)
    quake = any(g.seismic is not None for g in groups)
    extra_head = ((f" {'U kN/m':>8}" if water else "") + (f" {'bolt kN/m':>9}" if bolts else "")
                  + (f" {'kh, kv':>11}" if quake else ""))
    head = (f"{'#':>3}  {'blocks':<18} {'eval':<6} {'FS':>7} {'phi_c':>7} {'K_c':>8}{extra_head}  "
            f"{'mode':<9} verdict")
    rows = [head, "-" * len(head)]
    for i, g in enumerate(groups):
        ids = "{" + ", ".join(str(b) for b in sorted(g.blocks)) + "}"
        extra = ""
        if water:
            extra += f" {_fmt(None if g.water_force is None else g.water_force / 1e3, 1):>8}"
        if bolts:
            extra += f" {_fmt(None if g.bolt_force is None else g.bolt_force / 1e3, 1):>9}"
        if quake:
            k = "-" if g.seismic is None else f"{g.seismic[0]:.3g}, {g.seismic[1]:.3g}"
            extra += f" {k:>11}"
        rows.append(f"{i + 1:>3}  {ids:<18} {g.evaluator:<6} {_fmt(g.fs):>7} {_fmt(g.critical_friction, 2):>7} "
                    f"{_fmt(g.critical_acceleration):>8}{extra}  {g.mode.kind.value:<9} {g.verdict}")
        if g.mode.block_modes:
            rows.append(f"{'':>5}{_block_modes_line(g.mode.block_modes)}")
        rows += [f"{'':>5}{line}" for line in _explain_lines(g)]
    return "\n".join(rows)


#: Words for a mode in the tables.
_MODE_WORDS = {ModeKind.LIFTING: "lifting (the loads pull it off every contact)",
               ModeKind.SLIDING: "rigid sliding on one plane",
               ModeKind.ROTATION: "rigid rotation (about a vertex, or turning while it slides on two points)",
               ModeKind.SARMA: "Sarma mechanism (the blocks slide apart, shearing the joints between them)",
               ModeKind.TOPPLING: "block toppling (Goodman–Bray row)",
               ModeKind.NONE: "no admissible mode (stable by geometry)"}


def _explain_lines(g: GroupResult) -> list[str]:
    """'governs: ...', 'also admissible: ...', 'not admissible: ...' lines of a group; a row
    judged by DDA names DDA's factor as governing, its screening mode after it, and says where
    Sarma is above DDA (`GroupResult.sarma_above_dda`)."""
    lines = []
    mode = (_MODE_WORDS[ModeKind.NONE] if g.mode.kind == ModeKind.NONE
            else f"{_MODE_WORDS.get(g.mode.kind.value, g.mode.kind.value)}, FS {_fmt(g.mode.fs)}")
    if g.evaluator == Method.DDA and g.screened_by is not None:
        lines.append(f"governs: DDA strength reduction, FS {_fmt(g.fs)} (screened by {g.screened_by}: {mode})")
        above = g.sarma_above_dda
        if above is not None:
            by = "inf" if math.isinf(above) else f"{100 * above:.1f}"
            lines.append(f"Sarma above DDA by {by} %: DDA's factor {_fmt(g.fs)} governs, not Sarma's "
                         f"{_fmt(g.screening_fs)} (docs/kgm/footwall.md §9)")
    else:
        lines.append(f"governs: {mode}")
    if g.mode.unbalanced_moment:
        lines.append(f"moment not balanced: {g.mode.unbalanced_moment}; Sarma's translation is on the unsafe "
                     f"side here, judge the group with DDA (docs/kgm/footwall.md §9)")
    others = [m for m in g.modes if m is not g.mode]
    if others:
        lines.append("also admissible (safer): " + ", ".join(f"{m.kind.value} {_fmt(m.fs)}" for m in others))
    lines += [f"not admissible: {why}" for why in g.rejected]
    return lines


def _block_modes_line(steps) -> str:
    """'stable {13-15}; toppling {3-12}; sliding {0-2}': blocks by state, top to toe, runs of
    consecutive ids joined."""
    parts = []
    for state in (BlockState.STABLE, BlockState.TOPPLING, BlockState.SLIDING):
        ids = sorted(s.block for s in steps if s.state == state)
        if not ids:
            continue
        runs, start = [], ids[0]
        for a, b in zip(ids, ids[1:] + [None]):
            if b != a + 1:
                runs.append(f"{start}" if start == a else f"{start}-{a}")
                start = b
        parts.append(f"{state.value} {{{', '.join(runs)}}}")
    return "; ".join(parts)


def format_toppling(mode: Mode) -> str:
    """Goodman & Bray's table of a block-toppling mode (Hoek & Bray 1981): per block, top to
    toe, its height y_n, the heights M_n and L_n of the interface forces, P_n from above, the
    forces P_{n-1,t} and P_{n-1,s} it needs from below [kN/m], and its state; at limit
    equilibrium (strength reduced by FS)."""
    if not mode.block_modes:
        return ""
    head = (f"{'block':>5} {'y_n':>7} {'M_n':>7} {'L_n':>7} {'P_n':>10} {'P_n-1,t':>10} {'P_n-1,s':>10}  state")
    rows = [head, "-" * len(head)]
    for st in mode.block_modes:
        rows.append(f"{st.block:>5} {st.height:7.2f} {st.contact_above:7.2f} {st.contact_below:7.2f} "
                    f"{_fmt(st.force_above / 1e3, 1):>10} {_fmt(st.force_toppling / 1e3, 1):>10} "
                    f"{_fmt(st.force_sliding / 1e3, 1):>10}  {st.state.value}")
    return "\n".join(rows)


def format_paper_table(results: Sequence[GroupResult], *, title: str = "") -> str:
    """The layout of the paper's comparison: method, factor of safety, critical friction
    angle, verdict (one row per evaluator of the same group), as a Markdown table."""
    names = {Method.RIGID: "KGM (rigid group)", Method.SARMA: "SKGM (Sarma)", Method.DDA: "KGM + DDA (developed)"}
    out = []
    if title:
        out.append(title)
        out.append("")
    out.append("| method | factor of safety | critical friction angle | verdict |")
    out.append("|---|---|---|---|")
    for g in results:
        out.append(f"| {names.get(g.evaluator, g.evaluator)} | {_fmt(g.fs, 3)} | "
                   f"{_fmt(g.critical_friction, 2)}° | {g.verdict} |")
    return "\n".join(out)
