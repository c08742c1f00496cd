"""One BLAS thread around the dense solves of small systems.

OpenBLAS (NumPy's and SciPy's) starts a thread per core for a LAPACK factorisation. Beside
Taichi's own threads, which keep spinning for a while after a kernel, the two pools compete for
the cores: on the 2-core CI machine a 64-block model on the kernel path had dense solves of
0.1–1 s in 3 of 12 runs (docs/guide/performance.md, "Thread pools"), and a factorisation of a
few hundred unknowns gains nothing from a second thread. ``one_blas_thread`` limits the BLAS
libraries loaded in the process to one thread for the duration of a solve (threadpoolctl; a
no-op without it) and gives them back their count afterwards.
"""

from __future__ import annotations

from contextlib import contextmanager, nullcontext

_BLAS = None  # the BLAS libraries' controllers (threadpoolctl), found once


def _controllers() -> list:
    global _BLAS
    if _BLAS is None:
        try:
            from threadpoolctl import ThreadpoolController
        except ImportError:  # not installed: nothing to limit
            _BLAS = []
        else:
            _BLAS = [c for c in ThreadpoolController().lib_controllers if c.user_api == "blas"]
    return _BLAS


_DEPTH = 0  # how many blocks are open: inside one, BLAS is limited already


def limited() -> bool:
    """Whether a `one_blas_thread` block is open (a solve inside one need not open its own:
    the equilibrium stage's hundreds of small solves skip the context manager's cost)."""
    return _DEPTH > 0


@contextmanager
def one_blas_thread():
    """BLAS limited to one thread inside the block. A block inside another costs nothing (a
    small model's equilibrium stage opens one around its hundreds of solves, each of which
    opens one: asking each library for its thread count costs ~0.1 ms a solve)."""
    global _DEPTH
    if _DEPTH:
        yield
        return
    held = [(c, c.num_threads) for c in _controllers() if c.num_threads != 1]
    for c, _ in held:
        c.set_num_threads(1)
    _DEPTH += 1
    try:
        yield
    finally:
        _DEPTH -= 1
        for c, n in held:
            c.set_num_threads(n)


def dense_solves(solver):
    """`one_blas_thread` around a stretch of a dense solver's solves (``solver.backend``
    "dense"; another backend's threads are its own): one limit for all of them."""
    return one_blas_thread() if solver.backend == "dense" else nullcontext()
