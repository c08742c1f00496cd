"""Command-line consistency: one scene loader for ``ddatai`` and ``kgm`` (a build() returning
only a Scene, no DURATION), options checked before the run, one line per user error, results
named after the output and never overwritten, progress of a DDA analysis."""

import io
from pathlib import Path

import pytest

import ddatai as dd
from ddatai.cli import main
from ddatai.io.scenefile import SceneFileError, build_scene, load_scene_script

ROOT = Path(__file__).resolve().parents[1]

BARE = '''
import ddatai as dd


def build(width=1.0):
    scene = dd.Scene(gravity=9.81)
    rock = dd.Material(density=2500.0, young=5e9, poisson=0.25)
    scene.add_block([(-2, -1), (3, -1), (3, 0), (-2, 0)], material=rock, fixed=True)
    scene.add_block([(0, 0), (width, 0), (width, 1), (0, 1)], material=rock)
    scene.set_joint(dd.Joint(friction=30.0))
    return scene
'''


@pytest.fixture
def bare(tmp_path):
    path = tmp_path / "bare.py"
    path.write_text(BARE)
    return path


def _one_error_line(capsys) -> str:
    err = capsys.readouterr().err
    lines = [s for s in err.splitlines() if s.strip()]
    assert len(lines) == 1 and "Traceback" not in err, err
    return lines[0]


def test_a_scene_without_params_or_duration_runs_everywhere(bare, tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["run", str(bare), "--steps", "2", "--out", str(out), "--quiet"]) == 0
    assert dd.load_results(out / "bare.npz").summary()["steps"] == 2
    assert main(["run", str(bare), "--duration", "0.02", "--out", str(out), "--quiet"]) == 0
    # no DURATION, no --duration / --steps: one line that says what to give
    capsys.readouterr()
    assert main(["run", str(bare), "--out", str(out)]) == 2
    assert "defines no DURATION" in _one_error_line(capsys)
    # kgm reads the same script through the same loader
    from kgm.cli import main as kgm_main

    report = io.StringIO()
    assert kgm_main(["analyze", str(bare), "--method", "rigid"], out=report) == 0
    assert "block types" in report.getvalue()
    scene, params = build_scene(load_scene_script(bare), width=2.0)
    assert isinstance(scene, dd.Scene) and params is None and scene.n_blocks == 2


@pytest.mark.parametrize("option, message", [
    (["--stride", "0"], "--stride must be a positive integer"),
    (["--fps", "0"], "--fps must be a number in (0, 50]"),
    (["--fps", "200"], "--fps must be a number in (0, 50]"),
    (["--size", "10x10"], "--size must be at least 64 × 64"),
    (["--speed", "0"], "--speed must be a number > 0"),
    (["--every", "0"], "--every must be an integer >= 1"),
    (["--steps", "0"], "--steps must be an integer >= 1"),
    (["--duration", "-1"], "--duration must be a number > 0"),
    (["--checkpoint-every", "0"], "--checkpoint-every must be an integer >= 1"),
    (["--gif", "{tmp}/a_file/x.gif"], "--gif: cannot create the folder"),
    (["--gif", "{tmp}/x.png"], "--gif must name a .gif file"),
])
def test_bad_options_are_one_line_before_the_run(bare, tmp_path, capsys, monkeypatch, option, message):
    (tmp_path / "a_file").write_text("not a folder")
    import ddatai.cli

    def no_build(*a, **k):  # nothing is built or run before the options are checked
        raise AssertionError("the scene was built before the options were checked")

    monkeypatch.setattr(ddatai.cli, "run_scene", no_build)
    args = [a.format(tmp=tmp_path) for a in option]
    assert main(["run", str(bare), "--duration", "0.1", *args, "--out", str(tmp_path / "o")]) == 2
    assert message in _one_error_line(capsys)


