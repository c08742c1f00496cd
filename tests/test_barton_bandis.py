"""Barton–Bandis joints (docs/method/barton_bandis.md): the law and its bounds, where a joint is
accepted, and a block on a plane in DDA and in every kgm evaluator.

The reference answer is the law itself, written out here: a block of height h on a plane of
dip θ presses it with σn = ρ·g·h·cosθ, and slides once θ exceeds the angle the joint mobilises
there, φr + JRC·log10(JCS/σn); the critical inclination θc solves θ = φr + JRC·log10(JCS/σn(θ)).

Tolerances:
- kgm's limit equilibrium takes a uniform normal stress on a face, as the law above: its θc is
  exact up to the root search (1e-6°);
- DDA carries the block on its two corner contacts, each over half the base; sliding tips the
  normal stress to the front corner by e = h·tanφ/b of the mean, and the law, concave in σn,
  loses ~0.03° of mobilised angle at e = 0.13 (the heavier block below); the brief's 0.2°
  covers that and the start-up of the run (within 0.2° of θc the verdict must be right);
- a block at rest moves only by its contact springs' elastic offset: drift below 1e-5 × its
  size (tests/test_verification.py).
"""

import math

import numpy as np
import pytest
from scipy.optimize import brentq

import ddatai as dd
import kgm
from cases import G, ROCK, block_on_incline, downslope_displacement, incline_base, law_slack
from kgm.build import build_block_system
from kgm.judges.run import judge

RHO = 2500.0
JRC, JCS, PHI_R = 8.0, 10e6, 20.0
WIDTH = 4.0
LIGHT, HEAVY = 0.2, 0.5   # block heights [m]


def law(sigma_n):
    """φr + JRC·log10(JCS/σn) [degrees] (no bound reached at the stresses used here)."""
    return PHI_R + JRC * math.log10(JCS / sigma_n)


def critical_inclination(height):
    return brentq(lambda th: th - law(RHO * G * height * math.cos(math.radians(th))), 1.0, 80.0,
                  xtol=1e-12)


def joint():
    return dd.BartonBandis(jrc=JRC, jcs=JCS, residual_friction=PHI_R)


def incline(theta, heights, at=(1.0, 7.0)):
    """Blocks of the given heights, all WIDTH wide, on one fixed plane of dip θ (one joint)."""
    scene = dd.Scene(gravity=G)
    incline_base(scene, theta, length=14.0)
    ids = [block_on_incline(scene, theta, at=a, width=WIDTH, height=h) for a, h in zip(at, heights)]
    scene.set_joint(joint())
    return scene, ids


def mobilised(theta, d, duration):
    """Friction angle that a slide of d in ``duration`` from rest implies [degrees]:
    d = ½·g·(sinθ − cosθ·tanφ)·t²."""
    th = math.radians(theta)
    acc = 2.0 * d / duration ** 2
    return math.degrees(math.atan((math.sin(th) - acc / G) / math.cos(th)))


# ----------------------------------------------------------------------------- the law
def test_law_and_bounds():
    j = dd.BartonBandis(jrc=10.0, jcs=50e6, residual_friction=25.0)
    assert j.mobilised_friction(50e3) == pytest.approx(25.0 + 10.0 * 3.0, abs=1e-12)
    assert j.friction == 25.0                               # the single angle: residual
    assert j.mobilised_friction(1.0) == 70.0                # capped (Barton & Choubey: 70°)
    assert j.mobilised_friction(0.0) == 70.0                # unloaded: the cap
    assert j.mobilised_friction(80e6) == 25.0               # σn ≥ JCS: residual
    assert j.shear_strength(5e6) == pytest.approx(5e6 * math.tan(math.radians(35.0)), rel=1e-12)
    assert isinstance(j, dd.Joint) and j != dd.Joint(friction=25.0)


@pytest.mark.parametrize("kwargs, name", [
    (dict(jrc=-1.0, jcs=50e6, residual_friction=25.0), "jrc"),
    (dict(jrc=25.0, jcs=50e6, residual_friction=25.0), "jrc"),
    (dict(jrc=5.0, jcs=0.0, residual_friction=25.0), "jcs"),
    (dict(jrc=5.0, jcs=50e6, residual_friction=75.0), "residual_friction"),
    (dict(jrc=5.0, jcs=50e6, residual_friction=25.0, max_friction=95.0), "max_friction"),
    (dict(jrc=5.0, jcs=50e6, residual_friction=25.0, cohesion=-1.0), "cohesion"),
    (dict(jrc=5.0, jcs=float("nan"), residual_friction=25.0), "jcs"),
])
def test_bad_values_name_the_parameter(kwargs, name):
    with pytest.raises(ValueError, match=f"BartonBandis.{name}"):
        dd.BartonBandis(**kwargs)


