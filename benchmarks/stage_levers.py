"""A lever of the small-model equilibrium stage against the code it replaced, in one process.

    python benchmarks/stage_levers.py [--samples 40] [--rounds 4] [--lever blas|law|all]

The held members of Example II's DDA-judged study (``benchmarks/study_breakdown.py``'s samples:
group {0, 1} of ``scenes/example_2.py``, friction N(22°, 2°), cohesion N(20 kPa, 5 kPa),
correlated −0.3, seed 1) are settled by ``ddatai.start.settle`` with the lever and with the
code before it put back, member by member, the order alternating, ``--rounds`` times; each
stage's CPU time (this process's: the machine is shared, and a pair in one process sees the
same load) and a hash of each settled state (vertices and contact memory). Levers:

- ``blas``: one BLAS-thread limit around the whole stage (``ddatai.threads.dense_solves``)
  against one a factorisation;
- ``law``: the stage's return mapping evaluating only the contact law's fields it reads
  (``ddatai.contact_law.stage_law``) against the whole law on a coupled copy of its contacts.

Prints, per lever, the mean CPU ms of a held member's stage with and without it, their ratio,
the median ratio of the pairs, and whether every settled state is the same to the bit.
Threads pinned (BLAS one).
"""

from __future__ import annotations

import argparse
import contextlib
import hashlib
import os

for _k in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_k, "1")

import statistics  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def _members(n: int) -> list:
    import ddatai as dd
    from ddatai.io.scenefile import build_scene
    from ddatai.model import build_model
    from ddatai.parallel import ScriptFunction
    from kgm.build import prepare
    from kgm.judges.run import RunPlan, sub_scene
    from kgm.settings import DdaSettings, Settings
    from kgm.studies.sampling import read_variables, sample_variables

    variables, correlation = read_variables(ROOT / "docs" / "kgm" / "example_2_vars.toml")
    samples = sample_variables(variables, n, seed=1, correlation=correlation)
    build = ScriptFunction(str(ROOT / "scenes" / "example_2.py"))
    settings = Settings(dda=DdaSettings(params=dd.Params(dt=0.0013, penalty_ratio=1.0, kernels="fused")))
    blocks = frozenset({0, 1})
    models = []
    for i in range(n):
        scene, params = build_scene(build, friction=float(samples["friction"][i]),
                                    cohesion=float(samples["cohesion"][i]))
        problem = prepare(scene, settings=settings, params=params)
        plan = RunPlan.of(problem.system, blocks, settings.dda, problem.params)
        sub, _ = sub_scene(problem.scene, problem.system, blocks, free_neighbours=plan.free_neighbours)
        models.append(build_model(sub, plan.params))
    return models


def _levers() -> dict:
    """{name: (put the old code back, put the lever back)}."""
    from ddatai import contact_law, contacts as contact_sets, return_mapping, start

    dense_solves, stage_law = start.dense_solves, return_mapping.stage_law

    def whole_law(model, contacts, vec, sca, disp):
        return contact_law.contact_law(model, contact_sets.coupled(contacts), vec, sca, disp)

    def old_blas():
        start.dense_solves = lambda solver: contextlib.nullcontext()

    def new_blas():
        start.dense_solves = dense_solves

    def old_law():
        return_mapping.stage_law = whole_law

    def new_law():
        return_mapping.stage_law = stage_law

    return {"blas": (old_blas, new_blas), "law": (old_law, new_law)}


def _digest(state) -> str:
    h = hashlib.sha256(state.vertex_xy.tobytes())
    for _, v in sorted(vars(state.memory).items()):
        if isinstance(v, np.ndarray):
            h.update(v.tobytes())
    return h.hexdigest()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--samples", type=int, default=40)
    ap.add_argument("--rounds", type=int, default=4)
    ap.add_argument("--lever", default="all", choices=("blas", "law", "all"))
    a = ap.parse_args()
    from ddatai.start import settle
    from ddatai.step import Stepper

    models = _members(a.samples)
    held = [i for i, m in enumerate(models) if settle(Stepper(m), m.initial_state())[1].held]
    levers = _levers()
    names = list(levers) if a.lever == "all" else [a.lever]
    print(f"# {len(held)} held members of {a.samples}, {a.rounds} rounds; load {os.getloadavg()[0]:.1f}")
    for name in names:
        old, new = levers[name]
        times = {True: [], False: []}
        same = True
        for r in range(a.rounds):
            for i in held:
                digests = {}
                for lever_on in ((True, False) if (r + i) % 2 else (False, True)):
                    (new if lever_on else old)()
                    stepper, s0 = Stepper(models[i]), models[i].initial_state()
                    c = time.process_time()
                    state, _ = settle(stepper, s0)
                    times[lever_on].append(time.process_time() - c)
                    digests[lever_on] = _digest(state)
                same &= digests[True] == digests[False]
        new()
        on, off = statistics.fmean(times[True]), statistics.fmean(times[False])
        pairs = statistics.median(b / a for a, b in zip(times[True], times[False]))
        print(f"{name}: {1e3 * on:.2f} ms with, {1e3 * off:.2f} ms without (CPU, a held member's stage); "
              f"without/with {off / on:.3f}, median pair {pairs:.3f}; settled states the same to the bit: {same}")


if __name__ == "__main__":
    main()
