"""kgm's public names are a contract: `kgm.__all__` and the signature of every exported
function and class stay as they are (a result or settings class may gain fields, with
defaults, after its own; an enum keeps its members)."""

from __future__ import annotations

import inspect

import pytest

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
    "SubsetSampling": [("p0", K, "0.1"), ("proposal", K, "'conditional'"), ("spread", K, "None"),
                       ("max_levels", K, "20")],
    "ImportanceSampling": [("step", K, "None"), ("tol", K, "0.001"), ("max_iterations", K, "30"),
                           ("batch", K, "None")],
    # 3D wedges (docs/kgm/wedge.md)
    "Plane": [("dip", P, _NO), ("dip_direction", P, _NO), ("joint", P, "None")],
    "wedge": [("face", P, _NO), ("upper", P, _NO), ("height", P, _NO), ("joints", P, _NO), ("density", K, "2600.0"),
              ("water", K, "None"), ("seismic", K, "None"), ("bolts", K, "()"), ("tension_crack", K, "None"),
              ("bench_width", K, "None"), ("slope_length", K, "None"), ("forces", K, "()"), ("gravity", K, "9.81"),
              ("height_reference", K, "'joint1'")],
    "Wedge": [("forms", K, _NO), ("reason", K, _NO)],
    "TensionCrack": [("plane", P, _NO), ("distance", P, _NO)],
    "Support": [("fs", P, _NO), ("force", P, _NO), ("trend", P, _NO), ("plunge", P, _NO), ("pressure", P, _NO)],
    "polyhedral_block": [("halfspaces", P, _NO), ("joints", P, _NO), ("density", K, "2600.0"), ("gravity", K, "9.81"),
                         ("water_pressures", K, "None"), ("seismic", K, "None"), ("bolts", K, "()"),
                         ("forces", K, "()")],
    "Halfspace": [("normal", P, _NO), ("offset", P, _NO), ("label", P, _NO), ("kind", P, "'joint'")],
    "Water": [("fill", P, "1.0"), ("density", P, "1000.0"), ("pressures", P, "None")],
    "Seismic": [("k", P, _NO), ("trend", P, "None"), ("plunge", P, "0.0")],
    "Bolt": [("force", P, _NO), ("trend", P, _NO), ("plunge", P, _NO), ("kind", P, "'active'")],
    "Force": [("force", P, _NO), ("trend", P, _NO), ("plunge", P, _NO)],
    "joint_pyramids": [("joint_normals", P, _NO), ("free_outward_normals", P, _NO)],
    "JointPyramid": [("code", P, _NO), ("empty", P, _NO), ("finite", P, _NO)],
    "face_key_blocks": [("joints", P, _NO), ("free_outward_normals", P, _NO), ("force", P, "(0.0, 0.0, -1.0)")],
    "KeyBlock": [("pyramid", P, _NO), ("type", P, _NO), ("mode", P, _NO), ("fs", P, _NO)],
    "wedge_study": [("base", P, _NO), ("variables", P, _NO), ("n", P, _NO), ("sampling", K, "'monte-carlo'"),
                    ("seed", K, "0"), ("correlation", K, "None"), ("min_volume", K, "0.0"), ("out", K, "None"),
                    ("workers", K, "None"), ("client", K, "None")],
    "WedgeStudy": [(f, K, _NO) for f in ("n", "pf", "p_sliding", "valid", "table", "variables", "sampling", "seed",
                                        "min_volume")] + [("wall_time", K, "0.0"), ("resumed", K, "0")],
    "Fisher": [("kappa", P, _NO)],
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


