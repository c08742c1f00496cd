"""Behaviour fingerprint of kgm: run a fixed set of analyses and record every value they
return, to check that a restructuring of the package changes nothing (as
``benchmarks/behaviour.py`` does for the engine).

    python benchmarks/kgm_behaviour.py record FILE [--no-dda] [--only REGEX]   # run the set, write FILE
    python benchmarks/kgm_behaviour.py compare A B [--subset]   # every case of A and B identical?

The set:

* every scene script in ``scenes/``: `kgm.analyze` under 'rigid', 'sarma' and 'dda' (with the
  script's Params; a refused scene records its error), and progressive 'rigid' and 'sarma' for
  the scenes of up to 63 blocks;
* the examples of ``benchmarks/kgm_examples.py``: Example I and II and the jointed slope (the
  critical group of the Sarma search, `kgm.evaluate` under the three methods, and
  `kgm.factor_of_safety` / `kgm.critical_friction` under each), the footwall cases (their
  groups under the three methods), `kgm.exhaustive` of the small scenes;
* probabilistic studies (`kgm.probabilistic`): Example II's group {0, 1} judged by DDA over 200
  samples (``docs/kgm/example_2_vars.toml``, the study of ``benchmarks/probabilistic.py``), the
  same with the search in every sample (20 samples) and with DDA's FS (8 samples, one worker), a
  Sarma study of 200 samples with the search in every sample written to its CSV file and
  resumed from it, a Latin-hypercube rigid study; every table, summary and CSV file byte;
* the ``kgm`` command: ``analyze`` of Example I (dda, ``--compare``) and Example II (sarma,
  ``--progressive``) and ``probabilistic`` of Example II (rigid), stdout and stderr with wall
  times masked; the GIF of a DDA analysis (the arrays of its run).

The record of the code before kgm was laid out as a pipeline (docs/kgm/architecture.md) is
``benchmarks/results/kgm_behaviour.jsonl.gz`` (a name ending in .gz is read and written
compressed); the layout's record is identical to it bit for bit.

Every value is written exactly (floats by ``repr``, which round-trips), one case a line; wall
times are left out. Fields are recorded by name, the fields the result types had when the
recorder was written, so a field added later does not change the record. ``--no-dda`` leaves out
every case that runs DDA, and the Sarma search of the 141-block jointed slope (minutes): a
quick check after each move; ``--only REGEX`` runs the cases whose names match (e.g. the DDA
cases of Example I: ``--only 'example_1.*dda'``). ``compare``
prints each case that differs (the first differing value) and exits 1 if any does, or if a case
is only in one file (unless ``--subset``: then only the cases of both are compared).
"""

from __future__ import annotations

import contextlib
import dataclasses
import gzip
import hashlib
import io
import json
import math
import re
import sys
import tempfile
import time
from enum import Enum
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT)]

METHODS = ("rigid", "sarma", "dda")
SMALL = ("example_1", "example_2", "toppling", "sliding_block", "footwall")
#: scenes analysed progressively too (a progressive search of the large ones takes minutes)
PROGRESSIVE = SMALL + ("bolted_slope", "kgm_slope")
#: scenes whose Sarma search takes minutes (the quick record leaves it out, as DDA)
SLOW_SARMA = ("jointed_slope",)
VARS = ROOT / "docs" / "kgm" / "example_2_vars.toml"

# ---------------------------------------------------------------------- exact values
#: the fields recorded of each result type (by class name, wherever it is defined)
FIELDS = {
    "Mode": ("kind", "fs", "critical_friction", "sliding_contacts", "sheared_contacts", "direction", "pivot",
             "block_velocity", "critical_acceleration", "block_modes"),
    "BlockStep": ("block", "state", "force_above", "force_toppling", "force_sliding", "force_below", "height",
                  "contact_above", "contact_below", "base_dip"),
    "GroupResult": ("blocks", "fs", "critical_friction", "stable", "mode", "surface", "evaluator", "seed",
                    "iteration", "dda", "water_force", "bolt_force", "seismic", "modes", "rejected", "verdict",
                    "block_modes", "critical_acceleration"),
    "DdaEvaluation": ("fs", "critical_friction", "judgement", "runs", "timing"),
    "DdaJudgement": ("stable", "displacement", "speed", "threshold", "duration", "simulated", "steps", "friction",
                     "reduction", "model_blocks", "moving_blocks", "scene_blocks", "note", "batch"),
    "DdaTiming": ("steps", "sub_blocks", "whole_blocks"),
    "Report": ("method", "critical", "groups", "block_types", "history", "removed", "failure_surface", "fs_target"),
    "Study": ("n", "pf", "beta", "table", "variables", "method", "sampling", "seed", "resumed"),
}


