"""Behaviour fingerprint: run a fixed set of models and record every array they produce, to
check that a restructuring of the code changes nothing.

    python benchmarks/behaviour.py record DIR      # run the set, write DIR/<case>.npz
    python benchmarks/behaviour.py compare A B     # every array of A and B identical?

The set: every scene script in ``scenes/`` (its own build and Params, 40 steps, contacts and
their forces recorded), the verification cases of ``tests/cases.py`` (a block sliding on an
incline, the bi-planar pair, a randomly jointed scene, a block launched onto a slope) and the
three scaling families of ``benchmarks/scaling.py`` at 100, 400 and 400 blocks. Every run uses
``Params(solver="scipy")`` (SuperLU is deterministic; PARDISO's results may differ in their
last bits between processes) and records the equilibrium stage, every frame and every step
record; the step records' wall times (``t_*``) and the stage's ``wall_time`` are dropped.
``compare`` reports each array that differs (shape, or the largest difference), and the
solve counts (open-close iterations) side by side; it exits 1 when anything differs.
"""

from __future__ import annotations

import dataclasses
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT), str(ROOT / "benchmarks")]

STEPS = 40
WALL = ("t_contacts", "t_assembly", "t_solve", "t_update", "t_judge", "t_accept", "t_time_step",
        "t_energy", "wall_time")


def _scene_cases():
    from ddatai.io.scenefile import build_scene, load_scene_script

    for path in sorted((ROOT / "scenes").glob("*.py")):
        if path.name.startswith("_"):
            continue
        script = load_scene_script(path)
        try:
            scene, params = build_scene(script.build)
        except ImportError as err:  # an optional extra (the DXF section needs ezdxf)
            print(f"skip {path.stem}: {err}")
            continue
        yield path.stem, scene, params


def _verification_cases():
    import ddatai as dd
    from tests import cases

    scene, _ = cases.sliding_scene(30.0, 20.0)
    yield "sliding_block_30_20", scene, dd.Params(dt=1e-3)
    yield "biplanar_30", cases.biplanar_scene(30.0)[0], dd.Params()
    yield "random_jointed_3", cases.random_jointed_scene(3), dd.Params()
    launched = cases.launched_block(30.0, 20.0, 2.0)
    yield "launched_block", launched[0], dd.Params(dt=1e-3)


def _scaling_cases():
    import scaling

    yield "grid_100", *scaling.grid_scene(100)
    yield "stiffgrid_400", *scaling.stiffgrid_scene(400)
    yield "slope_400", *scaling.slope_scene(400)


def cases():
    yield from _scene_cases()
    yield from _verification_cases()
    yield from _scaling_cases()


def record(directory: Path) -> None:
    import ddatai as dd

    directory.mkdir(parents=True, exist_ok=True)
    for name, scene, params in cases():
        params = dataclasses.replace(params if params is not None else dd.Params(), solver="scipy")
        res = dd.simulate(scene, params, steps=STEPS, record_every=1, record_contacts=True)
        arrays = {}
        for f in dataclasses.fields(res):
            value = getattr(res, f.name)
            if isinstance(value, np.ndarray) and value.dtype.names:
                for field in value.dtype.names:
                    if field not in WALL:
                        arrays[f"{f.name}.{field}"] = value[field]
            elif isinstance(value, np.ndarray):
                arrays[f.name] = value
        np.savez(directory / f"{name}.npz", **arrays)
        oc = int(res.steps["oc_total"].sum())
        print(f"{name}: {len(res.steps)} steps, {oc} open-close solves, stage "
              f"{int(res.start['solves'][0]) if len(res.start) else 0} solves")


def compare(a: Path, b: Path) -> int:
    differ = 0
    names = sorted({p.name for p in a.glob("*.npz")} | {p.name for p in b.glob("*.npz")})
    for name in names:
        if not (a / name).exists() or not (b / name).exists():
            print(f"{name}: only in one set")
            differ += 1
            continue
        x, y = np.load(a / name), np.load(b / name)
        bad = []
        for key in sorted(set(x.files) | set(y.files)):
            if key.split(".")[-1] in WALL:  # wall times (new phases are timed on their own)
                continue
            if key not in x.files or key not in y.files:
                bad.append(f"{key} only in one")
            elif x[key].shape != y[key].shape:
                bad.append(f"{key} shape {x[key].shape} vs {y[key].shape}")
            elif not np.array_equal(x[key], y[key]):
                diff = np.max(np.abs(x[key].astype(float) - y[key].astype(float)))
                bad.append(f"{key} max diff {diff:.3g}")
        solves = (int(x["steps.oc_total"].sum()), int(y["steps.oc_total"].sum()))
        stage = (int(x["start.solves"].sum()), int(y["start.solves"].sum()))
        status = "identical" if not bad else "DIFFERS: " + "; ".join(bad[:6])
        print(f"{name}: step solves {solves[0]} / {solves[1]}, stage solves {stage[0]} / {stage[1]}: {status}")
        differ += bool(bad)
    print(f"{len(names) - differ} of {len(names)} cases identical")
    return int(differ > 0)


if __name__ == "__main__":
    if len(sys.argv) == 3 and sys.argv[1] == "record":
        record(Path(sys.argv[2]))
    elif len(sys.argv) == 4 and sys.argv[1] == "compare":
        raise SystemExit(compare(Path(sys.argv[2]), Path(sys.argv[3])))
    else:
        raise SystemExit(__doc__)
