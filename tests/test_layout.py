"""The package layout tells the architecture (ddatai/__init__.py draws it): the import graph of
ddatai and kgm has no cycle, the engine never imports a reader/writer (`ddatai.io`) or kgm, and
the contact layout has one definition (`ddatai.layout`) that the Taichi kernels share.

Every import is counted, also those inside functions (they hide a cycle as well as any other)."""

from __future__ import annotations

import ast
import functools
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
#: the engine: what a simulation runs through
CORE = ("assembly", "backend", "contact_law", "contacts", "cutting", "diagnosis", "energy", "fused", "geometry", "iterative", "kernels",
        "batch_detect", "limit_batch", "limit_equilibrium", "mechanisms", "return_mapping", "return_steps",
        "reassembly", "recorder", "records",
        "kinematics", "layout", "model", "model_checks", "narrow", "open_close", "params", "reference", "results", "scene",
        "solver", "pardiso", "updates", "start", "welded", "step", "support", "threads", "time_step", "water")
#: engine modules that reach an adapter only inside one public convenience method, by design
ALLOWED = {("results", "io.vtk")}  # Results.to_vtk


def _module(path: Path) -> str:
    rel = path.relative_to(ROOT).with_suffix("")
    parts = list(rel.parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts)


@functools.lru_cache(maxsize=None)
def _kgm_exports() -> dict[str, str]:
    """kgm's public names and the modules that define them (the lazy map of kgm/__init__.py),
    read from its source: ``from kgm import analyze`` imports `kgm.analysis`."""
    tree = ast.parse((ROOT / "kgm" / "__init__.py").read_text(encoding="utf-8"))
    for node in tree.body:
        if isinstance(node, ast.Assign) and any(isinstance(t, ast.Name) and t.id == "_EXPORTS" for t in node.targets):
            return {k: f"kgm.{v}" for k, v in ast.literal_eval(node.value).items()}
    raise AssertionError("kgm/__init__.py has no _EXPORTS map")


def _imported_by_name(node: ast.Call, package: list[str]):
    """The module an ``importlib.import_module(NAME[, PACKAGE])`` call imports: its name, None
    where the call is not one, or "?" where the name is computed."""
    func = node.func
    name = func.attr if isinstance(func, ast.Attribute) else getattr(func, "id", None)
    if name != "import_module" or not node.args:
        return None
    arg = node.args[0]
    if not (isinstance(arg, ast.Constant) and isinstance(arg.value, str)):
        return "?"
    target = arg.value
    if target.startswith("."):
        level = len(target) - len(target.lstrip("."))
        anchor = node.args[1] if len(node.args) > 1 else None
        pkg = str(anchor.value).split(".") if isinstance(anchor, ast.Constant) else package
        target = ".".join(pkg[:len(pkg) - level + 1] + [target.lstrip(".")])
    return target


@functools.lru_cache(maxsize=None)
def _imports(path: Path) -> frozenset[str]:
    """The ddatai / kgm modules ``path`` imports (absolute names): import statements (those
    inside functions too), ``importlib.import_module`` of a written name, and the package's
    names reached through it (``from kgm import analyze``, ``import kgm; kgm.analyze``); a
    computed name is "?" (only the lazy maps may import by one)."""
    here = _module(path)
    package = here.split(".") if path.name == "__init__.py" else here.split(".")[:-1]
    tree = ast.parse(path.read_text(encoding="utf-8"))
    out = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom):
            if node.level:
                base = package[:len(package) - node.level + 1]
                name = ".".join(base + ([node.module] if node.module else []))
            else:
                name = node.module or ""
            targets = [name] + [f"{name}.{a.name}" for a in node.names]
        elif isinstance(node, ast.Import):
            targets = [a.name for a in node.names]
        elif isinstance(node, ast.Call) and (name := _imported_by_name(node, package)) is not None:
            if name == "?":
                out.add("?")
            targets = [name]
        elif isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name) and node.value.id == "kgm":
            targets = [f"kgm.{node.attr}"]  # kgm.analyze(...) after ``import kgm``
        else:
            continue
        out |= {t for t in targets if t.split(".")[0] in ("ddatai", "kgm")}
    if here.startswith("kgm.") or here == "kgm":
        exports = _kgm_exports()
        out = {exports.get(t.removeprefix("kgm."), t) if t.count(".") == 1 else t for t in out}
    return frozenset(out)


