"""Example II's scene script (scenes/example_2.py) with the equilibrium stage as it ran before
its limit-equilibrium screen: the A of benchmarks/small_models.py's paired study.

Loading this script (each of a study's worker processes loads its scene script) sets, in that
process, the stage's code paths of the commit before the screen: ``ddatai.start.settle`` with
``screen=False`` (the return mapping alone), every limit-equilibrium program solved each time it
is asked (no answer kept), and the dense factorisations through ``scipy.linalg.cho_factor``,
``cho_solve``, ``lu_factor`` and ``lu_solve`` (the same floats as `ddatai.dense`, with SciPy's
checks). Why not a checkout of that commit: Taichi's offline cache keys the fused kernel by its
source files' paths, so a second checkout compiles it again (minutes on 2 cores).
"""

import sys
from pathlib import Path

from scipy.linalg import cho_factor, cho_solve, lu_factor, lu_solve

import ddatai.dense as dense
import ddatai.limit_equilibrium as limit_equilibrium
import ddatai.start as start

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from scenes.example_2 import DURATION, build  # noqa: E402,F401


class _Cholesky:
    def __init__(self, k):
        self.factor = cho_factor(k, lower=False, overwrite_a=False, check_finite=False)

    def solve(self, rhs):
        return cho_solve(self.factor, rhs, check_finite=False)


class _LU:
    def __init__(self, k):
        import warnings

        from scipy.linalg import LinAlgWarning

        with warnings.catch_warnings():
            warnings.simplefilter("ignore", LinAlgWarning)
            self.lu, self.piv = self.factor = lu_factor(k, check_finite=False)
        self.singular = False  # as before: a zero on U's diagonal is found by the caller

    def solve(self, rhs):
        return lu_solve(self.factor, rhs, check_finite=False)


if not getattr(start, "_AS_BEFORE", False):
    _settle = start.settle

    def _settle_before(stepper, state, welded=False, screen=True):
        return _settle(stepper, state, welded=welded, screen=False)

    start.settle, start._AS_BEFORE = _settle_before, True
    limit_equilibrium._interior_point = limit_equilibrium._solve_program
    dense.Cholesky, dense.LU = _Cholesky, _LU
