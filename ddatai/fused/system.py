"""The linear system of one member in the fused engine (Taichi functions): the contact springs
and friction of the assumed states (``ddatai.kernels.assembly.assemble_contacts``, §2.8), and a
factorisation that follows the system's block structure.

K is stored in a dense n × n slab (n = 6 × the free blocks) but only its *envelope* is touched:
row i of block-row r holds entries from column 6·env[r] on, env[r] being the first block-row
coupled to r by a contact of the step (the rows are the free blocks in a bandwidth-reducing
order chosen when the member is packed). The lower triangle and the diagonal lie row by row,
the upper triangle column by column (``at``), so that both sides of every inner product of the
factorisation and the triangular solves lie contiguous in memory (with the columns of U strided
by n, the factorisation was ~80 % of a 64-block step;
benchmarks/results/small_models_fused_factor.md). The factorisation is Doolittle's LU without pivoting on that
profile (a skyline solver, as Shi's block LDLᵀ), six rows of a block-row at a time: where K is symmetric (no sliding contact takes
its friction from the same solve) the upper factor is D·Lᵀ and the second inner product is
skipped (the cost of a Cholesky). Its work is n·w² for an envelope w wide instead of n³/3 (a
16-block grid: w ≈ 30 unknowns of 96). K is symmetric positive definite in the symmetric case
and a small non-symmetric perturbation of one otherwise (the friction slope μ·p beside the
inertia and the penalty springs), so no pivoting is needed; a zero or non-finite pivot makes
the solution non-finite, and the step is cut as for a singular K on
today's path.
"""


import taichi as ti

from ..kernels.common import E0, ES, G0, GS
from .layout import (BI_ROW, BW_SOL, CF_COH, CF_LEN, CF_NF, CF_SCA, CF_SHIFT, CF_TAN, CI_BOND, CI_COUPLED,
                     CI_DIR, CI_KIND, CI_LINE, CI_STATE, MF_PENALTY, MF_SHEAR, MI_B0, MI_B1, MI_C0, MI_K0,
                     MI_NC, MI_NF, MI_R0, MI_X0, XS_F0, XS_RHS, XS_Y)

VE = 0
OPEN = 0
SLIDE = 1
LOCK = 2


