"""`import kgm` and limit-equilibrium analyses must not load Taichi or imaging libraries
(checked in a fresh interpreter); the DDA evaluator starts Taichi only when it runs."""

import subprocess
import sys
from pathlib import Path

HEAVY = ("taichi", "imageio", "PIL", "matplotlib")
ROOT = Path(__file__).resolve().parents[1]


def _loaded_after(code: str) -> set:
    probe = code + f"\nimport sys\nprint([m for m in {HEAVY!r} if m in sys.modules])"
    out = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, check=True,
                         cwd=ROOT).stdout
    return set(eval(out.strip().splitlines()[-1]))


def test_import_kgm_is_light():
    assert _loaded_after("import ddatai\nimport kgm\nimport kgm.judges.dda, kgm.judges.batch, kgm.cli\n"
                         "import kgm.studies.probabilistic, kgm.dda") == set()


def test_rigid_and_sarma_analyses_are_light():
    code = """
import kgm
from scenes import example_1, example_2
for mod in (example_1, example_2):
    scene, params = mod.build()
    for method in ("rigid", "sarma"):
        rep = kgm.analyze(scene, method=method, progressive=True)
        kgm.critical_friction(scene, rep.critical.blocks, method=method)
"""
    assert _loaded_after(code) == set()
