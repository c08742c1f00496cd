"""Footwall slopes (docs/kgm/footwall.md): a face slab on its bedding plane, and the three
limit-equilibrium mechanisms after Alejano et al. — planar slab sliding, ploughing (the slab
pushes a toe block up a release joint), bilinear slab failure (the slab drives a toe block out
along a gentler release joint) — each on a small geometry of `scenes/footwall.py` against its
closed-form factor of safety, computed by hand there (eqs. F1–F8), not by kgm.

The referees: F1 for the planar slab (rigid and Sarma are exact: one block on one plane); the
two-block equilibrium F3–F7 for ploughing and bilinear (Sarma's mechanism for two blocks, so
kgm's Sarma evaluator must give it to round-off). The rigid evaluator (the group glued into one
body) has no mode for ploughing and gives F8, 28 % above, for the bilinear slab: unsafe.

Regressions of the two kgm defects these cases exposed: the toppling recursion took the
ploughing pair for a toppling row with the slab as its toe (FS 0.466 "toppling" against 1.116),
and Sarma's 48-point scan of F stepped over the bilinear root beside a pole of K(F) and fell
back to the rigid 1.277 against 0.996.

DDA: the default run brackets the ploughing and bilinear answers with two runs each (~15 s);
the full strength-reduction evaluations of the three cases are `slow` (~90 s together).
"""

import math

import numpy as np
import pytest

import kgm
from kgm.build import build_block_system
from kgm.judges.limits import F_MAX, F_MIN
from kgm.judges.rigid import evaluate_rigid
from kgm.judges.sarma import evaluate_sarma, sarma_checks
from kgm.judges.toppling import toppling_check
from kgm.kinds import ModeKind
from scenes import footwall as fw

G = 9.81
PAIR = frozenset({fw.P, fw.A})


def _system(case, **options):
    scene, _ = fw.build(case, **options)
    return scene, build_block_system(scene)


# ---------------------------------------------------------------------- the referees themselves
@pytest.mark.parametrize("case", ["ploughing", "bilinear"])
def test_two_block_closed_form_is_in_equilibrium(case):
    """At the closed-form FS the forces of F3–F6 balance each block (the weights, the base
    reactions at the reduced strength, ±Q on J2), every normal force is compressive, and the
    velocities keep J2 closed (F2). With c = 0 the FS scales with tanφ (all forces scale
    with the weights)."""
    fs = fw.closed_form_fs(case)
    d = fw.two_block_data(case)
    _, f = fw.two_block_residual(fs, d)
    assert min(f.values()) > 0
    mu, cr = math.tan(math.radians(d["friction"])) / fs, d["cohesion"] / fs
    shear_j = cr * d["L_J"] + f["Q"] * mu
    on_a = (np.array([0.0, -d["weight_A"]]) + f["N_A"] * d["n_A"] - (cr * d["L_A"] + f["N_A"] * mu) * d["d_A"]
            + f["Q"] * d["m"] - shear_j * d["s"])
    on_p = (np.array([0.0, -d["weight_P"]]) + f["N_P"] * d["n_P"] - (cr * d["L_P"] + f["N_P"] * mu) * d["d_P"]
            - f["Q"] * d["m"] + shear_j * d["s"])
    assert np.abs(on_a).max() < 1e-9 * d["weight_A"] and np.abs(on_p).max() < 1e-9 * d["weight_A"]
    assert abs((d["d_A"] - d["speed_ratio"] * d["d_P"]) @ d["m"]) < 1e-12
    if d["cohesion"] == 0.0:
        other = fw.closed_form_fs(case, friction=d["friction"] + 8.0)
        assert other / fs == pytest.approx(math.tan(math.radians(d["friction"] + 8.0))
                                           / math.tan(math.radians(d["friction"])), rel=1e-9)


