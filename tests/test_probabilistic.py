"""Probabilistic KGM (`kgm.probabilistic`) and parameter sweeps (`ddatai.sweep`) against exact
probabilities and closed forms; reproducibility over workers and resuming."""

import csv
import importlib.util
import math
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import scipy.stats as st

import kgm
import kgm_cases

ROOT = Path(__file__).resolve().parents[1]
THETA = 30.0  # dip of kgm_cases.incline_scene's plane [degrees]


def _exact_pf_friction(mean, sd):
    """Cohesionless block on a plane of dip θ: FS = tanφ/tanθ < 1 ⇔ φ < θ."""
    return st.norm.cdf((THETA - mean) / sd)


def test_pf_of_normal_friction_within_the_monte_carlo_interval():
    n = 4_000
    study = kgm.probabilistic(kgm_cases.incline_scene, {"friction": st.norm(33.0, 3.0)}, n,
                              method="rigid", group={1}, seed=11, workers=2)
    exact = _exact_pf_friction(33.0, 3.0)
    lo, hi = study.pf_interval(0.99)
    assert lo <= exact <= hi, (study.pf, exact, (lo, hi))
    assert study.n == n and len(study.table) == n
    # every sample's FS is the closed form of its own friction angle
    assert np.allclose(study.fs, kgm_cases.incline_fs(study.table["friction"], 0.0), rtol=1e-9)
    assert np.array_equal(study.failed, study.fs < 1.0)
    # β of a (nearly) normal FS: (E[FS] − 1)/σ[FS], from the samples' FS
    fs = study.fs
    assert study.beta == pytest.approx((fs.mean() - 1.0) / fs.std(ddof=1), rel=1e-12)
    assert study.block_frequency() == {1: 1.0}


def test_pf_of_normal_cohesion_within_the_monte_carlo_interval():
    """FS < 1 ⇔ c < c_crit = W(sinθ − cosθ tanφ)/A; cohesion normal, truncated at 0:
    P_f = (Φ((c_crit − μ)/σ) − Φ(−μ/σ)) / (1 − Φ(−μ/σ))."""
    n = 4_000
    friction, mean, sd = 20.0, 6000.0, 2000.0
    w = kgm_cases.RHO * kgm_cases.G * 10.0 * 1.0
    t = math.radians(THETA)
    c_crit = w * (math.sin(t) - math.cos(t) * math.tan(math.radians(friction))) / 10.0
    below = st.norm.cdf(-mean / sd)
    exact = (st.norm.cdf((c_crit - mean) / sd) - below) / (1.0 - below)
    cohesion = st.truncnorm(-mean / sd, np.inf, loc=mean, scale=sd)
    study = kgm.probabilistic(kgm_cases.incline_scene, {"friction": friction, "cohesion": cohesion},
                              n, method="sarma", group={1}, seed=5, workers=2)
    lo, hi = study.pf_interval(0.99)
    assert lo <= exact <= hi, (study.pf, exact)
    assert 0.15 < exact < 0.35
    assert np.all(study.table["friction"] == friction)  # a constant is a column too
    assert np.allclose(study.fs, kgm_cases.incline_fs(friction, study.table["cohesion"]), rtol=1e-9)


def test_latin_hypercube_reaches_the_monte_carlo_precision_with_a_hundredth_of_the_samples():
    """One variable, stratified: each of n strata holds one sample, so |P_f − exact| ≤ 1/n —
    200 samples are within the 95 % half-width of a 20,000-sample Monte Carlo estimate."""
    exact = _exact_pf_friction(33.0, 3.0)
    mc_half = 1.96 * math.sqrt(exact * (1 - exact) / 20_000)
    n = 200
    for seed in (1, 2, 3):
        lhs = kgm.probabilistic(kgm_cases.incline_scene, {"friction": st.norm(33.0, 3.0)}, n, method="rigid",
                                group={1}, sampling="latin-hypercube", seed=seed, workers=1)
        assert abs(lhs.pf - exact) <= 1.0 / n + 1e-12, (seed, lhs.pf, exact)
        # the measured error beats the 20,000-sample Monte Carlo half-width
        assert abs(lhs.pf - exact) < mc_half, (seed, lhs.pf, exact, mc_half)
        # one sample in each stratum of the friction distribution
        strata = np.floor(st.norm(33.0, 3.0).cdf(lhs.table["friction"]) * n).astype(int)
        assert sorted(strata) == list(range(n))


