"""Per-block work of the fused engine (Taichi functions): polygon integrals (docs/method/dda.md
§1.2), the mass matrix (§1.3), the displacement of a material point with the exact rotation
(§5.3), the block terms of K and F (§2.1–2.6) and the update of a block after a step (§5.2,
§5.4). Each is the per-block loop body of its NumPy twin (``ddatai.geometry.polygon_integrals``,
``ddatai.geometry.mass_matrix``, ``ddatai.kinematics.move_points``, ``ddatai.assembly.assemble_blocks``,
``ddatai.kinematics.update``), in the same order of operations where the twin has one."""


import taichi as ti

from ..kernels.common import _trow
from .layout import (BG_AREA, BG_CX, BG_CY, BG_S1, BG_S2, BG_S3, BI_ROW, BI_V0, BI_V1, BM_C, BM_CINV,
                     BM_RHO, BS_ACC, BS_STRESS, BS_VEL, MF_CARRY, MF_FIXED_PEN, MF_GX, MF_GY, MI_NF,
                     MI_P0, MI_P1, MI_R0, MI_X0, PF_FX, PF_FY, PF_X, PF_X0, PF_Y, PF_Y0, PI_BLOCK, PI_KIND,
                     POINT_FIXED, POINT_LOAD, XS_F0)
from .system import at


@ti.func
def geometry(E: ti.template(), b):
    """Area, centroid and central moments of block b at ``vxy`` into ``bgeo`` (sums relative
    to its first vertex, as `ddatai.geometry.polygon_integrals`)."""
    v0 = E.bint[b, BI_V0]
    ox = E.vxy[v0, 0]
    oy = E.vxy[v0, 1]
    s = 0.0
    sx = 0.0
    sy = 0.0
    sxx = 0.0
    syy = 0.0
    sxy = 0.0
    for k in range(v0, E.bint[b, BI_V1]):
        n = E.vnext[k]
        x1 = E.vxy[k, 0] - ox
        y1 = E.vxy[k, 1] - oy
        x2 = E.vxy[n, 0] - ox
        y2 = E.vxy[n, 1] - oy
        f = x1 * y2 - x2 * y1
        s += f
        sx += f * (x1 + x2)
        sy += f * (y1 + y2)
        sxx += f * (x1 * x1 + x1 * x2 + x2 * x2)
        syy += f * (y1 * y1 + y1 * y2 + y2 * y2)
        sxy += f * (2 * x1 * y1 + x1 * y2 + x2 * y1 + 2 * x2 * y2)
    s = s / 2.0
    sx = sx / 6.0
    sy = sy / 6.0
    sxx = sxx / 12.0
    syy = syy / 12.0
    sxy = sxy / 24.0
    xc = sx / s
    yc = sy / s
    E.bgeo[b, BG_AREA] = s
    E.bgeo[b, BG_CX] = ox + xc
    E.bgeo[b, BG_CY] = oy + yc
    E.bgeo[b, BG_S1] = sxx - xc * sx
    E.bgeo[b, BG_S2] = syy - yc * sy
    E.bgeo[b, BG_S3] = sxy - xc * sy


@ti.func
def radius(E: ti.template(), b):
    """Largest distance of block b's vertices from its centroid [m] (`kinematics.block_radius`)."""
    r = 0.0
    for k in range(E.bint[b, BI_V0], E.bint[b, BI_V1]):
        r = ti.max(r, ti.sqrt((E.vxy[k, 0] - E.bgeo[b, BG_CX]) ** 2 + (E.vxy[k, 1] - E.bgeo[b, BG_CY]) ** 2))
    return r


@ti.func
def mass(E: ti.template(), b):
    """M = ∫TᵀT dA of block b (docs/method/dda.md §1.3; × ρ for the mass)."""
    s = E.bgeo[b, BG_AREA]
    s1 = E.bgeo[b, BG_S1]
    s2 = E.bgeo[b, BG_S2]
    s3 = E.bgeo[b, BG_S3]
    M = ti.Matrix.zero(ti.f64, 6, 6)
    M[0, 0] = s
    M[1, 1] = s
    M[2, 2] = s1 + s2
    M[2, 3] = -s3
    M[3, 2] = -s3
    M[2, 4] = s3
    M[4, 2] = s3
    M[2, 5] = (s1 - s2) / 2
    M[5, 2] = (s1 - s2) / 2
    M[3, 3] = s1
    M[3, 5] = s3 / 2
    M[5, 3] = s3 / 2
    M[4, 4] = s2
    M[4, 5] = s3 / 2
    M[5, 4] = s3 / 2
    M[5, 5] = (s1 + s2) / 4
    return M


@ti.func
def moved(E: ti.template(), b, x, y, col):
    """A material point (x, y) of block b displaced by the block's D in ``bwork[b, col:col+6]``
    with the exact rotation (§5.3, `kinematics.move_points`)."""
    r = E.bwork[b, col + 2]
    return moved_by(E, b, x, y, col, ti.cos(r), ti.sin(r))


@ti.func
def moved_by(E: ti.template(), b, x, y, col, c, s):
    """`moved` with the cosine and sine of the block's rotation given (once a block, not once a
    point)."""
    X = x - E.bgeo[b, BG_CX]
    Y = y - E.bgeo[b, BG_CY]
    nx = x + (E.bwork[b, col + 0] + E.bwork[b, col + 3] * X + 0.5 * E.bwork[b, col + 5] * Y + X * (c - 1.0) - Y * s)
    ny = y + (E.bwork[b, col + 1] + E.bwork[b, col + 4] * Y + 0.5 * E.bwork[b, col + 5] * X + X * s + Y * (c - 1.0))
    return nx, ny


