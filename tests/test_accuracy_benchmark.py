"""The accuracy benchmark's references and its quick run (benchmarks/accuracy.py, issue 5).

The stick–slip integrator is checked against closed forms: constant ground acceleration
(uniformly accelerated sliding, down- and up-slope), a rectangular pulse (Newmark 1965: the
block keeps sliding after the pulse until friction stops it) and a sinusoid integrated phase by
phase in closed form (one-way and two-way sliding). The pivoting-block reference is checked
against its initial angular acceleration. The quick benchmark must write its table and chart
(the chart with the [plot] extra, matplotlib; without it, a line saying so).
"""

import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from benchmarks.accuracy import pivoting_block_rotation
from benchmarks.stick_slip import DOWN, STICK, UP, sinusoid_stick_slip, stick_slip

G = 9.81
ROOT = Path(__file__).resolve().parents[1]


def _gains(theta, phi):
    th, mu = math.radians(theta), math.tan(math.radians(phi))
    a_down = G * math.tan(math.radians(phi - theta))   # horizontal yield acceleration, down-slope
    a_up = G * math.tan(math.radians(phi + theta))     # the same, up-slope (ground pushed the other way)
    return math.cos(th) + mu * math.sin(th), math.cos(th) - mu * math.sin(th), a_down, a_up


@pytest.mark.parametrize("theta, phi, a", [(20.0, 30.0, 0.5 * G), (0.0, 30.0, 0.8 * G), (20.0, 30.0, -1.5 * G)])
def test_constant_ground_acceleration_gives_uniform_sliding(theta, phi, a):
    """Beyond the yield acceleration the block slides from t = 0 with constant relative
    acceleration: s = ½ c (a − a_y) t² down-slope, s = ½ c' (a + a_yu) t² up-slope."""
    c_down, c_up, a_down, a_up = _gains(theta, phi)
    expected_acc = c_down * (a - a_down) if a > 0 else c_up * (a + a_up)
    t = np.linspace(0.0, 2.0, 9)
    sol = stick_slip(theta, phi, lambda _: (a, 0.0), 2.0, t_eval=t, gravity=G)
    assert np.allclose(sol.displacement, 0.5 * expected_acc * t * t, rtol=1e-10, atol=1e-13)
    assert np.allclose(sol.velocity, expected_acc * t, rtol=1e-10, atol=1e-13)
    assert [p[2] for p in sol.phases] == [DOWN if a > 0 else UP]


def test_below_the_yield_acceleration_the_block_sticks():
    _, _, a_down, _ = _gains(20.0, 30.0)
    sol = stick_slip(20.0, 30.0, lambda _: (0.99 * a_down, 0.0), 1.0, gravity=G)
    assert sol.final_displacement == 0.0
    assert [p[2] for p in sol.phases] == [STICK]


def test_rectangular_pulse_slides_on_until_friction_stops_it():
    """a_g = a for t < t0, then 0: the block accelerates at c(a − a_y) until t0, then
    decelerates at c·a_y and stops at t1 = t0·a/a_y, after d = c (a − a_y) a t0² / (2 a_y)
    (Newmark 1965 on an incline, horizontal pulse); it then stays put (θ < φ)."""
    theta, phi, a, t0 = 20.0, 30.0, 0.6 * G, 0.25
    c, _, a_y, _ = _gains(theta, phi)
    t1 = t0 * a / a_y
    sol = stick_slip(theta, phi, lambda t: (a if t < t0 else 0.0, 0.0), 2.0, breaks=[t0], gravity=G)
    assert sol.final_displacement == pytest.approx(c * (a - a_y) * a * t0 ** 2 / (2 * a_y), rel=1e-10)
    assert [p[2] for p in sol.phases] == [DOWN, DOWN, STICK]
    assert sol.phases[1][1] == pytest.approx(t1, rel=1e-9)


