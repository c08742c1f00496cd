"""Results of a run: recorded frames, one record per step, ``.npz`` save/load.

Plain NumPy, no Taichi: the renderer, `kgm` and users read results without starting the
solver. Frame 0 is the initial state.
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Optional

import numpy as np

# the record layouts, public here too (ddatai.results.STEP_DTYPE)
from .records import BOLT_EVENT_DTYPE, START_DTYPE, STEP_DTYPE, STEP_PHASES, step_wall_time  # noqa: F401

class SimulationError(RuntimeError):
    """A run stopped because it diverged or could not converge.

    Attributes
    ----------
    step : int
        The step (1-based) that failed.
    time : float
        Simulated time at the start of that step [s].
    cause : str
        "nan", "penetration", "open-close" or "displacement".
    results : Results or None
        Everything recorded up to the last accepted step.
    """

    def __init__(self, message: str, *, step: int, time: float, cause: str,
                 results: Optional["Results"] = None):
        super().__init__(message)
        self.step = step
        self.time = time
        self.cause = cause
        self.results = results


class SimulationInterrupted(KeyboardInterrupt):
    """A run stopped by Ctrl-C (`KeyboardInterrupt`): what was recorded is kept.

    A subclass of `KeyboardInterrupt`, so a script that does not catch it still stops as
    Ctrl-C stops it. The interrupt is taken between two steps or inside one (that step is
    dropped); the results hold every frame recorded before it.

    Attributes
    ----------
    step : int
        Steps accepted before the interrupt.
    time : float
        Simulated time reached [s].
    results : Results
        Everything recorded up to then.
    checkpoint : Path or None
        The checkpoint written at the interrupt (``simulate(..., checkpoint=PATH)``), from
        which ``simulate(..., resume=PATH)`` continues.
    """

    def __init__(self, *, step: int, time: float, results: "Results", checkpoint=None):
        super().__init__(f"simulation interrupted after step {step} (t = {time:.6g} s)")
        self.step = step
        self.time = time
        self.results = results
        self.checkpoint = checkpoint


@dataclass(kw_only=True, eq=False)
class Results:
    """Recorded frames of a run (F frames, B blocks, V vertices) and per-step records."""

    time: np.ndarray
    """(F,) simulated time of each frame [s]."""
    centroid: np.ndarray
    """(F, B, 2) block centroids [m]."""
    rotation: np.ndarray
    """(F, B) accumulated rigid rotation [rad], counter-clockwise positive."""
    velocity: np.ndarray
    """(F, B, 2) centroid velocities [m/s] (relative to the ground under seismic input)."""
    angular_velocity: np.ndarray
    """(F, B) angular velocities [rad/s]."""
    stress: np.ndarray
    """(F, B, 3) block stresses (σx, σy, τxy) [Pa], compression negative."""
    vertices: np.ndarray
    """(F, V, 2) vertex positions [m]."""
    vertex_offset: np.ndarray
    """(B+1,) block b owns vertices ``vertex_offset[b]:vertex_offset[b+1]``."""
    block_fixed: np.ndarray
    """(B,) fixed blocks."""
    measured: np.ndarray
    """(F, nm, 2) positions of the scene's measured points [m]."""
    contact_offset: np.ndarray
    """(F+1,) frame f owns contacts ``contact_offset[f]:contact_offset[f+1]`` (empty unless
    contacts were recorded)."""
    contact_xy: np.ndarray
    """(C, 2) contact points (the contacting vertex) [m]."""
    contact_state: np.ndarray
    """(C,) int8 `ContactState` (0 open, 1 sliding, 2 locked)."""
    steps: np.ndarray
    """(S,) structured array, one record per accepted step (`STEP_DTYPE`)."""
    start: np.ndarray = field(default_factory=lambda: np.zeros(0, START_DTYPE))
    """(1,) structured record of the equilibrium stage before t = 0 (`START_DTYPE`), (0,) when
    the run had none (``Params(initial_equilibrium=False)``)."""
    bolt_xy: np.ndarray = field(default_factory=lambda: np.zeros((0, 0, 2, 2)))
    """(F, nb, 2, 2) both ends of every rock bolt [m]; empty without bolts."""
    bolt_force: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))
    """(F, nb) bolt tensions [N/m], tension positive, 0 once broken."""
    bolt_broken: np.ndarray = field(default_factory=lambda: np.zeros((0, 0), bool))
    """(F, nb) whether each bolt has broken by the frame."""
    bolt_events: np.ndarray = field(default_factory=lambda: np.zeros(0, BOLT_EVENT_DTYPE))
    """(k,) bolts that broke, in the order they broke (`BOLT_EVENT_DTYPE`)."""
    water_table: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    """(k, 2) the scene's water table h(x) [m]; empty without water."""
    contact_normal_force: np.ndarray = field(default_factory=lambda: np.zeros(0))
    """(C,) normal force of each recorded contact at the end of its step [N/m], compression
    positive, 0 when open (recorded with the contacts)."""
    contact_shear_force: np.ndarray = field(default_factory=lambda: np.zeros(0))
    """(C,) shear force of each recorded contact [N/m], signed along the contact's reference
    edge; at most its Coulomb strength N·tanφ + c·L; 0 when open and for vertex-vertex contacts."""
    fixed_points: np.ndarray = field(default_factory=lambda: np.zeros((0, 0, 2)))
    """(F, nf, 2) positions of the scene's fixed points [m] (held by stiff springs)."""
    load_points: np.ndarray = field(default_factory=lambda: np.zeros((0, 0, 2)))
    """(F, nl, 2) positions of the scene's point loads [m] (they move with their blocks)."""
    load_forces: np.ndarray = field(default_factory=lambda: np.zeros((0, 0, 2)))
    """(F, nl, 2) the point loads' forces at each frame's time [N/m]."""
    block_material: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    """(B,) index of each block's material in ``meta["scene"]["materials"]`` (empty for results
    written before it existed)."""
    metadata: str = ""
    """JSON text: the ddatai version, the parameters, the units of every field and a summary of
    the scene (`meta` reads it); empty for results written before it existed."""

    def __repr__(self) -> str:
        s = self.summary()
        t = f"t = {self.time[0]:.4g}–{self.time[-1]:.4g} s" if self.n_frames else "no frames"
        contacts = f", {len(self.contact_xy)} contacts recorded" if len(self.contact_xy) else ""
        return (f"<Results: {s['blocks']} blocks ({int(np.count_nonzero(self.block_fixed))} fixed), "
                f"{self.n_frames} frames ({t}), {s['steps']} steps{contacts}>")

    @property
    def meta(self) -> dict:
        """The run's metadata (`metadata` as a dict): ``ddatai_version``, ``params``,
        ``units`` (of every field), ``scene`` (blocks, vertices, materials, joints, ...)."""
        import json

        return json.loads(self.metadata) if self.metadata else {}

    @property
    def n_frames(self) -> int:
        return len(self.time)

    @property
    def n_blocks(self) -> int:
        return len(self.vertex_offset) - 1

    def polygons(self, frame: int = -1) -> list[np.ndarray]:
        """Deformed block polygons of a frame: list of (n, 2) CCW vertex arrays [m]."""
        xy = self.vertices[frame]
        o = self.vertex_offset
        return [xy[o[b]:o[b + 1]] for b in range(len(o) - 1)]

    def displacement(self, frame: int = -1) -> np.ndarray:
        """(B, 2) centroid displacement of a frame from frame 0 [m]."""
        return self.centroid[frame] - self.centroid[0]

    def contacts(self, frame: int = -1) -> tuple[np.ndarray, np.ndarray]:
        """Contact points (n, 2) and states (n,) recorded at a frame."""
        f = range(self.n_frames)[frame]
        a, b = self.contact_offset[f], self.contact_offset[f + 1]
        return self.contact_xy[a:b], self.contact_state[a:b]

    def contact_forces(self, frame: int = -1) -> tuple[np.ndarray, np.ndarray]:
        """Normal (compression positive) and shear forces (n,) of the contacts recorded at a
        frame [N/m], in the order of `contacts`."""
        f = range(self.n_frames)[frame]
        a, b = self.contact_offset[f], self.contact_offset[f + 1]
        if len(self.contact_normal_force) < b:
            raise ValueError("these results have no contact forces (recorded since contacts carry them)")
        return self.contact_normal_force[a:b], self.contact_shear_force[a:b]

    def contacts_csv(self, path) -> Path:
        """Write every recorded contact as CSV, one row per contact and frame: ``frame, time_s,
        x_m, y_m, state`` (0 open, 1 sliding, 2 locked), ``normal_N_per_m, shear_N_per_m``."""
        counts = np.diff(self.contact_offset)
        if counts.sum() == 0:
            raise ValueError("the results have no contacts (record them with record_contacts=True / --contacts)")
        frame = np.repeat(np.arange(self.n_frames), counts)
        forces = len(self.contact_normal_force) == len(self.contact_xy)
        normal = self.contact_normal_force if forces else np.full(len(frame), np.nan)
        shear = self.contact_shear_force if forces else np.full(len(frame), np.nan)
        table = np.column_stack([frame, self.time[frame], self.contact_xy, self.contact_state, normal, shear])
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        np.savetxt(path, table, delimiter=",", header="frame,time_s,x_m,y_m,state,normal_N_per_m,shear_N_per_m",
                   comments="", fmt=["%d", "%.10g", "%.10g", "%.10g", "%d", "%.10g", "%.10g"])
        return path

    def measured_displacement(self) -> np.ndarray:
        """(F, nm, 2) displacement of each measured point from frame 0 [m]."""
        return self.measured - self.measured[:1]

    def measured_csv(self, path) -> Path:
        """Write the measured points' positions and displacements as CSV: one row per frame,
        columns ``time_s`` then ``x{k}_m, y{k}_m, ux{k}_m, uy{k}_m`` for each point k."""
        nm = self.measured.shape[1]
        if nm == 0:
            raise ValueError("the results have no measured points")
        u = self.measured_displacement()
        cols = [self.time[:, None]]
        names = ["time_s"]
        for k in range(nm):
            cols.append(np.column_stack([self.measured[:, k], u[:, k]]))
            names += [f"x{k}_m", f"y{k}_m", f"ux{k}_m", f"uy{k}_m"]
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        np.savetxt(path, np.column_stack(cols), delimiter=",", header=",".join(names), comments="", fmt="%.10g")
        return path

    def block_at(self, point, frame: int = 0) -> int:
        """The block whose polygon contains ``point`` (x, y) [m] at a frame (default the
        first), or -1 if none does; a point on an edge shared by two blocks goes to the lower id."""
        x, y = float(point[0]), float(point[1])
        xy = self.vertices[frame]
        off = self.vertex_offset
        nxt = np.arange(len(xy)) + 1
        nxt[off[1:] - 1] = off[:-1]  # each block's last vertex closes on its first
        x0, y0, x1, y1 = xy[:, 0], xy[:, 1], xy[nxt, 0], xy[nxt, 1]
        block = np.repeat(np.arange(self.n_blocks), np.diff(off))
        # on an edge (within 1e-12 of the model size): inside
        scale = 1e-12 * max(float(np.ptp(xy)), 1.0)
        ex, ey = x1 - x0, y1 - y0
        cross = ex * (y - y0) - ey * (x - x0)
        along = (x - x0) * ex + (y - y0) * ey
        on_edge = (np.abs(cross) <= scale * np.hypot(ex, ey)) & (along >= 0) & (along <= ex * ex + ey * ey)
        if on_edge.any():
            return int(block[np.flatnonzero(on_edge)[0]])
        # even-odd rule: crossings of a ray towards +x
        spans = (y0 > y) != (y1 > y)
        with np.errstate(divide="ignore", invalid="ignore"):
            xc = x0 + (y - y0) * ex / np.where(ey == 0, 1.0, ey)
        hits = spans & (xc > x)
        inside = np.bincount(block[hits], minlength=self.n_blocks) % 2 == 1
        found = np.flatnonzero(inside)
        return int(found[0]) if len(found) else -1

    def history(self, point=None, *, block: Optional[int] = None, measured: Optional[int] = None) -> "History":
        """Time history of a material point, a block or a measured point.

        ``point`` (x, y) [m] is a point of the model at frame 0: the history follows the
        material point there (its block's exact affine motion, rigid rotation and strain).
        ``block`` follows a block's centroid; ``measured`` the scene's measured point of that
        index. The velocity of a point is its block's rigid-body velocity at it (the strain
        rate is not recorded). See `History`."""
        given = sum(v is not None for v in (point, block, measured))
        if given != 1:
            raise ValueError("history: give one of point=(x, y), block=id or measured=index")
        if self.n_frames == 0:
            raise ValueError("history: the results have no frames")
        if measured is not None:
            nm = self.measured.shape[1]
            if not (0 <= measured < nm):
                raise ValueError(f"history: measured must be in [0, {nm}), got {measured}")
            point = self.measured[0, measured]
            what = f"measured point {measured}"
        if block is not None:
            if not (0 <= block < self.n_blocks):
                raise ValueError(f"history: block must be in [0, {self.n_blocks}), got {block}")
            pos = self.centroid[:, block]
            what = f"block {block} (centroid)"
            vel = self.velocity[:, block]
        else:
            p = np.asarray(point, dtype=float).reshape(2)
            block = self.block_at(p, 0)
            if block < 0:
                raise ValueError(f"history: no block contains the point ({p[0]:g}, {p[1]:g}) at frame 0")
            if measured is None:
                what = f"point ({p[0]:g}, {p[1]:g}) of block {block}"
            pos = self._follow(p, block)
            r = pos - self.centroid[:, block]
            w = self.angular_velocity[:, block]
            vel = self.velocity[:, block] + np.stack([-w * r[:, 1], w * r[:, 0]], axis=1)
        return History(what=what, block=int(block), time=self.time.copy(), position=pos.copy(),
                       displacement=pos - pos[0], velocity=np.array(vel), rotation=self.rotation[:, block].copy(),
                       stress=self.stress[:, block].copy())

    def _follow(self, p: np.ndarray, block: int) -> np.ndarray:
        """(F, 2) positions of the material point at ``p`` (frame 0) of ``block``: every DDA
        step moves a block by an affine map (translation, finite rotation, constant strain), so
        frame 0's vertices map exactly onto each frame's; a least-squares fit recovers the map."""
        o0, o1 = self.vertex_offset[block], self.vertex_offset[block + 1]
        x0 = self.vertices[0, o0:o1]
        c = x0.mean(axis=0)
        basis = np.column_stack([x0 - c, np.ones(len(x0))])       # (n, 3)
        maps = np.einsum("kn,fnd->fkd", np.linalg.pinv(basis), self.vertices[:, o0:o1])  # (F, 3, 2)
        return np.einsum("k,fkd->fd", np.append(p - c, 1.0), maps)

    def to_vtk(self, directory, *, frames=None) -> Path:
        """Write frames (default all) as VTK files for ParaView: blocks with their fields,
        contacts with their forces, ``.pvd`` time series (`ddatai.io.vtk`; needs the optional
        ``ddatai[vtk]`` extra, meshio). Returns the path of ``blocks.pvd``."""
        from .io.vtk import write_vtk

        return write_vtk(self, directory, frames=frames)

    def save(self, path) -> None:
        """Write all arrays (and the metadata) to an ``.npz`` file."""
        np.savez_compressed(Path(path), **{f.name: np.asarray(getattr(self, f.name)) for f in fields(self)})

    def summary(self) -> dict:
        """A few totals of the run (steps, time-step cuts, open-close iterations, wall time)."""
        s = self.steps
        wall = float(step_wall_time(s).sum())
        return {
            "blocks": self.n_blocks,
            "steps": int(len(s)),
            "simulated_time": float(self.time[-1]) if len(self.time) else 0.0,
            "dt_cuts": int(s["dt_cuts"].sum()) if len(s) else 0,
            "oc_iterations": int(s["oc_total"].sum()) if len(s) else 0,
            "wall_time": wall,
        }