def test_jcs_in_mpa_is_warned():
    with pytest.warns(dd.UnitWarning, match="jcs"):
        dd.BartonBandis(jrc=5.0, jcs=50.0, residual_friction=25.0)


def test_accepted_wherever_a_joint_is():
    j = joint()
    scene = dd.Scene()
    ids = scene.cut([(0, 0), (4, 0), (4, 4), (0, 4)], [([(-1, 2), (5, 2)], j)], material=ROCK)
    scene.set_joint(j)
    scene.set_joint(dd.BartonBandis(jrc=2.0, jcs=JCS, residual_friction=30.0), between=tuple(ids))
    traces = dd.joint_sets([(0, 0), (4, 0), (4, 4), (0, 4)], [dd.JointSet(dip=30.0, spacing=1.0, joint=j)])
    assert traces and all(t[1] is j for t in traces)
    model = dd.build_model(scene)
    assert model.joint_barton.shape == (len(scene.joints), 6)
    mc = dd.build_model(_mc_scene())
    assert mc.joint_barton.shape == (0, 6)   # Mohr–Coulomb models carry nothing for it


def _mc_scene():
    scene = dd.Scene()
    incline_base(scene, 30.0)
    block_on_incline(scene, 30.0, at=4.0, width=1.0, height=1.0)
    scene.set_joint(dd.Joint(friction=35.0))
    return scene


# ----------------------------------------------------------------------------- kgm
@pytest.mark.parametrize("method", ["rigid", "sarma"])
def test_kgm_critical_inclination_is_the_law(method):
    """FS(θ) = 1 at θc, for two blocks of different weight on the same joint: their critical
    angles differ as the law says (JRC·log10 of their stress ratio, nearly)."""
    found = []
    for h in (LIGHT, HEAVY):
        def fs_minus_one(theta):
            scene, ids = incline(theta, [h], at=(4.0,))
            return kgm.factor_of_safety(scene, set(ids), method=method) - 1.0

        found.append(brentq(fs_minus_one, 30.0, 60.0, xtol=1e-10))
        assert found[-1] == pytest.approx(critical_inclination(h), abs=1e-6)
    assert found[0] - found[1] > 2.0   # the lighter block stands steeper


def test_kgm_sarma_faces_hold_the_law_at_their_own_stress():
    """A two-block group sliding on one plane, blocks of different weight: the Sarma forces
    at FS give each base face the friction of its own normal stress."""
    from kgm.judges.mechanisms import mechanisms, merge_faces
    from kgm.judges.sarma import _loaded, _statics_at

    theta = 40.0
    scene, ids = incline(theta, [LIGHT, LIGHT], at=(2.0, 2.0 + WIDTH))
    system = build_block_system(scene)
    members = sorted(ids)
    faces = merge_faces(system, members, frozenset())
    assert faces.tan_at is not None
    rep = kgm.evaluate(scene, set(ids), method="sarma")
    weight = system.block_mass[members] * system.gravity
    expected = math.tan(math.radians(law(RHO * G * LIGHT * math.cos(math.radians(theta))))) / math.tan(
        math.radians(theta))
    assert rep.fs == pytest.approx(expected, rel=1e-9)
    for mech in mechanisms(faces, system.block_force[members], len(members)):
        st = _statics_at(mech, faces, _loaded(system.block_force[members], None, mech, rep.fs), weight, rep.fs,
                         check=False)
        if st is None:
            continue
        base = mech.closed & (faces.b < 0)
        sigma = st.normal[base] / faces.length[base]
        assert np.allclose(faces.tan_at(st.normal)[base], np.tan(np.radians([law(s) for s in sigma])),
                           rtol=1e-9)


# ----------------------------------------------------------------------------- DDA
def test_dda_slides_with_the_friction_of_its_own_stress():
    """θ = 50°, above both critical angles: each block slides with the angle the law mobilises
    at its own normal stress (within 0.2°), the heavier one faster."""
    theta, duration = 50.0, 1.0
    scene, (light, heavy) = incline(theta, [LIGHT, HEAVY], at=(7.0, 1.0))
    res = dd.simulate(scene, duration=duration, record_every=1000)
    cos = math.cos(math.radians(theta))
    for b, h in ((light, LIGHT), (heavy, HEAVY)):
        d = downslope_displacement(res, b, theta)
        assert mobilised(theta, d, duration) == pytest.approx(law(RHO * G * h * cos), abs=0.2)
    assert downslope_displacement(res, heavy, theta) > downslope_displacement(res, light, theta)