# ---------------------------------------------------------------------- planar slab sliding
def test_planar_slab_sliding():
    """F1: FS = (c·L + W cosψ tanφ)/(W sinψ) = 1.1110 for the 12 m × 1.5 m slab on 40°,
    φ = 30°, c = 10 kPa; φc = atan((W sinψ − c·L)/(W cosψ)). Rigid and Sarma alike, and the
    search finds the slab."""
    p = fw.DEFAULTS["planar"]
    expected = fw.planar_fs(**p)
    assert expected == pytest.approx(1.11095, abs=1e-5)
    scene, system = _system("planar")
    w = fw.DENSITY * G * p["length"] * p["thickness"]
    psi = math.radians(p["dip"])
    phi_c = math.degrees(math.atan((w * math.sin(psi) - p["cohesion"] * p["length"]) / (w * math.cos(psi))))
    for method in ("rigid", "sarma"):
        g = kgm.evaluate(scene, [fw.SLAB], method)
        assert g.fs == pytest.approx(expected, rel=1e-9)
        assert g.critical_friction == pytest.approx(phi_c, abs=1e-6)
        assert g.mode.kind == ModeKind.SLIDING and g.stable
        crit = kgm.analyze(scene, method=method).critical
        assert crit.blocks == {fw.SLAB} and crit.fs == pytest.approx(expected, rel=1e-9)


# ---------------------------------------------------------------------- ploughing
def test_ploughing_is_a_two_block_mechanism_not_a_toppling_row():
    """The slab A (60° bedding, 2 m thick, 30 m high) pushes the toe block P up J1, which rises
    35° into the slope, shearing the vertical J2 (φ = 25°, c = 0): closed form 1.1160, which
    Sarma gives to round-off, with P moving up J1 and A down the bedding at the speed ratio of
    F2. The rigid evaluator has no mode (the glued pair would cut into the rock on both
    faces) and says why; the toppling recursion is not admissible: the two bases dip 85° apart
    (it used to read P as a column toppling into the slope onto the slab, FS 0.466)."""
    expected = fw.closed_form_fs("ploughing")
    assert expected == pytest.approx(1.11599, abs=1e-5)
    scene, system = _system("ploughing")
    mode, why = toppling_check(system, PAIR)
    assert mode is None and "not a toppling row" in why and "85°" in why
    ev = evaluate_sarma(system, PAIR)
    assert ev.mode.kind == ModeKind.SARMA and ev.fs == pytest.approx(expected, rel=1e-6)
    d = fw.two_block_data("ploughing")
    v = ev.mode.block_velocity
    assert v[fw.P] / np.linalg.norm(v[fw.P]) == pytest.approx(d["d_P"], abs=1e-9)   # up J1
    assert v[fw.A] / np.linalg.norm(v[fw.A]) == pytest.approx(d["d_A"], abs=1e-9)   # down the bedding
    assert np.linalg.norm(v[fw.P]) / np.linalg.norm(v[fw.A]) == pytest.approx(d["speed_ratio"], rel=1e-9)
    rigid = evaluate_rigid(system, PAIR)
    assert math.isinf(rigid.fs) and fw.rigid_fs("ploughing") == math.inf
    assert any("would cut into block 2" in r for r in rigid.rejected)
    rep = kgm.analyze(scene, method="sarma")
    assert rep.critical.blocks == PAIR and rep.critical.fs == pytest.approx(expected, rel=1e-6)
    table = rep.table()
    assert "governs: Sarma mechanism" in table and "not admissible: toppling: not a toppling row" in table
    assert kgm.analyze(scene, method="rigid").critical is None


