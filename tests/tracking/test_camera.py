"""The camera model: projection round trips with distortion, camera files, sub-pixel markers."""

import json

import cv2
import numpy as np
import pytest
from numpy.testing import assert_allclose
from toywalk.tracking.camera import (
    Camera,
    CameraError,
    backproject,
    default_camera,
    load_camera,
    pose_matrix,
    project,
    save_camera,
    undistort_pixels,
)
from toywalk.tracking.detect import MarkerDetector

from .synthetic import draw_marker

DISTORTED = Camera(width=640, height=480, matrix=np.array([[600.0, 0, 322.0], [0, 598.0, 241.0], [0, 0, 1]]),
                   distortion=np.array([-0.15, 0.08, 0.001, -0.0007, -0.01]),
                   ramp_pose=(np.array([0.1, -0.2, 0.3]), np.array([0.01, 0.02, 0.7])))


def test_project_backproject_round_trip():
    rng = np.random.default_rng(0)
    pts = np.column_stack([rng.uniform(-0.25, 0.25, 200), rng.uniform(-0.18, 0.18, 200),
                           rng.uniform(0.5, 2.0, 200)])
    uv = project(DISTORTED, pts, np.zeros(3), np.zeros(3))
    rays = backproject(DISTORTED, uv)
    expected = pts / np.linalg.norm(pts, axis=1, keepdims=True)
    np.testing.assert_allclose(rays, expected, atol=1e-9)  # iterative undistortion to 1e-12
    np.testing.assert_allclose(undistort_pixels(DISTORTED, uv), pts[:, :2] / pts[:, 2:], atol=1e-9)


def test_project_matches_a_direct_formula():
    """OpenCV's model written out (Brown-Conrady radial + tangential) for one point."""
    k1, k2, p1, p2, k3 = DISTORTED.distortion
    x, y = 0.21, -0.13
    r2 = x * x + y * y
    radial = 1 + k1 * r2 + k2 * r2**2 + k3 * r2**3
    xd = x * radial + 2 * p1 * x * y + p2 * (r2 + 2 * x * x)
    yd = y * radial + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y
    k = DISTORTED.matrix
    uv = project(DISTORTED, [[x, y, 1.0]], np.zeros(3), np.zeros(3))[0]
    np.testing.assert_allclose(uv, [k[0, 0] * xd + k[0, 2], k[1, 1] * yd + k[1, 2]], atol=1e-9)


def test_pose_and_points_behind():
    rvec, tvec = DISTORTED.ramp_pose
    m = pose_matrix(rvec, tvec)
    p = np.array([0.05, -0.02, 0.01])
    uv = project(DISTORTED, [p], rvec, tvec)[0]
    cam = m[:3, :3] @ p + m[:3, 3]
    np.testing.assert_allclose(backproject(DISTORTED, [uv])[0], cam / np.linalg.norm(cam), atol=1e-9)
    assert np.all(np.isnan(project(DISTORTED, [[0, 0, -1.0]], np.zeros(3), np.zeros(3))))


def test_json_round_trip(tmp_path):
    path = tmp_path / "c.json"
    cam = Camera(**{**DISTORTED.__dict__, "reprojection_error": 0.21})
    save_camera(cam, path)
    back = load_camera(path)
    np.testing.assert_array_equal(back.matrix, cam.matrix)
    np.testing.assert_array_equal(back.distortion, cam.distortion)
    for a, b in zip(back.ramp_pose, cam.ramp_pose, strict=True):
        np.testing.assert_array_equal(a, b)
    assert back.size == (640, 480) and back.reprojection_error == 0.21
    assert [p.name for p in tmp_path.iterdir()] == ["c.json"]  # no temporary file left


@pytest.mark.parametrize("content, message", [
    ("{", "cannot read camera file"),
    ("[1, 2]", "must hold a JSON object"),
    ('{"image_size": [640, 480], "distortion": [0, 0, 0, 0]}', "malformed camera description"),
    ('{"image_size": [640, 480], "camera_matrix": [[1, 0, 0], [0, 1, 0]], "distortion": [0, 0, 0, 0]}',
     "finite 3x3"),
    ('{"image_size": [640, 480], "camera_matrix": [[500, 0, 320], [0, 500, 240], [0, 0, 1]], '
     '"distortion": [0, 0, 0]}', "4, 5, 8, 12 or 14"),
    ('{"image_size": [0, 480], "camera_matrix": [[500, 0, 320], [0, 500, 240], [0, 0, 1]], '
     '"distortion": [0, 0, 0, 0]}', "image size must be positive"),
    ('{"image_size": [640, 480], "camera_matrix": [[500, 0, 320], [0, 500, 240], [0, 0, 1]], '
     '"distortion": [0, 0, 0, 0], "ramp_pose": {"rvec": [0, 0]}}', "malformed camera description"),
])
def test_malformed_files(tmp_path, content, message):
    path = tmp_path / "bad.json"
    path.write_text(content)
    with pytest.raises(CameraError, match=message):
        load_camera(path)