def test_two_blocks_on_one_joint_get_their_own_verdict():
    """Between the two critical angles the light block stands and the heavy one slides, in DDA
    and in kgm."""
    theta = 0.5 * (critical_inclination(LIGHT) + critical_inclination(HEAVY))
    scene, (light, heavy) = incline(theta, [LIGHT, HEAVY], at=(7.0, 1.0))
    res = dd.simulate(scene, duration=1.0, record_every=1000)
    assert np.linalg.norm(res.centroid[-1, light] - res.centroid[0, light]) < 1e-5 * WIDTH
    assert downslope_displacement(res, heavy, theta) > 1e-2
    for method in ("rigid", "sarma"):
        assert kgm.factor_of_safety(scene, {light}, method=method) > 1.0
        assert kgm.factor_of_safety(scene, {heavy}, method=method) < 1.0


@pytest.mark.parametrize("offset", [-0.2, 0.2])
def test_dda_and_kgm_agree_either_side_of_the_limit(offset):
    """0.2° below θc the block stays (DDA: no drift; kgm: FS > 1, the DDA evaluator stable),
    0.2° above it slides (DDA: it moves; kgm: FS < 1, the DDA evaluator unstable)."""
    theta = critical_inclination(LIGHT) + offset
    scene, (b,) = incline(theta, [LIGHT], at=(4.0,))
    res = dd.simulate(scene, duration=1.0, record_every=1000)
    moved = downslope_displacement(res, b, theta)
    slides = offset > 0
    if slides:
        # a = g(sinθ − cosθ·tanφ(σn)) > 0: the slide of 1 s is ~2 cm; half of it at least
        th = math.radians(theta)
        tphi = math.tan(math.radians(law(RHO * G * LIGHT * math.cos(th))))
        assert moved > 0.5 * 0.5 * G * (math.sin(th) - math.cos(th) * tphi)
    else:
        assert abs(moved) < 1e-5 * WIDTH
    for method in ("rigid", "sarma"):
        assert (kgm.factor_of_safety(scene, {b}, method=method) < 1.0) is slides
    verdict = judge(scene, build_block_system(scene), frozenset([b]), settings=kgm.DdaSettings(duration=1.0))
    assert verdict.stable is not slides


# ----------------------------------------------------------------------------- kgm toppling
def _toppling_row(joint):
    from kgm.candidates import toppling_row
    from scenes import toppling_slope

    scene, _ = toppling_slope.build(friction=35.0)
    scene.set_joint(joint)
    system = build_block_system(scene)
    return toppling_row(system, frozenset(range(16)))


def test_toppling_with_a_smooth_barton_bandis_joint_is_mohr_coulomb():
    """JRC = 0: the law is φr at every stress, so Goodman & Bray's recursion (the textbook
    16-block row) gives the factor of safety of a Mohr–Coulomb joint at φr, to round-off."""
    from kgm.judges.toppling import row_factor_of_safety

    bb = row_factor_of_safety(_toppling_row(dd.BartonBandis(jrc=0.0, jcs=JCS, residual_friction=38.15)))
    mc = row_factor_of_safety(_toppling_row(dd.Joint(friction=38.15)))
    assert bb == pytest.approx(mc, rel=1e-9)


def test_toppling_with_a_rough_joint_lies_between_its_bounds():
    """A rough joint mobilises between φr and the cap at the row's stresses: its FS lies
    between the Mohr–Coulomb FS at φr and at the cap, and the interface forces of its
    recursion at that FS satisfy the law at their own stress."""
    from kgm.judges.toppling import recursion, row_factor_of_safety

    jt = dd.BartonBandis(jrc=6.0, jcs=JCS, residual_friction=30.0)
    row = _toppling_row(jt)
    fs = row_factor_of_safety(row)
    lo = row_factor_of_safety(_toppling_row(dd.Joint(friction=30.0)))
    steps = recursion(row, reduction=fs)
    hi = row_factor_of_safety(_toppling_row(dd.Joint(friction=70.0)))
    assert lo < fs < hi
    checked = 0
    for s, rb in zip(steps, row.blocks):
        if s.force_below > 0 and rb.below.tan_at is not None and rb.below.length > 0:
            expected = math.tan(math.radians(law_jrc(6.0, 30.0, s.force_below / rb.below.length)))
            assert rb.below.tan_at(s.force_below) == pytest.approx(expected, rel=1e-9)
            checked += 1
    assert checked > 5


