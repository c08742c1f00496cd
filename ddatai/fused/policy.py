"""Which engine runs a simulation, and why (NumPy only, no Taichi): ``Params.kernels``
"fused" asks for the fused engine, "auto" takes it where it pays (docs/guide/performance.md).

The fused engine's one kernel compiles once per machine: Taichi keeps it in its offline cache
(``~/.cache/taichi/ticache``, or ``TI_OFFLINE_CACHE_FILE_PATH``), and this module leaves a
marker beside it once the kernel has run, so that "auto" knows a run will not pay the compile.
A single `ddatai.simulate` of at most ``FUSED_BLOCKS`` free blocks then runs fused; without the
compiled kernel, only a run long enough to pay ``COMPILE_SECONDS`` does. Batches of members
(``ddatai.fused.engine.run``: kgm's bisections and studies) run fused once the kernel is in the
process, or where they are long enough to pay its load or compile (``choose_batch``).
"""

from __future__ import annotations

import hashlib
import os
from pathlib import Path
from typing import Optional

#: "auto" runs a single simulation of at most this many free blocks on the fused engine. Its
#: skyline factorisation grows as n·w² (the envelope w ~2√n blocks on a compact mass), today's
#: path about as n. CPU ms a step, fused against today's (the Taichi kernels and PARDISO above 64
#: blocks), one thread, paired in fresh processes from a sudden start
#: (benchmarks/fused_threshold.py, benchmarks/results/fused_threshold.md): ntdda's grid 3.2 / 25
#: at 64 blocks, 21 / 30 at 144, 28 / 29 at 196, 49 / 43 at 256; a jointed slope 15 / 29 at 146,
#: 40 / 51 at 196, 64 / 67 at 257. The fused step stops paying at ~200 blocks on the grid (a
#: compact mass, the widest envelope for its size), and saves at least ``STEP_SAVING`` up to here
FUSED_BLOCKS = 196
#: the fused kernel's first compile on this project's 2-core CI machine [s] (README, "Performance")
COMPILE_SECONDS = 240.0
#: what a process pays to take the compiled kernel from Taichi's offline cache [s]: Taichi turns
#: the kernel's Python into its IR again (the cache's key, ~1.5 s) and LLVM optimises and makes
#: machine code of the cached module (~7.4 s); 10.0–10.2 s CPU a process at load 1.5–2.5, 12–13
#: at load 4–5 (benchmarks/fused_load.py, benchmarks/results/fused_load.md)
LOAD_SECONDS = 10.0
#: what a step of a single simulation of at most ``FUSED_BLOCKS`` free blocks saves on the fused
#: engine against today's path, at least [s] (benchmarks/results/fused_threshold.md, CPU: 7–50 ms
#: a step at 36–144 blocks, 1.5–10 ms at 196; benchmarks/small_models.py: ~1–3 ms at 1–16 blocks)
STEP_SAVING = 1.0e-3
#: what a step of a single simulation of 36 to 144 free blocks saves at least [s]: the CPU ms a
#: step today's path takes beyond the fused engine's there, the smallest of every measured pair
#: (benchmarks/results/fused_threshold.md: 12.9–21.7 ms on ntdda's grid of 36–64 blocks, 48.5 at
#: 100, 8.6 at 144; 6.7–13.9 on the jointed slope of 41–146), rounded down; outside that band
#: (and above 144 blocks: 1.5 ms at 196) ``STEP_SAVING``. A run loading the kernel from the
#: cache then pays from ``LOAD_SECONDS`` / 5 ms = 2,000 steps, not 10,000
MID_STEP_SAVING = 5.0e-3
MID_BLOCKS = (36, 144)
#: what a member-step of a batch of judgements saves on the fused engine against today's
#: side-by-side batch [s] (the batch shares a step's overhead among its members: ~36 µs a
#: member-step among 128, ~0.17 ms among 16; the settling stage, in NumPy on both, not counted)
BATCH_STEP_SAVING = 5.0e-5

_SOURCES = ("ddatai/fused/arrays.py", "ddatai/fused/blocks.py", "ddatai/fused/contacts.py",
            "ddatai/fused/iterate.py", "ddatai/fused/kernel.py", "ddatai/fused/law.py",
            "ddatai/fused/layout.py", "ddatai/fused/step.py", "ddatai/fused/system.py",
            "ddatai/kernels/common.py", "ddatai/kernels/detection.py")


def cache_dir() -> Path:
    """Taichi's offline-cache directory (where the compiled kernel is kept)."""
    path = os.environ.get("TI_OFFLINE_CACHE_FILE_PATH")
    return Path(path) if path else Path.home() / ".cache" / "taichi" / "ticache"


#: arch -> the marker's digest, taken once a process: reading the kernel's sources and Taichi's
#: package metadata cost ~5 ms, which every launch of a kgm bisection round paid again
_DIGESTS: dict = {}


def _marker(arch: str) -> Path:
    if arch not in _DIGESTS:
        root = Path(__file__).resolve().parents[2]
        digest = hashlib.sha1(arch.encode())
        for name in _SOURCES:
            digest.update((root / name).read_bytes())
        try:
            from importlib.metadata import version

            digest.update(version("taichi").encode())
        except Exception:  # noqa: BLE001 - no metadata: the sources alone key the marker
            pass
        _DIGESTS[arch] = digest.hexdigest()[:16]
    return cache_dir() / f"ddatai-fused-{_DIGESTS[arch]}"


