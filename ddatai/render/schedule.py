"""Which recorded frames an animation shows and for how long (`gif_schedule`: a stated playback
speed in simulated seconds per second), and the checks of the animation options."""

from __future__ import annotations

import math
from typing import Optional, Sequence

import numpy as np

from ..results import Results


def animation_schedule(results, fps, speed, stride, frames):
    """The frames to draw and how long each shows: sampled in simulated time at ``speed`` (the
    default), or every ``stride``-th / the given ``frames`` with durations left to the writer
    (None)."""
    if results.n_frames == 0:
        raise ValueError("results have no frames to render")
    if frames is None and stride is None:
        return gif_schedule(results.time, fps=fps, speed=speed)
    return chosen_frames(results, 1 if stride is None else stride, frames), None


def chosen_frames(results: Results, stride: int, frames: Optional[Sequence[int]]) -> list[int]:
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


def check_size(size) -> tuple[int, int]:
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
    size = check_size(size)
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
    return frames, display_times(ends, fps)


def display_times(ends: Sequence[int], fps: float) -> list[float]:
    """Display time of each frame [s] whose display ends after ``ends[i]`` frame periods,
    in whole hundredths of a second that add up to the schedule (no drift)."""
    stops = np.round(np.asarray(ends, dtype=float) * (100.0 / fps))
    durations = np.diff(np.concatenate([[0.0], stops])) / 100.0
    return [float(max(d, 0.01)) for d in durations]
