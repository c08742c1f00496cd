"""The geometry (``.geo``) and analysis (``.ana``) readers, each format (docs/ntdda.md §4)."""

from __future__ import annotations

import math

import numpy as np

from pathlib import Path
from .records import (NTDDA_ANGLE_OVERLAP, NTDDA_NORM_SPRING_PEN, NTDDA_OC_LIMIT, NTDDA_OPENCLOSE,
                      NTDDA_OPENCRITERIA, NTDDA_PFACTOR, NTDDA_SHEAR_NORM_RATIO, NtddaAnalysis,
                      NtddaBlockMaterial, NtddaFormatError, NtddaGeometry, NtddaJointMaterial,
                      NtddaQuirkWarning, NtddaUnsupportedWarning)
from .text import (_detect_format, _Element, _FIELDS, _INTEGER, _parse_xml, _read_text, _section,
                   _to_float, _Tokens, _warn, _Xml)

# ============================================================================ geometry readers
def read_ntdda_geometry(path) -> NtddaGeometry:
    """Read an ntdda geometry file (original text or DDAML, detected automatically).

    Raises `NtddaFormatError` for a malformed file. Warns about ignored content.
    """
    p, text = _read_text(path)
    log: list[str] = []
    if _detect_format(p, text) == "ddaml":
        return _read_ddaml_geometry(p, text, log)
    return _read_original_geometry(p, text, log)


def _read_original_geometry(path: Path, text: str, log: list) -> NtddaGeometry:
    """GHS "DC" input (docs/ntdda.md §4.2): e00, eight counts, then the records in a fixed order."""
    tk = _Tokens(path, text)
    e00 = tk.real("e00 (the minimum edge-node distance)")
    if e00 < 0:
        raise NtddaFormatError(f"{path}, line 1: e00 must be >= 0, got {e00:g}")
    n_joints = tk.integer("the number of joint lines", minimum=3)
    boundary_where = tk.where()
    n_boundary = tk.integer("the number of boundary lines")
    n_mat = tk.integer("the number of material lines")
    bolts_where = tk.where()
    n_bolts = tk.integer("the number of bolts")
    n_fixed = tk.integer("the number of fixed lines")
    n_load = tk.integer("the number of load points")
    n_meas = tk.integer("the number of measured points")
    n_hole = tk.integer("the number of hole points")
    if n_boundary > n_joints:
        raise NtddaFormatError(f"{path}, {boundary_where}: {n_boundary} boundary lines but only "
                               f"{n_joints} joint lines")
    if n_bolts:
        # ntdda accepts the count with a warning but never reads the bolt records, so the rest
        # of the file is misread (docs/ntdda.md §3.8); no bolt records to read into ddatai's bolts
        raise NtddaFormatError(f"{path}, {bolts_where}: {n_bolts} rock bolts declared; ntdda files' bolt "
                               "records are not read (ntdda misreads the rest of such a file): declare 0 "
                               "and add the bolts with Scene.add_bolt")
    joints, jtype, jwhere = [], [], []
    for k in range(n_joints):
        jwhere.append(tk.where())
        joints.append([tk.real(f"joint line {k + 1}: {f}") for f in _FIELDS[4]])
        jtype.append(tk.index(f"joint line {k + 1}: joint type"))
    mats, mtype, mwhere = [], [], []
    for k in range(n_mat):
        mwhere.append(tk.where())
        mats.append([tk.real(f"material line {k + 1}: {f}") for f in _FIELDS[4]])
        mtype.append(tk.index(f"material line {k + 1}: block material"))
    fixed, fwhere = tk.records(n_fixed, 4, "fixed line")
    load, lwhere = tk.records(n_load, 2, "load point")
    meas, mswhere = tk.records(n_meas, 2, "measured point")
    hole, hwhere = tk.records(n_hole, 2, "hole point")
    tk.finish("the last hole point" if n_hole else "the last record")
    geom = NtddaGeometry(
        path=str(path), format="original", edge_node_distance=e00,
        joints=np.array(joints, dtype=float).reshape(-1, 4), joint_type=np.array(jtype, dtype=np.int64),
        joint_where=tuple(jwhere), n_boundary_lines=n_boundary,
        material_lines=np.array(mats, dtype=float).reshape(-1, 4),
        material_line_type=np.array(mtype, dtype=np.int64), material_line_where=tuple(mwhere),
        fixed_lines=fixed, fixed_where=fwhere, load_points=load, load_where=lwhere,
        measured_points=meas, measured_where=mswhere, hole_points=hole, hole_where=hwhere,
        seismic_points=np.zeros((0, 2)), n_bolts=0, bolts_where="", warnings=tuple(log))
    _check_joint_lengths(geom)
    return geom


