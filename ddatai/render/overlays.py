"""What a frame draws over the blocks besides contacts: fixed points, point loads, the water
table and rock bolts, and their legend entries. Each draws nothing for results without it."""

from __future__ import annotations

import math

import numpy as np

from ..results import Results
from .colours import BOLT, BROKEN_BOLT, FIXED_POINT, LOAD, WATER
from .view import View


def draw_points_and_loads(d, view: View, results: Results, frame: int) -> None:
    """Fixed points as triangles; point loads as arrows of a fixed length along their force at
    the frame's time (a dot for a zero force)."""
    if results.fixed_points.size:
        for x, y in view.pixels(results.fixed_points[frame]).tolist():
            d.polygon([(x, y - 5), (x - 5, y + 4), (x + 5, y + 4)], fill=FIXED_POINT)
    if results.load_points.size:
        forces = results.load_forces[frame] if len(results.load_forces) > frame else np.zeros_like(
            results.load_points[frame])
        for (x, y), (fx, fy) in zip(view.pixels(results.load_points[frame]).tolist(), forces.tolist()):
            size = math.hypot(fx, fy)
            if not (size > 0 and math.isfinite(size)):
                d.ellipse([x - 3, y - 3, x + 3, y + 3], fill=LOAD)
                continue
            ux, uy = fx / size, -fy / size  # image y points down
            tail = (x - 28 * ux, y - 28 * uy)  # the arrow ends at the point it loads
            d.line([tail, (x, y)], fill=LOAD, width=3)
            d.polygon([(x, y), (x - 9 * ux + 5 * uy, y - 9 * uy - 5 * ux), (x - 9 * ux - 5 * uy, y - 9 * uy + 5 * ux)],
                      fill=LOAD)



def draw_water_and_bolts(d, view: View, results: Results, frame: int, width: int) -> None:
    """The water table (held level beyond its ends, across the picture) and the rock bolts:
    intact ones solid red with their ends, broken ones dashed grey with a cross at the middle.
    Nothing for results without them."""
    table = results.water_table
    if len(table):
        x_lo = view.x0 - view.left / view.scale
        x_hi = view.x0 + (width - view.left) / view.scale
        xs = np.concatenate([[min(x_lo, table[0, 0])], table[:, 0], [max(x_hi, table[-1, 0])]])
        line = view.pixels(np.stack([xs, np.interp(xs, table[:, 0], table[:, 1])], axis=1))
        d.line([tuple(p) for p in line.tolist()], fill=WATER, width=2)
    if results.bolt_xy.size == 0:
        return
    ends = view.pixels(results.bolt_xy[frame])          # (nb, 2, 2) in pixels
    for k, ((x1, y1), (x2, y2)) in enumerate(ends.tolist()):
        if results.bolt_broken[frame, k]:
            n = max(int(math.hypot(x2 - x1, y2 - y1) / 6), 1)
            for i in range(0, n, 2):  # dashes of 6 px
                a, b = i / n, min((i + 1) / n, 1.0)
                d.line([(x1 + a * (x2 - x1), y1 + a * (y2 - y1)), (x1 + b * (x2 - x1), y1 + b * (y2 - y1))],
                       fill=BROKEN_BOLT, width=2)
            mx, my = 0.5 * (x1 + x2), 0.5 * (y1 + y2)
            d.line([(mx - 4, my - 4), (mx + 4, my + 4)], fill=BOLT, width=2)
            d.line([(mx - 4, my + 4), (mx + 4, my - 4)], fill=BOLT, width=2)
        else:
            d.line([(x1, y1), (x2, y2)], fill=BOLT, width=2)
            for x, y in ((x1, y1), (x2, y2)):
                d.ellipse([x - 2, y - 2, x + 2, y + 2], fill=BOLT)


def water_and_bolt_legend(results: Results) -> list:
    """Legend entries for the water table and the bolts of results that have them."""
    out = []
    if len(results.water_table):
        out.append((WATER, "water table"))
    if results.bolt_xy.size:
        out.append((BOLT, "bolt"))
        if results.bolt_broken.any():
            out.append((BROKEN_BOLT, "broken bolt"))
    return out
