"""`kgm.probabilistic` with ``sampling="subset"`` and ``"importance"`` (`kgm.studies.rare`): the
estimators on a study's own samples, against exact probabilities of failure; resuming from the
study file, the same table on worker processes, the command line and the pictures."""

import importlib.util
import io
import math
import re
import shutil

import numpy as np
import pytest
import scipy.stats as st

import kgm
import kgm_cases
import test_reliability as closed

VARIABLES = {"friction": closed.FRICTION, "cohesion": closed.COHESION}
CORRELATION = {("friction", "cohesion"): closed.RHO}


def _slide(sampling, n, **kw):
    return kgm.probabilistic(kgm_cases.planar_scene, VARIABLES, n, method="rigid", group={0}, sampling=sampling,
                             correlation=CORRELATION, seed=kw.pop("seed", 1), **kw)


#: a block on a 30° plane with its friction angle N(34.65°, 2°): P_f = Φ((30 − 34.65)/2) ≈ 1e-2
#: (two levels of subset simulation: the default tests' cheap study)
INCLINE = {"friction": st.norm(34.65, 2.0)}
INCLINE_PF = float(st.norm.cdf((30.0 - 34.65) / 2.0))


def _incline(sampling, n, **kw):
    return kgm.probabilistic(kgm_cases.incline_scene, INCLINE, n, method="rigid", group={1}, sampling=sampling,
                             seed=kw.pop("seed", 3), **kw)


def test_planar_slide_study_by_importance_sampling():
    """Hoek & Bray's planar slide built as a scene and judged by the rigid evaluator, friction
    normal and cohesion lognormal correlated −0.5: P_f ≈ 9e-4 exactly (one-dimensional
    quadrature over φ); the importance estimate (FORM, then 60 samples) within three of its own
    c.o.v.; the design point in the variables' units on FS = 1."""
    exact = closed._slide_exact()
    imp = _slide("importance", 60)
    dp = imp.design_point
    assert dp.converged and imp.evaluations == 60 + dp.evaluations == len(imp.table)
    assert abs(imp.pf - exact) <= 3.0 * imp.pf_cov * exact, (imp.pf, imp.pf_cov, exact)
    assert imp.pf_cov < 0.5  # an estimate, not a bound
    # the design point in the variables' units: on FS = 1, friction the driving variable
    assert dp.fs == pytest.approx(1.0, abs=2e-3)
    assert kgm_cases.hoek_bray_fs(20.0, 60.0, 30.0, 5.0, dp.values["friction"], dp.values["cohesion"]) == \
        pytest.approx(dp.fs, rel=1e-9)
    assert abs(dp.alpha["friction"]) > abs(dp.alpha["cohesion"]) and \
        sum(a * a for a in dp.alpha.values()) == pytest.approx(1.0)
    # every row is a sample: its FS the closed form of its values
    t = imp.table
    assert np.allclose(t["fs"], kgm_cases.hoek_bray_fs(20.0, 60.0, 30.0, 5.0, t["friction"], t["cohesion"]),
                       rtol=1e-9)
    assert np.array_equal(t["failed"], t["fs"] < 1.0)


def test_a_subset_study_of_a_block_on_a_plane():
    """Subset simulation through kgm.probabilistic (50 samples a level, P_f ≈ 1e-2 exactly):
    within three of its own c.o.v.; each row the closed form of its values; the levels' FS
    thresholds falling to 1, each level's samples below the threshold before."""
    sub = _incline("subset", 50)
    assert abs(sub.pf - INCLINE_PF) <= 3.0 * sub.pf_cov * INCLINE_PF, (sub.pf, sub.pf_cov, INCLINE_PF)
    assert sub.evaluations == len(sub.table) == sub.levels[-1].evaluations == 50 + 45 * (len(sub.levels) - 1)
    t = sub.table
    assert np.allclose(t["fs"], kgm_cases.incline_fs(t["friction"], 0.0), rtol=1e-9)
    assert np.array_equal(t["failed"], t["fs"] < 1.0)
    thresholds = [lv.fs_threshold for lv in sub.levels]
    assert all(a > b for a, b in zip(thresholds, thresholds[1:])) and thresholds[-1] == 1.0
    for before, level in zip(sub.levels, sub.levels[1:]):
        assert np.all(level.fs <= before.fs_threshold)
    lo, hi = sub.pf_interval()
    assert lo < sub.pf < hi and "subset simulation" in sub.summary()