def test_correlated_variables_have_the_asked_correlation_and_their_marginals():
    v = {"friction": st.norm(30.0, 3.0), "cohesion": st.lognorm(0.5, scale=20e3)}
    s = kgm.sample_variables(v, 20_000, seed=3, correlation={("friction", "cohesion"): -0.6})
    z1 = st.norm.ppf(v["friction"].cdf(s["friction"]))
    z2 = st.norm.ppf(v["cohesion"].cdf(s["cohesion"]))
    r = np.corrcoef(z1, z2)[0, 1]
    assert r == pytest.approx(-0.6, abs=3 * (1 - 0.36) / math.sqrt(20_000) + 0.01)
    # marginals unchanged (Kolmogorov–Smirnov at 1 %)
    assert st.kstest(s["friction"], v["friction"].cdf).pvalue > 0.01
    assert st.kstest(s["cohesion"], v["cohesion"].cdf).pvalue > 0.01
    assert np.all(s["cohesion"] > 0)


def test_same_seed_same_table_on_one_and_two_worker_processes():
    v = {"friction": st.uniform(20.0, 20.0)}
    one = kgm.probabilistic(kgm_cases.jointed_scene, v, 24, method="rigid", seed=9, workers=1)
    two = kgm.probabilistic(kgm_cases.jointed_scene, v, 24, method="rigid", seed=9, workers=2)
    assert np.array_equal(one.table, two.table)
    # jointed_scene takes a seed: each sample is its own realisation of the joint set, and
    # any sample can be run again from its row
    assert len(set(one.table["seed"].tolist())) == 24
    row = one.table[7]
    again = kgm.analyze(kgm_cases.jointed_scene(friction=float(row["friction"]), seed=int(row["seed"])),
                        method="rigid").critical
    assert again.fs == row["fs"] and " ".join(map(str, sorted(again.blocks))) == row["critical"]
    assert len({r for r in one.table["critical"]}) > 1  # the critical group moves with the joints


@pytest.mark.skipif(importlib.util.find_spec("distributed") is None,
                    reason="dask.distributed is an optional extra (pip install ddatai[dask])")
def test_same_table_on_a_local_dask_cluster_with_one_and_two_workers():
    from dask.distributed import Client, LocalCluster

    v = {"friction": st.norm(33.0, 3.0)}
    ref = kgm.probabilistic(kgm_cases.incline_scene, v, 40, method="rigid", seed=4, workers=1)
    for n_workers in (1, 2):
        with LocalCluster(n_workers=n_workers, threads_per_worker=1, processes=True,
                          dashboard_address=None) as cluster, Client(cluster) as client:
            study = kgm.probabilistic(kgm_cases.incline_scene, v, 40, method="rigid", seed=4, client=client)
        assert np.array_equal(study.table, ref.table), n_workers


def _run_killed(out: Path, n: int, rows_before_kill: int) -> None:
    code = (f"import sys; sys.path[:0] = [{str(ROOT)!r}, {str(ROOT / 'tests')!r}]\n"
            "import scipy.stats as st, kgm, kgm_cases\n"
            f"kgm.probabilistic(kgm_cases.incline_scene_slow, {{'friction': st.norm(33.0, 3.0)}}, {n}, "
            f"method='rigid', seed=2, workers=1, out={str(out)!r})\n")
    proc = subprocess.Popen([sys.executable, "-c", code])
    try:
        deadline = time.time() + 120
        while time.time() < deadline:
            if out.exists() and out.read_text().count("\n") >= rows_before_kill + 2:
                break
            if proc.poll() is not None:
                raise AssertionError("the study finished before it was killed")
            time.sleep(0.02)
        proc.kill()
    finally:
        proc.wait()