def load_results(path) -> Results:
    """Read results written by `Results.save`."""
    with np.load(Path(path), allow_pickle=False) as data:
        # files written before the equilibrium stage existed have no ``start``
        kwargs = {f.name: data[f.name] for f in fields(Results) if f.name in data.files}
    if "metadata" in kwargs:
        kwargs["metadata"] = str(kwargs["metadata"])
    return Results(**kwargs)


#: unit of every `Results` field (as stored in a results file's metadata)
UNITS = {
    "time": "s", "centroid": "m", "rotation": "rad", "velocity": "m/s", "angular_velocity": "rad/s",
    "stress": "Pa (sigma_x, sigma_y, tau_xy; compression negative)", "vertices": "m",
    "vertex_offset": "-", "block_fixed": "-", "measured": "m", "contact_offset": "-", "contact_xy": "m",
    "contact_state": "0 open, 1 sliding, 2 locked", "contact_normal_force": "N/m (compression positive)",
    "contact_shear_force": "N/m", "steps": "see STEP_DTYPE (s, m, J/m, N/m)", "start": "see START_DTYPE",
    "bolt_xy": "m", "bolt_force": "N/m (tension positive)", "bolt_broken": "-", "bolt_events": "see BOLT_EVENT_DTYPE",
    "water_table": "m", "block_material": "index into scene.materials", "fixed_points": "m",
    "load_points": "m", "load_forces": "N/m",
    "forces": "per metre of thickness (plane problem)",
}


