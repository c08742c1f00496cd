"""Polygon validation, polygon integrals, mass matrix and block cutting (docs/method/dda.md §1, §7j)."""

import numpy as np
import pytest
import shapely

import ddatai as dd
from ddatai.geometry import displacement_matrix, mass_matrix, polygon_integrals, validate_polygon
from ddatai.cutting import cut

def integrals(xy):
    xy = np.asarray(xy, float)
    return {k: v[0] for k, v in polygon_integrals(xy, np.array([0, len(xy)])).items()}


def test_unit_square_integrals():
    g = integrals([(0, 0), (1, 0), (1, 1), (0, 1)])
    assert g["area"] == pytest.approx(1.0, abs=1e-15)
    assert np.allclose(g["centroid"], [0.5, 0.5], atol=1e-15)
    assert g["s1"] == pytest.approx(1 / 12, abs=1e-15)
    assert g["s2"] == pytest.approx(1 / 12, abs=1e-15)
    assert g["s3"] == pytest.approx(0.0, abs=1e-15)


def test_right_triangle_integrals():
    # legs a along x, b along y: ∫X² = a³b/36, ∫Y² = ab³/36, ∫XY = −a²b²/72
    a, b = 3.0, 2.0
    g = integrals([(0, 0), (a, 0), (0, b)])
    assert g["area"] == pytest.approx(a * b / 2)
    assert np.allclose(g["centroid"], [a / 3, b / 3])
    assert g["s1"] == pytest.approx(a ** 3 * b / 36)
    assert g["s2"] == pytest.approx(a * b ** 3 / 36)
    assert g["s3"] == pytest.approx(-a * a * b * b / 72)


def test_integrals_far_from_origin_keep_precision():
    """Central moments are invariant under translation, even at UTM-like coordinates."""
    sq = np.array([(0, 0), (2, 0), (2, 1), (0, 1)], float)
    near, far = integrals(sq), integrals(sq + [5e5, 4e6])
    for k in ("area", "s1", "s2", "s3"):
        assert far[k] == pytest.approx(near[k], rel=1e-9, abs=1e-12)
    assert np.allclose(far["centroid"] - [5e5, 4e6], near["centroid"], atol=1e-9)


def test_mass_matrix_equals_quadrature():
    """M = ∫ TᵀT dA checked against a dense midpoint quadrature on a non-symmetric polygon."""
    poly = np.array([(0, 0), (3, 0.5), (2.5, 2), (0.5, 1.5)])
    g = integrals(poly)
    M = mass_matrix(*(np.array([g[k]]) for k in ("area", "s1", "s2", "s3")))[0]
    n = 400
    xs = np.linspace(0, 3, n + 1)
    ys = np.linspace(0, 2, n + 1)
    cx, cy = 0.5 * (xs[1:] + xs[:-1]), 0.5 * (ys[1:] + ys[:-1])
    X, Y = np.meshgrid(cx, cy)
    pts = np.stack([X.ravel(), Y.ravel()], axis=1)
    inside = shapely.contains_xy(shapely.Polygon(poly), pts[:, 0], pts[:, 1])
    T = displacement_matrix(pts[inside], np.broadcast_to(g["centroid"], (inside.sum(), 2)))
    Mq = np.einsum("nki,nkj->ij", T, T) * (xs[1] - xs[0]) * (ys[1] - ys[0])
    assert np.allclose(M, Mq, rtol=2e-3, atol=2e-3 * np.abs(M).max())
    assert np.allclose(M, M.T)
    assert np.all(np.linalg.eigvalsh(M) > 0)


def test_validate_polygon_orients_and_cleans():
    cw = [(0, 0), (0, 1), (1, 1), (1, 0), (0, 0)]  # clockwise, closed, repeated start
    xy = validate_polygon(cw)
    assert len(xy) == 4
    assert integrals(xy)["area"] > 0
    # a vertex on the straight line between its neighbours is removed
    flat = validate_polygon([(0, 0), (0.5, 0), (1, 0), (1, 1), (0, 1)])
    assert len(flat) == 4


@pytest.mark.parametrize("bad, message", [
    ([(0, 0), (2, 2), (2, 0), (0, 1)], "self-intersecting"),
    ([(0, 0), (1, 0), (2, 0)], "zero area"),
    ([(0, 0), (1, 0)], "at least 3"),
    ([(0, 0), (1, np.nan), (1, 1)], "NaN"),
    ([(0, 0, 0), (1, 0, 0), (1, 1, 0)], "shape"),
])
def test_validate_polygon_rejects(bad, message):
    with pytest.raises(ValueError, match=message):
        validate_polygon(bad, name="block 7")
    with pytest.raises(ValueError, match="block 7"):
        validate_polygon(bad, name="block 7")


def test_cut_persistent_finite_and_dangling_traces():
    """Two persistent joints make 4 blocks; a dangling trace is dropped; area is conserved;
    every edge on a joint knows which one."""
    box = [(0, 0), (4, 0), (4, 2), (0, 2)]
    joints = [
        [(2, -1), (2, 3)],         # persistent, vertical
        [(-1, 1), (5, 1)],         # persistent, horizontal
        [(0.5, 0.2), (1.5, 0.6)],  # finite, dangling inside one block: dropped
        [(3, 1), (3, 2)],          # finite, ending on the horizontal joint and the boundary
    ]
    pieces = cut(box, joints)
    assert len(pieces) == 5
    assert sum(integrals(xy)["area"] for xy, _ in pieces) == pytest.approx(8.0)
    for xy, edge_joint in pieces:
        assert integrals(xy)["area"] > 0
        for k, j in enumerate(edge_joint):
            a, b = xy[k], xy[(k + 1) % len(xy)]
            if j < 0:
                # a boundary edge lies on the outline
                assert shapely.LineString(box + [box[0]]).distance(shapely.Point((a + b) / 2)) < 1e-9
            else:
                line = shapely.LineString(joints[j])
                assert line.distance(shapely.Point(a)) < 1e-9 and line.distance(shapely.Point(b)) < 1e-9
    assert 2 not in {j for _, ej in pieces for j in ej}  # the dangling trace bounds no block


