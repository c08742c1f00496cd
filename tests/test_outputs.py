"""Outputs users take elsewhere: contact forces, point and block histories (CSV), the block at a
point, metadata in the results file, a short repr."""

import json
import math

import numpy as np
import pytest

import ddatai as dd
from cases import G, ROCK, sliding_scene


def _run(theta, phi, **kw):
    scene, block = sliding_scene(theta, phi)
    idx = scene.add_measured_point(block, scene.polygon(block).mean(axis=0) + (0.2, 0.1))
    res = dd.simulate(scene, params=dd.Params(dt=0.005), duration=0.2, record_every=4, record_contacts=True, **kw)
    return scene, block, idx, res


@pytest.fixture(scope="module")
def sliding():
    return _run(30.0, 20.0)


def test_contact_forces_balance_the_weight(sliding):
    """A block sliding on a 30° incline (φ = 20°): its contacts carry N = W cos θ and, sliding,
    a shear force N tan φ; one at rest (φ = 40°) carries W sin θ in shear, locked."""
    weight = ROCK.density * G * 1.0
    theta = math.radians(30.0)
    for phi, state, shear in ((20.0, dd.ContactState.SLIDE, None), (40.0, dd.ContactState.LOCK, math.sin(theta))):
        _, _, _, res = _run(30.0, phi) if phi != 20.0 else (None, None, None, sliding[3])
        _, st = res.contacts(-1)
        normal, tangential = res.contact_forces(-1)
        assert len(normal) == 2 and np.all(st == state)
        assert normal.sum() == pytest.approx(weight * math.cos(theta), rel=2e-3)
        expected = weight * math.cos(theta) * math.tan(math.radians(phi)) if shear is None else weight * shear
        assert abs(tangential.sum()) == pytest.approx(expected, rel=2e-3)
    assert len(sliding[3].contact_normal_force) == len(sliding[3].contact_xy)


def test_histories_follow_points_blocks_and_measured_points(sliding, tmp_path):
    scene, block, idx, res = sliding
    # a vertex of the block, followed as a material point: exactly the recorded vertex
    v0 = res.vertex_offset[block]
    h = res.history(point=res.vertices[0, v0] + (1e-9, 1e-9))
    assert h.block == block
    assert np.allclose(h.position, res.vertices[:, v0], atol=1e-8)
    assert np.allclose(h.displacement, res.vertices[:, v0] - res.vertices[0, v0], atol=1e-8)
    # the measured point: its recorded positions, and its displacements
    m = res.history(measured=idx)
    assert np.allclose(m.position, res.measured[:, idx], atol=1e-10)
    assert np.allclose(res.measured_displacement()[:, idx], m.displacement, atol=1e-10)
    assert np.linalg.norm(m.displacement[-1]) > 1e-3  # it slid
    # a block: its centroid and velocity
    b = res.history(block=block)
    assert np.array_equal(b.position, res.centroid[:, block]) and np.array_equal(b.velocity, res.velocity[:, block])
    # the velocity of a point of a translating block is the block's
    assert np.allclose(m.velocity, res.velocity[:, block], atol=1e-6 + 1e-3 * np.abs(res.velocity[:, block]).max())
    path = m.to_csv(tmp_path / "h" / "m.csv")
    header = path.read_text().splitlines()[0].split(",")
    assert header[:3] == ["time_s", "x_m", "y_m"] and len(header) == 11
    back = np.loadtxt(path, delimiter=",", skiprows=1)
    assert back.shape == (res.n_frames, 11) and np.allclose(back, m.table(), rtol=1e-9, atol=1e-12)
    with pytest.raises(ValueError, match="one of"):
        res.history()
    with pytest.raises(ValueError, match="no block contains"):
        res.history(point=(100.0, 100.0))


def test_block_at_a_point(sliding):
    _, block, _, res = sliding
    assert res.block_at(res.centroid[0, block]) == block
    assert res.block_at(res.centroid[-1, block], frame=-1) == block
    assert res.block_at((1e3, 1e3)) == -1
    base = 1 - block
    assert res.block_at(res.centroid[0, base]) == base


def test_results_file_carries_metadata_and_repr_is_short(sliding, tmp_path):
    _, _, _, res = sliding
    path = tmp_path / "run.npz"
    res.save(path)
    back = dd.load_results(path)
    meta = back.meta
    assert meta["ddatai_version"] == dd.__version__
    assert meta["params"]["dt"] == 0.005 and meta["params"]["solver"] == "auto"
    assert meta["scene"]["blocks"] == 2 and meta["scene"]["fixed_blocks"] == 1
    assert meta["scene"]["materials"] == [{"density": 2500.0, "young": 5e9, "poisson": 0.25}]
    assert meta["scene"]["joints"][-1]["friction"] == 20.0
    for name in ("time", "centroid", "velocity", "stress", "contact_normal_force", "contact_shear_force"):
        assert name in meta["units"]
    assert json.loads(back.metadata) == meta
    assert np.array_equal(back.contact_shear_force, res.contact_shear_force)
    text = repr(res)
    assert len(text) < 200 and "2 blocks" in text and f"{res.n_frames} frames" in text


