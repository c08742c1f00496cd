"""Estimators of small probabilities of failure, in standard normal space (docs/kgm/reliability.md).

The uncertain inputs are independent standard normal variables u ∈ Rᵈ (a study reaches them
through each variable's distribution and the correlation: `kgm.probabilistic`); the limit state
g(u) fails where g ≤ 0 (g = FS − 1). ``g`` is evaluated on batches: it takes an array of points
(m, d) and returns their values (m,), so that a study can run a batch's points in parallel on
its workers. A nan value (a sample that could not be evaluated) counts as safe (+inf).

* `subset_simulation` (Au & Beck 2001): P_f as a product of conditional probabilities of
  nested failure domains g ≤ b₁ > b₂ > … > 0, each about ``p0``, the samples of each level
  drawn by modified Metropolis chains (component-wise, Au & Beck §4) started from the previous
  level's samples in the next domain. A level's chains advance in step, so that each step is
  one batch of as many points as chains. Cost grows with log(1/P_f): about
  n·(1 + (1 − p0)·log(P_f)/log(p0)) evaluations.
* `form`: the design point u* (the most probable failure point, nearest the origin on g = 0)
  by HL-RF iterations with a merit line search (Zhang & Der Kiureghian 1995), gradients by
  forward differences; β = ±‖u*‖ and P_f ≈ Φ(−β).
* `importance_sampling`: samples of N(u*, I) weighted by φ(u)/φ(u − u*) (Melchers 1989): an
  unbiased P_f with its sampling c.o.v.

Every estimator is reproducible from its seed: its random numbers come from
``numpy.random.default_rng(seed)`` in a fixed order, and g's values only choose among them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable, Optional

import numpy as np


def _norm_cdf(x):
    from scipy.special import ndtr

    return ndtr(x)


def _evaluate(g: Callable, u: np.ndarray) -> np.ndarray:
    """g's values of the points u (m, d), nan counted as +inf (safe); refuses a wrong shape."""
    if len(u) == 0:
        return np.zeros(0)
    values = np.asarray(g(np.array(u, dtype=float, copy=True)), dtype=float).reshape(-1)
    if values.shape != (len(u),):
        raise ValueError(f"the limit state returned {values.shape[0]} values for {len(u)} points")
    return np.where(np.isnan(values), np.inf, values)


def _check(dim, n, seed) -> None:
    if not isinstance(dim, (int, np.integer)) or dim < 1:
        raise ValueError(f"dim (the number of random variables) must be an integer >= 1, got {dim!r}")
    if not isinstance(n, (int, np.integer)) or n < 2:
        raise ValueError(f"n (samples a level / importance samples) must be an integer >= 2, got {n!r}")
    if not isinstance(seed, (int, np.integer)) or isinstance(seed, bool):
        raise ValueError(f"seed must be an integer, got {seed!r}")


# ---------------------------------------------------------------------- subset simulation
#: proposals of the modified Metropolis chains (`subset_simulation`)
PROPOSALS = ("conditional", "random-walk")
#: acceptance rate the adapted proposal spread aims at [-]: 0.2, below the 0.44 Papaioannou et
#: al. (2015) recommend for many variables, because a slope's few variables mix better so
#: (linear limit states in 1, 3 and 8 variables at P_f = 1e-6, 200-300 seeds: the scatter of
#: the estimates 1.33, 1.09 and 1.18 times the mean reported c.o.v.; at 0.44, 2.0 in 1
#: variable and 1.3 in 2 and in 8; docs/kgm/reliability.md)
ACCEPTANCE = 0.2
#: first scale of the adapted spread, times the seeds' standard deviation per component [-]
LAMBDA0 = 0.6

