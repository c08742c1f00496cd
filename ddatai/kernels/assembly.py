"""Contact vectors (the linearised normal and shear distances of every contact line, §2.8.1–2.8.4,
and their second-order rotation shift, §5.3) and the assembly of K and F into CSR data
(per-block terms, point springs and loads, contact springs and friction; docs/method/dda.md §2).
Their NumPy twins are in `ddatai.reference` and `ddatai.assembly`."""

import taichi as ti

from .common import (E0, ES, F64_1, F64_2, F64_3, G0, GS, I8_1, I32_1, I32_2, KIND_VE, STATE_LOCK, STATE_OPEN,
                     _cross, _pt, _store, _trow)


@ti.kernel
def contact_vectors(xy: F64_2, vblock: I32_1, vnext: I32_1, centroid: F64_2, cint: I32_2,
                    omega: F64_1, vec: F64_3, sca: F64_2):
    """Linearised normal and shear distances of every contact line (docs/method/dda.md §2.8.1–2.8.4).

    cint rows: (kind, vertex0, edge0, vertex1, edge1). Positions are taken relative to the
    contact vertex P1 so that the constant parts keep full precision.
    """
    for c in range(cint.shape[0]):
        nl = 1 + cint[c, 0]
        for q in range(nl):
            p1 = cint[c, 1 + 2 * q]
            k = cint[c, 2 + 2 * q]
            P1 = _pt(xy, p1)
            x2 = _pt(xy, vnext[k]) - P1
            x3 = _pt(xy, k) - P1
            l = (x3 - x2).norm()
            ci = ti.Vector([centroid[vblock[p1], 0], centroid[vblock[p1], 1]])
            cj = ti.Vector([centroid[vblock[k], 0], centroid[vblock[k], 1]])
            X1 = P1 - ci
            X2 = x2 + P1 - cj
            X3 = x3 + P1 - cj
            # ∂Δ/∂P1, ∂Δ/∂P2, ∂Δ/∂P3 with P1 at the origin
            ev = _trow(x2[1] - x3[1], x3[0] - x2[0], X1) / l
            gv = (_trow(x3[1], -x3[0], X2) + _trow(-x2[1], x2[0], X3)) / l
            sca[c, q] = _cross(x2, x3) / l
            _store(vec, c, E0 + 2 * q, ev)
            _store(vec, c, G0 + 2 * q, gv)
            if q == 0 and cint[c, 0] == KIND_VE:
                w = omega[c]
                t = (x3 - x2) / l
                # ds = (P1 - P0)·(P3 - P2)/l with P0 = (1-ω)P2 + ωP3 (§2.8.3)
                sca[c, 2] = (-(1.0 - w) * x2 - w * x3).dot(x3 - x2) / l
                c2 = (2.0 * (1.0 - w) * x2 - (1.0 - 2.0 * w) * x3) / l
                c3 = (-(1.0 - 2.0 * w) * x2 - 2.0 * w * x3) / l
                _store(vec, c, ES, _trow(t[0], t[1], X1))
                _store(vec, c, GS, _trow(c2[0], c2[1], X2) + _trow(c3[0], c3[1], X3))


