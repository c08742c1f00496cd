"""Write ``scenes/section/bedding_mapping.csv``: a virtual scanline survey of the bedding of the example
section, as a field mapper would record it (docs/method/joint_mapping.md).

A rock mass is generated with known bedding statistics (`dd.joint_sets`, seed 11) and mapped in
a 20 m high window along a 300 m horizontal scanline by the mapper of the tests
(tests/mapping_cases.py). ``dd.JointSet.fit`` reads the table back (scenes/section/drawing.py).
Run ``python scenes/section/mapping.py [PATH]``.
"""

import csv
import sys
from pathlib import Path

import ddatai as dd

HERE = Path(__file__).resolve().parent
TABLE = HERE / "bedding_mapping.csv"
LENGTH, WINDOW = 300.0, 20.0   # the survey: scanline length and window height [m]
#: the rock mass the survey maps (what a fit should find, within its sampling error)
BEDDING = dd.JointSet(dip=35.0, spacing=4.0, spacing_spread=0.5, trace_length=20.0, trace_spread=4.0,
                      gap=1.5, gap_spread=0.4)


def write(path=TABLE) -> Path:
    sys.path.insert(0, str(HERE.parents[1] / "tests"))
    from mapping_cases import map_window

    box = [(-40, -25), (LENGTH + 40, -25), (LENGTH + 40, 25), (-40, 25)]
    rows = map_window(dd.joint_sets(box, [BEDDING], seed=11), origin=(0.0, 0.0), trend=0.0, length=LENGTH,
                      window=WINDOW)
    with open(path, "w", newline="") as f:
        f.write(f"# bedding, scanline {LENGTH:g} m trending 0 deg, window {WINDOW:g} m high\n")
        w = csv.DictWriter(f, fieldnames=["dip", "position", "length", "censored", "gap"])
        w.writeheader()
        for r in rows:
            w.writerow({k: ("" if v is None else (f"{v:.3f}" if isinstance(v, float) else v)) for k, v in r.items()})
    return Path(path)


if __name__ == "__main__":
    print(write(sys.argv[1] if len(sys.argv) > 1 else TABLE))
