"""Probabilistic wedge studies (docs/kgm/wedge.md §5): the Fisher sampler against its
distribution, P_f and P(sliding | wedge) against a sample-by-sample brute force through the
reference path, samplings, correlation, the size filter and the CSV resume."""

from __future__ import annotations

import importlib.util
import math

import numpy as np
import pytest
import scipy.stats as st

import ddatai as dd
import kgm
from kgm.wedges.geometry import plane_normal
from kgm.wedges.study import scatter


def _base(**kw):
    j1, j2 = dd.Joint(friction=30.0), dd.Joint(friction=30.0)
    return kgm.wedge(kgm.Plane(70, 180), kgm.Plane(5, 180), 12.0, [kgm.Plane(50, 130, j1), kgm.Plane(55, 230, j2)],
                     **kw)


def test_fisher_angles_follow_fisher_distribution():
    """θ from the mean: P(θ' ≤ θ) = (1 − e^(K(cos θ − 1)))/(1 − e^(−2K)) (Kolmogorov–Smirnov),
    and the scattered poles' mean direction is the mean orientation."""
    k = 40.0
    f = kgm.Fisher(k)
    u = np.random.default_rng(0).random(20000)
    theta = np.radians(f.ppf(u))
    cdf = lambda t: (1 - np.exp(k * (np.cos(t) - 1))) / (1 - np.exp(-2 * k))   # noqa: E731
    assert st.kstest(theta, cdf).pvalue > 0.01
    dip, ddir = scatter(np.full(20000, 50.0), np.full(20000, 130.0), np.degrees(theta),
                        360 * np.random.default_rng(1).random(20000))
    n = plane_normal(dip, ddir)
    m = n.mean(axis=0)
    mean_angle = math.degrees(math.acos(m @ plane_normal(50, 130) / np.linalg.norm(m)))
    assert mean_angle < 0.3                   # the 95 % cone of the mean: 140/sqrt(K N) = 0.16°
    # the angle between each scattered plane and the mean is θ (a pole turned past the
    # horizontal is the same plane with its normal reversed)
    angle = np.degrees(np.arccos(np.abs(np.clip(n @ plane_normal(50, 130), -1, 1))))
    assert angle == pytest.approx(np.minimum(np.degrees(theta), 180 - np.degrees(theta)), abs=1e-9)
    assert kgm.Fisher(1e6).ppf(0.5) < 0.1
    with pytest.raises(ValueError, match="kappa"):
        kgm.Fisher(0.0)


def test_probabilities_equal_a_sample_by_sample_brute_force():
    """Every sample re-built with `kgm.wedge` (the reference path): the same verdicts and FS,
    so P_f = failed/all and P(sliding | wedge) = failed/valid as counted by hand."""
    base = _base()
    variables = {"joint1_orientation": kgm.Fisher(12.0), "joint2_orientation": kgm.Fisher(12.0),
                 "joint1_friction": st.norm(30, 4), "joint2_cohesion": st.uniform(1e3, 5e3), "height": 12.0}
    study = kgm.wedge_study(base, variables, 120, seed=4, min_volume=100.0)
    t = study.table
    failed = valid = 0
    for row in t:
        dip1, dd1 = scatter(np.array(50.0), np.array(130.0), row["joint1_orientation_angle"],
                            row["joint1_orientation_azimuth"])
        dip2, dd2 = scatter(np.array(55.0), np.array(230.0), row["joint2_orientation_angle"],
                            row["joint2_orientation_azimuth"])
        w = kgm.wedge(kgm.Plane(70, 180), kgm.Plane(5, 180), 12.0,
                      [kgm.Plane(float(dip1), float(dd1), dd.Joint(friction=row["joint1_friction"])),
                       kgm.Plane(float(dip2), float(dd2), dd.Joint(friction=30.0, cohesion=row["joint2_cohesion"]))])
        assert w.forms == bool(row["forms"])
        if w.forms:
            assert row["fs"] == pytest.approx(w.fs, rel=1e-9)
            ok = w.volume >= 100.0
            valid += ok
            failed += ok and w.fs < 1.0
    assert (study.valid, int(t["failed"].sum())) == (valid, failed)
    assert study.pf == failed / 120 and study.p_sliding == failed / valid
    assert 0 < study.pf < study.p_sliding < 1


