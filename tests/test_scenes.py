"""Every scene builds and runs a few steps headless, from its frictional equilibrium; the command line runs a scene and an
ntdda model; a run without --gif never imports an imaging library (fresh interpreter)."""

import importlib
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import ddatai as dd

ROOT = Path(__file__).resolve().parents[1]
SCENES = sorted(p.stem for p in (ROOT / "scenes").glob("*.py") if not p.stem.startswith("_"))
SMALL = {"stacked_grid": dict(n=4)}  # keep the test run short


def test_scene_list_is_complete():
    for name in ("sliding_block", "toppling", "rockfall", "masonry_wall", "jointed_slope", "stacked_grid"):
        assert name in SCENES


@pytest.mark.parametrize("name", SCENES)
def test_scene_builds_and_runs(name):
    if name == "dxf_section":  # reads a drawing: needs the optional [dxf] extra
        pytest.importorskip("ezdxf", reason="the optional [dxf] extra (ezdxf) is not installed")
    module = importlib.import_module(f"scenes.{name}")
    assert module.DURATION > 0
    scene, params = module.build(**SMALL.get(name, {}))
    assert isinstance(scene, dd.Scene) and isinstance(params, dd.Params)
    res = dd.simulate(scene, params=params, steps=3)
    assert res.n_frames == 4
    assert np.all(np.isfinite(res.vertices))
    # the equilibrium start finds each scene's frictional equilibrium: none needs the welded
    # fallback (docs/guide/equilibrium_start.md)
    if params.initial_equilibrium:
        assert len(res.start) == 1 and not res.start[0]["welded"], f"{name} started welded"


def test_scenes_build_only_what_they_use():
    """A scene without loads, fixed points or shaking leaves those empty (no work for them)."""
    from scenes import masonry_wall, sliding_block

    scene, _ = sliding_block.build()
    model = dd.build_model(scene)
    assert len(model.load_block) == len(model.fixed_point_block) == len(model.measured_block) == 0
    assert model.ground_acceleration is None
    scene, _ = masonry_wall.build()
    assert scene.ground_acceleration is not None


def _run(args, **kw):
    # this checkout's packages, whichever copy an editable install points to
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    return subprocess.run([sys.executable, *args], capture_output=True, text=True, cwd=ROOT, env=env, **kw)


def test_command_line_runs_a_scene_without_imaging(tmp_path):
    code = f"""
import sys
from ddatai.cli import main
rc = main(["run", "scenes/sliding_block.py", "--steps", "3", "--out", {str(tmp_path)!r}, "--quiet"])
heavy = [m for m in ("PIL", "imageio", "matplotlib") if m in sys.modules]
print("HEAVY", heavy, "RC", rc)
"""
    out = _run(["-c", code])
    assert out.returncode == 0, out.stderr[-2000:]
    assert "HEAVY [] RC 0" in out.stdout
    assert "sliding_block: 3 blocks, 3 steps" in out.stdout
    res = dd.load_results(tmp_path / "sliding_block.npz")
    assert res.n_frames == 4


def test_command_line_writes_a_gif_and_scene_script_runs(tmp_path):
    gif = tmp_path / "slide.gif"
    out = _run(["scenes/sliding_block.py", "--duration", "0.1", "--gif", str(gif), "--size", "160x120",
                "--out", str(tmp_path)])
    assert out.returncode == 0, out.stderr[-2000:]
    assert gif.is_file() and gif.stat().st_size > 0
    assert "GIF written" in out.stdout


def test_command_line_runs_an_ntdda_model(tmp_path):
    from test_ntdda import DATA

    geo, ana = DATA / "pushblock.geo", DATA / "pushblock.ana"
    out = _run(["-m", "ddatai.cli", "run", str(geo), str(ana), "--steps", "5", "--out", str(tmp_path), "--quiet"])
    assert out.returncode == 0, out.stderr[-2000:]
    assert (tmp_path / "pushblock.npz").is_file()


def test_command_line_reports_a_missing_scene(tmp_path):
    out = _run(["-m", "ddatai.cli", "run", str(tmp_path / "nope.py")])
    assert out.returncode != 0 and "no such scene file" in out.stderr
