"""A flag smeared by motion blur (tracking/detect.py, ``_refine_smeared``): when ArUco's outline
lies pixels off, one edge-line refinement falls short and the detector refines again; a marker
ArUco placed as usual is refined once, as before."""

import cv2
import numpy as np
import pytest
from toywalk.tracking.camera import default_camera, project
from toywalk.tracking.detect import _SMEARED_STEP, _refine_smeared, refine_corners

from .synthetic import draw_marker

CAMERA = default_camera(640, 480)


def _smeared(blur: int, side: float):
    """A marker of ``side`` (m) 0.4 m away (43-62 px), smeared by a horizontal box of ``blur``
    px (a flag moving across the image while the shutter is open: its edges' half-way crossings
    stay where the unsmeared edges are), 2 grey levels of noise; its true corners."""
    dictionary = cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_4X4_50)
    image = np.full((480, 640), 150, np.uint8)
    rvec, tvec = np.array([np.pi + 0.3, 0.2, 0.1]), np.array([0.0, 0.0, 0.4])
    draw_marker(image, CAMERA, dictionary, 0, side, rvec, tvec)
    h = side / 2
    true = project(CAMERA, [[-h, h, 0], [h, h, 0], [h, -h, 0], [-h, -h, 0]], rvec, tvec)
    smeared = cv2.blur(image.astype(float), (blur, 1)) if blur > 1 else image.astype(float)
    noisy = smeared + np.random.default_rng(1).normal(0.0, 2.0, image.shape)
    return np.clip(noisy, 0, 255).astype(np.uint8), true


def _outward(true, px):
    """The true corners moved ``px`` away from the quad's centre (as ArUco's outline of a
    smeared flag: 3.1 px on the stable-toy clip of test_occluded_leg.py)."""
    away = true - true.mean(axis=0)
    return true + px * away / np.linalg.norm(away, axis=1, keepdims=True)


@pytest.mark.parametrize("side", [0.02, 0.03])
@pytest.mark.parametrize("off", [2.0, 3.0])
def test_a_smeared_flag_is_refined_again(side, off):
    image, true = _smeared(5, side)
    rough = _outward(true, off)
    once = refine_corners(image, rough)
    first_step = np.max(np.linalg.norm(once - rough, axis=1))
    assert first_step > _SMEARED_STEP  # so it is refined again
    again = _refine_smeared(image, rough[None], once[None], None)[0]
    # one step leaves 0.49-0.89 px (the band's end thirds take in the 5-px smear), the further
    # steps 0.07-0.13 (measured); 0.2 px is the tracker's corner RMS on blurred rendered flags
    assert np.abs(once - true).max() > 0.45
    assert np.abs(again - true).max() < 0.2


@pytest.mark.parametrize("blur", [1, 5])
def test_an_ordinary_outline_is_refined_once(blur):
    """ArUco's outline of an unsmeared marker lies 0.9 px out (the median on every shipped
    walker's clips): one refinement, the result as before."""
    image, true = _smeared(blur, 0.02)
    rough = _outward(true, 0.9)
    once = refine_corners(image, rough)
    np.testing.assert_array_equal(_refine_smeared(image, rough[None], once[None], None)[0], once)
    if blur == 1:  # one step reaches the true corners within the noise
        assert np.abs(once - true).max() < 0.1