def test_size_filter_separates_the_two_probabilities():
    """Slivers (below ``min_volume``) are neither valid nor failed: P_f can only fall, and
    P(sliding | wedge) is counted over the wedges kept."""
    variables = {"joint1_orientation": kgm.Fisher(15.0), "joint2_orientation": kgm.Fisher(15.0)}
    all_ = kgm.wedge_study(_base(), variables, 4000, seed=2)
    big = kgm.wedge_study(_base(), variables, 4000, seed=2, min_volume=20.0)
    assert big.valid < all_.valid and big.pf <= all_.pf
    kept = all_.table["forms"] & (all_.table["volume"] >= 20.0)
    assert big.valid == int(kept.sum())
    assert big.p_sliding == pytest.approx(np.mean(all_.table["fs"][kept] < 1.0))


def test_samplings_and_correlation_come_from_kgm_sample_variables():
    variables = {"joint1_friction": st.norm(30, 3), "joint2_friction": st.norm(30, 3)}
    corr = {("joint1_friction", "joint2_friction"): 0.8}
    s = kgm.wedge_study(_base(), variables, 2000, sampling="latin-hypercube", seed=5, correlation=corr)
    ref = kgm.sample_variables(variables, 2000, sampling="latin-hypercube", seed=5, correlation=corr)
    assert np.array_equal(s.table["joint1_friction"], ref["joint1_friction"])
    assert np.corrcoef(s.table["joint1_friction"], s.table["joint2_friction"])[0, 1] == pytest.approx(0.8, abs=0.03)
    # friction only: every sample forms the same wedge; FS = FS(φ1, φ2) of the reference
    row = s.table[7]
    w = kgm.wedge(kgm.Plane(70, 180), kgm.Plane(5, 180), 12.0,
                  [kgm.Plane(50, 130, dd.Joint(friction=row["joint1_friction"])),
                   kgm.Plane(55, 230, dd.Joint(friction=row["joint2_friction"]))])
    assert row["fs"] == pytest.approx(w.fs, rel=1e-12)


def test_csv_resume_and_bad_variables(tmp_path):
    out = tmp_path / "samples.csv"
    variables = {"joint1_orientation": kgm.Fisher(20.0), "water_fill": st.uniform(0, 1)}
    first = kgm.wedge_study(_base(water=kgm.Water()), variables, 300, seed=1, out=out)
    again = kgm.wedge_study(_base(water=kgm.Water()), variables, 300, seed=1, out=out)
    assert again.resumed == 300 and first.resumed == 0
    for name in ("fs", "volume"):
        assert np.array_equal(np.nan_to_num(first.table[name]), np.nan_to_num(again.table[name]))
    assert again.pf == first.pf and again.reasons() == first.reasons()
    other = kgm.wedge_study(_base(water=kgm.Water()), variables, 300, seed=2, out=out)
    assert other.resumed == 0
    with pytest.raises(ValueError, match="unknown variable 'joint3_dip'"):
        kgm.wedge_study(_base(), {"joint3_dip": st.norm(10, 1)}, 10)
    with pytest.raises(ValueError, match="min_volume"):
        kgm.wedge_study(_base(), {}, 10, min_volume=-1.0)


@pytest.mark.skipif(importlib.util.find_spec("distributed") is None,
                    reason="dask.distributed is an optional extra (pip install ddatai[dask])")
def test_same_table_on_a_local_dask_cluster(monkeypatch):
    """On a Dask cluster the samples go out in chunks (`ddatai.parallel.run`): the same table."""
    from dask.distributed import Client, LocalCluster

    import kgm.wedges.study as study_module

    monkeypatch.setattr(study_module, "CLUSTER_CHUNK", 700)       # several tasks for 2,000 samples
    variables = {"joint1_orientation": kgm.Fisher(20.0), "joint1_friction": st.norm(30, 3)}
    ref = kgm.wedge_study(_base(), variables, 2000, seed=3)
    with LocalCluster(n_workers=1, threads_per_worker=1, processes=False, dashboard_address=None) as cluster, \
            Client(cluster) as client:
        on = kgm.wedge_study(_base(), variables, 2000, seed=3, client=client)
    for name in ("fs", "volume", "failed"):
        assert np.array_equal(np.nan_to_num(on.table[name]), np.nan_to_num(ref.table[name]))
    assert on.pf == ref.pf
