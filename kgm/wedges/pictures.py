"""Pictures of a wedge (docs/kgm/wedge.md §7), offscreen: a stereonet of its joint pyramids
with the friction cone and the sliding direction, and the wedge on its slope as a PNG and a
turning GIF drawn with matplotlib's 3D axes (the ``[plot]`` extra). `kgm.wedges.vtk` writes the
same block for ParaView and renders it with PyVista where the ``[3d]`` extra is installed.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Optional

import numpy as np

from .geometry import direction_vector

#: face colours by label (joints, crack, free faces)
COLOURS = {"joint 1": "#4c72b0", "joint 2": "#dd8452", "joint 3": "#55a868", "tension crack": "#8c8c8c",
           "slope face": "#c44e52", "upper face": "#937860"}


def _matplotlib():
    try:
        import matplotlib

        matplotlib.use("Agg", force=False)
        import matplotlib.pyplot as plt
    except ImportError:
        raise RuntimeError("wedge pictures need matplotlib: pip install 'ddatai[plot]'") from None
    return plt


def _project(d: np.ndarray) -> np.ndarray:
    """Stereographic projection of unit directions from the zenith onto the horizontal plane
    (Goodman & Shi's full-sphere net: the lower hemisphere inside the unit circle, the upper
    outside): (x, y) = (dₓ, d_y)/(1 − d_z), x east, y north."""
    d = np.asarray(d, dtype=float)
    return d[..., :2] / (1.0 - d[..., 2:3])


def _unproject(p: np.ndarray) -> np.ndarray:
    r2 = (p ** 2).sum(axis=-1, keepdims=True)
    return np.concatenate([2 * p, r2 - 1.0], axis=-1) / (1.0 + r2)


def _great_circle(normal, n=361) -> np.ndarray:
    """The projected great circle of the plane with this normal (both hemispheres)."""
    normal = np.asarray(normal, float) / np.linalg.norm(normal)
    a = np.cross(normal, [0.0, 0.0, 1.0])
    if np.linalg.norm(a) < 1e-9:
        a = np.array([1.0, 0.0, 0.0])
    a /= np.linalg.norm(a)
    b = np.cross(normal, a)
    t = np.linspace(0, 2 * np.pi, n)
    d = np.cos(t)[:, None] * a + np.sin(t)[:, None] * b
    p = _project(d)
    p[np.linalg.norm(p, axis=1) > 6] = np.nan                 # near the zenith: off the picture
    return p


def stereonet(wedge, path, *, size=(640, 640), dpi=100, title: Optional[str] = None) -> Path:
    """Write a stereonet of ``wedge`` (a `kgm.Wedge`) to ``path``: the joint pyramids of its
    joints on Goodman & Shi's full-sphere net (lower hemisphere inside the circle), the wedge's
    removable pyramid shaded, the great circles of the joints, slope and upper face, the friction
    cone of sliding directions (plunge ≥ φ of joint 1, for c = 0), the line of intersection and
    the sliding direction."""
    plt = _matplotlib()
    from matplotlib.colors import ListedColormap

    inputs = wedge.inputs
    joints = inputs["joints"]
    normals = np.array([j.normal for j in joints])
    fig, ax = plt.subplots(figsize=(size[0] / dpi, size[1] / dpi), dpi=dpi)
    lim = 2.4
    g = np.linspace(-lim, lim, 481)
    xx, yy = np.meshgrid(g, g)
    d = _unproject(np.stack([xx, yy], axis=-1))
    codes = ((d @ normals.T) < 0).astype(int) @ (2 ** np.arange(len(joints))[::-1])   # 0 above, 1 below
    ax.imshow(codes, extent=(-lim, lim, -lim, lim), origin="lower", alpha=0.18,
              cmap=ListedColormap(plt.cm.tab10.colors[:2 ** len(joints)]), interpolation="nearest")
    for code in range(2 ** len(joints)):
        name = format(code, f"0{len(joints)}b")
        pyr = next((p for p in wedge.pyramids if p.name == name), None)
        mask = codes == code
        if not mask.any():
            continue
        cx, cy = xx[mask].mean(), yy[mask].mean()
        kind = pyr.kind if pyr is not None else ""
        weight = "bold" if name == wedge.pyramid else "normal"
        ax.text(cx, cy, f"JP {name}\n{kind}", ha="center", va="center", fontsize=8, fontweight=weight)
        if name == wedge.pyramid:
            ax.contourf(xx, yy, mask.astype(float), levels=[0.5, 1.5], colors=["#4c72b0"], alpha=0.25)
    ax.add_patch(plt.Circle((0, 0), 1.0, fill=False, lw=1.2, color="k"))
    for k, j in enumerate(joints):
        p = _great_circle(j.normal)
        ax.plot(p[:, 0], p[:, 1], color=COLOURS.get(f"joint {k + 1}", "k"), lw=1.5,
                label=f"joint {k + 1} {j.dip:.0f}/{j.dip_direction:03.0f}")
    for name, plane in (("slope face", inputs["face"]), ("upper face", inputs["upper"])):
        p = _great_circle(plane.normal)
        ax.plot(p[:, 0], p[:, 1], "--", color=COLOURS[name], lw=1.2,
                label=f"{name} {plane.dip:.0f}/{plane.dip_direction:03.0f}")
    phi = joints[0].joint.friction
    r = math.cos(math.radians(phi)) / (1 + math.sin(math.radians(phi)))
    ax.add_patch(plt.Circle((0, 0), r, fill=False, ls=":", lw=1.5, color="#2ca02c"))
    ax.text(0, -r, f"friction cone φ = {phi:.0f}°", ha="center", va="top", fontsize=7, color="#2ca02c")
    if not math.isnan(wedge.intersection[0]):
        p = _project(direction_vector(*wedge.intersection))
        ax.plot(*p, "k^", ms=7, label=f"intersection {wedge.intersection[1]:.1f}/{wedge.intersection[0]:03.0f}")
    if wedge.forms and not math.isnan(wedge.sliding[0]):
        p = _project(direction_vector(*wedge.sliding))
        ax.plot(*p, "r*", ms=12, label=f"sliding {wedge.sliding[1]:.1f}/{wedge.sliding[0]:03.0f}")
    for a, lbl in ((0, "N"), (90, "E"), (180, "S"), (270, "W")):
        ax.text(1.08 * math.sin(math.radians(a)), 1.08 * math.cos(math.radians(a)), lbl, ha="center",
                va="center", fontsize=9)
    ax.set_xlim(-lim, lim)
    ax.set_ylim(-lim, lim)
    ax.set_aspect("equal")
    ax.axis("off")
    ax.legend(loc="lower left", fontsize=7, framealpha=0.8)
    ax.set_title(title or _title(wedge), fontsize=9)
    return _save(fig, path)


def _title(wedge) -> str:
    if not wedge.forms:
        return f"no wedge: {wedge.reason}"[:90]
    return f"wedge JP {wedge.pyramid}: FS {wedge.fs:.3f}, {wedge.mode}, V {wedge.volume:.4g} m³"


def _save(fig, path) -> Path:
    import matplotlib.pyplot as plt

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path)
    plt.close(fig)
    return path


def _scene(wedge):
    """Polygons to draw: the wedge's faces and the slope and upper face around it."""
    block = wedge.block
    polys = [(f.label, f.vertices) for f in block.faces]
    span = float(np.ptp(block.vertices, axis=0).max()) or 1.0
    c = block.vertices.mean(axis=0)
    surround = []
    for label in ("slope face", "upper face"):
        f = block.face(label)
        if f is None:
            continue
        n = f.normal
        u = np.cross(n, [0.0, 0.0, 1.0]) if abs(n[2]) < 0.99 else np.array([1.0, 0.0, 0.0])
        u /= np.linalg.norm(u)
        v = np.cross(n, u)
        o = f.centroid
        corners = [o + 0.8 * span * (a * u + b * v) for a, b in ((-1, -1), (1, -1), (1, 1), (-1, 1))]
        surround.append((label, np.array(corners)))
    return polys, surround, c, span