def test_a_killed_study_resumes_without_running_a_sample_twice(tmp_path):
    n = 40
    out = tmp_path / "study.csv"
    _run_killed(out, n, rows_before_kill=10)
    with open(out) as fh:
        written = sum(1 for _ in fh) - 2
    assert 10 <= written < n
    calls = []
    resumed = kgm.probabilistic(kgm_cases.incline_scene_slow, {"friction": st.norm(33.0, 3.0)}, n, method="rigid",
                                seed=2, workers=1, out=out, progress=lambda done, total: calls.append(done))
    assert resumed.resumed == written and len(calls) == n - written
    whole = kgm.probabilistic(kgm_cases.incline_scene, {"friction": st.norm(33.0, 3.0)}, n, method="rigid",
                              seed=2, workers=1)
    assert np.array_equal(resumed.table, whole.table)
    # the file holds each sample once, and reads back as the study
    with open(out) as fh:
        next(fh)
        indices = [int(r["index"]) for r in csv.DictReader(fh)]
    assert sorted(indices) == list(range(n))
    back = kgm.read_study(out)
    assert np.array_equal(back.table, whole.table) and back.pf == whole.pf


def test_csv_and_frequency_picture(tmp_path):
    study = kgm.probabilistic(kgm_cases.jointed_scene, {"friction": st.uniform(20.0, 20.0)}, 12, method="rigid",
                              seed=1, workers=1)
    assert np.array_equal(kgm.read_study(study.to_csv(tmp_path / "t.csv")).table, study.table)
    freq = study.block_frequency()
    assert all(0 < f <= 1 for f in freq.values())
    from PIL import Image

    path = study.write_png(kgm_cases.jointed_scene(seed=0), tmp_path / "freq.png", size=(320, 240))
    with Image.open(path) as im:
        assert im.size == (320, 240)
        assert len(im.getcolors(maxcolors=100000)) > 3


@pytest.mark.parametrize("kwargs, match", [
    (dict(variables={"frictoin": st.norm(30, 3)}), "not a parameter of build"),
    (dict(variables={"friction": [30, 3]}), "frozen scipy.stats distribution"),
    (dict(variables={}), "non-empty mapping"),
    (dict(n=0), "n .number of samples."),
    (dict(sampling="sobol"), "sampling must be one of"),
    (dict(method="fem"), "method must be one of"),
    (dict(workers=0), "workers must be an integer"),
    (dict(client=42), "client must be None"),
    (dict(variables={"friction": st.norm(30, 3), "cohesion": st.norm(1e3, 1)},
          correlation={("friction", "cohesion"): 1.5}), "must be a number in"),
    (dict(variables={"friction": st.norm(30, 3)}, correlation={("friction", "young"): 0.5}),
     "pair of two different sampled variables"),
    (dict(geometry_seed=True), "no 'seed' parameter"),
])
def test_bad_input_is_refused_before_any_work(kwargs, match):
    args = dict(variables={"friction": st.norm(30, 3)}, n=10, method="rigid")
    args.update(kwargs)
    with pytest.raises(ValueError, match=match):
        kgm.probabilistic(kgm_cases.incline_scene, args.pop("variables"), args.pop("n"), **args)


def test_a_file_of_another_study_is_not_resumed(tmp_path):
    out = tmp_path / "s.csv"
    kgm.probabilistic(kgm_cases.incline_scene, {"friction": st.norm(30, 3)}, 5, method="rigid", seed=1,
                      workers=1, out=out)
    with pytest.raises(ValueError, match="holds another study"):
        kgm.probabilistic(kgm_cases.incline_scene, {"friction": st.norm(30, 3)}, 5, method="rigid", seed=2,
                          workers=1, out=out)