def block_materials(scene) -> tuple[list[dict], np.ndarray]:
    """The scene's distinct materials (as dicts) and each block's index among them."""
    import dataclasses

    materials: list[dict] = []
    index = []
    for b in scene.blocks:
        m = dataclasses.asdict(b.material)
        if m not in materials:
            materials.append(m)
        index.append(materials.index(m))
    return materials, np.array(index, np.int64)


def run_metadata(scene, model, engine: str = "", why: str = "") -> str:
    """The metadata of a run as JSON text: ddatai version, parameters, units, scene summary, and
    the engine that ran it with the reason (``meta["engine"]``: "fused", "numpy" or "taichi";
    ``ddatai.fused.policy.choose``)."""
    import dataclasses
    import json

    from . import __version__

    blocks = scene.blocks
    materials, _ = block_materials(scene)
    xy = np.concatenate([b.vertices for b in blocks]) if blocks else np.zeros((0, 2))
    summary = {
        "blocks": len(blocks), "fixed_blocks": int(sum(b.fixed for b in blocks)), "vertices": int(len(xy)),
        "bounding_box_m": [float(v) for v in (*xy.min(axis=0), *xy.max(axis=0))] if len(xy) else [],
        "gravity_m_per_s2": scene.gravity,
        "materials": materials,
        "joints": [dataclasses.asdict(j) for j in scene.joints],
        "fixed_points": len(scene.fixed_points), "point_loads": len(scene.point_loads),
        "measured_points": len(scene.measured_points),
        "ground_acceleration": scene.ground_acceleration is not None,
        "water_table": getattr(scene, "water", None) is not None, "bolts": len(getattr(scene, "bolts", ())),
        "penalty_Pa": float(model.penalty), "model_scale_w0_m": float(model.max_step / model.params.max_displacement_ratio),
    }
    meta = {"ddatai_version": __version__, "params": dataclasses.asdict(model.params),
            "units": UNITS, "scene": summary}
    if engine:
        meta["engine"] = {"name": engine, "why": why}
    return json.dumps(meta, sort_keys=True, default=float)


