"""A probabilistic study's outcome (docs/kgm/probabilistic.md): `Study` (P_f, β, the FS
distribution, the block frequency map and the table of every sample), one sample's
`SampleRow`, the study file (a CSV written as the samples complete, resumed by a study started
again, read back by `read_study`) and the picture of the block frequencies.

The file's first line identifies the study (``# kgm probabilistic study {...}``, the arguments
that determine its samples); a file of another study is refused. Then a header and one line a
sample: index, seed, the sampled values, fs, failed (0/1), the critical group's block ids
separated by spaces and lost (0/1: the sample's worker process died twice while running it,
`ddatai.workers`); floats written by ``repr``, so a file read back gives the same table. A
subset or importance study (docs/kgm/reliability.md) writes one line an evaluation, in the
order its estimator asked for them.
"""

from __future__ import annotations

import csv
import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Mapping, Optional

import numpy as np

from ..kinds import RARE_SAMPLINGS, Sampling

#: first line of a study file: what identifies the study (a file of another study is refused)
HEADER_MARK = "# kgm probabilistic study "


@dataclass(frozen=True, kw_only=True)
class SampleRow:
    """One sample's outcome: a row of `Study.table` and a line of the study file."""

    fs: float
    """Factor of safety of the sample's critical group [-] (inf: no key group; nan: a DDA
    verdict without strength reduction)."""
    failed: bool
    """Whether the critical group fails (FS below the target, or unstable under DDA)."""
    critical: tuple = ()
    """Block ids of the critical group, ascending (empty: the sample has no key group)."""
    lost: bool = False
    """The sample was given up: its worker process died twice while running it (killed by the
    out-of-memory killer, a crash in a native library; `ddatai.workers`). Its FS is nan, it is
    not failed, and P_f leaves it out."""

    @property
    def critical_text(self) -> str:
        """The critical group as the table and the file spell it: ids separated by spaces."""
        return " ".join(str(b) for b in self.critical)

    @classmethod
    def of_group(cls, fs: float, failed: bool, blocks) -> "SampleRow":
        return cls(fs=float(fs), failed=bool(failed), critical=tuple(sorted(int(b) for b in blocks)))

    @classmethod
    def from_text(cls, fs: float, failed: bool, critical: str, lost: bool = False) -> "SampleRow":
        return cls(fs=fs, failed=failed, critical=tuple(int(b) for b in critical.split()), lost=lost)

    @classmethod
    def given_up(cls) -> "SampleRow":
        """The row of a lost sample."""
        return cls(fs=math.nan, failed=False, lost=True)



