"""Camera calibration from synthetic ChArUco views: recovery of a known camera, and refusals."""

import json
import subprocess

import cv2
import numpy as np
import pytest
from toywalk.tracking.calibrate import DEFAULT_BOARD, CalibrationError, calibrate, save_calibration
from toywalk.tracking.calibrate import board_views as library_board_views
from toywalk.tracking.camera import Camera, load_camera

from .synthetic import TOYWALK

# Tangential terms of a cheap lens, 4-8 of the calibration's standard errors from zero (below), so
# that a dropped, swapped or sign-flipped term is seen; with the earlier 0.0008, -0.0005 (2.5 and
# 1.2 standard errors) it would not be.
TRUE = Camera(width=640, height=480, matrix=np.array([[620.0, 0, 331.5], [0, 618.0, 236.0], [0, 0, 1]]),
              distortion=np.array([-0.12, 0.06, 0.0025, -0.002, 0.0]))
#: cv2.calibrateCameraExtended's order of the intrinsics and their standard errors
NAMES = ("fx", "fy", "cx", "cy", "k1", "k2", "p1", "p2", "k3")


def board_views(n=10, noise=1.5, seed=0):
    """Views of the default board through the lens ``TRUE`` (toywalk.tracking.calibrate.board_views:
    the board 0.42-0.58 m away at its focal length, tilted, off centre)."""
    return library_board_views(TRUE, n, noise, seed)


@pytest.fixture(scope="module")
def views():
    return board_views()


def test_recovers_a_known_camera(views):
    result = calibrate(views)
    k, d = result.camera.matrix, result.camera.distortion
    assert result.rms < 0.3  # px: corners of a rendered board with 1.5 grey levels of noise
    assert result.camera.reprojection_error == pytest.approx(result.rms)
    sd = result.std_intrinsics
    # What ten views of 24 corners at 1.5 grey levels resolve: the calibration's standard errors,
    # measured over board-view seeds 0-7, were fx, fy, cx, cy 0.8-1.4 px, k1 0.013-0.020, p1, p2
    # 3-6e-4 (bounds: 1.5 times the largest). k2 (SD 0.20-0.33) and k3 (0.94-1.76) are not
    # resolved: they trade against each other, and the board's corners reach only r = 0.31 of the
    # normalised field (its corners are at 0.65), where k2's whole effect is 0.1 px. So k2 is
    # checked against its standard error alone, and its sign is not claimed; that check means
    # something only while the standard error stays what these views give, so it is bounded too
    # (k2 below 0.5, k3 below 2.7: 1.5 times the largest measured over seeds 0-7, 0.33 and 1.76),
    # or a calibration that lost k2 altogether (an SE of 10, say) would pass it.
    assert np.all(sd[:4] < 2.0) and sd[4] < 0.03 and np.all(sd[6:8] < 1e-3), dict(zip(NAMES, sd, strict=True))
    assert sd[5] < 0.5 and sd[8] < 2.7, dict(zip(NAMES, sd, strict=True))
    # Every parameter within 4 of its standard errors of the truth. Measured over seeds 0-7, with
    # these and the earlier tangential terms: |error / SD| at most 2.6, RMS about 1 (the standard
    # errors are honest; p2 and cy run about 1 SD low). The earlier fixed tolerances were 1-1.5
    # standard errors for k1 (0.02) and k2 (0.1) and passed with this seed only: seed 1 misses k1
    # by 0.034 and k2 by 0.73.
    true = np.r_[TRUE.matrix[0, 0], TRUE.matrix[1, 1], TRUE.matrix[0, 2], TRUE.matrix[1, 2], TRUE.distortion]
    z = (np.r_[k[0, 0], k[1, 1], k[0, 2], k[1, 2], d] - true) / sd
    assert np.all(np.abs(z) < 4), dict(zip(NAMES, np.round(z, 1), strict=True))
    # the tangential distortion is seen: p1, p2 more than 3 standard errors from zero (6.2 and 5.7
    # here, 3.9-7.8 over seeds 0-7), so the check above tells them from a dropped term
    assert np.all(np.abs(d[2:4]) > 3 * sd[6:8]), (d[2:4], sd[6:8])
    # The projection of the test camera and the calibrated one agree over the field the views
    # cover (r <= 0.34), once the principal point's offset (resolved to its SD of about 1 px,
    # checked above) is taken out: measured 0.2-1.0 px over seeds 0-7 (0.54 here). A k1 of the
    # wrong sign moves points by up to 5.9 px; p1, p2 dropped or swapped by 0.7-1.3 px, which is
    # why they are checked on their own above.
    pts = np.column_stack([np.random.default_rng(1).uniform(-0.35, 0.35, (50, 2)) * [1, 0.7], np.ones(50)])
    a, _ = cv2.projectPoints(pts, np.zeros(3), np.zeros(3), TRUE.matrix, TRUE.distortion)
    b, _ = cv2.projectPoints(pts, np.zeros(3), np.zeros(3), k, d)
    offset = k[:2, 2] - TRUE.matrix[:2, 2]
    assert np.max(np.linalg.norm(b - a - offset, axis=-1)) < 1.5  # px


