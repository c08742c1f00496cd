"""Animation files written one frame at a time, so that memory does not grow with their length:
GIF (`GifStream`, Pillow) and MP4 video (`VideoStream`, the optional ``[video]`` extra)."""

from __future__ import annotations

from pathlib import Path
from typing import Optional

import numpy as np


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
