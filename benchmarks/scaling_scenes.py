"""The model families of the scaling benchmarks, and the ``--params`` text they all read.

Three families, each a function of the wanted block count that returns ``(scene, params)``:

- ``grid``: ntdda's scaling scene (``docs/ntdda.md`` §5) with its parameters: a
  fitted n × n grid of 1 m blocks on a fixed base, ρ = 2000 kg/m³, E = 100 MPa, ν = 0.25, plane
  stress, p = 1e9 N/m, φ = 30°, dynamic, Δt = 1 ms, step displacement g2·w0 = 0.03 m;
- ``stiffgrid``: the same grid in stiff rock (``scenes/stacked_grid.py``, gap 0: E = 5 GPa,
  ρ = 2500 kg/m³, automatic penalty 50·E = 250 GPa, plane strain, Δt = 1 ms). Its contact
  springs (period 2π·√(m/p) = 0.6 ms) are not resolved by the step, so the sudden start rings
  hard and the open-close iteration takes 3× as many iterations as on ``grid``;
- ``slope``: a 60° rock slope cut by two persistent joint sets (35° bedding, 105° cross set)
  whose spacing is chosen for the wanted block count; blocks below the toe and far behind the
  face are fixed; dynamic, Δt = 1 ms.

`benchmarks/scaling.py` times them; `benchmarks/oc_diagnosis.py` and `solve_changes.py` take one
case apart (their shared command line: `case_parser`, `case_scene`).
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "benchmarks" / "results"
GRID_STEP = 0.03  # ntdda's grid runs: largest step displacement g2·w0 [m]


def slope_scene(n_blocks: int):
    """A slope cut by two persistent joint sets, spacing chosen for about ``n_blocks`` blocks."""
    import ddatai as dd

    rock = dd.Material(density=2600.0, young=10e9, poisson=0.25)
    scene = dd.Scene(gravity=9.81)
    height = 30.0
    toe = (10.0, 0.0)
    crest = (10.0 + height / math.tan(math.radians(60.0)), height)
    outline = [(0.0, -6.0), (60.0, -6.0), (60.0, height), crest, toe, (0.0, 0.0)]
    area = 60.0 * 36.0 - 0.5 * height * (crest[0] - toe[0]) - 10.0 * height
    # 0.63: measured ratio of blocks to area·sinα/s² (blocks cut by the outline are smaller)
    spacing = math.sqrt(0.63 * area * math.sin(math.radians(70.0)) / n_blocks)
    sets = [dd.JointSet(dip=35.0, spacing=spacing, joint=dd.Joint(friction=28.0)),
            dd.JointSet(dip=105.0, spacing=spacing, joint=dd.Joint(friction=35.0))]
    # slivers (a few mm² where three joints nearly meet) merged into a neighbour, as the scenes
    # do: left in, one of them holds the sudden start of the 1,600-block slope in an
    # open-close cycle at Δt = 3e-7 s
    ids = scene.cut(outline, dd.joint_sets(outline, sets, seed=1), material=rock, slivers="merge")
    centroid = np.array([scene.polygon(b).mean(axis=0) for b in ids])
    for b, c in zip(ids, centroid):
        if c[1] < 0.0 or c[0] > 50.0:
            scene.set_fixed(b)
    return scene, dd.Params(dt=1e-3)


def grid_scene(n_blocks: int):
    """ntdda's grid (docs/ntdda.md §5) with ntdda's material, penalty and step limit."""
    import ddatai as dd

    n = int(round(math.sqrt(n_blocks)))
    scene = dd.Scene(gravity=9.81)
    rock = dd.Material(density=2000.0, young=1e8, poisson=0.25)
    scene.add_block([(-1, -1), (n + 1, -1), (n + 1, 0), (-1, 0)], material=rock, fixed=True)
    for j in range(n):
        for i in range(n):
            scene.add_block([(i, j), (i + 1, j), (i + 1, j + 1), (i, j + 1)], material=rock)
    scene.set_joint(dd.Joint(friction=30.0))
    # ntdda fixed g2·w0 = 0.03 m for every N; ddatai's w0 is half the larger side (n + 2 m),
    # at most 10 × the block size (`build_model`; run_one checks the result)
    w0 = min(0.5 * (n + 2), 10.0)
    return scene, dd.Params(dt=1e-3, penalty=1e9, plane="stress", max_displacement_ratio=GRID_STEP / w0)


def stiffgrid_scene(n_blocks: int):
    sys.path.insert(0, str(ROOT))
    from scenes.stacked_grid import build

    n = int(round(math.sqrt(n_blocks)))
    return build(n, gap=0.0, static=False, dt=1e-3)


SCENES = {"grid": grid_scene, "stiffgrid": stiffgrid_scene, "slope": slope_scene}


def parse_params(text: str) -> dict:
    """``--params`` "NAME=VALUE,..." as Params fields (True/False, None, numbers, else text)."""
    out = {}
    for item in filter(None, (text or "").split(",")):
        name, value = item.split("=", 1)
        if value in ("True", "False"):
            out[name] = value == "True"
        elif value == "None":
            out[name] = None
        else:
            try:
                out[name] = float(value) if any(ch in value for ch in ".e") else int(value)
            except ValueError:
                out[name] = value
    return out



def use_checkout() -> None:
    """Put this checkout first on the import path, so that ``import ddatai`` is the code beside
    this script and not a copy installed elsewhere (an editable install of another worktree)."""
    for path in (str(ROOT / "benchmarks"), str(ROOT)):
        if path in sys.path:
            sys.path.remove(path)
        sys.path.insert(0, path)


def case_parser(doc: str, size: int = 391, steps: int = 4) -> argparse.ArgumentParser:
    """The command line of a one-case diagnostic: ``--family``, ``--size``, ``--steps`` and
    ``--params`` (Params fields, as `parse_params` reads them); the caller adds its own."""
    ap = argparse.ArgumentParser(description=doc.splitlines()[0])
    ap.add_argument("--family", default="slope", choices=tuple(SCENES))
    ap.add_argument("--size", type=int, default=size)
    ap.add_argument("--steps", type=int, default=steps)
    ap.add_argument("--params", default="", help="Params fields NAME=VALUE,... (as scaling.py)")
    return ap


def case_scene(args: argparse.Namespace):
    """The scene and the Params of the case ``args`` names, ``--params`` applied."""
    scene, params = SCENES[args.family](args.size)
    return scene, dataclasses.replace(params, **parse_params(args.params))


def protocol_steps(size: int) -> int:
    """Timed steps per size of ntdda's scaling runs (100 for N ≤ 1,024, 20 at 4,096, 4 at 16,384),
    with 1,600 taken with the small sizes."""
    return 100 if size <= 1600 else 20 if size <= 6400 else 4
