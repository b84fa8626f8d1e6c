"""Errors shared by phase (a tracker's bias that repeats in every step) in the fit's standard
errors: the sandwich covariance of :func:`toywalk.sysid.problem.shared_covariance` against the spread
of least-squares estimates over draws of such errors, the cells of
:func:`toywalk.sysid.residuals.shared_errors`, and a fit of a file with ``*_phase_sd`` columns.

Through video on compass-3d the fit of the tracked angles put a collision's trailing share 2.5
standard errors from the truth in every seed (docs/diagnosis.md, "Through video"): the errors the
tracker repeats at each phase of every step do not average away over the steps, and an interval
that takes every sample's error as its own is too narrow.
"""

import numpy as np
import pytest
import scipy.sparse as sp
from toywalk.model.parameters import load_params
from toywalk.model.simulate import gait_walk
from toywalk.model.trajectory import TrajectoryTable
from toywalk.sysid.fit import fit, score_statistics, shared_covariance
from toywalk.sysid.measurement import observations
from toywalk.sysid.problem import whitened_loads
from toywalk.sysid.residuals import shared_errors

from ..conftest import DATA


def _linear_case(rng, steps=24, per_step=20, bins=5):
    """A straight-line model of the phase with a step-to-step drift, its samples' SDs (white
    1, shared 0.8 by phase bin) and the shared errors' loadings."""
    phase = np.tile((np.arange(per_step) + 0.5) / per_step, steps)
    step = np.repeat(np.arange(steps), per_step)
    design = np.c_[np.ones_like(phase), phase, np.sin(2 * np.pi * phase), step / steps]
    cell = np.minimum((phase * bins).astype(int), bins - 1)
    shared = np.full(len(phase), 0.8)
    loads = sp.csr_matrix((shared, (np.arange(len(phase)), cell)), shape=(len(phase), bins))
    sigma = np.sqrt(1.0 + shared**2)
    return design, sigma, loads


def test_sandwich_matches_the_spread_of_estimates():
    """Least squares on the whitened data, 4000 draws of white and shared errors: the estimates'
    covariance against the sandwich. 4000 draws give each variance to 2.2 % (sqrt(2/4000)), so
    15 % is about 6 of those; the Gauss-Newton covariance alone is short by a factor of 2 or
    more for the intercept and slope (what the test would see without the shared term)."""
    rng = np.random.default_rng(3)
    design, sigma, loads = _linear_case(rng)
    jac = design / sigma[:, None]
    cov = np.linalg.inv(jac.T @ jac)
    draws = 4000
    white = rng.standard_normal((draws, len(sigma)))
    common = rng.standard_normal((draws, loads.shape[1])) @ loads.T.toarray()
    data = (white + common) / sigma
    estimates = data @ jac @ cov
    empirical = np.cov(estimates.T)
    sandwich = shared_covariance(cov, jac, sigma, loads)
    np.testing.assert_allclose(np.diag(sandwich), np.diag(empirical), rtol=0.15)
    assert np.all(np.diag(sandwich)[:2] > 2.0 * np.diag(cov)[:2])
    # nothing shared: the Gauss-Newton covariance itself
    none = sp.csr_matrix(loads.shape)
    np.testing.assert_allclose(shared_covariance(cov, jac, sigma, none), cov, rtol=1e-10, atol=1e-14)


def test_rows_beyond_the_angles_stay_independent():
    """A prior's or a strike time's row is no angle: the sandwich treats it as before, so adding
    one changes the covariance exactly as the Gauss-Newton one's inverse says."""
    rng = np.random.default_rng(4)
    design, sigma, loads = _linear_case(rng)
    jac = np.vstack([design / sigma[:, None], [[0.0, 0.0, 0.0, 5.0]]])
    cov = np.linalg.inv(jac.T @ jac)
    dense = loads.toarray() / sigma[:, None]
    omega = np.eye(len(jac))
    omega[:len(sigma), :len(sigma)] = np.diag(1.0 - np.sum(dense**2, axis=1)) + dense @ dense.T
    gain = cov @ jac.T
    np.testing.assert_allclose(shared_covariance(cov, jac, sigma, loads), gain @ omega @ gain.T, rtol=1e-10,
                               atol=1e-14)


