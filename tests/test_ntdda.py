"""Reading ntdda ("DDA for Windows") input files and running them.

The example files are ntdda's own (doolin/ntdda ``examples/``), kept outside the repository in
a data folder ``data/ntdda`` under a ``shared`` folder beside the checkout (or
``$DDATAI_NTDDA_DATA``); ntdda's recorded runs of them are in ``data/ntdda-runs`` beside it. The
tests that need them are skipped without them. Expected values come from docs/ntdda.md §4.7
(what a correct reader must produce), from the closed-form push of ``pushblock`` and from
ntdda's recorded outputs, never from this code.
"""

import csv
import dataclasses
import os
import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest

import ddatai as dd
from ddatai.io.ntdda import (NtddaFormatError, NtddaQuirkWarning, NtddaUnsupportedWarning, NtddaWarning,
                          cut_ntdda_geometry, read_ntdda_analysis, read_ntdda_geometry,
                          write_measured_csv)
from ddatai.io.ntdda.geometry import ntdda_fixed_points

def _shared_data() -> Path:
    """The data folder: in a ``shared`` folder beside the checkout, or the workplace's
    /work/shared when CI runs from a clone elsewhere."""
    for root in (Path(__file__).resolve().parents[2] / "shared", Path("/work/shared")):
        if (root / "data" / "ntdda").is_dir():
            return root / "data"
    return Path(__file__).resolve().parents[2] / "shared" / "data"


SHARED = _shared_data()
DATA = Path(os.environ.get("DDATAI_NTDDA_DATA", SHARED / "ntdda"))
RUNS = DATA.parent / "ntdda-runs"


def data(name: str) -> Path:
    path = DATA / name
    assert path.exists(), f"ntdda example {path} is missing (set DDATAI_NTDDA_DATA)"
    return path


def read_quietly(geo, ana):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", NtddaWarning)
        return dd.read_ntdda(geo, ana)


def ntdda_centroids(name: str, step: int) -> np.ndarray:
    """ntdda's recorded (block, cx, cy, area) rows of one step, block order as in ntdda."""
    rows = [r for r in csv.DictReader(open(RUNS / f"{name}_centroids.csv")) if int(r["step"]) == step]
    return np.array([[float(r["cx"]), float(r["cy"]), float(r["area"])] for r in rows])


def variant(tmp_path: Path, name: str, edit) -> Path:
    """A copy of an example file changed by ``edit(text) -> text``."""
    text = data(name).read_text()
    new = edit(text)
    assert new != text, "the edit must change the file"
    out = tmp_path / Path(name).name
    out.write_text(new)
    return out


# ============================================================================ reading
def test_circleslope_files_read_as_peers_4_7():
    """Original-format circleslope: the content listed in docs/ntdda.md §4.7."""
    with pytest.warns(NtddaWarning):
        g = read_ntdda_geometry(data("circleslope.geo"))
        a = read_ntdda_analysis(data("circleslope.ana"))
    assert g.format == "original" and a.format == "original"
    assert g.edge_node_distance == 0.01 and g.n_boundary_lines == 0
    assert len(g.joints) == 30
    assert np.bincount(g.joint_type).tolist() == [0, 18, 7, 5]
    assert np.allclose(g.fixed_lines, [[1.3, 0, 1.3, 0], [1.3, -1.5, 1.3, -1.5], [-1, -1.5, -1, -1.5]])
    assert len(g.load_points) == len(g.measured_points) == len(g.hole_points) == 0
    assert not a.dynamic and a.n_steps == 20 and a.max_displacement == 0.006 and a.max_time_step == 0.01
    (m,) = a.block_materials
    assert (m.unit_mass, m.unit_weight, m.young, m.poisson) == (5.0, 161.0, 1e6, 0.49)
    assert [j.friction for j in a.joint_materials] == [10.0, 20.0, 0.0]
    assert all(j.cohesion == j.tensile == 0 for j in a.joint_materials)
    # ntdda's implicit settings for the original format
    assert a.auto_time_step and a.auto_penalty and a.penalty_factor == 50 and not a.plane_strain


