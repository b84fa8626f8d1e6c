"""The marker layout: which ArUco markers are stuck where on the walker and the ramp (docs/formats.md).

A layout file is JSON::

    {
      "dictionary": "DICT_4X4_50",
      "description": "free text",
      "markers": [
        {"id": 0, "body": "left_leg", "side": 0.06, "margin": 0.015,
         "rvec": [rx, ry, rz], "tvec": [tx, ty, tz], "name": "left upper flag"},
        ...
      ]
    }

``body`` is ``left_leg`` or ``right_leg`` (the leg body frame of docs/model.md section 1: origin at the
hip point, ``b1`` forward, ``b2`` along the hip axis to the left for both legs, ``b3`` along the leg
from foot to hip) or ``ramp`` (the ramp frame S: x downhill, y left, z along the ramp normal).
``side`` is the side of the black square (m), ArUco's marker length; ``margin`` (m, optional,
default ``side / 4``) is the white paper around it. ``rvec, tvec`` (Rodrigues vector, m) give the
pose of the marker frame in the body frame, ``X_body = R(rvec) X_marker + tvec``. The marker frame
is OpenCV's ArUco convention: origin at the marker's centre, x to the right and y up on the printed
marker, z out of the printed face; its corners, in ArUco's order, are top-left ``(-s/2, s/2, 0)``,
top-right ``(s/2, s/2, 0)``, bottom-right ``(s/2, -s/2, 0)``, bottom-left ``(-s/2, -s/2, 0)``.
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import cv2
import numpy as np
from toywalk.model.files import atomic_write_json, read_json_object

__all__ = [
    "BODIES",
    "LEGS",
    "LayoutError",
    "Marker",
    "MarkerLayout",
    "body_points",
    "default_layout",
    "load_layout",
    "marker_corners",
    "marker_pose_matrix",
    "save_layout",
]

#: Bodies a marker can be stuck to.
BODIES = ("left_leg", "right_leg", "ramp")
#: The leg bodies by their foot's letter ('L', 'R': docs/model.md's legs, the trajectory's stance).
LEGS = {"left_leg": "L", "right_leg": "R"}


class LayoutError(ValueError):
    """A marker layout file or argument is malformed; the message names what and where."""


def _is_number(value) -> bool:
    """A real number that a float holds, not a bool or a string that looks like one."""
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        return False
    try:
        float(value)
    except OverflowError:  # an integer too large for a float
        return False
    return True


def _short(value) -> str:
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


def _vector3(value, what: str) -> np.ndarray:
    items = value.tolist() if isinstance(value, np.ndarray) and value.ndim == 1 else value
    if not (isinstance(items, (list, tuple)) and len(items) == 3 and all(_is_number(v) for v in items)):
        raise LayoutError(f"{what} must be three numbers, got {_short(value)}")
    out = np.array(items, dtype=float)
    if not np.all(np.isfinite(out)):
        raise LayoutError(f"{what} must be three finite numbers, got {_short(value)}")
    return out


@dataclasses.dataclass(frozen=True)
class Marker:
    """One printed ArUco marker and where it is stuck.

    Attributes
    ----------
    id : int
        Marker id in the layout's dictionary.
    body : str
        One of :data:`BODIES`.
    side : float
        Side of the black square (m).
    rvec, tvec : ndarray, shape (3,)
        Pose of the marker frame in the body frame (Rodrigues vector; m).
    margin : float
        White paper around the black square on each side (m); ``side / 4`` if not given.
    name : str
        Free text.
    """

    id: int
    body: str
    side: float
    rvec: np.ndarray
    tvec: np.ndarray
    margin: float | None = None
    name: str = ""

    def __post_init__(self) -> None:
        where = f"marker {_short(self.id)}"
        if isinstance(self.id, bool) or not isinstance(self.id, (int, np.integer)) or self.id < 0:
            raise LayoutError(f"{where}: id must be an integer >= 0")
        object.__setattr__(self, "id", int(self.id))
        if not (isinstance(self.body, str) and self.body in BODIES):
            raise LayoutError(f"{where}: body must be one of {', '.join(BODIES)}, got {_short(self.body)}")
        if not _is_number(self.side):
            raise LayoutError(f"{where}: side must be a number (m), got {_short(self.side)}")
        side = float(self.side)
        if not (math.isfinite(side) and side > 0):
            raise LayoutError(f"{where}: side must be a positive length (m), got {self.side!r}")
        object.__setattr__(self, "side", side)
        margin = side / 4 if self.margin is None else self.margin
        if not _is_number(margin):
            raise LayoutError(f"{where}: margin must be a number (m), got {_short(self.margin)}")
        margin = float(margin)
        if not (math.isfinite(margin) and margin >= 0):
            raise LayoutError(f"{where}: margin must be a length >= 0 (m), got {self.margin!r}")
        object.__setattr__(self, "margin", margin)
        object.__setattr__(self, "rvec", _vector3(self.rvec, f"{where}: rvec"))
        object.__setattr__(self, "tvec", _vector3(self.tvec, f"{where}: tvec"))
        object.__setattr__(self, "name", str(self.name))

    def to_dict(self) -> dict:
        return {"id": self.id, "body": self.body, "side": self.side, "margin": self.margin,
                "rvec": self.rvec.tolist(), "tvec": self.tvec.tolist(), "name": self.name}


_MARKER_KEYS = {"id", "body", "side", "margin", "rvec", "tvec", "name"}
_LAYOUT_KEYS = {"dictionary", "description", "markers"}


@dataclasses.dataclass(frozen=True)
class MarkerLayout:
    """The ArUco dictionary and every marker of a setup.

    Attributes
    ----------
    dictionary : str
        Name of an OpenCV predefined dictionary, e.g. ``"DICT_4X4_50"``.
    markers : tuple of Marker
        Ids are unique and valid in the dictionary.
    description : str
    """

    dictionary: str
    markers: tuple
    description: str = ""

    def __post_init__(self) -> None:
        if not (isinstance(self.dictionary, str) and self.dictionary.startswith("DICT_")
                and isinstance(getattr(cv2.aruco, self.dictionary, None), int)):
            raise LayoutError(f"dictionary must name an OpenCV ArUco dictionary such as 'DICT_4X4_50', "
                              f"got {_short(self.dictionary)}")
        markers = tuple(self.markers)
        if not all(isinstance(m, Marker) for m in markers):
            raise LayoutError("markers must be Marker objects")
        size = self.aruco_dictionary().bytesList.shape[0]
        seen = set()
        for m in markers:
            if m.id in seen:
                raise LayoutError(f"marker id {m.id} appears more than once")
            if m.id >= size:
                raise LayoutError(f"marker id {m.id} is not in {self.dictionary} (ids 0..{size - 1})")
            seen.add(m.id)
        object.__setattr__(self, "markers", markers)
        object.__setattr__(self, "description", str(self.description))

    def aruco_dictionary(self):
        """The OpenCV ``cv2.aruco.Dictionary``."""
        return cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, self.dictionary))

    def on(self, body: str) -> tuple[Marker, ...]:
        """Markers stuck to ``body`` (one of :data:`BODIES`)."""
        if body not in BODIES:
            raise LayoutError(f"body must be one of {', '.join(BODIES)}, got {body!r}")
        return tuple(m for m in self.markers if m.body == body)

    def by_id(self, marker_id: int) -> Marker:
        for m in self.markers:
            if m.id == marker_id:
                return m
        raise KeyError(f"no marker with id {marker_id} in the layout")

    def to_dict(self) -> dict:
        return {"dictionary": self.dictionary, "description": self.description,
                "markers": [m.to_dict() for m in self.markers]}

    @classmethod
    def from_dict(cls, data) -> MarkerLayout:
        if not isinstance(data, dict):
            raise LayoutError("a marker layout must be a JSON object")
        unknown = set(data) - _LAYOUT_KEYS
        if unknown:
            raise LayoutError(f"unknown key(s) {', '.join(_short(k) for k in sorted(unknown))} (expected "
                              f"{', '.join(sorted(_LAYOUT_KEYS))})")
        if "dictionary" not in data:
            raise LayoutError("missing key 'dictionary' (e.g. \"DICT_4X4_50\")")
        items = data.get("markers")
        if not isinstance(items, list) or not items:
            raise LayoutError("'markers' must be a non-empty list")
        markers = []
        for k, item in enumerate(items):
            if not isinstance(item, dict):
                raise LayoutError(f"markers[{k}] must be an object")
            unknown = set(item) - _MARKER_KEYS
            if unknown:
                names = ", ".join(_short(u) for u in sorted(unknown))
                raise LayoutError(f"markers[{k}]: unknown key(s) {names}")
            missing = [key for key in ("id", "body", "side", "rvec", "tvec") if key not in item]
            if missing:
                raise LayoutError(f"markers[{k}]: missing key(s) {', '.join(missing)}")
            markers.append(Marker(id=item["id"], body=item["body"], side=item["side"],
                                  rvec=item["rvec"], tvec=item["tvec"], margin=item.get("margin"),
                                  name=item.get("name", "")))
        return cls(dictionary=data["dictionary"], markers=tuple(markers),
                   description=data.get("description", ""))


def load_layout(path: str | Path) -> MarkerLayout:
    """Read a marker layout JSON file; a one-line :class:`LayoutError` for a missing or bad file."""
    data = read_json_object(path, "marker layout file", LayoutError)
    try:
        return MarkerLayout.from_dict(data)
    except LayoutError as err:
        raise LayoutError(f"{path}: {err}") from err


def save_layout(layout: MarkerLayout, path: str | Path) -> None:
    """Write a marker layout JSON file atomically (temporary file in the same folder, renamed)."""
    atomic_write_json(path, layout.to_dict())


def marker_pose_matrix(marker: Marker) -> np.ndarray:
    """4x4 transform from the marker frame to its body frame."""
    out = np.eye(4)
    out[:3, :3] = cv2.Rodrigues(marker.rvec.reshape(3, 1))[0]
    out[:3, 3] = marker.tvec
    return out


def marker_corners(marker: Marker, margin: float = 0.0) -> np.ndarray:
    """Corners of the black square (or, with ``margin`` (m), of a square that much larger on each
    side), shape (4, 3), in the marker's body frame (m), in ArUco's order TL, TR, BR, BL."""
    h = marker.side / 2 + margin
    local = np.array([[-h, h, 0.0], [h, h, 0.0], [h, -h, 0.0], [-h, -h, 0.0]])
    pose = marker_pose_matrix(marker)
    return local @ pose[:3, :3].T + pose[:3, 3]


def body_points(layout: MarkerLayout, body: str) -> dict[int, np.ndarray]:
    """Marker id -> its four corners, shape (4, 3), in the body frame, for every marker on ``body``:
    the object points for ``cv2.solvePnP``."""
    return {m.id: marker_corners(m) for m in layout.on(body)}


# --- the default layout ---------------------------------------------------------------------------

def _rvec_from_axes(x_axis, y_axis) -> np.ndarray:
    """Rodrigues vector of the rotation whose columns are (x, y, x cross y) (x, y orthonormalised)."""
    x = np.asarray(x_axis, float)
    x = x / np.linalg.norm(x)
    y = np.asarray(y_axis, float)
    y = y - (y @ x) * x
    y = y / np.linalg.norm(y)
    rot = np.column_stack([x, y, np.cross(x, y)])
    return cv2.Rodrigues(rot)[0].ravel()


def _leg_flag(normal, up, centre) -> tuple[np.ndarray, np.ndarray]:
    """Pose of a flag whose printed face points along ``normal`` with its top towards ``up``."""
    normal = np.asarray(normal, float) / np.linalg.norm(normal)
    up = np.asarray(up, float)
    up = up - (up @ normal) * normal
    right = np.cross(up, normal)
    return _rvec_from_axes(right, up), np.asarray(centre, float)


def default_layout(params, camera_side: str = "right", dictionary: str | None = None,
                   reach: float | None = None, third_flag: bool = False) -> MarkerLayout:
    """The bundled marker layout, scaled from the walker's parameters.

    Each leg carries two flags (ids 0, 1 on the left leg, 2, 3 on the right leg) mounted in front of
    the leg rod and offset outboard, so that when the legs pass each other the two legs' flags sit
    side by side rather than one behind the other. Both face forward (down the ramp, towards a
    camera filming the walker as it comes down), turned 25 degrees towards the camera's side of the
    ramp: the upper flag (0.2 l below the hip) upright, the lower one (0.48 l below) tilted 30
    degrees upwards, so that each leg's two marker planes differ and its pose (pitch in particular)
    is well determined. Eight markers lie flat on the ramp (ids
    10-17) in two rows either side of the walking line, from behind the start to 2.3 leg lengths
    down the ramp, 0.9 l apart: a board that fixes the ramp frame. Sizes scale with the leg length
    l: leg markers 0.15 l, ramp markers 0.2 l. With ``reach`` the rows run on, 0.9 l apart, until
    they cover the ramp that far down (for a camera following a long walk): the left row's ids
    follow 10, then the right row's.

    Parameters
    ----------
    params : Params
        The walker (only the geometry is used).
    camera_side : {'right', 'left'}
        Side of the walking line (looking downhill) on which the camera stands.
    dictionary : str, optional
        Default: DICT_4X4_50, or the smallest of DICT_4X4_100, _250, _1000 that holds every id
        (the 4x4 dictionaries share their first markers, so ids 0-49 look the same in each).
    reach : float, optional
        How far down the ramp (m, ramp x) the ramp markers must reach; at least 2.3 l.
    third_flag : bool
        Add a third flag to each leg (ids 4 left, 5 right), of the same size, on a mast 0.2 l
        above the hip, upright and turned 60 degrees towards the camera's side: a leg then keeps
        two flags far apart and not parallel whichever one the other leg hides (measured in
        benchmarks/TRACKING.md, "Marker layouts": with flags hidden, pitch errors 4-10 times
        smaller for compass-3d, 0.03-0.16 degree for the toy-sized walker).
    """
    if camera_side not in ("right", "left"):
        raise LayoutError(f"camera_side must be 'right' or 'left', got {camera_side!r}")
    ell = float(params.leg_length)
    w = float(params.hip_width)
    towards = -1.0 if camera_side == "right" else 1.0  # +b2 is left
    side = 0.15 * ell
    margin = side / 4
    flag = side + 2 * margin
    rod = 0.025 * ell
    out = 0.75 * flag  # lateral offset of a flag's centre from its leg's axis, outboard
    turn = math.radians(25.0)
    tilt = math.radians(30.0)
    markers = []
    for k, (leg, outboard) in enumerate((("left_leg", 1.0), ("right_leg", -1.0))):
        normal_upper = np.array([math.cos(turn), towards * math.sin(turn), 0.0])
        normal_lower = math.cos(tilt) * normal_upper + math.sin(tilt) * np.array([0.0, 0.0, 1.0])
        for j, (normal, height) in enumerate(((normal_upper, -0.2 * ell), (normal_lower, -0.48 * ell))):
            centre = np.array([2 * rod + 0.5 * flag * abs(math.sin(turn)), outboard * out, height])
            rvec, tvec = _leg_flag(normal, [0.0, 0.0, 1.0], centre)
            markers.append(Marker(id=2 * k + j, body=leg, side=side, rvec=rvec, tvec=tvec, margin=margin,
                                  name=f"{leg.split('_')[0]} {'upper' if j == 0 else 'lower'} flag"))
    if third_flag:
        turn3 = math.radians(60.0)
        normal = np.array([math.cos(turn3), towards * math.sin(turn3), 0.0])
        for k, (leg, outboard) in enumerate((("left_leg", 1.0), ("right_leg", -1.0))):
            centre = np.array([2 * rod + 0.5 * flag * math.sin(turn3), outboard * out, 0.2 * ell])
            rvec, tvec = _leg_flag(normal, [0.0, 0.0, 1.0], centre)
            markers.append(Marker(id=4 + k, body=leg, side=side, rvec=rvec, tvec=tvec, margin=margin,
                                  name=f"{leg.split('_')[0]} third flag (above the hip)"))
    ramp_side = 0.2 * ell
    y_mid = -0.5 * w
    rows = (y_mid + 0.75 * ell + 0.5 * w, y_mid - 0.75 * ell - 0.5 * w)
    count = 4 if reach is None else max(4, int(math.ceil((float(reach) / ell + 0.4) / 0.9 - 1e-9)) + 1)
    xs = ell * np.round(-0.4 + 0.9 * np.arange(count), 9)  # -0.4, 0.5, 1.4, 2.3, ... exactly
    ident = np.zeros(3)  # marker x along ramp x, marker y along ramp y, face up: the ramp frame itself
    if dictionary is None:
        dictionary = next(name for name in ("DICT_4X4_50", "DICT_4X4_100", "DICT_4X4_250", "DICT_4X4_1000")
                          if 10 + 2 * count <= int(name.rsplit("_", 1)[1]))
    mid = 10
    for row, y in enumerate(rows):
        for x in xs:
            markers.append(Marker(id=mid, body="ramp", side=ramp_side, rvec=ident,
                                  tvec=np.array([x, y, 0.0]), margin=ramp_side / 4,
                                  name=f"ramp {'left' if row == 0 else 'right'} row"))
            mid += 1
    description = (f"default layout{' with a third flag a leg' if third_flag else ''} for a walker with "
                   f"leg_length {ell:g} m, hip_width {w:g} m, camera on the {camera_side} "
                   "(toywalk.tracking.markers.default_layout)")
    return MarkerLayout(dictionary=dictionary, markers=tuple(markers), description=description)
