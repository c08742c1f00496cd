"""The colours of a frame, and the block measures the speed colour scale shows.

Fixed blocks are grey; moving blocks take one of ten `SPEED_COLOURS` by their speed (centroid
speed plus |ω| × the block's radius), or by how far they have moved when nothing moves faster
than `MIN_SPEED_SCALE` (a static or settled run), or one of the categorical `LABEL_COLOURS` by
a group label the caller passes. Contacts, water, bolts and points have colours of their own.
"""

from __future__ import annotations

import numpy as np

from ..results import Results

BACKGROUND = (255, 255, 255)
FIXED = (178, 178, 178)
OUTLINE = (45, 45, 45)
TEXT = (20, 20, 20)
#: speed scale, slow to fast (a viridis-like ramp in 10 steps)
SPEED_COLOURS = [(68, 1, 84), (72, 36, 117), (64, 67, 135), (52, 94, 141), (41, 120, 142),
                 (32, 144, 140), (34, 167, 132), (68, 190, 112), (121, 209, 81), (189, 222, 38)]
#: group labels (categorical)
LABEL_COLOURS = [(31, 119, 180), (255, 127, 14), (44, 160, 44), (214, 39, 40), (148, 103, 189),
                 (140, 86, 75), (227, 119, 194), (188, 189, 34), (23, 190, 207), (127, 127, 127)]
DEFAULT_FREE = (120, 150, 190)  # moving blocks without a label when colouring by label
CONTACT_COLOURS = {0: (160, 160, 160), 1: (230, 85, 13), 2: (33, 113, 181)}
CONTACT_NAMES = {0: "open", 1: "sliding", 2: "locked"}
MIN_SPEED_SCALE = 1e-3  # m/s: the smallest top of the speed colour scale
MEASURED = (200, 0, 120)  # measured points (crosses)
FIXED_POINT = (0, 0, 0)  # fixed points (triangles)
LOAD = (0, 140, 60)  # point loads (arrows along the force)
WATER = (0, 150, 255)  # the water table
BOLT = (200, 20, 20)  # intact rock bolts
BROKEN_BOLT = (90, 90, 90)  # broken rock bolts (dashed)


def block_radius(results: Results) -> np.ndarray:
    """(B,) largest distance of a block's vertices from its centroid at frame 0 [m]."""
    off = results.vertex_offset
    centroid = results.centroid[0]
    block = np.repeat(np.arange(results.n_blocks), np.diff(off))
    r = np.hypot(*(results.vertices[0] - centroid[block]).T)
    return np.maximum.reduceat(r, off[:-1])


def block_speed(results: Results, frame: int, radius: np.ndarray) -> np.ndarray:
    """(B,) block speed at a frame: centroid speed plus |ω| × block radius [m/s]."""
    v = results.velocity[frame]
    return np.hypot(v[:, 0], v[:, 1]) + np.abs(results.angular_velocity[frame]) * radius


def block_displacement(results: Results, frame: int, radius: np.ndarray) -> np.ndarray:
    """(B,) how far each block has moved since frame 0: centroid displacement plus
    |rotation| × block radius [m]."""
    u = results.centroid[frame] - results.centroid[0]
    return np.hypot(u[:, 0], u[:, 1]) + np.abs(results.rotation[frame] - results.rotation[0]) * radius
