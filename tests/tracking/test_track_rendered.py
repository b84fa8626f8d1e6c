"""The tracker on a short clip made by the real renderer (noise level 1: sensor noise, motion
blur, flicker, MPEG-4), against the renderer's truth: the targets of issue 4.

The walker is the toy-sized one of test_track.py (leg 15 cm, its flags about 50 pixels wide at
1280x720), the case where tracking leg by leg failed: near heel strike the swing leg moves fast,
its blurred markers are often not decoded, and a leg seen through one small marker gave a wrong,
sometimes mirrored pose (pitch errors up to 14 degrees, RMS 0.9-1.7 degrees, strikes missed or
given to the wrong foot). One second (60 frames) holds two heel strikes.
"""

import subprocess

import numpy as np
import pytest
from toywalk.model.trajectory import read_trajectory
from toywalk.tracking.camera import load_camera
from toywalk.tracking.markers import load_layout
from toywalk.tracking.track import track_video

from ..conftest import DATA
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
        # issue 4: lean and pitch RMS <= 0.3 deg, steer <= 0.5 deg (measured 0.06-0.15)
        assert rms <= (0.5 if name == "steer" else 0.3), (name, rms)
        # the stated SDs are honest: errors over SD have an RMS of order one (measured 0.6-0.9)
        z = err[ok] / np.degrees(result.raw_sd[name][ok])
        assert 0.3 < np.sqrt(np.mean(z**2)) < 3.0, name


@pytest.mark.slow
def test_heel_strikes_found_timed_and_footed(clip):
    result, truth = clip
    dt = float(np.median(np.diff(truth.time)))
    true = [e for e in truth.events if truth.time[0] < e["time"] < truth.time[-1]]
    assert len(true) == 2  # the clip is chosen to hold two
    # none missed, none invented, each by the right foot
    assert [e.foot for e in result.events] == [e["foot"] for e in true]
    errors = [(e.time - s["time"]) / dt for e, s in zip(result.events, true, strict=True)]
    # issue 4: timing RMS <= a quarter of a frame interval (measured 0.09 and 0.01 frames)
    assert np.sqrt(np.mean(np.square(errors))) <= 0.25, errors


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
        # issue 4 targets; measured 0.04-0.14 (benchmarks/TRACKING.md, 18 steps)
        assert rms <= (0.5 if name == "steer" else 0.3), (name, rms)
    dt = float(np.median(np.diff(truth.time)))
    # a strike is sought with 3 samples either side (half a step): not within 3 frames of an end
    true = [e for e in truth.events if truth.time[0] + 3 * dt < e["time"] < truth.time[-1] - 3 * dt]
    assert len(true) == 10
    assert [e.foot for e in result.events] == [e["foot"] for e in true]
    errors = np.array([e.time - s["time"] for e, s in zip(result.events, true, strict=True)])
    # issue 4: a quarter frame; measured 0.10 frame (5 strikes a foot fix the templates)
    assert np.sqrt(np.mean(errors**2)) / dt <= 0.25
    # time_sd honest: error over SD measured 0.93 RMS
    assert np.sqrt(np.mean(np.square(errors / [e.time_sd for e in result.events]))) < 3.0