def _graph() -> dict[str, set[str]]:
    files = sorted(ROOT.glob("ddatai/**/*.py")) + sorted(ROOT.glob("kgm/**/*.py"))
    modules = {_module(f): f for f in files}
    graph = {}
    for name, path in modules.items():
        # an imported name resolves to the deepest module that exists (from .x import y: x.y or x)
        edges = set()
        for t in _imports(path) - {"?"}:
            while t and t not in modules:
                t = t.rpartition(".")[0]
            if t and t != name and t not in ("ddatai", "kgm"):
                edges.add(t)
        graph[name] = edges
    return graph


def test_no_import_cycle():
    graph = _graph()
    state: dict[str, int] = {}
    cycles = []

    def visit(node, stack):
        state[node] = 1
        for nxt in sorted(graph.get(node, ())):
            if state.get(nxt) == 1:
                cycles.append(stack[stack.index(nxt):] + [nxt])
            elif nxt not in state:
                visit(nxt, stack + [nxt])
        state[node] = 2

    for node in sorted(graph):
        if node not in state:
            visit(node, [node])
    assert not cycles, "import cycles:\n" + "\n".join(" -> ".join(c) for c in cycles)


def test_the_engine_imports_no_adapter_and_no_kgm():
    graph = _graph()
    assert set(graph) >= {f"ddatai.{m}" for m in CORE}, "a core module is missing from the layout list"
    tools = ("ddatai.io", "kgm", "ddatai.cli", "ddatai.run", "ddatai.render", "ddatai.sweep")
    bad = [(m, t) for m in CORE for t in graph[f"ddatai.{m}"]
           if any(t == x or t.startswith(x + ".") for x in tools)   # a package and its modules
           and (m, t.removeprefix("ddatai.")) not in ALLOWED]
    assert not bad, "engine modules importing adapters, tools or kgm: " + ", ".join(f"{m} -> {t}" for m, t in bad)


def test_ddatai_never_imports_kgm():
    graph = _graph()
    bad = [(m, t) for m, ts in graph.items() if m.startswith("ddatai") for t in ts if t.startswith("kgm")]
    assert not bad, bad


def test_kernels_share_the_contact_layout():
    """The Taichi kernels spell the layout as plain integers (a @ti.func cannot read an enum):
    they must equal `ddatai.layout`'s."""
    from ddatai import layout

    text = (ROOT / "ddatai" / "kernels" / "common.py").read_text(encoding="utf-8")
    tree = ast.parse(text)
    values = {}
    for node in tree.body:
        if isinstance(node, ast.Assign):
            try:
                value = ast.literal_eval(node.value)
            except ValueError:
                continue
            names = [t.id for t in node.targets if isinstance(t, ast.Name)]
            tuples = [t for t in node.targets if isinstance(t, ast.Tuple)]
            for name in names:
                values[name] = value
            for t in tuples:
                for el, v in zip(t.elts, value):
                    values[el.id] = v
    assert values["KIND_VE"] == layout.VE and values["KIND_VV"] == layout.VV
    assert (values["STATE_OPEN"], values["STATE_SLIDE"], values["STATE_LOCK"]) == (layout.OPEN, layout.SLIDE, layout.LOCK)
    assert [values[k] for k in ("E0", "G0", "E1", "G1", "ES", "GS")] == [layout.S_E0, layout.S_G0, layout.S_E1,
                                                                      layout.S_G1, layout.S_ES, layout.S_GS]
    assert values["N_SLOTS"] == layout.N_SLOTS
    # the memory rows that the narrow phase searches: the kernel path's and the fused engine's
    from ddatai.fused import layout as fused

    assert (values["MEM_KIND"], values["MEM_V0"], values["MEM_K2"]) == (fused.MEMI_KIND, fused.MEMI_V0, fused.MEMI_K2)


def _core_files():
    """The engine's source files: a module, or every module of a package (`ddatai.kernels`)."""
    for m in CORE:
        path = ROOT / "ddatai" / f"{m}.py"
        yield from ([path] if path.exists() else sorted((ROOT / "ddatai" / m).glob("*.py")))


#: no module anywhere in ddatai (its subpackages included) over this many lines
DDATAI_MAX_LINES = 500