@ti.func
def kidx(E: ti.template(), m, i, j):
    """Position of entry (i, j) of member m's matrix K (`ddatai.fused.system.at`; K0 follows it)."""
    return at(E, m, i, j)


@ti.func
def block_terms(E: ti.template(), m, dt, beta):
    """K0 (block-diagonal: inertia with Newmark's carry-over, elasticity) and F0 (velocity and
    acceleration carry-over, initial stress, body force), then the fixed-point springs and the
    point loads (§2.1–2.6; `assembly.block_terms_numpy`, `assembly.point_terms_numpy`). K0 is the
    second n × n matrix of the slab, F0 the second vector of the member's vectors."""
    nf = E.mi[m, MI_NF]
    n = 6 * nf
    k0 = n * n  # K0 after K
    f0 = E.mi[m, MI_X0] + XS_F0 * n
    carry = E.mf[m, MF_CARRY]
    gx = E.mf[m, MF_GX]
    gy = E.mf[m, MF_GY]
    for r in range(nf):
        b = E.rblock[E.mi[m, MI_R0] + r]
        rho = E.bmat[b, BM_RHO]
        s = E.bgeo[b, BG_AREA]
        M = mass(E, b)
        c_inertia = rho / (beta * dt * dt)
        c_velocity = rho / (beta * dt) * carry
        c_accel = rho * (0.5 / beta - 1.0)
        for a in range(6):
            mv = 0.0
            for c in range(6):
                k = c_inertia * M[a, c]
                if a >= 3 and c >= 3:
                    k += s * E.bmat[b, BM_C + 3 * (a - 3) + (c - 3)]
                E.kmat[kidx(E, m, 6 * r + a, 6 * r + c) + k0] += k
                mv += M[a, c] * (c_velocity * E.bst[b, BS_VEL + c] + c_accel * E.bst[b, BS_ACC + c])
            E.xvec[f0 + 6 * r + a] += mv
        for a in range(3):
            E.xvec[f0 + 6 * r + 3 + a] -= s * E.bst[b, BS_STRESS + a]
        E.xvec[f0 + 6 * r + 0] += rho * s * gx
        E.xvec[f0 + 6 * r + 1] += rho * s * gy
    fpp = E.mf[m, MF_FIXED_PEN]
    for p in range(E.mi[m, MI_P0], E.mi[m, MI_P1]):
        kind = E.pint[p, PI_KIND]
        b = E.pint[p, PI_BLOCK]
        r = E.bint[b, BI_ROW]
        if r >= 0 and (kind == POINT_FIXED or kind == POINT_LOAD):
            X = ti.Vector([E.pf[p, PF_X] - E.bgeo[b, BG_CX], E.pf[p, PF_Y] - E.bgeo[b, BG_CY]])
            t1 = _trow(1.0, 0.0, X)
            t2 = _trow(0.0, 1.0, X)
            fx = E.pf[p, PF_FX]
            fy = E.pf[p, PF_FY]
            if kind == POINT_FIXED:
                # the restoring spring towards the point's original position (§2.6)
                fx = fpp * (E.pf[p, PF_X0] - E.pf[p, PF_X])
                fy = fpp * (E.pf[p, PF_Y0] - E.pf[p, PF_Y])
                for a in range(6):
                    for c in range(6):
                        E.kmat[kidx(E, m, 6 * r + a, 6 * r + c) + k0] += fpp * (t1[a] * t1[c] + t2[a] * t2[c])
            for a in range(6):
                E.xvec[f0 + 6 * r + a] += t1[a] * fx + t2[a] * fy


@ti.func
def block_disp_row(E: ti.template(), b, col):
    """D of block b in ``bwork[b, col:col + 6]`` as a 6-vector."""
    return ti.Vector([E.bwork[b, col + a] for a in ti.static(range(6))])


@ti.func
def rotate_stress(sx, sy, t, angle):
    """The stress tensor rotated with its block (§5.4, `kinematics.rotate_stress`)."""
    c = ti.cos(angle)
    s = ti.sin(angle)
    return (c * c * sx - 2 * c * s * t + s * s * sy, s * s * sx + 2 * c * s * t + c * c * sy,
            c * s * (sx - sy) + (c * c - s * s) * t)


@ti.func
def strain_energy(E: ti.template(), b):
    """½·S·σᵀC⁻¹σ of block b [J/m] (`energy.mechanical_energy`)."""
    acc = 0.0
    for i in range(3):
        for j in range(3):
            acc += E.bst[b, BS_STRESS + i] * E.bmat[b, BM_CINV + 3 * i + j] * E.bst[b, BS_STRESS + j]
    return 0.5 * E.bgeo[b, BG_AREA] * acc


@ti.func
def kinetic_energy(E: ti.template(), b):
    """½·ρ·vᵀMv of block b [J/m] (M of `mass`, written out)."""
    s = E.bgeo[b, BG_AREA]
    s1 = E.bgeo[b, BG_S1]
    s2 = E.bgeo[b, BG_S2]
    s3 = E.bgeo[b, BG_S3]
    v = ti.Vector([E.bst[b, BS_VEL + a] for a in ti.static(range(6))])
    quad = s * (v[0] * v[0] + v[1] * v[1]) + (s1 + s2) * v[2] * v[2] + s1 * v[3] * v[3] + s2 * v[4] * v[4] + \
        0.25 * (s1 + s2) * v[5] * v[5] + 2.0 * (-s3 * v[2] * v[3] + s3 * v[2] * v[4] + 0.5 * (s1 - s2) * v[2] * v[5] +
                                            0.5 * s3 * v[3] * v[5] + 0.5 * s3 * v[4] * v[5])
    return 0.5 * E.bmat[b, BM_RHO] * quad
