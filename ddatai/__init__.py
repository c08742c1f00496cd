"""ddatai: 2D Discontinuous Deformation Analysis (Shi's DDA) with Taichi kernels.

Data flows one way::

    Scene (blocks, joints, points, loads, shaking)      ddatai.scene
      -> Model (static arrays) + State                  ddatai.model
      -> equilibrium at t = 0                           ddatai.start
           (return mapping; at a stall, limit equilibrium)  ddatai.return_mapping, ddatai.limit_equilibrium
           (many members: the programs side by side)   ddatai.limit_batch
           (many members: one detection at t = 0)      ddatai.batch_detect
           (no frictional equilibrium: the welded one)  ddatai.welded
      -> step, phase by phase                           ddatai.step
           Δt                                           ddatai.time_step
           contacts (detection, memory)                 ddatai.contacts, ddatai.layout
           block and contact terms                      ddatai.assembly
           open-close iteration                         ddatai.open_close
           contact law and judgement                    ddatai.contact_law
           update of points, stresses, velocities       ddatai.kinematics
           energy and work                              ddatai.energy
      -> Results (frames, per-step records, .npz)       ddatai.results
    simulate: the run from a scene to its results       ddatai.run
    readers and writers (scene scripts, DXF, ntdda, VTK, checkpoints)   ddatai.io

Importing ``ddatai`` is cheap: it loads neither Taichi nor any imaging library. Taichi is
initialised (CPU by default, ``Params(arch=...)``) by the first simulation.

>>> import ddatai as dd
>>> scene = dd.Scene(gravity=9.81)
>>> rock = dd.Material(density=2500.0, young=5e9, poisson=0.25)
>>> base = scene.add_block([(0, 0), (4, 0), (4, 1), (0, 1)], material=rock, fixed=True)
>>> top = scene.add_block([(1, 1), (2, 1), (2, 2), (1, 2)], material=rock)
>>> res = dd.simulate(scene, duration=0.1)   # doctest: +SKIP
"""

from __future__ import annotations

import importlib

__version__ = "0.1.0"

# public name -> module that defines it (PEP 562 lazy attributes)
_EXPORTS = {
    "Material": "params", "Joint": "params", "BartonBandis": "params", "Params": "params", "STRICT_CONVERGENCE": "params", "UnitWarning": "params",
    "Scene": "scene", "SliverWarning": "cutting",
    "Model": "model", "State": "model", "ContactState": "layout", "ContactKind": "layout",
    "build_model": "model",
    "Results": "results", "load_results": "results", "SimulationError": "results",
    "SimulationInterrupted": "results",
    "STEP_DTYPE": "records", "StepRecord": "records",
    "simulate": "run", "Stepper": "step", "PenaltyWarning": "step", "sweep": "sweep",
    "polygon_integrals": "geometry", "validate_polygon": "geometry",
    "write_gif": "render", "write_png": "render", "render_frames": "render", "write_video": "render",
    "joint_sets": "jointsets", "JointSet": "jointsets", "fit_mapping": "jointsets", "MappingFit": "jointsets",
    "read_dxf": "io.dxf", "read_dxf_section": "io.dxf", "DxfSection": "io.dxf",
    "read_ntdda": "io.ntdda", "NtddaCase": "io.ntdda", "NtddaFormatError": "io.ntdda",
    "NtddaWarning": "io.ntdda", "NtddaQuirkWarning": "io.ntdda", "NtddaUnsupportedWarning": "io.ntdda",
}

__all__ = sorted(_EXPORTS)


def __getattr__(name: str):
    module = _EXPORTS.get(name)
    if module is None:
        raise AttributeError(f"module 'ddatai' has no attribute {name!r}")
    value = getattr(importlib.import_module(f".{module}", __name__), name)
    globals()[name] = value
    return value


def __dir__():
    return sorted(set(globals()) | set(__all__))
