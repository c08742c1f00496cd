"""Dense factorisations of small systems by LAPACK, called directly.

``scipy.linalg.cho_factor``/``cho_solve`` and ``lu_factor``/``lu_solve`` check and convert
their arguments and, since SciPy 1.15, dispatch over batches of matrices: ~40–100 µs a call
that a factorisation of a few blocks' 6n rows does not take (the equilibrium stage of a
two-block group solves tens of such systems, its limit-equilibrium program tens more).
These call the same LAPACK routines (dpotrf/dpotrs, dgetrf/dgetrs) with the same arguments
as those functions do for a float64 matrix, so the floats are theirs; the errors are too.
"""

from __future__ import annotations

import numpy as np
from scipy.linalg.lapack import dgetrf, dgetrs, dpotrf, dpotrs  # this module loads on a first solve


class Cholesky:
    """K = UᵀU of a symmetric positive definite float64 K (upper factor, as ``cho_factor``'s
    default); ``numpy.linalg.LinAlgError`` where K is not positive definite."""

    def __init__(self, k: np.ndarray):
        self.factor, info = dpotrf(k, lower=False, clean=False, overwrite_a=False)
        if info > 0:
            raise np.linalg.LinAlgError(f"{info}-th leading minor of the array is not positive definite")
        if info < 0:
            raise ValueError(f'LAPACK reported an illegal value in {-info}-th argument on entry to "POTRF".')

    def solve(self, rhs: np.ndarray) -> np.ndarray:
        x, info = dpotrs(self.factor, rhs, lower=False, overwrite_b=False)
        if info != 0:
            raise ValueError(f"illegal value in {-info}th argument of internal potrs")
        return x


class LU:
    """PK = LU with partial pivoting of a float64 K (``lu_factor``); ``singular``: a zero on U's
    diagonal (where ``lu_factor`` warns)."""

    def __init__(self, k: np.ndarray):
        self.lu, self.piv, info = dgetrf(k, overwrite_a=False)
        if info < 0:
            raise ValueError(f"illegal value in {-info}th argument of internal getrf (lu_factor)")
        self.singular = info > 0

    def solve(self, rhs: np.ndarray) -> np.ndarray:
        x, info = dgetrs(self.lu, self.piv, rhs, trans=0, overwrite_b=False)
        if info != 0:
            raise ValueError(f"illegal value in {-info}th argument of internal gesv|posv")
        return x
