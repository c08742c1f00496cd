"""Where the equilibrium stage's CPU time goes (`ddatai.start.settle`), by part: PARDISO's
factorisations (phases 13 and 23, each with its solve) and solves with the factor (phase 33),
and the NumPy work around them — the frames' assembly, each iterate's re-assembly, the
contact law, the line search, the mechanism checks, detection, limit equilibrium, the
open-close finish — from a profile of the stage alone (cProfile inside `ddatai.start._stage`;
nothing in the library changes). The profiler's own overhead inflates the Python parts by
~10-30 %: the table's shares are the measure, the stage's plain CPU time is printed first.

    PYTHONPATH=$PWD python benchmarks/stage_profile.py grid 1600     # or slope 1600, stiffgrid 1600
    ... --updates: with `Params(factor_updates=True)` (CHOLMOD); --plain: the stage's CPU time only, unprofiled; --warm: the run once first, unprofiled, in
    the same process, so that what is measured is without Taichi's first materialisation of its
    kernels (~0.8 s in the first contact detection, a cost of the process, not of the stage)
"""

from __future__ import annotations

import cProfile
import pstats
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import ddatai as dd  # noqa: E402
import ddatai.mechanisms as mechanisms  # noqa: E402
import ddatai.pardiso as pardiso  # noqa: E402
import ddatai.start as start  # noqa: E402
import scaling_scenes  # noqa: E402

#: the parts: (label, module file ending, function name) of functions whose cumulative times do
#: not nest in one another on the stage's path (the solver's own calls are counted apart)
PARTS = [
    ("detection (`Stepper.detect`)", "step.py", "detect"),
    ("contacts at a pseudo-step's start (`Contacts.start`)", "contacts.py", "start"),
    ("frame: contact vectors, pattern, block terms (`Frame.build`)", "return_mapping.py", "build"),
    ("re-assembly each iterate (`ContactSystem.system`)", "reassembly.py", "system"),
    ("contact law (`stage_law`)", "contact_law.py", "stage_law"),
    ("line search (`return_steps.line_search`)", "return_steps.py", "line_search"),
    ("Anderson mixing", "return_steps.py", "anderson"),
    ("mechanism checks (`mechanisms`, `anchored` in the iterate)", "mechanisms.py", "anchored"),
    ("limit equilibrium (`unsupported_blocks`)", "limit_equilibrium.py", "unsupported_blocks"),
    ("open-close finish / test (`open_close.open_close`)", "open_close.py", "open_close"),
    ("balance check (`start.balanced`)", "start.py", "balanced"),
    ("updates of low rank, less their PARDISO calls (`lowrank.solve_updated`)", "lowrank.py", "solve_updated"),
]
#: with ``--updates``: CHOLMOD's part of the solver (its factorisations, updates, refinements; PARDISO's
#: calls inside it, an LU where K is not positive definite, are in PARDISO's rows)
UPDATES = [("CHOLMOD: factorisations, rank updates, their refinement (`Solver._solve_updating`)", "solver.py",
            "_solve_updating")]


def _pardiso_under(stats, file: str) -> float:
    """CPU of PARDISO's calls made from functions of ``file`` (through the factor's solve, a lambda
    of `ddatai.solver`)."""
    spent = 0.0
    for (f, _, fn), (_, _, _, _, callers) in stats.items():
        if f.endswith("solver.py") and fn == "<lambda>":
            for caller, (_, _, _, ct) in callers.items():
                if caller[0].endswith(file):
                    spent += ct
    return spent


