"""ParaView output: recorded frames as VTK files (optional extra ``ddatai[vtk]``, meshio).

`write_vtk` writes, for every frame drawn, ``blocks_NNNNN.vtu``: the deformed blocks as polygon
cells with their fields, and, when contacts were recorded, ``contacts_NNNNN.vtu``: the contact
points as vertex cells with their state and forces; ``blocks.pvd`` and ``contacts.pvd`` list
them with their simulated times, so ParaView opens each as one time series. The VTK files are
written by meshio; the two ``.pvd`` indexes are built with the standard library's XML writer.

Block fields (cell data): ``block_id``, ``fixed`` (0/1), ``material`` (index into
``Results.meta["scene"]["materials"]``, -1 when unknown), ``displacement`` [m] and ``velocity``
[m/s] of the centroid (3-vectors, z = 0), ``angular_velocity`` [rad/s], ``rotation`` [rad],
``stress`` (σx, σy, τxy) [Pa, compression negative]. Contact fields (point data): ``state``
(0 open, 1 sliding, 2 locked), ``normal_force`` and ``shear_force`` [N/m]. A frame without
contacts has no contacts file (meshio cannot read an empty one back), so the contact series
lists only the frames that have some. Coordinates are the model's (x, y) with z = 0, in metres.
"""

from __future__ import annotations

from pathlib import Path
from typing import Optional, Sequence
from xml.etree import ElementTree

import numpy as np


def _meshio():
    try:
        import meshio
    except ImportError:
        raise ImportError("VTK output needs meshio, an optional extra: pip install 'ddatai[vtk]'") from None
    return meshio


def _cells(offset: np.ndarray) -> tuple[list[tuple[str, np.ndarray]], np.ndarray]:
    """Polygon cell blocks (one per vertex count: meshio stores equal-sized cells together)
    and the block id of every cell in their order."""
    counts = np.diff(offset)
    cells, order = [], []
    for n in np.unique(counts):
        ids = np.flatnonzero(counts == n)
        kind = {3: "triangle", 4: "quad"}.get(int(n), "polygon")
        cells.append((kind, (offset[ids][:, None] + np.arange(n)[None, :]).astype(np.int64)))
        order.append(ids)
    return cells, np.concatenate(order) if order else np.zeros(0, np.int64)


def _pvd(path: Path, entries: list[tuple[float, str]]) -> None:
    root = ElementTree.Element("VTKFile", type="Collection", version="0.1", byte_order="LittleEndian")
    collection = ElementTree.SubElement(root, "Collection")
    for t, name in entries:
        ElementTree.SubElement(collection, "DataSet", timestep=repr(float(t)), group="", part="0", file=name)
    ElementTree.indent(root)
    ElementTree.ElementTree(root).write(path, encoding="utf-8", xml_declaration=True)


def write_vtk(results, directory, *, frames: Optional[Sequence[int]] = None) -> Path:
    """Write recorded frames (default all) to ``directory`` as VTK files for ParaView (module
    docstring); returns the path of ``blocks.pvd``."""
    meshio = _meshio()
    r = results
    if r.n_frames == 0:
        raise ValueError("results have no frames to write")
    idx = list(range(r.n_frames)) if frames is None else [range(r.n_frames)[f] for f in frames]
    out = Path(directory)
    out.mkdir(parents=True, exist_ok=True)
    cells, order = _cells(np.asarray(r.vertex_offset))
    sizes = [len(c[1]) for c in cells]

    def split(values: np.ndarray) -> list[np.ndarray]:
        v = values[order]
        return list(np.split(v, np.cumsum(sizes)[:-1]))

    def vec3(xy: np.ndarray) -> np.ndarray:
        return np.column_stack([xy, np.zeros(len(xy))])

    material = r.block_material if len(r.block_material) == r.n_blocks else np.full(r.n_blocks, -1)
    static = {"block_id": np.arange(r.n_blocks), "fixed": r.block_fixed.astype(np.int64),
              "material": np.asarray(material, np.int64)}
    blocks, contacts = [], []
    has_forces = len(r.contact_normal_force) == len(r.contact_xy)
    for f in idx:
        data = dict(static)
        data.update(displacement=vec3(r.centroid[f] - r.centroid[0]), velocity=vec3(r.velocity[f]),
                    angular_velocity=r.angular_velocity[f], rotation=r.rotation[f], stress=r.stress[f])
        mesh = meshio.Mesh(vec3(r.vertices[f]), cells, cell_data={k: split(np.asarray(v)) for k, v in data.items()})
        name = f"blocks_{f:05d}.vtu"
        mesh.write(out / name)
        blocks.append((float(r.time[f]), name))
        a, b = r.contact_offset[f], r.contact_offset[f + 1]
        if b > a:
            point_data = {"state": r.contact_state[a:b].astype(np.int64)}
            if has_forces:
                point_data.update(normal_force=r.contact_normal_force[a:b], shear_force=r.contact_shear_force[a:b])
            cmesh = meshio.Mesh(vec3(r.contact_xy[a:b]), [("vertex", np.arange(b - a)[:, None])],
                                point_data=point_data)
            name = f"contacts_{f:05d}.vtu"
            cmesh.write(out / name)
            contacts.append((float(r.time[f]), name))
    _pvd(out / "blocks.pvd", blocks)
    if contacts:
        _pvd(out / "contacts.pvd", contacts)
    return out / "blocks.pvd"