@pytest.mark.slow
def test_planar_slide_study_by_importance_sampling_and_subset_simulation():
    """The planar slide of `test_planar_slide_study_by_importance_sampling` with 300 samples:
    importance sampling and subset simulation (300 samples a level) within three of their own
    c.o.v. of the exact P_f. About 1,200 rigid evaluations: 10–20 s on the shared machine."""
    exact = closed._slide_exact()
    imp = _slide("importance", 300)
    assert abs(imp.pf - exact) <= 3.0 * imp.pf_cov * exact, (imp.pf, imp.pf_cov, exact)
    sub = _slide("subset", 300)
    assert abs(sub.pf - exact) <= 3.0 * sub.pf_cov * exact, (sub.pf, sub.pf_cov, exact)
    t = sub.table
    assert np.allclose(t["fs"], kgm_cases.hoek_bray_fs(20.0, 60.0, 30.0, 5.0, t["friction"], t["cohesion"]),
                       rtol=1e-9)
    thresholds = [lv.fs_threshold for lv in sub.levels]
    assert all(a > b for a, b in zip(thresholds, thresholds[1:])) and thresholds[-1] == 1.0


def _resume(tmp_path, n: int, workers: int):
    """A study file cut after 3n/2 of its evaluations (a partial line at its end): the study
    started again with the same arguments on ``workers`` reads them, evaluates the others and
    gives the uninterrupted table and P_f; the file reads back as the study."""
    out = tmp_path / "study.csv"
    whole = _incline("subset", n, out=out, workers=1)
    keep = 3 * n // 2
    assert len(whole.levels) >= 2 and whole.evaluations > keep + 2
    lines = out.read_text().splitlines(keepends=True)
    cut = tmp_path / "cut.csv"
    cut.write_text("".join(lines[:2 + keep]) + lines[2 + keep][:10])
    again = _incline("subset", n, out=cut, workers=workers)
    assert again.resumed == keep
    assert np.array_equal(again.table, whole.table) and again.pf == whole.pf and again.pf_cov == whole.pf_cov
    back = kgm.read_study(cut)
    assert np.array_equal(back.table, whole.table) and back.pf == whole.pf and len(back.levels) == len(whole.levels)
    assert all(np.array_equal(a.values["friction"], b.values["friction"]) for a, b in zip(back.levels, whole.levels))
    return out


def test_a_subset_study_resumes_from_its_file_bit_for_bit(tmp_path):
    out = _resume(tmp_path, 20, workers=1)
    # a file whose values are not this study's is refused, naming the evaluation
    bad = tmp_path / "bad.csv"
    shutil.copy(out, bad)
    text = bad.read_text().splitlines(keepends=True)
    row = text[5].split(",")
    row[2] = repr(float(row[2]) + 1e-9)
    text[5] = ",".join(row)
    bad.write_text("".join(text))
    with pytest.raises(ValueError, match="other values for evaluation 3"):
        _incline("subset", 20, out=bad, workers=1)


@pytest.mark.slow
def test_a_subset_study_resumes_on_worker_processes(tmp_path):
    """The resumed study on two worker processes, started once for all its batches
    (`ddatai.parallel.Executor`): the same table. About 5 s on the shared machine (the
    workers' start)."""
    _resume(tmp_path, 50, workers=2)


def test_settings_and_bad_input():
    sub = _incline(kgm.SubsetSampling(p0=0.2), 20, seed=2)
    assert all(lv.probability >= 0.2 for lv in sub.levels[:-1]) and sub.estimate.p0 == 0.2
    with pytest.raises(ValueError, match="whole numbers"):
        _incline(kgm.SubsetSampling(p0=0.3), 100)
    with pytest.raises(ValueError, match="geometry_seed=True with sampling='subset'"):
        kgm.probabilistic(kgm_cases.jointed_scene, {"friction": st.norm(30, 3)}, 100, method="rigid",
                          sampling="subset", geometry_seed=True)
    with pytest.raises(ValueError, match="needs at least one variable with a distribution"):
        kgm.probabilistic(kgm_cases.incline_scene, {"friction": 30.0}, 100, method="rigid", sampling="importance")
    with pytest.raises(ValueError, match="sampling must be one of"):
        kgm.probabilistic(kgm_cases.incline_scene, {"friction": st.norm(30, 3)}, 100, sampling="sobol")


def _scene_script(tmp_path):
    (tmp_path / "vars.toml").write_text('[friction]\ndistribution = "normal"\nmean = 34.65\nsd = 2.0\n')
    script = tmp_path / "scene.py"
    script.write_text(f"import sys; sys.path.insert(0, {str(kgm_cases.__file__.rsplit('/', 1)[0])!r})\n"
                      "import kgm_cases\n\n\ndef build(friction=30.0):\n"
                      "    return kgm_cases.incline_scene(friction=friction)\n")
    return script