@dataclass(frozen=True, kw_only=True, eq=False)
class Level:
    """One level of a subset simulation: its samples, the threshold b set on them and the
    fraction of them with g ≤ b."""

    u: np.ndarray
    """The level's samples in standard normal space (n, d): level 0 independent, then the
    states of the level's Markov chains, chain after chain (``chains`` of n / chains states
    each, the first state of each its seed from the level before) [-]."""
    g: np.ndarray
    """Their limit-state values (n,) [units of g]."""
    threshold: float
    """b: the p0-quantile of ``g`` (the next level's domain is g ≤ b), or 0 at the last level."""
    probability: float
    """Fraction of the samples with g ≤ b, the conditional probability of the next domain [-]."""
    chains: int
    """Markov chains that drew the samples (0: level 0, independent samples) [-]."""
    acceptance: float
    """Fraction of the chain moves accepted (nan at level 0) [-]."""
    gamma: float
    """Au & Beck's correlation factor γ of the chains' indicators I(g ≤ b) (0 at level 0) [-]."""
    cov: float
    """C.o.v. of ``probability``: √((1 − P)/(n·P)·(1 + γ)) [-]."""
    evaluations: int
    """Evaluations of g up to the end of this level, all levels [-]."""

    @property
    def last(self) -> bool:
        return self.threshold == 0.0


@dataclass(frozen=True, kw_only=True, eq=False)
class SubsetResult:
    """Outcome of `subset_simulation`."""

    pf: float
    """Probability of failure: the product of the levels' probabilities [-]."""
    cov: float
    """Its coefficient of variation by Au & Beck's estimate, √(Σ δⱼ²) over the levels (the
    levels' estimates taken as uncorrelated) [-]."""
    levels: tuple
    """The `Level` s, from the independent samples down to the failure domain."""
    evaluations: int
    """Evaluations of g [-]."""
    converged: bool
    """Whether the last level's p0-quantile reached g ≤ 0 (False: ``max_levels`` levels
    without reaching it; its samples with g ≤ 0, if any, give the last factor of ``pf``,
    else ``pf`` is 0 and P_f is below about p0^max_levels)."""
    n: int
    p0: float
    seed: int

    @property
    def beta(self) -> float:
        """Generalised reliability index −Φ⁻¹(P_f) [-]."""
        from scipy.special import ndtri

        return float(-ndtri(self.pf)) if 0.0 < self.pf < 1.0 else (math.inf if self.pf == 0.0 else -math.inf)

    def history(self) -> tuple[np.ndarray, np.ndarray]:
        """(evaluations, P_f estimate) after each level: the product of the levels' conditional
        probabilities so far times the fraction of the current level's samples with g ≤ 0."""
        evals, est, product = [], [], 1.0
        for level in self.levels:
            evals.append(level.evaluations)
            est.append(product * float(np.mean(level.g <= 0.0)))
            product *= level.probability
        return np.array(evals), np.array(est)


def chain_gamma(indicator: np.ndarray, probability: float) -> float:
    """Au & Beck's (2001, eq. 27–29) correlation factor γ of the indicators (chains, states)
    of a level's Markov chains: γ = 2 Σ_{τ=1}^{Ns−1} (1 − τ·Nc/N) ρ(τ), ρ(τ) = R(τ)/R(0),
    R(τ) = Σ I_k I_{k+τ} / (N − τ·Nc) − P² over all chains [-]."""
    nc, ns = indicator.shape
    n = nc * ns
    r0 = probability * (1.0 - probability)
    if ns < 2 or r0 <= 0.0:
        return 0.0
    x = indicator.astype(float)
    gamma = 0.0
    for tau in range(1, ns):
        r = float(np.sum(x[:, :-tau] * x[:, tau:])) / (n - tau * nc) - probability ** 2
        gamma += 2.0 * (1.0 - tau * nc / n) * r / r0
    return gamma


def _propose(rng, cur: np.ndarray, sigma: np.ndarray, proposal: str) -> tuple[np.ndarray, np.ndarray]:
    """A modified Metropolis candidate for each chain (rows of ``cur``): each component draws
    from its proposal and is kept by its own Metropolis test on φ; returns the candidates and
    which chains moved at all. 'conditional': ξ ~ N(ρu, 1 − ρ²), ρ = √(1 − σ²), reversible
    with respect to φ, so that every component's test passes (conditional sampling,
    Papaioannou et al. 2015); 'random-walk': ξ ~ N(u, σ²), kept with probability
    min(1, φ(ξ)/φ(u)) (Au & Beck 2001)."""
    z = rng.standard_normal(cur.shape)
    if proposal == "conditional":
        rho = np.sqrt(1.0 - sigma * sigma)
        return rho * cur + sigma * z, np.ones(len(cur), bool)
    cand = cur + sigma * z
    keep = rng.random(cur.shape) < np.exp(-0.5 * (cand * cand - cur * cur))
    return np.where(keep, cand, cur), np.any(keep, axis=1)


