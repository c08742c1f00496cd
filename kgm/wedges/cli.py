"""``kgm wedge INPUT.toml``: a wedge of a rock slope from a TOML file, its factor of safety,
support, probabilistic study and pictures (docs/kgm/wedge.md §8).

The file (SI units, angles in degrees)::

    [slope]
    face = { dip = 65, dip_direction = 185 }
    upper = { dip = 12, dip_direction = 195 }
    height = 30.0                 # m, the crest above the toe along joint 1's trace
    density = 2600.0              # kg/m³ (optional); bench_width, slope_length, height_reference
    [[joints]]                    # two, or three with a basal joint
    dip = 45
    dip_direction = 105
    friction = 20                 # Mohr–Coulomb: friction [deg], cohesion [Pa]; or Barton–Bandis:
    cohesion = 25e3               # jrc, jcs [Pa], residual_friction [deg]
    [[joints]]
    dip = 70
    dip_direction = 235
    friction = 30
    [tension_crack]               # optional
    dip = 70
    dip_direction = 165
    distance = 12.0               # m behind the crest along joint 1's trace
    [water]                       # optional: Hoek & Bray's filled fissures
    fill = 1.0                    # or pressures = [u1, u2, (u3), (crack)] in Pa
    [seismic]                     # optional
    k = 0.1                       # trend / plunge optional (default: along the sliding trend)
    [[bolts]]                     # optional, also [[forces]] (force, trend, plunge)
    force = 2e5                   # N
    trend = 5
    plunge = -10
    kind = "active"               # or "passive"
    [support]
    fs = 1.5                      # report the anchor force and face pressure for this FS
    [study]                       # optional probabilistic study
    n = 100000
    sampling = "latin-hypercube"
    min_volume = 10.0             # m³
    [study.variables.joint1_orientation]
    distribution = "fisher"
    k = 50
    [study.variables.joint1_friction]
    distribution = "normal"       # as in `kgm probabilistic`'s variables files
    mean = 20
    sd = 2
    [output]                      # optional; paths relative to this file
    png = "wedge.png"
    gif = "wedge.gif"
    stereonet = "wedge_stereonet.png"
    vtp = "wedge.vtp"
    csv = "wedge_samples.csv"
"""

from __future__ import annotations

import sys
from pathlib import Path

OUTPUTS = ("png", "gif", "stereonet", "vtp", "csv")


def add_parser(sub) -> None:
    """The ``wedge`` subcommand of ``kgm``."""
    p = sub.add_parser("wedge", help="a 3D wedge of a rock slope from a TOML file (FS, support, study, pictures)")
    p.add_argument("input", help="TOML file: slope, joints, water, seismic, bolts, study, output")
    for name in OUTPUTS:
        p.add_argument(f"--{name}", metavar="PATH", help=f"write the {name} here (overrides [output])")
    p.add_argument("--n", type=int, help="samples of the study (overrides [study] n)")
    p.add_argument("--seed", type=int, help="seed of the study (overrides [study] seed)")
    p.add_argument("--frames", type=int, default=36, help="frames of the GIF (default 36)")


def read_input(path) -> dict:
    """The TOML file as `kgm.wedge` arguments (``wedge``), the study (``study`` or None), the
    design FS (``support`` or None) and the output paths (``output``)."""
    from ddatai.io.tomlfile import read_toml

    path = Path(path)
    spec = read_toml(path, "wedge file")
    return from_mapping(spec, base=path.parent)


def from_mapping(spec: dict, base=Path(".")) -> dict:
    import ddatai as dd

    from ..wedges.geometry import Plane
    from ..wedges.mechanics import Bolt, Force, Seismic, Water
    from ..wedges.slope import TensionCrack

    unknown = set(spec) - {"slope", "joints", "tension_crack", "water", "seismic", "bolts", "forces", "support",
                           "study", "output"}
    if unknown:
        raise ValueError(f"unknown table(s) {sorted(unknown)} in the wedge file")
    slope = dict(_table(spec, "slope"))
    for key in ("face", "upper", "height"):
        if key not in slope:
            raise ValueError(f"[slope] needs {key}")
    plane = lambda t, where: Plane(_get(t, "dip", where), _get(t, "dip_direction", where))   # noqa: E731
    kw = dict(face=plane(slope.pop("face"), "[slope] face"), upper=plane(slope.pop("upper"), "[slope] upper"),
              height=slope.pop("height"))
    for key in ("density", "bench_width", "slope_length", "height_reference", "gravity"):
        if key in slope:
            kw[key] = slope.pop(key)
    if slope:
        raise ValueError(f"[slope] has unknown keys {sorted(slope)}")
    joints = spec.get("joints", [])
    if not isinstance(joints, list) or not 2 <= len(joints) <= 3:
        raise ValueError("the wedge file needs two [[joints]] tables (and an optional third, a basal joint)")
    planes = []
    for k, j in enumerate(joints):
        where = f"[[joints]] {k + 1}"
        j = dict(j)
        dip, ddir = _get(j, "dip", where), _get(j, "dip_direction", where)
        j.pop("dip"), j.pop("dip_direction")
        if "jrc" in j:
            law = dd.BartonBandis(jrc=j.pop("jrc"), jcs=_get(j, "jcs", where), residual_friction=_get(
                j, "residual_friction", where), cohesion=j.pop("cohesion", 0.0))
            j.pop("jcs"), j.pop("residual_friction")
        else:
            law = dd.Joint(friction=_get(j, "friction", where), cohesion=j.pop("cohesion", 0.0))
            j.pop("friction")
        if j:
            raise ValueError(f"{where} has unknown keys {sorted(j)}")
        planes.append(Plane(dip, ddir, law))
    kw["joints"] = planes
    if "tension_crack" in spec:
        t = _table(spec, "tension_crack")
        kw["tension_crack"] = TensionCrack(plane(t, "[tension_crack]"), _get(t, "distance", "[tension_crack]"))
    if "water" in spec:
        w = dict(_table(spec, "water"))
        if "pressures" in w:
            w["pressures"] = tuple(w["pressures"])
        kw["water"] = Water(**w)
    if "seismic" in spec:
        kw["seismic"] = Seismic(**_table(spec, "seismic"))
    kw["bolts"] = tuple(Bolt(**b) for b in spec.get("bolts", []))
    kw["forces"] = tuple(Force(**f) for f in spec.get("forces", []))
    study = None
    if "study" in spec:
        study = _study(dict(_table(spec, "study")))
    support = _table(spec, "support").get("fs") if "support" in spec else None
    output = {k: str(Path(base) / v) for k, v in _table(spec, "output").items()} if "output" in spec else {}
    bad = set(output) - set(OUTPUTS)
    if bad:
        raise ValueError(f"[output] has unknown keys {sorted(bad)}; known: {', '.join(OUTPUTS)}")
    return dict(wedge=kw, study=study, support=support, output=output)


