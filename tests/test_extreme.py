"""Property-based suite: random valid scenes (tests/extreme_cases.py) run with the default
parameters must finish with finite values, no penetration above the limit, no energy created
and Coulomb's law at every closed contact — or be refused before any work with a reason.

The default run draws a short profile; ``pytest -m slow tests/test_extreme.py`` runs the long
profile (2,000 examples). Cases that hypothesis shrank from failures are kept below as named
regression tests.
"""

from __future__ import annotations

import math
import re
import warnings

import numpy as np
import pytest

hypothesis = pytest.importorskip("hypothesis", reason="the property suite needs hypothesis (pip install -e '.[test]')")
from hypothesis import HealthCheck, given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402

from extreme_cases import REGIMES, SHAPES, CaseSpec, build, check, random_domain, random_spec, run_case  # noqa: E402

import ddatai as dd  # noqa: E402


def _log_uniform(lo: float, hi: float):
    return st.floats(math.log(lo), math.log(hi)).map(math.exp)


@st.composite
def cases(draw, regime: str, steps: int = 25):
    r = REGIMES[regime]
    strength = r["strength"][1]
    speed = st.floats(-2.5 * r["speed"], 2.5 * r["speed"])
    base = dict(
        size=draw(_log_uniform(*r["size"])), density=draw(st.floats(*r["density"])),
        young=draw(_log_uniform(*r["young"])), poisson=draw(st.floats(*r["poisson"])),
        friction=draw(st.floats(*r["friction"])),
        cohesion=draw(st.one_of(st.just(0.0), st.floats(0.0, strength))),
        tensile=draw(st.one_of(st.just(0.0), st.floats(0.0, strength))),
        gravity=draw(st.sampled_from([9.81, 0.0])),
        load=draw(st.one_of(st.just(0.0), st.floats(0.0, 10.0))),
        shaking=draw(st.one_of(st.just(0.0), st.floats(0.0, 5.0))), steps=steps)
    if draw(st.booleans()):
        n = draw(st.integers(1, 4))
        return CaseSpec(
            kind="stack", shapes=tuple(draw(st.sampled_from(SHAPES)) for _ in range(n)),
            aspects=tuple(draw(_log_uniform(0.3, 3.3)) for _ in range(n)),
            gaps=tuple(draw(st.one_of(st.just(0.0), st.floats(0.0, 0.5))) for _ in range(n)),
            shifts=tuple(draw(st.floats(-0.5, 0.5)) for _ in range(n)),
            velocities=tuple((draw(speed), draw(speed)) for _ in range(n)),
            spins=tuple(draw(st.floats(-2.5 * r["spin"], 2.5 * r["spin"])) for _ in range(n)), **base)
    n = draw(st.integers(1, 3))
    joints = tuple((draw(st.floats(0.2, 0.8)), draw(st.floats(0.2, 0.8)), draw(st.floats(0.0, 180.0)))
                   for _ in range(n))
    return CaseSpec(kind="cut", joints=joints, **base)


def _twin_contacts(twin: str, model, xy):
    """The contacts (cint) that the detection version ``twin`` finds at ``xy``: the Taichi
    kernels, their NumPy twin or the brute-force reference."""
    from ddatai import reference, vectorized

    if twin == "kernels":
        from ddatai.contacts import _Buffers, detect_contacts

        return detect_contacts(model, xy, _Buffers())[0]
    return (vectorized if twin == "vectorized" else reference).detect_contacts(model, xy)[0]


def _depths(model, xy, vertex, edge):
    """Signed distance of each vertex from its edge's line (negative: penetration)."""
    from ddatai.contacts import signed_distance

    return signed_distance(xy, model.vertex_next, vertex, edge)


def _holds(spec: CaseSpec, refuse_ok: bool, params: "dict | None" = None) -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # strain and precision warnings are part of the contract
        out = run_case(spec, params)
    if out.status == "refused":
        # a refusal must say what to change, and is allowed only where the regime allows it
        assert refuse_ok, f"refused a rock-like scene: {out.message}\n{spec!r}"
        assert "block" in out.message or "joint" in out.message, out.message
        return
    assert out.status == "ok", f"{out.status}: {out.message}\n{spec!r}"
    assert not out.problems, f"{out.problems}\n{spec!r}"


LONG = settings(max_examples=1000, deadline=None, database=None,
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])


# The default run draws its 25 scenes a regime with NumPy from fixed seeds (`random_spec`, the
# same ranges as `cases`), not with hypothesis: hypothesis mixes the literal constants of every
# project module loaded so far into what it draws, so even derandomised its examples change
# with the modules earlier tests happened to import, and the default run would test other
# scenes than a run of this file alone. The slow profile below explores with hypothesis.
@pytest.mark.parametrize("seed", range(25))
def test_rock_like_scenes_run_through(seed):
    _holds(random_spec(np.random.default_rng(1000 + seed), "rock", steps=25), refuse_ok=True)


#: seed 20: a 0.75 m domain of dense stiff rock (ρ 10,675 kg/m³, E 54 GPa, c 8.8 MPa) cut by
#: three joints, under a point load of 4.5 × its weight, with a crumb of 2.3e-7 m² (0.24 mm
#: thick) between three blocks: its neighbours' vertices lay 0.6 mm behind its edges' lines —
#: beyond the crumb, outside it — and were taken for contacts, which the open-close iteration
#: closed and opened for 20 iterations at every Δt down to 2e-9 s, until the crumb turned inside
#: out. A vertex in front of any edge of a convex block is no contact of it (docs/method/dda.md
#: §3.3 rule 3); the scene runs
@pytest.mark.parametrize("seed", range(25))
def test_extreme_scenes_run_through_or_are_refused(seed):
    _holds(random_spec(np.random.default_rng(2000 + seed), "extreme", steps=25), refuse_ok=True)


#: cut campaign seeds (`extreme_cases.random_domain`, `benchmarks/extreme.py --regime cut`) of
#: at most 64 free blocks (the NumPy path: no kernel compile in the default run), a few seconds
#: each; 14 ran away at step 30 on a false corner contact (docs/method/dda.md §3.3 rule 3), as
#: did 1 (`test_cut_domain_with_a_sliver_at_an_acute_corner_runs`, slow)
CUT_SEEDS = (0, 2, 5, 14)


@pytest.mark.parametrize("seed", CUT_SEEDS)
def test_cut_domains_run_through(seed):
    _holds(random_domain(np.random.default_rng(seed), steps=35), refuse_ok=False)


@pytest.mark.slow
@LONG
@given(cases("rock", steps=100))
def test_rock_like_scenes_long(spec):
    _holds(spec, refuse_ok=True)


