"""The continuity smoother of a leg's pitch (`toywalk.tracking.angles.motion_smoothed`, issue 14):
against a slow, obvious reference (the Gaussian posterior of all states at once), and on a
known synthetic signal with kinks at heel strikes."""

import math

import numpy as np
import pytest
from scipy.integrate import quad_vec
from toywalk.tracking import angles
from toywalk.tracking.angles import motion_smoothed


def _transition(dt):
    return np.array([[1.0, dt, dt * dt / 2], [0.0, 1.0, dt], [0.0, 0.0, 1.0]])


def _process(dt):
    """White unit jerk over dt, by quadrature of F(s) e3 e3^T F(s)^T (not the closed form)."""
    return quad_vec(lambda s: np.outer(_transition(s)[:, 2], _transition(s)[:, 2]), 0.0, dt)[0]


def _posterior(time, y, sd, strikes, density):
    """Posterior mean and SD of the angle at the sample times, from one linear least-squares
    problem over the states at every sample and every strike (a strike is a node of its own
    where rate and acceleration receive their free variance)."""
    nodes = sorted([(t, "sample", i) for i, t in enumerate(time)] + [(t, "strike", -1) for t in strikes])
    m = len(nodes)
    info = np.zeros((3 * m, 3 * m))
    vec = np.zeros(3 * m)
    prior = np.diag([1.0, angles._FREE_RATE**2, angles._FREE_ACCELERATION**2])
    first = y[np.flatnonzero(np.isfinite(y))[0]]
    info[:3, :3] += np.linalg.inv(prior)
    vec[:3] += np.linalg.inv(prior) @ np.array([first, 0.0, 0.0])
    free = np.diag([0.0, angles._FREE_RATE**2, angles._FREE_ACCELERATION**2])
    for j in range(1, m):
        dt = nodes[j][0] - nodes[j - 1][0]
        f = _transition(dt)
        cov = density * _process(dt)
        if nodes[j - 1][1] == "strike":
            cov = cov + f @ free @ f.T
        w = np.linalg.inv(cov)
        a = np.zeros((3, 3 * m))  # x_j - F x_{j-1}
        a[:, 3 * j:3 * j + 3] = np.eye(3)
        a[:, 3 * j - 3:3 * j] = -f
        info += a.T @ w @ a
    rows = []
    for j, (_, kind, i) in enumerate(nodes):
        if kind == "sample":
            rows.append(j)
            if np.isfinite(y[i]):
                info[3 * j, 3 * j] += 1 / sd[i] ** 2
                vec[3 * j] += y[i] / sd[i] ** 2
    cov = np.linalg.inv(info)
    mean = cov @ vec
    idx = [3 * j for j in rows]
    return mean[idx], np.sqrt(np.diag(cov)[idx])


def test_smoother_is_the_gaussian_posterior():
    rng = np.random.default_rng(3)
    time = np.cumsum(rng.uniform(0.012, 0.02, 30))  # uneven frame times (s)
    y = 0.3 * np.sin(9 * time) + 0.002 * rng.standard_normal(30)
    sd = rng.uniform(0.001, 0.004, 30)
    y[[7, 8, 20]] = np.nan  # gaps
    strikes = [time[12] + 0.004, time[25] + 0.01]
    for density in (1e2, 1e5):
        mean, msd, used = motion_smoothed(time, y, sd, strikes, density=density)
        ref_mean, ref_sd = _posterior(time, y, sd, strikes, density)
        assert used == density
        # one linear-Gaussian problem solved two ways: they agree to rounding. The batch
        # problem's information matrix spans the diffuse prior's 1e-7 (1 / (3e3 rad/s^2)^2) to
        # the samples' 1e6 rad^-2, so its inverse loses about 13 of 16 digits: 1e-8 rad is
        # 1e-5 of a sample's SD (measured 4e-9 rad, SDs 1e-7 relative)
        np.testing.assert_allclose(mean, ref_mean, rtol=0, atol=1e-8)
        np.testing.assert_allclose(msd, ref_sd, rtol=1e-6)


def _kinked_walk(rng, n=240, fps=60.0):
    """A leg-like pitch (rad): over each step (22 frames, as the toy's) a ramp of 0.6 rad with a
    0.2 rad bow and a 0.05 rad wobble (so not a quadratic), alternating in direction: continuous
    at each strike, its rate jumping there (by about 2 x 0.6 rad over a step's 0.37 s). Sampled
    with SDs from 0.05 to 0.5 degree."""
    step = 22 / fps
    time = np.arange(n) / fps
    strikes = np.arange(0.2, time[-1], step)
    y = np.zeros(n)
    for k, t in enumerate(time):
        done = int(np.sum(strikes <= t))
        t0 = strikes[done - 1] if done else strikes[0] - step
        s = (t - t0) / step
        y[k] = 0.3 * (-1) ** done * (2 * s - 1) + 0.2 * s * (1 - s) + 0.05 * math.sin(3 * math.pi * s)
    sd = np.radians(rng.uniform(0.05, 0.5, n))
    return time, y, y + sd * rng.standard_normal(n), sd, strikes


def test_smoother_recovers_a_kinked_signal_with_honest_sds():
    rng = np.random.default_rng(1)
    time, truth, y, sd, strikes = _kinked_walk(rng)
    mean, msd, density = motion_smoothed(time, y, sd, strikes)
    err, raw = mean - truth, y - truth
    # the neighbours' samples help: at least 1.5 times smaller errors (measured 2.44 here, 2.1-2.4
    # over seeds 1-6)
    assert np.sqrt(np.mean(err**2)) < np.sqrt(np.mean(raw**2)) / 1.5
    # honest SDs: RMS of error over SD 1 +- 3/sqrt(2 n_eff), the errors of neighbouring samples
    # correlated (they share samples): n_eff taken as n / 4 = 60, a bound of 1 +- 0.27 (measured
    # 0.77 here, 0.77-0.98 over seeds 1-6)
    z = np.sqrt(np.mean((err / msd) ** 2))
    assert 1 - 0.27 < z < 1 + 0.27, z
    # the strikes matter: told none, the model must bend at the kinks and its fitted jerk
    # density is far larger (measured 10-30 times over seeds 1-6; 3 times is the bound)
    _, _, density_blind = motion_smoothed(time, y, sd, ())
    assert density_blind > 3 * density


def test_smoother_refuses_bad_input():
    t = np.arange(10) / 60
    with pytest.raises(ValueError, match="one length"):
        motion_smoothed(t, np.zeros(9), np.ones(9))
    with pytest.raises(ValueError, match="increase"):
        motion_smoothed(t[::-1], np.zeros(10), np.ones(10))
    with pytest.raises(ValueError, match="at least 4"):
        motion_smoothed(t, np.full(10, np.nan), np.ones(10))
