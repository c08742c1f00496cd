"""Studies run from a plain script, as a user writes one: `kgm.probabilistic` and `ddatai.sweep`
called at a script's top level, with and without an ``if __name__ == "__main__":`` block, in a
fresh interpreter (`ddatai.parallel.plan`).

Worker processes start with ``spawn`` and import the running script again; a study started at
the top level of an unguarded script would start again in every worker, and Python's
`multiprocessing` breaks the pool with a screen of traceback. Here: limit-equilibrium samples
run in this process by default (no workers, no problem); where processes are the default (DDA
runs) an unguarded script still gets its result, in this process, with one warning line saying
what to add; asked for processes explicitly, it stops before any work with one line saying what
to add.
"""

import os
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest
import scipy.stats as st

ROOT = Path(__file__).resolve().parents[1]

#: a block on a 30° plane, built in the script itself (as a user would): FS = tanφ / tan 30°
BUILD = '''
import ddatai as dd


def build(friction=30.0):
    open(MARK, "a").write("built\\n")  # proves whether any sample was built
    scene = dd.Scene(gravity=9.81)
    rock = dd.Material(density=2500.0, young=5e9, poisson=0.25)
    c, s = 0.8660254037844387, 0.5
    scene.add_block([(0, 0), (20 * c, 20 * s), (20 * c, 20 * s - 2), (0, -2)], material=rock, fixed=True)
    x, y = 5 * c, 5 * s
    scene.add_block([(x, y), (x + 2 * c, y + 2 * s), (x + 2 * c - s, y + 2 * s + c), (x - s, y + c)],
                    material=rock)
    scene.set_joint(dd.Joint(friction=friction))
    return scene
'''


def _script(tmp_path: Path, body: str, *, guarded: bool) -> Path:
    mark = tmp_path / "built.txt"
    code = f"MARK = {str(mark)!r}\n" + textwrap.dedent(BUILD) + "\n"
    body = textwrap.dedent(body)
    if guarded:
        code += 'if __name__ == "__main__":\n' + textwrap.indent(body, "    ")
    else:
        code += body
    path = tmp_path / "study.py"
    path.write_text(code)
    return path


def _run(args, cwd: Path, timeout: float = 300.0) -> subprocess.CompletedProcess:
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    return subprocess.run([sys.executable, *args], capture_output=True, text=True, cwd=cwd, env=env,
                          timeout=timeout)


STUDY = '''
import scipy.stats as st
import kgm
study = kgm.probabilistic(build, {{"friction": st.norm(33.0, 3.0)}}, {n}, method="rigid", group={{1}},
                          seed=3{extra})
print("PF", repr(study.pf))
print("FS", ",".join(repr(float(x)) for x in study.fs[:20]))
'''


def test_unguarded_script_computes_its_probability_of_failure_in_this_process(tmp_path):
    """The first script of the issue: no guard, the default workers. Rigid samples run in this
    process (no worker is started, nothing to break); P_f is the closed form's within its
    99 % interval, and nothing is printed on stderr."""
    n = 400
    script = _script(tmp_path, STUDY.format(n=n, extra=""), guarded=False)
    out = _run([str(script)], tmp_path)
    assert out.returncode == 0, out.stderr[-3000:]
    assert "Traceback" not in out.stderr and "Warning" not in out.stderr, out.stderr
    pf = float(out.stdout.split("PF ")[1].split()[0])
    exact = st.norm.cdf((30.0 - 33.0) / 3.0)
    half = 2.576 * np.sqrt(exact * (1 - exact) / n)
    assert abs(pf - exact) <= half, (pf, exact)
    assert (tmp_path / "built.txt").read_text().count("built") == n


def test_unguarded_script_asking_for_processes_stops_before_any_work_with_one_line(tmp_path):
    script = _script(tmp_path, STUDY.format(n=50, extra=", workers=2"), guarded=False)
    out = _run([str(script)], tmp_path)
    assert out.returncode == 1
    lines = out.stderr.strip().splitlines()
    assert len(lines) == 1, out.stderr
    line = 1 + script.read_text().splitlines().index(
        next(x for x in script.read_text().splitlines() if x.startswith("study = kgm.probabilistic")))
    assert 'if __name__ == "__main__":' in lines[0] and str(script) in lines[0] and f"line {line}" in lines[0]
    assert "kgm.probabilistic" in lines[0] and "workers=1" in lines[0]
    assert not (tmp_path / "built.txt").exists()  # no sample was built
    assert "PF" not in out.stdout


def test_guarded_script_runs_its_study_on_two_processes_with_the_same_table(tmp_path):
    body = STUDY.format(n=60, extra=", workers=2") + STUDY.format(n=60, extra=", workers=1")
    script = _script(tmp_path, body, guarded=True)
    out = _run([str(script)], tmp_path)
    assert out.returncode == 0, out.stderr[-3000:]
    assert "Traceback" not in out.stderr and "Warning" not in out.stderr, out.stderr
    pf = [line for line in out.stdout.splitlines() if line.startswith("PF")]
    fs = [line for line in out.stdout.splitlines() if line.startswith("FS")]
    assert len(pf) == 2 and pf[0] == pf[1] and fs[0] == fs[1]
    # 60 samples, built in the worker processes and then 60 here
    assert (tmp_path / "built.txt").read_text().count("built") == 120