@pytest.mark.slow
@LONG
@given(cases("extreme", steps=100))
def test_extreme_scenes_long(spec):
    _holds(spec, refuse_ok=True)


# ---------------------------------------------------------------- named regressions

@pytest.mark.xfail(strict=True, reason="known: the integrator creates O(Δt) energy here (1.76 J/m by "
                   "step 22 at Δt = 10 ms, 0.22 J/m at 2.5 ms) beyond the allowance of the penalty "
                   "springs; the source is not found yet")
def test_frictionless_wedge_under_a_tilting_block_creates_no_energy():
    """Found by Hypothesis: a 4 × 3 m frictionless block cut by a horizontal joint and a 22°
    joint slides apart under gravity — the wedge under the 22° joint and the small triangle it
    cuts off the upper block slide right at ~1 m/s while the other two blocks tilt together —
    and the balance's rest falls to −1.76 J/m (kinetic energy 1,780 J/m), below the 1.4 J/m the
    penalty springs and tolerances allow. Strict: it fails the day the cause is fixed. Run
    under the strict open-close test (`ddatai.STRICT_CONVERGENCE`): the default's 1e-3 of the
    load carried allows work of that fraction of the energies (1.8 J/m here), which hides it."""
    spec = CaseSpec(kind="cut", size=1.0, density=800.0, young=float(np.exp(22.0)), poisson=0.0,
                    friction=0.0, cohesion=0.0, tensile=0.0, gravity=9.81, shapes=(), aspects=(),
                    gaps=(), shifts=(), velocities=(), spins=(), joints=((0.5, 0.5, 0.0), (0.5, 0.25, 22.0)),
                    load=0.0, shaking=0.0, steps=25)
    _holds(spec, refuse_ok=False, params=dd.STRICT_CONVERGENCE)


def _drop(speed: tuple, gravity: float, height: float = 0.5):
    scene = dd.Scene(gravity=gravity)
    rock = dd.Material(density=2600.0, young=10e9, poisson=0.25)
    scene.add_block([(-3, -1), (4, -1), (4, 0), (-3, 0)], material=rock, fixed=True)
    scene.add_block([(0, height), (1, height), (1, height + 1), (0, height + 1)], material=rock,
                    velocity=speed)
    scene.set_joint(dd.Joint(friction=30.0))
    return scene


@pytest.mark.parametrize("speed", [(0.0, -20.0), (5.0, -5.0), (0.0, -50.0)])
def test_impact_without_gravity(speed):
    """A block thrown at a fixed base without gravity: the time step took the cancelling root of
    ½aΔt² + vΔt = u and came out 0 (NaN at step 9 / 51). It must bounce, not tunnel: it never
    goes below the base beyond the penetration limit and ends moving away."""
    scene = _drop(speed, 0.0)
    model = dd.build_model(scene)
    res = dd.simulate(scene, duration=0.2)
    assert np.all(np.isfinite(res.vertices))
    assert res.steps["max_penetration"].max() <= model.penetration_limit
    lowest = res.vertices[:, 4:, 1].min()  # vertices of the free block
    assert lowest > -model.penetration_limit
    assert res.velocity[-1, 1, 1] > 0.0  # bounced


def test_time_step_has_no_cancellation():
    """Δt for a fast block with a round-off acceleration is v-limited, not 0."""
    from ddatai.time_step import choose_time_step

    model = dd.build_model(_drop((0.0, -20.0), 0.0))
    state = model.initial_state()
    dt = choose_time_step(model, state.replace(accel=1e-30), model.block_geometry(state.vertex_xy))
    assert dt == pytest.approx(min(model.max_step / 20.0, model.params.dt_max), rel=1e-9)


def test_soft_heavy_column_runs():
    """Weak rock mass (E = 20 MPa, ρ = 2,700 kg/m³, 3 blocks of 5 m: self-weight strain ~2 %):
    with 50·E the contacts sank past the penetration limit ("runaway penetration"); the
    automatic penalty now follows the column's load and the run finishes at rest."""
    scene = dd.Scene()
    soft = dd.Material(density=2700.0, young=20e6, poisson=0.3)
    scene.add_block([(-5, -5), (10, -5), (10, 0), (-5, 0)], material=soft, fixed=True)
    for k in range(3):
        scene.add_block([(0, 5 * k), (5, 5 * k), (5, 5 * k + 5), (0, 5 * k + 5)], material=soft)
    scene.set_joint(dd.Joint(friction=35.0))
    model = dd.build_model(scene)
    assert model.penalty > 50 * 20e6
    res = dd.simulate(scene, steps=100)
    assert res.steps["max_penetration"].max() <= model.penetration_limit
    # not a bound from the method: "ends at rest" (the ringing of a sudden start at this
    # stiffness would be ~0.1 m/s)
    assert np.abs(res.velocity[-1, 1:]).max() < 1e-2


def test_beyond_first_order_strain_is_refused_before_work():
    scene = dd.Scene()
    mud = dd.Material(density=2000.0, young=1e5, poisson=0.3)
    scene.add_block([(-5, -5), (10, -5), (10, 0), (-5, 0)], material=mud, fixed=True)
    scene.add_block([(0, 0), (5, 0), (5, 5), (0, 5)], material=mud)
    with pytest.raises(ValueError, match=r"block 1: elastic strain .* Young's modulus"):
        dd.build_model(scene)


def test_fast_soft_block_warns():
    scene = _drop((0.0, -10.0), 9.81)  # rock: v·√(ρ/E) = 5e-3, no warning
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        dd.build_model(scene)
    soft = dd.Scene()
    clay = dd.Material(density=2000.0, young=2e7, poisson=0.3)
    soft.add_block([(-3, -1), (4, -1), (4, 0), (-3, 0)], material=clay, fixed=True)
    soft.add_block([(0, 0.5), (1, 0.5), (1, 1.5), (0, 1.5)], material=clay, velocity=(0.0, -10.0))
    with pytest.warns(UserWarning, match=r"block 1: elastic strain 0.1 from an impact"):
        dd.build_model(soft)


def test_far_from_origin_warns():
    scene = dd.Scene()
    rock = dd.Material(density=2600.0, young=10e9, poisson=0.25)
    scene.add_block([(-3, -1), (4, -1), (4, 0), (-3, 0)], material=rock, fixed=True)
    scene.add_block([(0, 0), (1, 0), (1, 1), (0, 1)], material=rock)
    scene.add_block([(1e7, 0), (1e7 + 1, 0), (1e7 + 1, 1), (1e7, 1)], material=rock)
    with pytest.warns(UserWarning, match=r"block 2 lies farthest from the others"):
        dd.build_model(scene)


