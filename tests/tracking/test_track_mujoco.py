"""The tracker on images its own renderer did not make: a walk filmed by MuJoCo's OpenGL renderer
(tracking.render_mujoco: another rasteriser, lighting with shadows and highlights, mipmapped
textures, multisample anti-aliasing), held to the issue-4 targets of test_track_rendered.py.

The clip is test_track_rendered.py's compass-3d clip (3 simulated steps, 1.2 s at 60 fps, noise
level 1: sensor noise, motion blur, flicker, MPEG-4), filmed by MuJoCo from the camera that
``toywalk render`` places for it. MuJoCo's camera has no lens distortion and its principal point
at the image centre; the camera file the renderer writes says so, and the tracker uses it.

Bounds on the RMS of error over stated SD (``z``) reuse test_track_rendered.py's reasoning: above,
1 + 3/sqrt(2 n_eff), the sampling spread of an RMS over the clip's frames. On MuJoCo's frames the
errors are the per-frame scatter plus a bias common to the clip (a few hundredths of a degree
per signal, the same in every frame and for every noise seed: the tracker's corners sit slightly
differently on MuJoCo's shading and texture filtering). The per-frame SDs describe the scatter,
not that bias (as for the ramp pose: ``TrackResult.ramp`` calls such an error "a bias, not in
the per-frame SDs"), so the z bounds hold for the errors about their mean over the clip; the bias
is bounded separately, at a third of the angle targets.
"""

import dataclasses
import json
import math
import subprocess

import cv2
import numpy as np
import pytest
from toywalk.model.parameters import load_params
from toywalk.model.trajectory import TrajectoryTable, read_trajectory, write_trajectory
from toywalk.sysid.cli import main
from toywalk.tracking.camera import load_camera, project
from toywalk.tracking.markers import load_layout, marker_corners
from toywalk.tracking.render import Motion, RenderOptions, default_filming
from toywalk.tracking.render_mujoco import MujocoScene, MujocoUnavailable, gl_backend, render_mujoco
from toywalk.tracking.scene import Scene
from toywalk.tracking.track import track_video

from ..conftest import DATA
from .strikes import two_strike_errors
from .synthetic import TOYWALK

pytest.importorskip("mujoco")

COMPASS = DATA / "params" / "compass-3d.toml"
SIGNALS = ("lean", "steer", "pitch_left", "pitch_right")
BODY = {"left_leg": "L", "right_leg": "R"}


@pytest.fixture(scope="module")
def backend():
    try:
        return gl_backend()
    except MujocoUnavailable as err:
        pytest.skip(f"MuJoCo cannot render here: {err}")


@pytest.fixture(scope="module")
def compass():
    return load_params(COMPASS)


def _stroll(duration=0.4, n=41) -> TrajectoryTable:
    """A made-up stretch of walking on the left foot (as in test_render.py): both pitches swing,
    the walker leans and steers, the contact creeps forward."""
    t = np.linspace(0.0, duration, n)
    signals = {"lean": 0.06 * np.sin(2 * np.pi * t / 0.9), "steer": 0.1 * np.sin(2 * np.pi * t / 0.9 + 1),
               "pitch_left": -0.2 + 0.9 * t, "pitch_right": 0.2 - 0.9 * t,
               "contact_x": 0.05 * t, "contact_y": np.zeros(n)}
    return TrajectoryTable(t, signals, np.full(n, "L"), [], {"source": {"kind": "test"}})


def _detector(layout):
    par = cv2.aruco.DetectorParameters()
    par.cornerRefinementMethod = cv2.aruco.CORNER_REFINE_SUBPIX
    return cv2.aruco.ArucoDetector(layout.aruco_dictionary(), par)


