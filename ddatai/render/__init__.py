"""Offscreen rendering of recorded results to GIF and PNG.

Reads `ddatai.results.Results` only; never starts Taichi and never opens a window. Pillow draws
the frames (filled polygons, outlines, contacts, text) and encodes them; a GIF is written one
frame at a time (`GifStream`), so its memory does not grow with its length, and so is an MP4
video (`write_video`, `VideoStream`: the optional ``[video]`` extra, imageio's ffmpeg plugin). Pillow is imported
inside the functions, so ``import ddatai`` and runs without a GIF never load it.

Why Pillow and not a Taichi raster kernel: measured with ``benchmarks/render.py`` on the
development machine (2-vCPU EPYC), a 640×480 frame with its colours, outlines and text takes
8 ms for 1,024 blocks and 33 ms for 10,000 (GIF encoding adds 17–25 ms per frame): far under
the one-second budget. Pillow needs no JIT (rendering saved results does not start Taichi, whose
init and kernel compile cost about a second in a fresh process) and also draws the text of
labels, legend and scale bar. Output is deterministic: the same results give the same bytes.

A frame shows fixed blocks grey, moving blocks coloured by speed (a discrete scale fixed for the
whole animation; by displacement when no block moves faster than 1 mm/s, as in a static run)
or by a group label the caller passes (with a legend), fixed points as triangles, point loads
as arrows along their force, measured points as crosses, block outlines, optional contact points coloured by state (open / sliding / locked), the simulated
time and a scale bar in metres. The view frames every block of every rendered frame, with equal scales in x and y,
and does not move.

The package, in the order data flows through it: ``colours`` (the colours and the speed
scale's measures), ``view`` (world -> pixels, the scale bar's length), ``header`` (text size,
font, the header's layout), ``schedule`` (which frames an animation shows, for how long; the
option checks), ``overlays`` (points, loads, water, bolts), ``painter`` (a frame drawn whole;
`iter_frames`, `render_frames`), ``streams`` (`GifStream`, `VideoStream`) and ``writers``
(`write_gif`, `write_video`, `write_png`). Every name is importable from ``ddatai.render``.
"""

from __future__ import annotations

from .colours import (BACKGROUND, BOLT, BROKEN_BOLT, CONTACT_COLOURS, CONTACT_NAMES, DEFAULT_FREE, FIXED,
                      FIXED_POINT, LABEL_COLOURS, LOAD, MEASURED, MIN_SPEED_SCALE, OUTLINE, SPEED_COLOURS, TEXT,
                      WATER)
from .header import Box, Layout, layout, text_size
from .painter import iter_frames, render_frames
from .schedule import MAX_FPS, MAX_VIDEO_FPS, check_gif_options, gif_schedule
from .streams import GifStream, VideoStream, check_video_available
from .view import View
from .writers import write_gif, write_png, write_video

__all__ = ["BACKGROUND", "BOLT", "BROKEN_BOLT", "CONTACT_COLOURS", "CONTACT_NAMES", "DEFAULT_FREE", "FIXED",
           "FIXED_POINT", "LABEL_COLOURS", "LOAD", "MEASURED", "MIN_SPEED_SCALE", "OUTLINE", "SPEED_COLOURS",
           "TEXT", "WATER", "Box", "Layout", "layout", "text_size", "iter_frames", "render_frames", "MAX_FPS",
           "MAX_VIDEO_FPS", "check_gif_options", "gif_schedule", "GifStream", "VideoStream",
           "check_video_available", "View", "write_gif", "write_png", "write_video"]
