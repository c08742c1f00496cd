"""Where the model goes on the picture: the world -> pixel transform of an animation (`View`),
fixed for all its frames, and the length of the scale bar."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence

import numpy as np

from ..results import Results


@dataclass(frozen=True, kw_only=True)
class View:
    """World -> pixel transform shared by all frames of an animation."""

    x0: float
    """World x at the left edge of the drawing area [m]."""
    y0: float
    """World y at the bottom edge of the drawing area [m]."""
    scale: float
    """Pixels per metre."""
    height: int
    """Image height [px]."""
    left: int
    """Left margin [px]."""
    bottom: int
    """Bottom margin [px]."""

    def pixels(self, xy: np.ndarray) -> np.ndarray:
        px = self.left + (xy[..., 0] - self.x0) * self.scale
        py = self.height - self.bottom - (xy[..., 1] - self.y0) * self.scale
        return np.stack([px, py], axis=-1)


def fit_view(results: Results, frames: Sequence[int], size: tuple[int, int], *, top: int = 26,
          bottom: int = 30, side: int = 12) -> View:
    """The fixed view of an animation: every block of every drawn frame inside the drawing
    area (below the header of ``top`` pixels, above the scale bar's ``bottom``), equal scales."""
    width, height = size
    # frame by frame: no copy of every drawn frame's vertices at once
    lo, hi = np.full(2, np.inf), np.full(2, -np.inf)
    for f in frames:
        xy = results.vertices[f]
        lo, hi = np.minimum(lo, xy.min(axis=0)), np.maximum(hi, xy.max(axis=0))
    span = np.maximum(hi - lo, 1e-9)
    pad = 0.03 * span.max()
    lo, span = lo - pad, span + 2 * pad
    room_h = max(height - top - bottom, 8)
    scale = min((width - 2 * side) / span[0], room_h / span[1])
    # centre the model in the drawing area
    left = side + 0.5 * ((width - 2 * side) - span[0] * scale)
    extra_v = 0.5 * (room_h - span[1] * scale)
    return View(x0=float(lo[0]), y0=float(lo[1]), scale=float(scale), height=height,
                left=int(round(left)), bottom=int(round(bottom + extra_v)))



def scale_bar_length(target: float) -> float:
    """The largest 1, 2 or 5 × 10^k not above target."""
    k = math.floor(math.log10(target))
    for m in (5, 2, 1):
        if m * 10 ** k <= target:
            return m * 10 ** k
    return 10 ** k
