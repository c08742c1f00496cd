"""kgm: the Key Group Method for jointed rock slopes, on the blocks of a `ddatai.Scene`.

Finds the groups of blocks that can fail together (Yarahmadi Bafghi & Verdel's Key Group
Method) and judges them with three evaluators (docs/kgm/method.md):

* ``"rigid"`` – the group glued into one rigid body, limit equilibrium (KGM);
* ``"sarma"`` – blocks slide on their own bases and shear their shared joints (SKGM);
* ``"dda"`` – the group simulated with ddatai on its real joint geometry (the method of
  Shahami, Yarahmadi Bafghi & Fatehi Marji), FS by strength reduction.

``"rigid"`` and ``"sarma"`` also check block toppling of a row of blocks (Goodman & Bray 1976,
`kgm.toppling`) and take the least safe admissible mechanism. The scene's water table and rock
bolts (active pretension, passive capacity) enter every evaluator, and ``seismic=(kh, kv)`` adds
a pseudo-static load to the limit-equilibrium ones (docs/method/water_bolts.md).

>>> import kgm
>>> rep = kgm.analyze(scene, method="sarma")                      # doctest: +SKIP
>>> rep.critical.blocks, rep.critical.fs, rep.critical.critical_friction   # doctest: +SKIP
>>> kgm.factor_of_safety(scene, {0, 1}, method="rigid")           # doctest: +SKIP

Importing kgm loads NumPy and the light parts of ddatai only; Taichi starts when the DDA
evaluator runs its first simulation.
"""

from __future__ import annotations

import importlib

# public name -> module that defines it (PEP 562 lazy attributes)
_EXPORTS = {
    "analyze": "search", "evaluate": "search", "factor_of_safety": "search",
    "critical_friction": "search", "exhaustive": "search", "key_blocks": "search",
    "Settings": "settings", "DdaSettings": "settings",
    "Report": "report", "GroupResult": "report", "format_paper_table": "report",
    "format_groups": "report", "format_toppling": "report",
    "BlockSystem": "blocks", "build_block_system": "blocks", "classify_blocks": "blocks",
    "removable_arc": "blocks", "is_removable": "blocks", "rigid_modes": "blocks",
    "Mode": "blocks", "ModeKind": "blocks",
    "evaluate_rigid": "evaluators", "evaluate_sarma": "evaluators", "sarma_modes": "evaluators",
    "sarma_checks": "evaluators",
    "DdaJudgement": "dda", "DdaEvaluation": "dda", "DdaTiming": "dda", "judge": "dda",
    "sub_scene": "dda",
    "toppling_mode": "toppling", "toppling_row": "toppling", "toppling_check": "toppling", "BlockState": "toppling",
    "BlockStep": "toppling",
    "probabilistic": "studies.probabilistic", "Study": "studies.study", "read_study": "studies.study",
    "sample_variables": "studies.sampling",
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