def test_scene_cut_carries_joint_properties():
    scene = dd.Scene()
    rock = dd.Material(density=2600.0, young=1e10, poisson=0.2)
    weak = dd.Joint(friction=15.0, cohesion=1e4)
    strong = dd.Joint(friction=40.0)
    ids = scene.cut([(0, 0), (2, 0), (2, 2), (0, 2)], [([(1, -1), (1, 3)], weak),
                                                      ([(-1, 1), (3, 1)], strong)], material=rock)
    assert ids == [0, 1, 2, 3]
    # blocks ordered bottom to top, then left to right
    cents = [integrals(scene.polygon(i))["centroid"] for i in ids]
    assert cents[0][1] < cents[2][1] and cents[0][0] < cents[1][0]
    used = {scene.joints[j] for b in ids for j in scene.blocks[b].edge_joint if j >= 0}
    assert used == {weak, strong}


# ---------------------------------------------------------------------- trace ends that nearly meet
BOX10 = [(0, 0), (10, 0), (10, 10), (0, 10)]
#: a persistent horizontal joint; a vertical one from the floor to 1 µm below it; a vertical one
#: from it to 1 µm below the top (coordinates typed to six decimals)
NEAR = [[(-1, 5), (11, 5)], [(5, 0), (5, 4.999999)], [(3, 5), (3, 9.999999)]]


def test_trace_ends_a_micrometre_short_are_snapped():
    """Both short ends (1e-7 of the 10 m box, within the default snap of 1e-6 × its size) are
    extended onto the joint and the outline they nearly reach: 4 blocks of the right areas,
    their edges on the traces that made them, and nothing to warn about."""
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        pieces = cut(BOX10, NEAR)
    areas = sorted(round(float(integrals(xy)["area"]), 6) for xy, _ in pieces)
    assert areas == [15.0, 25.0, 25.0, 35.0]
    on = {j for _, ej in pieces for j in ej if j >= 0}
    assert on == {0, 1, 2}
    for xy, ej in pieces:  # the vertical edges lie on the vertical traces, to the snap
        for k, j in enumerate(ej):
            a, b = xy[k], xy[(k + 1) % len(xy)]
            if j in (1, 2):
                assert abs(a[0] - NEAR[j][0][0]) < 1e-12 and abs(b[0] - NEAR[j][0][0]) < 1e-12


def test_trace_ends_short_beyond_the_snap_are_warned_about():
    """With no snap the two short traces close no block (the box is cut in 2, not 4), and the
    warning names each trace, its end, the gap and the snap distance that closes it; passed
    that distance, `Scene.cut` makes the 4 blocks. A gap of 1 mm (1e-4 of the size, beyond the
    1e-5 band) is a finite joint that ends near another: dropped without a word."""
    import warnings

    from ddatai.cutting import TraceGapWarning
    with pytest.warns(TraceGapWarning) as rec:
        pieces = cut(BOX10, NEAR, snap_ends=0.0)
    assert len(pieces) == 2 and len(rec) == 1
    msg = str(rec[0].message)
    assert "joint 1's end (5, 4.999999) stops 1e-06 m short of joint 0" in msg
    assert "joint 2's end (3, 9.999999) stops 1e-06 m short of the outline" in msg
    assert "snap_ends=1.5e-06" in msg
    rock = dd.Material(density=2600.0, young=1e10, poisson=0.2)
    scene = dd.Scene()
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert len(scene.cut(BOX10, [(t, dd.Joint()) for t in NEAR], material=rock, snap_ends=1.5e-6)) == 4
        far = [NEAR[0], [(5, 0), (5, 4.999)]]
        assert len(cut(BOX10, far)) == 2
    with pytest.raises(ValueError, match="snap_ends must be a finite distance >= 0 m"):
        cut(BOX10, NEAR, snap_ends=-1.0)


def test_snapping_leaves_meeting_and_crossing_traces_alone():
    """Ends that already touch or cross a trace (by a hair) and persistent traces are not
    moved; a slanted joint whose end was rounded to six decimals onto another slanted one
    (short or past, whichever the rounding gives) closes its block either way."""
    import warnings

    from ddatai.cutting import snap_trace_ends
    meet = [[(-1, 5), (11, 5)], [(5, 0), (5, 5)], [(3, 5), (3, 10.0000001)]]
    traces, moved = snap_trace_ends(np.array(BOX10, float), meet, 1e-5)
    assert moved == [] and all(np.array_equal(a, np.asarray(b, float)) for a, b in zip(traces, meet))
    # the line y = 0.7x (through the box) and a joint from (2, 10) down to it at 60° from the
    # horizontal, its end rounded to six decimals
    d = np.array([np.cos(np.radians(-60.0)), np.sin(np.radians(-60.0))])
    s = np.linalg.solve(np.column_stack([d, -np.array([1.0, 0.7])]), -np.array([2.0, 10.0]))[0]
    end = np.round(np.array([2.0, 10.0]) + s * d, 6)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        pieces = cut(BOX10, [[(0, 0), (10, 7)], [(2, 10), tuple(end)]])
    assert len(pieces) == 3
    assert sum(integrals(xy)["area"] for xy, _ in pieces) == pytest.approx(100.0)
