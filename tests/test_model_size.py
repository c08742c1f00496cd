"""A model far larger than intended is refused before it is cut (ddatai.geometry.cut's size
estimate), with the estimate, the likely mistake and the way to go on."""

import time

import numpy as np
import pytest

import ddatai as dd
from ddatai.geometry import MAX_BLOCKS_ENV, ModelSizeError, estimate_blocks

ROCK = dd.Material(density=2600.0, young=10e9, poisson=0.25)
BOX = [(0, 0), (100, 0), (100, 50), (0, 50)]


def _grid_traces(spacing, width=100.0, height=50.0):
    """Two persistent orthogonal sets crossing the box: (width/s)(height/s) blocks."""
    xs = np.arange(1, int(round(width / spacing))) * spacing
    ys = np.arange(1, int(round(height / spacing))) * spacing
    return [([(x, -1.0), (x, height + 1.0)], dd.Joint()) for x in xs] + \
        [([(-1.0, y), (width + 1.0, y)], dd.Joint()) for y in ys]


def test_estimate_is_exact_for_persistent_joints_and_an_upper_bound_for_finite_ones():
    import shapely

    domain = shapely.Polygon(BOX)
    traces = _grid_traces(5.0)
    blocks, pieces, crossings = estimate_blocks(domain, [shapely.LineString(t) for t, _ in traces])
    assert (pieces, crossings) == (19 + 9, 19 * 9) and blocks == 20 * 10
    assert len(dd.Scene().cut(BOX, traces, material=ROCK)) == blocks
    # finite traces with rock bridges: Euler's count bounds the blocks from above
    sets = [dd.JointSet(dip=35.0, spacing=4.0, trace_length=20.0, gap=3.0, joint=dd.Joint()),
            dd.JointSet(dip=110.0, spacing=5.0, trace_length=15.0, gap=2.0, joint=dd.Joint())]
    finite = dd.joint_sets(BOX, sets, seed=3)
    bound = estimate_blocks(domain, [shapely.LineString(t) for t, _ in finite])[0]
    assert len(dd.Scene().cut(BOX, finite, material=ROCK)) <= bound


def test_a_spacing_ten_times_too_small_is_refused_before_cutting(monkeypatch):
    """0.1 m instead of 1 m: 500,000 blocks (the 1 m spacing makes 5,000). Refused in well under
    a second of estimating, against ~85 s of cutting and a MemoryError."""
    monkeypatch.setenv(MAX_BLOCKS_ENV, "100000")
    t0 = time.perf_counter()
    with pytest.raises(ModelSizeError, match=r"up to 500,000 blocks.*check the joint spacings.*--force"):
        dd.Scene().cut(BOX, _grid_traces(0.1), material=ROCK)
    assert time.perf_counter() - t0 < 10.0
    assert issubclass(ModelSizeError, ValueError)


def test_the_limit_follows_the_argument_the_environment_and_the_machine(monkeypatch):
    monkeypatch.delenv(MAX_BLOCKS_ENV, raising=False)
    traces = _grid_traces(10.0)  # 50 blocks
    with pytest.raises(ModelSizeError, match="up to 50 blocks"):
        dd.Scene().cut(BOX, traces, material=ROCK, max_blocks=49)
    assert len(dd.Scene().cut(BOX, traces, material=ROCK, max_blocks=50)) == 50
    monkeypatch.setenv(MAX_BLOCKS_ENV, "10")
    with pytest.raises(ModelSizeError):
        dd.Scene().cut(BOX, traces, material=ROCK)
    assert len(dd.Scene().cut(BOX, traces, material=ROCK, max_blocks=float("inf"))) == 50
    monkeypatch.setenv(MAX_BLOCKS_ENV, "inf")
    assert len(dd.Scene().cut(BOX, traces, material=ROCK)) == 50
    monkeypatch.setenv(MAX_BLOCKS_ENV, "many")
    with pytest.raises(ValueError, match="must be a number of blocks"):
        dd.Scene().cut(BOX, traces, material=ROCK)


def test_cli_refuses_in_one_line_and_force_goes_on(tmp_path, monkeypatch, capsys):
    from ddatai.cli import main

    script = tmp_path / "boxes.py"
    script.write_text(
        "import ddatai as dd\n"
        "def build():\n"
        "    s = dd.Scene()\n"
        "    rock = dd.Material(density=2600.0, young=10e9, poisson=0.25)\n"
        "    s.add_block([(-1, -1), (5, -1), (5, 0), (-1, 0)], material=rock, fixed=True)\n"
        "    s.cut([(0, 0), (4, 0), (4, 1), (0, 1)], [([(x, -1), (x, 2)], dd.Joint()) for x in (1, 2, 3)],\n"
        "          material=rock)\n"
        "    return s\n")
    monkeypatch.setenv(MAX_BLOCKS_ENV, "3")
    assert main(["run", str(script), "--steps", "1", "--quiet", "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert "up to 4 blocks" in err and "--force" in err and "Traceback" not in err
    assert main(["run", str(script), "--steps", "1", "--quiet", "--force", "--out", str(tmp_path)]) == 0
