"""The ramp pose measured from the ramp markers (tracking/ramp.py): per video for a fixed camera,
per frame for a moving one, a camera file's fixed pose checked against it; and, end to end, a
rendered walk tracked without the render's camera file (the README's usage)."""

import dataclasses
import json
import math
import re
import subprocess

import cv2
import numpy as np
import pytest
from numpy.testing import assert_allclose
from toywalk.model.kinematics import angles_from_rotations, rotation
from toywalk.model.trajectory import read_trajectory
from toywalk.tracking.camera import Camera
from toywalk.tracking.markers import default_layout
from toywalk.tracking.ramp import CHECK_FLOOR, RampPoseError, ramp_difference
from toywalk.tracking.track import track_frames

from ..conftest import DATA
from .scenes import NAMES, TOY, motion
from .synthetic import TOYWALK, render_walker_frame, walker_scene_camera

FPS = 60.0


def _turned(camera: Camera, delta) -> Camera:
    """``camera`` with its ramp pose turned by ``delta`` (rad) about the ramp's own axes:
    ``R = R_true exp([delta]x)``, the ramp_difference convention."""
    rvec, tvec = camera.ramp_pose
    rot = cv2.Rodrigues(rvec.reshape(3, 1))[0] @ cv2.Rodrigues(np.asarray(delta, float))[0]
    return dataclasses.replace(camera, ramp_pose=(cv2.Rodrigues(rot)[0].ravel(), tvec))


def _lens(camera: Camera) -> Camera:
    return dataclasses.replace(camera, ramp_pose=None)


@pytest.fixture(scope="module")
def clip():
    """Eight frames of the synthetic walker with the ramp markers in view (640x360)."""
    camera = walker_scene_camera(640, 360)
    layout = default_layout(TOY)
    rng = np.random.default_rng(21)
    times = np.arange(8) / FPS
    frames, truth = [], []
    for t in times:
        angles, contact = motion(t)
        frames.append(render_walker_frame(camera, layout, TOY, angles, "L", contact, rng=rng, ss=2)[0])
        truth.append(angles)
    return camera, layout, times, frames, np.array(truth)


def _track(clip, camera):
    _, layout, times, frames, _ = clip
    return track_frames(zip(times, frames, strict=True), camera, layout)


def _assert_accurate(result, truth):
    for k, name in enumerate(NAMES):
        err = np.degrees(result.raw[name] - truth[:, k])
        assert np.all(np.isfinite(err)), name
        # the tracker's targets (lean, pitch 0.3 deg, steer 0.5 deg RMS), as in test_track.py
        assert np.sqrt(np.mean(err**2)) < (0.5 if name == "steer" else 0.3), name


def test_a_ramp_turn_shifts_the_angle_it_is_named_after():
    """ramp_difference's convention, which the refusal's wording relies on: leg rotations read in
    a ramp frame turned by delta about its x, y, z axes come out with lean, pitches, steer shifted
    by -delta (to first order; 2e-4 rad turns, so second order is 4e-8 rad)."""
    r_true = cv2.Rodrigues(np.array([1.8, 0.98, -0.58]))[0]
    legs = {f: rotation(0.05, 0.03, p) for f, p in (("L", 0.2), ("R", -0.2))}
    steer, lean, pl, pr = angles_from_rotations(legs["L"], legs["R"])
    for axis, shifted in ((0, "lean"), (1, "pitch"), (2, "steer")):
        delta = np.zeros(3)
        delta[axis] = 2e-4
        r_used = r_true @ cv2.Rodrigues(delta)[0]
        np.testing.assert_allclose(ramp_difference(r_used, r_true), delta, atol=1e-12)
        seen = {f: r_used.T @ r_true @ legs[f] for f in legs}  # camera-frame legs read in r_used
        s2, l2, pl2, pr2 = angles_from_rotations(seen["L"], seen["R"])
        change = {"lean": l2 - lean, "pitch": 0.5 * (pl2 - pl + pr2 - pr), "steer": s2 - steer}
        for name, value in change.items():
            expected = -2e-4 if name == shifted else 0.0
            # first order in 2e-4 rad, with the legs' lean and steer (0.03-0.05 rad) coupling the
            # axes by about 5 % of the turn
            assert value == pytest.approx(expected, abs=2e-5), (shifted, name, value)


