"""Residual diagnostics: the repeated-pattern test's false-alarm rate and power, whiteness, and
gait features, on synthetic residuals whose truth is known."""

import numpy as np
import pytest
from numpy.testing import assert_allclose
from toywalk.sysid.residuals import feature_misfit, phase_bins, residual_report, step_features

from ..conftest import loaded_by
from .builders import grid_observations, walk_signals


def test_pattern_test_holds_its_false_alarm_rate():
    """White residuals: the repeated-pattern p-values are uniform (the repeated-measures F is exact
    for independent Gaussian bins). 400 components: the rate below 0.05 has a binomial SD of 0.011,
    so 0.02-0.08 is about 3 SD either way; a test with the wrong degrees of freedom falls outside
    it."""
    rng = np.random.default_rng(0)
    obs = grid_observations(rng=rng)
    p = []
    for _ in range(100):
        rep = residual_report(obs, rng.normal(0.0, 0.002, obs.value.shape))
        p += [t["pattern_p"] for t in rep.tests.values()]
    rate = np.mean(np.array(p) < 0.05)
    assert 0.02 < rate < 0.08, rate


def test_pattern_test_finds_a_pattern_and_whiteness_tests_see_correlation():
    """A residual that repeats every step at three quarters of the noise (1.5 mrad amplitude under
    2 mrad white noise, 16 steps of 40 samples, mirrored with the stance leg as a model's lean
    misfit is) is found: its p-value over 20 seeds was below 1.1e-8 in all (at 1 mrad below 1e-3 in
    19, at 0.5 mrad below 0.025 in 16); the same size of random offset per step is not a
    pattern."""
    rng = np.random.default_rng(1)
    obs = grid_observations(rng=rng)
    noise = rng.normal(0.0, 0.002, obs.value.shape)
    side = np.where(obs.stance[obs.step] == "L", 1.0, -1.0)  # a model's lean misfit flips with it
    pattern = 0.0015 * np.sin(2 * np.pi * obs.phase) * (obs.signal == 0) * side
    rep = residual_report(obs, noise + pattern)
    assert rep.systematic == ["lean"], rep.tests
    assert rep.tests["lean"]["pattern_p"] < 1e-6
    # Random per-step offsets (not repeated): no pattern, but the series is not white.
    offsets = rng.normal(0.0, 0.002, obs.n_steps)[obs.step] * (obs.signal == 1)
    rep = residual_report(obs, noise + offsets)
    assert "steer" not in rep.systematic
    assert rep.tests["steer"]["ljung_box_p"] < 1e-6 and rep.tests["steer"]["runs_p"] < 1e-6
    assert rep.tests["stance_pitch"]["ljung_box_p"] > 1e-3  # the white signals stay white


def test_a_shared_error_of_known_size_is_not_a_pattern():
    """An error shared by the same phase of every step of a foot (a tracker's bias by phase,
    removed with an estimate of SD 1 mrad: ``Observations.phase_sd``) under 2 mrad white noise: the
    plain test calls it a pattern nearly always (16 steps average the white noise down, not the
    shared error); told its SD, the test keeps its false-alarm rate. 100 draws of the shared error
    and the noise: the rate below 0.05 over 400 components, binomial SD 0.011, within 0.01-0.08
    (the F is approximate with the shared variance added, Satterthwaite's degrees of freedom:
    measured 0.064 over 800); the plain test's rate is above 0.8 (measured 0.90)."""
    import dataclasses

    rng = np.random.default_rng(3)
    obs = grid_observations(rng=rng)
    told = dataclasses.replace(obs, phase_sd=np.full(obs.value.shape, 0.001))
    bins = phase_bins(obs)
    cell = np.minimum((obs.phase * bins).astype(int), bins - 1)
    foot = obs.stance[obs.step]
    plain, aware = [], []
    for _ in range(100):
        shared = rng.normal(0.0, 0.001, (2, 4, bins))  # foot, signal, bin
        error = shared[(foot == "R").astype(int), obs.signal, cell]
        residuals = error + rng.normal(0.0, 0.002, obs.value.shape)
        plain += [t["pattern_p"] for t in residual_report(obs, residuals, bins=bins).tests.values()]
        aware += [t["pattern_p"] for t in residual_report(told, residuals, bins=bins).tests.values()]
    assert np.mean(np.array(plain) < 0.05) > 0.8
    assert 0.01 < np.mean(np.array(aware) < 0.05) < 0.08