def test_a_failing_sample_is_named():
    with pytest.raises(RuntimeError, match=r"sample \d+ \(friction=.*\) failed: ValueError"):
        kgm.probabilistic(kgm_cases.incline_scene, {"friction": st.uniform(80.0, 20.0)}, 4, method="rigid",
                          seed=1, workers=1)


def test_sweep_rows_follow_the_sliding_closed_form():
    """Parameter sweep of a block on a 30° plane: it stays at φ = 35° and slides ½·g(sinθ −
    cosθ tanφ)·t² at φ = 20° (duration 0.4 s)."""
    import ddatai as dd

    rows = dd.sweep(kgm_cases.incline_scene, {"friction": [20.0, 35.0], "cohesion": [0.0]}, duration=0.4,
                    measure=lambda res: {"final_time": float(res.time[-1])}, workers=1)
    assert list(rows["friction"]) == [20.0, 35.0] and rows["finished"].all()
    t = math.radians(THETA)
    a = kgm_cases.G * (math.sin(t) - math.cos(t) * math.tan(math.radians(20.0)))
    assert rows["max_displacement"][0] == pytest.approx(0.5 * a * 0.4 ** 2, rel=0.01)
    assert rows["max_displacement"][1] < 1e-4
    assert np.allclose(rows["final_time"], 0.4) and np.allclose(rows["time_reached"], 0.4)
    with pytest.raises(ValueError, match="non-empty list of values"):
        dd.sweep(kgm_cases.incline_scene, {"friction": 20.0}, duration=0.1)
    with pytest.raises(ValueError, match="duration must be"):
        dd.sweep(kgm_cases.incline_scene, [{"friction": 20.0}], duration=-1)


def test_dda_verdicts_of_sampled_friction_follow_the_closed_form():
    """method='dda': each sample's group simulated at its own strength (one run); the block on
    the 30° plane fails exactly when φ < 30° (samples within 1° of it are not asserted: the
    judgement resolves ~0.3° there)."""
    study = kgm.probabilistic(kgm_cases.incline_scene, {"friction": st.uniform(10.0, 40.0)}, 4, method="dda",
                              sampling="latin-hypercube", group={1}, seed=3, workers=1)
    phi = study.table["friction"]
    clear = np.abs(phi - THETA) > 1.0
    assert clear.sum() >= 3
    assert np.array_equal(study.failed[clear], phi[clear] < THETA)
    assert np.all(np.isnan(study.fs))  # verdicts only, no strength reduction


def test_cli_reads_a_variables_file_and_writes_the_study(tmp_path):
    from kgm.cli import main

    vars_toml = tmp_path / "vars.toml"
    vars_toml.write_text('[friction]\ndistribution = "normal"\nmean = 33.0\nsd = 3.0\n'
                         '[cohesion]\ndistribution = "constant"\nvalue = 0.0\n')
    script = tmp_path / "scene.py"
    script.write_text(f"import sys; sys.path.insert(0, {str(ROOT / 'tests')!r})\n"
                      "import kgm_cases\n\n\ndef build(friction=30.0, cohesion=0.0):\n"
                      "    return kgm_cases.incline_scene(friction=friction, cohesion=cohesion)\n")
    import io

    out = io.StringIO()
    rc = main(["probabilistic", str(script), "--vars", str(vars_toml), "--n", "300", "--method", "rigid",
               "--group", "1", "--workers", "1", "--seed", "7", "--out", str(tmp_path / "s.csv"),
               "--png", str(tmp_path / "f.png")], out=out)
    assert rc == 0, out.getvalue()
    back = kgm.read_study(tmp_path / "s.csv")
    ref = kgm.probabilistic(kgm_cases.incline_scene, {"friction": st.norm(33.0, 3.0), "cohesion": 0.0}, 300,
                            method="rigid", group={1}, seed=7, workers=1)
    assert np.array_equal(back.table, ref.table)
    assert f"P_f = {ref.pf:.4f}" in out.getvalue() and (tmp_path / "f.png").exists()
    # bad variables files: one clear line, exit status 2
    vars_toml.write_text('[friction]\ndistribution = "gaussian"\nmean = 30\nsd = 3\n')
    assert main(["probabilistic", str(script), "--vars", str(vars_toml), "--n", "5"], out=io.StringIO()) == 2


