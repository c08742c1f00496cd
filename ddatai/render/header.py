"""The header of a frame: its text size and font, and where the time stamp, the title and the
colour bar go (`layout`, `Layout`) so that no two of them overlap at any picture size."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Optional


def default_font(size: int):
    """Pillow's default font at ``size`` pixels (its FreeType font; the fixed 11-pixel bitmap
    font on Pillow builds without FreeType)."""
    from PIL import ImageFont

    try:
        return ImageFont.load_default(size=size)
    except (TypeError, ImportError, OSError):  # Pillow < 10.1 or no FreeType
        return ImageFont.load_default()


def text_size(size: tuple[int, int]) -> int:
    """Text height for a picture of ``size`` [px]: 10 px up to 480 px high, then growing with
    the height (15 px at 720, 22 at 1080), so that text stays readable on large frames."""
    return max(10, int(round(size[1] / 48)))


Box = tuple[float, float, float, float]  # (left, top, right, bottom) [px]


def _overlap(a: Box, b: Box) -> bool:
    return a[0] < b[2] and b[0] < a[2] and a[1] < b[3] and b[1] < a[3]


@dataclass(frozen=True, kw_only=True)
class Layout:
    """Where the header of a frame goes: the time stamp (top left), the colour bar with its
    label and end values (top right), the title between them or, when it does not fit there,
    on a line of its own below them (shortened with "…" when even that line is too narrow).
    Boxes are (left, top, right, bottom) in pixels; no two of them overlap, at any size
    (``tests/test_render.py`` measures them on rendered frames at 320×240 and 1280×720)."""

    time: Box
    """Box of the time stamp (its widest text)."""
    title: Optional[Box]
    """Box of the title (None without one)."""
    title_text: str
    """The title as drawn (shortened to fit)."""
    bar: Optional[Box]
    """The colour bar itself (None when colouring by group labels)."""
    bar_label: Optional[Box]
    """The colour bar's label (the quantity) left of the bar."""
    bar_values: Optional[Box]
    """The colour bar's end values, under the bar."""
    header: int
    """Height of the header [px]: the drawing area and the legend start below it."""
    pad: int
    """Margin [px]."""

    def boxes(self) -> dict:
        """The named boxes that are drawn."""
        out = {"time": self.time, "title": self.title, "colour bar": self.bar,
               "colour bar label": self.bar_label, "colour bar values": self.bar_values}
        return {k: v for k, v in out.items() if v is not None}


def _text_box(font, xy, text: str) -> Box:
    left, top, right, bottom = font.getbbox(text)
    return (xy[0] + left, xy[1] + top, xy[0] + right, xy[1] + bottom)


def layout(size: tuple[int, int], font, *, time_text: str, title: Optional[str],
           bar_label: Optional[str], bar_value: Optional[str]) -> Layout:
    """The header of a frame of ``size`` (`Layout`); ``time_text`` is the widest time stamp of
    the animation, ``bar_label``/``bar_value`` the colour bar's quantity and top value (None:
    no colour bar)."""
    width, height = size
    pad = max(6, int(round(height / 80)))
    text_h = font.getbbox("Ag")[3]
    time_box = _text_box(font, (pad, pad), time_text)
    bottoms = [time_box[3]]
    bar = label_box = values_box = None
    block_left = width - pad  # left edge of the colour bar's block
    if bar_label is not None:
        bar_w = int(min(max(0.18 * width, 50), 240))
        bar_h = max(8, int(round(0.8 * text_h)))
        x1 = width - pad - bar_w
        bar = (x1, pad, width - pad, pad + bar_h)
        lw = font.getlength(bar_label)
        label_box = _text_box(font, (x1 - 4 - lw, pad + 0.5 * bar_h - 0.5 * text_h), bar_label)
        vy = pad + bar_h + 2
        zero, top = _text_box(font, (x1, vy), "0"), _text_box(font, (width - pad - font.getlength(bar_value), vy),
                                                                   bar_value)
        values_box = (min(zero[0], top[0]), min(zero[1], top[1]), max(zero[2], top[2]), max(zero[3], top[3]))
        block_left = min(label_box[0], values_box[0])
        bottoms += [bar[3], label_box[3], values_box[3]]
    title_box, shown = None, title or ""
    if title:
        tw = font.getlength(title)
        gap_lo, gap_hi = time_box[2] + 2 * pad, block_left - 2 * pad
        if tw <= gap_hi - gap_lo:  # between the time and the colour bar: centred if it can be
            x = min(max(0.5 * (width - tw), gap_lo), gap_hi - tw)
            title_box = _text_box(font, (x, pad), title)
        else:  # a line of its own
            room = width - 2 * pad
            while shown and font.getlength(shown) > room:
                shown = shown[:-2] + "…" if len(shown) > 1 else ""
            y = max(bottoms) + max(2, pad // 2)
            title_box = _text_box(font, (0.5 * (width - font.getlength(shown)), y), shown)
        bottoms.append(title_box[3])
    return Layout(time=time_box, title=title_box, title_text=shown, bar=bar, bar_label=label_box,
                  bar_values=values_box, header=int(math.ceil(max(bottoms))) + pad, pad=pad)