@dataclass(frozen=True, kw_only=True, eq=False)
class Study:
    """Outcome of `probabilistic`."""

    n: int
    """Samples [-]."""
    pf: float
    """Probability of failure: the fraction of samples whose critical group fails (FS < 1, or
    unstable under DDA), among the samples evaluated (not `lost`) [-]; subset simulation and
    importance sampling: their estimate."""
    beta: float
    """Reliability index β = (mean FS − 1) / standard deviation of FS, over the samples with a
    finite FS (the definition of RocPlane and Slide, exact for a normally distributed FS) [-];
    nan when fewer than two samples have a finite FS."""
    table: np.ndarray
    """One row per sample, in sample order (a NumPy structured array): ``index``, ``seed``,
    the sampled variables (their names), ``fs``, ``failed``, ``critical`` (the critical
    group's block ids, space-separated) and ``lost`` (`Study.lost`)."""
    variables: tuple
    """Names of the sampled variables, in table order."""
    method: str
    """Evaluator: 'rigid', 'sarma' or 'dda'."""
    sampling: str
    """'monte-carlo', 'latin-hypercube', 'subset' or 'importance'."""
    seed: int
    """Seed of the study."""
    resumed: int = 0
    """Samples read from an earlier run's file instead of evaluated [-]."""
    wall_time: float = 0.0
    """Wall time of this call [s]."""
    # subset simulation and importance sampling (kgm.studies.rare, docs/kgm/reliability.md)
    pf_cov: float = math.nan
    """Coefficient of variation of ``pf``: Monte Carlo √((1 − P_f)/(n·P_f)); subset simulation
    Au & Beck's estimate with the chains' correlation; importance sampling its sampling c.o.v.
    [-]."""
    levels: tuple = ()
    """Subset simulation: its levels (`kgm.studies.estimates.StudyLevel`: FS thresholds,
    conditional probabilities, samples)."""
    evaluations: int = 0
    """Limit-state evaluations the estimate rests on (Monte Carlo: the samples) [-]."""
    design_point: Any = None
    """Importance sampling: FORM's design point (`kgm.studies.estimates.DesignPoint`), in the
    variables' units, with β and each variable's sensitivity α."""
    estimate: Any = None
    """Subset simulation and importance sampling: the estimator's own result
    (`kgm.studies.reliability`), in standard normal space."""
    limit_state: Optional[Callable] = None
    """Subset simulation and importance sampling by limit equilibrium: FS of samples given by
    their values (name -> array), in this process (`plot_levels` draws FS = 1 with it)."""

    @property
    def fs(self) -> np.ndarray:
        """Factor of safety of every sample's critical group [-] (inf: no failure mode; nan: a
        DDA verdict without strength reduction)."""
        return self.table["fs"]

    @property
    def failed(self) -> np.ndarray:
        return self.table["failed"]

    @property
    def lost(self) -> np.ndarray:
        """Samples given up because their worker process died twice while running them (killed
        by the out-of-memory killer, a crash in a native library): recorded with their values,
        ``fs`` nan, not failed, and left out of P_f (`ddatai.workers`)."""
        return self.table["lost"]

    @property
    def beta_pf(self) -> float:
        """The reliability index that P_f corresponds to, −Φ⁻¹(P_f) [-] (±inf when no sample or
        every sample failed)."""
        from scipy.stats import norm

        return float(-norm.ppf(self.pf))

    def pf_interval(self, confidence: float = 0.95) -> tuple[float, float]:
        """Confidence interval of P_f (Wilson's score interval for a binomial proportion; for
        Monte Carlo sampling — Latin hypercube estimates are tighter; subset simulation and
        importance sampling: P_f ×/÷ exp(z·√ln(1 + c.o.v.²)), the estimate taken as lognormal)."""
        from scipy.stats import norm

        z = float(norm.ppf(0.5 + 0.5 * confidence))
        if self.sampling in RARE_SAMPLINGS:
            k = math.exp(z * math.sqrt(math.log1p(self.pf_cov ** 2))) if math.isfinite(self.pf_cov) else math.inf
            return self.pf / k, min(1.0, self.pf * k)
        n, p = self.n - int(np.count_nonzero(self.lost)), self.pf
        centre = (p + z * z / (2 * n)) / (1 + z * z / n)
        half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / (1 + z * z / n)
        return max(0.0, centre - half), min(1.0, centre + half)

    def block_frequency(self) -> dict:
        """Block id -> fraction of the samples in whose critical group it is [-] (a map of the
        probable failure surface)."""
        counts: dict = {}
        for row in self.table["critical"]:
            for b in str(row).split():
                counts[int(b)] = counts.get(int(b), 0) + 1
        return {b: c / self.n for b, c in sorted(counts.items())}

    def fs_quantiles(self, q=(0.05, 0.5, 0.95)) -> dict:
        """Quantiles of the FS distribution [-]."""
        return {float(p): float(np.quantile(self.fs, p)) for p in q}

    def summary(self) -> str:
        lo, hi = self.pf_interval()
        lost = int(np.count_nonzero(self.lost))
        gave_up = f"; {lost} sample(s) lost (their worker process died twice), not counted" if lost else ""
        if self.sampling in RARE_SAMPLINGS:
            how = (f"subset simulation, {len(self.levels)} levels" if self.sampling == Sampling.SUBSET else
                   f"importance sampling at the design point, beta_FORM = {self.design_point.beta:.3f}")
            return (f"{self.evaluations} evaluations ({how}, {self.method}, seed {self.seed}): P_f = {self.pf:.3g} "
                    f"(c.o.v. {self.pf_cov:.2f}, 95 % {lo:.3g}-{hi:.3g}), beta = {self.beta:.3f}{gave_up}")
        finite = self.fs[np.isfinite(self.fs)]
        mean = float(np.mean(finite)) if len(finite) else math.inf
        return (f"{self.n} samples ({self.sampling}, {self.method}, seed {self.seed}): "
                f"P_f = {self.pf:.4f} (95 % {lo:.4f}-{hi:.4f}), beta = {self.beta:.3f}, "
                f"mean FS = {mean:.3f}{gave_up}")

    def plot_levels(self, path=None, **kwargs):
        """Subset simulation's levels (importance sampling's samples) over the two variables
        that drive failure, with FS = 1 (`kgm.studies.plots.plot_levels`; the [plot] extra)."""
        from .plots import plot_levels

        return plot_levels(self, path, **kwargs)

    def plot_convergence(self, path=None):
        """The P_f estimate against evaluations (`kgm.studies.plots.plot_convergence`)."""
        from .plots import plot_convergence

        return plot_convergence(self, path)

    def to_csv(self, path) -> Path:
        """Write the table (with the study's header line) to ``path``; returns the path. (A
        subset or importance study's own ``out`` file also names its estimator's settings, so
        that `read_study` runs the estimator again on it; this file keeps the table only.)"""
        path = Path(path)
        with open(path, "w", newline="") as fh:
            fh.write(HEADER_MARK + json.dumps(self._identity()) + "\n")
            w = csv.writer(fh)
            w.writerow(self.table.dtype.names)
            for row in self.table:
                w.writerow([_cell(v) for v in row])
        return path

    def _identity(self) -> dict:
        return dict(n=self.n, seed=self.seed, sampling=self.sampling, method=self.method,
                    variables=list(self.variables))

    def write_png(self, scene, path, *, size=(640, 480), title: Optional[str] = None) -> Path:
        """Draw the scene's blocks coloured by `block_frequency` (white: never in the critical
        group, dark red: always; fixed blocks grey) with a colour bar; returns the path."""
        return write_frequency_png(scene, self.block_frequency(), path, size=size,
                                   title=title or f"P_f = {self.pf:.3f}, {self.n} samples")


