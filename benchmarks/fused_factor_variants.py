"""Candidate rewrites of ``ddatai.fused.system.factor``, ``solve`` and ``block_gradient`` (Taichi
functions) for `benchmarks/fused_factor_probe.py`: every entry's subtractions written in the same
order as today's (the compiled rounding is not bit for bit today's: Taichi's fast math), measured
faster alone and not landed (benchmarks/results/small_models_fused_step.md): the factor two
columns at a time, the triangular solves a block-row at a time, the gradient's row sum in a
register."""

import taichi as ti

from ddatai.fused.layout import BI_ROW, BW_SOL, MI_B0, MI_B1, MI_NF, MI_X0, XS_RHS, XS_Y
from ddatai.fused.system import _gather, column_at, first, row_at


@ti.func
def factor(E: ti.template(), m, symmetric):
    """Doolittle LU of K in place on its envelope (module docstring), a block-row of six rows at
    a time: left of its diagonal block, each pair of columns j, j + 1 of the six rows of L
    (against columns j, j + 1 of U) and, where K is not symmetric, of the six columns of U
    (against rows j, j + 1 of L) in one pass over the inner products' range (the six rows share
    their envelope), then the diagonal block row by row. Returns 1, or 0 where a pivot is zero or not finite."""
    n = 6 * E.mi[m, MI_NF]
    ok = 1
    for R in range(n // 6):
        i0 = 6 * R
        fk = first(E, m, i0)
        r0 = row_at(E, m, i0)        # row i0 + a of L at r0 + a·n
        c0 = column_at(E, m, i0)     # column i0 + a of U at c0 − a·(n + 1)
        # two columns j, j + 1 of a block-column at a time (the same range of inner products
        # up to q = j − 1: the loads of L's six rows, or of U's six columns, shared, twelve
        # independent sums); column j + 1's term q = j once column j is final. Every entry's
        # subtractions are written in the order of q, as one column at a time; the compiled
        # rounding is not bit for bit that of one column at a time
        # (benchmarks/results/small_models_fused_step.md)
        for jp in range((i0 - fk) // 2):
            j = fk + 2 * jp
            lo = ti.max(fk, first(E, m, j))
            column_j = column_at(E, m, j)
            column_j1 = column_j - (n + 1)
            sl = ti.Vector([E.kmat[r0 + a * n + j] for a in ti.static(range(6))])
            sl1 = ti.Vector([E.kmat[r0 + a * n + j + 1] for a in ti.static(range(6))])
            for q in range(lo, j):
                u = E.kmat[column_j + q]
                u1 = E.kmat[column_j1 + q]
                for a in ti.static(range(6)):
                    lq = E.kmat[r0 + a * n + q]
                    sl[a] -= lq * u
                    sl1[a] -= lq * u1
            row_j = row_at(E, m, j)
            row_j1 = row_j + n
            su = sl
            su1 = sl1
            if not symmetric:
                su = ti.Vector([E.kmat[c0 - a * (n + 1) + j] for a in ti.static(range(6))])
                su1 = ti.Vector([E.kmat[c0 - a * (n + 1) + j + 1] for a in ti.static(range(6))])
                for q in range(lo, j):
                    v = E.kmat[row_j + q]
                    v1 = E.kmat[row_j1 + q]
                    for a in ti.static(range(6)):
                        w = E.kmat[c0 - a * (n + 1) + q]
                        su[a] -= v * w
                        su1[a] -= v1 * w
            pivot = E.kmat[row_j + j]
            lj = ti.Vector([0.0] * 6)
            for a in ti.static(range(6)):
                E.kmat[c0 - a * (n + 1) + j] = su[a]
                lj[a] = sl[a] / pivot
                E.kmat[r0 + a * n + j] = lj[a]
            u1 = E.kmat[column_j1 + j]
            for a in ti.static(range(6)):
                sl1[a] -= lj[a] * u1
            if symmetric:
                su1 = sl1
            else:
                v1 = E.kmat[row_j1 + j]
                for a in ti.static(range(6)):
                    su1[a] -= v1 * su[a]
            pivot1 = E.kmat[row_j1 + j + 1]
            for a in ti.static(range(6)):
                E.kmat[c0 - a * (n + 1) + j + 1] = su1[a]
                E.kmat[r0 + a * n + j + 1] = sl1[a] / pivot1
        for k in range(i0, i0 + 6):
            row_k = row_at(E, m, k)
            column_k = column_at(E, m, k)
            for j in range(i0, k):
                row_j = row_at(E, m, j)
                sl = E.kmat[row_k + j]
                column_j = column_at(E, m, j)
                for q in range(fk, j):
                    sl -= E.kmat[row_k + q] * E.kmat[column_j + q]
                if symmetric:
                    E.kmat[column_k + j] = sl
                else:
                    su = E.kmat[column_k + j]
                    for q in range(fk, j):
                        su -= E.kmat[row_j + q] * E.kmat[column_k + q]
                    E.kmat[column_k + j] = su
                E.kmat[row_k + j] = sl / E.kmat[row_j + j]
            d = E.kmat[row_k + k]
            for q in range(fk, k):
                d -= E.kmat[row_k + q] * E.kmat[column_k + q]
            E.kmat[row_k + k] = d
            if not (d != 0.0 and ti.abs(d) < 1e300):
                ok = 0
    return ok


@ti.func
def solve(E: ti.template(), m):
    nf = E.mi[m, MI_NF]
    n = 6 * nf
    rhs = E.mi[m, MI_X0] + XS_RHS * n
    y = E.mi[m, MI_X0] + XS_Y * n
    # forward: a block-row's six rows at once over the columns left of its diagonal block
    for R in range(nf):
        i0 = 6 * R
        r0 = row_at(E, m, i0)
        s = ti.Vector([E.xvec[rhs + i0 + a] for a in ti.static(range(6))])
        for q in range(first(E, m, i0), i0):
            yq = E.xvec[y + q]
            for a in ti.static(range(6)):
                s[a] -= E.kmat[r0 + a * n + q] * yq
        for a in ti.static(range(6)):
            v = s[a]
            for b in ti.static(range(a)):
                v -= E.kmat[r0 + a * n + i0 + b] * E.xvec[y + i0 + b]
            E.xvec[y + i0 + a] = v
    # backward: a block-row's six columns, then their updates of the rows above it in one pass
    for RR in range(nf):
        i0 = 6 * (nf - 1 - RR)
        c0 = column_at(E, m, i0)     # column i0 + a of U at c0 − a·(n + 1)
        for a in ti.static(range(5, -1, -1)):
            j = i0 + a
            xj = E.xvec[y + j] / E.kmat[row_at(E, m, j) + j]
            E.xvec[y + j] = xj
            for b in ti.static(range(a)):
                E.xvec[y + i0 + b] -= E.kmat[c0 - a * (n + 1) + i0 + b] * xj
        x = ti.Vector([E.xvec[y + i0 + a] for a in ti.static(range(6))])
        for q in range(first(E, m, i0), i0):
            v = E.xvec[y + q]
            for a in ti.static(range(5, -1, -1)):
                v -= E.kmat[c0 - a * (n + 1) + q] * x[a]
            E.xvec[y + q] = v
    finite = 1
    for b in range(E.mi[m, MI_B0], E.mi[m, MI_B1]):
        r = E.bint[b, BI_ROW]
        for a in range(6):
            v = 0.0
            if r >= 0:
                v = E.xvec[y + 6 * r + a]
                if not (ti.abs(v) < 1e300):
                    finite = 0
            E.bwork[b, BW_SOL + a] = v
    return finite


@ti.func
def block_gradient(E: ti.template(), m, col, brhs, out):
    """``system.block_gradient`` with row i's sum in a register (the same additions in the same
    order: the rows above have added their terms to out[i] before row i starts)."""
    nf = E.mi[m, MI_NF]
    n = 6 * nf
    k0 = n * n
    x = _gather(E, m, col)
    for i in range(n):
        E.xvec[out + i] = -E.xvec[brhs + i]
    for i in range(n):
        xi = E.xvec[x + i]
        at_i = row_at(E, m, i) + k0
        s = E.xvec[out + i]
        for j in range(first(E, m, i), i):
            kij = E.kmat[at_i + j]
            s += kij * E.xvec[x + j]
            E.xvec[out + j] += kij * xi
        E.xvec[out + i] = s + E.kmat[at_i + i] * xi
