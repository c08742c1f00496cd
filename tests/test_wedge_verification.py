"""Verification of the 3D wedge analysis (docs/kgm/wedge.md §6): closed forms derived here, and
published worked examples held to their printed precision.

Sources of the published numbers:

* Hoek & Bray, *Rock Slope Engineering* (3rd ed., 1981), Appendix 2, "comprehensive solution"
  of a wedge with a tension crack, water and external forces; reproduced with the same
  equations and the same example in Wyllie & Mah, *Rock Slope Engineering* (4th ed., 2004),
  Appendix III, §III.6 "Example" (parts 1a, 1b, 2 and 3), from which the numbers below are read.
* SWedge Verification Manual (Rocscience, 2019), problems 1–4: symmetric wedges judged by
  Kovári & Fritz's wedge factor λ = sin β / sin ω; at limit equilibrium the intersection's
  inclination satisfies tan iₐ = λ tan φ. The manual's own tables could not be read; its method
  is checked here on a family of wedges.
* Itasca, 3DEC verification problem "Sliding Wedge" (planes A 40°/130°, B 60°/220°, equal φ,
  c = 0): F = (R_A + R_B) tan φ / (W sin ψ), whose normal reactions we solve here.
* UnWedge theory (Rocscience): with c = 0 a block on one plane has FS = tan φ / tan α,
  whatever its weight.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

import ddatai as dd
import kgm
from kgm.wedges.geometry import Halfspace, plane_normal, trend_plunge

DEG = math.pi / 180


# ---------------------------------------------------------------- a block on one plane (prism)
def _prism(alpha, beta, height, width, joint, *, release=None):
    """A block on a plane dipping ``alpha`` towards +x (east), behind a face dipping ``beta``
    through the toe line (the y axis), under a horizontal upper face at ``height``, between
    two vertical release joints at y = 0 and y = ``width`` (frictionless by default)."""
    release = release or dd.Joint(friction=0.0)
    base = plane_normal(alpha, 90.0)
    face = plane_normal(beta, 90.0)
    hs = [Halfspace(face, 0.0, "slope face", "free"),
          Halfspace(np.array([0.0, 0.0, 1.0]), height, "upper face", "free"),
          Halfspace(-base, 0.0, "base", "joint"),
          Halfspace(np.array([0.0, -1.0, 0.0]), 0.0, "release south", "joint"),
          Halfspace(np.array([0.0, 1.0, 0.0]), width, "release north", "joint")]
    return hs, {"base": joint, "release south": release, "release north": release}


def test_block_on_one_plane_friction_only_is_tan_phi_over_tan_alpha():
    """FS = tan φ / tan α (c = 0, dry): α 35°, φ 40° → 1.1984 (UnWedge theory), for any size."""
    for height, width in ((10.0, 3.0), (250.0, 1.0)):
        hs, joints = _prism(35.0, 60.0, height, width, dd.Joint(friction=40.0))
        w = kgm.polyhedral_block(hs, joints, density=2650.0)
        assert w.forms and w.mode == "sliding on base"
        assert w.fs == pytest.approx(math.tan(40 * DEG) / math.tan(35 * DEG), rel=1e-12)
        assert round(w.fs, 4) == 1.1984
        assert w.sliding == pytest.approx((90.0, 35.0), abs=1e-9)


def test_block_on_one_plane_with_a_horizontal_seismic_coefficient():
    """FS = (cos α − k sin α) tan φ / (sin α + k cos α) for k·W horizontal towards the face:
    resolving W(−sin α·ŝ... ) along and across the plane; α 35°, φ 40°, k 0.1 → 0.9752."""
    hs, joints = _prism(35.0, 60.0, 20.0, 2.0, dd.Joint(friction=40.0))
    w = kgm.polyhedral_block(hs, joints, seismic=0.1)
    a, k = 35 * DEG, 0.1
    expected = (math.cos(a) - k * math.sin(a)) * math.tan(40 * DEG) / (math.sin(a) + k * math.cos(a))
    assert w.fs == pytest.approx(expected, rel=1e-12)
    assert round(w.fs, 4) == 0.9752
    # the same load as an explicit vector (kx east) and as kgm.Seismic with its trend
    assert kgm.polyhedral_block(hs, joints, seismic=(0.1, 0.0, 0.0)).fs == pytest.approx(expected, rel=1e-12)
    assert kgm.polyhedral_block(hs, joints, seismic=kgm.Seismic(0.1, trend=90.0)).fs == pytest.approx(expected,
                                                                                                     rel=1e-12)


def test_block_on_one_plane_with_cohesion_water_and_bolt():
    """FS = (c A + (W cos α − U + T sin θ) tan φ) / (W sin α − T cos θ): a base pressure u
    (U = u A) and an active anchor T pulling at θ to the plane, up-dip and into the base."""
    alpha, phi, c, h, width, rho, g = 30.0, 32.0, 15e3, 12.0, 4.0, 2600.0, 9.81
    hs, joints = _prism(alpha, 70.0, h, width, dd.Joint(friction=phi, cohesion=c))
    u, t, theta = 20e3, 300e3, 20.0
    a, th = alpha * DEG, theta * DEG
    up_dip = np.array([-math.cos(a), 0.0, math.sin(a)])
    into_base = -plane_normal(alpha, 90.0)
    d = math.cos(th) * up_dip + math.sin(th) * into_base
    bolt = kgm.Bolt(t, *trend_plunge(d))
    w = kgm.polyhedral_block(hs, joints, density=rho, gravity=g, water_pressures={"base": u}, bolts=[bolt])
    area = (h / math.sin(a)) * width
    weight = rho * g * w.volume
    assert w.volume == pytest.approx(0.5 * h * (h / math.tan(a) - h / math.tan(70 * DEG)) * width, rel=1e-12)
    expected = (c * area + (weight * math.cos(a) - u * area + t * math.sin(th)) * math.tan(phi * DEG)) / (
        weight * math.sin(a) - t * math.cos(th))
    assert w.areas["base"] == pytest.approx(area, rel=1e-12)
    assert w.fs == pytest.approx(expected, rel=1e-12)
    # the same anchor as a passive bolt resists only: FS = (c A + (W cos α − U + T sin θ) tan φ
    # + T cos θ) / (W sin α)
    w = kgm.polyhedral_block(hs, joints, density=rho, gravity=g, water_pressures={"base": u},
                             bolts=[kgm.Bolt(t, *trend_plunge(d), kind="passive")])
    expected = (c * area + (weight * math.cos(a) - u * area + t * math.sin(th)) * math.tan(phi * DEG)
                + t * math.cos(th)) / (weight * math.sin(a))
    assert w.fs == pytest.approx(expected, rel=1e-12)


# ---------------------------------------------------------------- 2D consistency
def _section_scene(alpha, beta, height, joint):
    """The prism's cross-section as a ddatai scene: the block on a fixed base (x towards the
    face, y up; the toe at the origin)."""
    ta, tb = math.tan(alpha * DEG), math.tan(beta * DEG)
    rock = dd.Material(density=2650.0, young=10e9, poisson=0.25)
    scene = dd.Scene(gravity=9.81)
    b = (-height / ta, height)
    ext = 5.0
    base = scene.add_block([(0.0, 0.0), b, (b[0] - ext, b[1] + ext * ta), (b[0] - ext, -3 * height),
                            (ext, -3 * height), (ext, -ext * ta)], material=rock, fixed=True)
    block = scene.add_block([(0.0, 0.0), (-height / tb, height), b], material=rock)
    scene.set_joint(joint, between=(base, block))
    return scene, block


@pytest.mark.parametrize("alpha, beta, phi, c, kh", [(35.0, 60.0, 40.0, 0.0, 0.0), (30.0, 65.0, 25.0, 40e3, 0.0),
                                                       (28.0, 55.0, 33.0, 25e3, 0.15)])
def test_prism_with_frictionless_release_planes_gives_the_2d_factor_of_safety(alpha, beta, phi, c, kh):
    """A prism whose sliding plane strikes parallel to the face, between frictionless vertical
    release planes, is the 2D section: FS equal to kgm's rigid limit equilibrium of that
    section per unit width, to 1e-9."""
    joint = dd.Joint(friction=phi, cohesion=c)
    scene, block = _section_scene(alpha, beta, 15.0, joint)
    fs2d = kgm.factor_of_safety(scene, {block}, method="rigid", seismic=(kh, 0.0) if kh else None)
    hs, joints = _prism(alpha, beta, 15.0, 3.0, joint)
    w = kgm.polyhedral_block(hs, joints, density=2650.0, gravity=9.81, seismic=kgm.Seismic(kh, trend=90.0) if kh
                             else None)
    assert w.fs == pytest.approx(fs2d, rel=1e-9, abs=0)


# ---------------------------------------------------------------- wedges by closed forms
def _wedge_geometry_reference(n1, n2, phi):
    """Independent closed form of a dry, cohesionless wedge sliding on both planes: the line of
    intersection i, the normal reactions from W = −R₁n₁ − R₂n₂ + (W·i)i (perpendicular to i),
    F = (R₁ + R₂) tan φ / (W sin ψ) (Hoek & Bray; the 3DEC verification's formula)."""
    i = np.cross(n1, n2)
    i = i / np.linalg.norm(i)
    i = i if i[2] < 0 else -i
    psi = math.asin(-i[2])
    w = np.array([0.0, 0.0, -1.0])
    perp = w - (w @ i) * i
    # −perp = R₁n₁ + R₂n₂: least squares on the 3×2 system (exact: perp ⟂ i)
    r, *_ = np.linalg.lstsq(np.column_stack([n1, n2]), -perp, rcond=None)
    return psi, r, (r[0] + r[1]) * math.tan(phi * DEG) / math.sin(psi)


def test_symmetric_wedge_by_kovari_fritz_wedge_factor():
    """60°/135° and 60°/225°, φ 30°: ψ 50.77°, wedge angle ξ 104.48°, K = sin β / sin(ξ/2) =
    1.2649 (β = 90°, symmetric), FS = K tan φ / tan ψ = 0.5963."""
    j = dd.Joint(friction=30.0)
    w = kgm.wedge(kgm.Plane(75, 180), kgm.Plane(0, 180), 20.0, [kgm.Plane(60, 135, j), kgm.Plane(60, 225, j)])
    n1, n2 = plane_normal(60, 135), plane_normal(60, 225)
    xi = math.pi - math.acos(n1 @ n2)
    i = np.cross(n1, n2)
    psi = math.asin(abs(i[2]) / np.linalg.norm(i))
    k = 1.0 / math.sin(xi / 2)
    assert (round(psi / DEG, 2), round(xi / DEG, 2), round(k, 4)) == (50.77, 104.48, 1.2649)
    assert w.fs == pytest.approx(k * math.tan(30 * DEG) / math.tan(psi), rel=1e-12)
    assert round(w.fs, 4) == 0.5963
    assert w.intersection == pytest.approx((180.0, psi / DEG), abs=1e-9)


@pytest.mark.parametrize("omega", [20.0, 35.0, 50.0, 65.0])
@pytest.mark.parametrize("phi", [25.0, 35.0])
def test_swedge_verification_method_limit_inclination(omega, phi):
    """SWedge Verification Manual, problems 1–4 (after Kovári & Fritz, checked against Kumsar,
    Aydan & Ulusay's tilting tests): a symmetric wedge of half wedge angle ω (each joint ω from
    the vertical bisecting plane) is at limit equilibrium when its intersection is inclined at
    iₐ with tan iₐ = tan φ / sin ω. Built at that iₐ, the vector analysis gives FS = 1."""
    ia = math.atan(math.tan(phi * DEG) / math.sin(omega * DEG))
    i = np.array([0.0, -math.cos(ia), -math.sin(ia)])             # trend 180°, plunge iₐ
    up = np.array([0.0, 0.0, 1.0]) - (-math.sin(ia)) * i
    up /= np.linalg.norm(up)
    side = np.array([1.0, 0.0, 0.0])
    planes = []
    for sgn in (1, -1):
        w_dir = math.cos(omega * DEG) * up + sgn * math.sin(omega * DEG) * side
        n = np.cross(i, w_dir)
        n = n if n[2] > 0 else -n
        planes.append(kgm.Plane(math.degrees(math.acos(n[2])), math.degrees(math.atan2(n[0], n[1])) % 360,
                                dd.Joint(friction=phi)))
    w = kgm.wedge(kgm.Plane(min(89.0, ia / DEG + 20), 180), kgm.Plane(0, 180), 10.0, planes)
    assert w.forms and w.mode == "sliding on joint 1 and joint 2"
    assert w.fs == pytest.approx(1.0, rel=1e-9)
    assert w.sliding[1] == pytest.approx(ia / DEG, abs=1e-9)


def test_3dec_sliding_wedge_and_its_acceleration():
    """3DEC "Sliding Wedge": A 40°/130°, B 60°/220°, equal φ, c = 0. The vector analysis gives
    the closed form F = (R_A + R_B) tan φ / (W sin ψ) at any size; its critical friction angle
    (F = 1) is 33.36°. Released at φ = 20° it slides along the intersection with
    a = g (sin ψ − (R_A + R_B) tan φ / W) = 2.694 m/s² for g = 10 m/s² (1.347 m after 1 s)."""
    n1, n2 = plane_normal(40, 130), plane_normal(60, 220)
    planes = lambda phi: [kgm.Plane(40, 130, dd.Joint(friction=phi)), kgm.Plane(60, 220, dd.Joint(friction=phi))]  # noqa
    for phi in (20.0, 30.0, 45.0):
        psi, r, fs = _wedge_geometry_reference(n1, n2, phi)
        for height in (5.0, 40.0):
            w = kgm.wedge(kgm.Plane(70, 175), kgm.Plane(5, 175), height, planes(phi), density=2000.0, gravity=10.0)
            assert w.mode == "sliding on joint 1 and joint 2"
            assert w.fs == pytest.approx(fs, rel=1e-10)
            assert np.array(w.normal_forces) / w.weight == pytest.approx(r, rel=1e-10)
    psi, r, _ = _wedge_geometry_reference(n1, n2, 30.0)
    assert (round(psi / DEG, 2), round(r[0], 4), round(r[1], 4)) == (37.06, 0.6733, 0.2421)
    phi_c = math.degrees(math.atan(math.sin(psi) / (r[0] + r[1])))
    assert round(phi_c, 2) == 33.36
    w = kgm.wedge(kgm.Plane(70, 175), kgm.Plane(5, 175), 10.0, planes(20.0), density=2000.0, gravity=10.0)
    a = 10.0 * (math.sin(psi) - (r[0] + r[1]) * math.tan(20 * DEG))
    assert w.acceleration == pytest.approx(a, rel=1e-10)
    assert round(w.acceleration, 3) == 2.694 and round(0.5 * w.acceleration, 3) == 1.347


# ---------------------------------------------------------------- Hoek & Bray's comprehensive example
FT = dict(density=160.0, gravity=1.0)                # γ = 160 lb/ft³ with g = 1: forces in lb


def _hoek_bray(water=False, **kw):
    j1, j2 = dd.Joint(friction=20.0, cohesion=500.0), dd.Joint(friction=30.0, cohesion=1000.0)
    return kgm.wedge(kgm.Plane(65, 185), kgm.Plane(12, 195), 100.0, [kgm.Plane(45, 105, j1), kgm.Plane(70, 235, j2)],
                     tension_crack=kgm.TensionCrack(kgm.Plane(70, 165), 40.0),
                     water=kgm.Water(density=62.5) if water else None, **FT, **kw)


def _printed(value, printed, digits):
    """``value`` and ``printed`` agree to the printed number of significant ``digits``."""
    return float(f"{value:.{digits}g}") == pytest.approx(float(f"{printed:.{digits}g}"), rel=1e-12)


def test_hoek_bray_comprehensive_example_saturated():
    """Wyllie & Mah App. III example (1a) = Hoek & Bray App. 2: H1 100 ft, L 40 ft, u from
    γw H5w / 3: areas, weight, pressure, crack thrust, normal reactions, S, Q and FS 1.1378."""
    w = _hoek_bray(water=True)
    assert w.forms and w.pyramid == "00" and w.mode == "sliding on joint 1 and joint 2"
    assert (round(w.intersection[1], 2), round(w.intersection[0], 2)) == (31.20, 157.73)    # ψi, αi
    assert round(w.areas["joint 1"], 2) == 5565.01
    assert round(w.areas["joint 2"], 1) == 6428.1
    # A5 printed 1846.6; the book's own m5, q5, n5, h5 (eq. III.56) give 1846.54, as we do: its
    # last digit is 3e-5 off, and V = u5·A5 (printed 2.0023e6) with it
    assert w.areas["tension crack"] == pytest.approx(1846.6, rel=5e-5)
    assert w.areas["tension crack"] == pytest.approx(0.58166 * 0.60945 * 87.521 ** 2 / (2 * 0.73527), rel=1e-5)
    assert _printed(w.weight, 2.8272e7, 5)
    assert round(w.water_pressure["joint 1"], 1) == 1084.3
    assert w.water_pressure["tension crack"] * w.areas["tension crack"] == pytest.approx(2.0023e6, rel=1e-4)
    # the book carries 5-digit intermediates (ρ, k_z, V, u1·A1 …): its forces are good to ~1e-4
    # (its own printed values in eq. III.61 give N1 = 1.51715e7, printed 1.5171e7; ours 1.51720e7)
    assert w.normal_forces[0] == pytest.approx(1.5171e7, rel=1e-4)
    assert w.normal_forces[1] == pytest.approx(5.7892e6, rel=1e-4)
    assert w.driving == pytest.approx(1.5886e7, rel=1e-4) and w.resisting == pytest.approx(1.8075e7, rel=1e-4)
    assert round(w.fs, 4) == 1.1378


def test_hoek_bray_comprehensive_example_dry():
    """Example (1b), dry: FS printed 1.7360 from N1 2.2565e7, N2 1.3853e7. The book's own
    equations with its printed ρ = µ = 1.03554, k_z 0.77047, l_z 0.47302 and W 2.8272e7 give
    N1 = ρ W k_z = 2.2557e7 and N2 = µ W l_z = 1.3848e7 (its wet case, part (1a), uses that
    W k_z): its dry line carries a slip of 3.5e-4. We hold the equations' values to the printed
    digits and FS to that slip: 1.7356 against the printed 1.7360."""
    w = _hoek_bray()
    assert _printed(w.normal_forces[0], 1.03554 * 0.77047 * 2.8272e7, 5)
    assert _printed(w.normal_forces[1], 1.03554 * 0.47302 * 2.8272e7, 5)
    assert _printed(w.driving, 1.4644e7, 5)
    assert w.fs == pytest.approx(1.7360, abs=5e-4)


def test_hoek_bray_minimum_factor_of_safety_under_a_load_in_its_worst_direction():
    """Example (2): the dry wedge under E = 8e6 lb in its worst direction: FS_min 1.04, the
    force plunging −1.62° (upwards) at trend 173.03°. Read from the dry state (1b), whose slip
    (above) moves the direction by < 0.01°."""
    fs, trend, plunge = _hoek_bray().worst_force(8e6)
    assert round(fs, 2) == 1.04
    assert trend == pytest.approx(173.03, abs=0.01) and plunge == pytest.approx(-1.62, abs=0.01)
    # it is the least: no other direction of the same force gives less
    from kgm.wedges.geometry import direction_vector
    from kgm.wedges.mechanics import equilibrium

    w = _hoek_bray()
    rng = np.random.default_rng(3)
    for t, p in zip(rng.uniform(0, 360, 400), np.degrees(np.arcsin(rng.uniform(-1, 1, 400)))):
        other = equilibrium(w.contacts, w.active + 8e6 * direction_vector(t, p), w.passive, w.mass).fs
        assert other >= fs - 1e-9
    assert _hoek_bray(forces=[kgm.Force(8e6, trend, plunge)]).fs == pytest.approx(fs, rel=1e-9)
    assert w.fs > fs


def test_hoek_bray_minimum_anchor_force_for_a_design_factor_of_safety():
    """Example (3): the saturated wedge needs T_min = 3.4307e6 lb, plunging −6.98° at trend
    349.43°, for FS 1.5 (the book rounds S′ and Q′ to 5 digits before T = (F S′ − Q′)/χ,
    χ = 1.6772: 3.4307e6; their exact values give 3.43045e6, 7e-5 apart). Applied as an active
    anchor, it gives FS 1.5."""
    w = _hoek_bray(water=True)
    sup = w.required_support(1.5)
    assert sup.force == pytest.approx(3.4307e6, rel=1e-4)
    assert round(sup.plunge, 2) == -6.98 and round(sup.trend, 2) == 349.43
    anchored = _hoek_bray(water=True, bolts=[kgm.Bolt(sup.force, sup.trend, sup.plunge)])
    assert anchored.fs == pytest.approx(1.5, rel=1e-9)
    # the book's approximation: plunge ½(φ1 + φ2) − ψi upwards, trend αi + 180°
    assert sup.trend == pytest.approx(157.73 + 180, abs=12) and sup.plunge == pytest.approx(25 - 31.2, abs=1.0)
    # a pressure on the slope face normal to it gives FS 1.5 as well
    face = w.block.face("slope face")
    pushed = _hoek_bray(water=True, forces=[kgm.Force(sup.pressure * face.area, *trend_plunge(-face.normal))])
    assert pushed.fs == pytest.approx(1.5, rel=1e-9)