def _level(u, g, threshold, chains, accepted, proposed, evaluations) -> Level:
    n = len(g)
    below = g <= threshold
    p = float(np.mean(below))
    gamma = chain_gamma(below.reshape(chains, -1), p) if chains else 0.0
    cov = math.sqrt((1.0 - p) / (n * p) * (1.0 + gamma)) if p > 0.0 else math.inf
    return Level(u=u, g=g, threshold=float(threshold), probability=p, chains=chains,
                 acceptance=accepted / proposed if proposed else math.nan, gamma=gamma, cov=cov,
                 evaluations=evaluations)


def subset_simulation(g: Callable, dim: int, *, n: int = 1000, p0: float = 0.1, seed: int = 0,
                      proposal: str = "conditional", spread: Optional[float] = None, max_levels: int = 20,
                      progress: Optional[Callable] = None) -> SubsetResult:
    """P(g(u) ≤ 0) for u ~ N(0, I_dim) by subset simulation (module docstring).

    ``n`` samples a level; ``p0`` the levels' conditional probability (n·p0 chains of 1/p0
    states: both must be whole numbers); ``proposal`` each component's proposal in the
    modified Metropolis chains, 'conditional' or 'random-walk' (``_propose``); ``spread`` its
    standard deviation σ ≤ 1 [-], None: adapted (the seeds' standard deviation per component
    times a factor that follows the chains' acceptance towards `ACCEPTANCE`);
    ``max_levels`` the most levels; ``progress(level)`` is called with each `Level` as it
    completes."""
    _check(dim, n, seed)
    chains = p0 * n
    if not (0.0 < p0 < 1.0) or abs(chains - round(chains)) > 1e-9 or n % round(chains) or round(chains) < 1:
        raise ValueError(f"p0 = {p0!r} with n = {n}: n·p0 (the chains) and 1/p0 (their length) must be whole numbers "
                         "(e.g. p0 = 0.1 with n a multiple of 10)")
    if proposal not in PROPOSALS:
        raise ValueError(f"proposal must be one of {PROPOSALS}, got {proposal!r}")
    if spread is not None and not (isinstance(spread, (int, float)) and 0.0 < spread <= 1.0):
        raise ValueError(f"spread must be None (adapted) or a number in (0, 1], got {spread!r}")
    if not (isinstance(max_levels, int) and max_levels >= 1):
        raise ValueError(f"max_levels must be an integer >= 1, got {max_levels!r}")
    nc = int(round(chains))
    ns = n // nc
    rng = np.random.default_rng(seed)
    u = rng.standard_normal((n, dim))
    gv = _evaluate(g, u)
    evaluations = n
    levels, product = [], 1.0
    n_chains, accepted, proposed = 0, 0, 0
    while True:
        order = np.argsort(gv, kind="stable")
        converged = bool(np.count_nonzero(gv <= 0.0) >= nc)
        if converged or len(levels) + 1 >= max_levels:
            level = _level(u, gv, 0.0, n_chains, accepted, proposed, evaluations)
            levels.append(level)
            product *= level.probability
            if progress is not None:
                progress(level)
            break
        lo, hi = gv[order[nc - 1]], gv[order[nc]]
        threshold = 0.5 * (lo + hi) if np.isfinite(hi) else lo
        level = _level(u, gv, threshold, n_chains, accepted, proposed, evaluations)
        levels.append(level)
        product *= level.probability
        if progress is not None:
            progress(level)
        # the next level: a chain from each of the nc samples of least g, all advanced in step
        state_u = np.empty((nc, ns, dim))
        state_g = np.empty((nc, ns))
        state_u[:, 0], state_g[:, 0] = u[order[:nc]], gv[order[:nc]]
        accepted = proposed = 0
        # the proposal's spread per component: fixed, or the seeds' own standard deviation
        # scaled by λ, which follows the acceptance of each step towards ACCEPTANCE
        # (Papaioannou et al. 2015)
        if spread is None:
            sigma, scale = np.std(state_u[:, 0], axis=0), LAMBDA0
            sigma[sigma == 0.0] = 1.0
        else:
            sigma, scale = np.full(dim, float(spread)), 1.0
        for k in range(1, ns):
            cur, cur_g = state_u[:, k - 1], state_g[:, k - 1]
            # modified Metropolis: each component moves by its own Metropolis step on φ ...
            xi, moved = _propose(rng, cur, np.minimum(scale * sigma, 1.0), proposal)
            # ... and the candidate is kept if it lies in the level's domain
            xi_g = cur_g.copy()
            xi_g[moved] = _evaluate(g, xi[moved])
            evaluations += int(np.count_nonzero(moved))
            ok = moved & (xi_g <= threshold)
            state_u[:, k] = np.where(ok[:, None], xi, cur)
            state_g[:, k] = np.where(ok, xi_g, cur_g)
            accepted += int(np.count_nonzero(ok))
            proposed += nc
            if spread is None:
                scale *= math.exp((np.count_nonzero(ok) / nc - ACCEPTANCE) / math.sqrt(k))
        u, gv = state_u.reshape(n, dim), state_g.reshape(n)
        n_chains = nc
    cov = math.sqrt(sum(level.cov ** 2 for level in levels)) if product > 0.0 else math.inf
    return SubsetResult(pf=float(product), cov=cov, levels=tuple(levels), evaluations=evaluations,
                        converged=converged, n=n, p0=float(p0), seed=int(seed))