def test_a_shared_error_of_known_size_widens_the_features_standard_errors():
    """The same shared error (1 mrad by signal, foot and phase bin, under 2 mrad of noise, 16
    steps) moves the features' means over the steps by more than the steps' scatter says: their z
    RMS over 20 draws 1.95-2.73 by feature (2.4 over all); told its SD, 0.85-1.58 (1.4 over all;
    with 16 steps the t's spread and the noisy model features keep it above 1). Bounds: above 2
    and below 1.7."""
    import dataclasses

    from toywalk.sysid.residuals import FEATURES, feature_misfit

    rng = np.random.default_rng(5)
    obs = grid_observations(rng=rng)
    told = dataclasses.replace(obs, phase_sd=np.full(obs.value.shape, 0.001))
    cell = np.minimum((obs.phase * 20).astype(int), 19)
    foot = (obs.stance[obs.step] == "R").astype(int)
    plain, aware = [], []
    for _ in range(20):
        shared = rng.normal(0.0, 0.001, (4, 2, 20))[obs.signal, foot, cell]
        measured = obs.value + shared + rng.normal(0.0, 0.002, obs.value.shape)
        keys = [k for k in FEATURES if k != "duration"] + ["steer_mean_right_minus_left"]
        for target, z in ((obs, plain), (told, aware)):
            f = feature_misfit(target, measured, obs.value, sigma=np.full(obs.value.shape, 0.002),
                               rng=1)
            z += [f[k]["z"] for k in keys]
    assert np.sqrt(np.mean(np.square(plain))) > 2
    assert np.sqrt(np.mean(np.square(aware))) < 1.7


def test_phase_bins_follow_the_samples_a_step():
    """A walk filmed with few samples a step (the stable toy at 60 frames/s: 6-7) still gets its
    repeated-pattern test: with 10 phase bins no step had a sample in every bin and the test
    was never made (p NaN). The bins are the most that keep the steps: 6 samples a step, 6
    bins; 40 samples, 10. At 6 bins the test holds its false-alarm rate (white residuals, 400
    components: 0.035 below 0.05, within 0.02-0.08 as above) and finds a pattern at 1.5 times
    the noise (3 mrad under 2 mrad, 16 steps): p at most 2.1e-7 over 20 seeds (with 2 mrad up to
    2.5e-3, at the verdict's level), where the fixed 10 bins gave NaN."""
    assert phase_bins(grid_observations(per_step=40)) == 10
    assert phase_bins(grid_observations(per_step=6)) == 6
    rng = np.random.default_rng(0)
    obs = grid_observations(per_step=6, rng=rng)
    p = [t["pattern_p"] for _ in range(100)
         for t in residual_report(obs, rng.normal(0.0, 0.002, obs.value.shape)).tests.values()]
    assert 0.02 < np.mean(np.array(p) < 0.05) < 0.08
    side = np.where(obs.stance[obs.step] == "L", 1.0, -1.0)
    pattern = 0.003 * np.sin(2 * np.pi * obs.phase) * (obs.signal == 0) * side
    rep = residual_report(obs, rng.normal(0.0, 0.002, obs.value.shape) + pattern)
    assert rep.bins == 6 and rep.systematic == ["lean"], rep.tests
    assert rep.tests["lean"]["pattern_p"] < 1e-6
    noisy = pattern + rng.normal(0.0, 0.002, obs.value.shape)
    assert np.isnan(residual_report(obs, noisy, bins=10).tests["lean"]["pattern_p"])  # as it was


def test_features_and_their_misfit():
    """Features from known curves: lean a sine of amplitude A has range 2A (the degree-6 curve
    through 40 samples: within 0.4 %); the misfit of a model with a 10 % smaller lean is found, the left-right
    difference of a walk whose right steps lean more is found."""
    obs = grid_observations(n_steps=12)
    amp = 0.05
    measured = amp * np.sin(2 * np.pi * obs.phase) * (obs.signal == 0)
    f = step_features(obs, measured)
    assert_allclose(f["lean_range"], 2 * amp, rtol=0.004)
    assert_allclose(f["duration"], 0.1)
    rng = np.random.default_rng(2)
    noisy = measured + rng.normal(0.0, 0.002, measured.shape)
    sigma = np.full(len(noisy), 0.002)
    misfit = feature_misfit(obs, noisy, 0.9 * measured, sigma=sigma, rng=3)
    assert misfit["lean_range"]["z"] > 5
    # A flat steer measured through noise: its range is the noise's, and so is the model's as
    # measured; compared without the noise, the noise alone seems a misfit.
    assert abs(misfit["steer_range"]["z"]) < 3
    assert feature_misfit(obs, noisy, 0.9 * measured)["steer_range"]["z"] > 5
    lopsided = noisy * np.where(obs.stance[obs.step] == "R", 1.1, 1.0)
    lr = feature_misfit(obs, lopsided, measured, sigma=sigma, rng=4)["lean_range_right_minus_left"]
    assert lr["z"] > 5 and lr["measured"] == pytest.approx(0.2 * amp, rel=0.2)


