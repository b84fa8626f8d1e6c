"""A variable-frame-rate video, as a phone films: the tracker times every frame by its own
presentation time in the container, and on such a clip meets the targets of an even-rate one
(issue 4: lean and pitch RMS <= 0.3 deg, steer <= 0.5 deg, heel strikes timed to a quarter frame
RMS); the same file read as a constant-rate one (frame k at k / fps) misses them.

The clip: data/params/compass-3d.toml walking for 1.38 s (two heel strikes with the tracker's 7
frames either side), rendered by the real renderer at noise level 1 and 960x540 at uneven times:
the rate drifts by +-10 % about 60 frames/s over 1.2 s, every interval jitters by up to 1 ms, and
one frame is dropped (a 33 ms interval) between the strikes, so that ``k / fps`` (the container's
nominal rate, 59.03 frames/s) is up to 38 ms (2.3 frames) off the truth. ``cv2.VideoWriter``
writes a constant rate, so the file's time-to-sample table is then rewritten with the uneven
times (mp4times.py). Smaller, at 640x360, the compass's markers are about 20 pixels wide and even
an even-rate clip misses the strike target (measured -0.35 and +0.25 frame, RMS 0.30).

Measured on an even-rate clip (60 frames/s) of the same walk, size and seed: lean 0.035 deg, steer
0.085, pitch_left 0.097, pitch_right 0.085; strikes -0.17 and +0.03 frame.
"""

import math
import subprocess

import numpy as np
import pytest
from toywalk.model.parameters import load_params
from toywalk.model.trajectory import SIGNALS, read_trajectory
from toywalk.tracking.camera import load_camera
from toywalk.tracking.markers import load_layout
from toywalk.tracking.render import Motion, RenderOptions, default_filming, render
from toywalk.tracking.track import track_frames, track_video
from toywalk.tracking.video import open_video

from ..conftest import DATA
from .mp4times import set_frame_times
from .strikes import match_strikes
from .synthetic import TOYWALK

COMPASS = DATA / "params" / "compass-3d.toml"
TIMESCALE = 90000  # ticks/s of the rewritten video track (the MPEG clock, as phones use)
FRAME = 1 / 60  # s: the mean frame interval, the unit of the strike target


def _phone_times(duration: float, rng) -> np.ndarray:
    """Frame times (s, whole ticks) of a phone at about 60 frames/s (module docstring)."""
    ticks, dropped = [0], False
    while True:
        t = ticks[-1] / TIMESCALE
        dt = FRAME * (1 + 0.1 * math.sin(2 * math.pi * t / 1.2)) + rng.uniform(-1e-3, 1e-3)
        if not dropped and t > 0.68:  # between the strikes (0.46 and 0.93 s)
            dt, dropped = dt + FRAME, True
        following = ticks[-1] + round(dt * TIMESCALE)
        if following > duration * TIMESCALE:
            return np.array(ticks) / TIMESCALE
        ticks.append(following)


