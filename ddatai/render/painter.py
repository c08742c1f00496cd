"""Drawing the frames of one animation (`_Painter`): the blocks in their colours, the overlays,
the contacts, the header, the scale bar and the legend, with a view and a colour scale fixed
for the whole animation; `iter_frames` and `render_frames` hand them out as arrays."""

from __future__ import annotations

from typing import Iterator, Optional, Sequence

import numpy as np

from ..results import Results
from .colours import (BACKGROUND, CONTACT_COLOURS, CONTACT_NAMES, DEFAULT_FREE, FIXED, FIXED_POINT, LABEL_COLOURS,
                      LOAD, MEASURED, MIN_SPEED_SCALE, OUTLINE, SPEED_COLOURS, TEXT, block_displacement, block_radius,
                      block_speed)
from .header import default_font, layout, text_size
from .overlays import draw_points_and_loads, draw_water_and_bolts, water_and_bolt_legend
from .schedule import check_size, chosen_frames
from .view import fit_view, scale_bar_length


class _Painter:
    """Draws frames of one animation with a fixed view and colour scale."""

    def __init__(self, results: Results, frames: Sequence[int], *, size, labels, label_names,
                 show_contacts, title, max_speed):
        self.results = results
        self.size = size
        self.font = default_font(text_size(size))
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
            self.radius = block_radius(results)
            free = ~results.block_fixed

            def top(measure) -> float:
                if not free.any():
                    return 0.0
                return max((float(measure(results, f, self.radius)[free].max()) for f in frames), default=0.0)

            fastest = top(block_speed)
            # 1 mm/s floor: a model at rest shows round-off speeds, which are not motion
            self.max_speed = float(max_speed) if max_speed is not None else max(fastest, MIN_SPEED_SCALE)
            self.measure = block_speed
            self.quantity, self.unit = "speed", "m/s"
            if max_speed is None and fastest < MIN_SPEED_SCALE:
                # no block moves faster than the floor (a static or settled run): the colours
                # show how far the blocks have moved instead, or a uniform scale shows nothing
                far = top(block_displacement)
                if far > 0.0:
                    self.measure, self.max_speed = block_displacement, far
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
        self.view = fit_view(results, frames, size, top=self.layout.header,
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
        draw_water_and_bolts(d, v, r, frame, width)
        draw_points_and_loads(d, v, r, frame)
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
        length = scale_bar_length(0.2 * width / self.view.scale)
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
        entries += water_and_bolt_legend(self.results)
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
    size = check_size(size)
    idx = chosen_frames(results, stride, frames)
    painter = _Painter(results, idx, size=size, labels=labels, label_names=label_names,
                       show_contacts=show_contacts, title=title, max_speed=max_speed)
    return (painter.image(f) for f in idx)