def test_far_away_model_runs_as_at_the_origin():
    """A model placed 1e9 m from the origin is centred internally: the same motion as at 0."""
    def sliding(x0):
        scene = dd.Scene()
        rock = dd.Material(density=2600.0, young=10e9, poisson=0.25)
        scene.add_block([(x0 - 3, -1), (x0 + 4, -1), (x0 + 4, 0), (x0 - 3, 0)], material=rock, fixed=True)
        scene.add_block([(x0, 0), (x0 + 1, 0), (x0 + 1, 1), (x0, 1)], material=rock, velocity=(1.0, 0.0))
        scene.set_joint(dd.Joint(friction=30.0))
        return dd.simulate(scene, duration=0.1)

    near, far = sliding(0.0), sliding(1e9)
    # 1e9 m is resolved to 1.2e-7 m in double precision: the centroids agree to a few of those
    assert far.centroid[-1, 1, 0] - 1e9 == pytest.approx(near.centroid[-1, 1, 0], abs=1e-6)


@pytest.mark.parametrize("density, young, poisson, friction, shaking", [
    (1800.0, math.exp(20.0), 0.25, 10.0, 1.0),
    (800.0, math.exp(14.0), 0.0, 7.0, 2.0),
])
def test_shaken_cut_block_without_gravity(density, young, poisson, friction, shaking):
    """Shrunk by the long profile: a domain cut in two by a flat joint, no gravity, shaken
    sideways. Friction work and the ground's work are round-off at the start (1e-12 J/m); the
    balance holds within the open-close tolerances (oc_force_tolerance of the energy flow), not
    within 1e-9 of the energies."""
    spec = CaseSpec(kind="cut", size=1.0, density=density, young=young, poisson=poisson,
                    friction=friction, cohesion=0.0, tensile=0.0, gravity=0.0,
                    joints=((0.5, 0.5, 0.0),), shaking=shaking, steps=100)
    _holds(spec, refuse_ok=False)


@pytest.mark.parametrize("spec", [
    CaseSpec(kind="stack", size=1.0, density=800.0, young=1202604.2841647768, poisson=0.4375, friction=33.0,
             cohesion=0.0, tensile=0.0, gravity=9.81, shapes=("rect",), aspects=(1.0,), gaps=(0.0,),
             shifts=(0.0,), velocities=((0.0, 0.0),), spins=(0.0,), steps=100),
    CaseSpec(kind="cut", size=1.0, density=1800.0, young=485165195.4097903, poisson=0.109375, friction=37.0,
             cohesion=0.0, tensile=0.0, gravity=0.0, joints=((0.5, 0.25, 0.0),), load=1.0, steps=100),
], ids=["soft-block-at-rest", "loaded-cut-domain"])
def test_start_energy_counts_the_stage_s_shear_springs(spec):
    """Shrunk by the long profile: a block the equilibrium stage leaves with its contacts locked
    at their strength. The first step's start energy measured those shear springs at ds = 0
    (the stage's lock point carries ds = S/ks), so a block at rest 'created' 0.27 J/m in step 1;
    the start energy now takes each spring as the step finds it."""
    _holds(spec, refuse_ok=False)


def test_pile_up_at_40_m_per_s_runs():
    """Shrunk by the long profile: four blocks thrown into each other and the base at ~40 m/s.
    With the impact penalty sized for a quarter of the penetration limit (p = 5e12 Pa, 1.7e4·E)
    the step exploded (a 2,653 m step displacement) at step 39; sized for the limit it runs."""
    spec = CaseSpec(kind="stack", size=1.0, density=2262.188460254739, young=3e8, poisson=0.1,
                    friction=36.21246063788806, cohesion=0.0, tensile=0.0, gravity=9.81,
                    shapes=("ell", "rect", "rect", "rect"), aspects=(1.8868891906842042, 0.4326133624909681, 1.0, 1.0),
                    gaps=(0.4580925773305716, 0.0, 0.0, 0.0), shifts=(0.0, 0.45469061723130344, 0.0, 0.0),
                    velocities=((-37.504905583649716, 0.0), (0.0, -41.30843549533605), (0.0, -36.0), (0.0, 0.0)),
                    spins=(0.0, 0.0, 0.0, 0.0), steps=100)
    _holds(spec, refuse_ok=False)


@pytest.mark.parametrize("spec", [
    CaseSpec(kind="stack", size=1.0, density=2262.188460254739, young=3e8, poisson=0.12170610398205237,
             friction=36.21246063788806, cohesion=0.0, tensile=0.0, gravity=0.0,
             shapes=("ell", "polygon", "rect", "ell"), aspects=(1.8868891906842042, 0.4326133624909681, 0.4326133624909681, 3.3),
             gaps=(0.4580925773305716, 0.0, 0.0, 0.0), shifts=(0.0, 0.45469061723130344, 0.006533529605422861, 0.0),
             velocities=((-37.504905583649716, 0.0), (0.0, -41.30843549533605), (-10.006421207571279, -37.535380306094886), (-1.9, 0.5)),
             spins=(4.819626315977349, 0.0, 0.0, 4.0), load=2.3844528945167025, steps=100),
    CaseSpec(kind="cut", size=1.0, density=6955.0, young=1202604.2841647768, poisson=0.25, friction=57.5,
             cohesion=0.0, tensile=0.0, gravity=9.81, joints=((0.5, 0.5, 0.0), (0.4375, 0.3359375, 146.5)), steps=100),
], ids=["spinning-impacts-11-percent-strain", "soft-heavy-17-percent-strain"])
def test_strained_models_are_warned_and_run(spec):
    """Shrunk by the long profile: models whose blocks strain 11 % (impact at 41 m/s, E = 0.3 GPa)
    and 17 % (weight, E = 1.2 MPa, ρ = 6,955 kg/m³) created 2 % and 0.3 % of their energy. They
    are warned before the run (small-strain accuracy); they must still finish with every other
    property, and the warning must name the block."""
    import ddatai as dd

    scene, _ = build(spec)
    with pytest.warns(UserWarning, match=r"block \d+: elastic strain"):
        dd.build_model(scene)
    _holds(spec, refuse_ok=False)


