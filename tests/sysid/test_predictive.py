"""Posterior predictive checks (sysid.sample_report.predictive_checks) on a model whose truth is
known: a walk the model can produce passes them, one with a pattern the model lacks fails them."""

import numpy as np
from toywalk.sysid.sample_report import CHECKED_FEATURES, MISFIT_SDS, misfit_notes, predictive_checks

from .builders import grid_observations, walk_signals

SD = 0.002


class _Posterior:
    """A stand-in for sysid.likelihood.LogPosterior: the 'model' is ``walk_signals`` without
    noise scaled by ``theta[0]``; a draw below 0.5 has no gait."""

    def __init__(self, obs):
        self.obs, self.sigma = obs, np.full(len(obs.value), SD)
        self.shape = walk_signals(obs, np.zeros(len(obs.value)))

    def gait(self, theta):
        return (None, None) if theta[0] < 0.5 else (float(theta[0]), None)

    def profile(self, gait, walker):
        return 0.0, 0.0, gait * self.shape


def _draws(rng, n=200):
    return np.c_[1.0 + 0.002 * rng.standard_normal(n)]  # a posterior 0.2 % wide about the truth


def test_a_walk_the_model_makes_passes_and_a_pattern_it_lacks_fails():
    """12 steps of 14 samples, 2 mrad noise, 40 draws a check.

    The model's own walk, 10 seeds (60 p-values): with 40 draws a p-value is 0 when the measured
    statistic lies beyond every replicate, 2/41 = 5 % of the time for a two-sided one on pure
    chance. Measured over 100 seeds: 2.5 % of p-values are 0, the statistics' mean p 0.44 to
    0.57. Here at most 6 zeros (expected 1.5) and a mean p within 0.35 to 0.65 (its SD over 60
    is about 0.04).

    The same walks with the steer swinging 5 % wider than the model's (measured over 30 seeds:
    chi-square p 0 in all, the steer range's p at most 0.1, median 0): chi-square p = 0 and the
    steer range's at most 0.1 in each of 5 seeds. A draw with no gait is skipped."""
    obs = grid_observations(n_steps=12, per_step=14)
    post = _Posterior(obs)
    ps = []
    for seed in range(10):
        rng = np.random.default_rng(seed)
        obs.value = post.shape + rng.normal(0.0, SD, len(obs.value))
        result = predictive_checks(post, _draws(rng), rng)
        assert result["draws"] == 40 and set(result["checks"]) == {"chi2", *CHECKED_FEATURES}
        ps += [c["p"] for c in result["checks"].values()]
        assert np.all(result["low"] <= result["high"])
    ps = np.array(ps)
    assert np.sum(ps == 0) <= 6 and 0.35 < ps.mean() < 0.65, ps
    steer = obs.signal == 1
    for seed in range(5):
        rng = np.random.default_rng(seed)
        obs.value = post.shape + rng.normal(0.0, SD, len(obs.value))
        obs.value[steer] += 0.05 * post.shape[steer]
        checks = predictive_checks(post, _draws(rng), rng)["checks"]
        assert checks["chi2"]["p"] == 0.0, (seed, checks["chi2"]["p"])
        assert checks["steer_range"]["p"] <= 0.1, (seed, checks["steer_range"]["p"])
    draws = _draws(rng)
    draws[::2] = 0.1
    assert predictive_checks(post, draws, rng)["draws"] < 40


def test_misfit_notes_name_failing_checks_and_the_fits_warnings():
    """misfit_notes: nothing for a walk the model makes, one line naming the failing checks for a
    pattern it lacks, and a line per warning of the fit.

    A check fails beyond MISFIT_SDS = 4 SDs of its replicates. Measured over 100 seeds of the
    model's own walk (600 checks): the largest distance 3.3 SDs, no note; here 6 seeds. The steer
    5 % wider, over 30 seeds: chi-square 9.9 to 19.3 SDs off (a note in each), the steer range 2.2
    to 7.8 (named in 19); here 3 seeds, each naming chi-square, and the steer range (7.3) at
    seed 0."""
    assert MISFIT_SDS == 4.0
    obs = grid_observations(n_steps=12, per_step=14)
    post = _Posterior(obs)
    for seed in range(6):
        rng = np.random.default_rng(seed)
        obs.value = post.shape + rng.normal(0.0, SD, len(obs.value))
        assert misfit_notes((), predictive_checks(post, _draws(rng), rng)) == [], seed
    steer = obs.signal == 1
    for seed in range(3):
        rng = np.random.default_rng(seed)
        obs.value = post.shape + rng.normal(0.0, SD, len(obs.value))
        obs.value[steer] += 0.05 * post.shape[steer]
        notes = misfit_notes((), predictive_checks(post, _draws(rng), rng))
        assert len(notes) == 1 and notes[0].startswith("posterior predictive checks fail"), notes
        assert "chi-square +" in notes[0] and (seed or "steer_range +7.26" in notes[0]), notes
    notes = misfit_notes(["the residual RMS is many times the noise SDs stated"], None)
    assert notes == ["the fit it starts from warns: the residual RMS is many times the noise SDs stated"]