def test_without_a_fixed_pose_the_ramp_is_measured(clip):
    camera, _, _, _, truth = clip
    result = _track(clip, _lens(camera))
    assert result.ramp["source"].startswith("ramp markers, one fixed pose fitted to 8 frames")
    # its uncertainty, per angle: small (a 640x360 board of eight markers), stated
    assert set(result.ramp["sd_deg"]) == {"lean", "pitch", "steer"}
    assert all(0 < v < 0.1 for v in result.ramp["sd_deg"].values())
    _assert_accurate(result, truth)


def test_a_fixed_pose_that_agrees_is_used_and_said_so(clip):
    camera, _, _, _, truth = clip
    result = _track(clip, camera)
    assert result.ramp["source"].startswith("camera file (fixed ramp_pose), confirmed by the ramp markers")
    check = result.ramp["check"]
    assert all(check["disagreement_deg"][a] <= check["limit_deg"][a] for a in check["limit_deg"])
    _assert_accurate(result, truth)


@pytest.mark.parametrize("axis, name", [(0, "lean"), (1, "pitch"), (2, "steer")])
def test_a_fixed_pose_off_by_half_a_degree_is_refused_naming_the_angle(clip, axis, name):
    """The issue's case: a camera file's pose 0.3-0.6 deg off gave biased angles without a word.
    Half a degree is ten times the 0.05 deg floor and far beyond 4 SDs of the measured pose."""
    camera = clip[0]
    delta = np.zeros(3)
    delta[axis] = math.radians(0.5)
    with pytest.raises(RampPoseError, match=rf"shift every {name} by ") as err:
        _track(clip, _turned(camera, delta))
    message = str(err.value)
    assert len(message.splitlines()) == 1 and "remove ramp_pose" in message
    shift = float(re.search(r"by ([-+.\d]+) deg", message).group(1))
    sd = float(re.search(r"measure it to ([.\d]+) deg", message).group(1))
    # the turn, seen through the measured pose's error: within 3 of its stated SDs (0.05-0.06 deg
    # at 640x360; measured -0.51 about each axis)
    assert abs(shift + 0.5) < 3 * sd, message


def test_a_fixed_pose_within_the_limit_is_accepted(clip):
    """Half the 0.05 deg floor about every axis: within the measurement's accuracy."""
    camera = clip[0]
    result = _track(clip, _turned(camera, np.full(3, 0.5 * CHECK_FLOOR)))
    assert result.ramp["source"].startswith("camera file")


def test_a_moving_camera_gets_each_frames_own_ramp_pose():
    """The camera slides 3 cm a frame along the ramp and turns 0.2 deg a frame about its normal
    (a hand-held following shot): each frame's ramp pose is measured, and a camera file's fixed
    pose (the first frame's) is refused: it is half a degree off in steer on the median frame."""
    base = walker_scene_camera(640, 360)
    layout = default_layout(TOY)
    rng = np.random.default_rng(8)
    rot = cv2.Rodrigues(base.ramp_pose[0].reshape(3, 1))[0]
    frames, truth, times = [], [], np.arange(6) / FPS
    for k, t in enumerate(times):
        slid = dataclasses.replace(base, ramp_pose=(base.ramp_pose[0],
                                                    base.ramp_pose[1] - rot @ [0.03 * k, 0.0, 0.0]))
        moved = _turned(slid, [0.0, 0.0, math.radians(0.2 * k)])
        angles, contact = motion(t)
        frames.append(render_walker_frame(moved, layout, TOY, angles, "L", contact, rng=rng, ss=2)[0])
        truth.append(angles)
    result = track_frames(zip(times, frames, strict=True), _lens(base), layout)
    assert result.ramp["source"].startswith("ramp markers, each frame's own pose in 6 of 6 frames")
    _assert_accurate(result, np.array(truth))
    with pytest.raises(RampPoseError, match=r"every steer by 0\.[4-6]\d deg \(median over 6 frames of a mov"):
        track_frames(zip(times, frames, strict=True), base, layout)


# --- end to end: render, then track without --camera (the README's usage) --------------------------

def _run(*args):
    r = subprocess.run([TOYWALK, *map(str, args)], capture_output=True, text=True, timeout=600)
    return r