def _read_ddaml_geometry(path: Path, text: str, log: list) -> NtddaGeometry:
    """DDAML geometry (docs/ntdda.md §4.4)."""
    xml = _Xml(path)
    geo = _section(xml, _parse_xml(path, text), "Geometry", "Analysis")
    e00 = 0.0  # ntdda's calloc'ed default when <Edgenodedist> is absent: no node merging
    joints, jtype, jwhere = [], [], []
    mats, mtype, mwhere = [], [], []
    fixed, fwhere = [], []
    points = {"Loadpointlist": ([], []), "Measuredpointlist": ([], []), "Holepointlist": ([], []),
              "Seismicpointlist": ([], [])}
    n_bolts, bolts_where = 0, ""

    def children(lst: _Element, allowed: tuple) -> list:
        out = []
        for ch in lst.children:
            if ch.name in allowed:
                out.append(ch)
            else:
                xml.fail(ch, f"unexpected element inside <{lst.name}>: expected "
                             + " or ".join(f"<{a}>" for a in allowed))
        return out

    for el in geo.children:
        if el.name == "Edgenodedist":
            e00 = xml.attr_real(el, "distance", minimum=0.0)
        elif el.name == "Jointlist":
            for j in children(el, ("Joint",)):
                jtype.append(xml.attr_int(j, "type", minimum=1))
                joints.append(xml.numbers(j, 4, "x1 y1 x2 y2"))
                jwhere.append(j.where())
        elif el.name == "Fixedpointlist":
            for f in children(el, ("Point", "Line")):
                if f.name == "Point":
                    x, y = xml.numbers(f, 2, "x y")
                    fixed.append([x, y, x, y])
                else:
                    fixed.append(xml.numbers(f, 4, "x1 y1 x2 y2"))
                fwhere.append(f.where())
        elif el.name in points:
            for pt in children(el, ("Point",)):
                points[el.name][0].append(xml.numbers(pt, 2, "x y"))
                points[el.name][1].append(pt.where())
        elif el.name == "Matlinelist":
            for m in children(el, ("Line",)):
                mtype.append(xml.attr_int(m, "type", minimum=1))
                mats.append(xml.numbers(m, 4, "x1 y1 x2 y2"))
                mwhere.append(m.where())
        elif el.name == "Boltlist":
            bolts = children(el, ("Bolt",))
            if bolts:
                n_bolts, bolts_where = len(bolts), bolts[0].where()
        elif el.name == "Boundlist":
            # ntdda parses it into a list it never allocates and crashes (docs/ntdda.md §3.9)
            xml.fail(el, "<Boundlist> is not supported (ntdda crashes on it); put these lines "
                         "in <Jointlist>")
        else:
            _warn(log, NtddaUnsupportedWarning, f"{path}, {el.where()}: unknown element ignored")
    if not joints:
        xml.fail(geo, "expected a <Jointlist> with at least 3 <Joint> elements")
    if n_bolts:
        raise NtddaFormatError(f"{path}, {bolts_where}: {n_bolts} rock bolts; ntdda files' bolt records are "
                               "not read (remove the <Boltlist> and add the bolts with Scene.add_bolt)")
    seismic = points["Seismicpointlist"]
    if seismic[0]:
        # ntdda parses the record into a local variable and never applies it (docs/ntdda.md §3.6)
        _warn(log, NtddaQuirkWarning, f"{path}, {seismic[1][0]}: seismic points ignored: ntdda never "
              "applies seismic loads (its time history is lost, docs/ntdda.md §3.6), and ddatai does "
              "not read them either (use Scene.set_ground_acceleration)")

    def arr(rows, width):
        return np.array(rows, dtype=float).reshape(-1, width)

    geom = NtddaGeometry(
        path=str(path), format="ddaml", edge_node_distance=e00,
        joints=arr(joints, 4), joint_type=np.array(jtype, dtype=np.int64), joint_where=tuple(jwhere),
        n_boundary_lines=0, material_lines=arr(mats, 4),
        material_line_type=np.array(mtype, dtype=np.int64), material_line_where=tuple(mwhere),
        fixed_lines=arr(fixed, 4), fixed_where=tuple(fwhere),
        load_points=arr(points["Loadpointlist"][0], 2), load_where=tuple(points["Loadpointlist"][1]),
        measured_points=arr(points["Measuredpointlist"][0], 2),
        measured_where=tuple(points["Measuredpointlist"][1]),
        hole_points=arr(points["Holepointlist"][0], 2), hole_where=tuple(points["Holepointlist"][1]),
        seismic_points=arr(seismic[0], 2), n_bolts=0, bolts_where="", warnings=tuple(log))
    _check_joint_lengths(geom)
    return geom


