"""The ``Recorder``: frames and step records accumulated during a run, and the `Results` built
from them (also a partial one, when a run stops)."""

from __future__ import annotations

import numpy as np

from .records import BOLT_EVENT_DTYPE, START_DTYPE, STEP_DTYPE, StepRecord
from .results import Results

class Recorder:
    """Accumulates frames during a run and builds `Results` (also a partial one on failure)."""

    def __init__(self, model, record_contacts: bool):
        self.model = model
        self.record_contacts = record_contacts
        self.frames: dict[str, list] = {k: [] for k in (
            "time", "centroid", "rotation", "velocity", "angular_velocity", "stress", "vertices",
            "measured", "fixed_points", "load_points", "load_forces")}
        self.contact_xy: list[np.ndarray] = []
        self.contact_state: list[np.ndarray] = []
        self.contact_normal: list[np.ndarray] = []
        self.contact_shear: list[np.ndarray] = []
        self.metadata = ""  # JSON text (`run_metadata`)
        self.block_material = np.zeros(0, np.int64)  # (B,) index into the metadata's materials
        self.contact_count: list[int] = []
        self.steps: list[tuple] = []  # step records a step at a time (`step`), after the arrays below
        self.step_arrays: list[np.ndarray] = []  # step records handed over as arrays (`step_rows`)
        self.start: list[tuple] = []
        self.bolts: dict[str, list] = {"bolt_xy": [], "bolt_force": [], "bolt_broken": []}
        self.bolt_state = None  # the last frame's (broken step, time, force) of every bolt

    def frame(self, state, centroid: np.ndarray, contact_xy=None, contact_state=None,
              contact_forces=None) -> None:
        origin = self.model.origin
        f = self.frames
        f["time"].append(state.time)
        f["centroid"].append(centroid + origin)
        f["rotation"].append(state.block_rotation.copy())
        f["velocity"].append(state.block_velocity[:, :2].copy())
        f["angular_velocity"].append(state.block_velocity[:, 2].copy())
        f["stress"].append(state.block_stress.copy())
        f["vertices"].append(state.vertex_xy + origin)
        f["measured"].append(state.measured_xy + origin)
        f["fixed_points"].append(state.fixed_point_xy + origin)
        f["load_points"].append(state.load_xy + origin)
        t = state.time
        f["load_forces"].append(np.array([fn(t) if callable(fn) else fn for fn in self.model.load_force],
                                         dtype=float).reshape(-1, 2))
        if len(self.model.bolt_block):
            from .support import bolt_ends, bolt_tension

            self.bolts["bolt_xy"].append(bolt_ends(self.model, state.vertex_xy) + origin)
            # the tension of the frame's geometry (after the equilibrium stage too); 0 once broken
            intact = state.bolt_broken_step < 0
            self.bolts["bolt_force"].append(np.where(intact, bolt_tension(self.model, state.vertex_xy), 0.0))
            self.bolts["bolt_broken"].append(state.bolt_broken_step >= 0)
            self.bolt_state = (state.bolt_broken_step, state.bolt_broken_time, state.bolt_broken_force)
        if self.record_contacts and contact_xy is not None:
            self.contact_xy.append(contact_xy + origin)
            self.contact_state.append(contact_state.astype(np.int8))
            self.contact_count.append(len(contact_xy))
            normal, shear = contact_forces if contact_forces is not None else (np.zeros(len(contact_xy)),) * 2
            self.contact_normal.append(np.asarray(normal, float))
            self.contact_shear.append(np.asarray(shear, float))
        else:
            self.contact_count.append(0)

    def step(self, record: StepRecord) -> None:
        self.steps.append(record.row())

    def step_rows(self, rows: np.ndarray) -> None:
        """Step records already in ``STEP_DTYPE`` (a launch of the fused engine), kept as one
        array: a Python tuple a step cost ~0.01 ms, as much as a small model's whole fused step
        (benchmarks/results/small_models_beside.md)."""
        if self.steps:  # the records before these, in order
            self.step_arrays.append(np.array(self.steps, dtype=STEP_DTYPE))
            self.steps = []
        self.step_arrays.append(np.array(rows, dtype=STEP_DTYPE))

    def step_records(self) -> np.ndarray:
        """Every step record so far, in order (``STEP_DTYPE``)."""
        tail = np.array(self.steps, dtype=STEP_DTYPE)
        return np.concatenate(self.step_arrays + [tail]) if self.step_arrays else tail

    def seed(self, results: "Results", state) -> None:
        """Start from the frames and step records of a partial run (a checkpoint) whose last
        state is ``state``, so that the finished `results` equal those of an unbroken run."""
        for name, frames in self.frames.items():
            frames.extend(getattr(results, name))
        off = results.contact_offset
        for f in range(results.n_frames):
            n = int(off[f + 1] - off[f])
            self.contact_count.append(n)
            if n:
                self.contact_xy.append(results.contact_xy[off[f]:off[f + 1]])
                self.contact_state.append(results.contact_state[off[f]:off[f + 1]])
                self.contact_normal.append(results.contact_normal_force[off[f]:off[f + 1]])
                self.contact_shear.append(results.contact_shear_force[off[f]:off[f + 1]])
        self.metadata = results.metadata
        self.block_material = results.block_material
        # a record written before a field was added gets the field's zero
        have = results.steps.dtype.names or ()
        self.steps.extend(tuple(r[k] if k in have else STEP_DTYPE[k].type(0) for k in STEP_DTYPE.names)
                          for r in results.steps)
        have = results.start.dtype.names or ()
        self.start.extend(tuple(r[k] if k in have else START_DTYPE[k].type(0) for k in START_DTYPE.names)
                          for r in results.start)
        # per-frame records of optional model parts (bolts), kept by name like the Results field
        for name, frames in getattr(self, "bolts", {}).items():
            if len(getattr(results, name, ())) == results.n_frames:
                frames.extend(getattr(results, name))
        if getattr(self, "bolts", None) and len(getattr(state, "bolt_broken_step", ())):
            self.bolt_state = (state.bolt_broken_step, state.bolt_broken_time, state.bolt_broken_force)

    def results(self) -> Results:
        f = self.frames
        m = self.model
        nb, nv, nm = m.n_blocks, m.n_vertices, len(m.measured_block)

        def stack(name, shape):
            return np.array(f[name]) if f[name] else np.zeros((0,) + shape)

        return Results(
            time=np.array(f["time"], dtype=float),
            centroid=stack("centroid", (nb, 2)),
            rotation=stack("rotation", (nb,)),
            velocity=stack("velocity", (nb, 2)),
            angular_velocity=stack("angular_velocity", (nb,)),
            stress=stack("stress", (nb, 3)),
            vertices=stack("vertices", (nv, 2)),
            vertex_offset=m.vertex_offset.astype(np.int64),
            block_fixed=m.block_fixed.copy(),
            measured=stack("measured", (nm, 2)),
            fixed_points=stack("fixed_points", (len(m.fixed_point_block), 2)),
            load_points=stack("load_points", (len(m.load_block), 2)),
            load_forces=stack("load_forces", (len(m.load_block), 2)),
            contact_offset=np.concatenate([[0], np.cumsum(self.contact_count)]).astype(np.int64),
            contact_xy=np.concatenate(self.contact_xy) if self.contact_xy else np.zeros((0, 2)),
            contact_state=np.concatenate(self.contact_state) if self.contact_state else np.zeros(0, np.int8),
            contact_normal_force=np.concatenate(self.contact_normal) if self.contact_normal else np.zeros(0),
            contact_shear_force=np.concatenate(self.contact_shear) if self.contact_shear else np.zeros(0),
            metadata=self.metadata,
            block_material=np.asarray(self.block_material, np.int64),
            steps=self.step_records(),
            start=np.array(self.start, dtype=START_DTYPE),
            **self._support(),
        )

    def _support(self) -> dict:
        """Bolt frames and events, and the water table, of a model that has them."""
        m = self.model
        out = {}
        if m.water_xy is not None:
            out["water_table"] = m.water_xy + m.origin
        if len(m.bolt_block) and self.bolts["bolt_xy"]:
            out.update({k: np.array(v) for k, v in self.bolts.items()})
            step, time, force = self.bolt_state
            broke = np.flatnonzero(step >= 0)
            broke = broke[np.argsort(step[broke], kind="stable")]
            out["bolt_events"] = np.array([(int(k), int(step[k]), float(time[k]), float(force[k])) for k in broke],
                                          dtype=BOLT_EVENT_DTYPE)
        return out
