"""Unit mistakes are warned about (a `UnitWarning` naming the value and the likely unit), and a
failure that a unit mistake explains names it as the likely cause."""

import math
import warnings

import pytest

import ddatai as dd
from ddatai.params import UnitWarning


@pytest.mark.parametrize("make, pattern", [
    (lambda: dd.Joint(friction=0.6), r"Joint\.friction = 0\.6° .*radians \(0\.6 rad = 34\.38°\)"),
    (lambda: dd.Material(density=2.6, young=5e9, poisson=0.25),
     r"Material\.density = 2\.6 kg/m³ .*g/cm³ .*2\.6 g/cm³ = 2600 kg/m³"),
    (lambda: dd.Material(density=26.0, young=5e9, poisson=0.25), r"Material\.density = 26 kg/m³ .*kN/m³"),
    (lambda: dd.Material(density=26000.0, young=5e9, poisson=0.25), r"Material\.density = 26000 .*N/m³"),
    (lambda: dd.Material(density=2600.0, young=5e3, poisson=0.25),
     r"Material\.young = 5000 Pa .*MPa \(5000 MPa = 5e\+09 Pa\)"),
    (lambda: dd.Material(density=2600.0, young=20.0, poisson=0.25), r"Material\.young = 20 Pa .*GPa"),
    (lambda: dd.Joint(friction=30.0, cohesion=50.0), r"Joint\.cohesion = 50 Pa .*kPa"),
])
def test_implausible_values_are_warned_with_the_likely_unit(make, pattern):
    with pytest.warns(UnitWarning, match=pattern) as caught:
        make()
    assert issubclass(UnitWarning, UserWarning)
    assert caught[0].filename == __file__  # points at the line that built it


def test_plausible_rock_values_are_silent():
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        dd.Material(density=2650.0, young=20e9, poisson=0.25)
        dd.Material(density=1800.0, young=1e5, poisson=0.3)   # a soft analogue, still not a unit slip
        dd.Joint(friction=0.0)                                 # frictionless: deliberate
        dd.Joint(friction=2.0, cohesion=0.0, tensile=1e5)
    assert dd.UnitWarning is UnitWarning


def _heavy_block(density):
    scene = dd.Scene(gravity=9.81)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UnitWarning)
        rock = dd.Material(density=density, young=5e9, poisson=0.25)
    scene.add_block([(-2, -1), (3, -1), (3, 0), (-2, 0)], material=rock, fixed=True)
    scene.add_block([(0, 0), (1, 0), (1, 1), (0, 1)], material=rock)
    return scene


def test_failure_names_a_unit_mistake_as_its_likely_cause():
    """A unit weight given as a density (25,000 N/m³) makes the block ten times too heavy for a
    soft penalty: the runaway-penetration message says so."""
    params = dd.Params(penalty=3e5, dt=0.01, dt_min_ratio=0.01)
    with pytest.raises(dd.SimulationError, match="runaway penetration") as info:
        dd.simulate(_heavy_block(25000.0), params=params, duration=1.0)
    assert "Likely cause: Material.density = 25000 kg/m³" in str(info.value)
    assert "N/m³" in str(info.value)
    # the same failure with a plausible density names no unit
    with pytest.raises(dd.SimulationError, match="runaway penetration") as info:
        dd.simulate(_heavy_block(2500.0), params=dd.Params(penalty=3e4, dt=0.01, dt_min_ratio=0.01),
                    duration=1.0)
    assert "Likely cause" not in str(info.value)


def test_refused_soft_model_names_the_unit():
    scene = dd.Scene(gravity=9.81)
    with pytest.warns(UnitWarning):
        rock = dd.Material(density=2500.0, young=5e3, poisson=0.25)
    scene.add_block([(-2, -1), (3, -1), (3, 0), (-2, 0)], material=rock, fixed=True)
    scene.add_block([(0, 0), (1, 0), (1, 1), (0, 1)], material=rock)
    with pytest.raises(ValueError, match=r"likely cause: Material\.young = 5000 Pa .* MPa"):
        dd.build_model(scene)


def test_a_strength_reductions_cohesion_is_not_a_unit_slip():
    """c/F of a joint checked when it was built is small by the method (a strength reduction to
    F = 500 in a bisection), not by a unit slip: no warning."""
    from kgm.strength import Strength

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        reduced = Strength(reduction=500.0).joint(dd.Joint(friction=30.0, cohesion=20e3))
        barton = Strength(reduction=500.0).joint(dd.BartonBandis(jrc=10.0, jcs=50e6, residual_friction=25.0, cohesion=20e3))
    assert reduced.cohesion == pytest.approx(40.0) and barton.cohesion == pytest.approx(40.0)
    assert math.tan(math.radians(reduced.friction)) == pytest.approx(math.tan(math.radians(30.0)) / 500.0)
