"""
Slope section from a DXF drawing
================================

A slope section read from a CAD drawing: ``scenes/section/section.dxf`` (written by
``scenes/section/drawing.py`` from the bedding fitted to a mapping table), its joint layers
given Barton–Bandis bedding and Mohr–Coulomb cross joints. Run ``python scenes/dxf_section.py [--gif out/dxf_section.gif]`` or
``kgm analyze scenes/dxf_section.py``."""

import sys
from pathlib import Path

import ddatai as dd

DURATION = 2.0  # s
try:
    HERE = Path(__file__).resolve().parent
except NameError:  # run by the documentation's gallery, which runs a script in its folder
    HERE = Path.cwd().resolve()


def build(drawing: str = str(HERE / "section" / "section.dxf")):
    """Returns (scene read from ``drawing``, params)."""
    if str(HERE.parent) not in sys.path:  # the scenes package, wherever the script is run from
        sys.path.insert(0, str(HERE.parent))
    from scenes.section.drawing import DEFAULT_JOINT, JOINTS, ROCK

    return dd.read_dxf(drawing, material=ROCK, joints=JOINTS, default_joint=DEFAULT_JOINT), dd.Params()


if __name__ == "__main__":
    from ddatai.cli import run_as_script

    run_as_script(build, DURATION, "dxf_section")