def test_markers_are_drawn_where_the_camera_model_projects_them(backend, compass):
    """The check of the MuJoCo renderer's truth: on noise-free frames ArUco finds every marker at
    the corners camera.project gives for the true poses, through the camera the renderer says it
    filmed with (fy kept, principal point centred, no distortion).

    Tolerances: test_render.py's for the project's renderer are 0.35 px RMS, 0.6 px a marker and
    0.1 px mean. Here the far ramp markers, seen at 25 degrees through mipmapped textures, have
    ArUco's corners 0.7-0.9 px off (the nearer ones 0.2-0.35 px): measured 0.52 px RMS, 0.87 px
    for the worst marker, mean offset 0.065 px (llvmpipe; another OpenGL driver filters and
    samples differently), so 0.7 px RMS, 1.2 px a marker and 0.15 px mean. A half-pixel
    convention error, a flipped texture or a wrong field of view shows in the mean (0.5 px and
    more) or as a marker not found.
    """
    table = _stroll()
    motion = Motion(table, compass)
    camera, _, layout = default_filming(table, compass)
    detector = _detector(layout)
    diffs, seen = [], set()
    with MujocoScene(compass, layout, camera) as scene:
        lens = scene.camera
        assert lens.matrix[1, 1] == camera.matrix[1, 1] and not np.any(lens.distortion)
        for t in (0.0, 0.2, 0.4):
            state = motion.state(t)
            img = scene.draw(state)
            assert img.shape == (camera.height, camera.width, 3) and img.dtype == np.uint8
            corners, ids, _ = detector.detectMarkers(cv2.cvtColor(img, cv2.COLOR_BGR2GRAY))
            assert ids is not None
            for c, i in zip(corners, ids.ravel(), strict=True):
                marker = layout.by_id(int(i))
                pts = marker_corners(marker)
                if marker.body != "ramp":
                    leg = BODY[marker.body]
                    pts = pts @ state.rotation[leg].T + state.hip[leg]
                d = c.reshape(4, 2) - project(lens, pts, *lens.ramp_pose)
                assert np.sqrt(np.mean(np.sum(d**2, axis=1))) < 1.2, (t, int(i), d)
                diffs.append(d)
                seen.add(int(i))
    assert {m.id for m in layout.markers} <= seen
    diffs = np.concatenate(diffs)
    assert np.sqrt(np.mean(np.sum(diffs**2, axis=1))) < 0.7
    assert np.all(np.abs(diffs.mean(axis=0)) < 0.15)


def test_images_differ_from_the_project_renderers(backend, compass):
    """The point of the second renderer: the same instant, camera and markers drawn by
    tracking.scene and by MuJoCo are different images (the mean absolute grey-level difference of
    the two is many times that between one renderer's frames a frame interval apart), while both
    show every marker."""
    table = _stroll()
    motion = Motion(table, compass)
    camera, _, layout = default_filming(table, compass)
    grey = {}
    with MujocoScene(compass, layout, camera) as mj:
        lens = mj.camera  # the project's renderer films with the same pinhole
        grey["mujoco"] = cv2.cvtColor(mj.draw(motion.state(0.2)), cv2.COLOR_BGR2GRAY)
    scene = Scene(compass, layout, lens)
    for name, t in (("scene", 0.2), ("scene_next", 0.2 + 1 / 60)):
        grey[name] = cv2.cvtColor(scene.finish(scene.draw(motion.state(t))), cv2.COLOR_BGR2GRAY)
    for name in ("mujoco", "scene"):
        _, ids, _ = _detector(layout).detectMarkers(grey[name])
        assert {m.id for m in layout.markers} <= set(ids.ravel().tolist()), name

    def mad(a, b):
        return float(np.mean(np.abs(grey[a].astype(float) - grey[b])))

    # measured 0.3 (next frame) and 36 (MuJoCo): backdrop, ramp texture, shading all differ
    assert mad("scene", "scene_next") < 1.0
    assert mad("mujoco", "scene") > 10.0
    assert mad("mujoco", "scene") > 20 * mad("scene", "scene_next")


def test_cli_renders_with_mujoco(backend, tmp_path, capsys):
    """``toywalk render --engine mujoco`` writes the renderer's files, the camera file the lens
    MuJoCo filmed with (no distortion, centred principal point) and, with the same seed, the
    same video frames again."""
    walk = tmp_path / "walk.csv"
    write_trajectory(_stroll(duration=0.1, n=11), walk)
    frames = []
    for name in ("a", "b"):
        out = tmp_path / name / "v.mp4"
        out.parent.mkdir()
        code = main(["render", str(walk), "--params", str(COMPASS), "--size", "320x180", "--fps", "30",
                     "--noise", "2", "--seed", "3", "--engine", "mujoco", "--out", str(out)])
        assert code == 0, capsys.readouterr().err
        assert sorted(p.name for p in out.parent.iterdir()) == [
            "v.camera.json", "v.json", "v.markers.json", "v.mp4", "v.truth.csv", "v.truth.events.csv"]
        meta = json.loads((out.parent / "v.json").read_text())
        assert meta["renderer"]["engine"] == "mujoco" and meta["options"]["level"] == 2
        lens = load_camera(out.parent / "v.camera.json")
        assert not np.any(lens.distortion) and tuple(lens.matrix[:2, 2]) == (159.5, 89.5)
        video = cv2.VideoCapture(str(out))
        frames.append([video.read()[1] for _ in range(meta["frames"])])
        video.release()
    assert len(frames[0]) == 4 and all(np.array_equal(a, b) for a, b in zip(*frames, strict=True))