def _line_counts(pattern: str) -> dict[str, int]:
    return {str(p.relative_to(ROOT)): len(p.read_text(encoding="utf-8").splitlines())
            for p in sorted(ROOT.glob(pattern))}


def test_ddatai_modules_stay_short():
    """One concern a module: no ddatai module over ~500 lines, in any subpackage (readers and
    writers, kernels, the fused engine, rendering); a longer one is split along its seams."""
    sizes = _line_counts("ddatai/**/*.py")
    assert {"ddatai/step.py", "ddatai/io/ntdda/geometry.py", "ddatai/kernels/common.py"} <= set(sizes)
    long = {f: n for f, n in sizes.items() if n > DDATAI_MAX_LINES}
    assert not long, f"ddatai modules over {DDATAI_MAX_LINES} lines: " + ", ".join(
        f"{f} ({n} lines)" for f, n in long.items())


def test_core_modules_stay_short():
    """One concern a module: no engine module over ~450 lines (the NumPy reference of the
    kernels excepted)."""
    long = {str(f.relative_to(ROOT)): n for f in _core_files() if f.stem != "reference"
            and (n := len(f.read_text(encoding="utf-8").splitlines())) > 470}
    assert not long, long


# ---------------------------------------------------------------------- kgm
#: kgm's modules in layers, lowest first (docs/kgm/architecture.md): a module imports only
#: modules of lower layers, so data flows one way
KGM_LAYERS = (
    ("kinds", "wedges.geometry", "wedges.vtk"),         # the vocabulary
    ("settings", "strength", "wedges.block_theory", "wedges.batched_geometry", "wedges.pictures"),
    ("system", "wedges.mechanics"),                     # the block system
    ("build", "faces", "wedges.block", "wedges.batched"),  # Scene -> system, the Problem; group faces
    ("candidates", "wedges.slope"),                     # key blocks, groups, toppling rows
    ("judges.evaluation", "judges.limits"),             # the judges ...
    ("judges.mechanisms", "judges.toppling", "judges.run", "judges.turning"),
    ("judges.fused",),                                  # ... DDA runs on the fused engine ...
    ("judges.rigid", "judges.batch"),
    ("judges.sarma", "judges.dda"),
    ("search",),                                        # greedy growth, enumeration
    ("report",),                                        # GroupResult, Report, tables
    ("analysis",),                                      # the entry points
    # small probabilities of failure: the estimators (pure numerics), their pictures and their
    # outcome in a study's terms, below the study; the study's subset and importance sampling
    # below kgm.probabilistic, which hands them its sample runner
    ("studies.reliability",),
    ("studies.estimates", "studies.plots"),
    ("studies.sampling", "studies.study"),              # studies over many analyses
    ("studies.rare",),
    ("studies.probabilistic", "wedges.study"),
    ("wedges.cli",),
    ("cli",),                                           # the kgm command
    # former homes, re-exporting their names for one release: nothing in kgm imports them
    ("blocks", "toppling", "evaluators", "judgement", "batched", "dda", "probability"),
)
#: the judges take values and return values, and never reach the search, the analyses built on
#: it, the studies or the command lines (nor the former homes of the search and the study)
KGM_ABOVE_JUDGES = ("search", "report", "analysis", "studies", "cli", "wedges.study", "wedges.cli", "probability")
#: the modules that may import a module by a computed name: the lazy maps of public names
KGM_LAZY_MAPS = ("kgm", "kgm.search")
#: no kgm module over this many lines (one concern a module) ...
KGM_MAX_LINES = 500
#: ... except these, each to be split along its banners, which must not grow meanwhile
KGM_OVERSIZE: dict = {}


def _kgm_modules() -> dict[str, Path]:
    """kgm's modules (kgm.judges.sarma as 'judges.sarma'), without the packages' maps."""
    return {_module(p).removeprefix("kgm."): p for p in sorted(ROOT.glob("kgm/**/*.py"))
            if p.name != "__init__.py"}


def test_kgm_subpackages_are_maps():
    """A subpackage's __init__ is its map (a docstring): it imports nothing, so importing one
    module of it does not load the others."""
    graph = _graph()
    busy = {_module(p): graph[_module(p)] for p in ROOT.glob("kgm/*/__init__.py") if graph[_module(p)]}
    assert not busy, busy


