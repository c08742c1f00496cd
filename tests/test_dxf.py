"""Sections from DXF (ddatai.io.dxf, optional ezdxf): the example drawing reads back to the blocks
of the same section built in Python, in metres or millimetres; a unitless drawing is refused
without units=; bad drawings name what is wrong."""

from pathlib import Path

import numpy as np
import pytest
import shapely

ezdxf = pytest.importorskip("ezdxf", reason="the optional [dxf] extra (ezdxf) is not installed")

import ddatai as dd  # noqa: E402
from ddatai.io.dxf import read_dxf_section, write_dxf_section  # noqa: E402

from scenes.section import drawing as example  # noqa: E402

SCENES = Path(__file__).resolve().parents[1] / "scenes"


def areas(scene):
    return np.array([shapely.Polygon(s.vertices).area for s in scene.blocks])


def read(path, **kw):
    return dd.read_dxf(path, material=example.ROCK, joints=example.JOINTS, default_joint=example.DEFAULT_JOINT, **kw)


def same_scene(a, b):
    """Same blocks (areas to 1e-9 relative, the round-off of coordinates written as text and
    scaled), same fixed blocks, joints and measured points."""
    assert a.n_blocks == b.n_blocks
    np.testing.assert_allclose(areas(a), areas(b), rtol=1e-9, atol=0)
    assert [s.fixed for s in a.blocks] == [s.fixed for s in b.blocks]
    assert a.joints == b.joints
    for sa, sb in zip(a.blocks, b.blocks):
        assert np.array_equal(sa.edge_joint, sb.edge_joint)


@pytest.mark.parametrize("units", ["m", "mm"])
def test_round_trip_is_the_python_section(tmp_path, units):
    path = example.write(tmp_path / f"section_{units}.dxf", units=units)
    scene = read(path)
    same_scene(scene, example.python_scene())
    assert len(scene.measured_points) == 2
    assert sum(s.fixed for s in scene.blocks) > 0


def test_the_committed_drawing_is_the_scripts():
    """scenes/section/section.dxf is what scenes/section/drawing.py writes (regenerate it if not)."""
    same_scene(read(example.DRAWING), example.python_scene())
    from ddatai.io.scenefile import load_scene_script

    built, _ = load_scene_script(SCENES / "dxf_section.py").build()
    assert built.n_blocks == example.python_scene().n_blocks


def _unitless(tmp_path, scale=1000.0):
    """The section in millimetres with $INSUNITS = 0 (unitless)."""
    path = example.write(tmp_path / "mm.dxf", units="mm")
    doc = ezdxf.readfile(path)
    doc.header["$INSUNITS"] = 0
    doc.saveas(path)
    return path


def test_unitless_drawing_is_refused_unless_units_are_given(tmp_path):
    path = _unitless(tmp_path)
    with pytest.raises(ValueError, match=r"no unit.*units='m'"):
        read(path)
    same_scene(read(path, units="mm"), example.python_scene())


def test_units_contradicting_the_header_are_refused(tmp_path):
    path = example.write(tmp_path / "mm.dxf", units="mm")
    with pytest.raises(ValueError, match="header says its unit is mm"):
        read(path, units="m")
    assert read_dxf_section(path, joint_layers=list(example.JOINTS)).scale == 1e-3


def test_water_layer_and_other_layers(tmp_path):
    g = example.geometry()
    path = tmp_path / "w.dxf"
    write_dxf_section(path, water=[(-5.0, 10.0), (65.0, 20.0)], **g)
    doc = ezdxf.readfile(path)
    doc.modelspace().add_text("title", dxfattribs={"layer": "TEXT"})   # ignored
    doc.saveas(path)
    scene = read(path)
    assert scene.water is not None


@pytest.mark.parametrize("edit, message", [
    (lambda msp: msp.add_circle((5, 5), 1.0, dxfattribs={"layer": "BEDDING"}), "CIRCLE entity cannot be read"),
    (lambda msp: msp.add_lwpolyline([(0, 0, 0.5), (1, 1, 0)], format="xyb", dxfattribs={"layer": "CROSS"}),
     "arc segments"),
    (lambda msp: msp.add_lwpolyline([(0, 0), (1, 1), (2, 0)], dxfattribs={"layer": "DOMAIN"}),
     "closed polylines"),
    (lambda msp: msp.add_lwpolyline([(0, 0), (1, 1)], dxfattribs={"layer": "CROSS", "extrusion": (0, 0, -1)}),
     "mirrored or tilted plane"),
    (lambda msp: msp.add_lwpolyline([(0, 0), (1, 1), (2, 0)], close=True, dxfattribs={"layer": "DOMAIN"}),
     "exactly one closed polyline"),
])
def test_bad_drawings_name_the_entity(tmp_path, edit, message):
    path = example.write(tmp_path / "bad.dxf")
    doc = ezdxf.readfile(path)
    edit(doc.modelspace())
    doc.saveas(path)
    with pytest.raises(ValueError, match=message):
        read(path)