def test_pushblock_files_read_as_peers_4_7():
    """DDAML pushblock: the content listed in docs/ntdda.md §4.7, and no warning (it relies on no
    quirk: its ignored <OCLimit> holds ntdda's hard-coded 8)."""
    with warnings.catch_warnings():
        warnings.simplefilter("error", NtddaWarning)
        case = dd.read_ntdda(data("pushblock.geo"), data("pushblock.ana"))
    g, a = case.geometry, case.analysis
    assert g.format == a.format == "ddaml"
    assert g.edge_node_distance == 0.01 and len(g.joints) == 7 and set(g.joint_type) == {1}
    assert np.allclose(g.fixed_lines[:, :2], [[12, 12], [12, 18], [48, 18], [48, 12]])
    assert np.allclose(g.fixed_lines[:, :2], g.fixed_lines[:, 2:])
    assert g.load_points.tolist() == [[17.5, 22.5]] and len(g.measured_points) == 0
    assert a.dynamic and a.rotation == "linear" and not a.gravity_turn_on and not a.auto_time_step
    assert not a.auto_penalty and a.penalty_factor == 50 and not a.plane_strain
    assert a.n_steps == 500 and a.max_time_step == 0.01 and a.max_displacement == 0.025
    assert a.save_interval == 1 and a.oc_limit == 8
    (m,) = a.block_materials
    assert (m.unit_mass, m.unit_weight, m.young, m.poisson, m.damping) == (18.0, 176.58, 3e6, 0.2, 0.0)
    assert (a.joint_materials[0].friction, a.joint_materials[0].cohesion) == (0.0, 0.0)
    assert a.load_histories[0].tolist() == [[0, 5000, 500], [5, 5000, 500]]
    # mapped onto the run
    p = case.params
    assert p.dt == 0.01 and case.duration == pytest.approx(5.0) and case.steps is None
    assert p.penalty == pytest.approx(1.5e8) and not p.static and p.plane == "stress"
    assert p.oc_max_iterations == 8 and p.max_displacement_ratio == 0.025
    assert case.gravity == pytest.approx(9.81) and case.scene.gravity == pytest.approx(9.81)
    assert [b.material.density for b in case.scene.blocks] == [18.0, 18.0]
    assert case.record_every == 1
    assert "blocks: 2" in case.summary() and "fixed dt = 0.01" in case.summary()


def test_circleslope_blocks_match_ntdda():
    """7 blocks with 23/9/7/6/5/5/4 vertices (docs/ntdda.md §4.7), in ntdda's order, with ntdda's
    recorded step-0 areas and centroids (10 significant digits in the CSV)."""
    case = read_quietly(data("circleslope.geo"), data("circleslope.ana"))
    assert [len(p) for p in case.blocks.polygons] == [23, 9, 7, 6, 5, 5, 4]
    ref = ntdda_centroids("circleslope", 0)
    ints = [dd.polygon_integrals(p, np.array([0, len(p)])) for p in case.blocks.polygons]
    ours = np.array([[i["centroid"][0, 0], i["centroid"][0, 1], i["area"][0]] for i in ints])
    assert np.allclose(ours, ref, rtol=1e-8, atol=1e-9)
    # the scene holds the same blocks; 3 fixed points on the base block (docs/ntdda.md §4.7)
    assert case.scene.n_blocks == 7
    assert [len(b.vertices) for b in case.scene.blocks] == [23, 9, 7, 6, 5, 5, 4]
    assert [fp.block for fp in case.scene.fixed_points] == [0, 0, 0]
    assert case.gravity == pytest.approx(161.0 / 5.0)
    assert case.params.static and case.params.dt is None and case.params.dt_max == 0.01
    assert case.steps == 20 and case.duration is None


def test_circleslope_edges_keep_their_joint_materials():
    """Slip-surface chords are joint type 1 (φ 10°), outline type 2 (φ 20°), the vertical
    joints type 3 (φ 0°): each block edge carries its line's joint."""
    case = read_quietly(data("circleslope.geo"), data("circleslope.ana"))
    toe = case.scene.blocks[6]  # the toe slice: face (type 2), vertical joint (3), two chords (1)
    friction = sorted(case.scene.joints[j].friction for j in toe.edge_joint)
    assert friction == [0.0, 10.0, 10.0, 20.0]
    base = case.scene.blocks[0]
    assert sorted(case.scene.joints[j].friction for j in base.edge_joint) == [10.0] * 18 + [20.0] * 5


def test_original_format_warns_about_its_quirks():
    """ntdda cannot run an original-format analysis file as shipped (B2) and re-estimates the
    penalty, which ddatai does not: both are reported."""
    with pytest.warns(NtddaWarning) as rec:
        dd.read_ntdda(data("circleslope.geo"), data("circleslope.ana"))
    kinds = sorted(((w.category.__name__, "uninitialised" in str(w.message)) for w in rec))
    assert kinds == [("NtddaQuirkWarning", True), ("NtddaUnsupportedWarning", False)]
    assert {w.category for w in rec} == {NtddaQuirkWarning, NtddaUnsupportedWarning}


