"""What the renderer's camera frames: the default camera holds the walk it is given (fixed, or
following a long walk down the ramp), a given camera lets the walker leave its view without
error, and the tracker marks the frames without the walker as gaps."""

import subprocess

import cv2
import numpy as np
import pytest
from toywalk.model.parameters import save_params
from toywalk.model.trajectory import TrajectoryTable, write_trajectory
from toywalk.sysid.commands.render import out_of_view_warning
from toywalk.tracking.camera import load_camera, project, save_camera
from toywalk.tracking.detect import MarkerDetector
from toywalk.tracking.markers import body_points, default_layout, load_layout, marker_corners
from toywalk.tracking.pose import estimate_pose
from toywalk.tracking.ramp import ramp_difference
from toywalk.tracking.render import Filming, RenderOptions, default_filming, render
from toywalk.tracking.scene import Scene, default_camera_for, look_at
from toywalk.tracking.track import track_video

from .scenes import TOY  # the toy-sized walker, 15 cm legs
from .synthetic import TOYWALK

NAMES = ("lean", "steer", "pitch_left", "pitch_right")


def _walk(start: float, stop: float, duration: float, rate: float = 100.0) -> TrajectoryTable:
    """A made-up walk: the stance contact slides from ``start`` to ``stop`` (m) down the ramp at an
    even pace while the legs swing (0.25 rad, 0.75 s strides), lean and steer."""
    t = np.linspace(0.0, duration, int(round(duration * rate)) + 1)
    w = 2 * np.pi / 0.75
    signals = {"lean": 0.03 * np.sin(w * t), "steer": 0.05 * np.cos(w * t),
               "pitch_left": 0.25 * np.sin(w * t), "pitch_right": -0.25 * np.sin(w * t),
               "contact_x": start + (stop - start) * t / duration, "contact_y": np.zeros_like(t)}
    return TrajectoryTable(t, signals, np.full(len(t), "L"), [], {"source": {"kind": "test"}})


def _inside(camera, pose, points) -> np.ndarray:
    """Which ramp-frame points the camera at ``pose`` sees inside its image."""
    uv = project(camera, points, *pose)
    return np.isfinite(uv).all(axis=1) & (uv[:, 0] >= 0) & (uv[:, 0] <= camera.width - 1) \
        & (uv[:, 1] >= 0) & (uv[:, 1] <= camera.height - 1)


def _frame_poses(camera, path, times):
    return [camera.ramp_pose if path is None else path.pose(float(t)) for t in times]


def test_a_short_walk_keeps_the_default_camera():
    """A walk of a few strides stays in the corridor the default camera was placed for: the
    camera is the one of default_camera_for (and so data/camera/default.json for compass-3d)."""
    camera, path, layout = default_filming(_walk(0.0, 0.2, 1.0), TOY, 640, 360)
    assert path is None
    expected = default_camera_for(TOY, 640, 360)
    np.testing.assert_array_equal(np.concatenate(camera.ramp_pose), np.concatenate(expected.ramp_pose))
    assert layout.to_dict() == default_layout(TOY).to_dict()


@pytest.mark.parametrize("stop, follows", [(0.4, False), (1.4, True)])
def test_the_default_camera_frames_the_walk_it_is_given(stop, follows):
    """A walk a little longer than the corridor (0.4 m; the corridor holds hips to 0.27 m) is
    framed from one place, farther back; the issue's 1.4 m is followed down the ramp. Either way the walker's
    every vertex is in the image in every frame, and at least six ramp markers are (three of
    each row in the default framing: enough for the ramp pose in every frame)."""
    table = _walk(0.0, stop, 6.0)
    camera, path, layout = default_filming(table, TOY, 640, 360, RenderOptions(fps=10))
    assert (path is not None) == follows
    film = Filming(table, TOY, camera, layout, RenderOptions(fps=10), 0, path)
    ramp = np.concatenate([marker_corners(m) for m in layout.on("ramp")])
    for t, pose in zip(film.times, _frame_poses(film.camera, path, film.times), strict=True):
        assert _inside(camera, pose, film.scene.walker_points(film.motion.state(t))).all(), t
        seen = _inside(camera, pose, ramp).reshape(-1, 4).all(axis=1)
        assert seen.sum() >= 6, (t, seen.sum())
    if follows:  # the rows run on along the walk
        assert max(m.tvec[0] for m in layout.on("ramp")) > stop


