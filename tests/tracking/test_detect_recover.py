"""Recovery of markers the ArUco detector misses (tracking/detect.py, MarkerDetector.recover):
a motion-blurred marker found from a rough predicted quad at the true corners, verified by its
bits; a wrong id and an empty region rejected."""

import cv2
import numpy as np
import pytest
from toywalk.tracking.camera import default_camera, project
from toywalk.tracking.detect import MarkerDetector, marker_matches

from .synthetic import draw_marker

CAMERA = default_camera(640, 480)
SIDE = 0.02  # m: about 44 px wide at 0.4 m with this camera (f = 879 px), like the toy's flags
H = SIDE / 2
RVEC = np.array([np.pi, 0.0, 0.0]) + np.array([0.2, -0.3, 0.1])
TVEC = np.array([0.0, 0.0, 0.4])
SQUARE = [[-H, H, 0], [H, H, 0], [H, -H, 0], [-H, -H, 0]]


@pytest.fixture(scope="module")
def blurred():
    """Marker 7 moving 6 px sideways during the exposure, seen as 3 sub-frames (the renderer's
    noise level 1), with 2 grey levels of sensor noise; truth: the corners at mid-exposure."""
    dictionary = cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_4X4_50)
    shifts = np.linspace(-0.5, 0.5, 3) * 6.0 / 879.0 * TVEC[2]  # m: 6 px at 0.4 m
    subs = []
    for s in shifts:
        image = np.full((480, 640), 140, np.uint8)
        draw_marker(image, CAMERA, dictionary, 7, SIDE, RVEC, TVEC + np.array([s, 0.3 * s, 0.0]))
        subs.append(image.astype(float))
    rng = np.random.default_rng(1)
    image = np.clip(np.mean(subs, axis=0) + rng.normal(0, 2.0, (480, 640)), 0, 255).astype(np.uint8)
    return image, project(CAMERA, SQUARE, RVEC, TVEC), dictionary


def test_blurred_marker_missed_by_aruco_is_recovered(blurred):
    image, truth, _ = blurred
    detector = MarkerDetector("DICT_4X4_50", camera=CAMERA)
    assert detector.detect(image) == {}  # the case recovery is for
    # a prediction 2.5 px off, as a constant-velocity guess near heel strike can be
    found = detector.recover(image, 7, truth + np.array([2.0, -1.5]))
    assert found is not None
    # measured 0.04 px; the edge lines of blurred, noisy edges (3 sub-frames) are good to a
    # small fraction of a pixel
    np.testing.assert_allclose(found, truth, atol=0.25)


def test_wrong_id_and_empty_region_rejected(blurred):
    image, truth, dictionary = blurred
    detector = MarkerDetector("DICT_4X4_50", camera=CAMERA)
    # another id at the right place: its bits differ in more than one cell
    assert detector.recover(image, 3, truth) is None
    assert not marker_matches(image, truth, dictionary, 3)
    assert marker_matches(image, truth, dictionary, 7)
    # the same quad over plain background (no edges, no code) and over noise
    empty = truth + np.array([-150.0, 0.0])
    assert detector.recover(image, 7, empty) is None
    noise = np.random.default_rng(2).integers(0, 256, image.shape, dtype=np.uint8)
    assert detector.recover(noise, 7, truth) is None
    assert not marker_matches(noise, truth, dictionary, 7)


def test_marker_matches_reads_an_unblurred_marker_in_every_rotation():
    """The corner order fixes the orientation: the same marker read from corners starting at
    another corner is a rotated code, which must not pass as the id."""
    dictionary = cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_4X4_50)
    image = np.full((480, 640), 140, np.uint8)
    draw_marker(image, CAMERA, dictionary, 12, SIDE, RVEC, TVEC)
    truth = project(CAMERA, SQUARE, RVEC, TVEC)
    assert marker_matches(image, truth, dictionary, 12, max_bit_errors=0)
    for k in (1, 2, 3):
        assert not marker_matches(image, np.roll(truth, k, axis=0), dictionary, 12)
