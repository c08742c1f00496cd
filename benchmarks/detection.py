"""Contact detection + contact vectors: the vectorised NumPy path against the Taichi kernels.

    python benchmarks/detection.py [--sizes 1,4,16,64,256,1024] [--repeats 300] [--out PATH]

On ntdda's grid (``benchmarks/scaling.py``'s ``grid_scene``: n unit blocks on a fixed base,
at rest, every edge in contact) it times, on the same vertices:

- the kernel path: `ddatai.contacts.detect_contacts` (broad phase: grid_bin, grid_scatter,
  grid_query[, big_query]; narrow_phase; with buffers reused as in a run) and the
  `kernels.contact_vectors` launch as `ddatai.assembly.contact_vectors` makes it;
- the NumPy path: `ddatai.vectorized.detect_contacts` and `ddatai.vectorized.contact_vectors`.

The block geometry (centroids) and the lock positions ω are computed once, outside the timing:
a step has them either way. The two paths alternate within every repeat (A/B, then B/A), the
garbage collector is paused while timing, and the table gives medians over the repeats (with
the 25–75 % range of the totals: the machine may be shared). The crossover is the block count
where the kernel path's median total becomes smaller, interpolated log-log between the two
sizes that bracket it. Writes ``benchmarks/results/detection.md``.
"""

from __future__ import annotations

import argparse
import gc
import math
import os
import platform
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "benchmarks" / "results"
sys.path.insert(0, str(ROOT / "benchmarks"))


def measure(n_blocks: int, repeats: int) -> dict:
    """Median times [ms] of both paths on the grid of ``n_blocks`` free blocks."""
    import ddatai as dd
    from ddatai import kernels, vectorized
    from ddatai.backend import ensure
    from ddatai.contacts import _Buffers, detect_contacts, edge_projection
    from scaling import grid_scene

    ensure("cpu")
    scene, params = grid_scene(n_blocks)
    model = dd.build_model(scene, params)
    xy = model.vertex_xy0
    centroid = np.ascontiguousarray(model.block_geometry(xy)["centroid"])
    buffers = _Buffers()
    cint, length = detect_contacts(model, xy, buffers)
    omega = edge_projection(xy, model.vertex_next, cint[:, 1], cint[:, 2])

    def kernel_detect():
        return detect_contacts(model, xy, buffers)

    def kernel_vectors(c):
        vec = np.zeros((len(c), 6, 6))
        sca = np.zeros((len(c), 3))
        kernels.contact_vectors(xy, model.vertex_block, model.vertex_next, centroid, c, omega, vec, sca)
        return vec, sca

    def numpy_detect():
        return vectorized.detect_contacts(model, xy)

    def numpy_vectors(c):
        return vectorized.contact_vectors(model, xy, centroid, c, omega)

    # the paths agree (tests/test_vectorized.py checks this on many more scenes)
    c_np, l_np = numpy_detect()
    assert np.array_equal(c_np, cint) and np.allclose(l_np, length, rtol=1e-12, atol=1e-15)
    v_k, s_k = kernel_vectors(cint)
    v_n, s_n = numpy_vectors(cint)
    assert np.allclose(v_n, v_k, rtol=1e-12, atol=1e-12) and np.allclose(s_n, s_k, rtol=1e-12, atol=1e-15)

    paths = {"kernel": (kernel_detect, kernel_vectors), "numpy": (numpy_detect, numpy_vectors)}
    times = {(p, part): [] for p in paths for part in ("detect", "vectors")}

    def run(name):
        detect, vectors = paths[name]
        t0 = time.perf_counter()
        c, _ = detect()
        t1 = time.perf_counter()
        vectors(c)
        t2 = time.perf_counter()
        times[name, "detect"].append(t1 - t0)
        times[name, "vectors"].append(t2 - t1)

    for _ in range(5):  # warm-up: kernels compiled (offline cache), buffers grown
        run("kernel")
        run("numpy")
    for v in times.values():
        v.clear()
    gc.collect()
    gc.disable()
    try:
        for r in range(repeats):
            for name in (("kernel", "numpy") if r % 2 == 0 else ("numpy", "kernel")):
                run(name)
    finally:
        gc.enable()
    out = dict(blocks=int(model.n_free), all_blocks=int(model.n_blocks), contacts=int(len(cint)),
               pairs=int(len(vectorized.broad_phase(model, xy, model.search_distance))))
    for name in paths:
        det = np.array(times[name, "detect"]) * 1e3
        vec = np.array(times[name, "vectors"]) * 1e3
        total = det + vec
        out[f"{name}_detect"] = float(np.median(det))
        out[f"{name}_vectors"] = float(np.median(vec))
        out[f"{name}_total"] = float(np.median(total))
        out[f"{name}_q25"], out[f"{name}_q75"] = (float(q) for q in np.percentile(total, [25, 75]))
    return out


