"""kgm with water, bolts and a seismic coefficient against Hoek & Bray's planar failure.

A planar slide with a water-filled tension crack (Hoek & Bray, "Rock Slope Engineering"): slope
height H, face angle ψf, sliding plane ψp daylighting at the toe, a vertical tension crack of
depth z in the horizontal upper surface, water depth z_w in the crack, the water pressure on the
plane falling linearly from γw·z_w at the crack to 0 at the toe:

    A = (H − z)/sin ψp                       W = ½·γ·H²·[(1 − (z/H)²)·cot ψp − cot ψf]
    U = ½·γw·z_w·A                           V = ½·γw·z_w²
    FS = [c·A + (W·(cos ψp − k·sin ψp) − U − V·sin ψp)·tan φ] / [W·(sin ψp + k·cos ψp) + V·cos ψp]

with k the horizontal seismic coefficient. A bolt of force T plunging β below the horizontal
into the slope presses the plane with T·sin(β + ψp) and pulls against the sliding with
T·cos(β + ψp); as RocPlane defines them, an *active* bolt (pretension) adds the first to the
normal force and subtracts the second from the driving force, a *passive* bolt (capacity) adds
both to the resisting side:

    active:  FS = [c·A + (N + T·sin(β+ψp))·tan φ] / [D − T·cos(β+ψp)]
    passive: FS = [c·A + (N + T·sin(β+ψp))·tan φ + T·cos(β+ψp)] / D

with N and D the numerator's normal force and the denominator above. A vertical seismic
coefficient kv (upwards) scales the weight's share to W·(1 − kv).

Both kgm evaluators compute the same FS from the water forces they integrate on the real faces
and the vector form of §4.2 (rigid) or Sarma's strength reduction on the wedge split in two
(sarma); the only differences are round-off, far below the 0.5 % the closed form is held to.
"""

import math

import pytest

import ddatai as dd
import kgm

H, PSI_F, PSI_P, Z = 20.0, 60.0, 35.0, 6.0      # m, degrees, degrees, m
RHO, PHI, C = 2600.0, 30.0, 25e3                # kg/m³, degrees, Pa
G, RHO_W = 9.81, 1000.0
BETA = 15.0                                     # bolt plunge below the horizontal [degrees]
TOL = 0.005     # the evaluators are exact for one plane: only round-off separates them (~1e-15)


def _x_crack() -> float:
    return -(H - Z) / math.tan(math.radians(PSI_P))


def planar_scene(z_w: float, *, split: bool = False, bolt=None) -> tuple[dd.Scene, list[int]]:
    """The slope facing +x, toe at the origin; the wedge above the plane is free (split in
    two by a vertical joint when ``split``), everything else fixed."""
    s = dd.Scene(gravity=G)
    rock = dd.Material(density=RHO, young=1e9, poisson=0.25)
    xc = _x_crack()
    crest = -H / math.tan(math.radians(PSI_F))
    boundary = [(-60.0, -20.0), (40.0, -20.0), (40.0, 0.0), (0.0, 0.0), (crest, H), (-60.0, H)]
    jt = dd.Joint(friction=PHI, cohesion=C)
    tp = math.tan(math.radians(PSI_P))
    joints = [([(5.0, -5.0 * tp), (xc - 5.0, -(xc - 5.0) * tp)], jt),
              ([(xc, H + 1.0), (xc, H - Z - 1.0)], jt)]
    if split:
        xm = 0.5 * (xc + crest)
        joints.append(([(xm, H + 1.0), (xm, -xm * tp - 1.0)], jt))
    ids = s.cut(boundary, joints, material=rock)
    free = []
    for b in ids:
        cx, cy = s.polygon(b).mean(axis=0)
        inside = xc < cx < 0 and cy > -cx * tp and cy < H
        s.set_fixed(b, not inside)
        if inside:
            free.append(b)
    if z_w > 0:
        s.set_water_table([(-60.0, H - Z + z_w), (xc, H - Z + z_w), (0.0, 0.0), (40.0, 0.0)])
    if bolt is not None:
        tension, active = bolt
        # from the face, plunging β into the slope, across the plane into the fixed rock
        p1 = (0.5 * crest - 0.5, 0.5 * H - 0.3)
        b = math.radians(BETA)
        p2 = (p1[0] - 30.0 * math.cos(b), p1[1] - 30.0 * math.sin(b))
        s.add_bolt(p1, p2, stiffness=1e8, pretension=tension if active else 0.0, capacity=tension)
    return s, free


