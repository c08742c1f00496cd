"""Block toppling: limit equilibrium (kgm rigid/sarma) against DDA on two published cases.

    python benchmarks/toppling.py [--no-dda] [--tolerance DEG] [--fs-tolerance F]
                                  [--case {goodman-bray,alejano-alonso,all}]

**Goodman & Bray's example.** The critical friction angle of the textbook row (blocks 1–13;
Hoek & Bray 1981, Wyllie & Mah 2004 §10.3: 38.15°) from the Goodman–Bray recursion of `kgm`
and from ddatai DDA (`kgm.critical_friction(..., method="dda")`: bisection on φ of every joint,
the group and the blocks it touches simulated from gravitational equilibrium).

**Alejano & Alonso's block toppling** (Problem 2 of Rocscience's Phase2/RS2 joint verification
manual; section as transcribed by XSLOPE, `benchmarks/rocscience/build_joint_problems.py`
`rj002`): a 9.85 m face at 58.65° from the toe (20, 10) to (14, 19.85), a basal joint at 30°
from the toe to the crest line at (2.9393, 19.85), columns at 64° spaced 1.6 m through the toe,
φ = 31° and c = 0 on both sets, γ = 25 kN/m³ (rock E = 20 GPa, ν = 0.3, as the manual's model).
The two sets cut 13 columns out of the 54.47 m² triangle above the basal joint (1361.8 kN/m).
References: Goodman & Bray's limit equilibrium as published by Alejano & Alonso, FS = 0.76;
the same recursion on the real 13 columns (XSLOPE's recomputation, and kgm), 0.7734; UDEC, 0.87.
The factor of safety here is by strength reduction (tanφ/F on every joint,
`kgm.factor_of_safety(..., method="dda")`, geometric bisection to ``--fs-tolerance``), on two
versions of the ground in front of the toe:

- *daylighting*: the rock in front of the toe follows the basal plane down, so the toe is free
  (the recursion's assumption, and `scenes/toppling_slope.py`'s convention);
- *bench*: the manual's model, a horizontal ground at the toe's level (y = 10 m) in front of it.
  The toe block's base ends on that ground's edge, which blocks it from sliding down the 30°
  plane; limit equilibrium sees a point contact there and treats the toe as free.

Measured (2-core AMD EPYC, default `DdaSettings`, the whole run 64 s): Goodman & Bray's
φc = 38.28° by DDA (39 s) against 38.15°; Alejano & Alonso's DDA FS = 0.779 with the base plane
daylighting (stable at 0.773, unstable at 0.784; 7 runs, 9 s; with --fs-tolerance 0.005:
0.773–0.776) against the recursion's 0.7734, and 1.044 with the bench (1.037–1.051; 8 runs,
15 s): the bench holds the toe (docs/kgm/method.md §4.5). With the batched K-section (the default
since, 16 probes a run; a loaded 2-core Intel Xeon): φc = 38.27° (42 s), FS 0.779 (0.773 –
0.785, 12 s) and, with the bench, 1.024: DDA's verdicts alternate between F = 1.004 and 1.049
there (the printed bracket turns over; docs/kgm/method.md §6.4). Again on 2026-11-29 (main, the
closing round's fewest probes; 2-core AMD EPYC, load ~2): FS 0.766 (0.759 – 0.773, 16 runs, 19 s)
with the base plane daylighting, and with the bench 0.957 (stable at 1.000, unstable at 0.916:
turned over; 8 runs, 6 s). The daylighting FS is held within 4 % of the recursion's 0.7734 by
`tests/test_kgm_toppling.py::test_published_case_alejano_alonso_by_dda_with_the_toe_free` (slow).
"""

import argparse
import math
import platform
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # the repository root: scenes/
import ddatai as dd  # noqa: E402
import kgm  # noqa: E402
from ddatai.io.scenefile import build_scene  # noqa: E402
from scenes import toppling_slope  # noqa: E402

#: Alejano & Alonso's case (RS2 joint verification manual, Problem 2)
AA_TOE, AA_FACE_TOP, AA_CREST = (20.0, 10.0), (14.0, 19.85), (2.9393, 19.85)
AA_BASE_DIP, AA_COLUMN_DIP, AA_SPACING = 30.0, 64.0, 1.6  # degrees, degrees, m
AA_FRICTION = 31.0          # degrees, both sets, no cohesion
AA_UNIT_WEIGHT = 25e3       # γ [N/m³]
AA_PUBLISHED_LE = 0.76      # Goodman & Bray's recursion as Alejano & Alonso publish it
AA_RECOMPUTED_LE = 0.7734   # the same recursion on the real 13 columns (XSLOPE)
AA_UDEC = 0.87
AA_RS2 = (0.86, 0.82)       # without / with "joint improvement"


