"""What a release at the first failed finish would buy Example II's study (a rule not in the code).

    python benchmarks/late_release.py [--samples 200] [--rounds 3] [--seed 1] [--every-pseudo-step]

Some members of Example II's DDA-judged study (friction N(22°, 2°), cohesion N(20 kPa, 5 kPa),
correlated −0.3, seed 1 or ``--seed``, group {0, 1} of ``scenes/example_2.py``) are released by their
equilibrium stage (`ddatai.start`) only after 60–100 solves: the first pseudo-step's Newton tail
hands the iterate to the open-close finish (``ddatai.return_mapping._finish``), whose test
converges and moves the group away — and the stage goes on (return mapping that stalls,
limit equilibrium that admits forces, frozen iterations that stall again) until the open-close
test from there releases the group. This benchmark runs the stages of the study's members
(``ddatai.limit_batch.settle_many``, batches of 40, as the study settles them) with today's code
and with that rule — where the stage's first finish after a Newton tail (``--every-pseudo-step``:
every pseudo-step's) converges and moves blocks away that their loads drive
(``ddatai.mechanisms.mechanisms`` and ``driven``, as the test of the out-of-balance blocks
decides), they are released there — patched in for the run, alternating
in one process (``--rounds`` each), CPU time; and says, member by member, whether the rule
gives the same held and released blocks and the same settled state (every field but the
cached geometry, to the bit), and how many solves it saves. Threads pinned.

The rule is refuted (benchmarks/results/study_throughput.md): the two open-close tests start
from different iterates, the static problem of non-associated friction has many solutions, and
``--samples 600 --seed 3`` finds a member that the stage holds in part and the rule releases.
"""

from __future__ import annotations

import argparse
import os

for _k in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "TI_CPU_MAX_NUM_THREADS"):
    os.environ.setdefault(_k, "1")

import statistics  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]


def models_of_study(n: int, seed: int = 1) -> list:
    import ddatai as dd
    from ddatai.io.scenefile import build_scene
    from ddatai.model import build_model
    from ddatai.parallel import ScriptFunction
    from kgm.build import prepare
    from kgm.judges.run import RunPlan, sub_scene
    from kgm.settings import DdaSettings, Settings
    from kgm.studies.sampling import read_variables, sample_variables

    variables, correlation = read_variables(ROOT / "docs" / "kgm" / "example_2_vars.toml")
    samples = sample_variables(variables, n, seed=seed, correlation=correlation)
    build = ScriptFunction(str(ROOT / "scenes" / "example_2.py"))
    settings = Settings(dda=DdaSettings(params=dd.Params(dt=0.0013, penalty_ratio=1.0, kernels="fused")))
    out = []
    for i in range(n):
        scene, params = build_scene(build, friction=float(samples["friction"][i]), cohesion=float(samples["cohesion"][i]))
        problem = prepare(scene, settings=settings, params=params)
        plan = RunPlan.of(problem.system, frozenset({0, 1}), settings.dda, problem.params)
        sub, _ = sub_scene(problem.scene, problem.system, frozenset({0, 1}), free_neighbours=plan.free_neighbours)
        out.append(build_model(sub, plan.params))
    return out


def released_at_first_finish(first_only: bool):
    """``_finish`` with the rule: after the Newton tail (``outcome.steady``; ``first_only``: the
    stage's first such finish only, its first pseudo-step), a converged test that moves blocks
    away as their loads drive them marks them in ``out`` (released there)."""
    import weakref

    from ddatai import return_mapping as rm
    from ddatai.mechanisms import driven, mechanisms, test_unbalanced

    seen = weakref.WeakSet()  # the steppers whose first finish after a Newton tail has come

    def finish(stepper, state, geom, frame, contacts, outcome, guess, out, size):
        rule = outcome.steady and not (first_only and stepper in seen)
        if outcome.steady:
            seen.add(stepper)
        finished, n = test_unbalanced(stepper, state, geom, frame, contacts, outcome, guess,
                                      ~stepper.model.block_fixed, rm.MAX_FINISH_SOLVES)
        if finished is None or not finished[2]:
            return None, n
        moving = mechanisms(stepper, state.vertex_xy, geom, finished[1], finished[0], out, size)
        if moving.any():
            if rule:
                out |= driven(stepper, state, geom, finished[1], finished[0], moving)
            return None, n
        disp, done, _ = finished
        rm._shift_lock_points(stepper, state.vertex_xy, done, guess.slip)
        done.coupled[:] = False
        return (disp, done), n

    return finish


def settle_all(models, batch: int = 40):
    from ddatai.limit_batch import settle_many

    states, t = [], time.process_time()
    for b0 in range(0, len(models), batch):
        states += settle_many(models[b0:b0 + batch])
    return states, time.process_time() - t


def records(models):
    """Each member's stage alone (its record: held, released, solves)."""
    from ddatai.start import settle
    from ddatai.step import Stepper

    return [settle(Stepper(m), m.initial_state())[1] for m in models]


def same_state(a, b) -> bool:
    for f in a.__dataclass_fields__:
        if f == "geometry":
            continue
        x, y = getattr(a, f), getattr(b, f)
        if hasattr(x, "__dataclass_fields__"):
            if not same_state(x, y):
                return False
        elif isinstance(x, np.ndarray):
            if not (isinstance(y, np.ndarray) and x.shape == y.shape and x.tobytes() == y.tobytes()):
                return False
        elif x != y and not (x is None and y is None):
            return False
    return True


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--samples", type=int, default=200)
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--seed", type=int, default=1, help="the study's seed (its samples)")
    ap.add_argument("--every-pseudo-step", action="store_true",
                    help="the rule at every pseudo-step's finish after its Newton tail, not the first only")
    a = ap.parse_args()
    from ddatai import return_mapping as rm

    models = models_of_study(a.samples, a.seed)
    today = rm._finish
    print(f"# {a.samples} members, load {os.getloadavg()[0]:.2f}", flush=True)
    times = {"today": [], "rule": []}
    settled = {}
    for r in range(a.rounds):
        for name in ("today", "rule") if r % 2 == 0 else ("rule", "today"):
            rm._finish = today if name == "today" else released_at_first_finish(not a.every_pseudo_step)
            settled[name], t = settle_all(models)
            times[name].append(t)
            print(f"round {r + 1} {name}: {1e3 * t / a.samples:.2f} ms a member's share of its batch's stages",
                  flush=True)
    rm._finish = today
    rec_today = records(models)
    rm._finish = released_at_first_finish(not a.every_pseudo_step)  # its steppers not yet seen
    rec_rule = records(models)
    rm._finish = today
    changed = [k for k, (x, y) in enumerate(zip(rec_today, rec_rule)) if (x.held, x.released) != (y.held, y.released)]
    states = [k for k, (x, y) in enumerate(zip(settled["today"], settled["rule"])) if not same_state(x, y)]
    fewer = [(x.solves, y.solves) for x, y in zip(rec_today, rec_rule) if x.solves != y.solves]
    for name, v in times.items():
        print(f"{name}: median {1e3 * statistics.median(v) / a.samples:.2f} ms a member")
    print(f"held/released changed: {len(changed)} of {a.samples} {changed}; settled state changed: {len(states)} "
          f"{states}; members with other solves: {len(fewer)} (solves {fewer})")


if __name__ == "__main__":
    main()