# ---------------------------------------------------------------------- FORM
@dataclass(frozen=True, kw_only=True, eq=False)
class FormResult:
    """Outcome of `form`: the design point and the first-order reliability."""

    u: np.ndarray
    """Design point u* in standard normal space (d,) [-]."""
    beta: float
    """Reliability index: ‖u*‖, negative where g(0) ≤ 0 (the median point fails) [-]."""
    alpha: np.ndarray
    """Unit vector −∇g/‖∇g‖ at u* (d,): the importance of each variable, αᵢ² summing to 1 [-]."""
    g: float
    """g(u*) [units of g]."""
    iterations: int
    evaluations: int
    """Evaluations of g, gradients included [-]."""
    converged: bool
    path: np.ndarray
    """The iterates (k, d), from the start to u* [-]."""

    @property
    def pf(self) -> float:
        """First-order probability of failure Φ(−β) [-]."""
        return float(_norm_cdf(-self.beta))


def form(g: Callable, dim: int, *, start: Optional[np.ndarray] = None, step: float = 0.05, tol: float = 1e-3,
         max_iterations: int = 50) -> FormResult:
    """The design point of g by the improved HL-RF iteration (module docstring): from u, with
    g and its forward-difference gradient ∇g (steps of ``step`` in u, one batch of dim + 1
    points), the HL-RF point u' = ((∇g·u − g)/‖∇g‖²)·∇g, reached along u' − u by halving the
    step until the merit ½‖u‖² + c·‖g‖ (c = 2‖u‖/‖∇g‖ + 1) decreases. Stops when ‖g‖ ≤ tol·‖g(start)‖
    and u is parallel to ∇g within ``tol``, or the step is shorter than tol·max(1, ‖u‖)."""
    _check(dim, 2, 0)
    u = np.zeros(dim) if start is None else np.array(start, dtype=float).reshape(dim)
    if not (step > 0.0 and tol > 0.0):
        raise ValueError(f"step and tol must be > 0, got {step!r}, {tol!r}")
    gu = float(_evaluate(g, u[None])[0])
    evaluations = 1
    if not np.isfinite(gu):
        raise ValueError(f"the limit state is not finite at the start point {u.tolist()}: g = {gu}")
    g0 = abs(gu) or 1.0
    path = [u.copy()]
    converged = False
    grad = np.zeros(dim)
    iterations = 0
    for iterations in range(1, max_iterations + 1):
        probes = u[None, :] + step * np.eye(dim)
        gp = _evaluate(g, probes)
        evaluations += dim
        grad = (gp - gu) / step
        norm = float(np.linalg.norm(grad))
        if not np.isfinite(norm) or norm == 0.0:
            raise ValueError(f"the limit state's gradient is {'zero' if norm == 0.0 else 'not finite'} at "
                             f"u = {u.tolist()} (g = {gu}): FORM cannot move from there")
        alpha = -grad / norm
        un = float(np.linalg.norm(u))
        parallel = un == 0.0 or np.linalg.norm(u / un - np.sign(np.dot(u, alpha)) * alpha) <= tol
        if abs(gu) <= tol * g0 and parallel and iterations > 1:
            converged = True
            break
        target = (np.dot(grad, u) - gu) / norm ** 2 * grad
        direction = target - u
        c = 2.0 * un / norm + 1.0

        def merit(x, gx):
            return 0.5 * float(np.dot(x, x)) + c * abs(gx)

        m0, lam = merit(u, gu), 1.0
        for _ in range(8):
            trial = u + lam * direction
            gt = float(_evaluate(g, trial[None])[0])
            evaluations += 1
            if np.isfinite(gt) and merit(trial, gt) < m0:
                break
            lam *= 0.5
        moved = float(np.linalg.norm(trial - u))
        u, gu = trial, gt
        path.append(u.copy())
        if moved <= tol * max(1.0, float(np.linalg.norm(u))) and abs(gu) <= tol * g0:
            converged = True
            break
    beta = float(np.linalg.norm(u))
    if np.dot(u, grad) > 0.0:  # g decreases away from the origin along u: the origin fails
        beta = -beta
    norm = float(np.linalg.norm(grad))
    return FormResult(u=u, beta=beta, alpha=-grad / norm if norm else np.zeros(dim), g=gu, iterations=iterations,
                      evaluations=evaluations, converged=converged, path=np.array(path))


