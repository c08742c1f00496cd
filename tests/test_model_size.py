"""A model far larger than intended is refused before it is cut (ddatai.cutting.cut's size
estimate), with the estimate, the likely mistake and the way to go on."""

import time

import numpy as np
import pytest

import ddatai as dd
from ddatai.cutting import MAX_BLOCKS_ENV, ModelSizeError, estimate_blocks
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


def _sliver_scene_traces():
    """A 10 × 5 box cut by two vertical joints 2 cm apart (a 125:1 sliver on each side of a
    horizontal joint)."""
    return [([(5.0, -1.0), (5.0, 6.0)], dd.Joint(friction=30.0)),
            ([(5.02, -1.0), (5.02, 6.0)], dd.Joint(friction=30.0)),
            ([(-1.0, 2.5), (11.0, 2.5)], dd.Joint(friction=25.0))]


def test_slivers_are_reported_and_merged_into_a_neighbour():
    import shapely

    from ddatai.cutting import SLIVER_ASPECT, SliverWarning
    box = [(0, 0), (10, 0), (10, 5), (0, 5)]
    with pytest.warns(SliverWarning, match=r"2 sliver block\(s\).*thinnest is 125:1.*slivers='merge'"):
        kept = dd.Scene().cut(box, _sliver_scene_traces(), material=ROCK)
    assert len(kept) == 6
    scene = dd.Scene()
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error", SliverWarning)  # merged: nothing left to warn about
        ids = scene.cut(box, _sliver_scene_traces(), material=ROCK, slivers="merge")
    assert len(ids) == 4
    polys = [shapely.Polygon(scene.polygon(b)) for b in ids]
    assert sum(p.area for p in polys) == pytest.approx(50.0, rel=1e-12)
    assert shapely.union_all(polys).equals(shapely.Polygon(box))
    for b in ids:  # the 2 cm pieces joined a neighbour: no block is thin any more
        xy = np.asarray(shapely.oriented_envelope(shapely.Polygon(scene.polygon(b))).exterior.coords)
        sides = np.linalg.norm(np.diff(xy[:3], axis=0), axis=1)
        assert sides.max() / sides.min() < SLIVER_ASPECT
        assert len(scene.blocks[b].edge_joint) == len(scene.polygon(b))
    # each quarter keeps two joint edges (the horizontal joint and the surviving vertical one)
    assert sorted(int((scene.blocks[b].edge_joint >= 0).sum()) for b in ids) == [2, 2, 2, 2]
    with pytest.raises(ValueError, match="slivers must be"):
        dd.Scene().cut(box, _sliver_scene_traces(), material=ROCK, slivers="drop")


@pytest.mark.slow
def test_the_close_spaced_jointed_slope_runs_once_its_slivers_are_merged():
    """scenes/jointed_slope.py with 0.3 m / 0.4 m spacings (~4,000 blocks, ~40 s): its blocks of
    1e-7 m² and 52:1 stopped the run at step 1; merged (the scene's default), it steps."""
    from scenes import jointed_slope

    scene, params = jointed_slope.build(bedding_spacing=0.3, cross_spacing=0.4)
    res = dd.simulate(scene, params, steps=2)
    assert len(res.steps) == 2