def kernel_cached(arch: str = "cpu") -> bool:
    """Whether the fused kernel of this source has run on this machine (its compiled code is in
    Taichi's offline cache)."""
    try:
        return _marker(arch).exists()
    except OSError:
        return False


def mark_cached(arch: str = "cpu") -> None:
    """Note that the fused kernel has compiled and run (`kernel_cached`)."""
    try:
        path = _marker(arch)
        path.parent.mkdir(parents=True, exist_ok=True)
        path.touch()
    except OSError:
        pass


def choose(model, *, steps: Optional[int], duration: Optional[float], batch: bool = False,
           record_contacts: bool = False, checkpoint: bool = False, resume: bool = False) -> tuple[str, str]:
    """("fused" or today's path's name, why) for a run of ``model`` (``Params.kernels``)."""
    from .pack import covers

    p = model.params
    today = "numpy" if model.numpy_path else "taichi"
    if p.kernels in ("numpy", "taichi"):
        return today, f"Params(kernels={p.kernels!r})"
    why_not = covers(model) or _params_not_covered(p)
    if why_not is None and p.arch not in ("cpu", "cuda", "gpu"):
        why_not = f"the fused engine runs on the CPU or CUDA, not arch={p.arch!r}"
    if why_not is None and (record_contacts or checkpoint or resume):
        why_not = "contacts are recorded, or the run writes or resumes a checkpoint"
    if why_not is not None:
        return today, why_not
    if p.kernels == "fused" or batch:
        return "fused", "Params(kernels='fused')" if p.kernels == "fused" else "a batch of members"
    if model.n_free > FUSED_BLOCKS:
        return today, f"{model.n_free} free blocks, more than the fused engine takes alone ({FUSED_BLOCKS})"
    loaded = _loaded()
    cached = loaded or kernel_cached("cpu" if p.arch == "cpu" else "cuda")
    cost = 0.0 if loaded else LOAD_SECONDS if cached else COMPILE_SECONDS
    dt = p.dt if p.dt is not None else p.dt_max
    expected = steps if steps is not None else (duration / dt if duration is not None else 0)
    if duration is not None and steps is not None:
        expected = min(steps, duration / dt)
    saving = MID_STEP_SAVING if MID_BLOCKS[0] <= model.n_free <= MID_BLOCKS[1] else STEP_SAVING
    if expected * saving >= cost:
        what = "in this process" if loaded else "in Taichi's offline cache" if cached else "not yet compiled"
        return "fused", f"a small model, its run of at least {expected:.0f} steps pays the fused kernel ({what})"
    what = (f"loading the compiled kernel (~{LOAD_SECONDS:.0f} s)" if cached else
            f"the fused kernel's first compile (~{COMPILE_SECONDS:.0f} s; then it is cached)")
    return today, f"a small model, but its {expected:.0f} steps do not pay {what}"


def _params_not_covered(params):
    """Why the fused engine does not run under ``params`` (a sentence), or None: it takes each
    iterate's lever arms, not ``lever_arm_rotation="predicted"`` (docs/method/dda.md §5.3)."""
    if params.lever_arm_rotation != "iterate":
        return (f"Params(lever_arm_rotation={params.lever_arm_rotation!r}): the fused engine takes each "
                f"iterate's lever arms")
    return None


def choose_batch(params, *, member_steps: float) -> tuple[str, str]:
    """("fused" or "today", why) for a batch of judgements (kgm's bisection rounds and studies)
    of about ``member_steps`` steps in all, under ``params`` (``Params.kernels``): "fused" always
    takes the fused engine; "auto" takes it once the kernel is in this process, or where the
    batch's saving pays loading it from Taichi's offline cache (``LOAD_SECONDS``) or, before its
    first compile on this machine, the compile (``COMPILE_SECONDS``); `ddatai.fused.warm`
    compiles it ahead of a session."""
    if params.kernels in ("numpy", "taichi"):
        return "today", f"Params(kernels={params.kernels!r})"
    if params.arch not in ("cpu", "cuda", "gpu"):
        return "today", f"the fused engine runs on the CPU or CUDA, not arch={params.arch!r}"
    if _params_not_covered(params) is not None:
        return "today", _params_not_covered(params)
    if params.kernels == "fused":
        return "fused", "Params(kernels='fused')"
    if _loaded():
        return "fused", "the fused kernel is in this process"
    cached = kernel_cached("cpu" if params.arch == "cpu" else "cuda")
    cost = LOAD_SECONDS if cached else COMPILE_SECONDS
    if member_steps * BATCH_STEP_SAVING >= cost:
        what = "loading it from Taichi's offline cache" if cached else "its first compile"
        return "fused", f"{member_steps:.0f} member-steps pay the fused kernel ({what})"
    what = (f"loading the compiled kernel (~{LOAD_SECONDS:.0f} s)" if cached else
            f"the fused kernel's first compile (~{COMPILE_SECONDS:.0f} s; then it is cached)")
    return "today", f"{member_steps:.0f} member-steps do not pay {what}"


def _loaded() -> bool:
    """Whether the fused kernel has already run in this process (compiled or loaded: free now)."""
    import sys

    engine = sys.modules.get("ddatai.fused.engine")
    return bool(engine is not None and getattr(engine, "LAUNCHED", False))