def _run(*args):
    r = subprocess.run([TOYWALK, *map(str, args)], capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    return r


@pytest.fixture(scope="module")
def clip(backend, compass, tmp_path_factory):
    """test_track_rendered.py's compass clip, filmed by MuJoCo at level 1 (seed 2), tracked:
    (TrackResult, truth, folder)."""
    folder = tmp_path_factory.mktemp("mujoco_compass")
    _run("simulate", "--params", COMPASS, "--steps", 3, "--out", folder / "walk.csv")
    table = read_trajectory(folder / "walk.csv")
    options = RenderOptions.preset(1, duration=1.2)
    camera, path, layout = default_filming(table, compass, options=options)
    assert path is None  # one fixed camera frames this walk
    out = render_mujoco(table, compass, camera, layout, options, folder / "v.mp4", rng=2,
                        source={"trajectory": "walk.csv", "params": str(COMPASS)})
    result, _ = track_video(out.paths["video"], load_camera(out.paths["camera"]),
                            load_layout(out.paths["markers"]))
    return result, read_trajectory(out.paths["truth"]), folder


@pytest.mark.slow
def test_mujoco_clip_meets_the_targets(clip):
    """Every frame tracked to the issue-4 targets with SDs honest about the frame-to-frame
    scatter, every strike found with its foot and timed to a quarter frame, the hip width
    estimated: test_track_rendered.py's compass targets, on MuJoCo's images."""
    result, truth, folder = clip
    np.testing.assert_allclose(result.time, truth.time, rtol=0, atol=1e-4)  # container timestamps
    assert read_trajectory(folder / "v.truth.csv").metadata["renderer"]["engine"] == "mujoco"
    for name in SIGNALS:
        err = np.degrees(result.raw[name] - truth.signals[name])
        assert np.isfinite(err).all(), name  # every marker is seen in every frame: no gaps
        rms = np.sqrt(np.mean(err**2))
        # issue 4: lean and pitch RMS <= 0.3 deg, steer <= 0.5 deg (measured, seeds 2 and 3:
        # lean 0.04-0.05, steer 0.09-0.10, pitch 0.08-0.09)
        assert rms <= (0.5 if name == "steer" else 0.3), (name, rms)
        # the clip's common bias (module docstring), at most a third of the targets: measured
        # (seeds 2, 3) lean +0.04, +0.03, steer -0.08, -0.08, pitches +0.04 to +0.05 deg
        assert abs(err.mean()) <= (0.5 if name == "steer" else 0.3) / 3, (name, err.mean())
        # z of the scatter about it (module docstring): n = 73 frames, lag-1 correlation <= 0.26,
        # n_eff = 63, sampling spread 3/sqrt(126) = 0.27; below, the lowest signal's mean in
        # test_track_rendered.py's compass clips (0.62) times 1 - 0.27. Measured 0.64-0.77
        # (seeds 2, 3). Uncentred, z is 0.88-1.49 (lean 1.30-1.49, steer 1.22-1.30): lean's bias
        # alone is 1.1-1.3 times its SD.
        sd = np.degrees(result.raw_sd[name])
        z = np.sqrt(np.mean(((err - err.mean()) / sd) ** 2))
        assert 0.62 * (1 - 0.27) < z < 1 + 0.27, (name, z)
    # two strikes, each found once by its foot within half a frame (strikes.MATCH_FRAMES)
    errors = np.array(two_strike_errors(truth, result.events))
    # issue 4: a quarter frame (measured -0.02 and +0.05 frame; seed 3: +0.07 and -0.05)
    assert np.sqrt(np.mean(errors**2)) <= 0.25, errors
    # the hip width (0.1 m), not told the tracker: measured 0.3-0.4 mm short; test_track_rendered.py's 1 mm
    assert abs(result.hip_width - 0.1) < 1e-3, result.hip_width


@pytest.mark.slow
def test_a_wrong_camera_fails_the_targets(clip):
    """The targets can fail on this clip: the same video tracked with a camera file whose focal
    length is 5 % long (a poor calibration; the ramp pose left to the ramp markers, as a wrong
    fixed one is refused) gives pitch errors past them (measured: pitch_right 0.44 deg RMS, all
    four angles biased by 0.17-0.43 deg). At 3 % the RMS stays within them (0.25 deg) but the bias
    check of test_mujoco_clip_meets_the_targets fails (pitch_right -0.24 deg)."""
    result, truth, folder = clip
    camera = load_camera(folder / "v.camera.json")
    k = camera.matrix.copy()
    k[0, 0] *= 1.05
    k[1, 1] *= 1.05
    wrong = dataclasses.replace(camera, matrix=k, ramp_pose=None)
    bad, _ = track_video(folder / "v.mp4", wrong, load_layout(folder / "v.markers.json"))
    worst = max(np.sqrt(np.mean(np.degrees(bad.raw[name] - truth.signals[name]) ** 2))
                / (0.5 if name == "steer" else 0.3) for name in SIGNALS)
    assert math.isfinite(worst) and worst > 1.0, worst