# ---------------------------------------------------------------------- bilinear
def test_bilinear_slab_root_beside_a_pole_of_k():
    """The slab on 50° bedding drives P out along J1 (25°), shearing J2 (perpendicular to the
    bedding; φ = 30°, c = 5 kPa): closed form 0.99605 (unstable), Sarma to round-off. K(F) of
    the mechanism jumps through infinity at F ≈ 0.83, inside the cell [0.750, 1.000] of a
    48-point log grid whose two ends both see K < 0: the old scan missed the root and the pair
    fell back to its rigid slide on J1, F8 = 1.2766, 28 % above (stable: unsafe). Now the
    Sarma mechanism governs, and the table says why the rigid slide is no limit state: the
    pair's resultant crosses J1's plane off J1, so it cannot balance its moment there, while the
    Sarma mechanism balances its members' (docs/kgm/footwall.md §9)."""
    expected = fw.closed_form_fs("bilinear")
    assert expected == pytest.approx(0.99605, abs=1e-5)
    rigid_expected = fw.rigid_fs("bilinear")
    assert rigid_expected == pytest.approx(1.27665, abs=1e-5)
    scene, system = _system("bilinear")
    from kgm.judges import mechanisms, sarma

    members = sorted(PAIR)
    faces = mechanisms.merge_faces(system, members, frozenset())
    force = system.block_force[members]
    weight = system.block_mass[members] * system.gravity
    (mech,) = mechanisms.mechanisms(faces, force, 2)

    def k_of(f):
        return sarma._statics(mech, faces, force, weight, f, faces.tan_phi, check=False).k

    grid = np.exp(np.linspace(math.log(F_MIN), math.log(F_MAX), 49))
    i = int(np.searchsorted(grid, expected))
    assert k_of(grid[i - 1]) < 0 and k_of(grid[i]) < 0          # no sign change over the cell ...
    fine = np.linspace(grid[i - 1], grid[i], 200)
    k = np.array([k_of(f) for f in fine])
    assert np.abs(k).max() > 1.0 and np.any(k > 0)               # ... which holds a pole and the root
    ev = evaluate_sarma(system, PAIR)
    assert ev.mode.kind == ModeKind.SARMA and ev.fs == pytest.approx(expected, rel=1e-6)
    rigid = evaluate_rigid(system, PAIR)
    assert rigid.mode.kind == ModeKind.SLIDING and rigid.fs == pytest.approx(rigid_expected, rel=1e-9)
    crit = kgm.analyze(scene, method="sarma").critical
    assert crit.blocks == PAIR and not crit.stable and crit.fs == pytest.approx(expected, rel=1e-6)
    lines = crit.explain().splitlines()
    assert lines[0].startswith("governs: Sarma mechanism") and "FS 0.996" in lines[0]
    assert not any(line.startswith("also admissible") for line in lines)
    assert ("not admissible: sliding, FS 1.277: moment not balanced at its limit: the resultant's line misses "
            "the face (a translation that balances them holds the group up to FS 0.996)") in lines


@pytest.mark.parametrize("case, options", [
    ("bilinear", dict(dip=55.0, toe_dip=15.0, height=20.0)),
    ("bilinear", dict(dip=50.0, toe_dip=20.0, height=16.0, cross_foot=6.0, friction=35.0, cohesion=0.0)),
    ("bilinear", dict(dip=55.0, toe_dip=25.0, cohesion=10e3, friction=35.0)),
    ("bilinear", dict(dip=45.0, toe_dip=15.0, height=20.0, cross_dip=90.0, cohesion=0.0)),
    ("ploughing", dict(dip=70.0, toe_dip=-25.0, cross_foot=4.0, friction=30.0)),
    ("ploughing", dict(dip=65.0, toe_dip=-30.0, height=24.0, friction=30.0, cohesion=20e3)),
    ("ploughing", dict(dip=60.0, toe_dip=-20.0, cross_dip=None, friction=32.0)),
])
def test_sarma_equals_the_closed_form_over_geometries(case, options):
    """Sarma's FS is the closed form on other footwall geometries (dips, heights, J2 vertical or
    perpendicular to the bedding, with and without cohesion); the second one is another root
    the old scan stepped over (it gave the rigid 1.924 against 1.317)."""
    expected = fw.closed_form_fs(case, **options)
    _, system = _system(case, **options)
    assert evaluate_sarma(system, PAIR).fs == pytest.approx(expected, rel=1e-6)


def test_the_scan_fallback_finds_the_root_beside_the_pole(monkeypatch):
    """Where the eigenvalue form does not apply (Barton–Bandis faces, an indeterminate
    mechanism) K is scanned, and refined around the near-singular points of the system: with
    the eigenvalue form switched off, the bilinear root beside its pole is still found (FS and
    critical friction angle of the closed form)."""
    from kgm.judges import sarma

    _, system = _system("bilinear")
    exact = evaluate_sarma(system, PAIR)
    monkeypatch.setattr(sarma, "pencil_roots", lambda *a, **k: None)  # where the Sarma judge finds it
    scanned = evaluate_sarma(system, PAIR)
    assert scanned.mode.kind == ModeKind.SARMA
    assert scanned.fs == pytest.approx(fw.closed_form_fs("bilinear"), rel=1e-9)
    assert scanned.mode.critical_friction == pytest.approx(exact.mode.critical_friction, abs=1e-9)