def exact(v):
    """A JSON value that is equal for two inputs if and only if they are identical."""
    if v is None or isinstance(v, (bool, np.bool_)):
        return None if v is None else bool(v)
    if isinstance(v, Enum):
        return exact(v.value)
    if isinstance(v, str):
        return str(v)
    if isinstance(v, (int, np.integer)):
        return int(v)
    if isinstance(v, (float, np.floating)):
        return "f" + repr(float(v))
    if isinstance(v, np.ndarray):
        if v.dtype.names:
            return {"dtype": str(v.dtype), **{k: exact(v[k]) for k in v.dtype.names}}
        return {"dtype": str(v.dtype), "shape": list(v.shape), "data": exact(v.tolist())}
    if isinstance(v, (frozenset, set)):
        return sorted(exact(x) for x in v)
    if isinstance(v, (list, tuple)):
        return [exact(x) for x in v]
    if isinstance(v, dict):
        return {json.dumps(exact(k)): exact(x) for k, x in sorted(v.items(), key=lambda kv: repr(kv[0]))}
    name = type(v).__name__
    if name in FIELDS:
        out = {"type": name}
        for f in FIELDS[name]:
            out[f] = exact(getattr(v, f))
        if name == "GroupResult":
            out["explain"] = v.explain()
        if name == "Report":
            out["table"] = v.table()
        if name == "DdaEvaluation":
            out["bracket_fs"] = exact(v.bracket("fs"))
            out["bracket_friction"] = exact(v.bracket("friction"))
        if name == "Study":
            out["summary"] = v.summary()
            out["block_frequency"] = exact(v.block_frequency())
            out["fs_quantiles"] = exact(v.fs_quantiles())
            out["pf_interval"] = exact(v.pf_interval())
            out["beta_pf"] = exact(v.beta_pf)
        return out
    if dataclasses.is_dataclass(v):
        raise TypeError(f"no field list for {name}: add it to FIELDS")
    raise TypeError(f"cannot record a {type(v).__name__}")


def attempt(fn):
    """fn()'s value, or the error it raises (its type and message)."""
    try:
        return fn()
    except Exception as exc:  # a refused scene: its message is behaviour too
        return {"error": f"{type(exc).__name__}: {exc}"}


# ---------------------------------------------------------------------- the cases
def _scenes():
    from ddatai.io.scenefile import build_scene, load_scene_script

    for path in sorted((ROOT / "scenes").glob("*.py")):
        if path.name.startswith("_"):
            continue
        try:
            scene, params = build_scene(load_scene_script(path))
        except ImportError as err:  # an optional extra (the DXF section needs ezdxf)
            print(f"skip {path.stem}: {err}", file=sys.stderr)
            continue
        yield path.stem, scene, params


def scene_cases(dda: bool):
    import kgm

    for name, scene, params in _scenes():
        for method in METHODS:
            heavy = method == "dda" or (method == "sarma" and name in SLOW_SARMA)
            if heavy and not dda:
                continue
            yield (f"analyze {name} {method}", heavy,
                   lambda s=scene, m=method, p=params: attempt(lambda: kgm.analyze(s, method=m, params=p)))
        for method in METHODS[:2] if name in PROGRESSIVE else ():
            yield (f"analyze {name} {method} progressive", False,
                   lambda s=scene, m=method: attempt(lambda: kgm.analyze(s, method=m, progressive=True)))
        if name in SMALL:
            for method in METHODS[:2]:
                yield (f"exhaustive {name} {method}", False,
                       lambda s=scene, m=method: attempt(lambda: kgm.exhaustive(s, m, max_size=3)))
            yield (f"classify {name}", False, lambda s=scene: attempt(
                lambda: kgm.classify_blocks(kgm.build_block_system(s))))


