"""Does a held member's equilibrium stage follow a path that its joints' strength does not change?

    python benchmarks/stage_friction_path.py [--n 200] [--sweep 24,30,40,50,60,70] [--json out.json]

The question behind sharing one member's stage with the others of a study: the members of
Example II's DDA-judged study (``benchmarks/probabilistic.py``: friction N(22°, 2°), cohesion
N(20 kPa, 5 kPa), seed 1, group {0, 1} of ``scenes/example_2.py``) differ only in their joints'
strength. In the stage's return mapping (`ddatai.return_mapping._iterate`) the strength enters
only through the Coulomb test of each closed vertex-edge contact with a shear spring: its slip
grows by (|k_s·ds| − S)/k_s where |k_s·ds| > S = N·tanφ + c·L (bonded); K, F, the line search
and the normal tests do not read it while every such contact is locked. So a stage in which no
contact ever exceeds its strength would be the same, to the bit, at any strength that keeps
every one of those tests (and the limit-equilibrium screen's answer) as it was, and could be
run once for all such members.

This script settles each member alone (`ddatai.start.settle`) and watches every contact-law
evaluation of its return mapping (`return_mapping.stage_law`): the friction each closed
shear-spring contact needs there to stay locked, tanφ ≥ (|k_s·ds| − c·L·bond)/N, and whether
any contact exceeds its strength (a slip increment). It prints, over the held members, the
friction their first iterate needs (the elastic solution with every contact locked, which no
strength changes), how many of their stages slide a contact, and, for the first held member,
how far its settled vertices move when its friction changes by 1e-9° and its cohesion by one
part in 1e12. Single thread (BLAS one thread); the stage's own NumPy path.
"""

from __future__ import annotations

import argparse
import json
import os

for _k in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "TI_CPU_MAX_NUM_THREADS"):
    os.environ.setdefault(_k, "1")

import statistics  # noqa: E402
import sys  # noqa: E402
from contextlib import contextmanager  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]