def _check_joint_lengths(geom: NtddaGeometry) -> None:
    if len(geom.joints) < 3:
        raise NtddaFormatError(f"{geom.path}: {len(geom.joints)} joint lines; at least 3 are needed "
                               "to close a block")
    seg = geom.joints
    scale = max(float(np.ptp(seg[:, [0, 2]])), float(np.ptp(seg[:, [1, 3]])))
    zero = np.hypot(seg[:, 2] - seg[:, 0], seg[:, 3] - seg[:, 1]) <= 1e-12 * max(scale, 1e-300)
    if zero.any():
        k = int(np.flatnonzero(zero)[0])
        raise NtddaFormatError(f"{geom.path}, {geom.joint_where[k]}: joint line {k + 1} has zero length")


# ============================================================================ analysis readers
def read_ntdda_analysis(path) -> NtddaAnalysis:
    """Read an ntdda analysis file (original text or DDAML, detected automatically)."""
    p, text = _read_text(path)
    log: list[str] = []
    if _detect_format(p, text) == "ddaml":
        return _read_ddaml_analysis(p, text, log)
    return _read_original_analysis(p, text, log)


def _read_original_analysis(path: Path, text: str, log: list) -> NtddaAnalysis:
    """GHS "DF" input (docs/ntdda.md §4.3) and ntdda's implicit settings for it."""
    tk = _Tokens(path, text)
    where = tk.where()
    kind = tk.integer("the analysis type (0 static, 1 dynamic)")
    if kind not in (0, 1):
        raise NtddaFormatError(f"{path}, {where}: the analysis type must be 0 (static) or 1 (dynamic), "
                               f"got {kind}")
    n_steps = tk.integer("the number of time steps", minimum=1)
    n_bmat = tk.integer("the number of block materials", minimum=1)
    n_jmat = tk.integer("the number of joint materials", minimum=1)
    where = tk.where()
    g2 = tk.real("g2 (the maximum displacement ratio)")
    if not g2 > 0:
        raise NtddaFormatError(f"{path}, {where}: g2 (maximum displacement ratio) must be > 0, got {g2:g}")
    where = tk.where()
    g1 = tk.real("g1 (the maximum time step)")
    if not g1 > 0:
        raise NtddaFormatError(f"{path}, {where}: g1 (maximum time step) must be > 0, got {g1:g}")
    names = ("unit mass", "unit weight", "Young's modulus", "Poisson's ratio", "sxx", "syy", "sxy",
             "txx", "tyy", "txy", "vx", "vy", "vr")
    bmats = []
    for k in range(n_bmat):
        where = tk.where()
        v = [tk.real(f"block material {k + 1}: {name}") for name in names]
        bmats.append(_block_material(path, where, unit_mass=v[0], unit_weight=v[1], young=v[2],
                                     poisson=v[3], damping=0.0, stress=tuple(v[4:7]),
                                     stress_gradient=tuple(v[7:10]), velocity=tuple(v[10:13]),
                                     strain=(0.0, 0.0, 0.0)))
    jmats = []
    for k in range(n_jmat):
        where = tk.where()
        v = [tk.real(f"joint material {k + 1}: {name}") for name in ("friction angle", "cohesion",
                                                                     "tensile strength")]
        jmats.append(_joint_material(path, where, *v))
    tk.finish("the last joint material")
    # ntdda's original-format reader replaces the contact constants by uninitialised memory
    # (docs/ntdda.md §3.12: NaN at step 1, circleslope crashes); ddatai uses ntdda's defaults
    _warn(log, NtddaQuirkWarning, f"{path}: original-format analysis file: ntdda leaves the contact "
          "constants uninitialised for this format (its runs end in NaN, docs/ntdda.md §3.12); "
          "ddatai uses ntdda's default constants")
    _warn(log, NtddaUnsupportedWarning, f"{path}: ntdda re-estimates the penalty every step for "
          "original-format files (automatic penalty); ddatai keeps it at 50 × the largest Young's "
          "modulus")
    for m in bmats:
        if any(m.stress_gradient):
            _warn(log, NtddaQuirkWarning, f"{path}, {m.where}: stress gradients (txx tyy txy) given: "
                  "ntdda also uses them as initial velocities (docs/ntdda.md §4.3, §3.14); "
                  "ddatai applies them only as σ = s + y_centroid·t")
        if any(m.velocity):
            _warn(log, NtddaQuirkWarning, f"{path}, {m.where}: initial velocities given: ntdda ignores "
                  "them in this format (it reads the stress gradients instead, docs/ntdda.md §3.14); "
                  "ddatai applies them")
    return NtddaAnalysis(
        path=str(path), format="original", dynamic=kind == 1, n_steps=n_steps, max_time_step=g1,
        auto_time_step=True, max_displacement=g2, auto_penalty=True, penalty_factor=NTDDA_PFACTOR,
        plane_strain=False, rotation="linear", gravity_turn_on=False, gravity_acceleration=None,
        oc_limit=NTDDA_OC_LIMIT, save_interval=1, contact_damping=0.0,
        openclose=NTDDA_OPENCLOSE, opencriteria=NTDDA_OPENCRITERIA, norm_spring_pen=NTDDA_NORM_SPRING_PEN,
        angle_overlap=NTDDA_ANGLE_OVERLAP, shear_norm_ratio=NTDDA_SHEAR_NORM_RATIO,
        block_materials=tuple(bmats), joint_materials=tuple(jmats), load_histories=(), load_where=(),
        warnings=tuple(log))