def law_jrc(jrc, phir, sigma_n):
    return min(max(phir + jrc * math.log10(JCS / sigma_n), phir), 70.0)


def test_kgm_dda_factor_of_safety_reduces_the_law():
    """kgm's DDA evaluator reduces tan φ(σn) by F at each contact's stress (the sub-model's
    joints carry ``reduction``): its FS of a block at θ = 44° is the law's tan φ(σn)/tan θ
    within the bisection tolerance plus the DDA judgement's friction resolution
    Δtanφ ≈ a_r/(g cosθ) (tests/test_kgm_dda.py)."""
    theta = 44.0
    scene, (b,) = incline(theta, [LIGHT], at=(4.0,))
    s = kgm.DdaSettings()
    th = math.radians(theta)
    expected = math.tan(math.radians(law(RHO * G * LIGHT * math.cos(th)))) / math.tan(th)
    dtan = s.acceleration_resolution / (G * math.cos(th))
    fs = kgm.factor_of_safety(scene, {b}, method="dda")
    assert fs == pytest.approx(expected, abs=s.fs_tolerance + dtan / math.tan(th))
    assert kgm.factor_of_safety(scene, {b}, method="rigid") == pytest.approx(expected, rel=1e-9)


def test_dda_law_holds_at_every_contact_of_every_step():
    """The example section (Barton–Bandis bedding, Mohr–Coulomb cross joints; its key group
    slides): after every accepted step a locked contact's shear force is at most its strength
    N·tan φ(N/L) + c·L, and a sliding contact's friction equals it, φ(σn) written out here
    (bounded to [φr, 70°]; a corner contact, L = 0, at φr) — within the open-close tolerance
    (1e-3 of the load the contact's free blocks carry) plus the round-off force."""
    from ddatai.model import build_model
    from ddatai.start import settle
    from ddatai.step import Stepper
    from scenes.section import drawing

    scene = drawing.python_scene()
    model = build_model(scene)
    stepper = Stepper(model)
    state, _ = settle(stepper, model.initial_state())
    checked_bb = 0
    while state.time < 0.3:
        outcome = stepper.advance(state)
        state, c = outcome.state, outcome.contacts
        tan = np.empty(c.n)
        for i in range(c.n):
            jt = scene.joints[c.joint[i]]
            if isinstance(jt, dd.BartonBandis):
                n, length = c.normal_force[i], c.length[i]
                if length == 0:
                    phi = jt.residual_friction
                elif n <= 0:
                    phi = jt.max_friction
                else:
                    phi = min(max(jt.residual_friction + jt.jrc * math.log10(jt.jcs * length / n),
                                  jt.residual_friction), jt.max_friction)
                tan[i] = math.tan(math.radians(phi))
            else:
                tan[i] = math.tan(math.radians(jt.friction))
        strength = c.normal_force * tan + c.cohesion * c.length * c.bond
        # the open-close tolerance: 1e-3 of the load the contact's free blocks carry
        slack = law_slack(model, stepper, c)
        ve = c.cint[:, 0] == dd.ContactKind.VE
        locked = ve & (c.state == dd.ContactState.LOCK)
        sliding = ve & (c.state == dd.ContactState.SLIDE)
        assert np.all(model.shear_penalty * np.abs(c.ds[locked]) <= strength[locked] + slack[locked])
        assert np.all(np.abs(outcome.friction[sliding] - strength[sliding]) <= slack[sliding])
        bb = np.array([isinstance(scene.joints[j], dd.BartonBandis) for j in c.joint])
        checked_bb += int(np.count_nonzero((locked | sliding) & bb & (c.normal_force > 0)))
    assert checked_bb > 0
    assert np.any(sliding & bb)   # the key group slides on the bedding


def test_kgm_face_friction_scalar_and_array_forms_agree():
    """`BlockSystem.face_tan_function` (the iterations' scalar form) is `face_tan` (the
    array form) on faces of mixed joints, loaded and unloaded, to round-off."""
    from scenes.section import drawing

    system = build_block_system(drawing.python_scene())
    rng = np.random.default_rng(0)
    for _ in range(100):
        ks = rng.choice(system.n_contacts, size=int(rng.integers(1, 4)), replace=False)
        n = float(rng.choice([0.0, rng.uniform(1.0, 1e7)]))
        assert system.face_tan_function(ks)(n) == pytest.approx(system.face_tan(ks, n), rel=1e-12)