def closed_form(z_w: float, k: float = 0.0, kv: float = 0.0, bolt=None) -> float:
    """Hoek & Bray's FS (module docstring), with RocPlane's active/passive bolt terms."""
    gamma, gw = RHO * G, RHO_W * G
    pp, pf = math.radians(PSI_P), math.radians(PSI_F)
    area = (H - Z) / math.sin(pp)
    w = 0.5 * gamma * H ** 2 * ((1 - (Z / H) ** 2) / math.tan(pp) - 1 / math.tan(pf))
    u = 0.5 * gw * z_w * area
    v = 0.5 * gw * z_w ** 2
    normal = w * ((1 - kv) * math.cos(pp) - k * math.sin(pp)) - u - v * math.sin(pp)
    driving = w * ((1 - kv) * math.sin(pp) + k * math.cos(pp)) + v * math.cos(pp)
    resisting_extra = 0.0
    if bolt is not None:
        t, active = bolt
        normal += t * math.sin(math.radians(BETA) + pp)
        shear = t * math.cos(math.radians(BETA) + pp)
        if active:
            driving -= shear
        else:
            resisting_extra = shear
    return (C * area + normal * math.tan(math.radians(PHI)) + resisting_extra) / driving


def test_weight_of_the_wedge_matches_hoek_bray():
    """The cut wedge is Hoek & Bray's: its weight W = ½γH²[(1 − (z/H)²)cot ψp − cot ψf]."""
    s, free = planar_scene(0.0)
    sys_ = kgm.build_block_system(s)
    w = 0.5 * RHO * G * H ** 2 * ((1 - (Z / H) ** 2) / math.tan(math.radians(PSI_P))
                                  - 1 / math.tan(math.radians(PSI_F)))
    assert sys_.block_mass[free].sum() * G == pytest.approx(w, rel=1e-9)


@pytest.mark.parametrize("z_w", [0.0, 2.0, 4.0, 6.0])
@pytest.mark.parametrize("method", ["rigid", "sarma"])
def test_water_filled_tension_crack(z_w, method):
    """U on the plane and V in the crack, several water depths (dry to a full crack)."""
    s, free = planar_scene(z_w, split=method == "sarma")
    fs = kgm.factor_of_safety(s, free, method=method)
    assert fs == pytest.approx(closed_form(z_w), rel=TOL)


@pytest.mark.parametrize("z_w, k, kv", [(3.0, 0.1, 0.0), (6.0, 0.15, 0.0), (4.0, 0.1, 0.05)])
@pytest.mark.parametrize("method", ["rigid", "sarma"])
def test_water_and_seismic_coefficient(z_w, k, kv, method):
    """Pseudo-static kh·W towards the free face (+x) and kv·W upwards, with water."""
    s, free = planar_scene(z_w, split=method == "sarma")
    fs = kgm.factor_of_safety(s, free, method=method, seismic=(k, kv))
    assert fs == pytest.approx(closed_form(z_w, k, kv), rel=TOL)


@pytest.mark.parametrize("active", [True, False], ids=["active", "passive"])
@pytest.mark.parametrize("z_w", [2.0, 6.0])
@pytest.mark.parametrize("method", ["rigid", "sarma"])
def test_bolt_water_and_seismic(active, z_w, method):
    """A bolt of 1.5 MN/m across the plane: active (pretension) and passive (capacity)."""
    bolt = (1.5e6, active)
    s, free = planar_scene(z_w, split=method == "sarma", bolt=bolt)
    fs = kgm.factor_of_safety(s, free, method=method, seismic=(0.1, 0.0))
    expected = closed_form(z_w, 0.1, bolt=bolt)
    assert fs == pytest.approx(expected, rel=TOL)
    # the bolt matters: without it the slope is less safe by more than the tolerance
    assert expected > closed_form(z_w, 0.1) * (1 + 10 * TOL)