def _block_material(path, where, **kw) -> NtddaBlockMaterial:
    m = NtddaBlockMaterial(where=where, **kw)
    if not m.unit_mass > 0:
        raise NtddaFormatError(f"{path}, {where}: unit mass must be > 0, got {m.unit_mass:g}")
    if m.unit_weight is not None and m.unit_weight < 0:
        raise NtddaFormatError(f"{path}, {where}: unit weight must be >= 0, got {m.unit_weight:g}")
    if not m.young > 0:
        raise NtddaFormatError(f"{path}, {where}: Young's modulus must be > 0, got {m.young:g}")
    if not 0.0 <= m.poisson < 0.5:
        raise NtddaFormatError(f"{path}, {where}: Poisson's ratio must be in [0, 0.5), got {m.poisson:g}")
    return m


def _joint_material(path, where, friction, cohesion, tensile) -> NtddaJointMaterial:
    if not 0.0 <= friction < 90.0:
        raise NtddaFormatError(f"{path}, {where}: friction angle must be in [0, 90) degrees, got {friction:g}")
    if cohesion < 0 or tensile < 0:
        raise NtddaFormatError(f"{path}, {where}: cohesion and tensile strength must be >= 0, "
                               f"got {cohesion:g} and {tensile:g}")
    return NtddaJointMaterial(friction=friction, cohesion=cohesion, tensile=tensile, where=where)