def _cell(v) -> Any:
    """A table cell as the study file writes it (floats by repr: read back, the same bits)."""
    if isinstance(v, (np.floating, float)):
        return repr(float(v))
    if isinstance(v, (np.bool_, bool)):
        return int(bool(v))
    if isinstance(v, np.integer):
        return int(v)
    return str(v)


def reliability_index(fs: np.ndarray) -> float:
    """β = (mean FS − 1) / sd(FS) over the finite FS (`Study.beta`)."""
    finite = fs[np.isfinite(fs)]
    if len(finite) < 2 or np.std(finite) == 0:
        return math.nan
    return float((np.mean(finite) - 1.0) / np.std(finite, ddof=1))


def pf_of(table: np.ndarray) -> float:
    """Failed samples over the samples evaluated (the lost ones left out) [-]."""
    kept = ~table["lost"]
    return float(np.mean(table["failed"][kept])) if np.any(kept) else math.nan


def monte_carlo_cov(table: np.ndarray) -> float:
    """√((1 − P_f)/(n·P_f)) of a Monte Carlo study's P_f [-] (inf when no sample failed)."""
    kept = int(np.count_nonzero(~table["lost"]))
    pf = pf_of(table)
    return math.sqrt((1.0 - pf) / (kept * pf)) if kept and pf > 0.0 else math.inf


