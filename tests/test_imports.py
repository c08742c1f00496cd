"""Import hygiene: `import ddatai` (and its geometry, scene, results modules) must not load
Taichi or any imaging library; only a simulation starts Taichi (in a fresh interpreter)."""

import subprocess
import sys

HEAVY = ("taichi", "imageio", "PIL", "matplotlib")


def _loaded_after(code: str) -> set:
    out = subprocess.run([sys.executable, "-c", code + f"\nimport sys\nprint([m for m in {HEAVY!r} if m in sys.modules])"],
                         capture_output=True, text=True, check=True).stdout
    return set(eval(out.strip().splitlines()[-1]))


def test_import_ddatai_is_light():
    assert _loaded_after("import ddatai") == set()


def test_building_a_scene_and_model_is_light():
    code = """
import ddatai as dd
s = dd.Scene()
r = dd.Material(density=2500.0, young=1e9, poisson=0.2)
s.cut([(0, 0), (2, 0), (2, 2), (0, 2)], [([(1, -1), (1, 3)], dd.Joint())], material=r)
m = dd.build_model(s)
import ddatai.results, ddatai.geometry, ddatai.reference
"""
    assert _loaded_after(code) == set()


def test_simulation_on_the_kernels_starts_taichi():
    code = """
import ddatai as dd
s = dd.Scene()
s.add_block([(0, 0), (1, 0), (1, 1)], material=dd.Material(density=2500.0, young=1e9, poisson=0.2))
dd.simulate(s, dd.Params(kernels="taichi"), steps=1)
"""
    assert "taichi" in _loaded_after(code)


def test_a_small_model_runs_without_taichi():
    """The small-model path (`Params.kernels`, "auto" for a few blocks on the CPU) is NumPy
    throughout: a run of a block on a base, its equilibrium stage included, never imports
    Taichi (whose import and kernel loading cost seconds, more than such a run)."""
    code = """
import ddatai as dd
s = dd.Scene()
rock = dd.Material(density=2500.0, young=1e9, poisson=0.2)
s.add_block([(-1, -1), (2, -1), (2, 0), (-1, 0)], material=rock, fixed=True)
s.add_block([(0, 0), (1, 0), (1, 1)], material=rock)
res = dd.simulate(s, steps=20)
assert res.start["held"][0] == 1 and res.steps["contacts"].min() > 0
"""
    assert "taichi" not in _loaded_after(code)


def test_the_engine_warnings_are_public_names_and_light():
    """A script filters the engine's warnings by their public names (`dd.PenaltyWarning`: the
    automatic penalty raised; `dd.SliverWarning`: thin blocks merged or kept by `Scene.cut`;
    `dd.UnitWarning`), which load no heavy module."""
    code = """
import warnings
import ddatai as dd
from ddatai.cutting import SliverWarning
from ddatai.params import UnitWarning
from ddatai.step import PenaltyWarning
assert (dd.PenaltyWarning, dd.SliverWarning, dd.UnitWarning) == (PenaltyWarning, SliverWarning, UnitWarning)
assert all(issubclass(w, UserWarning) for w in (PenaltyWarning, SliverWarning, UnitWarning))
warnings.simplefilter("ignore", dd.PenaltyWarning)
"""
    assert _loaded_after(code) == set()