def _read_ddaml_analysis(path: Path, text: str, log: list) -> NtddaAnalysis:
    """DDAML analysis (docs/ntdda.md §4.5). Elements are dispatched by name like ntdda does;
    unknown ones are reported (ntdda ignores them silently)."""
    xml = _Xml(path)
    ana = _section(xml, _parse_xml(path, text), "Analysis", "Geometry")
    s = dict(dynamic=False, rotation="linear", gravity_turn_on=False, gravity_acceleration=None,
             auto_time_step=False, auto_penalty=False, penalty_factor=None, plane_strain=False,
             n_steps=None, max_time_step=None, max_displacement=None, save_interval=1,
             oc_limit=None, contact_damping=0.0, openclose=NTDDA_OPENCLOSE,
             opencriteria=NTDDA_OPENCRITERIA, norm_spring_pen=NTDDA_NORM_SPRING_PEN,
             angle_overlap=NTDDA_ANGLE_OVERLAP, shear_norm_ratio=NTDDA_SHEAR_NORM_RATIO)
    bmats, jmats, histories, hwhere = [], [], [], []
    autopenalty_el = None
    oc_el = None
    for el in ana.children:
        name = el.name
        if name == "Analysistype":
            kind = el.attrs.get("type", "").strip().lower()
            if kind not in ("static", "dynamic"):
                xml.fail(el, f"attribute type must be \"static\" or \"dynamic\", got {el.attrs.get('type')!r}")
            s["dynamic"] = kind == "dynamic"
        elif name == "Rotation":
            kind = el.attrs.get("type", "").strip().lower()
            if kind not in ("linear", "secondorder", "exact"):
                xml.fail(el, "attribute type must be \"linear\", \"secondorder\" or \"exact\", "
                             f"got {el.attrs.get('type')!r}")
            s["rotation"] = kind
        elif name == "Gravity":
            s["gravity_turn_on"] = xml.attr_flag(el)
        elif name == "Gravaccel":
            s["gravity_acceleration"] = xml.attr_real(el, "value", minimum=0.0)
        elif name == "Autotimestep":
            s["auto_time_step"] = xml.attr_flag(el)
        elif name == "Autopenalty":
            s["auto_penalty"] = xml.attr_flag(el)
            autopenalty_el = el
            if "pfactor" in el.attrs:
                s["penalty_factor"] = xml.attr_real(el, "pfactor", positive=True)
        elif name == "Planestrain":
            s["plane_strain"] = xml.attr_flag(el)
        elif name == "Numtimesteps":
            s["n_steps"] = xml.attr_int(el, "timesteps", minimum=1)
        elif name == "Maxtimestep":
            s["max_time_step"] = xml.attr_real(el, "maxtimestep", positive=True)
        elif name == "Mintimestep":
            xml.attr_real(el, "mintimestep", minimum=0.0)  # parsed but unused, as in ntdda
        elif name == "Maxdisplacement":
            s["max_displacement"] = xml.attr_real(el, "maxdisplacement", positive=True)
        elif name == "Saveinterval":
            step = el.attrs.get("step", "").strip()
            if _INTEGER.match(step) and int(step) >= 1:
                s["save_interval"] = int(step)
            elif step in ("", "0"):
                s["save_interval"] = 10
                _warn(log, NtddaQuirkWarning, f"{path}, {el.where()}: no save interval given; ntdda "
                      "then saves every 10 steps, and so does ddatai")
            else:
                xml.fail(el, f"attribute step must be a whole number >= 1, got {el.attrs.get('step')!r}")
        elif name in ("Opencloselimit", "OCLimit"):
            s["oc_limit"] = xml.attr_int(el, "maxopenclose", minimum=2)
            oc_el = el
        elif name == "ContactDamping":
            s["contact_damping"] = xml.attr_real(el, "value", minimum=0.0)
            if s["contact_damping"] > 0:
                _warn(log, NtddaUnsupportedWarning, f"{path}, {el.where()}: contact damping is not "
                      "supported; ignored")
        elif name == "AConstants":
            _read_constants(xml, el, s, log)
        elif name == "Blockmaterial":
            bmats.append(_read_ddaml_block_material(xml, el, log))
        elif name == "Jointproperties":
            jmats.append(_read_ddaml_joint_material(xml, el))
        elif name == "Loadpointlist":
            for lp in el.children:
                if lp.name != "Loadpoint":
                    xml.fail(lp, "unexpected element inside <Loadpointlist>: expected <Loadpoint>")
                histories.append(_read_load_history(xml, lp))
                hwhere.append(lp.where())
        elif name == "Timehistory":
            _warn(log, NtddaQuirkWarning, f"{path}, {el.where()}: seismic time history ignored: ntdda "
                  "loses it and never applies it (docs/ntdda.md §3.6); use Scene.set_ground_acceleration")
        elif name in ("Writevertices", "Boltproperties"):
            pass  # output selection; bolt properties without bolts
        else:
            _warn(log, NtddaUnsupportedWarning, f"{path}, {el.where()}: unknown element ignored")

    for key, element, attr in (("n_steps", "Numtimesteps", "timesteps"),
                               ("max_time_step", "Maxtimestep", "maxtimestep"),
                               ("max_displacement", "Maxdisplacement", "maxdisplacement")):
        if s[key] is None:
            xml.fail(ana, f"expected a <{element} {attr}=\"...\"/> element (ntdda's default 0 cannot run)")
    if not bmats:
        xml.fail(ana, "expected at least one <Blockmaterial> element")
    if s["penalty_factor"] is None:
        # without pfactor ntdda sets the penalty to 0 and blocks sink into each other (docs/ntdda.md §3.5)
        s["penalty_factor"] = NTDDA_PFACTOR
        where = autopenalty_el.where() if autopenalty_el is not None else "<Analysis>"
        _warn(log, NtddaQuirkWarning, f"{path}, {where}: no pfactor given: ntdda would use a penalty of "
              f"0 (blocks sink into each other, docs/ntdda.md §3.5); ddatai uses pfactor = {NTDDA_PFACTOR:g}")
    if s["oc_limit"] is None:
        s["oc_limit"] = NTDDA_OC_LIMIT
    elif s["oc_limit"] != NTDDA_OC_LIMIT:
        what = ("ntdda ignores <OCLimit> (it only reads <Opencloselimit>)" if oc_el.name == "OCLimit"
                else "ntdda's driver ignores it")
        _warn(log, NtddaQuirkWarning, f"{path}, {oc_el.where()}: open-close limit {s['oc_limit']}: {what} "
              f"and always stops at {NTDDA_OC_LIMIT} iterations (docs/ntdda.md §3.4); ddatai uses "
              f"{s['oc_limit']}")
    if s["auto_penalty"]:
        _warn(log, NtddaUnsupportedWarning, f"{path}, {autopenalty_el.where()}: ntdda's automatic penalty "
              f"re-estimation is not supported; the penalty stays at pfactor × the largest Young's modulus")
    if s["plane_strain"]:
        _warn(log, NtddaQuirkWarning, f"{path}: plane strain: ntdda's plane-strain stiffness is too stiff by "
              "(1+ν)/(1−ν) (docs/guide/method_choices.md); ddatai uses the correct one")
    return NtddaAnalysis(path=str(path), format="ddaml", block_materials=tuple(bmats),
                         joint_materials=tuple(jmats), load_histories=tuple(histories),
                         load_where=tuple(hwhere), warnings=tuple(log), **s)