def test_missing_file(tmp_path):
    with pytest.raises(CameraError, match="camera file not found"):
        load_camera(tmp_path / "nope.json")


def test_binary_file(tmp_path):
    """An image passed as the camera file: one line, not a UnicodeDecodeError."""
    path = tmp_path / "photo.json"
    path.write_bytes(b"\x89PNG\r\n\x1a\n\x00\xff")
    with pytest.raises(CameraError, match="cannot read camera file .*decode") as info:
        load_camera(path)
    assert "\n" not in str(info.value)


def test_default_camera_field_of_view():
    cam = default_camera(1280, 720, horizontal_fov_deg=40.0)
    # the ray through the left edge of the image makes 20 degrees with the axis
    edge = backproject(cam, [[-0.5, (720 - 1) / 2]])[0]
    assert np.degrees(np.arctan2(-edge[0], edge[2])) == pytest.approx(20.0, abs=1e-9)
    assert json.loads(json.dumps(cam.to_dict()))["image_size"] == [1280, 720]


def test_a_lens_read_out_at_another_size_sees_the_same_picture():
    """A video mode of the same sensor: every 3D point lands where the image scaled with it puts
    it (pixel centres at half-integers: u' = (u + 0.5) s - 0.5), through OpenCV's own projection
    with distortion; a field of view's edge stays its edge; another aspect ratio is refused."""
    rng = np.random.default_rng(3)
    points = np.column_stack([rng.uniform(-0.2, 0.2, (50, 2)), rng.uniform(0.5, 1.5, 50)])
    zero = np.zeros(3)
    for w, h in ((960, 720), (320, 240), (1280, 960)):
        scaled = DISTORTED.at_size(w, h)
        s = w / DISTORTED.width
        assert scaled.size == (w, h)
        assert_allclose(np.r_[scaled.ramp_pose], np.r_[DISTORTED.ramp_pose], rtol=0, atol=0)
        # round-off of a float's last digits over hundreds of pixels
        assert_allclose(project(scaled, points, zero, zero),
                        (project(DISTORTED, points, zero, zero) + 0.5) * s - 0.5, rtol=0, atol=1e-9)
        assert_allclose(scaled.at_size(640, 480).matrix, DISTORTED.matrix, rtol=0, atol=1e-12)
    # the bundled lens at 1080p is the one default_camera gives there (render's lens at that size)
    assert_allclose(default_camera(1280, 720, 50.0).at_size(1920, 1080).matrix,
                    default_camera(1920, 1080, 50.0).matrix, rtol=0, atol=1e-9)
    with pytest.raises(CameraError, match="not the 640x480 camera's aspect ratio"):
        DISTORTED.at_size(1280, 720)
    with pytest.raises(CameraError, match="positive integers"):
        DISTORTED.at_size(0, 480)


def test_subpixel_marker_corners_recovered():
    """Markers rendered at random sub-pixel poses through a distorting lens: the detector's corners
    agree with the projected true corners to well under a pixel."""
    dictionary = cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_4X4_50)
    detector = MarkerDetector("DICT_4X4_50", camera=DISTORTED)
    rng = np.random.default_rng(4)
    side = 0.02
    h = side / 2
    errors = []
    for _ in range(12):
        rvec = np.array([np.pi, 0, 0]) + rng.normal(0, 0.35, 3)
        tvec = np.array([rng.uniform(-0.1, 0.1), rng.uniform(-0.07, 0.07), rng.uniform(0.3, 0.5)])
        image = np.full((480, 640), 140, np.uint8)
        draw_marker(image, DISTORTED, dictionary, 7, side, rvec, tvec, ss=4)
        image = np.clip(image + rng.normal(0, 1.0, image.shape), 0, 255).astype(np.uint8)
        truth = project(DISTORTED, [[-h, h, 0], [h, h, 0], [h, -h, 0], [-h, -h, 0]], rvec, tvec)
        found = detector.detect(image)
        assert list(found) == [7]
        errors.append(found[7] - truth)
    errors = np.array(errors).reshape(-1, 2)
    # measured 0.04 px RMS noise-free on 25-40 px markers; 1 grey level of noise adds a little
    assert np.sqrt(np.mean(errors**2)) < 0.1
    assert np.max(np.abs(errors)) < 0.4
    assert np.all(np.abs(errors.mean(axis=0)) < 0.03)  # px: no bias
