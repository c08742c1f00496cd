"""Time the offscreen renderer: ms per 640×480 frame for 1,000 and 10,000 blocks, and GIF writing.

    python benchmarks/render.py

This is the measurement behind the choice of Pillow as the rasteriser (see ddatai/render/__init__.py).
"""

import platform
import time

import numpy as np

import ddatai as dd
from ddatai.results import Results


def grid_results(n_side: int, frames: int) -> Results:
    n = n_side * n_side
    i, j = np.meshgrid(np.arange(n_side), np.arange(n_side))
    corners = np.array([(0, 0), (0.9, 0), (0.9, 0.9), (0, 0.9)])
    base = (np.stack([i.ravel(), j.ravel()], axis=1)[:, None, :] + corners[None]).reshape(-1, 2)
    rng = np.random.default_rng(0)
    verts = np.stack([base + 0.05 * f for f in range(frames)])
    speed = rng.random((frames, n, 2))
    return Results(time=np.arange(frames) * 0.01, centroid=np.zeros((frames, n, 2)),
                   rotation=np.zeros((frames, n)), velocity=speed, angular_velocity=np.zeros((frames, n)),
                   stress=np.zeros((frames, n, 3)), vertices=verts, vertex_offset=np.arange(0, 4 * n + 1, 4),
                   block_fixed=np.zeros(n, bool), measured=np.zeros((frames, 0, 2)),
                   contact_offset=np.zeros(frames + 1, int), contact_xy=np.zeros((0, 2)),
                   contact_state=np.zeros(0, np.int8), steps=np.zeros(0, dd.STEP_DTYPE))


def main() -> None:
    print(f"machine: {platform.machine()} {platform.processor()} python {platform.python_version()}")
    print("| blocks | ms per frame (median of 7) | GIF of 20 frames, ms per frame |\n|---|---|---|")
    import tempfile
    from pathlib import Path

    for side in (32, 100):
        res = grid_results(side, 20)
        times = []
        for _ in range(7):
            t = time.perf_counter()
            dd.render_frames(res, frames=[0])
            times.append(time.perf_counter() - t)
        with tempfile.TemporaryDirectory() as d:
            t = time.perf_counter()
            dd.write_gif(res, Path(d) / "x.gif", stride=1)
            gif = (time.perf_counter() - t) / 20
        print(f"| {side * side:,} | {1e3 * np.median(times):.1f} | {1e3 * gif:.1f} |")


if __name__ == "__main__":
    main()
