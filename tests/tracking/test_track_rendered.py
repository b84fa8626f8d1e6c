"""The tracker on a short clip made by the real renderer (noise level 1: sensor noise, motion
blur, flicker, MPEG-4), against the renderer's truth: the targets of issue 4.

The walker is the toy-sized one of test_track.py (leg 15 cm, its flags about 50 pixels wide at
1280x720), the case where tracking leg by leg failed: near heel strike the swing leg moves fast,
its blurred markers are often not decoded, and a leg seen through one small marker gave a wrong,
sometimes mirrored pose (pitch errors up to 14 degrees, RMS 0.9-1.7 degrees, strikes missed or
given to the wrong foot). One second (60 frames) holds two heel strikes.

Two more clips: stable-toy, whose steps last 6.4 frames, and compass-3d, the walker of
benchmarks/TRACKING.md whose level-1 results there this holds on a short clip.

Bounds on the RMS of error over stated SD (``z``): above, 1 + 3/sqrt(2 n_eff), the sampling
spread of an RMS over the clip's frames (``n_eff`` the frames, fewer where the errors of
neighbouring frames correlate: ``n (1 - r^2) / (1 + r^2)`` for a lag-1 correlation ``r``);
the tracker's one deliberate departure from honest SDs enlarges them. Below, a documented
miscalibration: ``walker_angles_with_sd`` inflates a frame's covariance by ``(rms / expected)^2``
where its residual exceeds the pooled pixel noise. On the blurred toy and stable-toy clips that
is what makes the SDs honest (without it ``z`` is 0.9-3.3), but it errs large: ``z`` is 0.6-1.07
on all three clips (three noise seeds each). The lower bound is the lowest signal's mean over
the seeds times the sampling floor 1 - 3/sqrt(2 n_eff).
"""

import subprocess

import numpy as np
import pytest
from toywalk.model.trajectory import read_trajectory
from toywalk.tracking.camera import load_camera
from toywalk.tracking.markers import load_layout
from toywalk.tracking.track import track_video

from ..conftest import DATA
from .strikes import match_strikes, two_strike_errors
from .synthetic import TOYWALK

TOY = DATA / "params" / "toy-sized.toml"
SIGNALS = ("lean", "steer", "pitch_left", "pitch_right")