# ----------------------------------------------------------------------------- softening
def test_jrc_mobilisation_table_and_peak_displacement():
    """Barton's table beyond the peak, interpolated in log10(δ/δp) (eq. BB7), and Barton and
    Bandis' δp = (L/500)·(JRC/L)^0.33 (eq. BB8)."""
    from ddatai.params import barton_peak_displacement, jrc_mobilised

    peak = 2e-3
    ratios = np.array([0.1, 1.0, 2.0, 4.0, 10.0, 100.0, 1e4])
    np.testing.assert_allclose(jrc_mobilised(ratios * peak, peak), [1.0, 1.0, 0.85, 0.70, 0.50, 0.0, 0.0])
    mid = math.sqrt(4.0 * 10.0)  # halfway between 4 and 10 in log
    assert jrc_mobilised(mid * peak, peak) == pytest.approx(0.60, rel=1e-12)
    assert barton_peak_displacement(1.0, 10.0) == pytest.approx(1.0 / 500.0 * 10.0 ** 0.33, rel=1e-12)
    with pytest.raises(ValueError, match="BartonBandis.peak_displacement"):
        dd.BartonBandis(jrc=JRC, jcs=JCS, residual_friction=PHI_R, peak_displacement=0.0)


def test_dda_softening_slides_down_to_the_residual_friction():
    """δp = 0.5 mm: once the block has slid 100·δp (5 cm) its joint mobilises φr alone, and it
    accelerates at g(sinθ − cosθ·tanφr), as DDA slides on a Mohr–Coulomb joint (within 1e-3,
    tests/test_verification.py); without softening it keeps the peak and slides far slower.
    A run resumed from a checkpoint goes on bit for bit (the slid distance is carried)."""
    theta, duration = 50.0, 1.2
    th = math.radians(theta)
    soft = dd.BartonBandis(jrc=JRC, jcs=JCS, residual_friction=PHI_R, peak_displacement=5e-4)
    scene, (b,) = incline(theta, [LIGHT], at=(6.0,))
    scene.set_joint(soft)
    res = dd.simulate(scene, duration=duration)
    d = np.array([downslope_displacement(res, b, theta, k) for k in range(res.n_frames)])
    late = d > 0.2   # far beyond 100·δp
    acc = 2.0 * np.polyfit(res.time[late], d[late], 2)[0]
    assert acc == pytest.approx(G * (math.sin(th) - math.cos(th) * math.tan(math.radians(PHI_R))), rel=1e-3)
    peak_scene, _ = incline(theta, [LIGHT], at=(6.0,))
    peak = downslope_displacement(dd.simulate(peak_scene, duration=duration, record_every=1000), b, theta)
    assert d[-1] > 3.0 * peak


def test_softening_resumes_bit_for_bit(tmp_path):
    theta = 50.0
    soft = dd.BartonBandis(jrc=JRC, jcs=JCS, residual_friction=PHI_R, peak_displacement=5e-4)

    def scene():
        s, _ = incline(theta, [LIGHT], at=(6.0,))
        s.set_joint(soft)
        return s

    whole = dd.simulate(scene(), steps=40, checkpoint=tmp_path / "w.npz", checkpoint_every=20)
    path = tmp_path / "c.npz"
    dd.simulate(scene(), steps=20, checkpoint=path, checkpoint_every=20)
    resumed = dd.simulate(scene(), steps=40, resume=path)
    assert np.array_equal(whole.vertices, resumed.vertices)


def test_mohr_coulomb_models_carry_nothing_for_it():
    """No Barton–Bandis joint: no law table, no slid distance in the contact memory; a
    Barton–Bandis joint without softening stores no slid distance either."""
    from ddatai.model import build_model
    from ddatai.step import Stepper

    for joint_, table in ((dd.Joint(friction=35.0), (0, 6)), (joint(), (1, 6))):
        scene = _mc_scene()
        scene.set_joint(joint_)
        model = build_model(scene)
        assert model.joint_barton.shape == table
        stepper = Stepper(model)
        state = model.initial_state()
        for _ in range(3):
            state, _ = stepper.step(state)
        assert len(state.memory.key) > 0 and len(state.memory.slip) == 0