def test_kgm_layers_list_every_module_once():
    listed = [m for layer in KGM_LAYERS for m in layer]
    assert len(listed) == len(set(listed)), "a kgm module is listed twice"
    assert set(listed) == set(_kgm_modules()), (
        f"kgm modules not in KGM_LAYERS: {sorted(set(_kgm_modules()) - set(listed))}; "
        f"listed but missing: {sorted(set(listed) - set(_kgm_modules()))}")


def test_kgm_imports_go_down_the_layers():
    graph = _graph()
    level = {f"kgm.{m}": i for i, layer in enumerate(KGM_LAYERS) for m in layer}
    # a subpackage's __init__ (its map) is at the level of its lowest module
    for name in list(level):
        parts = name.split(".")
        for k in range(2, len(parts)):
            pkg = ".".join(parts[:k])
            level[pkg] = min(level.get(pkg, level[name]), level[name])
    bad = [f"{m} -> {t}" for m, ts in graph.items() if m in level for t in ts
           if t.startswith("kgm.") and t in level and level[t] >= level[m] and not t.startswith(m + ".")]
    assert not bad, "kgm imports that do not go down the layers: " + ", ".join(sorted(bad))


def test_judges_never_import_search_studies_or_the_command_line():
    graph = _graph()
    judges = {m for m in _kgm_modules() if m.startswith("judges.")}
    assert judges
    above = tuple(f"kgm.{m}" for m in KGM_ABOVE_JUDGES)
    bad = [f"kgm.{m} -> {t}" for m in sorted(judges) for t in sorted(graph[f"kgm.{m}"])
           if any(t == a or t.startswith(a + ".") for a in above)]
    assert not bad, "judges importing what stands above them: " + ", ".join(bad)


def test_kgm_imports_by_computed_names_are_the_lazy_maps():
    """An import by a computed name escapes the checks above: only the lazy maps of public
    names (kgm's, and the search's former names) make one."""
    found = sorted(_module(p) for p in ROOT.glob("kgm/**/*.py") if "?" in _imports(p))
    assert set(found) <= set(KGM_LAZY_MAPS), f"kgm modules importing by a computed name: {found}"
    # and nothing in kgm takes a former name of the search from it (it would reach up)
    from kgm.search import FORMER_NAMES

    uses = sorted(f"{_module(p)} -> {t}" for p in ROOT.glob("kgm/**/*.py") for t in _imports(p)
                  if t.startswith("kgm.search.") and t.removeprefix("kgm.search.") in FORMER_NAMES)
    assert not uses, "former names of kgm.search used inside kgm: " + ", ".join(uses)


def test_kgm_modules_stay_short():
    """One concern a module: no kgm module (the packages' maps included) over ~500 lines."""
    sizes = {_module(p): len(p.read_text(encoding="utf-8").splitlines()) for p in ROOT.glob("kgm/**/*.py")}
    sizes = {m.removeprefix("kgm.") or m: n for m, n in sizes.items()}
    long = {m: n for m, n in sizes.items() if n > KGM_OVERSIZE.get(m, KGM_MAX_LINES)}
    assert not long, f"kgm modules over {KGM_MAX_LINES} lines: {long}"
    split = [m for m in KGM_OVERSIZE if sizes.get(m, 0) <= KGM_MAX_LINES]
    assert not split, f"modules now short enough to leave KGM_OVERSIZE: {split}"


def test_kgm_words_have_one_home():
    """The method names, the sampling schemes and how a DDA run ends are members of
    `kgm.kinds`; no other kgm module spells them as string literals (a comparison with a
    misspelt literal would be silently false)."""
    from kgm import kinds

    words = {w.value for enum in (kinds.Method, kinds.Sampling, kinds.RunEnd) for w in enum}
    assert {"rigid", "sarma", "dda"} <= words
    found = []
    for path in sorted(ROOT.glob("kgm/**/*.py")):
        if _module(path) == "kgm.kinds":
            continue
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Constant) and isinstance(node.value, str) and node.value in words:
                found.append(f"{path.relative_to(ROOT)}:{node.lineno} {node.value!r}")
    assert not found, "vocabulary spelt outside kgm.kinds: " + ", ".join(found)
