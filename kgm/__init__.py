"""kgm: the Key Group Method for jointed rock slopes, on the blocks of a `ddatai.Scene`.

Finds the groups of blocks that can fail together (Yarahmadi Bafghi & Verdel's Key Group
Method) and judges them with three evaluators (docs/kgm/method.md):

* ``"rigid"`` – the group glued into one rigid body, limit equilibrium (KGM);
* ``"sarma"`` – blocks slide on their own bases and shear their shared joints (SKGM);
* ``"dda"`` – the group simulated with ddatai on its real joint geometry (the method of
  Shahami, Yarahmadi Bafghi & Fatehi Marji), FS by strength reduction.

``"rigid"`` and ``"sarma"`` also check block toppling of a row of blocks (Goodman & Bray 1976,
`kgm.judges.toppling`) and take the least safe admissible mechanism. The scene's water table
and rock bolts (active pretension, passive capacity) enter every evaluator, and
``seismic=(kh, kv)`` adds a pseudo-static load to the limit-equilibrium ones
(docs/method/water_bolts.md).

The package is a one-way pipeline (docs/kgm/architecture.md): the scene's `kgm.build.Problem`
(made once per analysis) → candidates (`kgm.candidates`) → judges (`kgm.judges`) → search
(`kgm.search`) → report (`kgm.report`) → analyses (`kgm.analysis`) → studies (`kgm.studies`)
→ the ``kgm`` command (`kgm.cli`); the method names and other words are `kgm.kinds`.

>>> import kgm
>>> rep = kgm.analyze(scene, method="sarma")                      # doctest: +SKIP
>>> rep.critical.blocks, rep.critical.fs, rep.critical.critical_friction   # doctest: +SKIP
>>> kgm.factor_of_safety(scene, {0, 1}, method="rigid")           # doctest: +SKIP

In 3D, ``kgm.wedge`` judges the wedge that joints cut from a rock slope (block theory, vector
limit equilibrium with water, bolts and earthquakes, support, probabilistic studies, pictures;
`kgm.wedges`, docs/kgm/wedge.md).

Importing kgm loads NumPy and the light parts of ddatai only; Taichi starts when the DDA
evaluator runs its first simulation.
"""

from __future__ import annotations

import importlib

# public name -> module that defines it (PEP 562 lazy attributes)
_EXPORTS = {
    "analyze": "analysis", "evaluate": "analysis", "factor_of_safety": "analysis",
    "critical_friction": "analysis", "exhaustive": "analysis", "key_blocks": "candidates",
    "Settings": "settings", "DdaSettings": "settings",
    "Report": "report", "GroupResult": "report", "format_paper_table": "report",
    "format_groups": "report", "format_toppling": "report",
    "BlockSystem": "system", "build_block_system": "build", "classify_blocks": "judges.rigid",
    "removable_arc": "faces", "is_removable": "faces", "rigid_modes": "judges.rigid",
    "Mode": "judges.evaluation", "ModeKind": "kinds",
    "evaluate_rigid": "judges.rigid", "evaluate_sarma": "judges.sarma", "sarma_modes": "judges.sarma",
    "sarma_checks": "judges.sarma",
    "DdaJudgement": "judges.run", "DdaEvaluation": "judges.dda", "DdaTiming": "judges.dda",
    "judge": "judges.run", "sub_scene": "judges.run",
    "toppling_mode": "judges.toppling", "toppling_row": "candidates", "toppling_check": "judges.toppling",
    "BlockState": "kinds", "BlockStep": "judges.toppling",
    "probabilistic": "studies.probabilistic", "Study": "studies.study", "read_study": "studies.study",
    "sample_variables": "studies.sampling",
    "SubsetSampling": "studies.rare", "ImportanceSampling": "studies.rare",
    # 3D: wedges and key blocks of a rock slope (docs/kgm/wedge.md)
    "Plane": "wedges.geometry", "wedge": "wedges.slope", "Wedge": "wedges.block",
    "TensionCrack": "wedges.slope", "Support": "wedges.block", "polyhedral_block": "wedges.block",
    "Halfspace": "wedges.geometry", "Water": "wedges.mechanics",
    "Seismic": "wedges.mechanics", "Bolt": "wedges.mechanics", "Force": "wedges.mechanics",
    "joint_pyramids": "wedges.block_theory", "JointPyramid": "wedges.block_theory",
    "face_key_blocks": "wedges.block", "KeyBlock": "wedges.block",
    "wedge_study": "wedges.study", "WedgeStudy": "wedges.study", "Fisher": "wedges.study",
}

__all__ = sorted(_EXPORTS)


def __getattr__(name: str):
    module = _EXPORTS.get(name)
    if module is None:
        raise AttributeError(f"module 'kgm' has no attribute {name!r}")
    value = getattr(importlib.import_module(f".{module}", __name__), name)
    globals()[name] = value
    return value


def __dir__():
    return sorted(set(globals()) | set(__all__))
