"""Joint-set generator: orientation, spacing and persistence statistics on a large sample;
reproducibility; bad input."""

import numpy as np
import pytest
import shapely

import ddatai as dd

BOX = [(0, 0), (400, 0), (400, 400), (0, 400)]


def _dips(traces):
    d = np.array([t[1] - t[0] for t, _ in traces])
    ang = np.degrees(np.arctan2(d[:, 1], d[:, 0])) % 180.0
    return ang, np.hypot(d[:, 0], d[:, 1])


def test_orientation_and_spacing_statistics():
    """Length-weighted mean dip within 0.5° of the set's; spacing measured on a scanline normal
    to the set within 3 % of the mean (σ = 0.5 m, ~140 samples: standard error ~0.04 m)."""
    s = dd.JointSet(dip=30.0, spacing=2.0, spacing_spread=0.5, dip_spread=3.0)
    traces = dd.joint_sets(BOX, [s], seed=11)
    ang, length = _dips(traces)
    assert abs(np.average(ang, weights=length) - 30.0) < 0.5
    assert abs(np.sqrt(np.average((ang - 30.0) ** 2, weights=length)) - 3.0) < 0.75
    # scanline through the centre, normal to the set, 300 m long (inside the box)
    n = np.array([-np.sin(np.radians(30)), np.cos(np.radians(30))])
    c = np.array([200.0, 200.0])
    scan = shapely.LineString([c - 150 * n, c + 150 * n])
    hits = sum(1 for t, _ in traces if shapely.LineString(t).intersects(scan))
    assert abs(300.0 / hits - 2.0) < 0.06


def test_trace_length_and_gap_statistics():
    """Non-persistent set: mean trace length and gap (traces not cut by the boundary) within
    5 % of the set's, so the persistence L/(L + g) is reproduced."""
    s = dd.JointSet(dip=0.0, spacing=4.0, trace_length=6.0, gap=2.0, trace_spread=1.0, gap_spread=0.5)
    traces = dd.joint_sets(BOX, [s], seed=5)
    inner = [t for t, _ in traces if 1e-6 < t[:, 0].min() and t[:, 0].max() < 400 - 1e-6]
    lengths = np.array([np.ptp(t[:, 0]) for t in inner])
    assert abs(lengths.mean() - 6.0) < 0.3
    # gaps between successive traces on one line (horizontal: same y)
    gaps = []
    by_line = {}
    for t in inner:
        by_line.setdefault(round(float(t[0, 1]), 6), []).append(sorted(t[:, 0]))
    for segs in by_line.values():
        segs.sort()
        gaps += [b[0] - a[1] for a, b in zip(segs[:-1], segs[1:])]
    assert abs(np.mean(gaps) - 2.0) < 0.1


def test_reproducible_for_a_seed_and_carries_the_joint():
    weak = dd.Joint(friction=20.0, cohesion=1e4)
    sets = [dd.JointSet(dip=60.0, spacing=5.0, spacing_spread=1.0, joint=weak),
            dd.JointSet(dip=150.0, spacing=7.0, trace_length=10.0, gap=3.0)]
    a = dd.joint_sets(BOX, sets, seed=3)
    b = dd.joint_sets(BOX, sets, seed=3)
    c = dd.joint_sets(BOX, sets, seed=4)
    assert len(a) == len(b) and all(np.array_equal(x[0], y[0]) for x, y in zip(a, b))
    assert len(a) != len(c) or not all(np.array_equal(x[0], y[0]) for x, y in zip(a, c))
    assert {j for _, j in a} == {weak, dd.Joint()}
    # every trace lies inside the domain
    domain = shapely.Polygon(BOX)
    assert all(domain.buffer(1e-9).covers(shapely.LineString(t)) for t, _ in a)


def test_cut_by_generated_joints():
    scene = dd.Scene()
    rock = dd.Material(density=2600.0, young=1e10, poisson=0.25)
    box = [(0, 0), (20, 0), (20, 10), (0, 10)]
    traces = dd.joint_sets(box, [dd.JointSet(dip=20.0, spacing=2.0), dd.JointSet(dip=100.0, spacing=3.0)], seed=1)
    ids = scene.cut(box, traces, material=rock)
    assert len(ids) > 20
    area = sum(abs(shapely.Polygon(scene.polygon(b)).area) for b in ids)
    assert area == pytest.approx(200.0)


@pytest.mark.parametrize("kwargs, name", [
    (dict(dip=180.0, spacing=1.0), "dip"), (dict(dip=10.0, spacing=0.0), "spacing"),
    (dict(dip=10.0, spacing=1.0, trace_length=5.0), "gap"),
    (dict(dip=10.0, spacing=1.0, dip_spread=-1.0), "dip_spread"),
])
def test_bad_joint_sets(kwargs, name):
    with pytest.raises(ValueError, match=name):
        dd.JointSet(**kwargs)
