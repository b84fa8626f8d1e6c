"""The readers of user files, fuzzed: trajectory (model/trajectory.py), parameter file
(model/parameters.py), camera file (tracking/camera.py) and marker layout (tracking/markers.py).

On any input each reader either returns an object that satisfies its documented invariants or
raises its own error class (a ValueError) with a one-line message; never another exception (a
KeyError, TypeError, OverflowError, UnicodeDecodeError, RecursionError ... would reach the user as
a traceback) and never a warning (warnings are errors here). Inputs come two ways: arbitrary bytes,
and a valid file with some fields replaced by arbitrary JSON or TOML values, some removed and
some added, which reaches the validation behind the parsers.

Hypothesis runs derandomized (the same examples on every run, so CI is reproducible), at most 50
examples a property, without a deadline (the first example pays for imports).
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from toywalk.model.parameters import ParameterError, Params, load_params
from toywalk.model.trajectory import SIGNALS, TrajectoryError, TrajectoryTable, read_trajectory
from toywalk.tracking.camera import Camera, CameraError, load_camera
from toywalk.tracking.markers import LayoutError, MarkerLayout, load_layout

from .conftest import CAMERA, MARKERS, STABLE_TOY

FUZZ = settings(max_examples=50, deadline=None, derandomize=True, database=None,
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])

#: Any JSON value, nested a little; integers include ones too large for a float.
JSON = st.recursive(
    st.none() | st.booleans() | st.integers() | st.sampled_from([10**400, -(10**400), 2**64])
    | st.floats(allow_nan=True, allow_infinity=True) | st.text(max_size=12),
    lambda inner: st.lists(inner, max_size=4) | st.dictionaries(st.text(max_size=8), inner, max_size=4),
    max_leaves=12)


def _one_line(err: Exception) -> None:
    message = str(err)
    assert message and "\n" not in message, repr(message)


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    """One folder for every example (each example writes its files afresh)."""
    return tmp_path_factory.mktemp("fuzz")


def _mutated(base: dict, draw) -> dict:
    """``base`` with some keys given arbitrary values, some removed, some added."""
    data = dict(base)
    keys = sorted(data)
    if keys:
        for key in draw(st.lists(st.sampled_from(keys), max_size=3, unique=True)):
            data[key] = draw(JSON)
        for key in draw(st.lists(st.sampled_from(keys), max_size=2, unique=True)):
            data.pop(key, None)
    data.update(draw(st.dictionaries(st.text(max_size=8), JSON, max_size=2)))
    return data


# --- trajectory -----------------------------------------------------------------------------------

COLUMNS = ["time", *SIGNALS, "stance", "lean_sd", "steer_sd", "contact_x", "contact_y", "other"]
CELLS = (st.sampled_from(["", "L", "R", "nan", "inf", "-inf", "1e999", "abc", " 0.5 ", "-0", "0x1"])
         | st.floats(allow_nan=False, allow_infinity=False).map(repr)
         | st.text(max_size=6))


@st.composite
def csv_texts(draw, columns, rows=8):
    """A CSV text: a header drawn from ``columns`` (in any order, maybe with repeats) and rows of
    arbitrary cells, most as long as the header, some not."""
    header = draw(st.lists(st.sampled_from(columns), min_size=1, max_size=len(columns) + 1))
    lines = [",".join(header)]
    for _ in range(draw(st.integers(0, rows))):
        n = len(header) if draw(st.integers(0, 9)) else draw(st.integers(0, len(header) + 2))
        lines.append(",".join(draw(st.lists(CELLS, min_size=n, max_size=n))))
    return "\r\n".join(lines) + draw(st.sampled_from(["", "\r\n", "\n"]))


@st.composite
def increasing_walks(draw):
    """A well-formed walk's CSV (times increasing) with some cells changed: closer to a real file,
    so that the checks behind the header's are reached."""
    n = draw(st.integers(1, 6))
    lines = ["time,lean,steer,pitch_left,pitch_right,stance,lean_sd"]
    for i in range(n):
        cells = [repr(0.01 * i), "0.01", "0.02", "-0.1", "0.1", "L" if i % 2 else "R", "0.002"]
        if draw(st.booleans()):
            cells[draw(st.integers(0, 6))] = draw(CELLS)
        lines.append(",".join(cells))
    return "\n".join(lines) + "\n"


def _check_table(table: TrajectoryTable) -> None:
    """The documented invariants of what read_trajectory returns."""
    assert np.all(np.isfinite(table.time)) and np.all(np.diff(table.time) > 0)
    for name, column in table.signals.items():
        assert column.shape == table.time.shape
        if name.endswith("_sd"):
            assert np.all(np.isnan(column) | (column > 0)), name
        else:
            assert np.all(np.isnan(column) | np.isfinite(column)), name
    assert set(table.stance.tolist()) <= {"L", "R", ""}
    for event in table.events:
        assert math.isfinite(event["time"]) and event["foot"] in ("L", "R")
    assert isinstance(table.metadata, dict)


def _read_walk(folder, csv, events=None, metadata=None):
    paths = {"csv": folder / "walk.csv", "events": folder / "walk.events.csv", "json": folder / "walk.json"}
    for kind, content in (("csv", csv), ("events", events), ("json", metadata)):
        path = paths[kind]
        if content is None:
            path.unlink(missing_ok=True)
        elif isinstance(content, bytes):
            path.write_bytes(content)
        else:
            path.write_text(content, encoding="utf-8", newline="")
    try:
        table = read_trajectory(paths["csv"])
    except TrajectoryError as err:
        _one_line(err)
        return
    _check_table(table)