def test_spinning_block_leaving_its_base():
    """Shrunk by the long profile: a 2.7 m block settled on its base, launched up at 5 m/s with
    a spin of 2 rad/s. Its area grows as its settled strain is released, and DDA's constant
    density adds ρ·ΔS of mass: its spin energy grows by 2ΔS/S of itself, which the energy
    balance allows as it allows the translation's."""
    spec = CaseSpec(kind="stack", size=math.e, density=1800.0, young=333448837.24767584, poisson=0.25,
                    friction=10.0, cohesion=0.0, tensile=0.0, gravity=9.81, shapes=("rect",), aspects=(math.e,),
                    gaps=(0.0,), shifts=(0.0,), velocities=((0.0, 5.0),), spins=(2.0,), steps=100)
    _holds(spec, refuse_ok=False)


def test_soft_frictionless_mass_at_35_percent_strain_is_refused():
    """Shrunk by the long profile: a 1 MPa, 11,881 kg/m³ domain cut by frictionless cohesive
    joints (weight strain 0.35) turned singular at step 46. Beyond 25 % strain the stage cannot
    tell a block's deformation from a mechanism: refused before any work, naming the block."""
    spec = CaseSpec(kind="cut", size=1.0, density=11881.390705363707, young=1e6, poisson=0.0505099107197387,
                    friction=0.0, cohesion=2077855.8864777847, tensile=2658362.0, gravity=9.81,
                    joints=((0.5, 0.74609375, 0.0), (0.380859375, 0.6171875, 165.0)), steps=100)
    out = run_case(spec)
    assert out.status == "refused"
    assert "block 1: elastic strain 0.35" in out.message and "exceeds 0.25" in out.message


@pytest.mark.parametrize("dt_max", [None, 1e-3])
def test_wedge_tip_sliding_past_a_corner_keeps_its_contact(dt_max):
    """Shrunk by the long profile: a constant point load (¼ of the block's weight) on a block
    sliding on a 33° cut joint, no gravity, φ = 34°, c = 26 Pa. The upper block is a wedge whose
    tip starts on the lower block's corner; sliding, the tip moved along the joint, and while it
    was within the search distance of that corner but not the corner's nearest vertex (the
    wedge's 1.4 cm end edge put its other vertex nearer), detection tested it against no edge:
    the tip sank 1.3 mm into the lower block unseen, and the contact found at last threw the
    blocks apart (17.8 J/m created by step 70; 2,330 J/m with Δt ≤ 1 ms)."""
    spec = CaseSpec(kind="cut", size=1.0, density=1800.0, young=1318815734.4832146, poisson=0.25, friction=34.0,
                    cohesion=26.0, tensile=0.0, gravity=0.0, joints=((0.5, 0.5625, 33.0),), load=0.25, steps=100)
    if dt_max is None:
        _holds(spec, refuse_ok=False)
        return
    scene, _ = build(spec)
    params = dd.Params(dt_max=dt_max)
    res = dd.simulate(scene, params, duration=0.8)
    assert check(res, dd.build_model(scene, params)) == []


def test_soft_frictionless_cut_mass():
    """Shrunk by the long profile: a soft (1 MPa), light, frictionless mass cut by three joints
    under gravity (strain 2.4 %, not warned) created 2.69e3 J/m by step 28 (2.53e3 allowed).
    Every block is a mechanism, and the stage took "every block released" for "the static
    solve did not converge" and ran its ladder of pseudo-steps on them; the ladder now runs only
    when the open-close iteration did not converge."""
    spec = CaseSpec(kind="cut", size=1.0, density=800.0, young=1e6, poisson=0.0, friction=0.0, cohesion=0.0,
                    tensile=7015.0, gravity=9.81,
                    joints=((0.5, 0.28125, 0.0), (0.34375, 0.5625, 19.0), (0.6875, 0.625, 68.0)), steps=100)
    _holds(spec, refuse_ok=False)


def test_a_weightless_block_shaken_at_1e_5_g_stays_within_the_laws_round_off():
    """Found by the long profile (2026-11-29): a 1 m block cut in two by a horizontal joint, no
    gravity, shaken at 1e-5 g. Every contact force (~1e-3 N) lies below the law's round-off
    force p·open_tolerance·w0 (0.057 N), where a sliding contact may slip against its friction:
    friction work −1.8e-11 J/m in steps 6–7, 6.8e-12 J/m created by step 7 against the
    allowance's 6.8e-12 J/m before it counted that force's work (tests/extreme_cases.py)."""
    spec = CaseSpec(kind="cut", size=1.0, density=2274.0, young=377847034.1041358, poisson=0.25, friction=50.0,
                    cohesion=0.0, tensile=0.0, gravity=0.0, shapes=(), aspects=(), gaps=(), shifts=(),
                    velocities=(), spins=(), joints=((0.5, 0.5, 0.0),), outline=(), dt=0.0, load=0.0,
                    shaking=1e-05, steps=100)
    _holds(spec, refuse_ok=False)


def test_fast_collision_of_an_l_block_with_a_rectangle():
    """Shrunk by the long profile: an L-shaped block thrown up at 33 m/s and a rectangle thrown
    at (31, −29) m/s, stacked, rock-like (E = 20.7 GPa, φ = 10°). The rectangle's corner passes
    the L's outer corner 1.5 cm inside the L's right-face line and lands on its top face; the
    vertex–vertex contact closed on the right face instead (the less penetrated line after the
    free flight, 2 mm against 12 mm) and pushed the corner out sideways: 1.1e5 J/m created at
    step 22 against 447 J/m allowed (docs/method/dda.md §2.8.7)."""
    spec = CaseSpec(kind="stack", size=1.0, density=1800.0, young=20655628195.983295, poisson=0.1717098806614862,
                    friction=10.0, cohesion=0.0, tensile=0.0, gravity=9.81, shapes=("ell", "rect"),
                    aspects=(1.1919908786785993, 1.0), gaps=(0.0, 0.0), shifts=(-0.43384781843933484, 0.375),
                    velocities=((0.0, 33.0), (31.0, -29.0)), spins=(0.0, 0.0), joints=(), load=0.0, shaking=0.0,
                    steps=100)
    _holds(spec, refuse_ok=False)


def _acute_corner_model(tip_y: float):
    """A block B with a 32° corner at the origin between a 0.1 m edge (x = 0, from (0, 0.1)
    down to the corner) and a 20 m edge at 58°, and a sliver A whose tip lies 0.7 mm left of
    the short edge at height ``tip_y`` (outside B), its edges pointing down."""
    rock = dd.Material(density=2500.0, young=10e9, poisson=0.25)
    c, s = math.cos(math.radians(58.0)), math.sin(math.radians(58.0))
    scene = dd.Scene(gravity=0.0)
    b = scene.add_block([(0.0, 0.0), (20.0 * c, 20.0 * s), (-2.0, 17.0), (0.0, 0.1)], material=rock)
    a = scene.add_block([(-0.0007, tip_y), (-0.3, -1.0), (-0.0007, -1.0)], material=rock)
    return dd.build_model(scene), a, b