def table_dtype(names: tuple, width: int) -> list:
    """Columns of a study table (`Study.table`); ``width``: characters of the longest
    ``critical`` entry."""
    return [("index", np.int64), ("seed", np.int64)] + [(k, np.float64) for k in names] + \
        [("fs", np.float64), ("failed", bool), ("critical", f"U{width}"), ("lost", bool)]


def file_columns(names: tuple) -> list:
    """The header of a study file."""
    return ["index", "seed", *names, "fs", "failed", "critical", "lost"]


def study_table(n: int, names: tuple, samples: dict, seeds: np.ndarray, done: Mapping) -> np.ndarray:
    """`Study.table` of the sampled values ``samples`` and the rows ``done`` (index ->
    `SampleRow`)."""
    table = np.zeros(n, dtype=table_dtype(names, max([len(done[i].critical_text) for i in done] + [1])))
    table["index"] = np.arange(n)
    table["seed"] = seeds
    for k in names:
        table[k] = samples[k]
    for i, row in done.items():
        table["fs"][i], table["failed"][i], table["critical"][i] = row.fs, row.failed, row.critical_text
        table["lost"][i] = row.lost
    return table


# ---------------------------------------------------------------------- the study file
class StudyFile:
    """Appends completed samples to a study file, one line each, flushed (a killed study loses
    at most the samples in flight)."""

    def __init__(self, path: Path, identity: dict, names: tuple):
        fresh = not path.exists() or path.stat().st_size == 0
        path.parent.mkdir(parents=True, exist_ok=True)
        self.fh = open(path, "a", newline="")
        self.writer = csv.writer(self.fh)
        if fresh:
            self.fh.write(HEADER_MARK + json.dumps(identity) + "\n")
            self.writer.writerow(file_columns(names))
            self.fh.flush()

    def append(self, index: int, seed: int, values, row: SampleRow) -> None:
        self.writer.writerow([index, seed, *[repr(float(v)) for v in values], repr(float(row.fs)), int(row.failed),
                              row.critical_text, int(row.lost)])
        self.fh.flush()

    def close(self) -> None:
        self.fh.close()


def read_samples(path: Path, identity: dict, names: tuple) -> dict:
    """Samples already in a study file: index -> `SampleRow`. A file of another study is
    refused; a last line cut short by a kill is ignored (and rewritten), and a file written
    before studies recorded lost samples is rewritten with that column (none lost)."""
    if not path.exists() or path.stat().st_size == 0:
        return {}
    with open(path, newline="") as fh:
        first = fh.readline()
        if not first.startswith(HEADER_MARK):
            raise ValueError(f"{path} is not a kgm probabilistic study file (no '{HEADER_MARK.strip()}' line)")
        theirs = json.loads(first[len(HEADER_MARK):])
        if theirs != identity:
            raise ValueError(f"{path} holds another study ({theirs}); this one is {identity}: "
                             "use another file or delete it")
        lines = fh.read().splitlines(keepends=True)
    done = {}
    good = []
    header = lines[0] if lines else ""
    old = bool(header) and next(csv.reader([header])) == file_columns(names)[:-1]  # no 'lost' column
    for line in lines[1:]:
        row = next(csv.reader([line]))
        if not line.endswith("\n") or len(row) != len(names) + (5 if old else 6):
            break  # cut short
        try:
            if old:
                done[int(row[0])] = SampleRow.from_text(float(row[-3]), bool(int(row[-2])), row[-1])
                line = line.rstrip("\r\n") + ",0\r\n"
            else:
                done[int(row[0])] = SampleRow.from_text(float(row[-4]), bool(int(row[-3])), row[-2],
                                                        bool(int(row[-1])))
        except ValueError:
            break
        good.append(line)
    if old or len(good) != len(lines) - 1:  # drop a partial last line before appending
        if old:
            header = header.rstrip("\r\n") + ",lost\r\n"
        with open(path, "w", newline="") as fh:
            fh.write(first + header + "".join(good))
    return done


