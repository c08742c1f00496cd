"""A log–log scatter/line chart drawn with Pillow alone.

matplotlib is not a dependency of the project; Pillow already is (through imageio), so the
benchmarks draw their charts with ``PIL.ImageDraw``: axes, decade ticks with minor ticks,
point clouds, polylines, highlighted points with labels, and a legend.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Optional, Sequence

# colour-blind-safe palette (Okabe–Ito), then darker and lighter companions: twelve distinct
# colours, so that no two series of a chart share one
PALETTE = ((0, 114, 178), (213, 94, 0), (0, 158, 115), (204, 121, 167), (230, 159, 0),
           (86, 180, 233), (120, 80, 40), (0, 0, 0), (150, 150, 150), (128, 0, 128),
           (0, 90, 60), (190, 30, 45))


@dataclass
class Series:
    """One curve: a cloud of points, the line through some of them, and one highlighted point."""

    label: str
    points: Sequence[tuple[float, float]] = ()
    """Every (x, y) measured, drawn as small dots."""
    line: Sequence[tuple[float, float]] = ()
    """The curve, drawn as a polyline through the points in the order given."""
    highlight: Optional[tuple[float, float]] = None
    """A point to mark with a large diamond and a text label (e.g. the default parameters)."""
    highlight_text: str = ""
    color: Optional[tuple[int, int, int]] = None


def _font(size: int):
    from PIL import ImageFont

    try:
        return ImageFont.load_default(size=size)  # FreeType build of Pillow >= 10.1
    except (TypeError, OSError, ValueError):  # older Pillow or no FreeType: the bitmap font
        return ImageFont.load_default()


def _wrap(text: str, width: int) -> list[str]:
    """``text`` in lines of at most ``width`` characters, broken at spaces."""
    import textwrap

    return textwrap.wrap(text, width) or [""]


def _decades(lo: float, hi: float) -> tuple[int, int]:
    return math.floor(math.log10(lo)), math.ceil(math.log10(hi))


def _decade_label(k: int) -> str:
    return f"1e{k}"


def draw_loglog_chart(path, series: Sequence[Series], *, title: str, x_label: str, y_label: str,
                      highlight_legend: str = "", notes: Sequence[str] = (),
                      size: tuple[int, int] = (1200, 800), y_floor: float = 1e-16) -> None:
    """Write a PNG log–log chart of ``series`` to ``path``.

    y values at or below ``y_floor`` (round-off, exact zero) are drawn on the floor with a
    hollow marker; non-finite points are skipped. The axes span whole decades around the data.
    """
    from PIL import Image, ImageDraw

    width, height = size
    img = Image.new("RGB", size, "white")
    d = ImageDraw.Draw(img)
    f_title, f_axis, f_tick, f_small = _font(22), _font(17), _font(14), _font(13)
    # the legend column is as wide as its longest line (labels wrap at 34 characters)
    legend_lines = [_wrap(s.label, 34) for s in series]
    longest = max([d.textlength(t, font=f_tick) for lines in legend_lines for t in lines] +
                  [d.textlength(t, font=f_small) for t in notes] + [200.0])
    left, right, top, bottom = 110, int(longest) + 80, 60, 90

    def finite(p):
        return math.isfinite(p[0]) and math.isfinite(p[1]) and p[0] > 0

    xs, ys = [], []
    for s in series:
        for p in [*s.points, *s.line, *([s.highlight] if s.highlight else [])]:
            if finite(p):
                xs.append(p[0])
                ys.append(max(p[1], y_floor))
    if not xs:
        xs, ys = [1e-3, 1.0], [y_floor, 1.0]
    x0, x1 = _decades(min(xs), max(xs))
    y0, y1 = _decades(min(ys), max(ys))
    x1, y1 = max(x1, x0 + 1), max(y1, y0 + 1)
    pw, ph = width - left - right, height - top - bottom

    def to_px(x: float, y: float) -> tuple[float, float]:
        y = max(y, y_floor)
        u = (math.log10(x) - x0) / (x1 - x0)
        v = (math.log10(y) - y0) / (y1 - y0)
        return left + u * pw, top + (1 - v) * ph

    # grid and ticks
    grid, minor_grid, ink = (205, 205, 205), (236, 236, 236), (40, 40, 40)
    for k in range(x0, x1 + 1):
        for m in range(1, 10) if k < x1 else (1,):
            px, _ = to_px(m * 10.0 ** k, 10.0 ** y0)
            d.line([(px, top), (px, top + ph)], fill=grid if m == 1 else minor_grid)
            d.line([(px, top + ph), (px, top + ph + (8 if m == 1 else 4))], fill=ink)
        px, _ = to_px(10.0 ** k, 10.0 ** y0)
        text = _decade_label(k)
        d.text((px - d.textlength(text, font=f_tick) / 2, top + ph + 12), text, fill=ink, font=f_tick)
    ystep = max(1, math.ceil((y1 - y0) / 16))  # at most ~16 labelled decades
    for k in range(y0, y1 + 1):
        for m in range(1, 10) if (k < y1 and y1 - y0 <= 8) else (1,):
            _, py = to_px(10.0 ** x0, m * 10.0 ** k)
            d.line([(left, py), (left + pw, py)], fill=grid if m == 1 else minor_grid)
            d.line([(left - (8 if m == 1 else 4), py), (left, py)], fill=ink)
        if (k - y0) % ystep == 0:
            _, py = to_px(10.0 ** x0, 10.0 ** k)
            text = _decade_label(k)
            d.text((left - 12 - d.textlength(text, font=f_tick), py - 8), text, fill=ink, font=f_tick)
    d.rectangle([left, top, left + pw, top + ph], outline=ink, width=2)
    d.text((left + pw / 2 - d.textlength(x_label, font=f_axis) / 2, top + ph + 40), x_label,
           fill=ink, font=f_axis)
    # vertical y label: draw on a small image and rotate it
    lbl_w = int(d.textlength(y_label, font=f_axis)) + 4
    lbl = Image.new("RGB", (lbl_w, 24), "white")
    ImageDraw.Draw(lbl).text((2, 2), y_label, fill=ink, font=f_axis)
    lbl = lbl.rotate(90, expand=True)
    img.paste(lbl, (12, int(top + ph / 2 - lbl_w / 2)))
    d.text((left, 18), title, fill=ink, font=f_title)

    # highlight labels: each at the nearest free place on rings around its marker (free of the
    # labels placed before and of every highlight marker), joined to it by a thin leader line
    markers = [to_px(*s.highlight) for s in series if s.highlight and finite(s.highlight)]
    placed: list[tuple[float, float, float, float]] = [(mx - 11, my - 11, mx + 11, my + 11) for mx, my in markers]

    def free_spot(px: float, py: float, text: str, r: float) -> tuple[float, float, bool]:
        w, h = d.textlength(text, font=f_small), 15
        for radius in (r + 4, r + 22, r + 44, r + 70, r + 100):
            for angle in (-30, 30, -150, 150, -90, 90, 0, 180, -60, 60, -120, 120):
                ax, ay = math.cos(math.radians(angle)), math.sin(math.radians(angle))
                x = px + radius * ax - (w if ax < -1e-9 else 0 if ax > 1e-9 else w / 2)
                y = py + radius * ay - (h if ay < -1e-9 else 0 if ay > 1e-9 else h / 2)
                box = (x - 1, y - 1, x + w + 1, y + h + 1)
                inside = left <= box[0] and box[2] <= left + pw and top <= box[1] and box[3] <= top + ph
                if inside and all(box[2] < b[0] or box[0] > b[2] or box[3] < b[1] or box[1] > b[3] for b in placed):
                    placed.append(box)
                    return x, y, radius > r + 4
        x, y = px + r + 4, py - h - 2
        placed.append((x, y, x + w, y + h))
        return x, y, False

    for i, s in enumerate(series):
        color = s.color or PALETTE[i % len(PALETTE)]
        pts = [p for p in s.line if finite(p)]
        if len(pts) > 1:
            d.line([to_px(*p) for p in pts], fill=color, width=3, joint="curve")
        for p in s.points:
            if not finite(p):
                continue
            px, py = to_px(*p)
            r = 4
            if p[1] <= y_floor:
                d.ellipse([px - r, py - r, px + r, py + r], outline=color, width=2)
            else:
                d.ellipse([px - r, py - r, px + r, py + r], fill=color)
    # highlighted points and their labels last, on top of every curve
    for i, s in enumerate(series):
        color = s.color or PALETTE[i % len(PALETTE)]
        if s.highlight and finite(s.highlight):
            px, py = to_px(*s.highlight)
            r = 10
            d.polygon([(px, py - r), (px + r, py), (px, py + r), (px - r, py)], fill=color, outline=ink)
            d.polygon([(px, py - r - 1), (px + r + 1, py), (px, py + r + 1), (px - r - 1, py)], outline=ink)
    for i, s in enumerate(series):
        color = s.color or PALETTE[i % len(PALETTE)]
        if s.highlight and finite(s.highlight) and s.highlight_text:
            px, py = to_px(*s.highlight)
            x, y, far = free_spot(px, py, s.highlight_text, 10)
            w = d.textlength(s.highlight_text, font=f_small)
            if far:  # leader line from the marker's edge to the nearest point of the label
                qx, qy = min(max(px, x), x + w), min(max(py, y), y + 15)
                dist = math.hypot(qx - px, qy - py) or 1.0
                d.line([(px + 11 * (qx - px) / dist, py + 11 * (qy - py) / dist), (qx, qy)], fill=color, width=1)
            d.rectangle([x - 1, y + 1, x + w + 1, y + 15], fill="white")
            d.text((x, y), s.highlight_text, fill=color, font=f_small)

    # legend
    lx, ly = left + pw + 24, top + 4
    for i, s in enumerate(series):
        color = s.color or PALETTE[i % len(PALETTE)]
        d.line([(lx, ly + 9), (lx + 30, ly + 9)], fill=color, width=3)
        d.ellipse([lx + 11, ly + 5, lx + 19, ly + 13], fill=color)
        for k, text in enumerate(legend_lines[i]):
            d.text((lx + 40, ly + 18 * k), text, fill=ink, font=f_tick)
        ly += 26 + 18 * (len(legend_lines[i]) - 1)
    if highlight_legend:
        ly += 6
        px, py, r = lx + 15, ly + 9, 9
        d.polygon([(px, py - r), (px + r, py), (px, py + r), (px - r, py)], fill=(255, 255, 255), outline=ink)
        d.text((lx + 40, ly), highlight_legend, fill=ink, font=f_tick)
        ly += 26
    ly += 10
    for line in notes:
        d.text((lx, ly), line, fill=(90, 90, 90), font=f_small)
        ly += 19
    img.save(path)