@ti.kernel
def second_order_shift(xy: F64_2, vnext: I32_1, q: F64_2, cint: I32_2, omega: F64_1, shift: F64_2):
    """Second-order rotation terms of the contact distances (docs/method/dda.md §5.3): with q the
    exact-minus-linear displacement of every vertex, shift = ∂Δ/∂P·q for each normal line and
    ∂s/∂P·q for the shear of a vertex-edge contact (§2.8.1, §2.8.3)."""
    for c in range(cint.shape[0]):
        nl = 1 + cint[c, 0]
        for line in range(nl):
            p1 = cint[c, 1 + 2 * line]
            k = cint[c, 2 + 2 * line]
            p2 = vnext[k]
            P1, P2, P3 = _pt(xy, p1), _pt(xy, p2), _pt(xy, k)
            q1, q2, q3 = _pt(q, p1), _pt(q, p2), _pt(q, k)
            length = (P3 - P2).norm()
            shift[c, line] = ((P2[1] - P3[1]) * q1[0] + (P3[0] - P2[0]) * q1[1] +
                              (P3[1] - P1[1]) * q2[0] + (P1[0] - P3[0]) * q2[1] +
                              (P1[1] - P2[1]) * q3[0] + (P2[0] - P1[0]) * q3[1]) / length
            if line == 0 and cint[c, 0] == KIND_VE:
                w = omega[c]
                b1 = P3 - P2
                b2 = -P1 + 2.0 * (1.0 - w) * P2 - (1.0 - 2.0 * w) * P3
                b3 = P1 - (1.0 - 2.0 * w) * P2 - 2.0 * w * P3
                shift[c, 2] = (b1.dot(q1) + b2.dot(q2) + b3.dot(q3)) / length


@ti.kernel
def assemble_blocks(dof: I32_1, density: F64_1, elastic: F64_3, area: F64_1, mass: F64_3,
                    velocity: F64_2, accel: F64_2, stress: F64_2, body_acc_x: ti.f64,
                    body_acc_y: ti.f64, dt: ti.f64, carry: ti.f64, beta: ti.f64,
                    diag_slot: I32_1, stride: I32_1, data: F64_1, rhs: F64_1):
    """Per-block terms: inertia with velocity and acceleration carry-over (Newmark, γ = 1;
    β = ½ is Shi's §2.5), elasticity (§2.1), initial stress (§2.2) and body force (§2.4;
    gravity minus ground acceleration).

    With D = v Δt + Δt²((½ − β) a_n + β a_{n+1}) the inertia force ρ M a_{n+1} adds
    ρM/(βΔt²) to K and ρM (v/(βΔt) + (1/(2β) − 1) a_n) to F (v = carry × velocity)."""
    for b in range(dof.shape[0]):
        r = dof[b]
        if r >= 0:
            rho = density[b]
            s = area[b]
            c_inertia = rho / (beta * dt * dt)
            c_velocity = rho / (beta * dt) * carry
            c_accel = rho * (0.5 / beta - 1.0)
            base = diag_slot[r]
            st = stride[r]
            for a in range(6):
                mv = 0.0
                for c in range(6):
                    k = c_inertia * mass[b, a, c]
                    if a >= 3 and c >= 3:
                        k += s * elastic[b, a - 3, c - 3]
                    data[base + a * st + c] += k
                    mv += mass[b, a, c] * (c_velocity * velocity[b, c] + c_accel * accel[b, c])
                rhs[6 * r + a] += mv
            for a in range(3):
                rhs[6 * r + 3 + a] -= s * stress[b, a]
            rhs[6 * r + 0] += rho * s * body_acc_x
            rhs[6 * r + 1] += rho * s * body_acc_y


@ti.kernel
def assemble_points(point_block: I32_1, point_xy: F64_2, point_force: F64_2, stiffness: F64_1,
                    dof: I32_1, centroid: F64_2, diag_slot: I32_1, stride: I32_1,
                    data: F64_1, rhs: F64_1):
    """Point springs and point loads: K += k TᵀT, F += Tᵀ f (§2.3, §2.6)."""
    for p in range(point_block.shape[0]):
        b = point_block[p]
        r = dof[b]
        if r >= 0:
            X = ti.Vector([point_xy[p, 0] - centroid[b, 0], point_xy[p, 1] - centroid[b, 1]])
            t1 = _trow(1.0, 0.0, X)
            t2 = _trow(0.0, 1.0, X)
            k = stiffness[p]
            base = diag_slot[r]
            st = stride[r]
            if k != 0.0:
                for a in range(6):
                    for c in range(6):
                        ti.atomic_add(data[base + a * st + c], k * (t1[a] * t1[c] + t2[a] * t2[c]))
            for a in range(6):
                ti.atomic_add(rhs[6 * r + a], t1[a] * point_force[p, 0] + t2[a] * point_force[p, 1])