def _draw(ax, wedge, azimuth: float, elevation: float = 25.0) -> None:
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection

    polys, surround, c, span = _scene(wedge)
    for label, p in surround:
        ax.add_collection3d(Poly3DCollection([p], facecolor=COLOURS[label], alpha=0.08, edgecolor="none"))
    for label, p in polys:
        free = label in ("slope face", "upper face")
        ax.add_collection3d(Poly3DCollection([p], facecolor=COLOURS.get(label, "#aaaaaa"),
                                             alpha=0.55 if free else 0.95, edgecolor="k", linewidths=0.6))
    if wedge.forms and not math.isnan(wedge.sliding[0]):
        d = direction_vector(*wedge.sliding) * 0.5 * span
        ax.quiver(*c, *d, color="r", linewidth=2)
    r = 0.8 * span
    ax.set_xlim(c[0] - r, c[0] + r)
    ax.set_ylim(c[1] - r, c[1] + r)
    ax.set_zlim(c[2] - r, c[2] + r)
    ax.set_box_aspect((1, 1, 1))
    ax.set_xlabel("x east [m]", fontsize=7)
    ax.set_ylabel("y north [m]", fontsize=7)
    ax.set_zlabel("z [m]", fontsize=7)
    ax.tick_params(labelsize=6)
    ax.view_init(elev=elevation, azim=azimuth)


