"""Pictures of a study of a small probability of failure (matplotlib, the optional
``ddatai[plot]`` extra; docs/kgm/reliability.md):

* `plot_levels` – subset simulation's levels, each level's samples over the two variables that
  drive failure most, with the limit state FS = 1 drawn through them where it is cheap (a
  limit-equilibrium study evaluates a grid of samples in this process); importance sampling's
  samples, failed or not, and the design point; with one variable, FS against it;
* `plot_convergence` – the estimate of P_f against the evaluations it cost.
"""

from __future__ import annotations

from pathlib import Path
from typing import Optional, Sequence

import numpy as np

from ..kinds import RARE_SAMPLINGS, Sampling


def _pyplot(path):
    try:
        import matplotlib

        if path is not None:
            matplotlib.use("Agg")  # offscreen: no window for a file
        import matplotlib.pyplot as plt
    except ImportError:
        raise ImportError("plots need matplotlib, an optional extra: pip install 'ddatai[plot]'") from None
    return plt


def _save(fig, plt, path):
    if path is not None:
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        fig.savefig(path, dpi=100)
        plt.close(fig)
    return fig


def _rare(study, what: str) -> None:
    if study.sampling not in RARE_SAMPLINGS or study.estimate is None:
        raise ValueError(f"{what} draws a study of sampling='subset' or 'importance' (complete), "
                         f"not {study.sampling!r}")


def important_variables(study) -> list:
    """The sampled variables, those that drive failure most first: by ‖α‖ of the design point
    (importance sampling), or by how far the failed samples of the last level lie from the
    median along each normal score (subset simulation)."""
    names = [k for k in study.variables if np.ptp(study.table[k]) > 0.0] or list(study.variables)
    if study.design_point is not None and study.design_point.alpha:
        score = {k: abs(a) for k, a in study.design_point.alpha.items()}
    else:
        last = study.levels[-1]
        failed = last.fs <= 1.0
        u = last.u[failed] if np.any(failed) else last.u
        score = {k: abs(float(np.mean(u[:, j]))) for j, k in enumerate(names[:u.shape[1]])}
    return sorted(names, key=lambda k: -score.get(k, 0.0))


def plot_levels(study, path=None, *, variables: Optional[Sequence[str]] = None, contour: bool = True,
                grid: int = 25):
    """The samples of a subset or importance study over two variables (module docstring);
    ``variables``: which two (default: `important_variables`); ``contour``: draw FS = 1 on a
    ``grid`` × ``grid`` of samples (the other variables at the design point, or at the median
    of the last level's failed samples) where the study can evaluate them here
    (`kgm.Study.limit_state`). Saved to ``path`` when given; returns the Figure."""
    _rare(study, "plot_levels")
    plt = _pyplot(path)
    names = list(variables) if variables else important_variables(study)[:2]
    for k in names:
        if k not in study.variables:
            raise ValueError(f"plot_levels: {k!r} is not a variable of the study ({', '.join(study.variables)})")
    fig, ax = plt.subplots(figsize=(7, 5.2), constrained_layout=True)
    one = len(names) == 1
    groups = _sample_groups(study)
    for label, values, fs, colour in groups:
        ax.plot(values[names[0]], fs if one else values[names[1]], ".", ms=3, alpha=0.6, color=colour, label=label)
    if study.design_point is not None:
        dp = study.design_point
        ax.plot(dp.values[names[0]], dp.fs if one else dp.values[names[1]], "k*", ms=14, label="design point")
    if contour and study.limit_state is not None:
        _draw_limit_state(ax, study, names, grid, one)
    ax.set_xlabel(names[0])
    ax.set_ylabel("FS" if one else names[1])
    if one:
        ax.axhline(1.0, color="k", lw=1.2)
        for lv in study.levels[:-1]:
            ax.axhline(lv.fs_threshold, color="grey", lw=0.8, ls=":")
    ax.grid(True, alpha=0.3)
    legend = ax.legend(loc="best", fontsize=8)
    for handle in getattr(legend, "legend_handles", None) or getattr(legend, "legendHandles", []):
        if hasattr(handle, "set_markersize"):
            handle.set_markersize(8)
    ax.set_title(f"{study.sampling} ({study.method}): P_f = {study.pf:.3g}, c.o.v. {study.pf_cov:.2f}, "
                 f"{study.evaluations} evaluations", fontsize=10)
    return _save(fig, plt, path)


def _sample_groups(study) -> list:
    """(label, values, fs, colour) of each group of samples to draw."""
    import matplotlib

    if study.sampling == Sampling.SUBSET:
        cmap = matplotlib.colormaps["viridis"]
        out = []
        for j, lv in enumerate(study.levels):
            what = "Monte Carlo" if j == 0 else f"FS ≤ {study.levels[j - 1].fs_threshold:.3f}"
            out.append((f"level {j}: {what}", lv.values, lv.fs, cmap(j / max(1, len(study.levels) - 1))))
        return out
    t = study.table
    failed = t["failed"]
    values = {k: t[k] for k in study.variables}
    return [("importance samples, stable", {k: v[~failed] for k, v in values.items()}, t["fs"][~failed], "tab:blue"),
            ("importance samples, failed", {k: v[failed] for k, v in values.items()}, t["fs"][failed], "tab:red")]


