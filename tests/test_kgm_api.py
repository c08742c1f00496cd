"""kgm's public names are a contract: `kgm.__all__` and the signature of every exported
function and class stay as they are (a result or settings class may gain fields, with
defaults, after its own; an enum keeps its members)."""

from __future__ import annotations

import inspect

import kgm

P, K = "positional", "keyword"  # POSITIONAL_OR_KEYWORD, KEYWORD_ONLY
_NO = object()  # no default

#: name -> [(parameter, kind, default)] (default: a Python expression, or _NO)
SIGNATURES = {
    "analyze": [("scene", P, _NO), ("method", P, "'sarma'"), ("progressive", P, "False"),
                ("settings", K, "None"), ("params", K, "None"), ("seismic", K, "None")],
    "evaluate": [("scene", P, _NO), ("blocks", P, _NO), ("method", P, "'sarma'"), ("settings", K, "None"),
                 ("params", K, "None"), ("seismic", K, "None")],
    "factor_of_safety": [("scene", P, _NO), ("blocks", P, _NO), ("method", P, "'sarma'"), ("settings", K, "None"),
                         ("params", K, "None"), ("seismic", K, "None")],
    "critical_friction": [("scene", P, _NO), ("blocks", P, _NO), ("method", P, "'sarma'"), ("settings", K, "None"),
                          ("params", K, "None"), ("seismic", K, "None")],
    "exhaustive": [("scene", P, _NO), ("method", P, "'sarma'"), ("max_size", K, "4"), ("settings", K, "None"),
                   ("removed", K, "frozenset()"), ("seismic", K, "None")],
    "key_blocks": [("system", P, _NO), ("removed", P, "frozenset()")],
    "build_block_system": [("scene", P, _NO), ("seismic", K, "None"), ("contact_gap", K, "None")],
    "classify_blocks": [("system", P, _NO), ("removed", P, "frozenset()")],
    "removable_arc": [("normals", P, _NO), ("tol", P, "1e-06")],
    "is_removable": [("system", P, _NO), ("blocks", P, _NO), ("removed", P, "frozenset()")],
    "rigid_modes": [("system", P, _NO), ("blocks", P, _NO), ("removed", P, "frozenset()"), ("rejected", P, "None")],
    "evaluate_rigid": [("system", P, _NO), ("blocks", P, _NO), ("removed", P, "frozenset()")],
    "evaluate_sarma": [("system", P, _NO), ("blocks", P, _NO), ("removed", P, "frozenset()")],
    "sarma_modes": [("system", P, _NO), ("blocks", P, _NO), ("removed", P, "frozenset()")],
    "sarma_checks": [("system", P, _NO), ("blocks", P, _NO), ("removed", P, "frozenset()")],
    "toppling_mode": [("system", P, _NO), ("blocks", P, _NO), ("removed", P, "frozenset()")],
    "toppling_row": [("system", P, _NO), ("blocks", P, _NO), ("removed", P, "frozenset()")],
    "toppling_check": [("system", P, _NO), ("blocks", P, _NO), ("removed", P, "frozenset()")],
    "judge": [("scene", P, _NO), ("system", P, _NO), ("blocks", P, _NO), ("settings", K, _NO), ("params", K, "None"),
              ("removed", K, "frozenset()"), ("friction", K, "None"), ("reduction", K, "1.0"),
              ("record_every", K, "None")],
    "sub_scene": [("scene", P, _NO), ("system", P, _NO), ("blocks", P, _NO), ("removed", K, "frozenset()"),
                  ("free_neighbours", K, "False"), ("friction", K, "None"), ("reduction", K, "1.0")],
    "format_groups": [("groups", P, _NO)],
    "format_paper_table": [("results", P, _NO), ("title", K, "''")],
    "format_toppling": [("mode", P, _NO)],
    "probabilistic": [("build", P, _NO), ("variables", P, _NO), ("n", P, _NO), ("method", K, "'sarma'"),
                      ("sampling", K, "'monte-carlo'"), ("seed", K, "0"), ("correlation", K, "None"),
                      ("group", K, "None"), ("settings", K, "None"), ("client", K, "None"), ("workers", K, "None"),
                      ("out", K, "None"), ("geometry_seed", K, "None"), ("progress", K, "None"),
                      ("dda_fs", K, "False")],
    "read_study": [("path", P, _NO)],
    "sample_variables": [("variables", P, _NO), ("n", P, _NO), ("sampling", K, "'monte-carlo'"), ("seed", K, "0"),
                         ("correlation", K, "None")],
    # frozen keyword-only classes: their fields (a class may add fields with defaults after these)
    "BlockStep": [(f, K, _NO) for f in ("block", "state", "force_above", "force_toppling", "force_sliding",
                                        "force_below", "height", "contact_above", "contact_below", "base_dip")],
    "BlockSystem": [(f, K, _NO) for f in (
        "vertex_offset", "vertex_xy", "block_area", "block_centroid", "block_mass", "block_force", "block_moment",
        "block_fixed", "contact_blocks", "contact_start", "contact_end", "contact_normal", "contact_length",
        "contact_friction", "contact_cohesion", "contact_tensile", "contact_joint", "contact_edge", "contact_span",
        "gravity", "scale")] + [(f, K, "None") for f in (
            "block_water", "block_seismic", "block_bolt", "block_passive", "block_passive_moment",
            "contact_water")] + [("seismic", K, "(0.0, 0.0)"), ("contact_barton", K, "None")],
    "DdaEvaluation": [(f, K, _NO) for f in ("fs", "critical_friction", "judgement", "runs", "wall_time")]
    + [("timing", K, "None")],
    "DdaJudgement": [(f, K, _NO) for f in ("stable", "displacement", "speed", "threshold", "duration", "simulated",
                                           "steps", "wall_time", "friction", "reduction", "model_blocks",
                                           "moving_blocks", "scene_blocks")]
    + [("note", K, "''"), ("batch", K, "1")],
    "DdaSettings": [("params", K, "None"), ("duration", K, "None"), ("displacement_ratio", K, "0.005"),
                    ("acceleration_resolution", K, "0.05"), ("stop_ratio", K, "4.0"), ("rest_ratio", K, "1e-06"),
                    ("rest_steps", K, "20"), ("cohesion_held", K, "True"), ("free_neighbours", K, "False"),
                    ("friction_tolerance", K, "0.25"), ("fs_tolerance", K, "0.02"), ("candidates", K, "1"),
                    ("compare_whole", K, "False"), ("whole_steps", K, "100"), ("batch", K, "8"),
                    ("sample_batch", K, "128"), ("progress", K, "None")],
    "DdaTiming": [(f, K, _NO) for f in ("steps", "sub_step_time", "whole_step_time", "sub_blocks", "whole_blocks")],
    "GroupResult": [(f, K, _NO) for f in ("blocks", "fs", "critical_friction", "stable", "mode")]
    + [("surface", K, "()"), ("evaluator", K, "'rigid'"), ("seed", K, "None"), ("iteration", K, "0"),
       ("dda", K, "None"), ("water_force", K, "None"), ("bolt_force", K, "None"), ("seismic", K, "None"),
       ("modes", K, "()"), ("rejected", K, "()")],
    "Mode": [(f, K, _NO) for f in ("kind", "fs", "critical_friction", "sliding_contacts")]
    + [("sheared_contacts", K, "<factory>")]
    + [(f, K, "None") for f in ("direction", "pivot", "block_velocity", "critical_acceleration", "block_modes")],
    "Report": [(f, K, _NO) for f in ("method", "critical", "groups", "block_types", "history")]
    + [("removed", K, "()"), ("failure_surface", K, "()"), ("fs_target", K, "1.0"), ("wall_time", K, "0.0")],
    "Settings": [("fs_target", K, "1.0"), ("growth_tolerance", K, "0.0001"), ("max_group_size", K, "8"),
                 ("max_row_size", K, "32"), ("max_iterations", K, "100"), ("screening", K, "'sarma'"),
                 ("dda", K, "<factory>"), ("contact_gap", K, "None")],
    "Study": [(f, K, _NO) for f in ("n", "pf", "beta", "table", "variables", "method", "sampling", "seed")]
    + [("resumed", K, "0"), ("wall_time", K, "0.0")],
}
#: enums: their members' values
ENUMS = {
    "ModeKind": {"NONE": "none", "LIFTING": "lifting", "SLIDING": "sliding", "ROTATION": "rotation",
                 "SARMA": "sarma", "TOPPLING": "toppling"},
    "BlockState": {"STABLE": "stable", "TOPPLING": "toppling", "SLIDING": "sliding"},
}