def test_vtk_files_read_back(sliding, tmp_path):
    meshio = pytest.importorskip("meshio", reason="VTK output is the optional [vtk] extra (meshio), not installed")
    from xml.etree import ElementTree

    _, block, _, res = sliding
    pvd = res.to_vtk(tmp_path / "vtk")
    entries = ElementTree.parse(pvd).getroot().findall("./Collection/DataSet")
    assert [float(e.get("timestep")) for e in entries] == [float(t) for t in res.time]
    f = res.n_frames - 1
    mesh = meshio.read(tmp_path / "vtk" / entries[f].get("file"))
    assert np.allclose(mesh.points[:, :2], res.vertices[f])
    ids = np.concatenate(mesh.cell_data["block_id"])
    disp = np.concatenate(mesh.cell_data["displacement"])
    stress = np.concatenate(mesh.cell_data["stress"])
    for row, b in enumerate(ids):
        assert np.allclose(disp[row, :2], res.displacement(f)[b]) and np.allclose(stress[row], res.stress[f, b])
    assert set(np.concatenate(mesh.cell_data["material"]).tolist()) == {0}
    contacts = meshio.read(tmp_path / "vtk" / f"contacts_{f:05d}.vtu")
    normal, shear = res.contact_forces(f)
    assert np.allclose(contacts.points[:, :2], res.contacts(f)[0])
    assert np.allclose(contacts.point_data["normal_force"], normal)
    assert np.allclose(contacts.point_data["shear_force"], shear)


SCRIPT = '''
import sys
sys.path.insert(0, {tests!r})
from cases import sliding_scene

DURATION = 0.05


def build():
    scene, block = sliding_scene(30.0, 20.0)
    scene.add_measured_point(block, scene.polygon(block).mean(axis=0))
    return scene
'''


def test_command_line_writes_histories_measured_points_and_vtk(tmp_path, capsys, monkeypatch):
    from pathlib import Path

    from ddatai.cli import main

    script = tmp_path / "slide.py"
    script.write_text(SCRIPT.format(tests=str(Path(__file__).parent)))
    out = tmp_path / "out"
    scene, block = sliding_scene(30.0, 20.0)
    x, y = scene.polygon(block).mean(axis=0)
    assert main(["run", str(script), "--out", str(out), "--quiet", "--history", f"{x},{y}"]) == 0
    res = dd.load_results(out / "slide.npz")
    measured = np.loadtxt(out / "slide_measured.csv", delimiter=",", skiprows=1)
    assert measured.shape == (res.n_frames, 5) and np.allclose(measured[:, 3:], res.measured_displacement()[:, 0])
    history = np.loadtxt(out / f"slide_history_{x:g}_{y:g}.csv", delimiter=",", skiprows=1)
    assert np.allclose(history[:, 3:5], measured[:, 3:5], atol=1e-9)
    capsys.readouterr()
    assert main(["run", str(script), "--out", str(out), "--history", "99,99"]) == 2
    assert "no block of slide contains" in capsys.readouterr().err
    import importlib.util

    if importlib.util.find_spec("meshio") is not None:
        assert main(["run", str(script), "--out", str(out), "--quiet", "--vtk", str(tmp_path / "v")]) == 0
        assert (tmp_path / "v" / "blocks.pvd").is_file() and (tmp_path / "v" / "contacts.pvd").exists() is False
    # --vtk without meshio: one line, before the run

    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec", lambda name, *a: None if name == "meshio" else real(name, *a))
    assert main(["run", str(script), "--out", str(out), "--vtk", str(tmp_path / "v")]) == 2
    assert "--vtk needs meshio" in capsys.readouterr().err


def test_fixed_points_and_loads_are_recorded_and_drawn():
    from ddatai import render

    scene = dd.Scene(gravity=G)
    scene.add_block([(-2, -1), (6, -1), (6, 0), (-2, 0)], material=ROCK, fixed=True)
    pushed = scene.add_block([(0, 0), (1, 0), (1, 1), (0, 1)], material=ROCK)
    held = scene.add_block([(3, 0), (4, 0), (4, 1), (3, 1)], material=ROCK)
    scene.add_fixed_point(held, (3.5, 0.5))
    scene.add_point_load(pushed, (0.0, 0.5), lambda t: (1e5 * t, 0.0))
    scene.set_joint(dd.Joint(friction=30.0))
    res = dd.simulate(scene, params=dd.Params(dt=0.01), duration=0.2, record_every=5)
    assert res.fixed_points.shape == (res.n_frames, 1, 2) and res.load_points.shape == (res.n_frames, 1, 2)
    assert np.allclose(res.fixed_points[:, 0], (3.5, 0.5), atol=1e-4)
    assert np.allclose(res.load_forces[:, 0, 0], 1e5 * res.time) and np.all(res.load_forces[:, 0, 1] == 0)
    # the load point moves with its block
    assert np.allclose(res.load_points[:, 0] - res.load_points[0, 0], res.centroid[:, pushed] - res.centroid[0, pushed],
                       atol=1e-6)
    image = dd.render_frames(res, size=(300, 200), frames=[-1])[0]
    for colour in (render.LOAD, render.FIXED_POINT):
        assert np.any(np.all(image == colour, axis=-1))


def test_history_plot(sliding, tmp_path):
    pytest.importorskip("matplotlib", reason="plots are the optional [plot] extra (matplotlib), not installed")
    from PIL import Image

    _, block, idx, res = sliding
    path = tmp_path / "h.png"
    figure = res.history(measured=idx).plot(path)
    assert len(figure.axes) == 2
    with Image.open(path) as im:
        assert im.size == (700, 500)


def test_contacts_csv(sliding, tmp_path):
    _, _, _, res = sliding
    path = res.contacts_csv(tmp_path / "c.csv")
    assert path.read_text().splitlines()[0] == "frame,time_s,x_m,y_m,state,normal_N_per_m,shear_N_per_m"
    table = np.loadtxt(path, delimiter=",", skiprows=1)
    assert len(table) == len(res.contact_xy)
    last = table[table[:, 0] == res.n_frames - 1]
    normal, shear = res.contact_forces(-1)
    assert np.allclose(last[:, 5], normal) and np.allclose(last[:, 6], shear)
    assert np.allclose(last[:, 1], res.time[-1]) and np.allclose(last[:, 2:4], res.contacts(-1)[0])