def _reference(study) -> dict:
    """The values of the variables not drawn: the design point, or the median of the last
    level's failed samples."""
    if study.design_point is not None and study.design_point.values:
        return dict(study.design_point.values)
    last = study.levels[-1]
    failed = last.fs <= 1.0
    return {k: float(np.median(v[failed] if np.any(failed) else v)) for k, v in last.values.items()}


def _draw_limit_state(ax, study, names, grid: int, one: bool) -> None:
    ref = _reference(study)
    lo = {k: float(np.min(study.table[k])) for k in names}
    hi = {k: float(np.max(study.table[k])) for k in names}
    if one:
        x = np.linspace(lo[names[0]], hi[names[0]], 4 * grid)
        values = {k: np.full(len(x), v) for k, v in ref.items()}
        values[names[0]] = x
        ax.plot(x, study.limit_state(values), "k-", lw=1, label="FS of the variable")
        return
    x, y = np.meshgrid(np.linspace(lo[names[0]], hi[names[0]], grid), np.linspace(lo[names[1]], hi[names[1]], grid))
    values = {k: np.full(x.size, v) for k, v in ref.items()}
    values[names[0]], values[names[1]] = x.ravel(), y.ravel()
    fs = np.asarray(study.limit_state(values), dtype=float).reshape(x.shape)
    if np.nanmin(fs) < 1.0 < np.nanmax(fs):
        ax.contour(x, y, fs, levels=[1.0], colors="k", linewidths=1.2)
        ax.plot([], [], "k-", lw=1.2, label="FS = 1" + ("" if len(ref) <= 2 else " (others at the reference)"))


def plot_convergence(study, path=None):
    """P_f estimate against evaluations: after each level (subset simulation, with each
    level's 95 % interval from its c.o.v.) or the running mean of the importance samples
    (with ±2 standard errors), the final estimate dashed. Saved to ``path`` when given;
    returns the Figure."""
    _rare(study, "plot_convergence")
    plt = _pyplot(path)
    fig, ax = plt.subplots(figsize=(7, 4.5), constrained_layout=True)
    est = study.estimate
    if study.sampling == Sampling.SUBSET:
        evals, values = est.history()
        domains = np.cumprod([lv.probability for lv in est.levels])
        covs = np.sqrt(np.cumsum([lv.cov ** 2 for lv in est.levels]))
        ax.plot(evals, domains, "s-", color="grey", label="P(FS ≤ the level's threshold) after each level")
        for lv, x, y in zip(study.levels, evals, domains):
            ax.annotate(f"FS ≤ {lv.fs_threshold:.3f}", (x, y), textcoords="offset points", xytext=(6, 4), fontsize=7)
        # the estimate at level j: the product of the levels before times the fraction q of
        # level j's samples with FS < 1, whose c.o.v. (with its chains' γ) adds to theirs
        from .reliability import chain_gamma

        before = np.concatenate([[0.0], covs[:-1] ** 2])
        for j, lv in enumerate(est.levels):
            q = float(np.mean(lv.g <= 0.0))
            if 0.0 < q < 1.0:
                gamma = chain_gamma((lv.g <= 0.0).reshape(lv.chains, -1), q) if lv.chains else 0.0
                before[j] += (1.0 - q) / (len(lv.g) * q) * (1.0 + gamma)
        covs = np.sqrt(before)
        shown = values > 0
        band = np.exp(2 * covs[shown])
        ax.errorbar(evals[shown], values[shown], yerr=[values[shown] * (1 - 1 / band), values[shown] * (band - 1)],
                    fmt="o", capsize=3, label="P_f estimate (95 %) from the level's samples")
    else:
        k, running = est.history()
        x = est.weights * (est.g <= 0.0)
        n = np.arange(1, len(x) + 1)
        mean_sq = np.cumsum(x * x) / n
        se = np.sqrt(np.maximum(mean_sq - running ** 2, 0.0) / np.maximum(n - 1, 1))
        offset = study.evaluations - len(x)  # FORM's evaluations first
        shown = running > 0
        ax.plot((k + offset)[shown], running[shown], "-", label="importance sampling, running mean")
        ax.fill_between((k + offset)[shown], np.maximum(running - 2 * se, running / 10)[shown],
                        (running + 2 * se)[shown], alpha=0.25, label="±2 standard errors")
        ax.axvline(offset, color="grey", lw=0.8, ls=":", label=f"FORM: {offset} evaluations")
        if study.design_point is not None:
            ax.axhline(study.design_point.pf, color="tab:green", lw=1, ls="-.",
                       label=f"FORM Φ(−β) = {study.design_point.pf:.3g}")
    if study.pf > 0:
        ax.axhline(study.pf, color="k", ls="--", lw=1, label=f"P_f = {study.pf:.3g} (c.o.v. {study.pf_cov:.2f})")
        ax.set_yscale("log")
    ax.set_xlabel("evaluations of the limit state")
    ax.set_ylabel("P_f estimate")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(loc="best", fontsize=8)
    ax.set_title(f"{study.sampling} ({study.method}), seed {study.seed}", fontsize=10)
    return _save(fig, plt, path)