def test_a_function_from_a_prompt_cannot_go_to_processes_and_says_so(tmp_path):
    """``python -c`` (like a notebook): the workers cannot import ``build``."""
    code = f"MARK = {str(tmp_path / 'built.txt')!r}\n" + textwrap.dedent(BUILD) + \
        textwrap.dedent(STUDY.format(n=20, extra=", workers=2"))
    out = _run(["-c", code], tmp_path)
    assert out.returncode == 1
    lines = out.stderr.strip().splitlines()
    assert len(lines) == 1 and "define it in a module or script file" in lines[0], out.stderr
    assert not (tmp_path / "built.txt").exists()


def test_at_an_interactive_prompt_the_session_goes_on(tmp_path):
    """At a prompt (here ``python -i``) a `SystemExit` would close the session: the same line
    comes as an `InteractiveMainError`, and the session goes on."""
    code = f"MARK = {str(tmp_path / 'built.txt')!r}\n" + textwrap.dedent(BUILD) + \
        textwrap.dedent(STUDY.format(n=20, extra=", workers=2"))
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    out = subprocess.run([sys.executable, "-i", "-c", code], input='print("STILL", "HERE")\n', capture_output=True,
                         text=True, cwd=tmp_path, env=env, timeout=300)
    assert "InteractiveMainError" in out.stderr and "define it in a module or script file" in out.stderr
    assert "STILL HERE" in out.stdout + out.stderr, (out.stdout, out.stderr)
    assert not (tmp_path / "built.txt").exists()


SWEEP = '''
import ddatai as dd
rows = dd.sweep(build, {{"friction": [20.0, 40.0]}}, duration=0.05{extra})
print("MOVED", repr(float(rows["max_displacement"][0])), repr(float(rows["max_displacement"][1])))
'''


def test_unguarded_sweep_still_runs_where_processes_are_the_default(tmp_path):
    """A sweep's runs are simulations (processes by default); unguarded, the script still gets
    its rows, run in this process, and one warning line says what to add. The block slides
    ½·g(sinθ − cosθ·tanφ)·t² at φ = 20° and stays at φ = 40°."""
    script = _script(tmp_path, SWEEP.format(extra=""), guarded=False)
    out = _run([str(script)], tmp_path)
    assert out.returncode == 0, out.stderr[-3000:]
    warning = [line for line in out.stderr.splitlines() if "RuntimeWarning" in line]
    assert len(warning) == 1 and 'if __name__ == "__main__":' in warning[0], out.stderr
    assert "running in this process" in warning[0] and "Traceback" not in out.stderr
    slid, stayed = (float(x) for x in out.stdout.split("MOVED ")[1].split())
    t = np.radians(30.0)
    a = 9.81 * (np.sin(t) - np.cos(t) * np.tan(np.radians(20.0)))
    assert slid == pytest.approx(0.5 * a * 0.05 ** 2, rel=0.02) and stayed < 1e-6


def test_unguarded_sweep_asking_for_processes_stops_with_one_line(tmp_path):
    script = _script(tmp_path, SWEEP.format(extra=", workers=2"), guarded=False)
    out = _run([str(script)], tmp_path)
    assert out.returncode == 1
    lines = out.stderr.strip().splitlines()
    assert len(lines) == 1 and "ddatai.sweep" in lines[0] and 'if __name__ == "__main__":' in lines[0], out.stderr
    assert not (tmp_path / "built.txt").exists()


def test_the_default_follows_the_cost_of_a_sample():
    """Limit-equilibrium samples (light) run in this process, DDA runs (heavy) on one process per
    CPU, an explicit number wins; a lambda cannot go to processes: the default stays here and an
    explicit request is refused before any work."""
    import kgm_cases

    from ddatai.parallel import default_workers, plan

    assert plan(kgm_cases.incline_scene, cost="light") == 1
    assert plan(kgm_cases.incline_scene, cost="heavy") == default_workers()
    assert plan(kgm_cases.incline_scene, cost="light", workers=2) == 2
    assert plan(lambda: None, cost="heavy") == 1
    with pytest.raises(ValueError, match="cannot be sent"):
        plan(lambda: None, cost="light", workers=2)


def test_guard_detection_on_source():
    from ddatai.parallel import _guarded_lines

    src = 'import x\n\nif __name__ == "__main__":\n    run()\n    more()\nif "__main__" == __name__:\n    go()\n'
    assert _guarded_lines(src) == [(3, 5), (6, 7)]
    assert _guarded_lines("if __name__ != '__main__':\n    run()\n") == []