def test_scatter_noise_measures_white_noise_and_sees_correlated_noise():
    """The model-free noise SD (residuals.scatter_noise): 12 steps of 14 samples a signal (a
    140 samples/s film of 0.1 s steps, about the stable toy's 12-step walks), times jittered by up
    to 10 % of a sample interval, 2 mrad of white noise, 20 seeds (80 signals). Measured over 200
    seeds (800 signals): the estimate over the truth has mean 0.991 and SD 0.099 (range 0.66 to
    1.29), so each within 0.4 of 1 (4 SD) and the mean of 80 within 0.04 (3.6 SE). Against a
    slow, obvious reference on evenly spaced samples: numpy's 4th difference / sqrt(70), to
    round-off. Whiteness: over every other sample the scatter exceeds NOISE_WHITENESS times that
    over every sample in 4.1 % of white signals and in 83.5 % of signals with noise correlated
    over three samples (a running mean, same SD); here at most 10 of 80 white ones (3.6 SD above
    the expected 3.3) and at least 56 of 80 correlated ones (3.3 SD below 66.8)."""
    from toywalk.sysid.naming import NOISE_WHITENESS
    from toywalk.sysid.residuals import scatter_noise

    sd = 0.002
    ratios, white_flagged, correlated_seen = [], 0, 0
    for seed in range(20):
        rng = np.random.default_rng(seed)
        obs = grid_observations(n_steps=12, per_step=14)
        obs.time = obs.time + rng.uniform(-0.1, 0.1, len(obs.time)) * 0.1 / 14
        obs.value = walk_signals(obs, rng.normal(0.0, sd, len(obs.time)))
        got = scatter_noise(obs)
        assert set(got) == {"lean", "steer", "pitch_left", "pitch_right"}
        for name, v in got.items():
            assert v["windows"] == 12 * (14 - 4), v
            assert abs(v["sd"] / sd - 1) < 0.4, (seed, name, v)
            ratios.append(v["sd"] / sd)
            white_flagged += v["sd_alternate"] / v["sd"] > NOISE_WHITENESS
        running = rng.normal(0.0, sd, (len(obs.time) + 2))
        obs.value = walk_signals(obs, (running[:-2] + running[1:-1] + running[2:]) / np.sqrt(3))
        correlated_seen += sum(v["sd_alternate"] / v["sd"] > NOISE_WHITENESS
                               for v in scatter_noise(obs).values())
    assert abs(np.mean(ratios) - 1) < 0.04, np.mean(ratios)
    assert white_flagged <= 10 and correlated_seen >= 56, (white_flagged, correlated_seen)
    # the reference: even spacing, pure noise
    obs = grid_observations(n_steps=3, per_step=30)
    obs.value = np.random.default_rng(1).normal(0.0, sd, len(obs.time))
    for s, name in enumerate(("lean", "steer", "pitch_left", "pitch_right")):
        want = np.concatenate([np.diff(obs.value[(obs.signal == s) & (obs.step == k)], 4) for k in range(3)])
        assert_allclose(scatter_noise(obs)[name]["sd"], np.sqrt(np.mean(want**2) / 70.0), rtol=1e-9)


def test_features_of_a_walk_with_few_samples_a_step():
    """A walker taking 0.18 s a step filmed at 60 frames/s gives 11 samples a step: the curve's
    degree drops (to 5) so that every step still has its ranges, measured and model smoothed
    alike (a sine's range within 1 %: the degree-5 curve through 11 samples), and the left-right
    difference of a walk whose right steps were not seen is NaN, quietly (warnings are errors
    here)."""
    obs = grid_observations(n_steps=12, per_step=11)
    amp = 0.05
    measured = amp * np.sin(2 * np.pi * obs.phase) * (obs.signal == 0)
    f = step_features(obs, measured)
    assert np.all(np.isfinite(f["lean_range"])) and np.all(np.isfinite(f["swing_pitch_range"]))
    assert_allclose(f["lean_range"], 2 * amp, rtol=0.01)
    noisy = measured + np.random.default_rng(5).normal(0.0, 0.002, measured.shape)
    misfit = feature_misfit(obs, noisy, 0.9 * measured, sigma=np.full(len(noisy), 0.002), rng=6)
    assert misfit["lean_range"]["z"] > 5
    assert np.isnan(step_features(grid_observations(n_steps=2, per_step=4), np.zeros(32))["lean_range"]).all()
    right_unseen = np.where(obs.stance[obs.step] == "R", np.nan, measured)
    assert np.isnan(feature_misfit(obs, right_unseen, 0.9 * measured)
                    ["lean_range_right_minus_left"]["difference"])