@contextmanager
def watched_law(record: list):
    """While the body runs, each evaluation of the return mapping's contact law appends
    (the largest tanφ a closed shear-spring contact needs to stay locked, whether any exceeds
    its strength) to ``record``."""
    from ddatai import return_mapping
    from ddatai.layout import KIND, VE

    law_of = return_mapping.stage_law

    def watching(model, contacts, vec, sca, disp):
        law = law_of(model, contacts, vec, sca, disp)
        ve = contacts.cint[:, KIND] == VE
        cohesion = contacts.cohesion * contacts.length * contacts.bond
        shearing = ve & ((contacts.tan_phi > 0.0) | ((contacts.cohesion * contacts.length > 0.0) & contacts.bond))
        closed = shearing & law.closed
        trial = np.abs(model.shear_penalty * law.ds)
        normal = model.penalty * np.maximum(-law.dn, 0.0)
        need = np.where(trial <= cohesion, 0.0,
                        (trial - cohesion) / np.where(normal > 0.0, normal, np.nan))  # N = 0: only c holds it
        need = np.where(np.isnan(need), np.inf, need)
        # the test of `_iterate` (``excess > 0``: a slip increment)
        slides = bool(np.any(closed & (trial - law.strength > 0.0)))
        record.append((float(np.max(np.where(closed, need, 0.0), initial=0.0)), slides))
        return law

    return_mapping.stage_law = watching
    try:
        yield
    finally:
        return_mapping.stage_law = law_of


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=200)
    ap.add_argument("--json", default="")
    ap.add_argument("--sweep", default="", help="frictions [°] (comma-separated) at which one member of "
                    "cohesion 20 kPa is also settled and watched, e.g. 24,30,40,50,60,70")
    a = ap.parse_args()
    sys.path.insert(0, str(ROOT))

    import ddatai as dd
    from ddatai.io.scenefile import build_scene
    from ddatai.model import build_model
    from ddatai.parallel import ScriptFunction
    from ddatai.start import settle
    from ddatai.step import Stepper
    from kgm.build import prepare
    from kgm.judges.run import RunPlan, sub_scene
    from kgm.settings import DdaSettings, Settings
    from kgm.studies.sampling import read_variables, sample_variables

    variables, correlation = read_variables(ROOT / "docs" / "kgm" / "example_2_vars.toml")
    samples = sample_variables(variables, a.n, seed=1, correlation=correlation)
    build = ScriptFunction(str(ROOT / "scenes" / "example_2.py"))
    settings = Settings(dda=DdaSettings(params=dd.Params(dt=0.0013, penalty_ratio=1.0, kernels="fused")))
    blocks = frozenset({0, 1})

    def member(friction: float, cohesion: float):
        scene, params = build_scene(build, friction=friction, cohesion=cohesion)
        problem = prepare(scene, settings=settings, params=params)
        plan = RunPlan.of(problem.system, blocks, settings.dda, problem.params)
        sub, _ = sub_scene(problem.scene, problem.system, blocks, free_neighbours=plan.free_neighbours)
        model = build_model(sub, plan.params)
        record: list = []
        with watched_law(record):
            state, start = settle(Stepper(model), model.initial_state())
        return state, start, record

    rows, first_held = [], None
    for i in range(a.n):
        friction, cohesion = float(samples["friction"][i]), float(samples["cohesion"][i])
        state, start, record = member(friction, cohesion)
        first_need = float(np.degrees(np.arctan(record[0][0]))) if record else None
        rows.append(dict(i=i, friction=friction, cohesion=cohesion, held=start.held, released=start.released,
                         solves=start.solves, at_strength=start.at_strength, evaluations=len(record),
                         sliding_evaluations=sum(s for _, s in record), first_iterate_needs=first_need))
        if start.held and first_held is None:
            first_held = (friction, cohesion, state, start)
    held = [r for r in rows if r["held"]]
    print(f"# {dd.__file__}; {a.n} samples of Example II's study (seed 1); load {os.getloadavg()[0]:.2f}")
    print(f"held members: {len(held)}, released: {a.n - len(held)} "
          f"(released at the screen, no solve: {sum(1 for r in rows if not r['held'] and r['solves'] == 0)})")
    if held:
        needs = [r["first_iterate_needs"] for r in held]
        print(f"held members whose stage slides a contact (a slip increment): "
              f"{sum(1 for r in held if r['sliding_evaluations'])} of {len(held)}; "
              f"ending with contacts at their strength: {sum(1 for r in held if r['at_strength'])}")
        print(f"friction their first iterate needs to stay locked [°]: min {min(needs):.2f}, "
              f"median {statistics.median(needs):.2f}, max {max(needs):.2f}; their own friction "
              f"{min(r['friction'] for r in held):.2f}–{max(r['friction'] for r in held):.2f}")
        print(f"members whose friction is at least what their first iterate needs: "
              f"{sum(1 for r in rows if r['first_iterate_needs'] is not None and r['friction'] >= r['first_iterate_needs'])}")
        friction, cohesion, state, start = first_held
        for label, f, c in (("friction + 1e-9°", friction + 1e-9, cohesion),
                            ("cohesion × (1 + 1e-12)", friction, cohesion * (1.0 + 1e-12))):
            other, again, _ = member(f, c)
            print(f"first held member (φ {friction:.4f}°, c {cohesion:.1f} Pa), {label}: held {again.held}, "
                  f"solves {again.solves} (was {start.solves}), settled vertices move by up to "
                  f"{float(np.abs(other.vertex_xy - state.vertex_xy).max()):.3g} m")
    for friction in (float(f) for f in a.sweep.split(",") if f):
        _, start, record = member(friction, 20e3)
        need = f"{np.degrees(np.arctan(record[0][0])):.2f}°" if record else "-"
        print(f"friction {friction:g}°, cohesion 20 kPa: held {start.held}, solves {start.solves}, law evaluations "
              f"sliding a contact {sum(s for _, s in record)} of {len(record)}, at strength {start.at_strength}, "
              f"first iterate needs {need}")
    if a.json:
        Path(a.json).write_text(json.dumps(rows))


if __name__ == "__main__":
    main()
