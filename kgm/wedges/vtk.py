"""A wedge for ParaView and for VTK: a ``.vtp`` file (VTK XML PolyData, written as plain XML
without VTK) and, where the ``[3d]`` extra (PyVista, VTK) is installed, offscreen renders
(docs/kgm/wedge.md §7). VTK ≥ 9.4 wheels render without a display through EGL."""

from __future__ import annotations

from pathlib import Path
from xml.sax.saxutils import escape

import numpy as np

#: integer code of each face kind in the file's ``kind`` cell array
KIND_CODES = {"free": 0, "joint": 1, "crack": 2}


def _polygons(wedge):
    block = wedge.block
    if block is None:
        raise ValueError(f"no wedge to write ({wedge.reason})")
    points, polys, labels, kinds, areas, normal_force = [], [], [], [], [], []
    for f in block.faces:
        start = len(points)
        points.extend(f.vertices.tolist())
        polys.append(list(range(start, start + len(f.vertices))))
        labels.append(f.label)
        kinds.append(KIND_CODES[f.kind])
        areas.append(f.area)
        normal_force.append(wedge.normal_force_on.get(f.label, 0.0))
    return np.array(points), polys, labels, kinds, areas, normal_force


def write_vtp(wedge, path) -> Path:
    """Write the wedge's faces to ``path`` (VTK XML PolyData, ASCII): each face a polygon with
    cell data ``kind`` (0 free, 1 joint, 2 crack), ``area`` [m²], ``normal_force`` [N] and
    ``face`` (its index in the field data's label list); field data ``factor_of_safety``,
    ``volume`` [m³], ``weight`` [N] and ``face_labels``. Opens in ParaView as it is."""
    pts, polys, labels, kinds, areas, normal_force = _polygons(wedge)
    conn = " ".join(str(i) for p in polys for i in p)
    offsets = " ".join(str(int(x)) for x in np.cumsum([len(p) for p in polys]))
    fmt = lambda a: " ".join(repr(float(x)) for x in np.ravel(a))   # noqa: E731
    fs = wedge.fs if np.isfinite(wedge.fs) else -1.0
    xml = f"""<?xml version="1.0"?>
<VTKFile type="PolyData" version="1.0" byte_order="LittleEndian">
  <PolyData>
    <FieldData>
      <DataArray type="Float64" Name="factor_of_safety" NumberOfTuples="1" format="ascii">{fs!r}</DataArray>
      <DataArray type="Float64" Name="volume" NumberOfTuples="1" format="ascii">{wedge.volume!r}</DataArray>
      <DataArray type="Float64" Name="weight" NumberOfTuples="1" format="ascii">{wedge.weight!r}</DataArray>
      <DataArray type="String" Name="face_labels" NumberOfTuples="{len(labels)}" format="ascii">{_strings(labels)}</DataArray>
    </FieldData>
    <Piece NumberOfPoints="{len(pts)}" NumberOfVerts="0" NumberOfLines="0" NumberOfStrips="0" NumberOfPolys="{len(polys)}">
      <Points>
        <DataArray type="Float64" NumberOfComponents="3" format="ascii">{fmt(pts)}</DataArray>
      </Points>
      <Polys>
        <DataArray type="Int64" Name="connectivity" format="ascii">{conn}</DataArray>
        <DataArray type="Int64" Name="offsets" format="ascii">{offsets}</DataArray>
      </Polys>
      <CellData Scalars="kind">
        <DataArray type="Int32" Name="kind" format="ascii">{" ".join(str(k) for k in kinds)}</DataArray>
        <DataArray type="Int32" Name="face" format="ascii">{" ".join(str(k) for k in range(len(labels)))}</DataArray>
        <DataArray type="Float64" Name="area" format="ascii">{fmt(areas)}</DataArray>
        <DataArray type="Float64" Name="normal_force" format="ascii">{fmt(normal_force)}</DataArray>
      </CellData>
    </Piece>
  </PolyData>
</VTKFile>
"""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(xml, encoding="utf-8")
    return path


def _strings(labels) -> str:
    # VTK's ASCII string arrays: each string's characters as byte values, each ended by 0
    return " ".join(" ".join(str(b) for b in escape(s).encode("utf-8")) + " 0" for s in labels)


def _pyvista():
    try:
        import pyvista as pv
    except ImportError:
        raise RuntimeError("PyVista rendering needs the [3d] extra: pip install 'ddatai[3d]'") from None
    pv.OFF_SCREEN = True
    return pv


def _plotter(wedge, size):
    pv = _pyvista()
    pts, polys, labels, kinds, _, _ = _polygons(wedge)
    faces = np.concatenate([[len(p), *p] for p in polys])
    mesh = pv.PolyData(pts, faces)
    mesh.cell_data["kind"] = np.array(kinds)
    pl = pv.Plotter(off_screen=True, window_size=list(size))
    pl.add_mesh(mesh, scalars="kind", show_edges=True, cmap=["#c44e52", "#4c72b0", "#8c8c8c"], clim=(0, 2),
                show_scalar_bar=False)
    pl.add_text(f"FS {wedge.fs:.3f}  {wedge.mode}", font_size=10)
    pl.camera_position = "iso"
    return pl


def render_png(wedge, path, *, size=(640, 480)) -> Path:
    """The wedge rendered with PyVista/VTK offscreen to a PNG."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    pl = _plotter(wedge, size)
    pl.screenshot(str(path))
    pl.close()
    return path


def render_gif(wedge, path, *, frames: int = 36, size=(640, 480), fps: int = 12) -> Path:
    """The wedge turning once about the vertical, rendered with PyVista/VTK offscreen."""
    from PIL import Image

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    pl = _plotter(wedge, size)
    images = []
    for _ in range(frames):
        pl.camera.azimuth += 360.0 / frames
        pl.render()
        images.append(Image.fromarray(pl.screenshot(return_img=True)).quantize(colors=128))
    pl.close()
    images[0].save(path, save_all=True, append_images=images[1:], duration=int(1000 / fps), loop=0)
    return path