@pytest.fixture(scope="module")
def clip(tmp_path_factory):
    """(folder, true frame times, the walk's motion as rendered, the renderer's truth)."""
    folder = tmp_path_factory.mktemp("vfr")
    r = subprocess.run([TOYWALK, "simulate", "--params", str(COMPASS), "--steps", "3", "--out",
                        str(folder / "walk.csv")], capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    params, table = load_params(COMPASS), read_trajectory(folder / "walk.csv")
    times = _phone_times(1.38, np.random.default_rng(5))
    options = RenderOptions.preset(1, frame_times=tuple(times))
    camera, path, layout = default_filming(table, params, 960, 540, options)
    assert path is None  # one fixed camera
    render(table, params, camera, layout, options, folder / "v.mp4", rng=1)
    set_frame_times(folder / "v.mp4", times, TIMESCALE)
    return folder, times, Motion(table, params), read_trajectory(folder / "v.truth.csv")


def _inputs(folder):
    return load_camera(folder / "v.camera.json"), load_layout(folder / "v.markers.json")


@pytest.fixture(scope="module")
def tracked(clip):
    folder = clip[0]
    result, source = track_video(folder / "v.mp4", *_inputs(folder))
    return result, source


@pytest.fixture(scope="module")
def constant_rate(clip, tracked):
    """The same file tracked with frame k at k / (the container's nominal rate)."""
    folder = clip[0]
    fps = tracked[1].nominal_fps
    frames = ((k / fps, image) for k, (_, image) in enumerate(open_video(folder / "v.mp4")))
    return track_frames(frames, *_inputs(folder))


def _angle_rms(result, motion) -> dict:
    """RMS (deg) of each angle against the truth at the times the result gives its frames."""
    truth = np.array([motion.angles(t) for t in result.time])  # lean, steer, pitch_left, pitch_right
    out = {}
    for j, name in enumerate(SIGNALS):
        err = np.degrees(result.raw[name] - truth[:, j])
        ok = np.isfinite(err)
        assert (~ok).sum() <= 6, name  # as test_track_rendered.py: a few gaps near strikes at most
        out[name] = float(np.sqrt(np.mean(err[ok] ** 2)))
    return out


def _meets_angle_targets(rms: dict) -> bool:
    # issue 4: lean and pitch RMS <= 0.3 deg, steer <= 0.5 deg
    return all(v <= (0.5 if name == "steer" else 0.3) for name, v in rms.items())


def _true_strikes(truth) -> list:
    return [e for e in truth.events if truth.time[0] < e["time"] < truth.time[-1]]


@pytest.mark.slow
def test_frames_are_timed_by_the_container(clip, tracked):
    _, times, _, truth = clip
    result, source = tracked
    # OpenCV reads back the rewritten times: milliseconds as a double, to a rounding (1e-16 s)
    np.testing.assert_allclose(result.time, times, rtol=0, atol=1e-12)
    np.testing.assert_allclose(truth.time, times, rtol=0, atol=1e-12)  # the renderer drew them
    stamps = result.timestamps
    assert stamps["policy"] == "container"
    # uneven indeed: intervals of 14 to 33 ms, and k / fps 2.3 frames off at most
    assert stamps["frame_interval_s"]["min"] < 0.9 * FRAME < 1.9 * FRAME < stamps["frame_interval_s"]["max"]
    assert np.max(np.abs(np.arange(len(times)) / source.nominal_fps - times)) > 2 * FRAME


@pytest.mark.slow
def test_variable_rate_meets_the_targets(clip, tracked):
    _, _, motion, truth = clip
    result, _ = tracked
    rms = _angle_rms(result, motion)
    # measured: lean 0.041, steer 0.098, pitch_left 0.100, pitch_right 0.090 (deg)
    assert _meets_angle_targets(rms), rms
    true = _true_strikes(truth)
    assert len(true) == 2  # the clip is chosen to hold two
    strikes = match_strikes(true, result.events, FRAME)
    # one to one, same foot, within half a frame (strikes.MATCH_FRAMES): none missed or invented
    assert not strikes.missed and not strikes.invented, strikes.describe(FRAME)
    errors = np.array(strikes.errors) / FRAME
    # issue 4: timing RMS <= a quarter frame (measured +0.19 and +0.04 frame: RMS 0.14)
    assert np.sqrt(np.mean(errors**2)) <= 0.25, errors


@pytest.mark.slow
def test_constant_rate_reading_misses_the_targets(clip, constant_rate):
    """The check above can fail: the same frames timed k / fps put the angles and the strikes where
    the walker was up to 2.3 frames earlier or later."""
    _, _, motion, truth = clip
    assert constant_rate.timestamps["policy"] == "given"  # the times came with the frames
    rms = _angle_rms(constant_rate, motion)
    # measured: lean 0.34, steer 1.21, pitch_left 1.08, pitch_right 0.74 (deg)
    assert not _meets_angle_targets(rms), rms
    # paired within 3 frames, so that a strike timed that far off still counts as found
    strikes = match_strikes(_true_strikes(truth), constant_rate.events, FRAME, within=3.0)
    errors = np.array(strikes.errors) / FRAME
    # measured -1.21 and -0.85 frame
    assert strikes.missed or np.sqrt(np.mean(errors**2)) > 0.25, errors
