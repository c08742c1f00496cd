"""Command line: ``ddatai run SCENE.py`` (or ``ddatai run MODEL.geo MODEL.ana``).

    ddatai run SCENE.py [--duration S] [--steps N] [--every K] [--gif PATH] [--video PATH.mp4] [--out DIR]
                        [--contacts] [--size WxH] [--fps F] [--speed X] [--stride K]
                        [--arch cpu|gpu] [--checkpoint-every N] [--resume [PATH]] [--vtk DIR]
                        [--history X,Y ...] [--quiet] [--debug]

A scene script is a Python file defining ``build(**options)`` returning a Scene or
``(scene, params)``, and optionally ``DURATION`` (seconds; ``--duration`` or ``--steps``
replaces it), loaded by `ddatai.io.scenefile` like ``kgm`` loads it; ``python scenes/NAME.py
[options]`` runs the same way through `scene_main` (`run_as_script`). The options are checked before anything
is built; a user error (a bad option, a broken scene) prints one line and exits with status 2
(``--debug`` shows the traceback). The run shows a progress bar (simulated time, steps per
second), writes the results to ``DIR/NAME.npz`` (NAME: the GIF's name when ``--gif`` is given,
else the input's; an existing file is never overwritten: NAME-2.npz, ...), the GIF if ``--gif``
is given and the MP4 video if ``--video`` is (only then are imaging libraries imported), the
measured points' CSV
(``DIR/NAME_measured.csv``), a CSV per ``--history`` point, VTK files with ``--vtk`` and prints a
short summary. Ctrl-C saves what was recorded and a checkpoint (``DIR/NAME.checkpoint.npz``)
and exits with status 130.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from types import ModuleType
from typing import Callable, Optional, Sequence


def _size(text: str) -> tuple[int, int]:
    try:
        w, h = text.lower().split("x")
        return int(w), int(h)
    except ValueError:
        raise argparse.ArgumentTypeError(f"size must look like 640x480, got {text!r}") from None


def _point(text: str) -> tuple[float, float]:
    try:
        x, y = (float(v) for v in text.split(","))
        return x, y
    except ValueError:
        raise argparse.ArgumentTypeError(f"a point must look like 12.5,3, got {text!r}") from None


def _add_run_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("--duration", type=float, help="simulated time [s] (default: the scene's DURATION)")
    p.add_argument("--steps", type=int, help="stop after this many steps")
    p.add_argument("--every", type=int, default=None, help="record a frame every K steps")
    p.add_argument("--gif", type=Path, help="write an animated GIF here")
    p.add_argument("--video", type=Path, metavar="PATH.mp4",
                   help="write an MP4 video here (needs the [video] extra: imageio-ffmpeg); smaller and "
                        "sharper than a GIF for long runs; --size, --fps, --speed and --stride apply to it too")
    p.add_argument("--out", type=Path, default=Path("out"), help="directory for the results (.npz)")
    p.add_argument("--contacts", action="store_true", help="record contacts and draw them in the GIF")
    p.add_argument("--size", type=_size, default=(640, 480), help="GIF size, e.g. 640x480")
    p.add_argument("--fps", type=float, default=20.0, help="GIF frames per second (at most 50; a video's at most 120)")
    p.add_argument("--speed", type=float, default=1.0,
                   help="GIF playback speed: simulated seconds per second of animation (default 1: real time)")
    p.add_argument("--stride", type=int, default=None,
                   help="GIF: draw every K-th recorded frame, each for 1/fps s, instead of sampling time")
    p.add_argument("--arch", choices=("cpu", "gpu", "cuda"), default=None,
                   help="Taichi backend (default: the scene's Params)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.add_argument("--debug", action="store_true", help="show the traceback of an error")
    p.add_argument("--force", action="store_true",
                   help="build a model even when it looks larger than this machine can simulate")
    p.add_argument("--vtk", type=Path, metavar="DIR",
                   help="also write the frames as VTK files for ParaView (needs the [vtk] extra, meshio)")
    p.add_argument("--history", type=_point, action="append", metavar="X,Y",
                   help="write the history of the material point at (x, y) [m] to DIR/NAME_history_X_Y.csv "
                        "(repeatable)")
    p.add_argument("--checkpoint-every", type=int, default=None, metavar="N",
                   help="write a checkpoint every N steps to DIR/NAME.checkpoint.npz (Ctrl-C writes one too)")
    p.add_argument("--resume", nargs="?", type=Path, const=True, default=None, metavar="CHECKPOINT",
                   help="continue the run from a checkpoint (default DIR/NAME.checkpoint.npz) with "
                        "identical results")


class Progress:
    """One-line progress bar on stderr: simulated time, steps, steps per second."""

    def __init__(self, duration: Optional[float], steps: Optional[int], enabled: bool = True):
        self.duration, self.steps = duration, steps
        self.enabled = enabled
        self.start = time.perf_counter()
        self.last = 0.0
        self.next_line = 0.0
        self.n = 0      # steps taken by this call (the rate)
        self.step = 0   # steps of the run (a resumed run starts at its checkpoint's)

    def __call__(self, state, record) -> None:
        self.n += 1
        self.step = state.step
        now = time.perf_counter()
        if not self.enabled or now - self.last < 0.2:
            return
        self.last = now
        self._draw(state.time, now)

    def _draw(self, t: float, now: float, final: bool = False) -> None:
        if not sys.stderr.isatty() and not final and now - self.start < self.next_line:
            return  # not a terminal: a plain line every 10 s instead of a live bar
        self.next_line = now - self.start + 10.0
        if self.duration:
            frac = min(1.0, t / self.duration)
        elif self.steps:
            frac = min(1.0, self.step / self.steps)
        else:
            frac = 0.0
        bar = "#" * int(30 * frac) + "." * (30 - int(30 * frac))
        rate = self.n / max(now - self.start, 1e-9)
        total = f"/{self.duration:g}" if self.duration else ""
        end = " " if sys.stderr.isatty() else "\n"
        start = "\r" if sys.stderr.isatty() else ""
        sys.stderr.write(f"{start}[{bar}] t = {t:.4g}{total} s  {self.step} steps  {rate:.1f} steps/s{end}")
        sys.stderr.flush()

    def close(self, t: float) -> None:
        if self.enabled:
            self._draw(t, time.perf_counter(), final=True)
            if sys.stderr.isatty():
                sys.stderr.write("\n")


def load_scene_module(path: Path) -> ModuleType:
    """Import a scene script by path (`ddatai.io.scenefile.load_scene_script`)."""
    from .io.scenefile import load_scene_script

    return load_scene_script(path).module


def run_scene(build: Callable, duration: Optional[float], name: str, args: argparse.Namespace) -> int:
    """Build, simulate with a progress bar, save results (and GIF), print a summary. ``build``
    may return a Scene or (scene, params); ``duration`` (the script's DURATION) may be None
    when --duration or --steps is given."""
    import dataclasses

    from .params import Params
    from .io.scenefile import SceneFileError, build_scene

    if args.resume is None and args.duration is None and args.steps is None and duration is None:
        raise SceneFileError(f"{name} defines no DURATION: give --duration SECONDS or --steps N")
    scene, params = build_scene(build)
    params = params if params is not None else Params()
    for x, y in args.history or ():
        if not any(_covers(b.vertices, (x, y)) for b in scene.blocks):
            raise ValueError(f"--history {x:g},{y:g}: no block of {name} contains that point")
    if args.arch is not None:
        params = dataclasses.replace(params, arch=args.arch)
    duration = args.duration if args.duration is not None else duration
    if args.steps is not None:
        duration = args.duration  # --steps alone runs a number of steps
    return _simulate_and_report(scene, params, duration, args.steps, name, args)


def _covers(polygon, point) -> bool:
    import shapely

    return bool(shapely.Polygon(polygon).covers(shapely.Point(point)))


def check_options(args: argparse.Namespace) -> None:
    """Check the run options before anything is built or run; `ValueError` with one line."""
    import math

    from .render import check_gif_options

    def positive(name: str, value, integer: bool) -> None:
        if value is None:
            return
        if integer and not value >= 1:
            raise ValueError(f"--{name} must be an integer >= 1, got {value}")
        if not integer and not (math.isfinite(value) and value > 0):
            raise ValueError(f"--{name} must be a number > 0, got {value}")

    positive("duration", args.duration, False)
    positive("steps", args.steps, True)
    positive("every", args.every, True)
    positive("checkpoint-every", args.checkpoint_every, True)
    try:
        check_gif_options(size=args.size, fps=args.fps, speed=args.speed, stride=args.stride)
    except ValueError as err:
        raise ValueError(f"--{err}") from None
    video = getattr(args, "video", None)
    if video is not None:
        from .render import check_video_available

        if video.suffix.lower() != ".mp4":
            raise ValueError(f"--video must name a .mp4 file, got {video}")
        try:
            check_video_available()
        except ImportError as err:
            raise ValueError(f"--video: {err}") from None
        _check_writable_dir(video.parent, "--video")
        if video.is_dir():
            raise ValueError(f"--video {video} is a directory")
    _check_writable_dir(args.out, "--out")
    if args.vtk is not None:
        import importlib.util

        if importlib.util.find_spec("meshio") is None:
            raise ValueError("--vtk needs meshio, an optional extra: pip install 'ddatai[vtk]'")
        _check_writable_dir(args.vtk, "--vtk")
    if args.gif is not None:
        if args.gif.suffix.lower() != ".gif":
            raise ValueError(f"--gif must name a .gif file, got {args.gif}")
        _check_writable_dir(args.gif.parent, "--gif")
        if args.gif.is_dir():
            raise ValueError(f"--gif {args.gif} is a directory")


def _check_writable_dir(folder: Path, option: str) -> None:
    import os

    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise ValueError(f"{option}: cannot create the folder {folder}: {err.strerror}") from None
    if not folder.is_dir() or not os.access(folder, os.W_OK | os.X_OK):
        raise ValueError(f"{option}: cannot write in {folder}")


def _simulate_and_report(scene, params, duration, steps, name, args, after=None) -> int:
    import ddatai as dd
    from .results import SimulationInterrupted

    checkpoint = args.out / f"{name}.checkpoint.npz"
    resume = None
    if args.resume is not None:
        from .io.checkpoint import checkpoint_targets

        resume = checkpoint if args.resume is True else args.resume
        if args.duration is None and args.steps is None:  # the checkpoint's own targets
            targets = checkpoint_targets(resume)
            duration, steps = targets.duration, targets.steps
    progress = Progress(duration, steps, enabled=not args.quiet)
    t0 = time.perf_counter()
    try:
        results = dd.simulate(scene, params=params, duration=duration, steps=steps, record_every=args.every,
                              record_contacts=args.contacts or None, progress=progress,
                              checkpoint=checkpoint, checkpoint_every=args.checkpoint_every, resume=resume)
    except dd.SimulationError as err:
        progress.close(err.time)
        print(f"ddatai: {err}", file=sys.stderr)
        if err.results is not None and err.results.n_frames:
            out = _save(err.results, args.out, name)
            print(f"results up to step {err.step - 1} saved to {out}", file=sys.stderr)
        return 1
    except SimulationInterrupted as stop:
        progress.close(stop.time)
        out = _save(stop.results, args.out, name)
        print(f"ddatai: interrupted after step {stop.step} (t = {stop.time:.6g} s): the results recorded so far "
              f"are in {out}; continue with --resume {stop.checkpoint}", file=sys.stderr)
        return 130
    wall = time.perf_counter() - t0
    progress.close(float(results.time[-1]))
    out = _save(results, args.out, name)
    try:
        _write_outputs(results, out, name, args, after)
    except KeyboardInterrupt:
        print(f"ddatai: interrupted while writing the outputs; the results are in {out}", file=sys.stderr)
        return 130
    s = results.summary()
    print(f"{getattr(args, 'title', None) or name}: {s['blocks']} blocks, {s['steps']} steps to "
          f"t = {s['simulated_time']:.4g} s, "
          f"{s['dt_cuts']} dt cuts, {s['oc_iterations']} open-close iterations, "
          f"{wall:.2f} s wall time; results in {out}")
    return 0


def _write_outputs(results, out: Path, name: str, args: argparse.Namespace, after) -> None:
    """The outputs beside the results file: measured points, histories, VTK, GIF."""
    if after is not None:
        after(results)
    elif results.measured.shape[1]:
        path = results.measured_csv(out.with_name(out.stem + "_measured.csv"))
        print(f"measured points written to {path}")
    for x, y in args.history or ():
        path = results.history(point=(x, y)).to_csv(out.with_name(f"{out.stem}_history_{x:g}_{y:g}.csv"))
        print(f"history of ({x:g}, {y:g}) written to {path}")
    if args.vtk is not None:
        pvd = results.to_vtk(args.vtk)
        print(f"VTK files written to {args.vtk} (open {pvd.name} in ParaView)")
    if args.gif is not None:
        from .render import write_gif

        write_gif(results, args.gif, size=args.size, fps=args.fps, speed=args.speed, stride=args.stride,
                  show_contacts=args.contacts, title=getattr(args, "title", None) or name)
        print(f"GIF written to {args.gif} ({_gif_speed(results, args)})")
    if getattr(args, "video", None) is not None:
        from .render import write_video

        write_video(results, args.video, size=args.size, fps=args.fps, speed=args.speed, stride=args.stride,
                    show_contacts=args.contacts, title=getattr(args, "title", None) or name)
        print(f"video written to {args.video} ({_gif_speed(results, args)})")


def _gif_speed(results, args) -> str:
    """How the GIF plays, in words."""
    if args.stride is not None:
        return f"every {args.stride} recorded frame(s), {args.fps:g} frames/s"
    span = float(results.time[-1] - results.time[0])
    pace = "real time" if args.speed == 1 else f"{args.speed:g}× real time"
    return f"{pace}: {span:.3g} s simulated play in {span / args.speed:.3g} s at {args.fps:g} frames/s"


def _save(results, out_dir: Path, name: str) -> Path:
    """Save to DIR/NAME.npz, or NAME-2.npz, NAME-3.npz... when that exists (never overwritten)."""
    out_dir.mkdir(parents=True, exist_ok=True)
    path = out_dir / f"{name}.npz"
    k = 2
    while path.exists():
        path = out_dir / f"{name}-{k}.npz"
        k += 1
    results.save(path)
    return path


def _run_ntdda(geo: Path, ana: Path, args: argparse.Namespace) -> int:
    try:
        from .io.ntdda import read_ntdda, write_measured_csv
    except ImportError:
        raise ValueError("this installation has no ntdda reader") from None
    import dataclasses

    case = read_ntdda(geo, ana)
    print(case.summary())
    params = case.params if args.arch is None else dataclasses.replace(case.params, arch=args.arch)
    # an ntdda file gives a number of steps (automatic time step) or a duration (fixed one)
    if args.duration is not None or args.steps is not None:
        duration, steps = args.duration, args.steps
    else:
        duration, steps = case.duration, case.steps
    if args.every is None:
        args.every = case.record_every
    name = _output_name(args, Path(geo).stem)

    def measured(results) -> None:
        if results.measured.shape[1]:
            path = args.out / f"{name}_measured.csv"
            write_measured_csv(results, case, path)
            print(f"measured points written to {path}")

    return _simulate_and_report(case.scene, params, duration, steps, name, args, after=measured)


def _output_name(args: argparse.Namespace, stem: str) -> str:
    """Results are named after the GIF when one is written, else after the input."""
    return args.gif.stem if args.gif is not None else stem


def _guarded(args: argparse.Namespace, run: Callable[[], int], prog: str = "ddatai") -> int:
    """Run ``run()``; a user error prints one line (``--debug``: the traceback) and returns 2."""
    from .io.scenefile import SceneFileError

    try:
        return run()
    except (SceneFileError, ValueError, OSError) as err:
        if getattr(args, "debug", False):
            raise
        message = str(err).splitlines()[0] if str(err) else type(err).__name__
        print(f"{prog}: error: {message}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:  # before the first step: nothing to keep
        print(f"{prog}: interrupted before the run started; nothing saved", file=sys.stderr)
        return 130


def _allow_any_size(args) -> None:
    """``--force``: the scene's cuts build any number of blocks (`ddatai.cutting.MAX_BLOCKS_ENV`;
    the scene script's ``build`` cannot be given an argument it does not take)."""
    if getattr(args, "force", False):
        import os

        from .cutting import MAX_BLOCKS_ENV
        os.environ[MAX_BLOCKS_ENV] = "inf"


def main(argv: Optional[Sequence[str]] = None) -> int:
    parser = argparse.ArgumentParser(prog="ddatai", description="2D DDA simulator")
    sub = parser.add_subparsers(dest="command", required=True)
    run = sub.add_parser("run", help="run a scene script or an ntdda model")
    run.add_argument("inputs", nargs="+", type=Path, help="SCENE.py, SECTION.dxf, or MODEL.geo MODEL.ana")
    run.add_argument("--joints", type=Path, metavar="TOML",
                     help="a SECTION.dxf's material and joint layers (ddatai.io.dxf.read_joints_file)")
    _add_run_options(run)
    args = parser.parse_args(argv)
    inputs = args.inputs
    if not ((len(inputs) == 1 and inputs[0].suffix.lower() in (".py", ".dxf")) or len(inputs) == 2):
        parser.error("run takes SCENE.py, SECTION.dxf --joints JOINTS.toml, or MODEL.geo MODEL.ana")

    def go() -> int:
        check_options(args)
        _allow_any_size(args)
        if len(inputs) == 1:
            from .io.scenefile import load_scene_script

            script = load_scene_script(inputs[0], joints=args.joints)
            args.title = script.name  # the GIF's title: the scene, whatever the files are called
            return run_scene(script, script.duration, _output_name(args, script.name), args)
        args.title = inputs[0].stem
        return _run_ntdda(inputs[0], inputs[1], args)

    return _guarded(args, go)


def scene_main(build: Callable, duration: Optional[float], name: str, argv: Optional[Sequence[str]] = None) -> int:
    """Entry point of ``python scenes/NAME.py [options]``: the options of ``ddatai run``."""
    parser = argparse.ArgumentParser(prog=name, description=f"run the {name} scene")
    _add_run_options(parser)
    args = parser.parse_args(argv)

    def go() -> int:
        check_options(args)
        _allow_any_size(args)
        args.title = name
        return run_scene(build, duration, _output_name(args, name), args)

    return _guarded(args, go, prog=name)


def run_as_script(build: Callable, duration: Optional[float], name: str,
                  argv: Optional[Sequence[str]] = None) -> None:
    """The ``if __name__ == "__main__":`` block of a scene script: `scene_main`, exiting with
    its status when the run failed (2: a user error, 1: the run diverged, 130: Ctrl-C) and
    returning normally when it succeeded, so that a script that runs its scene can go on (the
    documentation's gallery runs every scene script this way)."""
    rc = scene_main(build, duration, name, argv)
    if rc:
        raise SystemExit(rc)


if __name__ == "__main__":
    sys.exit(main())
