"""The marker layout: file round trip, conventions, errors, the bundled default."""

import json

import cv2
import numpy as np
import pytest
from numpy.testing import assert_allclose
from toywalk.model.parameters import load_params
from toywalk.tracking.markers import (
    LayoutError,
    Marker,
    MarkerLayout,
    body_points,
    default_layout,
    load_layout,
    marker_corners,
    save_layout,
)

from ..conftest import DATA


def test_round_trip(tmp_path, toy_params):
    layout = default_layout(toy_params)
    path = tmp_path / "m.json"
    save_layout(layout, path)
    back = load_layout(path)
    assert back.dictionary == layout.dictionary
    assert [m.id for m in back.markers] == [m.id for m in layout.markers]
    for a, b in zip(layout.markers, back.markers, strict=True):
        assert (a.body, a.name) == (b.body, b.name)
        assert_allclose([a.side, a.margin], [b.side, b.margin], rtol=0, atol=0)  # JSON floats round-trip
        assert_allclose(marker_corners(a), marker_corners(b), rtol=0, atol=1e-15)
    assert not list(tmp_path.glob(".*tmp"))  # the atomic write left no temporary file


def test_corners_follow_arucos_convention():
    """Identity pose: TL (-s/2, s/2), TR, BR, BL (OpenCV ArUco order), in the marker plane z = 0."""
    m = Marker(id=3, body="ramp", side=0.2, rvec=[0, 0, 0], tvec=[1.0, 2.0, 0.0])
    assert_allclose(marker_corners(m), [[0.9, 2.1, 0], [1.1, 2.1, 0], [1.1, 1.9, 0], [0.9, 1.9, 0]],
                    atol=1e-15)
    # a quarter turn about x: marker y (up on the print) -> body z, marker z (face) -> body -y
    m = Marker(id=3, body="left_leg", side=0.2, rvec=[np.pi / 2, 0, 0], tvec=[0, 0, 0])
    c = marker_corners(m)
    assert_allclose(c[0], [-0.1, 0.0, 0.1], atol=1e-15)
    normal = np.cross(c[1] - c[0], c[3] - c[0])  # (TR - TL) x (BL - TL) = x_m x (-y_m) = -z_m
    assert_allclose(-normal / np.linalg.norm(normal), [0, -1, 0], atol=1e-12)
    assert_allclose(marker_corners(m, margin=0.05)[0], [-0.15, 0.0, 0.15], atol=1e-15)


def test_default_layout_covers_legs_and_ramp(toy_params):
    for params in (toy_params, load_params(DATA / "params" / "compass-3d.toml")):
        layout = default_layout(params)
        assert len(layout.on("left_leg")) >= 2 and len(layout.on("right_leg")) >= 2
        assert len(layout.on("ramp")) >= 4
        for m in layout.on("left_leg") + layout.on("right_leg"):
            face = cv2.Rodrigues(m.rvec)[0][:, 2]
            assert face[0] > 0.5  # faces forward, down the ramp, towards the camera
            assert m.side == pytest.approx(0.15 * params.leg_length)  # scaled with the walker
        pts = body_points(layout, "ramp")
        assert all(np.all(p[:, 2] == 0) for p in pts.values())  # flat on the ramp


def test_a_third_flag_a_leg(toy_params, tmp_path):
    """default_layout(third_flag=True): the default markers unchanged, and one more flag a leg
    (ids 4 left, 5 right) on a mast 0.2 l above the hip, facing forward and turned further
    towards the camera's side (for a camera on the right, -y) than either other flag, so parallel
    to neither; it survives the file round trip."""
    two, three = default_layout(toy_params), default_layout(toy_params, third_flag=True)
    extra = [m for m in three.markers if m.id not in {n.id for n in two.markers}]
    assert [(m.id, m.body) for m in extra] == [(4, "left_leg"), (5, "right_leg")]
    for a in two.markers:
        b = next(m for m in three.markers if m.id == a.id)
        assert_allclose(marker_corners(a), marker_corners(b), rtol=0, atol=0)
    for m in extra:
        assert m.tvec[2] == pytest.approx(0.2 * toy_params.leg_length)
        face = cv2.Rodrigues(m.rvec)[0][:, 2]
        assert face[0] > 0.4 and face[1] < -0.8  # 60 degrees towards a camera on the right
        for other in three.on(m.body):
            if other.id != m.id:
                assert abs(face @ cv2.Rodrigues(other.rvec)[0][:, 2]) < 0.95  # not parallel
    save_layout(three, tmp_path / "m.json")
    assert [m.id for m in load_layout(tmp_path / "m.json").markers] == [m.id for m in three.markers]


def test_bundled_layout_is_the_default_for_the_bundled_walker():
    params = load_params(DATA / "params" / "compass-3d.toml")
    bundled = load_layout(DATA / "markers" / "default.json")
    expected = default_layout(params)
    assert bundled.dictionary == expected.dictionary
    for a, b in zip(bundled.markers, expected.markers, strict=True):
        assert (a.id, a.body) == (b.id, b.body)
        assert_allclose(marker_corners(a), marker_corners(b), atol=1e-12)


def _write(tmp_path, data) -> str:
    path = tmp_path / "layout.json"
    path.write_text(data if isinstance(data, str) else json.dumps(data))
    return path


GOOD = {"dictionary": "DICT_4X4_50",
        "markers": [{"id": 1, "body": "ramp", "side": 0.1, "rvec": [0, 0, 0], "tvec": [0, 0, 0]}]}


@pytest.mark.parametrize("mutate, message", [
    (lambda d: d.update(dictionary="DICT_9X9_7"), "dictionary"),
    (lambda d: d.pop("dictionary"), "dictionary"),
    (lambda d: d.update(markers=[]), "non-empty"),
    (lambda d: d.update(extra=1), "unknown key"),
    (lambda d: d["markers"].append(dict(d["markers"][0])), "more than once"),
    (lambda d: d["markers"][0].update(id=50), "not in DICT_4X4_50"),
    (lambda d: d["markers"][0].update(id=-1), "id"),
    (lambda d: d["markers"][0].update(body="torso"), "body"),
    (lambda d: d["markers"][0].update(side=-0.1), "side"),
    (lambda d: d["markers"][0].update(side="big"), "side"),
    (lambda d: d["markers"][0].update(rvec=[0, 0]), "rvec"),
    (lambda d: d["markers"][0].update(tvec=[0, "x", 0]), "tvec"),
    (lambda d: d["markers"][0].pop("side"), "missing"),
    (lambda d: d["markers"][0].update(colour="red"), "unknown key"),
])
def test_malformed_layouts_fail_with_one_line(tmp_path, mutate, message):
    data = json.loads(json.dumps(GOOD))
    mutate(data)
    with pytest.raises(LayoutError, match=message) as info:
        load_layout(_write(tmp_path, data))
    assert "\n" not in str(info.value)
    assert isinstance(info.value, ValueError)


def test_unreadable_files(tmp_path):
    with pytest.raises(LayoutError, match="not found"):
        load_layout(tmp_path / "missing.json")
    with pytest.raises(LayoutError, match="cannot read"):
        load_layout(_write(tmp_path, "{not json"))
    with pytest.raises(LayoutError, match="JSON object"):
        load_layout(_write(tmp_path, "[1, 2]"))
    assert load_layout(_write(tmp_path, GOOD)).by_id(1).side == 0.1


def test_layout_rejects_non_markers():
    with pytest.raises(LayoutError):
        MarkerLayout("DICT_4X4_50", ("not a marker",))