def _run(*args):
    r = subprocess.run([TOYWALK, *map(str, args)], capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    return r


def _render_and_track(folder, params, steps: int, seed: int, duration: float):
    """Simulate ``steps`` steps, render ``duration`` s at noise level 1 and track the video:
    (TrackResult, the renderer's truth)."""
    _run("simulate", "--params", params, "--steps", steps, "--out", folder / "walk.csv")
    _run("render", folder / "walk.csv", "--params", params, "--seed", seed, "--duration", duration,
         "--out", folder / "v.mp4")
    result, _ = track_video(folder / "v.mp4", load_camera(folder / "v.camera.json"),
                            load_layout(folder / "v.markers.json"))
    return result, read_trajectory(folder / "v.truth.csv")


@pytest.fixture(scope="module")
def clip(tmp_path_factory):
    return _render_and_track(tmp_path_factory.mktemp("rendered"), TOY, 3, 1, 1.0)


@pytest.mark.slow
def test_angles_meet_the_targets(clip):
    result, truth = clip
    np.testing.assert_allclose(result.time, truth.time, atol=1e-4)  # the container's timestamps
    for name in SIGNALS:
        err = np.degrees(result.raw[name] - truth.signals[name])
        ok = np.isfinite(err)
        # Frames whose pose jumps away from both neighbours become gaps, not wrong values; the
        # renderer hides no marker at level 1, so few may (measured: 4 of 60 frames, all within
        # two frames of a heel strike).
        assert (~ok).sum() <= 6, name
        rms = np.sqrt(np.mean(err[ok] ** 2))
        # issue 4: lean and pitch RMS <= 0.3 deg, steer <= 0.5 deg (measured: lean 0.04, steer
        # 0.08, pitch_right 0.09, pitch_left 0.26; over noise seeds 1, 3, 4 pitch_left is 0.15-0.26)
        assert rms <= (0.5 if name == "steer" else 0.3), (name, rms)
        # z (module docstring): n = 56-58 frames, lag-1 correlation up to 0.49 (pitch_left), so
        # n_eff = 35 and the sampling spread 3/sqrt(70) = 0.36. Measured over seeds 1, 3, 4: lean
        # 0.64-0.71 (mean 0.67), steer 0.69-0.81, pitch_left 0.85-0.97, pitch_right 0.61-0.74.
        z = np.sqrt(np.mean((err[ok] / np.degrees(result.raw_sd[name][ok])) ** 2))
        assert 0.67 * (1 - 0.36) < z < 1 + 0.36, (name, z)


@pytest.mark.slow
def test_heel_strikes_found_timed_and_footed(clip):
    result, truth = clip
    dt = float(np.median(np.diff(truth.time)))
    true = [e for e in truth.events if truth.time[0] < e["time"] < truth.time[-1]]
    assert len(true) == 2  # the clip is chosen to hold two
    strikes = match_strikes(true, result.events, dt)
    # one to one, same foot, within half a frame (strikes.MATCH_FRAMES): none missed or invented
    assert not strikes.missed and not strikes.invented, strikes.describe(dt)
    errors = np.array(strikes.errors) / dt
    # issue 4: timing RMS <= a quarter of a frame interval (measured 0.14 and -0.02 frames)
    assert np.sqrt(np.mean(errors**2)) <= 0.25, errors


STABLE = DATA / "params" / "stable-toy.toml"


@pytest.fixture(scope="module")
def fast_clip(tmp_path_factory):
    """data/params/stable-toy.toml steps every 6.4 frames: 1.2 s hold 11 heel strikes."""
    return _render_and_track(tmp_path_factory.mktemp("rendered_fast"), STABLE, 13, 2, 1.2)


@pytest.mark.slow
def test_fast_steps_meet_the_targets(fast_clip):
    """The fast-stepping walker at the default noise level: every frame tracked to the targets,
    every strike found with its foot and timed to a quarter frame, with honest time SDs."""
    result, truth = fast_clip
    for name in SIGNALS:
        err = np.degrees(result.raw[name] - truth.signals[name])
        assert np.isfinite(err).all(), name
        rms = np.sqrt(np.mean(err**2))
        # issue 4 targets; measured 0.02-0.10 (0.04-0.14 in benchmarks/TRACKING.md, 18 steps)
        assert rms <= (0.5 if name == "steer" else 0.3), (name, rms)
        # z (module docstring): n = 73 frames, lag-1 correlation <= 0.2, n_eff = 67, sampling
        # spread 3/sqrt(134) = 0.26. Measured over seeds 2-4: lean 0.68-0.80, steer 0.66-0.78
        # (mean 0.71), pitch_left 0.94-1.00, pitch_right 0.95-1.07.
        z = np.sqrt(np.mean((err / np.degrees(result.raw_sd[name])) ** 2))
        assert 0.71 * (1 - 0.26) < z < 1 + 0.26, (name, z)
    dt = float(np.median(np.diff(truth.time)))
    # a strike is sought with 3 samples either side (half a step): not within 3 frames of an end
    true = [e for e in truth.events if truth.time[0] <= e["time"] <= truth.time[-1]]
    seek = (truth.time[0] + 3 * dt, truth.time[-1] - 3 * dt)
    strikes = match_strikes(true, result.events, dt, seek=seek)
    assert len(strikes.pairs) + len(strikes.missed) == 10
    # one to one, same foot, within half a frame (strikes.MATCH_FRAMES): none missed or invented
    assert not strikes.missed and not strikes.invented, strikes.describe(dt)
    errors = np.array(strikes.errors)
    # issue 4: a quarter frame; measured 0.10 frame (5 strikes a foot fix the templates)
    assert np.sqrt(np.mean(errors**2)) / dt <= 0.25
    # time_sd never too small: at most 1 + 3/sqrt(2 * 10), the sampling spread of an RMS over 10
    # strikes. It errs large here: 0.30 (seed 2). Since the renderer draws the heel strike's kink
    # as the walk has it (tracking/render.py, StepwiseSpline), the strikes are timed to 0.03
    # frame, while their SD takes the noise level from the breakpoint fit's residuals, which at
    # 6.4 frames a step hold the quadratics' misfit (before, the renderer rounded the kink and
    # each foot's strikes shared a bias of 0.5-1.3 SD: z 0.83-0.98). Too large an SD costs the
    # fit power, not a wrong verdict; too small names causes wrongly, and SDs half as large as
    # stated would give 0.6 here.
    time_sd = np.array([m.time_sd for _, m in strikes.pairs])
    z = np.sqrt(np.mean((errors / time_sd) ** 2))
    assert 0.15 < z < 1 + 3 / np.sqrt(20), z


COMPASS = DATA / "params" / "compass-3d.toml"


@pytest.fixture(scope="module")
def compass_clip(tmp_path_factory):
    """compass-3d at level 1 (benchmarks/TRACKING.md's level-1 seed, 2): 28 frames a step, 1.2 s
    hold two heel strikes."""
    return _render_and_track(tmp_path_factory.mktemp("rendered_compass"), COMPASS, 3, 2, 1.2)


@pytest.mark.slow
def test_compass_meets_the_targets(compass_clip):
    """benchmarks/TRACKING.md's level-1 compass-3d results on a short clip: every frame tracked to
    the issue-4 targets with honest SDs, every strike found with its foot and timed to a quarter
    frame, the hip width estimated."""
    result, truth = compass_clip
    np.testing.assert_allclose(result.time, truth.time, rtol=0, atol=1e-4)  # container timestamps
    for name in SIGNALS:
        err = np.degrees(result.raw[name] - truth.signals[name])
        # its legs move 4-6 px during a whole-frame shutter and keep every marker: no gaps
        # (benchmarks/TRACKING.md: 0 of 223 frames at level 1)
        assert np.isfinite(err).all(), name
        rms = np.sqrt(np.mean(err**2))
        # issue 4 targets; measured 0.02-0.06 over seeds 1-3 (0.027-0.058 in TRACKING.md, 8 steps)
        assert rms <= (0.5 if name == "steer" else 0.3), (name, rms)
        # z (module docstring): n = 73 frames, lag-1 correlation <= 0.23, n_eff = 66, sampling
        # spread 3/sqrt(132) = 0.26. Measured over seeds 1-3: lean 0.83-0.97, steer 0.84-0.93,
        # pitch_left 0.61-0.62 (mean 0.62), pitch_right 0.78-0.86.
        z = np.sqrt(np.mean((err / np.degrees(result.raw_sd[name])) ** 2))
        assert 0.62 * (1 - 0.26) < z < 1 + 0.26, (name, z)
    # two strikes, each found once by its foot within half a frame (strikes.MATCH_FRAMES)
    errors = np.array(two_strike_errors(truth, result.events))
    # issue 4: a quarter frame (measured -0.12 and 0.00 frame; 0.04 RMS in TRACKING.md)
    assert np.sqrt(np.mean(errors**2)) <= 0.25, errors
    # the tracker is not told the hip width (0.1 m) and estimates it: measured 0.16-0.23 mm short
    # over seeds 1-3 (0.1-0.4 mm in TRACKING.md); 1 mm is 1 % of it, and 2.5 times TRACKING.md's
    # largest error
    assert abs(result.hip_width - 0.1) < 1e-3, result.hip_width
