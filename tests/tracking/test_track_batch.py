"""The tracker's per-frame work done for all markers at once (tracking/track.py, detect.py):
the search regions of a body's markers against the marker-by-marker routine they replaced, and
region searches that skip short outlines against searches that examine every outline."""

import cv2
import numpy as np
import pytest
from toywalk.model.parameters import Params
from toywalk.tracking.detect import MarkerDetector, merge_regions
from toywalk.tracking.markers import default_layout
from toywalk.tracking.track import Tracker

from .synthetic import render_walker_frame, walker_scene_camera

PARAMS = Params(leg_length=0.15, foot_radius=0.03, foot_lateral_radius=0.005, hip_width=0.0,
                leg_mass=0.05, axle_mass=0.02, com_offset=(-0.005, 0.1, -0.11),
                inertia=(3e-4, 1e-4, 3e-4, 0.0, 0.0, 0.0), slope=0.0785, gravity=9.81)  # as test_track


def _regions_one_by_one(tracker, body, pred):
    """Search regions marker by marker, as ``Tracker._regions`` found them before it projected
    all of a body's markers at once: a slow, obvious reference. Returns (regions, min_side)."""
    rvec, tvec, (dr, dt) = pred
    rot = cv2.Rodrigues(rvec.reshape(3, 1))[0]
    facing = np.einsum("ij,ij->i", body.normals @ rot.T, body.centres @ rot.T + tvec) < 0
    regions, min_side = [], np.inf
    for k, marker_id in enumerate(body.ids):
        if not facing[k]:
            continue
        uv = tracker._project(body.points[marker_id], rvec, tvec)
        if not np.all(np.isfinite(uv)):
            continue
        lo, hi = uv.min(axis=0), uv.max(axis=0)
        size = float(np.max(hi - lo))
        motion = tracker._project(body.points[marker_id], rvec + dr, tvec + dt) - uv
        slack = 0.35 * size + 8.0 + float(np.nanmax(np.abs(motion))) if np.all(np.isfinite(motion)) \
            else 0.5 * size + 8.0
        regions.append((lo[0] - slack, lo[1] - slack, hi[0] + slack + 1, hi[1] + slack + 1))
        min_side = min(min_side, float(np.min(hi - lo)))
    return regions, min_side


@pytest.fixture(scope="module")
def walker():
    camera = walker_scene_camera(640, 360)
    layout = default_layout(PARAMS)
    image, poses = render_walker_frame(camera, layout, PARAMS, (0.03, 0.1, 0.2, -0.2), "L", (0.15, 0.0),
                                       rng=4, ss=2)
    return camera, layout, image, poses


def test_regions_match_marker_by_marker(walker):
    """Poses turned so that some markers face away, with and without motion: the same regions
    in the same order and the same smallest marker extent, to rounding."""
    camera, layout, _, poses = walker
    tracker = Tracker(camera, layout)
    rng = np.random.default_rng(7)
    counts = set()
    for name, body in tracker.bodies.items():
        rvec, tvec = (np.asarray(v, float) for v in poses[name])
        for _ in range(40):
            turn = cv2.Rodrigues(rng.normal(0.0, 0.8, 3))[0] @ cv2.Rodrigues(rvec.reshape(3, 1))[0]
            pred = (cv2.Rodrigues(turn)[0].ravel(), tvec + rng.normal(0.0, 0.01, 3),
                    (rng.normal(0.0, 0.02, 3), rng.normal(0.0, 0.002, 3)))
            tracker._min_side = np.inf
            regions = tracker._regions(body, pred)
            expected, min_side = _regions_one_by_one(tracker, body, pred)
            assert len(regions) == len(expected)
            # the same projections and sums: equal to rounding of pixel coordinates (1e-9 px)
            np.testing.assert_allclose(np.reshape(regions, (-1, 4)), np.reshape(expected, (-1, 4)),
                                       rtol=0, atol=1e-9)
            assert tracker._min_side == pytest.approx(min_side, abs=1e-9)
            counts.add(len(regions))
    assert 0 in counts and len(counts) >= 3  # bodies facing away, and facing with several markers


def test_region_search_skipping_short_outlines_finds_the_same(walker):
    """Regions around the walker's markers searched with their predicted size (outlines shorter
    than it skipped) give the same markers and corners as regions searched for any size."""
    camera, layout, image, poses = walker
    tracker = Tracker(camera, layout)
    regions = []
    tracker._min_side = np.inf
    for name in ("left_leg", "right_leg"):  # the tracker also follows the ramp: not the walker
        regions += tracker._regions(tracker.bodies[name], (*(np.asarray(v, float) for v in poses[name]),
                                           (np.zeros(3), np.zeros(3))))
    regions = merge_regions(regions, camera.width, camera.height)
    detector = MarkerDetector(layout.dictionary, camera=camera)
    every = detector.detect(image, regions)
    sized = detector.detect(image, regions, min_side=tracker._min_side)
    assert len(every) >= 4 and sorted(sized) == sorted(every)
    for i in every:
        np.testing.assert_array_equal(sized[i], every[i])  # the same outlines, so the same corners
    # a size far above the markers' skips them all (the filter works), and the whole frame is
    # still searched for any size
    assert detector.detect(image, regions, min_side=10 * tracker._min_side) == {}
    assert sorted(detector.detect(image, min_side=10 * tracker._min_side)) == sorted(detector.detect(image))
