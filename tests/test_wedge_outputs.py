"""The wedge's command line, TOML input, pictures and files (docs/kgm/wedge.md §7–8); input
errors name what is wrong; `import kgm` stays light."""

from __future__ import annotations

import importlib.util
import io
import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest

import ddatai as dd
import kgm
from kgm.cli import main

ROOT = Path(__file__).resolve().parents[1]
EXAMPLE = ROOT / "docs" / "kgm" / "wedge_example.toml"
needs_matplotlib = pytest.mark.skipif(importlib.util.find_spec("matplotlib") is None,
                                      reason="pictures need matplotlib (the [plot] extra)")


def _wedge(**kw):
    j1, j2 = dd.Joint(friction=20.0, cohesion=24e3), dd.Joint(friction=30.0, cohesion=48e3)
    return kgm.wedge(kgm.Plane(65, 185), kgm.Plane(12, 195), 30.0, [kgm.Plane(45, 105, j1), kgm.Plane(70, 235, j2)],
                     tension_crack=kgm.TensionCrack(kgm.Plane(70, 165), 12.0), **kw)


def test_import_kgm_loads_no_scipy_spatial_or_matplotlib():
    code = ("import kgm, kgm.wedges, kgm.wedges.cli, sys; "
            "print([m for m in ('matplotlib', 'scipy.spatial', 'scipy.optimize', 'PIL') if m in sys.modules])")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, cwd=ROOT).stdout
    assert out.strip().splitlines()[-1] == "[]"


def test_vtp_file_holds_the_wedge(tmp_path):
    w = _wedge()
    path = w.write_vtp(tmp_path / "w.vtp")
    root = ET.parse(path).getroot()
    piece = root.find("PolyData/Piece")
    assert int(piece.get("NumberOfPolys")) == len(w.block.faces) == 5
    arrays = {a.get("Name"): a.text.split() for a in root.iter("DataArray") if a.get("Name")}
    pts = np.array(root.find("PolyData/Piece/Points/DataArray").text.split(), float).reshape(-1, 3)
    offsets = np.array(arrays["offsets"], int)
    conn = np.array(arrays["connectivity"], int)
    assert offsets[-1] == len(conn) and conn.max() == len(pts) - 1
    assert np.array(arrays["area"], float) == pytest.approx([f.area for f in w.block.faces], rel=1e-12)
    assert float(arrays["factor_of_safety"][0]) == pytest.approx(w.fs, rel=1e-12)
    # the polygons' areas from the file's own points and connectivity
    start = 0
    for k, end in enumerate(offsets):
        poly = pts[conn[start:end]]
        area = 0.5 * np.linalg.norm(sum(np.cross(poly[i], poly[(i + 1) % len(poly)]) for i in range(len(poly))))
        assert area == pytest.approx(float(arrays["area"][k]), rel=1e-9)
        start = end


@needs_matplotlib
def test_pictures_are_written(tmp_path):
    from PIL import Image

    w = _wedge(water=kgm.Water(fill=0.5))
    png = w.write_png(tmp_path / "w.png")
    net = w.stereonet(tmp_path / "net.png")
    gif = w.write_gif(tmp_path / "w.gif", frames=4)
    assert Image.open(png).size == (640, 480) and Image.open(net).size == (640, 640)
    im = Image.open(gif)
    assert im.n_frames == 4 and im.size == (640, 480)
    frames = []
    for k in range(im.n_frames):           # the view turns: the frames differ
        im.seek(k)
        frames.append(np.asarray(im.convert("L"), float))
    assert np.abs(frames[0] - frames[2]).mean() > 1.0
    none = kgm.wedge(kgm.Plane(28, 185), kgm.Plane(5, 195), 30.0, [kgm.Plane(45, 105, dd.Joint()),
                                                                   kgm.Plane(70, 235, dd.Joint())])
    none.stereonet(tmp_path / "none.png")              # a stereonet shows why no wedge forms
    with pytest.raises(ValueError, match="no wedge to draw"):
        none.write_png(tmp_path / "x.png")
    with pytest.raises(ValueError, match="renderer"):
        w.write_png(tmp_path / "x.png", renderer="povray")


def test_pyvista_renderer_is_optional(tmp_path):
    w = _wedge()
    if importlib.util.find_spec("pyvista") is None:
        with pytest.raises(RuntimeError, match=r"\[3d\]"):
            w.write_png(tmp_path / "x.png", renderer="pyvista")
    else:                                                  # pragma: no cover - with the [3d] extra
        from PIL import Image

        assert Image.open(w.write_png(tmp_path / "x.png", renderer="pyvista")).size == (640, 480)


@needs_matplotlib
def test_kgm_wedge_command_runs_the_example(tmp_path):
    spec = EXAMPLE.read_text().replace("n = 100000", "n = 2000")
    src = tmp_path / "wedge.toml"
    src.write_text(spec)
    out = io.StringIO()
    assert main(["wedge", str(src), "--frames", "3"], out=out) == 0
    text = out.getvalue()
    w = _wedge(water=kgm.Water(fill=0.5), seismic=0.08, density=2600.0)
    assert f"FS = {w.fs:.4f}" in text and "sliding on joint 1 and joint 2" in text
    # the gallery script builds the same wedge from Python
    spec = importlib.util.spec_from_file_location("wedge_example", ROOT / "docs" / "kgm" / "wedge_example.py")
    example = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(example)
    assert example.build().fs == pytest.approx(w.fs, rel=1e-12)
    assert "support for FS 1.5" in text and "2000 samples (latin-hypercube, seed 1)" in text
    for name in ("wedge.png", "wedge.gif", "wedge_stereonet.png", "wedge.vtp", "wedge_samples.csv"):
        assert (tmp_path / name).is_file(), name
    first = (tmp_path / "wedge_samples.csv").read_text()
    assert first.startswith("# kgm wedge study ") and len(first.splitlines()) == 2002
    out = io.StringIO()
    assert main(["wedge", str(src), "--n", "500", "--csv", str(tmp_path / "other.csv")], out=out) == 0
    assert "500 samples" in out.getvalue()


