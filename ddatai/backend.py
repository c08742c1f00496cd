"""The one owner of the Taichi runtime.

Nothing in ddatai calls ``ti.init`` except `ensure`. It is called lazily by the first
simulation (or test) that needs a kernel, with double precision as the default float type:
penetrations of ~1e-8 m on coordinates of ~1e2 m do not survive float32
(docs/method/dda.md §8.9). Taichi keeps one runtime per process; asking for another arch
re-initialises it (and recompiles kernels on first use).
"""

from __future__ import annotations

import os

_current_arch: str | None = None
_requested_arch: str | None = None


def ensure(arch: str = "cpu") -> str:
    """Initialise Taichi for ``arch`` ("cpu", "gpu", "cuda", "vulkan", "metal") if not done.

    Returns the arch really in use. "gpu" picks the first available of CUDA, Vulkan, Metal and
    falls back to the CPU when there is none; naming a specific GPU backend that is absent
    raises ``RuntimeError``.
    """
    global _current_arch, _requested_arch
    if _current_arch is not None and arch in (_current_arch, _requested_arch):
        return _current_arch
    os.environ.setdefault("TI_SKIP_VERSION_CHECK", "ON")  # no network look-up from CI
    import taichi as ti

    # "gpu" tries CUDA, then Vulkan, then Metal. Not ti.gpu: it also probes OpenGL, which
    # crashes the process (segfault) on headless machines without a GPU driver.
    targets = {"cpu": ti.cpu, "gpu": [ti.cuda, ti.vulkan, ti.metal], "cuda": ti.cuda,
               "vulkan": ti.vulkan, "metal": ti.metal}
    if arch not in targets:
        raise ValueError(f"unknown Taichi arch {arch!r}; expected one of {sorted(targets)}")
    ti.init(arch=targets[arch], default_fp=ti.f64, default_ip=ti.i32,
            enable_fallback=True, offline_cache=True, log_level=ti.WARN)
    from . import kernel_prep

    kernel_prep.install()  # the kernels' first calls in a process, quicker (same IR, same code)
    actual = ti.lang.impl.current_cfg().arch
    name = {ti.cpu: "cpu", ti.x64: "cpu", ti.arm64: "cpu"}.get(actual, str(actual).split(".")[-1])
    if arch not in ("gpu", name):
        raise RuntimeError(f"Taichi arch {arch!r} requested but {name!r} was initialised")
    _current_arch = name
    _requested_arch = arch
    return _current_arch


#: at most this many CPU threads: scatter-add kernels run serially (see `serial_scatter`)
SERIAL_SCATTER_MAX_THREADS = 4


def serial_scatter() -> bool:
    """Whether kernels that scatter-add into the global matrix should run their loop serially.

    On the CPU Taichi makes every f64 ``atomic_add`` a compare-and-swap loop. With 2 threads the
    contact assembly at 1,600 blocks takes 4.6 ms in parallel and 2.3 ms serially (where the
    adds are plain stores), and the serial sum is bit-for-bit reproducible. Many-core CPUs and
    GPUs keep the parallel loop.
    """
    import taichi as ti

    if _current_arch != "cpu":
        return False
    return ti.lang.impl.current_cfg().cpu_max_num_threads <= SERIAL_SCATTER_MAX_THREADS


def current() -> str | None:
    """The arch Taichi was initialised with by `ensure`, or None."""
    return _current_arch