def read_study(path) -> Study:
    """A study from its CSV file (`Study.to_csv` or a study's ``out`` file), complete or not:
    the rows present, in sample order."""
    path = Path(path)
    with open(path, newline="") as fh:
        first = fh.readline()
        if not first.startswith(HEADER_MARK):
            raise ValueError(f"{path} is not a kgm probabilistic study file")
        identity = json.loads(first[len(HEADER_MARK):])
        rows = list(csv.DictReader(fh))
    names = tuple(identity["variables"])
    rows = sorted((r for r in rows if r.get("critical") is not None), key=lambda r: int(r["index"]))
    table = np.zeros(len(rows), dtype=table_dtype(names, max([len(r["critical"]) for r in rows] + [1])))
    for j, r in enumerate(rows):
        table[j] = (int(r["index"]), int(r["seed"]), *[float(r[k]) for k in names], float(r["fs"]),
                    bool(int(r["failed"])), r["critical"], bool(int(r.get("lost") or 0)))
    if identity["sampling"] in RARE_SAMPLINGS:
        from .estimates import replay

        return Study(table=table, variables=names, method=identity["method"], sampling=identity["sampling"],
                     seed=identity["seed"], n=len(rows), evaluations=len(rows), **replay(identity, table))
    return Study(n=len(rows), pf=pf_of(table) if len(rows) else math.nan, beta=reliability_index(table["fs"]),
                 table=table, variables=names, method=identity["method"], sampling=identity["sampling"],
                 seed=identity["seed"], pf_cov=monte_carlo_cov(table), evaluations=len(rows))


# ---------------------------------------------------------------------- the picture
def write_frequency_png(scene, frequency: Mapping, path, *, size=(640, 480), title: str = "") -> Path:
    """The scene's blocks coloured by how often each is in the critical group (Pillow)."""
    from PIL import Image, ImageDraw

    w, h = size
    polys = [np.asarray(scene.polygon(b), float) for b in range(scene.n_blocks)]
    allxy = np.concatenate(polys)
    lo, hi = allxy.min(axis=0), allxy.max(axis=0)
    bar = 60
    scale = min((w - bar - 20) / max(hi[0] - lo[0], 1e-12), (h - 50) / max(hi[1] - lo[1], 1e-12))

    def px(p):
        return [(float(10 + (x - lo[0]) * scale), float(h - 10 - (y - lo[1]) * scale)) for x, y in p]

    def colour(f):  # white -> dark red
        f = min(max(f, 0.0), 1.0)
        return (255, int(255 - 215 * f), int(255 - 235 * f)) if f < 0.5 else \
            (int(255 - 115 * (f - 0.5) * 2), int(147 - 107 * (f - 0.5) * 2), int(137 - 117 * (f - 0.5) * 2))

    img = Image.new("RGB", (w, h), (250, 250, 250))
    d = ImageDraw.Draw(img)
    fixed = {b for b in range(scene.n_blocks) if scene.blocks[b].fixed} if hasattr(scene, "blocks") else set()
    for b, p in enumerate(polys):
        fill = (190, 190, 190) if b in fixed else colour(float(frequency.get(b, 0.0)))
        d.polygon(px(p), fill=fill, outline=(60, 60, 60))
    x0 = w - bar + 10
    for k in range(100):
        y = h - 40 - k * (h - 80) / 100.0
        d.rectangle([x0, y - (h - 80) / 100.0, x0 + 15, y], fill=colour(k / 99.0))
    d.text((x0 + 18, 35), "1", fill=(0, 0, 0))
    d.text((x0 + 18, h - 50), "0", fill=(0, 0, 0))
    d.text((x0 - 10, 15), "freq.", fill=(0, 0, 0))
    if title:
        d.text((10, 5), title, fill=(0, 0, 0))
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    img.save(path)
    return path