@ti.func
def _outer_rows(vec: ti.template(), c, s, t_own, t_other, k, r, r_other, off_slot,
                diag_slot: ti.template(), stride: ti.template(), data: ti.template()):
    """Add k·v vᵀ-type terms on the rows of one block r: k·vec[c, s]·vec[c, t_own]ᵀ to its
    diagonal block and k·vec[c, s]·vec[c, t_other]ᵀ to the block at ``off_slot`` (its row,
    the other block's column), if that block is free."""
    if r >= 0:
        base = diag_slot[r]
        st = stride[r]
        for a in range(6):
            va = k * vec[c, s, a]
            for b in range(6):
                ti.atomic_add(data[base + a * st + b], va * vec[c, t_own, b])
            if r_other >= 0:
                for b in range(6):
                    ti.atomic_add(data[off_slot + a * st + b], va * vec[c, t_other, b])


@ti.func
def _outer(vec: ti.template(), c, su, sw, tu, tw, k, ri, rj, sij, sji,
           diag_slot: ti.template(), stride: ti.template(), data: ti.template()):
    """Add k·[u; w][u'; w']ᵀ (u = vec[c, su], w = vec[c, sw] on the rows of blocks i, j;
    u' = vec[c, tu], w' = vec[c, tw] on their columns): a rank-one term, non-symmetric unless
    (tu, tw) = (su, sw)."""
    _outer_rows(vec, c, su, tu, tw, k, ri, rj, sij, diag_slot, stride, data)
    _outer_rows(vec, c, sw, tw, tu, k, rj, ri, sji, diag_slot, stride, data)


@ti.func
def _spring(vec: ti.template(), c, su, sw, k, d0, ri, rj, sij, sji,
            diag_slot: ti.template(), stride: ti.template(), data: ti.template(), rhs: ti.template()):
    """Add the spring energy ½ k (d0 + uᵀDi + wᵀDj)² of contact c (u = vec[c, su], w = vec[c, sw])."""
    _outer(vec, c, su, sw, su, sw, k, ri, rj, sij, sji, diag_slot, stride, data)
    _spring_load(vec, c, su, sw, k, d0, ri, rj, rhs)


@ti.func
def _spring_load(vec: ti.template(), c, su, sw, k, d0, ri, rj, rhs: ti.template()):
    """The spring's part of F: −k·d0·[u; w] on the rows of blocks i, j (`_spring`)."""
    for a in range(6):
        if ri >= 0:
            ti.atomic_add(rhs[6 * ri + a], -k * d0 * vec[c, su, a])
        if rj >= 0:
            ti.atomic_add(rhs[6 * rj + a], -k * d0 * vec[c, sw, a])


@ti.func
def _friction_load(vec: ti.template(), c, f, ri, rj, rhs: ti.template()):
    """A sliding contact's friction in F: −f·[e_s; g_s] on the rows of blocks i, j, f = sgn·S
    (`assemble_contacts`)."""
    for a in range(6):
        if ri >= 0:
            ti.atomic_add(rhs[6 * ri + a], -f * vec[c, ES, a])
        if rj >= 0:
            ti.atomic_add(rhs[6 * rj + a], -f * vec[c, GS, a])


