"""Block theory of the 3D wedges (docs/kgm/wedge.md §3): joint pyramids, finiteness and
removability verdicts on daylighting, infinite and tapered blocks; the fast cone tests against
the linear programs; the vectorised wedges against the reference path."""

from __future__ import annotations

import math

import numpy as np
import pytest

import ddatai as dd
import kgm
from kgm.wedges import batched
from kgm.wedges.batched_geometry import _jp_empty
from kgm.wedges.block_theory import admissible_modes, block_pyramid_direction, is_finite, jp_is_empty
from kgm.wedges.geometry import Halfspace, plane_normal

J = dd.Joint(friction=30.0)
HB_FACE, HB_UPPER = kgm.Plane(65, 185), kgm.Plane(12, 195)
HB_JOINTS = [kgm.Plane(45, 105, J), kgm.Plane(70, 235, J)]


def test_daylighting_wedge_is_the_one_removable_pyramid():
    """Hoek & Bray's wedge: of the four joint pyramids of two joints only 00 (above both) is
    finite against the slope and upper faces; it is removable and it is the wedge."""
    w = kgm.wedge(HB_FACE, HB_UPPER, 30.0, HB_JOINTS)
    kinds = {p.name: p.kind for p in w.pyramids}
    assert kinds == {"00": "removable", "01": "infinite", "10": "infinite", "11": "infinite"}
    assert w.forms and w.pyramid == "00" and w.reason == ""
    # the same verdicts from the public block-theory LP
    table = kgm.joint_pyramids([p.normal for p in HB_JOINTS], [HB_FACE.normal, HB_UPPER.normal])
    assert {p.name: p.kind for p in table} == kinds


def test_not_daylighting_and_not_closing_wedges_are_infinite_with_their_reason():
    """Line of intersection 157.7°/31.2°: a face flatter than it along that trend lets it run
    into the slope (not daylighting); an upper face steeper than it never closes the wedge."""
    w = kgm.wedge(kgm.Plane(28, 185), kgm.Plane(5, 195), 30.0, HB_JOINTS)
    assert not w.forms and w.reason.startswith("not daylighting")
    assert all(p.kind == "infinite" for p in w.pyramids) and math.isnan(w.fs)
    w = kgm.wedge(kgm.Plane(65, 165), kgm.Plane(40, 160), 30.0, HB_JOINTS)
    assert not w.forms and w.reason.startswith("infinite: the line of intersection")
    w = kgm.wedge(HB_FACE, HB_UPPER, 30.0, [kgm.Plane(45, 105, J), kgm.Plane(45, 105, J)])
    assert not w.forms and "parallel" in w.reason


def _frustum(a=1.0, t=0.5, length=3.0, back=True):
    """A plug narrowing towards the free face y = 0 (rock at y < 0): four side joints whose
    inward normals lean towards the face's side, and a back joint."""
    hs = [Halfspace(np.array([0.0, 1.0, 0.0]), 0.0, "face", "free")]
    for k, (sx, sz) in enumerate(((1, 0), (-1, 0), (0, 1), (0, -1))):
        n = np.array([sx, t, sz], float)
        hs.append(Halfspace(n / np.linalg.norm(n), a / np.linalg.norm(n), f"side {k}", "joint"))
    if back:
        hs.append(Halfspace(np.array([0.0, -1.0, 0.0]), length, "back", "joint"))
    return hs


def test_tapered_block_is_finite_but_not_removable():
    """A plug that narrows towards the face (Goodman & Shi's tapered block): finite, and its
    joint pyramid is the origin alone — by the LP, the fast test and `polyhedral_block`."""
    hs = _frustum()
    inward = np.array([-h.normal for h in hs if h.kind == "joint"])
    free = np.array([h.normal for h in hs if h.kind == "free"])
    assert is_finite(inward, free) and jp_is_empty(inward)
    joints = {h.label: J for h in hs if h.kind == "joint"}
    w = kgm.polyhedral_block(hs, joints)
    assert not w.forms and w.reason.startswith("tapered") and w.volume > 0
    # the same plug widening towards the face comes out
    flipped = [Halfspace(h.normal * np.array([1, -1, 1]) if h.label.startswith("side") else h.normal,
                         h.offset, h.label, h.kind) for h in hs]
    w = kgm.polyhedral_block(flipped, joints)
    assert w.forms