@ti.func
def first(E: ti.template(), m, i):
    """First column of row i in the envelope."""
    return 6 * E.env[E.mi[m, MI_R0] + i // 6]


@ti.func
def row_at(E: ti.template(), m, i):
    """Where row i of the lower triangle starts in member m's slab: entry (i, q), q ≤ i, is at
    ``row_at(i) + q``."""
    return E.mi[m, MI_K0] + i * 6 * E.mi[m, MI_NF]


@ti.func
def column_at(E: ti.template(), m, j):
    """Where column j of the upper triangle starts: entry (q, j), q < j, is at
    ``column_at(j) + q`` (in the upper part of row n − 1 − j, from column n − j)."""
    n = 6 * E.mi[m, MI_NF]
    return E.mi[m, MI_K0] + (n - 1 - j) * n + n - j


@ti.func
def at(E: ti.template(), m, i, j):
    """Position of K's entry (i, j) in member m's slab (K0's: n² further on)."""
    out = row_at(E, m, i) + j
    if i < j:
        out = column_at(E, m, j) + i
    return out


@ti.func
def clear_block_terms(E: ti.template(), m):
    """Zero K0 (in the envelope) and F0 before the block terms of a try are added."""
    n = 6 * E.mi[m, MI_NF]
    k0 = n * n
    for i in range(n):
        row = row_at(E, m, i) + k0
        column = column_at(E, m, i) + k0
        for j in range(first(E, m, i), i):
            E.kmat[row + j] = 0.0
            E.kmat[column + j] = 0.0
        E.kmat[row + i] = 0.0
        E.xvec[E.mi[m, MI_X0] + XS_F0 * n + i] = 0.0


@ti.func
def load_block_terms(E: ti.template(), m):
    """K = K0 and F = F0 (in the envelope): each solve of the iteration starts from them."""
    n = 6 * E.mi[m, MI_NF]
    k0 = n * n
    for i in range(n):
        row = row_at(E, m, i)
        column = column_at(E, m, i)
        for j in range(first(E, m, i), i):
            E.kmat[row + j] = E.kmat[row + j + k0]
            E.kmat[column + j] = E.kmat[column + j + k0]
        E.kmat[row + i] = E.kmat[row + i + k0]
        E.xvec[E.mi[m, MI_X0] + XS_RHS * n + i] = E.xvec[E.mi[m, MI_X0] + XS_F0 * n + i]


@ti.func
def _outer_rows(E: ti.template(), m, c, s, t_own, t_other, k, s2, t2_own, t2_other, k2, r, r_other):
    """k·vec[c, s]·vec[c, t_own]ᵀ, then k2·vec[c, s2]·vec[c, t2_own]ᵀ, into block (r, r), and the
    same with t_other and t2_other into block (r, r_other) if both blocks are free
    (`kernels.assembly._outer_rows`, a contact's two rank-one terms in one pass: each entry
    takes the first term's addition, then the second's, as two passes would; k2 = 0 adds
    nothing). The slab's places of a block's row are found once (``at``, along a row of L: +1
    a column; along the row of U: −(n + 1) a column), not entry by entry."""
    if r >= 0:
        n = 6 * E.mi[m, MI_NF]
        k_base = E.mi[m, MI_K0]
        for side in range(2):
            col_block = r
            t = t_own
            t2 = t2_own
            if side == 1:
                col_block = r_other
                t = t_other
                t2 = t2_other
            if col_block >= 0:
                j0 = 6 * col_block
                for a in range(6):
                    va = k * E.cvec[c, 6 * s + a]
                    va2 = k2 * E.cvec[c, 6 * s2 + a]
                    i = 6 * r + a
                    lower = k_base + i * n + j0                        # at(i, j0 + b) = lower + b, j ≤ i
                    upper = k_base + (n - 1 - j0) * n + n - j0 + i      # at(i, j0 + b) = upper − b(n + 1), j > i
                    for b in range(6):
                        place = lower + b
                        if i < j0 + b:
                            place = upper - b * (n + 1)
                        E.kmat[place] = (E.kmat[place] + va * E.cvec[c, 6 * t + b]) + va2 * E.cvec[c, 6 * t2 + b]


@ti.func
def _force(E: ti.template(), m, c, su, sw, f, ri, rj):
    """f·vec[c, su] on the rows of block ri, f·vec[c, sw] on those of rj (free blocks only)."""
    rhs = E.mi[m, MI_X0] + XS_RHS * 6 * E.mi[m, MI_NF]
    for a in range(6):
        if ri >= 0:
            E.xvec[rhs + 6 * ri + a] += f * E.cvec[c, 6 * su + a]
        if rj >= 0:
            E.xvec[rhs + 6 * rj + a] += f * E.cvec[c, 6 * sw + a]


@ti.func
def contact_terms(E: ti.template(), m):
    """The normal spring of every closed contact on its active line, the shear spring of a
    locked vertex-edge contact, the friction of a sliding one (with its non-symmetric term
    when coupled to this solve's normal force), §2.8, in the order of
    `kernels.assembly.assemble_contacts`; a contact's springs in one pass over its blocks
    (`_outer_rows`). Returns whether K stays symmetric."""
    p = E.mf[m, MF_PENALTY]
    ks = E.mf[m, MF_SHEAR]
    symmetric = 1
    base = E.mi[m, MI_C0]
    for c in range(base, base + E.mi[m, MI_NC]):
        st = E.cint[c, CI_STATE]
        if st != OPEN:
            q = E.cint[c, CI_LINE]
            ri = E.bint[E.vblock[E.cint[c, 1 + 2 * q]], BI_ROW]
            rj = E.bint[E.vblock[E.cint[c, 2 + 2 * q]], BI_ROW]
            ve = E.cint[c, CI_KIND] == VE
            tan = E.cf[c, CF_TAN]
            cohesion = E.cf[c, CF_COH] * E.cf[c, CF_LEN] * ti.cast(E.cint[c, CI_BOND], ti.f64)
            const = E.cf[c, CF_NF] * tan + cohesion
            slope = 0.0
            if E.cint[c, CI_COUPLED] != 0:
                const = cohesion
                slope = p * tan
            sgn = ti.cast(E.cint[c, CI_DIR], ti.f64)
            # the normal spring of the active line; then, of a vertex-edge contact, the shear
            # spring of a locked one (k2 = k_s), or the friction of a sliding one (internal
            # force sgn·S(D)·∇ds with S = a − b·(dn0 + ∇dnᵀD)) and, coupled, its term
            # −sgn·b·∇ds ∇dnᵀ (k2, against the normal's vectors); the springs in one pass
            su = E0 + 2 * q
            sw = G0 + 2 * q
            f_normal = -p * (E.cf[c, CF_SCA + q] + E.cf[c, CF_SHIFT + q])
            t2u = ES
            t2w = GS
            k2 = 0.0
            f_shear = 0.0
            if ve:
                if st == LOCK:
                    k2 = ks
                    f_shear = -ks * (E.cf[c, CF_SCA + 2] + E.cf[c, CF_SHIFT + 2])
                else:
                    f_shear = -sgn * (const - slope * (E.cf[c, CF_SCA] + E.cf[c, CF_SHIFT]))
                    if st == SLIDE and slope != 0.0:
                        t2u = E0
                        t2w = G0
                        k2 = -sgn * slope
                        symmetric = 0
            if p != 0.0 or k2 != 0.0:
                _outer_rows(E, m, c, su, su, sw, p, ES, t2u, t2w, k2, ri, rj)
                _outer_rows(E, m, c, sw, sw, su, p, GS, t2w, t2u, k2, rj, ri)
            for term in range(2):
                fu = su
                fw = sw
                f = f_normal
                if term == 1:
                    fu = ES
                    fw = GS
                    f = f_shear
                if term == 0 or ve:
                    _force(E, m, c, fu, fw, f, ri, rj)
    return symmetric


@ti.func
def factor(E: ti.template(), m, symmetric):
    """Doolittle LU of K in place on its envelope (module docstring), a block-row of six rows at
    a time: left of its diagonal block, each column j of the six rows of L (against column j of
    U) and, where K is not symmetric, of the six columns of U (against row j of L) in one pass
    over the inner products' range (the six rows share their envelope), then the diagonal block
    row by row. Returns 1, or 0 where a pivot is zero or not finite."""
    n = 6 * E.mi[m, MI_NF]
    ok = 1
    for R in range(n // 6):
        i0 = 6 * R
        fk = first(E, m, i0)
        r0 = row_at(E, m, i0)        # row i0 + a of L at r0 + a·n
        c0 = column_at(E, m, i0)     # column i0 + a of U at c0 − a·(n + 1)
        for j in range(fk, i0):
            lo = ti.max(fk, first(E, m, j))
            column_j = column_at(E, m, j)
            sl = ti.Vector([E.kmat[r0 + a * n + j] for a in ti.static(range(6))])
            for q in range(lo, j):
                u = E.kmat[column_j + q]
                for a in ti.static(range(6)):
                    sl[a] -= E.kmat[r0 + a * n + q] * u
            row_j = row_at(E, m, j)
            if symmetric:
                for a in ti.static(range(6)):
                    E.kmat[c0 - a * (n + 1) + j] = sl[a]
            else:
                su = ti.Vector([E.kmat[c0 - a * (n + 1) + j] for a in ti.static(range(6))])
                for q in range(lo, j):
                    v = E.kmat[row_j + q]
                    for a in ti.static(range(6)):
                        su[a] -= v * E.kmat[c0 - a * (n + 1) + q]
                for a in ti.static(range(6)):
                    E.kmat[c0 - a * (n + 1) + j] = su[a]
            pivot = E.kmat[row_j + j]
            for a in ti.static(range(6)):
                E.kmat[r0 + a * n + j] = sl[a] / pivot
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
    """x = U⁻¹L⁻¹F with the factor in K, into the blocks' ``BW_SOL`` (zero for fixed blocks).
    Returns whether x is finite."""
    nf = E.mi[m, MI_NF]
    n = 6 * nf
    rhs = E.mi[m, MI_X0] + XS_RHS * n
    y = E.mi[m, MI_X0] + XS_Y * n
    for i in range(n):
        s = E.xvec[rhs + i]
        row = row_at(E, m, i)
        for q in range(first(E, m, i), i):
            s -= E.kmat[row + q] * E.xvec[y + q]
        E.xvec[y + i] = s
    for jj in range(n):
        j = n - 1 - jj
        xj = E.xvec[y + j] / E.kmat[row_at(E, m, j) + j]
        E.xvec[y + j] = xj
        column = column_at(E, m, j)
        for q in range(first(E, m, j), j):
            E.xvec[y + q] -= E.kmat[column + q] * xj
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
def _gather(E: ti.template(), m, col):
    """The iterate in ``bwork[:, col:col+6]`` in the system's row order, into the triangular
    solves' scratch (free between solves). Returns where it starts."""
    n = 6 * E.mi[m, MI_NF]
    x = E.mi[m, MI_X0] + XS_Y * n
    r0 = E.mi[m, MI_R0]
    for r in range(n // 6):
        b = E.rblock[r0 + r]
        for a in range(6):
            E.xvec[x + 6 * r + a] = E.bwork[b, col + a]
    return x


@ti.func
def block_energy(E: ti.template(), m, col, brhs):
    """½·xᵀK0x − F_blocksᵀx of the iterate in ``bwork[:, col:col+6]`` (the line search's
    energy without the contact springs; K0 symmetric, its envelope that of K)."""
    nf = E.mi[m, MI_NF]
    n = 6 * nf
    k0 = n * n
    quad = 0.0
    lin = 0.0
    x = _gather(E, m, col)
    for i in range(n):
        xi = E.xvec[x + i]
        row = 0.0
        at_i = row_at(E, m, i) + k0
        for j in range(first(E, m, i), i):
            row += E.kmat[at_i + j] * E.xvec[x + j]
        quad += xi * (2.0 * row + E.kmat[at_i + i] * xi)
        lin += E.xvec[brhs + i] * xi
    return 0.5 * quad - lin


@ti.func
def block_gradient(E: ti.template(), m, col, brhs, out):
    """K0·x − F_blocks of the iterate in ``bwork[:, col:col+6]`` into ``xvec[out:out+n]``."""
    nf = E.mi[m, MI_NF]
    n = 6 * nf
    k0 = n * n
    x = _gather(E, m, col)
    for i in range(n):
        E.xvec[out + i] = -E.xvec[brhs + i]
    for i in range(n):
        xi = E.xvec[x + i]
        at_i = row_at(E, m, i) + k0
        for j in range(first(E, m, i), i + 1):
            kij = E.kmat[at_i + j]
            E.xvec[out + i] += kij * E.xvec[x + j]
            if j < i:
                E.xvec[out + j] += kij * xi