def _table(spec, name) -> dict:
    t = spec[name]
    if not isinstance(t, dict):
        raise ValueError(f"[{name}] must be a table")
    return t


def _get(t, key, where):
    if key not in t:
        raise ValueError(f"{where} needs {key}")
    return t[key]


def _study(s: dict) -> dict:
    from ..kinds import Sampling
    from ..studies.sampling import variables_from_mapping
    from ..wedges.study import Fisher

    variables = dict(s.pop("variables", {}))
    correlation = s.pop("correlation", {})
    fisher = {k: Fisher(_get(v, "k", f"[study.variables.{k}]")) for k, v in variables.items()
              if isinstance(v, dict) and v.get("distribution") == "fisher"}
    rest = {k: v for k, v in variables.items() if k not in fisher}
    parsed, corr = variables_from_mapping(dict(rest, correlation=correlation) if correlation else rest)
    ordered = {k: fisher[k] if k in fisher else parsed[k] for k in variables}       # the file's order
    out = dict(variables=ordered, correlation=corr or None, n=int(s.pop("n", 10000)),
               sampling=s.pop("sampling", Sampling.MONTE_CARLO.value), seed=int(s.pop("seed", 0)),
               min_volume=float(s.pop("min_volume", 0.0)))
    if s:
        raise ValueError(f"[study] has unknown keys {sorted(s)}")
    return out


def run(args, out=None) -> int:
    """Run ``kgm wedge`` (its arguments parsed by `add_parser`'s parser)."""
    out = out or sys.stdout
    from .slope import wedge

    try:
        spec = read_input(args.input)
        outputs = dict(spec["output"])
        for name in OUTPUTS:
            if getattr(args, name, None):
                outputs[name] = getattr(args, name)
        w = wedge(**spec["wedge"])
        print(w.summary(), file=out)
        if w.forms:
            for label, area in w.areas.items():
                u = w.water_pressure.get(label)
                print(f"  {label}: area {area:.4g} m²" + (f", water {u:.4g} Pa" if u else "")
                      + (f", normal force {w.normal_force_on[label]:.4g} N" if label in w.normal_force_on else ""),
                      file=out)
            print(f"  line of intersection {w.intersection[1]:.2f}°/{w.intersection[0]:.2f}°; "
                  f"if released: {w.acceleration:.3g} m/s²", file=out)
            if spec["support"] is not None:
                s = w.required_support(spec["support"])
                print(f"support for FS {s.fs:g}: anchor {s.force:.4g} N plunging {s.plunge:.2f}° towards "
                      f"{s.trend:.2f}°, or a face pressure of {s.pressure:.4g} Pa", file=out)
        for p in w.pyramids:
            print(f"  joint pyramid {p.name}: {p.kind}", file=out)
        if spec["study"] is not None:
            from .study import wedge_study

            st = dict(spec["study"])
            if args.n is not None:
                st["n"] = args.n
            if args.seed is not None:
                st["seed"] = args.seed
            study = wedge_study(spec["wedge"], st.pop("variables"), st.pop("n"), out=outputs.get("csv"), **st)
            print(study.summary(), file=out)
            q = study.fs_quantiles()
            print("FS quantiles 5/50/95 % of the wedges: " + ", ".join(f"{v:.3f}" for v in q.values()), file=out)
            if study.reasons():
                print("no wedge: " + ", ".join(f"{k} {v}" for k, v in study.reasons().items()), file=out)
            if outputs.get("csv"):
                print(f"wrote {outputs['csv']}", file=out)
        elif outputs.get("csv"):
            raise ValueError("--csv writes the samples of a study: the file has no [study]")
        for name, method in (("png", "write_png"), ("stereonet", "stereonet"), ("vtp", "write_vtp")):
            if outputs.get(name):
                if w.block is None and name != "stereonet":
                    raise ValueError(f"no wedge to draw ({w.reason})")
                getattr(w, method)(outputs[name])
                print(f"wrote {outputs[name]}", file=out)
        if outputs.get("gif"):
            if w.block is None:
                raise ValueError(f"no wedge to draw ({w.reason})")
            w.write_gif(outputs["gif"], frames=args.frames)
            print(f"wrote {outputs['gif']}", file=out)
    except (ValueError, RuntimeError) as exc:
        print(f"kgm wedge: error: {exc}", file=sys.stderr)
        return 2
    return 0
