"""Command line: ``ddatai run SCENE.py`` (or ``ddatai run MODEL.geo MODEL.ana``).

    ddatai run SCENE.py [--duration S] [--steps N] [--every K] [--gif PATH] [--out DIR]
                        [--contacts] [--size WxH] [--fps F] [--speed X] [--stride K] [--arch cpu|gpu]

A scene script is a Python file defining ``build(**sizes) -> (Scene, Params)`` and
``DURATION`` (seconds); ``python scenes/NAME.py [options]`` runs the same way through
`scene_main`. The run shows a progress bar (simulated time, steps per second), writes the
results to ``DIR/NAME.npz``, the GIF if ``--gif`` is given (only then are imaging libraries
imported) and prints a short summary.
"""

from __future__ import annotations

import argparse
import importlib.util
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


def _add_run_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("--duration", type=float, help="simulated time [s] (default: the scene's DURATION)")
    p.add_argument("--steps", type=int, help="stop after this many steps")
    p.add_argument("--every", type=int, default=None, help="record a frame every K steps")
    p.add_argument("--gif", type=Path, help="write an animated GIF here")
    p.add_argument("--out", type=Path, default=Path("out"), help="directory for the results (.npz)")
    p.add_argument("--contacts", action="store_true", help="record contacts and draw them in the GIF")
    p.add_argument("--size", type=_size, default=(640, 480), help="GIF size, e.g. 640x480")
    p.add_argument("--fps", type=float, default=20.0, help="GIF frames per second (at most 50)")
    p.add_argument("--speed", type=float, default=1.0,
                   help="GIF playback speed: simulated seconds per second of animation (default 1: real time)")
    p.add_argument("--stride", type=int, default=None,
                   help="GIF: draw every K-th recorded frame, each for 1/fps s, instead of sampling time")
    p.add_argument("--arch", choices=("cpu", "gpu", "cuda"), default=None,
                   help="Taichi backend (default: the scene's Params)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
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
        self.n = 0

    def __call__(self, state, record) -> None:
        self.n += 1
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
            frac = min(1.0, self.n / self.steps)
        else:
            frac = 0.0
        bar = "#" * int(30 * frac) + "." * (30 - int(30 * frac))
        rate = self.n / max(now - self.start, 1e-9)
        total = f"/{self.duration:g}" if self.duration else ""
        end = " " if sys.stderr.isatty() else "\n"
        start = "\r" if sys.stderr.isatty() else ""
        sys.stderr.write(f"{start}[{bar}] t = {t:.4g}{total} s  {self.n} steps  {rate:.1f} steps/s{end}")
        sys.stderr.flush()

    def close(self, t: float) -> None:
        if self.enabled:
            self._draw(t, time.perf_counter(), final=True)
            if sys.stderr.isatty():
                sys.stderr.write("\n")


def load_scene_module(path: Path) -> ModuleType:
    """Import a scene script by path (it must define build() and DURATION)."""
    path = Path(path)
    if not path.is_file():
        raise SystemExit(f"ddatai: no such scene file: {path}")
    spec = importlib.util.spec_from_file_location(f"ddatai_scene_{path.stem}", path)
    module = importlib.util.module_from_spec(spec)
    sys.path.insert(0, str(path.resolve().parent.parent))  # lets scenes import their package
    spec.loader.exec_module(module)
    for name in ("build", "DURATION"):
        if not hasattr(module, name):
            raise SystemExit(f"ddatai: {path} does not define {name} (a scene needs build() and DURATION)")
    return module


def run_scene(build: Callable, duration: float, name: str, args: argparse.Namespace) -> int:
    """Build, simulate with a progress bar, save results (and GIF), print a summary."""
    import dataclasses

    scene, params = build()
    if args.arch is not None:
        params = dataclasses.replace(params, arch=args.arch)
    duration = args.duration if args.duration is not None else duration
    if args.steps is not None:
        duration = args.duration  # --steps alone runs a number of steps
    return _simulate_and_report(scene, params, duration, args.steps, name, args)


def _simulate_and_report(scene, params, duration, steps, name, args, after=None) -> int:
    import ddatai as dd
    from .results import SimulationInterrupted

    checkpoint = args.out / f"{name}.checkpoint.npz"
    resume = None
    if args.resume is not None:
        resume = checkpoint if args.resume is True else args.resume
        if args.duration is None and args.steps is None:
            duration = steps = None  # the checkpoint's own targets
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
    if after is not None:
        after(results)
    if args.gif is not None:
        from .render import write_gif

        write_gif(results, args.gif, size=args.size, fps=args.fps, speed=args.speed, stride=args.stride,
                  show_contacts=args.contacts, title=name)
        print(f"GIF written to {args.gif} ({_gif_speed(results, args)})")
    s = results.summary()
    print(f"{name}: {s['blocks']} blocks, {s['steps']} steps to t = {s['simulated_time']:.4g} s, "
          f"{s['dt_cuts']} dt cuts, {s['oc_iterations']} open-close iterations, "
          f"{wall:.2f} s wall time; results in {out}")
    return 0


def _gif_speed(results, args) -> str:
    """How the GIF plays, in words."""
    if args.stride is not None:
        return f"every {args.stride} recorded frame(s), {args.fps:g} frames/s"
    span = float(results.time[-1] - results.time[0])
    pace = "real time" if args.speed == 1 else f"{args.speed:g}× real time"
    return f"{pace}: {span:.3g} s simulated play in {span / args.speed:.3g} s at {args.fps:g} frames/s"


def _save(results, out_dir: Path, name: str) -> Path:
    out_dir.mkdir(parents=True, exist_ok=True)
    path = out_dir / f"{name}.npz"
    results.save(path)
    return path


def _run_ntdda(geo: Path, ana: Path, args: argparse.Namespace) -> int:
    try:
        from .ntdda import read_ntdda, write_measured_csv
    except ImportError:
        raise SystemExit("ddatai: this installation has no ntdda reader") from None
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
    name = Path(geo).stem

    def measured(results) -> None:
        if results.measured.shape[1]:
            path = args.out / f"{name}_measured.csv"
            write_measured_csv(results, case, path)
            print(f"measured points written to {path}")

    return _simulate_and_report(case.scene, params, duration, steps, name, args, after=measured)


def main(argv: Optional[Sequence[str]] = None) -> int:
    parser = argparse.ArgumentParser(prog="ddatai", description="2D DDA simulator")
    sub = parser.add_subparsers(dest="command", required=True)
    run = sub.add_parser("run", help="run a scene script or an ntdda model")
    run.add_argument("inputs", nargs="+", type=Path, help="SCENE.py, or MODEL.geo MODEL.ana")
    _add_run_options(run)
    args = parser.parse_args(argv)
    if args.command == "run":
        inputs = args.inputs
        if len(inputs) == 1 and inputs[0].suffix == ".py":
            module = load_scene_module(inputs[0])
            return run_scene(module.build, module.DURATION, inputs[0].stem, args)
        if len(inputs) == 2:
            return _run_ntdda(inputs[0], inputs[1], args)
        parser.error("run takes SCENE.py, or MODEL.geo MODEL.ana")
    return 2


def scene_main(build: Callable, duration: float, name: str, argv: Optional[Sequence[str]] = None) -> int:
    """Entry point of ``python scenes/NAME.py [options]``: the options of ``ddatai run``."""
    parser = argparse.ArgumentParser(prog=name, description=f"run the {name} scene")
    _add_run_options(parser)
    args = parser.parse_args(argv)
    return run_scene(build, duration, name, args)


if __name__ == "__main__":
    sys.exit(main())