# ---------------------------------------------------------------------- importance sampling
@dataclass(frozen=True, kw_only=True, eq=False)
class ImportanceResult:
    """Outcome of `importance_sampling`."""

    pf: float
    """Probability of failure: the mean of I(g ≤ 0)·w [-]."""
    cov: float
    """Its coefficient of variation, s(I·w)/(√n·P_f) [-]."""
    centre: np.ndarray
    """Centre of the sampling density N(centre, I) (d,) [-]."""
    u: np.ndarray
    """The samples (n, d) [-]."""
    g: np.ndarray
    """Their limit-state values (n,)."""
    weights: np.ndarray
    """φ(u)/φ(u − centre) of each sample (n,) [-]."""
    evaluations: int
    seed: int

    def history(self) -> tuple[np.ndarray, np.ndarray]:
        """(evaluations, P_f estimate) after each sample: the running mean of I·w."""
        k = np.arange(1, len(self.g) + 1)
        return k, np.cumsum((self.g <= 0.0) * self.weights) / k


def importance_sampling(g: Callable, dim: int, *, centre, n: int = 1000, seed: int = 0,
                        batch: Optional[int] = None) -> ImportanceResult:
    """P(g(u) ≤ 0) for u ~ N(0, I_dim) from n samples of N(centre, I) (module docstring),
    evaluated in batches of ``batch`` points (None: all at once)."""
    _check(dim, n, seed)
    centre = np.array(centre, dtype=float).reshape(dim)
    rng = np.random.default_rng(seed)
    u = centre + rng.standard_normal((n, dim))
    size = batch or n
    gv = np.concatenate([_evaluate(g, u[i:i + size]) for i in range(0, n, size)])
    # φ(u)/φ(u − c) = exp(−u·c + |c|²/2)
    w = np.exp(-u @ centre + 0.5 * float(np.dot(centre, centre)))
    x = (gv <= 0.0) * w
    pf = float(np.mean(x))
    cov = float(np.std(x, ddof=1) / (math.sqrt(n) * pf)) if pf > 0.0 else math.inf
    return ImportanceResult(pf=pf, cov=cov, centre=centre, u=u, g=gv, weights=w, evaluations=n, seed=int(seed))
