"""The limit-equilibrium programs of many small models solved side by side (docs/method/dda.md
§8.12): the members of a kgm batch — the samples of a probabilistic study, the probes of a
bisection round — are one group on one geometry at different joint strengths, so the first
program of each member's screen (`ddatai.mechanisms.unsupported_at_start`) has the same
equilibrium matrix and loads, and only its strengths (tanφ, cohesion, tensile strength) differ.

`screened_ahead` collects those programs, solves the programs of one matrix together by the
iteration of `ddatai.limit_equilibrium` (Mehrotra's predictor-corrector, every member with its
own iterates, steps and stop: `_mehrotra_many` follows `_mehrotra` line by line, with a member
axis in front), and keeps each answer where each member's own stage then takes it (the stage
runs as it would alone, and asks the same program: the same bytes). A dense Newton step of a
two-block program is ~20 NumPy calls whatever the number of members: side by side, a member's
program costs a fraction of a millisecond where alone it costs tens of them.
"""

from __future__ import annotations

from contextlib import contextmanager

import numpy as np

from . import limit_equilibrium as le

#: fewest programs of one matrix solved together (fewer: each on its own, `_solve_program`)
SIDE_BY_SIDE = 2


def settle_many(models, states=None) -> list:
    """Each model settled by its own equilibrium stage (`ddatai.start.settle`, from its initial
    state or ``states[k]``), the first programs of their screens solved side by side first
    (`screened_ahead`): the settled states, as each stage alone gives them."""
    from .start import settle
    from .step import Stepper

    steppers = [Stepper(m) for m in models]
    states = [m.initial_state() for m in models] if states is None else list(states)
    with screened_ahead(steppers, states):
        return [settle(st, s)[0] for st, s in zip(steppers, states)]


@contextmanager
def screened_ahead(steppers, states):
    """While the body runs, the first limit-equilibrium program of the screen of each member
    (``steppers[k]`` from ``states[k]``, `ddatai.mechanisms.screen_program`) is answered from
    programs solved side by side (`solve_programs`)."""
    from .mechanisms import screen_program

    programs = [p for p in (screen_program(st, s) for st, s in zip(steppers, states)) if p is not None]
    answers = solve_programs(programs)
    le.PRIMED.update(answers)
    try:
        yield
    finally:
        for key in answers:
            le.PRIMED.pop(key, None)


def solve_programs(programs) -> dict:
    """{`limit_equilibrium.program_key`: ``_solve_program``'s answer} of ``programs`` (each
    ``(a, b, tan_phi, cohesion, tensile)``), those of one dense matrix and load solved side by
    side."""
    answers: dict = {}
    groups: dict = {}
    for p in programs:
        key = le.program_key(*p)
        if key in answers:
            continue
        a, b = p[0], p[1]
        shape = (a.data.tobytes(), a.indices.tobytes(), a.indptr.tobytes(), a.shape, b.tobytes())
        groups.setdefault(shape, {})[key] = p
    for members in groups.values():
        keys, progs = list(members), list(members.values())
        a, b = progs[0][0], progs[0][1]
        if len(progs) < SIDE_BY_SIDE or a.shape[0] > le.DENSE_ROWS:
            for key, p in zip(keys, progs):
                answers[key] = le._solve_program(*p)
            continue
        with np.errstate(all="ignore"):
            outs = _mehrotra_many(a, b, *(np.stack([p[i] for p in progs]) for i in (2, 3, 4)))
        answers.update(zip(keys, outs))
    return answers


