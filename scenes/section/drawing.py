"""Write the example section drawing ``scenes/section/section.dxf`` (read by
``scenes/dxf_section.py``).

The drawing is generated, never edited by hand: a 30 m high, 60° slope in metres, cut by the
bedding set fitted to the mapping table ``bedding_mapping.csv`` (`dd.JointSet.fit`, dipping 35°
out of the face) and a steep cross set (`dd.joint_sets`, seed 7), with the fixed rock below the
toe and behind the slope, and two measured points. Layers: DOMAIN, FIXED, POINTS, BEDDING,
CROSS (`ddatai.io.dxf`). Run ``python scenes/section/drawing.py [PATH] [--units mm]``;
`python_scene` builds the same section directly in Python.
"""

from pathlib import Path

import numpy as np

import ddatai as dd

HERE = Path(__file__).resolve().parent
DRAWING = HERE / "section.dxf"
ROCK = dd.Material(density=2600.0, young=10e9, poisson=0.25)
#: the joint properties of each joint layer (the TOML of ``joints.toml`` says the same)
JOINTS = {"BEDDING": dd.BartonBandis(jrc=4.0, jcs=30e6, residual_friction=24.0),
          "CROSS": dd.Joint(friction=35.0)}
DEFAULT_JOINT = dd.Joint(friction=35.0)


def bedding() -> dd.JointSet:
    """The bedding set fitted to the mapping table, with the bedding's joint properties."""
    from scenes.section.mapping import LENGTH, TABLE, WINDOW

    return dd.JointSet.fit(TABLE, length=LENGTH, window=WINDOW, joint=JOINTS["BEDDING"])


def geometry() -> dict:
    """The section in metres: outline, traces (polyline, layer), fixed regions, points."""
    toe, crest = (10.0, 0.0), (10.0 + 30.0 / np.tan(np.radians(60.0)), 30.0)
    outline = np.array([(0.0, -6.0), (60.0, -6.0), (60.0, 30.0), crest, toe, (0.0, 0.0)])
    sets = [bedding(),
            dd.JointSet(dip=105.0, spacing=6.0, trace_length=20.0, gap=1.0, spacing_spread=0.8, dip_spread=4.0,
                        joint=JOINTS["CROSS"])]
    layer = {id(j): name for name, j in JOINTS.items()}
    # traces drawn to a box around the outline, so that those reaching it cross it cleanly
    lo, hi = outline.min(axis=0) - 1.0, outline.max(axis=0) + 1.0
    box = [(lo[0], lo[1]), (hi[0], lo[1]), (hi[0], hi[1]), (lo[0], hi[1])]
    traces = [(xy, layer[id(j)]) for xy, j in dd.joint_sets(box, sets, seed=7)]
    fixed = [np.array([(-1.0, -7.0), (61.0, -7.0), (61.0, 0.0), (-1.0, 0.0)]),
             np.array([(50.0, -7.0), (61.0, -7.0), (61.0, 31.0), (50.0, 31.0)])]
    points = np.array([(crest[0] + 1.0, 29.0), (toe[0] + 6.0, 2.0)])
    return {"boundary": outline, "traces": traces, "fixed": fixed, "points": points}


def python_scene() -> dd.Scene:
    """The same section built in Python (what the drawing must read back to)."""
    import shapely

    g = geometry()
    scene = dd.Scene(gravity=9.81)
    ids = scene.cut(g["boundary"], [(xy, JOINTS[name]) for xy, name in g["traces"]], material=ROCK)
    scene.set_joint(DEFAULT_JOINT)
    regions = shapely.union_all([shapely.Polygon(r) for r in g["fixed"]])
    for b in ids:
        if regions.covers(shapely.Polygon(scene.polygon(b)).centroid):
            scene.set_fixed(b)
    return scene


def write(path=DRAWING, units: str = "m") -> Path:
    """Write the drawing (in ``units``, as its header says)."""
    from ddatai.io.dxf import write_dxf_section

    write_dxf_section(path, units=units, **geometry())
    return Path(path)


if __name__ == "__main__":
    import argparse
    import sys

    sys.path.insert(0, str(HERE.parents[1]))

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("path", nargs="?", default=str(DRAWING))
    ap.add_argument("--units", default="m", help="drawing unit: m, mm, cm, ft, in (default m)")
    args = ap.parse_args()
    print(write(args.path, args.units))