def alejano_alonso_section(friction: float = AA_FRICTION, toe_ground: str = "daylight",
                           young: float = 20e9):
    """Alejano & Alonso's block-toppling section: (scene, params).

    Block 0 is the fixed rock below the basal joint; blocks 1–13 are the columns the 64° set
    cuts out of the triangle above it, numbered from the toe (ids ordered by centroid, bottom
    to top). ``toe_ground``: "daylight" (the rock in front of the toe follows the basal plane
    down: the toe is free, as the recursion assumes) or "bench" (the manual's model: a
    horizontal ground at the toe's level). ``friction`` [degrees] of every joint, c = 0.
    """
    toe, top, crest = (np.array(p) for p in (AA_TOE, AA_FACE_TOP, AA_CREST))
    rock = dd.Material(density=AA_UNIT_WEIGHT / 9.81, young=young, poisson=0.3)
    joint = dd.Joint(friction=friction, cohesion=0.0, tensile=0.0)
    scene = dd.Scene(gravity=9.81)
    down_dip = np.array([math.cos(math.radians(AA_BASE_DIP)), -math.sin(math.radians(AA_BASE_DIP))])
    if toe_ground == "daylight":
        out = toe + 20.0 * down_dip
        outline = [(0.0, -1.0), (out[0], -1.0), tuple(out), tuple(toe), tuple(crest), (0.0, 19.85)]
    elif toe_ground == "bench":  # the manual's 30 x 19.85 m section
        outline = [(0.0, 0.0), (30.0, 0.0), (30.0, 10.0), tuple(toe), tuple(crest), (0.0, 19.85)]
    else:
        raise ValueError(f"toe_ground must be 'daylight' or 'bench', not {toe_ground!r}")
    scene.add_block(outline, material=rock, fixed=True)
    # the column set: traces at 64°, 1.6 m apart (measured across them) from the one through the
    # toe, each from the basal joint up through the ground surface (cut clips them)
    along = np.array([math.cos(math.radians(AA_COLUMN_DIP)), math.sin(math.radians(AA_COLUMN_DIP))])
    across = np.array([-along[1], along[0]])  # into the slope
    basal = (crest - toe) / np.linalg.norm(crest - toe)
    traces, k = [], 1
    while True:
        s = AA_SPACING * k / float(basal @ across)  # where trace k meets the basal joint
        if s >= np.linalg.norm(crest - toe):
            break
        foot = toe + s * basal
        traces.append((np.array([foot - 0.5 * along, foot + 20.0 * along]), joint))
        k += 1
    scene.cut([tuple(toe), tuple(top), tuple(crest)], traces, material=rock)
    scene.set_joint(joint)
    return scene, dd.Params(dt=0.002, penalty_ratio=10.0)


def goodman_bray(args) -> None:
    scene, params = build_scene(toppling_slope, friction=toppling_slope.PUBLISHED_CRITICAL_FRICTION)
    group = list(range(13))  # textbook blocks 1–13
    print("Goodman & Bray's example (blocks 1-13)\n")
    print("| method | critical friction angle | wall time |")
    print("|---|---|---|")
    print(f"| published (Goodman & Bray 1976) | {toppling_slope.PUBLISHED_CRITICAL_FRICTION:.2f}° | - |")
    methods = ("rigid", "sarma") if args.no_dda else ("rigid", "sarma", "dda")
    settings = kgm.Settings(dda=kgm.DdaSettings(friction_tolerance=args.tolerance))
    for m in methods:
        t0 = time.perf_counter()
        phi = kgm.critical_friction(scene, group, method=m, settings=settings, params=params)
        print(f"| kgm {m} | {phi:.2f}° | {time.perf_counter() - t0:.1f} s |", flush=True)


def alejano_alonso(args) -> None:
    print(f"\nAlejano & Alonso's block toppling (RS2 joint verification, Problem 2), phi = {AA_FRICTION:g} deg\n")
    print("| method | ground in front of the toe | FS | bracket (stable – unstable) | wall time |")
    print("|---|---|---|---|---|")
    print(f"| Goodman & Bray, published (Alejano & Alonso) | free | {AA_PUBLISHED_LE:.2f} | - | - |")
    print(f"| Goodman & Bray on the 13 columns (XSLOPE) | free | {AA_RECOMPUTED_LE:.4f} | - | - |")
    print(f"| UDEC (Alejano & Alonso) | not stated | {AA_UDEC:.2f} | - | - |")
    print(f"| RS2 without / with joint improvement | bench (the manual's model) "
          f"| {AA_RS2[0]:.2f} / {AA_RS2[1]:.2f} | - | - |")
    columns = list(range(1, 14))
    scene, _ = alejano_alonso_section()
    for m in ("rigid", "sarma"):
        t0 = time.perf_counter()
        fs = kgm.factor_of_safety(scene, columns, method=m)
        print(f"| kgm {m} | free | {fs:.4f} | - | {time.perf_counter() - t0:.1f} s |", flush=True)
    if args.no_dda:
        return
    for ground, label in (("daylight", "daylighting base plane"), ("bench", "bench at the toe's level")):
        scene, params = alejano_alonso_section(toe_ground=ground)
        runs = []
        settings = kgm.Settings(dda=kgm.DdaSettings(fs_tolerance=args.fs_tolerance, progress=runs.append))
        t0 = time.perf_counter()
        fs = kgm.factor_of_safety(scene, columns, method="dda", settings=settings, params=params)
        wall = time.perf_counter() - t0
        stable = [r.reduction for r in runs if r.stable]
        unstable = [r.reduction for r in runs if not r.stable]
        lo = max(stable) if stable else 0.0
        hi = min(unstable) if unstable else math.inf
        print(f"| kgm dda ({len(runs)} runs) | {label} | {fs:.3f} | {lo:.3f} – {hi:.3f} | {wall:.0f} s |",
              flush=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--no-dda", action="store_true", help="limit equilibrium only")
    ap.add_argument("--tolerance", type=float, default=0.25, help="DDA bisection bracket on φ [degrees]")
    ap.add_argument("--fs-tolerance", type=float, default=0.02,
                    help="DDA bisection bracket on FS, hi/lo − 1 (Alejano & Alonso's case)")
    ap.add_argument("--case", choices=("goodman-bray", "alejano-alonso", "all"), default="all")
    args = ap.parse_args()
    print(f"machine: {platform.processor() or platform.machine()}, Python {platform.python_version()}\n")
    if args.case in ("goodman-bray", "all"):
        goodman_bray(args)
    if args.case in ("alejano-alonso", "all"):
        alejano_alonso(args)


if __name__ == "__main__":
    main()
