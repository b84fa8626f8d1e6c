"""Markers followed from predicted corners without ArUco's search (tracking/detect.py,
MarkerDetector.follow): the same corners as detection gives, to the truth; a prediction too far
off, a covered marker, a wrong code and a marker at the frame's edge are left to the detector."""

import cv2
import numpy as np
import pytest
from toywalk.tracking.camera import default_camera, project
from toywalk.tracking.detect import MarkerDetector

from .synthetic import draw_marker

CAMERA = default_camera(640, 480, distortion=(-0.08, 0.03, 0.0, 0.0, 0.0))
SIDE = 0.025  # m: about 40 px wide at 0.55 m (f = 879 px), like the ramp's markers
H = SIDE / 2
SQUARE = [[-H, H, 0], [H, H, 0], [H, -H, 0], [-H, -H, 0]]
# three markers on a board tilted away from the camera, at different places in the frame
POSES = {4: (np.array([np.pi + 0.5, 0.0, 0.1]), np.array([-0.12, 0.04, 0.55])),
         9: (np.array([np.pi + 0.5, 0.1, -0.1]), np.array([0.0, 0.05, 0.6])),
         21: (np.array([np.pi + 0.4, -0.2, 0.0]), np.array([0.13, -0.02, 0.5]))}


@pytest.fixture(scope="module")
def scene():
    dictionary = cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_4X4_50)
    image = np.full((480, 640), 150, np.uint8)
    for marker_id, (rvec, tvec) in POSES.items():
        draw_marker(image, CAMERA, dictionary, marker_id, SIDE, rvec, tvec)
    rng = np.random.default_rng(5)
    image = np.clip(image + rng.normal(0, 2.0, image.shape), 0, 255).astype(np.uint8)
    truth = {i: project(CAMERA, SQUARE, r, t) for i, (r, t) in POSES.items()}
    return image, truth


def test_followed_corners_are_the_detected_ones(scene):
    image, truth = scene
    detector = MarkerDetector("DICT_4X4_50", camera=CAMERA)
    detected = detector.detect(image)
    assert sorted(detected) == sorted(POSES)
    rng = np.random.default_rng(1)
    # predictions up to 0.9 px off, as a panning camera's constant-velocity guess can be
    predicted = {i: truth[i] + rng.uniform(-0.6, 0.6, (4, 2)) for i in truth}
    followed = detector.follow(image, predicted)
    assert sorted(followed) == sorted(POSES)
    for i in POSES:
        # the same edge-line refinement as a detected marker's, from a prediction instead of
        # ArUco's rough corners: the same corners to a few hundredths of a pixel (measured
        # 0.010-0.028 px), both 0.035-0.135 px from the truth (this texture's drawing, with either start)
        np.testing.assert_allclose(followed[i], detected[i], atol=0.05)
        np.testing.assert_allclose(followed[i], truth[i], atol=0.2)


def test_what_cannot_be_followed_is_left_to_the_detector(scene):
    image, truth = scene
    detector = MarkerDetector("DICT_4X4_50", camera=CAMERA)
    # a prediction 4 px off: the refinement finds the edges, but the marker moved more than
    # predicted (max_move 1.5 px), so it is not taken on trust
    assert detector.follow(image, {4: truth[4] + [4.0, 0.0]}) == {}
    # the marker's inner half covered by a grey bar: its code no longer reads
    covered = image.copy()
    box = np.round(truth[9]).astype(int)
    lo, hi = box.min(axis=0), box.max(axis=0)
    mid = (lo + hi) // 2
    covered[lo[1] + 8:hi[1] - 8, lo[0] + 8:mid[0]] = 150
    assert detector.follow(covered, {9: truth[9]}) == {}
    # marker 21's quad called 3: its code is read (check) and refused; unchecked, continuity is
    # trusted (the caller checks each marker's code at intervals)
    assert detector.follow(image, {3: truth[21]}, check={3}) == {}
    assert 3 in detector.follow(image, {3: truth[21]}, check=set())
    # a quad cut by the frame's edge
    assert detector.follow(image, {4: truth[4] - [truth[4][:, 0].min() - 3.0, 0.0]}) == {}
    # and an empty region
    assert detector.follow(image, {4: truth[4] + [0.0, 150.0]}) == {}