@pytest.mark.parametrize("twin", ["vectorized", "reference"])
def test_sliver_tip_at_an_acute_corner_is_no_penetration(twin):
    """A cut domain (`extreme_cases.random_domain`, seed 1 of the cut campaign: 28 blocks of
    26 m under 30 m/s²) ran away at step 30 "even with Δt = 3e-6 s": a sliver's tip lying 0.7
    mm off the short edge of a block with a 32° corner sat 0.049 m behind the long edge's
    line — inside the penetration band d9 and projecting onto the long edge, but outside the
    block — and the narrow phase took it for a contact of the long edge already 3.7× the
    penetration limit deep. The tip's shortest exit is the short edge (docs/method/dda.md
    §3.3 rule 3): it is a contact of the short edge, never of the long one."""

    model, a, b = _acute_corner_model(tip_y=0.06)
    off = model.vertex_offset
    tip, long_edge, short_edge = off[a], off[b], off[b] + 3
    xy = model.vertex_xy0
    # the case the rule is about: the tip projects onto the long edge, within d9 behind its line
    d = xy[long_edge + 1] - xy[long_edge]
    rel = xy[tip] - xy[long_edge]
    depth = float(rel @ np.array([d[1], -d[0]])) / float(np.hypot(*d))
    assert -model.max_penetration < depth < -0.5 * model.max_penetration
    assert 0.0 <= float(rel @ d) / float(d @ d) <= 1.0
    cint = _twin_contacts(twin, model, xy)
    pairs = {(int(v), int(e)) for v, e in cint[:, 1:3]}
    assert (tip, long_edge) not in pairs
    assert (tip, short_edge) in pairs or any(int(r[1]) == tip or int(r[3]) == tip for r in cint)


@pytest.mark.slow
def test_cut_domain_with_a_sliver_at_an_acute_corner_runs():
    """The run behind `test_sliver_tip_at_an_acute_corner_is_no_penetration` (cut campaign seed
    1): 28 blocks under 30 m/s², diverged at step 30 with runaway penetration; it runs its 60
    steps now (30 s on an idle core, 2–3 min on a loaded 2-core machine)."""
    from extreme_cases import random_domain

    spec = random_domain(np.random.default_rng(1), steps=60)
    _holds(spec, refuse_ok=False)


@pytest.mark.parametrize("twin", ["vectorized", "reference"])
def test_vertex_beyond_a_crumb_is_no_contact(twin):
    """Extreme seed 20 (`test_extreme_scenes_run_through_or_are_refused`): a crumb 0.24 mm
    thick, and a neighbour's vertex 0.5 mm behind its bottom edge's line, projecting onto it —
    past the crumb, in front of its other edges: outside the convex block, no contact of the
    bottom edge (docs/method/dda.md §3.3 rule 3; before, a contact 0.5 mm deep)."""
    rock = dd.Material(density=2500.0, young=10e9, poisson=0.25)
    scene = dd.Scene(gravity=0.0)
    crumb = scene.add_block([(0.0, 0.0), (2e-3, 0.0), (1e-3, 2.4e-4)], material=rock)
    tip = [(1e-3, -0.1), (-1.0, -3.0), (1.0, -3.0)]  # built 0.1 m below, then moved up through it
    a = scene.add_block(tip, material=rock)
    model = dd.build_model(scene)
    xy = model.vertex_xy0.copy()
    off = model.vertex_offset
    xy[off[a]:off[a + 1], 1] += 0.1005
    bottom = off[crumb]
    assert 0.5e-3 < model.max_penetration  # within the penetration band of the bottom edge
    cint = _twin_contacts(twin, model, xy)
    assert (off[a], bottom) not in {(int(v), int(e)) for v, e in cint[:, 1:3]}


def test_failure_message_names_a_sliver_and_a_contact_that_entered_too_deep():
    """A run that cannot go on says which input: a block thinner than the contacts'
    penetration band d9 (which the contact rules cannot resolve), and a contact that entered
    its step already deeper than the limit (which no Δt can undo)."""
    from types import SimpleNamespace

    from ddatai.diagnosis import failure_message

    rock = dd.Material(density=2500.0, young=10e9, poisson=0.25)
    scene = dd.Scene(gravity=9.81)
    crumb = scene.add_block([(0.0, 0.0), (2e-3, 0.0), (1e-3, 2.4e-4)], material=rock)
    big = scene.add_block([(1e-3, -0.1), (-1.0, -3.0), (1.0, -3.0)], material=rock)
    model = dd.build_model(scene)
    limit = model.penetration_limit
    attempt = SimpleNamespace(cause="penetration", culprits=((big, crumb),), culprit_force=1e9,
                              max_penetration=3 * limit, culprit_start=2 * limit)
    msg = failure_message(model, attempt, 5, 0.1, 1e-6)
    assert f"block {crumb} is a sliver" in msg and f"block {big} is a sliver" not in msg
    assert "entered the step already" in msg and "slivers='merge'" in msg
    attempt = SimpleNamespace(cause="open-close", culprits=((big, crumb),), changing=1)
    assert f"block {crumb} is a sliver" in failure_message(model, attempt, 5, 0.1, 1e-6)


@pytest.mark.parametrize("seed", [3, 4, 6, 10, 17, 25, 36, 37])
def test_cut_domain_starts_without_false_penetrations(seed):
    """Cut campaign seeds (`extreme_cases.random_domain`) whose blocks, as cut, do not overlap,
    but whose detection at t = 0 found 1–8 contacts "penetrated" 1.1–3.1× the penetration limit:
    a sliver's vertex shared with, or lying on, a neighbour's edge sat behind the line of
    that neighbour's next edge (docs/method/dda.md §3.3 rule 3). Seed 4, without gravity or
    loads, was pushed apart by them and stopped at step 11; seed 3 (a vertex at the far end of
    the neighbouring edge, on it to round-off) kept one until the rule allowed round-off."""
    from ddatai import vectorized
    from extreme_cases import random_domain

    scene, _ = build(random_domain(np.random.default_rng(seed)))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        model = dd.build_model(scene)
    xy = model.vertex_xy0
    cint, _ = vectorized.detect_contacts(model, xy)
    v, e = cint[cint[:, 0] == 0, 1], cint[cint[:, 0] == 0, 2]
    dn = _depths(model, xy, v, e)
    assert len(dn) and dn.min() > -1e-9 * model.w0