def test_a_calibration_repeats_exactly():
    """The same views give the same lens to the last bit. On several OpenCV threads they did not:
    over four runs of the bundled sample views k3 came out 0.5632805-0.5632830 (its order of
    summation changes from run to run), and tracking then moved the angles by up to 2e-5 rad.
    Five runs here: a thread-dependent solve would differ in at least one."""
    from toywalk.model.files import DATA_DIR

    views = sorted((DATA_DIR / "sample" / "calibration").glob("view-*.jpg"))
    assert len(views) >= 4
    images = [cv2.imread(str(v), cv2.IMREAD_GRAYSCALE) for v in views]
    threads = cv2.getNumThreads()
    first = calibrate(images).camera
    for _ in range(4):
        again = calibrate(images).camera
        assert np.array_equal(again.matrix, first.matrix)
        assert np.array_equal(again.distortion, first.distortion)
    assert cv2.getNumThreads() == threads  # the caller's setting is restored


def test_saved_file_has_board_and_loads(views, tmp_path):
    result = calibrate(views[:6])
    path = tmp_path / "cam.json"
    save_calibration(result, path)
    data = json.loads(path.read_text())
    assert data["calibration"]["board"] == DEFAULT_BOARD.to_dict()
    cam = load_camera(path)
    np.testing.assert_allclose(cam.matrix, result.camera.matrix)
    assert cam.reprojection_error == pytest.approx(result.rms)


def test_two_views_are_refused(views):
    with pytest.raises(CalibrationError, match=r"only 2 usable view\(s\)"):
        calibrate(views[:2])


def test_blurred_garbage_is_refused():
    rng = np.random.default_rng(2)
    junk = [cv2.GaussianBlur(rng.integers(0, 255, (480, 640), dtype=np.uint8), (31, 31), 8)
            for _ in range(6)]
    with pytest.raises(CalibrationError, match=r"only 0 usable view"):
        calibrate(junk)


def test_high_rms_is_refused(views):
    # a limit below what this noise gives: the refusal and its message name the number
    message = r"RMS reprojection error [0-9.]+ px exceeds the limit 0.01 px"
    with pytest.raises(CalibrationError, match=message):
        calibrate(views, max_rms=0.01)


def test_command_line(views, tmp_path):
    paths = []
    for k, v in enumerate(views[:6]):
        p = tmp_path / f"v{k}.png"
        cv2.imwrite(str(p), v)
        paths.append(p)
    out = tmp_path / "cam.json"
    run = subprocess.run([TOYWALK, "calibrate", *map(str, paths),
                          "--out", str(out)], capture_output=True, text=True, timeout=120)
    assert run.returncode == 0, run.stderr
    assert load_camera(out).width == 640
    bad = subprocess.run([TOYWALK, "calibrate", str(paths[0]),
                          str(tmp_path / "missing.png"), "--out", str(tmp_path / "c2.json")],
                         capture_output=True, text=True, timeout=120)
    assert bad.returncode == 2
    assert "not found" in bad.stderr and len(bad.stderr.strip().splitlines()) == 1
    assert not (tmp_path / "c2.json").exists()