@pytest.fixture(scope="module")
def stable_walk(tmp_path_factory):
    """The issue's walk: 16 steps of data/params/stable-toy.toml (seed 917), rendered at noise
    level 1 (seed 4411) by the default camera, which frames the whole walk (1.7 s, 103 frames)."""
    folder = tmp_path_factory.mktemp("stable16")
    _walk_and_film(folder, "stable-toy", 917, 4411)
    return folder


def _walk_and_film(folder, walker: str, walk_seed: int, render_seed: int) -> str:
    """``simulate`` 16 steps of data/params/WALKER.toml and ``render`` them at noise level 1 with the
    default camera into FOLDER/T.csv and FOLDER/V.mp4; render's summary line."""
    params = DATA / "params" / f"{walker}.toml"
    for args in (("simulate", "--params", params, "--steps", 16, "--seed", walk_seed,
                  "--out", folder / "T.csv"),
                 ("render", folder / "T.csv", "--params", params, "--noise", 1, "--seed", render_seed,
                  "--out", folder / "V.mp4")):
        r = _run(*args)
        assert r.returncode == 0, r.stderr
    return r.stdout


@pytest.mark.slow
def test_track_without_the_render_camera_meets_the_targets(stable_walk):
    """The bundled camera's ramp pose (where render puts the camera for compass-3d) biased lean,
    steer and pitches by -0.62, -0.34, +0.43 deg; measured from the markers they are unbiased."""
    out = stable_walk / "M.csv"
    r = _run("track", stable_walk / "V.mp4", "--out", out)
    assert r.returncode == 0, r.stderr
    assert "ramp pose: ramp markers, one fixed pose" in r.stdout
    meta = json.loads((stable_walk / "M.json").read_text())
    assert meta["ramp_pose"]["source"].startswith("ramp markers")
    assert meta["camera"]["use"] == "bundled default: intrinsics only"
    assert meta["markers"]["from"] == "written by render beside the video"
    tracked, truth = read_trajectory(out), read_trajectory(stable_walk / "V.truth.csv")
    for name in NAMES:
        err = np.degrees(tracked.signals[name] - truth.signals[name])
        assert np.isfinite(err).all(), name
        # the targets; measured 0.03 (lean), 0.07 (steer), 0.10 (pitches)
        assert np.sqrt(np.mean(err**2)) <= (0.5 if name == "steer" else 0.3), name
        # no bias left: the mean error is within the ramp pose's own SD (about 0.01 deg) and
        # the per-frame noise's standard error (0.1 deg / sqrt(103)), measured 0.004-0.018
        assert abs(np.mean(err)) < 0.05, name
    dt = float(np.median(np.diff(truth.time)))
    true = [e for e in truth.events if truth.time[0] + 3 * dt < e["time"] < truth.time[-1] - 3 * dt]
    assert [e["foot"] for e in tracked.events] == [e["foot"] for e in true]
    errors = np.array([e["time"] - s["time"] for e, s in zip(tracked.events, true, strict=True)])
    assert np.sqrt(np.mean(errors**2)) / dt <= 0.25  # a quarter frame; measured 0.12


