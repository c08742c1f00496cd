"""Loads and strength laws of the 3D wedges (docs/kgm/wedge.md §4): Barton–Bandis through the
project's joint law, partly filled fissures, custom pressures, the seismic direction, falling
wedges and passive support, and the limit-state hook of the studies."""

from __future__ import annotations

import math

import numpy as np
import pytest

import ddatai as dd
import kgm
from kgm.wedges.geometry import Halfspace, plane_normal

DEG = math.pi / 180


def _prism(alpha, joint, height=10.0, width=2.0):
    base = plane_normal(alpha, 90.0)
    hs = [Halfspace(plane_normal(70.0, 90.0), 0.0, "slope face", "free"),
          Halfspace(np.array([0.0, 0.0, 1.0]), height, "upper face", "free"),
          Halfspace(-base, 0.0, "base", "joint"),
          Halfspace(np.array([0.0, -1.0, 0.0]), 0.0, "south", "joint"),
          Halfspace(np.array([0.0, 1.0, 0.0]), width, "north", "joint")]
    free = dd.Joint(friction=0.0)
    return hs, {"base": joint, "south": free, "north": free}


def test_barton_bandis_base_mobilises_friction_at_its_normal_stress():
    """FS = N tan φ(σn)/(W sin α), σn = N/A, φ(σn) = φr + JRC log10(JCS/σn) (Barton & Choubey):
    the same law, `ddatai.BartonBandis.tan_friction`, as the 2D analyses."""
    law = dd.BartonBandis(jrc=8.0, jcs=60e6, residual_friction=26.0)
    hs, joints = _prism(32.0, law)
    w = kgm.polyhedral_block(hs, joints, density=2700.0)
    a = 32 * DEG
    n = w.weight * math.cos(a)
    sigma = n / w.areas["base"]
    phi = 26.0 + 8.0 * math.log10(60e6 / sigma)
    assert w.fs == pytest.approx(n * math.tan(phi * DEG) / (w.weight * math.sin(a)), rel=1e-12)
    assert w.fs == pytest.approx(n * float(law.tan_friction(sigma)) / (w.weight * math.sin(a)), rel=1e-12)
    # a bigger block presses harder: lower mobilised friction, lower FS
    big = kgm.polyhedral_block(*_prism(32.0, law, height=40.0), density=2700.0)
    assert big.fs < w.fs


def test_partly_filled_fissures_scale_the_unit_weight_of_water():
    """fill f is Hoek & Bray's pressures with γw·f (Wyllie & Mah §III.3)."""
    j = dd.Joint(friction=30.0, cohesion=1e4)
    planes = (kgm.Plane(65, 185), kgm.Plane(12, 195), 20.0, [kgm.Plane(45, 105, j), kgm.Plane(70, 235, j)])
    half = kgm.wedge(*planes, water=kgm.Water(fill=0.4))
    light = kgm.wedge(*planes, water=kgm.Water(density=400.0))
    assert half.fs == pytest.approx(light.fs, rel=1e-12)
    # no crack: u = γw Hw / 6, Hw the height of the line of intersection's upper end
    full = kgm.wedge(*planes, water=kgm.Water())
    top = max(v[2] for v in full.block.vertices)
    assert full.water_pressure["joint 1"] <= 1000 * 9.81 * top / 6 + 1e-9
    custom = kgm.wedge(*planes, water=kgm.Water(pressures=(full.water_pressure["joint 1"],) * 2))
    assert custom.fs == pytest.approx(full.fs, rel=1e-12)
    with pytest.raises(ValueError, match="Water.pressures has 1 values"):
        kgm.wedge(*planes, water=kgm.Water(pressures=(1e4,)))


def test_seismic_coefficient_acts_along_the_sliding_trend():
    j = dd.Joint(friction=35.0)
    planes = (kgm.Plane(70, 180), kgm.Plane(5, 180), 15.0, [kgm.Plane(50, 130, j), kgm.Plane(55, 230, j)])
    static = kgm.wedge(*planes)
    k = kgm.wedge(*planes, seismic=0.15)
    along = kgm.wedge(*planes, seismic=kgm.Seismic(0.15, trend=static.sliding[0]))
    assert k.fs == pytest.approx(along.fs, rel=1e-12) and k.fs < static.fs
    # the worst horizontal direction is close to the sliding trend: none of 72 is much worse
    others = [kgm.wedge(*planes, seismic=kgm.Seismic(0.15, trend=t)).fs for t in range(0, 360, 5)]
    assert min(others) >= k.fs - 0.02