def test_analyze_reports_water_bolt_and_seismic_columns():
    """analyze finds the wedge, and its table gets U, bolt and seismic columns."""
    s, free = planar_scene(6.0, bolt=(1.5e6, False))
    rep = kgm.analyze(s, method="rigid", seismic=(0.1, 0.0))
    crit = rep.critical
    assert crit.blocks == frozenset(free)
    u = 0.5 * RHO_W * G * 6.0 * (H - Z) / math.sin(math.radians(PSI_P))
    assert crit.water_force == pytest.approx(u, rel=1e-9)
    assert crit.bolt_force == pytest.approx(1.5e6, rel=1e-9)
    head = rep.table().splitlines()[0]
    assert "U kN/m" in head and "bolt kN/m" in head and "kh, kv" in head
    dry = kgm.analyze(planar_scene(0.0)[0], method="rigid").table().splitlines()[0]
    assert "U kN/m" not in dry and "bolt" not in dry and "kh" not in dry


def test_time_varying_inputs_are_refused():
    """kgm is static: a ground acceleration or a load function raises, naming what to do."""
    s, free = planar_scene(0.0)
    s.set_ground_acceleration(lambda t: (0.1 * math.sin(t), 0.0))
    with pytest.raises(ValueError, match="ground acceleration"):
        kgm.analyze(s, method="rigid")
    s, free = planar_scene(0.0)
    s.add_point_load(free[0], tuple(s.polygon(free[0]).mean(axis=0)), lambda t: (1e3 * t, 0.0))
    with pytest.raises(ValueError, match="point load 0 .* varies with time"):
        kgm.factor_of_safety(s, free, method="sarma")
    with pytest.raises(ValueError, match="seismic"):
        kgm.analyze(planar_scene(0.0)[0], method="dda", seismic=(0.1, 0.0))
    with pytest.raises(ValueError, match="seismic"):
        kgm.analyze(planar_scene(0.0)[0], method="rigid", seismic=(1.5, 0.0))


def test_dda_evaluator_carries_bolts_and_water():
    """kgm's DDA judgement runs the sub-scene with the scene's bolts and water table: a
    frictionless block held by a bolt of 1.2 × its demand has the rigid FS C·cos α/(W·sinθ)
    = 1.2, and DDA's strength reduction (capacity ÷ F) finds it within its bracket (2 %) plus
    the judgement's acceleration resolution (1 %)."""
    from test_water_bolts import bolted, static_demand

    s, b = bolted(1.2 * static_demand())
    s.set_water_table([(-20.0, -5.0), (30.0, -5.0)])   # below the model: dry, but carried along
    assert kgm.factor_of_safety(s, [b], method="rigid") == pytest.approx(1.2, rel=1e-9)
    sub, ids = kgm.sub_scene(s, kgm.build_block_system(s), frozenset([b]), reduction=2.0)
    assert sub.water is s.water and len(sub.bolts) == 1
    assert sub.bolts[0].capacity == pytest.approx(0.6 * static_demand())
    assert kgm.factor_of_safety(s, [b], method="dda") == pytest.approx(1.2, rel=0.03)


def test_cli_takes_a_seismic_coefficient_and_shows_the_columns():
    """`kgm analyze SCENE --seismic KH[,KV]`: the table shows U, bolt and (kh, kv) columns,
    and the seismic load lowers the FS of the bolted slope."""
    import io
    from pathlib import Path

    from kgm.cli import main

    scene = str(Path(__file__).resolve().parents[1] / "scenes" / "bolted_slope.py")
    outs = []
    for extra in ([], ["--seismic", "0.1,0"]):
        out = io.StringIO()
        assert main(["analyze", scene, "--method", "rigid", *extra], out=out) == 0
        outs.append(out.getvalue())
    assert "U kN/m" in outs[0] and "bolt kN/m" in outs[0] and "kh, kv" not in outs[0]
    assert "kh, kv" in outs[1] and "0.1, 0" in outs[1]
    fs = [float(o.split("critical key group")[1].split("FS ")[1].split(",")[0]) for o in outs]
    assert fs[1] < fs[0]