def test_bad_arguments(tmp_path):
    path = example.write(tmp_path / "s.dxf")
    with pytest.raises(ValueError, match="joint layer 'FAULTS'"):
        dd.read_dxf(path, material=example.ROCK, joints={**example.JOINTS, "FAULTS": dd.Joint()})
    with pytest.raises(ValueError, match=r"joints\['BEDDING'\] must be a ddatai.Joint"):
        dd.read_dxf(path, material=example.ROCK, joints={"BEDDING": 30.0})
    with pytest.raises(ValueError, match="units must be one of"):
        read(path, units="furlong")
    with pytest.raises(ValueError, match="not a valid DXF|cannot read"):
        (tmp_path / "junk.dxf").write_text("not a drawing")
        read(tmp_path / "junk.dxf")


def test_trace_ends_short_of_the_outline_are_snapped(tmp_path):
    """A trace drawn to within 1e-7 × the section's size of the outline (a CAD round-off)
    still cuts the block in two; with snap=0 it is a dangling trace and is dropped, with a
    warning naming the gap."""
    path = tmp_path / "snap.dxf"
    box = [(0.0, 0.0), (10.0, 0.0), (10.0, 5.0), (0.0, 5.0)]
    write_dxf_section(path, boundary=box, traces=[([(0.0, 2.0), (10.0 - 1e-6, 2.5)], "BEDDING")])
    kw = dict(material=example.ROCK, joints={"BEDDING": dd.Joint(friction=30.0)})
    scene = dd.read_dxf(path, **kw)
    assert scene.n_blocks == 2
    np.testing.assert_allclose(sorted(areas(scene)), [22.5, 27.5], rtol=1e-6)
    from ddatai.cutting import TraceGapWarning
    with pytest.warns(TraceGapWarning, match="stops 1e-06 m short of the outline"):
        assert dd.read_dxf(path, snap=0.0, **kw).n_blocks == 1


def test_joints_file_is_the_scripts():
    """scenes/section/joints.toml gives the drawing the material and joints of drawing.py."""
    from ddatai.io.dxf import read_joints_file

    opts = read_joints_file(SCENES / "section" / "joints.toml")
    assert opts["material"] == example.ROCK and opts["joints"] == example.JOINTS
    assert opts["default_joint"] == example.DEFAULT_JOINT and opts["duration"] == 2.0


def test_command_lines_take_a_section_and_its_joints(tmp_path, capsys):
    import kgm.cli
    from ddatai import cli

    dxf, joints = SCENES / "section" / "section.dxf", SCENES / "section" / "joints.toml"
    assert kgm.cli.main(["analyze", str(dxf), "--joints", str(joints), "--method", "rigid"]) == 0
    out = capsys.readouterr().out
    assert "critical key group [26, 30, 32, 36]: FS 0.966" in out
    assert cli.main(["run", str(dxf), "--joints", str(joints), "--steps", "2", "--out", str(tmp_path)]) == 0
    assert (tmp_path / "section.npz").exists()
    assert kgm.cli.main(["analyze", str(dxf)]) == 2
    assert "needs its joints file, --joints" in capsys.readouterr().err


@pytest.mark.parametrize("text, message", [
    ("[joints.BEDDING]\nfriction = 30.0\n", r"\[material\] table"),
    ("[material]\ndensity = 2600.0\nyoung = 1e10\npoisson = 0.25\n", r"\[joints.LAYER\]"),
    ("[material]\ndensity = 2600.0\nyoung = 1e10\npoisson = 0.25\n[joints.B]\njrc = 40\njcs = 1e7\n"
     "residual_friction = 25.0\n", r"\[joints.B\]: BartonBandis.jrc"),
    ("[material]\ndensity = 2600.0\nyoung = 1e10\npoisson = 0.25\n[joints.B]\nfriciton = 30\n",
     r"\[joints.B\]: .*friciton"),
    ("colour = 3\n", "unknown key 'colour'"),
])
def test_bad_joints_files_name_the_key(tmp_path, text, message):
    from ddatai.io.dxf import read_joints_file

    path = tmp_path / "joints.toml"
    path.write_text(text)
    with pytest.raises(ValueError, match=message):
        read_joints_file(path)