def test_a_mechanism_with_no_admissible_root_is_reported():
    """With c = 1 GPa the bilinear pair's translation holds beyond F = 1000: K(F) has a root
    only where J1 would pull (tension), so the mechanism is dropped and the evaluation says why,
    naming the root, the force and the face. Its rigid slide on J1 (FS > 1000) cannot balance
    its moment (the pair's resultant crosses J1's plane off J1), so no translation holds the
    pair and it turns on two points (docs/kgm/footwall.md §9): faces that open carry no
    cohesion (no tension), so the turning factor is F9's, the same as with c = 0."""
    _, system = _system("bilinear", cohesion=1e9)
    modes, notes = sarma_checks(system, PAIR)
    assert modes == [] and len(notes) == 1
    assert f"no root of K(F) for F in [{F_MIN:g}, {F_MAX:g}] has admissible forces" in notes[0]
    assert "tension" in notes[0] and "on the face of block 0 on the stable rock" in notes[0]
    ev = evaluate_sarma(system, PAIR)
    assert notes[0] in ev.rejected
    assert ev.mode.kind == ModeKind.ROTATION and ev.fs == pytest.approx(fw.turning_fs("bilinear", cohesion=0.0),
                                                                        rel=1e-6)
    assert any(r.startswith("sliding, FS ") and "moment not balanced" in r and "the group turns instead" in r
               for r in ev.rejected)


# ---------------------------------------------------------------------- DDA
def _judge(case, reduction):
    from kgm.judges.run import judge

    scene, params = fw.build(case)
    return judge(scene, build_block_system(scene), PAIR, settings=kgm.DdaSettings(), params=params,
                 reduction=reduction)


@pytest.mark.parametrize("case, stable_at, unstable_at", [("ploughing", 1.0, 1.2), ("bilinear", 0.9, 1.0)])
def test_dda_brackets_the_two_block_answers(case, stable_at, unstable_at):
    """DDA on the real geometry (the group and the rock, strength tanφ/F, c/F): the pair
    stands at the lower F and fails at the upper one, which bracket the closed form (ploughing
    1.116, bilinear 0.996) and exclude the rigid bilinear answer 1.277 (~3 s a run)."""
    expected = fw.closed_form_fs(case)
    assert stable_at < expected < unstable_at
    assert _judge(case, stable_at).stable
    assert not _judge(case, unstable_at).stable
    if case == "bilinear":
        assert unstable_at < fw.rigid_fs(case)


@pytest.mark.slow
@pytest.mark.parametrize("case", fw.CASES)
def test_dda_factor_of_safety_matches_the_closed_form(case):
    """DDA's FS by strength reduction (kgm.evaluate(..., "dda")) within the bisection
    tolerance plus the judgement's friction resolution Δtanφ ≈ a_r/(g cosα) (relative to the
    mobilised tanφ/FS) of the closed form: measured planar 1.1187 (F1: 1.1110), ploughing
    1.1238 (1.1160), bilinear 0.9754 (0.9961; rigid 1.2766). ~25–40 s a case."""
    scene, params = fw.build(case)
    group = [fw.SLAB] if case == "planar" else sorted(PAIR)
    expected = fw.closed_form_fs(case)
    g = kgm.evaluate(scene, group, "dda", params=params)
    s = kgm.DdaSettings()
    p = {**fw.DEFAULTS[case]}
    base = p["dip"] if case != "bilinear" else p["toe_dip"]  # the plane the moving toe slides on
    dtan = s.acceleration_resolution / (G * math.cos(math.radians(base)))
    tol = s.fs_tolerance + dtan / (math.tan(math.radians(p["friction"])) / expected)
    assert g.fs == pytest.approx(expected, rel=tol)
    assert g.stable is (expected >= 1.0)