def _read_constants(xml: _Xml, el: _Element, s: dict, log: list) -> None:
    names = {"Openclose": "openclose", "Opencriteria": "opencriteria", "NormSpringPen": "norm_spring_pen",
             "AngleOverlap": "angle_overlap", "ShearNormRatio": "shear_norm_ratio"}
    for ch in el.children:
        if ch.name in names:
            s[names[ch.name]] = xml.attr_real(ch, "value", positive=True)
        elif ch.name != "MinReflineFactor":
            _warn(log, NtddaUnsupportedWarning, f"{xml.path}, {ch.where()}: unknown contact constant ignored")
    if s["angle_overlap"] >= 30.0:
        xml.fail(el, f"AngleOverlap must be < 30 degrees, got {s['angle_overlap']:g}")
    # ddatai opens and closes contacts with its own much tighter tolerances
    # (docs/guide/method_choices.md); a file that changes ntdda's only gets told
    for key, default, what in (("openclose", NTDDA_OPENCLOSE, "Openclose"),
                               ("opencriteria", NTDDA_OPENCRITERIA, "Opencriteria")):
        if not math.isclose(s[key], default, rel_tol=1e-9):
            _warn(log, NtddaQuirkWarning, f"{xml.path}, {el.where()}: {what} = {s[key]:g} is not used: ddatai "
                  "opens and closes contacts with its own tolerances (docs/guide/method_choices.md)")