@pytest.mark.parametrize("text, message", [
    ("[slope]\nface = {dip = 65, dip_direction = 185}\nheight = 10\n", "[slope] needs upper"),
    ("[slope]\nface = {dip = 65, dip_direction = 185}\nupper = {dip = 5, dip_direction = 185}\nheight = 10\n"
     "[[joints]]\ndip = 40\ndip_direction = 120\nfriction = 30\n", "two [[joints]]"),
    ("[slope]\nface = {dip = 65, dip_direction = 185}\nupper = {dip = 5, dip_direction = 185}\nheight = 10\n"
     "[[joints]]\ndip = 40\ndip_direction = 120\nfriction = 30\n[[joints]]\ndip = 60\ndip_direction = 240\n",
     "[[joints]] 2 needs friction"),
    ("[slope]\nface = {dip = 65, dip_direction = 185}\nupper = {dip = 5, dip_direction = 185}\nheight = -1\n"
     "[[joints]]\ndip = 40\ndip_direction = 120\nfriction = 30\n[[joints]]\ndip = 60\ndip_direction = 240\n"
     "friction = 30\n", "height must be"),
    ("[slope]\nface = {dip = 65, dip_direction = 185}\nupper = {dip = 5, dip_direction = 185}\nheight = 10\n"
     "[[joints]]\ndip = 40\ndip_direction = 120\nfriction = 30\n[[joints]]\ndip = 60\ndip_direction = 240\n"
     "friction = 30\n[study.variables.joint4_dip]\ndistribution = \"normal\"\nmean = 1\nsd = 1\n",
     "unknown variable 'joint4_dip'"),
    ("[slope\n", "not valid TOML"),
])
def test_bad_input_gets_one_line_naming_it(tmp_path, capsys, text, message):
    src = tmp_path / "bad.toml"
    src.write_text(text)
    assert main(["wedge", str(src)], out=io.StringIO()) == 2
    err = capsys.readouterr().err
    assert message in err and len(err.strip().splitlines()) == 1


def test_api_errors_name_the_parameter():
    j = dd.Joint(friction=30.0)
    with pytest.raises(ValueError, match="joint 2 .* needs its strength"):
        kgm.wedge(kgm.Plane(65, 185), kgm.Plane(12, 195), 30.0, [kgm.Plane(45, 105, j), kgm.Plane(70, 235)])
    with pytest.raises(ValueError, match="Plane.dip must be"):
        kgm.Plane(95, 10)
    with pytest.raises(ValueError, match="steeper than the upper face"):
        kgm.wedge(kgm.Plane(10, 185), kgm.Plane(12, 195), 30.0, [kgm.Plane(45, 105, j), kgm.Plane(70, 235, j)])
    with pytest.raises(ValueError, match="Water.fill"):
        kgm.Water(fill=1.5)
    with pytest.raises(ValueError, match="Bolt.kind"):
        kgm.Bolt(1e5, 10, 0, kind="grouted")
    with pytest.raises(ValueError, match="seismic must be"):
        _wedge(seismic="strong")
    with pytest.raises(ValueError, match="joint 1 strikes parallel"):
        kgm.wedge(kgm.Plane(65, 185), kgm.Plane(12, 185), 30.0, [kgm.Plane(45, 185, j), kgm.Plane(70, 235, j)])


def test_bench_width_and_slope_length_scale_the_wedge():
    """The wedge is scaled about its toe until it lies within the bench width behind the crest
    and the slope length along it (SWedge's sizing): V ∝ H³ and the limit is reached exactly."""
    j = dd.Joint(friction=30.0)
    face, upper = kgm.Plane(65, 185), kgm.Plane(12, 185)
    args = (face, upper, 30.0, [kgm.Plane(45, 105, j), kgm.Plane(70, 235, j)])
    free = kgm.wedge(*args)
    h = -face.normal[:2] / np.linalg.norm(face.normal[:2])          # horizontal, into the slope
    strike = np.array([h[1], -h[0]])
    for width in (5.0, 12.0):
        b = kgm.wedge(*args, bench_width=width)
        assert b.height < free.height
        assert b.volume == pytest.approx(free.volume * (b.height / 30.0) ** 3, rel=1e-9)
        crest = b.block.face("slope face").vertices[:, :2] @ h
        assert np.max(b.block.vertices[:, :2] @ h) - np.max(crest) == pytest.approx(width, rel=1e-9)
        assert b.fs == pytest.approx(free.fs, rel=1e-9)      # friction only: FS does not depend on size
    s = kgm.wedge(*args, slope_length=8.0)
    assert np.ptp(s.block.vertices[:, :2] @ strike) == pytest.approx(8.0, rel=1e-9)
    assert kgm.wedge(*args, bench_width=1e4).volume == pytest.approx(free.volume, rel=1e-12)