def _mehrotra_many(a, b, tan_phi, cohesion, tensile) -> list:
    """`limit_equilibrium._mehrotra` (dense) of K programs that share ``a`` and ``b`` and differ
    in their strengths ((K, m) arrays): each member's iteration as its own (its steps, its
    stop), its answer ``(Σ(r⁺ + r⁻), y)`` or None."""
    k_n, m = tan_phi.shape
    n = a.shape[0]
    a = a.toarray()
    a_n, a_s = a[:, :m], a[:, m:]
    mu = tan_phi
    d = np.concatenate([tensile, cohesion, cohesion, np.zeros((k_n, 2 * n))], axis=1)

    def c_times(nn, ss, rp, rm, mu):
        return np.concatenate([nn, mu * nn - ss, mu * nn + ss, rp, rm], axis=1)

    def ct_times(v, mu):
        v2, v3 = v[:, m:2 * m], v[:, 2 * m:3 * m]
        return v[:, :m] + mu * (v2 + v3), v3 - v2, v[:, 3 * m:3 * m + n], v[:, 3 * m + n:]

    def step(v, dv):  # `limit_equilibrium._step`, row by row
        ratio = np.where(dv < 0, -v / np.where(dv < 0, dv, -1.0), np.inf)
        return np.minimum(1.0, ratio.min(axis=1))

    nn, ss = np.zeros((k_n, m)), np.zeros((k_n, m))
    rp = np.tile(np.maximum(-b, 0.0) + 1.0, (k_n, 1))
    rm = np.tile(np.maximum(b, 0.0) + 1.0, (k_n, 1))
    s = np.maximum(c_times(nn, ss, rp, rm, mu) + d, 1.0)
    z = np.ones_like(s)
    y = np.zeros((k_n, n))
    size = 1.0 + float(np.abs(b).max(initial=0.0))
    best_gap, best_sum, best_y = np.full(k_n, np.inf), np.zeros(k_n), np.zeros((k_n, n))
    out: list = [None] * k_n

    def best(g):  # where round-off ended member g's iteration: its best iterate, if close enough
        return (float(best_sum[g]), best_y[g].copy()) if best_gap[g] < 1e3 * le.IPM_TOLERANCE else None

    active = np.arange(k_n)
    for _ in range(le.MAX_IPM_ITERATIONS):
        if not len(active):
            break
        i = active
        mu_i, d_i = mu[i], d[i]
        aty = y[i] @ a
        ctz = ct_times(z[i], mu_i)
        rd = (-aty[:, :m] - ctz[0], -aty[:, m:] - ctz[1], 1.0 - y[i] - ctz[2], 1.0 + y[i] - ctz[3])
        re = np.concatenate([nn[i], ss[i]], axis=1) @ a.T + rp[i] - rm[i] + b
        ri = c_times(nn[i], ss[i], rp[i], rm[i], mu_i) + d_i - s[i]
        gap = np.einsum("ij,ij->i", s[i], z[i]) / s.shape[1]
        primal = np.maximum(np.abs(re).max(axis=1), np.abs(ri).max(axis=1)) / size
        dual = np.max([np.abs(r).max(axis=1) for r in rd], axis=0)
        finite = np.isfinite(gap + primal + dual)
        done = ~finite
        near = finite & (primal < 100.0 * le.IPM_TOLERANCE) & (dual < 10.0 * le.DUAL_TOLERANCE)
        better = near & (gap < best_gap[i])
        g = i[better]
        best_gap[g], best_sum[g], best_y[g] = gap[better], rp[g].sum(axis=1) + rm[g].sum(axis=1), y[g]
        converged = finite & (primal < le.IPM_TOLERANCE) & (dual < le.DUAL_TOLERANCE) & (gap < le.IPM_TOLERANCE)
        for j in np.flatnonzero(converged):
            out[i[j]] = (float(rp[i[j]].sum() + rm[i[j]].sum()), y[i[j]].copy())
        done |= converged
        q = z[i] / s[i]
        q1, q2, q3, q4, q5 = q[:, :m], q[:, m:2 * m], q[:, 2 * m:3 * m], q[:, 3 * m:3 * m + n], q[:, 3 * m + n:]
        h11, h12, h22 = q1 + mu_i * mu_i * (q2 + q3), mu_i * (q3 - q2), q2 + q3
        det = np.maximum(q1 * h22 + 4.0 * mu_i * mu_i * q2 * q3, 1e-300)
        i11, i12, i22 = h22 / det, -h12 / det, h11 / det
        cross = (a_n[None] * i12[:, None, :]) @ a_s.T
        newton_matrix = (a_n[None] * i11[:, None, :]) @ a_n.T + cross + cross.transpose(0, 2, 1) + \
            (a_s[None] * i22[:, None, :]) @ a_s.T
        diag = 1.0 / q4 + 1.0 / q5
        newton_matrix[:, np.arange(n), np.arange(n)] += diag
        # each member's Cholesky factor; one that is not positive definite ends that member's
        # iteration (round-off), as `_DenseFactor` ends one alone
        factor = np.zeros_like(newton_matrix)
        try:
            factor[~done] = np.linalg.cholesky(newton_matrix[~done])
        except np.linalg.LinAlgError:
            for j in np.flatnonzero(~done):
                try:
                    factor[j] = np.linalg.cholesky(newton_matrix[j])
                except np.linalg.LinAlgError:
                    done[j] = True
        go = np.flatnonzero(~done)
        for j in np.flatnonzero(done & ~converged):
            out[i[j]] = best(i[j])
        if not len(go):
            active = active[:0]
            break
        g = i[go]
        mu_g, z_g, s_g, ri_g = mu_i[go], z[g], s[g], ri[go]
        rd_g = tuple(r[go] for r in rd)
        re_g, q4_g, q5_g = re[go], q4[go], q5[go]
        i11_g, i12_g, i22_g = i11[go], i12[go], i22[go]
        lower_g = factor[go]
        upper_g = lower_g.transpose(0, 2, 1)

        def newton(rc):
            t = ct_times((rc - z_g * ri_g) / s_g, mu_g)
            qn, qs, qp, qm = (-r + u for r, u in zip(rd_g, t))
            hn, hs = i11_g * qn + i12_g * qs, i12_g * qn + i22_g * qs
            rhs = -re_g - (np.concatenate([hn, hs], axis=1) @ a.T + qp / q4_g - qm / q5_g)
            dy = np.linalg.solve(upper_g, np.linalg.solve(lower_g, rhs[:, :, None]))[:, :, 0]
            atdy = dy @ a
            pn, ps = qn + atdy[:, :m], qs + atdy[:, m:]
            dn, dsh = i11_g * pn + i12_g * ps, i12_g * pn + i22_g * ps
            dp, dm = (qp + dy) / q4_g, (qm - dy) / q5_g
            dslack = c_times(dn, dsh, dp, dm, mu_g) + ri_g
            return dn, dsh, dp, dm, dy, dslack, (rc - z_g * dslack) / s_g

        gap_g = gap[go]
        aff = newton(-s_g * z_g)
        a_p, a_d = step(s_g, aff[5]), step(z_g, aff[6])
        gap_aff = np.einsum("ij,ij->i", s_g + a_p[:, None] * aff[5], z_g + a_d[:, None] * aff[6]) / s.shape[1]
        sigma = (gap_aff / np.maximum(gap_g, 1e-300)) ** 3
        dn, dsh, dp, dm, dy, dslack, dz = newton((sigma * gap_g)[:, None] - s_g * z_g - aff[5] * aff[6])
        a_p, a_d = (0.99 * step(s_g, dslack))[:, None], (0.99 * step(z_g, dz))[:, None]
        nn[g], ss[g], rp[g], rm[g] = nn[g] + a_p * dn, ss[g] + a_p * dsh, rp[g] + a_p * dp, rm[g] + a_p * dm
        s[g] = s_g + a_p * dslack
        y[g], z[g] = y[g] + a_d * dy, z_g + a_d * dz
        active = g
    for g in active:  # the iterations ran out
        out[g] = best(g)
    return out