# ============================================================================ fixed lines
OUR_FIXED_POINTS = {
    # case: {block: [points]}; block 0 of cases 5 and 6 is the right-hand block (ntdda's order)
    1: {0: [(0.0, 0.5), (1.0, 0.5)]},
    2: {0: [(0.1, 0.5), (0.9, 0.5)]},
    3: {0: [(0.0, 0.5), (0.9, 0.5)]},
    4: {0: [(0.1, 0.5), (1.0, 0.5)]},
    5: {0: [(1.0, 0.5), (1.9, 0.5)], 1: [(0.1, 0.5), (1.0, 0.5)]},
    6: {0: [(1.0, 0.5), (2.0, 0.5)], 1: [(0.0, 0.5), (1.0, 0.5)]},
    7: {0: [(0.5, 0.0), (0.5, 1.0)]},
    8: {0: [(0.5, 0.1), (0.5, 0.9)]},
}
# ntdda's output, docs/ntdda.md §4.7 (printed to 4-5 decimals)
NTDDA_FIXED_POINTS = {
    1: [(0.00255, 0.5), (0.99745, 0.5)], 2: [(0.1, 0.5)], 3: [(0.00255, 0.5)], 4: [(0.99745, 0.5)],
    5: [(1.0039, 0.5), (0.9961, 0.5)], 6: [(0.0039, 0.5), (0.9961, 0.5), (1.0039, 0.5), (1.9961, 0.5)],
    7: [(0.5, 0.00255), (0.5, 0.99745)], 8: [(0.5, 0.1)],
}


@pytest.mark.parametrize("case", range(1, 9))
def test_fixed_lines_pin_every_crossed_block_at_both_ends(case):
    """ddatai's rule (docs/ntdda.md §4.8): every block a fixed line passes through is pinned at
    both ends of the line's piece inside it; a warning names ntdda's different points where a
    line ends inside a block (cases 2, 3, 4, 5, 8)."""
    g = read_ntdda_geometry(data(f"fixedlines/case{case}.geo"))
    with warnings.catch_warnings(record=True) as rec:
        warnings.simplefilter("always")
        blocks = cut_ntdda_geometry(g)
    got = {}
    for b, xy in zip(blocks.fixed_block, blocks.fixed_xy):
        got.setdefault(int(b), []).append(tuple(xy))
    want = OUR_FIXED_POINTS[case]
    assert sorted(got) == sorted(want)
    for b in want:
        assert np.allclose(sorted(got[b]), sorted(want[b]), atol=1e-12)
    if case in (5, 6):
        assert blocks.polygons[0][:, 0].min() == pytest.approx(1.0)  # block 0 is the right one
    quirks = [w for w in rec if issubclass(w.category, NtddaQuirkWarning)]
    assert len(quirks) == (1 if case in (2, 3, 4, 5, 8) else 0)


@pytest.mark.parametrize("case", range(1, 9))
def test_ntdda_fixed_line_rule_is_understood(case):
    """The replica of ntdda's rule used in the warnings gives ntdda's points (docs/ntdda.md §4.7)."""
    g = read_ntdda_geometry(data(f"fixedlines/case{case}.geo"))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", NtddaWarning)
        blocks = cut_ntdda_geometry(g)
    (line,) = g.fixed_lines
    pts = [tuple(p) for _, p in ntdda_fixed_points(blocks.polygons, line, blocks.w0)]
    assert np.allclose(sorted(pts), sorted(NTDDA_FIXED_POINTS[case]), atol=6e-5)


# ============================================================================ running
@pytest.fixture(scope="module")
def pushblock_run():
    case = dd.read_ntdda(data("pushblock.geo"), data("pushblock.ana"))
    return case, case.simulate()


def test_pushblock_load_point_follows_the_push(pushblock_run):
    """x(t) = 17.5 + ½(F/m)t², F = 5000, m = ρ·A = 18·25 = 450: 156.39 at 5 s (ntdda
    156.3992). Tolerance: DDA's inertia uses the block's current area at a fixed density, and
    the soft block (E = 3e6) resting on its two lower corners is compressed by its weight
    W = 4415 by about εx + εy ≈ −(1−ν)·2.5·W/(A·E/(1−ν²)) ≈ −1.0e-4, so its mass is 1e-4 low
    and its acceleration 1e-4 high (ntdda shows the same +1.0e-4); 3e-4 of the analytic value
    allows that (unit weight taken as mass would give x ≈ 31.7, friction or a lost load far
    less than 156)."""
    case, res = pushblock_run
    (load,) = case.points
    assert load.kind == "load" and load.block == 1
    x_end = res.measured[-1, load.index, 0]
    analytic = 17.5 + 0.5 * (5000.0 / 450.0) * 5.0 ** 2
    assert res.time[-1] == pytest.approx(5.0, abs=1e-9) and len(res.steps) == 500
    assert x_end == pytest.approx(analytic, rel=3e-4)
    assert x_end == pytest.approx(156.3992, rel=3e-4)   # ntdda's printed value, same bound