@dataclass(frozen=True, kw_only=True, eq=False)
class History:
    """Time history of one point or block (`Results.history`), one row per recorded frame."""

    what: str
    """What is followed, in words."""
    block: int
    """The block it belongs to."""
    time: np.ndarray
    """(F,) simulated time [s]."""
    position: np.ndarray
    """(F, 2) position [m]."""
    displacement: np.ndarray
    """(F, 2) displacement from the first frame [m]."""
    velocity: np.ndarray
    """(F, 2) velocity [m/s] (for a point: its block's rigid-body velocity there)."""
    rotation: np.ndarray
    """(F,) the block's accumulated rotation [rad], counter-clockwise positive."""
    stress: np.ndarray
    """(F, 3) the block's stress (σx, σy, τxy) [Pa], compression negative."""

    COLUMNS = ("time_s", "x_m", "y_m", "ux_m", "uy_m", "vx_m_per_s", "vy_m_per_s", "rotation_rad",
               "sigma_x_Pa", "sigma_y_Pa", "tau_xy_Pa")

    def table(self) -> np.ndarray:
        """(F, 11) the columns of ``History.COLUMNS``."""
        return np.column_stack([self.time, self.position, self.displacement, self.velocity, self.rotation,
                                self.stress])

    def plot(self, path=None):
        """Displacement and velocity against time, two panels (matplotlib, the optional
        ``ddatai[plot]`` extra); saved to ``path`` when given (any format matplotlib writes).
        Returns the matplotlib Figure."""
        try:
            import matplotlib

            if path is not None:
                matplotlib.use("Agg")  # offscreen: no window for a file
            import matplotlib.pyplot as plt
        except ImportError:
            raise ImportError("plots need matplotlib, an optional extra: pip install 'ddatai[plot]'") from None
        fig, (top, bottom) = plt.subplots(2, 1, sharex=True, figsize=(7, 5), constrained_layout=True)
        for ax, values, what, unit in ((top, self.displacement, "displacement", "m"),
                                       (bottom, self.velocity, "velocity", "m/s")):
            ax.plot(self.time, values[:, 0], label="x")
            ax.plot(self.time, values[:, 1], label="y")
            ax.plot(self.time, np.hypot(values[:, 0], values[:, 1]), "k--", lw=1, label="magnitude")
            ax.set_ylabel(f"{what} [{unit}]")
            ax.grid(True, alpha=0.3)
        top.legend(loc="best")
        top.set_title(self.what)
        bottom.set_xlabel("time [s]")
        if path is not None:
            path = Path(path)
            path.parent.mkdir(parents=True, exist_ok=True)
            fig.savefig(path, dpi=100)
            plt.close(fig)
        return fig

    def to_csv(self, path) -> Path:
        """Write the history as CSV (header line, one row per frame, SI units in the names)."""
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        np.savetxt(path, self.table(), delimiter=",", header=",".join(self.COLUMNS), comments="",
                   fmt="%.10g")
        return path
