"""Samples taken with the shutter open (toywalk.sysid.measurement.shutter_reads): each is the
angles' mean over the exposure, read by Simpson's rule; checked against an analytic mean, against
a slow box average of a finely sampled simulation, and by the bias it removes from a fit."""

import numpy as np
import pytest
from numpy.testing import assert_allclose
from toywalk.model.collocation import bvp, initial_guess
from toywalk.model.gait import find_gait
from toywalk.model.parameters import load_params
from toywalk.model.simulate import simulate
from toywalk.model.trajectory import TrajectoryTable
from toywalk.model.walker import Walker
from toywalk.sysid.fit import fit
from toywalk.sysid.likelihood import model_angles
from toywalk.sysid.measurement import MeasurementError, observations, operator, shutter_reads

from ..conftest import DATA

FPS = 60.0  # frames/s, the renderer's default
EXPOSURE = 0.4 / FPS  # s: the renderer's level-1 shutter, 0.4 of a frame interval
STRENGTH = 2e-4  # N m s/rad: rolling resistance, the library's typical strength
SD = 0.0013  # rad: a tracked angle's SD on rendered video at level 1 (benchmarks/TRACKING.md)


@pytest.fixture(scope="module")
def walk():
    """12 steps of the stable toy with rolling resistance, filmed at 60 frames/s with the shutter
    open 0.4 of a frame: each frame's angles are the box mean over its exposure of a simulation
    sampled at 24 kHz (trapezoids on 401 points a frame, linear between samples: error under
    1e-6 rad where the legs' angular accelerations reach 1e3 rad/s^2). Noise-free, with the SDs of
    tracked video stated, so that a fit's error is its bias and its SE is a tracked walk's."""
    params = load_params(DATA / "params" / "stable-toy.toml").replace(
        **{"effects.rolling_resistance": STRENGTH})
    gait = find_gait(params)
    traj = simulate(params, gait.fixed_point, 12, sample_rate=24000.0, steps_per_time_unit=64)
    left, right = traj.pitches()
    dense = {"lean": traj.lean, "steer": traj.steer, "pitch_left": left, "pitch_right": right}
    frames = np.arange(EXPOSURE, traj.times[-1] - EXPOSURE, 1.0 / FPS)
    u = np.linspace(-0.5, 0.5, 401) * EXPOSURE

    def mean(y, t):
        return np.trapezoid(np.interp(t + u, traj.times, y), u) / EXPOSURE

    signals = {k: np.array([mean(v, t) for t in frames]) for k, v in dense.items()}
    signals.update({f"{k}_sd": np.full(len(frames), SD) for k in dense})
    at_t = {k: np.interp(frames, traj.times, v) for k, v in dense.items()}
    stance = np.array(traj.stance)[np.searchsorted(traj.times, frames)]
    events = [{"time": 0.0, "foot": "L"}] + [{"time": e.time, "foot": e.foot} for e in traj.events]
    table = TrajectoryTable(frames, signals, stance, events, {"exposure_s": EXPOSURE})
    return params, gait, table, at_t