def test_a_following_camera_draws_the_ramp_from_where_it_stands(monkeypatch):
    """The ramp seen by a moved camera is a reference image, ray cast once, warped to each new
    pose: its markers must be where the camera at that instant sees them. Three frames 0.1 s apart,
    0.6-0.8 m down the walk: the second draws a new reference, the third is warped from it; the
    ramp pose fitted to the third frame's detected ramp markers matches the path's (measured
    0.013 deg and 0.2 mm; the limits, 0.05 deg and 1 mm, are about three times the pose's own
    scatter from corner noise at 1280x720, measured over eleven such frames)."""
    table = _walk(0.0, 1.4, 6.0)
    camera, path, layout = default_filming(table, TOY)
    film = Filming(table, TOY, camera, layout, RenderOptions(fps=10, start=2.8, duration=0.2), 0, path)
    cast = []
    real = Scene._static_layers
    monkeypatch.setattr(Scene, "_static_layers", lambda self, *a, **k: cast.append(1) or real(self, *a, **k))
    frames = [film.frame(k) for k in range(3)]
    assert len(cast) == 1  # the third frame's ramp is warped, not ray cast
    t = float(film.times[2])
    # the camera moved between the reference and this frame (by the walk's 0.23 m/s for 0.1 s)
    assert np.linalg.norm(path.pose(t)[1] - path.pose(float(film.times[1]))[1]) > 0.01
    found = MarkerDetector(layout.dictionary, camera=camera).detect(frames[2])
    points = body_points(layout, "ramp")
    ids = [i for i in found if i in points]
    assert len(ids) >= 6
    est = estimate_pose(camera, np.concatenate([points[i] for i in ids]),
                        np.concatenate([found[i] for i in ids]))
    rvec, tvec = path.pose(t)
    turn = ramp_difference(cv2.Rodrigues(est.rvec)[0], cv2.Rodrigues(rvec)[0])
    assert np.degrees(np.abs(turn)).max() < 0.05
    assert np.abs(est.tvec - tvec).max() < 1e-3


def test_a_moved_cameras_ramp_is_composited_as_numpy_would():
    """The moved camera's static image, ramp + sky (1 - cover) rounded, is composited with
    OpenCV's arithmetic in kept arrays; against the obvious NumPy expression of the same warps it
    is the same to the bit (both round the same float32 sums), at two poses, the second reusing
    the arrays, and the backdrop's gradient is the per-channel loop's."""
    from toywalk.tracking.scene import _gradient

    table = _walk(0.0, 1.4, 6.0)
    camera, path, layout = default_filming(table, TOY)
    film = Filming(table, TOY, camera, layout, RenderOptions(fps=10, start=2.8, duration=0.2), 0, path)
    scene = film.scene
    for t in (2.85, 2.9):  # not 2.8, the pose the scene was drawn for
        scene.set_pose(*path.pose(t))
        got = scene._static().copy()
        ramp, cover, sky, h_ref = scene._reference
        wc, hc = scene.canvas_size
        warp = np.array(scene.k_canvas @ np.column_stack([scene.r_cam[:, 0], scene.r_cam[:, 1], scene.t_cam])
                        @ np.linalg.inv(h_ref))
        ramp_w = cv2.warpPerspective(ramp, warp, (wc, hc), flags=cv2.INTER_LINEAR,
                                     borderMode=cv2.BORDER_CONSTANT, borderValue=0)
        cover_w = cv2.warpPerspective(cover, warp, (wc, hc), flags=cv2.INTER_LINEAR,
                                      borderMode=cv2.BORDER_CONSTANT, borderValue=0)
        want = np.clip(ramp_w + sky * (1 - cover_w)[..., None] + 0.5, 0, 255).astype(np.uint8)
        assert np.array_equal(got, want)
        assert 0.05 < np.mean(cover_w) < 1.0  # both the ramp and the sky are in view
    rows, cols = 37, 5
    grad = np.linspace(0, 1, rows, dtype=np.float32)[:, None]
    loop = np.empty((rows, cols, 3), np.float32)
    for ch, (top, bottom) in enumerate(((190, 120), (180, 110), (170, 100))):
        loop[..., ch] = top + (bottom - top) * grad
    assert np.array_equal(_gradient(rows, cols), loop)