def example_cases(dda: bool):
    import kgm
    from ddatai.io.scenefile import build_scene
    from scenes import example_1, example_2, footwall, kgm_slope

    for name, mod in (("example_1", example_1), ("example_2", example_2), ("kgm_slope", kgm_slope)):
        scene, params = build_scene(mod)
        group = kgm.analyze(scene, method="sarma").critical.blocks
        for method in METHODS if dda else METHODS[:2]:
            yield (f"evaluate {name} {sorted(group)} {method}", method == "dda",
                   lambda s=scene, g=group, m=method, p=params: kgm.evaluate(s, g, m, params=p))
            if name != "kgm_slope":
                yield (f"factor_of_safety {name} {sorted(group)} {method}", method == "dda",
                       lambda s=scene, g=group, m=method, p=params: kgm.factor_of_safety(s, g, m, params=p))
                yield (f"critical_friction {name} {sorted(group)} {method}", method == "dda",
                       lambda s=scene, g=group, m=method, p=params: kgm.critical_friction(s, g, m, params=p))
    for case in footwall.CASES:
        scene, params = footwall.build(case)
        group = [footwall.SLAB] if case == "planar" else [footwall.P, footwall.A]
        for method in METHODS if dda else METHODS[:2]:
            yield (f"evaluate footwall {case} {method}", method == "dda",
                   lambda s=scene, g=group, m=method, p=params: kgm.evaluate(s, g, m, params=p))
    scene, params = build_scene(example_2)
    yield ("evaluate example_2 seismic sarma", False,
           lambda: kgm.evaluate(scene, {0, 1}, "sarma", seismic=(0.1, 0.05)))


def study_cases(dda: bool):
    import kgm
    from kgm.probability import read_variables

    variables, correlation = read_variables(VARS)
    build = str(ROOT / "scenes" / "example_2.py")

    def study(**kw):
        s = kgm.probabilistic(build, variables, correlation=correlation, **kw)
        with tempfile.TemporaryDirectory() as tmp:
            path = s.to_csv(Path(tmp) / "study.csv")
            return {"study": exact(s), "csv": path.read_text(), "read": exact(kgm.read_study(path))}

    def resumed():
        with tempfile.TemporaryDirectory() as tmp:
            out = Path(tmp) / "samples.csv"
            first = kgm.probabilistic(build, variables, 200, method="sarma", seed=2, correlation=correlation,
                                      out=out, workers=1)
            text = out.read_text()
            again = kgm.probabilistic(build, variables, 200, method="sarma", seed=2, correlation=correlation,
                                      out=out, workers=1)
            return {"first": exact(first), "file": text, "again": exact(again), "file_again": out.read_text()}

    yield "study example_2 sarma 200 search, file and resume", False, resumed
    yield ("study example_2 rigid 50 latin-hypercube", False,
           lambda: study(n=50, method="rigid", sampling="latin-hypercube", seed=5, workers=1))
    if dda:
        yield ("study example_2 dda 200 group {0, 1}", True,
               lambda: study(n=200, method="dda", seed=1, group={0, 1}))
        yield "study example_2 dda 20 search", True, lambda: study(n=20, method="dda", seed=3)
        yield ("study example_2 dda 8 group {0, 1} with FS", True,
               lambda: study(n=8, method="dda", seed=4, group={0, 1}, dda_fs=True, workers=1))


#: wall times in the command's output
_TIMES = [(re.compile(p), r) for p, r in (
    (r"analysis time [0-9.]+ s", "analysis time <t> s"),
    (r"\(comparison [0-9.]+ s\)", "(comparison <t> s)"),
    (r"runs, [0-9.]+ s;", "runs, <t> s;"),
    (r"steps, [0-9.]+ s\)", "steps, <t> s)"),
)]


def _masked(text: str) -> str:
    for pattern, repl in _TIMES:
        text = pattern.sub(repl, text)
    return text


def cli_cases(dda: bool):
    from kgm.cli import main

    def command(*argv):
        out, err = io.StringIO(), io.StringIO()
        with contextlib.redirect_stderr(err):
            code = main(list(argv), out=out)
        return {"code": code, "stdout": _masked(out.getvalue()), "stderr": _masked(err.getvalue())}

    ex1, ex2 = str(ROOT / "scenes" / "example_1.py"), str(ROOT / "scenes" / "example_2.py")
    yield "cli analyze example_2 sarma progressive", False, lambda: command("analyze", ex2, "--progressive")
    yield ("cli probabilistic example_2 rigid 50", False,
           lambda: command("probabilistic", ex2, "--vars", str(VARS), "--n", "50", "--method", "rigid",
                           "--seed", "3", "--workers", "1"))
    if dda:
        yield "cli analyze example_1 dda compare", True, lambda: command("analyze", ex1, "--method", "dda",
                                                                        "--compare")
        yield "cli gif example_1 dda", True, _gif_case


