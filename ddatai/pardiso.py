"""MKL PARDISO called directly through ctypes (`ddatai.solver`'s ``"pardiso"`` backend, the
``[fast]`` extra): where pip put MKL's runtime, one handle per matrix type with every parameter
set by ddatai."""

from __future__ import annotations

import ctypes
import functools
import glob
import os
import site
import sys

import numpy as np


def _locate_mkl() -> None:
    """Tell pypardiso where MKL's runtime is (``PYPARDISO_MKL_RT``) when it sits in this
    environment's own library folder, as pip installs it. pypardiso looks it up by name, which
    fails inside a virtual environment, and then globs the whole environment: 0.6–1.4 s on
    importing pypardiso and again for every solver object it makes. The variable is inherited
    by worker processes started from this one."""
    if os.environ.get("PYPARDISO_MKL_RT"):
        return
    for folder in (os.path.join(sys.prefix, "lib"), os.path.join(site.USER_BASE or "", "lib")):
        found = sorted(glob.glob(os.path.join(folder, "libmkl_rt.so*")) +
                       glob.glob(os.path.join(folder, "libmkl_rt*.dylib")), key=len)
        if found:
            os.environ["PYPARDISO_MKL_RT"] = found[0]
            return


@functools.lru_cache(maxsize=None)
def _mkl_runtime():
    """MKL's runtime library, loaded once per process (through pypardiso, whose call wrapper
    copies the index arrays to one-based ones on every call, so ddatai calls the library
    itself)."""
    _locate_mkl()
    import pypardiso

    return pypardiso.PyPardisoSolver().libmkl


class PardisoError(RuntimeError):
    """MKL PARDISO reported an error (its error code is in the message)."""