def test_cut_domain_keeps_coulomb_after_a_start_that_released_what_its_held_blocks_leant_on():
    """Cut campaign seed 134 (`extreme_cases.random_domain`: a 15.8 m domain of 2 GPa rock under
    30 m/s², 15 blocks, a user Δt of 2.7 µs; ~3 s idle). Its equilibrium stage stalled with 8
    blocks held and 7 released, and three of the held blocks had settled 3–6 mm into the space
    of released ones, which start where they were at t = 0: the first step began 4.9 mm deep
    (0.62 of the penetration limit), the automatic penalty was raised ×2.5 a step to ×65, and
    at step 6 a bonded contact pulled open carried 1.2e7 N/m of shear against a strength of
    5.2e4 (Coulomb's bound of the campaign: 1e-3 × the largest penalty force or weight,
    3.8e5 N/m). A held block that settles into a released one is released too, and the rest
    solved again (docs/guide/equilibrium_start.md; and where the open-close test of a stalled
    stage does not converge, the out-of-balance blocks are released: here all 15 now): no
    contact starts deeper than a hundredth of the limit, and every accepted step keeps
    Coulomb's law to the campaign's bound (`extreme_cases.check`)."""
    from extreme_cases import random_domain

    spec = random_domain(np.random.default_rng(134), steps=30)
    _holds(spec, refuse_ok=False)
    scene, _ = build(spec)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        model = dd.build_model(scene, dd.Params(dt=spec.dt))
        res = dd.simulate(scene, dd.Params(dt=spec.dt), steps=1)
    assert res.start["released"][0] > 0
    assert res.steps["max_penetration"][0] < 0.01 * model.penetration_limit
    assert res.steps["penalty"][0] == model.penalty


@pytest.mark.slow
def test_cut_domain_block_wedged_among_six_neighbours():
    """Cut campaign seed 37 (`extreme_cases.random_domain`; ~10 s idle, ~75 s loaded): block 24
    touches six blocks (3, 4, 18, 19, 26, 31), and at step 15 their vertex–edge contacts opened
    and closed in turn for 20 iterations at every Δt down to 3e-6 s (before the open-close
    decisions took the load carried as their measure, docs/method/choices.md); it runs its 16
    steps now."""
    from extreme_cases import random_domain

    _holds(random_domain(np.random.default_rng(37), steps=16), refuse_ok=False)


@pytest.mark.slow
def test_cut_domain_contact_entering_too_deep():
    """Cut campaign seed 82 (`extreme_cases.random_domain`; 2 s idle, ~15 s loaded): a 457 m
    domain under 30 m/s² stopped at step 84 with "runaway penetration" between blocks 23 and 28,
    the contact having entered the step already 0.874 m deep (limit 0.229 m): the edge-edge
    contact of a vertex pair whose vertex had entered the edge at the far corner
    (`test_edge_edge_contact_of_a_vertex_that_entered_the_far_edge_is_none`). It runs its 90
    steps now."""
    from extreme_cases import random_domain

    _holds(random_domain(np.random.default_rng(82), steps=90), refuse_ok=False)


@pytest.mark.parametrize("twin", ["kernels", "vectorized", "reference"])
def test_edge_edge_contact_of_a_vertex_that_entered_the_far_edge_is_none(twin):
    """Cut seed 82 at step 84 (blocks 23 and 28, coordinates to 0.1 mm): vertex 3 (block A's
    corner) and vertex 5 (block B's) are mutual nearest, A's edge 3→0 runs along B's edge 4→5,
    so the vertex-pair rule made an edge-edge contact of vertex 3 on edge 4→5 — 0.874 m behind
    its line (3.8× the limit), while vertex 3 lies 2.2 mm in front of B's edge 8→4, which meets
    edge 4→5 at its far corner: the vertex entered that edge, and touches it (docs/method/dda.md
    §3.3 rule 3). Every contact now lies within the penetration limit, and vertex 3 keeps its
    contact with edge 8→4."""
    rock = dd.Material(density=1830.0, young=4.25e9, poisson=0.24)
    scene = dd.Scene(gravity=0.0)
    scene.add_block([(-59.3207, -60.2677), (-29.2509, -49.5028), (-53.6087, -31.8197), (-55.6228, -30.9129)],
                    material=rock)
    scene.add_block([(-54.7893, -31.2882), (-54.7246, -30.7796), (-100.8657, 2.8427), (-111.1564, -4.9074),
                     (-111.686, -5.5013)], material=rock)
    model = dd.build_model(scene, length_scale=228.66)  # the domain's w0
    xy = model.vertex_xy0
    cint = _twin_contacts(twin, model, xy)
    v, e = cint[cint[:, 0] == 0, 1], cint[cint[:, 0] == 0, 2]
    dn = _depths(model, xy, v, e)
    assert (3, 8) in set(zip(v.tolist(), e.tolist()))
    assert dn.min() > -model.penetration_limit, list(zip(v.tolist(), e.tolist(), dn.tolist()))


@pytest.mark.parametrize("twin", ["kernels", "vectorized", "reference"])
def test_vertex_vertex_contact_of_a_vertex_that_entered_the_far_edge_is_none(twin):
    """Cut seed 54 at step 18 (blocks 11 and 17, to 0.1 mm): corners 2 and 4 are mutual nearest
    with wedges apart, a vertex-vertex contact whose entrance line for vertex 2 is B's 11 mm
    edge 3→4 — vertex 2 lies 15 mm behind it (7× the limit), yet 7 mm in front of B's edge 7→3,
    which meets that edge at its far corner: it entered that edge, whose contact it keeps. The
    run stopped at step 18 ("entered the step already 0.0152 m deep"). The vertex pair gives
    way to the vertex-edge tests (docs/method/dda.md §3.3 rule 3)."""
    rock = dd.Material(density=2968.0, young=16.3e9, poisson=0.18)
    scene = dd.Scene(gravity=0.0)
    scene.add_block([(-2.0194, -0.8919), (-1.7371, -0.8098), (-1.6491, -0.5755)], material=rock)
    scene.add_block([(-1.6478, -0.5923), (-1.6385, -0.5869), (-1.4, -0.3831), (-1.4688, -0.2648),
                     (-1.5532, -0.3405)], material=rock)
    model = dd.build_model(scene, length_scale=2.0923)  # the domain's w0
    xy = model.vertex_xy0
    cint = _twin_contacts(twin, model, xy)
    rows = {tuple(int(x) for x in r) for r in cint}
    assert (0, 2, 7, -1, -1) in rows and not any(r[0] == 1 for r in rows), rows
    v = np.concatenate([cint[:, 1], cint[cint[:, 0] == 1, 3]])
    e = np.concatenate([cint[:, 2], cint[cint[:, 0] == 1, 4]])
    dn = _depths(model, xy, v, e)
    assert dn.min() > -model.penetration_limit