def test_pushblock_matches_ntdda_step_by_step_while_on_the_base():
    """Until the block reaches the base's edge (its centroid passes x = 50 at t ≈ 2.42 s) both
    codes solve the same discrete equations (Δt, penalty, mass, frictionless springs) when ours
    uses Shi's integrator (Newmark β = ½, ntdda's): the load point (the centroid) follows
    ntdda's recorded centroid to the CSV's 10 significant digits plus round-off (1e-7)."""
    case = dd.read_ntdda(data("pushblock.geo"), data("pushblock.ana"))
    res = dd.simulate(case.scene, dataclasses.replace(case.params, newmark_beta=0.5), duration=case.duration,
                      record_every=case.record_every)
    rows = [r for r in csv.DictReader(open(RUNS / "pushblock_centroids.csv")) if r["block"] == "2"]
    ntdda = np.array([[float(r["time"]), float(r["cx"]), float(r["cy"])] for r in rows])
    on_base = ntdda[:, 0] <= 2.4 + 1e-9
    assert np.allclose(res.time[:len(ntdda)][on_base], ntdda[on_base, 0], atol=1e-9)
    ours = res.measured[:len(ntdda), case.points[0].index][on_base]
    assert np.abs(ours - ntdda[on_base, 1:]).max() < 1e-7


def test_measured_csv(pushblock_run, tmp_path):
    """One row per frame: time, then x, y, dx, dy of every recorded point."""
    case, res = pushblock_run
    path = tmp_path / "push.csv"
    write_measured_csv(res, case, path)
    rows = list(csv.reader(open(path)))
    assert rows[0] == ["time", "L1_x", "L1_y", "L1_dx", "L1_dy"]
    assert len(rows) == 1 + res.n_frames
    last = np.array(rows[-1], dtype=float)
    assert last[0] == pytest.approx(5.0)
    assert last[1:3] == pytest.approx(res.measured[-1, 0])
    assert last[3:5] == pytest.approx(res.measured[-1, 0] - (17.5, 22.5))
    with pytest.raises(ValueError, match="measured points"):
        write_measured_csv(res, read_quietly(data("circleslope.geo"), data("circleslope.ana")), path)


def test_circleslope_runs_its_20_steps():
    """20 static steps with no NaN; the base (3 fixed points) stays put and every slice moves
    down the slope (down and towards the toe at x < 0), as in ntdda's run of the same model."""
    case = read_quietly(data("circleslope.geo"), data("circleslope.ana"))
    res = case.simulate()
    assert len(res.steps) == 20 and res.n_frames == 21
    assert np.all(np.isfinite(res.vertices)) and np.all(np.isfinite(res.stress))
    d = res.centroid[-1] - res.centroid[0]
    assert np.abs(d[0]).max() < 1e-6
    assert np.all(d[1:, 0] < 0) and np.all(d[1:, 1] < 0)


def test_command_line_end_to_end(tmp_path, capsys):
    """``ddatai run MODEL.geo MODEL.ana`` (in-process): summary, run, CSV and results file;
    a missing file is a one-line error with exit status 2."""
    from ddatai.cli import main

    rc = main(["run", str(data("pushblock.geo")), str(data("pushblock.ana")), "--out", str(tmp_path),
               "--duration", "0.5", "--quiet"])
    assert rc == 0
    assert "blocks: 2" in capsys.readouterr().out
    rows = list(csv.reader(open(tmp_path / "pushblock_measured.csv")))
    t, dx = float(rows[-1][0]), float(rows[-1][3])
    assert t == pytest.approx(0.5)
    assert dx == pytest.approx(0.5 * (5000 / 450) * 0.25, rel=3e-4)   # bound as in the 5 s test
    assert dd.load_results(tmp_path / "pushblock.npz").n_frames == 51
    bad = tmp_path / "missing.ana"
    assert main(["run", str(data("pushblock.geo")), str(bad), "--quiet"]) == 2
    assert "missing.ana" in capsys.readouterr().err


