"""The ``kgm analyze`` console command."""

import io
from pathlib import Path

import pytest

from kgm.cli import load_scene, main, scene_frame

ROOT = Path(__file__).resolve().parents[1]
EX1 = str(ROOT / "scenes" / "example_1.py")


def test_analyze_prints_the_candidate_table():
    out = io.StringIO()
    assert main(["analyze", EX1, "--method", "rigid", "--progressive"], out=out) == 0
    text = out.getvalue()
    assert "block types: 0:II, 1:III, 2:III, 3:V" in text
    assert "critical key group [0, 1]: FS 0.999, critical friction 11.02°" in text
    assert "round 1: removed [0, 1]" in text


def test_bad_scene_file_is_reported(capsys):
    assert main(["analyze", str(ROOT / "scenes" / "nope.py")]) == 2
    assert "no such scene file" in capsys.readouterr().err


def test_scene_frame_is_a_one_frame_result():
    scene, _ = load_scene(EX1)
    res = scene_frame(scene)
    assert res.n_frames == 1 and res.n_blocks == 4
    for b, poly in enumerate(res.polygons(0)):
        assert (poly == scene.blocks[b].vertices).all()


def test_gif_of_a_rigid_analysis(tmp_path):
    """Needs ddatai.render (the renderer of the main branch)."""
    pytest.importorskip("ddatai.render")
    path = tmp_path / "ex1.gif"
    assert main(["analyze", EX1, "--method", "rigid", "--gif", str(path)], out=io.StringIO()) == 0
    assert path.read_bytes()[:4] == b"GIF8"


def test_analyze_by_dda_says_when_the_verdict_run_stopped_at_rest(tmp_path):
    """A 2 × 1 block on a 30° plane with φ = 45° (FS 1.73): the DDA verdict's run is at rest
    from the equilibrium start and stops there; the report says so, with T, instead of a
    displacement "in" the few steps it took."""
    script = tmp_path / "held_block.py"
    script.write_text(
        "import sys\n"
        f"sys.path.insert(0, {str(ROOT / 'tests')!r})\n"
        "from kgm_cases import block_on_incline\n"
        "def build():\n"
        "    scene, _, _ = block_on_incline(theta=30.0, width=2.0, height=1.0, friction=45.0, cohesion=0.0)\n"
        "    return scene\n")
    out = io.StringIO()
    assert main(["analyze", str(script), "--method", "dda"], out=out) == 0
    text = out.getvalue()
    assert "at the scene's strength the group was at rest after" in text and "of T = " in text


def test_the_gif_of_a_dda_analysis_runs_the_analysed_problem(monkeypatch):
    """``--gif`` of a DDA analysis runs the verdict's judgement again, recorded: on the block
    system the analysis judged, its contact gap included. A block drawn 5 cm above its plane
    rests on it under ``Settings(contact_gap=0.06)``: the recorded run holds the plane in its
    sub-model (a rebuild with the default gap, 2.6 mm here, would simulate the block alone)."""
    from types import SimpleNamespace

    import ddatai.render
    import kgm
    from kgm.cli import write_result_gif
    from kgm_cases import block_above_incline

    scene = block_above_incline(0.05)
    settings = kgm.Settings(contact_gap=0.06, dda=kgm.DdaSettings(duration=0.02))
    crit = SimpleNamespace(blocks=frozenset({1}), verdict="stable", fs=1.4,
                           dda=SimpleNamespace(judgement=SimpleNamespace(duration=0.02)))
    seen = {}
    monkeypatch.setattr(ddatai.render, "write_gif", lambda res, path, **kw: seen.update(kw, blocks=res.n_blocks))
    write_result_gif("unused.gif", scene, SimpleNamespace(method="dda", critical=crit), None, settings)
    assert seen["blocks"] == 2 and list(seen["labels"]) == [-1, 0]


def test_analyze_takes_the_contact_gap(tmp_path, capsys):
    """``--contact-gap M`` is `kgm.Settings.contact_gap`: a 10 × 1 m block drawn 5 cm above its
    30° plane (φ 35°, c 20 kPa) is free of it with the default gap (a lifting group, FS 0) and
    rests on it at 6 cm, where its FS is the plane's closed form (tan φ + c·L/(W cos θ)) /
    tan θ; a negative gap is refused in one line."""
    import math

    script = tmp_path / "block_above.py"
    script.write_text(
        "import sys\n"
        f"sys.path.insert(0, {str(ROOT / 'tests')!r})\n"
        "from kgm_cases import block_above_incline\n"
        "def build():\n"
        "    return block_above_incline(0.05)\n")
    from kgm_cases import ROCK

    weight = ROCK.density * 9.81 * 10.0
    theta = math.radians(30.0)
    exact = (math.tan(math.radians(35.0)) + 20e3 * 10.0 / (weight * math.cos(theta))) / math.tan(theta)
    out = io.StringIO()
    assert main(["analyze", str(script), "--method", "rigid"], out=out) == 0
    assert "critical friction 90.00°, mode lifting, unstable" in out.getvalue()
    out = io.StringIO()
    assert main(["analyze", str(script), "--method", "rigid", "--contact-gap", "0.06"], out=out) == 0
    assert f"critical key group [1]: FS {exact:.3f}" in out.getvalue()
    assert main(["analyze", str(script), "--contact-gap", "-1"], out=io.StringIO()) == 2
    assert "contact_gap must be None or a distance >= 0 m" in capsys.readouterr().err
