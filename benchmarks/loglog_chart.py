"""Log–log charts of the benchmarks, drawn with matplotlib (the ``[plot]`` extra).

A chart is a row of panels that share their axes' meaning, each with a few series, so that
every curve can be told apart: a series is a cloud of measured points, the curve through some
of them and an optional highlighted point (the default parameters) with a short label.
``draw_loglog_chart`` writes a PNG; the benchmarks call it with their results
(``benchmarks/accuracy.py``, ``benchmarks/scaling.py``; ``--chart-from``/``--chart-only`` redraw
a chart from the saved results without running anything).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Optional, Sequence

# colour-blind-safe palette (Okabe–Ito): a panel has at most four series, so its colours differ
PALETTE = ("#0072B2", "#D55E00", "#009E73", "#CC79A7", "#E69F00", "#56B4E9", "#000000")


@dataclass
class Series:
    """One curve: a cloud of points, the line through some of them, and one highlighted point."""

    label: str
    points: Sequence[tuple[float, float]] = ()
    """Every (x, y) measured, drawn as small dots."""
    line: Sequence[tuple[float, float]] = ()
    """The curve, drawn through the points in the order given."""
    highlight: Optional[tuple[float, float]] = None
    """A point to mark with a large diamond and a text label (e.g. the default parameters)."""
    highlight_text: str = ""
    color: Optional[str] = None
    dashed: bool = False
    """Draw the line dashed (a second quantity of the same family, or another program)."""


@dataclass
class Panel:
    """One panel of a chart: a title and its series (four at most, so each stays readable)."""

    title: str
    series: Sequence[Series] = field(default_factory=list)


def have_matplotlib() -> bool:
    """Whether the charts can be drawn (matplotlib, the [plot] extra, is installed)."""
    import importlib.util

    return importlib.util.find_spec("matplotlib") is not None


#: what a benchmark prints instead of drawing its chart without matplotlib
NO_CHART = "chart not drawn: the benchmark charts need matplotlib (pip install -e '.[plot]')"


def _matplotlib():
    try:
        import matplotlib
    except ImportError as exc:  # pragma: no cover - depends on the environment
        raise ImportError("the benchmark charts need matplotlib: pip install -e '.[plot]'") from exc
    matplotlib.use("Agg")  # files only, no window
    import matplotlib.pyplot as plt

    return plt


def draw_loglog_chart(path, panels: Sequence[Panel], *, title: str, x_label: str, y_label: str,
                      highlight_legend: str = "", notes: Sequence[str] = (), y_floor: Optional[float] = None,
                      columns: Optional[int] = None) -> Path:
    """Write a PNG of log–log panels (`Panel`), ``columns`` per row (default one: the panels
    stacked, so that the chart stays readable at the width of a documentation page), one legend
    per panel. Points at or below ``y_floor`` are drawn hollow on the floor (round-off errors);
    ``notes`` go under the chart. Returns the path."""
    plt = _matplotlib()
    n = len(panels)
    import textwrap

    columns = columns or 1
    rows = math.ceil(n / columns)
    lines = [line for note in notes for line in textwrap.wrap(note, 100 * columns)]
    fig, axes = plt.subplots(rows, columns, figsize=(6.4 * columns, 3.6 * rows + 0.6 + 0.14 * len(lines)),
                             squeeze=False, sharex=True, sharey=True)
    for k, ax in enumerate(axes.flat):
        if k >= n:
            ax.set_visible(False)
            continue
        panel = panels[k]
        for i, s in enumerate(panel.series):
            colour = s.color or PALETTE[i % len(PALETTE)]
            style = "--" if s.dashed else "-"
            pts = [(x, y) for x, y in s.points if x > 0 and y > 0 and math.isfinite(x) and math.isfinite(y)]
            floor = y_floor if y_floor is not None else 0.0
            above = [(x, y) for x, y in pts if y > floor]
            below = [(x, max(y, floor)) for x, y in pts if y <= floor]
            if above:
                ax.scatter(*zip(*above), s=10, color=colour, alpha=0.45, linewidths=0)
            if below:
                ax.scatter(*zip(*below), s=18, facecolors="none", edgecolors=colour, alpha=0.7)
            line = [(x, max(y, floor) if y_floor is not None else y) for x, y in s.line if x > 0 and y > 0]
            if line:
                ax.plot(*zip(*line), style, color=colour, lw=1.8, label=s.label)
            elif pts:
                ax.plot([], [], style, color=colour, lw=1.8, label=s.label)
            if s.highlight is not None:
                hx, hy = s.highlight
                hy = max(hy, y_floor) if y_floor is not None else hy
                ax.scatter([hx], [hy], marker="D", s=60, color=colour, edgecolors="black", zorder=5)
                if s.highlight_text:
                    ax.annotate(s.highlight_text, (hx, hy), xytext=(6, 6), textcoords="offset points", fontsize=8)
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_title(panel.title, fontsize=10)
        ax.grid(True, which="major", alpha=0.3)
        ax.grid(True, which="minor", alpha=0.1)
        if y_floor is not None:
            ax.axhline(y_floor, color="grey", lw=0.8, ls=":")
        handles, labels = ax.get_legend_handles_labels()
        if highlight_legend and any(s.highlight is not None for s in panel.series):
            from matplotlib.lines import Line2D

            handles.append(Line2D([], [], marker="D", ls="none", color="grey", markeredgecolor="black"))
            labels.append(highlight_legend)
        ax.legend(handles, labels, fontsize=8, loc="best", framealpha=0.85)
        if k % columns == 0:
            ax.set_ylabel(y_label)
        if k >= n - columns:
            ax.set_xlabel(x_label)
            ax.tick_params(labelbottom=True)
    fig.suptitle(title, fontsize=12)
    bottom = 0.0
    if lines:
        fig.text(0.01, 0.005, "\n".join(lines), fontsize=8, va="bottom", ha="left", color="#333333")
        bottom = (0.14 * len(lines) + 0.15) / fig.get_figheight()
    fig.tight_layout(rect=(0, bottom, 1, 1 - 0.4 / fig.get_figheight()))
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