def test_cli_gif_draws_the_water_table_and_the_bolts(tmp_path):
    """`kgm analyze --gif` of a limit-equilibrium result draws the scene's water table and
    bolts."""
    import io
    from pathlib import Path

    import numpy as np
    pytest.importorskip("PIL")
    from PIL import Image

    from ddatai import render
    from kgm.cli import main

    scene = str(Path(__file__).resolve().parents[1] / "scenes" / "bolted_slope.py")
    gif = tmp_path / "slope.gif"
    assert main(["analyze", scene, "--method", "rigid", "--gif", str(gif)], out=io.StringIO()) == 0
    image = Image.open(gif)
    image.seek(0)
    pixels = {tuple(p) for p in np.asarray(image.convert("RGB")).reshape(-1, 3).tolist()}
    assert render.WATER in pixels and render.BOLT in pixels


@pytest.mark.parametrize("level", [1.0, 2.0, 3.0])
def test_sarma_biplanar_pair_under_a_level_water_table(level):
    """Under a level table the water on each block sums to its buoyancy ρw·g·A_sub (vertical),
    and every face force is effective: the bi-planar pair's limit equilibrium is the dry one
    with the effective weights W' = (ρ·A − ρw·A_sub)·g (tests/cases.py, biplanar_critical_friction):
    E = μ·W'_B/(1 − μ²) and E·[(cos α + μ sin α)/(sin α − μ cos α) + μ] = W'_A. The water on the
    shared face enters both members (Sarma's internal face); critical φ within 0.01°."""
    import shapely
    from scipy.optimize import brentq

    from cases import BIPLANAR, biplanar_polygons, biplanar_scene

    scene, (a, b) = biplanar_scene(20.0)
    scene.set_water_table([(-10.0, level), (10.0, level)])
    upper, lower, _ = biplanar_polygons(**BIPLANAR)
    below = shapely.box(-100.0, -100.0, 100.0, level)
    w_a, w_b = (2500.0 * shapely.Polygon(p).area - RHO_W * shapely.Polygon(p).intersection(below).area
                for p in (upper, lower))   # W'/g of cases.ROCK blocks [kg/m]
    alpha = math.radians(BIPLANAR["dip"])

    def f(mu):
        e = w_b * mu / (1 - mu * mu)
        return e * ((math.cos(alpha) + mu * math.sin(alpha)) / (math.sin(alpha) - mu * math.cos(alpha)) + mu) - w_a

    expected = math.degrees(math.atan(brentq(f, 1e-9, min(math.tan(alpha), 1.0) - 1e-9)))
    dry = kgm.critical_friction(biplanar_scene(20.0)[0], [a, b], method="sarma")
    assert abs(expected - dry) > 0.05            # the water changes the answer
    assert kgm.critical_friction(scene, [a, b], method="sarma") == pytest.approx(expected, abs=0.01)


def test_passive_bolt_resists_toppling():
    """A 1 × 4 m column on a flat base pushed over its toe by F at its top (sliding held by
    φ = 45°), bolted at height h_b to a wall behind it (passive capacity C): about the toe the
    load overturns with M = F·h − W·b/2 and the bolt resists with C·h_b, so FS_rot = C·h_b/M;
    unbolted the column topples (FS 0)."""
    rock = dd.Material(density=2500.0, young=5e9, poisson=0.25)
    b, h, force, h_b, cap = 1.0, 4.0, 20e3, 3.0, 15e3

    def column(bolted: bool):
        s = dd.Scene(gravity=G)
        s.add_block([(-4, -1), (4, -1), (4, 0), (-4, 0)], material=rock, fixed=True)
        s.add_block([(-3, 0), (-2, 0), (-2, 5), (-3, 5)], material=rock, fixed=True)     # the wall
        col = s.add_block([(0, 0), (b, 0), (b, h), (0, h)], material=rock)
        s.set_joint(dd.Joint(friction=45.0))
        s.add_point_load(col, (0.5 * b, h), (force, 0.0))
        if bolted:
            s.add_bolt((0.1, h_b), (-2.5, h_b), stiffness=1e8, capacity=cap)
        return s, col

    weight = 2500.0 * G * b * h
    s, col = column(False)
    assert kgm.factor_of_safety(s, [col], method="rigid") == 0.0
    s, col = column(True)
    res = kgm.evaluate(s, [col], method="rigid")
    assert res.mode.kind.value == "rotation"
    assert res.fs == pytest.approx(cap * h_b / (force * h - weight * b / 2), rel=1e-9)