def test_the_exported_names_stay():
    assert sorted(kgm.__all__) == sorted(set(SIGNATURES) | set(ENUMS))
    for name in kgm.__all__:
        assert getattr(kgm, name) is not None


def _described(p: inspect.Parameter):
    kind = {p.POSITIONAL_OR_KEYWORD: P, p.KEYWORD_ONLY: K}.get(p.kind, p.kind.name)
    if p.default is p.empty:
        return p.name, kind, _NO
    return p.name, kind, p.default


def _same_default(expected, actual) -> bool:
    if expected is _NO or actual is _NO:
        return expected is actual
    if expected == "<factory>":
        return repr(actual) == "<factory>"
    return type(eval(expected)) in (type(actual), *type(actual).__mro__) and eval(expected) == actual


def test_the_signatures_stay():
    for name, expected in SIGNATURES.items():
        obj = getattr(kgm, name)
        actual = [_described(p) for p in inspect.signature(obj).parameters.values()]
        is_class = isinstance(obj, type)
        head = actual[:len(expected)] if is_class else actual
        assert len(head) == len(expected), f"kgm.{name}: parameters {actual}, expected {expected}"
        for (n, k, d), (n2, k2, d2) in zip(expected, head):
            assert (n, k) == (n2, k2) and _same_default(d, d2), f"kgm.{name}: {n2} {k2} {d2!r}, expected {n} {k} {d}"
        # fields added to a class come after the old ones, keyword-only, with defaults
        assert all(k == K and d is not _NO for _, k, d in actual[len(expected):]), f"kgm.{name}: {actual}"


def test_the_enums_keep_their_members():
    for name, members in ENUMS.items():
        enum = getattr(kgm, name)
        assert {m.name: m.value for m in enum} == members
        assert all(isinstance(m, str) and m == v for m, v in zip(enum, members.values()))