@ti.kernel
def assemble_contacts(cint: I32_2, state: I8_1, line: I8_1, vblock: I32_1, dof: I32_1,
                      vec: F64_3, sca: F64_2, friction_const: F64_1, friction_slope: F64_1,
                      shear_dir: I8_1, slot_ab: I32_1, slot_ba: I32_1, diag_slot: I32_1,
                      stride: I32_1, penalty: ti.f64, shear_penalty: ti.f64, data: F64_1, rhs: F64_1,
                      serial: ti.template()):
    """Contact springs for the assumed states, and friction of sliding contacts (§2.8).

    A sliding contact's friction force has magnitude S = a − b·dn (a = ``friction_const``,
    b = ``friction_slope``) and acts against ``shear_dir`` along the gradient of ds. With b = 0
    it is a load (S from an earlier solve, Shi's explicit friction); with b = μ·p it follows
    the normal penetration dn of this very solve (implicit friction) and adds the
    non-symmetric term −dir·b·∇ds ∇dnᵀ to K. `slot_ab`/`slot_ba` locate the off-diagonal
    blocks of the pair (block of vertex0, block of edge0) in the CSR data array. ``serial``:
    run the loop on one thread (`ddatai.backend.serial_scatter`).
    """
    ti.loop_config(serialize=serial)
    for c in range(cint.shape[0]):
        st = state[c]
        if st != STATE_OPEN:
            q = ti.cast(line[c], ti.i32)
            i = vblock[cint[c, 1 + 2 * q]]
            j = vblock[cint[c, 2 + 2 * q]]
            ri = dof[i]
            rj = dof[j]
            sij = slot_ab[c]
            sji = slot_ba[c]
            if q == 1:
                sij = slot_ba[c]
                sji = slot_ab[c]
            _spring(vec, c, E0 + 2 * q, G0 + 2 * q, penalty, sca[c, q], ri, rj, sij, sji,
                    diag_slot, stride, data, rhs)
            if cint[c, 0] == KIND_VE:
                if st == STATE_LOCK:
                    _spring(vec, c, ES, GS, shear_penalty, sca[c, 2], ri, rj, sij, sji,
                            diag_slot, stride, data, rhs)
                else:
                    sgn = ti.cast(shear_dir[c], ti.f64)
                    # internal force sgn·S(D)·∇ds with S = a − b·(dn0 + ∇dnᵀD)
                    f = sgn * (friction_const[c] - friction_slope[c] * sca[c, 0])
                    _friction_load(vec, c, f, ri, rj, rhs)
                    if friction_slope[c] != 0.0:
                        _outer(vec, c, ES, GS, E0, G0, -sgn * friction_slope[c], ri, rj, sij, sji,
                               diag_slot, stride, data)


@ti.kernel
def assemble_contact_loads(cint: I32_2, state: I8_1, line: I8_1, vblock: I32_1, dof: I32_1,
                           vec: F64_3, sca: F64_2, friction_const: F64_1, friction_slope: F64_1,
                           shear_dir: I8_1, penalty: ti.f64, shear_penalty: ti.f64, rhs: F64_1,
                           serial: ti.template()):
    """The F part of `assemble_contacts` alone, its K terms left out: each closed contact's
    −k·d0·∇d of its springs and a sliding one's friction, the same terms added in the same
    order (an iterate whose K is kept, `ddatai.reassembly`). Its NumPy twin is
    ``ddatai.reassembly.contact_rhs``."""
    ti.loop_config(serialize=serial)
    for c in range(cint.shape[0]):
        st = state[c]
        if st != STATE_OPEN:
            q = ti.cast(line[c], ti.i32)
            ri = dof[vblock[cint[c, 1 + 2 * q]]]
            rj = dof[vblock[cint[c, 2 + 2 * q]]]
            _spring_load(vec, c, E0 + 2 * q, G0 + 2 * q, penalty, sca[c, q], ri, rj, rhs)
            if cint[c, 0] == KIND_VE:
                if st == STATE_LOCK:
                    _spring_load(vec, c, ES, GS, shear_penalty, sca[c, 2], ri, rj, rhs)
                else:
                    sgn = ti.cast(shear_dir[c], ti.f64)
                    _friction_load(vec, c, sgn * (friction_const[c] - friction_slope[c] * sca[c, 0]), ri, rj, rhs)