def _view_azimuth(wedge) -> float:
    """matplotlib azimuth that looks at the slope face from outside."""
    dd = wedge.inputs["face"].dip_direction
    return (90.0 - dd) % 360.0


def write_png(wedge, path, *, size=(640, 480), dpi=100, azimuth: Optional[float] = None, renderer: str = "matplotlib",
              title: Optional[str] = None) -> Path:
    """Draw the wedge on its slope to a PNG with matplotlib's 3D axes; ``renderer='pyvista'``
    (or 'auto' where PyVista is installed) renders it with VTK offscreen instead
    (`kgm.wedges.vtk.render_png`, the ``[3d]`` extra)."""
    _need_block(wedge)
    if _use_pyvista(renderer):
        from .vtk import render_png

        return render_png(wedge, path, size=size)
    plt = _matplotlib()
    fig = plt.figure(figsize=(size[0] / dpi, size[1] / dpi), dpi=dpi)
    ax = fig.add_subplot(projection="3d")
    _draw(ax, wedge, _view_azimuth(wedge) if azimuth is None else azimuth)
    ax.set_title(title or _title(wedge), fontsize=9)
    return _save(fig, path)


def write_gif(wedge, path, *, frames: int = 36, size=(640, 480), dpi=100, fps: int = 12, renderer: str = "matplotlib",
              title: Optional[str] = None) -> Path:
    """A GIF of the wedge on its slope turning once about the vertical (``frames`` views)."""
    _need_block(wedge)
    if not (isinstance(frames, int) and frames >= 2):
        raise ValueError(f"frames must be an integer >= 2, got {frames!r}")
    if _use_pyvista(renderer):
        from .vtk import render_gif

        return render_gif(wedge, path, frames=frames, size=size, fps=fps)
    plt = _matplotlib()
    from PIL import Image

    fig = plt.figure(figsize=(size[0] / dpi, size[1] / dpi), dpi=dpi)
    ax = fig.add_subplot(projection="3d")
    images = []
    start = _view_azimuth(wedge)
    _draw(ax, wedge, start)
    ax.set_axis_off()                              # a turning picture: no axes (a third of the cost)
    ax.set_title(title or _title(wedge), fontsize=9)
    for k in range(frames):
        ax.view_init(elev=25.0, azim=start + 360.0 * k / frames)        # the artists stay; the view turns
        fig.canvas.draw()
        rgba = np.asarray(fig.canvas.buffer_rgba())
        images.append(Image.fromarray(rgba[..., :3].copy()).quantize(colors=128, dither=Image.Dither.NONE))
    plt.close(fig)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    images[0].save(path, save_all=True, append_images=images[1:], duration=int(1000 / fps), loop=0)
    return path


def _need_block(wedge) -> None:
    if wedge.block is None:
        raise ValueError(f"no wedge to draw ({wedge.reason})")


def _use_pyvista(renderer: str) -> bool:
    if renderer not in ("auto", "matplotlib", "pyvista"):
        raise ValueError(f"renderer must be 'auto', 'matplotlib' or 'pyvista', got {renderer!r}")
    if renderer == "matplotlib":
        return False
    import importlib.util

    have = importlib.util.find_spec("pyvista") is not None
    if renderer == "pyvista" and not have:
        raise RuntimeError("renderer='pyvista' needs PyVista and VTK: pip install 'ddatai[3d]'")
    return have
