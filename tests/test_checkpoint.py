"""Ctrl-C keeps a run, and checkpoints continue one with identical results: a run split by a
checkpoint (interrupted, or stopped and resumed) equals an unbroken run bit for bit."""

import dataclasses
from dataclasses import fields

import numpy as np
import pytest

import ddatai as dd
from ddatai.results import STEP_PHASES, SimulationInterrupted
from scenes import toppling

DURATION = 0.6
WALL = {f"t_{phase}" for phase in STEP_PHASES} | {"wall_time"}  # wall-clock columns


def _assert_same_run(a, b):
    """Every recorded number equal, bit for bit (wall-clock timings aside)."""
    for f in fields(a):
        x, y = getattr(a, f.name), getattr(b, f.name)
        if isinstance(x, str):
            assert x == y, f.name
        elif x.dtype.names:
            assert x.dtype == y.dtype, f.name
            for name in x.dtype.names:
                if name not in WALL:
                    assert np.array_equal(x[name], y[name], equal_nan=True), f"{f.name}[{name}]"
        else:
            assert x.shape == y.shape and np.array_equal(x, y, equal_nan=x.dtype.kind == "f"), f.name


def _scene(solver="scipy"):
    scene, params = toppling.build()
    return scene, dataclasses.replace(params, solver=solver)


@pytest.fixture(scope="module")
def unbroken():
    """SuperLU: a fresh factorisation every solve, whatever came before."""
    scene, params = _scene()
    res = dd.simulate(scene, params=params, duration=DURATION, record_every=3, record_contacts=True)
    assert len(res.steps) > 40 and res.steps["closed"].max() > 0
    return res


def _stop_at(step):
    def progress(state, record):
        if state.step == step:
            raise KeyboardInterrupt
    return progress


def test_ctrl_c_keeps_the_run_and_resumes_bit_for_bit(unbroken, tmp_path):
    scene, params = _scene()
    path = tmp_path / "run.checkpoint.npz"
    with pytest.raises(SimulationInterrupted) as info:
        dd.simulate(scene, params=params, duration=DURATION, record_every=3, record_contacts=True,
                    progress=_stop_at(23), checkpoint=path)
    err = info.value
    assert isinstance(err, KeyboardInterrupt)  # a script that does not catch it still stops
    assert err.step == 23 and err.checkpoint == path and path.is_file()
    part = err.results
    assert len(part.steps) == 23 and part.n_frames == 1 + 23 // 3
    assert np.array_equal(part.vertices, unbroken.vertices[:part.n_frames])
    assert dd.load_results(path).n_frames == part.n_frames  # a checkpoint reads as partial results
    # the rest of the run from the checkpoint: its targets and recording options are kept
    scene, params = _scene()
    _assert_same_run(dd.simulate(scene, params=params, resume=path), unbroken)


@pytest.mark.parametrize("solver", ["auto", "scipy"])
def test_periodic_checkpoint_continues_a_stopped_run(tmp_path, solver):
    """With either solver (PARDISO, where installed, keeps an analysis between steps)."""
    scene, params = _scene(solver)
    whole = dd.simulate(scene, params=params, duration=DURATION, record_every=3, record_contacts=True,
                        checkpoint=tmp_path / "whole.npz", checkpoint_every=10)
    scene, params = _scene(solver)
    path = tmp_path / "every.npz"
    first = dd.simulate(scene, params=params, steps=25, record_every=3, record_contacts=True,
                        checkpoint=path, checkpoint_every=10)
    assert len(first.steps) == 25
    # the file holds step 20 (the last multiple of 10), not the end of the stopped run
    assert len(dd.load_results(path).steps) == 20
    scene, params = _scene(solver)
    _assert_same_run(dd.simulate(scene, params=params, duration=DURATION, resume=path,
                                 checkpoint=tmp_path / "again.npz", checkpoint_every=10), whole)


def test_resume_refuses_another_model_or_other_recording(unbroken, tmp_path):
    scene, params = _scene()
    path = tmp_path / "c.npz"
    dd.simulate(scene, params=params, steps=4, record_every=3, checkpoint=path, checkpoint_every=2)
    scene, params = _scene()
    with pytest.raises(ValueError, match="different model or different parameters"):
        dd.simulate(scene, params=dd.Params(dt=1e-3), resume=path)
    with pytest.raises(ValueError, match="record_every=3"):
        dd.simulate(scene, params=params, resume=path, record_every=1)
    results = tmp_path / "r.npz"
    unbroken.save(results)
    with pytest.raises(ValueError, match="not a checkpoint"):
        dd.simulate(scene, params=params, resume=results)
    with pytest.raises(ValueError, match="checkpoint path"):
        dd.simulate(scene, params=params, steps=2, checkpoint_every=2)


def test_command_line_ctrl_c_saves_and_resume_finishes(tmp_path):
    """SIGINT to ``ddatai run``: one clear line, the results so far saved, exit status 130;
    ``--resume`` then finishes the run."""
    import os
    import signal
    import subprocess
    import sys
    import time
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    cmd = [sys.executable, "-m", "ddatai.cli", "run", "scenes/sliding_block.py", "--steps", "3000",
           "--every", "10", "--checkpoint-every", "20", "--out", str(tmp_path), "--quiet"]
    # SIGINT as a terminal sends it, even where pytest runs as a background job of a shell without
    # job control (which starts it, and so this child, with SIGINT ignored: then Python installs
    # no KeyboardInterrupt handler and the run would finish as if never interrupted)
    proc = subprocess.Popen(cmd, cwd=root, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    checkpoint = tmp_path / "sliding_block.checkpoint.npz"
    deadline = time.monotonic() + 120
    while not checkpoint.exists() and proc.poll() is None and time.monotonic() < deadline:
        time.sleep(0.1)
    assert proc.poll() is None, proc.communicate()[1][-2000:]
    proc.send_signal(signal.SIGINT)
    out, err = proc.communicate(timeout=120)
    assert proc.returncode == 130, err[-2000:]
    assert "Traceback" not in err
    line = [s for s in err.splitlines() if "interrupted after step" in s]
    assert len(line) == 1 and "--resume" in line[0]
    saved = dd.load_results(tmp_path / "sliding_block.npz")
    done = len(saved.steps)
    assert 20 <= done < 3000 and saved.n_frames == 1 + done // 10
    os.remove(tmp_path / "sliding_block.npz")
    resumed = subprocess.run([*cmd[:5], "--steps", "%d" % (done + 15), "--out", str(tmp_path), "--quiet",
                              "--resume"], cwd=root, capture_output=True, text=True, timeout=300)
    assert resumed.returncode == 0, resumed.stderr[-2000:]
    res = dd.load_results(tmp_path / "sliding_block.npz")
    assert len(res.steps) == done + 15
    assert np.array_equal(res.steps["time"][:done], saved.steps["time"])


def test_command_line_resume_of_a_missing_checkpoint_is_one_line(tmp_path, capsys):
    from pathlib import Path

    from ddatai.cli import main

    scene = Path(__file__).resolve().parents[1] / "scenes" / "sliding_block.py"
    assert main(["run", str(scene), "--out", str(tmp_path), "--resume"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "no such checkpoint" in err[0] and "sliding_block.checkpoint.npz" in err[0]