def test_cut_merges_blocks_thinner_than_the_penetration_band():
    """A block thinner than the contacts' penetration band d9 (2·area/perimeter) cannot be
    resolved by penalty contact; `Scene.cut` merges it into a neighbour by default, saying so
    (7 of 200 random cut domains stopped at such blocks, docs/method/choices.md §8c), and keeps
    it with ``slivers="keep"``. The band is the one `build_model` gives a model of the blocks."""
    import shapely

    from ddatai.cutting import SliverWarning, contact_band

    rock = dd.Material(density=2500.0, young=10e9, poisson=0.25)
    joint = dd.Joint(friction=30.0)
    box = [(0.0, 0.0), (10.0, 0.0), (10.0, 10.0), (0.0, 10.0)]
    traces = [([(5.0, -1.0), (5.0, 11.0)], joint), ([(-1.0, 0.01), (11.0, 0.01)], joint)]  # 1 cm strips
    kept = dd.Scene()
    assert len(kept.cut(box, traces, material=rock, slivers="keep")) == 4
    model = dd.build_model(kept)
    off = model.vertex_offset
    faces = [shapely.Polygon(model.vertex_xy0[off[b]:off[b + 1]]) for b in range(model.n_blocks)]
    assert contact_band(faces) == pytest.approx(model.max_penetration, rel=1e-12)
    assert 0.01 < model.max_penetration  # the strips are thinner than the band
    merged = dd.Scene()
    with pytest.warns(SliverWarning, match="merged 2 block\\(s\\) thinner than the contacts' penetration band"):
        ids = merged.cut(box, traces, material=rock)
    assert len(ids) == 2 and all(abs(b.area - 50.0) < 1e-9 for b in (shapely.Polygon(merged.blocks[i].vertices)
                                                                     for i in ids))


def test_open_close_cycle_holds_its_contacts_closed():
    """The open-close iteration of cut seeds 6 and 103 went round a cycle of three sets of
    states for 20 iterations at every Δt (two contacts of one block, 1e-11 m from touching:
    one open → it closes; both closed → both pull free; both open → one closes). When the set
    of states comes back, the contacts that change around the cycle are held closed (an open one
    locks); the law then only chooses between sticking and sliding for them, and one it would
    open slides — never opens (docs/method/choices.md §6a)."""
    from types import SimpleNamespace

    from ddatai.layout import LOCK, OPEN, SLIDE
    from ddatai.open_close import hold_closed, hold_cycling

    states = [np.array([LOCK, OPEN, SLIDE], np.int8), np.array([LOCK, LOCK, SLIDE], np.int8),
              np.array([LOCK, OPEN, OPEN], np.int8), np.array([LOCK, OPEN, SLIDE], np.int8)]
    contacts = SimpleNamespace(state=states[0].copy(), n=3, coupled=np.array([False, False, True]))
    seen, history, held = {contacts.state.tobytes(): 0}, [contacts.state.copy()], np.zeros(3, bool)
    for k, st in enumerate(states[1:], start=1):
        contacts.state[:] = st
        hold_cycling(contacts, seen, history, held)
        assert held.any() == (k == 3)  # only when a set comes back
    assert held.tolist() == [False, True, True]
    assert contacts.state.tolist() == [LOCK, LOCK, SLIDE]  # the open one locks, the sliding one stays
    unit = dict(friction_now=np.zeros(3), strength=np.ones(3))
    law = SimpleNamespace(state=np.array([OPEN, OPEN, OPEN], np.int8), **unit)
    bad = hold_closed(contacts, law, np.array([True, True, True]), held)
    # the free contact opens as the law says; the held locked one must change, to sliding; the
    # held sliding one stays as it is
    assert law.state.tolist() == [OPEN, SLIDE, SLIDE] and bad.tolist() == [True, True, False]
    # a held contact sliding at its strength that the law would lock stays sliding (seed 162:
    # one contact flipping between sticking and sliding, its N and S moving with the state)
    law = SimpleNamespace(state=np.array([LOCK, LOCK, LOCK], np.int8), **unit)
    bad = hold_closed(contacts, law, np.array([True, True, True]), held)
    assert law.state.tolist() == [LOCK, LOCK, SLIDE] and bad.tolist() == [True, True, False]
    # a held sliding contact whose friction came from the last solve's N where it pulled
    # (uncoupled) and is below this solve's strength slides within Coulomb's cone: it stays (cut
    # seed 6 with two threads: coupled again it pulled, uncoupled it pressed, for 20 solves)
    contacts.coupled[:] = False
    law = SimpleNamespace(state=np.array([SLIDE, SLIDE, SLIDE], np.int8), friction_now=np.array([0.0, 0.0, 0.5]),
                          strength=np.ones(3))
    assert hold_closed(contacts, law, np.array([True, True, True]), held).tolist() == [True, True, False]
    law.friction_now[2] = 1.5  # beyond the strength: it must change
    assert hold_closed(contacts, law, np.array([True, True, True]), held).tolist() == [True, True, True]


def test_open_close_cycle_gives_up_the_try():
    """A try before the step's last gives up when a set of states (with the VV lines) comes back
    for the third time (`open_close.cycling`): twice it may still lead elsewhere, the third time
    the iteration goes round; a set that differs only in a VV line is another set; a set kept
    from one solve to the next is not a return."""
    from types import SimpleNamespace

    from ddatai.layout import LOCK, OPEN
    from ddatai.open_close import CYCLE_RECURRENCES, cycling

    a, b = np.array([LOCK, OPEN], np.int8), np.array([OPEN, LOCK], np.int8)
    contacts = SimpleNamespace(state=a.copy(), line=np.zeros(2, np.int8))
    recurring, verdicts = {}, []
    for st in (a, b, a, b, a):
        contacts.state[:] = st
        verdicts.append(cycling(contacts, recurring))
    assert CYCLE_RECURRENCES == 3 and verdicts == [False, False, False, False, True]
    contacts.line[0] = 1
    assert not cycling(contacts, recurring)
    # a set kept from solve to solve (lagged friction's forces still converging) is no return
    kept = {}
    contacts.state[:] = a
    assert not any(cycling(contacts, kept) for _ in range(2 * CYCLE_RECURRENCES))