#: the former module paths of kgm and the names they re-export for one release (their new homes
#: are in docs/kgm/architecture.md)
FORMER = {
    "blocks": ("BlockSystem", "build_block_system", "classify_blocks", "removable_arc", "is_removable", "rigid_modes",
               "Mode", "ModeKind", "group_faces", "check_group", "is_connected", "has_free_face", "GroupFaces",
               "block_type", "BLOCK_TYPES", "ANGLE_TOL", "DISTANCE_TOL", "MIN_CONTACT", "CONTACT_GAP",
               "BARTON_ITERATIONS", "BARTON_TOL"),
    "toppling": ("toppling_mode", "toppling_row", "toppling_check", "row_geometry", "upslope_neighbours",
                 "recursion", "toe_force", "row_factor_of_safety", "row_critical_friction", "BlockState", "BlockStep",
                 "RowBlock", "TopplingRow", "F_MIN", "F_MAX", "PHI_MAX", "BISECTION_STEPS", "BASE_MIN_COS",
                 "INTERFACE_MIN_COS", "ROW_BASE_ANGLE", "ROW_PIVOT_TOL", "Mode", "ModeKind", "group_faces",
                 "BARTON_ITERATIONS", "BARTON_TOL", "BlockSystem"),
    "evaluators": ("Evaluation", "evaluate_rigid", "evaluate_sarma", "sarma_modes", "sarma_checks",
                   "critical_friction_of", "F_MIN", "F_MAX", "PHI_MAX", "VELOCITY_TOL", "SCAN_SAMPLES", "POLE_SAMPLES",
                   "ROOT_K_TOL", "Mode", "ModeKind", "group_faces", "rigid_modes", "toppling_check", "BlockSystem"),
    "judgement": ("DdaJudgement", "judge", "sub_scene", "run_params", "group_size", "block_displacements",
                  "block_speeds", "RestCounter", "BlockSystem", "DdaSettings"),
    "batched": ("Member", "judge_many", "judge_members", "RestCounter", "block_displacements", "block_speeds",
                "group_size", "judge", "run_params", "sub_scene", "BlockSystem", "DdaSettings"),
    "dda": ("DdaEvaluation", "DdaTiming", "DdaJudgement", "evaluate_dda", "judge", "sub_scene", "run_params",
            "group_size", "time_sub_and_whole", "judge_many", "BlockSystem", "DdaSettings"),
    "search": ("analyze", "evaluate", "factor_of_safety", "critical_friction", "exhaustive", "key_blocks", "grow",
               "is_key_group", "connected_groups", "GroupResult", "Report", "contact_polylines", "build_block_system",
               "check_group", "classify_blocks", "critical_friction_of", "evaluate_rigid", "evaluate_sarma",
               "upslope_neighbours", "has_free_face", "Evaluation", "BlockSystem", "Settings", "METHODS"),
    "probability": ("probabilistic", "Study", "read_study", "sample_variables", "sample_seeds", "read_variables",
                    "variables_from_mapping", "write_frequency_png", "HEADER_MARK", "METHODS", "SAMPLINGS"),
}


def test_the_former_module_paths_still_give_their_names():
    import importlib

    for module, names in FORMER.items():
        old = importlib.import_module(f"kgm.{module}")
        missing = [n for n in names if not hasattr(old, n)]
        assert not missing, f"kgm.{module} lost {missing}"
    # the same objects as their new homes
    import kgm.blocks
    import kgm.dda
    import kgm.toppling

    assert kgm.blocks.build_block_system is kgm.build_block_system and kgm.dda.judge is kgm.judge
    assert kgm.toppling.BlockState is kgm.BlockState and kgm.blocks.Mode is kgm.Mode
    # the search's former entry points resolve from their new homes, on first use
    import kgm.search

    assert kgm.search.analyze is kgm.analyze and kgm.search.exhaustive is kgm.exhaustive
    assert kgm.search.Report is kgm.Report and kgm.search.METHODS == ("rigid", "sarma", "dda")
    with pytest.raises(AttributeError, match="no attribute 'nothing'"):
        kgm.search.nothing


def test_the_words_are_str_enums_that_compare_as_before():
    """`kgm.kinds`: the old strings compare equal, print as themselves, and name a method."""
    from kgm.kinds import Method, RunEnd

    assert Method("sarma") == "sarma" and f"{Method.DDA:<5}|" == "dda  |" and str(Method.RIGID) == "rigid"
    assert RunEnd.DIVERGED.note("step 12: nan") == "diverged after failing: step 12: nan"
    assert RunEnd.DURATION.note() == "" and RunEnd.AT_REST.note() == "at rest"
    assert kgm.Settings(screening="rigid").screening is Method.RIGID
    with pytest.raises(ValueError, match="unknown method 'sarm'"):
        kgm.analyze(None, method="sarm")
