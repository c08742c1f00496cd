"""Scene scripts: the one loader of ``ddatai run``, ``kgm analyze`` and the benchmarks.

A scene script is a Python file that defines ``build(**options)`` returning a `ddatai.Scene`,
or ``(scene, params)`` with a `ddatai.Params`, and optionally ``DURATION``, the simulated time
of a run [s] (``ddatai run --duration`` or ``--steps`` replaces it; ``kgm`` does not use it).
The script may import modules beside it and, when it sits in a package folder (``scenes/``),
its package (``from scenes import example_2``).

Every mistake in a script is a `SceneFileError` (a `ValueError`) whose message is one line:
the file, and what is wrong (missing file, no ``build``, an exception inside the script with
its line, a ``build`` that returns something else).
"""

from __future__ import annotations

import importlib.util
import math
import sys
import traceback
import types
from dataclasses import dataclass
from pathlib import Path
from types import ModuleType
from typing import Any, Callable, Optional

from ..params import Params
from ..scene import Scene
from .dxf import read_dxf, read_joints_file


class SceneFileError(ValueError):
    """A scene script that cannot be loaded or built (one-line message)."""


@dataclass(frozen=True, kw_only=True)
class SceneScript:
    """A loaded scene script."""

    path: Path
    """The file."""
    name: str
    """Its stem (the name of the run's outputs)."""
    build: Callable[..., Any]
    """Its ``build`` function (use `build_scene` to call it)."""
    duration: Optional[float]
    """Its ``DURATION`` [s], or None when it defines none."""
    module: ModuleType
    """The executed module."""


def _where(err: BaseException, path: Path) -> str:
    """" (line N)" of the deepest frame of ``err`` inside ``path``, or of a syntax error."""
    if isinstance(err, SyntaxError) and err.lineno:
        return f" (line {err.lineno})"
    line = None
    for frame in traceback.extract_tb(err.__traceback__):
        if Path(frame.filename).resolve() == path.resolve():
            line = frame.lineno
    return f" (line {line})" if line else ""


def _script_paths(path: Path) -> list[str]:
    # the script's folder (modules beside it) and the folder above it (its package)
    here = path.resolve().parent
    return [str(here), str(here.parent)]


def load_scene_script(path, joints=None) -> SceneScript:
    """Execute a scene script and return its ``build`` and ``DURATION``. A DXF section
    (``.dxf``) with its TOML ``joints`` file is read by `dxf_scene_script`."""
    path = Path(path)
    if not path.is_file():
        raise SceneFileError(f"no such scene file: {path}")
    if path.suffix.lower() == ".dxf":
        return dxf_scene_script(path, joints)
    if path.suffix != ".py":
        raise SceneFileError(f"{path}: a scene script is a Python file (.py)")
    spec = importlib.util.spec_from_file_location(f"_ddatai_scene_{path.stem}", path)
    module = importlib.util.module_from_spec(spec)
    added = _script_paths(path)
    sys.path[:0] = added
    try:
        spec.loader.exec_module(module)
    except Exception as err:  # noqa: BLE001 - any mistake in the user's script
        raise SceneFileError(f"{path}{_where(err, path)}: {type(err).__name__}: {err}") from err
    finally:
        for p in added:
            if p in sys.path:
                sys.path.remove(p)
    build = getattr(module, "build", None)
    if not callable(build):
        raise SceneFileError(f"{path} defines no build() (a scene script defines build() returning a Scene "
                             f"or (scene, params), and optionally DURATION in seconds)")
    duration = getattr(module, "DURATION", None)
    if duration is not None:
        if not (isinstance(duration, (int, float)) and math.isfinite(duration) and duration > 0):
            raise SceneFileError(f"{path}: DURATION must be a number of seconds > 0, got {duration!r}")
        duration = float(duration)
    return SceneScript(path=path, name=path.stem, build=build, duration=duration, module=module)


def build_scene(build, **options) -> tuple:
    """Call a scene's ``build(**options)`` (a `SceneScript`, a module or the function) and return
    ``(scene, params)``, params None when ``build`` returns only the scene."""
    path = None
    if isinstance(build, SceneScript):
        path, build = build.path, build.build
    elif isinstance(build, ModuleType):
        path, build = Path(getattr(build, "__file__", build.__name__)), getattr(build, "build")
    where = str(path) if path is not None else getattr(build, "__qualname__", "build")
    added = _script_paths(path) if path is not None else []
    sys.path[:0] = added
    try:
        built = build(**options)
    except Exception as err:  # noqa: BLE001 - a mistake in the scene (the traceback is kept as the cause)
        line = _where(err, path) if path is not None else ""
        raise SceneFileError(f"{where}{line}: build() failed: {type(err).__name__}: {err}") from err
    finally:
        for p in added:
            if p in sys.path:
                sys.path.remove(p)
    if isinstance(built, Scene):
        return built, None
    if isinstance(built, tuple) and built and isinstance(built[0], Scene):
        params = built[1] if len(built) > 1 else None
        if params is not None and not isinstance(params, Params):
            raise SceneFileError(f"{where}: build() returned ({type(params).__name__}) as its parameters; "
                                 f"expected a ddatai.Params or None")
        return built[0], params
    raise SceneFileError(f"{where}: build() returned {type(built).__name__}; expected a Scene or (scene, params)")


def dxf_scene_script(path, joints_file) -> SceneScript:
    """A `SceneScript` for a DXF section and its joints file: what ``ddatai
    run section.dxf --joints joints.toml`` and ``kgm analyze`` run."""
    path = Path(path)
    if joints_file is None:
        raise SceneFileError(f"{path}: a DXF section needs its joints file, --joints JOINTS.toml (the material "
                             f"and the properties of each joint layer)")
    try:
        options = read_joints_file(joints_file)
    except ValueError as err:
        raise SceneFileError(str(err)) from None
    duration = options.pop("duration", None)
    if duration is not None and not (isinstance(duration, (int, float)) and math.isfinite(duration) and duration > 0):
        raise SceneFileError(f"{joints_file}: duration must be a number of seconds > 0, got {duration!r}")

    def build():
        return read_dxf(path, **options)

    module = types.ModuleType(f"_ddatai_dxf_{path.stem}")
    module.build, module.DURATION, module.__file__ = build, duration, str(path)
    return SceneScript(path=path, name=path.stem, build=build,
                       duration=None if duration is None else float(duration), module=module)
