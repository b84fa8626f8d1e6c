"""Stride length as data: heel-strike contact positions in the fit and the posterior."""

import numpy as np
import pytest
from toywalk.model.parameters import load_params
from toywalk.model.simulate import simulate
from toywalk.model.trajectory import TrajectoryTable, read_trajectory, write_trajectory
from toywalk.sysid.fit import fit
from toywalk.sysid.measurement import MeasurementError, observations
from toywalk.sysid.sample import posterior_from_fit

from ..conftest import DATA
from .builders import RECOVERED, simulated_walk, start_off

#: Contact-position noise (m): a fifth of a millimetre, a tracker's error on a toy filmed whole.
POSITION_SD = 2e-4


def _located(truth, steps, noise, position_sd, seed):
    """A simulated walk with its heel strikes' contact positions (noise ``position_sd``, m, and
    that SD in the events file; exact without noise), from the strike the walk starts with."""
    table, gait = simulated_walk(truth, steps, noise, seed)
    traj = simulate(truth, gait.fixed_point, steps)
    rng = np.random.default_rng(seed + 1000)
    strikes = [(0.0, "L", 0.0, 0.0)] + [(e.time, e.foot, e.x, e.y) for e in traj.events]
    events = []
    for time, foot, x, y in strikes:
        event = {"time": time, "foot": foot, "x": x, "y": y}
        if position_sd:
            event.update(x=x + rng.normal(0.0, position_sd), y=y + rng.normal(0.0, position_sd),
                         x_sd=position_sd, y_sd=position_sd)
        events.append(event)
    return TrajectoryTable(table.time, table.signals, table.stance, events, {}), table


@pytest.fixture(scope="module")
def truth():
    return load_params(DATA / "params" / "stable-toy.toml").replace(
        **{"effects.impact_trailing_share": 0.1})


def test_exact_contacts_are_reproduced(truth, tmp_path):
    """At the true parameters, the model's contacts (each step's advance, mirrored back for a
    right-stance step, summed from the first strike) are the simulated walk's: a sign or
    mirroring error would miss by the 36 mm step width. The positions survive the file."""
    table, _ = _located(truth, 6, 0.0, 0.0, 0)
    write_trajectory(table, tmp_path / "walk.csv")
    back = read_trajectory(tmp_path / "walk.csv")
    assert [e["x"] for e in back.events] == [e["x"] for e in table.events]
    noise = {"lean": 1e-3, "steer": 1e-3, "pitch_left": 1e-3, "pitch_right": 1e-3,
             "contact_x": POSITION_SD, "contact_y": POSITION_SD}
    result = fit(back, truth, ["foot_radius"], noise_sd=noise, check_jacobian=False)
    assert result.success, result.status
    assert result.contact_source == "given"
    # Collocation (30, 4) against RK8 steps: 5e-13 m a step (tests/model/test_contact_travel.py),
    # over 6 steps; the fit at the truth leaves only that, plus the angles' interpolation.
    assert result.residual_rms["contact_x"] < 1e-8
    assert result.residual_rms["contact_y"] < 1e-8
    assert abs(result.estimates["origin_x"]) < 1e-8 and abs(result.estimates["origin_y"]) < 1e-8
    ys = np.array([e["y"] for e in table.events])
    assert np.ptp(ys) > 0.03  # the step width the check would catch


def test_bad_positions_are_refused(truth):
    table, _ = _located(truth, 3, 0.0, POSITION_SD, 0)
    table.events[1]["x_sd"] = -1.0
    with pytest.raises(MeasurementError, match="x_sd, y_sd"):
        observations(table)
    table.events[1]["x_sd"], table.events[2]["y"] = POSITION_SD, np.inf
    with pytest.raises(MeasurementError, match="finite or empty"):
        observations(table)


@pytest.fixture(scope="module")
def both(truth):
    """The recovery walk of tests/sysid/test_fit.py (12 steps, 0.002 rad, seed 1), fitted from
    its angles and strikes alone and with its contact positions."""
    located, angles_only = _located(truth, 12, 0.002, POSITION_SD, 1)
    start = start_off(truth)
    return located, fit(located, start, RECOVERED), fit(angles_only, start, RECOVERED)


def test_contact_positions_sharpen_the_fit(truth, both):
    """With the strides as data the three parameters are recovered within three SE and more
    precisely: the foot radius and the trailing-foot share set the step's advance (measured on
    this walk: SE 5.9e-5 to 4.5e-5 m and 1.37e-3 to 0.95e-3)."""
    _, with_contacts, without = both
    assert with_contacts.success and without.success
    for name in RECOVERED:
        err = with_contacts.estimates[name] - truth.get(name)
        assert abs(err) < 3 * with_contacts.std[name], (name, err, with_contacts.std[name])
    for name in ("foot_radius", "effects.impact_trailing_share"):
        # The information only grows with data; 10 % is half the gain measured, so the check
        # fails if the positions stopped informing the parameters.
        assert with_contacts.std[name] < 0.9 * without.std[name], name
    assert with_contacts.contact_source == "file"
    assert "contact_x" not in without.residual_rms
    for key in ("contact_x", "contact_y"):
        # 13 positions less two nuisances a coordinate: the RMS over the SD has a spread of
        # about 0.2; 0.5 to 1.4 is 2.5 of those either way.
        assert 0.5 < with_contacts.residual_rms[key] / POSITION_SD < 1.4, key
    # AD through the lifted displacements against re-solved central differences.
    assert max(with_contacts.jacobian_check.values()) < 1e-6
    assert {"origin_x", "origin_y"} <= set(with_contacts.names)


def test_posterior_reads_the_same_contacts(both):
    """The posterior (shooting, nuisances profiled) at the fit's estimates gives the fit's
    chi-square (collocation): measured 868.095 against 868.073."""
    located, result, _ = both
    post, estimates, _ = posterior_from_fit(result.to_json(), located)
    log_prob, _, status = post(estimates)
    # The shooting curves' Hermite interpolation (1e-5 rad, 0.5 % of the noise) moves chi-square
    # by a few hundredths over ~900 residuals; a dropped contact term would move it by about 20
    # (its 26 residuals).
    assert status == 0
    assert abs(-2 * log_prob - result.chi2) < 0.2