def test_step_dependence_tells_a_walk_off_its_cycle_from_a_misfit():
    """residuals.step_dependence on 12 steps of 17 samples a signal (a 12-step walk of the stable
    toy at 160 samples/s), 2 mrad white noise. A misfit repeated every step, however large (here
    up to 50 noise SDs, a different pattern per foot), does not count: its p-values are uniform,
    as the F test of nested linear models with Gaussian noise makes them. Over 200 draws the rate
    below 0.05 was measured 0.035; asserted within 0.02-0.09 (3 binomial SDs of 0.015). A walk
    off its cycle, its departure decaying by 0.9 a step from 5 noise SDs (a 2 % lean-rate kick
    gave F = 10.8 on a simulated walk), is found in every draw (measured p at most 5e-29)."""
    from toywalk.sysid.residuals import step_dependence

    sd = 0.002
    obs = grid_observations(n_steps=12, per_step=17)
    foot = np.where(obs.stance[obs.step] == "L", 1.0, -0.6)
    misfit = 50 * sd * foot * np.sin(2 * np.pi * obs.phase + obs.signal) * np.exp(-obs.phase)
    departure = 5 * sd * 0.9 ** obs.step * np.cos(np.pi * obs.phase + obs.signal)
    rng = np.random.default_rng(11)
    p_misfit, p_off = [], []
    for _ in range(200):
        noise = rng.normal(0.0, sd, len(obs.time))
        p_misfit.append(step_dependence(obs, misfit + noise)["p"])
        if len(p_off) < 20:
            p_off.append(step_dependence(obs, misfit + departure + noise)["p"])
    rate = np.mean(np.array(p_misfit) < 0.05)
    assert 0.02 <= rate <= 0.09, rate
    assert max(p_off) < 1e-6, max(p_off)
    # the degrees of freedom: per signal and foot, 6 steps of 3 own coefficients less the 3 the
    # common curve already has (15), over 4 signals and 2 feet; the rest of the 816 samples
    r = step_dependence(obs, misfit + noise)
    assert r["dfn"] == 4 * 2 * 15 and r["dfd"] == 816 - 4 * 2 * (9 + 15)
    # too few samples a step for the curves: no test (NaN), which leaves the choice to the
    # likelihood ratio (toywalk.sysid.fit.periodicity_test)
    short = grid_observations(n_steps=2, per_step=5)
    assert np.isnan(step_dependence(short, np.zeros(len(short.time)))["p"])


def test_the_tests_tails_are_scipy_stats_ones():
    """The p-values and densities come from scipy.special (scipy.stats takes a second to import in
    every process): each equals scipy.stats' own, the reference, where it is used."""
    from scipy import stats
    from toywalk.sysid.discrepancy import _normal_log_density, lr_p_value
    from toywalk.sysid.residuals import _ljung_box, _pattern, _runs
    from toywalk.tracking.angles import _chi_median

    rng = np.random.default_rng(5)
    x = rng.normal(size=(7, 5)) + np.linspace(0, 1, 5)  # steps by bins, with a pattern
    f, eps, p = _pattern(x)
    n, k = x.shape
    assert_allclose(p, stats.f.sf(f, eps * (k - 1), eps * (n - 1) * (k - 1)), rtol=1e-12)
    series = rng.normal(size=40)
    q, p = _ljung_box(series, 5)
    assert_allclose(p, stats.chi2.sf(q, 5), rtol=1e-12)
    z, p = _runs(series)
    assert_allclose(p, stats.norm.cdf(z), rtol=1e-12)
    for lr in (0.0, 0.5, 3.84, 40.0):
        assert_allclose(lr_p_value(lr, False), stats.chi2.sf(lr, 1), rtol=1e-12)
        assert_allclose(lr_p_value(lr, True), 0.5 * stats.chi2.sf(lr, 1), rtol=1e-12)
    assert_allclose(_normal_log_density(0.3, -0.1, 0.2), stats.norm.logpdf(0.3, -0.1, 0.2), rtol=1e-13)
    for dof in (1, 2.5, 9, 120):
        assert_allclose(_chi_median(dof), stats.chi.median(dof), rtol=1e-12)


def test_the_commands_do_not_load_scipy_stats():
    """Every toywalk command would pay scipy.stats' import (about a second) for a handful of
    tail probabilities that scipy.special gives: the analysis and tracking modules do without."""
    code = ("import toywalk.sysid.cli, toywalk.sysid.fit, toywalk.sysid.discrepancy, "
            "toywalk.sysid.summary, toywalk.sysid.walks, toywalk.sysid.commands.diagnose, "
            "toywalk.sysid.commands.fit, toywalk.tracking.track")
    assert loaded_by(code, "scipy.stats") == {"scipy.stats": False}