@FUZZ
@given(csv=st.binary(max_size=400))
def test_trajectory_reader_on_bytes(folder, csv):
    _read_walk(folder, csv)


@FUZZ
@given(csv=st.one_of(csv_texts(COLUMNS), increasing_walks(), st.text(max_size=200)),
       events=st.none() | csv_texts(["time", "foot", "x", "y", "time_sd", "x_sd"], rows=4)
       | st.binary(max_size=60),
       metadata=st.none() | JSON.map(json.dumps) | st.text(max_size=30) | st.binary(max_size=30))
def test_trajectory_reader_on_tables(folder, csv, events, metadata):
    _read_walk(folder, csv, events, metadata)


# --- parameter file -------------------------------------------------------------------------------

def _toml(value) -> str:
    """A TOML value (inline)."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return "nan" if math.isnan(value) else ("inf" if value > 0 else "-inf") if math.isinf(value) \
            else repr(value)
    if isinstance(value, int):
        return str(value)
    if isinstance(value, str):
        return json.dumps(value)  # a TOML basic string: JSON's escapes are TOML's
    if isinstance(value, list):
        return "[" + ", ".join(_toml(v) for v in value if v is not None) + "]"
    if isinstance(value, dict):
        return "{" + ", ".join(f"{json.dumps(k)} = {_toml(v)}" for k, v in value.items()
                               if v is not None) + "}"
    return '""'  # None: TOML has no null


def _toml_document(data: dict) -> str:
    lines = [f"{json.dumps(k)} = {_toml(v)}" for k, v in data.items() if v is not None]
    return "\n".join(lines) + "\n"


_PARAMS = {k: v for k, v in Params.to_dict(load_params(STABLE_TOY)).items()}


@st.composite
def parameter_files(draw):
    data = _mutated(_PARAMS, draw)
    if draw(st.booleans()):
        data["effects"] = draw(st.dictionaries(
            st.sampled_from(["hip_damping", "cross_slope", "asymmetry", "nope"]),
            st.floats(allow_nan=True, allow_infinity=True) | JSON, max_size=3))
    if draw(st.integers(0, 4)) == 0:
        data["gait"] = {"start": draw(st.lists(st.floats(), max_size=9))}
    return _toml_document(data)


def _load(folder, content):
    path = folder / "walker.toml"
    path.write_bytes(content) if isinstance(content, bytes) else path.write_text(content, encoding="utf-8")
    try:
        params = load_params(path)
    except ParameterError as err:
        _one_line(err)
        return
    assert np.all(np.isfinite(params.vector()))
    assert params.leg_length > 0 and 0 <= params.foot_radius < params.leg_length
    assert -math.pi / 2 < params.slope < math.pi / 2 and params.gravity > 0


@FUZZ
@given(content=st.binary(max_size=300) | st.text(max_size=200))
def test_parameter_loader_on_bytes(folder, content):
    _load(folder, content)


@FUZZ
@given(content=parameter_files())
def test_parameter_loader_on_parameter_files(folder, content):
    _load(folder, content)


# --- camera and marker layout files ---------------------------------------------------------------

_CAMERA = json.loads(CAMERA.read_text())
_LAYOUT = json.loads(MARKERS.read_text())


@st.composite
def camera_files(draw):
    data = _mutated(_CAMERA, draw)
    if draw(st.booleans()) and isinstance(data.get("ramp_pose"), dict):
        data["ramp_pose"] = _mutated(data["ramp_pose"], draw)
    return json.dumps(data)


@st.composite
def layout_files(draw):
    data = _mutated(_LAYOUT, draw)
    if isinstance(data.get("markers"), list) and data["markers"] and draw(st.booleans()):
        k = draw(st.integers(0, len(data["markers"]) - 1))
        markers = list(data["markers"])
        markers[k] = _mutated(markers[k], draw) if isinstance(markers[k], dict) else markers[k]
        data["markers"] = markers + draw(st.lists(st.sampled_from(markers), max_size=1))
    return json.dumps(data)


def _camera(folder, content):
    path = folder / "camera.json"
    path.write_bytes(content) if isinstance(content, bytes) else path.write_text(content)
    try:
        camera = load_camera(path)
    except CameraError as err:
        _one_line(err)
        return
    assert isinstance(camera, Camera) and camera.matrix.shape == (3, 3)
    assert np.all(np.isfinite(camera.matrix)) and np.all(np.isfinite(camera.distortion))
    assert camera.ramp_pose is None or all(np.all(np.isfinite(v)) for v in camera.ramp_pose)
    json.dumps(camera.to_dict(), allow_nan=False)  # writes back as strict JSON


def _layout(folder, content):
    path = folder / "layout.json"
    path.write_bytes(content) if isinstance(content, bytes) else path.write_text(content)
    try:
        layout = load_layout(path)
    except LayoutError as err:
        _one_line(err)
        return
    assert isinstance(layout, MarkerLayout) and layout.markers
    assert len({m.id for m in layout.markers}) == len(layout.markers)
    json.dumps(layout.to_dict(), allow_nan=False)


@FUZZ
@given(content=st.binary(max_size=300) | st.text(max_size=200) | JSON.map(json.dumps))
def test_camera_reader_on_bytes(folder, content):
    _camera(folder, content)


@FUZZ
@given(content=camera_files())
def test_camera_reader_on_camera_files(folder, content):
    _camera(folder, content)


@FUZZ
@given(content=st.binary(max_size=300) | st.text(max_size=200) | JSON.map(json.dumps))
def test_layout_reader_on_bytes(folder, content):
    _layout(folder, content)


@FUZZ
@given(content=layout_files())
def test_layout_reader_on_layout_files(folder, content):
    _layout(folder, content)