def crossover(rows: list[dict]) -> str:
    """Block count where the kernel path becomes faster (log-log interpolation of the ratio)."""
    ratio = [(r["blocks"], r["kernel_total"] / r["numpy_total"]) for r in rows]
    if ratio[0][1] <= 1.0:
        return f"the kernels are faster already at {ratio[0][0]} block(s)"
    for (n0, q0), (n1, q1) in zip(ratio, ratio[1:]):
        if q1 <= 1.0:
            f = math.log(q0) / (math.log(q0) - math.log(q1))
            n = math.exp(math.log(n0) + f * (math.log(n1) - math.log(n0)))
            return f"between {n0} and {n1} blocks (≈ {n:.0f}, log-log interpolation)"
    return f"none up to {ratio[-1][0]} blocks: the NumPy path is faster at every size measured"


def machine() -> str:
    import taichi as ti

    cpu = platform.processor() or platform.machine()
    try:
        with open("/proc/cpuinfo") as f:
            cpu = next(line.split(":", 1)[1].strip() for line in f if line.startswith("model name"))
    except (OSError, StopIteration):
        pass
    return (f"{cpu}, {os.cpu_count()} cores; Python {platform.python_version()}, NumPy {np.__version__}, "
            f"Taichi {'.'.join(map(str, ti.__version__))} (cpu backend)")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", default="1,4,16,64,256,1024")
    ap.add_argument("--repeats", type=int, default=300)
    ap.add_argument("--out", type=Path, default=RESULTS / "detection.md")
    a = ap.parse_args()
    load0 = os.getloadavg()[0]
    rows = []
    for n in (int(s) for s in a.sizes.split(",")):
        rows.append(measure(n, a.repeats))
        r = rows[-1]
        print(f"{r['blocks']:5d} blocks: kernel {r['kernel_total']:.3f} ms, numpy {r['numpy_total']:.3f} ms",
              flush=True)
    load1 = os.getloadavg()[0]
    lines = [
        "# Contact detection + contact vectors: NumPy path vs Taichi kernels",
        "",
        f"`python benchmarks/detection.py --sizes {a.sizes} --repeats {a.repeats}`",
        "",
        f"Machine: {machine()}. Load average {load0:.1f} at the start, {load1:.1f} at the end "
        "(the machine is shared: medians of A/B-interleaved repeats).",
        "",
        "Grid of n unit blocks on a fixed base (`benchmarks/scaling.py` `grid_scene`), at rest. "
        "Median ms per call; total = detection + contact vectors (25–75 % range).",
        "",
        "| free blocks | pairs | contacts | kernel detect | kernel vectors | kernel total | "
        "numpy detect | numpy vectors | numpy total | kernel / numpy |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        lines.append(
            f"| {r['blocks']} | {r['pairs']} | {r['contacts']} | {r['kernel_detect']:.3f} | "
            f"{r['kernel_vectors']:.3f} | "
            f"{r['kernel_total']:.3f} ({r['kernel_q25']:.3f}–{r['kernel_q75']:.3f}) | "
            f"{r['numpy_detect']:.3f} | {r['numpy_vectors']:.3f} | "
            f"{r['numpy_total']:.3f} ({r['numpy_q25']:.3f}–{r['numpy_q75']:.3f}) | "
            f"{r['kernel_total'] / r['numpy_total']:.2f} |")
    lines += ["", f"Crossover (kernels faster): {crossover(rows)}.", ""]
    text = "\n".join(lines)
    print(text)
    a.out.parent.mkdir(parents=True, exist_ok=True)
    a.out.write_text(text)


if __name__ == "__main__":
    main()