@pytest.mark.slow
@pytest.mark.parametrize("seed", [6, 103, 162])
def test_cut_domain_open_close_cycle_runs_through(seed):
    """Cut campaign seeds 6, 103 and 162 (`extreme_cases.random_domain`; 7-11 s each on a
    loaded 2-core machine) stopped at steps 256, 262 and 25: the open-close cycles of
    `test_open_close_cycle_holds_its_contacts_closed`. They run their 400 steps now: 162 by the
    hold on the last try (without it, it stops at step 25 still); 6 and 103, whose cycles came
    from a shared corner's false depth, also without it (docs/method/dda.md §3.3)."""
    from extreme_cases import random_domain

    _holds(random_domain(np.random.default_rng(seed), steps=400), refuse_ok=False)


def test_load_that_outgrows_the_automatic_penalty_raises_it_once_said():
    """A load that builds up in the run beyond what the automatic penalty was chosen for (a
    block pressed onto its base by a point load growing as t, none at t = 0, under a penalty of
    0.01·E so that a 0.2 MPa press reaches the penetration limit; ~1 s): the penalty is raised
    for the rest of the run once the deepest contact passes PENALTY_RAISE_AT of the limit,
    said once in a warning naming the contact's blocks and both penalties, each step's p in the
    step record; a user's penalty is never changed. (Cut campaign seed 170, a 366 m domain
    under 30 m/s², needed it until impacts were resolved: `test_cut_seed_170_keeps_its_contacts`.)"""
    from ddatai.step import PENALTY_RAISE_AT, PenaltyWarning

    rock = dd.Material(density=2600.0, young=10e9, poisson=0.25)
    scene = dd.Scene(gravity=9.81)
    scene.add_block([(-1.0, -1.0), (2.0, -1.0), (2.0, 0.0), (-1.0, 0.0)], material=rock, fixed=True)
    block = scene.add_block([(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)], material=rock)
    params = dd.Params(penalty_ratio=0.01)
    model = dd.build_model(scene, params)
    # the press reaches 1.6 × what the two corner springs hold at the limit after 0.4 s
    rate = 2.0 * model.penalty * model.penetration_limit / 0.5
    scene.add_point_load(block, (0.5, 0.5), lambda t: (0.0, -rate * t))
    model = dd.build_model(scene, params)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        res = dd.simulate(scene, params, duration=0.4)
    said = [str(w.message) for w in caught if issubclass(w.category, PenaltyWarning)]
    assert len(said) == 1 and re.search("blocks (0 and 1|1 and 0)", said[0]), said
    assert f"p = {model.penalty:.3g} Pa" in said[0], said
    p = res.steps["penalty"]
    assert p[0] == model.penalty and p[-1] > p[0] and np.all(np.diff(p) >= 0)
    raised = np.flatnonzero(np.diff(p) > 0)
    assert f"raised to {p[raised[0] + 1]:.3g} Pa" in said[0]
    # raised after the step that went past the trigger, never before
    assert res.steps["max_penetration"][raised[0]] > PENALTY_RAISE_AT * model.penetration_limit
    assert res.steps["max_penetration"].max() < model.penetration_limit
    # a penalty the user chose is kept: the run ends naming it where a contact runs past the
    # limit (1.4 × the limit at 0.7 s)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        with pytest.raises(dd.SimulationError, match="raise Params.penalty"):
            dd.simulate(scene, dd.Params(penalty=model.penalty), duration=0.7)


def test_cut_seed_170_keeps_its_contacts():
    """Cut campaign seed 170 (`extreme_cases.random_domain`; ~2 s): a 366 m domain under
    30 m/s² whose deepest contact sat at 0.013 of the penetration limit for 350 steps, then
    reached 0.56 and the limit in an impact (blocks 0 and 5), before impacts were resolved
    (`ddatai.impacts`). The run's properties hold (`extreme_cases.check`) with the automatic
    penalty."""
    from extreme_cases import random_domain

    spec = random_domain(np.random.default_rng(170), steps=400)
    scene, steps = build(spec)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        model = dd.build_model(scene)
        res = dd.simulate(scene, steps=steps)
        assert not check(res, model)
        # a penalty the user chose is kept: the run ends naming the penalty where a contact
        # runs past the limit, or keeps every contact within it at the user's p
        try:
            kept = dd.simulate(scene, dd.Params(penalty=model.penalty), steps=steps)
        except dd.SimulationError as e:
            assert "raise Params.penalty" in str(e)
        else:
            assert np.all(kept.steps["penalty"] == model.penalty)
            assert kept.steps["max_penetration"].max() <= model.penetration_limit


def test_step_that_turns_a_block_inside_out_is_rejected():
    """A solution whose strain turns a block inside out ((1+εx)(1+εy) − (γxy/2)² ≤ 0; cut seed
    82 inverted a 0.54 m² sliver at step 192 with a largest vertex displacement, 1.6 m, that
    passed the displacement test) is no accepted step: `Stepper.accept` rejects it, and a run
    that cannot avoid it ends naming the block."""
    from types import SimpleNamespace

    from ddatai.diagnosis import failure_message
    from ddatai.step import Stepper

    rock = dd.Material(density=2500.0, young=10e9, poisson=0.25)
    scene = dd.Scene(gravity=9.81)
    scene.add_block([(-5.0, -1.0), (5.0, -1.0), (5.0, 0.0), (-5.0, 0.0)], material=rock, fixed=True)
    block = scene.add_block([(0.0, 0.0), (1.0, 0.0), (1.0, 0.1), (0.0, 0.1)], material=rock)
    for x in (-200.0, 100.0):  # large blocks far off: a step's allowed displacement 3·g2·w0 ≫ 0.1 m
        scene.add_block([(x, 0.0), (x + 100.0, 0.0), (x + 100.0, 100.0), (x, 100.0)], material=rock)
    scene.add_block([(-200.0, -2.0), (200.0, -2.0), (200.0, -1.0), (-200.0, -1.0)], material=rock, fixed=True)
    model = dd.build_model(scene)
    assert 3.0 * model.max_step > 0.2
    stepper = Stepper(model)
    state = model.initial_state()
    geom = model.block_geometry(state.vertex_xy)
    contacts, vec, _ = stepper.find_contacts(state, geom)
    for ey, inverted in ((-0.5, False), (-1.0, True), (-1.5, True)):
        disp = np.zeros((model.n_blocks, 6))
        disp[block, 4] = ey  # εy: the block's height times 1 + εy
        oc = SimpleNamespace(displacement=disp, iterations=1, friction=np.zeros(contacts.n), coulomb=0.0)
        attempt = stepper.accept(state, geom, contacts, vec, oc)
        assert attempt.ok != inverted and (attempt.cause == "inverted") == inverted, (ey, attempt.cause)
    msg = failure_message(model, attempt, 3, 0.1, 1e-6)
    assert f"block {block} is turned inside out" in msg
