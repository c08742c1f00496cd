"""The outcome of a subset or importance study in a study's terms (docs/kgm/reliability.md):
subset simulation's levels (`StudyLevel`), FORM's design point (`DesignPoint`), and the
estimator run again on a study file's values of FS (`replay`, for `kgm.read_study`).

The estimators (`kgm.studies.reliability`) work in standard normal space on g = FS − 1; here
their thresholds are FS values and their points the variables' values, as an engineer reads
them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable

import numpy as np

from ..kinds import Method, Sampling


@dataclass(frozen=True, kw_only=True, eq=False)
class StudyLevel:
    """A level of a subset simulation in the study's terms (`kgm.Study.levels`)."""

    fs_threshold: float
    """The next domain is FS ≤ this (1 + the threshold of g; 1 at the last level) [-]."""
    probability: float
    """Fraction of the level's samples with FS ≤ ``fs_threshold`` [-]."""
    cov: float
    """Its c.o.v., Au & Beck's, with the chains' correlation [-]."""
    gamma: float
    """The chains' correlation factor γ [-]."""
    acceptance: float
    """Fraction of the chain moves accepted (nan at level 0) [-]."""
    evaluations: int
    """Evaluations up to the end of the level [-]."""
    u: np.ndarray
    """The level's samples in standard normal space (n, d) [-]."""
    values: dict
    """The level's samples in the variables' units: name -> (n,)."""
    fs: np.ndarray
    """Their FS (n,) [-]."""


@dataclass(frozen=True, kw_only=True, eq=False)
class DesignPoint:
    """FORM's design point (`kgm.Study.design_point`): the most probable combination of the
    inputs at which the slope fails; the variables with the largest ‖α‖ drive failure."""

    values: dict
    """The variables at the design point, in their units: name -> value."""
    u: np.ndarray
    """The design point in standard normal space (d,) [-]."""
    beta: float
    """Reliability index ‖u*‖ (negative where the median inputs fail) [-]."""
    alpha: dict
    """Sensitivity of each sampled variable: αᵢ = −(∂g/∂uᵢ)/‖∇g‖ (Σ αᵢ² = 1; αᵢ < 0: failure
    lies towards low values of the variable's normal score) [-]."""
    fs: float
    """FS at the design point (≈ 1) [-]."""
    iterations: int
    evaluations: int
    converged: bool

    @property
    def pf(self) -> float:
        """First-order P_f = Φ(−β) [-]."""
        from scipy.special import ndtr

        return float(ndtr(-self.beta))


def study_levels(estimate, values_of: Callable) -> tuple:
    """The `StudyLevel` s of a `kgm.studies.reliability.SubsetResult`; ``values_of(u)``: the
    variables' values of points u (name -> array)."""
    return tuple(StudyLevel(fs_threshold=lv.threshold + 1.0, probability=lv.probability, cov=lv.cov, gamma=lv.gamma,
                            acceptance=lv.acceptance, evaluations=lv.evaluations, u=lv.u, values=values_of(lv.u),
                            fs=lv.g + 1.0) for lv in estimate.levels)


def design_point(found, sampled, values: dict) -> DesignPoint:
    """The `DesignPoint` of a `kgm.studies.reliability.FormResult`; ``sampled``: the names of
    u's components, ``values``: the variables at u*."""
    return DesignPoint(values=values, u=found.u, beta=found.beta,
                       alpha={k: float(a) for k, a in zip(sampled, found.alpha)}, fs=found.g + 1.0,
                       iterations=found.iterations, evaluations=found.evaluations, converged=found.converged)


def generalised_beta(pf: float) -> float:
    """−Φ⁻¹(P_f) [-] (±inf at 0 and 1, nan for nan)."""
    from scipy.special import ndtri

    if not math.isfinite(pf):
        return math.nan
    return float(-ndtri(pf)) if 0.0 < pf < 1.0 else (math.inf if pf == 0.0 else -math.inf)


def form_step(step, method) -> float:
    """FORM's finite-difference step in u: as given, else 0.05 (limit equilibrium) or 0.5
    (DDA, whose FS is resolved to `kgm.DdaSettings.fs_tolerance`) [-]."""
    return step or (0.5 if method == Method.DDA else 0.05)


# ---------------------------------------------------------------------- a study file, again
class _Replay:
    """g served from a study file's rows, in their order."""

    def __init__(self, fs: np.ndarray):
        self.fs, self.count = fs, 0
        self.row_of: dict = {}  # a point's bytes -> its row

    def __call__(self, u: np.ndarray) -> np.ndarray:
        first, self.count = self.count, self.count + len(u)
        if self.count > len(self.fs):
            raise _Incomplete
        self.row_of.update((np.ascontiguousarray(p).tobytes(), first + j) for j, p in enumerate(u))
        return self.fs[first:self.count] - 1.0


class _Incomplete(Exception):
    pass


def replay(identity: dict, table: np.ndarray) -> dict:
    """The fields of the `kgm.Study` of a subset or importance study file: the estimator run
    again on the file's values of FS (no evaluation: the file is the log of the estimator's
    requests, each level's samples its rows). A file cut short gives P_f nan."""
    from . import reliability

    est = identity.get("estimator")
    if est is None:  # written by Study.to_csv, which keeps the table only
        return dict(pf=math.nan, beta=math.nan)
    dim, n, seed = len(est["sampled"]), identity["n"], identity["seed"]
    complete = len(table) > 0 and np.array_equal(table["index"], np.arange(len(table)))
    g = _Replay(np.where(table["lost"], np.nan, table["fs"]))
    names = identity["variables"]

    def values_of(u):  # the rows that evaluated each point
        rows = np.array([g.row_of[np.ascontiguousarray(p).tobytes()] for p in u], dtype=int)
        return {k: table[k][rows] for k in names}

    estimate, design, levels = None, None, ()
    try:
        if not complete:
            raise _Incomplete
        if identity["sampling"] == Sampling.SUBSET:
            estimate = reliability.subset_simulation(g, dim, n=n, p0=est["p0"], seed=seed, proposal=est["proposal"],
                                                     spread=est["spread"], max_levels=est["max_levels"])
            levels = study_levels(estimate, values_of)
        else:
            found = reliability.form(g, dim, step=form_step(est["step"], identity["method"]), tol=est["tol"],
                                     max_iterations=est["max_iterations"])
            estimate = reliability.importance_sampling(g, dim, centre=found.u, n=n, seed=seed, batch=est["batch"])
            try:
                at = {k: float(v[0]) for k, v in values_of(found.u[None]).items()}
            except KeyError:  # not one of the rows (it always is: FORM evaluates its last point)
                at = {}
            design = design_point(found, est["sampled"], at)
    except _Incomplete:
        estimate = None
    if estimate is None or g.count != len(table):
        return dict(pf=math.nan, beta=math.nan)
    return dict(pf=float(estimate.pf), beta=generalised_beta(float(estimate.pf)), pf_cov=float(estimate.cov),
                levels=levels, design_point=design, estimate=estimate)