def main():
    family, n = sys.argv[1], int(sys.argv[2])
    scene, params = getattr(scaling_scenes, f"{family}_scene")(n)
    if "--updates" in sys.argv:  # CHOLMOD's rank updates (`Params.factor_updates`, the [cholmod] extra)
        import dataclasses
        params = dataclasses.replace(params, factor_updates=True)
    phases: dict = {}
    call, test = pardiso._Pardiso.call, mechanisms.open_close
    inside = [False, 0.0]  # in the open-close iteration; PARDISO's CPU there
    staging = [False]  # in the stage (not the run's step after it)

    def timed(self, phase, *args, **kw):
        if not staging[0]:
            return call(self, phase, *args, **kw)
        t = time.process_time()
        try:
            return call(self, phase, *args, **kw)
        finally:
            count, cpu = phases.get(phase, (0, 0.0))
            phases[phase] = (count + 1, cpu + time.process_time() - t)
            if inside[0]:
                inside[1] += time.process_time() - t

    def tested(*args, **kw):
        inside[0] = True
        try:
            return test(*args, **kw)
        finally:
            inside[0] = False

    profile = cProfile.Profile(time.process_time)  # CPU time, as the rest (its default is wall time)
    stage = start._stage
    cpu = [0.0]

    def profiled(*args, **kw):
        t = time.process_time()
        staging[0] = True
        profile.enable()
        try:
            return stage(*args, **kw)
        finally:
            profile.disable()
            staging[0] = False
            cpu[0] += time.process_time() - t

    plain = [0.0]
    if "--warm" in sys.argv:
        t = time.process_time()
        dd.simulate(scene, params, steps=1)
        print(f"first run in this process (unmeasured parts included): {time.process_time() - t:.2f} s CPU")
    if "--plain" not in sys.argv:
        pardiso._Pardiso.call, start._stage, mechanisms.open_close = timed, profiled, tested
    else:
        def timed_stage(*args, **kw):
            t = time.process_time()
            try:
                return stage(*args, **kw)
            finally:
                plain[0] += time.process_time() - t
        start._stage = timed_stage
    r = dd.simulate(scene, params, steps=1)
    record = dict(zip(r.start.dtype.names, r.start[0].tolist()))
    print(family, n, {k: record[k] for k in ("solves", "factorisations", "held", "released", "in_doubt")})
    if "--plain" in sys.argv:
        print(f"stage CPU (plain) {plain[0]:.2f} s")
        return
    stats = pstats.Stats(profile).stats
    print(f"stage CPU with the profiler {cpu[0]:.2f} s")
    print("| part | calls | CPU s | share |\n|---|---|---|---|")
    factor = sum(c for p, (_, c) in phases.items() if p in (13, 23))
    nf = sum(k for p, (k, _) in phases.items() if p in (13, 23))
    solve_n, solve_c = phases.get(33, (0, 0.0))
    rows = [(f"PARDISO factorisation + solve (phases 13/23; analysis {phases.get(13, (0, 0))[0]} times)", nf, factor),
            ("PARDISO solve with the factor (phase 33)", solve_n, solve_c)]
    inside_oc = 0.0
    for label, file, name in PARTS + (UPDATES if "--updates" in sys.argv else []):
        hit = [(v[0], v[3]) for (f, _, fn), v in stats.items() if f.endswith(file) and fn == name]
        spent = sum(h[1] for h in hit)
        if name == "open_close":
            inside_oc, spent = spent, spent - inside[1]  # its PARDISO calls are in their rows
        if name == "solve_updated":  # its PARDISO calls (the columns of Z, the solves) are in their rows
            spent -= _pardiso_under(stats, "lowrank.py")
        if name == "_solve_updating":
            spent -= sum(c for (f, _, fn), (_, _, _, c, callers) in stats.items()
                         if f.endswith("pardiso.py") and fn == "call"
                         for caller in callers if caller[2] == "_solve_updating")
        rows.append((label, sum(h[0] for h in hit), spent))
    for label, calls, c in rows:
        print(f"| {label} | {calls} | {c:.2f} | {c / cpu[0]:.0%} |")
    counted = sum(c for _, _, c in rows)
    print(f"| rest (the iterates' own NumPy work, bookkeeping) | | {cpu[0] - counted:.2f} | "
          f"{(cpu[0] - counted) / cpu[0]:.0%} |")
    print(f"(the open-close iteration: {inside_oc:.2f} s, of which PARDISO {inside[1]:.2f} s, counted in "
          "PARDISO's rows; PARDISO's calls are counted there, not in the parts that make them)")
    top = sorted(((v[2], f"{Path(f).name}:{fn}", v[0]) for (f, _, fn), v in stats.items()), reverse=True)[:15]
    print("largest own times:", "; ".join(f"{name} {t:.2f} s ({n})" for t, name, n in top))


if __name__ == "__main__":
    main()