def test_reading_does_not_start_taichi():
    code = (f"import sys, warnings\nwarnings.simplefilter('ignore')\nimport ddatai as dd\n"
            f"c = dd.read_ntdda({str(data('circleslope.geo'))!r}, {str(data('circleslope.ana'))!r})\n"
            "print('taichi' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip().splitlines()[-1] == "False"


# ============================================================================ malformed files
MALFORMED = [
    # (file, edit, message fragments)
    ("circleslope.geo", lambda s: "\n".join(s.splitlines()[:20]),
     ["circleslope.geo, line 20", "ends early", "joint line 13: x1"]),
    ("circleslope.geo", lambda s: s.replace("30 0", "31 0", 1),
     ["circleslope.geo, line 40", "joint line 31: joint type", "'1.300000'"]),
    ("circleslope.geo", lambda s: s.replace("30 0", "29 0", 1),
     ["circleslope.geo, line 40", "unexpected extra data", "count"]),
    ("circleslope.geo", lambda s: s.replace("0.984808 -0.173648 0.965926", "0.98a4808 -0.173648 0.965926", 1),
     ["circleslope.geo, line 11", "joint line 3: x1 (a number)", "'0.98a4808'"]),
    ("circleslope.geo", lambda s: s.replace("\n0\n0\n3\n", "\n0\n2\n3\n", 1),
     ["circleslope.geo, line 4", "bolt records are not read", "Scene.add_bolt"]),
    ("circleslope.ana", lambda s: "\n".join(s.splitlines()[:12]),
     ["circleslope.ana, line 12", "ends early", "joint material 3: friction angle"]),
    ("circleslope.ana", lambda s: s.replace("\n3\n", "\n2\n", 1),
     ["circleslope.ana, line 13", "unexpected extra data"]),
    ("circleslope.ana", lambda s: s.replace("161.000000", "161,0", 1),
     ["circleslope.ana, line 7", "block material 1: unit weight (a number)", "'161,0'"]),
    ("circleslope.ana", lambda s: s.replace("0\n20\n", "2\n20\n", 1),
     ["circleslope.ana, line 1", "0 (static) or 1 (dynamic)"]),
    ("circleslope.ana", lambda s: s.replace("0.490000", "0.500000", 1),
     ["circleslope.ana, line 7", "Poisson's ratio must be in [0, 0.5)"]),
    ("pushblock.geo", lambda s: "\n".join(s.splitlines()[:15]),
     ["pushblock.geo, line", "not well-formed XML"]),
    ("pushblock.geo", lambda s: s.replace("10 9.98 10 20.01", "10 9.98 10", 1),
     ["pushblock.geo, line 12, <Joint>", "expected 4 numbers (x1 y1 x2 y2), got 3"]),
    ("pushblock.geo", lambda s: s.replace("9.98 20 50.01 20", "9.9.8 20 50.01 20", 1),
     ["pushblock.geo, line 13, <Joint>", "'9.9.8'"]),
    ("pushblock.geo", lambda s: s.replace('<Joint type="1"> 50 20.01', "<Joint> 50 20.01", 1),
     ["pushblock.geo, line 14, <Joint>", "missing attribute type"]),
    ("pushblock.geo", lambda s: s.replace("<Point> 17.5 22.5 </Point>", "<Point> 100 100 </Point>", 1),
     ["pushblock.geo, line 29, <Point>", "load point (100, 100) lies outside every block"]),
    ("pushblock.ana", lambda s: "\n".join(s.splitlines()[:40]),
     ["pushblock.ana, line", "not well-formed XML"]),
    ("pushblock.ana", lambda s: s.replace('numpoints = "2"', 'numpoints = "3"', 1),
     ["pushblock.ana, line", "<Loadpoint>", "numpoints = 3 but 2 records"]),
    ("pushblock.ana", lambda s: s.replace('maxtimestep="0.010000"', 'maxtimestep="0.01x"', 1),
     ["pushblock.ana, line 19, <Maxtimestep>", "attribute maxtimestep must be a number"]),
    ("pushblock.ana", lambda s: s.replace('<Numtimesteps timesteps="500"/>', "", 1),
     ["pushblock.ana, line 7, <Analysis>", "expected a <Numtimesteps"]),
    ("pushblock.ana", lambda s: s.replace("<Unitmass> 18.000000 </Unitmass>", "<Unitmass> heavy </Unitmass>"),
     ["pushblock.ana, line", "<Unitmass>", "'heavy'"]),
    ("pushblock.ana", lambda s: s.replace("0 5000 500;", "0 5000;", 1),
     ["pushblock.ana, line", "<Loadpoint>", "record 1: expected three numbers"]),
    ("pushblock.ana", lambda s: s.replace('<Autotimestep flag="no"/>', '<Autotimestep flag="maybe"/>', 1),
     ["pushblock.ana, line 15, <Autotimestep>", "\"yes\" or \"no\""]),
]


@pytest.mark.parametrize("name, edit, fragments", MALFORMED,
                         ids=[f"{m[0]}-{k}" for k, m in enumerate(MALFORMED)])
def test_malformed_files_name_file_line_and_expectation(tmp_path, name, edit, fragments):
    bad = variant(tmp_path, name, edit)
    stem = Path(name).stem
    geo = bad if name.endswith(".geo") else data(f"{stem}.geo")
    ana = bad if name.endswith(".ana") else data(f"{stem}.ana")
    with pytest.raises(NtddaFormatError) as exc:
        read_quietly(geo, ana)
    assert isinstance(exc.value, ValueError)
    for frag in fragments:
        assert frag in str(exc.value)


def test_inconsistent_file_pairs(tmp_path):
    """Errors that need both files: joint types beyond the joint materials, swapped files."""
    # two joint materials instead of three (the count and the last record changed together)
    ana = variant(tmp_path, "circleslope.ana",
                  lambda s: "\n".join(s.replace("\n3\n", "\n2\n", 1).splitlines()[:12]) + "\n")
    with pytest.raises(NtddaFormatError, match=r"circleslope.geo, line 34: joint line 26 has joint type 3, "
                                                r"but .*circleslope.ana defines 2 joint material"):
        read_quietly(data("circleslope.geo"), ana)
    with pytest.raises(NtddaFormatError, match=r"pushblock.ana, line 3, <DDA>: expected a <Geometry> "
                                                r"element \(found <Analysis>: are the geometry and analysis "
                                                r"files swapped\?\)"):
        dd.read_ntdda(data("pushblock.ana"), data("pushblock.geo"))
    with pytest.raises(NtddaFormatError, match="obsolete"):
        dd.read_ntdda(variant(tmp_path, "pushblock.geo", lambda s: "#!0xDDA-v1.5\n" + s), data("pushblock.ana"))


# ============================================================================ quirks
def pushblock_with(tmp_path, edit):
    return dd.read_ntdda(data("pushblock.geo"), variant(tmp_path, "pushblock.ana", edit))


def test_missing_pfactor_uses_50_not_0(tmp_path):
    with pytest.warns(NtddaQuirkWarning, match="pfactor"):
        case = pushblock_with(tmp_path, lambda s: s.replace(' pfactor="50.0"', "", 1))
    assert case.params.penalty == pytest.approx(50 * 3e6)


def test_oclimit_is_honoured_and_reported_when_not_8(tmp_path):
    with pytest.warns(NtddaQuirkWarning, match="ignores <OCLimit>"):
        case = pushblock_with(tmp_path, lambda s: s.replace('maxopenclose="8"', 'maxopenclose="12"', 1))
    assert case.params.oc_max_iterations == 12


def test_gravity_turn_on_phase_is_the_equilibrium_start(tmp_path):
    """ntdda's gravity turn-on phase maps onto `Params.initial_equilibrium`; without it gravity
    acts from t = 0, as in ntdda, and no warning is given either way."""
    assert not dd.read_ntdda(data("pushblock.geo"), data("pushblock.ana")).params.initial_equilibrium
    with warnings.catch_warnings():
        warnings.simplefilter("error", NtddaWarning)
        case = pushblock_with(tmp_path, lambda s: s.replace('<Gravity flag="no">', '<Gravity flag="yes">', 1))
    assert case.analysis.gravity_turn_on and case.params.initial_equilibrium


def test_load_history_shorter_than_the_run_holds_its_last_force(tmp_path):
    with pytest.warns(NtddaQuirkWarning, match="holds the last force"):
        case = pushblock_with(tmp_path, lambda s: s.replace("5 5000 500;", "2 3000 100;", 1))
    force = case.scene.point_loads[0].force
    assert force(1.0) == pytest.approx((4000.0, 300.0))
    assert force(4.0) == pytest.approx((3000.0, 100.0))


def test_initial_velocity_is_applied_without_ntdda_stress_mixup(tmp_path):
    with pytest.warns(NtddaQuirkWarning, match="Ivelocity"):
        case = pushblock_with(tmp_path, lambda s: s.replace(
            "<Ivelocity> 0.000000  0.000000  0.000000", "<Ivelocity> 1.5  0.0  0.25", 1))
    assert all(b.velocity == (1.5, 0.0) and b.angular_velocity == 0.25 for b in case.scene.blocks)
    assert all(b.stress == (0.0, 0.0, 0.0) for b in case.scene.blocks)


def test_gravity_is_unit_weight_over_unit_mass(tmp_path):
    """Without <Gravaccel>, g = γ/ρ (ntdda would take 9.81: reported); with it, g = Gravaccel and
    a unit weight that disagrees is reported."""
    with pytest.warns(NtddaQuirkWarning, match="ntdda would use g = 9.81"):
        case = pushblock_with(tmp_path, lambda s: s.replace("176.5800", "579.6", 1))
    assert case.gravity == pytest.approx(579.6 / 18.0) and case.scene.gravity == pytest.approx(32.2)
    with pytest.warns(NtddaQuirkWarning, match="unit weight 176.58 is not unit mass"):
        case = pushblock_with(tmp_path, lambda s: s.replace("<Rotation", '<Gravaccel value="10"/><Rotation', 1))
    assert case.gravity == 10.0


def test_original_format_initial_stress_gradient(tmp_path):
    """σ = s + y_centroid·t in the original format; ntdda's use of t as velocity is reported."""
    def edit(s):
        lines = s.splitlines()
        lines[7:10] = ["-100 -200 0", "10 20 0", "0 0 0"]
        return "\n".join(lines) + "\n"

    ana = variant(tmp_path, "circleslope.ana", edit)
    with warnings.catch_warnings(record=True) as rec:
        warnings.simplefilter("always")
        case = dd.read_ntdda(data("circleslope.geo"), ana)
    assert any(w.category is NtddaQuirkWarning and "stress gradients" in str(w.message) for w in rec)
    yc = ntdda_centroids("circleslope", 0)[:, 1]
    stress = np.array([b.stress for b in case.scene.blocks])
    assert np.allclose(stress[:, 0], -100 + 10 * yc, rtol=1e-8)
    assert np.allclose(stress[:, 1], -200 + 20 * yc, rtol=1e-8)
    assert all(b.velocity == (0.0, 0.0) for b in case.scene.blocks)


THREE_BLOCKS = """<?xml version="1.0"?>
<DDA><Geometry>
  <Edgenodedist distance="0.001"/>
  <Jointlist>
    <Joint type="1"> -0.01 0 3.01 0 </Joint>
    <Joint type="1"> -0.01 1 3.01 1 </Joint>
    <Joint type="1"> 0 -0.01 0 1.01 </Joint>
    <Joint type="2"> 1 -0.01 1 1.01 </Joint>
    <Joint type="2"> 2 -0.01 2 1.01 </Joint>
    <Joint type="1"> 3 -0.01 3 1.01 </Joint>
  </Jointlist>
  <Matlinelist>
    <Line type="2"> 0.5 0.5 1.5 0.5 </Line>
    <Line type="3"> 2.2 0.2 2.8 0.8 </Line>
  </Matlinelist>
  <Holepointlist> HOLE </Holepointlist>
  <Measuredpointlist> <Point> 0.5 0.5 </Point> </Measuredpointlist>
</Geometry></DDA>
"""
THREE_MATERIALS = """<?xml version="1.0"?>
<DDA><Analysis>
  <Analysistype type="static"/> <Numtimesteps timesteps="3"/> <Maxtimestep maxtimestep="0.001"/>
  <Maxdisplacement maxdisplacement="0.01"/> <Autopenalty flag="no" pfactor="10"/>
  <Gravaccel value="9.81"/> <Planestrain flag="no"/>
  MATERIALS
  <Jointproperties><Friction>30</Friction><Cohesion>1</Cohesion><Tensile>2</Tensile></Jointproperties>
  <Jointproperties><Friction>35</Friction></Jointproperties>
</Analysis></DDA>
"""


def three_blocks(tmp_path, hole=""):
    (tmp_path / "three.geo").write_text(THREE_BLOCKS.replace("HOLE", hole))
    mats = "".join(f"<Blockmaterial><Unitmass>{rho}</Unitmass><Youngsmod>1e9</Youngsmod>"
                   f"<Poissonratio>0.25</Poissonratio></Blockmaterial>" for rho in (1000, 2000, 3000))
    (tmp_path / "three.ana").write_text(THREE_MATERIALS.replace("MATERIALS", mats))
    return tmp_path / "three.geo", tmp_path / "three.ana"


def test_material_lines_and_hole_points(tmp_path):
    """Material lines (dc13): every block with an edge the line meets gets its material; a line
    meeting no edge gives it to the block containing its first end point; default 1. A hole
    point deletes the block containing it."""
    with warnings.catch_warnings():
        warnings.simplefilter("error", NtddaWarning)
        case = dd.read_ntdda(*three_blocks(tmp_path))
    left = {round(float(np.mean(b.vertices[:, 0])), 3): b.material.density for b in case.scene.blocks}
    assert left == {0.5: 2000.0, 1.5: 2000.0, 2.5: 3000.0}
    # joints: edges on lines of type 2 carry joint material 2
    mid = next(b for b in case.scene.blocks if np.mean(b.vertices[:, 0]) == pytest.approx(1.5))
    assert sorted(case.scene.joints[j].friction for j in mid.edge_joint) == [30, 30, 35, 35]
    assert case.params.static and case.params.penalty == pytest.approx(1e10)
    (pt,) = case.points
    assert pt.kind == "measured" and pt.name == "M1"
    case = dd.read_ntdda(*three_blocks(tmp_path, hole="<Point> 1.5 0.5 </Point>"))
    assert case.scene.n_blocks == 2
    assert sorted(round(float(np.mean(b.vertices[:, 0])), 3) for b in case.scene.blocks) == [0.5, 2.5]


BOUNDARY_GEO = """0.001
5 NB
0 0 1 0 1 0
0 0 2 0 1
2 0 2 1 1
2 1 0 1 1
0 1 0 0 1
1 -0.01 1 1.01 2
0.5 0.5 0.5 0.5
1.5 0.5
"""
BOUNDARY_ANA = """1 2 1 2 0.01 0.001
2000 19620 1e9 0.25  0 0 0  0 0 0  0 0 0
30 0 0
40 0 0
"""


@pytest.mark.parametrize("n_boundary", [0, 4])
def test_original_format_with_boundary_lines(tmp_path, n_boundary):
    """GHS boundary lines (the first n lines) change only the merging rules: a square cut by
    one joint gives two unit blocks either way; the joint's edges carry joint type 2."""
    geo, ana = tmp_path / "sq.geo", tmp_path / "sq.ana"
    geo.write_text(BOUNDARY_GEO.replace("NB", str(n_boundary)))
    ana.write_text(BOUNDARY_ANA)
    case = read_quietly(geo, ana)
    assert case.geometry.n_boundary_lines == n_boundary and case.analysis.dynamic
    areas = sorted(float(dd.polygon_integrals(b.vertices, np.array([0, len(b.vertices)]))["area"][0])
                   for b in case.scene.blocks)
    assert areas == pytest.approx([1.0, 1.0], rel=1e-12)
    assert case.gravity == pytest.approx(9.81)
    fp, = case.scene.fixed_points
    assert fp.xy == (0.5, 0.5) and np.mean(case.scene.blocks[fp.block].vertices[:, 0]) < 1
    (pt,) = case.points
    assert pt.name == "M1" and np.mean(case.scene.blocks[pt.block].vertices[:, 0]) > 1
    for b in case.scene.blocks:
        n = len(b.vertices)
        on_joint = [k for k in range(n) if np.allclose(b.vertices[[k, (k + 1) % n], 0], 1.0)]
        assert [case.scene.joints[b.edge_joint[k]].friction for k in on_joint] == [40.0]


def test_automatic_time_step_runs_the_file_s_steps(tmp_path):
    """With ntdda's automatic time step the file's step count is run (ntdda counts steps) and
    Maxtimestep is an upper bound."""
    case = pushblock_with(tmp_path, lambda s: s.replace('<Autotimestep flag="no"/>', '<Autotimestep flag="yes"/>'))
    assert case.params.dt is None and case.params.dt_max == 0.01
    assert case.steps == 500 and case.duration is None


NESTED = """<?xml version="1.0"?>
<DDA><Geometry><Edgenodedist distance="0.001"/><Jointlist>
  <Joint type="1"> 0 0 4 0 </Joint> <Joint type="1"> 4 0 4 4 </Joint>
  <Joint type="1"> 4 4 0 4 </Joint> <Joint type="1"> 0 4 0 0 </Joint>
  <Joint type="1"> 1 1 3 1 </Joint> <Joint type="1"> 3 1 3 3 </Joint>
  <Joint type="1"> 3 3 1 3 </Joint> <Joint type="1"> 1 3 1 1 </Joint>
  BRIDGE
</Jointlist></Geometry></DDA>
"""


def test_unconnected_loops_and_bridges(tmp_path):
    """A joint loop not connected to the rest: as in ntdda the inner block is deleted and the
    outer one keeps its full outline (warned). Joined by a single segment (a bridge), the
    outer block would wrap around it twice: an error, not a broken polygon."""
    geo = tmp_path / "nested.geo"
    geo.write_text(NESTED.replace("BRIDGE", ""))
    with pytest.warns(NtddaQuirkWarning, match="inside another block"):
        blocks = cut_ntdda_geometry(read_ntdda_geometry(geo))
    (outer,) = blocks.polygons
    assert np.ptp(outer, axis=0).tolist() == [4.0, 4.0] and len(outer) == 4
    geo.write_text(NESTED.replace("BRIDGE", '<Joint type="1"> 2 0 2 1 </Joint>'))
    with pytest.raises(NtddaFormatError, match=r"nested.geo: .*twice through the node .*simple polygons"):
        cut_ntdda_geometry(read_ntdda_geometry(geo))
