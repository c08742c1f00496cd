"""The inputs of a probabilistic study (docs/kgm/probabilistic.md): the sampled values of its
uncertain variables, the per-sample seeds, and the variables file of ``kgm probabilistic``.

Sampling: ``"monte-carlo"`` (independent uniform numbers) or ``"latin-hypercube"`` (one sample
in each of ``n`` equal-probability strata of every variable, `scipy.stats.qmc.LatinHypercube`),
mapped through each variable's inverse distribution function (``ppf``). Correlated variables
(e.g. friction and cohesion) are coupled by a Gaussian copula (the Nataf model): the uniform
numbers become standard normal ones, are mixed by the Cholesky factor of the correlation matrix
and mapped back (the correlation given is that of the normal scores). All samples are drawn
before any work from the study's seed, so a study's table does not depend on the number of
workers or on the order in which samples complete.
"""

from __future__ import annotations

import inspect
import math
from typing import Mapping, Optional

import numpy as np

from ..kinds import DRAWN_SAMPLINGS, SAMPLINGS, Sampling

#: names a variable cannot take: the other columns of a study's table
RESERVED = ("seed", "index", "fs", "failed", "critical", "lost")


def sample_variables(variables: Mapping, n: int, *, sampling: str = Sampling.MONTE_CARLO, seed: int = 0,
                     correlation: Optional[Mapping] = None) -> dict:
    """The ``n`` samples of a study: name -> array (n,). ``variables`` maps names to frozen
    `scipy.stats` distributions (anything with ``ppf``) or to constants; ``correlation`` maps
    pairs of names to the correlation of their normal scores (module docstring)."""
    _check_sampling(variables, n, sampling, correlation)
    names = [k for k, v in variables.items() if hasattr(v, "ppf")]
    rng = np.random.default_rng(seed)
    d = len(names)
    if d == 0:
        u = np.zeros((n, 0))
    elif sampling == Sampling.MONTE_CARLO:
        u = rng.random((n, d))
    else:
        from scipy.stats import qmc

        u = qmc.LatinHypercube(d=d, seed=rng).random(n)
    # ppf(0) is −inf for unbounded distributions: keep u inside (0, 1)
    u = np.clip(u, np.finfo(float).tiny, 1.0 - np.finfo(float).eps)
    if correlation:
        from scipy.stats import norm

        c = _correlation_matrix(names, correlation)
        u = norm.cdf(norm.ppf(u) @ np.linalg.cholesky(c).T)
    out = {}
    for k, v in variables.items():
        if hasattr(v, "ppf"):
            out[k] = np.asarray(v.ppf(u[:, names.index(k)]), dtype=float)
        else:
            out[k] = np.full(n, v)
    return out


def _correlation_matrix(names: list, correlation: Mapping) -> np.ndarray:
    c = np.eye(len(names))
    for pair, rho in correlation.items():
        if not (isinstance(pair, tuple) and len(pair) == 2 and all(p in names for p in pair) and pair[0] != pair[1]):
            raise ValueError(f"correlation key {pair!r} must be a pair of two different sampled variables "
                             f"(distributions) among {names}")
        if not (isinstance(rho, (int, float)) and -1.0 < rho < 1.0):
            raise ValueError(f"correlation of {pair} must be a number in (-1, 1), got {rho!r}")
        i, j = names.index(pair[0]), names.index(pair[1])
        c[i, j] = c[j, i] = float(rho)
    if np.min(np.linalg.eigvalsh(c)) <= 0.0:
        raise ValueError("the correlation matrix of the sampled variables is not positive definite")
    return c


def _check_sampling(variables, n, sampling, correlation) -> None:
    if not isinstance(variables, Mapping) or not variables:
        raise ValueError("variables must be a non-empty mapping of names to scipy.stats distributions "
                         "(e.g. {'friction': scipy.stats.norm(30, 3)}) or constants")
    for k, v in variables.items():
        if not isinstance(k, str) or not k.isidentifier():
            raise ValueError(f"variable name {k!r} must be a valid keyword argument name of build()")
        if k in RESERVED:
            raise ValueError(f"variable name {k!r} is reserved (a column of the study table)")
        if not hasattr(v, "ppf") and not isinstance(v, (int, float)):
            raise ValueError(f"variable {k!r} must be a frozen scipy.stats distribution (with ppf) or a "
                             f"number, got {type(v).__name__}")
    if not isinstance(n, int) or isinstance(n, bool) or n < 1:
        raise ValueError(f"n (number of samples) must be an integer >= 1, got {n!r}")
    if sampling not in SAMPLINGS:
        raise ValueError(f"sampling must be one of {SAMPLINGS}, got {sampling!r}")
    if sampling not in DRAWN_SAMPLINGS:
        raise ValueError(f"sample_variables draws {', '.join(map(repr, map(str, DRAWN_SAMPLINGS)))} samples; "
                         f"{sampling!r} samples are drawn by their estimator as it goes (kgm.probabilistic, "
                         "docs/kgm/reliability.md)")
    if correlation is not None and not isinstance(correlation, Mapping):
        raise ValueError("correlation must be a mapping {(name1, name2): rho}")