def test_command_line_subset_and_importance(tmp_path):
    """`kgm study ... --sampling subset` prints P_f, its c.o.v. and the levels, writes the study
    file that reads back as the study of kgm.probabilistic; ``importance`` prints the design
    point."""
    from kgm.cli import main

    script = _scene_script(tmp_path)
    out = io.StringIO()
    rc = main(["study", str(script), "--vars", str(tmp_path / "vars.toml"), "--n", "20", "--method", "rigid",
               "--group", "1", "--sampling", "subset", "--seed", "3", "--out", str(tmp_path / "s.csv")], out=out)
    text = out.getvalue()
    assert rc == 0, text
    ref = kgm.read_study(tmp_path / "s.csv")
    assert np.array_equal(ref.table, _incline("subset", 20).table)
    assert f"P_f = {ref.pf:.3g}" in text and "FS threshold" in text and f"c.o.v. {ref.pf_cov:.2f}" in text
    out = io.StringIO()
    rc = main(["study", str(script), "--vars", str(tmp_path / "vars.toml"), "--n", "10", "--method", "rigid",
               "--group", "1", "--sampling", "importance"], out=out)
    text = out.getvalue()
    assert rc == 0 and "design point (FORM" in text, text
    # on FS = 1: friction 30° (the FS of a block on a 30° plane is tanφ/tan 30°)
    assert float(re.search(r"friction = ([-\d.e+]+)", text).group(1)) == pytest.approx(30.0, abs=0.05), text


@pytest.mark.slow
@pytest.mark.skipif(importlib.util.find_spec("matplotlib") is None,
                    reason="plots need matplotlib, an optional extra (pip install 'ddatai[plot]')")
def test_command_line_pictures(tmp_path):
    """The levels and the convergence pictures from the command line, FS = 1 drawn on a
    two-variable study. About 10–20 s on the shared machine (matplotlib, a contour's grid of
    evaluations)."""
    from PIL import Image

    from kgm.cli import main

    script = _scene_script(tmp_path)
    out = io.StringIO()
    rc = main(["study", str(script), "--vars", str(tmp_path / "vars.toml"), "--n", "50", "--method", "rigid",
               "--group", "1", "--sampling", "subset", "--seed", "3",
               "--plot-levels", str(tmp_path / "levels.png"), "--plot-convergence", str(tmp_path / "pf.png")],
              out=out)
    assert rc == 0, out.getvalue()
    for name in ("levels.png", "pf.png"):
        with Image.open(tmp_path / name) as im:
            assert im.size[0] > 400 and len(im.getcolors(maxcolors=100000)) > 20
    # a two-variable study draws FS = 1
    imp = _slide("importance", 100)
    fig = imp.plot_levels(tmp_path / "imp.png", grid=8)
    assert any(c.get_label() == "FS = 1 (others at the reference)" or c.get_label() == "FS = 1"
               for c in fig.axes[0].get_lines())
    assert (tmp_path / "imp.png").exists()
    with pytest.raises(ValueError, match="draws a study of sampling='subset' or 'importance'"):
        kgm.probabilistic(kgm_cases.incline_scene, {"friction": st.norm(33, 3)}, 10, method="rigid",
                          group={1}).plot_levels(tmp_path / "x.png")


# ---------------------------------------------------------------------- Example II, slow profile
def _example_2_monte_carlo(variables, correlation, n: int, seed: int):
    """Plain Monte Carlo of ``n`` samples of Example II's group {P, A} judged by Sarma, each
    verdict Sarma's own: the study's samples (`kgm.sample_variables`, Gaussian copula), a
    sample failing when φ < φc(c), Sarma's critical friction at the sample's cohesion
    (FS < 1 ⇔ φ < φc at a fixed c: FS rises with φ). φc(c) is computed exactly on 33 values of
    c across the samples and interpolated (PCHIP); every sample within ε of the curve, ε ten
    times the interpolant's largest error at the midpoints, is evaluated on its own. Returns
    (P_f, samples evaluated on their own, ε)."""
    from pathlib import Path

    from scipy.interpolate import PchipInterpolator

    from ddatai.io.scenefile import build_scene, load_scene_script

    script = load_scene_script(str(Path(kgm_cases.__file__).parents[1] / "scenes" / "example_2.py"))

    def sarma(friction, cohesion):
        scene, _ = build_scene(script, friction=float(friction), cohesion=float(cohesion))
        return kgm.evaluate(scene, {0, 1}, "sarma")

    s = kgm.sample_variables(variables, n, seed=seed, correlation=correlation)
    phi, c = s["friction"], s["cohesion"]
    grid = np.linspace(c.min(), c.max(), 33)
    curve = PchipInterpolator(grid, [sarma(22.0, ck).critical_friction for ck in grid])
    mids = 0.5 * (grid[1:] + grid[:-1])
    err = max(abs(curve(m) - sarma(22.0, m).critical_friction) for m in mids)
    eps = max(10.0 * err, 1e-3)
    failed = phi < curve(c)
    near = np.flatnonzero(np.abs(phi - curve(c)) < eps)
    for i in near:
        failed[i] = sarma(phi[i], c[i]).fs < 1.0
    # a check of the curve away from it: 40 samples across the failure boundary's band
    rng = np.random.default_rng(seed)
    band = np.flatnonzero(np.abs(phi - curve(c)) < 1.0)
    for i in rng.choice(band, size=min(40, len(band)), replace=False):
        assert (sarma(phi[i], c[i]).fs < 1.0) == failed[i], (phi[i], c[i])
    return float(np.mean(failed)), len(near), eps