def test_simpson_reads_give_the_mean_over_the_shutter():
    """An angle sin(w t) has the mean sin(w t) sinc over a centred shutter of length e; Simpson's
    three reads give it to (w e)^4 / 2880 of the amplitude (w = 60 rad/s, e = 6.7 ms: 6e-6). A
    read past a heel strike lies in the next step, with that step's stance leg."""
    strikes = np.array([0.0, 0.1, 0.2, 0.3])
    t = np.arange(0.015, 0.3, 1 / FPS)  # frame 5 at 0.0983 s, 1.7 ms before a strike
    feet = ["L", "R", "L", "R"]
    events = [{"time": s, "foot": f} for s, f in zip(strikes, feet, strict=True)]
    table = TrajectoryTable(t, {k: np.zeros(len(t)) for k in ("lean", "steer", "pitch_left", "pitch_right")},
                            np.array(["L"] * len(t)), events, {"exposure_s": EXPOSURE})
    obs = observations(table)
    reads, average = shutter_reads(obs)
    assert average.shape[0] == len(obs.value) and average.shape[1] >= 3 * len(obs.value)
    omega = 60.0
    exact = np.sin(omega * obs.time) * np.sin(omega * EXPOSURE / 2) / (omega * EXPOSURE / 2)
    inside = (obs.time - EXPOSURE / 2 >= strikes[0]) & (obs.time + EXPOSURE / 2 <= strikes[-1])
    assert inside.sum() == len(inside) - 4  # the last frame's shutter closes after the walk's end
    assert_allclose((average @ np.sin(omega * reads.time))[inside], exact[inside],
                    atol=(omega * EXPOSURE) ** 4 / 2880)
    assert_allclose(np.asarray(average.sum(axis=1)).ravel(), 1.0, rtol=1e-12)  # a mean
    # the frame 1.7 ms before the strike at 0.1 s: its shutter is split there, six reads, three in
    # step 0 up to the strike and three in step 1 (the right leg in stance) from it
    i = int(np.argmin(np.abs(obs.time - 0.0983)))
    cols = average[i].indices
    assert obs.step[i] == 0 and len(cols) == 6 and obs.stance[1] == "R"
    assert sorted(reads.step[cols]) == [0, 0, 0, 1, 1, 1]
    assert_allclose(reads.time[cols].max(), obs.time[i] + EXPOSURE / 2)
    before, after = cols[reads.step[cols] == 0], cols[reads.step[cols] == 1]
    assert reads.phase[before].max() == 1.0 and reads.phase[after].min() == 0.0
    # instantaneous samples: the samples themselves
    table.metadata["exposure_s"] = 0.0
    assert shutter_reads(observations(table))[1] is None
    for bad in (-1e-3, 1.0, "1/150", True):
        table.metadata["exposure_s"] = bad
        with pytest.raises(MeasurementError, match="exposure_s"):
            observations(table)


def test_the_operator_reads_the_mean_over_the_shutter(walk):
    """The collocation gait read by the measurement operator with the shutter equals the slow box
    mean of the finely sampled simulation (two integrations, two ways of averaging; measured
    5.1e-6 rad at most, Simpson's error where the legs' angular jerk is largest: a tolerance of
    1e-5 rad, under 1 % of a tracked angle's SD), and the emcee likelihood's reading of the shot
    gait agrees too. Read at t instead, the model misses the frames by the few mrad the shutter
    makes (the check can fail)."""
    params, gait, table, at_t = walk
    obs = observations(table)
    prob = bvp(False, 30, 4, 1)
    sol = prob.solver(x0=initial_guess(Walker(params), gait.fixed_point, prob), p=params.input_vector(),
                      lbg=prob.lbg, ubg=prob.ubg)
    w = np.array(sol["x"]).ravel()
    a_op = operator(obs, prob, planar=False)[0]
    assert_allclose(a_op @ w, obs.value, atol=1e-5)
    shot, _ = model_angles(gait, obs, False, Walker(params, steps_per_time_unit=64))
    assert_allclose(shot, obs.value, atol=1e-5)
    table.metadata["exposure_s"] = 0.0
    try:
        instant = observations(table)
        miss = np.abs(operator(instant, prob, planar=False)[0] @ w - instant.value).max()
        assert miss > 1e-3, miss
    finally:
        table.metadata["exposure_s"] = EXPOSURE


@pytest.mark.slow
def test_the_shutter_removes_a_fits_bias(walk):
    """Rolling resistance fitted to the shutter-averaged frames: with the exposure in the
    measurement model the estimate is the truth within a third of its SE (what is left is the
    collocation's and the data's discretisation); read at t, as before, it was 2.15e-4 against
    2.0e-4, 6 SE off (the same as a rendered and tracked stable-toy walk gave: 2.19e-4, its
    true angles averaged over the shutter 2.15e-4; benchmarks/TRACKING.md)."""
    params, _, table, _ = walk
    start = params.replace(**{"effects.rolling_resistance": 0.0})
    free = ["effects.rolling_resistance"]
    name = free[0]
    with_shutter = fit(table, start, free, model="periodic")
    assert with_shutter.success, with_shutter.status
    err = with_shutter.estimates[name] - STRENGTH
    assert abs(err) < with_shutter.std[name] / 3, (with_shutter.estimates[name], with_shutter.std[name])
    table.metadata["exposure_s"] = 0.0
    try:
        at_t = fit(table, start, free, model="periodic")
    finally:
        table.metadata["exposure_s"] = EXPOSURE
    assert at_t.success, at_t.status
    assert (at_t.estimates[name] - STRENGTH) / at_t.std[name] > 3, (at_t.estimates[name], at_t.std[name])