def test_goodman_shi_counts_for_three_and_four_joint_sets():
    """Three non-parallel sets: all 2³ = 8 joint pyramids are non-empty; a fourth set in
    general position empties some of the 2⁴ = 16 (their inward normals surround the origin)."""
    n3 = [plane_normal(30, 10), plane_normal(60, 130), plane_normal(80, 250)]
    table = kgm.joint_pyramids(n3, [])
    assert len(table) == 8 and not any(p.empty for p in table)
    n4 = n3 + [plane_normal(45, 300)]
    table = kgm.joint_pyramids(n4, [])
    empty = [p for p in table if p.empty]
    assert len(table) == 16 and 0 < len(empty) < 16
    for p in table:                       # Gordan: empty iff 0 is inside the hull of the normals
        v = np.array(n4) * np.array(p.code)[:, None]
        lam = np.linalg.svd(v.T)[2][-1]
        assert p.empty == bool(np.all(lam > 1e-9) or np.all(lam < -1e-9))


def test_fast_cone_tests_agree_with_the_linear_programs():
    rng = np.random.default_rng(5)
    for _ in range(150):
        m = rng.integers(2, 5)
        v = rng.normal(size=(m, 3))
        v /= np.linalg.norm(v, axis=1, keepdims=True)
        f = rng.normal(size=(rng.integers(1, 3), 3))
        f /= np.linalg.norm(f, axis=1, keepdims=True)
        assert is_finite(v, f) == (block_pyramid_direction(v, f) is None)
        if m == 4:
            assert jp_is_empty(v) == bool(_jp_empty(v[None])[0])


def test_mode_analysis_is_goodman_shi():
    """Falling when r leaves every face; one face when its projection leaves the other;
    two faces along their intersection with positive normal forces; held otherwise."""
    v = np.array([plane_normal(45, 105), plane_normal(70, 235)])
    kinds = lambda r: [m.kind for m in admissible_modes(np.asarray(r, float), v)]   # noqa: E731
    assert kinds([0, 0, -1]) == ["two planes"]
    assert kinds([0, 0, 1]) == ["falling"]
    r = -v[0] + 0.3 * np.cross(v[0], [0, 0, 1])
    modes = admissible_modes(r, v)
    assert len(modes) == 1
    # every r: exactly one mode (or held), never two (general position)
    rng = np.random.default_rng(2)
    for r in rng.normal(size=(500, 3)):
        assert len(admissible_modes(r, v)) == 1


# ---------------------------------------------------------------- fast path = reference path
def _reference(kw, k):
    """The reference wedge for sample k of the batched keyword arrays ``kw``."""
    pick = lambda name: np.broadcast_to(kw[name], (N,))[k] if np.ndim(kw[name]) <= 1 else kw[name][k]  # noqa
    m = kw["joint_dip"].shape[1]
    barton = kw.get("barton")
    joints = []
    for j in range(m):
        if barton is not None and not np.isnan(barton["jrc"][k, j]):
            law = dd.BartonBandis(jrc=barton["jrc"][k, j], jcs=barton["jcs"][k, j],
                                  residual_friction=barton["residual"][k, j], cohesion=kw["cohesion"][k, j])
        else:
            law = dd.Joint(friction=kw["friction"][k, j], cohesion=kw["cohesion"][k, j])
        joints.append(kgm.Plane(kw["joint_dip"][k, j], kw["joint_dip_direction"][k, j], law))
    crack = None
    if kw.get("crack_dip") is not None:
        crack = kgm.TensionCrack(kgm.Plane(pick("crack_dip"), pick("crack_dip_direction")), pick("crack_distance"))
    bolts = [kgm.Bolt(*b) for b in kw.get("_bolts", [])]
    return kgm.wedge(kgm.Plane(pick("face_dip"), pick("face_dip_direction")),
                     kgm.Plane(pick("upper_dip"), pick("upper_dip_direction")), pick("height"), joints,
                     density=pick("density"), water=kgm.Water(fill=pick("water_fill")) if kw.get("water_fill")
                     is not None else None, seismic=pick("seismic_k") if kw.get("seismic_k") is not None else None,
                     tension_crack=crack, bench_width=kw.get("bench_width"), bolts=bolts)


N = 50