def _gif_case():
    """The arrays `kgm.cli.write_result_gif` draws for a DDA analysis of Example I (write_gif
    replaced by a recorder)."""
    import ddatai.render
    import kgm
    from kgm.cli import write_result_gif
    from scenes import example_1

    scene, params = example_1.build()
    settings = kgm.Settings()
    rep = kgm.analyze(scene, method="dda", settings=settings, params=params)
    seen = {}

    def fake(res, path, **kw):
        seen["arrays"] = {f.name: hashlib.sha256(np.ascontiguousarray(getattr(res, f.name)).tobytes()).hexdigest()
                          for f in dataclasses.fields(res)
                          if isinstance(getattr(res, f.name), np.ndarray) and not getattr(res, f.name).dtype.names}
        seen["frames"] = len(res.time)
        seen["kw"] = exact({k: v for k, v in kw.items()})

    real = ddatai.render.write_gif
    ddatai.render.write_gif = fake
    try:
        write_result_gif("unused.gif", scene, rep, params, settings)
    finally:
        ddatai.render.write_gif = real
    return seen


def cases(dda: bool):
    yield from scene_cases(dda)
    yield from example_cases(dda)
    yield from study_cases(dda)
    yield from cli_cases(dda)


# ---------------------------------------------------------------------- record and compare
def _open(path: Path, mode: str):
    """A record file, gzip-compressed when its name ends in .gz."""
    if path.suffix == ".gz":
        return gzip.open(path, mode + "t", encoding="utf-8")
    return open(path, mode, encoding="utf-8")


def record(path: Path, dda: bool, only: str = "") -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    t_all = time.perf_counter()
    with _open(path, "w") as fh:
        for name, heavy, fn in cases(dda):
            if only and not re.search(only, name):
                continue
            t0 = time.perf_counter()
            value = exact(fn())
            line = json.dumps({"case": name, "heavy": heavy, "value": value}, ensure_ascii=False, sort_keys=True)
            fh.write(line + "\n")
            fh.flush()
            digest = hashlib.sha256(line.encode()).hexdigest()[:12]
            print(f"{name}: {digest} ({time.perf_counter() - t0:.1f} s)", flush=True)
    print(f"recorded in {time.perf_counter() - t_all:.0f} s: {path}")


def _load(path: Path) -> dict:
    out = {}
    with _open(path, "r") as fh:
        lines = fh.read().splitlines()
    for line in lines:
        row = json.loads(line)
        out[row["case"]] = row
    return out


def _first_difference(a, b, where="") -> str:
    if type(a) is not type(b):
        return f"{where or '.'}: {str(a)[:80]} / {str(b)[:80]}"
    if isinstance(a, dict):
        for k in sorted(set(a) | set(b)):
            if k not in a or k not in b:
                return f"{where}.{k}: only in one"
            if a[k] != b[k]:
                return _first_difference(a[k], b[k], f"{where}.{k}")
    if isinstance(a, list):
        if len(a) != len(b):
            return f"{where}: {len(a)} / {len(b)} entries"
        for i, (x, y) in enumerate(zip(a, b)):
            if x != y:
                return _first_difference(x, y, f"{where}[{i}]")
    return f"{where or '.'}: {str(a)[:80]} / {str(b)[:80]}"


def compare(a: Path, b: Path, subset: bool) -> int:
    x, y = _load(a), _load(b)
    both = [k for k in x if k in y]
    only = [k for k in list(x) + [k for k in y if k not in x] if (k in x) != (k in y)]
    differ = 0
    for k in both:
        if x[k]["value"] != y[k]["value"]:
            differ += 1
            print(f"DIFFERS {k}: {_first_difference(x[k]['value'], y[k]['value'])}")
    for k in only:
        print(f"only in {'the first' if k in x else 'the second'}: {k}")
    print(f"{len(both) - differ} of {len(both)} cases identical"
          + (f"; {len(only)} only in one file" if only else ""))
    return int(differ > 0 or (bool(only) and not subset))


if __name__ == "__main__":
    argv = sys.argv[1:]
    only = ""
    if "--only" in argv:
        i = argv.index("--only")
        only = argv[i + 1] if i + 1 < len(argv) else ""
        del argv[i:i + 2]
    args = [a for a in argv if not a.startswith("--")]
    flags = {a for a in argv if a.startswith("--")}
    if len(args) == 2 and args[0] == "record" and flags <= {"--no-dda"}:
        record(Path(args[1]), dda="--no-dda" not in flags, only=only)
    elif len(args) == 3 and args[0] == "compare" and flags <= {"--subset"}:
        raise SystemExit(compare(Path(args[1]), Path(args[2]), "--subset" in flags))
    else:
        raise SystemExit(__doc__)