@pytest.mark.parametrize("theta, phi, amplitude, frequency, t_end", [
    (20.0, 30.0, 0.4 * G, 1.0, 3.0),   # the benchmark case: one-way sliding
    (20.0, 30.0, 1.5 * G, 1.0, 3.0),   # beyond g tan(φ + θ): two-way sliding
    (10.0, 20.0, 0.5 * G, 2.0, 2.0),
])
def test_sinusoid_matches_the_closed_form_phase_by_phase(theta, phi, amplitude, frequency, t_end):
    """Event-driven DOP853 against the closed-form phases (independent: no ODE solver)."""
    closed = sinusoid_stick_slip(theta, phi, amplitude, frequency, t_end, gravity=G)
    for rtol in (1e-8, 1e-12):
        sol = stick_slip(theta, phi, lambda t: (amplitude * math.sin(2 * math.pi * frequency * t), 0.0),
                         t_end, gravity=G, rtol=rtol, atol=rtol * 1e-2, max_step=0.01)
        assert sol.final_displacement == pytest.approx(closed, rel=1e-9, abs=1e-12)
    assert closed > 0.01
    if amplitude > G * math.tan(math.radians(phi + theta)):
        assert UP in [p[2] for p in sol.phases]


def test_lift_off_is_refused():
    """A horizontal a_g > g cotθ unloads the plane completely: not a sliding block any more."""
    with pytest.raises(ValueError, match="lifts off"):
        stick_slip(30.0, 40.0, lambda _: (2.0 * G, 0.0), 1.0, gravity=G)


def test_pivoting_block_starts_with_the_rigid_angular_acceleration():
    """ψ(t) ≈ ½ ψ''(0) t² for small t, ψ''(0) = 3 g (h sinθ − b cosθ) / (2 (b² + h²))."""
    b, h, theta = 0.2, 1.0, 30.0
    th = math.radians(theta)
    alpha0 = 3 * G * (h * math.sin(th) - b * math.cos(th)) / (2 * (b * b + h * h))
    psi, demand = pivoting_block_rotation(b, h, theta, 40.0, 0.01)
    assert psi == pytest.approx(0.5 * alpha0 * 0.01 ** 2, rel=1e-3)
    assert 0 < demand < math.tan(math.radians(40.0))


def test_quick_benchmark_writes_its_table_and_chart(tmp_path):
    """`benchmarks/accuracy.py --quick` prints the Markdown table with every case, and writes
    accuracy.md, accuracy.csv and accuracy.png; the defaults keep the verified accuracy. (It takes
    ~30 s on a quiet 2-core machine; how long is the benchmark's to report, not this test's to
    assert: the timeout only guards against a hang.)"""
    proc = subprocess.run([sys.executable, str(ROOT / "benchmarks" / "accuracy.py"), "--quick",
                           "--out", str(tmp_path)], capture_output=True, text=True, timeout=600, cwd=ROOT)
    assert proc.returncode == 0, proc.stderr[-3000:]
    rows = [line for line in proc.stdout.splitlines() if line.startswith("| **defaults**")]
    assert len(rows) == 1, proc.stdout
    cells = [c.strip() for c in rows[0].strip("|").split("|")[1:]]
    header = next(line for line in proc.stdout.splitlines() if line.startswith("| parameters"))
    names = [c.strip() for c in header.strip("|").split("|")[1:]]
    assert len(cells) == len(names) == 11
    errors = dict(zip(names, (float(c.split("·")[0]) for c in cells)))
    assert errors["sliding (30° plane, friction 20°)"] < 1e-3
    assert errors["free flight"] < 1e-10
    assert max(errors.values()) < 0.05
    # the moving and bonded cases, at the 1 % of a rigid-block closed form
    for name in names:
        if name.startswith(("launched", "cohesive", "bonded")):
            assert errors[name] < 0.01, name
    # the rocking block's five peaks, within the 5 % of Housner's (tests/test_rocking.py)
    assert errors["rocking block (b/h = 0.25, 5 impacts)"] < 0.05
    md = (tmp_path / "accuracy.md").read_text()
    assert "| **defaults** |" in md and "Machine:" in md
    rows = (tmp_path / "accuracy.csv").read_text().splitlines()
    assert rows[0].startswith("case,group,parameters,error,wall_s") and len(rows) == 1 + 11 * 2
    # the chart is drawn with matplotlib, the [plot] extra; without it the run says so
    import importlib.util

    if importlib.util.find_spec("matplotlib") is None:
        assert "pip install -e '.[plot]'" in proc.stderr and not (tmp_path / "accuracy.png").exists()
        return
    png = (tmp_path / "accuracy.png").read_bytes()
    assert png[:8] == b"\x89PNG\r\n\x1a\n" and len(png) > 10_000