@pytest.mark.parametrize("spec, check", [
    ({"x": {"distribution": "lognormal", "mean": 20e3, "sd": 5e3}}, lambda d: (d.mean(), d.std()) == pytest.approx((20e3, 5e3))),
    ({"x": {"distribution": "uniform", "min": 1.0, "max": 3.0}}, lambda d: (d.ppf(0), d.ppf(1)) == (1.0, 3.0)),
    ({"x": {"distribution": "triangular", "min": 0.0, "mode": 1.0, "max": 4.0}},
     lambda d: d.mean() == pytest.approx(5.0 / 3.0) and d.pdf(1.0) == pytest.approx(0.5)),
    ({"x": {"distribution": "truncated-normal", "mean": 1.0, "sd": 1.0, "min": 0.0}}, lambda d: d.ppf(0) == 0.0),
])
def test_variables_file_distributions(spec, check):
    from kgm.studies.sampling import variables_from_mapping

    variables, _ = variables_from_mapping(spec)
    assert check(variables["x"])


def test_the_study_file_gives_back_the_rows_it_was_given(tmp_path):
    """A sample's row (`kgm.studies.study.SampleRow`) written to the study file reads back
    bit for bit (floats by repr, nan and inf included), with its critical group's ids."""
    from kgm.studies.study import SampleRow, StudyFile, read_samples

    identity = dict(n=3, seed=0, sampling="monte-carlo", method="dda", variables=["friction"])
    rows = {0: SampleRow(fs=math.nan, failed=True, critical=(0, 1)), 1: SampleRow(fs=math.inf, failed=False),
            2: SampleRow(fs=0.1 + 0.2, failed=False, critical=(3, 12))}
    out = StudyFile(tmp_path / "study.csv", identity, ("friction",))
    for i, row in rows.items():
        out.append(i, 10 + i, [30.0 + i / 3], row)
    out.close()
    back = read_samples(tmp_path / "study.csv", identity, ("friction",))
    assert sorted(back) == sorted(rows)
    for i, row in rows.items():
        assert np.float64(back[i].fs).tobytes() == np.float64(row.fs).tobytes()
        assert (back[i].failed, back[i].critical, back[i].critical_text) == (row.failed, row.critical,
                                                                              " ".join(map(str, row.critical)))


def test_a_given_group_judged_by_its_dda_verdict_alone_is_not_screened(monkeypatch):
    """A DDA study of a given group without strength reduction takes each sample's DDA verdict
    alone (its FS is nan): the screening evaluator's FS, which it would drop, is not computed;
    the group is still checked (a group that is not connected is refused, naming it)."""
    from kgm.kinds import Method
    from kgm.studies import probabilistic as module

    def screened(*args, **kwargs):
        raise AssertionError("the screening evaluator ran")

    monkeypatch.setattr(module, "evaluate_group", screened)
    job = module._Job(build=kgm_cases.incline_scene, method=Method.DDA, settings=None, group=frozenset({1}),
                      pass_seed=False)
    out = module._screen(job, (0, {"friction": 20.0}, 1))
    assert out.group == frozenset({1}) and out.result is None and out.row.critical == (1,)
    with pytest.raises(ValueError, match="group"):
        module._screen(module._Job(build=kgm_cases.incline_scene, method=Method.DDA, settings=None,
                                   group=frozenset({0, 1}), pass_seed=False), (0, {"friction": 20.0}, 1))