@pytest.mark.slow
def test_track_without_a_camera_reads_the_bundled_lens_at_the_videos_size(stable_walk, tmp_path):
    """A video filmed in another mode of the same aspect ratio (render --size 1920x1080, as a
    phone's 1080p): track without --camera reads the bundled lens out at that size, says so, and
    meets the targets; a 4:3 video, which no scaling of the lens describes, is refused in one line
    that says to calibrate, with nothing written. (Refused whatever its aspect before: the video
    is 1920x1080 pixels but the camera file describes 1280x720.)"""
    params = DATA / "params" / "stable-toy.toml"
    for size, seconds in (("1920x1080", 0.7), ("1280x960", 0.1)):
        r = _run("render", stable_walk / "T.csv", "--params", params, "--size", size, "--duration",
                 seconds, "--seed", 8, "--out", tmp_path / f"{size}.mp4")
        assert r.returncode == 0, r.stderr
    out = tmp_path / "hd" / "M.csv"
    out.parent.mkdir()
    r = _run("track", tmp_path / "1920x1080.mp4", "--out", out)
    assert r.returncode == 0, r.stderr
    assert "lens: the bundled one scaled to 1920x1080" in r.stdout
    assert "warning" not in r.stderr  # every heel strike found, both legs in every frame
    meta = json.loads((out.parent / "M.json").read_text())
    assert meta["camera"]["use"] == "bundled default: intrinsics only, scaled from 1280x720 to 1920x1080"
    # the lens render filmed with at that size (default_camera_for, computed on its own)
    filmed = json.loads((tmp_path / "1920x1080.camera.json").read_text())
    assert_allclose(meta["camera"]["camera_matrix"], filmed["camera_matrix"], rtol=0, atol=1e-9)
    tracked, truth = read_trajectory(out), read_trajectory(tmp_path / "1920x1080.truth.csv")
    assert len(tracked.time) == 43  # 0.7 s at 60 frames/s, both ends
    for name in NAMES:
        err = np.degrees(tracked.signals[name] - truth.signals[name])
        assert np.isfinite(err).all(), name
        # the issue 4 targets, as above; measured 0.02 (lean), 0.06 (steer), 0.10-0.13 (pitches)
        assert np.sqrt(np.mean(err**2)) <= (0.5 if name == "steer" else 0.3), name
    (tmp_path / "sd").mkdir()
    r = _run("track", tmp_path / "1280x960.mp4", "--out", tmp_path / "sd" / "M.csv")
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1, r.stderr
    assert "does not fit its aspect ratio; calibrate the camera in this video mode" in r.stderr
    assert list((tmp_path / "sd").iterdir()) == []


@pytest.mark.slow
def test_track_refuses_a_camera_file_placed_elsewhere(stable_walk, tmp_path):
    """data/camera/default.json, given explicitly: its ramp pose is not where this video's camera
    stood; refused in one line naming the angle (lean, the largest, -0.6 deg), nothing written."""
    r = _run("track", stable_walk / "V.mp4", "--camera", DATA / "camera" / "default.json",
             "--out", tmp_path / "m.csv")
    assert r.returncode == 2
    assert len(r.stderr.strip().splitlines()) == 1
    assert "ramp_pose disagrees with the ramp markers" in r.stderr and "every lean by -0.6" in r.stderr
    assert list(tmp_path.iterdir()) == []


@pytest.mark.slow
def test_a_long_walk_tracked_from_a_following_camera_meets_the_targets(tmp_path):
    """The issue's second walk: 16 steps of data/params/toy-sized.toml (simulate seed 5, 1.37 m of
    travel; render seed 77), which leaves any fixed view, so render's default camera follows the
    walker (358 frames, about 40 s to render). Tracked as the README says, without --camera:
    each frame's own ramp pose from the markers, every frame but one tracked (frame 17, near a
    strike, is a gap), and the targets met (measured: lean 0.042, steer 0.063, pitches 0.140 and
    0.053 deg RMS; the 15 strikes inside the clip at 0.05 frame RMS)."""
    assert "camera following the walker" in _walk_and_film(tmp_path, "toy-sized", 5, 77)
    r = _run("track", tmp_path / "V.mp4", "--out", tmp_path / "M.csv")
    assert r.returncode == 0, r.stderr
    meta = json.loads((tmp_path / "M.json").read_text())
    assert meta["ramp_pose"]["source"].startswith("ramp markers, each frame's own pose in 358 of 358")
    assert meta["camera"]["use"] == "bundled default: intrinsics only"
    tracked, truth = read_trajectory(tmp_path / "M.csv"), read_trajectory(tmp_path / "V.truth.csv")
    for name in NAMES:
        err = np.degrees(tracked.signals[name] - truth.signals[name])
        assert np.isfinite(err).sum() >= len(err) - 2, name  # measured: one gap (frame 17)
        # the targets (issue 4): lean and pitch 0.3 deg, steer 0.5
        assert np.sqrt(np.nanmean(err**2)) <= (0.5 if name == "steer" else 0.3), name
    dt = float(np.median(np.diff(truth.time)))
    true = [e for e in truth.events if truth.time[0] + 3 * dt < e["time"] < truth.time[-1] - 3 * dt]
    assert len(true) == 15 and [e["foot"] for e in tracked.events] == [e["foot"] for e in true]
    errors = np.array([e["time"] - s["time"] for e, s in zip(tracked.events, true, strict=True)])
    assert np.sqrt(np.mean(errors**2)) / dt <= 0.25  # a quarter frame