def test_score_tests_hold_their_size_with_shared_errors():
    """A held column that lives at one phase of the step (a bump at 0.65, as a tracker's bias
    where the legs pass) under white and shared errors, nothing held wrong: 4000 draws of the
    score z. With the design effect its variance is 1 (measured 0.997; 4000 draws give it to
    2.2 %, 10 % allowed) and 1 % of the draws pass |z| > 2.58 (measured 1.05 %); taking every
    error as its own (``shared`` left out) the variance is the design effect, 14, and half the
    draws are false alarms: what the walks with nothing hidden showed through video
    (docs/diagnosis.md, "Through video")."""
    rng = np.random.default_rng(7)
    design, sigma, loads = _linear_case(rng)
    bump = np.exp(-(((design[:, 1] - 0.65) / 0.08) ** 2))
    jac = np.column_stack([design, bump]) / sigma[:, None]
    jac = np.vstack([jac, np.zeros((1, jac.shape[1]))])  # a row that shares nothing (a prior's)
    q = whitened_loads(loads, sigma, rows=len(jac))
    draws = 4000
    white = rng.standard_normal((draws, len(sigma)))
    common = rng.standard_normal((draws, loads.shape[1])) @ loads.T.toarray()
    data = np.hstack([(white + common) / sigma, rng.standard_normal((draws, 1))])
    z = np.array([score_statistics(jac, r, [4], q)[0]["z"] for r in data])
    z_plain = np.array([score_statistics(jac, r, [4])[0]["z"] for r in data])
    assert 0.9 < np.var(z) < 1.1 and np.mean(np.abs(z) > 2.58) < 0.02
    assert np.var(z_plain) > 5.0 and np.mean(np.abs(z_plain) > 2.58) > 0.3
    assert score_statistics(jac, data[0], [4], q)[0]["inflation"] == pytest.approx(np.var(z_plain), rel=0.1)


@pytest.fixture(scope="module")
def walk():
    """Eight steps of the stable toy, angles and heel strikes only: with the strikes' contact
    positions the step length pins the foot radius (standard error 9e-6 m against 1.4e-4 m
    without), and the angles' errors hardly reach it."""
    params = load_params(DATA / "params" / "stable-toy.toml")
    table = gait_walk(params, 8, noise=0.002, seed=5)
    signals = {k: v for k, v in table.signals.items() if not k.startswith("contact")}
    events = [{k: v for k, v in e.items() if k not in ("x", "y", "x_sd", "y_sd")} for e in table.events]
    return params, TrajectoryTable(table.time, signals, table.stance, events, table.metadata)


def _with_shared(table, size, shared=True):
    """The table with ``size`` (rad) in each sample's SD, shared by phase or (``shared`` False)
    the sample's own."""
    signals = dict(table.signals)
    for name in ("lean", "steer", "pitch_left", "pitch_right"):
        signals[f"{name}_phase_sd"] = np.full(len(table.time), size if shared else 0.0)
        signals[f"{name}_sd"] = np.hypot(signals[f"{name}_sd"], size)
    return TrajectoryTable(table.time, signals, table.stance, table.events, table.metadata)


def test_cells_are_signal_foot_and_phase(walk):
    """A sample shares its error with the samples of its signal, stance foot and phase bin, and
    with no other."""
    _, table = walk
    obs = observations(_with_shared(table, 0.001))
    loads = shared_errors(obs, bins=4)
    cell = loads.indices
    assert loads.nnz == len(obs.value) and np.allclose(loads.data, 0.001)
    foot = obs.stance[obs.step]
    b = np.minimum((obs.phase * 4).astype(int), 3)
    i, j = np.triu_indices(len(cell), 1)
    same = cell[i] == cell[j]
    expect = (obs.signal[i] == obs.signal[j]) & (foot[i] == foot[j]) & (b[i] == b[j])
    assert np.array_equal(same, expect)


def test_a_files_phase_sd_widens_the_fits_standard_errors(walk):
    """The same walk with 1 mrad more in every sample's SD, its own or shared by phase: the
    estimates are the same, the standard errors grow with the shared one, and the fit says by
    how much."""
    params, table = walk
    free = ["foot_radius", "com_offset[1]"]
    plain = fit(_with_shared(table, 0.001, shared=False), params, free, check_jacobian=False)
    shared = fit(_with_shared(table, 0.001), params, free, check_jacobian=False)
    assert not plain.shared_widening
    for name in free:
        assert shared.estimates[name] == pytest.approx(plain.estimates[name], rel=1e-9)
        assert shared.std[name] > 1.2 * plain.std[name]
        assert shared.shared_widening[name] > 1.2


def test_the_report_says_the_intervals_hold_the_shared_errors():
    """report.md's base-model paragraph names the widening of the base's and the candidates'
    standard errors where the file carries errors shared by phase, and says nothing without."""
    from types import SimpleNamespace

    from toywalk.sysid.diagnosis_report import _shared_words

    base = SimpleNamespace(shared_widening={"foot_radius": 1.41})
    rows = [{"effect": "effects.impact_trailing_share", "shared_widening": 2.06}, {"effect": "slope"}]
    words = _shared_words(SimpleNamespace(base=base, ranking=rows))
    assert "*_phase_sd" in words and "foot_radius x1.4" in words and "impact_trailing_share x2.1" in words
    plain = SimpleNamespace(base=SimpleNamespace(shared_widening={}), ranking=[{"effect": "slope"}])
    assert _shared_words(plain) == ""