def _cases():
    rng = np.random.default_rng(11)
    base = dict(face_dip=rng.uniform(55, 85, N), face_dip_direction=180.0, upper_dip=rng.uniform(0, 20, N),
                upper_dip_direction=rng.uniform(150, 210, N), height=rng.uniform(5, 40, N),
                joint_dip=np.column_stack([rng.uniform(30, 80, N), rng.uniform(30, 80, N)]),
                joint_dip_direction=np.column_stack([rng.uniform(90, 170, N), rng.uniform(190, 270, N)]),
                friction=np.column_stack([rng.uniform(20, 40, N), rng.uniform(20, 40, N)]),
                cohesion=np.column_stack([rng.uniform(0, 3e4, N), rng.uniform(0, 3e4, N)]),
                density=rng.uniform(2400, 2800, N))
    yield "dry", base
    yield "water, seismic", dict(base, water_fill=rng.uniform(0, 1, N), seismic_k=rng.uniform(0, 0.2, N))
    yield "crack, water", dict(base, water_fill=1.0, crack_dip=rng.uniform(60, 90, N), crack_dip_direction=180.0,
                               crack_distance=rng.uniform(1, 10, N))
    yield "bench", dict(base, bench_width=6.0)
    bb = dict(jrc=np.where(rng.random((N, 2)) < 0.5, rng.uniform(2, 15, (N, 2)), np.nan),
              jcs=rng.uniform(20e6, 100e6, (N, 2)), residual=rng.uniform(20, 30, (N, 2)),
              cap=np.full((N, 2), 70.0), reduction=np.ones((N, 2)))
    yield "barton-bandis", dict(base, barton=bb)
    third = dict(base, joint_dip=np.column_stack([base["joint_dip"], rng.uniform(5, 25, N)]),
                 joint_dip_direction=np.column_stack([base["joint_dip_direction"], rng.uniform(150, 210, N)]),
                 friction=np.column_stack([base["friction"], np.full(N, 30.0)]),
                 cohesion=np.column_stack([base["cohesion"], np.zeros(N)]))
    yield "basal joint", third
    yield "bolts", dict(base, _bolts=[(2e5, 0.0, -10.0, "active"), (1e5, 10.0, 0.0, "passive")])


@pytest.mark.parametrize("name, kw", list(_cases()), ids=[c[0] for c in _cases()])
def test_batched_wedges_equal_the_reference_path(name, kw):
    """Same verdict, reason, volume, FS, mode and normal forces as `kgm.wedge` (Qhull, LP) on
    random wedges of every kind, to 1e-9."""
    args = {k: v for k, v in kw.items() if not k.startswith("_")}
    bolts = [kgm.Bolt(*b) for b in kw.get("_bolts", [])]
    args["active_force"] = sum((b.vector for b in bolts if b.kind == "active"), np.zeros(3))
    args["passive_force"] = sum((b.vector for b in bolts if b.kind == "passive"), np.zeros(3))
    fast = batched.evaluate(**args)
    reasons = {"not daylighting": 1, "infinite": 2, "tapered": 3, "no volume": 4, "joints 1 and 2 are parallel": 5,
               "the tension crack does not cut": 6}
    formed = 0
    for k in range(N):
        ref = _reference(kw, k)
        assert ref.forms == bool(fast.forms[k]), (name, k, ref.reason)
        if not ref.forms:
            assert fast.reason[k] == next(c for r, c in reasons.items() if ref.reason.startswith(r)), (k, ref.reason)
            continue
        formed += 1
        assert fast.volume[k] == pytest.approx(ref.volume, rel=1e-9)
        assert fast.fs[k] == pytest.approx(ref.fs, rel=1e-9, abs=1e-12)
        assert batched.MODES[fast.mode[k]] == {"falling": "falling", "stable": "stable"}.get(
            ref.mode, "one plane" if " and " not in ref.mode else "two planes")
        assert fast.normal[k] == pytest.approx(np.array(ref.normal_forces), rel=1e-9, abs=1e-6 * ref.weight)
    assert formed >= N // 5


def test_key_blocks_of_a_face_are_typed_by_goodman_and_shi():
    """The slope's joint pyramids as blocks of its faces: 00 is the removable one, a key block
    (type I) below its critical friction and a potential key block (II) above it; the others
    are infinite (V). Friction only, its FS is the wedge's at any size."""
    free = [HB_FACE.normal, HB_UPPER.normal]
    for phi, expected in ((20.0, "I"), (45.0, "II")):
        planes = [kgm.Plane(45, 105, dd.Joint(friction=phi)), kgm.Plane(70, 235, dd.Joint(friction=phi))]
        blocks = {b.pyramid.name: b for b in kgm.face_key_blocks(planes, free)}
        assert blocks["00"].type == expected and {blocks[k].type for k in ("01", "10", "11")} == {"V"}
        assert blocks["00"].fs == pytest.approx(kgm.wedge(HB_FACE, HB_UPPER, 17.0, planes).fs, rel=1e-12)
    # a block held whatever its friction (III): a pyramid sitting in a socket that opens upwards
    bowl = [kgm.Plane(40, a, dd.Joint(friction=5.0)) for a in (0, 120, 240)]
    types = {b.pyramid.name: b.type for b in kgm.face_key_blocks(bowl, [np.array([0.0, 0.0, 1.0])])}
    assert types["000"] == "III"
