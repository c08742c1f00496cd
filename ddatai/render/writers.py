"""The files of a run: an animated GIF (`write_gif`), an MP4 video (`write_video`) and a PNG
of one frame (`write_png`), drawn by `iter_frames` and written as they are drawn."""

from __future__ import annotations

from pathlib import Path
from typing import Optional

from ..results import Results
from .painter import iter_frames, render_frames
from .schedule import MAX_VIDEO_FPS, animation_schedule, check_gif_options, display_times
from .streams import GifStream, VideoStream, check_video_available


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
    idx, durations = animation_schedule(results, fps, speed, stride, frames)
    if durations is None:  # every chosen frame shown for 1/fps, in whole hundredths
        durations = display_times(range(1, len(idx) + 1), fps)
    images = iter_frames(results, size=size, frames=idx, labels=labels, label_names=label_names,
                         show_contacts=show_contacts, title=title, max_speed=max_speed)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with GifStream(path) as gif:
        for image, seconds in zip(images, durations):
            gif.append(image, seconds)
    return path



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
    idx, durations = animation_schedule(results, fps, speed, stride, frames)
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