def test_falling_wedge_is_held_only_by_passive_support():
    """A pyramid in a roof, widening downwards (its joints meet 3 m above the roof): it falls,
    FS = 0, a = g; a passive bolt of capacity T pulling it up gives FS = T/W."""
    j = dd.Joint(friction=30.0, cohesion=0.0)
    apex, beta = np.array([0.0, 0.0, 3.0]), 30 * DEG
    hs = [Halfspace(np.array([0.0, 0.0, -1.0]), 0.0, "roof", "free")]       # the block above z = 0
    for k, theta in enumerate((0.0, 120.0, 240.0)):
        t = theta * DEG
        n = np.array([math.cos(t) * math.sin(beta), math.sin(t) * math.sin(beta), math.cos(beta)])
        hs.append(Halfspace(n, float(n @ apex), "abc"[k], "joint"))
    joints = {"a": j, "b": j, "c": j}
    w = kgm.polyhedral_block(hs, joints)
    assert w.forms and w.mode == "falling" and w.fs == 0.0
    assert w.acceleration == pytest.approx(9.81, rel=1e-12)
    assert w.sliding == pytest.approx((w.sliding[0], 90.0), abs=1e-9)
    held = kgm.polyhedral_block(hs, joints, bolts=[kgm.Bolt(0.6 * w.weight, 0.0, -90.0, "passive")])
    assert held.fs == pytest.approx(0.6, rel=1e-12)


def test_limit_state_is_the_study_evaluator():
    from kgm.wedges.study import limit_state

    j = dd.Joint(friction=30.0)
    base = kgm.wedge(kgm.Plane(70, 180), kgm.Plane(5, 180), 12.0, [kgm.Plane(50, 130, j), kgm.Plane(55, 230, j)])
    f = limit_state(base)
    phi = np.array([20.0, 30.0, 40.0])
    fs = f({"joint1_friction": phi, "joint2_friction": phi})
    for p, v in zip(phi, fs):
        w = kgm.wedge(kgm.Plane(70, 180), kgm.Plane(5, 180), 12.0, [kgm.Plane(50, 130, dd.Joint(friction=p)),
                                                                     kgm.Plane(55, 230, dd.Joint(friction=p))])
        assert v == pytest.approx(w.fs, rel=1e-12)
    assert np.isinf(f({"joint1_dip": np.array([89.0]), "joint2_dip": np.array([89.0])})[0])   # no wedge: safe


def test_a_held_block_needs_the_seismic_direction():
    """A block held without the earthquake has no sliding trend: k alone is refused, a trend
    works (a box on a flat floor between walls, pushed sideways: FS = tan φ / k)."""
    j = dd.Joint(friction=30.0)
    hs = [Halfspace(np.array([0.0, 0.0, 1.0]), 1.0, "top", "free"),
          Halfspace(np.array([0.0, 0.0, -1.0]), 0.0, "floor", "joint"),
          Halfspace(np.array([1.0, 0.0, 0.0]), 1.0, "east", "free"),
          Halfspace(np.array([-1.0, 0.0, 0.0]), 0.0, "west", "joint"),
          Halfspace(np.array([0.0, 1.0, 0.0]), 1.0, "north", "joint"),
          Halfspace(np.array([0.0, -1.0, 0.0]), 0.0, "south", "joint")]
    joints = {k: j for k in ("floor", "west", "north", "south")}
    assert kgm.polyhedral_block(hs, joints).fs == math.inf
    with pytest.raises(ValueError, match="kgm.Seismic"):
        kgm.polyhedral_block(hs, joints, seismic=0.2)
    w = kgm.polyhedral_block(hs, joints, seismic=kgm.Seismic(0.2, trend=90.0))
    assert w.fs == pytest.approx(math.tan(30 * DEG) / 0.2, rel=1e-12) and w.mode == "sliding on floor"