class _Pardiso:
    """One MKL PARDISO handle for one matrix type, called directly through ctypes.

    ``mtype`` 2 (real SPD, upper triangle), 1 (real, structurally symmetric: full storage of a
    non-symmetric matrix whose pattern is symmetric, LU on that pattern with diagonal pivots)
    or 11 (real non-symmetric, full storage, with scaling and weighted matching). Every
    parameter is set explicitly with ``iparm[0] = 1``: with ``iparm[0] = 0`` MKL replaces them
    all by its defaults, two steps of iterative refinement on every solve among them (3× the
    cost of the solve at 1,600 blocks, and not bit-reproducible between runs).

    The coupled K of DDA (friction tied to the normal force of the same solve) is 1: a contact
    couples its two blocks both ways, so the pattern is symmetric, and the matrix is the
    symmetric positive definite K plus the small friction terms, so diagonal pivots serve.
    Measured on the project's matrices (``benchmarks/pardiso_levers.py``,
    benchmarks/results/pardiso_levers.md): against 11, the same fill; the analysis 0.43–0.84×
    (no matching on the values), MKL's memory 0.85–0.89×, the numerical factorisation
    0.89–0.98× (no scaling; at 38,400 unknowns and more within the ±7 % noise of the shared
    machine), no pivot perturbed on the slopes and grids, the residual the same; at 102,400
    blocks the LU with its analysis 26.3 → 20.0 s CPU and the step's peak 7.18 → 6.93 GB. The other
    levers measured there did not pay: MKL's block formats (the analysis 6–15× faster, the
    factorisation 0.9–1.14×), the two-level factorisation (0.84–1.07×: noise), parallel METIS
    (which gives up reproducibility), METIS's ``10·L + 2`` optimisation levels and the solve's
    parallel modes.
    """

    def __init__(self, mtype: int):
        mkl = _mkl_runtime()
        self._lib = mkl.pardiso
        self.mtype = mtype
        self.pt = np.zeros(64, dtype=np.int64)
        self.iparm = np.zeros(64, dtype=np.int32)
        ip = self.iparm  # zero-based here; MKL's documentation numbers them from 1
        ip[0] = 1        # use the values below, not MKL's defaults
        ip[1] = 2        # fill-reducing ordering: METIS nested dissection
        ip[7] = 0        # no iterative refinement (a residual check below asks for it)
        ip[9] = 8 if mtype == 2 else 13  # pivot perturbation 1e-8 / 1e-13 (MKL's defaults)
        ip[10] = 1 if mtype == 11 else 0  # scaling (the general non-symmetric solver only)
        ip[12] = 1 if mtype == 11 else 0  # weighted matching (the general non-symmetric solver only)
        ip[34] = 1       # zero-based ia/ja
        # conditional numerical reproducibility: the same factor, bit for bit, on every run with
        # this many threads (MKL's threads otherwise sum in varying order: two runs of a
        # 400-block slope differed by 5e-13 m after 30 steps, and a chaotic scene then takes
        # another path); it costs nothing measurable at 1,600 blocks
        ip[33] = max(1, int(mkl.MKL_Get_Max_Threads()))
        self.perm = np.zeros(0, dtype=np.int32)
        self.key = None  # (indptr, indices) the current analysis belongs to
        self.n = 0
        self.factored = False  # whether the handle holds a numerical factor

    def call(self, phase: int, data: np.ndarray, indptr: np.ndarray, indices: np.ndarray,
             rhs: np.ndarray) -> np.ndarray:
        n = len(indptr) - 1
        x = np.zeros_like(rhs)  # (n,) or (nrhs, n): the right-hand sides one after another (column-major n × nrhs)
        nrhs = rhs.shape[0] if rhs.ndim == 2 else 1
        err = ctypes.c_int32(0)
        i32 = ctypes.POINTER(ctypes.c_int32)
        f64 = ctypes.POINTER(ctypes.c_double)
        self._lib(self.pt.ctypes.data_as(ctypes.POINTER(ctypes.c_int64)), ctypes.byref(ctypes.c_int32(1)),
                  ctypes.byref(ctypes.c_int32(1)), ctypes.byref(ctypes.c_int32(self.mtype)),
                  ctypes.byref(ctypes.c_int32(phase)), ctypes.byref(ctypes.c_int32(n)),
                  data.ctypes.data_as(f64), indptr.ctypes.data_as(i32), indices.ctypes.data_as(i32),
                  self.perm.ctypes.data_as(i32), ctypes.byref(ctypes.c_int32(nrhs)),
                  self.iparm.ctypes.data_as(i32), ctypes.byref(ctypes.c_int32(0)),
                  rhs.ctypes.data_as(f64), x.ctypes.data_as(f64), ctypes.byref(err))
        if err.value != 0:
            raise PardisoError(f"MKL PARDISO error {err.value} in phase {phase}")
        if phase in (12, 13, 22, 23):
            self.factored = True
        return x

    def release(self) -> None:
        if self.key is not None:
            dummy = np.zeros(1)
            try:
                self.call(-1, dummy, np.zeros(self.n + 1, np.int32), np.zeros(1, np.int32), np.zeros(self.n))
            except PardisoError:
                pass
            self.key = None
            self.factored = False

    def release_factor(self) -> None:
        """Free the numerical factor (MKL's phase 0) and keep the analysis: the next
        factorisation of the same structure (phase 23) needs no new ordering and gives the same
        factor, bit for bit."""
        if self.key is not None and self.factored:
            dummy = np.zeros(1)
            self.call(0, dummy, np.zeros(self.n + 1, np.int32), np.zeros(1, np.int32), np.zeros(self.n))
            self.factored = False

    @property
    def perturbed_pivots(self) -> int:
        """Pivots perturbed in the last factorisation (MKL's iparm(14))."""
        return int(self.iparm[13])

    @property
    def refinement_steps(self) -> int:
        """Iterative refinement steps MKL performed in the last solve (MKL's iparm(7))."""
        return int(self.iparm[6])


def _upper_triangle(indptr: np.ndarray, indices: np.ndarray, n: int) -> tuple:
    """((indptr, indices), positions of the upper triangle's entries in the CSR data, its
    indptr, its indices): what PARDISO reads of a symmetric K. In a function of its own so that
    its temporaries (the row of every entry) are gone before the factorisation; rows and
    positions as int32 where they fit (0.26 GB each as int64 at 102,400 blocks; a take with
    int32 positions gives the same values)."""
    small = len(indices) < 2**31
    rows = np.repeat(np.arange(n, dtype=np.int32 if small else np.int64), np.diff(indptr))
    mask = indices >= rows
    counts = np.bincount(rows[mask], minlength=n)
    del rows
    upper_indptr = np.concatenate([[0], np.cumsum(counts)]).astype(np.int32)
    # positions, not a boolean mask: a take is ~10x faster than boolean indexing
    pos = np.flatnonzero(mask)
    if small:
        pos = pos.astype(np.int32)
    return (indptr, indices), pos, upper_indptr, np.ascontiguousarray(indices[mask], dtype=np.int32)


def symmetric_pattern(indptr: np.ndarray, indices: np.ndarray, n: int) -> bool:
    """Whether the CSR pattern is symmetric (what PARDISO's matrix type 1 needs)."""
    from scipy.sparse import csr_matrix

    k = csr_matrix((np.ones(len(indices)), indices, indptr), shape=(n, n))
    return (k != k.T).nnz == 0