def sample_seeds(seed: int, n: int) -> np.ndarray:
    """The per-sample seeds of a study (given to ``build(seed=...)`` when it takes one: a new
    realisation of the joint sets per sample), independent of the sampled values."""
    return np.random.SeedSequence([int(seed), 0x6B676D]).generate_state(n, dtype=np.uint32).astype(np.int64)



# ---------------------------------------------------------------------- variables file
def variables_from_mapping(spec: Mapping) -> tuple[dict, dict]:
    """Variables and correlations from a plain mapping (a TOML file's tables), e.g.::

        [friction]                     # degrees
        distribution = "normal"        # normal | lognormal | truncated-normal | uniform | triangular | constant
        mean = 30.0
        sd = 3.0
        [cohesion]                     # Pa
        distribution = "truncated-normal"
        mean = 20e3
        sd = 5e3
        min = 0.0
        [correlation]
        "friction,cohesion" = -0.5

    lognormal takes the variable's own mean and sd; uniform min and max; triangular min, mode
    and max; truncated-normal mean, sd and optional min and max; constant value. Returns
    (variables, correlation) for `probabilistic`."""
    import scipy.stats as st

    variables, correlation = {}, {}
    for name, v in spec.items():
        if name == "correlation":
            for pair, rho in dict(v).items():
                a, _, b = str(pair).partition(",")
                correlation[(a.strip(), b.strip())] = rho
            continue
        if not isinstance(v, Mapping) or "distribution" not in v:
            raise ValueError(f"variable {name!r}: a table with 'distribution' and its parameters, got {v!r}")
        kind = v["distribution"]
        need = {"normal": ("mean", "sd"), "lognormal": ("mean", "sd"), "truncated-normal": ("mean", "sd"),
                "uniform": ("min", "max"), "triangular": ("min", "mode", "max"), "constant": ("value",)}
        if kind not in need:
            raise ValueError(f"variable {name!r}: distribution must be one of {sorted(need)}, got {kind!r}")
        missing = [k for k in need[kind] if k not in v]
        if missing:
            raise ValueError(f"variable {name!r} ({kind}) needs {', '.join(missing)}")
        if kind in ("normal", "lognormal", "truncated-normal") and not v["sd"] > 0:
            raise ValueError(f"variable {name!r}: sd must be > 0, got {v['sd']!r}")
        if kind == "normal":
            variables[name] = st.norm(v["mean"], v["sd"])
        elif kind == "lognormal":
            if not v["mean"] > 0:
                raise ValueError(f"variable {name!r}: a lognormal mean must be > 0, got {v['mean']!r}")
            s2 = math.log1p((v["sd"] / v["mean"]) ** 2)
            variables[name] = st.lognorm(math.sqrt(s2), scale=v["mean"] / math.sqrt(1.0 + (v["sd"] / v["mean"]) ** 2))
        elif kind == "truncated-normal":
            lo, hi = v.get("min", -math.inf), v.get("max", math.inf)
            variables[name] = st.truncnorm((lo - v["mean"]) / v["sd"], (hi - v["mean"]) / v["sd"],
                                           loc=v["mean"], scale=v["sd"])
        elif kind == "uniform":
            if not v["max"] > v["min"]:
                raise ValueError(f"variable {name!r}: max must be > min")
            variables[name] = st.uniform(v["min"], v["max"] - v["min"])
        elif kind == "triangular":
            lo, mode, hi = v["min"], v["mode"], v["max"]
            if not lo <= mode <= hi or not hi > lo:
                raise ValueError(f"variable {name!r}: needs min <= mode <= max and max > min")
            variables[name] = st.triang((mode - lo) / (hi - lo), loc=lo, scale=hi - lo)
        else:
            variables[name] = float(v["value"])
    return variables, correlation


def read_variables(path) -> tuple[dict, dict]:
    """`variables_from_mapping` of a TOML file."""
    from ddatai.io.tomlfile import read_toml

    return variables_from_mapping(read_toml(path, "variables file"))


def _scalar(v):
    return float(v) if isinstance(v, (np.floating, float)) else v.item() if isinstance(v, np.generic) else v


def _check_build(build, variables: Mapping, geometry_seed: Optional[bool]) -> bool:
    """Whether to pass ``seed=``; raises if ``build`` does not take a variable's name."""
    fn = build.resolve() if hasattr(build, "resolve") else build
    try:
        sig = inspect.signature(fn)
    except (TypeError, ValueError):
        return bool(geometry_seed)
    params = sig.parameters
    var_kw = any(p.kind is inspect.Parameter.VAR_KEYWORD for p in params.values())
    for k in variables:
        if k not in params and not var_kw:
            raise ValueError(f"variable {k!r} is not a parameter of build{sig} ({getattr(fn, '__name__', fn)})")
    takes_seed = "seed" in params or var_kw
    if geometry_seed and not takes_seed:
        raise ValueError(f"geometry_seed=True but build{sig} has no 'seed' parameter")
    return takes_seed and "seed" in params if geometry_seed is None else bool(geometry_seed)
