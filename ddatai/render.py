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
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Iterator, Optional, Sequence

import numpy as np

from .results import Results

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


def _view(results: Results, frames: Sequence[int], size: tuple[int, int], *, top: int = 26,
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


def _font(size: int):
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


def _nice_length(target: float) -> float:
    """The largest 1, 2 or 5 × 10^k not above target."""
    k = math.floor(math.log10(target))
    for m in (5, 2, 1):
        if m * 10 ** k <= target:
            return m * 10 ** k
    return 10 ** k


def _block_radius(results: Results) -> np.ndarray:
    """(B,) largest distance of a block's vertices from its centroid at frame 0 [m]."""
    off = results.vertex_offset
    centroid = results.centroid[0]
    block = np.repeat(np.arange(results.n_blocks), np.diff(off))
    r = np.hypot(*(results.vertices[0] - centroid[block]).T)
    return np.maximum.reduceat(r, off[:-1])


def _speed(results: Results, frame: int, radius: np.ndarray) -> np.ndarray:
    """(B,) block speed at a frame: centroid speed plus |ω| × block radius [m/s]."""
    v = results.velocity[frame]
    return np.hypot(v[:, 0], v[:, 1]) + np.abs(results.angular_velocity[frame]) * radius


def _moved(results: Results, frame: int, radius: np.ndarray) -> np.ndarray:
    """(B,) how far each block has moved since frame 0: centroid displacement plus
    |rotation| × block radius [m]."""
    u = results.centroid[frame] - results.centroid[0]
    return np.hypot(u[:, 0], u[:, 1]) + np.abs(results.rotation[frame] - results.rotation[0]) * radius


def _draw_points_and_loads(d, view: View, results: Results, frame: int) -> None:
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


class _Painter:
    """Draws frames of one animation with a fixed view and colour scale."""

    def __init__(self, results: Results, frames: Sequence[int], *, size, labels, label_names,
                 show_contacts, title, max_speed):
        self.results = results
        self.size = size
        self.font = _font(text_size(size))
        self.show_contacts = show_contacts
        self.title = title
        nb = results.n_blocks
        self.labels = None
        if labels is not None:
            lab = np.asarray(labels)
            if lab.shape != (nb,) or not np.issubdtype(lab.dtype, np.integer):
                raise ValueError(f"labels must be an integer array of shape ({nb},), got {lab.shape} {lab.dtype}")
            self.labels = lab
            used = sorted(set(int(x) for x in lab[lab >= 0]))
            names = list(label_names) if label_names is not None else [f"group {k}" for k in range(max(used, default=-1) + 1)]
            if used and max(used) >= len(names):
                raise ValueError(f"label_names has {len(names)} names but labels use {max(used) + 1}")
            self.legend = [(LABEL_COLOURS[k % len(LABEL_COLOURS)], names[k]) for k in used]
        else:
            # the colour scale's top over the drawn frames, one frame at a time (no (F, B) array)
            self.radius = _block_radius(results)
            free = ~results.block_fixed

            def top(measure) -> float:
                if not free.any():
                    return 0.0
                return max((float(measure(results, f, self.radius)[free].max()) for f in frames), default=0.0)

            fastest = top(_speed)
            # 1 mm/s floor: a model at rest shows round-off speeds, which are not motion
            self.max_speed = float(max_speed) if max_speed is not None else max(fastest, MIN_SPEED_SCALE)
            self.measure = _speed
            self.quantity, self.unit = "speed", "m/s"
            if max_speed is None and fastest < MIN_SPEED_SCALE:
                # no block moves faster than the floor (a static or settled run): the colours
                # show how far the blocks have moved instead, or a uniform scale shows nothing
                far = top(_moved)
                if far > 0.0:
                    self.measure, self.max_speed = _moved, far
                    self.quantity, self.unit = "displacement", "m"
        off = results.vertex_offset
        self.offsets = off
        # the header is laid out once for the animation (the widest time stamp), so that it
        # and the view stay put from frame to frame
        times = [self._time_text(float(results.time[f])) for f in frames]
        widest = max(times, key=self.font.getlength)
        coloured = self.labels is None
        self.layout = layout(size, self.font, time_text=widest, title=title,
                             bar_label=self.quantity if coloured else None,
                             bar_value=self._bar_value() if coloured else None)
        text_h = self.font.getbbox("Ag")[3]
        self.view = _view(results, frames, size, top=self.layout.header,
                          bottom=text_h + 2 * self.layout.pad + 4)

    @staticmethod
    def _time_text(t: float) -> str:
        return f"t = {t:.3f} s"

    def _bar_value(self) -> str:
        return f"{self.max_speed:.3g} {self.unit}"

    def block_colours(self, frame: int) -> list[tuple[int, int, int]]:
        r = self.results
        out = []
        if self.labels is not None:
            for b in range(r.n_blocks):
                if r.block_fixed[b]:
                    out.append(FIXED)
                elif self.labels[b] >= 0:
                    out.append(LABEL_COLOURS[int(self.labels[b]) % len(LABEL_COLOURS)])
                else:
                    out.append(DEFAULT_FREE)
            return out
        n = len(SPEED_COLOURS)
        value = self.measure(r, frame, self.radius)
        level = np.clip((value / self.max_speed * n).astype(int), 0, n - 1)
        return [FIXED if r.block_fixed[b] else SPEED_COLOURS[level[b]] for b in range(r.n_blocks)]

    def image(self, frame: int) -> np.ndarray:
        """One frame as an (H, W, 3) uint8 array."""
        return np.asarray(self.draw(frame))

    def draw(self, frame: int):
        from PIL import Image, ImageDraw

        r, v = self.results, self.view
        width, height = self.size
        self._frame = frame
        image = Image.new("RGB", self.size, BACKGROUND)
        d = ImageDraw.Draw(image)
        pix = v.pixels(r.vertices[frame])
        colours = self.block_colours(frame)
        off = self.offsets
        for b in range(r.n_blocks):
            pts = [tuple(p) for p in pix[off[b]:off[b + 1]].tolist()]
            d.polygon(pts, fill=colours[b], outline=OUTLINE)
        _draw_water_and_bolts(d, v, r, frame, width)
        _draw_points_and_loads(d, v, r, frame)
        if r.measured.shape[1]:
            for x, y in v.pixels(r.measured[frame]).tolist():
                d.line([(x - 4, y - 4), (x + 4, y + 4)], fill=MEASURED, width=2)
                d.line([(x - 4, y + 4), (x + 4, y - 4)], fill=MEASURED, width=2)
        if self.show_contacts and r.contact_offset[-1] > 0:
            cxy, cst = r.contacts(frame)
            cpix = v.pixels(cxy)
            for (x, y), s in zip(cpix.tolist(), cst.tolist()):
                if s != 0:  # open contacts would only clutter the picture
                    d.ellipse([x - 2, y - 2, x + 2, y + 2], fill=CONTACT_COLOURS[s])
        self.header(d)
        self._scale_bar(d)
        self._legend(d)
        return image

    def header(self, d, parts: Optional[Sequence[str]] = None) -> None:
        """Draw the header (`Layout`): the time stamp, the title, the colour bar, its label and
        its end values; ``parts`` names some of them (`Layout.boxes`' names) to draw only those."""
        lay, font = self.layout, self.font
        frame = getattr(self, "_frame", 0)

        def want(name: str) -> bool:
            return parts is None or name in parts

        if want("time"):
            d.text((lay.pad, lay.pad), self._time_text(float(self.results.time[frame])), fill=TEXT, font=font)
        if lay.title is not None and want("title"):
            left, top = font.getbbox(lay.title_text)[:2]
            d.text((lay.title[0] - left, lay.title[1] - top), lay.title_text, fill=TEXT, font=font)
        if lay.bar is not None:
            x0, y0, x1, y1 = lay.bar
            if want("colour bar"):
                n = len(SPEED_COLOURS)
                for k, c in enumerate(SPEED_COLOURS):
                    d.rectangle([x0 + k * (x1 - x0) / n, y0, x0 + (k + 1) * (x1 - x0) / n, y1], fill=c)
            if want("colour bar label"):
                left, top = font.getbbox(self.quantity)[:2]
                d.text((lay.bar_label[0] - left, lay.bar_label[1] - top), self.quantity, fill=TEXT, font=font)
            if want("colour bar values"):
                vy = y1 + 2
                d.text((x0, vy), "0", fill=TEXT, font=font)
                value = self._bar_value()
                d.text((x1 - font.getlength(value), vy), value, fill=TEXT, font=font)

    def _scale_bar(self, d) -> None:
        width, height = self.size
        pad = self.layout.pad
        length = _nice_length(0.2 * width / self.view.scale)
        px = length * self.view.scale
        text_h = self.font.getbbox("Ag")[3]
        x0, y0 = pad + 4, height - pad - 0.5 * text_h
        d.line([(x0, y0), (x0 + px, y0)], fill=TEXT, width=2)
        d.line([(x0, y0 - 4), (x0, y0 + 1)], fill=TEXT, width=1)
        d.line([(x0 + px, y0 - 4), (x0 + px, y0 + 1)], fill=TEXT, width=1)
        d.text((x0 + px + 6, y0 - 0.6 * text_h), f"{length:g} m", fill=TEXT, font=self.font)

    def _legend(self, d) -> None:
        """Group labels, contacts, water, bolts and points, one per line at the right, below
        the header."""
        width, _ = self.size
        pad = self.layout.pad
        text_h = self.font.getbbox("Ag")[3]
        box = max(8, int(round(0.8 * text_h)))
        x, y = width - pad, self.layout.header
        entries: list[tuple[tuple[int, int, int], str]] = []
        if self.labels is not None:
            entries = list(self.legend)
        if self.show_contacts:
            entries += [(CONTACT_COLOURS[s], CONTACT_NAMES[s] + " contact") for s in (1, 2)]
        entries += _water_and_bolt_legend(self.results)
        if self.results.measured.shape[1]:
            entries.append((MEASURED, "measured point"))
        if self.results.fixed_points.size:
            entries.append((FIXED_POINT, "fixed point"))
        if self.results.load_points.size:
            entries.append((LOAD, "point load"))
        for colour, name in entries:
            w = self.font.getlength(name)
            d.rectangle([x - box, y + 2, x, y + 2 + box], fill=colour, outline=OUTLINE)
            d.text((x - box - 4 - w, y), name, fill=TEXT, font=self.font)
            y += text_h + 4


def _schedule(results, fps, speed, stride, frames):
    """The frames to draw and how long each shows: sampled in simulated time at ``speed`` (the
    default), or every ``stride``-th / the given ``frames`` with durations left to the writer
    (None)."""
    if results.n_frames == 0:
        raise ValueError("results have no frames to render")
    if frames is None and stride is None:
        return gif_schedule(results.time, fps=fps, speed=speed)
    return _frames(results, 1 if stride is None else stride, frames), None


def _frames(results: Results, stride: int, frames: Optional[Sequence[int]]) -> list[int]:
    if results.n_frames == 0:
        raise ValueError("results have no frames to render")
    if frames is not None:
        out = [range(results.n_frames)[f] for f in frames]  # IndexError for a bad frame
    else:
        _check_stride(stride)
        out = list(range(0, results.n_frames, stride))
        if out[-1] != results.n_frames - 1:
            out.append(results.n_frames - 1)  # always end on the last frame
    return out


def _check_stride(stride) -> None:
    if not (isinstance(stride, (int, np.integer)) and not isinstance(stride, bool) and stride >= 1):
        raise ValueError(f"stride must be a positive integer, got {stride!r}")


def _check_size(size) -> tuple[int, int]:
    try:
        w, h = (int(size[0]), int(size[1]))
    except (TypeError, ValueError, IndexError):
        raise ValueError(f"size must be (width, height) in pixels, got {size!r}") from None
    if w < 64 or h < 64:
        raise ValueError(f"size must be at least 64 × 64 pixels, got {size!r}")
    return w, h


#: GIF frame delays are whole hundredths of a second, and most viewers slow down frames shown
#: for less than 0.02 s: 50 frames per second is the fastest GIF that plays as written
MAX_FPS = 50.0


#: a video's frame rate may be higher (its frames are not whole hundredths)
MAX_VIDEO_FPS = 120.0


def check_gif_options(*, size=(640, 480), fps: float = 20.0, speed: Optional[float] = 1.0,
                      stride: Optional[int] = None, max_fps: float = MAX_FPS) -> tuple[int, int]:
    """Validate the GIF options of `write_gif` (or, with ``max_fps=MAX_VIDEO_FPS``, the video
    options of `write_video`) without drawing anything (the command line calls it before a
    run); returns the size as (width, height). Raises `ValueError`."""
    size = _check_size(size)
    if not (isinstance(fps, (int, float)) and not isinstance(fps, bool) and math.isfinite(fps)
            and 0 < fps <= max_fps):
        raise ValueError(f"fps must be a number in (0, {max_fps:g}] frames per second, got {fps!r}")
    if speed is not None and not (isinstance(speed, (int, float)) and not isinstance(speed, bool)
                                  and math.isfinite(speed) and speed > 0):
        raise ValueError(f"speed must be a number > 0 (simulated seconds per second of playback), got {speed!r}")
    if stride is not None:
        _check_stride(stride)
    return size


def gif_schedule(time: np.ndarray, *, fps: float = 20.0, speed: float = 1.0
                 ) -> tuple[list[int], list[float]]:
    """Which recorded frames a GIF shows, and for how long, to play at a fixed speed.

    The animation samples simulated time every ``speed / fps`` seconds: target k shows the
    recorded frame nearest to ``time[0] + k·speed/fps`` for ``1/fps`` seconds, and the last
    recorded frame ends the animation. A frame chosen for consecutive targets (recorded frames
    sparser than the targets) is shown once for their combined time, so the animation lasts
    ``(time[-1] − time[0]) / speed`` seconds whatever the time steps were (to a frame).

    Returns (frame indices, display time of each frame [s]); the display times are whole
    hundredths of a second (the GIF unit), rounded so that their running sum stays on the
    schedule.
    """
    time = np.asarray(time, dtype=float)
    if len(time) == 0:
        raise ValueError("results have no frames to render")
    interval = speed / fps  # simulated seconds per GIF frame
    span = float(time[-1] - time[0])
    n = int(math.floor(span / interval * (1 + 1e-12))) + 1  # targets 0 .. n-1
    targets = time[0] + interval * np.arange(n)
    right = np.clip(np.searchsorted(time, targets), 1, len(time) - 1) if len(time) > 1 else np.zeros(n, int)
    if len(time) > 1:
        left = right - 1
        nearest = np.where(targets - time[left] <= time[right] - targets, left, right)
    else:
        nearest = right
    idx = [int(i) for i in nearest]
    if idx[-1] != len(time) - 1:
        idx.append(len(time) - 1)  # always end on the last frame
    frames: list[int] = []
    ends: list[int] = []  # each frame's display ends after this many targets
    for k, f in enumerate(idx):
        if frames and frames[-1] == f:
            ends[-1] = k + 1
        else:
            frames.append(f)
            ends.append(k + 1)
    return frames, _display_times(ends, fps)


def _display_times(ends: Sequence[int], fps: float) -> list[float]:
    """Display time of each frame [s] whose display ends after ``ends[i]`` frame periods,
    in whole hundredths of a second that add up to the schedule (no drift)."""
    stops = np.round(np.asarray(ends, dtype=float) * (100.0 / fps))
    durations = np.diff(np.concatenate([[0.0], stops])) / 100.0
    return [float(max(d, 0.01)) for d in durations]


def render_frames(results: Results, *, size=(640, 480), stride: int = 1, frames=None, labels=None,
                  label_names=None, show_contacts: bool = False, title: Optional[str] = None,
                  max_speed: Optional[float] = None) -> list[np.ndarray]:
    """Render frames to a list of (H, W, 3) uint8 arrays (see `write_gif` for the options).

    The list holds every image at once: for a long animation use `iter_frames` or `write_gif`,
    which keep one frame at a time."""
    return list(iter_frames(results, size=size, stride=stride, frames=frames, labels=labels,
                            label_names=label_names, show_contacts=show_contacts, title=title,
                            max_speed=max_speed))


def iter_frames(results: Results, *, size=(640, 480), stride: int = 1, frames=None, labels=None,
                label_names=None, show_contacts: bool = False, title: Optional[str] = None,
                max_speed: Optional[float] = None) -> Iterator[np.ndarray]:
    """Yield rendered frames one at a time as (H, W, 3) uint8 arrays (see `write_gif` for the
    options); the arguments are checked before the first frame is drawn."""
    size = _check_size(size)
    idx = _frames(results, stride, frames)
    painter = _Painter(results, idx, size=size, labels=labels, label_names=label_names,
                       show_contacts=show_contacts, title=title, max_speed=max_speed)
    return (painter.image(f) for f in idx)


def write_gif(results: Results, path, *, size=(640, 480), fps: float = 20.0, speed: float = 1.0,
              stride: Optional[int] = None, frames=None, labels=None, label_names=None,
              show_contacts: bool = False, title: Optional[str] = None,
              max_speed: Optional[float] = None) -> Path:
    """Render recorded frames to an animated GIF (offscreen; deterministic; bounded memory).

    By default the animation plays at a stated speed: it samples simulated time every
    ``speed / fps`` seconds (`gif_schedule`), so one second of playback shows ``speed``
    seconds of simulation wherever the time step was cut, and a run of T seconds plays for
    T / speed seconds (``speed=1``: real time; ``speed=0.1``: ten times slower). ``stride`` or
    ``frames`` choose recorded frames instead, each shown for 1/fps s (playback then follows
    the time steps). Each frame is drawn and written to the file before the next one
    (`GifStream`), so memory does not grow with the number of frames.

    Parameters
    ----------
    results : the run to draw.
    path : output file (.gif).
    size : (width, height) in pixels, at least 64 × 64.
    fps : frames per second of the animation, at most 50 (GIF delays are whole hundredths).
    speed : simulated seconds shown per second of playback (ignored with ``stride``/``frames``).
    stride : draw every stride-th recorded frame (the last frame is always drawn).
    frames : explicit frame indices (overrides stride).
    labels : (B,) int group label per block (-1: none) to colour by group instead of speed;
        ``label_names`` gives the legend text of each label.
    show_contacts : draw sliding and locked contacts (needs ``record_contacts=True``).
    title : text at the top.
    max_speed : top of the speed colour scale [m/s]; default the largest speed drawn (and, when
        that is below 1 mm/s, the blocks are coloured by how far they have moved instead).

    Returns the path written.
    """
    size = check_gif_options(size=size, fps=fps, speed=speed, stride=stride)
    idx, durations = _schedule(results, fps, speed, stride, frames)
    if durations is None:  # every chosen frame shown for 1/fps, in whole hundredths
        durations = _display_times(range(1, len(idx) + 1), fps)
    images = iter_frames(results, size=size, frames=idx, labels=labels, label_names=label_names,
                         show_contacts=show_contacts, title=title, max_speed=max_speed)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with GifStream(path) as gif:
        for image, seconds in zip(images, durations):
            gif.append(image, seconds)
    return path


class GifStream:
    """An animated GIF written one frame at a time: memory does not grow with the frames.

    Each frame goes to the file as it is appended: the rectangle that changed since the last
    frame, with its own colour table, so only the last frame is kept. Pillow encodes the
    frames (``PIL.GifImagePlugin.getheader`` and ``getdata``, its frame-by-frame GIF
    interface). Neither imageio's Pillow writer nor ``Image.save(save_all=True)`` streams: both
    hold every frame until the file is closed (gigabytes for a long run), and imageio's older
    streaming GIF writer declares a 256-colour table for every frame, which corrupts frames
    with fewer colours. A frame of at most 256 colours (every frame `write_gif` draws) is
    written exactly.

    >>> with GifStream("out.gif") as gif:              # doctest: +SKIP
    ...     for image in images:                       # (H, W, 3) uint8 arrays
    ...         gif.append(image, 0.05)                # shown for 0.05 s
    """

    def __init__(self, path, *, loop: int = 0):
        self.path = Path(path)
        self.loop = int(loop)  # 0: repeat for ever
        self.frames = 0
        self._previous: Optional[np.ndarray] = None  # the last frame (only the change is written)
        self._file = open(self.path, "wb")

    def append(self, image: np.ndarray, seconds: float) -> None:
        """Write one (H, W, 3) uint8 frame, shown for ``seconds`` (rounded to 0.01 s)."""
        from PIL import GifImagePlugin, Image

        image = np.asarray(image)
        if image.ndim != 3 or image.shape[2] != 3 or image.dtype != np.uint8:
            raise ValueError(f"a GIF frame must be an (H, W, 3) uint8 array, got {image.shape} {image.dtype}")
        ms = 10 * max(1, int(round(100.0 * seconds)))
        offset = (0, 0)
        part = image
        if self._previous is not None:
            if image.shape != self._previous.shape:
                raise ValueError(f"frame {self.frames} is {image.shape[1]}×{image.shape[0]} pixels, "
                                 f"the first was {self._previous.shape[1]}×{self._previous.shape[0]}")
            # only the rectangle that changed is written; the rest of the last frame stays
            changed = np.any(image != self._previous, axis=2)
            rows, cols = np.flatnonzero(changed.any(axis=1)), np.flatnonzero(changed.any(axis=0))
            y0, y1 = (int(rows[0]), int(rows[-1]) + 1) if len(rows) else (0, 1)
            x0, x1 = (int(cols[0]), int(cols[-1]) + 1) if len(cols) else (0, 1)
            part, offset = image[y0:y1, x0:x1], (x0, y0)
        frame = Image.fromarray(np.ascontiguousarray(part), "RGB")
        frame = frame.convert("P", palette=Image.Palette.ADAPTIVE, colors=256)
        if self._previous is None:
            header, _ = GifImagePlugin.getheader(frame, info={"loop": self.loop, "duration": ms})
            self._file.writelines(header)
        self._file.writelines(GifImagePlugin.getdata(frame, offset, duration=ms, disposal=1,
                                                     include_color_table=True))
        self._file.flush()
        self._previous = image
        self.frames += 1

    def close(self) -> None:
        if not self._file.closed:
            self._file.write(b";")  # GIF trailer
            self._file.close()

    def __enter__(self) -> "GifStream":
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def check_video_available() -> None:
    """`ImportError` naming the extra when the video writer's packages are missing."""
    import importlib.util

    if importlib.util.find_spec("imageio") is None or importlib.util.find_spec("imageio_ffmpeg") is None:
        raise ImportError("writing a video needs imageio and imageio-ffmpeg, an optional extra: "
                          "pip install 'ddatai[video]'")


class VideoStream:
    """An MP4 video (H.264) written one frame at a time through imageio's ffmpeg plugin (the
    ``[video]`` extra): like `GifStream`, only the last frame is held, and the file is smaller
    and sharper than a GIF for long runs (no 256-colour limit, motion-compensated frames).

    A video plays at a constant frame rate: a frame appended for ``seconds`` is written
    ``round(seconds × fps)`` times (counted on the running total, so the video keeps its
    schedule). Frames of odd width or height are padded by one background pixel (H.264 in the
    usual yuv420p pixel format needs even sizes).

    >>> with VideoStream("out.mp4", fps=25) as video:   # doctest: +SKIP
    ...     for image in images:                         # (H, W, 3) uint8 arrays
    ...         video.append(image, 0.04)
    """

    def __init__(self, path, *, fps: float = 20.0, quality: float = 7.0):
        check_video_available()
        import imageio.v2 as imageio

        self.path = Path(path)
        self.fps = float(fps)
        self.frames = 0          # video frames written
        self._elapsed = 0.0      # display time appended so far [s]
        self._shape = None
        self._writer = imageio.get_writer(self.path, format="FFMPEG", mode="I", fps=self.fps, codec="libx264",
                                          quality=quality, pixelformat="yuv420p", macro_block_size=1,
                                          ffmpeg_log_level="error")

    def append(self, image: np.ndarray, seconds: float) -> None:
        """Write one (H, W, 3) uint8 frame, shown for ``seconds``."""
        image = np.asarray(image)
        if image.ndim != 3 or image.shape[2] != 3 or image.dtype != np.uint8:
            raise ValueError(f"a video frame must be an (H, W, 3) uint8 array, got {image.shape} {image.dtype}")
        if self._shape is None:
            self._shape = image.shape
        elif image.shape != self._shape:
            raise ValueError(f"frame {self.frames} is {image.shape[1]}×{image.shape[0]} pixels, "
                             f"the first was {self._shape[1]}×{self._shape[0]}")
        h, w = image.shape[:2]
        if h % 2 or w % 2:
            image = np.pad(image, ((0, h % 2), (0, w % 2), (0, 0)), mode="edge")
        before = int(round(self._elapsed * self.fps))
        self._elapsed += float(seconds)
        repeat = int(round(self._elapsed * self.fps)) - before
        if self.frames == 0:
            repeat = max(repeat, 1)  # the first frame is always shown
        for _ in range(repeat):
            self._writer.append_data(image)
            self.frames += 1

    def close(self) -> None:
        if self._writer is not None:
            self._writer.close()
            self._writer = None

    def __enter__(self) -> "VideoStream":
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def write_video(results: Results, path, *, size=(640, 480), fps: float = 25.0, speed: float = 1.0,
                stride: Optional[int] = None, frames=None, labels=None, label_names=None,
                show_contacts: bool = False, title: Optional[str] = None,
                max_speed: Optional[float] = None, quality: float = 7.0) -> Path:
    """Render recorded frames to an MP4 video (H.264; needs the ``[video]`` extra: imageio and
    imageio-ffmpeg). The options are those of `write_gif`: the video plays at ``speed``
    simulated seconds per second (or shows every ``stride``-th recorded frame for 1/fps s),
    drawn and written one frame at a time (`VideoStream`). ``fps`` may be up to 120;
    ``quality`` is imageio's 0–10 (higher: larger, sharper files). Returns the path written."""
    size = check_gif_options(size=size, fps=fps, speed=speed, stride=stride, max_fps=MAX_VIDEO_FPS)
    check_video_available()
    idx, durations = _schedule(results, fps, speed, stride, frames)
    if durations is None:  # every chosen frame shown for 1/fps
        durations = [1.0 / fps] * len(idx)
    images = iter_frames(results, size=size, frames=idx, labels=labels, label_names=label_names,
                         show_contacts=show_contacts, title=title, max_speed=max_speed)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with VideoStream(path, fps=fps, quality=quality) as video:
        for image, seconds in zip(images, durations):
            video.append(image, seconds)
    return path


def write_png(results: Results, path, frame: int = -1, *, size=(640, 480), labels=None,
              label_names=None, show_contacts: bool = False, title: Optional[str] = None,
              max_speed: Optional[float] = None) -> Path:
    """Render one recorded frame to a PNG file (see `write_gif` for the options)."""
    from PIL import Image

    image = render_frames(results, size=size, frames=[frame], labels=labels, label_names=label_names,
                          show_contacts=show_contacts, title=title, max_speed=max_speed)[0]
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    Image.fromarray(image).save(path, format="PNG")
    return path


# ---------------------------------------------------------------------- water and bolts
WATER = (0, 150, 255)
BOLT = (200, 20, 20)
BROKEN_BOLT = (90, 90, 90)


def _draw_water_and_bolts(d, view: View, results: Results, frame: int, width: int) -> None:
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


def _water_and_bolt_legend(results: Results) -> list:
    """Legend entries for the water table and the bolts of results that have them."""
    out = []
    if len(results.water_table):
        out.append((WATER, "water table"))
    if results.bolt_xy.size:
        out.append((BOLT, "bolt"))
        if results.bolt_broken.any():
            out.append((BROKEN_BOLT, "broken bolt"))
    return out
