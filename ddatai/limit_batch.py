"""The limit-equilibrium programs of many small models solved side by side (docs/method/dda.md
§8.12): the members of a kgm batch — the samples of a probabilistic study, the probes of a
bisection round — are one group on one geometry at different joint strengths, so the first
program of each member's screen (``ddatai.mechanisms.unsupported_at_start``) has the same
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

from contextlib import contextmanager, nullcontext
from functools import partial
from importlib import import_module

import numpy as np

from . import limit_equilibrium as le

#: fewest programs of one matrix solved together (fewer: each on its own, `_solve_program`)
SIDE_BY_SIDE = 2


def settle_many(models, states=None) -> list:
    """Each model settled by its own equilibrium stage (`ddatai.start.settle`, from its initial
    state or ``states[k]``), the first programs of their screens solved side by side first
    (`screened_ahead`), then the stages side by side (`ddatai.side_by_side`: each runs its own
    code, the contact assembly, contact law and block displacements of the members waiting at
    them evaluated at once, `ddatai.stage_batch`): the settled states, as each stage alone gives
    them, to the bit."""
    from . import side_by_side
    from .start import settle
    from .step import Stepper
    from .threads import one_blas_thread

    _register_operations()
    steppers = [Stepper(m) for m in models]
    states = [m.initial_state() for m in models] if states is None else list(states)
    # one BLAS-thread limit around the whole batch: a member's stage opens its own, and side by
    # side the first to finish would give the threads back while the others still solve
    threads = one_blas_thread() if all(st.solver.backend == "dense" for st in steppers) else nullcontext()
    with screened_ahead(steppers, states), threads:
        # side by side: each member's stage as alone, their contact assembly and law evaluated
        # for all the members waiting at them at once (`ddatai.side_by_side`)
        return [out[0] for out in side_by_side.run([partial(settle, st, s) for st, s in zip(steppers, states)])]


@contextmanager
def screened_ahead(steppers, states):
    """While the body runs, the screen of each member (``steppers[k]`` from ``states[k]``,
    `ddatai.mechanisms.unsupported_at_start`) is the one done here, once: its first
    limit-equilibrium program answered from programs solved side by side (`solve_programs`),
    the rest as the stage alone asks them (`limit_equilibrium.unsupported_programs`). The members
    that share their geometry share its detection (`ddatai.batch_detect.share_detection`). The
    screens' answers stay primed for the stages' own tests, which may ask them again (as a
    stage alone finds its screen's last programs among those solved lately)."""
    from . import side_by_side
    from .batch_detect import share_detection
    from .mechanisms import SCREENED, screen_programs

    _register_operations()
    share_detection(steppers, states)
    started, done = [], {}
    # each screen up to its first program, side by side (`ddatai.side_by_side`: the members'
    # contacts at t = 0 started at once, each its own to the bit)
    screens = [screen_programs(st, s) for st, s in zip(steppers, states)]
    for st, s, programs, (first, end) in zip(steppers, states, screens,
                                              side_by_side.run([partial(_first, g) for g in screens])):
        if end is None:
            started.append((st, s, programs, first))
        else:
            done[id(st)] = (st, s, end.value)
    answers = solve_programs([p for _, _, _, p in started])
    le.PRIMED.update(answers)

    def solve(*program):  # a screen's later programs, kept too: its stage's tests may ask them again
        out = le._interior_point(*program)
        answers[le.program_key(*program)] = None if out is None else (out[0], out[1].copy())
        return out

    try:
        for st, s, programs, first in started:
            done[id(st)] = (st, s, le.answered(programs, solve, first))
        le.PRIMED.update(answers)
        SCREENED.update(done)
        yield
    finally:
        for key in answers:
            le.PRIMED.pop(key, None)
        for key in done:
            SCREENED.pop(key, None)


def _register_operations() -> None:
    """The stage's operations registered side by side (`ddatai.stage_batch` does it on import)."""
    import_module(f"{__package__}.stage_batch")


def _first(programs):
    """(the first program that the generator ``programs`` yields, None), or (None, its
    StopIteration) where it yields none."""
    try:
        return next(programs), None
    except StopIteration as end:
        return None, end


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
    stop), its answer ``(Σ(r⁺ + r⁻), y)`` or None. The iterates of the members still iterating
    are kept side by side (rows), a member's row dropped when it stops."""
    k_n, m = tan_phi.shape
    n = a.shape[0]
    a = a.toarray()
    at = np.ascontiguousarray(a.T)
    a_n, a_s = a[:, :m], a[:, m:]
    a_st = np.ascontiguousarray(a_s.T)
    a_nt = np.ascontiguousarray(a_n.T)
    diagonal = (slice(None), np.arange(n), np.arange(n))
    width = 3 * m + 2 * n

    def c_times(nn, ss, rp, rm, mu):
        return np.concatenate([nn, mu * nn - ss, mu * nn + ss, rp, rm], axis=1)

    def ct_times(v, mu):
        v2, v3 = v[:, m:2 * m], v[:, 2 * m:3 * m]
        return v[:, :m] + mu * (v2 + v3), v3 - v2, v[:, 3 * m:3 * m + n], v[:, 3 * m + n:]

    def step(v, dv):  # `limit_equilibrium._step`, row by row
        neg = dv < 0
        return np.minimum(1.0, np.where(neg, -v / np.where(neg, dv, -1.0), np.inf).min(axis=1))

    # the rows: the members still iterating (``ids``) and their iterates
    ids = np.arange(k_n)
    mu = tan_phi.copy()
    d = np.concatenate([tensile, cohesion, cohesion, np.zeros((k_n, 2 * n))], axis=1)
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

    for _ in range(le.MAX_IPM_ITERATIONS):
        aty = y @ a
        ctz = ct_times(z, mu)
        rd = (-aty[:, :m] - ctz[0], -aty[:, m:] - ctz[1], 1.0 - y - ctz[2], 1.0 + y - ctz[3])
        re = np.concatenate([nn, ss], axis=1) @ at + rp - rm + b
        ri = c_times(nn, ss, rp, rm, mu) + d - s
        gap = np.einsum("ij,ij->i", s, z) / width
        primal = np.maximum(np.abs(re).max(axis=1), np.abs(ri).max(axis=1)) / size
        dual = np.maximum(np.maximum(np.abs(rd[0]).max(axis=1), np.abs(rd[1]).max(axis=1)),
                          np.maximum(np.abs(rd[2]).max(axis=1), np.abs(rd[3]).max(axis=1)))
        finite = np.isfinite(gap + primal + dual)
        near = finite & (primal < 100.0 * le.IPM_TOLERANCE) & (dual < 10.0 * le.DUAL_TOLERANCE)
        better = near & (gap < best_gap[ids])
        if better.any():
            g = ids[better]
            best_gap[g], best_sum[g], best_y[g] = gap[better], rp[better].sum(axis=1) + rm[better].sum(axis=1), \
                y[better]
        ended = finite & (primal < le.IPM_TOLERANCE) & (gap < le.IPM_TOLERANCE)
        converged = ended & (dual < le.DUAL_TOLERANCE)
        for j in np.flatnonzero(converged):
            out[ids[j]] = (float(rp[j].sum() + rm[j].sum()), y[j].copy())
        q = z / s
        q1, q2, q3, q4, q5 = q[:, :m], q[:, m:2 * m], q[:, 2 * m:3 * m], q[:, 3 * m:3 * m + n], q[:, 3 * m + n:]
        h11, h12, h22 = q1 + mu * mu * (q2 + q3), mu * (q3 - q2), q2 + q3
        det = np.maximum(q1 * h22 + 4.0 * mu * mu * q2 * q3, 1e-300)
        i11, i12, i22 = h22 / det, -h12 / det, h11 / det
        cross = (a_n * i12[:, None, :]) @ a_st
        newton_matrix = (a_n * i11[:, None, :]) @ a_nt + cross + cross.transpose(0, 2, 1) + \
            (a_s * i22[:, None, :]) @ a_st
        newton_matrix[diagonal] += 1.0 / q4 + 1.0 / q5
        # each member's Cholesky factor; one that is not positive definite ends that member's
        # iteration (round-off), as `_DenseFactor` ends one alone
        done = ~finite | ended
        try:
            lower = np.linalg.cholesky(newton_matrix)
        except np.linalg.LinAlgError:
            lower = np.zeros_like(newton_matrix)
            for j in np.flatnonzero(~done):
                try:
                    lower[j] = np.linalg.cholesky(newton_matrix[j])
                except np.linalg.LinAlgError:
                    done[j] = True
        if done.any():
            for j in np.flatnonzero(done & ~converged):
                out[ids[j]] = best(ids[j])
            go = ~done
            if not go.any():
                ids = ids[:0]
                break
            ids, mu, d, nn, ss, rp, rm, s, z, y = (v[go] for v in (ids, mu, d, nn, ss, rp, rm, s, z, y))
            rd, re, ri, gap, lower = tuple(r[go] for r in rd), re[go], ri[go], gap[go], lower[go]
            q4, q5, i11, i12, i22 = q4[go], q5[go], i11[go], i12[go], i22[go]
        upper = lower.transpose(0, 2, 1)

        def newton(rc):
            t = ct_times((rc - z * ri) / s, mu)
            qn, qs, qp, qm = (-r + u for r, u in zip(rd, t))
            hn, hs = i11 * qn + i12 * qs, i12 * qn + i22 * qs
            rhs = -re - (np.concatenate([hn, hs], axis=1) @ at + qp / q4 - qm / q5)
            dy = np.linalg.solve(upper, np.linalg.solve(lower, rhs[:, :, None]))[:, :, 0]
            atdy = dy @ a
            pn, ps = qn + atdy[:, :m], qs + atdy[:, m:]
            dn, dsh = i11 * pn + i12 * ps, i12 * pn + i22 * ps
            dp, dm = (qp + dy) / q4, (qm - dy) / q5
            dslack = c_times(dn, dsh, dp, dm, mu) + ri
            return dn, dsh, dp, dm, dy, dslack, (rc - z * dslack) / s

        aff = newton(-s * z)
        a_p, a_d = step(s, aff[5]), step(z, aff[6])
        gap_aff = np.einsum("ij,ij->i", s + a_p[:, None] * aff[5], z + a_d[:, None] * aff[6]) / width
        sigma = (gap_aff / np.maximum(gap, 1e-300)) ** 3
        dn, dsh, dp, dm, dy, dslack, dz = newton((sigma * gap)[:, None] - s * z - aff[5] * aff[6])
        a_p, a_d = (0.99 * step(s, dslack))[:, None], (0.99 * step(z, dz))[:, None]
        nn, ss, rp, rm, s = nn + a_p * dn, ss + a_p * dsh, rp + a_p * dp, rm + a_p * dm, s + a_p * dslack
        y, z = y + a_d * dy, z + a_d * dz
    for g in ids:  # the iterations ran out
        out[g] = best(g)
    return out