def _read_ddaml_block_material(xml: _Xml, el: _Element, log: list) -> NtddaBlockMaterial:
    vals: dict = {}
    triples = {"Istress": "stress", "Ivelocity": "velocity", "Istrain": "strain"}
    scalars = {"Unitmass": "unit_mass", "Unitweight": "unit_weight", "Youngsmod": "young",
               "Poissonratio": "poisson", "Damping": "damping"}
    for ch in el.children:
        if ch.name in scalars:
            vals[scalars[ch.name]] = xml.value(ch, ch.name)
        elif ch.name in triples:
            vals[triples[ch.name]] = tuple(xml.numbers(ch, 3, "three values"))
        else:
            xml.fail(ch, "unexpected element inside <Blockmaterial>")
    for required in ("Unitmass", "Youngsmod", "Poissonratio"):
        if scalars[required] not in vals:
            xml.fail(el, f"missing <{required}>")
    m = _block_material(xml.path, el.where(), unit_mass=vals["unit_mass"],
                        unit_weight=vals.get("unit_weight"), young=vals["young"], poisson=vals["poisson"],
                        damping=vals.get("damping", 0.0), stress=vals.get("stress", (0.0, 0.0, 0.0)),
                        stress_gradient=(0.0, 0.0, 0.0), velocity=vals.get("velocity", (0.0, 0.0, 0.0)),
                        strain=vals.get("strain", (0.0, 0.0, 0.0)))
    where = f"{xml.path}, {el.where()}"
    if any(m.velocity):
        _warn(log, NtddaQuirkWarning, f"{where}: non-zero <Ivelocity>: ntdda also adds y_centroid × "
              "Ivelocity to the initial stresses (its material columns are mixed up, docs/ntdda.md §3.3); "
              "ddatai applies it as initial velocity only")
    if any(m.strain):
        _warn(log, NtddaUnsupportedWarning, f"{where}: non-zero <Istrain> ignored (ntdda never uses it)")
    if m.damping:
        _warn(log, NtddaQuirkWarning, f"{where}: block damping {m.damping:g} ignored: ntdda reads it and "
              "never uses it (docs/ntdda.md §3.13)")
    return m


def _read_ddaml_joint_material(xml: _Xml, el: _Element) -> NtddaJointMaterial:
    vals = {}
    for ch in el.children:
        if ch.name in ("Friction", "Cohesion", "Tensile"):
            vals[ch.name] = xml.value(ch, ch.name)
        else:
            xml.fail(ch, "unexpected element inside <Jointproperties>")
    if "Friction" not in vals:
        xml.fail(el, "missing <Friction> (friction angle in degrees)")
    return _joint_material(xml.path, el.where(), vals["Friction"], vals.get("Cohesion", 0.0),
                           vals.get("Tensile", 0.0))


def _read_load_history(xml: _Xml, el: _Element) -> np.ndarray:
    """``numpoints`` records ``t fx fy`` separated by ';', times strictly increasing."""
    n = xml.attr_int(el, "numpoints", minimum=2)
    records = [r for r in el.text.split(";") if r.strip()]
    if len(records) != n:
        xml.fail(el, f"numpoints = {n} but {len(records)} records 't fx fy;' follow")
    rows = []
    for k, rec in enumerate(records):
        toks = rec.split()
        vals = [_to_float(t) for t in toks]
        if len(toks) != 3 or any(v is None for v in vals):
            xml.fail(el, f"record {k + 1}: expected three numbers 't fx fy', got {rec.strip()!r}")
        rows.append(vals)
    hist = np.array(rows, dtype=float)
    if np.any(np.diff(hist[:, 0]) <= 0):
        xml.fail(el, "record times must be strictly increasing")
    return hist