@pytest.mark.slow
def test_example_2_sarma_at_1e_3_subset_and_importance_agree_with_a_million_samples():
    """Example II's key group {P, A} under Sarma with strong joints (φ ~ N(34.5°, 2.2°), c
    lognormal 20 ± 5 kPa, correlated −0.3: docs/kgm/example_2_rare_vars.toml): subset simulation
    (1,000 samples a level) and importance sampling (1,000) through kgm.probabilistic agree with
    a plain Monte Carlo of 10⁶ Sarma samples within three standard deviations of their
    difference (the estimates' own c.o.v. and the binomial one). 83 s wall on the shared 2-core
    machine at a load of ~7, up to 10 minutes under heavier load (docs/kgm/reliability.md)."""
    from pathlib import Path

    from ddatai.parallel import ScriptFunction
    from kgm.studies.sampling import read_variables

    root = Path(kgm_cases.__file__).parents[1]
    variables, correlation = read_variables(root / "docs" / "kgm" / "example_2_rare_vars.toml")
    n_mc = 1_000_000
    mc, alone, _ = _example_2_monte_carlo(variables, correlation, n_mc, seed=11)
    assert 3e-4 < mc < 3e-3 and alone < 2000
    mc_sd = math.sqrt(mc * (1.0 - mc) / n_mc)
    build = ScriptFunction(str(root / "scenes" / "example_2.py"))
    for sampling in ("subset", "importance"):
        study = kgm.probabilistic(build, variables, 1000, method="sarma", group={0, 1}, sampling=sampling,
                                  correlation=correlation, seed=5)
        sd = math.hypot(study.pf * study.pf_cov, mc_sd)
        assert abs(study.pf - mc) <= 3.0 * sd, (sampling, study.pf, study.pf_cov, mc)


@pytest.mark.slow
def test_dda_judged_importance_study_of_a_block_on_a_plane():
    """method="dda": the limit state is each sample's DDA strength-reduction factor (a bisection
    of DDA runs, resolved to DdaSettings.fs_tolerance = 2 %). A block on a 30° plane with its
    friction N(34°, 2°): FS = tanφ/tan 30°, so the design point lies where tanφ = tan 30°·(1 ± 2 %)
    and P_f between Φ((29.5° − 34°)/2°) and Φ((30.5° − 34°)/2°) (0.012–0.040); the importance
    estimate (FORM, then 40 samples on 2 workers) within three of its c.o.v. of that range.
    About 10 minutes on 2 shared cores (a sample took 10–20 s under a load of ~15)."""
    import scipy.special as sp

    variables = {"friction": st.norm(34.0, 2.0)}
    study = kgm.probabilistic(kgm_cases.incline_scene, variables, 40, method="dda", group={1},
                              sampling="importance", seed=2, workers=2)
    t = math.tan(math.radians(30.0))
    lo_phi, hi_phi = (math.degrees(math.atan(t * f)) for f in (0.98, 1.02))
    assert lo_phi <= study.design_point.values["friction"] <= hi_phi, study.design_point
    lo, hi = (float(sp.ndtr((p - 34.0) / 2.0)) for p in (lo_phi, hi_phi))
    assert lo * (1.0 - 3.0 * study.pf_cov) <= study.pf <= hi * (1.0 + 3.0 * study.pf_cov), (study.pf, lo, hi)
    # every row a DDA strength-reduction factor within the bisection's resolution of the closed form
    fs = study.table["fs"]
    assert np.all(np.abs(fs / kgm_cases.incline_fs(study.table["friction"], 0.0) - 1.0) < 0.03)