@pytest.mark.parametrize("text, message", [
    ("def build(:\n", r"broken.py \(line 1\): SyntaxError"),
    ("import ddatai as dd\ndef build():\n    return dd.Material(density=-1, young=1, poisson=0)\n",
     r"broken.py \(line 3\): build\(\) failed: ValueError: Material.density"),
    ("def build():\n    return 42\n", r"build\(\) returned int; expected a Scene or \(scene, params\)"),
    ("x = 1\n", r"defines no build\(\)"),
])
def test_broken_scene_scripts_are_one_line(tmp_path, capsys, text, message):
    import re

    path = tmp_path / "broken.py"
    path.write_text(text)
    assert main(["run", str(path), "--steps", "1", "--out", str(tmp_path)]) == 2
    assert re.search(message, _one_error_line(capsys))
    with pytest.raises(SceneFileError):
        build_scene(load_scene_script(path))
    from kgm.cli import main as kgm_main

    assert kgm_main(["analyze", str(path)], out=io.StringIO()) == 2
    assert re.search(message, _one_error_line(capsys))


def test_results_are_named_after_the_output_and_never_overwritten(bare, tmp_path):
    out = tmp_path / "out"
    for _ in range(2):
        assert main(["run", str(bare), "--steps", "1", "--out", str(out), "--quiet"]) == 0
    assert (out / "bare.npz").is_file() and (out / "bare-2.npz").is_file()
    assert main(["run", str(bare), "--steps", "1", "--out", str(out), "--quiet",
                 "--gif", str(tmp_path / "fast.gif"), "--size", "64x64"]) == 0
    assert (out / "fast.npz").is_file() and (tmp_path / "fast.gif").is_file()


def test_kgm_dda_analysis_shows_progress(tmp_path, capsys):
    """A DDA analysis prints a line as each of its runs ends (instead of minutes of silence)."""
    from kgm.cli import main as kgm_main

    path = tmp_path / "incline.py"
    path.write_text('''
import sys
sys.path.insert(0, %r)
from kgm_cases import block_on_incline


def build():
    scene, _, _ = block_on_incline(theta=30.0, width=2.0, friction=25.0, cohesion=0.0)
    return scene
''' % str(Path(__file__).parent))
    report = io.StringIO()
    assert kgm_main(["analyze", str(path), "--method", "dda"], out=report) == 0
    err = capsys.readouterr().err
    runs = [s for s in err.splitlines() if s.strip().startswith("DDA run ")]
    assert len(runs) >= 2 and "unstable" in err
    assert "DDA:" in report.getvalue()


def test_ctrl_c_while_writing_the_gif_keeps_the_results(bare, tmp_path, capsys, monkeypatch):
    import ddatai.render

    def interrupted(*a, **k):
        raise KeyboardInterrupt

    monkeypatch.setattr(ddatai.render, "write_gif", interrupted)
    out = tmp_path / "out"
    assert main(["run", str(bare), "--steps", "2", "--out", str(out), "--quiet", "--gif", str(tmp_path / "g.gif")]) == 130
    line = _one_error_line(capsys)
    assert "interrupted while writing the outputs" in line and str(out / "g.npz") in line
    assert dd.load_results(out / "g.npz").summary()["steps"] == 2


def test_gif_title_and_summary_name_the_scene(bare, tmp_path, capsys):
    """The files are named after the GIF; the GIF's title and the summary name the scene."""
    out = tmp_path / "out"
    assert main(["run", str(bare), "--steps", "1", "--out", str(out), "--quiet", "--size", "200x150",
                 "--gif", str(tmp_path / "fast.gif")]) == 0
    assert capsys.readouterr().out.splitlines()[-1].startswith("bare: 2 blocks, 1 steps")
    res = dd.load_results(out / "fast.npz")
    titled = dd.write_gif(res, tmp_path / "again.gif", size=(200, 150), title="bare")
    assert titled.read_bytes() == (tmp_path / "fast.gif").read_bytes()