def test_a_walker_passing_behind_a_given_camera_renders():
    """The walker walks past a camera standing on the ramp ahead of it, looking back up: some of
    its vertices are behind the camera at one end of a blurred frame's shutter and in front at
    the other (this raised a broadcasting error while counting the renders to average)."""
    table = _walk(0.0, 0.6, 1.0)
    pose = look_at([0.3, -0.02, 0.08], [0.0, 0.0, 0.05], np.array([0.0, 0.0, 1.0]))
    base = default_camera_for(TOY, 320, 180)
    camera = type(base)(base.width, base.height, base.matrix, base.distortion, ramp_pose=pose)
    film = Filming(table, TOY, camera, default_layout(TOY), RenderOptions.preset(1, fps=20), 0)
    scene: Scene = film.scene
    half = 0.5 * film.options.exposure / film.options.fps  # the shutter's half-open time (s)
    sizes, crossing = set(), []
    for k, t in enumerate(film.times):
        behind = [np.isnan(scene.walker_pixels(film.motion.state(t + dt))).any(axis=1)
                  for dt in (-half, half)]
        sizes.update(len(b) for b in behind)
        if behind[0].sum() != behind[1].sum():
            crossing.append(k)
    assert len(sizes) == 1  # the same vertices at every instant, NaN behind the camera
    assert crossing  # the case that failed is met: these frames are drawn
    for k in crossing:
        assert film.frame(k).shape == (180, 320, 3)


@pytest.fixture(scope="module")
def leaving(tmp_path_factory):
    """A 3.2 s clip (15 fps, a clean camera) by a fixed camera placed for the default corridor
    while the walker goes on, at a toy's 0.25 m/s, past its end, and what the tracker made of it."""
    folder = tmp_path_factory.mktemp("leaving")
    table = _walk(0.1, 0.9, 3.2)
    camera, layout = default_camera_for(TOY), default_layout(TOY)
    result = render(table, TOY, camera, layout, RenderOptions.preset(0, fps=15), folder / "v.mp4", rng=3)
    tracked, _ = track_video(folder / "v.mp4", load_camera(result.paths["camera"]),
                             load_layout(result.paths["markers"]))
    film = Filming(table, TOY, camera, layout, RenderOptions(fps=15), 0)
    in_view = np.array([_inside(camera, camera.ramp_pose, film.scene.walker_points(film.motion.state(t)))
                        .mean() for t in film.times])
    truth = np.array([film.motion.angles(t) for t in film.times])
    return tracked, in_view, truth, result


def test_the_render_says_where_the_walker_leaves_the_view(leaving, tmp_path):
    """render() reports each frame's share of the walker in view (the same as this file's own
    projection of the walker's vertices), and the command warns, in one line, when the walker is
    not wholly filmed; a camera that frames the walk gives no warning."""
    _, in_view, _, result = leaving
    np.testing.assert_array_equal(result.in_view, in_view)
    line = out_of_view_warning(result.frame_times, result.in_view)
    partly, gone = int(np.sum(in_view < 1)), int(np.sum(in_view == 0))
    assert f"in {partly} of {len(in_view)} frames" in line and f"none of it in {gone})" in line
    table = _walk(0.1, 0.9, 3.2)
    write_trajectory(table, tmp_path / "walk.csv")
    save_params(TOY, tmp_path / "walker.toml")
    save_camera(default_camera_for(TOY), tmp_path / "camera.json")
    common = ["render", str(tmp_path / "walk.csv"), "--params", str(tmp_path / "walker.toml"),
              "--noise", "0", "--fps", "5", "--size", "320x180"]
    given = subprocess.run([TOYWALK, *common[:-2], "--camera", str(tmp_path / "camera.json"),
                            "--out", str(tmp_path / "given.mp4")],
                           capture_output=True, text=True, timeout=300)
    assert given.returncode == 0, given.stderr
    assert "warning: the walker is not wholly in the camera's view" in given.stderr
    framed = subprocess.run([TOYWALK, *common, "--out", str(tmp_path / "framed.mp4")],
                            capture_output=True, text=True, timeout=300)
    assert framed.returncode == 0, framed.stderr
    assert "warning" not in framed.stderr


def test_frames_without_the_walker_are_gaps(leaving):
    tracked, in_view, truth, _ = leaving
    assert (in_view == 1).sum() >= 5 and (in_view == 0).sum() >= 5  # both kinds of frame
    for k, name in enumerate(NAMES):
        gone = in_view == 0
        assert np.isnan(tracked.raw[name][gone]).all(), name  # empty cells, nothing invented
        whole = in_view == 1
        err = np.degrees(tracked.raw[name][whole] - truth[whole, k])
        ok = np.isfinite(err)
        # where the walker is wholly in view, nearly every frame is tracked: the far leg may hide
        # behind the near one for a few frames as they pass (measured: 16 of 21 frames for the
        # left pitch, 20 for the others; 18 of 21 when the renderer's interpolation departed from
        # this made-up walk by 0.007 degrees: which frames the far leg hides in turns on less)
        assert ok.mean() >= 0.75, name
        # the tracker's targets there (0.3 deg lean and pitch RMS, 0.5 deg steer)
        assert np.sqrt(np.mean(err[ok] ** 2)) < (0.5 if name == "steer" else 0.3), name
