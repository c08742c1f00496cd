"""The welded start: the equilibrium a model starts from when the frictional stage finds none
(`ddatai.start`, docstring item 6; docs/method/dda.md §8.12).

Each contact touching at t = 0 is held as a spring for one static solve, then takes the joint
law: pulled beyond its tensile strength it opens, sheared beyond its Coulomb strength it is
handed over locked at that strength. So the run starts with the elastic settlement and stress
of its weight, and only the difference between the welded and the real joint forces is
released in the first steps. Checked against closed forms: the stress of a stacked column,
the ringing of a column under sudden gravity, a block sliding down a plane, a hanging block.
"""

import numpy as np
import pytest

import ddatai as dd
from ddatai.model import build_model
from ddatai.start import settle
from ddatai.step import Stepper
from tests.cases import G, ROCK, incline_frame, sliding_scene


def stacked_grid(n: int) -> dd.Scene:
    """n × n fitted 1 m blocks of ROCK (E = 5 GPa) on a fixed base, φ = 30°."""
    scene = dd.Scene(gravity=G)
    scene.add_block([(-1, -1), (n + 1, -1), (n + 1, 0), (-1, 0)], material=ROCK, fixed=True)
    for j in range(n):
        for i in range(n):
            scene.add_block([(i, j), (i + 1, j), (i + 1, j + 1), (i, j + 1)], material=ROCK)
    scene.set_joint(dd.Joint(friction=30.0))
    return scene


def test_a_stiff_grid_the_frictional_stage_cannot_settle_starts_welded_and_does_not_ring():
    """An 8 × 8 fitted grid of stiff rock (p = 250 GPa): its joints slip by microns under the
    Poisson effect of its own weight, and the frictional stage does not converge. The welded
    start holds every block, gives the bottom row σy = −ρ·g·(n − ½)·h at once (1 %, as the
    bonded column of the verification suite), and the blocks stay an order of magnitude
    slower than the ringing of sudden gravity, whose amplitude for an elastic column of
    height H is g·H/c (c = √(E/ρ), the 1D bar's first arrival) — which the same grid started
    under sudden gravity does reach."""
    n, duration = 8, 0.1
    scene = stacked_grid(n)
    bottom = np.arange(1, n + 1)  # block 0 is the base
    exact = -ROCK.density * G * (n - 0.5)
    ringing = G * n / np.sqrt(ROCK.young / ROCK.density)

    res = dd.simulate(scene, params=dd.Params(dt=1e-3), duration=duration)
    start = res.start[0]
    assert start["welded"] and start["held"] == n * n and start["released"] == 0
    for frame in (0, -1):
        assert res.stress[frame, bottom, 1].mean() == pytest.approx(exact, rel=0.01)
    assert np.abs(res.velocity).max() < 0.1 * ringing

    sudden = dd.simulate(scene, params=dd.Params(dt=1e-3, initial_equilibrium=False), duration=duration)
    assert np.abs(sudden.velocity).max() > 0.5 * ringing


def run_welded(scene: dd.Scene, block: int, duration: float):
    """Start ``scene`` from its welded equilibrium and run it for ``duration`` [s] (Δt = 1 ms).
    Returns (the start record, the block's centroid at t = 0 and at the end)."""
    model = build_model(scene, dd.Params(dt=1e-3))
    stepper = Stepper(model)
    state, record = settle(stepper, model.initial_state(), welded=True)
    assert record.welded and record.held == 1 and record.released == 0
    x0 = model.block_geometry(state.vertex_xy)["centroid"][block].copy()
    while state.time < duration * (1 - 1e-12):
        state, _ = stepper.step(state, t_end=duration)
    return record, x0, model.block_geometry(state.vertex_xy)["centroid"][block]


@pytest.mark.parametrize("phi", [30.0, 45.0])
def test_welded_start_hands_a_sheared_contact_over_at_its_strength(phi):
    """A block on a 40° plane started from its welded equilibrium: at φ = 30° the base
    contacts carry more shear than N·tanφ and are handed over at their strength, so the
    block slides from t = 0 with a = g(sin θ − cos θ tan φ) (displacement ½·a·t² within 1 %,
    no start-up impulse); at φ = 45° the block rests (the welded springs share the shear
    equally while the downhill corner carries more of the normal force, so the uphill contact
    may be handed over at its strength: the block holds all the same)."""
    theta, duration = 40.0, 0.3
    scene, block = sliding_scene(theta, phi)
    record, x0, x1 = run_welded(scene, block, duration)
    assert record.at_strength > 0 or phi > theta
    up_slope, _ = incline_frame(theta)
    moved = -float((x1 - x0) @ up_slope)
    th, mu = np.radians(theta), np.tan(np.radians(phi))
    if phi < theta:
        assert moved == pytest.approx(0.5 * G * (np.sin(th) - np.cos(th) * mu) * duration ** 2, rel=0.01)
    else:
        assert abs(moved) < 1e-5


@pytest.mark.parametrize("tensile", [0.0, 1e5])
def test_welded_start_opens_a_contact_pulled_beyond_its_tensile_strength(tensile):
    """A 1 m block hanging from the underside of a fixed block, held only by their shared
    face: welded, the face carries the block's weight in tension. Without tensile strength it
    opens and the block falls freely from t = 0 (½·g·t² within 0.5 %); bonded with
    T·L = 100 kN/m above the weight (24.5 kN/m), it stays (by its elastic stretch)."""
    scene = dd.Scene(gravity=G)
    scene.add_block([(-1, 1), (2, 1), (2, 2), (-1, 2)], material=ROCK, fixed=True)
    block = scene.add_block([(0, 0), (1, 0), (1, 1), (0, 1)], material=ROCK)
    scene.set_joint(dd.Joint(friction=30.0, cohesion=tensile, tensile=tensile))
    record, x0, x1 = run_welded(scene, block, 0.2)
    drop = x0[1] - x1[1]
    if tensile == 0.0:
        assert drop == pytest.approx(0.5 * G * 0.2 ** 2, rel=0.005)
    else:
        assert abs(drop) < 1e-5
